"""Run the Snakemake workflow once per test session in a scratch copy of the project.

The copy holds the workflow's own files (Snakefile, workflow/, config/, report/,
profiles/) and a copy of raw/, so the checkout is never written. Every test of
tests/workflow shares this one run (the full pipeline over the shipped data), but for
the diagnosis of raw/sweep_g0-8: its config skips it (``diagnosis.skip``), since that one
job is about 40 % of the run (96 s of 233 on a fast hour, 336 s of 715 on a slow one;
docs/benchmarks.md). The other two sweeps' diagnoses run in full; the skipped one is run
by the main job and benchmarks/bench_pipeline.py.
"""

from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
WORKFLOW_PARTS = ("Snakefile", "workflow", "config", "report", "profiles")
#: Sweep runs the test projects do not diagnose (see the module's docstring).
SKIPPED_DIAGNOSES = ["sweep_g0-8"]


def skip_diagnoses(project: Path, runs: list[str]) -> None:
    """Set ``diagnosis.skip`` of a copied project's config/config.yaml to ``runs``."""
    path = project / "config" / "config.yaml"
    text = path.read_text()
    line = "  skip: []"
    assert text.count(line) == 1, "config/config.yaml lost its diagnosis.skip line"
    path.write_text(text.replace(line, f"  skip: [{', '.join(runs)}]"))


def copy_project(dest: Path, raw_runs: list[str] | None = None) -> Path:
    """Copy the workflow files and the chosen runs of raw/ (all by default) to ``dest``,
    with the diagnoses of :data:`SKIPPED_DIAGNOSES` skipped."""
    dest.mkdir(parents=True, exist_ok=True)
    for part in WORKFLOW_PARTS:
        src = REPO / part
        if src.is_dir():
            shutil.copytree(src, dest / part, ignore=shutil.ignore_patterns("__pycache__"))
        else:
            shutil.copy2(src, dest / part)
    (dest / "raw").mkdir()
    for run in (
        raw_runs if raw_runs is not None else sorted(p.name for p in (REPO / "raw").iterdir())
    ):
        shutil.copytree(REPO / "raw" / run, dest / "raw" / run)
    skip_diagnoses(dest, SKIPPED_DIAGNOSES)
    return dest


def snakemake(workdir: Path, *args: str, check: bool = True) -> subprocess.CompletedProcess:
    """Run snakemake in ``workdir`` (its profiles/default applies), capturing the output."""
    env = dict(os.environ, PYTHONHASHSEED="0")
    proc = subprocess.run(
        [sys.executable, "-m", "snakemake", "--cores", "2", *args],
        cwd=workdir,
        capture_output=True,
        text=True,
        env=env,
        check=False,
    )
    if check and proc.returncode != 0:
        raise AssertionError(
            f"snakemake {' '.join(args)} failed ({proc.returncode}):\n{proc.stdout[-4000:]}\n"
            f"{proc.stderr[-6000:]}"
        )
    return proc


def tree_hashes(folder: Path, suffixes=(".png", ".json", ".parquet")) -> dict[str, str]:
    """sha256 of every file with one of ``suffixes`` under ``folder``, by relative path."""
    return {
        str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
        for p in sorted(folder.rglob("*"))
        if p.is_file() and p.suffix in suffixes
    }


@pytest.fixture(scope="session")
def built_project(tmp_path_factory) -> tuple[Path, Path]:
    """A scratch project where `snakemake --cores 2` has run to completion, and an
    untouched copy of it (results and .snakemake/ included, times kept), from which
    :func:`project_copy` makes projects that start up to date."""
    raw_before = tree_hashes(
        REPO / "raw", suffixes=(".yaml", ".flac", ".wav", ".csv", ".npz", ".tdms")
    )
    root = tmp_path_factory.mktemp("workflow")
    work = copy_project(root / "project")
    snakemake(work)
    raw_after = tree_hashes(
        REPO / "raw", suffixes=(".yaml", ".flac", ".wav", ".csv", ".npz", ".tdms")
    )
    assert raw_before == raw_after, "the workflow modified raw/"
    pristine = root / "pristine"
    shutil.copytree(work, pristine, symlinks=True)  # copy2: modification times kept
    return work, pristine


@pytest.fixture(scope="session")
def workflow_dir(built_project) -> Path:
    """The built project the tests of tests/workflow share."""
    return built_project[0]


@pytest.fixture
def project_copy(built_project, tmp_path) -> Path:
    """A copy of the built project, as it was when built, for a test to change."""
    dest = tmp_path / "project"
    shutil.copytree(built_project[1], dest, symlinks=True)
    return dest
