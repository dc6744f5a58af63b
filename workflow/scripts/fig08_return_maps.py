"""Snakemake glue: seed fig. 8, return maps at three Gamma."""

import sys

from bouncelab.figures import fig08_return_maps
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with house_style():
    fig, data = fig08_return_maps.make(
        read_table(snakemake.input.flights), snakemake.params.gammas, snakemake.wildcards.run
    )
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
