"""Snakemake glue: seed fig. 4, the accelerometer method against the continuity method."""

import sys

from bouncelab.figures import fig04_accelerometer
from bouncelab.figures.style import house_style, save_figure
from bouncelab.pipeline import accelerometer_figure_inputs
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

inputs = accelerometer_figure_inputs(snakemake.params.run_dir, read_table(snakemake.input.flights))
with house_style():
    fig, data = fig04_accelerometer.make(**inputs)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
