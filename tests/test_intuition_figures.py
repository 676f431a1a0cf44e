"""Tests for the intuition layer: kalman_course.chapters.intuition (the numbers) and
kalman_course.plotting.intuition / plotting.diagrams (the figures). Agg backend (conftest)."""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.patches import Ellipse

from kalman_course import ekf, gaussians, kf, plotting, symbolic
from kalman_course.chapters import beacons, intuition
from kalman_course.core.numdiff import numerical_jacobian
from kalman_course.plotting import diagrams


@pytest.fixture(autouse=True)
def close_all():
    yield
    plt.close("all")


def _renderer(fig):
    fig.canvas.draw()
    return fig.canvas.get_renderer()


def _points_along(line, per_segment=40):
    """Display coordinates of points along a line (its vertices and between them)."""
    xy = line.get_transform().transform(np.asarray(line.get_xydata(), dtype=float))
    xy = xy[np.all(np.isfinite(xy), axis=1)]
    if len(xy) < 2:
        return xy
    s = np.linspace(0.0, 1.0, per_segment)[:, None]
    return np.vstack([a + s * (b - a) for a, b in zip(xy[:-1], xy[1:])])


def _legend_covers_no_line(ax):
    legend = ax.get_legend()
    box = legend.get_window_extent(_renderer(ax.figure))
    for line in ax.lines:
        pts = _points_along(line)
        inside = ((pts[:, 0] > box.x0) & (pts[:, 0] < box.x1) & (pts[:, 1] > box.y0) & (pts[:, 1] < box.y1))
        assert not inside.any(), f"the legend covers {line.get_label()!r}"


# --------------------------------------------------------------------------------------
# chapter 03: the scalar filter, by hand
# --------------------------------------------------------------------------------------

YS = [1.5, 2.1, 1.4, 2.6, 2.3]


def test_scalar_table_follows_the_hand_formulas():
    t = intuition.kf_1d_table(0.0, 2.0, YS, q=0.1, r=0.5)
    assert len(t) == 5 and t.q == 0.1 and t.r == 0.5
    x_check, P_check = 0.0, 2.0
    for k, y in enumerate(YS):
        K = P_check / (P_check + 0.5)
        x_hat, P_hat = x_check + K * (y - x_check), (1 - K) * P_check
        assert np.allclose([t.x_check[k], t.P_check[k], t.y[k], t.K[k], t.x_hat[k], t.P_hat[k]],
                           [x_check, P_check, y, K, x_hat, P_hat], rtol=1e-12, atol=1e-12)
        x_check, P_check = x_hat, P_hat + 0.1
    # the two steps worked out by hand in the lecture
    assert np.allclose([t.K[0], t.x_hat[0], t.P_hat[0]], [0.8, 1.2, 0.4])
    assert np.allclose([t.P_check[1], t.K[1], t.x_hat[1], t.P_hat[1]], [0.5, 0.5, 1.65, 0.25])


def test_scalar_posterior_is_the_normalised_product_of_prior_and_likelihood():
    t = intuition.kf_1d_table(-1.0, 3.0, YS, q=0.2, r=0.7)
    for k in range(len(t)):
        mean, cov = gaussians.product([t.x_check[k]], [[t.P_check[k]]], [t.y[k]], [[t.r]])
        assert np.isclose(mean[0], t.x_hat[k]) and np.isclose(cov[0, 0], t.P_hat[k])
        assert np.isclose(1 / t.P_hat[k], 1 / t.P_check[k] + 1 / t.r)      # information adds


def test_scalar_table_without_a_measurement_keeps_the_prior_and_prints_a_dash():
    t = intuition.kf_1d_table(0.0, 1.0, [0.5, np.nan, 1.0], q=0.3, r=1.0)
    assert np.isnan(t.K[1]) and t.x_hat[1] == t.x_check[1] and t.P_hat[1] == t.P_check[1]
    assert np.isclose(t.P_check[2], t.P_hat[1] + 0.3)
    lines = t.to_text().splitlines()
    assert len(lines) == 4 and "gain K" in lines[0]
    assert lines[2].count("—") == 2 and "—" not in lines[1]
    assert str(t) == t.to_text() and "0.500" in lines[1]


@pytest.mark.parametrize("kwargs, match", [
    (dict(x0=0.0, P0=0.0, ys=YS, q=0.1, r=0.5), "P0"),
    (dict(x0=0.0, P0=1.0, ys=YS, q=-0.1, r=0.5), "q"),
    (dict(x0=0.0, P0=1.0, ys=YS, q=0.1, r=0.0), "r"),
    (dict(x0=np.nan, P0=1.0, ys=YS, q=0.1, r=0.5), "x0"),
    (dict(x0=0.0, P0=1.0, ys=[[1.0, 2.0]], q=0.1, r=0.5), "ys"),
    (dict(x0=0.0, P0=1.0, ys=[], q=0.1, r=0.5), "ys"),
])
def test_scalar_table_names_a_bad_argument(kwargs, match):
    x0, P0, ys = kwargs.pop("x0"), kwargs.pop("P0"), kwargs.pop("ys")
    with pytest.raises(ValueError, match=match):
        intuition.kf_1d_table(x0, P0, ys, **kwargs)


def test_scalar_gain_formula_limits_and_broadcasting():
    rng = np.random.default_rng(0)
    P, R, g = rng.uniform(0.1, 5, 20), rng.uniform(0.1, 5, 20), 1.7
    assert np.allclose(intuition.scalar_gain(P, R, g), P * g / (g**2 * P + R))
    assert isinstance(intuition.scalar_gain(1.0, 1.0), float) and intuition.scalar_gain(1.0, 1.0) == 0.5
    assert np.isclose(intuition.scalar_gain(1.0, 1e-12, g), 1 / g, rtol=1e-9)      # R -> 0: K -> G^-1
    assert intuition.scalar_gain(1e-12, 1.0, g) < 1e-11                             # P -> 0: K -> 0
    assert intuition.scalar_gain(0.0, 1.0) == 0.0
    assert intuition.scalar_gain(np.ones((2, 3)), np.array([1.0, 2.0, 4.0])).shape == (2, 3)
    with pytest.raises(ValueError, match="R"):
        intuition.scalar_gain(1.0, 0.0)
    with pytest.raises(ValueError, match="P_check"):
        intuition.scalar_gain(-1.0, 1.0)
    with pytest.raises(ValueError, match="g"):
        intuition.scalar_gain(1.0, 1.0, 0.0)
    with pytest.raises(ValueError, match="broadcast"):
        intuition.scalar_gain(np.ones(2), np.ones(3))


def test_matrix_gain_tends_to_the_inverse_of_G_as_R_vanishes():
    """The limit the lecture states for an invertible G, with the package's gain."""
    G = np.array([[1.0, 0.5], [-0.3, 2.0]])
    P = np.array([[2.0, 0.3], [0.3, 1.0]])
    K = kf.kf_gain(P, G, kf.innovation_covariance(P, G, 1e-10 * np.eye(2)))
    assert np.allclose(K, np.linalg.inv(G), atol=1e-8)


# --------------------------------------------------------------------------------------
# chapter 03: the steady state
# --------------------------------------------------------------------------------------

def _cv(T=0.5, sigma_a=0.5, sigma=2.0):
    return (symbolic.cv_transition(T), symbolic.cv_process_noise(T, sigma_a), symbolic.cv_observation_matrix(1),
            np.array([[sigma**2]]))


@pytest.mark.parametrize("T, sigma_a, sigma", [(0.5, 0.5, 2.0), (1.0, 1.0, 1.0), (0.1, 3.0, 0.3)])
def test_steady_state_matches_the_riccati_solution_and_the_alpha_beta_filter(T, sigma_a, sigma):
    scipy_linalg = pytest.importorskip("scipy.linalg")
    F, Q, G, R = _cv(T, sigma_a, sigma)
    ss = intuition.steady_state(F, Q, G, R)
    P_dare = scipy_linalg.solve_discrete_are(F.T, G.T, Q, R)
    assert np.allclose(ss.P_check, P_dare, rtol=1e-8)
    assert np.allclose(ss.K, P_dare @ G.T / (G @ P_dare @ G.T + R), rtol=1e-8)
    assert np.allclose(ss.P_hat, (np.eye(2) - ss.K @ G) @ ss.P_check, rtol=1e-8)
    # the closed form of the CV model's steady gain (Kalata's tracking index)
    lam = sigma_a * T**2 / sigma
    root = np.sqrt(lam**2 + 8 * lam)
    alpha, beta = -(lam**2 + 8 * lam - (lam + 4) * root) / 8, (lam**2 + 4 * lam - lam * root) / 4
    assert np.allclose(ss.K[:, 0], [alpha, beta / T], rtol=1e-8)


def test_steady_state_forgets_its_start_and_gives_up_when_nothing_settles():
    F, Q, G, R = _cv()
    a = intuition.steady_state(F, Q, G, R)
    b = intuition.steady_state(F, Q, G, R, P0=np.diag([1e4, 1e2]))
    assert np.allclose(a.P_check, b.P_check, rtol=1e-9) and a.steps > 1
    with pytest.raises(ValueError, match="max_steps"):
        intuition.steady_state(F, Q, G, R, max_steps=3)
    with pytest.raises(ValueError, match="settle"):      # an unobserved state that grows
        intuition.steady_state([[2.0]], [[1.0]], [[0.0]], [[1.0]], max_steps=200)


def test_run_kf_covariances_do_not_depend_on_the_measurements():
    """What makes a steady state possible at all (said in the lecture)."""
    F, Q, G, R = _cv()
    rng = np.random.default_rng(1)
    P0 = np.diag([100.0, 25.0])
    a = kf.run_kf(np.zeros(2), P0, F, Q, G, R, rng.normal(size=(40, 1)))
    b = kf.run_kf(np.ones(2), P0, F, Q, G, R, 10 * rng.normal(size=(40, 1)))
    assert np.allclose(a.P_hat, b.P_hat) and np.allclose(a.K, b.K)
    assert not np.allclose(a.x_hat, b.x_hat)


# --------------------------------------------------------------------------------------
# chapter 05: a cloud through the radar
# --------------------------------------------------------------------------------------

def _polar(p):
    return np.array([np.hypot(p[0], p[1]), np.arctan2(p[1], p[0])])


def _across(mean, along, across):
    return intuition.cross_range_covariance(mean, across, along)


def test_cross_range_covariance_is_wide_across_and_narrow_along_the_line_of_sight():
    mean = np.array([4.0, 3.0])
    P = intuition.cross_range_covariance(mean, 2.0, 0.2)
    u = mean / 5.0
    w = np.array([-0.6, 0.8])
    assert np.isclose(w @ P @ w, 4.0) and np.isclose(u @ P @ u, 0.04) and np.isclose(u @ P @ w, 0.0)
    assert np.allclose(P, P.T)
    # its bearing spread through the radar's tangent is sigma_across / range
    G = symbolic.radar_jacobian(np.r_[mean, 0.0, 0.0], "cv")[:2, :2]
    assert np.allclose(np.sqrt(np.diag(G @ P @ G.T)), [0.2, 2.0 / 5.0])
    with pytest.raises(ValueError, match="mean_xy"):
        intuition.cross_range_covariance([0.0, 0.0], 1.0, 1.0)
    with pytest.raises(ValueError, match="sigma_along"):
        intuition.cross_range_covariance(mean, 1.0, 0.0)


def test_radar_cloud_is_the_radar_model_and_its_tangent():
    mean, cov = np.array([4.0, 3.0]), np.array([[0.5, 0.1], [0.1, 0.3]])
    c = intuition.radar_cloud(mean, cov, n_samples=500, seed=7)
    assert c.samples_xy.shape == c.samples_polar.shape == (500, 2)
    assert np.allclose(c.samples_polar, np.array([_polar(p) for p in c.samples_xy]))
    J = numerical_jacobian(_polar, mean)
    assert np.allclose(c.lin_mean, _polar(mean))
    assert np.allclose(c.lin_cov, J @ cov @ J.T, rtol=1e-6)
    assert np.allclose(c.sample_mean, c.samples_polar.mean(axis=0))
    assert np.isclose(c.expected_share, 1 - np.exp(-4.5))
    again = intuition.radar_cloud(mean, cov, n_samples=500, seed=7)
    assert np.array_equal(again.samples_xy, c.samples_xy)
    assert not np.array_equal(intuition.radar_cloud(mean, cov, n_samples=500, seed=8).samples_xy, c.samples_xy)


def test_linearisation_holds_for_a_small_angular_spread_and_fails_for_a_large_one():
    tight = intuition.radar_cloud([4.0, 3.0], 0.1**2 * np.eye(2), n_samples=4000, seed=1)
    far = intuition.radar_cloud([40.0, 30.0], _across([40.0, 30.0], 0.2, 2.0), n_samples=4000, seed=2)
    near = intuition.radar_cloud([4.0, 3.0], _across([4.0, 3.0], 0.2, 2.0), n_samples=4000, seed=3)
    for good in (tight, far):
        assert abs(good.inside_share - good.expected_share) < 0.015
        assert np.allclose(np.sqrt(np.diag(good.sample_cov)), np.sqrt(np.diag(good.lin_cov)), rtol=0.06)
    assert near.inside_share < 0.85
    # the curvature lifts the mean range by many of the linearised standard deviations
    assert near.sample_mean[0] - near.lin_mean[0] > np.sqrt(near.lin_cov[0, 0])


def test_radar_cloud_unwraps_bearings_at_the_seam():
    c = intuition.radar_cloud([-10.0, 1e-3], 0.3**2 * np.eye(2), n_samples=300, seed=0)
    assert np.ptp(c.samples_polar[:, 1]) < 0.5            # no jump of 2π across the negative x axis
    assert np.allclose(np.cos(c.samples_polar[:, 1]), c.samples_xy[:, 0] / c.samples_polar[:, 0])


@pytest.mark.parametrize("args, kwargs, match", [
    (([0.0, 0.0], np.eye(2)), {}, "mean_xy"),
    (([1.0, 0.0], [[1.0, 2.0], [2.0, 1.0]]), {}, "cov_xy"),
    (([1.0, 0.0], np.eye(2)), dict(n_samples=3), "n_samples"),
    (([1.0, 0.0], np.eye(2)), dict(seed=-1), "seed"),
    (([1.0, 0.0, 0.0], np.eye(2)), {}, "mean_xy"),
])
def test_radar_cloud_names_a_bad_argument(args, kwargs, match):
    with pytest.raises(ValueError, match=match):
        intuition.radar_cloud(*args, **kwargs)


# --------------------------------------------------------------------------------------
# chapter 06: the cost and the IEKF's path
# --------------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def beacon_update():
    """The lecture's example: the first measurement of the beacon scenario, a prior 2.5 m off."""
    scenario = beacons.kitti_beacons("turns", seed=1)
    nearest = scenario.beacons[scenario.nearest[0]]
    g, G = beacons.beacon_observation(nearest), beacons.beacon_jacobian(nearest)
    x_check = scenario.truth[0] + np.array([2.0, -1.5, 0.5, 0.0])
    return dict(x_check=x_check, P_check=scenario.P0, y=scenario.z[0], g=g, G=G, R=scenario.R,
                residual=beacons.bearings_residual, truth=scenario.truth[0])


def _gradient(f, x):
    return numerical_jacobian(lambda z: np.array([f(z)]), x, 1e-5)[0]


def test_map_cost_is_the_two_weighted_squares(beacon_update):
    u = beacon_update
    x = u["x_check"] + np.array([0.3, -0.2, 0.1, 0.0])
    r = u["residual"](u["y"], u["g"](x))
    d = x - u["x_check"]
    expected = 0.5 * r @ np.linalg.inv(u["R"]) @ r + 0.5 * d @ np.linalg.inv(u["P_check"]) @ d
    assert np.isclose(intuition.map_cost(x, u["x_check"], u["P_check"], u["y"], u["g"], u["R"], u["residual"]),
                      expected)


def test_ekf_step_minimises_the_model_at_the_prior_and_the_iekf_the_cost(beacon_update):
    u = beacon_update
    args = (u["x_check"], u["P_check"], u["y"], u["g"], u["R"], u["residual"])
    path = intuition.iekf_iterates(u["x_check"], u["P_check"], u["y"], u["g"], u["G"], u["R"], u["residual"])
    ekf_hat = ekf.ekf_update(u["x_check"], u["P_check"], u["y"], u["g"], u["G"], u["R"],
                             residual=u["residual"]).x_hat
    iekf_hat = ekf.iekf_update(u["x_check"], u["P_check"], u["y"], u["g"], u["G"], u["R"],
                               residual=u["residual"]).x_hat
    assert np.array_equal(path[0], u["x_check"]) and np.allclose(path[1], ekf_hat)
    assert np.allclose(path[-1], iekf_hat, atol=1e-8) and 3 <= len(path) <= 11

    def model(x, x_op):
        return intuition.gauss_newton_cost(x, x_op, u["x_check"], u["P_check"], u["y"], u["g"], u["G"], u["R"],
                                           u["residual"])

    def cost(x):
        return intuition.map_cost(x, *args)

    # each iterate is the minimum of the quadratic model taken at the one before
    for k in range(1, len(path)):
        assert np.linalg.norm(_gradient(lambda x: model(x, path[k - 1]), path[k])) < 1e-4
        assert np.isclose(model(path[k - 1], path[k - 1]), cost(path[k - 1]))     # the model touches J there
    # the EKF's point is not a stationary point of J; the IEKF's is
    assert np.linalg.norm(_gradient(cost, path[1])) > 10
    assert np.linalg.norm(_gradient(cost, path[-1])) < 1e-3
    assert cost(path[-1]) < cost(path[1]) < cost(path[0])
    assert np.linalg.norm(path[-1][:2] - u["truth"][:2]) < np.linalg.norm(path[1][:2] - u["truth"][:2])


def test_gauss_newton_model_of_a_linear_observation_is_the_cost_itself():
    G = np.array([[1.0, 0.5]])
    args = (np.zeros(2), np.eye(2), np.array([1.0]))
    rng = np.random.default_rng(3)
    for _ in range(5):
        x, x_op = rng.normal(size=2), rng.normal(size=2)
        assert np.isclose(intuition.gauss_newton_cost(x, x_op, *args, lambda z: G @ z, lambda z: G, [[0.5]]),
                          intuition.map_cost(x, *args, lambda z: G @ z, [[0.5]]))


def test_cost_on_plane_evaluates_the_cost_at_each_node():
    point = np.array([1.0, 2.0, 3.0])
    U, V, J = intuition.cost_on_plane(lambda x: x[0] + 10 * x[1] + 100 * x[2], point, [0.0, 1.0, 2.0],
                                      [5.0, 6.0], dims=(2, 0))
    assert U.shape == V.shape == J.shape == (2, 3)
    assert np.allclose(J, 100 * U + V + 20.0)
    with pytest.raises(ValueError, match="dims"):
        intuition.cost_on_plane(lambda x: 0.0, point, [0.0, 1.0], [0.0, 1.0], dims=(1, 1))
    with pytest.raises(ValueError, match="cost"):
        intuition.cost_on_plane(None, point, [0.0, 1.0], [0.0, 1.0])


def test_cost_functions_name_a_bad_argument(beacon_update):
    u = beacon_update
    with pytest.raises(ValueError, match="P_check"):
        intuition.map_cost(u["x_check"], u["x_check"], np.zeros((4, 4)), u["y"], u["g"], u["R"])
    with pytest.raises(ValueError, match="residual"):
        intuition.map_cost(u["x_check"], u["x_check"], u["P_check"], u["y"], u["g"], u["R"], residual=3)
    with pytest.raises(ValueError, match="max_iter"):
        intuition.iekf_iterates(u["x_check"], u["P_check"], u["y"], u["g"], u["G"], u["R"], max_iter=0)


# --------------------------------------------------------------------------------------
# the chapter 03 figures
# --------------------------------------------------------------------------------------

def test_gaussian_product_draws_three_normalised_densities_at_their_means():
    fig, ax = plt.subplots()
    lines = plotting.plot_gaussian_product(ax, (0.0, 2.0), (1.5, 0.5), (1.2, 0.4), previous=(0.5, 1.0))
    assert set(lines) == {"previous", "prior", "likelihood", "posterior"}
    for key, (mean, var) in {"prior": (0.0, 2.0), "likelihood": (1.5, 0.5), "posterior": (1.2, 0.4)}.items():
        x, y = lines[key].get_xydata().T
        assert np.isclose(np.trapezoid(y, x), 1.0, atol=2e-3)          # a density, not a likelihood scaled
        assert abs(x[np.argmax(y)] - mean) < 0.05
        assert np.isclose(y.max(), 1 / np.sqrt(2 * np.pi * var), rtol=1e-3)
    assert lines["previous"].get_linestyle() == ":" and lines["posterior"].get_linewidth() > 2
    assert ax.get_legend() is not None
    with pytest.raises(ValueError, match="likelihood"):
        plotting.plot_gaussian_product(ax, (0.0, 1.0), (1.0, 0.0), (0.5, 0.5))
    with pytest.raises(ValueError, match="prior"):
        plotting.plot_gaussian_product(ax, (0.0,), (1.0, 1.0), (0.5, 0.5))


def test_kf_1d_steps_has_one_panel_per_step_titled_with_its_gain():
    t = intuition.kf_1d_table(0.0, 2.0, YS, q=0.1, r=0.5)
    fig = plotting.plot_kf_1d_steps(t, steps=[0, 1, 4])
    axes = fig.axes
    assert len(axes) == 3
    for ax, k in zip(axes, (0, 1, 4)):
        assert ax.get_title() == f"step {k}: P̌ = {t.P_check[k]:.3g}, K = {t.K[k]:.3g}"
        assert ax.get_xlabel() == "x [m]"
        assert len(ax.lines) >= 3 and ax.get_legend() is None
    assert len(axes[0].lines) < len(axes[1].lines)         # no "step before" at step 0
    labels = [text.get_text() for text in fig.legends[0].get_texts()]
    assert "prior N(x̌, P̌)" in labels and "posterior of the step before" in labels and len(set(labels)) == 4
    # the legend sits under the panels
    r = _renderer(fig)
    assert fig.legends[0].get_window_extent(r).y1 <= min(ax.get_tightbbox(r).y0 for ax in axes) + 1
    assert len(plotting.plot_kf_1d_steps(t).axes) == 3


def test_kf_1d_steps_names_what_it_cannot_draw():
    t = intuition.kf_1d_table(0.0, 2.0, [1.0, np.nan], q=0.1, r=0.5)
    with pytest.raises(ValueError, match="no measurement"):
        plotting.plot_kf_1d_steps(t, steps=[1])
    with pytest.raises(ValueError, match="steps"):
        plotting.plot_kf_1d_steps(t, steps=[2])
    with pytest.raises(ValueError, match="table"):
        plotting.plot_kf_1d_steps(object())


def test_gain_limits_figure_marks_both_limits_and_the_half_point():
    ratio = np.logspace(-3, 3, 50)
    K = intuition.scalar_gain(1.0, ratio)
    fig, ax = plt.subplots(figsize=(8, 3.8))
    line = plotting.plot_gain_limits(ax, ratio, K, points=[[0.25, 0.8], [1.0, 0.5]])
    assert ax.get_xscale() == "log" and np.allclose(line.get_ydata(), K)
    levels = sorted(round(float(l.get_ydata()[0]), 9) for l in ax.lines if len(l.get_ydata()) == 2
                    and l.get_ydata()[0] == l.get_ydata()[1])
    assert levels == [0.0, 1.0]
    notes = " ".join(t.get_text() for t in ax.texts)
    assert "R → 0" in notes and "P̌ → 0" in notes and "K → 0" in notes
    def drawn(points):
        return any(l.get_xydata().shape == np.shape(points) and np.allclose(l.get_xydata(), points)
                   for l in ax.lines)

    assert drawn([[0.25, 0.8], [1.0, 0.5]]) and drawn([[1.0, 0.5]])                # R = P̌: K = ½
    assert "R / P̌" in ax.get_xlabel() and ax.get_ylabel() == "gain K"
    fig.tight_layout()
    _legend_covers_no_line(ax)
    with pytest.raises(ValueError, match="ratio"):
        plotting.plot_gain_limits(ax, ratio[::-1], K)
    with pytest.raises(ValueError, match="points"):
        plotting.plot_gain_limits(ax, ratio, K, points=[0.25, 0.8])


def test_gain_convergence_figure_draws_the_sawtooth_and_the_steady_state():
    F, Q, G, R = _cv()
    rng = np.random.default_rng(2)
    n = 60
    hist = kf.run_kf(np.zeros(2), np.diag([100.0, 25.0]), F, Q, G, R, rng.normal(size=(n, 1)))
    ss = intuition.steady_state(F, Q, G, R)
    t = 0.5 * np.arange(1, n + 1)
    fig = plotting.plot_gain_convergence(t, hist, steady=ss, t_max=20)
    ax1, ax2 = fig.axes
    assert ax1.get_yscale() == "log" and ax2.get_xlabel() == "t [s]"
    saw = ax1.lines[0].get_ydata()
    assert np.allclose(saw[0::2], hist.P_check[:, 0, 0]) and np.allclose(saw[1::2], hist.P_hat[:, 0, 0])
    assert np.all(saw[1::2] < saw[0::2])                   # every update lowers the variance
    flat = {round(float(l.get_ydata()[0]), 9) for ax in (ax1, ax2) for l in ax.lines
            if len(l.get_ydata()) == 2 and l.get_linestyle() == "--"}
    for value in (ss.P_check[0, 0], ss.P_hat[0, 0], ss.K[0, 0], ss.K[1, 0]):
        assert round(float(value), 9) in flat
    assert np.allclose(ax2.lines[0].get_ydata(), hist.K[:, 0, 0])
    assert ax2.get_xlim()[1] == 20
    fig.canvas.draw()
    for ax in (ax1, ax2):
        _legend_covers_no_line(ax)
    with pytest.raises(ValueError, match="t_max"):
        plotting.plot_gain_convergence(t, hist, t_max=0.0)
    with pytest.raises(ValueError, match="hist"):
        plotting.plot_gain_convergence(t[:-1], hist)
    with pytest.raises(ValueError, match="gain_labels"):
        plotting.plot_gain_convergence(t, hist, gain_labels=("one",))


# --------------------------------------------------------------------------------------
# the chapter 05 and 06 figures
# --------------------------------------------------------------------------------------

def test_radar_linearisation_figure_has_the_cloud_above_and_its_image_below():
    clouds = [intuition.radar_cloud([4.0, 3.0], 0.01 * np.eye(2), n_samples=200, seed=1),
              intuition.radar_cloud([4.0, 3.0], _across([4.0, 3.0], 0.2, 2.0), n_samples=200, seed=2)]
    fig = plotting.plot_radar_linearisation(clouds, titles=["tight", "wide"])
    axes = np.array(fig.axes).reshape(2, 2)
    for c, cloud in enumerate(clouds):
        top, bottom = axes[0, c], axes[1, c]
        assert top.get_title() == ["tight", "wide"][c]
        assert sum(isinstance(p, Ellipse) for p in top.patches) == 1
        ellipses = [p for p in bottom.patches if isinstance(p, Ellipse)]
        assert len(ellipses) == 2
        centres = {tuple(np.round(e.center, 9)) for e in ellipses}
        assert tuple(np.round(cloud.lin_mean[::-1], 9)) in centres      # bearing across, range up
        assert f"{100 * cloud.inside_share:.1f} %" in bottom.get_title()
        assert bottom.get_xlabel() == "bearing φ [rad]" and bottom.get_ylabel() == "range ρ [m]"
        xmin, xmax = top.get_xlim()
        ymin, ymax = top.get_ylim()
        assert xmin < 0 < xmax and ymin < 0 < ymax                     # the radar is in view
    labels = [t.get_text() for t in fig.legends[0].get_texts()]
    assert "EKF: g(μ), G P Gᵀ" in labels and "radar" in labels
    with pytest.raises(ValueError, match="titles"):
        plotting.plot_radar_linearisation(clouds, titles=["one"])
    with pytest.raises(ValueError, match="clouds"):
        plotting.plot_radar_linearisation([])


def test_cost_iterates_figure_shows_the_ekf_step_and_the_iekf_path():
    x_check = np.array([1.0, 1.0])
    path = np.array([x_check, [0.2, 0.4], [0.05, 0.1], [0.0, 0.0]])
    u = v = np.linspace(-1.5, 1.5, 31)
    U, V = np.meshgrid(u, v)
    J = U**2 + 2 * V**2
    fig = plotting.plot_cost_iterates(U, V, J, path, model=(U - 0.2)**2 + (V - 0.4)**2, truth=[0.0, 0.0],
                                      names=("a [m]", "b [m]"))
    ax1, ax2 = fig.axes
    assert len(ax1.collections) > len(ax2.collections)             # the model's contours, left only
    def drawn(ax, points):
        return any(l.get_xydata().shape == np.shape(points) and np.allclose(l.get_xydata(), points)
                   for l in ax.lines)

    assert drawn(ax2, path[:, :2]) and drawn(ax1, [path[1]]) and drawn(ax2, [path[-1]])
    assert "EKF" in ax1.get_title() and "IEKF" in ax2.get_title()
    assert ax1.get_xlabel() == "a [m]" and ax2.get_ylabel() == "b [m]"
    with pytest.raises(ValueError, match="path"):
        plotting.plot_cost_iterates(U, V, J, path[:1])
    with pytest.raises(ValueError, match="J"):
        plotting.plot_cost_iterates(U, V, J[:-1], path)
    with pytest.raises(ValueError, match="model"):
        plotting.plot_cost_iterates(U, V, J, path, model=J[:-1])


# --------------------------------------------------------------------------------------
# the block diagrams
# --------------------------------------------------------------------------------------

def _display_boxes(diagram):
    r = _renderer(diagram.figure)
    return r, {name: patch.get_window_extent(r) for name, patch in diagram.patches.items()}


def _densify(poly, step=2.0):
    """Points every ``step`` pixels along a polyline, its corners included."""
    out = [poly[:1]]
    for a, b in zip(poly[:-1], poly[1:]):
        n = max(int(np.linalg.norm(b - a) / step), 1)
        out.append(a + np.linspace(0.0, 1.0, n + 1)[1:, None] * (b - a))
    return np.vstack(out)


def _check_layout(diagram):
    r, boxes = _display_boxes(diagram)
    names = list(boxes)
    for a in range(len(names)):                                       # boxes apart
        for b in range(a + 1, len(names)):
            assert not boxes[names[a]].overlaps(boxes[names[b]]), f"{names[a]} overlaps {names[b]}"
    for name, text in diagram.texts.items():                          # texts inside their boxes
        t, box = text.get_window_extent(r), boxes[name]
        assert box.x0 < t.x0 and t.x1 < box.x1 and box.y0 < t.y0 and t.y1 < box.y1, f"text of {name} overflows"
    for arrow, patch, label in diagram.arrows:
        path = patch.get_path().transformed(diagram.ax.transData)     # line and head, in pixels
        pts = np.vstack([_densify(poly) for poly in path.to_polygons(closed_only=False)])
        a, b = boxes[arrow.src], boxes[arrow.dst]
        assert a.padded(4).contains(*pts[0]), f"{arrow.src} -> {arrow.dst} does not start at its box"
        assert any(b.padded(4).contains(*p) for p in pts[-8:]), f"{arrow.dst} is not where it ends"
        for other, box in boxes.items():                              # no arrow through a third box
            if other in (arrow.src, arrow.dst):
                continue
            inner = box.padded(-2)
            assert not any(inner.contains(*p) for p in pts), f"{arrow.src} -> {arrow.dst} crosses {other}"
        if label is not None:                                         # labels beside, not on, the boxes
            lab = label.get_window_extent(r)
            for name, box in boxes.items():
                assert not lab.overlaps(box), f"the label {label.get_text()!r} covers {name}"


def test_bayes_filter_diagram_is_the_predict_update_loop():
    d = plotting.plot_bayes_filter_diagram()
    assert {"posterior_prev", "predict", "prior", "update", "posterior"} <= set(d.boxes)
    assert {("posterior_prev", "predict"), ("predict", "prior"), ("prior", "update"), ("update", "posterior"),
            ("posterior", "posterior_prev"), ("input", "predict"), ("observation", "update"),
            ("start", "prior"), ("posterior", "output")} == d.edges()
    assert "motion model" in d.texts["predict"].get_text() and "total probability" in d.texts["predict"].get_text()
    assert "Bayes' rule" in d.texts["update"].get_text() and "measurement model" in d.texts["update"].get_text()
    assert d.boxes["prior"].kind == "state" and d.boxes["observation"].kind == "sensor"
    _check_layout(d)


def test_eskf_diagram_is_the_error_state_loop():
    d = plotting.plot_eskf_diagram()
    assert set(d.boxes) == {"imu", "nominal", "covariance", "sensor", "update", "injection", "reset", "output"}
    assert {("imu", "nominal"), ("imu", "covariance"), ("nominal", "covariance"), ("covariance", "update"),
            ("sensor", "update"), ("update", "injection"), ("injection", "reset"), ("reset", "output"),
            ("covariance", "output"), ("output", "nominal")} == d.edges()
    dashed = [a for a, _, _ in d.arrows if a.dashed]
    assert [(a.src, a.dst) for a in dashed] == [("covariance", "output")]     # the branch without a measurement
    assert "Exp(−δθ̂)" in d.texts["injection"].get_text() and "p̌ − δp̂" in d.texts["injection"].get_text()
    assert "δx̂ ← 0" in d.texts["reset"].get_text()
    assert "F P̂ Fᵀ + B Q Bᵀ" in d.texts["covariance"].get_text()
    _check_layout(d)


def test_diagrams_draw_on_a_given_axes():
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(16, 5))
    d = diagrams.plot_bayes_filter_diagram(ax1)
    assert d.ax is ax1 and d.figure is fig and not ax1.axison
    assert diagrams.plot_eskf_diagram(ax2).ax is ax2


def test_layout_check_catches_overlaps_and_bad_arrows():
    """The layout checks above can fail: a text too long for its box, an arrow through a box."""
    fig, ax = plt.subplots(figsize=(6, 3))
    boxes = {"a": diagrams.Box(1, 1, 1.5, 0.8, "a text much too long for this box"),
             "b": diagrams.Box(5, 1, 1.5, 0.8, "b", "state"), "c": diagrams.Box(3, 1, 1.0, 0.8, "c", "sensor")}
    d = diagrams.draw_block_diagram(ax, boxes, [diagrams.Arrow("a", "b")])
    with pytest.raises(AssertionError, match="overflows|crosses"):
        _check_layout(d)
    boxes["a"] = diagrams.Box(1, 1, 1.5, 0.8, "a")
    fig, ax = plt.subplots(figsize=(6, 3))
    with pytest.raises(AssertionError, match="crosses"):
        _check_layout(diagrams.draw_block_diagram(ax, boxes, [diagrams.Arrow("a", "b")]))
    around = dict(via=((1, 2.0), (5, 2.0)), src_side="top", dst_side="top")
    fig, ax = plt.subplots(figsize=(6, 3))
    _check_layout(diagrams.draw_block_diagram(ax, boxes, [diagrams.Arrow("a", "b", "over", label_xy=(3, 2.2),
                                                                         **around)]))
    fig, ax = plt.subplots(figsize=(6, 3))
    with pytest.raises(AssertionError, match="covers c"):
        _check_layout(diagrams.draw_block_diagram(ax, boxes, [diagrams.Arrow("a", "b", "on c", label_xy=(3, 1.1),
                                                                             **around)]))


@pytest.mark.parametrize("boxes, arrows, match", [
    ({}, [], "boxes"),
    ({"a": "not a box"}, [], "boxes\\['a'\\]"),
    ({"a": diagrams.Box(0, 0, 1, 1, "a", "cloud")}, [], "kind"),
    ({"a": diagrams.Box(0, 0, 0, 1, "a")}, [], "size"),
    ({"a": diagrams.Box(0, 0, 1, 1, "a")}, [diagrams.Arrow("a", "z")], "no box named 'z'"),
    ({"a": diagrams.Box(0, 0, 1, 1, "a"), "b": diagrams.Box(3, 0, 1, 1, "b")},
     [diagrams.Arrow("a", "b", src_side="middle")], "side"),
    ({"a": diagrams.Box(0, 0, 1, 1, "a"), "b": diagrams.Box(3, 0, 1, 1, "b")},
     [diagrams.Arrow("a", "b", via=((1.0,),))], "via"),
])
def test_block_diagram_names_a_bad_argument(boxes, arrows, match):
    fig, ax = plt.subplots()
    with pytest.raises(ValueError, match=match):
        diagrams.draw_block_diagram(ax, boxes, arrows)


def test_intuition_figures_leave_global_style_alone():
    before = dict(matplotlib.rcParams)
    t = intuition.kf_1d_table(0.0, 2.0, YS, q=0.1, r=0.5)
    plotting.plot_kf_1d_steps(t)
    plotting.plot_bayes_filter_diagram()
    plotting.plot_eskf_diagram()
    assert dict(matplotlib.rcParams) == before
