"""Speed and memory of flight extraction on a 20-minute, 20 kHz continuity recording.

Measures (printed and written to benchmarks/results/extract.json):
- detection throughput, samples/s, once samples are decoded (target >= 1e8 on 2 cores);
- decode time of the FLAC recording (bouncelab.runs.read_recording), reported apart;
- peak resident memory of a full `extract_run` in a fresh subprocess (target < 2 GB).

The signal: a bouncing body at 30 Hz with ~40 us contacts, through a 10 us RC front
end, 2 mV noise on a 5 V swing (the rig's defaults), built with numpy at the sample
rate (fast to make; the detection cost does not depend on how it was made).

Usage: python benchmarks/bench_extract.py [--minutes 20]
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import soundfile as sf
import yaml

FS = 20_000


def make_signal(n, seed=0):
    """(n,) float32 volts: 5 V open, 0 V contact, one ~40 us contact per drive period."""
    rng = np.random.default_rng(seed)
    period = FS / 30.0
    starts = np.cumsum(rng.uniform(0.6, 1.4, size=int(n / period) + 2) * period)
    s = np.zeros(n, dtype=np.float32)
    k = starts[starts < n - 2].astype(np.int64)
    s[k] = rng.uniform(0.3, 1.0, size=k.size)  # one partial sample per contact
    q = np.exp(-1 / (10e-6 * FS))
    from scipy.signal import lfilter

    u = lfilter([1 - q], [1, -q], s).astype(np.float32) + s * q  # crude RC tail
    x = 5.0 - 5.0 * np.clip(u, 0, 1) + 0.002 * rng.standard_normal(n).astype(np.float32)
    return x.astype(np.float32)


def write_run(folder: Path, x):
    folder.mkdir(parents=True, exist_ok=True)
    sf.write(folder / "rec.flac", x / 10.0, FS, subtype="PCM_16")
    (folder / "run.yaml").write_text(
        yaml.safe_dump(
            {
                "format_version": 1,
                "kind": "sweep",
                "recording": "rec.flac",
                "sample_rate_hz": FS,
                "channels": {"continuity": 0},
                "full_scale_v": 10.0,
                "drive_frequency_hz": 30.0,
                "gamma_steps": [{"t_s": 0.0, "gamma": 3.0}],
            }
        )
    )


def peak_rss_of_extract(run_dir: Path) -> float:
    code = (
        "import resource, sys\n"
        "from bouncelab.flights import extract_run\n"
        f"f, q = extract_run({str(run_dir)!r})\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss)\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return int(out.stdout.strip().splitlines()[-1]) / 1024.0  # kB -> MB (Linux)


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=20.0)
    args = ap.parse_args()
    from bouncelab.flights import detect_contacts
    from bouncelab.runs import load_run, read_recording

    n = int(args.minutes * 60 * FS)
    x = make_signal(n)
    detect_contacts(x[: 10 * FS])  # compile / load the numba cache first
    best = np.inf
    for _ in range(3):
        t0 = time.perf_counter()
        det = detect_contacts(x)
        best = min(best, time.perf_counter() - t0)
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "bench"
        write_run(run_dir, x)
        t0 = time.perf_counter()
        rec = read_recording(load_run(run_dir), roles=("continuity",))
        decode_s = time.perf_counter() - t0
        del rec
        peak_mb = peak_rss_of_extract(run_dir)
    res = {
        "samples": n,
        "minutes": args.minutes,
        "detect_s": best,
        "detect_samples_per_s": n / best,
        "target_samples_per_s": 1e8,
        "decode_flac_s": decode_s,
        "extract_peak_rss_mb": peak_mb,
        "target_peak_mb": 2048,
        "flights": int(det.flights()[0].size),
        "self_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,
    }
    for k, v in res.items():
        print(f"{k:24s} {v:.4g}" if isinstance(v, float) else f"{k:24s} {v}")
    out = Path(__file__).parent / "results" / "extract.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
