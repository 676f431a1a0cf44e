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
    (lambda ax: plotting.plot_truth(ax, [0, 1, 2], [1, 2]), r"x must have shape \(3,\)"),
    (lambda ax: plotting.plot_truth(ax, [[0, 1], [1, 2]], [1, 2]), "1-D"),
    (lambda ax: plotting.plot_estimate(ax, [0, 1], [np.nan, 1]), "NaN"),
    (lambda ax: plotting.plot_measurements(ax, [0, 1], [np.inf, 1]), "inf"),
    (lambda ax: plotting.plot_truth(ax, "abc", [1, 2]), "numbers"),
    (lambda ax: plotting.plot_sigma_band(ax, [0, 1], [0, 0], [-1, 1]), "sigma must be >= 0"),
    (lambda ax: plotting.plot_sigma_band(ax, [0, 1], [0, 0], [1, 1], n_sigma=0), "n_sigma"),
    (lambda ax: plotting.plot_sigma_band(ax, [0, 1], [0, 0, 0], 1.0), "center"),
    (lambda ax: plotting.plot_error_with_band(ax, [0, 1], [0, 1], [1, 1, 1]), "sigma"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], np.eye(3)), r"cov must have shape \(2, 2\)"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0, 0], np.eye(2)), "mean"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], [[1, 0.5], [0, 1]]), "symmetric"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], [[1, 2], [2, 1]]), "semi-definite"),
    (lambda ax: plotting.plot_covariance_ellipse(ax, [0, 0], [[np.nan, 0], [0, 1]]), "finite"),
    (lambda ax: plotting.plot_belief(ax, [0.5, -0.1]), "non-negative"),
    (lambda ax: plotting.plot_belief(ax, []), "belief must not be empty"),
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


def test_kf_figures_label_their_curves():
    n = 30
    t = np.arange(n, dtype=float)
    x_hat = np.column_stack([t, 2 * t, np.ones(n), np.ones(n)])
    hist = FakeHistory(x_hat, np.tile(np.diag([0.5, 0.3, 0.1, 0.1]), (n, 1, 1)))
    fig = plotting.plot_kf_1d(t, t, t, hist, labels={"measurements": "fixes (simulated noise)"})
    texts = [text.get_text() for text in fig.axes[0].get_legend().get_texts()]
    assert "fixes (simulated noise)" in texts and "truth" in texts and "measurements" not in texts
    fig = plotting.plot_kf_2d(t, x_hat[:, :2], x_hat[:, :2], hist, labels={"truth": "truth (real)"})
    texts = [text.get_text() for text in fig.axes[0].get_legend().get_texts()]
    assert "truth (real)" in texts and "measurements" in texts
    with pytest.raises(ValueError, match="unknown roles"):
        plotting.plot_kf_1d(t, t, t, hist, labels={"meas": "x"})
    with pytest.raises(ValueError, match="must be a string"):
        plotting.plot_kf_1d(t, t, t, hist, labels={"truth": 3})


def test_no_global_style_changes():
    before = dict(matplotlib.rcParams)
    fig, ax = plt.subplots()
    plotting.plot_truth(ax, [0, 1], [0, 1])
    plotting.plot_covariance_ellipse(ax, [0, 0], np.eye(2))
    after = dict(matplotlib.rcParams)
    assert before == after


# --------------------------------------------------------------------------------------
# the subpackage: vocabulary and per-chapter modules
# --------------------------------------------------------------------------------------

def test_vocabulary_is_re_exported_by_the_subpackage():
    from kalman_course.plotting import eskf, vocabulary
    assert plotting.plot_truth is vocabulary.plot_truth and plotting.COLORS is vocabulary.COLORS
    assert plotting.plot_pose_errors is eskf.plot_pose_errors
    assert set(plotting.__all__) >= set(vocabulary.__all__)
    assert all(hasattr(plotting, name) for name in plotting.__all__)


def test_consistency_curves_share_one_band(ax):
    t = np.arange(10.0)
    lines, band = plotting.plot_consistency_curves(ax, t, {"tuned": np.full(10, 6.0), "Q / 100": t + 1.0},
                                                    1.2, 14.4)
    assert [line.get_label() for line in lines] == ["tuned", "Q / 100"]
    assert to_rgba(lines[0].get_color()) == to_rgba(COLORS["estimate"])
    assert isinstance(band, PolyCollection) and ax.get_yscale() == "log"
    assert len(ax.collections) == 1
    with pytest.raises(ValueError, match="curves"):
        plotting.plot_consistency_curves(ax, t, {}, 1.0, 2.0)
    with pytest.raises(ValueError, match="curves"):
        plotting.plot_consistency_curves(ax, t, {"short": np.ones(3)}, 1.0, 2.0)
    with pytest.raises(ValueError, match="lo"):
        plotting.plot_consistency_curves(ax, t, {"a": t}, 3.0, 2.0)


def test_flag_spans_finds_every_run():
    t = np.arange(10.0)
    flags = np.array([1, 1, 0, 0, 1, 1, 1, 0, 0, 1], dtype=bool)
    np.testing.assert_array_equal(plotting.flag_spans(t, flags), [[0, 1], [4, 6], [9, 9]])
    assert plotting.flag_spans(t, np.zeros(10, bool)).shape == (0, 2)
    with pytest.raises(ValueError, match="flags"):
        plotting.flag_spans(t, np.ones(9, bool))


def test_shade_spans_and_curves(ax):
    patches = plotting.shade_spans(ax, [[0.0, 1.0], [2.0, 3.0]], label="gap")
    assert len(patches) == 2 and [p.get_label() for p in patches][0] == "gap"
    assert plotting.shade_spans(ax, np.empty((0, 2))) == []
    with pytest.raises(ValueError, match="spans"):
        plotting.shade_spans(ax, [[1.0, 0.0]])
    lines = plotting.plot_curves(ax, {"a": ([0, 1], [1, 2]), "b": ([0, 1, 2], [1, np.nan, 3])})
    assert len(lines) == 2 and len(ax.lines) == 2
    with pytest.raises(ValueError, match="curves"):
        plotting.plot_curves(ax, {"a": ([0, 1], [1, 2, 3])})


def test_plot_track_draws_three_lines_and_checks_shapes(ax):
    xy = np.column_stack([np.arange(5.0), np.arange(5.0) ** 2, np.zeros(5)])
    lines = plotting.plot_track(ax, xy, xy + 0.1, xy[::2] - 0.2, estimate_label="ESKF")
    assert [line.get_label() for line in lines] == ["truth", "measurements", "ESKF"]
    assert len(plotting.plot_track(ax, xy, xy)) == 2
    with pytest.raises(ValueError, match="estimate_xy"):
        plotting.plot_track(ax, xy, np.arange(5.0))


def _eskf_like(n=50, seed=0):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 5.0, n)
    std = np.full((n, 15), 0.1)
    return t, 0.05 * rng.standard_normal((n, 3)), 0.001 * rng.standard_normal((n, 3)), std


def test_pose_errors_grid_has_six_panels_with_bands():
    t, dp, dtheta, std = _eskf_like()
    fig = plotting.plot_pose_errors(t, dp, dtheta, std)
    axes = fig.axes
    assert len(axes) == 6
    assert all(len(ax.collections) == 1 and isinstance(ax.collections[0], PolyCollection) for ax in axes)
    assert [ax.get_title() for ax in axes[:3]] == [f"position error {a}" for a in "xyz"]
    # attitude is drawn in degrees, with its band from columns 6-8 of std
    line = [ln for ln in axes[3].lines if ln.get_label() == "error"][0]
    np.testing.assert_allclose(line.get_ydata(), np.rad2deg(dtheta[:, 0]))
    band_top = axes[3].collections[0].get_paths()[0].vertices[:, 1].max()
    assert band_top == pytest.approx(3 * np.rad2deg(0.1))
    with pytest.raises(ValueError, match="std"):
        plotting.plot_pose_errors(t, dp, dtheta, std[:, :5])
    with pytest.raises(ValueError, match="position_error"):
        plotting.plot_pose_errors(t, dp[:-1], dtheta, std)


def test_bias_figures():
    t, _, _, std = _eskf_like()
    fig = plotting.plot_bias_estimates(t, np.full((50, 3), 0.01), np.full((50, 3), 1e-5))
    assert len(fig.axes) == 6 and all(len(ax.collections) == 0 for ax in fig.axes)
    np.testing.assert_allclose(fig.axes[3].lines[0].get_ydata(), np.rad2deg(1e-5) * 3600)
    sig_w = np.full((50, 3), 2e-5)
    fig = plotting.plot_bias_estimates(t, np.full((50, 3), 0.01), np.full((50, 3), 1e-5),
                                       accel_sigma=np.full((50, 3), 0.002), gyro_sigma=sig_w)
    band = fig.axes[4].collections[0].get_paths()[0].vertices[:, 1]     # ±3σ of b_ω y, in deg/h
    np.testing.assert_allclose([band.min(), band.max()], np.rad2deg(1e-5 + np.array([-3, 3]) * 2e-5) * 3600)
    with pytest.raises(ValueError, match="gyro_bias"):
        plotting.plot_bias_estimates(t, np.zeros((50, 3)), np.zeros((50, 2)))
    with pytest.raises(ValueError, match="together"):
        plotting.plot_bias_estimates(t, np.zeros((50, 3)), np.zeros((50, 3)), gyro_sigma=sig_w)

    class Run:
        def __init__(self, scale):
            self.t, self._std = t, std * scale

        def std(self):
            return self._std

    labels = [text.get_text() for text in fig.axes[3].get_legend().get_texts()]
    assert labels == ["±3σ", "b_ω x estimate"] and fig.axes[3].get_ylabel() == "b_ω x [deg/h]"

    # two runs whose σ coincide must both show: the second one dashed
    fig = plotting.plot_bias_sigmas({"random walk": Run(1.0), "constant": Run(1.0)})
    assert [len(ax.lines) for ax in fig.axes] == [2, 2]
    assert all(ax.lines[0].get_linestyle() == "-" and ax.lines[1].get_linestyle() != "-" for ax in fig.axes)
    assert all(ax.get_yscale() == "log" for ax in fig.axes)
    assert fig.axes[0].get_ylabel() == "σ of b_a [m/s²]"
    assert fig.axes[0].get_title().endswith(", z")
    with pytest.raises(ValueError, match="axis"):
        plotting.plot_bias_sigmas({"a": Run(1.0)}, axis=3)
    with pytest.raises(ValueError, match="results"):
        plotting.plot_bias_sigmas({"a": object()})


def test_curves_take_one_line_style_each():
    fig, ax = plt.subplots()
    t = np.arange(5.0)
    lines = plotting.plot_curves(ax, {"a": (t, t), "b": (t, t)}, linestyles=["-", "--"])
    assert [line.get_linestyle() for line in lines] == ["-", "--"]
    with pytest.raises(ValueError, match="linestyles"):
        plotting.plot_curves(ax, {"a": (t, t), "b": (t, t)}, linestyles=["-"])
    plt.close(fig)


def test_outage_and_error_norm_figures():
    t = np.linspace(300.0, 400.0, 101)
    fig = plotting.plot_outage_error(t, np.abs(np.sin(t)), np.full(101, 0.5), (325.0, 355.0), title="outage")
    (ax,) = fig.axes
    labels = [text.get_text() for text in ax.get_legend().get_texts()]
    assert "no observations" in labels and "horizontal error" in labels and "0 to 3σ" in labels
    # a norm is never negative: the band runs from 0 to 3σ, not ±3σ
    band = next(c for c in ax.collections if c.get_label() == "0 to 3σ")
    heights = band.get_paths()[0].vertices[:, 1]
    assert np.isclose(heights.min(), 0.0) and np.isclose(heights.max(), 1.5)
    assert ax.get_ylim()[0] == 0.0
    with pytest.raises(ValueError, match="norm"):
        plotting.plot_outage_error(t, np.sin(t), np.full(101, 0.5), (325.0, 355.0))
    with pytest.raises(ValueError, match="sigma"):
        plotting.plot_outage_error(t, np.abs(t), -np.ones(101), (325.0, 355.0))
    with pytest.raises(ValueError, match="outage"):
        plotting.plot_outage_error(t, t, np.ones(101), (355.0, 325.0))
    fig = plotting.plot_error_norms({"off": (t, t * 0 + 1.0), "on": (t, t * 0 + 0.5)},
                                    spans=[[310.0, 312.0], [330.0, 331.0]], span_label="interpolated")
    (ax,) = fig.axes
    assert len(ax.lines) == 2 and len(ax.patches) == 2


class _MC:
    def __init__(self, scale, n_runs=4, K=20):
        rng = np.random.default_rng(int(scale * 10))
        self.t = np.arange(K, dtype=float)
        self.nees = scale * rng.chisquare(15, size=(n_runs, K))
        self.nis = rng.chisquare(6, size=(n_runs, K))
        self.n_runs = n_runs


def test_monte_carlo_figure_draws_each_run_over_its_band():
    fig = plotting.plot_monte_carlo({"tuned Q": _MC(1.0), "Q / 100": _MC(4.0)})
    assert len(fig.axes) == 2
    for ax in fig.axes:
        assert len(ax.lines) == 2 and len(ax.collections) == 1
    lo, hi = plotting.consistency.chi2_bounds(15, 4)
    band = fig.axes[0].collections[0].get_paths()[0].vertices[:, 1]
    assert band.min() == pytest.approx(lo) and band.max() == pytest.approx(hi)
    with pytest.raises(ValueError, match="runs"):
        plotting.plot_monte_carlo({"a": _MC(1.0), "b": _MC(1.0, n_runs=3)})


def test_sensitivity_and_gating_figures():
    from types import SimpleNamespace as Row
    rows = [Row(q_factor=f, r_factor=1.0, ape_position=0.1 * f ** 0.1, ape_attitude_deg=0.05, nis=6.0 / f ** 0.2,
                nees_pose=6.0 * f ** 0.1) for f in (0.1, 1.0, 10.0)]
    fig = plotting.plot_sensitivity({"Q factor": ("q_factor", rows), "R factor": ("r_factor", rows[:1])},
                                    (5.5, 6.5))
    assert len(fig.axes) == 4
    assert [len(ax.lines) for ax in fig.axes] == [2, 2, 3, 3]     # bottom: NIS, NEES, the dof line
    with pytest.raises(ValueError, match="lo"):
        plotting.plot_sensitivity({"Q factor": ("q_factor", rows)}, (6.5, 5.5))
    t = np.linspace(0.0, 10.0, 101)
    fig = plotting.plot_gating({"ungated": (t, t * 0 + 1.0), "gated (99 %)": (t, t * 0 + 0.1)},
                               t, np.full(101, 5.0), 16.81, outlier_times=[2.0, 2.1, 7.0])
    ax1, ax2 = fig.axes
    assert len(ax1.lines) == 2 and len(ax1.patches) == 3 and len(ax2.patches) == 3
    assert to_rgba(ax1.lines[0].get_color()) == to_rgba(COLORS["prior"])
    with pytest.raises(ValueError, match="threshold"):
        plotting.plot_gating({"a": (t, t)}, t, t, -1.0)
    with pytest.raises(ValueError, match="nis"):
        plotting.plot_gating({"a": (t, t)}, t, t[:-1], 16.0)


def test_track_with_zoom_has_two_panels_and_checks_zoom():
    xy = np.column_stack([np.arange(20.0), np.sin(np.arange(20.0))])
    fig = plotting.plot_track_with_zoom(xy, xy + 0.1, xy, zoom=((2, 5), (-1, 1)), title="turns")
    ax1, ax2 = fig.axes
    assert ax1.get_title() == "turns" and ax2.get_xlim() == (2.0, 5.0)
    assert len(ax1.lines) == len(ax2.lines) == 3
    with pytest.raises(ValueError, match="zoom"):
        plotting.plot_track_with_zoom(xy, xy, zoom=((5, 2), (0, 1)))
    with pytest.raises(ValueError, match="zoom"):
        plotting.plot_track_with_zoom(xy, xy, zoom=(1, 2))


# --------------------------------------------------------------------------------------
# issue 15, item 5: what a look at every figure found
# --------------------------------------------------------------------------------------

def _extent(artist):
    fig = artist.figure
    fig.canvas.draw()
    return artist.get_window_extent(fig.canvas.get_renderer())


def _overlap(a, b):
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


def test_kf_2d_error_legend_sits_outside_the_error_panels():
    # the ±3σ band fills the error panels, so a legend inside them covers it
    n = 30
    t = np.arange(n, dtype=float)
    x_hat = np.column_stack([t, 2 * t, np.ones(n), np.ones(n)])
    hist = FakeHistory(x_hat, np.tile(np.diag([0.5, 0.3, 0.1, 0.1]), (n, 1, 1)))
    fig = plotting.plot_kf_2d(t, x_hat[:, :2] + 0.2, x_hat[:, :2] - 0.3, hist)
    ax_e1, ax_e2 = fig.axes[1], fig.axes[2]
    legend = _extent(ax_e1.get_legend())
    for ax in (ax_e1, ax_e2):
        assert not _overlap(legend, _extent(ax)), "the error legend covers an error panel"
    labels = [text.get_text() for text in ax_e1.get_legend().get_texts()]
    assert labels == ["±3σ", "error"]


def test_consistency_curves_take_one_line_style_per_curve(ax):
    t = np.arange(10.0)
    same = np.full(10, 6.0)
    lines, _ = plotting.plot_consistency_curves(ax, t, {"a": same, "b": same}, 1.2, 14.4, linestyles=("-", "--"))
    assert [line.get_linestyle() for line in lines] == ["-", "--"]
    lines, _ = plotting.plot_consistency_curves(ax, t, {"c": same, "d": same}, 1.2, 14.4)
    assert [line.get_linestyle() for line in lines] == ["-", "-"]       # default unchanged: solid
    with pytest.raises(ValueError, match="linestyles"):
        plotting.plot_consistency_curves(ax, t, {"a": same, "b": same}, 1.2, 14.4, linestyles=("-",))


def test_monte_carlo_curves_that_coincide_both_show():
    # identical NIS of two tunings: the second must not hide the first (a dashed line over a solid one)
    fig = plotting.plot_monte_carlo({"tuned Q": _MC(1.0), "Q / 100": _MC(4.0)})
    for ax in fig.axes:
        first, second = ax.lines
        assert first.get_linestyle() == "-" and second.get_linestyle() not in ("-", "None")


def test_sensitivity_figure_labels_its_axes_and_keeps_black_for_the_truth():
    from types import SimpleNamespace as Row
    rows = [Row(q_factor=f, ape_position=0.1, ape_attitude_deg=0.05, nis=6.0, nees_pose=6.0) for f in (0.1, 1.0)]
    fig = plotting.plot_sensitivity({"Q factor": ("q_factor", rows)}, (5.5, 6.5))
    top, bottom = fig.axes
    assert "[m]" in top.get_ylabel() and "[deg]" in top.get_ylabel()
    assert "NIS" in bottom.get_ylabel() and "NEES" in bottom.get_ylabel()
    for ax in fig.axes:
        for line in ax.lines:
            if line.get_label().startswith("_"):
                continue                                   # the unlabelled reference line at 6
            assert to_rgba(line.get_color()) != to_rgba(COLORS["truth"]), f"{line.get_label()} is drawn in black"


def test_gating_legends_sit_beside_the_panels():
    # an error peak in the upper right corner, where a legend inside the panel would sit
    t = np.linspace(0.0, 10.0, 101)
    peak = np.where(t > 9.0, 5.0, 0.1)
    fig = plotting.plot_gating({"ungated": (t, peak), "gated (99 %)": (t, t * 0 + 0.1)},
                               t, np.where(t < 1.0, 300.0, 5.0), 16.81, outlier_times=[9.5])
    for ax in fig.axes:
        assert not _overlap(_extent(ax.get_legend()), _extent(ax)), "a legend covers a panel of the gating figure"


def test_kf_1d_steps_density_label_carries_the_inverse_unit_of_the_state():
    from types import SimpleNamespace as Table
    table = Table(x_check=np.array([0.0, 1.2]), P_check=np.array([2.0, 0.5]), y=np.array([1.5, 2.1]),
                  K=np.array([0.8, 0.5]), x_hat=np.array([1.2, 1.65]), P_hat=np.array([0.4, 0.25]), r=0.5)
    assert plotting.plot_kf_1d_steps(table, steps=[0, 1]).axes[0].get_ylabel() == "density [1/m]"
    assert plotting.plot_kf_1d_steps(table, steps=[0, 1], unit="m/s").axes[0].get_ylabel() == "density [1/(m/s)]"
