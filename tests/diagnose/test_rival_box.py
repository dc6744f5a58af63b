"""An armature's best rival searched again in a box before a round chooses
(:func:`bouncelab.gap.select._rival_boxed`). Scripted selections (floor 1 rad): what is
tested is the rule; docs/diagnosis-log.md, session 81, measures it on a recording."""

from __future__ import annotations

from test_fit_units import _OneStepProblem, script_selection, scripted_fit

from bouncelab.gap import select

CANDIDATES = ["friction", "restitution", "harmonic", "feedback", "gamma_scale"]

ARMATURE = {"mass_ratio": 0.1, "f_ratio": 0.5, "zeta": 0.9}
PARAMS = {
    "restitution": {"e": 0.37},
    "friction+restitution": {"mu": 0.19, "e": 0.36},
    "restitution+harmonic": {"e": 0.35, "k": 2.0, "a": 0.03, "psi": 1.0},
    "restitution+feedback": {"e": 0.41, **ARMATURE},
}

#: Round 1 of the independent ``friction_restitution_gamma_scale`` in outline:
#: restitution taken (10 -> 5.8); round 2's armature 3.56, friction beside restitution
#: 3.83 (0.27 behind: beyond the tie), the harmonic 3.9.
GAPS = {"ideal": 10.0, "restitution": 5.8, "friction+restitution": 3.83,
        "restitution+harmonic": 3.9, "restitution+feedback": 3.56}  # fmt: skip


def boxing_fit_many(gaps: dict, boxed: dict, calls: list):
    """A scripted ``fit_many``: each job's model looked up in ``gaps`` (default 9), or in
    ``boxed`` for a box search (settings with a ``box_share``); armature models get the
    job's ``ride_load``; ``calls`` gets ``(model, boxed?)`` of every job."""

    def fake_fit_many(jobs, pool=None, progress=None, work=None):
        out = []
        for _problem, name, _base, fixed, _search, settings, _seed, *_more in jobs:
            box = getattr(settings, "box_share", None) is not None
            calls.append((name, box))
            gap = boxed.get(name, gaps.get(name, 9.0)) if box else gaps.get(name, 9.0)
            params = dict(PARAMS.get(name, {}))
            if "feedback" in name:
                params = {**ARMATURE, **params, "ride_load": fixed.get("ride_load", 1.0)}
            out.append(scripted_fit(name, params, gap))
        return out

    return fake_fit_many


def _select(monkeypatch, boxed: dict, refuted=None):
    calls = []
    script_selection(monkeypatch, boxing_fit_many(GAPS, boxed, calls), rival_box=True)
    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES, refuted=refuted)
    return sel, calls


def test_a_rival_the_box_takes_below_the_armature_is_taken(monkeypatch):
    """Reference: the recording's round 2 in outline; its box took friction beside
    restitution from 3.83 to 3.67 floors, within the tie of the armature's 3.56, and
    round 3 then found the miscalibration. Here the box reaches 1.0: friction is taken,
    the armature is not, and the box is recorded with the gaps before and after."""
    sel, calls = _select(monkeypatch, {"friction+restitution": 1.0})
    assert [e for e, _f in sel["accepted"]] == ["restitution", "friction"]
    assert sel["final"].objective == 1.0
    assert sel["rival_box"] == [
        {"round": 2, "rival": "friction", "model": "friction+restitution", "armature": 3.56,
         "before": 3.83, "after": 1.0}
    ]  # fmt: skip
    # only the rival is boxed, once; round 1 (the armature not proposed) boxes nothing
    assert [c for c in calls if c[1]] == [("friction+restitution", True)]


def test_a_box_that_gains_nothing_leaves_the_armature(monkeypatch):
    """The box ends no better (scripted: worse, 4.5) than the rival's own search: the
    better of the two on the fit steps is kept (3.83), and the armature, 0.27 floors
    ahead, is taken as without the box."""
    sel, calls = _select(monkeypatch, {"friction+restitution": 4.5})
    assert [e for e, _f in sel["accepted"]][:2] == ["restitution", "feedback"]
    assert sel["rival_box"][0]["after"] == 3.83
    assert ("friction+restitution", True) in calls


def test_a_refused_rival_is_passed_over_for_the_next(monkeypatch):
    """Where the takeoffs refuse the best rival (a harmonic, scripted at 3.6), the next
    one (friction, 3.83) is boxed; the refusal is not logged by the box's check."""
    gaps = {**GAPS, "restitution+harmonic": 3.6}
    calls = []
    script_selection(
        monkeypatch, boxing_fit_many(gaps, {"friction+restitution": 1.0}, calls), rival_box=True
    )
    why = {"k": 2.0, "a": 0.03, "psi": 1.0, "rms_rad": 0.2, "plain_rms_rad": 0.01}

    def refuted(effect, model):
        return why if effect == "harmonic" else None

    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES, refuted=refuted)
    assert sel["rival_box"][0]["rival"] == "friction"
    assert [e for e, _f in sel["accepted"]] == ["restitution", "friction"]
    assert [c for c in calls if c[1]] == [("friction+restitution", True)]


def test_no_box_where_the_round_proposes_another_effect(monkeypatch):
    """The armature behind friction (scripted 1.6 against 1.5 floors; round 3, strict,
    leaves the armature out): nothing is boxed."""
    gaps = {**GAPS, "friction+restitution": 1.5, "restitution+feedback": 1.6}
    calls = []
    script_selection(
        monkeypatch, boxing_fit_many(gaps, {"friction+restitution": 1.0}, calls), rival_box=True
    )
    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES)
    assert [e for e, _f in sel["accepted"]] == ["restitution", "friction"]
    assert sel["rival_box"] == []
    assert not [c for c in calls if c[1]]
