"""Snakemake glue: seed fig. 10, the harmonic model over the data."""

import sys

from bouncelab.figures import fig10_harmonic
from bouncelab.figures.style import house_style, save_figure
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

harmonic = read_table(snakemake.input.harmonic)
params = {
    k: float(harmonic[k].iloc[0]) for k in ("k", "a", "psi") if k in harmonic and len(harmonic)
}
with house_style():
    fig, data = fig10_harmonic.make(
        read_table(snakemake.input.flights), harmonic, snakemake.wildcards.run, params=params
    )
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
