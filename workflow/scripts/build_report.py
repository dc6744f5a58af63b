"""Snakemake glue: assemble the report context and render HTML and PDF."""

import sys

from bouncelab.report import render_html, render_pdf
from bouncelab.report.content import build_context

sys.stderr = open(snakemake.log[0], "w")  # tracebacks go to the rule's log

context = build_context(
    results_dir=snakemake.params.results_dir,
    raw_dir=snakemake.params.raw_dir,
    runs=snakemake.params.runs,
    config=dict(snakemake.params.config),
    captions_dir="workflow/report",
    bad_names=snakemake.params.bad_names,
)
render_html(context, "report/templates", snakemake.output.html, "report/style.css")
# typst reads images only below its root: the results folder holds figures and report
render_pdf(context, "report/templates", snakemake.output.pdf, root=snakemake.params.results_dir)
print(f"report: {len(context['sections'])} sections", file=sys.stderr)
