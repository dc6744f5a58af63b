"""The flight table of a run (CONTRACTS.md section 3) and its QC table per step.

:func:`extract_run` reads a run folder with :mod:`bouncelab.runs` (so every check of
the run format applies), detects the contacts (:func:`detect_contacts`), turns edges
into flights, assigns each to its Gamma step by takeoff time and adds the drive phase.
:func:`flights_from_detection` does the same on arrays, for tests and other callers.
"""

from __future__ import annotations

import logging
import math
from pathlib import Path

import numpy as np
import pandas as pd

from bouncelab.errors import BouncelabError, collected_warnings
from bouncelab.flights.coupling import ac_coupling_tau, undo_ac_coupling
from bouncelab.flights.detect import (
    BOUNCE_MAX,
    BOUNCE_RATIO,
    BOUNCE_WINDOW_S,
    HELD_BAND,
    HELD_MIN_S,
    HELD_TAU,
    Detection,
    NoContactsError,
    detect_contacts,
    held_stretches,
    interference_removed,
    without_switch_bounce,
)
from bouncelab.flights.phase import (
    MIN_FREQUENCY_CYCLES,
    TWO_PI,
    dominant_frequency,
    fit_sine,
    phase_at,
)

FLIGHT_COLUMNS = [
    "run",
    "step",
    "gamma",
    "t_takeoff_s",
    "t_landing_s",
    "flight_s",
    "T",
    "phi_takeoff",
    "phi_landing",
    "settled",
    "contact_before_s",
]
#: The words that open the extraction's warning of a drive channel at another frequency
#: than run.yaml's (the diagnosis says it once, :func:`bouncelab.gap.diagnose.extraction_warnings`).
DRIVE_CHANNEL_LINE = "the drive channel runs at"

QC_COLUMNS = [
    "run",
    "step",
    "gamma",
    "t_start_s",
    "t_end_s",
    "flights",
    "flights_settled",
    "glitches",
    "noise_v",
    "level_gap_v",
    "contact_fraction",
    "tau_rc_s",
    "interference_v",
    "drive_amplitude_v",
    "drive_noise_v",
    "drive_frequency_hz",
]


def sample_times(idx: np.ndarray, fs: float, time_s: np.ndarray | None) -> np.ndarray:
    """Times (s) of fractional sample indices: ``idx / fs``, or interpolated in ``time_s``."""
    idx = np.asarray(idx, dtype=np.float64)
    if time_s is None:
        return idx / fs
    k = np.arange(time_s.shape[0], dtype=np.float64)
    # beyond the ends (sub-sample edges before sample 0) extrapolate at the nominal rate
    t = np.interp(idx, k, time_s)
    t = np.where(idx < 0, time_s[0] + idx / fs, t)
    last = time_s.shape[0] - 1
    return np.where(idx > last, time_s[-1] + (idx - last) / fs, t)


def gap_mask(idx_a: np.ndarray, idx_b: np.ndarray, fs: float, time_s) -> np.ndarray:
    """True where the sample range ``[floor(a), ceil(b)]`` contains a data gap (a jump
    of the ``time_s`` axis longer than 1.5 sample periods)."""
    if time_s is None or time_s.shape[0] < 2:
        return np.zeros(np.shape(idx_a), dtype=bool)
    jumps = np.flatnonzero(np.diff(time_s) > 1.5 / fs)  # gap between sample j and j+1
    if jumps.size == 0:
        return np.zeros(np.shape(idx_a), dtype=bool)
    lo = np.floor(idx_a).astype(np.int64) - 1
    hi = np.ceil(idx_b).astype(np.int64)
    # any jump j with lo <= j < hi
    first = np.searchsorted(jumps, lo, side="left")
    return (first < jumps.size) & (jumps[np.minimum(first, jumps.size - 1)] < hi)


def flights_from_detection(
    det: Detection,
    fs: float,
    steps: pd.DataFrame,
    drive_freq_hz: float | None = None,
    settle_cycles: int = 10,
    time_s: np.ndarray | None = None,
    phase_fits: dict | None = None,
    phase_offset_rad: float = 0.0,
    run_id: str = "",
    phase_freq_hz: float | dict | None = None,
) -> pd.DataFrame:
    """Flight table (CONTRACTS.md section 3 columns plus ``contact_before_s``).

    Parameters
    ----------
    det : Detection of the continuity channel.
    fs : sampling rate, Hz.
    steps : DataFrame with ``step``, ``gamma``, ``t_start_s``, ``t_end_s`` (s); a flight
        belongs to the step its takeoff falls in; flights outside every step are dropped.
    drive_freq_hz : drive frequency (Hz) for ``T`` and ``settled``; None gives NaN ``T``
        and every flight settled.
    settle_cycles : drive cycles after each step start whose flights are not settled.
    time_s : (n,) sample times or None (``index / fs``).
    phase_fits : step -> SineFit of the drive channel (None or missing: NaN phases).
    phase_offset_rad : how far the drive reference leads the plate, rad.
    phase_freq_hz : the frequency (Hz) the phases advance at and ``phase_fits`` were
        fitted at (:func:`phase_frequency`), or step -> Hz (:func:`phase_frequencies`);
        None: ``drive_freq_hz``. ``T`` and
        ``settled`` always take ``drive_freq_hz`` (CONTRACTS.md section 3).
    """
    ta_i, tl_i = det.flights()
    ok = ~gap_mask(ta_i, tl_i, fs, time_s)
    ta_i, tl_i = ta_i[ok], tl_i[ok]
    t_take = sample_times(ta_i, fs, time_s)
    t_land = sample_times(tl_i, fs, time_s)
    # contact that precedes each flight (NaN when cut by the recording's start)
    c_start, c_end = det.contacts()
    j = np.searchsorted(c_end, ta_i) if c_end.size else np.zeros(ta_i.shape, dtype=int)
    has = (j < c_end.size) & (c_end[np.minimum(j, max(c_end.size - 1, 0))] == ta_i)
    cb = np.full(ta_i.shape, np.nan)
    if c_end.size:
        jj = np.minimum(j, c_end.size - 1)
        cb = np.where(has, (c_end[jj] - c_start[jj]) / fs, np.nan)
    st = steps.sort_values("t_start_s")
    k = np.searchsorted(st["t_start_s"].to_numpy(), t_take, side="right") - 1
    inside = k >= 0
    if len(st):
        kk = np.maximum(k, 0)
        inside &= t_take < st["t_end_s"].to_numpy()[kk]
    else:
        inside &= False
    t_take, t_land, k, cb = t_take[inside], t_land[inside], k[inside], cb[inside]
    step_ids = st["step"].to_numpy()[k]
    gammas = st["gamma"].to_numpy(dtype=np.float64)[k]
    t0 = st["t_start_s"].to_numpy(dtype=np.float64)[k]
    flight = t_land - t_take
    if drive_freq_hz:
        big_t = TWO_PI * drive_freq_hz * flight
        settled = (t_take - t0) >= settle_cycles / drive_freq_hz
    else:
        big_t = np.full(flight.shape, np.nan)
        settled = np.ones(flight.shape, dtype=bool)
    phi_t = np.full(flight.shape, np.nan)
    phi_l = np.full(flight.shape, np.nan)
    if phase_fits and drive_freq_hz:
        for s, fit in phase_fits.items():
            m = step_ids == s
            if m.any():
                if isinstance(phase_freq_hz, dict):
                    f_phase = phase_freq_hz.get(s, drive_freq_hz)
                else:
                    f_phase = phase_freq_hz or drive_freq_hz
                phi_t[m] = phase_at(t_take[m], fit, f_phase, phase_offset_rad)
                phi_l[m] = phase_at(t_land[m], fit, f_phase, phase_offset_rad)
    nan_g = gammas <= 0  # the plate is at rest: no phase
    phi_t[nan_g] = np.nan
    phi_l[nan_g] = np.nan
    return pd.DataFrame(
        {
            "run": pd.Series([run_id] * flight.size, dtype=object),
            "step": step_ids.astype(np.int64),
            "gamma": gammas,
            "t_takeoff_s": t_take,
            "t_landing_s": t_land,
            "flight_s": flight,
            "T": big_t,
            "phi_takeoff": phi_t,
            "phi_landing": phi_l,
            "settled": settled.astype(bool),
            "contact_before_s": cb,
        },
        columns=FLIGHT_COLUMNS,
    )


def _drop_steps(duration_s: float, t_first: float) -> pd.DataFrame:
    """A drop run has one pseudo-step: Gamma 0 (plate at rest) over the whole recording."""
    return pd.DataFrame(
        {"step": [0], "gamma": [0.0], "t_start_s": [t_first], "t_end_s": [duration_s]}
    )


def _qc_table(run_id, steps, det, fs, time_s, flights, fits, drive_present, freqs) -> pd.DataFrame:
    """QC per step: flights, glitches, noise, level gap, contact fraction, RC, drive fit
    and the drive's measured frequency (``freqs``: step -> Hz)."""
    rows = []
    tau_s = det.tau_samples / fs if det is not None else np.nan
    if det is not None:
        nb = det.n_glitch.shape[0]
        centres = sample_times((np.arange(nb) + 0.5) * det.block, fs, time_s)
        sizes = np.minimum(det.block, det.n_samples - np.arange(nb) * det.block)
    for row in steps.itertuples(index=False):
        f = flights[flights["step"] == row.step]
        rec = {
            "run": run_id,
            "step": int(row.step),
            "gamma": float(row.gamma),
            "t_start_s": float(row.t_start_s),
            "t_end_s": float(row.t_end_s),
            "flights": int(len(f)),
            "flights_settled": int(f["settled"].sum()),
            "glitches": 0,
            "noise_v": np.nan,
            "level_gap_v": np.nan,
            "contact_fraction": np.nan,
            "tau_rc_s": tau_s,
            "interference_v": np.nan,
            "drive_amplitude_v": np.nan,
            "drive_noise_v": np.nan,
            "drive_frequency_hz": freqs.get(int(row.step), np.nan),
        }
        if det is not None:
            m = (centres >= row.t_start_s) & (centres < row.t_end_s)
            if m.any():
                rec["glitches"] = int(det.n_glitch[m].sum())
                rec["noise_v"] = float(np.median(det.noise_v[m]))
                rec["level_gap_v"] = float(np.median(np.abs(det.contact_v - det.open_v)[m]))
                rec["contact_fraction"] = float(det.n_contact[m].sum() / sizes[m].sum())
                if det.interference_v.shape[0] == nb:
                    rec["interference_v"] = float(np.median(det.interference_v[m]))
        fit = fits.get(int(row.step)) if drive_present else None
        if fit is not None:
            rec["drive_amplitude_v"] = fit.amplitude
            rec["drive_noise_v"] = fit.noise
        rows.append(rec)
    return pd.DataFrame(rows, columns=QC_COLUMNS)


def _step_slice(t0, t1, fs, time_s, n):
    """Sample index range [a, b) of the time window [t0, t1), s."""
    if time_s is None:
        return max(0, int(np.ceil(t0 * fs))), min(n, int(np.ceil(t1 * fs)))
    return int(np.searchsorted(time_s, t0)), int(np.searchsorted(time_s, t1))


#: Relative difference between the drive channel's measured frequency (median over the
#: steps) and run.yaml's beyond which the phases follow the measured one: 10 times the
#: largest of the shipped runs' (2.3e-5), whose drives run at the stated frequency.
PHASE_FREQUENCY_TOLERANCE = 2e-4


def phase_frequency(freqs: dict, stated_hz: float) -> float:
    """The frequency (Hz) the drive phases advance at: the drive channel's own, the
    median of ``freqs`` (step -> Hz, :func:`drive_frequencies`), where it differs from
    ``stated_hz`` by more than :data:`PHASE_FREQUENCY_TOLERANCE`; else ``stated_hz``.

    Why: a sine fitted at the stated frequency gives each step one phase, right at its
    middle and off by ``pi df t`` towards its ends. A second black-box probe's drive at
    30.045 Hz stated as 30 Hz (0.15 %, under validate's 0.2 % warning) had phases a
    median 0.14 rad off (0.28 at the 99th percentile), and 0.47 rad at 0.5 %; the
    phases are of the plate, whose frequency the channel measures to 0.01 %.
    """
    measured = np.asarray(list(freqs.values()), dtype=np.float64)
    measured = measured[np.isfinite(measured)]
    if measured.size == 0 or not stated_hz:
        return float(stated_hz)
    median = float(np.median(measured))
    if abs(median / stated_hz - 1.0) > PHASE_FREQUENCY_TOLERANCE:
        return median
    return float(stated_hz)


#: Phase error (rad) at a step's ends beyond which each step's phases follow its own
#: measured drive frequency (:func:`phase_frequencies`): 6 times the largest of the
#: shipped runs' (0.0035, the estimates' own scatter over 2-s steps), where a probe's
#: drive drifting 0.3 % over the run put it at 0.29.
PHASE_DRIFT_RAD = 0.02


def phase_frequencies(freqs: dict, common_hz: float, steps: pd.DataFrame) -> dict:
    """The frequency (Hz) each step's drive phases advance at (step -> Hz).

    ``common_hz`` (:func:`phase_frequency`) for every step, unless the drive's frequency
    drifts within the run: where some step's own measured frequency (``freqs``: step ->
    Hz, :func:`drive_frequencies`, NaN where unknown) puts its ends more than
    :data:`PHASE_DRIFT_RAD` off the common one (``pi |f_step - f| duration``), each step
    with a measured frequency takes its own. Why: a phase re-anchored at each step's
    middle drifts from the plate's towards the step's ends; a probe's drive going 30.000
    to 30.090 Hz over a run (+0.3 %, an oscillator warming up) had a sawtooth error of up
    to 0.31 rad in every step. ``steps``: the step table (``step``, ``t_start_s``,
    ``t_end_s``, s).
    """
    ids = steps["step"].to_numpy(dtype=np.int64)
    durations = (steps["t_end_s"] - steps["t_start_s"]).to_numpy(dtype=np.float64)
    common = {int(s): float(common_hz) for s in ids}
    own = {
        int(s): float(freqs[int(s)]) for s in ids if int(s) in freqs and np.isfinite(freqs[int(s)])
    }
    off = [
        abs(own[int(s)] - common_hz) * d
        for s, d in zip(ids, durations, strict=True)
        if int(s) in own
    ]
    worst = np.pi * max(off, default=0.0)
    if worst <= PHASE_DRIFT_RAD:
        return common
    return common | own


def drive_fits(drive, steps, fs, freq_hz, time_s) -> dict:
    """SineFit of the drive channel per step (step -> SineFit) at ``freq_hz`` (Hz: one
    for all steps, or step -> Hz, :func:`phase_frequencies`); the first settle cycles
    are kept: the phase of the reference does not jump at a step change."""
    fits = {}
    n = drive.shape[0]
    for row in steps.itertuples(index=False):
        a, b = _step_slice(row.t_start_s, row.t_end_s, fs, time_s, n)
        if b - a < 8:
            continue
        t = np.arange(a, b) / fs if time_s is None else time_s[a:b]
        f = freq_hz[int(row.step)] if isinstance(freq_hz, dict) else freq_hz
        fits[int(row.step)], _ = fit_sine(t, drive[a:b], f)
    return fits


def drive_frequencies(drive, steps, fs, freq_hz, time_s) -> dict:
    """The drive channel's frequency (Hz) per step (step -> Hz,
    :func:`bouncelab.flights.phase.dominant_frequency`; NaN where it shows no clear line,
    as with the plate at rest) for the steps of at least ``MIN_FREQUENCY_CYCLES`` cycles
    of the stated ``freq_hz``. The samples are taken as spaced ``1 / fs``: where the
    ``time_s`` axis jumps within a step (samples missing), its longest stretch without
    a jump is read. Not the sine fits' frequency: those take the stated one, and lose
    the signal when it is wrong."""
    out = {}
    n = drive.shape[0]
    for row in steps.itertuples(index=False):
        a, b = _step_slice(row.t_start_s, row.t_end_s, fs, time_s, n)
        a, b = _longest_even_stretch(a, b, fs, time_s)
        if (b - a) * freq_hz >= MIN_FREQUENCY_CYCLES * fs:
            out[int(row.step)] = dominant_frequency(drive[a:b], fs)
    return out


def _longest_even_stretch(a: int, b: int, fs: float, time_s) -> tuple[int, int]:
    """The longest part ``[a', b')`` of the samples ``[a, b)`` whose ``time_s`` does not
    jump by more than 1.5 sample intervals (:func:`gap_mask`'s jumps); ``(a, b)`` itself
    without a ``time_s`` axis or a jump."""
    if time_s is None or b - a < 2:
        return a, b
    jumps = np.flatnonzero(np.diff(time_s[a:b]) > 1.5 / fs) + 1  # a stretch starts there
    if jumps.size == 0:
        return a, b
    starts = np.concatenate(([0], jumps))
    ends = np.concatenate((jumps, [b - a]))
    k = int(np.argmax(ends - starts))
    return a + int(starts[k]), a + int(ends[k])


#: A takeoff after a contact of at least this many drive cycles is a takeoff from rest.
STUCK_CYCLES = 0.25
#: Takeoffs from rest a polarity needs before its phases can judge it.
MIN_STUCK_TAKEOFFS = 20
#: Share of takeoffs from rest in the plate's falling half-cycle that refutes a polarity,
#: and the share the other polarity must reach to replace it.
REFUTED_SHARE, CONFIRMED_SHARE = 0.25, 0.75
#: Share of the recording in contact at or above which the share-of-time polarity rule
#: is in doubt: checked by the drive's phases, or warned about without a drive channel
#: (a wrong reading at Gamma 1.1-1.6 holds 38-47 %; a right one at Gamma >= 2 under 30 %).
DOUBTFUL_CONTACT_SHARE = 0.35


def stuck_takeoff_share(flights: pd.DataFrame, drive_freq_hz: float) -> tuple[float, int]:
    """Share of the takeoffs from rest that fall where the plate accelerates downward.

    A body resting on the plate can leave it only where the plate accelerates down (at
    g, plus friction's share, on a sinusoidal plate: drive phase ``asin((1 + mu) /
    Gamma)``), in the half-cycle ``0 < phi < pi`` of drive phase (zero at the upward
    zero crossing of the plate's position): a harmonic, an armature or a drive reference
    that lags the plate move it by a few tenths of a radian, not out of that half (the
    virtual rig's armature puts it at 1.55 rad at Gamma 1.15-1.35). The takeoffs after
    a contact of at least :data:`STUCK_CYCLES` cycles, at Gamma > 1 with a drive phase,
    are such takeoffs if the polarity is right; with the levels swapped they are
    landings, which at the Gammas where flights are shorter than contacts fall in the
    other half-cycle (3.4-4.1 rad at Gamma 1.15-1.35).

    Returns
    -------
    (the share in [0, 1], or NaN; the number of takeoffs from rest it is over)
    """
    phi = flights["phi_takeoff"].to_numpy(dtype=float)
    gamma = flights["gamma"].to_numpy(dtype=float)
    stuck = flights["contact_before_s"].to_numpy(dtype=float) >= STUCK_CYCLES / drive_freq_hz
    m = stuck & np.isfinite(phi) & (gamma > 1.0)
    if not m.any():
        return float("nan"), 0
    return float(np.mean(np.sin(phi[m]) > 0.0)), int(m.sum())


def polarity_refuted(flights, other_flights, drive_freq_hz: float) -> bool:
    """Whether the takeoff phases refute the polarity of ``flights`` and confirm that of
    ``other_flights`` (the same channel read with the levels swapped); see
    :func:`stuck_takeoff_share`. Both need :data:`MIN_STUCK_TAKEOFFS` takeoffs from rest.
    """
    here, n_here = stuck_takeoff_share(flights, drive_freq_hz)
    there, n_there = stuck_takeoff_share(other_flights, drive_freq_hz)
    enough = min(n_here, n_there) >= MIN_STUCK_TAKEOFFS
    return bool(enough and here < REFUTED_SHARE and there > CONFIRMED_SHARE)


def contact_share(det: Detection, n_samples: int) -> float:
    """Share of the recording's samples that the detection reads as contact, in [0, 1]."""
    return float(det.n_contact.sum() / max(n_samples, 1))


def _polarity_in_doubt(run, rest, det: Detection, n_samples: int) -> bool:
    """Whether ``auto`` read the levels by the share of time alone (a sweep with no step
    below Gamma 1 to rest on) and the contacts it read hold :data:`DOUBTFUL_CONTACT_SHARE`
    of the recording or more, where that share cannot tell which level is contact. Below
    it flights clearly dominate, the share is right, and nothing second-guesses it (a
    drive channel wired inverted would otherwise turn a right reading round)."""
    if run.contact_level != "auto" or run.kind != "sweep" or rest:
        return False
    return contact_share(det, n_samples) >= DOUBTFUL_CONTACT_SHARE


def extract_run(run_dir: str | Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """Flight table and QC table of one run folder.

    Returns
    -------
    flights : DataFrame, one row per flight, columns :data:`FLIGHT_COLUMNS`.
    qc : DataFrame, one row per Gamma step (one for a drop run), :data:`QC_COLUMNS`;
        ``qc.attrs["warnings"]``: the warnings logged while reading and extracting the
        run (list of str, each naming its file; :func:`bouncelab.errors.collected_warnings`),
        kept in a Parquet file's metadata by :func:`bouncelab.tables.write_table` so that
        the diagnosis can carry them.

    Raises
    ------
    BouncelabError
        Anything :func:`bouncelab.runs.read_recording` rejects; a continuity channel stuck
        at one rail; "no contacts found" (except for a sweep whose steps all have
        Gamma < 1, where the body never leaves the plate: no flights, no error).
    """
    with collected_warnings() as warnings:
        flights, qc = _extract_run(run_dir)
    qc.attrs["warnings"] = list(warnings)
    return flights, qc


def _extract_run(run_dir: str | Path) -> tuple[pd.DataFrame, pd.DataFrame]:
    """:func:`extract_run` without the collection of its warnings."""
    from bouncelab.runs import load_run, read_recording, step_table
    from bouncelab.runs.validate import (
        steps_after_end,
        steps_before_start,
        swapped_channels,
        time_gaps,
    )

    run = load_run(run_dir)
    rec = read_recording(run, roles=("continuity", "drive"))
    fs = float(rec.fs)
    swapped = swapped_channels(rec)
    if swapped:
        raise BouncelabError(run.yaml_path, swapped)
    x = rec.channels["continuity"]
    drive = rec.channels.get("drive")
    tau_ac = ac_coupling_tau(x, fs)
    if tau_ac is not None:
        # the drive channel came through the same input: its phase led by atan(fc / f)
        x = undo_ac_coupling(x, fs, tau_ac)
        drive = undo_ac_coupling(drive, fs, tau_ac) if drive is not None else None
        logging.getLogger(__name__).warning(
            "%s: the continuity channel drains towards its mean as through an AC-coupled "
            "input (a sound card's; corner %.3g Hz, time constant %.3g s): undone, on the "
            "drive channel too, before the detection",
            rec.path,
            1.0 / (2.0 * np.pi * tau_ac),
            tau_ac,
        )
    time_s = rec.time_s
    n = rec.n_samples
    if run.kind == "drop":
        steps = _drop_steps(rec.duration_s, rec.t_start_s)
        freq = None
    else:
        steps = step_table(run, rec.duration_s)[["step", "gamma", "t_start_s", "t_end_s"]]
        freq = run.drive_frequency_hz
        for misplaced in (
            steps_after_end(run, rec.duration_s),
            steps_before_start(run, rec.t_start_s),
        ):
            if misplaced:
                logging.getLogger(__name__).warning("%s: %s", run.yaml_path, misplaced)
    gaps = time_gaps(time_s, fs)
    if gaps:
        logging.getLogger(__name__).warning("%s: %s", rec.path, gaps)
    rest, opened = [], []
    for row in steps.itertuples(index=False):
        if run.kind == "sweep" and row.gamma < 1.0:
            rest.append(_step_slice(row.t_start_s, row.t_end_s, fs, time_s, n))
    if run.kind == "drop" and run.release_t_s is not None:
        opened.append(_step_slice(rec.t_start_s, run.release_t_s, fs, time_s, n))
    try:
        det = detect_contacts(x, run.contact_level, rest, opened, path=rec.path, sample_rate_hz=fs)
    except NoContactsError:
        if run.kind == "sweep" and len(steps) and bool((steps["gamma"] < 1.0).all()):
            det = None  # the body rests all along: no flights, and that is right
        else:
            raise
    n_bounce = 0
    if det is not None:
        det, n_bounce = without_switch_bounce(det, fs)
    if det is not None and det.ringing > 0:
        logging.getLogger(__name__).warning(
            "%s: the continuity channel moves before its edges (%.2g of the level gap, "
            "robust size), as behind a linear-phase anti-alias filter (a sound card's): "
            "its lobes are taken as noise, so contacts or flights that fill less than "
            "about %.2g of a sample interval are not seen",
            rec.path,
            det.ringing,
            min(6.0 * det.ringing, 0.45),
        )
    if det is not None:
        _warn_held_levels(x, det, fs, rec.path, time_s)
    fits, freqs, phase_freq = {}, {}, freq
    if drive is not None and freq:
        freqs = drive_frequencies(drive, steps, fs, freq, time_s)
        phase_freq = phase_frequency(freqs, freq)
        if phase_freq != freq:
            logging.getLogger(__name__).warning(
                "%s: " + DRIVE_CHANNEL_LINE + " %.4f Hz, %+.2f %% from drive_frequency_hz "
                "%g: the drive phases follow the channel; T and settle cycles use the "
                "stated value",
                rec.path,
                phase_freq,
                100 * (phase_freq / freq - 1.0),
                freq,
            )
        step_freqs = phase_frequencies(freqs, phase_freq, steps)
        if len(set(step_freqs.values())) > 1:
            own = np.array([freqs[s] for s in step_freqs if s in freqs and np.isfinite(freqs[s])])
            logging.getLogger(__name__).warning(
                "%s: the drive channel's frequency changes over the run (%.4f to %.4f Hz "
                "over the steps, %.2f %% of %g): each step's drive phases follow its own",
                rec.path,
                own.min(),
                own.max(),
                100 * np.ptp(own) / freq,
                freq,
            )
            phase_freq = step_freqs
        fits = drive_fits(drive, steps, fs, phase_freq, time_s)
    offset = float(run.extra.get("drive_phase_offset_rad", 0.0) or 0.0)
    if det is None:
        flights = pd.DataFrame({c: [] for c in FLIGHT_COLUMNS})
        flights = flights.astype(
            {"step": np.int64, "settled": bool, "run": object}
            | {c: np.float64 for c in FLIGHT_COLUMNS if c not in ("run", "step", "settled")}
        )
    else:

        def flights_of(d: Detection) -> pd.DataFrame:
            return flights_from_detection(
                d, fs, steps, freq, run.settle_cycles, time_s, fits, offset, run.run_id, phase_freq
            )

        flights = flights_of(det)
        if _polarity_in_doubt(run, rest, det, n):
            if fits:
                # read the other way round; kept where the drive's phases of the takeoffs
                # from rest refute this reading and confirm that one
                level = "low" if det.contact_high else "high"
                other = detect_contacts(x, level, rest, opened, path=rec.path, sample_rate_hz=fs)
                other, n_other = without_switch_bounce(other, fs)
                other_flights = flights_of(other)
                if polarity_refuted(flights, other_flights, freq):
                    det, flights, n_bounce = other, other_flights, n_other
            else:
                logging.getLogger(__name__).warning(
                    "%s: contact level read as the level held less of the time (%.0f %%), "
                    "with no step below Gamma 1 to rest on and no drive channel to check it; "
                    "where contacts outlast flights (Gamma below about 1.5) that reading is "
                    "the wrong way round: set contact_level in run.yaml",
                    rec.path,
                    100 * contact_share(det, n),
                )
    if n_bounce:  # of the reading kept (the polarity's other one may have replaced it)
        _warn_bounce(n_bounce, rec.path)
    overlong = overlong_flights(flights)
    if overlong.any():
        logging.getLogger(__name__).warning("%s: %s", rec.path, overlong_line(flights, overlong))
    pressed = pressed_takeoffs(flights)
    if pressed.any():
        from_rest = int(
            (flights["contact_before_s"].to_numpy(dtype=np.float64) > PRESSED_REST_S).sum()
        )
        logging.getLogger(__name__).warning(
            "%s: %d of %d takeoff(s) from rest while the plate pushed the body up (sin of "
            "the drive phase below %g after a contact over %g ms; median flight %.3g ms): "
            "the continuity circuit opening while the body rests (a dirty or loose "
            "contact); where they are most, contacts and flights read the wrong way round "
            "(set contact_level in run.yaml) or a drive channel inverted or delayed (its "
            "phases off: drive_phase_offset_rad in run.yaml); or a plate far from a sine "
            "(a harmonic whose acceleration rivals the drive's, k^2 a near 1, moves where "
            "the plate pushes: the diagnosis fits one)",
            rec.path,
            int(pressed.sum()),
            from_rest,
            PRESSED_SIN,
            1e3 * PRESSED_REST_S,
            1e3 * float(flights["flight_s"][pressed].median()),
        )
    qc = _qc_table(run.run_id, steps, det, fs, time_s, flights, fits, drive is not None, freqs)
    return flights, qc


def _warn_bounce(n: int, path) -> None:
    """The warning on ``n`` openings :func:`without_switch_bounce` left out."""
    logging.getLogger(__name__).warning(
        "%s: %d opening(s) shorter than %g of a sample within %g ms of a landing after "
        "a flight %g times longer or more, read as a switch's contact bounce (or a "
        "rebound too small to resolve): left out, the contacts around each merged",
        path,
        n,
        BOUNCE_MAX,
        1e3 * BOUNCE_WINDOW_S,
        BOUNCE_RATIO,
    )


def _warn_held_levels(x, det: Detection, fs: float, path, time_s) -> None:
    """Warn of stretches where the channel sits between its levels (partial conduction)."""
    min_samples = max(round(HELD_MIN_S * fs), math.ceil(HELD_TAU * det.tau_samples))
    if det.interference_v.size and det.interference_v.max() > 0:
        x = interference_removed(x, fs, det.block)  # a hum's crests are no held level
    held = held_stretches(x, det, min_samples)
    if held.count == 0:
        return
    t0 = float(time_s[held.longest_start]) if time_s is not None else held.longest_start / fs
    logging.getLogger(__name__).warning(
        "%s: the continuity channel sits between its levels (%.0f-%.0f %% of the gap) in "
        "%d stretch(es) of %.3g ms or more, %.3g ms in all (longest %.3g ms at t = %.4g s): "
        "a contact that half-conducts (dirty or loose), or a body chattering faster than "
        "the sampling (on a plate that vibrates at random)? Each is read as one contact "
        "where it lies above the detection threshold, else as flight",
        path,
        100 * HELD_BAND[0],
        100 * HELD_BAND[1],
        held.count,
        1e3 * min_samples / fs,
        1e3 * held.samples / fs,
        1e3 * held.longest_len / fs,
        t0,
    )


#: A flight longer than this (rad of the drive, about 41 periods) is no flight: at 30 Hz
#: 1.4 s, a rise of 2.4 m. The circuit stayed open (a lead off, contacts too brief to
#: see); such a "flight" once stopped the diagnosis ("T >= 512").
OVERLONG_T_RAD = 256.0

#: The words that open :func:`overlong_line` (the diagnosis says it once).
OVERLONG_LINE = "flight(s) longer than"


def overlong_flights(flights: pd.DataFrame) -> np.ndarray:
    """(n,) bool: flights longer than :data:`OVERLONG_T_RAD` (the circuit open, not a
    flight); all False for a drop run's table (no drive: ``T`` is NaN)."""
    t = flights["T"].to_numpy(dtype=np.float64)
    with np.errstate(invalid="ignore"):
        return t > OVERLONG_T_RAD


def overlong_line(flights: pd.DataFrame, overlong: np.ndarray) -> str:
    """One line on the flights of ``overlong`` (the longest, its time and step)."""
    long = flights[overlong]
    i = int(np.argmax(long["flight_s"].to_numpy()))
    return (
        f"{int(overlong.sum())} {OVERLONG_LINE} {OVERLONG_T_RAD / (2 * np.pi):.0f} drive "
        f"periods (the longest {long['flight_s'].iloc[i]:.3g} s from t = "
        f"{long['t_takeoff_s'].iloc[i]:.4g} s, step {int(long['step'].iloc[i])}): the "
        "circuit stayed open far longer than the body can fly (a lead off, or contacts too "
        "brief to see); kept in the flight table, left out of the diagnosis"
    )


#: A takeoff after a contact longer than ``PRESSED_REST_S`` (the body rests or rides)
#: at a drive phase whose sine is below ``PRESSED_SIN`` (the plate accelerating upward
#: at half its amplitude or more) cannot be the body's: the circuit opened.
PRESSED_REST_S, PRESSED_SIN = 2e-3, -0.5


def pressed_takeoffs(flights: pd.DataFrame) -> np.ndarray:
    """(n,) bool: flights that left a rest while the plate pushed the body up.

    A body resting on the plate leaves it only where the plate accelerates downward
    faster than gravity (Gamma sin phi > 1 + mu for a sine plate), so a takeoff after a
    long contact at ``sin phi < -0.5`` is the circuit opening, not a flight: a black-box
    probe's dirty contact gave 105 such flights, 39 of them at Gamma 1.0, and no word.
    On the shipped runs none (their flights below Gamma 1 follow 45-us impacts of the
    armature's chatter, not rests). False without drive phases. A strong harmonic also
    sets them off (an independent probe of k 3, a 0.15: 440 of 4097; session 82), so the
    warning names it too.
    """
    phi = flights["phi_takeoff"].to_numpy(dtype=np.float64)
    rest = flights["contact_before_s"].to_numpy(dtype=np.float64) > PRESSED_REST_S
    with np.errstate(invalid="ignore"):
        return rest & (np.sin(phi) < PRESSED_SIN)


def qc_path_for(out: str | Path) -> Path:
    """Where the QC table goes beside a flight table: ``<stem>.qc<suffix>``."""
    out = Path(out)
    return out.with_name(f"{out.stem}.qc{out.suffix}")
