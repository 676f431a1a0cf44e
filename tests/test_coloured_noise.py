"""Coloured lidar errors (chapter 10): the augmented ESKF, the remedies experiment, its figure.

The IMU and ground truth are the real KITTI excerpts; every lidar pose is simulated from a
seed, so each number here is deterministic. Statistical tolerances say how they follow
from the sample size.
"""

from __future__ import annotations

import dataclasses
from types import SimpleNamespace

import matplotlib.pyplot as plt
import numpy as np
import pytest

from kalman_course.chapters import coloured_noise as cn
from kalman_course.data import GaussMarkovErrors, load_kitti, simulate_lidar_poses
from kalman_course.evaluation import metrics
from kalman_course.filters import eskf
from kalman_course.filters import eskf_augmented as aug
from kalman_course.filters.eskf_config import load_config
from kalman_course.plotting import plot_coloured_noise


@pytest.fixture(scope="module")
def cruise():
    return load_kitti("cruise")


@pytest.fixture(scope="module")
def cfg():
    return load_config("kitti_lidar")


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def _gm_lidar(ex, seed, tau):
    return simulate_lidar_poses(ex.truth, seed, errors=GaussMarkovErrors(0.2, 0.3, tau))


# ---------------------------------------------------------------------------------------
# The augmented filter reduces to the plain one
# ---------------------------------------------------------------------------------------

def test_without_augmentation_it_is_eskf_run_to_the_bit(cruise, cfg):
    k0, s0 = cruise.initial_state()
    lidar = _gm_lidar(cruise, 11, 1.0)
    t_end = cruise.imu.t[k0] + 12.0
    plain = eskf.run(cruise.imu, s0, cfg, cruise.gravity, lidar=lidar, start=k0, t_end=t_end)
    same = aug.run(cruise.imu, s0, cfg, cruise.gravity, lidar=lidar, start=k0, t_end=t_end)
    assert same.time_constant is None and same.error_estimate.shape == (len(plain.t), 0)
    for name in ("t", "position", "velocity", "rotation", "accel_bias", "gyro_bias", "P", "updated"):
        assert np.array_equal(getattr(same, name), getattr(plain, name)), name
    assert np.array_equal(np.array(same.innovation), np.array(plain.innovation))
    assert np.array_equal(np.array(same.S), np.array(plain.S))


def test_as_tau_goes_to_zero_it_is_the_plain_filter_to_round_off(cruise, cfg):
    # τ = 1 µs: φ = exp(−0.1 s / 1 µs) underflows to 0 between poses, so the error state
    # forgets everything and adds exactly σ² = R: the same filter, summed in another order
    k0, s0 = cruise.initial_state()
    lidar = _gm_lidar(cruise, 12, 0.5)
    plain = eskf.run(cruise.imu, s0, cfg, cruise.gravity, lidar=lidar, start=k0)
    limit = aug.run(cruise.imu, s0, cfg, cruise.gravity, lidar=lidar, start=k0, time_constant=1e-6)
    assert limit.P_full.shape[1:] == (21, 21)
    np.testing.assert_allclose(limit.position, plain.position, rtol=0, atol=1e-9)
    np.testing.assert_allclose(limit.rotation, plain.rotation, rtol=0, atol=1e-12)
    np.testing.assert_allclose(limit.P, plain.P, rtol=1e-9, atol=1e-18)


def test_step_by_step_filter_equals_the_batch_run(cruise, cfg):
    # observations on IMU samples every 10 steps; the batch composes those 10 steps into
    # one propagation (Φ = ∏ F, φ = exp(−ΣT/τ)), the step filter takes them one by one
    k0, s0 = cruise.initial_state()
    imu = cruise.imu
    idx = np.arange(k0 + 10, k0 + 301, 10)
    poses = cruise.truth.interpolate(imu.t[idx])
    truth_like = SimpleNamespace(t=imu.t[idx], position=poses.position, rotation=poses.rotation)
    lidar = simulate_lidar_poses(truth_like, 3, errors=GaussMarkovErrors(0.2, 0.3, 1.0))
    batch = aug.run(imu, s0, cfg, cruise.gravity, lidar=lidar, start=k0, t_end=imu.t[idx[-1]],
                    time_constant=1.0, gap_factor=None)

    f = aug.AugmentedESKF(cfg, s0, cruise.gravity, time_constant=1.0)
    states = []
    for i in range(k0, idx[-1]):
        f.predict(imu.specific_force[i], imu.angular_rate[i], imu.specific_force[i + 1], imu.angular_rate[i + 1],
                  imu.t[i + 1] - imu.t[i])
        if i + 1 in idx:
            j = int(np.searchsorted(idx, i + 1))
            f.update_pose(lidar.position[j], lidar.rotation[j])
            states.append((f.nominal.position, f.P.copy(), f.error_estimate.copy()))
    assert len(states) == len(batch.t) == len(idx)
    np.testing.assert_allclose([s[0] for s in states], batch.position, rtol=0, atol=1e-9)
    np.testing.assert_allclose([s[1] for s in states], batch.P_full, rtol=1e-7, atol=1e-15)
    np.testing.assert_allclose([s[2] for s in states], batch.error_estimate, rtol=0, atol=1e-9)


# ---------------------------------------------------------------------------------------
# Building blocks
# ---------------------------------------------------------------------------------------

def test_the_error_block_stays_stationary_without_updates():
    # φ² σ² + σ² (1 − φ²) = σ² for any step: the prior diag(σ²) is the stationary covariance
    sigma = np.r_[np.full(3, 0.2), np.full(3, np.deg2rad(0.3))]
    P = aug.augmented_initial_covariance("kitti_lidar", sigma=sigma)
    F = aug.augmented_transition(np.eye(15), 0.37, 1.5)
    Q = aug.augmented_process_noise(np.zeros((15, 15)), sigma, 0.37, 1.5)
    P_next = F @ P @ F.T + Q
    np.testing.assert_allclose(P_next[aug.IDX_E, aug.IDX_E], np.diag(sigma ** 2), rtol=1e-14)
    assert F[aug.IDX_E, aug.IDX_E][0, 0] == pytest.approx(np.exp(-0.37 / 1.5), rel=1e-15)


def test_observation_matrix_and_residual():
    G = aug.augmented_observation_matrix()
    assert G.shape == (6, 21)
    np.testing.assert_array_equal(G[:, :15], eskf.POSE_G)
    np.testing.assert_array_equal(G[:, aug.IDX_E], np.eye(6))
    e_hat = np.array([0.1, -0.2, 0.05, 1e-3, -2e-3, 5e-4])
    R = np.eye(3)
    r = aug.augmented_residual([1.0, 2.0, 3.0], R, e_hat, [0.9, 2.1, 3.0], R)
    np.testing.assert_allclose(r, eskf.pose_residual([1.0, 2.0, 3.0], R, [0.9, 2.1, 3.0], R) + e_hat)


def test_inflation_factor_is_the_variance_of_a_long_mean():
    # 300 draws of 6 independent unit Gauss–Markov components (τ = 1 s, Δt = 0.1 s, N = 2000):
    # N · Var(mean) → k = (1 + φ)/(1 − φ) ≈ 20. Finite N lowers it by 2φ/(N(1 − φ)²) ≈ 0.5 %;
    # the sample variance of 1800 means has relative standard error √(2/1799) = 3.3 %, so
    # 3 standard errors plus the bias: 10.5 %. A factor 1/(1 − φ) (≈ 10.5) or without the
    # correlation (1) is far outside.
    tau, dt, N = 1.0, 0.1, 2000
    model = GaussMarkovErrors(1.0, np.rad2deg(1.0), tau)
    rng = np.random.default_rng(2024)
    t = np.arange(N) * dt
    means = np.concatenate([model.draw(t, rng).error.mean(axis=0) for _ in range(300)])
    k = cn.inflation_factor(tau, dt)
    phi = np.exp(-dt / tau)
    assert k == pytest.approx((1 + phi) / (1 - phi))
    assert N * means.var(ddof=1) == pytest.approx(k, rel=3 * np.sqrt(2 / (means.size - 1)) + 0.005)


def test_inflation_and_decimation_at_white_noise_change_nothing():
    assert cn.inflation_factor(0.0, 0.1) == 1.0
    assert cn.decimation_step(0.0, 0.1) == 1
    assert cn.decimation_step(0.5, 0.1036) == 10       # one pose per 2τ = 1 s


# ---------------------------------------------------------------------------------------
# Consistency on a seeded Gauss–Markov stream
# ---------------------------------------------------------------------------------------

def test_augmented_filter_is_consistent_where_the_plain_one_is_not():
    # τ = 1 s on cruise, 3 seeds: at each pose time the seed-averaged pose NEES against the
    # 95 % interval of an average of 3 χ²(6) values (chi2_bounds(6, 3))
    res = cn.coloured_noise("cruise", time_constants=(1.0,), seeds=(1, 2, 3), remedies=("plain", "augmented"))
    lo, hi = metrics.chi2_bounds(6, 3)
    assert res.nees_band == (lo, hi)
    assert res.nees_series.shape[:3] == (1, 2, 3)
    np.testing.assert_allclose(res.nees_series.mean(axis=-1), res.nees_pose, rtol=1e-12)
    (plain_below, plain_above), (aug_below, aug_above) = res.band_shares[0]
    assert res.verdict(1.0, "augmented") == "consistent" and max(aug_below, aug_above) <= cn.VERDICT_SHARE
    assert plain_above > 0.9                      # above the band at nearly every time
    assert res.verdict(1.0, "plain") == "overconfident"
    # and the augmented filter is the more accurate on every seed
    assert (res.ape_position[0, 1] < res.ape_position[0, 0]).all()


def test_the_verdict_is_taken_per_time_and_names_the_side():
    # a consistent filter's NEES (χ²(6) draws, independent over seeds), then the same scaled
    # by 0.6 (underconfident) and 1.6 (overconfident); the seed-and-time means of the scaled
    # ones (3.6, 9.6) lie inside or at the edge of chi2_bounds(6, 5) = [3.36, 9.40], which is
    # why that interval is not used for the means
    res = cn.coloured_noise("cruise", time_constants=(0.0,), seeds=(1, 2, 3, 4, 5), remedies=("plain",))
    rng = np.random.default_rng(4)
    draws = rng.chisquare(6, size=(1, 3, 5, 4000))
    fake = dataclasses.replace(res, remedies=("plain", "inflated_R", "augmented"),
                               nees_series=draws * np.array([1.0, 0.6, 1.6])[None, :, None, None],
                               nees_pose=draws.mean(axis=-1) * np.array([1.0, 0.6, 1.6])[None, :, None])
    shares = fake.band_shares[0]
    np.testing.assert_allclose(shares[0], [0.025, 0.025], atol=0.01)
    assert [fake.verdict(0.0, r) for r in fake.remedies] == ["consistent", "underconfident", "overconfident"]
    lo, hi = fake.nees_band
    assert lo < fake.nees_mean[0, 1] and fake.nees_mean[0, 2] < hi + 0.5


def test_remedies_agree_on_white_noise_and_are_deterministic(cruise):
    white = cn.coloured_noise(cruise, time_constants=(0.0,), seeds=(4,))
    for name in ("ape_position", "ape_attitude_deg", "nees_pose"):
        values = getattr(white, name)[0, :, 0]
        assert np.all(values == values[0]), name
    first = cn.coloured_noise(cruise, time_constants=(0.5,), seeds=(2,))
    again = cn.coloured_noise(cruise, time_constants=(0.5,), seeds=(2,))
    for name in ("raw_position", "raw_attitude_deg", "ape_position", "ape_attitude_deg", "nees_pose"):
        assert np.array_equal(getattr(first, name), getattr(again, name)), name
    assert len(set(first.nees_pose[0, :, 0])) == 4     # at τ > 0 the four filters differ


def test_table_says_what_is_real_and_simulated():
    res = cn.coloured_noise("cruise", time_constants=(0.0, 0.5), seeds=(1,), remedies=("plain", "fewer_observations"))
    text = res.table()
    assert "real: KITTI IMU" in text and "simulated: the lidar pose errors" in text
    assert "1 pose in 10" in text and "raw simulated poses" in text
    assert res.spread("position_ratio", 0.5, "plain").n == 1


# ---------------------------------------------------------------------------------------
# Figure
# ---------------------------------------------------------------------------------------

def _fake_result(T=2, M=2, S=3):
    rng = np.random.default_rng(0)
    return SimpleNamespace(time_constants=(0.0, 1.0)[:T], remedies=cn.REMEDIES[:M],
                           nees_pose=rng.uniform(2, 50, (T, M, S)), position_ratio=rng.uniform(0.3, 1.2, (T, M, S)),
                           nees_band=metrics.chi2_bounds(6, S))


def test_figure_draws_each_remedy_over_the_band_on_a_log_scale():
    fig = plot_coloured_noise(_fake_result())
    acc, nees = fig.axes
    assert nees.get_yscale() == "log"
    assert [t.get_text() for t in nees.get_xticklabels()] == ["white", "1 s"]
    assert len(nees.containers) == 2 and len(acc.containers) == 2      # one errorbar set per remedy
    one = plot_coloured_noise(_fake_result(), accuracy=False)
    assert len(one.axes) == 1


def test_figure_rejects_what_it_cannot_draw():
    with pytest.raises(ValueError, match="missing 'nees_pose'"):
        plot_coloured_noise(SimpleNamespace(time_constants=(0.0,), remedies=("plain",)))
    bad = _fake_result()
    bad.nees_pose = bad.nees_pose[:, :1]
    with pytest.raises(ValueError, match="nees_pose must have shape"):
        plot_coloured_noise(bad)


# ---------------------------------------------------------------------------------------
# Validation
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("kwargs, match", [
    ({"time_constant": 0.0}, "time_constant"),
    ({"time_constant": -1.0}, "time_constant"),
    ({"time_constant": "1"}, "time_constant"),
    ({"time_constant": 1.0, "sigma": [0.2, 0.2, 0.2]}, "sigma"),
    ({"time_constant": 1.0, "sigma": [0.2, 0.2, 0.0, 0.01, 0.01, 0.01]}, "sigma"),
    ({"time_constant": 1.0, "white_std": [-0.1, 0, 0, 0, 0, 0]}, "white_std"),
    ({"sigma": [0.2] * 6}, "only with a time_constant"),
    ({"time_constant": 1.0, "P0": np.ones((15, 14))}, "P0"),
])
def test_run_rejects_bad_arguments(cruise, cfg, kwargs, match):
    k0, s0 = cruise.initial_state()
    with pytest.raises(ValueError, match=match):
        aug.run(cruise.imu, s0, cfg, cruise.gravity, lidar=cruise.lidar, start=k0, **kwargs)


def test_run_needs_lidar_poses(cruise, cfg):
    k0, s0 = cruise.initial_state()
    with pytest.raises(ValueError, match="lidar"):
        aug.run(cruise.imu, s0, cfg, cruise.gravity, lidar=None, start=k0, time_constant=1.0)
    with pytest.raises(ValueError, match="lidar"):
        aug.run(cruise.imu, s0, cfg, cruise.gravity, lidar=SimpleNamespace(t=[1.0]), start=k0)


def test_building_blocks_reject_bad_arguments(cruise, cfg):
    with pytest.raises(ValueError, match="T"):
        aug.gauss_markov_decay(0.0, 1.0)
    with pytest.raises(ValueError, match="F"):
        aug.augmented_transition(np.eye(14), 0.1, 1.0)
    with pytest.raises(ValueError, match="e_hat"):
        aug.augmented_residual(np.zeros(3), np.eye(3), np.zeros(5), np.zeros(3), np.eye(3))
    with pytest.raises(ValueError, match="time_constant"):
        aug.AugmentedESKF(cfg, cruise.initial_state()[1], cruise.gravity, time_constant=-2.0)


@pytest.mark.parametrize("kwargs, match", [
    ({"remedies": ("magic",)}, "remedy"),
    ({"remedies": ()}, "remedies"),
    ({"time_constants": (-1.0,)}, "time_constants"),
    ({"time_constants": (1.0, 1.0)}, "repeat"),
    ({"time_constants": ()}, "time_constants"),
    ({"seeds": ()}, "seeds"),
    ({"seeds": (-3,)}, "seed"),
    ({"excerpt": "nowhere"}, "unknown KITTI excerpt"),
    ({"excerpt": 42}, "excerpt"),
])
def test_experiment_rejects_bad_arguments(kwargs, match):
    with pytest.raises(ValueError, match=match):
        cn.coloured_noise(**kwargs)


def test_result_and_helpers_reject_bad_arguments():
    with pytest.raises(ValueError, match="remedy"):
        cn.remedy_label("magic", 1.0, 0.1)
    with pytest.raises(ValueError, match="interval"):
        cn.inflation_factor(1.0, 0.0)
    res = cn.coloured_noise("cruise", time_constants=(0.0,), seeds=(1,), remedies=("plain",))
    with pytest.raises(ValueError, match="figure"):
        res.spread("speed", 0.0, "plain")
    with pytest.raises(ValueError, match="time_constant"):
        res.verdict(2.0, "plain")
    with pytest.raises(ValueError, match="remedy"):
        res.verdict(0.0, "augmented")
