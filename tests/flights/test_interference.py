"""Mains hum on the continuity channel: found, subtracted, and left alone when absent.

Truth: the synthetic contacts of flights_synth.py through an exact RC filter; the hum is
added in volts.  The reference for "as good as without hum" is the same signal without
it, detected the same way; tolerances are stated per test.
"""

import numpy as np
import pytest
from flights_synth import bouncing_contacts, continuity
from test_detect import match

import bouncelab.flights.interference as interference
from bouncelab.flights import detect_contacts
from bouncelab.flights.interference import (
    GATE_REL,
    GUARD_MIN,
    LINE_APART_S,
    LINE_BLOCK_S,
    MIN_RATIOS,
    fast_interference,
    find_lines,
    guard_samples,
    remove_interference,
)

GAP_V = 5.0


def hum(n, fs, amp_v, f_hz=50.0, third=0.0, phase=0.3):
    """Mains hum, volts: a sine at ``f_hz`` plus ``third`` of its third harmonic."""
    t = np.arange(n) / fs
    return amp_v * (np.sin(2 * np.pi * f_hz * t + phase) + third * np.sin(6 * np.pi * f_hz * t))


@pytest.mark.parametrize(
    "fs,f_hz,amp_rel,third",
    [(20_000.0, 50.0, 0.10, 0.0), (8_000.0, 60.0, 0.06, 0.3), (44_100.0, 50.0, 0.08, 0.0)],
)
def test_hum_is_subtracted_and_the_flights_come_back(fs, f_hz, amp_rel, third):
    """A hum of 3-10 % of the level gap: without the correction flights are lost (the
    test can fail); with it the share found and the errors are those of the hum-free
    signal within 0.5 % of flights and 2 us of median error (reference: the same contacts
    without hum), and the reported rms is the hum's within 10 %."""
    c = bouncing_contacts(10.0, seed=2)
    kw = dict(fs=fs, tau_s=25e-6, open_v=GAP_V, contact_v=0.0, noise_v=0.005, seed=3)
    x0, _ = continuity(c, 10.0, drift_v=0.2, **kw)
    h = hum(x0.shape[0], fs, amp_rel * GAP_V, f_hz, third)
    x = x0 + h
    ref = detect_contacts(x0, sample_rate_hz=fs)
    err0, found0, _, _ = match(ref, c, fs=fs)
    bare = detect_contacts(x)  # no sampling rate: no correction
    _, found_bare, _, _ = match(bare, c, fs=fs)
    det = detect_contacts(x, sample_rate_hz=fs)
    err, found, n_det, n_true = match(det, c, fs=fs)
    rms = float(np.median(det.interference_v))
    print(
        f"fs {fs:.0f} hum {amp_rel:.2f}: found {found_bare:.4f} bare, {found:.4f} corrected, "
        f"{found0:.4f} hum-free; median {np.median(err) * 1e6:.2f} us "
        f"({np.median(err0) * 1e6:.2f}); rms {rms:.4f} V (true {np.std(h):.4f})"
    )
    assert found_bare < found0 - 0.01
    assert found >= found0 - 0.005
    assert np.median(err) < np.median(err0) + 2e-6
    assert rms == pytest.approx(np.std(h), rel=0.1)


@pytest.mark.parametrize("open_rel,contact_rel", [(0.10, 0.0), (0.0, 0.10), (0.10, 0.02)])
def test_hum_on_one_level_is_estimated_per_level(monkeypatch, open_rel, contact_rel):
    """An open circuit (a high impedance) picks up hum that a closed one does not: a
    50 Hz hum of 10 % of the gap on one level only (or 10 % and 2 %).  Each level's own
    estimate finds every flight of the hum-free detection within 0.5 % and its median
    error within 2 us; one estimate from both levels (the test can fail) is worse."""
    fs = 20_000.0
    c = bouncing_contacts(10.0, seed=2)
    kw = dict(fs=fs, tau_s=25e-6, open_v=GAP_V, contact_v=0.0, noise_v=0.005, seed=3)
    x0, _ = continuity(c, 10.0, **kw)
    is_open = x0 > 0.5 * GAP_V
    x = x0 + hum(x0.shape[0], fs, GAP_V, 50.0) * np.where(is_open, open_rel, contact_rel)
    err0, found0, _, _ = match(detect_contacts(x0, sample_rate_hz=fs), c, fs=fs)
    err, found, _, _ = match(detect_contacts(x, sample_rate_hz=fs), c, fs=fs)
    monkeypatch.setattr(interference, "hum_per_state", lambda _rms: False)
    err_one, found_one, _, _ = match(detect_contacts(x, sample_rate_hz=fs), c, fs=fs)
    print(
        f"open {open_rel} contact {contact_rel}: found {found:.4f} per level, {found_one:.4f}"
        f" one estimate, {found0:.4f} hum-free; median {np.median(err) * 1e6:.2f} us"
        f" ({np.median(err_one) * 1e6:.2f}, {np.median(err0) * 1e6:.2f})"
    )
    assert found >= found0 - 0.005
    assert np.median(err) < np.median(err0) + 2e-6
    assert found_one < found - 0.005 or np.median(err_one) > np.median(err) + 2e-6


def test_the_levels_share_one_estimate_when_their_hum_is_alike():
    """The decision between one estimate and one per level: alike rms (a hum on the
    whole channel, 0.2 and 0.25 V) share one; one level at less than half the other's
    has its own."""
    assert not interference.hum_per_state([0.2, 0.25])
    assert interference.hum_per_state([0.01, 0.35])
    assert interference.hum_per_state([0.35, 0.07])


@pytest.mark.parametrize("fs", [8_000.0, 20_000.0, 44_100.0])
@pytest.mark.parametrize("tau_s", [0.0, 25e-6, 150e-6, 400e-6])
def test_a_clean_channel_is_left_alone_bit_for_bit(fs, tau_s):
    """No hum, drift, noise, RC front ends from none to 400 us: the gate does not fire,
    so the edges are those of a detection that never looked (bit for bit)."""
    c = bouncing_contacts(6.0, seed=5)
    x, _ = continuity(c, 6.0, fs=fs, tau_s=tau_s, noise_v=0.01, drift_v=0.3, seed=6)
    det = detect_contacts(x, sample_rate_hz=fs)
    assert not det.interference_v.any()
    assert np.array_equal(det.t_edge, detect_contacts(x).t_edge)


def test_the_estimate_is_the_hum_and_not_the_levels_or_the_edges():
    """The fast estimate on a slow RC front end (150 us) with short contacts follows the
    hum within 3 % of its amplitude plus 1 mV (rms over the samples used); without hum
    it stays below the gate's floor (``GATE_REL`` of the gap): neither the levels' own
    errors nor the RC tails pass for interference."""
    fs = 20_000.0
    c = bouncing_contacts(3.0, seed=7)
    x, _ = continuity(c, 3.0, fs=fs, tau_s=150e-6, noise_v=0.005, seed=8)
    h = hum(x.shape[0], fs, 0.05 * GAP_V)
    for signal, truth in ((x + h, h), (x, np.zeros_like(h))):
        fast, used = fast_interference(signal, 0.0, GAP_V, 0.005, fs, guard=20)
        core = slice(4000, -4000)  # away from the ends of the slow window
        dev = (fast - truth)[core][used[core]]
        assert np.sqrt(np.mean(dev**2)) < 0.03 * 0.05 * GAP_V + 1e-3
    fast, used = fast_interference(x, 0.0, GAP_V, 0.005, fs, guard=20)
    assert np.sqrt(np.mean(fast[used] ** 2)) < GATE_REL * GAP_V


def test_remove_returns_the_input_untouched_when_clean():
    """Nothing to subtract: the very array comes back (no copy), and the rms are zeros."""
    c = bouncing_contacts(2.0, seed=9)
    x, _ = continuity(c, 2.0, noise_v=0.01, seed=10)
    out, rms = remove_interference(x, 0.0, GAP_V, 0.01, 20_000.0, 4096)
    assert out is x
    assert rms.shape == (-(-x.shape[0] // 4096),) and not rms.any()


def test_extract_corrects_a_humming_run_and_reports_it_in_the_qc(tmp_path):
    """Through ``bouncelab extract`` (the pipeline's path, which passes the sampling
    rate): a 60 Hz hum of 8 % of the gap; every flight of the truth comes out, and the QC
    table's ``interference_v`` is the hum's rms within 10 % on both steps."""
    from flights_synth import write_npz_run

    from bouncelab.cli import main
    from bouncelab.tables import read_table

    fs = 20_000.0
    c = bouncing_contacts(4.0, seed=11)
    x, _ = continuity(c, 4.0, fs=fs, tau_s=25e-6, noise_v=0.005, seed=12)
    h = hum(x.shape[0], fs, 0.08 * GAP_V, f_hz=60.0)
    run = write_npz_run(
        tmp_path / "hum",
        {"continuity": x + h},
        kind="sweep",
        drive_frequency_hz=30.0,
        gamma_steps=[{"t_s": 0.0, "gamma": 3.0}, {"t_s": 2.0, "gamma": 3.5}],
    )
    out = tmp_path / "flights.parquet"
    assert main(["extract", str(run), "-o", str(out)]) == 0
    assert len(read_table(out)) == len(c) - 1
    qc = read_table(tmp_path / "flights.qc.parquet")
    assert qc["interference_v"].to_numpy() == pytest.approx(np.full(2, np.std(h)), rel=0.1)


@pytest.mark.parametrize("amp_rel", [0.05, 0.08])
def test_hum_beside_a_slow_drift_of_the_levels(amp_rel):
    """A hum of 5-8 % of the gap beside a slow drift of 30 % of it (a warming circuit,
    the levels moving 1.5 V over 36 s on a 5 V gap; a second black-box probe's case).
    The drift put the residuals from the global levels beyond a quarter of the gap and
    the RC decay ratios near 1 (the guard after each crossing 618 samples): the hum went
    unestimated in half the steps and 72-125 of 899 flights were lost. Reference: the
    same contacts with the drift and no hum; found within 0.5 %, median error within
    2 us."""
    fs, seconds = 20_000.0, 36.0
    c = long_contacts_with_chatter(seconds)
    kw = dict(fs=fs, tau_s=25e-6, open_v=GAP_V, contact_v=0.0, noise_v=0.02, seed=3)
    x0, _ = continuity(c, seconds, **kw)
    t = np.arange(x0.shape[0]) / fs
    x0 = x0 + 0.3 * GAP_V * np.sin(2 * np.pi * t / seconds)
    x = x0 + hum(x0.shape[0], fs, amp_rel * GAP_V)
    err0, found0, _, _ = match(detect_contacts(x0, sample_rate_hz=fs), c, fs=fs)
    err, found, n_det, n_true = match(detect_contacts(x, sample_rate_hz=fs), c, fs=fs)
    print(f"hum {amp_rel}: found {found:.4f} ({found0:.4f} without hum), {n_det}/{n_true}")
    assert found >= found0 - 0.005
    assert n_det <= n_true * 1.005  # no fragments
    assert np.median(err) < np.median(err0) + 2e-6


def long_contacts_with_chatter(seconds, seed=6):
    """One contact of 3-12 ms a cycle of 1/25 s (a body riding a 25 Hz plate)."""
    rng = np.random.default_rng(seed)
    out, t = [], 0.01
    while t < seconds - 0.06:
        d = rng.uniform(3e-3, 12e-3)
        out.append((t, t + d))
        t += 0.04
    return out


def rig_sweep(make_rig, restitution, rc_s):
    """The lab-artefact benchmark's sweep (Gamma 0.5-4.2 in 7 steps of 60 cycles at 30 Hz,
    20 kHz): ``(continuity volts (n,), sample rate, truth path)``."""
    from bouncelab.runs import read_recording

    cfg = {
        "kind": "sweep",
        "seed": 3,
        "body": {"restitution": restitution},
        "protocol": {"gammas": [0.5, 1.2, 1.6, 2.2, 2.8, 3.4, 4.2], "cycles_per_step": 60},
        "recording": {"sample_rate_hz": 20_000.0},
        "sensors": {"continuity": {"rc_time_s": rc_s}},
    }
    run_dir, truth = make_rig(f"sweep_e{restitution:g}_rc{rc_s * 1e6:g}us", cfg)
    rec = read_recording(run_dir)
    return np.asarray(rec.channels["continuity"], dtype=np.float64), rec.fs, truth


def estimate_error(x, h, fs):
    """rms (volts) of what :func:`remove_interference` subtracts from ``x`` minus ``h``."""
    from bouncelab.flights import detect

    s = detect._subsample(x)
    lo, hi, _ = detect.two_means(s)
    out, _ = remove_interference(x, lo, hi, detect._robust_noise(s), fs, detect.BLOCK)
    return float(np.std((x - out) - h))


def test_hum_on_a_bouncing_body_through_a_fast_front_end(make_rig):
    """A bouncing body (e 0.5, Gamma 1.2-4.2) on a fast front end (RC 10 us, a fifth of a
    sample), scaled as after a gain step (0.35 of the gap, +0.5 V: the right side of the
    lab-artefact benchmark's jump0.27 case), under a 50 Hz hum of 0.1 V (6 % of the gap):
    few crossings land mid-sample, and one chatter ratio (3.4) once stood for the RC
    decay, the guard grew to 620 samples and the hum was left in (estimate minus truth:
    72 mV rms, the hum's own 71). Reference: the hum added; the estimate within 10 % of
    its rms (measured 5 % with the running mean, 0.7 % with the lines)."""
    c, fs, _ = rig_sweep(make_rig, 0.5, 10e-6)
    c = c[int(0.27 * c.shape[0]) :]
    h = hum(c.shape[0], fs, 0.1)
    miss = estimate_error(0.35 * c + 0.5 + h, h, fs)
    print(f"estimate minus hum: {miss * 1e3:.1f} mV rms (hum {np.std(h) * 1e3:.1f})")
    assert miss < 0.1 * np.std(h)


def test_a_60_hz_hum_with_its_third_harmonic_among_dense_edges(make_rig):
    """The inelastic body (it rests, rides and chatters) through a slow front end (RC 100
    us: the guard after each crossing is 14 samples) under a 60 Hz hum of 10 % of the
    gap with a third harmonic of 0.3. The running mean bridged the edges' neighbourhoods
    by straight lines spanning much of a 180 Hz period: 62 mV rms off a 371 mV hum, and
    43 flights invented. Fitted as spectral lines: 2.9 mV. Reference: the hum added; the
    estimate within 3 % of its rms, and the clean recording's flights found again (the
    same count, median flight-time difference under 1 us)."""
    c, fs, _ = rig_sweep(make_rig, 0.0, 100e-6)
    h = hum(c.shape[0], fs, 0.1 * np.ptp(c), f_hz=60.0, third=0.3)
    miss = estimate_error(c + h, h, fs)
    print(f"estimate minus hum: {miss * 1e3:.1f} mV rms (hum {np.std(h) * 1e3:.1f})")
    assert miss < 0.03 * np.std(h)
    ta0, tl0 = detect_contacts(c, sample_rate_hz=fs).flights()
    ta, tl = detect_contacts(c + h, sample_rate_hz=fs).flights()
    assert ta.shape == ta0.shape
    assert np.median(np.abs((tl - ta) - (tl0 - ta0))) / fs < 1e-6


@pytest.mark.parametrize("f_hz,third", [(50.0, 0.0), (60.0, 0.3)])
def test_a_hum_on_the_open_level_through_a_slow_front_end(make_rig, f_hz, third):
    """A hum of 10 % of the gap picked up in proportion to how open the circuit is (the
    RC front end's own state: 0 in contact, 1 open), through a 100 us front end. Each
    sample took its own level's estimate, the whole of the open one at a sample 30 %
    open: 41 % of the flights found at 50 Hz, none at 60 Hz. The two estimates are now
    mixed by each sample's share of the way between the levels. Reference: the clean
    recording's flights; all found again (within 2 more or fewer), median flight-time
    difference under 1 us."""
    c, fs, _ = rig_sweep(make_rig, 0.0, 100e-6)
    lo, hi = np.percentile(c, [1, 99])
    h = hum(c.shape[0], fs, 0.1 * np.ptp(c), f_hz=f_hz, third=third)
    h *= np.clip((c - lo) / (hi - lo), 0.0, 1.0)
    det0 = detect_contacts(c, sample_rate_hz=fs)
    det = detect_contacts(c + h, sample_rate_hz=fs)
    err, found, n_det, n_true = match_edges(det, det0, fs)
    print(f"{f_hz} Hz: {n_det} flights for {n_true}, found {found:.3f}, ", end="")
    print(f"median {np.median(err) * 1e6:.2f} us")
    assert abs(n_det - n_true) <= 2 and found == 1.0
    assert np.median(err) < 1e-6


def match_edges(det, ref, fs, tol_s=0.3e-3):
    """Flight-time differences (s) of ``det``'s flights matched to ``ref``'s (both edges
    within ``tol_s``), the share of ``ref``'s found, and the two counts."""
    ta, tl = (v / fs for v in det.flights())
    ra, rl = (v / fs for v in ref.flights())
    j = np.clip(np.searchsorted(ta, ra), 1, max(ta.shape[0] - 1, 1))
    j = np.where(np.abs(ta[j - 1] - ra) < np.abs(ta[j] - ra), j - 1, j)
    ok = (np.abs(ta[j] - ra) < tol_s) & (np.abs(tl[j] - rl) < tol_s)
    return np.abs((tl[j] - ta[j]) - (rl - ra))[ok], float(ok.mean()), ta.shape[0], ra.shape[0]


def test_lines_are_found_at_their_frequencies():
    """Reference: the sines put in. 50 Hz and its third harmonic under white noise, over
    10 s at 20 kHz: both found within 0.01 Hz, strongest first, nothing else above the
    stop; a second line closer than a block of the fit can tell apart is not taken."""
    fs, n = 20_000.0, 200_000
    t = np.arange(n) / fs
    rng = np.random.default_rng(0)
    est = 0.2 * np.sin(2 * np.pi * 50.0 * t) + 0.05 * np.sin(2 * np.pi * 150.0 * t + 1.0)
    f = find_lines(est + 0.002 * rng.standard_normal(n), fs, 5.0)
    assert f.shape == (2,)
    assert f == pytest.approx([50.0, 150.0], abs=0.01)
    near = 50.0 + 0.5 * LINE_APART_S / LINE_BLOCK_S
    f = find_lines(est + 0.1 * np.sin(2 * np.pi * near * t), fs, 5.0)
    assert not np.any(np.abs(f - near) < 1.0)


def test_the_guard_needs_enough_decay_ratios():
    """Reference: an RC tail of q per sample falls to ``TAIL_REL`` (0.002) after
    ceil(log 0.002 / log q) samples, plus the edge's own: 10 for q = 0.5.  A lone ratio,
    or ratios that are no decay (|r| >= 1, chatter), measure nothing: ``GUARD_MIN``."""
    assert guard_samples(np.full(MIN_RATIOS, 0.5)) == 10
    assert guard_samples(np.array([3.39])) == GUARD_MIN
    assert guard_samples(np.array([0.5] * (MIN_RATIOS - 1) + [3.0, 7.0, -2.0])) == GUARD_MIN
    assert guard_samples(np.array([0.5] * MIN_RATIOS + [3.0, 7.0])) == 10
