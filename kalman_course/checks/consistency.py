"""Checks for chapter 09: NEES, NIS, chi-square bounds, the innovation gate, a verdict, and
(the optional challenge) the Monte Carlo NEES test.

Every case of the core checks comes from the reference ESKF on the KITTI ``cruise``
excerpt: pose and navigation-state errors and covariances of the shipped run, priors at
held-out lidar poses, innovations of the run with seeded map-matching failures, and NIS
records of three noise settings. Some cases re-express those quantities in mixed
coordinates (a seeded, non-symmetric, non-orthogonal matrix A: e → A e, P → A P Aᵀ), which
leaves every correct NEES/NIS unchanged but makes covariances strongly correlated and
observation matrices square, so that a dropped correlation or a misplaced transpose
changes the value instead of only the shape. The challenge's cases are NEES records of
seeded Monte Carlo runs of the ESKF on simulated IMU trajectories with exact truth
(lecture 09 §2).

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every family is drawn anew:
the NEES cases at other steps of the run and the NIS cases at other held-out poses, both
with the navigation and body frames turned by drawn rotations (e_p → C e_p, δθ → Bᵀ δθ: the
same run in other axes, so P stays strongly correlated); the mixing matrices; the gate's
map-matching failures (another outlier seed) and its innovations, turned alike (redrawn
until every listed mistake decides differently from the reference and from the others);
the verdict's three settings (Q and R factors drawn around 1, 1/4 and 4, each redrawn until
its record keeps its verdict and its distance from the bounds); the interval's (dof, n_runs,
confidence) with the same spread; and the seed of the Monte Carlo runs and which 5 of them
the short cases take (the 5 redrawn until every listed mistake decides differently; a step
whose run average lies within 1e-4 of a bound is left out). Real and simulated, as in the
self-check: the NEES, NIS and verdict cases are the reference filter on the real KITTI
cruise excerpt (turned, mixed or rescaled); the gate's run is real but its map-matching
failures are injected; the Monte Carlo runs are wholly simulated.

A learner's function is run on every case before anything is judged, and a known mistake
is named only when it reproduces the learner's results on all cases (a wrong formula
may agree with the right one on a single case; :func:`harness.known_mistake`), so each hint
names the mistake made. Hints name the concept, the mistake and the lecture section at tier 1
and keep the formula for tier 2 (:mod:`kalman_course.checks.hints`).
"""

from __future__ import annotations

import functools
import math
from typing import Callable

import numpy as np

from kalman_course.chapters import consistency
from kalman_course.filters import eskf
from kalman_course.evaluation import metrics
from kalman_course.evaluation import consistency as consistency_stats
from kalman_course.evaluation.pose import POSE_INDEX, evaluate
from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.checks import hints
from kalman_course.checks.harness import CheckFailed, call, check, known_mistake, type_name
from kalman_course.core import so3
from kalman_course.data import load_kitti
from kalman_course.filters.eskf_config import load_config

#: The excerpt the checks run on, the outlier seed and the verdict cases (label, Q factor, R factor).
EXCERPT = "cruise"
OUTLIER_SEED = 0
VERDICT_SETTINGS = (("reference", 1.0, 1.0), ("R / 4", 1.0, 0.25), ("R x 4", 1.0, 4.0))
#: Under a run seed, each verdict setting's drawn ranges of the Q and R factors and the verdict
#: its records keep (the reference stays consistent within ±7 %, so R moves by less).
VERDICT_DRAWN = (((0.8, 1.25), (0.93, 1.07), "consistent"), ((0.8, 1.25), (0.18, 0.35), "overconfident"),
                 ((0.8, 1.25), (2.8, 5.5), "underconfident"))
#: Seed of the mixing matrices of the re-expressed cases.
MIXING_SEED = 9

#: Relative tolerance of the NEES, NIS and interval checks. Every correct way of writing them
#: (solve, inv, pinv, Cholesky, einsum, scipy's χ² quantiles) agrees to ~1e-12 relative on
#: these cases; every wrong formula in the catalogues is off by at least 2 % on some case (the
#: closest: the Wilson–Hilferty approximation of the interval, 2.5 %; dropping the
#: correlations of S, 22 %), so 1e-6 separates the two by orders of magnitude.
RTOL = 1e-6


# --------------------------------------------------------------------------------------
# cases
# --------------------------------------------------------------------------------------

def _mixing(n: int, seed: int, family: str) -> np.ndarray:
    """A seeded, well-conditioned, non-symmetric and non-orthogonal n × n matrix (drawn anew
    under a run seed, one stream per ``family``)."""
    rng = inputs.rng(f"consistency.{family}.mixing", [MIXING_SEED, n, seed])
    A = np.eye(n) + 0.6 * rng.standard_normal((n, n))
    while np.linalg.cond(A) > 30:           # keep the re-expressed cases well conditioned
        A = np.eye(n) + 0.6 * rng.standard_normal((n, n))
    return A


def _turned(generator: np.random.Generator) -> np.ndarray:
    """T (15, 15) that re-expresses the error state [δp, δv, δθ, δb_a, δb_ω] in navigation and
    body frames turned by drawn rotations C and B: δp, δv → C δp, C δv (navigation frame),
    δθ, δb_a, δb_ω → Bᵀ · (body frame), and P → T P Tᵀ.

    The same run in other axes: a correct NEES or NIS is unchanged (T is orthogonal, and the
    lidar's R, isotropic per block, is unchanged by it), but every input is new, and rotations
    about arbitrary axes keep P as correlated as in the run's own axes (they spread each
    block's correlations over all of its entries).
    """
    C, B = so3.exp(generator.normal(size=3)), so3.exp(generator.normal(size=3))
    T = np.zeros((15, 15))
    for i, M in enumerate((C, C, B.T, B.T, B.T)):
        T[3 * i:3 * i + 3, 3 * i:3 * i + 3] = M
    return T


#: Where a turned run's label says so (see :func:`_turned`).
_TURNED = " (navigation and body frames turned)"


@functools.lru_cache(maxsize=None)
def _reference_run():
    ex = load_kitti(EXCERPT)
    k0, s0 = ex.initial_state()
    res = eskf.run(ex.imu, s0, load_config("kitti_lidar"), ex.gravity, lidar=ex.lidar, start=k0)
    return ex, res


@functools.lru_cache(maxsize=None)
def nees_cases():
    """(label, error, P) triples of the reference run at three times.

    Per time: the 6-dof pose error, the 3-dof position error, the 6-dof position-velocity
    error (position and velocity errors correlate at ~0.7 in P, so dropping the
    off-diagonal of P changes the NEES by tens of percent), and the pose error in mixed
    coordinates; once, the 1-dof heading error. Under a run seed: three other steps, in
    turned frames (:func:`_turned`; the heading is then about the turned body's z axis).
    """
    ex, res = _reference_run()
    m = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
    dv = res.velocity - ex.truth.interpolate(res.t).velocity
    # [δp, δv, δθ] of every step and its covariance, the first 9 error states
    err = np.concatenate([m["position_error"], dv, m["attitude_error"]], axis=1)
    cov = np.asarray(res.P)[:, :9, :9]
    steps, turned = np.linspace(5, len(res.t) - 1, 3).astype(int), ""
    if inputs.drawing():
        g = inputs.rng("consistency.nees", 0)
        steps = np.sort(g.choice(np.arange(5, len(res.t)), 3, replace=False))
        T = _turned(g)[:9, :9]
        err, cov, turned = err @ T.T, T @ cov @ T.T, _TURNED
    pv = np.r_[0:6]
    cases = []
    for j, k in enumerate(steps):
        e6, P6 = err[k, POSE_INDEX], cov[k][np.ix_(POSE_INDEX, POSE_INDEX)]
        cases.append((f"the 6-dof pose error at step {k}{turned}", e6, P6))
        cases.append((f"the 3-dof position error at step {k}{turned}", e6[:3], P6[:3, :3]))
        cases.append((f"the 6-dof position-velocity error at step {k}{turned}", err[k, pv], cov[k][np.ix_(pv, pv)]))
        A = _mixing(6, j, "nees")
        cases.append((f"the 6-dof pose error at step {k} in mixed coordinates", A @ e6, A @ P6 @ A.T))
        if j == 0:   # one 1-dof case: no correlations, so even element-wise functions of P are finite
            cases.append((f"the 1-dof heading error at step {k}{turned}", e6[5:], P6[5:, 5:]))
    return tuple(cases)


@functools.lru_cache(maxsize=None)
def prior_cases():
    """(label, innovation, P_check, G, R) at held-out lidar poses.

    The filter uses every other pose; at the poses in between, its row is a prior (no
    update there), so the pose residual against the held-out pose is a true innovation.
    The first cases observe the 6-dof pose block of the prior through a square,
    non-symmetric G with a non-diagonal R (the residual in mixed coordinates), where
    G P̌ Gᵀ, Gᵀ P̌ G and G P̌ G all have the same shape but different values; the rest are the
    KITTI lidar update itself: G (6, 15) and R = diag(σ²) with σ = 0.2 m and 0.3°. Under a
    run seed: six other held-out poses, the run in turned frames (:func:`_turned`; G and R
    are unchanged by it).
    """
    ex = load_kitti(EXCERPT)
    k0, s0 = ex.initial_state()
    cfg = load_config("kitti_lidar")
    lid = ex.lidar
    used = lid.select(slice(None, None, 2))
    held = np.arange(1, len(lid.t), 2)
    res = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=used, start=k0, output_times=lid.t[held])
    R = np.diag(cfg.lidar_std ** 2)
    G = np.array(eskf.POSE_G)
    rows, turned = held[np.linspace(3, len(held) - 2, 6).astype(int)], ""
    if inputs.drawing():
        g = inputs.rng("consistency.nis", 0)
        rows = np.sort(g.choice(held[3:len(held) - 1], 6, replace=False))
        T, turned = _turned(g), _TURNED
    kitti, square = [], []
    for n, j in enumerate(rows):
        r = int(np.searchsorted(res.t, lid.t[j] - 1e-9))
        y = eskf.pose_residual(res.position[r], res.rotation[r], lid.position[j], lid.rotation[j])
        P = res.P[r]
        if turned:   # G T = T₆ G: the residual turns with the pose rows of T
            y, P = T[np.ix_(POSE_INDEX, POSE_INDEX)] @ y, T @ P @ T.T
        kitti.append((f"the KITTI lidar innovation at t = {lid.t[j]:.1f} s (G 6×15){turned}", y, P, G, R))
        if n < 3:
            A = _mixing(6, 10 + n, "nis")
            P6 = P[np.ix_(POSE_INDEX, POSE_INDEX)]
            # ν' = A ν = A (G' δx) with δx the pose error: G' = A (square), R' = A R Aᵀ
            square.append((f"the lidar innovation at t = {lid.t[j]:.1f} s in mixed coordinates "
                           "(square, non-symmetric G 6×6)", A @ y, P6, A, A @ R @ A.T))
    return tuple(square + kitti)


def _rescaled(y, S, target):
    """The innovation y scaled so that its NIS with S is ``target``."""
    return y * math.sqrt(target / metrics.nis(y, S))


@functools.lru_cache(maxsize=None)
def gate_cases():
    """(innovation, S, confidence) for the outlier run, borderline and mixed cases.

    The outlier run's innovations at 99 %; innovations rescaled to lie just inside and just
    outside the 99 % gate, between the 95 % and the 99 % quantile (tested at 95 % too, so a
    confidence that is not taken from the argument shows), above the 99 % but below the
    99.5 % quantile, in the lower tail (below the 0.5 % quantile, which a two-sided
    test would reject), and at NIS 0.93 (below the confidence as a number, above the 1 %
    quantile); and outlier-run innovations in mixed coordinates, where S is
    strongly correlated (the NIS, hence the right decision, is unchanged). An innovation
    of the run whose NIS lies within 1 % of the gate is left out (none of the self-check's
    does), so that no way of rounding the NIS can flip a decision.

    Under a run seed: other map-matching failures (another outlier seed), and the whole run
    in turned frames (:func:`_turned`), from which every case is built as above; drawn again
    until every listed mistake decides differently from the reference and from every other
    (:func:`_gate_separates`: a run whose failures all stay within the gate's νᵀ ν would let
    the gate without S pass for one that accepts everything).
    """
    ex = load_kitti(EXCERPT)
    if not inputs.drawing():
        return _gate_cases_of(ex, OUTLIER_SEED, np.eye(6))
    g = inputs.rng("consistency.gate", 0)
    for _ in range(20):
        seed = int(g.integers(1, 2**31))           # never the self-check's OUTLIER_SEED (0)
        cases = _gate_cases_of(ex, seed, _turned(g)[np.ix_(POSE_INDEX, POSE_INDEX)])
        if _gate_separates(cases):
            return cases
    raise RuntimeError("no drawn outlier run gives gate cases that separate the listed mistakes")


def _gate_cases_of(ex, seed: int, T6: np.ndarray) -> tuple:
    """The gate cases of the run with the outliers of ``seed``, its innovations turned by T6."""
    bad, _ = consistency.inject_outliers(ex.lidar, seed)
    run = consistency.run_gated(ex, bad)
    innovation = [T6 @ y for y in run.innovation]
    covariance = [T6 @ S @ T6.T for S in run.S]
    q = metrics.chi2_ppf

    def clear(y, S, c):
        return abs(metrics.nis(y, S) / q(c, len(y)) - 1.0) >= 0.01

    cases = [(innovation[i], covariance[i], 0.99) for i in range(len(run.t))
             if clear(innovation[i], covariance[i], 0.99)]
    # (index, NIS as a multiple of a quantile (p), confidences to test it at)
    border = ((10, 0.97, 0.99, (0.99,)), (20, 1.03, 0.99, (0.99, 0.999)), (30, 0.9, 0.99, (0.99, 0.95)),
              (40, 1.1, 0.99, (0.99,)), (50, 0.99, 0.99, (0.99, 0.95)), (60, 0.5, 0.005, (0.99, 0.95)),
              (70, 0.97, 0.95, (0.95, 0.99)), (80, 1.02, 0.995, (0.99,)), (90, 0.93, None, (0.99,)),
              (100, 27.0, None, (0.99,)))
    for i, factor, p, confidences in border:
        for dims in (slice(0, 6), slice(0, 3)):
            y, S = innovation[i][dims], covariance[i][dims, dims]
            # p None: the NIS is `factor` itself (0.93: above the 1 % quantile, below 0.99;
            # 27: above q(0.99; 9) = 21.7, below m · q(0.99; m) for m = 3)
            y = _rescaled(y, S, factor * (1.0 if p is None else q(p, len(y))))
            cases.extend((y, S, c) for c in confidences)
    # NIS between consecutive 99 % quantiles, q(0.99; k) < NIS < q(0.99; k + 1) for k = 1 … 19:
    # any threshold with a wrong number of degrees of freedom shows which number it used
    for k in range(1, 20):
        for dims in (slice(0, 6), slice(0, 3)):
            y, S = innovation[110 + k][dims], covariance[110 + k][dims, dims]
            cases.append((_rescaled(y, S, 0.5 * (q(0.99, k) + q(0.99, k + 1))), S, 0.99))
    for n, i in enumerate(range(5, len(run.t), 12)):
        A = _mixing(6, 20 + n, "gate")
        y, S = A @ innovation[i], A @ covariance[i] @ A.T
        if clear(y, S, 0.99):
            cases.append((y, S, 0.99))
        if n < 8:        # and near the gate, where a NIS off by tens of percent flips decisions
            for factor in (0.5, 0.8, 1.25, 2.0):
                cases.append((_rescaled(y, S, factor * q(0.99, 6)), S, 0.99))
    return tuple(cases)


def _gate_separates(cases) -> bool:
    """Whether the reference and each of :func:`_gate_mistakes` decide differently from each other
    somewhere on ``cases``, so that each hint names its own mistake. νᵀ S ν is left out: its hint
    is the one of accepting everything, which names it too (S holds centimetres: νᵀ S ν is tiny)."""
    q = metrics.chi2_ppf
    values = [metrics.nis(y, S) for y, S, _ in cases]
    rules = [lambda v, m, c, y, S: v <= q(c, m)]
    rules += [decide for decide, why in _gate_mistakes() if not why.startswith(_GATE_BY_S)]
    decisions = {tuple(bool(rule(v, len(y), c, y, S)) for v, (y, S, c) in zip(values, cases)) for rule in rules}
    return len(decisions) == len(rules)


def _clear_verdict(values, dof, confidence, verdict) -> bool:
    """Whether a record's verdict is ``verdict`` with its mean at least 1 % from both bounds."""
    lo, hi = metrics.chi2_bounds(dof, len(values), confidence)
    mean = float(np.mean(values))
    return (consistency_stats.verdict(values, dof, confidence) == verdict
            and min(abs(mean / lo - 1.0), abs(mean / hi - 1.0)) >= 0.01)


@functools.lru_cache(maxsize=None)
def verdict_cases():
    """(label, NIS record (N,), dof, confidence) of the reference ESKF on the excerpt.

    The 6-dof pose NIS and the 3-dof position NIS of each verdict setting at 95 %, and
    records rescaled to means that separate the ways of misplacing N, dof and the
    confidence (see the comments).

    Under a run seed the three settings' Q and R factors are drawn (:data:`VERDICT_DRAWN`),
    each setting again until both its records keep their verdict with means at least 1 %
    from the bounds (the rescaled records are then built from the drawn reference).
    """
    ex = load_kitti(EXCERPT)
    k0, s0 = ex.initial_state()
    g = inputs.rng("consistency.verdict", 0)
    out = []
    for (label, qf, rf), (q_range, r_range, verdict) in zip(VERDICT_SETTINGS, VERDICT_DRAWN):
        for _ in range(100):
            if inputs.drawing():
                qf, rf = inputs.log_uniform(g, *q_range), inputs.log_uniform(g, *r_range)
                label = f"Q x {qf:.3f} and R x {rf:.3f}"
            res = eskf.run(ex.imu, s0, consistency.scaled_config("kitti_lidar", qf, rf), ex.gravity,
                           lidar=ex.lidar, start=k0)
            nu, S = np.array(res.innovation), np.array(res.S)
            records = [(f"the KITTI run with {label}", metrics.nis(nu, S), 6, 0.95),
                       (f"the KITTI run with {label}, position only", metrics.nis(nu[:, :3], S[:, :3, :3]), 3, 0.95)]
            if not inputs.drawing() or all(_clear_verdict(*r[1:], verdict) for r in records):
                break
        else:
            raise RuntimeError(f"no drawn Q and R factors in {q_range}, {r_range} give {verdict} records")
        out.extend(records)
    reference = out[0][1]
    N = len(reference)
    bounds = metrics.chi2_bounds
    # means between the 95 % and the 99.9 % bounds, judged at 99.9 % (the confidence argument:
    # at 95 % they are outside), and between the 90 % and the 95 % bounds (two tails of
    # (1 − c)/2, not 1 − c)
    for side, name in ((1, "above"), (0, "below")):
        target = 0.5 * (bounds(6, N, 0.95)[side] + bounds(6, N, 0.999)[side])
        out.append((f"a KITTI record rescaled to a mean just {name} its 95 % interval",
                    reference * (target / reference.mean()), 6, 0.999))
        target = 0.5 * (bounds(6, N, 0.95)[side] + bounds(6, N, 0.9)[side])
        out.append((f"a KITTI record rescaled to a mean just {name} the middle of its 95 % interval",
                    reference * (target / reference.mean()), 6, 0.95))
    # means 1 % outside each bound of the 95 % interval: a bound widened by a margin flips
    # one of these (1 % keeps them clear of round-off in any correct way of computing the
    # bounds; a narrowed bound is caught by the records just inside, above)
    lo, hi = bounds(6, N, 0.95)
    for target, where in ((0.99 * lo, "1 % below the lower"), (1.01 * hi, "1 % above the upper")):
        out.append((f"a KITTI record rescaled to a mean {where} bound of its 95 % interval",
                    reference * (target / reference.mean()), 6, 0.95))
    # ten values rescaled to means that separate the misplaced N's: 5.93 (inside the 95 %
    # interval, but below dof and outside the 5 % interval), 45 (inside the interval of the
    # SUM, F⁻¹(·; 60), but not of the mean's sum, F⁻¹(·; 600)/10)
    short = reference[:10]
    for mean in (5.93, 45.0):
        out.append((f"ten KITTI values rescaled to a mean of {mean}", short * (mean / short.mean()), 6, 0.95))
    # ... and to a mean between the upper 95 % bounds of 10 and of 9 values (N, not N − 1)
    mean = 0.5 * (bounds(6, 10, 0.95)[1] + bounds(6, 9, 0.95)[1])
    out.append((f"ten KITTI values rescaled to a mean of {mean:.3f}", short * (mean / short.mean()), 6, 0.95))
    # ... and to a mean of 1.1: below the interval of the mean (from 4.05), inside the quantiles of
    # ONE χ²(6) value divided by N ([0.12, 1.45]: dof where N · dof belongs) and of χ²(N) divided
    # by N ([0.32, 2.05]), above the mean's bounds divided by N once more ([0.41, 0.83])
    out.append(("ten KITTI values rescaled to a mean of 1.1", short * (1.1 / short.mean()), 6, 0.95))
    # ... and of 1.7: inside the quantiles of χ²(N) divided by N, above the mean's bounds divided by
    # dof ([0.68, 1.33]) and the quantiles of one value divided by N
    out.append(("ten KITTI values rescaled to a mean of 1.7", short * (1.7 / short.mean()), 6, 0.95))
    return tuple(out)


# --------------------------------------------------------------------------------------
# judging
# --------------------------------------------------------------------------------------

class _Failure(str):
    """A learner's call that gave no usable result (raised, wrong shape, NaN), as its message."""


def _scalar(value, what: str, v: str = "e", W: str = "P") -> float:
    """The learner's result as one float; a vector or matrix fails with a hint (``v``ᵀ ``W``⁻¹ ``v``)."""
    try:
        arr = None if isinstance(value, (str, bytes)) else np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.size != 1:
        if arr is not None and arr.ndim == 2 and arr.shape[0] == arr.shape[1]:
            raise CheckFailed(f"{what} should be one number, got a matrix of shape {arr.shape}. "
                              f"Hint: an outer product {v} ({W}⁻¹ {v})ᵀ: a transpose on the wrong side; the "
                              "statistic is a quadratic form, one number (lecture 09 §1)"
                              + hints.formula(f", {v}ᵀ {W}⁻¹ {v}"))
        shape = f"a {type_name(value)}" if arr is None else f"shape {arr.shape}"
        raise CheckFailed(f"{what} should be one number, got {shape}. Hint: the statistic is a quadratic "
                          f"form, one number (lecture 09 §1); did you return {W}⁻¹ {v} (a vector) or forget "
                          "a product?" + hints.formula(f" It is {v}ᵀ {W}⁻¹ {v}."))
    return float(arr.reshape(()))


def _outcome(fn: Callable, args: tuple, convert: Callable):
    """The learner's converted, finite result on ``args``, or a :class:`_Failure`."""
    try:
        value = convert(call(fn, *args))
    except CheckFailed as exc:
        return _Failure(str(exc))
    if not np.all(np.isfinite(value)):
        return _Failure(f"{getattr(fn, '__name__', 'your function')} returned NaN or inf")
    return value


def _evaluate(formula: Callable, case):
    """A (wrong or right) formula on a case, or None where it raises or is not finite."""
    try:
        with np.errstate(all="ignore"):
            value = np.asarray(formula(*case), dtype=float)
    except Exception:  # a mistake may not even have the right shapes on every case
        return None
    return value if np.all(np.isfinite(value)) else None


def _close(outcome, value) -> bool:
    if isinstance(outcome, _Failure) or value is None:
        return False
    outcome = np.asarray(outcome, dtype=float)
    return outcome.shape == value.shape and bool(np.allclose(outcome, value, rtol=RTOL, atol=1e-12))


def _reproduces(outcome, wrong) -> bool:
    """Whether a wrong formula's value on a case is what the learner's call gave there. A
    case where the formula cannot be evaluated counts as reproduced when the learner's call
    failed there too (a misplaced transpose raises on non-square G)."""
    return isinstance(outcome, _Failure) if wrong is None else _close(outcome, wrong)


#: The hint for results that agree with the reference to single precision only, and the largest
#: relative error where it applies: float32 keeps about 7 digits, which a solve with a condition
#: number of ~1e3 (the mixed coordinates) turns into 4; every listed mistake is off by 2 % or more.
SINGLE_PRECISION = ("the results agree with the reference to only 3–6 digits, as a computation in single precision "
                    "(float32) does; keep NumPy's default float64 throughout")
SINGLE_PRECISION_RTOL = 1e-3


def _single_precision(outcomes, expected) -> bool:
    """Whether every result is a number within :data:`SINGLE_PRECISION_RTOL` of the reference."""
    return all(not isinstance(o, _Failure) and e is not None and np.shape(o) == np.shape(e)
               and np.allclose(np.asarray(o, dtype=float), e, rtol=SINGLE_PRECISION_RTOL, atol=1e-12)
               for o, e in zip(outcomes, expected))


def _judge(outcomes, cases, labels, reference, mistakes, hint: str) -> None:
    """Fail with the hint of the known mistake that explains the learner's results.

    A mistake is named when it reproduces the learner's result on every case
    (:func:`harness.known_mistake`) and gives a wrong value the learner also gave on some case
    (a formula that only fails where the learner's call failed explains nothing). Else the
    mistake that agrees on the first wrong case alone is named, if any.

    Parameters
    ----------
    outcomes : list
        The learner's result per case (:func:`_outcome`).
    cases : sequence of tuple
        The arguments of each case, as the formulas take them.
    labels : sequence of str
        What each case is, for the message.
    reference : callable
        The correct formula.
    mistakes : sequence of (callable, str)
        Known wrong formulas and the hint that names each.
    hint : str
        The hint when no known mistake explains the results.
    """
    expected = [_evaluate(reference, c) for c in cases]
    correct = [_close(o, e) for o, e in zip(outcomes, expected)]
    if all(correct):
        return
    i = correct.index(False)
    summary = f"for {labels[i]} ({correct.count(False)} of {len(cases)} cases wrong)"
    # each formula evaluated once, then judged per case index
    wrong_by = [([_evaluate(f, c) for c in cases], why) for f, why in mistakes]
    shows = [(values, why) for values, why in wrong_by
             if any(w is not None and not ok and _close(o, w) for o, w, ok in zip(outcomes, values, correct))]
    why = known_mistake(outcomes, range(len(cases)), shows, lambda o, w, k: _reproduces(o, w),
                        evaluate=lambda values, k: values[k])
    if why is None and not isinstance(outcomes[i], _Failure):   # agrees with a mistake on this case only
        why = known_mistake(outcomes, range(len(cases)), wrong_by, lambda o, w, k: _close(o, w),
                            evaluate=lambda values, k: values[k], case=i)
    if why is not None:
        raise CheckFailed(f"wrong result {summary}. Hint: {why}")
    if _single_precision(outcomes, expected):
        raise CheckFailed(f"result differs from the reference {summary} by less than 0.1 %. Hint: {SINGLE_PRECISION}")
    if isinstance(outcomes[i], _Failure):
        own_hint = "Hint:" in outcomes[i]
        raise CheckFailed(f"{summary}: {outcomes[i]}" + ("" if own_hint else f" Hint: {hint}"))
    err = float(np.max(np.abs(np.asarray(outcomes[i]) - expected[i])))
    raise CheckFailed(f"result differs from the reference {summary} (max abs error {err:.3g}). "
                      f"Hint: {hint}")


def _diag_weighted(v, M):
    return float(np.sum(v ** 2 / np.diag(M)))


def _chol_wrong_side(v, M):
    z = np.linalg.solve(np.linalg.cholesky(M).T, v)
    return float(z @ z)


def _weight_mistakes(quantity: str, W: str, n: str, chi2: str):
    """Mistakes in vᵀ W⁻¹ v shared by the NEES and the NIS, as functions of (v, M). Each hint
    names the mistake and the concept at tier 1; the formula is marked (:mod:`hints`)."""
    F = hints.formula
    form = f"{quantity}ᵀ {W}⁻¹ {quantity}"
    return [
        (lambda v, M: float(v @ M @ v),
         f"that is {quantity}ᵀ {W} {quantity}: weight by the INVERSE covariance (lecture 09 §1)" + F(f", {form}")),
        (lambda v, M: float(v @ v), f"not {quantity}ᵀ {quantity}: the vector must be weighted by the inverse of "
                                    f"its covariance {W} (lecture 09 §1)" + F(f", {form}")),
        (lambda v, M: float(v @ (1 / M) @ v),
         f"1 / {W} inverts each entry; the {chi2} needs the matrix inverse (np.linalg.solve({W}, {quantity}))"
         + F(f": {form}")),
        (lambda v, M: float(v @ np.linalg.solve(M, v)) / len(v),
         f"do not divide by the dimension: the {chi2} is χ²({n}) with mean {n} (lecture 09 §1)"),
        (lambda v, M: math.sqrt(v @ np.linalg.solve(M, v)),
         f"that is the Mahalanobis distance; the {chi2} is its square"),
        (lambda v, M: float(v @ np.linalg.solve(M, v)) ** 2,
         f"squared twice: the quadratic form is already the squared (Mahalanobis) length" + F(f", {form}")),
        (lambda v, M: float(v @ np.linalg.solve(M, v)) / 2,
         f"no ½: the Gaussian's exponent has a −½, the {chi2} does not" + F(f"; it is {form} itself")),
        (_diag_weighted, f"only the diagonal of {W} (each component divided by its variance): the "
                         f"correlations are ignored; use the full inverse of {W}"),
        (lambda v, M: float(np.sum(v ** 2 / np.sqrt(np.diag(M)))),
         f"each component divided by its standard deviation, squared once, and the correlations "
         f"dropped; use the full inverse of {W}" + F(f": {form}")),
        (lambda v, M: float(np.sum(v ** 2 / np.diag(M) ** 2)),
         f"each component divided by its variance, then squared: that divides by the variance "
         f"twice (standard deviation vs variance), and drops the correlations; use the inverse of {W}"),
        (lambda v, M: float(np.linalg.solve(M, v) @ np.linalg.solve(M, v)),
         f"{W}⁻¹ applied twice ({quantity}ᵀ {W}⁻² {quantity}): dot {W}⁻¹ {quantity} with {quantity} itself"),
        (lambda v, M: float(np.sum(np.linalg.solve(M, v))),
         f"that is the sum of the entries of {W}⁻¹ {quantity}; the {chi2} is its dot product with "
         f"{quantity}" + F(f": {quantity}ᵀ ({W}⁻¹ {quantity})")),
        (_chol_wrong_side, f"Cholesky on the wrong side: with {W} = L Lᵀ, whiten by z = L⁻¹ {quantity} "
                           f"(solve(L, {quantity})), not L⁻ᵀ {quantity}; then zᵀ z"),
        (lambda v, M: float(v @ np.linalg.solve(np.linalg.cholesky(M), v)),
         f"{quantity}ᵀ L⁻¹ {quantity} whitens one side only: with {W} = L Lᵀ, z = L⁻¹ {quantity} "
         f"and the {chi2} is zᵀ z"),
        (lambda v, M: float(v @ np.linalg.solve(np.sqrt(M), v)),
         f"√{W} element-wise: {W} holds variances and covariances, and the {chi2} weights by the inverse "
         f"of {W} itself (not by standard deviations)"),
    ]


# --------------------------------------------------------------------------------------
# checks
# --------------------------------------------------------------------------------------

@check
def check_consistency_nees(nees):
    """The learner's ``nees(error, P)`` on KITTI pose, position and navigation errors."""
    labels, cases = zip(*[(label, (e, P)) for label, e, P in nees_cases()])
    outcomes = [_outcome(nees, c, lambda v, n=len(c[0]): _scalar(v, f"nees for a {n}-dof error"))
                for c in cases]
    _judge(outcomes, cases, labels, lambda e, P: float(e @ np.linalg.solve(P, e)),
           _weight_mistakes("e", "P", "n", "NEES"),
           "the NEES measures the error against the covariance the filter reported for it, a quadratic form "
           "in the inverse covariance that is χ²(n) for a consistent filter (lecture 09 §1 and the table at its "
           "top)" + hints.formula(": ε = eᵀ P⁻¹ e (np.linalg.solve(P, e) avoids forming the inverse)"))


def _S(P, G, R):
    return G @ P @ G.T + R


def _nis_mistakes():
    """Wrong NIS formulas as functions of (ν, P̌, G, R). Each hint names the mistake at tier 1;
    the formula of S follows it, marked (:mod:`hints`)."""
    S_is = hints.formula("; S = G P̌ Gᵀ + R")
    table = " (lecture 09's table)"

    def with_S(build):
        return lambda y, P, G, R: float(y @ np.linalg.solve(build(P, G, R), y))

    out = [
        (with_S(lambda P, G, R: G @ P @ G.T), "the innovation also carries the observation noise R, which is "
                                              "missing from S" + table + S_is),
        (with_S(lambda P, G, R: R), "the prior's uncertainty G P̌ Gᵀ is missing from S: the innovation "
                                    "carries the prior's error too" + table + S_is),
        (with_S(lambda P, G, R: P), "that weights ν by P̌⁻¹, the state's prior covariance; the "
                                    "innovation has its own covariance S" + table + S_is),
        (with_S(lambda P, G, R: P[:len(R), :len(R)] + R),
         "P̌[0:m, 0:m] is the covariance of the FIRST m error states, which are not what the sensor "
         "measures (in the ESKF: δp and δv, while the lidar sees δp and δθ, lecture 08 §4); the prior must "
         "be mapped into the measurement space through G" + S_is),
        (with_S(lambda P, G, R: P + R), "P̌ + R: the prior must be mapped into the measurement "
                                        "space through G" + table + S_is),
        (with_S(lambda P, G, R: G.T @ P @ G + R), "Gᵀ P̌ G: the transpose is on the wrong side" + S_is),
        (with_S(lambda P, G, R: G @ P @ G + R), "G P̌ G: the transpose of the second G is missing" + S_is),
        (with_S(lambda P, G, R: G @ G.T @ P + R), "G Gᵀ P̌: the order of the products" + S_is),
        (with_S(lambda P, G, R: G @ P @ G.T + np.sqrt(R)),
         "√R where R belongs: R holds variances (σ²), not standard deviations" + S_is),
        (with_S(lambda P, G, R: G @ P @ G.T + R @ R),
         "R R (or R²): R already holds variances (σ²)" + S_is),
        (with_S(lambda P, G, R: G @ P @ G.T + R ** 2),
         "R squared element-wise: R already holds variances (σ²)" + S_is),
        (with_S(lambda P, G, R: G @ P @ G.T + np.diag(R)),
         "np.diag(R) is a vector, which numpy adds to every row; add the matrix R" + S_is),
        (with_S(lambda P, G, R: G @ P @ G.T + np.linalg.inv(R)),
         "R⁻¹ added where R belongs: the observation noise enters S as its covariance (the inverse is "
         "taken of S as a whole)" + S_is),
        (with_S(lambda P, G, R: G @ P @ G.T - R),
         "wrong sign: the observation noise adds to the innovation's covariance" + S_is),
        (with_S(lambda P, G, R: G @ np.linalg.inv(P) @ G.T + R),
         "P̌⁻¹ inside S: S uses the prior covariance itself" + S_is),
        (lambda y, P, G, R: float(y @ (np.linalg.inv(G @ P @ G.T) + np.linalg.inv(R)) @ y),
         "(G P̌ Gᵀ)⁻¹ + R⁻¹ is not S⁻¹: add the covariances first, then invert S" + S_is),
    ]
    for f, why in _weight_mistakes("ν", "S", "m", "NIS"):
        out.append((lambda y, P, G, R, f=f: f(y, _S(P, G, R)), why))
    return out


@check(uses={"nees": "consistency_nees"})
def check_consistency_nis(nis):
    """The learner's ``nis(innovation, P_check, G, R)`` at held-out KITTI lidar poses."""
    labels, cases = zip(*[(label, (y, P, G, R)) for label, y, P, G, R in prior_cases()])
    outcomes = [_outcome(nis, c, lambda v: _scalar(v, "nis", "ν", "S")) for c in cases]
    _judge(outcomes, cases, labels, lambda y, P, G, R: float(metrics.nis(y, _S(P, G, R))),
           _nis_mistakes(),
           "measure ν against its own covariance S, the prior mapped into the measurement space plus the "
           "observation noise, an m × m matrix (m = len(ν); lecture 09's table, lecture 08 §4 for G)"
           + hints.formula(": ν̃ = νᵀ S⁻¹ ν with S = G P̌ Gᵀ + R (P̌ is n × n, G is m × n)"))


def _interval(value):
    """A learner's (lo, hi): any sequence of two numbers (tuple, list or array)."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        arr = None
    if arr is None or arr.shape != (2,):
        shape = type_name(value) if arr is None else f"shape {arr.shape}"
        raise CheckFailed(f"chi2_interval must return two numbers (lo, hi), got {shape}")
    return arr


def _interval_mistakes():
    """Wrong intervals as functions of (dof, n_runs, confidence)."""
    q = metrics.chi2_ppf

    def two(p_lo, p_hi, k, scale):
        return lambda d, n, c: [q(p_lo(c), k(d, n)) / scale(d, n), q(p_hi(c), k(d, n)) / scale(d, n)]

    lo_p, hi_p = (lambda c: (1 - c) / 2), (lambda c: (1 + c) / 2)
    dn, per_n = (lambda d, n: d * n), (lambda d, n: n)
    one = lambda d, n: 1  # noqa: E731
    z = {0.9: 1.6448536269514722, 0.95: 1.959963984540054, 0.99: 2.5758293035489004}
    F = hints.formula
    tails = F(": lo at (1 − c)/2, hi at (1 + c)/2")
    of_the_mean = F(": lo, hi = F⁻¹((1 ∓ c)/2; dof · n_runs) / n_runs")
    return [
        (two(lambda c: 0.0, lambda c: c, dn, per_n),
         "that is a one-sided interval [0, q_c]; a two-sided interval leaves (1 − c)/2 in each "
         "tail (lecture 09 §1)" + tails),
        (two(lambda c: 1 - c, lambda c: c, dn, per_n),
         "the tails are (1 − c)/2 each, not 1 − c" + tails),
        (two(lambda c: c / 2, lambda c: 1 - c / 2, dn, per_n),
         "confidence c is the mass INSIDE the interval, not the tail mass α: the tails hold "
         "α = 1 − c together" + tails),
        (lambda d, n, c: [q((1 - c) / 2, d * n) / n, q(c, d * n) / n],
         "lo is right, but hi is the c quantile: the upper tail also holds (1 − c)/2" + F(", so hi is at (1 + c)/2")),
        (lambda d, n, c: [q(1 - c, d * n) / n, q((1 + c) / 2, d * n) / n],
         "hi is right, but lo is the (1 − c) quantile: the lower tail also holds (1 − c)/2" + F(", so lo is at (1 − c)/2")),
        (two(hi_p, lo_p, dn, per_n), "lo and hi are swapped: lo is the lower quantile, hi the upper one"
                                     + F(", (1 − c)/2 and (1 + c)/2")),
        (two(lo_p, hi_p, lambda d, n: d, one),
         "n_runs is ignored: that is the interval of one value; the SUM of n_runs values is χ² with "
         "dof · n_runs degrees of freedom, and its quantiles divided by n_runs bound the mean (lecture 09 §1)"
         + of_the_mean),
        (two(lo_p, hi_p, dn, one),
         "these are bounds for the sum of the n_runs values; divide by n_runs for the mean"),
        (two(lo_p, hi_p, lambda d, n: n, per_n),
         "degrees of freedom: the sum has dof · n_runs of them, not n_runs (lecture 09 §1)"),
        (two(lo_p, hi_p, lambda d, n: d, per_n),
         "the quantiles of χ²(dof) divided by n_runs: the sum of n_runs values has dof · n_runs "
         "degrees of freedom, χ²(dof · n_runs) (lecture 09 §1)" + of_the_mean),
        (two(lo_p, hi_p, lambda d, n: d + n, per_n),
         "degrees of freedom: the sum has dof · n_runs of them (a product), not dof + n_runs"),
        (two(lo_p, hi_p, dn, lambda d, n: 1 / n),
         "multiplied by n_runs: the mean is the sum divided by n_runs; divide the quantiles"),
        (two(lo_p, hi_p, dn, lambda d, n: d * n),
         "divided by dof · n_runs: the mean of the NEES/NIS values is the sum divided by n_runs "
         "only (its mean is dof, not 1)"),
        (two(lo_p, hi_p, dn, lambda d, n: math.sqrt(n)),
         "divided by √n_runs: the mean is the sum divided by n_runs, not by √n_runs"),
        (two(lo_p, hi_p, lambda d, n: d * n - 1, per_n),
         "degrees of freedom off by one: the sum of n_runs χ²(dof) values has exactly dof · n_runs "
         "(no − 1: nothing is estimated from the data)"),
        (two(lo_p, hi_p, lambda d, n: d * (n - 1), per_n),
         "degrees of freedom off by one: the sum of n_runs χ²(dof) values has exactly dof · n_runs, "
         "not dof · (n_runs − 1)"),
        (two(lo_p, hi_p, lambda d, n: d * n * n, per_n),
         "degrees of freedom: the sum has dof · n_runs of them, counted once"),
        (lambda d, n, c: [d - z[c] * math.sqrt(2 * d / n), d + z[c] * math.sqrt(2 * d / n)],
         "that is the normal approximation of the mean, close for large dof · n_runs but "
         "not exact; use the χ² quantiles (lecture 09 §1)" + of_the_mean),
        (lambda d, n, c: [d * n * (1 - 2 / (9 * d * n) - z[c] * math.sqrt(2 / (9 * d * n))) ** 3 / n,
                          d * n * (1 - 2 / (9 * d * n) + z[c] * math.sqrt(2 / (9 * d * n))) ** 3 / n],
         "that is the Wilson–Hilferty approximation; close, but not exact; use the χ² quantiles (lecture 09 §1)"
         + of_the_mean),
    ]


#: Confidences of the interval cases: never 0.5, where c and 1 − c coincide, and only those
#: whose normal quantile a learner may have written out (the normal approximation's mistake).
INTERVAL_CONFIDENCES = (0.9, 0.95, 0.99)
#: Under a run seed, the ranges of (dof, n_runs) of the interval cases drawn in place of the
#: fixed ones, in their order: one value of few dof (the approximations are off by percents),
#: a KITTI-sized record, and means of 3 to 100 values.
INTERVAL_DRAWN = (((2, 9), (1, 1)), ((3, 12), (150, 600)), ((8, 20), (10, 40)), ((2, 5), (20, 100)),
                  ((4, 9), (10, 40)), ((2, 4), (3, 12)), ((5, 12), (2, 6)))


@functools.lru_cache(maxsize=None)
def interval_cases():
    """(dof, n_runs, confidence) of the interval check.

    Confidences from :data:`INTERVAL_CONFIDENCES`; n_runs 1 and several, dof ≠ n_runs, so that
    each misplaced factor changes the interval. Under a run seed each is drawn from its range
    in :data:`INTERVAL_DRAWN`, never one of the fixed cases.
    """
    n_updates = len(load_kitti(EXCERPT).lidar.t) - 1          # one NIS per lidar pose after the first
    fixed = ((6, 1, 0.95), (6, n_updates, 0.95), (15, 20, 0.95), (3, 50, 0.99), (6, 20, 0.99),
             (2, 7, 0.9), (9, 3, 0.9))

    def draw(g):
        out = []
        for (d_lo, d_hi), (n_lo, n_hi) in INTERVAL_DRAWN:
            case = fixed[0]
            while case in fixed or case[0] == case[1]:
                case = (int(g.integers(d_lo, d_hi + 1)),
                        int(round(inputs.log_uniform(g, n_lo, n_hi))), float(g.choice(INTERVAL_CONFIDENCES)))
            out.append(case)
        return tuple(out)

    return inputs.fixed_or_drawn(fixed, draw, "consistency.interval")


@check
def check_chi2_interval(chi2_interval):
    """The learner's ``chi2_interval(dof, n_runs, confidence)`` for KITTI-sized records."""
    cases = interval_cases()
    labels = [f"dof={d}, n_runs={n}, confidence={c}" for d, n, c in cases]
    outcomes = [_outcome(chi2_interval, c, _interval) for c in cases]
    _judge(outcomes, cases, labels, lambda d, n, c: metrics.chi2_bounds(d, n, c), _interval_mistakes(),
           "the SUM of n_runs independent χ²(dof) values is χ² again; its two-sided quantiles, leaving "
           "(1 − c)/2 in each tail, scaled to the mean (lecture 09 §1)"
           + hints.formula(": lo, hi = F⁻¹((1 ∓ c)/2; dof · n_runs) / n_runs"))


#: How the gate's hint that names weighting by S (not S⁻¹) starts (:func:`_gate_separates`).
_GATE_BY_S = "The NIS must weight ν by S⁻¹ (the"


def _gate_mistakes():
    """Wrong gate decisions as functions of (NIS, m, confidence, ν, S), with their hints (the
    threshold's formula marked, :mod:`hints`)."""
    q = metrics.chi2_ppf
    F = hints.formula
    quantile = F(": F⁻¹(confidence; m)")
    nis = F(": νᵀ S⁻¹ ν")
    section = " (lecture 09 §4)"
    out = [
        (lambda v, m, c, y, S: True,
         "Every innovation was accepted, even a map-matching failure metres away: the gate refuses "
         "nothing. It must refuse an innovation whose NIS is too large to be noise at this confidence"
         f"{section}. (If your gate does compute a NIS, check that it weights ν by the inverse of S: νᵀ S ν is "
         "tiny here, S holding variances of centimetres, so it passes everything.)"),
        (lambda v, m, c, y, S: False,
         "Every innovation was refused: a filter behind this gate never uses its sensor. Accept an "
         f"innovation whose NIS is plausible for m components at this confidence{section}."),
        (lambda v, m, c, y, S: v >= q(c, m), "The comparison is reversed: accept when the NIS is at "
                                              "most the threshold."),
        (lambda v, m, c, y, S: v <= q(c, 1),
         "The threshold is the χ² quantile for ONE degree of freedom; use the innovation's dimension."),
        (lambda v, m, c, y, S: v <= q(c, m * m),
         "The threshold has m² degrees of freedom (S.size?); an innovation of m components has m: "
         "len(innovation)."),
        (lambda v, m, c, y, S: v <= q(1 - c, m),
         "That threshold is the (1 − confidence) quantile (1 % for 99 %); the gate uses the "
         "`confidence` quantile."),
        (lambda v, m, c, y, S: v <= c, "Compare the NIS with a χ² quantile of the innovation's dimension, "
                                       f"not with the confidence{section}" + quantile + "."),
        (lambda v, m, c, y, S: q((1 - c) / 2, m) <= v <= q((1 + c) / 2, m),
         "That is the two-sided interval; the gate is one-sided: only a large NIS is rejected"
         f"{section}" + F(", at F⁻¹(confidence; m)") + "."),
        (lambda v, m, c, y, S: v <= q((1 + c) / 2, m),
         "The threshold is the (1 + c)/2 quantile, the upper end of a two-sided interval; the gate "
         f"is one-sided{section}" + quantile + "."),
        (lambda v, m, c, y, S: v <= q(0.99, m), "The 99 % is written into the function: use the "
                                                "`confidence` argument."),
        (lambda v, m, c, y, S: v <= q(0.95, m), "A fixed 95 % is written into the function: use the "
                                                "`confidence` argument."),
        (lambda v, m, c, y, S: math.sqrt(v) <= q(c, m),
         "The square root of the NIS (the Mahalanobis distance) is compared with a χ² quantile, "
         "or (the same decisions) the NIS with the square of the χ² quantile; the quantile is "
         "already a squared length: compare the NIS itself with it" + quantile + "."),
        (lambda v, m, c, y, S: v <= math.sqrt(q(c, m)),
         "The NIS is compared with the square root of the χ² quantile (√); the quantile is "
         "already on the NIS's (squared) scale."),
        (lambda v, m, c, y, S: v / m <= q(c, m),
         "The NIS is divided by the dimension; compare the NIS itself with the χ² quantile" + quantile + "."),
        (lambda v, m, c, y, S: v <= q(c, m) / m,
         "The threshold is divided by the dimension; compare the NIS with the χ² quantile itself" + quantile + "."),
        (lambda v, m, c, y, S: float(y @ S @ y) <= q(c, m),
         _GATE_BY_S + " inverse), not S" + nis + "."),
        (lambda v, m, c, y, S: float(y @ y) <= q(c, m),
         "ν must be weighted by the inverse of its covariance S, not νᵀ ν" + nis + "."),
        (lambda v, m, c, y, S: _diag_weighted(y, S) <= q(c, m),
         "Only the diagonal of S is used (the correlations are dropped); use the full S⁻¹" + nis + "."),
    ]
    for shift in (-1, 1):
        out.append((lambda v, m, c, y, S, shift=shift: v <= q(c, m + shift),
                    f"The degrees of freedom are off by one (m {'−' if shift < 0 else '+'} 1); an "
                    "innovation of m components has exactly m = len(innovation)."))
    for k in (2, 3, 4, 5, 6, 9, 12, 15):
        out.append((lambda v, m, c, y, S, k=k: v <= q(c, k),
                    f"Every innovation is gated with {k} degrees of freedom; use the innovation's "
                    "dimension m = len(innovation)."))
    return out


@functools.lru_cache(maxsize=None)
def _gate_reference():
    """NIS, dimension, confidence and threshold of each of :func:`gate_cases` (computed once)."""
    cases = gate_cases()
    values = np.array([metrics.nis(y, S) for y, S, _ in cases])
    dims = np.array([len(y) for y, _, _ in cases])
    conf = np.array([c for _, _, c in cases])
    threshold = np.array([metrics.chi2_ppf(c, m) for c, m in zip(conf, dims)])
    for a in (values, dims, conf, threshold):
        a.setflags(write=False)          # cached: shared by every call of the check
    return values, dims, conf, threshold


@check(uses={"nees": "consistency_nees", "chi2_interval": "chi2_interval"})
def check_innovation_gate(gate):
    """The learner's ``gate(innovation, S, confidence)`` on the KITTI outlier run."""
    cases = gate_cases()
    values, dims, conf, threshold = _gate_reference()
    answers = []
    for y, S, c in cases:
        answer = call(gate, y, S, c)
        if not isinstance(answer, (bool, np.bool_)):
            raise CheckFailed(f"gate must return True or False, got {type_name(answer)}")
        answers.append(bool(answer))
    answers = np.array(answers)
    wrong = np.nonzero(answers != (values <= threshold))[0]
    if wrong.size == 0:
        return
    # show the clearest wrong decision: the NIS farthest from its gate (a failure metres away
    # accepted says more than a borderline case)
    i = wrong[np.argmax(np.abs(np.log(values[wrong] / threshold[wrong])))]
    hint = (f"an innovation of {dims[i]} components with NIS {values[i]:.2f} ({conf[i]:.1%} gate "
            f"{threshold[i]:.2f}) was {'accepted' if answers[i] else 'rejected'}; {wrong.size} of "
            f"{len(cases)} decisions are wrong. ")
    why = known_mistake(answers, list(zip(values, dims, conf, cases)), _gate_mistakes(),
                        lambda a, w, k: w is not None and bool(w) == a,
                        evaluate=lambda decide, case: decide(*case[:3], *case[3][:2]))
    hint += why or _gate_dof_hint(values, dims, conf, answers)
    raise CheckFailed("wrong gate decisions. Hint: " + hint)


def _gate_dof_hint(values, dims, conf, answers) -> str:
    """Name the degrees of freedom a learner's threshold uses, if a χ² quantile explains it.

    For each innovation dimension m, the decisions on its cases are compared with
    NIS ≤ F⁻¹(confidence; k) for k = 1 … 40; the cases between consecutive quantiles make k
    unique when it is at most 20.
    """
    found = {}
    for m in sorted(set(dims.tolist())):
        mine = dims == m
        for k in range(1, 41):
            threshold = np.array([metrics.chi2_ppf(c, k) for c in conf[mine]])
            if np.array_equal(values[mine] <= threshold, answers[mine]):
                found[m] = k
                break
        else:
            return ("Accept an innovation whose NIS is at most the χ² quantile of the confidence, with as many "
                    "degrees of freedom as the innovation has components (lecture 09 §4)"
                    + hints.formula(": νᵀ S⁻¹ ν ≤ F⁻¹(confidence; m), m = len(innovation)") + ".")
    used = ", ".join(f"{k} for {m}-component innovations" for m, k in found.items())
    return (f"The threshold is a χ² quantile with the wrong degrees of freedom ({used}); an "
            "innovation of m components has m = len(innovation).")


@functools.lru_cache(maxsize=None)
def _expected_verdicts() -> list:
    """The reference verdict of each of :func:`verdict_cases` (computed once)."""
    return [consistency_stats.verdict(values, dof, c) for _, values, dof, c in verdict_cases()]


def _verdict_by(bounds, statistic=np.mean, labels=("overconfident", "underconfident")):
    """A verdict rule from a bounds function (dof, N, c) -> (lo, hi) and the statistic compared
    (None: the mean divided by dof)."""
    def rule(values, dof, c):
        lo, hi = bounds(dof, len(values), c)
        s = np.mean(values) / dof if statistic is None else statistic(values)
        return labels[0] if s > hi else labels[1] if s < lo else "consistent"
    return rule


def _verdict_by_share(one_value, tails: bool = False):
    """A verdict from the SHARE of single NIS values inside an interval of one value (a graded
    mistake), as the answers it allows on a record: "consistent", or either of the other two
    (a learner who tests the share may name the side by the mean, the median or the tail that
    holds more values; the mistake is the share, whatever the side).

    ``one_value(dof, c)`` -> (lo, hi) is the interval of one χ²(dof) value; with ``tails``, the
    record is consistent when neither tail holds more than (1 − c)/2 of the values, else when
    at least c of them lie inside."""
    either = frozenset(("overconfident", "underconfident"))

    def rule(values, dof, c):
        values = np.asarray(values, dtype=float)
        lo, hi = one_value(dof, c)
        if tails:
            passes = max(np.mean(values > hi), np.mean(values < lo)) <= (1 - c) / 2
        else:
            passes = np.mean((values >= lo) & (values <= hi)) >= c
        return "consistent" if passes else either
    return rule


#: The hint of a verdict taken from single values (the lecture's test is on the mean).
_SHARE_HINT = ("the verdict is taken from the share of single NIS values inside the interval of ONE value "
               "(lecture 09 §3's table and the look at the NEES above report that share to describe a run; it "
               "is not the test): that tests each step alone, and a share "
               "near c says nothing about the side on which the filter errs. Lecture 09 §1 tests the record "
               "as a whole: a consistent filter's innovations are white, so the NIS may be averaged over "
               "time, and the time-averaged NIS is compared with the much narrower interval of a mean of N "
               "values (your chi2_interval(dof, N)); above it overconfident, below it underconfident"
               + hints.formula(": N · NIS̄ ~ χ²(N · dof), so NIS̄ lies in [F⁻¹((1 − c)/2; N · dof), "
                               "F⁻¹((1 + c)/2; N · dof)] / N with probability c") + ".")


def _verdict_mistakes():
    """Wrong verdict rules as functions of (values, dof, confidence), with their hints. A rule
    returns a verdict, or the set of verdicts it allows (:func:`_verdict_by_share`)."""
    b, q = metrics.chi2_bounds, metrics.chi2_ppf
    F = hints.formula
    section = "(lecture 09 §1)"
    return [
        (lambda values, dof, c: "consistent",
         "verdict says 'consistent' for every record, even one whose mean NIS is several times dof: "
         f"the record was not tested {section}. Average it, compare the mean with the two-sided interval "
         "of a mean of N values (your chi2_interval), and name the side on which it leaves."),
        (_verdict_by(b, labels=("underconfident", "overconfident")),
         "overconfident and underconfident are swapped: a mean above the interval means the errors "
         f"are larger than S says, so the filter is OVERconfident (S too small); below it, underconfident {section}."),
        (_verdict_by(lambda d, n, c: b(d, 1, c)),
         "that is the interval of ONE value (χ²(dof)); the mean of N values has a much narrower "
         f"interval {section}" + F(", F⁻¹((1 ∓ c)/2; N · dof) / N") + "."),
        (_verdict_by(lambda d, n, c: (q((1 - c) / 2, d) / n, q((1 + c) / 2, d) / n)),
         "the quantiles of one value's χ²(dof), divided by N: the SUM of N values of dof components has "
         f"N · dof degrees of freedom, not dof {section}"
         + F("; the mean lies in F⁻¹((1 ∓ c)/2; N · dof) / N") + "."),
        (_verdict_by(lambda d, n, c: (q((1 - c) / 2, n) / n, q((1 + c) / 2, n) / n)),
         "degrees of freedom: N values of dof components sum to a χ² with N · dof of them, not N "
         f"{section}" + F("; the mean lies in F⁻¹((1 ∓ c)/2; N · dof) / N") + "."),
        (_verdict_by_share(lambda d, c: b(d, 1, c)), _SHARE_HINT),
        (_verdict_by_share(lambda d, c: b(d, 1, c), tails=True), _SHARE_HINT),
        (_verdict_by(lambda d, n, c: b(d * n, 1, c)),
         "the mean is compared with the bounds of the SUM of the N values (χ²(N · dof)); divide "
         f"them by N for the mean {section}."),
        # the same decisions: sum vs (lo, hi) is mean vs (lo/N, hi/N)
        (_verdict_by(b, statistic=np.sum),
         "either the SUM of the values is compared with the bounds of the mean, or the mean's "
         "bounds are divided by N once more (the same decisions): chi2_interval(dof, N) already is "
         "the interval of the mean; compare the mean with it."),
        (_verdict_by(lambda d, n, c: b(d * n, n, c)),
         "degrees of freedom counted twice: the mean of N values of dof components has the "
         "interval chi2_interval(dof, N), not chi2_interval(dof · N, N)."),
        (_verdict_by(lambda d, n, c: b(d, n - 1, c)),
         "N − 1 values: the mean of N values has the interval chi2_interval(dof, N) (off by one; "
         "nothing is estimated from the record)."),
        (_verdict_by(lambda d, n, c: b(n, d, c)),
         "the arguments dof and N are swapped: chi2_interval(dof, N, confidence)."),
        (_verdict_by(lambda d, n, c: b(d, n, c), statistic=None),
         "the mean is divided by dof (a normalised NIS) but the bounds are not: compare the mean "
         "itself with chi2_interval(dof, N)."),
        (_verdict_by(lambda d, n, c: tuple(x / d for x in b(d, n, c))),
         "the bounds are divided by dof but the mean is not: compare the mean with "
         "chi2_interval(dof, N) itself."),
        (_verdict_by(lambda d, n, c: b(d, n, 1 - c)),
         "the interval's confidence is 1 − c (the tail mass α); it must hold c inside."),
        (_verdict_by(lambda d, n, c: (q(1 - c, d * n) / n, q(c, d * n) / n)),
         f"the tails are (1 − c)/2 each, not 1 − c {section}."),
        (_verdict_by(lambda d, n, c: (0.0, q(c, d * n) / n)),
         f"a one-sided bound cannot say underconfident: use the two-sided interval {section}."),
        (_verdict_by(lambda d, n, c: (b(d, n, c)[1],) * 2),
         "only the upper bound is used: below it the mean must still be compared with the lower "
         "bound; between the two the filter is consistent."),
        (_verdict_by(lambda d, n, c: (d, d)),
         "compare the mean with the two-sided interval, not with dof itself: inside the interval "
         "the filter is consistent."),
        (_verdict_by(lambda d, n, c: b(d, n, 0.95)), "the 95 % is written into the function: use the "
                                                     "`confidence` argument."),
        (_verdict_by(lambda d, n, c: b(6, n, c)), "dof 6 is written into the function: use the `dof` argument."),
        # the same decisions as using the lower bound alone (above lo: over, below: under)
        (_verdict_by(lambda d, n, c: b(d, n, c)[::-1]),
         "lo and hi are swapped (or only the lower bound is used, the same decisions): above hi "
         "is overconfident, below lo underconfident, in between consistent."),
    ]


def _allows(answer: str, wrong) -> bool:
    """Whether a wrong rule's verdict (or set of verdicts) on a case is the learner's answer."""
    return answer in wrong if isinstance(wrong, frozenset) else answer == wrong


@check(uses=("chi2_interval",))
def check_consistency_verdict(verdict):
    """The learner's ``verdict(nis_values, dof, confidence)`` on NIS records of KITTI runs."""
    cases = verdict_cases()
    answers = [call(verdict, values, dof, c) for _, values, dof, c in cases]
    for answer in answers:
        if not isinstance(answer, str) or answer not in consistency_stats.VERDICTS:
            raise CheckFailed(f"verdict returned {answer!r}; it must return one of the strings "
                              f"{', '.join(map(repr, consistency_stats.VERDICTS))}")
    expected = _expected_verdicts()  # a cached list: not to be modified
    if answers == list(expected):
        return
    wrong = [k for k, (a, e) in enumerate(zip(answers, expected)) if a != e]
    i = wrong[0]
    label, values, dof, c = cases[i]
    lo, hi = metrics.chi2_bounds(dof, len(values), c)
    message = (f"for {label} ({dof}-dof NIS, N = {len(values)}) the mean NIS is {np.mean(values):.3f} "
               f"and its {c:.1%} interval [{lo:.3f}, {hi:.3f}]: expected {expected[i]!r}, got "
               f"{answers[i]!r} ({len(wrong)} of {len(cases)} records judged wrongly).")
    why = known_mistake(answers, cases, _verdict_mistakes(), lambda a, w, k: w is not None and _allows(a, w),
                        evaluate=lambda rule, case: rule(*case[1:]))
    raise CheckFailed(f"{message} Hint: " + (why or (
        "test the record as a whole (lecture 09 §1): average the NIS over time and compare the mean with "
        "the two-sided interval of a mean of N values (your chi2_interval(dof, N)). A mean above the "
        "interval means the errors are larger than S says, so the filter is OVERconfident (S too small); "
        "below it, underconfident")))


# --------------------------------------------------------------------------------------
# the challenge: the Monte Carlo NEES test
# --------------------------------------------------------------------------------------

#: Monte Carlo runs of the challenge (lecture 09 §2): runs, first seed, duration [s], and the
#: filters (label, process-noise density scale: 1 is tuned, 0.1 is Q / 100).
MC_RUNS, MC_SEED, MC_DURATION = 20, 0, 15.0
MC_FILTERS = (("the tuned filter", 1.0), ("the filter with Q / 100", 0.1))


@functools.lru_cache(maxsize=None)
def monte_carlo_cases():
    """(label, NEES of each run (n_runs, n_steps), dof, confidence) of simulated runs.

    The ESKF on ``MC_RUNS`` seeded synthetic IMU trajectories with exact truth
    (:func:`kalman_course.chapters.consistency.monte_carlo`), tuned and with Q / 100: the
    15-state NEES and the 6-dof pose NEES, of all runs and of 5 of them, at 90, 95 and
    99 %. n_runs (20 or 5) is never the number of steps (150) nor a dof, so averaging along
    the wrong axis, or taking n_runs from the wrong one, changes the shape or the interval;
    no run average lies closer than 1e-4 (relative) to its bound, so no correct way of
    computing the mean or the quantiles can flip a decision.

    Under a run seed the runs have another first seed (never one of the self-check's); the
    5-run cases take 5 drawn runs, drawn again (cheap: no new runs) until the reference and
    each of :func:`_monte_carlo_mistakes` decide differently somewhere (so each mistake is
    named by its own hint); a step whose run average lies within 1e-4 of a bound is left
    out of its case. The runs themselves are redrawn only if no choice of the 5 separates
    the mistakes, so a graded run costs as many simulated runs as the self-check.
    """
    if not inputs.drawing():
        runs = [consistency.monte_carlo(n_runs=MC_RUNS, seed=MC_SEED, duration=MC_DURATION, process_scale=scale)
                for _, scale in MC_FILTERS]
        return _monte_carlo_frozen(_monte_carlo_built(runs, np.arange(5)))
    g = inputs.rng("consistency.monte_carlo", MC_SEED)
    for _ in range(5):
        # seeds from MC_RUNS on: no run shares a seed with the self-check's runs 0 … MC_RUNS − 1
        seed = int(g.integers(MC_RUNS, 2**31))
        runs = [consistency.monte_carlo(n_runs=MC_RUNS, seed=seed, duration=MC_DURATION, process_scale=scale)
                for _, scale in MC_FILTERS]
        for _ in range(200):
            few = np.sort(g.choice(MC_RUNS, 5, replace=False))
            cases = [(label, _clear_steps(nees, dof, c), dof, c)
                     for label, nees, dof, c in _monte_carlo_built(runs, few)]
            if _monte_carlo_separates(cases):
                return _monte_carlo_frozen(cases)
    raise RuntimeError("no drawn Monte Carlo runs give cases that separate the listed mistakes")


def _monte_carlo_built(runs, few) -> list:
    """The cases of the Monte Carlo results ``runs`` (one per filter of MC_FILTERS); the 5-run
    cases take the runs ``few``."""
    cases = []
    for (label, _), mc in zip(MC_FILTERS, runs):
        cases += [(f"the 15-state NEES of {MC_RUNS} runs of {label}", mc.nees, 15, 0.95),
                  (f"the 6-dof pose NEES of {MC_RUNS} runs of {label}", mc.nees_pose, 6, 0.95),
                  (f"the 15-state NEES of 5 runs of {label}", mc.nees[few], 15, 0.99),
                  (f"the 6-dof pose NEES of 5 runs of {label}", mc.nees_pose[few], 6, 0.9)]
    return cases


def _monte_carlo_frozen(cases) -> tuple:
    for _, runs, _, _ in cases:
        runs.setflags(write=False)           # cached: shared by every call of the check
    return tuple(cases)


def _clear_steps(runs, dof, confidence) -> np.ndarray:
    """The columns (steps) of ``runs`` whose run average is at least 1e-4 (relative) from both
    bounds: there no correct way of computing the mean or the quantiles can flip a decision."""
    bounds = np.array(metrics.chi2_bounds(dof, runs.shape[0], confidence))
    distance = np.abs(runs.mean(axis=0)[:, None] / bounds - 1.0).min(axis=1)
    return np.ascontiguousarray(runs[:, distance >= 1e-4])


def _monte_carlo_separates(cases) -> bool:
    """Whether the reference and every listed mistake decide differently on some case."""
    rules = [_monte_carlo_reference] + [rule for rule, _ in _monte_carlo_mistakes()]
    decisions = {b"".join(np.asarray(rule(runs, dof, c), dtype=bool).tobytes() for _, runs, dof, c in cases)
                 for rule in rules}
    return len(decisions) == len(rules)


def _inside(average, lo, hi):
    return (average >= lo) & (average <= hi)


def _monte_carlo_reference(runs, dof, confidence):
    return _inside(runs.mean(axis=0), *metrics.chi2_bounds(dof, runs.shape[0], confidence))


def _monte_carlo_mistakes():
    """Wrong per-step decisions as functions of (runs (n_runs, n_steps), dof, confidence)."""
    b, q = metrics.chi2_bounds, metrics.chi2_ppf

    def band(bounds, statistic=lambda runs, d: runs.mean(axis=0)):
        return lambda runs, d, c: _inside(statistic(runs, d), *bounds(d, runs.shape[0], runs.shape[1], c))

    return [
        (lambda runs, d, c: ~_monte_carlo_reference(runs, d, c),
         "True and False are swapped: True where the run average is INSIDE its interval."),
        (band(lambda d, n, k, c: b(d, 1, c)),
         "that is the interval of ONE run's NEES; the average of n_runs independent runs is much "
         "narrower: the interval of a mean of n_runs values (your chi2_interval with n_runs)."),
        (band(lambda d, n, k, c: b(d, k, c)),
         "n_runs is the number of runs averaged at each step (the rows, axis 0), not the number of "
         "time steps (the columns)."),
        (band(lambda d, n, k, c: b(d, n * k, c)),
         "that is the interval of a mean over every run AND every step; at one step the average "
         "holds n_runs values only (and values of one run at different steps are not independent)."),
        (band(lambda d, n, k, c: b(d * n, 1, c)),
         "those are the bounds of the SUM of the n_runs values; the run average is the sum divided "
         "by n_runs."),
        (band(lambda d, n, k, c: b(d, n, c), statistic=lambda runs, d: runs.sum(axis=0)),
         "the SUM over the runs is compared with the interval of their mean: average the runs."),
        (band(lambda d, n, k, c: b(d, n, c), statistic=lambda runs, d: runs.mean(axis=0) / d),
         "the run average is divided by dof but the interval is not: compare the average itself."),
        (band(lambda d, n, k, c: b(n, d, c)), "dof and n_runs are swapped in the interval: "
                                              "chi2_interval(dof, n_runs, confidence)."),
        (band(lambda d, n, k, c: (0.0, q(c, d * n) / n)),
         "a one-sided bound: a run average below the interval (an underconfident filter) must fail "
         "too; use the two-sided interval."),
        (band(lambda d, n, k, c: (q(1 - c, d * n) / n, q(c, d * n) / n)),
         "the tails of the interval are (1 − c)/2 each, not 1 − c."),
        (band(lambda d, n, k, c: b(d, n, 1 - c)), "the interval's confidence is 1 − c; it must hold c inside."),
        (band(lambda d, n, k, c: b(d, n, 0.95)), "the 95 % is written into the function: use the "
                                                 "`confidence` argument."),
        (band(lambda d, n, k, c: b(15, n, c)), "15 degrees of freedom are written into the function: "
                                               "use the `dof` argument (the pose NEES has 6)."),
        (band(lambda d, n, k, c: b(d, n - 1, c)), "n_runs − 1: the average of n_runs runs has the "
                                                  "interval of a mean of n_runs values (nothing is "
                                                  "estimated from them)."),
        (band(lambda d, n, k, c: b(d, n, c), statistic=lambda runs, d: np.median(runs, axis=0)),
         "the median of the runs is not χ²-distributed like their mean: average them."),
        (lambda runs, d, c: np.all(_inside(runs, *b(d, 1, c)), axis=0),
         "each run's NEES is tested alone against the interval of one value; the Monte Carlo test "
         "averages the runs at each step and tests that average against its (narrower) interval."),
    ]


def _mask(value, shape: tuple[int, int]) -> np.ndarray:
    """The learner's decisions as a bool array (n_steps,), or a failure with a hint."""
    n_runs, n_steps = shape
    try:
        arr = None if isinstance(value, (str, bytes)) else np.asarray(value)
    except (TypeError, ValueError):
        arr = None
    what = f"monte_carlo_inside on {n_runs} runs of {n_steps} steps"
    if arr is None or arr.dtype == object:
        raise CheckFailed(f"{what} returned a {type_name(value)}; it must return one True/False per "
                          f"time step, an array of shape ({n_steps},)")
    if arr.shape == (n_runs,):
        raise CheckFailed(f"{what} returned {n_runs} values: one per RUN. Hint: each run was averaged "
                          "over time. The NEES of one run is correlated from step to step (an error "
                          "persists), so its time average is not the mean of independent χ² values; "
                          "at each time step, average the independent runs instead (one decision "
                          f"per step, shape ({n_steps},)).")
    if arr.shape == ():
        raise CheckFailed(f"{what} returned one number; it must return one True/False per time step, "
                          f"shape ({n_steps},) (the share inside is their mean, computed afterwards)")
    if arr.shape != (n_steps,):
        raise CheckFailed(f"{what} returned shape {arr.shape}; it must return one True/False per time "
                          f"step, shape ({n_steps},)")
    if arr.dtype != bool and not (np.issubdtype(arr.dtype, np.integer) and np.isin(arr, (0, 1)).all()):
        raise CheckFailed(f"{what} returned {arr.dtype} values; it must return True/False per time step "
                          f"(a boolean array of shape ({n_steps},))")
    return arr.astype(bool)


@check(uses=("chi2_interval",))
def check_monte_carlo_nees(monte_carlo_inside):
    """The learner's ``monte_carlo_inside(nees_runs, dof, confidence)`` on simulated Monte Carlo runs."""
    cases = monte_carlo_cases()
    answers = [_mask(call(monte_carlo_inside, runs, dof, c), runs.shape) for _, runs, dof, c in cases]
    expected = [_monte_carlo_reference(runs, dof, c) for _, runs, dof, c in cases]
    wrong = [int(np.sum(a != e)) for a, e in zip(answers, expected)]
    if not any(wrong):
        return
    i = next(k for k, w in enumerate(wrong) if w)
    label, runs, dof, c = cases[i]
    message = (f"for {label} ({c:.0%}), {wrong[i]} of {runs.shape[1]} steps are judged wrongly "
               f"({sum(1 for w in wrong if w)} of {len(cases)} cases wrong).")
    why = known_mistake(answers, cases, _monte_carlo_mistakes(), lambda a, w, k: w is not None and np.array_equal(w, a),
                        evaluate=lambda rule, case: rule(*case[1:]))
    if why is not None:
        raise CheckFailed(f"{message} Hint: {why}")
    raise CheckFailed(f"{message} Hint: at each time step, average the NEES of the n_runs independent "
                      "runs and test that average against the two-sided interval of a mean of n_runs "
                      "χ²(dof) values (lecture 09 §1–2).")
