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

Every function accepts a single element or a stack along leading axes: a vector has
shape (..., 3), a matrix (..., 3, 3), a quaternion (..., 4). Results keep the leading
axes. Only numpy is used.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "hat", "vee", "exp", "log", "Exp", "Log",
    "right_jacobian", "right_jacobian_inv", "left_jacobian", "left_jacobian_inv",
    "orthonormalise", "is_rotation", "interpolate", "angle",
    "quat_to_matrix", "matrix_to_quat", "quat_multiply", "quat_conjugate",
    "quat_normalise", "quat_exp",
]

#: Below this rotation angle (rad) the closed forms switch to Taylor series.
SMALL_ANGLE = 1e-4
#: Above π minus this margin (rad) ``log`` takes the axis from the symmetric part.
NEAR_PI = 1e-2


def _stack(value, name: str, tail: tuple[int, ...]) -> np.ndarray:
    """Return ``value`` as a finite float array whose trailing shape is ``tail``."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim < len(tail) or arr.shape[arr.ndim - len(tail):] != tail:
        want = ", ".join(str(n) for n in tail)
        raise ValueError(f"{name} must have shape ({want}) or (..., {want}), got shape {arr.shape}")
    if not np.all(np.isfinite(arr)):
        raise ValueError(f"{name} must be finite, got NaN or inf")
    return arr


def hat(phi) -> np.ndarray:
    """Skew-symmetric matrix of a vector.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Vector(s) φ, any unit.

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        [φ]× such that ``hat(a) @ b == cross(a, b)``.
    """
    phi = _stack(phi, "phi", (3,))
    x, y, z = phi[..., 0], phi[..., 1], phi[..., 2]
    zero = np.zeros_like(x)
    return np.stack([np.stack([zero, -z, y], -1),
                     np.stack([z, zero, -x], -1),
                     np.stack([-y, x, zero], -1)], -2)


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


def _exp_coefficients(theta: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Return A = sin θ/θ and B = (1 − cos θ)/θ², with Taylor series for small θ."""
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    A = np.where(small, 1.0 - t2 / 6.0 + t2 * t2 / 120.0, np.sin(t) / t)
    B = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - np.cos(t)) / (t * t))
    return A, B


def exp(phi) -> np.ndarray:
    """Exponential map so(3) → SO(3) (Rodrigues' formula), written Exp(φ) in the notes.

    Parameters
    ----------
    phi : array_like, shape (..., 3)
        Rotation vector(s) φ = θ·a in radians (θ the angle, a the unit axis).

    Returns
    -------
    numpy.ndarray, shape (..., 3, 3)
        The rotation matrix/matrices Exp(φ).
    """
    phi = _stack(phi, "phi", (3,))
    theta = np.linalg.norm(phi, axis=-1)
    A, B = _exp_coefficients(theta)
    K = hat(phi)
    return np.eye(3) + A[..., None, None] * K + B[..., None, None] * (K @ K)


def log(R) -> np.ndarray:
    """Logarithm map SO(3) → so(3) as a rotation vector, written Log(R) in the notes.

    Stable for all angles: a Taylor series near θ = 0, the closed form in between and,
    within ``NEAR_PI`` of θ = π, the axis from the symmetric part of R (its sign from the
    antisymmetric part; at exactly π either sign is a valid answer).

    Parameters
    ----------
    R : array_like, shape (..., 3, 3)
        Rotation matrix/matrices (assumed orthonormal; see :func:`orthonormalise`).

    Returns
    -------
    numpy.ndarray, shape (..., 3)
        Rotation vector(s) φ in radians with |φ| ∈ [0, π].
    """
    R = _stack(R, "R", (3, 3))
    s_vec = vee(R)                                  # sin θ · a
    sin_t = np.linalg.norm(s_vec, axis=-1)
    cos_t = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    theta = np.arctan2(sin_t, cos_t)                # in [0, π]

    small = theta < SMALL_ANGLE
    t2 = theta * theta
    safe_sin = np.where(small | (sin_t == 0.0), 1.0, sin_t)
    factor = np.where(small, 1.0 + t2 / 6.0 + 7.0 * t2 * t2 / 360.0, theta / safe_sin)
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
    phi = _stack(phi, "phi", (3,))
    theta = np.linalg.norm(phi, axis=-1)
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    B = np.where(small, 0.5 - t2 / 24.0 + t2 * t2 / 720.0, (1.0 - np.cos(t)) / (t * t))
    C = np.where(small, 1.0 / 6.0 - t2 / 120.0 + t2 * t2 / 5040.0, (t - np.sin(t)) / (t * t * t))
    K = hat(phi)
    return np.eye(3) - B[..., None, None] * K + C[..., None, None] * (K @ K)


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
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    D = np.where(small, 1.0 / 12.0 + t2 / 720.0 + t2 * t2 / 30240.0,
                 1.0 / (t * t) - (1.0 + np.cos(t)) / (2.0 * t * np.sin(t)))
    K = hat(phi)
    return np.eye(3) + 0.5 * K + D[..., None, None] * (K @ K)


def left_jacobian(phi) -> np.ndarray:
    """Left Jacobian of SO(3): ``Exp(φ + δ) ≈ Exp(J_l(φ) δ) Exp(φ)``; equals J_r(−φ)."""
    return right_jacobian(-_stack(phi, "phi", (3,)))


def left_jacobian_inv(phi) -> np.ndarray:
    """Inverse of :func:`left_jacobian`; equals J_r⁻¹(−φ)."""
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
    err = np.abs(np.swapaxes(R, -1, -2) @ R - np.eye(3)).max(initial=0.0)
    return bool(err <= tol and np.all(np.linalg.det(R) > 0))


def angle(R) -> np.ndarray:
    """Rotation angle θ ∈ [0, π] in radians of each matrix in ``R`` (..., 3, 3)."""
    R = _stack(R, "R", (3, 3))
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
    """
    R0 = _stack(R0, "R0", (3, 3))
    R1 = _stack(R1, "R1", (3, 3))
    alpha = np.asarray(alpha, dtype=float)
    delta = log(np.swapaxes(R0, -1, -2) @ R1)
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


def quat_multiply(p, q) -> np.ndarray:
    """Hamilton product p ⊗ q of quaternions (..., 4); ``quat_to_matrix(p ⊗ q) = R(p) R(q)``."""
    p = _stack(p, "p", (4,))
    q = _stack(q, "q", (4,))
    pw, pv = p[..., :1], p[..., 1:]
    qw, qv = q[..., :1], q[..., 1:]
    w = pw * qw - np.sum(pv * qv, axis=-1, keepdims=True)
    v = pw * qv + qw * pv + np.cross(pv, qv)
    return np.concatenate([w, v], axis=-1)


def quat_to_matrix(q) -> np.ndarray:
    """Rotation matrix of quaternion(s) ``q = (w, x, y, z)``, shape (..., 4) → (..., 3, 3).

    The quaternion is normalised first, so any non-zero scaling gives the same rotation.
    """
    w, x, y, z = np.moveaxis(quat_normalise(q), -1, 0)
    return np.stack([
        np.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
        np.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
        np.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
    ], -2)


def matrix_to_quat(R) -> np.ndarray:
    """Unit quaternion(s) (w, x, y, z) with w ≥ 0 of rotation matrix/matrices R (..., 3, 3).

    Uses Shepperd's method: each quaternion is computed from the largest of 1 + tr R and
    1 + 2R_ii − tr R, so no division by a small number occurs.
    """
    R = _stack(R, "R", (3, 3))
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
    theta = np.linalg.norm(phi, axis=-1)
    small = theta < SMALL_ANGLE
    t = np.where(small, 1.0, theta)
    t2 = theta * theta
    half_sinc = np.where(small, 0.5 - t2 / 48.0 + t2 * t2 / 3840.0, np.sin(0.5 * t) / t)
    return np.concatenate([np.cos(0.5 * theta)[..., None], half_sinc[..., None] * phi], axis=-1)
