"""Speed of the gap metrics (bouncelab.gap): what one evaluation of a fit costs.

Goal (issue 6): one full comparison of a 100-step run with ~10^4 flights per side in
under ~5 ms, since effect fitting calls it hundreds of times. Measures, prints and
writes ``benchmarks/results/gap.json``. Run: ``python benchmarks/bench_gap.py``.
"""

from __future__ import annotations

import json
import platform
import time
from pathlib import Path

import numpy as np
import pandas as pd

from bouncelab.gap import (
    compare_features,
    gap_table,
    noise_floor,
    prepare_flights,
    relative_gap,
    segment_regions,
)

GOAL_MS = 5.0
N_STEPS = 100
N_FLIGHTS = 10_000


def synthetic_run(seed: int) -> pd.DataFrame:
    """100 steps, 10^4 flights: periodic and broad steps mixed, in time order."""
    rng = np.random.default_rng(seed)
    step = np.repeat(np.arange(N_STEPS), N_FLIGHTS // N_STEPS)
    gamma = 1.0 + 0.07 * step
    period = 1 + (step // 25) % 3  # 1, 2, 3 cycling by blocks of steps
    phase = np.arange(len(step)) % period
    T = 1.0 + 0.1 * step * (1 + 0.3 * phase) + rng.normal(0, 0.05 + 0.5 * (step > 80), len(step))
    return pd.DataFrame(
        {
            "step": step,
            "gamma": gamma,
            "T": np.abs(T),
            "phi_takeoff": rng.uniform(0, 2 * np.pi, len(step)),
            "settled": (np.arange(len(step)) % 100) >= 10,
            "t_takeoff_s": np.arange(len(step)) * 0.05,
        }
    )


def best_ms(fn, repeat: int = 30) -> dict:
    """Median and best of ``repeat`` timed calls, ms (after one warm-up call)."""
    fn()
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1e3)
    return {"median_ms": float(np.median(times)), "best_ms": float(np.min(times))}


def main() -> dict:
    data, sim = synthetic_run(0), synthetic_run(1)
    data_prep = prepare_flights(data)
    sim_prep = prepare_flights(sim)
    floor = noise_floor(data, sim)
    gaps = relative_gap(gap_table(data_prep, sim), floor)
    cmp = compare_features(data, sim)
    results = {
        "gap_table_prepared_data_vs_sim_dataframe": best_ms(lambda: gap_table(data_prep, sim)),
        "gap_table_both_prepared": best_ms(lambda: gap_table(data_prep, sim_prep)),
        "full_comparison_with_relative_gap": best_ms(
            lambda: relative_gap(gap_table(data_prep, sim), floor)
        ),
        "prepare_flights": best_ms(lambda: prepare_flights(sim)),
        "noise_floor": best_ms(lambda: noise_floor(data, sim), repeat=5),
        "compare_features": best_ms(lambda: compare_features(data, sim), repeat=5),
        "segment_regions": best_ms(lambda: segment_regions(gaps, cmp), repeat=5),
    }
    key = "full_comparison_with_relative_gap"
    out = {
        "n_steps": N_STEPS,
        "n_flights_per_side": N_FLIGHTS,
        "goal_ms": GOAL_MS,
        "meets_goal": results[key]["median_ms"] < GOAL_MS,
        "results": results,
        "machine": {"python": platform.python_version(), "processor": platform.machine()},
        "note": "measured while other jobs may share the machine; re-run on a quiet one",
    }
    for name, r in results.items():
        print(f"{name:45s} median {r['median_ms']:8.2f} ms   best {r['best_ms']:8.2f} ms")
    print(f"goal: {key} < {GOAL_MS} ms -> {'met' if out['meets_goal'] else 'NOT met'}")
    path = Path(__file__).parent / "results" / "gap.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
