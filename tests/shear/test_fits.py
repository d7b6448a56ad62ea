"""The shear cell's fits on synthetic records with a known answer."""

import numpy as np
import pytest
import xarray as xr

from granpipe.shear.fits import TABLE_KEYS, event_times, point_fits, transitions
from granpipe.shear.measures import JAMMING
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
            "disk_du": (("replica", "sample", "disk"), rng.random((n_rep, s.size, n))),
            "disk_speed": (("replica", "sample", "disk"), rng.random((n_rep, s.size, n))),
            "disk_changes": (("replica", "sample", "disk"), np.zeros((n_rep, s.size, n), int)),
            **{
                f"jamming_{k}": (("replica", "sample"), 1.0 + rng.random((n_rep, s.size)))
                for k in JAMMING
            },
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


def _tables(phis, rng, lam_all, z, pressure, n=16):
    """Per-replica means at each point: the given means plus small noise."""
    out = []
    for k, _ in enumerate(phis):
        t = {key: 1.0 + 0.01 * rng.standard_normal(n) for key in TABLE_KEYS}
        t["lambda"] = -0.1 + 0.01 * rng.standard_normal(n)
        t["lambda_all"] = lam_all[k] + 0.01 * rng.standard_normal(n)
        t["z_frictionless"] = z[k] + 0.01 * rng.standard_normal(n)
        t["pressure"] = pressure[k] * np.exp(0.02 * rng.standard_normal(n))
        out.append(t)
    return out


def test_the_transition_and_the_jamming_points_of_known_means():
    rng = np.random.default_rng(1)
    phis = np.array([0.78, 0.80, 0.82, 0.84, 0.86, 0.88, 0.90])
    lam_all = 0.5 - 5.0 * (phis - 0.78)  # crosses zero at 0.88
    z = 3.0 + 25.0 * (phis - 0.80)  # reaches 4 at 0.84
    # ln P: steep below 0.83, shallow above (a break at 0.83)
    pressure = np.exp(np.where(phis < 0.83, 200 * (phis - 0.83), 10 * (phis - 0.83)))
    cfg = shear_section()["fits"]
    rows = {r.quantity: r for r in transitions(phis, _tables(phis, rng, lam_all, z, pressure),
                                               cfg)}  # fmt: skip
    star = rows["phi_lambda_all_zero"]
    assert star.value == pytest.approx(0.88, abs=0.001)
    assert star.ci_low < 0.88 < star.ci_high and star.ci_high - star.ci_low < 0.005
    assert rows["phi_J_z_frictionless"].value == pytest.approx(0.84, abs=0.001)
    assert rows["phi_J_pressure"].value == pytest.approx(0.83, abs=0.002)
    pj = rows["phi_J_pressure"]
    assert 0.828 < pj.ci_low <= pj.value <= pj.ci_high < 0.832
    diff = rows["phi_star_minus_phi_J_pressure"]
    assert diff.value == pytest.approx(0.05, abs=0.002) and diff.ci_low > 0.04
    assert rows["hexatic_at_phi_star"].value == pytest.approx(1.0, abs=0.01)
    assert np.isnan(rows["phi_lambda_zero"].value)  # λ over S keeps its sign
    assert np.isnan(rows["phi_J_z_frictional"].value)  # z_frictional stays near 1 < 3
    # a variant's rows carry its name
    names = [r.quantity for r in transitions(phis, _tables(phis, rng, lam_all, z, pressure),
                                             cfg, "[wide]")]  # fmt: skip
    assert names[1] == "phi_lambda_all_zero[wide]"
    # a single point: every crossing empty
    one = transitions(phis[:1], _tables(phis[:1], rng, lam_all, z, pressure), cfg)
    assert all(np.isnan(r.value) for r in one)


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


def test_a_vector_that_marks_the_rearranging_disks_predicts_when_and_where():
    """The whole vector's rate raised over the 0.2 s before each event predicts when (area
    near 1, interval above one half; the speed, flat, gives one half); the disks whose
    edges change at each event hold the largest |δu_i| one sample before it: found at
    precision 1 and area 1, while the random speeds give their share."""
    ds, _ = synthetic_runs(0.0)
    rng = np.random.default_rng(5)
    n_rep, S, n = ds["disk_du"].shape
    lam_all = 0.01 * rng.standard_normal((n_rep, S))
    du = rng.random((n_rep, S, n)) * 0.5
    changes = np.zeros((n_rep, S, n), dtype=np.int64)
    for r in range(n_rep):
        for e in np.flatnonzero(ds["network_changes"].values[r] >= 5):
            lam_all[r, e - 10 : e] += 1.0  # the 0.2 s before the event's sample
            movers = rng.choice(n, 2, replace=False)
            changes[r, e, movers] = 3
            du[r, e - 1, movers] = 0.9  # the largest one sample before
    ds["lyapunov_all"] = (("replica", "sample"), lam_all)
    ds["disk_du"] = (("replica", "sample", "disk"), du)
    ds["disk_changes"] = (("replica", "sample", "disk"), changes)
    res, curves = point_fits(ds, params())
    r = {x.quantity: x for x in res}
    when = r["when_auc_lambda_all"]
    assert when.value > 0.9 and when.ci_low > 0.5
    assert r["when_auc_speed"].value == pytest.approx(0.5)  # a constant: all tied
    assert r["when_positives"].value > 0
    assert r["where_precision_du"].value == 1.0 and r["where_auc_du"].value == 1.0
    assert r["where_precision_random"].value == pytest.approx(2 / n)
    assert r["where_precision_speed"].value < 0.9
    assert r["where_event_size"].value == 2.0
    roc = curves["when_roc_lambda_all"].values
    assert roc[0] >= 0 and roc[-1] == 1.0 and np.all(np.diff(roc) >= 0)


def test_noise_predicts_nothing():
    ds, _ = synthetic_runs(0.0, n_rep=12)
    rng = np.random.default_rng(6)
    ds["lyapunov_all"] = (("replica", "sample"), rng.standard_normal(ds["lyapunov_all"].shape))
    res, _ = point_fits(ds, params())
    when = {x.quantity: x for x in res}["when_auc_lambda_all"]
    assert when.ci_low < 0.5 < when.ci_high
