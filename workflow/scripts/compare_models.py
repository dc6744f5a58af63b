"""Snakemake glue: per-step gap between the run's flights and every model variant."""

import sys

from bouncelab.pipeline import compare_variants
from bouncelab.tables import read_table, write_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

data = read_table(snakemake.input.flights)
sims = {
    v: read_table(p) for v, p in zip(snakemake.params.variants, snakemake.input.sims, strict=True)
}
write_table(compare_variants(data, sims), snakemake.output[0])
