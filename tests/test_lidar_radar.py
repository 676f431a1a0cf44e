"""Chapter 05 (kalman_course.chapters.lidar_radar): the seeded CTRV lidar + radar scenario,
the Udacity log reader, the reference fusion filter with each measurement's own time step
(bug 6: irregular timestamps), and the CTRV EKF on KITTI."""

import dataclasses

import numpy as np
import pytest

from kalman_course import symbolic
from kalman_course.chapters import lidar_radar
from kalman_course.core.angles import wrap_angle
from kalman_course.evaluation.metrics import rmse
from kalman_course.filters import ekf

T0_US = 1477010443000000        # the first timestamp of the Udacity project's logs


def within_sd(sample_sd, sd, n, k=4.0):
    """True if a sample standard deviation from n draws is within k standard errors of sd."""
    return abs(sample_sd / sd - 1.0) < k / np.sqrt(2 * n)


def udacity_lines(scenario, with_yaw=False):
    """The scenario as lines of the Udacity log format (written here from the format's
    description, independently of the reader under test)."""
    truth = scenario.x
    lines = []
    for m in scenario.measurements():
        x = truth[m.index]
        gt = [x[0], x[1], x[2] * np.cos(x[3]), x[2] * np.sin(x[3])] + ([x[3], x[4]] if with_yaw else [])
        fields = ["L" if m.sensor == "lidar" else "R", *(f"{v:.12e}" for v in m.z),
                  str(T0_US + int(round(m.t * 1e6))), *(f"{v:.12e}" for v in gt)]
        lines.append("\t".join(fields))
    return lines


def write_log(path, lines):
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------
# the seeded scenario
# ---------------------------------------------------------------------------------------

def test_scenario_truth_follows_the_symbolic_ctrv_model_with_its_process_noise():
    sc = lidar_radar.ctrv_lidar_radar(seed=4)
    n = len(sc)
    rng = np.random.default_rng(4)                      # the documented order of the draws
    nu_a, nu_yaw = 3.0 * rng.standard_normal(n), 0.3 * rng.standard_normal(n)
    x = sc.x0
    for k in range(n):
        x = symbolic.ctrv_step(x, sc.dt, [nu_a[k], nu_yaw[k]])
        np.testing.assert_allclose(x, sc.x[k], rtol=0, atol=1e-12)
    np.testing.assert_allclose(sc.t, sc.dt * np.arange(1, n + 1))
    np.testing.assert_allclose(sc.R_lidar, np.diag([0.0225, 0.0225]))
    np.testing.assert_allclose(sc.R_radar, np.diag([0.09, 0.0009, 0.09]))


def test_scenario_interleaves_lidar_and_radar_with_the_stated_noise():
    sc = lidar_radar.ctrv_lidar_radar(seed=0, duration=500.0, x0=(50.0, 20.0, 5.0, 0.5, 0.1), sigma_a=0.0,
                                      sigma_yaw_acc=0.0)
    assert list(sc.sensor[:4]) == ["lidar", "radar", "lidar", "radar"]
    meas = list(sc.measurements())
    assert [m.sensor for m in meas[:2]] == ["lidar", "radar"] and len(meas) == len(sc)
    assert all(m.t == sc.t[m.index] for m in meas)
    lidar_res = sc.lidar_z - sc.x[sc.lidar_index, :2]
    np.testing.assert_allclose(np.cov(lidar_res.T), np.diag([0.0225, 0.0225]), atol=0.003)
    radar_true = np.array([symbolic.radar_observation(x) for x in sc.x[sc.radar_index]])
    res = sc.radar_z - radar_true
    res[:, 1] = wrap_angle(res[:, 1])
    for i, var in enumerate([0.09, 0.0009, 0.09]):
        assert within_sd(res[:, i].std(), np.sqrt(var), len(res))


def test_scenario_bearings_use_the_course_wrap_even_across_the_negative_x_axis():
    # a target crossing the negative x axis: bearings on both sides of the cut at ±π
    sc = lidar_radar.ctrv_lidar_radar(seed=2, duration=10.0, x0=(-20.0, -3.0, 1.0, np.pi / 2, 0.0),
                                      sigma_a=0.0, sigma_yaw_acc=0.0)
    phi = sc.radar_z[:, 1]
    assert (phi > 3.0).any() and (phi < -3.0).any()
    np.testing.assert_array_equal(phi, wrap_angle(phi))
    assert np.all((phi > -np.pi) & (phi <= np.pi))


def test_scenario_rejects_bad_arguments():
    with pytest.raises(ValueError, match="seed must be a non-negative integer"):
        lidar_radar.ctrv_lidar_radar(seed=-1)
    with pytest.raises(ValueError, match="R_radar must be positive definite"):
        lidar_radar.ctrv_lidar_radar(seed=0, R_radar=np.zeros((3, 3)))
    with pytest.raises(ValueError, match="duration must cover at least two measurements"):
        lidar_radar.ctrv_lidar_radar(seed=0, duration=0.05)


# ---------------------------------------------------------------------------------------
# the reader of the Udacity log
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("with_yaw", [False, True], ids=["EKF project (8/9 fields)", "UKF project (10/11 fields)"])
def test_udacity_log_round_trip(tmp_path, with_yaw):
    sc = lidar_radar.ctrv_lidar_radar(seed=1, duration=5.0)
    log = lidar_radar.read_udacity_log(write_log(tmp_path / "log.txt", udacity_lines(sc, with_yaw)))
    assert len(log) == len(sc) and list(log.sensor) == list(sc.sensor)
    np.testing.assert_allclose(log.t, sc.t - sc.t[0], rtol=0, atol=1e-9)
    np.testing.assert_allclose(log.lidar_z, sc.lidar_z, rtol=1e-11)
    np.testing.assert_allclose(log.radar_z, sc.radar_z, rtol=1e-11)
    np.testing.assert_allclose(lidar_radar.ctrv_to_cartesian(log.x), lidar_radar.ctrv_to_cartesian(sc.x),
                               rtol=1e-10, atol=1e-12)
    if with_yaw:
        np.testing.assert_allclose(log.x, sc.x, rtol=1e-11)
    else:
        assert np.isnan(log.x[:, 4]).all()                # the log gives no turn rate
    assert log.dt is None and log.seed is None and log.x0 is None


MALFORMED = [
    ("unknown sensor letter", "X\t1.0\t2.0\t{t}\t0\t0\t0\t0", r"line 3: the first field must be 'L' \(lidar\) or 'R'"),
    ("lidar line too short", "L\t1.0\t2.0\t{t}\t0\t0\t0", r"line 3: a 'L' line has 8 fields .* got 7"),
    ("radar line too long", "R\t1.0\t0.1\t0.2\t{t}\t0\t0\t0\t0\t0", r"line 3: a 'R' line has 9 fields .* got 10"),
    ("not a number", "L\t1.0\tabc\t{t}\t0\t0\t0\t0", r"line 3: field 3 must be a number, got 'abc'"),
    ("NaN measurement", "L\tnan\t2.0\t{t}\t0\t0\t0\t0", r"line 3: every number must be finite"),
    ("fractional timestamp", "L\t1.0\t2.0\t{t}.5\t0\t0\t0\t0", r"line 3: the timestamp \(field 4\) must be an integer"),
    ("bearing in degrees", "R\t5.0\t45.0\t0.2\t{t}\t0\t0\t0\t0", r"line 3: the bearing φ \(field 3\) must be in radians"),
    ("negative range", "R\t-5.0\t0.5\t0.2\t{t}\t0\t0\t0\t0", r"line 3: the range ρ \(field 2\) must not be negative"),
]


@pytest.mark.parametrize("line, message", [case[1:] for case in MALFORMED], ids=[case[0] for case in MALFORMED])
def test_malformed_log_line_names_its_line_number(tmp_path, line, message):
    good = udacity_lines(lidar_radar.ctrv_lidar_radar(seed=0, duration=0.2))
    path = write_log(tmp_path / "bad.txt", good[:2] + [line.format(t=T0_US + 150000)] + good[2:])
    with pytest.raises(ValueError, match=message) as error:
        lidar_radar.read_udacity_log(path)
    assert "bad.txt" in str(error.value)


def test_a_truncated_last_line_is_not_read_as_a_shorter_valid_line(tmp_path):
    # a UKF-project log (10/11 fields) whose last line lost its two yaw columns still has
    # the 8/9 fields of an EKF-project line: the file's first line says which format it is
    good = udacity_lines(lidar_radar.ctrv_lidar_radar(seed=0, duration=0.5), True)
    cut = "\t".join(good[-1].split("\t")[:-2])
    path = write_log(tmp_path / "cut.txt", good[:-1] + [cut])
    with pytest.raises(ValueError, match=rf"cut.txt, line {len(good)}: .* without the true yaw .* \(a truncated"):
        lidar_radar.read_udacity_log(path)
    binary = tmp_path / "log.bin"
    binary.write_bytes(b"L\t1.0\t2.0\xff\xfe\n")
    with pytest.raises(ValueError, match="log.bin is not a text log"):
        lidar_radar.read_udacity_log(binary)


def test_blank_lines_are_skipped_and_an_empty_log_is_an_error(tmp_path):
    good = udacity_lines(lidar_radar.ctrv_lidar_radar(seed=0, duration=0.2))
    assert len(lidar_radar.read_udacity_log(write_log(tmp_path / "a.txt", [good[0], "", good[1], "  "]))) == 2
    with pytest.raises(ValueError, match="holds no measurements"):
        lidar_radar.read_udacity_log(write_log(tmp_path / "empty.txt", ["", ""]))


# ---------------------------------------------------------------------------------------
# the reference fusion filter
# ---------------------------------------------------------------------------------------

def test_lidar_radar_fusion_meets_the_article_targets():
    sc = lidar_radar.ctrv_lidar_radar(0)
    res = lidar_radar.fuse_lidar_radar(sc)
    assert res.rmse["px"] <= 0.11 and res.rmse["py"] <= 0.11
    assert res.rmse["vx"] <= 0.52 and res.rmse["vy"] <= 0.52
    # the reported RMSE is that of the Cartesian estimates against the truth
    expected = rmse(res.cartesian(), lidar_radar.ctrv_to_cartesian(sc.x))
    np.testing.assert_allclose([res.rmse[k] for k in ("px", "py", "vx", "vy")], expected, rtol=1e-12)
    # each sensor alone is worse than both together
    for kwargs in ({"use_radar": False}, {"use_lidar": False}):
        alone = lidar_radar.fuse_lidar_radar(sc, **kwargs)
        assert alone.rmse["px"] + alone.rmse["py"] > res.rmse["px"] + res.rmse["py"]


def _after_convergence(result, t_start=2.0):
    """Position and velocity RMSE (norms over the two axes) from t_start on: the first
    seconds depend on which rows happen to open the log, the steady state does not."""
    late = result.t >= t_start
    e = rmse(result.cartesian()[late], result.cartesian(result.truth)[late])
    return np.hypot(e[0], e[1]), np.hypot(e[2], e[3])


def test_irregular_timestamps_are_used_bug_6(tmp_path):
    sc = lidar_radar.ctrv_lidar_radar(seed=0)
    lines = udacity_lines(sc)
    rng = np.random.default_rng(7)
    keep = np.sort(rng.choice(len(lines), size=round(0.7 * len(lines)), replace=False))     # drop 30 %
    full = lidar_radar.read_udacity_log(write_log(tmp_path / "full.txt", lines))
    dropped = lidar_radar.read_udacity_log(write_log(tmp_path / "dropped.txt", [lines[k] for k in keep]))
    steps = np.diff(dropped.t)
    assert steps.min() == pytest.approx(0.05) and steps.max() >= 0.2          # really irregular
    pos_full, vel_full = _after_convergence(lidar_radar.fuse_lidar_radar(full))
    pos, vel = _after_convergence(lidar_radar.fuse_lidar_radar(dropped))
    # what a filter that ignores the timestamps does: every step one nominal dt = 0.05 s
    fixed = dataclasses.replace(dropped, t=0.05 * np.arange(len(dropped)))
    pos_fixed, vel_fixed = _after_convergence(lidar_radar.fuse_lidar_radar(fixed))
    # 70 % of the data costs little (1/sqrt(0.7) = 1.2 for noise alone) ...
    assert pos < 1.5 * pos_full and vel < 1.5 * vel_full
    # ... while the fixed step misplaces the target along its path
    assert pos_fixed > 3.0 * pos and vel_fixed > 2.0 * vel


def test_zero_time_step_fuses_both_readings_at_the_same_instant():
    sc = lidar_radar.ctrv_lidar_radar(seed=3, duration=1.0)
    t = sc.t.copy()
    t[5] = t[4]                                               # lidar and radar together
    same_time = dataclasses.replace(sc, t=t)
    res = lidar_radar.fuse_lidar_radar(same_time)
    meas = list(same_time.measurements())
    # no prediction between rows 4 and 5: row 5 is the radar update of row 4's posterior
    expected = ekf.ekf_update(res.x_hat[4], res.P_hat[4], meas[5].z, symbolic.radar_observation,
                              symbolic.radar_jacobian, meas[5].R, residual=ekf.radar_residual, joseph=True)
    np.testing.assert_allclose(res.x_hat[5], expected.x_hat, rtol=1e-12, atol=1e-12)
    assert np.isfinite(res.x_hat).all()


def test_time_going_backwards_names_the_row_and_the_time():
    sc = lidar_radar.ctrv_lidar_radar(seed=3, duration=1.0)
    t = sc.t.copy()
    t[7] = t[6] - 0.01
    with pytest.raises(ValueError, match=r"row 7 \(radar\) is at t = 0\.340000 s, before row 6 at t = 0\.350000 s"):
        lidar_radar.fuse_lidar_radar(dataclasses.replace(sc, t=t))


def test_a_log_that_starts_with_radar_gets_its_prior_from_the_radar(tmp_path):
    lines = udacity_lines(lidar_radar.ctrv_lidar_radar(seed=5, duration=10.0))
    log = lidar_radar.read_udacity_log(write_log(tmp_path / "radar_first.txt", lines[1:]))
    assert log.sensor[0] == "radar"
    res = lidar_radar.fuse_lidar_radar(log)
    p, R_p = lidar_radar.radar_position_fix(log.radar_z[0], log.R_radar)
    np.testing.assert_allclose(res.x_hat[0, :2], p)
    np.testing.assert_allclose(res.P_hat[0, :2, :2], R_p)
    assert res.rmse["px"] < 0.15 and res.rmse["py"] < 0.15


def test_radar_position_fix_propagates_range_and_bearing_noise():
    z, R = np.array([12.0, 2.5, -1.0]), np.diag([0.09, 0.0009, 0.09])
    p, R_p = lidar_radar.radar_position_fix(z, R)
    np.testing.assert_allclose(p, 12.0 * np.array([np.cos(2.5), np.sin(2.5)]))
    # first-order propagation: against the central-difference Jacobian of (ρ, φ) -> p
    h = 1e-6
    J = np.column_stack([(lidar_radar.radar_position_fix(z + d, R)[0] - lidar_radar.radar_position_fix(z - d, R)[0])
                         / (2 * h) for d in (np.array([h, 0, 0]), np.array([0, h, 0]))])
    np.testing.assert_allclose(R_p, J @ R[:2, :2] @ J.T, rtol=1e-7)


def test_iterated_radar_updates_match_the_ekf_on_this_nearly_linear_case():
    sc = lidar_radar.ctrv_lidar_radar(0)
    e, i = lidar_radar.fuse_lidar_radar(sc), lidar_radar.fuse_lidar_radar(sc, iterated=True)
    assert (i.iterations[sc.radar_index] >= 2).all() and (e.iterations == 1).all()
    assert abs(i.rmse["px"] - e.rmse["px"]) < 0.1 * e.rmse["px"]


def test_kitti_ctrv_beats_raw_gnss():
    from kalman_course.data import load_kitti

    for name in ("cruise", "turns", "stop_go"):
        res = lidar_radar.run_kitti_ctrv(load_kitti(name))
        assert res.ekf_rmse < 0.9 * res.gnss_rmse, name
        distance = np.linalg.norm(res.x_hat[:, :2] - res.truth_xy, axis=1)
        assert res.ekf_rmse_all == pytest.approx(np.sqrt(np.mean(distance**2)), rel=1e-12)


@pytest.mark.parametrize("flag", ["use_lidar", "use_radar", "iterated", "joseph"])
def test_a_switch_given_as_text_or_a_number_is_refused(flag):
    # 'False' is a non-empty string, hence true: it must not switch a sensor on silently
    sc = lidar_radar.ctrv_lidar_radar(seed=0, duration=1.0)
    for value in ("False", "no", 0, 1):
        with pytest.raises(ValueError, match=f"{flag} must be True or False"):
            lidar_radar.fuse_lidar_radar(sc, **{flag: value})


def test_a_radar_row_at_the_sensors_position_is_named_with_its_row_and_time():
    import dataclasses
    sc = lidar_radar.ctrv_lidar_radar(seed=0, duration=1.0)
    at_origin = dataclasses.replace(sc, lidar_z=np.zeros_like(sc.lidar_z))   # the first fix puts the car on the radar
    with pytest.raises(ValueError, match=r"row 1 \(radar, t = 0\.100000 s, predicted position \(0, 0\) m\): "
                                         r"x must not be at the radar's position"):
        lidar_radar.fuse_lidar_radar(at_origin)
