"""Model variants: effect names, parameters, fit bounds (CONTRACTS.md section 5).

A :class:`Model` is an immutable combination of effects on top of the ideal,
completely inelastic ball on a sinusoidal plate.  Parameter names are the ``--set``
names of the command line.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np

from bouncelab.errors import BouncelabError

#: effect name -> parameter -> (default, lower, upper).  The bounds are the physically
#: sensible range a fit may explore (used by ``bouncelab.gap``); the defaults are the
#: seed paper's values where it gives one (mu 0.29, e 0.515, third harmonic).
EFFECTS: dict[str, dict[str, tuple[float, float, float]]] = {
    "friction": {"mu": (0.29, 0.0, 0.6)},
    "restitution": {"e": (0.515, 0.0, 0.95)},
    "harmonic": {
        "k": (3.0, 0.1, 6.0),
        "a": (0.1, 0.0, 0.5),
        "psi": (0.0, 0.0, 2.0 * math.pi),
    },
    "feedback": {
        "mass_ratio": (0.05, 0.0, 0.5),
        "f_ratio": (0.5, 0.05, 3.0),
        "zeta": (0.1, 0.01, 1.0),
        # 0: the armature feels impacts only (CONTRACTS.md section 5); 1: also the full
        # contact force of a riding body (weight and inertia), as a real shaker does
        "ride_load": (0.0, 0.0, 1.0),
    },
    "gamma_scale": {"s": (1.0, 0.7, 1.3)},
}

#: canonical order of effects in a model name
EFFECT_ORDER: tuple[str, ...] = tuple(EFFECTS)

#: physical validity (not the fit bounds): predicate and its statement per parameter
_VALID = {
    "mu": (lambda v: 0.0 <= v < 1.0, "must be in [0, 1) (friction below the weight)"),
    "e": (lambda v: 0.0 <= v < 1.0, "must be in [0, 1)"),
    "k": (lambda v: v > 0.0, "must be > 0"),
    "a": (lambda v: True, ""),
    "psi": (lambda v: True, ""),
    "mass_ratio": (lambda v: v >= 0.0, "must be >= 0"),
    "f_ratio": (lambda v: v > 0.0, "must be > 0"),
    "zeta": (lambda v: v >= 0.0, "must be >= 0"),
    "ride_load": (lambda v: 0.0 <= v <= 1.0, "must be in [0, 1]"),
    "s": (lambda v: v > 0.0, "must be > 0"),
}

_OWNER = {p: eff for eff, ps in EFFECTS.items() for p in ps}


def _number(name: str, value) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise BouncelabError(None, f"parameter {name}={value!r} is not a number") from None
    if not math.isfinite(v):
        raise BouncelabError(None, f"parameter {name}={value!r} is not finite")
    ok, why = _VALID[name]
    if not ok(v):
        raise BouncelabError(None, f"parameter {name}={v:g} {why}")
    return v


def _harmonic_list(value) -> tuple[tuple[float, float, float], ...]:
    try:
        triples = [tuple(t) for t in value]
    except TypeError:
        raise BouncelabError(None, "harmonics must be a list of (k, a, psi) triples") from None
    out = []
    for t in triples:
        if len(t) != 3:
            raise BouncelabError(None, f"harmonic {t!r} is not a (k, a, psi) triple")
        out.append((_number("k", t[0]), _number("a", t[1]), _number("psi", t[2])))
    return tuple(out)


@dataclass(frozen=True, eq=True)
class Model:
    """A combination of effects with all its parameters (defaults filled).

    Attributes
    ----------
    effects : tuple of str
        Effect names in canonical order (``EFFECT_ORDER``); empty for ``ideal``.
    params : dict
        Every parameter of every selected effect, as floats.  For ``harmonic`` the
        ``k``, ``a``, ``psi`` entries are those of the first harmonic.
    harmonics : tuple of (k, a, psi)
        All plate harmonics (empty unless ``harmonic`` is selected).
    """

    effects: tuple[str, ...] = ()
    params: dict = field(default_factory=dict, hash=False)
    harmonics: tuple[tuple[float, float, float], ...] = ()

    @classmethod
    def parse(cls, name: str, params: Mapping | None = None) -> Model:
        """Build a model from ``"friction+restitution"`` and a parameter mapping.

        ``params`` may also hold ``harmonics``: a list of ``(k, a, psi)`` triples
        (explicit ``k``/``a``/``psi`` then override the first triple).  Unknown effects,
        unknown parameters, parameters of effects not in the model and physically
        impossible values raise :class:`BouncelabError`.
        """
        params = dict(params or {})
        parts = [p.strip() for p in str(name).split("+")]
        if any(not p for p in parts):
            raise BouncelabError(None, f"model name {name!r} has an empty part")
        chosen = set()
        for p in parts:
            if p == "ideal":
                continue
            if p not in EFFECTS:
                raise BouncelabError(
                    None,
                    f"unknown model effect {p!r}; choose from ideal, " + ", ".join(EFFECT_ORDER),
                )
            if p in chosen:
                raise BouncelabError(None, f"effect {p!r} appears twice in {name!r}")
            chosen.add(p)
        effects = tuple(e for e in EFFECT_ORDER if e in chosen)
        harmonics_in = params.pop("harmonics", None)
        for key in params:
            owner = _OWNER.get(key)
            if owner is None:
                known = ", ".join(_OWNER)
                raise BouncelabError(None, f"unknown parameter {key!r}; known: {known}")
            if owner not in chosen:
                raise BouncelabError(
                    None,
                    f"parameter {key!r} belongs to effect {owner!r}, which is not in the model",
                )
        values: dict[str, float] = {}
        for eff in effects:
            for p, (default, _lo, _hi) in EFFECTS[eff].items():
                values[p] = _number(p, params.get(p, default))
        harmonics: tuple = ()
        if "harmonic" in chosen:
            if harmonics_in is not None:
                harmonics = _harmonic_list(harmonics_in)
                if not harmonics:
                    raise BouncelabError(None, "harmonics must hold at least one triple")
                first = list(harmonics[0])
                for i, p in enumerate(("k", "a", "psi")):
                    if p in params:
                        first[i] = values[p]
                    values[p] = first[i]
                harmonics = (tuple(first), *harmonics[1:])
            else:
                harmonics = ((values["k"], values["a"], values["psi"]),)
        elif harmonics_in is not None:
            raise BouncelabError(None, "harmonics given but 'harmonic' is not in the model")
        return cls(effects=effects, params=values, harmonics=harmonics)

    @property
    def name(self) -> str:
        """Canonical name, e.g. ``"friction+restitution"``; ``"ideal"`` without effects."""
        return "+".join(self.effects) if self.effects else "ideal"

    def with_params(self, **changes) -> Model:
        """A copy with some parameters changed (``harmonics=[...]`` replaces the list)."""
        merged = dict(self.params)
        if self.harmonics:
            merged["harmonics"] = self.harmonics
            # an explicit k/a/psi edits the first triple only
        merged.update(changes)
        if self.harmonics and "harmonics" in changes:
            for p in ("k", "a", "psi"):
                if p not in changes:
                    merged.pop(p, None)
        return Model.parse(self.name, merged)

    def __hash__(self) -> int:
        return hash((self.effects, tuple(sorted(self.params.items())), self.harmonics))

    # --- what the kernels need -------------------------------------------------------
    def gamma_true(self, gamma_stated):
        """True Gamma that drives the plate: ``s * stated`` (gamma_scale), else stated."""
        return np.asarray(gamma_stated, dtype=float) * self.params.get("s", 1.0)

    def harmonic_arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(k, a, psi)`` arrays of shape ``(n_harmonics,)``; harmonics with ``a = 0`` dropped."""
        hs = [h for h in self.harmonics if h[1] != 0.0]
        if not hs:
            z = np.zeros(0)
            return z, z.copy(), z.copy()
        arr = np.array(hs, dtype=float)
        return arr[:, 0].copy(), arr[:, 1].copy(), arr[:, 2].copy()


def rigid_plate_restitution(e: float, mass_ratio: float) -> float:
    """The restitution of the body's rebound from the plate's velocity *before* the impact,
    for a two-body impact of restitution ``e`` with an armature of mass ratio
    ``mass_ratio`` (both dimensionless; ``e`` as the model defines it: the relative
    velocity after the impact is ``-e`` times before, both against the recoiling plate).

    Another convention that a simulation may use: the body rebounds at ``-e_r`` times its
    speed relative to the plate as it was, as from an infinitely heavy plate, and the
    armature then takes the momentum ``m (1 + e_r) |u|``. Both conserve momentum; the
    armature's kick is the same when ``1 + e = (1 + e_r)(1 + mass_ratio)``, so
    ``e_r = (e - mass_ratio) / (1 + mass_ratio)``. Why it matters: with m/M 0.04 the
    two conventions differ by 0.06 in ``e`` (12 % of e 0.5); fitted to a recording
    made with the other one (benchmarks/independent_rig.py), the model's ``e`` is
    0.571 for its 0.5, ``e_r`` 0.503. With ``mass_ratio = 0`` both are ``e``.
    """
    return (float(e) - float(mass_ratio)) / (1.0 + float(mass_ratio))


def two_body_restitution(e_r: float, mass_ratio: float) -> float:
    """The model's ``e`` for a rigid-plate restitution ``e_r`` beside an armature of mass
    ratio ``mass_ratio``: the inverse of :func:`rigid_plate_restitution`,
    ``e = e_r (1 + mass_ratio) + mass_ratio``. Why: a recording made in that other
    convention is scored against the model in its own; with m/M 0.05 an ``e_r`` of 0.4
    is the model's 0.47, and 0.01 off in ``e`` costs 0.2 noise floors there
    (docs/diagnosis-log.md, session 51)."""
    return float(e_r) * (1.0 + float(mass_ratio)) + float(mass_ratio)


def parse_assignments(items: Iterable[str]) -> dict[str, float]:
    """Turn ``["mu=0.29", "e=0.5"]`` into a dict; bad items raise :class:`BouncelabError`."""
    out: dict[str, float] = {}
    for item in items:
        key, sep, value = str(item).partition("=")
        key = key.strip()
        if not sep or not key:
            raise BouncelabError(None, f"--set {item!r} is not NAME=VALUE")
        if key not in _OWNER:
            raise BouncelabError(None, f"--set {item!r}: unknown parameter {key!r}")
        out[key] = _number(key, value.strip())
    return out
