"""Do the one-parameter probes warn about the parameters the diagnosis misses?

    python benchmarks/bench_flat_probes.py --diagnoses DIR --work WORK
        [--generator independent|compliant] [--only NAME ...] [--record NAME]
    python benchmarks/bench_flat_probes.py --blind BLIND_OUT [--only NAME ...] [--record NAME]

Since session 75 a step's summary probes each fitted parameter 15 % either side of its
value, the others held (:func:`bouncelab.gap.fit.flat_directions`), and warns where the
fit steps' gap stays within what the data resolve. The probes add warnings and nothing
else (the selection, the intervals and every number of a diagnosis stay as they were), so
this benchmark replays them on stored diagnoses instead of diagnosing again: for each
case it rebuilds the diagnosis's final problem (its seed, ensemble, held-out steps and
the refinement's draws, from ``design``), re-evaluates the final point there and checks
that its objective's noise equals the stored ``objective_noise`` (to 1e-9 rad; a case that
differs is reported, not scored), then probes and scores. (The stored ``gap_fit`` is kept
beside the rebuilt objective for information: after a box refinement or a recheck it is
another ensemble's.)

``--diagnoses DIR`` holds ``bench_independent.py --diagnoses DIR`` outputs (one JSON per
case); the runs are made again under ``WORK`` with the generator's cases (reused when
there). ``--blind BLIND_OUT`` is a blind validation's folder (``runs/``, ``diagnoses/``,
``truth/``). Scores, per scored parameter: its relative error (the generators' scoring),
warned before (the stored warnings) and after (with the new lines). Prints a line per
case (``*``: a parameter newly warned about) and the counts (misses warned, unwarned
values within 15 %); writes ``benchmarks/results/flat_probes_<set>.json`` (or
``--record``). Reads the truth, so it is a benchmark of the diagnosis, never part of it.
About 5-20 s a case on 2 cores.

The warnings from the selection's own fits of more effects
(:func:`bouncelab.gap.diagnose.superset_warnings`, also session 75) are replayed beside
the probes: they need no simulation, only the stored rounds (each fit's model and
held-out gap) and the final model.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from bouncelab.gap.diagnose import superset_warnings
from bouncelab.gap.fit import (
    DATA_RESOLUTION,
    NOISE_SIGMAS,
    FitResult,
    flat_directions,
    flat_warnings,
    free_params,
    objective_noise,
    step_gaps,
    warned_params,
)
from bouncelab.physics.model import Model

RESULTS = Path(__file__).resolve().parent / "results"
MATCH_RAD = 1e-9  # the rebuilt objective's noise against the stored one
GOAL = 0.15
_INTERVAL_LOOSE = re.compile(r"^(\w+)=\S+ is poorly identified: interval")


def rebuilt_final(run_dir: Path, diagnosis: dict) -> tuple[FitResult, object, dict]:
    """The final step's fit as the diagnosis had it (no cloud: the probes need none), its
    problem, and the checks ``{"objective_rad", "stored_rad", "noise_rad",
    "stored_noise_rad", "match"}``."""
    from bench_truth_vs_fit import diagnosis_problem

    design = diagnosis["design"]
    problem = diagnosis_problem(run_dir, design)
    refine, box = design.get("refine"), design.get("box") or {}
    if refine and not box.get("kept"):  # the refined fit's own averaged objective
        problem = replace(problem, n_draws=int(refine["n_draws"]))
    last = diagnosis["steps"][-1]
    model = Model.parse(last["model"], last["params"])
    free = free_params(model.effects, design.get("fixed") or {})
    gaps = step_gaps(problem, model)
    objective = problem.mean(gaps, problem.fit)
    fit = FitResult(
        model, free, objective, gaps, np.empty((0, len(free))), np.empty((0, gaps.size)), 0, 0.0
    )
    noise = objective_noise(fit, problem)
    checks = {
        "objective_rad": objective,
        "stored_rad": float(last["gap_fit"]),
        "noise_rad": noise,
        "stored_noise_rad": float(last["objective_noise"]),
    }
    checks["match"] = bool(abs(noise - checks["stored_noise_rad"]) <= MATCH_RAD)
    return fit, problem, checks


def probe_lines(run_dir: Path, diagnosis: dict) -> tuple[list[str], dict]:
    """The lines the probes add to the final step's warnings (as ``_fit_summary`` makes
    them: not for a parameter its interval already calls loose) and the checks."""
    fit, problem, checks = rebuilt_final(run_dir, diagnosis)
    unit = problem.mean(problem.floor, problem.fit)
    tolerance = max(NOISE_SIGMAS * checks["noise_rad"], DATA_RESOLUTION * unit)
    loose = {
        m.group(1)
        for line in diagnosis["steps"][-1]["warnings"]
        if (m := _INTERVAL_LOOSE.match(line))
    }
    flat = {k: v for k, v in flat_directions(fit, problem, tolerance).items() if k not in loose}
    lines = flat_warnings(fit, flat, unit, tolerance)
    return lines + stored_superset_lines(diagnosis, lines), checks


def stored_superset_lines(diagnosis: dict, lines: list[str]) -> list[str]:
    """:func:`superset_warnings` on a stored diagnosis's rounds (``lines``: those the
    probes add; the parameters warned already are left out, as the diagnosis does)."""
    floor = float(diagnosis["noise_floor"])
    final = diagnosis["final_model"]
    tried = [
        (Model.parse(c["model"], c["params"]), float(c["gap"]))
        for tried in diagnosis.get("rounds") or []
        for c in tried
    ]
    warned = warned_params(diagnosis["steps"][-1]["warnings"] + lines)
    margin = float(diagnosis["design"]["stop_rule"]["margin_floors"])
    return superset_warnings(
        Model.parse(final["model"], final["params"]),
        float(diagnosis["final_gap"]),
        tried,
        floor,
        margin,
        warned,
    )


def with_lines(diagnosis: dict, lines: list[str]) -> dict:
    """``diagnosis`` with ``lines`` added to its last step's warnings (a copy)."""
    out = json.loads(json.dumps(diagnosis))
    out["steps"][-1]["warnings"] = [*out["steps"][-1]["warnings"], *lines]
    return out


def generated_cases(args) -> list[tuple[str, Path, dict, callable]]:
    """``(name, run_dir, diagnosis, score)`` of ``--diagnoses``: ``score(diagnosis)`` is
    ``{param: (relative error, warned)}`` by ``bench_independent.py``'s scoring."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from bench_independent import GENERATORS, score

    cases_of, make, _stem = GENERATORS[args.generator]
    out = []
    for path in sorted(Path(args.diagnoses).glob("*.json")):
        name = path.stem
        if (args.only and name not in args.only) or name not in cases_of:
            continue
        diagnosis = json.loads(path.read_text())
        if not diagnosis.get("steps"):
            continue
        run_dir = Path(args.work) / name
        if not (run_dir / "run.yaml").is_file():
            make(run_dir, **cases_of[name])
        truth = json.loads(run_dir.with_name(name + ".truth.json").read_text())

        def scored(d, truth=truth):
            s = score(truth, d)
            return {k: (v, s["param_warned"][k]) for k, v in s["param_rel_error"].items()}

        out.append((name, run_dir, diagnosis, scored))
    return out


def blind_cases(args) -> list[tuple[str, Path, dict, callable]]:
    """The same for ``--blind``: :func:`bouncelab.gap.blind.score_case`'s errors."""
    from bouncelab.gap.blind import score_case
    from bouncelab.rig import read_truth

    root = Path(args.blind)
    out = []
    for path in sorted((root / "diagnoses").glob("*.json")):
        name = path.stem
        if args.only and name not in args.only:
            continue
        diagnosis = json.loads(path.read_text())
        if not diagnosis.get("steps"):
            continue
        _flights, truth = read_truth(root / "truth" / f"{name}.parquet")

        def scored(d, truth=truth):
            s = score_case(d, truth)
            return {
                k: (v, s["param_warned"][eff][k])
                for eff, errs in s["param_errors"].items()
                for k, v in errs.items()
            }

        out.append((name, root / "runs" / name, diagnosis, scored))
    return out


def counts(rows: list[tuple[float, bool]]) -> dict:
    """Misses (over 15 %) and how many are warned; unwarned values and how many are right."""
    return {
        "n_params": len(rows),
        "n_outside_goal": sum(e > GOAL for e, _ in rows),
        "n_outside_goal_warned": sum(e > GOAL and w for e, w in rows),
        "n_unwarned": sum(not w for _, w in rows),
        "n_unwarned_within_goal": sum(e <= GOAL and not w for e, w in rows),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    src = p.add_mutually_exclusive_group(required=True)
    src.add_argument("--diagnoses", help="bench_independent.py --diagnoses folder")
    src.add_argument("--blind", help="a blind validation's output folder")
    p.add_argument("--work", default=None, help="runs of --diagnoses are made here")
    p.add_argument("--generator", default="independent", help="independent or compliant")
    p.add_argument("--only", nargs="*", default=None)
    p.add_argument("--record", default=None, help="file name under benchmarks/results")
    args = p.parse_args(argv)
    if args.diagnoses and not args.work:
        p.error("--diagnoses needs --work")
    cases = blind_cases(args) if args.blind else generated_cases(args)
    label = "blind" if args.blind else args.generator
    record = {"cases": {}, "mismatched": []}
    before, after = [], []
    for name, run_dir, diagnosis, scored in cases:
        t0 = time.perf_counter()
        lines, checks = probe_lines(run_dir, diagnosis)
        seconds = time.perf_counter() - t0
        if not checks["match"]:
            record["mismatched"].append({"case": name, **checks})
            print(f"{name:34s} not rebuilt: {checks}", flush=True)
            continue
        old, new = scored(diagnosis), scored(with_lines(diagnosis, lines))
        record["cases"][name] = {
            "selected": diagnosis["selected"],
            "lines": lines,
            "params": {
                k: {"error": e, "warned_before": old[k][1], "warned_after": w}
                for k, (e, w) in new.items()
            },  # fmt: skip
            "seconds": seconds,
        }
        before += list(old.values())
        after += list(new.values())
        changed = [k for k in new if new[k][1] != old[k][1]]
        errors = " ".join(
            f"{k} {100 * e:.0f}%{'*' if k in changed else ''}" for k, (e, _w) in new.items()
        )
        print(
            f"{name:34s} {'+'.join(diagnosis['selected']) or '-':36s} {errors}"
            f"  ({len(lines)} lines, {seconds:.0f} s)",
            flush=True,
        )
    record["summary"] = {"before": counts(before), "after": counts(after)}
    out = RESULTS / (args.record or f"flat_probes_{label}.json")
    out.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    print(json.dumps(record["summary"]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
