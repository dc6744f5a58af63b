"""A fitted harmonic the takeoff phases refuse (gap.takeoff_reading ``harmonic_refuted``,
gap.select ``forward_select(refuted=...)``)."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
from test_fit_units import _OneStepProblem, script_selection, table_fit_many

from bouncelab.gap import select
from bouncelab.gap.takeoff_reading import (
    MIN_STEPS,
    REFUTED_RATIO,
    harmonic_refuted,
    predicted_takeoff,
    read_takeoffs,
    takeoff_rms,
)


def _takeoffs(k: float, a: float, psi: float, mu: float, noise: float = 0.002) -> pd.DataFrame:
    """Steps of ride takeoffs (the columns of ``ride_takeoffs``) off a plate with the
    harmonic ``k, a, psi`` and friction ``mu``, each phase with a seeded error (rad)."""
    gamma = np.linspace(1.5, 3.2, 18)
    start = np.full(gamma.size, 3.5)  # rides begin after the plate's top
    phi = predicted_takeoff(gamma, start, k, a, psi, mu)
    phi = phi + np.random.default_rng(0).normal(0.0, noise, phi.size)
    return pd.DataFrame(
        {
            "step": np.arange(gamma.size),
            "gamma": gamma,
            "phi_takeoff": phi % (2 * np.pi),
            "phi_start": start,
            "n": 20,
        }
    )


def test_the_rms_refits_mu():
    """Reference: phases made with mu 0.2 and no harmonic, read at the truth: the rms is
    the seeded error (2 mrad), not the 0.2 of friction left out."""
    pts = _takeoffs(2.0, 0.0, 0.0, 0.2)
    assert takeoff_rms(pts, 2.0, 0.0, 0.0) == pytest.approx(0.002, rel=0.3)


def test_a_harmonic_standing_in_for_another_effect_is_refused():
    """Reference: a plate with friction alone. A k-2 harmonic of a k^2 0.1 (the size that
    stood in for the armature on the independent ``friction_feedback``) moves every
    takeoff by far more than the 2 mrad the phases scatter: refused, with the rms of both."""
    pts = _takeoffs(2.0, 0.0, 0.0, 0.2)
    reading = read_takeoffs(pts)
    got = harmonic_refuted(pts, reading, 2.0, 0.025, 3.0)
    assert got is not None
    assert got["rms_rad"] > REFUTED_RATIO * got["plain_rms_rad"]
    assert got["plain_rms_rad"] == pytest.approx(reading["plain"]["rms_rad"])
    assert got | {"rms_rad": 0, "plain_rms_rad": 0} == {
        "k": 2.0, "a": 0.025, "psi": 3.0, "rms_rad": 0, "plain_rms_rad": 0,
    }  # fmt: skip
    # a harmonic too weak to move the takeoffs is not refused
    assert harmonic_refuted(pts, reading, 2.0, 1e-5, 3.0) is None


def test_a_true_harmonic_is_not_refused_even_somewhat_off():
    """Reference: takeoffs off a plate with a k-3 harmonic (a 0.05, psi 1) and mu 0.2. At
    the truth and 20 % off in a or 0.3 rad in psi it fits better than no harmonic."""
    pts = _takeoffs(3.0, 0.05, 1.0, 0.2)
    reading = read_takeoffs(pts)
    for a, psi in [(0.05, 1.0), (0.06, 1.0), (0.04, 1.3)]:
        assert harmonic_refuted(pts, reading, 3.0, a, psi) is None
    # the judge is no harmonic at all: where the plate has one, even another k that fits
    # the phases poorly is not worse than none (plain rms 0.32 rad here)
    assert harmonic_refuted(pts, reading, 2.0, 0.1, 1.0) is None


def test_nothing_is_judged_without_a_reading_or_at_a_k_the_phases_cannot_tell():
    pts = _takeoffs(2.0, 0.0, 0.0, 0.2)
    reading = read_takeoffs(pts)
    # a half-whole k repeats every other cycle: one cycle's phase cannot judge it
    assert harmonic_refuted(pts, reading, 2.5, 0.05, 3.0) is None
    few = pts.iloc[: MIN_STEPS - 1]
    assert harmonic_refuted(few, read_takeoffs(few), 2.0, 0.05, 3.0) is None


def test_a_refused_harmonic_is_not_proposed_and_the_next_best_is_judged(monkeypatch):
    """Reference: a scripted selection. Round 1: the harmonic alone the least (3 floors),
    the armature next (4); the baseline 10. Refused, the harmonic gives way to the
    armature, which is taken, and the refusal is kept with its round."""
    gaps = {"ideal": 10.0, "harmonic": 3.0, "feedback": 4.0}
    params = {"harmonic": {"k": 2.0, "a": 0.02, "psi": 3.0}}
    script_selection(monkeypatch, table_fit_many(gaps, params))
    seen = []

    def refuted(effect, model):
        seen.append(effect)
        if effect == "harmonic":
            return {"k": 2.0, "a": 0.02, "psi": 3.0, "rms_rad": 0.2, "plain_rms_rad": 0.01}
        return None

    kw = dict(candidates=["harmonic", "feedback"], settings=select.SelectSettings(max_effects=1))
    sel = select.forward_select(_OneStepProblem(), 1.0, refuted=refuted, **kw)
    assert [e for e, _f in sel["accepted"]] == ["feedback"]
    # the round would have proposed it: kept as proposed (the diagnosis warns of it)
    assert sel["takeoff_refused"] == [
        {"round": 1, "effect": "harmonic", "model": "harmonic", "proposed": True, "k": 2.0,
         "a": 0.02, "psi": 3.0, "rms_rad": 0.2, "plain_rms_rad": 0.01}
    ]  # fmt: skip
    assert sorted(seen) == ["feedback", "harmonic"]
    # without the judge the harmonic is taken
    plain = select.forward_select(_OneStepProblem(), 1.0, **kw)
    assert [e for e, _f in plain["accepted"]] == ["harmonic"]
    assert plain["takeoff_refused"] == []


def test_a_pair_with_a_refused_harmonic_does_not_replace_an_armature_taken_alone(monkeypatch):
    """Reference: a scripted selection (floor 1). Round 1 takes the armature alone (10 ->
    0.9, within the floor); the pair of friction and a harmonic would replace it (0.4,
    the independent ``friction_feedback``'s old answer). With the harmonic refused the
    armature stays, and the refusal is kept as the pair check's."""
    gaps = {"ideal": 10.0, "friction": 5.0, "harmonic": 4.0, "feedback": 0.9,
            "friction+harmonic": 0.4}  # fmt: skip
    params = {"harmonic": {"k": 2.0, "a": 0.02, "psi": 3.0},
              "friction+harmonic": {"mu": 0.2, "k": 2.0, "a": 0.02, "psi": 3.0}}  # fmt: skip
    script_selection(monkeypatch, table_fit_many(gaps, params))
    why = {"k": 2.0, "a": 0.02, "psi": 3.0, "rms_rad": 0.2, "plain_rms_rad": 0.01}

    def refuted(effect, model):
        return why if effect == "harmonic" and model.params["a"] > 0 else None

    kw = dict(candidates=["friction", "harmonic", "feedback"])
    plain = select.forward_select(_OneStepProblem(), 1.0, **kw)
    assert plain["pair_check"]["replaced_by"] == ["harmonic", "friction"]
    sel = select.forward_select(_OneStepProblem(), 1.0, refuted=refuted, **kw)
    assert [e for e, _f in sel["accepted"]] == ["feedback"]
    assert "replaced_by" not in sel["pair_check"]
    assert sel["pair_check"]["refused_pair"] == "friction+harmonic"
    pair = [t for t in sel["takeoff_refused"] if t["round"] == "pair_check"]
    assert pair == [{"round": "pair_check", "effect": "harmonic", "model": "friction+harmonic",
                     "proposed": True, **why}]  # fmt: skip
    # round 1's harmonic (4 floors) trailed the armature (0.9): refused, not proposed
    (first,) = [t for t in sel["takeoff_refused"] if t["round"] == 1]
    assert first["proposed"] is False


def test_a_refused_harmonic_that_would_not_be_proposed_is_marked_so(monkeypatch):
    """Reference: a scripted selection. Round 1: friction the least (2 floors), the
    harmonic next (3). Refused or not, friction is proposed: the refusal changed nothing
    (``proposed`` False, no warning in the diagnosis)."""
    gaps = {"ideal": 10.0, "friction": 2.0, "harmonic": 3.0}
    params = {"harmonic": {"k": 2.0, "a": 0.02, "psi": 3.0}}
    script_selection(monkeypatch, table_fit_many(gaps, params))
    why = {"k": 2.0, "a": 0.02, "psi": 3.0, "rms_rad": 0.2, "plain_rms_rad": 0.01}
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "harmonic"],
        settings=select.SelectSettings(max_effects=1),
        refuted=lambda e, m: why if e == "harmonic" else None,
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["friction"]
    assert [t["proposed"] for t in sel["takeoff_refused"]] == [False]
