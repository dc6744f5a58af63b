"""Rig speed: a 5-minute sweep recording (Gamma 0 to 8, feedback, 3 channels).

Goal (issue 3): at least 20 times real time, i.e. 300 s of recording in at most 15 s
on 2 cores. Prints and writes benchmarks/results/rig.json.

    python benchmarks/bench_rig.py
"""

from __future__ import annotations

import json
import tempfile
import time
from pathlib import Path

from bouncelab.rig import parse_rig_config, simulate_rig, write_run

GOAL_X_REALTIME = 20.0


def config() -> dict:
    """Gamma 0-8 by 0.05 at 25 Hz, 46 cycles per step: 161 steps = 296 s, plus accel."""
    return parse_rig_config(
        {
            "kind": "sweep",
            "seed": 1,
            "drive": {"frequency_hz": 25.0},
            "protocol": {"gamma_start": 0.0, "gamma_stop": 8.0, "gamma_step": 0.05,
                         "cycles_per_step": 46},
            "sensors": {"accel": {"enabled": True}},
        }
    )  # fmt: skip


def main() -> dict:
    cfg = config()
    simulate_rig(parse_rig_config({"kind": "drop", "protocol": {"duration_s": 0.3}}))  # warm
    t0 = time.perf_counter()
    res = simulate_rig(cfg)
    t_sim = time.perf_counter() - t0
    with tempfile.TemporaryDirectory() as tmp:
        t1 = time.perf_counter()
        write_run(res, Path(tmp) / "bench", "flac")
        t_write = time.perf_counter() - t1
    duration = res.n_samples / res.fs
    out = {
        "recording_s": duration,
        "simulate_s": round(t_sim, 3),
        "write_flac_s": round(t_write, 3),
        "x_realtime_simulate": round(duration / t_sim, 1),
        "x_realtime_total": round(duration / (t_sim + t_write), 1),
        "goal_x_realtime": GOAL_X_REALTIME,
        "true_flights": len(res.truth),
        "meets_goal": duration / (t_sim + t_write) >= GOAL_X_REALTIME,
    }
    print(json.dumps(out, indent=2))
    path = Path(__file__).parent / "results" / "rig.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(out, indent=2) + "\n")
    return out


if __name__ == "__main__":
    main()
