"""Two effects that offset each other, each worse alone than none: the selection's pair
swap (:func:`bouncelab.gap.select._pair_swap`). Scripted selections (floor 1 rad): what
is tested is the rule; docs/diagnosis-log.md, session 80, measures it on a recording."""

from __future__ import annotations

from test_fit_units import _OneStepProblem, script_selection, table_fit_many

from bouncelab.gap import select

CANDIDATES = ["friction", "restitution", "harmonic", "gamma_scale"]

#: Round 1 of the black-box probe's friction (mu 0.15) and Gamma miscalibration (s 1.1):
#: friction alone at its null value, the miscalibration barely moved, a harmonic taken.
ROUND_1 = {"ideal": 10.0, "friction": 10.0, "restitution": 10.0, "harmonic": 6.0,
           "gamma_scale": 8.0}  # fmt: skip
PARAMS = {
    "friction": {"mu": 0.0},
    "restitution": {"e": 0.0},
    "harmonic": {"k": 3.0, "a": 0.03, "psi": 1.0},
    "gamma_scale": {"s": 1.01},
    select.model_name(["friction", "gamma_scale"]): {"mu": 0.15, "s": 1.1},
}


def _pair(a: str, b: str) -> str:
    return select.model_name([a, b])


def test_a_pair_round_1_left_apart_replaces_the_effects_taken(monkeypatch):
    """Reference: the probe's run (harmonic taken, then nothing; the pair alone 0.1
    floors). The swap fits the three pairs no round fitted and takes the miscalibration
    (round 1's better) and friction; the selection then ends within the floor."""
    gaps = {**ROUND_1, _pair("friction", "gamma_scale"): 0.1}
    names = []
    script_selection(monkeypatch, table_fit_many(gaps, PARAMS, names))
    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES)
    assert [e for e, _f in sel["accepted"]] == ["gamma_scale", "friction"]
    assert sel["stop"] == "within_floor" and sel["final"].objective == 0.1
    swap = sel["pair_swap"]
    assert swap["taken"] == ["gamma_scale", "friction"] and swap["current"] == 6.0
    # the pairs with the harmonic were round 2's: not fitted again
    assert sorted(swap["pairs"]) == ["friction+restitution", "gamma_scale+friction",
                                     "gamma_scale+restitution"]  # fmt: skip
    assert names.count(_pair("friction", "gamma_scale")) == 1
    # the first step is the miscalibration's round-1 fit
    assert sel["accepted"][0][1].objective == 8.0


def test_no_swap_within_the_floor_or_without_a_pair_that_earns_its_place(monkeypatch):
    """Within ``explained_ratio`` floors no pair is fitted; above it, a best pair that
    does not remove ``margin`` floors and ``min_shrink`` of the gap leaves the selection
    as it was (its fits kept in ``pair_swap``)."""
    names = []
    within = {**ROUND_1, "harmonic": 1.5, _pair("friction", "gamma_scale"): 0.1}
    script_selection(monkeypatch, table_fit_many(within, PARAMS, names))
    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES)
    assert [e for e, _f in sel["accepted"]] == ["harmonic"] and sel["pair_swap"] is None
    assert _pair("friction", "gamma_scale") not in names
    close = {**ROUND_1, _pair("friction", "gamma_scale"): 5.9}
    script_selection(monkeypatch, table_fit_many(close, PARAMS))
    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES)
    assert [e for e, _f in sel["accepted"]] == ["harmonic"]
    assert "taken" not in sel["pair_swap"] and sel["pair_swap"]["current"] == 6.0


def test_a_pair_with_a_refused_harmonic_is_not_swapped_in_and_is_marked_proposed(monkeypatch):
    """Reference: a scripted selection. Restitution taken (6 floors), then nothing; the
    best pair round 1 left apart has a harmonic the takeoff phases refuse: restitution
    stays, the refusal is kept as the swap's with ``proposed`` (every refusal has one:
    the diagnosis reads it for its warnings; blind ``ool_vdep_restitution`` stopped on a
    KeyError before), and ``refused_pair`` names it."""
    gaps = {**ROUND_1, "restitution": 6.0, "harmonic": 8.0,
            _pair("friction", "harmonic"): 0.1}  # fmt: skip
    script_selection(monkeypatch, table_fit_many(gaps, {**PARAMS, "restitution": {"e": 0.4}}))
    why = {"k": 3.0, "a": 0.03, "psi": 1.0, "rms_rad": 0.2, "plain_rms_rad": 0.01}

    def refuted(effect, model):
        return why if effect == "harmonic" else None

    sel = select.forward_select(_OneStepProblem(), 1.0, candidates=CANDIDATES, refuted=refuted)
    assert [e for e, _f in sel["accepted"]] == ["restitution"]
    assert sel["pair_swap"]["refused_pair"] == _pair("friction", "harmonic")
    assert "taken" not in sel["pair_swap"]
    assert all("proposed" in t for t in sel["takeoff_refused"])
    swapped = [t for t in sel["takeoff_refused"] if t["round"] == "pair_swap"]
    assert [t["proposed"] for t in swapped if t["model"] == _pair("friction", "harmonic")] == [True]
