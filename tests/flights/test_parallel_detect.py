"""The parallel detection gives exactly (bit for bit) what the serial kernels give.

Reference: ``detect_serial`` below, the detection as the serial kernels
(``kernels.*_serial``) define it, arranged as the single-threaded code did before the
passes were cut into pieces.  Tolerance: none; every array of the Detection must be
equal to the last bit (``np.array_equal``), for any thread count and any piece length,
on synthetic signals (cuts inside flights, inside contacts, on glitches and on edges)
and on a virtual-rig recording with restitution chatter.
"""

import numpy as np
import pytest
from flights_synth import bouncing_contacts, continuity

from bouncelab.errors import BouncelabError
from bouncelab.flights import detect as D
from bouncelab.flights import detect_contacts
from bouncelab.flights import kernels as K

FS = 20_000.0
FIELDS = (
    "t_edge kind first_state contact_high open_v contact_v noise_v q d_prior n_glitch "
    "n_contact glitch_at block n_samples"
).split()


def detect_serial(x, contact_level="auto", rest=(), opened=(), block=D.BLOCK):
    """The serial definition of :func:`detect_contacts` (dict of the Detection fields)."""
    x = np.ascontiguousarray(x)
    D.check_transitions(x)
    lo0, hi0, _ = D.two_means(x)
    noise = D._robust_noise(x)
    assert hi0 - lo0 > D.MIN_SEPARATION * max(noise, 1e-12)
    lo_b, hi_b, frac_hi, sd_b = K.block_levels_serial(x, block, lo0, hi0, D.MIN_COUNT)
    lo, hi = D._fill_levels(lo_b, hi_b, lo0, hi0)
    high = D.decide_polarity(frac_hi, block, contact_level, rest, opened)
    open_v, contact_v = (lo, hi) if high else (hi, lo)
    gap = contact_v - open_v
    sd = np.where(np.isfinite(sd_b), sd_b, np.nanmedian(sd_b) if np.isfinite(sd_b).any() else 0)
    inv = 1.0 / gap
    r, slow = K.rc_ratios_serial(x[: D.PRIOR_SAMPLES], block, open_v, inv, 200_000)
    if r.size < 200 and x.shape[0] > D.PRIOR_SAMPLES:
        r, slow = K.rc_ratios_serial(x, block, open_v, inv, 200_000)
    r, slow = r[np.isfinite(r)], slow[np.isfinite(slow)]
    if r.size < 8:  # the slow front end's ratios only where no edge is clean
        r = np.concatenate([r, slow])
    q = float(np.median(r)) if r.size >= 8 else 0.0
    q = 0.0 if q < K.Q_MIN else min(q, 0.9)
    sdz = sd / np.abs(gap) * np.sqrt(1.0 + q * q) / (1.0 - q)
    args = (block, open_v, inv, sdz, q, D.THR_MIN, D.THR_MAX)
    t0, k0, *_ = K.detect_edges_serial(x[: D.PRIOR_SAMPLES], *args, 0.0, D.GLITCH_K)
    d_prior = D._short_contact_prior(t0, k0) if q > 0 else 0.0
    t, kind, n_glitch, n_contact, first, glitch_at = K.detect_edges_serial(
        x, *args, d_prior, D.GLITCH_K
    )
    if q == 0.0 and D.point_sampled(t):
        t = t + 0.5  # instants, not interval means: each edge in the middle of its interval
    return dict(
        t_edge=t, kind=kind, first_state=first, contact_high=high, open_v=open_v,
        contact_v=contact_v, noise_v=sd, q=q, d_prior=d_prior, n_glitch=n_glitch,
        n_contact=n_contact, glitch_at=glitch_at, block=block, n_samples=x.shape[0],
    )  # fmt: skip


def differing(det, ref):
    """Names of the Detection fields that are not bit-for-bit equal to the reference."""
    return [f for f in FIELDS if not np.array_equal(getattr(det, f), ref[f], equal_nan=True)]


def synthetic(tau_s, glitches=40, seconds=20.0, seed=3):
    """Bouncing contacts (15-45 us), chatter, long rests; 0.3 V drift; +-3 V spikes."""
    c = bouncing_contacts(seconds, seed=2)
    x, gidx = continuity(
        c, seconds, tau_s=tau_s, noise_v=0.02, drift_v=0.3, glitches=glitches, seed=seed
    )
    return x, gidx, c


@pytest.fixture(scope="module")
def signals():
    """RC 25 us (glitch rule (b) active), 10 us (the rig's), none (box model)."""
    return {tau: synthetic(tau) for tau in (25e-6, 10e-6, 0.0)}


@pytest.mark.parametrize("tau_s", [25e-6, 10e-6, 0.0])
@pytest.mark.parametrize("n_threads,piece", [(1, None), (2, None), (2, 997), (3, 20_011)])
def test_identical_to_serial_synthetic(signals, monkeypatch, tau_s, n_threads, piece):
    """Any thread count and piece length (997 samples: some 400 cuts, many inside
    flights, contacts and chatter), with the prior learnt on a prefix that ends inside
    the recording (PRIOR_SAMPLES lowered to 150001 so the head pass is exercised)."""
    monkeypatch.setattr(D, "PRIOR_SAMPLES", 150_001)
    x, _, _ = signals[tau_s]
    ref = detect_serial(x)
    det = detect_contacts(x, n_threads=n_threads, piece=piece)
    assert differing(det, ref) == []
    assert det.t_edge.size > 1000  # the comparison covers many edges
    if tau_s > 0:
        assert det.d_prior > 0  # and pulses placed with a learnt prior


def edge_params(x):
    """The parameters the edge pass gets in detect_contacts, for a direct comparison."""
    det = detect_contacts(x)
    gap = det.contact_v - det.open_v
    sdz = det.noise_v / np.abs(gap) * np.sqrt(1.0 + det.q**2) / (1.0 - det.q)
    return det, (det.block, det.open_v, 1.0 / gap, sdz, det.q, D.THR_MIN, D.THR_MAX, 0.0, 6.0)


@pytest.mark.parametrize("warmup", [D.EDGE_WARMUP, 0])
def test_edge_pass_cut_on_glitches_edges_contacts_and_flights(signals, monkeypatch, warmup):
    """Cuts placed on purpose: at each glitch and its neighbours, at the samples on both
    sides of edges, in the middle of contacts and of flights.  Without warm-up many
    pieces start from a wrong guess (at a glitch, inside a contact) and are rerun from
    the true state: the rerun path is exercised and the result is still exact."""
    monkeypatch.setattr(D, "EDGE_WARMUP", warmup)
    x, gidx, contacts = signals[25e-6]
    det, params = edge_params(x)
    te = det.t_edge
    cuts = set()
    for g in gidx:
        cuts |= {int(g) - 1, int(g), int(g) + 1, int(g) + 2}
    for t in te[::7]:
        cuts |= {int(np.ceil(t)), int(np.ceil(t)) + 1}
    mids = 0.5 * (te[:-1] + te[1:])  # alternately inside contacts and inside flights
    cuts |= {int(m) for m in mids[::5]}
    ref_t, ref_k, ref_ng, ref_nc, ref_first, ref_g = K.detect_edges_serial(x, *params)
    with D.Parallel(2) as par:
        results, pieces, starts = par.edges(x, params, cuts=sorted(cuts))
        reruns = par.reruns
    assert len(pieces) > 1000
    assert np.array_equal(np.concatenate([r[0] for r in results]), ref_t)
    assert np.array_equal(np.concatenate([r[1] for r in results]), ref_k)
    assert np.array_equal(np.concatenate([r[2] for r in results])[:4096], ref_g)
    assert starts[0][0] == ref_first
    n_glitch = np.zeros_like(ref_ng)
    for (a, _), r in zip(pieces, results, strict=True):
        n_glitch[a // det.block : a // det.block + r[3].size] += r[3]
    assert np.array_equal(n_glitch, ref_ng)
    print(f"warm-up {warmup}: {len(pieces)} pieces, {reruns} rerun")
    if warmup == 0:
        assert reruns > 0


def test_pulses_placed_again_as_a_second_serial_pass(signals):
    """Placing the one-interval contacts again with a prior (place_pulses) gives the
    serial pass run with that prior, edge for edge (reference: detect_edges_serial)."""
    x, _, _ = signals[25e-6]
    det, params = edge_params(x)
    res = K.edge_range(x, 1, x.shape[0], det.first_state, K.u_at(x, 0, *params[:3]), *params)
    t = res[0].copy()
    assert res[7].size > 100  # many contacts lie wholly inside one interval
    for d_prior in (0.3, det.d_prior, 0.9):
        K.place_pulses(t, res[7], res[8], res[9], det.q, d_prior)
        want = K.detect_edges_serial(x, *params[:7], d_prior, params[8])[0]
        assert np.array_equal(t, want)


def test_block_levels_runs(signals):
    """Levels by runs of blocks, replayed: equal to block_levels_serial for drifting
    levels, a level absent for many blocks (long rest), few-sample blocks, and crossed
    starting levels (the plain path)."""
    x, _, _ = signals[25e-6]
    rest = np.concatenate([np.full(200_000, 0.01), x])  # 10 s in contact first
    rest[:200_000] += 0.02 * np.random.default_rng(1).standard_normal(200_000)
    lo0, hi0, _ = D.two_means(x)
    for sig, block, lo, hi in (
        (x, 4096, lo0, hi0),
        (rest, 4096, lo0, hi0),
        (x[:5000], 64, lo0, hi0),
        (x, 4096, hi0, lo0),
    ):
        ref = K.block_levels_serial(sig, block, lo, hi, D.MIN_COUNT)
        for n_threads, piece in ((1, None), (2, None), (3, 7 * block)):
            with D.Parallel(n_threads, piece) as par:
                got, _ = par.block_levels(sig, block, lo, hi, D.MIN_COUNT)
            for a, b in zip(got, ref, strict=True):
                assert np.array_equal(a, b, equal_nan=True)


@pytest.mark.parametrize("tau_s", [25e-6, 100e-6])
def test_rc_ratios_pieces(tau_s):
    """RC ratios scanned in pieces, concatenated and cut: the serial kernel's lists
    (strict and slow), with and without the cut to max_out taking effect."""
    c = bouncing_contacts(6.0, seed=5)
    x, _ = continuity(c, 6.0, tau_s=tau_s, noise_v=0.01, seed=6)
    det = detect_contacts(x)
    gap = det.contact_v - det.open_v
    for max_out in (200_000, 20):
        ref = K.rc_ratios_serial(x, det.block, det.open_v, 1.0 / gap, max_out)
        assert max(ref[0].size, ref[1].size) >= 20
        with D.Parallel(2, 3001) as par:
            got = par.rc_ratios(x, 0, x.shape[0], det.block, det.open_v, 1.0 / gap, max_out)
        assert np.array_equal(got[0], ref[0]) and np.array_equal(got[1], ref[1])


@pytest.mark.parametrize(
    "make",
    [
        lambda x: np.full(x.size, 9.99969),
        lambda x: np.where(np.arange(x.size) < 0.995 * x.size, 10.0, x),
        lambda x: np.where(np.arange(x.size) > 0.004 * x.size, -1.0, x),
        lambda x: np.where(np.arange(x.size) < 0.98 * x.size, 10.0, x),
    ],
)
def test_rail_check_from_block_extremes(signals, make):
    """The stuck-rail check from the per-block extremes says what the full check says
    (same error message, or none)."""
    x = make(signals[25e-6][0][:300_000].copy())

    def outcome(fn):
        try:
            fn()
        except BouncelabError as e:
            return str(e)
        return None

    with D.Parallel(2) as par:
        _, rec = par.block_levels(x, D.BLOCK, float(x.min()), float(x.max()), D.MIN_COUNT)
    ext = (*K.block_extremes(rec), D.BLOCK)
    want = outcome(lambda: D.check_transitions(x, "rec.npz"))
    assert outcome(lambda: D.check_transitions(x, "rec.npz", ext)) == want


def test_identical_to_serial_on_rig_recording(make_rig):
    """A virtual-rig sweep with restitution chatter (e = 0.515) and the rig's noise:
    detect_contacts on the recorded channel equals the serial definition."""
    from bouncelab.runs import load_run, read_recording

    cfg = {
        "kind": "sweep",
        "seed": 21,
        "body": {"restitution": 0.515},
        "protocol": {"gammas": [0.5, 1.6, 2.8, 4.2], "cycles_per_step": 30},
    }
    run_dir, _ = make_rig("parallel_e0515", cfg)
    x = read_recording(load_run(run_dir), roles=("continuity",)).channels["continuity"]
    ref = detect_serial(x)
    for n_threads, piece in ((2, None), (2, 1009)):
        det = detect_contacts(x, n_threads=n_threads, piece=piece)
        assert differing(det, ref) == []
    assert det.t_edge.size > 500


def test_held_levels_cut_anywhere_read_as_serial():
    """Held levels (a contact that half-conducts: :func:`kernels._held_reading` reads up to
    three intervals on each side of the sample) with cuts at every sample of each hold
    and around it, without warm-up: the serial pass's edges, bit for bit."""
    from test_detect import held_in_longest_flights

    c = bouncing_contacts(4.0, seed=4)
    held, starts = held_in_longest_flights(c, 0.4, hold_s=1e-3, count=4)
    x, _ = continuity(held, 4.0, tau_s=25e-6, noise_v=0.01, seed=5)
    det, params = edge_params(x)
    cuts = sorted({int(a * FS) + j for a in starts for j in range(-5, 26)})
    ref_t, ref_k, *_ = K.detect_edges_serial(x, *params)
    for warmup in (0, D.EDGE_WARMUP):
        D_warm = D.EDGE_WARMUP
        try:
            D.EDGE_WARMUP = warmup
            with D.Parallel(2) as par:
                results, _, _ = par.edges(x, params, cuts=cuts)
        finally:
            D.EDGE_WARMUP = D_warm
        assert np.array_equal(np.concatenate([r[0] for r in results]), ref_t)
        assert np.array_equal(np.concatenate([r[1] for r in results]), ref_k)
    s, e = det.contacts()
    assert sum(((e / FS > a) & (s / FS < a + 1e-3)).sum() for a in starts) == len(starts)
