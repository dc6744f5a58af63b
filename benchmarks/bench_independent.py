"""The gap diagnosis on recordings from a generator that is not our rig.

Acceptance of issue 6 runs ``bouncelab diagnose`` on recordings made independently of
the virtual rig. ``independent_rig.py`` (beside this file) makes such recordings another
way (hard contact with a finite closed time, fixed-step integration, instant Gamma
switches off the drive cycles, impacts-only armature, instantaneous sampling). Each case
below is generated in a temporary folder, diagnosed from the run folder alone, and only
then scored against the generator's truth: the effects selected against the true ones,
the relative parameter errors (psi: of 2 pi; the discrete k too, so a wrong k counts
as a miss, as in the blind validation), the verdict, and the time.

Measures, prints and writes ``benchmarks/results/independent.json`` (with ``--seed N``,
the diagnosis's own seed, ``independent_seedN.json``: a check that an answer is not one
seed's luck).
Run: ``python benchmarks/bench_independent.py [--only NAME ...] [--workers 2] [--seed 0]
[--diagnoses DIR] [--generator compliant]`` (``--diagnoses``: keep each case's diagnosis
JSON there, to score it again later; ``--generator compliant``: the cases of a third
generator, ``compliant_rig.py``, a compliant contact and a loaded armature, recorded in
``benchmarks/results/compliant.json``).
One case (:data:`WARM_UP`) is diagnosed first, untimed, so that numba's compiling after an
install or a source change does not land on the first case's time.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import tempfile
import time
from pathlib import Path

from bouncelab.gap.blind import warning_counts
from bouncelab.gap.diagnose import diagnose_run
from bouncelab.gap.fit import warned_params

sys.path.insert(0, str(Path(__file__).resolve().parent))
import compliant_rig  # noqa: E402
from bench_blind_seeds import retried  # noqa: E402
from bench_diagnose import GOAL_S  # noqa: E402
from bench_physics import machine_speed  # noqa: E402
from independent_rig import make_case  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "benchmarks" / "results" / "independent.json"

CASES = {
    "null": {},
    "null_10khz": {"fs": 10000.0, "g1": 5.0, "seed": 12},
    "friction_27hz_off_cycle_csv": {
        "f": 27.0, "g1": 5.0, "t0": 0.37, "mu": 0.2, "format": "csv", "seed": 2,
    },
    "friction_noisy_44khz": {"mu": 0.3, "noise_v": 0.2, "fs": 44100.0, "seed": 13},
    "restitution_33hz_contact_high": {"f": 33.0, "e": 0.45, "contact_high": True, "seed": 3},
    "restitution_contact_350us": {"e": 0.45, "contact_s": 3.5e-4, "seed": 11},
    "friction_restitution": {"mu": 0.15, "e": 0.3, "seed": 16},
    "harmonic_k3": {"g1": 6.0, "a": 0.07, "k": 3.0, "psi": 2.0, "seed": 4},
    "harmonic_k2_35hz": {"f": 35.0, "g1": 5.0, "a": 0.1, "k": 2.0, "psi": 4.0, "seed": 14},
    "gamma_scale_25hz": {"f": 25.0, "g1": 6.0, "s": 0.92, "seed": 5},
    "gamma_scale_20hz": {"f": 20.0, "s": 1.08, "step_s": 3.0, "seed": 15},
    "feedback_impacts_only": {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "seed": 6},
    "seed_like_impacts_only": {
        "mu": 0.29, "e": 0.5, "mass_ratio": 0.04, "f_ratio": 0.6, "zeta": 0.04, "seed": 7,
    },
    "delay_2ms": {"delay_s": 0.002, "seed": 17},
    # the seed's protocol: Gamma 0 to 8 in steps of 0.05
    "null_g0-8_20hz": {"f": 20.0, "g1": 8.0, "step_s": 4.0, "seed": 32},
    "friction_restitution_g0-8_25hz": {
        "f": 25.0, "g1": 8.0, "step_s": 3.2, "mu": 0.25, "e": 0.5, "contact_s": 1e-4, "seed": 31,
    },
    "friction_harmonic_g0-8": {"g1": 8.0, "mu": 0.2, "a": 0.05, "k": 3.0, "psi": 1.0, "seed": 33},
    # non-integer and higher multiples (CONTRACTS.md section 5 allows any k)
    "harmonic_k1.5": {"g1": 6.0, "a": 0.07, "k": 1.5, "psi": 2.0, "seed": 41},
    "harmonic_k2.5": {"g1": 6.0, "a": 0.06, "k": 2.5, "psi": 3.0, "seed": 43},
    "harmonic_k5": {"g1": 6.0, "a": 0.04, "k": 5.0, "psi": 1.0, "seed": 42},
    # a subharmonic on the seed's protocol: 78-cycle steps that the fits cut to 47 (an odd
    # 31 dropped from each: the model's subharmonic is then in antiphase with the
    # recording's clock on every other step, but continuous with the body, which is what
    # the flights see; docs/diagnosis-log.md, session 17)
    "harmonic_k0.5_g0-8": {"g1": 8.0, "step_s": 2.6, "a": 0.06, "k": 0.5, "psi": 2.5, "seed": 44},
    # protocols other than ours: swept down, coarse or few steps, steps starting above the
    # takeoff, long or short steps, chaos only, no drive channel, 8 kHz sampling
    "friction_descending": {"mu": 0.2, "descending": True, "seed": 51},
    "feedback_descending": {
        "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "descending": True, "seed": 55,
    },
    "restitution_no_drive": {"e": 0.45, "no_drive": True, "seed": 52},
    "null_coarse_g1-4": {"g0": 1.0, "g1": 4.0, "dg": 0.2, "step_s": 3.0, "seed": 53},
    "friction_coarse_g0-6": {"g1": 6.0, "dg": 0.25, "mu": 0.25, "seed": 54},
    "friction_six_steps": {"g0": 1.5, "g1": 4.0, "dg": 0.5, "step_s": 4.0, "mu": 0.2, "seed": 58},
    "friction_long_steps": {"g0": 1.0, "g1": 4.0, "dg": 0.5, "step_s": 40.0, "mu": 0.2, "seed": 63},
    # swept up and back down in one run (session 36): every Gamma but the top one twice,
    # the second time on the branch the way down leaves (restitution: past the doublings)
    "friction_up_down": {"g0": 1.0, "g1": 4.0, "dg": 0.1, "mu": 0.2, "up_down": True, "seed": 64},
    "restitution_up_down": {
        "g0": 2.0, "g1": 6.0, "dg": 0.1, "e": 0.4, "up_down": True, "seed": 65,
    },
    # stepped by hand: every step's length drawn within 40 % of 2 s (36-84 cycles)
    "friction_restitution_uneven_steps": {
        "g1": 5.0, "mu": 0.2, "e": 0.4, "step_jitter": 0.4, "seed": 66,
    },
    # the seed's three effects on 3-s steps (90 cycles, cut to 75 in the fits: 7575
    # cycles, the most a fit runs): what a lab's sweep of the seed's rig costs
    "seed_like_long_steps": {
        "g1": 5.0, "step_s": 3.0, "mu": 0.29, "e": 0.5, "mass_ratio": 0.04, "f_ratio": 0.6,
        "zeta": 0.04, "seed": 67,
    },
    "gamma_scale_40hz_short_steps": {"s": 1.1, "step_s": 1.0, "f": 40.0, "seed": 57},
    "restitution_chaotic_g5-8": {"g0": 5.0, "g1": 8.0, "dg": 0.1, "e": 0.4, "seed": 61},
    "friction_8khz": {"fs": 8000.0, "mu": 0.25, "seed": 62},
    # pairs of library effects other than the seed's, and more of the protocol's range
    # (session 23): a Gamma miscalibration beside friction or restitution, a harmonic
    # beside restitution, the armature beside friction alone, a high and a low e, 60 Hz
    "friction_gamma_scale": {"g1": 5.0, "mu": 0.2, "s": 0.93, "seed": 101},
    "restitution_harmonic": {"g1": 5.0, "e": 0.4, "a": 0.06, "k": 2.0, "psi": 1.5, "seed": 102},
    "friction_feedback": {"mu": 0.2, "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "seed": 103},
    "restitution_gamma_scale": {"e": 0.4, "s": 1.07, "seed": 104},
    "friction_restitution_high_e": {"mu": 0.35, "e": 0.6, "g1": 5.0, "seed": 105},
    "null_60hz": {"f": 60.0, "seed": 107},
    "restitution_low_e": {"e": 0.15, "seed": 108},
    # and more: a harmonic or the armature beside a Gamma miscalibration, the armature
    # beside restitution, three effects with a harmonic or a miscalibration, 40 and 25 Hz
    "harmonic_gamma_scale": {"g1": 5.0, "a": 0.06, "k": 3.0, "psi": 1.0, "s": 1.06, "seed": 111},
    "restitution_feedback": {
        "e": 0.4, "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "seed": 112,
    },
    "feedback_gamma_scale": {
        "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "s": 0.94, "seed": 113,
    },
    "friction_restitution_harmonic": {
        "g1": 5.0, "mu": 0.2, "e": 0.4, "a": 0.05, "k": 2.0, "psi": 2.0, "seed": 114,
    },
    "friction_restitution_gamma_scale": {"mu": 0.2, "e": 0.4, "s": 0.95, "seed": 115},
    "friction_harmonic": {"g1": 5.0, "mu": 0.25, "a": 0.06, "k": 2.0, "psi": 0.5, "seed": 116},
    "friction_40hz": {"f": 40.0, "mu": 0.15, "g1": 5.0, "seed": 117},
    "restitution_25hz_g0-6": {"f": 25.0, "e": 0.5, "g1": 6.0, "dg": 0.1, "seed": 118},
    # flaws of a lab's records (session 37): 3 % of the short contacts missed by the
    # circuit (their flights merge), each step's Gamma read off with a 1 % error; the
    # diagnosis should see through them to the effects
    "friction_lost_contacts": {"mu": 0.2, "lost_contacts": 0.03, "seed": 121},
    "restitution_gamma_read": {"e": 0.45, "gamma_read_sd": 0.01, "seed": 122},
    "null_lost_contacts_gamma_read": {"lost_contacts": 0.03, "gamma_read_sd": 0.01, "seed": 123},
    "friction_restitution_lost_contacts_gamma_read": {
        "mu": 0.2, "e": 0.4, "g1": 5.0, "lost_contacts": 0.03, "gamma_read_sd": 0.01, "seed": 124,
    },
    # a body that sticks when its impacts get slow (session 76), as simulators end the
    # chatter: once its next flight would be shorter than 1.5 contact times (the
    # data's flights end at 150 us where 48 kHz resolves 42 us; read as the chatter's
    # floor), or once its rebound is slower than 10 mm/s (not read: flagged)
    "friction_restitution_sticky": {
        "f": 22.0, "fs": 48000.0, "g0": 1.2, "g1": 6.0, "dg": 0.3, "step_s": 90 / 22.0,
        "mu": 0.25, "e": 0.35, "contact_s": 3e-4, "stick_flight_s": 4.5e-4, "seed": 31,
    },
    "restitution_sticky_speed": {
        "f": 28.0, "g0": 0.8, "g1": 3.2, "dg": 0.1, "step_s": 1.2, "t0": 0.23, "e": 0.45,
        "stick_v": 1e-2, "seed": 21,
    },
    # outside the library: each should come out unexplained
    "vdep_restitution": {
        "e": 0.4, "e_slope": 0.4, "g0": 1.0, "g1": 3.5, "dg": 0.1, "step_s": 1.33, "seed": 71,
    },
    "vdep_restitution_b": {
        "e": 0.2, "e_slope": 0.5, "g0": 0.8, "g1": 3.0, "dg": 0.1, "step_s": 1.33, "seed": 72,
    },
    "vibration": {"vib_rms": 2e-5, "seed": 73},
    "vibration_27hz": {"f": 27.0, "vib_rms": 3e-5, "g0": 0.5, "g1": 4.5, "dg": 0.1, "seed": 74},
    # a vibration a tenth or less of those (0.1 g rms): within the gap's noise floor, seen
    # only as flights that do not repeat where the model's do (session 73)
    "vibration_weak": {"vib_rms": 2e-6, "seed": 75},
    "vibration_weak_35hz": {
        "f": 35.0, "vib_rms": 1.5e-6, "g0": 0.5, "g1": 4.5, "dg": 0.1, "seed": 76,
    },
    # ... beside a library effect, which must still be found
    "restitution_vibration": {"e": 0.4, "vib_rms": 3e-6, "seed": 77},
    "friction_vibration": {"mu": 0.2, "vib_rms": 2e-6, "seed": 78},
    "friction_delay": {"mu": 0.2, "delay_s": 0.001, "seed": 106},
    # protocols a lab may run that none above does: the steps in a random order (no state
    # carried from a neighbouring Gamma), a Gamma range never stepped, a fast and a slow
    # drive (session 55)
    "friction_shuffled": {"mu": 0.2, "shuffled": True, "seed": 201},
    "restitution_gamma_gap": {"e": 0.4, "skip_lo": 1.5, "skip_hi": 2.55, "seed": 202},
    "harmonic_60hz": {"f": 60.0, "g1": 5.0, "a": 0.06, "k": 2.0, "psi": 1.5, "seed": 203},
    "friction_12hz": {"f": 12.0, "mu": 0.25, "step_s": 4.0, "seed": 204},
    # two effects that offset each other at the takeoff threshold, each worse alone than
    # none: friction raises it to 1.15, the miscalibration brings it back to a stated
    # 1.045 (a black-box probe's case, session 80: select._pair_swap)
    "friction_gamma_scale_offset": {"g1": 5.0, "mu": 0.15, "s": 1.1, "seed": 205},
    # outside the library: a body held on the plate through each 100-us impact at 80 Hz
    # (0.05 rad of phase), then leaving at its rebound speed (a dwell, session 81)
    "held_contact_80hz": {"f": 80.0, "e": 0.5, "contact_s": 1e-4, "hold": True, "seed": 301},
    # strengths beyond those above (session 82): a bouncy and a weak or strong friction,
    # harmonics of a fifth of the drive, a heavy or stiff armature, a 20 % miscalibration
    "restitution_high_e": {"e": 0.8, "seed": 401},
    "friction_weak": {"mu": 0.08, "seed": 402},
    "friction_strong": {"mu": 0.5, "g1": 6.0, "seed": 403},
    "harmonic_strong": {"g1": 5.0, "a": 0.2, "k": 2.0, "psi": 1.0, "seed": 404},
    "friction_restitution_bouncy": {"mu": 0.1, "e": 0.75, "seed": 405},
    "feedback_stiff": {"mass_ratio": 0.1, "f_ratio": 1.5, "zeta": 0.1, "seed": 406},
    "gamma_scale_large": {"s": 1.2, "seed": 407},
    "feedback_heavy": {"mass_ratio": 0.2, "f_ratio": 0.8, "zeta": 0.3, "seed": 408},
    "harmonic_slow_strong": {"g1": 5.0, "a": 0.2, "k": 0.5, "psi": 2.0, "seed": 409},
    "friction_restitution_strong": {"mu": 0.4, "e": 0.7, "g1": 6.0, "seed": 410},
    "restitution_gamma_scale_low": {"e": 0.5, "s": 0.8, "g1": 6.0, "seed": 411},
    "friction_harmonic_k3": {"g1": 5.0, "mu": 0.2, "a": 0.15, "k": 3.0, "psi": 3.0, "seed": 412},
    "null_15hz": {"f": 15.0, "step_s": 4.0, "seed": 413},
    "friction_50hz": {"f": 50.0, "mu": 0.3, "seed": 414},
    "harmonic_k4": {"g1": 6.0, "a": 0.05, "k": 4.0, "psi": 2.5, "seed": 415},
    # a half-integer harmonic beside friction or restitution: both missed in session 82
    # (round 1 chose the harmonic's k alone, and later rounds keep it)
    "friction_harmonic_k1.5": {"g1": 5.0, "mu": 0.2, "a": 0.1, "k": 1.5, "psi": 4.0, "seed": 416},
    "restitution_harmonic_k0.5": {
        "g1": 5.0, "e": 0.4, "a": 0.15, "k": 0.5, "psi": 1.0, "seed": 417,
    },
    "friction_harmonic_k0.5": {"g1": 5.0, "mu": 0.2, "a": 0.1, "k": 0.5, "psi": 2.0, "seed": 424},
    "restitution_harmonic_k2.5": {
        "g1": 5.0, "e": 0.4, "a": 0.06, "k": 2.5, "psi": 3.0, "seed": 425,
    },
    # ... where a whole k beside restitution and a half-integer one beside a
    # miscalibration are found
    "restitution_harmonic_k3": {"g1": 5.0, "e": 0.4, "a": 0.06, "k": 3.0, "psi": 2.0, "seed": 422},
    "harmonic_gamma_scale_k1.5": {
        "g1": 5.0, "a": 0.1, "k": 1.5, "psi": 1.0, "s": 1.05, "seed": 423,
    },
    "feedback_slow": {"mass_ratio": 0.05, "f_ratio": 0.3, "zeta": 0.1, "seed": 418},
    "friction_gamma_scale_low": {"g1": 6.0, "mu": 0.4, "s": 0.9, "seed": 419},
    "restitution_60hz": {"f": 60.0, "e": 0.5, "seed": 420},
    "null_g0-3_fine": {"g1": 3.0, "dg": 0.02, "step_s": 1.5, "seed": 421},
}  # fmt: skip


#: Cases of the third generator, ``compliant_rig.py``: no impact map, a Kelvin-Voigt
#: contact whose damping makes the restitution, an armature loaded by the contact force
#: all the time (``--generator compliant``, ``benchmarks/results/compliant.json``).
COMPLIANT_CASES = {
    "null": {},
    "friction": {"mu": 0.25, "seed": 2},
    "restitution": {"e": 0.5, "seed": 3},
    "friction_restitution": {"mu": 0.25, "e": 0.5, "seed": 1},
    # a soft pad: 1 ms in contact, 0.19 rad of drive phase at 30 Hz, while the plate moves
    "restitution_soft_1ms": {"e": 0.45, "contact_s": 1e-3, "seed": 4},
    "gamma_scale": {"s": 0.93, "g1": 5.0, "seed": 5},
    "harmonic_k3": {"g1": 6.0, "a": 0.06, "k": 3.0, "psi": 1.0, "seed": 6},
    "feedback_loaded": {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.05, "seed": 7},
    "seed_like": {
        "mu": 0.29, "e": 0.5, "mass_ratio": 0.04, "f_ratio": 0.6, "zeta": 0.04, "seed": 8,
    },
    "restitution_25hz_csv_high": {
        "f": 25.0, "e": 0.4, "format": "csv", "contact_high": True, "seed": 9,
    },
    # outside the library: a Hertzian contact, e 0.96 at 1 cm/s, 0.40 at 0.3 m/s, 0.14 at 1 m/s
    "hertzian_contact": {"hertz": True, "e": 0.4, "seed": 10},
}  # fmt: skip

#: generator name -> (its cases, its make_case, the record's file stem)
GENERATORS = {
    "independent": (CASES, make_case, "independent"),
    "compliant": (COMPLIANT_CASES, compliant_rig.make_case, "compliant"),
}

#: The case diagnosed once, untimed, before the others: the quickest (8 s warm).
WARM_UP = "friction_six_steps"


def score(truth: dict, diag: dict) -> dict:
    """Selected against true effects, relative parameter errors, verdict.

    The generator rebounds the body from the plate's velocity before the impact and then
    kicks the armature (its ``e`` is the rigid-plate restitution), the model's impact is
    a two-body one: beside the armature the generator's ``e`` is compared with the
    diagnosis's ``e_rigid_plate`` (docs/diagnosis.md section 1), and the model's own
    ``e`` is kept as ``e_two_body`` in ``other_errors``. A truth whose
    ``restitution_frame`` is ``two_body`` (``compliant_rig.py``: the contact pushes the
    armature as it pushes the body) is compared with the model's ``e``."""
    true = truth["effects"]
    last = diag["steps"][-1] if diag["steps"] else {}
    fitted = last.get("params", {})
    compared, other = dict(fitted), {}
    rigid = truth.get("restitution_frame", "rigid_plate") == "rigid_plate"
    if rigid and "e_rigid_plate" in last and "e" in true.get("restitution", {}):
        other["e_two_body"] = abs(fitted["e"] / true["restitution"]["e"] - 1.0)
        compared["e"] = last["e_rigid_plate"]
    errors = {}
    for params in true.values() if not truth["outside"] else ():  # scored: library cases
        for name, value in params.items():
            if name not in compared:
                continue
            if name == "psi":
                d = (compared[name] - value + math.pi) % (2 * math.pi) - math.pi
                errors[name] = abs(d) / (2 * math.pi)
            else:
                errors[name] = abs(compared[name] - value) / abs(value)
    out_of_library = bool(truth["outside"])
    warned = warned_params(last.get("warnings", []))
    return {
        "true": sorted(true),
        "outside": truth["outside"],
        "selected": diag["selected"],
        "set_right": sorted(diag["selected"]) == sorted(true),
        "top_right": bool(diag["selected"]) and diag["selected"][0] in true
        if true
        else not diag["selected"],
        "unexplained": diag["unexplained"],
        "verdict_right": diag["unexplained"] == out_of_library,
        "param_rel_error": errors,
        # whether the last step warns about each scored parameter (loose, on a bound,
        # trading off): can a value given without a warning be taken as it is?
        "param_warned": {name: name in warned for name in errors},
        "other_errors": other,
        "final_floors": diag["final_gap"] / diag["noise_floor"],
        "min_contact_s": diag["design"].get("min_contact_s"),
        "fitted": fitted,
        # the diagnosis's work: flights its kernels simulated (time per flight: the machine)
        "flights": diag["design"]["work"]["flights"],
        # the refinement's generations (None: not refined; section 1, "Refinement")
        "refine_generations": (diag["design"].get("refine") or {}).get("maxiter"),
        # additions refused because the effects before them, refitted, did as well
        "not_earned": [n["effect"] for n in diag.get("not_earned", [])],
        # additions taken for the takeoff phases where the flight times gained nothing
        "phase_taken": [n["effect"] for n in diag.get("phase_taken", [])],
        # a run left unexplained is diagnosed again (docs/diagnosis.md section 1, "Retries"):
        # each seed's conclusion, so that a run's time shows what its retry cost
        "retry": retried(diag),
        # the harmonic read off the takeoff phases, where it stood out (None: not seen)
        "harmonic_read": diag["design"].get("harmonic_read"),
    }


def parameters_by_warning(cases) -> dict:
    """The scored parameters counted by their warnings (:func:`warning_counts`: those
    outside 15 % and of them warned about, those without a warning and of them within
    15 %). Cases scored before ``param_warned`` was kept are left out."""
    return warning_counts(
        [
            (v <= 0.15, c["param_warned"][name])
            for c in cases
            if "param_warned" in c
            for name, v in c["param_rel_error"].items()
        ]
    )


def stage_seconds(timings: dict) -> dict:
    """Where a case's time went (the diagnosis's ``timings``): ``diagnoses_s``, each
    seed's diagnosis (two when retried), and ``stages_s``, the reported diagnosis's
    seconds per stage of the selection (``round 1``, ``refinement``, ...)."""
    return {
        "diagnoses_s": [round(d["total_s"], 1) for d in timings["diagnoses"]],
        "stages_s": {k: round(v["seconds"], 1) for k, v in timings["stages"].items()},
    }


def summarize(cases_by_name: dict) -> dict:
    """The record's ``summary`` of its scored cases (``name -> score``)."""
    cases = cases_by_name.values()
    library = [c for c in cases if not c.get("outside")]
    return {
        "cases": len(cases_by_name),
        "library_cases": len(library),
        "set_right": sum(c["set_right"] for c in library),
        "verdict_right": sum(c["verdict_right"] for c in cases),
        "outside_flagged": sum(c["unexplained"] for c in cases if c.get("outside")),
        "outside_cases": len(cases) - len(library),
        "params_within_15pct": sum(v <= 0.15 for c in cases for v in c["param_rel_error"].values()),
        "params": sum(len(c["param_rel_error"]) for c in cases),
        "param_warnings": parameters_by_warning(cases),
        "max_diagnose_s": max(c["diagnose_s"] for c in cases),
        "over_goal_s": sorted(n for n, c in cases_by_name.items() if c["diagnose_s"] > GOAL_S),
    }


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--only", nargs="*", default=None)
    p.add_argument("--workers", type=int, default=2)
    p.add_argument("--seed", type=int, default=0, help="the diagnosis's seed (default 0)")
    p.add_argument("--diagnoses", default=None, help="folder to keep each diagnosis JSON in")
    p.add_argument(
        "--generator", choices=sorted(GENERATORS), default="independent",
        help="independent_rig.py (default) or compliant_rig.py, each with its own cases",
    )  # fmt: skip
    args = p.parse_args()
    keep = Path(args.diagnoses) if args.diagnoses else None
    if keep:
        keep.mkdir(parents=True, exist_ok=True)
    cases_of, make, stem = GENERATORS[args.generator]
    names = args.only or list(cases_of)
    out = OUT.with_name(f"{stem}.json" if args.seed == 0 else f"{stem}_seed{args.seed}.json")
    record = json.loads(out.read_text()) if out.exists() and args.only else {"cases": {}}
    with tempfile.TemporaryDirectory() as tmp:
        # untimed: numba compiles the kernels at their first use after an install or a
        # source change (40 s), which would land on the first case's time (session 56)
        warm = Path(tmp) / "warm_up"
        make_case(warm, **CASES[WARM_UP])
        diagnose_run(warm, workers=args.workers, seed=args.seed, progress=False)
        for name in names:
            run_dir = Path(tmp) / name
            t0 = time.perf_counter()
            make(run_dir, **cases_of[name])
            t1 = time.perf_counter()
            diag = diagnose_run(
                run_dir, workers=args.workers, seed=args.seed, progress=False, include_timings=True
            )
            t2 = time.perf_counter()
            if keep:
                (keep / f"{name}.json").write_text(json.dumps(diag, indent=1) + "\n")
            truth = json.loads(run_dir.with_name(name + ".truth.json").read_text())
            s = score(truth, diag) | {"generate_s": t1 - t0, "diagnose_s": t2 - t1}
            s |= stage_seconds(diag["timings"])
            s["machine_feedback_mflights_s"] = machine_speed()
            record["cases"][name] = s
            errs = ", ".join(f"{k} {100 * v:.1f} %" for k, v in s["param_rel_error"].items())
            print(
                f"{name:32s} true {s['true']} selected {s['selected']} "
                f"{'unexplained' if s['unexplained'] else 'explained'} "
                f"{s['final_floors']:.2f} floors; {errs}; {t2 - t1:.0f} s",
                flush=True,
            )
    record["summary"] = summarize(record["cases"])
    record["machine"] = {"cpus": platform.machine(), "python": platform.python_version()}
    record["diagnosis_seed"] = args.seed
    record["generator"] = args.generator
    out.write_text(json.dumps(record, indent=1, sort_keys=True) + "\n")
    print(json.dumps(record["summary"]))


if __name__ == "__main__":
    main()
