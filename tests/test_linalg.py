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

