"""Full validation of a run folder, its report, the step table and Gamma gaps.

:func:`validate_run` = :func:`~bouncelab.runs.spec.load_run` (run.yaml, schema, paths)
+ :func:`~bouncelab.runs.readers.read_recording` (header and data checks) + a
:class:`ValidationReport` of what was found. Nothing is ever written.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from bouncelab.errors import BouncelabError
from bouncelab.runs.readers import TIME_COLUMN, Recording, read_recording
from bouncelab.runs.spec import EXTENSION_KEYS, ROLES, Run, load_run

STEP_COLUMNS = ("step", "gamma", "t_start_s", "t_end_s", "n_cycles")
GAP_FACTOR = 1.5
#: An audio channel within ``CLIP_TOL`` of its full scale (8-bit's largest code is
#: 127/128 of it) in at least ``CLIP_SHARE`` of its samples is clipped.
CLIP_TOL, CLIP_SHARE = 0.01, 1e-3


def step_table(run: Run, duration_s: float) -> pd.DataFrame:
    """One row per Gamma step: when it starts and ends on the recording's time axis.

    A step lasts until the next starts or the recording ends (CONTRACTS.md section 1).

    Parameters
    ----------
    run : Run
    duration_s : float
        End of the recording, s (:attr:`Recording.duration_s`).

    Returns
    -------
    DataFrame
        Columns ``step`` (int64, index into ``gamma_steps``), ``gamma`` (float64),
        ``t_start_s``, ``t_end_s`` (float64, s) and ``n_cycles`` (float64, drive
        cycles in the step; NaN without a drive frequency). Empty (same columns)
        for runs without steps, e.g. drops.
    """
    # a step planned past the recording's end (the lab stopped early) holds no data: it is
    # left out (steps_after_end names it in warnings), the others keep their indices
    steps = run.gamma_steps[: len(steps_inside(run, duration_s))]
    t_start = np.array([t for t, _ in steps], dtype=np.float64)
    gamma = np.array([g for _, g in steps], dtype=np.float64)
    t_end = np.append(t_start[1:], float(duration_s)) if steps else np.empty(0)
    f = run.drive_frequency_hz if run.drive_frequency_hz is not None else math.nan
    return pd.DataFrame(
        {
            "step": np.arange(len(steps), dtype=np.int64),
            "gamma": gamma,
            "t_start_s": t_start,
            "t_end_s": t_end,
            "n_cycles": (t_end - t_start) * f,
        }
    )


def steps_inside(run: Run, duration_s: float) -> list:
    """The ``gamma_steps`` that start before ``duration_s`` (the recording's end, s)."""
    return [st for st in run.gamma_steps if st[0] < duration_s]


def steps_after_end(run: Run, duration_s: float) -> str | None:
    """A warning naming the steps that start at or after the recording's end, or None."""
    n_in = len(steps_inside(run, duration_s))
    late = len(run.gamma_steps) - n_in
    if run.kind != "sweep" or late == 0:
        return None
    first = run.gamma_steps[n_in]
    return (
        f"{late} gamma step(s) start at or after the end of the recording "
        f"({duration_s:g} s), e.g. gamma_steps[{n_in}] at {first[0]:g} s "
        f"(Gamma {first[1]:g}): no data there, left out"
    )


def steps_before_start(run: Run, t_start_s: float) -> str | None:
    """A warning naming the steps that end before the recording starts, or None.

    A CSV whose ``time_s`` counts from a lab clock (12.3 s at its first sample) beside
    steps written from 0 puts every flight in the last step that starts before the
    recording, all with the wrong Gamma, and nothing else looks wrong.
    """
    t = [ts for ts, _ in run.gamma_steps]
    early = sum(1 for i in range(len(t) - 1) if t[i + 1] <= t_start_s)
    if run.kind != "sweep" or early == 0:
        return None
    return (
        f"{early} gamma step(s) end before the recording starts (t = {t_start_s:g} s on its "
        f"time axis), e.g. gamma_steps[0] at {t[0]:g} s: no data there; gamma_steps' t_s "
        "must be on the recording's time axis (its time_s column when it has one)"
    )


def gamma_gaps(gammas, factor: float = GAP_FACTOR) -> list[tuple[float, float]]:
    """Ranges of Gamma with no step: jumps much larger than the typical spacing.

    The distinct Gamma values are sorted (so up-and-down sweeps count once); a jump
    between neighbours larger than ``factor`` times the median jump is a gap, e.g. the
    seed's 1.75-1.95 in a 0.05 grid (4 times the spacing).

    Parameters
    ----------
    gammas : array-like, shape (n_steps,)
    factor : float
        Threshold relative to the median spacing.

    Returns
    -------
    list of (gamma_lo, gamma_hi)
        The two Gamma values either side of each gap, increasing.
    """
    g = np.unique(np.round(np.asarray(gammas, dtype=np.float64), 9))
    if g.size < 3:  # two values: no typical spacing to compare with
        return []
    d = np.diff(g)
    typical = float(np.median(d))
    return [(float(g[i]), float(g[i + 1])) for i in np.flatnonzero(d > factor * typical)]


@dataclass(frozen=True)
class ChannelSummary:
    """Range of one channel: role, where it is in the file, min and max in volts, and
    ``dtype``, what bouncelab reads it as (float32 for audio, float64 otherwise: not
    necessarily the file's own type, which a float32 NPZ or TDMS channel is not)."""

    role: str
    spec: int | str
    min_v: float
    max_v: float
    dtype: str


@dataclass(frozen=True)
class ValidationReport:
    """What :func:`validate_run` found in a valid run folder.

    ``steps`` is :func:`step_table`; ``gaps`` the Gamma gaps; ``warnings`` things
    that are allowed but worth a look (ignored keys, unused ``full_scale_v``, a
    ``time_s`` spacing that disagrees with ``sample_rate_hz``, steps too short to
    settle); ``extract_problem``: why extracting the run's flights will fail although the
    folder meets the contract (a continuity channel with no contacts where the body
    must leave the plate: a drop run, or a step at Gamma 1 or more), or None. It is
    among the warnings too; the workflow's check refuses the run on it, so that the
    report does not wait for products the run cannot give.
    """

    run: Run
    fs: float
    n_samples: int
    t_start_s: float
    duration_s: float
    has_time_column: bool
    channels: list[ChannelSummary]
    steps: pd.DataFrame
    gaps: list[tuple[float, float]]
    warnings: list[str] = field(default_factory=list)
    extract_problem: str | None = None

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready dict of the report (numbers as Python floats and ints)."""
        r = self.run
        steps = self.steps
        return {
            "run": r.run_id,
            "path": str(r.path),
            "kind": r.kind,
            "source": r.source,
            "recording": r.recording_path.name,
            "format": r.format,
            "sample_rate_hz": self.fs,
            "n_samples": self.n_samples,
            "t_start_s": self.t_start_s,
            # the recording's length; its end on the time axis is t_end_s (they differ
            # when a time_s column starts later than 0)
            "duration_s": self.duration_s - self.t_start_s,
            "t_end_s": self.duration_s,
            "time_column": self.has_time_column,
            "contact_level": r.contact_level,
            "channels": [
                {"role": c.role, "channel": c.spec, "min_v": c.min_v, "max_v": c.max_v}
                for c in self.channels
            ],
            "drive_frequency_hz": r.drive_frequency_hz,
            "n_steps": len(steps),
            "gamma_min": float(steps["gamma"].min()) if len(steps) else None,
            "gamma_max": float(steps["gamma"].max()) if len(steps) else None,
            "gamma_gaps": [list(g) for g in self.gaps],
            "settle_cycles": r.settle_cycles,
            "drop_height_m": r.drop_height_m,
            "release_t_s": r.release_t_s,
            "mass_kg": r.mass_kg,
            "warnings": list(self.warnings),
        }

    def summary(self) -> str:
        """Human-readable multi-line report (what ``bouncelab validate`` prints)."""
        r = self.run
        lines = [f"run        {r.run_id}  ({r.kind}, source: {r.source or 'not stated'})"]
        time_note = ", time from time_s column" if self.has_time_column else ""
        lines.append(
            f"recording  {r.recording_path.name}  ({r.format}, {self.fs:g} Hz, "
            f"{self.n_samples} samples, {self.duration_s - self.t_start_s:.6g} s{time_note})"
        )
        for i, c in enumerate(self.channels):
            head = "channels   " if i == 0 else "           "
            lines.append(
                f"{head}{c.role:<10} {c.spec!s:<16} {c.min_v:+.4g} .. {c.max_v:+.4g} V  "
                f"(read as {c.dtype})"
            )
        lines.append(f"contact    level {r.contact_level}")
        if r.mass_kg is not None:
            lines.append(f"mass       {r.mass_kg:g} kg")
        if r.kind == "sweep":
            st = self.steps
            cyc = st["n_cycles"]
            lines.append(
                f"steps      {len(st)}, Gamma {st['gamma'].min():g} .. {st['gamma'].max():g}, "
                f"drive {r.drive_frequency_hz:g} Hz, {cyc.min():.4g} .. {cyc.max():.4g} cycles "
                f"per step (first {r.settle_cycles} discarded)"
            )
            gaps = ", ".join(f"{lo:g} .. {hi:g}" for lo, hi in self.gaps) or "none"
            lines.append(f"gaps       Gamma {gaps}")
        else:
            lines.append(
                f"drop       height {r.drop_height_m:g} m, released at t = {r.release_t_s:g} s"
            )
        for w in self.warnings:
            lines.append(f"warning    {w}")
        lines.append("ok")
        return "\n".join(lines)


def _warnings(run: Run, rec: Recording, steps: pd.DataFrame, problem: str | None) -> list[str]:
    """The report's warnings; ``problem``: :func:`extract_problem` of the run."""
    out = []
    unknown = [str(k) for k in run.extra if k not in EXTENSION_KEYS]
    if unknown:
        out.append(f"unknown keys kept and ignored: {', '.join(unknown)}")
    if run.extra_channels:
        out.append(f"unknown channel roles ignored: {', '.join(map(str, run.extra_channels))}")
    if not run.is_audio and run.full_scale_v != 1.0:
        out.append("full_scale_v applies to audio only; ignored for this format")
    if rec.time_s is not None and rec.n_samples > 1:
        dt = float(np.median(np.diff(rec.time_s)))
        if abs(dt * run.sample_rate_hz - 1.0) > 0.01:
            out.append(
                f"time_s spacing {dt:.6g} s disagrees with sample_rate_hz "
                f"{run.sample_rate_hz:g} (1/fs = {1 / run.sample_rate_hz:.6g} s)"
            )
    if "accel" in run.channels and run.accel_v_per_g is None:
        out.append("accel channel without accel_v_per_g: accelerations stay in volts")
    if run.kind == "drop" and run.gamma_steps:
        out.append("gamma_steps ignored in a drop run")
    for misplaced in (
        steps_after_end(run, rec.duration_s),
        steps_before_start(run, rec.t_start_s),
    ):
        if misplaced:
            out.append(misplaced)
    if run.kind == "sweep" and len(steps):
        short = steps.index[steps["n_cycles"] <= run.settle_cycles].tolist()
        if short:
            out.append(
                f"{len(short)} step(s) no longer than settle_cycles ({run.settle_cycles} cycles),"
                f" e.g. step {short[0]}: no settled flights there"
            )
    if problem:
        out.append(f"{problem}; extract and calibrate will fail")
    elif rec.channels["continuity"].size and np.ptp(rec.channels["continuity"]) == 0:
        out.append("continuity channel is constant: no contact edges to find")
    elif contacts_expected(run, steps):
        from bouncelab.flights.coupling import ac_coupling_tau

        tau = ac_coupling_tau(rec.channels["continuity"], rec.fs)
        if tau is not None:
            out.append(
                "continuity channel drains towards its mean as through an AC-coupled "
                f"input (a sound card's; corner {1 / (2 * np.pi * tau):.3g} Hz): "
                "extract and calibrate undo it (docs/flights.md)"
            )
    gaps = time_gaps(rec.time_s, rec.fs)
    if gaps:
        out.append(gaps)
    out.extend(clipped_channels(run, rec))
    drive = rec.channels.get("drive")
    if run.kind == "sweep" and drive is not None and run.drive_frequency_hz and len(steps):
        from bouncelab.flights.extract import drive_frequencies
        from bouncelab.flights.phase import drive_frequency_warning

        f = run.drive_frequency_hz
        measured = drive_frequencies(drive, steps, rec.fs, f, rec.time_s)
        warning = drive_frequency_warning(list(measured.values()), f)
        if warning:
            out.append(warning)
    return out


def time_gaps(time_s: np.ndarray | None, fs: float) -> str | None:
    """One line on the jumps of a ``time_s`` axis longer than 1.5 sample intervals
    (samples missing: a DAQ's buffer overrun), None without any. The extraction leaves
    out the flights across them (:func:`bouncelab.flights.extract.gap_mask`)."""
    if time_s is None or time_s.shape[0] < 2:
        return None
    step = np.diff(time_s)
    jumps = np.flatnonzero(step > 1.5 / fs)
    if jumps.size == 0:
        return None
    j = jumps[np.argmax(step[jumps])]
    return (
        f"time_s jumps by more than 1.5 sample intervals at {jumps.size} place(s), "
        f"{1e3 * float(np.sum(step[jumps] - 1.0 / fs)):.3g} ms missing in all (the "
        f"largest {1e3 * float(step[j]):.3g} ms after t = {float(time_s[j]):.6g} s): "
        "samples missing there; flights across a jump are left out"
    )


def clipped_channels(run: Run, rec: Recording) -> list[str]:
    """One line per audio channel side held at the input's full scale (``full_scale_v``):
    a level beyond the sound card's range, read flat. The edges on that side lose
    their shape (a probe's contact level 30 % beyond full scale: flight times 13 us
    short, median, at 20 kHz). [] for other formats, whose range is not known."""
    if not run.is_audio:
        return []
    out = []
    full = float(run.full_scale_v)
    for role, x in rec.channels.items():
        if not x.size:
            continue
        for sign, name in ((1.0, "+"), (-1.0, "-")):
            share = np.count_nonzero(sign * x >= full * (1.0 - CLIP_TOL)) / x.size
            if share >= CLIP_SHARE:
                out.append(
                    f"{role} channel at {name}{full:g} V, the input's full scale, in "
                    f"{100 * share:.2g} % of its samples: clipped, a level beyond the input's "
                    "range read flat, which shifts edge times (lower the input gain)"
                )
    return out


#: A continuity channel sits at two levels: in a block of ``TWO_LEVEL_BLOCK_S`` with both
#: levels, at least ``TWO_LEVEL_MIN`` of its samples lie within ``TWO_LEVEL_BAND`` of the
#: block's gap of one of them (a sine: 2/3; a two-level channel under a 20 % hum: ~1).
TWO_LEVEL_BLOCK_S, TWO_LEVEL_BAND, TWO_LEVEL_MIN, TWO_LEVEL_BLOCKS = 0.2, 0.25, 0.85, 200
#: ... and a drive channel is taken for a continuity one from this share on (a sine
#: clipped at 60 % of its amplitude reads about 0.8)
TWO_LEVEL_DRIVE = 0.95


def two_level_share(x: np.ndarray, fs: float) -> float | None:
    """Median over blocks of the share of samples (n,) within :data:`TWO_LEVEL_BAND` of
    the gap of the block's low or high level (1st and 99th percentiles), over up to
    :data:`TWO_LEVEL_BLOCKS` blocks spread over ``x`` whose gap is at least a fifth of the
    whole channel's; None where no block has one (a channel at one level)."""
    n = x.shape[0]
    size = max(int(TWO_LEVEL_BLOCK_S * fs), 64)
    if n < size:
        return None
    lo_all, hi_all = np.percentile(x[:: max(n // 200_000, 1)], [1, 99])
    shares = []
    for a in np.unique(np.linspace(0, n - size, TWO_LEVEL_BLOCKS).astype(np.int64)):
        b = np.asarray(x[a : a + size], dtype=np.float64)
        lo, hi = np.percentile(b, [1, 99])
        gap = hi - lo
        if not gap > 0.2 * (hi_all - lo_all):
            continue
        near = (np.abs(b - lo) < TWO_LEVEL_BAND * gap) | (np.abs(b - hi) < TWO_LEVEL_BAND * gap)
        shares.append(float(near.mean()))
    return float(np.median(shares)) if shares else None


def swapped_channels(rec: Recording) -> str | None:
    """Why the continuity and drive channels look swapped in run.yaml, or None: the
    continuity channel does not sit at two levels (:func:`two_level_share`) while the
    drive channel does (which no drive does: the continuity channel alone can read low,
    blind `chaos_seed_like_b` 0.23, a 20 % hum 0.77). A probe's WAV with the two
    swapped was extracted into 2045 invented flights and diagnosed, every command
    exiting 0."""
    drive = rec.channels.get("drive")
    if drive is None:
        return None
    cont = two_level_share(rec.channels["continuity"], rec.fs)
    other = two_level_share(drive, rec.fs)
    if cont is None or other is None or cont >= TWO_LEVEL_MIN or other < TWO_LEVEL_DRIVE:
        return None
    return (
        f"the continuity channel does not sit at two levels ({100 * cont:.0f} % of its "
        f"samples near them, a sine gives 67 %) while the drive channel does "
        f"({100 * other:.0f} %): are the two swapped in run.yaml's channels?"
    )


def contacts_expected(run, steps: pd.DataFrame) -> bool:
    """Whether the body must leave the plate in this run: a drop, or a sweep with a
    step at Gamma 1 or more (below it the body rests, and no contact is no fault)."""
    return run.kind == "drop" or bool(len(steps) and (steps["gamma"] >= 1.0).any())


def extract_problem(run, rec: Recording, steps: pd.DataFrame) -> str | None:
    """Why extracting the run's flights will fail, or None (:class:`ValidationReport`'s
    ``extract_problem``): continuity and drive channels swapped
    (:func:`swapped_channels`); where contacts are expected (:func:`contacts_expected`),
    a constant continuity channel or one with no contacts to find (:func:`_no_contacts`)."""
    swapped = swapped_channels(rec)
    if swapped:
        return swapped
    if not contacts_expected(run, steps):
        return None
    x = rec.channels["continuity"]
    if x.size and np.ptp(x) == 0:
        return "the continuity channel is constant: no contact edges to find"
    return _no_contacts(rec)


def _no_contacts(rec: Recording) -> str | None:
    """Why the continuity channel holds no contact to find, or None: the detection's own
    test (:func:`bouncelab.flights.detect.detect_contacts`, a few tenths of a second on a
    20-minute recording), so that validate says what extract would."""
    from bouncelab.flights.detect import NoContactsError, detect_contacts

    try:
        detect_contacts(rec.channels["continuity"], sample_rate_hz=rec.fs)
    except NoContactsError as exc:
        return exc.problem
    except BouncelabError:
        return None  # another fault of the signal: extract names it
    return None


def validate_run(run_dir: str | Path) -> ValidationReport:
    """Check a run folder completely (run.yaml and every sample) and report it.

    Raises
    ------
    BouncelabError
        The first problem found, naming the file (see :func:`load_run` and
        :func:`read_recording` for the checks).
    """
    run = load_run(run_dir)
    rec = read_recording(run, ROLES)
    steps = step_table(run, rec.duration_s)
    problem = extract_problem(run, rec, steps)
    channels = [
        ChannelSummary(
            role,
            run.channels[role],
            float(np.min(arr)),
            float(np.max(arr)),
            str(arr.dtype),
        )
        for role, arr in rec.channels.items()
    ]
    return ValidationReport(
        run=run,
        fs=rec.fs,
        n_samples=rec.n_samples,
        t_start_s=rec.t_start_s,
        duration_s=rec.duration_s,
        has_time_column=rec.time_s is not None,
        channels=channels,
        steps=steps,
        gaps=gamma_gaps(steps["gamma"]) if run.kind == "sweep" else [],
        warnings=_warnings(run, rec, steps, problem),
        extract_problem=problem,
    )


__all__ = ["TIME_COLUMN", "ValidationReport", "gamma_gaps", "step_table", "validate_run"]
