"""The papers' contact laws: Jacobian leaves against central finite differences at pairs
and flat walls, on each smooth piece, and analytic contact values."""

import math

import numpy as np
import pytest

from granpipe.engine import BoxLaw, DrumLaw
from granpipe.engine.laws import COULOMB, NO_FRICTION, VISCOUS

DRUM = DrumLaw(k_n=565.97, gamma_n=8.7308, gamma_t=6.8927, mu=0.44)
BOX = BoxLaw(kappa_n=1e6, kappa_t=1e4, gamma_n=100.0, gamma_t=100.0, mu=0.6)


def central_difference(f, x, h):
    """Jacobian of f at x by central differences with steps h (per component)."""
    x = np.asarray(x, dtype=float)
    cols = []
    for k in range(x.size):
        e = np.zeros_like(x)
        e[k] = h[k]
        cols.append((np.asarray(f(x + e)) - np.asarray(f(x - e))) / (2 * h[k]))
    return np.array(cols).T


def assert_jacobian_close(j_exact, j_fd, rtol=1e-6):
    scale = np.abs(j_exact).max()
    np.testing.assert_allclose(j_exact, j_fd, rtol=0, atol=rtol * scale)


def drum_regime(d, v, radius_sum):
    return DRUM.pair(d, v, 0.0, 0.0, radius_sum / 2, radius_sum / 2, 0.5)[1]


def drum_force(d, v, s):
    """The drum law's force on i (its Eq. 1 does not depend on the radii apart from
    their sum, nor on spins or masses)."""
    return DRUM.pair(d, v, 0.0, 0.0, s / 2, s / 2, 0.5)[0][:2]


def drum_jacobian(d, v, s):
    jac = DRUM.pair_jacobian(d, v, 0.0, 0.0, s / 2, s / 2, 0.5)
    return jac[:2, :2], jac[:2, 2:4]


def random_drum_contacts(rng, wanted, count):
    """Random contact states of the drum law in the given regime, away from switches."""
    out = []
    while len(out) < count:
        s = rng.choice([1.0, 1.0833, 1.1667, 0.5 + 0.6923])
        ang = rng.uniform(0, 2 * np.pi)
        r = s * rng.uniform(0.85, 0.995)
        d = r * np.array([np.cos(ang), np.sin(ang)])
        v = rng.normal(0, 1.0, 2) * rng.choice([0.03, 0.3, 3.0])
        if drum_regime(d, v, s) != wanted:
            continue
        # stay away from the switching surfaces (gamma_t |u| = mu f_n and f_n = 0)
        n = d / r
        u = v[1] * n[0] - v[0] * n[1]
        f_n = -DRUM.k_n * (r - s) - DRUM.gamma_n * (v @ n)
        if abs(DRUM.gamma_t * abs(u) - DRUM.mu * f_n) < 1e-3 * (1 + abs(f_n)) or abs(f_n) < 1e-2:
            continue
        out.append((d, v, s))
    return out


@pytest.mark.parametrize("regime", [VISCOUS, COULOMB, NO_FRICTION])
def test_drum_pair_jacobian_matches_finite_differences(regime):
    rng = np.random.default_rng(1 + regime)
    for d, v, s in random_drum_contacts(rng, regime, 20):
        j_d, j_v = drum_jacobian(d, v, s)
        fd_d = central_difference(lambda x, v=v, s=s: drum_force(x, v, s), d, [1e-7] * 2)
        h_v = [1e-7 * (1 + abs(v).max())] * 2
        fd_v = central_difference(lambda x, d=d, s=s: drum_force(d, x, s), v, h_v)
        assert_jacobian_close(j_d, fd_d)
        assert_jacobian_close(j_v, fd_v)


@pytest.mark.parametrize("normal", [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0)])
def test_drum_flat_wall_jacobian_matches_finite_differences(normal):
    rng = np.random.default_rng(7)
    n = np.array(normal)
    t = np.array([-n[1], n[0]])
    checked = 0
    while checked < 30:
        radius = rng.choice([0.5, 0.58335])
        h = radius * rng.uniform(0.8, 0.995)
        v = n * rng.normal(0, 1.0) + t * rng.normal(0, 1.0) * rng.choice([0.05, 1.0, 5.0])
        f_n = -DRUM.k_n * (h - radius) - DRUM.gamma_n * (v @ n)
        u = v @ t
        if abs(DRUM.gamma_t * abs(u) - DRUM.mu * f_n) < 1e-3 * (1 + abs(f_n)) or abs(f_n) < 1e-2:
            continue
        jac = DRUM.wall_pair_jacobian(h, v, 0.0, radius, 1.0, n)
        # a displacement dd of the disk changes h by n . dd
        j_h, j_v = jac[:2, :2] @ n, jac[:2, 2:4]

        def f_h(x, v=v, radius=radius):
            return DRUM.wall_pair(x[0], v, 0.0, radius, 1.0, n)[0][:2]

        def f_v(x, h=h, radius=radius):
            return DRUM.wall_pair(h, x, 0.0, radius, 1.0, n)[0][:2]

        fd_h = central_difference(f_h, [h], [1e-8])[:, 0]
        fd_v = central_difference(f_v, v, [1e-7] * 2)
        assert_jacobian_close(j_h[:, None], fd_h[:, None])
        assert_jacobian_close(j_v, fd_v)
        checked += 1


@pytest.mark.parametrize("want_slip", [False, True])
def test_box_pair_jacobian_matches_finite_differences(want_slip):
    """Jacobian of (F_x, F_y, tau_i, tau_j) w.r.t. (d, v, w_i, w_j) at fixed prior history."""
    rng = np.random.default_rng(11 + want_slip)
    dt = 4.4446e-5
    checked = 0
    while checked < 25:
        a_i, a_j = rng.choice([0.5, 0.45, 0.6], 2)
        s = a_i + a_j
        ang = rng.uniform(0, 2 * np.pi)
        r = s - rng.uniform(1e-5, 2e-3)
        d = r * np.array([np.cos(ang), np.sin(ang)])
        v = rng.normal(0, 0.3, 2)
        w = rng.normal(0, 1.0, 2)
        m_eff = rng.choice([0.5, 1.0, 0.3])
        # history between stick and deep slip
        xi = rng.normal(0, 2e-4) * (20.0 if want_slip else 1.0)
        x0 = np.concatenate([d, v, w])

        def f(x, xi=xi, a_i=a_i, a_j=a_j, m_eff=m_eff):
            return BOX.pair(x[:2], x[2:4], x[4], x[5], a_i, a_j, m_eff, xi, dt)[0][:4]

        # classify and keep away from the truncation surface
        n = d / r
        tvec = np.array([-n[1], n[0]])
        lev_i, lev_j = 0.5 * (r + a_i - a_j), 0.5 * (r + a_j - a_i)
        vt = v @ tvec - lev_i * w[0] - lev_j * w[1]
        f_n = BOX.kappa_n * (s - r) - BOX.gamma_n * m_eff * (v @ n)
        f_t = -BOX.kappa_t * (xi + vt * dt) - BOX.gamma_t * m_eff * vt
        margin = abs(abs(f_t) - BOX.mu * abs(f_n))
        if (abs(f_t) > BOX.mu * abs(f_n)) != want_slip or margin < 1e-3 * abs(f_n):
            continue
        jac = BOX.pair_jacobian(d, v, w[0], w[1], a_i, a_j, m_eff, xi, dt)[:4, :6]
        fd = central_difference(f, x0, [1e-9, 1e-9, 1e-7, 1e-7, 1e-7, 1e-7])
        for block in (slice(0, 2), slice(2, 4), slice(4, 6)):
            assert_jacobian_close(jac[:, block], fd[:, block])
        checked += 1


def test_drum_analytic_contact_values():
    """Drum paper Sec. II.2: dt = 4e-5 s is about tau/82 for two small disks."""
    tau = DRUM.contact_time(0.5)
    assert 80 < tau / 1.14368e-3 < 86
    w = math.sqrt(DRUM.k_n / 0.5 - DRUM.gamma_n**2 / (4 * 0.25))
    assert tau == pytest.approx(math.pi / w, rel=1e-15)
    assert DRUM.restitution(0.5) == pytest.approx(math.exp(-DRUM.gamma_n * tau), rel=1e-15)


def test_box_analytic_contact_values():
    """Box paper Eq. A5; dt = t_c/50 gives about 141,000 steps per drive period."""
    t_c = BOX.contact_time(0.5)
    assert 2 * math.pi / (t_c / 50) == pytest.approx(141_000, rel=5e-3)


@pytest.mark.parametrize("want_slip", [False, True])
@pytest.mark.parametrize("normal", [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0)])
def test_box_flat_wall_jacobian_matches_finite_differences(normal, want_slip):
    """Jacobian of (F_x, F_y, tau) w.r.t. (h, v, w) against a flat wall, fixed history."""
    rng = np.random.default_rng(21 + want_slip)
    n = np.array(normal)
    t = np.array([-n[1], n[0]])
    dt = 4.4446e-5
    checked = 0
    while checked < 15:
        a = 0.5
        h = a - rng.uniform(1e-5, 2e-3)
        v = n * rng.normal(0, 0.3) + t * rng.normal(0, 0.3)
        w = rng.normal(0, 1.0)
        xi = rng.normal(0, 2e-4) * (20.0 if want_slip else 1.0)
        lev = a - 0.5 * (a - h)
        vt = v @ t - lev * w
        f_n = BOX.kappa_n * (a - h) - BOX.gamma_n * (v @ n)
        f_t = -BOX.kappa_t * (xi + vt * dt) - BOX.gamma_t * vt
        margin = abs(abs(f_t) - BOX.mu * abs(f_n))
        if (abs(f_t) > BOX.mu * abs(f_n)) != want_slip or margin < 1e-3 * abs(f_n):
            continue

        def f(x, xi=xi, a=a):
            return BOX.wall_pair(x[0], x[1:3], x[3], a, 1.0, n, xi, dt)[0]

        full = BOX.wall_pair_jacobian(h, v, w, a, 1.0, n, xi, dt)[:3]
        # columns (h, v_x, v_y, w): a displacement dd of the disk changes h by n . dd
        jac = np.column_stack([full[:, :2] @ n, full[:, 2:5]])
        fd = central_difference(f, np.r_[h, v, w], [1e-9, 1e-7, 1e-7, 1e-7])
        assert_jacobian_close(jac[:, :1], fd[:, :1])
        assert_jacobian_close(jac[:, 1:3], fd[:, 1:3])
        assert_jacobian_close(jac[:, 3:], fd[:, 3:])
        checked += 1
