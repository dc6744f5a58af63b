"""Snakemake glue: seed fig. 6 from the drop run's calibration."""

import json
import sys

from bouncelab.figures import fig06_drop_test
from bouncelab.figures.style import house_style, save_figure

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

with open(snakemake.input.calibration) as fh:
    calibration = json.load(fh)
with house_style():
    fig, data = fig06_drop_test.make(calibration, snakemake.wildcards.run)
save_figure(fig, snakemake.output.png, data, snakemake.output.data, dpi=snakemake.params.dpi)
