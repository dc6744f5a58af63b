"""Snakemake glue: one model variant under one sweep run's protocol."""

import json
import sys

from bouncelab.pipeline import simulate_variant
from bouncelab.tables import write_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with open(snakemake.input.check) as fh:
    duration_s = json.load(fh)["info"]["duration_s"]
calibration = snakemake.input.calibration[0] if snakemake.input.calibration else None
table = simulate_variant(
    snakemake.params.run_dir,
    snakemake.params.variant,
    calibration_path=calibration,
    defaults=snakemake.params.defaults,
    n_starts=snakemake.params.starts,
    seed=snakemake.params.seed,
    duration_s=duration_s,
    log_path=snakemake.log[0],
)
write_table(table, snakemake.output[0])
