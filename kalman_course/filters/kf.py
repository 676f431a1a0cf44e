"""The linear Kalman filter: predict, update, and a runner that records every step.

Chapter 03 of the course. Lecture notation: prior :math:`\\check x, \\check P`
(``x_check``, ``P_check``), posterior :math:`\\hat x, \\hat P` (``x_hat``, ``P_hat``).

Motion model :math:`x_k = F x_{k-1} + v_k + B w_k`, :math:`w_k \\sim \\mathcal N(0, Q)`;
observation model :math:`y_k = G x_k + C n_k`, :math:`n_k \\sim \\mathcal N(0, R)`.
The five equations:

.. math::

    \\check x_k &= F \\hat x_{k-1} + v_k \\\\
    \\check P_k &= F \\hat P_{k-1} F^T + B Q B^T \\\\
    K_k &= \\check P_k G^T (G \\check P_k G^T + C R C^T)^{-1} \\\\
    \\hat x_k &= \\check x_k + K_k (y_k - G \\check x_k) \\\\
    \\hat P_k &= (I - K_k G) \\check P_k

The public functions validate their inputs (a ``ValueError`` names the argument and what
was expected; a covariance must be symmetric positive semi-definite, R and S positive
definite). :func:`run_kf` validates once and then runs the same equations through
private, unvalidated kernels (built on :mod:`kalman_course.core.linalg`, where each
formula is written once), so a long run costs no more per step than the maths. The
single steps :func:`kf_predict` and :func:`kf_update` validate once too: a model matrix
already validated, or a mean or covariance that a step returned, is recognised by its
bytes and not checked again (anything changed in place is checked again).

Numerics. The gain is solved with the Cholesky factor of S (S = L Lᵀ), never through an
explicit S⁻¹, whose gain is not backward stable and turns an ill-conditioned S into an
indefinite P̂ (see :func:`kalman_course.core.linalg.whitened_gain`). The standard form
:math:`\\hat P = (I - K G) \\check P` is computed as :math:`\\check P - Z^T Z` with
:math:`Z = L^{-1} G \\check P`, whose round-off is of order ε‖P̌‖ whatever cond(S) is.
The Joseph form, the default (``joseph=True``), stays accurate further: where one update
shrinks a variance by more than about 1e12 (a vague prior meeting a very precise sensor),
ε‖P̌‖ is no longer small against P̂'s smallest eigenvalues, and the standard form
(``joseph=False``) returns them as 0 or worse. ``tests/test_kf.py`` checks both forms
against 50-digit arithmetic on models with cond(S) and cond(P̌) up to 3e12, and the Joseph
form also at cond(P̌) 1e16 and on a variance shrunk by 1e18. A step whose result overflows
(a covariance too large for float64) raises instead of returning inf or NaN.

Smoothing. :func:`rts_smooth` runs the Rauch–Tung–Striebel backward pass over the record
of a run: the estimate of each step given *all* the measurements, before and after it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from kalman_course.core import linalg
from kalman_course.core.validation import (SYMMETRY_RTOL, as_covariance, as_flag, as_matrix,
                                           as_observation_noise, as_process_noise, as_real_array,
                                           as_rows, as_vector)

__all__ = [
    "kf_predict",
    "innovation_covariance",
    "kf_gain",
    "kf_update",
    "KFUpdate",
    "run_kf",
    "KFHistory",
    "rts_smooth",
    "RTSResult",
]


class KFUpdate(NamedTuple):
    """Everything one Kalman update computes.

    Attributes
    ----------
    x_hat : ndarray, shape (n,)
        Posterior mean :math:`\\hat x`.
    P_hat : ndarray, shape (n, n)
        Posterior covariance :math:`\\hat P`, symmetric.
    innovation : ndarray, shape (m,)
        :math:`y - G \\check x`.
    S : ndarray, shape (m, m)
        Innovation covariance :math:`G \\check P G^T + C R C^T` (symmetric up to
        round-off; :func:`innovation_covariance` returns it exactly symmetrised).
    K : ndarray, shape (n, m)
        Kalman gain :math:`\\check P G^T S^{-1}`.
    """

    x_hat: np.ndarray
    P_hat: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    K: np.ndarray


@dataclass(frozen=True, eq=False)
class KFHistory:
    """The record of a :func:`run_kf` run over N steps.

    Attributes
    ----------
    x_check : ndarray, shape (N, n)
        Prior means :math:`\\check x_k`.
    P_check : ndarray, shape (N, n, n)
        Prior covariances :math:`\\check P_k`.
    x_hat : ndarray, shape (N, n)
        Posterior means :math:`\\hat x_k`.
    P_hat : ndarray, shape (N, n, n)
        Posterior covariances :math:`\\hat P_k`.
    innovation : ndarray, shape (N, m)
        Innovations :math:`y_k - G \\check x_k`; NaN rows where there was no measurement.
    S : ndarray, shape (N, m, m)
        Innovation covariances :math:`S_k`; NaN where there was no measurement.
    K : ndarray, shape (N, n, m)
        Kalman gains :math:`K_k`; NaN where there was no measurement.
    """

    x_check: np.ndarray
    P_check: np.ndarray
    x_hat: np.ndarray
    P_hat: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    K: np.ndarray


# ---------------------------------------------------------------------------------------
# unvalidated kernels: the equations, nothing else
# ---------------------------------------------------------------------------------------

def _predict(x_hat, P_hat, F, BQBt, v, P_out=None):
    """The prediction equations; returns (x̌, P̌), P̌ written into ``P_out`` if given."""
    x_check = F.dot(x_hat)                                         # x̌ = F x̂
    if v is not None:
        x_check += v                                               #      + v
    P_check = linalg.predict_covariance(P_hat, F, BQBt, P_out)     # P̌ = F P̂ Fᵀ + B Q Bᵀ
    return x_check, P_check


def _update(x_check, P_check, y, G, CRCt, joseph, I, P_out=None):
    """The update equations; returns (x̂, P̂, innovation, S, K), P̂ written into ``P_out`` if
    given. ``I`` is the (n, n) identity, made once by the caller (``np.eye`` costs as much
    as a matrix product here)."""
    innovation = y - G.dot(x_check)                                # e = y − G x̌
    GP = G.dot(P_check)                                            # G P̌, (m, n)
    S = linalg.innovation_covariance(GP, G, CRCt)                  # S = G P̌ Gᵀ + C R Cᵀ
    K, Z = linalg.whitened_gain(GP, S)                             # K = P̌ Gᵀ S⁻¹, Z = L⁻¹ G P̌
    x_hat = x_check + K.dot(innovation)                            # x̂ = x̌ + K e
    if joseph or Z is None:                      # P̂ = (I − K G) P̌ (I − K G)ᵀ + K C R Cᵀ Kᵀ
        # (also when S has no Cholesky factor in float64: K then is an LU solve's, and the
        # Joseph form is right for any gain)
        P_hat = linalg.joseph_update(P_check, K, G, CRCt, I, P_out)
    else:                                        # P̂ = P̌ − K G P̌ = P̌ − Zᵀ Z
        P_hat = linalg.whitened_update(P_check, Z, P_out)
    return x_hat, P_hat, innovation, S, K


# ---------------------------------------------------------------------------------------
# validate once: the model's matrices and the steps' own results, known by content
# ---------------------------------------------------------------------------------------

# A learner's loop calls kf_predict and kf_update with the same F, Q, G, R at every step,
# and hands each step the covariance the other one returned. Checking those again costs
# more than the step's arithmetic (Q of the CV model is singular, so its check takes
# eigenvalues; every covariance costs a Cholesky factorisation). Validation depends on an
# argument's dtype, shape and values only, so a float64 array is recognised by its bytes:
#
# - a model matrix whose bytes equal those of one that passed is not checked again; the
#   memo keeps a private, read-only copy of the validated result;
# - a mean or covariance whose bytes equal those of one that a step returned is not
#   checked either: like run_kf, which validates x0 and P0 and then trusts what it
#   computes from validated inputs, the steps trust what they returned.
#
# A caller who writes into an array changes its bytes, so it is validated again.
_MODEL_MEMO: dict[tuple, np.ndarray] = {}
_MODEL_MEMO_SIZE = 64
_RETURNED: dict[tuple, None] = {}                  # keys only, oldest first
_RETURNED_SIZE = 32
_IDENTITY: dict[int, np.ndarray] = {}


def _content(value):
    """(shape, bytes) of a float64 ndarray, None for None, False for anything else."""
    if value is None:
        return None
    if type(value) is np.ndarray and value.dtype == np.float64:
        return value.shape, value.tobytes()
    return False


def _validated_model(kind, value, jacobian, dim, validate):
    """``validate(value, jacobian, dim)``, or its remembered result for the same content.

    Parameters
    ----------
    kind : str
        Which argument pair this is (part of the key: the same bytes may be valid as one
        and not as another).
    value, jacobian : array_like or None
        The arguments validated together (Q and B, R and C, or F and None).
    dim : int or tuple
        The dimensions they must match.
    validate : callable
        The :mod:`kalman_course.core.validation` call; it raises the ValueError naming
        the argument.

    Returns
    -------
    numpy.ndarray
        The validated (and, for Q with B or R with C, mapped) matrix; read-only when it
        comes from the memo.
    """
    content, jacobian_content = _content(value), _content(jacobian)
    if content is False or jacobian_content is False:    # lists, other dtypes: every time
        return validate(value, jacobian, dim)
    key = (kind, dim, content, jacobian_content)
    result = _MODEL_MEMO.get(key)
    if result is None:
        result = np.array(validate(value, jacobian, dim))    # a copy the caller cannot touch
        result.flags.writeable = False
        if len(_MODEL_MEMO) >= _MODEL_MEMO_SIZE:
            _MODEL_MEMO.clear()
        _MODEL_MEMO[key] = result
    return result


def _transition(F, _, n):
    """F validated as the (n, n) motion Jacobian (the signature :func:`_validated_model` calls)."""
    return as_matrix(F, "F", (n, n))


def _observation_jacobian(G, _, shape):
    """G validated as the (m, n) observation Jacobian (the signature :func:`_validated_model` calls)."""
    return as_matrix(G, "G", shape)


def _recognised(value, ndim, shape=None):
    """True if ``value`` is a float64 array with ``ndim`` axes (and ``shape``, if given)
    whose shape and bytes are those of a mean or covariance that a step returned."""
    return (type(value) is np.ndarray and value.dtype == np.float64 and value.ndim == ndim
            and (shape is None or value.shape == shape)
            and (value.shape, value.tobytes()) in _RETURNED)


def _returned(value):
    """Remember a mean or covariance that a step returns, by shape and bytes; returns it."""
    _RETURNED[(value.shape, value.tobytes())] = None
    if len(_RETURNED) > _RETURNED_SIZE:
        del _RETURNED[next(iter(_RETURNED))]
    return value


def _finite(step: str, **results):
    """Raise if a step's result overflowed: finite inputs can still give inf (a covariance
    near 1e308 squared by F), and an inf or NaN must never reach the next step unnoticed."""
    for name, value in results.items():
        # the sum of finite entries is finite unless it overflows, and then the entry-wise
        # test decides; a Python sum of the listed entries costs a fifth of np.isfinite().all()
        if not math.isfinite(sum(value.ravel().tolist())) and not np.isfinite(value).all():
            raise ValueError(f"{step}: {name} overflowed (inf or NaN from finite inputs; its entries exceed "
                             f"float64's range, about 1e308): rescale the state's units or its covariance")


def _identity(n):
    """The (n, n) identity, made once per n and read-only."""
    I = _IDENTITY.get(n)
    if I is None:
        I = _IDENTITY[n] = np.eye(n)
        I.flags.writeable = False
    return I


# ---------------------------------------------------------------------------------------
# public, validated steps
# ---------------------------------------------------------------------------------------

def kf_predict(x_hat, P_hat, F, Q, B=None, v=None):
    """Kalman prediction: propagate the posterior through the motion model.

    .. math::

        \\check x = F \\hat x + v, \\qquad \\check P = F \\hat P F^T + B Q B^T

    Parameters
    ----------
    x_hat : array_like, shape (n,)
        Posterior mean at the previous step, :math:`\\hat x_{k-1}`.
    P_hat : array_like, shape (n, n)
        Posterior covariance at the previous step, :math:`\\hat P_{k-1}`.
    F : array_like, shape (n, n)
        Motion (state-transition) Jacobian.
    Q : array_like, shape (n, n) or (q, q)
        Process-noise covariance; (n, n) when ``B`` is None, else (q, q). It may be
        singular (for example the constant-velocity model's Q).
    B : array_like, shape (n, q), optional
        Process-noise Jacobian; None means the identity (Q already in state space).
    v : array_like, shape (n,), optional
        Known input already mapped into the state space (for example a control term).

    Returns
    -------
    x_check : ndarray, shape (n,)
        Prior mean :math:`\\check x_k`.
    P_check : ndarray, shape (n, n)
        Prior covariance :math:`\\check P_k`, symmetric.

    Raises
    ------
    ValueError
        If an argument is not finite or a shape does not match, or ``P_hat`` or ``Q`` is
        not a symmetric positive semi-definite covariance.
    """
    if not _recognised(x_hat, 1):
        x_hat = as_vector(x_hat, "x_hat")
    n = x_hat.shape[0]
    if not _recognised(P_hat, 2, (n, n)):
        P_hat = as_covariance(P_hat, "P_hat", n, psd=True)
    F = _validated_model("F", F, None, n, _transition)
    BQBt = _validated_model("Q", Q, B, n, as_process_noise)
    if v is not None:
        v = as_vector(v, "v", n)
    x_check, P_check = _predict(x_hat, P_hat, F, BQBt, v)
    _finite("kf_predict", x_check=x_check, P_check=P_check)
    return _returned(x_check), _returned(P_check)


def innovation_covariance(P_check, G, R, C=None):
    """Innovation covariance :math:`S = G \\check P G^T + C R C^T`.

    Parameters
    ----------
    P_check : array_like, shape (n, n)
        Prior covariance :math:`\\check P`.
    G : array_like, shape (m, n)
        Observation Jacobian.
    R : array_like, shape (m, m) or (r, r)
        Observation-noise covariance, symmetric positive definite; (m, m) when ``C`` is
        None, else (r, r).
    C : array_like, shape (m, r), optional
        Observation-noise Jacobian; None means the identity.

    Returns
    -------
    ndarray, shape (m, m)
        :math:`S`, symmetric.

    Raises
    ------
    ValueError
        If an argument is not finite or a shape does not match, ``P_check`` is not a
        symmetric positive semi-definite covariance, or ``R`` is not symmetric positive
        definite.
    """
    P_check = as_covariance(P_check, "P_check", psd=True)
    G = as_matrix(G, "G", (None, P_check.shape[0]))
    CRCt = as_observation_noise(R, C, G.shape[0])
    return linalg.symmetrise(linalg.innovation_covariance(G.dot(P_check), G, CRCt))


def kf_gain(P_check, G, S):
    """Kalman gain :math:`K = \\check P G^T S^{-1}`.

    Since :math:`\\check P` and S are symmetric, :math:`K^T = S^{-1} G \\check P` is
    solved, never multiplied by an inverse: one measured component is a division, two or
    three a Cholesky factor of S written out (cheaper than a LAPACK call), more an LU solve
    (:func:`kalman_course.core.linalg.gain`). K is the exact gain of an S and a
    :math:`\\check P G^T` perturbed by a few ε entry by entry, however ill-conditioned S is.

    Parameters
    ----------
    P_check : array_like, shape (n, n)
        Prior covariance :math:`\\check P`.
    G : array_like, shape (m, n)
        Observation Jacobian.
    S : array_like, shape (m, m)
        Innovation covariance, symmetric positive definite.

    Returns
    -------
    ndarray, shape (n, m)
        The gain K.

    Raises
    ------
    ValueError
        If an argument is not finite or a shape does not match, ``P_check`` is not a
        symmetric positive semi-definite covariance, or ``S`` is not symmetric positive
        definite.
    """
    P_check = as_covariance(P_check, "P_check", psd=True)
    G = as_matrix(G, "G", (None, P_check.shape[0]))
    S = as_covariance(S, "S", G.shape[0], positive_definite=True)
    return linalg.gain(G.dot(P_check), S)


def kf_update(x_check, P_check, y, G, R, C=None, joseph=True):
    """Kalman update: condition the prior on the measurement y.

    .. math::

        e = y - G \\check x, \\quad S = G \\check P G^T + C R C^T, \\quad
        K = \\check P G^T S^{-1}, \\quad \\hat x = \\check x + K e,

    and either the Joseph form :math:`\\hat P = (I - K G) \\check P (I - K G)^T + K C R C^T K^T`
    (the default), which stays symmetric positive semi-definite even for a sub-optimal K, or
    the standard form :math:`\\hat P = (I - K G) \\check P`. Both are symmetrised.

    K is solved with the Cholesky factor L of S (S = L Lᵀ), and the standard form is
    computed as :math:`\\check P - Z^T Z` with :math:`Z = L^{-1} G \\check P` (equal to
    :math:`K G \\check P`): its round-off is of order ε‖P̌‖ however ill-conditioned S is.
    That is why the Joseph form, whose round-off scales with P̂, is the default: where one
    update shrinks a variance by more than about 1e12, ε‖P̌‖ is a sizeable part of P̂'s
    smallest eigenvalues (a prior of 1e8 meeting a measurement of variance 1e-10 gives 0
    in the standard form, 1e-10 in the Joseph form). (If S has no Cholesky factor in
    float64, K comes from an LU solve and P̂ from the Joseph form.)

    Parameters
    ----------
    x_check : array_like, shape (n,)
        Prior mean :math:`\\check x`.
    P_check : array_like, shape (n, n)
        Prior covariance :math:`\\check P`.
    y : array_like, shape (m,)
        The measurement.
    G : array_like, shape (m, n)
        Observation Jacobian.
    R : array_like, shape (m, m) or (r, r)
        Observation-noise covariance, symmetric positive definite; (m, m) when ``C`` is
        None, else (r, r).
    C : array_like, shape (m, r), optional
        Observation-noise Jacobian; None means the identity.
    joseph : bool, default True
        The Joseph form for the posterior covariance; False: the standard form (see above
        for when it matters).

    Returns
    -------
    KFUpdate
        Named tuple ``(x_hat, P_hat, innovation, S, K)`` with shapes (n,), (n, n), (m,),
        (m, m), (n, m).

    Raises
    ------
    ValueError
        If an argument is not finite or a shape does not match (``y`` fixes m),
        ``P_check`` is not a symmetric positive semi-definite covariance, ``R`` is not
        symmetric positive definite, or ``joseph`` is not a bool.
    """
    if not _recognised(x_check, 1):
        x_check = as_vector(x_check, "x_check")
    n = x_check.shape[0]
    if not _recognised(P_check, 2, (n, n)):
        P_check = as_covariance(P_check, "P_check", n, psd=True)
    y = as_vector(y, "y")
    m = y.shape[0]
    G = _validated_model("G", G, None, (m, n), _observation_jacobian)
    CRCt = _validated_model("R", R, C, m, as_observation_noise)
    joseph = as_flag(joseph, "joseph")
    x_hat, P_hat, innovation, S, K = _update(x_check, P_check, y, G, CRCt, joseph, _identity(n))
    _finite("kf_update", x_hat=x_hat, P_hat=P_hat)
    return KFUpdate(_returned(x_hat), _returned(P_hat), innovation, S, K)


# ---------------------------------------------------------------------------------------
# the runner
# ---------------------------------------------------------------------------------------

def run_kf(x0, P0, F, Q, G, R, ys, *, B=None, vs=None, joseph=True):
    """Run the Kalman filter over a sequence of measurements and record every step.

    Convention (as in the lecture): ``x0, P0`` are the *prior* at step 0, so step 0 is an
    update only; every step k ≥ 1 first predicts from the posterior of step k − 1 and
    then updates with ``ys[k]``. A row of ``ys`` that is entirely NaN means "no measurement
    at this step": the posterior equals the prior and that step's innovation, S and K
    rows are NaN.

    Inputs are validated once, up front; the loop then runs the bare equations.

    Parameters
    ----------
    x0 : array_like, shape (n,)
        Prior mean at step 0, :math:`\\check x_0`.
    P0 : array_like, shape (n, n)
        Prior covariance at step 0, :math:`\\check P_0`.
    F : array_like, shape (n, n)
        Motion Jacobian (time-invariant).
    Q : array_like, shape (n, n) or (q, q)
        Process-noise covariance; (q, q) when ``B`` is given.
    G : array_like, shape (m, n)
        Observation Jacobian (time-invariant).
    R : array_like, shape (m, m)
        Observation-noise covariance, symmetric positive definite.
    ys : array_like, shape (N, m)
        Measurements, one row per step; an all-NaN row is a missing measurement. A scalar
        series must be given as a column, ``ys[:, None]``.
    B : array_like, shape (n, q), optional
        Process-noise Jacobian; None means the identity.
    vs : array_like, shape (N, n), optional
        Known inputs in state space: ``vs[k]`` is added in the prediction of step k.
        ``vs[0]`` is not used (there is no prediction at step 0).
    joseph : bool, default True
        The Joseph form of the covariance update; False: the standard form, computed as in
        :func:`kf_update`, which says when the Joseph form is the accurate choice.

    Returns
    -------
    KFHistory
        Priors, posteriors, innovations, their covariances and the gains, one row per
        step.

    Raises
    ------
    ValueError
        If an argument is not finite or a shape does not match, ``P0`` or ``Q`` is not a
        symmetric positive semi-definite covariance, ``R`` is not symmetric positive
        definite, ``ys`` has a row that is only partly NaN or holds inf, or ``joseph`` is
        not a bool.
    """
    x0 = as_vector(x0, "x0")
    n = x0.shape[0]
    P0 = as_covariance(P0, "P0", n, psd=True)
    F = as_matrix(F, "F", (n, n))
    BQBt = as_process_noise(Q, B, n)
    G = as_matrix(G, "G", (None, n))
    m = G.shape[0]
    CRCt = as_observation_noise(R, None, m)
    ys = as_real_array(ys, "ys")
    if ys.ndim == 1 and m == 1:
        raise ValueError(f"ys must have shape (N, 1), one measurement row per step, got "
                         f"shape {ys.shape}; reshape a 1-D series with ys[:, None]")
    ys = as_matrix(ys, "ys", ("N", m), missing_rows=True)
    N = ys.shape[0]
    measured = ~np.isnan(ys[:, 0])                    # rows are all NaN or all finite
    if vs is not None:
        vs = as_matrix(vs, "vs", (N, n))
    joseph = as_flag(joseph, "joseph")

    x_check = np.empty((N, n))
    P_check = np.empty((N, n, n))
    x_hat = np.empty((N, n))
    P_hat = np.empty((N, n, n))
    innovation = np.full((N, m), np.nan)
    S = np.full((N, m, m), np.nan)
    K = np.full((N, n, m), np.nan)
    rows = list(ys)
    inputs = [None] * N if vs is None else list(vs)
    I = np.eye(n)

    # The covariances are symmetrised straight into their history rows (saves a copy per
    # step); P then is that row, which nothing writes to again.
    x, P = x0, P0                                       # prior at step 0
    P_check[0] = P0
    for k, has_measurement in enumerate(measured.tolist()):
        if k > 0:
            x, P = _predict(x, P, F, BQBt, inputs[k], P_check[k])
        x_check[k] = x
        if has_measurement:                             # else: posterior = prior, NaN rows
            x, P, innovation[k], S[k], K[k] = _update(x, P, rows[k], G, CRCt, joseph, I,
                                                      P_hat[k])
        else:
            P_hat[k] = P
        x_hat[k] = x

    bad = ~(np.isfinite(P_hat).all(axis=(1, 2)) & np.isfinite(x_hat).all(axis=1))
    if bad.any():
        _finite(f"run_kf, step {int(np.argmax(bad))}", x_hat=x_hat[bad][0], P_hat=P_hat[bad][0])
    return KFHistory(x_check=x_check, P_check=P_check, x_hat=x_hat, P_hat=P_hat,
                     innovation=innovation, S=S, K=K)


# ---------------------------------------------------------------------------------------
# the Rauch–Tung–Striebel smoother
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class RTSResult:
    """What :func:`rts_smooth` returns for a run of N steps.

    Attributes
    ----------
    x_smooth : ndarray, shape (N, n)
        Smoothed means :math:`\\tilde x_k`, the estimate of step k given all N measurements.
    P_smooth : ndarray, shape (N, n, n)
        Smoothed covariances :math:`\\tilde P_k`, symmetric.
    C : ndarray, shape (N - 1, n, n)
        Smoother gains :math:`C_k = \\hat P_k F_k^T \\check P_{k+1}^{-1}`, k = 0 … N − 2.
    """

    x_smooth: np.ndarray
    P_smooth: np.ndarray
    C: np.ndarray


#: Largest relative difference between a recorded prior covariance and F P̂ Fᵀ + B Q Bᵀ
#: recomputed from the record, when :func:`rts_smooth` is given Q (round-off is ~1e-16).
RTS_CONSISTENCY_RTOL = 1e-8


def _history_field(history, field: str):
    """``history.<field>``, or a ValueError saying what ``history`` must be."""
    if not hasattr(history, field):
        raise ValueError(f"history must be the KFHistory that run_kf returns (or a record with x_check, "
                         f"P_check, x_hat and P_hat), got {type(history).__name__} without {field!r}")
    return getattr(history, field)


def _symmetric_rows(P: np.ndarray, name: str) -> None:
    """Raise ValueError naming the first matrix of the stack ``P`` (N, n, n) that is not symmetric."""
    asym = np.abs(P - np.swapaxes(P, -1, -2)).max(axis=(-2, -1))
    scale = np.maximum(np.abs(P).max(axis=(-2, -1)), 1e-300)
    bad = asym > SYMMETRY_RTOL * scale
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"{name}[{k}] must be symmetric, max |P - P.T| = {asym[k]:.3g}")


def _transitions(F, N: int, n: int) -> np.ndarray:
    """F as the stack (N − 1, n, n) of F_k (step k to k + 1): one (n, n) matrix repeated, or a stack."""
    arr = as_real_array(F, "F")
    if arr.ndim != 3:
        F = as_matrix(F, "F", (n, n))
        return np.broadcast_to(F, (max(N - 1, 0), n, n))
    if arr.shape[0] != N - 1:
        raise ValueError(f"F must be one ({n}, {n}) matrix or a stack of N − 1 = {N - 1} matrices, F[k] "
                         f"taking step k to step k + 1 (history has N = {N} steps), got shape {arr.shape}")
    return as_rows(arr, "F", (n, n), N - 1, count="N − 1")


def _check_priors(P_hat, P_check, F, BQBt) -> None:
    """Raise if a recorded prior covariance P̌_{k+1} is not F_k P̂_k F_kᵀ + B Q Bᵀ: the F or Q
    given to the smoother is then not the one the filter ran with."""
    predicted = np.matmul(np.matmul(F, P_hat[:-1]), np.swapaxes(F, -1, -2)) + BQBt
    scale = np.maximum(np.abs(P_check[1:]).max(axis=(-2, -1)), 1e-300)
    off = np.abs(predicted - P_check[1:]).max(axis=(-2, -1)) / scale
    bad = off > RTS_CONSISTENCY_RTOL
    if bad.any():
        k = int(np.argmax(bad))
        raise ValueError(f"F and Q do not match the filter's run: history.P_check[{k + 1}] differs from "
                         f"F P_hat[{k}] Fᵀ + B Q Bᵀ by {off[k]:.3g} relative (more than round-off); pass "
                         "the F, Q (and B) the filter used")


def rts_smooth(history, F, Q=None, *, B=None) -> RTSResult:
    """Rauch–Tung–Striebel smoother: the backward pass over a Kalman filter's record.

    From the last step backwards, k = N − 2, …, 0:

    .. math::

        C_k &= \\hat P_k F_k^T \\check P_{k+1}^{-1} \\\\
        \\tilde x_k &= \\hat x_k + C_k (\\tilde x_{k+1} - \\check x_{k+1}) \\\\
        \\tilde P_k &= \\hat P_k + C_k (\\tilde P_{k+1} - \\check P_{k+1}) C_k^T

    starting from the filter's last posterior, :math:`\\tilde x_{N-1} = \\hat x_{N-1}`,
    :math:`\\tilde P_{N-1} = \\hat P_{N-1}`. The priors x̌_{k+1}, P̌_{k+1} are the record's
    own (``history.x_check[k + 1]``, the prediction of step k + 1 from step k, known inputs
    included), not predicted again, so the smoother uses exactly the filter's numbers.
    C_k is solved from :math:`\\check P_{k+1} C_k^T = F_k \\hat P_k` (P̌ and P̂ are
    symmetric), never through an inverse, and each P̃_k is symmetrised. A step without a
    measurement needs nothing special: its posterior is its prior.

    Parameters
    ----------
    history : KFHistory
        The record :func:`run_kf` returns (or any record with ``x_check`` and ``x_hat``
        (N, n), ``P_check`` and ``P_hat`` (N, n, n), in that convention: row k holds the
        prior and the posterior of step k).
    F : array_like, shape (n, n) or (N - 1, n, n)
        Motion Jacobian the filter used: one matrix (as :func:`run_kf` takes it), or one
        per step, ``F[k]`` taking step k to step k + 1.
    Q : array_like, shape (n, n) or (q, q), optional
        The filter's process-noise covariance ((q, q) with ``B``). Not needed by the
        equations; if given, every recorded P̌_{k+1} is checked against F_k P̂_k F_kᵀ + B Q Bᵀ
        (relative tolerance :data:`RTS_CONSISTENCY_RTOL`), which catches an F or Q other
        than the filter's.
    B : array_like, shape (n, q), optional, keyword-only
        Process-noise Jacobian of ``Q``; None means the identity.

    Returns
    -------
    RTSResult
        ``x_smooth`` (N, n), ``P_smooth`` (N, n, n) and the gains ``C`` (N − 1, n, n).

    Raises
    ------
    ValueError
        If ``history`` lacks a field or a field has the wrong shape or a NaN or inf (named
        with its row, ``history.P_check[3]``), a covariance is not symmetric, a prior
        covariance P̌_{k+1} is not positive definite (it is solved with), ``F`` has the
        wrong shape or stack length, ``Q`` (or ``B``) is not a valid process noise, or the
        record does not match ``F`` and ``Q``.

    Examples
    --------
    >>> hist = run_kf([0.0], [[1.0]], [[1.0]], [[0.1]], [[1.0]], [[0.5]], [[0.2], [0.4], [0.1]])
    >>> smooth = rts_smooth(hist, [[1.0]], [[0.1]])
    >>> bool(smooth.P_smooth[0, 0, 0] < hist.P_hat[0, 0, 0])
    True
    """
    x_hat = as_matrix(_history_field(history, "x_hat"), "history.x_hat", ("N", "n"))
    N, n = x_hat.shape
    x_check = as_rows(_history_field(history, "x_check"), "history.x_check", (n,), N)
    P_hat = as_rows(_history_field(history, "P_hat"), "history.P_hat", (n, n), N)
    P_check = as_rows(_history_field(history, "P_check"), "history.P_check", (n, n), N)
    _symmetric_rows(P_hat, "history.P_hat")
    _symmetric_rows(P_check, "history.P_check")
    F = _transitions(F, N, n)
    if Q is not None:
        _check_priors(P_hat, P_check, F, as_process_noise(Q, B, n))
    elif B is not None:
        raise ValueError("B was given without Q: B is the Jacobian of Q, pass both or neither")

    # C_kᵀ = P̌_{k+1}⁻¹ F_k P̂_k, for every k at once (P̌ and P̂ symmetric)
    try:
        C = np.swapaxes(np.linalg.solve(P_check[1:], np.matmul(F, P_hat[:-1])), -1, -2)
    except np.linalg.LinAlgError:
        k = next(k for k in range(1, N) if np.linalg.matrix_rank(P_check[k]) < n)
        raise ValueError(f"history.P_check[{k}] must be positive definite for the smoother, which solves "
                         f"with it; it is singular (smallest eigenvalue "
                         f"{np.linalg.eigvalsh(linalg.symmetrise(P_check[k]))[0]:.3g})") from None
    x_smooth = np.empty((N, n))
    P_smooth = np.empty((N, n, n))
    x_smooth[-1], P_smooth[-1] = x_hat[-1], P_hat[-1]
    for k in range(N - 2, -1, -1):
        x_smooth[k] = x_hat[k] + C[k] @ (x_smooth[k + 1] - x_check[k + 1])     # x̃ = x̂ + C (x̃ − x̌)
        P = P_hat[k] + C[k] @ (P_smooth[k + 1] - P_check[k + 1]) @ C[k].T      # P̃ = P̂ + C (P̃ − P̌) Cᵀ
        linalg.symmetrise(P, P_smooth[k])
    if not (np.isfinite(x_smooth).all() and np.isfinite(P_smooth).all()):
        raise ValueError("rts_smooth: the smoothed estimate overflowed (inf or NaN from finite inputs); "
                         "rescale the state's units or its covariance")
    return RTSResult(x_smooth=x_smooth, P_smooth=P_smooth, C=C)
