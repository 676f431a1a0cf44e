"""Checks for chapter 02: conditioning a joint Gaussian and pushing one through y = Gx + n."""

from __future__ import annotations

import numpy as np

from kalman_course.core import gaussians
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_symmetric


def random_joint(n: int, m: int, seed: int):
    """A random joint Gaussian of x (n) and y (m): (mu_x, mu_y, Sigma_xx, Sigma_xy, Sigma_yy)."""
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(n + m, n + m))
    Sigma = A @ A.T + 0.5 * np.eye(n + m)
    mu = rng.normal(size=n + m)
    return mu[:n], mu[n:], Sigma[:n, :n], Sigma[:n, n:], Sigma[n:, n:]


def _conditional_cases():
    for n, m, seed in ((2, 1, 3), (3, 2, 4), (4, 3, 5)):
        mu_x, mu_y, Sxx, Sxy, Syy = random_joint(n, m, seed)
        y = mu_y + np.random.default_rng(seed + 100).normal(size=m)
        yield (mu_x, mu_y, Sxx, Sxy, Syy, y), gaussians.conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)


def _call_conditional(fn, args):
    result = call(fn, *args)
    if not isinstance(result, tuple) or len(result) != 2:
        raise CheckFailed("gaussian_conditional must return a tuple (mean, cov)")
    return result


@check
def check_conditional_mean(gaussian_conditional):
    """The mean of the learner's ``gaussian_conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)``."""
    for args, (mean, _) in _conditional_cases():
        mu_x, mu_y, Sxx, Sxy, Syy, y = args
        got, _ = _call_conditional(gaussian_conditional, args)
        expect_close(got, mean, "conditional mean", mistakes=[
            (mu_x + Sxy @ (y - mu_y), "the gain is Σ_xy Σ_yy⁻¹: the innovation y − μ_y must be "
                                      "weighted by the inverse of Σ_yy"),
            (mu_x - Sxy @ np.linalg.solve(Syy, y - mu_y), "sign: the mean moves towards the observation, "
                                                          "μ_x + Σ_xy Σ_yy⁻¹ (y − μ_y)"),
            (mu_x, "the mean did not move: add Σ_xy Σ_yy⁻¹ (y − μ_y)"),
        ], hint="μ_x|y = μ_x + Σ_xy Σ_yy⁻¹ (y − μ_y)")


@check
def check_conditional_covariance(gaussian_conditional):
    """The covariance of the learner's ``gaussian_conditional``: the Schur complement of Σ_yy."""
    for args, (_, cov) in _conditional_cases():
        _, _, Sxx, Sxy, Syy, _ = args
        _, got = _call_conditional(gaussian_conditional, args)
        expect_close(got, cov, "conditional covariance", mistakes=[
            (Sxx + Sxy @ np.linalg.solve(Syy, Sxy.T), "sign: observing y removes uncertainty, "
                                                     "Σ_xx − Σ_xy Σ_yy⁻¹ Σ_yx"),
            (Sxx, "the covariance did not shrink: subtract Σ_xy Σ_yy⁻¹ Σ_yx (the Schur complement)"),
            (Sxx - Sxy @ Sxy.T, "Σ_yy⁻¹ is missing between Σ_xy and Σ_yx"),
        ], hint="Σ_x|y = Σ_xx − Σ_xy Σ_yy⁻¹ Σ_yx")
        expect_symmetric(got, "conditional covariance")


@check
def check_linear_map_moments(linear_map_moments):
    """The learner's ``linear_map_moments(mu_x, Sigma_xx, G, R)`` returns (mu_y, Sigma_yy, Sigma_xy)."""
    rng = np.random.default_rng(21)
    for n, m in ((2, 2), (3, 2), (4, 1)):
        A = rng.normal(size=(n, n))
        Sxx = A @ A.T + 0.3 * np.eye(n)
        mu_x = rng.normal(size=n)
        G = rng.normal(size=(m, n))
        B = rng.normal(size=(m, m))
        R = B @ B.T + 0.2 * np.eye(m)
        result = call(linear_map_moments, mu_x, Sxx, G, R)
        if not isinstance(result, tuple) or len(result) != 3:
            raise CheckFailed("linear_map_moments must return a tuple (mu_y, Sigma_yy, Sigma_xy)")
        mu_y, Syy, Sxy = gaussians.linear_map(mu_x, Sxx, G, R)
        expect_close(result[0], mu_y, "mu_y", hint="the noise has zero mean, so μ_y = G μ_x")
        expect_close(result[1], Syy, "Sigma_yy", mistakes=[
            (G @ Sxx @ G.T, "the observation noise adds its covariance: Σ_yy = G Σ_xx Gᵀ + R"),
            (G @ Sxx @ G.T + R @ R, "R is already a covariance: add R, not R R"),
        ], hint="Σ_yy = G Σ_xx Gᵀ + R")
        expect_close(result[2], Sxy, "Sigma_xy", mistakes=[
            (G @ Sxx, "that is Σ_yx (shape (m, n)); Σ_xy = E[(x − μ_x)(y − μ_y)ᵀ] = Σ_xx Gᵀ"),
            (Sxx, "Σ_xy = Σ_xx Gᵀ: the map G must appear"),
        ], hint="Σ_xy = Σ_xx Gᵀ, shape (n, m)")
