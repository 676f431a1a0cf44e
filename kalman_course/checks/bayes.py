"""Checks for chapter 01: the histogram (discrete Bayes) filter on a circular corridor."""

from __future__ import annotations

import numpy as np

from kalman_course.filters import bayes
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape

#: The corridor of chapter 01: 1 where a cell has a door, 0 where it is wall.
CORRIDOR = np.array([1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0])


def door_likelihood(world, z, p_correct):
    """Reference p(z | x = i): ``p_correct`` where the map agrees with ``z``, else 1 − p_correct."""
    return np.where(np.asarray(world) == z, p_correct, 1.0 - p_correct)


def _beliefs(n: int, seed: int, count: int) -> list[np.ndarray]:
    """Random, peaked probability vectors (a few cells carry most of the mass)."""
    rng = np.random.default_rng(seed)
    return [bayes.normalise(rng.gamma(0.5, size=n) + 1e-3) for _ in range(count)]


@check
def check_door_likelihood(sensor_likelihood):
    """The learner's ``sensor_likelihood(world, z, p_correct)`` builds p(z | x) for every cell."""
    for z in (0, 1):
        for p in (0.9, 0.7):
            got = call(sensor_likelihood, CORRIDOR, z, p)
            want = door_likelihood(CORRIDOR, z, p)
            expect_close(got, want, f"likelihood for z={z}, p_correct={p}", mistakes=[
                (door_likelihood(CORRIDOR, 1 - z, p),
                 "the values are swapped: p(z | x) is p_correct where the map shows what was sensed"),
                (np.where(CORRIDOR == z, 1.0, 0.0),
                 "a real sensor errs: use p_correct and 1 - p_correct, not 1 and 0"),
            ], hint="p(z | x = i) = p_correct if world[i] == z else 1 - p_correct")


@check
def check_histogram_update(histogram_update):
    """The learner's ``histogram_update(belief, likelihood)`` applies Bayes' rule."""
    n = len(CORRIDOR)
    for k, prior in enumerate(_beliefs(n, seed=1, count=4)):
        likelihood = door_likelihood(CORRIDOR, k % 2, 0.8)
        got = call(histogram_update, prior, likelihood)
        got = expect_shape(got, (n,), "posterior")
        if not np.isclose(got.sum(), 1.0, atol=1e-9):
            raise CheckFailed(f"the posterior sums to {got.sum():.4f}, not 1. Hint: divide prior × "
                              "likelihood by the evidence p(y) = Σ_i p(y | x=i) p(x=i)")
        expect_close(got, bayes.histogram_update(prior, likelihood), "posterior", mistakes=[
            (bayes.normalise(prior + likelihood), "Bayes' rule multiplies prior and likelihood; it does not add them"),
            (bayes.normalise(likelihood), "the prior is missing: posterior ∝ likelihood × prior"),
        ])


@check
def check_histogram_predict(histogram_predict):
    """The learner's ``histogram_predict(belief, transition)`` applies total probability."""
    n = len(CORRIDOR)
    # Asymmetric motion (mostly one step forward) so that a transposed matrix shows.
    transition = bayes.circular_motion_model(n, {0: 0.1, 1: 0.7, 2: 0.2})
    for belief in _beliefs(n, seed=2, count=4):
        got = call(histogram_predict, belief, transition)
        got = expect_shape(got, (n,), "predicted belief")
        expect_close(got, bayes.histogram_predict(belief, transition), "predicted belief", mistakes=[
            (transition.T @ belief, "transition[i, j] = p(x_k = i | x_k-1 = j): sum over j, "
                                    "i.e. transition @ belief, not transition.T @ belief"),
            (belief, "the belief did not move: prediction must apply the motion model"),
        ], hint="p(x_k = i) = Σ_j p(x_k = i | x_k-1 = j) p(x_k-1 = j)")
        if not np.isclose(got.sum(), 1.0, atol=1e-9):
            raise CheckFailed("the predicted belief does not sum to 1: total probability conserves mass")


def reference_histogram_filter(belief0, transition, world, measurements, p_correct):
    """Reference recursion: update at step 0, then predict and update at every later step."""
    beliefs, belief = [], np.asarray(belief0, dtype=float)
    for k, z in enumerate(measurements):
        if k > 0:
            belief = bayes.histogram_predict(belief, transition)
        belief = bayes.histogram_update(belief, door_likelihood(world, z, p_correct))
        beliefs.append(belief)
    return np.array(beliefs)


def corridor_scenario(seed: int = 7, steps: int = 12, p_correct: float = 0.85):
    """A robot moving around the corridor, with its true cells and noisy door readings."""
    rng = np.random.default_rng(seed)
    n = len(CORRIDOR)
    step_probs = {0: 0.1, 1: 0.8, 2: 0.1}
    offsets, probs = zip(*step_probs.items())
    cells = [int(rng.integers(n))]
    for _ in range(steps - 1):
        cells.append((cells[-1] + int(rng.choice(offsets, p=probs))) % n)
    cells = np.array(cells)
    z = np.where(rng.random(steps) < p_correct, CORRIDOR[cells], 1 - CORRIDOR[cells])
    return cells, z, bayes.circular_motion_model(n, step_probs), p_correct


@check
def check_histogram_filter(run_histogram_filter):
    """The learner's whole recursion on a seeded corridor run matches the reference."""
    n = len(CORRIDOR)
    for seed in (7, 11):
        cells, z, transition, p_correct = corridor_scenario(seed)
        belief0 = np.full(n, 1.0 / n)
        got = call(run_histogram_filter, belief0, transition, CORRIDOR, z, p_correct)
        want = reference_histogram_filter(belief0, transition, CORRIDOR, z, p_correct)
        got = expect_shape(got, want.shape, "beliefs")
        no_recursion = np.array([bayes.histogram_update(belief0, door_likelihood(CORRIDOR, zk, p_correct))
                                 for zk in z])
        expect_close(got, want, "beliefs", rtol=1e-6, atol=1e-9, mistakes=[
            (no_recursion, "each step restarts from belief0: the recursion must carry the "
                           "previous posterior forward"),
        ], hint="at each step after the first, predict from the previous posterior, then update")
