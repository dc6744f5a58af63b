"""Render the report context to HTML (self-contained) and PDF (typst), deterministically.

The context is a dict with ``title``, ``subtitle``, ``version``, ``git_revision`` and
``sections``: a list of ``{"id", "title", "blocks"}``, each block a dict with a ``type``
(``text``, ``note``, ``heading``, ``equation``, ``figure``, ``table``, ``code``) and the
fields its template branch uses. Both formats come from the templates in one folder
(``report/templates/``), so they cannot drift apart in content.
"""

from __future__ import annotations

import base64
import os
import re
from pathlib import Path

import jinja2

_TYPST_SPECIAL = re.compile(r"([\\#$*_`<>@\[\]~/=+\-'\"])")


def typst_escape(text) -> str:
    """Escape ``text`` for typst markup: every character with a markup meaning."""
    return _TYPST_SPECIAL.sub(r"\\\1", str(text))


def typst_string(text) -> str:
    """Escape ``text`` for a typst string literal."""
    return str(text).replace("\\", "\\\\").replace('"', '\\"')


def typst_raw(text) -> str:
    """Raw text for a typst raw block: only the fence itself must not appear."""
    return str(text).replace("```", "'''")


def data_uri(path) -> str:
    """A PNG file as a ``data:`` URI, so the HTML opens offline as one file."""
    payload = base64.b64encode(Path(path).read_bytes()).decode("ascii")
    return f"data:image/png;base64,{payload}"


def _environment(template_dir: Path, relative_to: Path) -> jinja2.Environment:
    env = jinja2.Environment(
        loader=jinja2.FileSystemLoader(str(template_dir)),
        undefined=jinja2.StrictUndefined,
        autoescape=jinja2.select_autoescape(enabled_extensions=("html.j2",)),
        keep_trailing_newline=True,
        trim_blocks=False,
    )
    env.filters["datauri"] = data_uri
    env.filters["typst"] = typst_escape
    env.filters["typst_str"] = typst_string
    env.filters["typst_raw"] = typst_raw
    env.filters["relpath"] = lambda p: Path(os.path.relpath(Path(p).resolve(), relative_to))
    return env


def render_html(context: dict, template_dir, html_path, css_path=None) -> Path:
    """Write the self-contained HTML report; returns its path."""
    template_dir = Path(template_dir)
    html_path = Path(html_path)
    html_path.parent.mkdir(parents=True, exist_ok=True)
    css = Path(css_path).read_text() if css_path else ""
    env = _environment(template_dir, html_path.parent.resolve())
    text = env.get_template("report.html.j2").render(css=css, **context)
    html_path.write_text(text)
    return html_path


def render_pdf(context: dict, template_dir, pdf_path, root=None) -> Path:
    """Write the typst source beside ``pdf_path`` and compile it to PDF.

    ``root`` is the folder typst may read images from (default: the common parent of
    the PDF and the figures, i.e. the results folder); figure paths are made relative
    to the typst file.
    """
    import typst  # imported here: only the PDF needs it

    template_dir = Path(template_dir)
    pdf_path = Path(pdf_path)
    pdf_path.parent.mkdir(parents=True, exist_ok=True)
    typ_path = pdf_path.with_suffix(".typ")
    env = _environment(template_dir, typ_path.parent.resolve())
    typ_path.write_text(env.get_template("report.typ.j2").render(**context))
    root = Path(root).resolve() if root else pdf_path.parent.resolve().parent
    pdf_bytes = typst.compile(str(typ_path), root=str(root))
    pdf_path.write_bytes(pdf_bytes)
    return pdf_path
