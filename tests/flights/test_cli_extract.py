"""`bouncelab extract` through the CLI: outputs, QC beside them, and bad input (one line)."""

import hashlib

import numpy as np
import pandas as pd
import pytest
from flights_synth import bouncing_contacts, continuity, write_npz_run

from bouncelab.cli import main
from bouncelab.flights import FLIGHT_COLUMNS
from bouncelab.tables import read_table

SWEEP = {"kind": "sweep", "drive_frequency_hz": 30.0}


def folder_hash(folder):
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        if p.is_file():
            h.update(p.name.encode() + p.read_bytes())
    return h.hexdigest()


def one_error_line(capsys):
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error:"), err
    return err[0]


@pytest.mark.parametrize("suffix", [".parquet", ".csv"])
def test_extract_writes_table_and_qc(tmp_path, suffix):
    """Synthetic sweep (no drive channel): CONTRACTS columns, NaN phases, QC beside it."""
    c = bouncing_contacts(4.0, seed=7)
    x, _ = continuity(c, 4.0, tau_s=25e-6, noise_v=0.01, seed=8)
    run = write_npz_run(
        tmp_path / "r1",
        {"continuity": x},
        gamma_steps=[{"t_s": 0.0, "gamma": 3.0}, {"t_s": 2.0, "gamma": 3.5}],
        **SWEEP,
    )
    before = folder_hash(run)
    out = tmp_path / "out" / f"flights{suffix}"
    assert main(["extract", str(run), "-o", str(out)]) == 0
    assert folder_hash(run) == before
    f = read_table(out)
    qc = read_table(out.with_name(f"flights.qc{suffix}"))
    assert list(f.columns[: len(FLIGHT_COLUMNS)]) == FLIGHT_COLUMNS
    assert len(f) == len(c) - 1  # every flight between the contacts of the truth
    assert f["phi_takeoff"].isna().all()
    assert list(qc["step"]) == [0, 1] and qc["flights"].sum() == len(f)
    assert (f["run"] == "r1").all()


def test_all_gamma_below_one_gives_no_flights(tmp_path):
    rng = np.random.default_rng(1)
    x = 0.01 * rng.standard_normal(40_000)  # resting in contact all along
    run = write_npz_run(
        tmp_path / "rest",
        {"continuity": x},
        gamma_steps=[{"t_s": 0.0, "gamma": 0.0}, {"t_s": 1.0, "gamma": 0.8}],
        **SWEEP,
    )
    out = tmp_path / "f.csv"
    assert main(["extract", str(run), "-o", str(out)]) == 0
    assert len(pd.read_csv(out)) == 0


def test_no_contacts_found(tmp_path, capsys):
    rng = np.random.default_rng(2)
    x = 5.0 + 0.01 * rng.standard_normal(40_000)
    run = write_npz_run(
        tmp_path / "flat", {"continuity": x}, gamma_steps=[{"t_s": 0.0, "gamma": 2.0}], **SWEEP
    )
    assert main(["extract", str(run), "-o", str(tmp_path / "f.csv")]) == 2
    line = one_error_line(capsys)
    assert "no contacts found" in line and "rec.npz" in line


def test_stuck_rail(tmp_path, capsys):
    run = write_npz_run(
        tmp_path / "stuck",
        {"continuity": np.full(40_000, 10.0)},
        gamma_steps=[{"t_s": 0.0, "gamma": 2.0}],
        **SWEEP,
    )
    assert main(["extract", str(run), "-o", str(tmp_path / "f.csv")]) == 2
    line = one_error_line(capsys)
    assert "stuck at one rail" in line and "rec.npz" in line


def test_reader_errors_pass_through(tmp_path, capsys):
    """Whatever bouncelab.runs rejects (here NaN samples) is one line naming the file."""
    x = np.zeros(1000)
    x[10] = np.nan
    run = write_npz_run(
        tmp_path / "nan", {"continuity": x}, gamma_steps=[{"t_s": 0.0, "gamma": 2.0}], **SWEEP
    )
    assert main(["extract", str(run), "-o", str(tmp_path / "f.csv")]) == 2
    assert "rec.npz" in one_error_line(capsys)


def test_refuses_to_write_into_run_folder_and_bad_suffix(tmp_path, capsys):
    c = bouncing_contacts(1.0, seed=7)
    x, _ = continuity(c, 1.0, seed=8)
    run = write_npz_run(
        tmp_path / "r2", {"continuity": x}, gamma_steps=[{"t_s": 0.0, "gamma": 3.0}], **SWEEP
    )
    before = folder_hash(run)
    assert main(["extract", str(run), "-o", str(run / "f.csv")]) == 2
    assert "run folder" in one_error_line(capsys)
    assert main(["extract", str(run), "-o", str(tmp_path / "f.txt")]) == 2
    assert ".parquet or .csv" in one_error_line(capsys)
    assert folder_hash(run) == before
