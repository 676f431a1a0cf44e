"""The linear algebra every Kalman-type filter shares, each formula written once.

Unvalidated kernels: callers validate at their public boundary (``core.validation``) and
then call these inside their loops. Notation of the lecture: posterior covariance P̂
(n, n), motion Jacobian F (n, n), process noise in state space B Q Bᵀ (n, n), prior
covariance P̌ (n, n), observation Jacobian G (m, n), observation noise in measurement
space R (m, m) (already C R Cᵀ where an observation-noise Jacobian C is used),
innovation covariance S (m, m), gain K (n, m).

``np.dot`` is used because for these tiny matrices it has the least call overhead of
numpy's products.
"""

from __future__ import annotations

import numpy as np
from numpy import dot
from numpy.linalg import solve

__all__ = ["expm", "symmetrise", "predict_covariance", "innovation_covariance", "gain", "joseph_form",
           "joseph_update", "short_update"]


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
    return symmetrise(dot(dot(F, P_hat), F.T) + BQBt, out)


def innovation_covariance(GP: np.ndarray, G: np.ndarray, R: np.ndarray) -> np.ndarray:
    """S = G P̌ Gᵀ + R, given GP = G P̌ (m, n); returns (m, m)."""
    return dot(GP, G.T) + R


def gain(GP: np.ndarray, S: np.ndarray) -> np.ndarray:
    """K = P̌ Gᵀ S⁻¹, given GP = G P̌ (m, n) and S (m, m); returns (n, m).

    P̌ is symmetric, so P̌ Gᵀ = (G P̌)ᵀ. One or two measured components (a range, a 2-D
    position fix) use the closed form S⁻¹ = 1/s or adj(S)/det(S): for so small an S,
    ``np.linalg.solve`` costs more in call overhead than the rest of an update. A larger
    S is solved, never inverted; a singular S raises ``numpy.linalg.LinAlgError``.
    """
    m = S.shape[0]
    if m == 1:
        return GP.T / S[0, 0]
    if m == 2:
        (a, b), (c, d) = S.tolist()
        det = a * d - b * c
        if det > 0:                          # always when S is positive definite
            S_inv = np.array([[d / det, -b / det], [-c / det, a / det]])
            return dot(GP.T, S_inv)
    return solve(S, GP).T                    # Kᵀ = S⁻¹ G P̌; reports a singular S


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
    I_KG = I - dot(K, G)
    return dot(dot(I_KG, P_check), I_KG.T) + dot(dot(K, R), K.T)


def joseph_update(P_check: np.ndarray, K: np.ndarray, G: np.ndarray, R: np.ndarray,
                  I: np.ndarray | None = None, out: np.ndarray | None = None) -> np.ndarray:
    """P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ, symmetrised (:func:`joseph_form`, then
    :func:`symmetrise`); ``out`` receives P̂."""
    return symmetrise(joseph_form(P_check, K, G, R, I), out)


def short_update(P_check: np.ndarray, K: np.ndarray, GP: np.ndarray,
                 out: np.ndarray | None = None) -> np.ndarray:
    """P̂ = (I − K G) P̌ = P̌ − K (G P̌), given GP = G P̌, symmetrised.

    Right only for the optimal gain; cheaper than :func:`joseph_update`.
    """
    return symmetrise(P_check - dot(K, GP), out)


def expm(A: np.ndarray) -> np.ndarray:
    """Matrix exponential e^A by scaling and squaring a Taylor series (numpy only).

    Scales A by 2^-s until its 1-norm is below 0.5, sums the Taylor series to 18 terms
    (the remainder is then below 1e-17 of the result) and squares s times back.

    Parameters
    ----------
    A : numpy.ndarray, shape (n, n)

    Returns
    -------
    numpy.ndarray, shape (n, n)
    """
    A = np.asarray(A, dtype=float)
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

