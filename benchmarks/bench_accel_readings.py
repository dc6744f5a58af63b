"""How well an accelerometer on the plate reads the Gamma scale and the drive's harmonics.

Reference: the virtual rig's own parameters (its ``drive.gamma_scale`` and
``drive.harmonics``), which the readings never see. For each configuration below the rig
writes a run with an ``accel`` channel (default sensor: 10 mV/g, 0.5 g rms noise, 0.3 g
hum, impact ringing), and ``bouncelab.flights.accel`` reads it
(:func:`accel_gamma_run`, :func:`gamma_scale_from_accel`, :func:`harmonics_from_accel`).
Printed and written to ``benchmarks/results/accel_readings.json``: per configuration the
true and read ``s``, whether the truth lies in the reading's interval, and for a true
harmonic the read ``a`` and ``psi`` with their errors; a harmonic read where the rig has
none is listed as spurious.

Goal (what the diagnosis's warnings assume, docs/diagnosis.md section 1): on a rigid
shaker ``s`` within 1 %, a harmonic's ``a`` within 5 % and ``psi`` within 0.05 rad, and
no spurious harmonic. With the armature the plate's amplitude varies with Gamma: the
readings are recorded, not held to the goal.

    python benchmarks/bench_accel_readings.py
"""

from __future__ import annotations

import json
import math
import platform
import tempfile
import time
from pathlib import Path

import yaml

from bouncelab.flights.accel import accel_gamma_run, gamma_scale_from_accel, harmonics_from_accel
from bouncelab.rig import run_rig
from bouncelab.runs import load_run

RESULTS = Path(__file__).resolve().parent / "results" / "accel_readings.json"

GOALS = {"s_rel": 0.01, "a_rel": 0.05, "psi_rad": 0.05}

PROTOCOL = {"gamma_start": 0.8, "gamma_stop": 4.0, "gamma_step": 0.4, "cycles_per_step": 40}


def _case(name, seed, freq, scale=1.0, harmonics=(), feedback=False, body=None):
    drive = {"frequency_hz": freq, "gamma_scale": scale}
    if harmonics:
        drive["harmonics"] = [{"k": k, "a": a, "psi": psi} for k, a, psi in harmonics]
    return name, {
        "kind": "sweep",
        "seed": seed,
        "body": body or {"friction_mu": 0.29, "restitution": 0.515},
        "drive": drive,
        "shaker": {"feedback": feedback},
        "protocol": PROTOCOL,
        "sensors": {"accel": {"enabled": True}},
    }


CASES = [
    _case("rigid_null_30hz", 1, 30.0),
    _case("rigid_s0.93_25hz", 2, 25.0, scale=0.93),
    _case("rigid_s1.06_35hz", 3, 35.0, scale=1.06),
    _case("rigid_k2_a0.12_28hz", 4, 28.0, harmonics=[(2.0, 0.12, 4.0)]),
    _case("rigid_k3_a0.06_30hz", 5, 30.0, harmonics=[(3.0, 0.06, 5.0)]),
    _case("rigid_k4_a0.05_32hz", 6, 32.0, harmonics=[(4.0, 0.05, 2.0)]),
    _case("rigid_k3_a0.08_s0.94_26hz", 7, 26.0, scale=0.94, harmonics=[(3.0, 0.08, 1.0)]),
    _case("rigid_inelastic_k2_a0.07", 8, 30.0, harmonics=[(2.0, 0.07, 0.5)],
          body={"friction_mu": 0.0, "restitution": 0.0}),
    _case("armature_null_30hz", 9, 30.0, feedback=True),
    _case("armature_s0.93_30hz", 10, 30.0, scale=0.93, feedback=True),
    _case("armature_k3_a0.08_30hz", 11, 30.0, harmonics=[(3.0, 0.08, 1.0)], feedback=True),
]  # fmt: skip


def wrapped(x: float) -> float:
    """``x`` (rad) wrapped to [-pi, pi)."""
    return (x + math.pi) % (2.0 * math.pi) - math.pi


def measure(name: str, cfg: dict, root: Path) -> dict:
    (root / f"{name}.yaml").write_text(yaml.safe_dump(cfg))
    run_rig(root / f"{name}.yaml", root / name, root / f"{name}_truth.parquet")
    t0 = time.perf_counter()
    table = accel_gamma_run(load_run(root / name))
    scale = gamma_scale_from_accel(table)
    read = harmonics_from_accel(table)
    seconds = time.perf_counter() - t0
    true_s = cfg["drive"]["gamma_scale"]
    row = {
        "rigid": not cfg["shaker"]["feedback"],
        "read_s": round(seconds, 3),
        "s_true": true_s,
        "s": scale["s"],
        "s_ci": scale["s_ci"],
        "s_rel_error": abs(scale["s"] - true_s) / true_s,
        "s_in_ci": scale["s_ci"][0] <= true_s <= scale["s_ci"][1],
        "harmonics_read": read,
    }
    truth = {int(h["k"]): h for h in cfg["drive"].get("harmonics", [])}
    row["harmonic_errors"] = {}
    for k, h in truth.items():
        got = next((r for r in read if r["k"] == k), None)
        row["harmonic_errors"][str(k)] = (
            None
            if got is None
            else {
                "a_true": h["a"],
                "a": got["a"],
                "a_rel_error": abs(got["a"] - h["a"]) / h["a"],
                "psi_true": h["psi"],
                "psi": got["psi"],
                "psi_error_rad": abs(wrapped(got["psi"] - h["psi"])),
            }
        )
    row["spurious"] = [r["k"] for r in read if r["k"] not in truth]
    if row["rigid"]:
        errs = list(row["harmonic_errors"].values())
        row["meets_goal"] = bool(
            row["s_rel_error"] <= GOALS["s_rel"]
            and not row["spurious"]
            and all(
                e is not None
                and e["a_rel_error"] <= GOALS["a_rel"]
                and e["psi_error_rad"] <= GOALS["psi_rad"]
                for e in errs
            )
        )
    return row


def main() -> dict:
    rows = {}
    with tempfile.TemporaryDirectory() as tmp:
        for name, cfg in CASES:
            rows[name] = measure(name, cfg, Path(tmp))
            r = rows[name]
            harm = "; ".join(
                f"k{k}: a {e['a']:.4f} ({100 * e['a_rel_error']:.1f} %), psi err "
                f"{e['psi_error_rad']:.3f}"
                if e
                else f"k{k}: not read"
                for k, e in r["harmonic_errors"].items()
            )
            print(
                f"{name:28s} s {r['s']:.4f} for {r['s_true']:.2f} "
                f"({100 * r['s_rel_error']:.2f} %, in interval: {r['s_in_ci']})"
                + (f"  {harm}" if harm else "")
                + (f"  spurious k {r['spurious']}" if r["spurious"] else "")
                + (f"  goal {'met' if r['meets_goal'] else 'MISSED'}" if r["rigid"] else "")
            )
    rigid = [r for r in rows.values() if r["rigid"]]
    out = {
        "goals": GOALS,
        "protocol": PROTOCOL,
        "cases": rows,
        "summary": {
            "rigid_meeting_goal": f"{sum(r['meets_goal'] for r in rigid)}/{len(rigid)}",
            "s_in_interval": f"{sum(r['s_in_ci'] for r in rows.values())}/{len(rows)}",
            "spurious_harmonics": sum(len(r["spurious"]) for r in rows.values()),
        },
        "machine": {"processor": platform.machine(), "python": platform.python_version()},
    }
    print(out["summary"])
    RESULTS.write_text(json.dumps(out, indent=1) + "\n")
    print(f"wrote {RESULTS}")
    return out


if __name__ == "__main__":
    main()
