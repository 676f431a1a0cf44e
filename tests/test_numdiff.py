"""core.numdiff.numerical_jacobian against Jacobians worked out by hand."""

import numpy as np
import pytest

from kalman_course.core.numdiff import numerical_jacobian


def test_linear_map_gives_its_matrix():
    A = np.array([[1.0, -2.0, 0.5], [3.0, 0.0, 4.0]])
    b = np.array([0.3, -1.0])
    J = numerical_jacobian(lambda x: A @ x + b, np.array([0.2, -0.7, 1.5]))
    assert J.shape == (2, 3)
    np.testing.assert_allclose(J, A, rtol=0, atol=1e-9)


def test_range_bearing_matches_analytic_jacobian():
    # h(x) = [r, θ] of a point (px, py): ∂r/∂p = p/r, ∂θ/∂p = [−py, px]/r²
    px, py = 3.0, -4.0
    r2 = px**2 + py**2
    r = np.sqrt(r2)
    analytic = np.array([[px / r, py / r], [-py / r2, px / r2]])
    J = numerical_jacobian(lambda p: np.array([np.hypot(p[0], p[1]), np.arctan2(p[1], p[0])]),
                           [px, py])
    np.testing.assert_allclose(J, analytic, rtol=1e-8, atol=1e-10)


def test_ctrv_like_step_matches_analytic_jacobian():
    # f(x) = [v cos ψ, v sin ψ, v ψ²] for x = (v, ψ): a non-square (3, 2) Jacobian
    v, psi = 2.5, 0.8
    analytic = np.array([[np.cos(psi), -v * np.sin(psi)],
                         [np.sin(psi), v * np.cos(psi)],
                         [psi**2, 2 * v * psi]])
    J = numerical_jacobian(lambda x: np.array([x[0] * np.cos(x[1]), x[0] * np.sin(x[1]),
                                               x[0] * x[1] ** 2]), np.array([v, psi]))
    assert J.shape == (3, 2)
    np.testing.assert_allclose(J, analytic, rtol=1e-8, atol=1e-10)


def test_central_difference_is_second_order():
    # for f = exp, the error of a central difference is h²/6 · f''' = h²/6 · e^x:
    # a step 10 times larger gives an error 100 times larger (away from round-off)
    x = np.array([0.5])
    errors = [abs(numerical_jacobian(lambda z: np.exp(z), x, h=h)[0, 0] - np.exp(0.5))
              for h in (1e-2, 1e-3)]
    np.testing.assert_allclose(errors[0] / errors[1], 100.0, rtol=0.01)
    np.testing.assert_allclose(errors[0], 1e-4 / 6 * np.exp(0.5), rtol=0.01)


def test_does_not_modify_x():
    x = np.array([1.0, 2.0])
    numerical_jacobian(lambda z: z**2, x)
    np.testing.assert_array_equal(x, [1.0, 2.0])


@pytest.mark.parametrize("x, h, name", [
    (np.array([[1.0, 2.0]]), 1e-6, "x"),
    (np.array([np.nan, 1.0]), 1e-6, "x"),
    ("abc", 1e-6, "x"),
    (np.array([1.0, 2.0]), 0.0, "h"),
    (np.array([1.0, 2.0]), -1e-6, "h"),
    (np.array([1.0, 2.0]), np.inf, "h"),
])
def test_bad_x_or_h_is_named(x, h, name):
    with pytest.raises(ValueError, match=rf"^{name} must"):
        numerical_jacobian(lambda z: z, x, h)


@pytest.mark.parametrize("f", [
    lambda z: np.outer(z, z),                 # 2-D output
    lambda z: float(z[0]),                    # scalar output
    lambda z: np.log(z - 1.0),                # NaN at x − h (log of a negative number)
    lambda z: np.ones(3) if z[0] > 1 else np.ones(2),   # length changes with x
])
def test_bad_f_output_is_named(f):
    with np.errstate(invalid="ignore", divide="ignore"):
        with pytest.raises(ValueError, match=r"^f must"):
            numerical_jacobian(f, np.array([1.0, 2.0]))
