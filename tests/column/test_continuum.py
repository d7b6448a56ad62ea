"""Continuum models: units, wave speed, observed order, rest states (docs/column.md)."""

import numpy as np
import pytest

from granpipe.column import continuum as c
from granpipe.column.model import ColumnParams, parameter_set

P = parameter_set("figure1_N10")
S = 2 * P.N * P.r


def test_longwave_coefficients_of_eq38():
    co = c.longwave_coefficients(P)
    # Eq. (38): A₋ = 6.5, not the text's 13.5 (docs/column.md)
    assert (co.A_plus, co.A_minus) == pytest.approx((2.5, 6.5), rel=1e-14)
    assert co.B == pytest.approx(-1 / P.h, rel=1e-14)
    assert co.gamma == pytest.approx(co.A_minus / (36 * co.C1))


def test_printed_eq35_wave_speed_depends_on_units():
    """The printed C(1) = A₊/3 − hB/3 + 2rαh² carries a length²: cgs and SI disagree."""
    si = ColumnParams(N=10, m=1e-3, r=0.01, g=9.8067, K=P.K * 1e-3, e=0.09, a=0.0106,
                        omega=P.omega, T=1.0)  # fmt: skip
    cgs, mks = c.longwave_coefficients(P), c.longwave_coefficients(si)
    assert cgs.C1 == pytest.approx(5.1667, rel=1e-4)  # 2.5/3 + 1/3 + 4 cm²
    assert mks.C1 == pytest.approx(1.1671, rel=1e-4)  # ... + 4e-4 m²
    # the same column: h sqrt(K/m) is the same speed in both systems, C(1) is not
    assert P.h * np.sqrt(P.K / P.m) / 100 == pytest.approx(si.h * np.sqrt(si.K / si.m))


def _same_column_in_si(p):
    return ColumnParams(N=p.N, m=p.m * 1e-3, r=p.r * 1e-2, g=p.g * 1e-2, K=p.K * 1e-3,
                          e=p.e, a=p.a * 1e-2, omega=p.omega, T=p.T)  # fmt: skip


def test_same_column_in_cgs_and_si_gives_the_same_dimensionless_solution():
    si = _same_column_in_si(P)
    q_cgs, q_si = c.dimensionless(P), c.dimensionless(si)
    for f in ("g", "a", "omega", "T"):
        assert getattr(q_si, f) == pytest.approx(getattr(q_cgs, f), rel=1e-14), f
    t_end = 0.3 * q_cgs.T  # through the first tap and past it
    a = c.solve_longwave(q_cgs, t_end, dz=1 / 8, record_dt=t_end / 30)
    b = c.solve_longwave(q_si, t_end, dz=1 / 8, record_dt=t_end / 30)
    assert a["y"].shape == b["y"].shape
    moved = np.max(np.abs(a["y"] - a["y"][0]))
    assert moved > 0.1  # the tap moved the column by a tenth of a diameter or more
    assert np.max(np.abs(a["y"] - b["y"])) < 1e-10 * moved
    a = c.solve_bsr(q_cgs, 5.0, dz=1 / 4, record_dt=0.5)
    b = c.solve_bsr(q_si, 5.0, dz=1 / 4, record_dt=0.5)
    assert np.max(np.abs(a["tracers"] - b["tracers"])) < 1e-10


def _phase_speed(N, k, dz=1 / 16, C0=0.1, eps=1e-4):
    """Phase speed of a standing mode sin(kz) on a pre-compressed column, fixed ends."""
    q = ColumnParams(N=N, m=1.0, r=0.5, g=0.0, K=1.0, e=0.0, a=0.0, omega=1.0, T=1e9)
    z = np.linspace(0, N, int(round(N / dz)) + 1)
    Y = z * (1 - C0) + eps * np.sin(k * z)
    top = (np.array([0.0, 1e4]), np.full(2, N * (1 - C0)), np.zeros(2))
    period = 2 * np.pi / k
    out = c.solve_longwave(q, 2.2 * period, dz=dz, top=top, record_dt=period / 400,
                           initial=(Y, np.zeros_like(Y)))  # fmt: skip
    s = np.sin(k * z)
    amp = (out["y"] - z * (1 - C0)) @ s / (s @ s)
    i = np.where(np.sign(amp[1:]) != np.sign(amp[:-1]))[0]
    t0 = out["t"][i] - amp[i] * (out["t"][i + 1] - out["t"][i]) / (amp[i + 1] - amp[i])
    return np.pi / np.mean(np.diff(t0)) / k


@pytest.mark.parametrize("N", [10, 20])
def test_longwave_speed_is_the_chains_sound_speed_to_the_order_of_the_expansion(N):
    """Chain: ω = 2 sin(k/2) (units h, sqrt(m/K)), speed 1 − k²/24 + O(k⁴)."""
    k = np.pi / N
    speed = _phase_speed(N, k)
    chain = 2 * np.sin(k / 2) / k
    # agreement to O(k⁴): far inside the k²/24 dispersive correction itself
    assert abs(speed - chain) < 0.05 * k**2 / 24, (speed, chain)
    assert abs(speed - 1.0) > 0.5 * k**2 / 24  # the dispersion is there


def test_longwave_second_order_on_a_smooth_problem():
    """A smooth velocity pulse in the resting column (no tap): successive differences."""
    q = ColumnParams(N=10, m=1.0, r=0.5, g=0.025, K=1.0, e=0.09, a=0.0, omega=1.0, T=1e9)
    zi = np.arange(1, 11) - 0.5
    ys = []
    for k in (4, 8, 16, 32):
        z = np.linspace(0, 10, 10 * k + 1)
        init = (c.longwave_equilibrium(q, z), 0.02 * np.exp(-(((z - 5) / 1.5) ** 2)))
        out = c.solve_longwave(q, 30.0, dz=1 / k, record_dt=1.0, initial=init)
        ys.append(np.array([np.interp(zi, out["z"], row) for row in out["y"]]))
    e = np.array([np.max(np.abs(a - b)) for a, b in zip(ys[:-1], ys[1:], strict=True)])
    orders = np.log2(e[:-1] / e[1:])
    # measured 2.010, 2.003 (2.001 on to h/64)
    assert np.all(np.abs(orders - 2) < 0.1), orders


def _bsr_mms(H):
    Z = S + 4 * P.h
    k, U, w = np.pi / (2 * Z), 20.0, 10.0
    b, cc = 7 * P.h, 3 * P.h
    xg, wg = np.polynomial.legendre.leggauss(60)
    yq = np.concatenate([-P.h / 2 * (xg + 1), P.h / 2 * (xg + 1)])
    wq = np.concatenate([wg, wg]) * P.h / 2

    def exact(z, t):
        return U * np.sin(k * z) * (1 + 0.5 * np.sin(w * t))

    def forcing(z, t):
        f = 1 + 0.5 * np.sin(w * t)
        u, uz = U * np.sin(k * z) * f, U * k * np.cos(k * z) * f
        ut = U * np.sin(k * z) * 0.5 * w * np.cos(w * t)
        Y, Zc = yq[None, :], z[:, None]
        base = np.exp(-(((Zc + Y) - b) ** 2) / (2 * cc * cc)) / (cc * np.sqrt(2 * np.pi))
        base = base * (2 * P.r - np.abs(Y))
        # u increases with z, so σ(u(z + y) − u(z)) = sgn(y)
        I0, I1 = (base * wq).sum(1), (base * np.sign(Y) * wq).sum(1)
        return ut + u * uz + P.g + P.K / P.m * (I0 - P.e * I1)

    out = c.solve_bsr(
        P, 0.2, dz=P.h / H, exact=exact, forcing=forcing, record_dt=0.2, stop_when_collapsed=False
    )
    sel = out["z"] < Z - 2 * P.h  # outflow top: errors there leave the domain
    return np.max(np.abs(out["u"][-1][sel] - exact(out["z"], out["t"][-1])[sel]))


def test_bsr_second_order_on_manufactured_solution():
    """u = U sin(πz/2Z)(1 + sin(ωt)/2): Burgers flux, kernel integral with e and σ jumps."""
    errs = np.array([_bsr_mms(H) for H in (4, 8, 16)])
    orders = np.log2(errs[:-1] / errs[1:])
    # measured 2.003, 2.001 (and 2.000 at H = 32)
    assert np.all(np.abs(orders - 2) < 0.1), orders


def test_longwave_rest_state_is_the_chains_and_stays_at_rest():
    q = c.dimensionless(P).with_(a=0.0)
    out = c.solve_longwave(q, 50.0, dz=1 / 8, record_dt=10.0)
    assert np.max(np.abs(out["v"])) < 1e-12
    assert np.max(np.abs(out["y"] - out["y"][0])) < 1e-12 * q.N
    # compression C = 1 − y_z is the chain's G (N − z) at every half node (Eq. 26)
    zh = out["z_cell"]
    C = 1 - np.diff(out["y"][0]) / np.diff(out["z"])
    assert C == pytest.approx(q.g * (q.N - zh), rel=1e-12)
    assert out["rho"][0] == pytest.approx(1 / (1 - q.g * (q.N - zh)), rel=1e-12)


def test_bsr_stays_at_rest_without_forces():
    p = P.with_(a=0.0, g=0.0)
    out = c.solve_bsr(p, 0.3, dz=P.h / 4, kernel="none", record_dt=0.1)
    assert np.all(out["u"] == 0.0)
    assert np.array_equal(out["rho"][-1], out["rho"][0])
    assert np.allclose(out["tracers"], out["tracers"][0])


def test_bsr_as_printed_has_no_rest_state():
    """The even kernel of Eq. (45) is a downward body force at rest (docs/column.md, BSR)."""
    dz = P.h / 8
    z = (np.arange(int(round((S + 4 * P.h) / dz))) + 0.5) * dz
    F = c.bsr_kernel_force(P, z, np.zeros_like(z), dz)
    assert np.all(F < -P.g)  # pulls down everywhere, more than gravity alone
    b = 7 * P.h
    # at z = b the integral is ≈ Θ(0) h² (the kernel is nearly flat over ±h)
    peak = -P.g - P.K / P.m * P.h**2 / (3 * P.h * np.sqrt(2 * np.pi))
    assert F[np.argmin(np.abs(z - b))] == pytest.approx(peak, rel=0.02)
    # the free top of the hybrid treatment: no elastic force above φ
    F_cut = c.bsr_kernel_force(P, z, np.zeros_like(z), dz, phi=10.0)
    assert np.all(F_cut[z > 10.0] == -P.g)


def test_bsr_derived_kernel_is_normalised_and_gives_the_chains_sound_speed():
    """Σ_j W_j Δ_j = 1: the bulk of the rest state balances gravity and the long-wave
    frequency ω² = Σ_j (W_j/Δ_j) 4 sin²(kΔ_j/2) tends to k² (sound speed 1, the chain's)."""
    for ds, b in ((1 / 4, 1.0), (1 / 16, 1.0), (1 / 16, 0.5), (1 / 8, 0.0)):
        W = c.bsr_bond_weights(ds, b)
        delta = np.arange(1, W.size + 1) * ds
        assert np.sum(W * delta) == pytest.approx(1.0, rel=1e-13)
        k = 1e-3
        omega2 = np.sum(W / delta * 4 * np.sin(k * delta / 2) ** 2)
        assert omega2 / k**2 == pytest.approx(1.0, rel=1e-5)
        # short waves stay bounded and stable: ω² ≥ 0 for every k
        ks = np.linspace(0, np.pi / ds, 200)
        assert np.all(np.sum(W / delta * 4 * np.sin(np.outer(ks, delta) / 2) ** 2, axis=1) >= 0)


def test_bsr_derived_holds_the_chains_rest_state_where_printed_falls():
    """The odd kernel on the compression balances gravity on the chain's rest map wherever
    every bond is present; only within one kernel reach of the free top does it settle."""
    q = c.dimensionless(P)
    for K, b in ((4, 1.0), (16, 1.0), (8, 0.0)):
        ds = 1 / K
        s = (np.arange(q.N * K) + 0.5) * ds
        W = c.bsr_bond_weights(ds, b)
        y = c.bsr_rest_map(q, s)
        yg = c.bsr_rest_map(q, -(np.arange(W.size) + 0.5) * ds)
        a = np.empty_like(s)
        c._bsr_accel(y, np.zeros_like(s), yg, np.zeros_like(yg), W, ds, q.g, q.e, 0.01, s.size, a)
        bulk = s < q.N - W.size * ds
        assert np.max(np.abs(a[bulk])) < 1e-12 * q.g  # floor contact included
        assert np.max(np.abs(a[~bulk])) > 1e-3 * q.g  # the top is out of balance ...
        rest = c.bsr_rest_state(q, s, W, ds)  # ... and settles into its own rest state
        c._bsr_accel(rest, np.zeros_like(s), yg, np.zeros_like(yg), W, ds, q.g, q.e, 0.01,
                     s.size, a)  # fmt: skip
        assert np.max(np.abs(a)) < 1e-8 * q.g
        shift = np.max(np.abs(rest - y))
        if b > 0:  # by a fraction of one particle's weight (measured 0.2-0.25 G)
            assert shift < 0.3 * q.g
        else:  # point particles: every sub-lattice of labels is its own chain with its
            # own top and settles on its own, through the whole depth (measured 4.4 G)
            assert shift > 2 * q.g
    # printed Eq. (45) on the same column: a body force beyond gravity everywhere
    dz = 1 / 8
    z = (np.arange(int(round((q.N + 4) / dz))) + 0.5) * dz
    assert np.all(c.bsr_kernel_force(q, z, np.zeros_like(z), dz) < -q.g)


def test_bsr_derived_point_kernel_on_the_particle_labels_is_the_smooth_chain():
    """With the point-particle kernel and one material point per particle the derived BSR
    is the chain of Eq. (24) with the smooth sign: it must follow the discrete solver's
    smooth model (Eq. 30 with a step χ sharp to 1e-9) through a tap."""
    from granpipe.column import discrete as d

    q = c.dimensionless(P)
    w = 0.01
    sol = c.solve_bsr_derived(q, q.T, ds=1.0, kernel_width=0.0, sigma_width=w,
                              record_dt=q.T / 50, cfl=0.25)  # fmt: skip
    qs = q.with_(smooth=True, alpha_sigma=1 / w, alpha_chi=1e9)
    disc = d.simulate(qs, d.initial_state(qs), 1, h=d.default_step(qs, 0.05),
                      record_dt=q.T / 50, sample_fracs=())  # fmt: skip
    n = min(sol["t"].size, disc["t"].size)
    moved = np.max(np.abs(disc["y"][:n] - disc["y"][0]))
    assert moved > 0.1  # the tap lifts the column by a sizeable part of h
    # measured 3.6e-6 h, shrinking like cfl² (4.4e-5 h at the default cfl = 1)
    assert np.max(np.abs(sol["tracers"][:n] - disc["y"][:n])) < 1e-5 * moved


def test_bsr_derived_converges_under_refinement():
    """On the Fig. 2 problem (the long tap) successive differences of the smooth-kernel
    model shrink at an order near 1.5 (measured 1.4) and the material stays ordered."""
    from granpipe.column.model import physics

    fig2 = {"N": 10, "m": 1.0, "r": 1.0, "g": 980.67, "stiffness_factor": 2.0, "e": 0.09,
            "a": 1.06, "tap_duration": 0.5, "T": 1.0}  # fmt: skip
    q = c.dimensionless(physics(fig2))
    ys = []
    for K in (4, 8, 16):
        sol = c.solve_bsr_derived(q, 0.5 * q.T, ds=1 / K, record_dt=q.T / 20)
        assert sol["min_spacing"] > 0.5
        ys.append(sol["tracers"])
    e = [np.max(np.abs(a - b)) for a, b in zip(ys[:-1], ys[1:], strict=True)]
    assert np.log2(e[0] / e[1]) > 1.0, e
