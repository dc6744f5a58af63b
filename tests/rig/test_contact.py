"""Contact model: damping from restitution, and the restitution the kernel delivers."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rig_helpers import quiet_config

from bouncelab.rig.config import derive
from bouncelab.rig.kernels import zeta_from_restitution


@pytest.mark.parametrize("e", [0.05, 0.3, 0.515, 0.8, 0.95])
def test_zeta_inverts_the_linear_dashpot_restitution(e):
    """Reference: a linear spring-dashpot restitutes exp(-pi zeta / sqrt(1 - zeta^2))
    (half a damped period); the inversion must give it back to 1e-12."""
    z = zeta_from_restitution(e)
    assert math.exp(-math.pi * z / math.sqrt(1 - z * z)) == pytest.approx(e, rel=1e-12)


def test_plastic_mode_is_critical_damping():
    """e = 0: zeta = 1 exactly (no rebound: the penetration never returns to zero)."""
    assert zeta_from_restitution(0.0) == 1.0


def test_contact_duration_is_tens_of_microseconds():
    """A stiff metal block touches for well under 100 us: with contact_time_s 40 us and
    e 0.515 the contact lasts 40 us / sqrt(1 - zeta^2) = 40.9 us (derived, analytic)."""
    d = derive(quiet_config())
    assert 40e-6 < d["contact_duration_s"] < 42e-6


def test_restitution_without_friction_from_drop_flights(simulate):
    """With mu = 0 and a still, rigid plate successive flights shrink by exactly e
    (flight = 2 u / g). Reference e = 0.515; tolerance 0.5 % on the first three ratios
    (gravity acting during the 41 us contact changes a 0.1-0.8 m/s impact by < 0.1 %;
    the integrator's error at 25 steps per contact is of the same size)."""
    cfg = quiet_config(
        kind="drop",
        body={"friction_mu": 0.0, "restitution": 0.515},
        protocol={"drop_height_m": 0.05, "release_t_s": 0.05, "duration_s": 0.6},
    )
    fl = simulate(cfg).truth["flight_s"].to_numpy()
    ratios = fl[1:4] / fl[:3]
    np.testing.assert_allclose(ratios, 0.515, rtol=5e-3)
