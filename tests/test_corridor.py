"""Chapter 01's scenario builds the lecture's motion model without the exercise's function:
the two agree."""

import numpy as np
import pytest

from kalman_course.chapters import corridor
from kalman_course.filters import bayes


@pytest.mark.parametrize("n, step_probs", [(20, {0: 0.1, 1: 0.8, 2: 0.1}), (7, {-1: 0.2, 1: 0.5, 9: 0.3}),
                                           (5, {0: 1.0})])
def test_the_scenario_s_transition_is_the_circular_motion_model(n, step_probs):
    world = np.arange(n) % 2
    _, _, transition, _ = corridor.scenario(world, 3, 6, 0.8, step_probs)
    np.testing.assert_allclose(transition, bayes.circular_motion_model(n, step_probs), rtol=0, atol=1e-15)
