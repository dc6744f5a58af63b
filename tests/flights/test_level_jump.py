"""Levels that jump mid-recording (a gain or supply change): found, and each side detected.

Truth: the synthetic contacts of flights_synth.py; the jump is applied to the volts.  The
reference is the same signal without the jump; tolerances are stated per test.
"""

import numpy as np
import pytest
from flights_synth import bouncing_contacts, continuity
from test_detect import FS, match

from bouncelab.flights import detect, detect_contacts
from bouncelab.flights.detect import TRACKED_JUMP, level_jump, refine_cut


def bouncing_after_rest(duration_s, rest_s, seed):
    """A rest in contact for ``rest_s`` (Gamma < 1), then bouncing."""
    c = [(0.0, rest_s)] + [(a + rest_s, b + rest_s) for a, b in bouncing_contacts(
        duration_s - rest_s, seed=seed)]  # fmt: skip
    return c


@pytest.mark.parametrize(
    "gain,offset_v,jump_s,n_samples",
    [
        (0.6, 0.0, 6.03, None),
        # a level lost to the end of a recording whose last block is a few samples: that
        # block cannot be judged, and the lost level still runs "to the end" (it did not)
        (0.6, 0.0, 6.03, 48 * 4096 + 6),
        (1.5, 0.5, 7.77, None),
        (0.75, -0.3, 4.4, None),
    ],
)
def test_a_level_jump_is_split_and_both_sides_are_found(gain, offset_v, jump_s, n_samples):
    """The open level moves by 25-70 % of the gap at ``jump_s`` (contact low, 0 V; with
    an offset both levels move), after 2 s of rest: without the split flights are lost
    or invented by the thousand (the test can fail); with it >= 99.5 % of the true flights
    are found, at most 3 more or fewer, the median error within 2 us of the jump-free
    signal's, and the jump placed within 1 ms."""
    c = bouncing_after_rest(10.0, 2.0, seed=21)
    x0, _ = continuity(c, 10.0, tau_s=25e-6, noise_v=0.01, drift_v=0.1, seed=22)
    if n_samples:
        x0 = x0[:n_samples]
        c = [(a, b) for a, b in c if b < (n_samples - 1) / FS]
    k = int(jump_s * FS)
    x = x0.copy()
    x[k:] = x[k:] * gain + offset_v
    err0, found0, _, _ = match(detect_contacts(x0), c)
    det = detect_contacts(x)
    err, found, n_det, n_true = match(det, c)
    print(
        f"gain {gain}: found {found:.4f} ({n_det} / {n_true}), median {np.median(err) * 1e6:.2f} us"
    )
    assert found >= 0.995 and abs(n_det - n_true) <= 3
    assert np.median(err) < np.median(err0) + 2e-6
    whole = detect._detect(x, "auto", (), (), detect.BLOCK, None, detect.Parallel(1), None)
    cut = level_jump(x, whole)
    assert cut is not None
    assert abs(refine_cut(x, cut, detect.BLOCK) - k) < 1e-3 * FS


def test_without_the_split_the_same_run_breaks(monkeypatch):
    """The check is what saves it: with level jumps never reported, a gain drop of 40 %
    loses or invents more than 5 % of the flights."""
    c = bouncing_after_rest(10.0, 2.0, seed=21)
    x, _ = continuity(c, 10.0, tau_s=25e-6, noise_v=0.01, drift_v=0.1, seed=22)
    x[int(6.03 * FS) :] *= 0.6
    monkeypatch.setattr(detect, "level_jump", lambda x, det: None)
    _, found, n_det, n_true = match(detect_contacts(x), c)
    assert found < 0.95 or abs(n_det - n_true) > 0.05 * n_true


@pytest.mark.parametrize("tau_s", [0.0, 25e-6, 150e-6, 400e-6])
@pytest.mark.parametrize("noise_v", [0.01, 0.3])
def test_no_jump_is_reported_on_a_steady_channel(tau_s, noise_v):
    """Drift of 0.5 V, noise up to 6 % of the gap, RC front ends up to 400 us (whose
    transition samples lie near neither level): no jump."""
    c = bouncing_after_rest(8.0, 1.0, seed=23)
    x, _ = continuity(c, 8.0, tau_s=tau_s, noise_v=noise_v, drift_v=0.5, seed=24)
    whole = detect._detect(x, "auto", (), (), detect.BLOCK, None, detect.Parallel(1), None)
    assert level_jump(x, whole) is None


def chatter_contacts(duration_s, rest_s, seed):
    """A rest, then bouncing whose contacts are, in stretches of 0.3-0.8 s, either
    bursts of 3-14 contacts of 5-40 us (shorter than a 50 us sample) or single contacts
    of 0.2-1 ms, with flights of 5-25 ms between them."""
    rng = np.random.default_rng(seed)
    c = [(0.0, rest_s)]
    t = rest_s + 0.01
    while t < duration_s - 0.05:
        end, short = t + rng.uniform(0.3, 0.8), rng.random() < 0.5
        while t < min(end, duration_s - 0.05):
            for _ in range(rng.integers(3, 15) if short else 1):
                d = rng.uniform(5e-6, 40e-6) if short else rng.uniform(2e-4, 1e-3)
                c.append((t, t + d))
                t += d + (rng.uniform(20e-6, 300e-6) if short else 0.0)
            t += rng.uniform(5e-3, 25e-3)
    return c


@pytest.mark.parametrize("seed", [3, 4])
def test_a_contact_level_read_off_partial_samples_is_not_a_jump(seed):
    """Stretches of contacts shorter than a sample fill the contact band with partial
    samples: the block contact level wanders from 0.03 V to 0.9-1 V (a fifth of the 5 V
    gap) and back while the samples that reach the contact stay at 0 V.  Before the
    samples were asked (``_step_held``), each wandering was taken for a jump the tracking
    followed (the test can fail: 9 detection passes at seed 3).  Reference: the synthetic
    levels never move."""
    c = chatter_contacts(12.0, 2.0, seed)
    x, _ = continuity(c, 12.0, tau_s=10e-6, noise_v=0.01, seed=seed)
    whole = detect._detect(x, "auto", (), (), detect.BLOCK, None, detect.Parallel(1), None)
    assert np.ptp(whole.contact_v) > TRACKED_JUMP * 5.0  # the wandering is there
    assert level_jump(x, whole) is None


@pytest.mark.parametrize(
    "gain,offset_v,jump_s,hum_v",
    [
        # both levels shifted by a fifth of the gap (a supply step): every sample lies
        # within a quarter gap of both sides' levels; before, the cut fell anywhere in
        # four blocks and 335 flights were invented
        (1.0, -1.0, 7.77, 0.0),
        (1.0, -1.0, 5.5, 0.1),  # with a hum of 2 % of the gap
        # the open level falls to near the old mid level: the first right-side window
        # still held the old open level, the cut came 53 ms early, every later flight lost
        (0.4, 0.0, 6.03, 0.0),
        # a gain drop with an offset, under a 50 Hz hum of 6 % of the new gap
        (0.35, 0.5, 8.41, 0.1),
    ],
)
def test_the_cut_is_placed_on_the_jump_for_shifts_and_deep_drops(gain, offset_v, jump_s, hum_v):
    """Jumps the first refinement misplaced (reference: the synthetic contacts, a rest
    hint as extract gives for a Gamma < 1 step, the sampling rate for the hum): every
    true flight found within 0.3 ms, none invented, and the cut within 1 ms of the jump."""
    from test_interference import hum

    c = bouncing_after_rest(10.0, 2.0, seed=21)
    x, _ = continuity(c, 10.0, tau_s=25e-6, noise_v=0.01, drift_v=0.1, seed=22)
    k = int(jump_s * FS)
    x[k:] = x[k:] * gain + offset_v
    x = x + hum(x.shape[0], FS, hum_v)
    det = detect_contacts(x, rest_intervals=[(0, int(1.9 * FS))], sample_rate_hz=FS)
    err, found, n_det, n_true = match(det, c)
    assert found == 1.0 and n_det == n_true
    whole = detect._detect(x, "low", (), (), detect.BLOCK, None, detect.Parallel(1), None)
    cut = level_jump(x, whole)
    assert cut is not None
    assert abs(refine_cut(x, cut, detect.BLOCK) - k) < 1e-3 * FS


@pytest.mark.parametrize("gain", [0.4, 0.2])
def test_without_hints_the_polarity_is_read_on_each_side(gain):
    """No rest or open interval (a sweep with no step below Gamma 1): the open level
    falls from 5 V to 2 V or 1 V, near or below the old mid level, so the whole read the
    new open level as contact and took the contact level for the high one (every flight
    read as a contact: 9 % found). Read on each side, the contacts' share of time is
    short again: the polarity is right and every true flight found (within 0.3 ms)."""
    c = bouncing_after_rest(10.0, 2.0, seed=21)
    x, _ = continuity(c, 10.0, tau_s=25e-6, noise_v=0.01, drift_v=0.1, seed=22)
    x[int(6.03 * FS) :] *= gain
    det = detect_contacts(x, sample_rate_hz=FS)
    _, found, n_det, n_true = match(det, c)
    assert not det.contact_high
    assert found == 1.0 and n_det == n_true
