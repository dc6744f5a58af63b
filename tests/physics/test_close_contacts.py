"""The continuity circuit's view of the model's flights when every contact lasts at least
``min_contact`` (``physics.kernels.close_contacts``, ``physics.simulate.seen_flights``).
References: flights worked out by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from bouncelab.physics import Model, simulate_protocol
from bouncelab.physics import kernels as K
from bouncelab.physics.simulate import protocol_flight_times, seen_flights


def test_bounce_shortened_ride_kept_quick_rebound_hidden_members_apart():
    """Contact 0.1 rad. Member 0: a flight from rest (kept whole); a bounce at its landing
    (opens 0.1 later: 1.0 -> 0.9); a rebound of 0.05 that lands inside the contact (not
    seen), so the next bounce opens 0.1 after *that* landing; a takeoff after a ride of
    0.5 (longer than the contact: unchanged). Member 1 starts afresh."""
    member = np.array([0, 0, 0, 0, 0, 1])
    t_takeoff = np.array([0.0, 1.0, 2.0, 2.05, 3.5, 0.0])
    T = np.array([1.0, 1.0, 0.05, 0.95, 1.0, 0.3])
    seen, t_open, T_seen = K.close_contacts(member, t_takeoff, T, 0.1)
    assert seen.tolist() == [True, True, False, True, True, True]
    np.testing.assert_allclose(T_seen[seen], [1.0, 0.9, 0.85, 1.0, 0.3], rtol=0, atol=1e-12)
    np.testing.assert_allclose(t_open[seen], [0.0, 1.1, 2.15, 3.5, 0.0], rtol=0, atol=1e-12)


def test_zero_contact_changes_nothing():
    member = np.zeros(3, dtype=np.int64)
    t = np.array([0.0, 1.0, 2.0])
    T = np.array([1.0, 1.0, 0.5])
    seen, t_open, T_seen = K.close_contacts(member, t, T, 0.0)
    assert seen.all()
    np.testing.assert_array_equal(T_seen, T)
    np.testing.assert_array_equal(t_open, t)


@pytest.mark.parametrize("min_contact", [0.0, 0.1])
def test_protocol_rows_are_the_gathered_rows_with_their_contacts_closed(min_contact):
    """The fits' one-pass reading of the kernel's buffer (``protocol_rows``) gives, bit
    for bit, the written rows of each trajectory's block gathered column by column and
    then passed through ``close_contacts``; an empty block and the unwritten room between
    blocks are skipped; without a contact time the rows are read as written (the
    circuit's ``landing - opens`` could round a flight time). The same flights as the
    hand-worked case above (member 0), a member with no rows, and a member of two
    flights."""
    max_rec = 8
    blocks = [
        ([0.0, 1.0, 2.0, 2.05, 3.5], [1.0, 1.0, 0.05, 0.95, 1.0], [0, 0, 1, 1, 2]),
        ([], [], []),
        ([0.25, 0.9], [0.3, 0.7], [0, 1]),
    ]
    out = np.full((K.NCOL, max_rec * len(blocks)), np.nan)  # unwritten room: never read
    rows = np.array([len(b[0]) for b in blocks], dtype=np.int64)
    for j, (tto, T, step) in enumerate(blocks):
        at = slice(j * max_rec, j * max_rec + len(tto))
        out[K.C_TTO, at], out[K.C_T, at], out[K.C_STEP, at] = tto, T, step
        out[K.C_START, at] = j
        out[K.C_SETTLED, at] = [1.0 if k % 2 else 0.0 for k in range(len(tto))]
    member, step, T, settled = K.protocol_rows(out, rows, max_rec, min_contact)

    keep = np.concatenate([np.arange(j * max_rec, j * max_rec + r) for j, r in enumerate(rows)])
    expected_member = out[K.C_START, keep].astype(np.int64)
    seen, _, T_seen = K.close_contacts(expected_member, out[K.C_TTO, keep], out[K.C_T, keep],
                                       min_contact)  # fmt: skip
    if min_contact == 0.0:
        T_seen = out[K.C_T, keep]
    np.testing.assert_array_equal(member, expected_member[seen])
    np.testing.assert_array_equal(step, out[K.C_STEP, keep].astype(np.int64)[seen])
    np.testing.assert_array_equal(T, T_seen[seen])
    np.testing.assert_array_equal(settled, (out[K.C_SETTLED, keep] > 0.5)[seen])
    assert member.dtype == step.dtype == np.int64 and settled.dtype == np.bool_
    assert len(T) == (7 if min_contact == 0.0 else 6)  # the rebound inside the contact hides


@pytest.fixture(scope="module")
def bouncing():
    """Restitution 0.5 at Gamma 2-3: every landing is a bounce, chatter included."""
    model = Model.parse("restitution", {"e": 0.5})
    gammas, cycles = np.array([2.0, 2.5, 3.0]), np.array([30, 30, 30])
    return model, gammas, cycles


def test_seen_flights_frame_and_arrays_agree(bouncing):
    """The DataFrame route (reports) and the fits' array route give the same flights."""
    model, gammas, cycles = bouncing
    c = 2.0 * math.pi * 30.0 * 2e-4  # 200 us at 30 Hz
    frame = seen_flights(simulate_protocol(model, gammas, cycles), c)
    arrays = protocol_flight_times(model, gammas, cycles, min_contact=c)
    np.testing.assert_allclose(frame["T"].to_numpy(), arrays["T"], rtol=0, atol=1e-12)
    np.testing.assert_array_equal(frame["step"].to_numpy(), arrays["step"])


def test_seen_flights_are_shorter_and_fewer(bouncing):
    """Every seen flight is at most its model flight; rebounds shorter than the contact
    vanish, so the shortest seen flight lasts longer than none at all; a body riding the
    plate longer than the contact takes off on time."""
    model, gammas, cycles = bouncing
    c = 2.0 * math.pi * 30.0 * 2e-4
    sim = simulate_protocol(model, gammas, cycles)
    seen = seen_flights(sim, c)
    assert 0 < len(seen) < len(sim)
    landing = sim["t_takeoff"] + sim["T"]
    seen_landing = seen["t_takeoff"] + seen["T"]
    # landings are the physics: every seen landing is a model landing
    assert np.isin(np.round(seen_landing.to_numpy(), 9), np.round(landing.to_numpy(), 9)).all()
    np.testing.assert_allclose(seen["phi_takeoff"], np.mod(seen["t_takeoff"], 2 * math.pi))
    assert seen_flights(sim, 0.0) is sim
