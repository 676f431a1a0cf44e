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
    assert row.nees_verdict == row.nis_verdict == "consistent"
    assert row.verdict == "consistent (NEES and NIS)"
    assert row.nis_band == pytest.approx(metrics.chi2_bounds(6, 293))
    # the NEES band counts correlated steps by their correlation time: wider than 293 white values
    white = metrics.chi2_bounds(6, 293)
    assert row.nees_band[0] < white[0] and row.nees_band[1] > white[1]


def test_sensitivity_verdict_uses_the_nees_too(cruise):
    """Q × 0.01: the NIS passes but the pose NEES (12) is far above its band; the verdict says so."""
    (row,) = C.sensitivity(cruise, [("Q x 0.01", 0.01, 1.0)])
    assert row.nis_verdict == "consistent" and row.nees_verdict == "overconfident"
    assert row.verdict == "overconfident (NEES)"


@pytest.mark.parametrize("nees, nis, expected", [
    ("consistent", "consistent", "consistent (NEES and NIS)"),
    ("overconfident", "overconfident", "overconfident (NEES and NIS)"),
    ("overconfident", "consistent", "overconfident (NEES)"),
    ("consistent", "underconfident", "underconfident (NIS)"),
    ("underconfident", "overconfident", "underconfident (NEES), overconfident (NIS)"),
])
def test_combined_verdict(nees, nis, expected):
    assert C.combined_verdict(nees, nis) == expected


def test_combined_verdict_rejects_unknown_words():
    with pytest.raises(ValueError, match="verdict"):
        C.combined_verdict("fine", "consistent")


# ---------------------------------------------------------------------------------------
# the band of a time (and run) average, checked by simulation with a consistent linear KF
# ---------------------------------------------------------------------------------------

def _cv_kf_nees(seed, n_steps=300, r_scale=1.0):
    """NEES (4 dof) of a correctly modelled 2-D CV Kalman filter on its own simulated data.

    The prior at step 0 is drawn from the prior covariance, so the NEES is χ²(4) at every
    step; successive values are strongly correlated (the error is carried from step to step).
    ``r_scale`` scales the R the filter assumes (1: correct).
    """
    from kalman_course.data import cv_target
    from kalman_course.filters import kf
    sc = cv_target(n_steps, 0.1, 0.5, 1.0, seed)
    rng = np.random.default_rng(seed + 10_000)
    D = np.diag([1.0, 1.0, 0.25, 0.25])
    x0 = sc.F @ sc.x0 + np.sqrt(np.diag(D)) * rng.standard_normal(4)
    h = kf.run_kf(x0, sc.Q + D, sc.F, sc.Q, sc.H, r_scale * sc.R, sc.z)
    return metrics.nees(h.x_hat - sc.x, h.P_hat)


def test_correlation_time_of_an_ar1_sequence():
    # AR(1) with φ = 0.8: τ = (1 + φ) / (1 − φ) = 9
    rng = np.random.default_rng(4)
    x = np.empty(40_000)
    x[0] = 0.0
    e = rng.standard_normal(x.size)
    for k in range(1, x.size):
        x[k] = 0.8 * x[k - 1] + e[k]
    assert stats.correlation_time(x) == pytest.approx(9.0, rel=0.15)
    assert stats.correlation_time(rng.standard_normal(5000)) == pytest.approx(1.0, abs=0.15)


def test_average_band_of_an_uncorrelated_record_is_the_chi2_band():
    # alternating values: ρ_1 = −1, so τ = 1 and the band is that of 2 × 100 independent values
    values = np.tile([1.0, 11.0], (2, 50))
    band = stats.average_band(values, 6)
    assert band.correlation_time == 1.0 and band.n_effective == 200.0
    assert (band.lo, band.hi) == pytest.approx(metrics.chi2_bounds(6, 200), rel=1e-10)
    assert band.mean == 6.0 and band.verdict == "consistent"


@pytest.mark.parametrize("n_runs, n_trials", [(1, 150), (3, 80)])
def test_average_band_covers_a_consistent_kf(n_runs, n_trials):
    """Coverage of the 95 % band, measured over independent trials of a consistent filter.

    The band of n_runs · K independent values (chi2_bounds) treats the correlated steps as
    independent and covers far too rarely; the correlation-time band covers about 90–95 %.
    """
    inside = inside_white = 0
    for trial in range(n_trials):
        record = np.array([_cv_kf_nees(1000 * trial + i) for i in range(n_runs)])
        band = stats.average_band(record, 4)
        inside += band.lo <= band.mean <= band.hi
        lo, hi = metrics.chi2_bounds(4, record.size)
        inside_white += lo <= band.mean <= hi
    assert 0.86 <= inside / n_trials <= 0.99, inside / n_trials
    assert inside_white / n_trials < 0.6, inside_white / n_trials


def test_average_band_sees_an_overconfident_kf():
    # the filter assumes R / 9 (σ / 3): its NEES is far above the band on every seed
    for seed in range(3):
        assert stats.average_band(_cv_kf_nees(seed, r_scale=1 / 9), 4).verdict == "overconfident"


@pytest.mark.parametrize("values, dof, match", [
    ([[1.0, np.nan]], 6, "finite"), (np.ones((2, 2, 2)), 6, "shape"), ([1.0, 2.0], 0, "dof"),
    (["a"], 6, "values"),
])
def test_average_band_names_the_bad_argument(values, dof, match):
    with pytest.raises(ValueError, match=match):
        stats.average_band(values, dof)


# ---------------------------------------------------------------------------------------
# whiteness of the innovations
# ---------------------------------------------------------------------------------------

def _innovations(seed, phi=0.0, n=300):
    """n innovations of 3 components with a fixed non-diagonal S; AR(1) with φ in time."""
    rng = np.random.default_rng(seed)
    A = np.array([[2.0, 0.0, 0.0], [0.5, 1.0, 0.0], [0.1, -0.3, 0.5]])
    S = np.broadcast_to(A @ A.T, (n, 3, 3))
    w = rng.standard_normal((n, 3))
    u = np.empty_like(w)
    u[0] = w[0]
    for k in range(1, n):
        u[k] = phi * u[k - 1] + np.sqrt(1 - phi ** 2) * w[k]
    return u @ A.T, S


def test_whiteness_passes_white_innovations_on_most_seeds():
    passed = [stats.innovation_whiteness(*_innovations(seed), max_lag=8).white for seed in range(40)]
    assert 33 <= sum(passed) <= 40           # 38 expected at 95 %
    w = stats.innovation_whiteness(*_innovations(0), max_lag=8)
    assert w.autocorrelation.shape == (3, 8) and list(w.lags) == list(range(1, 9))
    assert w.band == pytest.approx(1.959964 / np.sqrt(300), rel=1e-5)
    assert w.threshold == pytest.approx(metrics.chi2_ppf(0.95, 24))


def test_whiteness_fails_coloured_innovations():
    for seed in range(5):
        w = stats.innovation_whiteness(*_innovations(seed, phi=0.5), max_lag=8)
        assert not w.white and w.statistic > 3 * w.threshold
        assert np.all(w.autocorrelation[:, 0] > w.band)          # lag 1 ≈ φ on every component


def test_whiteness_whitens_with_s():
    # whitening by S makes the test blind to the units: ν scaled by 3 with S scaled by 9 is the
    # same whitened sequence
    nu, S = _innovations(1)
    w = stats.innovation_whiteness(nu, S, max_lag=5)
    scaled = stats.innovation_whiteness(3.0 * nu, 9.0 * S, max_lag=5)
    np.testing.assert_allclose(scaled.autocorrelation, w.autocorrelation, atol=1e-12)


@pytest.mark.parametrize("call, match", [
    (lambda nu, S: stats.innovation_whiteness(nu[:, :2], S), "innovation"),
    (lambda nu, S: stats.innovation_whiteness(nu, -S), "positive definite"),
    (lambda nu, S: stats.innovation_whiteness(nu, S, max_lag=300), "max_lag"),
    (lambda nu, S: stats.innovation_whiteness(nu, S, max_lag=0), "max_lag"),
    (lambda nu, S: stats.innovation_whiteness(np.where(np.arange(300)[:, None] == 3, np.nan, nu), S), "finite"),
])
def test_whiteness_names_the_bad_argument(call, match):
    nu, S = _innovations(0)
    with pytest.raises(ValueError, match=match):
        call(nu, S)


def test_whiteness_runs_on_kitti(cruise):
    """Real IMU and truth, simulated lidar errors: white ones pass, Gauss–Markov (τ 1 s) ones fail."""
    white = C.whiteness_runs(cruise, [0, 1, 2])
    coloured = C.whiteness_runs(cruise, [0, 1, 2], time_constant=1.0)
    assert white.n_white >= 2 and coloured.n_white == 0
    assert np.all(coloured.statistics > 10 * coloured.tests[0].threshold)
    assert coloured.nees_verdicts == ("overconfident",) * 3
    # the mean NIS points the wrong way: coloured errors the filter averages as white look *smaller*
    assert np.all(coloured.nis < 6.0) and "underconfident" in coloured.nis_verdicts
    assert white.nis_verdicts.count("consistent") >= 2 and white.nis.shape == (3,)
    again = C.whiteness_runs(cruise, [0, 1, 2])
    np.testing.assert_array_equal(again.statistics, white.statistics)
    with pytest.raises(ValueError, match="seed"):
        C.whiteness_runs(cruise, [])


def test_plot_whiteness(cruise):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from kalman_course.plotting.consistency import plot_whiteness
    cases = {"white": C.whiteness_runs(cruise, [0, 1]), "τ 1 s": C.whiteness_runs(cruise, [0, 1], 1.0)}
    fig = plot_whiteness(cases)
    left, right = fig.axes
    assert len(right.lines) == 3                          # two cases and the threshold
    labels = right.get_legend_handles_labels()[1]
    assert labels[:2] == ["white: 2 of 2 white", "τ 1 s: 0 of 2 white"]
    plt.close(fig)
    with pytest.raises(ValueError):
        plot_whiteness({})


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
