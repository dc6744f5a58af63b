"""``bouncelab calibrate`` on drop tests of the compliant-contact generator.

The drop tests the workflow calibrates against are the virtual rig's; ``compliant_rig.py``
(beside this file) makes them another way: the body released from rest above a still
plate, Coulomb friction on the guide, a Kelvin-Voigt contact whose damping makes the
restitution (so no impact map, and each contact lasts its 85-900 us). Each case is
written in a temporary folder, calibrated from the run folder alone, and only then scored
against the generator's truth: the relative errors of ``mu`` and ``e`` and whether the
95 % intervals hold the truth.

The truth's ``e`` is the contact's own, for a body arriving at 0.5 m/s without gravity.
Gravity and friction act during the contact too, so at the last bounces' speeds (5 cm/s)
the rebound loses a little more: a drop test of a real body sees the same.

Measures, prints and writes ``benchmarks/results/compliant_drop.json``.
Run: ``python benchmarks/bench_compliant_drop.py [--only NAME ...]``.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import tempfile
import time
from pathlib import Path

from bouncelab.calibration import calibrate_run

sys.path.insert(0, str(Path(__file__).resolve().parent))
from compliant_rig import make_drop  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "compliant_drop.json"

#: the goal of the parameters (issue 6's 15 %, the same for the drop test)
GOAL = 0.15

CASES = {
    "seed_rig": {},  # the seed's values: mu 0.29, e 0.515, 5 cm
    "low_friction_high_e": {"mu": 0.05, "e": 0.8, "h": 0.03, "seed": 2},
    "high_friction_low_e": {"mu": 0.45, "e": 0.4, "h": 0.1, "seed": 3},
    "no_friction": {"mu": 0.0, "e": 0.6, "seed": 4},
    "soft_pad_1ms": {"mu": 0.29, "e": 0.5, "contact_s": 1e-3, "seed": 5},
    "csv_44khz": {"mu": 0.2, "e": 0.55, "fs": 44100.0, "format": "csv", "seed": 6},
    # white noise of 0.15 V on the 2.5-V gap (17 sigmas; below 10 the detection refuses
    # the channel, docs/flights.md "Detection": at 0.3 V, "no contacts found ... 8.3")
    "noisy": {"mu": 0.25, "e": 0.5, "noise_v": 0.15, "seed": 7},
    "late_release_10cm": {"mu": 0.29, "e": 0.515, "h": 0.1, "release_t_s": 0.73, "seed": 8},
}


def score(truth: dict, cal: dict) -> dict:
    """Relative errors of ``mu`` (absolute where the truth is 0) and ``e``, and whether
    each 95 % interval holds the truth."""
    mu, e = truth["mu"], truth["e"]
    return {
        "mu": cal["mu"],
        "e": cal["restitution"],
        "mu_error": abs(cal["mu"] - mu) / mu if mu else abs(cal["mu"] - mu),
        "e_error": abs(cal["restitution"] - e) / e,
        "mu_in_ci": cal["mu_ci"][0] <= mu <= cal["mu_ci"][1],
        "e_in_ci": cal["restitution_ci"][0] <= e <= cal["restitution_ci"][1],
        "n_bounces": cal["n_bounces"],
        "true_mu": mu,
        "true_e": e,
        "contact_time_s": truth["contact_time_s"],
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=None)
    args = p.parse_args()
    names = args.only or list(CASES)
    record = json.loads(OUT.read_text()) if OUT.exists() and args.only else {"cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            run_dir = Path(tmp) / name
            truth = make_drop(run_dir, **CASES[name])
            t0 = time.perf_counter()
            cal = calibrate_run(run_dir)
            s = score(truth, cal) | {"calibrate_s": time.perf_counter() - t0}
            record["cases"][name] = s
            print(
                f"{name:22s} mu {s['mu']:.4f} (true {s['true_mu']:.3f}, "
                f"{'in' if s['mu_in_ci'] else 'OUT of'} CI), e {s['e']:.4f} (true "
                f"{s['true_e']:.3f}, {100 * s['e_error']:.2f} %, "
                f"{'in' if s['e_in_ci'] else 'OUT of'} CI), {s['n_bounces']} bounces",
                flush=True,
            )
    cases = record["cases"].values()
    record["summary"] = {
        "cases": len(record["cases"]),
        "within_goal": sum(c["mu_error"] <= GOAL and c["e_error"] <= GOAL for c in cases),
        "max_mu_error": max(c["mu_error"] for c in cases),
        "max_e_error": max(c["e_error"] for c in cases),
        "mu_in_ci": sum(c["mu_in_ci"] for c in cases),
        "e_in_ci": sum(c["e_in_ci"] for c in cases),
    }
    record["machine"] = {"cpus": platform.machine(), "python": platform.python_version()}
    OUT.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    print(json.dumps(record["summary"]))


if __name__ == "__main__":
    main()
