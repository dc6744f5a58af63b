"""Snakemake glue: confusion matrix and recovery errors of the blind validation."""

import json
import sys

from bouncelab.figures import fig_blind_validation
from bouncelab.figures.style import house_style, save_figure

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with open(snakemake.input[0]) as fh:
    scores = json.load(fh)
with house_style():
    fig, data = fig_blind_validation.make(scores)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
