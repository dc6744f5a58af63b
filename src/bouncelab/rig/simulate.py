"""Running the rig: from a full config to ADC codes, true flights and parameters.

:func:`simulate_rig` arranges the numba kernel (``kernels.simulate_chunk``) chunk by
chunk, then the sensor chain (``sensors``); it writes nothing. The result's ``truth``
defines a flight exactly as the continuity circuit sees it: the open interval between
the end of one contact and the start of the next (contact = penetration > 0).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from bouncelab.rig import kernels as K
from bouncelab.rig import sensors
from bouncelab.rig.config import derive, step_schedule

CHUNK = 1 << 17  # samples per kernel call: bounds the event buffers, not the result

# independent random streams, one per component (SeedSequence spawn keys)
STREAM_CONT_NOISE, STREAM_DRIFT, STREAM_DRIVE, STREAM_ACCEL, STREAM_VIBRATION = range(5)

TRUTH_COLUMNS = [
    "step", "gamma", "gamma_true", "t_takeoff_s", "t_landing_s", "flight_s", "T",
    "v_takeoff_m_s", "v_impact_m_s", "settled",
]  # fmt: skip


@dataclass
class RigResult:
    """What one rig run produced, before writing.

    ``codes``: (n_samples, n_channels) int16 ADC codes, columns in the order of
    ``roles``; ``full_scale_v``: volts of a full-scale code; ``truth``: true flights
    (``TRUTH_COLUMNS``); ``params``: ``{"config": ..., "derived": ...}``;
    ``run_meta``: the run.yaml keys that depend on the config (not recording/channels).
    """

    fs: float
    roles: list[str]
    codes: np.ndarray
    full_scale_v: float
    truth: pd.DataFrame
    params: dict
    run_meta: dict = field(default_factory=dict)

    @property
    def n_samples(self) -> int:
        return int(self.codes.shape[0])


def rng_for(seed: int, stream: int) -> np.random.Generator:
    """The random generator of one component: PCG64 on SeedSequence(seed, spawn_key)."""
    return np.random.Generator(np.random.PCG64(np.random.SeedSequence(seed, spawn_key=(stream,))))


def kernel_params(cfg: dict, d: dict) -> np.ndarray:
    """The kernel's parameter vector ``p`` from a full config and its derived numbers."""
    body, eff, proto = cfg["body"], cfg["effects"], cfg["protocol"]
    p = K.new_params()
    p[K.P_MASS] = body["mass_kg"]
    p[K.P_G] = body["g_m_s2"]
    p[K.P_MU] = body["friction_mu"]
    p[K.P_V_REG] = body["friction_v_reg_m_s"]
    p[K.P_DRAG] = eff["drag_n_s_per_m"]
    p[K.P_K] = d["contact_stiffness_n_m"]
    p[K.P_MU_RED] = d["contact_reduced_mass_kg"]
    p[K.P_E0] = body["restitution"]
    p[K.P_E_SLOPE] = eff["restitution_slope_s_per_m"]
    p[K.P_U_REF] = eff["restitution_ref_speed_m_s"]
    p[K.P_OMEGA] = d["omega_rad_s"]
    p[K.P_RAMP] = cfg["drive"]["ramp_cycles"] / cfg["drive"]["frequency_hz"]
    p[K.P_FEEDBACK] = 1.0 if cfg["shaker"]["feedback"] else 0.0
    p[K.P_ARM_MASS] = cfg["shaker"]["armature_mass_kg"]
    p[K.P_ARM_K] = d["armature_stiffness_n_m"]
    p[K.P_ARM_C] = d["armature_damping_n_s_m"]
    drop = cfg["kind"] == "drop"
    p[K.P_RELEASE_T] = proto["release_t_s"] if drop else -1.0
    p[K.P_HOLD_X] = proto["drop_height_m"] if drop else 0.0
    p[K.P_RC_TAU] = cfg["sensors"]["continuity"]["rc_time_s"]
    p[K.P_FS] = cfg["recording"]["sample_rate_hz"]
    p[K.P_NSUB] = d["steps_per_sample_impact"]
    p[K.P_NCOARSE] = d["steps_per_sample_flight"]
    p[K.P_NREST] = d["steps_per_sample_rest"]
    p[K.P_FINE_WINDOW] = d["fine_window_s"]
    return p


def initial_state(cfg: dict, d: dict, p: np.ndarray) -> np.ndarray:
    """Start state: a sweep's body rests on the plate in static equilibrium (armature
    sagging under its weight); a drop test's body is held at the drop height."""
    s = K.new_state()
    s[K.S_TLAND] = -1e9  # long ago: a resting contact takes the rest step
    if cfg["kind"] == "drop":
        h = cfg["protocol"]["drop_height_m"]
        s[K.S_X], s[K.S_DELTA], s[K.S_RC] = h, -h, 1.0
        return s
    w = p[K.P_MASS] * p[K.P_G]
    y0 = -w / p[K.P_ARM_K] if p[K.P_FEEDBACK] > 0.5 else 0.0
    s[K.S_Y] = y0
    s[K.S_X] = y0 - w / p[K.P_K]
    s[K.S_DELTA] = w / p[K.P_K]
    s[K.S_CONTACT] = 1.0
    s[K.S_RC] = 0.0
    s[K.S_C] = K.dashpot(p, p[K.P_E0])
    return s


def harmonic_arrays(cfg: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(k, a, psi) arrays of the drive's harmonic distortion, each (n_harm,)."""
    hs = cfg["drive"]["harmonics"]
    return (
        np.array([h["k"] for h in hs], dtype=float),
        np.array([h["a"] for h in hs], dtype=float),
        np.array([h["psi"] for h in hs], dtype=float),
    )


def run_kernel(cfg: dict, d: dict, vib: tuple[np.ndarray, np.ndarray, np.ndarray] | None):
    """Integrate the whole recording in chunks.

    ``vib``: random plate vibration ``(x, v, a)`` at the ``n + 1`` sample instants, or
    ``None`` when off.

    Returns ``(rc_open, acc_plate, force, events)``: three (n,) float64 arrays (see
    ``kernels.simulate_chunk``) and the events as ``(t, kind, v)`` arrays.
    """
    n = d["n_samples"]
    p = kernel_params(cfg, d)
    s = initial_state(cfg, d, p)
    seg_t, seg_amp, seg_prev = step_schedule(d)
    hk, ha, hpsi = harmonic_arrays(cfg)
    rc, acc, force = np.empty(n), np.empty(n), np.empty(n)
    ev_t, ev_k, ev_v = [], [], []
    buf_t = np.empty(4 * CHUNK + 64)
    buf_k = np.empty(4 * CHUNK + 64, dtype=np.int8)
    buf_v = np.empty(4 * CHUNK + 64)
    still = np.zeros(CHUNK + 1)
    for i0 in range(0, n, CHUNK):
        m = min(CHUNK, n - i0)
        sl = slice(i0, i0 + m)
        if vib is None:
            vx = vv = va = still[: m + 1]
        else:
            vx, vv, va = (np.ascontiguousarray(a[i0 : i0 + m + 1]) for a in vib)
        n_ev = K.simulate_chunk(
            p, s, i0, m, seg_t, seg_amp, seg_prev, hk, ha, hpsi, vx, vv, va,
            rc[sl], acc[sl], force[sl], buf_t, buf_k, buf_v,
        )  # fmt: skip
        if n_ev < 0:
            raise RuntimeError("rig event buffer overflow (more than 4 edges per sample)")
        ev_t.append(buf_t[:n_ev].copy())
        ev_k.append(buf_k[:n_ev].copy())
        ev_v.append(buf_v[:n_ev].copy())
    return rc, acc, force, (np.concatenate(ev_t), np.concatenate(ev_k), np.concatenate(ev_v))


def flights_from_events(events, cfg: dict, d: dict) -> pd.DataFrame:
    """True flights: each takeoff edge paired with the landing edge that follows it.

    Edges alternate (the contact flag toggles), so a flight is a takeoff at index i and
    a landing at i + 1; a drop test's release (no contact before it) and a flight still
    open when the recording ends are not flights.
    """
    t, kind, v = events
    i = np.flatnonzero((kind[:-1] == K.EV_TAKEOFF) & (kind[1:] == K.EV_LANDING))
    t_to, t_ld = t[i], t[i + 1]
    f = cfg["drive"]["frequency_hz"]
    if cfg["kind"] == "sweep":
        step_t = np.asarray(d["step_t_s"])
        step = np.clip(np.searchsorted(step_t, t_to, side="right") - 1, 0, len(step_t) - 1)
        gam = np.asarray(d["gammas"])[step]
        gam_true = np.asarray(d["gammas_true"])[step]
        settled = t_to - step_t[step] >= cfg["protocol"]["settle_cycles"] / f
    else:
        step = np.full(i.size, -1)
        gam = gam_true = np.full(i.size, np.nan)
        settled = np.ones(i.size, dtype=bool)
    flight = t_ld - t_to
    return pd.DataFrame(
        {
            "step": step.astype(np.int64),
            "gamma": gam,
            "gamma_true": gam_true,
            "t_takeoff_s": t_to,
            "t_landing_s": t_ld,
            "flight_s": flight,
            "T": 2.0 * math.pi * f * flight,
            "v_takeoff_m_s": v[i],
            "v_impact_m_s": v[i + 1],
            "settled": settled,
        },
        columns=TRUTH_COLUMNS,
    )


def simulate_rig(cfg: dict) -> RigResult:
    """Simulate the lab for a full config (see ``config.load_rig_config``).

    Deterministic: the config (with its ``seed``) fixes every number.
    """
    d = derive(cfg)
    n, fs = d["n_samples"], float(cfg["recording"]["sample_rate_hz"])
    seed = int(cfg["seed"])
    eff, sens = cfg["effects"], cfg["sensors"]
    vib = None
    if eff["random_vibration_rms_m"] > 0:
        vib = sensors.random_vibration(
            n + 1, fs, eff["random_vibration_rms_m"], tuple(eff["random_vibration_band_hz"]),
            rng_for(seed, STREAM_VIBRATION),
        )  # fmt: skip
    rc, acc_plate, force, events = run_kernel(cfg, d, vib)
    fsv = sens["adc"]["full_scale_v"]

    roles = ["continuity"]
    cont_v = sensors.continuity_volts(
        rc, sens["continuity"], fs, eff["sensor_delay_s"],
        rng_for(seed, STREAM_CONT_NOISE), rng_for(seed, STREAM_DRIFT),
    )  # fmt: skip
    columns = [sensors.adc_codes(cont_v, fsv)]
    del cont_v
    sweep = cfg["kind"] == "sweep"
    if sweep and sens["drive"]["enabled"]:
        gcmd = sensors.commanded_gamma(
            n, fs, np.asarray(d["step_t_s"]), np.asarray(d["gammas"]),
            cfg["drive"]["ramp_cycles"] / cfg["drive"]["frequency_hz"],
        )  # fmt: skip
        drv = sensors.drive_volts(
            n, fs, d["omega_rad_s"], gcmd, sens["drive"]["v_per_gamma"],
            sens["drive"]["noise_v"], rng_for(seed, STREAM_DRIVE),
        )  # fmt: skip
        columns.append(sensors.adc_codes(drv, fsv))
        roles.append("drive")
        del gcmd, drv
    if sens["accel"]["enabled"]:
        acv = sensors.accel_volts(
            acc_plate, force, fs, sens["accel"], cfg["body"]["g_m_s2"],
            cfg["shaker"]["armature_mass_kg"], rng_for(seed, STREAM_ACCEL),
        )  # fmt: skip
        columns.append(sensors.adc_codes(acv, fsv))
        roles.append("accel")
        del acv
    codes = np.stack(columns, axis=1)
    truth = flights_from_events(events, cfg, d)
    return RigResult(
        fs=fs,
        roles=roles,
        codes=codes,
        full_scale_v=fsv,
        truth=truth,
        params={"config": cfg, "derived": derived_for_json(d, events)},
        run_meta=run_meta(cfg, d),
    )


def derived_for_json(d: dict, events) -> dict:
    """The derived numbers, JSON-safe, plus the first landing time (drop tests' fall)."""
    out = {k: (None if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}
    t, kind, _ = events
    landings = t[kind == K.EV_LANDING]
    out["first_landing_t_s"] = float(landings[0]) if landings.size else None
    return out


def run_meta(cfg: dict, d: dict) -> dict:
    """run.yaml keys that follow from the config (CONTRACTS.md section 1)."""
    cont = cfg["sensors"]["continuity"]
    meta: dict = {
        "format_version": 1,
        "kind": cfg["kind"],
        "sample_rate_hz": cfg["recording"]["sample_rate_hz"],
        "contact_level": "low" if cont["contact_v"] < cont["open_v"] else "high",
        "mass_kg": cfg["body"]["mass_kg"],
    }
    if cfg["kind"] == "sweep":
        meta["drive_frequency_hz"] = cfg["drive"]["frequency_hz"]
        meta["gamma_steps"] = [
            {"t_s": float(t), "gamma": float(g)}
            for t, g in zip(d["step_t_s"], d["gammas"], strict=True)
        ]
        meta["settle_cycles"] = cfg["protocol"]["settle_cycles"]
    else:
        meta["drop_height_m"] = cfg["protocol"]["drop_height_m"]
        meta["release_t_s"] = cfg["protocol"]["release_t_s"]
        # an optional key (kept by readers): calibration then uses the rig's own g
        meta["g_m_s2"] = cfg["body"]["g_m_s2"]
    if cfg["sensors"]["accel"]["enabled"]:
        meta["accel_v_per_g"] = cfg["sensors"]["accel"]["v_per_g"]
    meta["source"] = "synthetic"
    meta["description"] = cfg["description"]
    return meta
