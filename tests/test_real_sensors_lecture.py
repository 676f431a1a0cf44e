"""Lecture 10's glue (kalman_course.chapters.real_sensors): its figure, sample checks and definitions.

Everything here is simulated from seeds (error models, synthetic trajectories), except one
short table from the coloured-noise experiment (real KITTI IMU and truth, simulated lidar
errors). Statistical tolerances are derived from the sample sizes in the comments.
"""

from __future__ import annotations

import math

import matplotlib

matplotlib.use("Agg")

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

from kalman_course.chapters import coloured_noise, real_sensors as rs  # noqa: E402
from kalman_course.core import so3  # noqa: E402
from kalman_course.data import GaussMarkovErrors, MapMatchingFailures, WhiteErrors  # noqa: E402
from kalman_course.evaluation.drift import drift  # noqa: E402
from kalman_course.filters.eskf_relative import relative_motion, relative_pose_jacobian  # noqa: E402
from kalman_course.plotting import plot_error_draws  # noqa: E402


@pytest.fixture(autouse=True)
def close_figures():
    yield
    plt.close("all")


# ---------------------------------------------------------------------------------------
# The variance of a mean of Gauss–Markov errors
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("phi", [0.3, 0.9016, 0.99])
def test_mean_variance_factor_is_the_closed_form_and_tends_to_the_inflation_factor(phi):
    k = (1 + phi) / (1 - phi)
    for n in (1, 2, 30, 1000):
        closed = k - 2 * phi * (1 - phi ** n) / (n * (1 - phi) ** 2)
        assert rs.mean_variance_factor(phi, n) == pytest.approx(closed, rel=1e-10)
    # the gap to the limit shrinks as 1/n
    tau = -0.1 / math.log(phi)
    assert coloured_noise.inflation_factor(tau, 0.1) == pytest.approx(k, rel=1e-12)
    assert 0 < k - rs.mean_variance_factor(phi, 10**6) < 2 * phi / (10**6 * (1 - phi) ** 2) * 1.000001


def test_mean_variance_factor_of_white_errors_is_one_and_of_one_error_is_one():
    assert rs.mean_variance_factor(0.0, 50) == 1.0
    assert rs.mean_variance_factor(0.95, 1) == 1.0


def test_mean_variance_factor_against_samples():
    # 4000 draws × 6 components of 20 errors 0.1 s apart with τ = 0.5 s: N ē²/σ² is k_N χ²(1),
    # whose sample mean over M = 24000 has a standard error k_N √(2/M) (0.9 %); 4 of them
    model = GaussMarkovErrors(0.2, 0.3, 0.5)
    t = np.arange(20) * 0.1
    x = rs.normalised_draws(model, t, 4000, seed=3)
    k_n = rs.mean_variance_factor(math.exp(-0.1 / 0.5), 20)
    sample = np.mean(20 * x.mean(axis=1) ** 2)
    assert abs(sample - k_n) < 4 * k_n * math.sqrt(2 / x.shape[0])


# ---------------------------------------------------------------------------------------
# Normalised draws
# ---------------------------------------------------------------------------------------

def test_normalised_draws_shape_seed_and_unit_variance():
    t = np.arange(15) * 0.1
    model = GaussMarkovErrors(0.2, 0.3, 1.0)
    x = rs.normalised_draws(model, t, 500, seed=1)
    assert x.shape == (3000, 15)
    assert np.array_equal(x, rs.normalised_draws(model, t, 500, seed=1))
    assert not np.array_equal(x, rs.normalised_draws(model, t, 500, seed=2))
    # variance 1 at every time: the sample variance of M = 3000 has standard error √(2/M) (2.6 %)
    assert np.all(np.abs(x.var(axis=0) - 1) < 4 * math.sqrt(2 / 3000))


def test_normalised_draws_correlate_as_exp_of_minus_dt_over_tau_and_white_ones_not():
    # E[x0 x1] = φ with standard error √((1 + φ²)/M), M = 6000
    t = np.arange(3) * 0.1
    phi = math.exp(-0.1 / 0.4)
    gm = rs.normalised_draws(GaussMarkovErrors(0.2, 0.3, 0.4), t, 1000, seed=4)
    white = rs.normalised_draws(WhiteErrors(0.2, 0.3), t, 1000, seed=4)
    M = gm.shape[0]
    assert abs(np.mean(gm[:, 0] * gm[:, 1]) - phi) < 4 * math.sqrt((1 + phi ** 2) / M)
    assert abs(np.mean(gm[:, 0] * gm[:, 2]) - phi ** 2) < 4 * math.sqrt((1 + phi ** 4) / M)
    assert abs(np.mean(white[:, 0] * white[:, 1])) < 4 * math.sqrt(1 / M)


# ---------------------------------------------------------------------------------------
# The relative-pose Jacobian and the drift metric
# ---------------------------------------------------------------------------------------

@pytest.mark.parametrize("seed", [0, 1, 2])
def test_relative_jacobian_by_differences_equals_the_analytic_one(seed):
    rng = np.random.default_rng(seed)
    p_c, p = 5.0 * rng.standard_normal((2, 3))
    R_c, R = so3.exp(rng.standard_normal(3)), so3.exp(rng.standard_normal(3))
    numeric = rs.relative_jacobian_by_differences(p_c, R_c, p, R)
    assert numeric.shape == (6, 21)
    np.testing.assert_allclose(numeric, relative_pose_jacobian(R_c, *relative_motion(p_c, R_c, p, R)), atol=1e-8)


def test_relative_jacobian_by_differences_fails_for_a_wrong_block():
    # the check can fail: a sign flip of the clone's position block is seen
    rng = np.random.default_rng(7)
    p_c, p = 5.0 * rng.standard_normal((2, 3))
    R_c, R = so3.exp(rng.standard_normal(3)), so3.exp(rng.standard_normal(3))
    wrong = relative_pose_jacobian(R_c, *relative_motion(p_c, R_c, p, R))
    wrong[0:3, 15:18] *= -1
    assert not np.allclose(rs.relative_jacobian_by_differences(p_c, R_c, p, R), wrong, atol=1e-8)


def _curved_track(n=3000, step=0.5, yaw_rate=0.004):
    """A planar path (m) with slowly varying heading and its rotations; frames `step` m apart."""
    s = np.arange(n) * step
    yaw = 0.5 * np.sin(yaw_rate * s)
    p = np.column_stack([np.cumsum(step * np.cos(yaw)), np.cumsum(step * np.sin(yaw)), 0.01 * s])
    R = so3.exp(np.column_stack([np.zeros(n), np.zeros(n), yaw]))
    return p, R


def test_segment_errors_from_the_definition_equal_the_drift_metric():
    p, R = _curved_track()
    # an estimate with a 1 % scale error and a yaw error growing with distance
    extra = so3.exp(np.column_stack([np.zeros(len(p)), np.zeros(len(p)), 2e-5 * np.arange(len(p))]))
    p_est, R_est = 1.01 * p, R @ extra
    d = drift(p_est, R_est, p, R)
    tr, rot = rs.segment_errors(p_est, R_est, p, R, d.first, d.last, d.length)
    np.testing.assert_allclose(tr, 100 * d.translation_error / d.length, rtol=1e-12)
    np.testing.assert_allclose(rot, np.rad2deg(d.rotation_error / d.length) * 100, rtol=1e-9, atol=1e-12)
    assert tr.mean() == pytest.approx(d.translation_percent, rel=1e-12)
    assert rot.mean() == pytest.approx(d.rotation_deg_per_100m, rel=1e-9)
    # the truth against itself has no drift
    tr0, rot0 = rs.segment_errors(p, R, p, R, d.first, d.last, d.length)
    assert np.abs(tr0).max() < 1e-9 and np.abs(rot0).max() < 1e-6


# ---------------------------------------------------------------------------------------
# Tables a lecture can store: no wall-clock time unless asked
# ---------------------------------------------------------------------------------------

def test_the_coloured_noise_table_shows_its_run_time_only_when_asked():
    # one τ, one seed, one filter: the real KITTI IMU and truth with simulated white lidar errors
    result = coloured_noise.coloured_noise("cruise", time_constants=(0.0,), seeds=(1,), remedies=("plain",))
    assert "runtime" not in result.table()
    assert result.table(timings=True).splitlines()[:-1] == result.table().splitlines()
    assert result.table(timings=True).splitlines()[-1].startswith("runtime ")


# ---------------------------------------------------------------------------------------
# The figure
# ---------------------------------------------------------------------------------------

def test_error_draws_figure():
    before = dict(matplotlib.rcParams)
    t = np.arange(300) * 0.1
    gm = GaussMarkovErrors(0.2, 0.3, 1.0)
    failing = MapMatchingFailures(gm, jump_rate=0.1, jump_position=1.0, jump_duration=2.0, outlier_rate=0.05,
                                  outlier_position=2.0)
    draws = {"white": WhiteErrors(0.2, 0.3).draw(t, np.random.default_rng(0)),
             "GM": gm.draw(t, np.random.default_rng(0)),
             "GM + failures": failing.draw(t, np.random.default_rng(0))}
    fig = plot_error_draws(t, draws, sigma=0.2, axis=1, title="simulated")
    assert len(fig.axes) == 3
    assert [ax.get_title(loc="left") for ax in fig.axes] == list(draws)
    assert fig.axes[-1].get_xlabel() == "t [s]" and fig.axes[0].get_ylabel() == "δp_y [m]"
    # the panels without failures share a scale of at least ±3σ; the failures' panel is circled and shaded
    assert fig.axes[0].get_ylim() == fig.axes[1].get_ylim() and fig.axes[0].get_ylim()[1] >= 0.6
    labels = [text.get_text() for text in fig.legends[0].get_texts()]
    assert "outlier" in labels and "inside a jump (a wrong match held)" in labels
    n_outliers = int(draws["GM + failures"].outliers.sum())
    circled = [line for line in fig.axes[2].get_lines() if line.get_label() == "outlier"]
    assert n_outliers > 0 and len(circled[0].get_xdata()) == n_outliers
    assert dict(matplotlib.rcParams) == before


# ---------------------------------------------------------------------------------------
# Bad input
# ---------------------------------------------------------------------------------------

_T = np.arange(10) * 0.1
_DRAW = WhiteErrors(0.2, 0.3).draw(_T, np.random.default_rng(0))


@pytest.mark.parametrize("call, match", [
    (lambda: rs.mean_variance_factor(1.0, 3), "phi"),
    (lambda: rs.mean_variance_factor(-0.1, 3), "phi"),
    (lambda: rs.mean_variance_factor(0.5, 0), "n must"),
    (lambda: rs.mean_variance_factor(0.5, 2.0), "n must"),
    (lambda: rs.normalised_draws("white", _T, 3, 0), "model"),
    (lambda: rs.normalised_draws(WhiteErrors(0.0, 0.3), _T, 3, 0), "positive"),
    (lambda: rs.normalised_draws(WhiteErrors(0.2, 0.3), _T, 0, 0), "repeats"),
    (lambda: rs.normalised_draws(WhiteErrors(0.2, 0.3), _T, 3, -1), "seed"),
    (lambda: rs.relative_jacobian_by_differences([0, 0], np.eye(3), [1, 0, 0], np.eye(3)), "p_clone"),
    (lambda: rs.relative_jacobian_by_differences([0, 0, 0], 2 * np.eye(3), [1, 0, 0], np.eye(3)), "R_clone"),
    (lambda: rs.segment_errors(np.zeros((5, 3)), np.tile(np.eye(3), (4, 1, 1)), np.zeros((5, 3)),
                               np.tile(np.eye(3), (5, 1, 1)), [0], [4], [1.0]), "rotation"),
    (lambda: rs.segment_errors(np.zeros((5, 3)), np.tile(np.eye(3), (5, 1, 1)), np.zeros((5, 3)),
                               np.tile(np.eye(3), (5, 1, 1)), [0], [5], [1.0]), "first and last"),
    (lambda: rs.segment_errors(np.zeros((5, 3)), np.tile(np.eye(3), (5, 1, 1)), np.zeros((5, 3)),
                               np.tile(np.eye(3), (5, 1, 1)), [0.0], [4.0], [1.0]), "first and last"),
    (lambda: plot_error_draws(_T, {}, sigma=0.2), "draws"),
    (lambda: plot_error_draws(_T, {"a": _DRAW}, sigma=0.0), "sigma"),
    (lambda: plot_error_draws(_T, {"a": _DRAW}, sigma=0.2, axis=3), "axis"),
    (lambda: plot_error_draws(_T[::-1], {"a": _DRAW}, sigma=0.2), "t must"),
    (lambda: plot_error_draws(_T[:5], {"a": _DRAW}, sigma=0.2), "draws\\['a'\\]"),
])
def test_bad_input_raises_a_value_error_naming_it(call, match):
    with pytest.raises(ValueError, match=match):
        call()


# ---------------------------------------------------------------------------------------
# The benchmark report's chapter-10 table (kalman_course.tooling.bench)
# ---------------------------------------------------------------------------------------

def test_bench_coloured_noise_rows_say_what_is_real_and_collapse_the_white_case():
    from kalman_course.tooling import bench

    lines = bench.coloured_noise_rows(time_constants=(0.0, 1.0), seeds=(1,))
    head = lines[0]
    assert "Real: the KITTI IMU and ground truth" in head and "Simulated: the lidar pose errors" in head
    rows = [line for line in lines if line.startswith("| 0 |") or line.startswith("| 1 |")]
    # τ = 0: one row for the four identical filters; τ = 1 s: one row per filter
    assert [r.split("|")[1].strip() for r in rows] == ["0", "1", "1", "1", "1"]
    assert "all four filters" in rows[0] and "augmented" in rows[-1]
    assert all(r.rstrip().endswith(("consistent |", "overconfident |", "underconfident |")) for r in rows)
