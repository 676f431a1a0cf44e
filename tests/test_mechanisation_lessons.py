"""The chapter-07 experiments of ``chapters.mechanisation``: attitude integration and its
order, and the error budget of the flat, non-rotating navigation frame."""

import math
from types import SimpleNamespace

import numpy as np
import pytest

from kalman_course.chapters import mechanisation as mech
from kalman_course.chapters.eskf_bias import EARTH_RATE
from kalman_course.core import so3
from kalman_course.filters.eskf_config import load_config

# a cone that is not small, turning backwards: separates sin β from β and the sign of Ω
BETA, CONE = 0.7, -2.3


def _linear(w0, w_dot):
    return lambda s: np.asarray(w0) + s * np.asarray(w_dot)


# ---------------------------------------------------------------------------------------
# the coning motion
# ---------------------------------------------------------------------------------------

def test_coning_attitude_is_unit_and_tilts_z_by_the_cone_angle():
    t = np.linspace(0.0, 3.0, 31)
    q = mech.coning_attitude(t, BETA, CONE)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)
    z_body = so3.quat_to_matrix(q)[:, :, 2]
    assert np.allclose(np.arccos(z_body[:, 2]), BETA, atol=1e-12)
    # the horizontal axis of rotation turns at Ω: its azimuth at t is Ω t
    assert np.allclose(np.arctan2(q[:, 2], q[:, 1]), np.angle(np.exp(1j * CONE * t)), atol=1e-12)


def test_coning_rate_satisfies_the_kinematics_by_finite_differences():
    t, h = np.linspace(0.1, 4.0, 40), 1e-6
    q = mech.coning_attitude(t, BETA, CONE)
    q_dot = (mech.coning_attitude(t + h, BETA, CONE) - mech.coning_attitude(t - h, BETA, CONE)) / (2 * h)
    w = mech.coning_rate(t, BETA, CONE)
    rhs = 0.5 * so3.quat_multiply(q, np.c_[np.zeros(len(t)), w])     # q̇ = ½ q ⊗ (0, ω): body rate
    assert np.abs(q_dot - rhs).max() < 1e-8
    # the rate on the left of q would be the navigation-frame rate, which differs here
    left = 0.5 * so3.quat_multiply(np.c_[np.zeros(len(t)), w], q)
    assert np.abs(q_dot - left).max() > 0.1


def test_coning_rate_integral_matches_quadrature_on_irregular_intervals():
    t = np.array([0.0, 0.013, 0.05, 0.31, 0.32, 1.7])
    nodes, weights = np.polynomial.legendre.leggauss(10)
    expected = []
    for a, b in zip(t[:-1], t[1:]):
        s = 0.5 * (b - a) * nodes + 0.5 * (a + b)
        expected.append(0.5 * (b - a) * weights @ mech.coning_rate(s, BETA, CONE))
    assert np.allclose(mech.coning_rate_integral(t, BETA, CONE), expected, atol=1e-13)


@pytest.mark.parametrize("kwargs, match", [
    (dict(t=[0.0, 1.0], cone_angle=0.0, cone_rate=1.0), "cone_angle"),
    (dict(t=[0.0, 1.0], cone_angle=3.2, cone_rate=1.0), "cone_angle"),
    (dict(t=[0.0, 1.0], cone_angle=0.2, cone_rate=np.nan), "cone_rate"),
    (dict(t=[0.0, 1.0], cone_angle=0.2, cone_rate="1"), "cone_rate"),
    (dict(t=[[0.0, 1.0]], cone_angle=0.2, cone_rate=1.0), "t"),
])
def test_coning_functions_reject_bad_input(kwargs, match):
    for f in (mech.coning_attitude, mech.coning_rate, mech.coning_rate_integral):
        with pytest.raises(ValueError, match=match):
            f(**kwargs)


def test_coning_rate_integral_needs_increasing_times():
    with pytest.raises(ValueError, match="t must"):
        mech.coning_rate_integral([0.0, 0.5, 0.4], BETA, CONE)
    with pytest.raises(ValueError, match="t must"):
        mech.coning_rate_integral([0.0], BETA, CONE)


# ---------------------------------------------------------------------------------------
# the RK4 reference
# ---------------------------------------------------------------------------------------

def test_reference_attitude_with_a_constant_rate_is_q0_times_exp():
    q0 = so3.quat_exp([0.4, -1.1, 0.7])                   # not the identity: the side of ω matters
    w = np.array([0.9, 0.3, -1.4])
    t = np.linspace(0.0, 2.0, 11)
    q = mech.reference_attitude(lambda s: w, t, q0, substeps=64)
    exact = so3.quat_multiply(np.broadcast_to(q0, (len(t), 4)), so3.quat_exp(t[:, None] * w))
    assert mech.attitude_error(q, exact).max() < 1e-11
    wrong_side = so3.quat_multiply(so3.quat_exp(t[:, None] * w), np.broadcast_to(q0, (len(t), 4)))
    assert mech.attitude_error(q, wrong_side).max() > 0.1


def test_reference_attitude_matches_scipy_on_a_curving_rate():
    integrate = pytest.importorskip("scipy.integrate")

    def rate(s):
        return np.array([0.8 * np.sin(1.3 * s), -0.5 + 0.2 * s, 0.6 * np.cos(2.1 * s)])

    t = np.linspace(0.0, 5.0, 51)
    q0 = np.array([0.9, 0.1, -0.3, 0.2])
    sol = integrate.solve_ivp(lambda s, q: 0.5 * so3.quat_multiply(q, np.r_[0.0, rate(s)]), (0.0, 5.0),
                              q0 / np.linalg.norm(q0), method="DOP853", rtol=1e-12, atol=1e-13, t_eval=t)
    q = mech.reference_attitude(rate, t, q0, substeps=16)
    assert mech.attitude_error(q, sol.y.T).max() < 1e-10


@pytest.mark.parametrize("kwargs, match", [
    (dict(rate=np.zeros(3), t=[0.0, 1.0], q0=[1, 0, 0, 0]), "rate"),
    (dict(rate=lambda s: np.zeros(3), t=[0.0, 1.0], q0=[1, 0, 0]), "q0"),
    (dict(rate=lambda s: np.zeros(3), t=[1.0, 0.0], q0=[1, 0, 0, 0]), "t must"),
    (dict(rate=lambda s: np.zeros(3), t=[0.0, 1.0], q0=[1, 0, 0, 0], substeps=0), "substeps"),
    (dict(rate=lambda s: np.zeros(2), t=[0.0, 1.0], q0=[1, 0, 0, 0]), "rate"),
])
def test_reference_attitude_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        mech.reference_attitude(**kwargs)


# ---------------------------------------------------------------------------------------
# the rules
# ---------------------------------------------------------------------------------------

def test_step_rotation_vectors_zeroth_and_first_order_by_hand():
    w = np.array([[1.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.5, 0.5, 3.0]])
    T = np.array([0.1, 0.3])                              # irregular steps, each its own T
    zeroth = mech.step_rotation_vectors(w, T, "zeroth_order")
    assert np.allclose(zeroth, [[0.05, 0.1, 0.0], [0.075, 0.375, 0.45]])
    first = mech.step_rotation_vectors(w, T, "first_order")
    # ω_0 × ω_1 = (0, 0, 2): the correction turns about +z by T²/12 · 2
    assert np.allclose(first[0] - zeroth[0], [0.0, 0.0, 0.01 * 2 / 12])
    assert np.allclose(first[1] - zeroth[1], 0.09 / 12 * np.cross(w[1], w[2]))


def test_step_rotation_vectors_use_given_rate_integrals():
    w = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    inc = np.array([[0.3, -0.2, 0.1]])
    assert np.allclose(mech.step_rotation_vectors(w, 0.2, "zeroth_order", inc), inc)
    assert np.allclose(mech.step_rotation_vectors(w, 0.2, "first_order", inc), inc + [0.0, 0.0, 0.04 / 12])


@pytest.mark.parametrize("kwargs, match", [
    (dict(w=np.zeros((1, 3)), T=0.1, rule="zeroth_order"), "w must hold"),
    (dict(w=np.zeros((3, 2)), T=0.1, rule="zeroth_order"), "w"),
    (dict(w=np.zeros((3, 3)), T=-0.1, rule="zeroth_order"), "T"),
    (dict(w=np.zeros((3, 3)), T=[0.1, 0.0], rule="zeroth_order"), "T"),
    (dict(w=np.zeros((3, 3)), T=[0.1, 0.1, 0.1], rule="zeroth_order"), "T"),
    (dict(w=np.zeros((3, 3)), T=0.1, rule="second_order"), "rule"),
    (dict(w=np.zeros((3, 3)), T=0.1, rule="euler"), "euler"),
    (dict(w=np.zeros((3, 3)), T=0.1, rule="first_order", rate_integrals=np.zeros((3, 3))), "rate_integrals"),
])
def test_step_rotation_vectors_reject_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        mech.step_rotation_vectors(**kwargs)


def test_euler_rule_is_the_renormalised_forward_step_with_the_start_rate():
    q0 = so3.quat_exp([0.2, 0.5, -0.4])
    w = np.array([[0.3, -0.7, 1.2], [-0.9, 0.4, 0.1], [0.5, 0.5, -0.5]])
    T = 0.2
    q = mech.integrate_quaternion(q0, w, T, "euler")
    by_hand = [q0]
    for k in range(2):
        p = by_hand[-1] + 0.5 * T * so3.quat_multiply(by_hand[-1], np.r_[0.0, w[k]])
        by_hand.append(p / np.linalg.norm(p))
    assert np.allclose(q, by_hand, atol=1e-15)
    assert np.allclose(np.linalg.norm(q, axis=1), 1.0, atol=1e-15)


def test_exp_rules_are_exact_for_a_constant_rate_and_euler_is_not():
    q0 = so3.quat_exp([-0.3, 0.8, 0.2])
    w = np.tile([0.4, -1.0, 0.6], (51, 1))
    T = 0.05
    exact = so3.quat_multiply(np.broadcast_to(q0, (51, 4)), so3.quat_exp(np.arange(51)[:, None] * T * w[0]))
    for rule in ("zeroth_order", "first_order"):
        assert mech.attitude_error(mech.integrate_quaternion(q0, w, T, rule), exact).max() < 1e-13
    assert mech.attitude_error(mech.integrate_quaternion(q0, w, T, "euler"), exact).max() > 1e-4


def test_quaternion_and_matrix_versions_agree_to_round_off():
    t = np.arange(401) * 0.01
    q_true = mech.coning_attitude(t, BETA, CONE)
    w = mech.coning_rate(t, BETA, CONE)
    R0 = so3.quat_to_matrix(q_true[0])
    for rule in ("zeroth_order", "first_order"):
        q = mech.integrate_quaternion(q_true[0], w, 0.01, rule)
        R = mech.integrate_rotation_matrix(R0, w, 0.01, rule)
        assert np.abs(so3.quat_to_matrix(q) - R).max() < 1e-12
    with pytest.raises(ValueError, match="euler"):
        mech.integrate_rotation_matrix(R0, w, 0.01, "euler")
    with pytest.raises(ValueError, match="R0"):
        mech.integrate_rotation_matrix(2 * R0, w, 0.01, "zeroth_order")


def test_integrate_quaternion_rejects_rate_integrals_for_euler_and_short_rates():
    with pytest.raises(ValueError, match="rate_integrals"):
        mech.integrate_quaternion([1, 0, 0, 0], np.zeros((3, 3)), 0.1, "euler", np.zeros((2, 3)))
    with pytest.raises(ValueError, match="w must hold"):
        mech.integrate_quaternion([1, 0, 0, 0], np.zeros((1, 3)), 0.1, "euler")
    with pytest.raises(ValueError, match="q0"):
        mech.integrate_quaternion([0, 0, 0, 0], np.zeros((3, 3)), 0.1, "first_order")


def test_first_order_correction_has_the_sign_that_reduces_the_local_error():
    w0, w_dot = np.array([0.3, -0.2, 0.5]), np.array([0.4, 0.3, -0.2])
    T = 0.1
    truth = mech.reference_attitude(_linear(w0, w_dot), [0.0, T], [1, 0, 0, 0], substeps=64)[-1]
    w = np.stack([w0, w0 + T * w_dot])
    zeroth = mech.attitude_error(mech.integrate_quaternion([1, 0, 0, 0], w, T, "zeroth_order")[-1], truth)
    first = mech.attitude_error(mech.integrate_quaternion([1, 0, 0, 0], w, T, "first_order")[-1], truth)
    flipped = so3.quat_exp(0.5 * (w[0] + w[1]) * T - T * T / 12 * np.cross(w[0], w[1]))
    assert first < 1e-3 * zeroth
    assert mech.attitude_error(flipped, truth) > 1.5 * zeroth       # the wrong sign doubles the error


def test_local_errors_scale_as_t3_and_t5_and_sola_agrees_with_exp():
    local = mech.local_errors([0.4, -0.3, 0.6], [0.15, 0.1, -0.12], [0.2, 0.1, 0.05])
    assert np.allclose(mech.halving_ratios(local["zeroth_order"][::-1]), 8, rtol=0.02)
    assert np.allclose(mech.halving_ratios(local["first_order"][::-1]), 32, rtol=0.02)
    assert np.allclose(mech.halving_ratios(local["sola_vs_exp"][::-1]), 32, rtol=0.02)
    with pytest.raises(ValueError, match="steps"):
        mech.local_errors([0.4, -0.3, 0.6], [0.15, 0.1, -0.12], [0.1, -0.05])


def test_sola_increment_carries_half_the_rotation_vector_correction():
    w0, w1, T = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0]), 1e-3
    dq = mech.sola_increment(w0, w1, T)
    assert np.isclose(np.linalg.norm(dq), 1.0, atol=1e-15)
    # vector part: ½ ω̄ T plus T²/24 ω_0 × ω_1, to first order in the small angle
    assert np.allclose(dq[1:], [0.5e-3 / 2 * 1, 0.5e-3 / 2 * 1, 1e-6 / 24], rtol=1e-6, atol=1e-15)
    with pytest.raises(ValueError, match="T"):
        mech.sola_increment(w0, w1, 0.0)


def test_coning_correction_residual_is_zero():
    first, second = mech.coning_correction_residual()
    assert first.shape == second.shape == (3, 1)
    assert all(e == 0 for e in (*first, *second))


# ---------------------------------------------------------------------------------------
# orders
# ---------------------------------------------------------------------------------------

def test_attitude_error_handles_sign_small_and_near_pi_angles():
    axis = np.array([2.0, -1.0, 3.0]) / np.sqrt(14.0)
    q = so3.quat_exp(0.3 * axis)
    for angle in (1e-9, 0.4, np.pi - 1e-6):
        other = so3.quat_multiply(q, so3.quat_exp(angle * axis[::-1] / np.linalg.norm(axis)))
        assert np.isclose(mech.attitude_error(other, q), angle, rtol=1e-7, atol=0.0)
        assert np.isclose(mech.attitude_error(-other, q), angle, rtol=1e-7, atol=0.0)


def test_max_attitude_errors_measure_the_orders_on_coning():
    t = np.arange(801) * 0.01
    q = mech.coning_attitude(t, 0.2, np.pi)
    w = mech.coning_rate(t, 0.2, np.pi)
    inc = mech.coning_rate_integral(t, 0.2, np.pi)
    expected = {("euler", None): 2, ("zeroth_order", None): 4, ("first_order", None): 4,
                ("first_order", "exact"): 16}
    for (rule, exact), ratio in expected.items():
        e = mech.max_attitude_errors(q, w, 0.01, rule, rate_integrals=inc if exact else None)
        assert np.allclose(mech.halving_ratios(e), ratio, rtol=0.03), (rule, exact)
    # stride 1 of the exact motion with the true increments equals the truth at the samples
    zero = mech.max_attitude_errors(q, w, 0.01, "zeroth_order", strides=(1,))
    assert zero.shape == (1,) and zero[0] > 1e-5


@pytest.mark.parametrize("kwargs, match", [
    (dict(strides=(1, 3)), "multiple"),
    (dict(strides=(1, 2.5)), "strides"),
    (dict(strides=()), "strides"),
    (dict(T=0.0), "T"),
])
def test_max_attitude_errors_rejects_bad_input(kwargs, match):
    t = np.arange(9) * 0.01
    args = dict(q_true=mech.coning_attitude(t, 0.2, 1.0), w=mech.coning_rate(t, 0.2, 1.0), T=0.01,
                rule="zeroth_order")
    args.update(kwargs)
    with pytest.raises(ValueError, match=match):
        mech.max_attitude_errors(**args)


def test_halving_ratios_and_slope_recover_a_known_power():
    h = 0.01 * 2.0 ** np.arange(4)
    e = 3.7 * h ** 2.5
    assert np.allclose(mech.halving_ratios(e), 2 ** 2.5)
    assert mech.loglog_slope(h, e) == pytest.approx(2.5, abs=1e-12)
    with pytest.raises(ValueError, match="errors"):
        mech.halving_ratios([1e-3, 0.0])
    with pytest.raises(ValueError, match="steps"):
        mech.loglog_slope([0.1, 0.1], [1.0, 2.0])


# ---------------------------------------------------------------------------------------
# the flat frame's error budget
# ---------------------------------------------------------------------------------------

def _truth():
    # 300 m east at 10 m/s, 400 m north at 16 m/s, then 160 m back south: the farthest point
    # (500 m out) is not the end; the height climbs 3 m at a steady rate
    t = np.arange(0.0, 66.0, 1.0)
    p = np.zeros((len(t), 3))
    v = np.zeros((len(t), 3))
    east, north, south = t <= 30.0, (t > 30.0) & (t <= 55.0), t > 55.0
    p[east, 0], v[east, 0] = 10.0 * t[east], 10.0
    p[~east, 0] = 300.0
    p[north, 1], v[north, 1] = 16.0 * (t[north] - 30.0), 16.0
    p[south, 1], v[south, 1] = 400.0 - 16.0 * (t[south] - 55.0), -16.0
    p[:, 2] = 3.0 * t / t[-1] - 1.0
    return SimpleNamespace(t=t, position=p, velocity=v)


def test_drive_extent_by_hand():
    ext = mech.drive_extent(_truth())
    assert ext.duration == 65.0
    assert ext.top_speed == 16.0
    assert ext.max_distance == pytest.approx(math.hypot(300.0, 400.0))
    assert ext.height_range == pytest.approx(3.0)
    dz = 3.0 / 65.0                                       # per 1 s sample
    assert ext.path_length == pytest.approx(30 * math.hypot(10.0, dz) + 35 * math.hypot(16.0, dz))
    assert ext.mean_speed == pytest.approx(ext.path_length / 65.0)


def test_drive_extent_rejects_bad_truth():
    with pytest.raises(ValueError, match="velocity"):
        mech.drive_extent(SimpleNamespace(t=[0.0, 1.0], position=np.zeros((2, 3))))
    truth = _truth()
    truth.position = truth.position[:-1]
    with pytest.raises(ValueError, match="truth.position"):
        mech.drive_extent(truth)


def test_neglected_terms_by_hand_and_south_of_the_equator():
    ext = mech.drive_extent(_truth())
    g = 9.7                                              # not 9.81: the gravity terms must use it
    terms = mech.neglected_terms(49.0, ext, [0.0, 0.0, -g], radius=6.0e6)
    phi = np.deg2rad(49.0)
    assert terms["earth_rate_up"].size == pytest.approx(EARTH_RATE * np.sin(phi))
    assert terms["earth_rate_north"].size == pytest.approx(EARTH_RATE * np.cos(phi))
    assert terms["coriolis"].size == pytest.approx(2 * EARTH_RATE * 16.0)
    assert terms["transport_rate"].size == pytest.approx(16.0 / 6.0e6)
    assert terms["gravity_direction"].size == pytest.approx(g * 500.0 / 6.0e6)
    assert terms["gravity_magnitude"].size == pytest.approx(2 * g * 3.0 / 6.0e6)
    assert {t.channel for t in terms.values()} <= set(mech.CHANNELS)
    south = mech.neglected_terms(-49.0, ext, g, radius=6.0e6)
    assert south["earth_rate_up"].size == pytest.approx(terms["earth_rate_up"].size)
    with pytest.raises(ValueError, match="extent"):
        mech.neglected_terms(49.0, {"top_speed": 1.0}, g)
    with pytest.raises(ValueError, match="latitude"):
        mech.neglected_terms(95.0, ext, g)
    with pytest.raises(ValueError, match="gravity"):
        mech.neglected_terms(49.0, ext, [0.0, 0.0, 0.0])


@pytest.mark.parametrize("channel", mech.CHANNELS)
def test_growth_closed_forms_match_the_integrator_chain(channel):
    for t in (0.1, 7.0, 470.0):
        closed = mech.position_error_growth(channel, 3e-4, t, gravity=9.7,
                                            speed=12.5 if channel == "heading_rate" else None)
        chain = mech.chain_position_error(channel, 3e-4, t, gravity=9.7, speed=12.5)
        assert closed == pytest.approx(chain, rel=1e-12)


@pytest.mark.parametrize("channel", mech.CHANNELS)
def test_growth_power_is_how_the_error_scales_with_the_horizon(channel):
    kw = dict(speed=3.0) if channel == "heading_rate" else {}
    e = mech.position_error_growth(channel, 1e-3, np.array([10.0, 20.0]), **kw)
    assert e[1] / e[0] == pytest.approx(2 ** mech.GROWTH_POWER[channel], rel=1e-12)


def test_chain_matches_scipy_van_loan_and_a_seeded_monte_carlo_for_gyro_noise():
    linalg = pytest.importorskip("scipy.linalg")
    g, sigma, t = 9.7, 2e-3, 20.0
    F = np.array([[0.0, 0.0, 0.0], [g, 0.0, 0.0], [0.0, 1.0, 0.0]])     # δθ → δv → δp
    Q = np.diag([sigma ** 2, 0.0, 0.0])
    M = linalg.expm(np.block([[-F, Q], [np.zeros((3, 3)), F.T]]) * t)
    P = M[3:, 3:].T @ M[:3, 3:]
    assert mech.chain_position_error("gyro_white", sigma, t, gravity=g) == pytest.approx(np.sqrt(P[2, 2]), rel=1e-10)
    rng = np.random.default_rng(7)
    h, n = 0.02, int(t / 0.02)
    theta = np.cumsum(rng.normal(0.0, sigma * np.sqrt(h), (4000, n)), axis=1)
    p = np.cumsum(np.cumsum(g * theta * h, axis=1) * h, axis=1)[:, -1]
    assert p.std() == pytest.approx(mech.position_error_growth("gyro_white", sigma, t, gravity=g), rel=0.05)


@pytest.mark.parametrize("kwargs, match", [
    (dict(channel="tilt", size=1.0, t=1.0), "channel"),
    (dict(channel="acceleration", size=-1.0, t=1.0), "size"),
    (dict(channel="acceleration", size=1.0, t=-1.0), "t must"),
    (dict(channel="heading_rate", size=1.0, t=1.0), "speed"),
    (dict(channel="tilt_rate", size=1.0, t=1.0, speed=3.0), "speed"),
    (dict(channel="tilt_rate", size=1.0, t=1.0, gravity=0.0), "gravity"),
])
def test_position_error_growth_rejects_bad_input(kwargs, match):
    with pytest.raises(ValueError, match=match):
        mech.position_error_growth(**kwargs)


def test_imu_error_sources_read_the_config_metadata_and_the_right_std_entries():
    cfg = load_config("kitti_lidar")
    std = np.arange(1.0, 16.0) * 1e-3                     # every entry different: a wrong slice shows
    rows = mech.imu_error_sources(cfg, {"accel": 0.01, "gyro": 1.75e-4}, std)
    assert rows["accel_white"].size == cfg.si("process.accel_noise")
    assert rows["gyro_white"].size == cfg.si("process.gyro_noise")
    assert rows["accel_bias_walk"].size == cfg.si("process.accel_bias_noise")
    assert rows["gyro_bias_walk"].size == cfg.si("process.gyro_bias_noise")
    assert rows["gyro_white_metadata"].size == 1.75e-4
    assert rows["accel_bias_sigma"].size == std[10]        # the larger of b_a,x and b_a,y
    assert rows["gyro_bias_sigma"].size == std[13]         # the larger of b_ω,x and b_ω,y
    assert {r.channel for r in rows.values()} <= set(mech.CHANNELS)
    assert list(mech.imu_error_sources(cfg)) == ["accel_white", "gyro_white", "accel_bias_walk", "gyro_bias_walk"]
    with pytest.raises(ValueError, match="config"):
        mech.imu_error_sources({"accel": 0.1})
    with pytest.raises(ValueError, match="metadata"):
        mech.imu_error_sources(cfg, {"accel": 0.01})
    with pytest.raises(ValueError, match="filter_std"):
        mech.imu_error_sources(cfg, filter_std=np.ones(9))


def test_error_budget_rows_and_speed():
    terms = mech.neglected_terms(49.0, mech.drive_extent(_truth()), 9.7)
    rows = [terms["earth_rate_up"], terms["coriolis"]]
    b = mech.error_budget(rows, [30.0, 60.0], gravity=9.7, speed=16.0)
    assert b.shape == (2, 2)
    assert b[0, 0] == pytest.approx(0.5 * 16.0 * terms["earth_rate_up"].size * 900.0)
    assert b[1, 1] == pytest.approx(0.5 * terms["coriolis"].size * 3600.0)
    with pytest.raises(ValueError, match="sources"):
        mech.error_budget([], [30.0])
    with pytest.raises(ValueError, match="speed"):
        mech.error_budget(rows, [30.0])
