# Run discovery and the functions that turn the run list into job inputs.
#
# Only run.yaml is read here (tolerantly), so building the DAG stays fast. A run whose
# run.yaml is broken still gets its check and extract jobs: they fail with the run's own
# clear error under --keep-going, while the report depends only on runs whose check
# (a checkpoint) passed and lists the others with their error.

import json
import re
import sys
from pathlib import Path

import yaml

RAW = Path(config["raw_dir"])
RES = Path(config["results_dir"])
RUN_ID_RE = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")


def _peek_run_yaml(run_dir):
    """run.yaml as a dict, or {} when it cannot be parsed (the check job says why)."""
    try:
        meta = yaml.safe_load((run_dir / "run.yaml").read_text())
    except Exception:
        return {}
    return meta if isinstance(meta, dict) else {}


RUNS = {
    p.parent.name: _peek_run_yaml(p.parent)
    for p in sorted(RAW.glob("*/run.yaml"))
    if RUN_ID_RE.match(p.parent.name)
}
# Folders whose name breaks the contract's pattern get no jobs; the report lists them.
BAD_NAMES = sorted(
    p.parent.name for p in RAW.glob("*/run.yaml") if not RUN_ID_RE.match(p.parent.name)
)
SWEEPS = [r for r, m in RUNS.items() if m.get("kind") == "sweep"]
DROPS = [r for r, m in RUNS.items() if m.get("kind") == "drop"]
# a misspelt id in diagnosis.skip would skip nothing, silently: say so once, at the start
UNKNOWN_SKIPS = sorted(set(config["diagnosis"].get("skip", [])) - set(SWEEPS))
if UNKNOWN_SKIPS:
    print(
        f"warning: diagnosis.skip in the config names no sweep run of {RAW}/: "
        + ", ".join(UNKNOWN_SKIPS),
        file=sys.stderr,
    )
ACCEL_RUNS = [r for r, m in RUNS.items() if "accel" in (m.get("channels") or {})]
# an accelerometer in g: what `diagnosis: fix_accel` needs (bouncelab diagnose --fix-accel)
ACCEL_G_RUNS = [r for r in ACCEL_RUNS if RUNS[r].get("accel_v_per_g")]
VARIANTS = list(config["variants"])


wildcard_constraints:
    run="|".join(re.escape(r) for r in RUNS) or "NO_RUNS",
    variant="|".join(re.escape(v) for v in VARIANTS),


def check_verdict(run):
    """The run's check.json (evaluated after the checkpoint ran)."""
    with open(checkpoints.check_run.get(run=run).output[0]) as fh:
        return json.load(fh)


def run_ok(run):
    """True when the run's check passed."""
    return check_verdict(run)["ok"]


def run_diagnosable(run):
    """True unless the run's check found it too short to diagnose (no_diagnosis)."""
    return not check_verdict(run).get("no_diagnosis")


def run_diagnosed(run):
    """Whether the pipeline diagnoses this sweep run: diagnosis enabled, the run not in
    diagnosis.skip, and long enough (run_diagnosable)."""
    skipped = run in config["diagnosis"].get("skip", [])
    return config["diagnosis"]["enabled"] and not skipped and run_diagnosable(run)


def _mass_kg(meta):
    """A run's stated mass_kg as a float, or None (absent or not a number)."""
    try:
        return float(meta.get("mass_kg"))
    except (TypeError, ValueError):
        return None


def calibration_run_for(sweep, usable=None):
    """The drop run whose calibration feeds this sweep's models, or None: pinned, else
    among the drop runs of the sweep's body (the same mass_kg, when stated; all drop runs
    when none matches) the one sharing the longest name prefix, the first by name on a tie.
    Why the body first: a drop test of another body dropped into raw/ must not take over
    the runs calibrated before it (it did, being first by name with no prefix shared).
    ``usable``: a predicate on drop run ids (their check passed); the others are not
    candidates. Why: a broken drop run of the same body, first by name, took over a good
    one's sweep, whose models then fell back to the defaults (a black-box probe).
    """
    cal = config.get("calibration", {})
    if cal.get("source", "auto") == "none":
        return None
    pinned = cal.get("pin", {}).get(sweep)
    if pinned:
        return pinned
    drops = [d for d in DROPS if usable is None or usable(d)]
    if not drops:
        return None
    mass = _mass_kg(RUNS[sweep])
    # the same number as stated (0.249 and 0.2490 parse to one float)
    same_body = [d for d in drops if mass is not None and _mass_kg(RUNS[d]) == mass]

    def shared_prefix(drop):
        n = 0
        for a, b in zip(drop, sweep):
            if a != b:
                break
            n += 1
        return n

    return max(sorted(same_body or drops), key=shared_prefix)


def calibration_input(wildcards):
    """Calibration JSON for a sweep's models: [] when none (defaults are used)."""
    drop = calibration_run_for(wildcards.run, usable=run_ok)
    if drop is None or drop not in DROPS or not run_ok(drop):
        return []
    return [f"{RES}/runs/{drop}/calibration.json"]


def sweep_products(run):
    """Every per-run output of a sweep run that the report uses."""
    out = [
        f"{RES}/runs/{run}/flights.parquet",
        f"{RES}/runs/{run}/compare.parquet",
        f"{RES}/runs/{run}/energy.parquet",
    ]
    out += [f"{RES}/runs/{run}/sim/{v}.parquet" for v in VARIANTS]
    diagnosed = run_diagnosed(run)  # a too-short or unchosen run gets the rest
    if diagnosed:
        out.append(f"{RES}/runs/{run}/diagnosis.json")
    out += [
        f"{RES}/figures/{run}/{fig}.png"
        for fig in SWEEP_FIGURES
        if diagnosed or fig != "fig_gap_diagnosis"
    ]
    if run in ACCEL_RUNS:
        out.append(f"{RES}/figures/{run}/fig04_accelerometer.png")
    return out


def drop_products(run):
    return [
        f"{RES}/runs/{run}/flights.parquet",
        f"{RES}/runs/{run}/calibration.json",
        f"{RES}/figures/{run}/fig06_drop_test.png",
        f"{RES}/figures/{run}/fig03_rig.png",
    ]


def products_of_valid_runs(wildcards):
    """Outputs of every run that passed its check (what the report is built from)."""
    out = []
    for run in SWEEPS:
        if run_ok(run):
            out += sweep_products(run)
    for run in DROPS:
        if run_ok(run):
            out += drop_products(run)
    return out


def all_run_targets(wildcards):
    """What `rule all` asks of every run, valid or not.

    A broken run's extract job is requested too, so that it fails with the run's own
    error (visible under --keep-going) instead of silently vanishing.
    """
    out = [f"{RES}/runs/{run}/check.json" for run in RUNS]
    for run in RUNS:
        if not run_ok(run):
            out.append(f"{RES}/runs/{run}/flights.parquet")
    return out


def run_files(wildcards):
    """Every file of the run folder, so that editing a run reruns its jobs."""
    return sorted(str(p) for p in (RAW / wildcards.run).iterdir() if p.is_file())


SWEEP_FIGURES = [
    "fig03_rig",
    "fig05_continuity",
    "fig07_bifurcation",
    "fig08_return_maps",
    "fig09_friction",
    "fig10_harmonic",
    "gap_over_gamma",
    "energy_budget",
]
if config["diagnosis"]["enabled"]:
    SWEEP_FIGURES.append("fig_gap_diagnosis")
FIG = f"{RES}/figures"
DPI = config["figures"]["dpi"]


def figure_output(name, category, run=True):
    """PNG (marked for Snakemake's report) and the JSON of its numbers."""
    folder = f"{FIG}/{{run}}" if run else FIG
    return {
        "png": report(
            f"{folder}/{name}.png",
            caption=f"../report/{name}.rst",
            category=category,
            subcategory="{run}" if run else None,
        ),
        "data": f"{folder}/{name}.json",
    }
