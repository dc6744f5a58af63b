"""A "flight" far longer than a body can fly (the circuit open: a lead off) is warned of
by the extraction, kept in its table, and left out of the diagnosis, which it once
stopped with an unnamed error ("data flight table has negative steps or T >= 512";
a black-box probe's 3-s open stretch, T 565 rad). The diagnosis is a stand-in here
(a real one needs minutes): what is tested is what it is given and what it says."""

from __future__ import annotations

import numpy as np
import pandas as pd

from bouncelab.flights.extract import OVERLONG_T_RAD, overlong_flights
from bouncelab.tables import read_table, write_table


def with_open_stretch(path, tmp_path):
    """The flight table at ``path`` with one flight stretched to 3 s (T about 565 rad at
    30 Hz), written beside it; returns the new path and the table."""
    table = read_table(path)
    i = len(table) // 2
    table.loc[i, "T"] = 3.0 * 2 * np.pi * 30.0
    table.loc[i, "flight_s"] = 3.0
    return write_table(table, tmp_path / "open.parquet"), table


def test_an_overlong_flight_is_left_out_with_a_warning_naming_the_table(null_run, given, tmp_path):
    from bouncelab.gap.diagnose import diagnose_run

    run_dir, flights = null_run
    n = len(read_table(flights))
    path, table = with_open_stretch(flights, tmp_path)
    assert overlong_flights(table).sum() == 1
    r = diagnose_run(run_dir, flights=path, retries=0, progress=False)
    assert given["n"] == n - 1 and given["max_T"] < OVERLONG_T_RAD
    lines = [w for w in r["input_warnings"] if "longer than 41 drive periods" in w]
    assert len(lines) == 1 and str(path) in lines[0] and "left out of the diagnosis" in lines[0]
    assert lines[0] in r["warnings"]


def test_the_extraction_warns_and_the_diagnosis_does_not_repeat_it(null_run, given, tmp_path):
    """The line the extraction logged (kept in the QC table) is said once."""
    from bouncelab.flights.extract import OVERLONG_LINE, overlong_line
    from bouncelab.gap.diagnose import without_overlong

    _, flights = null_run
    _, table = with_open_stretch(flights, tmp_path)
    qc = pd.DataFrame({"step": [0]})
    qc.attrs["warnings"] = [f"rec.flac: {overlong_line(table, overlong_flights(table))}"]
    kept, lines = without_overlong(table, qc, "run")
    assert len(kept) == len(table) - 1 and lines == []
    assert OVERLONG_LINE in qc.attrs["warnings"][0]
    kept, lines = without_overlong(table, None, "run")
    assert len(lines) == 1 and lines[0].startswith("run: 1 flight(s) longer than")
    again, lines = without_overlong(kept, None, "run")
    assert again is kept and lines == []
    drop = pd.DataFrame({"T": [np.nan, np.nan]})  # a drop run's table: no drive, no T
    assert not overlong_flights(drop).any()
