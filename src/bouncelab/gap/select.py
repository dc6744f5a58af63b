"""Forward selection of candidate effects, judged on held-out Gamma steps.

Round by round, every effect of the library not yet in the model is added alone to the
current model and refitted (:func:`bouncelab.gap.fit.fit_model`): every parameter of
the enlarged model is searched globally, with the current model's best values in the
initial population, then all are refined together. Holding the earlier effects at
their values while the new one is searched fails on combinations: an effect fitted
alone absorbs part of the others (restitution alone takes e = 0.39 on a blind case with
e = 0.515 and friction), and the new effect then finds no room. The addition with the
smallest held-out gap (the one with the fewest parameters among those tied with it within
``tie`` noise floors) is accepted when it shrinks the held-out gap

- by at least ``margin`` noise floors, and
- by at least ``min_shrink`` of the current gap,

and selection stops when no addition passes, when the current gap is already within
``explained_ratio`` noise floors (unless the takeoff phases show the model wrong,
``unsettled`` of :func:`forward_select`; above ``strict_ratio`` one more round is tried
first, without the armature, whose addition must halve the gap: :class:`SelectSettings`),
or after ``max_effects`` effects. In a round fitted because of the phases, where no
addition passes on flight times, one that stays within ``explained_ratio`` floors and
sets the phases right, where the effects before it refitted from its point do not, is
taken (:func:`_phase_pick`). An addition whose
strength sits at its null value (:data:`INERT`: friction with mu 0) adds nothing but a
better refit of the effects already taken: it is not accepted; the current model takes
that refit's values (refined locally without the inert effect) when they do better,
and the next addition is judged against it; an effect the final refinement takes to its
null value is dropped the same way. From the second effect on, the proposal must also
beat the effects before it refitted locally from its own values (:func:`earns_place`):
a joint refit's gain can be theirs; when it does not, the refit is kept and the
selection stops. A selection that ends with the armature alone (or
would, before a strict round) is checked against every pair of the other effects
(:func:`_pair_for_armature`). The
selected model's parameters are then refined (:func:`bouncelab.gap.fit.refine_settings`).
All gaps here are weighted means over held-out steps in radians
(:meth:`bouncelab.gap.fit.Problem.mean`);
the noise floor is the same mean of the data's own floor.

Joint fits of later rounds on runs that reach far above the first period doubling search
the low-Gamma steps first (``continuation`` of :func:`bouncelab.gap.fit.fit_model`),
except models with the shaker's armature: its push grows with the impacts, the low steps
pin it weakly, and there the first search took a soft armature that acts as a Gamma
factor (virtual run ``seed_protocol_long_25hz``: friction then missed; docs/diagnosis.md).
"""

from __future__ import annotations

import contextlib
import math
import sys
from dataclasses import dataclass, field, replace

import numpy as np

from bouncelab.gap.fit import (
    BOX_MAXITER,
    BOX_POPULATION,
    BOX_SHARE,
    CHOICES,
    DATA_RESOLUTION,
    K_CHOICES,
    RECHECK_TOP,
    REFINE_DRAWS,
    RIDE_LOAD_CHOICES,
    EvaluationPool,
    FitResult,
    FitSettings,
    Problem,
    fit_model,
    fresh_objectives,
    recheck_best,
    refine_settings,
    spent_cycles,
)
from bouncelab.physics import EFFECT_ORDER, EFFECTS, Model

#: The candidate effects (CONTRACTS.md section 5), in the order they are tried.
CANDIDATES = EFFECT_ORDER

#: Discrete parameters fitted as separate searches: name -> (effect, choices).
SPLITS = {"k": ("harmonic", K_CHOICES), "ride_load": ("feedback", RIDE_LOAD_CHOICES)}

#: Optimiser seeds of the armature's joint fit in the last round (the least fit-step
#: objective kept). Why: one differential-evolution search of the armature beside two
#: other effects ends anywhere between 1.2 and 2.8 floors on the blind ``seed_like_b``
#: (four seeds; the truth 1.53), and the last round then compares that draw with a
#: Gamma miscalibration within the ``tie``: with other diagnosis seeds the blind
#: ``g_seed_like`` (2.28 against 2.32 floors) and ``seed_like_c`` (1.64 against 1.88)
#: took the miscalibration, the simpler of two tied additions (docs/diagnosis-log.md,
#: session 21). Seeds ``seed + j * SEED_STRIDE``, ``j < ARMATURE_SEEDS``.
ARMATURE_SEEDS = 3
SEED_STRIDE = 7919

#: Fresh ensembles on which a later round compares its armature choices, and how many
#: standard errors of their difference the other choice must win by (:func:`armature_choice`).
CHOICE_DRAWS = 4
CHOICE_SIGMAS = 2.0

#: One drive cycle of phase (rad).
TWO_PI = 2.0 * math.pi

#: Relative difference of an armature parameter between the armature taken alone and
#: :func:`armature_alternative` beyond which the parameter is reported poorly identified
#: (issue 6's recovery goal).
ALTERNATIVE_SHARE = 0.15

#: effect -> (strength parameter, its null value, tolerance): within the tolerance the
#: effect does nothing a flight table could show. Why: a joint refit can gain by moving
#: the effects already taken, with the new one at its bound (blind cases: friction at
#: mu 0 after feedback, a harmonic of a 0.001 after restitution; a harmonic of the wrong
#: k refitted to the right one beside restitution at e 0). The tolerances are 1/20 of
#: the weakest true effects of the blind cases (mu 0.1, e 0.2, a 0.05, m/M 0.04, s 4 %).
INERT = {
    "friction": ("mu", 0.0, 0.005),
    "restitution": ("e", 0.0, 0.01),
    "harmonic": ("a", 0.0, 0.0025),
    "feedback": ("mass_ratio", 0.0, 0.002),
    "gamma_scale": ("s", 1.0, 0.002),
}


def is_inert(effect: str, params: dict) -> bool:
    """Whether ``effect``'s strength in ``params`` is at its null value (:data:`INERT`)."""
    name, null, tol = INERT[effect]
    return name in params and abs(float(params[name]) - null) <= tol


@dataclass(frozen=True)
class SelectSettings:
    """Stop rule of the forward selection (gaps in units of the held-out noise floor).

    Attributes
    ----------
    margin : an accepted effect removes at least this many noise floors of held-out gap.
        On the development cases the largest reduction any effect gave a null run was
        0.12 floors; twice that.
    min_shrink : and at least this share of the current held-out gap.
    explained_ratio : no effect is added once the held-out gap is at most this many
        noise floors. The virtual rig is a different model (compliant contact, sensor
        chain): its null runs sit at 0.2-0.35 floors against the ideal model, and runs
        whose true effect was found at 0.14-1.9 floors, which this leaves room for.
    unexplained_ratio : the final held-out gap above this many floors is "unexplained".
    max_effects : at most this many effects are accepted.
    settled_ratio : the last round searches the armature again with its other
        ``ride_load`` choice unless round 1's choice is the round's proposal and brings the
        held-out gap within this many floors (:func:`_armature_again`). One floor: below
        it the data cannot tell the choices apart; above it they can. At
        ``explained_ratio`` (2), an independent seed-like recording's loaded armature
        (1.59 floors, f_ratio 0.34 for 0.6, takeoff phases 0.16 rad off) ended the
        selection unexplained while the impacts-only one reaches 0.60 floors.
    strict_ratio, strict_shrink : a run within ``explained_ratio`` floors but above
        ``strict_ratio`` still tries the next round, and takes an addition only when it
        removes at least ``strict_shrink`` of the held-out gap (and ``margin``). Why: a
        harmonic alone at 1.99 floors ended the independent ``harmonic_gamma_scale``,
        whose miscalibration then takes it to 0.60 (70 % less); a plain stop at 1 floor
        gave two blind single-effect runs a spurious second effect
        (``g_restitution_high``: the armature, 1.76 -> 1.04, 41 % less). After the
        first round such a strict round leaves the armature out: the most flexible
        effect is the one that stands in (``g_restitution_high``'s armature: 1.94 ->
        0.99 floors, 49 % less, on this code), and its searches would double the time
        of a run (independent ``friction_restitution``: 35 -> 125 s with it).
    box_ratio : a selected model without the armature still above this many floors is
        refined again in a box around its fit (:func:`box_refinement`).
    tie : additions whose held-out gaps lie within this many noise floors of the least
        are tied, and the one with the fewest fitted parameters is taken (then the
        least gap). Why: a loaded armature on a soft suspension (``f_ratio`` near 0) is a
        constant amplitude factor, a Gamma miscalibration with three parameters; on the
        development case ``gamma_scale_a`` it came out 0.013 floors ahead of
        ``gamma_scale`` (0.130 against 0.143), a difference the data cannot make.
    repeat_limit : rad; the final model's periodic steps whose data repeat, in the median,
        by this much or more (or by 2.5 samples, where that is more) name the run
        unexplained: a random force (``gap.diagnose.repeat_reason``). 0.02 is twice
        the most any generated case without plate vibration showed (one sample, 0.0094
        rad); a rig whose flights scatter more for a cause it accepts can raise it (a
        large value turns the rule off).
    not_first : effects that round 1 fits and reports but does not take: the round's
        proposal is the best of the others; later rounds may take them. The retry of a
        diagnosis that took the armature first and left the run unexplained sets it
        (:func:`bouncelab.gap.diagnose.retry_settings`). Why: the armature's four
        parameters stand in for two or three effects at once in round 1, and a selection
        that starts from it cannot drop it later (independent
        ``friction_restitution_harmonic``: the armature 0.31 floors ahead of restitution,
        just outside ``tie``, then restitution, unexplained at 3.49 floors with seeds 0
        and 1 alike; restitution first gives restitution, the harmonic and friction,
        explained at 1.00-1.49; docs/diagnosis-log.md, session 80).
    """

    margin: float = 0.25
    min_shrink: float = 0.1
    explained_ratio: float = 2.0
    unexplained_ratio: float = 3.0
    max_effects: int = 3
    tie: float = 0.25
    settled_ratio: float = 1.0
    strict_ratio: float = 1.0
    strict_shrink: float = 0.5
    box_ratio: float = 1.5
    repeat_limit: float = 0.02
    not_first: tuple[str, ...] = ()


def pick_addition(scored: list[tuple[str, float, int]], tie: float) -> int:
    """Index of the addition to propose from ``(effect, held-out gap in floors, number of
    fitted parameters)`` rows: the fewest parameters among those within ``tie`` floors
    of the least gap, then the least gap, then the effect name (deterministic)."""
    least = min(g for _e, g, _n in scored)
    near = [i for i, (_e, g, _n) in enumerate(scored) if g - least <= tie]
    return min(near, key=lambda i: (scored[i][2], scored[i][1], scored[i][0]))


def model_name(effects) -> str:
    """Canonical model name of a set of effects (``"ideal"`` when empty)."""
    return Model.parse("+".join(effects) if effects else "ideal").name


def heldout_gap(fit: FitResult, problem: Problem) -> float:
    """Weighted mean gap (rad, :meth:`Problem.mean`) over the held-out steps."""
    return problem.mean(fit.gaps, problem.heldout)


def evaluation_pool(problem: Problem, workers: int):
    """An :class:`bouncelab.gap.fit.EvaluationPool` of ``workers`` processes for the fits
    of ``problem``, or a null context for one worker (the kernels then use numba's
    threads for the ensemble members). One pool serves every round, so the workers
    import and load the compiled kernels once."""
    if workers <= 1:
        return contextlib.nullcontext(None)
    return EvaluationPool(problem, workers)


@dataclass
class WorkTally:
    """Flights one diagnosis's fits have simulated (:attr:`FitResult.flights`, every fit
    counted once, kept or not): the diagnosis's work, deterministic, reported as
    ``design.work``. Why: a diagnosis's time follows the flights its kernels simulate
    (chatter makes several a cycle), not its cycles (docs/diagnosis-log.md,
    session 30)."""

    flights: int = 0
    #: the selection's stage the next fits belong to (``baseline``, ``round N``,
    #: ``pair_check``, ``refinement``, ``box``, ``weak_dropped``), set by
    #: :func:`forward_select` as it goes
    stage: str = "baseline"
    #: one entry per fit counted: ``stage``, ``model``, ``n_evals``, ``flights``,
    #: ``seconds`` (wall clock: for ``--timings`` only, never in the deterministic keys),
    #: and what the fit reached: its ``params``, fit-step ``objective`` and held-out
    #: ``heldout_gap`` (rad; each left out where not finite: the JSON is strict)
    fits: list = field(default_factory=list)

    def add(self, fits, problems=None) -> None:
        """Count ``fits``; ``problems``: each fit's :class:`Problem`, for its held-out
        gap in the log (None: left out)."""
        for i, f in enumerate(fits):
            self.flights += int(f.flights)
            held = heldout_gap(f, problems[i]) if problems is not None else math.nan
            reached = {"objective": float(f.objective), "heldout_gap": float(held)}
            self.fits.append(
                {
                    "stage": self.stage,
                    "model": f.model.name,
                    "n_evals": int(f.n_evals),
                    "flights": int(f.flights),
                    "seconds": float(f.seconds),
                    "params": {k: float(v) for k, v in f.model.params.items()},
                    **{k: v for k, v in reached.items() if math.isfinite(v)},
                }
            )


def fit_many(
    jobs: list[tuple], pool=None, progress: bool | None = None, work: WorkTally | None = None
) -> list[FitResult]:
    """Run :func:`fit_model` jobs (argument tuples ``(problem, model_name, base, fixed,
    search, settings, seed)``, optionally followed by ``continuation`` and ``starts``) one after
    another, each evaluating its populations in ``pool`` when given. Results come back
    in job order and do not depend on the pool. A progress bar is shown on a terminal
    (``progress=None``: when stderr is a TTY). ``work``: the tally their flights are
    added to.
    """
    from tqdm import tqdm

    if progress is None:
        progress = sys.stderr.isatty()
    results = []
    with tqdm(total=len(jobs), desc="fits", unit="fit", disable=not progress, leave=False) as bar:
        for job in jobs:
            problem, name, base, fixed, search, settings, seed, *more = job
            results.append(
                fit_model(
                    problem,
                    name,
                    base,
                    fixed=fixed,
                    search=search,
                    settings=settings,
                    seed=seed,
                    pool=pool,
                    continuation=bool(more and more[0]),
                    starts=more[1] if len(more) > 1 else None,
                )
            )
            bar.set_postfix_str(name, refresh=False)
            bar.update()
    if work is not None:
        work.add(results, [job[0] for job in jobs])
    return results


def _discrete_splits(effect: str, fixed: dict, chosen: dict | None = None) -> list[dict]:
    """One fit per value of a discrete parameter (harmonic ``k``, feedback ``ride_load``),
    else one fit.

    A separate global search per choice explores the continuous parameters properly for
    each; one search over all mixes the choices and misses narrow basins.  Once the
    effect has been fitted alone (round 1), later rounds keep its choice (``chosen``:
    parameter -> value): a joint search per choice every round would cost more than all
    other effects together (the armature's is searched again in the last round,
    :func:`_armature_again`).
    """
    chosen = chosen or {}
    for name, (owner, values) in SPLITS.items():
        if effect == owner and name not in fixed:
            if name in chosen:
                return [{name: chosen[name]}]
            return [{name: v} for v in values]
    return [{}]


def read_starts(read: dict | None, name: str, fixed: dict) -> list[dict]:
    """Other starts of a fit of model ``name`` with ``fixed`` parameters
    (:func:`bouncelab.gap.fit.fit_model`'s ``starts``: the search starts from the best on
    the fit steps) from the harmonic ``read`` off the takeoff phases
    (:func:`bouncelab.gap.takeoff_reading.seen_harmonic`, None: nothing seen): its ``k, a,
    psi``, and its ``mu`` where the model has friction, when the model has the harmonic
    and ``k`` is free or fixed at the read one; else none.

    Why: a global search of a model with a harmonic misses the harmonic's narrow basin
    on some runs, and the reading finds it without a simulation. On the independent
    ``friction_harmonic`` at diagnosis seed 1 the selection ended with ``a`` 20 % off at
    1.87 floors, from the reading at 0.08 floors with ``a, mu, psi`` at the truth; the
    seed-1 ``restitution_harmonic`` and ``friction_harmonic_g0-8`` needed the retry
    without it (docs/diagnosis-log.md, sessions 52-53).
    """
    model = Model.parse(name)
    if read is None or "harmonic" not in model.effects:
        return []
    if "k" in fixed and float(fixed["k"]) != float(read["k"]):
        return []
    start = {p: read[p] for p in ("k", "a", "psi")}
    if "friction" in model.effects:
        start["mu"] = read["mu"]
    return [start]


def _k_held_again(tried, prev: dict, job, pool, progress, work: WorkTally, read=None):
    """``tried`` with each joint fit beside a taken harmonic (its ``k`` in ``prev``) that
    moved ``k`` fitted again with the ``k`` taken held, the better on the fit steps kept
    (:func:`_best_of`). ``job``: ``(problem, fixed, fit settings, seed)``. Not the
    armature's fits: they are the dearest, and keep their choice free.

    Why: the joint search over ``k`` (:data:`bouncelab.gap.fit.JOINT_K_CHOICES`) is one
    population for every ``k``, and a broad mediocre basin at another ``k`` can beat the
    right one's narrow basin that the population missed: the independent
    ``friction_harmonic_g0-8`` took k 3 in round 1 and its joint friction fit ended at
    k 4, unexplained at 3.0 floors (docs/diagnosis-log.md, session 51). Only where ``k``
    moved: fitting every joint fit twice cost 23-59 % more flights (session 50).
    ``read``: the harmonic read off the takeoff phases (:func:`read_starts`).
    """
    problem, fixed, fit_settings, seed = job
    if "k" not in prev or "k" in fixed:
        return tried
    k = float(prev["k"])
    moved = [
        (e, f)
        for e, f in tried
        if e != "feedback" and "k" in f.model.params and float(f.model.params["k"]) != k
    ]
    if not moved:
        return tried
    jobs = [
        (
            problem,
            f.model.name,
            prev,
            {**fixed, "k": k},
            None,
            fit_settings,
            seed,
            "feedback" not in f.model.effects,  # (the rounds' continuation rule)
            read_starts(read, f.model.name, {**fixed, "k": k}),
        )
        for _e, f in moved
    ]
    again = dict(zip([e for e, _f in moved], fit_many(jobs, pool, progress, work), strict=True))
    return [(e, _best_of(e, [e, e], [f, again[e]]) if e in again else f) for e, f in tried]


def _least_objective(effect: str, owners: list[str], fits: list[FitResult]) -> FitResult:
    """The fit of ``effect`` with the least fit-step objective (never the held-out gap,
    which judges the effect and must not choose its parameters)."""
    mine = [f for o, f in zip(owners, fits, strict=True) if o == effect]
    return min(mine, key=lambda f: f.objective)


def _best_of(effect: str, owners: list[str], fits: list[FitResult]) -> FitResult:
    """:func:`_least_objective`, with ``n_evals`` and ``seconds`` summed over the fits of
    ``effect``."""
    mine = [f for o, f in zip(owners, fits, strict=True) if o == effect]
    best = _least_objective(effect, owners, fits)
    cont = [f.extra["continuation"] for f in mine if "continuation" in f.extra]
    best.n_evals = sum(f.n_evals for f in mine)
    best.seconds = sum(f.seconds for f in mine)
    if cont:  # the cost of every split's first search counts in the budget
        best.extra["continuation"] = {
            **best.extra.get("continuation", cont[0]),
            "cycles": sum(c["cycles"] for c in cont),
        }
    return best


def armature_choice(fits: dict[float, FitResult], kept: float, problem: Problem) -> FitResult:
    """The armature a later round adds: the fit with round 1's ``ride_load`` (``kept``),
    unless the fit with another choice does better on fresh ensembles
    (:func:`bouncelab.gap.fit.fresh_objectives`, :data:`CHOICE_DRAWS`): its mean
    fit-step objective lower by more than :data:`CHOICE_SIGMAS` standard errors of the
    difference and by more than :data:`bouncelab.gap.fit.DATA_RESOLUTION` of the fit
    steps' mean noise floor.

    ``fits``: ``ride_load`` -> the joint fit with that choice. Why not simply the least
    fit-step objective: a five-parameter joint search ends on a lucky draw of the orbit
    lottery, and which choice wins is then a lottery too. On the rig's ``g_seed_like``
    (a loaded armature beside friction and restitution; both choices searched in round
    2 by a first version of this rule) the two fits came out at
    3.34 and 3.76 floors, on fresh ensembles at 3.86 and 3.90 (standard deviations 0.17,
    0.07): the lesser took the selection on to a harmonic instead of friction. On the
    independent seed-like recording (before its generator's fix, docs/diagnosis-log.md,
    session 18) the impacts-only armature was 0.77 floors on fresh ensembles
    against 1.61 for the loaded one: a clear win, taken. The other choice's
    evaluations count in the kept fit's ``n_evals`` either way.
    """
    best = fits[kept]
    others = {v: f for v, f in fits.items() if v != kept}
    spent = sum(f.n_evals for f in fits.values())
    if others and problem.fit.any():
        ref = fresh_objectives(best.model, problem, CHOICE_DRAWS)
        margin_of = {}
        for v in sorted(others):
            gain = _fresh_gain(ref, others[v].model, problem)
            if gain is not None:
                margin_of[v] = gain
        if margin_of:
            best = others[max(margin_of, key=margin_of.get)]
    best.n_evals = spent
    return best


def _fresh_gain(ref: np.ndarray, model: Model, problem: Problem) -> float | None:
    """How much lower ``model``'s mean fit-step objective (rad) is on :data:`CHOICE_DRAWS`
    fresh ensembles than ``ref`` (another model's, same draws), where clearly so
    (:func:`_clearly_lower`); else None (the data do not tell the two apart, or ``ref``
    is ahead)."""
    return _clearly_lower(ref, fresh_objectives(model, problem, CHOICE_DRAWS), problem)


def _clearly_lower(ref: np.ndarray, vals: np.ndarray, problem: Problem) -> float | None:
    """``ref.mean() - vals.mean()`` (fresh objectives of two models on the same draws,
    rad) where it is more than :data:`CHOICE_SIGMAS` standard errors of the difference
    and more than :data:`bouncelab.gap.fit.DATA_RESOLUTION` of the fit steps' mean noise
    floor; else None."""
    se = math.sqrt((ref.var(ddof=1) + vals.var(ddof=1)) / vals.size)
    resolution = DATA_RESOLUTION * problem.mean(problem.floor, problem.fit)
    gain = float(ref.mean() - vals.mean())
    return gain if gain > max(CHOICE_SIGMAS * se, resolution) else None


def _proposal(tried: list[tuple[str, FitResult]], problem: Problem, floor: float, tie: float):
    """The addition a round proposes among ``tried`` (``(effect, fit)``): the least held-out
    gap, the fewest parameters within ``tie`` floors (:func:`pick_addition`), inert
    additions left out; None when all are inert."""
    live = [(e, f) for e, f in tried if not is_inert(e, f.model.params)]
    if not live:
        return None
    scored = [(e, heldout_gap(f, problem) / floor, len(f.free)) for e, f in live]
    return live[pick_addition(scored, tie)]


def _settled(tried, problem: Problem, floor: float, settings: SelectSettings) -> bool:
    """Whether the armature of ``tried`` is the round's proposal and brings the held-out
    gap within ``settled_ratio`` floors: more searches of it could then only move its
    parameters along the valley the flight times leave flat (:func:`_armature_again`)."""
    mine = dict(tried)
    pick = _proposal(tried, problem, floor, settings.tie)
    settled = heldout_gap(mine["feedback"], problem) <= settings.settled_ratio * floor
    return pick is not None and pick[0] == "feedback" and settled


def _armature_contends(tried, problem: Problem, floor: float, settings: SelectSettings) -> bool:
    """Whether the armature of ``tried`` (one round's ``(effect, fit)``) is within ``tie``
    floors of held-out gap of the best other addition: only then do its extra searches
    (:func:`_armature_seeds`, :func:`_armature_again`) run. Inert additions count: their
    gap is what the current model, refitted, gives without a new effect (blind
    ``friction_restitution``, diagnosis seed 4: harmonic and miscalibration inert at 2.44
    and 2.80 floors, the armature's first search 3.55; its extra searches took it to
    1.56 and a false armature was selected).

    Why: each costs as much as all other additions of the round, and where the armature
    is not an effect they bought nothing. Measured in last rounds (first search against
    the best other addition, in floors; docs/diagnosis-log.md, session 26): a true
    armature led or trailed by at most 0.13 (blind ``seed_like_b`` seed 1: 1.97 against
    1.84), on nine runs; a false one trailed by 0.35 or more, or nothing else gained
    (independent ``friction_restitution_harmonic``: 2.56 against 2.20, about 100 s of
    extra searches for the same selection).
    """
    if "feedback" not in dict(tried):
        return True
    return -_armature_lead(tried, problem) <= settings.tie * floor


def _armature_lead(tried, problem: Problem) -> float:
    """Held-out gap (rad) of the best other addition of ``tried`` (inert ones included:
    their gap is the current model's, refitted) less the armature's; inf without another."""
    others = [heldout_gap(f, problem) for e, f in tried if e != "feedback"]
    if not others:
        return math.inf
    return min(others) - heldout_gap(dict(tried)["feedback"], problem)


def _worth_searching_again(tried, problem: Problem, floor: float, settings) -> bool:
    """Whether the last round's armature gets its extra searches: it does not settle the
    run already (:func:`_settled`) and contends with the other additions
    (:func:`_armature_contends`)."""
    return not _settled(tried, problem, floor, settings) and _armature_contends(
        tried, problem, floor, settings
    )


def _armature_leads(tried, problem: Problem, floor: float, settings: SelectSettings) -> bool:
    """Whether the armature of ``tried`` is the round's proposal, more than ``tie`` floors
    of held-out gap ahead of every other addition, and within ``explained_ratio``
    floors: the round takes it and the run is explained with it, so the runner-up's
    second start (:func:`_runner_up_start`) would have to gain more than the lead to
    change the round (on the seed-like runs it gained nothing, session 61): it does not
    run.

    Not used for the armature's own extra seeds (:func:`_armature_seeds`): they cannot
    change the round's choice, but they move the armature's parameters, and the verdict
    (the takeoff phases, the drift of friction) rests on those. Skipping them where the
    armature leads (session 60) turned the blind ``seed_like_c`` at diagnosis seed 21
    from explained at 1.63 floors to unexplained at 2.31, flagged on its phases, and paid
    a whole retry for the 13 % of flights it saved (docs/diagnosis-log.md, session 66).
    """
    pick = _proposal(tried, problem, floor, settings.tie)
    if pick is None or pick[0] != "feedback":
        return False
    explained = heldout_gap(pick[1], problem) <= settings.explained_ratio * floor
    return _armature_lead(tried, problem) > settings.tie * floor and explained


def _armature_seeds(tried, job, pool, progress, floor, settings, work: WorkTally):
    """``tried`` of the last round with the armature's joint fit run again with
    :data:`ARMATURE_SEEDS` - 1 more optimiser seeds (``seed + j * SEED_STRIDE``), the
    least fit-step objective kept (:func:`_best_of`). ``job``: the round's
    :func:`fit_model` job of that fit (None: no armature in the round).

    Runs after :func:`_armature_again`, with the ``ride_load`` it kept. Skipped when
    the armature already settles the run (:func:`_settled`), for the time goal
    (``raw/sweep_g0-8`` is settled at 0.81 floors by its armature), and when no
    armature is added. Not skipped where the armature leads the round clearly: the
    seeds move its parameters, on which the verdict rests (:func:`_armature_leads`).
    Why more seeds: see :data:`ARMATURE_SEEDS`. Why after the other choice: where that
    choice settles the run, the seeds are saved (independent ``seed_like_impacts_only``:
    the other choice at 0.94 floors with the same final model as the seeds first, 302
    million flights for 384, 116 s for 146 s; docs/diagnosis-log.md, sessions 30-31).
    """
    if job is None or ARMATURE_SEEDS <= 1:
        return tried
    problem, name, start, fixed, search, fit_settings, seed, *more = job
    if not _worth_searching_again(tried, problem, floor, settings):
        return tried
    mine = dict(tried)
    kept = mine["feedback"].model.params.get("ride_load")  # the choice _armature_again kept
    if kept is not None:
        fixed = {**fixed, "ride_load": kept}
    jobs = [
        (problem, name, start, fixed, search, fit_settings, seed + j * SEED_STRIDE, *more)
        for j in range(1, ARMATURE_SEEDS)
    ]
    fits = [mine["feedback"], *fit_many(jobs, pool, progress, work)]
    best = _best_of("feedback", ["feedback"] * len(fits), fits)
    return [(e, best if e == "feedback" else f) for e, f in tried]


def _armature_again(tried, kept: float, job, pool, progress, floor, settings, work: WorkTally):
    """``tried`` of the last round the selection has room for (``max_effects``), with the
    armature searched again with its other ``ride_load`` choices and chosen by
    :func:`armature_choice`. ``job``: ``(problem, start, fixed, fit settings, seed)``.

    Why: later rounds keep the choices round 1 made with each effect alone (a harmonic
    alone is a harmonic at its frequency; a joint search per ``k`` every round would
    cost more than all other additions together). But fitted alone where friction and
    restitution carry the gap, the armature stands in for them, and its choice can say
    nothing of the shaker: on an independent seed-like recording with the impacts-only
    armature (m/M 0.04; ``benchmarks/independent_rig.py`` before its session-18 fix)
    round 1 took the loaded one at m/M 0.48 and f_ratio 2.8; kept, round 3 searched only
    that one (1.97 floors held out) and took a Gamma miscalibration (1.84); searched
    again, the impacts-only armature came out at 0.83 floors. In the last round only,
    because each search of the armature costs as much as all other additions of a round
    (in every later round it made ``raw/sweep_g0-8`` 142 s instead of 102, goal 120); an
    armature taken earlier keeps its choice free in the joint fits after it.

    Each other choice is searched twice and the better on the fit steps kept
    (:func:`_best_of`): every parameter at once, as every round searches, and the
    armature's own parameters alone from the round's values of the others (then all
    refined together). By the last round the other effects have been fitted together;
    a joint search of five parameters on a round's budget can miss the armature's narrow
    valley: on the corrected seed-like recording it ended at m/M 0.078 for 0.04 and
    f_ratio 0.43 for 0.6 (1.41 floors on the fit steps), the armature's own search in
    the truth's basin (0.65 floors; m/M, f_ratio and zeta within 15 %).

    The own search runs first, and where it settles the run (the round's proposal
    within ``settled_ratio`` floors, :func:`_settled`) the joint one is not run: it
    could then only move the parameters along the valley the flight times leave flat,
    as where the kept choice settles the run (below). On the independent
    ``seed_like_long_steps`` the own search reached 0.88 floors and the joint one 0.85
    with a larger fit-step objective (0.062 against 0.056): the same answer for 57
    million flights fewer (session 62).

    Skipped when the armature with round 1's choice is the round's proposal and brings
    the run within ``settled_ratio`` (1) noise floors: the other choice could then only
    move its parameters along the valley the flight times leave flat, for a search that
    costs as much as all other additions of the round (``raw/sweep_g0-8``, 0.81 floors:
    123 s with it instead of 102, goal 120).
    """
    problem, start, fixed, fit_settings, seed = job
    mine = dict(tried)
    if "feedback" not in mine or not _worth_searching_again(tried, problem, floor, settings):
        return tried
    name = mine["feedback"].model.name
    own = tuple(p for p in EFFECTS["feedback"] if p != "ride_load")
    loads = {kept: mine["feedback"]}
    for v in [v for v in RIDE_LOAD_CHOICES if v != kept]:
        job_of = {
            search: (problem, name, start, {**fixed, "ride_load": v}, search, fit_settings,
                     seed, False)
            for search in (None, own)
        }  # fmt: skip
        # the own search first: where it settles the run, the joint one is not run
        (alone,) = fit_many([job_of[own]], pool, progress, work)
        with_it = [(e, alone if e == "feedback" else f) for e, f in tried]
        if _settled(with_it, problem, floor, settings):
            loads[v] = alone
            continue
        (joint,) = fit_many([job_of[None]], pool, progress, work)
        # the better of the two searches (the joint one first, as before: ties go to it)
        loads[v] = _best_of("feedback", ["feedback", "feedback"], [joint, alone])
    chosen = armature_choice(loads, kept, problem)
    return [(e, chosen if e == "feedback" else f) for e, f in tried]


def _runner_up_start(rounds, accepted, problem: Problem, floor: float, tie: float):
    """``(effect, parameters)``: a second start for this round's joint fit of the last
    round's runner-up, from the third round on; else None.

    The runner-up is the last round's proposal without the effect it took and without
    the armature (:func:`_proposal`), and the start is its fit's values (the effects
    before the last one taken and the runner-up itself) with the last effect's values
    from the current model; the fit of the two starts with the least fit-step objective
    is kept (:func:`_best_of`). Why: a flexible effect taken beside another can stand in
    for the runner-up, whose joint fit then starts from its null value with the other
    effects where the stand-in left them. Beside restitution the armature's five
    parameters stand in for friction (1.25-1.97 floors held out where friction reaches
    2.6-3.4): on the blind ``seed_like_c`` and ``seed_like_b`` with diagnosis seed 3
    the start from the current model ended at 1.77 and 2.69 floors (mu 0.025), the start
    from round 2's friction + restitution at 0.93 and 1.33 with lower fit-step
    objectives (docs/diagnosis-log.md, sessions 21-22). A harmonic does the same:
    on the independent ``friction_restitution_harmonic`` (mu 0.2, e 0.4, a 0.05) round
    3's friction from restitution + harmonic reached 2.65 floors against 2.62 without
    it, from round 2's friction + restitution 2.20, and friction is taken (session 24).
    Never the armature as the runner-up: the last round searches it again with other
    seeds (:func:`_armature_seeds`), and a second start of it would cost as much as all
    the other additions of the round together.

    The second start runs after the round's other fits, and not at all where the
    armature's first search leads them clearly (:func:`_armature_leads`): the round
    then takes the armature whatever the runner-up's second start gives. On the
    independent ``seed_like_long_steps`` (session 61) the armature led at 1.02 floors,
    the harmonic's first start at 2.35; its second ended at 2.69 for 12-16 s.
    """
    if len(accepted) < 2:
        return None
    others = [(e, f) for e, f in rounds[-1] if e not in (accepted[-1][0], "feedback")]
    runner = _proposal(others, problem, floor, tie)
    if runner is None:
        return None
    return runner[0], dict(runner[1].model.params)


def _round1_choices(rounds) -> dict:
    """The discrete choices (``k``, ``ride_load``: :data:`SPLITS`) of round 1, where each
    effect was fitted alone; empty before round 1."""
    return {
        name: f.model.params[name]
        for e, f in (rounds[0] if rounds else [])
        for name, (owner, _values) in SPLITS.items()
        if e == owner
    }


def _round1_pairs(rounds, problem: Problem):
    """``(singles, pairs)``: round 1's fits of the effects other than the armature
    (``effect -> FitResult``) and every pair of them, each ordered by their round-1
    held-out gaps (the least first)."""
    singles = {e: f for e, f in rounds[0] if e != "feedback"}
    gap1 = {e: heldout_gap(f, problem) for e, f in singles.items()}
    order = sorted(singles, key=lambda e: (gap1[e], e))
    return singles, [(a, b) for i, a in enumerate(order) for b in order[i + 1 :]]


def _fit_pairs(pairs, singles, round1, job, pool, progress) -> list[FitResult]:
    """Joint fits of each pair ``(a, b)`` of round-1 effects added to the baseline, from
    the baseline's and their round-1 values (round 1's discrete choices, ``k``).
    ``job``: ``(problem, baseline fit, fixed, fit settings, seed)``."""
    problem, base_fit, fixed, fit_settings, seed = job
    jobs = []
    for a, b in pairs:
        start = {**base_fit.model.params, **singles[a].model.params, **singles[b].model.params}
        extra = {}
        for e in (a, b):
            (split,) = _discrete_splits(e, fixed, round1)
            extra.update(split)
        name = model_name([*base_fit.model.effects, a, b])
        # a joint fit without the armature: low-Gamma steps first, as in later rounds
        jobs.append(
            (problem, name, {**start, **fixed}, {**fixed, **extra}, None, fit_settings, seed, True)
        )
    return fit_many(jobs, pool, progress) if jobs else []


def _best_pair(pairs, fits, problem: Problem, refused, taken):
    """``(gaps, best, refused_pair)`` of the joint fits ``fits`` of ``pairs``: each one's
    held-out gap (rad); the best ``(gap, (a, b), fit)`` with neither effect inert nor
    refused (``refused(effect, fit)``), None without one; and the model name of a better
    pair with a refused effect whose gap ``taken`` (gap -> bool) would have taken, or
    None."""
    gaps = [heldout_gap(f, problem) for f in fits]
    live = [
        (g, (a, b), f)
        for (a, b), f, g in zip(pairs, fits, gaps, strict=True)
        if not any(is_inert(e, f.model.params) for e in (a, b))
    ]
    allowed = [r for r in live if not (refused is not None and any(refused(e, r[2]) for e in r[1]))]
    refused_pair = None
    if len(allowed) < len(live):
        g0, _pair, f0 = min(live, key=lambda r: (r[0], r[1]))
        if taken(g0) and all(f0 is not r[2] for r in allowed):
            refused_pair = f0.model.name
    best = min(allowed, key=lambda r: (r[0], r[1])) if allowed else None
    return gaps, best, refused_pair


def _pair_for_armature(rounds, accepted, job, pool, progress, floor, settings, refused=None):
    """``(accepted, info, fits)``: the selection with an armature taken alone replaced by
    the pair of other effects that explains the run better, or ``(accepted, None, [])``
    when the selection is not the armature alone.

    Every pair of round 1's other candidates is fitted jointly from their round-1 values
    (round 1's ``k``). The pair with the least held-out gap replaces the armature when it
    beats it by ``margin`` floors and neither of its effects is inert or refused
    (``refused(effect, fit)``: True where :func:`forward_select`'s ``refuted`` refuses
    it); its effects are ordered by their round-1 gaps, the first one's step being its
    round-1 fit. ``job``: ``(problem, baseline fit, fixed, fit settings, seed)``.
    ``info``: ``armature`` and ``pairs`` (held-out gaps in floors) and ``replaced_by``
    (the pair taken, if any);
    ``fits``: the pairs' fits (their cost counts in the refinement's budget).

    Why: forward selection adds one effect at a time, and the armature is the one effect
    whose four parameters can stand in for two others at once. On an independent
    recording with friction (mu 0.2) and a Gamma miscalibration (s 0.93) a heavily
    damped loaded armature (zeta 0.56) came out at 1.13 floors alone, within the floor,
    where friction alone reached 4.9 and the miscalibration 3.8; the pair reaches 0.12
    (docs/diagnosis-log.md, session 23). Only for an armature taken alone: a round
    of fits without the armature costs little beside one with it. Called where the
    armature alone would end the selection: at its stop, and before a strict round
    (:class:`SelectSettings`), which would otherwise go on from the armature (that
    recording: friction beside it, 1.13 -> 0.17 floors, and no check).
    """
    if [e for e, _f in accepted] != ["feedback"] or not rounds:
        return accepted, None, []
    problem = job[0]
    singles, pairs = _round1_pairs(rounds, problem)
    fits = _fit_pairs(pairs, singles, _round1_choices(rounds), job, pool, progress)
    g_arm = heldout_gap(accepted[0][1], problem)
    gaps, best, refused_pair = _best_pair(
        pairs, fits, problem, refused, lambda g: g_arm - g >= settings.margin * floor
    )
    info = {
        "armature": g_arm / floor,
        "pairs": {f"{a}+{b}": g / floor for (a, b), g in zip(pairs, gaps, strict=True)},
    }
    if refused_pair is not None:
        info["refused_pair"] = refused_pair  # would have replaced the armature
    if best is None:
        return accepted, info, fits
    g_pair, (a, b), fit = best
    if g_arm - g_pair < settings.margin * floor:
        return accepted, info, fits
    info["replaced_by"] = [a, b]
    return [(a, singles[a]), (b, fit)], info, fits


def _pair_swap(rounds, current, job, pool, progress, floor, settings, refused=None):
    """``(info, accepted, fits)`` where a selection stops above ``explained_ratio`` floors:
    the pairs of round 1's effects other than the armature that no round fitted, fitted
    jointly from their round-1 values (:func:`_fit_pairs`), and the best of them (neither
    effect inert nor refused) in place of the effects taken when it earns its place
    against ``current`` (:func:`earns_place`: ``margin`` floors and ``min_shrink``).
    ``info``: ``current`` and ``pairs`` (held-out gaps in floors), ``taken`` (the pair,
    its effects ordered by their round-1 gaps, if taken) and ``refused_pair`` (the model)
    when a pair with an effect ``refused`` would have been taken; ``accepted`` the new selection
    (the first effect's step its round-1 fit) or None; ``fits`` the pairs' fits. None
    for all three where the gap is within ``explained_ratio`` or no pair is left.

    Why: forward selection adds one effect at a time, and two effects that offset each
    other where the body first leaves the plate are each worse alone than none: friction
    (mu 0.15) raises the takeoff threshold to Gamma 1.15 and a Gamma miscalibration (s
    1.1) lowers it again to a stated 1.045. On a black-box probe's recording of that pair
    friction alone fitted mu 0 and the miscalibration alone s 1.014; a harmonic was
    taken, then friction, the refinement dropped friction and the run ended unexplained
    at 4.27 floors, while the pair fits it at 0.15 (docs/diagnosis-log.md, session 80).
    """
    problem, base_fit = job[0], job[1]
    g_cur = heldout_gap(current, problem)
    if g_cur <= settings.explained_ratio * floor or not rounds:
        return None, None, []
    done = {f.model.name for tried in rounds for _e, f in tried}
    singles, pairs = _round1_pairs(rounds, problem)
    pairs = [p for p in pairs if model_name([*base_fit.model.effects, *p]) not in done]
    if not pairs:
        return None, None, []
    fits = _fit_pairs(pairs, singles, _round1_choices(rounds), job, pool, progress)

    def earns(g: float) -> bool:
        return earns_place(g, g_cur, floor, settings.margin, settings.min_shrink)

    gaps, best, refused_pair = _best_pair(pairs, fits, problem, refused, earns)
    info = {
        "current": g_cur / floor,
        "pairs": {f"{a}+{b}": g / floor for (a, b), g in zip(pairs, gaps, strict=True)},
    }
    if refused_pair is not None:
        info["refused_pair"] = refused_pair  # would have been taken
    if best is None:
        return info, None, fits
    g_pair, (a, b), fit = best
    if not earns(g_pair):
        return info, None, fits
    info["taken"] = [a, b]
    return info, [(a, singles[a]), (b, fit)], fits


def armature_alternative(accepted, job, pool, progress, work: WorkTally, alone=None):
    """The other reading of an armature taken alone: its other ``ride_load`` choice beside
    a Gamma miscalibration, and whether the data tell the two apart. None unless the
    selection is the armature alone with ``ride_load`` and ``s`` free. ``job``:
    ``(problem, fixed, fit settings, seed)``; ``alone``: round 1's armature fits,
    ``ride_load -> FitResult``. The search starts from the better of round 1's fit with
    the other choice and the selected armature's values (``s`` 1).

    Returns ``{"model", "params", "gap"}`` (the alternative's fit, held-out gap in rad),
    ``told_apart`` (the selected armature's mean fit-step objective on fresh ensembles,
    :func:`bouncelab.gap.fit.fresh_objectives`, lower than the alternative's by more than
    :data:`CHOICE_SIGMAS` standard errors of the difference and more than
    :data:`bouncelab.gap.fit.DATA_RESOLUTION` of the fit steps' mean noise floor, as
    :func:`armature_choice` decides a choice) and ``moved`` (``param -> [selected,
    alternative]`` for the armature's parameters that differ by more than
    :data:`ALTERNATIVE_SHARE`).

    Why: a riding body's load changes the plate's amplitude while it rides, as a Gamma
    factor does, so a loaded armature alone and an impacts-only one with a miscalibrated
    Gamma can give the same flight times. On the independent ``feedback_gamma_scale``
    (impacts-only m/M 0.05, f_ratio 0.6, zeta 0.05, s 0.94) the selection took the loaded
    armature alone at 0.21 floors held out, f_ratio 0.845 and zeta 0.24 (41 % and 385 %
    off, without a warning); the impacts-only one with s free reaches 0.23 floors at s
    0.937, f_ratio 0.527, zeta 0.038. Where the armature alone is the truth
    (``feedback_impacts_only``), the alternative stays behind: 0.25 floors against 0.08
    (docs/diagnosis-log.md, session 61). Only for an armature alone: beside other effects
    the alternative would be a search of six or more parameters.
    """
    if [e for e, _f in accepted] != ["feedback"]:
        return None
    problem, fixed, fit_settings, seed = job
    if "ride_load" in fixed or "s" in fixed:
        return None
    arm = accepted[0][1]
    load = float(arm.model.params["ride_load"])
    others = [v for v in RIDE_LOAD_CHOICES if v != load]
    if not others:
        return None
    other = {**fixed, "ride_load": others[0]}
    start = {**arm.model.params, **other, "s": 1.0}
    first = (alone or {}).get(others[0])
    base = {**first.model.params, **other, "s": 1.0} if first is not None else start
    work.stage = "armature_alternative"
    (alt,) = fit_many(
        [(problem, "feedback+gamma_scale", base, other, None, fit_settings, seed, False, [start])],
        pool,
        progress,
        work,
    )
    moved = {}
    for name in EFFECTS["feedback"]:
        if name == "ride_load":
            continue
        v, w = float(arm.model.params[name]), float(alt.model.params[name])
        if abs(w - v) > ALTERNATIVE_SHARE * abs(v):
            moved[name] = [v, w]
    told_apart = False
    if problem.fit.any():  # the selected armature clearly ahead of the alternative
        ref = fresh_objectives(alt.model, problem, CHOICE_DRAWS)
        told_apart = _fresh_gain(ref, arm.model, problem) is not None
    return {
        "model": alt.model.name,
        "params": {k: float(v) for k, v in alt.model.params.items()},
        "gap": float(heldout_gap(alt, problem)),
        "told_apart": bool(told_apart),
        "moved": moved,
    }


def _rechecked(fit: FitResult, problem: Problem, pool, work: WorkTally | None) -> FitResult:
    """:func:`bouncelab.gap.fit.recheck_best` of ``fit`` (its :data:`RECHECK_TOP` best
    evaluations), the flights of the fresh ensembles added to ``work``."""
    checked = recheck_best(fit, problem, RECHECK_TOP, pool)
    if work is not None:
        work.flights += checked.flights - fit.flights
    return checked


def _box_job(fit: FitResult, problem: Problem, fixed: dict, fit_settings: FitSettings, seed: int):
    """The :func:`fit_model` job that searches ``fit``'s model again in a box around its
    values (:func:`bouncelab.gap.fit.box_around`, :data:`BOX_POPULATION` over
    :data:`BOX_MAXITER` generations), its discrete choices held."""
    choices = {k: v for k, v in fit.model.params.items() if k in CHOICES}
    settings = replace(
        fit_settings,
        box_share=BOX_SHARE,
        popsize=BOX_POPULATION,
        max_population=BOX_POPULATION,
        maxiter=BOX_MAXITER,
        feedback_extra_popsize=0,
        feedback_maxiter_factor=1,
    )
    return (problem, fit.model.name, dict(fit.model.params), {**fixed, **choices}, None,
            settings, seed)  # fmt: skip


def _rival_boxed(tried, job, pool, progress, floor, settings, work: WorkTally, refused=None):
    """``(tried, info)``: ``tried`` (one round's ``(effect, fit)`` after round 1) with the
    best rival of an armature the round proposes searched again in a box around its
    values (:func:`_box_job`), the better of the two searches on the fit steps kept
    (:func:`_best_of`); ``info`` (``rival``, ``model``, ``armature``, ``before``,
    ``after``: held-out gaps in floors) or None where nothing was boxed. ``job``:
    ``(problem, fixed, fit settings, seed)``; ``refused(effect, fit)``: True where the
    takeoffs refuse it.

    Only where the round proposes the armature among the additions not refused; the
    rival is the one of those with the least held-out gap other than the armature, not
    inert. Why: the armature's four parameters get several searches in a round
    (:func:`_armature_again`, :func:`_armature_seeds`), a joint model of friction and
    restitution one, and its truth can be a hole narrow in every parameter (see
    :func:`box_refinement`): on the independent ``friction_restitution_gamma_scale`` the
    last round's armature came out at 1.69 floors (f_ratio on its bound) against the
    miscalibration's 2.18 at mu 0.191, e 0.396, s 0.948 (truth 0.2, 0.4, 0.95); the box
    took that to 1.07 (mu, e, s within 0.2 %) in 770 evaluations, 11 s
    (docs/diagnosis-log.md, session 81).
    """
    problem, fixed, fit_settings, seed = job
    judged = [(e, f) for e, f in tried if refused is None or not refused(e, f)]
    pick = _proposal(judged, problem, floor, settings.tie)
    if pick is None or pick[0] != "feedback":
        return tried, None
    rivals = [
        (heldout_gap(f, problem), e, f)
        for e, f in judged
        if e != "feedback" and not is_inert(e, f.model.params)
    ]
    if not rivals:
        return tried, None
    g_before, effect, rival = min(rivals, key=lambda r: (r[0], r[1]))
    (boxed,) = fit_many([_box_job(rival, problem, fixed, fit_settings, seed)], pool, progress, work)
    best = _best_of(effect, [effect, effect], [rival, boxed])
    info = {
        "rival": effect,
        "model": rival.model.name,
        "armature": heldout_gap(pick[1], problem) / floor,
        "before": g_before / floor,
        "after": heldout_gap(best, problem) / floor,
    }
    return [(e, best if e == effect else f) for e, f in tried], info


def box_refinement(
    fit: FitResult,
    problem: Problem,
    fixed: dict,
    fit_settings: FitSettings,
    seed: int,
    pool=None,
    progress: bool | None = None,
    work: WorkTally | None = None,
) -> tuple[FitResult, dict]:
    """The selected model searched again in a box around ``fit``'s values
    (:func:`bouncelab.gap.fit.box_around`), its best evaluations rechecked on fresh
    ensembles (:func:`bouncelab.gap.fit.recheck_best`); kept when it does better than
    ``fit`` on the same fresh ensembles (:func:`bouncelab.gap.fit.fresh_objectives`).

    Why: a joint model's truth can be a hole narrow in every parameter that the
    full-range searches step over. On the independent ``friction_restitution_harmonic``
    the selection ended at 2.2 floors with mu 0.28 (truth 0.2; the truth scores 0.82 on
    fresh ensembles): one parameter 0.02 off the truth costs more than a floor, yet the
    straight path from the fit to the truth descends all the way. A search of 24 over
    30 generations in the box of :data:`bouncelab.gap.fit.BOX_SHARE` found it (mu, e,
    a, psi within 1.3 %, 0.2 %, 0.4 %, 0.7 %; docs/diagnosis-log.md, session 25).
    Not for models with the armature (:func:`forward_select`): they are refined on the
    expected gap, their misses are flat valleys rather than holes (blind ``seed_like_c``:
    the box's fit scored 1.21 floors on fresh ensembles against the fit's 1.07), and an
    armature evaluation costs more (``ool_vibration``'s box: about 60 s).

    Returns
    -------
    ``(fit, info)``: the fit kept (``fit`` itself when the box did no better) and
    ``info`` (``fresh_before``, ``fresh_after``: mean fresh objectives, rad; ``kept``:
    whether the box's fit was kept; ``n_evals``).
    """
    (boxed,) = fit_many([_box_job(fit, problem, fixed, fit_settings, seed)], pool, progress, work)
    boxed = _rechecked(boxed, problem, pool, work)
    before = float(fresh_objectives(fit.model, problem).mean())
    after = float(fresh_objectives(boxed.model, problem).mean())
    info = {
        "fresh_before": before,
        "fresh_after": after,
        "kept": after < before,
        "n_evals": boxed.n_evals,
    }
    return (boxed if after < before else fit), info


def one_cycle_later(params: dict) -> dict | None:
    """``params`` with its harmonic's phase as the plate shows it one drive cycle later,
    ``psi + 2 pi k`` (mod 2 pi); None without a harmonic or where that is ``psi`` (a
    whole ``k``).

    Why: a flight is timed on the drive's phase, so a half-integer harmonic is the same
    plate one cycle on with ``psi + pi``: flight-time distributions barely tell the two
    apart (only the cycles counted from each step's start do), and a search can settle on
    either.
    """
    if "k" not in params or "psi" not in params:
        return None
    shift = (TWO_PI * float(params["k"])) % TWO_PI
    if min(shift, TWO_PI - shift) < 1e-9:
        return None
    return {**params, "psi": (float(params["psi"]) + shift) % TWO_PI}


def _refined_from(fit: FitResult, start: dict, job, pool, progress, work):
    """``fit``'s model refined locally from ``start`` (no global search, its discrete
    choices held at ``start``'s), and the fresh objectives (rad, one per draw) of ``fit``
    and of the refit on the same :data:`CHOICE_DRAWS` ensembles: ``(refit, before,
    after)``. ``job``: ``(problem, fixed, fit settings, seed)``. The shared step of
    :func:`harmonic_twin` and :func:`harmonic_k_beside`."""
    problem, fixed, fit_settings, seed = job
    choices = {k: v for k, v in start.items() if k in CHOICES}
    local = (problem, fit.model.name, start, {**fixed, **choices}, (), fit_settings, seed)
    (refit,) = fit_many([local], pool, progress, work)
    before = fresh_objectives(fit.model, problem, CHOICE_DRAWS)
    after = fresh_objectives(refit.model, problem, CHOICE_DRAWS)
    return refit, before, after


def harmonic_twin(
    fit: FitResult,
    problem: Problem,
    fixed: dict,
    fit_settings: FitSettings,
    seed: int,
    pool=None,
    progress: bool | None = None,
    work: WorkTally | None = None,
) -> tuple[FitResult, dict | None]:
    """``fit`` against its harmonic's twin (:func:`one_cycle_later`), refined locally
    from the twin's phase (no global search, ``k`` held), the two scored on the same
    :data:`CHOICE_DRAWS` fresh ensembles (:func:`bouncelab.gap.fit.fresh_objectives`).
    The twin replaces ``fit`` where it does better by the rule of an armature's choices
    (more than :data:`CHOICE_SIGMAS` standard errors of the difference and more than
    :data:`bouncelab.gap.fit.DATA_RESOLUTION` of the fit steps' mean noise floor); where
    neither does better so, the two tie and psi is reported poorly identified.

    Why: on an independent probe (k 0.5, a 0.2, psi 2.0; session 82) the selection
    reported psi 5.14, the twin 2.0 + pi, with an interval of 0.015 rad and no warning;
    on 8 fresh ensembles it scores 0.22 floors, the truth 0.08 and the truth's twin 0.20.
    Why the resolution: on three other independent harmonics of half-integer k (a 0.06-0.07)
    the twin of the true phase scored 0.03 floors better or 0.10 worse: the data do not
    tell them apart, and the choice would follow the lottery of the orbits.

    Returns
    -------
    ``(fit, info)``: the fit kept and ``info`` (None where the model has no twin):
    ``psi_before``, ``psi_after`` (the twin's, refined), ``fresh_before``,
    ``fresh_after`` (mean fresh objectives, rad), ``resolution`` (rad), ``kept`` (the
    twin replaced the fit), ``tie`` (neither did better by the rule: psi warned),
    ``n_evals``.
    """
    twin = one_cycle_later(fit.model.params)
    if twin is None:
        return fit, None
    job = (problem, fixed, fit_settings, seed)
    refit, before, after = _refined_from(fit, twin, job, pool, progress, work)
    better = _clearly_lower(before, after, problem) is not None
    worse = _clearly_lower(after, before, problem) is not None
    info = {
        "psi_before": float(fit.model.params["psi"]),
        "psi_after": float(refit.model.params["psi"]),
        "fresh_before": float(before.mean()),
        "fresh_after": float(after.mean()),
        "resolution": float(DATA_RESOLUTION * problem.mean(problem.floor, problem.fit)),
        "kept": better,
        "tie": not (better or worse),
        "n_evals": refit.n_evals,
    }
    return (refit if info["kept"] else fit), info


def harmonic_at_each_k(held: dict, effects, job, pool, progress, work) -> list[FitResult]:
    """The harmonic beside ``effects`` (the others' parameters held at ``held``) at each
    ``k`` of :data:`bouncelab.gap.fit.K_CHOICES`: one fit per ``k``, in that order, with
    only its ``a`` and ``psi`` searched. ``job``: ``(problem, fixed, fit settings, seed)``.

    Why: the harmonic alone (round 1) takes the ``k`` that best mimics the rest of the gap,
    and where friction or restitution is most of it that ``k`` is wrong; a joint fit may
    move ``k`` only among :data:`bouncelab.gap.fit.JOINT_K_CHOICES`, which lack 1.5 and
    2.5 (independent ``friction_harmonic_k1.5``: k 2.5, unexplained at 2.84 floors;
    ``restitution_harmonic_k0.5``: the harmonic never taken; session 82).
    """
    problem, fixed, fit_settings, seed = job
    name = model_name([*(e for e in effects if e != "harmonic"), "harmonic"])
    held = {p: v for p, v in held.items() if p not in EFFECTS["harmonic"]}
    jobs = [
        (problem, name, held, {**held, **fixed, "k": k}, None, fit_settings, seed)
        for k in K_CHOICES
    ]
    return fit_many(jobs, pool, progress, work)


def _least_k(fits: list[FitResult], held: float | None = None) -> float:
    """The ``k`` of the least fit-step objective among :func:`harmonic_at_each_k`'s fits;
    ``held`` (a ``k`` already chosen) where none does strictly better."""
    objectives = np.array([f.objective for f in fits])
    if held is not None and objectives[K_CHOICES.index(held)] <= objectives.min():
        return float(held)
    return float(K_CHOICES[int(np.argmin(objectives))])


def _k_beside_taken(k_alone: float, prev: dict, effects, job, pool, progress, work) -> float:
    """The ``k`` a harmonic added beside ``effects`` is fitted with: the least objective's
    of :func:`harmonic_at_each_k` from ``prev`` (the current fit's values), ``k_alone``
    (round 1's, the harmonic fitted alone) where no other does strictly better."""
    return _least_k(harmonic_at_each_k(prev, effects, job, pool, progress, work), k_alone)


def harmonic_k_beside(
    fit: FitResult,
    problem: Problem,
    fixed: dict,
    fit_settings: FitSettings,
    seed: int,
    pool,
    progress,
    work: WorkTally,
) -> tuple[FitResult, dict | None]:
    """``fit`` against its harmonic at the ``k`` chosen beside its other effects
    (:func:`harmonic_at_each_k` from ``fit``'s values): where another ``k`` does best
    there, the model with it is refined locally (``k`` held) and replaces ``fit`` where
    it does clearly better on the same :data:`CHOICE_DRAWS` fresh ensembles (the rule of
    an armature's choices, :func:`_clearly_lower`).

    Why: a harmonic taken in round 1 keeps the ``k`` it took alone, and the joint fits
    cannot reach 1.5 or 2.5 (:func:`harmonic_at_each_k`); on independent
    ``friction_harmonic_k1.5`` the final friction was right (mu 0.204 for 0.2) beside a
    harmonic of k 2.5.

    Returns
    -------
    ``(fit, info)``: the fit kept and ``info`` (None without a harmonic beside another
    effect, or with ``k`` fixed): ``k_before``, ``k_best`` (the least objective beside
    the others), ``objectives`` (``k`` -> fit-step objective, rad), ``fresh_before``,
    ``fresh_after`` (mean fresh objectives, rad; null where ``k_best`` is ``k_before``),
    ``kept``, ``n_evals``.
    """
    effects = fit.model.effects
    if "harmonic" not in effects or len(effects) < 2 or "k" in fixed:
        return fit, None
    job = (problem, fixed, fit_settings, seed)
    at_k = harmonic_at_each_k(fit.model.params, effects, job, pool, progress, work)
    k_before = float(fit.model.params["k"])
    k_best = _least_k(at_k, k_before)
    info = {
        "k_before": k_before,
        "k_best": k_best,
        "objectives": {str(k): float(f.objective) for k, f in zip(K_CHOICES, at_k, strict=True)},
        "fresh_before": None,
        "fresh_after": None,
        "kept": False,
        "n_evals": sum(f.n_evals for f in at_k),
    }
    if k_best == k_before:
        return fit, info
    start = {**fit.model.params, **at_k[K_CHOICES.index(k_best)].model.params}
    refit, before, after = _refined_from(fit, start, job, pool, progress, work)
    info.update(
        fresh_before=float(before.mean()),
        fresh_after=float(after.mean()),
        kept=_clearly_lower(before, after, problem) is not None,
        n_evals=info["n_evals"] + refit.n_evals,
    )
    return (refit if info["kept"] else fit), info


def _without(
    problem, fit: FitResult, effect: str, fixed, fit_settings, seed, pool, work=None
) -> FitResult:
    """``fit``'s model without the inert ``effect`` (:func:`is_inert`), its other
    parameters refined locally from ``fit``'s values (no global search)."""
    effects = [e for e in fit.model.effects if e != effect]
    own = set(EFFECTS[effect])
    base = {k: v for k, v in fit.model.params.items() if k not in own}
    (refit,) = fit_many(
        [(problem, model_name(effects), base, fixed, (), fit_settings, seed)], pool, False, work
    )
    return refit


def earns_place(g_new: float, g_without: float, floor: float, margin: float, shrink: float) -> bool:
    """The acceptance rule (module docstring): whether an addition's held-out gap ``g_new``
    beats ``g_without`` by ``margin`` noise floors and by ``shrink`` of ``g_without``. All
    in rad. ``g_without`` is the current fit's gap and, from the second effect on, also
    that of the effects before the addition refitted locally from its own point
    (:func:`_without`).

    Why the second: a joint refit also refits the effects taken before, from a new start,
    and its gain can be theirs. On the blind ``g_feedback`` (a riding armature alone) round 1's
    armature stopped at zeta's bound (2.24 floors); friction beside it took 1.64 floors,
    but the armature alone refitted from that joint fit's point takes 0.96 (mu 0.027
    added nothing; docs/diagnosis-log.md, session 47).
    """
    return g_without - g_new >= margin * floor and g_new <= (1.0 - shrink) * g_without


def _phase_pick(tried, problem: Problem, floor: float, limit: float, unsettled, without):
    """In a round the takeoff phases called for (the current model within the floor, its
    phases wrong), the addition the phases accept where the flight times accept none:
    the least held-out gap among the live additions of ``tried`` within ``limit`` floors
    whose model clears ``unsettled`` while the effects before it, refitted from its point
    (``without(effect, fit)``), do not. Returns ``(effect, fit, refit)`` or None.

    Why: such a round is fitted because the phases show the model wrong, but it is
    judged on flight times alone, within the floor, where they cannot tell the models
    apart. On the blind ``g_seed_like`` at fresh diagnosis seeds 18 and 17 round 3 had
    the true set, phases -0.04 and +0.04 rad (at seed 18 every parameter within 11 % of
    the truth), at 1.85 and 1.82 floors against 1.04 and 1.80 for restitution and an
    over-damped armature (phases -0.21 and -0.25 rad): friction failed the margin and
    the run ended unexplained (docs/diagnosis-log.md, session 48).
    """
    live = [(e, f) for e, f in tried if not is_inert(e, f.model.params)]
    live = [(e, f) for e, f in live if heldout_gap(f, problem) <= limit * floor]
    for e, f in sorted(live, key=lambda ef: (heldout_gap(ef[1], problem), ef[0])):
        if unsettled(f.model) is None:
            refit = without(e, f)
            if unsettled(refit.model) is not None:
                return e, f, refit
    return None


def _pooled_cloud(fit: FitResult, earlier: FitResult) -> FitResult:
    """``fit`` with the evaluations of ``earlier``, a fit of the same model and
    parameters on the same problem, added to its cloud (``fit`` itself otherwise).

    Why: the refit of an inert addition (:func:`_without`) is a local search, so its own
    cloud spans only a few Nelder-Mead steps and the intervals drawn from it
    (:func:`bouncelab.gap.fit.bootstrap_params`) would be that narrow: on the blind
    ``restitution_a`` and ``restitution_c`` e's interval no longer held the truth once
    such a refit replaced the round-1 fit (session 25).
    """
    if fit.model.name != earlier.model.name or fit.free != earlier.free:
        return fit
    return replace(
        fit,
        cloud_x=np.vstack([earlier.cloud_x, fit.cloud_x]),
        cloud_gaps=np.vstack([earlier.cloud_gaps, fit.cloud_gaps]),
        n_evals=earlier.n_evals + fit.n_evals,
    )


def forward_select(
    problem: Problem,
    floor: float,
    *,
    baseline: str = "ideal",
    base_params: dict | None = None,
    fixed: dict | None = None,
    candidates=CANDIDATES,
    fit_settings: FitSettings | None = None,
    settings: SelectSettings | None = None,
    seed: int = 0,
    workers: int = 1,
    progress: bool | None = None,
    unsettled=None,
    interval=None,
    harmonic_read: dict | None = None,
    refuted=None,
    random_force=None,
) -> dict:
    """Forward selection from ``baseline`` over ``candidates`` (see the module docstring).

    Parameters
    ----------
    problem : from :func:`bouncelab.gap.fit.make_problem`.
    floor : rad, the held-out noise floor (mean over held-out steps).
    baseline : model the effects are added to; its own parameters are refitted first
        (unless ``fixed``).
    base_params : starting values of parameters (e.g. of the baseline).
    fixed : parameters held at these values in every fit (e.g. ``--fix-calibration``).
    seed : seed of the optimisers.
    workers : processes that evaluate each generation of a fit (:func:`evaluation_pool`).
    unsettled : ``model -> str | None``, what the data shows beyond the flight-time gap
        (the diagnosis passes its takeoff-phase rule); while it names a reason for the
        current model, being within ``explained_ratio`` floors does not stop the
        selection: the next round is tried and judged as any other. Why: a flexible
        effect that stands in for a missing one can bring the flight times within the
        floor while the phases show the model wrong (an armature in place of friction:
        the blind seed-like cases with other diagnosis seeds, phases -0.18 to -0.46 rad;
        docs/diagnosis-log.md, session 21). In that round an addition within the floor
        that sets the phases right is taken even when the flight times gain nothing
        (:func:`_phase_pick`; ``phase_taken`` in the result).
    interval : ``(fit, problem, step index) -> {param: [lo, hi]}``, the intervals the
        diagnosis reports for a step (its ``params_ci``). With two or more effects
        selected, every effect whose strength's interval in the final model, after the
        refinement, reaches its null value widened by the :data:`INERT` tolerance is
        dropped and the final model refitted without it (``weak_dropped`` in the
        result); the first effect too where another stays, the new first step then
        being that effect's round-1 fit alone. Why: on the stored blind outputs of session 26
        this separates the 4 spurious later effects from 51 true ones (a harmonic of a
        0.008 after restitution, a Gamma miscalibration of s 0.99); the round fits'
        intervals are too narrow to do it at selection time (docs/diagnosis-log.md,
        session 26). A spurious effect can sit in the middle of the selection (blind
        ``w_friction_harmonic`` at diagnosis seed 17: harmonic, s 0.995 with interval
        [0.991, 1.003], then friction; session 50), or first: where the data's chatter
        ends early (:func:`bouncelab.gap.fit.chatter_floor_T`) a Gamma miscalibration
        led round 1 of an independent friction and restitution (s 1.18, standing in for
        both) and ended at s 0.9985 with interval [0.9968, 1.0004] beside them (session
        76); on the 32 stored diagnoses of two or more effects no first effect's
        interval reaches its null value.
    harmonic_read : the plate's harmonic read off the takeoff phases where one stands out
        (:func:`bouncelab.gap.takeoff_reading.seen_harmonic`: ``k, a, psi, mu``), or None.
        Every round's fit of a model with the harmonic starts from it where it does
        better than from the current model (:func:`read_starts`).
    refuted : ``(effect, model) -> dict | None``, what the data beyond the flight times
        says against an addition (the diagnosis passes the takeoff phases' verdict on a
        fitted harmonic, :func:`bouncelab.gap.takeoff_reading.harmonic_refuted`). A
        refused addition is neither proposed nor taken for the phases in its round, the
        next best being judged in its place, nor one of a pair that replaces an armature
        taken alone (``takeoff_refused`` in the result: ``round``, 1-based or
        ``"pair_check"``, the effect, the fit's ``model``, ``proposed``: whether it would
        have been proposed, or its pair taken, without the refusal, and the dict). Why: a
        harmonic fitted to the flight times can stand in for the armature while the
        takeoff phases show no such plate (docs/diagnosis.md section 1, "A harmonic the
        takeoffs refuse").
    random_force : ``model -> str | None``, the repeat rule on a model (the diagnosis
        passes :func:`bouncelab.gap.diagnose.random_force_rule`: only where the data's
        flights repeat at no step). After a round has taken an effect, while the held-out
        gap is above ``unexplained_ratio`` floors, a reason it names ends the selection
        (``stop`` ``random_force``): the data scatter where the model's orbits repeat,
        which no further library effect removes, and later rounds fit the scatter
        (independent ``vibration``: a harmonic, then an armature of mass ratio 0.45;
        docs/diagnosis.md section 1, "A random force ends the selection").

    Returns
    -------
    dict with ``baseline`` (FitResult), ``rounds`` (list of lists of
    ``(effect, FitResult)``: every addition tried in each round; the first round is
    fitted even when the baseline is within the floor), ``accepted`` (list of
    ``(effect, FitResult)`` in order; the last one refined when
    :func:`bouncelab.gap.fit.refine_settings` allows), ``final`` (FitResult), ``stop``
    (why it stopped), ``final_problem`` (the problem of the final fit: ``problem`` with
    ``n_draws`` of the refinement, or ``problem`` itself), ``refined`` (the refinement's
    settings, or None), ``went_on`` (the reasons of ``unsettled`` that let the
    selection go on past the floor, one per round), ``not_earned`` and ``phase_taken``
    (additions refused by :func:`earns_place`'s refit, taken for the phases),
    ``takeoff_refused`` (see ``refuted``), ``pair_swap`` (:func:`_pair_swap`'s ``info``
    where a round took nothing above ``explained_ratio`` floors: two effects of round 1
    in place of those taken; None otherwise), ``rival_box`` (``round`` and
    :func:`_rival_boxed`'s ``info`` for each round after the first that proposed the
    armature),
    ``weak_dropped`` (list of ``{"effect", "param", "interval"}``, see ``interval``),
    ``armature_alternative`` (:func:`armature_alternative`, or None) and
    ``work`` (``flights``: what
    every fit simulated, :class:`WorkTally`) and ``fit_log`` (:attr:`WorkTally.fits`:
    each fit's stage, model, evaluations, flights and wall-clock seconds).
    """
    fit_settings = fit_settings or FitSettings()
    settings = settings or SelectSettings()
    fixed = dict(fixed or {})
    base_model = Model.parse(baseline)
    start = {**(base_params or {})}
    work = WorkTally()
    with evaluation_pool(problem, workers) as pool:
        (base_fit,) = fit_many(
            [(problem, base_model.name, start, fixed, None, fit_settings, seed)],
            None,
            progress,
            work,
        )
        current = base_fit
        effects = list(base_model.effects)
        rounds, accepted, went_on, not_earned, phase_taken = [], [], [], [], []
        takeoff_refused, rival_box = [], []

        def refused(effect: str, fit: FitResult, where: int | str = "pair_check") -> bool:
            """Whether ``refuted`` refuses ``effect`` as ``fit`` has it (kept in
            ``takeoff_refused`` with ``where``: the round, or the pair check)."""
            why = refuted(effect, fit.model) if refuted is not None else None
            if why is not None:
                takeoff_refused.append(
                    {"round": where, "effect": effect, "model": fit.model.name, **why}
                )
            return why is not None

        def mark_proposed(where, proposed_model: str | None) -> None:
            """``proposed`` on the refusals of ``where``: whether the refused fit would have
            been taken or proposed without the refusal (the diagnosis warns of those)."""
            for entry in takeoff_refused:
                if entry["round"] == where:
                    entry["proposed"] = entry["model"] == proposed_model

        pair_check, pair_fits = None, []
        pair_swap, swap_tried, swap_fits = None, False, []
        round1_armatures: dict = {}
        pair_job = (problem, base_fit, fixed, fit_settings, seed)

        def check_pairs(accepted):
            """:func:`_pair_for_armature` on ``accepted``, its refusals marked and its fits
            counted: ``(accepted, pair_check, pair_fits)``."""
            accepted, check, fits = _pair_for_armature(
                rounds, accepted, pair_job, pool, progress, floor, settings, refused
            )
            mark_proposed("pair_check", (check or {}).get("refused_pair"))
            work.stage = "pair_check"
            work.add(fits, [problem] * len(fits))
            return accepted, check, fits

        def swap_pair() -> bool:
            """Once, where a round takes nothing: :func:`_pair_swap` on the current
            model; True when a pair replaced the effects taken (``accepted``,
            ``effects`` and ``current`` set to it)."""
            nonlocal pair_swap, swap_tried, swap_fits, accepted, effects, current
            if swap_tried:
                return False
            swap_tried = True
            work.stage = "pair_swap"
            pair_swap, swapped, swap_fits = _pair_swap(
                rounds, current, pair_job, pool, progress, floor, settings,
                lambda e, f: refused(e, f, "pair_swap"),
            )  # fmt: skip
            work.add(swap_fits, [problem] * len(swap_fits))
            mark_proposed("pair_swap", (pair_swap or {}).get("refused_pair"))
            if swapped is None:
                return False
            accepted = swapped
            effects = [*base_model.effects, *(e for e, _f in accepted)]
            current = accepted[-1][1]
            return True

        def shows_more(model) -> bool:
            """Whether the data shows ``model`` wrong beyond the flight times (the reason
            kept in ``went_on``): within the floor, the selection then goes on."""
            reason = unsettled(model) if unsettled is not None else None
            if reason:
                went_on.append(reason)
            return bool(reason)

        stop = "max_effects"
        k_chosen_beside = None  # the k of a harmonic a later round took, chosen beside
        k_retry, k_retried = None, False

        def harmonic_k_round(todo, round1: dict, prev: dict) -> bool:
            """Once, where a round after the first takes nothing with the current model
            above ``explained_ratio`` floors and fitted the harmonic at round 1's ``k``:
            that ``k`` chosen again beside the effects taken (:func:`_k_beside_taken`);
            True where it differs (``k_retry`` set: the next round fits the harmonic
            alone at it)."""
            nonlocal k_retry, k_retried
            if (
                k_retried
                or "harmonic" not in todo
                or "k" not in round1
                or "k" in fixed
                or heldout_gap(current, problem) <= settings.explained_ratio * floor
            ):
                return False
            k_retried = True
            work.stage = "harmonic_k_round"
            k = _k_beside_taken(
                round1["k"], prev, effects, (problem, fixed, fit_settings, seed), pool,
                progress, work,
            )  # fmt: skip
            if k == round1["k"]:
                return False
            k_retry = k
            return True

        while len(accepted) < settings.max_effects:
            g_cur = heldout_gap(current, problem)
            if (
                accepted
                and random_force is not None
                and g_cur > settings.unexplained_ratio * floor
                and random_force(current.model)
            ):
                stop = "random_force"
                break
            within = g_cur <= settings.explained_ratio * floor
            for_phases = bool(within and rounds and shows_more(current.model))
            if for_phases:
                within = False
            # above strict_ratio a run within the floor still tries the next round, but
            # takes an addition only when it removes strict_shrink of the gap
            strict = within and g_cur > settings.strict_ratio * floor
            if strict and rounds and pair_check is None:
                # the armature alone would end the selection here: its pairs come first
                accepted, pair_check, pair_fits = check_pairs(accepted)
                if pair_check is not None and "replaced_by" in pair_check:
                    effects = [*base_model.effects, *pair_check["replaced_by"]]
                    current = accepted[-1][1]
                    continue
            if strict and rounds:
                within = False
            if within and rounds:
                stop = "within_floor"
                break
            todo = [e for e in candidates if e not in effects]
            if k_retry is not None:
                todo = ["harmonic"]
            if strict and rounds:  # a strict round leaves the armature out (SelectSettings)
                todo = [e for e in todo if e != "feedback"]
            if not todo:
                stop = "within_floor" if strict else "no_candidates"
                break
            prev = {**current.model.params, **fixed}
            work.stage = f"round {len(rounds) + 1}"
            owners, jobs = [], []
            round1 = _round1_choices(rounds)
            k_here = None
            if k_retry is not None:  # the harmonic alone, at the k chosen beside (harmonic_k_round)
                k_here = round1["k"] = k_retry
                k_retry = None
            last = len(accepted) == settings.max_effects - 1
            starts = [(eff, prev) for eff in todo]
            second = _runner_up_start(rounds, accepted, problem, floor, settings.tie)
            for eff, start in starts:
                for extra in _discrete_splits(eff, fixed, round1):
                    name = model_name([*effects, eff])
                    owners.append(eff)
                    # later rounds are joint fits: they search the low-Gamma steps first,
                    # but not with an armature (module docstring)
                    cont = bool(rounds) and "feedback" not in Model.parse(name).effects
                    fixed_here = {**fixed, **extra}
                    jobs.append(
                        (problem, name, start, fixed_here, None, fit_settings, seed, cont,
                         read_starts(harmonic_read, name, fixed_here))
                    )  # fmt: skip
            fits = fit_many(jobs, pool, progress, work)
            if not rounds:  # each ride_load's armature alone (armature_alternative)
                round1_armatures = {
                    float(f.model.params["ride_load"]): f
                    for o, f in zip(owners, fits, strict=True)
                    if o == "feedback"
                }
            if second is not None:  # the runner-up's joint fit, also from its own point
                tried = [(eff, _least_objective(eff, owners, fits)) for eff in todo]
                if not _armature_leads(tried, problem, floor, settings):
                    eff, start = second[0], {**prev, **second[1], **fixed}
                    for i in [i for i, o in enumerate(owners) if o == eff]:
                        owners.append(eff)
                        jobs.append((*jobs[i][:2], start, *jobs[i][3:]))
                    fits = fits + fit_many(jobs[len(fits) :], pool, progress, work)
            tried = [(eff, _best_of(eff, owners, fits)) for eff in todo]
            tried = _k_held_again(
                tried, prev, (problem, fixed, fit_settings, seed), pool, progress, work,
                harmonic_read,
            )  # fmt: skip
            # the other ride_load before the extra seeds: where it settles the run the
            # seeds are skipped (_armature_seeds)
            if last and "ride_load" in round1 and "ride_load" not in fixed:
                tried = _armature_again(
                    tried, round1["ride_load"], (problem, prev, fixed, fit_settings, seed),
                    pool, progress, floor, settings, work,
                )  # fmt: skip
            if last and rounds:
                tried = _armature_seeds(
                    tried, jobs[owners.index("feedback")] if "feedback" in owners else None,
                    pool, progress, floor, settings, work,
                )  # fmt: skip
            if rounds:  # an armature's rival gets a search of its own (_rival_boxed)
                tried, boxed = _rival_boxed(
                    tried, (problem, fixed, fit_settings, seed), pool, progress, floor,
                    settings, work,
                    lambda e, f: refuted is not None and refuted(e, f.model) is not None,
                )  # fmt: skip
                if boxed is not None:
                    rival_box.append({"round": len(rounds) + 1, **boxed})
            rounds.append(tried)
            if within and shows_more(current.model):
                within, strict, for_phases = False, False, True
            # the first round is always fitted: its candidates are reported
            if within and not strict:
                stop = "within_floor"
                break
            # a strict round that takes nothing ends as a run within the floor
            no_gain = "within_floor" if strict else "no_improvement"
            for e, f in tried:
                if accepted and is_inert(e, f.model.params):
                    refit = _without(problem, f, e, fixed, fit_settings, seed, pool, work)
                    if heldout_gap(refit, problem) < heldout_gap(current, problem):
                        current = _pooled_cloud(refit, current)  # the effects taken, better fitted
                        accepted[-1] = (accepted[-1][0], current)
            g_cur = heldout_gap(current, problem)
            # round 1's not_first effects are reported, not taken (SelectSettings)
            eligible = [(e, f) for e, f in tried if rounds[1:] or e not in settings.not_first]
            # additions the data beside the flight times refuse are not judged
            judged = [(e, f) for e, f in eligible if not refused(e, f, len(rounds))]
            proposal = _proposal(judged, problem, floor, settings.tie)
            if len(judged) < len(eligible):
                unjudged = _proposal(eligible, problem, floor, settings.tie)
                mark_proposed(len(rounds), unjudged[1].model.name if unjudged else None)
            shrink = settings.strict_shrink if strict else settings.min_shrink
            if proposal is None or not earns_place(
                heldout_gap(proposal[1], problem), g_cur, floor, settings.margin, shrink
            ):
                pick = None
                if for_phases:
                    pick = _phase_pick(
                        judged, problem, floor, settings.explained_ratio, unsettled,
                        lambda e, f: _without(problem, f, e, fixed, fit_settings, seed, pool, work),
                    )  # fmt: skip
                if pick is None and swap_pair():
                    continue
                if pick is None and harmonic_k_round(todo, round1, prev):
                    continue
                if pick is None:
                    stop = no_gain
                    break
                eff, best, alone = pick
                phase_taken.append(
                    {
                        "effect": eff,
                        "floors": heldout_gap(best, problem) / floor,
                        "current": g_cur / floor,
                        "without": heldout_gap(alone, problem) / floor,
                    }
                )
            else:
                eff, best = proposal
                if accepted:
                    g_new = heldout_gap(best, problem)
                    # the gain must be the addition's, not a better fit of the effects before it
                    alone = _without(problem, best, eff, fixed, fit_settings, seed, pool, work)
                    g_alone = heldout_gap(alone, problem)
                    if not earns_place(g_new, g_alone, floor, settings.margin, shrink):
                        # no addition passes; the refit (better than the current fit, as it
                        # failed where the test above passed) is kept
                        not_earned.append(
                            {"effect": eff, "floors": g_new / floor, "without": g_alone / floor}
                        )
                        current = _pooled_cloud(alone, current)
                        accepted[-1] = (accepted[-1][0], current)
                        if swap_pair() or harmonic_k_round(todo, round1, prev):
                            continue
                        stop = no_gain
                        break
            accepted.append((eff, best))
            effects.append(eff)
            current = best
            if eff == "harmonic" and k_here is not None:
                k_chosen_beside = k_here
        if pair_check is None:
            accepted, pair_check, pair_fits = check_pairs(accepted)
            if pair_check is not None and "replaced_by" in pair_check:
                current = accepted[-1][1]
        k_beside = None
        if (
            accepted
            and current.model.params.get("k") != k_chosen_beside
            and heldout_gap(current, problem) > settings.explained_ratio * floor
        ):
            # a harmonic whose k was chosen alone (round 1's, or a pair of its fits), with
            # a gap left for another k to explain (harmonic_k_round's condition)
            work.stage = "harmonic_k_beside"
            current, k_beside = harmonic_k_beside(
                current, problem, fixed, fit_settings, seed, pool, progress, work
            )
            if k_beside is not None and k_beside["kept"]:
                accepted[-1] = (accepted[-1][0], current)
        final_problem, refined = problem, None
        if accepted:
            done = [base_fit] + [f for tried in rounds for _e, f in tried] + pair_fits + swap_fits
            refined = refine_settings(
                problem, current.model.effects, fit_settings, fixed,
                spent_cycles(done, problem),
            )  # fmt: skip
        if refined is not None:
            # the selected model again, from its fitted values, on the expected gap
            final_problem = replace(problem, n_draws=REFINE_DRAWS)
            work.stage = "refinement"
            (current,) = fit_many(
                [(final_problem, current.model.name, dict(current.model.params), fixed,
                  None, refined, seed)],
                pool,
                progress,
                work,
            )  # fmt: skip
            current = _rechecked(current, final_problem, pool, work)
            accepted[-1] = (accepted[-1][0], current)
            if is_inert(accepted[-1][0], current.model.params):
                # the refinement took the last effect to its null value: not an effect
                eff = accepted.pop()[0]
                if accepted:
                    current = _without(
                        final_problem, current, eff, fixed, fit_settings, seed, pool, work
                    )
                    accepted[-1] = (accepted[-1][0], current)
                else:
                    current, final_problem, refined = base_fit, problem, None
        twin = None
        if accepted:
            work.stage = "harmonic_twin"
            current, twin = harmonic_twin(
                current, problem, fixed, fit_settings, seed, pool, progress, work
            )
            if twin is not None and twin["kept"]:
                accepted[-1] = (accepted[-1][0], current)
                final_problem = problem
        box = None
        n_continuous = sum(p.choices is None for p in current.free)
        if (
            accepted
            and n_continuous >= 2
            and "feedback" not in current.model.effects  # refined on the expected gap above
            and heldout_gap(current, final_problem) > settings.box_ratio * floor
        ):
            work.stage = "box"
            current, box = box_refinement(
                current, problem, fixed, fit_settings, seed, pool, progress, work
            )
            if box["kept"]:
                accepted[-1] = (accepted[-1][0], current)
                final_problem = problem
        weak = []
        if interval is not None and len(accepted) >= 2:
            # an effect whose refined interval reaches its null value: not an effect (the
            # first one too, where another stays)
            ci = interval(current, final_problem, len(accepted) - 1)
            for eff, _fit in accepted:
                name, null, tol = INERT[eff]
                if name not in ci:  # held fixed (a calibration): not the data's to judge
                    continue
                lo, hi = ci[name]
                if lo - tol <= null <= hi + tol:
                    weak.append({"effect": eff, "param": name, "interval": [float(lo), float(hi)]})
            if len(weak) == len(accepted):  # the first stays where every one reaches it
                weak = [w for w in weak if w["effect"] != accepted[0][0]]
            work.stage = "weak_dropped"
            for w in weak:
                current = _without(
                    final_problem, current, w["effect"], fixed, fit_settings, seed, pool, work
                )
            if weak:
                dropped = {w["effect"] for w in weak}
                kept = [(e, f) for e, f in accepted if e not in dropped]
                alone = dict(rounds[0]) if rounds else {}
                if accepted[0][0] in dropped and len(kept) > 1 and kept[0][0] in alone:
                    # the new first step's fit held the dropped one: its round-1 fit alone
                    kept[0] = (kept[0][0], alone[kept[0][0]])
                kept[-1] = (kept[-1][0], current)
                accepted = kept
        alternative = armature_alternative(
            accepted, (problem, fixed, fit_settings, seed), pool, progress, work, round1_armatures
        )
    return {
        "baseline": base_fit,
        "rounds": rounds,
        "accepted": accepted,
        "final": current,
        "stop": stop,
        "final_problem": final_problem,
        "refined": refined,
        "went_on": went_on,
        "pair_check": pair_check,
        "pair_swap": pair_swap,
        "rival_box": rival_box,
        "armature_alternative": alternative,
        "harmonic_k_beside": k_beside,
        "harmonic_twin": twin,
        "box": box,
        "weak_dropped": weak,
        "not_earned": not_earned,
        "phase_taken": phase_taken,
        "takeoff_refused": takeoff_refused,
        "work": {"flights": work.flights},
        "fit_log": work.fits,
    }
