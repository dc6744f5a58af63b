"""The accelerometer's Gamma scale beside the diagnosis (gap.diagnose.accel_calibration,
accel_warnings): read on the shipped accelerometer run, absent without a channel, one
warning line for a channel that cannot be read, and the rule of the warnings."""

from __future__ import annotations

import shutil
import subprocess
from pathlib import Path

import pytest
import yaml

from bouncelab.gap.diagnose import accel_calibration, accel_fixed, accel_warnings
from bouncelab.runs import load_run

REPO = Path(__file__).resolve().parents[2]


def test_the_shipped_accelerometer_run_reads_its_true_scale():
    # reference: raw/accel_g2-4 was made by the rig with gamma_scale 1 (config/rig); its
    # armature moves each step's reading by about 1 %, so 2 % is the tolerance
    accel, notes = accel_calibration(load_run(REPO / "raw" / "accel_g2-4"))
    assert notes == []
    assert abs(accel["s"] - 1.0) < 0.02
    assert accel["s_ci"][0] <= 1.0 <= accel["s_ci"][1]
    assert accel["n_steps"] == 5 and len(accel["by_step"]["gamma_accel"]) == 5
    assert accel["harmonics"] == []  # the rig's drive there has none


def test_no_accel_channel_no_calibration():
    assert accel_calibration(load_run(REPO / "raw" / "sweep_g0-8")) == (None, [])


def test_an_unreadable_accel_channel_is_one_warning_and_leaves_raw_alone(tmp_path):
    run_dir = tmp_path / "broken_accel"
    shutil.copytree(REPO / "raw" / "accel_g2-4", run_dir)
    spec = yaml.safe_load((run_dir / "run.yaml").read_text())
    spec["channels"]["accel"] = 7  # the file has three channels
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec))
    before = {p.name: p.read_bytes() for p in run_dir.iterdir()}
    accel, notes = accel_calibration(load_run(run_dir))
    assert accel is None
    assert len(notes) == 1 and notes[0].startswith("accelerometer not read:")
    assert "recording.flac" in notes[0] or "run.yaml" in notes[0]
    assert {p.name: p.read_bytes() for p in run_dir.iterdir()} == before


def _accel(s, lo, hi, harmonics=()):
    return {
        "s": s, "s_ci": [lo, hi], "ratio_min": lo, "ratio_max": hi, "n_steps": 5,
        "harmonics": list(harmonics),
    }  # fmt: skip


def _result(selected, s=None, **params):
    if s is not None:
        params["s"] = s
    return {"selected": selected, "final_model": {"model": "+".join(selected), "params": params}}


H3 = {"k": 3, "a": 0.08, "a_ci": [0.079, 0.081], "psi": 1.0}
H2_WEAK = {"k": 2, "a": 0.012, "a_ci": [0.011, 0.013], "psi": 4.0}
ARM = {"f_ratio": 0.6, "zeta": 0.04, "rms_ratio": 3.0}
ARM_READ = {"armature": ARM | {"read": True}}
ARM_NOT_READ = {"armature": ARM | {"read": False, "rms_ratio": 1.1}}


def _feedback(f_ratio, zeta):
    return _result(["feedback"], f_ratio=f_ratio, zeta=zeta, mass_ratio=0.04, ride_load=1.0)


@pytest.mark.parametrize(
    ("accel", "result", "warned"),
    [
        (None, _result([]), False),
        # no gamma_scale selected: a reading 1 - 7 % off warns, 1 + 2 % does not
        (_accel(0.93, 0.925, 0.935), _result(["friction"]), True),
        (_accel(1.02, 1.015, 1.025), _result(["friction"]), False),
        # 1 inside the interval: the steps disagree too much to say
        (_accel(0.95, 0.90, 1.01), _result([]), False),
        # a fitted gamma_scale near the reading, and one far from it
        (_accel(0.93, 0.925, 0.935), _result(["gamma_scale"], 0.94), False),
        (_accel(0.93, 0.925, 0.935), _result(["gamma_scale"], 1.05), True),
        # with the armature selected the plate's own motion differs per step: no warning
        # within 10 %, one beyond (a gamma_scale standing in for another effect)
        (_accel(0.93, 0.925, 0.935), _result(["restitution", "feedback"]), False),
        (_accel(1.0, 0.99, 1.01), _result(["feedback", "gamma_scale"], 1.08), False),
        (_accel(1.0, 0.99, 1.01), _result(["feedback", "gamma_scale"], 1.15), True),
        # a harmonic read at a 0.08 and none selected; a weak one (0.012) only listed
        (_accel(1.0, 0.99, 1.01, [H3]), _result(["friction"], mu=0.2), True),
        (_accel(1.0, 0.99, 1.01, [H2_WEAK]), _result(["friction"], mu=0.2), False),
        # the fitted harmonic at the read one, at another k, and 50 % off in a
        (_accel(1.0, 0.99, 1.01, [H3]), _result(["harmonic"], k=3.0, a=0.085, psi=1.0), False),
        (_accel(1.0, 0.99, 1.01, [H3]), _result(["harmonic"], k=2.0, a=0.2, psi=1.6), True),
        (_accel(1.0, 0.99, 1.01, [H3]), _result(["harmonic"], k=3.0, a=0.04, psi=1.0), True),
        # a half-integer k is not among the accelerometer's harmonics: nothing to compare
        (_accel(1.0, 0.99, 1.01, [H3]), _result(["harmonic"], k=2.5, a=0.1, psi=1.0), False),
        # nor is one on the mains hum (k 2 at a 25 Hz drive)
        (
            _accel(1.0, 0.99, 1.01, [H3]) | {"harmonics_on_hum": [2]},
            _result(["harmonic"], k=2.0, a=0.2, psi=1.6),
            False,
        ),
        # the armature's ring read and no feedback selected; not read: nothing to say
        (_accel(1.0, 0.99, 1.01) | ARM_READ, _result(["restitution"], e=0.5), True),
        (_accel(1.0, 0.99, 1.01) | ARM_NOT_READ, _result(["restitution"], e=0.5), False),
        # feedback fitted near the reading (f_ratio 2 %, zeta 25 % off), zeta 2.2 times
        # the reading, f_ratio 17 % off; and a plate reading off 1 stays silent beside it
        (_accel(1.0, 0.99, 1.01) | ARM_READ, _feedback(0.61, 0.05), False),
        (_accel(1.0, 0.99, 1.01) | ARM_READ, _feedback(0.61, 0.09), True),
        (_accel(1.0, 0.99, 1.01) | ARM_READ, _feedback(0.7, 0.04), True),
        (_accel(0.93, 0.925, 0.935) | ARM_READ, _feedback(0.6, 0.04), False),
    ],
)
def test_accel_warnings(accel, result, warned):
    out = accel_warnings(accel, result)
    assert len(out) == int(warned)
    if warned:
        assert "accelerometer reads" in out[0]


def test_a_harmonic_fitted_at_another_k_names_the_one_read():
    (line,) = accel_warnings(
        _accel(1.0, 0.99, 1.01, [H3]), _result(["harmonic"], k=2.0, a=0.2, psi=1.6)
    )
    assert line.startswith("harmonic k = 2, a = 0.2 fitted, but the accelerometer reads none")
    assert line.endswith("it reads k = 3, a = 0.08 [0.079, 0.081], psi = 1")


def test_fix_accel_holds_the_scale_and_the_strongest_harmonic():
    assert accel_fixed(_accel(0.97, 0.96, 0.98)) == {"s": 0.97}
    assert accel_fixed(_accel(0.97, 0.96, 0.98, [H3, H2_WEAK])) == {
        "s": 0.97, "k": 3.0, "a": 0.08, "psi": 1.0,
    }  # fmt: skip


def test_fix_accel_holds_the_armature_only_where_its_ring_is_read():
    assert accel_fixed(_accel(0.97, 0.96, 0.98, [H3]) | ARM_READ) == {
        "s": 0.97, "f_ratio": 0.6, "zeta": 0.04, "k": 3.0, "a": 0.08, "psi": 1.0,
    }  # fmt: skip
    assert accel_fixed(_accel(0.97, 0.96, 0.98) | ARM_NOT_READ) == {"s": 0.97}


def test_a_zeta_far_from_the_reading_names_both():
    (line,) = accel_warnings(
        _accel(1.0, 0.99, 1.01) | ARM_READ,
        _feedback(0.61, 0.09),
    )
    assert (
        line
        == "feedback zeta = 0.09 fitted, but the accelerometer reads f_ratio = 0.6, zeta = 0.04"
    )


def test_with_the_flights_the_shipped_run_reads_its_armature_too():
    # reference: config/rig/accel_g2-4.yaml, an 18 Hz armature at a 35 Hz drive
    from bouncelab.flights import extract_run

    run_dir = REPO / "raw" / "accel_g2-4"
    flights, _qc = extract_run(run_dir)
    accel, notes = accel_calibration(load_run(run_dir), flights)
    assert notes == [] and accel["armature"]["read"]
    assert abs(accel["armature"]["f_ratio"] - 18.0 / 35.0) < 0.01 * 18.0 / 35.0
    assert "armature" not in accel_calibration(load_run(run_dir))[0]  # not without flights


@pytest.fixture(scope="module")
def miscalibrated_run(tmp_path_factory):
    """A short rig run whose plate moves at 1.07 x the stated Gamma, rigid shaker, with an
    accelerometer (reference: the rig's gamma_scale)."""
    from bouncelab.rig import run_rig

    root = tmp_path_factory.mktemp("accel_fix")
    cfg = {
        "kind": "sweep",
        "seed": 21,
        "body": {"friction_mu": 0.0, "restitution": 0.0},
        "drive": {"frequency_hz": 28.0, "gamma_scale": 1.07},
        "shaker": {"feedback": False},
        "protocol": {"gammas": [1.2, 1.6, 2.0, 2.4, 2.8, 3.2], "cycles_per_step": 30},
        "sensors": {"accel": {"enabled": True}},
    }
    (root / "c.yaml").write_text(yaml.safe_dump(cfg))
    run_rig(root / "c.yaml", root / "run", root / "truth.parquet")
    return root / "run"


def test_fix_accel_holds_s_at_the_reading(miscalibrated_run):
    from bouncelab.gap.diagnose import diagnose_run
    from bouncelab.gap.fit import FitSettings

    # what is held does not depend on the search's budget: a small one (a tenth of the time)
    small = FitSettings(popsize=4, maxiter=4, local_evals=4, n_boot=50)
    d = diagnose_run(miscalibrated_run, fix_accel=True, retries=0, fit_settings=small)
    accel = d["accel_calibration"]
    assert accel["fixed"] is True
    assert abs(accel["s"] - 1.07) < 0.01 * 1.07  # the reading, against the rig's truth
    assert d["design"]["fixed"] == {"s": accel["s"]}
    (candidate,) = [c for c in d["candidates"] if c["effect"] == "gamma_scale"]
    assert candidate["params"]["s"] == accel["s"]  # held, not fitted
    assert not any("accelerometer" in w for w in d["input_warnings"])


def test_fix_accel_without_an_accelerometer_is_one_error(tmp_path):
    out = tmp_path / "d.json"
    proc = subprocess.run(
        ["bouncelab", "diagnose", str(REPO / "raw" / "sweep_g0-8"), "-o", str(out),
         "--fix-accel"],
        capture_output=True, text=True, check=False,
    )  # fmt: skip
    assert proc.returncode != 0 and not out.exists()
    (line,) = proc.stderr.strip().splitlines()
    assert line.startswith("error: ") and "sweep_g0-8" in line and "accel" in line


def test_a_run_at_25_hz_writes_strict_json(tmp_path):
    """At a 25 Hz drive the second harmonic falls on the 50 Hz hum: it is not read, its
    per-step values are null in the JSON (strict: no NaN), and the clash is named."""
    import json

    from bouncelab.rig import run_rig

    cfg = {
        "kind": "sweep", "seed": 22, "drive": {"frequency_hz": 25.0},
        "shaker": {"feedback": False},
        "protocol": {"gammas": [1.5, 2.5], "cycles_per_step": 30},
        "sensors": {"accel": {"enabled": True}},
    }  # fmt: skip
    (tmp_path / "c.yaml").write_text(yaml.safe_dump(cfg))
    run_rig(tmp_path / "c.yaml", tmp_path / "run", tmp_path / "truth.parquet")
    accel, notes = accel_calibration(load_run(tmp_path / "run"))
    assert notes == [] and accel["harmonics_on_hum"] == [2] and accel["harmonics"] == []
    assert accel["by_step"]["a2"] == [None, None]
    json.dumps(accel, allow_nan=False)
