"""Run the Snakemake workflow once per test session in a scratch copy of the project.

The copy holds the workflow's own files (Snakefile, workflow/, config/, report/,
profiles/) and a copy of raw/, so the checkout is never written. Every test of
tests/workflow shares this one run (the full pipeline over the shipped data).
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


def copy_project(dest: Path, raw_runs: list[str] | None = None) -> Path:
    """Copy the workflow files and the chosen runs of raw/ (all by default) to ``dest``."""
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
def workflow_dir(tmp_path_factory) -> Path:
    """A scratch project where `snakemake --cores 2` has run to completion."""
    raw_before = tree_hashes(
        REPO / "raw", suffixes=(".yaml", ".flac", ".wav", ".csv", ".npz", ".tdms")
    )
    work = copy_project(tmp_path_factory.mktemp("workflow") / "project")
    snakemake(work)
    raw_after = tree_hashes(
        REPO / "raw", suffixes=(".yaml", ".flac", ".wav", ".csv", ".npz", ".tdms")
    )
    assert raw_before == raw_after, "the workflow modified raw/"
    return work
