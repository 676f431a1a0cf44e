"""Chapter 05 (kalman_course.chapters.lidar_radar), the model comparison: the figure-eight
scenario, the CV model in the fusion filter, the CV-against-CTRV comparison, the position
NEES, and the KITTI σ_a tools (the car's accelerations and the σ_a sweep)."""

import dataclasses
import re
from functools import partial
from types import SimpleNamespace

import numpy as np
import pytest

from kalman_course.chapters import lidar_radar
from kalman_course.core.angles import wrap_angle
from kalman_course.data.kitti import TruthData, simulate_gnss
from kalman_course.evaluation.metrics import rmse

RMSE_KEYS = ("px", "py", "vx", "vy")


def rmse_row(result):
    return np.array([result.rmse[k] for k in RMSE_KEYS])


# ---------------------------------------------------------------------------------------
# the figure-eight scenario
# ---------------------------------------------------------------------------------------

def test_figure_eight_shapes_times_and_sensor_order():
    # the scenario structure a filter relies on: n rows at dt, 2 m, lidar first, then alternating
    sc = lidar_radar.figure_eight_lidar_radar(seed=3, duration=2.0, dt=0.1)
    n = 20
    assert len(sc) == n and sc.x.shape == (n, 5) and sc.x0.shape == (5,)
    np.testing.assert_allclose(sc.t, 0.1 * np.arange(1, n + 1), rtol=0, atol=1e-12)
    assert list(sc.sensor) == ["lidar", "radar"] * (n // 2)
    assert sc.lidar_z.shape == (n // 2, 2) and sc.radar_z.shape == (n // 2, 3)
    np.testing.assert_array_equal(sc.lidar_index, np.arange(0, n, 2))
    np.testing.assert_array_equal(sc.radar_index, np.arange(1, n, 2))
    assert sc.dt == 0.1 and sc.seed == 3


def test_figure_eight_follows_its_documented_curve_and_draws():
    # the docstring's recipe, rebuilt independently: A, B, period, θ, then lidar and radar noise
    seed, dt, n = 11, 0.05, 500
    sc = lidar_radar.figure_eight_lidar_radar(seed)
    rng = np.random.default_rng(seed)
    A, B, period, theta = rng.uniform(8, 14), rng.uniform(4, 7), rng.uniform(20, 30), rng.uniform(0, 2 * np.pi)
    t = dt * np.arange(n + 1)
    u = 2 * np.pi / period * t + theta
    pos = np.column_stack([A + 5 + A * np.sin(u), B * np.sin(2 * u)])
    np.testing.assert_allclose(sc.x[:, :2], pos[1:], rtol=0, atol=1e-9)
    np.testing.assert_allclose(sc.x0[:2], pos[0], rtol=0, atol=1e-9)
    lidar_noise = rng.standard_normal((n // 2, 2)) * 0.15
    radar_noise = rng.standard_normal((n // 2, 3)) * np.array([0.3, 0.03, 0.3])
    np.testing.assert_allclose(sc.lidar_z, pos[1:][sc.lidar_index] + lidar_noise, rtol=0, atol=1e-9)
    x = sc.x[sc.radar_index]
    rho = np.hypot(x[:, 0], x[:, 1])
    h = np.column_stack([rho, np.arctan2(x[:, 1], x[:, 0]),
                         x[:, 2] * (x[:, 0] * np.cos(x[:, 3]) + x[:, 1] * np.sin(x[:, 3])) / rho])
    expected = h + radar_noise
    expected[:, 1] = wrap_angle(expected[:, 1])
    np.testing.assert_allclose(sc.radar_z, expected, rtol=0, atol=1e-9)


def test_figure_eight_speed_heading_and_turn_rate_are_the_derivatives_of_the_path():
    # v, ψ and ω must describe the path itself (checked by central differences on a fine grid)
    dt = 0.001
    sc = lidar_radar.figure_eight_lidar_radar(seed=5, duration=30.0, dt=dt)
    p, x = sc.x[:, :2], sc.x[1:-1]
    v_fd = (p[2:] - p[:-2]) / (2 * dt)
    np.testing.assert_allclose(x[:, 2], np.hypot(v_fd[:, 0], v_fd[:, 1]), rtol=0, atol=1e-4)
    np.testing.assert_allclose(wrap_angle(x[:, 3] - np.arctan2(v_fd[:, 1], v_fd[:, 0])), 0.0, rtol=0, atol=1e-4)
    psi = sc.x[:, 3]
    assert np.abs(np.diff(psi)).max() < 0.1                  # unwrapped: no 2π jumps
    np.testing.assert_allclose(x[:, 4], (psi[2:] - psi[:-2]) / (2 * dt), rtol=0, atol=1e-4)


def test_figure_eight_same_seed_same_data_other_seed_other_data():
    # reproducible for a seed; another seed changes both the path and the noise
    a, b = lidar_radar.figure_eight_lidar_radar(7), lidar_radar.figure_eight_lidar_radar(7)
    for name in ("t", "x", "lidar_z", "radar_z", "x0"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
    c = lidar_radar.figure_eight_lidar_radar(8)
    assert not np.allclose(a.x, c.x)
    noise_a, noise_c = a.lidar_z - a.x[a.lidar_index, :2], c.lidar_z - c.x[c.lidar_index, :2]
    assert not np.allclose(noise_a, noise_c)


def test_figure_eight_process_noise_is_stored_but_does_not_move_the_truth():
    # documented: σ_a and σ_ψ̈ are the filter's defaults only, the truth does not use them
    a = lidar_radar.figure_eight_lidar_radar(2, sigma_a=3.0, sigma_yaw_acc=0.3)
    b = lidar_radar.figure_eight_lidar_radar(2, sigma_a=0.5, sigma_yaw_acc=2.0)
    assert (b.sigma_a, b.sigma_yaw_acc) == (0.5, 2.0)
    np.testing.assert_array_equal(a.x, b.x)
    np.testing.assert_array_equal(a.lidar_z, b.lidar_z)
    np.testing.assert_array_equal(a.radar_z, b.radar_z)


@pytest.mark.parametrize("seed", range(8))
def test_figure_eight_stays_at_least_5_m_from_the_radar(seed):
    # the radar at the origin must never see a range below 5 m (h and its Jacobian blow up at 0);
    # over a full loop (period <= 30 s) the closest approach is the documented 5 m
    sc = lidar_radar.figure_eight_lidar_radar(seed, duration=30.0, dt=0.01)
    r = np.hypot(sc.x[:, 0], sc.x[:, 1])
    assert r.min() >= 5.0 - 1e-9
    assert r.min() < 5.01


@pytest.mark.parametrize("seed", range(4))
def test_figure_eight_is_not_a_constant_turn_rate_motion(seed):
    # CTRV (no noise) holds v and ω constant; the figure-eight turns both ways and changes speed
    sc = lidar_radar.figure_eight_lidar_radar(seed)
    omega, speed = sc.x[:, 4], sc.x[:, 2]
    assert omega.max() > 0.05 and omega.min() < -0.05
    assert speed.max() > 1.2 * speed.min()


@pytest.mark.parametrize("kwargs, name", [
    ({"seed": -1}, "seed"),
    ({"seed": 1.5}, "seed"),
    ({"seed": 0, "duration": 0.0}, "duration"),
    ({"seed": 0, "duration": 0.05}, "duration"),               # a single measurement
    ({"seed": 0, "dt": -0.1}, "dt"),
    ({"seed": 0, "sigma_a": -1.0}, "sigma_a"),
    ({"seed": 0, "sigma_yaw_acc": np.nan}, "sigma_yaw_acc"),
    ({"seed": 0, "R_lidar": np.zeros((2, 2))}, "R_lidar"),
    ({"seed": 0, "R_radar": np.eye(2)}, "R_radar"),
])
def test_figure_eight_rejects_bad_arguments_by_name(kwargs, name):
    # a student's wrong argument must be named in the error
    with pytest.raises(ValueError, match=rf"^{name} "):
        lidar_radar.figure_eight_lidar_radar(**kwargs)


# ---------------------------------------------------------------------------------------
# the CV model in the fusion filter
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def straight_line():
    # a noise-free CTRV target with ω = 0: a straight line at constant speed (a CV truth)
    return lidar_radar.ctrv_lidar_radar(3, sigma_a=0.0, sigma_yaw_acc=0.0, x0=(5.0, 2.0, 5.0, 0.5, 0.0))


def test_unknown_model_is_rejected_by_name(straight_line):
    # "ca" is a model the symbolic layer knows, but the fusion filter only offers cv and ctrv
    for model in ("ca", "CV", None):
        with pytest.raises(ValueError, match=re.escape(f"model must be 'ctrv' or 'cv', got {model!r}")):
            lidar_radar.fuse_lidar_radar(straight_line, model=model)


def test_cv_and_ctrv_both_track_a_straight_constant_velocity_line(straight_line):
    # on a truth both models can generate, both must converge, and neither may be far worse
    assert np.ptp(straight_line.x[:, 2:], axis=0).max() == 0.0          # really v, ψ, ω constant
    truth = lidar_radar.ctrv_to_cartesian(straight_line.x)
    late = straight_line.t >= 2.0                                       # after the prior's v = 0 is forgotten
    pos, vel = {}, {}
    for model in ("cv", "ctrv"):
        res = lidar_radar.fuse_lidar_radar(straight_line, sigma_a=0.5, sigma_yaw_acc=0.1, model=model)
        assert res.model == model
        e = rmse(res.cartesian()[late], truth[late])
        pos[model], vel[model] = np.hypot(e[0], e[1]), np.hypot(e[2], e[3])
        assert res.rmse["px"] < 0.15 and res.rmse["py"] < 0.15          # better than the raw lidar σ
        assert vel[model] < 0.25                                         # 5 % of the 5 m/s speed
    assert 1 / 1.5 < pos["cv"] / pos["ctrv"] < 1.5
    assert 1 / 2 < vel["cv"] / vel["ctrv"] < 2


def test_cv_and_ctrv_results_report_the_same_cartesian_rmse(straight_line):
    # the comparison reads the same four keys from both; for CV they are of x_hat itself
    cv = lidar_radar.fuse_lidar_radar(straight_line, model="cv")
    ctrv = lidar_radar.fuse_lidar_radar(straight_line, model="ctrv")
    assert set(cv.rmse) == set(ctrv.rmse) == set(RMSE_KEYS)
    n = len(straight_line)
    assert cv.x_hat.shape == (n, 4) and cv.P_hat.shape == (n, 4, 4)
    assert ctrv.x_hat.shape == (n, 5) and cv.truth.shape == (n, 5)
    np.testing.assert_array_equal(cv.cartesian(), cv.x_hat)
    expected = rmse(cv.x_hat, lidar_radar.ctrv_to_cartesian(straight_line.x))
    np.testing.assert_allclose(rmse_row(cv), expected, rtol=1e-12)


def test_cv_filter_ignores_sigma_yaw_acc(straight_line):
    # documented: CV uses σ_a on both axes and no yaw noise
    a = lidar_radar.fuse_lidar_radar(straight_line, sigma_a=1.0, sigma_yaw_acc=0.1, model="cv")
    b = lidar_radar.fuse_lidar_radar(straight_line, sigma_a=1.0, sigma_yaw_acc=5.0, model="cv")
    np.testing.assert_array_equal(a.x_hat, b.x_hat)
    np.testing.assert_array_equal(a.P_hat, b.P_hat)


def _kf_update(x, P, residual, H, R):
    S = H @ P @ H.T + R
    K = np.linalg.solve(S, H @ P).T
    return x + K @ residual, (np.eye(len(x)) - K @ H) @ P


def _radar_h_and_jacobian_cv(x):
    px, py, vx, vy = x
    rho = np.hypot(px, py)
    h = np.array([rho, np.arctan2(py, px), (px * vx + py * vy) / rho])
    cross = vx * py - vy * px
    H = np.array([[px / rho, py / rho, 0, 0],
                  [-py / rho**2, px / rho**2, 0, 0],
                  [py * cross / rho**3, -px * cross / rho**3, px / rho, py / rho]])
    return h, H


def test_cv_filter_first_steps_match_a_hand_written_cv_ekf(straight_line):
    # prior, CV prediction with noise [a_x, a_y] (σ_a each), radar EKF and lidar KF updates,
    # over enough rows that the radar's range rate sees a non-zero velocity
    sc, sigma_a = straight_line, 2.0
    res = lidar_radar.fuse_lidar_radar(sc, sigma_a=sigma_a, model="cv")
    z0 = sc.lidar_z[0]
    x = np.array([z0[0], z0[1], 0.0, 0.0])
    P = np.diag([0.0225, 0.0225, 25.0, 25.0])                  # R_lidar, and the CTRV prior's σ_v = 5 m/s
    np.testing.assert_allclose(res.x_hat[0], x, rtol=0, atol=1e-12)
    np.testing.assert_allclose(res.P_hat[0], P, rtol=0, atol=1e-12)
    lidar_H = np.hstack([np.eye(2), np.zeros((2, 2))])
    measurements = list(sc.measurements())
    for k in range(1, 8):
        T = sc.t[k] - sc.t[k - 1]
        F = np.block([[np.eye(2), T * np.eye(2)], [np.zeros((2, 2)), np.eye(2)]])
        G = np.vstack([0.5 * T**2 * np.eye(2), T * np.eye(2)])
        x, P = F @ x, F @ P @ F.T + sigma_a**2 * G @ G.T
        m = measurements[k]
        if m.sensor == "radar":
            h, H = _radar_h_and_jacobian_cv(x)
            nu = m.z - h
            nu[1] = wrap_angle(nu[1])
            x, P = _kf_update(x, P, nu, H, m.R)
        else:
            x, P = _kf_update(x, P, m.z - x[:2], lidar_H, m.R)
        np.testing.assert_allclose(res.x_hat[k], x, rtol=1e-9, atol=1e-12, err_msg=f"row {k}")
        np.testing.assert_allclose(res.P_hat[k], P, rtol=1e-9, atol=1e-12, err_msg=f"row {k}")
    assert np.hypot(x[2], x[3]) > 1.0                            # the range rate really was exercised


# ---------------------------------------------------------------------------------------
# the position NEES
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("model", ["cv", "ctrv"])
def test_position_nees_is_the_position_block_nees_of_every_row(straight_line, model):
    # e^T P^-1 e over [p_x, p_y] only, whatever the rest of the state layout
    res = lidar_radar.fuse_lidar_radar(straight_line, model=model)
    eps = lidar_radar.position_nees(res)
    assert eps.shape == (len(straight_line),)
    assert np.isfinite(eps).all() and (eps >= 0).all()
    for k in (0, 1, 37, len(straight_line) - 1):
        e = res.x_hat[k, :2] - straight_line.x[k, :2]
        expected = e @ np.linalg.solve(res.P_hat[k, :2, :2], e)
        assert eps[k] == pytest.approx(expected, rel=1e-10)


# ---------------------------------------------------------------------------------------
# CV against CTRV
# ---------------------------------------------------------------------------------------

SHORT_EIGHT = partial(lidar_radar.figure_eight_lidar_radar, duration=3.0)
CV_GRID, CTRV_GRID = (1.0, 4.0), ((1.0, 1.0), (3.0, 0.3))


@pytest.fixture(scope="module")
def comparison():
    return lidar_radar.compare_cv_ctrv(seeds=(0, 1, 2), tuning_seeds=(100, 101), scenario=SHORT_EIGHT,
                                       cv_sigmas=CV_GRID, ctrv_sigmas=CTRV_GRID)


def _never_called(seed):
    pytest.fail("compare_cv_ctrv built a scenario before checking its seeds")


@pytest.mark.parametrize("seeds, tuning_seeds, message", [
    ((1, 2), (2, 3), r"tuning_seeds must not overlap seeds; both hold \[2\]"),
    ((5,), (5,), r"tuning_seeds must not overlap seeds; both hold \[5\]"),
    ((), (1,), r"seeds and tuning_seeds must each hold at least one seed"),
    ((1,), (), r"seeds and tuning_seeds must each hold at least one seed"),
])
def test_compare_rejects_overlapping_or_missing_seeds_up_front(seeds, tuning_seeds, message):
    # tuning on a test seed would flatter the result; the check must come before any work
    with pytest.raises(ValueError, match=message):
        lidar_radar.compare_cv_ctrv(seeds, tuning_seeds, scenario=_never_called)


def test_compare_result_has_one_row_per_seed(comparison):
    # every per-seed array lines up with the seeds; the NEES has one column per scenario row
    n_rows = len(SHORT_EIGHT(0))
    assert comparison.seeds == (0, 1, 2) and comparison.tuning_seeds == (100, 101)
    for model, grid in (("cv", CV_GRID), ("ctrv", CTRV_GRID)):
        assert comparison.rmse[model].shape == (3, 4)
        assert comparison.position_nees[model].shape == (3, n_rows)
        assert comparison.tuning_score[model].shape == (len(grid),)
        assert comparison.meets_rubric(model).shape == (3,) and comparison.score(model).shape == (3,)
    assert comparison.settings["cv"] == [(1.0, 0.0), (4.0, 0.0)]
    assert comparison.settings["ctrv"] == list(CTRV_GRID)


def test_compare_tunes_on_the_tuning_seeds_and_reports_the_test_seeds(comparison):
    # recomputed by hand: the tuning score, the argmin choice, and each test seed's RMSE and NEES
    rubric = np.array(lidar_radar.UDACITY_RUBRIC)
    runs = {"cv": [(s, None) for s in CV_GRID], "ctrv": list(CTRV_GRID)}
    for model, grid in runs.items():
        score = [np.median([(rmse_row(lidar_radar.fuse_lidar_radar(SHORT_EIGHT(seed), a, y, model=model))
                             / rubric).sum() for seed in (100, 101)]) for a, y in grid]
        np.testing.assert_allclose(comparison.tuning_score[model], score, rtol=1e-12)
        best = int(np.argmin(score))
        assert comparison.chosen[model] == comparison.settings[model][best]
        a, y = grid[best]
        for i, seed in enumerate((0, 1, 2)):
            res = lidar_radar.fuse_lidar_radar(SHORT_EIGHT(seed), a, y, model=model)
            np.testing.assert_allclose(comparison.rmse[model][i], rmse_row(res), rtol=1e-12)
            np.testing.assert_allclose(comparison.position_nees[model][i], lidar_radar.position_nees(res),
                                       rtol=1e-12)
        np.testing.assert_allclose(comparison.score(model), (comparison.rmse[model] / rubric).sum(axis=1),
                                   rtol=1e-12)
        np.testing.assert_array_equal(comparison.meets_rubric(model), (comparison.rmse[model] <= rubric).all(axis=1))


# ---------------------------------------------------------------------------------------
# the car's along-track acceleration
# ---------------------------------------------------------------------------------------

def synthetic_excerpt(t, velocity):
    """An excerpt-like object: only ``truth`` (a real TruthData), positions integrated from
    the velocities by the trapezoid rule, attitude fixed (kitti_acceleration ignores it)."""
    t = np.asarray(t, dtype=float)
    v = np.column_stack([velocity, np.zeros(len(t))]) if velocity.shape[1] == 2 else velocity
    p = np.vstack([np.zeros(3), np.cumsum(0.5 * (v[1:] + v[:-1]) * np.diff(t)[:, None], axis=0)])
    K = len(t)
    truth = TruthData(t, p, v, np.tile([1.0, 0.0, 0.0, 0.0], (K, 1)), np.tile(np.eye(3), (K, 1, 1)))
    return SimpleNamespace(truth=truth)


def ramp_on_a_turn(a, duration=20.0, dt=0.1, turn_rate=0.2):
    """Speed a·t on a path whose heading turns at turn_rate: the velocity components vary in
    ways that are not the along-track acceleration."""
    t = dt * np.arange(int(round(duration / dt)) + 1)
    heading = turn_rate * t
    return synthetic_excerpt(t, (a * t)[:, None] * np.column_stack([np.cos(heading), np.sin(heading)]))


def test_kitti_acceleration_of_a_constant_along_track_acceleration_on_a_turn():
    # |v| = a t: d|v|/dt = a everywhere and |v| changes by a·interval over any interval, turn or no turn
    a = 0.8
    acc = lidar_radar.kitti_acceleration(ramp_on_a_turn(a), interval=1.0, step=0.1)
    assert acc.rms_along == pytest.approx(a, rel=1e-9)
    assert acc.rms_speed_change == pytest.approx(a * 1.0, rel=1e-9)
    assert (acc.interval, acc.step) == (1.0, 0.1)
    longer = lidar_radar.kitti_acceleration(ramp_on_a_turn(a), interval=2.0, step=0.2)
    assert longer.rms_speed_change == pytest.approx(a * 2.0, rel=1e-9)


def test_kitti_acceleration_of_a_turn_at_constant_speed_is_zero():
    # a turn at constant speed accelerates the car sideways, not along its track
    t = 0.1 * np.arange(201)
    heading = 0.3 * t
    excerpt = synthetic_excerpt(t, 12.0 * np.column_stack([np.cos(heading), np.sin(heading)]))
    acc = lidar_radar.kitti_acceleration(excerpt)
    assert acc.rms_along == pytest.approx(0.0, abs=1e-9)
    assert acc.rms_speed_change == pytest.approx(0.0, abs=1e-9)


def test_kitti_acceleration_is_a_root_mean_square_not_a_mean():
    # speeding up at +a then braking at −a averages to zero; the RMS must still be a
    a, dt, k_turn = 1.5, 0.1, 100
    t = dt * np.arange(2 * k_turn + 1)
    t_turn = t[k_turn]
    speed = 5.0 + a * np.where(t <= t_turn, t, 2 * t_turn - t)
    acc = lidar_radar.kitti_acceleration(synthetic_excerpt(t, np.column_stack([speed, 0 * speed])), 1.0, 0.1)
    # np.gradient is exact on each line; at the apex the central difference is (a − a)/2 = 0
    assert acc.rms_along == pytest.approx(a * np.sqrt((len(t) - 1) / len(t)), rel=1e-9)
    # speed change over [s, s + 1]: +a before the apex, −a after, a(2 t_turn − 2s − 1) across it
    starts = dt * np.arange(int(round((t[-1] - 1.0) / dt)))
    change = np.where(starts + 1.0 <= t_turn, a, np.where(starts >= t_turn, -a, a * (2 * t_turn - 2 * starts - 1.0)))
    assert acc.rms_speed_change == pytest.approx(np.sqrt(np.mean(change**2)), rel=1e-9)


def test_white_equivalent_follows_its_formula():
    # σ_a = rms_speed_change / √(step · interval), as the property's docstring derives
    acc = lidar_radar.kitti_acceleration(ramp_on_a_turn(0.8), interval=2.0, step=0.2)
    assert acc.white_equivalent == pytest.approx(0.8 * 2.0 / np.sqrt(0.2 * 2.0), rel=1e-9)
    direct = lidar_radar.KittiAcceleration(rms_along=1.0, rms_speed_change=0.6, interval=1.0, step=0.1)
    assert direct.white_equivalent == pytest.approx(0.6 / np.sqrt(0.1), rel=1e-12)


def test_white_equivalent_recovers_the_sigma_of_white_acceleration():
    # the stated meaning: a speed driven by white acceleration σ_a held over each step gives σ_a back
    sigma_a, step, n = 1.2, 0.1, 6000
    rng = np.random.default_rng(42)
    speed = 40.0 + np.concatenate([[0.0], np.cumsum(sigma_a * step * rng.standard_normal(n))])
    assert speed.min() > 0                                     # |v| is the speed itself: no sign flips
    t = step * np.arange(n + 1)
    acc = lidar_radar.kitti_acceleration(synthetic_excerpt(t, np.column_stack([speed, 0 * speed])), 1.0, step)
    # about n·step/interval = 600 independent 1 s windows: relative standard error ≈ 1/√1200 ≈ 3 %
    assert acc.white_equivalent == pytest.approx(sigma_a, rel=4 / np.sqrt(2 * 600))


def test_kitti_acceleration_rejects_a_truth_too_short_for_the_interval():
    # fewer than two start times leave no RMS to speak of
    short = synthetic_excerpt(0.1 * np.arange(11), np.column_stack([np.ones(11), np.zeros(11)]))    # 1.0 s
    with pytest.raises(ValueError, match=r"the truth spans 1\.0 s, too short for interval = 1\.0 s"):
        lidar_radar.kitti_acceleration(short, interval=1.0)
    # a single 1 s window (one start time) is still too short
    one = synthetic_excerpt(0.05 * np.arange(22), np.column_stack([np.ones(22), np.zeros(22)]))    # 1.05 s
    with pytest.raises(ValueError, match="too short for interval"):
        lidar_radar.kitti_acceleration(one, interval=1.0, step=0.1)
    just = synthetic_excerpt(0.1 * np.arange(13), np.column_stack([np.ones(13), np.zeros(13)]))     # 1.2 s
    assert lidar_radar.kitti_acceleration(just, interval=1.0, step=0.1).rms_speed_change == pytest.approx(0.0)
    for kwargs, name in (({"interval": 0.0}, "interval"), ({"step": -0.1}, "step")):
        with pytest.raises(ValueError, match=rf"^{name} must be a finite positive number"):
            lidar_radar.kitti_acceleration(just, **kwargs)


# ---------------------------------------------------------------------------------------
# the σ_a sweep on KITTI
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def cruise():
    from kalman_course.data import load_kitti

    return load_kitti("cruise")


def test_sigma_sweep_shapes_and_cells_match_single_runs(cruise):
    # each cell is run_kitti_ctrv on GNSS re-simulated with that seed; the fixes do not depend on σ_a
    sigmas, seeds = (1.0, 5.0), (3,)
    sweep = lidar_radar.kitti_sigma_a_sweep([cruise], sigmas=sigmas, gnss_seeds=seeds)
    assert sweep.names == ("cruise",) and sweep.sigmas == sigmas and sweep.gnss_seeds == seeds
    for arr in (sweep.rmse_all, sweep.rmse_at_fixes, sweep.gnss_rmse):
        assert arr.shape == (1, 2, 1) and np.isfinite(arr).all()
    assert sweep.gnss_rmse[0, 0, 0] == sweep.gnss_rmse[0, 1, 0]
    noisy = dataclasses.replace(cruise, gnss=simulate_gnss(cruise.gnss, 3, cruise.gnss.sigma))
    for j, sigma in enumerate(sigmas):
        res = lidar_radar.run_kitti_ctrv(noisy, sigma_a=sigma)
        assert sweep.rmse_all[0, j, 0] == pytest.approx(res.ekf_rmse_all, rel=1e-12)
        assert sweep.rmse_at_fixes[0, j, 0] == pytest.approx(res.ekf_rmse, rel=1e-12)
        assert sweep.gnss_rmse[0, j, 0] == pytest.approx(res.gnss_rmse, rel=1e-12)
    assert sweep.rmse_all[0, 0, 0] != sweep.rmse_all[0, 1, 0]                 # σ_a reaches the filter
    assert sweep.best_sigma().tolist() == [sigmas[int(np.argmin(sweep.rmse_all[0, :, 0]))]]


def test_sigma_sweep_rejects_empty_inputs(cruise):
    # an empty axis would give empty arrays and a meaningless best σ_a
    for kwargs in ({"excerpts": []}, {"excerpts": [cruise], "sigmas": ()}, {"excerpts": [cruise], "gnss_seeds": ()}):
        with pytest.raises(ValueError, match="must each hold at least one value"):
            lidar_radar.kitti_sigma_a_sweep(**kwargs)
    with pytest.raises(ValueError, match="^sigmas must be a finite positive number"):
        lidar_radar.kitti_sigma_a_sweep([cruise], sigmas=(0.0,))
