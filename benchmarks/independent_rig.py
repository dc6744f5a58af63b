"""A second recording generator, written without bouncelab's physics or rig code.

The virtual rig (``bouncelab.rig``) is the project's own; acceptance is checked on
recordings made elsewhere. This generator makes them differently on purpose, so that
what the diagnosis assumes of our rig shows up:

- hard contact: instantaneous impacts (restitution ``e``), a body that sticks once its
  rebound is slower than ``stick_v``, or (``stick_flight_s`` > 0, a simulator's
  sticking threshold) once its next flight, predicted with the plate's acceleration
  held, would be shorter than ``stick_flight_s``; the continuity circuit stays closed
  ``contact_s`` after every impact (a real impact lasts tens to hundreds of
  microseconds);
- fixed-step integration (``dt`` = 2 us) of flight under gravity and Coulomb friction,
  the armature propagated exactly over each step;
- Gamma switched instantly at each step's ``t_s``, wherever the drive phase is (``t0``
  puts the steps off the drive cycles); swept up, down, or up and back down
  (``up_down``: every Gamma but the top one twice, on both branches of a hysteresis);
  steps of one length, or of lengths within ``step_jitter`` of it (a hand-stepped sweep);
  or in a random order (``shuffled``), or with a Gamma range never stepped
  (``skip_lo`` to ``skip_hi``: a gap in the data, CONTRACTS.md section 1);
- a shaker armature kicked by impacts only (CONTRACTS.md section 5, no riding load);
- the circuit sampled instantaneously, with white noise, either polarity, WAV or CSV;
- outside the library: a sensor delay, a restitution that changes with impact speed,
  random plate vibration (a sum of sinusoids of random frequencies in 5-200 Hz), a body
  held on the plate through each impact's ``contact_s`` (``hold``: a dwell; it then
  leaves at its rebound speed relative to the plate);
- flaws of a lab's records, which a diagnosis should see through: a circuit that misses
  a share of the short contacts (``lost_contacts``: the flights around each merge), and
  each step's Gamma read off with a random relative error (``gamma_read_sd``: the
  recording is driven at the true Gamma, ``run.yaml`` states the reading).

Use: ``python benchmarks/independent_rig.py OUT_DIR [--mu 0.2 --e 0.4 ...]`` writes
``OUT_DIR/run.yaml`` and the recording, and ``OUT_DIR.truth.json`` beside the folder
(never inside it). ``bench_independent.py`` runs the diagnosis on a set of such cases.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numba
import numpy as np
import pandas as pd
import soundfile as sf
import yaml

G = 9.81  # m/s^2

#: Longest contact the circuit can miss (``lost_contacts``): an impact's or a short ride's,
#: not a body resting on the plate.
LOST_CONTACT_MAX_S = 3e-3


@numba.njit(cache=True)
def integrate(
    t_end, dt, w, amp_t, amp_v, mu, e, hk, ha, hpsi, mass_ratio, f_ratio, zeta, contact_s,
    stick_v, stick_flight_s, fs, step, e_slope, e_ref_v, vib_w, vib_a, vib_phi, hold,
):  # fmt: skip
    """Contact state (1.0 closed) at each sample instant ``k / fs``, shape (n,), and the
    number of impacts. SI units; ``amp_t``/``amp_v``: the plate amplitude (m) from each
    time on (instant switches); ``step``: the armature's free propagator over ``dt``
    (:func:`armature_step`), shape (2, 2); restitution ``e + e_slope (|u| - e_ref_v)``
    at impact speed ``|u|`` (clipped to [0, 0.99]); random plate vibration: sinusoids of
    ``vib_w`` (rad/s), ``vib_a`` (m), ``vib_phi`` (rad), shape (N,) each; ``hold``: the
    body moves with the plate through each impact's ``contact_s`` and leaves at its
    rebound speed relative to the plate then (a dwell; else it leaves at once)."""
    n_out = int(t_end * fs)
    # the vibration's phasors at t, rotated by one step each step (no trig in the loop)
    vc = np.cos(vib_phi)
    vs = np.sin(vib_phi)
    rc = np.cos(vib_w * dt)
    rs = np.sin(vib_w * dt)
    xv = np.sum(vib_a * vs)
    vv = np.sum(vib_a * vib_w * vc)
    contact = np.zeros(n_out, dtype=np.float32)
    wn = f_ratio * w  # armature natural frequency, rad/s
    z = 0.0  # armature displacement (m) and velocity
    zd = 0.0
    k_amp = 0
    y = 0.0
    v = 0.0
    riding = True
    held = False  # moving with the plate through an impact (hold)
    held_until = -1.0
    held_rebound = 0.0
    closed_until = -1.0
    impacts = 0
    next_sample = 0
    for i in range(int(t_end / dt)):
        t = i * dt
        while k_amp + 1 < amp_t.shape[0] and t >= amp_t[k_amp + 1]:
            k_amp += 1
        amp = amp_v[k_amp]
        ph = w * t
        av = 0.0
        for j in range(vib_w.shape[0]):
            av -= vib_a[j] * vib_w[j] * vib_w[j] * vs[j]
        xp = amp * (math.sin(ph) + ha * math.sin(hk * ph + hpsi)) + z + xv
        vp = amp * w * (math.cos(ph) + ha * hk * math.cos(hk * ph + hpsi)) + zd + vv
        ap = (
            -amp * w * w * (math.sin(ph) + ha * hk * hk * math.sin(hk * ph + hpsi))
            - 2.0 * zeta * wn * zd
            - wn * wn * z
            + av
        )
        # the vibration at t + dt
        xv1 = 0.0
        vv1 = 0.0
        for j in range(vib_w.shape[0]):
            c = vc[j] * rc[j] - vs[j] * rs[j]
            vs[j] = vs[j] * rc[j] + vc[j] * rs[j]
            vc[j] = c
            xv1 += vib_a[j] * vs[j]
            vv1 += vib_a[j] * vib_w[j] * c
        if held:
            y = xp
            v = vp
            if t >= held_until:  # the dwell ends: the body leaves at its rebound speed
                held = False
                v = vp + held_rebound
        if riding:
            y = xp
            v = vp
            # friction opposes the body's motion: it leaves once the plate falls faster
            g_eff = G * (1.0 + mu) if v > 0.0 else G * (1.0 - mu)
            if ap < -g_eff:
                riding = False
        # the armature's state at t + dt, exact: the impact test below compares the body
        # with the plate where both really are (a plate position short of the armature's
        # acceleration term made the body "land" again microseconds after each takeoff)
        z1 = step[0, 0] * z + step[0, 1] * zd
        zd1 = step[1, 0] * z + step[1, 1] * zd
        if not riding and not held:
            acc = -G * (1.0 + mu) if v > 0.0 else -G * (1.0 - mu)
            y += v * dt + 0.5 * acc * dt * dt
            v += acc * dt
            t1 = t + dt
            ph1 = w * t1
            xp1 = amp * (math.sin(ph1) + ha * math.sin(hk * ph1 + hpsi)) + z1 + xv1
            vp1 = amp * w * (math.cos(ph1) + ha * hk * math.cos(hk * ph1 + hpsi)) + zd1 + vv1
            if y <= xp1:
                v_rel = v - vp1  # < 0: the body hits the plate
                impacts += 1
                closed_until = t1 + contact_s
                e_u = min(max(e + e_slope * (-v_rel - e_ref_v), 0.0), 0.99)
                zd1 += mass_ratio * (1.0 + e_u) * v_rel  # the impact's momentum kicks the armature
                y = xp1
                rebound = -e_u * v_rel
                # the next flight with the plate's acceleration held: up against gravity
                # and friction relative to the plate, then down to it
                c_up = G * (1.0 + mu) + ap
                c_down = G * (1.0 - mu) + ap
                short = False
                if stick_flight_s > 0.0 and c_up > 0.0 and c_down > 0.0:
                    flight = rebound / c_up + rebound / math.sqrt(c_up * c_down)
                    short = flight < stick_flight_s
                if rebound < stick_v or short:
                    riding = True
                elif hold:
                    held, held_until, held_rebound = True, t1 + contact_s, rebound
                else:
                    v = vp1 + rebound
        z = z1
        zd = zd1
        xv = xv1
        vv = vv1
        while next_sample < n_out and next_sample <= t * fs:
            closed = riding or t < closed_until
            contact[next_sample] = 1.0 if closed else 0.0
            next_sample += 1
    return contact, impacts


def armature_step(wn: float, zeta: float, dt: float) -> np.ndarray:
    """Propagator of the free armature over ``dt`` (s): ``[z, zd](t + dt) = P @ [z, zd](t)``
    for ``z'' + 2 zeta wn z' + wn^2 z = 0`` (``wn`` rad/s, ``0 <= zeta < 1``), shape (2, 2).
    Exact, from the closed-form damped sinusoid."""
    if wn <= 0.0:
        return np.eye(2)
    if not 0.0 <= zeta < 1.0:
        raise ValueError(f"zeta {zeta}: the generator's armature is underdamped (0 <= zeta < 1)")
    wd = wn * math.sqrt(1.0 - zeta * zeta)
    decay, c, s = math.exp(-zeta * wn * dt), math.cos(wd * dt), math.sin(wd * dt)
    return decay * np.array(
        [[c + zeta * wn * s / wd, s / wd], [-wn * wn * s / wd, c - zeta * wn * s / wd]]
    )


def vibration(rms_m: float, seed: int, n: int = 24, band_hz=(5.0, 200.0)):
    """Random plate vibration as ``n`` sinusoids of frequencies drawn uniformly in
    ``band_hz``, random phases, equal amplitudes of ``rms_m`` in all (m): ``(w rad/s,
    a m, phi rad)``, shape (n,) each; empty arrays for ``rms_m = 0``."""
    if rms_m <= 0.0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    rng = np.random.default_rng([seed, 7])  # apart from the noise's stream
    w = 2.0 * math.pi * rng.uniform(band_hz[0], band_hz[1], n)
    return w, np.full(n, rms_m * math.sqrt(2.0 / n)), rng.uniform(0.0, 2.0 * math.pi, n)


def make_case(out: Path, **opt) -> dict:
    """Write one run folder ``out`` and ``out.truth.json``; returns the truth."""
    o = dict(DEFAULTS, **opt)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    w = 2.0 * math.pi * o["f"]
    gammas = np.round(np.arange(o["g0"], o["g1"] + 1e-9, o["dg"]), 6)
    if o["skip_hi"] > o["skip_lo"]:  # a Gamma range never stepped: a gap in the data
        gammas = gammas[(gammas < o["skip_lo"]) | (gammas > o["skip_hi"])]
    if o["up_down"]:  # up, then down again: every Gamma but the top twice, as labs sweep
        gammas = np.concatenate([gammas, gammas[-2::-1]])
    elif o["descending"]:  # swept down: the other branch of every hysteresis loop
        gammas = gammas[::-1]
    elif o["shuffled"]:  # the steps in a random order, as a lab randomises its protocol
        gammas = np.random.default_rng([o["seed"], 5]).permutation(gammas)
    if o["step_jitter"]:  # stepped by hand: each length within +- step_jitter of step_s
        # (a stream of its own, so that the recording's noise stays the seed's)
        share = np.random.default_rng([o["seed"], 3]).uniform(-1.0, 1.0, gammas.size)
        durations = o["step_s"] * (1.0 + o["step_jitter"] * share)
        t_s = o["t0"] + np.concatenate([[0.0], np.cumsum(durations)[:-1]])
        t_end = float(t_s[-1] + durations[-1])
    else:  # the product, not a sum of lengths: the recorded cases' step times to the bit
        t_s = o["t0"] + o["step_s"] * np.arange(gammas.size)
        t_end = float(t_s[-1] + o["step_s"])
    amp_t = np.concatenate([[0.0], t_s])
    amp_v = np.concatenate([[0.0], o["s"] * gammas * G / w**2])
    contact, impacts = integrate(
        t_end, o["dt"], w, amp_t, amp_v, o["mu"], o["e"], o["k"], o["a"], o["psi"],
        o["mass_ratio"], o["f_ratio"], o["zeta"], o["contact_s"], o["stick_v"],
        o["stick_flight_s"], o["fs"], armature_step(o["f_ratio"] * w, o["zeta"], o["dt"]),
        o["e_slope"], o["e_ref_v"], *vibration(o["vib_rms"], o["seed"]), o["hold"],
    )  # fmt: skip
    n_lost = 0
    if o["lost_contacts"]:  # the circuit fails to close on some short contacts
        contact, n_lost = lose_contacts(contact, o["lost_contacts"], o["fs"], o["seed"])
    shift = int(round(o["delay_s"] * o["fs"]))
    if shift:  # a sensor delay: the circuit reports every contact late
        contact = np.concatenate([np.ones(shift, np.float32), contact[:-shift]])
    rng = np.random.default_rng(o["seed"])
    n = contact.size
    level = contact if o["contact_high"] else 1.0 - contact
    volts = 3.3 * level + rng.normal(0.0, o["noise_v"], n)
    time_s = np.arange(n) / o["fs"]
    drive = 0.8 * np.sin(w * time_s) + rng.normal(0.0, 0.01, n)
    stated = gammas
    if o["gamma_read_sd"]:  # each step's Gamma read off a scope, with a relative error
        error = np.random.default_rng([o["seed"], 5]).standard_normal(gammas.size)
        stated = np.round(gammas * (1.0 + o["gamma_read_sd"] * error), 4)
    spec = {
        "format_version": 1,
        "kind": "sweep",
        "sample_rate_hz": int(o["fs"]),
        "drive_frequency_hz": o["f"],
        "gamma_steps": [
            {"t_s": float(t), "gamma": float(g)} for t, g in zip(t_s, stated, strict=True)
        ],
        "settle_cycles": 10,
        "mass_kg": 0.2,
        "description": "independent generator (benchmarks/independent_rig.py)",
    }
    columns = [volts] if o["no_drive"] else [volts, drive]
    if o["format"] == "wav":
        data = np.stack(columns, axis=1) / 4.0
        sf.write(out / "rec.wav", data.astype(np.float32), int(o["fs"]), subtype="PCM_24")
        spec |= {"recording": "rec.wav", "channels": {"continuity": 0, "drive": 1}}
        spec["full_scale_v"] = 4.0
    else:
        frame = pd.DataFrame({"time_s": time_s, "cont": volts, "drv": drive})
        frame.to_csv(out / "rec.csv", index=False, float_format="%.10g")
        spec |= {"recording": "rec.csv", "channels": {"continuity": "cont", "drive": "drv"}}
    if o["no_drive"]:
        del spec["channels"]["drive"]
    (out / "run.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    truth = {**o, "impacts": int(impacts), "effects": true_effects(o), "outside": outside(o)}
    if n_lost:
        truth["contacts_lost"] = n_lost
    out.with_name(out.name + ".truth.json").write_text(json.dumps(truth, indent=1))
    return truth


def lose_contacts(
    contact: np.ndarray, share: float, fs: float, seed: int
) -> tuple[np.ndarray, int]:
    """``contact`` (1.0 closed, shape (n,)) with each contact shorter than
    :data:`LOST_CONTACT_MAX_S` opened with probability ``share``, and how many were: a
    circuit that does not close on a light touch, so the flights before and after it are
    recorded as one."""
    closed = contact > 0.5
    edges = np.diff(closed.astype(np.int8), prepend=0, append=0)
    starts, ends = np.flatnonzero(edges == 1), np.flatnonzero(edges == -1)
    short = (ends - starts) < LOST_CONTACT_MAX_S * fs
    lost = short & (np.random.default_rng([seed, 4]).random(starts.size) < share)
    out = contact.copy()
    for a, b in zip(starts[lost], ends[lost], strict=True):
        out[a:b] = 0.0
    return out, int(lost.sum())


def outside(o: dict) -> list[str]:
    """Effects outside the library (CONTRACTS.md section 5) that the options switch on:
    a run with any of them should come out unexplained."""
    names = {"delay_s": "sensor_delay", "e_slope": "velocity_dependent_restitution"}
    out = [name for key, name in names.items() if o[key] != 0]
    out += ["random_vibration"] if o["vib_rms"] > 0 else []
    return out + (["held_contact"] if o["hold"] else [])


def true_effects(o: dict) -> dict:
    """Library effects (CONTRACTS.md section 5) that the options switch on, with their
    parameters; the contact time, stick speed and sensor delay are outside the library."""
    eff = {}
    if o["mu"] > 0:
        eff["friction"] = {"mu": o["mu"]}
    if o["e"] > 0:
        eff["restitution"] = {"e": o["e"]}
    if o["a"] > 0:
        eff["harmonic"] = {"k": o["k"], "a": o["a"], "psi": o["psi"]}
    if o["mass_ratio"] > 0:
        eff["feedback"] = {k: o[k] for k in ("mass_ratio", "f_ratio", "zeta")}
    if o["s"] != 1.0:
        eff["gamma_scale"] = {"s": o["s"]}
    return eff


DEFAULTS = {
    "f": 30.0, "fs": 20000.0, "g0": 0.0, "g1": 4.0, "dg": 0.05, "step_s": 2.0,
    "step_jitter": 0.0, "t0": 0.0,
    "mu": 0.0, "e": 0.0, "k": 3.0, "a": 0.0, "psi": 0.0, "s": 1.0,
    "mass_ratio": 0.0, "f_ratio": 0.6, "zeta": 0.05,
    "contact_s": 8e-5, "stick_v": 2e-4, "stick_flight_s": 0.0, "noise_v": 0.02,
    "delay_s": 0.0,
    "contact_high": False, "format": "wav", "seed": 1, "dt": 2e-6,
    "descending": False, "up_down": False, "no_drive": False,
    "e_slope": 0.0, "e_ref_v": 0.3, "vib_rms": 0.0,
    "lost_contacts": 0.0, "gamma_read_sd": 0.0, "shuffled": False, "skip_lo": 0.0,
    "skip_hi": 0.0, "hold": False,
}  # fmt: skip


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("out", type=Path)
    for key, value in DEFAULTS.items():
        kind = type(value) if not isinstance(value, bool) else None
        if kind is None:
            p.add_argument("--" + key.replace("_", "-"), action="store_true")
        else:
            p.add_argument("--" + key.replace("_", "-"), type=kind, default=value)
    args = vars(p.parse_args())
    out = args.pop("out")
    truth = make_case(out, **args)
    print(f"{out}: {truth['impacts']} impacts, effects {sorted(truth['effects'])}")


if __name__ == "__main__":
    main()
