"""Flight extraction on recordings with a real lab's faults, against the virtual rig's truth.

Black-box probes of the contract (sessions 68-69) found faults that only show on signals
our rig does not make. This benchmark keeps them measured: each case is a virtual-rig
sweep (an inelastic body, e 0, which rests and rides, or a bouncing one, e 0.5; Gamma
0.5-4.2 in 7 steps of 60 cycles) with one fault of a lab's signal chain applied, and its
flights are scored against the rig's truth:

- ``rc_100us``, ``rc_250us``: a front end slower than the sampling (a pull-up with a
  filter capacitor; 2 and 5 samples at 20 kHz), made by the rig itself;
- ``gain_0.4``, ``shift_20pct``, ``gain_0.35_offset_hum``: the channel's gain or offset
  changed at 55 % of the recording (an amplifier knob, a supply), the last under a 50 Hz
  hum of 2 % of the original gap;
- ``hum_5pct``: a 50 Hz hum of 5 % of the gap, with its third harmonic;
- ``dropouts_12``: the circuit opening for 2-3 samples at 12 random instants inside
  contacts of at least 3 ms (a dirty contact);
- ``soundcard_fir``, ``soundcard_fir_ac2hz`` (44.1 kHz): a linear-phase anti-alias filter
  (127 taps, cut at 0.9 of Nyquist: its edges ring) on both channels, then a 2 Hz AC
  coupling; its 63-sample delay is taken off the truth;
- ``ac_coupled_*``: both channels through a first-order high-pass of 0.5-20 Hz (a sound
  card's AC-coupled input).

Scores per case: true flights over 1 ms and the share found (both edges within 0.3 ms),
flights in the table that match no true flight of any length (``spurious``), median and
95th percentile of the flight-time error of the found ones (us), non-positive flights,
the change of the takeoff phases against the unchanged recording's table (mrad), and
the warnings ``extract`` gave. Prints a line per case and writes
``benchmarks/results/lab_artefacts.json``.

    python benchmarks/bench_lab_artefacts.py [--work DIR] [--only CASE ...] [--jump-grid]
        [--hum-grid]

``--jump-grid`` runs 50 gain and offset steps instead (five instants, five changes, with
and without a 2 % hum; ``lab_artefacts_jump_grid.json``). ``--hum-grid`` runs 144 mains
hums (3-18 % of the swing, 50 or 60 Hz, on both levels or the open one only, 10 or 100 us
front ends at 8-44.1 kHz, both bodies; ``lab_artefacts_hum_grid.json``, about 6 minutes);
the recordings without hum are scored too (``base_*``), as the reference.

About a minute on 2 cores. The recordings are made in a temporary folder (or ``--work``,
where those already there are reused).
"""

from __future__ import annotations

import argparse
import json
import logging
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml
from scipy import signal

from bouncelab.flights import extract_run
from bouncelab.rig import read_truth, run_rig
from bouncelab.runs import load_run, read_recording

OUT = Path(__file__).resolve().parent / "results" / "lab_artefacts.json"
TOL_S = 0.3e-3  # both edges of a found flight within this of the truth's
FIR_TAPS = 127


def rig_config(e: float, fs: float, rc_s: float) -> dict:
    """A virtual-rig sweep: restitution ``e``, sampling ``fs`` Hz, RC front end ``rc_s``."""
    return {
        "kind": "sweep",
        "seed": 3,
        "body": {"restitution": e},
        "protocol": {"gammas": [0.5, 1.2, 1.6, 2.2, 2.8, 3.4, 4.2], "cycles_per_step": 60},
        "recording": {"sample_rate_hz": fs},
        "sensors": {"continuity": {"rc_time_s": rc_s}},
    }


def jump(gain: float, offset_v: float, hum_share: float = 0.0, at: float = 0.55):
    """A change of the continuity channel's gain and offset at ``at`` of the recording."""

    def apply(cont, drive, fs, rng):
        x = cont.copy()
        k = int(at * x.shape[0])
        x[k:] = x[k:] * gain + offset_v
        return x + hum_share * np.ptp(cont) * hum(x.shape[0], fs), drive

    return apply


def hum(n: int, fs: float, third: float = 0.0) -> np.ndarray:
    """A unit 50 Hz sine with ``third`` of its third harmonic, shape (n,)."""
    t = np.arange(n) / fs
    return np.sin(2 * np.pi * 50.0 * t + 0.3) + third * np.sin(6 * np.pi * 50.0 * t)


def with_hum(cont, drive, fs, rng):
    return cont + 0.05 * np.ptp(cont) * hum(cont.shape[0], fs, third=0.3), drive


def dropouts(cont, drive, fs, rng, count=12):
    """The circuit opening for 2-3 samples inside contacts of at least 3 ms."""
    x = cont.copy()
    lo, hi = np.percentile(x, [1, 99])
    width = int(3e-3 * fs)
    held = np.convolve(x < 0.5 * (lo + hi), np.ones(width), "same") >= width
    for k in rng.choice(np.flatnonzero(held), size=count, replace=False):
        x[k : k + 2 + k % 2] = hi
    return x, drive


def soundcard(ac_hz: float | None):
    """A linear-phase anti-alias FIR on both channels, then optionally an AC coupling."""

    def apply(cont, drive, fs, rng):
        taps = signal.firwin(FIR_TAPS, 0.9)
        out = []
        for ch in (cont, drive):
            y = signal.lfilter(taps, 1.0, ch)
            if ac_hz:
                b, a = signal.butter(1, ac_hz / (fs / 2), "high")
                y = signal.lfilter(b, a, y)
            out.append(y)
        return out[0], out[1]

    return apply


def ac_coupled(corner_hz: float):
    """Both channels through a first-order high-pass (a sound card's AC coupling)."""

    def apply(cont, drive, fs, rng):
        b, a = signal.butter(1, corner_hz / (fs / 2), "high")
        return signal.lfilter(b, a, cont), signal.lfilter(b, a, drive)

    return apply


#: case -> (e, fs, rc_s, fault or None, truth delay in samples)
CASES = {
    "clean_e0": (0.0, 20_000.0, 10e-6, None, 0),
    "clean_e0.5": (0.5, 20_000.0, 10e-6, None, 0),
    "rc_100us_e0": (0.0, 20_000.0, 100e-6, None, 0),
    "rc_100us_e0.5": (0.5, 20_000.0, 100e-6, None, 0),
    "rc_250us_e0": (0.0, 20_000.0, 250e-6, None, 0),
    "gain_0.4_e0.5": (0.5, 20_000.0, 10e-6, jump(0.4, 0.0), 0),
    "shift_20pct_e0.5": (0.5, 20_000.0, 10e-6, jump(1.0, -1.0), 0),
    "gain_0.35_offset_hum_e0.5": (0.5, 20_000.0, 10e-6, jump(0.35, 0.5, 0.02), 0),
    "hum_5pct_e0.5": (0.5, 20_000.0, 10e-6, with_hum, 0),
    "dropouts_12_e0": (0.0, 20_000.0, 10e-6, dropouts, 0),
    "soundcard_fir_e0": (0.0, 44_100.0, 10e-6, soundcard(None), FIR_TAPS // 2),
    "soundcard_fir_e0.5": (0.5, 44_100.0, 10e-6, soundcard(None), FIR_TAPS // 2),
    "soundcard_fir_ac2hz_e0.5": (0.5, 44_100.0, 10e-6, soundcard(2.0), FIR_TAPS // 2),
    "ac_coupled_0.5hz_e0": (0.0, 20_000.0, 10e-6, ac_coupled(0.5), 0),
    "ac_coupled_2hz_e0.5": (0.5, 20_000.0, 10e-6, ac_coupled(2.0), 0),
    "ac_coupled_20hz_e0.5": (0.5, 20_000.0, 10e-6, ac_coupled(20.0), 0),
}


def jump_grid() -> dict:
    """``--jump-grid``: gain and offset steps at five instants (in flight or in contact),
    five changes, with and without a 2 % hum, on the bouncing body (50 cases)."""
    changes = {
        "gain0.5": (0.5, 0.0), "gain0.7_off0.2": (0.7, 0.2), "gain1.4": (1.4, 0.0),
        "shift20pct": (1.0, -1.0), "gain0.35_off0.5": (0.35, 0.5),
    }  # fmt: skip
    cases = {}
    for at in (0.27, 0.41, 0.55, 0.72, 0.86):
        for name, (gain, offset) in changes.items():
            for hum_share in (0.0, 0.02):
                key = f"jump{at:g}_{name}_hum{hum_share:g}"
                cases[key] = (0.5, 20_000.0, 10e-6, jump(gain, offset, hum_share, at), 0)
    return cases


def mains(share: float, f_hz: float, third: float, open_only: bool):
    """A mains hum of ``share`` of the channel's swing at ``f_hz`` with ``third`` of its
    third harmonic; ``open_only``: picked up in proportion to how open the circuit is
    (the front end's own state: 0 in contact, 1 open), as a high-impedance open circuit
    picks it up and a closed one does not."""

    def apply(cont, drive, fs, rng):
        t = np.arange(cont.shape[0]) / fs
        h = (
            share
            * np.ptp(cont)
            * (np.sin(2 * np.pi * f_hz * t + 0.3) + third * np.sin(6 * np.pi * f_hz * t + 1.1))
        )
        if open_only:  # the rig's contact level is the low one
            lo, hi = np.percentile(cont, [1, 99])
            h = h * np.clip((cont - lo) / (hi - lo), 0.0, 1.0)
        return cont + h, drive

    return apply


def hum_grid() -> dict:
    """``--hum-grid``: mains hum of 3, 10 and 18 % of the swing, 50 Hz or 60 Hz with a
    third harmonic of 0.3, on both levels or on the open level only, through a fast
    (10 us) or slow (100 us) front end at 8, 20 and 44.1 kHz, on the inelastic and the
    bouncing body (144 cases, and the 12 recordings without hum; the rig's drive is 30 Hz,
    so a 60 Hz hum is locked to it)."""
    cases = {}
    for e in (0.0, 0.5):
        for fs in (8_000.0, 20_000.0, 44_100.0):
            for rc_s in (10e-6, 100e-6):
                cases[f"base_e{e:g}_fs{fs:g}_rc{rc_s * 1e6:g}"] = (e, fs, rc_s, None, 0)
                for share in (0.03, 0.1, 0.18):
                    for f_hz, third in ((50.0, 0.0), (60.0, 0.3)):
                        for open_only in (False, True):
                            key = f"e{e:g}_fs{fs:g}_rc{rc_s * 1e6:g}_hum{share:g}_{f_hz:g}Hz" + (
                                "_open" if open_only else ""
                            )
                            cases[key] = (e, fs, rc_s, mains(share, f_hz, third, open_only), 0)
    return cases


def base_run(work: Path, e: float, fs: float, rc_s: float) -> tuple[Path, Path]:
    """The rig's recording for ``(e, fs, rc_s)`` and its truth, made once."""
    name = f"rig_e{e:g}_fs{fs:g}_rc{rc_s * 1e6:g}us"
    run_dir, truth = work / name, work / f"{name}.truth.parquet"
    if not run_dir.exists():
        cfg = work / f"{name}.yaml"
        cfg.write_text(yaml.safe_dump(rig_config(e, fs, rc_s)))
        run_rig(cfg, run_dir, truth)
    return run_dir, truth


def faulty_run(base: Path, out: Path, fault, seed: int) -> Path:
    """``base`` with ``fault`` applied to its channels, written as an NPZ run."""
    run, rec = load_run(base), read_recording(base)
    cont, drive = fault(
        rec.channels["continuity"], rec.channels["drive"], rec.fs, np.random.default_rng(seed)
    )
    out.mkdir(parents=True, exist_ok=True)
    np.savez(out / "rec.npz", continuity=cont, drive=drive)
    spec = {
        "format_version": 1,
        "kind": "sweep",
        "recording": "rec.npz",
        "sample_rate_hz": rec.fs,
        "channels": {"continuity": "continuity", "drive": "drive"},
        "drive_frequency_hz": run.drive_frequency_hz,
        "settle_cycles": run.settle_cycles,
        "gamma_steps": [{"t_s": t, "gamma": g} for t, g in run.gamma_steps],
        "source": "synthetic",
    }
    (out / "run.yaml").write_text(yaml.safe_dump(spec))
    return out


def score(flights, truth, delay_s: float) -> dict:
    """The flight table against the rig's truth (shifted by ``delay_s``)."""
    tt = truth["t_takeoff_s"].to_numpy() + delay_s
    tl = truth["t_landing_s"].to_numpy() + delay_s
    mt, ml = flights["t_takeoff_s"].to_numpy(), flights["t_landing_s"].to_numpy()
    long = (tl - tt) > 1e-3
    if mt.size == 0:
        return {"n_true_long": int(long.sum()), "n_table": 0, "found_long": 0.0}
    j = np.clip(np.searchsorted(mt, tt), 1, max(mt.size - 1, 1))
    j = np.where(np.abs(mt[j - 1] - tt) < np.abs(mt[np.minimum(j, mt.size - 1)] - tt), j - 1, j)
    j = np.minimum(j, mt.size - 1)
    found = (np.abs(mt[j] - tt) < TOL_S) & (np.abs(ml[j] - tl) < TOL_S)
    err = np.abs((ml[j] - mt[j]) - (tl - tt))[found & long]
    i = np.clip(np.searchsorted(tt, mt), 1, tt.size - 1)
    i = np.where(np.abs(tt[i - 1] - mt) < np.abs(tt[i] - mt), i - 1, i)
    real = (np.abs(tt[i] - mt) < TOL_S) & (np.abs(tl[i] - ml) < TOL_S)
    return {
        "n_true_long": int(long.sum()),
        "n_table": int(mt.size),
        "found_long": float(found[long].mean()),
        "spurious": int((~real).sum()),
        "non_positive": int((flights["flight_s"] <= 0).sum()),
        "median_err_us": float(np.median(err) * 1e6) if err.size else None,
        "p95_err_us": float(np.percentile(err, 95) * 1e6) if err.size else None,
    }


def phase_change(flights, clean, delay_s: float) -> dict:
    """Median and largest change (mrad) of the takeoff phases of the flights that the
    unchanged recording's table also holds (takeoffs within 0.3 ms, after ``delay_s``)."""
    ct = clean["t_takeoff_s"].to_numpy() + delay_s
    mt = flights["t_takeoff_s"].to_numpy()
    if ct.size < 2 or mt.size == 0:
        return {}
    i = np.clip(np.searchsorted(ct, mt), 1, ct.size - 1)
    i = np.where(np.abs(ct[i - 1] - mt) < np.abs(ct[i] - mt), i - 1, i)
    ok = np.abs(ct[i] - mt) < TOL_S
    d = flights["phi_takeoff"].to_numpy()[ok] - clean["phi_takeoff"].to_numpy()[i[ok]]
    d = np.abs(np.angle(np.exp(1j * d)))
    d = d[np.isfinite(d)]
    if d.size == 0:
        return {}
    return {"phase_median_mrad": float(np.median(d) * 1e3), "phase_max_mrad": float(d.max() * 1e3)}


class _Warnings(logging.Handler):
    def __init__(self):
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record):
        self.messages.append(record.getMessage())


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--work", type=Path, help="keep recordings here (reused)")
    p.add_argument("--only", nargs="*", help="case names")
    p.add_argument("--out", type=Path, default=None)
    p.add_argument("--jump-grid", action="store_true", help="the 50 gain/offset steps instead")
    p.add_argument("--hum-grid", action="store_true", help="the 144 mains hums instead")
    args = p.parse_args()
    cases = jump_grid() if args.jump_grid else hum_grid() if args.hum_grid else CASES
    grid = "jump_grid" if args.jump_grid else "hum_grid" if args.hum_grid else None
    out = args.out or (OUT.with_name(f"lab_artefacts_{grid}.json") if grid else OUT)
    names = args.only or list(cases)
    tmp = None if args.work else tempfile.TemporaryDirectory()
    work = args.work or Path(tmp.name)
    work.mkdir(parents=True, exist_ok=True)
    results, clean = {}, {}
    t_all = time.perf_counter()
    for seed, name in enumerate(names):
        e, fs, rc_s, fault, delay = cases[name]
        base, truth_path = base_run(work, e, fs, rc_s)
        run_dir = base if fault is None else faulty_run(base, work / name, fault, seed)
        handler = _Warnings()
        logging.getLogger("bouncelab").addHandler(handler)
        t0 = time.perf_counter()
        try:
            flights, _ = extract_run(run_dir)
        finally:
            logging.getLogger("bouncelab").removeHandler(handler)
        truth, _ = read_truth(truth_path)
        if fault is not None:
            if base not in clean:
                clean[base] = extract_run(base)[0]
            phases = phase_change(flights, clean[base], delay / fs)
        else:
            phases = {}
        res = (
            score(flights, truth, delay / fs)
            | phases
            | {
                "seconds": round(time.perf_counter() - t0, 2),
                "warnings": [m.split(": ", 1)[-1][:160] for m in handler.messages],
            }
        )
        results[name] = res
        print(
            f"{name:28s} found {res['found_long']:.3f} of {res['n_true_long']}, table "
            f"{res['n_table']}, spurious {res.get('spurious')}, non-positive "
            f"{res.get('non_positive')}, error median {res.get('median_err_us')} us, "
            f"phases {res.get('phase_median_mrad')} mrad; {len(res['warnings'])} warning(s)",
            flush=True,
        )
    bad = [k for k, r in results.items() if r["found_long"] < 1.0 or r.get("spurious")]
    print(f"{len(bad)} of {len(results)} cases lost or invented flights")
    doc = {
        "what": "flight extraction on virtual-rig sweeps with a lab's signal faults",
        "cases_losing_or_inventing": len(bad),
        "seconds": round(time.perf_counter() - t_all, 1),
        "numpy": np.__version__,
        "cases": results,
    }
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(doc, indent=1) + "\n")
    print(f"wrote {out}")
    if tmp is not None:
        tmp.cleanup()


if __name__ == "__main__":
    main()
