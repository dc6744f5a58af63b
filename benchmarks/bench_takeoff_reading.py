"""The takeoff reading (``bouncelab.gap.takeoff_reading``) on the independent generator's
recordings, beside their truth.

For every case of ``bench_independent.py``: generate the recording, extract its flights,
read the takeoff phases (no simulation), and score the reading against the truth: the
harmonic's ``k``, ``a``, ``psi`` where the case has one, the guide's ``mu`` where it has
friction, and, for every case, how much better a harmonic fits the takeoffs than none
(``rms_ratio``: plain rms over the best harmonic's). The truth is read only after the
reading. Prints a line per case and writes ``benchmarks/results/takeoff_reading.json``.

    python benchmarks/bench_takeoff_reading.py [--only NAME ...] [--work DIR]

``--work DIR`` keeps the recordings in ``DIR`` and reuses those already there (the
reading is quick; the generator takes most of the 10 minutes).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_independent import CASES  # noqa: E402
from independent_rig import make_case  # noqa: E402

from bouncelab.flights import extract_run  # noqa: E402
from bouncelab.gap.takeoff_reading import (  # noqa: E402
    SEEN_AK2,
    SEEN_RATIO,
    read_takeoffs,
    ride_takeoffs,
    seen_harmonic,
)
from bouncelab.runs import load_run  # noqa: E402

OUT = Path(__file__).resolve().parent / "results" / "takeoff_reading.json"


def seen(case: dict) -> bool:
    """Whether the reading's best harmonic stands out: the diagnosis's rule
    (:func:`bouncelab.gap.takeoff_reading.seen_harmonic`) on a scored case."""
    return "best" in case and seen_harmonic(case) is not None


def score(truth: dict, reading: dict) -> dict:
    """The reading against the generator's truth: ``k_right``, relative error of ``a``,
    error of ``psi`` (rad, wrapped) where the truth has a harmonic; absolute error of the
    best harmonic fit's ``mu`` and the plain fit's where it has friction."""
    out: dict = {"n_steps": reading["n_steps"]}
    if "best" not in reading:
        return out
    best, plain = reading["best"], reading["plain"]
    out["best"] = best
    out["plain"] = plain
    out["rms_ratio"] = plain["rms_rad"] / max(best["rms_rad"], 1e-12)
    eff = truth["effects"]
    if "harmonic" in eff:
        h = eff["harmonic"]
        out["k_right"] = best["k"] == float(h["k"])
        out["a_rel_error"] = abs(best["a"] / h["a"] - 1.0)
        out["psi_error_rad"] = abs((best["psi"] - h["psi"] + math.pi) % (2 * math.pi) - math.pi)
    if "friction" in eff:
        out["mu_error_best"] = abs(best["mu"] - eff["friction"]["mu"])
        out["mu_error_plain"] = abs(plain["mu"] - eff["friction"]["mu"])
    return out


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=None)
    p.add_argument("--work", type=Path, default=None, help="keep and reuse the recordings here")
    args = p.parse_args()
    names = args.only or list(CASES)
    record = json.loads(OUT.read_text()) if OUT.exists() and args.only else {"cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        for name in names:
            run_dir = (args.work or Path(tmp)) / name
            if not run_dir.with_name(name + ".truth.json").exists():
                make_case(run_dir, **CASES[name])
            flights, _qc = extract_run(run_dir)
            t0 = time.perf_counter()
            reading = read_takeoffs(
                ride_takeoffs(flights, float(load_run(run_dir).drive_frequency_hz))
            )
            dt = time.perf_counter() - t0
            truth = json.loads(run_dir.with_name(name + ".truth.json").read_text())
            s = score(truth, reading) | {
                "true": sorted(truth["effects"]),
                "outside": truth["outside"],
                "read_s": dt,
            }
            record["cases"][name] = s
            b = s.get("best", {})
            print(
                f"{name:44s} {s['n_steps']:3d} steps; best k {b.get('k')} a {b.get('a', 0):.4f} "
                f"psi {b.get('psi', 0):.3f} mu {b.get('mu', 0):.3f}; rms ratio "
                f"{s.get('rms_ratio', float('nan')):.2f}; true {s['true']}; {dt:.1f} s",
                flush=True,
            )
    cases = record["cases"].values()
    harm = [c for c in cases if "k_right" in c]
    fric = [c for c in cases if "mu_error_plain" in c and "feedback" not in c["true"]]
    record["summary"] = {
        "cases": len(record["cases"]),
        "harmonic_cases": len(harm),
        "k_right": sum(c["k_right"] for c in harm),
        "a_within_10pct": sum(c["a_rel_error"] <= 0.1 for c in harm),
        "psi_within_0.1rad": sum(c["psi_error_rad"] <= 0.1 for c in harm),
        "friction_cases_without_armature": len(fric),
        "mu_within_0.02": sum(min(c["mu_error_best"], c["mu_error_plain"]) <= 0.02 for c in fric),
        "max_read_s": max(c["read_s"] for c in cases),
        # the diagnosis's rule (takeoff_reading.seen_harmonic): a harmonic "seen" where it
        # carries at least SEEN_AK2 of the plate's acceleration and fits SEEN_RATIO times better
        "seen_rule": {"a_k2": SEEN_AK2, "rms_ratio": SEEN_RATIO},
        "seen_in_harmonic_cases": sum(seen(c) for c in harm),
        "seen_in_other_library_cases": sorted(
            n
            for n, c in record["cases"].items()
            if seen(c) and "harmonic" not in c["true"] and not c["outside"]
        ),
        "seen_in_outside_cases": sorted(
            n for n, c in record["cases"].items() if seen(c) and c["outside"]
        ),
    }
    OUT.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    print(json.dumps(record["summary"]))


if __name__ == "__main__":
    main()
