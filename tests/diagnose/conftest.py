"""Make the pseudo-data helpers (``diag_synth.py``) importable; a null run shared by the
tests of the diagnosis's seeds (``--check-seeds``, ``--retries``)."""

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))


@pytest.fixture(scope="module")
def null_run(tmp_path_factory):
    """A small pseudo-data run of the ideal model: its folder and flight table's path."""
    from diag_synth import pseudo_flights, write_run

    from bouncelab.physics import Model
    from bouncelab.tables import write_table

    root = tmp_path_factory.mktemp("seeds")
    run_dir = write_run(root)
    path = write_table(pseudo_flights(run_dir, Model.parse("ideal"), seed=3), root / "f.parquet")
    return run_dir, path
