"""Speed and memory of flight extraction on a 20-minute, 20 kHz continuity recording.

Measures (printed and written to benchmarks/results/extract.json):
- detection throughput, samples/s, of ``detect_contacts`` on the decoded samples (float32
  volts, as the FLAC reader gives them), on numba's thread count (target >= 1e8 on
  2 cores), best and median of several repetitions, and its CPU time; the same on one
  thread;
- the same on a harder signal where the RC constant is not measurable, so its estimate
  scans the whole recording instead of the first 100 s (``worst_*``);
- the same with a 50 Hz mains hum of 5 % of the swing added, which the detection finds
  and subtracts first (``hum_*``; docs/flights.md, "Interference"); every detection is
  given the sampling rate, as ``extract_run`` gives it, so the hum gate is timed too;
- decode time of the FLAC recording (``bouncelab.runs.read_recording``), reported apart;
- peak resident memory of a full ``extract_run`` in a fresh subprocess (target < 2 GB).

The signal (``make_signal``): a body bouncing at 30 Hz, one event per drive period:
a short contact (20-60 us), a restitution chatter sequence (flights halving from 2 ms
to 0.1 ms, then a rest of 2-8 ms) or a sticking contact (1-10 ms); sampled exactly
through the rig's RC front end (10 us), 2 mV noise and 10 mV drift on a 5 V swing
(the rig's defaults, config/rig/*.yaml).

Usage: python benchmarks/bench_extract.py [--minutes 20] [--repeat 7]
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numba
import numpy as np
import soundfile as sf
import yaml
from scipy.signal import lfilter

FS = 20_000
DRIVE_HZ = 30.0


def make_contacts(duration_s, rng):
    """Contact intervals (s) of a bouncing body: (m, 2) array, sorted, disjoint."""
    out = []
    period = 1.0 / DRIVE_HZ
    t = 0.01
    while t < duration_s - 0.05:
        kind = rng.random()
        if kind < 0.6:  # bouncing region: one short contact
            d = rng.uniform(20e-6, 60e-6)
            out.append((t, t + d))
        elif kind < 0.85:  # restitution chatter, then a rest on the plate
            s, f = t, rng.uniform(1e-3, 2e-3)
            while f > 0.1e-3:
                d = rng.uniform(20e-6, 60e-6)
                out.append((s, s + d))
                s += d + f
                f *= 0.5
            out.append((s, s + rng.uniform(2e-3, 8e-3)))
        else:  # sticking region: a long contact
            out.append((t, t + rng.uniform(1e-3, 10e-3)))
        t = out[-1][1] + period * rng.uniform(0.5, 1.0)
    return np.asarray(out)


def rc_sampled(contacts_samples, n, q):
    """Switch (1 in contact) through a first-order RC (``q = exp(-1/tau)``, tau in
    samples), sampled at integer times: (n,) exact values, 0 open .. 1 contact.

    ``c[k]`` is what the switch adds over the interval ``(k-1, k]``:
    ``integral of exp(-(k-t)/tau)/tau dt`` over the part of the interval in contact, and
    ``u[k] = q u[k-1] + c[k]``.
    """
    tau = -1.0 / np.log(q)
    a, b = contacts_samples[:, 0], contacts_samples[:, 1]
    ka, kb = np.ceil(a).astype(np.int64), np.ceil(b).astype(np.int64)
    c = np.zeros(n + 2)
    one = ka == kb  # contact inside one interval
    np.add.at(c, ka[one], np.exp(-(ka[one] - b[one]) / tau) - np.exp(-(ka[one] - a[one]) / tau))
    m = ~one
    np.add.at(c, ka[m], 1.0 - np.exp(-(ka[m] - a[m]) / tau))
    np.add.at(c, kb[m], np.exp(-(kb[m] - b[m]) / tau) - q)
    full = np.zeros(n + 3)  # intervals ka+1 .. kb-1 wholly in contact
    np.add.at(full, ka[m] + 1, 1.0)
    np.add.at(full, kb[m], -1.0)
    c += np.cumsum(full)[: n + 2] * (1.0 - q)
    return lfilter([1.0], [1.0, -q], c[:n])


def make_signal(n, seed=0, tau_s=10e-6, measurable_rc=True):
    """(n,) float32 volts: 5 V open, 0 V contact, rig-default RC, noise and drift.

    ``measurable_rc=False`` gives the old benchmark's signal instead: one-sample contacts
    only (no clean edge to measure the RC from)."""
    rng = np.random.default_rng(seed)
    duration = n / FS
    if measurable_rc:
        cont = make_contacts(duration, rng) * FS
    else:
        starts = np.cumsum(rng.uniform(0.6, 1.4, size=int(duration * DRIVE_HZ) + 2) * FS / 30)
        starts = starts[starts < n - 3]
        cont = np.stack([starts, starts + rng.uniform(0.3, 1.0, starts.size)], axis=1)
    u = rc_sampled(cont[cont[:, 1] < n - 1], n, np.exp(-1.0 / (tau_s * FS)))
    t = np.arange(n) / FS
    drift = 0.01 * np.sin(2 * np.pi * t / max(duration, 1e-9) * 0.7 + 0.3)
    x = 5.0 - 5.0 * u + drift + 0.002 * rng.standard_normal(n)
    return x.astype(np.float32)


def write_run(folder: Path, x):
    """A sweep run folder (FLAC, full scale 10 V) holding the continuity channel ``x``."""
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
                "drive_frequency_hz": DRIVE_HZ,
                "gamma_steps": [{"t_s": 0.0, "gamma": 3.0}],
            }
        )
    )


def peak_rss_of_extract(run_dir: Path) -> tuple[float, int]:
    """Peak RSS (MB) of a fresh process running ``extract_run`` and its flight count.

    The peak is the child's own ``VmHWM`` (Linux): ``getrusage``'s ``ru_maxrss`` would
    also count the parent's resident memory at the fork.
    """
    code = (
        "from bouncelab.flights import extract_run\n"
        f"f, q = extract_run({str(run_dir)!r})\n"
        "hwm = [ln for ln in open('/proc/self/status') if ln.startswith('VmHWM')][0]\n"
        "print(len(f), hwm.split()[1])\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    n_flights, rss_kb = out.stdout.strip().splitlines()[-1].split()
    return int(rss_kb) / 1024.0, int(n_flights)  # kB -> MB


def timed(fn, repeat, cpu=None):
    """Wall-clock seconds of ``repeat`` calls (after one warm call) and the last result;
    the process CPU seconds of each call (all threads) are appended to ``cpu``."""
    res = fn()
    times = []
    for _ in range(repeat):
        c0 = time.process_time()
        t0 = time.perf_counter()
        res = fn()
        times.append(time.perf_counter() - t0)
        if cpu is not None:
            cpu.append(time.process_time() - c0)
    return times, res


def main() -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("--minutes", type=float, default=20.0)
    ap.add_argument("--repeat", type=int, default=7)
    args = ap.parse_args()
    from bouncelab.flights import detect_contacts
    from bouncelab.runs import load_run, read_recording

    n = int(args.minutes * 60 * FS)
    threads = numba.get_num_threads()
    res = {"samples": n, "minutes": args.minutes, "threads": threads}
    with tempfile.TemporaryDirectory() as tmp:
        run_dir = Path(tmp) / "bench"
        write_run(run_dir, make_signal(n))
        run = load_run(run_dir)
        dec, rec = timed(lambda: read_recording(run, roles=("continuity",)), 3)
        x = rec.channels["continuity"]  # decoded samples, float32 volts
        del rec
        detect_contacts(x[: 10 * FS], sample_rate_hz=FS)  # load the numba cache first
        det_cpu = []
        det_t, det = timed(lambda: detect_contacts(x, sample_rate_hz=FS), args.repeat, det_cpu)
        one_t, _ = timed(
            lambda: detect_contacts(x, n_threads=1, sample_rate_hz=FS), max(3, args.repeat // 2)
        )
        worst = make_signal(n, seed=1, measurable_rc=False)
        worst_t, _ = timed(
            lambda: detect_contacts(worst, sample_rate_hz=FS), max(3, args.repeat // 2)
        )
        hummed = x + np.float32(0.25) * np.sin(2 * np.pi * 50.0 * np.arange(n) / FS).astype(
            np.float32
        )
        hum_t, hum_det = timed(lambda: detect_contacts(hummed, sample_rate_hz=FS), 3)
        peak_mb, n_flights = peak_rss_of_extract(run_dir)
    res |= {
        "detect_s_best": min(det_t),
        "detect_s_median": statistics.median(det_t),
        "detect_samples_per_s_best": n / min(det_t),
        "detect_samples_per_s_median": n / statistics.median(det_t),
        # CPU seconds of all threads per detection: less sensitive to other load; on an
        # otherwise idle machine the wall time is at least this over the thread count
        "detect_cpu_s_best": min(det_cpu),
        "detect_cpu_s_median": statistics.median(det_cpu),
        "detect_1thread_samples_per_s_best": n / min(one_t),
        "detect_1thread_samples_per_s_median": n / statistics.median(one_t),
        "worst_detect_samples_per_s_best": n / min(worst_t),
        "worst_detect_samples_per_s_median": n / statistics.median(worst_t),
        "hum_detect_samples_per_s_best": n / min(hum_t),
        "hum_flights_share_of_clean": hum_det.flights()[0].shape[0] / det.flights()[0].shape[0],
        "target_samples_per_s": 1e8,
        "decode_flac_s_best": min(dec),
        "decode_flac_s_median": statistics.median(dec),
        "extract_peak_rss_mb": peak_mb,
        "target_peak_mb": 2048,
        "flights": n_flights,
        "edges": int(det.t_edge.size),
        "tau_rc_us": det.tau_samples / FS * 1e6,
        "repeat": args.repeat,
    }
    for k, v in res.items():
        print(f"{k:36s} {v:.4g}" if isinstance(v, float) else f"{k:36s} {v}")
    out = Path(__file__).parent / "results" / "extract.json"
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(res, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
