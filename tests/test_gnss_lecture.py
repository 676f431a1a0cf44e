"""Chapter 03's GNSS experiment helper: fresh simulated noise per seed, nothing else changes."""
from __future__ import annotations

import numpy as np
import pytest

from kalman_course.chapters.gnss import position_rmse_over_seeds, truth_at
from kalman_course.data import load_kitti


@pytest.fixture(scope="module")
def record():
    gnss = load_kitti("turns").gnss
    return gnss, truth_at("turns", gnss.t)


def test_each_row_is_one_fresh_draw_given_to_the_filter(record):
    gnss, truth = record
    seen = []

    def passthrough(fixes):
        seen.append(fixes.seed)
        return fixes.position_noisy

    raw, filtered = position_rmse_over_seeds(passthrough, gnss, truth, [3, 4, 5], sigma=2.0)
    assert seen == [3, 4, 5]
    np.testing.assert_array_equal(raw, filtered)            # the filter saw exactly the scored draw
    assert len(set(raw.round(9))) == 3                      # every seed draws new noise
    # 3-D RMSE of N(0, σ² I₃) noise is about σ√3 (here σ = 2 m; the truth is 6 mm from the record)
    assert np.all(np.abs(raw - 2.0 * np.sqrt(3.0)) < 0.6)
    again, _ = position_rmse_over_seeds(passthrough, gnss, truth, [3, 4, 5], sigma=2.0)
    np.testing.assert_array_equal(raw, again)


def test_a_filter_returning_the_truth_scores_zero_and_the_raw_fixes_do_not(record):
    gnss, truth = record
    raw, filtered = position_rmse_over_seeds(lambda fixes: truth, gnss, truth, [0])
    assert filtered[0] == 0.0 and raw[0] > 1.0


def test_bad_input_names_the_argument(record):
    gnss, truth = record
    with pytest.raises(ValueError, match="truth_position"):
        position_rmse_over_seeds(lambda f: f.position_noisy, gnss, truth[:-1], [0])
    with pytest.raises(ValueError, match="seeds"):
        position_rmse_over_seeds(lambda f: f.position_noisy, gnss, truth, [])
