"""Checks for chapter 03: the linear Kalman filter, graded on KITTI GNSS excerpts.

The states the checks use come from KITTI ground truth (positions and velocities of the
car), and the whole-run check filters the excerpts' noisy 1 Hz GNSS positions; the
challenge's check (``gnss_kf_gaps``) filters them with some fixes removed. B is the
process-noise Jacobian (Q = B (σ_a² I) Bᵀ), G the observation Jacobian.

The cases are chosen so that the mistakes learners make change the result: noise levels
other than 1 and anisotropic, non-diagonal covariances (with σ = 1 a standard deviation
and a variance are the same number, and with R = I the products R R, √R, R⁻¹ and I all
equal R), time steps other than 1 s, and dense observation matrices of m < n rows (with
a position selector G and symmetric inputs, several transposes change nothing). Each
check's known mistakes are listed as wrong values with the hint that names them; the
list is walked only when the learner's value is wrong, so it costs nothing on a pass.

The CV model's check then sweeps the time step from 1 µs to 1000 s (:data:`CV_SWEEP`), σ_a
on both sides of 1, comparing each entry of Q relative to its block's size (the blocks differ
by T² in size), so that a cut-off or special case for very short or very long steps shows.

Hints come in tiers (:mod:`kalman_course.checks.hints`): the first names the concept, the
mistake where one is known and the lecture section; the formula is marked and shown at tier 2.
Which listed mistake explains a learner's whole run is asked of :func:`harness.known_mistake`
over every case of the run checks. Row 0 of the whole run, the belief at t[0], is the learner's
decision from what the first fix tells and what it does not (the exercise gives no matrix):
:func:`_initial_state_hint` names each wrong decision (a velocity variance near zero, σ for
σ², a zero or a discarded position variance, coupled blocks, a start velocity from the second
fix or of some direction).

Tolerances: the checks compare with ``expect_close``'s default rtol 1e-7 / atol 1e-9
unless a comment says otherwise. Every correct way to write the step functions (inverse
or solve, Joseph or short form, with or without a final symmetrisation) agrees with the
reference to ~1e-13 relative here, six orders below; every mistake in the catalogue
(``tests/mutants/ch03.py``) differs by more than 1e-4 relative.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every family is drawn anew, in
the same roles: the CV model's (T, σ_a), each still on its side of 1; other KITTI states,
other fixes and other dense covariances; the GNSS noise's three σ (one below 1, two above,
in a drawn order) and the rotation that makes R non-diagonal; the dense m = 2 < n = 4 update
cases and the dense prediction case (redrawn while cond(S) ≥ 1e3 or a listed mistake comes
within 1e-3 relative of the reference without being it); the prediction's (T, σ_a) settings;
and for the whole runs σ_a and σ_gnss (one below 1 and one above in each run, never the
self-check's pair) and a window of each excerpt's fixes (each end moved in by up to a fifth),
for the challenge also the missing fixes (two single dropouts and a 3–5 s outage at drawn
rows, and the last fix), each run redrawn until no listed mistake gives the reference's run.
"""

from __future__ import annotations

import functools
import itertools

import numpy as np

from kalman_course.filters import kf
from kalman_course import symbolic
from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.checks import hints
from kalman_course.checks.harness import (CheckFailed, as_array, call, check, expect_close, expect_shape,
                                          expect_symmetric, known_mistake, type_name, with_symmetrised)
from kalman_course.core import linalg
from kalman_course.chapters.gnss import truth_at
from kalman_course.data import load_kitti
from kalman_course.evaluation.metrics import rmse

#: Excerpts the KF checks run on, and the settings of the lecture's whole run.
EXCERPTS = ("cruise", "turns")
SIGMA_A = 1.0       # m/s², acceleration noise of the CV model
SIGMA_GNSS = 1.0    # m, per axis: the noise of the excerpts' noisy GNSS copy
SIGMA_V0 = 15.0     # m/s, initial velocity uncertainty: the car's speed is unknown at start

#: (excerpt, σ_a, σ_gnss) of the whole-run check: both noise levels ≠ 1 and on both sides
#: of 1, so that a standard deviation used for a variance (or σ_a not squared) shows.
RUN_CASES = (("cruise", 0.5, 1.6), ("turns", 2.0, 0.7))
#: Under a run seed, the ranges each run case's (σ_a, σ_gnss) is drawn from: in each run one
#: below 1 and one above, at least 20 % from 1, as in the self-check.
RUN_DRAWN = (((0.3, 0.8), (1.2, 2.5)), ((1.3, 3.0), (0.4, 0.8)))

#: (T, σ_a) of the CV-model check: T ≠ 1 (T, T², T³, T⁴ differ), σ_a ≠ 1 (σ ≠ σ²), each
#: on both sides of 1.
CV_CASES = ((0.1, 2.0), (0.5, 0.3), (2.0, 0.7))
#: Under a run seed, the ranges each CV case's (T, σ_a) is drawn from: every one keeps its
#: side of 1 and stays at least 20 % away from it.
CV_DRAWN = (((0.05, 0.3), (1.5, 3.0)), ((0.3, 0.8), (0.2, 0.5)), ((1.5, 3.0), (0.5, 0.8)))

#: Anisotropic GNSS noise (m): the vertical is worse than the horizontal, all ≠ 1.
GNSS_SIGMAS = np.array([0.5, 1.5, 3.0])

SHAPES_UPDATE = ("the shapes are x̌ (n,), P̌ (n, n), y (m,), G (m, n), R (m, m); then "
                 "S is (m, m), K is (n, m) and I − K G is (n, n). Multiply matrices "
                 "with @ (not *); S⁻¹ is a matrix inverse (np.linalg.solve or inv), not a "
                 "division; and check the order and the transposes (lecture 03 §3): "
                 + hints.formula("S = G P̌ Gᵀ + R, K = P̌ Gᵀ S⁻¹"))

#: The formulas the hints point to, shown at hint tier 2 (:mod:`kalman_course.checks.hints`).
Q_FORMULA = hints.formula("Q = B (σ_a² I) Bᵀ with B = [T²/2 I; T I]")
F_FORMULA = hints.formula("F = [[I, T I], [0, I]]")
PRIOR_FORMULA = hints.formula("P̌ = F P̂ Fᵀ + Q")
S_FORMULA = hints.formula("S = G P̌ Gᵀ + R")
GAIN_FORMULA = hints.formula("K = P̌ Gᵀ S⁻¹")
MEAN_FORMULA = hints.formula("x̂ = x̌ + K (y − G x̌)")
JOSEPH_FORMULA = hints.formula("Joseph form: P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ")


def _about(why: str, section: str, formula: str) -> str:
    """A hint at its two tiers: ``why`` (the concept or the mistake) and where the lecture
    derives it, then the marked ``formula`` (shown at tier 2)."""
    return f"{why} (lecture 03 §{section}): {formula}"


def _drawn(rng: np.random.Generator, low: float, high: float) -> float:
    """A drawn noise level or time step, log-uniform in [low, high] and rounded to three
    decimals (a message quotes it exactly)."""
    return round(float(inputs.log_uniform(rng, low, high)), 3)


def _relative_near_miss(expected, wrong, margin: float = 1e-3) -> bool:
    """Whether a listed mistake comes within ``margin`` relative (max norm) of the reference
    without being it (to 1e-10, an identity of the case's structure, such as R R = R * R for
    a diagonal R): a drawn case where that happens is drawn again."""
    expected, wrong = np.asarray(expected, dtype=float), np.asarray(wrong, dtype=float)
    if wrong.shape != expected.shape:
        return False
    distance = np.max(np.abs(wrong - expected)) / np.max(np.abs(expected))
    return bool(1e-10 < distance < margin)


@functools.lru_cache(maxsize=None)
def _cv_cases():
    """The (T, σ_a) of the CV-model check: :data:`CV_CASES`, or drawn from :data:`CV_DRAWN`."""
    return inputs.fixed_or_drawn(
        CV_CASES, lambda rng: tuple((_drawn(rng, *T), _drawn(rng, *sigma)) for T, sigma in CV_DRAWN),
        "kf.cv")


#: The sweep of the CV model's time step beyond the three cases' 0.1–2 s: from a step far shorter
#: than any sensor's (1 µs, where T⁴/4 is 2.5e-25) to one far longer than the exercise's 1 s
#: fixes (1000 s), three decades apart or more, with σ_a alternating below and above 1, so that
#: a cut-off or a special case a learner writes for very short or very long steps shows. Four
#: steps: each costs a learner call, and the check's run time stays within 1.5× of the three
#: cases' alone.
CV_SWEEP = ((1e-6, 0.05), (1e-3, 3.0), (30.0, 0.4), (1000.0, 12.0))


@functools.lru_cache(maxsize=None)
def _cv_sweep():
    """The (T, σ_a) of the sweep: :data:`CV_SWEEP`, or under a run seed each step drawn
    log-uniform within a factor 3 of the fixed one (three significant digits) with σ_a drawn on
    the same side of 1 as the fixed sweep's, again alternating."""
    def draw(rng):
        out = []
        for T, sigma in CV_SWEEP:
            step = float(f"{float(inputs.log_uniform(rng, T / 3.0, T * 3.0)):.3g}")
            level = _drawn(rng, 0.05, 0.9) if sigma < 1.0 else _drawn(rng, 1.2, 20.0)
            out.append((step, level))
        return tuple(out)
    return inputs.fixed_or_drawn(CV_SWEEP, draw, "kf.cv.sweep")


def _scaled_q(Q, T: float, sigma_a: float, dim: int = 3) -> np.ndarray:
    """Q divided entry by entry by the size of its block, σ_a² (T²/2 or T)(T²/2 or T): the
    blocks of Q differ by T² in size (10⁻¹² at T = 1 µs), so an absolute tolerance would hide
    every short step's position block; scaled, a correct Q is [[I, I], [I, I]] to round-off at
    every T."""
    scale = sigma_a * np.r_[np.full(dim, 0.5 * T**2), np.full(dim, T)]
    return np.asarray(Q, dtype=float) / np.outer(scale, scale)


def cv_matrices_reference(T, sigma_a, dim=3):
    """(F, Q) of the constant-velocity model, blocked state [p (dim), v (dim)]."""
    return symbolic.cv_transition(T, dim), symbolic.cv_process_noise(T, sigma_a, dim)


@functools.lru_cache(maxsize=None)
def _cv_reference(T: float, sigma_a: float):
    """:func:`cv_matrices_reference` of a check case, computed once (read-only)."""
    F, Q = cv_matrices_reference(T, sigma_a)
    F.flags.writeable = Q.flags.writeable = False
    return F, Q


def position_observation(dim=3):
    """G that picks the position out of the blocked CV state."""
    return np.hstack([np.eye(dim), np.zeros((dim, dim))])


def _spd(rng: np.random.Generator, n: int) -> np.ndarray:
    """A random, dense, exactly symmetric positive definite (n, n) matrix."""
    A = rng.normal(size=(n, n))
    return linalg.symmetrise(A @ A.T + 0.1 * np.eye(n))


@functools.lru_cache(maxsize=None)
def _kitti_states(name: str, count: int = 4, seed: int = 0):
    """A few CV states [p, v] from KITTI ground truth with random dense SPD covariances
    (other states and covariances under a run seed)."""
    truth = load_kitti(name).truth
    rng = inputs.rng(f"kf.states.{name}", seed)
    idx = rng.choice(len(truth.t), size=count, replace=False)
    return tuple((np.r_[truth.position[i], truth.velocity[i]], _spd(rng, 6)) for i in idx)


#: The rotation angles (rad) that turn the diagonal GNSS R into a non-diagonal one.
GNSS_ANGLES = (0.6, 0.6)


def _gnss_noise(j: int, sigmas=GNSS_SIGMAS, angles=GNSS_ANGLES) -> np.ndarray:
    """The R of GNSS case ``j``: diagonal anisotropic for even j (first, so that an
    element-wise √R stays finite), rotated and non-diagonal for odd j (about z by the first
    angle, about x by the second)."""
    R = np.diag(np.square(sigmas))
    if j % 2 == 0:
        return R
    (c, s), (c2, s2) = ((np.cos(a), np.sin(a)) for a in angles)
    Rot = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]) @ \
        np.array([[1.0, 0.0, 0.0], [0.0, c2, -s2], [0.0, s2, c2]])
    return linalg.symmetrise(Rot @ R @ Rot.T)


def _drawn_gnss_noise(rng: np.random.Generator):
    """(σ, angles) of the GNSS noise under a run seed: one σ in 0.3–0.8 m and two in 1.2–2
    and 2.5–4 m (all ≠ 1, anisotropic), in a drawn order; rotations of 0.3–1.2 rad either way."""
    sigmas = rng.permutation([_drawn(rng, 0.3, 0.8), _drawn(rng, 1.2, 2.0), _drawn(rng, 2.5, 4.0)])
    angles = tuple(float(a) for a in rng.choice([-1.0, 1.0], 2) * rng.uniform(0.3, 1.2, 2))
    return sigmas, angles


def _dense_update_case(rng: np.random.Generator):
    """(x̌, P̌, y, G, R) with m = 2 < n = 4, everything dense."""
    n, m = 4, 2
    return (rng.normal(size=n) * 3.0, _spd(rng, n), rng.normal(size=m) * 3.0,
            rng.normal(size=(m, n)), 0.7 * _spd(rng, m))


def _update_separated(case, ref) -> bool:
    """Whether a drawn update case keeps its mistakes apart: cond(S) < 1e3 (correct variants
    agree to ~1e-13) and no listed S, gain or posterior is a near miss of the reference."""
    x_check, P_check, y, G, R = case
    if np.linalg.cond(ref.S) >= 1e3:
        return False
    families = ((ref.S, _s_mistakes(P_check, G, R)), (ref.K, _k_mistakes(P_check, G, R, ref.S, ref.K)),
                (ref.x_hat, _posterior_mean_mistakes(x_check, y, G, ref.K, ref.innovation)),
                (ref.P_hat, _posterior_cov_mistakes(P_check, G, R, ref.S, ref.K)))
    return not any(_relative_near_miss(want, wrong) for want, mistakes in families for wrong, _ in mistakes)


@functools.lru_cache(maxsize=None)
def _update_cases():
    """(x̌, P̌, y, G, R) of the gain and update checks, with the reference update.

    KITTI states with the noisy GNSS fixes and anisotropic R (diagonal, then rotated),
    then two dense cases with m = 2 < n = 4 and a dense G, where K (n, m) and its
    transpose differ in shape, G P̌ Gᵀ is not a block of P̌, and every transpose matters.
    Under a run seed: other states, fixes (drawn rows), σ and rotations of R
    (:func:`_drawn_gnss_noise`), and dense cases drawn until :func:`_update_separated`.
    """
    G = position_observation()
    cases = []
    for name in EXCERPTS:
        fixes = load_kitti(name).gnss.observations()
        rng = inputs.rng(f"kf.update.{name}", 0)
        rows, sigmas, angles = [j * 5 for j in range(4)], GNSS_SIGMAS, GNSS_ANGLES
        if inputs.drawing():
            rows = rng.choice(len(fixes.t), size=4, replace=False)
            sigmas, angles = _drawn_gnss_noise(rng)
        for j, (x_check, P_check) in enumerate(_kitti_states(name)):
            cases.append((x_check, P_check, fixes.position[rows[j]], G, _gnss_noise(j, sigmas, angles)))
    rng = inputs.rng("kf.update.dense", 3)
    for _ in range(2):
        case = _dense_update_case(rng)
        while inputs.drawing() and not _update_separated(case, kf.kf_update(*case, joseph=True)):
            case = _dense_update_case(rng)
        cases.append(case)
    return tuple((case, kf.kf_update(*case, joseph=True)) for case in cases)


def _pair(result, fn_name: str, names: tuple[str, str], shapes=None):
    """The two results of a learner function that returns a pair (tuple or list).

    ``shapes``, the expected shapes of the two, lets the message name a swapped order.
    """
    if not isinstance(result, (tuple, list)) or len(result) != 2:
        raise CheckFailed(f"{fn_name} must return a tuple ({names[0]}, {names[1]}), got "
                          f"{type_name(result)}")
    first, second = result
    if shapes is not None:
        try:
            got = (np.shape(first), np.shape(second))
        except Exception:  # ragged learner output: the comparisons report it
            got = None
        if got is not None and got != tuple(shapes) and got == tuple(shapes)[::-1]:
            raise CheckFailed(f"{fn_name} returned ({names[1]}, {names[0]}), shapes {got}: "
                              f"return them in the order ({names[0]}, {names[1]})")
    return first, second


def _call(fn, *args, hint: str):
    """:func:`call`, with ``hint`` added when the learner's code raises (usually a
    shape mismatch in a product)."""
    try:
        return call(fn, *args)
    except CheckFailed as exc:
        raise CheckFailed(f"{exc}. Hint: {hint}") from None


def _expect(value, expected, what: str, *, formula: str, mistakes=(), **tolerances):
    """:func:`expect_close`, naming a transposed matrix and an element-wise product.

    A matrix of the transposed shape is the transpose of the right formula (K = P̌ Gᵀ S⁻¹
    written S⁻¹ G P̌); a matrix where a vector is expected comes from ``F * x`` (which
    broadcasts) instead of ``F @ x``.
    """
    expected = np.asarray(expected, dtype=float)
    arr = as_array(value, what)
    if expected.ndim == 2 and expected.shape[0] != expected.shape[1] and arr.shape == expected.T.shape:
        raise CheckFailed(f"{what} has shape {arr.shape}, expected {expected.shape}: you computed "
                          f"its transpose. Hint: {formula}")
    if expected.ndim == 1 and arr.ndim == 2 and expected.shape[0] in arr.shape:
        raise CheckFailed(f"{what} has shape {arr.shape}, expected {expected.shape}: a matrix times "
                          f"a vector is written A @ x; A * x multiplies element-wise and "
                          f"broadcasts to a matrix. Hint: {formula}")
    return expect_close(value, expected, what, mistakes=mistakes, hint=formula, **tolerances)


def _blocks_that_differ(value: np.ndarray, expected: np.ndarray, dim: int = 3) -> str:
    """Which (position/velocity) blocks of a blocked 2·dim matrix differ, in words."""
    names = ("position", "velocity")
    wrong = []
    for a in range(2):
        for b in range(2):
            block = (slice(a * dim, (a + 1) * dim), slice(b * dim, (b + 1) * dim))
            if not np.allclose(value[block], expected[block], rtol=1e-7, atol=1e-9):
                wrong.append(f"{names[a]}–{names[b]}")
    return ", ".join(wrong) if wrong else "none"


# ---------------------------------------------------------------------------------------
# the CV model
# ---------------------------------------------------------------------------------------

def _q_mistakes(T, sigma_a, F, Q):
    """Wrong Q of the CV model a learner writes, each with the hint that names it.

    B is the process-noise Jacobian [T²/2 I; T I]: how an
    acceleration held over the step moves [p, v].
    """
    I = np.eye(3)
    B = np.vstack([0.5 * T**2 * I, T * I])
    q = sigma_a**2
    yield q * np.eye(6), ("σ_a is the standard deviation of an acceleration, not of the state: "
                          "Q = σ_a² I puts the noise straight on every position and velocity. The "
                          "acceleration enters the state through the process-noise Jacobian B (how "
                          "a held acceleration moves p and v over the step; lecture 03 §5): "
                          + Q_FORMULA)
    yield sigma_a * B @ B.T, _about("σ_a is a standard deviation: square it (the acceleration's "
                                    "variance is σ_a²)", "5", Q_FORMULA)
    yield sigma_a**4 * B @ B.T, _about("σ_a is squared twice: the acceleration's variance is σ_a², "
                                       "not σ_a⁴", "5", Q_FORMULA)
    yield symbolic.cv_process_noise_continuous(T, q, 3), _about(
        "that is the continuous-white-noise Q; this exercise uses piecewise-constant "
        "acceleration (held over the step)", "5", Q_FORMULA)
    swapped = np.vstack([T * I, 0.5 * T**2 * I])
    yield q * swapped @ swapped.T, _about(
        "the blocks of B are swapped: the position's block is on top, the velocity's below",
        "5", hints.formula("a held acceleration moves the position by T²/2 and the velocity by T, "
                           "B = [T²/2 I; T I]"))
    for wrong_B, block in ((np.vstack([T**2 * I, T * I]), "position"),
                           (np.vstack([0.5 * T * I, T * I]), "position"),
                           (np.vstack([0.5 * T**2 * I, I]), "velocity")):
        yield q * wrong_B @ wrong_B.T, _about(
            f"the {block} block of B is wrong: it is how far an acceleration held over the step "
            f"moves the {block}", "5",
            hints.formula("the position moves by ½ a T² = T²/2 · a and the velocity by T · a, so "
                          "B = [T²/2 I; T I]"))
    yield q * np.diag(np.diag(B @ B.T)), _about(
        "the cross terms are missing: the same acceleration moves position and velocity, so "
        "they are correlated", "5", hints.formula("off-diagonal blocks σ_a² T³/2 I"))
    unit = np.vstack([0.5 * I, I])
    yield q * unit @ unit.T, _about("Q must use the time step T passed in, not 1", "5", Q_FORMULA)
    yield F, "cv_matrices returned (Q, F): return them in the order (F, Q)"


def _f_mistakes(T, F, Q):
    """Wrong F of the CV model, each with its hint."""
    I, Z = np.eye(3), np.zeros((3, 3))
    yield F.T, _about("F is transposed: the position gains from the velocity, not the other way "
                      "round", "5", F_FORMULA)
    yield np.block([[I, I], [Z, I]]), _about("the position gains T · v over a step, not v", "5", F_FORMULA)
    yield Q, "cv_matrices returned (Q, F): return them in the order (F, Q)"


@check
def check_cv_process_noise(cv_matrices):
    """The learner's ``cv_matrices(T, sigma_a)`` returns (F, Q) of the 3-D CV model."""
    for T, sigma_a in _cv_cases():
        result = _call(cv_matrices, T, sigma_a, hint=_about("F and Q are (6, 6): the process-noise "
                                                             "Jacobian B is (6, 3), the acceleration's "
                                                             "covariance is (3, 3)", "5", Q_FORMULA))
        F_res, Q_res = _pair(result, "cv_matrices", ("F", "Q"))
        F, Q = _cv_reference(T, sigma_a)
        # default rtol 1e-7: any correct way to write F and Q is exact to ~1e-16 here; the
        # nearest mistake (T³/3 for T³/2 at T = 0.1) is off by 1e-1 relative in its blocks
        expect_close(F_res, F, f"F for T={T}", mistakes=_f_mistakes(T, F, Q),
                     hint=_about("over a step the position gains the velocity times T and the velocity "
                                 "stays", "5", F_FORMULA))
        Q_arr = as_array(Q_res, f"Q for T={T}")
        if Q_arr.shape == (3, 3):
            raise CheckFailed(f"Q for T={T} has shape (3, 3), expected (6, 6). Hint: B is (6, 3), so "
                              "B Bᵀ is (6, 6) and Bᵀ B is (3, 3) (lecture 03 §5): " + Q_FORMULA)
        value = expect_shape(Q_arr, Q.shape, f"Q for T={T}")
        if not np.allclose(value, Q, rtol=1e-7, atol=1e-9):   # the hint is built only for a wrong Q
            expect_close(value, Q, f"Q for T={T}, sigma_a={sigma_a}", mistakes=_q_mistakes(T, sigma_a, F, Q),
                         hint="Q carries the acceleration's variance into the position and the velocity "
                              "through the process-noise Jacobian B (lecture 03 §5); the blocks that "
                              f"differ: {_blocks_that_differ(value, Q)}. "
                              + hints.formula("Q = B (σ_a² I) Bᵀ with B = [T²/2 I; T I], blocks "
                                              "σ_a² [[T⁴/4 I, T³/2 I], [T³/2 I, T² I]]"))
        expect_symmetric(value, "Q")
    for T, sigma_a in _cv_sweep():
        # the sweep's own hint: the three cases above name every listed mistake first
        every_step = _about("F and Q must hold for every step, very short and very long: build them "
                            "from T as the lecture derives them, with no cut-off or special case for "
                            "small or large T", "5", Q_FORMULA)
        F, Q = _cv_reference(T, sigma_a)
        F_res, Q_res = _pair(_call(cv_matrices, T, sigma_a, hint=every_step), "cv_matrices", ("F", "Q"))
        expect_close(F_res, F, f"F for T={T:g}", hint=every_step)
        value = expect_shape(Q_res, Q.shape, f"Q for T={T:g}, sigma_a={sigma_a}")
        # rtol 1e-7 on the scaled Q (see _scaled_q): a correct Q is exact to ~1e-15 at every T
        expect_close(_scaled_q(value, T, sigma_a), _scaled_q(Q, T, sigma_a),
                     f"Q for T={T:g}, sigma_a={sigma_a} (each entry relative to its block's size)",
                     hint=every_step)


# ---------------------------------------------------------------------------------------
# predict
# ---------------------------------------------------------------------------------------

#: (T, σ_a) of the prediction's KITTI cases, in turn; under a run seed each is drawn from the
#: ranges beside it (T around 1 s, well below and above; σ_a on both sides of 1).
PREDICT_SETTINGS = ((1.0, 0.5), (0.1, 2.0), (0.37, 1.3), (2.5, 0.8))
PREDICT_DRAWN = (((0.6, 1.6), (0.3, 0.7)), ((0.05, 0.2), (1.5, 3.0)), ((0.25, 0.6), (1.1, 1.6)),
                 ((1.8, 3.5), (0.6, 0.9)))


def _dense_predict_case(rng: np.random.Generator):
    """(x̂, P̂, F, Q) with n = 4, F ≠ Fᵀ everywhere and Q not diagonal."""
    n = 4
    return rng.normal(size=n), _spd(rng, n), rng.normal(size=(n, n)), 0.5 * _spd(rng, n)


@functools.lru_cache(maxsize=None)
def _predict_cases():
    """(x̂, P̂, F, Q) with the reference prior: KITTI states under the CV model at several
    T and σ_a (all ≠ 1), then a dense F and dense Q (F ≠ Fᵀ everywhere, Q not diagonal).
    Under a run seed the settings are drawn (:data:`PREDICT_DRAWN`) and the dense case again
    while a listed prior is a near miss."""
    settings = inputs.fixed_or_drawn(
        PREDICT_SETTINGS,
        lambda rng: tuple((_drawn(rng, *T), _drawn(rng, *sigma)) for T, sigma in PREDICT_DRAWN),
        "kf.predict.settings")
    cases = []
    for name in EXCERPTS:
        for k, (x_hat, P_hat) in enumerate(_kitti_states(name)):
            T, sigma_a = settings[k % len(settings)]
            cases.append((x_hat, P_hat, *cv_matrices_reference(T, sigma_a)))
    rng = inputs.rng("kf.predict.dense", 5)
    case = _dense_predict_case(rng)
    while inputs.drawing() and any(_relative_near_miss(kf.kf_predict(*case)[1], wrong)
                                   for wrong, _ in _prior_mistakes(*case)):
        case = _dense_predict_case(rng)
    cases.append(case)
    return tuple((case, kf.kf_predict(*case)) for case in cases)


def _prior_mistakes(x_hat, P_hat, F, Q):
    """Wrong prior covariances a learner writes, each with the hint that names it."""
    yield F @ P_hat @ F.T, _about("the process noise is missing: the step adds its uncertainty", "2",
                                  PRIOR_FORMULA)
    yield F @ P_hat @ F + Q, _about("a transpose is missing: P̂ is carried through F on both sides",
                                    "2", PRIOR_FORMULA)
    yield F.T @ P_hat @ F + Q, _about("order: not Fᵀ P̂ F, F stands on the left", "2", PRIOR_FORMULA)
    yield F @ P_hat @ F.T - Q, _about("sign: the process noise adds uncertainty", "2", PRIOR_FORMULA)
    yield P_hat + Q, _about("F is missing: the covariance is carried through the motion model", "2",
                            PRIOR_FORMULA)
    yield P_hat, _about("P̌ equals P̂: the prior covariance carries P̂ through the motion model and "
                        "adds the process noise", "2", PRIOR_FORMULA)
    yield F @ P_hat + Q, _about("Fᵀ is missing on the right", "2", PRIOR_FORMULA)
    yield F @ (P_hat + Q) @ F.T, _about(
        "Q was propagated through F: Q is the covariance the noise adds during the step, already "
        "as it stands at the step's end (B carried the held acceleration there), so Q is added "
        "after the propagation of P̂, not before", "2", PRIOR_FORMULA)
    yield F * P_hat * F.T + Q, _about("element-wise product: multiply matrices with @, not *", "2",
                                      hints.formula("P̌ = F @ P̂ @ F.T + Q"))
    yield F @ P_hat @ F.T + np.sqrt(np.abs(Q)), ("Q already holds variances: add Q as it is, "
                                                 "not its square root (lecture 03 §2)")
    yield F @ P_hat @ F.T + Q @ Q, "Q already holds variances: add Q once, not Q Q (lecture 03 §2)"


@check
def check_kf_predict(kf_predict):
    """The learner's ``kf_predict(x_hat, P_hat, F, Q)`` on KITTI states and a dense case."""
    for case, (x_check, P_check) in _predict_cases():
        x_hat, P_hat, F, Q = case
        n = len(x_hat)
        result = _call(kf_predict, *case, hint="x̂ is (n,), P̂, F and Q are (n, n) (lecture 03 §2): "
                                               + hints.formula("x̌ = F @ x̂ and P̌ = F @ P̂ @ F.T + Q"))
        x_res, P_res = _pair(result, "kf_predict", ("x_check", "P_check"), ((n,), (n, n)))
        # default rtol 1e-7: multi_dot, einsum or another bracketing agree to ~1e-15
        mean_formula = hints.formula("x̌ = F x̂")
        _expect(x_res, x_check, "x_check",
                formula=_about("the prior mean is the posterior mean carried through the motion model",
                               "2", mean_formula), mistakes=[
            (F.T @ x_hat, _about("the motion model multiplies the state from the left, not Fᵀ x̂ "
                                 "(x̂ @ F is Fᵀ x̂)", "2", mean_formula)),
            (x_hat, _about("x̌ equals x̂: the prior mean is carried through the motion model", "2",
                           mean_formula)),
        ])
        _expect(P_res, P_check, "P_check",
                formula=_about("the prior covariance carries P̂ through the motion model and adds the "
                               "process noise", "2", PRIOR_FORMULA),
                mistakes=with_symmetrised(_prior_mistakes(x_hat, P_hat, F, Q)))


# ---------------------------------------------------------------------------------------
# gain
# ---------------------------------------------------------------------------------------

def _s_mistakes(P_check, G, R):
    """Wrong innovation covariances, each with its hint."""
    GPGt = G @ P_check @ G.T
    m = len(R)
    w, V = np.linalg.eigh(R)
    sqrtm_R = (V * np.sqrt(w)) @ V.T
    yield R, ("S is the covariance of the innovation y − G x̌ before y is seen: the prior's error "
              "seen through G adds to the measurement noise. S = R leaves out the prior's "
              "uncertainty, as if x̌ were exact (lecture 03 §3, Σ_yy): " + S_FORMULA)
    yield GPGt, _about("the measurement noise is missing from S", "3", S_FORMULA)
    root = "R already holds variances (σ²): add R, not √R (a standard deviation)"
    yield GPGt + np.sqrt(np.abs(R)), _about(root, "3", S_FORMULA)
    yield GPGt + sqrtm_R, _about(root, "3", S_FORMULA)
    # for a diagonal R the two are one value: one hint names both
    squared = _about("R already holds variances (σ²): add R, not R R (or R**2), which squares them "
                     "again", "3", S_FORMULA)
    yield GPGt + R @ R, squared
    yield GPGt + R * R, squared
    yield GPGt + np.linalg.inv(R), _about("S adds the covariance R itself, not its inverse R⁻¹", "3",
                                          S_FORMULA)
    yield GPGt + np.eye(m), _about("you added the identity to S; use the R passed in (R = I only when "
                                   "every σ is 1)", "3", S_FORMULA)
    yield GPGt - R, _about("sign: the measurement noise adds uncertainty", "3", S_FORMULA)


def _k_mistakes(P_check, G, R, S, K):
    """Wrong gains computed with the right S, each with its hint."""
    PGt = P_check @ G.T
    yield PGt @ np.linalg.inv(R), _about("the gain inverts S, the innovation's covariance, not R⁻¹",
                                         "3", GAIN_FORMULA)
    yield linalg.gain(G @ P_check, G @ P_check @ G.T), _about("R is missing in the gain's S", "3",
                                                               S_FORMULA)
    yield PGt @ S, _about("the gain divides by S: invert S (np.linalg.inv or, better, "
                          "np.linalg.solve)", "3", GAIN_FORMULA)
    yield linalg.gain(G, S), _about("P̌ is missing in the gain", "3", GAIN_FORMULA)
    yield PGt, _about("the inverse of S is missing in the gain", "3", GAIN_FORMULA)
    # the gain of each wrong S, for a K computed from its own (wrong) S expression
    for S_wrong, why in _s_mistakes(P_check, G, R):
        try:
            yield linalg.gain(G @ P_check, S_wrong), f"in the gain: {why}"
        except np.linalg.LinAlgError:  # a singular wrong S: no gain to compare with
            continue


@check
def check_kf_gain(kf_gain):
    """The learner's ``kf_gain(P_check, G, R)`` returns (K, S)."""
    for (_, P_check, _, G, R), ref in _update_cases():
        m, n = G.shape
        result = _call(kf_gain, P_check, G, R, hint=SHAPES_UPDATE)
        K_res, S_res = _pair(result, "kf_gain", ("K", "S"), ((n, m), (m, m)))
        # default rtol 1e-7: inverse, solve, pinv or Cholesky agree to ~1e-13 (cond(S) < 1e3)
        _expect(S_res, ref.S, "S",
                formula=_about("S is the covariance of the innovation: the prior's uncertainty seen "
                               "through G, plus the measurement noise", "3", S_FORMULA),
                mistakes=_s_mistakes(P_check, G, R))
        _expect(K_res, ref.K, "K", formula=_about("K is (n, m): it turns an innovation (m,) into a "
                                                  "state correction (n,); np.linalg.solve(S, G P̌) "
                                                  "gives S⁻¹ G P̌, which is Kᵀ", "3", GAIN_FORMULA),
                mistakes=_k_mistakes(P_check, G, R, ref.S, ref.K))


# ---------------------------------------------------------------------------------------
# update
# ---------------------------------------------------------------------------------------

def _posterior_mean_mistakes(x_check, y, G, K, innovation):
    """Wrong posterior means (with the right gain), each with its hint."""
    sign = _about("sign of the innovation: it is measured minus predicted, and the mean moves "
                  "towards y", "3", MEAN_FORMULA)
    yield x_check - K @ innovation, sign
    yield x_check + K @ y, _about("the innovation is measured minus predicted: subtract the predicted "
                                  "measurement from y", "3", hints.formula("y − G x̌"))
    yield x_check, _about("x̂ equals the prior x̌: add the correction, the gain times the innovation",
                          "3", MEAN_FORMULA)
    m = len(y)
    yield x_check + K @ (y - x_check[:m]), (
        "the predicted measurement is G x̌: G maps the state into measurement space. y − x̌[:m] "
        "works only when G picks the first m components, and here G is dense")


def _gain_inside_update_mistakes(x_check, P_check, G, R, ref):
    """Posterior means of a kf_update that computes its own, wrong gain."""
    for K_wrong, why in _k_mistakes(P_check, G, R, ref.S, ref.K):
        yield x_check + K_wrong @ ref.innovation, (f"the gain inside kf_update is wrong ({why}); "
                                                   "kf_gain(P̌, G, R) computes it")


def _posterior_cov_mistakes(P_check, G, R, S, K):
    """Wrong posterior covariances (with the right gain), each with its hint."""
    I_KG = np.eye(len(P_check)) - K @ G
    A = I_KG @ P_check @ I_KG.T
    w, V = np.linalg.eigh(R)
    def joseph(why):
        return _about(why, "8", JOSEPH_FORMULA)

    short = hints.formula("P̂ = (I − K G) P̌")
    yield A, joseph("the Joseph form needs its second term, the measurement noise carried by the gain")
    yield A + K @ K.T, joseph("the second term is missing R: not K Kᵀ")
    yield A + K @ np.linalg.inv(R) @ K.T, joseph("the second term carries R itself, not K R⁻¹ Kᵀ")
    # (I − K G) P̌ (I − K G)ᵀ + K S Kᵀ = P̌ − K R Kᵀ for the optimal gain: one hint names both
    r_for_s = joseph("R and S swapped: the Joseph form's second term carries the measurement noise R, "
                     "not K S Kᵀ; the short form subtracts K S Kᵀ (with S, not R)")
    yield A + K @ S @ K.T, r_for_s
    yield A + K @ ((V * np.sqrt(w)) @ V.T) @ K.T, \
        joseph("R already holds variances: the second term carries R, not K √R Kᵀ")
    yield A + K @ np.sqrt(np.abs(R)) @ K.T, \
        joseph("R already holds variances: the second term carries R, not K √R Kᵀ")
    yield A + K @ R @ R @ K.T, joseph("R already holds variances: not K R R Kᵀ")
    yield A - K @ R @ K.T, joseph("sign: the measurement noise adds to the second term")
    yield I_KG.T @ P_check @ I_KG + K @ R @ K.T, \
        joseph("transpose on the wrong side: the transposed factor stands on the right")
    yield I_KG @ P_check @ I_KG + K @ R @ K.T, joseph("transpose missing on the right factor")
    yield P_check - K @ G, _about("K G must multiply P̌: multiply by P̌", "3", short)
    yield P_check, _about("P̂ equals the prior P̌: the update shrinks it", "3", short)
    yield P_check + K @ G @ P_check, _about("sign: the update shrinks the covariance", "3",
                                            hints.formula("P̂ = P̌ − K G P̌"))
    yield P_check @ I_KG, _about("order: not P̌ (I − K G), the factor I − K G stands on the left", "3",
                                 short)
    yield P_check - K @ R @ K.T, r_for_s


def _is_the_prior(x_res, P_res, x_check, P_check) -> bool:
    """Whether ``kf_update`` returned its prior unchanged (the exercise's placeholder).

    Every case's update moves the mean and shrinks the covariance by far more than the
    tolerance (rtol 1e-9), so only a posterior that ignores y matches.
    """
    x_arr, P_arr = as_array(x_res, "x_hat"), as_array(P_res, "P_hat")
    return (x_arr.shape == x_check.shape and P_arr.shape == P_check.shape
            and np.allclose(x_arr, x_check, rtol=1e-9, atol=1e-12)
            and np.allclose(P_arr, P_check, rtol=1e-9, atol=1e-12))


@check(uses=("kf_gain",))
def check_kf_update(kf_update):
    """The learner's ``kf_update(x_check, P_check, y, G, R)`` returns (x_hat, P_hat)."""
    for case, ref in _update_cases():
        x_check, P_check, y, G, R = case
        n = len(x_check)
        result = _call(kf_update, *case, hint=SHAPES_UPDATE)
        x_res, P_res = _pair(result, "kf_update", ("x_hat", "P_hat"), ((n,), (n, n)))
        if _is_the_prior(x_res, P_res, x_check, P_check):
            raise CheckFailed("the posterior equals the prior (x̂ = x̌ and P̂ = P̌): the measurement y "
                              "was not used. Hint: the update corrects the prior mean by the gain "
                              "times the innovation and shrinks the covariance, in Joseph "
                              "form (lecture 03 §3 and §8): " + MEAN_FORMULA)
        # default rtol 1e-7: the short form (I − K G) P̌ (the seed lecture's form), P̌ − K S Kᵀ
        # and the Joseph form agree to ~1e-13 for the optimal gain, so all are accepted
        _expect(x_res, ref.x_hat, "x_hat",
                formula=_about("the posterior mean corrects the prior by the gain times the innovation",
                               "3", MEAN_FORMULA),
                mistakes=itertools.chain(
                    _posterior_mean_mistakes(x_check, y, G, ref.K, ref.innovation),
                    _gain_inside_update_mistakes(x_check, P_check, G, R, ref)))
        _expect(P_res, ref.P_hat, "P_hat",
                formula=_about("the posterior covariance, in Joseph form", "8", JOSEPH_FORMULA),
                mistakes=with_symmetrised(_posterior_cov_mistakes(P_check, G, R, ref.S, ref.K)))
        expect_symmetric(P_res, "P_hat")


# ---------------------------------------------------------------------------------------
# the whole run
# ---------------------------------------------------------------------------------------

def reference_gnss_kf(t, y, sigma_a=SIGMA_A, sigma_gnss=SIGMA_GNSS, sigma_v0=SIGMA_V0):
    """Reference CV Kalman filter on GNSS positions.

    The prior at step 0 is the first fix with zero velocity (covariance σ_gnss² for position,
    σ_v0² for velocity); every later step predicts over its own time step and updates.

    Returns
    -------
    x_hat : ndarray, shape (N, 6)
    P_hat : ndarray, shape (N, 6, 6)
    """
    return _gnss_kf_variant(t, y, sigma_a, sigma_gnss, sigma_v0)


def _gnss_kf_variant(t, y, sigma_a, sigma_gnss, sigma_v0=SIGMA_V0, *, r_var=None, q_sigma=None,
                     step=None, lag=0, predict=True, store_prior=False, update_first=False):
    """The reference run, or one of the learner mistakes it is told to make.

    Parameters
    ----------
    t, y, sigma_a, sigma_gnss, sigma_v0
        As :func:`reference_gnss_kf`.
    r_var : float, optional
        The variance put on R's diagonal (default σ_gnss²).
    q_sigma : float, optional
        The σ_a handed to the CV model (default σ_a).
    step : callable, optional
        ``step(t, k)``: the time step of prediction k (default t[k] − t[k−1]).
    lag : int
        Update step k with y[k − lag].
    predict : bool
        Predict before each update.
    store_prior : bool
        Store the prior of each step instead of its posterior.
    update_first : bool
        Also update the initial state with y[0].

    Returns
    -------
    x_hat : ndarray, shape (N, 6)
    P_hat : ndarray, shape (N, 6, 6)
    """
    G = position_observation()
    R = (sigma_gnss**2 if r_var is None else r_var) * np.eye(3)
    q_sigma = sigma_a if q_sigma is None else q_sigma
    x = np.r_[y[0], np.zeros(3)]
    P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])
    if update_first:
        x, P = kf.kf_update(x, P, y[0], G, R, joseph=True)[:2]
    xs, Ps = [x], [P]
    for k in range(1, len(t)):
        if predict:
            T = t[k] - t[k - 1] if step is None else step(t, k)
            x, P = kf.kf_predict(x, P, *cv_matrices_reference(T, q_sigma))
        prior = (x, P)
        x, P = kf.kf_update(x, P, y[k - lag], G, R, joseph=True)[:2]
        xs.append(prior[0] if store_prior else x)
        Ps.append(prior[1] if store_prior else P)
    return np.array(xs), np.array(Ps)


def _fixes(name: str, start: int = 0, stop: int | None = None):
    """(t, y) of the excerpt's GNSS fixes ``start:stop``."""
    fixes = load_kitti(name).gnss.observations()
    return fixes.t[start:stop], fixes.position[start:stop]


def _drawn_window(rng: np.random.Generator, name: str) -> tuple[int, int]:
    """(start, stop) of a drawn window of an excerpt's fixes: each end moved in by up to a
    fifth of them (the cruise excerpt keeps at least 18 of its 30 fixes)."""
    count = len(load_kitti(name).gnss.observations().t)
    cut = count // 5
    return int(rng.integers(0, cut + 1)), count - int(rng.integers(0, cut + 1))


def _far_from(run, reference) -> bool:
    """Whether a listed mistake's run is more than 100 times the check's tolerance from the
    reference's (rtol 1e-4; atol 1e-4 m for x, 1e-7 for P): a drawn run where one is closer
    is drawn again, so that no mistake can pass nor be named by another's hint."""
    (x, P), (x_ref, P_ref) = run, reference
    return not (np.allclose(x, x_ref, rtol=1e-4, atol=1e-4) and np.allclose(P, P_ref, rtol=1e-4, atol=1e-7))


def _drawn_noise_levels(rng: np.random.Generator, ranges, fixed) -> tuple[float, float]:
    """(σ_a, σ_gnss) drawn from ``ranges``, never the self-check's pair ``fixed``."""
    while True:
        levels = tuple(_drawn(rng, *r) for r in ranges)
        if levels != tuple(fixed):
            return levels


@functools.lru_cache(maxsize=None)
def _run_cases():
    """(excerpt, σ_a, σ_gnss, start, stop) of the whole-run check: :data:`RUN_CASES` on all of
    each excerpt's fixes, or under a run seed the noise levels drawn from :data:`RUN_DRAWN` on
    a drawn window of the fixes, again until every run of :func:`_run_mistakes` is far from
    the reference's (:func:`_far_from`)."""
    if not inputs.drawing():
        return tuple((name, sigma_a, sigma_gnss, 0, None) for name, sigma_a, sigma_gnss in RUN_CASES)
    out = []
    for (name, *fixed), ranges in zip(RUN_CASES, RUN_DRAWN):
        rng = inputs.rng(f"kf.run.{name}", 0)
        while True:
            sigma_a, sigma_gnss = _drawn_noise_levels(rng, ranges, fixed)
            start, stop = _drawn_window(rng, name)
            _, _, *reference = _run_reference(name, sigma_a, sigma_gnss, start, stop)
            t, y = _fixes(name, start, stop)
            if all(_far_from(run, reference) for run, _ in _run_mistakes(t, y, sigma_a, sigma_gnss)):
                break
        out.append((name, sigma_a, sigma_gnss, start, stop))
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _run_reference(name: str, sigma_a: float, sigma_gnss: float, start: int = 0, stop: int | None = None):
    """(t, y, x_ref, P_ref) of a whole-run case (the reference is the same for every learner)."""
    t, y = _fixes(name, start, stop)
    return (t, y, *reference_gnss_kf(t, y, sigma_a, sigma_gnss))


def _excerpt_label(name: str, start: int, stop: int | None) -> str:
    """How a message names a run's fixes: the excerpt, and the window when it is not all of it."""
    if start == 0 and stop is None:
        return f"the '{name}' excerpt"
    return f"the '{name}' excerpt's fixes {start} to {stop - 1}"


#: The whole run's known mistakes: (the :func:`_gnss_kf_variant` keywords for (σ_a, σ_gnss), hint).
_RUN_MISTAKES = (
    (lambda sigma_a, sigma_gnss: dict(r_var=sigma_gnss),
     _about("R holds variances, and you used the standard deviation σ_gnss", "9",
            hints.formula("R = σ_gnss² I"))),
    (lambda sigma_a, sigma_gnss: dict(r_var=sigma_gnss**4),
     _about("σ_gnss is squared twice in R", "9", hints.formula("R = σ_gnss² I"))),
    (lambda sigma_a, sigma_gnss: dict(r_var=1.0),
     _about("use the sigma_gnss passed in, not R = I", "9", hints.formula("R = σ_gnss² I"))),
    (lambda sigma_a, sigma_gnss: dict(q_sigma=sigma_a**2),
     "cv_matrices takes the standard deviation σ_a and squares it itself: pass sigma_a, not "
     "sigma_a**2"),
    (lambda sigma_a, sigma_gnss: dict(q_sigma=np.sqrt(sigma_a)),
     _about("σ_a was not squared: Q holds the acceleration's variance", "5", Q_FORMULA)),
    (lambda sigma_a, sigma_gnss: dict(q_sigma=1.0),
     "the process noise must use the sigma_a passed in, not 1"),
    *((lambda sigma_a, sigma_gnss, step=step: dict(step=step),
       _about("each prediction uses its own time step, the time since the previous fix: the fixes "
              "are not exactly 1 s apart", "9", hints.formula("T = t[k] − t[k−1]")))
      for step in (lambda t, k: 1.0, lambda t, k: float(np.mean(np.diff(t))),
                   lambda t, k: t[k] - t[0], lambda t, k: t[k])),
    (lambda sigma_a, sigma_gnss: dict(store_prior=True),
     "you stored the prior (after the prediction): store the posterior of each step, after its "
     "update (lecture 03 §9)"),
    (lambda sigma_a, sigma_gnss: dict(lag=1), "step k updates with its own fix y[k] (off by one: y[k − 1])"),
    (lambda sigma_a, sigma_gnss: dict(predict=False),
     "each step predicts (kf_predict) before it updates (lecture 03 §9)"),
)


def _run_mistakes(t, y, sigma_a, sigma_gnss):
    """Runs with one learner mistake each, and the hint naming it (computed lazily)."""
    for keywords, why in _RUN_MISTAKES:
        yield _gnss_kf_variant(t, y, sigma_a, sigma_gnss, **keywords(sigma_a, sigma_gnss)), why


@functools.lru_cache(maxsize=None)
def _run_mistake(index: int, j: int):
    """The run of mistake ``j`` of :data:`_RUN_MISTAKES` on whole-run case ``index``, built only
    when a learner's run is wrong."""
    name, sigma_a, sigma_gnss, start, stop = _run_cases()[index]
    t, y = _fixes(name, start, stop)
    return _gnss_kf_variant(t, y, sigma_a, sigma_gnss, **_RUN_MISTAKES[j][0](sigma_a, sigma_gnss))


#: What every hint about row 0 ends with: what the belief at t[0] is made of (tier 1), and
#: the row itself (tier 2).
_ROW_ZERO = ("Row 0 is the belief at t[0] from the first fix alone: the fix gives the position, with "
             "the error of every fix; it says nothing of the velocity, whose spread per axis is "
             "sigma_v0")
_ROW_ZERO_FORMULA = hints.formula("x₀ = [y[0], 0], P₀ = diag(σ_gnss² I, σ_v0² I)")


def _variance_hint(got, var: float, sigma: float, what: str, fix_var: float) -> str | None:
    """What is wrong with the diagonal ``got`` (3,) of the ``what`` ("position" or "velocity")
    block of P₀, whose variance should be ``var`` = ``sigma``²: None if it is right, else the
    decision that gives it. ``fix_var`` is one fix's variance σ_gnss² (a velocity block copied
    from the position's is named)."""
    if np.allclose(got, var, rtol=1e-9):
        return None
    if np.allclose(got, sigma, rtol=1e-9):
        return (f"the initial {what} variance must be σ² = {var:g}, you used the standard deviation "
                f"σ = {sigma:g}")
    if np.allclose(got, var**2, rtol=1e-9):
        return f"the initial {what} variance is σ⁴ = {var**2:g}: σ is squared twice"
    shown = np.round(got, 6).tolist()
    if what == "position":
        if np.all(np.abs(got) <= 1e-6 * var):
            return ("the initial position variance is zero, which claims the first fix is exact: it has "
                    "the error of every fix, R")
        if np.allclose(got, 1.0, rtol=1e-9):
            return ("the initial position variance is 1 on each axis, as if σ_gnss were 1: the first fix "
                    "has the error of every fix, R, with the sigma_gnss passed in")
        if np.all(got >= 10.0 * var):
            return (f"the initial position variance is {shown}: that throws away what the first fix tells, "
                    "the position to within the error of one fix")
    else:
        if np.allclose(got, fix_var, rtol=1e-9):
            return (f"the initial velocity variance is {shown}, the fix's own variance σ_gnss²: the fix says "
                    "nothing of the velocity, not the fix's error; the velocity's spread is sigma_v0's")
        if np.all(got < 0.1 * var):
            spread = 3.0 * np.sqrt(np.clip(got, 0.0, None))
            return (f"the initial velocity variance is {shown}, near zero for a car that moves: it claims the "
                    f"velocity is known to within ±{np.max(spread):.3g} m/s (3σ), as if the filter knew the "
                    "car's speed. The car is moving at t[0], at a speed and in a direction the filter does "
                    "not know, and a P₀ that claims knowledge it does not have makes the filter "
                    "overconfident at the start (lecture 03 §7)")
    return f"the initial {what} variance is {shown}, expected σ² = {var:g}"


def _initial_state_hint(x0, P0, y0, sigma_gnss, sigma_v0=SIGMA_V0, *, second=None) -> str | None:
    """A hint naming the wrong decision in row 0 (the belief at t[0]), or None if it is right.

    Parameters
    ----------
    x0 : ndarray, shape (6,)
        The learner's row 0 of x_hat.
    P0 : ndarray, shape (6, 6)
        The learner's row 0 of P_hat.
    y0 : ndarray, shape (3,)
        The first fix (m).
    sigma_gnss, sigma_v0 : float
        The fix's noise (m) and the start velocity's spread (m/s), per axis.
    second : tuple (float, ndarray (3,)), optional
        The time step to the second fix and the second fix, to name a start velocity taken
        from the two fixes.
    """
    x_ref = np.r_[y0, np.zeros(3)]
    pos_var, vel_var = sigma_gnss**2, sigma_v0**2
    P_ref = np.diag(np.r_[np.full(3, pos_var), np.full(3, vel_var)])
    if np.allclose(x0, x_ref, rtol=1e-9, atol=1e-9) and np.allclose(P0, P_ref, rtol=1e-9, atol=1e-12):
        return None
    if np.allclose(x0, 0.0, atol=1e-12) and np.allclose(P0, np.eye(6), atol=1e-12):
        return _about("row 0 is still the exercise's placeholder (x = 0, P = I): decide the belief at t[0] "
                      "from what the first fix tells and what it does not. " + _ROW_ZERO, "9", _ROW_ZERO_FORMULA)
    G = position_observation()
    updated = kf.kf_update(x_ref, P_ref, y0, G, pos_var * np.eye(3), joseph=True)
    if np.allclose(P0, updated.P_hat, rtol=1e-6, atol=1e-9):
        return _about("row 0 was updated with y[0], but the initial state already is that fix: it "
                      "counts twice. Row 0 is the initial state itself", "9", hints.formula("x₀ = [y[0], 0]"))
    parts = []
    position, velocity = np.asarray(x0[:3], dtype=float), np.asarray(x0[3:], dtype=float)
    if not np.allclose(position, y0, rtol=1e-9, atol=1e-9):
        parts.append("the belief starts at the origin: at t[0] the car is where the first fix says, to "
                     "within the fix's error" if np.allclose(position, 0.0, atol=1e-9) else
                     "the position of the belief at t[0] is the first fix itself: nothing else is known yet")
    if not np.allclose(velocity, 0.0, atol=1e-9):
        from_fixes = None
        if second is not None and np.all(np.isfinite(second[1])) and second[0] > 0:
            from_fixes = (np.asarray(second[1], dtype=float) - y0) / second[0]
        if from_fixes is not None and np.allclose(velocity, from_fixes, rtol=1e-6, atol=1e-9):
            parts.append("the start velocity was taken from the second fix: at t[0] only y[0] is known, and "
                         "the update of step 1 uses y[1] again, which counts it twice")
        else:
            parts.append("a start velocity other than zero claims a direction of travel that nothing has told "
                         "the filter: with every direction as likely, the mean velocity is zero")
    P0 = np.asarray(P0, dtype=float)
    for block, var, sigma, what in ((slice(0, 3), pos_var, sigma_gnss, "position"),
                                    (slice(3, 6), vel_var, sigma_v0, "velocity")):
        wrong = _variance_hint(np.diag(P0)[block], var, sigma, what, pos_var)
        if wrong is not None:
            parts.append(wrong)
    if np.any(np.abs(P0[:3, 3:]) > 1e-12) or np.any(np.abs(P0[3:, :3]) > 1e-12):
        parts.append("P₀ couples the position and velocity errors, but the first fix tells nothing about "
                     "the velocity: nothing links the two at t[0], so their blocks of P₀ are zero")
    for block, what in ((slice(0, 3), "the fix's errors on the three axes are independent (R is diagonal)"),
                        (slice(3, 6), "nothing links the three velocity components")):
        inner = P0[block, block]
        if np.any(np.abs(inner - np.diag(np.diag(inner))) > 1e-12):
            parts.append(f"{what}: that block of P₀ is diagonal")
    if not parts:           # row 0 differs below the rounding that the parts above resolve
        parts.append("row 0 differs from the belief at t[0]")
    return _about("; ".join(parts) + ". " + _ROW_ZERO, "9", _ROW_ZERO_FORMULA)


def _same_run(x_hat, P_hat, x_ref, P_ref) -> bool:
    """Whether a run (or one row of it) is the reference: rtol 1e-6, atol 1e-6 m for x and
    1e-9 for P (see :func:`check_gnss_kf_run`)."""
    return bool(np.allclose(x_hat, x_ref, rtol=1e-6, atol=1e-6) and np.allclose(P_hat, P_ref, rtol=1e-6, atol=1e-9))


def _learner_runs(fn, calls, hint: str) -> list:
    """The learner's run on each of ``calls`` (argument tuples); a call that raised leaves its
    :class:`CheckFailed` in its place, raised when the check reaches that case (the messages
    come in the cases' order, as with one call at a time)."""
    out = []
    for args in calls:
        try:
            out.append(_call(fn, *args, hint=hint))
        except CheckFailed as exc:
            out.append(exc)
    return out


def _result(got):
    """A result of :func:`_learner_runs`, raising the failure stored in its place."""
    if isinstance(got, CheckFailed):
        raise got
    return got


def _is_run(got, wrong) -> bool:
    """Whether a learner's result (a pair, as returned) is the run ``wrong`` ((x_hat, P_hat));
    False for a result of another form or shape."""
    if wrong is None or isinstance(got, CheckFailed) or not isinstance(got, (tuple, list)) or len(got) != 2:
        return False
    try:
        x_hat, P_hat = (np.asarray(value, dtype=float) for value in got)
    except (TypeError, ValueError):
        return False
    x_wrong, P_wrong = wrong
    return x_hat.shape == x_wrong.shape and P_hat.shape == P_wrong.shape and \
        _same_run(x_hat, P_hat, x_wrong, P_wrong)


def _reject_known_run_mistakes(got: list, index: int, t, y, sigma_gnss, mistakes, run_of, where: str) -> None:
    """Raise CheckFailed if run ``index``'s initial state is wrong or a listed mistake explains
    the learner's runs (:func:`harness.known_mistake`: on every case, else on this one); return
    if none does.

    Parameters
    ----------
    got : list
        The learner's results on every case of the check (:func:`_learner_runs`).
    index : int
        The case whose run is wrong (its shapes are checked).
    t, y, sigma_gnss
        That case's times, fixes and GNSS noise, for the initial state's hint.
    mistakes : sequence of str
        The hints of the listed mistakes, in order.
    run_of : callable
        ``run_of(case, j)``: the run (x_hat, P_hat) of mistake ``j`` on a case.
    where : str
        The run, as the message names it.
    """
    x_hat, P_hat = (np.asarray(value, dtype=float) for value in got[index])
    initial = _initial_state_hint(x_hat[0], P_hat[0], y[0], sigma_gnss,
                                  second=(t[1] - t[0], y[1]) if len(t) > 1 else None)
    if initial is not None:
        raise CheckFailed(f"row 0 of x_hat / P_hat on {where} is wrong. Hint: {initial}")
    why = known_mistake(got, range(len(got)), list(enumerate(mistakes)), lambda g, w, _: _is_run(g, w),
                        evaluate=lambda j, case: run_of(case, j), case=index)
    if why is not None:
        raise CheckFailed(f"the run on {where} is wrong. Hint: {why}")


@check(uses={"cv_matrices": "cv_process_noise", "kf_predict": "kf_predict", "kf_gain": "kf_gain",
             "kf_update": "kf_update"})
def check_gnss_kf_run(run_gnss_kf):
    """The learner's ``run_gnss_kf(t, y, sigma_a, sigma_gnss)`` on the KITTI excerpts' noisy GNSS.

    Tolerance rtol 1e-6 (atol 1e-6 m for x, 1e-9 for P): a correct run differs from the
    reference by round-off only (also with the short-form update or an inverse instead of a
    solve); the smallest mistake in the catalogue, a constant time step (1 s or the mean
    step) where the fixes are up to 1.4 ms from 1 s apart, exceeds the tolerance more than
    100-fold.
    """
    cases = _run_cases()
    references = [_run_reference(*case) for case in cases]
    results = _learner_runs(run_gnss_kf, [(t, y, case[1], case[2]) for case, (t, y, *_) in zip(cases, references)],
                            hint=_about("y is (N, 3), G is (3, 6), R is (3, 3); each step k ≥ 1 predicts "
                                        "over its own time step and updates with y[k]", "9",
                                        hints.formula("G = [I 0], R = σ_gnss² I, T = t[k] − t[k−1]")))
    for index, ((name, sigma_a, sigma_gnss, start, stop), (t, y, x_ref, P_ref)) in enumerate(zip(cases, references)):
        excerpt = _excerpt_label(name, start, stop)
        N = len(t)
        result = _result(results[index])
        x_res, P_res = _pair(result, "run_gnss_kf", ("x_hat (N, 6)", "P_hat (N, 6, 6)"))
        rows = "one row per fix: row 0 is the initial state, row k ≥ 1 the posterior after the fix y[k]"
        for value, ref, what in ((x_res, x_ref, "x_hat"), (P_res, P_ref, "P_hat")):
            shape = np.shape(as_array(value, what))
            if len(shape) == ref.ndim and shape[1:] == ref.shape[1:] and shape[0] != N:
                raise CheckFailed(f"{what} on {excerpt} has {shape[0]} rows for {N} fixes. "
                                  f"Hint: {rows}")
        x_hat = expect_shape(x_res, x_ref.shape, "x_hat")
        P_hat = expect_shape(P_res, P_ref.shape, "P_hat")
        if _same_run(x_hat, P_hat, x_ref, P_ref):
            continue
        _reject_known_run_mistakes(results, index, t, y, sigma_gnss, [why for _, why in _RUN_MISTAKES],
                                   _run_mistake, f"{excerpt} (σ_a = {sigma_a}, σ_gnss = {sigma_gnss})")
        truth = truth_at(name, t)
        # 3-D position RMSE = norm of the per-axis RMSEs (NaN in a learner's x_hat stays NaN)
        err = np.linalg.norm(rmse(x_hat[:, :3], truth, axis=0))
        err_ref = np.linalg.norm(rmse(x_ref[:, :3], truth, axis=0))
        expect_close(x_hat, x_ref, f"x_hat on {excerpt}", rtol=1e-6, atol=1e-6,
                     hint=f"your position RMSE against ground truth is {err:.3f} m, the reference "
                          f"reaches {err_ref:.3f} m. Check the noise levels of R and Q, each step's own "
                          "time step and that each row stores the posterior (lecture 03 §9): "
                          + hints.formula("R = σ_gnss² I, Q from cv_matrices(t[k] − t[k−1], sigma_a)"))
        expect_close(P_hat, P_ref, f"P_hat on {excerpt}", rtol=1e-6, atol=1e-9,
                     hint="x_hat is right but P_hat is not: store the posterior covariance of "
                          "each step, the one returned with x_hat")


# ---------------------------------------------------------------------------------------
# challenge: missing fixes
# ---------------------------------------------------------------------------------------

#: Rows of the excerpts' fixes that the gaps check removes: single dropouts, a 4 s outage
#: (rows 8–11) and the last fix (a gap that no later fix ends). Negative rows count from
#: the end.
GAP_ROWS = (3, 8, 9, 10, 11, 17, -1)


def with_missing_fixes(y, rows=GAP_ROWS) -> np.ndarray:
    """A copy of the fixes ``y`` (N, 3) with the rows ``rows`` (default :data:`GAP_ROWS`)
    set to NaN."""
    y = np.array(y, dtype=float)
    y[sorted({row % len(y) for row in rows})] = np.nan
    return y


def _drawn_gap_rows(rng: np.random.Generator, count: int) -> tuple[int, ...]:
    """Missing rows in the roles of :data:`GAP_ROWS` for ``count`` fixes: two single dropouts
    and an outage of 3–5 fixes at drawn rows in [2, count − 3], at least two fixes apart (so
    that a fix ends each gap and the next one sees its effect), and the last fix."""
    length = int(rng.integers(3, 6))
    while True:
        singles = rng.choice(np.arange(2, count - 2), size=2, replace=False)
        outage = int(rng.integers(2, count - 2 - length + 1))
        segments = sorted([(int(a), int(a)) for a in singles] + [(outage, outage + length - 1)])
        if all(later[0] - earlier[1] >= 3 for earlier, later in zip(segments, segments[1:])):
            break
    rows = [row for first, last in segments for row in range(first, last + 1)]
    return tuple(rows) + (-1,)


def reference_gnss_kf_gaps(t, y, sigma_a=SIGMA_A, sigma_gnss=SIGMA_GNSS, sigma_v0=SIGMA_V0):
    """:func:`reference_gnss_kf` where a row of ``y`` that is all NaN is a missing fix.

    Every step predicts over its own time step; a step with a fix then updates, a step
    without one keeps its prior as its posterior.

    Returns
    -------
    x_hat : ndarray, shape (N, 6)
    P_hat : ndarray, shape (N, 6, 6)
    """
    return _gaps_variant(t, y, sigma_a, sigma_gnss, sigma_v0)


def _gaps_variant(t, y, sigma_a, sigma_gnss, sigma_v0=SIGMA_V0, *, at_gap="prior"):
    """The gaps reference, or a run making one learner mistake at the missing fixes.

    Parameters
    ----------
    t, y, sigma_a, sigma_gnss, sigma_v0
        As :func:`reference_gnss_kf_gaps`.
    at_gap : {"prior", "stale", "stale_then_long", "predicted", "last_fix", "zero"}
        What a step without a fix does: keep the prior (the reference); store the last
        posterior and skip the prediction ("stale", the next step predicts over its own
        time step only; "stale_then_long", the next step predicts over the whole time since
        the last prediction); or update with a made-up fix: the predicted position, the
        last fix received, or zeros.

    Returns
    -------
    x_hat : ndarray, shape (N, 6)
    P_hat : ndarray, shape (N, 6, 6)
    """
    G = position_observation()
    R = sigma_gnss**2 * np.eye(3)
    x = np.r_[y[0], np.zeros(3)]
    P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])
    xs, Ps = [x], [P]
    last_fix, t_state = y[0], t[0]   # the last fix used, the time x and P refer to
    for k in range(1, len(t)):
        missing = bool(np.all(np.isnan(y[k])))
        if missing and at_gap in ("stale", "stale_then_long"):
            xs.append(x)
            Ps.append(P)
            continue
        T = t[k] - (t_state if at_gap == "stale_then_long" else t[k - 1])
        x, P = kf.kf_predict(x, P, *cv_matrices_reference(T, sigma_a))
        t_state = t[k]
        if missing:
            made_up = {"prior": None, "predicted": G @ x, "last_fix": last_fix,
                       "zero": np.zeros(3)}[at_gap]
            if made_up is not None:
                x, P = kf.kf_update(x, P, made_up, G, R, joseph=True)[:2]
        else:
            x, P = kf.kf_update(x, P, y[k], G, R, joseph=True)[:2]
            last_fix = y[k]
        xs.append(x)
        Ps.append(P)
    return np.array(xs), np.array(Ps)


@functools.lru_cache(maxsize=None)
def _gaps_cases():
    """(excerpt, σ_a, σ_gnss, start, stop, missing rows) of the gaps check: the whole-run
    settings on all the fixes with :data:`GAP_ROWS` missing, or under a run seed the noise
    levels and window drawn as for :func:`_run_cases` with the rows of
    :func:`_drawn_gap_rows`, again until every run of :func:`_gaps_mistakes` is far from the
    reference's (:func:`_far_from`)."""
    if not inputs.drawing():
        return tuple((name, sigma_a, sigma_gnss, 0, None, GAP_ROWS)
                     for name, sigma_a, sigma_gnss in RUN_CASES)
    out = []
    for (name, *fixed), ranges in zip(RUN_CASES, RUN_DRAWN):
        rng = inputs.rng(f"kf.gaps.{name}", 0)
        while True:
            sigma_a, sigma_gnss = _drawn_noise_levels(rng, ranges, fixed)
            start, stop = _drawn_window(rng, name)
            rows = _drawn_gap_rows(rng, stop - start)
            t, y, *reference = _gaps_reference(name, sigma_a, sigma_gnss, start, stop, rows)
            if all(_far_from(run, reference) for run, _ in _gaps_mistakes(t, y, sigma_a, sigma_gnss)):
                break
        out.append((name, sigma_a, sigma_gnss, start, stop, rows))
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _gaps_reference(name: str, sigma_a: float, sigma_gnss: float, start: int = 0, stop: int | None = None,
                    rows: tuple = GAP_ROWS):
    """(t, y with gaps, x_ref, P_ref) of a gaps case (the same for every learner)."""
    t, y = _fixes(name, start, stop)
    y = with_missing_fixes(y, rows)
    y.flags.writeable = False
    return (t, y, *reference_gnss_kf_gaps(t, y, sigma_a, sigma_gnss))


#: What every hint of a missing fix ends with: what the filter knows at t[k] without its fix.
_AFTER_A_GAP = ("With no fix the posterior is the prior (lecture 03 §3): at t[k] the best estimate "
                "is the prediction to t[k], and the next step predicts on from there")

#: The challenge's known mistakes at the missing fixes: (``at_gap`` of :func:`_gaps_variant`, hint).
_GAP_MISTAKES = (
    ("stale", "at a missing fix you stored the last posterior and skipped the prediction: time "
              f"passes during an outage, and the car moves on. {_AFTER_A_GAP}"),
    ("stale_then_long",
     "the rows of the missing fixes hold the last posterior, and the next fix predicts over the "
     "whole gap at once: store the prediction to t[k] at each missing fix, and predict step by "
     "step (one long step holds one acceleration for the whole gap, which is another model). "
     + _AFTER_A_GAP),
    ("predicted", "a missing fix is no measurement: updating with the predicted position G x̌ leaves "
                  f"the mean but shrinks P̂ as if a fix had arrived. {_AFTER_A_GAP}"),
    ("last_fix", "a missing fix is not the last fix received again: that fix was used already, and "
                 f"using it twice pulls the estimate back to where the car was. {_AFTER_A_GAP}"),
    ("zero", "a missing fix is no fix at the origin (np.nan_to_num makes NaN 0): skip its update. "
             + _AFTER_A_GAP),
)


def _gaps_mistakes(t, y, sigma_a, sigma_gnss):
    """Runs with one mistake at the missing fixes each, and the hint naming it (lazily)."""
    for at_gap, why in _GAP_MISTAKES:
        yield _gaps_variant(t, y, sigma_a, sigma_gnss, at_gap=at_gap), why


@functools.lru_cache(maxsize=None)
def _gaps_mistake(index: int, j: int):
    """The run of mistake ``j`` of :data:`_GAP_MISTAKES` on gaps case ``index`` (built only when a
    learner's run is wrong)."""
    name, sigma_a, sigma_gnss, start, stop, rows = _gaps_cases()[index]
    t, y, *_ = _gaps_reference(name, sigma_a, sigma_gnss, start, stop, rows)
    return _gaps_variant(t, y, sigma_a, sigma_gnss, at_gap=_GAP_MISTAKES[j][0])


@check(uses={"cv_matrices": "cv_process_noise", "kf_predict": "kf_predict", "kf_gain": "kf_gain",
             "kf_update": "kf_update", "run_gnss_kf": "gnss_kf_run"})
def check_gnss_kf_gaps(run_gnss_kf_gaps):
    """The learner's ``run_gnss_kf_gaps(t, y, sigma_a, sigma_gnss)``: the KITTI excerpts'
    fixes with a 4 s outage, single dropouts and the last fix missing (NaN rows); under a
    run seed, drawn ones in the same roles (:func:`_gaps_cases`).

    The exercise's filter starts from row 0 of the learner's ``run_gnss_kf`` (the belief at
    t[0] they decided there): a wrong one is named as ``run_gnss_kf``'s, to fix first.

    Tolerance as in :func:`check_gnss_kf_run` (rtol 1e-6; atol 1e-6 m for x, 1e-9 for P);
    the nearest mistake, the last fix's prior replaced by its stale posterior, differs by
    more than 1e-2 m in that row.
    """
    cases = _gaps_cases()
    references = [_gaps_reference(*case) for case in cases]
    # a copy: a learner's in-place edit of y (np.nan_to_num(y, copy=False)) must not
    # change the cached case
    results = _learner_runs(run_gnss_kf_gaps, [(t, y.copy(), case[1], case[2])
                                               for case, (t, y, *_) in zip(cases, references)],
                            hint="y is (N, 3) with NaN rows where a fix is missing; x_hat is (N, 6) "
                                 "and P_hat (N, 6, 6), one row per time t[k]")
    for index, ((name, sigma_a, sigma_gnss, start, stop, rows), (t, y, x_ref, P_ref)) in \
            enumerate(zip(cases, references)):
        excerpt = _excerpt_label(name, start, stop)
        N = len(t)
        missing = set(np.flatnonzero(np.all(np.isnan(y), axis=1)).tolist())
        result = _result(results[index])
        x_res, P_res = _pair(result, "run_gnss_kf_gaps", ("x_hat (N, 6)", "P_hat (N, 6, 6)"))
        for value, ref, what in ((x_res, x_ref, "x_hat"), (P_res, P_ref, "P_hat")):
            arr = as_array(value, what)
            if arr.ndim == ref.ndim and arr.shape[1:] == ref.shape[1:] and arr.shape[0] != N:
                raise CheckFailed(f"{what} on {excerpt} has {arr.shape[0]} rows for {N} "
                                  f"times ({len(missing)} fixes missing). Hint: one row per time "
                                  "t[k], also where the fix is missing: there the row is the "
                                  "estimate without that fix")
            if arr.shape == ref.shape and not np.all(np.isfinite(arr)):
                row = int(np.flatnonzero(~np.all(np.isfinite(arr.reshape(N, -1)), axis=1))[0])
                why = (f"fix {row} is missing (NaN) and an update with it makes the state NaN from "
                       "there on: skip the update where y[k] is all NaN (the posterior is then the "
                       "prior)" if row in missing else "check the steps around it")
                raise CheckFailed(f"{what} on {excerpt} contains NaN from row {row} on. "
                                  f"Hint: {why}")
        x_hat = expect_shape(x_res, x_ref.shape, "x_hat")
        P_hat = expect_shape(P_res, P_ref.shape, "P_hat")
        if _same_run(x_hat, P_hat, x_ref, P_ref):
            continue
        _reject_known_run_mistakes(results, index, t, y, sigma_gnss, [why for _, why in _GAP_MISTAKES],
                                   _gaps_mistake, f"{excerpt} with missing fixes")
        wrong_rows = [k for k in range(N) if not _same_run(x_hat[k], P_hat[k], x_ref[k], P_ref[k])]
        first = wrong_rows[0]
        where = (f"row {first} is a missing fix: there the posterior is the prior, predicted to "
                 f"t[{first}] over its own time step" if first in missing else
                 f"row {first} has a fix" + (", right after a missing one: the step still "
                                               "predicts over t[k] − t[k−1] from the row before"
                                               if first - 1 in missing else
                                               ": before the first missing fix the run is "
                                               "run_gnss_kf's, a prediction over the step's own "
                                               "time step t[k] − t[k−1] and an update with y[k]"))
        expect_close(x_hat, x_ref, f"x_hat on {excerpt} with missing fixes", rtol=1e-6,
                     atol=1e-6, hint=f"the first wrong row is {first}; {where}")
        expect_close(P_hat, P_ref, f"P_hat on {excerpt} with missing fixes", rtol=1e-6,
                     atol=1e-9, hint=f"x_hat is right but P_hat is not; the first wrong row is "
                                     f"{first}; {where}")
