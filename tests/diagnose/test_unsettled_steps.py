"""Steps that end before their flights settle leave nothing to compare: a black-box
probe's 8-cycle steps under the default settle_cycles 10 were diagnosed as "selected
nothing, gap 0 -> 0, explained" for a friction of 0.2. Now one line naming run.yaml says
why and what to change, and the pipeline's check gives the run every product but the
diagnosis (as for a run of too few steps)."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from diag_synth import GAMMAS, duration_s, pseudo_flights, write_run

from bouncelab.errors import BouncelabError
from bouncelab.gap.fit import unsettled_steps
from bouncelab.physics import Model
from bouncelab.runs import load_run


@pytest.mark.parametrize("cycles, settle, ok", [(8, 10, False), (8, 2, True), (40, 10, True)])
def test_steps_shorter_than_settle_cycles_are_refused(tmp_path, cycles, settle, ok):
    run_dir = write_run(tmp_path, cycles=cycles)
    spec = yaml.safe_load((run_dir / "run.yaml").read_text())
    spec["settle_cycles"] = settle
    (run_dir / "run.yaml").write_text(yaml.safe_dump(spec, sort_keys=False))
    why = unsettled_steps(load_run(run_dir), duration_s(cycles=cycles))
    if ok:
        assert why is None
    else:
        assert why.startswith(f"only 0 of {len(GAMMAS)} Gamma steps last longer than settle")
        assert "lower settle_cycles in run.yaml" in why


def test_the_diagnosis_and_the_pipeline_check_say_it(tmp_path):
    from bouncelab.gap.diagnose import diagnose_flights
    from bouncelab.pipeline import check_run_verdict

    run_dir = write_run(tmp_path, cycles=8)
    run = load_run(run_dir)
    flights = pseudo_flights(run_dir, Model.parse("ideal"), seed=3, cycles=8)
    with pytest.raises(BouncelabError, match="settle_cycles") as err:
        diagnose_flights(run, flights, duration_s(cycles=8), progress=False)
    assert "run.yaml" in str(err.value)
    # a channel with contacts for the check (write_run's is silent, which it refuses)
    rec = dict(np.load(run_dir / "rec.npz"))
    k = np.arange(rec["cont_v"].size)
    rec["cont_v"] = np.where(k % 400 < 20, 0.0, 5.0)
    np.savez(run_dir / "rec.npz", **rec)
    verdict = check_run_verdict(run_dir)
    assert verdict["ok"] and "settle_cycles" in verdict["no_diagnosis"], verdict
