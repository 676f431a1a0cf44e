"""Chapter 03's tuning from the innovations: the NIS sees the scale of S, the whiteness the gain."""
from __future__ import annotations

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import pytest

from kalman_course import plotting, symbolic
from kalman_course.chapters import kf_tuning
from kalman_course.data import cv_target
from kalman_course.evaluation.consistency import innovation_whiteness
from kalman_course.filters import kf

DT, SIGMA_A, SIGMA = 0.5, 0.7, 1.5          # not 1: a swapped Q and R would show
F, G = symbolic.cv_transition(DT), symbolic.cv_observation_matrix(1)
X0, P0 = np.zeros(2), np.diag([10.0**2, 5.0**2])


@pytest.fixture(scope="module")
def runs():
    return [cv_target(120, DT, SIGMA_A, SIGMA, seed=500 + r, dim=1) for r in range(12)]


def _row(runs, sigma_a, sigma):
    return kf_tuning.innovation_tuning(runs, X0, P0, F, G, symbolic.cv_process_noise(DT, sigma_a),
                                       np.array([[sigma**2]]))


def test_the_true_setting_is_consistent_and_white(runs):
    row = _row(runs, SIGMA_A, SIGMA)
    assert row.nis_verdict == "consistent" and row.n_white >= 10
    lo, hi = row.nis_band
    assert lo < 1.0 < hi and len(row.whiteness) == 12


def test_scaling_q_and_r_together_divides_the_nis_and_keeps_the_estimate(runs):
    true, scaled = _row(runs, SIGMA_A, SIGMA), _row(runs, 2 * SIGMA_A, 2 * SIGMA)     # both variances × 4
    # P0 is not scaled, so after the transient the gain is the same to a few parts in a thousand
    assert scaled.nis == pytest.approx(true.nis / 4, rel=0.02)
    assert scaled.position_rmse == pytest.approx(true.position_rmse, rel=0.01)
    assert scaled.nis_verdict == "underconfident" and scaled.n_white == true.n_white


def test_the_nis_can_be_met_with_a_wrong_ratio_and_the_whiteness_sees_it(runs):
    Q_stiff = symbolic.cv_process_noise(DT, SIGMA_A / 10)
    sigma = kf_tuning.sigma_for_unit_nis(runs, X0, P0, F, G, Q_stiff, lo=0.5, hi=10.0, iterations=12)
    stiff = kf_tuning.innovation_tuning(runs, X0, P0, F, G, Q_stiff, np.array([[sigma**2]]))
    assert sigma > SIGMA                                   # the NIS alone blames the measurements
    assert stiff.nis == pytest.approx(1.0, abs=0.01) and stiff.nis_verdict == "consistent"
    assert stiff.n_white <= 2 and stiff.position_rmse > 1.5 * _row(runs, SIGMA_A, SIGMA).position_rmse


def test_bad_input_names_the_argument(runs):
    Q = symbolic.cv_process_noise(DT, SIGMA_A)
    with pytest.raises(ValueError, match="runs"):
        kf_tuning.innovation_tuning([], X0, P0, F, G, Q, np.eye(1))
    with pytest.raises(ValueError, match="skip"):
        kf_tuning.innovation_tuning(runs, X0, P0, F, G, Q, np.eye(1), skip=-1)
    with pytest.raises(ValueError, match="lo < hi"):
        kf_tuning.sigma_for_unit_nis(runs, X0, P0, F, G, Q, lo=2.0, hi=1.0)
    with pytest.raises(ValueError, match="does not cross"):
        kf_tuning.sigma_for_unit_nis(runs, X0, P0, F, G, Q, lo=5.0, hi=10.0)


def test_plot_innovations(runs):
    h = kf.run_kf(X0, P0, F, symbolic.cv_process_noise(DT, SIGMA_A), G, np.array([[SIGMA**2]]), runs[0].z)
    nu, S = h.innovation[:, 0], h.S[:, 0, 0]
    white = innovation_whiteness(nu[:, None], S[:, None, None], max_lag=5)
    fig = plotting.plot_innovations(runs[0].t, {"a": (nu, S, white), "b": (nu, S, white)})
    assert len(fig.axes) == 3
    labels = fig.axes[1].get_legend_handles_labels()[1]          # axes[0] is the autocorrelation panel
    assert any("innovation" in label for label in labels)
    plt.close(fig)
    with pytest.raises(ValueError, match="cases"):
        plotting.plot_innovations(runs[0].t, {})
    with pytest.raises(ValueError, match="values"):
        plotting.plot_innovations(runs[0].t[:-1], {"a": (nu, S, white)})
