"""Bad input: one BouncelabError naming the file and the problem; CLI prints one line."""

from __future__ import annotations

import subprocess
import sys

import pytest

from bouncelab.errors import BouncelabError
from bouncelab.rig import load_rig_config, run_rig


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        ("kind: sweep\nbody: {mass: 1}\n", "body"),  # unknown key (typo)
        ("kind: bounce\n", "kind"),
        ("description: no kind\n", "kind"),
        ("kind: sweep\nprotocol: {gaps: [[2.0, 1.0]]}\n", "gaps"),
        ("kind: sweep\nprotocol: {gammas: [1.8], gaps: [[1.7, 1.9]]}\n", "gap"),
        ("kind: drop\nprotocol: {release_t_s: 3.0, duration_s: 2.0}\n", "release_t_s"),
        ("kind: sweep\nbody: {restitution: 1.5}\n", "restitution"),
        ("kind: [sweep\n", "YAML"),
        ("- 1\n- 2\n", "mapping"),
    ],
)
def test_bad_config(tmp_path, text, needle):
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(BouncelabError) as exc:
        load_rig_config(path)
    assert str(path) in str(exc.value) and needle in str(exc.value)


def test_missing_config(tmp_path):
    with pytest.raises(BouncelabError, match="not found"):
        load_rig_config(tmp_path / "nope.yaml")


def test_truth_inside_run_folder_is_refused(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("kind: drop\nprotocol: {release_t_s: 0.01, duration_s: 0.05}\n")
    with pytest.raises(BouncelabError, match="outside the run folder"):
        run_rig(cfg, tmp_path / "r1", tmp_path / "r1" / "truth.parquet")


def test_existing_folder_needs_force_and_other_files_are_kept(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("kind: drop\nprotocol: {release_t_s: 0.01, duration_s: 0.05}\n")
    run_rig(cfg, tmp_path / "r1")
    with pytest.raises(BouncelabError, match="--force"):
        run_rig(cfg, tmp_path / "r1")
    run_rig(cfg, tmp_path / "r1", force=True)
    (tmp_path / "r1" / "notes.txt").write_text("mine")
    with pytest.raises(BouncelabError, match="notes.txt"):
        run_rig(cfg, tmp_path / "r1", force=True)
    assert (tmp_path / "r1" / "notes.txt").read_text() == "mine"


def test_bad_run_id(tmp_path):
    cfg = tmp_path / "c.yaml"
    cfg.write_text("kind: drop\nprotocol: {release_t_s: 0.01, duration_s: 0.05}\n")
    with pytest.raises(BouncelabError, match="run folder name"):
        run_rig(cfg, tmp_path / "_bad id")


def test_cli_prints_one_error_line(tmp_path):
    path = tmp_path / "bad.yaml"
    path.write_text("kind: bounce\n")
    out = subprocess.run(
        [sys.executable, "-m", "bouncelab", "rig", str(path), "-o", str(tmp_path / "r")],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert out.returncode == 2
    lines = out.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and str(path) in lines[0]
    assert not (tmp_path / "r").exists()
