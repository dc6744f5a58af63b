"""A third recording generator: a compliant contact and a shaker armature that feels it.

Neither the virtual rig (``bouncelab.rig``) nor ``independent_rig.py`` beside this file:
no impact map at all. The body and the plate touch through a Kelvin-Voigt contact (a
spring and a dashpot in parallel, force ``k delta + c delta'`` while it pushes, released
when it would pull), and everything is one ordinary differential equation integrated by
fixed-step RK4 (``dt`` = 2 us, 50 steps in a 100-us contact):

- restitution is not a parameter but what the contact's damping gives (``e`` of a body
  bouncing on a still plate, found by :func:`contact_for`); chatter, sticking and rides
  are the same equation, the body resting on the compressed spring;
- the contact lasts ``contact_s`` (half the spring's period), and the continuity circuit
  is closed exactly while the spring is compressed;
- the plate is the commanded motion plus a damped armature (``mass_ratio``, ``f_ratio``,
  ``zeta``) driven by the contact force all the time: impacts and the riding body's
  weight and inertia alike (the ``ride_load = 1`` armature of docs/physics.md, reached
  here without any special case);
- Coulomb friction on the guide, ``mu`` of the weight against the body's velocity
  (smoothed over ``1e-4`` m/s);
- the drive's amplitude ramped linearly over ``ramp_cycles`` at each step change (a real
  amplifier does not jump);
- outside the library: a Hertzian contact (``hertz``: force ``k delta^1.5 (1 + c delta')``,
  the Hunt-Crossley law, whose restitution falls with impact speed).

Use: ``python benchmarks/compliant_rig.py OUT_DIR [--mu 0.2 --e 0.4 ...]`` writes
``OUT_DIR/run.yaml`` and the recording, and ``OUT_DIR.truth.json`` beside it (never
inside). ``bench_independent.py --generator compliant`` diagnoses a set of such cases;
:func:`make_drop` writes a drop test (the body released above the still plate), which
``bench_compliant_drop.py`` calibrates.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numba
import numpy as np
import soundfile as sf
import yaml

G = 9.81  # m/s^2
MASS_KG = 0.2
#: friction's smoothing: the sign of the velocity as tanh(v / V_EPS)
V_EPS = 1e-4  # m/s


@numba.njit(cache=True, inline="always")
def _contact_force(delta, ddelta, k_c, c_c, hertz):
    """Force of the contact on the body (N, >= 0) at penetration ``delta`` (m) and its
    rate ``ddelta`` (m/s): Kelvin-Voigt ``k delta + c delta'``, or Hunt-Crossley
    ``k delta^1.5 (1 + c delta')`` with ``hertz``; zero when apart or when it would pull."""
    if delta <= 0.0:
        return 0.0
    if hertz:
        f = k_c * delta**1.5 * (1.0 + c_c * ddelta)
    else:
        f = k_c * delta + c_c * ddelta
    return f if f > 0.0 else 0.0


@numba.njit(cache=True, inline="always")
def _plate(t, amp, amp_rate, w, hk, ha, hpsi):
    """Commanded plate position (m) and velocity (m/s) at ``t`` (s), for the amplitude
    ``amp`` (m) at ``t`` changing at ``amp_rate`` (m/s; nonzero during a ramp). The
    ramp's own term matters: the contact's dashpot sees any velocity the position has."""
    ph = w * t
    s1, c1 = math.sin(ph), math.cos(ph)
    sk, ck = math.sin(hk * ph + hpsi), math.cos(hk * ph + hpsi)
    shape = s1 + ha * sk
    return amp * shape, amp * w * (c1 + ha * hk * ck) + amp_rate * shape


@numba.njit(cache=True, inline="always")
def _rates(t, st, t0, amp0, amp_rate, w, hk, ha, hpsi, mu, k_c, c_c, hertz, m_ratio, wn, zeta):
    """Time derivatives of the state ``(y, v, z, zd)``: the body's height and velocity, the
    armature's displacement and velocity (m, m/s), with the contact force (N); the
    commanded amplitude is ``amp0`` at ``t0``, changing at ``amp_rate``."""
    xp, vp = _plate(t, amp0 + amp_rate * (t - t0), amp_rate, w, hk, ha, hpsi)
    y, v, z, zd = st[0], st[1], st[2], st[3]
    f = _contact_force(xp + z - y, vp + zd - v, k_c, c_c, hertz)
    acc = -G - mu * G * math.tanh(v / V_EPS) + f / MASS_KG
    # the armature, of mass MASS_KG / m_ratio, pushed down by the contact force
    zacc = -2.0 * zeta * wn * zd - wn * wn * z - f * m_ratio / MASS_KG
    return v, acc, zd, zacc, f


@numba.njit(cache=True)
def integrate(t_end, dt, w, ramp_t, amp_t, amp_v, mu, k_c, c_c, hertz, hk, ha, hpsi,
              m_ratio, wn, zeta, fs, y0=0.0, t_release=0.0):  # fmt: skip
    """Contact state (1.0 closed) at each sample instant ``i / fs``, shape (n,), and the
    number of contacts begun. SI units. ``amp_t``/``amp_v``: the commanded amplitude (m)
    reached at each time (s), ramped linearly over the ``ramp_t`` (s) before it. The body
    starts at rest ``y0`` (m) above the plate, held there until ``t_release`` (s): a drop
    test (0: at rest on the plate from the start)."""
    n_out = int(t_end * fs)
    out = np.zeros(n_out, dtype=np.float32)
    xp, _ = _plate(0.0, amp_v[0], 0.0, w, hk, ha, hpsi)
    st = np.array([xp + y0, 0.0, 0.0, 0.0])
    k1 = np.zeros(4)
    k2 = np.zeros(4)
    k3 = np.zeros(4)
    k4 = np.zeros(4)
    tmp = np.zeros(4)
    j = 0
    was_closed = True
    contacts = 0
    nxt = 0
    n_steps = int(t_end / dt)
    h = 0.5 * dt
    for i in range(n_steps):
        t = i * dt
        if t < t_release:  # held above the plate: the circuit open
            while nxt < n_out and nxt <= t * fs:
                nxt += 1
            continue
        while j + 1 < amp_t.shape[0] and t >= amp_t[j + 1]:
            j += 1
        # linear in time over the ramp_t before the next step starts (never beyond it)
        rate = 0.0
        amp = amp_v[j]
        if j + 1 < amp_t.shape[0] and t + dt > amp_t[j + 1] - ramp_t:
            rate = (amp_v[j + 1] - amp_v[j]) / ramp_t
            amp = amp_v[j] + rate * max(t - (amp_t[j + 1] - ramp_t), 0.0)
        r = _rates(t, st, t, amp, rate, w, hk, ha, hpsi, mu, k_c, c_c, hertz, m_ratio, wn, zeta)
        for q in range(4):
            k1[q] = r[q]
            tmp[q] = st[q] + h * r[q]
        closed = r[4] > 0.0
        r = _rates(
            t + h, tmp, t, amp, rate, w, hk, ha, hpsi, mu, k_c, c_c, hertz, m_ratio, wn, zeta
        )
        for q in range(4):
            k2[q] = r[q]
            tmp[q] = st[q] + h * r[q]
        r = _rates(
            t + h, tmp, t, amp, rate, w, hk, ha, hpsi, mu, k_c, c_c, hertz, m_ratio, wn, zeta
        )
        for q in range(4):
            k3[q] = r[q]
            tmp[q] = st[q] + dt * r[q]
        r = _rates(
            t + dt, tmp, t, amp, rate, w, hk, ha, hpsi, mu, k_c, c_c, hertz, m_ratio, wn, zeta
        )
        for q in range(4):
            k4[q] = r[q]
            st[q] += dt * (k1[q] + 2.0 * k2[q] + 2.0 * k3[q] + k4[q]) / 6.0
        if closed and not was_closed:
            contacts += 1
        was_closed = closed
        while nxt < n_out and nxt <= t * fs:
            out[nxt] = 1.0 if closed else 0.0
            nxt += 1
    return out, contacts


@numba.njit(cache=True)
def bounce_once(v0, k_c, c_c, hertz, dt):
    """Restitution and contact time (s) of a body arriving at ``v0`` (m/s, > 0) on a
    still, rigid plate, without gravity: the contact's own ``e``."""
    y, v, t = 0.0, -v0, 0.0
    while True:  # RK4 of y'' = f(-y, -v) / m while in contact
        a1 = _contact_force(-y, -v, k_c, c_c, hertz) / MASS_KG
        y2, v2 = y + 0.5 * dt * v, v + 0.5 * dt * a1
        a2 = _contact_force(-y2, -v2, k_c, c_c, hertz) / MASS_KG
        y3, v3 = y + 0.5 * dt * v2, v + 0.5 * dt * a2
        a3 = _contact_force(-y3, -v3, k_c, c_c, hertz) / MASS_KG
        y4, v4 = y + dt * v3, v + dt * a3
        a4 = _contact_force(-y4, -v4, k_c, c_c, hertz) / MASS_KG
        y += dt * (v + 2.0 * v2 + 2.0 * v3 + v4) / 6.0
        v += dt * (a1 + 2.0 * a2 + 2.0 * a3 + a4) / 6.0
        t += dt
        if t > dt and (y >= 0.0 or _contact_force(-y, -v, k_c, c_c, hertz) <= 0.0):
            return v / v0, t


def contact_for(e: float, contact_s: float, dt: float, hertz: bool = False,
                v_ref: float = 0.3) -> tuple[float, float]:  # fmt: skip
    """Stiffness and damping ``(k, c)`` of a contact that returns ``e`` and lasts about
    ``contact_s`` for a body arriving at ``v_ref`` m/s (bisection on the damping; the
    Kelvin-Voigt ``e`` does not depend on the speed, the Hertzian one does)."""
    if hertz:
        # Hertz: contact time ~ 2.87 (m^2 / (k^2 v))^(1/5)
        k_c = (2.87**2.5) * MASS_KG / (contact_s**2.5 * v_ref**0.5)
    else:
        k_c = MASS_KG * (math.pi / contact_s) ** 2
    scale = 2.0 * math.sqrt(k_c * MASS_KG) if not hertz else 1.0
    lo, hi = 0.0, 5.0 * scale if not hertz else 50.0
    for _ in range(60):
        mid = 0.5 * (lo + hi)
        if bounce_once(v_ref, k_c, mid, hertz, dt / 20)[0] > e:
            lo = mid
        else:
            hi = mid
    return k_c, 0.5 * (lo + hi)


#: the CSV recording's column of each channel role
CSV_COLUMNS = {"continuity": "cont_v", "drive": "drive_v"}


def write_run(out: Path, spec: dict, stem: str, fmt: str, fs: float, channels: dict) -> None:
    """Write the recording ``out/<stem>.wav`` (16-bit, full scale 4 V) or ``.csv`` (with
    ``time_s``) of ``channels`` (role -> volts, shape (n,) each, continuity first) and
    ``out/run.yaml`` of ``spec`` with its ``recording`` and ``channels`` keys added."""
    if fmt == "csv":
        import pandas as pd

        spec["recording"] = f"{stem}.csv"
        spec["channels"] = {role: CSV_COLUMNS[role] for role in channels}
        n = len(next(iter(channels.values())))
        columns = {"time_s": np.arange(n) / fs}
        columns |= {CSV_COLUMNS[role]: v for role, v in channels.items()}
        pd.DataFrame(columns).to_csv(out / f"{stem}.csv", index=False, float_format="%.9g")
    else:
        spec["recording"] = f"{stem}.wav"
        spec["channels"] = {role: i for i, role in enumerate(channels)}
        spec["full_scale_v"] = 4.0
        volts = np.stack(list(channels.values()), axis=1)
        sf.write(out / f"{stem}.wav", (volts[:, 0] if volts.shape[1] == 1 else volts) / 4.0,
                 int(fs), subtype="PCM_16")  # fmt: skip
    (out / "run.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))


DEFAULTS = {
    "f": 30.0, "fs": 20000.0, "g0": 0.0, "g1": 4.0, "dg": 0.05, "step_s": 2.0,
    "ramp_cycles": 1.0, "mu": 0.0, "e": 0.0, "contact_s": 1e-4, "hertz": False,
    "k": 3.0, "a": 0.0, "psi": 0.0, "s": 1.0,
    "mass_ratio": 0.0, "f_ratio": 0.6, "zeta": 0.05,
    "noise_v": 0.02, "contact_high": False, "format": "wav", "seed": 1, "dt": 2e-6,
}  # fmt: skip

#: damping ratio of the null cases' contact: e 0.004, below what the diagnosis counts as
#: restitution (``select.INERT``: 0.01); a critically damped contact still returns 0.14
PLASTIC_ZETA = 8.0


def make_case(out: Path, **opt) -> dict:
    """Write one run folder ``out`` and ``out.truth.json``; returns the truth."""
    o = dict(DEFAULTS, **opt)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    w = 2.0 * math.pi * o["f"]
    if o["e"] > 0.0 or o["hertz"]:
        k_c, c_c = contact_for(o["e"], o["contact_s"], o["dt"], o["hertz"])
    else:  # plastic: a damping ratio of 8 returns e 0.004 (2 gives 0.05, 4 0.014)
        k_c = MASS_KG * (math.pi / o["contact_s"]) ** 2
        c_c = 2.0 * PLASTIC_ZETA * math.sqrt(k_c * MASS_KG)
    e_slow = bounce_once(0.05, k_c, c_c, o["hertz"], o["dt"] / 20)
    e_fast = bounce_once(0.5, k_c, c_c, o["hertz"], o["dt"] / 20)
    gammas = np.round(np.arange(o["g0"], o["g1"] + 1e-9, o["dg"]), 6)
    t_s = o["step_s"] * np.arange(gammas.size)
    t_end = float(t_s[-1] + o["step_s"])
    amp_v = o["s"] * gammas * G / w**2
    wn = o["f_ratio"] * w
    contact, n_contacts = integrate(
        t_end, o["dt"], w, o["ramp_cycles"] / o["f"], t_s, amp_v, o["mu"], k_c, c_c,
        bool(o["hertz"]), o["k"], o["a"], o["psi"], o["mass_ratio"], wn, o["zeta"], o["fs"],
    )  # fmt: skip
    rng = np.random.default_rng(o["seed"])
    n = contact.size
    level = contact if o["contact_high"] else 1.0 - contact
    volts = 2.5 * level + rng.normal(0.0, o["noise_v"], n)
    time_s = np.arange(n) / o["fs"]
    drive = 0.7 * np.sin(w * time_s) + rng.normal(0.0, 0.01, n)
    spec = {
        "format_version": 1,
        "kind": "sweep",
        "sample_rate_hz": int(o["fs"]),
        "drive_frequency_hz": o["f"],
        "gamma_steps": [
            {"t_s": float(t), "gamma": float(g)} for t, g in zip(t_s, gammas, strict=True)
        ],
        "settle_cycles": 10,
        "mass_kg": MASS_KG,
        "contact_level": "high" if o["contact_high"] else "low",
        "description": "compliant-contact generator (benchmarks/compliant_rig.py)",
    }
    write_run(out, spec, "rec", o["format"], o["fs"], {"continuity": volts, "drive": drive})
    effects: dict = {}
    if o["mu"] > 0:
        effects["friction"] = {"mu": o["mu"]}
    if o["e"] > 0 and not o["hertz"]:
        effects["restitution"] = {"e": o["e"]}
    if o["a"] > 0:
        effects["harmonic"] = {"k": o["k"], "a": o["a"], "psi": o["psi"]}
    if o["mass_ratio"] > 0:
        effects["feedback"] = {
            "mass_ratio": o["mass_ratio"], "f_ratio": o["f_ratio"], "zeta": o["zeta"],
        }  # fmt: skip
    if o["s"] != 1.0:
        effects["gamma_scale"] = {"s": o["s"]}
    truth = {
        "effects": effects,
        "outside": ["hertzian_contact"] if o["hertz"] else [],
        # the contact's e is against the recoiling plate: the model's two-body e
        "restitution_frame": "two_body",
        "contact_e_at": {"0.05_m_s": e_slow[0], "0.5_m_s": e_fast[0]},
        "contact_time_s": {"0.05_m_s": e_slow[1], "0.5_m_s": e_fast[1]},
        "contacts": int(n_contacts),
        "options": o,
    }
    out.with_name(out.name + ".truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    truth["impacts"] = int(n_contacts)
    return truth


DROP_DEFAULTS = {
    "mu": 0.29, "e": 0.515, "contact_s": 1e-4, "h": 0.05, "release_t_s": 0.2,
    "duration_s": 1.5, "fs": 20000.0, "noise_v": 0.02, "format": "wav", "seed": 1, "dt": 2e-6,
}  # fmt: skip


def make_drop(out: Path, **opt) -> dict:
    """Write one drop-test run folder ``out`` (CONTRACTS.md section 1, ``kind: drop``; the
    plate still, the body released from ``h`` m at ``release_t_s``) and
    ``out.truth.json``; returns the truth (``mu``, ``e``)."""
    o = dict(DROP_DEFAULTS, **opt)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    k_c, c_c = contact_for(o["e"], o["contact_s"], o["dt"])
    contact, n_contacts = integrate(
        o["duration_s"], o["dt"], 1.0, 1.0, np.zeros(1), np.zeros(1), o["mu"], k_c, c_c,
        False, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0, o["fs"], o["h"], o["release_t_s"],
    )  # fmt: skip
    rng = np.random.default_rng(o["seed"])
    volts = 2.5 * (1.0 - contact) + rng.normal(0.0, o["noise_v"], contact.size)
    spec = {
        "format_version": 1,
        "kind": "drop",
        "sample_rate_hz": int(o["fs"]),
        "mass_kg": MASS_KG,
        "drop_height_m": o["h"],
        "release_t_s": o["release_t_s"],
        "g_m_s2": G,  # the generator's gravity (calibrate assumes 9.80665 without it)
        "contact_level": "low",
        "description": "compliant-contact generator, drop test (benchmarks/compliant_rig.py)",
    }
    write_run(out, spec, "drop", o["format"], o["fs"], {"continuity": volts})
    truth = {
        "mu": o["mu"],
        "e": bounce_once(0.5, k_c, c_c, False, o["dt"] / 20)[0],
        "contact_time_s": bounce_once(0.5, k_c, c_c, False, o["dt"] / 20)[1],
        "contacts": int(n_contacts),
        "options": o,
    }
    out.with_name(out.name + ".truth.json").write_text(json.dumps(truth, indent=1) + "\n")
    return truth


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    for key, value in DEFAULTS.items():
        if isinstance(value, bool):
            p.add_argument("--" + key.replace("_", "-"), action="store_true")
        else:
            p.add_argument("--" + key.replace("_", "-"), type=type(value), default=value)
    args = vars(p.parse_args())
    out = args.pop("out")
    truth = make_case(out, **args)
    print(
        f"{out}: {truth['contacts']} contacts, effects {sorted(truth['effects'])}, "
        f"e {truth['contact_e_at']}, contact {truth['contact_time_s']}"
    )


if __name__ == "__main__":
    main()
