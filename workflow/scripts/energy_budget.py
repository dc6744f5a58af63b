"""Snakemake glue: energy budget across Gamma, per model variant, in joules."""

import sys

from bouncelab.pipeline import energy_budgets
from bouncelab.tables import read_table, write_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

sims = {
    v: read_table(p) for v, p in zip(snakemake.params.variants, snakemake.input.sims, strict=True)
}
write_table(energy_budgets(snakemake.params.run_dir, sims), snakemake.output[0])
