"""The pile's state and events: the tilt of a constructed pile, the event detectors on
synthetic V records (a ramp, a burst that does not last, a lasting rise)."""

import math

import numpy as np
import pytest

from granpipe.drum.measures import coarse_blocks, onset_events, pile_state, stop_events

R_DRUM = 32.4  # inner radius of the paper's drum [d_s]


def _pile(level=-14.0, d=1.08):
    """Disks on a triangular lattice filling the drum below a horizontal surface."""
    pts = []
    row = 0
    y = -R_DRUM + d / 2
    while y < level:
        x0 = -R_DRUM + (d / 2 if row % 2 else 0.0)
        for x in np.arange(x0, R_DRUM, d):
            if math.hypot(x, y) < R_DRUM - d / 2:
                pts.append((x, y))
        y += d * math.sqrt(3) / 2
        row += 1
    p = np.array(pts)
    return p, np.full(len(p), d / 2)


def _turned(p, degrees):
    """The pile turned rigidly about the drum's axis by ``degrees`` the drum's way
    (clockwise)."""
    a = -math.radians(degrees)
    rot = np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])
    return p @ rot.T


@pytest.mark.parametrize("alpha", [0.0, 1.0, 4.5, 8.0, 12.0, -6.0])
def test_tilt_and_centroid_of_a_pile_turned_by_a_known_angle(alpha):
    p, r = _pile()
    tilt0, c0 = pile_state(p, r)
    assert abs(tilt0) < 0.05 and abs(c0) < 0.05  # a level, symmetric pile
    tilt, c = pile_state(_turned(p, alpha), r)
    # the surface points are lattice tops on a staircase: ~0.25 degree
    assert tilt == pytest.approx(alpha, abs=0.25)
    assert c == pytest.approx(alpha, abs=1e-9)


def test_tilt_sign_follows_the_drum_and_masses_weight_the_centroid():
    p, r = _pile()
    # the clockwise drum lifts the left side: the surface falls to the right
    tilt, _ = pile_state(_turned(p, 5.0), r)
    assert tilt > 0 and _turned(p, 5.0)[:, 0].mean() < 0
    m = np.where(p[:, 0] < 0, 3.0, 1.0)  # heavier on the left: centroid turned the drum's way
    _, c = pile_state(p, r, m)
    assert c > 1.0


T_BLOCK = 0.004
SECONDS = (np.arange(6250) + 0.5) * T_BLOCK  # a 25 s onset window of 4 ms blocks
PILE_SECONDS = np.arange(251) * 0.1
RIGID = 0.17
EVENTS = dict(block=25, startup_excess=0.1, startup_hold=5, burst_excess=0.3, flow_excess=0.1,
              flow_hold=20)  # fmt: skip


def _events(V):
    V = np.atleast_2d(V)
    rigid = np.full((V.shape[0], PILE_SECONDS.size), RIGID)
    return onset_events(SECONDS, V, PILE_SECONDS, rigid, **EVENTS)


def _startup(t):
    """V after t = 0: the fall's motion decaying onto 0.9 of rigid rotation by ~2 s."""
    return RIGID * (0.9 + 2.0 * np.exp(-t / 0.4))


def test_coarse_blocks_are_exact_means():
    start, m = coarse_blocks(SECONDS, np.arange(6250.0), 25)
    assert start[0] == pytest.approx(0.0) and start[1] == pytest.approx(0.1)
    assert m[0] == pytest.approx(12.0) and len(m) == 250


def test_detectors_on_a_ramp():
    t = SECONDS
    V = _startup(t) + RIGID * np.clip(0.05 * (t - 5.0), 0.0, None)  # +5 % of rigid per s
    ev = _events(V)
    # start-up: 0.9 + 2 exp(-t/0.4) <= 1.1 from t = 0.4 ln 10 = 0.92 s (block 0.9-1.0 s)
    assert ev["startup_end"][0] == pytest.approx(0.9, abs=0.11)
    # ratio 0.9 + 0.05 (t - 5) passes 1.1 at 9 s and 1.3 at 13 s
    assert ev["flow_onset"][0] == pytest.approx(9.0, abs=0.11)
    assert ev["first_burst"][0] == pytest.approx(13.0, abs=0.11)


def test_detectors_on_a_burst_that_does_not_last_and_a_lasting_rise():
    t = SECONDS
    burst = _startup(t) + np.where((t >= 6.0) & (t < 7.0), RIGID, 0.0)  # 1 s at 1.9x
    rise = _startup(t) + np.where(t >= 15.0, 0.5 * RIGID, 0.0)  # to 1.4x for good
    late = _startup(t) + np.where(t >= 24.0, 0.5 * RIGID, 0.0)  # rises 1 s before the end
    ev = _events(np.stack([burst, rise, late]))
    np.testing.assert_allclose(ev["first_burst"], [6.0, 15.0, 24.0], atol=1e-9)
    assert np.isnan(ev["flow_onset"][0])  # one second is not the 2 s of sustained flow
    assert ev["flow_onset"][1] == pytest.approx(15.0)
    assert np.isnan(ev["flow_onset"][2])  # not two seconds of record left
    # a burst during the start-up is not a burst: search from the start-up's end
    early = _startup(t) + np.where((t >= 0.0) & (t < 0.5), RIGID, 0.0)
    assert np.isnan(_events(early)["first_burst"][0])


def test_stop_of_the_flow_after_the_drum_stops():
    t = (np.arange(3000) + 0.5) * T_BLOCK  # a 12 s decay window
    V = np.where(t < 5.0, 1.5, 1.5 * np.exp(-(t - 5.0) / 1.0)) * RIGID  # below 1x after 5.4 s
    rigid = np.full((1, 121), RIGID)
    stop = stop_events(t, V[None], np.arange(121) * 0.1, rigid, block=25, stop_time=5.0,
                       stop_fraction=1.0, hold=20)  # fmt: skip
    assert stop[0] == pytest.approx(5.0 + math.log(1.5), abs=0.11)
