"""Checks for chapter 10 (real sensors): the Gauss–Markov observation error and the augmented
ESKF's F and Q, the relative pose of visual odometry (increment, residual, Jacobian), KITTI's
drift metric, and (the optional challenge) one step of choosing the VO noise by the NIS.

Cases (what is real, what is simulated)
---------------------------------------
- Gauss–Markov blocks: made-up stationary σ, different on every component (m and rad), time
  constants 0.5–5 s and steps 0.01–2 s, including steps longer than τ, where the first-order
  forms are off by a factor (the first-order decay 1 − T/τ even turns negative); then, judged
  after those, a sweep of T/τ from 1e-6 to 1e3 (three a decade, steps from 5e-8 s to 3e5 s, σ
  from 4 mrad to 40 m: both sides of 1), where a special case for short or long steps shows.
- Augmented matrices: the plain ESKF's F and B Q Bᵀ (:mod:`kalman_course.filters.eskf`) at
  states of the real KITTI ground truth of ``turns`` (tilted, made-up non-zero biases), steps of
  0.01, 0.104 and 1 s; the observation error made up: six Gauss–Markov components with their own
  time constants (:data:`AUG_TAU_FACTORS`, position errors longer than attitude errors) and
  correlated drives (:data:`AUG_DRIVE_CORRELATION`), whose stationary covariance Σ
  (:func:`stationary_covariance`) has correlations up to 0.61; and the first of them again with
  the base τ from 1e6 T down to 1e-3 T (T ≪ τ to T ≫ τ).
- Relative motion, residual and Jacobian: pairs of real KITTI ground-truth poses (``turns``)
  0.1, 1 and 3 s apart (up to 1.45 rad of turning), tilted by up to ~0.5 rad so that no
  rotation is about the vertical alone; the same pairs moved by one rigid transform (a relative
  pose must not change); measured increments are the true ones plus seeded noise (simulated);
  the residual and the Jacobian also for a camera's increments, at KITTI's cam0 lever arm (real
  calibration, 1.37 m from the IMU) and at a made-up one (:data:`MADE_UP_LEVER_ARM`);
  and a turn sweep: a tilted KITTI pose and made-up poses turned from it by 1e-8 and 1e-4 rad
  and by π − 1e-3 and π − 1e-6 rad, each about an axis and about its opposite (the Jacobian
  takes the two nearest a half turn).
- Drift: the real ORB-SLAM2 and S-PTAM tracks of sequence 00, anchored to the truth at one frame
  as in lecture 10 §2 (:func:`kalman_course.chapters.visual_odometry.setup`), against the real
  ground truth, every 5th of the first 1550 frames (about 160 s), segments of 50, 100, 200 and
  400 m.
- Challenge: innovations and their S of the relative VO filter
  (:func:`kalman_course.chapters.visual_odometry.run_relative_vo`: real IMU, real VO) over the
  first 60 s, run with σ's that are too small and too large (median NIS off its χ² median by
  factors from 1/1300 to 39), cut into blocks of 1, 2 and 3 components of one unit each.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every family is drawn anew from
the same sources: the Gauss–Markov σ, T and τ (made up, over the same ranges, a step 2.5–6
times τ among them); the augmented cases at three other IMU samples of ``turns`` (real truth
state and IMU reading) with other made-up tilts, biases, σ, T, τ factors and drive
correlations (Σ's correlations then 0.3–0.6); the made-up lever arm (0.5–2 m, any direction); other pairs of real
``turns`` truth poses (the same spread of gaps, other tilts, another rigid transform of 1 rad
to nearly π, redrawn until some pair turns by 1 rad), hence other residual and Jacobian cases
(the measured increments' noise, simulated, drawn again); the drift metric on another window
of the same real VO tracks and truth of sequence 00 (its start, length and stride, the segment
lengths and step drawn; segments with a rotational error under 5e-4 rad left out, so that the
arccos of the trace still agrees within the tolerance); and for the challenge the real VO
filter's runs over a stretch of 40–60 s with other σ factors (too small and too large) and
other blocks of 1, 2 and 3 components.

A learner's function is run on every case before anything is judged, and a known mistake is
named only when it reproduces the learner's results on every case (a wrong formula is
consistent; agreeing with the right one on one case is a coincidence), so each hint names the
mistake made.

Tolerances (and why; "measured" numbers are over these cases)
-------------------------------------------------------------
- Gauss–Markov blocks, augmented F and Q, relative motion, the position part of the residual:
  :data:`RTOL` relative, :data:`ATOL` absolute: round-off only (exp, expm1, block_diag, solve
  and the order of products agree to ~1e-15; Q_e by expm1 and Σ − F_e Σ F_eᵀ agree to ~5e-11
  relative at T/τ = 1e-6); every listed mistake is off by more than 1e-2 relative on some case
  (measured), except for F_aug and Q_aug's closest, one decay per row symmetrised afterwards,
  off by 6.5e-4 to 1.2e-3 relative (measured on the fixed cases and two run seeds).
- The attitude part of the residual: |y_θ|² + 1e-12 absolute (as chapter 08's pose residual), so
  the lecture's first-order (ΔR_mᵀ ΔŘ − I)^∨ passes (it differs from the Log by less than
  |y_θ|²/4); every listed mistake errs by O(|y_θ|) or O(|ΔŘ| |y_θ|) on the 1–3 s cases
  (|y_θ| ≈ 0.02–0.09 rad, turning up to 1.45 rad): 17 times the tolerance or more (measured).
- Jacobian: :data:`JACOBIAN_ATOL` absolute against central differences of the residual
  (h = 1e-6; they agree with the analytic blocks to 5e-9, measured, with and without a lever
  arm); every listed mistake errs by more than 0.9 in some block entry (measured).
- Drift: :data:`DRIFT_RTOL` relative on every segment's errors: the angle by an arccos of the
  trace loses precision at small angles (at the smallest rotational error here, 1e-3 rad, it
  differs from the norm of the Log by up to 1.8e-9 relative, measured; a drawn case keeps no
  segment under 5e-4 rad, where it loses ~1e-8); the other ways of
  writing it agree to ~1e-14; every listed mistake is off by more than 20 % on some segment
  (measured).
- Challenge: :data:`RTOL` relative on the new σ (solve, inv, Cholesky and einsum give NIS values
  equal to ~1e-13; χ² quantiles from the package or scipy agree to ~1e-12). The closest listed
  mistake, only the diagonal of S, is off by 2e-4 relative (measured: the components of one
  increment's innovation correlate weakly); the others by 30 % or more.
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np

from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.checks import hints
from kalman_course.checks.harness import CheckFailed, as_array, call, check, known_mistake, type_name
from kalman_course.chapters import visual_odometry as vo
from kalman_course.chapters.real_sensors import relative_jacobian_by_differences
from kalman_course.core import so3
from kalman_course.core.numdiff import numerical_jacobian
from kalman_course.core.linalg import symmetrise
from kalman_course.data import load_kitti
from kalman_course.evaluation import metrics
from kalman_course.evaluation.drift import drift
from kalman_course.filters import eskf, eskf_augmented, eskf_relative
from kalman_course.filters.eskf import NominalState

#: Relative and absolute tolerance of the exact formulas (see the module notes).
RTOL, ATOL = 1e-9, 1e-12
#: Relative tolerance of the drift metric's per-segment errors (see the module notes).
DRIFT_RTOL = 1e-7
#: Absolute tolerance of a Jacobian against central differences (see the module notes).
JACOBIAN_ATOL = 1e-6
#: Step of the central differences.
FD_STEP = 1e-6

#: Gauss–Markov cases: (stationary σ (6,) [m ×3, rad ×3], T s, τ s). σ differs per component and
#: the steps include T > τ.
_SIGMA_A = np.array([0.2, 0.15, 0.35, 0.004, 0.006, 0.009])
_SIGMA_B = np.array([1.5, 0.8, 2.5, 0.02, 0.01, 0.03])
GM_CASES = ((_SIGMA_A, 0.104, 0.5), (_SIGMA_A, 0.01, 3.0), (_SIGMA_B, 2.0, 0.5), (_SIGMA_B, 0.37, 1.3),
            (_SIGMA_A, 1.0, 5.0))

#: Under a run seed, the Gauss–Markov cases' ranges of τ (s) and of T/τ, in the order of GM_CASES:
#: a lidar step, an IMU step, a step 2.5–6 times τ (where 1 − T/τ < −1.5), and two in between.
#: τ never reaches 1 s (where T τ and T/τ coincide) and T/τ never 1 (where τ/T does).
GM_DRAWN = (((0.3, 0.8), (0.1, 0.4)), ((1.5, 5.0), (0.002, 0.01)), ((0.3, 0.8), (2.5, 6.0)),
            ((1.1, 2.0), (0.2, 0.5)), ((3.0, 6.0), (0.1, 0.3)))
#: ... and the ranges of the stationary σ per component, m (position) and rad (attitude).
SIGMA_DRAWN = ((0.1, 3.0), (0.002, 0.05))

#: The sweep of the Gauss–Markov checks, judged after their main cases: ratios T/τ log-spaced from
#: GM_SWEEP_RATIOS[0] (where a learner's series or "φ ≈ 1 − T/τ for small steps" would be
#: accurate to 5e-13, below the tolerance) to GM_SWEEP_RATIOS[1] (where φ = exp(−1000) is 0
#: exactly), GM_SWEEP_COUNT of them (three a decade: a cut-off "φ = 0 beyond 20 τ", off by
#: exp(−20) = 2e-9, meets T/τ = 21.5, where φ is still 4.6e-10, above ATOL); τ cycles through GM_SWEEP_TAUS (s), so that the steps T
#: range from 5e-8 s to 3e5 s; σ on both sides of 1 (made up: σ ≠ σ², and Q_e well above the
#: absolute tolerance even at the shortest step, 3e-11 for σ = 4 mrad). Every correct way of
#: writing the blocks agrees to 5e-11 relative even at T/τ = 1e-6 (1 − φ² loses digits to
#: cancellation there), 20 times inside RTOL.
GM_SWEEP_RATIOS, GM_SWEEP_COUNT = (1e-6, 1e3), 28
GM_SWEEP_TAUS = (0.05, 3.0, 300.0)
GM_SWEEP_SIGMA = np.array([0.03, 2.5, 40.0, 0.004, 0.6, 1.8])
#: Under a run seed: each ratio moved by a drawn factor within its decade, τ drawn from
#: GM_SWEEP_TAUS_DRAWN (s), σ drawn per component from SIGMA_SWEEP_DRAWN (spanning 1).
GM_SWEEP_TAUS_DRAWN = (0.02, 500.0)
SIGMA_SWEEP_DRAWN = (0.003, 50.0)

#: Augmented-matrix cases: (IMU step or interval T s, base time constant τ s); one KITTI state each (IMU
#: sample). Each component's τ is the base times its factor in AUG_TAU_FACTORS (position errors last
#: longer than attitude errors), so no two components share one.
AUG_STEPS = ((0.01, 0.5), (0.104, 1.0), (1.0, 3.0))
AUG_SAMPLES = (700, 2500, 4400)
AUG_TAU_FACTORS = np.array([1.6, 1.0, 2.2, 0.45, 0.6, 0.35])
#: The correlations of the white drives of the six components (x, y, z, roll, pitch, yaw of the map
#: matcher's error): a lateral shift goes with a yaw error, a vertical one with roll and pitch. The
#: stationary covariance Σ has correlations C_ij · 2√(τ_i τ_j)/(τ_i + τ_j), up to 0.61 here.
AUG_DRIVE_CORRELATION = np.array([
    [1.0, 0.3, 0.0, 0.0, 0.0, 0.2],
    [0.3, 1.0, 0.0, 0.1, 0.0, 0.7],
    [0.0, 0.0, 1.0, -0.4, 0.3, 0.0],
    [0.0, 0.1, -0.4, 1.0, 0.25, 0.0],
    [0.0, 0.0, 0.3, 0.25, 1.0, 0.0],
    [0.2, 0.7, 0.0, 0.0, 0.0, 1.0]])
#: Under a run seed, the ranges of T and of the base τ (s) of each augmented case: T always below
#: every τ (the factors are drawn from AUG_TAU_FACTORS_DRAWN) and the ranges apart, so that swapping
#: them changes F_e.
AUG_DRAWN = (((0.005, 0.02), (0.8, 1.6)), ((0.05, 0.2), (1.0, 2.5)), ((0.5, 1.0), (3.0, 6.0)))
AUG_TAU_FACTORS_DRAWN = (0.35, 2.5)
#: The augmented cases' sweep: the first case's step (its F and B Q Bᵀ) again, with base τ = T / ratio
#: for these ratios T/τ (from T ≪ τ to T ≫ τ, as the Gauss–Markov sweep); under a run seed each
#: ratio is moved by a drawn factor of up to 3 either way.
AUG_SWEEP_RATIOS = (1e-6, 1e-2, 10.0, 1e3)
#: ESKF noise densities of the cases (accel, gyro, accel bias, gyro bias), as chapter 08's.
DENSITY = np.array([0.03, 1e-3, 1.67e-4, 2.91e-6])

#: A made-up camera lever arm (m, body frame) beside KITTI's cam0 (:func:`camera_lever_arms`): behind,
#: left and above the IMU, no component near zero, the signs of x and y opposite to KITTI's.
MADE_UP_LEVER_ARM = np.array([-0.45, 0.9, 1.6])

#: Pose-pair cases: (truth frame of the clone, frames later) on ``turns``; 10 frames ≈ 1 s.
POSE_PAIRS = ((100, 1), (100, 30), (260, 10), (380, 30), (530, 10))
#: The rigid transform every pair is also moved by: rotation vector (rad) and translation (m).
MOVE_ROTATION = np.array([0.3, -0.5, 2.0])
MOVE_TRANSLATION = np.array([120.0, -45.0, 3.0])
#: Under a run seed, the ranges of the frames between the two poses of each pair, in the order
#: of POSE_PAIRS, and the least rotation (rad) the largest relative rotation must reach (the
#: fixed pairs' reaches 1.45 rad; subtracting rotation vectors is wrong by O(|ΔŘ| |y_θ|)).
POSE_GAPS_DRAWN = ((1, 2), (20, 35), (8, 14), (20, 35), (8, 14))
POSE_TURN_DRAWN = 1.0
#: The turn sweep of the relative-pose checks: a tilted KITTI truth pose (frame) and a second pose
#: turned from it by each of these angles (rad), about a drawn axis and about its opposite (both
#: signs), and moved by a drawn 0.5–3 m: increments near the identity, where every side and
#: order of the products almost agree, and near a half turn, where rotation vectors wrap (the
#: Log of an increment of π − 1e-6 rad may come back as a turn the other way). Under a run seed
#: each angle's distance from 0 or π is moved by a drawn factor of up to 3 either way.
TURN_SWEEP_FRAME = 300
TURN_SWEEP_ANGLES = (1e-8, 1e-4, np.pi - 1e-3, np.pi - 1e-6)

#: Drift cases: VO systems, frames (every ``DRIFT_STRIDE``-th of the first ``DRIFT_FRAMES``
#: after the anchor frame), segment lengths (m) and the step between segment starts (frames).
DRIFT_SYSTEMS = ("ORB-SLAM2", "S-PTAM")
DRIFT_FRAMES, DRIFT_STRIDE = 1550, 5
DRIFT_LENGTHS = (50.0, 100.0, 200.0, 400.0)
DRIFT_STEP = 3
#: Under a run seed: the window's length (frames) and stride, each segment length's range (m)
#: and the step's; a drawn case keeps the segments whose rotational error is at least
#: DRIFT_LEAST_ANGLE rad (where an arccos of the trace still agrees to ~1e-8) and every
#: length must keep DRIFT_LEAST_SEGMENTS of them.
DRIFT_WINDOW_DRAWN, DRIFT_STRIDES_DRAWN = (1300, 1800), (4, 5, 6)
DRIFT_LENGTHS_DRAWN = ((40.0, 60.0), (80.0, 130.0), (170.0, 260.0), (330.0, 450.0))
DRIFT_STEPS_DRAWN = (2, 3, 4)
DRIFT_LEAST_ANGLE, DRIFT_LEAST_SEGMENTS = 5e-4, 5

#: Challenge: the calibration stretch (s) and the σ's the runs use, as factors of 1 cm / 0.01°.
NIS_SECONDS = 60.0
NIS_FACTORS = (1.0, 30.0)
_NIS_STD0 = np.array([0.01, 0.01, 0.01, 1.7e-4, 1.7e-4, 1.7e-4])
NIS_BLOCKS = ((0, 3), (3, 6), (0, 1), (5, 6), (1, 3))
#: Under a run seed: the stretch's range (s, never longer than the self-check's) and each run's
#: σ factor range (too small, too large), drawn per VO system.
NIS_SECONDS_DRAWN = (40.0, 60.0)
NIS_FACTORS_DRAWN = ((0.6, 1.6), (20.0, 45.0))


# --------------------------------------------------------------------------------------
# judging, shared by every check
# --------------------------------------------------------------------------------------

def _close(value, wanted, atol, rtol=RTOL) -> bool:
    if value is None or wanted is None:
        return False
    value, wanted = np.asarray(value, dtype=float), np.asarray(wanted, dtype=float)
    return value.shape == wanted.shape and bool(np.allclose(value, wanted, rtol=rtol, atol=atol))


def _evaluate(formula: Callable, case):
    """A (right or wrong) formula on one case, or None where it raises or is not finite."""
    try:
        with np.errstate(all="ignore"):
            value = np.asarray(formula(*case), dtype=float)
    except Exception:  # a mistake need not even have the right shapes on every case
        return None
    return value if np.all(np.isfinite(value)) else None


#: The hint for results that agree with the reference to single precision only, and the largest
#: relative error where it applies (float32 keeps about 7 digits; every listed mistake is off by
#: more than 1e-3 relative on some case, see the module notes).
SINGLE_PRECISION = ("the results agree with the reference to only 4–7 digits, as a computation in single precision "
                    "(float32) does; keep NumPy's default float64 throughout")
SINGLE_PRECISION_RTOL = 1e-4


def _single_precision(got, wanted) -> bool:
    """Whether every result is within :data:`SINGLE_PRECISION_RTOL` of its reference (and of its shape)."""
    return all(g is not None and w is not None and np.shape(g) == np.shape(w)
               and bool(np.allclose(np.asarray(g, dtype=float), w, rtol=SINGLE_PRECISION_RTOL, atol=1e-9))
               for g, w in zip(got, wanted))


def _judge(what: str, got: list, cases, labels, reference: Callable, mistakes, hint: str,
           atol=ATOL, rtol=RTOL, precision: bool = True) -> None:
    """Fail unless ``got[k]`` matches ``reference(*cases[k])`` on every case.

    ``mistakes`` is a list of (formula, why): a formula of a case's arguments giving a wrong
    value; the first that reproduces the learner's values on every case is named
    (:func:`harness.known_mistake`). ``atol`` may be a function of the case (a per-case
    tolerance). With ``precision``, results that agree to single precision only are told so
    (off where a check's cases are built to show small approximations, as a sweep's are).
    """
    tol = atol if callable(atol) else (lambda *case: atol)
    wanted = [reference(*case) for case in cases]
    wrong = [k for k, case in enumerate(cases) if not _close(got[k], wanted[k], tol(*case), rtol)]
    if not wrong:
        return
    k = wrong[0]
    summary = f"{len(wrong)} of {len(cases)} cases wrong"
    why = known_mistake(got, cases, mistakes, lambda g, w, n: _close(g, w, tol(*cases[n]), rtol), evaluate=_evaluate)
    if why is not None:
        raise CheckFailed(f"{what} is wrong ({labels[k]}; {summary}). Hint: {why}")
    err = np.abs(np.asarray(got[k], dtype=float) - wanted[k]).max()
    message = f"{what} differs from the reference ({labels[k]}; max abs error {err:.3g}, {summary})."
    if precision and _single_precision(got, wanted):
        raise CheckFailed(f"{message} Hint: {SINGLE_PRECISION}")
    raise CheckFailed(f"{message} Hint: {hint}")


def _pair(value, what: str, names: tuple[str, str]):
    """A learner's result that must be a pair (a, b)."""
    if isinstance(value, (tuple, list)) and len(value) == 2:
        return value
    raise CheckFailed(f"{what} must return a tuple ({names[0]}, {names[1]}), got a {type_name(value)}")


def _array(value, shape: tuple, what: str, diag_hint: bool = False) -> np.ndarray:
    """A learner's array of exactly ``shape`` and finite, or a failure that says what came back."""
    arr = as_array(value, what)
    if arr.shape != tuple(shape):
        extra = ""
        if diag_hint and arr.shape == (shape[0],):
            extra = f" (a vector of the diagonal? the check wants the {shape[0]} × {shape[1]} matrix: np.diag)"
        elif arr.shape == ():
            extra = f" (a number? the check wants the {' × '.join(map(str, shape))} matrix)"
        raise CheckFailed(f"{what} has shape {arr.shape}, expected {tuple(shape)}{extra}")
    if not np.all(np.isfinite(arr)):
        raise CheckFailed(f"{what} contains NaN or inf")
    return arr


# --------------------------------------------------------------------------------------
# 1. the Gauss–Markov blocks
# --------------------------------------------------------------------------------------

_phi = eskf_augmented.gauss_markov_decay


def _drawn_sigma(g: np.random.Generator) -> np.ndarray:
    """Six stationary σ, each its own: three in m, three in rad (:data:`SIGMA_DRAWN`)."""
    return np.r_[inputs.log_uniform(g, *SIGMA_DRAWN[0], 3), inputs.log_uniform(g, *SIGMA_DRAWN[1], 3)]


def _draw_gm_cases(g: np.random.Generator) -> tuple:
    cases = []
    for tau_range, ratio_range in GM_DRAWN:
        tau = float(inputs.log_uniform(g, *tau_range))
        cases.append((_drawn_sigma(g), tau * float(inputs.log_uniform(g, *ratio_range)), tau))
    return tuple(cases)


@functools.lru_cache(maxsize=None)
def gm_cases():
    """(σ (6,), T, τ) of the Gauss–Markov check: :data:`GM_CASES`, or under a run seed drawn from
    the same ranges (:data:`GM_DRAWN`, :data:`SIGMA_DRAWN`; all made up, as the fixed ones)."""
    return inputs.fixed_or_drawn(GM_CASES, _draw_gm_cases, "real_sensors.gauss_markov")


@functools.lru_cache(maxsize=None)
def gm_sweep():
    """(σ (6,), T, τ) of the Gauss–Markov sweep (:data:`GM_SWEEP_RATIOS`): from T ≪ τ to T ≫ τ.

    Under a run seed each ratio is moved within its decade (never beyond the sweep's ends), and τ
    and σ are drawn (:data:`GM_SWEEP_TAUS_DRAWN`, :data:`SIGMA_SWEEP_DRAWN`).
    """
    ratios = np.logspace(*np.log10(GM_SWEEP_RATIOS), GM_SWEEP_COUNT)

    def fixed():
        taus = [GM_SWEEP_TAUS[k % len(GM_SWEEP_TAUS)] for k in range(len(ratios))]
        return tuple((GM_SWEEP_SIGMA, float(r * tau), float(tau)) for r, tau in zip(ratios, taus))

    def draw(g):
        step = ratios[1] / ratios[0]
        moved = np.clip(ratios * inputs.log_uniform(g, 1 / np.sqrt(step), np.sqrt(step), len(ratios)),
                        *GM_SWEEP_RATIOS)
        out = []
        for r in moved:
            tau = float(inputs.log_uniform(g, *GM_SWEEP_TAUS_DRAWN))
            out.append((inputs.log_uniform(g, *SIGMA_SWEEP_DRAWN, 6), float(r * tau), tau))
        return tuple(out)

    cases = inputs.fixed_or_drawn(fixed(), draw, "real_sensors.gauss_markov_sweep")
    for sigma, _, _ in cases:
        sigma.setflags(write=False)
    return cases


#: The hint when a function is right on a check's main cases but not across its sweep.
_SWEEP_HINT = ("your blocks are right on the check's main cases but not across its sweep of T/τ from 1e-6 to 1e3: "
               "the exact decay and its stationary variance hold for every step, long or short (lecture 10 §1), "
               "so a special case, a cut-off or an approximation for small or large T/τ (a series, φ = 0 beyond "
               "some T) shows here")


def _gm_F(sigma, T, tau):
    return _phi(T, tau) * np.eye(6)


def _gm_Q(sigma, T, tau):
    return np.diag(eskf_augmented.gauss_markov_noise(sigma, T, tau))


def _gm_label(sigma, T, tau) -> str:
    return f"T = {T:g} s, τ = {tau:g} s, σ = ({', '.join(f'{v:g}' for v in sigma)})"


def _longest_step(cases) -> tuple[float, float]:
    """(T, τ) of the case whose step is longest against τ: the one a hint quotes."""
    return max(((T, tau) for _, T, tau in cases), key=lambda step: step[0] / step[1])


def _minus(x: float) -> str:
    return f"{x:.3g}".replace("-", "−")


def _euler_hint(cases) -> str:
    T, tau = _longest_step(cases)
    grows = {2.0: "doubles", 3.0: "triples"}.get(round(T / tau - 1.0, 12), f"grows {T / tau - 1.0:.3g}-fold")
    return (f"F_e = (1 − T/τ) I is the first-order (Euler) step of ė = −e/τ, right only for T ≪ τ: "
            f"at T = {T:g} s and τ = {tau:g} s it is {_minus(1.0 - T / tau)} I, an error that flips sign and "
            f"{grows}. The equation has an exact solution over any step (lecture 10 §1): how much of e "
            "survives T seconds?")


def _gm_f_mistakes(cases):
    """The wrong F_e formulas of (σ, T, τ) and their hints (one quotes the longest step of ``cases``)."""
    return [(lambda s, T, tau: (1.0 - T / tau) * np.eye(6), _euler_hint(cases))] + _GM_F_MISTAKES


_GM_F_MISTAKES = [
    (lambda s, T, tau: np.exp(-tau / T) * np.eye(6),
     "the exponent is upside down: a longer step (or a shorter memory τ) must leave LESS of the error "
     "(lecture 10 §1)" + hints.formula("; the exponent is −T/τ, a ratio of seconds to seconds")),
    (lambda s, T, tau: np.exp(-T * tau) * np.eye(6),
     "T·τ has units of s²: the exponent of the decay must be dimensionless (lecture 10 §1)" + hints.formula(", −T/τ")),
    (lambda s, T, tau: np.exp(T / tau) * np.eye(6),
     "sign: the error decays (ė = −e/τ), so the factor over the step is below 1 (lecture 10 §1)"),
    (lambda s, T, tau: _phi(T, tau) ** 2 * np.eye(6),
     "φ² = exp(−2T/τ) is how the VARIANCE decays over the step; F_e carries the error itself, the share of "
     "it that survives the step (lecture 10 §1)" + hints.formula(": φ")),
    (lambda s, T, tau: np.exp(-T / tau * np.eye(6)),
     "np.exp of a matrix is element-wise: the off-diagonal zeros became exp(0) = 1, coupling all six "
     "components. Multiply the identity by the scalar decay instead"),
    (lambda s, T, tau: np.eye(6),
     "F_e = I keeps the whole error for ever (a random constant or random walk): a Gauss–Markov error "
     "forgets itself with the time constant τ"),
    (lambda s, T, tau: _gm_Q(s, T, tau),
     "F_e and Q_e are swapped: gauss_markov_blocks returns (F_e, Q_e)"),
    (lambda s, T, tau: np.zeros((6, 6)),
     "F_e = 0 forgets the error at every step: that is white noise, chapter 08's assumption, which this "
     "model replaces"),
]

def _gm_q_mistakes(cases):
    """The wrong Q_e formulas of (σ, T, τ) and their hints (one quotes the longest step of ``cases``)."""
    T, tau = _longest_step(cases)
    first_order = (f"Q_e = 2σ²T/τ is the first-order variance (the continuous density 2σ²/τ times T), right "
                   f"only for T ≪ τ: at T = {T:g} s, τ = {tau:g} s it is {2.0 * T / tau:.3g}σ², far above the "
                   "stationary σ². Use the exact solution: the new part must keep the error's variance "
                   f"stationary (lecture 10 §1)" + hints.formula(": F_e diag(σ²) F_eᵀ + Q_e = diag(σ²)"))
    return [(lambda s, T, tau: np.diag(2.0 * s ** 2 / tau * T), first_order)] + _GM_Q_MISTAKES


_GM_Q_MISTAKES = [
    (lambda s, T, tau: np.diag(s ** 2 * T),
     "σ²T is how a white noise of density σ integrates; here σ is the error's stationary standard "
     "deviation (m or rad), so σ²T has the wrong units (m²·s). The new part must keep the variance "
     "stationary (lecture 10 §1)" + hints.formula(": F_e diag(σ²) F_eᵀ + Q_e = diag(σ²)")),
    (lambda s, T, tau: np.diag(s ** 2),
     "the whole stationary variance σ² is added at every step, as for white noise: most of the error "
     "is carried over by F_e, and only what keeps the variance at σ² is new (lecture 10 §1)"),
    (lambda s, T, tau: np.diag(s ** 2 * (1.0 - _phi(T, tau))),
     "σ²(1 − φ): the variance carried over by F_e is φ² σ² (F_e σ² F_eᵀ), not φ σ² (lecture 10 §1)"
     + hints.formula(", so the new part is σ²(1 − φ²)")),
    (lambda s, T, tau: np.diag(s ** 2 * (1.0 - _phi(T, tau)) ** 2),
     "σ²(1 − φ)² is not what keeps the variance stationary (lecture 10 §1)"
     + hints.formula(": F_e σ² F_eᵀ + Q_e = σ² gives σ²(1 − φ²)")),
    (lambda s, T, tau: np.diag(s * (1.0 - _phi(T, tau) ** 2)),
     "σ is a standard deviation: Q_e holds variances, σ²"),
    (lambda s, T, tau: np.diag(s * np.sqrt(1.0 - _phi(T, tau) ** 2)),
     "that is the standard deviation of the new part; Q_e is its covariance (a variance on the diagonal)"),
    (lambda s, T, tau: np.diag(s ** 2 * _phi(T, tau) ** 2),
     "φ²σ² is the part of the variance CARRIED OVER by F_e; Q_e is what is new (lecture 10 §1)"
     + hints.formula(", σ²(1 − φ²)")),
    (lambda s, T, tau: np.diag(np.full(6, s[0] ** 2) * (1.0 - _phi(T, tau) ** 2)),
     "one σ for all six components: sigma holds one stationary σ per component (m for position, rad "
     "for attitude)"),
    (lambda s, T, tau: np.zeros((6, 6)),
     "Q_e = 0: nothing new enters, so the error would decay to zero and the filter would learn it "
     "exactly; keep its variance stationary"),
]


@check
def check_gauss_markov_blocks(gauss_markov_blocks):
    """``gauss_markov_blocks(sigma, T, tau)`` returns (F_e (6, 6), Q_e (6, 6)) of one step."""
    cases, sweep = gm_cases(), gm_sweep()
    results = [_pair(call(gauss_markov_blocks, sigma, T, tau), "gauss_markov_blocks", ("F_e", "Q_e"))
               for sigma, T, tau in cases + sweep]
    results, swept = results[:len(cases)], results[len(cases):]
    labels = [_gm_label(*case) for case in cases]
    F = [_array(r[0], (6, 6), f"F_e ({label})", diag_hint=True) for r, label in zip(results, labels)]
    _judge("F_e", F, cases, labels, _gm_F, _gm_f_mistakes(cases),
           "the error decays with time constant τ; F_e = φ I with φ the share of the error that survives "
           "T seconds (lecture 10 §1)")
    Q = [_array(r[1], (6, 6), f"Q_e ({label})", diag_hint=True) for r, label in zip(results, labels)]
    _judge("Q_e", Q, cases, labels, _gm_Q, _gm_q_mistakes(cases),
           "Q_e is the covariance of what is new in the error after the step; it must keep the error's "
           "variance stationary (lecture 10 §1)" + hints.formula(": F_e diag(σ²) F_eᵀ + Q_e = diag(σ²)"))
    _judge_sweep(swept, sweep)


def _judge_sweep(results, sweep) -> None:
    """Judge ``gauss_markov_blocks``' results on the sweep (after its main cases passed)."""
    labels = [f"T/τ = {T / tau:.2g}: {_gm_label(sigma, T, tau)}" for sigma, T, tau in sweep]
    for k, name in enumerate(("F_e", "Q_e")):
        try:
            got = [_array(r[k], (6, 6), f"{name} ({label})") for r, label in zip(results, labels)]
        except CheckFailed as exc:
            raise CheckFailed(f"{exc} Hint: {_SWEEP_HINT}") from None
        _judge(name, got, sweep, labels, (_gm_F, _gm_Q)[k], (), _SWEEP_HINT, precision=False)


# --------------------------------------------------------------------------------------
# 2. the augmented transition and process noise
# --------------------------------------------------------------------------------------

def stationary_covariance(sigma, tau, correlation) -> np.ndarray:
    """Σ (6, 6) of six first-order Gauss–Markov components driven by correlated white noise.

    Component i has stationary standard deviation ``sigma[i]`` and time constant ``tau[i]``;
    the drives have the correlation matrix ``correlation`` (positive definite). Σ solves
    A Σ + Σ A = Q_c with A = diag(1/τ), so Σ_ij = C_ij σ_i σ_j · 2√(τ_i τ_j)/(τ_i + τ_j): a
    covariance for any τ, and one step of any length keeps it (F_e Σ F_eᵀ + Q_e = Σ).
    """
    sigma, tau = np.asarray(sigma, dtype=float), np.asarray(tau, dtype=float)
    shrink = 2.0 * np.sqrt(np.outer(tau, tau)) / np.add.outer(tau, tau)
    return symmetrise(np.outer(sigma, sigma) * np.asarray(correlation, dtype=float) * shrink)


def _drawn_correlation(rng: np.random.Generator) -> np.ndarray:
    """A drawn correlation matrix of six drives with correlations up to about ±0.7."""
    L = rng.normal(size=(6, 6))
    M = L @ L.T + 3.0 * np.eye(6)
    d = np.sqrt(np.diag(M))
    return M / np.outer(d, d)


def _aug_case(F, BQBt, sigma, T, tau, correlation):
    Sigma = stationary_covariance(sigma, tau, correlation)
    tau = np.array(tau, dtype=float)
    for arr in (F, BQBt, Sigma, tau):
        arr.setflags(write=False)
    return (F, BQBt, Sigma, T, tau)


@functools.lru_cache(maxsize=None)
def augmented_cases():
    """(F (15, 15), B Q Bᵀ (15, 15), Σ (6, 6), T, τ (6,)) at KITTI truth states (real) with made-up biases.

    Σ is the stationary covariance of correlated components (:func:`stationary_covariance`, the
    drives' correlations :data:`AUG_DRIVE_CORRELATION`), τ one per component. Under a run seed: three
    other IMU samples of the excerpt (their truth state and real IMU reading), T, the base τ
    (:data:`AUG_DRAWN`), the τ factors, the correlations and σ (:data:`SIGMA_DRAWN`) drawn, and
    other tilts and biases.
    """
    ex = load_kitti("turns")
    rng = inputs.rng("real_sensors.augmented", 10)
    settings = zip(AUG_STEPS, AUG_SAMPLES, (_SIGMA_A, _SIGMA_B, _SIGMA_A[::-1].copy()),
                   [AUG_TAU_FACTORS] * 3, [AUG_DRIVE_CORRELATION] * 3)
    if inputs.drawing():
        samples = np.sort(rng.choice(np.arange(10, len(ex.imu.t) - 10), len(AUG_DRAWN), replace=False))
        steps = [tuple(float(inputs.log_uniform(rng, *r)) for r in ranges) for ranges in AUG_DRAWN]
        settings = zip(steps, samples, [_drawn_sigma(rng) for _ in AUG_DRAWN],
                       [inputs.log_uniform(rng, *AUG_TAU_FACTORS_DRAWN, 6) for _ in AUG_DRAWN],
                       [_drawn_correlation(rng) for _ in AUG_DRAWN])
    cases = []
    for (T, tau), k, sigma, factors, correlation in settings:
        nav = ex.truth.state_at(float(ex.imu.t[k]))
        R = nav.rotation @ so3.exp(rng.normal(size=3) * 0.3)
        b_a, b_w = rng.normal(size=3) * 0.05, rng.normal(size=3) * 0.005
        F_t = eskf.error_dynamics(R, ex.imu.specific_force[k], ex.imu.angular_rate[k], b_a, b_w)
        F, B = eskf.discretise(F_t, eskf.noise_jacobian(R), T)
        BQBt = symmetrise(B @ eskf.process_noise(DENSITY, T) @ B.T)
        cases.append(_aug_case(F, BQBt, sigma, T, tau * np.asarray(factors), correlation))
    F, BQBt, _, T, _ = cases[0]
    for ratio in AUG_SWEEP_RATIOS:
        factors, correlation, sigma = AUG_TAU_FACTORS, AUG_DRIVE_CORRELATION, GM_SWEEP_SIGMA
        if inputs.drawing():
            ratio *= float(inputs.log_uniform(rng, 1 / 3, 3))
            factors = inputs.log_uniform(rng, *AUG_TAU_FACTORS_DRAWN, 6)
            correlation, sigma = _drawn_correlation(rng), _drawn_sigma(rng)
        cases.append(_aug_case(F, BQBt, sigma, T, (T / ratio) * np.asarray(factors), correlation))
    return tuple(cases)


def _blockdiag(A, B) -> np.ndarray:
    n, m = A.shape[0], B.shape[0]
    out = np.zeros((n + m, n + m))
    out[:n, :n] = A
    out[n:, n:] = B
    return out


def _decays(T, tau) -> np.ndarray:
    """φ_i = exp(−T/τ_i) (6,)."""
    return np.exp(-T / np.asarray(tau, dtype=float))


def _stationary_noise(Sigma, T, tau) -> np.ndarray:
    """Q_e = Σ − F_e Σ F_eᵀ, entry by entry Σ_ij (1 − φ_i φ_j), without the cancellation at T ≪ τ."""
    rates = 1.0 / np.asarray(tau, dtype=float)
    return -np.expm1(-T * np.add.outer(rates, rates)) * Sigma


def _aug_F(F, BQBt, Sigma, T, tau):
    return _blockdiag(F, np.diag(_decays(T, tau)))


def _aug_Q(F, BQBt, Sigma, T, tau):
    return _blockdiag(BQBt, _stationary_noise(Sigma, T, tau))


def _coupled(F, rows: bool) -> np.ndarray:
    """F_aug with the observation error coupled to the pose error through POSE_G (a graded mistake)."""
    out = _blockdiag(F, np.zeros((6, 6)))
    if rows:
        out[15:, :15] = eskf.POSE_G
    else:
        out[:15, 15:] = eskf.POSE_G.T
    return out


def _one_tau(pick):
    """The right blocks with every component given the one time constant ``pick(tau)``."""
    def F(F, Q, S, T, tau):
        return _blockdiag(F, _phi(T, pick(tau)) * np.eye(6))

    def Q(F, Q, S, T, tau):
        return _blockdiag(Q, (1.0 - _phi(T, pick(tau)) ** 2) * S)
    return F, Q


def _rows_only(F, Q, S, T, tau):
    return _blockdiag(Q, (1.0 - _decays(T, tau) ** 2)[:, None] * S)


def _columns_only(F, Q, S, T, tau):
    return _blockdiag(Q, S * (1.0 - _decays(T, tau) ** 2)[None, :])


def _rows_symmetrised(F, Q, S, T, tau):
    return symmetrise(_rows_only(F, Q, S, T, tau))


_ROWS_HINT = ("each entry of Σ is scaled by the decay of its row only (Σ − F_e F_e Σ, or (1 − φ²) times Σ row by "
              "row): the part of the covariance that the step carries over is F_e Σ F_eᵀ, with one component's "
              "decay on each side" + hints.formula(", so entry (i, j) keeps φ_i φ_j of itself"))

# each mistake: (F_aug formula, Q_aug formula, why); None: that matrix is not part of the mistake
_AUG_MISTAKES = [
    (lambda F, Q, S, T, tau: np.eye(21), lambda F, Q, S, T, tau: np.zeros((21, 21)),
     "F_aug is the identity and Q_aug zero: the step does nothing (the placeholder). Over one step the "
     "navigation errors move as in the plain ESKF (its F and B Q Bᵀ, given) and the observation error as "
     "its Gauss–Markov components; place each in its rows and columns of the 21-state"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.eye(6)), lambda F, Q, S, T, tau: _blockdiag(Q, np.zeros((6, 6))),
     "the observation error is held constant (its block of F_aug is I and of Q_aug zero): a random "
     "constant, which the filter would learn once and for all. Its rows are a Gauss–Markov step"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.eye(6)), None,
     "the observation error's block of F_aug is I: with the Gauss–Markov noise added that is a random "
     "walk, whose variance grows without bound; each component decays with its own time constant"),
    (None, lambda F, Q, S, T, tau: _blockdiag(Q, np.zeros((6, 6))),
     "the observation error's block of Q_aug is zero: it only decays, and the filter would soon believe "
     "it knows the error exactly; add what keeps its covariance at Σ"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.zeros((6, 6))), lambda F, Q, S, T, tau: _blockdiag(Q, S),
     "the observation error is treated as white (F block 0, Q block Σ): that is the plain ESKF's "
     "assumption with six useless states"),
    (None, lambda F, Q, S, T, tau: _blockdiag(Q, S),
     "the whole stationary covariance Σ is added at every step, as for white noise: most of the error is "
     "carried over by F_e, and only what keeps its covariance at Σ is new (lecture 10 §1, for one component)"),
    (lambda F, Q, S, T, tau: _blockdiag(np.eye(15), np.diag(_decays(T, tau))), None,
     "the navigation block of F_aug is the identity: the navigation errors still move with the plain "
     "ESKF's F over the step (rows and columns 0:15)"),
    (None, lambda F, Q, S, T, tau: _blockdiag(np.zeros((15, 15)), _stationary_noise(S, T, tau)),
     "the navigation block of Q_aug is zero: the IMU's noise B Q Bᵀ still enters the navigation errors "
     "(rows and columns 0:15)"),
    (lambda F, Q, S, T, tau: _blockdiag(np.diag(_decays(T, tau)), F),
     lambda F, Q, S, T, tau: _blockdiag(_stationary_noise(S, T, tau), Q),
     "the order of the states: δx = [δp, δv, δθ, δb_a, δb_ω, δe], the navigation errors first (0:15), "
     "the observation error last (15:21)"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.diag(np.exp(-np.asarray(tau) / T))),
     lambda F, Q, S, T, tau: _blockdiag(Q, S * (1.0 - np.outer(*[np.exp(-np.asarray(tau) / T)] * 2))),
     "T and τ are swapped: the share of a component that survives the step is exp(−T/τ_i)"),
    (None, lambda F, Q, S, T, tau: _blockdiag(Q, np.diag(np.diag(S) * (1.0 - _decays(T, tau) ** 2))),
     "the correlations between the components are dropped (only the diagonal of Q_e is filled): Σ is not "
     "diagonal, and what is new in the error over a step is correlated too. Which covariance Q_e keeps an "
     "error of covariance Σ at Σ after the step?" + hints.formula(" F_e Σ F_eᵀ + Q_e = Σ")),
    (None, lambda F, Q, S, T, tau: _blockdiag(Q, np.diag(np.diag(S) ** 2 * (1.0 - _decays(T, tau) ** 2))),
     "the diagonal of Σ holds variances (m², rad²), not standard deviations, and the correlations between "
     "the components are dropped"),
    (None, _rows_only, _ROWS_HINT),
    (None, _columns_only, _ROWS_HINT.replace("row", "column")),
    (None, _rows_symmetrised, _ROWS_HINT + "; symmetrising the result afterwards does not give that"),
    (None, lambda F, Q, S, T, tau: _blockdiag(Q, S * (1.0 - _decays(T, tau))[:, None]),
     "Σ − F_e Σ: the covariance carried over is F_e Σ F_eᵀ, with F_e on both sides (and Q_e must be "
     "symmetric)"),
    (None, lambda F, Q, S, T, tau: _blockdiag(Q, S ** 2 * (1.0 - np.outer(_decays(T, tau), _decays(T, tau)))),
     "Σ squared entry by entry: Sigma already holds variances and covariances (m², rad²), not standard "
     "deviations"),
    (*_one_tau(np.mean),
     "one time constant (the mean of tau) for all six components: each decays with its own τ_i"
     + hints.formula(", and the covariance of components i and j keeps φ_i φ_j of itself")),
    (*_one_tau(lambda tau: np.asarray(tau)[0]),
     "one time constant (tau[0]) for all six components: each decays with its own τ_i"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.eye(6) - T * np.diag(1.0 / np.asarray(tau))),
     lambda F, Q, S, T, tau: _blockdiag(Q, T * S * np.add.outer(1.0 / np.asarray(tau), 1.0 / np.asarray(tau))),
     "first order in T: F_e = I − T/τ and Q_e = T(AΣ + ΣA) hold for T ≪ τ only; the check's steps reach "
     "T ≫ τ, where 1 − T/τ is negative. Each component's decay over T has an exact form, and the new part "
     "must keep the covariance at Σ for any step"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.eye(6) - T * np.diag(1.0 / np.asarray(tau))),
     lambda F, Q, S, T, tau: _blockdiag(Q, S * (1.0 - np.outer(1.0 - T / np.asarray(tau), 1.0 - T / np.asarray(tau)))),
     "first order in T: the decay 1 − T/τ_i holds for T ≪ τ only; the check's steps reach T ≫ τ, where it is "
     "negative. How much of component i survives T seconds exactly? (Q_e from it, Σ − F_e Σ F_eᵀ, is right "
     "once F_e is)"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.eye(6) - T * np.diag(1.0 / np.asarray(tau))), None,
     "F_e = I − T/τ is the first-order (Euler) step, right for T ≪ τ only; the check's steps reach T ≫ τ, "
     "where it turns negative. How much of component i survives T seconds exactly?"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.exp(-T / np.asarray(tau) * np.eye(6))), None,
     "np.exp of a matrix is element-wise: the off-diagonal zeros became exp(0) = 1, coupling all six "
     "components. Put the six decays on the diagonal instead"),
    (lambda F, Q, S, T, tau: _blockdiag(F, np.diag(_decays(T, tau) ** 2)), None,
     "φ_i² = exp(−2T/τ_i) is how a VARIANCE decays over the step; F_e carries the error itself"),
    (lambda F, Q, S, T, tau: _blockdiag(F, _stationary_noise(S, T, tau)),
     lambda F, Q, S, T, tau: _blockdiag(Q, np.diag(_decays(T, tau))),
     "F_e and Q_e are swapped: F_e carries the error over the step, Q_e is the covariance of what is new"),
    (lambda F, Q, S, T, tau: _coupled(F, rows=True) + _blockdiag(np.zeros((15, 15)), np.diag(_decays(T, tau))), None,
     "the observation error's rows depend on the pose error (POSE_G in rows 15:21): over one IMU step "
     "nothing couples them, since the error belongs to the map matcher, not to the vehicle's motion. "
     "The updates correlate them, and P carries that correlation; F_aug is block-diagonal"),
    (lambda F, Q, S, T, tau: _coupled(F, rows=False) + _blockdiag(np.zeros((15, 15)), np.diag(_decays(T, tau))), None,
     "the pose errors' rows depend on the observation error (POSE_Gᵀ in columns 15:21): the vehicle's "
     "motion does not depend on the map matcher's error; F_aug is block-diagonal"),
]


def _aug_label(F, BQBt, Sigma, T, tau) -> str:
    return f"T = {T:g} s, τ = ({', '.join(f'{v:.3g}' for v in tau)}) s, Σ with correlations"


@check(uses=("gauss_markov_blocks",))
def check_augmented_matrices(augmented_matrices):
    """``augmented_matrices(F, BQBt, Sigma, T, tau)`` returns (F_aug (21, 21), Q_aug (21, 21)).

    Σ (6, 6) is the observation error's stationary covariance (correlated components), τ (6,)
    one time constant per component.
    """
    cases = augmented_cases()
    labels = [_aug_label(*case) for case in cases]
    results = [_pair(call(augmented_matrices, *case), "augmented_matrices", ("F_aug", "Q_aug")) for case in cases]
    try:
        F_got = [_array(r[0], (21, 21), f"F_aug ({label})") for r, label in zip(results, labels)]
        Q_got = [_array(r[1], (21, 21), f"Q_aug ({label})") for r, label in zip(results, labels)]
    except CheckFailed as exc:
        if "NaN or inf" not in str(exc):
            raise
        raise CheckFailed(f"{exc}. Hint: the check's steps reach T = 1000 τ; there each component's share that "
                          "survives the step is tiny but finite, between 0 and 1: an exponent with the wrong sign, "
                          "or a division by a decay, overflows") from None
    F_ok = all(_close(g, _aug_F(*c), ATOL) for g, c in zip(F_got, cases))
    Q_ok = all(_close(g, _aug_Q(*c), ATOL) for g, c in zip(Q_got, cases))
    if F_ok and Q_ok:
        return
    why = known_mistake(list(zip(F_got, Q_got)), cases, [((F_wrong, Q_wrong), why) for F_wrong, Q_wrong, why in _AUG_MISTAKES],
                        lambda g, w, n: _close(g[0], w[0], ATOL) and _close(g[1], w[1], ATOL),
                        evaluate=lambda pair, c: (_evaluate(pair[0] or _aug_F, c), _evaluate(pair[1] or _aug_Q, c)))
    if why is not None:
        n_wrong = sum(not (_close(f, _aug_F(*c), ATOL) and _close(q, _aug_Q(*c), ATOL))
                      for f, q, c in zip(F_got, Q_got, cases))
        raise CheckFailed(f"F_aug and Q_aug are wrong ({labels[0]}; {n_wrong} of {len(cases)} cases wrong). Hint: {why}")
    if _single_precision(F_got + Q_got, [_aug_F(*c) for c in cases] + [_aug_Q(*c) for c in cases]):
        raise CheckFailed(f"F_aug and Q_aug differ from the reference ({labels[0]}) by round-off only. "
                          f"Hint: {SINGLE_PRECISION}")
    blocks = (("the navigation errors", slice(0, 15)), ("the observation error", slice(15, 21)))
    sources = {("F_aug", 0): "the plain ESKF's F", ("Q_aug", 0): "the plain ESKF's B Q Bᵀ",
               ("F_aug", 15): "F_e: how much of each component survives the step, each with its own τ_i",
               ("Q_aug", 15): "Q_e: what keeps an error of covariance Σ at Σ after the step, for any T "
                              "(lecture 10 §1 does it for one component)"
                              + hints.formula(": F_e Σ F_eᵀ + Q_e = Σ")}
    for name, got, ref in (("F_aug", F_got, _aug_F), ("Q_aug", Q_got, _aug_Q)):
        for g, c, label in zip(got, cases, labels):
            e = ref(*c)
            for rname, r in blocks:
                for cname, col in blocks:
                    if _close(g[r, col], e[r, col], ATOL):
                        continue
                    where = (f"the block of {name} in the rows of {rname} ({r.start}:{r.stop}) and the columns "
                             f"of {cname} ({col.start}:{col.stop}), {label}")
                    if r != col:
                        raise CheckFailed(f"{where} should be zero. Hint: over one step nothing couples the "
                                          "observation error to the navigation errors")
                    if name == "Q_aug" and r.start == 15 and not _close(g[r, col], g[r, col].T, ATOL):
                        raise CheckFailed(f"{where} is not symmetric. Hint: a covariance is symmetric; entry "
                                          "(i, j) of what is new depends on both components' decays alike")
                    raise CheckFailed(f"{where} differs from the reference (max abs error "
                                      f"{np.abs(g[r, col] - e[r, col]).max():.3g}). Hint: it is "
                                      f"{sources[(name, r.start)]}")


# --------------------------------------------------------------------------------------
# 3. relative motion, residual and Jacobian
# --------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def pose_pairs():
    """(label, p0, R0, p1, R1): real KITTI truth poses (tilted), and the same pairs moved rigidly.

    Under a run seed: other pairs of the excerpt's truth (gaps from :data:`POSE_GAPS_DRAWN`),
    other tilts, and another rigid transform (a turn of 1 rad to nearly π about a random axis,
    a shift of ~100 m); drawn again until some pair turns by :data:`POSE_TURN_DRAWN` or more.
    """
    ex = load_kitti("turns")
    rng = inputs.rng("real_sensors.pose_pairs", 12)
    pairs, rotation, c = POSE_PAIRS, MOVE_ROTATION, MOVE_TRANSLATION
    if inputs.drawing():
        pairs, rotation, c = _drawn_pairs(rng, len(ex.truth.t))
    C = so3.exp(rotation)
    while True:
        plain, moved = _tilted_pairs(ex, rng, pairs, C, c)
        turn = max(so3.angle(R0.T @ R1) for _, _, R0, _, R1 in plain)
        if not inputs.drawing() or turn >= POSE_TURN_DRAWN:
            break
    out = []
    for case in plain + moved:
        for arr in case[1:]:
            arr.setflags(write=False)
        out.append(case)
    return tuple(out)


@functools.lru_cache(maxsize=None)
def turn_sweep_pairs():
    """(label, p0, R0, p1, R1) of the turn sweep (:data:`TURN_SWEEP_ANGLES`), each angle about an
    axis and about its opposite: a real KITTI truth pose (tilted) and a made-up second pose."""
    ex = load_kitti("turns")
    rng = inputs.rng("real_sensors.turn_sweep", 14)
    frame = TURN_SWEEP_FRAME if not inputs.drawing() else int(rng.integers(0, len(ex.truth.t)))
    p0, R0 = ex.truth.position[frame].copy(), ex.truth.rotation[frame] @ so3.exp(rng.normal(size=3) * 0.3)
    out = []
    for angle in TURN_SWEEP_ANGLES:
        if inputs.drawing():   # the distance from 0 or from π moved, never across either
            near = min(angle, np.pi - angle)
            moved = near * float(inputs.log_uniform(rng, 1 / 3, 3))
            angle = moved if angle < 1.0 else np.pi - moved
        axis = rng.normal(size=3)
        axis /= np.linalg.norm(axis)
        shift = rng.normal(size=3)
        shift *= rng.uniform(0.5, 3.0) / np.linalg.norm(shift)
        for sign, side in ((1.0, "+"), (-1.0, "−")):
            R1 = R0 @ so3.exp(sign * angle * axis)
            p1 = p0 + R0 @ shift
            case = (f"a KITTI pose and one turned by {side}{angle:.6g} rad from it (made up)", p0.copy(), R0.copy(),
                    p1, R1)
            for arr in case[1:]:
                arr.setflags(write=False)
            out.append(case)
    return tuple(out)


def _drawn_pairs(rng: np.random.Generator, n_frames: int):
    """Drawn (frame, gap) pairs and a rigid transform (rotation vector, translation)."""
    pairs = []
    for lo, hi in POSE_GAPS_DRAWN:
        gap = int(rng.integers(lo, hi + 1))
        pairs.append((int(rng.integers(0, n_frames - gap)), gap))
    axis = rng.normal(size=3)
    angle = rng.uniform(1.0, np.pi - 1e-3)
    return tuple(pairs), angle * axis / np.linalg.norm(axis), rng.normal(size=3) * 100.0


def _tilted_pairs(ex, rng, pairs, C, c):
    """The truth pose pairs, each pose tilted by its own drawn rotation, and the same moved by (C, c)."""
    plain, moved = [], []
    for k, n in pairs:
        tilt0, tilt1 = so3.exp(rng.normal(size=3) * 0.3), so3.exp(rng.normal(size=3) * 0.3)
        p0, R0 = ex.truth.position[k].copy(), ex.truth.rotation[k] @ tilt0
        p1, R1 = ex.truth.position[k + n].copy(), ex.truth.rotation[k + n] @ tilt1
        span = f"{n / 10:g} s apart"
        plain.append((f"two KITTI poses {span}", p0, R0, p1, R1))
        moved.append((f"the same two poses {span}, the whole track moved by a rigid transform",
                      C @ p0 + c, C @ R0, C @ p1 + c, C @ R1))
    return plain, moved


def _ref_dp(p0, R0, p1, R1):
    return eskf_relative.relative_motion(p0, R0, p1, R1)[0]


def _ref_dR(p0, R0, p1, R1):
    return eskf_relative.relative_motion(p0, R0, p1, R1)[1]


_DP_MISTAKES = [
    (lambda p0, R0, p1, R1: p1 - p0,
     "Δp is the displacement in the navigation frame: the motion must be seen from pose 0's BODY frame "
     "(where a VO or an IMU measures it); a relative pose does not change when the whole track is moved "
     "or turned, p1 − p0 does"),
    (lambda p0, R0, p1, R1: R0 @ (p1 - p0),
     "R0 = R_nb maps body vectors to the navigation frame; to see the navigation-frame displacement "
     "from pose 0's body, use the inverse map, R0ᵀ"),
    (lambda p0, R0, p1, R1: R1.T @ (p1 - p0),
     "the displacement is seen from pose 1's body frame; ΔT = T0⁻¹ T1 expresses it in pose 0's"),
    (lambda p0, R0, p1, R1: R0.T @ (p0 - p1),
     "sign: Δp is where pose 1 is seen from pose 0 (lecture 10 §2)" + hints.formula(", R0ᵀ (p1 − p0)")),
    (lambda p0, R0, p1, R1: R1.T @ (p0 - p1),
     "that is where pose 0 is seen from pose 1 (the inverse relative pose T1⁻¹ T0); ΔT = T0⁻¹ T1"),
    (lambda p0, R0, p1, R1: R0.T @ p1 - p0,
     "only p1 was rotated: the difference p1 − p0 as a whole is seen from pose 0's body frame"),
]

_DR_MISTAKES = [
    (lambda p0, R0, p1, R1: R1 @ R0.T,
     "R1 R0ᵀ is the rotation between the two poses in the NAVIGATION frame; the relative pose's rotation "
     "is seen from pose 0's body frame, and must not change when the whole track is turned"),
    (lambda p0, R0, p1, R1: R0 @ R1.T,
     "R0 R1ᵀ is the navigation-frame rotation from pose 1 back to pose 0; ΔR turns pose 0's body axes "
     "into pose 1's, seen from pose 0"),
    (lambda p0, R0, p1, R1: R1.T @ R0,
     "that is the inverse, pose 0 seen from pose 1 (T1⁻¹ T0); ΔT = T0⁻¹ T1"),
    (lambda p0, R0, p1, R1: R0 @ R1,
     "the inverse of R0 is missing: pose 0 is inverted (lecture 10 §2)" + hints.formula(": ΔR = R0⁻¹ R1 and R0⁻¹ = R0ᵀ")),
    (lambda p0, R0, p1, R1: R1 @ R0,
     "order and inverse: pose 0 is inverted, and stands on the left (lecture 10 §2)"
     + hints.formula(": ΔR = R0⁻¹ R1 (R0⁻¹ = R0ᵀ)")),
]


@check
def check_relative_motion(relative_motion):
    """``relative_motion(p0, R0, p1, R1)`` returns (Δp (3,), ΔR (3, 3)) = T0⁻¹ T1."""
    cases = pose_pairs() + turn_sweep_pairs()
    labels = [c[0] for c in cases]
    args = [c[1:] for c in cases]
    results = [_pair(call(relative_motion, *a), "relative_motion", ("dp", "dR")) for a in args]
    dp = [_array(r[0], (3,), f"Δp ({label})") for r, label in zip(results, labels)]
    dR = [_array(r[1], (3, 3), f"ΔR ({label})") for r, label in zip(results, labels)]
    _judge("Δp", dp, args, labels, _ref_dp, _DP_MISTAKES,
           "Δp is where pose 1 is, seen from pose 0's body frame (lecture 10 §2); it must not change when the "
           "whole track is moved by a rigid transform (the check does that)", atol=1e-9)
    _judge("ΔR", dR, args, labels, _ref_dR, _DR_MISTAKES,
           "ΔR turns pose 0's body axes into pose 1's, seen from pose 0's body frame (lecture 10 §2); it must "
           "not change when the whole track is turned (the check does that)")


@functools.lru_cache(maxsize=None)
def camera_lever_arms() -> tuple:
    """Lever arms t (3,) m of a camera in the body frame: KITTI's cam0 from its calibration (real,
    about 1.10 m ahead, 0.32 m right, 0.75 m above the IMU) and :data:`MADE_UP_LEVER_ARM`; under a
    run seed the second is drawn (0.5–2 m in a random direction)."""
    frames = load_kitti("turns").frames
    kitti = -frames.R_cam_imu.T @ frames.t_cam_imu
    other = MADE_UP_LEVER_ARM.copy()
    if inputs.drawing():
        g = inputs.rng("real_sensors.lever_arm", 15)
        other = g.normal(size=3)
        other *= g.uniform(0.5, 2.0) / np.linalg.norm(other)
    for t in (kitti, other):
        t.setflags(write=False)
    return kitti, other


_NO_LEVER_ARM = np.zeros(3)
_NO_LEVER_ARM.setflags(write=False)


def _camera_increment(dp, dR, t):
    """The camera's displacement seen from the clone's body, Δp + ΔR t − t, for an IMU increment (Δp, ΔR)."""
    return dp + dR @ t - t


@functools.lru_cache(maxsize=None)
def residual_cases():
    """(label, clone p, R, current p, R, Δp_m, ΔR_m, t): KITTI truth poses, measured increment simulated.

    First the IMU's own increments (t = 0); then the same pose pairs with a camera at each lever
    arm of :func:`camera_lever_arms`. The measurement is the true increment (the camera's) with
    seeded noise: 3 cm in Δp and 0.02–0.05 rad in ΔR (under a run seed: the pairs of
    :func:`pose_pairs`, other noise, its ΔR scales drawn from 0.02–0.05 rad).
    """
    rng = inputs.rng("real_sensors.residual", 13)
    scales = (0.02, 0.05, 0.03, 0.04, 0.05)
    if inputs.drawing():
        scales = tuple(rng.uniform(0.02, 0.05, len(scales)))
    out = []
    scales += tuple(rng.uniform(0.02, 0.05, len(turn_sweep_pairs())))
    pairs = pose_pairs()[:len(POSE_PAIRS)] + turn_sweep_pairs()
    settings = [(pair, scale, _NO_LEVER_ARM, "") for pair, scale in zip(pairs, scales)]
    for t, name in zip(camera_lever_arms(), ("KITTI's cam0", "a camera")):
        settings += [(pair, scale, t, f"; increments of {name} at lever arm ({', '.join(f'{v:.2f}' for v in t)}) m")
                     for pair, scale in zip(pose_pairs()[:len(POSE_PAIRS)], rng.uniform(0.02, 0.05, len(POSE_PAIRS)))]
    for (label, p0, R0, p1, R1), scale, t, camera in settings:
        dp, dR = eskf_relative.relative_motion(p0, R0, p1, R1)
        dp_m, dR_m = _camera_increment(dp, dR, t) + rng.normal(size=3) * 0.03, dR @ so3.exp(rng.normal(size=3) * scale)
        case = (p0, R0, p1, R1, dp_m, dR_m, t)
        for arr in case:
            arr.setflags(write=False)
        out.append((f"clone and current pose: {label}{camera}; measured increment with simulated noise", *case))
    return tuple(out)


def _ref_residual(pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM):
    y = eskf_relative.relative_pose_residual(pc, Rc, p, R, dp_m, dR_m)
    dp, dR = eskf_relative.relative_motion(pc, Rc, p, R)
    return np.r_[y[:3] + dR @ t - t, y[3:]]


def _residual_tolerance(pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM) -> np.ndarray:
    """Per entry: 1e-9 m on the position part, |y_θ|² + 1e-12 on the attitude part."""
    y_theta = _ref_residual(pc, Rc, p, R, dp_m, dR_m, t)[3:]
    return np.r_[np.full(3, 1e-9), np.full(3, float(y_theta @ y_theta) + 1e-12)]


def _with_theta(theta: Callable):
    """A residual formula with the right position part and the attitude part ``theta(ΔŘ, ΔR_m)``."""
    def formula(pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM):
        dp, dR = eskf_relative.relative_motion(pc, Rc, p, R)
        return np.r_[_camera_increment(dp, dR, t) - dp_m, theta(dR, dR_m)]
    return formula


def _swapped(pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM):
    dp, dR = eskf_relative.relative_motion(p, R, pc, Rc)
    return np.r_[_camera_increment(dp, dR, t) - dp_m, so3.log(dR_m.T @ dR)]


def _no_lever_arm(pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM):
    return _ref_residual(pc, Rc, p, R, dp_m, dR_m)


_RESIDUAL_MISTAKES = [
    (lambda pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM: np.zeros(6),
     "the residual is zero: nothing was compared. Predict the increment from the clone to the current "
     "pose (your relative_motion) and compare it with the measured one"),
    (_with_theta(lambda dR, dR_m: so3.log(dR) - so3.log(dR_m)),
     "rotation vectors do not subtract: Log(ΔŘ) − Log(ΔR_m) is close to the rotation between them only "
     "when both are small, and an increment over a turn is not. Compose the two rotations and take one "
     "Log, so that the result is the attitude error in the current body frame (as in chapter 08)"),
    (lambda *case: -_ref_residual(*case),
     "sign (both parts): with error = nominal − true the residual is prediction minus measurement, as in "
     "chapter 08, so that y ≈ G δx with G's δp block R_cᵀ and δθ block +I"),
    (lambda *case: np.r_[-_ref_residual(*case)[:3], _ref_residual(*case)[3:]],
     "sign of the position part: prediction minus measurement, Δp̌ − Δp_m"),
    (_with_theta(lambda dR, dR_m: so3.log(dR.T @ dR_m)),
     "sign of the attitude part: the prediction relative to the measurement, as in chapter 08 (lecture 10 §2)"
     + hints.formula(": ΔŘ ≈ ΔR_m Exp(δθ), so the Log of ΔR_mᵀ ΔŘ, not of ΔŘᵀ ΔR_m")),
    (_with_theta(lambda dR, dR_m: so3.log(dR @ dR_m.T)),
     "the attitude error is taken on the wrong side: Log(ΔŘ ΔR_mᵀ) is expressed in the clone's frame; the "
     "current attitude's error δθ lives in the current body frame (lecture 10 §2)" + hints.formula(": ΔR_mᵀ ΔŘ")),
    (_with_theta(lambda dR, dR_m: so3.log(dR_m @ dR.T)),
     "side and sign: the attitude error lives in the current body frame, the prediction relative to the "
     "measurement (lecture 10 §2)" + hints.formula(": Log(ΔR_mᵀ ΔŘ)")),
    (_with_theta(lambda dR, dR_m: so3.log(dR_m @ dR)),
     "a transpose is missing: compare the two increments by the rotation from the measured to the predicted "
     "one (lecture 10 §2)" + hints.formula(", ΔR_mᵀ ΔŘ")),
    (_swapped,
     "the increment was predicted from the current pose to the clone: the clone is the EARLIER pose, so "
     "the motion since then is T_c⁻¹ T (relative_motion(clone, current)), as the VO's increment is"),
    (lambda pc, Rc, p, R, dp_m, dR_m, t=_NO_LEVER_ARM: np.r_[_camera_increment(p - pc, Rc.T @ R, t) - dp_m,
                                                            so3.log(dR_m.T @ Rc.T @ R)],
     "the predicted displacement is in the navigation frame, the measured one in the clone's body "
     "frame: predict it with your relative_motion"),
    (_no_lever_arm,
     "the camera's lever arm is ignored: the measured increment is the camera's, and the cell's line "
     "dp_camera predicts it from the IMU's; compare dp_camera, not the IMU's Δp̌, with Δp_m"),
    (lambda *case: np.r_[_ref_residual(*case)[3:], _ref_residual(*case)[:3]],
     "order: y = [position part; attitude part], as G's rows"),
]


def _residual_args(case):
    """The arguments a case passes: the IMU's own increments as six, a camera's with its lever arm."""
    return case[:6] if not np.any(case[6]) else case


@check(uses=("relative_motion",))
def check_relative_pose_residual(relative_pose_residual):
    """``relative_pose_residual(p_clone, R_clone, p_check, R_check, dp_meas, dR_meas, lever_arm=0)`` returns y (6,).

    The attitude part is accepted within |y_θ|² of the Log (see the module notes).
    """
    cases = residual_cases()
    labels = [c[0] for c in cases]
    args = [c[1:] for c in cases]
    got = [_array(_call_with_lever_arm(relative_pose_residual, "relative_pose_residual", _residual_args(a)), (6,),
                  f"y ({label})") for a, label in zip(args, labels)]
    _judge("y", got, args, labels, _ref_residual, _RESIDUAL_MISTAKES,
           "the residual compares the predicted increment with the measured one (lecture 10 §2): the difference "
           "of the (camera's) displacements in the clone's body frame, then the attitude error of the predicted "
           "increment against the measured one, as a rotation vector in the current body frame"
           + hints.formula(": y = [Δp̌_camera − Δp_m; Log(ΔR_mᵀ ΔŘ)]"),
           atol=_residual_tolerance, rtol=0.0)


def _call_with_lever_arm(fn, name: str, args):
    """The learner's function, with a lever arm where the case has one; a signature without it is named."""
    try:
        return call(fn, *args)
    except CheckFailed as exc:
        if "positional argument" in str(exc) and "TypeError" in str(exc):
            raise CheckFailed(f"{name} takes the camera's lever arm too, as its last argument "
                              "(lever_arm=np.zeros(3): the IMU's own increments). Hint: keep the cell's first "
                              "line as it is") from None
        raise


def _camera_residual_of_error(pc, Rc, p, R, t):
    """y(δx_a) of the camera's relative pose at fixed nominal poses: the true poses from the error
    (error = nominal − true), the measurement the true camera increment, noise-free."""
    def residual(dx):
        p_true_c, R_true_c = pc - dx[15:18], Rc @ so3.exp(-dx[18:21])
        p_true, R_true = p - dx[0:3], R @ so3.exp(-dx[6:9])
        dp_m, dR_m = eskf_relative.relative_motion(p_true_c, R_true_c, p_true, R_true)
        return _ref_residual(pc, Rc, p, R, _camera_increment(dp_m, dR_m, t), dR_m, t)
    return residual


@functools.lru_cache(maxsize=None)
def jacobian_cases():
    """(label, R_clone, Δp̌, ΔŘ, t, G by central differences): the nominal pose pairs with t = 0, the two
    nearest a half turn, then the pose pairs again with each camera lever arm of :func:`camera_lever_arms`."""
    out = []
    half_turns = [pair for pair in turn_sweep_pairs() if so3.angle(pair[2].T @ pair[4]) > 3.0]
    settings = [(pair, _NO_LEVER_ARM, "") for pair in pose_pairs() + tuple(half_turns[-2:])]
    for t, name in zip(camera_lever_arms(), ("KITTI's cam0", "a camera")):
        settings += [(pair, t, f"; increments of {name} at lever arm ({', '.join(f'{v:.2f}' for v in t)}) m")
                     for pair in pose_pairs()[:len(POSE_PAIRS)]]
    for (label, pc, Rc, p, R), t, camera in settings:
        dp, dR = eskf_relative.relative_motion(pc, Rc, p, R)
        if np.any(t):
            G = numerical_jacobian(_camera_residual_of_error(pc, Rc, p, R, t), np.zeros(21), FD_STEP)
        else:
            G = relative_jacobian_by_differences(pc, Rc, p, R, FD_STEP)
        for arr in (dp, dR, G):
            arr.setflags(write=False)
        out.append((f"clone and current pose: {label}{camera}", Rc, dp, dR, t, G))
    return tuple(out)


_G_ROWS = (("y_p", 0, 3), ("y_θ", 3, 6))
_G_COLS = (("δp", 0, 3), ("δv", 3, 6), ("δθ", 6, 9), ("δb_a", 9, 12), ("δb_ω", 12, 15), ("δp_c", 15, 18),
           ("δθ_c", 18, 21))
_G_FORMULAS = {("y_p", "δp"): "Ř_cᵀ", ("y_p", "δθ"): "−ΔŘ [t]×", ("y_p", "δp_c"): "−Ř_cᵀ",
               ("y_p", "δθ_c"): "[Δp̌ + ΔŘ t]×", ("y_θ", "δθ"): "I", ("y_θ", "δθ_c"): "−ΔŘᵀ"}


def _reference_jacobian(Rc, dp, dR, t) -> np.ndarray:
    """G (6, 21) of the camera's relative-pose residual: the package's for t = 0 plus the lever arm's terms."""
    G = eskf_relative.relative_pose_jacobian(Rc, dp, dR)
    G[0:3, 6:9] = -dR @ so3.hat(t)
    G[0:3, 18:21] = so3.hat(dp + dR @ t)
    return G


def _g_alternatives(Rc, dp, dR, t) -> dict:
    """Known wrong values of the blocks of G, with the hint for each (q = Δp̌ + ΔŘ t, where the current
    camera is seen from the clone's body; q = Δp̌ without a lever arm)."""
    hat = so3.hat
    q = dp + dR @ t
    lever = np.any(t)
    forgot_lever = ("the lever arm is the whole vector from the clone's IMU to the current CAMERA, seen from the "
                    "clone's body: an attitude error of the clone turns the frame in which all of it is seen"
                    + hints.formula(" (Δp̌ + ΔŘ t)"))
    alternatives = {
        ("y_p", "δp_c"): [
            (Rc.T, "sign: the clone's position error enters the predicted displacement p̌ − p̌_c with a minus"),
            (-np.eye(3), "the displacement is seen from the clone's body frame: the clone's position error is "
                         "rotated like the current one" + hints.formula(", −Ř_cᵀ")),
            (-Rc, "R_c = R_nb maps body to navigation; the displacement is seen from the clone"
                  + hints.formula(": −Ř_cᵀ")),
        ],
        ("y_p", "δθ_c"): [
            (-hat(q), "sign of the lever arm: expand the true clone attitude to first order in δθ_c (lecture 10 "
                      "§2, error = nominal − true)"
                      + hints.formula(": with Ř_c = R_c Exp(δθ_c), R_cᵀ = Exp(δθ_c) Ř_cᵀ ≈ (I + [δθ_c]×) Ř_cᵀ, "
                                      "so the true increment gains δθ_c × q with q = Δp̌ + ΔŘ t, and y_p gains "
                                      "−δθ_c × q = [q]× δθ_c")),
            (np.zeros((3, 3)), "missing: an attitude error of the clone turns the frame in which the displacement "
                               "is seen, so it moves y_p by a lever arm (lecture 10 §2)" + hints.formula(", [Δp̌ + ΔŘ t]× δθ_c")),
            (hat(Rc @ q), "the lever arm is the displacement in the clone's BODY frame, not in the "
                          "navigation frame"),
        ],
        ("y_θ", "δθ_c"): [
            (-np.eye(3), "the clone's attitude error lives in the clone's body frame, the residual's attitude "
                         "part in the current one: rotate it across the increment" + hints.formula(", −ΔŘᵀ")),
            (-dR, "transpose: the clone's attitude error is carried into the current body frame by ΔŘᵀ "
                  "(ΔŘ = Ř_cᵀ Ř maps current-body vectors to clone-body ones)"),
            (dR.T, "sign: y_θ decreases with the clone's attitude error (lecture 10 §2)"
                   + hints.formula(": y_θ = Log(ΔR_mᵀ ΔŘ) with ΔŘ = Ř_cᵀ Ř, so −ΔŘᵀ")),
            (np.eye(3), "sign and frame: the clone's attitude error enters with a minus and must be carried across "
                        "the increment into the current body frame (lecture 10 §2)" + hints.formula(": −ΔŘᵀ")),
        ],
    }
    if lever:
        alternatives[("y_p", "δθ_c")] = [
            (hat(dp), forgot_lever + "; lecture 10 §2's block is for t = 0" + hints.formula(": [Δp̌ + ΔŘ t]×, not [Δp̌]×")),
            (hat(dp + dR @ t - t), forgot_lever + "; the clone's own camera sits at t in the clone's body, fixed "
                                   "there, and does not move when the clone's attitude is wrong, so the −t of the "
                                   "camera's displacement does not belong in this block"
                                   + hints.formula(": [Δp̌ + ΔŘ t]×, not [Δp̌ + ΔŘ t − t]×")),
            (hat(dp + t), forgot_lever + "; the lever arm t is in the CURRENT body frame, which is turned against "
                          "the clone's" + hints.formula(": ΔŘ t, not t")),
            (-hat(dp), forgot_lever + ", and its sign follows from error = nominal − true"),
        ] + alternatives[("y_p", "δθ_c")]
        alternatives[("y_p", "δθ")] = [
            (np.zeros((3, 3)), "missing: the current pose's attitude error swings the camera about the IMU, so "
                               "it moves the predicted camera displacement by the lever arm turned wrongly "
                               "(expand ΔŘ t with Ř = R Exp(δθ))" + hints.formula("; the block is −ΔŘ [t]×")),
            (dR @ hat(t), "sign of the lever arm's block: expand the true attitude to first order in δθ with "
                          "error = nominal − true, Ř = R Exp(δθ)"
                          + hints.formula(": the true R t is Ř Exp(−δθ) t ≈ Ř(t + t × δθ), so y_p gains "
                                          "ΔŘ (δθ × t) = −ΔŘ [t]× δθ")),
            (-hat(t), "the swing of the camera happens in the current body frame; seen from the clone it is turned "
                      "across the increment" + hints.formula(": −ΔŘ [t]×")),
            (-hat(dR @ t), "order: the cross product is taken in the current body frame, where δθ lives, and then "
                           "turned into the clone's" + hints.formula(": −ΔŘ [t]×; −[ΔŘ t]× = −ΔŘ [t]× ΔŘᵀ turns δθ as well")),
            (-Rc.T @ hat(t), "the lever arm's block is seen from the clone across the increment, by ΔŘ = Ř_cᵀ Ř, "
                             "not by Ř_cᵀ alone"),
        ]
    return alternatives


@check
def check_relative_pose_jacobian(relative_pose_jacobian):
    """``relative_pose_jacobian(R_clone, dp_check, dR_check, lever_arm=0)`` returns G (6, 21).

    Compared with central differences of the residual (see the module notes), first for the IMU's
    own increments (three arguments), then for a camera's at a lever arm; a wrong block is named,
    and the placeholder's empty clone columns are recognised.
    """
    for label, Rc, dp, dR, t, G_fd in jacobian_cases():
        args = (Rc, dp, dR, t) if np.any(t) else (Rc, dp, dR)
        value = _call_with_lever_arm(relative_pose_jacobian, "relative_pose_jacobian", args)
        if np.shape(value) == (6, 15):
            raise CheckFailed("G has shape (6, 15), expected (6, 21): the residual also depends on the clone's "
                              "errors δp_c and δθ_c, columns 15:21 of the augmented error state")
        G = _array(value, (6, 21), f"G ({label})")
        if _close(G, G_fd, JACOBIAN_ATOL, rtol=0.0):
            continue
        ref = _reference_jacobian(Rc, dp, dR, t)
        if _close(G[:, :15], ref[:, :15], JACOBIAN_ATOL, rtol=0.0) and not G[:, 15:].any():
            raise CheckFailed(f"G's clone columns 15:21 are all zero ({label}): the clone was treated as exactly "
                              "known. Hint: the residual compares the motion since the clone, so the clone's "
                              "position and attitude errors move it too; fill the blocks (y_p, δp_c), "
                              "(y_p, δθ_c) and (y_θ, δθ_c) (lecture 10 §2)")
        alternatives = _g_alternatives(Rc, dp, dR, t)
        for rname, r0, r1 in _G_ROWS:
            for cname, c0, c1 in _G_COLS:
                g, e = G[r0:r1, c0:c1], ref[r0:r1, c0:c1]
                if _close(g, e, JACOBIAN_ATOL, rtol=0.0):
                    continue
                where = f"the ({rname}, {cname}) block of G (rows {r0}:{r1}, columns {c0}:{c1}; {label})"
                for wrong, why in alternatives.get((rname, cname), ()):
                    if _close(g, wrong, JACOBIAN_ATOL, rtol=0.0):
                        raise CheckFailed(f"{where} is wrong. Hint: {why}")
                formula = _G_FORMULAS.get((rname, cname), "0")
                if not e.any():
                    raise CheckFailed(f"{where} should be zero: the residual does not depend on {cname}"
                                      + (" (without a lever arm the current attitude error does not move the "
                                         "displacement: −ΔŘ [t]× is zero for t = 0)" if cname == "δθ" else ""))
                if not g.any():
                    raise CheckFailed(f"{where} is missing (all zeros). Hint: the residual depends on {cname} "
                                      "(lecture 10 §2)" + hints.formula(f"; the block is {formula}"))
                raise CheckFailed(f"{where} differs from central differences of the residual (max abs error "
                                  f"{np.abs(g - e).max():.3g}). Hint: make the true poses from the error "
                                  "(error = nominal − true, Ř = R Exp(δθ)), the true camera increment from them, "
                                  "and expand the residual to first order (lecture 10 §2 does it for t = 0)"
                                  + hints.formula(f"; the block is {formula}"))


# --------------------------------------------------------------------------------------
# 4. the drift metric
# --------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def drift_cases():
    """(label, position, rotation, true position, true rotation, first, last, length) per VO system.

    Real: the anchored ORB-SLAM2 / S-PTAM tracks and the ground truth of sequence 00, every
    ``DRIFT_STRIDE``-th frame; the segments as the drift metric chooses them. Under a run
    seed: another window of the same real tracks (:data:`DRIFT_WINDOW_DRAWN` frames from a
    drawn start, a drawn stride), other segment lengths and step; only the segments whose
    rotational error is at least :data:`DRIFT_LEAST_ANGLE` are kept, and the window is drawn
    again until every length keeps :data:`DRIFT_LEAST_SEGMENTS` of them in both tracks.
    """
    setups = [vo.setup("seq00", system) for system in DRIFT_SYSTEMS]
    if not inputs.drawing():
        frames = np.arange(0, DRIFT_FRAMES, DRIFT_STRIDE)
        return tuple(_drift_case(s, frames, DRIFT_LENGTHS, DRIFT_STEP, "") for s in setups)
    g = inputs.rng("real_sensors.drift", 0)
    n_frames = min(len(s.vo.t) for s in setups)
    for _ in range(100):
        size = int(g.integers(DRIFT_WINDOW_DRAWN[0], DRIFT_WINDOW_DRAWN[1] + 1))
        start = int(g.integers(0, n_frames - size))
        frames = np.arange(start, start + size, int(g.choice(DRIFT_STRIDES_DRAWN)))
        lengths = tuple(float(np.round(g.uniform(lo, hi), 1)) for lo, hi in DRIFT_LENGTHS_DRAWN)
        step = int(g.choice(DRIFT_STEPS_DRAWN))
        out = tuple(_drift_case(s, frames, lengths, step, f" (frames {start}–{start + size - 1})",
                                least_angle=DRIFT_LEAST_ANGLE) for s in setups)
        if all(np.sum(case[7] == L) >= DRIFT_LEAST_SEGMENTS for case in out for L in lengths):
            return out
    raise RuntimeError("no drawn window of sequence 00 holds enough segments of every length")


def _drift_case(s, frames, lengths, step, window: str, least_angle: float = 0.0):
    """One drift case of the anchored VO setup ``s`` at ``frames`` (indices after its anchor)."""
    truth = s.excerpt.truth
    p, R = s.vo.position[frames], s.vo.rotation[frames]
    pt, Rt = truth.position[s.first + frames], truth.rotation[s.first + frames]
    ref = drift(p, R, pt, Rt, lengths, step)
    first, last, length = ref.first, ref.last, ref.length
    # an arccos of the trace, a correct way of taking the angle, loses precision at small angles
    keep = _segment_motion_errors(p, R, pt, Rt, first, last)[1] >= least_angle
    case = (p, R, pt, Rt, first[keep].copy(), last[keep].copy(), length[keep].copy())
    for arr in case:
        arr.setflags(write=False)
    return (f"{s.system} on sequence 00{window}, {int(keep.sum())} segments of "
            f"{', '.join(f'{v:g}' for v in lengths)} m", *case)


def _rel(p, R, i, j):
    """Δp (S, 3) and ΔR (S, 3, 3) of the segments from frames i to j."""
    Ri = R[i]
    return np.einsum("sba,sb->sa", Ri, p[j] - p[i]), np.swapaxes(Ri, -1, -2) @ R[j]


def _segment_motion_errors(p, R, pt, Rt, i, j):
    """|Δp_true − Δp| (m) and angle(ΔRᵀ ΔR_true) (rad) of every segment."""
    dp, dR = _rel(p, R, i, j)
    dpt, dRt = _rel(pt, Rt, i, j)
    return np.linalg.norm(dpt - dp, axis=1), so3.angle(np.swapaxes(dR, -1, -2) @ dRt)


def _drift_t(p, R, pt, Rt, i, j, L):
    return 100.0 * _segment_motion_errors(p, R, pt, Rt, i, j)[0] / L


def _drift_r(p, R, pt, Rt, i, j, L):
    return np.rad2deg(_segment_motion_errors(p, R, pt, Rt, i, j)[1] / L) * 100.0


def _per_100m_deg(rad, L):
    return np.rad2deg(rad / L) * 100.0


_DRIFT_MISTAKES = [
    # (translational formula, rotational formula, why); None: that output is right
    (lambda p, R, pt, Rt, i, j, L: np.linalg.norm(p[j] - pt[j], axis=1),
     lambda p, R, pt, Rt, i, j, L: so3.angle(np.swapaxes(Rt[j], -1, -2) @ R[j]),
     "these are the absolute errors at each segment's end, in m and rad (the placeholder): they include "
     "every error made before the segment. The drift metric compares the MOTION over the segment (the "
     "relative pose from its start to its end, estimated vs true) and divides by the segment's length: "
     "percent, and degrees per 100 m"),
    (lambda p, R, pt, Rt, i, j, L: 100.0 * np.linalg.norm(p[j] - pt[j], axis=1) / L,
     lambda p, R, pt, Rt, i, j, L: _per_100m_deg(so3.angle(np.swapaxes(Rt[j], -1, -2) @ R[j]), L),
     "the absolute error at the segment's end, per length: it carries every error made before the segment "
     "(a drift metric must not depend on when the first mistake happened). Compare the relative poses "
     "from the segment's start to its end (your relative_motion on the estimate and on the truth)"),
    (lambda p, R, pt, Rt, i, j, L: 100.0 * np.linalg.norm((p[j] - p[i]) - (pt[j] - pt[i]), axis=1) / L, None,
     "the displacements were compared in the navigation frame: a heading error made BEFORE the segment "
     "turns the whole estimated displacement and counts as drift in it. Compare the motions each in its "
     "own body frame at the segment's start (your relative_motion)"),
    (lambda p, R, pt, Rt, i, j, L: 100.0 * np.linalg.norm(
        np.einsum("sba,sb->sa", R[j], p[j] - p[i]) - np.einsum("sba,sb->sa", Rt[j], pt[j] - pt[i]), axis=1) / L,
     None,
     "the displacements are seen from the segment's END; the relative pose T_i⁻¹ T_j sees them from its "
     "start (relative_motion(start, end))"),
    (lambda p, R, pt, Rt, i, j, L: 100.0 * np.abs(np.linalg.norm(_rel(pt, Rt, i, j)[0], axis=1)
                                                  - np.linalg.norm(_rel(p, R, i, j)[0], axis=1)) / L, None,
     "only the lengths of the two displacements were compared: a displacement in the wrong direction but "
     "of the right length would count as no error. Take the length of their difference"),
    (lambda p, R, pt, Rt, i, j, L: 100.0 * _segment_motion_errors(p, R, pt, Rt, i, j)[0]
     / np.linalg.norm(_rel(pt, Rt, i, j)[0], axis=1), None,
     "divided by the straight-line distance between the segment's ends; the metric divides by the "
     "segment's length L along the path (the `length` argument)"),
    (lambda p, R, pt, Rt, i, j, L: _segment_motion_errors(p, R, pt, Rt, i, j)[0] / L, None,
     "that is a fraction (m per m); the translational error is in percent of the segment length"),
    (lambda p, R, pt, Rt, i, j, L: 100.0 * _segment_motion_errors(p, R, pt, Rt, i, j)[0], None,
     "not divided by the segment's length: the translational error is per length travelled, in %"),
    (lambda p, R, pt, Rt, i, j, L: _segment_motion_errors(p, R, pt, Rt, i, j)[0], None,
     "that is the error in metres; the translational error is per length travelled, in % (lecture 10 §2)"
     + hints.formula(": 100 · error / L")),
    (None, lambda p, R, pt, Rt, i, j, L: _segment_motion_errors(p, R, pt, Rt, i, j)[1] / L * 100.0,
     "radians: the rotational error is in DEGREES per 100 m"),
    (None, lambda p, R, pt, Rt, i, j, L: np.rad2deg(_segment_motion_errors(p, R, pt, Rt, i, j)[1] / L),
     "that is degrees per METRE; the unit is degrees per 100 m (× 100)"),
    (None, lambda p, R, pt, Rt, i, j, L: np.rad2deg(_segment_motion_errors(p, R, pt, Rt, i, j)[1]),
     "not divided by the segment's length: the rotational error is per length travelled, in degrees per "
     "100 m"),
    (None, lambda p, R, pt, Rt, i, j, L: _segment_motion_errors(p, R, pt, Rt, i, j)[1] / L,
     "radians per metre: the unit is degrees per 100 m"),
    (None, lambda p, R, pt, Rt, i, j, L: _per_100m_deg(np.abs(so3.angle(_rel(pt, Rt, i, j)[1])
                                                              - so3.angle(_rel(p, R, i, j)[1])), L),
     "angles do not subtract: two rotations by the same angle about different axes differ. Take the "
     "angle of the rotation between the two relative rotations, ΔRᵀ ΔR_true"),
    (None, lambda p, R, pt, Rt, i, j, L: _per_100m_deg(np.linalg.norm(
        so3.log(_rel(pt, Rt, i, j)[1]) - so3.log(_rel(p, R, i, j)[1]), axis=1), L),
     "rotation vectors do not subtract: take the angle of the rotation between the two relative "
     "rotations, ΔRᵀ ΔR_true"),
    (None, lambda p, R, pt, Rt, i, j, L: _per_100m_deg(so3.angle(np.swapaxes(Rt[i], -1, -2) @ R[i]
                                                                 @ np.swapaxes(R[j], -1, -2) @ Rt[j]), L),
     "the rotations were compared in the navigation frame: the relative rotation of the segment is "
     "R_iᵀ R_j (your relative_motion) for the estimate and for the truth"),
    (lambda p, R, pt, Rt, i, j, L: _drift_r(p, R, pt, Rt, i, j, L), lambda p, R, pt, Rt, i, j, L: _drift_t(
        p, R, pt, Rt, i, j, L), "the two outputs are swapped: (translational error %, rotational error °/100 m)"),
]


@check(uses=("relative_motion",))
def check_drift_segments(segment_errors):
    """``segment_errors(position, rotation, true_position, true_rotation, first, last, length)`` returns
    (translational error % (S,), rotational error °/100 m (S,))."""
    cases = drift_cases()
    labels = [c[0] for c in cases]
    args = [c[1:] for c in cases]
    results = [_pair(call(segment_errors, *a), "segment_errors", ("t_err", "r_err")) for a in args]
    S = [len(a[4]) for a in args]
    t = [_array(r[0], (n,), f"the translational errors ({label})") for r, n, label in zip(results, S, labels)]
    r = [_array(r[1], (n,), f"the rotational errors ({label})") for r, n, label in zip(results, S, labels)]
    t_ok = all(_close(g, _drift_t(*a), ATOL, DRIFT_RTOL) for g, a in zip(t, args))
    r_ok = all(_close(g, _drift_r(*a), ATOL, DRIFT_RTOL) for g, a in zip(r, args))
    if t_ok and r_ok:
        return
    outputs = {why: (t_wrong, r_wrong) for t_wrong, r_wrong, why in _DRIFT_MISTAKES}
    why = known_mistake(list(zip(t, r)), args, [(pair, why) for why, pair in outputs.items()],
                        lambda g, w, n: _close(g[0], w[0], ATOL, DRIFT_RTOL) and _close(g[1], w[1], ATOL, DRIFT_RTOL),
                        evaluate=lambda pair, a: (_evaluate(pair[0] or _drift_t, a), _evaluate(pair[1] or _drift_r, a)))
    if why is not None:
        t_wrong, r_wrong = outputs[why]
        what = "both outputs are" if t_wrong and r_wrong else \
            "the translational errors are" if t_wrong else "the rotational errors are"
        raise CheckFailed(f"{what} wrong ({labels[0]}). Hint: {why}")
    if not t_ok:
        _judge("the translational errors (%)", t, args, labels, _drift_t, (),
               "the difference of the displacements over the segment, each seen from the segment's start "
               "(relative_motion), in % of the segment's length L (lecture 10 §2)"
               + hints.formula(": 100 |Δp_true − Δp| / L"), rtol=DRIFT_RTOL)
    _judge("the rotational errors (°/100 m)", r, args, labels, _drift_r, (),
           "the angle of ΔRᵀ ΔR_true (the relative rotations of the segment, estimated and true) per segment "
           "length, in degrees per 100 m (lecture 10 §2)", rtol=DRIFT_RTOL)


# --------------------------------------------------------------------------------------
# challenge: one step of choosing the VO noise by the NIS
# --------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def nis_cases():
    """(label, σ, innovations (N, m), S (N, m, m)) of the relative VO filter's first NIS_SECONDS.

    Real IMU and VO (ORB-SLAM2, S-PTAM); each run with σ = factor × (1 cm, 0.01°) per component,
    cut into the blocks :data:`NIS_BLOCKS`. Under a run seed: a stretch of drawn length
    (:data:`NIS_SECONDS_DRAWN`, from the same start: the filter starts at the anchor frame),
    the factors drawn per system (:data:`NIS_FACTORS_DRAWN`) and other blocks of the same
    sizes (a whole position and attitude block, one component of each, two of one unit).
    """
    g = inputs.rng("real_sensors.nis", 0)
    seconds, blocks = NIS_SECONDS, NIS_BLOCKS
    if inputs.drawing():
        seconds = float(g.uniform(*NIS_SECONDS_DRAWN))
        # one position and one attitude component, and two components of one unit
        pos, att, two = int(g.integers(0, 3)), int(g.integers(3, 6)), int(g.choice([0, 1, 3, 4]))
        blocks = ((0, 3), (3, 6), (pos, pos + 1), (att, att + 1), (two, two + 2))
    out = []
    for system in DRIFT_SYSTEMS:
        s = vo.setup("seq00", system)
        factors = NIS_FACTORS
        if inputs.drawing():
            factors = tuple(float(inputs.log_uniform(g, *r)) for r in NIS_FACTORS_DRAWN)
        for factor in factors:
            std = factor * _NIS_STD0
            res = vo.run_relative_vo(s, tuple(std), t_end=float(s.t[0] + seconds))
            y, S = np.array(res.innovation), np.array(res.S)
            for a, b in blocks:
                yb, Sb = np.ascontiguousarray(y[:, a:b]), np.ascontiguousarray(S[:, a:b, a:b])
                for arr in (yb, Sb):
                    arr.setflags(write=False)
                unit = "m" if b <= 3 else "rad"
                out.append((f"{system}, σ = {std[a]:.3g} {unit}, components {a}:{b} of {len(yb)} increments",
                            float(std[a]), yb, Sb))
    return tuple(out)


def _block_nis(y, S):
    return metrics.nis(y, S)


def _ratio(y, S, statistic=np.median, target=None):
    m = y.shape[1]
    return statistic(_block_nis(y, S)) / (metrics.chi2_ppf(0.5, m) if target is None else target(m))


def _ref_std(std, y, S):
    return std * np.sqrt(_ratio(y, S))


def _diagonal(S):
    return S * np.eye(S.shape[-1])


_NIS_MISTAKES = [
    (lambda std, y, S: std,
     "σ came back unchanged: the innovations were not used (the placeholder). Compute each increment's "
     "NIS, compare its median with the χ² median of as many degrees of freedom as components, and scale σ "
     "so that the ratio would become 1 if S scaled like R"),
    (lambda std, y, S: std * np.sqrt(_ratio(y, S, statistic=np.mean)),
     "the MEAN NIS was used: the real innovations have a heavy tail (VO glitches, interpolated IMU "
     "samples), which the mean follows and the median ignores; compare the median with the χ² median"),
    (lambda std, y, S: std * np.sqrt(_ratio(y, S, target=lambda m: m)),
     "the median NIS was compared with m, the MEAN of χ²(m); the median of χ²(m) is lower "
     "(chi2_ppf(0.5, m): 0.455 for one component, 2.37 for three)"),
    (lambda std, y, S: std * np.sqrt(_ratio(y, S, statistic=np.mean, target=lambda m: m)),
     "mean NIS against m: the real innovations have a heavy tail that the mean follows; use the median "
     "NIS and the median of χ²(m)"),
    (lambda std, y, S: std * _ratio(y, S),
     "σ was scaled by the ratio of NIS values itself: a NIS scales like a VARIANCE (ν²/S), so σ scales with "
     "its square root"),
    (lambda std, y, S: std / np.sqrt(_ratio(y, S)),
     "the ratio is upside down: a median NIS ABOVE the χ² median means the innovations are larger than S "
     "says, so σ must grow"),
    (lambda std, y, S: std ** 2 * _ratio(y, S),
     "that is a variance (σ²); return the standard deviation σ"),
    (lambda std, y, S: std * np.sqrt(_ratio(y, S, target=lambda m: metrics.chi2_ppf(0.5, 6))),
     "the χ² median of 6 degrees of freedom for every block: use as many as the block has components "
     "(innovation.shape[1])"),
    (lambda std, y, S: std * np.sqrt(_ratio(y, S, target=lambda m: metrics.chi2_ppf(0.5, 3))),
     "the χ² median of 3 degrees of freedom for every block: use as many as the block has components "
     "(innovation.shape[1])"),
    (lambda std, y, S: std * np.sqrt(_ratio(y, _diagonal(S))),
     "only the diagonal of S was used: the components of one increment's innovation are correlated "
     "through the filter's covariance; the NIS is νᵀ S⁻¹ ν with the whole S"),
    (lambda std, y, S: std * float(np.clip(np.sqrt(_ratio(y, S)), 0.5, 2.0)),
     "the step was clipped to [½, 2]: this function returns the unclipped σ (the loop that calls it limits "
     "its steps)"),
]


@check
def check_nis_rescaled_std(rescaled_std):
    """``rescaled_std(std, innovation, S)`` returns the next σ (a number) for one block."""
    cases = nis_cases()
    labels = [c[0] for c in cases]
    args = [c[1:] for c in cases]
    got = []
    for a, label in zip(args, labels):
        value = as_array(call(rescaled_std, *a), f"the new σ ({label})")
        if value.size != 1:
            raise CheckFailed(f"the new σ ({label}) should be one number, got shape {value.shape}. Hint: one σ "
                              "for the whole block: the median of the NIS of all increments, not one per "
                              "increment or per component")
        got.append(value.reshape(()))
    _judge("the new σ", got, args, labels, _ref_std, _NIS_MISTAKES,
           "scale σ so that the median NIS of the block would meet the χ² median of as many degrees of freedom as "
           "the block has components, the NIS of each increment with the block's whole S (lecture 10 §2); a NIS "
           "scales like a variance" + hints.formula(": σ × √(median NIS / χ² median)"), atol=0.0)
