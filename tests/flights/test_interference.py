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
from bouncelab.flights.interference import GATE_REL, fast_interference, remove_interference

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
