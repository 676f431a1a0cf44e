"""The chapter-01 and chapter-02 experiments of ``chapters.intuition``."""

import numpy as np
import pytest

from kalman_course.chapters import intuition


def test_truncated_normal_moments_match_scipy():
    stats = pytest.importorskip("scipy.stats")
    for mu, sigma, low, high in ((3.0, 2.0, 0.0, 10.0), (0.0, 1.0, -0.5, 2.0), (-4.0, 0.3, -4.2, -1.0)):
        d = stats.truncnorm((low - mu) / sigma, (high - mu) / sigma, loc=mu, scale=sigma)
        m, s = intuition.truncated_normal_moments(mu, sigma, low, high)
        assert m == pytest.approx(d.mean(), rel=1e-12, abs=1e-12)
        assert s == pytest.approx(d.std(), rel=1e-10)


def test_truncated_normal_moments_against_a_fine_grid():
    x = np.linspace(0.0, 10.0, 200_001)
    w = np.exp(-0.5 * ((x - 3.0) / 2.0) ** 2)
    w /= w.sum()
    m = np.sum(w * x)
    s = np.sqrt(np.sum(w * (x - m) ** 2))
    assert intuition.truncated_normal_moments(3.0, 2.0, 0.0, 10.0) == pytest.approx((m, s), abs=1e-4)


def test_truncated_normal_moments_without_truncation_are_the_gaussians():
    assert intuition.truncated_normal_moments(1.0, 0.5, -20.0, 20.0) == pytest.approx((1.0, 0.5), abs=1e-12)


@pytest.mark.parametrize("args", [(0.0, 0.0, -1.0, 1.0), (0.0, 1.0, 1.0, 1.0), (0.0, 1.0, 2.0, -2.0),
                                  (0.0, 1.0, 50.0, 60.0)])
def test_truncated_normal_moments_rejects_bad_input(args):
    with pytest.raises(ValueError):
        intuition.truncated_normal_moments(*args)


P = np.array([[4.0, 1.5], [1.5, 1.0]])
G = np.array([[1.0, 0.0]])
R = np.array([[0.25]])


def test_information_trial_traces_and_covariance_drop():
    t = intuition.information_trial([0.0, 0.0], P, G, R, seeds=[0], n_runs=10)
    K = P @ G.T / (P[0, 0] + R[0, 0])
    assert t.prior_trace == pytest.approx(5.0)
    assert t.posterior_trace == pytest.approx(np.trace(P - K @ G @ P))
    assert np.all(t.covariance_drop >= -1e-12)
    assert t.prior_sq_error.shape == t.posterior_sq_error.shape == (1, 10)


def test_information_trial_correct_model_mse_matches_trace():
    t = intuition.information_trial([1.0, -2.0], P, G, R, seeds=range(4), n_runs=5000)
    assert np.mean(t.prior_sq_error) == pytest.approx(t.prior_trace, rel=0.05)
    assert np.mean(t.posterior_sq_error) == pytest.approx(t.posterior_trace, rel=0.05)
    assert 0.05 < np.median(t.share_worse) < 0.5


def test_information_trial_wrong_models_hurt():
    biased = intuition.information_trial([0.0, 0.0], P, G, R, seeds=range(3), n_runs=2000, bias=[3.0])
    noisy = intuition.information_trial([0.0, 0.0], P, G, R, seeds=range(3), n_runs=2000, R_true=[[16.0]])
    assert np.all(biased.mse_ratio > 1) and np.all(noisy.mse_ratio > 1)


def test_information_trial_is_seeded():
    a = intuition.information_trial([0.0, 0.0], P, G, R, seeds=[3, 4], n_runs=50)
    b = intuition.information_trial([0.0, 0.0], P, G, R, seeds=[3, 4], n_runs=50)
    assert np.array_equal(a.posterior_sq_error, b.posterior_sq_error)
    assert not np.array_equal(a.posterior_sq_error[0], a.posterior_sq_error[1])


@pytest.mark.parametrize("kwargs", [dict(seeds=[]), dict(seeds=[-1]), dict(seeds=[0], n_runs=0),
                                    dict(seeds=[0], bias=[1.0, 2.0])])
def test_information_trial_rejects_bad_input(kwargs):
    with pytest.raises(ValueError):
        intuition.information_trial([0.0, 0.0], P, G, R, **kwargs)


# --------------------------------------------------------------------------------------
# chapter 02: two correlated scalars conditioned by hand, the slice picture, folded SymPy
# --------------------------------------------------------------------------------------

import sympy as sp  # noqa: E402

from kalman_course import gaussians as library  # noqa: E402
from kalman_course.symbolic.equations import Derivation, Equation  # noqa: E402

PAIRS = [(1.5, 0.8, -0.6), (0.3, 4.0, 0.9), (2.0, 2.0, 0.05), (1.0, 0.5, -0.97)]


def _library_conditional(mean, cov, y):
    m, v = library.conditional(mean[:1], mean[1:], cov[:1, :1], cov[:1, 1:], cov[1:, 1:], [y])
    return m[0], v[0, 0]


@pytest.mark.parametrize("sx, sy, rho", PAIRS)
def test_correlated_pair_covariance_has_the_given_spreads_and_correlation(sx, sy, rho):
    cov = intuition.correlated_pair_covariance(sx, sy, rho)
    assert cov.shape == (2, 2) and np.array_equal(cov, cov.T)
    assert np.sqrt(np.diag(cov)) == pytest.approx([sx, sy], rel=1e-14)
    assert cov[0, 1] / np.sqrt(cov[0, 0] * cov[1, 1]) == pytest.approx(rho, rel=1e-14)


@pytest.mark.parametrize("args", [(0.0, 1.0, 0.2), (1.0, -2.0, 0.2), (1.0, 1.0, 1.0), (1.0, 1.0, -1.0),
                                  (1.0, 1.0, np.nan), (1.0, 1.0, "0.3"), ("1", 1.0, 0.3)])
def test_correlated_pair_covariance_rejects_bad_input(args):
    with pytest.raises(ValueError, match="sigma_x|sigma_y|rho"):
        intuition.correlated_pair_covariance(*args)


def test_scalar_conditioning_is_proved_step_by_step():
    d = intuition.scalar_conditioning()
    assert d.verify()
    labels = ("cov_wy", "slope", "var_w_any_a", "var_w", "mean_from_blocks", "var_from_blocks", "exponent_split",
              "determinant_split")
    assert d.check() == {label: True for label in labels}


@pytest.mark.parametrize("sx, sy, rho", PAIRS)
@pytest.mark.parametrize("y", [-3.0, 0.7])
def test_scalar_conditioning_matches_the_library_for_any_pair(sx, sy, rho, y):
    d = intuition.scalar_conditioning()
    pair = dict(mu_x=0.4, mu_y=-1.1, sigma_x=sx, sigma_y=sy, rho=rho)
    cov = intuition.correlated_pair_covariance(sx, sy, rho)
    m, v = _library_conditional(np.array([0.4, -1.1]), cov, y)
    assert d.evaluate("mean", y=y, **pair) == pytest.approx(m, abs=1e-12)
    assert d.evaluate("var", **pair) == pytest.approx(v, rel=1e-12)
    assert d.evaluate("slope", **pair) == pytest.approx(cov[0, 1] / cov[1, 1], rel=1e-12)


def test_scalar_conditioning_identities_reject_the_usual_slips():
    # the proof machinery on the same left-hand sides: a wrong right-hand side does not hold
    d = intuition.scalar_conditioning()
    sx, sy, rho = (d.symbols[k] for k in ("sigma_x", "sigma_y", "rho"))
    var_lhs = d["var_w"].lhs
    for wrong in (sx**2 * (1 - rho), sx * (1 - rho**2), sx * sp.sqrt(1 - rho**2)):
        assert not Equation("wrong_var", var_lhs, sp.Matrix([[wrong]])).holds()
    assert not Equation("wrong_slope", d["slope"].lhs, rho * sy / sx).holds()
    mu_x, mu_y, y = (d.symbols[k] for k in ("mu_x", "mu_y", "y"))
    assert not Equation("wrong_mean", d["mean_from_blocks"].lhs,
                        sp.Matrix([[mu_x + rho * sy / sx * (y - mu_y)]])).holds()


def test_window_slice_keeps_the_window_and_its_numbers():
    pts = np.array([[1.0, 0.95], [3.0, 1.02], [5.0, 1.2], [-1.0, 0.99], [9.0, 0.5]])
    w = intuition.window_slice(pts, 1.0, 0.1)
    assert w.n == 3 and np.array_equal(w.x, [1.0, 3.0, -1.0])
    assert w.x_mean == pytest.approx(1.0) and w.x_var == pytest.approx(4.0)     # ddof = 1
    assert w.y_offset == pytest.approx((-0.05 + 0.02 - 0.01) / 3)
    assert w.y_spread == pytest.approx((0.05**2 + 0.02**2 + 0.01**2) / 3)
    a = -2.5
    assert w.mean_tolerance(a, n_se=3) == pytest.approx(3 * np.sqrt(4.0 / 3) + 2.5 * abs(w.y_offset))
    assert w.var_tolerance(a, n_se=3) == pytest.approx(3 * 4.0 * np.sqrt(2.0 / 2) + 6.25 * w.y_spread)


def test_window_slice_accepts_the_conditional_and_rejects_the_marginal():
    mean, cov = np.array([1.0, -2.0]), intuition.correlated_pair_covariance(1.5, 0.8, -0.6)
    draws = np.random.default_rng(7).multivariate_normal(mean, cov, size=400_000, method="cholesky")
    w = intuition.window_slice(draws, -1.4, 0.03)
    m, v = _library_conditional(mean, cov, -1.4)
    a = cov[0, 1] / cov[1, 1]
    assert abs(w.x_mean - m) < w.mean_tolerance(a) and abs(w.x_var - v) < w.var_tolerance(a)
    assert abs(w.x_mean - mean[0]) > w.mean_tolerance(a) and abs(w.x_var - cov[0, 0]) > w.var_tolerance(a)


@pytest.mark.parametrize("args, match", [((np.zeros((5, 3)), 0.0, 1.0), "samples"),
                                         ((np.full((5, 2), np.nan), 0.0, 1.0), "samples"),
                                         ((np.zeros((5, 2)), np.inf, 1.0), "y_obs"),
                                         ((np.zeros((5, 2)), 0.0, 0.0), "half_width"),
                                         ((np.zeros((5, 2)), 3.0, 0.1), "half_width")])
def test_window_slice_rejects_bad_input(args, match):
    with pytest.raises(ValueError, match=match):
        intuition.window_slice(*args)


@pytest.mark.parametrize("cov", [np.diag([4.0, 0.25]), np.array([[2.25, -0.72], [-0.72, 0.64]]),
                                 np.array([[0.5, 0.69], [0.69, 1.0]])])
@pytest.mark.parametrize("k", [1.0, 2.5])
def test_ellipse_highest_point_is_where_y_peaks(cov, k):
    mean = np.array([0.3, -4.0])
    top = intuition.ellipse_highest_point(mean, cov, k)
    # maximising y on (p - mean)ᵀ Σ⁻¹ (p - mean) = k² gives p = mean + k Σ e_y / sqrt(Σ_yy)
    # good to the documented 2π k σ / n_points (σ the larger standard deviation)
    tol = 2 * np.pi * k * np.sqrt(np.max(np.diag(cov))) / 100_001
    assert top == pytest.approx(mean + k * cov[:, 1] / np.sqrt(cov[1, 1]), abs=tol)
    d = top - mean
    assert d @ np.linalg.solve(cov, d) == pytest.approx(k * k, rel=1e-9)


@pytest.mark.parametrize("kwargs", [dict(cov=np.diag([1.0, 0.0])), dict(n_sigma=0.0), dict(n_points=4),
                                    dict(n_points=True), dict(mean=[0.0])])
def test_ellipse_highest_point_rejects_bad_input(kwargs):
    args = dict(mean=[0.0, 0.0], cov=np.eye(2), n_sigma=1.0) | kwargs
    with pytest.raises(ValueError):
        intuition.ellipse_highest_point(**args)


def _tiny_derivation():
    a, b = sp.symbols("a b")
    return Derivation("tiny", "t", "m", (
        Equation("name_it", sp.Symbol("c"), a + b, "a name", "definition"),
        Equation("true_one", (a + b) ** 2, a**2 + 2 * a * b + b**2, "true"),
        Equation("false_one", (a + b) ** 2, a**2 + b**2, "false"),
        Equation("other", a * b, b * a, "also true"),
    ))


def test_check_chain_reports_each_step_and_what_it_leaves_out():
    d = _tiny_derivation()
    good = intuition.check_chain(d, {"square": "true_one"})
    assert good.all_hold and good.rows == (("square", ("true_one",), True),)
    assert good.unnamed == ("false_one", "other")
    bad = intuition.check_chain(d, {"square": ["true_one"], "wrong square": ["other", "false_one"]})
    assert not bad.all_hold and [ok for _, _, ok in bad.rows] == [True, False] and bad.unnamed == ()
    assert "FAILS" in bad.to_text() and "wrong square" in str(bad)


def test_check_chain_covers_the_lecture_s_block_derivations():
    from kalman_course import symbolic
    schur = symbolic.schur_block_inverse()
    chain = intuition.check_chain(schur, {"ldu": "ldu", "blocks": "inverse_blocks"})
    assert chain.all_hold and "inverse_2x2" in chain.unnamed and "schur_complement" not in chain.unnamed


@pytest.mark.parametrize("steps, match", [({}, "non-empty"), ({"s": []}, "names no identity"),
                                          ({"s": "missing"}, "lacks"), ({"s": "name_it"}, "definition"),
                                          (["true_one"], "mapping")])
def test_check_chain_rejects_bad_steps(steps, match):
    with pytest.raises(ValueError, match=match):
        intuition.check_chain(_tiny_derivation(), steps)
    with pytest.raises(ValueError, match="Derivation"):
        intuition.check_chain("not a derivation", {"s": "true_one"})


def test_folded_wraps_the_full_markdown_in_details():
    d = _tiny_derivation()
    text = intuition.Folded(d, "  open me: a < b  ")._repr_markdown_()
    assert text.startswith("<details>\n<summary>open me: a &lt; b</summary>\n\n")
    assert text.rstrip().endswith("</details>")
    assert d.to_markdown() in text
    assert "open me" in repr(intuition.Folded(d, "open me")) and "tiny" in repr(intuition.Folded(d, "open me"))
    for bad in ("", "   ", 3):
        with pytest.raises(ValueError, match="summary"):
            intuition.Folded(d, bad)
    with pytest.raises(ValueError, match="Derivation"):
        intuition.Folded(d.to_markdown(), "x")


def test_conditional_slice_figure_draws_the_conditional_on_the_slice():
    import matplotlib.pyplot as plt

    from kalman_course import plotting
    mean, cov, y_obs = np.array([1.0, -2.0]), np.array([[2.25, -0.72], [-0.72, 0.64]]), -1.4
    m, v = _library_conditional(mean, cov, y_obs)
    rng = np.random.default_rng(0)
    fig = plotting.plot_conditional_slice(mean, cov, y_obs, samples=rng.normal(size=(50, 2)),
                                          slice_x=rng.normal(m, np.sqrt(v), 500))
    top, bottom = fig.axes
    by_label = {line.get_label(): line for line in top.get_lines()}
    xs, ys = by_label["E[x | y] (regression line)"].get_data()
    assert (xs[1] - xs[0]) / (ys[1] - ys[0]) == pytest.approx(cov[0, 1] / cov[1, 1])
    assert np.interp(y_obs, ys, xs) == pytest.approx(m)
    gx, gy = by_label["p(x | y) along the slice"].get_data()
    assert gx[np.argmax(gy)] == pytest.approx(m, abs=np.ptp(gx) / 399)
    band_x, _ = by_label["±3σ of p(x | y)"].get_data()
    assert band_x == pytest.approx([m - 3 * np.sqrt(v), m + 3 * np.sqrt(v)])
    assert sum("joint" in p.get_label() for p in top.patches) == 2
    curves = {line.get_label(): line for line in bottom.get_lines()}
    cx, cy = curves[f"p(x | y = {y_obs:g})"].get_data()
    assert np.sum(cy) * (cx[1] - cx[0]) == pytest.approx(1.0, abs=0.01)       # a density
    assert cx[np.argmax(curves["p(x), before"].get_data()[1])] == pytest.approx(mean[0], abs=0.05)
    assert any("500 simulated draws" in p.get_label() for p in bottom.patches)
    plt.close(fig)


@pytest.mark.parametrize("kwargs, match", [(dict(cov=np.diag([1.0, 0.0])), "cov"), (dict(n_sigma=()), "n_sigma"),
                                           (dict(band_sigma=-1.0), "band_sigma"), (dict(y_obs=np.nan), "y_obs")])
def test_conditional_slice_figure_rejects_bad_input(kwargs, match):
    from kalman_course import plotting
    args = dict(mean=[0.0, 0.0], cov=np.array([[1.0, 0.3], [0.3, 2.0]]), y_obs=0.5) | kwargs
    with pytest.raises(ValueError, match=match):
        plotting.plot_conditional_slice(**args)
