"""ROC curves, their area and precision at a set's size on synthetic scores with known
answers: noise gives 0.5, a perfect score 1, a known shift its normal-theory area; the
pooled bootstrap equals the area of the pooled resample."""

import math

import numpy as np
import pytest
from scipy.stats import norm

from granpipe.analysis.bootstrap import resample_counts
from granpipe.analysis.prediction import (
    bootstrap_auc,
    event_follows,
    locate,
    precision_at_size,
    roc_auc,
    roc_curve,
    trailing_mean,
)


def test_noise_gives_one_half_and_a_perfect_score_one():
    rng = np.random.default_rng(1)
    labels = rng.random(20_000) < 0.2
    assert roc_auc(rng.normal(size=labels.size), labels) == pytest.approx(0.5, abs=0.015)
    assert roc_auc(labels + 0.1 * rng.random(labels.size), labels) == 1.0
    assert roc_auc(-(labels + 0.1 * rng.random(labels.size)), labels) == 0.0
    assert roc_auc(np.zeros(labels.size), labels) == 0.5  # all tied
    assert math.isnan(roc_auc(np.arange(5.0), np.zeros(5, bool)))


def test_shifted_gaussians_give_the_normal_theory_area():
    # positives ~ N(d, 1), negatives ~ N(0, 1): AUC = Phi(d / sqrt 2)
    rng = np.random.default_rng(2)
    d = 1.0
    s = np.r_[rng.normal(d, 1, 30_000), rng.normal(0, 1, 30_000)]
    y = np.r_[np.ones(30_000, bool), np.zeros(30_000, bool)]
    assert roc_auc(s, y) == pytest.approx(norm.cdf(d / math.sqrt(2)), abs=0.006)
    fpr, tpr = roc_curve(s, y)
    assert fpr[0] == tpr[0] == 0 and fpr[-1] == tpr[-1] == 1
    assert np.all(np.diff(fpr) >= 0) and np.all(np.diff(tpr) >= 0)
    assert np.trapezoid(tpr, fpr) == pytest.approx(roc_auc(s, y), abs=1e-9)


def test_roc_curve_of_ties_is_one_diagonal_step():
    fpr, tpr = roc_curve(np.ones(4), np.array([1, 0, 1, 0], bool))
    assert fpr.tolist() == [0, 1] and tpr.tolist() == [0, 1]


def test_bootstrap_of_the_pooled_area():
    rng = np.random.default_rng(3)
    scores, labels = [], []
    for r in range(12):
        y = rng.random(400) < 0.1
        scores.append(rng.normal(size=400) + 0.8 * y + 0.3 * r)  # replicas differ in level
        labels.append(y)
    value, boot = bootstrap_auc(scores, labels, n_resamples=400, seed=0)
    assert value == pytest.approx(roc_auc(np.concatenate(scores), np.concatenate(labels)))
    assert boot.ci_low[0] < value < boot.ci_high[0]
    assert boot.ci_low[0] > 0.5  # the score predicts
    # each resample is the pooled area of the replicas it draws (the same draws)
    W = resample_counts(12, 400, np.random.default_rng(0))
    for b in range(3):
        pick = np.repeat(np.arange(12), W[b].astype(int))
        pooled = roc_auc(np.concatenate([scores[i] for i in pick]),
                         np.concatenate([labels[i] for i in pick]))  # fmt: skip
        assert boot.samples[b, 0] == pytest.approx(pooled, rel=1e-12)
    # noise: the interval holds one half
    noise = [rng.normal(size=400) for _ in range(12)]
    _, boot = bootstrap_auc(noise, labels, n_resamples=400, seed=0)
    assert boot.ci_low[0] < 0.5 < boot.ci_high[0]


def test_precision_at_the_sets_size():
    members = np.zeros(100, bool)
    members[[3, 40, 77]] = True
    score = np.zeros(100)
    score[members] = 1.0
    assert precision_at_size(score, members) == 1.0
    assert precision_at_size(-score, members) == 0.0
    rng = np.random.default_rng(4)
    random = [precision_at_size(rng.random(100), members) for _ in range(4000)]
    assert np.mean(random) == pytest.approx(0.03, abs=0.01)  # the members' share
    assert math.isnan(precision_at_size(score, np.zeros(100, bool)))


def test_locate_scores_one_event_by_every_score():
    rng = np.random.default_rng(5)
    members = np.zeros(200, bool)
    members[rng.choice(200, 20, replace=False)] = True
    perfect = members + 0.1 * rng.random(200)
    noise = rng.random(200)
    got = locate({"du": perfect, "speed": noise}, members)
    assert set(got) == {"precision_du", "precision_speed", "precision_random", "auc_du",
                        "auc_speed", "event_size"}  # fmt: skip
    assert got["precision_du"] == 1.0 and got["auc_du"] == 1.0
    assert got["precision_speed"] == precision_at_size(noise, members)
    assert got["auc_speed"] == roc_auc(noise, members)
    assert got["precision_random"] == pytest.approx(0.1) and got["event_size"] == 20
    assert locate({"du": perfect}, np.zeros(200, bool)) is None


def test_trailing_mean_and_event_follows():
    x = np.arange(6.0)
    assert np.allclose(trailing_mean(x, 3)[2:], [1, 2, 3, 4])
    assert np.isnan(trailing_mean(x, 3)[:2]).all()
    f = event_follows(10, np.array([4, 9]), 2)
    assert np.flatnonzero(f).tolist() == [2, 3, 7, 8]
