"""Tests for kalman_course.core.gaussians."""

import math

import numpy as np
import pytest
from scipy import stats

from kalman_course.core.gaussians import (block_inverse, conditional, gaussian_logpdf, gaussian_pdf,
                                     joint_linear, linear_map, marginal, product,
                                     schur_complement)


def random_spd(rng, n, ridge=0.2):
    A = rng.standard_normal((n, n))
    return A @ A.T / n + ridge * np.eye(n)


def random_joint(seed, n, m):
    """Blocks of a random valid joint Gaussian of x (n) and y (m)."""
    rng = np.random.default_rng(seed)
    mean = rng.standard_normal(n + m)
    cov = random_spd(rng, n + m)
    return (mean[:n], mean[n:], cov[:n, :n], cov[:n, n:], cov[n:, n:]), (mean, cov), rng


# --------------------------------------------------------------------------------------
# density
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("n", [1, 2, 5])
def test_logpdf_matches_scipy(n):
    rng = np.random.default_rng(n)
    mean = rng.standard_normal(n)
    cov = random_spd(rng, n)
    X = rng.standard_normal((7, n)) * 2
    ref = stats.multivariate_normal(mean, cov).logpdf(X)
    out = gaussian_logpdf(X, mean, cov)
    assert out.shape == (7,)
    np.testing.assert_allclose(out, ref, rtol=1e-12)
    single = gaussian_logpdf(X[0], mean, cov)
    assert isinstance(single, float)
    assert single == pytest.approx(ref[0], rel=1e-12)
    np.testing.assert_allclose(gaussian_pdf(X, mean, cov), np.exp(ref), rtol=1e-12)
    assert isinstance(gaussian_pdf(X[0], mean, cov), float)


def test_pdf_hand_values():
    # 1-D: N(x; mu, s^2) = exp(-(x-mu)^2 / (2 s^2)) / sqrt(2 pi s^2)
    assert gaussian_pdf([1.0], [0.0], [[4.0]]) == pytest.approx(
        math.exp(-1 / 8) / math.sqrt(8 * math.pi), rel=1e-14)
    # 2-D standard normal at the origin: 1 / (2 pi)
    assert gaussian_pdf([0.0, 0.0], [0.0, 0.0], np.eye(2)) == pytest.approx(1 / (2 * math.pi))


def test_pdf_integrates_to_one_on_a_grid():
    mean, cov = np.array([0.5, -1.0]), np.array([[1.0, 0.6], [0.6, 2.0]])
    h = 0.05
    g = np.arange(-12, 12, h)
    X, Y = np.meshgrid(g, g, indexing="ij")
    pts = np.column_stack([X.ravel(), Y.ravel()])
    assert gaussian_pdf(pts, mean, cov).sum() * h * h == pytest.approx(1.0, abs=1e-9)


def test_logpdf_far_in_the_tail_does_not_underflow():
    assert gaussian_logpdf([100.0], [0.0], [[1.0]]) == pytest.approx(
        -0.5 * (math.log(2 * math.pi) + 100.0**2))


# --------------------------------------------------------------------------------------
# marginal and conditional
# --------------------------------------------------------------------------------------

def test_marginal_picks_blocks_in_order():
    rng = np.random.default_rng(1)
    mean, cov = rng.standard_normal(4), random_spd(rng, 4)
    m, c = marginal(mean, cov, [2, 0])
    np.testing.assert_array_equal(m, mean[[2, 0]])
    np.testing.assert_array_equal(c, [[cov[2, 2], cov[2, 0]], [cov[0, 2], cov[0, 0]]])
    m1, c1 = marginal(mean, cov, 3)
    assert m1.shape == (1,) and c1.shape == (1, 1)


def test_marginal_is_the_integral_of_the_joint():
    """Integrate a 2-D density over its second coordinate numerically."""
    mean, cov = np.array([0.3, -0.2]), np.array([[1.5, -0.7], [-0.7, 1.0]])
    m, c = marginal(mean, cov, [0])
    h = 0.01
    ys = np.arange(-10, 10, h)
    for x in (-1.0, 0.2, 2.5):
        pts = np.column_stack([np.full_like(ys, x), ys])
        integral = gaussian_pdf(pts, mean, cov).sum() * h
        assert integral == pytest.approx(gaussian_pdf([x], m, c), rel=1e-9)


@pytest.mark.parametrize("seed,n,m", [(0, 1, 1), (1, 2, 1), (2, 2, 3), (3, 4, 2)])
def test_conditional_is_joint_over_marginal(seed, n, m):
    """log p(x | y) = log p(x, y) - log p(y) at random points: Bayes by brute force."""
    (mu_x, mu_y, Sxx, Sxy, Syy), (mean, cov), rng = random_joint(seed, n, m)
    y = mu_y + rng.standard_normal(m)
    c_mean, c_cov = conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)
    assert np.array_equal(c_cov, c_cov.T)
    for _ in range(5):
        x = mu_x + 2 * rng.standard_normal(n)
        lhs = gaussian_logpdf(x, c_mean, c_cov)
        rhs = gaussian_logpdf(np.concatenate([x, y]), mean, cov) - gaussian_logpdf(y, mu_y, Syy)
        assert lhs == pytest.approx(rhs, abs=1e-10)


def test_conditional_matches_the_precision_form():
    """With L = Sigma^-1: Sigma_x|y = L_xx^-1, mu_x|y = mu_x - L_xx^-1 L_xy (y - mu_y)."""
    (mu_x, mu_y, Sxx, Sxy, Syy), (mean, cov), rng = random_joint(7, 3, 2)
    y = rng.standard_normal(2)
    L = np.linalg.inv(cov)
    Lxx_inv = np.linalg.inv(L[:3, :3])
    c_mean, c_cov = conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)
    np.testing.assert_allclose(c_cov, Lxx_inv, rtol=1e-10)
    np.testing.assert_allclose(c_mean, mu_x - Lxx_inv @ L[:3, 3:] @ (y - mu_y), rtol=1e-10)
    # the conditional covariance is the Schur complement of Sigma_yy in the joint covariance
    np.testing.assert_allclose(c_cov, schur_complement(cov, 3), rtol=1e-12)


def test_conditional_hand_value():
    # x, y standard normal with correlation rho: x | y ~ N(rho y, 1 - rho^2)
    rho = 0.6
    m, c = conditional([0.0], [0.0], [[1.0]], [[rho]], [[1.0]], [2.0])
    assert m[0] == pytest.approx(1.2)
    assert c[0, 0] == pytest.approx(0.64)


def test_conditional_of_a_deterministic_copy_is_degenerate_not_an_error():
    m, c = conditional([0.0], [0.0], [[1.0]], [[1.0]], [[1.0]], [0.7])
    assert m[0] == pytest.approx(0.7)
    assert c[0, 0] == pytest.approx(0.0, abs=1e-15)


# --------------------------------------------------------------------------------------
# linear maps
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed,n,m", [(0, 2, 1), (1, 3, 2), (2, 2, 4)])
def test_linear_map_matches_sample_moments(seed, n, m):
    """Sample moments of y = G x + noise agree within 5 standard errors for N samples."""
    rng = np.random.default_rng(seed)
    mu_x = rng.standard_normal(n)
    Sxx = random_spd(rng, n)
    G = rng.standard_normal((m, n))
    R = random_spd(rng, m)
    mu_y, Syy, Sxy = linear_map(mu_x, Sxx, G, R)

    N = 200_000
    x = rng.multivariate_normal(mu_x, Sxx, size=N)
    y = x @ G.T + rng.multivariate_normal(np.zeros(m), R, size=N)
    z = np.hstack([x, y])
    mean_z, cov_z = z.mean(axis=0), np.cov(z, rowvar=False)
    true_mean = np.concatenate([mu_x, mu_y])
    true_cov = np.block([[Sxx, Sxy], [Sxy.T, Syy]])

    # standard errors of a Gaussian sample mean and sample covariance entry
    se_mean = np.sqrt(np.diag(true_cov) / N)
    d = np.diag(true_cov)
    se_cov = np.sqrt((np.outer(d, d) + true_cov**2) / N)
    assert np.all(np.abs(mean_z - true_mean) <= 5 * se_mean)
    assert np.all(np.abs(cov_z - true_cov) <= 5 * se_cov)


def test_linear_map_formulas_and_zero_noise():
    rng = np.random.default_rng(3)
    mu_x, Sxx, G = rng.standard_normal(3), random_spd(rng, 3), rng.standard_normal((2, 3))
    mu_y, Syy, Sxy = linear_map(mu_x, Sxx, G, np.zeros((2, 2)))
    np.testing.assert_allclose(mu_y, G @ mu_x)
    np.testing.assert_allclose(Syy, G @ Sxx @ G.T, rtol=1e-13)
    np.testing.assert_allclose(Sxy, Sxx @ G.T)
    assert Sxy.shape == (3, 2)
    assert np.array_equal(Syy, Syy.T)


def test_joint_linear_blocks_and_conditioning_round_trip():
    rng = np.random.default_rng(4)
    mu_x, Sxx = rng.standard_normal(2), random_spd(rng, 2)
    G, R = rng.standard_normal((3, 2)), random_spd(rng, 3)
    mean, cov = joint_linear(mu_x, Sxx, G, R)
    mu_y, Syy, Sxy = linear_map(mu_x, Sxx, G, R)
    assert mean.shape == (5,) and cov.shape == (5, 5)
    np.testing.assert_array_equal(mean, np.concatenate([mu_x, mu_y]))
    np.testing.assert_array_equal(cov[:2, :2], Sxx)
    np.testing.assert_array_equal(cov[:2, 2:], Sxy)
    np.testing.assert_array_equal(cov[2:, :2], Sxy.T)
    np.testing.assert_array_equal(cov[2:, 2:], Syy)
    assert np.linalg.eigvalsh(cov).min() > 0
    # marginal over x gives back the prior
    m, c = marginal(mean, cov, [0, 1])
    np.testing.assert_array_equal(m, mu_x)
    np.testing.assert_array_equal(c, Sxx)


def test_conditioning_the_linear_joint_is_the_kalman_update():
    from kalman_course.filters.kf import kf_update

    rng = np.random.default_rng(5)
    mu_x, Sxx = rng.standard_normal(3), random_spd(rng, 3)
    G, R = rng.standard_normal((2, 3)), random_spd(rng, 2)
    y = rng.standard_normal(2)
    mu_y, Syy, Sxy = linear_map(mu_x, Sxx, G, R)
    c_mean, c_cov = conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)
    up = kf_update(mu_x, Sxx, y, G, R)
    np.testing.assert_allclose(c_mean, up.x_hat, rtol=1e-12)
    np.testing.assert_allclose(c_cov, up.P_hat, rtol=1e-11, atol=1e-14)


# --------------------------------------------------------------------------------------
# product
# --------------------------------------------------------------------------------------

def test_product_1d_against_a_normalised_grid_product():
    mu_a, var_a, mu_b, var_b = 1.0, 0.5, -0.5, 2.0
    mean, cov = product([mu_a], [[var_a]], [mu_b], [[var_b]])
    # closed form
    assert cov[0, 0] == pytest.approx(var_a * var_b / (var_a + var_b), rel=1e-14)
    assert mean[0] == pytest.approx((mu_a * var_b + mu_b * var_a) / (var_a + var_b), rel=1e-14)
    # pointwise product of the densities, normalised by a fine Riemann sum
    h = 1e-3
    grid = np.arange(-15, 15, h)[:, None]
    prod = gaussian_pdf(grid, [mu_a], [[var_a]]) * gaussian_pdf(grid, [mu_b], [[var_b]])
    prod /= prod.sum() * h
    np.testing.assert_allclose(prod, gaussian_pdf(grid, mean, cov), atol=1e-9)


@pytest.mark.parametrize("n", [1, 2, 4])
def test_product_information_form_and_normaliser(n):
    rng = np.random.default_rng(10 + n)
    mu_a, Sa = rng.standard_normal(n), random_spd(rng, n)
    mu_b, Sb = rng.standard_normal(n), random_spd(rng, n)
    mean, cov = product(mu_a, Sa, mu_b, Sb)
    info = np.linalg.inv(Sa) + np.linalg.inv(Sb)
    np.testing.assert_allclose(cov, np.linalg.inv(info), rtol=1e-10)
    np.testing.assert_allclose(
        mean, np.linalg.solve(info, np.linalg.solve(Sa, mu_a) + np.linalg.solve(Sb, mu_b)),
        rtol=1e-10, atol=1e-12)
    assert np.array_equal(cov, cov.T)
    # N(x; a) N(x; b) = N(mu_a; mu_b, Sa + Sb) N(x; mean, cov) at every x
    log_norm = gaussian_logpdf(mu_a, mu_b, Sa + Sb)
    for x in rng.standard_normal((5, n)):
        lhs = gaussian_logpdf(x, mu_a, Sa) + gaussian_logpdf(x, mu_b, Sb)
        assert lhs == pytest.approx(log_norm + gaussian_logpdf(x, mean, cov), abs=1e-10)


# --------------------------------------------------------------------------------------
# Schur complement and block inverse
# --------------------------------------------------------------------------------------

@pytest.mark.parametrize("p,k", [(2, 1), (3, 1), (3, 2), (5, 2), (6, 3)])
@pytest.mark.parametrize("symmetric", [True, False])
def test_schur_and_block_inverse_against_numpy(p, k, symmetric):
    rng = np.random.default_rng(100 * p + k)
    M = random_spd(rng, p) if symmetric else rng.standard_normal((p, p)) + p * np.eye(p)
    A, B, C, D = M[:k, :k], M[:k, k:], M[k:, :k], M[k:, k:]
    np.testing.assert_allclose(schur_complement(M, k), A - B @ np.linalg.inv(D) @ C, rtol=1e-12)
    Minv = block_inverse(M, k)
    np.testing.assert_allclose(Minv, np.linalg.inv(M), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Minv @ M, np.eye(p), atol=1e-12)
    # the top-left block of M^-1 is the inverse of the Schur complement of D
    np.testing.assert_allclose(np.linalg.inv(Minv[:k, :k]), schur_complement(M, k), rtol=1e-10)


@pytest.mark.parametrize("k", [1, 2, 3])
def test_block_inverse_of_a_well_conditioned_matrix_with_a_nearly_singular_block(k):
    # cond(M) ≈ 7 while one diagonal block has cond 2e15 (D for k = 2): solving with that
    # block would lose every digit; pivoting on the other keeps float64 round-off
    M = np.array([[1.0, 0.0, 1.0, 0.0], [0.0, 1.0, 0.0, 1.0], [1.0, 0.0, 1e-15, 0.0], [0.0, 1.0, 0.0, 2.0]])
    assert np.linalg.cond(M) < 10
    for matrix in (M, M[::-1, ::-1]):                     # the nearly singular block below, then above
        exact = np.linalg.inv(matrix)
        np.testing.assert_allclose(block_inverse(matrix, k), exact, rtol=0, atol=1e-14 * np.abs(exact).max())


def test_block_inverse_hand_value():
    M = np.array([[4.0, 2.0], [1.0, 3.0]])          # det 10
    np.testing.assert_allclose(block_inverse(M, 1), np.array([[3.0, -2.0], [-1.0, 4.0]]) / 10)
    assert schur_complement(M, 1)[0, 0] == pytest.approx(4 - 2 * 1 / 3)


# --------------------------------------------------------------------------------------
# validation: every error names its argument
# --------------------------------------------------------------------------------------

ASYM = np.array([[1.0, 0.3], [0.0, 1.0]])
INDEF = np.array([[1.0, 2.0], [2.0, 1.0]])
I2, Z2 = np.eye(2), np.zeros(2)

CASES = [
    (lambda: gaussian_pdf(np.zeros(3), Z2, I2), r"x must have shape \(2,\)"),
    (lambda: gaussian_pdf(np.zeros((4, 3)), Z2, I2), r"x must have shape \(N, 2\)"),
    (lambda: gaussian_pdf(np.zeros((1, 1, 2)), Z2, I2), r"x must be one point"),
    (lambda: gaussian_logpdf(Z2, np.zeros((2, 1)), I2), r"mean must be a 1-D vector"),
    (lambda: gaussian_logpdf(Z2, Z2, np.eye(3)), r"cov must have shape \(2, 2\)"),
    (lambda: gaussian_logpdf(Z2, Z2, ASYM), r"cov must be symmetric"),
    (lambda: gaussian_logpdf(Z2, Z2, INDEF), r"cov must be positive definite"),
    (lambda: gaussian_logpdf(Z2, Z2, np.zeros((2, 2))), r"cov must be positive definite"),
    (lambda: gaussian_logpdf([np.nan, 0.0], Z2, I2), r"x must be finite"),
    (lambda: marginal(Z2, I2, [2]), r"indices must lie in range\(2\)"),
    (lambda: marginal(Z2, I2, [0, 0]), r"indices must not repeat"),
    (lambda: marginal(Z2, I2, []), r"indices must be a non-empty"),
    (lambda: marginal(Z2, I2, [0.5]), r"indices must be integers"),
    (lambda: marginal(Z2, ASYM, [0]), r"cov must be symmetric"),
    (lambda: marginal(np.zeros(3), I2, [0]), r"cov must have shape \(3, 3\)"),
    (lambda: conditional(Z2, [0.0], I2, np.zeros((2, 2)), [[1.0]], [0.0]),
     r"Sigma_xy must have shape \(2, 1\)"),
    (lambda: conditional(Z2, [0.0], ASYM, np.zeros((2, 1)), [[1.0]], [0.0]),
     r"Sigma_xx must be symmetric"),
    (lambda: conditional(Z2, [0.0], I2, np.zeros((2, 1)), [[0.0]], [0.0]),
     r"Sigma_yy must be positive definite"),
    (lambda: conditional(Z2, [0.0], I2, np.zeros((2, 1)), [[1.0]], [0.0, 1.0]),
     r"y must have shape \(1,\)"),
    (lambda: conditional(Z2, [0.0], I2, np.zeros((2, 1)), np.eye(2), [0.0]),
     r"Sigma_yy must have shape \(1, 1\)"),
    (lambda: conditional([0.0], [0.0], [[1.0]], [[2.0]], [[1.0]], [0.0]),
     r"Sigma_xx, Sigma_xy and Sigma_yy do not form a valid joint covariance"),
    (lambda: conditional(np.zeros((1, 2)), [0.0], I2, np.zeros((2, 1)), [[1.0]], [0.0]),
     r"mu_x must be a 1-D vector"),
    (lambda: conditional(Z2, [[0.0]], I2, np.zeros((2, 1)), [[1.0]], [0.0]),
     r"mu_y must be a 1-D vector"),
    (lambda: linear_map(Z2, I2, np.ones((1, 3)), [[1.0]]), r"G must have shape \(m, 2\)"),
    (lambda: linear_map(Z2, I2, np.ones((2, 2)), INDEF), r"R must be positive semi-definite"),
    (lambda: linear_map(Z2, I2, np.ones((2, 2)), ASYM), r"R must be symmetric"),
    (lambda: linear_map(Z2, I2, np.ones((1, 2)), I2), r"R must have shape \(1, 1\)"),
    (lambda: linear_map(Z2, ASYM, np.ones((1, 2)), [[1.0]]), r"Sigma_xx must be symmetric"),
    (lambda: linear_map(Z2, np.eye(3), np.ones((1, 2)), [[1.0]]), r"Sigma_xx must have shape"),
    (lambda: joint_linear(Z2, I2, np.ones((1, 2)), [[-1.0]]), r"R must have a non-negative"),
    (lambda: product(Z2, I2, np.zeros(3), I2), r"mu_b must have shape \(2,\)"),
    (lambda: product(Z2, INDEF, Z2, I2), r"Sigma_a must be positive definite"),
    (lambda: product(Z2, I2, Z2, ASYM), r"Sigma_b must be symmetric"),
    (lambda: product(Z2, I2, Z2, np.eye(3)), r"Sigma_b must have shape \(2, 2\)"),
    (lambda: schur_complement(np.ones((2, 3)), 1), r"M must be a square matrix"),
    (lambda: schur_complement(np.eye(3), 0), r"k must satisfy 0 < k < 3"),
    (lambda: schur_complement(np.eye(3), 3), r"k must satisfy 0 < k < 3"),
    (lambda: schur_complement(np.eye(3), 1.0), r"k must be an integer"),
    (lambda: schur_complement(np.array([[1.0, 0, 0], [0, 1, 1], [0, 1, 1]]), 1),
     r"M must have an invertible lower-right block D"),
    (lambda: block_inverse(np.array([[1.0, 1.0], [1.0, 1.0]]), 1),
     r"M must have an invertible Schur complement"),
    (lambda: block_inverse([[1.0, np.nan], [0.0, 1.0]], 1), r"M must be finite"),
]


@pytest.mark.parametrize("call,match", CASES, ids=[c[1][:40] for c in CASES])
def test_validation_errors_name_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
