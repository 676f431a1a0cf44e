"""Tests for kalman_course.plotting (Agg backend, set in conftest)."""

from __future__ import annotations

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.collections import PolyCollection
from matplotlib.colors import to_rgba
from matplotlib.container import BarContainer
from matplotlib.lines import Line2D
from matplotlib.patches import Ellipse

from kalman_course import plotting
from kalman_course.plotting import COLORS


@pytest.fixture
def ax():
    fig, ax = plt.subplots()
    yield ax
    plt.close(fig)


@pytest.fixture(autouse=True)
def close_all():
    yield
    plt.close("all")


class FakeHistory:
    def __init__(self, x_hat, P_hat):
        self.x_hat, self.P_hat = x_hat, P_hat


def test_backend_is_agg():
    assert matplotlib.get_backend().lower() == "agg"


def test_colors_are_the_vocabulary_and_read_only():
    assert to_rgba(COLORS["truth"]) == to_rgba("black")
    assert to_rgba(COLORS["estimate"]) == to_rgba("tab:blue")
    r, g, b, _ = to_rgba(COLORS["measurement"])
    assert r == g == b and 0.2 < r < 0.9  # a grey
    for role in ("band", "prior", "likelihood", "posterior", "ellipse"):
        to_rgba(COLORS[role])
    with pytest.raises(TypeError):
        COLORS["truth"] = "red"


def test_lines_carry_the_course_style(ax):
    t = np.arange(5.0)
    truth = plotting.plot_truth(ax, t, t**2)
    meas = plotting.plot_measurements(ax, t, [0, np.nan, 4.1, 8.9, 16.2])
    est = plotting.plot_estimate(ax, t, t**2 + 0.1)
    assert all(isinstance(a, Line2D) for a in (truth, meas, est))
    assert to_rgba(truth.get_color()) == to_rgba("black") and truth.get_label() == "truth"
    assert meas.get_linestyle() == "None" and meas.get_marker() == "."
    assert to_rgba(meas.get_color()) == to_rgba(COLORS["measurement"])
    assert to_rgba(est.get_color()) == to_rgba(COLORS["estimate"]) and est.get_label() == "estimate"
    assert len(ax.lines) == 3


def test_keywords_override_the_style(ax):
    line = plotting.plot_estimate(ax, [0, 1], [1, 2], color="tab:green", label="prior", lw=3)
    assert to_rgba(line.get_color()) == to_rgba("tab:green")
    assert line.get_label() == "prior" and line.get_linewidth() == 3
    line = plotting.plot_truth(ax, [0, 1], [1, 2], c="red")
    assert to_rgba(line.get_color()) == to_rgba("red")


def test_measurements_accept_a_column(ax):
    line = plotting.plot_measurements(ax, np.arange(3.0), np.array([[1.0], [np.nan], [2.0]]))
    assert np.isnan(line.get_ydata()[1])


def test_sigma_band_limits_and_label(ax):
    t = np.linspace(0, 1, 4)
    center, sigma = np.array([0.0, 1.0, 2.0, 3.0]), np.array([0.1, 0.2, 0.3, 0.4])
    band = plotting.plot_sigma_band(ax, t, center, sigma)
    assert isinstance(band, PolyCollection) and band.get_label() == "±3σ"
    ys = band.get_paths()[0].vertices[:, 1]
    assert ys.max() == pytest.approx(3.0 + 1.2) and ys.min() == pytest.approx(-0.3)
    assert plotting.plot_sigma_band(ax, t, 0.0, 0.5, n_sigma=2).get_label() == "±2σ"


def test_error_with_band(ax):
    t = np.arange(10.0)
    line, band = plotting.plot_error_with_band(ax, t, np.sin(t), np.full(10, 0.5))
    assert isinstance(line, Line2D) and isinstance(band, PolyCollection)
    ys = band.get_paths()[0].vertices[:, 1]
    assert ys.max() == pytest.approx(1.5) and ys.min() == pytest.approx(-1.5)
    np.testing.assert_allclose(line.get_ydata(), np.sin(t))


@pytest.mark.parametrize("cov", [
    [[4.0, 0.0], [0.0, 1.0]],
    [[1.0, 0.0], [0.0, 9.0]],
    [[2.0, 1.2], [1.2, 1.0]],
    [[1.0, -0.9], [-0.9, 1.0]],
    [[3.0, 0.0], [0.0, 3.0]],
])
def test_ellipse_axes_match_the_eigenvalues(ax, cov):
    cov = np.array(cov)
    mean = np.array([1.0, -2.0])
    patch = plotting.plot_covariance_ellipse(ax, mean, cov, n_sigma=3)
    assert isinstance(patch, Ellipse) and patch in ax.patches
    vals, vecs = np.linalg.eigh(cov)
    assert patch.width == pytest.approx(6 * np.sqrt(vals[1]))
    assert patch.height == pytest.approx(6 * np.sqrt(vals[0]))
    np.testing.assert_allclose(patch.center, mean)
    # the ellipse's boundary points are at Mahalanobis distance 3
    theta = np.linspace(0, 2 * np.pi, 17)
    boundary = patch.get_patch_transform().transform(np.column_stack([np.cos(theta), np.sin(theta)]))
    d = boundary - mean
    maha = np.sqrt(np.einsum("ij,jk,ik->i", d, np.linalg.inv(cov), d))
    np.testing.assert_allclose(maha, 3.0, rtol=1e-6)
    assert not patch.get_fill()


def test_ellipse_of_a_degenerate_covariance(ax):
    patch = plotting.plot_covariance_ellipse(ax, [0, 0], [[1.0, 1.0], [1.0, 1.0]], n_sigma=1)
    assert patch.height == pytest.approx(0.0, abs=1e-7)
    assert patch.width == pytest.approx(2 * np.sqrt(2.0))
    assert patch.angle == pytest.approx(45.0) or patch.angle == pytest.approx(-135.0)


def test_ellipse_style_and_label(ax):
    patch = plotting.plot_covariance_ellipse(ax, [0, 0], np.eye(2), label="prior ±3σ", color="tab:gray")
    assert patch.get_label() == "prior ±3σ"
    assert to_rgba(patch.get_edgecolor()) == to_rgba("tab:gray")
    patch = plotting.plot_covariance_ellipse(ax, [0, 0], np.eye(2))
    assert to_rgba(patch.get_edgecolor()) == to_rgba(COLORS["ellipse"])


def test_belief_bars(ax):
    belief = np.array([0.1, 0.2, 0.7])
    bars = plotting.plot_belief(ax, belief)
    assert isinstance(bars, BarContainer) and len(bars) == 3
    np.testing.assert_allclose([b.get_height() for b in bars], belief)
    bars = plotting.plot_belief(ax, [1, 2], positions=[10, 20])
    assert [b.get_x() + b.get_width() / 2 for b in bars] == pytest.approx([10, 20])


def test_samples_and_consistency(ax):
    pts = np.random.default_rng(0).normal(size=(50, 2))
    coll = plotting.plot_samples(ax, pts)
    assert coll.get_offsets().shape == (50, 2)
    line, band = plotting.plot_consistency(ax, np.arange(4.0), [1.0, np.nan, 2.0, 3.0], 0.5, 2.5)
    assert band.get_label() == "[0.50, 2.50]" and line.get_label() == "NEES"


@pytest.mark.parametrize("call, match", [
    (lambda ax: plotting.plot_truth(ax, [0, 1, 2], [1, 2]), "length 3"),
    (lambda ax: plotting.plot_truth(ax, [[0, 1], [1, 2]], [1, 2]), "1-D"),
    (lambda ax: plotting.plot_estimate(ax, [0, 1], [np.nan, 1]), "NaN"),
    (lambda ax: plotting.plot_measurements(ax, [0, 1], [np.inf, 1]), "inf"),
    (lambda ax: plotting.plot_truth(ax, "abc", [1, 2]), "numbers"),
    (lambda ax: plotting.plot_sigma_band(ax, [0, 1], [0, 0], [-1, 1]), "sigma must be >= 0"),
    (lambda ax: plotting.plot_sigma_band(ax, [0, 1], [0, 0], [1, 1], n_sigma=0), "n_sigma"),
    (lambda ax: plotting.plot_sigma_band(ax, [0, 1], [0, 0, 0], 1.0), "center"),
    (lambda ax: plotting.plot_error_with_band(ax, [0, 1], [0, 1], [1, 1, 1]), "sigma"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], np.eye(3)), "2x2"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0, 0], np.eye(2)), "mean"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], [[1, 0.5], [0, 1]]), "symmetric"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], [[1, 2], [2, 1]]), "semi-definite"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], [[np.nan, 0], [0, 1]]), "finite"),
    (lambda ax: plotting.plot_belief(ax, [0.5, -0.1]), "non-negative"),
    (lambda ax: plotting.plot_belief(ax, []), "at least one"),
    (lambda ax: plotting.plot_belief(ax, [1, 2], positions=[1]), "positions"),
    (lambda ax: plotting.plot_samples(ax, np.zeros((3, 3))), r"\(N, 2\)"),
    (lambda ax: plotting.plot_consistency(ax, [0, 1], [1, 1], 2.0, 1.0), "lo <= hi"),
])
def test_bad_input_raises_a_clear_error(ax, call, match):
    with pytest.raises(ValueError, match=match):
        call(ax)


def test_belief_sequence_figure():
    beliefs = [np.full(6, 1 / 6), np.array([0, 0, 0.5, 0.5, 0, 0])]
    doors = np.array([1, 0, 1, 0, 0, 0], dtype=bool)
    fig = plotting.plot_belief_sequence(beliefs, titles=["a", "b"], true_cells=[2, 3], doors=doors)
    axes = fig.axes
    assert len(axes) == 2 and axes[1].get_title() == "b"
    assert len(axes[0].patches) == 6 + 2  # bars and door spans
    with pytest.raises(ValueError, match="cells"):
        plotting.plot_belief_sequence([np.ones(3), np.ones(4)])
    with pytest.raises(ValueError, match="titles"):
        plotting.plot_belief_sequence(beliefs, titles=["only one"])
    with pytest.raises(ValueError, match="doors"):
        plotting.plot_belief_sequence(beliefs, doors=[True])
    with pytest.raises(ValueError, match="at least one"):
        plotting.plot_belief_sequence([])


def test_conditioning_figure():
    samples = np.random.default_rng(1).multivariate_normal([0, 1], [[1, 0.8], [0.8, 2]], 100)
    fig = plotting.plot_conditioning([0, 1], [[1, 0.8], [0.8, 2]], 2.0, 0.4, 0.68, samples=samples)
    ax1, ax2 = fig.axes
    assert len(ax1.patches) == 2 and len(ax2.lines) == 2
    with pytest.raises(ValueError, match="cond_var"):
        plotting.plot_conditioning([0, 1], np.eye(2), 0.0, 0.0, -1.0)


def test_kf_figures():
    n = 30
    t = np.arange(n, dtype=float)
    x_hat = np.column_stack([t, 2 * t, np.ones(n), np.ones(n)])
    P_hat = np.tile(np.diag([0.5, 0.3, 0.1, 0.1]), (n, 1, 1))
    hist = FakeHistory(x_hat, P_hat)
    fig = plotting.plot_kf_1d(t, t + 0.1, np.where(t % 3 == 0, np.nan, t), hist)
    assert len(fig.axes) == 2
    fig = plotting.plot_kf_2d(t, x_hat[:, :2] + 0.2, x_hat[:, :2] - 0.3, hist, ellipse_every=10)
    assert len(fig.axes) == 3
    assert sum(isinstance(p, Ellipse) for p in fig.axes[0].patches) == 3
    with pytest.raises(ValueError, match="steps"):
        plotting.plot_kf_1d(t[:-1], t[:-1], None, hist)
    with pytest.raises(ValueError, match="index"):
        plotting.plot_kf_1d(t, t, None, hist, index=4)
    with pytest.raises(ValueError, match="KFHistory"):
        plotting.plot_kf_1d(t, t, None, object())
    with pytest.raises(ValueError, match="truth_xy"):
        plotting.plot_kf_2d(t, x_hat[:, :3], x_hat[:, :2], hist)
    with pytest.raises(ValueError, match="ellipse_every"):
        plotting.plot_kf_2d(t, x_hat[:, :2], x_hat[:, :2], hist, ellipse_every=-1)


def test_no_global_style_changes():
    before = dict(matplotlib.rcParams)
    fig, ax = plt.subplots()
    plotting.plot_truth(ax, [0, 1], [0, 1])
    plotting.plot_covariance_ellipse(ax, [0, 0], np.eye(2))
    after = dict(matplotlib.rcParams)
    assert before == after
