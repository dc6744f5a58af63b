"""The harmonic read off the takeoff phases as a start of the fits (gap.takeoff_reading
``seen_harmonic``, gap.select ``read_starts``, gap.fit ``fit_model(starts=...)``)."""

from __future__ import annotations

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run
from test_fit_units import _OneStepProblem, script_selection, scripted_fit

from bouncelab.gap.fit import (
    K_CHOICES,
    FitSettings,
    encode,
    fit_model,
    make_problem,
)
from bouncelab.gap.select import read_starts
from bouncelab.gap.takeoff_reading import SEEN_AK2, SEEN_RATIO, seen_harmonic
from bouncelab.physics import Model
from bouncelab.runs import load_run

READ = {"k": 3.0, "a": 0.05, "psi": 1.0, "mu": 0.2}


def _reading(a: float, k: float, ratio: float) -> dict:
    best = {"k": k, "a": a, "psi": 1.0, "mu": 0.2, "rms_rad": 0.01}
    return {"n_steps": 20, "plain": {"mu": 0.3, "rms_rad": 0.01 * ratio}, "by_k": [best],
            "best": best}  # fmt: skip


@pytest.mark.parametrize(
    ("a_k2", "ratio", "seen"),
    [
        (SEEN_AK2 * 1.01, SEEN_RATIO * 1.01, True),
        (SEEN_AK2 * 0.99, SEEN_RATIO * 5, False),  # too weak a share of the acceleration
        (SEEN_AK2 * 5, SEEN_RATIO * 0.99, False),  # fits the takeoffs too little better
    ],
)
def test_a_harmonic_is_seen_only_when_strong_and_much_better_than_none(a_k2, ratio, seen):
    got = seen_harmonic(_reading(a_k2 / 9.0, 3.0, ratio))
    assert (got is not None) == seen
    if seen:
        assert got == pytest.approx({"k": 3.0, "a": a_k2 / 9.0, "psi": 1.0, "mu": 0.2})


def test_nothing_is_seen_on_a_run_with_too_few_steps_to_read():
    assert seen_harmonic({"n_steps": 3}) is None


def test_the_read_start_goes_to_models_with_the_harmonic_at_its_k():
    assert read_starts(None, "harmonic", {}) == []
    assert read_starts(READ, "restitution", {}) == []  # no harmonic in the model
    assert read_starts(READ, "harmonic", {"k": 2.0}) == []  # another k's split
    assert read_starts(READ, "harmonic", {"k": 3.0}) == [{"k": 3.0, "a": 0.05, "psi": 1.0}]
    # mu only where the model has friction
    assert read_starts(READ, "friction+harmonic", {}) == [READ]


@pytest.fixture(scope="module")
def harmonic_problem(tmp_path_factory):
    truth = Model.parse("harmonic", {"k": 3.0, "a": 0.05, "psi": 1.0})
    run_dir = write_run(tmp_path_factory.mktemp("hstart"), cycles=12)
    flights = pseudo_flights(run_dir, truth, seed=3, cycles=12)
    return make_problem(load_run(run_dir), flights, duration_s(cycles=12), n_members=2)


def test_a_fit_starts_from_the_read_point_only_where_it_does_better(harmonic_problem):
    """Both points are evaluated first (one evaluation each); the search then runs from
    the better one, so with a worse start it is the fit made without starts."""
    settings = FitSettings(popsize=2, maxiter=1, local_evals=1)
    fixed, base = {"k": 3.0}, {"a": 0.0, "psi": 0.0}  # no harmonic: the truth does better
    plain = fit_model(harmonic_problem, "harmonic", base, fixed=fixed, settings=settings, seed=2)
    truth = {"a": 0.05, "psi": 1.0}
    read = fit_model(harmonic_problem, "harmonic", base, fixed=fixed, settings=settings,
                     seed=2, starts=[truth])  # fmt: skip
    row = encode(read.free, truth)
    # the base, the read point, then the search's first member: the read point
    np.testing.assert_array_equal(read.cloud_x[1], row)
    np.testing.assert_allclose(read.cloud_x[2], row, rtol=0, atol=1e-12)  # (DE's scaling)
    w = harmonic_problem.weights * harmonic_problem.fit
    at = harmonic_problem.clipped(read.cloud_gaps[:2]) @ w / w.sum()
    assert at[1] < at[0] and read.objective <= at[1]
    worse = fit_model(harmonic_problem, "harmonic", {"a": 0.05, "psi": 1.0}, fixed=fixed,
                      settings=settings, seed=2, starts=[{"a": 0.0}])  # fmt: skip
    from_truth = fit_model(harmonic_problem, "harmonic", {"a": 0.05, "psi": 1.0}, fixed=fixed,
                           settings=settings, seed=2)  # fmt: skip
    np.testing.assert_array_equal(worse.cloud_x[2:], from_truth.cloud_x)
    assert not np.all(np.isclose(plain.cloud_x, row), axis=1).any()


def test_the_selection_starts_every_harmonic_fit_from_the_reading(monkeypatch):
    """Reference: a scripted selection that records each job's extra starts. Round 1
    fits the harmonic once per k: only the read k's fit gets the reading; round 2's
    joint fits with the harmonic get it (with mu beside friction), the others none."""
    from bouncelab.gap import select

    starts = {}

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, _seed, *more in jobs:
            key = (name, fixed.get("k"))
            starts[key] = more[1] if len(more) > 1 else []
            gap = {"ideal": 10.0, "harmonic": 5.0}.get(name, 9.0)
            params = {"k": fixed.get("k", 3.0), "a": 0.05} if "harmonic" in name else {}
            out.append(scripted_fit(name, params, gap if key != ("harmonic", 2.0) else 4.0))
        return out

    script_selection(monkeypatch, fake_fit_many)
    select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "harmonic"],
        settings=select.SelectSettings(explained_ratio=0.5), harmonic_read=READ,
    )  # fmt: skip
    for k in K_CHOICES:
        want = [{"k": 3.0, "a": 0.05, "psi": 1.0}] if k == 3.0 else []
        assert starts[("harmonic", k)] == want
    assert starts[("friction", None)] == []
    # round 1 took the harmonic at k 2 (the scripted least); round 2's joint fit moves k
    # among the common multiples, so the read k 3 is one of its starts, with mu ...
    assert starts[("friction+harmonic", None)] == [READ]
    # ... and its refit with k 2 held (it ended at k 3: _k_held_again) has none
    assert starts[("friction+harmonic", 2.0)] == []
