"""Do the accelerometer's warnings fire where the diagnosis is wrong, and only there?

The blind validation's single-effect cases (``config/blind/cases.yaml``: nulls, friction,
restitution, harmonics, Gamma miscalibrations, on a rigid shaker), and four shorter or
harder runs of the same effects (:data:`HARD`), are made by the virtual rig with an
``accel`` channel (default sensor: 10 mV/g, 0.5 g rms noise, 0.3 g
hum), and diagnosed (``diagnose_run``, seed 0, no retry) without being told anything. A
case's plate is right when the diagnosis selected ``gamma_scale`` exactly when the rig's
scale differs from 1, with ``s`` within 3 %, and a harmonic exactly when the rig has one,
with its ``k`` and ``a`` within 30 %: the tolerances of the warnings
(``gap.diagnose.accel_warnings``). Reference: the rig's own parameters, read only here.

Counted: warned where the plate is wrong (caught), silent where it is wrong (missed),
warned where it is right (false alarm). Printed and written to
``benchmarks/results/accel_warnings.json``.

    python benchmarks/bench_accel_warnings.py [--only NAME ...]

With ``--only`` the named cases are run again and merged into the record's others.
"""

from __future__ import annotations

import argparse
import json
import platform
import tempfile
import time
from pathlib import Path

import yaml

from bouncelab.gap.blind import deep_merge, load_cases
from bouncelab.gap.diagnose import ACCEL_HARMONIC_REL, ACCEL_SCALE_TOL, diagnose_run
from bouncelab.rig import run_rig
from bouncelab.yamlfile import read_yaml

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "benchmarks" / "results" / "accel_warnings.json"
BLIND_CASES = ROOT / "config" / "blind" / "cases.yaml"
SINGLE = ("null", "friction", "restitution", "harmonic", "gamma_scale")
#: Case names of one library effect or none (the validation's ``g_`` and ``w_`` too).
PREFIXES = SINGLE + tuple(p + s for p in ("g_", "w_") for s in SINGLE)


def cases() -> dict[str, dict]:
    """The blind single-effect and null cases (rigid shaker) and :data:`HARD`, each with
    an accelerometer."""
    accel = {"sensors": {"accel": {"enabled": True}}}
    out = {}
    for case in load_cases(BLIND_CASES):
        cfg = case["rig"]
        if not case["name"].startswith(PREFIXES):
            continue
        if cfg.get("shaker", {}).get("feedback") or cfg.get("effects"):
            continue
        out[case["name"]] = deep_merge(cfg, accel)
    base = read_yaml(BLIND_CASES, "blind case file").get("base") or {}
    for name, over in HARD.items():
        out[name] = deep_merge(deep_merge(base, over), accel)
    return out


#: Shorter or harder runs of the same effects (session 45), where the flight times erred:
#: a few steps, or a harmonic over a wide Gamma range. Rigid shaker, accelerometer on.
K3 = {"frequency_hz": 30.0, "harmonics": [{"k": 3.0, "a": 0.08, "psi": 1.0}]}
HARD = {
    "hard_gamma_scale_5_steps": {
        "seed": 11, "body": {"friction_mu": 0.29, "restitution": 0.515},
        "drive": {"frequency_hz": 28.0, "gamma_scale": 1.07},
        "protocol": {"gammas": [0.6, 1.2, 2.0, 2.8, 3.6], "cycles_per_step": 40},
    },
    "hard_harmonic_13_steps": {
        "seed": 32, "drive": K3,
        "protocol": {"gamma_start": 1.2, "gamma_stop": 3.6, "gamma_step": 0.2,
                     "cycles_per_step": 40},
    },
    "hard_harmonic_4_steps": {
        "seed": 31, "drive": K3,
        "protocol": {"gammas": [0.6, 1.5, 2.5, 3.5], "cycles_per_step": 40},
    },
    "hard_gamma_scale_6_steps": {
        "seed": 21, "drive": {"frequency_hz": 28.0, "gamma_scale": 1.07},
        "protocol": {"gammas": [1.2, 1.6, 2.0, 2.4, 2.8, 3.2], "cycles_per_step": 30},
    },
}  # fmt: skip


def plate_right(cfg: dict, result: dict) -> tuple[bool, str]:
    """Whether the diagnosis got the plate's motion right (see the module's docstring)."""
    drive = cfg.get("drive", {})
    true_s = float(drive.get("gamma_scale", 1.0))
    harmonics = drive.get("harmonics") or []
    params = result["final_model"]["params"]
    selected = result["selected"]
    why = []
    if ("gamma_scale" in selected) != (true_s != 1.0):
        why.append(f"gamma_scale {'selected' if 'gamma_scale' in selected else 'missed'}")
    elif true_s != 1.0 and abs(params["s"] - true_s) > ACCEL_SCALE_TOL * true_s:
        why.append(f"s {params['s']:.4g} for {true_s}")
    if ("harmonic" in selected) != bool(harmonics):
        why.append(f"harmonic {'selected' if 'harmonic' in selected else 'missed'}")
    elif harmonics:
        h = harmonics[0]
        if params["k"] != h["k"] or abs(params["a"] - h["a"]) > ACCEL_HARMONIC_REL * h["a"]:
            why.append(f"harmonic k {params['k']:g} a {params['a']:.3g} for {h['k']:g}, {h['a']}")
    return not why, "; ".join(why)


def main() -> dict:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", nargs="*", help="case names")
    args = ap.parse_args()
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, cfg in cases().items():
            if args.only and name not in args.only:
                continue
            path = Path(tmp) / f"{name}.yaml"
            path.write_text(yaml.safe_dump(cfg))
            run_rig(path, Path(tmp) / name, Path(tmp) / f"{name}_truth.parquet")
            t0 = time.perf_counter()
            d = diagnose_run(Path(tmp) / name, retries=0, workers=2)
            right, why = plate_right(cfg, d)
            warned = [w for w in d["input_warnings"] if "accelerometer" in w]
            rows[name] = {
                "selected": d["selected"],
                "params": d["final_model"]["params"],
                "plate_right": right,
                "why_wrong": why,
                "warnings": warned,
                "accel_s": d["accel_calibration"]["s"],
                "accel_harmonics": d["accel_calibration"]["harmonics"],
                "diagnose_s": round(time.perf_counter() - t0, 1),
            }
            verdict = "right" if right else f"WRONG ({why})"
            print(f"{name:22s} {', '.join(d['selected']) or 'nothing':34s} plate {verdict}; "
                  f"warned: {len(warned)}")  # fmt: skip
            for w in warned:
                print(f"{'':24s}{w}")
    if args.only and RESULTS.is_file():  # the other cases as last recorded
        rows = json.loads(RESULTS.read_text())["cases"] | rows
    caught = sum(1 for r in rows.values() if not r["plate_right"] and r["warnings"])
    missed = sum(1 for r in rows.values() if not r["plate_right"] and not r["warnings"])
    false = sum(1 for r in rows.values() if r["plate_right"] and r["warnings"])
    out = {
        "summary": {"cases": len(rows), "plate_wrong_caught": caught, "plate_wrong_missed": missed,
                    "false_alarms": false},
        "cases": rows,
        "machine": {"processor": platform.machine(), "python": platform.python_version()},
    }  # fmt: skip
    print(out["summary"])
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {RESULTS}")
    return out


if __name__ == "__main__":
    main()
