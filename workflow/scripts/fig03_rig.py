"""Snakemake glue: seed fig. 3, the rig schematic with the run's parameters."""

import json
import sys

from bouncelab.figures import fig03_rig
from bouncelab.figures.style import house_style, save_figure

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with open(snakemake.input.check) as fh:
    info = json.load(fh)["info"]
params = {
    "run_id": info["run"],
    "kind": info["kind"],
    "source": info.get("source"),
    "mass_kg": info.get("mass_kg"),
    "drive_frequency_hz": info.get("drive_frequency_hz"),
    "sample_rate_hz": info.get("sample_rate_hz"),
    "gamma_min": info.get("gamma_min") if info["kind"] == "sweep" else None,
    "gamma_max": info.get("gamma_max"),
    "n_steps": info.get("n_steps"),
    "settle_cycles": info.get("settle_cycles"),
    "drop_height_m": info.get("drop_height_m"),
    "duration_s": info.get("duration_s"),
    "channels": [c["role"] for c in info.get("channels", [])],
}
with house_style():
    fig, data = fig03_rig.make(params)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
