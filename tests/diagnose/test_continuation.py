"""Continuation of joint fits: the low-Gamma part of a problem, when a run calls for it,
and a fit that searches it first (``gap.fit.Problem.restricted``,
``gap.fit.continuation_gamma``, ``fit_model(continuation=True)``)."""

from __future__ import annotations

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run

from bouncelab.gap.fit import (
    CONTINUATION_GAMMA,
    RESTRICTED_TAIL_CYCLES,
    EvaluationPool,
    FitSettings,
    continuation_gamma,
    fit_model,
    make_problem,
    problem_cycles,
    spent_cycles,
    step_gaps,
)
from bouncelab.physics import Model
from bouncelab.runs import load_run

#: An up-sweep far above the first period doubling (like the seed's Gamma 0 to 8):
#: 12 of its 32 steps at Gamma <= 3.
WIDE = tuple(np.round(np.arange(0.8, 7.0, 0.2), 6))
TRUTH = Model.parse("friction+restitution", {"mu": 0.2, "e": 0.4})
CYCLES = 24


def _problem(root, gammas, name):
    run_dir = write_run(root, name, gammas=gammas, cycles=CYCLES)
    flights = pseudo_flights(run_dir, TRUTH, seed=5, cycles=CYCLES, gammas=gammas)
    return make_problem(load_run(run_dir), flights, duration_s(gammas, CYCLES), n_members=2)


@pytest.fixture(scope="module")
def wide(tmp_path_factory):
    return _problem(tmp_path_factory.mktemp("cont"), WIDE, "wide")


def test_restricted_problem_is_the_low_gamma_part_of_an_up_sweep(wide):
    """On an up-sweep the restricted protocol is the run's first steps, so the model's
    flights there are the same and so are its per-step gaps (to 1e-12 rad); the data,
    floors and held-out steps are those steps' own."""
    low = wide.restricted(2.0)
    keep = wide.steps["gamma"].to_numpy() <= 2.0
    assert 0 < keep.sum() < len(keep)
    assert list(low.steps["step"]) == list(wide.steps["step"][keep])
    n = int(keep.sum())  # the kept steps, then the next for a flight's landing
    assert list(low.protocol["step"]) == list(wide.protocol["step"][: n + 1])
    assert low.protocol["cycles"].iloc[-1] == RESTRICTED_TAIL_CYCLES
    np.testing.assert_array_equal(low.floor, wide.floor[keep])
    np.testing.assert_array_equal(low.heldout, wide.heldout[keep])
    assert set(low.data_table["step"]) <= set(low.steps["step"])
    assert problem_cycles(low) < problem_cycles(wide)
    for model in (TRUTH, Model.parse("harmonic", {"k": 3.0, "a": 0.05, "psi": 1.0})):
        np.testing.assert_allclose(
            step_gaps(low, model), step_gaps(wide, model)[keep], rtol=0, atol=1e-12
        )
    assert wide.restricted(2.0) is low  # made once


def test_restricted_protocol_keeps_recording_order_on_a_down_sweep(tmp_path):
    """A down-sweep's low steps come last: they are kept in that order, not re-sorted."""
    down = _problem(tmp_path, WIDE[::-1], "down")
    low = down.restricted(CONTINUATION_GAMMA)
    gammas = low.protocol["gamma"].to_numpy()
    assert np.all(gammas <= CONTINUATION_GAMMA) and np.all(np.diff(gammas) < 0)
    assert list(low.protocol["step"]) == list(down.protocol["step"][-len(gammas) :])


def test_continuation_only_on_runs_reaching_far_above_period_doubling(wide, tmp_path):
    """The seed-like wide sweep gets it; a run mostly below Gamma 3 does not (its low
    part would cost as much as the whole)."""
    assert continuation_gamma(wide) == CONTINUATION_GAMMA
    narrow = _problem(tmp_path, tuple(np.round(np.arange(0.8, 3.8, 0.15), 6)), "narrow")
    assert continuation_gamma(narrow) is None
    # a joint fit on it is the plain fit
    settings = FitSettings(popsize=3, maxiter=2, local_evals=2)
    fit = fit_model(narrow, "friction+restitution", settings=settings, continuation=True)
    assert "continuation" not in fit.extra


def test_continued_fit_reports_and_pays_for_its_first_search(wide):
    """The first search is reported (its parameters, evaluations) and its simulated
    cycles count in the diagnosis's budget; with a pool the same numbers come out."""
    settings = FitSettings(popsize=3, maxiter=2, local_evals=2)
    name = "friction+restitution"
    plain = fit_model(wide, name, settings=settings, seed=1)
    cont = fit_model(wide, name, settings=settings, seed=1, continuation=True)
    info = cont.extra["continuation"]
    assert info["max_gamma"] == CONTINUATION_GAMMA and info["n_evals"] > 6
    assert set(info["params"]) == {"mu", "e"}
    low_cycles = problem_cycles(wide.restricted(CONTINUATION_GAMMA))
    assert info["cycles"] == info["n_evals"] * low_cycles
    assert spent_cycles([cont], wide) == pytest.approx(
        cont.n_evals * problem_cycles(wide) + info["cycles"]
    )
    assert spent_cycles([plain], wide) == plain.n_evals * problem_cycles(wide)
    with EvaluationPool(wide, 2) as pool:
        pooled = fit_model(wide, name, settings=settings, seed=1, pool=pool, continuation=True)
    assert pooled.extra["continuation"] == info
    np.testing.assert_array_equal(pooled.cloud_gaps, cont.cloud_gaps)
    assert pooled.model.params == cont.model.params
