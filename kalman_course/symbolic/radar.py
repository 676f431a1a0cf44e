"""The radar observation, derived (chapter 05): range, bearing and range rate of a target
seen from the origin, and its Jacobian.

:func:`radar_model` writes h(x) once for the Cartesian state [p_x, p_y, v_x, v_y] and lets
SymPy derive G = ∂h/∂x, both for that state and, by substituting v_x = v cos ψ,
v_y = v sin ψ, for the turning models' [p_x, p_y, v, ψ, ω(, a)]. :func:`radar_observation`
and :func:`radar_jacobian` are those expressions lambdified (once, cached) for any state
layout of :mod:`kalman_course.symbolic.motion`.
"""

from __future__ import annotations

import functools

import numpy as np
import sympy as sp

from kalman_course.core.validation import as_vector
from kalman_course.symbolic.equations import Derivation, Equation, derivation_builder
from kalman_course.symbolic.motion import MOTION_MODELS, motion_state_names
from kalman_course.symbolic.numeric import lambdify_matrix

__all__ = ["radar_model", "radar_observation", "radar_jacobian"]


@derivation_builder
def radar_model() -> Derivation:
    """The radar observation (range, bearing, range rate) and its Jacobian.

    Written for the Cartesian state [p_x, p_y, v_x, v_y]; the CTRV/CTRA form follows by
    substituting v_x = v cos ψ, v_y = v sin ψ.
    """
    px, py, vx, vy = sp.symbols("p_x p_y v_x v_y", real=True)
    v, psi = sp.symbols("v psi", real=True)
    rho = sp.sqrt(px**2 + py**2)
    h = sp.Matrix([rho, sp.atan2(py, px), (px * vx + py * vy) / rho])
    X = sp.Matrix([px, py, vx, vy])
    G = h.jacobian(X)
    c1 = px**2 + py**2
    c2 = sp.sqrt(c1)
    c3 = c1 * c2
    # the Jacobian as the seed article writes it out by hand
    G_hand = sp.Matrix([[px / c2, py / c2, 0, 0],
                        [-py / c1, px / c1, 0, 0],
                        [py * (vx * py - vy * px) / c3, px * (px * vy - py * vx) / c3, px / c2, py / c2]])
    polar = {vx: v * sp.cos(psi), vy: v * sp.sin(psi)}
    h_turn = h.subs(polar)
    om, a = sp.symbols("omega a", real=True)
    X_turn = sp.Matrix([px, py, v, psi, om])
    G_turn = h_turn.jacobian(X_turn)
    chain = G.subs(polar) * sp.Matrix([px, py, v * sp.cos(psi), v * sp.sin(psi)]).jacobian(X_turn)
    equations = [
        Equation("observation", sp.Matrix(sp.symbols("rho phi rhodot")), h,
                 r"range, bearing (atan2, in $(-\pi, \pi]$) and range rate, the velocity projected on "
                 r"the line of sight", "definition"),
        Equation("jacobian_hand", G, G_hand,
                 "SymPy's Jacobian equals the hand-derived one of the lecture"),
        Equation("range_rate_is_derivative", h[2], (sp.diff(rho, px) * vx + sp.diff(rho, py) * vy),
                 r"the range rate is $d\rho/dt = \nabla \rho \cdot v$"),
        Equation("jacobian_turn_chain", G_turn, chain,
                 r"for the CTRV state the Jacobian is the Cartesian one times the Jacobian of "
                 r"$(v, \psi) \mapsto (v \cos\psi, v \sin\psi)$ (chain rule)"),
    ]
    return Derivation(
        name="radar_model",
        title="Radar observation: range, bearing, range rate",
        model=(r"A radar at the origin measures $y = h(x) + n$, $n \sim \mathcal{N}(0, R)$, of a target "
               r"with position $(p_x, p_y)$ and velocity $(v_x, v_y)$ (for the turning models "
               r"$v_x = v \cos\psi$, $v_y = v \sin\psi$)."),
        equations=tuple(equations),
        symbols={"p_x": px, "p_y": py, "v_x": vx, "v_y": vy, "v": v, "psi": psi, "omega": om, "a": a},
        results={"h": h, "G": G, "h_turn": h_turn, "G_turn": G_turn},
    )


# --------------------------------------------------------------------------------------
# Numeric radar observation, lambdified once from the expressions above
# --------------------------------------------------------------------------------------

@functools.cache
def _radar_functions() -> dict:
    """h and G for the Cartesian and the turning-model layouts, lambdified once."""
    d = radar_model()
    sy = d.symbols
    cart = [sy["p_x"], sy["p_y"], sy["v_x"], sy["v_y"]]
    turn = [sy["p_x"], sy["p_y"], sy["v"], sy["psi"]]
    G_turn = d.results["G_turn"][:, :4]       # ∂h/∂ω = 0
    return {"h_cart": lambdify_matrix(cart, d.results["h"]), "G_cart": lambdify_matrix(cart, d.results["G"]),
            "h_turn": lambdify_matrix(turn, d.results["h_turn"]), "G_turn": lambdify_matrix(turn, G_turn)}


def _radar_state(x, model: str):
    """Validate a state of the layout of ``model``; return it and its size."""
    if model not in MOTION_MODELS:
        raise ValueError(f"model must be one of {MOTION_MODELS}, got {model!r}")
    n = len(motion_state_names(model))
    x = as_vector(x, "x", n)
    if np.hypot(x[0], x[1]) < 1e-9:
        raise ValueError("x must not be at the radar's position (range 0 has no bearing)")
    return x, n


def radar_observation(x, model: str = "ctrv") -> np.ndarray:
    """Radar measurement function h(x) of a target seen from a radar at the origin.

    Parameters
    ----------
    x : array_like, shape (n,)
        Target state in the layout of ``model``
        (:func:`~kalman_course.symbolic.motion.motion_state_names`); not at the origin.
    model : {"cv", "ca", "ctrv", "ctra"}
        The state layout; default CTRV.

    Returns
    -------
    ndarray, shape (3,)
        [ρ (m), φ (rad, in (−π, π]), ρ̇ (m/s)]: range, bearing, range rate.
    """
    x, _ = _radar_state(x, model)
    fn = _radar_functions()["h_cart" if model in ("cv", "ca") else "h_turn"]
    return np.asarray(fn(*x[:4]), dtype=float).reshape(-1)


def radar_jacobian(x, model: str = "ctrv") -> np.ndarray:
    """Radar observation Jacobian G = ∂h/∂x, derived by SymPy.

    Parameters
    ----------
    x : array_like, shape (n,)
        Target state in the layout of ``model``; not at the origin.
    model : {"cv", "ca", "ctrv", "ctra"}
        The state layout; default CTRV.

    Returns
    -------
    G : ndarray, shape (3, n)
        Zero in the columns of ω and a, which h does not depend on.
    """
    x, n = _radar_state(x, model)
    G = np.zeros((3, n))
    fn = _radar_functions()["G_cart" if model in ("cv", "ca") else "G_turn"]
    G[:, :4] = np.asarray(fn(*x[:4]), dtype=float)
    return G
