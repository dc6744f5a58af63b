"""Unit checks of the pieces of the fit: held-out design, parameter coding, intervals,
warnings, calibration input. Each states its reference."""

from __future__ import annotations

import json
from dataclasses import replace

import numpy as np
import pandas as pd
import pytest

from bouncelab.errors import BouncelabError
from bouncelab.gap.diagnose import read_calibration
from bouncelab.gap.fit import (
    BOX_ABSOLUTE,
    BOX_MIN_SHARE,
    JOINT_K_CHOICES,
    K_CHOICES,
    FitResult,
    bootstrap_params,
    box_around,
    chatter_floor_T,
    decode,
    encode,
    fit_warnings,
    free_params,
    heldout_mask,
    intervals,
    joint_choices,
    min_contact_T,
    noise_intervals,
    poorly_identified,
    resolution_T,
    warned_params,
)
from bouncelab.physics import EFFECTS, Model


def test_heldout_mask_interleaves():
    """Every third step held out, the ends fitted: 10 steps -> indices 1, 4, 7."""
    m = heldout_mask(10, 3)
    assert np.flatnonzero(m).tolist() == [1, 4, 7]
    assert not m[0] and not m[-1]
    with pytest.raises(ValueError):
        heldout_mask(10, 1)


def test_free_params_bounds_and_fixed():
    """Bounds are those of physics.EFFECTS; a fixed parameter is not fitted; k is discrete."""
    free = free_params(("friction", "harmonic"), fixed={"mu": 0.29})
    names = [p.name for p in free]
    assert names == ["k", "a", "psi"]
    a = free[1]
    assert (a.lower, a.upper) == EFFECTS["harmonic"]["a"][1:]
    assert free[0].choices == K_CHOICES


def test_a_joint_fit_moves_a_fitted_harmonic_among_the_common_multiples_and_its_own():
    """From scratch k is searched over every choice; from a fitted k over
    JOINT_K_CHOICES and that k (the same tuple when it is one of them)."""
    free = free_params(("friction", "harmonic"))
    assert joint_choices(free, {})[1].choices == K_CHOICES
    assert joint_choices(free, {"k": 3.0, "mu": 0.1})[1].choices == JOINT_K_CHOICES
    k = joint_choices(free, {"k": 2.5})[1]
    assert k.choices == (0.5, 2.0, 2.5, 3.0, 4.0) and (k.lower, k.upper) == (0.0, 4.0)
    assert joint_choices(free, {"k": 2.5})[0] == free[0]  # mu untouched
    assert set(JOINT_K_CHOICES) < set(K_CHOICES)


def test_the_box_is_a_share_of_each_value_within_the_bounds():
    """Reference: the rule of :func:`box_around`. mu 0.28 and share 0.35 -> 0.182-0.378;
    psi and s take their absolute half-widths; e near 0 gets BOX_MIN_SHARE of its range
    and stops at its bound; the harmonic's k keeps its choices."""
    free = free_params(["friction", "restitution", "harmonic", "gamma_scale"])
    params = {"mu": 0.28, "e": 0.001, "k": 2.0, "a": 0.05, "psi": 0.2, "s": 1.1}
    box = {p.name: p for p in box_around(free, params, 0.35)}
    assert box["mu"].lower == pytest.approx(0.182) and box["mu"].upper == pytest.approx(0.378)
    assert box["a"].lower == pytest.approx(0.0325) and box["a"].upper == pytest.approx(0.0675)
    assert box["psi"].lower == 0.0 and box["psi"].upper == pytest.approx(0.2 + BOX_ABSOLUTE["psi"])
    assert box["s"].lower == pytest.approx(1.1 - BOX_ABSOLUTE["s"])
    assert box["e"].lower == 0.0 and box["e"].upper == pytest.approx(0.001 + BOX_MIN_SHARE * 0.95)
    assert box["k"] == next(p for p in free if p.name == "k")


def test_encode_decode_round_trip():
    """Decoding an encoded dict gives it back (k snapped to the nearest choice)."""
    free = free_params(("harmonic", "gamma_scale"))
    params = {"k": 2.1, "a": 0.2, "psi": 1.0, "s": 0.95}
    back = decode(free, encode(free, params))
    assert back == {"k": 2.0, "a": 0.2, "psi": 1.0, "s": 0.95}


def _fake_fit(xs, gaps, names=("mu",)):
    """A FitResult on a known cloud of evaluations (no simulation)."""
    free = free_params(("friction", "gamma_scale"))
    free = [p for p in free if p.name in names]
    xs = np.asarray(xs, dtype=float).reshape(len(xs), len(free))
    gaps = np.asarray(gaps, dtype=float)
    i = int(np.argmin(gaps[:, ::1].mean(axis=1)))
    params = dict(zip(names, xs[i], strict=True))
    model = Model.parse(
        "+".join(sorted({"mu": "friction", "s": "gamma_scale"}[n] for n in names)), params
    )
    return FitResult(model, free, float(gaps[i].mean()), gaps[i], xs, gaps, len(xs), 0.0)


class _P:
    """The attributes of a Problem that the bootstrap uses (equal step weights)."""

    def __init__(self, n):
        self.fit = np.ones(n, dtype=bool)
        self.heldout = ~self.fit
        self.weights = np.ones(n)

    def clipped(self, gaps):
        return np.asarray(gaps)  # no floors here: nothing to clip


def test_bootstrap_picks_the_resampled_best():
    """Cloud of 3 evaluations over 4 steps; evaluation 1 is best on every step, so every
    resample picks it and the interval collapses to its value (0.2)."""
    gaps = [[1, 1, 1, 1], [0.1, 0.2, 0.1, 0.3], [0.5, 0.5, 0.5, 0.5]]
    fit = _fake_fit([0.1, 0.2, 0.3], gaps)
    boot = bootstrap_params(fit, _P(4), n_boot=50, seed=1)
    assert np.all(boot[:, 0] == 0.2)
    assert intervals(fit, boot)["mu"] == [0.2, 0.2]


def test_bootstrap_spreads_when_steps_disagree():
    """Two evaluations, each best on half the steps: resamples pick both, so the 95 %
    interval spans both values."""
    gaps = [[0.1, 0.1, 0.9, 0.9], [0.9, 0.9, 0.1, 0.1]]
    fit = _fake_fit([0.1, 0.3], gaps)
    boot = bootstrap_params(fit, _P(4), n_boot=400, seed=2)
    assert intervals(fit, boot)["mu"] == [0.1, 0.3]


def test_noise_interval_spans_the_evaluations_within_the_tolerance():
    """Cloud of mean objectives 0.10 (mu 0.2), 0.14 (mu 0.3), 0.25 (mu 0.1), 0.5 (mu 0.4):
    a tolerance of 0.05 keeps mu 0.2 and 0.3, of 0.2 also 0.1, of 0 only the best."""
    gaps = [[0.25, 0.25], [0.1, 0.1], [0.14, 0.14], [0.5, 0.5]]
    fit = _fake_fit([0.1, 0.2, 0.3, 0.4], gaps)
    assert noise_intervals(fit, _P(2), 0.05)["mu"] == [0.2, 0.3]
    assert noise_intervals(fit, _P(2), 0.2)["mu"] == [0.1, 0.3]
    assert noise_intervals(fit, _P(2), 0.0)["mu"] == [0.2, 0.2]


def test_poorly_identified_warns_on_wide_intervals_only():
    """mu = 0.2 with [0.15, 0.3]: width 0.15 = 75 % of the value, warned; with
    [0.19, 0.21] (10 %) not; a discrete parameter never."""
    fit = _fake_fit([0.1, 0.2], [[0.5, 0.5], [0.1, 0.1]])
    assert len(poorly_identified(fit, {"mu": [0.15, 0.3]})) == 1
    assert "mu" in poorly_identified(fit, {"mu": [0.15, 0.3]})[0]
    assert poorly_identified(fit, {"mu": [0.19, 0.21]}) == []


def test_warnings_on_bound_and_trade_off():
    """mu at its lower bound 0 is reported; two parameters moving together across
    bootstrap refits (correlation 1) are reported as trading off, once the refits take
    three distinct points (two always line up)."""
    fit = _fake_fit([[0.0, 1.0], [0.3, 1.1]], [[0.1, 0.1], [0.5, 0.5]], names=("mu", "s"))
    boot = np.array([[0.0, 1.0], [0.1, 1.05], [0.2, 1.1], [0.3, 1.15]])
    w = fit_warnings(fit, boot)
    assert any("mu" in x and "lower bound" in x for x in w)
    assert any("trade off" in x for x in w)
    still = np.tile([0.1, 1.0], (4, 1))  # no spread: nothing can trade off
    assert fit_warnings(fit, still) == [x for x in w if "bound" in x]
    # refits that took two evaluated points line up whatever the objective: not read
    two = np.array([[0.0, 1.0], [0.3, 1.15], [0.0, 1.0], [0.3, 1.15]])
    assert fit_warnings(fit, two) == [x for x in w if "bound" in x]
    three = np.vstack([two, [0.1, 1.05]])
    assert any("trade off" in x for x in fit_warnings(fit, three))


def test_warned_params_reads_the_fits_own_warning_lines():
    """The parameters named by fit_warnings and poorly_identified, read back from their
    lines: mu on its bound and loose, mu and s trading off; a line of another kind (the
    verdict's) names none."""
    fit = _fake_fit([[0.0, 1.0], [0.3, 1.1]], [[0.1, 0.1], [0.5, 0.5]], names=("mu", "s"))
    boot = np.array([[0.0, 1.0], [0.1, 1.05], [0.2, 1.1], [0.3, 1.15]])
    bound = [x for x in fit_warnings(fit, boot) if "bound" in x]
    assert warned_params(bound) == {"mu"}
    assert warned_params(fit_warnings(fit, boot)) == {"mu", "s"}
    assert warned_params(poorly_identified(fit, {"mu": [0.15, 0.3]})) == {"mu"}
    assert warned_params(["the verdict is borderline: 2.87 +- 0.65 noise floors"]) == set()
    assert warned_params([]) == set()


def test_read_calibration(tmp_path):
    """A section-4 JSON is read; a missing key, a non-number or bad JSON is one error."""
    good = tmp_path / "cal.json"
    good.write_text(json.dumps({"mu": 0.29, "mu_ci": [0.27, 0.31], "restitution": 0.515,
                                "restitution_ci": [0.5, 0.53], "n_bounces": 12}))  # fmt: skip
    assert read_calibration(good)["mu"] == 0.29
    for text, what in [
        ('{"mu": 0.2}', "restitution"),
        ('{"mu": "x", "restitution": 0.5}', "mu"),
        ("not json", "JSON"),
        ('{"mu": 1.5, "restitution": 0.5}', "outside"),
    ]:
        bad = tmp_path / "bad.json"
        bad.write_text(text)
        with pytest.raises(BouncelabError, match=what) as exc:
            read_calibration(bad)
        assert "bad.json" in str(exc.value)


def test_member_offsets_alternate_around_the_model():
    """Member 0 is the model itself; the others step out by MEMBER_SPREAD on both sides."""
    from bouncelab.gap.fit import MEMBER_SPREAD, member_offsets

    np.testing.assert_array_equal(
        member_offsets(5) / MEMBER_SPREAD, np.array([0.0, 1.0, -1.0, 2.0, -2.0])
    )


def test_clipped_caps_each_step_at_gap_cap_floors():
    """A step counts at most GAP_CAP of its floors: 9 rad against a 0.03 rad floor counts
    0.3 rad; gaps under the cap are untouched."""
    from bouncelab.gap.fit import GAP_CAP, Problem

    p = Problem.__new__(Problem)
    p.floor = np.array([0.03, 1.0])
    np.testing.assert_allclose(p.clipped(np.array([9.0, 2.0])), [GAP_CAP * 0.03, 2.0])


def test_pick_addition_prefers_fewer_parameters_within_the_tie():
    from bouncelab.gap.select import pick_addition

    rows = [("feedback", 0.130, 3), ("gamma_scale", 0.143, 1), ("harmonic", 1.17, 2)]
    assert rows[pick_addition(rows, 0.25)][0] == "gamma_scale"
    # outside the tie the least gap wins whatever its parameters
    rows = [("feedback", 0.66, 3), ("gamma_scale", 4.14, 1)]
    assert rows[pick_addition(rows, 0.25)][0] == "feedback"
    # no tie band: the least gap
    rows = [("feedback", 0.130, 3), ("gamma_scale", 0.143, 1)]
    assert rows[pick_addition(rows, 0.0)][0] == "feedback"


def test_is_inert_reads_each_effects_strength():
    from bouncelab.gap.select import INERT, is_inert

    assert set(INERT) == set(EFFECTS)
    assert is_inert("friction", {"mu": 0.0}) and not is_inert("friction", {"mu": 0.1})
    assert is_inert("harmonic", {"k": 3.0, "a": 0.001, "psi": 1.0})
    assert not is_inert("harmonic", {"k": 3.0, "a": 0.05, "psi": 1.0})
    assert is_inert("gamma_scale", {"s": 1.001}) and not is_inert("gamma_scale", {"s": 0.96})
    assert not is_inert("feedback", {"f_ratio": 0.6})  # strength not fitted: not inert


def scripted_fit(name: str, params: dict, gap: float) -> FitResult:
    """A fit of ``name`` at ``params`` whose objective (and one-step gap) is ``gap``: the
    stand-in for ``fit_many``'s results in the scripted selections below."""
    return FitResult(
        model=Model.parse(name, params), free=free_params(Model.parse(name).effects),
        objective=gap, gaps=np.array([gap]), cloud_x=np.zeros((1, 0)),
        cloud_gaps=np.array([[gap]]), n_evals=1, seconds=0.0,
    )  # fmt: skip


def script_selection(monkeypatch, fake_fit_many, refined=None, alternative=False, rival_box=False):
    """Make :func:`bouncelab.gap.select.forward_select` run on scripted fits: ``fit_many``
    is ``fake_fit_many``, the held-out gap is each fit's objective, no simulated cycles
    are counted, and the refinement's settings are ``refined`` (None: no refinement).
    One optimiser seed per job (the last round's armature seeds have a test of their own);
    no :func:`bouncelab.gap.select.armature_alternative` unless ``alternative``, no box
    of an armature's rival (:func:`bouncelab.gap.select._rival_boxed`) unless
    ``rival_box``."""
    from bouncelab.gap import select

    if not alternative:
        monkeypatch.setattr(select, "armature_alternative", lambda *a, **k: None)

    monkeypatch.setattr(select, "ARMATURE_SEEDS", 1)
    monkeypatch.setattr(select, "fit_many", fake_fit_many)
    monkeypatch.setattr(select, "heldout_gap", lambda fit, problem: fit.objective)
    monkeypatch.setattr(select, "refine_settings", lambda *a, **k: refined)
    monkeypatch.setattr(select, "spent_cycles", lambda *a, **k: 0.0)
    if not rival_box:
        monkeypatch.setattr(select, "_rival_boxed", lambda tried, *a, **k: (tried, None))
    # no box refinement unless a test scripts one
    monkeypatch.setattr(select, "box_refinement", lambda fit, *a, **k: (fit, {"kept": False}))
    # nor a harmonic's one-cycle twin (its fresh ensembles need a real problem)
    monkeypatch.setattr(select, "harmonic_twin", lambda fit, *a, **k: (fit, None))
    # and a harmonic's k is not chosen again beside the other effects
    monkeypatch.setattr(select, "_k_beside_taken", lambda k_alone, *a, **k: k_alone)
    monkeypatch.setattr(select, "harmonic_k_beside", lambda fit, *a, **k: (fit, None))


def table_fit_many(gaps: dict, params: dict, names: list | None = None):
    """A scripted ``fit_many`` that looks each job's model up in ``gaps`` (default 9
    floors: an addition that gains nothing) and ``params`` (default none), recording the
    model names in ``names`` when given."""

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        if names is not None:
            names.extend(name for _problem, name, *_rest in jobs)
        return [
            scripted_fit(name, params.get(name, {}), gaps.get(name, 9.0))
            for _problem, name, *_rest in jobs
        ]

    return fake_fit_many


def armature_table_fit_many(table: dict, calls: list):
    """A scripted ``fit_many`` that looks each job's model up in ``table`` (name -> (gap,
    params); default 9 floors and none), gives armature models the job's ``ride_load``
    (default 1) and records the model names in ``calls``."""

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, _seed, *_more in jobs:
            calls.append(name)
            gap, params = table.get(name, (9.0, {}))
            if "feedback" in name:
                params = {**params, "ride_load": fixed.get("ride_load", 1.0)}
            out.append(scripted_fit(name, params, gap))
        return out

    return fake_fit_many


def select_from_table(monkeypatch, table, candidates, ci, calls=None, refit=None) -> dict:
    """A scripted selection (floor 1) over ``candidates``, each model's fit looked up in
    ``table`` (:func:`armature_table_fit_many`; names fitted go to ``calls``), every
    step's refined intervals ``ci``; ``refit``: ``(name, objective)`` of the final
    model's local refit without a dropped effect (:func:`with_local_refit`)."""
    from bouncelab.gap import select

    fit_many = armature_table_fit_many(table, [] if calls is None else calls)
    if refit is not None:
        fit_many = with_local_refit(fit_many, *refit)
    script_selection(monkeypatch, fit_many)
    return select.forward_select(
        _OneStepProblem(), 1.0, candidates=candidates, interval=lambda fit, problem, i: ci
    )


#: Restitution (10 -> 5), then a harmonic of a 0.008 beside it (-> 1.0).
RESTITUTION_THEN_WEAK_HARMONIC = {
    "ideal": (10.0, {}),
    "restitution": (5.0, {"e": 0.3}),
    "restitution+harmonic": (1.0, {"e": 0.3, "a": 0.008, "k": 2.0, "psi": 0.7}),
}


def with_local_refit(fit_many, name: str, objective: float):
    """``fit_many`` with the local refit of ``name`` (a job searching nothing: the final
    model refitted without a dropped effect) given ``objective``."""

    def wrapped(jobs, *args, **kwargs):
        fits = fit_many(jobs, *args, **kwargs)
        for (_p, job_name, _b, _f, search, *_r), fit in zip(jobs, fits, strict=True):
            if job_name == name and search == ():
                fit.objective = objective
        return fits

    return wrapped


def test_an_inert_addition_is_not_an_effect_but_its_refit_is_kept(monkeypatch):
    """Reference: a scripted selection (gaps in noise floors, held-out gap = objective).
    Round 1 takes restitution (10 -> 5). In round 2 friction at mu 0 "shrinks" the gap to
    1 by refitting e; it is not accepted, restitution takes the refit (1.2, refined
    without friction), and the harmonic (4.5) is then judged against 1.2 and refused."""
    from bouncelab.gap import select

    script = {
        "ideal": scripted_fit("ideal", {}, 10.0),
        "friction": scripted_fit("friction", {"mu": 0.2}, 9.0),
        "restitution": scripted_fit("restitution", {"e": 0.3}, 5.0),
        "friction+restitution": scripted_fit("friction+restitution", {"mu": 0.0, "e": 0.5}, 1.0),
        "restitution+harmonic": scripted_fit("restitution+harmonic", {"e": 0.3, "k": 2.0}, 4.5),
    }
    calls, continued = [], {}

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, _fixed, search, _settings, _seed, *more in jobs:
            calls.append((name, search))
            continued[name] = bool(more and more[0])
            if search == ():  # the refit without the inert effect, from its values
                assert base == {"e": 0.5}
                out.append(scripted_fit(name, base, 1.2))
            else:
                out.append(script.get(name, scripted_fit(name, {}, 9.5)))
        return out

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "fresh_objectives", lambda *a, **k: np.full(4, 9.5))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "harmonic", "feedback"],
        settings=select.SelectSettings(explained_ratio=0.5),
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["restitution"]
    assert sel["final"].model.params == {"e": 0.5} and sel["final"].objective == 1.2
    assert ("restitution", ()) in calls and sel["stop"] == "no_improvement"
    # the refit's cloud holds round 1's evaluations too (its intervals are drawn from it)
    assert sel["final"].n_evals == 2 and len(sel["final"].cloud_gaps) == 2
    # the joint fits of round 2 search the low-Gamma steps first, round 1 and refits not
    assert continued["friction+restitution"] and continued["restitution+harmonic"]
    assert not continued["friction"] and not continued["restitution"]
    assert not continued["restitution+feedback"]  # the armature is not continued


def test_an_effect_the_refinement_takes_to_null_is_dropped(monkeypatch):
    """Reference: a scripted selection. Restitution (10 -> 5) then friction (mu 0.2,
    -> 2) are accepted; the refinement of friction + restitution ends at mu 0.001 (gap
    1.9): friction is dropped, and restitution takes the local refit without it (1.95)."""
    from bouncelab.gap import select

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, _fixed, search, settings, _seed, *_more in jobs:
            if search == ():  # restitution refitted from friction's round (4) or its refinement
                out.append(scripted_fit(name, base, 1.95 if base == {"e": 0.5} else 4.0))
            elif name == "friction+restitution" and settings == "refined":
                out.append(scripted_fit(name, {"mu": 0.001, "e": 0.5}, 1.9))
            elif name == "friction+restitution":
                out.append(scripted_fit(name, {"mu": 0.2, "e": 0.45}, 2.0))
            elif name == "restitution":
                out.append(scripted_fit(name, {"e": 0.3}, 5.0))
            else:
                out.append(scripted_fit(name, {}, 9.5 if name != "ideal" else 10.0))
        return out

    script_selection(monkeypatch, fake_fit_many, refined="refined")
    monkeypatch.setattr(select, "replace", lambda problem, **k: problem)
    monkeypatch.setattr(select, "recheck_best", lambda fit, *a, **k: fit)
    sel = select.forward_select(
        None, 1.0, candidates=["friction", "restitution", "harmonic"],
        settings=select.SelectSettings(explained_ratio=0.5),
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["restitution"]
    assert sel["final"].model.params == {"e": 0.5} and sel["final"].objective == 1.95
    assert sel["accepted"][0][1] is sel["final"]


class _OneStepProblem:
    """The least of a problem that :func:`bouncelab.gap.select.armature_choice` reads:
    one fit step of noise floor 1 rad."""

    fit = np.array([True])
    floor = np.array([1.0])

    def mean(self, values, mask):
        return float(np.asarray(values)[mask].mean())


@pytest.mark.parametrize(
    "fresh, taken",
    [
        # impacts-only clearly better on fresh ensembles (means 1.0 against 3.0): switch
        ({0.0: [1.0, 1.1, 0.9, 1.0], 1.0: [3.0, 3.1, 2.9, 3.0]}, 0.0),
        # a lucky fit of the other choice, no better on fresh ensembles: round 1's kept
        ({0.0: [3.5, 3.9, 3.6, 4.1], 1.0: [3.9, 3.8, 4.0, 3.9]}, 1.0),
        # better beyond the noise but by less than DATA_RESOLUTION (0.12) floors: kept
        ({0.0: [3.80, 3.80, 3.80, 3.80], 1.0: [3.90, 3.90, 3.90, 3.90]}, 1.0),
    ],
)
def test_later_rounds_search_every_armature_choice_but_keep_the_harmonics_k(
    monkeypatch, fresh, taken
):
    """Reference: a scripted selection. Round 1: restitution (10 -> 5); the harmonic fits
    best alone at k 3, the armature alone best loaded (ride_load 1). Round 2 searches the
    harmonic at k 3 only and the armature with each ride_load (the other choice twice:
    every parameter searched, and the armature's alone: at 1.2 floors the own search
    does not settle the run); the impacts-only fit (gap 1.2) beats the loaded one (3) on
    the fit steps, and is taken only when it also does on
    fresh ensembles by more than 2 standard errors and 0.12 floors (``fresh``: objective
    per draw, rad). Only in the last round the selection has room for: before it, and
    before session 16 in every round, only round 1's choice (loaded) is searched."""
    from bouncelab.gap import select

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, _seed, *_more in jobs:
            calls.append((name, dict(fixed)))
            choice = {k: v for k, v in fixed.items() if k in ("k", "ride_load")}
            gap = {
                ("restitution", ()): 5.0,
                ("harmonic", (("k", 3.0),)): 8.0,
                ("feedback", (("ride_load", 1.0),)): 7.0,
                ("restitution+feedback", (("ride_load", 0.0),)): 1.2,
                ("restitution+feedback", (("ride_load", 1.0),)): 3.0,
            }.get((name, tuple(sorted(choice.items()))), 9.0 if name != "ideal" else 10.0)
            full = {**choice, "mass_ratio": 0.04} if "feedback" in name else choice
            out.append(scripted_fit(name, full, gap))
        return out

    calls = []
    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(
        select,
        "fresh_objectives",
        lambda model, problem, draws: np.array(fresh[model.params["ride_load"]]),
    )
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["restitution", "harmonic", "feedback"],
        settings=select.SelectSettings(explained_ratio=0.5, max_effects=2),
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    assert sel["final"].model.params["ride_load"] == taken
    assert sel["final"].n_evals == 3  # every search of both choices is counted
    n_k = len(K_CHOICES)
    round2 = calls[1 + n_k + 2 + 1 :]  # baseline, each harmonic k, 2 armatures, restitution
    assert sorted(f["ride_load"] for n, f in round2 if n == "restitution+feedback") == [0, 0, 1]
    assert [f["k"] for n, f in round2 if n == "restitution+harmonic"] == [3.0]

    # with room for a third effect, round 2 is not the last: round 1's choice is kept
    calls.clear()
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["restitution", "harmonic", "feedback"],
        settings=select.SelectSettings(explained_ratio=0.5, max_effects=3),
    )  # fmt: skip
    round2 = calls[1 + n_k + 2 + 1 : 1 + n_k + 2 + 1 + 2]
    assert [f["ride_load"] for n, f in round2 if n == "restitution+feedback"] == [1.0]
    assert sel["accepted"][1][1].model.params["ride_load"] == 1.0


@pytest.mark.parametrize(("kept_gap", "loads"), [(0.4, [1.0]), (1.5, [1.0, 0.0, 0.0])])
def test_the_last_round_skips_the_other_armature_only_when_the_kept_one_settles_the_run(
    monkeypatch, kept_gap, loads
):
    """Reference: a scripted selection as above, where the loaded armature of round 1's
    choice brings round 2 to ``kept_gap`` floors and is taken either way. Within
    settled_ratio (1 floor) the impacts-only armature is not searched (it could only move
    the parameters); at 1.5 floors, within explained_ratio (2) but above the noise, it is
    (an independent seed-like recording ended unexplained with the loaded one at 1.59),
    twice, as it does not settle the run either: the armature's own parameters from the
    round's values, then every parameter searched (there the joint search ended at 1.25
    floors, m/M 95 % off; the armature's own at 0.94, every parameter within 15 %)."""
    from bouncelab.gap import select

    calls = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, search, _settings, _seed, *_more in jobs:
            calls.append((name, dict(fixed), search))
            load = fixed.get("ride_load")
            gap = {("restitution", None): 5.0, ("feedback", 1.0): 8.0}.get((name, load), 9.0)
            gap = kept_gap if name == "restitution+feedback" else gap
            params = {"ride_load": fixed.get("ride_load", 1.0), "mass_ratio": 0.04}
            out.append(scripted_fit(name, params if "feedback" in name else {}, gap))
        return out

    script_selection(monkeypatch, fake_fit_many)
    # both choices score alike on fresh ensembles: round 1's is kept
    monkeypatch.setattr(select, "fresh_objectives", lambda m, p, draws: np.array([1.0, 1.1]))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["restitution", "feedback"],
        settings=select.SelectSettings(max_effects=2),
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    joint = [(f["ride_load"], s) for n, f, s in calls if n == "restitution+feedback"]
    assert [load for load, _s in joint] == loads
    own = ("mass_ratio", "f_ratio", "zeta")
    assert [s for _load, s in joint[1:]] == [own, None][: len(joint) - 1]
    assert sel["final"].model.params["ride_load"] == 1.0


def test_a_noiseless_objective_still_gets_the_data_resolution(monkeypatch):
    """With the objective's own noise 0, the interval still spans the evaluations within
    DATA_RESOLUTION (0.12) mean floors of the best: floors 0.5 rad give a tolerance of
    0.06 rad, which keeps mu 0.3 (0.04 rad worse) and not mu 0.1 (0.15 rad worse)."""
    from bouncelab.gap import diagnose

    class _Floors(_P):
        def __init__(self, n):
            super().__init__(n)
            self.floor = np.full(n, 0.5)

        def mean(self, values, mask):
            return float(np.mean(np.asarray(values)[mask]))

    monkeypatch.setattr(diagnose, "objective_noise", lambda fit, problem: 0.0)
    # the fake problem cannot simulate the probes 15 % away nor the walk of a side at the
    # fitted value (test_flat_directions.py)
    monkeypatch.setattr(diagnose, "flat_directions", lambda fit, problem, tolerance, rise: {})
    monkeypatch.setattr(diagnose, "edge_bounds", lambda fit, problem, ci, tolerance, rise: ci)
    gaps = [[0.25, 0.25], [0.1, 0.1], [0.14, 0.14], [0.5, 0.5]]
    fit = _fake_fit([0.1, 0.2, 0.3, 0.4], gaps)
    summary = diagnose._fit_summary(fit, _Floors(2), seed=0, n_boot=20)
    assert summary["params_ci"]["mu"] == [0.2, 0.3]


def test_refine_budget_scales_with_the_run_and_skips_small_models():
    """The refinement's generations are what REFINE_CYCLES allows on the run's protocol
    (evaluations x draws x cycles), at most REFINE_MAXITER; models of fewer than
    REFINE_MIN_PARAMS continuous parameters, and runs too long for
    REFINE_MIN_GENERATIONS generations, are not refined."""
    import pandas as pd

    from bouncelab.gap import fit
    from bouncelab.gap.fit import FitSettings, Problem, refine_settings

    def problem(cycles):
        p = Problem.__new__(Problem)
        p.protocol = pd.DataFrame({"cycles": [cycles]})
        return p

    combo = ("friction", "restitution", "feedback")  # 5 continuous parameters + ride_load
    settings = FitSettings()
    population = 8 * 6  # (popsize 6 + 2 for feedback) per parameter, 48 at most
    short = refine_settings(problem(100), combo, settings)
    assert short.maxiter == fit.REFINE_MAXITER and short.max_population == 48
    cycles = 2000
    expected = int(fit.REFINE_CYCLES / (cycles * fit.REFINE_DRAWS) // population) - 1
    assert refine_settings(problem(cycles), combo, settings).maxiter == expected
    assert fit.REFINE_MIN_GENERATIONS <= expected < fit.REFINE_MAXITER
    # the shipped 7650-cycle sweep would get 4 generations: skipped
    assert refine_settings(problem(7650), combo, settings) is None
    # one or two continuous parameters: the rounds' budget finds them
    assert refine_settings(problem(100), ("friction", "restitution"), settings) is None
    assert refine_settings(problem(100), ("harmonic",), settings) is None
    # calibrated parameters held fixed do not count
    fixed = {"mu": 0.2, "e": 0.5}
    assert refine_settings(problem(100), combo, settings, fixed).maxiter == fit.REFINE_MAXITER
    assert refine_settings(problem(100), ("friction", "restitution"), settings, fixed) is None
    # what the rounds spent comes off DIAGNOSIS_CYCLES: less left, fewer generations
    left = fit.DIAGNOSIS_CYCLES - fit.REFINE_CYCLES / 2
    run = 1000  # short enough that half the refinement still runs its evolution
    half = int(fit.REFINE_CYCLES / 2 / (run * fit.REFINE_DRAWS) // population) - 1
    assert fit.REFINE_MIN_GENERATIONS <= half < fit.REFINE_MAXITER
    assert refine_settings(problem(run), combo, settings, None, left).maxiter == half
    assert refine_settings(problem(cycles), combo, settings, None, fit.DIAGNOSIS_CYCLES) is None


def test_a_refinement_too_short_for_its_evolution_is_skipped():
    """Below REFINE_MIN_GENERATIONS (12) generations there is no refinement; from it on
    the evolution runs all the generations the budget gives. Why 12: the evolution
    first beat the selected values at generation 11 on the logged refinements, and the
    local search alone, run on 8-11 generations in sessions 28-30, gained 1.2 % for
    17 s (docs/diagnosis-log.md, session 31)."""
    import pandas as pd

    from bouncelab.gap import fit
    from bouncelab.gap.fit import FitSettings, Problem, refine_settings

    def problem(cycles):
        p = Problem.__new__(Problem)
        p.protocol = pd.DataFrame({"cycles": [cycles]})
        return p

    combo = ("friction", "restitution", "feedback")
    population = 48
    assert fit.REFINE_MIN_GENERATIONS == 12

    def cycles_for(generations):  # the longest run that still gets this many
        return fit.REFINE_CYCLES / fit.REFINE_DRAWS / population / (generations + 1)

    for gens in range(fit.REFINE_MIN_GENERATIONS - 4, fit.REFINE_MIN_GENERATIONS + 3):
        got = refine_settings(problem(cycles_for(gens) * 0.999), combo, FitSettings())
        if gens < fit.REFINE_MIN_GENERATIONS:
            assert got is None, gens
        else:
            assert got is not None and got.maxiter == gens, gens


def test_feedback_search_generations_shrink_on_long_runs():
    """A model with feedback searches maxiter x feedback_maxiter_factor generations while
    FEEDBACK_SEARCH_CYCLES allows them for a full population, fewer on longer runs, never
    fewer than maxiter; models without feedback and runs of unknown length keep theirs."""
    from bouncelab.gap import fit
    from bouncelab.gap.fit import FitSettings, search_budget

    s = FitSettings()
    full = s.maxiter * s.feedback_maxiter_factor
    assert search_budget(("feedback",), s) == (s.popsize + s.feedback_extra_popsize, full)
    assert search_budget(("feedback",), s, 2460.0)[1] == full  # the blind feedback runs
    cycles = 4260.0
    allowed = int(fit.FEEDBACK_SEARCH_CYCLES / (s.max_population * cycles)) - 1
    assert s.maxiter < allowed < full
    assert search_budget(("friction", "feedback"), s, cycles)[1] == allowed
    assert search_budget(("feedback",), s, 1e6)[1] == s.maxiter
    assert search_budget(("friction",), s, 1e6) == (s.popsize, s.maxiter)


def test_fit_protocol_cuts_long_runs_to_the_budget():
    """Reference: the arithmetic of fit_protocol's docstring. A run within max_cycles is
    untouched; a longer one has every step cut to one length c, the largest whole number
    with sum(min(cycles, c)) <= max_cycles, steps and Gamma values in their order; no
    step is cut below settle + min_settled cycles, even if the total then exceeds the
    budget."""
    import pandas as pd

    from bouncelab.gap.fit import FIT_PROTOCOL_CYCLES, fit_protocol

    def proto(cycles):
        n = len(cycles)
        return pd.DataFrame({"step": np.arange(n), "gamma": np.linspace(1, 8, n), "cycles": cycles})

    shipped = proto([50] * 153)  # raw/sweep_g0-8: exactly the budget
    assert fit_protocol(shipped, 10).equals(shipped)
    long = proto([100] * 141)  # benchmarks/configs/seed_protocol_long.yaml
    cut = fit_protocol(long, 10)
    assert cut["cycles"].sum() <= FIT_PROTOCOL_CYCLES < (cut["cycles"] + 1).sum()
    assert cut["cycles"].nunique() == 1
    assert cut[["step", "gamma"]].equals(long[["step", "gamma"]])
    mixed = proto([10, 200, 300, 5000])  # short steps keep their length
    assert fit_protocol(mixed, 10, 1000)["cycles"].tolist() == [10, 200, 300, 490]
    assert fit_protocol(mixed, 10, 100, min_settled=30)["cycles"].tolist() == [10, 40, 40, 40]
    assert fit_protocol(mixed, 10, None)["cycles"].tolist() == [10, 200, 300, 5000]
    assert mixed["cycles"].tolist() == [10, 200, 300, 5000]  # input not modified


def _contact_table(contacts_s, gamma=2.0, flight_s=0.02):
    """A flight table of one settled step whose contacts (between flights) are given."""
    t, rows = 0.0, []
    for c in contacts_s:
        rows.append({"step": 0, "gamma": gamma, "settled": True,
                     "t_takeoff_s": t, "t_landing_s": t + flight_s})  # fmt: skip
        t += flight_s + c
    return pd.DataFrame(rows)


class _Rate:
    """The two numbers of a run that min_contact_T reads."""

    sample_rate_hz = 20000.0
    drive_frequency_hz = 30.0


def test_min_contact_reads_the_floor_of_the_contacts():
    """Bounces of 100 us (2 samples at 20 kHz) with longer rides mixed in: 100 us in rad
    of drive phase (2 pi 30 Hz x 1e-4 s = 0.01885 rad)."""
    rng = np.random.default_rng(0)
    bounces = 1e-4 + 2e-6 * rng.standard_normal(300)
    contacts = np.concatenate([bounces, rng.uniform(1e-3, 2e-2, 200)])
    got = min_contact_T(_Rate(), _contact_table(rng.permutation(contacts)))
    assert got == pytest.approx(2 * np.pi * 30.0 * 1e-4, rel=0.05)


@pytest.mark.parametrize(
    "contacts, why",
    [
        (np.full(300, 3e-5), "shorter than 1.5 samples: the edges cannot resolve it"),
        (np.linspace(0.0, 1e-2, 300), "rides from zero up: no floor"),
        (np.full(20, 1e-4), "too few contacts"),
    ],
)
def test_min_contact_is_zero_when_there_is_none_to_read(contacts, why):
    assert min_contact_T(_Rate(), _contact_table(contacts)) == 0.0, why


def test_min_contact_ignores_steps_below_gamma_one():
    """Below Gamma 1 there are no flights to speak of; contacts there are not read."""
    assert min_contact_T(_Rate(), _contact_table(np.full(300, 1e-4), gamma=0.9)) == 0.0


def test_min_contact_of_a_contact_sampled_at_instants_is_its_mean():
    """A closure of 80 us (1.6 samples at 20 kHz) sampled at instants shows as 1 sample
    (40 % of contacts) or 2 (60 %): the low quantile is 50 us, under the 1.5-sample
    limit; the pile-up's mean is the 80 us."""
    rng = np.random.default_rng(1)
    contacts = np.where(rng.random(500) < 0.4, 5e-5, 1e-4) + 1e-6 * rng.standard_normal(500)
    contacts = np.concatenate([contacts, rng.uniform(2e-3, 2e-2, 200)])
    got = min_contact_T(_Rate(), _contact_table(rng.permutation(contacts)))
    assert got == pytest.approx(2 * np.pi * 30.0 * 8e-5, rel=0.05)


def _bounce_table(flights_s, contact_s=1e-4, gamma=2.0, step=0):
    """A flight table of one settled step of flights ``flights_s`` (s), each starting
    ``contact_s`` after the landing before it (a bouncing body), T at a 30 Hz drive."""
    t, rows = 0.0, []
    for f in flights_s:
        rows.append({"step": step, "gamma": gamma, "settled": True, "t_takeoff_s": t,
                     "t_landing_s": t + f, "T": 2 * np.pi * 30.0 * f})  # fmt: skip
        t += f + contact_s
    return pd.DataFrame(rows)


def test_the_chatter_floor_binds_where_a_bouncing_body_shows_no_short_flight():
    """Reference: the definition. A bouncing body (every flight 100 us after the last
    landing) whose flights reach down to 400 us, four times the two samples of 100 us
    that 20 kHz resolves (min_T 0.01885 rad at 30 Hz): the comparison starts at 0.9 of
    the third shortest flight."""
    rng = np.random.default_rng(2)
    flights = np.concatenate([[4e-4, 4.1e-4, 4.2e-4], rng.uniform(5e-4, 2e-2, 300)])
    table = _bounce_table(rng.permutation(flights))
    min_T = resolution_T(_Rate())
    assert min_T == pytest.approx(2 * np.pi * 30.0 * 1e-4)
    got = chatter_floor_T(_Rate(), table, min_T, 2 * np.pi * 30.0 * 1e-4)
    assert got == pytest.approx(0.9 * 2 * np.pi * 30.0 * 4.2e-4)


@pytest.mark.parametrize(
    "flights_s, contact_s, why",
    [
        (np.geomspace(1e-4, 2e-2, 300), 1e-4, "flights down to what the recording resolves"),
        (np.geomspace(4e-4, 2e-2, 300), 5e-3, "an inelastic body: rides between the flights"),
        (np.geomspace(4e-4, 2e-2, 60), 1e-4, "too few flights to read a floor"),
        (np.geomspace(1.5e-4, 2e-2, 300), 1e-4, "a floor under twice min_T"),
    ],
)
def test_the_chatter_floor_keeps_min_t_otherwise(flights_s, contact_s, why):
    table = _bounce_table(flights_s, contact_s=contact_s)
    min_T = resolution_T(_Rate())
    assert chatter_floor_T(_Rate(), table, min_T, 0.0) == min_T, why


def test_the_chatter_floor_reads_only_settled_flights_above_gamma_one():
    """Short flights below Gamma 1 or unsettled do not hold the floor down."""
    table = _bounce_table(np.geomspace(4e-4, 2e-2, 300))
    short = _bounce_table([1e-4] * 20, gamma=0.9, step=1)
    min_T = resolution_T(_Rate())
    got = chatter_floor_T(_Rate(), pd.concat([table, short], ignore_index=True), min_T, 0.0)
    assert got > min_T


def armature_last_round(monkeypatch, fake_fit_many) -> dict:
    """A scripted selection over restitution, the armature and a Gamma miscalibration
    whose round 2 is the last (``max_effects`` 2, ``explained_ratio`` 0.5): the
    armature with ``ARMATURE_SEEDS`` (3) seeds, both ``ride_load`` choices alike on
    fresh ensembles."""
    from bouncelab.gap import select

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "ARMATURE_SEEDS", 3)
    monkeypatch.setattr(select, "fresh_objectives", lambda m, p, draws: np.array([1.0, 1.1]))
    return select.forward_select(
        _OneStepProblem(), 1.0, candidates=["restitution", "feedback", "gamma_scale"],
        settings=select.SelectSettings(max_effects=2, explained_ratio=0.5),
    )  # fmt: skip


def seeded_armature_fits(calls: list, by_seed: dict, miscal_gap: float):
    """A scripted ``fit_many`` for :func:`armature_last_round`: restitution at 5 floors,
    restitution plus the armature at ``by_seed[optimiser seed]``, plus a Gamma
    miscalibration at ``miscal_gap``, anything else 9; ``(model, seed)`` of every job is
    appended to ``calls``."""

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, seed, *_more in jobs:
            calls.append((name, seed))
            params = {"ride_load": fixed.get("ride_load", 1.0), "mass_ratio": 0.04}
            if name == "restitution+feedback":
                out.append(scripted_fit(name, {**params, "zeta": seed}, by_seed[seed]))
            elif name == "restitution+gamma_scale":
                out.append(scripted_fit(name, {"s": 1.05}, miscal_gap))
            elif name == "restitution":
                out.append(scripted_fit(name, {}, 5.0))
            else:
                out.append(scripted_fit(name, params if "feedback" in name else {}, 9.0))
        return out

    return fake_fit_many


@pytest.mark.parametrize("first_seed_gap", [1.7, 0.8])
def test_the_last_round_searches_the_armature_with_several_seeds_and_keeps_the_least(
    monkeypatch, first_seed_gap
):
    """Reference: a scripted selection. Round 1 takes restitution (10 -> 5). Round 2, the
    last with ``max_effects`` 2, fits the armature beside it with ``ARMATURE_SEEDS`` (3)
    optimiser seeds ``seed + j * SEED_STRIDE``, which end at 1.7, 1.2 and 1.6 floors (the
    orbit lottery of one search); the least on the fit steps (1.2) is the armature the
    round compares, and it beats a Gamma miscalibration at 1.5 that would win against the
    first seed's 1.7 (within the tie, 0.25 floors, as the simpler addition). Round 1
    and the other additions: one seed; the other ``ride_load`` choice's searches too,
    which run first. When the first seed's armature is the proposal within one floor
    (0.8), it settles the run: no other seed, no other choice."""
    from bouncelab.gap import select

    calls = []
    by_seed = {0: first_seed_gap, select.SEED_STRIDE: 1.2, 2 * select.SEED_STRIDE: 1.6}

    fake_fit_many = seeded_armature_fits(calls, by_seed, miscal_gap=1.5)

    sel = armature_last_round(monkeypatch, fake_fit_many)
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    seeds = [s for n, s in calls if n == "restitution+feedback"]
    if first_seed_gap < 1.0:
        assert sel["final"].objective == first_seed_gap and seeds == [0]
    else:
        assert sel["final"].objective == 1.2
        assert sel["final"].model.params["zeta"] == select.SEED_STRIDE
        assert seeds[:3] == [0, 0, 0]  # the round's; the other choice: all, the armature's own
        assert seeds[3:] == [select.SEED_STRIDE, 2 * select.SEED_STRIDE]
    # round 1's armature (each ride_load) and the miscalibration: one seed each
    assert [s for n, s in calls if n in ("feedback", "restitution+gamma_scale")] == [0, 0, 0]


@pytest.mark.parametrize(("miscal_gap", "explained_ratio"), [(2.0, 2.0), (1.6, 2.0), (2.0, 1.4)])
def test_the_last_round_runs_the_extra_seeds_of_an_armature_even_where_it_leads(
    monkeypatch, miscal_gap, explained_ratio
):
    """Reference: a scripted selection as above. Round 2's armature ends at 1.5 floors
    (the round's search and the other ``ride_load``'s two: not settled, above one floor),
    its extra seeds at 1.2 and 1.6. Beside a Gamma miscalibration at 2.0 it leads by 0.5
    floors, more than the tie (0.25), within ``explained_ratio`` (2); tied with it at 1.6;
    or above ``explained_ratio`` (1.4). In each the seeds run and the second seed's 1.2
    is taken: a clear lead decides the round, not the armature's parameters, on which the
    verdict rests (the skip of session 60 lost blind ``seed_like_c``'s verdict at
    diagnosis seed 21, session 66). Fails if the seeds are skipped where it leads.
    """
    from bouncelab.gap import select

    calls = []
    by_seed = {0: 1.5, select.SEED_STRIDE: 1.2, 2 * select.SEED_STRIDE: 1.6}

    fake_fit_many = seeded_armature_fits(calls, by_seed, miscal_gap)

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "ARMATURE_SEEDS", 3)
    monkeypatch.setattr(select, "fresh_objectives", lambda m, p, draws: np.array([1.0, 1.1]))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["restitution", "feedback", "gamma_scale"],
        settings=select.SelectSettings(max_effects=2, explained_ratio=explained_ratio),
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    seeds = [s for n, s in calls if n == "restitution+feedback"]
    assert seeds[:3] == [0, 0, 0]  # the round's; the other choice: all, the armature's own
    assert seeds[3:] == [select.SEED_STRIDE, 2 * select.SEED_STRIDE]
    assert sel["final"].objective == 1.2


def impacts_only_fresher_selection(monkeypatch, fake_fit_many, armature_seeds: int = 1) -> dict:
    """:func:`bouncelab.gap.select.forward_select` on ``fake_fit_many``'s fits over
    restitution, the armature and a Gamma miscalibration (``max_effects`` 2,
    ``explained_ratio`` 0.5), the impacts-only armature better on fresh ensembles (0.5
    against 1.0), with ``armature_seeds`` optimiser seeds."""
    from bouncelab.gap import select

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "ARMATURE_SEEDS", armature_seeds)
    fresh = {0.0: [0.5, 0.6], 1.0: [1.0, 1.1]}
    monkeypatch.setattr(
        select, "fresh_objectives", lambda m, p, draws: np.array(fresh[m.params["ride_load"]])
    )
    return select.forward_select(
        _OneStepProblem(), 1.0, candidates=["restitution", "feedback", "gamma_scale"],
        settings=select.SelectSettings(max_effects=2, explained_ratio=0.5),
    )  # fmt: skip


def other_load_fit(name: str, params: dict, load: float) -> FitResult:
    """The scripted fits of the two ``ride_load`` tests below other than restitution plus
    the armature: the armature alone 9 floors loaded and 9.5 impacts-only (round 1 keeps
    the loaded one), restitution 5, anything else 9."""
    if name == "feedback":
        return scripted_fit(name, params, 9.0 if load == 1.0 else 9.5)
    if name == "restitution":
        return scripted_fit(name, {}, 5.0)
    return scripted_fit(name, {"s": 1.05} if "gamma" in name else {}, 9.0)


@pytest.mark.parametrize("other_gap, seeded", [(0.9, False), (1.4, True)])
def test_the_last_rounds_other_ride_load_runs_before_the_extra_seeds(
    monkeypatch, other_gap, seeded
):
    """Reference: a scripted selection. Round 1 takes restitution (10 -> 5) and keeps the
    loaded armature (ride_load 1: 9 floors alone against 9.5). In round 2, the last, the
    loaded armature's first search is at 1.7 floors; the impacts-only choice, searched
    first, reaches ``other_gap`` and wins on fresh ensembles (0.5 against 1.0). Within
    one floor (0.9) it settles the run: no extra seed is searched. Above (1.4) the two
    extra seeds are searched with the impacts-only choice, not round 1's, and the best of
    them (1.2) is taken. Why this order: docs/diagnosis-log.md, session 31
    (independent ``seed_like_impacts_only`` 116 s instead of 146 s, the same answer)."""
    from bouncelab.gap import select

    calls = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, seed, *_more in jobs:
            load = fixed.get("ride_load", 1.0)
            calls.append((name, load, seed))
            params = {"ride_load": load, "mass_ratio": 0.04, "zeta": seed}
            if name == "restitution+feedback":
                gap = 1.7 if load == 1.0 else (other_gap if seed == 0 else 1.2)
                out.append(scripted_fit(name, params, gap))
            else:
                out.append(other_load_fit(name, params, load))
        return out

    sel = impacts_only_fresher_selection(monkeypatch, fake_fit_many, armature_seeds=3)
    joint = [(load, seed) for n, load, seed in calls if n == "restitution+feedback"]
    final = sel["final"].model.params
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    assert final["ride_load"] == 0.0
    if seeded:
        assert joint[-2:] == [(0.0, select.SEED_STRIDE), (0.0, 2 * select.SEED_STRIDE)]
        assert sel["final"].objective == 1.2
    else:
        # the round's, the other choice's own search: it settles the run, so no joint one
        assert joint == [(1.0, 0), (0.0, 0)]
        assert sel["final"].objective == 0.9


@pytest.mark.parametrize(
    ("own_gap", "joint_run", "final_gap"), [(0.9, False, 0.9), (1.3, True, 1.1), (1.05, True, 1.05)]
)
def test_the_other_ride_loads_joint_search_runs_only_where_its_own_search_leaves_the_run_unsettled(
    monkeypatch, own_gap, joint_run, final_gap
):
    """Reference: a scripted selection as above (restitution, then the last round with the
    loaded armature's first search at 1.7 floors). The impacts-only choice is searched
    for the armature's own parameters first (``own_gap``), and every parameter at once
    (1.1, or 1.2 where the own search is at 1.05) only where the own search leaves the
    run above ``settled_ratio`` (one floor): at 0.9 it settles the run and the joint
    search could only move the parameters along the flat valley, so it is not run. The
    better of the two on the fit steps is kept where both ran
    (:func:`bouncelab.gap.select._armature_again`)."""

    searches = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, search, _settings, _seed, *_more in jobs:
            load = fixed.get("ride_load", 1.0)
            params = {"ride_load": load, "mass_ratio": 0.04, "zeta": 0.1}
            if name == "restitution+feedback":
                if load == 1.0:
                    gap = 1.7
                elif search is None:
                    searches.append("joint")
                    gap = 1.2 if own_gap < 1.1 else 1.1
                else:
                    searches.append("own")
                    gap = own_gap
                out.append(scripted_fit(name, params, gap))
            else:
                out.append(other_load_fit(name, params, load))
        return out

    sel = impacts_only_fresher_selection(monkeypatch, fake_fit_many)
    assert searches == (["own", "joint"] if joint_run else ["own"])
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    assert sel["final"].model.params["ride_load"] == 0.0
    assert sel["final"].objective == final_gap


def test_the_selection_counts_the_flights_of_every_fit_it_made(monkeypatch):
    """Reference: the scripted selection above (first seed 1.7 floors), every fit
    costing 100 flights: the work reported is 100 per fit made, the extra armature seeds
    and the other ride_load's searches included though only the best is kept."""
    from bouncelab.gap import select

    calls = []
    by_seed = {0: 1.7, select.SEED_STRIDE: 1.2, 2 * select.SEED_STRIDE: 1.6}

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, seed, *_more in jobs:
            calls.append(name)
            params = {"ride_load": fixed.get("ride_load", 1.0), "mass_ratio": 0.04}
            if name == "restitution+feedback":
                fit = scripted_fit(name, {**params, "zeta": seed}, by_seed[seed])
            elif name == "restitution":
                fit = scripted_fit(name, {}, 5.0)
            else:
                fit = scripted_fit(name, params if "feedback" in name else {}, 9.0)
            out.append(replace(fit, flights=100))
        if work is not None:
            work.add(out)
        return out

    sel = armature_last_round(monkeypatch, fake_fit_many)
    assert calls.count("restitution+feedback") == 5  # 3 seeds, 2 searches of the other choice
    assert sel["work"] == {"flights": 100 * len(calls)}
    # the log behind --timings: one entry per fit, in the order made, with its stage
    log = sel["fit_log"]
    assert [f["model"] for f in log] == calls
    assert sum(f["flights"] for f in log) == sel["work"]["flights"]
    stages = [f["stage"] for f in log]
    assert stages == sorted(stages) and stages[0] == "baseline" and stages[-1] == "round 2"
    # the last round's extra armature searches are that round's work
    assert {f["stage"] for f in log if f["model"] == "restitution+feedback"} == {"round 2"}


@pytest.mark.parametrize("trail, searched_again", [(0.2, True), (0.3, False)])
def test_the_last_round_searches_the_armature_again_only_within_the_tie_of_the_best(
    monkeypatch, trail, searched_again
):
    """Reference: a scripted selection. Round 1 takes restitution (10 -> 5). In round 2,
    the last, a Gamma miscalibration reaches 1.5 floors and the armature's first search
    1.5 + ``trail``. Within the tie (0.25 floors) its other seeds and its other
    ``ride_load`` choice are searched, and its second seed's 1.2 is taken; beyond the tie
    they are not, and the miscalibration is taken. Why: a false armature's first search
    trailed by 0.35 floors or more on the runs measured, a true one by at most 0.13
    (:func:`bouncelab.gap.select._armature_contends`)."""

    calls = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, seed, *_more in jobs:
            calls.append((name, seed))
            params = {"ride_load": fixed.get("ride_load", 1.0), "mass_ratio": 0.04}
            gap = {"restitution": 5.0, "restitution+gamma_scale": 1.5}.get(name, 9.0)
            if name == "restitution+feedback":
                gap = 1.5 + trail if seed == 0 else 1.2
            if "feedback" not in name:
                params = {"s": 1.05} if "gamma_scale" in name else {}
            out.append(scripted_fit(name, params, gap))
        return out

    sel = armature_last_round(monkeypatch, fake_fit_many)
    joint = [s for n, s in calls if n == "restitution+feedback"]
    if searched_again:
        assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
        assert len(joint) == 5  # the round's, the other choice twice, two more seeds
    else:
        assert [e for e, _f in sel["accepted"]] == ["restitution", "gamma_scale"]
        assert joint == [0]


@pytest.mark.parametrize("phases_off", [False, True])
def test_the_selection_goes_on_within_the_floor_while_the_phases_show_the_model_wrong(
    monkeypatch, phases_off
):
    """Reference: a scripted selection (floor 1, explained_ratio 2). Round 1 takes
    restitution (10 -> 5), round 2 the armature (-> 1.8, within the floor: the selection
    stops there). When the takeoff phases of restitution plus the armature are off
    (``unsettled`` names a reason), round 3 is tried anyway, and friction beside them
    (-> 1.2, 0.6 floors and a third less) is accepted by the usual rule; the reason is
    kept in ``went_on``. The phases of the baseline and of restitution alone are not
    read: the gap above the floor already keeps the selection going there."""
    from bouncelab.gap import select

    gaps = {
        "ideal": 10.0,
        "restitution": 5.0,
        "restitution+feedback": 1.8,
        "friction+restitution": 2.5,
        "friction+restitution+feedback": 1.2,
    }

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, _settings, _seed, *_more in jobs:
            params = {"ride_load": fixed.get("ride_load", 1.0), "mass_ratio": 0.04}
            params = params if "feedback" in name else {}
            if "friction" in name:
                params["mu"] = 0.2
            out.append(scripted_fit(name, params, gaps.get(name, 9.0)))
        return out

    checked = []

    def unsettled(model):
        checked.append(model.name)
        return "phases off" if phases_off and model.name == "restitution+feedback" else None

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "fresh_objectives", lambda m, p, draws: np.array([1.0, 1.1]))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "feedback"],
        settings=select.SelectSettings(explained_ratio=2.0), unsettled=unsettled,
    )  # fmt: skip
    accepted = [e for e, _f in sel["accepted"]]
    if phases_off:
        assert accepted == ["restitution", "feedback", "friction"]
        assert sel["final"].objective == 1.2 and sel["went_on"] == ["phases off"]
    else:
        assert accepted == ["restitution", "feedback"] and sel["stop"] == "within_floor"
        assert sel["went_on"] == []
    assert checked == ["restitution+feedback"]


#: The armature's parameters in the scripted runner-up selections below.
_ARMATURE = {"mass_ratio": 0.04, "f_ratio": 0.6, "zeta": 0.1}


def runner_up_fit_many(calls: list, table: dict, joint: str, gap_from):
    """A ``fit_many`` stand-in for the runner-up selections below. Each job's fit is
    ``table[name]`` (``(gap, params)``; ``gap`` may be a function of the params; 9 floors
    when absent), with the job's discrete choices (``k``, ``ride_load``) and the
    armature's :data:`_ARMATURE` values; the ``joint`` fit scores ``gap_from(start)`` at
    its start with mu (0 when absent). Every job's ``(name, start)`` goes to ``calls``."""

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, fixed, _search, _settings, _seed, *_more in jobs:
            calls.append((name, dict(base)))
            if name == joint:
                out.append(scripted_fit(name, {**base, "mu": base.get("mu", 0.0)}, gap_from(base)))
                continue
            gap, params = table.get(name, (9.0, {}))
            if "harmonic" in name:
                params = {**params, "k": fixed.get("k", 2.0)}
            if "feedback" in name:
                params = {**_ARMATURE, **params, "ride_load": fixed.get("ride_load", 1.0)}
            out.append(scripted_fit(name, params, gap(params) if callable(gap) else gap))
        return out

    return fake_fit_many


def runner_up_selection(monkeypatch, fake_fit_many, candidates: list, **settings) -> dict:
    """The scripted selection of the runner-up tests below (floor 1, explained_ratio
    0.5 and ``settings``): ``fake_fit_many`` from :func:`runner_up_fit_many`, fresh
    ensembles that never decide."""
    from bouncelab.gap import select

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "fresh_objectives", lambda m, p, draws: np.array([1.0, 1.1]))
    return select.forward_select(
        _OneStepProblem(), 1.0, candidates=candidates,
        settings=select.SelectSettings(**{"explained_ratio": 0.5, **settings}),
    )  # fmt: skip


def test_after_the_armature_the_runner_up_is_also_fitted_from_its_own_point(monkeypatch):
    """Reference: a scripted selection (floor 1, explained_ratio 0.5). Round 1 takes
    restitution (10 -> 5); round 2 the armature beside it (-> 1.9), friction the
    runner-up (friction + restitution at mu 0.2, e 0.5: 2.6). Round 3 fits friction +
    restitution + armature twice: from the current model (mu 0, e 0.3 where the
    armature left it: ends at 1.8) and from the runner-up's values with the current
    armature (ends at 0.9). The least fit-step objective is kept, and friction is
    accepted (blind ``seed_like_c``, diagnosis seed 3: 1.77 against 0.93 floors). No
    second start before the third round: round 2 has one per effect."""

    calls = []
    armature = {**_ARMATURE, "ride_load": 1.0}
    table = {
        "ideal": (10.0, {}),
        "restitution": (5.0, {"e": 0.3}),
        "feedback": (lambda p: 8.0 if p["ride_load"] == 1.0 else 9.0, {}),  # loaded, alone
        "restitution+feedback": (1.9, {"e": 0.3, **armature}),
        "friction+restitution": (2.6, {"mu": 0.2, "e": 0.5}),
    }
    joint = "friction+restitution+feedback"
    fake = runner_up_fit_many(calls, table, joint, lambda b: 0.9 if b.get("mu") == 0.2 else 1.8)
    sel = runner_up_selection(monkeypatch, fake, ["friction", "restitution", "feedback"])
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback", "friction"]
    assert sel["final"].objective == 0.9
    starts = [b for n, b in calls if n == joint]
    assert len(starts) == 2
    assert starts[0]["e"] == 0.3 and "mu" not in starts[0]  # the current model
    assert starts[1] == {**armature, "mu": 0.2, "e": 0.5}  # the runner-up's, this armature
    assert [n for n, _b in calls].count("friction+restitution") == 1


def test_after_a_harmonic_the_runner_up_is_also_fitted_from_its_own_point(monkeypatch):
    """Reference: a scripted selection (floor 1, explained_ratio 0.5). Round 1 takes
    restitution (10 -> 5); round 2 a harmonic beside it (-> 2.6). The armature (2.7) and
    friction (friction + restitution at mu 0.2, e 0.4: 3.9) come next; the armature is
    never the second start (its own re-searches are the last round's), so friction is.
    Round 3 fits friction + restitution + harmonic twice: from the current model (mu 0,
    where the harmonic left e: 2.65, no gain) and from the runner-up's values with the
    current harmonic (2.2): friction is accepted (independent
    ``friction_restitution_harmonic``, session 24: 2.65 against 2.20 floors)."""

    calls = []
    harmonic = {"a": 0.06, "psi": 2.5}  # k: round 1's choice
    table = {
        "ideal": (10.0, {}),
        "restitution": (5.0, {"e": 0.35}),
        "restitution+harmonic": (2.6, {"e": 0.35, **harmonic}),
        "friction+restitution": (3.9, {"mu": 0.2, "e": 0.4}),
        "restitution+feedback": (2.7, {"e": 0.5}),
    }
    joint = "friction+restitution+harmonic"
    fake = runner_up_fit_many(calls, table, joint, lambda b: 2.2 if b.get("mu") == 0.2 else 2.65)
    candidates = ["friction", "restitution", "harmonic", "feedback"]
    sel = runner_up_selection(monkeypatch, fake, candidates, tie=0.05)
    assert [e for e, _f in sel["accepted"]] == ["restitution", "harmonic", "friction"]
    assert sel["final"].objective == 2.2
    starts = [b for n, b in calls if n == joint]
    assert len(starts) == 2
    assert starts[0]["e"] == 0.35 and "mu" not in starts[0]  # the current model
    second = {n: v for n, v in starts[1].items() if n != "k"}
    assert second == {**harmonic, "mu": 0.2, "e": 0.4}  # the runner-up's, this harmonic
    # the armature, runner-up on the gap, is fitted from the current model only
    armature_starts = [b for n, b in calls if n == "restitution+harmonic+feedback"]
    assert armature_starts and all(b["e"] == 0.35 for b in armature_starts)


@pytest.mark.parametrize(
    ("armature_gap", "explained_ratio", "second_start"),
    [(1.0, 2.0, False), (2.35, 2.0, True), (1.0, 0.9, True)],
)
def test_the_runner_ups_second_start_is_skipped_where_the_armature_leads_clearly(
    monkeypatch, armature_gap, explained_ratio, second_start
):
    """Reference: a scripted selection (floor 1). Round 1 takes restitution (10 -> 5),
    round 2 friction beside it (-> 2.6), a harmonic the runner-up (3.0). Round 3, the
    last, fits the armature beside them at ``armature_gap`` and the harmonic from the
    current model (2.4). At 1.0 floors the armature leads every other addition by more
    than the tie (0.25) and is within ``explained_ratio`` (2): the round takes it
    whatever a second start of the harmonic gives, so the harmonic is not fitted again
    from its own point (seed-like protocols: the second start cost 12-15 s and lost).
    Tied with the harmonic (2.35 against 2.4), or above ``explained_ratio`` (0.9), the
    second start runs from the runner-up's values (2.3)
    (:func:`bouncelab.gap.select._armature_leads`)."""

    calls = []
    table = {
        "ideal": (10.0, {}),
        "restitution": (5.0, {"e": 0.3}),
        "feedback": (lambda p: 8.0 if p["ride_load"] == 1.0 else 9.0, {}),
        "friction+restitution": (2.6, {"mu": 0.2, "e": 0.5}),
        "restitution+harmonic": (3.0, {"e": 0.35, "a": 0.06, "psi": 2.5}),
        "restitution+feedback": (3.5, {"e": 0.5}),
        "friction+restitution+feedback": (armature_gap, {"mu": 0.2, "e": 0.5}),
    }
    joint = "friction+restitution+harmonic"
    fake = runner_up_fit_many(calls, table, joint, lambda b: 2.3 if "a" in b else 2.4)
    candidates = ["friction", "restitution", "harmonic", "feedback"]
    sel = runner_up_selection(monkeypatch, fake, candidates, explained_ratio=explained_ratio)
    assert [e for e, _f in sel["accepted"]][:2] == ["restitution", "friction"]
    starts = [b for n, b in calls if n == joint]
    assert starts[0] == {"mu": 0.2, "e": 0.5}  # the current model
    if second_start:
        assert len(starts) == 2 and starts[1]["a"] == 0.06  # the runner-up's values
    else:
        assert len(starts) == 1
        assert [e for e, _f in sel["accepted"]] == ["restitution", "friction", "feedback"]


@pytest.mark.parametrize(
    ("alt_fresh", "warned"), [([0.23, 0.24, 0.22, 0.23], True), ([0.35, 0.36, 0.34, 0.35], False)]
)
def test_an_armature_alone_is_checked_against_its_other_load_with_a_gamma_scale(
    monkeypatch, alt_fresh, warned
):
    """Reference: a scripted selection (floor 1) shaped on the independent
    ``feedback_gamma_scale`` (session 61). Round 1 takes the loaded armature alone at
    0.21 floors (f_ratio 0.845, zeta 0.24; the impacts-only one 1.67 at f_ratio 0.66);
    the impacts-only armature beside a Gamma miscalibration, searched from round 1's
    impacts-only fit and from the selected values, reaches s 0.937, f_ratio 0.527, zeta
    0.038. On fresh ensembles the selected scores 0.21: at 0.23 the two are within
    DATA_RESOLUTION (0.12) and f_ratio and zeta (moved by more than 15 %; mass_ratio 4 %,
    not) get the warning :func:`bouncelab.gap.fit.warned_params` reads; at 0.35 the data
    tell them apart (0.14 > 0.12): no warning. The selection is not changed either way."""
    from bouncelab.gap import select
    from bouncelab.gap.diagnose import alternative_warnings
    from bouncelab.gap.fit import warned_params

    loaded = {"mass_ratio": 0.055, "f_ratio": 0.845, "zeta": 0.24, "ride_load": 1.0}
    alt = {"mass_ratio": 0.053, "f_ratio": 0.527, "zeta": 0.038, "ride_load": 0.0, "s": 0.937}
    jobs_seen = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, fixed, *rest in jobs:
            jobs_seen.append((name, dict(fixed), dict(base), rest[-1] if len(rest) == 5 else None))
            if name == "feedback" and fixed.get("ride_load") == 1.0:
                out.append(scripted_fit(name, loaded, 0.21))
            elif name == "feedback":
                out.append(scripted_fit(name, {**loaded, "f_ratio": 0.66, "ride_load": 0.0}, 1.67))
            elif name == "feedback+gamma_scale":
                out.append(scripted_fit(name, alt, 0.23))
            else:
                out.append(scripted_fit(name, {}, 10.0 if name == "ideal" else 5.0))
        return out

    script_selection(monkeypatch, fake_fit_many, alternative=True)
    fresh = {"feedback": [0.21, 0.22, 0.20, 0.21], "feedback+gamma_scale": alt_fresh}
    monkeypatch.setattr(select, "fresh_objectives", lambda m, p, draws: np.array(fresh[m.name]))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["feedback", "gamma_scale"],
        settings=select.SelectSettings(explained_ratio=2.0),
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == ["feedback"]
    assert sel["final"].model.params["ride_load"] == 1.0
    name, fixed, base, starts = jobs_seen[-1]
    assert name == "feedback+gamma_scale" and fixed == {"ride_load": 0.0}
    # from round 1's impacts-only armature, or from the selected one's values
    assert base["f_ratio"] == 0.66 and base["s"] == 1.0
    assert starts == [{**loaded, "ride_load": 0.0, "s": 1.0}]
    found = sel["armature_alternative"]
    assert found["told_apart"] is not warned
    assert set(found["moved"]) == {"f_ratio", "zeta"}
    lines = alternative_warnings(found, 1.0)
    assert warned_params(lines) == ({"f_ratio", "zeta"} if warned else set())


@pytest.mark.parametrize(
    "pair_gap, taken", [(0.2, ["gamma_scale", "friction"]), (1.0, ["feedback"])]
)
def test_an_armature_taken_alone_is_checked_against_every_pair(monkeypatch, pair_gap, taken):
    """Reference: a scripted selection (floor 1, explained_ratio 2, margin 0.25). Round 1
    takes the armature alone (10 -> 1.1, within the floor); friction alone reaches 5 and
    a Gamma miscalibration 4 (an independent recording with both: 4.9, 3.8 and the
    armature 1.13). The pair, fitted from the two round-1 values, replaces the armature
    when it beats it by the margin (0.2: the pair, ordered by round-1 gaps, the first
    step its round-1 fit) and not otherwise (1.0: 0.1 floors better only)."""
    from bouncelab.gap import select

    calls = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, _fixed, _search, _settings, _seed, *_more in jobs:
            calls.append((name, dict(base)))
            gap, params = {
                "ideal": (10.0, {}),
                "friction": (5.0, {"mu": 0.4}),
                "gamma_scale": (4.0, {"s": 0.9}),
                "feedback": (
                    1.1,
                    {"ride_load": 1.0, "mass_ratio": 0.1, "f_ratio": 0.4, "zeta": 0.5},
                ),
                "friction+gamma_scale": (pair_gap, {"mu": 0.2, "s": 0.93}),
            }.get(name, (9.0, {}))  # round 2 (1.1 floors: strict_ratio) gains nothing
            out.append(scripted_fit(name, params, gap))
        return out

    script_selection(monkeypatch, fake_fit_many)
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "gamma_scale", "feedback"]
    )
    assert [e for e, _f in sel["accepted"]] == taken
    assert calls.count(("friction+gamma_scale", {"mu": 0.4, "s": 0.9})) == 1
    assert sel["pair_check"]["pairs"] == {"gamma_scale+friction": pair_gap}
    assert ("replaced_by" in sel["pair_check"]) == (taken != ["feedback"])
    assert sel["final"].objective == (pair_gap if taken != ["feedback"] else 1.1)
    if taken != ["feedback"]:
        assert sel["accepted"][0][1].model.name == "gamma_scale"  # its round-1 fit


def test_the_pairs_come_before_a_strict_round_after_the_armature_alone(monkeypatch):
    """Reference: a scripted selection (floor 1). Round 1 takes the armature alone at 1.13
    floors: within explained_ratio (2) but above strict_ratio (1), where a strict round
    would go on. Beside the armature, friction would reach 0.17 (85 % less: the strict
    round takes it); friction with a Gamma miscalibration reaches 0.12. The independent
    ``friction_gamma_scale`` (mu 0.2, s 0.93) took the armature and friction this way in
    session 25. The pairs are checked first, where the armature alone would have ended
    the selection: the pair replaces it, and the run ends within the floor."""
    from bouncelab.gap import select

    calls = []
    armature = {"mass_ratio": 0.08, "f_ratio": 0.05, "zeta": 0.86}
    table = {
        "ideal": (10.0, {}),
        "friction": (4.9, {"mu": 0.4}),
        "gamma_scale": (3.8, {"s": 0.9}),
        "feedback": (1.13, armature),
        "friction+feedback": (0.17, {**armature, "mu": 0.2}),
        "friction+gamma_scale": (0.12, {"mu": 0.2, "s": 0.93}),
    }
    script_selection(monkeypatch, armature_table_fit_many(table, calls))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "gamma_scale", "feedback"]
    )
    assert [e for e, _f in sel["accepted"]] == ["gamma_scale", "friction"]
    assert sel["pair_check"]["replaced_by"] == ["gamma_scale", "friction"]
    assert sel["final"].objective == 0.12 and sel["stop"] == "within_floor"
    assert "friction+feedback" not in calls  # no strict round beside the armature
    assert calls.count("friction+gamma_scale") == 1


@pytest.mark.parametrize("a_interval, kept", [((0.0, 0.013), False), ((0.007, 0.010), True)])
def test_a_later_effect_whose_refined_interval_reaches_its_null_value_is_dropped(
    monkeypatch, a_interval, kept
):
    """Reference: a scripted selection (floor 1). Round 1 takes restitution (10 -> 5),
    round 2 a harmonic of a 0.008 beside it (-> 1.0). With the harmonic's interval
    after the refinement reaching a = 0 (0 to 0.013: blind ``g_restitution_low`` with
    diagnosis seed 3) the harmonic is dropped, restitution refitted without it, and
    ``weak_dropped`` says why; with an interval clear of the null band (0.007 to 0.010,
    the band being a <= 0.0025) it is kept."""

    calls = []
    sel = select_from_table(
        monkeypatch, RESTITUTION_THEN_WEAK_HARMONIC, ["restitution", "harmonic"],
        {"a": list(a_interval)}, calls,
    )  # fmt: skip
    taken = [e for e, _f in sel["accepted"]]
    if kept:
        assert taken == ["restitution", "harmonic"] and sel["weak_dropped"] == []
        assert sel["final"].objective == 1.0
    else:
        assert taken == ["restitution"] and sel["final"].objective == 5.0
        assert sel["weak_dropped"] == [
            {"effect": "harmonic", "param": "a", "interval": [0.0, 0.013]}
        ]
        assert calls[-1] == "restitution"  # refitted without the harmonic


@pytest.mark.parametrize("s_interval, kept", [((0.991, 1.003), False), ((0.95, 0.97), True)])
def test_a_middle_effect_whose_refined_interval_reaches_its_null_value_is_dropped(
    monkeypatch, s_interval, kept
):
    """Reference: a scripted selection (floor 1), the shape of blind
    ``w_friction_harmonic`` at diagnosis seed 17. Round 1 takes a harmonic (10 -> 5),
    round 2 a Gamma miscalibration beside it (-> 3), round 3 friction (-> 0.5). With the
    miscalibration's interval in the final model reaching s = 1 (0.991 to 1.003, the
    band being |s - 1| <= 0.002) it is dropped though it is not the last effect, and the
    final model refitted without it (0.6); with an interval clear of the band (0.95 to
    0.97) all three are kept."""

    calls = []
    h = {"a": 0.05, "k": 3.0, "psi": 1.0}
    table = {
        "ideal": (10.0, {}),
        "harmonic": (5.0, h),
        "harmonic+gamma_scale": (3.0, {**h, "s": 0.995}),
        "friction+harmonic+gamma_scale": (0.5, {**h, "s": 0.995, "mu": 0.2}),
        "friction+harmonic": (4.0, {**h, "mu": 0.2}),  # round 2: the miscalibration wins
    }
    ci = {"a": [0.045, 0.055], "s": list(s_interval), "mu": [0.18, 0.21]}
    sel = select_from_table(
        monkeypatch, table, ["harmonic", "gamma_scale", "friction"], ci, calls,
        refit=("friction+harmonic", 0.6),  # the local refit without s
    )  # fmt: skip
    taken = [e for e, _f in sel["accepted"]]
    if kept:
        assert taken == ["harmonic", "gamma_scale", "friction"] and sel["weak_dropped"] == []
        assert sel["final"].objective == 0.5
    else:
        assert taken == ["harmonic", "friction"] and sel["final"].objective == 0.6
        assert sel["weak_dropped"] == [
            {"effect": "gamma_scale", "param": "s", "interval": [0.991, 1.003]}
        ]
        assert calls[-1] == "friction+harmonic"  # refitted without the miscalibration
        assert sel["accepted"][-1][1] is sel["final"]


@pytest.mark.parametrize("s_interval, kept", [((0.9968, 1.0004), False), ((0.92, 0.94), True)])
def test_a_first_effect_whose_refined_interval_reaches_its_null_value_is_dropped(
    monkeypatch, s_interval, kept
):
    """Reference: a scripted selection (floor 1), the shape of an independent friction
    and restitution whose chatter ends early (session 76). Round 1 takes a Gamma
    miscalibration standing in for both (10 -> 7.7), round 2 restitution beside it
    (-> 4.7), round 3 friction (-> 0.8) with s back at 0.9985. With the miscalibration's
    interval in the final model reaching s = 1 it is dropped though it came first: the
    final model is refitted without it (0.3) and the first step is restitution's round-1
    fit alone; with an interval clear of the band all three are kept."""

    calls = []
    table = {
        "ideal": (10.0, {}),
        "gamma_scale": (7.7, {"s": 1.18}),
        "restitution": (8.7, {"e": 0.41}),
        "friction": (8.6, {"mu": 0.1}),
        "restitution+gamma_scale": (4.7, {"e": 0.31, "s": 0.93}),
        "friction+gamma_scale": (7.7, {"mu": 0.19, "s": 1.28}),
        "friction+restitution+gamma_scale": (0.8, {"e": 0.35, "mu": 0.23, "s": 0.9985}),
        "friction+restitution": (5.0, {"e": 0.35, "mu": 0.25}),
    }
    ci = {"s": list(s_interval), "e": [0.34, 0.36], "mu": [0.24, 0.26]}
    sel = select_from_table(
        monkeypatch, table, ["gamma_scale", "restitution", "friction"], ci, calls,
        refit=("friction+restitution", 0.3),  # the local refit without s
    )  # fmt: skip
    taken = [e for e, _f in sel["accepted"]]
    if kept:
        assert taken == ["gamma_scale", "restitution", "friction"]
        assert sel["weak_dropped"] == [] and sel["final"].objective == 0.8
    else:
        assert taken == ["restitution", "friction"] and sel["final"].objective == 0.3
        assert sel["weak_dropped"] == [
            {"effect": "gamma_scale", "param": "s", "interval": list(s_interval)}
        ]
        assert sel["accepted"][0][1].model.name == "restitution"  # its round-1 fit alone
        assert sel["accepted"][-1][1] is sel["final"]


def test_the_first_effect_stays_where_every_effect_reaches_its_null_value(monkeypatch):
    """Reference: a scripted selection (floor 1): restitution (10 -> 5), then a harmonic
    (-> 1.0), both intervals reaching their null values: the later one is dropped, the
    first stays (a selection is never emptied this way)."""

    ci = {"a": [0.0, 0.013], "e": [0.0, 0.4]}
    sel = select_from_table(
        monkeypatch, RESTITUTION_THEN_WEAK_HARMONIC, ["restitution", "harmonic"], ci
    )
    assert [e for e, _f in sel["accepted"]] == ["restitution"]
    assert [w["effect"] for w in sel["weak_dropped"]] == ["harmonic"]


def test_no_pair_check_when_the_armature_is_not_alone(monkeypatch):
    """Reference: a scripted selection. Round 1 takes restitution (10 -> 5), round 2 the
    armature beside it (-> 1.5, within the floor): no pairs are fitted."""
    from bouncelab.gap import select

    calls = []
    table = {
        "ideal": (10.0, {}),
        "restitution": (5.0, {"e": 0.3}),
        "feedback": (6.0, {"mass_ratio": 0.1, "f_ratio": 0.4, "zeta": 0.5}),
        "restitution+feedback": (1.5, {"e": 0.4, "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1}),
        "friction+restitution": (4.0, {"mu": 0.1, "e": 0.3}),
    }
    script_selection(monkeypatch, armature_table_fit_many(table, calls))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "feedback"]
    )
    assert [e for e, _f in sel["accepted"]] == ["restitution", "feedback"]
    assert sel["pair_check"] is None
    assert calls.count("friction+restitution") == 1  # round 2's, no pair fit


@pytest.mark.parametrize(
    "second, final_gap, boxed",
    [("friction", 2.0, True), ("friction", 1.2, False), ("feedback", 2.0, False)],
)
def test_a_selected_model_above_the_box_ratio_is_searched_again_in_a_box(
    monkeypatch, second, final_gap, boxed
):
    """Reference: a scripted selection. Restitution (10 -> 5) then ``second`` (-> the final
    gap) are accepted. Above SelectSettings.box_ratio (1.5 floors) the box refinement is
    called on the final fit and its fit replaces the last accepted one; at 1.2 it is not
    called, nor on a model with the armature (refined on the expected gap instead)."""
    from bouncelab.gap import select

    joint = {
        "friction": ("friction+restitution", {"mu": 0.3, "e": 0.4}),
        "feedback": (
            "restitution+feedback",
            {"e": 0.4, "mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 0.0},
        ),
    }[second]

    gaps = {"ideal": 10.0, "restitution": 5.0, joint[0]: final_gap}
    params = {"restitution": {"e": 0.3}, joint[0]: joint[1]}
    script_selection(monkeypatch, table_fit_many(gaps, params))
    calls = []

    def fake_box(fit, *a, **k):
        calls.append(fit.model.params)
        return scripted_fit(fit.model.name, {**fit.model.params, "e": 0.41}, 0.9), {"kept": True}

    monkeypatch.setattr(select, "box_refinement", fake_box)
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", second]
    )
    assert [e for e, _f in sel["accepted"]] == ["restitution", second]
    assert calls == ([joint[1]] if boxed else [])
    assert (sel["final"].model.params["e"] == 0.41) == boxed
    assert sel["accepted"][-1][1] is sel["final"]
    assert (sel["box"] is not None) == boxed


@pytest.mark.parametrize("fresh_after, kept", [(0.5, True), (1.5, False)])
def test_the_box_fit_is_kept_only_when_it_does_better_on_fresh_ensembles(
    monkeypatch, fresh_after, kept
):
    """Reference: scripted fits. The box search of friction + harmonic (k 2 held as a
    choice) returns mu 0.2; fresh ensembles score the fit 1.0 and the box's fit
    ``fresh_after``: the box's fit is kept only below 1.0."""
    from bouncelab.gap import select

    fit = scripted_fit("friction+harmonic", {"mu": 0.28, "k": 2.0, "a": 0.05, "psi": 1.7}, 2.2)
    jobs_seen = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        jobs_seen.extend(jobs)
        (_problem, name, base, _fixed, _search, _settings, _seed) = jobs[0]
        return [scripted_fit(name, {**base, "mu": 0.2}, 0.8)]

    monkeypatch.setattr(select, "fit_many", fake_fit_many)
    monkeypatch.setattr(select, "recheck_best", lambda f, *a, **k: f)
    monkeypatch.setattr(
        select,
        "fresh_objectives",
        lambda model, problem: np.full(4, fresh_after if model.params["mu"] == 0.2 else 1.0),
    )
    out, info = select.box_refinement(fit, None, {}, select.FitSettings(), 0)
    (_problem, name, base, fixed, _search, settings, _seed) = jobs_seen[0]
    assert name == "friction+harmonic" and base["mu"] == 0.28
    assert fixed == {"k": 2.0} and settings.box_share == select.BOX_SHARE
    assert info["kept"] == kept and info["fresh_before"] == 1.0
    assert (out.model.params["mu"] == 0.2) == kept and (out is fit) != kept


@pytest.mark.parametrize(
    "first_gap, second_gap, taken, n_rounds",
    [
        # harmonic_gamma_scale (independent): 1.99 -> 0.60, 70 % less: taken
        (1.99, 0.60, ["harmonic", "gamma_scale"], 2),
        # g_restitution_high (blind): 1.76 -> 1.04, 41 % less: not taken
        (1.76, 1.04, ["harmonic"], 2),
        # within strict_ratio (1 floor): no second round
        (0.9, 0.1, ["harmonic"], 1),
    ],
)
def test_between_one_and_two_floors_an_addition_must_halve_the_gap(
    monkeypatch, first_gap, second_gap, taken, n_rounds
):
    """Reference: a scripted selection (floor 1; explained_ratio 2, strict_ratio 1,
    strict_shrink 0.5). Round 1 takes the harmonic (10 -> ``first_gap``); round 2's best
    addition, the miscalibration, reaches ``second_gap``."""
    from bouncelab.gap import select

    gaps = {"ideal": 10.0, "harmonic": first_gap, "harmonic+gamma_scale": second_gap}
    params = {
        "harmonic": {"k": 3.0, "a": 0.08, "psi": 1.0},
        "harmonic+gamma_scale": {"k": 3.0, "a": 0.08, "psi": 1.0, "s": 1.05},
    }
    script_selection(monkeypatch, table_fit_many(gaps, params))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "harmonic", "gamma_scale"]
    )
    assert [e for e, _f in sel["accepted"]] == taken
    assert len(sel["rounds"]) == n_rounds
    assert sel["stop"] == "within_floor"


def test_a_strict_round_leaves_the_armature_out(monkeypatch):
    """Reference: a scripted selection (floor 1). Round 1 takes restitution (10 -> 1.94,
    g_restitution_high); round 2 is strict. The armature beside it would reach 0.5 (74 %
    less) but is not fitted; friction (1.76) does not halve the gap: restitution alone."""
    from bouncelab.gap import select

    names = []
    gaps = {"ideal": 10.0, "restitution": 1.94, "friction+restitution": 1.76,
            "restitution+feedback": 0.5}  # fmt: skip
    params = {
        "restitution": {"e": 0.6},
        "friction+restitution": {"mu": 0.05, "e": 0.6},
        "feedback": {"mass_ratio": 0.1, "f_ratio": 0.5, "zeta": 0.5, "ride_load": 0.0},
    }
    script_selection(monkeypatch, table_fit_many(gaps, params, names))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "feedback"]
    )
    assert [e for e, _f in sel["accepted"]] == ["restitution"]
    assert [e for e, _f in sel["rounds"][1]] == ["friction"]
    assert "restitution+feedback" not in names and "feedback" in names  # round 1 has it


@pytest.mark.parametrize(
    "refit_gap, taken", [(0.9, ["restitution"]), (2.4, ["restitution", "friction"])]
)
def test_an_addition_must_beat_the_effects_before_it_refitted_from_its_point(
    monkeypatch, refit_gap, taken
):
    """Reference: a scripted selection (floor 1). Round 1 takes restitution (10 -> 2.5),
    round 2's friction + restitution reaches 1.6. Restitution alone, refitted locally from
    that joint fit's point, reaches ``refit_gap``: at 0.9 the joint fit's gain was
    restitution's better fit (blind ``g_feedback``, session 47), so friction is not taken,
    restitution keeps the refit and the selection stops (no addition passes); at 2.4 friction earns
    its place (0.8 floors and a third of the gap) and is taken."""
    from bouncelab.gap import select

    starts = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, _fixed, search, *_rest in jobs:
            if search == ():  # the refit without the addition, from its values
                starts.append((name, dict(base)))
                out.append(scripted_fit(name, base, refit_gap))
            elif name == "restitution":
                out.append(scripted_fit(name, {"e": 0.3}, 2.5))
            elif name == "friction+restitution":
                out.append(scripted_fit(name, {"mu": 0.03, "e": 0.45}, 1.6))
            else:
                out.append(scripted_fit(name, {}, 9.5 if name != "ideal" else 10.0))
        return out

    script_selection(monkeypatch, fake_fit_many)
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "harmonic"]
    )
    assert [e for e, _f in sel["accepted"]] == taken
    assert starts[0] == ("restitution", {"e": 0.45})  # from the joint fit's values
    if refit_gap < 1.6:
        assert sel["not_earned"] == [{"effect": "friction", "floors": 1.6, "without": 0.9}]
        assert sel["final"].objective == 0.9 and sel["final"].model.params == {"e": 0.45}
        assert sel["stop"] == "no_improvement"
    else:
        assert sel["not_earned"] == [] and sel["final"].objective == 1.6


@pytest.mark.parametrize(
    "phases_right_with, taken",
    [
        ("friction", ["restitution", "feedback", "friction"]),
        ("nothing", ["restitution", "feedback"]),
        ("friction_or_its_refit", ["restitution", "feedback"]),
    ],
)
def test_a_round_entered_for_the_phases_takes_the_addition_that_sets_them_right(
    monkeypatch, phases_right_with, taken
):
    """Reference: a scripted selection (floor 1, explained at 2). Restitution (10 -> 3)
    and the armature (-> 1.3, within the floor) are taken; the takeoff phases of that
    model are wrong, so round 3 is fitted. Friction beside them scores 1.8 held out,
    worse on flight times, and fails the margin. When friction's model is the one whose
    phases are right and the two effects before it, refitted from its point (3.3), are
    still wrong, friction is taken for the phases (blind ``g_seed_like`` at seeds 17 and
    18, session 48); when no model's phases are right, or the refit without friction
    (from its e of 0.45) sets them right too, nothing is taken."""
    from bouncelab.gap import select

    arm = {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.04}
    fits = {
        "ideal": (10.0, {}),
        "restitution": (3.0, {"e": 0.5}),
        "friction+restitution": (2.9, {"mu": 0.2, "e": 0.5}),
        "restitution+feedback": (1.3, {"e": 0.5, **arm}),
        "friction+restitution+feedback": (1.8, {"mu": 0.25, "e": 0.45, **arm}),
    }
    refits = {"restitution": 5.0, "restitution+feedback": 3.3}  # without the addition

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, base, fixed, search, *_rest in jobs:
            if search == ():
                out.append(scripted_fit(name, base, refits.get(name, 9.5)))
                continue
            gap, params = fits.get(name, (9.5, {}))
            if "feedback" in name:
                params = {**params, "ride_load": fixed.get("ride_load", 1.0)}
            out.append(scripted_fit(name, params, gap))
        return out

    def unsettled(model):
        with_friction = "friction" in model.effects
        refit = model.params.get("e") == 0.45 and not with_friction  # from friction's point
        right = {
            "friction": with_friction,
            "nothing": False,
            "friction_or_its_refit": with_friction or refit,
        }[phases_right_with]
        return None if right else "takeoff phases differ"

    script_selection(monkeypatch, fake_fit_many)
    monkeypatch.setattr(select, "fresh_objectives", lambda *a, **k: np.full(4, 9.5))
    sel = select.forward_select(
        _OneStepProblem(), 1.0, candidates=["friction", "restitution", "harmonic", "feedback"],
        unsettled=unsettled,
    )  # fmt: skip
    assert [e for e, _f in sel["accepted"]] == taken
    if phases_right_with == "friction":
        assert sel["phase_taken"] == [
            {"effect": "friction", "floors": 1.8, "current": 1.3, "without": 3.3}
        ]
        assert sel["final"].objective == 1.8 and sel["went_on"] == ["takeoff phases differ"]
    else:
        assert sel["phase_taken"] == [] and sel["stop"] == "no_improvement"
        assert sel["final"].objective == 1.3


def test_a_joint_fit_that_moved_the_taken_harmonics_k_is_fitted_again_with_it_held(
    monkeypatch,
):
    """Reference: the independent friction_harmonic_g0-8's shape (docs/diagnosis-log.md,
    session 51). The harmonic is taken at k 3; friction's joint fit moved it to k 4 at
    2.96 floors, and is fitted again with k held at 3 (1.0 floors: kept); the
    miscalibration's kept k 3 and the armature's moved k are not fitted again; a held fit
    that does worse leaves the first; with no harmonic taken nothing is fitted again."""
    from bouncelab.gap import select

    calls = []

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        calls.extend((name, fixed.get("k")) for _p, name, _b, fixed, *_rest in jobs)
        truth = {"mu": 0.2, "a": 0.05, "k": 3.0, "psi": 1.0}
        return [scripted_fit(name, truth, held_gap) for _p, name, *_rest in jobs]

    monkeypatch.setattr(select, "fit_many", fake_fit_many)
    harmonic = {"a": 0.03, "k": 3.0, "psi": 1.5}
    moved = {"a": 0.03, "k": 4.0, "psi": 6.3}
    armature = {"mass_ratio": 0.04, "f_ratio": 0.2, "zeta": 0.5, "ride_load": 0.0}
    tried = [
        ("friction", scripted_fit("friction+harmonic", {**moved, "mu": 0.23}, 2.96)),
        ("gamma_scale", scripted_fit("harmonic+gamma_scale", {**harmonic, "s": 0.98}, 3.5)),
        ("feedback", scripted_fit("harmonic+feedback", {**moved, **armature}, 3.2)),
    ]
    job = (None, {}, None, 0)
    held_gap = 1.0
    out = dict(select._k_held_again(tried, harmonic, job, None, None, None))
    assert calls == [("friction+harmonic", 3.0)]
    assert out["friction"].objective == 1.0 and out["friction"].model.params["k"] == 3.0
    assert out["gamma_scale"] is tried[1][1] and out["feedback"] is tried[2][1]
    held_gap = 4.0
    out = dict(select._k_held_again(tried, harmonic, job, None, None, None))
    assert out["friction"].model.params["k"] == 4.0
    calls.clear()
    assert select._k_held_again(tried, {"mu": 0.2}, job, None, None, None) == tried
    assert calls == []
