"""Checks for chapter 08: the pieces of the error-state Kalman filter, and a run on KITTI.

States come from KITTI ground truth (tilted attitudes, real IMU readings) with made-up
non-zero biases. A wrong block matrix (F_t, B_t, the nominal-state A) is reported block by
block, naming the block and, where the mistake is a known one (sign, transpose, frame,
missing bias correction), the mistake. The whole run is compared with
:func:`kalman_course.filters.eskf.run` on a 5 s slice of the turns excerpt; when it differs,
the check first grades the pieces the learner's run calls, then rebuilds the run from those
pieces, so that the lecture's first-order forms (accepted by their own checks) are accepted
in the run too, and a mistake made in the run itself (a dropped reset, σ for σ², degrees
for radians, no update at all, the prior stored for the posterior, ...) is named.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every case is drawn anew from
its family. Real: the KITTI ``turns`` samples of the states (other samples, with other
drawn tilts and biases) and, for the whole run, the real IMU readings and ground truth of a
drawn window of ``turns`` (3–5 s, no longer than the fixed 5 s, starting at a drawn truth
pose). Simulated: the run's lidar poses (the excerpt's noise model, another noise seed); the
attitude errors of the residual and injection cases (sizes drawn in the same four bands,
3e-3 … 5e-2 rad); the time steps of the discretisation, propagation and challenge cases; the
dense covariances P and the correlated R of the gain and update cases (the lidar σ drawn
around the course's and the GNSS σ on both sides of 1 m), the sub-optimal gain's factor; the
reset's δx̂ (three sizes, |δθ̂| ≤ 0.09 rad); the map frames of the pose residual (made up:
turned by 0.5–3 rad about axes near the vertical, their origins drawn within about 1 km); and
the quaternion pairs of the nominal-state EKF (attitudes at 0, in the middle and
10⁻³ … 3·10⁻² rad short of π, and a pair across π).

The pose residual is judged twice on each case: with the measured pose in the navigation frame
(four arguments, as the run calls it), then with the same pose expressed in a map frame
(:data:`MAP_FRAMES`) whose origin and axes the call passes, so the lecture's navigation-frame
residual passes the first and is named on the second. The reset is judged for the attitude
error in the body frame (this filter's, two arguments, as the run calls it) and in the
navigation frame (lecture 08 §1's global error, ``frame="navigation"``), whose block has the
opposite sign; the two blocks exchanged (or Gᵀ P G, which exchanges them) are named first.

The discretisation is also swept over steps from 1e-6 to 10 s (T = 1 s left out, where T, √T
and T² coincide). Sign choices that leave B Q Bᵀ unchanged (a noise column negated, in B_t or
in the discretised B) are accepted: −n has the covariance of n, and the filter uses B only in
B Q Bᵀ. The run's diagnosis tries R built with wrong units first (the attitude σ in degrees,
converted twice, a variance converted with one factor, σ for σ²: that section's own task),
comparing the first two updates before rebuilding a whole run. Hints come in tiers
(:mod:`hints`), and a result in single precision is named before its values are compared.

The exercise's whole-step placeholders are recognised and named: a covariance returned
unpropagated, a nominal state returned uninjected, a run that never uses its lidar poses, and
(in the optional challenge) a finite-difference Jacobian left at zero. The accelerometer noise
of the course's configuration is isotropic, so a B_t whose n_a block is left unrotated changes
nothing in the filter; the noise-Jacobian check therefore also evaluates B Q Bᵀ with an
anisotropic accelerometer (:data:`ANISOTROPIC_ACCEL`), where that mistake shows.

Tolerances (and why)
--------------------
- Exact formulas (F_t, B_t, F, B, P̌, K, P̂, A): 1e-10 … 1e-8, round-off only; every graded
  mistake changes a result by more than 1e-4 relative on these cases.
- Attitude residual and injection: |error| ≤ |δθ|², because the lecture's first-order forms
  (δθ = (R_measᵀ Ř − I)^∨, R̂ = Ř (I − [δθ]×) re-orthonormalised) differ from Log / Exp by
  O(|δθ|²) (at most |δθ|²/4 for the vee of R − I, |δθ|³/3 for the SVD-projected injection),
  while every sign, frame or order mistake errs by O(|δθ|) (the cases have |δθ| ≤ 0.1, so
  the margin is at least a factor 10).
- Map-frame residual: the same tolerances as in the navigation frame (the map frame's
  rotation and shift add round-off of ~1e-13 m on origins of ~1 km); every map-frame mistake
  errs by more than 1 cm in position or 100 attitude tolerances (tests measure it).
- Reset: exact G P Gᵀ with G = J_l(δθ̂) (body frame) or J_r(δθ̂) (navigation frame), or the
  first-order I ± ½[δθ̂]×, or anything within |δθ̂|² max|P[6:9]| (any G = I ± ½[δθ̂]× +
  O(|δθ̂|²)); the other frame's block (the sign mistake) errs by about |δθ̂| max|P[6:9]|, 5.5 to
  13 tolerances (measured over the fixed cases and six run seeds).
- Run: positions and rotations 1e-6, P 1e-3 relative, against the reference run or a run
  rebuilt from the learner's own (checked) pieces.
- Challenge (finite-difference transition J): 1e-5 absolute against the check's own central
  differences (h = 1e-6; round-off on positions of a few hundred metres is about 1e-7, a
  one-sided difference errs by about 1e-8); every graded mistake errs by O(1) in some block.
"""

from __future__ import annotations

import contextlib
import dataclasses
import functools
import io

import numpy as np

from kalman_course.filters import eskf
from kalman_course.core import so3
from kalman_course.core.linalg import expm, symmetrise
from kalman_course.evaluation.metrics import position_rmse
from kalman_course.checks import cases as inputs
from kalman_course.checks import hints
from kalman_course.checks.harness import CheckFailed, call, check, expect_close, expect_shape, expect_symmetric
from kalman_course.checks.harness import known_mistake, learner_namespace, upstream_failure
from kalman_course.data import TruthData, load_kitti, simulate_lidar_poses
from kalman_course.filters.eskf import NominalState
from kalman_course.filters.eskf_config import load_config

#: The whole-run check: excerpt and length of the slice (s).
RUN_EXCERPT, RUN_SECONDS = "turns", 5.0
DENSITY = np.array([0.03, 1e-3, 1.67e-4, 2.91e-6])
#: Accelerometer white-noise densities per body axis (m/s²/√Hz) of an IMU whose vertical axis is
#: noisier (vibration): with them, B Q Bᵀ shows whether n_a was rotated into the navigation frame.
ANISOTROPIC_ACCEL = np.array([0.02, 0.03, 0.09])

#: Rows / columns of the error state and of the noise vector: (name, start, stop).
_ERR = (("δp", 0, 3), ("δv", 3, 6), ("δθ", 6, 9), ("δb_a", 9, 12), ("δb_ω", 12, 15))
_NOISE = (("n_a", 0, 3), ("n_ω", 3, 6), ("n_ba", 6, 9), ("n_bω", 9, 12))
_NOMINAL = (("p", 0, 3), ("v", 3, 6), ("q", 6, 10), ("b_a", 10, 13), ("b_ω", 13, 16))


@functools.lru_cache(maxsize=None)
def _cases(count: int = 4, seed: int = 8):
    """(nominal state, f, ω) from KITTI truth and readings, with non-zero biases."""
    ex = load_kitti("turns")
    rng = inputs.rng("eskf.states", seed)   # under a run seed: other samples, tilts and biases
    out = []
    for k in rng.choice(np.arange(100, len(ex.imu) - 100), size=count, replace=False):
        nav = ex.truth.state_at(float(ex.imu.t[k]))
        tilt = so3.exp(rng.normal(size=3) * 0.3)           # tilt it more than a road does
        x = NominalState(nav.position, nav.velocity, nav.rotation @ tilt,
                         rng.normal(size=3) * 0.05, rng.normal(size=3) * 0.005)
        out.append((x, ex.imu.specific_force[k].copy(), ex.imu.angular_rate[k].copy()))
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _attitude_scales():
    """The sizes (rad, per axis) of the attitude errors of the residual and injection cases,
    one per state of :func:`_cases`: a spread over 3e-3 … 5e-2, drawn in the same bands."""
    bands = ((0.005, 0.015), (0.002, 0.005), (0.015, 0.03), (0.03, 0.05))
    return inputs.fixed_or_drawn((0.01, 0.003, 0.03, 0.05),
                                 lambda rng: tuple(float(inputs.log_uniform(rng, *b)) for b in bands),
                                 "eskf.attitude_scales")


@functools.lru_cache(maxsize=None)
def _steps():
    """Time steps (s): the discretisation's (random walk, then constant bias), the propagation's
    (one per state of :func:`_cases`) and the challenge's."""
    def draw(rng):
        return (tuple(inputs.log_uniform(rng, 0.002, 0.02, 2)), (float(inputs.log_uniform(rng, 0.002, 0.02)),),
                tuple(inputs.log_uniform(rng, 0.004, 0.02, 4)), float(rng.uniform(0.01, 0.02)))
    return inputs.fixed_or_drawn(((0.01, 0.004), (0.01,), (0.01,) * 4, 0.01), draw, "eskf.steps")


def _error(nom, true):
    """The error of ``nom`` with respect to ``true`` (15,), error = nominal − true, δθ in the body frame."""
    return np.concatenate([nom.position - true.position, nom.velocity - true.velocity,
                           so3.log(true.rotation.T @ nom.rotation),
                           nom.accel_bias - true.accel_bias, nom.gyro_bias - true.gyro_bias])


def _error_nav_frame(nom, true):
    """The same with the attitude error taken in the navigation frame, Log(Ř Rᵀ) (a graded mistake)."""
    e = _error(nom, true)
    e[6:9] = so3.log(nom.rotation @ true.rotation.T)
    return e


def _fd_transition(x, f, w, T, g, h=1e-6, error=_error, step_nominal=True, step_true=True):
    """∂(error after one IMU step)/∂(error before it) at δx = 0, by central differences.

    The true state with error d is ``inject(x, d)``; readings f, ω held over the step.
    ``error`` and leaving the nominal or the true states unstepped build graded mistakes.
    """
    def step(state, stepped):
        return eskf.nominal_step(state, f, w, f, w, T, g) if stepped else state

    x1 = step(x, step_nominal)
    J = np.zeros((15, 15))
    for i in range(15):
        d = np.zeros(15)
        d[i] = h
        J[:, i] = (error(x1, step(eskf.inject(x, d), step_true))
                   - error(x1, step(eskf.inject(x, -d), step_true))) / (2 * h)
    return J


def _close(a, b, atol, rtol=0.0) -> bool:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return a.shape == b.shape and bool(np.allclose(a, b, rtol=rtol, atol=atol))


def _narrow_floats(value, depth: int = 0):
    """The floating dtypes narrower than float64 in a result (arrays, tuples, state fields)."""
    if depth > 3:
        return
    if isinstance(value, (np.ndarray, np.generic)) and value.dtype.kind in "fc" \
            and value.dtype.itemsize < (8 if value.dtype.kind == "f" else 16):
        yield value.dtype.name
    elif isinstance(value, (tuple, list)):
        for item in value:
            yield from _narrow_floats(item, depth + 1)
    elif dataclasses.is_dataclass(value) and not isinstance(value, type):
        for field in dataclasses.fields(value):
            yield from _narrow_floats(getattr(value, field.name), depth + 1)


def _expect_double(value, what: str) -> None:
    """Fail on a result in single precision before its values are compared: the tolerances
    (1e-10 … 1e-15) are far below float32's rounding (about 6e-8 relative), so the value
    comparison would report a wrong number instead of the cause."""
    narrow = next(_narrow_floats(value), None)
    if narrow is not None:
        raise CheckFailed(f"{what} is {narrow}: it was computed in single precision. Hint: keep NumPy's "
                          "default float64 (no .astype(np.float32), no dtype=np.float32); float32 keeps about "
                          "7 digits, and a filter's covariance loses more than that in a few steps")


def _same_up_to_column_signs(got, ref, atol: float) -> bool:
    """Whether each column of ``got`` is the same column of ``ref`` or its negative."""
    got, ref = np.asarray(got, dtype=float), np.asarray(ref, dtype=float)
    if got.shape != ref.shape or got.ndim != 2:
        return False
    if got.size == 0:
        return True
    same = np.abs(got - ref).max(axis=0) <= atol          # column by column, as np.allclose(rtol=0)
    flipped = np.abs(got + ref).max(axis=0) <= atol
    return bool(np.all(same | flipped))


def _expect_blocks(got, ref, rows, cols, what: str, formulas: dict, alternatives: dict,
                   atol: float = 1e-10, fallback: str = "", section: str = "lecture 08 §1",
                   column_signs_free: bool = False) -> None:
    """Fail naming the first wrong block of the block matrix ``got`` (and the mistake, if known).

    Parameters
    ----------
    got, ref : numpy.ndarray
        The learner's matrix (already of the right shape) and the reference.
    rows, cols : tuple of (name, start, stop)
        The block partition.
    what : str
        Name of the matrix in messages (``F_t``).
    formulas : dict
        ``{(row, col): "−R[a]×"}``: what each non-zero block should be (shown at hint tier 2).
    alternatives : dict
        ``{(row, col): [(wrong block, hint), ...]}``: known wrong values of one block.
    atol : float
        Absolute tolerance per entry (the blocks are O(1) … O(10)).
    fallback : str
        Added to the message of a wrong block that matches no known mistake.
    section : str
        Where the lecture derives the blocks, for the hints.
    column_signs_free : bool
        Take a block whose columns equal the reference's up to their signs as right (a noise
        Jacobian: see :func:`check_eskf_noise_jacobian`).
    """
    same = (lambda g, e: _same_up_to_column_signs(g, e, atol)) if column_signs_free else \
        (lambda g, e: _close(g, e, atol))
    for rname, r0, r1 in rows:
        for cname, c0, c1 in cols:
            g, e = got[r0:r1, c0:c1], ref[r0:r1, c0:c1]
            if same(g, e):
                continue
            where = f"the ({rname}, {cname}) block of {what} (rows {r0}:{r1}, columns {c0}:{c1})"
            formula = formulas.get((rname, cname), "0")
            should_be = hints.formula(f"; it should be {formula}")
            why = known_mistake([g], [None], alternatives.get((rname, cname), ()),
                                close=lambda mine, wrong, _: wrong is not None and same(mine, wrong),
                                evaluate=lambda wrong, _: wrong)
            if why:
                raise CheckFailed(f"{where} is wrong. Hint: {why}")
            if not e.any():
                raise CheckFailed(f"{where} should be zero: nothing in this model couples {rname} to {cname} "
                                  f"(a block put in the wrong place? check the row and column ranges; {section})")
            if not g.any():
                elsewhere = [f"rows {q0}:{q1}, columns {d0}:{d1}" for _, q0, q1 in rows for _, d0, d1 in cols
                             if (q0, d0) != (r0, c0) and got[q0:q1, d0:d1].shape == e.shape
                             and not ref[q0:q1, d0:d1].any() and same(got[q0:q1, d0:d1], e)]
                if elsewhere:
                    raise CheckFailed(f"{where} is missing: its value was put in the wrong place "
                                      f"({elsewhere[0]}). Hint: rows are the derivative, columns the variable "
                                      f"({section})" + should_be)
                raise CheckFailed(f"{where} is missing (all zeros). Hint: {rname} depends on {cname} ({section})"
                                  + should_be)
            if _close(g, -e, atol):
                raise CheckFailed(f"{where} has the wrong sign. Hint: the error is nominal − true, and each sign "
                                  f"follows from it ({section})" + should_be)
            if g.shape[0] == g.shape[1] and same(g, e.T):
                raise CheckFailed(f"{where} is transposed. Hint: R = R_nb maps body to navigation, Rᵀ maps back "
                                  f"({section})" + should_be)
            err = np.abs(g - e).max()
            raise CheckFailed(f"{where} differs from the reference (max abs error {err:.3g}) ({section})"
                              + hints.formula(f"; it should be {formula}.") + (f" {fallback}" if fallback else ""))


_F_FORMULAS = {("δp", "δv"): "I", ("δv", "δθ"): "−R[a]× with a = f − b_a (body frame)",
               ("δv", "δb_a"): "−R", ("δθ", "δθ"): "−[ω − b_ω]×", ("δθ", "δb_ω"): "−I"}


@check
def check_eskf_error_dynamics(error_dynamics):
    """``error_dynamics(R, f, w, b_a, b_w)`` returns F_t (15, 15)."""
    g = np.array([0.0, 0.0, -9.8092])
    for x, f, w in _cases():
        R, b_a, b_w = x.rotation, x.accel_bias, x.gyro_bias
        value = call(error_dynamics, R, f, w, b_a, b_w)
        _expect_double(value, "F_t")
        got = expect_shape(value, (15, 15), "F_t")
        ref = eskf.error_dynamics(R, f, w, b_a, b_w)
        if _close(got, ref, 1e-10):
            continue
        a, hat = f - b_a, so3.hat
        F = hints.formula
        alternatives = {
            ("δv", "δθ"): [
                (-hat(R @ a), "navigation-frame specific force: the δv–δθ block takes the bias-corrected "
                              "specific force in the BODY frame, and rotates after the cross product (lecture "
                              "08 §1)" + F(": −R[a]× with a = f − b_a, not −[R a]×")),
                (-R @ hat(f), "use the bias-corrected specific force inside the cross product (lecture 08 §1)"
                              + F(": a = f − b_a in −R[a]×")),
                (-R @ hat(f + b_a), "the bias is subtracted from the reading, not added (lecture 08 §1)"
                                    + F(": a = f − b_a, not f + b_a")),
                (-R.T @ hat(a), "transpose: R = R_nb maps the body-frame force to navigation (lecture 08 §1)"
                                + F(", so −R[a]×, not −Rᵀ[a]×")),
                (-hat(a) @ R, "order of the product: rotate after the cross product (lecture 08 §1)"
                              + F(": −R[a]×, not −[a]× R")),
                (hat(R @ a), "sign and frame: the specific force is taken in the BODY frame, and the block "
                             "has a minus sign (lecture 08 §1)" + F(": −R[a]×, not +[R a]×")),
            ],
            ("δv", "δb_a"): [
                (-np.eye(3), "the accelerometer bias is a BODY-frame error: it enters δv̇ rotated into the "
                             "navigation frame (lecture 08 §1)" + F(": −R δb_a")),
                (-R.T, "transpose: R = R_nb maps body to navigation (lecture 08 §1)" + F(": the δv–δb_a block "
                                                                                       "is −R, not −Rᵀ")),
            ],
            ("δθ", "δθ"): [
                (-hat(w), "use the bias-corrected angular rate (lecture 08 §1)" + F(": −[ω − b_ω]×")),
                (-hat(w + b_w), "the bias is subtracted from the reading, not added (lecture 08 §1)"
                                + F(": −[ω − b_ω]×, not −[ω + b_ω]×")),
                (-R @ hat(w - b_w), "δθ is a body-frame error: its own block is not rotated by R (lecture 08 §1)"
                                    + F(": −[ω − b_ω]×")),
            ],
            ("δθ", "δb_ω"): [(-R, "the gyro bias and δθ are both in the body frame: nothing rotates between "
                                  "them (lecture 08 §1)" + F(": the block is −I, not −R"))],
        }
        T = 1e-3
        J = _fd_transition(x, f, w, T, g)
        fd_err = np.abs(J - (np.eye(15) + got * T)).max()
        _expect_blocks(got, ref, _ERR, _ERR, "F_t", _F_FORMULAS, alternatives,
                       fallback=f"I + F_t T differs from a finite-difference Jacobian of one IMU step by "
                                f"{fd_err:.2e} at T = 1 ms")


_B_FORMULAS = {("δv", "n_a"): "R", ("δθ", "n_ω"): "I", ("δb_a", "n_ba"): "I", ("δb_ω", "n_bω"): "I"}


def _accel_noise_effect(block, R) -> str:
    """What an unrotated n_a block does to B Q Bᵀ with an anisotropic accelerometer, in words.

    ``block`` is the learner's (δv, n_a) block of B_t. With the course's isotropic density
    σ² I, R σ² I Rᵀ = σ² I and the mistake is invisible in the filter; with different
    densities per body axis (:data:`ANISOTROPIC_ACCEL`) the velocity-noise rate
    block diag(σ²) blockᵀ differs from R diag(σ²) Rᵀ.
    """
    S = np.diag(ANISOTROPIC_ACCEL ** 2)
    ref, got = R @ S @ R.T, block @ S @ block.T
    rel = np.abs(got - ref).max() / np.abs(ref).max()
    tilt = np.degrees(np.arccos(np.clip(R[2, 2], -1.0, 1.0)))
    return (f"With this course's equal noise on the three accelerometer axes the mistake hides "
            f"(R σ² I Rᵀ = σ² I), but for an accelerometer with σ_a = {tuple(ANISOTROPIC_ACCEL.tolist())} "
            f"m/s²/√Hz per body axis, the velocity noise B Q Bᵀ would be off by {100 * rel:.0f} % here: each "
            f"body axis's noise would land on the navigation axis of the same name, although this body is "
            f"rotated (tilted by {tilt:.0f}°)")


#: Variances (one per noise column, all different) under which B Q Bᵀ is compared: the filter
#: uses B_t only through B Q Bᵀ (after discretisation, which scales columns), and with a
#: different variance on every column, B' Q B'ᵀ = B Q Bᵀ holds for B' = B diag(±1), a sign
#: choice per column, but not for a column rotated, permuted, moved or left out.
_COLUMN_VARIANCES = np.array([4.0, 9.0, 81.0, 1.0, 2.0, 3.0, 5.0, 6.0, 7.0, 11.0, 13.0, 17.0]) * 1e-4


def _noise_effect(B, cols: int) -> np.ndarray:
    """B diag(_COLUMN_VARIANCES) Bᵀ: what the filter does with a noise Jacobian."""
    B = np.asarray(B, dtype=float)
    return (B * _COLUMN_VARIANCES[:cols]) @ B.T


@check
def check_eskf_noise_jacobian(noise_jacobian):
    """``noise_jacobian(R, bias_model)`` returns B_t (15, 12) or (15, 6).

    Accepted besides the lecture's B_t: any sign of each noise column. The noise is zero-mean
    and symmetric, so −n has the covariance of n (lecture 08 §4); the filter uses B_t only in
    B Q Bᵀ, which a sign choice leaves unchanged (compared with :data:`_COLUMN_VARIANCES`).
    """
    for x, _, _ in _cases():
        R = x.rotation
        for model, cols in (("random_walk", 12), ("constant", 6)):
            what = f"B_t ({model} bias)"
            value = call(noise_jacobian, R, model)
            _expect_double(value, what)
            if np.shape(value) == (15, 12) and cols == 6:
                raise CheckFailed(f"{what} has shape (15, 12), expected (15, 6): the constant-bias model "
                                  "(δḃ = 0) has no bias-noise columns, only n_a and n_ω (lecture 08 §6)")
            got = expect_shape(value, (15, cols), what)
            ref = eskf.noise_jacobian(R, model)
            if _close(got, ref, 1e-12) or _close(_noise_effect(got, cols), _noise_effect(ref, cols), 1e-15, 1e-12):
                continue       # the lecture's B_t, or one with other signs of its columns
            alternatives = {
                ("δv", "n_a"): [
                    (np.eye(3), "n_a is accelerometer noise in the BODY frame; it enters δv̇ rotated "
                                "(lecture 08 §1): " + hints.formula("R n_a") + ". "
                                + _accel_noise_effect(np.eye(3), R)),
                    (R.T, "transpose: R = R_nb maps body to navigation, so the body-frame n_a enters δv̇ "
                          "through R, not Rᵀ (lecture 08 §1). " + _accel_noise_effect(R.T, R)),
                ],
                ("δθ", "n_ω"): [
                    (R, "δθ is a body-frame error and n_ω a body-frame noise: nothing rotates between them "
                        "(lecture 08 §1), " + hints.formula("the block is I, not R")),
                    (R.T, "δθ is a body-frame error and n_ω a body-frame noise: nothing rotates between them "
                          "(lecture 08 §1), " + hints.formula("the block is I, not Rᵀ")),
                ],
            }
            _expect_blocks(got, ref, _ERR, _NOISE[:cols // 3], what, _B_FORMULAS, alternatives, atol=1e-12,
                           fallback="columns n_a, n_ω, n_ba, n_bω; rows δp, δv, δθ, δb_a, δb_ω "
                                    "(the constant-bias model has no bias columns)",
                           section="lecture 08 §1", column_signs_free=True)


#: Steps (s) of the discretisation's sweep (random-walk model, the first state), from far below
#: an IMU's interval to a GNSS outage's seconds (T = 1 s is left out: there T, √T and T²
#: coincide, and so would the scaling mistakes). Four calls: the check's time stays within
#: 1.5 times what it was without them.
_SWEPT_STEPS = (1e-6, 1e-3, 0.3, 10.0)


@functools.lru_cache(maxsize=None)
def _swept_steps() -> tuple:
    """The sweep's steps: :data:`_SWEPT_STEPS`, each moved by up to 25 % under a run seed."""
    rng = inputs.rng("eskf.discretisation.sweep", 5)
    factors = inputs.log_uniform(rng, 0.8, 1.25, len(_SWEPT_STEPS)) if inputs.drawing() else np.ones(len(_SWEPT_STEPS))
    return tuple(float(T * k) for T, k in zip(_SWEPT_STEPS, factors))


def _white_and_walk_mistakes(s: float, T: float, random_walk: bool):
    """(wrong σ² T of a diagonal block of B Q Bᵀ, hint) for the scaling mistakes of B's columns."""
    if random_walk:
        return [(s * s * T * T, "T where √T belongs: a random walk's variance grows with T, so its column of B "
                                "scales with √T (lecture 08 §3)"),
                (s * s, "the random-walk column of B must be scaled by √T (lecture 08 §3)"),
                (s * s / T, "the random-walk column of B is multiplied by √T, not divided (lecture 08 §3)")]
    return [(s * s, "√T where T belongs: with the per-sample variance σ²/T in Q, a white-noise column of B "
                    "scales with T (lecture 08 §3)"),
            (s * s / T, "the white-noise column of B must be scaled by T (lecture 08 §3)"),
            (s * s * T ** 3, "the white-noise column of B is scaled by T, not T² (lecture 08 §3)"),
            (s * s / T ** 3, "the white-noise column of B is multiplied by T, not divided (lecture 08 §3)")]


@check
def check_eskf_discretisation(discretise):
    """``discretise(F_t, B_t, T)`` returns (F, B); checked through the blocks of B Q Bᵀ.

    Steps: the cases' own (about an IMU interval), then a sweep over :data:`_SWEPT_STEPS` on
    the first state. B is accepted with any sign of each column (the filter uses it only in
    B Q Bᵀ, see :func:`check_eskf_noise_jacobian`).
    """
    first = True
    for x, f, w in _cases():
        F_t = eskf.error_dynamics(x.rotation, f, w, x.accel_bias, x.gyro_bias)
        for model in ("random_walk", "constant"):
            B_t = eskf.noise_jacobian(x.rotation, model)
            own = _steps()[0 if model == "random_walk" else 1]
            for T in own + (_swept_steps() if first and model == "random_walk" else ()):
                result = call(discretise, F_t, B_t, T)
                if not isinstance(result, (tuple, list)) or len(result) != 2:
                    raise CheckFailed("discretise must return a tuple (F, B)")
                _expect_double(result, f"(F, B) for T = {T:g}")
                F_ref, B_ref = eskf.discretise(F_t, B_t, T)
                I = np.eye(15)
                F_got = expect_shape(result[0], F_ref.shape, f"F for T = {T:g}")
                if not _close(F_got, F_ref, 1e-12, 1e-13):   # the mistakes (expm: 0.1 ms each) only on failure
                    why = hints.formula(": F = I + F_t T")
                    expect_close(F_got, F_ref, f"F for T = {T:g}", rtol=1e-13, atol=1e-12, mistakes=[
                        (F_t * T, "the identity is missing from F (lecture 08 §3)" + why),
                        (I + F_t, "F_t must be multiplied by the step T (lecture 08 §3)" + why),
                        (I - F_t * T, "sign: the error moves forward along δẋ over the step (lecture 08 §3)"
                                      + hints.formula(": F = I + F_t T, since δx_k ≈ δx_{k−1} + δẋ T")),
                        (I + F_t * T * T, "F_t is multiplied by the step T, not T² (lecture 08 §3)" + why),
                        (expm(F_t * T), "that is the exact exponential e^{F_t T}; the lecture and the course "
                                        "use its first-order form (lecture 08 §3; they differ by ½ F_t² T²)" + why),
                    ], hint="F = I + F_t T is given in the exercise: return it unchanged")
                B = expect_shape(result[1], B_ref.shape, f"B for T = {T:g} ({model} bias)")
                Qd = B @ eskf.process_noise(DENSITY, T, model) @ B.T
                blocks = (("δv", 3, DENSITY[0]), ("δθ", 6, DENSITY[1]), ("δb_a", 9, DENSITY[2]),
                          ("δb_ω", 12, DENSITY[3]))
                for name, i, s in blocks[:2] if model == "constant" else blocks:
                    expect_close(Qd[i, i], s * s * T, f"the {name} block of B Q Bᵀ for T = {T:g}", rtol=1e-9,
                                 atol=0.0, mistakes=_white_and_walk_mistakes(s, T, i >= 9),
                                 hint="B Q Bᵀ must add the variance each noise really brings in over T seconds "
                                      "(lecture 08 §3)" + hints.formula(": σ² T on every block"))
                # any sign of a column: −n has the covariance of n, and B enters the filter as B Q Bᵀ only
                if not _same_up_to_column_signs(B, B_ref, 1e-14 * max(1.0, T)):
                    raise CheckFailed(f"B for T = {T:g} differs from B_t with its columns scaled (max abs error "
                                      f"{np.abs(np.abs(B) - np.abs(B_ref)).max():.3g}). Hint: each column of B is "
                                      "the same column of B_t, scaled for one step as its kind of noise needs "
                                      "(lecture 08 §3)" + hints.formula(": the n_a, n_ω columns × T and the bias "
                                                                        "columns × √T"))
        first = False


@functools.lru_cache(maxsize=None)
def _propagate_cases():
    """(P, F, B, Q): a dense P and the transition and noise of one step from each state."""
    rng = inputs.rng("eskf.propagate", 2)
    out = []
    for (x, f, w), T in zip(_cases(), _steps()[2]):
        A = rng.normal(size=(15, 15)) * 0.1
        P = A @ A.T + 1e-4 * np.eye(15)
        F, B = eskf.discretise(eskf.error_dynamics(x.rotation, f, w, x.accel_bias, x.gyro_bias),
                               eskf.noise_jacobian(x.rotation), T)
        out.append((P, F, B, eskf.process_noise(DENSITY, T)))
    return tuple(out)


@check
def check_eskf_propagate(propagate_covariance):
    """``propagate_covariance(P, F, B, Q)`` returns P̌ (15, 15), symmetric positive definite."""
    F_ = hints.formula
    for P, F, B, Q in _propagate_cases():
        value = call(propagate_covariance, P, F, B, Q)
        _expect_double(value, "P_check")
        got = expect_shape(value, (15, 15), "P_check")
        ref = eskf.propagate_covariance(P, F, B, Q)
        noise = B @ Q @ B.T
        half = F @ P @ F
        expect_close(got, ref, "P_check", rtol=1e-9, atol=1e-15, mistakes=[
            (P, "P̌ equals P̂: the covariance was not propagated. Over a step the error is carried by the "
                "transition F, and the step's noise w (12 numbers, covariance Q) enters through B (lecture 08 "
                "§4, Predict)" + F_(": P̌ = F P̂ Fᵀ + B Q Bᵀ")),
            (F @ P @ F.T, "the process noise is missing: the step's noise adds uncertainty (lecture 08 §4)"
                          + F_(": P̌ = F P̂ Fᵀ + B Q Bᵀ")),
            (0.5 * (half + half.T) + noise, "transpose: the covariance is carried through F on both sides, "
                                            "once transposed (lecture 08 §4)" + F_(": F P̂ Fᵀ, not F P̂ F")),
            (half + noise, "transpose: the covariance is carried through F on both sides, once transposed "
                           "(lecture 08 §4)" + F_(": F P̂ Fᵀ, not F P̂ F")),
            (F.T @ P @ F + noise, "transpose: F on the left, Fᵀ on the right (lecture 08 §4)"
                                  + F_(": F P̂ Fᵀ, not Fᵀ P̂ F")),
            (F @ P @ F.T - noise, "sign: the process noise adds uncertainty, it does not remove it (lecture 08 §4)"
                                  + F_(": + B Q Bᵀ")),
            (F @ P @ F.T + B @ np.sqrt(Q) @ B.T, "Q already holds variances: no square root (lecture 08 §3)"
                                                 + F_(": B Q Bᵀ, not B √Q Bᵀ")),
            (F @ P @ F.T + B @ Q @ Q @ B.T, "Q already holds variances: do not square it (lecture 08 §3)"
                                            + F_(": B Q Bᵀ, not B Q² Bᵀ")),
            (F @ P @ F.T + B @ B.T, "the noise covariance Q is missing between B and Bᵀ (lecture 08 §4)"
                                    + F_(": + B Q Bᵀ, not + B Bᵀ")),
            (P + noise, "the transition is missing: P̂ must be carried through F (lecture 08 §4)"
                        + F_(": P̌ = F P̂ Fᵀ + B Q Bᵀ, not P̂ + B Q Bᵀ")),
        ], hint="the prior covariance carries P̂ through the step's transition and adds the noise the step "
                "brings in (lecture 08 §4, Predict): " + F_("P̌ = F P̂ Fᵀ + B Q Bᵀ"))
        expect_symmetric(got, "P_check")


def _attitude_tolerance(dtheta) -> float:
    """|δθ|²: how far the lecture's first-order forms may be from Log / Exp (see the module notes)."""
    return float(np.dot(dtheta, dtheta)) + 1e-12


@functools.lru_cache(maxsize=None)
def _residual_cases():
    """(nominal state, p_meas, R_meas): a measured pose near each state (navigation frame)."""
    rng = inputs.rng("eskf.residual", 3)
    out = []
    for (x, _, _), scale in zip(_cases(), _attitude_scales()):
        p_m = x.position + rng.normal(size=3) * 0.2
        out.append((x, p_m, x.rotation @ so3.exp(rng.normal(size=3) * scale)))
    return tuple(out)


#: The map frames of the residual's map cases: (origin p_map (m), rotation vector of R_map (rad)) in
#: the navigation frame, one per case of :func:`_residual_cases`: turned by 2.4, 0.9, −2.9 and 1.6
#: rad about axes near the vertical (a map in another heading, slightly tilted), hundreds of metres away.
MAP_FRAMES = (((412.0, -173.5, 12.3), (0.05, -0.03, 2.4)), ((-95.0, 260.0, -4.0), (-0.08, 0.02, 0.9)),
              ((1500.0, 820.0, 35.0), (0.03, 0.1, -2.9)), ((-640.0, -310.0, 7.5), (0.12, -0.06, 1.6)))


@functools.lru_cache(maxsize=None)
def _map_frames():
    """(p_map (3,), R_map (3, 3)) per map case; under a run seed each turned by 0.5–3 rad about a
    drawn axis within about 0.15 rad of the vertical, its origin drawn within about 1 km."""
    def draw(rng):
        frames = []
        for _ in MAP_FRAMES:
            angle = rng.uniform(0.5, 3.0) * rng.choice((-1.0, 1.0))
            frames.append((tuple(rng.normal(size=3) * np.array([500.0, 500.0, 20.0])),
                           tuple(np.r_[rng.normal(size=2) * 0.1, angle])))
        return tuple(frames)
    frames = inputs.fixed_or_drawn(MAP_FRAMES, draw, "eskf.residual.map")
    return tuple((np.array(p, dtype=float), so3.exp(np.array(v, dtype=float))) for p, v in frames)


def _call_with_map(pose_residual, *args):
    """The learner's residual with the map frame's pose: a signature without it is named."""
    try:
        return call(pose_residual, *args)
    except CheckFailed as exc:
        if "positional argument" in str(exc) and "TypeError" in str(exc):
            raise CheckFailed("pose_residual takes the map frame's pose too: pose_residual(p_check, R_check, "
                              "p_meas, R_meas, p_map=np.zeros(3), R_map=np.eye(3)), where the defaults are "
                              "the navigation frame itself (the run's lidar poses). Hint: keep the cell's "
                              "first line as it is") from None
        raise


def _map_mistakes(x, p_meas, R_meas, p_map, R_map):
    """Known wrong ways to bring a map-frame pose into the residual: (position part, attitude
    part, hint) per mistake; None where that part is not what the mistake changes."""
    F_ = hints.formula
    p_c, R_c = x.position, x.rotation
    p_nav, R_nav = p_map + R_map @ p_meas, R_map @ R_meas
    position = [
        (p_c - p_meas, "the measured position is in the map frame and the prediction in the navigation frame: "
                       "bring the measurement into the navigation frame first, with the map frame's pose "
                       "(origin p_map, axes R_map)" + F_(": p_meas in the navigation frame is p_map + R_map p_meas")),
        (p_c - (p_map + R_map.T @ p_meas), "transpose: R_map turns map-frame vectors into the navigation "
                                           "frame, as R = R_nb turns body vectors (lecture 08 §1)"
                                           + F_(": p_map + R_map p_meas, not p_map + R_mapᵀ p_meas")),
        (p_c - R_map @ p_meas, "the map frame's origin is missing: a map-frame position is rotated into the "
                               "navigation axes and then shifted by where the map's origin lies, p_map"),
        (p_c - (R_map @ p_meas - p_map), "sign of the offset: the map's origin p_map is where the map-frame "
                                         "position 0 lies in the navigation frame, so it is added"),
        (p_c - R_map @ (p_meas + p_map), "order: p_map is a navigation-frame vector; rotate the map-frame "
                                         "position first, then add the origin"),
        (R_map.T @ (p_c - p_map) - p_meas, "this position residual is in the map frame: it is R_mapᵀ δp to "
                                           "first order, so its block of G would be R_mapᵀ, not the +I of "
                                           "POSE_G; compare the two positions in the navigation frame"),
        (p_meas - R_map.T @ (p_c - p_map), "this position residual is in the map frame, and measurement minus "
                                           "prediction: POSE_G's +I block needs prediction minus measurement in "
                                           "the navigation frame"),
    ]
    attitude = [
        (so3.log(R_meas.T @ R_c), "the measured attitude is the body's attitude in the map frame, the "
                                  "prediction's in the navigation frame: bring the measurement into the "
                                  "navigation frame first" + F_(": R_map R_meas (navigation ← map ← body)")),
        (so3.log((R_meas @ R_map).T @ R_c), "order of the rotations: the measured attitude maps body to map, "
                                            "R_map maps map to navigation, so R_map stands on the left"
                                            + F_(": R_map R_meas, not R_meas R_map")),
        (so3.log((R_map.T @ R_meas).T @ R_c), "transpose: R_map turns the map frame into the navigation frame"
                                              + F_(": R_map R_meas, not R_mapᵀ R_meas")),
    ]
    return p_nav, R_nav, position, attitude


@check
def check_eskf_pose_residual(pose_residual):
    """``pose_residual(p_check, R_check, p_meas, R_meas, p_map=0, R_map=I)`` returns y (6,).

    First with the measurement in the navigation frame (four arguments, as the run calls it),
    then the same measurements expressed in a map frame (:data:`MAP_FRAMES`), whose pose the
    call passes. The attitude part is accepted within |δθ|² of Log((R_map R_meas)ᵀ Ř): the
    lecture's first-order δθ = (R_navᵀ Ř − I)^∨ passes; sign, frame and order mistakes err by
    O(|δθ|), map-frame mistakes by O(1).
    """
    F_ = hints.formula
    cases = [(x, p_m, R_m, None) for x, p_m, R_m in _residual_cases()]
    cases += [(x, R_map.T @ (p_m - p_map), R_map.T @ R_m, (p_map, R_map))
              for (x, p_m, R_m), (p_map, R_map) in zip(_residual_cases(), _map_frames())]
    for x, p_meas, R_meas, frame in cases:
        if frame is None:
            value = call(pose_residual, x.position, x.rotation, p_meas, R_meas)
            p_m, R_m, map_position, map_attitude, where = p_meas, R_meas, [], [], ""
        else:
            value = _call_with_map(pose_residual, x.position, x.rotation, p_meas, R_meas, *frame)
            p_m, R_m, map_position, map_attitude = _map_mistakes(x, p_meas, R_meas, *frame)
            where = " (a pose measured in a map frame)"
        _expect_double(value, "y")
        got = expect_shape(value, (6,), "y")
        ref = eskf.pose_residual(x.position, x.rotation, p_m, R_m)
        dth = ref[3:]
        body = so3.log(x.rotation @ R_m.T)
        tol = _attitude_tolerance(dth)
        if not got.any():
            raise CheckFailed(f"y is zero{where}: nothing was compared (the placeholder). Hint: the residual "
                              "compares the predicted pose with the measured one, position first, then attitude as "
                              "a rotation vector, such that y ≈ G δx + n with POSE_G's +I blocks under error = "
                              "nominal − true (lecture 08 §4, Update)")
        if _close(got[:3], -ref[:3], 1e-12) and _close(got[3:], -dth, tol):
            raise CheckFailed(f"y is the negative of the residual (both parts){where}. Hint: sign: this is "
                              "measurement minus prediction, the habit of the earlier chapters. Here error = nominal "
                              "− true, and the residual must satisfy y ≈ G δx + n with G = POSE_G (blocks +I), so it "
                              "is prediction minus measurement (lecture 08 §4, Update)"
                              + F_(": y = [p̌ − p_meas; Log(R_measᵀ Ř)], the measurement in the navigation frame"))
        expect_close(got[:3], ref[:3], f"the position residual y[0:3]{where}", atol=1e-12, mistakes=[
            *map_position,
            (-ref[:3], "sign of the position residual: error = nominal − true, so the residual is prediction "
                       "minus measurement (lecture 08 §4)" + F_(": y = p̌ − p_meas")),
            (ref[3:], "order: y = [δp; δθ], the position residual first (lecture 08 §4)"),
        ], hint="the position residual compares prediction with measurement in the error's convention, both in "
                "the navigation frame (lecture 08 §4, Update): " + F_("y[0:3] = p̌ − p_meas"))
        expect_close(got[3:], dth, f"the attitude residual y[3:6]{where}", rtol=0.0, atol=tol, mistakes=[
            *map_attitude,
            (-dth, "sign of the attitude residual: Ř ≈ R_meas Exp(δθ), so the residual rotation is R_meas "
                   "undone from Ř, not the other way round (lecture 08 §4)"
                   + F_(": δθ = Log(R_measᵀ Ř), not Log(Řᵀ R_meas)")),
            (body, "the attitude error lives in the body frame: the rotations compose on the right "
                   "(lecture 08 §1)" + F_(": Log(R_measᵀ Ř), not Log(Ř R_measᵀ)")),
            (-body, "body frame and sign: the attitude error lives in the body frame (lecture 08 §1)"
                    + F_(": Log(R_measᵀ Ř), not Log(R_meas Řᵀ)")),
            (so3.log(R_m @ x.rotation), "transpose: one of the two rotations is undone, so it enters "
                                        "transposed (lecture 08 §4)" + F_(": Log(R_measᵀ Ř), not Log(R_meas Ř)")),
            (so3.log(x.rotation) - so3.log(R_m), "rotation vectors do not subtract: the difference of two "
                                                 "rotations is the rotation between them (lecture 07 §1)"
                                                 + F_(": δθ = Log(R_measᵀ Ř), not Log(Ř) − Log(R_meas)")),
            (ref[:3], "order: y = [δp; δθ], the attitude residual second (lecture 08 §4)"),
        ], hint="the attitude residual is the rotation vector between the measured and the predicted attitude, "
                "both in the navigation frame, in the body frame (lecture 08 §4, Update): "
                + F_("y[3:6] = Log(R_measᵀ Ř) (or, to first order, (R_measᵀ Ř − I)^∨)"))


def _update_case(seed=4):
    """(P, G, R) of a lidar pose: a dense prior P, and R of σ_p = 0.2 m, σ_θ = 0.3° (under a run
    seed: P drawn anew, σ_p in 0.05 … 0.5 m and σ_θ in 0.1 … 1°)."""
    rng = inputs.rng("eskf.update", seed)
    A = rng.normal(size=(15, 15)) * 0.05
    P = A @ A.T + np.diag(np.r_[np.full(3, 0.04), np.full(3, 0.01), np.full(3, 1e-4), np.full(3, 4e-4), np.full(3, 1e-6)])
    var_p, sigma_deg = 0.04, 0.3
    if inputs.drawing():     # drawn after P, so that the fixed stream stays as it was
        var_p, sigma_deg = inputs.log_uniform(rng, 0.05, 0.5) ** 2, inputs.log_uniform(rng, 0.1, 1.0)
    R = np.diag(np.r_[np.full(3, var_p), np.full(3, np.deg2rad(sigma_deg) ** 2)])
    return P, eskf.POSE_G.copy(), R


def _gnss_variances(rng):
    """GNSS variances (3,) under a run seed: σ from 0.3 to 2 m, some below and some above 1."""
    while True:
        sigma = inputs.log_uniform(rng, 0.3, 2.0, 3)
        if sigma.min() < 0.9 and sigma.max() > 1.1:   # both sides of 1, where R, √R and R² part
            return sigma ** 2


@functools.lru_cache(maxsize=None)
def _gain_cases():
    """(P, G, R): the lidar pose with diagonal and with correlated R, and a GNSS position fix."""
    out = []
    for seed in (4, 5):
        out.append(_update_case(seed))
    P, G, R = _update_case(6)
    C = inputs.rng("eskf.gain.correlation", 16).normal(size=(6, 6)) * 0.02
    out.append((P, G, R + C @ C.T))                                  # non-diagonal SPD R
    P, _, _ = _update_case(7)
    gnss = inputs.fixed_or_drawn(np.array([0.09, 0.25, 0.64]), _gnss_variances, "eskf.gain.gnss")
    out.append((P, eskf.POSITION_G.copy(), np.diag(gnss)))          # GNSS: G (3, 15)
    return tuple(out)


@functools.lru_cache(maxsize=None)
def _suboptimal_factor() -> float:
    """The factor of the sub-optimal gain c K of the update check (0.7; drawn in 0.3 … 0.9)."""
    return inputs.fixed_or_drawn(0.7, lambda rng: float(rng.uniform(0.3, 0.9)), "eskf.update.factor")


@check
def check_eskf_gain(kalman_gain):
    """``kalman_gain(P, G, R)`` returns K (15, m)."""
    F_ = hints.formula
    for P, G, R in _gain_cases():
        m = G.shape[0]
        value = call(kalman_gain, P, G, R)
        _expect_double(value, "K")
        if np.shape(value) == (m, 15):
            raise CheckFailed(f"K has shape {(m, 15)}, expected {(15, m)}: transpose? K maps the residual (m,) "
                              "to the error state (15,) (lecture 03 §3)" + F_(": K = P Gᵀ S⁻¹"))
        got = expect_shape(value, (15, m), "K")
        ref = eskf.kalman_gain(P, G, R)
        if _close(got, ref, 1e-12, 1e-8):
            continue
        inv, PGt, GPGt = np.linalg.inv, P @ G.T, G @ P @ G.T
        with np.errstate(invalid="ignore"):     # √R of a correlated R: NaN entries, never matched
            root_R = np.sqrt(R)
        S = F_(": S = G P Gᵀ + R")
        expect_close(got, ref, "K", rtol=1e-8, atol=1e-12, mistakes=[
            (PGt @ inv(GPGt), "the observation noise R is missing from the innovation covariance S (lecture 03 §3)"
                              + S),
            (PGt @ inv(R), "P Gᵀ R⁻¹ is the gain only when P is the POSTERIOR P̂ (it follows from the information "
                           "form P̂⁻¹ = P̌⁻¹ + Gᵀ R⁻¹ G); kalman_gain is given the PRIOR P̌ (lecture 03 §3, "
                           "lecture 08 §4)" + F_(", so K = P̌ Gᵀ S⁻¹ with S = G P̌ Gᵀ + R")),
            (PGt @ inv(GPGt + root_R), "R holds variances: no square root in S (lecture 03 §3)" + S),
            (PGt @ inv(GPGt + R @ R), "R holds variances already: do not square it in S (lecture 03 §3)" + S),
            (PGt @ inv(GPGt - R), "sign: the observation noise adds to the innovation covariance (lecture 03 §3)"
                                  + S),
            (PGt @ (GPGt + R), "the inverse is missing: the gain divides by S (lecture 03 §3)" + F_(": K = P Gᵀ S⁻¹")),
            (G.T @ inv(GPGt + R), "P is missing in front: the gain weighs by the prior covariance (lecture 03 §3)"
                                  + F_(": K = P Gᵀ S⁻¹")),
        ], hint="the gain weighs the prior uncertainty of the observed error against the innovation's "
                "(lecture 03 §3, lecture 08 §4, Update): " + F_("K = P Gᵀ (G P Gᵀ + R)⁻¹"))


@check
def check_eskf_covariance_update(update_covariance):
    """``update_covariance(P, K, G, R)`` returns P̂ (Joseph form, valid for any K)."""
    for P, G, R in _gain_cases():
        n = P.shape[0]
        K_opt = eskf.kalman_gain(P, G, R)
        c = _suboptimal_factor()
        for K, label in ((K_opt, "the optimal gain"), (c * K_opt, f"a sub-optimal gain {c:.2g} K")):
            value = call(update_covariance, P, K, G, R)
            _expect_double(value, f"P_hat with {label}")
            got = expect_shape(value, (n, n), f"P_hat with {label}")
            ref = eskf.update_covariance(P, K, G, R)
            if _close(got, ref, 1e-14, 1e-8):
                expect_symmetric(got, "P_hat")
                continue
            A = np.eye(n) - K @ G
            Ap = np.eye(n) + K @ G
            with np.errstate(invalid="ignore"):     # √R of a correlated R: NaN entries, never matched
                root_R = np.sqrt(R)
            KRK = K @ R @ K.T
            F_ = hints.formula
            joseph = F_(": P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ")
            expect_close(got, ref, f"P_hat with {label}", rtol=1e-8, atol=1e-14, mistakes=[
                (A @ P @ A.T, "the Joseph form needs its second term, the noise the gain lets in, + K R Kᵀ "
                              "(lecture 03 §8)" + joseph),
                (A @ P, "(I − K G) P̌ is right only for the optimal gain; the Joseph form holds for any K and stays "
                        "symmetric (lecture 03 §8)" + joseph),
                (symmetrise(A @ P), "(I − K G) P̌, even symmetrised, is right only for the optimal gain; the Joseph "
                                    "form holds for any K (lecture 03 §8)" + joseph),
                (A.T @ P @ A + KRK, "transpose: (I − K G) on the left, its transpose on the right (lecture 03 §8)"
                                    + F_(": (I − K G) P̌ (I − K G)ᵀ, not (I − K G)ᵀ P̌ (I − K G)")),
                (A @ P @ A.T - KRK, "sign: the Joseph form adds the measurement noise, + K R Kᵀ (lecture 03 §8)"),
                (A @ P @ A.T + K @ root_R @ K.T, "R holds variances: no square root in K R Kᵀ (lecture 03 §8)"),
                (A @ P @ A.T + K @ K.T, "the observation noise R is missing from K R Kᵀ (lecture 03 §8)"),
                (Ap @ P @ Ap.T + KRK, "sign: the update removes the observed part, I − K G, not I + K G "
                                      "(lecture 03 §8)"),
            ], hint="the Joseph form keeps P̂ right for any gain and symmetric (lecture 03 §8, lecture 08 §4): "
                    + F_("P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ"))
            expect_symmetric(got, "P_hat")
            if np.linalg.eigvalsh(symmetrise(got)).min() < 0.0:
                raise CheckFailed("P_hat is not positive semi-definite. Hint: the Joseph form is a sum of two "
                                  "positive semi-definite terms (lecture 03 §8)")


def _rotation_error(R, R_ref) -> float:
    """The angle (rad) of R_refᵀ R."""
    return float(np.linalg.norm(so3.log(so3.orthonormalise(R_ref.T @ R))))


@functools.lru_cache(maxsize=None)
def _inject_cases():
    """(true state, nominal state, δx): nominal = true with the error δx, at each state."""
    rng = inputs.rng("eskf.inject", 6)
    out = []
    for (true, _, _), scale in zip(_cases(), _attitude_scales()):
        dx = np.r_[rng.normal(size=3) * 0.2, rng.normal(size=3) * 0.05, rng.normal(size=3) * scale,
                   rng.normal(size=3) * 0.01, rng.normal(size=3) * 1e-3]
        nom = NominalState(true.position + dx[0:3], true.velocity + dx[3:6], true.rotation @ so3.exp(dx[6:9]),
                           true.accel_bias + dx[9:12], true.gyro_bias + dx[12:15])
        out.append((true, nom, dx))
    return tuple(out)


@check
def check_eskf_inject(inject):
    """``inject(nominal, dx)`` removes the estimated error: returns the corrected NominalState.

    The rotation is accepted within |δθ|² (angle) of Ř Exp(−δθ): the lecture's first-order
    Ř (I − [δθ]×), re-orthonormalised, passes; sign and side mistakes err by O(|δθ|).
    """
    F_ = hints.formula
    for true, nom, dx in _inject_cases():
        got = call(inject, nom, dx)
        for field in ("position", "velocity", "rotation", "accel_bias", "gyro_bias"):
            if not hasattr(got, field):
                raise CheckFailed(f"inject must return a NominalState; the result has no {field!r}")
        fields = ("position", "velocity", "rotation", "accel_bias", "gyro_bias")
        _expect_double(tuple(getattr(got, name) for name in fields), "the injected state")
        if all(_close(getattr(got, name), getattr(nom, name), 0.0) for name in fields):
            raise CheckFailed("the nominal state came back unchanged: the estimated error δx̂ was not used. "
                              "Hint: inject removes δx̂ from every part of the nominal state (position, "
                              "velocity, attitude and both biases), with the signs of error = nominal − true; "
                              "the attitude must stay a rotation matrix (lecture 08 §4, Inject)")
        R = expect_shape(got.rotation, (3, 3), "rotation after injection")
        if not so3.is_rotation(R, tol=1e-9):
            raise CheckFailed("the rotation after injection is not orthonormal (RᵀR ≠ I). Hint: the lecture's "
                              "first-order form is not a rotation unless it is re-orthonormalised "
                              "(so3.orthonormalise); the exponential is (lecture 08 §4, Inject)"
                              + F_(": R̂ = Ř Exp(−δθ)"))

        parts = {"δp": (0, 3), "δv": (3, 6), "δθ": (6, 9), "δb_a": (9, 12), "δb_ω": (12, 15)}
        for field, own, formula in (("position", "δp", "p̂ = p̌ − δp"), ("velocity", "δv", "v̂ = v̌ − δv"),
                                    ("accel_bias", "δb_a", "b̂_a = b̌_a − δb_a"),
                                    ("gyro_bias", "δb_ω", "b̂_ω = b̌_ω − δb_ω")):
            base, (i0, i1) = getattr(nom, field), parts[own]
            name = field.replace("_", " ")
            mistakes = [(base + dx[i0:i1], f"sign: error = nominal − true, so the estimated error is removed, "
                                           f"not added (lecture 08 §4, Inject)" + F_(f": {formula}")),
                        (base, f"the {name} is not corrected (lecture 08 §4, Inject)" + F_(f": {formula}"))]
            mistakes += [(base - dx[j0:j1], f"wrong part of dx: {own} is dx[{i0}:{i1}], not dx[{j0}:{j1}] "
                                            f"({other}; lecture 08 §4)")
                         for other, (j0, j1) in parts.items() if other != own]
            expect_close(getattr(got, field), getattr(true, field), f"{name} after injection", atol=1e-12,
                         mistakes=mistakes, hint=f"remove the {name}'s part of δx̂ from the nominal {name} "
                                                 "(lecture 08 §4, Inject): " + F_(formula))

        err = _rotation_error(R, true.rotation)
        if err <= _attitude_tolerance(dx[6:9]):
            continue
        th = dx[6:9]
        why = known_mistake([R], [None], [
            (nom.rotation @ so3.exp(th), "sign: the attitude error is removed, so the correction turns by −δθ "
                                         "(lecture 08 §4, Inject)" + F_(": Ř = R Exp(δθ), so R̂ = Ř Exp(−δθ)")),
            (so3.exp(-th) @ nom.rotation, "δθ is a body-frame error: multiply on the right (lecture 08 §4)"
                                          + F_(": Ř Exp(−δθ), not Exp(−δθ) Ř")),
            (so3.exp(th) @ nom.rotation, "sign and side: the body-frame error is removed on the right "
                                         "(lecture 08 §4)" + F_(": R̂ = Ř Exp(−δθ)")),
            (nom.rotation.T @ so3.exp(-th), "transpose: correct Ř itself, not Řᵀ (lecture 08 §4)"
                                            + F_(": R̂ = Ř Exp(−δθ), not Řᵀ Exp(−δθ)")),
            (nom.rotation, "the attitude is not corrected (lecture 08 §4, Inject)" + F_(": R̂ = Ř Exp(−δθ)")),
            *[(nom.rotation @ so3.exp(-dx[j0:j1]), f"wrong part of dx: δθ is dx[6:9], not dx[{j0}:{j1}] "
                                                   f"({other}; lecture 08 §4)")
              for other, (j0, j1) in parts.items() if other != "δθ"],
        ], close=lambda mine, wrong, _: _rotation_error(mine, wrong) <= _attitude_tolerance(th),
            evaluate=lambda wrong, _: wrong)
        if why:
            raise CheckFailed(f"rotation after injection is wrong. Hint: {why}")
        raise CheckFailed(f"rotation after injection differs from the corrected attitude by {err:.3g} rad "
                          f"(allowed, for the lecture's first-order form: |δθ|² = {_attitude_tolerance(th):.2g}). "
                          "Hint: the body-frame attitude error is removed on the right (lecture 08 §4, Inject): "
                          + F_("R̂ = Ř Exp(−δθ)"))


@functools.lru_cache(maxsize=None)
def _reset_case():
    """(P, the δx̂ of three resets): |δθ̂| of about 5e-3, 3e-2 and 8e-2 rad (drawn in bands
    around them, each redrawn until |δθ̂| ≤ 0.09, which keeps the sign mistake 10 tolerances off)."""
    rng = inputs.rng("eskf.reset", 7)
    P, _, _ = _update_case(9)
    scales = inputs.fixed_or_drawn((3e-3, 2e-2, 5e-2), lambda r: tuple(
        float(inputs.log_uniform(r, *band)) for band in ((2e-3, 5e-3), (1e-2, 3e-2), (3e-2, 5e-2))),
        "eskf.reset.scales")
    steps = []
    for scale in scales:
        dx = np.r_[rng.normal(size=6) * 0.1, rng.normal(size=3) * scale, rng.normal(size=6) * 1e-3]
        while inputs.drawing() and np.linalg.norm(dx[6:9]) > 0.09:
            dx = np.r_[rng.normal(size=6) * 0.1, rng.normal(size=3) * scale, rng.normal(size=6) * 1e-3]
        steps.append(dx)
    return P, tuple(steps)


def _call_reset(reset_covariance, P, dx, frame):
    """The learner's reset for ``frame``: "body" called as the run calls it (two arguments),
    "navigation" with the frame as the third; a signature without it is named."""
    if frame == "body":
        return call(reset_covariance, P, dx)
    try:
        return call(reset_covariance, P, dx, frame)
    except CheckFailed as exc:
        if "positional argument" in str(exc) and "TypeError" in str(exc):
            raise CheckFailed("reset_covariance takes the frame of the attitude error too: reset_covariance(P, dx, "
                              "frame=\"body\"), also called with frame=\"navigation\". Hint: keep the cell's first "
                              "line as it is") from None
        raise


#: Per frame of the attitude error: the exact reset block (a function of δθ̂), the sign of the
#: first-order ½[δθ̂]× and what the frame's error and injection are.
_RESET_FRAMES = {"body": (so3.left_jacobian, 1.0, "Ř = R Exp(δθ), R̂ = Ř Exp(−δθ̂)"),
                 "navigation": (so3.right_jacobian, -1.0, "Ř = Exp(δθ) R, R̂ = Exp(−δθ̂) Ř")}


@check
def check_eskf_reset(reset_covariance):
    """``reset_covariance(P, dx, frame="body")`` returns G P Gᵀ with the reset Jacobian of the
    attitude error in ``frame``: "body" (this filter, Ř = R Exp(δθ)) or "navigation" (the
    global error of lecture 08 §1, Ř = Exp(δθ) R, injected as R̂ = Exp(−δθ̂) Ř).

    Accepted per frame: the exact block (J_l(δθ̂) in the body frame, J_r(δθ̂) = J_l(−δθ̂) in the
    navigation frame), the first-order I ± ½[δθ̂]×, or anything within |δθ̂|² max|P[6:9]| of the
    exact result (|δθ̂| ≤ 0.09 here, so a sign mistake, the other frame's block, off by about
    |δθ̂| max|P[6:9]|, stays outside: by 5.5 to 13 tolerances, measured over the fixed cases and
    six run seeds). The body frame is judged first, on every δx̂, then the navigation frame.
    """
    P, steps = _reset_case()

    def sandwich(block, rows=slice(6, 9)):
        G = np.eye(15)
        G[rows, rows] = block
        return symmetrise(G @ P @ G.T), G

    F_ = hints.formula
    results = {frame: [] for frame in _RESET_FRAMES}
    for frame in _RESET_FRAMES:
        for dx in steps:
            value = _call_reset(reset_covariance, P, dx, frame)
            _expect_double(value, "P after reset")
            results[frame].append(expect_shape(value, (15, 15), "P after reset"))

    def tolerance(th):
        # only the attitude rows and columns change: scale the tolerance by them
        return float(th @ th) * np.abs(P[6:9]).max()

    def near(got, wanted, th):
        return _close(got, wanted, max(tolerance(th), 1e-15), 1e-9)

    def right(got, dx, frame):
        exact_block, sign, _ = _RESET_FRAMES[frame]
        th = dx[6:9]
        exact, _ = sandwich(exact_block(th))
        first, _ = sandwich(np.eye(3) + sign * 0.5 * so3.hat(th))
        return _close(got, exact, 1e-15, 1e-9) or _close(got, first, 1e-15, 1e-9) or _close(got, exact, tolerance(th))

    def first_order(sign, dx):
        return sandwich(np.eye(3) + sign * 0.5 * so3.hat(dx[6:9]))[0]

    # the two frames' blocks exchanged: named before either frame is judged alone
    if not all(right(g, dx, f) for f in _RESET_FRAMES for g, dx in zip(results[f], steps)) and all(
            near(g, first_order(-_RESET_FRAMES[f][1], dx), dx[6:9]) for f in _RESET_FRAMES
            for g, dx in zip(results[f], steps)):
        raise CheckFailed("P after reset is wrong in both frames. Hint: the two frames' attitude blocks are "
                          "exchanged (Gᵀ P G for G P Gᵀ exchanges them too): derive each from its own error and injection, body frame Ř = R Exp(δθ) with "
                          "R̂ = Ř Exp(−δθ̂), navigation frame Ř = Exp(δθ) R with R̂ = Exp(−δθ̂) Ř (lecture 08 §4, "
                          "Reset, does the body frame)"
                          + F_(": body I + ½[δθ̂]× (J_l(δθ̂)), navigation I − ½[δθ̂]× (J_r(δθ̂))"))
    body_block = F_(": δθ⁺ = Log(Exp(δθ̂ + e) Exp(−δθ̂)) ≈ (I + ½[δθ̂]×) e, so the attitude block is "
                    "J_l(δθ̂) ≈ I + ½[δθ̂]×")
    nav_block = F_(": Exp(δθ⁺) = R̂ Rᵀ = Exp(−δθ̂) Exp(δθ̂ + e) ≈ Exp((I − ½[δθ̂]×) e), so the attitude block is "
                   "J_r(δθ̂) ≈ I − ½[δθ̂]×")
    for frame in _RESET_FRAMES:
        _, sign, definition = _RESET_FRAMES[frame]
        block = body_block if frame == "body" else nav_block
        label = f" (frame=\"{frame}\": {definition})"
        for got, dx in zip(results[frame], steps):
            th = dx[6:9]
            if right(got, dx, frame):
                expect_symmetric(got, "P after reset")
                continue
            G1 = sandwich(np.eye(3) + sign * 0.5 * so3.hat(th))[1]
            if frame == "body":
                flipped = ("sign of the reset Jacobian: I − ½[δθ̂]× is the reset of an error on the other side "
                           "(the navigation frame's, Ř = Exp(δθ) R) or of the opposite convention (true = nominal "
                           "⊕ error); this filter's body-frame error = nominal − true gives the other sign (lecture "
                           "08 §4, Reset; the same wrong result comes from Gᵀ P G for G P Gᵀ, or from the right "
                           "Jacobian J_r)" + block)
            else:
                flipped = ("the navigation frame's reset is not the body frame's: with the error on the left, "
                           "Ř = Exp(δθ) R, and the injection R̂ = Exp(−δθ̂) Ř, the correction stands on the other side "
                           "of the error it removes. Follow lecture 08 §4's Reset derivation with the error on the "
                           "left (the self-check below the cell measures the block; the same wrong result comes from "
                           "the left Jacobian J_l, or from Gᵀ P G)" + block)
            why = known_mistake([got], [None], [
                (first_order(-sign, dx), flipped),
                (P, "the covariance is (to first order) unchanged; this exercise asks for the reset P ← G P Gᵀ "
                    "(with Gᵀ on the right: the symmetric part of G P G is P + O(|δθ̂|²); lecture 08 §4, Reset)"),
                (symmetrise(G1 @ P), "P ← G P Gᵀ: the Gᵀ on the right is missing (lecture 08 §4, Reset)"),
                (G1 @ P @ G1, "transpose: P ← G P Gᵀ, not G P G (lecture 08 §4, Reset)"),
                (sandwich(np.eye(3) + sign * so3.hat(th))[0], "the factor ½ is missing from G's attitude block "
                                                              "(lecture 08 §4, Reset)" + block),
                (sandwich(np.eye(3) - sign * so3.hat(th))[0], "the factor ½ is missing from G's attitude block, "
                                                              "and its sign is that of the other frame "
                                                              "(lecture 08 §4, Reset)" + block),
                (sandwich(np.eye(3) + sign * 0.5 * so3.hat(th), slice(3, 6))[0],
                 "wrong block: the reset changes the attitude block G[6:9, 6:9] (rows and columns of δθ; "
                 "lecture 08 §4, Reset)"),
                (sandwich(np.eye(3) + sign * 0.5 * so3.hat(dx[3:6]))[0],
                 "wrong part of dx: δθ̂ is dx[6:9] (lecture 08 §4)"),
            ], close=lambda mine, wrong, _: near(mine, wrong, th), evaluate=lambda wrong, _: wrong)
            if why:
                raise CheckFailed(f"P after reset is wrong{label}. Hint: {why}")
            exact, _ = sandwich(_RESET_FRAMES[frame][0](th))
            err = np.abs(np.asarray(got) - exact).max()
            raise CheckFailed(f"P after reset differs from G P Gᵀ{label} (max abs error {err:.3g}). Hint: the "
                              "reset moves the covariance to the corrected state through G, the Jacobian of the "
                              "error after the injection with respect to the error before it: the identity except "
                              "its attitude block (lecture 08 §4, Reset)" + block)


# ---------------------------------------------------------------------------------------
# The whole run
# ---------------------------------------------------------------------------------------

#: Graded learner functions that run_eskf calls: learner name -> check name. The run check
#: asks about them before its own diagnosis (so a wrong piece is named first, also when the
#: run crashes).
_RUN_USES = {"error_dynamics": "eskf_error_dynamics", "noise_jacobian": "eskf_noise_jacobian",
             "discretise": "eskf_discretisation", "propagate_covariance": "eskf_propagate",
             "pose_residual": "eskf_pose_residual", "kalman_gain": "eskf_gain",
             "update_covariance": "eskf_covariance_update", "inject": "eskf_inject",
             "reset_covariance": "eskf_reset"}

#: Mistakes made in the run itself: flag -> (hint). Tried in this order by :func:`_diagnose_run`.
_RUN_MISTAKES = (
    ("no_update", "the posterior equals the prior: the lidar poses were never used. At each lidar time, "
                  "compute the residual and the gain, the estimated error δx̂ = K y and P̂, inject δx̂ into "
                  "the nominal state and reset P (lecture 08 §4)"),
    ("P0_std", "the prior covariance holds variances, not standard deviations (lecture 08 §4)"
               + hints.formula(": P₀ = diag(σ₀²) (cfg.prior_std**2), not diag(σ₀)")),
    ("no_reset", "the covariance reset after the injection is missing (lecture 08 §4, Reset)"
                 + hints.formula(": P ← G P Gᵀ (reset_covariance(P, dx))")),
    ("no_inject", "the estimated error is never injected into the nominal state (lecture 08 §4, Inject)"
                  + hints.formula(": x ← inject(x, δx̂)")),
    ("no_update_P", "the covariance is not updated after the observation (lecture 08 §4, Update)"
                    + hints.formula(": P̂ = update_covariance(P̌, K, G, R)")),
    ("prior_out", "the prior (before the update) is stored instead of the posterior: record t, x̂ and P̂ "
                  "after the update, injection and reset (lecture 08 §4)"),
    ("dx_sign", "sign of the correction: the estimated error is K times the residual of your pose_residual, "
                "and inject removes it (lecture 08 §4)" + hints.formula(": δx̂ = K y with y = prediction − "
                                                                       "measurement")),
    ("no_interp", "at a lidar time between two IMU samples, interpolate the readings to that time before "
                  "propagating to it (exercise §8)"
                  + hints.formula(": f_j = (1 − s) f_{k−1} + s f_k")),
    ("no_predict_to_obs", "propagate the state to the lidar time before the update (the lidar time lies "
                          "between two IMU samples; exercise §8)"),
    ("full_step", "after an update at a lidar time t_j, the rest of the IMU interval is shorter than a whole "
                  "one (exercise §8)" + hints.formula(": imu.t[k] − t_j, not imu.t[k] − imu.t[k−1] (keep t, f, ω "
                                                      "of the last node you reached)")),
    ("stale_start", "after an update at a lidar time, propagate the rest of the IMU interval from the "
                    "readings interpolated at the lidar time (the last node), not from those of imu.t[k−1] "
                    "(exercise §8)"),
    ("loop_start", "off by one: the loop over IMU samples skips the first step (exercise §8)"
                   + hints.formula(": it starts at k0 + 1, the first step going from imu.t[k0] to imu.t[k0 + 1]")),
    ("w_start", "linearise F_t at the step's mean angular rate, the rate the nominal step uses, not at ω₀ "
                "(lecture 08 §4, Predict)" + hints.formula(": ½(ω₀ + ω₁)")),
    ("constant_bias", "the configuration's bias model is a random walk: use noise_jacobian(R) and "
                      "process_noise(density, T) with their bias-noise columns (lecture 08 §3)"),
    ("gravity_sign", "gravity: pass ex.gravity (the navigation-frame vector, z down = −9.81) to the nominal "
                     "step (lecture 07 §4)"),
)


def _learner_pieces(namespace) -> dict:
    """The building blocks the run uses: the learner's (from their namespace) or the reference's."""
    pieces = {"error_dynamics": eskf.error_dynamics, "noise_jacobian": eskf.noise_jacobian,
              "discretise": eskf.discretise, "process_noise": eskf.process_noise,
              "propagate_covariance": eskf.propagate_covariance, "pose_residual": eskf.pose_residual,
              "kalman_gain": eskf.kalman_gain, "update_covariance": eskf.update_covariance,
              "inject": eskf.inject, "reset_covariance": eskf.reset_covariance,
              "nominal_step": eskf.nominal_step}
    for name in pieces:
        learner_fn = namespace.get(name)
        if callable(learner_fn):
            pieces[name] = learner_fn
    return pieces


def _drive(pieces: dict, ex, t_end: float, cfg, mistake: str | None = None, R_noise=None,
           rows: int | None = None):
    """The run of the exercise, from the given building blocks, optionally with one mistake.

    Mirrors the exercise's ``run_eskf`` (and :func:`kalman_course.filters.eskf.run`, to
    1e-9 m): the nominal state propagated by the midpoint rule, the covariance by F and B at
    the start of each step (mean rate), an observation between two IMU samples reached by
    interpolating the readings, then residual, gain, Joseph update, injection and reset.
    ``R_noise`` replaces the observation noise the run builds from ``cfg`` (a run with R in
    other units); ``rows`` stops the run once it has that many output rows (a run that
    differs from the learner's in its first rows cannot reproduce the rest: the cheap test
    before a whole run). Returns (t, positions, rotations, P) at the lidar times.
    """
    pc = pieces
    imu, lidar = ex.imu, ex.lidar
    k0, s0 = ex.initial_state()
    x = NominalState.from_nav(s0)
    P = np.diag(cfg.prior_std if mistake == "P0_std" else cfg.prior_std ** 2)
    R_noise = np.diag(cfg.lidar_std ** 2) if R_noise is None else R_noise
    g = -ex.gravity if mistake == "gravity_sign" else ex.gravity
    model = "constant" if mistake == "constant_bias" else "random_walk"

    def predict(x, P, f0, w0, f1, w1, dt):
        w_lin = w0 if mistake == "w_start" else 0.5 * (w0 + w1)
        F_t = pc["error_dynamics"](x.rotation, f0, w_lin, x.accel_bias, x.gyro_bias)
        F, B = pc["discretise"](F_t, pc["noise_jacobian"](x.rotation, model), dt)
        P = pc["propagate_covariance"](P, F, B, pc["process_noise"](cfg.process_density, dt, model))
        return pc["nominal_step"](x, f0, w0, f1, w1, dt, g), P

    t, f, w = imu.t[k0], imu.specific_force[k0], imu.angular_rate[k0]
    j = int(np.searchsorted(lidar.t, t, side="right"))
    out = []
    for k in range(k0 + (2 if mistake == "loop_start" else 1), len(imu.t)):
        if imu.t[k] > t_end or (rows is not None and len(out) >= rows):
            break
        while j < len(lidar.t) and lidar.t[j] <= imu.t[k]:
            s = (lidar.t[j] - imu.t[k - 1]) / (imu.t[k] - imu.t[k - 1])
            if mistake == "no_interp":
                f_j, w_j = imu.specific_force[k], imu.angular_rate[k]
            else:
                f_j = (1 - s) * imu.specific_force[k - 1] + s * imu.specific_force[k]
                w_j = (1 - s) * imu.angular_rate[k - 1] + s * imu.angular_rate[k]
            if lidar.t[j] > t and mistake != "no_predict_to_obs":
                x, P = predict(x, P, f, w, f_j, w_j, lidar.t[j] - t)
                t, f, w = lidar.t[j], f_j, w_j
            if mistake in ("prior_out", "no_update"):
                out.append((t, x.position, x.rotation, P))
                if mistake == "no_update":
                    j += 1
                    continue
            y = pc["pose_residual"](x.position, x.rotation, lidar.position[j], lidar.rotation[j])
            K = pc["kalman_gain"](P, eskf.POSE_G, R_noise)
            dx = -K @ y if mistake == "dx_sign" else K @ y
            if mistake != "no_update_P":
                P = pc["update_covariance"](P, K, eskf.POSE_G, R_noise)
            if mistake != "no_inject":
                x = pc["inject"](x, dx)
            if mistake != "no_reset":
                P = pc["reset_covariance"](P, dx)
            if mistake != "prior_out":
                out.append((t, x.position, x.rotation, P))
            j += 1
        if imu.t[k] > t:
            if mistake == "stale_start":
                f, w = imu.specific_force[k - 1], imu.angular_rate[k - 1]
            dt = imu.t[k] - (imu.t[k - 1] if mistake == "full_step" else t)
            x, P = predict(x, P, f, w, imu.specific_force[k], imu.angular_rate[k], dt)
            t, f, w = imu.t[k], imu.specific_force[k], imu.angular_rate[k]
    ts, ps, Rs, Ps = zip(*out)
    return np.array(ts), np.array(ps), np.array(Rs), np.array(Ps)


def _same_run(result, other) -> bool:
    """Whether the learner's (t, positions, rotations, P) equals ``other`` within the run's tolerances."""
    try:
        arrays = [np.asarray(r, dtype=float) for r in result]
    except (TypeError, ValueError):
        return False
    t, p, R, P = arrays
    t2, p2, R2, P2 = other
    return (_close(t, t2, 1e-9) and _close(p, p2, 1e-6) and _close(R, R2, 1e-6)
            and _close(P, P2, 5e-9, 1e-3))


def _quiet(fn, *args):
    """Run a check or a reference computation with prints silenced; CheckFailed passes through."""
    with contextlib.redirect_stdout(io.StringIO()):
        return fn(*args)


#: Rows of the learner's run compared before a whole run is rebuilt with a mistake: the first
#: two updates (the second shows a missing reset or injection).
_FIRST_ROWS = 2

_DEG = 180.0 / np.pi

#: What the attitude part of R may hold instead of σ_θ² (rad²), from σ_θ in rad: (name, how
#: the learner got there, the diagonal entry). The exercise's own task (its §8): R in the
#: residual's units, from a configuration that states the attitude σ in degrees.
_R_ATTITUDE_UNITS = (
    ("deg", "the attitude σ in degrees (0.3) used as if it were radians", lambda s: (s * _DEG) ** 2),
    ("twice", "the attitude σ converted from degrees a second time (cfg.lidar_std is in radians "
              "already, so np.deg2rad makes σ 57 times too small)", lambda s: (s / _DEG) ** 2),
    ("var_deg", "a variance in deg² converted with one factor π/180 (a variance converts with the "
                "square of the factor)", lambda s: s * s * _DEG),
    ("std", "σ where the variance σ² belongs", lambda s: s),
    ("std_deg", "σ where the variance σ² belongs, in degrees as well", lambda s: s * _DEG),
    ("std_twice", "σ where the variance σ² belongs, converted from degrees a second time", lambda s: s / _DEG),
)

#: The same for the position part (m²), from σ_p in m.
_R_POSITION_UNITS = (("std", "σ where the variance σ² belongs", lambda s: s),)


def _units_of_R(cfg):
    """The observation noise R built with wrong units: (R, what is wrong with it in words), each
    combination of a position part and an attitude part, the right one left out."""
    s_p, s_th = cfg.lidar_std[:3], cfg.lidar_std[3:]
    position = (("", "", lambda s: s * s),) + _R_POSITION_UNITS
    attitude = (("", "", lambda s: s * s),) + _R_ATTITUDE_UNITS
    out = []
    for p_name, p_why, p_var in position:
        for a_name, a_why, a_var in attitude:
            if p_name or a_name:
                why = "; and ".join(w for w in (p_why and f"in its position part, {p_why}",
                                                a_why and f"in its attitude part, {a_why}") if w)
                out.append((np.diag(np.r_[p_var(s_p), a_var(s_th)]), why))
    return out


def _r_units_hint(why: str) -> str:
    """The hint for an R built with wrong units (the run's own task, exercise 08 §8)."""
    return ("units of the observation noise R (exercise §8; lecture 08 §4, Update): R is the covariance "
            "of the pose residual's noise, so it holds VARIANCES in the residual's units, m² and rad²; "
            f"yours has, {why}. The table of cfg.describe shows the settings as written, with their units "
            "(the attitude σ in DEGREES); cfg.lidar_std holds the same six σ in SI units (m and rad): "
            + hints.formula("R = diag(σ²) = np.diag(cfg.lidar_std**2)"))


def _first_rows(result, count: int):
    """The first ``count`` rows of a run (t, positions, rotations, P)."""
    return tuple(np.asarray(x, dtype=float)[:count] for x in result)


def _reproduces(result, pieces, ex, t_end, cfg, mistake=None, R_noise=None) -> bool:
    """Whether the run from ``pieces`` with one mistake (or another R) gives the learner's
    ``result``: its first rows first (cheap), then the whole run."""
    try:
        head = call(_drive, pieces, ex, t_end, cfg, mistake, R_noise, _FIRST_ROWS, label="your building blocks")
        if not _same_run(_first_rows(result, _FIRST_ROWS), _first_rows(head, _FIRST_ROWS)):
            return False
        whole = call(_drive, pieces, ex, t_end, cfg, mistake, R_noise, label="your building blocks")
    except CheckFailed:
        return False
    return _same_run(result, whole)


def _diagnose_run(run_eskf, result, ex, t_end, cfg) -> str | None:
    """Why the learner's run differs, or None if it equals a run built from the learner's pieces.

    1. A graded piece the run calls that fails its own check: fix that first.
    2. ``process_noise`` (ungraded) against the reference.
    3. The run rebuilt from the learner's pieces: equal means the run is right (pieces such as
       the lecture's first-order forms, accepted by their checks, change the numbers slightly).
    4. The same with R in wrong units (the section's own task: :func:`_units_of_R`), then with
       one known run mistake at a time (``_RUN_MISTAKES``).
    """
    namespace = learner_namespace(run_eskf) or {}
    why = _failing_piece(namespace)
    if why:
        return why
    pieces = _learner_pieces(namespace)
    try:
        own = call(_drive, pieces, ex, t_end, cfg, label="your building blocks")
    except CheckFailed:
        own = None
    if own is not None and _same_run(result, own):
        return None
    for R_noise, what in _units_of_R(cfg):
        if _reproduces(result, pieces, ex, t_end, cfg, R_noise=R_noise):
            return _r_units_hint(what)
    for mistake, why in _RUN_MISTAKES:
        if _reproduces(result, pieces, ex, t_end, cfg, mistake):
            return why
    return ""


def _failing_piece(namespace) -> str:
    """The message for the first piece of the run (in the learner's namespace) that fails, or ""."""
    upstream = upstream_failure(_RUN_USES, namespace)
    if upstream:
        return upstream
    pn = namespace.get("process_noise")
    if callable(pn):
        for T in _steps()[0]:
            got = call(pn, DENSITY, T)
            ref = eskf.process_noise(DENSITY, T)
            if not _close(np.asarray(got, dtype=float) if np.shape(got) == ref.shape else np.zeros(0), ref, 1e-15, 1e-9):
                return ("your process_noise is wrong. Hint: fix process_noise first: Q_k holds per-sample "
                        "variances, from the densities as each kind of noise needs them (lecture 08 §3)"
                        + hints.formula(": Q_k = diag(σ_a²/T ×3, σ_ω²/T ×3, σ_ba² ×3, σ_bω² ×3), density² / T "
                                        "for the white noises, density² for the random walks"))
    return ""


def _names_a_piece(why: str | None) -> bool:
    """Whether a diagnosis blames one of the learner's pieces (a message of its own, with its hint)."""
    return bool(why) and why.startswith(("your ", "this function calls your "))


def _diagnose_crash(run_eskf, ex, t_end, cfg, message: str) -> str:
    """Why the learner's run raised ``message``: a failing piece, or a run mistake that raises the same."""
    why = _failing_piece(learner_namespace(run_eskf) or {})
    if why:
        return why
    pieces = _learner_pieces(learner_namespace(run_eskf) or {})
    error = message.split(" raised ", 1)[-1]
    for mistake, hint in _RUN_MISTAKES:
        try:
            call(_drive, pieces, ex, t_end, cfg, mistake, label="run_eskf")
        except CheckFailed as exc:
            if str(exc).split(" raised ", 1)[-1] == error:
                return f"a run with this mistake fails the same way: {hint}"
    return ""


def _window(ex, first: int, seconds: float, lidar_seed: int):
    """``ex`` seen from its truth pose ``first`` on (so that ``initial_state`` starts there), with
    its lidar poses simulated anew (the excerpt's white-noise σ, another seed); and t_end."""
    tr = ex.truth
    truth = TruthData(tr.t[first:], tr.position[first:], tr.velocity[first:], tr.quaternion[first:],
                      tr.rotation[first:])
    lidar = simulate_lidar_poses(tr, lidar_seed, ex.lidar.sigma_position, ex.lidar.sigma_attitude_deg)
    window = dataclasses.replace(ex, truth=truth, lidar=lidar)
    k0, _ = window.initial_state()
    return window, float(window.imu.t[k0] + seconds)


@functools.lru_cache(maxsize=None)
def _run_case():
    """(excerpt, t_end, what: the run in words) of the whole-run check.

    Fixed: the first RUN_SECONDS of the excerpt. Under a run seed: a window of the same real
    IMU readings and truth, 3 s … RUN_SECONDS long (never longer: the check runs the filter
    several times), from a drawn truth pose, with the lidar poses simulated from another seed.
    """
    ex = load_kitti(RUN_EXCERPT)
    if not inputs.drawing():
        k0, _ = ex.initial_state()
        return ex, float(ex.imu.t[k0] + RUN_SECONDS), f"the first {RUN_SECONDS:.0f} s of '{RUN_EXCERPT}'"
    rng = inputs.rng("eskf.run")
    cfg = load_config("kitti_lidar")
    while True:
        seconds = float(rng.uniform(0.8 * RUN_SECONDS, RUN_SECONDS))
        last = int(np.searchsorted(ex.truth.t, ex.truth.t[-1] - seconds - 1.0))   # room to run, and a margin
        seed = int(rng.integers(10_000, 2**31))
        window, t_end = _window(ex, int(rng.integers(1, last)), seconds, seed)
        if _bias_noise_shows(window, t_end, cfg):
            break
    start = t_end - seconds
    return window, t_end, (f"{seconds:.2f} s of '{RUN_EXCERPT}' from τ = {start:.2f} s "
                           f"(lidar noise seed {seed})")


def _bias_noise_shows(ex, t_end, cfg, margin: float = 1.5) -> bool:
    """Whether the run on ``ex`` tells the bias random walks' noise σ² T from σ² T² (a bias column
    of B scaled by T, or the bias variances of Q multiplied by T) by ``margin`` times the run's
    tolerances. Of the run's mistakes this one changes it least (about as much as no bias noise
    at all): a window where it shows keeps every listed mistake apart from the reference."""
    def bias_noise_times_T(density, T, model="random_walk"):
        Q = eskf.process_noise(density, T, model).copy()
        Q[6:, 6:] *= T
        return Q

    pieces = _learner_pieces({})
    ref = _drive(pieces, ex, t_end, cfg)
    wrong = _drive(dict(pieces, process_noise=bias_noise_times_T), ex, t_end, cfg)
    return _run_gap(wrong, ref) >= margin


def _run_gap(result, other) -> float:
    """How far a run is from ``other`` in units of :func:`_same_run`'s tolerances (> 1: told apart)."""
    gaps = []
    for a, b, atol, rtol in zip(result, other, (1e-9, 1e-6, 1e-6, 5e-9), (0.0, 0.0, 0.0, 1e-3)):
        a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
        if a.shape != b.shape:
            return np.inf
        gaps.append(float(np.max(np.abs(a - b) / (atol + rtol * np.abs(b)))))
    return max(gaps)


@check
def check_eskf_run(run_eskf):
    """``run_eskf(ex, t_end, cfg)`` returns (t, positions, rotations, P) at the lidar times."""
    ex, t_end, window = _run_case()
    cfg = load_config("kitti_lidar")
    k0, s0 = ex.initial_state()
    try:
        result = call(run_eskf, ex, t_end, cfg)
    except CheckFailed as exc:          # the run crashed: a wrong piece, or a mistake that diverges
        why = _diagnose_crash(run_eskf, ex, t_end, cfg, str(exc))
        if _names_a_piece(why):        # the piece's own failure, told as the harness tells one
            raise CheckFailed(why) from None
        raise CheckFailed(f"{exc}" + (f". Hint: {why}" if why else "")) from None
    if not isinstance(result, (tuple, list)) or len(result) != 4:
        raise CheckFailed("run_eskf must return a tuple (t, positions, rotations, P)")
    ref = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=ex.lidar, start=k0, t_end=t_end)
    if np.ndim(result[0]) == 1 and len(result[0]) == 2 * len(ref.t):
        raise CheckFailed(f"t has {len(result[0])} rows, twice the {len(ref.t)} lidar poses. Hint: record one "
                          "row per update, after the update, injection and reset (the posterior), not the "
                          "prior as well")
    t = expect_shape(result[0], ref.t.shape, "t")
    p = expect_shape(result[1], ref.position.shape, "positions")
    Rs = expect_shape(result[2], ref.rotation.shape, "rotations")
    P = expect_shape(result[3], ref.P.shape, "P")
    if _same_run((t, p, Rs, P), (ref.t, ref.position, ref.rotation, ref.P)):
        return
    why = _diagnose_run(run_eskf, (t, p, Rs, P), ex, t_end, cfg)
    if why is None:            # equal to the run built from the learner's own (checked) pieces
        return
    if _names_a_piece(why):
        raise CheckFailed(why)
    truth = ex.truth.position[np.searchsorted(ex.truth.t, ref.t - 1e-6)]
    err, err_ref = position_rmse(p, truth), position_rmse(ref.position, truth)
    what = f"the run on {window}"
    if why:
        raise CheckFailed(f"{what} is wrong (position RMSE {err:.4f} m, reference {err_ref:.4f} m). Hint: {why}")
    expect_close(t, ref.t, "the update times", atol=1e-9,
                 hint="one output row per lidar pose in (t₀, t_end], at the lidar time")
    expect_close(p, ref.position, f"positions on {what}", rtol=0.0, atol=1e-6,
                 hint=f"your position RMSE against ground truth is {err:.4f} m, the reference's "
                      f"{err_ref:.4f} m. Every piece passes its check, and the run is none of the known "
                      "mistakes of the loop (R's units among them): compare the loop with the lecture's "
                      "(lecture 08 §4; exercise §8)"
                      + hints.formula(": propagate to each lidar time, residual, gain, update, inject, reset"))
    expect_close(Rs, ref.rotation, "rotations", atol=1e-6,
                 hint="each row holds the posterior attitude after the update, injection and reset "
                      "(lecture 08 §4)")
    expect_close(P, ref.P, "P at the update times", rtol=1e-3, atol=5e-9,
                 hint="store the posterior P̂ (after update and reset) at each lidar time (lecture 08 §4)")


# ---------------------------------------------------------------------------------------
# Bonus: the nominal-state EKF
# ---------------------------------------------------------------------------------------

def _fixed_quaternion_angles():
    """The self-check's attitude angles, and the pair across π: its axis and half-gaps (rad)."""
    return (0.0, 1.5, 2.9, np.pi - 0.02), np.array([0.48, -0.6, 0.64]), (0.02, 0.02)


def _drawn_quaternion_angles(rng):
    """The same family under a run seed: 0, two in the middle, one just short of π, and a pair
    across π whose two sides lie 10⁻⁴ … 3·10⁻² rad from it."""
    angles = (0.0, float(rng.uniform(0.5, 2.0)), float(rng.uniform(2.0, 3.0)),
              float(np.pi - inputs.log_uniform(rng, 1e-3, 3e-2)))
    u = rng.normal(size=3)
    return angles, u / np.linalg.norm(u), tuple(inputs.log_uniform(rng, 1e-4, 3e-2, 2))


@functools.lru_cache(maxsize=None)
def _quaternion_pairs():
    """(q_check, q_meas) pairs with q_measᵀ q_check ≥ 0 (before the check flips signs)."""
    angles, u, (below, above) = inputs.fixed_or_drawn(_fixed_quaternion_angles(), _drawn_quaternion_angles,
                                                      "eskf.quaternion.angles")
    rng = inputs.rng("eskf.quaternion", 11)
    pairs = []
    for angle in angles:
        axis = rng.normal(size=3)
        q = so3.matrix_to_quat(so3.exp(axis / np.linalg.norm(axis) * angle))
        pairs.append((q, so3.matrix_to_quat(so3.quat_to_matrix(q) @ so3.exp(rng.normal(size=3) * 0.05))))
    # across π: scalar parts of opposite sign although q_m is close to q (0.04 rad when fixed)
    pairs.append((np.r_[np.cos((np.pi - below) / 2), np.sin((np.pi - below) / 2) * u],
                  np.r_[np.cos((np.pi + above) / 2), np.sin((np.pi + above) / 2) * u]))
    out = []
    for q, q_m in pairs:
        out.append((q, -q_m if q_m @ q < 0.0 else q_m))
    return tuple(out)


@check
def check_nominal_ekf_observation(align_quaternion):
    """``align_quaternion(q_check, q_meas)`` returns ±q_meas, whichever is closer to q_check.

    Cases: attitudes at and near 0 (vector part ≈ 0) and near π (scalar part ≈ 0), both signs of
    q_check and of q_meas, so that a rule on one component (w ≥ 0) or on the vector part
    alone fails.
    """
    for q, q_m in _quaternion_pairs():
        for s_check in (1.0, -1.0):
            for s_meas in (1.0, -1.0):
                got = call(align_quaternion, s_check * q, s_meas * q_m)
                _expect_double(got, "the aligned measured quaternion")
                want = s_check * q_m
                expect_close(got, want, "the aligned measured quaternion", atol=1e-12, mistakes=[
                    (-want, "sign: q and −q are the same rotation, but the EKF subtracts quaternions, so of "
                            "±q_meas take the one on q̌'s side, judged by the dot product over all four "
                            "components, with q̌ as given (lecture 08 §9)" + hints.formula(": q_measᵀ q̌ ≥ 0")),
                ], hint="of ±q_meas, return the one closer to q_check, with no normalisation to w ≥ 0 (lecture "
                        "08 §9)" + hints.formula(": q_meas if q_meas · q_check ≥ 0, else −q_meas"))


_A_FORMULAS = {("p", "v"): "I", ("v", "q"): "∂(R(q) a)/∂q = rotate_jacobian(q, f − b_a)",
               ("v", "b_a"): "−R(q)", ("q", "q"): "½ Ω(ω − b_ω)", ("q", "b_ω"): "−½ Ξ(q)"}


@check
def check_nominal_ekf_jacobian(nominal_jacobian):
    """``nominal_jacobian(q, f, w, b_a, b_w)`` returns A = ∂ẋ/∂x (16, 16)."""
    from kalman_course.filters import nominal_ekf as ne

    for x, f, w in _cases():
        q = so3.matrix_to_quat(x.rotation)
        b_a, b_w = x.accel_bias, x.gyro_bias
        value = call(nominal_jacobian, q, f, w, b_a, b_w)
        _expect_double(value, "A")
        got = expect_shape(value, (16, 16), "A")
        ref = ne.continuous_jacobian(q, f, w, b_a, b_w)
        if _close(got, ref, 1e-10):
            continue
        if not np.any(got[6:10]):
            raise CheckFailed("the rows of q̇ in A (rows 6:10) are all zero. Hint: the rows of q are missing: q̇ is "
                              "linear in q and in ω − b_ω, and its derivatives with respect to q and to b_ω fill "
                              "the blocks (q, q) and (q, b_ω) (lecture 08 §9)"
                              + hints.formula(": q̇ = ½ q ⊗ (0, ω − b_ω) = ½ Ω(ω − b_ω) q = ½ Ξ(q)(ω − b_ω)"))
        R = so3.quat_to_matrix(q)
        F = hints.formula
        alternatives = {
            ("v", "q"): [(ne.rotate_jacobian(q, f), "use the bias-corrected force (lecture 08 §9)"
                                                    + F(": ∂(R(q)(f − b_a))/∂q")),
                         (ne.rotate_jacobian(q, f + b_a), "the bias is subtracted, not added (lecture 08 §9)"
                                                          + F(": a = f − b_a"))],
            ("v", "b_a"): [(-np.eye(3), "b_a is in the body frame: it reaches v̇ rotated (lecture 08 §9)"
                                        + F(": v̇ = R(q)(f − b_a) + g, so −R(q)")),
                           (-R.T, "transpose: R(q) maps body to navigation (lecture 08 §9)"
                                  + F(": −R(q), not −R(q)ᵀ"))],
            ("q", "q"): [(ne.quat_omega(w - b_w), "the factor ½ of the quaternion kinematics is missing "
                                                  "(lecture 08 §9)" + F(": q̇ = ½ q ⊗ (0, ω − b_ω), so ½ Ω(ω − b_ω)")),
                         (0.5 * ne.quat_omega(w), "use the bias-corrected rate (lecture 08 §9)"
                                                  + F(": ½ Ω(ω − b_ω)")),
                         (0.5 * ne.quat_omega(w + b_w), "the bias is subtracted, not added (lecture 08 §9)"
                                                        + F(": ½ Ω(ω − b_ω)"))],
            ("q", "b_ω"): [(0.5 * ne.quat_xi(q), "the gyro bias enters q̇ with a minus sign (lecture 08 §9)"
                                                 + F(": q̇ = ½ q ⊗ (0, ω − b_ω), ∂q̇/∂b_ω = −½ Ξ(q)")),
                           (-ne.quat_xi(q), "the factor ½ of the quaternion kinematics is missing (lecture 08 §9)"
                                            + F(": ∂q̇/∂b_ω = −½ Ξ(q)"))],
        }
        _expect_blocks(got, ref, _NOMINAL, _NOMINAL, "A", _A_FORMULAS, alternatives, section="lecture 08 §9",
                       fallback=hints.formula("ṗ = v, v̇ = R(q)(f − b_a) + g, q̇ = ½ q ⊗ (0, ω − b_ω)"))


# ---------------------------------------------------------------------------------------
# Challenge: the transition measured by finite differences (lecture 08 §2)
# ---------------------------------------------------------------------------------------

@check(uses={"inject": "eskf_inject"})
def check_eskf_fd_transition(transition_by_finite_differences):
    """``transition_by_finite_differences(x, f, w, T, g)`` returns J (15, 15).

    J = ∂(error after one IMU step)/∂(error before it) at δx = 0, measured by differences;
    compared with the check's own central differences (see the module notes for the
    tolerance), and, when wrong, with the known mistakes and with F = I + F_t T.
    """
    g = np.array([0.0, 0.0, -9.8092])
    T = _steps()[3]
    for x, f, w in _cases()[:2]:
        value = call(transition_by_finite_differences, x, f, w, T, g)
        _expect_double(value, "J")
        got = expect_shape(value, (15, 15), "J")
        ref = _fd_transition(x, f, w, T, g)
        if _close(got, ref, 1e-5):
            continue
        F = np.eye(15) + eskf.error_dynamics(x.rotation, f, w, x.accel_bias, x.gyro_bias) * T
        mistakes = [
            (np.zeros((15, 15)), "J is all zero: nothing was measured. For each of the 15 error components, "
                                 "make true states with a small error ±h in that component only, step them "
                                 "and the nominal state through the same IMU step, and difference the errors "
                                 "after the step: that is column i of J (lecture 08 §2)"),
            (-ref, "sign: with error = nominal − true, the true state with error d is the nominal state with "
                   "d removed (inject(x, d)), and the error after the step is nominal − true again; a "
                   "sign flipped in one of the two flips J (lecture 08 §2)"),
            (_fd_transition(x, f, w, T, g, error=_error_nav_frame),
             "the attitude error lives in the body frame, not the navigation frame (lecture 08 §1)"
             + hints.formula(": Ř = R Exp(δθ), so δθ = Log(Rᵀ Ř), not Log(Ř Rᵀ)")),
            (np.eye(15), "J = I: the errors were compared before the step; step the nominal state and each "
                         "true state through nominal_step first (lecture 08 §2)"),
            (_fd_transition(x, f, w, T, g, step_nominal=False),
             "the nominal state was compared before the step: measure each stepped true state against the "
             "nominal state after the same step (nominal_step(x, ...); lecture 08 §2)"),
            (_fd_transition(x, f, w, T, g, step_true=False),
             "the true states were compared before the step: push each of them through the same IMU step "
             "(nominal_step) as the nominal state (lecture 08 §2)"),
            (2 * ref, "factor 2: a central difference divides by 2h, the distance between +h and −h "
                      "(lecture 08 §2)"),
            (ref.T, "transposed: column i of J is the derivative with respect to the i-th error component "
                    "before the step (J[:, i]), row i that of the i-th component after it (lecture 08 §2)"),
            (F, "that is F = I + F_t T itself, not a measurement: J must come from nominal_step by "
                "differences (it equals F only up to O(T²); lecture 08 §2)"),
        ]
        why = known_mistake([got], [None], mistakes, close=lambda mine, wrong, _: _close(mine, wrong, 1e-5),
                            evaluate=lambda wrong, _: wrong)
        if why:
            raise CheckFailed(f"J is wrong. Hint: {why}")
        err = np.abs(np.asarray(got, dtype=float) - ref).max()
        off_F = np.abs(np.asarray(got, dtype=float) - F).max()
        raise CheckFailed(f"J differs from a central-difference Jacobian of one IMU step by {err:.3g} "
                          f"(and from F = I + F_t T by {off_F:.3g}, where O(T²) ≈ {T * T:.0e} is expected). "
                          "Hint: each column of J is a central difference of the error after the step, "
                          "with respect to one error component before it (lecture 08 §2)"
                          + hints.formula(": column i = (error after the step of the true state with error "
                                          "+h e_i, minus that with −h e_i) / 2h, with error = nominal − true and "
                                          "the true state inject(x, ±h e_i)"))
