"""The early-stop measurement of ``benchmarks/bench_early_stop.py``: its counting of the
flights a stopped trial would save, and its hook on the fits' global search, which must
run the same search as :func:`bouncelab.gap.fit._global_search`."""

import sys
from pathlib import Path

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run

import bouncelab.gap.fit as fit
from bouncelab.gap.fit import FitSettings, FreeParam, _global_search
from bouncelab.physics import Model
from bouncelab.runs import load_run

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_early_stop import Recorder, savings, stop_point  # noqa: E402


def problem(n_entries=4, cap=10.0):
    """Four steps, one per protocol entry in order, all fitted, weights 1."""
    return {
        "n_entries": n_entries,
        "entry": np.arange(n_entries),
        "fit": np.ones(n_entries, dtype=bool),
        "weights": np.ones(n_entries),
        "cap": np.full(n_entries, cap),
    }


PER_ENTRY = np.array([1.0, 1.0, 1.0, 1.0])  # flights spread evenly: 25 a entry of 100


def test_a_trial_that_loses_on_its_first_step_stops_once_that_step_is_complete():
    """Objective = mean of the four gaps = sum / 4. The first step alone gives 2.0 / 4 =
    0.5 > the bound 0.4; with a margin of one entry it is known after two entries: the
    last two entries' 50 flights are saved."""
    saved, at = stop_point(problem(), np.array([2.0, 0, 0, 0]), PER_ENTRY, 100, 0.4, every=1)
    assert (saved, at) == (pytest.approx(50.0), 0.5)
    # without the margin the first entry suffices
    saved, at = stop_point(problem(), np.array([2.0, 0, 0, 0]), PER_ENTRY, 100, 0.4, 1, 0)
    assert (saved, at) == (pytest.approx(75.0), 0.25)
    # checks every two entries: the first check after entry 2, still one step complete
    saved, _ = stop_point(problem(), np.array([2.0, 0, 0, 0]), PER_ENTRY, 100, 0.4, every=2)
    assert saved == pytest.approx(50.0)


def test_a_trial_whose_gap_comes_last_or_that_wins_is_not_stopped():
    assert stop_point(problem(), np.array([0, 0, 0, 2.0]), PER_ENTRY, 100, 0.4, 1) == (0.0, 1.0)
    # a winner: its whole objective 0.25 is below its parent's 0.4
    assert stop_point(problem(), np.array([1.0, 0, 0, 0]), PER_ENTRY, 100, 0.4, 1) == (0.0, 1.0)


def test_gaps_count_clipped_and_held_out_steps_not_at_all():
    """The objective clips each step at its cap and reads the fit steps alone."""
    p = problem(cap=1.0)
    assert stop_point(p, np.array([5.0, 0, 0, 0]), PER_ENTRY, 100, 0.4, 1)[0] == 0.0
    p = problem()
    p["fit"][0] = False
    p["weights"] = np.ones(4)
    assert stop_point(p, np.array([5.0, 0, 0, 0]), PER_ENTRY, 100, 0.4, 1)[0] == 0.0


def test_savings_skip_the_first_population_and_count_only_trials_with_parents():
    rec = Recorder()
    rec.problems[1] = problem()
    losing = np.array([2.0, 0, 0, 0])  # objective 0.5
    rec.sims = [(1, PER_ENTRY, 100, losing, 1), (1, PER_ENTRY, 100, losing, 1)]
    # the first population (no parents yet), then a generation whose trial loses
    rec.generations = [(0, 1, None, np.array([0.5])), (1, 2, np.array([0.4]), np.array([0.5]))]
    s = savings(rec, 0.0)
    assert s["trials"] == 1 and s["trials_stopped"] == 1
    assert s["saved_share_of_flights"] == pytest.approx(50.0 / 200.0)
    assert s["de_share_of_flights"] == 1.0


class CountingEvaluator:
    """A stand-in for the fits' evaluator: a smooth objective, evaluated by population."""

    def __init__(self):
        self.n = 0

    def many(self, xs):
        self.n += len(xs)
        return [float(np.sum((np.asarray(x) - 0.3) ** 2)) for x in xs]

    def __call__(self, x):
        return self.many([x])[0]


def test_the_hooked_search_is_the_fits_search():
    """The benchmark's search (scipy's solver held to read the parents) returns the same
    point after the same evaluations as :func:`bouncelab.gap.fit._global_search`."""
    sub = [FreeParam("a", 0.0, 1.0), FreeParam("b", -1.0, 1.0)]

    def lift(z):
        return np.asarray(z, dtype=float)

    args = (sub, np.array([0.5, 0.0]), 6, 10, FitSettings(), 3)
    ev_fit, ev_hook = CountingEvaluator(), CountingEvaluator()
    x_fit = _global_search(ev_fit, lift, *args)
    x_hook = Recorder().global_search(ev_hook, lift, *args)
    np.testing.assert_array_equal(x_fit, x_hook)
    assert ev_fit.n == ev_hook.n


def test_the_hooks_record_every_evaluation_of_a_fit_and_leave_it_unchanged(tmp_path, monkeypatch):
    """With the benchmark's hooks on :mod:`bouncelab.gap.fit`, a small fit gives the same
    result, and the recorded evaluations add up to its flights, each generation after the
    first with its parents' objectives."""
    run_dir = write_run(tmp_path)
    flights = pseudo_flights(run_dir, Model.parse("restitution", {"e": 0.4}), seed=3)
    problem = fit.make_problem(load_run(run_dir), flights, duration_s(), n_members=2)
    settings = FitSettings(popsize=4, maxiter=3, local_evals=2)
    plain = fit.fit_model(problem, "restitution", settings=settings, seed=1)

    rec = Recorder()
    monkeypatch.setattr(fit, "counted_step_gaps", rec.counted_step_gaps)
    monkeypatch.setattr(fit, "protocol_flight_times", rec.protocol_flight_times)
    monkeypatch.setattr(fit, "_global_search", rec.global_search)
    hooked = fit.fit_model(problem, "restitution", settings=settings, seed=1)

    assert hooked.model.params == plain.model.params
    assert hooked.objective == plain.objective and hooked.flights == plain.flights
    assert sum(s[2] for s in rec.sims) == hooked.flights
    assert len(rec.generations) >= 2 and rec.generations[0][2] is None
    assert all(len(g[2]) == len(g[3]) for g in rec.generations[1:])
    s = savings(rec, 0.0)
    assert 0 < s["trials"] and 0.0 <= s["saved_share_of_flights"] < 1.0


def test_racing_stops_a_trial_that_trails_its_parent_early_even_if_it_would_win():
    """The racing rule compares the steps done with the parent's: a trial 0.3 behind
    after the first step (lead 0.1 of the parent's 0.4 allows 0.04) is stopped, although
    its whole objective 0.3 would beat the parent's 0.4: the rule is not exact."""
    trial = np.array([1.2, 0, 0, 0])  # objective 0.3
    parent = np.array([0.0, 0, 0, 1.6])  # objective 0.4
    assert stop_point(problem(), trial, PER_ENTRY, 100, 0.4, 1) == (0.0, 1.0)
    saved, at = stop_point(problem(), trial, PER_ENTRY, 100, 0.4, 1, parent=parent, lead=0.1)
    assert (saved, at) == (pytest.approx(50.0), 0.5)
    rec = Recorder()
    rec.problems[1] = problem()
    rec.sims = [(1, PER_ENTRY, 100, parent, 1), (1, PER_ENTRY, 100, trial, 1)]
    rec.generations = [(0, 1, None, np.array([0.4])), (1, 2, np.array([0.4]), np.array([0.3]))]
    s = savings(rec, 0.0, lead=0.1)
    assert (s["winners"], s["winners_stopped"]) == (1, 1)
    assert savings(rec, 0.0)["winners_stopped"] == 0


def test_playing_the_rule_drops_stopped_trials_from_the_cloud_and_keeps_the_best(
    tmp_path, monkeypatch
):
    """``Recorder(race_lead=...)`` plays the rule inside the search: a stopped trial loses
    and leaves the fit's cloud (a re-proposal is simulated again). With a lead too large
    to matter only the exact stops act: they lose anyway, so the fit's best is the same."""
    run_dir = write_run(tmp_path)
    flights = pseudo_flights(run_dir, Model.parse("restitution", {"e": 0.4}), seed=3)
    problem = fit.make_problem(load_run(run_dir), flights, duration_s(), n_members=2)
    settings = FitSettings(popsize=4, maxiter=3, local_evals=2)
    plain = fit.fit_model(problem, "restitution", settings=settings, seed=1)

    rec = Recorder(race_lead=1e9)
    monkeypatch.setattr(fit, "counted_step_gaps", rec.counted_step_gaps)
    monkeypatch.setattr(fit, "protocol_flight_times", rec.protocol_flight_times)
    monkeypatch.setattr(fit, "_global_search", rec.global_search)
    raced = fit.fit_model(problem, "restitution", settings=settings, seed=1)

    assert raced.model.params == plain.model.params and raced.objective == plain.objective
    assert rec.race_stopped > 0 and rec.race_saved > 0
    assert raced.n_evals == len(rec.sims) - rec.race_stopped
