"""Recording readers: FLAC, WAV, CSV, NPZ and TDMS to channels in volts.

:func:`read_recording` reads the channels of a :class:`~bouncelab.runs.spec.Run` by
role and runs every check that needs the file: sample rate and channel presence
(named against ``run.yaml``), then the data checks (empty, truncated or corrupt,
NaN or infinite samples, ``time_s`` not strictly increasing, steps or release after
the end; named against the recording) so that every consumer gets them. A ``time_s``
printed with too few digits (ties, within its resolution of a regular axis) is read as
that regular axis (:func:`rounded_time_axis`).

Dtypes: audio channels are float32 (16- and 24-bit PCM samples are exact in float32,
the ``full_scale_v`` factor then rounds to a relative 6e-8; half the memory of float64
for a long recording), CSV / NPZ / TDMS channels are float64. Each channel is
its own C-contiguous, writable 1-D array.

Memory: audio is decoded in blocks of :data:`AUDIO_BLOCK_FRAMES` frames straight into
the per-channel output arrays, so the peak is the output plus one block. CSV is
parsed by pandas (peak about twice the needed columns); NPZ members are read one at
a time (memory-mapped when stored uncompressed); TDMS channels are read one at a time.
"""

from __future__ import annotations

import logging
import os
import struct
import zipfile
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
import pandas as pd
import soundfile as sf

from bouncelab.errors import BouncelabError
from bouncelab.runs.spec import ROLES, Run, load_run

TIME_COLUMN = "time_s"
AUDIO_BLOCK_FRAMES = 1 << 16  # 64 Ki frames: ~0.8 MB per block for 3 float32 channels
UNKNOWN_FRAMES = 1 << 62  # libsndfile reports more frames than this for "length unknown"


@dataclass(frozen=True)
class Recording:
    """Channels of one recording, in volts.

    Attributes
    ----------
    path : Path
        The recording file.
    format : str
        ``flac``, ``wav``, ``csv``, ``npz`` or ``tdms``.
    fs : float
        Sampling rate, Hz (``sample_rate_hz`` of run.yaml; equal to the file's own for audio).
    n_samples : int
        Samples per channel (> 0).
    channels : dict[str, numpy.ndarray]
        Role -> 1-D array of shape ``(n_samples,)`` in volts; only the roles that
        were asked for and are mapped in run.yaml. float32 for audio, float64 otherwise.
    time_s : numpy.ndarray or None
        Shape ``(n_samples,)``, s, strictly increasing: the CSV ``time_s`` column (or an
        NPZ array ``time_s``) when present; ``None`` means time is ``index / fs``.
    """

    path: Path
    format: str
    fs: float
    n_samples: int
    channels: dict[str, np.ndarray] = field(default_factory=dict)
    time_s: np.ndarray | None = None

    @property
    def t_start_s(self) -> float:
        """Time of the first sample, s (0 unless a ``time_s`` column says otherwise)."""
        return float(self.time_s[0]) if self.time_s is not None else 0.0

    @property
    def duration_s(self) -> float:
        """End of the recording on its own time axis, s.

        ``n_samples / fs`` without a ``time_s`` column; with one, the last time plus one
        sample period. Equal to the length of the recording when time starts at 0. This is
        what ends the last Gamma step (:func:`bouncelab.runs.step_table`).
        """
        if self.time_s is None:
            return self.n_samples / self.fs
        return float(self.time_s[-1]) + 1.0 / self.fs

    @property
    def times(self) -> np.ndarray:
        """Sample times, s, shape ``(n_samples,)`` float64.

        ``time_s`` itself when present, else ``index / fs`` built anew on each access
        (8 bytes per sample: keep the result rather than asking twice).
        """
        if self.time_s is not None:
            return self.time_s
        return np.arange(self.n_samples, dtype=np.float64) / self.fs


# ---------------------------------------------------------------------- audio


def wav_missing_bytes(path: Path) -> int:
    """Bytes the WAV header promises in its ``data`` chunk that the file lacks (0 if none).

    libsndfile silently shortens a truncated WAV to the frames present; this reads the
    RIFF chunk list to catch it. Unknown data lengths (0 or 0xFFFFFFFF, written by
    streaming recorders and RF64) are not judged.
    """
    size = path.stat().st_size
    with open(path, "rb") as f:
        head = f.read(12)
        if len(head) < 12 or head[:4] not in (b"RIFF", b"RIFX", b"RF64") or head[8:] != b"WAVE":
            return 0  # not a RIFF WAV; libsndfile judges it
        endian = ">" if head[:4] == b"RIFX" else "<"
        pos = 12
        while pos + 8 <= size:
            f.seek(pos)
            chunk_id, length = struct.unpack(endian + "4sI", f.read(8))
            if chunk_id == b"data":
                if length in (0, 0xFFFFFFFF):
                    return 0
                return max(0, pos + 8 + length - size)
            pos += 8 + length + (length & 1)  # chunks are padded to even length
    return 0


# leading bytes of each audio container (ID3 may precede a FLAC stream; "riff" is Wave64)
_AUDIO_MAGIC = {
    ".flac": (b"fLaC", b"ID3"),
    ".wav": (b"RIFF", b"RIFX", b"RF64", b"BW64", b"riff"),
}


def check_audio_magic(path: Path) -> None:
    """Raise unless the file starts like its extension says (FLAC or WAV).

    Without this, libsndfile tries other decoders on garbage (mpg123 among them), which
    print warnings straight to the process's stderr and break the one-line error.
    """
    with open(path, "rb") as f:
        head = f.read(4)
    if not head.startswith(_AUDIO_MAGIC[path.suffix.lower()]):
        kind = path.suffix.lower().lstrip(".").upper()
        raise BouncelabError(path, f"corrupt audio: not a {kind} file (starts with {head!r})")


def _decode_known_length(
    path: Path, run: Run, roles: tuple[str, ...], n_channels: int, n: int
) -> dict[str, np.ndarray]:
    """Decode ``n`` frames block by block straight into one float32 array per role."""
    out = {role: np.empty(n, dtype=np.float32) for role in roles}
    pos = 0
    try:
        with sf.SoundFile(str(path)) as f:
            block = np.empty((min(AUDIO_BLOCK_FRAMES, n), n_channels), dtype=np.float32)
            while pos < n:
                got = f.read(min(len(block), n - pos), dtype="float32", always_2d=True, out=block)
                k = len(got)
                if k == 0:
                    break
                for role in roles:
                    out[role][pos : pos + k] = got[:, run.channels[role]]
                pos += k
    except (sf.SoundFileError, RuntimeError) as exc:
        raise BouncelabError(
            path, f"truncated or corrupt audio after {pos} of {n} frames: {_one_line(exc)}"
        ) from None
    if pos < n:
        raise BouncelabError(path, f"truncated audio: {pos} of {n} frames present")
    return out


def _read_audio(run: Run, roles: tuple[str, ...]) -> Recording:
    path = run.recording_path
    check_audio_magic(path)
    try:
        info = sf.info(str(path))
    except (sf.SoundFileError, RuntimeError) as exc:
        raise BouncelabError(path, f"truncated or corrupt audio: {_one_line(exc)}") from None
    if float(info.samplerate) != run.sample_rate_hz:
        raise BouncelabError(
            run.yaml_path,
            f"sample_rate_hz is {run.sample_rate_hz:g} but {path.name} is sampled at "
            f"{info.samplerate} Hz",
        )
    for role in roles:
        index = run.channels[role]
        if index >= info.channels:
            raise BouncelabError(
                run.yaml_path,
                f"channels.{role}: index {index} is out of range, {path.name} has "
                f"{info.channels} channel(s) (0-based)",
            )
    if path.suffix.lower() == ".wav" and (missing := wav_missing_bytes(path)) > 0:
        raise BouncelabError(
            path, f"truncated audio: the WAV header promises {missing} more bytes of samples"
        )
    n = int(info.frames)
    if n <= 0:
        raise BouncelabError(path, "empty recording: no samples")
    if n >= UNKNOWN_FRAMES:
        # a streamed FLAC that never wrote its length: libsndfile fails at the end of such
        # a stream instead of returning the last frames, so the end cannot be told from damage
        raise BouncelabError(
            path,
            "audio header gives no length (written by a streaming encoder); re-encode the "
            "file, e.g. `flac -f -o fixed.flac file.flac` or sox, so that it states its length",
        )
    out = _decode_known_length(path, run, roles, info.channels, n)
    scale = np.float32(run.full_scale_v)
    for arr in out.values():
        arr *= scale  # in place: no second copy
    return Recording(path, run.format, run.sample_rate_hz, n, out)


# ------------------------------------------------------------------------ CSV


def csv_delimiter(header: str) -> str:
    """The field separator of a CSV header line: ``,`` unless the header has none and has
    ``;`` or a tab (exports of spreadsheets set to a European locale)."""
    if "," not in header:
        for sep in (";", "\t"):
            if sep in header:
                return sep
    return ","


def _is_number(field: str, decimal: str) -> bool:
    """Whether one CSV field parses as a number (empty: no)."""
    text = field.strip().strip('"')
    if decimal == ",":
        text = text.replace(",", ".")
    try:
        float(text)
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class CsvDialect:
    """How a CSV file is laid out, from its first lines (:func:`csv_dialect`).

    Attributes
    ----------
    sep : field separator.
    decimal : ``.``, or ``,`` (a decimal comma, with ``;`` or tab separators).
    skip : 0-based line numbers to skip: leading ``#`` comment lines, and a units row
        right after the header (a second row of text, e.g. ``s;V;V``).
    """

    sep: str
    decimal: str
    skip: tuple[int, ...]


def csv_dialect(path: Path) -> CsvDialect:
    """Read the separator, the decimal mark and the lines to skip from a CSV's first lines.

    Exports of data-acquisition software often start with ``#`` comment lines, put a row
    of units under the header, and in a European locale write ``;``-separated fields
    with decimal commas; each is recognised here so that such a file reads as it is.
    """
    with open(path, encoding="utf-8", errors="replace") as f:
        lines = [line.rstrip("\r\n") for _, line in zip(range(64), f, strict=False)]
    comments = 0
    while comments < len(lines) and lines[comments].lstrip().startswith("#"):
        comments += 1
    skip = list(range(comments))
    header = lines[comments] if comments < len(lines) else ""
    sep = csv_delimiter(header)
    rows = [line.split(sep) for line in lines[comments + 1 :] if line.strip()]
    decimal = "."
    fields = [f for row in rows for f in row]
    if sep != "," and any("," in f for f in fields) and not any("." in f for f in fields):
        decimal = ","
    if len(rows) >= 2 and not any(_is_number(f, decimal) for f in rows[0]):
        if any(_is_number(f, decimal) for f in rows[1]):
            skip.append(comments + 1)  # a units row under the header
    return CsvDialect(sep, decimal, tuple(skip))


def _read_csv(run: Run, roles: tuple[str, ...]) -> Recording:
    path = run.recording_path
    try:
        dialect = csv_dialect(path)
        read = dict(sep=dialect.sep, decimal=dialect.decimal, skiprows=list(dialect.skip))
        columns = list(pd.read_csv(path, nrows=0, **read).columns)
    except pd.errors.EmptyDataError:
        raise BouncelabError(path, "empty recording: no header and no samples") from None
    except (ValueError, UnicodeDecodeError, OSError) as exc:
        raise BouncelabError(path, f"cannot read CSV: {_one_line(exc)}") from None
    for role in roles:
        name = run.channels[role]
        if name not in columns:
            raise BouncelabError(
                run.yaml_path,
                f"channels.{role}: column {name!r} not in {path.name} "
                f"(columns: {_listing(columns)})",
            )
    wanted = list(dict.fromkeys([run.channels[r] for r in roles]))
    if TIME_COLUMN in columns and TIME_COLUMN not in wanted:
        wanted.append(TIME_COLUMN)
    try:
        df = pd.read_csv(path, usecols=wanted, dtype=dict.fromkeys(wanted, np.float64), **read)
    except (ValueError, UnicodeDecodeError, pd.errors.ParserError) as exc:
        raise BouncelabError(path, f"cannot read CSV samples: {_one_line(exc)}") from None
    n = len(df)
    if n == 0:
        raise BouncelabError(path, "empty recording: header but no samples")
    # one writable, contiguous copy per column; the frame is dropped right after
    arrays = {col: np.array(df[col].to_numpy(dtype=np.float64), copy=True) for col in wanted}
    del df
    channels: dict[str, np.ndarray] = {}
    for role in roles:
        arr = arrays[run.channels[role]]
        # two roles on one column get their own arrays, so that they never alias
        channels[role] = arr.copy() if any(arr is a for a in channels.values()) else arr
    time_s = arrays.get(TIME_COLUMN) if TIME_COLUMN in columns else None
    return Recording(path, run.format, run.sample_rate_hz, n, channels, time_s)


# ------------------------------------------------------------------------ NPZ


def _npz_stored_member(path: Path, name: str) -> np.ndarray | None:
    """Memory-map member ``name.npy`` of an uncompressed NPZ; None if not possible."""
    try:
        with zipfile.ZipFile(path) as zf:
            info = zf.getinfo(name + ".npy")
        if info.compress_type != zipfile.ZIP_STORED:
            return None
        with open(path, "rb") as f:
            f.seek(info.header_offset)
            local = f.read(30)
            if local[:4] != b"PK\x03\x04":
                return None
            name_len, extra_len = struct.unpack("<HH", local[26:30])
            start = info.header_offset + 30 + name_len + extra_len
            f.seek(start)
            version = np.lib.format.read_magic(f)
            if version == (1, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_1_0(f)
            elif version == (2, 0):
                shape, fortran, dtype = np.lib.format.read_array_header_2_0(f)
            else:  # version 3 has no public header reader: let np.load do it
                return None
            offset = f.tell()
        if dtype.hasobject or fortran:
            return None
        if offset + dtype.itemsize * int(np.prod(shape)) > start + info.file_size:
            return None
        return np.memmap(path, dtype=dtype, mode="r", offset=offset, shape=shape)
    except (KeyError, ValueError, OSError, zipfile.BadZipFile, struct.error):
        return None


def _npz_array(npz, path: Path, name: str) -> np.ndarray:
    """One NPZ member as a float64 array, memory-mapped first when stored."""
    arr = _npz_stored_member(path, name)
    if arr is None:
        try:
            arr = npz[name]
        except Exception as exc:  # zlib, zipfile, numpy header errors: all mean corrupt
            raise BouncelabError(path, f"cannot read array {name!r}: {_one_line(exc)}") from None
    if arr.dtype.kind not in "biuf":
        raise BouncelabError(path, f"array {name!r} is not numeric (dtype {arr.dtype})")
    if arr.ndim != 1:
        raise BouncelabError(path, f"array {name!r} must be 1-D, has shape {arr.shape}")
    if isinstance(arr, np.memmap):  # copy into RAM (converting integers); the map is dropped
        return np.array(arr, dtype=np.float64, copy=True)
    return _owned_float64(arr)


def _read_npz(run: Run, roles: tuple[str, ...]) -> Recording:
    path = run.recording_path
    try:
        npz = np.load(path, allow_pickle=False)
    except (OSError, ValueError, EOFError, zipfile.BadZipFile) as exc:
        raise BouncelabError(path, f"cannot read NPZ: {_one_line(exc)}") from None
    if not isinstance(npz, np.lib.npyio.NpzFile):
        raise BouncelabError(path, "not an NPZ archive (a single .npy array?)")
    with npz:
        names = list(npz.files)
        for role in roles:
            if run.channels[role] not in names:
                raise BouncelabError(
                    run.yaml_path,
                    f"channels.{role}: array {run.channels[role]!r} not in {path.name} "
                    f"(arrays: {_listing(names)})",
                )
        channels = {role: _npz_array(npz, path, run.channels[role]) for role in roles}
        time_s = _npz_array(npz, path, TIME_COLUMN) if TIME_COLUMN in names else None
    n = _common_length(channels, time_s, path)
    return Recording(path, run.format, run.sample_rate_hz, n, channels, time_s)


# ----------------------------------------------------------------------- TDMS


def _tdms_channel(tdms, spec: str):
    """The TDMS channel for ``"group/channel"``; tries every '/' so names may contain one."""
    for i, ch in enumerate(spec):
        if ch != "/":
            continue
        group, channel = spec[:i], spec[i + 1 :]
        try:
            return tdms[group][channel]
        except KeyError:
            continue
    return None


def _tdms_names(tdms) -> list[str]:
    return [f"{g.name}/{c.name}" for g in tdms.groups() for c in g.channels()]


# npTDMS logs damage (a bad version number, an incomplete last segment) as warnings
# instead of raising; these words in a warning mean the file is truncated or corrupt
_TDMS_DAMAGE_WORDS = ("incomplete", "unrecognised", "truncat", "not a multiple", "corrupt")


@contextmanager
def _tdms_warnings():
    """Collect npTDMS warnings (list of messages) instead of letting npTDMS print them.

    npTDMS writes warnings to stderr through its own handler, which would break the
    one-line error contract; the handler is silenced only inside this block.
    """
    messages: list[str] = []

    class _Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            messages.append(record.getMessage())

    keep = _Keep(level=logging.WARNING)
    parent = logging.getLogger("nptdms")
    try:
        from nptdms.log import log_manager

        console = log_manager.console_handler
    except (ImportError, AttributeError):  # another npTDMS layout: nothing to silence
        console = None
    old_level = console.level if console is not None else None
    if console is not None:
        console.setLevel(logging.CRITICAL + 1)
    parent.addHandler(keep)
    try:
        yield messages
    finally:
        parent.removeHandler(keep)
        if console is not None:
            console.setLevel(old_level)


def _tdms_damage(path: Path, messages: list[str]) -> None:
    for m in messages:
        if any(w in m.lower() for w in _TDMS_DAMAGE_WORDS):
            raise BouncelabError(path, f"truncated or corrupt TDMS file: {_one_line(m)}")


def _read_tdms(run: Run, roles: tuple[str, ...]) -> Recording:
    with _tdms_warnings() as messages:
        try:
            return _read_tdms_quiet(run, roles, messages)
        except BouncelabError:
            _tdms_damage(run.recording_path, messages)  # the damage explains the error
            raise


def _read_tdms_quiet(run: Run, roles: tuple[str, ...], messages: list[str]) -> Recording:
    from nptdms import TdmsFile  # imported here: npTDMS is slow to import and TDMS is rare

    path = run.recording_path
    try:
        tdms = TdmsFile.open(path)  # streaming: metadata now, data per channel on demand
    except Exception as exc:  # npTDMS raises many types on a damaged file
        raise BouncelabError(path, f"cannot read TDMS file: {_one_line(exc)}") from None
    with tdms:
        _tdms_damage(path, messages)
        found = {role: _tdms_channel(tdms, run.channels[role]) for role in roles}
        for role, chan in found.items():
            if chan is None:
                raise BouncelabError(
                    run.yaml_path,
                    f"channels.{role}: 'group/channel' {run.channels[role]!r} not in "
                    f"{path.name} (channels: {_listing(_tdms_names(tdms))})",
                )
        channels = {}
        for role, chan in found.items():
            try:
                data = chan[:]
            except Exception as exc:
                raise BouncelabError(
                    path, f"cannot read channel {run.channels[role]!r}: {_one_line(exc)}"
                ) from None
            _tdms_damage(path, messages)
            data = np.asarray(data)
            if data.dtype.kind not in "biuf":
                raise BouncelabError(
                    path, f"channel {run.channels[role]!r} is not numeric (dtype {data.dtype})"
                )
            channels[role] = _owned_float64(data)
    n = _common_length(channels, None, path)
    return Recording(path, run.format, run.sample_rate_hz, n, channels)


# ----------------------------------------------------------------- data checks


def _owned_float64(arr: np.ndarray) -> np.ndarray:
    """``arr`` as a C-contiguous, writable float64 ndarray; copies only when it must
    (a fresh float64 array from a reader is kept as it is: no second copy in memory)."""
    return np.require(np.asarray(arr), dtype=np.float64, requirements=["C", "W", "O"])


def _common_length(channels: dict[str, np.ndarray], time_s, path: Path) -> int:
    lengths = {role: len(a) for role, a in channels.items()}
    if time_s is not None:
        lengths[TIME_COLUMN] = len(time_s)
    if len(set(lengths.values())) > 1:
        detail = ", ".join(f"{k}: {v}" for k, v in lengths.items())
        raise BouncelabError(path, f"channels differ in length ({detail})")
    return next(iter(lengths.values()))


#: A rounded ``time_s`` may stray from the regular axis by at most this many of its
#: own steps (the 99th percentile of its positive steps, i.e. its printed resolution).
ROUNDED_TIME_TOLERANCE = 1.01


def rounded_time_axis(t: np.ndarray, fs: float) -> np.ndarray | None:
    """The regular axis that a ``time_s`` printed with too few digits stands for.

    Exported spreadsheets often print time with fewer digits than the sampling needs
    (LabVIEW's ``%.3f`` is a millisecond; ``%.6g`` is 0.1 ms past 10 s): consecutive
    samples then share a time. Such a column still says where the recording starts,
    and that no samples are missing. When ``t`` (shape ``(n,)``, s) never decreases,
    has ties, and stays within its own resolution of ``t0 + index / fs``, this returns
    that axis (``t0`` the median offset); otherwise ``None`` (a column that goes
    backwards, or jumps, is an error the caller reports). A strictly increasing ``t``
    is returned as ``None`` too: it is used as it is.
    """
    d = np.diff(t)
    if d.size == 0 or (d > 0).all() or (d < 0).any() or not (d > 0).any():
        return None
    resolution = float(np.percentile(d[d > 0], 99))
    regular = np.arange(t.shape[0], dtype=np.float64) / fs
    t0 = float(np.median(t - regular))
    if np.max(np.abs(t - (t0 + regular))) > ROUNDED_TIME_TOLERANCE * max(resolution, 1.0 / fs):
        return None
    return t0 + regular


def _unround_time(rec: Recording) -> Recording:
    """``rec`` with a rounded ``time_s`` replaced by its regular axis (a warning logged)."""
    if rec.time_s is None:
        return rec
    t = rec.time_s
    if not np.isfinite(t).all():
        return rec
    regular = rounded_time_axis(t, rec.fs)
    if regular is None:
        return rec
    ties = int(np.count_nonzero(np.diff(t) == 0))
    logging.getLogger(__name__).warning(
        "%s: time_s is printed with too few digits (%d repeated values); using "
        "%.9g s + index / %g Hz",
        rec.path,
        ties,
        regular[0],
        rec.fs,
    )
    return replace(rec, time_s=regular)


#: Largest relative difference between ``time_s``'s median spacing and ``1 /
#: sample_rate_hz`` that is read (with validate's warning above 1 %); beyond it, an error.
TIME_SPACING_TOL = 0.4


def check_samples(run: Run, rec: Recording) -> None:
    """Data checks shared by every format; raises BouncelabError.

    Empty recording, NaN or infinite samples, ``time_s`` not finite, not strictly
    increasing or spaced more than 40 % off ``1 / sample_rate_hz`` (named against the
    recording); every Gamma step, or the release time,
    at or after the recording's end (named against run.yaml, which holds the times; some
    steps past the end are a protocol the lab stopped early, left out with a warning).
    """
    path = rec.path
    if rec.n_samples == 0:
        raise BouncelabError(path, "empty recording: no samples")
    for role, arr in rec.channels.items():
        if not np.isfinite(arr).all():
            i = int(np.flatnonzero(~np.isfinite(arr))[0])
            raise BouncelabError(
                path,
                f"{role} channel {run.channels[role]!r} has a non-finite sample "
                f"({arr[i]}) at index {i}, t = {i / rec.fs:.6g} s",
            )
    if rec.time_s is not None:
        t = rec.time_s
        if not np.isfinite(t).all():
            i = int(np.flatnonzero(~np.isfinite(t))[0])
            raise BouncelabError(path, f"time_s is not finite ({t[i]}) at index {i}")
        bad = np.flatnonzero(t[1:] <= t[:-1])
        if bad.size:
            i = int(bad[0]) + 1
            raise BouncelabError(
                path,
                f"time_s is not strictly increasing: {t[i]:.9g} at index {i} after {t[i - 1]:.9g}",
            )
        if t.shape[0] > 1:
            # a jump of the time axis over 1.5 sample periods is a data gap, so a spacing
            # this far off 1/fs would read every sample as a gap and keep no flight
            dt = float(np.median(np.diff(t)))
            if abs(dt * run.sample_rate_hz - 1.0) > TIME_SPACING_TOL:
                raise BouncelabError(
                    path,
                    f"time_s spacing {dt:.6g} s (median) is {dt * run.sample_rate_hz:.3g} "
                    f"sample periods of sample_rate_hz {run.sample_rate_hz:g}: the column "
                    "and run.yaml disagree about the sampling rate",
                )
    end = rec.duration_s
    if run.kind == "sweep" and run.gamma_steps and run.gamma_steps[0][0] >= end:
        raise BouncelabError(
            run.yaml_path,
            f"every gamma step starts at or after the end of {path.name} ({end:g} s): "
            f"gamma_steps[0] at {run.gamma_steps[0][0]:g} s",
        )
    if run.release_t_s is not None and not rec.t_start_s <= run.release_t_s < end:
        raise BouncelabError(
            run.yaml_path,
            f"release_t_s = {run.release_t_s:g} s is outside {path.name} "
            f"({rec.t_start_s:g} to {end:g} s)",
        )


# --------------------------------------------------------------------- public

_READERS = {
    "flac": _read_audio,
    "wav": _read_audio,
    "csv": _read_csv,
    "npz": _read_npz,
    "tdms": _read_tdms,
}


def read_recording(run: Run | str | os.PathLike, roles=ROLES) -> Recording:
    """Read the channels of a run by role, in volts, with every data check.

    Parameters
    ----------
    run : Run or path
        A :class:`Run` from :func:`load_run`, or a run folder (loaded here).
    roles : iterable of str
        Roles wanted, among ``continuity``, ``drive``, ``accel``; roles that run.yaml
        does not map are skipped (``continuity`` is always mapped).

    Returns
    -------
    Recording
        ``channels[role]``: shape ``(n_samples,)``, volts; float32 for FLAC/WAV (sample
        value x ``full_scale_v``), float64 for CSV/NPZ/TDMS (values as stored).

    Raises
    ------
    BouncelabError
        run.yaml named for a sample-rate mismatch, a missing channel or steps after the
        end; the recording named for empty, truncated, corrupt or non-finite data and a
        ``time_s`` that does not increase.
    """
    if not isinstance(run, Run):
        run = load_run(run)
    roles = tuple(roles)
    unknown = [r for r in roles if r not in ROLES]
    if unknown:
        raise ValueError(f"unknown channel role(s) {unknown}; use {ROLES}")
    roles = tuple(r for r in ROLES if r in roles and r in run.channels)
    rec = _unround_time(_READERS[run.format](run, roles))
    check_samples(run, rec)
    return rec


def _one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split()) or type(exc).__name__
    return text if len(text) <= 200 else text[:197] + "..."


def _listing(names: list[str], limit: int = 12) -> str:
    shown = ", ".join(repr(n) for n in names[:limit])
    return shown + (f", ... ({len(names)} in all)" if len(names) > limit else "") or "none"
