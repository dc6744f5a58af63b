"""Snakemake glue: seed fig. 9, the model with and without friction over the data."""

import sys

from bouncelab.figures import fig09_friction
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

friction = read_table(snakemake.input.friction)
mu = float(friction["mu"].iloc[0]) if "mu" in friction and len(friction) else None
with house_style():
    fig, data = fig09_friction.make(
        read_table(snakemake.input.flights),
        read_table(snakemake.input.ideal),
        friction,
        snakemake.wildcards.run,
        mu=mu,
    )
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
