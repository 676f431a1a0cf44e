"""Rotations: the group SO(3), its Lie algebra so(3) and unit quaternions.

Conventions used throughout the course
---------------------------------------
- A rotation matrix ``R_nb`` maps body-frame coordinates to navigation-frame coordinates:
  ``v_n = R_nb @ v_b``.
- ``hat`` turns a vector φ (3,) into the skew-symmetric matrix [φ]× (3, 3) with
  ``hat(a) @ b == np.cross(a, b)``; ``vee`` is its inverse.
- ``exp`` (alias ``Exp``) maps a rotation vector φ (3,) in radians to a rotation matrix,
  ``Exp(φ) = I + sin θ/θ [φ]× + (1 − cos θ)/θ² [φ]×²`` with θ = |φ|; ``log`` (alias ``Log``)
  is its inverse on rotation angles in [0, π].
- Quaternions are scalar first, ``q = (w, x, y, z)``, Hamilton product, and represent
  the same rotation as ``quat_to_matrix(q)``. ``matrix_to_quat`` returns the
  representative with ``w >= 0``.

Roll, pitch and yaw: ``from_rpy`` and ``to_rpy``, R_nb = Rz(yaw) Ry(pitch) Rx(roll) (intrinsic
z-y'-x''), radians.

Every function that needs a rotation matrix (``log``, ``angle``, ``interpolate``,
``matrix_to_quat``, ``to_rpy``) refuses one that is not: max |RᵀR − I| above
:data:`~kalman_course.core.validation.ROTATION_TOL` (a scaled or sheared matrix) or det R ≤ 0
(a reflection), with a ValueError naming the argument and, in a stack, the index of the
first bad matrix. ``orthonormalise`` is what turns a nearly orthonormal matrix into one.

Every function accepts a single element or a stack along leading axes: a vector has
shape (..., 3), a matrix (..., 3, 3), a quaternion (..., 4). Results keep the leading
axes. Only numpy is used.

These are the course's only SO(3) kernels (the filters use them in their inner loops), so
each map has two paths with the same thresholds (:data:`SMALL_ANGLE`, :data:`NEAR_PI`)
and the same Taylor series: one for a single element, in Python floats (a filter calls it
once per update, where numpy's per-call cost would dominate), and one for a stack, in
numpy. Every function validates its arguments; ``exp``, ``log``, ``hat``, ``left_jacobian``
and ``angle`` take ``check=False`` for callers that validated at their own boundary.
"""

from __future__ import annotations

import math

import numpy as np

from kalman_course.core.validation import ROTATION_TOL, check_rotations

__all__ = [
    "hat", "vee", "exp", "log", "Exp", "Log",
    "right_jacobian", "right_jacobian_inv", "left_jacobian", "left_jacobian_inv",
    "orthonormalise", "is_rotation", "as_rotations", "interpolate", "angle",
    "quat_to_matrix", "matrix_to_quat", "quat_multiply", "quat_conjugate",
    "quat_normalise", "quat_exp", "from_rpy", "to_rpy",
]

#: Below this rotation angle (rad) the closed forms switch to Taylor series.
SMALL_ANGLE = 1e-4
#: Above π minus this margin (rad) ``log`` takes the axis from the symmetric part.
NEAR_PI = 1e-2
#: :func:`to_rpy` treats a rotation with |cos(pitch)| below this as gimbal-locked.
GIMBAL_LOCK = 1e-8


def _stack(value, name: str, tail: tuple[int, ...]) -> np.ndarray:
    """Return ``value`` as a finite float array whose trailing shape is ``tail``."""
    if type(value) is np.ndarray and value.dtype == np.float64:
        arr = value                       # the fast path of the filters' inner loops
    else:
        try:
            arr = np.asarray(value, dtype=float)
        except (TypeError, ValueError):
            raise ValueError(f"{name} must be a numeric array, got {type(value).__name__}") from None
    if arr.ndim < len(tail) or arr.shape[arr.ndim - len(tail):] != tail:
        want = ", ".join(str(n) for n in tail)
        raise ValueError(f"{name} must have shape ({want}) or (..., {want}), got shape {arr.shape}")
    # a NaN or inf makes the sum non-finite (cheaper than isfinite().all() on tiny arrays);
    # a finite sum proves every entry finite, an overflowing one is checked entry by entry
    if not math.isfinite(np.add.reduce(arr, axis=None)) and not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    return arr


def as_rotations(value, name: str) -> np.ndarray:
    """Return ``value`` as a float array of rotation matrices, shape (3, 3) or (..., 3, 3).

    The rule is the project's (:func:`~kalman_course.core.validation.as_rotation` for one
    matrix, :class:`~kalman_course.core.observations.PoseObservations` for a record):
    max |RᵀR − I| ≤ :data:`~kalman_course.core.validation.ROTATION_TOL` (1e-6) and
    det R > 0, which rejects a scaled, sheared or far-from-orthonormal matrix and a
    reflection.

    Parameters
    ----------
    value : array_like, shape (3, 3) or (..., 3, 3)
        Candidate rotation matrix or stack.
    name : str
        Argument name used in error messages.

    Returns
    -------
    numpy.ndarray, shape (3, 3) or (..., 3, 3)
        ``value`` itself when it is a float64 ndarray, else a converted copy.

    Raises
    ------
    ValueError
        If ``value`` has the wrong shape or holds a NaN or inf, or a matrix is not a
        rotation; a stack's first bad matrix is named by its index, for example
        ``rotation[4] is a reflection, not a rotation (det = -1, expected +1)`` or
        ``R is not a rotation matrix (|RᵀR − I| = 0.21, tolerance 1e-06)``.
    """
    R = _stack(value, name, (3, 3))
    check_rotations(R, name)
    return R


def _is_rotation_entries(r00, r01, r02, r10, r11, r12, r20, r21, r22) -> bool:
    """The rule of :func:`as_rotations` for one matrix given as floats (the fast path of
    :func:`log`, which has the entries already): max |RᵀR − I| ≤ ROTATION_TOL, det > 0."""
    # the six distinct entries of RᵀR − I: column norms minus one, column dot products
    gram = max(abs(r00 * r00 + r10 * r10 + r20 * r20 - 1.0), abs(r01 * r01 + r11 * r11 + r21 * r21 - 1.0),
               abs(r02 * r02 + r12 * r12 + r22 * r22 - 1.0), abs(r00 * r01 + r10 * r11 + r20 * r21),
               abs(r00 * r02 + r10 * r12 + r20 * r22), abs(r01 * r02 + r11 * r12 + r21 * r22))
    det = r00 * (r11 * r22 - r12 * r21) - r01 * (r10 * r22 - r12 * r20) + r02 * (r10 * r21 - r11 * r20)
    return gram <= ROTATION_TOL and det > 0.0


# ---------------------------------------------------------------------------------------
# Kernels. Every map below is a polynomial in K = [φ]× of degree two,
#     I + a K + b K²,   with K² = φφᵀ − θ² I,
# whose coefficients a(θ), b(θ) switch to their Taylor series below SMALL_ANGLE. The
# series are written once (``_series_*``, functions of θ², valid for floats and arrays);
# each map has a path for one element (Python floats: a filter calls it once per update)
# and one for a stack (numpy arrays), with the same thresholds and series.
# ---------------------------------------------------------------------------------------

def _series_sinc(t2):
    """sin θ / θ for small θ, from θ²."""
    return 1.0 - t2 / 6.0 + t2 * t2 / 120.0


def _series_cosc(t2):
    """(1 − cos θ) / θ² for small θ, from θ²."""
    return 0.5 - t2 / 24.0 + t2 * t2 / 720.0


def _series_sinc3(t2):
    """(θ − sin θ) / θ³ for small θ, from θ²."""
    return 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0


def _series_inv(t2):
    """1/θ² − (1 + cos θ) / (2 θ sin θ) (the K² coefficient of J_r⁻¹) for small θ."""
    return 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0


def _series_half_sinc(t2):
    """sin(θ/2) / θ for small θ, from θ² (the vector part of a quaternion per radian)."""
    return 0.5 - t2 / 48.0 + t2 * t2 / 3840.0


def _series_log(t2):
    """θ / sin θ for small θ, from θ²."""
    return 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0


def _coefficients(phi: np.ndarray, which: str):
    """(θ², a, b) of the map ``which`` at φ: floats for φ (3,), arrays (...) for a stack.

    ``which``: "exp" (a = sin θ/θ, b = (1 − cos θ)/θ²), "right_jacobian" (a = −(1 − cos θ)/θ²,
    b = (θ − sin θ)/θ³), "left_jacobian" (a = +(1 − cos θ)/θ², same b) or "right_jacobian_inv"
    (a = ½, b = 1/θ² − (1 + cos θ)/(2θ sin θ)).
    """
    if phi.ndim == 1:
        x, y, z = phi.tolist()
        t2 = x * x + y * y + z * z
        small = t2 < SMALL_ANGLE * SMALL_ANGLE
        t = math.sqrt(t2)
        if which == "exp":
            a = _series_sinc(t2) if small else math.sin(t) / t
            b = _series_cosc(t2) if small else (1.0 - math.cos(t)) / t2
        elif which == "right_jacobian_inv":
            a = 0.5
            b = _series_inv(t2) if small else 1.0 / t2 - (1.0 + math.cos(t)) / (2.0 * t * math.sin(t))
        else:
            a = _series_cosc(t2) if small else (1.0 - math.cos(t)) / t2
            a = -a if which == "right_jacobian" else a
            b = _series_sinc3(t2) if small else (t - math.sin(t)) / (t2 * t)
        return t2, a, b
    t2 = np.add.reduce(phi * phi, axis=-1)
    any_small = bool(t2.size) and np.minimum.reduce(t2, axis=None) < SMALL_ANGLE * SMALL_ANGLE
    small = t2 < SMALL_ANGLE * SMALL_ANGLE if any_small else None
    t = np.sqrt(np.where(small, 1.0, t2)) if any_small else np.sqrt(t2)   # no 0/0 where the series is used
    if which == "exp":
        a, b = np.sin(t) / t, (1.0 - np.cos(t)) / (t * t)
        series = (_series_sinc, _series_cosc)
    elif which == "right_jacobian_inv":
        a = np.full(t2.shape, 0.5)
        b = 1.0 / (t * t) - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t))
        series = (None, _series_inv)
    else:
        a, b = (1.0 - np.cos(t)) / (t * t), (t - np.sin(t)) / (t * t * t)
        series = (_series_cosc, _series_sinc3)
    if any_small:
        s2 = t2[small]
        if series[0] is not None:
            a[small] = series[0](s2)
        b[small] = series[1](s2)
    if which == "right_jacobian":
        a = -a
    return t2, a, b


def _quadratic_map(phi: np.ndarray, which: str) -> np.ndarray:
    """I + a K + b K² (K = [φ]×, K² = φφᵀ − θ² I) of the map ``which`` for a validated φ (3,) or (..., 3)."""
    t2, a, b = _coefficients(phi, which)
    if phi.ndim == 1:
        x, y, z = phi.tolist()
        xx, yy, zz, xy, xz, yz = x * x, y * y, z * z, x * y, x * z, y * z
        return np.array([[1.0 - b * (yy + zz), b * xy - a * z, b * xz + a * y],
                         [b * xy + a * z, 1.0 - b * (xx + zz), b * yz - a * x],
                         [b * xz - a * y, b * yz + a * x, 1.0 - b * (xx + yy)]])
    K = _hat(phi)
    out = K @ K
    out *= b[..., None, None]
    out += a[..., None, None] * K
    out += _I3
    return out


#: vec([φ]×) = _HAT_GENERATORS @ φ: [φ]× is linear in φ (row-major 3 × 3 entries).
_HAT_GENERATORS = np.array([[0, 0, 0], [0, 0, -1], [0, 1, 0],
                            [0, 0, 1], [0, 0, 0], [-1, 0, 0],
                            [0, -1, 0], [1, 0, 0], [0, 0, 0]], dtype=float)
_I3 = np.eye(3)


def _hat(phi: np.ndarray) -> np.ndarray:
    """[φ]× of a validated stack φ (..., 3): one product with the generators (exact)."""
    return (phi @ _HAT_GENERATORS.T).reshape(*phi.shape[:-1], 3, 3)


def hat(phi, *, check: bool = True) -> np.ndarray:
    """Skew-symmetric matrix of a vector.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Vector(s) φ, any unit.
    check : bool, keyword-only
        Validate the argument (default). A filter's inner loop that validated its inputs
        at its own boundary passes False to skip the check (a float64 ndarray is required then).

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        [φ]× such that ``hat(a) @ b == cross(a, b)``.
    """
    if check:
        phi = _stack(phi, "phi", (3,))
    if phi.ndim == 1:
        x, y, z = phi.tolist()
        return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return _hat(phi)


def vee(M) -> np.ndarray:
    """Vector of a skew-symmetric matrix (inverse of :func:`hat`).

    Parameters
    ----------
    M : array_like, shape (..., 3, 3)
        Skew-symmetric matrix/matrices. Only the antisymmetric part is used:
        ``vee(M) == vee((M - M.T) / 2)``.

    Returns
    -------
    numpy.ndarray, shape (..., 3)
    """
    M = _stack(M, "M", (3, 3))
    return 0.5 * np.stack([M[..., 2, 1] - M[..., 1, 2],
                           M[..., 0, 2] - M[..., 2, 0],
                           M[..., 1, 0] - M[..., 0, 1]], -1)


def exp(phi, *, check: bool = True) -> np.ndarray:
    """Exponential map so(3) → SO(3) (Rodrigues' formula), written Exp(φ) in the notes.

    ``Exp(φ) = I + sin θ/θ [φ]× + (1 − cos θ)/θ² [φ]×²`` with θ = |φ|; both coefficients
    use their Taylor series below :data:`SMALL_ANGLE`.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) φ = θ·a in radians (θ the angle, a the unit axis).
    check : bool, keyword-only
        Validate the argument (default). A filter's inner loop that validated its inputs
        at its own boundary passes False to skip the check (a float64 ndarray is required then).

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        The rotation matrix/matrices Exp(φ).
    """
    return _quadratic_map(_stack(phi, "phi", (3,)) if check else phi, "exp")


def log(R, *, check: bool = True) -> np.ndarray:
    """Logarithm map SO(3) → so(3) as a rotation vector, written Log(R) in the notes.

    Stable for all angles: a Taylor series near θ = 0, the closed form in between and,
    within ``NEAR_PI`` of θ = π, the axis from the symmetric part of R (its sign from the
    antisymmetric part; at exactly π either sign is a valid answer).

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Rotation matrix/matrices: max |RᵀR − I| ≤ ``ROTATION_TOL`` (1e-6) and det R = +1.
        A matrix further from SO(3), such as one printed with few digits, can be projected
        onto it first with :func:`orthonormalise`.
    check : bool, keyword-only
        Validate the argument (default): its shape, that it is finite, and that each
        matrix is a rotation. A filter's inner loop that validated its inputs at its own
        boundary passes False to skip the check (a float64 ndarray is required then; the
        result for a matrix that is not a rotation is then meaningless, e.g. 0 for a
        reflection).

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        Rotation vector(s) φ in radians with |φ| ∈ [0, π].

    Raises
    ------
    ValueError
        With ``check``: if ``R`` has the wrong shape, holds a NaN or inf, or a matrix is
        not orthonormal (``R is not a rotation matrix (|RᵀR − I| = 0.2, ...)``) or is a
        reflection (``R[3] is a reflection, not a rotation (det = -1, ...)``).
    """
    if check:
        R = _stack(R, "R", (3, 3))
        if R.ndim != 2:
            check_rotations(R, "R")
    if R.ndim == 2:
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
        if check and not _is_rotation_entries(r00, r01, r02, r10, r11, r12, r20, r21, r22):
            check_rotations(R, "R")                    # raises, with the project's message
        sx, sy, sz = 0.5 * (r21 - r12), 0.5 * (r02 - r20), 0.5 * (r10 - r01)   # sin θ · a
        sin_t = math.sqrt(sx * sx + sy * sy + sz * sz)
        theta = math.atan2(sin_t, 0.5 * (r00 + r11 + r22 - 1.0))
        if theta <= math.pi - NEAR_PI:
            factor = _series_log(theta * theta) if theta < SMALL_ANGLE else theta / sin_t
            return np.array([factor * sx, factor * sy, factor * sz])
        return _log_stack(R[None])[0]
    return _log_stack(R)


def _log_stack(R: np.ndarray) -> np.ndarray:
    """:func:`log` of a validated stack (..., 3, 3)."""
    s_vec = vee(R)                                  # sin θ · a
    sin_t = np.linalg.norm(s_vec, axis=-1)
    cos_t = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    theta = np.arctan2(sin_t, cos_t)                # in [0, π]

    small = theta < SMALL_ANGLE
    safe_sin = np.where(small | (sin_t == 0.0), 1.0, sin_t)
    factor = np.where(small, _series_log(theta * theta), theta / safe_sin)
    phi = factor[..., None] * s_vec

    near_pi = theta > np.pi - NEAR_PI
    if np.any(near_pi):
        Rn = R[near_pi]
        cn = cos_t[near_pi]
        # (R + Rᵀ)/2 = cos θ I + (1 − cos θ) a aᵀ
        aaT = (0.5 * (Rn + np.swapaxes(Rn, -1, -2)) - cn[:, None, None] * np.eye(3)) / (1.0 - cn)[:, None, None]
        diag = np.diagonal(aaT, axis1=-2, axis2=-1)
        j = np.argmax(diag, axis=-1)
        rows = np.arange(len(j))
        axis = aaT[rows, :, j] / np.sqrt(np.maximum(diag[rows, j], 1e-300))[:, None]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        sign = np.where(np.sum(axis * s_vec[near_pi], axis=-1) < 0.0, -1.0, 1.0)
        phi[near_pi] = (sign * theta[near_pi])[:, None] * axis
    return phi


#: Capitalised aliases matching the notation of the lecture notes.
Exp = exp
Log = log


def right_jacobian(phi) -> np.ndarray:
    """Right Jacobian of SO(3): ``Exp(φ + δ) ≈ Exp(φ) Exp(J_r(φ) δ)`` for small δ.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) in radians.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        ``J_r = I − (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×²``.
    """
    return _quadratic_map(_stack(phi, "phi", (3,)), "right_jacobian")


def right_jacobian_inv(phi) -> np.ndarray:
    """Inverse of :func:`right_jacobian`, in closed form.

    ``J_r⁻¹ = I + ½[φ]× + (1/θ² − (1 + cos θ)/(2 θ sin θ)) [φ]×²``; valid for θ < π.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) in radians, |φ| < π.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
    """
    phi = _stack(phi, "phi", (3,))
    theta = np.linalg.norm(phi, axis=-1)
    if np.any(theta >= np.pi):
        raise ValueError("phi must have norm < π for right_jacobian_inv (the Jacobian is singular at 2π "
                         f"and the inverse is not unique from π), got max |phi| = {theta.max():.6g}")
    return _quadratic_map(phi, "right_jacobian_inv")


def left_jacobian(phi, *, check: bool = True) -> np.ndarray:
    """Left Jacobian of SO(3): ``Exp(φ + δ) ≈ Exp(J_l(φ) δ) Exp(φ)``; equals J_r(−φ).

    ``J_l = I + (1 − cos θ)/θ² [φ]× + (θ − sin θ)/θ³ [φ]×²``, shape (..., 3, 3) for φ (..., 3).
    ``check=False`` skips the validation of φ (see :func:`exp`).
    """
    return _quadratic_map(_stack(phi, "phi", (3,)) if check else phi, "left_jacobian")


def left_jacobian_inv(phi) -> np.ndarray:
    """Inverse of :func:`left_jacobian`; equals J_r⁻¹(−φ), shape (..., 3, 3) for φ (..., 3)."""
    return right_jacobian_inv(-_stack(phi, "phi", (3,)))


def orthonormalise(R) -> np.ndarray:
    """Closest rotation matrix in the Frobenius norm (SVD: U diag(1, 1, det(U Vᵀ)) Vᵀ).

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Nearly orthonormal matrix/matrices, e.g. calibration values printed with few digits
        or a product of many rotations that has accumulated round-off.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        Proper rotation(s), det = +1.
    """
    R = _stack(R, "R", (3, 3))
    U, _, Vt = np.linalg.svd(R)
    d = np.sign(np.linalg.det(U @ Vt))
    d = np.where(d == 0.0, 1.0, d)
    U = U.copy()
    U[..., :, 2] *= d[..., None]
    return U @ Vt


def is_rotation(R, tol: float = 1e-9) -> bool:
    """True if every matrix in ``R`` (..., 3, 3) has |RᵀR − I| ≤ tol and det(R) > 0."""
    R = _stack(R, "R", (3, 3))
    if isinstance(tol, (bool, np.bool_)) or not isinstance(tol, (int, float, np.floating, np.integer)) \
            or not math.isfinite(tol) or tol < 0:
        raise ValueError(f"tol must be a finite non-negative number, got {tol!r}")
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(initial=0.0)
    return bool(err <= tol and np.all(np.linalg.det(R) > 0))


def angle(R, *, check: bool = True) -> np.ndarray:
    """Rotation angle θ ∈ [0, π] in radians of each matrix in ``R`` (..., 3, 3).

    Raises ValueError if a matrix of ``R`` is not a rotation (the rule of :func:`log`).
    ``check=False`` skips the validation, for a caller whose ``R`` is a product of
    rotations it validated (a product of matrices each 1e-6 from SO(3) can be 2e-6 from it).
    """
    if check:
        R = as_rotations(R, "R")
    sin_t = np.linalg.norm(vee(R), axis=-1)
    cos_t = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    return np.arctan2(sin_t, cos_t)


def interpolate(R0, R1, alpha) -> np.ndarray:
    """Geodesic interpolation ``R0 Exp(α Log(R0ᵀ R1))`` (spherical linear interpolation).

    Parameters
    ----------
    R0, R1 : array_like, shape (..., 3, 3)
        Rotations at α = 0 and α = 1.
    alpha : array_like, shape (...) or scalar
        Fraction(s) of the way from R0 to R1 (values outside [0, 1] extrapolate).

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)

    Raises
    ------
    ValueError
        If ``R0`` or ``R1`` is not a rotation (the rule of :func:`log`), or ``alpha`` is not
        finite.
    """
    R0 = as_rotations(R0, "R0")
    R1 = as_rotations(R1, "R1")
    try:
        alpha = np.asarray(alpha, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"alpha must be a number or an array of numbers, got {alpha!r}") from None
    if not np.isfinite(alpha).all():
        raise ValueError("alpha must be finite, got NaN or inf")
    delta = log(np.swapaxes(R0, -1, -2) @ R1, check=False)        # both validated above
    return R0 @ exp(alpha[..., None] * delta)


# ---------------------------------------------------------------------------------------
# Quaternions (w, x, y, z), Hamilton convention
# ---------------------------------------------------------------------------------------

def quat_normalise(q) -> np.ndarray:
    """Return q / |q| for quaternion(s) ``q`` of shape (..., 4); raises on a zero quaternion."""
    q = _stack(q, "q", (4,))
    n = np.linalg.norm(q, axis=-1, keepdims=True)
    if np.any(n == 0.0):
        raise ValueError("q must be non-zero to be normalised, got a quaternion of norm 0")
    return q / n


def quat_conjugate(q) -> np.ndarray:
    """Conjugate (w, −x, −y, −z) of quaternion(s) of shape (..., 4); the inverse of a unit q."""
    q = _stack(q, "q", (4,))
    return q * np.array([1.0, -1.0, -1.0, -1.0])


def _hamilton(pw, px, py, pz, qw, qx, qy, qz) -> list:
    """Components (w, x, y, z) of p ⊗ q from the components of p and q (floats or arrays)."""
    return [pw * qw - px * qx - py * qy - pz * qz, pw * qx + px * qw + py * qz - pz * qy,
            pw * qy - px * qz + py * qw + pz * qx, pw * qz + px * qy - py * qx + pz * qw]


def quat_multiply(p, q) -> np.ndarray:
    """Hamilton product p ⊗ q of quaternions (..., 4); ``quat_to_matrix(p ⊗ q) = R(p) R(q)``."""
    p = _stack(p, "p", (4,))
    q = _stack(q, "q", (4,))
    if p.ndim == 1 and q.ndim == 1:
        return np.array(_hamilton(*p.tolist(), *q.tolist()))
    return np.stack(_hamilton(*np.moveaxis(p, -1, 0), *np.moveaxis(q, -1, 0)), axis=-1)


def _quat_matrix(w, x, y, z) -> list:
    """Entries (nested 3 × 3 list) of the rotation matrix of a unit quaternion (floats or arrays)."""
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]]


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of quaternion(s) ``q = (w, x, y, z)``, shape (..., 4) → (..., 3, 3).

    The quaternion is normalised first, so any non-zero scaling gives the same rotation.
    """
    q = _stack(q, "q", (4,))
    if q.ndim == 1:
        w, x, y, z = q.tolist()
        n = math.sqrt(w * w + x * x + y * y + z * z)
        if n == 0.0:
            raise ValueError("q must be non-zero to be normalised, got a quaternion of norm 0")
        return np.array(_quat_matrix(w / n, x / n, y / n, z / n))
    entries = _quat_matrix(*np.moveaxis(quat_normalise(q), -1, 0))
    return np.stack([np.stack(row, -1) for row in entries], -2)


def matrix_to_quat(R) -> np.ndarray:
    """Unit quaternion(s) (w, x, y, z) with w ≥ 0 of rotation matrix/matrices R (..., 3, 3).

    Uses Shepperd's method: each quaternion is computed from the largest of 1 + tr R and
    1 + 2R_ii − tr R, so no division by a small number occurs.

    Raises ValueError if a matrix of ``R`` is not a rotation (the rule of :func:`log`): the
    method returns a plausible unit quaternion for any matrix, e.g. (0, 1, 0, 0) for −I.
    """
    R = as_rotations(R, "R")
    r00, r11, r22 = R[..., 0, 0], R[..., 1, 1], R[..., 2, 2]
    tr = r00 + r11 + r22
    cand = np.stack([1.0 + tr, 1.0 + 2 * r00 - tr, 1.0 + 2 * r11 - tr, 1.0 + 2 * r22 - tr], -1)
    k = np.argmax(cand, axis=-1)
    s = np.sqrt(np.maximum(np.take_along_axis(cand, k[..., None], -1)[..., 0], 1e-300))  # = 4|q_k|/2
    d21 = R[..., 2, 1] - R[..., 1, 2]
    d02 = R[..., 0, 2] - R[..., 2, 0]
    d10 = R[..., 1, 0] - R[..., 0, 1]
    s01 = R[..., 0, 1] + R[..., 1, 0]
    s02 = R[..., 0, 2] + R[..., 2, 0]
    s12 = R[..., 1, 2] + R[..., 2, 1]
    q = np.where((k == 0)[..., None], np.stack([s * s, d21, d02, d10], -1), 0.0)
    q = np.where((k == 1)[..., None], np.stack([d21, s * s, s01, s02], -1), q)
    q = np.where((k == 2)[..., None], np.stack([d02, s01, s * s, s12], -1), q)
    q = np.where((k == 3)[..., None], np.stack([d10, s02, s12, s * s], -1), q)
    q = q / (2.0 * s[..., None])
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., :1] < 0.0, -q, q)


def quat_exp(phi) -> np.ndarray:
    """Unit quaternion of the rotation vector(s) φ (..., 3) in radians: (cos θ/2, sin(θ/2) φ/θ)."""
    phi = _stack(phi, "phi", (3,))
    if phi.ndim == 1:
        x, y, z = phi.tolist()
        t2 = x * x + y * y + z * z
        theta = math.sqrt(t2)
        k = _series_half_sinc(t2) if theta < SMALL_ANGLE else math.sin(0.5 * theta) / theta
        return np.array([math.cos(0.5 * theta), k * x, k * y, k * z])
    theta = np.linalg.norm(phi, axis=-1)
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    half_sinc = np.where(small, _series_half_sinc(theta * theta), np.sin(0.5 * t) / t)
    return np.concatenate([np.cos(0.5 * theta)[..., None], half_sinc[..., None] * phi], axis=-1)


# ---------------------------------------------------------------------------------------
# Roll, pitch, yaw
# ---------------------------------------------------------------------------------------

def _angles(value, name: str) -> np.ndarray:
    """``value`` as a finite float array (any shape) of angles in radians, |angle| ≤ 2π."""
    try:
        arr = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be an angle in radians (a number or an array of numbers), "
                         f"got {type(value).__name__}") from None
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    if arr.size and np.abs(arr).max() > 2.0 * math.pi:
        worst = float(arr.flat[np.argmax(np.abs(arr))])
        raise ValueError(f"{name} must be in radians, |{name}| ≤ 2π, got {worst:g} "
                         f"(degrees? convert with np.deg2rad)")
    return arr


def from_rpy(roll, pitch, yaw) -> np.ndarray:
    """Rotation matrix R_nb of roll, pitch and yaw angles: ``R = Rz(yaw) Ry(pitch) Rx(roll)``.

    The convention is the intrinsic z-y'-x'' sequence (the aerospace one): turn the
    navigation frame by yaw about its z axis, the result by pitch about its new y axis, and
    that by roll about its newest x axis; ``Rx(a) = Exp(a e_x)`` and so on, each a
    right-handed (anticlockwise) turn.

    Parameters
    ----------
    roll, pitch, yaw : float or array_like, shape (...)
        The angles in radians, broadcast against each other; each |angle| ≤ 2π. Any
        pitch is a rotation, but :func:`to_rpy` returns pitch in [−π/2, π/2] and roll and
        yaw in (−π, π], so a round trip gives the same angles only inside those ranges.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        R_nb (body to navigation), one matrix per broadcast element.

    Raises
    ------
    ValueError
        If an angle is not a finite number, the three do not broadcast, or an angle
        exceeds 2π in magnitude (a hint that it is in degrees).
    """
    roll, pitch, yaw = _angles(roll, "roll"), _angles(pitch, "pitch"), _angles(yaw, "yaw")
    try:
        roll, pitch, yaw = np.broadcast_arrays(roll, pitch, yaw)
    except ValueError:
        raise ValueError(f"roll, pitch and yaw must broadcast to one shape, got shapes {roll.shape}, "
                         f"{pitch.shape} and {yaw.shape}") from None
    cr, sr = np.cos(roll), np.sin(roll)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cy, sy = np.cos(yaw), np.sin(yaw)
    rows = [[cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr]]
    return np.stack([np.stack(row, -1) for row in rows], -2)


def to_rpy(R) -> np.ndarray:
    """Roll, pitch and yaw (radians) of rotation matrices, the inverse of :func:`from_rpy`.

    With ``R = Rz(yaw) Ry(pitch) Rx(roll)`` (intrinsic z-y'-x''):
    pitch = atan2(−R₂₀, √(R₂₁² + R₂₂²)) ∈ [−π/2, π/2], roll = atan2(R₂₁, R₂₂) ∈ (−π, π],
    yaw = atan2(R₁₀, R₀₀) ∈ (−π, π].

    Gimbal lock: at pitch = ±π/2 only yaw ∓ roll is defined. Where |cos pitch| <
    :data:`GIMBAL_LOCK` (1e-8, |pitch| within 1e-8 rad of π/2) the function returns roll = 0
    and puts the whole turn about the vertical into yaw = atan2(−R₀₁, R₁₁). ``from_rpy`` of
    the result then reproduces R to within about 1e-8 (the entries the dropped roll would
    set, |cos pitch| · |sin roll| and |cos pitch| · |1 − cos roll|, are below GIMBAL_LOCK).
    Outside that band the general formulas reproduce R to about round-off / |cos pitch|,
    also below about 1e-8. Near the lock the separate roll and yaw are ill-conditioned
    whichever the formula: a change of ε in R moves them by about ε / |cos pitch|.

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Rotation matrices R_nb (the rule of :func:`log`: max |RᵀR − I| ≤ ROTATION_TOL,
        det +1).

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        (roll, pitch, yaw) along the last axis, radians.

    Raises
    ------
    ValueError
        If ``R`` has the wrong shape, is not finite, or a matrix is not a rotation (the
        first such matrix of a stack is named by its index).
    """
    R = as_rotations(R, "R")
    cos_pitch = np.hypot(R[..., 2, 1], R[..., 2, 2])
    pitch = np.arctan2(-R[..., 2, 0], cos_pitch)
    locked = cos_pitch < GIMBAL_LOCK
    roll = np.where(locked, 0.0, np.arctan2(R[..., 2, 1], R[..., 2, 2]))
    yaw = np.where(locked, np.arctan2(-R[..., 0, 1], R[..., 1, 1]), np.arctan2(R[..., 1, 0], R[..., 0, 0]))
    # atan2 returns −π for a negative zero; the documented range is (−π, π]
    roll, yaw = (np.where(a == -np.pi, np.pi, a) for a in (roll, yaw))
    return np.stack([roll, pitch, yaw], -1)
