"""The four ESKF error-state conventions of appendix A1 (kalman_course.chapters.conventions).

Every function is checked against something computed another way: the definitions written
out by hand, the course's filter (eskf.inject, eskf.error_dynamics), an RK4 integration of
the kinematics, and closed forms of the left-error F_t. Attitudes include angles near 0 and
near π; errors are not tiny where the function is exact.
"""

import numpy as np
import pytest

from kalman_course.chapters import conventions as cv
from kalman_course.core import so3
from kalman_course.filters import eskf
from kalman_course.filters.eskf import IDX_BA, IDX_BW, IDX_P, IDX_TH, IDX_V, NominalState

N_T_RIGHT, N_T_LEFT = cv.Convention("nominal - true", "right"), cv.Convention("nominal - true", "left")
T_N_RIGHT, T_N_LEFT = cv.Convention("true - nominal", "right"), cv.Convention("true - nominal", "left")
GRAVITY = np.array([0.0, 0.0, -9.8092])

# attitudes: generic, near 0, near π
ROTATION_VECTORS = {
    "generic": np.array([0.7, -1.1, 0.4]),
    "near 0": np.array([1e-7, -2e-7, 5e-8]),
    "near pi": (np.pi - 1e-3) * np.array([2.0, -1.0, 2.0]) / 3.0,
}


def _state(phi, seed=0):
    rng = np.random.default_rng(seed)
    return NominalState(rng.normal(scale=20.0, size=3), rng.normal(scale=3.0, size=3), so3.exp(phi),
                        rng.normal(scale=0.1, size=3), rng.normal(scale=0.01, size=3))


def _dx(scale, seed=1):
    return scale * np.random.default_rng(seed).normal(size=15)


def _close_states(x, y, atol=1e-12):
    return all(np.allclose(getattr(x, f), getattr(y, f), rtol=0.0, atol=atol)
               for f in ("position", "velocity", "rotation", "accel_bias", "gyro_bias"))


# --- Convention ------------------------------------------------------------------------

def test_convention_properties():
    assert cv.COURSE == N_T_RIGHT and len(set(cv.CONVENTIONS)) == 4
    assert (N_T_RIGHT.sign, T_N_LEFT.sign) == (1.0, -1.0)
    assert (N_T_RIGHT.frame, N_T_LEFT.frame) == ("body", "navigation")
    assert T_N_LEFT.label == "true - nominal, left (navigation)"


@pytest.mark.parametrize("args, word", [(("nominal-true", "right"), "error"), (("true - nominal", "body"), "side")])
def test_convention_rejects_unknown_names(args, word):
    with pytest.raises(ValueError, match=word):
        cv.Convention(*args)


def test_as_convention():
    assert cv.as_convention(("true - nominal", "left")) == T_N_LEFT
    with pytest.raises(ValueError, match="made_in"):
        cv.as_convention(("true - nominal", "up"), "made_in")
    with pytest.raises(ValueError, match="convention must be a Convention"):
        cv.as_convention("course")


# --- definitions, written out by hand ------------------------------------------------------

@pytest.mark.parametrize("where", list(ROTATION_VECTORS))
def test_error_state_matches_the_definitions(where):
    true = _state(ROTATION_VECTORS[where])
    d = _dx(0.2)                                        # not small: the definitions are exact
    phi = d[IDX_TH]
    R = true.rotation
    by_hand = {
        N_T_RIGHT: (true.position + d[IDX_P], R @ so3.exp(phi)),
        N_T_LEFT: (true.position + d[IDX_P], so3.exp(phi) @ R),
        T_N_RIGHT: (true.position - d[IDX_P], R @ so3.exp(-phi)),      # R = Ř Exp(δθ)
        T_N_LEFT: (true.position - d[IDX_P], so3.exp(-phi) @ R),       # R = Exp(δθ) Ř
    }
    for c, (p_check, R_check) in by_hand.items():
        nominal = cv.nominal_with_error(true, d, c)
        assert np.allclose(nominal.position, p_check, atol=1e-12)
        assert np.allclose(nominal.rotation, R_check, atol=1e-12)
        assert np.allclose(nominal.gyro_bias - true.gyro_bias, c.sign * d[IDX_BW], atol=1e-15)
        assert np.allclose(cv.error_state(nominal, true, c), d, atol=1e-9)


def test_error_state_sign_and_side_on_a_known_pair():
    true = _state(ROTATION_VECTORS["generic"])
    phi = np.array([0.01, -0.02, 0.03])
    nominal = NominalState(true.position + [1.0, 2.0, 3.0], true.velocity, so3.exp(phi) @ true.rotation,
                           true.accel_bias, true.gyro_bias)
    assert np.allclose(cv.error_state(nominal, true, N_T_LEFT)[IDX_P], [1.0, 2.0, 3.0])
    assert np.allclose(cv.error_state(nominal, true, T_N_LEFT)[IDX_P], [-1.0, -2.0, -3.0])
    assert np.allclose(cv.error_state(nominal, true, N_T_LEFT)[IDX_TH], phi, atol=1e-12)
    assert np.allclose(cv.error_state(nominal, true, N_T_RIGHT)[IDX_TH], true.rotation.T @ phi, atol=1e-12)
    assert np.allclose(cv.error_state(nominal, true, T_N_LEFT)[IDX_TH], -phi, atol=1e-12)


@pytest.mark.parametrize("where", list(ROTATION_VECTORS))
@pytest.mark.parametrize("c", cv.CONVENTIONS, ids=lambda c: c.label)
def test_inject_undoes_the_definition(where, c):
    true = _state(ROTATION_VECTORS[where])
    d = _dx(0.3)
    assert _close_states(cv.inject(cv.nominal_with_error(true, d, c), d, c), true, atol=1e-10)


def test_inject_of_the_course_is_the_filters():
    nominal = _state(ROTATION_VECTORS["near pi"])
    d = _dx(0.05)
    assert _close_states(cv.inject(nominal, d, cv.COURSE), eskf.inject(nominal, d), atol=1e-14)
    # true - nominal, right: p̂ = p̌ + δp̂ and R̂ = Ř Exp(δθ̂), written out
    plus = cv.inject(nominal, d, T_N_RIGHT)
    assert np.allclose(plus.position, nominal.position + d[IDX_P])
    assert np.allclose(plus.rotation, nominal.rotation @ so3.exp(d[IDX_TH]), atol=1e-14)


@pytest.mark.parametrize("where", list(ROTATION_VECTORS))
@pytest.mark.parametrize("error", cv.ERROR_SIGNS)
def test_left_error_is_the_rotated_right_error(where, error):
    true = _state(ROTATION_VECTORS[where])
    nominal = cv.nominal_with_error(true, _dx(0.4), cv.COURSE)       # a large error: the relation is exact
    right = cv.error_state(nominal, true, cv.Convention(error, "right"))[IDX_TH]
    left = cv.error_state(nominal, true, cv.Convention(error, "left"))[IDX_TH]
    assert np.allclose(cv.attitude_error_to_left(nominal.rotation, right), left, atol=1e-12)
    if where != "near 0":
        assert not np.allclose(left, right, atol=1e-3)


def test_state_arguments_are_validated():
    true = _state(ROTATION_VECTORS["generic"])
    with pytest.raises(ValueError, match="nominal must be a NominalState"):
        cv.error_state((1, 2, 3), true, cv.COURSE)
    bent = NominalState(true.position, true.velocity, 1.01 * true.rotation)
    with pytest.raises(ValueError, match="true.rotation"):
        cv.error_state(true, bent, cv.COURSE)
    with pytest.raises(ValueError, match="dx"):
        cv.inject(true, np.zeros(14), cv.COURSE)
    with pytest.raises(ValueError, match="dtheta_right"):
        cv.attitude_error_to_left(np.eye(3), [1.0, 2.0])


# --- error dynamics --------------------------------------------------------------------

def _readings():
    return np.array([1.3, -0.7, 9.6]), np.array([0.4, -0.25, 0.6])


@pytest.mark.parametrize("where", list(ROTATION_VECTORS))
def test_error_dynamics_closed_forms(where):
    x = _state(ROTATION_VECTORS[where])
    f, w = _readings()
    R, a, omega = x.rotation, f - x.accel_bias, w - x.gyro_bias
    right = cv.error_dynamics(x, f, w, N_T_RIGHT)
    assert np.array_equal(right, eskf.error_dynamics(R, f, w, x.accel_bias, x.gyro_bias))
    left = cv.error_dynamics(x, f, w, T_N_LEFT)
    assert np.allclose(left[IDX_V, IDX_TH], -so3.hat(R @ a), atol=1e-12)
    assert np.allclose(left[IDX_TH, IDX_TH], 0.0, atol=1e-12)
    assert np.allclose(left[IDX_TH, IDX_BW], -R, atol=1e-15)
    assert np.allclose(left[IDX_V, IDX_BA], -R, atol=1e-15)
    assert np.allclose(left[IDX_P, IDX_V], np.eye(3))
    assert np.allclose(right[IDX_TH, IDX_TH], -so3.hat(omega))
    for side in cv.SIDES:     # the sign of the error does not change F_t
        assert np.array_equal(cv.error_dynamics(x, f, w, cv.Convention("nominal - true", side)),
                              cv.error_dynamics(x, f, w, cv.Convention("true - nominal", side)))


def _rk4(state, f, w, g, t, steps=400):
    """Integrate ṗ = v, v̇ = R a + g, Ṙ = R[ω]× with classical RK4 (independent of flow)."""
    a, omega = f - state.accel_bias, w - state.gyro_bias
    y = np.concatenate([state.position, state.velocity, state.rotation.ravel()])

    def rate(y):
        R = y[6:].reshape(3, 3)
        return np.concatenate([y[3:6], R @ a + g, (R @ so3.hat(omega)).ravel()])

    h = t / steps
    for _ in range(steps):
        k1 = rate(y)
        k2 = rate(y + 0.5 * h * k1)
        k3 = rate(y + 0.5 * h * k2)
        k4 = rate(y + h * k3)
        y = y + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    return y[0:3], y[3:6], y[6:].reshape(3, 3)


@pytest.mark.parametrize("t", [0.7, -0.4])
def test_flow_matches_rk4_and_reverses(t):
    x = _state(ROTATION_VECTORS["near pi"])
    f, w = _readings()
    w = 3.0 * w                                           # a fast turn: about 1.5 rad over t
    moved = cv.flow(x, f, w, GRAVITY, t)
    p, v, R = _rk4(x, f, w, GRAVITY, t)
    assert np.allclose(moved.position, p, atol=1e-9)
    assert np.allclose(moved.velocity, v, atol=1e-9)
    assert np.allclose(moved.rotation, R, atol=1e-10)
    assert _close_states(cv.flow(moved, f, w, GRAVITY, -t), x, atol=1e-10)
    with pytest.raises(ValueError, match="t must be"):
        cv.flow(x, f, w, GRAVITY, float("nan"))


def test_error_rate_of_a_pure_velocity_error():
    # same attitude and biases, velocities differ by d: δṗ = d exactly, δv̇ = 0, the rest 0
    true = _state(ROTATION_VECTORS["generic"])
    d = np.array([0.3, -0.2, 0.5])
    nominal = NominalState(true.position, true.velocity + d, true.rotation, true.accel_bias, true.gyro_bias)
    f, w = _readings()
    for c in cv.CONVENTIONS:
        expected = np.zeros(15)
        expected[IDX_P] = c.sign * d
        assert np.allclose(cv.error_rate(nominal, true, f, w, GRAVITY, c), expected, atol=1e-9)
    with pytest.raises(ValueError, match="h must be"):
        cv.error_rate(nominal, true, f, w, GRAVITY, cv.COURSE, h=0.0)


@pytest.mark.parametrize("where", list(ROTATION_VECTORS))
@pytest.mark.parametrize("c", cv.CONVENTIONS, ids=lambda c: c.label)
def test_each_F_fits_its_own_error_and_not_the_other_side(where, c):
    true = _state(ROTATION_VECTORS[where])
    f, w = _readings()
    residuals = []
    for scale in (1e-4, 1e-5):
        nominal = cv.nominal_with_error(true, _dx(scale), c)
        own = cv.dynamics_residual(cv.error_dynamics(nominal, f, w, c), nominal, true, f, w, GRAVITY, c)
        residuals.append(own)
        other = cv.Convention(c.error, "left" if c.side == "right" else "right")
        wrong = cv.dynamics_residual(cv.error_dynamics(nominal, f, w, other), nominal, true, f, w, GRAVITY, c)
        if where != "near 0":                       # at R = I the two sides coincide
            assert wrong > 0.05
    assert residuals[0] < 1e-3
    assert 5.0 < residuals[0] / residuals[1] < 20.0     # the misfit is quadratic in the error


def test_dynamics_residual_rejects_a_bad_F():
    x = _state(ROTATION_VECTORS["generic"])
    f, w = _readings()
    with pytest.raises(ValueError, match="F must be"):
        cv.dynamics_residual(np.eye(9), x, x, f, w, GRAVITY, cv.COURSE)


def test_seed_framework_block():
    f, w = _readings()
    tilted = _state(ROTATION_VECTORS["generic"])
    course = cv.error_dynamics(tilted, f, w, cv.COURSE)
    assert np.array_equal(cv.seed_framework_dynamics(tilted, f, w, "body"), course)
    literal = cv.seed_framework_dynamics(tilted, f, w, "navigation")
    a = f - tilted.accel_bias
    assert np.allclose(literal[IDX_V, IDX_TH], -tilted.rotation @ so3.hat(tilted.rotation @ a))
    assert np.array_equal(np.delete(literal, np.s_[3:6], axis=0), np.delete(course, np.s_[3:6], axis=0))
    nominal = cv.nominal_with_error(tilted, _dx(1e-4), cv.COURSE)
    for c in (N_T_RIGHT, N_T_LEFT):
        F = cv.seed_framework_dynamics(nominal, f, w, "navigation")
        assert cv.dynamics_residual(F, nominal, tilted, f, w, GRAVITY, c) > 0.1
    level = NominalState(tilted.position, tilted.velocity, np.eye(3), tilted.accel_bias, tilted.gyro_bias)
    blocks = [F[IDX_V, IDX_TH] for F in (cv.seed_framework_dynamics(level, f, w, "navigation"),
                                         cv.error_dynamics(level, f, w, N_T_LEFT), course)]
    assert np.allclose(blocks[0], blocks[1], atol=1e-15)       # at R = I the forms coincide
    assert np.allclose(blocks[0], -so3.hat(a), atol=1e-15)
    assert not np.allclose(blocks[2], blocks[0], atol=1e-3)     # the tilted course block differs
    with pytest.raises(ValueError, match="force_frame"):
        cv.seed_framework_dynamics(tilted, f, w, "nav")


# --- injection ---------------------------------------------------------------------------

def test_injection_miss_pattern():
    true = _state(ROTATION_VECTORS["near pi"])
    d = _dx(1e-3)
    for A in cv.CONVENTIONS:
        for B in cv.CONVENTIONS:
            miss = cv.injection_miss(true, d, B, A)
            if A == B:
                assert miss < 1e-9
            elif A.side == B.side:
                assert miss == pytest.approx(2.0, abs=1e-8)
                left = cv.injection_error(true, d, B, A)       # in the course's (right) coordinates
                assert np.allclose(np.abs(np.delete(left, np.s_[6:9])), 2 * np.abs(np.delete(d, np.s_[6:9])),
                                   atol=1e-12)
                assert np.linalg.norm(left[IDX_TH]) == pytest.approx(2 * np.linalg.norm(d[IDX_TH]), rel=1e-9)
            else:
                assert miss > 0.1
    with pytest.raises(ValueError, match="dx must not be zero"):
        cv.injection_miss(true, np.zeros(15), N_T_RIGHT, N_T_LEFT)


def test_identify_injection():
    true = _state(ROTATION_VECTORS["generic"])
    d = _dx(1e-3)
    found = cv.identify_injection(eskf.inject, true, d)
    assert found[cv.COURSE] < 1e-10 and all(m > 0.1 for c, m in found.items() if c != cv.COURSE)

    def left_plus(nominal, dx):      # true − nominal, left, to first order
        R = (np.eye(3) + so3.hat(dx[IDX_TH])) @ nominal.rotation
        return NominalState(nominal.position + dx[IDX_P], nominal.velocity + dx[IDX_V], so3.orthonormalise(R),
                            nominal.accel_bias + dx[IDX_BA], nominal.gyro_bias + dx[IDX_BW])

    found = cv.identify_injection(left_plus, true, d)
    assert min(found, key=found.get) == T_N_LEFT and found[T_N_LEFT] < 1e-5
    assert sorted(found.values())[1] > 0.1
    with pytest.raises(ValueError, match="inject_fn must be callable"):
        cv.identify_injection("inject", true, d)
    with pytest.raises(ValueError, match="dx must not be zero"):
        cv.identify_injection(eskf.inject, true, np.zeros(15))


# --- gravity, the example, the table ------------------------------------------------------

def test_velocity_rate_signs():
    R = so3.exp(ROTATION_VECTORS["generic"])
    f = R.T @ np.array([0.0, 0.0, 9.8092])                 # at rest, tilted
    assert np.allclose(cv.velocity_rate(R, f, GRAVITY, 1), 0.0, atol=1e-12)
    assert np.allclose(cv.velocity_rate(R, f, -GRAVITY, -1), 0.0, atol=1e-12)
    assert np.allclose(cv.velocity_rate(R, f, GRAVITY, -1), [0.0, 0.0, 19.6184], atol=1e-12)
    with pytest.raises(ValueError, match="gravity_sign"):
        cv.velocity_rate(R, f, GRAVITY, 0.5)
    with pytest.raises(ValueError, match="rotation"):
        cv.velocity_rate(2 * R, f, GRAVITY)


def test_example_case():
    case = cv.example_case(seed=3, error_scale=2e-4)
    again = cv.example_case(seed=3, error_scale=2e-4)
    assert np.array_equal(case.dx, again.dx) and _close_states(case.true, again.true, atol=0.0)
    assert np.allclose(cv.error_state(case.nominal, case.true, cv.COURSE), case.dx, atol=1e-12)
    assert 1e-5 < np.abs(case.dx).max() < 1e-3
    # the specific force is gravity's reaction plus a manoeuvre, not zero
    assert 5.0 < np.linalg.norm(case.specific_force) < 15.0
    assert not np.array_equal(cv.example_case(seed=4).dx, case.dx)
    with pytest.raises(ValueError, match="seed"):
        cv.example_case(seed=-1)
    with pytest.raises(ValueError, match="error_scale"):
        cv.example_case(error_scale=0.0)


def test_mixing_table():
    values = {(A, B): 10.0 * i + j for i, A in enumerate(cv.CONVENTIONS) for j, B in enumerate(cv.CONVENTIONS)}
    text = cv.mixing_table(values, "F of", "error of", fmt=".0f")
    lines = text.splitlines()
    assert lines[0] == "rows: F of; columns: error of" and len(lines) == 6
    assert lines[4].startswith(T_N_RIGHT.label) and lines[4].split()[-4:] == ["20", "21", "22", "23"]
    del values[(N_T_LEFT, T_N_RIGHT)]
    with pytest.raises(ValueError, match="every pair"):
        cv.mixing_table(values, "F of", "error of")
