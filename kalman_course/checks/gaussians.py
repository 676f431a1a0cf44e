"""Checks for chapter 02: conditioning a joint Gaussian and pushing one through y = Gx + n.

The cases are chosen so that the mistakes learners make give different numbers: the first
case of every check is square (n = m) with a non-symmetric Σ_xy or G, so a transposed block
gives a wrong value instead of a shape error; the others have n ≠ m (both n > m and n < m),
where a transpose changes the shape; covariances are full (non-diagonal) and anisotropic
(scales from 0.1 to 30), so that a variance and a standard deviation, a matrix and its
diagonal, or R and R R are different numbers. The linear map's noise is correlated with x
(a dense cross-covariance Σ_xn, so that G Σ_xn is not symmetric): leaving out a cross term, or
the independent-noise formulas of lecture 02 §5, give other numbers. Reference and wrong values
are computed once per process (``functools.cache``).

Hints come in tiers (:mod:`kalman_course.checks.hints`): the concept, the mistake and the
lecture section first (§3–§6 of lecture 02), the formula marked for tier 2.

Tolerance: the default ``rtol=1e-7, atol=1e-9`` of :func:`expect_close`. The condition
numbers of the Σ_yy here stay below 300, so correct variants (an explicit inverse, a solve,
a Cholesky factor, the gain form, the precision form through the inverse of the whole joint
covariance) agree with the reference to ~1e-11 relative; every listed mistake differs by more
than 1e-2 relative on some case.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every family is drawn anew, in
the same shapes and roles: the joint Gaussians (the square case's scales in 0.3–3.5, at least
a factor 3 apart; the anisotropic case's from below 0.2 to above 15) and the observed y; the
linear maps' Σ_xx, G, R and Σ_xn (the square case's R = diag(σ²) with one σ in 0.1–0.5 and one
in 1.3–3; the correlation in :data:`CORRELATION_DRAWN`); and the fused pairs (their spreads
drawn around 1, 5 and 30). A drawn case is drawn again while cond(Σ_yy) exceeds 300 or a
listed mistake comes within 1e-2 relative of the reference without being it (a mistake that
is the reference by an identity, such as the variances of a 1-dimensional y, changes
nothing); the linear maps' fixed cases are held to the same rule.
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course.checks import cases as inputs
from kalman_course.checks import hints
from kalman_course.core import gaussians
from kalman_course.core.linalg import symmetrise
from kalman_course.checks.harness import (CheckFailed, as_array, call, check, expect_close,
                                          expect_symmetric, type_name)


#: The formulas the hints point to, shown at hint tier 2 (:mod:`kalman_course.checks.hints`).
CONDITIONAL_MEAN = hints.formula("μ_x|y = μ_x + Σ_xy Σ_yy⁻¹ (y − μ_y)")
CONDITIONAL_COV = hints.formula("Σ_x|y = Σ_xx − Σ_xy Σ_yy⁻¹ Σ_yx")
MAPPED_COV = hints.formula("Σ_yy = G Σ_xx Gᵀ + G Σ_xn + Σ_xnᵀ Gᵀ + R")
CROSS_COV = hints.formula("Σ_xy = Σ_xx Gᵀ + Σ_xn")


def _about(why: str, section: str, formula: str) -> str:
    """A hint at its two tiers: ``why`` (the concept or the mistake) and where the lecture
    derives it, then the marked ``formula`` (shown at tier 2)."""
    return f"{why} (lecture 02 §{section}): {formula}"


def random_joint(n: int, m: int, seed, scales=None):
    """A random joint Gaussian of x (n) and y (m): (mu_x, mu_y, Sigma_xx, Sigma_xy, Sigma_yy).

    ``seed`` is an integer or a ``numpy.random.Generator`` to draw from. ``scales`` (length
    n + m) multiplies each component's standard deviation, which makes the covariance
    anisotropic; by default every component has a scale of 1.
    """
    rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(seed)
    A = rng.normal(size=(n + m, n + m))
    Sigma = A @ A.T + 0.5 * np.eye(n + m)
    mu = rng.normal(size=n + m)
    if scales is not None:
        D = np.diag(np.asarray(scales, dtype=float))
        Sigma = D @ Sigma @ D
        mu = D @ mu
    return mu[:n], mu[n:], Sigma[:n, :n], Sigma[:n, n:], Sigma[n:, n:]


def _near_miss(expected, wrong) -> bool:
    """Whether a listed mistake comes within 1e-2 relative (max norm) of the reference
    without being it: such a drawn case would let a wrong formula pass or a hint go unnamed,
    so it is drawn again (a mistake that equals the reference to 1e-10, by an identity that
    holds for the case's shape, changes nothing)."""
    expected, wrong = np.asarray(expected, dtype=float), np.asarray(wrong, dtype=float)
    if wrong.shape != expected.shape:
        return False
    distance = np.max(np.abs(wrong - expected)) / np.max(np.abs(expected))
    return bool(1e-10 < distance < 1e-2)


def _separated(pairs) -> bool:
    """Whether no mistake in ``pairs`` ((reference, [(wrong, hint), ...]), ...) is a near miss."""
    return not any(_near_miss(ref, wrong) for ref, mistakes in pairs for wrong, _ in mistakes)


def _sqrtm(S):
    """Symmetric square root of an SPD matrix (what a learner's scipy.linalg.sqrtm gives)."""
    w, V = np.linalg.eigh(S)
    return (V * np.sqrt(w)) @ V.T


def _shape_hint(exc: CheckFailed, sizes: str, hint: str) -> CheckFailed:
    """Append ``hint`` to a learner's exception when it is a shape mismatch (n ≠ m case)."""
    text = str(exc)
    if any(word in text for word in ("mismatch", "shape", "broadcast", "aligned", "dimension")):
        return CheckFailed(f"{text} ({sizes}). Hint: {hint}")
    return exc


def _tuple(result, size: int, names: str, fn_name: str) -> tuple:
    """A learner's multiple return as a tuple; a list of the same length is as good."""
    if isinstance(result, (tuple, list)) and len(result) == size:
        return tuple(result)
    raise CheckFailed(f"{fn_name} must return {size} values {names} (a tuple or a list), "
                      f"got {type_name(result)}"
                      + (f" of length {len(result)}" if isinstance(result, (tuple, list)) else ""))


# ---------------------------------------------------------------------------------------
# the conditional
# ---------------------------------------------------------------------------------------

#: (n, m, seed, scales): square first, then n > m, and an anisotropic n > m case.
_CONDITIONAL_SHAPES = ((2, 2, 6, (1.0, 3.0, 0.5, 2.0)),
                       (2, 1, 3, None),
                       (3, 2, 4, (0.1, 1.0, 30.0, 2.0, 0.3)),
                       (4, 3, 5, None))

_CONDITIONAL_SHAPE_HINT = ("with n ≠ m the shapes do not fit, so a block is transposed "
                           "somewhere in the function (mean or covariance): Σ_xy is (n, m), "
                           "Σ_yx = Σ_xyᵀ is (m, n), and the innovation y − μ_y has m entries "
                           "(lecture 02 §4): " + hints.formula("Σ_yy⁻¹ Σ_yx is solve(Σ_yy, Σ_xy.T)"))


@functools.cache
def _conditional_cases():
    """Each case: (args, mean, cov, mean mistakes, cov mistakes).

    Under a run seed each shape's joint and y are drawn (:func:`_drawn_scales`), again while
    cond(Σ_yy) > 300 or a mistake is a near miss (:func:`_near_miss`)."""
    out = []
    for n, m, seed, scales in _CONDITIONAL_SHAPES:
        if not inputs.drawing():
            joint = random_joint(n, m, seed, scales)
            y_noise = np.random.default_rng(seed + 100).normal(size=m)
            out.append(_conditional_case(joint, y_noise))
            continue
        rng = inputs.rng("gaussians.conditional", seed)
        while True:
            joint = random_joint(n, m, rng, _drawn_scales(rng, scales))
            case = _conditional_case(joint, rng.normal(size=m))
            (*_, Syy, _), mean, cov, mean_mistakes, cov_mistakes = case
            if np.linalg.cond(Syy) <= 300 and _separated(((mean, mean_mistakes), (cov, cov_mistakes))):
                break
        out.append(case)
    return out


def _drawn_scales(rng: np.random.Generator, fixed):
    """Scales in the role of a shape's fixed ones: None stays None (every scale 1); four, as
    the square case's, in 0.3–3.5 and at least a factor 3 apart; five, as the anisotropic
    case's, one below 0.2, one above 15 and three in 0.3–3 (in a drawn order)."""
    if fixed is None:
        return None
    if len(fixed) == 4:
        while True:
            scales = inputs.log_uniform(rng, 0.3, 3.5, 4)
            if scales.max() >= 3.0 * scales.min():
                return scales
    spread = np.r_[inputs.log_uniform(rng, 0.08, 0.2), inputs.log_uniform(rng, 15.0, 40.0),
                   inputs.log_uniform(rng, 0.3, 3.0, len(fixed) - 2)]
    return rng.permutation(spread)


def _conditional_case(joint, y_noise):
    """(args, mean, cov, mean mistakes, cov mistakes) of one joint Gaussian, y drawn from the
    marginal of y with the standard normal ``y_noise``."""
    mu_x, mu_y, Sxx, Sxy, Syy = joint
    n, m = len(mu_x), len(mu_y)
    y = mu_y + np.sqrt(np.diag(Syy)) * y_noise
    mean, cov = gaussians.conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)
    innovation = y - mu_y
    K = np.linalg.solve(Syy, Sxy.T).T                        # Σ_xy Σ_yy⁻¹
    K_diag = Sxy / np.diag(Syy)                              # only the variances of y
    mean_mistakes = [
        (mu_x + Sxy @ innovation, _about("the innovation y − μ_y must be weighted by the inverse of "
                                         "Σ_yy", "4", hints.formula("the gain is Σ_xy Σ_yy⁻¹"))),
        (mu_x + Sxy @ Syy @ innovation, _about("Σ_yy multiplies the innovation where its inverse "
                                               "belongs, a solve with Σ_yy", "4", CONDITIONAL_MEAN)),
        (mu_x - K @ innovation, _about("sign: the mean moves towards the observation", "4",
                                       CONDITIONAL_MEAN)),
        (mu_x, _about("the mean did not move: observing y pulls it", "4", CONDITIONAL_MEAN)),
        (mu_x + K @ y, "the mean of y is missing from the innovation: subtract μ_y from y "
                       "(lecture 02 §4)"),
        (mu_x + K_diag @ innovation, "only the diagonal of Σ_yy (the variances) was used, "
                                     "as in the one-dimensional formula: the components of "
                                     "y are correlated (Σ_yy is not diagonal), so weigh "
                                     "the innovation by the inverse of the whole matrix "
                                     "Σ_yy, not by each variance alone (lecture 02 §4)"),
    ]
    cov_mistakes = [
        (Sxx + K @ Sxy.T, _about("sign: observing y removes uncertainty", "4", CONDITIONAL_COV)),
        (Sxx, _about("the covariance did not shrink: observing y removes the part of x's uncertainty "
                     "that y explains (the Schur complement)", "3 and §4", CONDITIONAL_COV)),
        (Sxx - Sxy @ Sxy.T, "Σ_yy⁻¹ is missing between Σ_xy and Σ_yx (lecture 02 §4)"),
        (Sxx - Sxy @ Syy @ Sxy.T, _about("Σ_yy stands where its inverse belongs", "4", CONDITIONAL_COV)),
        (Sxx - K_diag @ Sxy.T, "only the diagonal of Σ_yy (the variances) was used, as in "
                               "the one-dimensional formula: y's components are correlated, "
                               "invert the whole matrix Σ_yy (lecture 02 §4)"),
    ]
    if n == m:
        mean_mistakes += [
            (mu_x + Sxy.T @ np.linalg.solve(Syy, innovation),
             _about("Σ_xy is transposed: Σ_xy has shape (n, m)", "4",
                    hints.formula("the gain is Σ_xy Σ_yy⁻¹"))),
            (mu_x + K @ (y - mu_x), "the innovation subtracts the mean of y: y − μ_y, not μ_x "
                                    "(lecture 02 §4)"),
            (mu_y + K @ innovation, "the conditional mean of x starts from μ_x, not μ_y (lecture 02 §4)"),
            (mu_x + np.linalg.solve(Syy, Sxy) @ innovation,
             _about("Σ_yy⁻¹ Σ_xy is the gain transposed (and in the wrong order)", "4",
                    hints.formula("the gain is Σ_xy Σ_yy⁻¹ = solve(Σ_yy, Σ_xy.T).T"))),
        ]
        cov_mistakes += [
            (Sxx - Sxy @ np.linalg.solve(Syy, Sxy),
             _about("the last factor is transposed: Σ_yx = Σ_xyᵀ", "4", CONDITIONAL_COV)),
            (Sxx - Sxy.T @ np.linalg.solve(Syy, Sxy),
             _about("Σ_xy and Σ_yx are swapped (transposed)", "4", CONDITIONAL_COV)),
            (Syy - Sxy.T @ np.linalg.solve(Sxx, Sxy),
             "that is the covariance of y given x (the Schur complement of Σ_xx, what is "
             "left of y's uncertainty once x is known). Here y is observed and x is "
             "unknown: start from Σ_xx and take the Schur complement of Σ_yy (lecture 02 "
             "§3 and §4)"),
            (Sxx - np.linalg.solve(Syy, Sxy.T) @ Sxy,
             _about("the factors are in the wrong order (matrix products do not commute)", "4",
                    CONDITIONAL_COV)),
        ]
    # a learner who symmetrises the result (as the exercise's return line does) turns a
    # non-symmetric wrong covariance into its symmetric part: name that one too
    cov_mistakes += [(symmetrise(w), why) for w, why in cov_mistakes
                     if not np.allclose(w, w.T, rtol=1e-9, atol=1e-12)]
    return (mu_x, mu_y, Sxx, Sxy, Syy, y), mean, cov, mean_mistakes, cov_mistakes


def _call_conditional(fn, args):
    """The learner's (mean, cov), with a hint on a shape error or a swapped order."""
    n, m = len(args[0]), len(args[1])
    try:
        result = call(fn, *args)
    except CheckFailed as exc:
        raise _shape_hint(exc, f"n = {n}, m = {m}", _CONDITIONAL_SHAPE_HINT) from None
    mean, cov = _tuple(result, 2, "(mean, cov)", "gaussian_conditional")
    if np.ndim(mean) == 2 and np.ndim(cov) == 1:
        raise CheckFailed("gaussian_conditional returned (cov, mean): the order is (mean, cov)")
    return mean, cov


@check
def check_conditional_mean(gaussian_conditional):
    """The mean of the learner's ``gaussian_conditional(mu_x, mu_y, Sxx, Sxy, Syy, y)``."""
    for args, mean, _, mistakes, _ in _conditional_cases():
        got, _ = _call_conditional(gaussian_conditional, args)
        expect_close(got, mean, f"conditional mean (n = {len(mean)}, m = {len(args[1])})",
                     mistakes=mistakes,
                     hint=_about("the conditional mean corrects μ_x by how far y is from its mean, "
                                 "weighted through the covariances", "4", CONDITIONAL_MEAN))


@check
def check_conditional_covariance(gaussian_conditional):
    """The covariance of the learner's ``gaussian_conditional``: the Schur complement of Σ_yy."""
    for args, _, cov, _, mistakes in _conditional_cases():
        n, m = cov.shape[0], len(args[1])
        _, got = _call_conditional(gaussian_conditional, args)
        what = f"conditional covariance (n = {n}, m = {m})"
        arr = as_array(got, what)
        if n != m and arr.shape == (m, m):
            raise CheckFailed(f"{what} has shape {arr.shape}, the size of y: the covariance of x "
                              f"given y is (n, n) = ({n}, {n}) (not the covariance of y given x; "
                              "lecture 02 §4): " + CONDITIONAL_COV)
        expect_close(arr, cov, what, mistakes=mistakes,
                     hint=_about("the conditional covariance is the Schur complement of Σ_yy", "3 and §4",
                                 CONDITIONAL_COV))
        expect_symmetric(arr, what)


# ---------------------------------------------------------------------------------------
# the linear map, with a noise that is correlated with x
# ---------------------------------------------------------------------------------------

_LINEAR_SHAPE_HINT = ("with n ≠ m the shapes do not fit, so a matrix is transposed somewhere: G "
                      "is (m, n), Σ_xn = E[(x − μ_x) nᵀ] is (n, m), Σ_yy is (m, m) and Σ_xy is (n, m) "
                      "(lecture 02 §5): " + hints.formula("the cross terms of Σ_yy are G Σ_xn, of shape (m, m), "
                                                          "and its transpose Σ_xnᵀ Gᵀ; Σ_xy = Σ_xx Gᵀ + Σ_xn"))

#: How strongly the cases correlate x and the noise: Σ_xn = Σ_xx^½ K R^½ with the spectral norm
#: of K equal to this (below 1, so that the covariance of [x; n] stays positive definite), and
#: the range it is drawn from under a run seed.
CORRELATION = 0.7
CORRELATION_DRAWN = (0.5, 0.85)


def linear_map_moments_reference(mu_x, Sigma_xx, G, R, Sigma_xn):
    """Moments of y = G x + n when the noise n ~ N(0, R) is correlated with x.

    Expanding the expectations as lecture 02 §5 does, but keeping the cross terms that the
    independence of x and n removes there:

    .. math::

        \\mu_y = G\\mu_x, \\qquad
        \\Sigma_{yy} = G\\Sigma_{xx}G^T + G\\Sigma_{xn} + \\Sigma_{xn}^T G^T + R, \\qquad
        \\Sigma_{xy} = \\Sigma_{xx}G^T + \\Sigma_{xn}.

    Parameters
    ----------
    mu_x : array_like, shape (n,)
        Mean of x.
    Sigma_xx : array_like, shape (n, n)
        Covariance of x.
    G : array_like, shape (m, n)
        The linear map.
    R : array_like, shape (m, m)
        Covariance of the noise n (zero mean).
    Sigma_xn : array_like, shape (n, m)
        Cross-covariance E[(x − μ_x) nᵀ] of x and the noise.

    Returns
    -------
    mu_y : ndarray, shape (m,)
    Sigma_yy : ndarray, shape (m, m), symmetric
    Sigma_xy : ndarray, shape (n, m)

    Raises
    ------
    ValueError
        If a shape does not match (``Sigma_xn`` named), or ``Sigma_xx`` or ``R`` is not a
        covariance.
    """
    mu_y, Syy, Sxy = gaussians.linear_map(mu_x, Sigma_xx, G, R)
    Sigma_xn = np.asarray(Sigma_xn, dtype=float)
    if Sigma_xn.shape != Sxy.shape:
        raise ValueError(f"Sigma_xn must have shape (n, m) = {Sxy.shape}, got {Sigma_xn.shape}")
    cross = np.asarray(G, dtype=float) @ Sigma_xn                 # G Σ_xn, (m, m)
    return mu_y, symmetrise(Syy + cross + cross.T), Sxy + Sigma_xn


@functools.cache
def _linear_cases():
    """Each case: (args, (mu_y, Syy, Sxy), mistakes for mu_y, Syy, Sxy). The first is square
    with a non-symmetric G and a diagonal, anisotropic R (noise σ = 0.2 and 1.5, so √R, R
    and R R all differ); then n > m with full R, n > m with m = 1, and n < m. In every case
    the noise is correlated with x (:data:`CORRELATION`) through a dense Σ_xn, so that G Σ_xn
    is not symmetric and leaving out a cross term, or transposing one, changes Σ_yy.

    Under a run seed each is drawn from another stream, the square case's σ in 0.1–0.5 and
    1.3–3 (in a drawn order) and the correlation from :data:`CORRELATION_DRAWN`; fixed or
    drawn, a case is drawn again while a mistake is a near miss (:func:`_near_miss`)."""
    rng = inputs.rng("gaussians.linear", 21)
    out = []
    for n, m in ((2, 2), (3, 2), (4, 1), (2, 3)):
        while True:
            square_sigmas, correlation = (0.2, 1.5), CORRELATION
            if inputs.drawing():
                square_sigmas = rng.permutation([inputs.log_uniform(rng, 0.1, 0.5),
                                                 inputs.log_uniform(rng, 1.3, 3.0)])
                correlation = float(rng.uniform(*CORRELATION_DRAWN))
            case = _linear_case(rng, n, m, square_sigmas, correlation)
            if case is not None and _separated(zip(case[1], case[2])):
                break
        out.append(case)
    return out


def _noise_mistakes(GSG, R, cross_terms, m: int):
    """The wrong ways to add the noise's covariance R to G Σ_xx Gᵀ (with the cross terms
    ``cross_terms`` right), each with its hint."""
    full = GSG + cross_terms
    out = [
        (full, _about("R is missing: the observation noise adds its covariance", "5", MAPPED_COV)),
        (full + R @ R, "R is already a covariance (variances): add R, not R R (do not square "
                       "it; lecture 02 §5)"),
        (full + _sqrtm(R), "R holds variances: add R, not its square root (a standard "
                           "deviation; lecture 02 §5)"),
        (full + np.linalg.inv(R), "add the noise covariance R itself, not R⁻¹ (lecture 02 §5)"),
        (full - R, "sign: the noise adds its covariance, + R (lecture 02 §5)"),
        (R, "Σ_yy is only the noise: the uncertainty of x, carried through the map G, adds "
            "to it, and so do the cross terms of the correlation (lecture 02 §5)"),
        (R + cross_terms, "Σ_yy is only the noise and the cross terms: the uncertainty of x, "
                          "carried through the map G, adds to them (lecture 02 §5)"),
    ]
    if not np.allclose(R, np.diag(np.diag(R))):
        out += [
            (full + np.diag(np.diag(R)), "only the diagonal of R was added: the noise "
                                         "components are correlated, add the whole R"),
            (full + R ** 2, "R is already a covariance (variances): add R, do not square it"),
        ]
    if not np.allclose(R, np.eye(m)):
        out.append((full + np.eye(m), "the noise covariance is R, not the identity"))
    with np.errstate(invalid="ignore"):
        root = np.sqrt(R)                                    # element-wise: NaN off-diagonal < 0
    if np.all(np.isfinite(root)):
        out.append((full + root, "R holds variances: add R, not its element-wise square root "
                                 "(a standard deviation)"))
    return out


def _correlated(expectation: str) -> str:
    """What a hint for the formulas of an independent noise says: expand ``expectation``."""
    return (f"here the noise is correlated with x (Σ_xn ≠ 0): expand {expectation} as §5 does and keep "
            "the terms that independence made zero there")


def _linear_case(rng: np.random.Generator, n: int, m: int, square_sigmas, correlation: float):
    """One case of :func:`_linear_cases`, drawn from ``rng``; ``square_sigmas`` are the noise
    standard deviations of the square case's diagonal R, ``correlation`` the spectral norm of
    the K in Σ_xn = Σ_xx^½ K R^½. None when the drawn Σ_xx is not well inside the positive
    definite matrices (it is drawn again)."""
    A = rng.normal(size=(n, n))
    Sxx = np.diag(rng.uniform(0.3, 3.0, n)) @ (A @ A.T + 0.3 * np.eye(n)) @ \
        np.diag(rng.uniform(0.3, 3.0, n))
    Sxx = symmetrise(Sxx)
    eigenvalues = np.linalg.eigvalsh(Sxx)
    if eigenvalues[0] < 1e-3 * eigenvalues[-1]:
        return None     # the two scalings of A Aᵀ + 0.3 I can make it indefinite: draw again
    mu_x = rng.normal(size=n)
    G = rng.normal(size=(m, n))
    if (n, m) == (2, 2):
        R = np.diag(np.square(square_sigmas))
    else:
        B = rng.normal(size=(m, m)) * rng.uniform(0.2, 2.0, m)[:, None]
        R = B @ B.T + 0.2 * np.eye(m)
    K = rng.normal(size=(n, m))
    Sxn = _sqrtm(Sxx) @ (correlation / np.linalg.norm(K, 2) * K) @ _sqrtm(R)
    mu_y, Syy, Sxy = linear_map_moments_reference(mu_x, Sxx, G, R, Sxn)
    GSG = G @ Sxx @ G.T
    cross = G @ Sxn                                           # G Σ_xn, (m, m), not symmetric
    cross_terms = cross + cross.T
    syy_mistakes = _noise_mistakes(GSG, R, cross_terms, m) + [
        (GSG + R, _about(_correlated("E[(y − μ_y)(y − μ_y)ᵀ]") + "; you added the noise as if it were "
                         "independent of x", "5",
                         MAPPED_COV)),
        (GSG, _about("R is missing, and so are the cross terms of the noise's correlation with x: the "
                     "noise adds both", "5", MAPPED_COV)),
        (GSG + cross + R, _about("only one of the two cross terms: E[G (x − μ_x) nᵀ] and its "
                                 "transpose E[n (x − μ_x)ᵀ Gᵀ] are both in the expansion", "5", MAPPED_COV)),
        (GSG + cross.T + R, _about("only one of the two cross terms: E[n (x − μ_x)ᵀ Gᵀ] and its "
                                   "transpose E[G (x − μ_x) nᵀ] are both in the expansion", "5", MAPPED_COV)),
        (GSG + 0.5 * cross_terms + R,
         _about("half of the cross terms: one of the two was left out and the symmetrisation halved the "
                "other; both are in the expansion", "5", MAPPED_COV)),
        (GSG + 2.0 * cross + R, _about("the two cross terms are transposes of each other, not equal: "
                                       "G Σ_xn is not symmetric", "5", MAPPED_COV)),
        (GSG + 2.0 * cross.T + R, _about("the two cross terms are transposes of each other, not equal: "
                                         "Σ_xnᵀ Gᵀ is not symmetric", "5", MAPPED_COV)),
        (GSG - cross_terms + R, _about("sign: the cross terms come from expanding a product of sums, each "
                                       "with a plus", "5", MAPPED_COV)),
        (GSG + 2.0 * cross_terms + R, _about("the cross terms were counted twice: each of the two appears "
                                             "once in the expansion", "5", MAPPED_COV)),
    ]
    sxy_mistakes = [
        (Sxx @ G.T, _about(_correlated("E[(x − μ_x)(y − μ_y)ᵀ]") + ": E[(x − μ_x) nᵀ] = Σ_xn is not "
                           "zero", "5", CROSS_COV)),
        (Sxx @ G.T - Sxn, _about("sign: Σ_xy adds E[(x − μ_x) nᵀ] = Σ_xn", "5", CROSS_COV)),
        (Sxx, _about("the map G must appear in Σ_xy, and so must the correlation of x and the noise", "5",
                     CROSS_COV)),
        ((Sxx @ G.T + Sxn) @ np.linalg.inv(Syy), _about("that is the gain Σ_xy Σ_yy⁻¹ of the next chapter, "
                                                       "not the cross-covariance", "5", CROSS_COV)),
        (Sxx @ G.T + 2.0 * Sxn, _about("Σ_xn counted twice in Σ_xy: (x − μ_x)(y − μ_y)ᵀ has one term in "
                                       "(x − μ_x) nᵀ", "5", CROSS_COV)),
    ]
    mu_mistakes = []
    if n == m:
        swapped = G @ Sxn.T                                   # the Σ_xn transposed
        syy_mistakes += [
            (G.T @ Sxx @ G + cross_terms + R, _about("G and Gᵀ are swapped (transposed)", "5", MAPPED_COV)),
            (G @ Sxx @ G + cross_terms + R, _about("the transpose of the last G is missing", "5", MAPPED_COV)),
            (GSG + G @ R @ G.T + cross_terms,
             "the noise was pushed through the map: in y = G x + n the noise is added after the "
             "map, in the measurement's own axes and units (R is m × m), so R is added as it is, "
             "not as G R Gᵀ"),
            (Sxx + Sxn + Sxn.T + R, _about("the map G must appear in Σ_yy, also in its cross terms", "5",
                                           MAPPED_COV)),
            (GSG + swapped + swapped.T + R,
             _about("Σ_xn is transposed in the cross terms: Σ_xn = E[(x − μ_x) nᵀ] has shape (n, m), so "
                    "E[G (x − μ_x) nᵀ] = G Σ_xn", "5", MAPPED_COV)),
            (GSG + G.T @ Sxn + Sxn.T @ G + R,
             _about("Gᵀ stands where G belongs in the cross terms: y − μ_y = G (x − μ_x) + n", "5",
                    MAPPED_COV)),
            (GSG + Sxn + Sxn.T + R,
             _about("the map is missing from the cross terms: x enters y only through G", "5", MAPPED_COV)),
        ]
        sxy_mistakes += [
            (G @ Sxx + Sxn.T, "that is Σ_yx = G Σ_xx + Σ_xnᵀ, the transpose of Σ_xy: Σ_xy = "
                              "E[(x − μ_x)(y − μ_y)ᵀ] has one row per component of x and one "
                              "column per component of y, shape (n, m)"),
            (G @ Sxx + Sxn, "G Σ_xx is Σ_yx's first term, the transpose of Σ_xx Gᵀ: Σ_xy = "
                            "E[(x − μ_x)(y − μ_y)ᵀ] has one row per component of x, shape (n, m)"),
            (Sxx + Sxn, _about("the map G must appear in Σ_xy", "5", CROSS_COV)),
            (G.T @ Sxx + Sxn, _about("Σ_xx comes first (Gᵀ Σ_xx is another matrix)", "5", CROSS_COV)),
            (Sxx @ G.T + Sxn.T, _about("Σ_xn is transposed: Σ_xy takes E[(x − μ_x) nᵀ] = Σ_xn, shape (n, m), "
                                       "not Σ_nx = Σ_xnᵀ", "5", CROSS_COV)),
            (Sxx @ G.T + Sxn + R, _about("R is the noise's own covariance: it is no part of Σ_xy", "5",
                                         CROSS_COV)),
            (Sxx @ G.T + G @ Sxn, _about("the noise is added after the map: E[(x − μ_x) nᵀ] is Σ_xn itself, "
                                         "G does not multiply it", "5", CROSS_COV)),
            (Sxx @ G.T + Sxn @ G.T, _about("the noise is added after the map: E[(x − μ_x) nᵀ] is Σ_xn itself, "
                                           "Gᵀ does not multiply it", "5", CROSS_COV)),
        ]
        mu_mistakes += [
            (mu_x, _about("the mean goes through the map", "5", hints.formula("μ_y = G μ_x"))),
            (G.T @ mu_x, _about("G is transposed", "5", hints.formula("μ_y = G μ_x"))),
        ]
    return (mu_x, Sxx, G, R, Sxn), (mu_y, Syy, Sxy), (mu_mistakes, syy_mistakes, sxy_mistakes)


def _close(a, b) -> bool:
    """True when ``a`` and ``b`` are numeric arrays of one shape and equal to the default
    tolerance; False for anything that is not numeric (compared later, with a message)."""
    try:
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    except (TypeError, ValueError):
        return False
    return a.shape == b.shape and np.allclose(a, b, rtol=1e-7, atol=1e-9)


@check
def check_linear_map_moments(linear_map_moments):
    """The learner's ``linear_map_moments(mu_x, Sigma_xx, G, R, Sigma_xn)`` returns (mu_y, Sigma_yy,
    Sigma_xy) of y = G x + n, for a noise n correlated with x (cross-covariance Σ_xn)."""
    for args, (mu_y, Syy, Sxy), (mu_mistakes, syy_mistakes, sxy_mistakes) in _linear_cases():
        n, m = Sxy.shape
        sizes = f"n = {n}, m = {m}"
        try:
            result = call(linear_map_moments, *args)
        except CheckFailed as exc:
            if "positional argument" in str(exc):
                raise CheckFailed(f"{exc}. Hint: linear_map_moments takes five arguments, (mu_x, Sigma_xx, "
                                  "G, R, Sigma_xn): the last is the cross-covariance E[(x − μ_x) nᵀ] of x "
                                  "and the noise, shape (n, m)") from None
            raise _shape_hint(exc, sizes, _LINEAR_SHAPE_HINT) from None
        got_mu, got_syy, got_sxy = _tuple(result, 3, "(mu_y, Sigma_yy, Sigma_xy)", "linear_map_moments")
        mu_x, Sxx = args[0], args[1]
        if _close(got_mu, mu_x) and _close(got_syy, Sxx):     # the exercise's placeholder
            raise CheckFailed(f"you returned the moments of x itself ({sizes}), as if the sensor read "
                              "x directly and without noise: y = G x + n has m components; push the "
                              "mean and the covariance of x through the map G, add what the noise and "
                              "its correlation with x bring, and give the cross-covariance of x and y "
                              "(lecture 02 §5)")
        try:
            if _close(got_syy, Sxy) and _close(got_sxy, Syy):
                raise CheckFailed("Sigma_yy and Sigma_xy are swapped: the order is "
                                  "(mu_y, Sigma_yy, Sigma_xy)")
        except (TypeError, ValueError):                  # non-numeric: compared below
            pass
        expect_close(got_mu, mu_y, f"mu_y ({sizes})", mistakes=mu_mistakes,
                     hint=_about("the noise has zero mean, so the mean of y is the mean of x carried "
                                 "through the map (the correlation changes no mean)", "5",
                                 hints.formula("μ_y = G μ_x")))
        expect_close(got_syy, Syy, f"Sigma_yy ({sizes})", mistakes=syy_mistakes,
                     hint=_about("Σ_yy is the covariance of x carried through the map G, plus the "
                                 "noise's, plus the two cross terms of their correlation", "5", MAPPED_COV))
        arr = as_array(got_sxy, f"Sigma_xy ({sizes})")
        if n != m and arr.shape == (m, n):
            raise CheckFailed(f"Sigma_xy ({sizes}) has shape {arr.shape}: that is Σ_yx = G Σ_xx + Σ_xnᵀ, "
                              f"its transpose; Σ_xy has shape (n, m) = ({n}, {m}) (lecture 02 §5): "
                              + CROSS_COV)
        expect_close(arr, Sxy, f"Sigma_xy ({sizes})", mistakes=sxy_mistakes,
                     hint=_about("Σ_xy = E[(x − μ_x)(y − μ_y)ᵀ] is the cross-covariance of x and y, shape "
                                 "(n, m); expand it as Σ_yy", "5", CROSS_COV))


# ---------------------------------------------------------------------------------------
# fusing two estimates (optional challenge)
# ---------------------------------------------------------------------------------------

#: (n, seed, spread) of the fusion cases, and the range each spread is drawn from under a run
#: seed: two estimates of about one size, then one 5 and one 30 times less certain.
_FUSION_CASES = ((2, 51, 1.0, (0.7, 1.5)), (3, 52, 5.0, (3.0, 8.0)), (2, 53, 30.0, (20.0, 50.0)))


@functools.cache
def _fusion_cases():
    """Each case: (args, mean, cov, cov mistakes, mean mistakes). Two 2-D estimates whose
    ellipses point different ways, a 3-D pair with scales from 0.2 to 5, and a pair in which
    one estimate is far less certain than the other (the fused one stays near the better).
    No case is one-dimensional or diagonal: there the scalar formulas would be right.

    Under a run seed each pair is drawn from another stream with its spread drawn from its
    range in :data:`_FUSION_CASES`, and drawn again while a mistake is a near miss."""
    out = []
    for n, seed, spread, spread_range in _FUSION_CASES:
        rng = inputs.rng("gaussians.fusion", seed)
        while True:
            if inputs.drawing():
                spread = float(inputs.log_uniform(rng, *spread_range))
            case = _fusion_case(rng, n, spread)
            _, mean, cov, cov_mistakes, mean_mistakes = case
            if not inputs.drawing() or _separated(((cov, cov_mistakes), (mean, mean_mistakes))):
                break
        out.append(case)
    return out


def _fusion_case(rng: np.random.Generator, n: int, spread: float):
    """One case of :func:`_fusion_cases`, drawn from ``rng``: Σ_b is about ``spread`` times Σ_a."""
    covs = []
    for scale in (1.0, spread):
        A = rng.normal(size=(n, n))
        D = np.diag(rng.uniform(0.2, 2.0, n))
        covs.append(symmetrise(scale * D @ (A @ A.T + 0.3 * np.eye(n)) @ D))
    Sa, Sb = covs
    mu_a, mu_b = rng.normal(size=n), 3.0 * rng.normal(size=n)
    mean, cov = gaussians.product(mu_a, Sa, mu_b, Sb)
    K_swapped = np.linalg.solve(Sa + Sb, Sb).T              # Σ_b (Σ_a + Σ_b)⁻¹
    elementwise = 1.0 / (1.0 / Sa + 1.0 / Sb)
    cov_mistakes = [
        (elementwise, "1 / Σ is not the inverse of a covariance matrix: the one-dimensional "
                      "formula 1 / (1/σ_a² + 1/σ_b²) does not work element by element. "
                      "Information (the inverse covariance, a matrix inverse) adds up, or "
                      "use the conditioning you wrote above with G = I"),
        (Sa + Sb, "covariances add for a sum of two independent variables, not when two "
                  "estimates of the same x are fused: the fused covariance is smaller than "
                  "both"),
        (0.5 * (Sa + Sb), "an average of the covariances: the fused covariance is smaller "
                          "than both, since each estimate adds information"),
        (np.linalg.inv(Sa + Sb), "the inverse of the sum is not the sum of the inverses: "
                                 "the inverses (the information) add up"),
        (Sa, "the covariance did not shrink: the second estimate adds information"),
        (symmetrise(Sa - K_swapped @ Sa),
         _about("the weights are swapped: moving from estimate a towards b, the gain grows with a's "
                "uncertainty", "6", hints.formula("Σ_a (Σ_a + Σ_b)⁻¹ (b's gain, Σ_b (Σ_a + Σ_b)⁻¹, "
                                                  "moves from b towards a)"))),
        (symmetrise(Sa @ Sb @ np.linalg.inv(Sa + Sb)),
         _about("the factors are in the wrong order (matrix products do not commute)", "6",
                hints.formula("the gain Σ_a (Σ_a + Σ_b)⁻¹ multiplies Σ_b from the left"))),
    ]
    mean_mistakes = [
        (elementwise @ (mu_a / np.diag(Sa) + mu_b / np.diag(Sb)),
         "each mean was weighed by its variances alone, as in the one-dimensional formula "
         "applied element by element: weigh it by the whole inverse covariance"),
        (cov @ (mu_a / np.diag(Sa) + mu_b / np.diag(Sb)),
         "each mean was weighed by its variances alone (element by element): weigh it by "
         "the whole inverse covariance, the information matrix"),
        (0.5 * (mu_a + mu_b), "the plain average ignores how certain each estimate is: the "
                              "fused mean lies nearer the more certain one"),
        (mu_a + K_swapped @ (mu_b - mu_a), "the weights are swapped: the fused mean moves "
                                           "towards the more certain estimate, not the "
                                           "less certain one"),
        (mu_a, "the mean did not move: the second estimate must pull it"),
    ]
    return (mu_a, Sa, mu_b, Sb), mean, cov, cov_mistakes, mean_mistakes


@check
def check_gaussian_fusion(gaussian_fusion):
    """The learner's ``gaussian_fusion(mu_a, Sigma_a, mu_b, Sigma_b)``: the normalised product
    of two Gaussian densities of the same x, returned as (mean, cov)."""
    for args, mean, cov, cov_mistakes, mean_mistakes in _fusion_cases():
        n = len(mean)
        result = call(gaussian_fusion, *args)
        got_mean, got_cov = _tuple(result, 2, "(mean, cov)", "gaussian_fusion")
        if np.ndim(got_mean) == 2 and np.ndim(got_cov) == 1:
            raise CheckFailed("gaussian_fusion returned (cov, mean): the order is (mean, cov)")
        expect_close(got_cov, cov, f"fused covariance (n = {n})", mistakes=cov_mistakes,
                     hint="the fused belief is the normalised product of the two densities; "
                          "lecture 02 §6 shows it is conditioning with G = I")
        expect_symmetric(got_cov, f"fused covariance (n = {n})")
        expect_close(got_mean, mean, f"fused mean (n = {n})", mistakes=mean_mistakes,
                     hint="the fused mean is the conditional mean of x given that the second "
                          "estimate observed it: lecture 02 §6 with G = I")
