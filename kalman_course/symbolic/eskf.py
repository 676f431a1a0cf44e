"""SymPy derivations behind the ESKF of chapter 08 (convention: error = nominal − true).

Three :class:`~kalman_course.symbolic.equations.Derivation` objects, each proved by ``verify()``:

:func:`eskf_error_dynamics`
    The continuous error dynamics, obtained by linearising the difference between the
    nominal and the true kinematics: with Ř = R Exp(δθ) ≈ R(I + [δθ]×), b̌ = b + δb and the
    noise entering the true readings, the first-order term of δv̇ and δθ̇ is computed in
    explicit 3-vectors (R a general 3 × 3 matrix of symbols) and shown equal to the rows
    of F_t and B_t the filter uses. The lidar attitude residual Log(R_mᵀ Ř) is shown to be
    δθ − n to first order, which makes G's attitude block the identity.
:func:`eskf_discretisation`
    Why white-noise columns of B scale with T and random-walk columns with √T: with the
    per-sample variances of Q_k, B Q_k Bᵀ equals T·B_t Q_c B_tᵀ, the first-order term of the
    exact ∫₀ᵀ Φ B_t Q_c B_tᵀ Φᵀ ds. Per axis the exact δp–δv block of that integral is
    computed and its first-order truncation compared with the lecture's.
:func:`eskf_reset`
    The reset Jacobian: after injecting δθ̂ the new error is Log(Exp(δθ) Exp(−δθ̂)); its
    derivative at δθ = δθ̂ is I + ½[δθ̂]× to first order in δθ̂ (the opposite sign of the
    convention true = nominal ⊕ δθ).

``results`` hold the symbolic F_t (15 × 15) and B_t (15 × 12) built from the derived rows,
with :func:`error_dynamics_function` turning F_t into a numpy function (``lambdify``) that
the tests compare with :func:`kalman_course.filters.eskf.error_dynamics`.

:func:`kalman_course.symbolic.derivations` lists them last (this module is the last topic of
:mod:`kalman_course.symbolic.registry`), so the course's export includes them.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

from kalman_course.core.validation import as_matrix, as_vector
from kalman_course.symbolic.equations import Derivation, Equation, derivation_builder, symbol_matrix
from kalman_course.symbolic.numeric import lambdify_matrix

__all__ = ["eskf_error_dynamics", "eskf_discretisation", "eskf_reset", "error_dynamics_function", "skew"]


def skew(v) -> sp.Matrix:
    """[v]× of a 3-vector (SymPy), ``skew(a) * b == a.cross(b)``."""
    v = sp.Matrix(v)
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def _vee(M: sp.Matrix) -> sp.Matrix:
    return sp.Matrix([(M[2, 1] - M[1, 2]) / 2, (M[0, 2] - M[2, 0]) / 2, (M[1, 0] - M[0, 1]) / 2])


def _first_order(expr: sp.Matrix, eps: sp.Symbol) -> sp.Matrix:
    """The coefficient of ε in ``expr``: d expr/dε at ε = 0, expanded."""
    return sp.Matrix(expr).diff(eps).subs(eps, 0).expand()


def _vec(name: str) -> sp.Matrix:
    return symbol_matrix(name, 3, 1)


@derivation_builder
def eskf_error_dynamics() -> Derivation:
    """δv̇ and δθ̇ by first-order expansion; F_t and B_t assembled from the derived rows."""
    eps = sp.Symbol("epsilon")
    R = symbol_matrix("R", 3, 3)                 # true attitude (any 3 × 3 matrix will do)
    f, w_m = _vec("f"), _vec("omega_m")          # IMU readings, body frame
    b_a, b_w = _vec("b_a"), _vec("b_omega")      # true biases
    dth, dba, dbw = _vec(r"delta\theta"), _vec(r"delta b_a"), _vec(r"delta b_omega")
    n_a, n_w = _vec("n_a"), _vec("n_omega")
    g = _vec("g")
    I3 = sp.eye(3)

    a = f - b_a                                  # bias-corrected body specific force
    w = w_m - b_w
    R_nom = R * (I3 + eps * skew(dth))           # Ř = R Exp(εδθ), first order
    ba_nom, bw_nom = b_a + eps * dba, b_w + eps * dbw

    # velocity: v̇ = R (f − b_a − n_a) + g (true), v̌̇ = Ř (f − b̌_a) + g (nominal)
    dv_dot = (R_nom * (f - ba_nom) + g) - (R * (f - b_a - eps * n_a) + g)
    dv_first = _first_order(dv_dot, eps)
    dv_lecture = (-R * skew(a) * dth - R * dba + R * n_a).expand()

    # attitude: Ṙ = R[ω_m − b_ω − n_ω]×, (Ř)˙ = Ř[ω_m − b̌_ω]×; with Ř = R E, E = Exp(εδθ):
    # Ė = Rᵀ(Ř)˙ − RᵀṘ E = E[ω̌]× − [ω]× E, and Ė = ε[δθ̇]× to first order.
    E = I3 + eps * skew(dth)
    w_nom = w_m - bw_nom
    w_true = w_m - b_w - eps * n_w
    E_dot = E * skew(w_nom) - skew(w_true) * E
    dth_first = _vee(_first_order(E_dot, eps))
    dth_lecture = (-skew(w) * dth - dbw + n_w).expand()

    # the same first-order term through the identity [x]×[y]× − [y]×[x]× = [x × y]×
    x, y = _vec("x"), _vec("y")
    commutator = skew(x) * skew(y) - skew(y) * skew(x)

    # observation: R_m = R Exp(n_θ), residual Log(R_mᵀ Ř) ≈ vee of the first-order term
    n_th = _vec(r"n_\theta")
    RtR = (I3 - eps * skew(n_th)) * (I3 + eps * skew(dth))      # R_mᵀ Ř with RᵀR = I
    resid_first = _vee(_first_order(RtR, eps))

    # the navigation-frame form: for a rotation (here about z by ψ) [R a]× = R [a]× Rᵀ
    psi = sp.Symbol("psi", real=True)
    Rz = sp.Matrix([[sp.cos(psi), -sp.sin(psi), 0], [sp.sin(psi), sp.cos(psi), 0], [0, 0, 1]])

    # assemble F_t and B_t from the derived rows
    F = sp.zeros(15, 15)
    F[0:3, 3:6] = I3
    F[3:6, 6:9] = -R * skew(a)
    F[3:6, 9:12] = -R
    F[6:9, 6:9] = -skew(w)
    F[6:9, 12:15] = -I3
    B = sp.zeros(15, 12)
    B[3:6, 0:3] = R
    B[6:9, 3:6] = I3
    B[9:12, 6:9] = I3
    B[12:15, 9:12] = I3
    dx = sp.Matrix.vstack(_vec(r"delta p"), _vec(r"delta v"), dth, dba, dbw)
    noise = sp.Matrix.vstack(n_a, n_w, _vec("n_ba"), _vec("n_bomega"))
    rhs = sp.Matrix.vstack(dx[3:6, 0], dv_lecture, dth_lecture, noise[6:9, 0], noise[9:12, 0])

    equations = (
        Equation("convention", sp.Symbol(r"\check{R}"), sp.Symbol("R") * sp.Function("Exp")(sp.Symbol(r"\delta\theta")),
                 r"error = nominal $-$ true: $\delta p = \check p - p$, $\check R = R\,\mathrm{Exp}(\delta\theta)$, "
                 r"$\delta b = \check b - b$", "definition"),
        Equation("velocity_error", dv_first, dv_lecture,
                 r"first-order term of $\dot{\check v} - \dot v$: "
                 r"$\delta\dot v = -R[a]_\times\delta\theta - R\,\delta b_a + R\,n_a$ with the "
                 r"BODY-frame $a = f - b_a$", "check"),
        Equation("skew_commutator", commutator, skew(x.cross(y)),
                 r"$[x]_\times[y]_\times - [y]_\times[x]_\times = [x \times y]_\times$", "check"),
        Equation("attitude_error", dth_first, dth_lecture,
                 r"first-order term of $\dot E$ for $E = R^T\check R$: "
                 r"$\delta\dot\theta = -[\omega]_\times\delta\theta - \delta b_\omega + n_\omega$", "check"),
        Equation("attitude_error_skew", _first_order(E_dot, eps), skew(dth_lecture),
                 r"... and that first-order term is exactly skew-symmetric", "check"),
        Equation("state_equation", (F * dx + B * noise).expand(), rhs.expand(),
                 r"so $\delta\dot x = F_t\,\delta x + B_t w$ with the $F_t$, $B_t$ of the filter "
                 r"(biases: $\delta\dot b = n_b$)", "check"),
        Equation("nav_frame_form", skew(Rz * a), Rz * skew(a) * Rz.T,
                 r"the navigation-frame form is $-[R a]_\times = -R[a]_\times R^T$ (shown for a rotation "
                 r"about $z$): it differs from $-R[a]_\times$ by the factor $R^T$ and is wrong for this "
                 r"body-frame $\delta\theta$", "check"),
        Equation("pose_residual", resid_first, dth - n_th,
                 r"with $R_m = R\,\mathrm{Exp}(n_\theta)$: $\mathrm{Log}(R_m^T\check R) = \delta\theta - n_\theta$ "
                 r"to first order, so $G$'s attitude block is $I$", "check"),
    )
    return Derivation(
        name="eskf_error_dynamics",
        title="ESKF: continuous error dynamics (error = nominal - true)",
        model=(r"Nominal kinematics $\dot{\check p} = \check v$, $\dot{\check v} = \check R(f - \check b_a) + g$, "
               r"$\dot{\check R} = \check R[\omega_m - \check b_\omega]_\times$; the true ones use the true biases "
               r"and the noises $n_a$, $n_\omega$ in the readings. The error $\delta x = [\delta p, \delta v, "
               r"\delta\theta, \delta b_a, \delta b_\omega]$ is expanded to first order with $\epsilon$ "
               r"scaling every error and noise."),
        equations=equations,
        symbols={"R": R, "f": f, "omega_m": w_m, "b_a": b_a, "b_omega": b_w},
        results={"F_t": F, "B_t": B},
    )


@derivation_builder
def eskf_discretisation() -> Derivation:
    """B Q_k Bᵀ = T B_t Q_c B_tᵀ, and the per-axis δp–δv block of the exact integral."""
    T, s = sp.symbols("T s", positive=True)
    sa, sw, sba, sbw = sp.symbols(r"sigma_a sigma_omega sigma_ba sigma_bomega", positive=True)
    R = symbol_matrix("R", 3, 3)
    I3, Z3 = sp.eye(3), sp.zeros(3)
    B_t = sp.Matrix(sp.BlockMatrix([[Z3, Z3, Z3, Z3], [R, Z3, Z3, Z3], [Z3, I3, Z3, Z3],
                                    [Z3, Z3, I3, Z3], [Z3, Z3, Z3, I3]]))
    B_d = sp.Matrix(B_t)
    B_d[:, 0:6] = B_d[:, 0:6] * T
    B_d[:, 6:12] = B_d[:, 6:12] * sp.sqrt(T)
    Q_k = sp.diag(*([sa ** 2 / T] * 3 + [sw ** 2 / T] * 3 + [sba ** 2] * 3 + [sbw ** 2] * 3))
    Q_c = sp.diag(*([sa ** 2] * 3 + [sw ** 2] * 3 + [sba ** 2] * 3 + [sbw ** 2] * 3))

    # one axis of δp, δv driven by white acceleration noise of density σ_a
    Phi = sp.Matrix([[1, s], [0, 1]])
    L = sp.Matrix([0, 1])
    exact = (Phi * L * sa ** 2 * L.T * Phi.T).applyfunc(lambda e: sp.integrate(e, (s, 0, T)))
    first = exact.applyfunc(lambda e: sp.series(e, T, 0, 2).removeO())

    equations = (
        Equation("F_discrete", sp.Symbol("F"), sp.Symbol("I") + sp.Symbol("F_t") * T,
                 r"first-order transition over one IMU step: $F = I + F_t T$", "definition"),
        Equation("BQB", (B_d * Q_k * B_d.T).expand(), (T * B_t * Q_c * B_t.T).expand(),
                 r"white-noise columns $\times T$ with per-sample variances $\sigma^2/T$, random-walk "
                 r"columns $\times\sqrt T$ with $\sigma_b^2$: $B Q_k B^T = T\,B_t Q_c B_t^T$", "check"),
        Equation("pv_block_exact", exact, sa ** 2 * sp.Matrix([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]]),
                 r"per axis, the exact $\int_0^T \Phi L \sigma_a^2 L^T \Phi^T ds$ of the $\delta p$--$\delta v$ block",
                 "check"),
        Equation("pv_block_first_order", first, sp.Matrix([[0, 0], [0, sa ** 2 * T]]),
                 r"its first-order part is the lecture's: only $\delta v$ receives $\sigma_a^2 T$", "check"),
        Equation("constant_bias_BQB", (B_d[:, 0:6] * Q_k[0:6, 0:6] * B_d[:, 0:6].T).expand(),
                 sp.diag(sp.zeros(3), sa ** 2 * T * R * R.T, sw ** 2 * T * sp.eye(3), sp.zeros(6)).expand(),
                 r"constant bias ($\delta\dot b = 0$): $B$ keeps only its $n_a$, $n_\omega$ columns, "
                 r"so $B Q_k B^T$ has no bias blocks and the bias variances can only shrink", "check"),
    )
    return Derivation(
        name="eskf_discretisation",
        title="ESKF: discretising the error dynamics and the process noise",
        model=(r"$\delta\dot x = F_t\delta x + B_t w$ with $w = [n_a, n_\omega, n_{ba}, n_{b\omega}]$ white, "
               r"densities $\sigma_a, \sigma_\omega, \sigma_{ba}, \sigma_{b\omega}$; one IMU step of $T$ seconds."),
        equations=equations,
        symbols={"T": T, "sigma_a": sa, "sigma_omega": sw, "sigma_ba": sba, "sigma_bomega": sbw},
        results={"B_d": B_d, "Q_k": Q_k},
    )


@derivation_builder
def eskf_reset() -> Derivation:
    """The reset Jacobian's attitude block for error = nominal − true."""
    eps, lam = sp.symbols("epsilon lambda")
    h, e = _vec(r"\hat\theta"), _vec("e")
    I3 = sp.eye(3)

    def exp2(v):                                  # Exp to second order
        K = skew(v)
        return I3 + K + K * K / 2

    # δθ⁺ = Log(Exp(δθ) Exp(−δθ̂)); Log ≈ vee of the antisymmetric part (exact to 2nd order)
    dth_hat = lam * h
    dth = dth_hat + eps * e
    M = exp2(dth) * exp2(-dth_hat)
    plus = _vee((M - M.T) / 2)
    J_e = _first_order(plus, eps)                                 # ∂δθ⁺/∂δθ · e
    J_first = J_e.applyfunc(lambda x: sp.series(x, lam, 0, 2).removeO()).expand()
    expected = ((I3 + skew(dth_hat) / 2) * e).expand()

    equations = (
        Equation("injection", sp.Symbol(r"\hat R"), sp.Symbol(r"\check R") * sp.Function("Exp")(-sp.Symbol(r"\hat{\delta\theta}")),
                 r"injection for error = nominal $-$ true: $\hat R = \check R\,\mathrm{Exp}(-\hat{\delta\theta})$", "definition"),
        Equation("new_error", sp.Symbol(r"\delta\theta^+"),
                 sp.Function("Log")(sp.Function("Exp")(sp.Symbol(r"\delta\theta")) * sp.Function("Exp")(-sp.Symbol(r"\hat{\delta\theta}"))),
                 r"the error with respect to the corrected nominal state", "definition"),
        Equation("reset_jacobian", J_first, expected,
                 r"$\partial\delta\theta^+/\partial\delta\theta = I + \tfrac12[\hat{\delta\theta}]_\times$ to first "
                 r"order (exactly: the left Jacobian $J_l(\hat{\delta\theta})$)", "check"),
    )
    return Derivation(
        name="eskf_reset",
        title="ESKF: the reset Jacobian for error = nominal - true",
        model=(r"After the update, $\hat{\delta\theta}$ is injected and the error reset to zero; the "
               r"covariance follows as $P \leftarrow G P G^T$ with $G = \mathrm{diag}(I, I, J, I, I)$."),
        equations=equations,
        symbols={},
        results={"J": I3 + skew(dth_hat) / 2},
    )


@functools.cache
def error_dynamics_function():
    """The SymPy F_t of :func:`eskf_error_dynamics` as a numpy function (lambdified once).

    Returns
    -------
    callable
        ``F_t(R, f, omega_m, b_a, b_omega)`` with the attitude R of shape (3, 3) and the
        specific force f (m/s²), the angular rate omega_m (rad/s) and the biases b_a, b_omega
        of shape (3,); returns F_t of shape (15, 15).
    """
    d = eskf_error_dynamics()
    names = ("R", "f", "omega_m", "b_a", "b_omega")
    fn = lambdify_matrix([x for name in names for x in d.symbols[name]], d.results["F_t"])

    def F_t(R, f, omega_m, b_a, b_omega):
        R = as_matrix(R, "R", (3, 3))
        vectors = [as_vector(v, name, 3) for v, name in zip((f, omega_m, b_a, b_omega), names[1:])]
        return np.asarray(fn(*R.ravel(), *np.concatenate(vectors)), dtype=float)

    return F_t
