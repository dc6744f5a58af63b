"""Drive phase from the ``drive`` reference channel.

Convention (CONTRACTS.md section 3, docs/flights.md): the drive channel is a sine in
phase with the plate position, ``drive(t) = A sin(omega t + theta) + c``; the plate
phase is ``phi(t) = omega t + theta - drive_phase_offset_rad`` (mod 2 pi), zero at the
upward zero crossing of the plate position.  ``drive_phase_offset_rad`` (optional
run.yaml key, default 0) is how far the drive reference leads the plate.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class SineFit:
    """Least-squares sine at a known frequency over one time window.

    ``amplitude`` (channel units), ``theta`` (rad, phase at ``t_ref_s``), ``offset``,
    ``noise`` (rms residual), ``n`` (samples used), ``t_ref_s`` (s).
    """

    amplitude: float
    theta: float
    offset: float
    noise: float
    n: int
    t_ref_s: float

    @property
    def significant(self) -> bool:
        """True when the amplitude stands clearly above its own uncertainty (20 sigma)."""
        if self.n < 3:
            return False
        return self.amplitude > 20.0 * self.noise * np.sqrt(2.0 / self.n)


def fit_sine(t_s: np.ndarray, y: np.ndarray, freq_hz: float, n_harmonics: int = 1) -> tuple:
    """Fit ``c + sum_h a_h sin(h w t') + b_h cos(h w t')`` by least squares, robustly.

    Parameters
    ----------
    t_s : (n,) times, s.   y : (n,) samples.   freq_hz : drive frequency, Hz.
    n_harmonics : harmonics fitted (1 = fundamental only).

    Returns
    -------
    (SineFit of the fundamental, model (n,) evaluated at ``t_s``).

    Robust: after a first fit, samples with residuals beyond 5 robust sigma (glitches)
    are dropped and the fit is repeated.  Times are taken relative to ``t_s[0]`` to
    keep the design matrix well conditioned.
    """
    t_s = np.asarray(t_s, dtype=np.float64)
    y = np.asarray(y, dtype=np.float64)
    n = y.shape[0]
    if n < 2 * n_harmonics + 2:
        return SineFit(0.0, 0.0, float(np.mean(y)) if n else 0.0, 0.0, n, 0.0), np.zeros(n)
    t_ref = float(t_s[0])
    w = TWO_PI * freq_hz * (t_s - t_ref)
    cols = [np.ones(n)]
    for h in range(1, n_harmonics + 1):
        cols += [np.sin(h * w), np.cos(h * w)]
    a = np.stack(cols, axis=1)
    keep = np.ones(n, dtype=bool)
    for _ in range(2):
        coef, *_ = np.linalg.lstsq(a[keep], y[keep], rcond=None)
        resid = y - a @ coef
        mad = np.median(np.abs(resid[keep] - np.median(resid[keep]))) * 1.4826
        keep = np.abs(resid) <= 5.0 * max(mad, 1e-12)
        if keep.sum() < a.shape[1] + 1:
            keep[:] = True
            break
    model = a @ coef
    s, c = coef[1], coef[2]
    noise = float(np.std((y - model)[keep]))
    fit = SineFit(
        amplitude=float(np.hypot(s, c)),
        theta=float(np.arctan2(c, s)),
        offset=float(coef[0]),
        noise=noise,
        n=int(keep.sum()),
        t_ref_s=t_ref,
    )
    return fit, model


def phase_at(t_s, fit: SineFit, freq_hz: float, offset_rad: float = 0.0) -> np.ndarray:
    """Plate phase (rad, in [0, 2 pi)) at times ``t_s`` (s) from a drive fit; NaN if the
    fit has no significant amplitude (a step with the plate at rest)."""
    t_s = np.asarray(t_s, dtype=np.float64)
    if not fit.significant:
        return np.full(t_s.shape, np.nan)
    phi = TWO_PI * freq_hz * (t_s - fit.t_ref_s) + fit.theta - offset_rad
    return np.mod(phi, TWO_PI)


#: Relative difference between the drive channel's frequency and run.yaml's
#: ``drive_frequency_hz`` above which :func:`drive_frequency_warning` speaks. Why 0.2 %:
#: on an independent friction recording (30 Hz) stated at 29.85 Hz (0.5 % off) the
#: diagnosis took friction + a Gamma miscalibration and called the run unexplained; at
#: 30.09 Hz (0.3 %) it was right (docs/diagnosis-log.md, session 37). A function
#: generator is exact to far better, and :func:`dominant_frequency` reads a step to 0.01 %.
DRIVE_FREQUENCY_TOLERANCE = 0.002

#: Fewest whole cycles of the stated frequency a window needs for a frequency estimate.
MIN_FREQUENCY_CYCLES = 8

#: How far a spectral line must stand above the median of the spectrum (magnitudes) to
#: be the drive's (:func:`dominant_frequency`): white noise peaks at a few times it.
LINE_PROMINENCE = 30.0


def dominant_frequency(y: np.ndarray, fs: float) -> float:
    """Frequency (Hz) of the strongest spectral line of ``y`` (samples at ``fs`` Hz, shape
    (n,)), away from DC: the peak of the Hann-windowed spectrum, placed between the peak
    bin and its larger neighbour by the ratio of their magnitudes (Grandke's estimator,
    exact for a lone sine under a Hann window but for the leakage of its mirror image:
    within 0.01 % of the frequency over 8 cycles, 0.0002 % over 60).
    NaN for fewer than 16 samples, or when the peak does not stand
    :data:`LINE_PROMINENCE` times above the spectrum's median (noise, a plate at rest)."""
    y = np.asarray(y, dtype=np.float64)
    n = y.shape[0]
    if n < 16:
        return float("nan")
    spec = np.abs(np.fft.rfft((y - np.mean(y)) * np.hanning(n)))
    k = int(np.argmax(spec[2:])) + 2  # bins 0-1: what is left of the offset and drift
    if k + 1 >= spec.shape[0] or spec[k] <= LINE_PROMINENCE * np.median(spec[2:]):
        return float("nan")
    below, peak, above = spec[k - 1 : k + 2]
    if above >= below:
        shift = (2.0 * above - peak) / (peak + above)
    else:
        shift = -(2.0 * below - peak) / (peak + below)
    return float((k + shift) * fs / n)


def drive_frequency_warning(
    measured_hz: np.ndarray, stated_hz: float, path: str | None = None
) -> str | None:
    """A warning when the drive channel's frequency, measured per step (``measured_hz``,
    NaN where the plate rests or there is no drive channel), disagrees with run.yaml's
    ``drive_frequency_hz`` by more than :data:`DRIVE_FREQUENCY_TOLERANCE` (the median
    over the steps); None otherwise. Why: flight times in radians and the settle cycles
    use the stated frequency (the phases the channel's: ``extract.phase_frequency``),
    and a run.yaml copied from another run gives a diagnosis of another experiment,
    without any error. ``path``: the file the warning names first (none: the caller's
    context names it)."""
    measured = np.asarray(measured_hz, dtype=np.float64)
    measured = measured[np.isfinite(measured)]
    if measured.size == 0 or not stated_hz:
        return None
    median = float(np.median(measured))
    off = median / float(stated_hz) - 1.0
    if abs(off) <= DRIVE_FREQUENCY_TOLERANCE:
        return None
    return (f"{path}: " if path else "") + (
        f"the drive channel runs at {median:.3f} Hz (median over {measured.size} "
        f"steps), {100 * off:+.1f} % from drive_frequency_hz {float(stated_hz):g}; flight "
        "times in radians and the settle cycles use the stated value (the drive phases "
        "follow the channel)"
    )
