"""Make the pseudo-data helpers (``diag_synth.py``) importable; a null run shared by the
tests of the diagnosis's seeds (``--check-seeds``, ``--retries``); a stand-in diagnosis."""

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


@pytest.fixture
def given(monkeypatch):
    """``diagnose_flights`` replaced by a stand-in (a real diagnosis needs minutes): what
    it was given is recorded (``max_T``, ``n`` flights, ``left_out_steps``)."""
    import bouncelab.gap.diagnose as diag

    seen = {}

    def fake(run, table, duration, *, seed, left_out_steps=(), **kw):
        seen["max_T"] = float(table["T"].max())
        seen["n"] = len(table)
        seen["left_out_steps"] = list(left_out_steps)
        return {
            "verdict_margin": {"rel_gap": 0.5, "n_heldout": 10},
            "design": {"seed": seed}, "selected": [], "unexplained": False,
            "final_rel_gap": 0.5, "warnings": [],
        }  # fmt: skip

    monkeypatch.setattr(diag, "diagnose_flights", fake)
    return seen
