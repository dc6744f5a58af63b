"""How much of a blind case's verdict is the diagnosis's own seed?

    python benchmarks/bench_blind_seeds.py --out OUT [--seeds 0 1 2 3 4]
        [--only NAME ...] [--record benchmarks/results/blind_seeds.json] [--workers 2]

``bouncelab diagnose`` is deterministic: its seed (``--seed`` of the blind harness,
default 0) fixes the simulated ensembles' random numbers and the optimisers' draws. The
recording does not change with it. A case whose selection or parameters move with that
seed is decided by a lottery inside the diagnosis, not by the data, and a single-seed
record (``benchmarks/results/blind_validation.json``, seed 0) cannot rank two versions of
the code on it. This benchmark runs the blind harness (:func:`bouncelab.gap.blind.run_blind`)
on the same cases with several diagnosis seeds and records, per case, how often the set
is right, how often the verdict is right (the right set and explained, or flagged for an
out-of-library case), and the largest parameter error of each seed; and, since each
diagnosis retries an unexplained run with the next seed, what each retried seed
concluded and how many verdicts the retry turned right.

Default cases: the combinations, where session 20 saw the seed move the answer. Layout of
``OUT``: one blind output folder per seed (``seed<N>/``), reused when present, so a seed
already run (e.g. ``python -m bouncelab.gap.blind --out OUT/seed1 --seed 1``) is not run
again (its ``diagnose_s`` is then None). Reads the truth only through the blind
harness's scoring, after each diagnosis.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
from pathlib import Path

from bouncelab.gap.blind import DEFAULT_CASES, load_cases, run_blind

#: The combination cases of ``config/blind/cases.yaml`` (default ``--only``).
COMBINATIONS = (
    "seed_like",
    "seed_like_b",
    "seed_like_c",
    "g_seed_like",
    "w_friction_harmonic",
    "friction_restitution",
    "w_friction_restitution",
)


def verdict_right(score: dict) -> bool:
    """The blind harness's score of one case: the right answer as a user reads it (the
    right set and explained; for a null case nothing and explained; for an
    out-of-library case flagged unexplained)."""
    if score["kind"] == "outside":
        return bool(score["unexplained"])
    return bool(score["set_right"]) and not score["unexplained"]


def max_param_error(score: dict) -> float | None:
    """Largest relative error over the fitted true parameters (None: none fitted)."""
    errs = [e for eff in score["param_errors"].values() for e in eff.values()]
    return max(errs) if errs else None


def retried(diagnosis: dict) -> list[dict]:
    """What each seed of a diagnosis's retry concluded (docs/diagnosis.md section 1,
    "Retries of an unexplained run"): ``[{seed, selected, unexplained, final_rel_gap}]``
    (with ``gap_se`` and ``borderline`` where the diagnosis has them, since session 59),
    empty when the first diagnosis was not retried."""
    return [
        {k: d[k] for k in ("seed", "selected", "unexplained", "final_rel_gap", "gap_se",
                           "borderline") if k in d}
        for d in (diagnosis.get("retry") or {}).get("diagnoses", [])
    ]  # fmt: skip


def seeds_record(
    per_seed: dict[int, dict],
    reused: dict[int, set] | None = None,
    retries: dict[int, dict[str, list]] | None = None,
) -> dict:
    """Per case and seed: the selection, ``set_right``, ``verdict_right``,
    ``max_param_error``, ``diagnose_s`` (None where the diagnosis was ``reused``: seed ->
    case names read from an earlier run), ``retry`` (seed -> case name -> :func:`retried`)
    and ``verdict_right_first``, the verdict of the first diagnosis alone (a retried one
    was unexplained: right only for an out-of-library case); per case the counts over
    seeds; overall the counts, and how many runs were retried and how many of those the
    retry turned to a right verdict (``rescued``)."""
    reused = reused or {}
    retries = retries or {}
    names = sorted({n for res in per_seed.values() for n in res["cases"]})
    cases = {}
    for name in names:
        rows = {}
        for seed, res in sorted(per_seed.items()):
            sc = res["cases"].get(name)
            if sc is None:
                continue
            rows[str(seed)] = {
                "selected": sc["selected"],
                "unexplained": sc["unexplained"],
                "set_right": sc["set_right"],
                "verdict_right": verdict_right(sc),
                "max_param_error": max_param_error(sc),
                "param_errors": sc["param_errors"],
                "diagnose_s": None
                if name in reused.get(seed, ())
                else res.get("timings", {}).get(name, {}).get("diagnose_s"),
                "retry": retries.get(seed, {}).get(name, []),
            }
            row = rows[str(seed)]
            row["verdict_right_first"] = (
                sc["kind"] == "outside" if row["retry"] else row["verdict_right"]
            )
        n = len(rows)
        cases[name] = {
            "true": per_seed[next(iter(per_seed))]["cases"][name]["true"],
            "seeds": rows,
            "n_seeds": n,
            "set_right": sum(r["set_right"] for r in rows.values()),
            "verdict_right": sum(r["verdict_right"] for r in rows.values()),
            "params_within_15pc": sum(
                r["max_param_error"] is not None and r["max_param_error"] <= 0.15
                for r in rows.values()
            ),
            "verdict_right_first": sum(r["verdict_right_first"] for r in rows.values()),
            "retried": sum(bool(r["retry"]) for r in rows.values()),
            "rescued": sum(
                r["verdict_right"] and not r["verdict_right_first"] for r in rows.values()
            ),
        }
    total = sum(c["n_seeds"] for c in cases.values())
    return {
        "cases": cases,
        "summary": {
            "seeds": sorted(per_seed),
            "case_runs": total,
            "set_right": sum(c["set_right"] for c in cases.values()),
            "verdict_right": sum(c["verdict_right"] for c in cases.values()),
            "params_within_15pc": sum(c["params_within_15pc"] for c in cases.values()),
            "verdict_right_first": sum(c["verdict_right_first"] for c in cases.values()),
            "retried": sum(c["retried"] for c in cases.values()),
            "rescued": sum(c["rescued"] for c in cases.values()),
        },
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--out", required=True, help="folder of the per-seed blind outputs")
    p.add_argument("--seeds", type=int, nargs="+", default=[0, 1, 2, 3, 4])
    p.add_argument("--only", nargs="+", default=list(COMBINATIONS))
    p.add_argument("--cases", default=str(DEFAULT_CASES))
    p.add_argument("--record", default=None, help="write the record here (JSON)")
    p.add_argument("--note", default="", help="a line saying what code was measured")
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args(argv)

    cases = [c for c in load_cases(args.cases) if c["name"] in set(args.only)]
    missing = set(args.only) - {c["name"] for c in cases}
    if missing:
        print(f"error: {args.cases}: no case named {sorted(missing)}", file=sys.stderr)
        return 2
    per_seed, reused, retries = {}, {}, {}
    for seed in args.seeds:
        print(f"--- diagnosis seed {seed}", flush=True)
        out = Path(args.out) / f"seed{seed}"
        diagnoses = {c["name"]: out / "diagnoses" / f"{c['name']}.json" for c in cases}
        reused[seed] = {name for name, path in diagnoses.items() if path.is_file()}
        per_seed[seed] = run_blind(cases, out, seed=seed, workers=args.workers)
        retries[seed] = {
            name: retried(json.loads(path.read_text()))
            for name, path in diagnoses.items()
            if path.is_file()
        }
    record = seeds_record(per_seed, reused, retries)
    record["machine"] = {"python": platform.python_version(), "processor": platform.machine()}
    record["note"] = args.note
    print(f"{'case':24s} {'set right':>10s} {'verdict':>8s} {'params':>7s}  per seed")
    for name, c in record["cases"].items():
        per = " ".join(
            f"{s}:{'R' if r['verdict_right'] else ('s' if r['set_right'] else '-')}"
            for s, r in c["seeds"].items()
        )
        print(
            f"{name:24s} {c['set_right']:>4d}/{c['n_seeds']:<5d} {c['verdict_right']:>4d}/"
            f"{c['n_seeds']:<3d} {c['params_within_15pc']:>3d}/{c['n_seeds']:<3d}  {per}"
        )
    s = record["summary"]
    print(
        f"all: set right {s['set_right']}/{s['case_runs']}, verdict right "
        f"{s['verdict_right']}/{s['case_runs']}, parameters within 15 % "
        f"{s['params_within_15pc']}/{s['case_runs']}  (R: right and explained, s: right "
        "set but unexplained, -: wrong set)"
    )
    print(
        f"retried {s['retried']}/{s['case_runs']}, the retry turned {s['rescued']} right "
        f"(the first diagnoses alone: {s['verdict_right_first']}/{s['case_runs']} verdicts)"
    )
    if args.record:
        Path(args.record).write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
