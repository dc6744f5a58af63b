"""Helpers of the runs tests: tiny run folders of every format, written by our own writers.

The writers here are deliberately independent of ``bouncelab.rig`` so the readers are
tested against files made another way: soundfile for FLAC/WAV, pandas for CSV,
numpy for NPZ, npTDMS for TDMS.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pandas as pd
import soundfile as sf
import yaml

FS = 2000.0  # Hz: small files, fast tests
DURATION_S = 4.0
DRIVE_HZ = 25.0
STEPS = [(0.0, 0.5), (1.0, 1.0), (2.0, 1.5), (3.0, 2.5)]
FORMATS = ("flac", "wav", "csv", "npz", "tdms")
TDMS_GROUP = "rig"
DELETE = object()  # marks a run.yaml key to remove in ``yaml_overrides``


def known_signals(n: int = int(FS * DURATION_S), fs: float = FS, seed: int = 0) -> dict:
    """Role -> float64 volts, shape (n,): a contact square wave, a drive sine, a noisy accel.

    Amplitudes stay inside +-0.9 so that audio at full_scale_v = 1 V never clips.
    """
    t = np.arange(n) / fs
    rng = np.random.default_rng(seed)
    return {
        "continuity": np.where(np.sin(2 * np.pi * DRIVE_HZ * t) > 0.3, 0.05, 0.85),
        "drive": 0.6 * np.sin(2 * np.pi * DRIVE_HZ * t),
        "accel": 0.3 * np.sin(2 * np.pi * DRIVE_HZ * t + 0.4) + 0.05 * rng.standard_normal(n),
    }


def channel_spec(fmt: str) -> dict:
    """run.yaml ``channels`` for a format written by :func:`write_recording`."""
    if fmt in ("flac", "wav"):
        return {"continuity": 0, "drive": 1, "accel": 2}
    if fmt == "tdms":
        return {r: f"{TDMS_GROUP}/{r}" for r in ("continuity", "drive", "accel")}
    return {"continuity": "cont_v", "drive": "drive_v", "accel": "accel_v"}


def write_recording(
    path: Path,
    signals: dict,
    fs: float = FS,
    full_scale_v: float = 1.0,
    subtype: str = "PCM_16",
    time_s=None,
    compressed: bool = False,
) -> None:
    """Write ``signals`` (role -> volts) in the format of ``path``'s extension."""
    fmt = path.suffix.lower().lstrip(".")
    names = channel_spec(fmt)
    roles = list(signals)
    if fmt in ("flac", "wav"):
        data = np.stack([signals[r] for r in roles], axis=1) / full_scale_v
        sf.write(path, data, int(fs), subtype=subtype, format=fmt.upper())
    elif fmt == "csv":
        cols = {} if time_s is None else {"time_s": time_s}
        cols |= {names[r]: signals[r] for r in roles}
        pd.DataFrame(cols).to_csv(path, index=False)  # shortest repr: exact round trip
    elif fmt == "npz":
        arrays = {names[r]: signals[r] for r in roles}
        if time_s is not None:
            arrays["time_s"] = time_s
        with open(path, "wb") as f:  # file object: numpy must not append ".npz"
            (np.savez_compressed if compressed else np.savez)(f, **arrays)
    elif fmt == "tdms":
        from nptdms import ChannelObject, TdmsWriter

        with TdmsWriter(str(path)) as w:
            w.write_segment([ChannelObject(TDMS_GROUP, r, np.asarray(signals[r])) for r in roles])
    else:
        path.write_bytes(b"not a recording\n")


def base_yaml(fmt: str, kind: str = "sweep") -> dict:
    """A valid run.yaml dict for a recording ``rec.<fmt>`` from :func:`write_recording`."""
    doc = {
        "format_version": 1,
        "kind": kind,
        "recording": f"rec.{fmt}",
        "sample_rate_hz": FS,
        "channels": channel_spec(fmt),
        "source": "synthetic",
        "mass_kg": 0.249,
    }
    if kind == "sweep":
        doc["drive_frequency_hz"] = DRIVE_HZ
        doc["gamma_steps"] = [{"t_s": t, "gamma": g} for t, g in STEPS]
    else:
        doc["drop_height_m"] = 0.05
        doc["release_t_s"] = 0.5
    return doc


def write_yaml(path: Path, doc: dict) -> None:
    path.write_text(yaml.safe_dump(doc, sort_keys=False), encoding="utf-8")


def tree_digest(folder: Path) -> str:
    """SHA-256 over every file's relative path and bytes under ``folder`` (sorted)."""
    h = hashlib.sha256()
    for p in sorted(folder.rglob("*")):
        h.update(str(p.relative_to(folder)).encode())
        if p.is_file():
            h.update(p.read_bytes())
    return h.hexdigest()


def run_factory(root: Path):
    """Factory: ``make_run(fmt, name=..., kind=..., yaml_overrides=..., **writer_kw)``.

    Writes ``root/raw/<name>/`` with ``run.yaml`` and ``rec.<fmt>`` holding
    :func:`known_signals` (or ``signals=``), and returns the folder.
    ``yaml_overrides`` replaces keys (``DELETE`` removes one).
    """

    def make(
        fmt: str,
        name: str | None = None,
        kind: str = "sweep",
        yaml_overrides: dict | None = None,
        signals: dict | None = None,
        **writer_kw,
    ) -> Path:
        run_dir = root / "raw" / (name or f"run_{fmt}")
        run_dir.mkdir(parents=True)
        sig = known_signals() if signals is None else signals
        write_recording(run_dir / f"rec.{fmt}", sig, **writer_kw)
        doc = base_yaml(fmt, kind)
        if "full_scale_v" in writer_kw:
            doc["full_scale_v"] = writer_kw["full_scale_v"]
        for key, value in (yaml_overrides or {}).items():
            if value is DELETE:
                doc.pop(key, None)
            else:
                doc[key] = value
        write_yaml(run_dir / "run.yaml", doc)
        return run_dir

    return make
