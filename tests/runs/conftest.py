"""Fixtures of the runs tests; the writers are in ``runs_fixtures.py``."""

from __future__ import annotations

import pytest
from runs_fixtures import run_factory


@pytest.fixture
def make_run(tmp_path):
    """Factory writing tiny run folders under ``tmp_path/raw`` (see ``run_factory``)."""
    return run_factory(tmp_path)
