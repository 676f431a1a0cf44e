"""The simulated consumer-grade MEMS IMU (data.mems_imu), the bias-model comparison run on it
(chapters.bias_models), Earth rotation's size, and the chapter's bias figure.

Statistical tolerances: a sample variance s² of n independent Gaussian draws has a relative
standard deviation of √(2/n), a sample mean a standard deviation of σ/√n; every check below
allows 4 of those (a false alarm about once in 16,000 runs), with n the number of draws
compared. Where the draws are correlated (a Gauss–Markov drift along time) the standard
deviation used is derived in the test.
"""

from __future__ import annotations

import math

import matplotlib.pyplot as plt
import numpy as np
import pytest

from kalman_course.chapters import bias_models
from kalman_course.core import so3
from kalman_course.core.imu import dead_reckon
from kalman_course.data.kitti import load_kitti
from kalman_course.evaluation.pose import evaluate
from kalman_course.data.mems_imu import (CONSUMER_MEMS, MemsSpec, gauss_markov_drift, reference_imu,
                                         simulate_mems_imu)
from kalman_course.plotting import plot_bias_models

EXCERPTS = ("cruise", "turns", "stop_go")


@pytest.fixture(scope="module")
def references():
    return {name: reference_imu(load_kitti(name)) for name in EXCERPTS}


@pytest.fixture(scope="module")
def turns_run():
    return bias_models.run_bias_models("turns", CONSUMER_MEMS, seed=0)


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


def _variance_ok(sample_variance, variance, n):
    """|s² − σ²| ≤ 4 √(2/n) σ² for the mean square s² of n zero-mean Gaussian draws."""
    return abs(sample_variance / variance - 1.0) <= 4.0 * math.sqrt(2.0 / n)


# ---------------------------------------------------------------------------------------
# The spec: datasheet units and their conversions
# ---------------------------------------------------------------------------------------

def test_conversions_from_datasheet_units():
    spec = CONSUMER_MEMS
    # 1 °/√h = (π/180) rad / √(3600 s): ARW × 60 is the rate noise density in °/s/√Hz
    assert math.degrees(spec.gyro_noise_density) * 60.0 == pytest.approx(spec.gyro_arw_deg_rth)
    # 1 µg = 9.80665e-6 m/s²; VRW in m/s/√h is the density × 60
    assert spec.accel_noise_density == pytest.approx(spec.accel_noise_ug_rthz * 9.80665e-6)
    assert spec.accel_vrw_m_s_rth == pytest.approx(spec.accel_noise_density * 60.0)
    # the bias instability is the Gauss–Markov drift's stationary σ (°/h → rad/s, mg → m/s²)
    assert math.degrees(spec.gyro_bias_sigma) * 3600.0 == pytest.approx(spec.gyro_bias_instability_deg_h)
    assert spec.accel_bias_sigma == pytest.approx(spec.accel_bias_instability_mg * 9.80665e-3)
    # its driving density q, with q² = 2σ²/τ (also the random walk of t ≪ τ)
    assert spec.gyro_bias_density ** 2 == pytest.approx(2.0 * spec.gyro_bias_sigma ** 2 / spec.gyro_bias_time_s)
    assert spec.accel_bias_density ** 2 == pytest.approx(2.0 * spec.accel_bias_sigma ** 2 / spec.accel_bias_time_s)
    # the preset's numbers: 20 °/h and τ = 100 s give q = 20 √0.02 °/h/√s ≈ 1.37e-5 rad/s²/√Hz
    assert math.degrees(spec.gyro_bias_density) * 3600.0 == pytest.approx(20.0 * math.sqrt(0.02))
    assert spec.gyro_bias_density == pytest.approx(1.371e-5, rel=1e-3)
    assert math.degrees(spec.gyro_turn_on) * 3600.0 == pytest.approx(spec.gyro_turn_on_deg_h)
    assert spec.accel_turn_on == pytest.approx(spec.accel_turn_on_mg * 9.80665e-3)
    assert np.allclose(spec.densities, [spec.accel_noise_density, spec.gyro_noise_density,
                                        spec.accel_bias_density, spec.gyro_bias_density])
    text = spec.describe()
    assert "°/√h" in text and "rad/s²/√Hz" in text and "Gauss–Markov stationary σ" in text
    assert f"| {math.degrees(spec.gyro_bias_density) * 3600 * 60:.3g} | °/h/√h |" in text


def test_the_preset_is_consumer_grade():
    # the ranges the module docstring justifies (datasheet classes of smartphone/automotive parts)
    assert 0.2 <= CONSUMER_MEMS.gyro_arw_deg_rth <= 0.8
    assert 5.0 <= CONSUMER_MEMS.gyro_bias_instability_deg_h <= 50.0
    assert 0.05 <= CONSUMER_MEMS.accel_bias_instability_mg <= 0.2
    assert 70.0 <= CONSUMER_MEMS.accel_noise_ug_rthz <= 300.0


def test_the_filter_configuration_takes_the_spec():
    cfg = bias_models.config_for_spec(CONSUMER_MEMS, "constant")
    assert cfg.bias_model == "constant"
    assert np.allclose(cfg.process_density, CONSUMER_MEMS.densities)
    assert np.allclose(cfg.prior_std[9:12], CONSUMER_MEMS.accel_turn_on)
    assert np.allclose(cfg.prior_std[12:15], CONSUMER_MEMS.gyro_turn_on)
    P0 = bias_models.frozen_bias_covariance(cfg)
    assert np.all(P0[9:15, 9:15] == 0.0) and np.all(np.diag(P0)[:9] > 0.0)


# ---------------------------------------------------------------------------------------
# The noise-free reference generated from the ground truth
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", EXCERPTS)
def test_reference_mechanises_back_to_its_motion_over_10_s(references, name):
    ref = references[name]
    stop = int(np.searchsorted(ref.t, ref.t[0] + 10.0))
    mech = dead_reckon(ref, ref.trajectory.state(0), ref.gravity, stop=stop)
    position = np.linalg.norm(mech.position - ref.trajectory.position[:stop], axis=1).max()
    attitude = np.rad2deg(so3.angle(np.swapaxes(mech.rotation, 1, 2) @ ref.trajectory.rotation[:stop])).max()
    # midpoint integration of a smooth motion at 100 Hz: millimetres, thousandths of a degree
    assert position < 0.01 and attitude < 0.01


@pytest.mark.parametrize("name", EXCERPTS)
def test_reference_mechanises_back_to_the_kitti_truth_over_5_s(references, name):
    ex, ref = load_kitti(name), references[name]
    stop = int(np.searchsorted(ref.t, ref.t[0] + 5.0))
    mech = dead_reckon(ref, ref.trajectory.state(0), ref.gravity, stop=stop)
    sel = (ex.truth.t >= mech.t[0]) & (ex.truth.t <= mech.t[-1])
    tq = ex.truth.t[sel]
    p = np.column_stack([np.interp(tq, mech.t, mech.position[:, i]) for i in range(3)])
    k = np.searchsorted(mech.t, tq).clip(1, len(mech.t) - 1)
    R = so3.interpolate(mech.rotation[k - 1], mech.rotation[k], (tq - mech.t[k - 1]) / (mech.t[k] - mech.t[k - 1]))
    position = np.linalg.norm(p - ex.truth.position[sel], axis=1).max()
    attitude = np.rad2deg(so3.angle(np.swapaxes(ex.truth.rotation[sel], 1, 2) @ R)).max()
    # stated tolerance: 4 cm and 0.4° over 5 s, the smoothing residual at a single pose (up to
    # 3.6 cm and 0.34° on these excerpts, the truth's own jitter) plus the mechanisation's drift
    assert position < 0.04 and attitude < 0.4
    # and on average the smoothed motion follows the truth to about a centimetre and 0.1°
    smoothing = evaluate(ref.truth.t, ref.truth.position, ref.truth.rotation, ex.truth)
    assert smoothing["ape_position"] < 0.015 and smoothing["ape_attitude_deg"] < 0.15


@pytest.mark.parametrize("name", EXCERPTS)
def test_reference_agrees_with_the_real_imu_over_1_s(references, name):
    # a frame or sign error would show as g-sized or turn-rate-sized differences; the real
    # OXTS readings and the generated ones agree over 1 s means to a tenth of that
    ex, ref = load_kitti(name), references[name]
    inside = (ex.imu.t >= ref.t[0]) & (ex.imu.t <= ref.t[-1])
    blocks = len(ref.t) // 100

    def block_means(x):
        return x[:blocks * 100].reshape(blocks, 100, 3).mean(axis=1)

    df = block_means(ref.specific_force) - block_means(ex.imu.specific_force[inside])
    dw = block_means(ref.angular_rate) - block_means(ex.imu.angular_rate[inside])
    assert np.sqrt(np.mean(df ** 2, axis=0)).max() < 0.15                  # m/s²
    assert np.rad2deg(np.sqrt(np.mean(dw ** 2, axis=0))).max() < 0.15      # °/s
    assert np.array_equal(ref.t, ex.imu.t[inside])                          # the real IMU clock


# ---------------------------------------------------------------------------------------
# The simulated errors
# ---------------------------------------------------------------------------------------

def test_seeded_and_deterministic(references):
    a = simulate_mems_imu(references["cruise"], CONSUMER_MEMS, seed=3)
    b = simulate_mems_imu(references["cruise"], CONSUMER_MEMS, seed=3)
    c = simulate_mems_imu(references["cruise"], CONSUMER_MEMS, seed=4)
    for field in ("specific_force", "angular_rate", "accel_bias", "gyro_bias"):
        assert np.array_equal(getattr(a, field), getattr(b, field))
        assert not np.array_equal(getattr(a, field), getattr(c, field))
    assert a.simulated and not a.interpolated.any() and a.seed == 3
    # from the excerpt directly: the same reference, so the same draw
    d = simulate_mems_imu(load_kitti("cruise"), CONSUMER_MEMS, seed=3)
    assert np.array_equal(a.angular_rate, d.angular_rate)


def test_readings_are_reference_plus_bias_plus_noise(references):
    m = simulate_mems_imu(references["turns"], CONSUMER_MEMS, seed=5)
    ref = m.reference
    assert np.allclose(m.angular_rate, ref.angular_rate + m.gyro_bias + m.gyro_noise, rtol=0, atol=1e-15)
    assert np.allclose(m.specific_force, ref.specific_force + m.accel_bias + m.accel_noise, rtol=0, atol=1e-13)


def test_white_noise_density_matches_the_spec(references):
    m = simulate_mems_imu(references["turns"], CONSUMER_MEMS, seed=11)
    ref = m.reference
    # the readings minus reference and bias, their variance × rate = density²
    n_w = m.angular_rate - ref.angular_rate - m.gyro_bias
    n_a = m.specific_force - ref.specific_force - m.accel_bias
    n = n_w.size                                            # 3 axes × N samples, each a draw
    assert _variance_ok(np.mean(n_w ** 2) * m.noise_dt, CONSUMER_MEMS.gyro_noise_density ** 2, n)
    assert _variance_ok(np.mean(n_a ** 2) * m.noise_dt, CONSUMER_MEMS.accel_noise_density ** 2, n)
    assert m.noise_dt == pytest.approx(np.median(np.diff(m.t)))


def test_bias_drift_steps_have_the_exact_discrete_variance(references):
    # on the real (irregular) KITTI IMU clock: d_{k+1} − φ_k d_k, φ_k = exp(−dt_k/τ), divided by
    # σ_b √(1 − φ_k²), must be standard normal; the random walk's increments / √dt would not be
    m = simulate_mems_imu(references["turns"], CONSUMER_MEMS, seed=12)
    dt = np.diff(m.t)[:, None]
    assert dt.max() > 1.5 * dt.min()                         # the steps are irregular
    for drift, sigma, tau in ((m.gyro_drift, CONSUMER_MEMS.gyro_bias_sigma, CONSUMER_MEMS.gyro_bias_time_s),
                              (m.accel_drift, CONSUMER_MEMS.accel_bias_sigma, CONSUMER_MEMS.accel_bias_time_s)):
        assert np.all(drift[0] == 0.0)
        phi = np.exp(-dt / tau)
        z = (drift[1:] - phi * drift[:-1]) / (sigma * np.sqrt(1.0 - phi ** 2))
        assert _variance_ok(np.mean(z ** 2), 1.0, z.size)
        assert abs(z.mean()) <= 4.0 / math.sqrt(z.size)


def test_simulated_bias_is_turn_on_plus_the_gauss_markov_drift_of_its_draws(references):
    # simulate_mems_imu draws turn-on (3), turn-on (3), then the gyro and accel innovations
    ref = references["cruise"]
    m = simulate_mems_imu(ref, CONSUMER_MEMS, seed=8)
    rng = np.random.default_rng(8)
    b_w0 = CONSUMER_MEMS.gyro_turn_on * rng.standard_normal(3)
    b_a0 = CONSUMER_MEMS.accel_turn_on * rng.standard_normal(3)
    n = len(ref.t)
    d_w = gauss_markov_drift(ref.t, CONSUMER_MEMS.gyro_bias_sigma, CONSUMER_MEMS.gyro_bias_time_s,
                             rng.standard_normal((n - 1, 3)))
    d_a = gauss_markov_drift(ref.t, CONSUMER_MEMS.accel_bias_sigma, CONSUMER_MEMS.accel_bias_time_s,
                             rng.standard_normal((n - 1, 3)))
    assert np.array_equal(m.gyro_bias, b_w0 + d_w) and np.array_equal(m.accel_bias, b_a0 + d_a)
    assert np.array_equal(m.gyro_bias[0], b_w0)


def _gm_loop(t, sigma, tau, normals):
    """The recursion d_{k+1} = φ_k d_k + σ √(1 − φ_k²) n_k written out, step by step."""
    d = np.zeros((len(t), normals.shape[1]))
    for k in range(len(t) - 1):
        phi = math.exp(-(t[k + 1] - t[k]) / tau)
        d[k + 1] = phi * d[k] + sigma * math.sqrt(1.0 - phi * phi) * normals[k]
    return d


def test_gauss_markov_drift_equals_its_recursion_over_irregular_and_long_steps():
    rng = np.random.default_rng(3)
    # irregular steps, a run of 240 τ (several closed-form blocks) and one gap of 50 τ
    t = np.cumsum(rng.uniform(0.002, 0.05, 12000))
    t = np.concatenate([t[:5000], t[5000:] + 100.0])
    normals = rng.standard_normal((len(t) - 1, 3))
    d = gauss_markov_drift(t, 0.7, 2.0, normals)
    assert (t[-1] - t[0]) / 2.0 > 200.0
    assert np.allclose(d, _gm_loop(t, 0.7, 2.0, normals), rtol=0.0, atol=1e-10)
    # deterministic: a function of its draws only
    assert np.array_equal(d, gauss_markov_drift(t, 0.7, 2.0, normals))


@pytest.mark.parametrize("dt", [0.01, 7.0, 100.0, 400.0])
def test_gauss_markov_step_variance_is_exact_for_any_step(dt):
    # from d_0 = 0, one step of dt gives Var d_1 = σ² (1 − exp(−2 dt/τ)); and from d_1, a second
    # step keeps exp(−dt/τ) of it: Cov(d_1, d_2) = exp(−dt/τ) Var d_1
    sigma, tau, n = 2.0, 100.0, 200_000
    d = gauss_markov_drift([0.0, dt, 2 * dt], sigma, tau, np.random.default_rng(5).standard_normal((2, n)))
    var1 = sigma ** 2 * -math.expm1(-2.0 * dt / tau)
    assert _variance_ok(np.mean(d[1] ** 2), var1, n)
    # the random walk of the same q would have variance q² dt = 2σ² dt/τ: 2×, 8× too large at dt = τ, 4τ
    if dt >= tau:
        assert np.mean(d[1] ** 2) < 0.6 * 2.0 * sigma ** 2 * dt / tau
    phi = math.exp(-dt / tau)
    # the regression of d_2 on d_1: slope φ, residual variance σ²(1 − φ²) (n − 1 degrees of freedom)
    slope = np.sum(d[1] * d[2]) / np.sum(d[1] ** 2)
    assert abs(slope - phi) <= 4.0 * math.sqrt((1.0 - phi ** 2) * sigma ** 2 / np.sum(d[1] ** 2))
    assert _variance_ok(np.mean((d[2] - phi * d[1]) ** 2), sigma ** 2 * (1.0 - phi ** 2), n)


def test_gauss_markov_spread_follows_its_formula_and_stays_bounded():
    # 1000 independent drifts on the real seq00 IMU clock (470 s, 4.7 τ): the spread across them at
    # time t is σ √(1 − exp(−2t/τ)) → σ, where a random walk of density q = σ √(2/τ) would reach q √t
    t = load_kitti("seq00").imu.t
    sigma, tau, n = CONSUMER_MEMS.gyro_bias_sigma, CONSUMER_MEMS.gyro_bias_time_s, 1000
    ks = np.searchsorted(t, t[0] + np.array([10.0, 100.0, 250.0, 450.0, t[-1] - t[0]]))
    rng = np.random.default_rng(9)
    rows = np.concatenate([gauss_markov_drift(t, sigma, tau, rng.standard_normal((len(t) - 1, 100)))[ks]
                           for _ in range(n // 100)], axis=1)               # 100 drifts at a time
    for k, d_k in zip(ks, rows):
        expected = sigma ** 2 * -math.expm1(-2.0 * (t[k] - t[0]) / tau)
        assert _variance_ok(np.mean(d_k ** 2), expected, n)
    d = rows
    spread_end = math.sqrt(np.mean(d[-1] ** 2))
    assert spread_end < 1.1 * sigma                                       # bounded near σ
    assert spread_end < 0.4 * CONSUMER_MEMS.gyro_bias_density * math.sqrt(t[-1] - t[0])   # not q √t (3.1 σ)


def test_gauss_markov_long_run_is_stationary_with_autocorrelation_exp_minus_one_at_tau():
    # one long run per column, irregular steps around τ/100, 1200 τ in all; the first 10 τ discarded
    rng = np.random.default_rng(21)
    sigma, tau, m = 1.5, 1.0, 4
    t = np.cumsum(rng.uniform(0.005, 0.015, 120_000))
    d = gauss_markov_drift(t, sigma, tau, rng.standard_normal((len(t) - 1, m)))
    keep = t - t[0] > 10.0 * tau
    x, span = d[keep], t[keep][-1] - t[keep][0]
    # the time mean of d² of a Gauss–Markov process over a span T has the standard deviation
    # σ² √(2τ/T) (Cov(d²(t), d²(s)) = 2σ⁴ exp(−2|t − s|/τ)); m independent columns divide it by √m
    for part in (x[: len(x) // 2], x[len(x) // 2:]):                       # first half, second half
        rel_sd = math.sqrt(2.0 * tau / (0.5 * span * m))
        assert abs(np.mean(part ** 2) / sigma ** 2 - 1.0) <= 4.0 * rel_sd
    # autocorrelation at lag τ, on a regular grid of τ/100 (1200 τ, the first 10 τ discarded): ρ(τ) = e^{-1}
    h = 100
    grid = np.arange(0.0, 1200.0 * tau, tau / h)
    g = gauss_markov_drift(grid, sigma, tau, rng.standard_normal((len(grid) - 1, m)))[10 * h:]
    N = len(g) - h
    rho = np.mean(g[:-h] * g[h:]) / np.mean(g ** 2)
    # Bartlett's variance of a sample autocorrelation of an AR(1) with φ = exp(−1/h) at lag h
    phi = math.exp(-1.0 / h)
    var = ((1 + phi ** 2) * (1 - phi ** (2 * h)) / (1 - phi ** 2) - 2 * h * phi ** (2 * h)) / (N * m)
    assert abs(rho - math.exp(-1.0)) <= 4.0 * math.sqrt(var)


def test_turn_on_bias_matches_the_spec(references):
    ref = references["cruise"]
    b_w = np.array([simulate_mems_imu(ref, CONSUMER_MEMS, seed=s).gyro_bias[0] for s in range(200)])
    b_a = np.array([simulate_mems_imu(ref, CONSUMER_MEMS, seed=s).accel_bias[0] for s in range(200)])
    for b, sigma in ((b_w, CONSUMER_MEMS.gyro_turn_on), (b_a, CONSUMER_MEMS.accel_turn_on)):
        assert _variance_ok(np.mean(b ** 2), sigma ** 2, b.size)
        assert abs(b.mean()) <= 4.0 * sigma / math.sqrt(b.size)


def test_bias_at_interpolates_the_simulated_bias(references):
    m = simulate_mems_imu(references["cruise"], CONSUMER_MEMS, seed=1)
    b_a, b_w = m.bias_at(m.t[[0, 10, -1]])
    assert np.array_equal(b_w, m.gyro_bias[[0, 10, -1]]) and np.array_equal(b_a, m.accel_bias[[0, 10, -1]])
    k0, state = m.initial_state()
    assert k0 == 0 and np.array_equal(state.position, m.reference.trajectory.position[0])
    with pytest.raises(ValueError, match="times"):
        m.bias_at([m.t[-1] + 1.0])


# ---------------------------------------------------------------------------------------
# The comparison and Earth rotation
# ---------------------------------------------------------------------------------------

def test_the_comparison_orders_the_bias_models(turns_run):
    rw, const, frozen = (turns_run.metrics[v] for v in bias_models.VARIANTS)
    # neither filter has the Gauss–Markov model that made the data; the random walk of density
    # q = σ √(2/τ) approximates it well enough that its final bias errors sit near 1σ and its
    # bias NEES near 6; the constant model's σ shrinks while the bias drifts
    assert rw["gyro_bias_error_sigma"] < const["gyro_bias_error_sigma"]
    assert rw["nees_bias"] < const["nees_bias"]
    assert 3.0 <= rw["nees_pose"] <= 12.0
    # not estimating the biases at all costs accuracy many times over
    assert frozen["ape_position"] > 3.0 * rw["ape_position"]
    assert frozen["ape_attitude_deg"] > 3.0 * rw["ape_attitude_deg"]
    assert math.isinf(frozen["gyro_bias_error_sigma"]) and math.isnan(frozen["nees_bias"])
    # the frozen filter's biases never leave zero
    assert np.all(turns_run.results["frozen at 0"].gyro_bias == 0.0)
    assert turns_run.true_gyro_bias.shape == (len(turns_run.t), 3)


def test_comparison_table_says_what_is_simulated():
    comparison = bias_models.compare_bias_models("cruise", seeds=[0, 1])
    text = comparison.table()
    assert "simulated" in text and "real ground truth" in text and "2 seeds" in text
    assert comparison.metrics["constant"]["ape_position"].shape == (2,)
    assert "— (σ = 0)" in text
    earth = bias_models.earth_rotation_table(CONSUMER_MEMS, comparison)
    assert "11.35" in earth and "filter's own final σ [°/h]" in earth and "actual error ÷ own σ" in earth
    assert comparison.metrics["random walk"]["gyro_bias_error_axes_deg_h"].shape == (2, 3)
    # the vertical part is never called separable; a "yes" needs the actual error and the σ below it
    rows = [line.split(" | ") for line in earth.splitlines() if line.startswith("| random walk") or
            line.startswith("| constant")]
    assert len(rows) == 4
    for row in rows:
        own, actual, part = float(row[2]), float(row[3]), float(row[5])
        if "z (vertical)" in row[1]:
            assert row[6].startswith("not separable")
        else:
            assert row[6].startswith("yes") == (actual < part and own < part)


def _fake_comparison(error_deg_h, sigma_deg_h):
    """A BiasModelComparison of one seed whose two filters have the given final gyro errors and σ (3,)."""
    one = {"gyro_bias_error_axes_deg_h": np.array([error_deg_h]), "gyro_bias_sigma_axes_deg_h": np.array([sigma_deg_h])}
    return bias_models.BiasModelComparison("fake", CONSUMER_MEMS, "lidar", (0,),
                                           {"random walk": one, "constant": one}, None)


@pytest.mark.parametrize("error, sigma, verdict", [
    ([2.0, -2.0, 0.1], [3.0, 3.0, 0.1], "yes: above both"),        # horizontal error and σ below 9.87
    ([2.0, -2.0, 0.1], [12.0, 12.0, 0.1], "no: within the filter's own σ"),
    ([15.0, 5.0, 0.1], [3.0, 3.0, 0.1], "no: within the actual error"),
])
def test_earth_rotation_verdicts(error, sigma, verdict):
    table = bias_models.earth_rotation_table(CONSUMER_MEMS, _fake_comparison(error, sigma))
    horizontal = [line for line in table.splitlines() if "x, y (horizontal)" in line]
    vertical = [line for line in table.splitlines() if "z (vertical)" in line]
    assert len(horizontal) == len(vertical) == 2
    assert all(f"| {verdict}" in line for line in horizontal)
    # a z error of 0.1 °/h, far below Ω sin φ, still does not make the vertical part separable
    assert all("not separable" in line and "| 0.10 | 0.10 | 1.0 |" in line for line in vertical)
    rms_error = math.sqrt((error[0] ** 2 + error[1] ** 2) / 2)
    assert f"| {rms_error:.2f} |" in horizontal[0]


def test_earth_rotation_at_kitti():
    er = bias_models.earth_rotation()
    assert er.rate_deg_h == pytest.approx(15.041, abs=1e-3)
    assert er.latitude_deg == bias_models.KITTI_LATITUDE_DEG
    assert er.up_deg_h == pytest.approx(er.rate_deg_h * math.sin(math.radians(49.0)))
    assert math.hypot(er.north_deg_h, er.up_deg_h) == pytest.approx(er.rate_deg_h)
    assert bias_models.earth_rotation(0.0).up_deg_h == pytest.approx(0.0, abs=1e-12)
    assert er.up_rad_s == pytest.approx(7.2921150e-5 * math.sin(math.radians(49.0)))


def test_bias_figure(turns_run):
    m = turns_run.mems
    fig = plot_bias_models(m.t, m.accel_bias, m.gyro_bias,
                           {v: turns_run.results[v] for v in ("random walk", "constant")}, zoom_from=m.t[0] + 20)
    ax_w, ax_a = fig.axes[:2]
    assert ax_w.get_xlabel() == "t [s]" and ax_a.get_xlabel() == "t [s]"
    assert "°/h" in ax_w.get_ylabel() and "mg" in ax_a.get_ylabel()
    labels = [line.get_label() for line in ax_w.lines]
    assert labels == ["true bias (simulated)", "random walk", "constant"]
    assert len(ax_w.collections) == 2                    # one ±3σ band per filter


# ---------------------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------------------

def test_validation_errors(references):
    fields = dict(name="x", gyro_arw_deg_rth=0.3, gyro_bias_instability_deg_h=20.0, gyro_bias_time_s=100.0,
                  gyro_turn_on_deg_h=360.0, accel_noise_ug_rthz=150.0, accel_bias_instability_mg=0.1,
                  accel_bias_time_s=100.0, accel_turn_on_mg=5.0)
    for key, bad in (("gyro_arw_deg_rth", -0.3), ("accel_bias_time_s", 0.0), ("accel_turn_on_mg", float("nan")),
                     ("gyro_bias_instability_deg_h", "20")):
        with pytest.raises(ValueError, match=key):
            MemsSpec(**{**fields, key: bad})
    with pytest.raises(ValueError, match="name"):
        MemsSpec(**{**fields, "name": ""})
    with pytest.raises(ValueError, match="spec"):
        simulate_mems_imu(references["cruise"], {"gyro_arw_deg_rth": 0.3}, 0)
    with pytest.raises(ValueError, match="seed"):
        simulate_mems_imu(references["cruise"], CONSUMER_MEMS, -1)
    with pytest.raises(ValueError, match="normals"):
        gauss_markov_drift([0.0, 1.0, 2.0], 1.0, 1.0, np.zeros((3, 2)))
    with pytest.raises(ValueError, match="increasing"):
        gauss_markov_drift([0.0, 1.0, 1.0], 1.0, 1.0, np.zeros((2, 2)))
    with pytest.raises(ValueError, match="time_constant"):
        gauss_markov_drift([0.0, 1.0], 1.0, 0.0, np.zeros((1, 2)))
    ex = load_kitti("cruise")
    with pytest.raises(ValueError, match="knot_spacing"):
        reference_imu(ex, knot_spacing=0.1)
    with pytest.raises(ValueError, match="truth"):
        reference_imu(type("NoTruth", (), {"imu": ex.imu, "gravity": ex.gravity})())
    with pytest.raises(ValueError, match="latitude_deg"):
        bias_models.earth_rotation(100.0)
    with pytest.raises(ValueError, match="observations"):
        bias_models.run_bias_models(references["cruise"], observations="radar")
    with pytest.raises(ValueError, match="seeds"):
        bias_models.compare_bias_models("cruise", seeds=[])
    m = simulate_mems_imu(references["cruise"], CONSUMER_MEMS, 0)
    with pytest.raises(ValueError, match="true_gyro_bias"):
        plot_bias_models(m.t, m.accel_bias, m.gyro_bias[:-1], {"x": None})
    with pytest.raises(ValueError, match="gyro_axis"):
        plot_bias_models(m.t, m.accel_bias, m.gyro_bias, {}, gyro_axis=3)
    with pytest.raises(ValueError, match="results"):
        plot_bias_models(m.t, m.accel_bias, m.gyro_bias, {"x": object()})
