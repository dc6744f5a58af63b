"""Round-1 candidates in the diagnosis JSON (CONTRACTS.md section 6): each effect added
alone to the baseline and refitted. A refit cannot do worse than its own null value (the
baseline itself, the same flights to the bit), so a search that ended worse on its fit
steps is reported there. Found by a black-box probe: on an ideal-ball recording the
restitution candidate came out at its start e 0.515, 55 times the baseline's gap."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from bouncelab.gap.diagnose import candidate_entry
from bouncelab.physics import Model, simulate_protocol


def fit_of(name, params, objective):
    """What candidate_entry reads of a FitResult: the model, its objective, n_evals."""
    return SimpleNamespace(model=Model.parse(name, params), objective=objective, n_evals=18)


def test_a_search_that_ends_worse_than_the_baseline_is_reported_at_its_null():
    entry = candidate_entry(
        "restitution", fit_of("restitution", {"e": 0.515}, 0.26), 0.25, 0.0048, 0.0045
    )
    assert entry["params"] == {"e": 0.0}
    assert entry["gap"] == 0.0045 and entry["gap_fit"] == 0.0048
    assert entry["shrink"] == 0.0 and entry["at_null"] is True
    harmonic = candidate_entry(
        "harmonic", fit_of("harmonic", {"k": 2.0, "a": 0.1, "psi": 1.0}, 0.3), 0.4, 0.1, 0.2
    )
    assert harmonic["params"]["a"] == 0.0 and harmonic["params"]["k"] == 2.0


def test_a_search_better_on_its_fit_steps_is_reported_as_found_even_if_worse_held_out():
    """Held-out steps judge flexibility: a fit better on its own steps and worse on the
    held-out ones is an honest negative shrink (friction mu 0.0033 on an ideal run)."""
    entry = candidate_entry(
        "friction", fit_of("friction", {"mu": 0.0033}, 0.0031), 0.0196, 0.0048, 0.0045
    )
    assert entry["params"] == {"mu": 0.0033}
    assert entry["shrink"] == pytest.approx((0.0045 - 0.0196) / 0.0045)
    assert "at_null" not in entry


@pytest.mark.parametrize(
    "name, params",
    [
        ("restitution", {"e": 0.0}),
        ("friction", {"mu": 0.0}),
        ("harmonic", {"k": 2.0, "a": 0.0, "psi": 1.0}),
        ("feedback", {"mass_ratio": 0.0, "f_ratio": 0.7, "zeta": 0.2}),
        ("gamma_scale", {"s": 1.0}),
    ],
)
def test_each_null_value_is_the_ideal_ball_to_the_bit(name, params):
    """Why the baseline's gaps may stand for the candidate at its null: the flights are
    the same numbers, under the lab's protocol (reference: the ideal model's own)."""
    gammas, cycles = np.linspace(0.5, 4.5, 17), np.full(17, 40)
    ideal = simulate_protocol(Model.parse("ideal"), gammas, cycles)
    null = simulate_protocol(Model.parse(name, params), gammas, cycles)
    assert len(ideal) > 300
    np.testing.assert_array_equal(null["T"].to_numpy(), ideal["T"].to_numpy())


def test_a_held_strength_is_reported_as_held():
    """With --fix-calibration the candidate is friction at the calibrated mu, not refitted:
    it stays there even where it does worse than the baseline."""
    entry = candidate_entry(
        "friction", fit_of("friction", {"mu": 0.05}, 0.3), 0.4, 0.1, 0.2, fixed={"mu": 0.05}
    )
    assert entry["params"] == {"mu": 0.05} and "at_null" not in entry
