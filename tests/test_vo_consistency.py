"""Why the VO-increments filter is overconfident, and what lets VO + IMU beat VO alone:
where the filter linearises (FEJ, the ideal EKF), the unobservable heading, the simulated
IMU, the clock and frame checks, and the variants of lecture 10 §2."""

from types import SimpleNamespace

import numpy as np
import pytest

from kalman_course.chapters import visual_odometry as vo
from kalman_course.core import so3
from kalman_course.core.imu import NavState
from kalman_course.core.observations import PoseObservations
from kalman_course.data import imu_trajectory, load_kitti
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.eskf_relative import (pose_transition_blocks, relative_motion, relative_pose_jacobian,
                                                 run_relative, yaw_nullspace)

G = np.array([0.0, 0.0, -9.8092])
# an increment σ of the size NIS-tuning gives for ORB-SLAM2 (m ×3, rad ×3), unequal per axis
STD = (0.0058, 0.0041, 0.0029, 3.8e-4, 2.2e-4, 1.9e-4)


@pytest.fixture(scope="module")
def seq00():
    return load_kitti("seq00")


@pytest.fixture(scope="module")
def orb(seq00):
    return vo.setup(seq00, "ORB-SLAM2")


@pytest.fixture(scope="module")
def sptam(seq00):
    return vo.setup(seq00, "S-PTAM")


def random_state(rng):
    """A tilted, moving state far from the origin (so that [u]× p matters)."""
    return (100.0 * rng.standard_normal(3), 10.0 * rng.standard_normal(3),
            so3.exp(np.array([0.4, -0.3, 2.5]) * rng.standard_normal(3)))


# ---------------------------------------------------------------------------------------
# the unobservable heading direction and the two Jacobians
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1])
def test_yaw_nullspace_is_the_error_of_a_turn_about_gravity(seed):
    # the nominal equals the truth; turning the truth by φ about u = g/|g| changes the error
    # (nominal − true) by −φ N, to first order: central differences in φ
    rng = np.random.default_rng(seed)
    p, v, R = random_state(rng)
    u = G / np.linalg.norm(G)

    def error(phi):
        C = so3.exp(phi * u)
        return np.concatenate([p - C @ p, v - C @ v, so3.log((C @ R).T @ R), np.zeros(6)])

    h = 1e-6
    numeric = (error(h) - error(-h)) / (2 * h)
    np.testing.assert_allclose(-numeric, yaw_nullspace(p, v, R, G), atol=1e-6)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_relative_jacobian_annihilates_the_turn_at_any_pair_of_poses(seed):
    rng = np.random.default_rng(seed)
    p_c, v_c, R_c = random_state(rng)
    p, v, R = random_state(rng)
    Gr = relative_pose_jacobian(R_c, *relative_motion(p_c, R_c, p, R))
    n_c = yaw_nullspace(p_c, v_c, R_c, G)
    N = np.concatenate([yaw_nullspace(p, v, R, G), n_c[0:3], n_c[6:9]])
    np.testing.assert_allclose(Gr @ N, 0.0, atol=1e-10)
    # at a clone pose other than the one the nullspace was taken at, it does not
    Gr_off = relative_pose_jacobian(R_c @ so3.exp(np.array([0.0, 0.0, 0.01])),
                                    *relative_motion(p_c, R_c @ so3.exp(np.array([0.0, 0.0, 0.01])), p, R))
    assert np.abs(Gr_off @ N).max() > 1e-3


def test_an_update_adds_no_information_along_the_turn_only_at_a_consistent_linearisation():
    # information form: (P⁺)⁻¹ = P⁻¹ + Gᵀ R⁻¹ G, so Nᵀ P⁻¹ N is unchanged iff G N = 0
    rng = np.random.default_rng(3)
    p_c, v_c, R_c = random_state(rng)
    p, v, R = random_state(rng)
    n_c = yaw_nullspace(p_c, v_c, R_c, G)
    N = np.concatenate([yaw_nullspace(p, v, R, G), n_c[0:3], n_c[6:9]])
    A = rng.standard_normal((21, 21))
    P = A @ A.T + 0.1 * np.eye(21)
    Rn = np.diag(np.array(STD) ** 2)

    def info_gain(R_clone_lin):
        Gr = relative_pose_jacobian(R_clone_lin, *relative_motion(p_c, R_clone_lin, p, R))
        K = eskf.kalman_gain(P, Gr, Rn)
        P_post = eskf.update_covariance(P, K, Gr, Rn)
        return N @ np.linalg.solve(P_post, N) - N @ np.linalg.solve(P, N)

    before = N @ np.linalg.solve(P, N)
    assert abs(info_gain(R_c)) < 1e-8 * before
    assert info_gain(R_c @ so3.exp(np.array([0.0, 0.002, 0.0]))) > 1e-3 * before


def discretised_transition(state, f_of_t, w_of_t, duration, n):
    """Φ = ∏ (I + F_t T) of the lecture over n equal steps, and the nominal state at the end."""
    T = duration / n
    t = np.arange(n + 1) * T
    f, w = f_of_t(t), w_of_t(t)
    x = eskf.NominalState(*state)
    Phi = np.eye(15)
    for k in range(n):
        F_t = eskf.error_dynamics(x.rotation, f[k], 0.5 * (w[k] + w[k + 1]), x.accel_bias, x.gyro_bias)
        F, _ = eskf.discretise(F_t, eskf.noise_jacobian(x.rotation), T)
        Phi = F @ Phi
        x = eskf.nominal_step(x, f[k], w[k], f[k + 1], w[k + 1], T, G)
    return Phi, (x.position, x.velocity, x.rotation)


@pytest.mark.parametrize("seed", [0, 1])
def test_pose_transition_blocks_are_the_limit_of_the_discretised_transition_and_carry_the_nullspace(seed):
    # a turning, accelerating, tilted motion over one VO interval (0.1 s): the product of the
    # lecture's F = I + F_t T converges to the closed form at first order in the step
    rng = np.random.default_rng(seed)
    a = random_state(rng)
    c = rng.standard_normal((4, 3))

    def f_of_t(t):
        return np.array([1.5, -0.7, 9.9]) + np.outer(np.sin(20 * t), c[0]) + np.outer(t, c[1])

    def w_of_t(t):
        return np.array([0.05, -0.03, 0.4]) + 0.3 * np.outer(np.cos(15 * t), c[2]) + np.outer(t, c[3])

    gaps = []
    for n in (100, 1000):
        Phi, b = discretised_transition(a, f_of_t, w_of_t, 0.1, n)
        closed = pose_transition_blocks(a, b, 0.1, G)
        product = (Phi[0:3, 6:9], Phi[3:6, 6:9], Phi[6:9, 6:9])
        gaps.append([np.abs(x - y).max() / np.abs(y).max() for x, y in zip(closed, product)])
    gaps = np.array(gaps)
    assert np.all(gaps[0] < 3e-2) and np.all(gaps[1] < 3e-3)
    assert np.all(gaps[0] / gaps[1] > 5)                                 # first order: ×10 smaller per ×10 steps
    # the ½ g T² and g T terms are needed: without them the position block is far off
    wrong = -so3.hat(b[0] - a[0] - a[1] * 0.1) @ a[2]
    assert np.abs(wrong - Phi[0:3, 6:9]).max() > 10 * np.abs(closed[0] - Phi[0:3, 6:9]).max()
    # the closed form maps the turn's direction at the start exactly onto the one at the end
    Phi_c = Phi.copy()
    Phi_c[0:3, 6:9], Phi_c[3:6, 6:9], Phi_c[6:9, 6:9] = closed
    np.testing.assert_allclose(Phi_c @ yaw_nullspace(*a, G), yaw_nullspace(*b, G), atol=1e-9)


def test_pose_transition_blocks_and_yaw_nullspace_name_bad_input():
    R = np.eye(3)
    with pytest.raises(ValueError, match="start must be a tuple"):
        pose_transition_blocks((np.zeros(3), np.zeros(3)), (np.zeros(3), np.zeros(3), R), 1.0)
    with pytest.raises(ValueError, match="end rotation"):
        pose_transition_blocks((np.zeros(3), np.zeros(3), R), (np.zeros(3), np.zeros(3), 2 * R), 1.0)
    with pytest.raises(ValueError, match="T must be"):
        pose_transition_blocks((np.zeros(3), np.zeros(3), R), (np.zeros(3), np.zeros(3), R), -1.0)
    with pytest.raises(ValueError, match="velocity"):
        yaw_nullspace(np.zeros(3), np.zeros(2), R)


# ---------------------------------------------------------------------------------------
# run_relative's linearise_at
# ---------------------------------------------------------------------------------------

def synthetic_drive(seed, duration=30.0, every=10, sigma_p=0.01, sigma_theta=2e-4):
    """imu_trajectory with white VO increments every ``every`` samples and its truth."""
    sc = imu_trajectory(seed, duration=duration)
    rng = np.random.default_rng(seed)
    idx = np.arange(0, len(sc.t), every)
    track = vo.white_increments(sc.position[idx], sc.rotation[idx], sc.t[idx], (sigma_p, sigma_theta),
                                int(rng.integers(1 << 30)))
    cfg = load_config("kitti_gnss").replace(
        process__accel_noise=sc.accel_noise_density, process__gyro_noise=sc.gyro_noise_density,
        process__accel_bias_noise=sc.accel_bias_density, process__gyro_bias_noise=sc.gyro_bias_density)
    return sc, track, cfg


def test_the_default_linearisation_is_unchanged(seq00, orb):
    # the numbers of run_relative before linearise_at existed (same call, first 60 s of ORB-SLAM2)
    res = run_relative(seq00.imu, orb.initial, "kitti_gnss", seq00.gravity, vo=orb.vo, relative_std=STD,
                       start=orb.start, t_end=orb.t[0] + 60)
    assert len(res.t) == 579
    np.testing.assert_allclose(res.position[-1], [107.64233119273878, 207.36391321423795, -1.1065729285010946],
                               rtol=0, atol=1e-9)
    np.testing.assert_allclose([res.P[-1][0, 0], res.P[-1][8, 8]], [2.4632805111691813, 7.060680622084682e-05],
                               rtol=1e-9)
    np.testing.assert_allclose(res.gyro_bias[-1], [-7.070730835944776e-06, 2.824250533712842e-05,
                                                   5.980743708274529e-04], rtol=0, atol=1e-13)
    same = run_relative(seq00.imu, orb.initial, "kitti_gnss", seq00.gravity, vo=orb.vo, relative_std=STD,
                        start=orb.start, t_end=orb.t[0] + 60, linearise_at=None)
    np.testing.assert_array_equal(same.P, res.P)


def test_first_estimates_stay_closer_to_the_ideal_ekf_than_the_estimates_do():
    sc, track, cfg = synthetic_drive(7)
    x0 = NavState(sc.position[0], sc.velocity[0], sc.rotation[0])
    kw = dict(vo=track, relative_std=(0.01, 2e-4))
    runs = {name: run_relative(sc.imu, x0, cfg, sc.gravity, linearise_at=lin, **kw)
            for name, lin in (("estimates", None), ("fej", "first_estimates"), ("truth", sc))}
    k = np.searchsorted(sc.t, runs["truth"].t - 1e-9)
    var = {name: vo.yaw_variance(r.rotation, r.P) for name, r in runs.items()}
    err = {name: vo.yaw_error(r.rotation, sc.rotation[k]) for name, r in runs.items()}
    # FEJ differs from the ideal EKF only by where the first estimates sit (cm, mrad)
    np.testing.assert_allclose(var["fej"], var["truth"], rtol=5e-3)
    np.testing.assert_allclose(err["fej"], err["truth"], atol=2e-4)
    # and it is closer to it than the default, in heading and in position
    for name in ("estimates", "fej"):
        assert not np.array_equal(runs[name].P, runs["truth"].P)
    assert np.abs(err["fej"] - err["truth"]).max() < 0.5 * np.abs(err["estimates"] - err["truth"]).max()
    gap = {name: np.abs(runs[name].position - runs["truth"].position).max() for name in ("estimates", "fej")}
    assert gap["fej"] < 0.5 * gap["estimates"]
    # every linearisation still follows the truth on a clean drive
    for r in runs.values():
        assert np.abs(r.position - sc.position[k]).max() < 1.0


def test_first_estimates_run_with_gnss_and_bad_linearisation_is_named():
    sc, track, cfg = synthetic_drive(2, duration=5.0)
    x0 = NavState(sc.position[0], sc.velocity[0], sc.rotation[0])
    g = np.arange(55, len(sc.t), 100)
    from kalman_course.core.observations import PositionObservations
    gnss = PositionObservations(sc.t[g], sc.position[g])
    res = run_relative(sc.imu, x0, cfg, sc.gravity, vo=track, relative_std=(0.01, 2e-4), gnss=gnss,
                       linearise_at="first_estimates")
    assert len(res.gnss_innovation) == len(g)
    with pytest.raises(ValueError, match="linearise_at must be None, 'first_estimates'"):
        run_relative(sc.imu, x0, cfg, sc.gravity, vo=track, relative_std=(0.01, 2e-4), linearise_at="fej")
    with pytest.raises(ValueError, match="linearise_at must be None"):
        run_relative(sc.imu, x0, cfg, sc.gravity, vo=track, relative_std=(0.01, 2e-4), linearise_at=3.0)
    # the truth must hold every event's time (here the truth has only the VO frames)
    frames = SimpleNamespace(t=track.t, position=track.position, velocity=np.zeros_like(track.position),
                             rotation=track.rotation)
    with pytest.raises(ValueError, match="linearise_at has no state"):
        run_relative(sc.imu, x0, cfg, sc.gravity, vo=track, relative_std=(0.01, 2e-4), gnss=gnss,
                     linearise_at=frames)


# ---------------------------------------------------------------------------------------
# the pieces of the experiments
# ---------------------------------------------------------------------------------------

def test_white_increments_have_the_given_unequal_sigma_and_start_at_the_truth():
    sc = imu_trajectory(3, duration=60.0)
    idx = np.arange(0, len(sc.t), 2)
    track = vo.white_increments(sc.position[idx], sc.rotation[idx], sc.t[idx], STD, 11)
    np.testing.assert_allclose(track.position[0], sc.position[0])
    dp_t, dR_t = zip(*(relative_motion(sc.position[a], sc.rotation[a], sc.position[b], sc.rotation[b])
                       for a, b in zip(idx[:-1], idx[1:])))
    dp_m, dR_m = zip(*(relative_motion(track.position[k], track.rotation[k], track.position[k + 1],
                                       track.rotation[k + 1]) for k in range(len(idx) - 1)))
    e = np.hstack([np.array(dp_m) - np.array(dp_t),
                   so3.log(np.swapaxes(np.array(dR_t), 1, 2) @ np.array(dR_m))])
    n = len(e)
    np.testing.assert_allclose(e.std(axis=0), STD, rtol=4 / np.sqrt(2 * n))
    assert np.all(np.abs(e.mean(axis=0)) < 4 * np.array(STD) / np.sqrt(n))
    assert abs(np.corrcoef(e[:-1, 5], e[1:, 5])[0, 1]) < 4 / np.sqrt(n)      # white
    with pytest.raises(ValueError, match="std must be"):
        vo.white_increments(sc.position[idx], sc.rotation[idx], sc.t[idx], (0.01, 0.0), 1)


def test_simulated_imu_follows_the_configuration_model():
    # a fake reference of 20 000 samples at an irregular ~100 Hz
    rng = np.random.default_rng(0)
    t = np.cumsum(0.01 + 0.001 * rng.random(20000))
    ref = SimpleNamespace(t=t, specific_force=np.tile([0.2, -0.1, 9.81], (len(t), 1)),
                          angular_rate=np.tile([0.0, 0.01, -0.2], (len(t), 1)))
    cfg = load_config("kitti_gnss")
    sig_a, sig_w, q_a, q_w = cfg.process_density
    imu = vo.simulated_imu(ref, cfg, seed=4)
    assert not imu.interpolated.any()
    dt_nom = np.median(np.diff(t))
    for meas, clean, bias, sig, q in ((imu.specific_force, ref.specific_force, imu.accel_bias, sig_a, q_a),
                                      (imu.angular_rate, ref.angular_rate, imu.gyro_bias, sig_w, q_w)):
        noise = meas - clean - bias
        n = noise.size
        assert abs(noise.std() / (sig / np.sqrt(dt_nom)) - 1) < 4 / np.sqrt(2 * n)
        steps = np.diff(bias, axis=0) / np.sqrt(np.diff(t))[:, None]
        assert abs(steps.std() / q - 1) < 4 / np.sqrt(2 * steps.size)
    # the turn-on biases over seeds: their spread is the prior's
    b0 = np.array([vo.simulated_imu(SimpleNamespace(t=t[:3], specific_force=ref.specific_force[:3],
                                                    angular_rate=ref.angular_rate[:3]), cfg, seed=s).gyro_bias[0]
                   for s in range(400)])
    assert abs(b0.std() / cfg.prior_std[12] - 1) < 4 / np.sqrt(2 * b0.size)
    with pytest.raises(ValueError, match="random-walk bias model"):
        vo.simulated_imu(ref, cfg.replace(bias_model="constant"))
    with pytest.raises(ValueError, match="reference must be a ReferenceImu"):
        vo.simulated_imu(SimpleNamespace(t=t))


def test_yaw_error_is_the_turn_about_the_vertical_even_when_tilted():
    R_true = so3.exp(np.array([[0.5, -0.3, 2.9], [-0.2, 0.6, -3.1], [0.0, 0.0, 1e-3]]))   # tilted, near ±π, near 0
    phi = 0.01
    turned = so3.exp(np.array([0.0, 0.0, phi])) @ R_true                 # a turn about the navigation z
    np.testing.assert_allclose(vo.yaw_error(turned, R_true), phi, rtol=1e-12)
    tipped = so3.exp(np.array([phi, -phi, 0.0])) @ R_true                # about a horizontal axis
    np.testing.assert_allclose(vo.yaw_error(tipped, R_true), 0.0, atol=1e-12)
    with pytest.raises(ValueError, match="rotation and true_rotation"):
        vo.yaw_error(R_true, R_true[:2])


def test_yaw_variance_against_samples_of_a_correlated_attitude_error():
    rng = np.random.default_rng(1)
    R = so3.exp(np.array([[0.4, -0.2, 2.0]]))
    A = rng.standard_normal((15, 15))
    P = (A @ A.T)[None] * 1e-4
    dtheta = rng.multivariate_normal(np.zeros(3), P[0, 6:9, 6:9], size=200000)
    sampled = np.var((R[0] @ dtheta.T)[2])
    np.testing.assert_allclose(vo.yaw_variance(R, P), sampled, rtol=0.02)
    with pytest.raises(ValueError, match="P"):
        vo.yaw_variance(R, P[:, :9, :9])


def fake_result(t, position, rotation, P):
    r = SimpleNamespace(t=t, position=position, rotation=rotation, P=P)
    r.at = lambda times: r
    return r


def test_consistency_score_splits_the_nees_by_block():
    K = 300
    t = np.arange(K) * 0.1
    truth = SimpleNamespace(t=t, position=np.column_stack([np.linspace(0, 600, K), np.zeros(K), np.zeros(K)]),
                            rotation=np.repeat(np.eye(3)[None], K, axis=0))
    e_p, e_th = np.array([0.3, -0.4, 0.0]), np.array([0.0, 0.0, 0.002])
    P = np.repeat(np.diag([0.25] * 6 + [1e-6] * 9)[None], K, axis=0)
    P[:, 6:9, 6:9] = np.diag([1e-6, 1e-6, 4e-6])
    res = fake_result(t, truth.position + e_p, truth.rotation @ so3.exp(e_th), P)
    c = vo.consistency_score(res, truth, t)
    np.testing.assert_allclose(c.nees_position, 0.25 / 0.25, rtol=1e-9)
    np.testing.assert_allclose(c.nees_attitude, 0.002 ** 2 / 4e-6, rtol=1e-6)
    np.testing.assert_allclose(c.nees_yaw, 1.0, rtol=1e-6)
    np.testing.assert_allclose(c.nees, 2.0, rtol=1e-6)
    np.testing.assert_allclose(c.ate, 0.5, rtol=1e-9)
    np.testing.assert_allclose([c.yaw_error_end_deg, c.yaw_sigma_end_deg], np.rad2deg([0.002, 0.002]), rtol=1e-6)


def test_yaw_change_at_dropouts_sums_each_side():
    t = np.arange(100) * 0.1
    truth = SimpleNamespace(t=t, position=np.zeros((100, 3)), rotation=np.repeat(np.eye(3)[None], 100, axis=0))
    yaw = np.zeros(100)
    yaw[40:] += 0.01        # a step at frame 40 (τ 4.0 s), inside the dropout's settling second
    yaw[80:] -= 0.003       # one at 8.0 s, far from it
    res = fake_result(t, truth.position, so3.exp(np.column_stack([np.zeros((100, 2)), yaw])), None)
    t_imu = np.arange(0, 10, 0.01)
    imu = SimpleNamespace(t=t_imu, interpolated=(t_imu > 3.0) & (t_imu < 3.5))
    at, elsewhere = vo.yaw_change_at_dropouts(res, truth, t, imu)
    np.testing.assert_allclose([at, elsewhere], np.rad2deg([0.01, -0.003]), atol=1e-12)
    at0, _ = vo.yaw_change_at_dropouts(res, truth, t, imu, settle_s=0.0)
    assert at0 == 0.0


def test_gyro_increments_of_a_constant_rate_and_rotation_increments():
    t = np.arange(0, 5, 0.01)
    w = np.array([0.02, -0.05, 0.3])
    imu = SimpleNamespace(t=t, specific_force=np.zeros((len(t), 3)), angular_rate=np.tile(w, (len(t), 1)),
                          interpolated=np.zeros(len(t), dtype=bool))
    frames = np.array([0.013, 0.117, 0.22, 1.5, 3.333])
    d, dropout = vo.gyro_increments(imu, frames)
    np.testing.assert_allclose(d, np.outer(np.diff(frames), w), atol=1e-12)
    assert not dropout.any()
    R = so3.exp(np.outer(frames, w))
    np.testing.assert_allclose(vo.rotation_increments(R), d, atol=1e-12)
    imu.interpolated[150] = True                     # τ 1.5 s: the frame there is an end of interval 3
    assert vo.gyro_increments(imu, frames)[1].tolist() == [False, False, True, True]
    with pytest.raises(ValueError, match="inside the IMU record"):
        vo.gyro_increments(imu, np.array([0.0, 6.0]))


def test_tilt_misalignment_recovers_a_known_axis_offset_from_turns():
    rng = np.random.default_rng(2)
    M = 3000
    turns = np.column_stack([0.002 * rng.standard_normal((M, 2)), 0.03 * rng.standard_normal(M)])
    phi = np.array([0.0017, 0.0054, 0.0])           # 0.1° and 0.31°
    C_T = so3.exp(phi)                               # Exp(φ) = Cᵀ: R_vo = R_imu C
    d_vo = turns @ C_T.T                             # Cᵀ Δθ (exact conjugation of the rotation)
    offset = np.array([1e-5, -2e-5, 3e-5])
    d_gyro = turns + offset + 1e-5 * rng.standard_normal((M, 3))
    est, c = vo.tilt_misalignment(d_vo, d_gyro)
    np.testing.assert_allclose(est, phi, atol=5e-5)
    np.testing.assert_allclose(c, offset, atol=2e-6)
    # turning the VO attitudes by Exp(φ) gives back the IMU's
    R_imu = so3.exp(np.array([0.1, -0.2, 1.4]))
    np.testing.assert_allclose((R_imu @ C_T.T) @ so3.exp(est), R_imu, atol=1e-4)
    with pytest.raises(ValueError, match="dtheta_vo and dtheta_gyro"):
        vo.tilt_misalignment(d_vo[:, :2], d_gyro)


# ---------------------------------------------------------------------------------------
# the experiments on KITTI sequence 00 (real IMU and VO), cut short
# ---------------------------------------------------------------------------------------

def test_linearisation_runs_on_the_real_imu(orb):
    runs = vo.linearisation_runs(orb, STD, seeds=(1,), t_end=orb.t[0] + 60)
    assert [r.linearisation for r in runs] == list(vo.LINEARISATIONS) and all(r.imu == "real" for r in runs)
    sc = {r.linearisation: r.score for r in runs}
    # the real-IMU tracks are those of white_increment_track
    assert np.isclose(sc["first_estimates"].nees, sc["truth"].nees, rtol=0.02)
    assert sc["estimates"].yaw_sigma_end_deg < sc["first_estimates"].yaw_sigma_end_deg
    assert all(np.isfinite([s.nees, s.nees_position, s.nees_attitude, s.nees_yaw, s.ate]).all() for s in sc.values())
    # the heading error splits into what arose at the dropouts and elsewhere, adding up to the change over the run
    for r in runs:
        assert r.yaw_change is not None
        np.testing.assert_allclose(sum(r.yaw_change), r.score.yaw_error_end_deg, atol=0.05)
    table = vo.linearisation_table(runs)
    assert "real IMU" in table and table.count("\n| real IMU") == 3
    with pytest.raises(ValueError, match="imu must be one of"):
        vo.linearisation_runs(orb, STD, imu="ideal")
    with pytest.raises(ValueError, match="linearisation must be one of"):
        vo.linearisation_runs(orb, STD, linearisations=("fej",))
    with pytest.raises(ValueError, match="t_end"):
        vo.linearisation_runs(orb, STD, t_end=orb.t[0])


def test_linearisation_runs_on_the_simulated_imu_are_consistent(orb):
    runs = vo.linearisation_runs(orb, STD, seeds=(1, 2), linearisations=("estimates", "first_estimates"),
                                 imu="simulated", t_end=orb.t[0] + 60)
    assert len(runs) == 4 and all(r.imu == "simulated" and r.yaw_change is None for r in runs)
    assert vo.linearisation_table(runs).count("| — |") == 2          # no dropouts to split at
    # a filter whose every model is right: a mean NEES below the 6 of a consistent filter (it starts at
    # the truth with a non-zero prior, so it may be below, never far above)
    assert all(r.score.nees < 6.0 for r in runs)


def test_the_clock_offset_that_fits_best_is_zero(orb):
    runs = vo.clock_offset_runs(orb, STD, offsets=(-0.03, 0.0, 0.03), t_end=orb.t[0] + 90)
    nees = [r.score.nees for r in runs]
    assert nees[1] == min(nees)
    with pytest.raises(ValueError, match="linearisation must be"):
        vo.clock_offset_runs(orb, STD, linearisation="truth")


def test_the_gyro_finds_the_sptam_track_one_frame_late_and_orb_on_time(orb, sptam):
    # no truth: the VO's rotation increments against the gyro's at each lag
    lag_orb, lag_sptam = vo.frame_lag(orb, t_cal=30.0), vo.frame_lag(sptam, t_cal=30.0)
    assert min(lag_orb, key=lag_orb.get) == 0 and min(lag_sptam, key=lag_sptam.get) == 1
    assert lag_sptam[1] < 0.5 * lag_sptam[0]
    fixed = vo.realigned(sptam, lag=1)
    lag_fixed = vo.frame_lag(fixed, t_cal=30.0)
    assert min(lag_fixed, key=lag_fixed.get) == 0
    np.testing.assert_allclose(lag_fixed[0], lag_sptam[1], rtol=0.05)
    with pytest.raises(ValueError, match="lag must be"):
        vo.realigned(sptam, lag=-1)


def test_both_vo_tracks_are_tilted_the_same_way_against_the_imu(orb, sptam):
    tilt_orb = np.rad2deg(vo.vo_tilt(orb))
    tilt_sptam = np.rad2deg(vo.vo_tilt(vo.realigned(sptam, lag=1)))
    assert tilt_orb[2] == 0.0
    for tilt in (tilt_orb, tilt_sptam):
        assert 0.2 < tilt[1] < 0.45 and abs(tilt[0]) < 0.2
    # realigning by the tilt turns every VO attitude by Exp(φ) (before the one-pose anchoring)
    phi = vo.vo_tilt(orb)
    turned = vo.realigned(orb, tilt=phi)
    a = np.swapaxes(orb.vo.rotation[:-1], 1, 2) @ orb.vo.rotation[1:]
    b = np.swapaxes(turned.vo.rotation[:-1], 1, 2) @ turned.vo.rotation[1:]
    E = so3.exp(phi)
    np.testing.assert_allclose(b[:50], E.T @ a[:50] @ E, atol=1e-9)
    with pytest.raises(ValueError, match="t_cal"):
        vo.vo_tilt(orb, t_cal=0.5)


def test_vio_variants_score_every_variant_against_vo_alone(orb):
    variants = (vo.VioVariant("as in the table"), vo.VioVariant("FEJ + prior", "first_estimates", 5e-5, 2.91e-7))
    rows = vo.vio_variants(orb, STD, variants, t_end=orb.t[0] + 60)
    assert [r.name for r in rows] == ["VO alone", "as in the table", "FEJ + prior"]
    assert rows[0].consistency is None and rows[1].consistency is not None
    n = len(rows[0].score.position_error)
    cut = vo.VoSetup(orb.excerpt, orb.system, orb.first, orb.first + n - 1, orb.start, orb.initial,
                     PoseObservations(orb.vo.t[:n], orb.vo.position[:n], orb.vo.rotation[:n]), orb.t[n - 1],
                     orb.t_stop)
    alone = vo.score(cut, cut.t, cut.vo.position, cut.vo.rotation)
    assert rows[0].score.ate == alone.ate
    cfg = variants[1].config()
    assert np.all(cfg.prior_std[12:15] == 5e-5) and cfg.process_density[3] == 2.91e-7
    table = vo.vio_table(rows, "ORB-SLAM2, first 60 s")
    assert table.startswith("ORB-SLAM2, first 60 s") and "(reference)" in table
    with pytest.raises(ValueError, match="variants must be"):
        vo.vio_variants(orb, STD, ())
    with pytest.raises(ValueError, match="rows must be"):
        vo.vio_table(rows[1:])
