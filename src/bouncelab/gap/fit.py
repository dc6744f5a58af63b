"""Refitting a model's parameters to a sweep run: the objective, the optimiser, intervals.

The objective of a parameter vector is the weighted mean (weights ``1 / floor`` of the
data, :meth:`Problem.mean`) over the *fit* Gamma steps of the per-step gap (``gap`` of
:func:`bouncelab.gap.distances.gap_table`, radians of drive phase) between the measured
flights and the model simulated under the run's own protocol
(:func:`bouncelab.protocol.simulate_run`). Every evaluation uses the same
seed and start phases (common random numbers), so the objective is a deterministic
function of the parameters. It is non-smooth (orbits appear and vanish), so the
optimiser is global and derivative-free: :func:`scipy.optimize.differential_evolution`
with ``polish=False`` and a fixed seed, then a short Nelder-Mead refinement from the best
point (no gradients). Each evaluation's per-step gaps over *all* steps are kept; the
bootstrap over steps re-weights them (see :func:`bootstrap_params`), so parameter
intervals cost no new simulations.

Held-out design: the run's steps in Gamma order are dealt into fit and held-out steps,
every third step held out (:func:`heldout_mask`), so a flexible effect cannot buy a
smaller gap by fitting noise of the steps it is judged on.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path

import numpy as np
import pandas as pd
from scipy.optimize import differential_evolution, minimize

from bouncelab.gap._kernels import ensemble_gaps
from bouncelab.gap.distances import (
    DEFAULT_ALPHA,
    KEY_SPAN,
    FlightSample,
    flight_order,
    prepare_flights,
    returnmap_scale,
    step_distances,
)
from bouncelab.gap.noise import noise_floor
from bouncelab.physics import EFFECTS, Model
from bouncelab.physics.simulate import CHATTER_EPS, OutputBuffer, protocol_flight_times
from bouncelab.protocol import run_protocol, simulate_run
from bouncelab.runs import Run

#: Harmonic multiples tried for ``k`` (a discrete choice, not a continuous parameter: the
#: gap is very rugged in ``k``). 0.5 stands for a low-frequency shaker oscillation, 2 to 5
#: for harmonic distortion (the seed's fig. 10 uses the third harmonic), 1.5 and 2.5 for
#: the non-integer multiples CONTRACTS.md section 5 allows (without them an independent
#: generator's k 1.5 and 2.5 came out as 0.5; docs/diagnosis-log.md, session 17).
K_CHOICES = (0.5, 1.5, 2.0, 2.5, 3.0, 4.0, 5.0)

#: The multiples a joint fit may move an already fitted harmonic to, besides its own
#: (:func:`joint_choices`): a round-1 choice can still be corrected beside another effect,
#: while the population meets the round-1 ``k`` as often as before the three choices
#: above were added (over all seven, an independent friction-plus-harmonic run lost its
#: friction; docs/diagnosis-log.md, session 17).
JOINT_K_CHOICES = (0.5, 2.0, 3.0, 4.0)

#: Values tried for the feedback's ``ride_load``: the contract's impacts-only armature (0)
#: and one also loaded by a riding body's weight and inertia (1, a real shaker).  A
#: choice: the two are different physics, not ends of a range worth interpolating.
RIDE_LOAD_CHOICES = (0.0, 1.0)

#: The discrete parameters and their choices.
CHOICES = {"k": K_CHOICES, "ride_load": RIDE_LOAD_CHOICES}

#: Parameters that wrap around (a fit "on its bound" there means nothing).
PERIODIC = {"psi"}

#: A parameter closer than this share of its range to a bound is reported on the bound.
BOUND_SHARE = 0.01

#: |correlation| across bootstrap refits above which two parameters are said to trade off.
TRADE_OFF_CORR = 0.9

#: Distinct ``(a, b)`` values the bootstrap refits of two parameters must take before
#: their correlation is read: refits drawn from two evaluated points correlate +-1
#: whatever the objective (a 60 Hz harmonic's ``a`` and ``psi``, docs/diagnosis-log.md,
#: session 55).
TRADE_OFF_MIN_POINTS = 3

#: Smallest per-step noise floor of the diagnosis (rad). The data floor of a periodic step
#: is about 0; the virtual rig's null runs (compliant contact, sensor chain) differ from
#: the ideal model by up to 0.03 rad on locked orbits, a model error no effect should be
#: fitted to (docs/diagnosis.md). Three samples at 20 kHz and a 30 Hz drive.
MIN_FLOOR = 0.03

#: Relative Gamma offset between neighbouring ensemble members (:func:`member_offsets`).
MEMBER_SPREAD = 1e-4

#: Chatter flights shorter than this many samples of the recording are summed
#: analytically by the kernel (its chatter tail) in the fits: 1/50 of a sample, far below
#: what the recording resolves, and 1.6 times fewer kernel flights for restitution models.
CHATTER_SAMPLES = 0.02

#: Fresh ensembles drawn at the best parameters to measure the objective's own noise
#: (:func:`objective_noise`).
NOISE_DRAWS = 4

#: Evaluations whose fit-step objective lies within this many noise standard deviations
#: of the best are consistent with the data (:func:`noise_intervals`).
NOISE_SIGMAS = 2.0

#: ...and evaluations within this many of the fit steps' mean noise floors of the best
#: are too (whichever tolerance is larger): the objective difference that fitting an
#: effect to pure data noise produced (the largest reduction any effect gave a
#: development null run, 0.12 floors). Why: where the members agree the objective's noise
#: is ~0 and the noise set shrinks to the best point, though the data cannot tell apart
#: what lies so close (blind case ``feedback_c``: zeta interval [0.057, 0.069], truth
#: 0.03 at 0.245 floors against the fit's 0.281).
DATA_RESOLUTION = 0.12

#: An interval wider than this share of its parameter's value (lower to upper end) gets
#: a warning (:func:`poorly_identified`): twice the 15 % of issue 6's recovery goal.
WIDE_SHARE = 0.3

#: Relative move of each fitted parameter that :func:`flat_directions` probes (either
#: side, the others held): the 15 % recovery goal of issue 6. Why: the bootstrap and the
#: noise set read only the points the search evaluated, which cluster along the search's
#: path; on the independent ``seed_like_long_steps`` the armature's zeta had the interval
#: [0.115, 0.130] while zeta 15 % and 30 % lower cost 0.05 and 0.02 floors of the fit
#: steps, and the truth lay at 0.04 (docs/diagnosis-log.md, session 75).
PROBE_SHARE = 0.15

#: Relative moves :func:`edge_bounds` walks inward, largest first, on a side of an
#: interval that the evaluated points leave at the fitted value: half of
#: :data:`PROBE_SHARE` down to about 0.25 %. Why: the bootstrap and the noise set read
#: only the points the search evaluated; where none within the tolerance lies on one
#: side of the best (the search came from the other), the side is reported as the fitted
#: value itself, a precision nobody measured (independent ``friction_restitution_sticky``:
#: e 0.3491 with interval [0.3491, 0.3500], mu 0.2489 with [0.2489, 0.2523]; session 77).
EDGE_SHARES = tuple(PROBE_SHARE / 2.0**k for k in range(1, 7))

#: A step's gap counts at most this many of its noise floors in every mean over steps
#: (:meth:`Problem.clipped`).
GAP_CAP = 10.0


#: Ensembles averaged per evaluation in the refinement of the selected model
#: (:func:`refine_settings`).
REFINE_DRAWS = 3

#: Best evaluations of the refinement scored again on fresh ensembles (:func:`recheck_best`).
RECHECK_TOP = 8

#: Differential-evolution population (in all) and most generations of that refinement.
REFINE_POPULATION = 48
REFINE_MAXITER = 40

#: Budget of the refinement in simulated drive cycles (one ensemble member; evaluations x
#: draws x the protocol's cycles): about 30 generations of 48 on a run of 1500 cycles
#: (the blind cases, 8-40).
REFINE_CYCLES = 6e6

#: Budget of the whole selection and refinement in simulated drive cycles (evaluations x
#: draws x the protocol's cycles, one ensemble member): the refinement gets what the
#: rounds left of it, at most :data:`REFINE_CYCLES`. Why: on 2 cores a cycle of the
#: seed-like models costs 6.6-8.5 us with the ensemble (blind cases, session 8); the
#: long out-of-library runs spent 19 and 14 million cycles in the rounds, and a full
#: refinement on top made them 164 s and 138 s (goal 120 s). Every library case of the
#: blind validation spends less than this (most, g_feedback, 14.8 million).
DIAGNOSIS_CYCLES = 15e6

#: Budget of one search of a model with ``feedback`` whose armature was already fitted
#: (a later round of the selection), in simulated cycles (evaluations x the protocol's
#: cycles): its extra generations (``feedback_maxiter_factor``) shrink on long runs to
#: what this allows, never below the plain ``maxiter``. The blind cases' library runs
#: with feedback (at most 2460 cycles) keep all 20; on ``ool_vibration`` (4260 cycles,
#: feedback accepted in round 2) round 3 gets 11.
FEEDBACK_SEARCH_CYCLES = 24 * 21 * 2500.0

#: Most drive cycles one simulation of a fit runs (one ensemble member): on longer runs
#: every step is cut to the same length (:func:`fit_protocol`), after its settle cycles
#: and at least :data:`FIT_MIN_SETTLED` settled cycles. Why: a diagnosis costs about
#: its protocol's cycles (7650 cycles, the shipped ``sweep_g0-8``: 100 s on 2 cores; the
#: seed's protocol at its longest, 14100 cycles: 180 s against the 2-minute goal), while
#: a step's flight-time distribution needs tens of settled cycles, not hundreds. The
#: blind cases (at most 40 cycles a step) and shipped runs are not cut.
FIT_PROTOCOL_CYCLES = 7650

#: Fewest settled cycles a step keeps in the fits' protocol (:func:`fit_protocol`).
FIT_MIN_SETTLED = 30

#: The data's shortest contact (:func:`min_contact_T`): the contacts between flights
#: have a floor when their 1 % quantile is at least ``CONTACT_FLOOR_RATIO`` of their
#: ``CONTACT_QUANTILE`` quantile; the mean of the pile-up at it is the contact time if
#: it spans ``CONTACT_MIN_SAMPLES`` samples and there are ``CONTACT_MIN_COUNT`` contacts.
CONTACT_QUANTILE = 0.05
CONTACT_FLOOR_RATIO = 0.7
CONTACT_MIN_SAMPLES = 1.5
CONTACT_MIN_COUNT = 50

#: The data's shortest flight where the body bounces (:func:`chatter_floor_T`): read
#: from at least ``CHATTER_FLOOR_MIN_COUNT`` settled flights at Gamma > 1, of which at
#: least ``BOUNCE_SHARE`` start within ``BOUNCE_CONTACTS`` contact times (plus
#: ``BOUNCE_SAMPLES`` samples) of the last landing, as the ``CHATTER_FLOOR_RANK``-th
#: shortest (a stray flight or two does not set it); it binds where it is at least
#: ``CHATTER_FLOOR_RATIO`` times the shortest flight the recording resolves, and the
#: comparison then starts at ``CHATTER_FLOOR_SHARE`` of it.
CHATTER_FLOOR_MIN_COUNT = 100
CHATTER_FLOOR_RANK = 3
CHATTER_FLOOR_RATIO = 2.0
CHATTER_FLOOR_SHARE = 0.9
BOUNCE_SHARE = 0.5
BOUNCE_CONTACTS = 2.0
BOUNCE_SAMPLES = 4.0

#: Continuation of a joint fit (:func:`low_gamma_problem`): the steps of nominal Gamma up
#: to this are searched first. Why 3: below the completely inelastic ball's first period
#: doubling (Gamma about 3.3-3.7) the motion is a single period-1 orbit, so the objective
#: is smooth there; above it, most steps of a model a little off sit on another orbit
#: than the data, each counting its capped 10 floors, and the truth of a joint model is a
#: narrow hole (independent case ``friction_harmonic_g0-8``, docs/diagnosis.md).
CONTINUATION_GAMMA = 3.0

#: ...used only when those steps are at most this share of the protocol's cycles (else
#: the run is mostly low-Gamma already and the first search would cost as much as the
#: joint one and find the same) and hold at least :data:`CONTINUATION_MIN_STEPS` fit steps.
CONTINUATION_MAX_SHARE = 0.5
CONTINUATION_MIN_STEPS = 8

#: Cycles of the step after a kept stretch in :meth:`Problem.restricted`: longer than any
#: flight that takes off at Gamma <= 3 (under 2 pi).
RESTRICTED_TAIL_CYCLES = 2

#: Box of the box refinement (:func:`box_around`): ``BOX_SHARE`` of each parameter's
#: value either side, absolute half-widths for the phase (rad) and the Gamma scale, and
#: at least ``BOX_MIN_SHARE`` of the range either side (a value near zero).
BOX_SHARE = 0.35
BOX_ABSOLUTE = {"psi": 0.5, "s": 0.05}
BOX_MIN_SHARE = 0.02

#: Differential-evolution population (in all) and most generations of the box refinement.
BOX_POPULATION = 24
BOX_MAXITER = 30

#: Fewer generations than this and the refinement is skipped. Why: its evolution starts
#: with the fitted values in its population and needs many generations to beat them.
#: Logged in session 28 (docs/diagnosis-log.md): on the blind refinements of 24-33
#: generations (the four seed-like cases and ``feedback_a``) it first did at generation
#: 11, 12, 14, 23 and 26; on the independent ``vibration_27hz`` (9 generations) never.
#: Sessions 28-30 ran such a short refinement as its local search alone: on that run it
#: gained 1.2 % of the fit-step objective, changed no verdict, and cost about 17 s of a
#: 126 s diagnosis (goal 120 s; docs/diagnosis-log.md, session 31). Below 8 generations (the shipped
#: 7650-cycle sweep gets 4) the whole refinement had made ``sweep_g0-8`` 147 s for 89 s.
REFINE_MIN_GENERATIONS = 12

#: The selected model is refined when it has at least this many continuous parameters:
#: the round budgets find one or two parameters, not the armature's curved valley.
REFINE_MIN_PARAMS = 3


@dataclass(frozen=True)
class FitSettings:
    """Budget and design of one fit (all counts are simulations unless stated).

    Attributes
    ----------
    n_members : ensemble members per evaluation, whose true Gamma differs by
        :data:`MEMBER_SPREAD` steps (:func:`member_offsets`); the per-step gap is the
        least over the members. 1 runs the model alone.
    popsize : differential-evolution population per free parameter...
    max_population : ...but at most this many in all (joint fits of combinations).
    maxiter : differential-evolution generations after the initial population; 0: no
        global search, the local one alone (from ``base``).
    tol : relative convergence tolerance of differential evolution.
    local_evals : Nelder-Mead evaluations per free parameter after the global search.
    n_boot : bootstrap resamples of the fit steps for the intervals.
    heldout_every : every this-many-th step (in Gamma order) is held out.
    feedback_extra_popsize, feedback_maxiter_factor : a model with ``feedback`` searches
        with ``popsize + feedback_extra_popsize`` per parameter (within
        ``max_population``) over ``maxiter * feedback_maxiter_factor`` generations.  Why:
        its three parameters sit in a narrow curved valley (the riding plate's amplitude
        change is about ``r / (f^2 - 1 - r)``; 10 % off in ``f_ratio`` costs 9 noise
        floors on the blind case ``feedback_a``), which 6 x 10 missed (3.8 floors, the
        truth 0.56) and 8 x 20 found (0.42 floors; ``mass_ratio``, ``f_ratio``, ``zeta``
        within 1 %, 1 %, 8 %).
    box_share : when set, the global search explores a box around ``base`` instead of
        the full bounds (:func:`box_around`); the refinement of the selected model.
    """

    n_members: int = 4
    popsize: int = 6
    max_population: int = 24
    maxiter: int = 10
    tol: float = 0.01
    local_evals: int = 10
    n_boot: int = 200
    heldout_every: int = 3
    feedback_extra_popsize: int = 2
    feedback_maxiter_factor: int = 2
    box_share: float | None = None


@dataclass(frozen=True)
class FreeParam:
    """One fitted parameter: its bounds, or a discrete set of values (``choices``)."""

    name: str
    lower: float
    upper: float
    choices: tuple[float, ...] | None = None


@dataclass(frozen=True)
class KernelInputs:
    """A problem's arrays in the form :func:`bouncelab.gap._kernels.ensemble_gaps` takes.

    ``protocol_step`` int64 (P,): step of each protocol entry (recording order);
    ``grid`` int64 (G,): the steps ascending; ``pos`` int64 (G,): where each step of
    ``Problem.steps`` (Gamma order) sits in ``grid``; ``data_t_*``: the data's settled
    flights and ``data_p_*`` (K rows) its projected return-map pairs, sorted by
    ``(step, value)``; ``directions`` (K, 2); ``scale`` the return-map factor.
    """

    protocol_step: np.ndarray
    grid: np.ndarray
    pos: np.ndarray
    data_t_step: np.ndarray
    data_t_val: np.ndarray
    data_p_step: np.ndarray
    data_p_val: np.ndarray
    directions: np.ndarray
    scale: float

    @classmethod
    def of(cls, data: FlightSample, protocol: pd.DataFrame, steps: pd.DataFrame) -> KernelInputs:
        in_gamma_order = steps["step"].to_numpy(dtype=np.int64)
        grid = np.sort(in_gamma_order)
        proj = data.projections
        return cls(
            protocol_step=protocol["step"].to_numpy(dtype=np.int64),
            grid=grid,
            pos=np.searchsorted(grid, in_gamma_order),
            data_t_step=data.flights.step,
            data_t_val=data.flights.value,
            data_p_step=np.array([p.step for p in proj], dtype=np.int64).reshape(len(proj), -1),
            data_p_val=np.array([p.value for p in proj], dtype=np.float64).reshape(len(proj), -1),
            directions=np.ascontiguousarray(data.directions, dtype=np.float64),
            scale=returnmap_scale(data.directions),
        )


@dataclass
class Problem:
    """A sweep run prepared for many model evaluations.

    Attributes
    ----------
    run : the run (protocol: steps, drive frequency, settle cycles).
    data : the measured settled flights, prepared once.
    data_table : the measured flight table (CONTRACTS.md section 3).
    duration_s : end of the recording (s).
    steps : DataFrame ``step``, ``gamma`` of every protocol step, in Gamma order, shape (G,).
    heldout : bool ndarray, shape (G,): True for held-out steps.
    min_T : rad, flights shorter than this are dropped from the data and every simulation:
        two samples of the recording (it cannot resolve shorter ones), or just below the
        data's shortest chatter flight where that lies well above them
        (:func:`chatter_floor_T`).
    floor : ndarray (G,), rad, the data's noise floor per step, at least ``min_floor``.
    protocol : the run's steps in recording order (``step``, ``gamma``, ``cycles``), what
        every simulation of the fits runs: the run's own, its steps cut short on long
        runs (:func:`fit_protocol`).
    seed : seed of the start phase of every simulation (common random numbers).
    n_members : ensemble members per evaluation (:func:`member_offsets`).
    n_draws : ensembles per evaluation whose capped per-step gaps are averaged
        (:func:`step_gaps`); 1 in the selection, :data:`REFINE_DRAWS` in the refinement
        of the selected model (:func:`refine_settings`).
    min_contact : rad, the data's shortest contact (:func:`min_contact_T`): every
        simulation is read as the continuity circuit would show it (each contact at
        least this long); 0 when the recording does not resolve one.
    chatter_stop : rad, where the data's flights end above what the recording resolves
        (:func:`chatter_floor_T`), every simulation ends a chatter sequence once its
        next flight would be shorter than this (the shortest flight compared plus
        ``min_contact``, as the circuit shows a flight shorter by its contact); 0: the
        kernels' own ends, far below a sample.
    stick_speed : g / omega, where the data's body sticks instead of rebounding
        (:func:`sticking_speed`): every simulation's rebounds slower than this stick; 0:
        none.
    """

    run: Run
    data: FlightSample
    data_table: pd.DataFrame
    duration_s: float
    steps: pd.DataFrame
    heldout: np.ndarray
    min_T: float
    floor: np.ndarray
    protocol: pd.DataFrame
    seed: int = 0
    n_members: int = 1
    n_draws: int = 1
    min_contact: float = 0.0
    chatter_stop: float = 0.0
    stick_speed: float = 0.0
    _restricted: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    @cached_property
    def kernel_inputs(self) -> KernelInputs:
        """The arrays every evaluation passes to the gap kernel, made once."""
        return KernelInputs.of(self.data, self.protocol, self.steps)

    @property
    def fit(self) -> np.ndarray:
        """bool ndarray, shape (G,): the steps the parameters are fitted on."""
        return ~self.heldout

    @property
    def weights(self) -> np.ndarray:
        """ndarray (G,), 1/rad: step weights ``1 / floor`` of every mean over steps."""
        return 1.0 / self.floor

    def mean(self, values: np.ndarray, mask: np.ndarray) -> float:
        """Weighted mean of per-step ``values`` (shape (G,)) over the steps of ``mask``.

        Weights ``1 / floor``: a step counts by how precisely the data pin it down, so
        chaotic steps of few, broad flights (floors of radians) do not drown the
        periodic ones (floors of hundredths). The weights come from the data alone, so
        no model can lower its gap by being noisy. NaN when ``mask`` is empty.
        """
        w = self.weights[mask]
        v = self.clipped(values)[mask]
        return float(np.sum(w * v) / np.sum(w)) if mask.any() else float("nan")

    def restricted(self, max_gamma: float) -> Problem:
        """This problem on its steps of nominal Gamma at most ``max_gamma`` alone: the
        protocol keeps those steps in recording order (each still starts with its settle
        cycles), and the data, floors and held-out design are those steps' own. The step
        that follows each kept stretch in the recording is kept for
        :data:`RESTRICTED_TAIL_CYCLES` cycles and not compared: a flight that takes off at
        the end of a kept step then lands as it does in the whole run (else it is cut,
        and a one-flight difference in a step of few flights is a tenth of a radian).
        Made once per ``max_gamma`` and kept (a pool's worker builds it from its own
        problem)."""
        key = float(max_gamma)
        if key not in self._restricted:
            keep = self.steps["gamma"].to_numpy(dtype=float) <= key
            ids = self.steps["step"].to_numpy()[keep]
            kept = self.protocol["step"].isin(ids).to_numpy()
            tail = np.zeros_like(kept)
            tail[1:] = kept[:-1] & ~kept[1:]
            proto = self.protocol.loc[kept | tail].copy()
            cut = tail[kept | tail]
            proto.loc[cut, "cycles"] = np.minimum(
                proto.loc[cut, "cycles"].to_numpy(), RESTRICTED_TAIL_CYCLES
            )
            proto = proto.reset_index(drop=True)
            table = self.data_table.loc[self.data_table["step"].isin(ids)]
            self._restricted[key] = replace(
                self,
                protocol=proto,
                steps=self.steps.loc[keep].reset_index(drop=True),
                heldout=self.heldout[keep],
                floor=self.floor[keep],
                data=prepare_flights(table.reset_index(drop=True), name="data"),
                data_table=table,
            )
        return self._restricted[key]

    def clipped(self, gaps: np.ndarray) -> np.ndarray:
        """Per-step gaps (shape (..., G), rad) clipped at :data:`GAP_CAP` floors each.

        A robust mean: a step where the model settles on another of several coexisting
        orbits than the data can be off by radians (T = 2 pi against 4 pi), hundreds of
        floors where the floor is a sample; one such step would otherwise outweigh the
        whole run and make the fit a lottery over which orbit each member hits.
        """
        return np.minimum(gaps, GAP_CAP * self.floor)


def heldout_mask(n_steps: int, every: int = 3) -> np.ndarray:
    """Held-out steps among ``n_steps`` in Gamma order: indices ``i % every == every // 2``.

    Interleaved, so that fit and held-out steps cover the same Gamma range; with
    ``every = 3`` the first and last step are fit steps. Returns bool ndarray (n_steps,).
    """
    if every < 2:
        raise ValueError("heldout_every must be at least 2")
    idx = np.arange(n_steps)
    return idx % every == every // 2


def too_few_steps(n_steps: int, every: int = 3) -> str | None:
    """Why a run of ``n_steps`` Gamma steps cannot be diagnosed, or None when it can.

    The fits need two fit steps and one held-out step (:func:`heldout_mask`), so with
    ``every = 3`` at least 3 steps.  One rule for the diagnosis, the pipeline's DAG and
    the report.
    """
    held = heldout_mask(int(n_steps), every)
    if held.sum() < 1 or (~held).sum() < 2:
        return f"diagnosis needs at least 3 Gamma steps, the run has {int(n_steps)}"
    return None


def unsettled_steps(run, duration_s: float, every: int = 3) -> str | None:
    """Why a run whose steps end before their flights settle cannot be diagnosed, or None.

    The diagnosis compares settled flights (after ``settle_cycles`` of each step); where
    too few steps outlast them, data and model alike have nothing to compare and every
    model "explains" the run at a gap of 0 (a black-box probe's 8-cycle steps under the
    default 10: nothing selected, explained, for friction 0.2).
    """
    from bouncelab.runs.validate import step_table

    steps = step_table(run, duration_s)
    n_long = int((steps["n_cycles"] > run.settle_cycles).sum())
    if too_few_steps(n_long, every) is None:
        return None
    return (
        f"only {n_long} of {len(steps)} Gamma steps last longer than settle_cycles "
        f"({run.settle_cycles} drive cycles): too few with settled flights to compare "
        "(3 needed); lower settle_cycles in run.yaml, or record longer steps"
    )


def continuation_gamma(problem: Problem) -> float | None:
    """Nominal Gamma up to which a joint fit of ``problem`` first searches
    (:func:`fit_model`'s ``continuation``), or None when the run does not call for it.

    :data:`CONTINUATION_GAMMA` when its steps hold at least
    :data:`CONTINUATION_MIN_STEPS` fit steps and at most :data:`CONTINUATION_MAX_SHARE`
    of the protocol's cycles: runs that reach far above the first period doubling (the
    seed's Gamma 0 to 8), where a joint model a little off sits on other orbits at most
    steps.
    """
    gamma = problem.steps["gamma"].to_numpy(dtype=float)
    low = gamma <= CONTINUATION_GAMMA
    if np.count_nonzero(low & problem.fit) < CONTINUATION_MIN_STEPS:
        return None
    proto = problem.protocol
    cycles = proto["cycles"].to_numpy(dtype=float)
    share = cycles[proto["gamma"].to_numpy(dtype=float) <= CONTINUATION_GAMMA].sum()
    if share > CONTINUATION_MAX_SHARE * cycles.sum():
        return None
    return CONTINUATION_GAMMA


def resolution_T(run: Run, samples: float = 2.0) -> float:
    """Shortest flight the recording resolves: ``samples`` samples in radians of drive phase."""
    return 2.0 * math.pi * float(run.drive_frequency_hz) * samples / float(run.sample_rate_hz)


def min_contact_T(run: Run, flights: pd.DataFrame) -> float:
    """The data's shortest contact, rad of drive phase; 0 when there is none to read.

    Every impact of a real body lasts a finite time, during which the continuity circuit
    is closed; the model's impacts are instantaneous. So a flight that starts at an
    impact is seen shorter by that time, and a rebound that lands again within it is not
    seen at all. The contacts between consecutive settled flights of one step at
    Gamma > 1 then pile up at the contact time (every bounce, and every ride shorter
    than it), with nothing below. When the 1 % quantile is at least
    :data:`CONTACT_FLOOR_RATIO` of the :data:`CONTACT_QUANTILE` quantile ``q`` (a floor,
    not the low tail of rides that start at zero, as in a model's own flights), the
    contact time is the mean of the pile-up (the contacts up to ``1.5 q`` plus
    :data:`CONTACT_MIN_SAMPLES` samples), if that spans at least
    :data:`CONTACT_MIN_SAMPLES` samples (a sub-sample contact shows as about one sample:
    the edges cannot resolve it). 0 otherwise, and with fewer than
    :data:`CONTACT_MIN_COUNT` contacts.
    """
    if flights.empty:
        return 0.0
    f = flights.sort_values(["step", "t_takeoff_s"], kind="stable")
    step = f["step"].to_numpy()
    same = step[1:] == step[:-1]
    same &= f["settled"].to_numpy(dtype=bool)[1:]
    same &= f["gamma"].to_numpy(dtype=float)[1:] > 1.0
    takeoff = f["t_takeoff_s"].to_numpy(dtype=float)
    contact = takeoff[1:] - f["t_landing_s"].to_numpy(dtype=float)[:-1]
    contact = contact[same & (contact >= 0)]
    if contact.size < CONTACT_MIN_COUNT:
        return 0.0
    lowest, shortest = np.quantile(contact, [0.01, CONTACT_QUANTILE])
    if lowest < CONTACT_FLOOR_RATIO * shortest:
        return 0.0
    # the pile-up's mean: a contact of 1.6 samples sampled at instants shows as 1 or 2
    # samples, so its low quantile is 1 sample; the mean of the pile-up is 1.6
    ts = 1.0 / float(run.sample_rate_hz)
    pile = contact[contact <= 1.5 * shortest + CONTACT_MIN_SAMPLES * ts]
    typical = float(np.mean(pile))
    if typical < CONTACT_MIN_SAMPLES * ts:
        return 0.0
    return 2.0 * math.pi * float(run.drive_frequency_hz) * typical


def _settled_pairs(run: Run, flights: pd.DataFrame, min_T: float, min_contact: float):
    """The flights of at least ``min_T`` rad in time order within each step (``f``), and
    two bool arrays over each flight but the first, shape ``(len(f) - 1,)``: ``kept``,
    settled at Gamma > 1 after a flight of its own step; ``bounce``, those of ``kept``
    that start within :data:`BOUNCE_CONTACTS` times ``min_contact`` (rad) plus
    :data:`BOUNCE_SAMPLES` samples of the landing before them (a rebound, not a ride).
    What :func:`chatter_floor_T` and :func:`sticking_speed` read."""
    f = flights.sort_values(["step", "t_takeoff_s"], kind="stable")
    f = f.loc[f["T"].to_numpy(dtype=float) >= min_T]
    step = f["step"].to_numpy()
    kept = f["settled"].to_numpy(dtype=bool)[1:] & (f["gamma"].to_numpy(dtype=float)[1:] > 1.0)
    kept &= step[1:] == step[:-1]
    takeoff, landing = (f[c].to_numpy(dtype=float) for c in ("t_takeoff_s", "t_landing_s"))
    omega = 2.0 * math.pi * float(run.drive_frequency_hz)
    within = BOUNCE_CONTACTS * min_contact / omega + BOUNCE_SAMPLES / float(run.sample_rate_hz)
    return f, kept, kept & (takeoff[1:] - landing[:-1] <= within)


def chatter_floor_T(run: Run, flights: pd.DataFrame, min_T: float, min_contact: float) -> float:
    """The shortest flight the comparison keeps, rad: ``min_T``, or just below the data's
    shortest flight where the body bounces and that lies well above ``min_T``.

    A body with restitution chatters after each impact, each rebound shorter than the
    last; the model's constant ``e`` carries the geometric series down to flights far
    below any sample before the body sticks. A real body stops short of that where its
    impacts get slow (a restitution that falls at low impact speed, a soft or sticky
    contact; a simulator's sticking threshold does the same): its flights end at some
    length, with nothing below, although the recording resolves shorter ones.

    Read where the body bounces: of the settled flights at Gamma > 1 (at least
    :data:`CHATTER_FLOOR_MIN_COUNT`), at least :data:`BOUNCE_SHARE` start within
    :data:`BOUNCE_CONTACTS` times ``min_contact`` plus :data:`BOUNCE_SAMPLES` samples of
    the landing before them in their step (the bouncing runs of the records: 0.76-0.97;
    an inelastic body rides between most flights: at most 0.40). The floor is then the
    :data:`CHATTER_FLOOR_RANK`-th shortest of those flights; where it is at least
    :data:`CHATTER_FLOOR_RATIO` times ``min_T``, :data:`CHATTER_FLOOR_SHARE` of it is
    returned, else ``min_T``. :func:`make_problem` then leaves the shorter flights out of
    both sides of the comparison (the data have at most ``CHATTER_FLOOR_RANK - 1``) and
    ends every simulation's chatter once its next flight would be that short (the
    kernels' chatter threshold, ``Problem.chatter_stop``), so that the model's body
    sticks where the data's does instead of chattering on through the takeoff. An
    inelastic body's shortest flight says nothing of chatter (it has none): its runs
    keep ``min_T``, and a restitution fitted to them keeps its whole chatter.

    Why: on a recording of friction with restitution (mu 0.25, e 0.35) from a generator
    written against the contract alone, whose body sticks once its next flight would be
    shorter than 1.5 contact times (300 us contacts, 48 kHz), the shortest flight is
    188 us against 42 us resolved: the diagnosis found both effects within 0.2 % and
    left the run unexplained at 4.86 noise floors; with the floor read, explained at
    0.82 with mu and e within 0.15 % (docs/diagnosis-log.md, session 76). On every other
    recording of the records (the rig's, the independent and compliant generators', the
    blind cases, the shipped runs) it does not bind: the bouncing ones have flights down
    to 1.0-1.54 times ``min_T``.

    ``run``: the run (its sampling and drive frequency); ``flights``: its flight table
    (CONTRACTS.md section 3), already cut at ``min_T`` (rad); ``min_contact``: rad,
    :func:`min_contact_T` of that table.
    """
    f, kept, bounce = _settled_pairs(run, flights, min_T, min_contact)
    if np.count_nonzero(kept) < max(CHATTER_FLOOR_MIN_COUNT, CHATTER_FLOOR_RANK):
        return float(min_T)
    if np.count_nonzero(bounce) < BOUNCE_SHARE * np.count_nonzero(kept):
        return float(min_T)
    floor = float(np.sort(f["T"].to_numpy(dtype=float)[1:][kept])[CHATTER_FLOOR_RANK - 1])
    if floor < CHATTER_FLOOR_RATIO * min_T:
        return float(min_T)
    return CHATTER_FLOOR_SHARE * floor


#: Chatter rebounds a sticking speed is read from (:func:`sticking_speed`), at least.
STICK_MIN_COUNT = 100
#: The relative deceleration (g) of the body at a rebound's takeoff, at least, for the
#: rebound to count (:func:`sticking_speed`): the plate holding the body, so that only
#: a speed of its own lifts it (friction moves it by mu).
STICK_PRESS = 0.3
#: The quantile of the rebounds' speeds read as the data's slowest rebound.
STICK_QUANTILE = 0.01
#: How far above the speed of a rebound the recording just resolves (the median over the
#: rebounds, each at its own phase) the slowest rebounds must lie for a sticking speed.
STICK_RATIO = 1.5
#: Share of the slowest rebounds' speed taken as the sticking speed: a little under, so
#: that the model keeps the rebounds the data show.
STICK_SHARE = 0.95


def rebound_speeds(T, phi_takeoff, gamma) -> np.ndarray:
    """Relative speed (g / omega) at which a body left a sinusoidal plate for a flight of
    ``T`` rad from drive phase ``phi_takeoff`` (rad) at ``gamma``: the speed whose flight
    under the relative acceleration ``-1 + gamma sin(phi)`` returns to the plate after
    ``T``, ``T / 2 - gamma (cos phi0 - (sin(phi0 + T) - sin phi0) / T)`` (friction
    ignored: it changes the deceleration by ``mu``). Arrays of one shape."""
    T = np.asarray(T, dtype=np.float64)
    phi0 = np.asarray(phi_takeoff, dtype=np.float64)
    return T / 2.0 - np.asarray(gamma, dtype=np.float64) * (
        np.cos(phi0) - (np.sin(phi0 + T) - np.sin(phi0)) / T
    )


def sticking_speed(run: Run, flights: pd.DataFrame, min_T: float, min_contact: float) -> float:
    """The speed (g / omega) below which the data's body sticks instead of rebounding,
    read from its chatter; 0 where it shows none.

    The chatter rebounds (settled flights at Gamma > 1 that start within
    :data:`BOUNCE_CONTACTS` contact times plus :data:`BOUNCE_SAMPLES` samples of the
    landing before them in their step, are shorter than the flight before, and leave
    with a drive phase where the plate holds the body, ``1 - gamma sin(phi)`` above
    :data:`STICK_PRESS`; at least :data:`STICK_MIN_COUNT` that follow such a rebound)
    each give the speed they left the plate at (:func:`rebound_speeds`). A constant
    restitution rebounds at every speed, down to what the recording resolves; a body
    that sticks below some impact speed (a real one at slow impacts; a simulator's
    sticking threshold) shows none below it. Where the
    :data:`STICK_QUANTILE` quantile of the speeds is at least :data:`STICK_RATIO` times
    the median speed of a rebound of ``min_T`` at the same phases, :data:`STICK_SHARE` of
    it is returned. Flight lengths cannot say it (:func:`chatter_floor_T`): a rebound of
    one speed flies 0.5-2 ms by the plate's acceleration at the impact.

    Why: the independent generator's body sticking below 10 mm/s (``restitution_sticky_
    speed``, e 0.45) was called unexplained at 3.5 noise floors with e right; with the
    speed read (8.97 mm/s), explained at 1.83. A black-box probe's generator sticking
    below 2 mm/s (e 0.5) gave nothing at 8.4 floors; now restitution, e 0.5015, 2.27. The
    speeds read there pile up at 9.4 and 2.1 mm/s, 8.0 and 2.0 times the resolved speed;
    on the 150 other recordings at hand (the shipped runs, the rig's blind cases, the
    independent and compliant generators', the probes') the quantile lies at 1.34 of it
    at most (a Hertzian contact), and harmonics' periodic orbits have next to no
    sequences (docs/diagnosis-log.md, session 79).

    ``flights``: the run's flight table (CONTRACTS.md section 3) cut at ``min_T`` (rad);
    ``min_contact``: rad, :func:`min_contact_T`.
    """
    f, _, bounce = _settled_pairs(run, flights, min_T, min_contact)
    if len(f) < STICK_MIN_COUNT:
        return 0.0
    T = f["T"].to_numpy(dtype=float)
    gamma = f["gamma"].to_numpy(dtype=float)[1:]
    phi = f["phi_takeoff"].to_numpy(dtype=float)[1:]
    rebound = bounce & (T[1:] < T[:-1]) & np.isfinite(phi)
    # where the plate holds the body (relative deceleration over STICK_PRESS g), a flight
    # is a rebound of its own speed; elsewhere the plate pulls away and any body leaves
    pressed = 1.0 - gamma * np.sin(np.where(np.isfinite(phi), phi, 0.0))
    rebound &= pressed > STICK_PRESS
    # chatter: a rebound after a rebound (three flights falling in a row); a periodic
    # orbit whose landings the plate's harmonic turns into takeoffs has next to none
    sequences = rebound & np.concatenate(([False], rebound[:-1]))
    if np.count_nonzero(sequences) < STICK_MIN_COUNT:
        return 0.0
    speeds = rebound_speeds(T[1:][rebound], phi[rebound], gamma[rebound])
    resolved = rebound_speeds(np.full(speeds.shape, min_T), phi[rebound], gamma[rebound])
    slowest = float(np.quantile(speeds, STICK_QUANTILE))
    if slowest < STICK_RATIO * float(np.median(resolved)):
        return 0.0
    return STICK_SHARE * slowest


def fit_protocol(
    protocol: pd.DataFrame,
    settle_cycles: int,
    max_cycles: float | None = FIT_PROTOCOL_CYCLES,
    min_settled: int = FIT_MIN_SETTLED,
) -> pd.DataFrame:
    """The protocol the fits simulate: ``protocol`` with every step cut to at most ``c``
    drive cycles, ``c`` the largest whole number that keeps the total within
    ``max_cycles``, but at least ``settle_cycles + min_settled``.

    The step order, Gamma values and the state carried from step to step are the run's;
    only each step's dwell is shorter, so the simulated settled flights are a smaller
    sample of the same attractor (a multistable run's history is its sequence of
    steps, not their lengths, once each step has settled). ``max_cycles`` None or a
    protocol within it: returned unchanged (a copy).

    Parameters
    ----------
    protocol : the run's steps (``step``, ``gamma``, ``cycles``, ...), recording order.
    settle_cycles : cycles at each step's start whose flights are not compared.

    Returns
    -------
    DataFrame, the columns of ``protocol``, ``cycles`` possibly smaller.
    """
    out = protocol.copy()
    cycles = out["cycles"].to_numpy(dtype=np.int64)
    if max_cycles is None or cycles.sum() <= max_cycles:
        return out
    # total with every step cut at c is sum(min(cycles, c)), increasing in c
    lowest = int(settle_cycles) + int(min_settled)
    cap = lowest
    for c in np.unique(np.maximum(cycles, lowest)):
        if np.minimum(cycles, c).sum() > max_cycles:
            break
        cap = int(c)
    # between two distinct step lengths, the largest cap that still fits
    spare = max_cycles - np.minimum(cycles, cap).sum()
    longer = int(np.count_nonzero(cycles > cap))
    if longer:
        cap += int(spare // longer)
    out["cycles"] = np.minimum(cycles, max(cap, lowest))
    return out


def make_problem(
    run: Run,
    flights: pd.DataFrame,
    duration_s: float,
    *,
    seed: int = 0,
    n_members: int = 1,
    heldout_every: int = 3,
    min_floor: float = MIN_FLOOR,
    max_cycles: float | None = FIT_PROTOCOL_CYCLES,
    left_out_steps=(),
) -> Problem:
    """Prepare a run and its measured flights for fitting (see :class:`Problem`).

    The per-step floor is :func:`bouncelab.gap.noise.noise_floor` of the data alone (the
    data against an independent sample of its own size and spread), at least
    ``min_floor`` rad. The fits simulate the run's protocol cut to ``max_cycles`` drive
    cycles (:func:`fit_protocol`; None: the whole protocol). ``left_out_steps``: steps
    simulated (the state carries over them) but not compared, as those whose circuit
    never closed (:func:`bouncelab.gap.diagnose.open_circuit_steps`).
    """
    proto = fit_protocol(run_protocol(run, duration_s), int(run.settle_cycles), max_cycles)
    compared = ~proto["step"].isin([int(s) for s in left_out_steps])
    steps = proto.loc[compared, ["step", "gamma"]].sort_values(["gamma", "step"], kind="stable")
    steps = steps.reset_index(drop=True)
    data_table = flights.reset_index(drop=True)
    min_T = resolution_T(run)
    data_table = data_table.loc[data_table["T"].to_numpy(dtype=float) >= min_T]
    # the contacts are read before the chatter floor's cut, which would merge flights
    min_contact = min_contact_T(run, data_table)
    floor_T = chatter_floor_T(run, data_table, min_T, min_contact)
    chatter_stop = floor_T + min_contact if floor_T > min_T else 0.0
    # a chatter that ends at a speed (read beside the length: a body that sticks below a
    # speed also has a shortest flight, and the two together explained both generators')
    stick = sticking_speed(run, data_table, min_T, min_contact)
    min_T = floor_T
    data_table = data_table.loc[data_table["T"].to_numpy(dtype=float) >= min_T]
    floor = align_steps(noise_floor(data_table, steps=steps), steps)["floor"]
    return Problem(
        protocol=proto[["step", "gamma", "cycles"]].reset_index(drop=True),
        run=run,
        data=prepare_flights(data_table, name="data"),
        data_table=data_table,
        duration_s=float(duration_s),
        steps=steps,
        heldout=heldout_mask(len(steps), heldout_every),
        min_T=min_T,
        floor=np.maximum(floor.to_numpy(dtype=float), min_floor),
        seed=int(seed),
        n_members=int(n_members),
        min_contact=min_contact,
        chatter_stop=chatter_stop,
        stick_speed=stick,
    )


def member_offsets(n_members: int) -> np.ndarray:
    """Relative Gamma offsets of the ensemble members: ``0, +d, -d, +2d, -2d, ...`` with
    ``d =`` :data:`MEMBER_SPREAD`; member 0 is the model itself. Shape (n_members,)."""
    j = np.arange(int(n_members))
    return MEMBER_SPREAD * np.where(j % 2 == 1, (j + 1) // 2, -(j // 2)).astype(float)


def member_model(model: Model, offset: float) -> Model:
    """``model`` with its true Gamma scaled by ``1 + offset`` (through ``gamma_scale``)."""
    if offset == 0.0:
        return model
    effects = list(model.effects)
    if "gamma_scale" not in effects:
        effects.append("gamma_scale")
    params = {**model.params, "s": float(model.params.get("s", 1.0)) * (1.0 + offset)}
    return Model.parse("+".join(effects), params)


def simulate(problem: Problem, model: Model, member: int = 0) -> pd.DataFrame:
    """The model under the run's protocol with the common random numbers, as a flight table.

    ``member`` picks the ensemble member (:func:`member_offsets`; 0 is the model itself).
    Flights shorter than ``problem.min_T`` (chatter the recording cannot resolve) are
    dropped, as they are from the measured table.
    """
    offset = float(member_offsets(member + 1)[member])
    sim = simulate_run(
        problem.run,
        member_model(model, offset),
        problem.duration_s,
        seed=problem.seed,
        min_contact=problem.min_contact,
        chatter_eps=max(CHATTER_EPS, problem.chatter_stop),
        stick_speed=problem.stick_speed,
    )
    return sim.loc[sim["T"].to_numpy(dtype=float) >= problem.min_T].reset_index(drop=True)


def _combined_gap(d: dict) -> np.ndarray:
    """The per-step gap (rad) of :func:`bouncelab.gap.distances.step_distances` output,
    weighted as in :func:`bouncelab.gap.distances.gap_table` (``DEFAULT_ALPHA``)."""
    return DEFAULT_ALPHA * d["w1_T"] + (1.0 - DEFAULT_ALPHA) * d["w_returnmap"]


def best_member_simulation(problem: Problem, model: Model) -> pd.DataFrame:
    """The model's flight table that :func:`step_gaps` scores: at each Gamma step, the
    flights of the ensemble member whose gap to the data is least (the first on ties).

    Why: the named features (takeoff phase, clusters, locking) of one simulation are
    one draw of the multistable lottery, like its gap. On a blind case with the seed's
    three effects, member 0 of the fitted model settled on another orbit in one
    periodic step (takeoff phase 0.72 rad off) while a neighbour matched the data; the
    mean phase offset over the sharp steps was +0.13 rad from that step alone.

    Returns
    -------
    DataFrame, the columns of :func:`simulate`, rows in time order.
    """
    grid = np.sort(problem.steps["step"].to_numpy(dtype=np.int64))
    sims, gaps = [], []
    for m in range(max(1, problem.n_members)):
        sim = simulate(problem, model, member=m)
        d = step_distances(problem.data, prepare_flights(sim, name="simulation"), grid)
        sims.append(sim)
        gaps.append(np.nan_to_num(_combined_gap(d), nan=np.inf))
    best = np.argmin(np.asarray(gaps), axis=0)  # shape (G,), grid order
    parts = [sim.loc[sim["step"].isin(grid[best == m])] for m, sim in enumerate(sims)]
    out = pd.concat(parts, ignore_index=True)
    return out.iloc[flight_order(out)].reset_index(drop=True)


def step_gaps(
    problem: Problem, model: Model, buffer: OutputBuffer | None = None, shift: float = 0.0
) -> np.ndarray:
    """Per-step gap (rad) of ``model`` against the data, ndarray shape (G,) in step order
    of ``problem.steps``: the least over the ``problem.n_members`` ensemble members.

    Why the least: the dynamics are multistable, and which of coexisting orbits a run
    settles on after a chaotic stretch is decided by differences far below anything a
    model can pin down. One simulation is then a lottery: on a blind case with the
    seed's three effects, the true model was 12 noise floors from the data with one
    member (it missed a period-2 orbit the rig had locked into) and 1 floor with the
    least of eight. The members differ by Gamma offsets of 1e-4 (:func:`member_offsets`),
    far finer than any lab's amplitude calibration, which act only through chaos; where
    the motion is stable they give the same gap.

    The same numbers as :func:`bouncelab.gap.distances.gap_table` of :func:`simulate`
    per member, computed from the kernel's arrays without DataFrames (the inner loop of
    every fit), when the run fits in the fits' protocol; on longer runs the simulations
    run ``problem.protocol``, each step cut short (:func:`fit_protocol`).
    ``buffer``: the simulation's output array kept between calls.
    ``shift`` moves every member's Gamma offset by ``shift * MEMBER_SPREAD``: a fresh
    ensemble, another draw of the multistable lottery (:func:`objective_noise`).

    With ``problem.n_draws > 1`` the result is the mean over that many ensembles (shifted
    by ``shift + k / n_draws``) of the capped gaps (:meth:`Problem.clipped`): the expected
    gap rather than one draw of the lottery.
    """
    return counted_step_gaps(problem, model, buffer, shift)[0]


def counted_step_gaps(
    problem: Problem, model: Model, buffer: OutputBuffer | None = None, shift: float = 0.0
) -> tuple[np.ndarray, int]:
    """:func:`step_gaps` and the flights the kernel simulated for them (every member and
    draw, chatter included; :attr:`OutputBuffer.flights`): the evaluation's work."""
    buffer = buffer if buffer is not None else OutputBuffer()
    before = buffer.flights
    if problem.n_draws > 1:
        draws = [
            problem.clipped(_one_draw_gaps(problem, model, buffer, shift + k / problem.n_draws))
            for k in range(problem.n_draws)
        ]
        gaps = np.mean(draws, axis=0)
    else:
        gaps = _one_draw_gaps(problem, model, buffer, shift)
    return gaps, buffer.flights - before


def _one_draw_gaps(
    problem: Problem, model: Model, buffer: OutputBuffer | None, shift: float
) -> np.ndarray:
    """Per-step gaps of one ensemble (see :func:`step_gaps`), shape (G,)."""
    proto = problem.protocol
    sim = protocol_flight_times(
        model,
        proto["gamma"].to_numpy(),
        proto["cycles"].to_numpy(),
        settle_cycles=int(problem.run.settle_cycles),
        gamma_factors=1.0 + member_offsets(max(1, problem.n_members)) + shift * MEMBER_SPREAD,
        chatter_eps=max(resolution_T(problem.run, CHATTER_SAMPLES), problem.chatter_stop),
        buffer=buffer,
        min_contact=problem.min_contact,
        stick_speed=problem.stick_speed,
    )
    return _ensemble_min_gaps(problem, sim)


def _ensemble_min_gaps(problem: Problem, sim: dict[str, np.ndarray]) -> np.ndarray:
    """Per-step gap, shape (G,), of simulated flights (``sim`` as
    :func:`bouncelab.physics.simulate.protocol_flight_times` returns them): the least over
    the members (see :func:`step_gaps`)."""
    k = problem.kernel_inputs
    gaps = ensemble_gaps(
        sim["member"], k.protocol_step[sim["step"]], sim["T"], sim["settled"],
        max(1, problem.n_members), float(problem.min_T), k.grid,
        k.data_t_step, k.data_t_val, k.data_p_step, k.data_p_val, k.directions,
        DEFAULT_ALPHA, k.scale, KEY_SPAN,
    )  # fmt: skip
    return np.min(gaps[:, k.pos], axis=0)


def align_steps(table: pd.DataFrame, steps: pd.DataFrame) -> pd.DataFrame:
    """Rows of a per-step table in the order of ``steps`` (Gamma order)."""
    pos = pd.Index(table["step"].to_numpy()).get_indexer(steps["step"].to_numpy())
    if np.any(pos < 0):
        raise ValueError("gap table lacks some protocol steps")
    return table.iloc[pos].reset_index(drop=True)


def free_params(effects, fixed: dict | None = None) -> list[FreeParam]:
    """Fitted parameters of ``effects`` (names of CONTRACTS.md section 5), in canonical
    order, within :data:`bouncelab.physics.EFFECTS` bounds; those in ``fixed`` are left
    out. The harmonic ``k`` and the feedback's ``ride_load`` are choices (:data:`CHOICES`)."""
    fixed = fixed or {}
    out = []
    for eff in EFFECTS:
        if eff not in effects:
            continue
        for name, (_default, lo, hi) in EFFECTS[eff].items():
            if name in fixed:
                continue
            if name in CHOICES:
                out.append(FreeParam(name, 0.0, len(CHOICES[name]) - 1.0, CHOICES[name]))
            else:
                out.append(FreeParam(name, float(lo), float(hi)))
    return out


def joint_choices(free: list[FreeParam], start: dict) -> list[FreeParam]:
    """``free`` with a free harmonic ``k`` searched among :data:`JOINT_K_CHOICES` and the
    ``k`` of ``start`` (the value a joint fit starts from), sorted; unchanged when
    ``start`` has no ``k`` (the harmonic fitted from scratch searches all of
    :data:`K_CHOICES`)."""
    if "k" not in start:
        return free
    ks = tuple(sorted({*JOINT_K_CHOICES, float(start["k"])}))
    return [
        FreeParam(p.name, 0.0, len(ks) - 1.0, ks) if p.name == "k" and p.choices else p
        for p in free
    ]


def box_around(free: list[FreeParam], params: dict, share: float) -> list[FreeParam]:
    """``free`` with each continuous parameter's bounds narrowed to ``share`` of its
    value in ``params`` either side (the absolute half-widths of :data:`BOX_ABSOLUTE` for
    the phase and the Gamma scale, whose value is not their size), within its bounds and
    at least :data:`BOX_MIN_SHARE` of its range either side; choices are left whole."""
    out = []
    for p in free:
        if p.choices is not None:
            out.append(p)
            continue
        v = float(params[p.name])
        half = BOX_ABSOLUTE.get(p.name, share * abs(v))
        half = max(half, BOX_MIN_SHARE * (p.upper - p.lower))
        out.append(replace(p, lower=max(p.lower, v - half), upper=min(p.upper, v + half)))
    return out


def decode(free: list[FreeParam], x: np.ndarray) -> dict:
    """Parameter dict from an optimiser vector (choices indexed by the rounded value)."""
    out = {}
    for p, v in zip(free, np.asarray(x, dtype=float), strict=True):
        if p.choices is not None:
            out[p.name] = float(p.choices[int(np.clip(np.rint(v), 0, len(p.choices) - 1))])
        else:
            out[p.name] = float(np.clip(v, p.lower, p.upper))
    return out


def encode(free: list[FreeParam], params: dict) -> np.ndarray:
    """Optimiser vector of a parameter dict (the nearest choice for discrete ones)."""
    x = []
    for p in free:
        v = float(params[p.name])
        if p.choices is not None:
            x.append(float(np.argmin(np.abs(np.asarray(p.choices) - v))))
        else:
            x.append(float(np.clip(v, p.lower, p.upper)))
    return np.asarray(x)


@dataclass
class FitResult:
    """A refitted model.

    Attributes
    ----------
    model : the model with the best parameters.
    free : the fitted parameters.
    objective : rad, the mean gap over the fit steps at the best parameters.
    gaps : ndarray (G,), rad, per-step gap at the best parameters (Gamma order).
    cloud_x : ndarray (n_evals, len(free)), every evaluated optimiser vector.
    cloud_gaps : ndarray (n_evals, G), the per-step gaps of each evaluation.
    n_evals, seconds : cost of the fit.
    flights : flights the kernel simulated for the fit's evaluations (every member and
        draw, chatter included): its work, deterministic.
    """

    model: Model
    free: list[FreeParam]
    objective: float
    gaps: np.ndarray
    cloud_x: np.ndarray
    cloud_gaps: np.ndarray
    n_evals: int
    seconds: float
    extra: dict = field(default_factory=dict)
    flights: int = 0


# The problem and output buffer of an EvaluationPool's worker process, set once when it
# starts (:func:`_worker_start`): a worker serves one problem for its whole life.
_WORKER: dict = {}


def _worker_start(problem_path: str) -> None:
    """Set up a pool's worker: one numba thread, and the problem read from the pickle at
    ``problem_path`` (written by :class:`EvaluationPool`)."""
    import pickle

    import numba

    # the processes are the parallelism: kernels on two threads each would oversubscribe
    numba.set_num_threads(1)
    with open(problem_path, "rb") as f:
        problem = pickle.load(f)
    _WORKER.update(problem=problem, buffer=OutputBuffer())


def _worker_compile(kernel: str) -> None:
    """Compile (or load from numba's cache) one of the two kernels every evaluation runs,
    ``"simulation"`` or ``"gaps"``, with the argument types of the worker's problem: a
    one-cycle simulation, or the gaps of no flights."""
    problem = _WORKER["problem"]
    if kernel == "simulation":
        protocol_flight_times(
            Model.parse("ideal"),
            problem.protocol["gamma"].to_numpy()[:1],
            np.ones(1, dtype=np.int64),
            settle_cycles=0,
            min_contact=problem.min_contact,
        )
    else:
        empty = {
            "member": np.zeros(0, dtype=np.int64),
            "step": np.zeros(0, dtype=np.int64),
            "T": np.zeros(0),
            "settled": np.zeros(0, dtype=bool),
        }
        _ensemble_min_gaps(problem, empty)


def _worker_gaps(
    model_name: str,
    params: dict,
    n_draws: int = 1,
    shift: float = 0.0,
    max_gamma: float | None = None,
) -> tuple[np.ndarray, int]:
    problem = _WORKER["problem"]
    if max_gamma is not None:
        problem = problem.restricted(max_gamma)
    if problem.n_draws != n_draws:
        problem = replace(problem, n_draws=n_draws)
    return counted_step_gaps(problem, Model.parse(model_name, params), _WORKER["buffer"], shift)


class EvaluationPool:
    """Processes that evaluate the models of one generation of a fit in parallel.

    Every worker receives ``problem`` once, when it starts; a task is one model (name and
    parameters), its result the per-step gaps (:func:`step_gaps`), the same numbers as
    in the calling process (each simulation depends only on its own inputs). Why the
    population and not whole fits in parallel: one feedback fit costs as much as all the
    other candidates of a round together, and fits in parallel then wait for it.

    Started with ``spawn``, not ``fork``: the physics kernels use numba's thread pool,
    which is not safe to fork once started. Use as a context manager.
    """

    def __init__(self, problem: Problem, workers: int):
        import multiprocessing
        import pickle
        import tempfile
        from concurrent.futures import ProcessPoolExecutor

        self.problem = problem
        self.workers = int(workers)
        # the problem (megabytes) goes by a file, not in the arguments of the spawn: those
        # are written to a pipe the new process reads only once it has imported the
        # package, so the workers would start one after the other (1.4 s each, session 62)
        temp = tempfile.NamedTemporaryFile(prefix="bouncelab-pool-", suffix=".pkl", delete=False)
        with temp as f:
            pickle.dump(problem, f, protocol=pickle.HIGHEST_PROTOCOL)
        self._problem_path = f.name
        self._executor = ProcessPoolExecutor(
            max_workers=self.workers,
            mp_context=multiprocessing.get_context("spawn"),
            initializer=_worker_start,
            initargs=(self._problem_path,),
        )
        # numba compiles the kernels at their first use (then caches them): here one in
        # each worker at once while the caller waits, not one after the other in the
        # caller (a first diagnosis after an install: about 16 of its 46 s of compiling)
        try:
            for task in [self._executor.submit(_worker_compile, k) for k in ("simulation", "gaps")]:
                task.result()
        except BaseException:
            self.close()  # no caller holds the pool yet to close it
            raise

    def serves(self, problem: Problem) -> bool:
        """Whether this pool's workers hold ``problem`` (or the same run and data with
        another ``n_draws``, which a task passes along)."""
        return self.problem is problem or self.problem.data is problem.data

    def counted_gaps(
        self,
        model_name: str,
        params: list[dict],
        n_draws: int = 1,
        shift: float = 0.0,
        max_gamma: float | None = None,
    ) -> list[tuple[np.ndarray, int]]:
        """Per-step gaps (each ndarray (G,), rad) of ``model_name`` at each parameter dict,
        averaged over ``n_draws`` ensembles shifted by ``shift``, on the pool's problem or
        its :meth:`Problem.restricted` to ``max_gamma``; each with the flights simulated
        for it (:func:`counted_step_gaps`)."""
        n = len(params)
        return list(
            self._executor.map(
                _worker_gaps,
                [model_name] * n,
                params,
                [int(n_draws)] * n,
                [float(shift)] * n,
                [max_gamma] * n,
            )
        )

    def close(self) -> None:
        self._executor.shutdown()
        Path(self._problem_path).unlink(missing_ok=True)

    def __enter__(self) -> EvaluationPool:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _Evaluator:
    """Objective with a record of every evaluation (vector and per-step gaps).

    :meth:`many` evaluates a whole population, in ``pool`` when given; evaluations are
    recorded in the order of the population, as one by one, so a fit's result does not
    depend on the pool.
    """

    def __init__(
        self,
        problem: Problem,
        model_name: str,
        base: dict,
        free: list[FreeParam],
        pool: EvaluationPool | None = None,
        max_gamma: float | None = None,
    ):
        if pool is not None and not pool.serves(problem):
            raise ValueError("the evaluation pool serves another problem")
        self.max_gamma = max_gamma
        if max_gamma is not None:  # the pool holds the whole problem and restricts it too
            problem = problem.restricted(max_gamma)
        self.problem, self.model_name, self.base, self.free = problem, model_name, base, free
        self.pool = pool
        self.xs: list[np.ndarray] = []
        self.gaps: list[np.ndarray] = []
        self.flights = 0  # simulated by this evaluator (counted_step_gaps)
        self._cache: dict[tuple, float] = {}
        self._buffer = OutputBuffer()

    def model(self, x) -> Model:
        return Model.parse(self.model_name, {**self.base, **decode(self.free, x)})

    def many(self, xs) -> list[float]:
        """Objective values of the optimiser vectors ``xs``; each new one is recorded."""
        keyed = []
        todo: dict[tuple, dict] = {}  # first occurrence of each new parameter set, in order
        for x in xs:
            params = decode(self.free, x)
            key = tuple(sorted(params.items()))
            keyed.append(key)
            if key not in self._cache and key not in todo:  # DE re-proposes the same k often
                todo[key] = params
        full = [{**self.base, **p} for p in todo.values()]
        if self.pool is not None and len(full) > 1:
            counted = self.pool.counted_gaps(
                self.model_name, full, self.problem.n_draws, max_gamma=self.max_gamma
            )
        else:
            counted = [
                counted_step_gaps(self.problem, Model.parse(self.model_name, p), self._buffer)
                for p in full
            ]
        gaps = [g for g, _ in counted]
        self.flights += sum(n for _, n in counted)
        for (key, params), g in zip(todo.items(), gaps, strict=True):
            self.xs.append(encode(self.free, params))
            self.gaps.append(g)
            fit = self.problem.fit
            self._cache[key] = self.problem.mean(g, fit) if fit.any() else 0.0
        return [self._cache[key] for key in keyed]

    def __call__(self, x) -> float:
        return self.many([x])[0]


def fit_model(
    problem: Problem,
    model_name: str,
    base: dict | None = None,
    *,
    fixed: dict | None = None,
    search: tuple[str, ...] | None = None,
    settings: FitSettings | None = None,
    seed: int = 0,
    pool: EvaluationPool | None = None,
    continuation: bool = False,
    starts: list[dict] | None = None,
) -> FitResult:
    """Refit ``model_name``'s parameters to the run (see the module docstring).

    Parameters
    ----------
    problem : from :func:`make_problem`.
    model_name : e.g. ``"friction+restitution"``.
    base : parameter values: the start of the search for fitted ones (default: the
        ``EFFECTS`` defaults) and the value of fixed ones.
    fixed : parameters held at these values, not fitted (e.g. a drop-test calibration).
    search : names of the parameters the global search explores (default: all fitted
        ones); the others start at their ``base`` value and move only in the local
        refinement. Forward selection searches the new effect's parameters globally and
        refines all together.
    settings : budget, see :class:`FitSettings`.
    seed : seed of the optimiser (the simulation's seed is ``problem.seed``).
    pool : processes that evaluate each generation of the global search in parallel
        (:class:`EvaluationPool` of this ``problem``); the result does not depend on it.
    continuation : on runs that reach far above the first period doubling
        (:func:`continuation_gamma`), search first on the low-Gamma steps alone
        (:meth:`Problem.restricted`, the protocol's low steps only, with the same
        budget), and start the global search from that optimum when it beats ``base``
        on all fit steps. Why: there a joint model's truth is a narrow hole among
        steps on other orbits (independent case ``friction_harmonic_g0-8``: the
        search over all steps ended at 3.5 floors, the low-Gamma steps alone found a
        point at 0.96). Reported in ``extra["continuation"]``.
    starts : other starting points (parameter values over ``base``): the search starts
        from the one of ``base`` and these that does best on the fit steps (one
        evaluation each; the rest of the initial population is drawn as without them).
        Forward selection passes the plate's harmonic read off the takeoff phases
        (:mod:`bouncelab.gap.takeoff_reading`).

    Returns
    -------
    FitResult (deterministic for the same inputs).
    """
    t0 = time.perf_counter()
    settings = settings or FitSettings()
    proto = Model.parse(model_name)
    # fixed values of effects outside this model (a calibrated mu in a restitution fit) drop
    fixed = {k: float(v) for k, v in (fixed or {}).items() if k in proto.params}
    free = free_params(proto.effects, fixed)
    start = {**_defaults(free), **(base or {})}
    free = joint_choices(free, base or {})
    ev = _Evaluator(problem, model_name, fixed, free, pool)
    x = encode(free, start)
    if starts:
        least = ev(x)
        for more in starts:
            other = encode(free, {**start, **more})
            value = ev(other)
            if value < least:
                x, least = other, value
    names = [p.name for p in free]
    glob = [i for i, n in enumerate(names) if search is None or n in search]
    # the extra feedback generations shrink on long runs only once the armature has been
    # fitted (its values are in the initial population): finding it from scratch needs
    # them all (with 10 on the 7650-cycle sweep_g0-8 it was missed, gamma_scale taken)
    seeded = all(name in (base or {}) for name in EFFECTS["feedback"])
    popsize, maxiter = search_budget(
        proto.effects, settings, problem_cycles(problem) if seeded else None
    )
    extra = {}
    if glob and maxiter > 0:
        sub = [free[i] for i in glob]
        if settings.box_share is not None:
            sub = box_around(sub, decode(free, x), settings.box_share)

        def lift(z):
            y = x.copy()
            y[glob] = z
            return y

        def search(evaluator: _Evaluator, z0: np.ndarray) -> np.ndarray:
            return _global_search(evaluator, lift, sub, z0, popsize, maxiter, settings, seed)

        z0 = x[glob]
        max_gamma = continuation_gamma(problem) if continuation else None
        if max_gamma is not None:
            info = _low_gamma_search(
                problem, model_name, fixed, free, x, [names[i] for i in glob], pool,
                max_gamma, (popsize, maxiter, settings, seed),
            )  # fmt: skip
            extra["continuation"] = info
            z_low = encode(free, info["params"])[glob]
            # the low-Gamma optimum starts the joint search when it does better there too
            if ev(lift(z_low)) < ev(x):
                z0 = z_low
        x[glob] = search(ev, z0)
    if free:
        _refine(ev, free, x, settings.local_evals * len(free))
    else:
        ev(x)
    cloud_x = np.asarray(ev.xs, dtype=float).reshape(len(ev.xs), len(free))
    cloud_gaps = np.asarray(ev.gaps, dtype=float)
    w = problem.weights * problem.fit
    clipped = problem.clipped(cloud_gaps)
    values = clipped @ w / w.sum() if problem.fit.any() else np.zeros(len(ev.xs))
    i = int(np.argmin(values))  # the best evaluation overall (global search and refinement)
    return FitResult(
        model=ev.model(cloud_x[i]),
        free=free,
        objective=float(values[i]),
        gaps=cloud_gaps[i],
        cloud_x=cloud_x,
        cloud_gaps=cloud_gaps,
        n_evals=len(ev.xs),
        seconds=time.perf_counter() - t0,
        extra=extra,
        flights=ev.flights + extra.get("continuation", {}).get("flights", 0),
    )


def _low_gamma_search(
    problem: Problem,
    model_name: str,
    fixed: dict,
    free: list[FreeParam],
    x: np.ndarray,
    searched: list[str],
    pool: EvaluationPool | None,
    max_gamma: float,
    budget: tuple,
) -> dict:
    """The first search of a continued fit (:func:`fit_model`): the ``searched``
    parameters on the steps up to ``max_gamma`` (:meth:`Problem.restricted`), the others
    at their values in ``x``, from ``x``, with the joint search's ``budget``
    (``(popsize, maxiter, settings, seed)``).

    Returns
    -------
    dict: ``max_gamma``, ``params`` (every fitted parameter at the search's best),
    ``n_evals`` and ``cycles`` (simulated drive cycles, one member) of the search.
    """
    popsize, maxiter, settings, seed = budget
    glob = [i for i, p in enumerate(free) if p.name in searched]
    low = _Evaluator(problem, model_name, fixed, free, pool, max_gamma)

    def lift(z):
        y = x.copy()
        y[glob] = z
        return y

    sub = [free[i] for i in glob]
    z = _global_search(low, lift, sub, x[glob], popsize, maxiter, settings, seed)
    return {
        "max_gamma": max_gamma,
        "params": decode(free, lift(z)),
        "n_evals": len(low.xs),
        "cycles": len(low.xs) * low.problem.n_draws * problem_cycles(low.problem),
        "flights": low.flights,
    }


def _global_search(
    ev: _Evaluator,
    lift,
    sub: list[FreeParam],
    z0: np.ndarray,
    popsize: int,
    maxiter: int,
    settings: FitSettings,
    seed: int,
) -> np.ndarray:
    """Differential evolution of ``ev`` over the searched parameters ``sub`` (their
    vector ``z`` is lifted to the full optimiser vector by ``lift``), from ``z0`` in the
    initial population; returns the best ``z``."""

    def objective(z):
        return ev(lift(z))

    def population_map(_func, zs):
        # scipy's map-like ``workers``: the values of ``objective`` over the population
        # (``_func`` wraps it), evaluated together so that a pool can share them out
        return ev.many([lift(z) for z in zs])

    de = differential_evolution(
        objective,
        [(p.lower, p.upper) for p in sub],
        seed=seed,
        popsize=population_per_param(popsize, settings.max_population, len(sub)),
        maxiter=maxiter,
        tol=settings.tol,
        polish=False,
        init="latinhypercube",  # sobol would round the population up to 2^m
        x0=z0,
        integrality=[p.choices is not None for p in sub],
        updating="deferred",
        workers=population_map,
    )
    return de.x


def problem_cycles(problem: Problem) -> float:
    """Drive cycles one simulation of ``problem``'s protocol runs (one ensemble member)."""
    return float(problem.protocol["cycles"].sum())


def spent_cycles(fits, problem: Problem) -> float:
    """Simulated drive cycles (one member) the ``fits`` of ``problem`` used: evaluations
    x draws x the protocol's cycles, the unit of :data:`DIAGNOSIS_CYCLES`."""
    own = float(sum(f.n_evals for f in fits)) * problem.n_draws * problem_cycles(problem)
    return own + sum(f.extra.get("continuation", {}).get("cycles", 0.0) for f in fits)


def search_budget(effects, settings: FitSettings, cycles: float | None = None) -> tuple[int, int]:
    """Differential evolution's ``(popsize per parameter, maxiter)`` for a model of
    ``effects`` (larger with ``feedback``, see :class:`FitSettings`) on a run of
    ``cycles`` simulated drive cycles per evaluation (None: any length).

    With ``feedback`` the extra generations are what :data:`FEEDBACK_SEARCH_CYCLES`
    allows for a full population (``max_population``), at least ``maxiter``.
    """
    popsize, maxiter = settings.popsize, settings.maxiter
    if "feedback" in effects:
        popsize += settings.feedback_extra_popsize
        longest = maxiter * settings.feedback_maxiter_factor
        if cycles is not None and cycles > 0:
            allowed = int(FEEDBACK_SEARCH_CYCLES / (settings.max_population * cycles)) - 1
            longest = min(longest, max(maxiter, allowed))
        maxiter = longest
    return popsize, maxiter


def population_per_param(popsize: int, max_population: int, n_params: int) -> int:
    """Differential evolution's ``popsize`` (per parameter) for ``n_params`` searched
    parameters: ``popsize``, but at most ``max_population`` in all."""
    return max(1, min(popsize, max_population // n_params))


def refine_settings(
    problem: Problem,
    effects,
    settings: FitSettings,
    fixed: dict | None = None,
    spent: float = 0.0,
) -> FitSettings | None:
    """Budget of the refinement of a selected model of ``effects``, or None to skip it.

    Why a refinement: on the blind seed-like cases (friction, restitution, feedback) the
    selection's joint fit of six parameters, one 4-member ensemble per evaluation, lands
    on a lucky draw of the orbit lottery far from the truth (``seed_like_c``: mu 27 %,
    mass_ratio 26 %, f_ratio 24 % off). Refitting the selected model with the capped
    gaps averaged over :data:`REFINE_DRAWS` ensembles (the expected gap, not one draw)
    and a population of :data:`REFINE_POPULATION` over up to :data:`REFINE_MAXITER`
    generations brought all three within 7 % when refitted offline with 40 generations;
    in the blind harness (27 generations on that run) mu 5.5 %, mass_ratio 19 %,
    f_ratio 3 % (docs/diagnosis.md). The selection itself is unchanged; only the
    selected model's parameters are refined.

    The number of generations is what :data:`REFINE_CYCLES` allows on this run (at most
    :data:`REFINE_MAXITER`), and no more than what the selection's rounds left of
    :data:`DIAGNOSIS_CYCLES` (``spent``: simulated cycles the rounds used,
    :func:`spent_cycles`); None for models of fewer than :data:`REFINE_MIN_PARAMS`
    continuous parameters or when fewer than :data:`REFINE_MIN_GENERATIONS` generations
    fit the budget (long runs).
    """
    free = free_params(effects, fixed)
    if sum(p.choices is None for p in free) < REFINE_MIN_PARAMS:
        return None
    popsize, _maxiter = search_budget(effects, settings)
    population = population_per_param(popsize, REFINE_POPULATION, len(free)) * len(free)
    cycles = problem_cycles(problem) * REFINE_DRAWS
    budget = min(REFINE_CYCLES, DIAGNOSIS_CYCLES - float(spent))
    maxiter = min(REFINE_MAXITER, int(budget / cycles // population) - 1)
    if maxiter < REFINE_MIN_GENERATIONS:
        return None
    return replace(
        settings,
        max_population=REFINE_POPULATION,
        maxiter=maxiter,
        feedback_maxiter_factor=1,
    )


def recheck_best(
    fit: FitResult, problem: Problem, top: int, pool: EvaluationPool | None = None
) -> FitResult:
    """The fit's ``top`` best evaluations scored again on fresh ensembles; the best of
    the pooled draws kept.

    Why: the best of hundreds of evaluations of a noisy objective is partly the luckiest
    draw (the winner's curse); on the blind seed-like cases more generations of the
    refinement moved the armature's parameters further along their flat valley, not
    closer to the truth. Each of the ``top`` points gets ``problem.n_draws`` more
    ensembles, shifted half-way between the fit's own (:func:`step_gaps`), and the point
    with the least mean over both sets of draws is returned with those averaged gaps.
    """
    if top < 1 or not problem.fit.any() or len(fit.cloud_x) == 0:
        return fit
    w = problem.weights * problem.fit
    values = problem.clipped(fit.cloud_gaps) @ w / w.sum()
    best = np.argsort(values, kind="stable")[:top]
    params = [{**fit.model.params, **decode(fit.free, fit.cloud_x[i])} for i in best]
    shift = 0.5 / max(problem.n_draws, 1)
    if pool is not None and len(params) > 1:
        counted = pool.counted_gaps(fit.model.name, params, problem.n_draws, shift)
    else:
        buffer = OutputBuffer()
        counted = [
            counted_step_gaps(problem, Model.parse(fit.model.name, p), buffer, shift)
            for p in params
        ]
    fresh = [g for g, _ in counted]
    pooled = [
        (problem.clipped(fit.cloud_gaps[i]) + problem.clipped(g)) / 2.0
        for i, g in zip(best, fresh, strict=True)
    ]
    scores = [float(g @ w / w.sum()) for g in pooled]
    j = int(np.argmin(scores))
    return replace(
        fit,
        model=Model.parse(fit.model.name, params[j]),
        objective=scores[j],
        gaps=pooled[j],
        n_evals=fit.n_evals + len(params),
        flights=fit.flights + sum(n for _, n in counted),
    )


def _defaults(free: list[FreeParam]) -> dict:
    out = {}
    for p in free:
        for eff in EFFECTS.values():
            if p.name in eff:
                out[p.name] = eff[p.name][0]
    return out


def _refine(ev: _Evaluator, free: list[FreeParam], x: np.ndarray, max_evals: int) -> np.ndarray:
    """A short Nelder-Mead search over the continuous parameters from ``x`` (no gradients).

    Discrete choices stay at their value. The simplex starts at 5 % of each range, a
    scale the global search resolves; the objective clips to the bounds.
    """
    cont = [i for i, p in enumerate(free) if p.choices is None]
    if not cont or max_evals < 2:
        return x
    lo = np.array([free[i].lower for i in cont])
    hi = np.array([free[i].upper for i in cont])

    def sub(z):
        y = x.copy()
        y[cont] = np.clip(z, lo, hi)
        return ev(y)

    z0 = x[cont]
    step = 0.05 * (hi - lo)
    simplex = [z0] + [z0 + np.where(np.arange(len(cont)) == j, step, 0.0) for j in range(len(cont))]
    simplex = np.array([np.clip(s, lo, hi) for s in simplex])
    # a vertex on the upper bound would collapse the simplex: step inwards there
    for j in range(len(cont)):
        if simplex[j + 1, j] == simplex[0, j]:
            simplex[j + 1, j] = z0[j] - step[j]
    res = minimize(
        sub,
        z0,
        method="Nelder-Mead",
        options={"maxfev": max_evals, "initial_simplex": simplex, "xatol": 1e-4, "fatol": 1e-6},
    )
    y = x.copy()
    y[cont] = np.clip(res.x, lo, hi)
    return y


def bootstrap_params(
    fit: FitResult, problem: Problem, n_boot: int = 200, seed: int = 0
) -> np.ndarray:
    """Refits over bootstrap resamples of the fit steps, on the evaluations already made.

    Each resample draws the fit steps with replacement; its refit is the evaluated
    parameter vector with the least resampled mean gap. This needs no new simulation,
    and its resolution is that of the evaluations near the optimum (the late population
    of the global search and the local refinement): an interval narrower than their
    spacing comes out as a single value.

    Returns
    -------
    ndarray (n_boot, len(fit.free)): the parameter values (decoded) of each refit.
    """
    idx = np.flatnonzero(problem.fit)
    if len(fit.free) == 0 or len(idx) == 0 or len(fit.cloud_x) == 0:
        return np.zeros((n_boot, len(fit.free)))
    rng = np.random.default_rng(seed)
    counts = rng.multinomial(len(idx), np.full(len(idx), 1.0 / len(idx)), size=n_boot)
    # weighted sums (the common denominator of one resample does not change its argmin)
    clipped = problem.clipped(fit.cloud_gaps)[:, idx]
    values = (counts * problem.weights[idx]) @ clipped.T  # (n_boot, n_evals)
    best = np.argmin(values, axis=1)
    decoded = np.array([list(decode(fit.free, x).values()) for x in fit.cloud_x])
    return decoded[best]


def fresh_step_gaps(model: Model, problem: Problem, draws: int = NOISE_DRAWS) -> np.ndarray:
    """Per-step gaps (rad) of ``model`` on ``draws`` fresh ensembles, shape (draws, G):
    the member offsets shifted by ``k / (draws + 1)`` of :data:`MEMBER_SPREAD`
    (:func:`step_gaps`), ``k = 1 .. draws``, none of them the fits' own ensemble.

    Why: the best evaluation of a fit is the luckiest draw of the orbit lottery among
    hundreds; on fresh ensembles two points compare without that winner's curse.
    """
    buffer = OutputBuffer()
    return np.array(
        [step_gaps(problem, model, buffer, shift=k / (draws + 1)) for k in range(1, draws + 1)]
    )


def fresh_objectives(model: Model, problem: Problem, draws: int = NOISE_DRAWS) -> np.ndarray:
    """Fit-step objective (rad) of ``model`` on ``draws`` fresh ensembles
    (:func:`fresh_step_gaps`), shape (draws,)."""
    return np.array([problem.mean(g, problem.fit) for g in fresh_step_gaps(model, problem, draws)])


def objective_noise(fit: FitResult, problem: Problem, draws: int = NOISE_DRAWS) -> float:
    """Standard deviation (rad) of the fit-step objective at the best parameters over
    ``draws`` fresh ensembles (:func:`fresh_objectives`).

    The objective's own noise: which of coexisting orbits the members settle on after a
    chaotic stretch is a lottery, so the same parameters score differently with another
    ensemble. The best evaluation of a fit is the luckiest draw among hundreds; parameters
    whose objective lies within this noise of it cannot be told apart by the data.
    0 for fewer than two draws or no fit steps.
    """
    if draws < 2 or not problem.fit.any():
        return 0.0
    return float(np.std(fresh_objectives(fit.model, problem, draws), ddof=1))


def noise_intervals(fit: FitResult, problem: Problem, tolerance: float) -> dict:
    """``{name: [lo, hi]}``: the range of each fitted parameter over the evaluations whose
    fit-step objective lies within ``tolerance`` (rad) of the best (a profile-like set;
    always holds the best value)."""
    if len(fit.free) == 0 or len(fit.cloud_x) == 0:
        return {}
    w = problem.weights * problem.fit
    if not w.any():
        return {p.name: [float(fit.model.params[p.name])] * 2 for p in fit.free}
    values = problem.clipped(fit.cloud_gaps) @ w / w.sum()
    near = values <= fit.objective + tolerance
    decoded = np.array([list(decode(fit.free, x).values()) for x in fit.cloud_x[near]])
    out = {}
    for j, p in enumerate(fit.free):
        best = float(fit.model.params[p.name])
        out[p.name] = [float(min(decoded[:, j].min(), best)), float(max(decoded[:, j].max(), best))]
    return out


def poorly_identified(fit: FitResult, ci: dict, share: float = WIDE_SHARE) -> list[str]:
    """Warnings for continuous parameters whose interval spans more than ``share`` of
    the fitted value (both sides together): the data leave them loose."""
    out = []
    for p in fit.free:
        if p.choices is not None or p.name in PERIODIC or p.name not in ci:
            continue
        v = float(fit.model.params[p.name])
        lo, hi = ci[p.name]
        if hi - lo > share * max(abs(v), 1e-12):
            out.append(f"{p.name}={v:.4g} is poorly identified: interval {lo:.4g} to {hi:.4g}")
    return out


def probe_rise(fit: FitResult, problem: Problem) -> Callable[[str, float], float]:
    """``rise(name, value)``: the fit-step objective (rad; :meth:`Problem.mean` of
    :func:`step_gaps` over ``problem.fit``, the search's own ensemble) of ``fit.model``
    with the one parameter ``name`` moved to ``value``, the others held, less the fitted
    point's, evaluated alike (once, at the first call); negative where the move does
    better. Each call costs a simulation of the fit steps.

    Why the fitted point again rather than ``fit.objective``: a final fit's objective can
    be another ensemble's (the box refinement keeps its point by fresh draws, a refined
    fit is rechecked on others): on 4 of 21 stored diagnoses of session 75 it differed
    from the point's objective on ``problem`` by 0.1-2.5 %.
    """
    buffer = OutputBuffer()
    base: list[float] = []

    def objective(model: Model) -> float:
        return problem.mean(step_gaps(problem, model, buffer), problem.fit)

    def rise(name: str, value: float) -> float:
        if not base:
            base.append(objective(fit.model))
        return objective(fit.model.with_params(**{name: value})) - base[0]

    return rise


def _probed(fit: FitResult) -> list:
    """The fitted parameters a one-parameter probe moves: continuous, not periodic,
    fitted away from 0 (a relative move of 0 is none)."""
    return [
        p
        for p in fit.free
        if p.choices is None and p.name not in PERIODIC and float(fit.model.params[p.name]) != 0.0
    ]


def flat_directions(
    fit: FitResult,
    problem: Problem,
    tolerance: float,
    share: float = PROBE_SHARE,
    rise: Callable[[str, float], float] | None = None,
) -> dict[str, list[tuple[float, float]]]:
    """The moves of one parameter the data cannot resolve: ``{name: [(value, rise), ...]}``.

    Each continuous, non-periodic fitted parameter is moved to ``(1 - share)`` and
    ``(1 + share)`` of its fitted value (kept within its bounds; a side the bounds cut to
    less than half the move is not probed), the others held, and the fit-step objective
    evaluated there (:func:`probe_rise`, or ``rise`` when given, to share its fitted
    point). Listed are the probes whose objective lies within ``tolerance`` (rad) of the
    fitted point's, with that rise (rad). A probe needs no refit of the others, so a
    listed move is one the data surely leave open; an unlisted one may still be open
    along a trade-off. Costs a simulation of the fitted point and two per parameter.
    """
    out: dict[str, list[tuple[float, float]]] = {}
    if not problem.fit.any():
        return out
    rise = rise or probe_rise(fit, problem)
    for p in _probed(fit):
        v = float(fit.model.params[p.name])
        for side in (-1.0, 1.0):
            moved = min(max(v * (1.0 + side * share), p.lower), p.upper)
            if abs(moved - v) < 0.5 * share * abs(v):
                continue
            up = rise(p.name, moved)
            if up <= tolerance:
                out.setdefault(p.name, []).append((float(moved), float(up)))
    return out


def edge_bounds(
    fit: FitResult,
    problem: Problem,
    ci: dict,
    tolerance: float,
    rise: Callable[[str, float], float] | None = None,
    shares: tuple[float, ...] = EDGE_SHARES,
) -> dict[str, list[float]]:
    """``ci`` with each side that sits at the fitted value moved out to the farthest
    one-parameter probe within ``tolerance`` (rad) of the fitted point, ``{name: [lo,
    hi]}`` (a new dict; other entries as they were).

    A side of an interval from the evaluated points (:func:`intervals`,
    :func:`noise_intervals`) sits at the fitted value where no point within the
    tolerance lies on that side: the search came from the other, not a measured
    precision. There the parameter is moved by each of ``shares`` of its value in turn,
    largest first (:data:`EDGE_SHARES`, kept within its bounds), the others held
    (:func:`probe_rise`), and the first move within the tolerance is the side's bound,
    like a point of the noise set. Where none is, the side is the smallest share's move:
    the points within the tolerance lie inside it, and a side at the fitted value would
    claim a precision no probe measured (a black-box probe's s 0.80025 with interval
    [0.80025, 0.80025], the truth 0.8 0.03 % away; docs/diagnosis-log.md, session 80).
    Continuous, non-periodic parameters fitted away from 0 only. Costs a simulation of
    the fitted point and up to ``len(shares)`` per side.
    """
    out = {name: list(bounds) for name, bounds in ci.items()}
    if not problem.fit.any():
        return out
    rise = rise or probe_rise(fit, problem)
    for p in _probed(fit):
        if p.name not in out:
            continue
        v = float(fit.model.params[p.name])
        for end, side in ((0, -1.0), (1, 1.0)):
            if out[p.name][end] != v:
                continue
            moved = v
            for share in shares:
                moved = float(min(max(v * (1.0 + side * share), p.lower), p.upper))
                if moved != v and rise(p.name, moved) <= tolerance:
                    out[p.name][end] = moved
                    break
            else:  # every move resolved: the side lies within the smallest
                out[p.name][end] = moved
    return out


def flat_warnings(fit: FitResult, flat: dict, unit: float, tolerance: float) -> list[str]:
    """Warning lines for :func:`flat_directions`' ``flat`` (one per parameter, its probe
    of least rise), worded as :func:`poorly_identified`'s; ``unit``: rad of one noise
    floor of the fit steps, ``tolerance`` (rad) the probes were held to."""
    out = []
    for name, probes in flat.items():
        value, rise = min(probes, key=lambda vr: vr[1])
        v = float(fit.model.params[name])
        out.append(
            f"{name}={v:.4g} is poorly identified: at {value:.4g} ({100 * (value / v - 1):+.0f} %, "
            f"the others held) the fit steps' gap is {rise / unit:+.2f} noise floors from the "
            f"best, within what the data resolve ({tolerance / unit:.2f})"
        )
    return out


#: The lines of :func:`fit_warnings` and :func:`poorly_identified`, by the parameters they
#: name: ``p=v is poorly identified ...``, ``p=v sits on its ... bound ...`` and
#: ``p and q trade off ...``.
_PARAM_WARNING = re.compile(
    r"^(\w+)=\S+ (?:is poorly identified|sits on its)|^(\w+) and (\w+) trade off"
)


def warned_params(warnings: list[str]) -> set[str]:
    """The parameters that a fit's warnings (a diagnosis step's ``warnings``, written by
    :func:`fit_warnings` and :func:`poorly_identified`) say not to trust alone: loose,
    on a bound, or trading off with another. Other lines are ignored.

    Why: the blind validation scores whether a parameter outside the 15 % goal was
    warned about, and whether one without a warning can be taken at its value.
    """
    out: set[str] = set()
    for line in warnings:
        m = _PARAM_WARNING.match(line)
        if m:
            out.update(g for g in m.groups() if g)
    return out


def intervals(fit: FitResult, boot: np.ndarray, level: float = 0.95) -> dict:
    """Percentile intervals ``{name: [lo, hi]}`` of the bootstrap refits, widened to hold
    the best value (a discrete cloud can leave it just outside)."""
    out = {}
    q = (1.0 - level) / 2.0
    for j, p in enumerate(fit.free):
        best = float(fit.model.params[p.name])
        lo, hi = np.quantile(boot[:, j], [q, 1.0 - q]) if len(boot) else (best, best)
        out[p.name] = [float(min(lo, best)), float(max(hi, best))]
    return out


def fit_warnings(fit: FitResult, boot: np.ndarray) -> list[str]:
    """Warnings about a fit: parameters on a bound, pairs that trade off.

    On a bound: within :data:`BOUND_SHARE` of the range from a bound of
    :data:`bouncelab.physics.EFFECTS` (periodic and discrete parameters excepted). Trade
    off: |Pearson correlation| of two parameters across the bootstrap refits above
    :data:`TRADE_OFF_CORR`, read where the refits take at least
    :data:`TRADE_OFF_MIN_POINTS` distinct pairs of values (two points always line up).
    """
    out = []
    for p in fit.free:
        if p.choices is not None or p.name in PERIODIC:
            continue
        v = float(fit.model.params[p.name])
        span = p.upper - p.lower
        if v - p.lower <= BOUND_SHARE * span:
            out.append(f"{p.name}={v:.4g} sits on its lower bound {p.lower:g}")
        elif p.upper - v <= BOUND_SHARE * span:
            out.append(f"{p.name}={v:.4g} sits on its upper bound {p.upper:g}")
    n = len(fit.free)
    if len(boot) > 2 and n > 1:
        sd = boot.std(axis=0)
        for i in range(n):
            for j in range(i + 1, n):
                if (
                    sd[i] > 0
                    and sd[j] > 0
                    and len(np.unique(boot[:, [i, j]], axis=0)) >= TRADE_OFF_MIN_POINTS
                ):
                    # a spread of rounding size can still be 0 to corrcoef: NaN, no warning
                    with np.errstate(invalid="ignore", divide="ignore"):
                        r = float(np.corrcoef(boot[:, i], boot[:, j])[0, 1])
                    if abs(r) > TRADE_OFF_CORR:
                        a, b = fit.free[i].name, fit.free[j].name
                        out.append(f"{a} and {b} trade off (bootstrap correlation {r:+.2f})")
    return out
