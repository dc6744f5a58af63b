"""How the refinement's best model moves over its generations: what a shorter one would give.

    python benchmarks/bench_refine_progress.py --out OUT --case seed_like --seed 20
        [--case ... --seed ...] [--record benchmarks/results/refine_progress.json]

The final model of a diagnosis with the armature is refitted on the expected gap
(:func:`bouncelab.gap.fit.refine_settings`), and that refit is over half of such a
diagnosis's flights (docs/diagnosis-log.md, session 64). Session 65 found that the
refinement is what settles the takeoff phases, so the verdict before it cannot stand in
for it. This benchmark asks how many of the refinement's generations the verdict and the
parameters need.

Per blind case and diagnosis seed it runs the diagnosis once (``--retries 0``), keeps
the refinement's fit (every evaluation, in the order of the generations), and at
generations 0, 5, 10, ... reads the best evaluation so far by the refinement's own
objective. For that point it gives the held-out gap in noise floors, the median takeoff-phase
offset and whether the phase rule flags it (:func:`bouncelab.gap.diagnose.phase_shift_reason`),
and its parameter errors against the rig's truth. The truth is read only after the
diagnosis, here in the benchmark.

What it leaves out: the final step's recheck on fresh ensembles and the drift rule, so
the last row is close to the diagnosis's verdict but need not be equal to it (the
diagnosis's own is recorded beside it).
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from bouncelab.gap.blind import (
    DEFAULT_CASES,
    load_cases,
    make_case,
    relative_errors,
    true_effects,
)

#: Generations at which the best so far is read (the last generation is always read too).
CHECKPOINTS = (0, 5, 10, 15, 20, 25, 30, 35)


def capture_refinement():
    """Wrap :func:`bouncelab.gap.select.fit_many` so that the refinement's
    ``(problem, FitResult)`` is kept; returns the list it is appended to."""
    import bouncelab.gap.select as select

    kept: list = []
    original = select.fit_many

    def fit_many(jobs, pool=None, progress=None, work=None):
        results = original(jobs, pool, progress, work)
        if work is not None and work.stage == "refinement":
            kept.append((jobs[0][0], results[0]))
        return results

    select.fit_many = fit_many
    return kept


def best_so_far(problem, fit, n_evals: int) -> int:
    """Index of the best of the first ``n_evals`` evaluations by the fit's objective (the
    weighted mean capped gap over the fit steps, as :func:`bouncelab.gap.fit.recheck_best`)."""
    w = problem.weights * problem.fit
    values = problem.clipped(fit.cloud_gaps[:n_evals]) @ w / w.sum()
    return int(np.argmin(values))


def progress_rows(problem, fit, maxiter: int, truth: dict, limit: float) -> list[dict]:
    """One row per checkpoint generation: the best point so far, its held-out gap in
    floors (the verdict's mean of capped gap over floor), phases and parameter errors."""
    from bouncelab.gap.diagnose import (
        _features,
        phase_shift_reason,
        sharp_phase_offset,
        verdict_margin,
    )
    from bouncelab.gap.fit import decode
    from bouncelab.physics import Model

    population = fit.n_evals // (maxiter + 1)
    rows = []
    for g in sorted({*(c for c in CHECKPOINTS if c < maxiter), maxiter}):
        n = min(fit.n_evals, (g + 1) * population)
        i = best_so_far(problem, fit, n)
        params = {**fit.model.params, **decode(fit.free, fit.cloud_x[i])}
        model = Model.parse(fit.model.name, params)
        phase = sharp_phase_offset(problem, _features(problem, model))
        reason = phase_shift_reason(phase)
        errors = {
            f"{eff}.{k}": v
            for eff, true in truth.items()
            for k, v in relative_errors(true, params).items()
        }
        rel = verdict_margin(problem, fit.cloud_gaps[i], limit)["rel_gap"]
        rows.append(
            {
                "generation": g,
                "n_evals": n,
                "heldout_floors": rel,
                "phase_median_rad": phase.get("median"),
                "phase_flagged": reason is not None,
                "unexplained": bool(rel > limit or reason is not None),
                "param_errors": errors,
                "max_param_error": max(errors.values()) if errors else None,
            }
        )
    return rows


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True, help="folder of the blind runs")
    p.add_argument("--case", action="append", required=True, help="a blind case's name")
    p.add_argument("--seed", action="append", type=int, required=True, help="one per --case")
    p.add_argument("--cases", default=str(DEFAULT_CASES))
    p.add_argument("--record", default=None, help="write the record here (JSON)")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)
    if len(args.case) != len(args.seed):
        print("error: give one --seed per --case", file=sys.stderr)
        return 2
    known = {c["name"]: c for c in load_cases(args.cases)}
    missing = [n for n in args.case if n not in known]
    if missing:
        print(f"error: {args.cases}: no case named {missing}", file=sys.stderr)
        return 2

    from bouncelab.gap.diagnose import diagnose_run
    from bouncelab.rig import read_truth

    kept = capture_refinement()
    out = Path(args.out)
    record = {"cases": {}}
    for name, seed in zip(args.case, args.seed, strict=True):
        run_dir, truth_path = make_case(known[name], out)
        kept.clear()
        t0 = time.perf_counter()
        result = diagnose_run(run_dir, seed=seed, retries=0, workers=args.workers, progress=False)
        seconds = time.perf_counter() - t0
        _flights, truth_params = read_truth(truth_path)  # only now, after the diagnosis
        truth, _outside = true_effects(truth_params)
        key = f"{name} seed {seed}"
        entry = {
            "selected": result["selected"],
            "unexplained": result["unexplained"],
            "final_rel_gap": result["final_rel_gap"],
            "unexplained_reasons": result["unexplained_reasons"],
            "refine": result["design"]["refine"],
            "flights": result["design"]["work"]["flights"],
            "diagnose_s": round(seconds, 1),
        }
        if kept and result["design"]["refine"]:
            problem, fit = kept[-1]
            limit = float(result["verdict_margin"]["limit"])
            maxiter = int(result["design"]["refine"]["maxiter"])
            entry["refinement_flights"] = int(fit.flights)
            entry["generations"] = progress_rows(problem, fit, maxiter, truth, limit)
        record["cases"][key] = entry
        print(f"{key}: {entry['selected']}, unexplained {entry['unexplained']} ({seconds:.0f} s)")
        for row in entry.get("generations", []):
            phase = row["phase_median_rad"]
            flagged = " (flagged)" if row["phase_flagged"] else ""
            print(
                f"  gen {row['generation']:3d}: {row['heldout_floors']:.2f} floors, phases "
                f"{phase if phase is None else round(phase, 3)} rad{flagged}, "
                f"max param error {row['max_param_error'] or 0:.3f}"
            )
    record["machine"] = {"python": platform.python_version(), "processor": platform.machine()}
    if args.record:
        Path(args.record).write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
