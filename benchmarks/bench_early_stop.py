"""What an exact early stop of losing trials would save the diagnosis (a diagnostic).

The idea measured: in the fits' differential evolution (``updating="deferred"``), a trial
replaces its parent only if its objective is not larger than the parent's. The objective
is a weighted mean of non-negative per-step gaps, and the protocol's steps are simulated
in recording order, so the gaps of the steps already simulated give a lower bound of the
objective; once that bound exceeds the parent's objective the trial has lost, and its
remaining steps could be skipped with no change to the search (only the cloud of
evaluations that intervals are drawn from would lose the stopped trials).

Before building a resumable simulation for that, this script measures the gain. It runs
one diagnosis in one process (``workers=1``) with two hooks:

- every simulation records its flights per protocol entry and its per-step gaps;
- the global search runs scipy's solver itself, so that each trial's parent objective is
  known (the same search: the diagnosis's total flights come out as without the hook).

Then, for every trial of a later generation, it finds the first check (after every
protocol entry, or every 5, 10, 20 % of them) where the gaps of the steps complete by
then (a step's entry and the next one simulated) exceed the parent's objective, and
counts the flights after it as saved. Flights per entry are the rows the fits read,
scaled to the evaluation's kernel count.

Also measured, for comparison: a racing rule, which is not exact. It stops a trial once
it trails its parent over the steps simulated so far by more than a share (5, 10, 20 %)
of the parent's objective. That saves more but stops some trials that would have won,
so the searches change; the record counts those winners.

``--race LEAD`` plays that rule inside the searches instead: a trial it stops loses to
its parent and leaves the fit's cloud, as in a simulation that had stopped (every trial
is still simulated whole, so this judges the rule's answers, not its time). It writes
the diagnosis's answer and the share of flights the rule would have saved to
``early_stop_<run>_race<LEAD>.json``: compare the answer with the recorded one, over
fresh seeds, before building a resumable simulation.

Measures, prints and writes ``benchmarks/results/early_stop_<case>.json``.
Run: ``python benchmarks/bench_early_stop.py [--case seed_like_long_steps | --run DIR]
[--seed 0] [--race LEAD]`` (cases of ``bench_independent.py``, made in a temporary
folder); about 3 minutes a run.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
from pathlib import Path

import numpy as np

# scipy's own solver class (what ``differential_evolution`` runs), to read each trial's
# parent objective; private, but this is a measurement, not the product
from scipy.optimize._differentialevolution import DifferentialEvolutionSolver

import bouncelab.gap.fit as fit
from bouncelab.gap.diagnose import diagnose_run

COUNTED_STEP_GAPS = fit.counted_step_gaps
PROTOCOL_FLIGHT_TIMES = fit.protocol_flight_times

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_independent import CASES  # noqa: E402
from independent_rig import make_case  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
CHECK_SHARES = (0.0, 0.05, 0.1, 0.2)  # 0: a check after every protocol entry
RACING_LEADS = (0.05, 0.1, 0.2)  # of the parent's objective


class Recorder:
    """Hooks on :mod:`bouncelab.gap.fit` that record every simulation and DE generation."""

    def __init__(self, race_lead: float | None = None):
        self.race_lead = race_lead  # play the racing rule in the searches (see _race)
        self.race_saved = 0.0  # flights the stopped trials would not have simulated
        self.race_stopped = 0  # evaluations the rule stopped
        self._gaps_of = {}  # (problem key, objective) -> per-step gaps: the parents
        self.sims = []  # (problem key, flights per protocol entry, kernel flights, gaps, draws)
        self._per_entry = np.zeros(0)
        self.problems = {}  # problem key -> what the partial objective needs
        self.generations = []  # (first sim index, end sim index, parent objectives, values)

    def protocol_flight_times(self, *args, **kwargs):
        """:func:`bouncelab.physics.simulate.protocol_flight_times`, keeping the flights
        per protocol entry of its simulation."""
        sim = PROTOCOL_FLIGHT_TIMES(*args, **kwargs)
        self._per_entry = np.bincount(sim["step"], minlength=len(args[1])).astype(float)
        return sim

    def counted_step_gaps(self, problem, model, buffer=None, shift=0.0):
        """:func:`bouncelab.gap.fit.counted_step_gaps`, recording each evaluation."""
        gaps, flights = COUNTED_STEP_GAPS(problem, model, buffer, shift)
        key = id(problem)
        if key not in self.problems:
            proto = problem.protocol
            entry = {s: j for j, s in enumerate(proto["step"].to_numpy())}  # last entry
            self.problems[key] = {
                "n_entries": len(proto),
                "entry": np.array([entry[s] for s in problem.steps["step"].to_numpy()]),
                "fit": problem.fit.copy(),
                "weights": problem.weights.copy(),
                "cap": fit.GAP_CAP * problem.floor,
            }
        # with n_draws > 1 the entries are the last draw's (such evaluations are skipped)
        self.sims.append((key, self._per_entry, flights, gaps, problem.n_draws))
        if problem.n_draws == 1:
            self._gaps_of.setdefault((key, objective(self.problems[key], gaps)), gaps)
        return gaps, flights

    def global_search(self, ev, lift, sub, z0, popsize, maxiter, settings, seed):
        """:func:`bouncelab.gap.fit._global_search` with scipy's solver held, so that the
        population map sees the parents' objectives."""
        held = {}

        def evaluate(z):  # one trial's objective (the module's objective() is another)
            return ev(lift(z))

        def population_map(_func, zs):
            energies = held["solver"].population_energies
            parents = None if np.all(np.isinf(energies)) else energies.copy()
            start = len(self.sims)
            values = ev.many([lift(z) for z in zs])
            if self.race_lead is not None and parents is not None:
                values = self._race(ev, start, parents, values)
            self.generations.append((start, len(self.sims), parents, np.array(values)))
            return values

        with DifferentialEvolutionSolver(
            evaluate,
            [(p.lower, p.upper) for p in sub],
            rng=seed,  # as differential_evolution(seed=...) passes it
            popsize=fit.population_per_param(popsize, settings.max_population, len(sub)),
            maxiter=maxiter,
            tol=settings.tol,
            polish=False,
            init="latinhypercube",
            x0=z0,
            integrality=[p.choices is not None for p in sub],
            updating="deferred",
            workers=population_map,
        ) as solver:
            held["solver"] = solver
            return solver.solve().x

    def _race(self, ev, start: int, parents, values) -> list[float]:
        """Play the racing rule on one generation, as a search that stopped trials would
        run: each new evaluation the rule stops (:func:`stop_point`, a check after every
        entry) loses to its parent (value inf) and leaves the fit's cloud and cache, as a
        stopped simulation would have no whole gaps; its flights after the stop are
        counted in ``race_saved``. Every trial is still simulated whole here: this judges
        the rule's answers, not its time."""
        values = np.array(values, dtype=float)
        new = self.sims[start:]
        first = len(ev.gaps) - len(new)  # the evaluator recorded them in the same order
        stopped = []
        for i, (key, per_entry, flights, gaps, draws) in enumerate(new):
            if draws != 1:
                continue
            problem = self.problems[key]
            slots = np.flatnonzero(values == objective(problem, gaps))
            if len(slots) == 0:
                continue
            bound = float(parents[slots].max())
            parent = self._gaps_of.get((key, bound))
            saved, _ = stop_point(
                problem, gaps, per_entry, flights, bound, 1, 1, parent, self.race_lead
            )
            if saved > 0:
                self.race_saved += saved
                self.race_stopped += 1
                values[slots] = np.inf
                stopped.append(first + i)
        for j in reversed(stopped):
            ev._cache.pop(tuple(sorted(fit.decode(ev.free, ev.xs[j]).items())), None)
            del ev.xs[j]
            del ev.gaps[j]
        return list(values)


def step_parts(problem: dict, gaps) -> np.ndarray:
    """Each step's part of the objective (the fits' weighted mean of clipped gaps over
    the fit steps; 0 on held-out steps), shape (G,): they add up to the objective."""
    fit_steps = problem["fit"]
    w = problem["weights"]
    return np.where(fit_steps, w * np.minimum(gaps, problem["cap"]), 0.0) / w[fit_steps].sum()


def objective(problem: dict, gaps) -> float:
    """The fits' objective of per-step ``gaps``, computed as the fits do (the same bits)."""
    w = problem["weights"][problem["fit"]]
    return float(np.sum(w * np.minimum(gaps, problem["cap"])[problem["fit"]]) / np.sum(w))


def stop_point(
    problem: dict, gaps, per_entry, flights, bound, every, margin=1, parent=None, lead=0.0
):
    """``(flights saved, share of the protocol run)`` when a trial of per-step ``gaps``
    stops at the first check (every ``every`` entries) where the steps complete by then
    exceed ``bound`` (exact: the trial has lost); a step is complete once ``margin`` more
    entries have run. With ``parent`` (its per-step gaps) and ``lead`` > 0, also where
    the trial trails the parent over those steps by more than ``lead * bound`` (a racing
    rule, not exact: it can stop a trial that would have won)."""
    part = step_parts(problem, gaps)
    ahead = step_parts(problem, parent) if parent is not None and lead > 0 else None
    cost = np.cumsum(per_entry / max(per_entry.sum(), 1.0) * flights)
    n = problem["n_entries"]
    for c in [*range(every, n, every), n]:
        done = problem["entry"] + margin < c
        mine = part[done].sum()
        if mine > bound or (ahead is not None and mine > ahead[done].sum() + lead * bound):
            return flights - cost[c - 1], c / n
    return 0.0, 1.0


def savings(rec: Recorder, share: float, margin: int = 1, lead: float = 0.0) -> dict:
    """Flights an early stop saves over the recorded diagnosis, checking every ``share``
    of the protocol's entries (0: after each); with ``lead`` > 0 the racing rule of
    :func:`stop_point` too, and the winners it stops are counted."""
    total = sum(s[2] for s in rec.sims)
    # each objective value's first evaluation: the parents' per-step gaps
    gaps_of = {}
    for key, _, _, gaps, draws in rec.sims:
        if draws == 1:
            gaps_of.setdefault((key, objective(rec.problems[key], gaps)), gaps)
    de = saved = 0.0
    trials = stopped = winners = winners_stopped = 0
    where = []
    for start, end, parents, values in rec.generations:
        for key, per_entry, flights, gaps, draws in rec.sims[start:end]:
            de += flights
            if parents is None or draws != 1:  # the first population has no parents
                continue
            problem = rec.problems[key]
            value = objective(problem, gaps)
            mine = np.flatnonzero(values == value)  # the population slots it was tried in
            if len(mine) == 0:
                continue
            trials += 1
            bound = float(parents[mine].max())
            won = value <= bound
            winners += won
            every = max(1, round(share * problem["n_entries"]))
            parent = gaps_of.get((key, bound))
            s, at = stop_point(
                problem, gaps, per_entry, flights, bound, every, margin, parent, lead
            )
            if s > 0:
                stopped += 1
                winners_stopped += won
                where.append(at)
            saved += s
    return {
        "check_every_share": share,
        "step_margin_entries": margin,
        "racing_lead": lead,
        "trials": trials,
        "winners": winners,
        "trials_stopped": stopped,
        "winners_stopped": winners_stopped,
        "median_stop_share": float(np.median(where)) if where else None,
        "de_share_of_flights": float(de / total),
        "saved_share_of_flights": float(saved / total),
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--case", default="seed_like_long_steps", choices=sorted(CASES))
    p.add_argument("--run", default=None, help="a run folder to diagnose instead of a case")
    p.add_argument("--seed", type=int, default=0, help="the diagnosis's seed")
    p.add_argument("--race", type=float, default=None, help="play the racing rule with this lead")
    args = p.parse_args()
    rec = Recorder(race_lead=args.race)
    fit.counted_step_gaps = rec.counted_step_gaps
    fit.protocol_flight_times = rec.protocol_flight_times
    fit._global_search = rec.global_search
    name = args.case if args.run is None else Path(args.run).name
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(args.run) if args.run is not None else Path(tmp) / args.case
        if args.run is None:
            make_case(run_dir, **CASES[args.case])
        diag = diagnose_run(run_dir, workers=1, seed=args.seed, progress=False)
    if args.race is not None:
        race_out(diag, rec, name, args)
        return
    out = {
        "case": name,
        "diagnosis_seed": args.seed,
        "selected": diag["selected"],
        "unexplained": diag["unexplained"],
        "flights": diag["design"]["work"]["flights"],
        "savings": [savings(rec, s) for s in CHECK_SHARES] + [savings(rec, 0.0, margin=0)],
        # a racing rule, not exact: what it saves and which winners it stops
        "racing": [savings(rec, 0.0, lead=lead) for lead in RACING_LEADS],
    }
    # where the flights are along the protocol (the main problem, every simulation)
    main_key = max(rec.problems, key=lambda k: rec.problems[k]["n_entries"])
    per = sum(s[1] for s in rec.sims if s[0] == main_key)
    cum = np.cumsum(per) / per.sum()
    out["protocol_share_at_flights_share"] = {
        f"{q:.2f}": float(np.searchsorted(cum, q) / len(per)) for q in (0.25, 0.5, 0.75, 0.9)
    }
    print(json.dumps(out, indent=1))
    path = ROOT / "benchmarks" / "results" / f"early_stop_{name}.json"
    path.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")


def race_out(diag: dict, rec: Recorder, name: str, args) -> None:
    """Print and write the answer of a diagnosis run with the racing rule played."""
    total = sum(s[2] for s in rec.sims)
    out = {
        "case": name,
        "diagnosis_seed": args.seed,
        "racing_lead": args.race,
        "selected": diag["selected"],
        "unexplained": diag["unexplained"],
        "final_model": diag["final_model"],
        "final_rel_gap": diag["final_rel_gap"],
        "flights_simulated": total,
        "flights_saved_share": float(rec.race_saved / total),
    }
    print(json.dumps(out, indent=1))
    path = ROOT / "benchmarks" / "results" / f"early_stop_{name}_race{args.race:g}.json"
    path.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
