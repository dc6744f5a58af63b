"""Scoring of the blind validation: the true effects come from the rig's parameters, the
confusion matrix and error rates from the diagnoses. Known inputs, hand-counted outputs."""

from __future__ import annotations

from pathlib import Path

import pytest

from bouncelab.gap.blind import (
    LABELS,
    deep_merge,
    interval_hits,
    load_cases,
    merge_results,
    relative_errors,
    score_case,
    summarize,
    true_effects,
)


def _truth(mu=0.0, e=0.0, feedback=False, s=1.0, harmonics=(), **effects):
    eff = {
        "random_vibration_rms_m": 0.0, "drag_n_s_per_m": 0.0,
        "restitution_slope_s_per_m": 0.0, "sensor_delay_s": 0.0,
    } | effects  # fmt: skip
    return {
        "config": {
            "body": {"friction_mu": mu, "restitution": e},
            "drive": {"gamma_scale": s, "harmonics": list(harmonics)},
            "shaker": {"feedback": feedback, "damping_ratio": 0.05},
            "effects": eff,
        },
        "derived": {"mass_ratio": 0.1245, "f_ratio": 0.4667},
    }


def _diag(selected, params, unexplained=False):
    return {"selected": selected, "unexplained": unexplained,
            "final_model": {"params": params}}  # fmt: skip


def test_true_effects_from_rig_parameters():
    lib, out = true_effects(_truth(mu=0.2, feedback=True, sensor_delay_s=0.001))
    assert lib["friction"] == {"mu": 0.2}
    assert lib["feedback"] == {"mass_ratio": 0.1245, "f_ratio": 0.4667, "zeta": 0.05}
    assert out == ["sensor_delay"]
    lib, out = true_effects(_truth(harmonics=[{"k": 3.0, "a": 0.1}]))
    assert lib == {"harmonic": {"k": 3.0, "a": 0.1, "psi": 0.0}} and out == []


def test_relative_errors():
    """|0.22 - 0.2| / 0.2 = 0.1; psi wraps: 6.2 against 0.0 is 0.083 rad off, / 2 pi."""
    err = relative_errors({"mu": 0.2, "psi": 0.0}, {"mu": 0.22, "psi": 6.2})
    assert err["mu"] == pytest.approx(0.1)
    assert err["psi"] == pytest.approx((2 * 3.141592653589793 - 6.2) / (2 * 3.141592653589793))


def test_summary_counts():
    """Four cases counted by hand: friction right, gamma_scale confused with friction,
    a null with a false alarm, an out-of-library case flagged."""
    scores = {
        "f": score_case(_diag(["friction"], {"mu": 0.21}), _truth(mu=0.2)),
        "g": score_case(_diag(["friction"], {"mu": 0.1}), _truth(s=0.9)),
        "n": score_case(_diag([], {}, unexplained=True), _truth()),
        "o": score_case(_diag([], {}, unexplained=True), _truth(random_vibration_rms_m=1e-5)),
    }
    s = summarize(scores)
    cm = s["confusion"]
    i = {lab: k for k, lab in enumerate(LABELS)}
    assert cm[i["friction"]][i["friction"]] == 1
    assert cm[i["gamma_scale"]][i["friction"]] == 1
    assert cm[i["none"]][i["none"]] == 1
    assert s["top_effect_right"] == 0.5
    assert (s["n_null"], s["null_false_alarms"]) == (1, 1)
    assert (s["n_outside"], s["outside_flagged"]) == (1, 1)
    assert s["param_errors"] == {"friction.mu": [pytest.approx(0.05)]}


def test_spurious_second_effect_counts_against_the_set_not_the_top():
    """Restitution found first, then a harmonic it does not have: the top effect is
    right, the set is not."""
    scores = {
        "r": score_case(_diag(["restitution", "harmonic"], {"e": 0.2}), _truth(e=0.2)),
        "f": score_case(_diag(["friction"], {"mu": 0.2}), _truth(mu=0.2)),
    }
    s = summarize(scores)
    assert s["top_effect_right"] == 1.0
    assert (s["n_single"], s["single_set_right"]) == (2, 1)


def test_interval_hits_and_their_count():
    """mu 0.2 inside [0.15, 0.25], e 0.5 outside [0.3, 0.45]; psi 0.05 inside the interval
    [6.2, 6.4] that wraps past 2 pi (6.33 = 0.05 + 2 pi)."""
    hits = interval_hits(
        {"mu": 0.2, "e": 0.5, "psi": 0.05},
        {"mu": [0.15, 0.25], "e": [0.3, 0.45], "psi": [6.2, 6.4]},
    )
    assert hits == {"mu": True, "e": False, "psi": True}
    diag = _diag(["friction"], {"mu": 0.21})
    diag["steps"] = [{"params_ci": {"mu": [0.15, 0.19]}}]
    s = summarize({"f": score_case(diag, _truth(mu=0.2))})
    assert (s["n_params_in_interval"], s["n_params_scored"]) == (0, 1)


def test_parameters_counted_by_their_warnings():
    """mu 0.2 fitted 0.3 (50 % off) with a warning naming it, e 0.4 fitted 0.41 (2.5 %)
    without one, s 1.1 fitted 1.3 (18 %) without one: 2 outside the goal, 1 of them
    warned about; 2 unwarned, 1 of them within the goal."""
    diag = _diag(["friction", "restitution", "gamma_scale"], {"mu": 0.3, "e": 0.41, "s": 1.3})
    diag["steps"] = [{"warnings": ["mu=0.3 is poorly identified: interval 0.1 to 0.5"]}]
    sc = score_case(diag, _truth(mu=0.2, e=0.4, s=1.1))
    assert sc["param_warned"] == {
        "friction": {"mu": True}, "restitution": {"e": False}, "gamma_scale": {"s": False},
    }  # fmt: skip
    assert summarize({"c": sc})["param_warnings"] == {
        "n_params": 3, "n_outside_goal": 2, "n_outside_goal_warned": 1,
        "n_unwarned": 2, "n_unwarned_within_goal": 1,
    }  # fmt: skip


def test_case_file_merges_over_base():
    cases = load_cases(Path(__file__).parents[2] / "config" / "blind" / "cases.yaml")
    names = {c["name"] for c in cases}
    required = {"null_a", "friction_a", "restitution_a", "harmonic_a", "gamma_scale_a"}
    required |= {"seed_like", "ool_vibration", "ool_delay", "ool_vdep_restitution"}
    assert required <= names
    fr = next(c for c in cases if c["name"] == "friction_a")["rig"]
    assert fr["body"]["friction_mu"] == 0.15 and fr["body"]["restitution"] == 0.0
    assert deep_merge({"a": {"b": 1, "c": 2}}, {"a": {"b": 3}}) == {"a": {"b": 3, "c": 2}}


def test_merged_record_summarizes_every_case():
    """A re-run case replaces its record entry, a new one is added, and the summaries
    are those of the merged cases: one null false alarm before, none after the re-run
    of that case; the new friction case counts in its set."""

    def entry(diag, truth, kind_set):
        return {**score_case(diag, truth), "set": kind_set}

    record = {
        "cases": {
            "n": entry(_diag(["friction"], {"mu": 0.1}), _truth(), "validation"),
            "f": entry(_diag(["friction"], {"mu": 0.2}), _truth(mu=0.2), "development"),
        },
        "timings": {"n": {"diagnose_s": 1.0}, "f": {"diagnose_s": 2.0}},
    }
    assert summarize(record["cases"])["null_false_alarms"] == 1
    new = {
        "cases": {
            "n": entry(_diag([], {}), _truth(), "validation"),
            "g": entry(_diag(["friction"], {"mu": 0.3}), _truth(mu=0.3), "validation"),
        },
        "timings": {"n": {"diagnose_s": 3.0}, "g": {"diagnose_s": 4.0}},
    }
    merged = merge_results(record, new)
    assert set(merged["cases"]) == {"n", "f", "g"}
    assert merged["timings"]["n"] == {"diagnose_s": 3.0}
    assert merged["summary"]["null_false_alarms"] == 0
    assert merged["summary"]["n_single"] == 2
    assert merged["by_set"]["validation"]["n_single"] == 1
    assert merged["by_set"]["development"]["n_single"] == 1
