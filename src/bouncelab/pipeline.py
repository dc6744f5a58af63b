"""What the Snakemake scripts call: each function is one job's work, testable alone.

The scripts under ``workflow/scripts/`` only unpack the ``snakemake`` object, call one
function here, and write its result. Keeping the logic here means the tests exercise it
without Snakemake, and a user can run any stage from Python.
"""

from __future__ import annotations

import json
from pathlib import Path

from bouncelab.errors import BouncelabError


def check_run_verdict(run_dir) -> dict:
    """Validate a run folder and return a JSON-ready verdict; never raises for bad input.

    Returns ``{"ok": bool, "run": id, "error": one line or "", "summary": text,
    "info": validate's dict or {}, "no_diagnosis": why a sweep cannot be diagnosed, or
    ""}``. The workflow records this instead of failing, so that one broken run cannot
    stop the report; the run's own jobs still fail with the same error.  A sweep too
    short to diagnose (:func:`bouncelab.gap.fit.too_few_steps`, or whose steps end before
    their flights settle, :func:`bouncelab.gap.fit.unsettled_steps`) passes, and gets every
    product but the diagnosis. A run that meets the contract but has no contacts to
    extract (``ValidationReport.extract_problem``) is refused with that problem.
    """
    from bouncelab.gap.fit import too_few_steps, unsettled_steps
    from bouncelab.runs import validate_run

    run_dir = Path(run_dir)
    try:
        report = validate_run(run_dir)
    except BouncelabError as exc:
        return _refused(run_dir, str(exc))
    if report.extract_problem:
        # the folder meets the contract, but extract would fail: the run is refused here,
        # or the report waits for its products (a black-box probe's silent channel)
        return _refused(run_dir, f"{report.run.recording_path}: {report.extract_problem}")
    info = json.loads(json.dumps(report.to_dict(), default=str))
    short = None
    if info.get("kind") == "sweep":
        short = too_few_steps(info.get("n_steps") or 0) or unsettled_steps(
            report.run, float(info["duration_s"])
        )
    return {
        "ok": True,
        "run": run_dir.name,
        "error": "",
        "summary": report.summary(),
        "info": info,
        "no_diagnosis": short or "",
    }


def _refused(run_dir: Path, error: str) -> dict:
    """:func:`check_run_verdict` of a run that cannot be used: ``error`` says why."""
    return {
        "ok": False,
        "run": run_dir.name,
        "error": error,
        "summary": "",
        "info": {},
        "no_diagnosis": "",
    }


def resolve_variant_params(spec: dict, calibration: dict | None, defaults: dict) -> dict:
    """Parameter values of a configured model variant.

    ``spec`` is one entry of the config's ``variants``: ``{"model": name, "params":
    {...}}``. A value ``"calibrated"`` takes ``mu`` or ``e`` from the drop-test
    calibration (CONTRACTS.md section 4: ``mu``, ``restitution``), else from ``defaults``.
    """
    out = {}
    for name, value in (spec.get("params") or {}).items():
        if value == "calibrated":
            if name not in ("mu", "e"):
                raise BouncelabError(None, f"only mu and e can be 'calibrated', not {name!r}")
            key = "mu" if name == "mu" else "restitution"
            out[name] = float(calibration[key]) if calibration else float(defaults[name])
        else:
            out[name] = float(value)
    return out


def run_duration_s(run_dir) -> float:
    """End of a run's recording on its own time axis (s), read from the samples."""
    from bouncelab.runs import load_run, read_recording

    return float(read_recording(load_run(run_dir), roles=("continuity",)).duration_s)


def simulate_variant(
    run_dir,
    spec: dict,
    calibration_path=None,
    defaults: dict | None = None,
    n_starts: int = 4,
    seed: int = 0,
    duration_s: float | None = None,
    log_path=None,
):
    """One configured model variant under a sweep run's protocol, as a flight table."""
    from bouncelab.physics import Model
    from bouncelab.protocol import simulate_run
    from bouncelab.runs import load_run

    calibration = json.loads(Path(calibration_path).read_text()) if calibration_path else None
    params = resolve_variant_params(spec, calibration, defaults or {"mu": 0.29, "e": 0.515})
    model = Model.parse(spec["model"], params)
    run = load_run(run_dir)
    if duration_s is None:
        duration_s = run_duration_s(run_dir)
    table = simulate_run(run, model, duration_s, n_starts=n_starts, seed=seed)
    if log_path:
        source = f"calibration {calibration_path}" if calibration else "defaults"
        Path(log_path).write_text(
            f"{run.run_id}: model {model.name} {json.dumps(model.params, sort_keys=True)} "
            f"(calibrated values from {source}), {n_starts} starts, seed {seed}: "
            f"{len(table)} flights\n"
        )
    return table


def compare_variants(data, sims: dict):
    """Per-step gap between measured flights and each simulated variant.

    Returns one table: the columns of :func:`bouncelab.gap.relative_gap` (``step``,
    ``gamma``, counts, ``w1_T``, ``w_returnmap``, ``gap`` in rad, ``floor``,
    ``rel_gap``) with a ``variant`` column first. The noise floor of each variant comes
    from its own ensemble (even against odd starts) and from halves of the data.
    """
    import pandas as pd

    from bouncelab.gap import gap_table, noise_floor, relative_gap

    if "step" not in data:
        raise BouncelabError(None, "measured flights have no 'step' column")
    steps = data[["step", "gamma"]].drop_duplicates("step")
    for sim in sims.values():
        steps = pd.concat([steps, sim[["step", "gamma"]].drop_duplicates("step")])
    steps = steps.drop_duplicates("step").sort_values("step").reset_index(drop=True)
    tables = []
    for variant, sim in sims.items():
        gaps = gap_table(data, sim, steps=steps)
        floor = noise_floor(data, sim, steps=steps)
        rel = relative_gap(gaps, floor)
        rel.insert(0, "variant", variant)
        tables.append(rel)
    return pd.concat(tables, ignore_index=True)


def energy_budgets(run_dir, sims: dict):
    """Energy budget per step (J per drive cycle) of each variant, for the run's mass.

    Without ``mass_kg`` in run.yaml the seed's 249 g is used and the table says so
    (column ``mass_source``).
    """
    import pandas as pd

    from bouncelab.energy import energy_budget
    from bouncelab.runs import load_run

    run = load_run(run_dir)
    mass, source = (run.mass_kg, "run.yaml") if run.mass_kg else (0.249, "seed (249 g)")
    tables = []
    for variant, sim in sims.items():
        b = energy_budget(sim, mass, run.drive_frequency_hz)
        b.insert(0, "variant", variant)
        tables.append(b)
    out = pd.concat(tables, ignore_index=True)
    out["mass_kg"] = mass
    out["mass_source"] = source
    return out


def accelerometer_figure_inputs(run_dir, flights, gamma_target: float = 3.0, window_s=0.2):
    """Everything seed fig. 4 shows, for a sweep run with an ``accel`` channel.

    Runs the accelerometer method over the whole run, matches it with the continuity
    ``flights``, and cuts a ``window_s`` stretch from the middle of the step nearest
    ``gamma_target`` with its drive-subtracted residual. Returns the keyword arguments
    of :func:`bouncelab.figures.fig04_accelerometer.make`.
    """
    import numpy as np

    from bouncelab.flights.accel import (
        accel_flights,
        accel_gamma_run,
        compare_methods,
        subtract_drive,
    )
    from bouncelab.runs import load_run, read_recording, step_table

    run = load_run(run_dir)
    if "accel" not in run.channels:
        raise BouncelabError(run.yaml_path, "the run has no accel channel")
    rec = read_recording(run, roles=("accel",))
    accel = rec.channels["accel"]
    steps = step_table(run, rec.duration_s)
    f = float(run.drive_frequency_hz)
    acc = accel_flights(accel, rec.fs, steps, f, rec.time_s)
    table, summary = compare_methods(flights, acc)
    step = steps.iloc[int((steps["gamma"] - gamma_target).abs().to_numpy().argmin())]
    t = rec.times
    a, b = np.searchsorted(t, [step["t_start_s"], step["t_end_s"]])
    resid, _, _ = subtract_drive(t[a:b], accel[a:b], f)
    half = int(window_s * rec.fs) // 2
    mid = (b - a) // 2
    lo, hi = max(0, mid - half), min(b - a, mid + half)
    t_win = np.asarray(t[a:b][lo:hi], dtype=float)
    land = flights["t_landing_s"].to_numpy()
    return {
        "time_s": t_win,
        "accel_v": np.asarray(accel[a:b][lo:hi], dtype=float),
        "residual_v": np.asarray(resid[lo:hi], dtype=float),
        "continuity_landings_s": land[(land >= t_win[0]) & (land <= t_win[-1])],
        "comparison": table,
        "summary": summary,
        "run_id": run.run_id,
        "gamma": float(step["gamma"]),
        "gamma_by_step": accel_gamma_run(run, rec),  # the recording read once
    }
