"""The rig's sensor chain and random plate vibration: pure numpy functions.

Each function takes its random generator explicitly (one independent stream per
component, see ``simulate.py``), so switching one channel on or off does not change the
others' noise. Arrays are 1-D over ADC samples, ``n`` long, volts unless named.
"""

from __future__ import annotations

import math

import numpy as np

ADC_BITS = 16
ADC_MAX_CODE = 2 ** (ADC_BITS - 1)  # 32768: a code of 32768 would stand for full scale


def adc_codes(volts: np.ndarray, full_scale_v: float) -> np.ndarray:
    """16-bit ADC: ``round(v / full_scale_v * 32768)``, clipped, as int16 (n,).

    A code ``q`` stands for ``q / 32768 * full_scale_v`` volts, the convention by which
    PCM audio readers scale to [-1, 1) (``full_scale_v`` in run.yaml).
    """
    q = np.rint(np.asarray(volts) * (ADC_MAX_CODE / full_scale_v))
    return np.clip(q, -ADC_MAX_CODE, ADC_MAX_CODE - 1).astype(np.int16)


def codes_to_volts(codes: np.ndarray, full_scale_v: float) -> np.ndarray:
    """Volts (float64) that ADC codes stand for (exact: a power-of-two scale)."""
    return codes.astype(np.float64) * (full_scale_v / ADC_MAX_CODE)


def baseline_drift(n: int, fs: float, amp_v: float, period_s: float, rng) -> np.ndarray:
    """Slow baseline drift (V): three sinusoids of periods ``period_s`` x U(0.5, 2),
    random phases, summed and scaled so the largest of the three has ``amp_v / 2``.

    Smooth and bounded (at most about ``1.5 amp_v``), like a thermal drift of the
    circuit's supply.
    """
    if amp_v == 0.0 or n == 0:
        return np.zeros(n)
    periods = period_s * rng.uniform(0.5, 2.0, size=3)
    phases = rng.uniform(0.0, 2.0 * math.pi, size=3)
    weights = np.array([0.5, 0.3, 0.2])
    t = np.arange(n) / fs
    out = np.zeros(n)
    for p, ph, wt in zip(periods, phases, weights, strict=True):
        out += wt * np.sin(2.0 * math.pi * t / p + ph)
    return amp_v * out


def continuity_volts(
    rc_open: np.ndarray, cont: dict, fs: float, delay_s: float, rng_noise, rng_drift
) -> np.ndarray:
    """Continuity channel (V) from the RC front end's normalised output.

    ``rc_open``: (n,) RC output at the sample instants, 0 in contact .. 1 open.
    Level ``contact_v + (open_v - contact_v) rc_open``, delayed by ``delay_s``
    (linear interpolation, the first value held before the start), plus drift and white
    noise of ``cont`` (the ``sensors.continuity`` config block).
    """
    n = rc_open.size
    level = rc_open
    if delay_s > 0.0:
        t = np.arange(n) / fs
        level = np.interp(t - delay_s, t, rc_open)
    v = cont["contact_v"] + (cont["open_v"] - cont["contact_v"]) * level
    v = v + baseline_drift(n, fs, cont["drift_v"], cont["drift_period_s"], rng_drift)
    return v + cont["noise_v"] * rng_noise.standard_normal(n)


def commanded_gamma(n: int, fs: float, step_t: np.ndarray, gammas: np.ndarray, ramp_s: float):
    """Stated (commanded) Gamma at each sample (n,), with the same linear ramp as the
    plate's amplitude: step ``i`` ramps from ``gammas[i-1]`` (0 before the first) to
    ``gammas[i]`` over ``ramp_s`` from ``step_t[i]``."""
    t = np.arange(n) / fs
    idx = np.clip(np.searchsorted(step_t, t, side="right") - 1, 0, len(step_t) - 1)
    prev = np.concatenate([[0.0], gammas[:-1]])
    if ramp_s > 0:
        r = np.clip((t - step_t[idx]) / ramp_s, 0.0, 1.0)
    else:
        r = np.ones(n)
    return prev[idx] + (gammas[idx] - prev[idx]) * r


def drive_volts(
    n: int, fs: float, omega: float, gamma_cmd: np.ndarray, v_per_gamma: float, noise_v, rng
) -> np.ndarray:
    """Drive reference channel (V): ``v_per_gamma * Gamma_cmd(t) * sin(omega t)`` + noise.

    In phase with the commanded plate position: phase zero at the upward zero crossing
    of the plate (docs/rig.md). The harmonic distortion, the Gamma miscalibration and the
    armature's response are the shaker's, not the signal generator's: not in here.
    """
    t = np.arange(n) / fs
    return v_per_gamma * gamma_cmd * np.sin(omega * t) + noise_v * rng.standard_normal(n)


def resonator_coeffs(f_hz: float, zeta: float, fs: float) -> tuple[np.ndarray, np.ndarray]:
    """IIR (b, a) whose impulse response is ``exp(-s t) sin(w_d t)`` sampled at ``fs``
    (impulse invariance), ``w_d = 2 pi f sqrt(1 - zeta^2)``, ``s = zeta 2 pi f``."""
    w = 2.0 * math.pi * f_hz
    wd = w * math.sqrt(1.0 - zeta**2)
    r = math.exp(-zeta * w / fs)
    b = np.array([0.0, r * math.sin(wd / fs)])
    a = np.array([1.0, -2.0 * r * math.cos(wd / fs), r * r])
    return b, a


def accel_volts(
    acc_plate: np.ndarray, force: np.ndarray, fs: float, acc: dict, g: float, arm_mass_kg: float,
    rng,
) -> np.ndarray:  # fmt: skip
    """Accelerometer channel (V): plate acceleration, impact ringing, heavy noise.

    ``acc_plate``: (n,) plate acceleration (m/s^2); ``force``: (n,) contact force on the
    body averaged over each sample (N). Each sample's impulse ``force / fs`` (N s) kicks
    a ringing mode (``ring_hz``, ``ring_damping_ratio``) of the plate; the fraction
    ``ring_participation`` of the plate's velocity change ``impulse / arm_mass_kg`` rings
    with acceleration amplitude ``omega_ring * dv``. Then white noise (``noise_g``) and
    mains hum (``hum_g`` at ``hum_hz``, random phase). Scaled by ``v_per_g``.
    """
    from scipy.signal import lfilter

    n = acc_plate.size
    w_ring = 2.0 * math.pi * acc["ring_hz"]
    b, a = resonator_coeffs(acc["ring_hz"], acc["ring_damping_ratio"], fs)
    dv = acc["ring_participation"] * (force / fs) / arm_mass_kg
    ring = w_ring * lfilter(b, a, dv)
    t = np.arange(n) / fs
    hum = acc["hum_g"] * g * np.sin(2.0 * math.pi * acc["hum_hz"] * t + rng.uniform(0, 2 * math.pi))
    noise = acc["noise_g"] * g * rng.standard_normal(n)
    return acc["v_per_g"] * (acc_plate + ring + hum + noise) / g


def random_vibration(
    n: int, fs: float, rms_m: float, band_hz: tuple[float, float], rng
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Band-limited Gaussian plate vibration at ``n`` sample instants.

    White Gaussian spectrum kept only in ``band_hz``, scaled to ``rms_m``; velocity and
    acceleration are the exact derivatives of the band-limited signal (spectrum times
    ``i w`` and ``-w^2``). Returns ``(x (m), v (m/s), a (m/s^2))``, each (n,); zeros
    when ``rms_m`` is 0.
    """
    if rms_m == 0.0 or n < 4:
        z = np.zeros(n)
        return z, z.copy(), z.copy()
    spec = rng.standard_normal(n // 2 + 1) + 1j * rng.standard_normal(n // 2 + 1)
    f = np.fft.rfftfreq(n, 1.0 / fs)
    spec[(f < band_hz[0]) | (f > band_hz[1])] = 0.0
    x = np.fft.irfft(spec, n)
    scale = rms_m / max(float(np.sqrt(np.mean(x**2))), 1e-300)
    w = 2.0 * math.pi * f
    v = np.fft.irfft(spec * 1j * w, n)
    a = np.fft.irfft(-spec * w**2, n)
    return x * scale, v * scale, a * scale
