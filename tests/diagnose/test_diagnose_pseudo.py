"""Small blind cases on pseudo-data: the "measured" flights come from the physics model
with a known effect (another start phase than the diagnosis uses, 0.005 rad timing
noise), so the truth is exact. Budget reduced (``FAST``) to keep CI short; the full
validation on the virtual rig is ``python -m bouncelab.gap.blind`` (docs/diagnosis.md).
"""

from __future__ import annotations

import json

import pytest
from diag_synth import GAMMAS, duration_s, pseudo_flights, write_run

from bouncelab.gap.diagnose import diagnose_flights
from bouncelab.gap.fit import FitSettings
from bouncelab.physics import Model
from bouncelab.runs import load_run

FAST = FitSettings(popsize=5, maxiter=6, local_evals=6, n_boot=100)
CONTRACT_KEYS = {
    "run", "noise_floor", "baseline", "candidates", "steps", "selected",
    "final_gap", "unexplained", "regions",
}  # fmt: skip


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    return write_run(tmp_path_factory.mktemp("diag"))


def _diagnose(run_dir, model, seed=5, **kw):
    flights = pseudo_flights(run_dir, model, seed=seed)
    return diagnose_flights(
        load_run(run_dir), flights, duration_s(), seed=0, fit_settings=FAST, workers=1, **kw
    )


@pytest.fixture(scope="module")
def friction_result(run_dir):
    return _diagnose(run_dir, Model.parse("friction", {"mu": 0.2}))


def test_friction_selected_and_recovered(friction_result):
    """Truth: friction with mu = 0.2. Goal (issue 6): the top effect right and the
    parameter within 15 % of the truth."""
    r = friction_result
    assert r["selected"][:1] == ["friction"]
    mu = r["steps"][0]["params"]["mu"]
    assert abs(mu - 0.2) / 0.2 < 0.15
    lo, hi = r["steps"][0]["params_ci"]["mu"]
    assert lo <= mu <= hi
    # the baseline gap is far above the floor, the final one is not
    assert r["baseline"]["gap"] > 5 * r["noise_floor"]
    assert r["unexplained"] is False
    assert r["steps"][0]["shrink"] > 0.8


def test_contract_keys_and_json(friction_result):
    """CONTRACTS.md section 6: every key present, strict JSON (no NaN)."""
    r = friction_result
    assert CONTRACT_KEYS <= set(r)
    json.dumps(r, allow_nan=False)
    assert [c["effect"] for c in r["candidates"]] == [
        "friction", "restitution", "harmonic", "feedback", "gamma_scale",
    ]  # fmt: skip
    for c in r["candidates"]:
        assert set(c) >= {"effect", "params", "gap", "shrink"}
    for reg in r["regions"]:
        assert set(reg) >= {"gamma_min", "gamma_max", "gap", "explained_by"}
    # the onset region (ideal takes off at Gamma 1, friction at 1.2) is explained by friction
    assert any(reg["explained_by"] == "friction" for reg in r["regions"])


def test_null_selects_nothing(run_dir):
    """Truth: the ideal model itself. Goal: no false alarm (nothing selected, explained)."""
    r = _diagnose(run_dir, Model.parse("ideal"), seed=9)
    assert r["selected"] == []
    assert r["unexplained"] is False
    assert r["final_gap"] <= 3 * r["noise_floor"]


def test_combination_recovered_by_joint_refit(run_dir):
    """Truth: friction and restitution together (mu = 0.25, e = 0.45). Restitution alone
    absorbs part of the friction; the later round refits both jointly (every parameter
    searched globally), so both are selected and both parameters land within 15 %."""
    r = _diagnose(run_dir, Model.parse("friction+restitution", {"mu": 0.25, "e": 0.45}))
    assert sorted(r["selected"]) == ["friction", "restitution"]
    params = r["final_model"]["params"]
    assert abs(params["mu"] - 0.25) / 0.25 < 0.15
    assert abs(params["e"] - 0.45) / 0.45 < 0.15
    assert r["unexplained"] is False


def test_a_down_sweep_is_diagnosed_like_an_up_sweep(tmp_path):
    """Runs of other labs need not sweep upwards: Gamma stepped down (state carried from
    the higher step, so the branches of the hysteresis are those a down-sweep shows).
    Truth: friction with mu = 0.2; it must be the top effect, within 15 %, explained,
    and the profile must come out in Gamma order."""
    down = write_run(tmp_path, "down", gammas=tuple(reversed(GAMMAS)))
    r = _diagnose(down, Model.parse("friction", {"mu": 0.2}))
    assert r["selected"][:1] == ["friction"]
    assert abs(r["steps"][0]["params"]["mu"] - 0.2) / 0.2 < 0.15
    assert r["unexplained"] is False
    gammas = r["profile"]["gamma"]
    assert gammas == sorted(gammas) and len(gammas) == len(GAMMAS)


def test_a_harmonic_the_takeoffs_refuse_is_reported_and_not_taken(run_dir, monkeypatch):
    """Truth: friction (mu 0.2). With a judge that refuses every harmonic fit it is shown
    (JSON ``takeoff_refused`` with its round; a warning for each one that would have been
    proposed, none for the others) and friction is still taken; the judge sees harmonics
    only (``diagnose_flights``' closure)."""
    from bouncelab.gap import diagnose

    judged = []

    def refuse(points, reading, k, a, psi):
        judged.append(k)
        return {"k": float(k), "a": float(a), "psi": float(psi), "rms_rad": 0.3,
                "plain_rms_rad": 0.01}  # fmt: skip

    monkeypatch.setattr(diagnose, "harmonic_refuted", refuse)
    r = _diagnose(run_dir, Model.parse("friction", {"mu": 0.2}))
    assert r["selected"][:1] == ["friction"]
    assert "harmonic" not in r["selected"]
    assert judged and r["takeoff_refused"]
    assert {t["effect"] for t in r["takeoff_refused"]} == {"harmonic"}
    assert r["takeoff_refused"][0]["round"] == 1
    warned = [w for w in r["warnings"] if "takeoff phases 30 times worse" in w]
    assert len(warned) == sum(t["proposed"] for t in r["takeoff_refused"])
    json.dumps(r, allow_nan=False)
