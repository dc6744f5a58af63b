"""Snakemake glue: check one run folder; always succeeds, records the verdict as JSON."""

import json

from bouncelab.pipeline import check_run_verdict

with open(snakemake.log[0], "w") as log:
    verdict = check_run_verdict(snakemake.params.run_dir)
    log.write((verdict["summary"] or verdict["error"]) + "\n")
with open(snakemake.output[0], "w") as fh:
    json.dump(verdict, fh, indent=1, sort_keys=True)
