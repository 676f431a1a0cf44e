"""Tests for kalman_course.evaluation.metrics: scipy.stats.chi2 as the oracle, hand values."""

import math

import numpy as np
import pytest
from scipy import stats

from kalman_course.filters.kf import run_kf
from kalman_course.evaluation.metrics import (chi2_bounds, chi2_cdf, chi2_ppf, nees, nis,
                                              position_rmse, rmse, share_inside)

DOFS = [0.5, 1, 2, 3, 4.5, 6, 15, 40, 150, 1000, 4500]


# --------------------------------------------------------------------------------------
# RMSE
# --------------------------------------------------------------------------------------

def test_rmse_hand_values():
    est = np.array([[1.0, 0.0], [3.0, 0.0]])
    truth = np.array([[0.0, 0.0], [0.0, 4.0]])
    np.testing.assert_allclose(rmse(est, truth), [math.sqrt(5.0), math.sqrt(8.0)])
    assert rmse(est, truth, axis=None) == pytest.approx(math.sqrt(26 / 4))
    np.testing.assert_allclose(rmse(est, truth, axis=1), [math.sqrt(0.5), math.sqrt(12.5)])
    assert isinstance(rmse([1.0, 2.0], [1.0, 0.0]), float)


def test_position_rmse_hand_values():
    # errors (3, 4, 0) and (0, 0, 12): norms 5 and 12, RMS sqrt((25 + 144) / 2)
    est = np.array([[3.0, 4.0, 0.0], [1.0, 1.0, 13.0]])
    truth = np.array([[0.0, 0.0, 0.0], [1.0, 1.0, 1.0]])
    assert position_rmse(est, truth) == pytest.approx(math.sqrt(169 / 2), rel=1e-15)
    assert isinstance(position_rmse(est, truth), float)
    # one row: the error's norm
    assert position_rmse([[3.0, 4.0]], [[0.0, 0.0]]) == pytest.approx(5.0, rel=1e-15)


@pytest.mark.parametrize("estimate, truth, match", [
    (np.zeros(3), np.zeros(3), r"estimate must have shape \(N, d\)"),
    (np.zeros((2, 3)), np.zeros((3, 2)), r"estimate and truth must have the same shape"),
    ("a", "b", r"estimate must be an array of real numbers"),
])
def test_position_rmse_bad_input(estimate, truth, match):
    with pytest.raises(ValueError, match=match):
        position_rmse(estimate, truth)


def test_rmse_propagates_nan_rather_than_hiding_it():
    out = rmse([[np.nan, 1.0], [0.0, 1.0]], [[0.0, 0.0], [0.0, 0.0]])
    assert math.isnan(out[0]) and out[1] == pytest.approx(1.0)


# --------------------------------------------------------------------------------------
# NEES / NIS
# --------------------------------------------------------------------------------------

def test_nees_known_case():
    assert nees([1.0, 2.0], np.diag([1.0, 4.0])) == pytest.approx(2.0)
    # correlated: e^T P^-1 e with P = [[2, 1], [1, 2]], P^-1 = [[2, -1], [-1, 2]] / 3
    assert nees([1.0, 1.0], [[2.0, 1.0], [1.0, 2.0]]) == pytest.approx(2 / 3)
    assert isinstance(nis([3.0], [[9.0]]), float)
    assert nis([3.0], [[9.0]]) == pytest.approx(1.0)


def test_nees_batched_matches_loop_and_broadcasts():
    rng = np.random.default_rng(0)
    N, n = 20, 3
    E = rng.standard_normal((N, n))
    A = rng.standard_normal((N, n, n))
    P = A @ np.swapaxes(A, 1, 2) + 0.1 * np.eye(n)
    out = nees(E, P)
    assert out.shape == (N,)
    np.testing.assert_allclose(out, [e @ np.linalg.solve(p, e) for e, p in zip(E, P)], rtol=1e-10)
    np.testing.assert_allclose(nis(E, P[0]), [e @ np.linalg.solve(P[0], e) for e in E], rtol=1e-10)


def test_nan_rows_give_nan_and_their_covariance_is_not_inspected():
    E = np.array([[1.0, 0.0], [np.nan, np.nan], [0.0, 2.0]])
    S = np.array([np.eye(2), np.full((2, 2), np.nan), 4 * np.eye(2)])
    out = nis(E, S)
    assert out[0] == pytest.approx(1.0) and math.isnan(out[1]) and out[2] == pytest.approx(1.0)
    assert np.all(np.isnan(nis(np.full((2, 2), np.nan), S[:2])))


def test_nis_of_run_kf_history_is_chi2_consistent():
    """A correctly specified filter on simulated data: NEES and NIS have means n and m."""
    rng = np.random.default_rng(1)
    T = 0.5
    F = np.array([[1.0, T], [0.0, 1.0]])
    Q = 0.2 * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    G = np.array([[1.0, 0.0]])
    R = np.array([[0.5]])
    runs, N = 60, 40
    nees_all, nis_all = np.empty((runs, N)), np.empty((runs, N))
    for r in range(runs):
        x = rng.multivariate_normal([0.0, 1.0], np.eye(2))
        truth, ys = np.empty((N, 2)), np.empty((N, 1))
        for k in range(N):
            if k:
                x = F @ x + rng.multivariate_normal([0.0, 0.0], Q)
            truth[k] = x
            ys[k] = G @ x + rng.normal(0.0, math.sqrt(R[0, 0]))
        h = run_kf([0.0, 1.0], np.eye(2), F, Q, G, R, ys)
        nees_all[r] = nees(h.x_hat - truth, h.P_hat)
        nis_all[r] = nis(h.innovation, h.S)
    lo, hi = chi2_bounds(2, n_runs=runs, confidence=0.99)
    assert share_inside(nees_all.mean(axis=0), lo, hi) >= 0.9
    lo, hi = chi2_bounds(1, n_runs=runs, confidence=0.99)
    assert share_inside(nis_all.mean(axis=0), lo, hi) >= 0.9
    # and a filter that underestimates R by 10x is flagged
    h_bad = run_kf([0.0, 1.0], np.eye(2), F, Q, G, R / 10, ys)
    assert nis(h_bad.innovation, h_bad.S).mean() > chi2_bounds(1, n_runs=N, confidence=0.99)[1]


# --------------------------------------------------------------------------------------
# chi-square
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("dof", DOFS)
def test_chi2_cdf_matches_scipy(dof):
    x = np.concatenate([dof * np.geomspace(1e-4, 1, 8), dof * np.linspace(0.05, 4, 30),
                        [dof + 80 * math.sqrt(dof)]])
    ref = stats.chi2.cdf(x, dof)
    np.testing.assert_allclose(chi2_cdf(x, dof), ref, rtol=1e-8, atol=0)


@pytest.mark.parametrize("dof", DOFS)
def test_chi2_ppf_matches_scipy_and_inverts_cdf(dof):
    p = np.array([1e-10, 1e-6, 0.001, 0.005, 0.025, 0.05, 0.3, 0.5, 0.7, 0.95, 0.975,
                  0.995, 0.999, 1 - 1e-7])
    q = chi2_ppf(p, dof)
    np.testing.assert_allclose(q, stats.chi2.ppf(p, dof), rtol=1e-8, atol=0)
    np.testing.assert_allclose(chi2_cdf(q, dof), p, rtol=1e-8)


def test_chi2_hand_values_and_edges():
    # dof 2 is the exponential distribution: F(x) = 1 - exp(-x/2)
    for x in (0.1, 1.0, 7.5):
        assert chi2_cdf(x, 2) == pytest.approx(1 - math.exp(-x / 2), rel=1e-13)
    assert chi2_ppf(0.5, 2) == pytest.approx(2 * math.log(2), rel=1e-13)
    assert chi2_ppf(0.95, 1) == pytest.approx(3.841458820694124, rel=1e-12)
    assert chi2_cdf(0.0, 3) == 0.0 and chi2_cdf(-1.0, 3) == 0.0
    assert chi2_cdf(math.inf, 3) == 1.0
    assert chi2_ppf(0.0, 3) == 0.0 and chi2_ppf(1.0, 3) == math.inf
    assert math.isnan(chi2_cdf(math.nan, 3)) and math.isnan(chi2_ppf(math.nan, 3))
    assert isinstance(chi2_cdf(1.0, 1), float) and isinstance(chi2_ppf(0.5, 1), float)
    # broadcasting of dof against x
    np.testing.assert_allclose(chi2_cdf(2.0, [1, 2, 3]), stats.chi2.cdf(2.0, [1, 2, 3]),
                               rtol=1e-12)


@pytest.mark.parametrize("dof,n_runs,conf", [(1, 1, 0.95), (2, 50, 0.95), (3, 1, 0.99),
                                             (6, 100, 0.9), (15, 25, 0.95)])
def test_chi2_bounds_match_scipy(dof, n_runs, conf):
    lo, hi = chi2_bounds(dof, n_runs, conf)
    a = (1 - conf) / 2
    assert lo == pytest.approx(stats.chi2.ppf(a, dof * n_runs) / n_runs, rel=1e-10)
    assert hi == pytest.approx(stats.chi2.ppf(1 - a, dof * n_runs) / n_runs, rel=1e-10)
    assert lo < dof < hi


def test_chi2_bounds_hand_value():
    lo, hi = chi2_bounds(1)
    assert lo == pytest.approx(0.000982069117175, rel=1e-9)
    assert hi == pytest.approx(5.023886187314888, rel=1e-12)


def test_share_inside():
    assert share_inside([0.5, 1.0, 2.0, 3.0], 1.0, 2.0) == pytest.approx(0.5)   # closed ends
    assert share_inside([[0.5, np.nan], [1.5, 9.0]], 1.0, 2.0) == pytest.approx(1 / 3)


# --------------------------------------------------------------------------------------
# validation: every error names its argument
# --------------------------------------------------------------------------------------

ASYM = np.array([[1.0, 0.3], [0.0, 1.0]])
INDEF = np.array([[1.0, 2.0], [2.0, 1.0]])

CASES = [
    (lambda: rmse(np.zeros((3, 2)), np.zeros((2, 3))), r"estimate and truth must have the same"),
    (lambda: rmse([], []), r"estimate must not be empty"),
    (lambda: nees([1.0, 0.0], np.eye(3)), r"P must have shape \(2, 2\)"),
    (lambda: nees([1.0, 0.0], ASYM), r"P must be symmetric"),
    (lambda: nees([1.0, 0.0], INDEF), r"P must be positive definite"),
    (lambda: nees(np.zeros((2, 2, 2)), np.eye(2)), r"error must have shape \(n,\) or \(N, n\)"),
    (lambda: nees(np.zeros((3, 2)), np.stack([np.eye(2)] * 2)), r"P must have shape \(3, 2, 2\)"),
    (lambda: nees(np.ones((2, 2)), np.stack([np.eye(2), ASYM])), r"P must be symmetric.*P\[1\]"),
    (lambda: nees(np.ones((2, 2)), np.stack([np.eye(2), INDEF])), r"P must be positive definite, P\[1\]"),
    (lambda: nees(np.ones((2, 2)), np.stack([np.eye(2), np.full((2, 2), np.inf)])),
     r"P must be finite, P\[1\]"),
    (lambda: nees([[np.inf, 0.0]], np.eye(2)), r"error must not contain inf"),
    (lambda: nees([np.nan, 0.0], np.eye(2)), r"error must be finite"),
    (lambda: nis([1.0], [[0.0]]), r"S must be positive definite"),
    (lambda: nis(np.ones((2, 1)), np.stack([[[1.0]], [[-1.0]]])), r"S must be positive definite, S\[1\]"),
    (lambda: nis(np.zeros((1, 2)), np.eye(3)), r"S must have shape \(1, 2, 2\) or \(2, 2\)"),
    (lambda: chi2_cdf(1.0, 0), r"dof must be a finite positive number"),
    (lambda: chi2_cdf(1.0, [1, -2]), r"dof must be a finite positive number"),
    (lambda: chi2_ppf(1.5, 2), r"p must be a probability in \[0, 1\]"),
    (lambda: chi2_ppf(-0.1, 2), r"p must be a probability"),
    (lambda: chi2_ppf(0.5, math.inf), r"dof must be a finite positive number"),
    (lambda: chi2_bounds(0), r"dof must be a finite positive number"),
    (lambda: chi2_bounds(2, n_runs=0), r"n_runs must be a positive integer"),
    (lambda: chi2_bounds(2, n_runs=2.5), r"n_runs must be a positive integer"),
    (lambda: chi2_bounds(2, confidence=1.0), r"confidence must lie strictly between 0 and 1"),
    (lambda: share_inside([1.0], 2.0, 1.0), r"lo must not exceed hi"),
    (lambda: share_inside([np.nan], 0.0, 1.0), r"values must contain at least one"),
]


@pytest.mark.parametrize("call,match", CASES, ids=[c[1][:40] for c in CASES])
def test_validation_errors_name_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
