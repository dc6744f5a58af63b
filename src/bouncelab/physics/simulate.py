"""Protocols: arrange kernel runs and build flight DataFrames (units in docs/architecture.md).

- :func:`simulate_grid`: each Gamma from rest (or given start phases), transients skipped;
- :func:`simulate_protocol`: the lab protocol, Gamma steps with the state carried over;
- :func:`simulate_drop`: a body released above a still plate (drop test).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bouncelab.errors import BouncelabError
from bouncelab.physics import kernels as K
from bouncelab.physics.model import Model

#: a predicted chatter flight shorter than this (rad) ends the chatter: the rest of the
#: geometric series is summed analytically and the body sticks
CHATTER_EPS = 1e-5
#: relative height counted as contact (nondimensional; 1e-13 g/omega^2 is ~1e-16 m at 30 Hz)
CONTACT_TOL = 1e-13
#: hard cap on impacts in one chatter sequence
CHATTER_CAP = 10_000
#: a ride longer than this many drive cycles without takeoff counts as stuck
RIDE_CYCLES = 64

_NO_END = np.int64(2**50)  # "no step boundary" for a single-Gamma run

FLIGHT_COLUMNS = (
    "gamma",
    "T",
    "phi_takeoff",
    "phi_landing",
    "v_impact",
    "e_friction",
    "e_impact",
    "e_plate",
    "chatter",
    "start",
    "flight",
    "x_takeoff",
    "v_takeoff",
    "tail",
)
_COLS = {
    "gamma": K.C_GAMMA,
    "T": K.C_T,
    "phi_takeoff": K.C_PHI0,
    "phi_landing": K.C_PHIL,
    "v_impact": K.C_VIMP,
    "e_friction": K.C_EFRIC,
    "e_impact": K.C_EIMP,
    "e_plate": K.C_EPLATE,
    "chatter": K.C_CHAT,
    "start": K.C_START,
    "flight": K.C_FLIGHT,
    "x_takeoff": K.C_X0,
    "v_takeoff": K.C_V0,
    "tail": K.C_TAIL,
    "step": K.C_STEP,
    "t_takeoff": K.C_TTO,
    "settled": K.C_SETTLED,
}
_BOOL = {"chatter", "settled"}
_INT = {"start", "flight", "step"}


def kernel_params(model: Model, fast: bool = True) -> np.ndarray:
    """The ``par`` vector of :mod:`bouncelab.physics.kernels` for ``model``, shape ``(NPAR,)``.

    ``fast=False`` sends pure sine plates through the general landing solver too (the
    before/after comparison of ``tests/physics/test_fastpath_*.py``).
    """
    p = model.params
    par = np.zeros(K.NPAR)
    par[K.P_S] = p.get("s", 1.0)
    par[K.P_MU] = p.get("mu", 0.0)
    par[K.P_E] = p.get("e", 0.0)
    par[K.P_R] = p.get("mass_ratio", 0.0)
    par[K.P_F] = p.get("f_ratio", 1.0)
    par[K.P_Z] = p.get("zeta", 0.0)
    par[K.P_LOAD] = p.get("ride_load", 0.0)
    par[K.P_EPS] = CHATTER_EPS
    par[K.P_HTOL] = CONTACT_TOL
    par[K.P_CAP] = CHATTER_CAP
    par[K.P_RIDE] = RIDE_CYCLES * 2.0 * math.pi
    par[K.P_FAST] = 1.0 if fast else 0.0
    par[K.P_ENERGY] = 1.0
    par[K.P_ALLCOLS] = 1.0
    return par


def _check_model(model) -> Model:
    if not isinstance(model, Model):
        raise BouncelabError(None, f"expected a physics.Model, got {type(model).__name__}")
    return model


def _gamma_array(gammas, what="gamma") -> np.ndarray:
    g = np.atleast_1d(np.asarray(gammas, dtype=float))
    if g.ndim != 1 or g.size == 0:
        raise BouncelabError(None, f"{what} must be a non-empty 1-D list of numbers")
    if not np.all(np.isfinite(g)) or np.any(g < 0):
        raise BouncelabError(None, f"{what} values must be finite and >= 0")
    return g


def _start_phases(phi_start, n_starts: int, seed: int) -> np.ndarray:
    """Start phases, shape ``(n_starts,)``: given, phase 0 for one start, or seeded uniform."""
    if phi_start is not None:
        ph = np.atleast_1d(np.asarray(phi_start, dtype=float))
        if ph.ndim != 1 or ph.size == 0 or not np.all(np.isfinite(ph)):
            raise BouncelabError(None, "phi_start must be finite numbers")
        return np.mod(ph, 2.0 * np.pi)
    if int(n_starts) < 1:
        raise BouncelabError(None, f"n_starts must be >= 1, not {n_starts}")
    if n_starts == 1:
        return np.zeros(1)
    return np.random.default_rng(seed).uniform(0.0, 2.0 * np.pi, int(n_starts))


def _frame(out: np.ndarray, columns, keep=None) -> pd.DataFrame:
    """DataFrame from ``out[column, row]``, keeping the rows where ``keep`` (default all).

    Float columns are views into ``out`` when nothing is dropped (``copy=False``: no
    block consolidation, which costs seconds for millions of rows).
    """
    data = {}
    for name in columns:
        col = out[_COLS[name]]
        if keep is not None:
            col = col[keep]
        if name in _BOOL:
            data[name] = col > 0.5
        elif name in _INT:
            data[name] = col.astype(np.int64)
        else:
            data[name] = col
    return pd.DataFrame(data, copy=False)


def _written(rows, max_rec):
    """Mask of the written rows of each trajectory block (None when every block is full)."""
    if np.all(rows == max_rec):
        return None
    idx = np.arange(max_rec)
    return (idx[None, :] < rows[:, None]).ravel()


def simulate_grid(
    model: Model,
    gammas,
    n_flights: int,
    n_skip: int = 0,
    phi_start=None,
    n_starts: int = 1,
    seed: int = 0,
) -> pd.DataFrame:
    """Each Gamma on its own: the body starts at rest on the plate, flights are recorded.

    Parameters
    ----------
    model : Model
    gammas : array_like, shape (n_gamma,)
        Stated Gamma values (``gamma_scale`` multiplies them for the plate).
    n_flights : int
        Flights recorded per Gamma and start (fewer if the body sticks for good,
        e.g. none below Gamma = 1 for ``ideal``).
    n_skip : int
        Transient flights dropped before recording.
    phi_start : float or array_like, optional
        Start phases (rad) of the body resting on the plate; default phase 0 for one
        start, seeded uniform phases for ``n_starts > 1``.
    n_starts, seed : int
        Ensemble size and the seed of its start phases.

    Returns
    -------
    DataFrame, one row per flight, ordered by Gamma, start, flight: ``FLIGHT_COLUMNS``
    (``T``, phases in rad, velocities in g/omega, energies per mass in (g/omega)^2).
    """
    model = _check_model(model)
    g = _gamma_array(gammas)
    n_flights, n_skip = int(n_flights), int(n_skip)
    if n_flights < 1 or n_skip < 0:
        raise BouncelabError(None, "n_flights must be >= 1 and n_skip >= 0")
    starts = _start_phases(phi_start, n_starts, seed)
    ns = starts.size
    g_st = np.repeat(g, ns)
    g_tr = model.gamma_true(g_st)
    n = g_st.size
    hk, ha, hp = model.harmonic_arrays()
    out = np.empty((K.NCOL, n * n_flights))
    rows, _status = K.run_many(
        kernel_params(model), hk, ha, hp, g_tr[:, None], g_st[:, None],
        np.array([_NO_END]), True, np.tile(starts, g.size), np.zeros(n), np.zeros(n),
        n_skip, n_flights, 0, np.tile(np.arange(ns, dtype=float), g.size), out,
    )  # fmt: skip
    return _frame(out, FLIGHT_COLUMNS, _written(rows, n_flights))


def simulate_protocol(
    model: Model,
    gammas,
    cycles,
    settle_cycles: int = 10,
    seed: int = 0,
    n_starts: int = 1,
    phi_start=None,
    chatter_eps: float = CHATTER_EPS,
    stick_speed: float = 0.0,
) -> pd.DataFrame:
    """The lab protocol: Gamma steps with the state carried from one step to the next.

    Step ``i`` lasts ``cycles[i]`` drive cycles at stated ``gammas[i]``.  The new
    amplitude takes effect at the step's first phase (a whole number of cycles since
    the start, where ``sin`` is 0, so the fundamental's position is continuous) whatever
    the body is doing: a body in flight flies on, a riding body rides on.  Flights
    still in the air when the last step ends are dropped.

    Returns the columns of :func:`simulate_grid` plus ``step`` (index of the takeoff's
    step), ``t_takeoff`` (phase since the protocol start, rad) and ``settled`` (False
    for takeoffs within the first ``settle_cycles`` cycles of their step, and for a
    flight the change of Gamma itself ends: the instant amplitude change jumps the
    plate's velocity and catches a body that took off just before it, a flight a real
    drive, whose amplitude changes over cycles, does not make).

    ``chatter_eps`` (rad) ends a chatter sequence once its predicted flight is shorter
    (default :data:`CHATTER_EPS`; docs/physics.md, "Chatter termination").
    ``stick_speed`` (g / omega, > 0) ends it at once where a rebound would be slower: the
    body sticks (docs/physics.md, "Sticking speed"); 0: never.
    """
    model = _check_model(model)
    g, step_end = _protocol_steps(gammas, cycles, settle_cycles)
    starts = _start_phases(phi_start, n_starts, seed)
    ns = starts.size
    g_st = np.tile(g, (ns, 1))
    g_tr = model.gamma_true(g_st)
    hk, ha, hp = model.harmonic_arrays()
    max_rec = int(4 * step_end[-1] + 64)
    par = kernel_params(model)
    par[K.P_EPS] = float(chatter_eps)
    par[K.P_STICK] = float(stick_speed)
    while True:
        out = np.empty((K.NCOL, ns * max_rec))
        rows, status = K.run_many(
            par, hk, ha, hp, g_tr, g_st, step_end, True, starts,
            np.zeros(ns), np.zeros(ns), 0, max_rec, int(settle_cycles),
            np.arange(ns, dtype=float), out,
        )  # fmt: skip
        if not np.any(status == K.ST_FULL):
            break
        max_rec *= 4  # chatter made more flights than guessed: rerun with room
    columns = (*FLIGHT_COLUMNS, "step", "t_takeoff", "settled")
    return _frame(out, columns, _written(rows, max_rec))


def _protocol_steps(gammas, cycles, settle_cycles) -> tuple[np.ndarray, np.ndarray]:
    """Checked protocol: stated Gammas (S,) and the cycle at which each step ends (S,)."""
    g = _gamma_array(gammas)
    cyc = np.atleast_1d(np.asarray(cycles))
    if cyc.shape != g.shape or not np.all(np.isfinite(cyc.astype(float))):
        raise BouncelabError(None, "cycles must give one whole number per Gamma step")
    if np.any(cyc < 1) or np.any(np.asarray(cyc, dtype=float) % 1 != 0):
        raise BouncelabError(None, "cycles must be whole numbers >= 1")
    if settle_cycles < 0:
        raise BouncelabError(None, "settle_cycles must be >= 0")
    return g, np.cumsum(cyc.astype(np.int64))


class OutputBuffer:
    """The kernel's output array, kept between calls of :func:`protocol_flight_times`.

    Why: the array has room for every flight chatter could make (about 140 MB for a long
    sweep run's ensemble); a fresh one per call maps its pages anew, and those page
    faults took a third of a fit's evaluation. One buffer per caller (e.g. per fit), not
    a module global, so that callers in threads or processes never share one.

    ``flights`` counts the flights the kernel has written into the buffer over all calls
    (chatter included, reruns after a full buffer too): the work done through it (a
    diagnosis reports its total, ``design.work`` of :mod:`bouncelab.gap.diagnose`).
    """

    def __init__(self) -> None:
        self._array: np.ndarray | None = None
        self.flights = 0

    @property
    def array(self) -> np.ndarray | None:
        """The array kept (None before the first call)."""
        return self._array

    def get(self, shape: tuple[int, int]) -> np.ndarray:
        """An uninitialised float64 array of ``shape``, the same one while the shape holds."""
        if self._array is None or self._array.shape != shape:
            self._array = np.empty(shape)
        return self._array


def protocol_flight_times(
    model: Model,
    gammas,
    cycles,
    settle_cycles: int = 10,
    gamma_factors=(1.0,),
    chatter_eps: float = CHATTER_EPS,
    buffer: OutputBuffer | None = None,
    min_contact: float = 0.0,
    stick_speed: float = 0.0,
) -> dict[str, np.ndarray]:
    """The lab protocol for an ensemble whose members' true Gamma is scaled, as arrays.

    The inner loop of the gap fits (:mod:`bouncelab.gap.fit`): the flights of
    :func:`simulate_protocol` from phase 0, one member per entry of ``gamma_factors``
    (member ``j`` runs with true Gamma ``gamma_factors[j] * model.gamma_true(gammas)``),
    without building a DataFrame. All members run in one parallel kernel call.
    ``chatter_eps`` (rad) ends a chatter sequence once its predicted flight is shorter
    (default :data:`CHATTER_EPS`); a caller that cannot resolve such flights may raise
    it to save the kernel the long geometric tails. ``buffer`` keeps the kernel's
    output array between calls (:class:`OutputBuffer`); the results never share its memory.
    ``min_contact`` (rad) > 0: the flights as a continuity circuit shows them when every
    contact lasts at least that long (:func:`seen_flights`). ``stick_speed`` (g / omega):
    rebounds slower than this stick (:func:`simulate_protocol`).

    Returns
    -------
    dict of 1-D arrays of one length, in time order within each member: ``member``
    (int64), ``step`` (int64, index into ``gammas``), ``T`` (rad), ``settled`` (bool).
    """
    model = _check_model(model)
    g, step_end = _protocol_steps(gammas, cycles, settle_cycles)
    factors = np.atleast_1d(np.asarray(gamma_factors, dtype=float))
    ns = factors.size
    g_st = np.tile(g, (ns, 1))
    g_tr = model.gamma_true(g_st) * factors[:, None]
    hk, ha, hp = model.harmonic_arrays()
    par = kernel_params(model)
    par[K.P_EPS] = float(chatter_eps)
    par[K.P_STICK] = float(stick_speed)
    par[K.P_ENERGY] = 0.0  # flight times only: the energy columns are not read
    par[K.P_ALLCOLS] = 0.0  # nor any column but those protocol_rows reads
    # room for chatter at once: np.empty only maps pages, so unwritten room costs nothing,
    # while a rerun after a full buffer costs a whole simulation
    max_rec = int(32 * step_end[-1] + 64)
    buffer = buffer or OutputBuffer()
    while True:
        out = buffer.get((K.NCOL, ns * max_rec))
        rows, status = K.run_many(
            par, hk, ha, hp, g_tr, g_st, step_end, True, np.zeros(ns),
            np.zeros(ns), np.zeros(ns), 0, max_rec, int(settle_cycles),
            np.arange(ns, dtype=float), out,
        )  # fmt: skip
        buffer.flights += int(rows.sum())
        if not np.any(status == K.ST_FULL):
            break
        max_rec *= 4
    member, step, T, settled = K.protocol_rows(out, rows, max_rec, float(min_contact))
    return {"member": member, "step": step, "T": T, "settled": settled}


def seen_flights(sim: pd.DataFrame, min_contact: float) -> pd.DataFrame:
    """A protocol's flight table as a continuity circuit shows it when every contact
    lasts at least ``min_contact`` rad (:func:`bouncelab.physics.kernels.close_contacts`).

    ``sim``: :func:`simulate_protocol` output (members in ``start``, time order within
    each). Flights that land before the circuit opens are dropped; the others take off,
    as seen, when it opens: ``T``, ``t_takeoff`` and ``phi_takeoff`` change, the body's
    state and energies (the physics) do not. ``min_contact`` 0 returns ``sim`` itself.
    """
    if not min_contact > 0.0 or sim.empty:
        return sim
    seen, t_open, T_seen = K.close_contacts(
        sim["start"].to_numpy(dtype=np.int64),
        sim["t_takeoff"].to_numpy(dtype=np.float64),
        sim["T"].to_numpy(dtype=np.float64),
        float(min_contact),
    )
    out = sim.assign(T=T_seen, t_takeoff=t_open, phi_takeoff=np.mod(t_open, 2.0 * math.pi))
    return out.loc[seen].reset_index(drop=True)


def simulate_from(
    model: Model, gamma: float, phi0: float, x0: float, v0: float, n_flights: int, n_skip: int = 0
) -> pd.DataFrame:
    """Flights of a body released in flight: height ``x0``, velocity ``v0`` at phase ``phi0``.

    For starting on a known orbit (e.g. the restitution period-1 orbit) or above the
    plate.  ``x0`` must not be below the plate.  Columns as :func:`simulate_grid`.
    """
    model = _check_model(model)
    g = _gamma_array([gamma])
    vals = np.array([phi0, x0, v0], dtype=float)
    if not np.all(np.isfinite(vals)):
        raise BouncelabError(None, "phi0, x0 and v0 must be finite")
    if int(n_flights) < 1 or int(n_skip) < 0:
        raise BouncelabError(None, "n_flights must be >= 1 and n_skip >= 0")
    hk, ha, hp = model.harmonic_arrays()
    out = np.empty((K.NCOL, int(n_flights)))
    rows, _ = K.run_many(
        kernel_params(model), hk, ha, hp, model.gamma_true(g)[:, None], g[:, None],
        np.array([_NO_END]), False, np.array([math.fmod(vals[0], 2.0 * math.pi) % (2.0 * math.pi)]),
        vals[1:2], vals[2:3], int(n_skip), int(n_flights), 0, np.zeros(1), out,
    )  # fmt: skip
    return _frame(out[:, : rows[0]], FLIGHT_COLUMNS)


def simulate_drop(model: Model, height: float, n_flights: int = 200) -> pd.DataFrame:
    """A body released at rest from ``height`` above a still plate (Gamma = 0).

    The first row is the fall, then the rebounds until the chatter ends in sticking
    (or ``n_flights`` rows).  ``height`` is nondimensional (``x omega^2 / g``; any
    ``omega`` works on a still plate).  The last row's ``e_*`` terms include the
    summed chatter tail.  Feedback, if in the model, still makes the plate recoil.
    """
    h = float(height)
    if not math.isfinite(h) or h <= 0:
        raise BouncelabError(None, f"drop height must be > 0, not {height!r}")
    return simulate_from(model, 0.0, 0.0, h, 0.0, n_flights)
