"""Simulated observation error models: white (the shipped draw), Gauss–Markov, map-matching failures.

Statistical tests use long seeded draws; each tolerance is a number of standard errors
(5 unless said otherwise) of the estimator, computed from the sample size as the comment
next to it says.
"""

import numpy as np
import pytest

from kalman_course.core import so3
from kalman_course.data import (EXCERPTS, ErrorDraw, GaussMarkovErrors, LidarData, MapMatchingFailures,
                                ObservationErrors, WhiteErrors, load_kitti, simulate_lidar_poses)

SIGMA_P, SIGMA_A_DEG = 0.2, 0.3
SIGMA6 = np.r_[np.full(3, SIGMA_P), np.full(3, np.deg2rad(SIGMA_A_DEG))]   # per component, m and rad
N_SE = 5.0


def draw(model, t, seed):
    return model.draw(t, np.random.default_rng(seed))


def failures_model(base=None, **kw):
    params = dict(jump_rate=0.02, jump_position=2.0, jump_attitude_deg=1.5, jump_duration=3.0,
                  outlier_rate=0.01, outlier_position=5.0, outlier_attitude_deg=4.0)
    params.update(kw)
    return MapMatchingFailures(base or WhiteErrors(SIGMA_P, SIGMA_A_DEG), **params)


def autocorrelation(x, lag):
    """Sample autocorrelation of the columns of x (n, m) at ``lag`` (mean removed)."""
    x = x - x.mean(axis=0)
    return (x[lag:] * x[:-lag]).sum(axis=0) / (x * x).sum(axis=0)


# ---------------------------------------------------------------------------------------
# White: the shipped draw
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("name", EXCERPTS)
def test_the_shipped_lidar_draw_is_reproduced_byte_for_byte(name):
    ex = load_kitti(name)
    default = simulate_lidar_poses(ex.truth, ex.lidar.seed)
    explicit = simulate_lidar_poses(ex.truth, ex.lidar.seed,
                                    errors=WhiteErrors(ex.lidar.sigma_position, ex.lidar.sigma_attitude_deg))
    for lidar in (default, explicit):
        for field in ("t", "position", "quaternion", "rotation"):
            np.testing.assert_array_equal(getattr(lidar, field), getattr(ex.lidar, field), err_msg=field)
        assert lidar.error_model == ex.lidar.error_model == "white"
        assert lidar.failures is None and ex.lidar.failures is None
        assert (lidar.sigma_position, lidar.sigma_attitude_deg, lidar.seed) == (0.2, 0.3, ex.lidar.seed)


def test_white_draw_consumes_the_generator_as_the_shipped_draw():
    t = np.arange(50) * 0.1
    rng = np.random.default_rng(11)
    d = WhiteErrors(SIGMA_P, SIGMA_A_DEG).draw(t, rng)
    ref = np.random.default_rng(11)
    n_p, n_theta = ref.standard_normal((50, 3)), ref.standard_normal((50, 3))   # n_p first, then n_θ
    np.testing.assert_array_equal(d.position, SIGMA_P * n_p)
    np.testing.assert_array_equal(d.attitude, np.deg2rad(SIGMA_A_DEG) * n_theta)
    assert d.error.shape == (50, 6) and d.failures is None and d.jump_times is None
    assert rng.random() == ref.random()                     # nothing more was taken


# ---------------------------------------------------------------------------------------
# Gauss–Markov
# ---------------------------------------------------------------------------------------

def test_gauss_markov_has_the_white_sigma_and_exponential_autocorrelation():
    dt, tau, K = 0.1, 1.0, 200_000
    phi = np.exp(-dt / tau)
    x = draw(GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, tau), np.arange(K) * dt, 3).error / SIGMA6
    # variance of an AR(1) with unit variance: Var(s²) ≈ (2/K)(1 + φ²)/(1 − φ²)
    se_var = np.sqrt(2.0 / K * (1 + phi**2) / (1 - phi**2))
    np.testing.assert_allclose(x.var(axis=0), 1.0, atol=N_SE * se_var)
    for lag in (1, 5, 20):
        # Bartlett's variance of r_k for an AR(1): (1/K)[(1+φ²)(1−φ^2k)/(1−φ²) − 2kφ^2k]
        rho = phi**lag
        se = np.sqrt(((1 + phi**2) * (1 - rho**2) / (1 - phi**2) - 2 * lag * rho**2) / K)
        np.testing.assert_allclose(autocorrelation(x, lag), np.exp(-lag * dt / tau), atol=N_SE * se,
                                   err_msg=f"lag {lag}")
    # the six components are independent; the sample correlation of two independent AR(1)
    # with the same φ has variance (1/K)(1 + φ²)/(1 − φ²)
    off = np.corrcoef(x.T)[~np.eye(6, dtype=bool)]
    assert np.abs(off).max() < N_SE * np.sqrt((1 + phi**2) / (1 - phi**2) / K)


def test_gauss_markov_with_a_vanishing_time_constant_is_the_white_draw():
    t = np.arange(2000) * 0.1
    white = draw(WhiteErrors(SIGMA_P, SIGMA_A_DEG), t, 5).error
    # exp(−0.1/1e-6) underflows to 0: every step is a fresh white sample, bit for bit
    np.testing.assert_array_equal(draw(GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, 1e-6), t, 5).error, white)
    # τ = 5 ms: φ = exp(−20) ≈ 2e-9, white to that relative size
    np.testing.assert_allclose(draw(GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, 5e-3), t, 5).error, white,
                               rtol=0, atol=1e-8 * np.abs(white).max())


def test_gauss_markov_with_a_long_time_constant_barely_moves():
    t = np.arange(100) * 0.1
    tau = 1e4
    e = draw(GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, tau), t, 9).error
    # e_k − e_0 ~ N(0, 2σ²(1 − exp(−(t_k − t_0)/τ))): at most 6 of its σ over 600 values
    spread = SIGMA6 * np.sqrt(2 * (1 - np.exp(-(t - t[0]) / tau)))[:, None]
    assert np.all(np.abs(e - e[0]) <= 6 * spread)
    assert np.abs(e[0]).max() > 10 * spread.max()               # while e_0 itself has the full σ


def test_gauss_markov_follows_its_recursion_on_irregular_steps():
    t = np.cumsum(np.random.default_rng(0).uniform(0.01, 0.8, 300))
    tau = 0.4
    e = draw(GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, tau), t, 21).error
    rng = np.random.default_rng(21)
    n = np.hstack([rng.standard_normal((300, 3)), rng.standard_normal((300, 3))])
    expected = np.empty_like(n)
    expected[0] = SIGMA6 * n[0]
    for k in range(1, 300):
        phi = np.exp(-(t[k] - t[k - 1]) / tau)
        expected[k] = phi * expected[k - 1] + SIGMA6 * np.sqrt(1 - phi**2) * n[k]
    np.testing.assert_allclose(e, expected, rtol=1e-10, atol=1e-14)


def test_gauss_markov_correlation_follows_each_irregular_step():
    # M independent short sequences with steps 0.1, 1.0 and 0.2 s: the products x_i x_j
    # (unit variance) are independent across sequences and the six components, so their
    # mean has standard error sqrt((1 + ρ²) / (6 M)); a variance has sqrt(2 / (6 M))
    t = np.array([0.0, 0.1, 1.1, 1.3])
    tau, M = 0.5, 4000
    model = GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, tau)
    rng = np.random.default_rng(4)
    x = np.stack([model.draw(t, rng).error / SIGMA6 for _ in range(M)])       # (M, 4, 6)
    for i in range(4):
        assert abs((x[:, i] ** 2).mean() - 1.0) < N_SE * np.sqrt(2 / (6 * M)), f"variance at t[{i}]"
        for j in range(i + 1, 4):
            rho = np.exp(-(t[j] - t[i]) / tau)
            se = np.sqrt((1 + rho**2) / (6 * M))
            assert abs((x[:, i] * x[:, j]).mean() - rho) < N_SE * se, f"corr(t[{i}], t[{j}])"


# ---------------------------------------------------------------------------------------
# Map-matching failures
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("base", [WhiteErrors(SIGMA_P, SIGMA_A_DEG), GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, 1.0)],
                         ids=["white", "gauss-markov"])
def test_failures_at_rate_zero_give_the_base_draw_exactly(base):
    t = np.cumsum(np.full(500, 0.1))
    none = failures_model(base, jump_rate=0.0, outlier_rate=0.0)
    d = draw(none, t, 8)
    np.testing.assert_array_equal(d.error, draw(base, t, 8).error)
    assert not d.failures.any() and d.jump_times.size == 0
    assert none.sigma_position == base.sigma_position and none.sigma_attitude_deg == base.sigma_attitude_deg


def test_failure_mask_marks_exactly_the_rows_that_differ_from_the_base():
    t = np.cumsum(np.random.default_rng(1).uniform(0.05, 0.15, 20_000))
    base = GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, 0.5)
    model = failures_model(base, jump_rate=0.05, outlier_rate=0.02)
    d, b = draw(model, t, 13), draw(base, t, 13)             # the base draw comes first
    changed = np.any(d.error != b.error, axis=1)
    assert changed.any() and not changed.all()
    np.testing.assert_array_equal(d.failures, changed)
    held = np.zeros(len(t), dtype=bool)
    for start in d.jump_times:
        held |= (t >= start) & (t < start + model.jump_duration)
    np.testing.assert_array_equal(d.jumps, held)
    np.testing.assert_array_equal(d.failures, d.jumps | d.outliers)
    assert np.all(np.diff(d.jump_times) >= 0)
    assert d.jump_times.min() >= t[0] - model.jump_duration and d.jump_times.max() <= t[-1]


def test_jumps_occur_at_their_rate_hold_their_offset_and_cover_the_expected_fraction():
    dt, K = 0.1, 500_000
    t = np.arange(K) * dt
    lam, dur = 0.02, 3.0
    model = failures_model(jump_rate=lam, jump_duration=dur, outlier_rate=0.0)
    d, b = draw(model, t, 17), draw(model.base, t, 17)
    # starts are Poisson over a span of T + duration: count standard error sqrt(λ (T + d))
    expected = lam * (t[-1] - t[0] + dur)
    assert abs(len(d.jump_times) - expected) < N_SE * np.sqrt(expected)
    # fraction of observations inside a jump: 1 − exp(−λ d); for this Poisson boolean
    # model the fraction over a span T has variance (2/T)[e^{−λd}(1 − e^{−λd})/λ − d e^{−2λd}]
    q = np.exp(-lam * dur)
    se = np.sqrt(2 / (t[-1] - t[0]) * (q * (1 - q) / lam - dur * q**2))
    assert abs(d.jumps.mean() - (1 - q)) < N_SE * se
    # within one jump the offset is constant; across jumps its σ is the one given
    diff = (d.error - b.error)[d.jumps]
    latest = (np.searchsorted(d.jump_times, t, side="right") - 1)[d.jumps]      # the jump held
    _, first, which = np.unique(latest, return_index=True, return_inverse=True)
    offsets = diff[first]
    np.testing.assert_allclose(diff, offsets[which], rtol=0, atol=1e-12)
    size = np.r_[np.full(3, model.jump_position), np.full(3, np.deg2rad(model.jump_attitude_deg))]
    # σ̂ from n·3 normal values: standard error of σ̂/σ ≈ 1/sqrt(2·3n)
    n = len(offsets)
    for block in (slice(0, 3), slice(3, 6)):
        sigma_hat = np.sqrt((offsets[:, block] ** 2).mean())
        assert abs(sigma_hat / size[block][0] - 1) < N_SE / np.sqrt(6 * n)


def test_outliers_occur_at_their_rate_with_their_size():
    K, p = 500_000, 0.01
    t = np.arange(K) * 0.1
    model = failures_model(jump_rate=0.0, outlier_rate=p)
    d, b = draw(model, t, 19), draw(model.base, t, 19)
    # binomial count: standard error sqrt(K p (1 − p))
    assert abs(d.outliers.sum() - K * p) < N_SE * np.sqrt(K * p * (1 - p))
    np.testing.assert_array_equal(d.failures, d.outliers)
    extra = (d.error - b.error)[d.outliers]
    size = np.r_[np.full(3, model.outlier_position), np.full(3, np.deg2rad(model.outlier_attitude_deg))]
    n = len(extra)
    for block in (slice(0, 3), slice(3, 6)):
        sigma_hat = np.sqrt((extra[:, block] ** 2).mean())
        assert abs(sigma_hat / size[block][0] - 1) < N_SE / np.sqrt(6 * n)   # 1/sqrt(2·3n)
    # an outlier is a single observation: its neighbours are clean unless outliers themselves
    k = np.flatnonzero(d.outliers[1:-1]) + 1
    assert np.mean(d.outliers[k + 1]) < p + N_SE * np.sqrt(p * (1 - p) / len(k))


def test_every_outlier_probability_between_0_and_1_is_accepted():
    t = np.arange(200) * 0.1
    assert draw(failures_model(outlier_rate=1.0, jump_rate=0.0), t, 2).outliers.all()
    assert not draw(failures_model(outlier_rate=0.0, jump_rate=0.0), t, 2).outliers.any()


# ---------------------------------------------------------------------------------------
# Determinism and the lidar record
# ---------------------------------------------------------------------------------------

MODELS = [WhiteErrors(SIGMA_P, SIGMA_A_DEG), GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, 1.0),
          failures_model(GaussMarkovErrors(SIGMA_P, SIGMA_A_DEG, 1.0), jump_rate=0.1, outlier_rate=0.05)]


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.describe())
def test_draws_are_determined_by_the_seed(model):
    t = np.cumsum(np.random.default_rng(0).uniform(0.05, 0.2, 600))
    a, b, c = draw(model, t, 7), draw(model, t, 7), draw(model, t, 8)
    np.testing.assert_array_equal(a.error, b.error)
    assert np.abs(a.error - c.error).max() > 0.1 * SIGMA_P
    if a.failures is not None:
        np.testing.assert_array_equal(a.failures, b.failures)
        np.testing.assert_array_equal(a.jump_times, b.jump_times)
    for arr in (a.error, a.failures):
        assert arr is None or not arr.flags.writeable


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.describe())
def test_simulated_lidar_applies_the_model_errors_with_attitude_on_the_right(model):
    truth = load_kitti("turns").truth
    lidar = simulate_lidar_poses(truth, 31, errors=model)
    d = draw(model, truth.t, 31)
    np.testing.assert_allclose(lidar.position, truth.position + d.position, rtol=0, atol=1e-12)
    np.testing.assert_allclose(lidar.rotation, truth.rotation @ so3.exp(d.attitude), rtol=0, atol=1e-12)
    # the body-frame error: Log(Rᵀ R_obs) is the drawn δθ; on the left it would not be
    np.testing.assert_allclose(so3.log(np.swapaxes(truth.rotation, 1, 2) @ lidar.rotation), d.attitude,
                               atol=1e-9)
    left = so3.log(lidar.rotation @ np.swapaxes(truth.rotation, 1, 2))
    assert np.abs(left - d.attitude).max() > 10 * 1e-9
    assert lidar.error_model == model.describe() and lidar.simulated
    assert (lidar.sigma_position, lidar.sigma_attitude_deg) == (SIGMA_P, SIGMA_A_DEG)
    if isinstance(model, MapMatchingFailures):
        np.testing.assert_array_equal(lidar.failures, d.failures)
        assert not lidar.failures.flags.writeable
        sub = lidar.select(slice(10, 40))
        np.testing.assert_array_equal(sub.failures, lidar.failures[10:40])
        assert sub.error_model == lidar.error_model
    else:
        assert lidar.failures is None


def test_descriptions_name_the_model_and_its_parameters():
    assert WhiteErrors(0.2, 0.3).describe() == "white"
    assert GaussMarkovErrors(0.2, 0.3, 0.5).describe() == "Gauss–Markov, τ = 0.5 s"
    text = failures_model(GaussMarkovErrors(0.2, 0.3, 3.0)).describe()
    assert text.startswith("Gauss–Markov, τ = 3 s + jumps 0.02/s × 3 s (2 m, 1.5°)")
    assert text.endswith("+ outliers 1% (5 m, 4°)")
    assert "outliers" not in failures_model(outlier_rate=0.0).describe()
    assert "no failures" in failures_model(jump_rate=0.0, outlier_rate=0.0).describe()
    assert all(isinstance(m, ObservationErrors) for m in MODELS)


def test_single_observation_and_error_draw_record():
    for model in MODELS:
        d = draw(model, [5.0], 1)
        assert isinstance(d, ErrorDraw) and d.error.shape == (1, 6) and len(d) == 1


# ---------------------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("make,msg", [
    (lambda: WhiteErrors(-0.1, 0.3), "sigma_position must be a finite non-negative number"),
    (lambda: WhiteErrors(0.2, float("nan")), "sigma_attitude_deg must be a finite non-negative number"),
    (lambda: GaussMarkovErrors(0.2, -0.3, 1.0), "sigma_attitude_deg must be a finite non-negative number"),
    (lambda: GaussMarkovErrors(0.2, 0.3, 0.0), "time_constant must be a finite positive number"),
    (lambda: GaussMarkovErrors(0.2, 0.3, -1.0), "time_constant must be a finite positive number"),
    (lambda: failures_model(jump_rate=-0.1), "jump_rate must be a finite non-negative number"),
    (lambda: failures_model(jump_position=-1.0), "jump_position must be a finite non-negative number"),
    (lambda: failures_model(outlier_rate=-0.01), "outlier_rate must be a finite non-negative number"),
    (lambda: failures_model(outlier_rate=1.5), r"outlier_rate must be a probability in \[0, 1\]"),
    (lambda: failures_model(outlier_attitude_deg=-2.0), "outlier_attitude_deg must be a finite non-negative"),
    (lambda: failures_model(jump_duration=0.0), "jump_duration must be positive when jump_rate > 0"),
    (lambda: failures_model(jump_position=0.0, jump_attitude_deg=0.0), "jump_position or jump_attitude_deg"),
    (lambda: failures_model(outlier_position=0.0, outlier_attitude_deg=0.0), "outlier_position or outlier_att"),
    (lambda: MapMatchingFailures("white"), "base must be a WhiteErrors or GaussMarkovErrors"),
    (lambda: MapMatchingFailures(failures_model()), "base must be a WhiteErrors or GaussMarkovErrors"),
])
def test_bad_parameters_are_named(make, msg):
    with pytest.raises(ValueError, match=msg):
        make()


@pytest.mark.parametrize("model", MODELS, ids=lambda m: m.describe())
@pytest.mark.parametrize("t,make_rng,msg", [
    ([0.0, 0.1, 0.1, 0.3], np.random.default_rng, r"t must be strictly increasing: t\[2\] = 0.1 <= t\[1\] = 0.1"),
    ([0.0, 0.2, 0.1], np.random.default_rng, r"t must be strictly increasing: t\[2\]"),
    (np.zeros((4, 1)), np.random.default_rng, r"t must be a 1-D array of shape \(K,\), got shape \(4, 1\)"),
    ([0.0, np.nan], np.random.default_rng, r"t\[1\] is NaN"),
    ([0.0, 0.1], int, "rng must be a numpy.random.Generator"),
    ([0.0, 0.1], np.random.RandomState, "rng must be a numpy.random.Generator"),
], ids=["repeated", "decreasing", "2-D", "NaN", "seed-not-generator", "RandomState"])
def test_bad_draw_arguments_are_named(model, t, make_rng, msg):
    with pytest.raises(ValueError, match=msg):
        model.draw(t, make_rng(0))


def test_simulate_lidar_poses_rejects_a_model_that_is_not_one_or_contradicts_the_sigmas():
    truth = load_kitti("cruise").truth
    with pytest.raises(ValueError, match="errors must be None or an error model"):
        simulate_lidar_poses(truth, 1, errors="gauss-markov")
    with pytest.raises(ValueError, match="contradict errors"):
        simulate_lidar_poses(truth, 1, 0.5, 0.3, errors=GaussMarkovErrors(0.2, 0.3, 1.0))
    # the σ arguments may repeat the model's
    lidar = simulate_lidar_poses(truth, 1, 0.4, 0.6, errors=GaussMarkovErrors(0.4, 0.6, 1.0))
    assert (lidar.sigma_position, lidar.sigma_attitude_deg) == (0.4, 0.6)


def test_lidar_record_checks_its_failure_mask():
    lidar = load_kitti("cruise").lidar
    args = (lidar.t, lidar.position, lidar.rotation, lidar.quaternion, 0.2, 0.3, 1)
    with pytest.raises(ValueError, match=r"failures must be None or a boolean array of shape \(294,\)"):
        LidarData(*args, failures=np.zeros(10, dtype=bool))
    with pytest.raises(ValueError, match="failures must be None or a boolean array"):
        LidarData(*args, failures=np.zeros(len(lidar)))
    with pytest.raises(ValueError, match="error_model must be a non-empty string"):
        LidarData(*args, error_model="")
