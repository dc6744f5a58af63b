"""A half-integer harmonic against its phase one drive cycle later
(:func:`bouncelab.gap.select.harmonic_twin`); docs/diagnosis-log.md, session 82, measures
it on an independent recording."""

from __future__ import annotations

import math

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run
from test_fit_units import _OneStepProblem, scripted_fit

from bouncelab.gap import select
from bouncelab.gap.diagnose import twin_warnings
from bouncelab.gap.fit import FitSettings, fit_model, make_problem, warned_params
from bouncelab.physics import Model
from bouncelab.runs import load_run


@pytest.mark.parametrize(
    ("k", "psi", "twin"),
    [
        (0.5, 2.0, 2.0 + math.pi),
        (1.5, 2.0, 2.0 + math.pi),  # 3 pi: the same as pi
        (2.5, 4.0, 4.0 - math.pi),  # wrapped into [0, 2 pi)
        (0.25, 1.0, 1.0 + math.pi / 2),
    ],
)
def test_the_twin_is_the_harmonic_one_drive_cycle_later(k, psi, twin):
    got = select.one_cycle_later({"mu": 0.2, "k": k, "a": 0.1, "psi": psi})
    assert got == pytest.approx({"mu": 0.2, "k": k, "a": 0.1, "psi": twin})


@pytest.mark.parametrize(
    "params", [{"k": 2.0, "a": 0.1, "psi": 1.0}, {"k": 3.0, "a": 0.1, "psi": 6.0}, {"mu": 0.2}]
)
def test_a_whole_harmonic_or_none_has_no_twin(params):
    assert select.one_cycle_later(params) is None


def _scripted_twin(monkeypatch, before, after):
    """:func:`select.harmonic_twin` of a k-0.5 fit whose twin's refit and the two fresh
    objectives are scripted (``before``, ``after``: per draw, rad), on one fit step of
    noise floor 1 rad (a resolution of 0.12 rad)."""
    jobs = []

    def fake_fit_many(js, pool=None, progress=None, work=None):
        jobs.extend(js)
        return [scripted_fit("harmonic", {"k": 0.5, "a": 0.2, "psi": 2.01}, 1.0)]

    fresh = {2.01: np.array(after), 5.14: np.array(before)}
    monkeypatch.setattr(select, "fit_many", fake_fit_many)
    monkeypatch.setattr(
        select,
        "fresh_objectives",
        lambda model, problem, draws: fresh[round(model.params["psi"], 2)],
    )
    fit = scripted_fit("harmonic", {"k": 0.5, "a": 0.2, "psi": 5.14}, 2.0)
    kept, info = select.harmonic_twin(fit, _OneStepProblem(), {}, FitSettings(), 0)
    return fit, kept, info, jobs


def test_the_twin_is_refined_from_its_phase_with_k_held_and_kept_when_better(monkeypatch):
    fit, kept, info, jobs = _scripted_twin(monkeypatch, [0.70, 0.71], [0.30, 0.31])
    ((_problem, name, base, fixed, search, _settings, _seed),) = jobs
    assert name == "harmonic" and search == ()  # a local refinement only
    assert base["psi"] == pytest.approx(5.14 - math.pi) and fixed == {"k": 0.5}
    assert kept is not fit and kept.model.params["psi"] == 2.01
    assert info["kept"] and not info["tie"]
    assert twin_warnings(info) == []


def test_a_worse_twin_leaves_the_fit_unwarned(monkeypatch):
    fit, kept, info, _ = _scripted_twin(monkeypatch, [0.30, 0.31], [0.70, 0.71])
    assert kept is fit and not info["kept"] and not info["tie"]
    assert twin_warnings(info) == []


@pytest.mark.parametrize(
    ("before", "after"),
    [
        ([0.40, 0.41], [0.30, 0.31]),  # beyond its standard errors, within the resolution
        ([0.90, 0.30], [0.30, 0.31]),  # beyond the resolution, within 2 standard errors
    ],
)
def test_a_twin_the_data_do_not_tell_apart_leaves_the_fit_and_warns_about_psi(
    monkeypatch, before, after
):
    fit, kept, info, _ = _scripted_twin(monkeypatch, before, after)
    assert info["tie"] and not info["kept"] and kept is fit
    (line,) = twin_warnings(info)
    assert warned_params([line]) == {"psi"}
    assert "psi=5.14" in line and "psi=2.01" in line


def test_on_a_k_half_harmonic_the_twin_of_a_wrong_phase_finds_the_true_one(tmp_path):
    """Reference: pseudo-data of k 0.5, a 0.2, psi 2.0 (the model's own flights, 12 cycles
    a step); a fit started at psi 2 + pi and refined there stays there; its twin comes
    back to within 0.1 rad of 2.0 and is kept."""
    truth = Model.parse("harmonic", {"k": 0.5, "a": 0.2, "psi": 2.0})
    run_dir = write_run(tmp_path, cycles=12)
    flights = pseudo_flights(run_dir, truth, seed=4, cycles=12)
    problem = make_problem(load_run(run_dir), flights, duration_s(cycles=12), n_members=2)
    settings = FitSettings(local_evals=6)
    wrong = fit_model(
        problem, "harmonic", {"a": 0.2, "psi": 2.0 + math.pi}, fixed={"k": 0.5},
        search=(), settings=settings,
    )  # fmt: skip
    assert abs(wrong.model.params["psi"] - (2.0 + math.pi)) < 0.3
    kept, info = select.harmonic_twin(wrong, problem, {}, settings, 0)
    assert info["kept"] and not info["tie"]
    assert info["fresh_after"] < info["fresh_before"]
    assert kept.model.params["psi"] == pytest.approx(2.0, abs=0.1)
