"""core.linalg kernels against the formulas written out with plain numpy."""

import numpy as np
import pytest

from kalman_course.core import linalg


def _spd(rng, n):
    A = rng.standard_normal((n, n))
    return A @ A.T + 0.1 * np.eye(n)


def test_predict_covariance_is_F_P_Ft_plus_Q_exactly_symmetric():
    rng = np.random.default_rng(5)
    F, P, Q = rng.standard_normal((4, 4)), _spd(rng, 4), _spd(rng, 4)
    P_check = linalg.predict_covariance(P, F, Q)
    np.testing.assert_allclose(P_check, F @ P @ F.T + Q, rtol=1e-13)
    assert np.array_equal(P_check, P_check.T)


def test_predict_covariance_writes_into_out():
    rng = np.random.default_rng(6)
    F, P, Q = rng.standard_normal((3, 3)), _spd(rng, 3), _spd(rng, 3)
    history = np.zeros((2, 3, 3))
    result = linalg.predict_covariance(P, F, Q, history[1])
    assert np.shares_memory(result, history) and not history[0].any()
    np.testing.assert_array_equal(history[1], linalg.predict_covariance(P, F, Q))


def test_update_kernels_agree_with_the_textbook_forms():
    rng = np.random.default_rng(7)
    n, m = 4, 2
    P, R, G = _spd(rng, n), _spd(rng, m), rng.standard_normal((m, n))
    GP = G @ P
    S = linalg.innovation_covariance(GP, G, R)
    np.testing.assert_allclose(S, G @ P @ G.T + R, rtol=1e-13)
    K = linalg.gain(GP, S)
    np.testing.assert_allclose(K, P @ G.T @ np.linalg.inv(S), rtol=1e-10)
    I_KG = np.eye(n) - K @ G
    joseph = linalg.joseph_update(P, K, G, R)
    np.testing.assert_allclose(joseph, I_KG @ P @ I_KG.T + K @ R @ K.T, rtol=1e-10, atol=1e-13)
    # with the optimal gain the short form is the same matrix
    np.testing.assert_allclose(linalg.short_update(P, K, GP), joseph, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("scale", [0.0, 1e-3, 0.3, 5.0, 40.0])
def test_expm_agrees_with_scipy(scale):
    from scipy.linalg import expm as scipy_expm

    A = scale * np.random.default_rng(4).normal(size=(15, 15))
    assert np.allclose(linalg.expm(A), scipy_expm(A), rtol=1e-12, atol=1e-14 * np.abs(scipy_expm(A)).max())



def _spd_with_condition(rng, m, condition):
    U, _ = np.linalg.qr(rng.standard_normal((m, m)))
    return linalg.symmetrise(U @ np.diag(np.geomspace(1.0, 1.0 / condition, m)) @ U.T)


@pytest.mark.parametrize("m", [1, 2, 3, 4, 6])
def test_whitened_gain_is_the_gain_and_the_cholesky_whitened_cross_covariance(m):
    """K = P̌ Gᵀ S⁻¹ and Z = L⁻¹ G P̌ with S = L Lᵀ, so that K G P̌ = Zᵀ Z, for every path
    (m = 1 divides, m = 2, 3 write the factor out, larger m use LAPACK)."""
    rng = np.random.default_rng(30 + m)
    n = 5
    P, G, R = _spd(rng, n), rng.standard_normal((m, n)), _spd(rng, m)
    GP = G @ P
    S = linalg.innovation_covariance(GP, G, R)
    K, Z = linalg.whitened_gain(GP, S)
    assert K.shape == (n, m) and Z.shape == (m, n)
    np.testing.assert_allclose(K, np.linalg.solve(S, GP).T, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(np.linalg.cholesky(S) @ Z, GP, rtol=1e-12, atol=1e-13)
    np.testing.assert_allclose(Z.T @ Z, K @ GP, rtol=1e-11, atol=1e-13)
    np.testing.assert_array_equal(linalg.gain(GP, S), K if m <= 3 else np.linalg.solve(S, GP).T)


@pytest.mark.parametrize("m", [2, 3])
@pytest.mark.parametrize("condition", [1e4, 1e8, 1e12])
def test_the_written_out_factor_inverts_the_cholesky_factor(m, condition):
    """_inverse_cholesky_factor(S) is lower triangular with T S Tᵀ = I to round-off."""
    S = _spd_with_condition(np.random.default_rng(int(np.log10(condition)) + m), m, condition)
    T = linalg._inverse_cholesky_factor(S)
    assert np.array_equal(T, np.tril(T)) and (np.diag(T) > 0).all()
    # the factor of an S with round-off in ε‖S‖ moves by ε cond(S) relative to ‖L⁻¹‖; both
    # ways of computing it agree to that, and T S Tᵀ = I − T E Tᵀ with ‖E‖ ≈ ε‖S‖
    eps = np.finfo(float).eps
    T_lapack = np.linalg.inv(np.linalg.cholesky(S))
    np.testing.assert_allclose(T, T_lapack, rtol=0, atol=20 * eps * condition * np.abs(T_lapack).max())
    np.testing.assert_allclose(T @ S @ T.T, np.eye(m), rtol=0, atol=20 * eps * condition)


@pytest.mark.parametrize("S", [np.array([[-2.0]]), np.array([[1.0, 2.0], [2.0, 1.0]]),
                               np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 3.0], [0.0, 3.0, 1.0]]),
                               np.diag([1.0, 1.0, 1.0, -1.0]), np.array([[np.nan, 0.0], [0.0, 1.0]])],
                         ids=["m1-negative", "m2-indefinite", "m3-indefinite", "m4-indefinite", "m2-nan"])
def test_an_S_without_cholesky_factor_is_solved_by_LU(S):
    """A grader's deliberately wrong S is not positive definite: no Z, and K is the LU solve's."""
    GP = np.random.default_rng(40).standard_normal((S.shape[0], 3))
    K, Z = linalg.whitened_gain(GP, S)
    assert Z is None
    np.testing.assert_array_equal(K, np.linalg.solve(S, GP).T)
    np.testing.assert_array_equal(linalg.gain(GP, S), K)


def test_gain_of_one_component_keeps_float32():
    """Lecture 09's round-off table runs the filter in float32 with one measured component."""
    GP = np.array([[2.0, 1.0]], dtype=np.float32)
    S = np.array([[4.0]], dtype=np.float32)
    K, Z = linalg.whitened_gain(GP, S)
    assert K.dtype == Z.dtype == np.float32
    np.testing.assert_array_equal(K, GP.T / S[0, 0])


def test_whitened_update_is_the_short_form_exactly_symmetric_into_out():
    rng = np.random.default_rng(8)
    n, m = 4, 2
    P, R, G = _spd(rng, n), _spd(rng, m), rng.standard_normal((m, n))
    GP = G @ P
    K, Z = linalg.whitened_gain(GP, linalg.innovation_covariance(GP, G, R))
    history = np.zeros((2, n, n))
    P_hat = linalg.whitened_update(P, Z, history[1])
    assert np.shares_memory(P_hat, history) and not history[0].any()
    assert np.array_equal(P_hat, P_hat.T)
    np.testing.assert_allclose(P_hat, linalg.short_update(P, K, GP), rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(P_hat, linalg.joseph_update(P, K, G, R), rtol=1e-10, atol=1e-13)
