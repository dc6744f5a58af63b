"""Snakemake glue: seed fig. 5, a stretch of the continuity channel with detected flights."""

import sys

import numpy as np

from bouncelab.figures import fig05_continuity
from bouncelab.figures.style import house_style, save_figure
from bouncelab.runs import load_run, read_recording
from bouncelab.tables import read_table

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

flights = read_table(snakemake.input.flights)
run = load_run(snakemake.params.run_dir)
rec = read_recording(run, roles=("continuity",))
window = fig05_continuity.choose_window(flights)
t = rec.times if rec.time_s is None else rec.time_s
if window is None:  # no flights at all: show the first quarter second
    window = (float(t[0]), float(t[0]) + 0.25, None)
lo, hi = np.searchsorted(t, window[:2])
with house_style():
    fig, data = fig05_continuity.make(
        np.asarray(t[lo:hi]),
        np.asarray(rec.channels["continuity"][lo:hi], dtype=float),
        flights,
        run.run_id,
        gamma=window[2],
    )
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
