"""Fixtures of the rig tests; plain helpers live in rig_helpers.py."""

from __future__ import annotations

import pytest
from rig_helpers import quiet_config  # noqa: F401  (re-exported for fixtures)

from bouncelab.rig import simulate_rig


@pytest.fixture(scope="session")
def simulate():
    """``simulate(cfg)`` -> RigResult (the session fixture keeps numba's load once)."""
    return simulate_rig
