"""Synthetic continuity signals with a known truth, for the detection tests.

A switch (open 0 / contact 1) is integrated through an exact first-order RC filter on a
fine grid (``oversample`` points per sample), then sampled, scaled to volts, and given
white noise, slow drift and optional single-sample glitches.  All randomness is seeded.
"""

from __future__ import annotations

import numpy as np
import yaml
from scipy.signal import lfilter


def switch_signal(n, fs, contacts, oversample=50):
    """Fine-grid switch (n*oversample,) with 1 inside each (start_s, end_s) contact, or
    ``level`` inside a ``(start_s, end_s, level)`` one (a contact that half-conducts)."""
    m = n * oversample
    s = np.zeros(m)
    dt = 1.0 / (fs * oversample)
    for a, b, *level in contacts:
        ia = int(np.ceil(a / dt))
        ib = int(np.ceil(b / dt))
        s[max(ia, 0) : max(min(ib, m), 0)] = level[0] if level else 1.0
    return s


def continuity(
    contacts,
    duration_s,
    fs=20_000.0,
    tau_s=25e-6,
    open_v=5.0,
    contact_v=0.0,
    noise_v=0.01,
    drift_v=0.0,
    glitches=0,
    glitch_v=3.0,
    seed=0,
    oversample=50,
):
    """Sampled continuity channel (n,) in volts for the given contact intervals (s).

    The RC filter is applied on a grid ``oversample`` times finer than the sampling
    (0.5-1 us), so edge times are exact to that grid.  Returns ``(x, glitch_idx)``.
    """
    rng = np.random.default_rng(seed)
    n = int(round(duration_s * fs))
    s = switch_signal(n, fs, contacts, oversample)
    dt = 1.0 / (fs * oversample)
    if tau_s > 0:
        a = np.exp(-dt / tau_s)
        # start the filter at the first value, as if it had been there forever
        y, _ = lfilter([1 - a], [1, -a], s, zi=[a * s[0]])
    else:
        y = s
    u = y[::oversample][:n]  # sample k at t = k / fs
    t = np.arange(n) / fs
    x = open_v + (contact_v - open_v) * u
    x = x + drift_v * np.sin(2 * np.pi * t / max(duration_s, 1e-9) * 0.7 + 0.3)
    x = x + noise_v * rng.standard_normal(n)
    gidx = np.sort(rng.choice(np.arange(5, n - 5), size=glitches, replace=False))
    x[gidx] += glitch_v * rng.choice([-1.0, 1.0], size=glitches)
    return x, gidx


def bouncing_contacts(
    duration_s, period_s=1 / 30, contact_s=30e-6, jitter_s=4e-3, seed=1, start_s=0.01
):
    """Contacts of a bouncing body: one short contact per period with random jitter,
    plus a few chatter sequences (flights of 0.2-2 ms) and some long rests."""
    rng = np.random.default_rng(seed)
    out = []
    t = start_s
    while t < duration_s - 0.02:
        kind = rng.random()
        if kind < 0.7:
            d = contact_s * rng.uniform(0.5, 1.5)
            out.append((t, t + d))
            t += d + period_s + rng.uniform(-jitter_s, jitter_s)
        elif kind < 0.85:
            # restitution chatter: flights shrinking geometrically
            f = rng.uniform(1e-3, 2e-3)
            while f > 0.15e-3:
                d = contact_s * rng.uniform(0.5, 1.5)
                out.append((t, t + d))
                t += d + f
                f *= 0.5
            d = rng.uniform(2e-3, 8e-3)
            out.append((t, t + d))
            t += d + period_s * 0.6
        else:
            d = rng.uniform(1e-3, 10e-3)
            out.append((t, t + d))
            t += d + period_s * rng.uniform(0.3, 1.0)
    return [c for c in out if c[1] < duration_s - 0.005]


def true_flights(contacts):
    """(takeoff, landing) arrays, s, of the flights between consecutive contacts."""
    c = np.asarray(contacts)
    return c[:-1, 1], c[1:, 0]


def write_npz_run(folder, channels, fs=20_000.0, **yaml_keys):
    """A hand-made run folder with an NPZ recording (for bad-input tests)."""
    folder.mkdir(parents=True, exist_ok=True)
    np.savez(folder / "rec.npz", **channels)
    spec = {
        "format_version": 1,
        "recording": "rec.npz",
        "sample_rate_hz": fs,
        "channels": {role: role for role in channels},
    } | yaml_keys
    (folder / "run.yaml").write_text(yaml.safe_dump(spec))
    return folder
