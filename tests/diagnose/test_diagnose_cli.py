"""``bouncelab diagnose``: bad input gives one error line (exit 2), a good run writes the
JSON of CONTRACTS.md section 6 and leaves the run folder untouched; the result is
deterministic."""

from __future__ import annotations

import hashlib
import json

import pandas as pd
import pytest
from diag_synth import duration_s, pseudo_flights, write_run

from bouncelab.cli import main
from bouncelab.gap.diagnose import diagnose_flights
from bouncelab.gap.fit import FitSettings
from bouncelab.physics import Model
from bouncelab.runs import load_run
from bouncelab.tables import write_table

FAST = FitSettings(popsize=4, maxiter=4, local_evals=4, n_boot=50)


def _tree_hash(folder):
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(p.name.encode() + p.read_bytes())
    return h.hexdigest()


@pytest.fixture(scope="module")
def null_case(tmp_path_factory):
    root = tmp_path_factory.mktemp("cli")
    run_dir = write_run(root)
    flights = pseudo_flights(run_dir, Model.parse("ideal"), seed=3)
    path = write_table(flights, root / "flights.parquet")
    return run_dir, path


@pytest.mark.parametrize(
    "extra, message",
    [
        (["-o", "out.txt"], "must end in .json"),
        (["-o", "o.json", "--fix-calibration"], "needs --calibration"),
        (["-o", "o.json", "--baseline", "wobble"], "unknown model effect"),
        (["-o", "o.json", "--calibration", "missing.json"], "calibration file not found"),
    ],
)
def test_bad_input_one_line(null_case, tmp_path, capsys, extra, message, monkeypatch):
    run_dir, flights = null_case
    monkeypatch.chdir(tmp_path)
    code = main(["diagnose", str(run_dir), "--flights", str(flights), *extra])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and err[0].startswith("error:") and message in err[0]


def test_output_under_run_folder_refused(null_case, capsys):
    run_dir, flights = null_case
    code = main(
        ["diagnose", str(run_dir), "--flights", str(flights), "-o", str(run_dir / "d.json")]
    )
    assert code == 2
    assert "under the run folder" in capsys.readouterr().err


def test_flights_of_another_run_refused(null_case, tmp_path, capsys):
    run_dir, flights = null_case
    from bouncelab.tables import read_table

    other = read_table(flights)
    other["run"] = "someone_else"
    bad = write_table(other, tmp_path / "other.csv")
    code = main(["diagnose", str(run_dir), "--flights", str(bad), "-o", str(tmp_path / "d.json")])
    assert code == 2
    assert "other.csv" in capsys.readouterr().err


def test_cli_writes_contract_json(null_case, tmp_path, monkeypatch, capsys):
    """End to end on pseudo-data of the ideal model (with the small test budget): the null
    (truth: no effect) selects nothing; the run folder's bytes do not change."""
    import bouncelab.gap.diagnose as diag

    monkeypatch.setattr(diag, "FitSettings", lambda: FAST)
    run_dir, flights = null_case
    before = _tree_hash(run_dir)
    out = tmp_path / "diag.json"
    code = main(
        ["diagnose", str(run_dir), "--flights", str(flights), "-o", str(out), "--workers", "1",
         "--timings"]
    )  # fmt: skip
    assert code == 0
    r = json.loads(out.read_text())
    assert r["run"] == "pseudo" and r["selected"] == [] and r["unexplained"] is False
    assert len(r["candidates"]) == 5
    # the work reported counts every fit: at least the rounds' (the baseline's besides)
    work = r["design"]["work"]["flights"]
    assert work > sum(c["flights"] for tried in r["rounds"] for c in tried) > 0
    assert _tree_hash(run_dir) == before
    # --timings: the whole call, each seed's diagnosis (one: explained), the fits by stage
    t = r["timings"]
    assert [d["seed"] for d in t["diagnoses"]] == [0]
    assert t["total_s"] >= t["read_s"] + t["diagnoses"][0]["total_s"]
    assert sum(s["seconds"] for s in t["stages"].values()) <= t["diagnoses"][0]["total_s"]
    assert list(t["stages"])[:2] == ["baseline", "round 1"]
    assert sum(s["fits"] for s in t["stages"].values()) == len(t["fits"]) > 5
    assert sum(f["flights"] for f in t["fits"]) <= work
    # each fit's log says what it reached: round 1's kept fits are the ones it reports
    logged = [f for f in t["fits"] if f["stage"] == "round 1"]
    for c in r["rounds"][0]:
        assert any(
            f["model"] == c["model"] and f["heldout_gap"] == c["gap"] and f["params"] == c["params"]
            for f in logged
        ), c["model"]
    last = capsys.readouterr().err.strip().splitlines()[-1]
    assert last.startswith("time: ") and "seed 0 " in last and "round 1 " in last


def test_deterministic_and_calibration_fixed(null_case):
    """Same inputs, same dict; with --fix-calibration the friction candidate's mu is the
    calibration's (0.05), not fitted, and the calibration is reported beside it."""
    run_dir, flights_path = null_case
    from bouncelab.tables import read_table

    flights = read_table(flights_path)
    run = load_run(run_dir)
    cal = {"mu": 0.05, "restitution": 0.3, "run": "drop_a"}
    kw = {"seed": 0, "fit_settings": FAST, "workers": 1, "progress": False}
    a = diagnose_flights(run, flights, duration_s(), calibration=cal, fix_calibration=True, **kw)
    b = diagnose_flights(run, flights, duration_s(), calibration=cal, fix_calibration=True, **kw)
    assert json.dumps(a) == json.dumps(b)
    fric = next(c for c in a["candidates"] if c["effect"] == "friction")
    assert fric["params"]["mu"] == 0.05
    rest = next(c for c in a["candidates"] if c["effect"] == "restitution")
    assert rest["params"]["e"] == 0.3
    assert a["calibration"]["fixed"] is True and a["calibration"]["mu"] == 0.05
    assert a["calibration"]["run"] == "drop_a"  # whose calibration, for the report


def test_a_drive_channel_off_the_stated_frequency_is_a_warning(
    null_case, tmp_path, monkeypatch, capsys
):
    """The QC table that ``extract`` writes beside the flights holds the drive channel's
    measured frequency; 5 % off run.yaml's, the diagnosis says so first among its warnings,
    apart in ``input_warnings``, and on stderr as a ``warning:`` line (the diagnosis of a
    run.yaml copied from another run is of another experiment; docs/flights.md)."""
    import bouncelab.gap.diagnose as diag
    from bouncelab.tables import read_table

    monkeypatch.setattr(diag, "FitSettings", lambda: FAST)
    run_dir, flights = null_case
    stated = load_run(run_dir).drive_frequency_hz
    copied = write_table(read_table(flights), tmp_path / "flights.parquet")
    qc = {"step": [0, 1, 2], "drive_frequency_hz": [float("nan"), 1.05 * stated, 1.05 * stated]}
    write_table(pd.DataFrame(qc), tmp_path / "flights.qc.parquet")
    out = tmp_path / "diag.json"
    args = ["diagnose", str(run_dir), "--flights", str(copied), "-o", str(out), "--workers", "1"]
    assert main(args) == 0
    r = json.loads(out.read_text())
    (warning,) = r["input_warnings"]
    assert r["warnings"][0] == warning
    assert f"runs at {1.05 * stated:.3f} Hz (median over 2 steps), +5.0 %" in warning
    assert f"warning: {warning}" in capsys.readouterr().err.splitlines()


def test_each_input_warning_is_printed_once(null_case, tmp_path, monkeypatch, capsys):
    """A warning the extraction logged (printed then, as logging does) is not printed
    again among the final ``warning:`` lines; one it did not log (the drive check's) is.
    Scripted diagnosis: the terminal's lines are what is tested."""
    import logging

    from bouncelab.gap import diagnose

    logged = "rec.wav: 3 takeoff(s) from rest while the plate pushed the body up"
    drive = "run.yaml: the drive channel runs at 30.300 Hz, +1.0 % from drive_frequency_hz 30"

    def scripted(run_dir, **kwargs):
        logging.getLogger("bouncelab.flights.extract").warning(logged)
        gaps = {"baseline": {"gap": 0.1}, "final_gap": 0.1, "noise_floor": 0.1}
        return {"selected": [], "unexplained": False, "input_warnings": [drive, logged], **gaps}

    monkeypatch.setattr(diagnose, "diagnose_run", scripted)
    monkeypatch.setattr(logging.getLogger(), "handlers", [])  # stderr by logging itself
    run_dir, flights = null_case
    code = main(["diagnose", str(run_dir), "-o", str(tmp_path / "d.json")])
    err = capsys.readouterr().err
    assert code == 0
    assert err.count(logged) == 1 and f"warning: {drive}" in err
