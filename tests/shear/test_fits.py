"""The shear cell's fits on synthetic records with a known answer."""

import numpy as np
import pytest
import xarray as xr

from granpipe.shear.fits import event_times, phi_crossing, point_fits
from tests.shear.conftest import shear_section

BLOCK, SAMPLE, RECORD = 0.004, 0.02, 12.0


def synthetic_runs(lead, n_rep=6, seed=0, bump=None):
    """λ = −0.5 except +0.5 from ``lead`` s before each event to 1.5 s after it, small
    noise; a burst of 10 network changes in the sample of each event (every 2.5-3.5 s)."""
    rng = np.random.default_rng(seed)
    t = (np.arange(round(RECORD / BLOCK)) + 0.5) * BLOCK
    s = (np.arange(round(RECORD / SAMPLE)) + 1) * SAMPLE
    lam = np.full((n_rep, t.size), -0.5) + 0.02 * rng.standard_normal((n_rep, t.size))
    changes = np.zeros((n_rep, s.size), dtype=np.int64)
    truth = []
    for r in range(n_rep):
        k = np.cumsum(rng.integers(125, 175, 4))  # samples between events: 2.5-3.5 s
        k = k[k < s.size - round(2.0 / SAMPLE)]
        changes[r, k] = 10
        ev = s[k] - SAMPLE / 2  # the event's time: the middle of its sample interval
        for e in ev:
            if bump is None:
                lam[r, (t > e - lead) & (t < e + 1.5)] += 1.0
            else:  # a bump of height 0.3 centred ``bump`` s after the event
                lam[r] += 0.3 * np.exp(-((t - e - bump) ** 2) / (2 * 0.1**2))
        truth.append(ev)
    n = 5
    ds = xr.Dataset(
        {
            "local_lyapunov": (("replica", "time"), lam),
            "global_speed": (("replica", "time"), np.ones_like(lam)),
            "network_changes": (("replica", "sample"), changes),
            "speed_lyapunov_correlation": (("replica", "sample"), np.full(changes.shape, 0.2)),
            "lyapunov_all": (("replica", "sample"), 3.0 * lam[:, :: round(SAMPLE / BLOCK)]),
            "snapshot_positions": (("replica", "disk", "xy"), np.zeros((n_rep, n, 2))),
            "snapshot_du": (("replica", "disk"), np.ones((n_rep, n))),
            "snapshot_speed": (("replica", "disk"), np.ones((n_rep, n))),
            "diameter": (("disk",), np.ones(n)),
        },
        coords={"replica": np.arange(n_rep), "time": t, "sample": s},
        attrs={"block_s": BLOCK, "sample_s": SAMPLE},
    )
    return ds, truth


def params():
    cfg = shear_section(events={"min_changes": 5, "quiet_s": 0.5},
                        fits={"aligned_before_s": 2.0, "aligned_after_s": 2.0,
                              "bootstrap_resamples": 300})  # fmt: skip
    return {"events": cfg["events"], "fits": cfg["fits"]}


def test_events_are_found_where_the_bursts_are():
    ds, truth = synthetic_runs(0.6)
    found = event_times(ds, params()["events"])
    for f, t in zip(found, truth, strict=True):
        np.testing.assert_allclose(f, t)


@pytest.mark.parametrize("lead", [0.6, -0.3])
def test_lead_time_of_a_known_step_is_recovered(lead):
    """λ̄ of the event-triggered average crosses zero where λ steps up: ``lead`` s before
    the events (a lag of 0.3 s for lead = −0.3), to within a block and the hold; the
    interval (bootstrap by replica) holds the truth and excludes zero."""
    ds, _ = synthetic_runs(lead)
    res, curves = point_fits(ds, params())
    r = {x.quantity: x for x in res}
    assert r["lead_time"].value == pytest.approx(lead, abs=2 * BLOCK)
    assert r["event_lag"].value == pytest.approx(-lead, abs=2 * BLOCK)
    assert r["lead_time"].ci_low <= lead + 2 * BLOCK and r["lead_time"].ci_high >= lead - 2 * BLOCK
    assert r["lead_time"].ci_low * r["lead_time"].ci_high > 0  # excludes zero
    assert r["correlation_all"].value == pytest.approx(0.2)
    # the same step in the whole tangent vector's rate (tripled, at the samples' resolution)
    assert r["lambda_all_lead_time"].value == pytest.approx(lead, abs=2 * SAMPLE)
    # the aligned mean: +0.5 inside the step, −0.5 well outside it
    tau, m = curves["tau"].values, curves["aligned_lambda"].values
    assert np.nanmean(m[(tau > -lead + 0.05) & (tau < 1.45)]) == pytest.approx(0.5, abs=0.01)
    assert np.nanmean(m[tau > 1.6]) == pytest.approx(-0.5, abs=0.01)
    # the time average: -0.5 plus the step's share of the record
    assert r["lambda_mean"].value == pytest.approx(
        float(ds["local_lyapunov"].values.mean()), rel=1e-12)  # fmt: skip
    # the whole tangent vector's rate: its own mean, not λ's
    assert r["lambda_all_mean"].value == pytest.approx(
        float(ds["lyapunov_all"].values.mean()), rel=1e-12)  # fmt: skip
    assert abs(r["lambda_all_mean"].value - r["lambda_mean"].value) > 0.05


def test_zero_crossing_in_phi_is_interpolated_between_points():
    rng = np.random.default_rng(1)
    phis = [0.80, 0.82, 0.84, 0.86]
    means = [m + 0.01 * rng.standard_normal(16) for m in (-0.2, -0.1, 0.1, 0.2)]
    cfg = shear_section()["fits"]
    res = phi_crossing(phis, means, cfg)
    exact = 0.82 + 0.02 * (-np.mean(means[1])) / (np.mean(means[2]) - np.mean(means[1]))
    assert res.value == pytest.approx(exact, rel=1e-12)
    assert abs(res.value - 0.83) < 0.001
    assert res.ci_low < res.value < res.ci_high and res.ci_high - res.ci_low < 0.005
    # no crossing, or a single point: NaN
    assert np.isnan(phi_crossing(phis, [m - 1.0 for m in means], cfg).value)
    assert np.isnan(phi_crossing(phis[:1], means[:1], cfg).value)


def test_a_bump_of_lambda_before_the_events_is_timed_though_it_never_turns_positive():
    """λ = −0.5 plus a bump of 0.3 centred 0.3 s before each event: λ̄ never crosses zero
    (no lead time, as at every φ of the validation scale), but its maximum sits 0.3 s
    before the events, with an interval that holds it and excludes zero."""
    ds, _ = synthetic_runs(0.0, bump=-0.3)
    res, _ = point_fits(ds, params())
    r = {x.quantity: x for x in res}
    assert np.isnan(r["lead_time"].value)
    peak = r["lambda_peak_time"]
    assert peak.value == pytest.approx(-0.3, abs=0.03)  # the smoothed top is flat
    assert peak.ci_low <= -0.3 <= peak.ci_high and peak.ci_high < 0
    # the excess over λ far from the events: the bump's mean over [−0.5, 0) and [0, 0.5)
    tau = np.arange(-125, 125) * BLOCK
    f = 0.3 * np.exp(-((tau + 0.3) ** 2) / (2 * 0.1**2))
    for key, want in (("before", f[tau < 0].mean()), ("after", f[tau >= 0].mean())):
        x = r[f"lambda_excess_{key}"]
        assert x.value == pytest.approx(want, abs=0.01) and x.ci_low <= want <= x.ci_high
