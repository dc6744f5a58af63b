"""An AC-coupled continuity channel (a sound card's input): found, its corner read, undone.

Truth: the synthetic contacts of flights_synth.py, passed through scipy's first-order
Butterworth high-pass at a known corner (the bilinear transform of an RC coupling);
tolerances are stated per test.
"""

import numpy as np
import pytest
from flights_synth import bouncing_contacts, continuity, write_npz_run
from scipy import signal
from test_detect import FS, match

from bouncelab.flights import detect_contacts, extract_run
from bouncelab.flights.coupling import ac_coupling_tau, orphan_share, undo_ac_coupling


def high_pass(x, corner_hz, fs=FS):
    b, a = signal.butter(1, corner_hz / (fs / 2), "high")
    return signal.lfilter(b, a, x)


def resting_then_bouncing(seconds=8.0, rest_s=2.0, seed=3):
    """Contacts: the body rests for ``rest_s`` (a Gamma < 1 step), then bounces."""
    return [(0.0, rest_s)] + [
        (a + rest_s, b + rest_s) for a, b in bouncing_contacts(seconds - rest_s, seed=seed)
    ]


@pytest.mark.parametrize("corner_hz", [0.5, 2.0, 20.0])
def test_the_corner_is_read_and_the_levels_come_back(corner_hz):
    """The corner comes out within 3 % (reference: the filter's own), and the inverse
    leaves the levels flat again: at most a fifth of the samples near neither level that
    the coupled channel has (the rest drains; the bouncing, mostly open, hardly)."""
    c = resting_then_bouncing()
    x, _ = continuity(c, 8.0, noise_v=0.01, seed=4)
    y = high_pass(x, corner_hz)
    tau = ac_coupling_tau(y, FS)
    assert tau is not None
    assert 1.0 / (2 * np.pi * tau) == pytest.approx(corner_hz, rel=0.03)
    assert orphan_share(undo_ac_coupling(y, FS, tau)) < min(0.2 * orphan_share(y), 0.01)


@pytest.mark.parametrize(
    "change", ["none", "rc_250us", "gain_step", "hum", "drift", "drift_2v"], ids=lambda c: c
)
def test_a_dc_channel_is_not_taken_for_a_coupled_one(change):
    """A DC channel, also through a slow RC front end, with a gain step to 0.4 (whose
    orphans no inversion removes), a 5 % hum or a slow drift of 0.5 or 2 V (40 % of the
    gap: half the samples off the global levels, which an inversion over tens of
    seconds would 'mend'; the time constants searched stop at 5 s): no coupling."""
    c = resting_then_bouncing()
    tau_s = 250e-6 if change == "rc_250us" else 25e-6
    drift = {"drift": 0.5, "drift_2v": 2.0}.get(change, 0.1)
    x, _ = continuity(c, 8.0, tau_s=tau_s, noise_v=0.01, drift_v=drift, seed=4)
    if change == "gain_step":
        x[int(5.5 * FS) :] *= 0.4
    if change == "hum":
        x = x + 0.25 * np.sin(2 * np.pi * 50 * np.arange(x.shape[0]) / FS)
    assert ac_coupling_tau(x, FS) is None


def test_undo_inverts_the_high_pass():
    """Two levels through a 2 Hz coupling and back: within 0.2 % of the gap of the DC
    signal after its first level (the constant of integration) is matched."""
    c = resting_then_bouncing()
    x, _ = continuity(c, 8.0, noise_v=0.0, seed=4)
    back = undo_ac_coupling(high_pass(x, 2.0), FS, 1.0 / (2 * np.pi * 2.0))
    back += x[0] - back[0]
    assert np.max(np.abs(back - x)) < 0.002 * 5.0


def test_extract_undoes_a_coupled_run_and_says_so(tmp_path, caplog):
    """A sweep recorded through a 2 Hz AC coupling, contact_level auto: the rest at Gamma
    0.5 drains to the open level, so the polarity was read backwards and every flight
    was a contact. Undone, every flight is found (within 0.3 ms of the truth), with a
    warning naming the corner; the same flights as the channel without coupling."""
    c = resting_then_bouncing()
    x, _ = continuity(c, 8.0, noise_v=0.01, seed=4)
    steps = [{"t_s": 0.0, "gamma": 0.5}, {"t_s": 2.0, "gamma": 3.0}]
    run = write_npz_run(
        tmp_path / "coupled", {"continuity": high_pass(x, 2.0)},
        kind="sweep", drive_frequency_hz=30.0, gamma_steps=steps,
    )  # fmt: skip
    with caplog.at_level("WARNING"):
        flights, _ = extract_run(run)
    assert "AC-coupled input" in caplog.text and "corner 2" in caplog.text
    truth = detect_contacts(x)
    err, found, n_det, n_true = match(truth, c)
    assert found == 1.0
    t_true = np.sort(truth.flights()[0] / FS)
    t_got = np.sort(flights["t_takeoff_s"].to_numpy())
    assert t_got.shape == t_true[t_true > 2.0].shape
    assert np.max(np.abs(t_got - t_true[t_true > 2.0])) < 3e-4


def test_validate_names_the_coupling(tmp_path):
    """validate says what extract will do: the corner, within 3 % (reference: the
    filter's); a DC channel gets no such line."""
    from bouncelab.runs import validate_run

    c = resting_then_bouncing()
    x, _ = continuity(c, 8.0, noise_v=0.01, seed=4)
    steps = [{"t_s": 0.0, "gamma": 0.5}, {"t_s": 2.0, "gamma": 3.0}]
    for name, ch in (("coupled", high_pass(x, 2.0)), ("dc", x)):
        run = write_npz_run(
            tmp_path / name, {"continuity": ch}, kind="sweep", drive_frequency_hz=30.0,
            gamma_steps=steps,
        )  # fmt: skip
        found = [w for w in validate_run(run).warnings if "AC-coupled" in w]
        if name == "dc":
            assert not found
        else:
            corner = float(found[0].split("corner ")[1].split(" Hz")[0])
            assert corner == pytest.approx(2.0, rel=0.03)
