"""Snakemake glue: seed fig. 7, data and ideal model under the run's protocol."""

import sys

from bouncelab.figures import fig07_bifurcation
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with house_style():
    fig, data = fig07_bifurcation.make(
        read_table(snakemake.input.flights),
        read_table(snakemake.input.model),
        snakemake.wildcards.run,
    )
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
