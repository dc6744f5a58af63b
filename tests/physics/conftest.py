"""Fixtures of the physics tests; plain helpers live in physics_helpers.py."""

import numpy as np
import pytest


@pytest.fixture(scope="session")
def rng():
    return np.random.default_rng(12345)
