"""A harmonic's ``k`` chosen beside the other effects, not alone
(:func:`bouncelab.gap.select.harmonic_at_each_k`, :func:`bouncelab.gap.select.harmonic_k_beside`);
docs/diagnosis-log.md, session 83, measures it on independent recordings."""

from __future__ import annotations

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run
from test_fit_units import _OneStepProblem, script_selection, scripted_fit, table_fit_many

from bouncelab.gap import select
from bouncelab.gap.fit import K_CHOICES, FitSettings, fit_model, make_problem
from bouncelab.physics import Model
from bouncelab.runs import load_run


def test_each_k_is_fitted_with_the_other_effects_held():
    jobs = []

    def fake_fit_many(js, pool=None, progress=None, work=None):
        jobs.extend(js)
        return [scripted_fit(name, {}, 1.0) for _p, name, *_ in js]

    prev = {"mu": 0.2, "e": 0.4, "k": 2.5, "a": 0.04, "psi": 3.3}
    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(select, "fit_many", fake_fit_many)
        select.harmonic_at_each_k(
            prev, ["friction", "restitution", "harmonic"], ("problem", {"e": 0.4}, None, 0),
            None, False, None,
        )  # fmt: skip
    assert [job[3]["k"] for job in jobs] == list(K_CHOICES)
    for _problem, name, base, fixed, search, _settings, _seed in jobs:
        assert name == Model.parse("friction+restitution+harmonic").name
        assert search is None  # a global search of what is free: a and psi
        assert {"a", "psi"}.isdisjoint(fixed) and {"a", "psi", "k"}.isdisjoint(base)
        assert fixed["mu"] == 0.2 and fixed["e"] == 0.4


def _at_k(objectives: dict) -> list:
    """:func:`select.harmonic_at_each_k`'s fits with the given objective per ``k`` (1.0
    for the others), each at ``a`` 0.1 and ``psi`` = its ``k``."""
    return [
        scripted_fit("friction+harmonic", {"mu": 0.2, "k": k, "a": 0.1, "psi": k},
                     objectives.get(k, 1.0))
        for k in K_CHOICES
    ]  # fmt: skip


@pytest.mark.parametrize(
    ("objectives", "held", "want"),
    [
        ({1.5: 0.2}, 2.5, 1.5),  # another k does better
        ({1.5: 0.2, 2.5: 0.2}, 2.5, 2.5),  # a tie keeps the k held
        ({1.5: 0.2}, None, 1.5),
        ({}, None, K_CHOICES[0]),  # no k held: the first of the least
    ],
)
def test_the_least_objective_chooses_k_and_a_tie_keeps_the_one_held(objectives, held, want):
    assert select._least_k(_at_k(objectives), held) == want


def _scripted_beside(monkeypatch, objectives, before, after):
    """:func:`select.harmonic_k_beside` of a friction + harmonic fit at k 2.5 whose fits
    at each ``k`` (``objectives``), refit and fresh objectives (``before``, ``after``: per
    draw, rad) are scripted, on one fit step of noise floor 1 rad."""
    jobs = []

    def fake_fit_many(js, pool=None, progress=None, work=None):
        jobs.extend(js)
        if len(js) == len(K_CHOICES):
            return _at_k(objectives)
        return [
            scripted_fit("friction+harmonic", {"mu": 0.21, "k": 1.5, "a": 0.1, "psi": 4.0}, 0.1)
        ]

    fresh = {2.5: np.array(before), 1.5: np.array(after)}
    monkeypatch.setattr(select, "fit_many", fake_fit_many)
    monkeypatch.setattr(
        select, "fresh_objectives", lambda model, problem, draws: fresh[model.params["k"]]
    )
    fit = scripted_fit("friction+harmonic", {"mu": 0.2, "k": 2.5, "a": 0.04, "psi": 3.3}, 2.0)
    kept, info = select.harmonic_k_beside(
        fit, _OneStepProblem(), {}, FitSettings(), 0, None, False, None
    )
    return fit, kept, info, jobs


def test_a_better_k_beside_the_others_is_refined_with_k_held_and_kept_when_clearly_better(
    monkeypatch,
):
    fit, kept, info, jobs = _scripted_beside(monkeypatch, {1.5: 0.2}, [2.0, 2.1], [0.3, 0.31])
    (_problem, name, base, fixed, search, _settings, _seed) = jobs[-1]
    assert len(jobs) == len(K_CHOICES) + 1
    assert name == "friction+harmonic" and search == ()  # a local refinement only
    assert fixed == {"k": 1.5} and base == {"mu": 0.2, "k": 1.5, "a": 0.1, "psi": 1.5}
    assert info["k_before"] == 2.5 and info["k_best"] == 1.5 and info["kept"]
    assert kept is not fit and kept.model.params["k"] == 1.5


@pytest.mark.parametrize(
    ("before", "after"),
    [
        ([0.40, 0.41], [0.35, 0.36]),  # within the resolution (0.12 rad)
        ([0.30, 0.31], [0.70, 0.71]),  # worse
    ],
)
def test_a_k_not_clearly_better_on_fresh_ensembles_leaves_the_fit(monkeypatch, before, after):
    fit, kept, info, _ = _scripted_beside(monkeypatch, {1.5: 0.2}, before, after)
    assert kept is fit and not info["kept"] and info["k_best"] == 1.5


def test_where_the_k_taken_does_best_beside_the_others_nothing_is_refitted(monkeypatch):
    fit, kept, info, jobs = _scripted_beside(monkeypatch, {2.5: 0.2}, [0.3], [0.3])
    assert len(jobs) == len(K_CHOICES) and kept is fit
    assert info["k_best"] == 2.5 and not info["kept"] and info["fresh_after"] is None


@pytest.mark.parametrize(
    ("name", "params", "fixed"),
    [
        ("harmonic", {"k": 2.5, "a": 0.1, "psi": 1.0}, {}),  # alone: its round-1 choice
        ("friction+restitution", {"mu": 0.2, "e": 0.4}, {}),
        ("friction+harmonic", {"mu": 0.2, "k": 2.5, "a": 0.1, "psi": 1.0}, {"k": 2.5}),
    ],
)
def test_no_harmonic_beside_another_effect_or_a_k_held_is_left_alone(
    monkeypatch, name, params, fixed
):
    monkeypatch.setattr(select, "fit_many", lambda *a, **k: pytest.fail("fitted"))
    fit = scripted_fit(name, params, 1.0)
    kept, info = select.harmonic_k_beside(
        fit, _OneStepProblem(), fixed, FitSettings(), 0, None, False, None
    )
    assert kept is fit and info is None


def _scripted_rounds(monkeypatch, gaps, params, k_gaps=None):
    """A scripted selection over friction, restitution and the harmonic (``gaps`` and
    ``params`` by model name, :func:`table_fit_many`; ``k_gaps``: the gap of a joint
    restitution + harmonic fit by its ``k``): the selection, the jobs fitted, the calls
    of ``_k_beside_taken`` (``k_alone``, ``prev``, ``effects``; it returns 0.5) and the
    fits :func:`select.harmonic_k_beside` was given."""
    jobs, chosen, beside = [], [], []
    table = table_fit_many(gaps, params)
    joint = Model.parse("restitution+harmonic").name

    def fake_fit_many(js, pool=None, progress=None, work=None):
        jobs.extend(js)
        fits = table(js, pool, progress, work)
        for n, (_p, name, _base, fixed, *_rest) in enumerate(js):
            if name == joint and k_gaps is not None:
                k = fixed["k"]
                fits[n] = scripted_fit(name, {"e": 0.4, "k": k, "a": 0.1, "psi": 1.0}, k_gaps[k])
        return fits

    def k_beside_taken(k_alone, prev, effects, *rest):
        chosen.append((k_alone, dict(prev), list(effects)))
        return 0.5

    def k_beside(fit, *rest):
        beside.append(fit)
        return fit, None

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "_k_beside_taken", k_beside_taken)
    monkeypatch.setattr(select, "harmonic_k_beside", k_beside)
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "harmonic"]
    )
    return sel, jobs, chosen, beside


ROUND1 = {"ideal": 20.0, "restitution": 5.0, "harmonic": 8.0, "friction": 9.0}
ROUND1_PARAMS = {"restitution": {"e": 0.4}, "harmonic": {"k": 2.5, "a": 0.05, "psi": 1.0}}


def test_a_round_that_takes_nothing_above_the_floor_retries_the_harmonic_at_the_k_chosen_beside(
    monkeypatch,
):
    """Round 1 takes restitution (5 floors) and fits the harmonic alone at k 2.5; round 2
    takes nothing (the harmonic at k 2.5 beside restitution: 4.9). Its k is chosen again
    beside restitution, from round 1's values (scripted: 0.5), and round 3 fits the
    harmonic alone at it, which is taken (0.5 floors); its k is not chosen again after
    the selection."""
    sel, jobs, chosen, beside = _scripted_rounds(
        monkeypatch, ROUND1, ROUND1_PARAMS, k_gaps={2.5: 4.9, 0.5: 0.5}
    )
    ((k_alone, prev, effects),) = chosen
    assert k_alone == 2.5 and effects == ["restitution"] and prev["e"] == 0.4
    assert [[e for e, _f in r] for r in sel["rounds"][1:]] == [
        ["friction", "harmonic"],
        ["harmonic"],
    ]
    assert [e for e, _f in sel["accepted"]] == ["restitution", "harmonic"]
    assert sel["final"].model.params["k"] == 0.5
    assert beside == []


def test_the_retry_fits_nothing_where_the_k_chosen_beside_is_round_ones(monkeypatch):
    """As above, with ``_k_beside_taken`` finding round 1's k again: the selection stops
    after round 2, once."""
    sel, _jobs, chosen, _beside = _scripted_rounds(
        monkeypatch, ROUND1, {**ROUND1_PARAMS, "harmonic": {"k": 0.5, "a": 0.05, "psi": 1.0}},
        k_gaps={0.5: 4.9},
    )  # fmt: skip
    assert len(chosen) == 1 and len(sel["rounds"]) == 2
    assert sel["stop"] == "no_improvement"


def test_no_retry_where_the_run_is_within_the_explained_ratio(monkeypatch):
    """Round 1's restitution at 1.8 floors (within 2): round 2 is strict and takes
    nothing; the harmonic's k is not chosen again."""
    gaps = {**ROUND1, "restitution": 1.8}
    sel, _jobs, chosen, _beside = _scripted_rounds(
        monkeypatch, gaps, ROUND1_PARAMS, k_gaps={2.5: 1.7, 0.5: 0.1}
    )
    assert chosen == [] and [e for e, _f in sel["accepted"]] == ["restitution"]


@pytest.mark.parametrize(("final", "again"), [(2.5, True), (1.5, False)])
def test_a_harmonic_taken_in_round_one_has_its_k_chosen_again_beside_the_effects_after_it(
    monkeypatch, final, again
):
    """Round 1 takes the harmonic (k 2.5), round 2 friction beside it (``final`` floors):
    the final model goes to :func:`select.harmonic_k_beside` where it is above 2 floors;
    no round added the harmonic, so none chose its k."""
    gaps = {"ideal": 20.0, "restitution": 9.0, "harmonic": 5.0, "friction": 6.0}
    gaps["friction+harmonic"] = final
    params = {
        "harmonic": {"k": 2.5, "a": 0.05, "psi": 1.0},
        "friction+harmonic": {"mu": 0.2, "k": 2.5, "a": 0.05, "psi": 1.0},
    }
    sel, _jobs, chosen, beside = _scripted_rounds(monkeypatch, gaps, params)
    assert chosen == []
    assert [e for e, _f in sel["accepted"]] == ["harmonic", "friction"]
    assert [f.model.name for f in beside] == ["friction+harmonic"] * again


def test_beside_friction_the_true_k_of_a_half_integer_harmonic_is_found(tmp_path):
    """Reference: pseudo-data of friction mu 0.2 and a harmonic k 1.5, a 0.1, psi 4.0
    (the model's own flights, 12 cycles a step); a fit held at k 2.5 and refined there
    is replaced by one at the true k, whose fresh objective is lower."""
    truth = Model.parse("friction+harmonic", {"mu": 0.2, "k": 1.5, "a": 0.1, "psi": 4.0})
    run_dir = write_run(tmp_path, cycles=12)
    flights = pseudo_flights(run_dir, truth, seed=5, cycles=12)
    problem = make_problem(load_run(run_dir), flights, duration_s(cycles=12), n_members=2)
    settings = FitSettings(local_evals=6)
    wrong = fit_model(
        problem, "friction+harmonic", {"mu": 0.2, "a": 0.05, "psi": 3.3}, fixed={"k": 2.5},
        search=(), settings=settings,
    )  # fmt: skip
    kept, info = select.harmonic_k_beside(wrong, problem, {}, settings, 0, None, False, None)
    assert info["k_before"] == 2.5 and info["k_best"] == 1.5
    assert info["kept"] and info["fresh_after"] < info["fresh_before"]
    assert kept.model.params["k"] == 1.5
    assert kept.model.params["mu"] == pytest.approx(0.2, rel=0.15)
