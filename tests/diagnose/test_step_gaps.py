"""The fits' inner loop (``gap.fit.step_gaps``: kernel arrays, no DataFrames) against the
plain route (``protocol.simulate_run`` per member, ``gap.distances.gap_table``)."""

from __future__ import annotations

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run

from bouncelab.gap.distances import gap_table
from bouncelab.gap.fit import (
    align_steps,
    make_problem,
    member_model,
    member_offsets,
    simulate,
    step_gaps,
)
from bouncelab.physics import Model
from bouncelab.physics.simulate import protocol_flight_times, simulate_protocol
from bouncelab.runs import load_run


@pytest.fixture(scope="module")
def problem(tmp_path_factory):
    run_dir = write_run(tmp_path_factory.mktemp("gaps"))
    truth = Model.parse("restitution", {"e": 0.4})
    flights = pseudo_flights(run_dir, truth, seed=3)
    return make_problem(load_run(run_dir), flights, duration_s(), n_members=3)


MODELS = [
    Model.parse("ideal"),
    Model.parse("friction+restitution", {"mu": 0.2, "e": 0.45}),
    Model.parse("harmonic+gamma_scale", {"k": 3.0, "a": 0.05, "psi": 1.0, "s": 1.05}),
    Model.parse("feedback", {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1}),
]


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.name)
def test_step_gaps_is_the_least_member_gap_of_the_plain_route(problem, model, monkeypatch):
    """Same numbers to 1e-9 rad (the Gamma factor is applied in another order: ~1e-12).
    The chatter cut of the fits is set to the kernel default here, so both routes
    simulate the same physics."""
    import bouncelab.gap.fit as fit

    monkeypatch.setattr(fit, "CHATTER_SAMPLES", 1e-5 / fit.resolution_T(problem.run, 1.0))
    fast = step_gaps(problem, model)
    plain = [
        align_steps(gap_table(problem.data, simulate(problem, model, m), steps=problem.steps),
                    problem.steps)["gap"].to_numpy()
        for m in range(problem.n_members)
    ]  # fmt: skip
    np.testing.assert_allclose(fast, np.min(plain, axis=0), rtol=0, atol=1e-9)


def test_protocol_arrays_match_simulate_protocol():
    """``protocol_flight_times`` member j is ``simulate_protocol`` of the model with
    gamma_scale s = 1 + offset_j (flight times to 1e-9 rad, same steps and settling)."""
    gammas, cycles = np.array([0.8, 1.6, 2.4, 3.3]), np.array([20, 20, 20, 20])
    model = Model.parse("friction+restitution", {"mu": 0.15, "e": 0.5})
    offsets = member_offsets(3)
    arrays = protocol_flight_times(model, gammas, cycles, 5, 1.0 + offsets)
    for j, off in enumerate(offsets):
        ref = simulate_protocol(member_model(model, off), gammas, cycles, settle_cycles=5)
        mine = arrays["member"] == j
        assert mine.sum() == len(ref)
        np.testing.assert_allclose(arrays["T"][mine], ref["T"].to_numpy(), rtol=0, atol=1e-9)
        np.testing.assert_array_equal(arrays["step"][mine], ref["step"].to_numpy())
        np.testing.assert_array_equal(arrays["settled"][mine], ref["settled"].to_numpy())
