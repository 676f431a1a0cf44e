"""Lecture 08's honest numbers: spreads over noise seeds, what is simulated, the GNSS outage's
attribution, the bias estimates against their σ, and the Earth's rotation.

Each test can fail: the statistical ones use seeded draws with tolerances derived from the
sample size (the derivation is in a comment next to each).
"""

from __future__ import annotations

import types

import numpy as np
import pytest

from kalman_course.chapters import eskf_bias, eskf_outage, eskf_seeds
from kalman_course.chapters.eskf_sources import REAL_INPUTS, gnss_source, lidar_source, sources_line
from kalman_course.core import so3
from kalman_course.data import load_kitti, simulate_gnss, simulate_lidar_poses
from kalman_course.evaluation.attitude import heading_tilt_error
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.spread import spread
from kalman_course.filters import eskf
from kalman_course.filters.eskf import NominalState
from kalman_course.filters.eskf_config import load_config

OUTAGE = (325.0, 355.0)


@pytest.fixture(scope="module")
def turns():
    return load_kitti("turns")


@pytest.fixture(scope="module")
def cfg():
    return load_config("kitti_lidar")


@pytest.fixture(scope="module")
def cfg_gnss():
    return load_config("kitti_gnss")


# ---------------------------------------------------------------------------------------
# evaluation.spread and evaluation.attitude
# ---------------------------------------------------------------------------------------

def test_spread_is_median_and_range_and_counts_the_values_above_a_bar():
    s = spread([0.41, 0.30, 0.35, 0.38, 0.42])
    assert (s.median, s.low, s.high, s.n) == (0.38, 0.30, 0.42, 5)
    assert s.count_above(0.4) == 2 and s.count_above(0.42) == 0 and s.count_above(0.0) == 5
    assert s.text(".2f") == "0.38 (0.30–0.42)"
    assert spread([2.0, 4.0]).median == 3.0                # even length: the mean of the middle two


@pytest.mark.parametrize("bad", [[], [1.0, np.nan], [[1.0, 2.0]], "abc"])
def test_spread_rejects_what_is_no_sample(bad):
    with pytest.raises(ValueError, match="values"):
        spread(bad)


def test_heading_and_tilt_of_known_errors_at_any_true_attitude():
    rng = np.random.default_rng(16)
    R_true = so3.exp(rng.normal(size=(5, 3)))
    yaw = np.deg2rad(1.5)
    heading, tilt = heading_tilt_error(so3.exp([0.0, 0.0, yaw]) @ R_true, R_true)
    assert np.allclose(heading, 1.5, atol=1e-9) and np.allclose(tilt, 0.0, atol=1e-9)
    # a navigation-frame error about a horizontal axis is all tilt, whatever the body's attitude
    d = np.deg2rad([0.3, -0.4, 0.0])
    heading, tilt = heading_tilt_error(so3.exp(d) @ R_true, R_true)
    assert np.allclose(heading, 0.0, atol=1e-9) and np.allclose(tilt, 0.5, atol=1e-9)
    # the body-frame error the pose metrics use, δθ = Log(R_trueᵀ R), has the same length
    dtheta = so3.log(np.swapaxes(R_true, -1, -2) @ (so3.exp(d) @ R_true))
    assert np.allclose(np.rad2deg(np.linalg.norm(dtheta, axis=1)), 0.5, atol=1e-9)
    # the estimate turned clockwise about up has a negative heading error
    h, _ = heading_tilt_error(so3.exp([0.0, 0.0, -yaw]), np.eye(3))
    assert h == pytest.approx(-1.5) and np.shape(h) == ()


def test_heading_tilt_error_rejects_mismatched_shapes():
    with pytest.raises(ValueError, match="same shape"):
        heading_tilt_error(np.eye(3), np.stack([np.eye(3)] * 2))
    with pytest.raises(ValueError, match="rotation_true"):
        heading_tilt_error(np.eye(3), np.eye(2))


# ---------------------------------------------------------------------------------------
# chapters.eskf_sources: every label says what is simulated
# ---------------------------------------------------------------------------------------

def test_labels_name_the_simulated_inputs_and_whether_they_match_the_filters_R(turns, cfg):
    text = lidar_source(turns.lidar, cfg)
    assert "simulated" in text and f"seed {turns.lidar.seed}" in text and "exactly the filter's R" in text
    other = cfg.replace(observation__lidar_position=0.4)
    assert "not the filter's R" in lidar_source(turns.lidar, other)
    coloured = types.SimpleNamespace(sigma_position=0.2, sigma_attitude_deg=0.3, seed=1,
                                     error_model="Gauss–Markov, τ = 1 s")
    assert "Gauss–Markov" in lidar_source(coloured, cfg) and "not the filter's R" in lidar_source(coloured, cfg)
    g = gnss_source(turns.gnss, load_config("kitti_gnss"))
    assert "simulated white noise σ 1 m" in g and "(real)" in g and "exactly the filter's R" in g
    line = sources_line(turns.lidar, turns.gnss, cfg)
    assert line.startswith("inputs: " + REAL_INPUTS) and "lidar poses simulated" in line and "GNSS fixes" in line


def test_labels_refuse_records_that_are_not_simulated_observations(turns):
    with pytest.raises(ValueError, match="sigma_position"):
        lidar_source(turns.truth)
    with pytest.raises(ValueError, match="sigma"):
        gnss_source(turns.truth)


# ---------------------------------------------------------------------------------------
# chapters.eskf_seeds: the spread over lidar noise draws
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def turns_spread(turns, cfg):
    return eskf_seeds.lidar_seed_spread(turns, cfg, [1, 2, 3])


def test_each_seed_is_a_new_draw_of_the_shipped_size(turns, turns_spread):
    rows = turns_spread.rows
    assert [r.seed for r in rows] == [1, 2, 3] and turns_spread.excerpt == "turns"
    assert len({r.raw_position for r in rows}) == 3                     # three different draws
    # white noise σ = 0.2 m per axis: the raw position RMSE estimates sqrt(3) σ = 0.346 m. Its
    # mean square averages 3K squared N(0, σ²) values (K poses), so its relative standard
    # deviation is sqrt(2 / (3K)) and that of the RMSE half of it; allow four of those.
    K = len(turns.truth.t)
    tol = 4 * 0.5 * np.sqrt(2 / (3 * K))
    for r in rows:
        assert r.raw_position == pytest.approx(np.sqrt(3) * turns.lidar.sigma_position, rel=tol)
        # the filter beats the raw poses it was given on every draw
        assert r.position_ratio < 1.0 and r.attitude_ratio < 1.0
        assert r.position_ratio == r.eskf_position / r.raw_position


def test_a_seed_reproduces_the_direct_run(turns, cfg, turns_spread):
    lidar = simulate_lidar_poses(turns.truth, 2, turns.lidar.sigma_position, turns.lidar.sigma_attitude_deg)
    k0, s0 = turns.initial_state()
    res = eskf.run(turns.imu, s0, cfg, turns.gravity, lidar=lidar, start=k0)
    m = evaluate(res.t, res.position, res.rotation, turns.truth, res.P)
    row = turns_spread.rows[1]
    assert (row.eskf_position, row.eskf_attitude_deg, row.nees_pose) == (
        m["ape_position"], m["ape_attitude_deg"], m["nees_pose"])
    assert turns_spread.position_ratio.values == tuple(r.position_ratio for r in turns_spread.rows)
    assert turns_spread.nees_pose.median == float(np.median([r.nees_pose for r in turns_spread.rows]))


def test_paired_ratio_and_the_table(turns_spread):
    same = eskf_seeds.paired_ratio([turns_spread], [turns_spread], "nees_pose")
    assert same.values == (1.0, 1.0, 1.0)
    other = eskf_seeds.SeedSpread("turns", turns_spread.rows[:2])
    with pytest.raises(ValueError, match="pair up"):
        eskf_seeds.paired_ratio([turns_spread], [other])
    with pytest.raises(ValueError, match="attr"):
        eskf_seeds.paired_ratio([turns_spread], [turns_spread], "speed")
    table = eskf_seeds.seed_spread_table([turns_spread], position_target=0.0)
    row = table.splitlines()[-1].split()
    assert row[0] == "turns" and row[1] == "3"
    assert row[4] == "3"            # every ratio is above a target of 0 (row: name, n, median, (range), count, ...)
    assert row[10::3] == [str(turns_spread.inconsistent(b)) for b in eskf_seeds.NEES_BLOCKS]
    with pytest.raises(ValueError, match="block"):
        turns_spread.inconsistent("velocity")
    with pytest.raises(ValueError, match="seed"):
        eskf_seeds.lidar_seed_spread(load_kitti("turns"), "kitti_lidar", [])


# ---------------------------------------------------------------------------------------
# chapters.eskf_bias
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def turns_runs(turns, cfg):
    k0, s0 = turns.initial_state()
    ref = eskf.run(turns.imu, s0, cfg, turns.gravity, lidar=turns.lidar, start=k0)
    frozen_cfg, P0 = eskf_bias.frozen_bias(cfg)
    frozen = eskf.run(turns.imu, s0, frozen_cfg, turns.gravity, lidar=turns.lidar, start=k0, P0=P0)
    return ref, frozen


def test_bias_in_sigmas_divides_the_last_estimate_by_its_own_sigma(turns_runs):
    ref, frozen = turns_runs
    a, w = eskf_bias.bias_in_sigmas(ref)
    sd = np.sqrt(np.diag(ref.P[-1]))
    assert np.array_equal(a, ref.accel_bias[-1] / sd[9:12]) and np.array_equal(w, ref.gyro_bias[-1] / sd[12:15])
    with pytest.raises(ValueError, match="frozen"):
        eskf_bias.bias_in_sigmas(frozen)


def test_frozen_biases_stay_exactly_zero_and_do_as_well_on_turns(turns, turns_runs):
    ref, frozen = turns_runs
    assert not frozen.accel_bias.any() and not frozen.gyro_bias.any()
    assert not frozen.P[:, 9:, :].any() and not frozen.P[:, :, 9:].any()
    # the lecture's claim on this draw: no worse than the reference by more than 5 %
    m_ref = evaluate(ref.t, ref.position, ref.rotation, turns.truth, ref.P)
    m_frozen = evaluate(frozen.t, frozen.position, frozen.rotation, turns.truth, frozen.P)
    assert m_frozen["ape_position"] <= 1.05 * m_ref["ape_position"]
    assert 3.0 <= m_frozen["nees_pose"] <= 12.0


def test_earth_rate_from_the_sidereal_day():
    sidereal_day_h = 86164.0905 / 3600.0
    rate = eskf_bias.earth_rate(49.0)
    total, north, up = rate.deg_per_hour()
    assert total == pytest.approx(360.0 / sidereal_day_h, rel=1e-6)
    assert north ** 2 + up ** 2 == pytest.approx(total ** 2)
    assert up > north                                   # above 45° the vertical part is the larger
    assert eskf_bias.earth_rate(0.0).vertical == 0.0 and eskf_bias.earth_rate(90.0).vertical == rate.total
    for bad in (91.0, np.nan, "49", True):
        with pytest.raises(ValueError, match="latitude"):
            eskf_bias.earth_rate(bad)


# ---------------------------------------------------------------------------------------
# chapters.eskf_outage
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def study(turns, cfg_gnss):
    return eskf_outage.outage_study(turns, cfg_gnss, OUTAGE)


def test_the_filter_in_the_outage_is_the_imu_alone_from_its_own_state(turns, cfg_gnss, study):
    """No fix inside the outage, so the filter's nominal state there is the IMU integrated from
    its state at the outage start: the attribution's dead reckoning must reproduce its error."""
    k0, s0 = turns.initial_state()
    fixes = turns.gnss.observations()
    kept = fixes.select((fixes.t < OUTAGE[0]) | (fixes.t > OUTAGE[1]))
    times = np.union1d(turns.truth.t, [study.t_start])
    res = eskf.run(turns.imu, s0, cfg_gnss, turns.gravity, gnss=kept, start=k0, output_times=times,
                   clip_output_times=True)
    i = int(np.argmin(np.abs(res.t - study.t_start)))
    state = NominalState(res.position[i], res.velocity[i], res.rotation[i], res.accel_bias[i], res.gyro_bias[i])
    k = int(np.searchsorted(turns.imu.t, study.t_start))
    # the same timeline nodes as the filter's run (every truth time), so the same integration steps
    nodes = turns.truth.t[(turns.truth.t > study.t_start) & (turns.truth.t <= study.t_end)]
    alone = eskf.run(turns.imu, state, cfg_gnss, turns.gravity, start=k, output_times=nodes)
    j = int(np.argmin(np.abs(turns.truth.t - study.t_end)))
    err = np.linalg.norm(alone.position[-1, :2] - turns.truth.position[j, :2])
    assert err == pytest.approx(study.filter_error, rel=1e-9)
    heading, tilt = heading_tilt_error(state.rotation, turns.truth.state_at(study.t_start).rotation)
    assert (study.heading_deg, study.tilt_deg) == pytest.approx((float(heading), float(tilt)))


def test_the_outage_study_measures_what_the_lecture_says(study):
    assert study.t_start >= OUTAGE[0] and study.t_end <= OUTAGE[1]
    assert set(study.swapped) == set(eskf_outage.SWAP_FIELDS)
    # the filter, started at the truth, ends the outage far worse than the IMU alone from the truth
    assert study.filter_error > 3 * max(study.imu_from_run_start, study.imu_from_outage_start)
    assert study.tilt_deg > 3 * study.imu_tilt_deg
    assert study.filter_peak >= study.filter_error
    # swapping in the filter's position alone barely changes the IMU's drift; its attitude does
    assert study.swapped["rotation"] > 3 * study.swapped["position"]


def test_outage_seed_errors_reproduce_the_study_for_one_seed(turns, cfg_gnss):
    over = eskf_outage.outage_seed_errors(turns, cfg_gnss, OUTAGE, [7])
    one = eskf_outage.outage_study(turns, cfg_gnss, OUTAGE, gnss=simulate_gnss(turns.gnss, 7, turns.gnss.sigma))
    assert over["filter_error"].values == pytest.approx((one.filter_error,), rel=1e-9)
    assert over["tilt_deg"].values == pytest.approx((one.tilt_deg,))


@pytest.mark.parametrize("outage", [(300.0, 330.0), (355.0, 325.0), (340.0, 400.0), "soon"])
def test_an_outage_outside_the_excerpt_is_refused(turns, cfg_gnss, outage):
    with pytest.raises(ValueError, match="outage"):
        eskf_outage.outage_study(turns, cfg_gnss, outage)


# ---------------------------------------------------------------------------------------
# the benchmark report keeps the SLAM tracks apart and labels every row
# ---------------------------------------------------------------------------------------

def test_bench_rows_say_what_they_rest_on():
    from kalman_course.tooling import bench

    rows = bench.excerpt_accuracy("turns")
    for label, r in rows.items():
        assert "simulated" in r["inputs"] or r.get("slam"), label
    slam = {label for label, r in rows.items() if r.get("slam")}
    assert slam == {"ORB-SLAM2 (SE(3)-aligned)", "S-PTAM (SE(3)-aligned)"}
    assert all("camera only" in rows[label]["inputs"] for label in slam)
    assert [name for name, _ in bench.seq00_slam_ate()] == ["ORB-SLAM2", "S-PTAM"]
