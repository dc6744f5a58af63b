"""Pseudo-data for the diagnosis tests: a run folder whose "measured" flights are made by
the physics model itself (a known model, with timing noise), so the truth is exact.

The recording is a tiny NPZ file of the right length; the tests pass the flights directly
(the path of ``bouncelab diagnose --flights``), so nothing is extracted from it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import yaml

from bouncelab.physics import Model
from bouncelab.protocol import simulate_run
from bouncelab.runs import load_run

FS = 2000.0  # Hz of the placeholder recording (its samples are never analysed)
DRIVE_HZ = 30.0
CYCLES = 30
GAMMAS = tuple(np.round(np.arange(0.8, 3.7, 0.15), 6))  # 20 steps: onset, period 2, lock


def write_run(root: Path, name: str = "pseudo", gammas=GAMMAS, cycles: int = CYCLES) -> Path:
    """A sweep run folder with the given Gamma steps, ``cycles`` drive cycles each."""
    run_dir = root / name
    run_dir.mkdir(parents=True)
    step_s = cycles / DRIVE_HZ
    duration = step_s * len(gammas)
    n = int(round(duration * FS))
    np.savez(run_dir / "rec.npz", cont_v=np.zeros(n), drive_v=np.zeros(n))
    spec = {
        "format_version": 1,
        "kind": "sweep",
        "recording": "rec.npz",
        "sample_rate_hz": FS,
        "channels": {"continuity": "cont_v", "drive": "drive_v"},
        "drive_frequency_hz": DRIVE_HZ,
        "gamma_steps": [
            {"t_s": round(i * step_s, 9), "gamma": float(g)} for i, g in enumerate(gammas)
        ],
        "settle_cycles": 10,
        "source": "synthetic",
    }
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    return run_dir


def duration_s(gammas=GAMMAS, cycles: int = CYCLES) -> float:
    """Length (s) of the run written by :func:`write_run`."""
    return len(gammas) * cycles / DRIVE_HZ


def pseudo_flights(
    run_dir: Path,
    model: Model,
    seed: int,
    noise_rad: float = 0.005,
    cycles: int = CYCLES,
    gammas=GAMMAS,
):
    """Flights of ``model`` under the run's protocol from a seeded random start phase (not
    the diagnosis's own start), with Gaussian timing noise of ``noise_rad`` on ``T`` (the
    rig's sampling resolution is about 0.01 rad). ``cycles``, ``gammas``: as given to
    :func:`write_run`.
    """
    run = load_run(run_dir)
    sim = simulate_run(run, model, duration_s(gammas, cycles), n_starts=2, seed=seed)
    sim = sim.loc[sim["start"] == 1].reset_index(drop=True)  # member 0 starts at phase 0
    rng = np.random.default_rng(seed)
    sim["T"] = np.abs(sim["T"].to_numpy() + noise_rad * rng.standard_normal(len(sim)))
    sim["start"] = 0
    return sim
