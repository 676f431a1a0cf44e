"""The Kalman filter, derived (chapter 03): the gain as the minimiser of the trace of the
posterior covariance, the update as Gaussian conditioning, and the constant-velocity (CV)
model with its process noise.

The CV model's numeric matrices are generated from its SymPy expressions (lambdified once
and cached): :func:`cv_transition`, :func:`cv_process_noise`,
:func:`cv_process_noise_continuous`, :func:`cv_noise_jacobian` and
:func:`cv_observation_matrix`.

CV state order
--------------
For ``dim`` spatial axes the CV state is **blocked**: all positions first, then all
velocities, ``x = [p_1, ..., p_dim, v_1, ..., v_dim]`` (in 2-D: ``[p_x, p_y, v_x, v_y]``).
This matches the ESKF error state ``[δp, δv, ...]`` and makes the position observation
``G = [I, 0]``. Per axis the model is the 2-state ``[p, v]``; the ``dim``-axis matrices
are Kronecker products ``kron(M_axis, I_dim)``.

Notation follows the course: prior x̌, P̌; posterior x̂, P̂; motion Jacobian F,
process-noise Jacobian B, process noise Q; observation Jacobian G, observation-noise
Jacobian C, observation noise R; gain K; innovation covariance S.
"""

from __future__ import annotations

import functools
from typing import Callable

import numpy as np
import sympy as sp
from sympy.matrices.expressions import BlockMatrix, Identity, MatrixSymbol, ZeroMatrix

from kalman_course.symbolic.equations import (
    Derivation,
    Equation,
    ExactArithmetic,
    derivation_builder,
    symbol_matrix,
)
from kalman_course.symbolic.numeric import as_dimension, as_real, as_time_step, lambdify_matrix

__all__ = ["kalman_gain", "kf_update_conditioning", "cv_model", "cv_transition", "cv_noise_jacobian",
           "cv_process_noise", "cv_process_noise_continuous", "cv_observation_matrix"]


def _who(nx: int, ny: int) -> str:
    """'explicit, 2 states and 1 observation' style prefix for check descriptions."""
    return (f"explicit, {nx} state{'s' if nx != 1 else ''} and "
            f"{ny} observation{'s' if ny != 1 else ''}")


def _trace_gradient(expr, K: sp.Matrix) -> sp.Matrix:
    """Matrix of partial derivatives ∂expr/∂K_ij (same shape as K)."""
    return sp.Matrix(K.shape[0], K.shape[1], lambda i, j: sp.diff(expr, K[i, j]))


def _gain_checks(nx: int, ny: int) -> list[Equation]:
    """Explicit proof that K* = P̌ Gᵀ S⁻¹ minimises tr P̂(K) for an nx-state, ny-obs system."""
    P = symbol_matrix("p", nx, nx, symmetric=True)
    G = symbol_matrix("g", ny, nx)
    R = symbol_matrix("r", ny, ny, symmetric=True)
    K = symbol_matrix("k", nx, ny)
    I = sp.eye(nx)
    P_hat = (I - K * G) * P * (I - K * G).T + K * R * K.T
    trace = P_hat.trace()
    grad = _trace_gradient(trace, K)
    # the expressions at the optimum are formed exactly over rational functions
    f = ExactArithmetic(P, G, R, K)
    Pd, Gd, Rd, Kd, Id = f(P), f(G), f(R), f(K), f(I)
    Sd = Gd * Pd * Gd.transpose() + Rd
    K_opt_d = Pd * Gd.transpose() * Sd.inv()
    A_opt = Id - K_opt_d * Gd
    P_hat_opt = f.back(A_opt * Pd * A_opt.transpose() + K_opt_d * Rd * K_opt_d.transpose())
    K_opt = f.back(K_opt_d)
    at_opt = {K[i, j]: K_opt[i, j] for i in range(nx) for j in range(ny)}
    dK = Kd - K_opt_d
    tag = f"{nx}x{ny}"
    who = _who(nx, ny)
    return [
        Equation(f"gradient_{tag}", grad, -2 * (I - K * G) * P * G.T + 2 * K * R,
                 f"{who}: SymPy's entry-wise derivative of the trace matches the matrix formula", "check"),
        Equation(f"stationary_{tag}", grad.subs(at_opt, simultaneous=True), sp.zeros(nx, ny),
                 f"{who}: the gradient vanishes at $K^*$", "check"),
        Equation(f"minimum_{tag}", trace - P_hat_opt.trace(),
                 f.back(dK * Sd * dK.transpose()).trace(),
                 f"{who}: " r"$\operatorname{tr} \hat P(K) - \operatorname{tr} \hat P(K^*) = "
                 r"\operatorname{tr}((K - K^*) S (K - K^*)^T) \ge 0$, so $K^*$ is the global minimum",
                 "check"),
        Equation(f"short_form_{tag}", P_hat_opt, f.back(A_opt * Pd),
                 f"{who}: " r"at $K^*$ the Joseph form equals $(I - K G) \check P$", "check"),
    ]


@derivation_builder
def kalman_gain() -> Derivation:
    """The Kalman gain as the minimiser of the trace of the posterior covariance."""
    n, m = sp.symbols("n m", integer=True, positive=True)
    P = MatrixSymbol(r"\check{P}", n, n)
    G = MatrixSymbol("G", m, n)
    R = MatrixSymbol("R", m, m)
    K = MatrixSymbol("K", n, m)
    In, Im, Znm, Zmn = Identity(n), Identity(m), ZeroMatrix(n, m), ZeroMatrix(m, n)
    A = In - K * G
    # errors are estimate - truth: e_hat = x_hat - x = (I - K G) e_check + K n,
    # Cov([e_check; n]) = blkdiag(P, R)
    T = BlockMatrix([[A, K]])
    P_hat = A * P * A.T + K * R * K.T
    S = G * P * G.T + R
    K_opt = P * G.T * S.I

    equations = [
        Equation("error", MatrixSymbol(r"\hat{e}", n, 1),
                 A * MatrixSymbol(r"\check{e}", n, 1) + K * MatrixSymbol(r"\mathbf{n}", m, 1),
                 r"with any gain $K$, $\hat x = \check x + K (y - G \check x)$ leaves the error "
                 r"$\hat e = \hat x - x$ (estimate minus truth)",
                 "definition"),
        Equation("joseph", T * BlockMatrix([[P, Znm], [Zmn, R]]) * T.T, P_hat,
                 "its covariance for any gain (the Joseph form), as prior error and noise are independent"),
        Equation("innovation_cov", MatrixSymbol("S", m, m), S,
                 "innovation covariance", "definition"),
        *_gain_checks(2, 1),
        *_gain_checks(2, 2),
        Equation("gain", K, K_opt,
                 r"setting $\partial \operatorname{tr} \hat P / \partial K = -2 (I - K G) \check P G^T + 2 K R$ "
                 "to zero gives the Kalman gain",
                 "definition"),
    ]
    return Derivation(
        name="kalman_gain",
        title="The Kalman gain minimises the trace of the posterior covariance",
        model=(r"Prior error $\check{e} = \check{x} - x \sim \mathcal{N}(0, \check{P})$, observation "
               r"$y = G x + n$ with $n \sim \mathcal{N}(0, R)$ independent; update "
               r"$\hat{x} = \check{x} + K (y - G \check{x})$ with a gain $K$ to be chosen "
               r"so that $\operatorname{tr} \hat{P}$, the expected squared error, is smallest."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "P_check": P, "G": G, "R": R, "K": K},
        results={"P_hat": P_hat, "S": S, "K": K_opt},
    )


def _update_checks(nx: int, ny: int) -> list[Equation]:
    """Explicit proof that conditioning the joint prior on y is the KF update."""
    P = symbol_matrix("p", nx, nx, symmetric=True)
    G = symbol_matrix("g", ny, nx)
    R = symbol_matrix("r", ny, ny, symmetric=True)
    x_check, y = symbol_matrix("x", nx, 1), symbol_matrix("y", ny, 1)
    f = ExactArithmetic(P, G, R, x_check, y)
    Pd, Gd, Rd, xd, yd, Id = f(P), f(G), f(R), f(x_check), f(y), f(sp.eye(nx))
    # the joint of [x; y] from the linear map, then the conditioning formula
    mu_y, S_yy, S_xy = Gd * xd, Gd * Pd * Gd.transpose() + Rd, Pd * Gd.transpose()
    cond_mean = f.back(xd + S_xy * S_yy.inv() * (yd - mu_y))
    cond_cov = f.back(Pd - S_xy * S_yy.inv() * S_xy.transpose())
    # the KF formulas, written independently
    S = Gd * Pd * Gd.transpose() + Rd
    K = Pd * Gd.transpose() * S.inv()
    kf_mean = f.back(xd + K * (yd - Gd * xd))
    kf_cov = f.back((Id - K * Gd) * Pd)
    tag = f"{nx}x{ny}"
    who = _who(nx, ny)
    return [
        Equation(f"mean_{tag}", cond_mean, kf_mean,
                 f"{who}: the conditional mean is the KF mean update", "check"),
        Equation(f"cov_{tag}", cond_cov, kf_cov,
                 f"{who}: " r"the conditional covariance is $(I - K G) \check P$", "check"),
        Equation(f"cov_sym_{tag}", kf_cov, f.back(Pd - K * S * K.transpose()),
                 f"{who}: " r"$(I - K G) \check P = \check P - K S K^T$ (the symmetric form)", "check"),
        Equation(f"information_{tag}", f.back((Pd.inv() + Gd.transpose() * Rd.inv() * Gd).inv()), kf_cov,
                 f"{who}: " r"information form, $\hat P^{-1} = \check P^{-1} + G^T R^{-1} G$",
                 "check"),
    ]


@derivation_builder
def kf_update_conditioning() -> Derivation:
    """The Kalman filter update obtained by conditioning the joint prior of state and observation."""
    n, m, l = sp.symbols("n m l", integer=True, positive=True)
    x_check = MatrixSymbol(r"\check{x}", n, 1)
    P = MatrixSymbol(r"\check{P}", n, n)
    G = MatrixSymbol("G", m, n)
    C = MatrixSymbol("C", m, l)
    R = MatrixSymbol("R", l, l)
    y = MatrixSymbol("y", m, 1)
    In, Im, Il = Identity(n), Identity(m), Identity(l)
    S = G * P * G.T + C * R * C.T
    K = P * G.T * S.I
    # [x; y] = T [x; n] with T = [[I, 0], [G, C]], Cov([x; n]) = blkdiag(P, R)
    T = BlockMatrix([[In, ZeroMatrix(n, l)], [G, C]])
    joint_cov = BlockMatrix([[P, P * G.T], [G * P, S]])
    x_hat = x_check + K * (y - G * x_check)
    P_hat_cond = P - (P * G.T) * S.I * (G * P)
    P_hat = (In - K * G) * P

    equations = [
        Equation("joint_cov", T * BlockMatrix([[P, ZeroMatrix(n, l)], [ZeroMatrix(l, n), R]]) * T.T, joint_cov,
                 "the joint covariance of the predicted state and the observation $y = G x + C n$"),
        Equation("innovation_cov", MatrixSymbol("S", m, m), S,
                 r"innovation covariance: the $\Sigma_{yy}$ block", "definition"),
        Equation("gain", MatrixSymbol("K", n, m), K,
                 r"gain: $\Sigma_{xy} \Sigma_{yy}^{-1}$", "definition"),
        Equation("posterior_mean", MatrixSymbol(r"\hat{x}", n, 1), x_hat,
                 r"posterior mean: the conditional mean with $\mu_x = \check x$, $\mu_y = G \check x$",
                 "definition"),
        Equation("posterior_cov", P_hat_cond, P_hat,
                 r"posterior covariance: the conditional covariance factorises as $(I - K G) \check P$"),
        *_update_checks(2, 1),
        *_update_checks(2, 2),
    ]
    return Derivation(
        name="kf_update_conditioning",
        title="The Kalman update is Gaussian conditioning",
        model=(r"Prior $x \sim \mathcal{N}(\check{x}, \check{P})$; observation "
               r"$y = G x + C n$ with $n \sim \mathcal{N}(0, R)$ independent of $x$. The "
               r"posterior is $p(x \mid y)$ of the joint Gaussian of $[x; y]$ (in the explicit "
               r"checks $C = I$)."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "l": l, "x_check": x_check, "P_check": P, "G": G, "C": C,
                 "R": R, "y": y},
        results={"S": S, "K": K, "x_hat": x_hat, "P_hat": P_hat},
    )


@derivation_builder
def cv_model() -> Derivation:
    """The constant-velocity model per axis: F, the noise Jacobian and both process-noise Q."""
    T, s, t = sp.symbols("T s t", nonnegative=True)
    sigma_a, q = sp.symbols(r"sigma_a q", positive=True)
    p0, v0, a = sp.symbols("p_0 v_0 a", real=True)
    A = sp.Matrix([[0, 1], [0, 0]])  # d/dt [p, v] = A [p, v] + L a
    L = sp.Matrix([0, 1])
    F = sp.Matrix([[1, T], [0, 1]])
    Phi_s = F.subs(T, s)

    def integral(M: sp.Matrix, var=s) -> sp.Matrix:
        """Entry-wise unevaluated integral from 0 to T (evaluated by verify())."""
        return M.applyfunc(lambda e: sp.Integral(e, (var, 0, T)))

    B = sp.Matrix([T**2 / 2, T])  # the process-noise Jacobian
    B_imm = sp.ImmutableMatrix(B)
    Q_pw = sigma_a**2 * sp.Matrix([[T**4 / 4, T**3 / 2], [T**3 / 2, T**2]])
    Q_c = q * sp.Matrix([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    # exact kinematics under an acceleration a held over one step
    kinematics = sp.Matrix([p0 + sp.Integral(v0 + sp.Integral(a, (s, 0, t)), (t, 0, T)),
                            v0 + sp.Integral(a, (s, 0, T))])

    equations = [
        Equation("transition_ode", sp.Derivative(sp.ImmutableMatrix(F), T), sp.MatMul(
                     sp.ImmutableMatrix(A), sp.ImmutableMatrix(F), evaluate=False),
                 r"$F(T) = \begin{bmatrix} 1 & T \\ 0 & 1 \end{bmatrix}$ solves "
                 r"$\dot F = A F$ ...", "identity"),
        Equation("transition_initial", sp.Subs(sp.ImmutableMatrix(F), T, 0), sp.eye(2),
                 r"... with $F(0) = I$, so $F(T) = \Phi(T) = e^{A T}$", "identity"),
        Equation("transition_exp", (A * T).exp(), F,
                 r"SymPy's matrix exponential $e^{A T}$ agrees", "check"),
        Equation("noise_jacobian", integral(Phi_s * L), B,
                 r"an acceleration held over the step enters through "
                 r"$B = \int_0^T \Phi(s) L \, ds$"),
        Equation("constant_acceleration", F * sp.Matrix([p0, v0]) + B * a, kinematics,
                 r"$F x + B a$ is exactly the motion under a constant acceleration $a$"),
        Equation("Q_piecewise", sp.MatMul(B_imm, sigma_a**2, B_imm.T, evaluate=False), Q_pw,
                 r"piecewise-constant white acceleration of variance $\sigma_a^2$ ($Q = \sigma_a^2$): "
                 r"the prediction adds $B Q B^T$"),
        Equation("Q_continuous", integral(Phi_s * L * q * L.T * Phi_s.T), Q_c,
                 r"continuous white acceleration of spectral density $q$: the prediction adds "
                 r"$\int_0^T \Phi(s) L q L^T \Phi(s)^T ds$"),
        Equation("Q_piecewise_rank", sp.Determinant(sp.ImmutableMatrix(Q_pw)), sp.Integer(0),
                 r"the piecewise $B Q B^T$ has rank one: a single acceleration moves $p$ and $v$ together"),
        Equation("Q_continuous_det", sp.Determinant(sp.ImmutableMatrix(Q_c)), q**2 * T**4 / 12,
                 r"the continuous one is positive definite for $T > 0$"),
    ]
    return Derivation(
        name="cv_model",
        title="Constant-velocity model and its process noise",
        model=(r"Per axis the state is $[p, v]$ with $\dot p = v$, $\dot v = a$, that is "
               r"$\dot x = A x + L a$ with "
               r"$A = \begin{bmatrix} 0 & 1 \\ 0 & 0 \end{bmatrix}$, "
               r"$L = \begin{bmatrix} 0 \\ 1 \end{bmatrix}$; time step $T$. "
               r"For several axes the state is blocked, $[p_1 \dots p_d, v_1 \dots v_d]$, and "
               r"every matrix becomes $M \otimes I_d$."),
        equations=tuple(equations),
        symbols={"T": T, "sigma_a": sigma_a, "q": q},
        results={"F": F, "B": B, "Q_piecewise": Q_pw, "Q_continuous": Q_c},
    )


# --------------------------------------------------------------------------------------
# Numeric CV matrices, generated from the SymPy expressions above
# --------------------------------------------------------------------------------------

@functools.cache
def _cv_functions() -> dict[str, Callable]:
    """Per-axis CV matrices as numpy functions, lambdified once from :func:`cv_model`."""
    d = cv_model()
    T, sigma_a, q = d.symbols["T"], d.symbols["sigma_a"], d.symbols["q"]
    return {
        "F": lambdify_matrix((T,), d.results["F"]),
        "B": lambdify_matrix((T,), d.results["B"]),
        "Q_piecewise": lambdify_matrix((T, sigma_a), d.results["Q_piecewise"]),
        "Q_continuous": lambdify_matrix((T, q), d.results["Q_continuous"]),
    }


def _per_axis(block, dim: int) -> np.ndarray:
    """The blocked ``dim``-axis matrix of a per-axis one, ``kron(block, I_dim)``."""
    return np.kron(np.asarray(block, dtype=float), np.eye(dim))


def cv_transition(T, dim: int = 1) -> np.ndarray:
    """Return the constant-velocity transition matrix F.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    F : ndarray, shape (2*dim, 2*dim)
        ``[[I, T I], [0, I]]`` for the blocked state ``[p_1..p_dim, v_1..v_dim]``.
    """
    T, dim = as_time_step(T), as_dimension(dim)
    return _per_axis(_cv_functions()["F"](T), dim)


def cv_noise_jacobian(T, dim: int = 1) -> np.ndarray:
    """Return the process-noise Jacobian B of a piecewise-constant acceleration.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    B : ndarray, shape (2*dim, dim)
        ``[[T²/2 I], [T I]]``: how one acceleration per axis, held over the step, moves
        the blocked state. ``B @ (sigma_a**2 * I) @ B.T`` equals :func:`cv_process_noise`.
    """
    T, dim = as_time_step(T), as_dimension(dim)
    return _per_axis(_cv_functions()["B"](T), dim)


def cv_process_noise(T, sigma_a, dim: int = 1) -> np.ndarray:
    """Return Q of the CV model driven by piecewise-constant white acceleration.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    sigma_a : float
        Standard deviation of the acceleration held over each step, in m/s² (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    Q : ndarray, shape (2*dim, 2*dim)
        ``sigma_a² [[T⁴/4 I, T³/2 I], [T³/2 I, T² I]]`` in the blocked state order.
    """
    T, dim = as_time_step(T), as_dimension(dim)
    sigma_a = as_real(sigma_a, "sigma_a")
    return _per_axis(_cv_functions()["Q_piecewise"](T, sigma_a), dim)


def cv_process_noise_continuous(T, q, dim: int = 1) -> np.ndarray:
    """Return Q of the CV model driven by continuous white acceleration.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    q : float
        Spectral density of the acceleration noise in m²/s³ (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    Q : ndarray, shape (2*dim, 2*dim)
        ``q [[T³/3 I, T²/2 I], [T²/2 I, T I]]`` in the blocked state order.
    """
    T, dim = as_time_step(T), as_dimension(dim)
    q = as_real(q, "q")
    return _per_axis(_cv_functions()["Q_continuous"](T, q), dim)


def cv_observation_matrix(dim: int = 1) -> np.ndarray:
    """Return the position-observation Jacobian G of the CV model.

    Parameters
    ----------
    dim : int
        Number of spatial axes.

    Returns
    -------
    G : ndarray, shape (dim, 2*dim)
        ``[I, 0]``: positions are observed, velocities are not.
    """
    dim = as_dimension(dim)
    return np.hstack([np.eye(dim), np.zeros((dim, dim))])
