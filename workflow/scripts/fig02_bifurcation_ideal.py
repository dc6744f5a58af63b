"""Snakemake glue: seed fig. 2 from the ideal model's Gamma grid."""

from bouncelab.figures import fig02_bifurcation_ideal
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

with house_style():
    fig, data = fig02_bifurcation_ideal.make(read_table(snakemake.input[0]))
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
