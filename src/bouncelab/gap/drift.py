"""Does a selected effect's strength depend on Gamma? A check for effects outside the library.

Pole friction (``mu``), restitution (``e``) and a harmonic's share of the drive (``a``)
are constants of the model. Their look-alikes outside the library are not: air drag
grows with the body's speed, and a restitution that falls with impact speed changes
with it; both speeds grow with Gamma. A random vibration of the plate, taken for a
harmonic, is a fixed amplitude in metres, a share of the drive that falls as the drive
grows (the blind ``ool_vibration_b``: a 0.143 below the median Gamma, 0.103 above).
Fitted over a whole sweep, such an effect is taken for the library's constant one, at a
compromise value, and can leave little gap (the blind cases ``ool_drag`` and
``g_ool_drag``: friction, mu 0.025, explained). Fitted on the low and on the high half
of the Gamma steps apart, the compromise splits: mu 0.000 against 0.026 for drag, e
0.085 against 0.163 for a speed-dependent restitution, while the rig's true friction and
restitution agree within 9 % of their value in every blind case of one or two effects,
and within 20 % beside the shaker's armature (docs/diagnosis-log.md, session 15).

:func:`strength_by_half` refits the one strength parameter of each such selected effect,
every other parameter held at its final value, on the fit steps of each half;
:func:`drift_reason` names a difference beyond both :data:`DRIFT_REL` of the final value
and :data:`DRIFT_ABS`.
"""

from __future__ import annotations

import numpy as np

from bouncelab.gap.fit import Problem, step_gaps
from bouncelab.physics import EFFECTS, Model
from bouncelab.physics.simulate import OutputBuffer

#: The effects checked and their strength parameter. Not the armature: its mass ratio
#: sits in a flat valley beside friction and restitution, and the true one of the blind
#: seed-like cases splits by up to 103 % between the halves (docs/diagnosis-log.md,
#: session 27).
DRIFT_PARAMS = {"friction": "mu", "restitution": "e", "harmonic": "a"}

#: A difference between the halves beyond this share of the final value (twice the
#: largest of a true friction or restitution in the blind cases, 20 %: friction beside
#: the armature; four times that of a true harmonic, 5 % in the blind cases over five
#: diagnosis seeds and 6.5 % in the independent ones)...
DRIFT_REL = {"mu": 0.4, "e": 0.4, "a": 0.2}

#: ...and beyond this absolute difference is a strength that depends on Gamma. Four times
#: the tolerance below which the selection calls the effect inert (``select.INERT``):
#: the blind cases' true effects differ by at most 0.010 in mu, 0.034 in e and 0.0025
#: in a.
DRIFT_ABS = {"mu": 0.02, "e": 0.04, "a": 0.01}

#: Values of the coarse scan over ``[0, 2 x final + 2 x DRIFT_ABS]`` and of the fine
#: scan around each half's best (one coarse step either side).
COARSE_POINTS = 21
FINE_POINTS = 11


def strength_by_half(problem: Problem, model: Model) -> dict:
    """Strength of each checked effect of ``model`` refitted on each half of the steps.

    The steps are split at the median of their Gamma (the lower half includes it); each
    half's value minimises the objective (:meth:`Problem.mean`) over that half's fit
    steps, by a scan of :data:`COARSE_POINTS` values then :data:`FINE_POINTS` around
    the best. One simulation of the whole protocol serves both halves at each value.

    Returns
    -------
    dict effect -> ``{"param", "final", "low", "high", "gamma_split"}`` (values in the
    parameter's units, ``gamma_split`` the median Gamma); empty when ``model`` has no
    checked effect or a half has no fit step.
    """
    gamma = problem.steps["gamma"].to_numpy(dtype=float)
    split = float(np.median(gamma))
    halves = {"low": problem.fit & (gamma <= split), "high": problem.fit & (gamma > split)}
    if not all(m.any() for m in halves.values()):
        return {}
    buffer = OutputBuffer()
    out = {}
    for effect, name in DRIFT_PARAMS.items():
        if effect not in model.effects:
            continue
        final = float(model.params[name])
        _default, lower, upper = EFFECTS[effect][name]
        hi = min(float(upper), 2.0 * final + 2.0 * DRIFT_ABS[name])
        best = _half_optima(problem, model, name, (max(float(lower), 0.0), hi), halves, buffer)
        out[effect] = {"param": name, "final": final, **best, "gamma_split": split}
    return out


def _half_optima(
    problem: Problem, model: Model, name: str, bounds: tuple, halves: dict, buffer
) -> dict:
    """Per half (name -> bool mask (G,) of its fit steps), the value of parameter
    ``name`` within ``bounds`` with the least mean gap: a coarse scan, then a fine one
    around the best. Each value is simulated once for all halves."""
    lo, hi = bounds
    cache: dict[float, np.ndarray] = {}

    def gaps(value: float) -> np.ndarray:
        value = float(np.clip(value, lo, hi))
        if value not in cache:
            trial = Model.parse(model.name, {**model.params, name: value})
            cache[value] = step_gaps(problem, trial, buffer)
        return cache[value]

    coarse = np.linspace(lo, hi, COARSE_POINTS)
    width = coarse[1] - coarse[0]
    best = {}
    for half, mask in halves.items():
        values = [problem.mean(gaps(v), mask) for v in coarse]
        v0 = float(coarse[int(np.argmin(values))])
        fine = np.linspace(max(lo, v0 - width), min(hi, v0 + width), FINE_POINTS)
        values = [problem.mean(gaps(v), mask) for v in fine]
        best[half] = float(fine[int(np.argmin(values))])
    return best


def drift_reason(by_half: dict) -> str | None:
    """One line naming the effects whose halves differ beyond :data:`DRIFT_REL` of the
    final value and :data:`DRIFT_ABS` (:func:`strength_by_half` output), else None."""
    parts = []
    for effect, r in by_half.items():
        diff = abs(r["high"] - r["low"])
        if diff > DRIFT_ABS[r["param"]] and diff > DRIFT_REL[r["param"]] * abs(r["final"]):
            parts.append(
                f"{effect}'s {r['param']} is {r['low']:.3g} below Gamma {r['gamma_split']:.3g} "
                f"and {r['high']:.3g} above"
            )
    if not parts:
        return None
    return "; ".join(parts) + ": a strength that changes with Gamma, which no library effect has"
