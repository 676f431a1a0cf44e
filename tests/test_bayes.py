"""Tests for kalman_course.filters.bayes (the histogram filter)."""

import numpy as np
import pytest

from kalman_course.filters.bayes import (circular_motion_model, histogram_predict, histogram_update,
                                 normalise)


def test_normalise():
    np.testing.assert_allclose(normalise([1.0, 3.0]), [0.25, 0.75])
    np.testing.assert_allclose(normalise(np.array([0, 2, 0])), [0.0, 1.0, 0.0])


def test_update_is_bayes_by_hand():
    prior = [0.2, 0.3, 0.5]
    likelihood = [0.9, 0.1, 0.5]
    # unnormalised 0.18, 0.03, 0.25; evidence p(y) = 0.46
    np.testing.assert_allclose(histogram_update(prior, likelihood),
                               [0.18 / 0.46, 0.03 / 0.46, 0.25 / 0.46], rtol=1e-14)


def test_update_with_a_scaled_likelihood_is_unchanged():
    rng = np.random.default_rng(0)
    prior = normalise(rng.random(10))
    lik = rng.random(10)
    np.testing.assert_allclose(histogram_update(prior, lik), histogram_update(prior, 7.5 * lik),
                               rtol=1e-14)


def test_zero_evidence_raises_naming_likelihood():
    with pytest.raises(ValueError, match=r"likelihood gives zero evidence"):
        histogram_update([0.5, 0.5, 0.0], [0.0, 0.0, 1.0])


def test_predict_conserves_mass_and_is_total_probability():
    rng = np.random.default_rng(1)
    n = 12
    T = rng.random((n, n))
    T /= T.sum(axis=0)
    belief = normalise(rng.random(n))
    out = histogram_predict(belief, T)
    assert out.sum() == pytest.approx(1.0, abs=1e-14)
    by_hand = [sum(T[i, j] * belief[j] for j in range(n)) for i in range(n)]
    np.testing.assert_allclose(out, by_hand, rtol=1e-13)
    for _ in range(200):                                   # repeated prediction
        out = histogram_predict(normalise(out), T)
    assert out.sum() == pytest.approx(1.0, abs=1e-12)


def test_circular_motion_model_by_hand():
    T = circular_motion_model(5, {0: 0.1, 1: 0.8, 2: 0.1})
    assert T.shape == (5, 5)
    np.testing.assert_allclose(T.sum(axis=0), 1.0)
    # from cell 4 the robot reaches 4, 0 and 1 (wrap-around)
    np.testing.assert_allclose(T[:, 4], [0.8, 0.1, 0.0, 0.0, 0.1])
    belief = np.array([0.0, 1.0, 0.0, 0.0, 0.0])
    np.testing.assert_allclose(histogram_predict(belief, T), [0.0, 0.1, 0.8, 0.1, 0.0])
    belief = np.array([0.5, 0.0, 0.0, 0.0, 0.5])
    np.testing.assert_allclose(histogram_predict(belief, T), [0.45, 0.45, 0.05, 0.0, 0.05])


def test_circular_motion_model_negative_and_coinciding_offsets():
    T = circular_motion_model(4, {-1: 0.5, 3: 0.25, 1: 0.25})      # -1 and 3 coincide mod 4
    np.testing.assert_allclose(T[:, 0], [0.0, 0.25, 0.0, 0.75])
    exact = circular_motion_model(6, {2: 1.0})
    np.testing.assert_array_equal(histogram_predict(np.eye(6)[5], exact), np.eye(6)[1])


def test_a_corridor_with_doors_localises():
    """The classic example: doors at cells 0, 3 and 8 of a 10-cell ring, the robot
    moves one cell per step and sees door/no door with 75 % reliability."""
    n = 10
    doors = np.zeros(n, dtype=bool)
    doors[[0, 3, 8]] = True
    T = circular_motion_model(n, {0: 0.1, 1: 0.8, 2: 0.1})
    belief = np.full(n, 1 / n)
    true_cell = 2
    for step in range(8):
        if step:
            true_cell = (true_cell + 1) % n
            belief = histogram_predict(belief, T)
        sees_door = doors[true_cell]
        belief = histogram_update(belief, np.where(doors == sees_door, 0.75, 0.25))
    assert int(np.argmax(belief)) == true_cell
    assert belief.sum() == pytest.approx(1.0, abs=1e-14)


# --------------------------------------------------------------------------------------
# validation: every error names its argument
# --------------------------------------------------------------------------------------

GOOD_T = circular_motion_model(3, {1: 1.0})

CASES = [
    (lambda: normalise([0.0, 0.0]), r"belief must have a positive sum"),
    (lambda: normalise([1.0, -0.5]), r"belief must be non-negative"),
    (lambda: normalise([[0.5, 0.5]]), r"belief must be a 1-D vector of shape \(n,\)"),
    (lambda: normalise([]), r"belief must not be empty"),
    (lambda: histogram_update([0.5, 0.6], [1.0, 1.0]), r"belief must sum to 1"),
    (lambda: histogram_update([1.5, -0.5], [1.0, 1.0]), r"belief must be non-negative"),
    (lambda: histogram_update([[0.5, 0.5]], [1.0, 1.0]), r"belief must be a 1-D vector"),
    (lambda: histogram_update([np.nan, 1.0], [1.0, 1.0]), r"belief must be finite"),
    (lambda: histogram_update([0.5, 0.5], [1.0, 1.0, 1.0]), r"likelihood must have shape \(2,\)"),
    (lambda: histogram_update([0.5, 0.5], [1.0, -1.0]), r"likelihood must be non-negative"),
    (lambda: histogram_update([0.5, 0.5], [1.0, np.inf]), r"likelihood must be finite"),
    (lambda: histogram_predict([0.5, 0.6, 0.0], GOOD_T), r"belief must sum to 1"),
    (lambda: histogram_predict([0.5, 0.5], GOOD_T), r"transition must have shape \(2, 2\)"),
    (lambda: histogram_predict([1.0, 0.0, 0.0], GOOD_T.T * 0.5),
     r"transition columns must sum to 1.*column 0"),
    (lambda: histogram_predict([1.0, 0.0, 0.0], np.array([[1.5, 0, 0], [-0.5, 1, 0], [0, 0, 1]])),
     r"transition must be non-negative"),
    (lambda: histogram_predict([1.0, 0.0, 0.0], np.full((3, 3), np.nan)),
     r"transition must be finite"),
    (lambda: circular_motion_model(0, {0: 1.0}), r"n must be a positive integer"),
    (lambda: circular_motion_model(2.5, {0: 1.0}), r"n must be a positive integer"),
    (lambda: circular_motion_model(3, {}), r"step_probs must be a non-empty dict"),
    (lambda: circular_motion_model(3, [0.5, 0.5]), r"step_probs must be a non-empty dict"),
    (lambda: circular_motion_model(3, {0: 0.5, 1: 0.4}), r"step_probs probabilities must sum to 1"),
    (lambda: circular_motion_model(3, {0: 1.5, 1: -0.5}), r"step_probs\[1\] must be a finite non-negative number"),
    (lambda: circular_motion_model(3, {0.5: 1.0}), r"step_probs keys must be integer"),
]


@pytest.mark.parametrize("call,match", CASES, ids=[c[1][:40] for c in CASES])
def test_validation_errors_name_the_argument(call, match):
    with pytest.raises(ValueError, match=match):
        call()
