"""Multivariate Gaussians: density, marginal, conditional, linear maps and products.

Chapter 02 of the course. Every function here is a small, direct transcription of one
formula from the lecture:

* the density :math:`\\mathcal N(x; \\mu, \\Sigma)` and its logarithm;
* marginalising a joint Gaussian (pick the blocks);
* conditioning a joint Gaussian on one of its parts, which is where the Schur complement
  appears:

  .. math::

      p(x \\mid y) = \\mathcal N\\big(\\mu_x + \\Sigma_{xy}\\Sigma_{yy}^{-1}(y - \\mu_y),\\;
      \\Sigma_{xx} - \\Sigma_{xy}\\Sigma_{yy}^{-1}\\Sigma_{xy}^T\\big);

* pushing a Gaussian through a linear map with additive noise, y = G x + n;
* the normalised product of two Gaussian densities in the same variable;
* the Schur complement itself and the block inverse it gives.

Inverses are never formed where a linear solve or a Cholesky factor does the job.
"""

from __future__ import annotations

import math

import numpy as np

from kalman_course.core import linalg
from kalman_course.core.validation import as_covariance, as_matrix, as_real_array, as_vector

__all__ = [
    "gaussian_pdf",
    "gaussian_logpdf",
    "marginal",
    "conditional",
    "linear_map",
    "joint_linear",
    "product",
    "schur_complement",
    "block_inverse",
]


# ---------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------

def _as_points(x, name: str, n: int) -> np.ndarray:
    """Return ``x`` as a finite array of shape (n,) or (N, n)."""
    arr = as_real_array(x, name)
    if arr.ndim == 1:
        return as_vector(arr, name, n)
    if arr.ndim == 2:
        return as_matrix(arr, name, ("N", n))
    raise ValueError(f"{name} must be one point of shape ({n},) or N points of shape (N, {n}), "
                     f"got shape {arr.shape}")


def _as_block_split(M, name: str, k) -> tuple[np.ndarray, int]:
    """Validate a square matrix ``M`` and a block size ``k`` with 0 < k < M.shape[0]."""
    M = as_matrix(M, name)
    if M.shape[0] != M.shape[1]:
        raise ValueError(f"{name} must be a square matrix, got shape {M.shape}")
    if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)):
        raise ValueError(f"k must be an integer block size, got {k!r}")
    p = M.shape[0]
    if not 0 < k < p:
        raise ValueError(f"k must satisfy 0 < k < {p} (the size of {name}), got {k}")
    return M, int(k)


# ---------------------------------------------------------------------------------------
# density
# ---------------------------------------------------------------------------------------

def gaussian_logpdf(x, mean, cov):
    """Log of the Gaussian density :math:`\\log \\mathcal N(x; \\mu, \\Sigma)`.

    .. math::

        \\log \\mathcal N(x; \\mu, \\Sigma) = -\\tfrac12\\big(n \\log 2\\pi + \\log|\\Sigma|
        + (x-\\mu)^T \\Sigma^{-1} (x-\\mu)\\big)

    computed from the Cholesky factor :math:`\\Sigma = L L^T`:
    :math:`\\log|\\Sigma| = 2\\sum_i \\log L_{ii}` and the quadratic form is
    :math:`\\|L^{-1}(x-\\mu)\\|^2`.

    Parameters
    ----------
    x : array_like, shape (n,) or (N, n)
        One point, or N points as rows.
    mean : array_like, shape (n,)
        Mean :math:`\\mu`.
    cov : array_like, shape (n, n)
        Covariance :math:`\\Sigma`, symmetric positive definite.

    Returns
    -------
    float or ndarray, shape (N,)
        The log density at each point.

    Raises
    ------
    ValueError
        If a shape does not match, or ``cov`` is not a symmetric positive-definite matrix.
    """
    mean = as_vector(mean, "mean")
    n = mean.shape[0]
    cov = as_covariance(cov, "cov", n, positive_definite=True)
    x = _as_points(x, "x", n)

    L = np.linalg.cholesky(cov)
    d = (x - mean).T                              # (n,) or (n, N)
    z = np.linalg.solve(L, d)                     # L z = x - mu
    mahalanobis_sq = np.sum(z * z, axis=0)
    log_det = 2.0 * np.sum(np.log(np.diag(L)))
    log_p = -0.5 * (n * math.log(2.0 * math.pi) + log_det + mahalanobis_sq)
    return float(log_p) if x.ndim == 1 else log_p


def gaussian_pdf(x, mean, cov):
    """Gaussian density :math:`\\mathcal N(x; \\mu, \\Sigma)`.

    Parameters
    ----------
    x : array_like, shape (n,) or (N, n)
        One point, or N points as rows.
    mean : array_like, shape (n,)
        Mean :math:`\\mu`.
    cov : array_like, shape (n, n)
        Covariance :math:`\\Sigma`, symmetric positive definite.

    Returns
    -------
    float or ndarray, shape (N,)
        The density at each point, ``exp(gaussian_logpdf(x, mean, cov))``.

    Raises
    ------
    ValueError
        As for :func:`gaussian_logpdf`.
    """
    log_p = gaussian_logpdf(x, mean, cov)
    return float(np.exp(log_p)) if np.ndim(log_p) == 0 else np.exp(log_p)


# ---------------------------------------------------------------------------------------
# marginal and conditional
# ---------------------------------------------------------------------------------------

def marginal(mean, cov, indices):
    """Marginal of a joint Gaussian over the components ``indices``.

    For :math:`[a; b] \\sim \\mathcal N([\\mu_a; \\mu_b], [[\\Sigma_{aa}, \\Sigma_{ab}],
    [\\Sigma_{ba}, \\Sigma_{bb}]])` the marginal is :math:`a \\sim \\mathcal N(\\mu_a,
    \\Sigma_{aa})`: integrating b out just drops its rows and columns.

    Parameters
    ----------
    mean : array_like, shape (n,)
        Joint mean.
    cov : array_like, shape (n, n)
        Joint covariance.
    indices : sequence of int, length k
        Which components form ``a``, in the order wanted (distinct, in ``range(n)``).

    Returns
    -------
    mean_a : ndarray, shape (k,)
        :math:`\\mu_a`.
    cov_aa : ndarray, shape (k, k)
        :math:`\\Sigma_{aa}`.

    Raises
    ------
    ValueError
        If shapes do not match, ``cov`` is not a symmetric positive semi-definite
        covariance, or ``indices`` is empty, repeats an index, is not made of integers, or
        is out of range.
    """
    mean = as_vector(mean, "mean")
    n = mean.shape[0]
    cov = as_covariance(cov, "cov", n, psd=True)
    try:
        idx = np.asarray(indices)
    except (TypeError, ValueError):          # a ragged list
        raise ValueError(f"indices must be a non-empty 1-D sequence of integers, got {indices!r}") from None
    if idx.ndim == 0:
        idx = idx.reshape(1)
    if idx.ndim != 1 or idx.size == 0:
        raise ValueError(f"indices must be a non-empty 1-D sequence of integers, got {indices!r}")
    if not np.issubdtype(idx.dtype, np.integer):
        raise ValueError(f"indices must be integers, got dtype {idx.dtype}")
    if np.any(idx < 0) or np.any(idx >= n):
        raise ValueError(f"indices must lie in range({n}), got {idx.tolist()}")
    if np.unique(idx).size != idx.size:
        raise ValueError(f"indices must not repeat a component, got {idx.tolist()}")
    return mean[idx].copy(), cov[np.ix_(idx, idx)].copy()


def conditional(mu_x, mu_y, Sigma_xx, Sigma_xy, Sigma_yy, y):
    """Condition a joint Gaussian of x and y on an observed value of y.

    With

    .. math::

        \\begin{bmatrix} x \\\\ y \\end{bmatrix} \\sim \\mathcal N\\left(
        \\begin{bmatrix} \\mu_x \\\\ \\mu_y \\end{bmatrix},
        \\begin{bmatrix} \\Sigma_{xx} & \\Sigma_{xy} \\\\ \\Sigma_{xy}^T & \\Sigma_{yy}
        \\end{bmatrix}\\right)

    the conditional is :math:`p(x \\mid y) = \\mathcal N(\\mu_{x|y}, \\Sigma_{x|y})` with

    .. math::

        \\mu_{x|y} = \\mu_x + \\Sigma_{xy}\\Sigma_{yy}^{-1}(y - \\mu_y), \\qquad
        \\Sigma_{x|y} = \\Sigma_{xx} - \\Sigma_{xy}\\Sigma_{yy}^{-1}\\Sigma_{xy}^T,

    the covariance being the Schur complement of :math:`\\Sigma_{yy}` in the joint
    covariance. This is the Kalman update with gain :math:`K = \\Sigma_{xy}\\Sigma_{yy}^{-1}`,
    computed by :func:`kalman_course.core.linalg.gain` (a linear solve with
    :math:`\\Sigma_{yy}`, or its closed form for one or two components; never a general
    inverse).

    Parameters
    ----------
    mu_x : array_like, shape (n,)
        Mean of x.
    mu_y : array_like, shape (m,)
        Mean of y.
    Sigma_xx : array_like, shape (n, n)
        Covariance of x.
    Sigma_xy : array_like, shape (n, m)
        Cross-covariance :math:`E[(x-\\mu_x)(y-\\mu_y)^T]`.
    Sigma_yy : array_like, shape (m, m)
        Covariance of y, symmetric positive definite.
    y : array_like, shape (m,)
        The observed value of y.

    Returns
    -------
    mean : ndarray, shape (n,)
        :math:`\\mu_{x|y}`.
    cov : ndarray, shape (n, n)
        :math:`\\Sigma_{x|y}`, symmetric.

    Raises
    ------
    ValueError
        If a shape does not match, ``Sigma_xx`` is not a symmetric positive
        semi-definite covariance, ``Sigma_yy`` is not symmetric positive definite, or the three blocks do not form
        a valid (positive semi-definite) joint covariance.
    """
    mu_x = as_vector(mu_x, "mu_x")
    mu_y = as_vector(mu_y, "mu_y")
    n, m = mu_x.shape[0], mu_y.shape[0]
    Sigma_xx = as_covariance(Sigma_xx, "Sigma_xx", n, psd=True)
    Sigma_xy = as_matrix(Sigma_xy, "Sigma_xy", (n, m))
    Sigma_yy = as_covariance(Sigma_yy, "Sigma_yy", m, positive_definite=True)
    y = as_vector(y, "y", m)

    # The Kalman update in other letters: gain K = Sigma_xy Sigma_yy^-1 (the kernel's
    # "G P" is Sigma_xy^T, its S is Sigma_yy), mean = mu_x + K (y - mu_y),
    # cov = Sigma_xx - K Sigma_xy^T.
    K = linalg.gain(Sigma_xy.T, Sigma_yy)                    # (n, m), by a solve or closed form
    mean = mu_x + K @ (y - mu_y)
    cov = linalg.short_update(Sigma_xx, K, Sigma_xy.T)

    smallest = np.linalg.eigvalsh(cov)[0]
    scale = max(float(np.max(np.abs(Sigma_xx))), 1e-300)
    if smallest < -1e-10 * scale:
        raise ValueError("Sigma_xx, Sigma_xy and Sigma_yy do not form a valid joint covariance: "
                         f"the Schur complement Sigma_xx - Sigma_xy Sigma_yy^-1 Sigma_xy^T has "
                         f"eigenvalue {smallest:.3g} < 0")
    return mean, cov


# ---------------------------------------------------------------------------------------
# linear maps
# ---------------------------------------------------------------------------------------

def linear_map(mu_x, Sigma_xx, G, R):
    """Moments of y = G x + n for x ~ N(mu_x, Sigma_xx) and independent n ~ N(0, R).

    .. math::

        \\mu_y = G\\mu_x, \\qquad \\Sigma_{yy} = G\\Sigma_{xx}G^T + R, \\qquad
        \\Sigma_{xy} = \\Sigma_{xx}G^T.

    Parameters
    ----------
    mu_x : array_like, shape (n,)
        Mean of x.
    Sigma_xx : array_like, shape (n, n)
        Covariance of x.
    G : array_like, shape (m, n)
        The linear map.
    R : array_like, shape (m, m)
        Covariance of the additive noise n. Nothing is inverted here, so R only has to
        be symmetric positive semi-definite (a zero R gives the noise-free map y = G x).

    Returns
    -------
    mu_y : ndarray, shape (m,)
        Mean of y.
    Sigma_yy : ndarray, shape (m, m)
        Covariance of y, symmetric.
    Sigma_xy : ndarray, shape (n, m)
        Cross-covariance of x and y.

    Raises
    ------
    ValueError
        If a shape does not match, or ``Sigma_xx`` or ``R`` is not a symmetric positive
        semi-definite covariance.
    """
    mu_x = as_vector(mu_x, "mu_x")
    n = mu_x.shape[0]
    Sigma_xx = as_covariance(Sigma_xx, "Sigma_xx", n, psd=True)
    G = as_matrix(G, "G", (None, n))
    m = G.shape[0]
    R = as_covariance(R, "R", m, psd=True)

    G_Sigma = G @ Sigma_xx                                   # G Sigma_xx, (m, n)
    mu_y = G @ mu_x
    Sigma_xy = G_Sigma.T                                     # Sigma_xx G^T (Sigma_xx symmetric)
    Sigma_yy = linalg.symmetrise(linalg.innovation_covariance(G_Sigma, G, R))   # G Sigma_xx G^T + R
    return mu_y, Sigma_yy, Sigma_xy


def joint_linear(mu_x, Sigma_xx, G, R):
    """Joint Gaussian of x and y = G x + n, stacked as [x; y].

    .. math::

        \\begin{bmatrix} x \\\\ y \\end{bmatrix} \\sim \\mathcal N\\left(
        \\begin{bmatrix} \\mu_x \\\\ G\\mu_x \\end{bmatrix},
        \\begin{bmatrix} \\Sigma_{xx} & \\Sigma_{xx}G^T \\\\ G\\Sigma_{xx} &
        G\\Sigma_{xx}G^T + R \\end{bmatrix}\\right)

    Parameters
    ----------
    mu_x : array_like, shape (n,)
        Mean of x.
    Sigma_xx : array_like, shape (n, n)
        Covariance of x.
    G : array_like, shape (m, n)
        The linear map.
    R : array_like, shape (m, m)
        Covariance of the additive noise (positive semi-definite).

    Returns
    -------
    mean : ndarray, shape (n + m,)
        Joint mean.
    cov : ndarray, shape (n + m, n + m)
        Joint covariance, symmetric.

    Raises
    ------
    ValueError
        As for :func:`linear_map`.
    """
    mu_y, Sigma_yy, Sigma_xy = linear_map(mu_x, Sigma_xx, G, R)      # validates the inputs
    mu_x = as_vector(mu_x, "mu_x")
    Sigma_xx = as_covariance(Sigma_xx, "Sigma_xx", mu_x.shape[0])
    mean = np.concatenate([mu_x, mu_y])
    cov = np.block([[Sigma_xx, Sigma_xy],
                    [Sigma_xy.T, Sigma_yy]])
    return mean, linalg.symmetrise(cov)


def product(mu_a, Sigma_a, mu_b, Sigma_b):
    """Normalised product of two Gaussian densities in the same variable.

    :math:`\\mathcal N(x; \\mu_a, \\Sigma_a)\\,\\mathcal N(x; \\mu_b, \\Sigma_b)
    \\propto \\mathcal N(x; \\mu, \\Sigma)` with
    :math:`\\Sigma = (\\Sigma_a^{-1} + \\Sigma_b^{-1})^{-1}` and
    :math:`\\mu = \\Sigma(\\Sigma_a^{-1}\\mu_a + \\Sigma_b^{-1}\\mu_b)`.

    Computed in the equivalent "gain" form, which needs one solve with
    :math:`\\Sigma_a + \\Sigma_b` (the closed form for n <= 2) and no general inverse:

    .. math::

        K = \\Sigma_a(\\Sigma_a + \\Sigma_b)^{-1}, \\qquad
        \\mu = \\mu_a + K(\\mu_b - \\mu_a), \\qquad \\Sigma = \\Sigma_a - K\\Sigma_a.

    (This is the Kalman update with G = I: a fusion of two estimates of the same x.)

    Parameters
    ----------
    mu_a : array_like, shape (n,)
        Mean of the first density.
    Sigma_a : array_like, shape (n, n)
        Covariance of the first density, symmetric positive definite.
    mu_b : array_like, shape (n,)
        Mean of the second density.
    Sigma_b : array_like, shape (n, n)
        Covariance of the second density, symmetric positive definite.

    Returns
    -------
    mean : ndarray, shape (n,)
        :math:`\\mu`.
    cov : ndarray, shape (n, n)
        :math:`\\Sigma`, symmetric.

    Raises
    ------
    ValueError
        If a shape does not match or a covariance is not symmetric positive definite.
    """
    mu_a = as_vector(mu_a, "mu_a")
    n = mu_a.shape[0]
    Sigma_a = as_covariance(Sigma_a, "Sigma_a", n, positive_definite=True)
    mu_b = as_vector(mu_b, "mu_b", n)
    Sigma_b = as_covariance(Sigma_b, "Sigma_b", n, positive_definite=True)

    # the Kalman update with G = I: "G P" is Sigma_a and S = Sigma_a + Sigma_b
    K = linalg.gain(Sigma_a, Sigma_a + Sigma_b)
    mean = mu_a + K @ (mu_b - mu_a)
    cov = linalg.short_update(Sigma_a, K, Sigma_a)
    return mean, cov


# ---------------------------------------------------------------------------------------
# Schur complement and block inverse
# ---------------------------------------------------------------------------------------

def schur_complement(M, k):
    """Schur complement of the lower-right block D in M = [[A, B], [C, D]].

    .. math::

        M / D = A - B D^{-1} C

    computed with a linear solve with D.

    Parameters
    ----------
    M : array_like, shape (p, p)
        The partitioned square matrix.
    k : int
        Size of the upper-left block A (0 < k < p); D is (p - k, p - k).

    Returns
    -------
    ndarray, shape (k, k)
        :math:`A - B D^{-1} C`.

    Raises
    ------
    ValueError
        If ``M`` is not a finite square matrix, ``k`` is out of range, or D is singular.
    """
    M, k = _as_block_split(M, "M", k)
    A, B = M[:k, :k], M[:k, k:]
    C, D = M[k:, :k], M[k:, k:]
    try:
        D_inv_C = np.linalg.solve(D, C)
    except np.linalg.LinAlgError:
        raise ValueError("M must have an invertible lower-right block D = M[k:, k:] "
                         "(it is singular)") from None
    return A - B @ D_inv_C


def block_inverse(M, k):
    """Inverse of M = [[A, B], [C, D]] assembled from its block factorisation.

    With the Schur complement :math:`S = A - B D^{-1} C` of D,

    .. math::

        M^{-1} = \\begin{bmatrix} S^{-1} & -S^{-1} B D^{-1} \\\\
        -D^{-1} C S^{-1} & D^{-1} + D^{-1} C S^{-1} B D^{-1} \\end{bmatrix}.

    Only the blocks D (p - k square) and S (k square) are solved with; M itself is never
    inverted directly. Where D is closer to singular than A (its smallest singular value
    is the smaller), the same factorisation is taken with the roles of the blocks swapped,
    the Schur complement of A; solving with a nearly singular D would lose the digits of a
    well-conditioned M (cond(M) = 7 with cond(D) = 2e15 gave errors of 0.1 on entries of 2).

    Parameters
    ----------
    M : array_like, shape (p, p)
        The partitioned square matrix.
    k : int
        Size of the upper-left block A (0 < k < p).

    Returns
    -------
    ndarray, shape (p, p)
        :math:`M^{-1}`.

    Raises
    ------
    ValueError
        If ``M`` is not a finite square matrix, ``k`` is out of range, or D or the Schur
        complement S is singular (then M is singular or this partition cannot invert it).
    """
    M, k = _as_block_split(M, "M", k)
    p = M.shape[0]
    sigma_min = [np.linalg.svd(X, compute_uv=False)[-1] for X in (M[:k, :k], M[k:, k:])]
    if sigma_min[1] < sigma_min[0]:
        # pivot on A: the factorisation of P M Pᵀ (blocks swapped), whose inverse is P M⁻¹ Pᵀ
        order = np.r_[k:p, 0:k]
        back = np.argsort(order)
        return _block_inverse_on_D(M[np.ix_(order, order)], p - k)[np.ix_(back, back)]
    return _block_inverse_on_D(M, k)


def _block_inverse_on_D(M, k):
    """:func:`block_inverse`'s formula, solving with D = M[k:, k:] and the Schur complement of D."""
    B, C, D = M[:k, k:], M[k:, :k], M[k:, k:]
    S = schur_complement(M, k)
    try:
        D_inv = np.linalg.solve(D, np.eye(D.shape[0]))
        S_inv = np.linalg.solve(S, np.eye(k))      # S: the Schur complement here
    except np.linalg.LinAlgError:
        raise ValueError("M must have an invertible Schur complement A - B D^-1 C "
                         "(it is singular, so M is singular)") from None
    D_inv_C = D_inv @ C                      # (p-k, k)
    B_D_inv = B @ D_inv                      # (k, p-k)

    top_left = S_inv
    top_right = -S_inv @ B_D_inv
    bottom_left = -D_inv_C @ S_inv
    bottom_right = D_inv + D_inv_C @ S_inv @ B_D_inv
    return np.block([[top_left, top_right],
                     [bottom_left, bottom_right]])
