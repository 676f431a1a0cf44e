"""Consistency statistics (evaluation layer) and the chapter 09 experiments: summaries,
gating, outliers, Monte Carlo, update forms; and a smoke test of the benchmark report."""

import numpy as np
import pytest

from kalman_course.chapters import consistency as C
from kalman_course.core import linalg
from kalman_course.evaluation import consistency as stats
from kalman_course.evaluation import metrics
from kalman_course.data import load_kitti


@pytest.fixture(scope="module")
def cruise():
    return load_kitti("cruise")


@pytest.fixture(scope="module")
def outlier_runs(cruise):
    bad, mask = C.inject_outliers(cruise.lidar, 0)
    return mask, C.run_gated(cruise, bad), C.run_gated(cruise, bad, confidence=None)


def test_verdict_of_chi_square_draws():
    rng = np.random.default_rng(3)
    values = rng.chisquare(6, size=400)
    assert stats.verdict(values, 6) == "consistent"
    assert stats.verdict(2.0 * values, 6) == "overconfident"
    assert stats.verdict(0.5 * values, 6) == "underconfident"
    s = stats.summarise(values, 6)
    assert s.lo == pytest.approx(metrics.chi2_ppf(0.025, 6))
    assert 0.9 < s.share_inside < 0.99
    assert s.mean_lo < s.mean < s.mean_hi


def test_summarise_run_average_and_nan():
    values = np.array([5.0, np.nan, 6.0, 7.0])
    s = stats.summarise(values, 6, n_runs=20)
    assert s.mean == pytest.approx(6.0)
    assert (s.lo, s.hi) == pytest.approx(metrics.chi2_bounds(6, 20))
    with pytest.raises(ValueError):
        stats.summarise([np.nan], 6)


@pytest.mark.parametrize("call, name", [
    (lambda: stats.summarise([1.0, np.inf], 6), "values"),
    (lambda: stats.summarise([1.0], 0), "dof"),
    (lambda: stats.summarise([1.0], 6, n_runs=2.5), "n_runs"),
    (lambda: stats.verdict([1.0], 6, confidence=1.5), "confidence"),
    (lambda: stats.gate_threshold(3, 0.0), "confidence"),
    (lambda: stats.gate([1.0, 2.0], np.eye(3)), "S"),
    (lambda: stats.gate([1.0, np.nan], np.eye(2)), "innovation"),
    (lambda: stats.gate([1.0, 2.0], np.diag([1.0, -1.0])), "S"),
])
def test_statistics_name_the_bad_argument(call, name):
    with pytest.raises(ValueError, match=name):
        call()


def test_gate_threshold_and_decisions():
    S = np.diag([4.0, 1.0, 0.25])
    threshold = stats.gate_threshold(3, 0.99)
    assert threshold == pytest.approx(11.344866730144373, rel=1e-9)
    y = np.array([2.0, 1.0, 0.5])                      # NIS 3
    assert stats.gate(y, S)
    assert not stats.gate(y * np.sqrt(1.01 * threshold / 3.0), S)
    assert stats.gate(y * np.sqrt(0.99 * threshold / 3.0), S)


def test_inject_outliers_is_seeded_and_local(cruise):
    a, mask = C.inject_outliers(cruise.lidar, 5, n_bursts=2, burst_length=4, offset=2.5, yaw_deg=2.0)
    b, mask_b = C.inject_outliers(cruise.lidar, 5, n_bursts=2, burst_length=4, offset=2.5, yaw_deg=2.0)
    np.testing.assert_array_equal(a.position, b.position)
    np.testing.assert_array_equal(mask, mask_b)
    assert mask.sum() == 8 and not mask[:20].any()
    shift = np.linalg.norm(a.position - cruise.lidar.position, axis=1)
    np.testing.assert_allclose(shift[mask], 2.5, rtol=1e-12)
    assert np.all(shift[~mask] == 0.0)
    np.testing.assert_allclose(a.position[mask, 2], cruise.lidar.position[mask, 2])
    with pytest.raises(ValueError):
        C.inject_outliers(cruise.lidar, 0, n_bursts=100, burst_length=10)


def test_gated_run_rejects_the_outliers(cruise, outlier_runs):
    mask, gated, ungated = outlier_runs
    assert ungated.accepted.all() and ungated.reruns == 1
    rejected = ~gated.accepted
    assert np.all(rejected[mask[gated.index]])               # every map-matching failure refused
    assert rejected[~mask[gated.index]].sum() <= 3           # and hardly any good pose
    # the decision is the sequential one: every pose is judged by its own prior's NIS
    np.testing.assert_array_equal(gated.accepted, gated.nis <= gated.threshold)
    from kalman_course.evaluation.pose import evaluate
    errs = []
    for run in (gated, ungated):
        r = run.result
        errs.append(evaluate(r.t, r.position, r.rotation, cruise.truth)["ape_position"])
    assert errs[0] < 0.2 < 0.3 < errs[1]


def test_gated_run_without_outliers_matches_the_plain_filter(cruise):
    from kalman_course.filters import eskf
    run = C.run_gated(cruise, confidence=None)
    k0, s0 = cruise.initial_state()
    ref = eskf.run(cruise.imu, s0, "kitti_lidar", cruise.gravity, lidar=cruise.lidar, start=k0)
    np.testing.assert_allclose(run.result.position, ref.position, atol=1e-12)
    np.testing.assert_allclose(run.nis, metrics.nis(np.array(ref.innovation), np.array(ref.S)))


def test_monte_carlo_small_is_consistent():
    mc = C.monte_carlo(n_runs=6, seed=0, duration=6.0)
    assert mc.nees.shape == mc.nis.shape == (6, len(mc.t))
    assert 10.0 < np.mean(mc.nees) < 20.0
    assert 4.0 < np.mean(mc.nis) < 8.0
    assert np.all(mc.position_error < 5 * mc.position_std)
    again = C.monte_carlo(n_runs=6, seed=0, duration=6.0)
    np.testing.assert_array_equal(mc.nees, again.nees)


def test_scaled_config():
    base = C.scaled_config()
    cfg = C.scaled_config("kitti_lidar", 4.0, 0.25)
    np.testing.assert_allclose(cfg.process_density[:2], 2.0 * base.process_density[:2])
    np.testing.assert_allclose(cfg.process_density[2:], base.process_density[2:])
    np.testing.assert_allclose(cfg.lidar_std, 0.5 * base.lidar_std)
    with pytest.raises(ValueError):
        C.scaled_config("kitti_lidar", 0.0)


def test_sensitivity_row(cruise):
    (row,) = C.sensitivity(cruise, [("reference", 1.0, 1.0)])
    assert row.ape_position < 0.2 and 3.0 < row.nees_pose < 12.0
    assert row.verdict == "consistent"


def test_update_forms():
    P = np.eye(2)
    G = np.array([[1.0, 0.0]])
    R = np.array([[0.01]])
    K = P @ G.T / (G @ P @ G.T + R)
    np.testing.assert_allclose(C.simple_update(P, K, G), C.joseph_update(P, K, G, R), atol=1e-15)
    bad = 1.5 * K
    assert C.covariance_health(C.simple_update(P, bad, G))[1] < 0.0
    assert C.covariance_health(C.joseph_update(P, bad, G, R))[1] > 0.0
    # the Joseph form is the shared kernel's, for any gain
    np.testing.assert_array_equal(C.joseph_update(P, bad, G, R), linalg.joseph_update(P, bad, G, R))
    # the short form is left unsymmetrised on purpose: a gain not proportional to P̌Gᵀ shows it
    hand = np.array([[1.2], [0.1]])
    P_corr = np.array([[1.0, 0.5], [0.5, 1.0]])
    assert C.covariance_health(C.simple_update(P_corr, hand, G))[0] > 0.1
    with pytest.raises(ValueError, match="G"):
        C.simple_update(P, K, np.ones((1, 3)))
    skew = np.array([[1.0, 0.3], [0.1, 1.0]])
    assert C.covariance_health(skew)[0] == pytest.approx(0.2)
    assert C.covariance_health(C.symmetrise(skew))[0] == 0.0


def test_roundoff_experiment():
    asym32, eig32 = C.roundoff_experiment(np.float32, "simple")
    assert asym32 > 1e-4 and eig32 < 0.0
    # the update forms stay in single precision (an upcast would hide the failure)
    P32 = np.eye(2, dtype=np.float32)
    G32, R32 = np.array([[1.0, 0.0]], np.float32), np.array([[0.01]], np.float32)
    K32 = np.array([[0.5], [0.0]], np.float32)
    assert C.simple_update(P32, K32, G32).dtype == np.float32
    assert C.joseph_update(P32, K32, G32, R32).dtype == np.float32
    assert C.roundoff_experiment(np.float32, "joseph")[1] > 0.0
    assert C.roundoff_experiment(np.float64, "simple", symmetric=True)[0] == 0.0
    with pytest.raises(ValueError):
        C.roundoff_experiment(form="long")


def test_bench_smoke():
    """A tiny part of the benchmark report: the KF timing runs and one excerpt's accuracy rows."""
    from kalman_course.tooling import bench
    for dim in (2, 3):
        k = bench.kf_speed(n_steps=50, repeats=1, dim=dim)
        assert k["dim"] == dim and k["run_kf"] > 0 and k["calls"] > 0 and k["ratio"] > 0
    rows = bench.excerpt_accuracy("cruise")
    lidar, raw = rows["ESKF + lidar (10 Hz)"], rows["raw lidar poses (σ 0.2 m, 0.3°)"]
    assert lidar["pos"] < 0.4 * raw["pos"] and lidar["att"] < 0.3 * raw["att"]
    assert rows["ESKF + GNSS (1 Hz)"]["pos"] < 0.7 * rows["raw GNSS fixes (σ 1 m)"]["pos"]
    assert set(rows) >= {"ORB-SLAM2 (SE(3)-aligned)", "S-PTAM (SE(3)-aligned)"}


def test_median_time_and_its_arguments():
    from kalman_course.tooling import bench
    calls = []
    assert bench.median_time(lambda: calls.append(1), repeats=5, warmup=2) >= 0.0
    assert len(calls) == 7
    with pytest.raises(ValueError, match="repeats"):
        bench.median_time(lambda: None, repeats=0)
