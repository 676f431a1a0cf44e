"""The chapter-01 and chapter-02 experiments of ``chapters.intuition``."""

import numpy as np
import pytest

from kalman_course.chapters import intuition


def test_truncated_normal_moments_match_scipy():
    stats = pytest.importorskip("scipy.stats")
    for mu, sigma, low, high in ((3.0, 2.0, 0.0, 10.0), (0.0, 1.0, -0.5, 2.0), (-4.0, 0.3, -4.2, -1.0)):
        d = stats.truncnorm((low - mu) / sigma, (high - mu) / sigma, loc=mu, scale=sigma)
        m, s = intuition.truncated_normal_moments(mu, sigma, low, high)
        assert m == pytest.approx(d.mean(), rel=1e-12, abs=1e-12)
        assert s == pytest.approx(d.std(), rel=1e-10)


def test_truncated_normal_moments_against_a_fine_grid():
    x = np.linspace(0.0, 10.0, 200_001)
    w = np.exp(-0.5 * ((x - 3.0) / 2.0) ** 2)
    w /= w.sum()
    m = np.sum(w * x)
    s = np.sqrt(np.sum(w * (x - m) ** 2))
    assert intuition.truncated_normal_moments(3.0, 2.0, 0.0, 10.0) == pytest.approx((m, s), abs=1e-4)


def test_truncated_normal_moments_without_truncation_are_the_gaussians():
    assert intuition.truncated_normal_moments(1.0, 0.5, -20.0, 20.0) == pytest.approx((1.0, 0.5), abs=1e-12)


@pytest.mark.parametrize("args", [(0.0, 0.0, -1.0, 1.0), (0.0, 1.0, 1.0, 1.0), (0.0, 1.0, 2.0, -2.0),
                                  (0.0, 1.0, 50.0, 60.0)])
def test_truncated_normal_moments_rejects_bad_input(args):
    with pytest.raises(ValueError):
        intuition.truncated_normal_moments(*args)


P = np.array([[4.0, 1.5], [1.5, 1.0]])
G = np.array([[1.0, 0.0]])
R = np.array([[0.25]])


def test_information_trial_traces_and_covariance_drop():
    t = intuition.information_trial([0.0, 0.0], P, G, R, seeds=[0], n_runs=10)
    K = P @ G.T / (P[0, 0] + R[0, 0])
    assert t.prior_trace == pytest.approx(5.0)
    assert t.posterior_trace == pytest.approx(np.trace(P - K @ G @ P))
    assert np.all(t.covariance_drop >= -1e-12)
    assert t.prior_sq_error.shape == t.posterior_sq_error.shape == (1, 10)


def test_information_trial_correct_model_mse_matches_trace():
    t = intuition.information_trial([1.0, -2.0], P, G, R, seeds=range(4), n_runs=5000)
    assert np.mean(t.prior_sq_error) == pytest.approx(t.prior_trace, rel=0.05)
    assert np.mean(t.posterior_sq_error) == pytest.approx(t.posterior_trace, rel=0.05)
    assert 0.05 < np.median(t.share_worse) < 0.5


def test_information_trial_wrong_models_hurt():
    biased = intuition.information_trial([0.0, 0.0], P, G, R, seeds=range(3), n_runs=2000, bias=[3.0])
    noisy = intuition.information_trial([0.0, 0.0], P, G, R, seeds=range(3), n_runs=2000, R_true=[[16.0]])
    assert np.all(biased.mse_ratio > 1) and np.all(noisy.mse_ratio > 1)


def test_information_trial_is_seeded():
    a = intuition.information_trial([0.0, 0.0], P, G, R, seeds=[3, 4], n_runs=50)
    b = intuition.information_trial([0.0, 0.0], P, G, R, seeds=[3, 4], n_runs=50)
    assert np.array_equal(a.posterior_sq_error, b.posterior_sq_error)
    assert not np.array_equal(a.posterior_sq_error[0], a.posterior_sq_error[1])


@pytest.mark.parametrize("kwargs", [dict(seeds=[]), dict(seeds=[-1]), dict(seeds=[0], n_runs=0),
                                    dict(seeds=[0], bias=[1.0, 2.0])])
def test_information_trial_rejects_bad_input(kwargs):
    with pytest.raises(ValueError):
        intuition.information_trial([0.0, 0.0], P, G, R, **kwargs)
