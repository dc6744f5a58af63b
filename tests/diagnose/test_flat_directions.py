"""The one-parameter probes of a fit (:func:`bouncelab.gap.fit.flat_directions`,
:func:`bouncelab.gap.fit.edge_bounds`)."""

from __future__ import annotations

import numpy as np
import pytest

from bouncelab.gap import fit as fitmod
from bouncelab.gap.fit import (
    EDGE_SHARES,
    FitResult,
    edge_bounds,
    flat_directions,
    flat_warnings,
    free_params,
    warned_params,
)
from bouncelab.physics import Model


class _Problem:
    """What the probes read of a problem: the fit steps and their mean."""

    fit = np.array([True, True, False])

    def mean(self, values, mask):
        return float(np.mean(np.asarray(values)[mask]))


def _scripted(monkeypatch, objective):
    """step_gaps replaced by ``objective(params)`` (rad) on every step; the calls kept."""
    calls = []

    def fake(problem, model, buffer=None, shift=0.0):
        calls.append(dict(model.params))
        return np.full(3, objective(model.params))

    monkeypatch.setattr(fitmod, "step_gaps", fake)
    return calls


def _fit(name: str, params: dict, objective: float) -> FitResult:
    model = Model.parse(name, params)
    free = free_params(model.effects)
    return FitResult(model, free, objective, np.zeros(3), np.empty((0, len(free))),
                     np.empty((0, 3)), 0, 0.0)  # fmt: skip


def test_a_parameter_the_objective_ignores_is_listed_and_a_steep_one_is_not(monkeypatch):
    # the gap grows 1 rad per unit of relative mu error and not at all with zeta
    _scripted(monkeypatch, lambda p: 0.5 + abs(p["mu"] / 0.2 - 1.0))
    params = {"mu": 0.2, "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 0.0}
    base = 0.5
    flat = flat_directions(_fit("friction+feedback", params, base), _Problem(), tolerance=0.05)
    assert set(flat) == {"mass_ratio", "f_ratio", "zeta"}
    assert [v for v, _ in flat["zeta"]] == pytest.approx([0.085, 0.115])
    assert all(rise == pytest.approx(0.0) for _, rise in flat["zeta"])
    # a looser tolerance than the 0.15 rad of a 15 % move of mu lists it too
    assert "mu" in flat_directions(_fit("friction+feedback", params, base), _Problem(), 0.2)


def test_probes_stay_within_the_bounds_and_skip_choices_phases_and_nulls(monkeypatch):
    calls = _scripted(monkeypatch, lambda p: 1.0)
    # mass_ratio near its upper bound 0.5: 15 % more is cut to 4 %, not probed
    params = {"mass_ratio": 0.48, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 1.0}
    flat = flat_directions(_fit("feedback", params, 1.0), _Problem(), tolerance=0.01)
    assert flat["mass_ratio"] == [(pytest.approx(0.408), 0.0)]
    assert {c["ride_load"] for c in calls} == {1.0}  # a choice is never moved
    calls.clear()
    harmonic = {"k": 2.0, "a": 0.05, "psi": 1.0}
    flat = flat_directions(_fit("harmonic", harmonic, 1.0), _Problem(), tolerance=0.01)
    assert set(flat) == {"a"}
    assert {c["psi"] for c in calls} == {1.0} and {c["k"] for c in calls} == {2.0}
    calls.clear()
    assert flat_directions(_fit("friction", {"mu": 0.0}, 1.0), _Problem(), 0.01) == {}
    assert calls == []  # nothing to move at a null value


def test_a_probe_that_does_better_than_the_fit_is_listed_with_its_negative_rise(monkeypatch):
    def objective(p):  # less damping does better; every other move does worse
        steep = abs(p["mass_ratio"] / 0.05 - 1.0) + abs(p["f_ratio"] / 0.6 - 1.0)
        return steep + (0.3 if p["zeta"] < 0.1 else 0.4 if p["zeta"] == 0.1 else 1.0)

    _scripted(monkeypatch, objective)
    params = {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 0.0}
    flat = flat_directions(_fit("feedback", params, 0.4), _Problem(), tolerance=0.0)
    assert flat == {"zeta": [(pytest.approx(0.085), pytest.approx(-0.1))]}


def test_an_interval_side_at_the_fitted_value_is_walked_out_to_the_farthest_probe_within(
    monkeypatch,
):
    # the gap rises 1 rad per unit of relative mu error: within 0.02 rad lie moves up to
    # 2 %, so of the walk's moves (7.5, 3.75, 1.875 ... %) 1.875 % is the first within
    calls = _scripted(monkeypatch, lambda p: 0.5 + abs(p["mu"] / 0.2 - 1.0))
    fit = _fit("friction", {"mu": 0.2}, 0.5)
    ci = edge_bounds(fit, _Problem(), {"mu": [0.2, 0.21]}, tolerance=0.02)
    assert ci == {"mu": [pytest.approx(0.2 * (1 - 0.01875)), 0.21]}
    # the fitted point once, then 7.5 %, 3.75 % and 1.875 % below it; the upper side,
    # which the evaluated points reach, is not probed
    assert [c["mu"] for c in calls] == pytest.approx([0.2, 0.185, 0.1925, 0.19625])
    assert EDGE_SHARES[:3] == pytest.approx((0.075, 0.0375, 0.01875))


def test_a_side_every_probe_resolves_is_the_smallest_move_and_sides_off_the_value_are_left(
    monkeypatch,
):
    calls = _scripted(monkeypatch, lambda p: 0.5 + 100.0 * abs(p["mu"] / 0.2 - 1.0))
    fit = _fit("friction", {"mu": 0.2}, 0.5)
    # a move of 0.23 % costs 0.23 rad: the points within 0.1 rad lie inside that move,
    # not at the fitted value alone (an interval of no width excludes every truth)
    smallest = EDGE_SHARES[-1]
    assert smallest == pytest.approx(0.0023, rel=0.02)
    ci = edge_bounds(fit, _Problem(), {"mu": [0.2, 0.2]}, tolerance=0.1)
    assert ci == {"mu": [pytest.approx(0.2 * (1 - smallest)), pytest.approx(0.2 * (1 + smallest))]}
    assert len(calls) == 1 + 2 * len(EDGE_SHARES)
    calls.clear()
    assert edge_bounds(fit, _Problem(), {"mu": [0.19, 0.21]}, 0.1) == {"mu": [0.19, 0.21]}
    assert calls == []  # neither side at the value: nothing simulated


def test_the_walk_keeps_to_the_bounds_and_leaves_choices_phases_and_fixed_alone(monkeypatch):
    calls = _scripted(monkeypatch, lambda p: 1.0)  # every move within any tolerance
    params = {"mass_ratio": 0.5, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 1.0}
    ci = {"mass_ratio": [0.5, 0.5], "f_ratio": [0.55, 0.65], "zeta": [0.1, 0.12],
          "ride_load": [1.0, 1.0]}  # fmt: skip
    out = edge_bounds(_fit("feedback", params, 1.0), _Problem(), ci, tolerance=0.0)
    # mass_ratio on its upper bound 0.5: only its lower side moves (7.5 % at once)
    assert out["mass_ratio"] == [pytest.approx(0.4625), 0.5]
    assert out["zeta"] == [pytest.approx(0.0925), 0.12]
    assert out["f_ratio"] == [0.55, 0.65] and out["ride_load"] == [1.0, 1.0]
    assert {c["ride_load"] for c in calls} == {1.0}
    assert ci["zeta"] == [0.1, 0.12]  # the caller's dict untouched
    calls.clear()
    harmonic = _fit("harmonic", {"k": 2.0, "a": 0.05, "psi": 1.0}, 1.0)
    out = edge_bounds(harmonic, _Problem(), {"k": [2, 2], "a": [0.05, 0.06], "psi": [1, 1]}, 0.0)
    assert out["psi"] == [1, 1] and out["k"] == [2, 2]
    assert {c["psi"] for c in calls} == {1.0}


def test_the_warning_names_the_parameter_the_move_and_the_rise_in_floors():
    fit = _fit("feedback", {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1222}, 0.4)
    lines = flat_warnings(fit, {"zeta": [(0.1405, 0.012), (0.1039, 0.003)]}, 0.05, 0.006)
    assert lines == [
        "zeta=0.1222 is poorly identified: at 0.1039 (-15 %, the others held) the fit "
        "steps' gap is +0.06 noise floors from the best, within what the data resolve (0.12)"
    ]
    assert warned_params(lines) == {"zeta"}


def test_a_fit_of_more_effects_as_good_as_the_final_one_warns_of_its_other_values():
    from bouncelab.gap.diagnose import superset_warnings

    final = Model.parse(
        "restitution+feedback",
        {"e": 0.478, "f_ratio": 0.273, "mass_ratio": 0.077, "zeta": 0.188, "ride_load": 0.0},
    )
    floor = 0.05
    wider = {"e": 0.47, "f_ratio": 0.567, "mass_ratio": 0.059, "zeta": 0.2, "ride_load": 1.0}
    tried = [
        # the final model itself, far off: not a superset
        (Model.parse("restitution+feedback", {**wider, "f_ratio": 2.0}), 0.01),
        # a superset beyond the margin: ignored
        (Model.parse("friction+restitution+feedback", {**wider, "mu": 0.1, "e": 0.2}), 0.10),
        # supersets within the margin: the least gap of them speaks for each parameter
        (Model.parse("restitution+harmonic+feedback", {**wider, "a": 0.02, "k": 2.0, "psi": 1.0}),
         0.044),
        (Model.parse("restitution+feedback+gamma_scale", {**wider, "f_ratio": 0.9, "s": 1.0}),
         0.055),
    ]  # fmt: skip
    lines = superset_warnings(final, 0.049, tried, floor, margin=0.25)
    assert warned_params(lines) == {"f_ratio", "mass_ratio"}  # e and zeta within 15 %
    f_line = next(line for line in lines if line.startswith("f_ratio"))
    assert "restitution+harmonic+feedback" in f_line and "0.567" in f_line and "0.88" in f_line
    # a parameter warned about already gets no second line; nothing wider, nothing said
    assert warned_params(superset_warnings(final, 0.049, tried, floor, 0.25, {"f_ratio"})) == {
        "mass_ratio"
    }
    assert superset_warnings(final, 0.049, tried[:2], floor, 0.25) == []
