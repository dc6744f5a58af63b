"""Snakemake glue: the gap before and after the diagnosis's accepted effects."""

import json
import sys

from bouncelab.figures import fig_gap_diagnosis
from bouncelab.figures.style import house_style, save_figure

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with open(snakemake.input[0]) as fh:
    diagnosis = json.load(fh)
with house_style():
    fig, data = fig_gap_diagnosis.make(diagnosis)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
