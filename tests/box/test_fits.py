"""The box fits on synthetic point tables with known thresholds, breakpoints and barriers,
and the threshold interpolation on a Γ grid.

The analysis helpers check the generic regressions; here the glue: grouping by
(init, N_l, walls), crystal points whose crystal broke left out, criteria and scales,
regions from the T_g* breakpoints handed to the Arrhenius fits, summary rows next to the
paper's numbers, and intervals that cover the truth on noisy data.
"""

import math

import numpy as np
import pandas as pd
import pytest

from granpipe.analysis.summary import summary_frame
from granpipe.box import fits, measures
from granpipe.box.fits import threshold_crossing, threshold_from_flags
from granpipe.box.layout import Walls
from granpipe.box.measures import BOUNCING_THRESHOLD, CONVECTION_THRESHOLD

DETECTION = {
    "convection_s_c": 1.0,
    "bouncing_s_b": 1.0 / 30.0,
    "detachment_gap": 1e-3,
    "detachment_fraction": 0.02,
    "roll_significance": 3.0,
    "roll_displacement": 1.0,
}
# every point in the T_g* fits (the synthetic law holds from Γ = 0.8), weighted barriers
FITS = {"breakpoints_random": 1, "breakpoints_crystal": 2, "confidence": 0.95,
        "bootstrap": 200, "N_l": None, "temperature_points": "all",
        "crystal_points": "intact", "slip_weights": "weighted"}  # fmt: skip

GAMMA = np.round(np.linspace(0.8, 4.0, 17), 3)
K_BREAK = {"random": [3.3], "crystal": [2.0, 6.0]}
SLOPES = {"random": [1.0, 2.5], "crystal": [0.5, 3.0, 1.2]}
E_B = {"random": {"all": 7.0}, "crystal": {"A2": 30.0, "B": 7.0}}

W6 = "mu_w=0.6,walls=shaken,torque=lever"
W0 = "mu_w=0.0,walls=shaken,torque=lever"


def _tg(init, K):
    """Continuous piecewise power law T_g*(K_m) through T_g*(1) = 0.01."""
    x = np.log(K)
    y = math.log(0.01) + SLOPES[init][0] * x
    for k, b in enumerate(np.log(K_BREAK[init])):
        y = y + (SLOPES[init][k + 1] - SLOPES[init][k]) * np.clip(x - b, 0, None)
    return np.exp(y)


def _table(seed, mu_w=0.6, side_walls="shaken"):
    rng = np.random.default_rng(seed)
    rows = []
    for init in ("random", "crystal"):
        for n_l in (20, 40):
            for g in GAMMA:
                K = g * g
                tg = _tg(init, K)
                trials = 20000
                if init == "random":
                    p = 0.5 * math.exp(-7.0 / K)
                elif K <= K_BREAK["crystal"][0]:
                    p = 0.0  # region A1: no slip at all
                elif K <= K_BREAK["crystal"][1]:
                    # continuous with region B at K_m = 6
                    p = 0.1 * math.exp(-7.0 / 6.0) * math.exp(-30.0 / K + 30.0 / 6.0)
                else:
                    p = 0.1 * math.exp(-7.0 / K)
                n_slips = rng.binomial(trials, p)
                rows.append(
                    {
                        "point": f"N_l={n_l},Gamma={float(g)!r},init={init},mu_w={mu_w!r},"
                        f"walls={side_walls},torque=lever",
                        "mu_w": mu_w,
                        "side_walls": side_walls,
                        "wall_torque": "lever",
                        "N_l": n_l,
                        "N": 20 * n_l,
                        "Gamma": g,
                        "K_m": K,
                        "init": init,
                        "replicas": 1,
                        "measured_periods": 200,
                        "wall_seconds": 10.0,
                        "steps": 1000,
                        "ns_per_particle_step": 50.0,
                        # s_b grows exponentially through σ/30 at Γ = 1.1; s_c through σ
                        # at Γ = 1.9 (random) / 2.7 (crystal)
                        "s_b": (1 / 30) * math.exp(4.0 * (g - 1.1)),
                        "s_c": math.exp(2.0 * (g - (1.9 if init == "random" else 2.7))),
                        # the roll score through 3 at Γ = 2.5, the centre risen 10 σ
                        "roll_significance": 5.0 * (g - 1.9),
                        "roll_displacement": 10.0,
                        "detachment_fraction": max(0.0, 0.3 * (g - 1.0)),
                        "T_g": tg * math.exp(0.05 * rng.standard_normal()),
                        "T_g_sem": 0.05 * tg,
                        "p_s": n_slips / trials,
                        "p_s_sem": math.sqrt(max(n_slips, 1)) / trials,
                        "n_slips": n_slips,
                        "n_trials": trials,
                        "crystal_intact": 1,
                        "crystal_intact_ramp": 1,
                        "psi6_ramp": 0.995,
                        "dislocations_ramp": 0,
                        "psi6_start": 0.99,
                        "psi6_end": 0.98,
                        "hexagonal_start": 1.0,
                        "hexagonal_end": 0.99,
                        "dislocations_start": 0,
                        "dislocations_end": 0,
                    }
                )
    return fits.roll_levels(pd.DataFrame(rows), DETECTION)


def test_thresholds_interpolate_between_bracketing_grid_points():
    ths = fits.thresholds_table(_table(0), DETECTION)
    assert len(ths) == 2 * 2 * 4
    for r in ths.itertuples():
        assert r.status == "crossed" and r.Gamma_low < r.Gamma < r.Gamma_high
        assert r.Gamma_high - r.Gamma_low == pytest.approx(0.2)
    assert (ths["mu_w"] == 0.6).all()
    by = {(r.init, r.N_l, r.criterion): r.Gamma for r in ths.itertuples()}
    # log interpolation of an exponential measure is exact
    assert by[("random", 20, "bouncing")] == pytest.approx(1.1, abs=1e-9)
    assert by[("random", 40, "convection")] == pytest.approx(1.9, abs=1e-9)
    assert by[("crystal", 20, "convection")] == pytest.approx(2.7, abs=1e-9)
    # detachment 0.3 (Γ - 1) reaches 0.02 at Γ = 1.0667, linear between 1.0 and 1.2
    assert by[("crystal", 40, "detachment")] == pytest.approx(1.0 + 0.02 / 0.3, abs=1e-9)
    # the roll score 5 (Γ - 1.9) reaches 3 at Γ = 2.5, linear
    assert by[("random", 20, "rolls")] == pytest.approx(2.5, abs=1e-9)


def test_the_roll_onset_waits_for_the_bed_to_have_moved():
    """With the score above 3 everywhere (a steady drift scores so), the roll onset is
    where the centre's rise reaches ``roll_displacement`` (here 0.5 (Γ - 1) σ: 1 σ at
    Γ = 3), and at the grid's start under the score alone."""
    table = _table(0).assign(
        roll_significance=8.0, roll_displacement=lambda t: 0.5 * (t["Gamma"] - 1)
    )
    by = {}
    for d_min in (1.0, 0.0):
        det = {**DETECTION, "roll_displacement": d_min}
        ths = fits.thresholds_table(fits.roll_levels(table, det), det)
        by[d_min] = ths[(ths["criterion"] == "rolls") & (ths["init"] == "random")
                        & (ths["N_l"] == 20)].iloc[0]  # fmt: skip
    assert by[1.0]["Gamma"] == pytest.approx(3.0, abs=1e-9) and by[1.0]["status"] == "crossed"
    assert by[0.0]["status"] != "crossed" and by[0.0]["Gamma_high"] == pytest.approx(0.8)


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_segmented_and_arrhenius_fits_cover_the_truth(seed):
    """Each interval covers the truth and is no wider than the data allow: at 5 % scatter
    of T_g* over 17 points and 20,000 trials per point, the widths seen over these seeds
    are at most 0.22 of a breakpoint, 0.44 in a slope and 0.55 of a barrier; the bounds
    below are about twice that (an infinite or a useless interval fails)."""
    table = _table(seed)
    tfits = fits.temperature_fits(table, FITS, DETECTION)
    sfits = fits.slip_fits(table, tfits, FITS)
    for (init, n_l, walls), tf in tfits.items():
        assert tf["regions"] == (["A", "B"] if init == "random" else ["A1", "A2", "B"])
        for true, est, (lo, hi) in zip(
            K_BREAK[init], tf["breakpoints_K_m"], tf["breakpoints_K_m_ci"], strict=True
        ):
            assert lo <= true <= hi, (init, n_l, true, est, lo, hi)
            assert hi - lo < 0.5 * true, (init, n_l, true, lo, hi)
        for true, (lo, hi) in zip(SLOPES[init], tf["slope_ci"], strict=True):
            assert lo <= true <= hi
            assert hi - lo < 1.0, (init, n_l, true, lo, hi)
        slip = sfits[(init, n_l, walls)]
        for region, true in E_B[init].items():
            af = slip[region]
            assert af.E_b_ci[0] <= true <= af.E_b_ci[1], (init, region, af.E_b, af.E_b_ci)
            assert af.E_b_ci[1] - af.E_b_ci[0] < 1.2 * true, (init, region, af.E_b_ci)
        if init == "crystal":
            # A1 has no slip: no barrier, only upper bounds, and the paper's "exactly zero"
            assert math.isnan(slip["A1"].E_b) and len(slip["A1"].zero_upper) > 0


def test_summary_rows_carry_paper_values_and_fit_cleanly():
    table = _table(4)
    ths = fits.thresholds_table(table, DETECTION)
    tfits = fits.temperature_fits(table, FITS, DETECTION)
    sfits = fits.slip_fits(table, tfits, FITS)
    df = summary_frame(fits.summary_rows(table, ths, tfits, sfits)).set_index("quantity")
    assert df.loc[f"K_m_break_1[N_l=20,init=random,{W6}]", "paper_value"] == 3.3
    assert df.loc[f"E_b_A2[N_l=40,init=crystal,{W6}]", "paper_value"] == 130.0
    assert df.loc[f"E_b_B[N_l=40,init=crystal,{W6}]", "paper_value"] == 7.0
    assert df.loc[f"E_b_all[N_l=20,init=random,{W6}]", "paper_value"] == 7.0
    assert df.loc[f"psi6_at_measurement_start[N_l=20,Gamma=0.8,init=crystal,{W6}]",
                  "value"] == 0.99  # fmt: skip
    assert df.loc[f"crystal_intact_points[N_l=20,init=crystal,{W6}]", "value"] == 17
    row = df.loc[f"Gamma_convection[N_l=20,init=crystal,{W6}]"]
    assert row["ci_low"] == pytest.approx(2.6) and row["ci_high"] == pytest.approx(2.8)
    assert (df["study"] == "box").all()
    ds = fits.fits_datasets(table, ths, tfits, sfits)
    assert set(ds) == {"phase_diagram", "temperature", "slips"}


def _fit_all(table, crystal_points="intact"):
    table = table.assign(used=fits.used_mask(table, crystal_points))
    ths = fits.thresholds_table(table, DETECTION)
    tfits = fits.temperature_fits(table, FITS, DETECTION)
    sfits = fits.slip_fits(table, tfits, FITS)
    return ths, tfits, sfits


def test_a_broken_crystal_point_is_left_out_of_the_crystal_fits():
    table = _table(5)
    broken = (table["init"] == "crystal") & (table["Gamma"] == 1.6)
    # a shattered bed: slips everywhere, hot, convecting; flagged by the crystal check
    table.loc[broken, ["crystal_intact", "p_s", "n_slips", "T_g", "s_c"]] = [
        0,
        0.3,
        6000,
        5.0,
        10.0,
    ]
    ths, tfits, sfits = _fit_all(table)
    ths0, tfits0, sfits0 = _fit_all(table[~broken].reset_index(drop=True))
    pd.testing.assert_frame_equal(ths, ths0)
    for key in tfits0:
        assert np.array_equal(tfits[key]["breakpoints_K_m"], tfits0[key]["breakpoints_K_m"])
        for region, af in sfits0[key].items():
            assert sfits[key][region].E_b == af.E_b or math.isnan(af.E_b)
    df = summary_frame(fits.summary_rows(table, ths, tfits, sfits)).set_index("quantity")
    row = df.loc[f"crystal_intact_points[N_l=20,init=crystal,{W6}]"]
    assert (row["value"], row["n"]) == (16, 17)
    # without the flag the same point does change the crystal fits; labelled by their
    # initialisation (the paper's reading, the default) every crystal point is used
    table.loc[broken, "crystal_intact"] = 1
    ths1, _, _ = _fit_all(table)
    assert not ths1.equals(ths0)
    table.loc[broken, "crystal_intact"] = 0
    ths2, _, _ = _fit_all(table, "initialisation")
    pd.testing.assert_frame_equal(ths2, ths1)
    with pytest.raises(ValueError, match="crystal_points"):
        fits.used_mask(table, "whole")


def test_the_temperature_break_is_fitted_inside_the_bouncing_bed():
    """The comoving bed (no detachment below Γ ≈ 1.07) is nearly cold, T_g* ~ 1e-10, and
    its step to the bouncing bed takes the single breakpoint when every point is fitted;
    over the bouncing points only, the break in the bouncing bed's law (K_m = 3.3) is
    found, as the paper's regions A and B both lie inside the bouncing bed."""
    table = _table(9)
    comoving = table["detachment_fraction"] <= DETECTION["detachment_fraction"]
    assert set(table.loc[comoving, "Gamma"]) == {0.8, 1.0}
    table.loc[comoving, ["T_g", "T_g_sem"]] = [1e-10, 5e-12]
    key = (  # the random start at N_l = 20
        "random", 20, Walls(0.6, "shaken", "lever"),
    )  # fmt: skip
    bouncing = fits.temperature_fits(table, {**FITS, "temperature_points": "bouncing"},
                                     DETECTION)[key]  # fmt: skip
    every = fits.temperature_fits(table, FITS, DETECTION)[key]
    lo, hi = bouncing["breakpoints_K_m_ci"][0]
    assert lo <= 3.3 <= hi and bouncing["n_points"] == len(GAMMA) - 2
    assert every["n_points"] == len(GAMMA)  # ... the step takes the break, far below 3.3
    assert every["breakpoints_K_m"][0] < 2.0 and every["breakpoints_K_m_ci"][0][1] < 3.3
    with pytest.raises(ValueError, match="temperature_points"):
        fits.temperature_fits(table, {**FITS, "temperature_points": "hot"}, DETECTION)


def test_both_readings_of_the_barrier_fit_are_given():
    """The reading of ``slip_weights`` under the region's name, the other with its suffix:
    unweighted, the least-squares line through ln p_s; weighted, by the points' errors."""
    from granpipe.analysis import regression

    table = _table(10)
    key = ("random", 40, Walls(0.6, "shaken", "lever"))
    g = table[(table["init"] == "random") & (table["N_l"] == 40)].sort_values("Gamma")
    K, p = g["K_m"].to_numpy(), g["p_s"].to_numpy()
    plain = regression.arrhenius_fit(K, p_s=p, n_trials=g["n_trials"].to_numpy(), level=0.95)
    x, y = 1.0 / K[p > 0], np.log(p[p > 0])
    assert plain.E_b == pytest.approx(-np.polyfit(x, y, 1)[0], rel=1e-9)
    for main, other in (("unweighted", "weighted"), ("weighted", "unweighted")):
        cfg = {**FITS, "slip_weights": main}
        sfits = fits.slip_fits(table, fits.temperature_fits(table, cfg, DETECTION), cfg)[key]
        assert {"all", f"all_{other}", "A", "B", f"A_{other}", f"B_{other}"} <= set(sfits)
        unweighted = sfits["all" if main == "unweighted" else "all_unweighted"]
        assert unweighted.E_b == pytest.approx(plain.E_b, rel=1e-12)
        weighted = sfits["all" if main == "weighted" else "all_weighted"]
        assert weighted.E_b != pytest.approx(plain.E_b, rel=1e-6)
        assert weighted.E_b_ci[0] <= 7.0 <= weighted.E_b_ci[1]


def test_each_replica_as_a_point_of_the_barrier_fit():
    """Three replicas per point whose p_s scatter by a factor e^{±0.5} about a barrier of
    7: pooled, one point per Γ (the mean of its replicas); each, three points per Γ, the
    least-squares line through every replica's ln p_s. Both intervals cover 7."""
    from granpipe.analysis import regression

    rng = np.random.default_rng(3)
    table = _table(3)
    trials = table["n_trials"].to_numpy()
    p_rep = [
        0.5 * np.exp(-7.0 / k + 0.5 * rng.standard_normal(3)) if init == "random" else np.full(3, p)
        for k, init, p in zip(table["K_m"], table["init"], table["p_s"], strict=True)
    ]  # fmt: skip
    slips = [rng.binomial(n, p) for n, p in zip(trials, p_rep, strict=True)]
    table = table.assign(
        replicas=3,
        p_s_replica=[tuple(k / n) for k, n in zip(slips, trials, strict=True)],
        p_s_sem_replica=[(np.nan,) * 3] * len(table),
        n_slips_replica=[tuple(k) for k in slips],
        n_trials_replica=[(n,) * 3 for n in trials],
        p_s=[k.sum() / (3 * n) for k, n in zip(slips, trials, strict=True)],
        n_slips=[k.sum() for k in slips],
        n_trials=3 * trials,
    )  # fmt: skip
    key = ("random", 40, Walls(0.6, "shaken", "lever"))
    g = table[(table["init"] == "random") & (table["N_l"] == 40)]
    K = np.repeat(g["K_m"].to_numpy(), 3)
    p = np.concatenate([np.asarray(v) for v in g["p_s_replica"]])
    line = regression.arrhenius_fit(K, p_s=p, n_trials=np.full(len(K), 1.0e9), level=0.95)
    out = {}
    for each in fits.SLIP_REPLICAS:
        cfg = {**FITS, "slip_weights": "unweighted", "slip_replicas": each}
        out[each] = fits.slip_fits(table, fits.temperature_fits(table, cfg, DETECTION), cfg)[key]
        fit = out[each]["all"]
        assert fit.E_b_ci[0] <= 7.0 <= fit.E_b_ci[1], (each, fit)
    assert out["each"]["all"].n_points == (p > 0).sum() > 2.5 * out["pooled"]["all"].n_points
    assert out["each"]["all"].E_b == pytest.approx(line.E_b, rel=1e-12)
    assert out["pooled"]["all"].E_b != pytest.approx(line.E_b, rel=1e-6)
    with pytest.raises(ValueError, match="slip_replicas"):
        fits.slip_fits(table, {}, {**FITS, "slip_replicas": "median"})


def test_the_crystals_regions_split_at_its_convection_onset():
    """``crystal_regions: convection`` moves A2/B from the second T_g* break (K_m 6 here)
    to the crystal's Eq. (B2) onset (Γ 2.7, K_m 7.29): B loses the points between, A2
    gains them; an onset at the break gives the temperature reading's fits; no onset on
    the grid refuses A2 and B, saying why."""
    table = _table(4)
    key = ("crystal", 40, Walls(0.6, "shaken", "lever"))
    base = {**FITS, "slip_weights": "unweighted"}
    tf = fits.temperature_fits(table, base, DETECTION)
    ths = fits.thresholds_table(table, DETECTION)
    onsets = fits.convection_onsets(ths)
    assert onsets[key] == pytest.approx(2.7**2, rel=1e-9)
    temp = fits.slip_fits(table, tf, base)[key]
    conv = fits.slip_fits(table, tf, {**base, "crystal_regions": "convection"}, onsets)[key]
    between = (
        (table["init"] == "crystal")
        & (table["N_l"] == 40)
        & (table["K_m"] > tf[key]["breakpoints_K_m"][1])
        & (table["K_m"] < onsets[key])
    )
    assert between.sum() > 0
    assert conv["B"].n_points == temp["B"].n_points - between.sum()
    assert conv["A2"].n_points == temp["A2"].n_points + between.sum()
    assert conv["all"].E_b == temp["all"].E_b
    at_break = {key: float(tf[key]["breakpoints_K_m"][1])}
    same = fits.slip_fits(table, tf, {**base, "crystal_regions": "convection"}, at_break)[key]
    assert same["A2"].E_b == pytest.approx(temp["A2"].E_b, rel=1e-12)
    none = fits.slip_fits(table, tf, {**base, "crystal_regions": "convection"}, {})[key]
    assert math.isnan(none["A2"].E_b) and "onset" in none["B"].note
    with pytest.raises(ValueError, match="crystal_regions"):
        fits.slip_fits(table, tf, {**base, "crystal_regions": "bogus"})


def test_the_crystals_regions_split_where_its_slip_curve_bends():
    """``crystal_regions: slips``: the crystal slips with a barrier of 100 up to K_m = 9
    and of 7 above (continuous there), its second T_g* break at K_m 6. The two-segment fit
    of ln p_s against 1/K_m finds the bend at 9 and the regions split there recover both
    barriers exactly; the T_g* split mixes them. Too few slipping points refuse A2 and B,
    saying why, and keep the bend's row."""
    table = _table(6)
    crystal = table["init"] == "crystal"
    K = table["K_m"].to_numpy()
    law = 0.5 * np.exp(-7.0 / 9.0) * np.exp(np.where(K <= 9.0, -100.0 / K + 100.0 / 9.0,
                                                     -7.0 / K + 7.0 / 9.0))  # fmt: skip
    p = np.where(crystal & (K > K_BREAK["crystal"][0]), law, table["p_s"])
    table = table.assign(p_s=p, n_trials=1e30, n_slips=p * 1e30, p_s_sem=np.nan)
    key = ("crystal", 40, Walls(0.6, "shaken", "lever"))
    cfg = {**FITS, "slip_weights": "unweighted", "crystal_points": "initialisation",
           "crystal_regions": "slips"}  # fmt: skip
    tf = fits.temperature_fits(table, cfg, DETECTION)
    bends = fits.slip_bends(table, tf, cfg)
    assert bends[key]["K_m"] == pytest.approx(9.0, rel=1e-3)
    lo, hi = bends[key]["K_m_ci"]
    assert lo <= hi and bends[key]["n_points"] == 13  # the 13 slipping points above K_m 2
    by = fits.slip_fits(table, tf, cfg, None, bends)[key]
    assert by["A2"].E_b == pytest.approx(100.0, rel=1e-6)
    assert by["B"].E_b == pytest.approx(7.0, rel=1e-6)
    temp = fits.slip_fits(table, tf, {**cfg, "crystal_regions": "temperature"})[key]
    assert temp["B"].E_b > 20.0  # B from K_m 6 holds points of the steep branch
    assert fits.slip_bends(table, tf, {**cfg, "crystal_regions": "replica"}) == {}
    rows = {r["quantity"]: r for r in fits.summary_rows(table, fits.thresholds_table(
        table, DETECTION), tf, fits.slip_fits(table, tf, cfg, None, bends), bends)}  # fmt: skip
    assert rows[fits._fmt_q("K_m_slip_bend", *key)]["value"] == pytest.approx(9.0, rel=1e-3)
    few = table[~crystal | (table["Gamma"] <= 2.2)]
    tf_few = fits.temperature_fits(few, cfg, DETECTION)
    bends_few = fits.slip_bends(few, tf_few, cfg)
    assert "too few" in bends_few[key]["error"]
    refused = fits.slip_fits(few, tf_few, cfg, None, bends_few)[key]
    assert math.isnan(refused["A2"].E_b) and "too few" in refused["B"].note
    ds = fits.fits_datasets(few, fits.thresholds_table(few, DETECTION), tf_few,
                            {key: refused}, bends_few)["slips"]  # fmt: skip
    row = ds["name"].to_numpy() == "K_m_bend"
    assert row.sum() == 2  # one per N_l of the crystal
    assert all("too few" in str(n) for n in ds["note"].to_numpy()[row])


def test_the_crystals_regions_split_by_each_replicas_own_convection():
    """``crystal_regions: replica``: at every Γ above the first T_g* break two replicas of
    each crystal point stay unconvected and slip with a barrier of 30, two convect
    (s_c 5 σ) and slip with one of 7. Split per replica, A2 recovers 30 and B 7 exactly;
    at the second T_g* break (the default) each region mixes both kinds of replica
    (one line through both: the barriers' mean)."""
    table = _table(5)
    conv = (False, False, True, True)
    E = np.where(conv, 7.0, 30.0)
    rows = {c: [] for c in ("p_s", "s_c", "n_trials")}
    for K in table["K_m"]:
        p = 0.0 if K <= K_BREAK["crystal"][0] else 0.5 * np.exp(-E / K)
        rows["p_s"].append(tuple(np.broadcast_to(p, 4)))
        rows["s_c"].append(tuple(np.where(conv, 5.0, 0.1)))
        rows["n_trials"].append((1.0e9,) * 4)
    table = table.assign(
        replicas=4,
        p_s_replica=rows["p_s"],
        p_s_sem_replica=[(np.nan,) * 4] * len(table),
        n_slips_replica=[tuple(1e9 * np.asarray(p)) for p in rows["p_s"]],
        n_trials_replica=rows["n_trials"],
        s_c_replica=rows["s_c"],
        convecting_replica=[conv] * len(table),
    )
    key = ("crystal", 40, Walls(0.6, "shaken", "lever"))
    base = {**FITS, "slip_weights": "unweighted", "crystal_points": "initialisation"}
    tf = fits.temperature_fits(table, base, DETECTION)
    by = fits.slip_fits(table, tf, {**base, "crystal_regions": "replica"})[key]
    above = ((table["init"] == "crystal") & (table["N_l"] == 40)
             & (table["K_m"] > tf[key]["breakpoints_K_m"][0])).sum()  # fmt: skip
    assert by["A2"].E_b == pytest.approx(30.0, rel=1e-9)
    assert by["B"].E_b == pytest.approx(7.0, rel=1e-9)
    assert by["A2"].n_points == by["B"].n_points == 2 * above
    temp = fits.slip_fits(table, tf, {**base, "slip_replicas": "each"})[key]
    # one line through both kinds of replica: the mean of the barriers, in both regions
    assert temp["A2"].E_b == pytest.approx(18.5, rel=1e-9)
    assert temp["B"].E_b == pytest.approx(18.5, rel=1e-9)
    assert by["all"].E_b == pytest.approx(temp["all"].E_b, rel=1e-12)
    # the random start keeps its pooled points
    rkey = ("random", 40, Walls(0.6, "shaken", "lever"))
    pooled = fits.slip_fits(table, tf, base)[rkey]["all"]
    assert (
        fits.slip_fits(table, tf, {**base, "crystal_regions": "replica"})[rkey]["all"].n_points
        == pooled.n_points
    )
    no_s_c = table.drop(columns=["convecting_replica"])
    refused = fits.slip_fits(no_s_c, tf, {**base, "crystal_regions": "replica"})[key]
    assert math.isnan(refused["A2"].E_b) and "per-replica s_c" in refused["B"].note


def test_wall_settings_are_separate_groups():
    a, b = _table(6, mu_w=0.6), _table(7, mu_w=0.0)
    c = _table(8, mu_w=0.6, side_walls="still")
    both = pd.concat([a, b, c], ignore_index=True)
    ths, tfits, sfits = _fit_all(both)
    ths_a, tfits_a, sfits_a = _fit_all(a)
    other = {Walls(0.0, "shaken", "lever"), Walls(0.6, "still", "lever")}
    assert set(tfits) == set(tfits_a) | {(i, n, w) for i, n, _ in tfits_a for w in other}
    sel = ths[(ths["mu_w"] == 0.6) & (ths["side_walls"] == "shaken")].reset_index(drop=True)
    pd.testing.assert_frame_equal(sel, ths_a)
    for key, tf in tfits_a.items():
        assert np.array_equal(tfits[key]["breakpoints_K_m"], tf["breakpoints_K_m"])
    df = summary_frame(fits.summary_rows(both, ths, tfits, sfits)).set_index("quantity")
    # the paper's numbers stand beside the rows of its own walls only: Table I's friction
    # with the whole box shaken
    assert df.loc[f"E_b_all[N_l=20,init=random,{W6}]", "paper_value"] == 7.0
    assert pd.isna(df.loc[f"E_b_all[N_l=20,init=random,{W0}]", "paper_value"])
    still = "mu_w=0.6,walls=still,torque=lever"
    assert pd.isna(df.loc[f"E_b_all[N_l=20,init=random,{still}]", "paper_value"])


def test_exact_on_linear_measure_any_grid():
    rng = np.random.default_rng(0)
    for _ in range(20):
        g = np.sort(rng.uniform(0.8, 4.0, size=9))
        g[0], g[-1] = 0.8, 4.0
        s_c = 0.7 * (g - 2.345) + CONVECTION_THRESHOLD  # crosses sigma at 2.345
        th = threshold_crossing(g[::-1], s_c[::-1], CONVECTION_THRESHOLD)  # unsorted input
        assert th.value == pytest.approx(2.345, abs=1e-12)
        assert th.low < 2.345 <= th.high and th.status == "crossed" and th.n_crossings == 1


def test_log_scale_exact_on_exponential_measure():
    g = np.linspace(0.8, 3.0, 12)
    s_b = BOUNCING_THRESHOLD * np.exp(4.0 * (g - 1.13))
    th = threshold_crossing(g, s_b, BOUNCING_THRESHOLD, scale="log")
    assert th.value == pytest.approx(1.13, abs=1e-12)
    lin = threshold_crossing(g, s_b, BOUNCING_THRESHOLD)
    assert lin.value != pytest.approx(1.13, abs=1e-3)  # linear interpolation is biased here


def test_band_gives_interval():
    g = np.linspace(1.0, 3.0, 11)
    m = g - 1.0
    th = threshold_crossing(g, m, 1.0, measure_low=m - 0.1, measure_high=m + 0.1)
    assert (th.ci_low, th.value, th.ci_high) == pytest.approx((1.9, 2.0, 2.1))


def test_outside_grid_and_nonmonotonic():
    g = np.array([1.0, 1.5, 2.0, 2.5])
    below = threshold_crossing(g, [2.0, 3, 4, 5], 1.0)
    assert below.status == "below_grid" and np.isnan(below.value) and below.high == 1.0
    above = threshold_crossing(g, [0.1, 0.2, 0.3, 0.4], 1.0)
    assert above.status == "above_grid" and above.low == 2.5 and np.isnan(above.high)
    wiggly = threshold_crossing(np.arange(6.0), [0, 2, 0, 0, 2, 3], 1.0)
    assert wiggly.n_crossings == 2 and wiggly.value == pytest.approx(0.5)
    last = threshold_crossing(np.arange(6.0), [0, 2, 0, 0, 2, 3], 1.0, which="last")
    assert last.value == pytest.approx(3.5)


def test_flags_bracket():
    th = threshold_from_flags([1.0, 1.2, 1.4, 1.6], [False, False, True, True])
    assert (th.low, th.value, th.high) == pytest.approx((1.2, 1.3, 1.4))
    assert (th.ci_low, th.ci_high) == (1.2, 1.4)
    assert threshold_from_flags([1.0, 2.0], [False, False]).status == "above_grid"


def test_the_convection_measure_over_the_first_cycles_of_the_record():
    """s_c² is the mean of s_j² over the cycles looked at (Eq. B2): over 2 of the cycles
    1, 1, 3, 3 of one replica it is 1, over all 4 sqrt(5); replicas are averaged after
    the root; a record shorter than asked gives NaN."""
    s_j = np.array([[1.0, 1.0, 3.0, 3.0], [2.0, 2.0, 2.0, 2.0]])
    assert fits.convection_after(s_j, 2) == pytest.approx((1.0 + 2.0) / 2)
    assert fits.convection_after(s_j, 4) == pytest.approx((math.sqrt(5.0) + 2.0) / 2)
    assert math.isnan(fits.convection_after(s_j, 5))


def test_slips_over_a_window_of_periods():
    p = np.array([[0.0, 0.1, 0.2, np.nan], [0.0, 0.3, 0.2, 0.4]])
    assert fits.slips_between(p, 0, 2) == pytest.approx(0.1)
    assert fits.slips_between(p, 2, 4) == pytest.approx((0.2 + 0.2 + 0.4) / 3)
    assert math.isnan(fits.slips_between(p, 2, 5))


def test_the_onset_per_record_length_is_a_criterion_of_its_own():
    """A table with s_c over the first 8 and 32 cycles gets the onset of each: here s_c
    over 32 cycles is s_c over 8 shifted by 0.4 in Γ, so is its threshold."""
    table = _table(11)
    table["s_c_8"] = table["s_c"]
    table["s_c_32"] = np.exp(2.0 * (table["Gamma"] - np.where(table["init"] == "random",
                                                               1.5, 2.3)))  # fmt: skip
    table["s_c_200"] = np.nan  # longer than the record: no criterion
    ths = fits.thresholds_table(table, DETECTION)
    assert set(ths["criterion"]) == {"bouncing", "detachment", "convection", "rolls",
                                     "convection_8periods", "convection_32periods"}  # fmt: skip
    by = {(r.init, r.N_l, r.criterion): r.Gamma for r in ths.itertuples()}
    assert by[("random", 20, "convection_8periods")] == pytest.approx(1.9, abs=1e-9)
    assert by[("random", 20, "convection_32periods")] == pytest.approx(1.5, abs=1e-9)
    rows = fits.summary_rows(table.assign(p_s_0_50=0.01, p_s_50_200=np.nan), ths, {}, {})
    names = {r["quantity"] for r in rows}
    assert f"Gamma_convection_32periods[N_l=40,init=crystal,{W6}]" in names
    assert any(n.startswith("p_s_periods_0_50[") for n in names)
    assert not any(n.startswith("p_s_periods_50_200[") for n in names)


def test_the_onset_against_the_record_names_each_reading_and_record():
    """Fig. 7's table: every criterion convection / rolls over the first n periods and over
    the whole record (200 here) is one row of its reading and record, the others none;
    the figure draws from it."""
    from granpipe.figures import box as figs

    table = _table(11)
    table["s_c_8"] = table["s_c"]
    table["s_c_32"] = np.exp(2.0 * (table["Gamma"] - np.where(table["init"] == "random",
                                                               1.5, 2.3)))  # fmt: skip
    ths = fits.thresholds_table(table, DETECTION)
    rec = figs.onset_records(ths, full_record=200)
    assert set(zip(rec["reading"], rec["record"], strict=True)) == {
        ("convection", 8),
        ("convection", 32),
        ("convection", 200),
        ("rolls", 200),
    }
    assert len(rec) == 4 * 2 * 2  # per reading and record: 2 starts x 2 N_l
    one = rec[(rec["init"] == "random") & (rec["N_l"] == 20)].set_index(["reading", "record"])
    assert one.loc[("convection", 32), "Gamma"] == pytest.approx(1.5, abs=1e-9)
    assert one.loc[("convection", 200), "Gamma"] == pytest.approx(1.9, abs=1e-9)
    assert one.loc[("rolls", 200), "Gamma"] == pytest.approx(1.9 + 3.0 / 5.0, abs=1e-9)
    fig = figs.fig7_onset_record(table, ths, 1.82, reading="synthetic")
    assert len(fig.axes) == 4


def test_the_combined_roll_score_of_beds_without_rolls_is_standard_normal():
    """Points of 1, 3 and 9 replicas of diffusing beds (c_j independent, mean zero): the
    combined score has spread 1 at every replica count (the replicas' mean would have
    1/√n), so the threshold of 3 means the same with replicas; a roll still scores
    higher with more of them."""
    rng = np.random.default_rng(5)
    for n in (1, 3, 9):
        z = [fits.rolls_after(rng.normal(0.0, 0.02, (n, 32)), 32) for _ in range(600)]
        assert np.std(z) == pytest.approx(1.0, abs=0.1), n
        assert abs(np.mean(z)) < 0.15
    assert measures.combined_score([2.0, 2.0, 2.0, np.nan]) == pytest.approx(2.0 * math.sqrt(3))
    assert math.isnan(measures.combined_score([np.nan]))


def test_the_roll_score_over_the_first_periods_of_each_replica():
    """rolls_after maps each replica's first n contrasts to its score and combines the
    replicas' scores (Σ z / √n); a record shorter than asked gives NaN, and the table's
    roll_<n> columns become criteria rolls_<n>periods."""
    rng = np.random.default_rng(2)
    c = np.vstack([0.05 + rng.normal(0.0, 0.01, 40), rng.normal(0.0, 0.01, 40)])
    scores = [measures.roll_significance(row, 32) for row in c]
    assert fits.rolls_after(c, 32) == pytest.approx(np.sum(scores) / math.sqrt(2))
    assert scores[0] > 10.0 > 3.0 > scores[1]
    assert math.isnan(fits.rolls_after(c, 41))
    table = _table(3).assign(roll_8=lambda t: 5.0 * (t["Gamma"] - 2.3), roll_displacement_8=4.0)
    ths = fits.thresholds_table(fits.roll_levels(table, DETECTION), DETECTION)
    by = {(r.init, r.N_l, r.criterion): r.Gamma for r in ths.itertuples()}
    assert by[("crystal", 40, "rolls_8periods")] == pytest.approx(2.9, abs=1e-9)


def test_slips_sampled_in_flight_are_fitted_beside_the_cycle_start():
    """With p_s from the phase of longest flight following its own barrier (5 against the
    cycle start's 7), the flight rows recover 5 while the default rows keep 7, and each
    phase's p_s is a row of its point."""
    table = _table(7)
    rng = np.random.default_rng(7)
    K = table["K_m"].to_numpy()
    n = table["n_trials"].to_numpy()
    slips = rng.binomial(n, 0.5 * np.exp(-5.0 / K))
    table = table.assign(
        p_s_flight=slips / n, p_s_sem_flight=np.nan, n_slips_flight=slips, n_trials_flight=n,
        flight_phase=0.5, p_s_phase_0of2=table["p_s"], p_s_phase_1of2=slips / n,
    )  # fmt: skip
    ths, tfits, sfits = _fit_all(table)
    fit = sfits[("random", 20, Walls(0.6, "shaken", "lever"))]
    assert fit["all"].E_b == pytest.approx(7.0, abs=0.7)
    assert fit["all_flight"].E_b == pytest.approx(5.0, abs=0.5)
    assert "all_unweighted_flight" in fit  # the other reading (FITS weights the main)
    names = {r["quantity"] for r in fits.summary_rows(table, ths, tfits, sfits)}
    assert f"E_b_all_flight[N_l=20,init=random,{W6}]" in names
    point = table["point"].iloc[0]
    assert {f"p_s_phase_0of2[{point}]", f"p_s_phase_1of2[{point}]"} <= names
    assert not any(q.startswith("p_s_periods_") for q in names)  # no window asked for


def test_every_fit_row_stays_on_a_grid_too_small_to_fit():
    """Two Γ per group are too few for the T_g* breakpoints: the break, slope and regional
    barrier rows of every group are still there, empty, and the fits files' note says why
    (the barrier over all points is fitted)."""
    table = _table(4)
    table = table[table["Gamma"].isin(GAMMA[:2])].reset_index(drop=True)
    ths = fits.thresholds_table(table, DETECTION)
    tfits = fits.temperature_fits(table, FITS, DETECTION)
    sfits = fits.slip_fits(table, tfits, FITS)
    df = summary_frame(fits.summary_rows(table, ths, tfits, sfits)).set_index("quantity")
    ds = fits.fits_datasets(table, ths, tfits, sfits)
    for init, k in (("random", 1), ("crystal", 2)):
        regions = fits.REGION_NAMES[k]
        for n_l in (20, 40):
            group = f"[N_l={n_l},init={init},{W6}]"
            names = [f"K_m_break_{i + 1}" for i in range(k)]
            names += [f"T_g_slope_{r}" for r in regions]
            names += [f"E_b_{r}{s}" for r in regions for s in ("", "_unweighted")]
            for name in names:
                assert math.isnan(df.loc[name + group, "value"]), name + group
            assert {f"E_b_all{group}", f"E_b_all_unweighted{group}"} <= set(df.index)
            for what in ("temperature", "slips"):
                d = ds[what]
                mine = (d["init"] == init) & (d["N_l"] == n_l) & ~d["name"].str.contains("_all")
                notes = d["note"].values[mine.values]
                assert notes.size and all("T_g* fit" in n for n in notes), (what, init, n_l)
