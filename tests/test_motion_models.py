"""Planar motion models and the radar observation: derived Jacobians against finite
differences, the ω → 0 branch, and agreement with independent numerics (ODE integration)."""

import numpy as np
import pytest

from kalman_course import symbolic

MODELS = symbolic.MOTION_MODELS


def _random_state(model, rng, omega=None):
    n = len(symbolic.motion_state_names(model))
    x = rng.normal(size=n) * 3.0
    x[:2] += rng.uniform(5, 20, size=2) * rng.choice([-1, 1], size=2)
    if model in ("ctrv", "ctra"):
        x[2] = rng.uniform(1, 15)
        x[3] = rng.uniform(-np.pi, np.pi)
        x[4] = rng.uniform(-0.8, 0.8) if omega is None else omega
    return x


def _numeric_jacobian(fn, x, eps=1e-6):
    cols = []
    for i in range(len(x)):
        dx = np.zeros(len(x))
        dx[i] = eps
        cols.append((fn(x + dx) - fn(x - dx)) / (2 * eps))
    return np.column_stack(cols)


# omegas: generic, tiny (series branch), exactly zero, and either side of the switch
OMEGAS = [None, 1e-9, 0.0, -3e-4]


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("omega", OMEGAS)
def test_motion_jacobian_matches_finite_differences(model, omega):
    # a fixed seed per case (hash() of a str changes from one process to the next)
    rng = np.random.default_rng(10 * MODELS.index(model) + OMEGAS.index(omega))
    for _ in range(5):
        x = _random_state(model, rng, omega)
        T = rng.uniform(0.01, 1.0)
        F = symbolic.motion_jacobian(model, x, T)
        # differentiate the exact closed form where it is accurate, else the model itself
        num = _numeric_jacobian(lambda s: symbolic.motion_step(model, s, T), x, eps=1e-6)
        np.testing.assert_allclose(F, num, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("model", MODELS)
def test_noise_jacobian_matches_finite_differences(model):
    rng = np.random.default_rng(7)
    for omega in (None, 0.0):
        x = _random_state(model, rng, omega)
        T = 0.3
        B = symbolic.motion_noise_jacobian(model, x, T)
        num = _numeric_jacobian(lambda w: symbolic.motion_step(model, x, T, w), np.zeros(2))
        np.testing.assert_allclose(B, num, rtol=1e-7, atol=1e-9)


@pytest.mark.parametrize("model", ["ctrv", "ctra"])
def test_turning_models_are_continuous_through_the_series_switch(model):
    rng = np.random.default_rng(3)
    x = _random_state(model, rng)
    T = 0.5
    w_switch = symbolic.OMEGA_SERIES_THRESHOLD / T
    for w in (w_switch, -w_switch):
        below, above = x.copy(), x.copy()
        below[4], above[4] = w * (1 - 1e-9), w * (1 + 1e-9)
        f_b, f_a = symbolic.motion_step(model, below, T), symbolic.motion_step(model, above, T)
        np.testing.assert_allclose(f_b, f_a, rtol=0, atol=1e-10)
        F_b, F_a = symbolic.motion_jacobian(model, below, T), symbolic.motion_jacobian(model, above, T)
        np.testing.assert_allclose(F_b, F_a, rtol=0, atol=1e-8)
    # at ω = 0 the model is finite and is the straight line
    x[4] = 0.0
    f = symbolic.motion_step(model, x, T)
    assert np.all(np.isfinite(symbolic.motion_jacobian(model, x, T)))
    a = x[5] if model == "ctra" else 0.0
    dist = x[2] * T + a * T**2 / 2
    np.testing.assert_allclose(f[:2], x[:2] + dist * np.array([np.cos(x[3]), np.sin(x[3])]), atol=1e-12)


def test_ctrv_step_is_the_flow_of_its_ode():
    # independent numerics: the CTRV ODE integrated by scipy, then the noise entering as B w
    from scipy.integrate import solve_ivp

    def ctrv_ode(t, s):
        return [s[2] * np.cos(s[3]), s[2] * np.sin(s[3]), 0.0, s[4], 0.0]

    rng = np.random.default_rng(11)
    for omega in (None, None, 0.0, 1e-7, -3e-4):  # closed form and series branch
        x = _random_state("ctrv", rng, omega)
        w = rng.normal(size=2)
        for T in (0.05, 0.7):
            sol = solve_ivp(ctrv_ode, (0.0, T), x, rtol=1e-12, atol=1e-12)
            np.testing.assert_allclose(symbolic.ctrv_step(x, T), sol.y[:, -1], rtol=1e-9, atol=1e-9)
            np.testing.assert_allclose(symbolic.ctrv_step(x, T, w) - symbolic.ctrv_step(x, T),
                                       symbolic.ctrv_noise_jacobian(x, T) @ w, rtol=1e-12, atol=1e-12)


def test_radar_observation_is_range_bearing_range_rate():
    rng = np.random.default_rng(12)
    for _ in range(5):
        x = _random_state("ctrv", rng)
        p, v = x[:2], x[2] * np.array([np.cos(x[3]), np.sin(x[3])])
        rho = np.hypot(*p)
        expected = [rho, np.arctan2(p[1], p[0]), p @ v / rho]
        np.testing.assert_allclose(symbolic.radar_observation(x), expected, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(symbolic.radar_observation(np.r_[p, v], "cv"), expected, rtol=1e-12, atol=1e-12)


def test_ctra_with_zero_acceleration_is_ctrv():
    rng = np.random.default_rng(5)
    x = _random_state("ctrv", rng)
    np.testing.assert_allclose(symbolic.motion_step("ctra", np.r_[x, 0.0], 0.4)[:5],
                               symbolic.ctrv_step(x, 0.4), atol=1e-12)


def test_cv_planar_matches_the_chapter_03_matrices():
    x = np.array([1.0, 2.0, 3.0, -1.0])
    T = 0.7
    np.testing.assert_allclose(symbolic.motion_jacobian("cv", x, T), symbolic.cv_transition(T, 2))
    B = symbolic.motion_noise_jacobian("cv", x, T)
    np.testing.assert_allclose(B @ B.T * 4.0, symbolic.cv_process_noise(T, 2.0, 2))


@pytest.mark.parametrize("model", MODELS)
def test_radar_jacobian_matches_finite_differences_including_near_the_branch_cut(model):
    rng = np.random.default_rng(17)
    n = len(symbolic.motion_state_names(model))
    for bearing in (0.3, 2.0, np.pi - 1e-4, -np.pi + 1e-4, -1.2):
        x = _random_state(model, rng)
        r = rng.uniform(2, 30)
        x[:2] = r * np.cos(bearing), r * np.sin(bearing)
        G = symbolic.radar_jacobian(x, model)
        assert G.shape == (3, n)

        def h(s):
            return symbolic.radar_observation(s, model)

        # difference of wrapped bearings, so the ±π jump does not enter
        cols = []
        for i in range(n):
            dx = np.zeros(n)
            dx[i] = 1e-6
            d = h(x + dx) - h(x - dx)
            d[1] = (d[1] + np.pi) % (2 * np.pi) - np.pi
            cols.append(d / 2e-6)
        np.testing.assert_allclose(G, np.column_stack(cols), rtol=1e-6, atol=1e-7)


def test_radar_rejects_the_origin_and_bad_shapes():
    with pytest.raises(ValueError, match="range 0"):
        symbolic.radar_observation(np.zeros(5))
    with pytest.raises(ValueError, match="shape"):
        symbolic.radar_jacobian(np.ones(4))  # ctrv needs 5


def test_models_validate_their_inputs():
    with pytest.raises(ValueError, match="model must be one of"):
        symbolic.motion_step("bicycle", np.zeros(5), 0.1)
    with pytest.raises(ValueError, match=r"x must have shape \(5,\).*'p_x', 'p_y', 'v', 'psi', 'omega'"):
        symbolic.motion_step("ctrv", np.zeros(4), 0.1)
    with pytest.raises(ValueError, match="T must be a real number"):
        symbolic.motion_step("cv", np.zeros(4), "0.1")
    with pytest.raises(ValueError, match="w must have shape"):
        symbolic.motion_step("ca", np.zeros(6), 0.1, w=np.zeros(3))
    with pytest.raises(ValueError, match="sigmas must have shape"):
        symbolic.motion_process_noise("ctra", np.ones(6), 0.1, [1.0])
    with pytest.raises(ValueError, match="T must be"):
        symbolic.motion_step("ctrv", np.zeros(5), -1.0)
    with pytest.raises(ValueError, match="finite"):
        symbolic.motion_jacobian("ca", np.full(6, np.nan), 0.1)


@pytest.mark.parametrize("name", ["cv_planar_model", "ca_model", "ctrv_model", "ctra_model", "radar_model"])
def test_model_derivations_are_registered_and_prove(name):
    d = symbolic.derivations()[name]
    assert d.verify()


@pytest.mark.parametrize("model, name", list(zip(MODELS, ["cv_planar_model", "ca_model", "ctrv_model", "ctra_model"])))
def test_state_names_are_the_derivations_state(model, name):
    d = symbolic.derivation(name)
    state = [str(s) for s in d["initial"].rhs]  # f(x, 0, 0) = x
    assert list(symbolic.motion_state_names(model)) == state


def test_numeric_models_are_lambdified_once():
    from kalman_course.symbolic import motion, radar

    x = np.array([1.0, 2.0, 3.0, 0.4, 0.3])
    symbolic.ctrv_step(x, 0.1)
    symbolic.radar_observation(x)
    assert motion._model_functions("ctrv") is motion._model_functions("ctrv")
    assert radar._radar_functions() is radar._radar_functions()
    assert motion._model_functions.cache_info().currsize >= 1


# ---------------------------------------------------------------- chapter 04 on KITTI

def test_kitti_model_states_are_consistent_across_models():
    from kalman_course.chapters import motion

    t = np.array([320.0, 330.0, 340.0])
    _, cv = motion.kitti_model_states("turns", "cv", t)
    _, ctra = motion.kitti_model_states("turns", "ctra", t)
    _, ca = motion.kitti_model_states("turns", "ca", t)
    assert cv.shape == (3, 4) and ctra.shape == (3, 6) and ca.shape == (3, 6)
    np.testing.assert_allclose(cv[:, :2], ctra[:, :2])
    np.testing.assert_allclose(np.hypot(cv[:, 2], cv[:, 3]), ctra[:, 2])
    np.testing.assert_allclose(ctra[:, 2] * np.cos(ctra[:, 3]), cv[:, 2], atol=1e-12)
    np.testing.assert_allclose(ca[:, :4], cv)
    with pytest.raises(ValueError, match="model must be one of"):
        motion.kitti_model_states("turns", "bicycle", t)


def test_prediction_error_grows_with_the_horizon_and_short_horizons_are_good():
    from kalman_course.chapters import motion

    err = motion.horizon_errors("cruise", horizons=(0.5, 1.0, 2.0, 4.0))
    assert err.rms.shape == (4, 4) and err.n_starts > 10
    assert np.all(np.diff(err.rms, axis=1) > 0)
    assert np.all(err.rms[:, 0] < 0.2)            # half a second ahead: decimetres at most
    assert np.all(err.p95 >= 0)
    t, truth, paths = motion.predicted_paths("cruise", 430.0, 2.0, n=5)
    assert t.shape == (5,) and truth.shape == (5, 2)
    for path in paths.values():
        np.testing.assert_allclose(path[0], truth[0], atol=0.05)   # every model starts on the truth


def test_causal_states_use_nothing_after_the_start_time():
    from kalman_course.chapters import motion
    from kalman_course.data import load_kitti

    ex = load_kitti("turns")
    t = np.array([320.0, 330.05, 340.0])
    _, ca = motion.kitti_model_states("turns", "ca", t, causal=True)
    _, ctra = motion.kitti_model_states("turns", "ctra", t, causal=True)
    v_now, v_before = ex.truth.interpolate(t).velocity[:, :2], ex.truth.interpolate(t - 1.0).velocity[:, :2]
    np.testing.assert_allclose(ca[:, 4:6], v_now - v_before, rtol=1e-12, atol=1e-12)   # backward, 1 s wide
    last = np.searchsorted(ex.imu.t, t, side="right") - 1
    assert np.all(ex.imu.t[last] <= t)
    np.testing.assert_allclose(ctra[:, 4], ex.imu.angular_rate[last, 2])
    # the centred state differs: it reads the velocity half a second ahead
    _, ca_centred = motion.kitti_model_states("turns", "ca", t, causal=False)
    assert not np.allclose(ca_centred[:, 4:6], ca[:, 4:6])
    np.testing.assert_allclose(ca_centred[:, :4], ca[:, :4])


def test_the_future_flatters_the_acceleration_models_on_kitti():
    from kalman_course.chapters import motion

    kw = dict(horizons=(0.5, 1.0), models=("ca", "ctra"))
    causal, centred = motion.horizon_errors("turns", causal=True, **kw), motion.horizon_errors("turns", causal=False, **kw)
    assert causal.n_starts == centred.n_starts
    assert np.all(causal.rms > centred.rms)


@pytest.mark.parametrize("model", ["ctrv", "ctra"])
def test_noise_inside_step_is_the_flow_of_the_noisy_ode(model):
    from scipy.integrate import solve_ivp

    from kalman_course.chapters import motion

    def ode(t, s, w):
        ds = [s[2] * np.cos(s[3]), s[2] * np.sin(s[3]), w[0], s[4], w[1]]
        if model == "ctra":
            ds[2] = s[5]
            ds.append(w[0])
        return ds

    rng = np.random.default_rng(21)
    for omega in (None, 0.0):
        x = _random_state(model, rng, omega)
        for T in (0.1, 1.0):
            w = rng.normal(size=(3, 2)) * [2.0, 0.5]
            got = motion.noise_inside_step(model, x, T, w)
            assert got.shape == (3, len(x))
            for wi, gi in zip(w, got):
                sol = solve_ivp(ode, (0.0, T), x, args=(wi,), rtol=1e-12, atol=1e-12)
                np.testing.assert_allclose(gi, sol.y[:, -1], rtol=1e-9, atol=1e-9)
            # zero noise: the course's exact noise-free step
            np.testing.assert_allclose(motion.noise_inside_step(model, x, T, [0.0, 0.0]),
                                       symbolic.motion_step(model, x, T), rtol=1e-10, atol=1e-10)


def test_noise_inside_step_differs_from_the_linear_noise_model_where_the_yaw_noise_moves_the_position():
    from kalman_course.chapters import motion

    x = np.array([0.0, 0.0, 15.0, 0.0, 0.0])
    end = motion.noise_inside_step("ctrv", x, 1.0, [0.0, 0.5])
    linear = symbolic.motion_step("ctrv", x, 1.0, [0.0, 0.5])
    assert linear[1] == 0.0                      # B does not move the position sideways
    assert abs(end[1] - 15.0 * 0.5 / 6) < 0.01   # v nu T^3 / 6, to leading order
    np.testing.assert_allclose(end[2:], linear[2:], atol=1e-12)   # speed, heading, turn rate agree


def test_noise_covariance_check_holds_for_short_steps_and_not_for_long_ones():
    from kalman_course.chapters import motion

    x = np.array([1.0, 2.0, 15.0, 0.4, 0.3])
    short = motion.noise_covariance_check("ctrv", x, 0.1, [2.0, 0.5], seeds=range(3), n_samples=20_000)
    long = motion.noise_covariance_check("ctrv", x, 1.0, [2.0, 0.5], seeds=range(3), n_samples=20_000)
    assert short.ratio.shape == (3,) and np.all(np.abs(short.ratio - 1) < 0.05)
    assert np.all(long.ratio > 2.0)
    assert abs(np.median(long.ratio) / long.predicted_ratio - 1) < 0.05
    assert np.all(long.cross_track_std > 1.0) and np.all(short.cross_track_std < 0.01)
    with pytest.raises(ValueError, match="model must be"):
        motion.noise_covariance_check("ca", np.zeros(6), 0.1, [1.0, 1.0])
    with pytest.raises(ValueError, match="w must have shape"):
        motion.noise_inside_step("ctrv", x, 0.1, [1.0, 2.0, 3.0])
