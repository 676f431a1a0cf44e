"""Real visual odometry fused with the IMU: the relative-pose ESKF (stochastic cloning), the
chapter's runs on KITTI sequence 00 and their figures."""

import matplotlib.pyplot as plt
import numpy as np
import pytest

from kalman_course.chapters import visual_odometry as vo_chapter
from kalman_course.core import so3
from kalman_course.core.imu import NavState
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.data import imu_trajectory, load_kitti
from kalman_course.evaluation.metrics import chi2_bounds, nees
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.eskf_relative import (clone_covariance, relative_motion, relative_pose_jacobian,
                                                 relative_pose_residual, run_relative)
from kalman_course.plotting import plot_drift_by_length, plot_vo_tracks

POSE = [0, 1, 2, 6, 7, 8]


# ---------------------------------------------------------------------------------------
# helpers: a synthetic drive with exact truth and VO increments with known white noise
# ---------------------------------------------------------------------------------------

def matched_config(sc):
    """The chapter's configuration with the simulator's own IMU noise (a correctly tuned filter)."""
    return load_config("kitti_gnss").replace(
        process__accel_noise=sc.accel_noise_density, process__gyro_noise=sc.gyro_noise_density,
        process__accel_bias_noise=sc.accel_bias_density, process__gyro_bias_noise=sc.gyro_bias_density)


def noisy_vo(sc, rng, sigma_p, sigma_theta, every=10):
    """VO poses every ``every`` IMU samples whose increments are the true ones plus white noise:
    Δp_m = Δp + σ_p n_p, ΔR_m = ΔR Exp(σ_θ n_θ), chained from the true first pose."""
    idx = np.arange(0, len(sc.t), every)
    p, R = sc.position[idx], sc.rotation[idx]
    ps, Rs = [p[0]], [R[0]]
    for k in range(1, len(idx)):
        dp, dR = relative_motion(p[k - 1], R[k - 1], p[k], R[k])
        dp = dp + sigma_p * rng.standard_normal(3)
        dR = dR @ so3.exp(sigma_theta * rng.standard_normal(3))
        ps.append(ps[-1] + Rs[-1] @ dp)
        Rs.append(Rs[-1] @ dR)
    return PoseObservations(sc.t[idx], np.array(ps), so3.orthonormalise(np.array(Rs)))


def _nav(sc):
    """The true state at the first sample."""
    return NavState(sc.position[0], sc.velocity[0], sc.rotation[0])


def pose_error(res, sc):
    k = np.searchsorted(sc.t, res.t - 1e-9)
    return np.concatenate([res.position - sc.position[k],
                           so3.log(np.swapaxes(sc.rotation[k], 1, 2) @ res.rotation)], axis=1)


# ---------------------------------------------------------------------------------------
# the relative pose observation
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_relative_jacobian_matches_finite_differences(seed):
    rng = np.random.default_rng(seed)
    p_c, p = 5.0 * rng.standard_normal(3), 5.0 * rng.standard_normal(3)
    R_c, R = so3.exp(rng.standard_normal(3)), so3.exp(rng.standard_normal(3))
    dp_m, dR_m = relative_motion(p_c, R_c, p, R)          # a noise-free measurement

    def residual(dx):
        # nominal = true ⊕ error: p̌ = p + δp, Ř = R Exp(δθ), likewise for the clone
        return relative_pose_residual(p_c + dx[15:18], R_c @ so3.exp(dx[18:21]), p + dx[0:3],
                                      R @ so3.exp(dx[6:9]), dp_m, dR_m)

    G = relative_pose_jacobian(R_c, *relative_motion(p_c, R_c, p, R))
    h = 1e-6
    numeric = np.column_stack([(residual(h * e) - residual(-h * e)) / (2 * h) for e in np.eye(21)])
    np.testing.assert_allclose(G, numeric, atol=1e-8)
    # velocity and biases do not enter one increment
    assert np.all(G[:, 3:6] == 0.0) and np.all(G[:, 9:15] == 0.0)


def test_increments_do_not_see_a_fixed_transform_of_the_vo_frame():
    # the VO's map differs from the navigation frame by a fixed transform: its increments do not
    rng = np.random.default_rng(4)
    p0, p1 = rng.standard_normal(3), rng.standard_normal(3)
    R0, R1 = so3.exp(rng.standard_normal(3)), so3.exp(rng.standard_normal(3))
    C, c = so3.exp(np.array([0.3, -0.1, 2.0])), np.array([100.0, -20.0, 3.0])
    a = relative_motion(p0, R0, p1, R1)
    b = relative_motion(C @ p0 + c, C @ R0, C @ p1 + c, C @ R1)
    np.testing.assert_allclose(a[0], b[0], atol=1e-12)
    np.testing.assert_allclose(a[1], b[1], atol=1e-12)


def test_cloning_copies_the_pose_block_and_its_correlations():
    rng = np.random.default_rng(5)
    A = rng.standard_normal((15, 15))
    P = A @ A.T + np.eye(15)
    Pa = clone_covariance(P)
    np.testing.assert_array_equal(Pa[:15, :15], P)
    np.testing.assert_array_equal(Pa[15:, 15:], P[np.ix_(POSE, POSE)])
    np.testing.assert_array_equal(Pa[:15, 15:], P[:, POSE])
    np.testing.assert_array_equal(Pa, Pa.T)
    # the clone is the same random variable as the pose: the difference has zero variance
    D = np.zeros((6, 21))
    D[:, POSE] = np.eye(6)
    D[:, 15:] = -np.eye(6)
    np.testing.assert_allclose(D @ Pa @ D.T, 0.0, atol=1e-12)


def test_the_update_resets_both_attitudes_with_their_own_jacobian():
    # the augmented update ends with P ← G_r P G_rᵀ, G_r the identity except J_l(δθ̂) on the
    # current attitude (rows 6:9) and J_l(δθ̂_c) on the clone's (18:21); built here explicitly
    from kalman_course.core.linalg import joseph_update
    from kalman_course.filters.eskf_relative import _correct_augmented

    rng = np.random.default_rng(8)
    A = rng.standard_normal((15, 15))
    P = clone_covariance(0.01 * (A @ A.T) + 0.01 * np.eye(15))
    P[:15, :15] += 0.05 * np.eye(15)                 # the state has moved on since the clone
    x = eskf.NominalState(np.zeros(3), np.ones(3), np.eye(3))
    clone = (np.zeros(3), np.eye(3))
    G = relative_pose_jacobian(np.eye(3), np.array([1.0, 0.0, 0.0]), np.eye(3))
    y = np.array([0.1, -0.2, 0.05, 0.02, -0.03, 0.04])
    R = np.diag([1e-3] * 3 + [1e-4] * 3)
    _, _, P_post, S = _correct_augmented(x, clone, P, y, G, R, exact_reset=True)
    K = P @ G.T @ np.linalg.inv(G @ P @ G.T + R)
    dx = K @ y
    Gr = np.eye(21)
    Gr[6:9, 6:9] = so3.left_jacobian(dx[6:9])
    Gr[18:21, 18:21] = so3.left_jacobian(dx[18:21])
    np.testing.assert_allclose(P_post, Gr @ joseph_update(P, K, G, R) @ Gr.T, atol=1e-12)
    np.testing.assert_allclose(S, G @ P @ G.T + R, atol=1e-12)
    assert np.abs(dx[18:21]).max() > 1e-3                # the clone's reset is not trivially I


# ---------------------------------------------------------------------------------------
# the filter on a synthetic drive
# ---------------------------------------------------------------------------------------

def test_exact_increments_and_a_clean_imu_reproduce_the_truth():
    sc = imu_trajectory(1, duration=30.0)
    vo = noisy_vo(sc, np.random.default_rng(0), 0.0, 0.0)
    res = run_relative(sc.imu_clean, _nav(sc), matched_config(sc), sc.gravity, vo=vo, relative_std=(0.01, 1e-3))
    e = pose_error(res, sc)
    assert len(res.t) == len(vo.t) - 1                           # every VO frame after the start
    assert not res.updated[0] and res.updated[1:].all()          # the first frame only starts the chain
    assert len(res.innovation) == len(res.t) - 1
    assert np.abs(e).max() < 1e-8


@pytest.mark.parametrize("with_gnss", [False, True])
def test_the_relative_filter_is_consistent_over_seeded_runs(with_gnss):
    # n independent runs of 20 s, each starting from an initial error drawn from P0, with the
    # simulator's own IMU noise in the filter and VO increments with the R the filter uses.
    # At the last update each run's pose NEES is χ²(6) if the filter is consistent, so their
    # mean times n is χ²(6n): chi2_bounds(6, n, 0.99) is the 99 % interval of the mean. With
    # GNSS fixes (σ 1 m) half-way between VO frames the clone is corrected by the GNSS updates
    # too, through its cross-covariance.
    n = 24
    final = []
    for i in range(n):
        rng = np.random.default_rng(200 + i)
        cfg0 = load_config("kitti_gnss")
        prior = cfg0.prior_std
        ba0, bw0 = prior[9:12] * rng.standard_normal(3), prior[12:15] * rng.standard_normal(3)
        dx0 = prior * rng.standard_normal(15)
        sc = imu_trajectory(200 + i, duration=20.0, accel_bias0=ba0, gyro_bias0=bw0)
        vo = noisy_vo(sc, rng, 0.01, np.deg2rad(0.05))
        gnss = None
        if with_gnss:
            g = np.arange(55, len(sc.t), 100)                  # 1 Hz, 0.05 s off the VO frames
            gnss = PositionObservations(sc.t[g], sc.position[g] + 1.0 * rng.standard_normal((len(g), 3)))
        x0 = eskf.NominalState(sc.position[0] + dx0[0:3], sc.velocity[0] + dx0[3:6],
                               sc.rotation[0] @ so3.exp(dx0[6:9]), ba0 + dx0[9:12], bw0 + dx0[12:15])
        res = run_relative(sc.imu, x0, matched_config(sc), sc.gravity, vo=vo, gnss=gnss,
                           relative_std=(0.01, np.deg2rad(0.05)))
        if with_gnss:
            assert len(res.gnss_innovation) == len(gnss.t) and len(res.t) == len(vo.t) - 1 + len(gnss.t)
        final.append(nees(pose_error(res, sc)[-1], res.P[-1][np.ix_(POSE, POSE)]))
    lo, hi = chi2_bounds(6, n, 0.99)
    assert lo < np.mean(final) < hi, (np.mean(final), lo, hi)


def test_tuning_by_the_nis_recovers_a_known_increment_noise():
    # increments with σ_p = 1 cm and σ_θ = 0.05° per axis; the tuner starts 3× and 0.1× off.
    # One 60 s run has 600 increments: the sample median of χ²(1) values then has a relative
    # standard error of ≈ 1.06 / (0.455 √600) ≈ 9.5 %, i.e. ≈ 5 % on σ (a square root);
    # with the tuner's own 10 % stopping tolerance on the median (5 % on σ), 3 SE + 5 % ≈ 20 %.
    sc = imu_trajectory(5, duration=60.0)
    vo = noisy_vo(sc, np.random.default_rng(5), 0.01, np.deg2rad(0.05))
    cfg = matched_config(sc)

    def run(std):
        return run_relative(sc.imu, _nav(sc), cfg, sc.gravity, vo=vo, relative_std=std)

    tuned = vo_chapter.tune_std(run, (0.03,) * 3 + (np.deg2rad(0.005),) * 3, vo_chapter.RELATIVE_BLOCKS)
    assert tuned.converged
    np.testing.assert_allclose(tuned.std[:3], 0.01, rtol=0.2)
    np.testing.assert_allclose(tuned.std[3:], np.deg2rad(0.05), rtol=0.2)
    np.testing.assert_allclose(tuned.target, 0.455, atol=1e-3)
    assert tuned.history[0][0] == (0.03,) * 3 + (np.deg2rad(0.005),) * 3


def test_bad_input_is_named():
    sc = imu_trajectory(1, duration=2.0)
    vo = noisy_vo(sc, np.random.default_rng(0), 0.0, 0.0)
    with pytest.raises(ValueError, match="relative_std must be 2"):
        run_relative(sc.imu, _nav(sc), "kitti_gnss", sc.gravity, vo=vo, relative_std=(0.01, 0.0, 1.0))
    with pytest.raises(ValueError, match="vo must be a PoseObservations"):
        run_relative(sc.imu, _nav(sc), "kitti_gnss", sc.gravity, vo=None, relative_std=(0.01, 1e-3))
    with pytest.raises(ValueError, match="blocks must be"):
        vo_chapter.tune_std(lambda std: None, (0.01,), [])


# ---------------------------------------------------------------------------------------
# the chapter on KITTI sequence 00 (real VO and IMU)
# ---------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def seq00():
    return load_kitti("seq00")


@pytest.fixture(scope="module")
def slice_comparison(seq00):
    # the first 120 s, R tuned on the first 30 s: every row, quickly
    return vo_chapter.compare(seq00, t_end=120.0, calibration_s=30.0)


def test_setup_anchors_the_vo_by_one_pose_and_keeps_its_increments(seq00):
    s = vo_chapter.setup(seq00, "S-PTAM", t_end=60.0)
    imu, truth, slam = seq00.imu, seq00.truth, seq00.sptam
    assert imu.t[s.start] < truth.t[s.first] <= imu.t[s.start + 1]   # the first frame the IMU covers
    assert truth.t[s.first - 1] < imu.t[0]
    np.testing.assert_allclose(s.vo.position[0], truth.position[s.first], atol=1e-9)
    np.testing.assert_allclose(s.vo.rotation[0], truth.rotation[s.first], atol=1e-9)
    for k in (1, 100, len(s.vo.t) - 1):       # a rigid move: every increment is the VO's own
        a = relative_motion(s.vo.position[k - 1], s.vo.rotation[k - 1], s.vo.position[k], s.vo.rotation[k])
        j = s.first + k
        b = relative_motion(slam.position[j - 1], slam.rotation[j - 1], slam.position[j], slam.rotation[j])
        np.testing.assert_allclose(a[0], b[0], atol=1e-9)
        np.testing.assert_allclose(a[1], b[1], atol=1e-9)
    assert s.t[-1] <= 60.0 < truth.t[s.last + 1] and s.t_stop >= s.t_end
    np.testing.assert_allclose(s.initial.position, truth.state_at(imu.t[s.start]).position)


def test_the_comparison_on_a_slice_has_every_row_and_a_labelled_table(slice_comparison):
    c = slice_comparison
    methods = [r.method for r in c.rows]
    assert methods == list(vo_chapter.METHODS)[:4] * 2 + ["imu_gnss"]
    for r in c.rows:
        assert r.t.shape == c.t.shape and np.isfinite(r.score.ate)
        assert np.isnan(r.score.nees) == (r.method == "vo")
        assert r.score.drift.n_segments > 0
    orb = c.row("ORB-SLAM2", "vo")
    np.testing.assert_allclose(orb.score.position_error[0], 0.0, atol=1e-9)       # anchored at the first frame
    assert len(c.row("ORB-SLAM2", "relative").std) == 6 and len(c.row("S-PTAM", "absolute").std) == 2
    text = vo_chapter.table(c)
    assert text.count("\n| ") == len(c.rows) + 1                         # header and one line per row
    for needle in ("Real:", "simulated: the GNSS noise", "real VO + real IMU", "simulated noise σ 1 m",
                   "NIS-tuned", *vo_chapter.METHODS.values()):
        assert needle in text
    # wall-clock times only when asked: a lecture stores the default table and nbval compares it
    assert "run [s]" not in text and "tuning took" not in text
    timed = vo_chapter.table(c, timings=True)
    assert "| run [s] |" in timed and "tuning took" in timed and timed.count("\n| ") == len(c.rows) + 1
    with pytest.raises(ValueError, match="no row"):
        c.row("DSO", "vo")
    with pytest.raises(ValueError, match="comparison must be a VoComparison"):
        vo_chapter.table(c.rows)


def test_given_noise_skips_the_tuning(seq00):
    c = vo_chapter.compare(seq00, systems="ORB-SLAM2", t_end=40.0, absolute_std=(0.1, 0.01),
                           relative_std=(0.01, 1e-3), reference=False)
    assert [r.method for r in c.rows] == ["vo", "absolute", "relative", "relative_gnss"]
    assert all(r.tuned is None for r in c.rows)
    assert c.row("ORB-SLAM2", "absolute").tuned is None and c.row("ORB-SLAM2", "absolute").std == (0.1, 0.01)
    assert "(given)" in vo_chapter.table(c)
    with pytest.raises(ValueError, match="system must be one of"):
        vo_chapter.setup(seq00, "DSO")


def test_on_the_whole_sequence_gnss_anchored_vio_beats_the_vo_alone(seq00):
    # the chapter's target (ORB-SLAM2, all of sequence 00): VO + IMU + GNSS below VO alone in
    # ATE and in both drift rates; and the absolute-pose fusion, tuned on its innovations, is
    # overconfident: its mean pose NEES over the K frames lies far above the 99 % interval
    c = vo_chapter.compare(seq00, systems=("ORB-SLAM2",), reference=False)
    vo_alone, fused = c.row("ORB-SLAM2", "vo").score, c.row("ORB-SLAM2", "relative_gnss").score
    assert fused.ate < vo_alone.ate
    assert fused.drift.translation_percent < vo_alone.drift.translation_percent
    assert fused.drift.rotation_deg_per_100m < vo_alone.drift.rotation_deg_per_100m
    absolute = c.row("ORB-SLAM2", "absolute")
    assert absolute.tuned.converged
    assert absolute.score.nees > chi2_bounds(6, 1, 0.99)[1]


# ---------------------------------------------------------------------------------------
# figures
# ---------------------------------------------------------------------------------------

def test_track_figure_draws_the_truth_and_each_estimate(slice_comparison):
    c = slice_comparison
    tracks = c.tracks("ORB-SLAM2")
    fig = plot_vo_tracks(c.truth_position, tracks, title="ORB-SLAM2")
    ax = fig.axes[0]
    labels = [line.get_label() for line in ax.lines]
    assert labels == ["truth", *tracks, "start (anchor)"]
    np.testing.assert_allclose(ax.lines[1].get_xydata(), tracks["VO alone"][:, :2])
    assert ax.get_xlabel() == "east [m]" and ax.get_aspect() == 1.0
    plt.close(fig)
    with pytest.raises(ValueError, match="tracks"):
        plot_vo_tracks(c.truth_position, {})
    with pytest.raises(ValueError, match=r"tracks\['x'\]"):
        plot_vo_tracks(c.truth_position, {"x": np.zeros(5)})


def test_drift_figure_has_one_curve_per_estimate_and_length_axis(slice_comparison):
    curves = slice_comparison.drift_curves("S-PTAM")
    fig = plot_drift_by_length(curves)
    ax_t, ax_r = fig.axes
    assert [line.get_label() for line in ax_t.lines] == list(curves)
    lengths, t_pct, r_deg = curves["VO alone"]
    np.testing.assert_allclose(ax_t.lines[0].get_ydata(), t_pct)
    np.testing.assert_allclose(ax_r.lines[0].get_ydata(), r_deg)
    assert "%" in ax_t.get_ylabel() and "°/100 m" in ax_r.get_ylabel() and ax_r.get_xlabel() == "segment length [m]"
    plt.close(fig)
    with pytest.raises(ValueError, match="must be \\(lengths"):
        plot_drift_by_length({"a": (lengths, t_pct)})


# ---------------------------------------------------------------------------------------
# white increments: the same filter with an increment model that is exactly right
# ---------------------------------------------------------------------------------------

def test_white_increment_track_has_white_increments_of_the_given_sigma(seq00):
    s = vo_chapter.setup(seq00, "ORB-SLAM2", t_end=seq00.truth.t[0] + 80.0)
    std = (0.02, 0.01, 0.005, 0.002, 0.001, 0.0005)          # per component, none equal: a swap shows
    track = vo_chapter.white_increment_track(s, std, seed=7)
    truth = seq00.truth
    p_true, R_true = truth.position[s.frames], truth.rotation[s.frames]
    np.testing.assert_allclose(track.position[0], p_true[0])
    np.testing.assert_allclose(track.rotation[0], R_true[0])
    n_p = np.array([R_true[k - 1].T @ (p_true[k] - p_true[k - 1]) for k in range(1, len(p_true))])
    m_p = np.array([track.rotation[k - 1].T @ (track.position[k] - track.position[k - 1]) for k in range(1, len(p_true))])
    n_th = np.array([so3.log((R_true[k - 1].T @ R_true[k]).T @ (track.rotation[k - 1].T @ track.rotation[k]))
                     for k in range(1, len(p_true))])
    noise = np.hstack([m_p - n_p, n_th])
    n = len(noise)
    np.testing.assert_allclose(noise.std(axis=0) / np.array(std), 1.0, atol=4 / np.sqrt(2 * n))
    lag1 = [np.corrcoef(noise[:-1, i], noise[1:, i])[0, 1] for i in range(6)]
    assert np.all(np.abs(lag1) < 4 / np.sqrt(n))                                   # white: no lag-1 correlation
    again = vo_chapter.white_increment_track(s, std, seed=7)
    np.testing.assert_array_equal(again.position, track.position)
    assert not np.array_equal(vo_chapter.white_increment_track(s, std, seed=8).position, track.position)


def test_white_increment_runs_score_each_seed_and_reject_none(seq00):
    s = vo_chapter.setup(seq00, "ORB-SLAM2", t_end=seq00.truth.t[0] + 20.0)
    scores = vo_chapter.white_increment_runs(s, (0.01, 0.001), [1, 2])
    assert len(scores) == 2 and all(np.isfinite(sc.nees) and sc.ate > 0 for sc in scores)
    assert scores[0].ate != scores[1].ate
    with pytest.raises(ValueError, match="seeds"):
        vo_chapter.white_increment_runs(s, (0.01, 0.001), [])
