"""The shipped data set in raw/: made by the rig, valid, small."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

ROOT = Path(__file__).resolve().parents[2]
CONFIGS = sorted((ROOT / "config" / "rig").glob("*.yaml"))


def test_every_config_has_its_run():
    names = {c.stem for c in CONFIGS}
    assert {"sweep_g0-4", "sweep_g0-8", "drop_test"} <= names
    for name in names:
        assert (ROOT / "raw" / name / "run.yaml").is_file(), name


def test_an_accelerometer_run_is_shipped():
    docs = [yaml.safe_load((ROOT / "raw" / c.stem / "run.yaml").read_text()) for c in CONFIGS]
    roles = [set(doc["channels"]) for doc in docs]
    assert {"continuity", "drive", "accel"} in roles


def test_raw_is_at_most_25_mb():
    total = sum(p.stat().st_size for p in (ROOT / "raw").rglob("*") if p.is_file())
    assert total <= 25 * 1024 * 1024, total


@pytest.mark.parametrize("cfg", CONFIGS, ids=[c.stem for c in CONFIGS])
def test_shipped_run_validates(cfg):
    from bouncelab.runs import load_run, validate_run

    run_dir = ROOT / "raw" / cfg.stem
    run = load_run(run_dir)
    assert run.source == "synthetic"
    validate_run(run_dir)


def test_sweep_g0_8_has_the_seed_gaps():
    """No step strictly inside Gamma 1.75-1.95 or 4.55-4.85 (seed section IV)."""
    doc = yaml.safe_load((ROOT / "raw" / "sweep_g0-8" / "run.yaml").read_text())
    gammas = [s["gamma"] for s in doc["gamma_steps"]]
    assert min(gammas) == 0.0 and max(gammas) == 8.0
    assert not [g for g in gammas if 1.75 < g < 1.95 or 4.55 < g < 4.85]
    assert 1.75 in gammas and 1.95 in gammas and 4.55 in gammas and 4.85 in gammas
