"""Snakemake glue: seed fig. 1 from the ideal model at Gamma = 2.5."""

import sys

from bouncelab.figures import fig01_takeoff_line
from bouncelab.figures.style import house_style, save_figure
from bouncelab.physics import Model, simulate_protocol

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

GAMMA = 2.5  # in the bouncing regime with a visible ride on the plate between flights
# one step from rest at phase 0: the protocol gives absolute takeoff phases
flights = simulate_protocol(Model.parse("ideal"), [GAMMA], [4], settle_cycles=0)
with house_style():
    fig, data = fig01_takeoff_line.make(flights, GAMMA)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
