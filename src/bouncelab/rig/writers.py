"""Writing a rig result as a run folder (CONTRACTS.md section 1), bit for bit repeatable.

One recording file, ``recording.<ext>``, beside ``run.yaml``. Audio (FLAC, WAV) holds
the ADC's int16 codes as 16-bit PCM with ``full_scale_v`` in run.yaml; CSV, NPZ and
TDMS hold the volts those codes stand for. Nothing here writes a timestamp: the NPZ's
zip entries carry a fixed date, TDMS and audio files carry none.
"""

from __future__ import annotations

import io
import re
import zipfile
from pathlib import Path

import numpy as np
import yaml

from bouncelab.errors import BouncelabError
from bouncelab.rig.sensors import codes_to_volts
from bouncelab.rig.simulate import RigResult

RUN_ID_PATTERN = re.compile(r"[A-Za-z0-9][A-Za-z0-9_.-]*")
FORMATS = ("flac", "wav", "csv", "npz", "tdms")
TDMS_GROUP = "rig"
ZIP_DATE = (1980, 1, 1, 0, 0, 0)  # the zip format's epoch: no wall-clock time in the file


def prepare_run_dir(out_dir: Path, force: bool) -> None:
    """Create ``out_dir``; refuse a bad run id or a folder holding other files.

    With ``force`` an earlier rig output (``run.yaml``, ``recording.*``) is replaced;
    anything else in the folder is never touched and is an error.
    """
    if not RUN_ID_PATTERN.fullmatch(out_dir.name):
        raise BouncelabError(
            out_dir, "run folder name must match [A-Za-z0-9][A-Za-z0-9_.-]* (it is the run id)"
        )
    if out_dir.exists() and not out_dir.is_dir():
        raise BouncelabError(out_dir, "exists and is not a folder")
    if out_dir.is_dir():
        entries = sorted(out_dir.iterdir())
        ours = [e for e in entries if e.name == "run.yaml" or e.name.startswith("recording.")]
        others = [e for e in entries if e not in ours]
        if others:
            raise BouncelabError(
                out_dir, f"folder holds other files ({others[0].name}); not overwriting"
            )
        if ours and not force:
            raise BouncelabError(out_dir, "run folder exists; pass --force to replace it")
        for e in ours:
            e.unlink()
    out_dir.mkdir(parents=True, exist_ok=True)


def write_audio(path: Path, codes: np.ndarray, fs: float, fmt: str) -> None:
    """16-bit PCM FLAC or WAV of int16 codes (n, n_ch)."""
    import soundfile as sf

    if fs != int(fs):
        raise BouncelabError(path, f"audio formats need an integer sample rate, not {fs}")
    sf.write(path, codes, int(fs), subtype="PCM_16", format=fmt.upper())


def write_csv(path: Path, volts: np.ndarray, roles: list[str], fs: float, time_col: bool) -> None:
    """CSV with one column per role (volts, 10 significant digits), optional ``time_s``."""
    cols = list(roles)
    data = volts
    if time_col:
        cols = ["time_s", *cols]
        data = np.column_stack([np.arange(volts.shape[0]) / fs, volts])
    with open(path, "w", newline="\n") as fh:
        fh.write(",".join(cols) + "\n")
        np.savetxt(fh, data, fmt="%.10g", delimiter=",")


def write_npz(path: Path, volts: np.ndarray, roles: list[str]) -> None:
    """NPZ (deflated) with one float64 array per role; fixed zip dates (np.savez would
    stamp the current time into every entry)."""
    with zipfile.ZipFile(path, "w", compression=zipfile.ZIP_DEFLATED) as zf:
        for j, role in enumerate(roles):
            buf = io.BytesIO()
            np.lib.format.write_array(buf, np.ascontiguousarray(volts[:, j]), allow_pickle=False)
            info = zipfile.ZipInfo(f"{role}.npy", date_time=ZIP_DATE)
            info.compress_type = zipfile.ZIP_DEFLATED
            info.external_attr = 0o644 << 16
            zf.writestr(info, buf.getvalue())


def write_tdms(path: Path, volts: np.ndarray, roles: list[str], fs: float) -> None:
    """TDMS, one group ``rig``, one float64 channel per role, ``wf_increment`` set."""
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(path)) as writer:
        chans = [
            ChannelObject(
                TDMS_GROUP,
                role,
                np.ascontiguousarray(volts[:, j]),
                properties={"unit_string": "V", "wf_increment": 1.0 / fs},
            )  # fmt: skip
            for j, role in enumerate(roles)
        ]
        writer.write_segment(chans)


def channel_map(roles: list[str], fmt: str) -> dict:
    """run.yaml ``channels``: audio index, CSV column, NPZ array or TDMS group/channel."""
    if fmt in ("flac", "wav"):
        return {role: j for j, role in enumerate(roles)}
    if fmt == "tdms":
        return {role: f"{TDMS_GROUP}/{role}" for role in roles}
    return {role: role for role in roles}


def run_yaml(result: RigResult, recording: str, fmt: str) -> dict:
    """The run.yaml mapping: required keys first, then the config-dependent ones."""
    meta = dict(result.run_meta)
    doc = {
        "format_version": meta.pop("format_version"),
        "kind": meta.pop("kind"),
        "recording": recording,
        "sample_rate_hz": meta.pop("sample_rate_hz"),
        "channels": channel_map(result.roles, fmt),
    }
    if fmt in ("flac", "wav"):
        doc["full_scale_v"] = result.full_scale_v
    doc.update(meta)
    return doc


def write_run(
    result: RigResult, out_dir: str | Path, fmt: str = "flac", csv_time_column: bool = False,
    force: bool = False,
) -> Path:  # fmt: skip
    """Write ``result`` as the run folder ``out_dir`` (created); returns its path."""
    out_dir = Path(out_dir)
    if fmt not in FORMATS:
        raise BouncelabError(out_dir, f"unknown recording format {fmt!r}")
    prepare_run_dir(out_dir, force)
    rec = out_dir / f"recording.{fmt}"
    if fmt in ("flac", "wav"):
        write_audio(rec, result.codes, result.fs, fmt)
    else:
        volts = codes_to_volts(result.codes, result.full_scale_v)
        if fmt == "csv":
            write_csv(rec, volts, result.roles, result.fs, csv_time_column)
        elif fmt == "npz":
            write_npz(rec, volts, result.roles)
        else:
            write_tdms(rec, volts, result.roles, result.fs)
    doc = run_yaml(result, rec.name, fmt)
    text = yaml.safe_dump(doc, sort_keys=False, default_flow_style=None, width=100)
    (out_dir / "run.yaml").write_text(text)
    return out_dir
