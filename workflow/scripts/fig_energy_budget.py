"""Snakemake glue: energy budget across Gamma for every model variant."""

import sys

from bouncelab.figures import fig_energy_budget
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with house_style():
    fig, data = fig_energy_budget.make(read_table(snakemake.input[0]), snakemake.wildcards.run)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
