"""Snakemake glue: seed fig. 2 from the ideal model's Gamma grid."""

import sys

from bouncelab.figures import fig02_bifurcation_ideal
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with house_style():
    grid = snakemake.params.grid
    fig, data = fig02_bifurcation_ideal.make(read_table(snakemake.input[0]), (grid[0], grid[1]))
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
