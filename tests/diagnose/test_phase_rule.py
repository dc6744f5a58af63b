"""The takeoff-phase rule of the diagnosis (``gap.diagnose.sharp_phase_offset``): a
timing shift of every step is read, one step on another orbit is not."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from bouncelab.gap.diagnose import (
    MIN_FLOOR,
    PHASE_TOL,
    SHARP_FLOORS,
    phase_shift_reason,
    sharp_phase_offset,
)


def _case(offsets, floors=None):
    n = len(offsets)
    steps = pd.DataFrame({"step": np.arange(n), "gamma": 1.0 + 0.1 * np.arange(n)})
    floor = np.full(n, MIN_FLOOR) if floors is None else np.asarray(floors, dtype=float)
    problem = SimpleNamespace(steps=steps, floor=floor)
    # per-step table in another row order than the steps: it must be aligned by step
    per = pd.DataFrame({"step": steps["step"][::-1], "phase_offset": np.asarray(offsets)[::-1]})
    return problem, {"per_step": per}


def test_a_shift_of_every_step_is_read_in_full():
    """A 2 ms delay at 30 Hz: -0.377 rad at every step, small scatter (1e-3 rad)."""
    shift = -2e-3 * 2 * np.pi * 30
    off = shift + 1e-3 * np.sin(np.arange(12))
    out = sharp_phase_offset(*_case(off))
    assert out["median"] == pytest.approx(shift, abs=2e-3)
    assert abs(out["median"]) > PHASE_TOL and out["steps"] == "sharp" and out["n_steps"] == 12
    assert out["median_se"] < 2e-3
    assert "-0.377 rad (median over 12 sharp steps" in phase_shift_reason(out)


def test_one_step_on_another_orbit_moves_the_mean_not_the_median():
    """The blind seed-like case: ten steps within 0.21 rad, one at 0.72 rad."""
    off = [0.21, 0.14, 0.14, 0.10, 0.07, 0.04, 0.03, 0.02, 0.01, 0.03, 0.72]
    out = sharp_phase_offset(*_case(off))
    assert out["mean"] > PHASE_TOL  # the old rule flagged it
    assert out["median"] == pytest.approx(0.07, abs=1e-9)
    assert out["max_abs"] == pytest.approx(0.72)


def test_offsets_around_pi_do_not_jump():
    """Offsets either side of +-pi: the median lies near pi, not near 0."""
    off = np.array([3.10, -3.12, 3.05, -3.08, 3.13])
    med = sharp_phase_offset(*_case(off))["median"]
    assert abs(abs(med) - np.pi) < 0.1


def test_chaotic_steps_are_left_out_unless_fewer_than_three_are_sharp():
    off = [0.0, 0.0, 0.9, 0.9, 0.9]
    broad = SHARP_FLOORS * MIN_FLOOR * 2
    out = sharp_phase_offset(*_case(off, [MIN_FLOOR] * 3 + [broad] * 2))
    assert (out["median"], out["n_steps"], out["steps"]) == (0.0, 3, "sharp")
    out = sharp_phase_offset(*_case(off, [MIN_FLOOR] * 2 + [broad] * 3))
    assert (out["median"], out["n_steps"], out["steps"]) == (pytest.approx(0.9), 5, "all")


def test_no_step_with_flights_on_both_sides_gives_none():
    out = sharp_phase_offset(*_case([np.nan, np.nan, np.nan]))
    assert out["median"] is None and out["n_steps"] == 0
    assert phase_shift_reason(out) is None


def test_a_large_median_of_scattered_chaotic_steps_is_not_a_shift():
    """The shipped accel_g2-4: five chaotic steps, offsets -0.21 to +0.64 rad. The median
    (+0.18) is beyond 0.1 rad but within 2 standard errors of zero: no flag. The same
    median with a tenth of the scatter is flagged."""
    broad = [SHARP_FLOORS * MIN_FLOOR * 3] * 5
    off = np.array([-0.07, 0.64, 0.18, 0.28, -0.21])
    out = sharp_phase_offset(*_case(off, broad))
    assert out["steps"] == "all" and out["median"] == pytest.approx(0.18)
    assert out["median_se"] > out["median"] / 2
    assert phase_shift_reason(out) is None
    tight = sharp_phase_offset(*_case(0.18 + 0.1 * (off - 0.18), broad))
    assert phase_shift_reason(tight) is not None


def test_fewer_than_three_steps_never_flag():
    out = sharp_phase_offset(*_case([0.5, 0.5]))
    assert out["median"] == pytest.approx(0.5) and out["median_se"] is None
    assert phase_shift_reason(out) is None


@pytest.mark.parametrize(
    "median,hint",
    [(3.122, "close to pi"), (-3.0, "close to pi"), (1.5, "close to pi/2"), (-0.38, None)],
)
def test_an_offset_near_pi_or_half_pi_names_the_drive_wiring(median, hint):
    """A drive reference wired inverted (or an accelerometer) shifts every phase by pi;
    the reason then says so and what to add to ``drive_phase_offset_rad`` (minus the
    offset, which is model minus data; on raw/sweep_g0-4 with its drive inverted the
    diagnosis read +3.122 rad, and -3.1218 rad put the phases back within 0.02 rad). A
    delay-sized offset gets no such hint."""
    reason = phase_shift_reason(
        {"median": median, "median_se": 0.01, "n_steps": 10, "steps": "sharp"}
    )
    if hint is None:
        assert "drive_phase_offset_rad" not in reason
    else:
        assert hint in reason and f"add {-median:.4f} rad to drive_phase_offset_rad" in reason
