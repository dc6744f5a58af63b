"""The seed's discarded accelerometer method (seed section II and fig. 4), rebuilt.

Per Gamma step: fit the drive sine and its harmonics (plus mains hum) to the ``accel``
channel by least squares and subtract it; impacts are what remains.  A landing is the
first sample of a burst whose absolute residual exceeds ``k`` robust noise sigmas
(median absolute deviation), bursts closer than ``dead_s`` (the ringing) being one.
As the seed did, the takeoff is not measured: it comes from the takeoff line
``Gamma sin(phi) = 1`` of the ideal inelastic ball: a landing in the bouncing region
(``Gamma sin(phi) > 1``) takes off at once, one in the sticking region waits for the
next crossing of the line.  The plate phase comes from the accelerometer fit itself
(plate acceleration ``-A w^2 sin(phi)``), so no drive channel is needed.

:func:`compare_methods` matches these flights with the continuity method's by landing
time and returns the figure-ready table and summary numbers (docs/flights.md).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from bouncelab.flights.phase import TWO_PI

ACCEL_COLUMNS = [
    "step",
    "gamma",
    "t_takeoff_s",
    "t_landing_s",
    "flight_s",
    "phi_landing",
    "peak_sigma",
]


def drive_basis(t, freq_hz, n_harmonics=5, hum_hz=(50.0,)) -> np.ndarray:
    """Least-squares basis of a plate's commanded motion at times ``t`` (n,) s: a
    constant, ``sin``/``cos`` of the drive (``freq_hz``, Hz) and its harmonics up to
    ``n_harmonics``, then of each hum frequency (Hz) that is not a drive harmonic.
    Shape (n, 1 + 2 n_harmonics + 2 n_hum); columns 1 and 2 are the fundamental's sine
    and cosine."""
    cols = [np.ones_like(t)]
    for h in range(1, n_harmonics + 1):
        w = TWO_PI * freq_hz * h * t
        cols += [np.sin(w), np.cos(w)]
    for f in hum_hz:
        if f > 0 and abs(f / freq_hz - round(f / freq_hz)) > 1e-6:
            cols += [np.sin(TWO_PI * f * t), np.cos(TWO_PI * f * t)]
    return np.stack(cols, axis=1)


def drive_fit(t_s, a, freq_hz, n_harmonics=5, hum_hz=(50.0,)):
    """Least-squares fit of the drive, its harmonics and hum to ``a``, refitted without
    the impact bursts (samples beyond 4 robust sigmas of the first fit's residual).

    Parameters as :func:`subtract_drive`. Returns the residual (n,) and the coefficients
    of :func:`drive_basis` (time from ``t_s[0]``): ``coef[2h - 1]``, ``coef[2h]`` are the
    sine and cosine of harmonic ``h`` (1 = the fundamental).
    """
    t = np.asarray(t_s, dtype=np.float64) - float(t_s[0])
    a = np.asarray(a, dtype=np.float64)
    m = drive_basis(t, freq_hz, n_harmonics, hum_hz)
    keep = np.ones(t.shape, dtype=bool)
    for _ in range(2):  # refit without the impact bursts
        coef, *_ = np.linalg.lstsq(m[keep], a[keep], rcond=None)
        resid = a - m @ coef
        sig = 1.4826 * np.median(np.abs(resid - np.median(resid)))
        keep = np.abs(resid) < 4.0 * max(sig, 1e-300)
    return resid, coef


def subtract_drive(t_s, a, freq_hz, n_harmonics=5, hum_hz=(50.0,)):
    """Residual of ``a`` after a least-squares fit of the drive, its harmonics and hum.

    Parameters
    ----------
    t_s : (n,) s.  a : (n,) accelerometer samples (any unit).  freq_hz : drive, Hz.
    n_harmonics : drive harmonics fitted (1 = fundamental only).
    hum_hz : other known frequencies fitted and removed (mains hum), Hz.

    Returns
    -------
    resid : (n,) residual.  amp : fundamental amplitude.  phase0 : plate phase (rad) at
    ``t_s[0]``, from ``a = -amp sin(phi)`` (acceleration opposes position).
    """
    resid, coef = drive_fit(t_s, a, freq_hz, n_harmonics, hum_hz)
    s, c = coef[1], coef[2]  # a ~ s sin(w t) + c cos(w t) = amp sin(w t + th)
    amp = float(np.hypot(s, c))
    th = float(np.arctan2(c, s))
    return resid, amp, float(np.mod(th + np.pi, TWO_PI))  # -sin(phi) = sin(phi + pi)


def find_impacts(resid, fs, k_sigma=6.0, dead_s=2e-3):
    """Sample indices (m,) of impact onsets in a residual, and their peak in sigmas (m,).

    An onset is the first sample with ``|resid| > k_sigma * sigma`` (sigma from the
    median absolute deviation) after at least ``dead_s`` below the threshold.
    """
    sig = 1.4826 * np.median(np.abs(resid - np.median(resid)))
    over = np.abs(resid) > k_sigma * max(sig, 1e-300)
    idx = np.flatnonzero(over)
    if idx.size == 0:
        return idx, np.empty(0)
    dead = max(1, int(round(dead_s * fs)))
    start = np.concatenate([[True], np.diff(idx) > dead])
    on = idx[start]
    ends = np.concatenate([idx[np.flatnonzero(start)[1:] - 1], [idx[-1]]])
    peaks = np.array([np.abs(resid[a : b + 1]).max() for a, b in zip(on, ends, strict=True)])
    return on, peaks / max(sig, 1e-300)


def takeoff_phase(phi_land, gamma):
    """Takeoff phase (rad, unwrapped: >= phi_land) after a landing at ``phi_land``.

    The ideal inelastic ball leaves at once in the bouncing region ``Gamma sin(phi) > 1``
    and otherwise rides the plate to the next crossing of the takeoff line at
    ``arcsin(1/Gamma)`` (mod 2 pi).  NaN for ``Gamma <= 1`` (it never leaves).
    """
    phi_land = np.asarray(phi_land, dtype=np.float64)
    if gamma <= 1.0:
        return np.full(phi_land.shape, np.nan)
    p0 = np.arcsin(1.0 / gamma)
    p = np.mod(phi_land, TWO_PI)
    bouncing = (p > p0) & (p < np.pi - p0)
    wait = np.mod(p0 - p, TWO_PI)
    return np.where(bouncing, phi_land, phi_land + wait)


def accel_flights(
    accel, fs, steps, freq_hz, time_s=None, k_sigma=6.0, dead_s=2e-3, n_harmonics=5, hum_hz=(50.0,)
) -> pd.DataFrame:
    """Flights from an accelerometer channel, one row per detected landing.

    Parameters
    ----------
    accel : (n,) accelerometer samples (volts or g; only ratios matter).
    fs : Hz.  steps : DataFrame ``step, gamma, t_start_s, t_end_s``.  freq_hz : Hz.
    time_s : (n,) or None.

    Returns a DataFrame with :data:`ACCEL_COLUMNS`: the flight ends at an impact onset
    and starts at the takeoff that the takeoff line gives after the previous impact.
    """
    rows = []
    n = accel.shape[0]
    w = TWO_PI * freq_hz
    for st in steps.itertuples(index=False):
        if time_s is None:
            a, b = max(0, int(np.ceil(st.t_start_s * fs))), min(n, int(np.ceil(st.t_end_s * fs)))
            t = np.arange(a, b) / fs
        else:
            a, b = np.searchsorted(time_s, st.t_start_s), np.searchsorted(time_s, st.t_end_s)
            t = time_s[a:b]
        if b - a < 64 or st.gamma <= 1.0:
            continue
        resid, _, phase0 = subtract_drive(t, accel[a:b], freq_hz, n_harmonics, hum_hz)
        on, peak = find_impacts(resid, fs, k_sigma, dead_s)
        if on.size < 2:
            continue
        t_land = t[on]
        phi_land = phase0 + w * (t_land - t[0])
        phi_take = takeoff_phase(phi_land, st.gamma)
        t_take = t[0] + (phi_take - phase0) / w
        # flight i: takeoff after impact i, landing at impact i+1
        ok = t_take[:-1] < t_land[1:]
        rows.append(
            pd.DataFrame(
                {
                    "step": int(st.step),
                    "gamma": float(st.gamma),
                    "t_takeoff_s": t_take[:-1][ok],
                    "t_landing_s": t_land[1:][ok],
                    "flight_s": (t_land[1:] - t_take[:-1])[ok],
                    "phi_landing": np.mod(phi_land[1:][ok], TWO_PI),
                    "peak_sigma": peak[1:][ok],
                }
            )
        )
    if not rows:
        return pd.DataFrame({c: [] for c in ACCEL_COLUMNS})
    return pd.concat(rows, ignore_index=True)[ACCEL_COLUMNS]


def compare_methods(cont: pd.DataFrame, acc: pd.DataFrame, tol_s: float = 1e-3):
    """Match accelerometer flights to continuity flights by landing time.

    Parameters
    ----------
    cont : continuity flight table (``t_takeoff_s``, ``t_landing_s``, ``flight_s``, ``step``,
        ``gamma``).  acc : :func:`accel_flights` table.  tol_s : largest landing mismatch, s.

    Returns
    -------
    table : DataFrame, one row per continuity flight: ``step, gamma, t_landing_s,
        flight_s_continuity, flight_s_accel`` (NaN when not found), ``diff_s``
        (accel - continuity), ``found``.
    summary : dict: ``n_continuity``, ``n_accel``, ``share_found``, ``share_false``
        (accel flights matching none), ``median_abs_error_s``, ``p90_abs_error_s``,
        ``p99_abs_error_s``.
    """
    tl = cont["t_landing_s"].to_numpy(dtype=np.float64)
    al = acc["t_landing_s"].to_numpy(dtype=np.float64)
    fa = np.full(tl.shape, np.nan)
    used = np.zeros(al.shape, dtype=bool)
    if al.size and tl.size:
        j = np.clip(np.searchsorted(al, tl), 1, max(al.size - 1, 1))
        cand = np.stack([j - 1, np.minimum(j, al.size - 1)])
        d = np.abs(al[cand] - tl)
        best = cand[np.argmin(d, axis=0), np.arange(tl.size)]
        hit = np.abs(al[best] - tl) <= tol_s
        fa[hit] = acc["flight_s"].to_numpy()[best[hit]]
        used[best[hit]] = True
    fc = cont["flight_s"].to_numpy(dtype=np.float64)
    table = pd.DataFrame(
        {
            "step": cont["step"].to_numpy(),
            "gamma": cont["gamma"].to_numpy(),
            "t_landing_s": tl,
            "flight_s_continuity": fc,
            "flight_s_accel": fa,
            "diff_s": fa - fc,
            "found": np.isfinite(fa),
        }
    )
    err = np.abs(table["diff_s"].to_numpy())
    err = err[np.isfinite(err)]

    def q(p):
        return float(np.percentile(err, p)) if err.size else float("nan")

    summary = {
        "n_continuity": int(tl.size),
        "n_accel": int(al.size),
        "share_found": float(np.mean(np.isfinite(fa))) if tl.size else float("nan"),
        "share_false": float(1.0 - used.mean()) if al.size else float("nan"),
        "median_abs_error_s": q(50),
        "p90_abs_error_s": q(90),
        "p99_abs_error_s": q(99),
    }
    return table, summary


def compare_run(run_dir: str | Path, **kwargs):
    """Both methods on one run with an ``accel`` channel: ``(table, summary)``."""
    from bouncelab.errors import BouncelabError
    from bouncelab.flights.extract import extract_run
    from bouncelab.runs import load_run, read_recording, step_table

    run = load_run(run_dir)
    if "accel" not in run.channels:
        raise BouncelabError(run.yaml_path, "the run has no accel channel")
    if run.kind != "sweep":
        raise BouncelabError(run.yaml_path, "the accelerometer method needs a sweep run")
    rec = read_recording(run, roles=("accel",))
    steps = step_table(run, rec.duration_s)
    acc = accel_flights(
        rec.channels["accel"], rec.fs, steps, run.drive_frequency_hz, rec.time_s, **kwargs
    )
    cont, _ = extract_run(run_dir)
    return compare_methods(cont, acc)


#: Steps whose stated Gamma is below this are left out of the Gamma scale: the plate's
#: amplitude is then small beside the accelerometer's noise and the body's impacts.
MIN_GAMMA_FOR_SCALE = 0.5

#: Resamples of the steps for the interval of the Gamma scale (seeded: deterministic).
SCALE_BOOTSTRAP = 2000


#: A drive harmonic closer than this to a hum frequency (Hz) cannot be told from the hum
#: in one step's fit (a step of 1-2 s resolves about 1 Hz).
HUM_CLASH_HZ = 1.0


def hum_clashes(freq_hz: float, n_harmonics: int = 5, hum_hz=(50.0,)) -> set[int]:
    """The drive harmonics ``h`` (2 .. ``n_harmonics``) within :data:`HUM_CLASH_HZ` of a
    hum frequency: at a 25 Hz drive the second harmonic is the 50 Hz mains hum, and an
    accelerometer's 0.3 g of hum would read as a plate harmonic."""
    return {
        h
        for h in range(2, n_harmonics + 1)
        for f in hum_hz
        if f > 0 and abs(h * freq_hz - f) < HUM_CLASH_HZ
    }


def plate_gamma_by_step(
    accel_g, fs, steps, freq_hz, settle_cycles=0, time_s=None, n_harmonics=5, hum_hz=(50.0,)
) -> pd.DataFrame:
    """The plate's Gamma per step as an accelerometer on the plate reads it.

    The amplitude of the drive's fundamental in the acceleration, in units of g, is the
    plate's reduced acceleration ``A omega^2 / g``: what the run's ``gamma_steps`` state.
    Fitted by least squares with the harmonics and mains hum (:func:`subtract_drive`,
    impacts left out of the second pass), on each step after its ``settle_cycles``.

    Parameters
    ----------
    accel_g : (n,) acceleration in g (the channel's volts over ``accel_v_per_g``).
    fs : Hz.  steps : DataFrame ``step, gamma, t_start_s, t_end_s``.  freq_hz : Hz.
    settle_cycles : drive cycles left out at each step's start (the amplitude's ramp).
    time_s : (n,) or None (then ``index / fs``).

    Returns
    -------
    DataFrame, one row per step with at least two drive cycles after its settle cycles:
    ``step``, ``gamma`` (stated), ``gamma_accel`` (read), ``gamma_accel_se`` (its
    standard error from the residual's robust scatter, white noise assumed), ``n_samples``;
    and per harmonic ``h`` = 2 .. ``n_harmonics`` of the drive, the plate position's
    harmonic in the model's terms (CONTRACTS.md section 5, ``harmonic`` with ``k = h``):
    ``a{h}`` (amplitude relative to the fundamental's, so the acceleration's ratio over
    ``h^2``), ``a{h}_se`` and ``psi{h}`` (rad, in [0, 2 pi), against the plate phase);
    NaN for a harmonic that falls on a hum frequency (:func:`hum_clashes`).
    """
    accel_g = np.asarray(accel_g, dtype=np.float64)
    n = accel_g.shape[0]
    clash = hum_clashes(freq_hz, n_harmonics, hum_hz)
    rows = []
    for st in steps.itertuples(index=False):
        t_from = st.t_start_s + settle_cycles / freq_hz
        if time_s is None:
            a, b = max(0, int(np.ceil(t_from * fs))), min(n, int(np.ceil(st.t_end_s * fs)))
            t = np.arange(a, b) / fs
        else:
            a, b = np.searchsorted(time_s, t_from), np.searchsorted(time_s, st.t_end_s)
            t = np.asarray(time_s[a:b], dtype=np.float64)
        if b - a < 64 or (b - a) / fs < 2.0 / freq_hz:
            continue
        resid, coef = drive_fit(t, accel_g[a:b], freq_hz, n_harmonics, hum_hz)
        sigma = 1.4826 * float(np.median(np.abs(resid - np.median(resid))))
        se = sigma * float(np.sqrt(2.0 / (b - a)))  # of any one sine's amplitude
        amp = float(np.hypot(coef[1], coef[2]))
        th1 = float(np.arctan2(coef[2], coef[1]))
        row = {
            "step": int(st.step),
            "gamma": float(st.gamma),
            "gamma_accel": amp,
            "gamma_accel_se": se,
            "n_samples": int(b - a),
        }
        for h in range(2, n_harmonics + 1):
            if h in clash:
                row[f"a{h}"] = row[f"a{h}_se"] = row[f"psi{h}"] = np.nan
                continue
            # plate position Gamma [sin(phi) + a sin(h phi + psi)] has the acceleration
            # -Gamma [sin(phi) + a h^2 sin(h phi + psi)]; the fit's phases are of time
            # from the step's start, with phi = w t + th1 + pi
            amp_h = float(np.hypot(coef[2 * h - 1], coef[2 * h]))
            th_h = float(np.arctan2(coef[2 * h], coef[2 * h - 1]))
            scale = max(amp, 1e-300) * h * h
            row[f"a{h}"] = amp_h / scale
            row[f"a{h}_se"] = se / scale
            row[f"psi{h}"] = float(np.mod(th_h - h * (th1 + np.pi) - np.pi, TWO_PI))
        rows.append(row)
    columns = ["step", "gamma", "gamma_accel", "gamma_accel_se", "n_samples"]
    for h in range(2, n_harmonics + 1):
        columns += [f"a{h}", f"a{h}_se", f"psi{h}"]
    return pd.DataFrame(rows, columns=columns)


def gamma_scale_from_accel(by_step: pd.DataFrame, min_gamma: float = MIN_GAMMA_FOR_SCALE):
    """The Gamma scale ``s`` (true Gamma = ``s`` x stated, CONTRACTS.md section 5) that
    an accelerometer reads, from :func:`plate_gamma_by_step`.

    ``s`` is the median over steps (stated Gamma >= ``min_gamma``) of read over stated
    Gamma; ``s_ci`` the 95 % percentile interval of that median over the steps resampled
    (:data:`SCALE_BOOTSTRAP`, seed 0), so that it holds what differs from step to step
    (a shaker whose armature the body's impacts load reads differently at each Gamma),
    not only the noise. Returns ``{"s", "s_ci", "ratio_min", "ratio_max", "n_steps"}``,
    or None when no step qualifies. As exact as ``accel_v_per_g``: a sensitivity off by
    some per cent moves ``s`` by as much.
    """
    use = by_step[(by_step["gamma"] >= min_gamma) & np.isfinite(by_step["gamma_accel"])]
    if use.empty:
        return None
    ratio = (use["gamma_accel"] / use["gamma"]).to_numpy(dtype=np.float64)
    rng = np.random.default_rng(0)
    medians = np.median(rng.choice(ratio, size=(SCALE_BOOTSTRAP, ratio.size)), axis=1)
    lo, hi = np.quantile(medians, [0.025, 0.975])
    return {
        "s": float(np.median(ratio)),
        "s_ci": [float(lo), float(hi)],
        "ratio_min": float(ratio.min()),
        "ratio_max": float(ratio.max()),
        "n_steps": int(ratio.size),
    }


#: Least relative amplitude ``a`` of a harmonic that :func:`harmonics_from_accel`
#: reports: a loaded armature puts about 0.001 at the harmonics (raw/accel_g2-4), and the
#: library's harmonic cases have 0.05-0.12.
MIN_HARMONIC_A = 0.01


def harmonics_from_accel(
    by_step: pd.DataFrame, min_gamma: float = MIN_GAMMA_FOR_SCALE, min_a: float = MIN_HARMONIC_A
) -> list[dict]:
    """The drive's harmonics in the plate's motion that an accelerometer reads, in the
    ``harmonic`` effect's terms, from :func:`plate_gamma_by_step`.

    Per harmonic ``k`` (integer, 2 .. 5): ``a`` the median over the steps with stated
    Gamma >= ``min_gamma`` with ``a_ci`` (95 % interval of that median, steps resampled,
    seed ``k``), and ``psi`` the circular mean of the steps' phases weighted by their ``a``.
    Only harmonics with ``a >= min_a`` and above five standard errors are listed, the
    strongest first; one on a hum frequency (NaN, :func:`hum_clashes`) never is.
    """
    use = by_step[by_step["gamma"] >= min_gamma]
    out = []
    if use.empty:
        return out
    for k in range(2, 10):
        if f"a{k}" not in use:
            continue
        a = use[f"a{k}"].to_numpy(dtype=np.float64)
        if not np.isfinite(a).all():
            continue  # on a hum frequency: not read
        psi = use[f"psi{k}"].to_numpy(dtype=np.float64)
        median = float(np.median(a))
        if median < min_a or median < 5.0 * float(np.median(use[f"a{k}_se"])):
            continue
        rng = np.random.default_rng(k)
        medians = np.median(rng.choice(a, size=(SCALE_BOOTSTRAP, a.size)), axis=1)
        lo, hi = np.quantile(medians, [0.025, 0.975])
        mean_psi = float(np.mod(np.angle(np.sum(a * np.exp(1j * psi))), TWO_PI))
        out.append({"k": k, "a": median, "a_ci": [float(lo), float(hi)], "psi": mean_psi})
    return sorted(out, key=lambda h: -h["a"])


def accel_in_g(run) -> bool:
    """Whether ``run`` is a sweep with an ``accel`` channel and its ``accel_v_per_g``: what
    the accelerometer's readings need (volts alone do not say what a g is)."""
    return run.kind == "sweep" and "accel" in run.channels and bool(run.accel_v_per_g)


def accel_gamma_run(run, recording=None) -> pd.DataFrame | None:
    """:func:`plate_gamma_by_step` of a sweep run (:class:`bouncelab.runs.Run`) with an
    ``accel`` channel and its ``accel_v_per_g``; None without either (volts alone do not
    say what a g is). ``recording``: the run's recording with its ``accel`` channel
    already read (:func:`bouncelab.runs.read_recording`), else it is read here."""
    from bouncelab.runs import read_recording, step_table

    if not accel_in_g(run):
        return None
    rec = recording if recording is not None else read_recording(run, roles=("accel",))
    steps = step_table(run, rec.duration_s)
    accel_g = np.asarray(rec.channels["accel"], dtype=np.float64) / float(run.accel_v_per_g)
    return plate_gamma_by_step(
        accel_g, rec.fs, steps, run.drive_frequency_hz, run.settle_cycles, rec.time_s
    )
