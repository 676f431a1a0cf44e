"""Planar motion models, derived (chapter 04): CV, CA, CTRV, CTRA.

Each model is written once as a continuous-time ODE. SymPy integrates it over a step T
(with the process noise held constant over the step), gives the exact discrete model
x_k = f(x_{k-1}, w_k, T), and differentiates it for the motion Jacobian F = ∂f/∂x and
the process-noise Jacobian B = ∂f/∂w (both at w = 0). The turning models divide by the
yaw rate ω; for |ω T| below ``OMEGA_SERIES_THRESHOLD`` the numeric functions switch to a
Taylor series in ω, derived symbolically from the same integrand, so the model and its
Jacobians stay finite and continuous through ω = 0.

State orders (units m, m/s, m/s², rad, rad/s)::

    cv   [p_x, p_y, v_x, v_y]            noise w = [a_x, a_y]        (m/s²)
    ca   [p_x, p_y, v_x, v_y, a_x, a_y]  noise w = [j_x, j_y]        (m/s³)
    ctrv [p_x, p_y, v, ψ, ω]             noise w = [ν_a, ν_ψ̈]        (m/s², rad/s²)
    ctra [p_x, p_y, v, ψ, ω, a]          noise w = [ν_j, ν_ψ̈]        (m/s³, rad/s²)

The chapter 05 lidar + radar scenario simulates its target with this CTRV model. The numeric
functions (:func:`motion_step`, :func:`motion_jacobian`, :func:`motion_noise_jacobian`,
:func:`ctrv_step`, ...) are lambdified once per model and cached.
"""

from __future__ import annotations

import functools
import types

import numpy as np
import sympy as sp

from kalman_course.core.validation import as_vector
from kalman_course.symbolic.equations import Derivation, Equation, derivation_builder
from kalman_course.symbolic.numeric import as_time_step, lambdify_matrix

__all__ = ["MOTION_MODELS", "OMEGA_SERIES_THRESHOLD", "SERIES_ORDER", "cv_planar_model", "ca_model",
           "ctrv_model", "ctra_model", "motion_state_names", "motion_step", "motion_jacobian",
           "motion_noise_jacobian", "motion_process_noise", "ctrv_step", "ctrv_jacobian",
           "ctrv_noise_jacobian"]

#: The planar motion models, in the order the course introduces them.
MOTION_MODELS = ("cv", "ca", "ctrv", "ctra")

#: Below this |ω T| (rad) the turning models use their Taylor series in ω.
OMEGA_SERIES_THRESHOLD = 0.02

#: Order of that series: terms up to ω^(SERIES_ORDER − 1) are kept. At the threshold the
#: first dropped term is below 1e-15 of the step's displacement.
SERIES_ORDER = 8


def _motion_symbols():
    """The shared symbols of the planar models (one set, so the models compose)."""
    T, t = sp.symbols("T t", nonnegative=True)
    px, py, vx, vy, ax, ay, v, a, psi, om = sp.symbols(
        r"p_x p_y v_x v_y a_x a_y v a psi omega", real=True)
    jx, jy, nu_a, nu_yaw, nu_j = sp.symbols(r"j_x j_y nu_a nu_psiddot nu_j", real=True)
    return types.SimpleNamespace(T=T, t=t, px=px, py=py, vx=vx, vy=vy, ax=ax, ay=ay, v=v, a=a,
                                 psi=psi, om=om, jx=jx, jy=jy, nu_a=nu_a, nu_yaw=nu_yaw, nu_j=nu_j)


def _turn_integrals(s, speed, order=None):
    """∫₀ᵀ speed(t) (cos ψ(t), sin ψ(t)) dt with ψ(t) = ψ + ω t.

    With ``order`` None SymPy integrates in closed form (ω ≠ 0); otherwise the integrand's
    Taylor polynomial in ω, cos(ψ + ω t) = Σ (ω t)^k / k! · cos(ψ + k π/2), is integrated
    term by term (exact to that order, and finite at ω = 0).
    """
    t, T, om, psi = s.t, s.T, s.om, s.psi
    if order is None:
        nonzero = sp.Symbol("w_nz", real=True, nonzero=True)  # ω ≠ 0 for the closed form
        cx = sp.integrate(speed * sp.cos(psi + nonzero * t), (t, 0, T)).subs(nonzero, om)
        cy = sp.integrate(speed * sp.sin(psi + nonzero * t), (t, 0, T)).subs(nonzero, om)
        return cx, cy
    cos_terms = sum((om * t) ** k / sp.factorial(k) * sp.cos(psi + k * sp.pi / 2) for k in range(order))
    sin_terms = sum((om * t) ** k / sp.factorial(k) * sp.sin(psi + k * sp.pi / 2) for k in range(order))
    cx = sp.integrate(sp.expand(speed * cos_terms), (t, 0, T))
    cy = sp.integrate(sp.expand(speed * sin_terms), (t, 0, T))
    return sp.expand(cx), sp.expand(cy)


@functools.cache
def _model_parts(name: str) -> dict:
    """Symbols, continuous dynamics and exact (and series) discrete model of one planar model."""
    s = _motion_symbols()
    T = s.T
    h2, h3 = T**2 / 2, T**3 / 6
    if name == "cv":
        x = [s.px, s.py, s.vx, s.vy]
        w = [s.ax, s.ay]
        dyn = sp.Matrix([s.vx, s.vy, 0, 0])
        f0 = sp.Matrix([s.px + s.vx * T, s.py + s.vy * T, s.vx, s.vy])
        noise = sp.Matrix([h2 * s.ax, h2 * s.ay, T * s.ax, T * s.ay])
        series = None
        title = "Constant velocity (CV), planar"
    elif name == "ca":
        x = [s.px, s.py, s.vx, s.vy, s.ax, s.ay]
        w = [s.jx, s.jy]
        dyn = sp.Matrix([s.vx, s.vy, s.ax, s.ay, 0, 0])
        f0 = sp.Matrix([s.px + s.vx * T + s.ax * h2, s.py + s.vy * T + s.ay * h2,
                        s.vx + s.ax * T, s.vy + s.ay * T, s.ax, s.ay])
        noise = sp.Matrix([h3 * s.jx, h3 * s.jy, h2 * s.jx, h2 * s.jy, T * s.jx, T * s.jy])
        series = None
        title = "Constant acceleration (CA), planar"
    elif name in ("ctrv", "ctra"):
        accel = name == "ctra"
        x = [s.px, s.py, s.v, s.psi, s.om] + ([s.a] if accel else [])
        w = [s.nu_j if accel else s.nu_a, s.nu_yaw]
        speed = s.v + s.a * s.t if accel else s.v
        dyn = sp.Matrix([s.v * sp.cos(s.psi), s.v * sp.sin(s.psi), s.a if accel else 0, s.om, 0]
                        + ([0] if accel else []))
        nu = w[0]
        cx, cy = _turn_integrals(s, speed)
        sx, sy = _turn_integrals(s, speed, SERIES_ORDER)
        tail = [s.v + s.a * T, s.psi + s.om * T, s.om, s.a] if accel else [s.v, s.psi + s.om * T, s.om]
        f0 = sp.Matrix([s.px + cx, s.py + cy] + tail)
        series = sp.Matrix([s.px + sx, s.py + sy] + tail)
        if accel:   # a jerk ν_j held over the step, along the heading
            noise = sp.Matrix([h3 * sp.cos(s.psi) * nu, h3 * sp.sin(s.psi) * nu, h2 * nu, T * nu,
                               h2 * s.nu_yaw, T * s.nu_yaw])
        else:       # an acceleration ν_a held over the step, along the heading
            noise = sp.Matrix([h2 * sp.cos(s.psi) * nu, h2 * sp.sin(s.psi) * nu, T * nu,
                               h2 * s.nu_yaw, T * s.nu_yaw])
        title = ("Constant turn rate and acceleration (CTRA)" if accel
                 else "Constant turn rate and velocity (CTRV)")
    else:
        raise KeyError(f"unknown motion model {name!r}; known: {MOTION_MODELS}")
    return dict(s=s, x=x, w=w, dyn=dyn, f0=f0, series=series, noise=noise, title=title)


def _model_derivation(name: str, registry_name: str) -> Derivation:
    """The derivation of model ``name`` ("cv", "ca", "ctrv", "ctra"), registered as ``registry_name``."""
    parts = _model_parts(name)
    s, x, w, dyn, f0, series, noise = (parts[k] for k in ("s", "x", "w", "dyn", "f0", "series", "noise"))
    T = s.T
    X, W = sp.Matrix(x), sp.Matrix(w)
    f = f0 + noise
    at_zero_noise = {wi: 0 for wi in w}
    F = f.jacobian(X).subs(at_zero_noise)
    B = f.jacobian(W).subs(at_zero_noise)
    flow = dyn.subs(dict(zip(x, list(f0))), simultaneous=True)
    state = r"[" + ", ".join(sp.latex(xi) for xi in x) + r"]"
    equations = [
        Equation("dynamics", sp.Matrix([sp.Symbol(r"\dot{" + sp.latex(xi) + "}") for xi in x]), dyn,
                 "the continuous-time model (noise-free)", "definition"),
        Equation("flow", sp.Derivative(sp.ImmutableMatrix(f0), T), flow,
                 r"the discrete model $f(x, 0, T)$ solves the ODE: $\partial f / \partial T$ is the "
                 r"dynamics evaluated at $f$ ..."),
        Equation("initial", sp.Subs(sp.ImmutableMatrix(f0), T, 0), X,
                 r"... and starts at the state: $f(x, 0, 0) = x$"),
        Equation("noise_linear", f - f0, B * W,
                 r"the noise held over the step enters linearly, $f(x, w) = f(x, 0) + B w$"),
        Equation("motion_jacobian", sp.MatrixSymbol("F", len(x), len(x)), F,
                 r"$F = \partial f / \partial x$ at $w = 0$, derived by SymPy", "definition"),
        Equation("noise_jacobian", sp.MatrixSymbol("B", len(x), len(w)), B,
                 r"$B = \partial f / \partial w$ at $w = 0$", "definition"),
    ]
    results = {"f": f0, "f_noisy": f, "F": F, "B": B, "dynamics": dyn}
    if series is not None:
        om = s.om
        Fs = (series + noise).jacobian(X).subs(at_zero_noise)
        straight = f0.applyfunc(lambda e: sp.Limit(e, om, 0))
        equations += [
            Equation("limit_straight", straight, series.subs(om, 0),
                     r"as $\omega \to 0$ the turn becomes a straight line, and the series branch "
                     r"at $\omega = 0$ is that limit"),
            Equation("series", sp.MatrixSymbol(r"f_{\mathrm{series}}", len(x), 1), series,
                     rf"for $|\omega T| < {OMEGA_SERIES_THRESHOLD}$ the numeric model uses the Taylor "
                     rf"series of the integrand in $\omega$ up to $\omega^{{{SERIES_ORDER - 1}}}$",
                     "definition"),
        ]
        results.update({"f_series": series, "F_series": Fs})
    symbols = {str(xi): xi for xi in x} | {str(wi): wi for wi in w} | {"T": T}
    return Derivation(
        name=registry_name,
        title=parts["title"],
        model=(rf"Planar state ${state}$, noise $w = [{', '.join(sp.latex(wi) for wi in w)}]$ held "
               r"constant over a step of $T$ seconds. The exact discrete model is the ODE's flow; "
               r"its Jacobians are derived, never typed."),
        equations=tuple(equations),
        symbols=symbols,
        results=results,
    )


@derivation_builder
def cv_planar_model() -> Derivation:
    """Planar constant velocity, state [p_x, p_y, v_x, v_y], noise [a_x, a_y]."""
    return _model_derivation("cv", "cv_planar_model")


@derivation_builder
def ca_model() -> Derivation:
    """Planar constant acceleration, state [p_x, p_y, v_x, v_y, a_x, a_y], noise [j_x, j_y]."""
    return _model_derivation("ca", "ca_model")


@derivation_builder
def ctrv_model() -> Derivation:
    """Constant turn rate and velocity, state [p_x, p_y, v, ψ, ω], noise [ν_a, ν_ψ̈]."""
    return _model_derivation("ctrv", "ctrv_model")


@derivation_builder
def ctra_model() -> Derivation:
    """Constant turn rate and acceleration, state [p_x, p_y, v, ψ, ω, a], noise [ν_j, ν_ψ̈]."""
    return _model_derivation("ctra", "ctra_model")


#: The derivation of each model of :data:`MOTION_MODELS`, whose results are lambdified below.
_DERIVATION_OF_MODEL = {"cv": cv_planar_model, "ca": ca_model, "ctrv": ctrv_model, "ctra": ctra_model}


# --------------------------------------------------------------------------------------
# Numeric models, lambdified once from the expressions above
# --------------------------------------------------------------------------------------

@functools.cache
def _model_functions(name: str) -> dict:
    """The numpy functions of model ``name``: f, F, B (and the ω-series f, F), lambdified once."""
    d = _DERIVATION_OF_MODEL[name]()
    parts = _model_parts(name)
    x, w, T = parts["x"], parts["w"], parts["s"].T
    args = list(x) + list(w) + [T]
    fns = {
        "n": len(x), "m": len(w),
        "f": lambdify_matrix(args, d.results["f_noisy"]),
        "F": lambdify_matrix(list(x) + [T], d.results["F"]),
        "B": lambdify_matrix(list(x) + [T], d.results["B"]),
    }
    if "f_series" in d.results:
        noise = d.results["f_noisy"] - d.results["f"]
        fns["f_series"] = lambdify_matrix(args, d.results["f_series"] + noise)
        fns["F_series"] = lambdify_matrix(list(x) + [T], d.results["F_series"])
        fns["omega_index"] = x.index(parts["s"].om)
    return fns


def motion_state_names(model: str) -> tuple[str, ...]:
    """Names of the state components of ``model``, in order.

    Parameters
    ----------
    model : {"cv", "ca", "ctrv", "ctra"}

    Returns
    -------
    tuple of str
        For example ``("p_x", "p_y", "v", "psi", "omega")`` for CTRV (the names of the
        derivation's state symbols).
    """
    names = {"cv": ("p_x", "p_y", "v_x", "v_y"), "ca": ("p_x", "p_y", "v_x", "v_y", "a_x", "a_y"),
             "ctrv": ("p_x", "p_y", "v", "psi", "omega"),
             "ctra": ("p_x", "p_y", "v", "psi", "omega", "a")}
    if not isinstance(model, str) or model not in names:
        raise ValueError(f"model must be one of {MOTION_MODELS}, got {model!r}")
    return names[model]


def _model_args(model, x, T):
    """Validate the arguments of a model function; also say whether the ω-series applies."""
    if model not in MOTION_MODELS:
        raise ValueError(f"model must be one of {MOTION_MODELS}, got {model!r}")
    fns = _model_functions(model)
    try:
        x = as_vector(x, "x", fns["n"])
    except ValueError as err:
        raise ValueError(f"{err} (the {model} state is {list(motion_state_names(model))})") from None
    T = as_time_step(T)
    series = "omega_index" in fns and abs(x[fns["omega_index"]] * T) < OMEGA_SERIES_THRESHOLD
    return fns, x, T, series


def motion_step(model: str, x, T, w=None) -> np.ndarray:
    """Propagate a planar state over one step: :math:`f(x, w, T)`.

    Parameters
    ----------
    model : {"cv", "ca", "ctrv", "ctra"}
    x : array_like, shape (n,)
        State in the order of :func:`motion_state_names`.
    T : float
        Step, s (>= 0).
    w : array_like, shape (2,), optional
        Process noise held constant over the step (see the module notes); default zero.

    Returns
    -------
    ndarray, shape (n,)
        The exact flow of the model. The turning models use their ω-series for
        ``|ω T| < OMEGA_SERIES_THRESHOLD``.
    """
    fns, x, T, series = _model_args(model, x, T)
    w = np.zeros(fns["m"]) if w is None else as_vector(w, "w", fns["m"])
    fn = fns["f_series"] if series else fns["f"]
    return np.asarray(fn(*x, *w, T), dtype=float).reshape(-1)


def motion_jacobian(model: str, x, T) -> np.ndarray:
    """Motion Jacobian :math:`F = \\partial f / \\partial x` at (x, w = 0).

    Parameters
    ----------
    model : {"cv", "ca", "ctrv", "ctra"}
    x : array_like, shape (n,)
        State in the order of :func:`motion_state_names`.
    T : float
        Step, s (>= 0).

    Returns
    -------
    F : ndarray, shape (n, n)
        Derived by SymPy from the exact flow (from its ω-series for
        ``|ω T| < OMEGA_SERIES_THRESHOLD``).
    """
    fns, x, T, series = _model_args(model, x, T)
    fn = fns["F_series"] if series else fns["F"]
    return np.asarray(fn(*x, T), dtype=float)


def motion_noise_jacobian(model: str, x, T) -> np.ndarray:
    """Process-noise Jacobian :math:`B = \\partial f / \\partial w` at (x, w = 0).

    Parameters
    ----------
    model : {"cv", "ca", "ctrv", "ctra"}
    x : array_like, shape (n,)
        State in the order of :func:`motion_state_names`.
    T : float
        Step, s (>= 0).

    Returns
    -------
    B : ndarray, shape (n, 2)
        How the two noise components of ``model``, held over the step, move the state.
    """
    fns, x, T, _ = _model_args(model, x, T)
    return np.asarray(fns["B"](*x, T), dtype=float)


def motion_process_noise(model: str, x, T, sigmas) -> np.ndarray:
    """Process noise in state space, :math:`B \\, \\mathrm{diag}(\\sigma^2) \\, B^T`.

    Parameters
    ----------
    model : {"cv", "ca", "ctrv", "ctra"}
    x : array_like, shape (n,)
        State in the order of :func:`motion_state_names`.
    T : float
        Step, s (>= 0).
    sigmas : array_like, shape (2,)
        Standard deviations of the two noise components of ``model`` (for CTRV: σ_a in
        m/s² and σ_ψ̈ in rad/s²).

    Returns
    -------
    Q : ndarray, shape (n, n)
        ``B diag(sigmas²) Bᵀ`` with B from :func:`motion_noise_jacobian`.
    """
    sigmas = as_vector(sigmas, "sigmas", 2)
    B = motion_noise_jacobian(model, x, T)
    return (B * sigmas**2) @ B.T


def ctrv_step(x, T, w=None) -> np.ndarray:
    """CTRV step :math:`f(x, w, T)`: :func:`motion_step` with ``model="ctrv"``.

    Parameters
    ----------
    x : array_like, shape (5,)
        State [p_x (m), p_y (m), v (m/s), ψ (rad), ω (rad/s)].
    T : float
        Step, s (>= 0).
    w : array_like, shape (2,), optional
        Noise [ν_a (m/s²), ν_ψ̈ (rad/s²)] held over the step; default zero.

    Returns
    -------
    ndarray, shape (5,)
    """
    return motion_step("ctrv", x, T, w)


def ctrv_jacobian(x, T) -> np.ndarray:
    """CTRV motion Jacobian F, shape (5, 5), at the state x (5,) for a step T (s).

    :func:`motion_jacobian` with ``model="ctrv"``.
    """
    return motion_jacobian("ctrv", x, T)


def ctrv_noise_jacobian(x, T) -> np.ndarray:
    """CTRV process-noise Jacobian B, shape (5, 2), for w = [ν_a, ν_ψ̈] at the state x (5,).

    :func:`motion_noise_jacobian` with ``model="ctrv"``; T is the step in s.
    """
    return motion_noise_jacobian("ctrv", x, T)
