"""Rig configuration: reading, schema validation, defaults, derived quantities.

The schema ``bouncelab/schemas/rig.schema.json`` is the one place where keys, units and
defaults are defined; :func:`load_rig_config` checks a YAML file against it with a real
validator, fills the defaults, then runs the checks a schema cannot express.
:func:`derive` turns a full config into the numbers the simulation needs (contact
stiffness and damping from the restitution, the step schedule, step sizes).
"""

from __future__ import annotations

import copy
import json
import math
from importlib import resources
from pathlib import Path
from typing import Any

import jsonschema
import numpy as np

from bouncelab.errors import BouncelabError
from bouncelab.rig.kernels import zeta_from_restitution
from bouncelab.yamlfile import read_yaml

# largest rest step as a fraction of the contact oscillator's period over pi:
# omega_n * h <= 0.75 keeps velocity Verlet stable (limit 2) and quasi-static riding accurate
REST_STEP_OMEGA_H = 0.75


def rig_schema() -> dict:
    """The JSON Schema of a rig config (package data)."""
    text = resources.files("bouncelab").joinpath("schemas/rig.schema.json").read_text()
    return json.loads(text)


def fill_defaults(cfg: dict, schema: dict) -> dict:
    """A copy of ``cfg`` with every missing key that has a schema ``default`` filled.

    Recurses into objects; an object missing from ``cfg`` starts from its own default
    (``{}``) and is filled in turn.
    """
    out = copy.deepcopy(cfg)
    for key, sub in schema.get("properties", {}).items():
        if key not in out and "default" in sub:
            out[key] = copy.deepcopy(sub["default"])
        if sub.get("type") == "object" and isinstance(out.get(key), dict):
            out[key] = fill_defaults(out[key], sub)
        if sub.get("type") == "array" and isinstance(out.get(key), list):
            items = sub.get("items", {})
            if items.get("type") == "object":
                out[key] = [fill_defaults(it, items) for it in out[key]]
    return out


def parse_rig_config(raw: Any, path: str | Path = "<config>") -> dict:
    """Validate a config mapping, fill defaults, check semantics; return the full config."""
    if not isinstance(raw, dict):
        raise BouncelabError(path, "rig config must be a YAML mapping")
    schema = rig_schema()
    errors = sorted(
        jsonschema.Draft202012Validator(schema).iter_errors(raw), key=lambda e: list(e.path)
    )
    if errors:
        err = errors[0]
        where = "/".join(str(p) for p in err.path) or "top level"
        raise BouncelabError(path, f"config key {where}: {err.message}")
    cfg = fill_defaults(raw, schema)
    check_semantics(cfg, path)
    return cfg


def load_rig_config(path: str | Path) -> dict:
    """Read a rig config YAML file; returns the full config with defaults filled.

    Raises :class:`BouncelabError` naming the file for a missing file, bad YAML, a
    schema violation or an inconsistent protocol.
    """
    path = Path(path)
    return parse_rig_config(read_yaml(path, "rig config file"), path)


def check_semantics(cfg: dict, path: str | Path) -> None:
    """Checks a schema cannot express; raises :class:`BouncelabError`."""
    proto = cfg["protocol"]
    fs = cfg["recording"]["sample_rate_hz"]
    if cfg["kind"] == "sweep":
        if "gammas" not in proto and proto["gamma_stop"] < proto["gamma_start"]:
            raise BouncelabError(path, "protocol.gamma_stop is below protocol.gamma_start")
        for lo, hi in proto["gaps"]:
            if not lo < hi:
                raise BouncelabError(path, f"protocol.gaps: [{lo}, {hi}] is not low < high")
        if not stated_gammas(cfg):
            raise BouncelabError(path, "protocol: every Gamma step falls in a gap")
        if cfg["drive"]["frequency_hz"] * 4 > fs:
            raise BouncelabError(path, "drive.frequency_hz must be well below the sample rate")
    else:
        if proto["release_t_s"] >= proto["duration_s"]:
            raise BouncelabError(path, "protocol.release_t_s must be before protocol.duration_s")
    lo, hi = cfg["effects"]["random_vibration_band_hz"]
    if cfg["effects"]["random_vibration_rms_m"] > 0 and not 0 <= lo < hi <= fs / 2:
        raise BouncelabError(
            path, "effects.random_vibration_band_hz must be [low, high] with high <= fs/2"
        )
    cont = cfg["sensors"]["continuity"]
    fsv = cfg["sensors"]["adc"]["full_scale_v"]
    if cont["open_v"] == cont["contact_v"]:
        raise BouncelabError(path, "sensors.continuity: open_v and contact_v must differ")
    if max(abs(cont["open_v"]), abs(cont["contact_v"])) >= fsv:
        raise BouncelabError(path, "sensors.continuity levels exceed the ADC full scale")
    if cfg["sensors"]["accel"]["enabled"] and cfg["sensors"]["accel"]["ring_hz"] >= fs / 2:
        raise BouncelabError(path, "sensors.accel.ring_hz must be below fs/2")


def stated_gammas(cfg: dict) -> list[float]:
    """Stated Gamma of every step of a sweep, gaps removed (rounded to 1e-9)."""
    proto = cfg["protocol"]
    if "gammas" in proto:
        gammas = [float(g) for g in proto["gammas"]]
    else:
        n = int(
            math.floor((proto["gamma_stop"] - proto["gamma_start"]) / proto["gamma_step"] + 1e-9)
        )
        gammas = [proto["gamma_start"] + i * proto["gamma_step"] for i in range(n + 1)]
    gammas = [round(g, 9) for g in gammas]
    tol = 1e-9  # a step exactly on a gap's edge is kept (the seed's gaps are open intervals)
    return [g for g in gammas if not any(lo + tol < g < hi - tol for lo, hi in proto["gaps"])]


def derive(cfg: dict) -> dict:
    """The numbers the simulation needs, from a full config (SI units throughout).

    Contact: with ``mu_red`` the reduced mass of body and armature (the body's mass
    with a rigid shaker), ``omega_n = pi / contact_time_s``, ``k = mu_red omega_n^2``,
    ``zeta = -ln e / sqrt(pi^2 + ln^2 e)`` (1 for e = 0), ``c = 2 zeta sqrt(k mu_red)``.
    Schedule (sweep): step ``i`` starts at ``i * cycles_per_step / f`` (phase zero of
    the drive), true amplitude ``gamma_scale * Gamma_i g / omega^2``.
    """
    body, drive, shaker = cfg["body"], cfg["drive"], cfg["shaker"]
    proto, integ = cfg["protocol"], cfg["integration"]
    fs = float(cfg["recording"]["sample_rate_hz"])
    m, g = body["mass_kg"], body["g_m_s2"]
    f = drive["frequency_hz"]
    omega = 2.0 * math.pi * f
    arm_m = shaker["armature_mass_kg"]
    feedback = bool(shaker["feedback"])
    mu_red = m * arm_m / (m + arm_m) if feedback else m
    t_c = body["contact_time_s"]
    omega_n = math.pi / t_c
    k = mu_red * omega_n**2
    zeta = float(zeta_from_restitution(body["restitution"]))
    omega_arm = 2.0 * math.pi * shaker["natural_frequency_hz"]
    d: dict[str, Any] = {
        "omega_rad_s": omega,
        "contact_stiffness_n_m": k,
        "contact_reduced_mass_kg": mu_red,
        "contact_zeta": zeta,
        "contact_damping_n_s_m": 2.0 * zeta * math.sqrt(k * mu_red),
        "contact_duration_s": (t_c / math.sqrt(1.0 - zeta**2)) if zeta < 1 else float("inf"),
        "static_penetration_m": m * g / k,
        "armature_stiffness_n_m": arm_m * omega_arm**2,
        "armature_damping_n_s_m": 2.0 * shaker["damping_ratio"] * arm_m * omega_arm,
        "mass_ratio": m / arm_m,
        "f_ratio": shaker["natural_frequency_hz"] / f,
        "steps_per_sample_impact": int(math.ceil(integ["steps_per_contact"] / (t_c * fs))),
        "steps_per_sample_rest": max(2, int(math.ceil(omega_n / fs / REST_STEP_OMEGA_H))),
        "steps_per_sample_flight": int(integ["flight_steps_per_sample"]),
        "fine_window_s": integ["fine_contacts"] * t_c,
    }
    if cfg["kind"] == "sweep":
        gammas = stated_gammas(cfg)
        step_s = proto["cycles_per_step"] / f
        d["gammas"] = gammas
        d["gammas_true"] = [drive["gamma_scale"] * gm for gm in gammas]
        d["step_t_s"] = [round(i * step_s, 9) for i in range(len(gammas))]
        d["amplitudes_m"] = [gt * g / omega**2 for gt in d["gammas_true"]]
        d["duration_s"] = len(gammas) * step_s
    else:
        d["gammas"], d["gammas_true"], d["step_t_s"], d["amplitudes_m"] = [], [], [0.0], [0.0]
        d["duration_s"] = float(proto["duration_s"])
    d["n_samples"] = int(round(d["duration_s"] * fs))
    return d


def step_schedule(derived: dict) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Segment arrays for the kernel: start times (s), amplitudes (m), ramp-from (m)."""
    seg_t = np.asarray(derived["step_t_s"], dtype=float)
    seg_amp = np.asarray(derived["amplitudes_m"], dtype=float)
    seg_prev = np.concatenate([[0.0], seg_amp[:-1]])
    return seg_t, seg_amp, seg_prev
