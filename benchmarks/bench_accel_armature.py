"""How well a plate accelerometer reads the shaker's armature (its ring-down after the
impacts), against the virtual rig's own armature.

:func:`bouncelab.flights.armature.armature_from_accel` is what ``bouncelab diagnose``
shows beside a fitted ``feedback`` (JSON ``accel_calibration.armature``), warns from, and
holds with ``--fix-accel``. Runs: the blind validation's cases with the armature
(``config/blind/cases.yaml``: feedback alone above and below its resonance, the seed-like
combinations) and its rigid-shaker cases (the nulls and single effects with the four
harder runs of ``bench_accel_warnings.py``, random plate vibration, a sensor delay),
each made again with an accelerometer (the rig's default
sensor: 10 mV/g, 0.5 g rms noise, 0.3 g hum, a 3 kHz mounting ring); the configs of
``benchmarks/configs/accel_*.yaml``; and the shipped ``config/rig/accel_g2-4.yaml``.
Reference: the rig's ``f_ratio`` (its derived number) and ``damping_ratio``, read only
here, after the reading.

Goals: on a rigid shaker no armature read; where one is read, ``f_ratio`` within 2 % and
``zeta`` within 15 %. A true armature that is not read is counted, not a miss of the
goals: one rung in step with the drive looks like the drive's harmonics (the module's
docstring).

``--diagnose NAME ...`` also diagnoses those runs (``diagnose_run``, seed 0, 2 workers)
with ``--fix-accel``, which holds ``f_ratio`` and ``zeta`` at the reading, and scores the
selection and every parameter against the rig (``gap.blind.score_case``) beside the blind
validation's record of the same case (``blind_validation.json``): the accelerometer
leaves the continuity recording as it is (the rig draws its noise apart), so the record
is this recording diagnosed without the reading.

    python benchmarks/bench_accel_armature.py [--only NAME ...] [--diagnose NAME ...]

Prints and writes ``benchmarks/results/accel_armature.json`` (``--only`` merges the named
runs into the record's others).
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import tempfile
import time
from pathlib import Path

import yaml

from bouncelab.flights import extract_run
from bouncelab.flights.armature import armature_from_accel
from bouncelab.gap.blind import deep_merge, load_cases, score_case
from bouncelab.gap.diagnose import diagnose_run
from bouncelab.rig import read_truth, run_rig
from bouncelab.runs import load_run
from bouncelab.yamlfile import read_yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_accel_warnings import cases as accel_warning_cases  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "accel_armature.json"
F_RATIO_GOAL, ZETA_GOAL = 0.02, 0.15
ARMATURE_CASES = (
    "feedback_a", "feedback_b", "feedback_c", "g_feedback",
    "seed_like", "seed_like_b", "seed_like_c", "g_seed_like",
)  # fmt: skip
#: Rigid-shaker cases outside the library, beside ``bench_accel_warnings.cases()`` (the
#: blind single-effect and null cases, and four harder runs).
OUTSIDE_CASES = ("ool_vibration", "ool_vibration_b", "ool_delay")


def configs() -> dict[str, dict]:
    """Every run's rig config, with the accelerometer on."""
    accel = {"sensors": {"accel": {"enabled": True}}}
    blind = {c["name"]: c["rig"] for c in load_cases(ROOT / "config" / "blind" / "cases.yaml")}
    out = {name: deep_merge(blind[name], accel) for name in ARMATURE_CASES + OUTSIDE_CASES}
    out |= accel_warning_cases()
    paths = sorted((ROOT / "benchmarks" / "configs").glob("accel_*.yaml"))
    for path in [*paths, ROOT / "config" / "rig" / "accel_g2-4.yaml"]:
        out[path.stem] = read_yaml(path, "rig config")
    return out


def measure(name: str, cfg: dict, tmp: Path, diagnose: bool = False) -> dict:
    """One run made, extracted and read; the reading scored against the rig's armature;
    with ``diagnose``, the run diagnosed with the reading held and scored too."""
    (tmp / f"{name}.yaml").write_text(yaml.safe_dump(cfg))
    run_rig(tmp / f"{name}.yaml", tmp / name, tmp / f"{name}.parquet")
    flights, _qc = extract_run(tmp / name)
    t0 = time.perf_counter()
    reading = armature_from_accel(load_run(tmp / name), flights)
    seconds = time.perf_counter() - t0
    _f, truth = read_truth(tmp / f"{name}.parquet")  # only now
    shaker = truth["config"]["shaker"]
    true = (
        {"f_ratio": truth["derived"]["f_ratio"], "zeta": shaker["damping_ratio"]}
        if shaker["feedback"]
        else None
    )
    read = bool(reading and reading["read"])
    errors = {k: abs(reading[k] - v) / v for k, v in true.items()} if (true and read) else None
    if true is None:
        met = not read
    else:
        met = (not read) or (errors["f_ratio"] <= F_RATIO_GOAL and errors["zeta"] <= ZETA_GOAL)
    out = {
        "armature": true is not None,
        "true": true,
        "reading": reading,
        "rel_errors": errors,
        "meets_goals": met,
        "read_s": round(seconds, 2),
    }
    if diagnose:
        t0 = time.perf_counter()
        result = diagnose_run(tmp / name, fix_accel=True, workers=2)
        scored = score_case(result, truth)
        out["diagnosis_fix_accel"] = {
            "fixed": result["design"]["fixed"],
            "selected": scored["selected"],
            "set_right": scored["set_right"],
            "unexplained": scored["unexplained"],
            "param_errors": scored["param_errors"],
            "input_warnings": result["input_warnings"],
            "diagnose_s": round(time.perf_counter() - t0, 1),
        }
        blind = json.loads((RESULTS.parent / "blind_validation.json").read_text())["cases"]
        if name in blind:
            keys = ("selected", "set_right", "unexplained", "param_errors")
            out["blind_record"] = {k: blind[name][k] for k in keys}
    return out


def _rounded(errors: dict | None) -> dict | None:
    if errors is None:
        return None
    return {f"{e}.{p}": round(v, 3) for e, ps in errors.items() for p, v in ps.items()}


def summary(runs: dict) -> dict:
    arm = [r for r in runs.values() if r["armature"]]
    rigid = [r for r in runs.values() if not r["armature"]]
    read = [r for r in arm if r["rel_errors"]]
    return {
        "armature_runs": len(arm),
        "armature_read": len(read),
        "armature_read_within_goals": sum(r["meets_goals"] for r in read),
        "rigid_runs": len(rigid),
        "rigid_read": sum(bool(r["reading"] and r["reading"]["read"]) for r in rigid),
        "max_f_ratio_error": max((r["rel_errors"]["f_ratio"] for r in read), default=None),
        "max_zeta_error": max((r["rel_errors"]["zeta"] for r in read), default=None),
        "max_rigid_rms_ratio": max(
            (r["reading"]["rms_ratio"] for r in rigid if r["reading"]), default=None
        ),
        "min_read_rms_ratio": min((r["reading"]["rms_ratio"] for r in read), default=None),
        "max_read_s": max(r["read_s"] for r in runs.values()),
        "meets_goals": all(r["meets_goals"] for r in runs.values()),
        "diagnosed_fix_accel": {
            name: {
                "set_right": r["diagnosis_fix_accel"]["set_right"],
                "params_within_15pct": _within(r["diagnosis_fix_accel"]["param_errors"]),
                "blind_record_within_15pct": _within(
                    (r.get("blind_record") or {}).get("param_errors")
                ),
            }
            for name, r in runs.items()
            if "diagnosis_fix_accel" in r
        },
    }


def _within(errors: dict | None, tol: float = 0.15) -> list[int] | None:
    """``[within tol, scored]`` over every parameter of ``errors``."""
    if errors is None:
        return None
    values = [v for ps in errors.values() for v in ps.values()]
    return [sum(v <= tol for v in values), len(values)]


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=None, help="run only these, merged into the record")
    p.add_argument("--diagnose", nargs="*", default=[], help="diagnose these with --fix-accel too")
    args = p.parse_args()
    cfgs = configs()
    names = args.only or list(cfgs)
    unknown = sorted(set(names) - set(cfgs)) + sorted(set(args.diagnose) - set(names))
    if unknown:
        raise SystemExit(f"error: unknown runs {unknown}; known: {sorted(cfgs)}")
    runs = json.loads(RESULTS.read_text())["runs"] if args.only and RESULTS.exists() else {}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            r = runs[name] = measure(name, cfgs[name], Path(tmp), name in args.diagnose)
            reading = r["reading"] or {}
            errors = r["rel_errors"] or {}
            print(
                f"{name:24s} armature {'yes' if r['armature'] else 'no ':3s}  "
                f"read {'yes' if reading.get('read') else 'no ':3s}  "
                f"rms ratio {reading.get('rms_ratio', float('nan')):5.2f}  "
                f"f_ratio {reading.get('f_ratio', float('nan')):.4f} "
                f"({100 * errors.get('f_ratio', float('nan')):4.1f} %)  "
                f"zeta {reading.get('zeta', float('nan')):.4f} "
                f"({100 * errors.get('zeta', float('nan')):4.1f} %)  {r['read_s']:5.1f} s",
                flush=True,
            )
            if "diagnosis_fix_accel" in r:
                d, rec = r["diagnosis_fix_accel"], r.get("blind_record") or {}
                print(f"    --fix-accel: {d['selected']}, set right {d['set_right']}, "
                      f"errors {_rounded(d['param_errors'])}; without the reading (blind "
                      f"record): {rec.get('selected')}, {_rounded(rec.get('param_errors'))}",
                      flush=True)  # fmt: skip
    out = {
        "summary": summary(runs),
        "goals": {"f_ratio_rel": F_RATIO_GOAL, "zeta_rel": ZETA_GOAL, "rigid_read": 0},
        "runs": dict(sorted(runs.items())),
        "cpu_count": os.cpu_count(),
        "python": platform.python_version(),
        "machine": platform.machine(),
    }
    print(json.dumps(out["summary"], indent=1))
    RESULTS.write_text(json.dumps(out, indent=1, sort_keys=True) + "\n")
    print(f"-> {RESULTS}")


if __name__ == "__main__":
    main()
