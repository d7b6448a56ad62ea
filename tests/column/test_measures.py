"""Column measures: the period of the tap-to-tap return map (Theorem 1) on synthetic
sequences and a real column, and its reading in the chaos map and the note."""

import numpy as np
import pytest

from granpipe.column import discrete as d
from granpipe.column.measures import chaos_map, return_period
from granpipe.column.model import physics
from granpipe.column.protocol import lyapunov_point, perturbed_start
from granpipe.seeds import replica_rng
from tests.column.test_stages import GENERIC


def _cycle(period, n_states, dim=6, noise=1e-14, seed=0):
    rng = np.random.default_rng(seed)
    orbit = rng.uniform(-1.0, 1.0, (period, dim))
    x = orbit[np.arange(n_states) % period]
    return x + noise * rng.standard_normal(x.shape)


@pytest.mark.parametrize("period", [1, 2, 3, 5])
def test_noisy_cycle_gives_its_smallest_period(period):
    x = _cycle(period, 24)
    p, dist = return_period(x, None, 8, 1e-6)
    assert p == period  # not a multiple of it
    assert dist[period - 1] < 1e-12  # the noise, ~1e-14 sqrt(dim)
    assert np.all(dist[: period - 1] > 1e-2)  # shorter lags: O(1)


def test_aperiodic_sequence_has_no_period():
    # the logistic map at r = 4 (chaotic), a period-7 cycle when only 6 are sought,
    # and a sequence that converges too slowly to repeat within the tolerance
    x = np.empty((40, 1))
    x[0] = 0.3
    for k in range(39):
        x[k + 1] = 4.0 * x[k] * (1.0 - x[k])
    assert return_period(x, None, 8, 1e-6)[0] == 0
    assert return_period(_cycle(7, 24), None, 6, 1e-6)[0] == 0
    slow = 1.0 + 4e-6 * 0.5 ** np.arange(24.0)[:, None]  # first step 2e-6, then halving
    assert return_period(slow, None, 4, 1e-6)[0] == 0
    assert return_period(slow, None, 4, 1e-5)[0] == 1


def test_slow_oscillating_approach_is_undecided_not_period_two():
    """x_k = μ^k v with μ = −0.9: lag 2 closes ten times faster than lag 1."""
    v = np.ones(4)
    x = 3e-6 * (-0.9) ** np.arange(30.0)[:, None] * v
    p, dist = return_period(x[-12:], None, 6, 1e-6)
    assert dist[1] < 1e-6 < dist[0] < 100e-6 and p == -2
    assert return_period(x[-12:], None, 6, 2e-5)[0] == 1  # looser: a fixed point


def test_modes_and_nan_break_a_period():
    x = _cycle(2, 12)
    modes = np.zeros((12, 3), dtype=np.int8)
    assert return_period(x, modes, 3, 1e-6)[0] == 2
    modes[7, 1] = d.STICK  # one state with a different contact mode: no period
    assert return_period(x, modes, 3, 1e-6)[0] == 0
    x[5, 0] = np.nan
    assert return_period(x, None, 3, 1e-6)[0] == 0
    with pytest.raises(ValueError):
        return_period(x[:5], None, 3, 1e-6)  # fewer than 2 max_period states


def test_sampling_at_tap_ends_leaves_the_run_unchanged():
    """Samples at t = kT add no step: tangent growth identical bit for bit."""
    p = physics({**GENERIC, "a": 0.002})
    outs = []
    for fracs in ((), (1.0,)):
        s = perturbed_start(p, replica_rng("column", GENERIC, 0), 1.0)
        s.dy[:], s.dv[:] = 1e-3, 1.0
        outs.append(d.simulate(p, s, 3, h=d.default_step(p, 0.2), tangent=True, sample_fracs=fracs))
    assert np.array_equal(outs[0]["log_growth"], outs[1]["log_growth"])
    assert np.all(np.isfinite(outs[1]["samples_v"])) and np.all(outs[1]["sample_modes"] >= 0)


def test_column_at_rest_each_tap_has_period_one_at_round_off():
    """A small tap on a long period: the column settles to the same rest state after
    every tap (period 1, distance at round-off, all states at rest); a strong tap on the
    same column has no period and distances far above the tolerance."""
    kw = dict(n_transient=25, n_taps=8, perturbation=1.0, twin_epsilon=1e-9, plain=False)
    kw.update(step_factor=0.2, return_max_period=3, return_taps=6, return_tolerance=1e-6)
    calm, _ = lyapunov_point({**GENERIC, "a": 0.0001, "T": 0.6}, range(2), **kw)
    assert calm["return_period"].values.tolist() == [1, 1]
    assert float(calm["return_distance"].max()) < 1e-11
    assert np.all(calm["rest_fraction"].values == 1.0)
    strong, _ = lyapunov_point({**GENERIC, "a": 0.005, "T": 0.3}, range(2), **kw)
    assert strong["return_period"].values.tolist() == [0, 0]
    assert float(strong["return_distance"].min()) > 1e-4
    m = chaos_map([calm, strong])
    here, there = {"a": 0.0001, "T": 0.6}, {"a": 0.005, "T": 0.3}
    assert int(m["period_mode"].sel(here)) == 1 and int(m["period_mode"].sel(there)) == 0
    assert float(m["period_fraction"].sel(here)) == 1.0
    assert float(m["period_fraction"].sel(there)) == 0.0
    assert m["period_counts"].sel(here).values.tolist() == [0, 2, 0, 0]
    assert m["period_counts"].sel(there).values.tolist() == [2, 0, 0, 0]
    assert np.isnan(float(m["period_fraction"].sel(a=0.0001, T=0.3)))  # no point there


def _point(a, T, periods, lam):
    """A chaos point as lyapunov_point writes it, with given periods and exponents."""
    import xarray as xr

    n = len(periods)
    return xr.Dataset(
        {
            "lambda_tap": ("replica", np.array(lam, float)),
            "lambda_twin": ("replica", np.array(lam, float)),
            "lambda_plain": ("replica", np.array(lam, float)),
            "failed": ("replica", np.zeros(n, dtype=np.int64)),
            "return_period": ("replica", np.array(periods, dtype=np.int64)),
            "rest_fraction": ("replica", np.ones(n)),
        },
        attrs={"a": a, "T": T, "return_max_period": 4, "return_taps": 8},
    )


def test_note_reads_the_periods_honestly():
    """Period 1 up to chaos → 'no'; a period 2 before chaos → 'in part'; undecided named."""
    from granpipe.column.fits import _return_periods_reading

    units = {"length": "m", "time": "s"}
    neg, pos = [-0.5, -0.6, -0.55], [1.0, 1.2, 1.1]
    flat = chaos_map([_point(1e-4, 0.3, [1, 1, 1], neg), _point(1e-3, 0.3, [0, 0, 0], pos)])
    lines, verdict = _return_periods_reading(flat, units)
    assert verdict == "no" and "period 1 at every regular amplitude" in lines[-1]
    pts = [
        _point(1e-4, 0.3, [1, 1, 1], neg),
        _point(3e-4, 0.3, [-2, -2, -2], neg),
        _point(5e-4, 0.3, [2, 2, 1], neg),
        _point(1e-3, 0.3, [0, 0, 0], pos),
    ]
    lines, verdict = _return_periods_reading(chaos_map(pts), units)
    assert verdict.startswith("in part") and "longest period 2" in verdict
    text = "\n".join(lines)
    assert "a = 0.0003: undecided (3/3)" in text and "a = 0.0005: 2 (2/3)" in text
    assert "Undecided replicas" in text
