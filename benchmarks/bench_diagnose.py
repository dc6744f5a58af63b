"""Speed of the whole gap diagnosis of one sweep run (issue 6, Speed).

Goal: at most 2 minutes per sweep run on 2 cores for the whole diagnosis (extraction of
the flights, every candidate fit, forward selection, intervals, regions). Measured on the
largest shipped run, ``raw/sweep_g0-8`` (Gamma 0 to 8 in steps of 0.05 with the seed's
data gaps, 50 cycles per step at 25 Hz; friction, restitution and shaker feedback), so
selection goes through several rounds.

``--rig-config CONFIG`` times a run the virtual rig makes from CONFIG instead (in a
temporary folder) and records the parameter errors against its ground truth:
``benchmarks/configs/seed_protocol_long.yaml`` is the seed's protocol at its longest
(Gamma 1 to 8 in steps of 0.05, 100 cycles per step at 30 Hz: 14100 cycles, nearly twice
the shipped run), the length where the 2-minute goal is not met (docs/diagnosis.md,
section 5).

``--cold-cache`` times the first diagnosis after an install or a source change: the script
runs itself again with numba's cache in a new, empty folder (``NUMBA_CACHE_DIR``), so
every kernel is compiled on the way, as on a fresh checkout (the workers too).

Measures, prints and writes ``benchmarks/results/diagnose.json`` (``diagnose_<config
name>.json`` with ``--rig-config``; ``_cold_cache`` appended with ``--cold-cache``).
Run: ``python benchmarks/bench_diagnose.py [--run raw/sweep_g0-8 | --rig-config CONFIG]
[--workers 2] [--cold-cache]``.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from bouncelab.gap.blind import score_case
from bouncelab.gap.diagnose import diagnose_run
from bouncelab.rig import read_truth, run_rig

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_physics import machine_speed  # noqa: E402

GOAL_S = 120.0
COLD_MARK = "BOUNCELAB_BENCH_COLD_CACHE"
ROOT = Path(__file__).resolve().parents[1]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--run", default=str(ROOT / "raw" / "sweep_g0-8"))
    p.add_argument("--rig-config", default=None, help="rig config of a virtual run to time")
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--cold-cache", action="store_true", help="time it with numba's cache empty")
    args = p.parse_args()
    if args.cold_cache and os.environ.get(COLD_MARK) is None:
        # numba reads its cache folder when it is imported, which this script already did:
        # the timed run is a child started with the empty folder in its environment
        with tempfile.TemporaryDirectory() as cache:
            env = {**os.environ, "NUMBA_CACHE_DIR": cache, COLD_MARK: "1"}
            sys.exit(subprocess.run([sys.executable, *sys.argv], env=env).returncode)
    errors, name = None, "diagnose"
    if args.rig_config is None:
        t0 = time.perf_counter()
        result = diagnose_run(args.run, workers=args.workers, progress=False)
        total_s = time.perf_counter() - t0
    else:
        name = f"diagnose_{Path(args.rig_config).stem}"
        with tempfile.TemporaryDirectory() as tmp:
            run_dir = Path(tmp) / Path(args.rig_config).stem
            run_rig(args.rig_config, run_dir, Path(tmp) / "truth.parquet")
            t0 = time.perf_counter()
            result = diagnose_run(run_dir, workers=args.workers, progress=False)
            total_s = time.perf_counter() - t0
            _flights, truth = read_truth(Path(tmp) / "truth.parquet")
        errors = score_case(result, truth)["param_errors"]
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
        "flights": result["design"]["work"]["flights"],
        "us_per_flight": round(total_s / max(result["design"]["work"]["flights"], 1) * 1e6, 3),
        "selected": result["selected"],
        "final_model": result["final_model"],
        "baseline_gap": result["baseline"]["gap"],
        "final_gap": result["final_gap"],
        "noise_floor": result["noise_floor"],
        "unexplained": result["unexplained"],
        "param_errors": errors,
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "machine": platform.machine(),
        "machine_feedback_mflights_s": machine_speed(),
        "numba_cache": "empty" if args.cold_cache else "as found",
    }
    if args.cold_cache:
        name += "_cold_cache"
    print(json.dumps(out, indent=1))
    path = ROOT / "benchmarks" / "results" / f"{name}.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")


if __name__ == "__main__":
    main()
