"""Benchmark: reading long recordings with ``bouncelab.runs.read_recording``.

Goal (issue 3): a 20-minute, 20 kHz, 3-channel recording reads with a peak memory
well under 2 GB, i.e. without several copies of it. Measured here for FLAC and WAV at
full size; CSV, NPZ and TDMS at 2 minutes (their readers scale linearly).

Each read runs in a fresh Python process, so the peak resident memory (``VmHWM`` of
``/proc/self/status``, Linux) is that of the read alone plus the interpreter and
imports (``baseline_rss_mb``, measured the same way without reading).

    python benchmarks/runs_read.py [--minutes 20] [--other-minutes 2]

Prints a table and writes ``benchmarks/results/runs_read.json``.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
import soundfile as sf
import yaml

FS = 20_000
DRIVE_HZ = 30.0
BLOCK = 1 << 20
RESULTS = Path(__file__).parent / "results" / "runs_read.json"

CHILD = r"""
import json, sys, time
from bouncelab.runs import load_run, read_recording
run = load_run(sys.argv[1])
t0 = time.perf_counter()
rec = read_recording(run) if sys.argv[2] == "read" else None
dt = time.perf_counter() - t0
out = sum(a.nbytes for a in rec.channels.values()) if rec else 0
# VmHWM: this process's peak resident memory; unlike ru_maxrss it is not inherited
# from the parent across fork + exec
hwm = [l for l in open("/proc/self/status") if l.startswith("VmHWM:")][0]
peak = int(hwm.split()[1]) / 1024
print(json.dumps({"read_s": dt, "peak_rss_mb": peak, "output_mb": out / 2**20}))
"""


def block_signals(i0: int, n: int, rng: np.random.Generator) -> np.ndarray:
    """Frames i0..i0+n of a continuity square wave, drive sine and noisy accel, (n, 3) V."""
    t = (i0 + np.arange(n)) / FS
    phase = 2 * np.pi * DRIVE_HZ * t
    cont = np.where(np.sin(phase) > 0.2, 0.02, 0.9) + 0.002 * rng.standard_normal(n)
    return np.stack(
        [cont, 0.7 * np.sin(phase), 0.3 * np.sin(phase + 0.3) + 0.05 * rng.standard_normal(n)],
        axis=1,
    )


def write_run(folder: Path, fmt: str, minutes: float) -> None:
    """A run folder with a 3-channel recording of ``minutes`` in format ``fmt``."""
    folder.mkdir(parents=True)
    n = int(minutes * 60 * FS)
    rng = np.random.default_rng(0)
    rec = folder / f"rec.{fmt}"
    if fmt in ("flac", "wav"):
        with sf.SoundFile(rec, "w", FS, 3, subtype="PCM_16", format=fmt.upper()) as f:
            for i0 in range(0, n, BLOCK):
                f.write(block_signals(i0, min(BLOCK, n - i0), rng))
        channels = {"continuity": 0, "drive": 1, "accel": 2}
    else:
        data = block_signals(0, n, rng)
        names = ["cont_v", "drive_v", "accel_v"]
        if fmt == "csv":
            pd.DataFrame(data, columns=names).to_csv(rec, index=False, float_format="%.6g")
        elif fmt == "npz":
            with open(rec, "wb") as f:
                np.savez(f, **{k: data[:, j] for j, k in enumerate(names)})
        else:
            from nptdms import ChannelObject, TdmsWriter

            with TdmsWriter(str(rec)) as w:
                w.write_segment(
                    [ChannelObject("rig", k, data[:, j].copy()) for j, k in enumerate(names)]
                )
            names = [f"rig/{k}" for k in names]
        channels = dict(zip(("continuity", "drive", "accel"), names, strict=True))
    doc = {
        "format_version": 1,
        "kind": "sweep",
        "recording": rec.name,
        "sample_rate_hz": FS,
        "channels": channels,
        "drive_frequency_hz": DRIVE_HZ,
        "gamma_steps": [{"t_s": 2.0 * i, "gamma": 0.1 * i} for i in range(int(minutes * 30))],
        "source": "synthetic",
    }
    (folder / "run.yaml").write_text(yaml.safe_dump(doc))


def child(run_dir: Path, mode: str) -> dict:
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(run_dir), mode],
        capture_output=True,
        text=True,
        check=True,
    )
    return json.loads(out.stdout)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, default=20.0, help="FLAC/WAV length")
    ap.add_argument("--other-minutes", type=float, default=2.0, help="CSV/NPZ/TDMS length")
    args = ap.parse_args()
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        for fmt in ("flac", "wav", "csv", "npz", "tdms"):
            minutes = args.minutes if fmt in ("flac", "wav") else args.other_minutes
            folder = Path(tmp) / f"bench_{fmt}"
            t0 = time.perf_counter()
            write_run(folder, fmt, minutes)
            write_s = time.perf_counter() - t0
            base = child(folder, "none")
            res = child(folder, "read")
            size_mb = (folder / f"rec.{fmt}").stat().st_size / 2**20
            row = {
                "format": fmt,
                "minutes": minutes,
                "channels": 3,
                "sample_rate_hz": FS,
                "file_mb": round(size_mb, 1),
                "write_s": round(write_s, 2),
                "read_s": round(res["read_s"], 3),
                "times_real_time": round(minutes * 60 / res["read_s"], 1),
                "output_mb": round(res["output_mb"], 1),
                "baseline_rss_mb": round(base["peak_rss_mb"], 1),
                "peak_rss_mb": round(res["peak_rss_mb"], 1),
                "peak_over_output": round(
                    (res["peak_rss_mb"] - base["peak_rss_mb"]) / res["output_mb"], 2
                ),
            }
            rows.append(row)
            print(
                f"{fmt:5s} {minutes:5.1f} min  file {row['file_mb']:7.1f} MB  read "
                f"{row['read_s']:7.2f} s ({row['times_real_time']:6.0f}x real time)  "
                f"output {row['output_mb']:6.1f} MB  peak RSS {row['peak_rss_mb']:7.1f} MB "
                f"(baseline {row['baseline_rss_mb']:.0f} MB; extra/output "
                f"{row['peak_over_output']:.2f})",
                flush=True,
            )
    RESULTS.parent.mkdir(parents=True, exist_ok=True)
    RESULTS.write_text(
        json.dumps(
            {
                "benchmark": "runs_read",
                "goal": "20 min x 20 kHz x 3 channels read with peak memory well under 2 GB",
                "note": "measured on a shared 2-core machine; timings are disturbed",
                "results": rows,
            },
            indent=2,
        )
        + "\n"
    )
    print(f"wrote {RESULTS}")


if __name__ == "__main__":
    main()
