"""The verdict's margin: the final held-out gap in noise floors, its standard error over
the held-out steps, and the run-level warnings it gives. References: the weighted means
of :class:`bouncelab.gap.fit.Problem` (the identity below) and standard errors by hand."""

from __future__ import annotations

import numpy as np
import pytest

from bouncelab.gap.diagnose import FEW_HELDOUT, margin_warnings, verdict_margin
from bouncelab.gap.fit import GAP_CAP, Problem


def problem_of(floor, heldout) -> Problem:
    """A :class:`Problem` with only the per-step floors and held-out design set: all that
    :meth:`Problem.mean` and :meth:`Problem.clipped` read."""
    p = Problem.__new__(Problem)
    p.floor = np.asarray(floor, dtype=float)
    p.heldout = np.asarray(heldout, dtype=bool)
    return p


def test_the_margin_is_the_diagnosis_gap_over_its_floor_with_the_standard_error_of_a_mean():
    """Reference: the diagnosis's ``final_gap / noise_floor`` (both weighted means over
    held-out steps, weights 1 / floor) is the plain mean of each held-out step's gap over
    its floor; here 1, 3, 5 (the fitted steps' 99 ignored): mean 3, standard error
    std(ddof=1) / sqrt(3) = 2 / sqrt(3)."""
    floor = np.array([0.1, 0.05, 0.2, 0.4, 0.3])
    heldout = np.array([False, True, True, False, True])
    gaps = floor * np.array([99.0, 1.0, 3.0, 99.0, 5.0])
    p = problem_of(floor, heldout)
    m = verdict_margin(p, gaps, limit=3.0)
    assert m["rel_gap"] == pytest.approx(p.mean(gaps, heldout) / p.mean(p.floor, heldout))
    assert m["rel_gap"] == pytest.approx(3.0)
    assert m["se"] == pytest.approx(2.0 / np.sqrt(3.0))
    assert m["n_heldout"] == 3 and m["borderline"] is True
    # the same spread far from the limit: not borderline
    assert verdict_margin(p, gaps, limit=6.0)["borderline"] is False


def test_the_margin_reads_each_step_capped_as_the_objective_does():
    """A step on another orbit counts GAP_CAP floors, not its hundreds: ratios 1 and
    GAP_CAP, mean (1 + GAP_CAP) / 2."""
    p = problem_of([0.1, 0.1], [True, True])
    m = verdict_margin(p, np.array([0.1, 50.0]), limit=3.0)
    assert m["rel_gap"] == pytest.approx((1.0 + GAP_CAP) / 2)


def test_one_heldout_step_has_no_standard_error_and_warns_of_few_steps():
    """One held-out step: no standard error, no borderline judgement, and the warning
    that the verdict rests on it alone."""
    p = problem_of([0.1, 0.1, 0.1], [False, True, False])
    m = verdict_margin(p, np.array([0.1, 0.35, 0.1]), limit=3.0)
    assert m["se"] is None and m["borderline"] is None
    (warning,) = margin_warnings(m, [2.5])
    assert "only 1 Gamma step is held out (2.5)" in warning


@pytest.mark.parametrize("n", [FEW_HELDOUT - 1, FEW_HELDOUT])
def test_few_heldout_steps_are_named_and_a_borderline_verdict_is_stated(n):
    """Below FEW_HELDOUT held-out steps the warning names them; a gap within one
    standard error of the limit (ratios alternating 2 and 4 around the limit 3) is
    called borderline with its numbers."""
    ratios = np.resize([2.0, 4.0], n)
    p = problem_of(np.full(n, 0.1), np.ones(n, dtype=bool))
    m = verdict_margin(p, 0.1 * ratios, limit=3.0)
    warnings = margin_warnings(m, np.linspace(1.0, 2.0, n))
    few = [w for w in warnings if w.startswith("only")]
    assert len(few) == (1 if n < FEW_HELDOUT else 0)
    (borderline,) = [w for w in warnings if "borderline" in w]
    assert f"+- {m['se']:.2g} noise floors (standard error over {n} held-out steps)" in (borderline)


def test_a_clear_verdict_gives_no_warning():
    """Ten held-out steps at 1 +- 0.1 floors against the limit 3: nothing to say."""
    ratios = 1.0 + 0.1 * np.resize([-1.0, 1.0], 10)
    p = problem_of(np.full(10, 0.1), np.ones(10, dtype=bool))
    m = verdict_margin(p, 0.1 * ratios, limit=3.0)
    assert m["borderline"] is False and margin_warnings(m, np.arange(10.0)) == []


@pytest.mark.parametrize("borderline", [True, False, None])
def test_the_command_line_names_a_borderline_verdict_with_its_margin(borderline):
    """``bouncelab diagnose`` prints its one line with the margin only when the verdict
    is borderline (reference: the values given, as formatted)."""
    from pathlib import Path

    from bouncelab.cli.diagnose import summary_line

    result = {
        "selected": ["restitution", "feedback"], "unexplained": True, "final_gap": 1.613,
        "noise_floor": 0.5348, "baseline": {"gap": 3.241},
        "verdict_margin": {"rel_gap": 3.015, "se": 2.009, "limit": 3.0, "borderline": borderline},
    }  # fmt: skip
    line = summary_line(Path("out.json"), result)
    assert line.startswith("wrote out.json: selected restitution, feedback; gap 3.241 -> 1.613")
    tail = " (borderline: 3.02 +- 2 noise floors against the limit 3)"
    assert line.endswith("unexplained" + tail) == bool(borderline)
    assert line.endswith(", unexplained") == (not borderline)
