"""Checks for chapter 01: the histogram (discrete Bayes) filter on a circular corridor.

Every check runs the learner's function on several seeded cases chosen so that the mistakes
learners make give different numbers (a transposed transition matrix, a sum over the wrong
axis, a likelihood that ignores z, a recursion that restarts from the first belief, ...),
and names the mistake when the learner's result matches one of them. The reference values
and the wrong values are computed once per process (``functools.cache``): a check's run
time is the learner's calls and the comparisons.

Which listed mistake explains a learner's results is asked of :func:`harness.known_mistake`:
the one that reproduces every case, else the first that reproduces the first wrong case. Hints
come in tiers (:mod:`kalman_course.checks.hints`): the concept, the mistake and the lecture
section first, the formula at tier 2.

Tolerances: every quantity here is a product, sum or quotient of a few dozen numbers of
order 1, so any correct formulation (a loop, ``einsum``, the log domain, the evidence as a
dot product) agrees with the reference to ~1e-15; the default ``rtol=1e-7, atol=1e-9`` of
:func:`expect_close` leaves eight orders of margin on that side, while every listed mistake
differs from the reference by more than 1e-3 on some case.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every family is drawn anew: the
likelihood's maps (two lengths, never 20, so that the global ``CORRIDOR`` still shows by its
length; the short one with more doors than walls) and its p_correct values (one above 0.8, one
in 0.56–0.7, never 0.5); the update's map, door likelihood, peaked priors, large random
likelihoods and ruled-out cells, at other lengths; the prediction's circular models (a forward
one, one that also steps back and jumps) on another corridor length and a column-stochastic
matrix of another size, each redrawn until it is well conditioned; the recursion's runs (the
corridor from a uniform belief, and another 20-cell map from a peaked one) with other seeds,
lengths, p_correct values and motion models, redrawn until every listed mistake is off by more
than 1e-3; and the motion models' corridor lengths, offsets and probabilities, the last with
three offsets equal modulo n.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course.filters import bayes
from kalman_course.chapters.corridor import CORRIDOR, corridor_scenario, scenario as _scenario
from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.checks import hints
from kalman_course.checks.harness import (CheckFailed, as_array, call, check, expect_close, expect_shape,
                                          known_mistake)

#: Another 20-cell map with the doors elsewhere: a run that reads the global ``CORRIDOR``
#: instead of its ``world`` argument gives other beliefs on it.
OTHER_WORLD = np.array([0, 0, 1, 0, 1, 1, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 1, 0, 0, 0])

#: A 13-cell map (more doors than walls): a likelihood built with a fixed length of 20 fails.
SHORT_WORLD = np.array([1, 0, 1, 1, 0, 1, 1, 0, 1, 0, 0, 1, 1])


def door_likelihood(world, z, p_correct):
    """Reference p(z | x = i): ``p_correct`` where the map agrees with ``z``, else 1 − p_correct."""
    return np.where(np.asarray(world) == z, p_correct, 1.0 - p_correct)


def _beliefs(n: int, seed: int, count: int) -> list[np.ndarray]:
    """Random, peaked probability vectors (a few cells carry most of the mass); drawn anew
    under a run seed (``seed`` keeps the call sites' streams apart)."""
    rng = inputs.rng("bayes.beliefs", seed)
    return [bayes.normalise(rng.gamma(0.5, size=n) + 1e-3) for _ in range(count)]


def _same(a, b) -> bool:
    """True when two learner results are the same array (the same deterministic code run on
    arguments it ignores gives bit-identical results)."""
    try:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):                 # not numeric: compared later, with a message
        return False
    return a.shape == b.shape and np.array_equal(a, b)


def _results(fn, cases, arguments) -> list:
    """The learner's result on every case, ``arguments(case)`` being the call's arguments; a
    call that raised leaves its :class:`CheckFailed` in its place, raised when the check
    reaches that case (so the messages come in the cases' order, as with one call at a time).
    """
    out = []
    for case in cases:
        try:
            out.append(call(fn, *arguments(case)))
        except CheckFailed as exc:
            out.append(exc)
    return out


def _result(got):
    """A learner's result from :func:`_results`, raising the failure stored in its place."""
    if isinstance(got, CheckFailed):
        raise got
    return got


def _agrees(got, wrong, rtol: float = 1e-7, atol: float = 1e-9) -> bool:
    """Whether a learner's result is a known mistake's value (False for a value that could
    not be computed, a result that is not numeric, or one of another shape)."""
    if wrong is None or isinstance(got, CheckFailed):
        return False
    try:
        got, wrong = np.asarray(got, dtype=float), np.asarray(wrong, dtype=float)
    except (TypeError, ValueError):
        return False
    return got.shape == wrong.shape and bool(np.allclose(got, wrong, rtol=rtol, atol=atol))


def _expect(got: list, k: int, expected, what: str, cases, mistakes, hint: str, **tolerances) -> np.ndarray:
    """Fail unless the learner's result on case ``k`` (``got[k]``) matches ``expected``.

    When it does not, the hint is the one of the listed mistake that reproduces the learner's
    results on every case, else of the first that reproduces case ``k``
    (:func:`harness.known_mistake`); the wrong values are built only then (most learners'
    results are right, and building every wrong value on every call would double the
    check's run time).

    Parameters
    ----------
    got : list
        The learner's results on every case of the check (:func:`_results`).
    k : int
        The case compared now.
    expected : array_like
        The reference on case ``k``.
    what : str
        The quantity, as the message names it.
    cases : sequence
        The check's cases, as the mistakes' formulas take them.
    mistakes : iterable of (callable, str)
        ``(formula, hint)``: ``formula(case)`` is the mistake's value on a case.
    hint : str
        The hint when no listed mistake explains the result.
    """
    rtol, atol = tolerances.get("rtol", 1e-7), tolerances.get("atol", 1e-9)
    arr = expect_shape(_result(got[k]), np.shape(expected), what)
    if np.allclose(arr, expected, rtol=rtol, atol=atol):
        return arr
    why = known_mistake(got, cases, mistakes, lambda g, w, _: _agrees(g, w, rtol, atol), case=k)
    if why is not None:
        raise CheckFailed(f"{what} is wrong. Hint: {why}")
    return expect_close(arr, expected, what, hint=hint, rtol=rtol, atol=atol)


# ---------------------------------------------------------------------------------------
# drawing cases under a run seed
# ---------------------------------------------------------------------------------------

def _drawn_world(rng: np.random.Generator, n: int, more_doors: bool = False) -> np.ndarray:
    """A drawn n-cell map with at least two doors and two walls (so that z = 0 and z = 1 give
    different likelihoods), with more doors than walls if ``more_doors``."""
    while True:
        world = (rng.random(n) < rng.uniform(0.55, 0.8) if more_doors
                 else rng.random(n) < rng.uniform(0.3, 0.6)).astype(int)
        doors = int(world.sum())
        if 2 <= doors <= n - 2 and (doors > n - doors or not more_doors):
            return world


def _drawn_p(rng: np.random.Generator, low: float, high: float) -> float:
    """A drawn p_correct, rounded to three decimals so that a message quotes it exactly."""
    return round(float(rng.uniform(low, high)), 3)


def _drawn_length(rng: np.random.Generator, low: int, high: int, avoid=()) -> int:
    """A drawn number of cells in [low, high], none of ``avoid``."""
    while True:
        n = int(rng.integers(low, high + 1))
        if n not in avoid:
            return n


def _drawn_step_probs(rng: np.random.Generator, offsets) -> dict:
    """{offset: probability} over ``offsets``, each probability at least 0.05 and below 0.85
    (a near-certain step makes the model nearly a shift, and a shift of the belief nearly
    right), in thousandths so that a message quotes them exactly; plain Python numbers (they
    are printed in messages)."""
    while True:
        thousandths = rng.multinomial(1000, rng.dirichlet(np.full(len(offsets), 2.0)))
        if thousandths.min() >= 50 and thousandths.max() < 850:
            return {int(o): int(k) / 1000 for o, k in zip(offsets, thousandths)}


def _differs(want: np.ndarray, wrong, margin: float = 1e-3) -> bool:
    """Whether a listed mistake's value is off the reference by more than ``margin`` somewhere
    (a drawn case where a mistake agrees with the reference is redrawn)."""
    wrong = np.asarray(wrong, dtype=float)
    return wrong.shape != want.shape or not np.allclose(wrong, want, rtol=0.0, atol=margin)


# ---------------------------------------------------------------------------------------
# the sensor model
# ---------------------------------------------------------------------------------------

#: (world, p_correct) pairs: two map lengths, and p_correct values far from 0.5 and from
#: each other (at 0.5 a swapped likelihood would be right; a fixed p would match only one).
_LIKELIHOOD_CASES = ((CORRIDOR, 0.9), (CORRIDOR, 0.65), (SHORT_WORLD, 0.8))


@functools.cache
def _likelihood_cases():
    """The (world, p_correct) pairs of the likelihood check: :data:`_LIKELIHOOD_CASES`, or
    drawn under a run seed in their roles (one map for the first two, with a p_correct above
    0.8 and one in 0.56–0.7; a shorter map with more doors than walls). No drawn map has 20
    cells: a likelihood built on the global CORRIDOR then shows by its length."""
    def draw(rng):
        n = _drawn_length(rng, 12, 40, avoid={len(CORRIDOR)})
        short = _drawn_length(rng, 5, 17, avoid={n, len(CORRIDOR)})
        world = _drawn_world(rng, n)
        return ((world, _drawn_p(rng, 0.8, 0.97)), (world, _drawn_p(rng, 0.56, 0.7)),
                (_drawn_world(rng, short, more_doors=True), _drawn_p(rng, 0.6, 0.95)))
    return inputs.fixed_or_drawn(_LIKELIHOOD_CASES, draw, "bayes.likelihood")


@functools.cache
def _door(k: int, z: int) -> np.ndarray:
    """The reference likelihood of reading ``z`` in case ``k`` of :func:`_likelihood_cases`."""
    world, p = _likelihood_cases()[k]
    return door_likelihood(world, z, p)


def _only_zeros_and_ones(value) -> bool:
    """Whether a learner's result holds only 0 and 1 (a perfect sensor, which has its own hint)."""
    try:
        return bool(np.all(np.isin(np.asarray(value, dtype=float), (0.0, 1.0))))
    except (TypeError, ValueError):
        return False


#: The likelihood's known mistakes: (formula of a case (world, z, p, want), hint).
_LIKELIHOOD_MISTAKES = (
    (lambda c: door_likelihood(c[0], 1 - c[1], c[2]),
     "the values are swapped: the sensor is right with probability p_correct, so the likely cells "
     "are those whose map shows what was sensed (lecture 01 §5): "
     + hints.formula("p(z | x = i) is p_correct where world[i] == z and 1 - p_correct elsewhere")),
    (lambda c: np.where(c[0] == c[1], 1.0, 0.0),
     "a real sensor errs: use p_correct and 1 - p_correct, not 1 and 0 (lecture 01 §5)"),
    (lambda c: np.where(c[0] == c[1], c[2], 0.0),
     "a cell whose map disagrees with z is not impossible: the sensor errs with "
     "probability 1 - p_correct, so give it 1 - p_correct, not 0 (lecture 01 §5)"),
    (lambda c: c[3] / c[3].sum(),
     "do not normalise the likelihood: p(z | x = i) is a function of the cell i, not a "
     "distribution over the cells (Bayes' rule normalises the posterior, lecture 01 §2)"),
)


@check
def check_door_likelihood(sensor_likelihood):
    """The learner's ``sensor_likelihood(world, z, p_correct)`` builds p(z | x) for every cell."""
    cases = [(world, z, p, _door(k, z)) for k, (world, p) in enumerate(_likelihood_cases()) for z in (0, 1)]
    results = _results(sensor_likelihood, cases, lambda c: c[:3])
    got = {(k // 2, c[1]): _result(r) for k, (c, r) in enumerate(zip(cases, results))}
    pairs = _likelihood_cases()
    # Arguments the result does not depend on: compared between calls, so that any fixed
    # value the learner wrote in (a p of 0.9, the comparison world == 1) is caught.
    for k, (world, p) in enumerate(pairs):
        if _same(got[k, 0], got[k, 1]):
            raise CheckFailed(f"your likelihood is the same for z=0 and z=1 (p_correct={p}): it must "
                              "depend on z. It is p(z | x = i) for the reading z that was actually "
                              "received: after a 'wall' reading the wall cells are the likely ones, "
                              "after a 'door' reading the door cells (lecture 01 §5): "
                              + hints.formula("compare the map with z, not with a door"))
    # the self-check names a fixed p_correct once its first case (p = 0.9, where a fixed 0.9
    # is right) has been compared, so that a fixed 1/0 sensor gets its own hint first; drawn
    # p_correct values are no number a learner wrote in, so a graded run names it at once
    # (unless the values are all 0 and 1: the perfect sensor's hint comes first)
    p_first = 0 if inputs.drawing() and not _only_zeros_and_ones(got[0, 1]) else 1
    for index, (world, z, p, want) in enumerate(cases):
        k = index // 2
        if z == 0 and k == p_first and _same(got[0, 1], got[1, 1]):
            raise CheckFailed(f"your likelihood is the same for p_correct={pairs[0][1]} and "
                              f"p_correct={pairs[1][1]}: use the argument p_correct, not a fixed number")
        what = f"likelihood for z={z}, p_correct={p} on a {len(world)}-cell world"
        arr = as_array(got[k, z], what)
        if arr.ndim == 0 or arr.shape == (1,):
            raise CheckFailed(f"{what} is a single number: p(z | x = i) has one entry per cell "
                              f"i, shape ({len(world)},) (compare the whole array world == z)")
        if arr.ndim == 1 and arr.shape != want.shape:
            raise CheckFailed(f"{what} has {arr.size} entries, expected one per cell of world "
                              f"({len(world)}): take the length from the world argument")
        if arr.shape == want.shape and np.any(arr < 0):
            raise CheckFailed(f"{what} has negative entries: a probability lies in [0, 1]; "
                              "the sensor errs with probability 1 - p_correct (not p_correct - 1)")
        _expect(results, index, want, what, cases, _LIKELIHOOD_MISTAKES,
                hint="the likelihood is how probable the reading z is in each cell, given the map "
                     "and how often the sensor is right (lecture 01 §5): "
                     + hints.formula("p(z | x = i) = p_correct if world[i] == z else 1 - p_correct"))


# ---------------------------------------------------------------------------------------
# the update
# ---------------------------------------------------------------------------------------

@functools.cache
def _update_cases():
    """(prior, likelihood) pairs: door likelihoods on the corridor, random positive
    likelihoods larger than 1 (densities need not be ≤ 1), one with impossible cells, and
    two lengths. No prior is uniform, so "prior left out" shows.

    Under a run seed: another map of 12–40 cells with a drawn p_correct for the door
    likelihoods, a short length of 5–11, the large likelihoods' scale drawn in 10–100 and the
    two ruled-out cells drawn."""
    rng = inputs.rng("bayes.update", 31)
    n, short, world, p, scale, ruled_out = len(CORRIDOR), 7, CORRIDOR, 0.8, 40.0, [1, 4]
    if inputs.drawing():
        n, short = _drawn_length(rng, 12, 40), _drawn_length(rng, 5, 11)
        world, p = _drawn_world(rng, n), _drawn_p(rng, 0.6, 0.95)
        scale = float(inputs.log_uniform(rng, 10.0, 100.0))
        ruled_out = list(rng.choice(short, 2, replace=False))
    priors = _beliefs(n, seed=1, count=3) + _beliefs(short, seed=5, count=2)
    likelihoods = [door_likelihood(world, 1, p), door_likelihood(world, 0, p),
                   scale * rng.gamma(2.0, size=n), rng.random(short) + 0.05, rng.random(short)]
    likelihoods[-1][ruled_out] = 0.0                # cells the measurement rules out
    return [(p, lk, bayes.histogram_update(p, lk)) for p, lk in zip(priors, likelihoods)]


#: The update's known mistakes: (formula of a case (prior, likelihood, want), hint).
_UPDATE_MISTAKES = (
    (lambda c: c[0],
     "the posterior equals the prior: the measurement was not used (the likelihood is "
     "missing). Bayes' rule weighs each cell's prior by how well that cell explains the "
     "reading, then normalises (lecture 01 §2)"),
    (lambda c: bayes.normalise(c[0] + c[1]),
     "Bayes' rule multiplies prior and likelihood; it does not add them (lecture 01 §2)"),
    (lambda c: bayes.normalise(c[1]),
     "the prior is missing: Bayes' rule weighs the likelihood by the prior (lecture 01 §2): "
     + hints.formula("posterior ∝ likelihood × prior")),
    (lambda c: bayes.normalise(c[1] / c[0]),
     "you divided the likelihood by the prior: Bayes' rule multiplies them (lecture 01 §2)"),
    (lambda c: bayes.normalise(c[1] ** 2 * c[0]),
     "the likelihood is applied twice: one measurement multiplies the prior by its "
     "likelihood once (lecture 01 §2)"),
)


@check
def check_histogram_update(histogram_update):
    """The learner's ``histogram_update(belief, likelihood)`` applies Bayes' rule."""
    cases = _update_cases()
    results = _results(histogram_update, cases, lambda c: c[:2])
    for k, (prior, likelihood, want) in enumerate(cases):
        n = len(prior)
        got = as_array(_result(results[k]), "posterior")
        if got.ndim == 0:
            raise CheckFailed("the posterior is a single number: Bayes' rule weighs each cell on its "
                              "own, an element-wise product (np.dot or @ sums the products into the "
                              "evidence; lecture 01 §5): " + hints.formula("likelihood * belief"))
        got = expect_shape(got, (n,), "posterior")
        if not np.isclose(got.sum(), 1.0, atol=1e-9):
            proportional = np.allclose(got / got.sum(), want, rtol=1e-7, atol=1e-9) if got.sum() else False
            raise CheckFailed(
                f"the posterior sums to {got.sum():.4f}, not 1. Hint: divide likelihood × prior by "
                "the evidence p(z), the probability of the reading over all the cells (lecture 01 "
                "§2)" + (" (your values are proportional to the right ones: only the normaliser is "
                         "wrong)" if proportional else "")
                + ": " + hints.formula("p(z) = Σ_i p(z | x=i) p(x=i), its sum over the cells"))
        _expect(results, k, want, "posterior", cases, _UPDATE_MISTAKES,
                hint="Bayes' rule weighs each cell's prior by the likelihood of the reading and "
                     "normalises by the evidence (lecture 01 §2): "
                     + hints.formula("posterior = likelihood * belief / Σ(likelihood * belief)"))


# ---------------------------------------------------------------------------------------
# the prediction
# ---------------------------------------------------------------------------------------

#: The self-check's circular motion models (on the 20-cell corridor): one moving forward, one
#: that also steps back and jumps three cells.
_FORWARD, _BACKWARD = {0: 0.1, 1: 0.7, 2: 0.2}, {-1: 0.6, 0: 0.3, 3: 0.1}


def _well_conditioned(transition: np.ndarray) -> bool:
    """Whether a motion model is far from singular: the inverted-model mistake solves with it,
    and a circular model can have an eigenvalue near 0 (steps of 0 and 1 with equal
    probabilities on an even ring)."""
    return bool(np.linalg.cond(transition) < 1e3)


@functools.cache
def _predict_cases():
    """(belief, transition) pairs. The circular models are doubly stochastic, so a sum over
    the wrong axis gives back the belief and a transpose still sums to one; the random
    column-stochastic matrix (rows do not sum to one) makes both show differently.

    Under a run seed: a corridor of 12–40 cells, the forward model's probabilities and the
    other model's back step (1 or 2), jump (3–5) and probabilities drawn, and a general matrix
    of 5–11 cells; each model redrawn until it is well conditioned."""
    n, size, forward, backward = len(CORRIDOR), 7, _FORWARD, _BACKWARD
    rng = inputs.rng("bayes.predict", 41)
    if inputs.drawing():
        n, size = _drawn_length(rng, 12, 40), _drawn_length(rng, 5, 11)
        forward = _drawn_step_probs(rng, (0, 1, 2))
        backward = _drawn_step_probs(rng, (-int(rng.integers(1, 3)), 0, int(rng.integers(3, 6))))
    models = [bayes.circular_motion_model(n, forward), bayes.circular_motion_model(n, backward)]
    while inputs.drawing() and not all(_well_conditioned(T) for T in models):
        forward, backward = _drawn_step_probs(rng, tuple(forward)), _drawn_step_probs(rng, tuple(backward))
        models = [bayes.circular_motion_model(n, forward), bayes.circular_motion_model(n, backward)]
    general = rng.gamma(0.7, size=(size, size))
    general /= general.sum(axis=0)                  # columns sum to 1, rows do not
    while inputs.drawing() and not _well_conditioned(general):
        general = rng.gamma(0.7, size=(size, size))
        general /= general.sum(axis=0)
    pairs = [(b, models[0]) for b in _beliefs(n, seed=2, count=2)] + \
            [(_beliefs(n, seed=3, count=1)[0], models[1])] + \
            [(b, general) for b in _beliefs(size, seed=4, count=2)]
    return [(b, T, bayes.histogram_predict(b, T)) for b, T in pairs]


#: Where the lecture derives the prediction, and the product that gives it.
_TOTAL_PROBABILITY = "total probability over the cells the robot comes from (lecture 01 §4 and §5)"
_PREDICT_PRODUCT = hints.formula("transition @ belief")


def _transposed_prediction(case):
    """The prediction with the transition matrix transposed (the robot moving backwards)."""
    belief, transition, _ = case
    return transition.T @ belief


#: The prediction's known mistakes: (formula of a case (belief, transition, want), hint).
_PREDICT_MISTAKES = (
    (_transposed_prediction,
     "the transition matrix is transposed (the robot moves backwards): transition[i, j] = "
     "p(x_k = i | x_k-1 = j) is the probability of moving from cell j to cell i, so p(x_k = i) "
     "sums over the cells j the robot comes from, the columns of row i (belief @ transition, "
     f"transition.T @ belief and a sum over axis 0 sum over the rows; {_TOTAL_PROBABILITY})"),
    (lambda c: _transposed_prediction(c) / _transposed_prediction(c).sum(),
     "the transition matrix is transposed (then normalised): the prediction sums to 1 by itself "
     f"({_TOTAL_PROBABILITY})"),
    (lambda c: c[0],
     "the predicted belief equals the belief you started from: either the motion model was not "
     "applied, or the sum ran over the wrong axis (over i, axis 0: each column sums to 1, so "
     f"Σ_i transition[i, j] belief[j] = belief[j]); sum over j, {_TOTAL_PROBABILITY}: "
     + _PREDICT_PRODUCT),
    (lambda c: c[0] * c[1].sum(axis=1),
     f"the sum ran over the wrong axis: sum over j, the cell the robot comes from ({_TOTAL_PROBABILITY}): "
     + hints.formula("p(x_k = i) = Σ_j transition[i, j] belief[j], i.e. (transition * belief).sum(axis=1) "
                     "or transition @ belief")),
    (lambda c: c[1] @ c[1] @ c[0],
     "the motion model is applied twice: one prediction is one step of the motion model "
     f"({_TOTAL_PROBABILITY}): " + _PREDICT_PRODUCT),
    (lambda c: np.roll(c[0], 1),
     "you shifted the belief by one cell: the robot may also stay or overshoot; apply the whole "
     f"motion model ({_TOTAL_PROBABILITY}): " + _PREDICT_PRODUCT),
    (lambda c: np.roll(c[0], -1),
     f"you shifted the belief back by one cell: apply the motion model ({_TOTAL_PROBABILITY}): "
     + _PREDICT_PRODUCT),
    (lambda c: np.linalg.solve(c[1], c[0]),
     "you inverted the motion model (that runs it backwards in time): predict forwards "
     f"({_TOTAL_PROBABILITY}): " + _PREDICT_PRODUCT),
)


@check
def check_histogram_predict(histogram_predict):
    """The learner's ``histogram_predict(belief, transition)`` applies total probability."""
    cases = _predict_cases()
    results = _results(histogram_predict, cases, lambda c: c[:2])
    for k, (belief, transition, want) in enumerate(cases):
        n = len(belief)
        got = as_array(_result(results[k]), "predicted belief")
        if got.shape == (n, n):
            raise CheckFailed(f"the predicted belief is an ({n}, {n}) matrix: transition * belief "
                              "multiplies element-wise without summing over j, the cell the robot "
                              f"comes from ({_TOTAL_PROBABILITY}): " + hints.formula("use transition @ belief"))
        _expect(results, k, want, "predicted belief", cases, _PREDICT_MISTAKES,
                hint=f"the prediction is the law of {_TOTAL_PROBABILITY}: "
                     + hints.formula("p(x_k = i) = Σ_j p(x_k = i | x_k-1 = j) p(x_k-1 = j)"))
        if not np.isclose(got.sum(), 1.0, atol=1e-9):
            raise CheckFailed("the predicted belief does not sum to 1: total probability conserves mass")


# ---------------------------------------------------------------------------------------
# the recursion
# ---------------------------------------------------------------------------------------

def reference_histogram_filter(belief0, transition, world, measurements, p_correct):
    """Reference recursion: update at step 0, then predict and update at every later step."""
    beliefs, belief = [], np.asarray(belief0, dtype=float)
    for k, z in enumerate(measurements):
        if k > 0:
            belief = bayes.histogram_predict(belief, transition)
        belief = bayes.histogram_update(belief, door_likelihood(world, z, p_correct))
        beliefs.append(belief)
    return np.array(beliefs)


def _variant_filter(belief0, transition, world, measurements, p_correct, *, restart=False,
                    predict_first=False, no_predict=False, store_prior=False,
                    from_belief0=False) -> np.ndarray:
    """The recursion with one of the mistakes learners make (for the check's hints)."""
    beliefs, belief = [], np.asarray(belief0, dtype=float)
    for k, z in enumerate(measurements):
        start = belief0 if (restart or from_belief0) else belief
        if (k > 0 or predict_first) and not no_predict and not restart:
            start = bayes.histogram_predict(start, transition)
        if store_prior:
            beliefs.append(start)
        belief = bayes.histogram_update(start, door_likelihood(world, z, p_correct))
        if not store_prior:
            beliefs.append(belief)
    return np.array(beliefs)


@functools.cache
def _filter_cases():
    """Runs of the recursion, ``[(args, beliefs)]``: the notebook's corridor run from a
    uniform belief, and a run on another map with another p_correct, a motion model that also
    steps back, and a peaked initial belief (so that a learner who ignores world, p_correct
    or belief0 shows).

    Under a run seed both runs are drawn in these roles (:func:`_drawn_filter_case`)."""
    n = len(CORRIDOR)
    if inputs.drawing():
        rng = inputs.rng("bayes.filter", 7)
        cases = [_drawn_filter_case(rng, corridor=True), _drawn_filter_case(rng, corridor=False)]
    else:
        cases = []
        _, z, transition, p = corridor_scenario(7)
        cases.append((np.full(n, 1.0 / n), transition, CORRIDOR, z, p))
        _, z, transition, p = _scenario(OTHER_WORLD, 11, 10, 0.7, {-1: 0.1, 1: 0.6, 2: 0.3})
        cases.append((_beliefs(n, seed=12, count=1)[0], transition, OTHER_WORLD, z, p))
    return [(args, reference_histogram_filter(*args)) for args in cases]


def _drawn_filter_case(rng: np.random.Generator, corridor: bool):
    """The arguments of a drawn run: on the corridor from a uniform belief (the notebook's
    run, with another robot, 10–16 steps, a p_correct in 0.6–0.95 other than the notebook's
    0.85 and drawn probabilities of steps 0, 1, 2), or on a drawn 20-cell map (the global
    CORRIDOR's length, so that reading it gives beliefs of the right shape) from a peaked
    belief, 8–14 steps, steps −1, 1, 2. Redrawn until every listed mistake of the recursion is
    off by more than 1e-3 (a run whose readings never change hides the measurement-index
    mistakes, for instance)."""
    n = len(CORRIDOR)
    while True:
        seed = int(rng.integers(2**31))
        if corridor:
            world, steps, offsets = CORRIDOR, int(rng.integers(10, 17)), (0, 1, 2)
            belief0 = np.full(n, 1.0 / n)
        else:
            world, steps, offsets = _drawn_world(rng, n), int(rng.integers(8, 15)), (-1, 1, 2)
            while np.array_equal(world, CORRIDOR):
                world = _drawn_world(rng, n)
            belief0 = bayes.normalise(rng.gamma(0.5, size=n) + 1e-3)
        p = 0.85
        while p == 0.85:
            p = _drawn_p(rng, 0.6, 0.95)
        _, z, transition, p = _scenario(world, seed, steps, p, _drawn_step_probs(rng, offsets))
        args = (belief0, transition, world, z, p)
        if _separates(args, uniform_start=corridor):
            return args


def _separates(args, uniform_start: bool) -> bool:
    """Whether every listed mistake of the recursion is off the reference, and off every other
    mistake, by more than 1e-3 on the run ``args``.

    From a uniform belief a doubly stochastic model changes nothing, so there a prediction
    before the first reading agrees with the reference, and predicting from belief0 agrees
    with restarting from it (whose hint names both): the self-check's corridor run has the
    same two coincidences, and its second run separates them. The mistakes about the world
    and belief0 arguments are left out where the run's own arguments make them the
    reference (the corridor, a uniform belief0)."""
    want = reference_histogram_filter(*args)
    listed = _RECURSION_MISTAKES + tuple(m for m in _ARGUMENT_MISTAKES if m[2](args))
    mistakes = [np.asarray(formula((args, want)), dtype=float) for formula, *_ in listed]
    agreeing = ({3} if uniform_start else set())          # _variant_filter(predict_first=True)
    if any(_differs(want, wrong) == (k in agreeing) for k, wrong in enumerate(mistakes)):
        return False
    twins = ({(0, 1)} if uniform_start else set())        # restart, from_belief0
    return all(_differs(mistakes[j], mistakes[k]) or (j, k) in twins
               for j in range(len(mistakes)) for k in range(j + 1, len(mistakes)))


#: Where a recursion's hint points: the section that draws the loop.
_THE_LOOP = "the loop the filter runs, lecture 01 §5"

#: The recursion's known mistakes: (formula of a case (args, want), hint).
_RECURSION_MISTAKES = (
    (lambda c: _variant_filter(*c[0], restart=True),
     "each step restarts from belief0 and uses its own reading only: the filter neither "
     f"moves nor remembers ({_THE_LOOP}). "
     + hints.formula("Each step's prior is the previous posterior, moved by the motion model (no "
                     "motion before the first reading)")),
    (lambda c: _variant_filter(*c[0], from_belief0=True),
     f"each step predicts from belief0: predict from the previous posterior ({_THE_LOOP})"),
    (lambda c: _variant_filter(*c[0], no_predict=True),
     "the prediction step is missing: after the first step, predict with the motion model "
     f"before each update ({_THE_LOOP})"),
    (lambda c: _variant_filter(*c[0], predict_first=True),
     "there is a prediction before the first measurement: at step 0 the initial belief is "
     f"the prior, update it directly ({_THE_LOOP})"),
    (lambda c: _variant_filter(*c[0], store_prior=True),
     "you stored the prior (the predicted belief) of each step: store the posterior, after "
     f"the update ({_THE_LOOP})"),
    (lambda c: reference_histogram_filter(c[0][0], c[0][1].T, *c[0][2:]),
     "the motion model is transposed: the robot moves backwards (lecture 01 §5): "
     + hints.formula("predict with transition @ belief")),
    (lambda c: reference_histogram_filter(*c[0][:3], np.roll(c[0][3], 1), c[0][4]),
     "each update uses the previous step's measurement: the measurement index is off by "
     "one; update step k with measurements[k]"),
    (lambda c: reference_histogram_filter(*c[0][:3], np.full_like(c[0][3], c[0][3][0]), c[0][4]),
     "every update uses the first measurement: update step k with measurements[k]"),
    (lambda c: np.array([bayes.histogram_predict(b, c[0][1]) for b in c[1]]),
     "you stored the belief after the next prediction: store the posterior right after "
     f"the update ({_THE_LOOP})"),
    (lambda c: np.tile(c[1][-1], (len(c[0][3]), 1)),
     "every row holds the last posterior: one array was appended again and again and "
     "changed in place; append a new array (or a copy) at every step"),
    (lambda c: reference_histogram_filter(*c[0][:4], 1.0 - c[0][4]),
     "the likelihood is swapped: pass p_correct itself to the sensor model"),
)

#: Mistakes about the run's arguments: (formula, hint, whether a run's arguments can show it).
#: On the corridor a run that reads the global CORRIDOR is right, from a uniform belief0 one
#: that starts uniform.
_ARGUMENT_MISTAKES = (
    (lambda c: reference_histogram_filter(c[0][0], c[0][1], CORRIDOR, *c[0][3:]),
     "the sensor model used the global CORRIDOR: use the world argument",
     lambda args: args[2] is not CORRIDOR),
    (lambda c: reference_histogram_filter(np.full(len(c[0][0]), 1.0 / len(c[0][0])), *c[0][1:]),
     "the run starts from a uniform belief: start from the belief0 argument",
     lambda args: not np.allclose(args[0], args[0][0])),
)


@functools.cache
def _recursion_mistake(index: int, j: int) -> np.ndarray:
    """The beliefs of mistake ``j`` (of :data:`_RECURSION_MISTAKES`, then
    :data:`_ARGUMENT_MISTAKES`) on case ``index``, built only when a learner's run is wrong."""
    formula = (_RECURSION_MISTAKES + _ARGUMENT_MISTAKES)[j][0]
    return formula(_filter_cases()[index])


def _ignored_argument(run_histogram_filter, args, got) -> str | None:
    """The name of an argument the learner's run gives the same result without, or None."""
    belief0, transition, world, z, p = args
    probes = (("p_correct", (belief0, transition, world, z, 0.6 if p != 0.6 else 0.75)),
              ("transition", (belief0, np.eye(len(belief0)), world, z, p)))
    for name, probe in probes:
        try:
            other = call(run_histogram_filter, *probe)
        except CheckFailed:
            continue
        if _same(other, got):
            return name
    return None


@check(uses={"sensor_likelihood": "door_likelihood", "histogram_predict": "histogram_predict",
             "histogram_update": "histogram_update"})
def check_histogram_filter(run_histogram_filter):
    """The learner's whole recursion on seeded corridor runs matches the reference."""
    cases = _filter_cases()
    results = _results(run_histogram_filter, cases, lambda c: c[0])
    mistakes = [(j, m[1]) for j, m in enumerate(_RECURSION_MISTAKES + _ARGUMENT_MISTAKES)]
    for index, (args, want) in enumerate(cases):
        got = as_array(_result(results[index]), "beliefs")
        steps, n = want.shape
        if got.shape == (n,):
            raise CheckFailed(f"beliefs has shape {got.shape}: return every step's posterior, "
                              f"shape ({steps}, {n}), not only the last one")
        if got.ndim == 2 and got.shape[1] == n and got.shape[0] != steps:
            raise CheckFailed(f"beliefs has {got.shape[0]} rows for {steps} measurements: one "
                              "posterior per measurement (is the loop off by one?)")
        arr = expect_shape(got, want.shape, "beliefs")
        # rtol 1e-6 (as before): a dozen chained updates keep a correct run within ~1e-13
        # of the reference; the closest listed mistake is off by more than 1e-2
        if np.allclose(arr, want, rtol=1e-6, atol=1e-9):
            continue
        why = known_mistake(results, range(len(cases)), mistakes,
                            lambda g, w, _: _agrees(g, w, rtol=1e-6, atol=1e-9),
                            evaluate=lambda j, i: _recursion_mistake(i, j), case=index)
        if why is not None:
            raise CheckFailed(f"beliefs is wrong. Hint: {why}")
        ignored = _ignored_argument(run_histogram_filter, args, got)
        if ignored is not None:
            raise CheckFailed(f"beliefs differ from the reference, and your run gives the "
                              f"same beliefs whatever {ignored} is: use the {ignored} "
                              "argument, not a fixed value")
        expect_close(arr, want, "beliefs", rtol=1e-6, atol=1e-9,
                     hint=f"at each step after the first, predict from the previous posterior, then "
                          f"update ({_THE_LOOP})")


# ---------------------------------------------------------------------------------------
# the motion model (optional challenge)
# ---------------------------------------------------------------------------------------

#: (n, step_probs): the notebook's corridor; a model that also steps back and jumps three
#: cells; and one whose three offsets all land on the same cell (2 ≡ 7 ≡ −3 mod 5), so
#: that writing each probability instead of adding it loses mass.
_MOTION_CASES = ((20, {0: 0.1, 1: 0.8, 2: 0.1}),
                 (7, {-1: 0.2, 0: 0.3, 3: 0.5}),
                 (5, {2: 0.5, 7: 0.25, -3: 0.25}))


@functools.cache
def _motion_cases():
    """The (n, step_probs) of the motion-model check: :data:`_MOTION_CASES`, or drawn under a
    run seed in their roles: a corridor of 12–19 cells with steps 0, 1, 2 (fewer than the
    notebook's 20, so that a model of 20 hard-coded cells shows by its shape, not by an index
    error); a short one of 8–12 cells with a step back (1 or 2), a stay and a jump (3–5), all
    different modulo n; and one of 4–9 cells whose three offsets are b, b + n and b − n (all
    equal modulo n; 2b ≢ 0, so that the model is not its own transpose), with drawn
    probabilities."""
    def draw(rng):
        n0, n1, n2 = (_drawn_length(rng, 12, 19), _drawn_length(rng, 8, 12), _drawn_length(rng, 4, 9))
        back, jump = -int(rng.integers(1, 3)), int(rng.integers(3, 6))
        b = int(rng.integers(1, n2))
        while (2 * b) % n2 == 0:
            b = int(rng.integers(1, n2))
        return ((n0, _drawn_step_probs(rng, (0, 1, 2))),
                (n1, _drawn_step_probs(rng, (back, 0, jump))),
                (n2, _drawn_step_probs(rng, (b, b + n2, b - n2))))
    return inputs.fixed_or_drawn(_MOTION_CASES, draw, "bayes.motion")


def _unwrapped_model(n: int, step_probs: dict, direction: int) -> np.ndarray:
    """The corridor model without the wrap-around (a straight corridor whose robot falls off
    the end), stepping forward (``direction`` 1) or, transposed, backward (−1)."""
    return sum(prob * np.eye(n, k=-direction * offset) for offset, prob in step_probs.items())


def _overwritten_model(n: int, step_probs: dict) -> np.ndarray:
    """The corridor model with each probability written (=) instead of added (+=)."""
    transition = np.zeros((n, n))
    for offset, prob in step_probs.items():
        for j in range(n):
            transition[(j + offset) % n, j] = prob
    return transition


@check
def check_corridor_motion_model(circular_motion_model):
    """The learner's ``circular_motion_model(n, step_probs)`` builds the (n, n) transition matrix
    ``transition[i, j]`` = p(x_k = i | x_k-1 = j) of a circular corridor."""
    for n, step_probs in _motion_cases():
        want = bayes.circular_motion_model(n, step_probs)
        what = f"transition matrix for n = {n}, step_probs = {step_probs}"
        got = as_array(call(circular_motion_model, n, dict(step_probs)), what)
        if got.shape != (n, n):
            raise CheckFailed(f"{what} has shape {got.shape}, expected ({n}, {n}): one row and one "
                              "column per cell, n taken from the argument")
        if not np.allclose(got.sum(axis=0), 1.0, atol=1e-9):
            if any(np.allclose(got, _unwrapped_model(n, step_probs, d), atol=1e-12) for d in (1, -1)):
                raise CheckFailed(
                    f"{what}: some columns sum to less than 1, probability is lost at the end of "
                    "the corridor. Hint: the corridor is circular: a step past the last cell comes back "
                    "to cell 0 (and a step back from cell 0 lands on the last cell); wrap the "
                    "destination around")
            if np.allclose(got, _overwritten_model(n, step_probs), atol=1e-12):
                raise CheckFailed(
                    f"{what}: some columns sum to less than 1. Hint: offsets that land on the same cell "
                    "(here all of them, modulo n) are different ways of getting there: their "
                    "probabilities add up, the last one must not replace the others")
            raise CheckFailed(
                f"{what}: column sums {np.round(got.sum(axis=0), 4)}, expected all 1. Hint: column j is "
                "the distribution of where a robot in cell j ends up, so it sums to one (lecture 01 §5)")
        order = list(step_probs.values())
        expect_close(got, want, what, mistakes=[
            (want.T, "the model is transposed: your robot moves backwards. transition[i, j] is the "
                     "probability of going FROM cell j TO cell i (lecture 01 §5): "
                     + hints.formula("a step of +1 from cell j puts its probability in row j + 1 of "
                                     "column j")),
            (bayes.circular_motion_model(n, dict(enumerate(order))),
             "the offsets are the keys of step_probs (how many cells the robot moves), not the "
             "positions 0, 1, 2, ... of its probabilities"),
            (np.full((n, n), 1.0 / n), "a uniform matrix forgets the motion: each column must "
                                       "follow step_probs"),
        ], hint="column j is where a robot in cell j ends up, each offset of step_probs taking it "
                "that many cells round the ring (lecture 01 §5): "
                + hints.formula("transition[(j + offset) % n, j] += step_probs[offset]"))
