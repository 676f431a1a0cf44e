"""Observation streams: each sensor with its own noise, kind and extrinsics, in every error-state filter.

The measurement model of :mod:`kalman_course.filters.eskf_streams` is checked against finite
differences; a plain stream reproduces the filters' own ``lidar=``/``gnss=`` paths bit for bit;
a lever arm and a mounting rotation that the simulated sensor really has are worth having
(lower error over seeds, a truth the filter does not share); zero noise means known exactly;
bad streams and output times are refused by name.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.core.numdiff import numerical_jacobian
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.data import load_kitti
from kalman_course.filters import eskf, eskf_augmented, eskf_relative
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.eskf_streams import STREAM_KINDS, ObservationStream

LEVER_ARM = np.array([1.2, -0.6, 0.9])           # an antenna 1.5 m from the IMU, not on an axis
R_BS = so3.exp([0.02, -0.35, 1.4])               # a camera turned 80° about z and tilted


def _excerpt(seconds: float = 20.0):
    ex = load_kitti("turns")
    k0, s0 = ex.initial_state()
    return ex, k0, s0, float(ex.imu.t[k0] + seconds)


def _sensor_reports(ex, times, seed: int, lever=None, R_bs=None, sigma_p=0.3, sigma_th=0.01, pose=False):
    """Simulated reports of a sensor mounted at (lever, R_bs) on the true body: p + R l, R R_bs, with noise."""
    rng = np.random.default_rng(seed)
    truth = ex.truth.interpolate(times)
    lever = np.zeros(3) if lever is None else lever
    p = truth.position + truth.rotation @ lever + rng.normal(scale=sigma_p, size=(len(times), 3))
    if not pose:
        return PositionObservations(times, p)
    R = truth.rotation @ (np.eye(3) if R_bs is None else R_bs)
    R = R @ so3.exp(rng.normal(scale=sigma_th, size=(len(times), 3)))
    return PoseObservations(times, p, R)


# ---------------------------------------------------------------------------------------
# the measurement model
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("kind", ["position", "pose"])
@pytest.mark.parametrize("mounted", [False, True], ids=["at the origin", "lever arm and R_bs"])
def test_jacobian_matches_finite_differences(kind, mounted):
    rng = np.random.default_rng(4)
    p, R = rng.normal(size=3) * 20, so3.exp(rng.normal(size=3))
    R_bs = R_BS if mounted and kind == "pose" else None
    # a report that fits the true attitude: G is the residual's first-order model there (a
    # rotation residual r ≠ 0 would add J_r⁻¹(r), which the filters' G leaves out)
    reports = PoseObservations([0.0], [p + 0.3], [R if R_bs is None else R @ R_bs])
    stream = ObservationStream(reports, np.full(STREAM_KINDS[kind], 0.1), kind=kind,
                               lever_arm=LEVER_ARM if mounted else None, rotation=R_bs)

    def residual(dx):      # the nominal pose is the true one with the error dx = [δp, δθ] added
        return stream.residual(0, p + dx[:3], R @ so3.exp(dx[3:]))

    np.testing.assert_allclose(stream.jacobian(R), numerical_jacobian(residual, np.zeros(6)), atol=1e-7)
    if not mounted:
        G = eskf.POSE_G if kind == "pose" else eskf.POSITION_G
        np.testing.assert_array_equal(eskf._stream_jacobian(stream, R), G)


def test_the_lever_arm_moves_the_predicted_position_by_R_l():
    R = so3.exp([0.0, 0.0, np.pi / 2])             # body x points north (nav y)
    stream = ObservationStream(PositionObservations([0.0], [[0.0, 0.0, 0.0]]), 0.5, lever_arm=[1.0, 0.0, 0.0])
    np.testing.assert_allclose(stream.residual(0, np.zeros(3), R), [0.0, 1.0, 0.0], atol=1e-15)


# ---------------------------------------------------------------------------------------
# a plain stream is the filters' own lidar / GNSS path
# ---------------------------------------------------------------------------------------

def _same(a, b):
    for name in ("t", "position", "velocity", "rotation", "P", "updated"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_plain_streams_equal_the_lidar_and_gnss_arguments_exactly():
    ex, k0, s0, t_end = _excerpt(8.0)
    cfg = load_config("kitti_lidar")
    gnss = ex.gnss.observations()
    ref = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, gnss=gnss, start=k0, t_end=t_end)
    streams = [ObservationStream(ex.lidar, cfg.lidar_std, name="camera"),
               ObservationStream(gnss, cfg.gnss_std, name="antenna")]
    res = eskf.run(ex.imu, s0, cfg, ex.gravity, streams=streams, start=k0, t_end=t_end)
    _same(res, ref)
    assert ref.sources[:3] == ["lidar"] * 3 and set(ref.sources) == {"lidar", "gnss"}
    assert set(res.sources) == {"camera", "antenna"} and len(res.sources) == len(ref.sources)


def test_augmented_and_relative_filters_take_streams_like_the_eskf():
    ex, k0, s0, t_end = _excerpt(8.0)
    cfg = load_config("kitti_lidar")
    antenna = ObservationStream(_sensor_reports(ex, ex.gnss.t[(ex.gnss.t > ex.imu.t[k0]) & (ex.gnss.t < t_end)], 1,
                                                LEVER_ARM), 0.3, lever_arm=LEVER_ARM, name="antenna")
    ref = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, streams=[antenna], start=k0, t_end=t_end)
    aug = eskf_augmented.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, streams=[antenna], start=k0,
                             t_end=t_end)
    np.testing.assert_allclose(aug.position, ref.position, atol=1e-9)
    np.testing.assert_allclose(aug.P, ref.P, rtol=1e-9, atol=1e-15)
    assert aug.sources == ref.sources and "antenna" in ref.sources
    # with augmentation the stream still updates (white errors, no ê)
    aug_gm = eskf_augmented.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, streams=[antenna], start=k0,
                                t_end=t_end, time_constant=2.0)
    assert aug_gm.sources.count("antenna") == ref.sources.count("antenna") > 0

    # the relative filter: GNSS given as gnss= or as a plain stream is the same run
    vo = ex.lidar.select((ex.lidar.t > ex.imu.t[k0]) & (ex.lidar.t < t_end))
    gnss = ex.gnss.observations()
    rel = eskf_relative.run_relative(ex.imu, s0, cfg, ex.gravity, vo=vo, relative_std=(0.05, 0.002), gnss=gnss,
                                     start=k0, t_end=t_end)
    rel_s = eskf_relative.run_relative(ex.imu, s0, cfg, ex.gravity, vo=vo, relative_std=(0.05, 0.002),
                                       streams=[ObservationStream(gnss, cfg.gnss_std, name="fixes")],
                                       start=k0, t_end=t_end)
    _same(rel_s, rel)
    assert set(rel.sources) == {"gnss"} and set(rel_s.sources) == {"fixes"}


# ---------------------------------------------------------------------------------------
# extrinsics the sensor really has are worth modelling (direction asserted over seeds)
# ---------------------------------------------------------------------------------------

def _ate(ex, res):
    truth = ex.truth.interpolate(res.t)
    return float(np.sqrt(np.mean(np.sum((res.position - truth.position) ** 2, axis=1))))


def test_a_modelled_lever_arm_beats_ignoring_it_on_every_seed():
    ex, k0, s0, t_end = _excerpt(30.0)
    cfg = load_config("kitti_lidar")
    times = np.arange(ex.imu.t[k0] + 0.05, t_end, 0.1)
    for seed in (1, 2, 3):
        reports = _sensor_reports(ex, times, seed, LEVER_ARM, sigma_p=0.1)
        with_arm = eskf.run(ex.imu, s0, cfg, ex.gravity, start=k0, t_end=t_end,
                            streams=[ObservationStream(reports, 0.1, lever_arm=LEVER_ARM, name="antenna")])
        without = eskf.run(ex.imu, s0, cfg, ex.gravity, start=k0, t_end=t_end,
                           streams=[ObservationStream(reports, 0.1, name="antenna")])
        assert _ate(ex, with_arm) < 0.5 * _ate(ex, without), seed


def test_a_modelled_mounting_rotation_beats_ignoring_it_on_every_seed():
    ex, k0, s0, t_end = _excerpt(20.0)
    cfg = load_config("kitti_lidar")
    times = np.arange(ex.imu.t[k0] + 0.05, t_end, 0.1)
    std = np.r_[np.full(3, 0.1), np.full(3, 0.005)]
    for seed in (1, 2, 3):
        reports = _sensor_reports(ex, times, seed, LEVER_ARM, R_BS, 0.1, 0.005, pose=True)
        runs = [eskf.run(ex.imu, s0, cfg, ex.gravity, start=k0, t_end=t_end,
                         streams=[ObservationStream(reports, std, name="camera", **mounting)])
                for mounting in (dict(lever_arm=LEVER_ARM, rotation=R_BS), {})]
        attitude = []
        for res in runs:
            truth = ex.truth.interpolate(res.t)
            error = so3.log(np.swapaxes(truth.rotation, 1, 2) @ res.rotation)
            attitude.append(np.degrees(np.median(np.linalg.norm(error, axis=1))))
        # modelled, the filter estimates the body's attitude (not the camera's) and its position
        assert attitude[0] < 1.0 < 10.0 < attitude[1], (seed, attitude)
        assert _ate(ex, runs[0]) < 0.5 * _ate(ex, runs[1]), seed


def test_positions_only_lidar_with_its_own_sigma():
    # the Toronto data's lidar: positions, no attitude, σ of its own
    ex, k0, s0, t_end = _excerpt(20.0)
    cfg = load_config("kitti_lidar")
    positions = PositionObservations(ex.lidar.t, ex.lidar.position)
    res = eskf.run(ex.imu, s0, cfg, ex.gravity, start=k0, t_end=t_end,
                   streams=[ObservationStream(positions, cfg.lidar_std[:3], name="lidar positions")])
    assert res.updated.all() and all(y.shape == (3,) for y in res.innovation)
    assert _ate(ex, res) < 1.0


def test_zero_noise_means_known_exactly():
    ex, k0, s0, t_end = _excerpt(3.0)
    times = np.array([ex.imu.t[k0] + 1.0])
    reports = _sensor_reports(ex, times, 5)
    res = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=t_end,
                   streams=[ObservationStream(reports, 0.0, name="surveyed point")])
    np.testing.assert_allclose(res.position[0], reports.position[0], atol=1e-9)
    assert np.abs(res.P[0][:3, :3]).max() < 1e-12


# ---------------------------------------------------------------------------------------
# output times
# ---------------------------------------------------------------------------------------

def test_output_times_at_the_start_give_the_initial_state_and_none_is_dropped_silently():
    ex, k0, s0, t_end = _excerpt(2.0)
    t0 = float(ex.imu.t[k0])
    ask = np.array([t0, t0 + 0.5, t0 + 1.0])
    res = eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=t_end, output_times=ask)
    np.testing.assert_array_equal(res.t, ask)
    np.testing.assert_array_equal(res.position[0], s0.position)
    np.testing.assert_array_equal(res.P[0], eskf.initial_covariance(load_config("kitti_lidar")))
    wide = np.r_[t0 - 1.0, ask, t_end + 1.0]
    for run in (eskf.run, eskf_augmented.run):
        kwargs = {"lidar": ex.lidar} if run is eskf_augmented.run else {}
        with pytest.warns(eskf.OutputTimesWarning, match=r"2 of 5 output_times lie outside the run"):
            res = run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=t_end, output_times=wide, **kwargs)
        with warnings.catch_warnings():
            warnings.simplefilter("error")
            clipped = run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=t_end, output_times=wide,
                          clip_output_times=True, **kwargs)
        np.testing.assert_array_equal(clipped.t, res.t)
    with pytest.raises(ValueError, match=r"output_times must be strictly increasing.*output_times\[2\]"):
        eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=t_end, output_times=[t0 + 1, t0 + 2, t0 + 2])
    with pytest.raises(ValueError, match=r"clip_output_times"):
        eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, start=k0, t_end=t_end, output_times=ask,
                 clip_output_times="yes")


# ---------------------------------------------------------------------------------------
# bad streams are refused by name
# ---------------------------------------------------------------------------------------

POS = PositionObservations([0.0, 1.0], np.zeros((2, 3)))
POSE = PoseObservations([0.0, 1.0], np.zeros((2, 3)), np.stack([np.eye(3)] * 2))


@pytest.mark.parametrize("kwargs, message", [
    (dict(observations=POS, noise=[0.1, 0.1]), r"gps\.noise must be 3 standard deviations"),
    (dict(observations=POSE, noise=[0.1] * 3), r"gps\.noise must be 6 standard deviations"),
    (dict(observations=POS, noise=-0.1), r"gps\.noise must be a finite non-negative number"),
    (dict(observations=POS, noise=[0.1, -0.1, 0.1]), r"gps\.noise: standard deviations must be ≥ 0"),
    (dict(observations=POS, noise=[[1.0, 2.0, 0], [2.0, 1.0, 0], [0, 0, 1.0]]), r"gps\.noise"),
    (dict(observations=POS, noise=[0.1, np.nan, 0.1]), r"gps\.noise"),
    (dict(observations=POS, noise=0.1, kind="pose"), r"gps: a pose stream needs observations with t, position "
                                                     r"and rotation"),
    (dict(observations=POS, noise=0.1, kind="velocity"), r"gps\.kind must be 'position' or 'pose'"),
    (dict(observations=POS, noise=0.1, lever_arm=[1.0, 2.0]), r"gps\.lever_arm"),
    (dict(observations=POS, noise=0.1, rotation=np.eye(3)), r"gps\.rotation \(R_bs\) only applies to a pose"),
    (dict(observations=POSE, noise=[0.1] * 6, rotation=-np.eye(3)), r"gps\.rotation"),
    (dict(observations=np.zeros((2, 3)), noise=0.1), r"gps: a position stream needs observations with t and "
                                                     r"position"),
])
def test_a_bad_stream_is_refused_naming_the_field(kwargs, message):
    with pytest.raises(ValueError, match=message):
        ObservationStream(name="gps", **kwargs)


def test_bad_stream_lists_are_refused_by_the_filter():
    ex, k0, s0, t_end = _excerpt(1.0)
    stream = ObservationStream(POS, 0.1, name="gps")
    for streams, message in ((stream, r"streams must be a list of ObservationStream"),
                             ([stream, POS], r"streams\[1\] must be an ObservationStream"),
                             ([stream, stream], r"repeated: gps"),
                             ([ObservationStream(POS, 0.1, name="gnss")], r"repeated: gnss")):
        with pytest.raises(ValueError, match=message):
            eskf.run(ex.imu, s0, "kitti_lidar", ex.gravity, gnss=ex.gnss.observations(), start=k0,
                     t_end=t_end, streams=streams)


def test_the_step_filter_updates_from_a_stream_as_the_batch_runner_does():
    ex, k0, s0, t_end = _excerpt(1.0)
    cfg = load_config("kitti_lidar")
    t_imu = ex.imu.t[k0:k0 + 11]
    reports = _sensor_reports(ex, t_imu[[10]], 3, LEVER_ARM, R_BS, pose=True)
    stream = ObservationStream(reports, np.r_[np.full(3, 0.2), np.full(3, 0.01)], lever_arm=LEVER_ARM,
                               rotation=R_BS, name="camera")
    flt = eskf.ESKF(cfg, s0, ex.gravity)
    for i in range(k0, k0 + 10):
        flt.predict(ex.imu.specific_force[i], ex.imu.angular_rate[i], ex.imu.specific_force[i + 1],
                    ex.imu.angular_rate[i + 1], ex.imu.t[i + 1] - ex.imu.t[i],
                    interpolated=bool(ex.imu.interpolated[i] or ex.imu.interpolated[i + 1]))
    flt.update_stream(stream, 0)
    res = eskf.run(ex.imu, s0, cfg, ex.gravity, streams=[stream], start=k0, t_end=t_imu[-1])
    np.testing.assert_allclose(res.position[-1], flt.nominal.position, atol=1e-9)
    np.testing.assert_allclose(res.P[-1], flt.P, rtol=1e-7, atol=1e-14)
    for bad, message in ((1, r"k must be the index of one of camera's 1 reports"),
                         (True, r"k must be the index"), (0.0, r"k must be the index")):
        with pytest.raises(ValueError, match=message):
            flt.update_stream(stream, bad)
    with pytest.raises(ValueError, match=r"stream must be an ObservationStream"):
        flt.update_stream(reports, 0)
