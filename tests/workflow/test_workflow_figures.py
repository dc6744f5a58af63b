"""Every figure the workflow draws against its committed baseline image.

A changed figure fails with the difference image saved under tests/_failed_figures/
(ignored by git). After an intended change, regenerate the baselines with

    BOUNCELAB_UPDATE_BASELINES=1 pytest tests/workflow/test_workflow_figures.py

and commit tests/baseline/figures/. Tolerance: RMS difference of 2 (0-255 scale), which
absorbs antialiasing noise but not a moved point, line or label.
"""

from __future__ import annotations

import os
import shutil
from pathlib import Path

import pytest
from matplotlib.testing.compare import compare_images

from .conftest import REPO

BASELINES = REPO / "tests" / "baseline" / "figures"
FAILED = REPO / "tests" / "_failed_figures"
TOLERANCE = 2.0


def figure_pngs(workflow_dir: Path) -> list[Path]:
    root = workflow_dir / "results" / "figures"
    return sorted(root.rglob("*.png"))


def test_every_figure_matches_its_baseline(workflow_dir):
    root = workflow_dir / "results" / "figures"
    pngs = figure_pngs(workflow_dir)
    assert pngs, "the workflow drew no figure"
    if os.environ.get("BOUNCELAB_UPDATE_BASELINES") == "1":
        shutil.rmtree(BASELINES, ignore_errors=True)
        for png in pngs:
            dest = BASELINES / png.relative_to(root)
            dest.parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(png, dest)
        pytest.skip(f"baselines rewritten: {len(pngs)} figures")
    problems = []
    for png in pngs:
        rel = png.relative_to(root)
        base = BASELINES / rel
        if not base.is_file():
            problems.append(f"{rel}: no baseline (run with BOUNCELAB_UPDATE_BASELINES=1)")
            continue
        out = FAILED / rel
        out.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(png, out)
        result = compare_images(str(base), str(out), tol=TOLERANCE, in_decorator=True)
        if result is None:
            out.unlink()
            continue
        problems.append(f"{rel}: RMS {result['rms']:.2f} > {TOLERANCE}; diff in {result['diff']}")
    stale = {p.relative_to(BASELINES) for p in BASELINES.rglob("*.png")} - {
        p.relative_to(root) for p in pngs
    }
    problems += [f"{rel}: baseline without a figure" for rel in sorted(stale)]
    assert not problems, "\n".join(problems)
