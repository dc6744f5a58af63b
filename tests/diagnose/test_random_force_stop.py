"""A random force ends the selection (``gap.select.forward_select(random_force=...)``):
once a round has taken an effect and the held-out gap is still above the unexplained
limit, a repeat rule that names a random force on the current model stops the rounds
(``stop`` ``random_force``); within that limit it is not asked.

Reference: scripted selections (floor 1, ``test_fit_units.script_selection``): friction
alone at ``g`` floors, friction with a harmonic at 1.0."""

from __future__ import annotations

import pytest
from test_fit_units import _OneStepProblem, script_selection, table_fit_many

from bouncelab.gap import select

PARAMS = {"harmonic": {"k": 2.0, "a": 0.02, "psi": 3.0},
          "friction+harmonic": {"mu": 0.2, "k": 2.0, "a": 0.02, "psi": 3.0}}  # fmt: skip


def _select(monkeypatch, g_friction, random_force):
    gaps = {"ideal": 10.0, "friction": g_friction, "harmonic": 8.0, "friction+harmonic": 1.0}
    script_selection(monkeypatch, table_fit_many(gaps, PARAMS))
    return select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "harmonic"], random_force=random_force
    )


def test_a_named_random_force_stops_after_the_first_effect(monkeypatch):
    """Friction at 5 floors (above the limit of 3): the rule, asked on the friction model,
    names a random force, and the harmonic is not added; without the rule it is."""
    asked = []

    def scatter(model):
        asked.append(model.name)
        return "the flights do not repeat where the model's do"

    sel = _select(monkeypatch, 5.0, scatter)
    assert [e for e, _f in sel["accepted"]] == ["friction"]
    assert sel["stop"] == "random_force"
    assert len(sel["rounds"]) == 1
    assert asked == ["friction"]
    plain = _select(monkeypatch, 5.0, None)
    assert [e for e, _f in plain["accepted"]] == ["friction", "harmonic"]
    silent = _select(monkeypatch, 5.0, lambda model: None)
    assert [e for e, _f in silent["accepted"]] == ["friction", "harmonic"]


@pytest.mark.parametrize("g_friction", [2.5, 3.0])
def test_the_rule_is_not_asked_within_the_unexplained_limit(monkeypatch, g_friction):
    """Friction at 2.5 or 3 floors (not above ``unexplained_ratio``): the next round runs
    and takes the harmonic; the rule is never asked."""
    asked = []

    def scatter(model):
        asked.append(model.name)
        return "scatter"

    sel = _select(monkeypatch, g_friction, scatter)
    assert [e for e, _f in sel["accepted"]] == ["friction", "harmonic"]
    assert asked == []
    assert select.SelectSettings().unexplained_ratio == 3.0
