"""The fits' inner loop (``gap.fit.step_gaps``: kernel arrays, no DataFrames) against the
plain route (``protocol.simulate_run`` per member, ``gap.distances.gap_table``)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from diag_synth import duration_s, pseudo_flights, write_run

from bouncelab.gap.distances import gap_table
from bouncelab.gap.fit import (
    CHATTER_SAMPLES,
    MEMBER_SPREAD,
    EvaluationPool,
    FitSettings,
    align_steps,
    best_member_simulation,
    counted_step_gaps,
    fit_model,
    make_problem,
    member_model,
    member_offsets,
    resolution_T,
    simulate,
    step_gaps,
)
from bouncelab.physics import Model
from bouncelab.physics.simulate import OutputBuffer, protocol_flight_times, simulate_protocol
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


@pytest.mark.parametrize("model", MODELS[1:3], ids=lambda m: m.name)
def test_best_member_simulation_is_the_table_step_gaps_scores(problem, model, monkeypatch):
    """Its per-step gap is the least over members (the fits' number, 1e-9 rad), every
    step comes from one member (its flights equal that member's), rows in time order."""
    import bouncelab.gap.fit as fit

    monkeypatch.setattr(fit, "CHATTER_SAMPLES", 1e-5 / fit.resolution_T(problem.run, 1.0))
    best = best_member_simulation(problem, model)
    gaps = align_steps(gap_table(problem.data, best, steps=problem.steps), problem.steps)
    np.testing.assert_allclose(gaps["gap"], step_gaps(problem, model), rtol=0, atol=1e-9)
    members = [simulate(problem, model, m) for m in range(problem.n_members)]
    for step, rows in best.groupby("step"):
        same = [
            np.array_equal(rows["T"].to_numpy(), sim.loc[sim["step"] == step, "T"].to_numpy())
            for sim in members
        ]
        assert any(same), f"step {step} mixes members"
    assert np.all(np.diff(best["t_takeoff_s"].to_numpy()) >= 0)


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


def test_several_draws_are_the_mean_of_each_draws_capped_gaps(problem):
    """Reference: the mean of capped per-draw gaps, each draw computed alone (one
    ensemble, ``n_draws`` 1, shifted by k / n), as ``step_gaps`` documents: exactly."""
    model = Model.parse("friction+restitution", {"mu": 0.15, "e": 0.45})
    three = replace(problem, n_draws=3)
    alone = [step_gaps(replace(problem, n_draws=1), model, shift=k / 3) for k in range(3)]
    np.testing.assert_array_equal(step_gaps(three, model), np.mean(three.clipped(alone), axis=0))


def test_the_gap_kernel_reads_members_in_blocks_or_scattered_alike(problem):
    """``ensemble_gaps`` finds each member's flights as a block when the members come in
    order and by a mask otherwise: shuffling the members' blocks (each kept in time
    order) changes no number."""
    from bouncelab.gap._kernels import ensemble_gaps
    from bouncelab.gap.distances import DEFAULT_ALPHA, KEY_SPAN

    model = Model.parse("restitution", {"e": 0.5})
    proto = problem.protocol
    sim = protocol_flight_times(
        model, proto["gamma"].to_numpy(), proto["cycles"].to_numpy(), 10, 1.0 + member_offsets(3)
    )
    k = problem.kernel_inputs

    def gaps(order):
        a = {name: v[order] for name, v in sim.items()}
        return ensemble_gaps(
            a["member"], k.protocol_step[a["step"]], a["T"], a["settled"], 3,
            float(problem.min_T), k.grid, k.data_t_step, k.data_t_val, k.data_p_step,
            k.data_p_val, k.directions, DEFAULT_ALPHA, k.scale, KEY_SPAN,
        )  # fmt: skip

    in_order = np.arange(len(sim["T"]))
    blocks = [np.flatnonzero(sim["member"] == m) for m in (2, 0, 1)]
    scattered = np.concatenate(blocks)
    assert np.any(np.diff(sim["member"][scattered]) < 0)
    np.testing.assert_array_equal(gaps(in_order), gaps(scattered))


def test_a_reused_output_buffer_changes_no_result():
    """The kernel's output array kept between calls (``OutputBuffer``): each call's
    arrays equal a fresh call's, and none shares the buffer's memory (a later call
    must not overwrite an earlier result)."""
    gammas, cycles = np.array([1.2, 2.2, 3.1]), np.array([15, 15, 15])
    models = [
        Model.parse("restitution", {"e": 0.5}),
        Model.parse("friction", {"mu": 0.3}),
    ]
    buffer = OutputBuffer()
    kept = [
        protocol_flight_times(m, gammas, cycles, 4, (1.0, 1.0001), buffer=buffer) for m in models
    ]
    for m, got in zip(models, kept, strict=True):
        fresh = protocol_flight_times(m, gammas, cycles, 4, (1.0, 1.0001))
        assert got.keys() == fresh.keys()
        for k in fresh:
            np.testing.assert_array_equal(got[k], fresh[k])
    # results own their memory: nothing of them lies in the buffer's array
    arr = buffer.array
    assert arr is not None
    for got in kept:
        for v in got.values():
            assert not np.shares_memory(v, arr)


def test_fit_in_an_evaluation_pool_equals_the_serial_fit(problem):
    """A fit whose populations are evaluated by two worker processes gives the same
    evaluations, in the same order, and the same best model as one run in-process."""
    settings = FitSettings(popsize=4, maxiter=3, local_evals=3)
    name = "friction+restitution"
    serial = fit_model(problem, name, settings=settings, seed=2)
    with EvaluationPool(problem, 2) as pool:
        pooled = fit_model(problem, name, settings=settings, seed=2, pool=pool)
    assert pooled.n_evals == serial.n_evals > 10
    np.testing.assert_array_equal(pooled.cloud_x, serial.cloud_x)
    np.testing.assert_array_equal(pooled.cloud_gaps, serial.cloud_gaps)
    assert pooled.model.params == serial.model.params


@pytest.mark.parametrize("min_contact", [0.0, 0.01])
def test_a_pool_compiles_the_kernels_with_the_types_of_an_evaluation(
    problem, min_contact, monkeypatch
):
    """The workers' warm-up (:func:`_worker_compile`) calls each kernel with the argument
    types of a real evaluation: otherwise numba would compile a second specialisation at
    the first evaluation and the warm-up would only cost time."""
    import numba

    import bouncelab.gap.fit as fit
    import bouncelab.physics.kernels as kernels

    problem = replace(problem, min_contact=min_contact)
    seen: dict[str, set] = {}

    def recorder(name, kernel):
        def call(*args):
            seen.setdefault(name, set()).add(tuple(numba.typeof(a) for a in args))
            return kernel(*args)

        return call

    for name in ("run_many", "protocol_rows"):
        monkeypatch.setattr(kernels, name, recorder(name, getattr(kernels, name)))
    monkeypatch.setattr(fit, "ensemble_gaps", recorder("ensemble_gaps", fit.ensemble_gaps))
    monkeypatch.setattr(fit, "_WORKER", {"problem": problem, "buffer": OutputBuffer()})
    fit._worker_compile("simulation")
    fit._worker_compile("gaps")
    warmed = {k: set(v) for k, v in seen.items()}
    step_gaps(problem, Model.parse("friction+restitution", {"mu": 0.2, "e": 0.45}))
    expected = {"run_many", "protocol_rows", "ensemble_gaps"}
    assert set(warmed) == expected
    assert seen == warmed  # the evaluation brought no new argument types


def test_a_pool_whose_workers_fail_to_start_is_closed(problem):
    """An error in the workers' warm-up (here a problem with no protocol steps) reaches the
    caller, and the pool's processes are gone: no caller holds the pool to close it."""
    import multiprocessing

    from bouncelab.errors import BouncelabError

    before = set(multiprocessing.active_children())
    broken = replace(problem, protocol=problem.protocol.iloc[:0])
    with pytest.raises(BouncelabError, match="gamma must be a non-empty"):
        EvaluationPool(broken, 2)
    assert set(multiprocessing.active_children()) <= before


def test_no_generations_is_the_local_search_alone(problem):
    """maxiter 0 (a refinement too short for its evolution): no global search, the
    Nelder-Mead search from ``base`` alone, at most local_evals per free parameter, and
    its first evaluation is ``base`` itself."""
    settings = FitSettings(maxiter=0, local_evals=4)
    base = {"mu": 0.1, "e": 0.5}
    fit = fit_model(problem, "friction+restitution", base, settings=settings, seed=2)
    assert 2 < fit.n_evals <= 4 * 2
    np.testing.assert_allclose(fit.cloud_x[0], [0.1, 0.5])
    with_search = fit_model(
        problem,
        "friction+restitution",
        base,
        seed=2,
        settings=FitSettings(maxiter=1, popsize=1, local_evals=4),
    )
    assert with_search.n_evals > fit.n_evals


def test_several_draws_average_the_capped_gaps_of_shifted_ensembles(problem):
    """n_draws = 3 gives the mean over the ensembles shifted by 0, 1/3 and 2/3 of the
    member spacing of each one's capped gaps (the refinement's expected gap)."""
    model = Model.parse("restitution", {"e": 0.5})
    three = replace(problem, n_draws=3)
    draws = [problem.clipped(step_gaps(problem, model, shift=k / 3)) for k in range(3)]
    np.testing.assert_allclose(step_gaps(three, model), np.mean(draws, axis=0), atol=1e-12)
    # a shift moves every draw alike
    moved = [problem.clipped(step_gaps(problem, model, shift=0.5 + k / 3)) for k in range(3)]
    np.testing.assert_allclose(
        step_gaps(three, model, shift=0.5), np.mean(moved, axis=0), atol=1e-12
    )


def test_a_pool_evaluates_other_draws_of_its_problem(problem):
    """The refinement reuses the selection's pool: a task carries its n_draws, and the
    workers' numbers equal the in-process ones."""
    three = replace(problem, n_draws=3)
    params = [{"e": 0.3}, {"e": 0.5}]
    with EvaluationPool(problem, 2) as pool:
        pooled = [g for g, _n in pool.counted_gaps("restitution", params, n_draws=3)]
        assert pool.serves(three)
    for p, g in zip(params, pooled, strict=True):
        np.testing.assert_array_equal(g, step_gaps(three, Model.parse("restitution", p)))


def test_an_evaluation_pool_serves_only_its_problem(problem):
    other = make_problem(problem.run, problem.data_table, problem.duration_s, n_members=1)
    with EvaluationPool(problem, 2) as pool, pytest.raises(ValueError, match="another problem"):
        fit_model(other, "friction", pool=pool)


def test_feedback_search_shrinks_with_the_run_only_once_the_armature_is_fitted(
    problem, monkeypatch
):
    """fit_model passes the run's cycles to search_budget (which may then cut the extra
    feedback generations) only when the armature's values are already in ``base``: the
    first search of feedback keeps its whole budget."""
    from bouncelab.gap import fit

    seen = []
    real = fit.search_budget

    def spy(effects, settings, cycles=None):
        seen.append(cycles)
        return real(effects, settings, cycles)

    monkeypatch.setattr(fit, "search_budget", spy)
    small = FitSettings(popsize=1, maxiter=1, local_evals=1, max_population=4)
    armature = {"mass_ratio": 0.05, "f_ratio": 0.6, "zeta": 0.1, "ride_load": 0.0}
    fit_model(problem, "feedback", {}, fixed={"ride_load": 0.0}, settings=small)
    fit_model(problem, "friction+feedback", armature, fixed={"ride_load": 0.0}, settings=small)
    assert seen == [None, float(problem.protocol["cycles"].sum())]


def test_recheck_best_undoes_a_lucky_draw(problem):
    """recheck_best scores the fit's best evaluations on fresh ensembles and keeps the
    best of the pooled draws: a far-off point whose recorded gaps were made to look
    lucky (half the truth's) loses to the truth once its fresh draws are counted; the
    pool gives the same result as the process itself."""
    from bouncelab.gap.fit import FitResult, free_params, recheck_best

    two = replace(problem, n_draws=2)
    free = free_params(("restitution",))
    xs = np.array([[0.4], [0.6], [0.85]])  # the data's truth is e = 0.4
    gaps = np.array([step_gaps(two, Model.parse("restitution", {"e": x[0]})) for x in xs])
    gaps[2] = 0.5 * gaps[0]  # a lucky draw: better than the truth's
    w = two.weights * two.fit
    assert np.argmin(two.clipped(gaps) @ w) == 2  # the lucky point is the fit's best
    lucky = FitResult(
        model=Model.parse("restitution", {"e": 0.85}), free=free, objective=0.0,
        gaps=gaps[2], cloud_x=xs, cloud_gaps=gaps, n_evals=3, seconds=0.0,
    )  # fmt: skip
    checked = recheck_best(lucky, two, top=3)
    assert checked.model.params["e"] == pytest.approx(0.4)
    assert checked.n_evals == 6
    assert checked.objective == pytest.approx(two.mean(checked.gaps, two.fit))
    with EvaluationPool(two, 2) as pool:
        pooled = recheck_best(lucky, two, top=3, pool=pool)
    assert pooled.model.params == checked.model.params
    np.testing.assert_array_equal(pooled.gaps, checked.gaps)
    assert recheck_best(lucky, two, top=0) is lucky


def test_a_cut_protocol_still_tells_the_truth_from_a_wrong_model(tmp_path):
    """Long runs are fitted on a shorter protocol (fit.fit_protocol). Reference: the
    pseudo-data's generating model (restitution e = 0.4, 60 cycles a step). Cut to 40
    cycles a step (30 settled, fit.FIT_MIN_SETTLED), the truth's mean gap stays within
    1.5 times its uncut value plus 0.02 rad (measured: 0.047 -> 0.084), and below a model
    0.1 off in e and the ideal model; the fits simulate that many cycles."""
    from bouncelab.gap.fit import problem_cycles

    run_dir = write_run(tmp_path, cycles=60)
    truth = Model.parse("restitution", {"e": 0.4})
    run = load_run(run_dir)
    flights = pseudo_flights(run_dir, truth, seed=3, cycles=60)
    dur = duration_s(cycles=60)
    full = make_problem(run, flights, dur, n_members=3, max_cycles=None)
    cut = make_problem(run, flights, dur, n_members=3, max_cycles=40 * 20)
    assert problem_cycles(full) == 60 * 20 and problem_cycles(cut) == 40 * 20
    assert cut.steps.equals(full.steps)

    def gap(problem, model):
        return problem.mean(step_gaps(problem, model), problem.fit)

    g_truth = gap(cut, truth)
    assert g_truth <= 1.5 * gap(full, truth) + 0.02
    assert g_truth < gap(cut, Model.parse("restitution", {"e": 0.5}))
    assert g_truth < gap(cut, Model.parse("ideal"))


def test_a_finite_contact_in_the_data_is_read_and_put_in_the_model(tmp_path):
    """Pseudo-data of restitution 0.4 seen through contacts of 1.5 ms (3 samples of the
    2 kHz placeholder): the problem reads the contact time from the data's contacts
    (within 5 %), and the true model, read the same way, is closer to the data than the
    model with instantaneous contacts (the shift of every bounce's flight by 0.28 rad)."""
    from bouncelab.protocol import simulate_run

    run_dir = write_run(tmp_path)
    run = load_run(run_dir)
    truth = Model.parse("restitution", {"e": 0.4})
    contact = 2 * np.pi * 30.0 * 1.5e-3
    sim = simulate_run(run, truth, duration_s(), n_starts=2, seed=3, min_contact=contact)
    data = sim.loc[sim["start"] == 1].reset_index(drop=True)
    problem = make_problem(run, data, duration_s(), n_members=3)
    assert problem.min_contact == pytest.approx(contact, rel=0.05)
    with_contact = problem.mean(step_gaps(problem, truth), problem.fit)
    instantaneous = problem.mean(step_gaps(replace(problem, min_contact=0.0), truth), problem.fit)
    assert with_contact < 0.5 * instantaneous, (with_contact, instantaneous)


def test_an_evaluation_counts_the_flights_its_kernel_simulated(problem):
    """Reference: the flights of the same ensembles from ``protocol_flight_times`` with no
    contact rule (every kernel row: the work a diagnosis reports), one
    draw and three; the gaps are step_gaps' and the counts the same in a pool."""
    model = MODELS[1]
    gaps, flights = counted_step_gaps(problem, model)
    np.testing.assert_array_equal(gaps, step_gaps(problem, model))

    def kernel_flights(shift):
        sim = protocol_flight_times(
            model,
            problem.protocol["gamma"].to_numpy(),
            problem.protocol["cycles"].to_numpy(),
            settle_cycles=int(problem.run.settle_cycles),
            gamma_factors=1.0 + member_offsets(problem.n_members) + shift * MEMBER_SPREAD,
            chatter_eps=resolution_T(problem.run, CHATTER_SAMPLES),
        )
        return len(sim["T"])

    assert flights == kernel_flights(0.0) > 0
    three = replace(problem, n_draws=3)
    assert counted_step_gaps(three, model)[1] == sum(kernel_flights(k / 3) for k in range(3))
    buffer = OutputBuffer()
    counted_step_gaps(problem, model, buffer)
    counted_step_gaps(problem, model, buffer)
    assert buffer.flights == 2 * flights
    with EvaluationPool(problem, 2) as pool:
        pooled = pool.counted_gaps(model.name, [dict(model.params)] * 2)
    assert [n for _g, n in pooled] == [flights, flights]
