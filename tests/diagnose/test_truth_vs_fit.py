"""The benchmark that tells a blind case's search misses from its objective's
(``benchmarks/bench_truth_vs_fit.py``): which cases it takes, and which truth it scores."""

from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[2] / "benchmarks"))
from bench_truth_vs_fit import independent_true_params, missed_cases, truth_points  # noqa: E402


def test_only_cases_with_a_parameter_beyond_the_goal_are_taken():
    scores = {
        "cases": {
            "a": {"param_errors": {"friction": {"mu": 0.149}}},
            "b": {"param_errors": {"feedback": {"mass_ratio": 0.01, "zeta": 0.151}}},
            "c": {"param_errors": {}},
            "d": {"param_errors": {"restitution": {"e": 0.57}}, "outside": ["e_slope"]},
        }
    }
    assert missed_cases(scores) == ["b"]


def test_the_truth_gets_its_effects_and_the_models_extra_effect_its_null_value():
    """w_friction_harmonic's shape: the diagnosis added a Gamma miscalibration the
    truth lacks (scored at s = 1) and has every true parameter in place of its fit."""
    diagnosis = {
        "final_model": {
            "model": "friction+harmonic+gamma_scale",
            "params": {"mu": 0.2, "k": 2.0, "a": 0.07, "psi": 1.0, "s": 0.98},
        }
    }
    true = {"friction": {"mu": 0.25}, "harmonic": {"k": 2.0, "a": 0.1, "psi": 1.1}}
    name, points = truth_points(diagnosis, true)
    assert name == "friction+harmonic+gamma_scale"
    assert points == [{"mu": 0.25, "k": 2.0, "a": 0.1, "psi": 1.1, "s": 1.0}]


def test_an_armature_is_scored_with_both_ride_load_choices_and_a_missing_effect_added():
    diagnosis = {
        "final_model": {
            "model": "restitution+feedback",
            "params": {"e": 0.5, "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 0.0},
        }
    }
    true = {
        "friction": {"mu": 0.29},
        "restitution": {"e": 0.515},
        "feedback": {"mass_ratio": 0.0415, "f_ratio": 0.6, "zeta": 0.04},
    }
    name, points = truth_points(diagnosis, true)
    assert name == "friction+restitution+feedback"
    assert [p["ride_load"] for p in points] == [0.0, 1.0]
    assert all(p["mu"] == 0.29 and p["zeta"] == 0.04 for p in points)


def test_the_independent_generators_restitution_is_scored_in_the_models_convention():
    """Beside an armature the generator's rigid-plate e 0.4 (m/M 0.05) is the model's
    0.47 (e = e_r (1 + r) + r); without one, and the other parameters, unchanged."""
    effects = {
        "restitution": {"e": 0.4},
        "feedback": {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05},
    }
    true = independent_true_params(effects)
    assert abs(true["restitution"]["e"] - 0.47) < 1e-12
    assert true["feedback"] == effects["feedback"]
    assert effects["restitution"]["e"] == 0.4  # the generator's truth is not modified
    assert independent_true_params({"restitution": {"e": 0.4}}) == {"restitution": {"e": 0.4}}
