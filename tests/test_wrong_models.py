"""Chapter 01 (kalman_course.chapters.wrong_models): the histogram filter on a world it models wrongly."""

import numpy as np
import pytest

from kalman_course.chapters.wrong_models import CorridorModel, corridor_trials
from kalman_course.filters import bayes

DOORS = tuple(i in (1, 4, 5, 11, 15) for i in range(20))
STEPS = ((0, 0.1), (1, 0.8), (2, 0.1))
RIGHT = CorridorModel(DOORS, 0.9, 0.1, STEPS)


def test_one_run_is_the_filter_written_out():
    # the same draws, in the same order, through predict (from step 1) and update: a swapped order fails
    result = corridor_trials(RIGHT, RIGHT, [5], steps=6)
    rng = np.random.default_rng(5)
    T = bayes.circular_motion_model(20, dict(STEPS))
    p_door = np.where(DOORS, 0.9, 0.1)
    cell, belief = int(rng.integers(20)), np.full(20, 0.05)
    for k in range(6):
        if k:
            cell = int((cell + rng.choice([0, 1, 2], p=[0.1, 0.8, 0.1])) % 20)
            belief = T @ belief
        says = rng.random() < p_door[cell]
        belief = belief * (p_door if says else 1 - p_door)
        belief /= belief.sum()
    assert result.correct[0] == (np.argmax(belief) == cell)
    assert result.confidence[0] == pytest.approx(belief.max(), rel=1e-12)


def test_the_right_model_is_calibrated_and_wrong_ones_are_not():
    # with the right model the confidence is the probability of being right, so on average they agree
    seeds = range(300)
    right = corridor_trials(RIGHT, RIGHT, seeds)
    assert abs(right.accuracy - right.mean_confidence) < 3 * right.standard_error
    worse_sensor = corridor_trials(RIGHT, CorridorModel(DOORS, 0.7, 0.3, STEPS), seeds)
    assert worse_sensor.mean_confidence > worse_sensor.accuracy + 3 * worse_sensor.standard_error
    modest = corridor_trials(CorridorModel(DOORS, 0.7, 0.3, STEPS), RIGHT, seeds)
    assert modest.mean_confidence < modest.accuracy - 3 * modest.standard_error


@pytest.mark.parametrize("args, message", [
    ((DOORS, 1.0, 0.1, STEPS), "p_hit"),
    ((DOORS, 0.9, 0.0, STEPS), "p_false"),
    ((DOORS, 0.9, 0.1, ((1, 0.5), (2, 0.4))), "step_probs"),
    ((DOORS[:1], 0.9, 0.1, STEPS), "doors"),
])
def test_a_model_that_is_no_probability_model_is_refused(args, message):
    with pytest.raises(ValueError, match=message):
        CorridorModel(*args)


def test_trials_refuse_mismatched_worlds_and_empty_seeds():
    with pytest.raises(ValueError, match="same number of cells"):
        corridor_trials(RIGHT, CorridorModel(DOORS[:10], 0.9, 0.1, STEPS), [1])
    with pytest.raises(ValueError, match="seeds"):
        corridor_trials(RIGHT, RIGHT, [])
    with pytest.raises(ValueError, match="steps"):
        corridor_trials(RIGHT, RIGHT, [1], steps=0)
