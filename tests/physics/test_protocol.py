"""The lab protocol and ensembles."""

import math

import numpy as np
import pytest

from bouncelab.errors import BouncelabError
from bouncelab.physics import Model, simulate_grid, simulate_protocol
from bouncelab.physics import kernels as K

TWO_PI = 2 * math.pi


def test_single_step_protocol_equals_grid():
    # one step from rest at phase 0 is the grid run cut at the step's end: identical flights
    m = Model.parse("friction+restitution", {"mu": 0.2, "e": 0.4})
    prot = simulate_protocol(m, [2.7], [80], settle_cycles=0)
    grid = simulate_grid(m, [2.7], len(prot))
    assert np.array_equal(prot["T"].to_numpy(), grid["T"].to_numpy())
    # every flight of the protocol lands before the last step ends
    assert (prot["t_takeoff"] + prot["T"]).max() <= 80 * TWO_PI


def test_steps_settle_and_carry_state():
    gammas, cycles, settle = [1.5, 3.5, 3.6, 2.0], [40, 60, 50, 30], 10
    df = simulate_protocol(Model.parse("ideal"), gammas, cycles, settle_cycles=settle)
    ends = np.cumsum(cycles) * TWO_PI
    starts = np.concatenate([[0.0], ends[:-1]])
    step = df["step"].to_numpy()
    # the step of a row is where its takeoff lies; gamma is that step's stated Gamma
    assert np.all(df["t_takeoff"] >= starts[step]) and np.all(df["t_takeoff"] < ends[step])
    assert np.allclose(df["gamma"], np.array(gammas)[step])
    # settled is False exactly for takeoffs within the first `settle` cycles of a step
    expect = df["t_takeoff"].to_numpy() >= starts[step] + settle * TWO_PI
    assert np.array_equal(df["settled"].to_numpy(), expect)
    assert np.all(np.diff(df["t_takeoff"]) > 0)
    assert set(step) == {0, 1, 2, 3}
    # the state carries over: at Gamma 3.5 the body is locked in the bouncing region and
    # never rides, so step 2 (3.6) starts from that orbit, not from rest (compare with
    # step 2 run alone from rest, whose first flight leaves the line arcsin(1/3.6))
    alone = simulate_protocol(Model.parse("ideal"), [3.6], [50])
    assert alone["phi_takeoff"].iloc[0] == pytest.approx(math.asin(1 / 3.6), abs=1e-12)
    carried = df[df["step"] == 2]
    assert not np.isclose(carried["T"].iloc[0], alone["T"].iloc[0])
    assert carried["t_takeoff"].iloc[0] - starts[2] < TWO_PI  # no wait for a fresh start
    # settled flights of the locked step (Gamma 3.6) have T = 2 pi after the transient
    inside = df["t_takeoff"] + df["T"] < ends[2]  # landed before Gamma changed again
    locked = df[(df["step"] == 2) & df["settled"] & inside]["T"].to_numpy()[-5:]
    assert np.allclose(locked, TWO_PI, atol=1e-6)


def test_batch_order_does_not_matter():
    # run_many hands trajectories to threads in a spread order (a permutation); each
    # depends on its own inputs only, so a Gamma alone gives the flights it gives in a batch
    m = Model.parse("harmonic+feedback")
    gam = np.linspace(1.5, 7.5, 13)
    batch = simulate_grid(m, gam, 50)
    for g in gam[[0, 5, 12]]:
        alone = simulate_grid(m, [g], 50)["T"].to_numpy()
        assert np.array_equal(alone, batch[batch["gamma"] == g]["T"].to_numpy())
    for n in range(1, 300):
        order = (np.arange(n) * K.spread_stride(n)) % n
        assert np.array_equal(np.sort(order), np.arange(n))


@pytest.mark.parametrize(("name", "gamma"), [("ideal", 4.0), ("ideal", 6.45), ("harmonic", 2.5)])
def test_step_to_the_same_gamma_changes_nothing(name, gamma):
    # a flight in the air at a step boundary flies on (its landing search restarts there,
    # also from above the plate's range at 6.45, where T = 4 pi): the flights equal those
    # of one step of the same length to rounding (periodic orbits, no amplification)
    m = Model.parse(name)
    two = simulate_protocol(m, [gamma, gamma], [40, 40], settle_cycles=0)
    one = simulate_protocol(m, [gamma], [80], settle_cycles=0)
    start, end = two["t_takeoff"].to_numpy(), (two["t_takeoff"] + two["T"]).to_numpy()
    assert np.any((start < 40 * TWO_PI) & (end > 40 * TWO_PI))  # one crosses the boundary
    assert len(two) == len(one)
    assert np.allclose(two["T"], one["T"], rtol=0, atol=1e-12)


def test_history_matters_under_the_protocol():
    # sweeping up into the period-doubled range vs jumping there: both valid flights,
    # and the table records which step each flight belongs to
    m = Model.parse("ideal")
    up = simulate_protocol(m, [3.0, 3.5, 3.9], [50, 50, 50])
    jump = simulate_protocol(m, [3.9], [150])
    assert len(up) > 0 and len(jump) > 0
    assert up["flight"].is_monotonic_increasing


def test_ensemble_of_starts_is_seeded():
    m = Model.parse("restitution", {"e": 0.3})
    a = simulate_grid(m, [2.2, 4.1], 20, n_starts=4, seed=7)
    b = simulate_grid(m, [2.2, 4.1], 20, n_starts=4, seed=7)
    c = simulate_grid(m, [2.2, 4.1], 20, n_starts=4, seed=8)
    assert a.equals(b)
    assert not a.equals(c)
    assert sorted(a["start"].unique()) == [0, 1, 2, 3]
    p = simulate_protocol(m, [2.2, 4.1], [30, 30], n_starts=3, seed=1)
    assert sorted(p["start"].unique()) == [0, 1, 2]


def test_given_start_phases():
    # a start phase inside the bouncing region takes off at once from there
    df = simulate_grid(Model.parse("ideal"), [3.0], 1, phi_start=[1.0, 2.0])
    assert np.allclose(df["phi_takeoff"], [1.0, 2.0])


@pytest.mark.parametrize(
    ("gammas", "cycles"), [([1.0, 2.0], [10]), ([1.0], [0]), ([1.0], [2.5]), ([-1.0], [3])]
)
def test_bad_protocol_is_refused(gammas, cycles):
    with pytest.raises(BouncelabError):
        simulate_protocol(Model.parse("ideal"), gammas, cycles)


def test_chatter_heavy_protocol_grows_its_buffer():
    # e = 0.8 at Gamma 1.1 chatters to sticking every cycle, ~7 flights per cycle:
    # more rows than the first guess of 4 per cycle + 64
    m = Model.parse("restitution", {"e": 0.8})
    df = simulate_protocol(m, [1.1], [20])
    assert len(df) > 4 * 20 + 64
    assert df["chatter"].any()


#: The four-step protocol of the kernel-column tests: Gamma and cycles per step.
GAMMAS_4 = np.array([1.8, 2.6, 3.4, 4.2])
CYCLES_4 = np.array([30, 30, 30, 30])


def _kernel_columns(model, setting: int, value: float, fill: float = 0.0) -> np.ndarray:
    """The kernel's written columns, shape (NCOL, rows), for one trajectory of ``model``
    through Gamma 1.8-4.2 (4 steps of 30 cycles, 5 settle) with ``par[setting] = value``
    and the buffer filled with ``fill`` beforehand."""
    from bouncelab.physics.simulate import _protocol_steps, kernel_params

    g, step_end = _protocol_steps(GAMMAS_4, CYCLES_4, 5)
    hk, ha, hp = model.harmonic_arrays()
    max_rec = int(32 * step_end[-1] + 64)
    par = kernel_params(model)
    par[setting] = value
    out = np.full((K.NCOL, max_rec), fill)
    (rows,), (status,) = K.run_many(
        par, hk, ha, hp, model.gamma_true(g)[None, :], g[None, :], step_end, True,
        np.zeros(1), np.zeros(1), np.zeros(1), 0, max_rec, 5, np.zeros(1), out,
    )  # fmt: skip
    assert status != K.ST_FULL and rows > 100
    return out[:, :rows]


@pytest.mark.parametrize(
    "name, params",
    [
        ("friction+harmonic", {"mu": 0.2, "k": 2.0, "a": 0.05, "psi": 1.0}),
        (
            "friction+restitution+feedback",
            {"mu": 0.2, "e": 0.4, "mass_ratio": 0.1, "f_ratio": 0.4, "zeta": 0.2, "ride_load": 1.0},
        ),
    ],  # fmt: skip
)
def test_the_fits_kernel_skips_only_the_energy_of_rides(name, params):
    """``protocol_flight_times`` (every fit's evaluation) runs the kernel without
    friction's ride term (``P_ENERGY`` 0), which on a plate that is not a pure sine costs
    a walk between the plate's turning points. Reference: the full kernel, bit for bit
    for the flights (times, phases, states, steps); the friction loss does differ, so the
    term was skipped."""
    from bouncelab.physics.simulate import protocol_flight_times

    model = Model.parse(name, params)
    cols = {energy: _kernel_columns(model, K.P_ENERGY, energy) for energy in (1.0, 0.0)}
    dynamics = [K.C_T, K.C_PHI0, K.C_PHIL, K.C_VIMP, K.C_TTO, K.C_X0, K.C_V0, K.C_STEP]
    np.testing.assert_array_equal(cols[0.0][dynamics], cols[1.0][dynamics])
    assert cols[0.0][K.C_EFRIC].sum() < cols[1.0][K.C_EFRIC].sum()
    fits = protocol_flight_times(model, GAMMAS_4, CYCLES_4, 5)
    np.testing.assert_array_equal(fits["T"], cols[1.0][K.C_T])


def test_the_fits_kernel_writes_only_the_columns_the_fits_read():
    """With ``P_ALLCOLS`` 0 (``protocol_flight_times``, every fit's evaluation) the kernel
    writes only ``FIT_COLUMNS``, the same bits as the full kernel's; every other column
    keeps what the buffer held (here NaN). Reference: the full kernel on the same
    trajectory (restitution with a harmonic: chatter, rides and a non-sine plate)."""
    model = Model.parse("restitution+harmonic", {"e": 0.4, "k": 2.0, "a": 0.05, "psi": 1.0})
    cols = {a: _kernel_columns(model, K.P_ALLCOLS, a, np.nan) for a in (1.0, 0.0)}
    fit = list(K.FIT_COLUMNS)
    np.testing.assert_array_equal(cols[0.0][fit], cols[1.0][fit])
    others = [c for c in range(K.NCOL) if c not in K.FIT_COLUMNS]
    assert np.isnan(cols[0.0][others]).all()
    assert not np.isnan(cols[1.0]).any()


def test_a_flight_the_change_of_gamma_catches_is_not_settled():
    # a 3rd harmonic puts the takeoff 0.07 rad before each 40-cycle step ends; the instant
    # amplitude change (the plate's velocity jumps by Delta Gamma) catches the body there
    m = Model.parse("friction+harmonic", {"mu": 0.2, "k": 3.0, "a": 0.05, "psi": 1.0})
    gammas, cycles = [4.6, 4.7, 4.8, 4.9, 5.0], [40] * 5
    df = simulate_protocol(m, gammas, cycles, settle_cycles=10)
    ends = np.cumsum(cycles) * TWO_PI
    landing = (df["t_takeoff"] + df["T"]).to_numpy()
    caught = np.abs(landing - ends[df["step"].to_numpy()]) < K.CAUGHT
    assert caught.sum() == 4  # at every change of Gamma
    assert np.all(df["T"].to_numpy()[caught] < 0.1)
    assert not df["settled"].to_numpy()[caught].any()
    # the settled flights are the orbits' alone (2.97 rad and longer)
    assert df.loc[df["settled"], "T"].min() > 1.0
    # a flight across a change that lands later is kept, as a measured one is
    gammas, cycles = [1.5, 3.5, 3.6, 2.0], [40, 60, 50, 30]
    df = simulate_protocol(Model.parse("ideal"), gammas, cycles, settle_cycles=10)
    ends = np.cumsum(cycles) * TWO_PI
    across = (df["t_takeoff"] + df["T"]).to_numpy() > ends[df["step"].to_numpy()] + K.CAUGHT
    assert across.any() and df["settled"].to_numpy()[across].all()
