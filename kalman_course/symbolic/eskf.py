"""SymPy derivations behind the ESKF of chapter 08 (convention: error = nominal − true).

Three :class:`~kalman_course.symbolic.equations.Derivation` objects, each a chain of
displayed steps (:class:`~kalman_course.symbolic.stepwise.Step`) that SymPy proves with
explicit 3 × 3 matrices, a general rotation R(q) and symbolic 3-vectors:

:func:`eskf_error_dynamics`
    δv̇ and δθ̇ derived from the true and the nominal kinematics, line by line: subtract,
    substitute Ř = R Exp(δθ) and b̌ = b + δb, expand Exp(δθ) ≈ I + [δθ]×, drop products of
    small terms, collect (δθ̇ through the identity [x]×[y]× − [y]×[x]× = [x × y]×); then
    F_t and B_t of δẋ = F_t δx + B_t w; the lidar residual Log(R_mᵀ Ř) ≈ δθ − n_θ (so G's
    attitude block is I); and the global (navigation-frame) variant of the attitude error,
    δθ_g = R δθ, for which −[R a]× is the right block.
:func:`eskf_discretisation`
    F = e^{F_t T} ≈ I + F_t T and the noise integral ≈ T B_t Q_c B_tᵀ, which the lecture's B
    (white-noise columns × T, random-walk columns × √T) and per-sample Q reproduce; the
    exact δp–δv block of one axis and its first-order part; the constant-bias variant.
:func:`eskf_reset`
    Injection R̂ = Ř Exp(−δθ̂) and the error left after it, δθ⁺ = Log(Exp(δθ) Exp(−δθ̂)),
    expanded to first order: δθ⁺ ≈ (I + ½[δθ̂]×)(δθ − δθ̂), the reset Jacobian's block.

``results`` hold the symbolic F_t (15 × 15) and B_t (15 × 12), made explicit from the
displayed block matrices, and the discrete B and Q; :func:`error_dynamics_function` turns
F_t into a numpy function (``lambdify``) that the tests compare with
:func:`kalman_course.filters.eskf.error_dynamics`.

:func:`kalman_course.symbolic.derivations` lists them last (this module is the last topic of
:mod:`kalman_course.symbolic.registry`), so the course's export includes them.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp
from sympy.matrices.expressions import BlockDiagMatrix, BlockMatrix, Identity, Transpose, ZeroMatrix

from kalman_course.core.validation import as_matrix, as_vector
from kalman_course.symbolic.equations import Derivation, derivation_builder, symbol_matrix
from kalman_course.symbolic.numeric import lambdify_matrix
from kalman_course.symbolic.stepwise import (Cross, Exp, ExplicitModel, Log, MatExp, MatIntegral, Skew, Step,
                                             TimeDerivative, Vee, add, mat, mul, skew_matrix, unit_quaternion_rotation,
                                             vec)

__all__ = ["eskf_error_dynamics", "eskf_discretisation", "eskf_reset", "error_dynamics_function", "skew", "SYMBOLS"]

I3, Z3 = Identity(3), ZeroMatrix(3, 3)
HALF = sp.Rational(1, 2)


def skew(v) -> sp.Matrix:
    """[v]× of an explicit 3-vector (SymPy), ``skew(a) * b == a.cross(b)``."""
    return skew_matrix(v)


def _components(name: str) -> sp.Matrix:
    return sp.Matrix([sp.Symbol(f"{name}_{i}") for i in (1, 2, 3)])


class _Symbols:
    """The displayed symbols of chapter 08 (LaTeX names), shared by the three derivations."""

    R, R_check, R_hat, R_m = mat("R"), mat(r"\check{R}"), mat(r"\hat{R}"), mat("R_{m}")
    dp, dv, dth = vec(r"\delta p"), vec(r"\delta v"), vec(r"\delta\theta")
    dba, dbw = vec(r"\delta b_{a}"), vec(r"\delta b_{\omega}")
    n_a, n_w, n_ba, n_bw = vec("n_{a}"), vec(r"n_{\omega}"), vec("n_{ba}"), vec(r"n_{b\omega}")
    f, w_m, g = vec("f"), vec(r"\omega_{m}"), vec("g")
    b_a, b_w, b_a_check, b_w_check = vec("b_{a}"), vec(r"b_{\omega}"), vec(r"\check{b}_{a}"), vec(r"\check{b}_{\omega}")
    a, w, a_check, w_check = vec("a"), vec(r"\omega"), vec(r"\check{a}"), vec(r"\check{\omega}")
    p, p_check, v, v_check = vec("p"), vec(r"\check{p}"), vec("v"), vec(r"\check{v}")
    v_dot, v_check_dot, dv_dot = vec(r"\dot{v}"), vec(r"\dot{\check{v}}"), vec(r"\delta\dot{v}")
    R_dot, R_check_dot = mat(r"\dot{R}"), mat(r"\dot{\check{R}}")
    dp_dot, dth_dot = vec(r"\delta\dot{p}"), vec(r"\delta\dot{\theta}")
    b_a_dot, b_w_dot = vec(r"\dot{b}_{a}"), vec(r"\dot{b}_{\omega}")
    b_a_check_dot, b_w_check_dot = vec(r"\dot{\check{b}}_{a}"), vec(r"\dot{\check{b}}_{\omega}")
    dba_dot, dbw_dot = vec(r"\delta\dot{b}_{a}"), vec(r"\delta\dot{b}_{\omega}")
    # observation
    p_m, n_p, n_th, y_p, y_th = vec("p_{m}"), vec("n_{p}"), vec(r"n_{\theta}"), vec("y_{p}"), vec(r"y_{\theta}")
    # global (navigation-frame) attitude error
    dth_g = vec(r"\delta\theta_{g}")
    # generic vectors of the lemmas
    x, y = vec("x"), vec("y")
    # matrices of the state equation
    F_t, B_t = mat("F_{t}", 15, 15), mat("B_{t}", 15, 12)


#: The displayed symbols of the chapter (``SYMBOLS.dth`` is δθ, ...), for lectures and tests.
SYMBOLS = S = _Symbols


def _F_t_blocks(R_check, a_check, w_check) -> BlockMatrix:
    """F_t as a 5 × 5 block matrix of displayed 3 × 3 blocks (order δp, δv, δθ, δb_a, δb_ω)."""
    return BlockMatrix([[Z3, I3, Z3, Z3, Z3],
                        [Z3, Z3, -mul(R_check, Skew(a_check)), -R_check, Z3],
                        [Z3, Z3, -Skew(w_check), Z3, -I3],
                        [Z3, Z3, Z3, Z3, Z3],
                        [Z3, Z3, Z3, Z3, Z3]])


def _B_t_blocks(R_check) -> BlockMatrix:
    """B_t as a 5 × 4 block matrix (noises n_a, n_ω, n_ba, n_bω)."""
    return BlockMatrix([[Z3, Z3, Z3, Z3],
                        [R_check, Z3, Z3, Z3],
                        [Z3, I3, Z3, Z3],
                        [Z3, Z3, I3, Z3],
                        [Z3, Z3, Z3, I3]])


def _column(*blocks) -> BlockMatrix:
    return BlockMatrix([[b] for b in blocks])


def _dynamics_model(eps: sp.Symbol) -> ExplicitModel:
    """True and nominal kinematics, the error definitions, with every error and noise ∝ ε."""
    R, unit, _ = unit_quaternion_rotation("q")
    m = ExplicitModel(small=(eps,), relation=unit)
    m.define(S.R, R)
    small = {S.dth: r"\delta\theta", S.dba: r"\delta b_a", S.dbw: r"\delta b_\omega", S.dp: r"\delta p",
             S.dv: r"\delta v", S.n_a: "n_a", S.n_w: r"n_\omega", S.n_ba: "n_ba", S.n_bw: r"n_b\omega",
             S.n_p: "n_p", S.n_th: r"n_\theta"}
    for node, name in small.items():
        m.define(node, eps * _components(name))
    for node, name in {S.f: "f", S.w_m: r"\omega_m", S.g: "g", S.b_a: "b_a", S.b_w: r"b_\omega",
                       S.p: "p", S.v: "v", S.x: "x", S.y: "y"}.items():
        m.define(node, _components(name))
    # convention: error = nominal - true
    m.define(S.R_check, mul(S.R, Exp(S.dth)))
    m.define(S.b_a_check, add(S.b_a, S.dba))
    m.define(S.b_w_check, add(S.b_w, S.dbw))
    m.define(S.p_check, add(S.p, S.dp))
    m.define(S.v_check, add(S.v, S.dv))
    # bias-corrected readings, true and nominal
    m.define(S.a, add(S.f, -S.b_a))
    m.define(S.w, add(S.w_m, -S.b_w))
    m.define(S.a_check, add(S.f, -S.b_a_check))
    m.define(S.w_check, add(S.w_m, -S.b_w_check))
    # kinematics: the true state sees the noises, the nominal one does not
    m.define(S.v_dot, add(mul(S.R, add(S.f, -S.b_a, -S.n_a)), S.g))
    m.define(S.v_check_dot, add(mul(S.R_check, add(S.f, -S.b_a_check)), S.g))
    m.define(S.R_dot, mul(S.R, Skew(add(S.w_m, -S.b_w, -S.n_w))))
    m.define(S.R_check_dot, mul(S.R_check, Skew(add(S.w_m, -S.b_w_check))))
    m.define(S.b_a_dot, -S.n_ba)
    m.define(S.b_w_dot, -S.n_bw)
    m.define(S.b_a_check_dot, ZeroMatrix(3, 1))
    m.define(S.b_w_check_dot, ZeroMatrix(3, 1))
    # time derivatives of the errors
    m.define(S.dp_dot, add(S.v_check, -S.v))
    m.define(S.dv_dot, add(S.v_check_dot, -S.v_dot))
    m.define(S.dba_dot, add(S.b_a_check_dot, -S.b_a_dot))
    m.define(S.dbw_dot, add(S.b_w_check_dot, -S.b_w_dot))
    E_dot = TimeDerivative(Exp(S.dth))
    m.define(E_dot, add(mul(S.R_dot.T, S.R_check), mul(S.R.T, S.R_check_dot)))   # d/dt (Rᵀ Ř)
    # d/dt Exp(δθ) = [δθ̇]× + O(ε²) (the step exp_derivative): δθ̇ = (d/dt Exp(δθ))^∨ to first order
    m.define(S.dth_dot, Vee(E_dot), valid_to=1)
    # state equation
    m.define(S.F_t, _F_t_blocks(S.R_check, S.a_check, S.w_check))
    m.define(S.B_t, _B_t_blocks(S.R_check))
    # lidar pose: p_m = p + n_p, R_m = R Exp(n_θ); the residual of the filter
    m.define(S.p_m, add(S.p, S.n_p))
    m.define(S.R_m, mul(S.R, Exp(S.n_th)))
    m.define(S.y_p, add(S.p_check, -S.p_m))
    m.define(S.y_th, Log(mul(S.R_m.T, S.R_check)))
    # global attitude error: Ř = Exp(δθ_g) R, so Exp(δθ_g) = Ř Rᵀ; δθ_g = R δθ (step global_adjoint)
    m.define(Exp(S.dth_g), mul(S.R_check, S.R.T))
    m.define(S.dth_g, mul(S.R, S.dth))
    return m


def _time_model(eps: sp.Symbol) -> ExplicitModel:
    """δθ(t) = ε (φ₀ + t φ₁): at any time t its value and its rate are arbitrary vectors, which
    is all a first derivative at that time depends on."""
    t = sp.Symbol("t", real=True)
    m = ExplicitModel(small=(eps,), time=t)
    phi = _components(r"\varphi") + t * _components(r"\dot\varphi")
    m.define(S.dth, eps * phi)
    m.define(S.dth_dot, eps * phi.diff(t))
    return m


def _product_rule_model() -> ExplicitModel:
    """R(t) and Ř(t) any differentiable matrices, of first degree in t (value and rate at t
    arbitrary, which is all a first derivative depends on); Exp(δθ) = Rᵀ Ř."""
    t = sp.Symbol("t", real=True)
    m = ExplicitModel(time=t)
    R0, R1, C0, C1 = (symbol_matrix(name, 3, 3) for name in ("R0", "R1", "C0", "C1"))
    m.define(S.R, R0 + t * R1)
    m.define(S.R_check, C0 + t * C1)
    m.define(S.R_dot, R1)
    m.define(S.R_check_dot, C1)
    m.define(Exp(S.dth), mul(S.R.T, S.R_check))
    return m


@derivation_builder
def eskf_error_dynamics() -> Derivation:
    """δv̇ and δθ̇ step by step; F_t and B_t; the pose residual; the global variant."""
    eps = sp.Symbol("epsilon")
    m = _dynamics_model(eps)
    mt = _time_model(eps)
    first = ((eps, 1),)

    def check(label, lhs, rhs, text, model=m, orders=()):
        return Step(label, lhs, rhs, text, "check", model, orders)

    def approx(label, lhs, rhs, text, model=m):
        return Step(label, lhs, rhs, text, "check", model, first)

    def define(label, lhs, rhs, text):
        return Step(label, lhs, rhs, text, "definition", m)

    dth, R, Rc, a, w = S.dth, S.R, S.R_check, S.a, S.w
    E = Exp(dth)
    E_dot = TimeDerivative(E)
    equations = (
        # -- convention and lemmas
        define("convention", Rc, mul(R, E),
               r"error = nominal $-$ true: $\delta p = \check p - p$, $\delta v = \check v - v$, "
               r"$\delta b = \check b - b$, and the attitude error $\delta\theta$ in the body frame"),
        approx("exp_first_order", E, add(I3, Skew(dth)),
               r"the exponential to first order: the next term of its series, "
               r"$\tfrac12[\delta\theta]_\times^2$, is of second order"),
        check("cross_antisymmetry", mul(Skew(S.x), S.y), -mul(Skew(S.y), S.x),
              r"$[x]_\times y = x \times y = -y \times x$, for any 3-vectors"),
        check("skew_commutator", add(mul(Skew(S.x), Skew(S.y)), -mul(Skew(S.y), Skew(S.x))), Skew(Cross(S.x, S.y)),
              r"the commutator of two skew matrices, for any 3-vectors"),
        approx("exp_derivative", E_dot, Skew(S.dth_dot),
               r"for any small $\delta\theta(t)$: the derivative of $\mathrm{Exp}$ to first order", model=mt),
        # -- velocity
        define("dv_definition", S.dv_dot, add(S.v_check_dot, -S.v_dot),
               r"differentiate $\delta v = \check v - v$"),
        check("dv_dynamics", S.dv_dot,
              add(add(mul(Rc, add(S.f, -S.b_a_check)), S.g), mul(-1, add(mul(R, add(S.f, -S.b_a, -S.n_a)), S.g))),
              r"substitute the nominal kinematics (nominal bias, no noise) and the true ones "
              r"(true bias, accelerometer noise $n_a$)"),
        check("dv_substitute", S.dv_dot, add(mul(R, E, add(a, -S.dba)), mul(-1, R, add(a, -S.n_a))),
              r"$\check R = R\,\mathrm{Exp}(\delta\theta)$, $\check b_a = b_a + \delta b_a$, $a = f - b_a$; "
              r"$g$ cancels"),
        approx("dv_expand", S.dv_dot, add(mul(R, add(I3, Skew(dth)), add(a, -S.dba)), mul(-1, R, add(a, -S.n_a))),
               r"expand the exponential to first order"),
        approx("dv_drop", S.dv_dot, add(mul(R, Skew(dth), a), -mul(R, S.dba), mul(R, S.n_a)),
               r"multiply out: $R a$ cancels, $R[\delta\theta]_\times\delta b_a$ is of second order and dropped"),
        approx("dv_collect", S.dv_dot, add(-mul(R, Skew(a), dth), -mul(R, S.dba), mul(R, S.n_a)),
               r"$[\delta\theta]_\times a = -[a]_\times\delta\theta$, with $a = f - b_a$ the bias-corrected "
               r"specific force in the body frame"),
        approx("dv_nominal", S.dv_dot, add(-mul(Rc, Skew(S.a_check), dth), -mul(Rc, S.dba), mul(Rc, S.n_a)),
               r"evaluate at the nominal state ($\check a = f - \check b_a$): $\check R - R$ and $\check a - a$ "
               r"are small, so the change is of second order; the filter knows only $\check R$ and $\check a$"),
        # -- attitude
        check("dth_definition", E, mul(R.T, Rc),
              r"the convention solved for the error ($R^T R = I$)"),
        check("dth_product_rule", E_dot, add(mul(S.R_dot.T, Rc), mul(R.T, S.R_check_dot)),
              r"differentiate $R^T \check R$ (the product rule, for any differentiable $R(t)$, $\check R(t)$)",
              model=_product_rule_model()),
        check("dth_dynamics", E_dot,
              add(mul(Transpose(mul(R, Skew(add(w, -S.n_w)))), Rc), mul(R.T, Rc, Skew(add(w, -S.dbw)))),
              r"substitute $\dot R = R[\omega - n_\omega]_\times$ (true) and "
              r"$\dot{\check R} = \check R[\omega - \delta b_\omega]_\times$ (nominal), "
              r"$\omega = \omega_m - b_\omega$"),
        check("dth_substitute", E_dot, add(mul(-1, Skew(add(w, -S.n_w)), E), mul(E, Skew(add(w, -S.dbw)))),
              r"$[x]_\times^T = -[x]_\times$ and $R^T \check R = \mathrm{Exp}(\delta\theta)$"),
        approx("dth_expand", E_dot,
               add(mul(-1, Skew(add(w, -S.n_w)), add(I3, Skew(dth))),
                   mul(add(I3, Skew(dth)), Skew(add(w, -S.dbw)))),
               r"expand the exponential to first order"),
        approx("dth_drop", E_dot,
               add(mul(Skew(dth), Skew(w)), -mul(Skew(w), Skew(dth)), Skew(S.n_w), -Skew(S.dbw)),
               r"multiply out: $-[\omega]_\times + [\omega]_\times$ cancels, products of two small terms are dropped"),
        approx("dth_commutator", E_dot, add(Skew(Cross(dth, w)), Skew(add(S.n_w, -S.dbw))),
               r"the commutator identity, and $[x]_\times + [y]_\times = [x + y]_\times$"),
        approx("dth_collect", E_dot, Skew(add(-mul(Skew(w), dth), -S.dbw, S.n_w)),
               r"$\delta\theta \times \omega = -[\omega]_\times\delta\theta$"),
        approx("dth_rate", S.dth_dot, add(-mul(Skew(w), dth), -S.dbw, S.n_w),
               r"compare with the derivative of $\mathrm{Exp}$: the vectors inside $[\,]_\times$ are equal"),
        approx("dth_nominal", S.dth_dot, add(-mul(Skew(S.w_check), dth), -S.dbw, S.n_w),
               r"evaluate at the nominal state, $\check\omega = \omega_m - \check b_\omega$"),
        # -- position, biases, and the state equation
        check("dp_rate", S.dp_dot, S.dv, r"$\dot{\check p} - \dot p = \check v - v$"),
        check("bias_rates", _column(S.dba_dot, S.dbw_dot), _column(S.n_ba, S.n_bw),
              r"random walks: the true biases drift, $\dot b_a = -n_{ba}$, $\dot b_\omega = -n_{b\omega}$ "
              r"(the sign of a white noise is a name), the nominal ones are constant"),
        define("F_t", S.F_t, _F_t_blocks(Rc, S.a_check, S.w_check),
               r"the rows just derived, as a matrix (error order $\delta p, \delta v, \delta\theta, "
               r"\delta b_a, \delta b_\omega$)"),
        define("B_t", S.B_t, _B_t_blocks(Rc), r"noise order $n_a, n_\omega, n_{ba}, n_{b\omega}$"),
        approx("state_equation", _column(S.dp_dot, S.dv_dot, S.dth_dot, S.dba_dot, S.dbw_dot),
               add(mul(S.F_t, _column(S.dp, S.dv, dth, S.dba, S.dbw)),
                   mul(S.B_t, _column(S.n_a, S.n_w, S.n_ba, S.n_bw))),
               r"so $\delta\dot x = F_t\,\delta x + B_t w$, the $F_t$ and $B_t$ of the filter"),
        # -- the lidar pose residual
        define("pose_measurement", S.R_m, mul(R, Exp(S.n_th)),
               r"the lidar pose: $p_m = p + n_p$ and this attitude, noise $n_\theta$ in the body frame"),
        define("pose_residual", S.y_th, Log(mul(S.R_m.T, Rc)),
               r"the attitude residual of the filter (position: $y_p = \check p - p_m$)"),
        check("pose_position", S.y_p, add(S.dp, -S.n_p), r"$\check p - p_m = (p + \delta p) - (p + n_p)$"),
        check("pose_attitude_substitute", mul(S.R_m.T, Rc), mul(Exp(S.n_th).T, E),
              r"$R_m = R\,\mathrm{Exp}(n_\theta)$, $\check R = R\,\mathrm{Exp}(\delta\theta)$, $R^T R = I$"),
        approx("pose_attitude_expand", mul(S.R_m.T, Rc), mul(add(I3, -Skew(S.n_th)), add(I3, Skew(dth))),
               r"expand both exponentials to first order"),
        approx("pose_attitude_drop", mul(S.R_m.T, Rc), add(I3, Skew(add(dth, -S.n_th))),
               r"multiply out and drop the product of two small terms"),
        approx("pose_attitude", S.y_th, add(dth, -S.n_th),
               r"$\mathrm{Log}(I + [\phi]_\times) \approx \phi$: so $y \approx G\,\delta x - n$ with $G$'s "
               r"attitude block $I$ (the sign of a zero-mean noise does not change its covariance)"),
        # -- global variant
        check("nav_frame_form", Skew(mul(R, a)), mul(R, Skew(a), R.T),
              r"$[R a]_\times = R [a]_\times R^T$ for every rotation $R$ (SymPy: $R = R(q)$ of a unit "
              r"quaternion, $q^T q = 1$ used explicitly; every rotation is one)"),
        check("global_error", Exp(S.dth_g), mul(R, E, R.T),
              r"a global (navigation-frame) attitude error $\delta\theta_g$ is defined by "
              r"$\check R = \mathrm{Exp}(\delta\theta_g) R$"),
        Step("global_adjoint", mul(R, E, R.T), Exp(mul(R, dth)),
             r"exact, term by term in the series, since $R[\delta\theta]_\times^n R^T = [R\delta\theta]_\times^n$ "
             r"(checked to third order): so $\delta\theta_g = R\,\delta\theta$",
             "check", m, ((eps, 3),)),
        approx("dv_global", S.dv_dot, add(-mul(Skew(mul(R, a)), S.dth_g), -mul(R, S.dba), mul(R, S.n_a)),
               r"with the global error the attitude block is $-[R a]_\times$ (the navigation-frame specific "
               r"force); it is wrong only when mixed with the body-frame $\delta\theta$ of this filter"),
    )

    # the numbers: F_t and B_t made explicit at a nominal state given by plain symbols
    R_sym = symbol_matrix("R", 3, 3)
    f, w_m, b_a, b_w = _components("f"), _components("omega_m"), _components("b_a"), _components("b_omega")
    nominal = ExplicitModel()
    nominal.define(S.R_check, R_sym)
    nominal.define(S.a_check, f - b_a)
    nominal.define(S.w_check, w_m - b_w)
    F = nominal.explicit(_F_t_blocks(S.R_check, S.a_check, S.w_check))
    B = nominal.explicit(_B_t_blocks(S.R_check))
    return Derivation(
        name="eskf_error_dynamics",
        title="ESKF: continuous error dynamics (error = nominal - true)",
        model=(r"True kinematics $\dot v = R(f - b_a - n_a) + g$, $\dot R = R[\omega_m - b_\omega - n_\omega]_\times$; "
               r"nominal kinematics $\dot{\check v} = \check R(f - \check b_a) + g$, "
               r"$\dot{\check R} = \check R[\omega_m - \check b_\omega]_\times$ (readings $f$, $\omega_m$ in the body "
               r"frame). Errors: $\check R = R\,\mathrm{Exp}(\delta\theta)$, $\check b = b + \delta b$. Each step is "
               r"proved with $R = R(q)$ a general rotation and symbolic 3-vectors; $\approx$ means equal to first "
               r"order in the errors and noises."),
        equations=equations,
        symbols={"R": R_sym, "f": f, "omega_m": w_m, "b_a": b_a, "b_omega": b_w},
        results={"F_t": F, "B_t": B},
    )


@derivation_builder
def eskf_discretisation() -> Derivation:
    """F ≈ I + F_t T, the noise integral ≈ T B_t Q_c B_tᵀ = B Q Bᵀ, one axis exactly."""
    T, s = sp.symbols("T s", positive=True)
    sa, sw, sba, sbw = sp.symbols(r"\sigma_{a} \sigma_{\omega} \sigma_{ba} \sigma_{b\omega}", positive=True)
    tau = sp.Symbol("tau", positive=True)
    R, unit, _ = unit_quaternion_rotation("q")
    m = ExplicitModel(small=(T,), relation=unit, exact_substitution={T: tau ** 2})   # sqrt(T) = tau
    m.define(S.R_check, R)
    m.define(S.a_check, _components("a"))
    m.define(S.w_check, _components(r"\omega"))
    m.define(S.F_t, _F_t_blocks(S.R_check, S.a_check, S.w_check))
    m.define(S.B_t, _B_t_blocks(S.R_check))
    Q_c, Q, B, F, Q_d = mat("Q_{c}", 12, 12), mat("Q", 12, 12), mat("B", 15, 12), mat("F", 15, 15), mat("Q_{d}", 15, 15)
    sqT = sp.sqrt(T)
    m.define(Q_c, BlockDiagMatrix(sa ** 2 * I3, sw ** 2 * I3, sba ** 2 * I3, sbw ** 2 * I3))
    m.define(Q, BlockDiagMatrix(sa ** 2 / T * I3, sw ** 2 / T * I3, sba ** 2 * I3, sbw ** 2 * I3))
    m.define(B, BlockMatrix([[Z3, Z3, Z3, Z3], [T * S.R_check, Z3, Z3, Z3], [Z3, T * I3, Z3, Z3],
                             [Z3, Z3, sqT * I3, Z3], [Z3, Z3, Z3, sqT * I3]]))
    m.define(F, add(Identity(15), mul(S.F_t, T)))
    Phi_s = MatExp(mul(S.F_t, s))
    m.define(Q_d, MatIntegral(mul(Phi_s, S.B_t, Q_c, S.B_t.T, Phi_s.T), s, 0, T))
    # constant bias: only the n_a, n_omega columns and variances
    B_c = BlockMatrix([[Z3, Z3], [T * S.R_check, Z3], [Z3, T * I3], [Z3, Z3], [Z3, Z3]])
    Q_w = BlockDiagMatrix(sa ** 2 / T * I3, sw ** 2 / T * I3)
    # one axis of δp, δv driven by white acceleration noise of density sigma_a
    Phi_axis = sp.ImmutableMatrix([[1, s], [0, 1]])
    L = sp.ImmutableMatrix([0, 1])
    axis_exact = sp.ImmutableMatrix([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]]) * sa ** 2
    first = ((T, 1),)
    Z15 = ZeroMatrix(3, 3)

    equations = (
        Step("continuous", mat(r"\delta\dot{x}", 15, 1),
             add(mul(S.F_t, mat(r"\delta x", 15, 1)), mul(S.B_t, mat("w", 12, 1))),
             r"the continuous error dynamics, $w$ white with $E[w(t)w(t')^T] = Q_c\,\delta(t - t')$, "
             r"$Q_c = \mathrm{diag}(\sigma_a^2 I, \sigma_\omega^2 I, \sigma_{ba}^2 I, \sigma_{b\omega}^2 I)$ "
             r"(densities)", "definition", m),
        Step("solution", mat(r"\delta x_{k}", 15, 1),
             add(mul(MatExp(mul(S.F_t, T)), mat(r"\delta x_{k-1}", 15, 1)),
                 MatIntegral(mul(Phi_s, S.B_t, mat("w(t_{k} - s)", 12, 1)), s, 0, T)),
             r"its solution over one IMU step of $T$ seconds ($F_t$ held constant)", "definition", m),
        Step("F_first_order", MatExp(mul(S.F_t, T)), add(Identity(15), mul(S.F_t, T)),
             r"the transition to first order in $T$: the lecture's $F = I + F_t T$", "check", m, first),
        Step("Q_d_definition", Q_d, MatIntegral(mul(Phi_s, S.B_t, Q_c, S.B_t.T, Phi_s.T), s, 0, T),
             r"the covariance of the noise term", "definition", m),
        Step("Q_d_first_order", Q_d, mul(T, S.B_t, Q_c, S.B_t.T),
             r"to first order in $T$ (SymPy: the $15 \times 15$ integral with $F_t$ and $B_t$ of the filter)",
             "check", m, first),
        Step("BQB", mul(T, S.B_t, Q_c, S.B_t.T), mul(B, Q, B.T),
             r"the lecture's $B$ (white-noise columns times $T$, random-walk columns times $\sqrt T$) with "
             r"per-sample variances ($\sigma^2/T$ for $n_a$, $n_\omega$; $\sigma_b^2$ for the biases)",
             "check", m),
        Step("BQB_blocks", mul(B, Q, B.T),
             BlockDiagMatrix(Z15, sa ** 2 * T * I3, sw ** 2 * T * I3, sba ** 2 * T * I3, sbw ** 2 * T * I3),
             r"every block is $\sigma^2 T\,I$ ($\check R \check R^T = I$ for the velocity block)", "check", m),
        Step("pv_block_exact",
             MatIntegral(mul(Phi_axis, L, sa ** 2, L.T, Phi_axis.T), s, 0, T), axis_exact,
             r"one axis of the $\delta p$--$\delta v$ block exactly ($\Phi(s) = [1, s; 0, 1]$, noise into "
             r"$\delta v$ only)", "check", m),
        Step("pv_block_first_order", axis_exact, sp.ImmutableMatrix([[0, 0], [0, sa ** 2 * T]]),
             r"its first-order part is the lecture's: only $\delta v$ receives $\sigma_a^2 T$", "check", m, first),
        Step("constant_bias_BQB", mul(B_c, Q_w, B_c.T),
             BlockDiagMatrix(Z15, sa ** 2 * T * I3, sw ** 2 * T * I3, Z15, Z15),
             r"constant bias ($\delta\dot b = 0$): $B$ keeps only its $n_a$, $n_\omega$ columns, so no bias "
             r"variance is added and the bias variances can only shrink", "check", m),
    )

    # the numbers: B and Q with R given by plain symbols
    R_sym = symbol_matrix("R", 3, 3)
    nominal = ExplicitModel()
    nominal.define(S.R_check, R_sym)
    return Derivation(
        name="eskf_discretisation",
        title="ESKF: discretising the error dynamics and the process noise",
        model=(r"$\delta\dot x = F_t\delta x + B_t w$ with $w = [n_a, n_\omega, n_{ba}, n_{b\omega}]$ white, "
               r"densities $\sigma_a, \sigma_\omega, \sigma_{ba}, \sigma_{b\omega}$; one IMU step of $T$ seconds. "
               r"$\approx$ means equal to first order in $T$; the checks use a general rotation $\check R = R(q)$."),
        equations=equations,
        symbols={"T": T, "sigma_a": sa, "sigma_omega": sw, "sigma_ba": sba, "sigma_bomega": sbw, "R": R_sym},
        results={"B_d": nominal.explicit(m.meaning(B)), "Q_k": nominal.explicit(m.meaning(Q))},
    )


@derivation_builder
def eskf_reset() -> Derivation:
    """The error left after injection and the reset Jacobian's attitude block."""
    eps, lam = sp.symbols("epsilon lambda")
    R_hat, dth_hat, dth_plus, e = S.R_hat, vec(r"\delta\hat{\theta}"), vec(r"\delta\theta^{+}"), vec("e")
    R, unit, _ = unit_quaternion_rotation("q")
    m = ExplicitModel(small=(eps, lam), relation=unit)
    h = _components(r"\hat\theta")
    m.define(S.R, R)
    m.define(dth_hat, lam * h)                        # the estimate, small (order lambda)
    m.define(e, eps * _components("e"))               # the error the update leaves (order epsilon)
    m.define(S.dth, add(dth_hat, e))
    m.define(S.R_check, mul(S.R, Exp(S.dth)))
    m.define(R_hat, mul(S.R_check, Exp(-dth_hat)))
    m.define(Exp(dth_plus), mul(S.R.T, R_hat))
    m.define(dth_plus, Log(mul(Exp(S.dth), Exp(-dth_hat))), valid_to=2)
    both = ((eps, 1), (lam, 1))
    a, E_a = dth_hat, Skew(dth_hat)

    def sq(X):
        return mul(X, X)

    equations = (
        Step("injection", R_hat, mul(S.R_check, Exp(-dth_hat)),
             r"inject the estimate $\delta\hat\theta$ (error = nominal $-$ true, hence the minus)", "definition", m),
        Step("new_error", R_hat, mul(S.R, Exp(dth_plus)),
             r"the error $\delta\theta^+$ of the corrected state, in the same convention", "definition", m),
        Step("new_error_solved", Exp(dth_plus), mul(S.R.T, S.R_check, Exp(-dth_hat)),
             r"solve for $\mathrm{Exp}(\delta\theta^+)$ and substitute the injection", "check", m),
        Step("new_error_product", Exp(dth_plus), mul(Exp(S.dth), Exp(-dth_hat)),
             r"$\check R = R\,\mathrm{Exp}(\delta\theta)$ and $R^T R = I$", "check", m),
        Step("split", S.dth, add(dth_hat, e),
             r"the update estimated $\delta\hat\theta$; $e = \delta\theta - \delta\hat\theta$ is the error it "
             r"leaves, the one $\hat P$ describes", "definition", m),
        Step("expand", Exp(dth_plus),
             mul(add(I3, Skew(add(a, e)), mul(HALF, sq(Skew(add(a, e))))), add(I3, -E_a, mul(HALF, sq(E_a)))),
             r"both exponentials to second order (a product of $e$ and $\delta\hat\theta$ is about to matter)",
             "check", m, both),
        Step("keep", Exp(dth_plus), add(I3, Skew(e), mul(HALF, add(mul(E_a, Skew(e)), -mul(Skew(e), E_a)))),
             r"keep what is linear in $e$ and at most linear in $\delta\hat\theta$ (without $e$ the product is "
             r"exactly $I$)", "check", m, both),
        Step("commute", Exp(dth_plus), add(I3, Skew(add(e, mul(HALF, Cross(a, e))))),
             r"the commutator identity $[x]_\times[y]_\times - [y]_\times[x]_\times = [x \times y]_\times$",
             "check", m, both),
        Step("reset_jacobian", dth_plus, mul(add(I3, mul(HALF, E_a)), add(S.dth, -dth_hat)),
             r"take $\mathrm{Log}$: the new error is $(I + \tfrac12[\delta\hat\theta]_\times)$ times the old one; "
             r"so $\hat P \leftarrow G_r \hat P G_r^T$ with "
             r"$G_r = \mathrm{diag}(I, I, I + \tfrac12[\delta\hat\theta]_\times, I, I)$ "
             r"(exactly: the left Jacobian $J_l(\delta\hat\theta)$)", "check", m, both),
    )
    return Derivation(
        name="eskf_reset",
        title="ESKF: the reset Jacobian for error = nominal - true",
        model=(r"After the update, $\delta\hat\theta$ is injected and the error estimate reset to zero. "
               r"$\approx$ means equal to first order in $e$ and in $\delta\hat\theta$ (the terms in "
               r"$e\,\delta\hat\theta$ kept); $R = R(q)$ is a general rotation."),
        equations=equations,
        symbols={},
        results={"J": sp.eye(3) + skew(lam * h) / 2},
    )


@functools.cache
def error_dynamics_function():
    """The SymPy F_t of :func:`eskf_error_dynamics` as a numpy function (lambdified once).

    Returns
    -------
    callable
        ``F_t(R, f, omega_m, b_a, b_omega)`` with the nominal attitude R of shape (3, 3) and
        the specific force f (m/s²), the angular rate omega_m (rad/s) and the nominal biases
        b_a, b_omega of shape (3,); returns F_t of shape (15, 15).
    """
    d = eskf_error_dynamics()
    names = ("R", "f", "omega_m", "b_a", "b_omega")
    fn = lambdify_matrix([x for name in names for x in d.symbols[name]], d.results["F_t"])

    def F_t(R, f, omega_m, b_a, b_omega):
        R = as_matrix(R, "R", (3, 3))
        vectors = [as_vector(v, name, 3) for v, name in zip((f, omega_m, b_a, b_omega), names[1:])]
        return np.asarray(fn(*R.ravel(), *np.concatenate(vectors)), dtype=float)

    return F_t
