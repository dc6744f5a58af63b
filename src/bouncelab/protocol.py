"""A sweep run's protocol, and a model simulated under it as a flight table.

This is the bridge between a run (SI: seconds, hertz, Gamma steps at times) and the
nondimensional model (:mod:`bouncelab.physics`: drive cycles and phases). Models
are compared with data under the lab's own protocol because the dynamics are
multistable: the same Gamma can give different attractors depending on history.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from bouncelab.errors import BouncelabError
from bouncelab.physics import Model, simulate_protocol
from bouncelab.physics.simulate import CHATTER_EPS, seen_flights
from bouncelab.runs import Run, step_table

TWO_PI = 2.0 * math.pi


def run_protocol(run: Run, duration_s: float) -> pd.DataFrame:
    """The run's Gamma steps with their lengths in whole drive cycles.

    Returns the :func:`bouncelab.runs.step_table` columns (``step``, ``gamma``,
    ``t_start_s``, ``t_end_s``) plus ``cycles``: the step's length in drive cycles,
    rounded to a whole number (the model changes amplitude at whole cycles, where the
    plate's position is zero), at least 1.
    """
    if run.kind != "sweep":
        raise BouncelabError(run.yaml_path, f"run is a {run.kind} run; a protocol needs a sweep")
    steps = step_table(run, duration_s)
    if steps.empty:
        raise BouncelabError(run.yaml_path, "no Gamma steps inside the recording")
    f = float(run.drive_frequency_hz)
    cycles = np.maximum(1, np.rint((steps["t_end_s"] - steps["t_start_s"]) * f)).astype(int)
    out = steps[["step", "gamma", "t_start_s", "t_end_s"]].copy()
    out["cycles"] = cycles
    return out.reset_index(drop=True)


def simulate_run(
    run: Run,
    model: Model,
    duration_s: float,
    n_starts: int = 1,
    seed: int = 0,
    min_contact: float = 0.0,
    chatter_eps: float = CHATTER_EPS,
    stick_speed: float = 0.0,
) -> pd.DataFrame:
    """The model under the run's protocol, as a flight table like the measured one.

    Parameters
    ----------
    run : the sweep run whose steps, drive frequency and settle cycles are used.
    model : the model variant.
    duration_s : end of the recording (s), which ends the last step.
    n_starts : ensemble of start phases (each member runs the whole protocol).
    seed : seed of the start phases.
    min_contact : rad; > 0: the flights as a continuity circuit shows them when every
        contact lasts at least that long (:func:`bouncelab.physics.simulate.seen_flights`).
    chatter_eps : rad; a chatter sequence ends once its next flight would be shorter
        (:func:`bouncelab.physics.simulate.simulate_protocol`).
    stick_speed : g / omega; a rebound slower than this sticks (0: none).

    Returns
    -------
    DataFrame with the model's flight columns (``gamma``, ``T``, ``phi_takeoff``,
    ``phi_landing``, ``v_impact``, energies, ``chatter``, ``start``, ``settled``) and,
    as in CONTRACTS.md section 3, ``run``, ``step`` (index into the run's
    ``gamma_steps``), ``t_takeoff_s``, ``t_landing_s`` and ``flight_s`` on the
    recording's time axis (step start + time since the model's step start), plus one
    column per model parameter.
    """
    proto = run_protocol(run, duration_s)
    f = float(run.drive_frequency_hz)
    sim = simulate_protocol(
        model,
        proto["gamma"].to_numpy(),
        proto["cycles"].to_numpy(),
        settle_cycles=int(run.settle_cycles),
        seed=seed,
        n_starts=n_starts,
        chatter_eps=chatter_eps,
        stick_speed=stick_speed,
    )
    sim = seen_flights(sim, min_contact)
    # phase at which each model step starts, to put flights on the recording's clock
    phase_start = TWO_PI * np.concatenate([[0], np.cumsum(proto["cycles"].to_numpy())[:-1]])
    idx = sim["step"].to_numpy().astype(int)
    t_start = proto["t_start_s"].to_numpy()[idx]
    since_step = (sim["t_takeoff"].to_numpy() - phase_start[idx]) / (TWO_PI * f)
    out = sim.copy()
    out["step"] = proto["step"].to_numpy()[idx]
    out["t_takeoff_s"] = t_start + since_step
    out["flight_s"] = out["T"] / (TWO_PI * f)
    out["t_landing_s"] = out["t_takeoff_s"] + out["flight_s"]
    out.insert(0, "run", run.run_id)
    for name, value in sorted(model.params.items()):
        if np.ndim(value) == 0:
            out[name] = float(value)
    return out
