"""The report: a content model of sections and blocks, rendered to HTML and PDF.

:mod:`bouncelab.report.render` turns a context (title, sections of blocks) into a
self-contained HTML file and a typst PDF from the jinja2 templates under ``report/``;
:mod:`bouncelab.report.content` assembles that context from the pipeline's results.
"""

from bouncelab.report.render import render_html, render_pdf

__all__ = ["render_html", "render_pdf"]
