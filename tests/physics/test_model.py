"""Model names, parameters and the EFFECTS table (CONTRACTS.md section 5)."""

import math

import numpy as np
import pytest

from bouncelab.errors import BouncelabError
from bouncelab.physics import EFFECTS, Model, parse_assignments


def test_effects_table_has_every_contract_parameter_with_sane_bounds():
    want = {
        "friction": {"mu"},
        "restitution": {"e"},
        "harmonic": {"k", "a", "psi"},
        "feedback": {"mass_ratio", "f_ratio", "zeta"},
        "gamma_scale": {"s"},
    }
    # the contract's parameters, plus feedback's optional ride_load (default 0: the
    # contract's impacts-only armature)
    want["feedback"].add("ride_load")
    assert {k: set(v) for k, v in EFFECTS.items()} == want
    assert EFFECTS["feedback"]["ride_load"][0] == 0.0
    for params in EFFECTS.values():
        for default, lo, hi in params.values():
            assert lo <= default <= hi and lo < hi
    assert EFFECTS["restitution"]["e"][2] < 1 and EFFECTS["friction"]["mu"][2] < 1


def test_parse_canonical_name_defaults_and_copy():
    m = Model.parse("restitution+friction", {"mu": 0.3})
    assert m.name == "friction+restitution"
    assert m.effects == ("friction", "restitution")
    assert m.params == {"mu": 0.3, "e": EFFECTS["restitution"]["e"][0]}
    m2 = m.with_params(e=0.2)
    assert m2.params["e"] == 0.2 and m.params["e"] != 0.2
    assert Model.parse("ideal").name == "ideal" and Model.parse("ideal").params == {}
    full = Model.parse("friction+restitution+harmonic+feedback+gamma_scale")
    assert full.name == "friction+restitution+harmonic+feedback+gamma_scale"


def test_harmonic_list_and_single():
    m = Model.parse("harmonic", {"harmonics": [(3, 0.1, 0.0), (0.37, 0.2, 1.0)]})
    assert m.harmonics == ((3.0, 0.1, 0.0), (0.37, 0.2, 1.0))
    assert (m.params["k"], m.params["a"]) == (3.0, 0.1)
    m2 = m.with_params(a=0.3)
    assert m2.harmonics[0] == (3.0, 0.3, 0.0) and m2.harmonics[1] == (0.37, 0.2, 1.0)
    m3 = Model.parse("harmonic", {"k": 2.5, "a": 0.2, "psi": math.pi})
    assert m3.harmonics == ((2.5, 0.2, math.pi),)


@pytest.mark.parametrize(
    ("name", "params"),
    [
        ("frictio", {}),
        ("friction+friction", {}),
        ("friction+", {}),
        ("friction", {"e": 0.5}),
        ("friction", {"nope": 1}),
        ("friction", {"mu": 1.2}),
        ("restitution", {"e": "x"}),
        ("restitution", {"e": float("nan")}),
        ("feedback", {"f_ratio": 0}),
        ("gamma_scale", {"s": -1}),
        ("harmonic", {"harmonics": [(1, 2)]}),
    ],
)
def test_bad_models_raise_one_line_errors(name, params):
    with pytest.raises(BouncelabError) as err:
        Model.parse(name, params)
    assert "\n" not in str(err.value)


def test_parse_assignments():
    assert parse_assignments(["mu=0.29", "e = 0.5"]) == {"mu": 0.29, "e": 0.5}
    for bad in (["mu"], ["=1"], ["zz=1"], ["mu=abc"]):
        with pytest.raises(BouncelabError):
            parse_assignments(bad)


def test_rigid_plate_restitution_gives_the_same_impact_in_the_other_convention():
    """Reference: the two impact laws written out. The model's two-body impact (docs/
    physics.md): body velocity change J = (1 + e)(-u)/(1 + r), armature -r J. The other
    convention: the body rebounds at -e_r u from the plate as it was, the armature takes
    r (1 + e_r) u. With e_r = rigid_plate_restitution(e, r) both give the same body and
    armature velocities after the impact (to rounding), and e_r = e without an armature."""
    from bouncelab.physics import rigid_plate_restitution

    rng = np.random.default_rng(3)
    for e, r, vp, u in rng.uniform([0.0, 0.0, -2.0, -3.0], [0.95, 0.5, 2.0, -0.01], (50, 4)):
        jump = (1.0 + e) * (-u) / (1.0 + r)
        body, armature = vp + u + jump, -r * jump
        e_r = rigid_plate_restitution(e, r)
        assert abs((vp - e_r * u) - body) < 1e-12
        assert abs(r * (1.0 + e_r) * u - armature) < 1e-12
    assert rigid_plate_restitution(0.515, 0.0) == 0.515
    assert abs(rigid_plate_restitution(0.5707, 0.0448) - 0.5030) < 1e-3


def test_two_body_restitution_undoes_the_rigid_plate_one():
    """Reference: the inverse written out, e = e_r (1 + r) + r; the independent
    generator's e_r 0.4 beside m/M 0.05 is the model's 0.47."""
    from bouncelab.physics import rigid_plate_restitution, two_body_restitution

    for e, r in np.random.default_rng(5).uniform([0.0, 0.0], [0.95, 0.5], (50, 2)):
        assert abs(two_body_restitution(rigid_plate_restitution(e, r), r) - e) < 1e-12
    assert abs(two_body_restitution(0.4, 0.05) - 0.47) < 1e-12
    assert two_body_restitution(0.515, 0.0) == 0.515
