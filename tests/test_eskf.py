"""The error-state Kalman filter: F against finite differences, noise, reset, runs on KITTI."""

from __future__ import annotations

import types
import warnings

import numpy as np
import pytest

from kalman_course.filters import eskf
from kalman_course.core import so3
from kalman_course.core.observations import PositionObservations
from kalman_course.evaluation.pose import evaluate
from kalman_course.data import imu_trajectory, load_kitti
from kalman_course.filters.eskf import NominalState
from kalman_course.filters.eskf_config import load_config
from kalman_course.evaluation.trajectory import ate_rmse

G = np.array([0.0, 0.0, -9.8092])


# ---------------------------------------------------------------------------------------
# F_t proven by finite differences of one nominal step
# ---------------------------------------------------------------------------------------

def _error(nom: NominalState, true: NominalState) -> np.ndarray:
    """δx = nominal − true in the course's convention (Ř = R Exp(δθ))."""
    return np.concatenate([nom.position - true.position, nom.velocity - true.velocity,
                           so3.log(true.rotation.T @ nom.rotation),
                           nom.accel_bias - true.accel_bias, nom.gyro_bias - true.gyro_bias])


def _fd_transition(nom: NominalState, f, w, T: float, h: float = 1e-6) -> np.ndarray:
    """∂δx_{k+1}/∂δx_k: inject ±h into each error component, step nominal and true alike."""
    nom1 = eskf.nominal_step(nom, f, w, f, w, T, G)
    J = np.zeros((15, 15))
    for i in range(15):
        d = np.zeros(15)
        d[i] = h
        up = _error(nom1, eskf.nominal_step(eskf.inject(nom, d), f, w, f, w, T, G))
        down = _error(nom1, eskf.nominal_step(eskf.inject(nom, -d), f, w, f, w, T, G))
        J[:, i] = (up - down) / (2 * h)
    return J


def _random_case(rng):
    R = so3.exp(rng.normal(size=3) * 0.8)                      # tilted by tens of degrees
    nom = NominalState(rng.normal(size=3) * 10, rng.normal(size=3) * 5, R,
                       rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.01)  # non-zero biases
    f = R.T @ np.array([0.0, 0.0, 9.81]) + rng.normal(size=3) * 2.0
    w = rng.normal(size=3) * 0.5
    return nom, f, w


def _filter_F(nom, f, w, T):
    F_t = eskf.error_dynamics(nom.rotation, f, w, nom.accel_bias, nom.gyro_bias)
    F, _ = eskf.discretise(F_t, eskf.noise_jacobian(nom.rotation), T)
    return F_t, F


def _tolerance(F_t, T):
    # F = I + F_t T is exact to first order; the next term of the true transition is
    # ½ F_t² T² (plus what the midpoint rule adds, of the same order). Allow twice it,
    # plus the finite-difference round-off.
    return 2.0 * 0.5 * np.abs(F_t @ F_t).max() * T * T + 1e-7


@pytest.mark.parametrize("seed", range(4))
@pytest.mark.parametrize("T", [1e-3, 1e-2])
def test_discrete_F_equals_finite_difference_to_first_order(seed, T):
    nom, f, w = _random_case(np.random.default_rng(seed))
    F_t, F = _filter_F(nom, f, w, T)
    J = _fd_transition(nom, f, w, T)
    assert np.abs(J - F).max() <= _tolerance(F_t, T)


def test_residual_is_second_order_in_T():
    nom, f, w = _random_case(np.random.default_rng(7))
    errs = [np.abs(_fd_transition(nom, f, w, T) - _filter_F(nom, f, w, T)[1]).max() for T in (1e-2, 5e-3)]
    assert 3.5 < errs[0] / errs[1] < 4.5          # halving T quarters the mismatch


def _wrong_variants(nom, f, w, T):
    F_t, F = _filter_F(nom, f, w, T)
    a = f - nom.accel_bias
    wb = w - nom.gyro_bias
    R = nom.rotation
    out = {}
    bad = F.copy(); bad[3:6, 6:9] = -so3.hat(R @ a) * T; out["nav-frame specific force"] = bad
    bad = F.copy(); bad[3:6, 6:9] = +R @ so3.hat(a) * T; out["sign of the v-theta block"] = bad
    bad = F.copy(); bad[3:6, 6:9] = -R @ so3.hat(f) * T; out["uncorrected specific force"] = bad
    bad = F.copy(); bad[6:9, 6:9] = np.eye(3) + so3.hat(wb) * T; out["sign of the theta-theta block"] = bad
    bad = F.copy(); bad[6:9, 12:15] = +np.eye(3) * T; out["sign of the gyro-bias block"] = bad
    bad = F.copy(); bad[3:6, 9:12] = -np.eye(3) * T; out["accel bias not rotated"] = bad
    bad = F.copy(); bad[0:3, 3:6] = 0.0; out["missing p-v block"] = bad
    return F_t, out


@pytest.mark.parametrize("seed", range(3))
def test_deliberately_wrong_F_fails_the_same_test(seed):
    T = 1e-3
    nom, f, w = _random_case(np.random.default_rng(seed))
    J = _fd_transition(nom, f, w, T)
    F_t, variants = _wrong_variants(nom, f, w, T)
    tol = _tolerance(F_t, T)
    for name, bad in variants.items():
        assert np.abs(J - bad).max() > 5 * tol, name


# ---------------------------------------------------------------------------------------
# Noise, residual, injection, reset
# ---------------------------------------------------------------------------------------

def test_process_noise_blocks_scale_with_T():
    rng = np.random.default_rng(0)
    R = so3.exp(rng.normal(size=3))
    dens = np.array([0.03, 1e-3, 1.67e-4, 2.91e-6])
    for T in (0.01, 0.004):
        F, B = eskf.discretise(np.zeros((15, 15)), eskf.noise_jacobian(R), T)
        Qd = B @ eskf.process_noise(dens, T) @ B.T
        np.testing.assert_allclose(Qd[3:6, 3:6], dens[0] ** 2 * T * np.eye(3), rtol=1e-12, atol=1e-20)
        np.testing.assert_allclose(Qd[6:9, 6:9], dens[1] ** 2 * T * np.eye(3), rtol=1e-12)
        np.testing.assert_allclose(Qd[9:12, 9:12], dens[2] ** 2 * T * np.eye(3), rtol=1e-12)
        np.testing.assert_allclose(Qd[12:15, 12:15], dens[3] ** 2 * T * np.eye(3), rtol=1e-12)
        assert np.all(Qd[0:3] == 0.0)
        np.testing.assert_allclose(B[9:12, 6:9], np.sqrt(T) * np.eye(3))
        np.testing.assert_allclose(B[3:6, 0:3], R * T)
    Bc = eskf.noise_jacobian(R, "constant")
    assert Bc.shape == (15, 6)
    _, Bd = eskf.discretise(np.zeros((15, 15)), Bc, 0.01)
    Qc = Bd @ eskf.process_noise(dens, 0.01, "constant") @ Bd.T
    assert np.all(Qc[9:, 9:] == 0.0)


def test_pose_residual_is_nominal_minus_measurement_to_first_order():
    rng = np.random.default_rng(3)
    Rm, pm = so3.exp(rng.normal(size=3)), rng.normal(size=3)
    dp, dth = np.array([0.1, -0.2, 0.3]), np.array([1e-3, -2e-3, 5e-4])
    y = eskf.pose_residual(pm + dp, Rm @ so3.exp(dth), pm, Rm)
    np.testing.assert_allclose(y, np.concatenate([dp, dth]), atol=1e-12)
    np.testing.assert_allclose(eskf.POSE_G @ np.concatenate([dp, np.zeros(3), dth, np.zeros(6)]), y, atol=1e-12)


def test_injection_removes_the_error_with_the_right_signs():
    rng = np.random.default_rng(4)
    true = NominalState(rng.normal(size=3), rng.normal(size=3), so3.exp(rng.normal(size=3)),
                        rng.normal(size=3) * 0.1, rng.normal(size=3) * 0.01)
    dx = rng.normal(size=15) * 0.01
    # nominal = true ⊕ δx  (p̌ = p + δp, Ř = R Exp(δθ), b̌ = b + δb)
    nom = NominalState(true.position + dx[0:3], true.velocity + dx[3:6], true.rotation @ so3.exp(dx[6:9]),
                       true.accel_bias + dx[9:12], true.gyro_bias + dx[12:15])
    fixed = eskf.inject(nom, dx)
    np.testing.assert_allclose(_error(fixed, true), 0.0, atol=1e-14)
    assert so3.is_rotation(fixed.rotation, tol=1e-12)


def test_reset_jacobian_matches_finite_differences_of_the_reset():
    rng = np.random.default_rng(5)
    dth_hat = rng.normal(size=3) * 0.05
    h = 1e-7
    J = np.zeros((3, 3))
    for i in range(3):
        e = np.zeros(3)
        e[i] = h
        plus = so3.log(so3.exp(dth_hat + e) @ so3.exp(-dth_hat))
        minus = so3.log(so3.exp(dth_hat - e) @ so3.exp(-dth_hat))
        J[:, i] = (plus - minus) / (2 * h)
    G = eskf.reset_jacobian(np.concatenate([np.zeros(6), dth_hat, np.zeros(6)]))
    np.testing.assert_allclose(G[6:9, 6:9], J, atol=1e-7)
    np.testing.assert_allclose(G[6:9, 6:9], np.eye(3) + 0.5 * so3.hat(dth_hat), atol=2e-3)
    # the other sign convention's Jacobian (I − ½[δθ̂]×) is wrong here
    assert np.abs(np.eye(3) - 0.5 * so3.hat(dth_hat) - J).max() > 0.02
    np.testing.assert_array_equal(np.delete(np.delete(G, np.s_[6:9], 0), np.s_[6:9], 1), np.eye(12))


def test_reset_covariance_is_G_P_Gt_with_the_reset_jacobian():
    rng = np.random.default_rng(6)
    A = rng.normal(size=(15, 15)) * 0.1
    P = eskf.update_covariance(A @ A.T + 1e-4 * np.eye(15), np.zeros((15, 6)), eskf.POSE_G, np.eye(6))
    dx = rng.normal(size=15) * 0.05
    G = eskf.reset_jacobian(dx)
    np.testing.assert_allclose(eskf.reset_covariance(P, dx), G @ P @ G.T, rtol=1e-13, atol=1e-17)
    assert np.array_equal(eskf.reset_covariance(P, dx, exact=False), P)


def test_joseph_update_keeps_P_symmetric_and_shrinks_it():
    P = np.diag(np.arange(1.0, 16.0)) * 0.01
    K = eskf.kalman_gain(P, eskf.POSE_G, np.eye(6) * 0.04)
    P1 = eskf.update_covariance(P, K, eskf.POSE_G, np.eye(6) * 0.04)
    assert np.array_equal(P1, P1.T)
    assert np.all(np.linalg.eigvalsh(P1) > 0)
    assert np.all(np.diag(P1) <= np.diag(P) + 1e-15)


# ---------------------------------------------------------------------------------------
# The batch runner equals the step-by-step filter
# ---------------------------------------------------------------------------------------

def _stepwise(imu, s0, config, gravity, k0, t_end, lidar=None, gnss=None, gap_factor=3.0):
    """The step-by-step ESKF over the timeline ``run`` documents: every IMU sample and every
    observation time, readings interpolated at observation times between samples, the
    inflated noise on steps touching an interpolated sample or bridging a gap in imu.t.

    Returns {time: (position, rotation, P)} after the last update at each observation time.
    """
    t, f_all, w_all = imu.t, imu.specific_force, imu.angular_rate
    last = int(np.searchsorted(t, t_end, side="right")) - 1
    gap = np.diff(t[k0:last + 1]) > gap_factor * np.median(np.diff(t[k0:last + 1]))
    events = []
    for kind, obs in enumerate((lidar, gnss)):
        if obs is not None:
            events += [(tj, kind, j) for j, tj in enumerate(obs.t) if t[k0] < tj <= t[last]]
    events.sort()
    flt = eskf.ESKF(config, s0, gravity)
    out = {}
    t_prev, f_prev, w_prev = t[k0], f_all[k0], w_all[k0]
    e = 0
    for k in range(k0 + 1, last + 1):
        inflated = bool(imu.interpolated[k - 1] or imu.interpolated[k] or gap[k - 1 - k0])
        while e < len(events) and events[e][0] <= t[k]:
            tj, kind, j = events[e]
            e += 1
            if tj > t_prev:
                s = (tj - t[k - 1]) / (t[k] - t[k - 1])
                fj = (1 - s) * f_all[k - 1] + s * f_all[k]
                wj = (1 - s) * w_all[k - 1] + s * w_all[k]
                flt.predict(f_prev, w_prev, fj, wj, tj - t_prev, interpolated=inflated)
                t_prev, f_prev, w_prev = tj, fj, wj
            if kind == 0:
                flt.update_pose(lidar.position[j], lidar.rotation[j])
            else:
                flt.update_position(gnss.position[j])
            out[tj] = (flt.nominal.position.copy(), flt.nominal.rotation.copy(), flt.P.copy())
        if t[k] > t_prev:
            flt.predict(f_prev, w_prev, f_all[k], w_all[k], t[k] - t_prev, interpolated=inflated)
            t_prev, f_prev, w_prev = t[k], f_all[k], w_all[k]
    return out


def _without_samples(imu, t_from, t_to):
    """The IMU record with every sample strictly inside (t_from, t_to) removed: a gap."""
    keep = (imu.t <= t_from) | (imu.t >= t_to)
    return types.SimpleNamespace(t=imu.t[keep], specific_force=imu.specific_force[keep],
                                 angular_rate=imu.angular_rate[keep], interpolated=imu.interpolated[keep])


@pytest.mark.parametrize("sensors", ["lidar", "gnss", "lidar+gnss", "lidar+imu gap"])
@pytest.mark.parametrize("bias_model", ["random_walk", "constant"])
@pytest.mark.parametrize("exact_reset", [True, False], ids=["exact reset", "lecture reset"])
def test_batch_runner_equals_stepwise_filter(sensors, bias_model, exact_reset):
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    t_end = ex.imu.t[k0] + 4.0
    imu = ex.imu
    if "imu gap" in sensors:
        imu = _without_samples(imu, imu.t[k0] + 1.5, imu.t[k0] + 2.0)
        k0 = int(np.searchsorted(imu.t, ex.imu.t[k0]))
    lidar = ex.lidar if "lidar" in sensors else None
    gnss = PositionObservations(ex.gnss.t, ex.gnss.position_noisy) if "gnss" in sensors else None
    cfg = load_config("kitti_gnss" if sensors == "gnss" else "kitti_lidar").replace(
        bias_model=bias_model, exact_reset=exact_reset)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = eskf.run(imu, s0, cfg, ex.gravity, lidar=lidar, gnss=gnss, start=k0, t_end=t_end)
    assert [w.category for w in caught] == ([eskf.ImuGapWarning] if "imu gap" in sensors else [])
    ref = _stepwise(imu, s0, cfg, ex.gravity, k0, t_end, lidar, gnss)
    assert res.updated.all() and len(res.t) == len(ref) >= (4 if sensors == "gnss" else 35)
    if lidar is not None:   # the lidar times really do fall between IMU samples
        assert np.min(np.abs(imu.t[:, None] - res.t[None, :]), axis=0).max() > 1e-3
    for i, (t, (p, R, P)) in enumerate(sorted(ref.items())):
        assert res.t[i] == pytest.approx(t, abs=1e-12)
        np.testing.assert_allclose(res.position[i], p, atol=1e-9)
        np.testing.assert_allclose(res.rotation[i], R, atol=1e-11)
        np.testing.assert_allclose(res.P[i], P, rtol=1e-7, atol=1e-14)


# ---------------------------------------------------------------------------------------
# A gap in the IMU stream is bridged with the inflated noise, and reported
# ---------------------------------------------------------------------------------------

def _pose_errors(ex, res):
    """Attitude error angle (deg) and 6-dof pose NEES of every row of ``res``."""
    truth = ex.truth.interpolate(res.t)
    e_p = res.position - truth.position
    e_th = so3.log(np.swapaxes(truth.rotation, 1, 2) @ res.rotation)
    e6 = np.concatenate([e_p, e_th], axis=1)
    pose = [0, 1, 2, 6, 7, 8]
    P6 = res.P[:, pose][:, :, pose]
    nees = np.einsum("ki,ki->k", e6, np.linalg.solve(P6, e6[..., None])[..., 0])
    return np.rad2deg(np.linalg.norm(e_th, axis=1)), nees


def _turn_with_a_gap(seconds=2.0):
    """The turns excerpt with ``seconds`` of IMU removed where the car turns most, and t_end."""
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    t, wz = ex.imu.t, ex.imu.angular_rate[:, 2]
    yaw = np.concatenate([[0.0], np.cumsum(np.abs(0.5 * (wz[1:] + wz[:-1])) * np.diff(t))])
    starts = np.arange(k0 + 500, np.searchsorted(t, t[-1] - seconds - 6.0))     # after 5 s of filtering
    ends = np.searchsorted(t, t[starts] + seconds)
    a = starts[np.argmax(yaw[ends] - yaw[starts])]
    t_from, t_to = t[a], t[a] + seconds
    assert np.rad2deg(yaw[np.searchsorted(t, t_to)] - yaw[a]) > 45.0        # it is a turn
    imu = _without_samples(ex.imu, t_from, t_to)
    return ex, imu, int(np.searchsorted(imu.t, t[k0])), s0, t_to + 5.0


def test_a_gap_in_the_imu_stream_is_bridged_with_inflated_noise_and_reported():
    ex, imu, k0, s0, t_end = _turn_with_a_gap()
    with pytest.warns(eskf.ImuGapWarning, match=r"1 gap\(s\) .* the longest 2.01 s"):
        bridged = eskf.run(imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=t_end)
    angle, nees = _pose_errors(ex, bridged)
    assert angle.max() < 1.5
    assert nees.max() < 60.0 and nees.mean() < 12.0
    # the same run with the ordinary process noise across the gap: what the detection prevents
    blind = eskf.run(imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=t_end,
                     gap_factor=None)
    angle, nees = _pose_errors(ex, blind)
    assert angle.max() > 10.0 and nees.max() > 1000.0


def test_a_stream_without_gaps_gives_no_warning():
    ex = load_kitti("turns")            # its longest step is 1.7 × the median: jitter, not a gap
    k0, s0 = ex.initial_state()
    with warnings.catch_warnings():
        warnings.simplefilter("error", eskf.ImuGapWarning)
        eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, t_end=ex.imu.t[k0] + 5.0)
    assert np.diff(ex.imu.t).max() > 1.5 * np.median(np.diff(ex.imu.t))


def test_covariances_stay_symmetric_positive_definite():
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    res = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0)
    assert np.array_equal(res.P, np.swapaxes(res.P, 1, 2))
    assert np.linalg.eigvalsh(res.P).min() > 0.0
    assert so3.is_rotation(res.rotation, tol=1e-9)


# ---------------------------------------------------------------------------------------
# Biases: the signs of the injection are right if the filter finds the true bias
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("bias_model", ["random_walk", "constant"])
def test_filter_recovers_imu_biases_on_synthetic_motion(bias_model):
    b_a, b_w = np.array([0.08, -0.05, 0.06]), np.array([0.004, -0.003, 0.002])
    sc = imu_trajectory(11, duration=40.0, accel_bias0=b_a, gyro_bias0=b_w,
                        accel_bias_density=0.0, gyro_bias_density=0.0)
    obs = slice(None, None, 10)
    lidar = types.SimpleNamespace(t=sc.t[obs], position=sc.position[obs], rotation=sc.rotation[obs])
    initial = NominalState(sc.position[0], sc.velocity[0], sc.rotation[0])
    cfg = load_config("kitti_lidar").replace(bias_model=bias_model, prior__accel_bias=0.2,
                                             prior__gyro_bias=0.01, observation__lidar_position=0.01,
                                             observation__lidar_attitude=1e-3)
    res = eskf.run(sc.imu, initial, cfg, G, lidar=lidar)
    assert np.abs(res.accel_bias[-1] - b_a).max() < 0.01
    assert np.abs(res.gyro_bias[-1] - b_w).max() < 2e-4


# ---------------------------------------------------------------------------------------
# Acceptance bars on KITTI (one seed each; the benchmark averages over seeds)
# ---------------------------------------------------------------------------------------

def _metrics(ex, res):
    est = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
    sel = np.isin(ex.lidar.t, res.t)
    raw = evaluate(ex.lidar.t[sel], ex.lidar.position[sel], ex.lidar.rotation[sel], ex.truth)
    return est, raw


@pytest.mark.parametrize("name", ["turns", "stop_go"])
def test_lidar_fusion_meets_the_acceptance_bars(name):
    ex = load_kitti(name)
    k0, s0 = ex.initial_state()
    res = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0)
    est, raw = _metrics(ex, res)
    assert est["ape_position"] <= 0.4 * raw["ape_position"]
    assert est["ape_attitude_deg"] <= 0.3 * raw["ape_attitude_deg"]
    assert est["rpe_position"] <= 0.4 * raw["rpe_position"]
    assert est["rpe_attitude_deg"] <= 0.4 * raw["rpe_attitude_deg"]
    assert 3.0 <= est["nees_pose"] <= 12.0


def test_gnss_fusion_beats_raw_gnss():
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    g = types.SimpleNamespace(t=ex.gnss.t, position=ex.gnss.position_noisy)
    res = eskf.run(ex.imu, s0, "kitti_gnss", ex.gravity, gnss=g, start=k0,
                   output_times=ex.gnss.t, clip_output_times=True)
    res = res.at(ex.gnss.t)
    truth = ex.truth.interpolate(res.t)
    fused = np.sqrt(np.mean(np.sum((res.position - truth.position) ** 2, axis=1)))
    sel = np.isin(ex.gnss.t, res.t)
    raw = np.sqrt(np.mean(np.sum((ex.gnss.position_noisy[sel] - truth.position) ** 2, axis=1)))
    assert fused <= 0.7 * raw


def _seq00_ate(ex, res):
    res = res.at(ex.truth.t)
    k = np.searchsorted(ex.truth.t, res.t - 1e-6)
    cam = ex.frames.cam0_position
    return ate_rmse(cam(res.position, res.rotation), cam(ex.truth.position[k], ex.truth.rotation[k]))


def test_whole_sequence_with_lidar_needs_the_interpolation_flags():
    ex = load_kitti("seq00")
    k0, s0 = ex.initial_state()
    res = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0)
    est = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
    assert _seq00_ate(ex, res) <= 0.2
    assert 3.0 <= est["nees_pose"] <= 12.0
    blind = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, lidar=ex.lidar, start=k0, use_interpolation_flags=False)
    worse = evaluate(blind.t, blind.position, blind.rotation, ex.truth, blind.P)
    assert _seq00_ate(ex, blind) > _seq00_ate(ex, res)
    assert worse["nees_pose"] > 12.0            # overconfident inside the interpolated spans


def test_whole_sequence_with_gnss():
    ex = load_kitti("seq00")
    k0, s0 = ex.initial_state()
    g = types.SimpleNamespace(t=ex.gnss.t, position=ex.gnss.position_noisy)
    res = eskf.run(ex.imu, s0, "kitti_gnss", ex.gravity, gnss=g, start=k0, output_times=ex.truth.t,
                   clip_output_times=True)
    assert _seq00_ate(ex, res) <= 1.5
