"""``--check-seeds``: the same run diagnosed with other seeds, and whether they agree
(:mod:`bouncelab.gap.seeds`)."""

from __future__ import annotations

import json

import pytest

from bouncelab.cli import main
from bouncelab.gap.seeds import majority_index, seed_check, seed_warning


def _result(seed, selected, unexplained=False, rel_gap=0.8, params=None):
    """The keys of a diagnosis that :func:`seed_check` reads."""
    return {
        "design": {"seed": seed},
        "selected": selected,
        "unexplained": unexplained,
        "final_rel_gap": rel_gap,
        "final_model": {"model": "+".join(selected) or "ideal", "params": params or {}},
    }


def test_seeds_that_agree():
    """The same effects in another order and the same verdict agree; each shared
    parameter's range spans the seeds' values."""
    check = seed_check(
        [
            _result(0, ["restitution", "friction"], params={"mu": 0.29, "e": 0.50}),
            _result(1, ["friction", "restitution"], params={"mu": 0.31, "e": 0.48}),
        ]
    )
    assert check["seeds"] == [0, 1]
    assert check["reported_seed"] == 0 and check["reported_share"] == [2, 2]
    assert check["sets_agree"] and check["verdicts_agree"] and check["agree"]
    assert check["params_range"] == {"e": [0.48, 0.50], "mu": [0.29, 0.31]}
    assert seed_warning(check) is None


def test_seeds_that_disagree_are_named():
    """Another set, or the same set with another verdict, is a disagreement; the warning
    names what each seed concluded, and only parameters every model has get a range."""
    check = seed_check(
        [
            _result(0, ["restitution", "harmonic", "friction"], params={"mu": 0.2, "a": 0.05}),
            _result(1, ["restitution", "feedback"], True, 3.5, params={"zeta": 0.1}),
            _result(2, ["restitution", "harmonic", "friction"], params={"mu": 0.21, "a": 0.04}),
        ]
    )
    assert not check["sets_agree"] and not check["verdicts_agree"] and not check["agree"]
    assert check["params_range"] == {}
    warning = seed_warning(check)
    assert "seed 0: restitution + harmonic + friction, explained" in warning
    assert "seed 1: restitution + feedback, unexplained" in warning
    assert check["reported_share"] == [2, 3]
    assert "seed 0's is reported, the conclusion of 2 of 3 seeds" in warning
    same_set = seed_check([_result(0, ["friction"]), _result(1, ["friction"], True)])
    assert same_set["sets_agree"] and not same_set["agree"]
    assert "seed 1: friction, unexplained" in seed_warning(same_set)


def test_one_diagnosis_agrees_with_itself_and_none_is_an_error():
    assert seed_check([_result(3, [])])["agree"]
    assert majority_index([_result(3, [])]) == 0
    with pytest.raises(ValueError):
        seed_check([])
    with pytest.raises(ValueError):
        majority_index([])


def test_the_reported_diagnosis_is_the_conclusion_most_seeds_reached():
    """The first diagnosis of the most common conclusion (effects in any order, and the
    verdict), whatever the gaps; between conclusions shared equally, the one with the
    least final held-out gap, then the one reached first."""
    a = ["restitution", "friction"]
    b = ["harmonic", "friction"]
    # a majority wins over a smaller gap
    assert majority_index([_result(0, b, rel_gap=0.1), _result(1, a), _result(2, a[::-1])]) == 1
    # all differ: the least gap (the frh seeds 1-3 of session 38), then the first
    frh = [_result(1, ["feedback", "restitution", "friction"], True, 3.15),
           _result(2, ["restitution", "harmonic", "friction"], False, 1.21),
           _result(3, ["feedback", "restitution"], True, 3.4)]  # fmt: skip
    assert majority_index(frh) == 1
    assert majority_index([_result(0, a), _result(1, b), _result(2, ["feedback"])]) == 0
    # two against two: the conclusion whose diagnoses reach the least gap, its first seed
    two_two = [_result(0, a, rel_gap=0.9), _result(1, b, rel_gap=1.0),
               _result(2, b, rel_gap=0.5), _result(3, a, rel_gap=0.8)]  # fmt: skip
    assert majority_index(two_two) == 1
    # the same effects with another verdict are another conclusion
    assert majority_index([_result(0, a, True), _result(1, a), _result(2, a)]) == 1


def test_cli_reports_the_majority_and_warns_when_seeds_differ(
    null_run, tmp_path, monkeypatch, capsys
):
    """The command's result is the diagnosis of the conclusion most seeds reached, with
    ``seed_check`` beside it; when the seeds disagree, the warning is in ``warnings`` and
    on stderr, and the summary line says so. The diagnoses are stand-ins here (a
    real lottery needs minutes): what is tested is the wiring."""
    import bouncelab.gap.diagnose as diag

    calls = []

    def fake(run, table, duration, *, seed, **kw):
        calls.append(seed)
        r = _result(seed, ["friction"] if seed == 5 else ["harmonic"])
        return {**r, "baseline": {"model": "ideal", "gap": 1.0}, "final_gap": 0.1,
                "noise_floor": 0.1, "warnings": []}  # fmt: skip

    monkeypatch.setattr(diag, "diagnose_flights", fake)
    run_dir, flights = null_run
    out = tmp_path / "d.json"
    args = ["diagnose", str(run_dir), "--flights", str(flights), "-o", str(out)]
    assert main([*args, "--seed", "5", "--check-seeds", "3"]) == 0
    assert calls == [5, 6, 7]
    r = json.loads(out.read_text())
    assert r["design"]["seed"] == 6 and r["selected"] == ["harmonic"]
    assert r["seed_check"]["reported_seed"] == 6
    assert r["seed_check"]["seeds"] == [5, 6, 7] and not r["seed_check"]["agree"]
    (warning,) = r["warnings"]
    err = capsys.readouterr().err.splitlines()
    assert f"warning: {warning}" in err
    assert err[-1].endswith("3 seeds disagree, seed 6's reported (2 of 3)")


def test_check_seeds_below_one_is_one_error_line(null_run, tmp_path, capsys):
    run_dir, flights = null_run
    out = tmp_path / "d.json"
    args = ["diagnose", str(run_dir), "--flights", str(flights), "-o", str(out)]
    assert main([*args, "--check-seeds", "0"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--check-seeds must be >= 1" in err[0]


def test_real_diagnoses_with_two_seeds(null_run):
    """Two real diagnoses (the small test budget) of a null run: the reported one is the
    plain diagnosis of the first seed (two seeds agree, or tie and the first is
    reported), the check holds both seeds' conclusions."""
    from bouncelab.gap.diagnose import diagnose_run
    from bouncelab.gap.fit import FitSettings

    run_dir, flights = null_run
    kw = {"flights": flights, "workers": 1, "progress": False}
    kw["fit_settings"] = FitSettings(popsize=4, maxiter=4, local_evals=4, n_boot=50)
    plain = diagnose_run(run_dir, **kw)
    checked = diagnose_run(run_dir, check_seeds=2, **kw)
    check = checked.pop("seed_check")
    assert json.dumps(checked) == json.dumps(plain)
    assert check["seeds"] == [0, 1]
    assert check["diagnoses"][0]["final_rel_gap"] == plain["final_rel_gap"]
    assert check["agree"] == (seed_warning(check) is None)


def test_replay_of_five_seed_records_counts_flags():
    """The benchmark that replays ``bench_blind_seeds.py``'s records as three-seed checks:
    a case right on every seed is never flagged; on a case wrong at seed 4 alone the
    checks that include seed 4 (first seeds 2, 3 and 4) are flagged, and each reports
    the other two's right conclusion, where one seed alone was wrong once."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
    from bench_seed_check import replay

    def row(ok):
        sel = ["friction"] if ok else ["harmonic"]
        return {"selected": sel, "unexplained": False, "set_right": ok, "verdict_right": ok}

    record = {
        "cases": {
            "steady": {"seeds": {str(s): row(True) for s in range(5)}},
            "lottery": {"seeds": {str(s): row(s != 4) for s in range(5)}},
        }
    }
    r = replay(record)
    assert (r["checks"], r["first_right"], r["reported_right"]) == (10, 9, 10)
    assert (r["wrong_flagged"], r["wrong_quiet"]) == (0, 0)
    assert (r["right_flagged"], r["right_quiet"]) == (3, 7)
    assert {(f["case"], f["first_seed"]) for f in r["flagged"]} == {
        ("lottery", 2),
        ("lottery", 3),
        ("lottery", 4),
    }


def test_with_a_progress_bar_each_seed_is_announced(null_run, monkeypatch, capsys):
    """Several whole diagnoses are a long wait: with progress shown, a line says which
    seed the fits' bars belong to."""
    import bouncelab.gap.diagnose as diag

    def fake(run, table, duration, *, seed, **kw):
        return {**_result(seed, []), "warnings": []}

    monkeypatch.setattr(diag, "diagnose_flights", fake)
    run_dir, flights = null_run
    diag.diagnose_run(run_dir, flights=flights, check_seeds=2, seed=4, progress=True)
    err = capsys.readouterr().err.splitlines()
    assert err == ["diagnosis with seed 4 (1 of 2)", "diagnosis with seed 5 (2 of 2)"]
    diag.diagnose_run(run_dir, flights=flights, check_seeds=2, progress=False)
    assert capsys.readouterr().err == ""
