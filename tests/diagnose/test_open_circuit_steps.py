"""A Gamma step where the continuity circuit never closes (no flight, under 1 % of its
samples in contact: contacts too short to show, or a lead off) is simulated but not
compared. A black-box probe's generator, whose contacts last nothing where the plate
already pulls away at the landing, read no flight at true Gamma 3.3 and above: its
harmonic was not found and its Gamma miscalibration called unexplained until those
steps were left out. The diagnosis is a stand-in where a real one would take minutes:
what is tested is what it is given and what it says."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from bouncelab.gap.diagnose import OPEN_CIRCUIT_SHARE, open_circuit_steps
from bouncelab.tables import read_table, write_table


def qc_of(steps, gammas, shares) -> pd.DataFrame:
    return pd.DataFrame({"step": steps, "gamma": gammas, "contact_fraction": shares})


def test_only_a_moving_plates_step_open_throughout_and_without_flights_is_open():
    qc = qc_of([0, 1, 2, 3, 4], [0.5, 1.2, 3.0, 3.4, 3.8], [1.0, 0.4, 0.0, 0.0, 0.2])
    flights = pd.DataFrame({"step": [1, 1, 3]})
    # step 0: the body rests (circuit closed); 1, 3: flights; 4: closed a fifth of the time
    assert open_circuit_steps(qc, flights) == [2]
    qc.loc[4, "contact_fraction"] = 0.5 * OPEN_CIRCUIT_SHARE
    assert open_circuit_steps(qc, flights) == [2, 4]
    at_rest = qc_of([0], [0.0], [0.0])  # a plate at rest is not a step to compare anyway
    assert open_circuit_steps(at_rest, flights.iloc[:0]) == []
    assert open_circuit_steps(None, flights) == []
    assert open_circuit_steps(qc.drop(columns="contact_fraction"), flights) == []


def test_a_left_out_step_is_simulated_but_not_compared(tmp_path):
    from diag_synth import GAMMAS, duration_s, pseudo_flights, write_run

    from bouncelab.gap.fit import make_problem, step_gaps
    from bouncelab.physics import Model
    from bouncelab.runs import load_run

    run_dir = write_run(tmp_path)
    run = load_run(run_dir)
    flights = pseudo_flights(run_dir, Model.parse("ideal"), seed=3)
    top = int(np.argmax(GAMMAS))
    flights = flights[flights["step"] != top]
    whole = make_problem(run, flights, duration_s())
    cut = make_problem(run, flights, duration_s(), left_out_steps=[top])
    assert top in set(whole.steps["step"]) and top not in set(cut.steps["step"])
    assert len(cut.steps) == len(whole.steps) - 1
    pd.testing.assert_frame_equal(cut.protocol, whole.protocol)  # still simulated
    ideal = Model.parse("ideal")
    g_whole = step_gaps(whole, ideal)
    g_cut = step_gaps(cut, ideal)
    # the top step, without data, has the largest gap of the whole run's
    i_top = int(np.flatnonzero(whole.steps["step"].to_numpy() == top)[0])
    assert g_whole[i_top] == pytest.approx(np.max(g_whole))
    others = np.delete(g_whole, i_top)
    np.testing.assert_allclose(g_cut, others)


def test_the_diagnosis_leaves_out_the_open_steps_and_says_so(null_run, given, tmp_path):
    from bouncelab.flights.extract import qc_path_for
    from bouncelab.gap.diagnose import diagnose_run

    run_dir, flights = null_run
    table = read_table(flights)
    top = int(table["step"].max())
    gamma = float(table.loc[table["step"] == top, "gamma"].iloc[0])
    path = write_table(table[table["step"] != top], tmp_path / "f.parquet")
    steps = sorted(set(table["step"]))
    qc = qc_of(steps, [0.0] * len(steps), [0.3] * len(steps))
    qc["gamma"] = [float(table.loc[table["step"] == s, "gamma"].iloc[0]) for s in steps]
    qc.loc[qc["step"] == top, "contact_fraction"] = 0.0
    write_table(qc, qc_path_for(path))
    r = diagnose_run(run_dir, flights=path, retries=0, progress=False)
    assert given["left_out_steps"] == [top]
    assert r["left_out_steps"] == [{"step": top, "gamma": gamma}]
    (line,) = [w for w in r["input_warnings"] if "circuit open throughout" in w]
    assert line.startswith(f"{path}: 1 step(s)") and f"(Gamma {gamma:g})" in line
    # with the circuit closed now and then there, the step is compared
    qc.loc[qc["step"] == top, "contact_fraction"] = 0.2
    write_table(qc, qc_path_for(path))
    r = diagnose_run(run_dir, flights=path, retries=0, progress=False)
    assert given["left_out_steps"] == [] and r["left_out_steps"] == []


def test_too_few_steps_left_to_compare_says_why(tmp_path):
    from diag_synth import duration_s, pseudo_flights, write_run

    from bouncelab.errors import BouncelabError
    from bouncelab.gap.diagnose import diagnose_flights
    from bouncelab.physics import Model
    from bouncelab.runs import load_run

    gammas = [1.5, 2.0, 2.5]
    run_dir = write_run(tmp_path, gammas=gammas)
    flights = pseudo_flights(run_dir, Model.parse("ideal"), seed=3, gammas=gammas)
    with pytest.raises(BouncelabError, match=r"has 2 to compare \(1 left out: the circuit"):
        diagnose_flights(
            load_run(run_dir), flights, duration_s(gammas), left_out_steps=[2], progress=False
        )


def test_open_steps_are_compared_where_too_few_would_be_left(null_run, given, tmp_path):
    """Leaving them out must not refuse a run the diagnosis took before: with only two
    steps left to compare, every step is compared, and the warning says why."""
    from bouncelab.flights.extract import qc_path_for
    from bouncelab.gap.diagnose import diagnose_run

    run_dir, flights = null_run
    table = read_table(flights)
    steps = sorted(set(table["step"]))
    gammas = [float(table.loc[table["step"] == s, "gamma"].iloc[0]) for s in steps]
    dark = steps[2:]  # all but two
    path = write_table(table[~table["step"].isin(dark)], tmp_path / "f.parquet")
    qc = qc_of(steps, gammas, [0.0 if s in dark else 0.3 for s in steps])
    write_table(qc, qc_path_for(path))
    r = diagnose_run(run_dir, flights=path, retries=0, progress=False)
    assert given["left_out_steps"] == [] and r["left_out_steps"] == []
    (line,) = [w for w in r["input_warnings"] if "circuit open throughout" in w]
    assert line.endswith("so they are compared all the same")
