"""Continuum models: coefficients, manufactured solutions (observed order), rest states."""

import numpy as np
import pytest

from granpipe.column import continuum as c
from granpipe.column.params import parameter_set

P = parameter_set("figure1_N10")
S = 2 * P.N * P.r


def test_longwave_coefficients_of_eq38():
    co = c.longwave_coefficients(P)
    # Eq. (38): A₋ = 6.5, not the text's 13.5 (docs/column.md)
    assert (co.A_plus, co.A_minus) == pytest.approx((2.5, 6.5), rel=1e-14)
    assert co.B == pytest.approx(-1 / P.h, rel=1e-14)
    assert co.gamma == pytest.approx(co.A_minus / (36 * co.C1))


def _lw_mms(J, viscosity="as_printed"):
    co = c.longwave_coefficients(P)
    k, eps, w, th = np.pi / (2 * S), 0.2, 30.0, 0.3
    Kh2m, h, r, al, e = P.K * P.h**2 / P.m, P.h, P.r, co.alpha, P.e

    def exact(z, t):
        s = np.sin(k * z)
        return z + eps * s * np.sin(w * t + th), eps * s * w * np.cos(w * t + th)

    def forcing(z, t):
        s, cz = np.sin(k * z), np.cos(k * z)
        T, T1, T2 = np.sin(w * t + th), w * np.cos(w * t + th), -w * w * np.sin(w * t + th)
        yz, yzz = 1 + eps * k * cz * T, -eps * k * k * s * T
        vz, vzz = eps * k * cz * T1, -eps * k * k * s * T1
        visc = yzz if viscosity == "as_printed" else np.maximum(yzz, 0)
        R = (co.A_plus / 3) * yzz - (h / 3) * (co.B * yz + e * al * co.A_plus * vz) * yzz
        R += (
            h
            * h
            * (
                2 * r * al * yz**2 * yzz
                + e * al * co.B * yz * yzz * vz
                + e * al * co.A_plus / 6 * visc * vzz
            )
        )
        return eps * s * T2 * (1 + co.gamma * h * h * k * k) - (-P.g + Kh2m * R)

    out = c.solve_longwave(
        P, 0.05, dz=S / J, exact=exact, forcing=forcing, record_dt=0.05, viscosity=viscosity
    )
    return np.max(np.abs(out["y"][-1] - exact(out["z"], out["t"][-1])[0]))


def test_longwave_second_order_on_manufactured_solution():
    """y = z + ε sin(πz/2S) sin(ωt + θ), full nonlinear Eq. (35) with g and e."""
    errs = np.array([_lw_mms(J) for J in (10, 20, 40)])
    orders = np.log2(errs[:-1] / errs[1:])
    # measured 2.014, 2.003 (and 2.001, 2.000 on to J = 160)
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


def test_longwave_stays_at_rest_without_taps():
    p = P.with_(a=0.0)
    out = c.solve_longwave(p, 0.5, dz=S / 40, record_dt=0.1)
    assert np.max(np.abs(out["v"])) < 1e-9 * p.g
    assert np.max(np.abs(out["y"] - out["y"][0])) < 1e-11 * S
    assert np.allclose(out["rho"], P.m / (2 * P.r))
    # and the rest state is compressed by gravity: y_z < 1 at the bottom, = 1 at the top
    y0 = out["y"][0]
    assert (y0[1] - y0[0]) < (y0[-1] - y0[-2]) < out["z"][1] * (1 + 1e-12)


def test_bsr_stays_at_rest_without_forces():
    p = P.with_(a=0.0, g=0.0)
    out = c.solve_bsr(p, 0.3, dz=P.h / 4, kernel=False, record_dt=0.1)
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
