"""Speed of the whole gap diagnosis of one sweep run (issue 6, Speed).

Goal: at most 2 minutes per sweep run on 2 cores for the whole diagnosis (extraction of
the flights, every candidate fit, forward selection, intervals, regions). Measured on the
largest shipped run, ``raw/sweep_g0-8`` (Gamma 0 to 8 in steps of 0.05 with the seed's
data gaps, 50 cycles per step at 25 Hz; friction, restitution and shaker feedback), so
selection goes through several rounds.

Measures, prints and writes ``benchmarks/results/diagnose.json``.
Run: ``python benchmarks/bench_diagnose.py [--run raw/sweep_g0-8] [--workers 2]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import time
from pathlib import Path

from bouncelab.gap.diagnose import diagnose_run

GOAL_S = 120.0
ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--run", default=str(ROOT / "raw" / "sweep_g0-8"))
    p.add_argument("--workers", type=int, default=2)
    args = p.parse_args()
    t0 = time.perf_counter()
    result = diagnose_run(args.run, workers=args.workers, progress=False)
    total_s = time.perf_counter() - t0
    n_evals = sum(c["n_evals"] for c in result["candidates"]) + sum(
        s["n_evals"] for s in result["steps"]
    )
    out = {
        "goal_s": GOAL_S,
        "run": result["run"],
        "diagnose_s": round(total_s, 2),
        "meets_goal": total_s <= GOAL_S,
        "workers": args.workers,
        "n_steps": result["design"]["n_steps"],
        "n_evals_round1_and_accepted": n_evals,
        "selected": result["selected"],
        "final_model": result["final_model"],
        "baseline_gap": result["baseline"]["gap"],
        "final_gap": result["final_gap"],
        "noise_floor": result["noise_floor"],
        "unexplained": result["unexplained"],
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    print(json.dumps(out, indent=1))
    path = ROOT / "benchmarks" / "results" / "diagnose.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
