"""Snakemake glue: seed fig. 1 from the ideal model at Gamma = 2.5."""

from bouncelab.figures import fig01_takeoff_line
from bouncelab.figures.style import house_style, save_figure
from bouncelab.physics import Model, simulate_grid

GAMMA = 2.5  # in the bouncing regime with a visible ride on the plate between flights
flights = simulate_grid(Model.parse("ideal"), [GAMMA], n_flights=6, n_skip=0)
with house_style():
    fig, data = fig01_takeoff_line.make(flights, GAMMA)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
