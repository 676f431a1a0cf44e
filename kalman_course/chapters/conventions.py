"""The four error-state conventions of an ESKF and how they turn into one another (appendix A1).

Books, papers and code define the ESKF's error differently along two independent choices:

- the **error sign**: ``"nominal - true"`` (this course and lecture 08: δp = p̌ − p, Ř = R Exp(δθ))
  or ``"true - nominal"`` (δp = p − p̌, R = Ř Exp(δθ));
- the **attitude side**: ``"right"``, Exp(δθ) multiplies the attitude on the right, so δθ is
  resolved in the body frame; or ``"left"``, Exp(δθ) on the left, δθ in the navigation frame.

All conventions describe the same physics: the errors of one are a fixed function of the
errors of another (δθ_left = Ř δθ_right exactly, the sign flips every block), so their error
dynamics are related by a change of variables and their injections are inverse to their
definitions. This module writes each definition once and derives the rest from it:

:func:`error_state`, :func:`nominal_with_error`, :func:`inject`
    the exact error between a nominal and a true state, a nominal state carrying a given
    error, and the injection (the estimate of the true state from the nominal one and δx̂);
:func:`error_dynamics`
    F_t of each convention, obtained from the course's F_t
    (:func:`kalman_course.filters.eskf.error_dynamics`) by the change of variables;
:func:`flow`, :func:`error_rate`, :func:`dynamics_residual`
    exact kinematics over a short time for constant IMU readings, the rate of the exact
    error by central differences, and how far F_t δx is from it;
:func:`injection_error`, :func:`injection_miss`, :func:`identify_injection`
    what error an injection formula leaves (and its size relative to the error
    injected), and which convention a given injection
    function belongs to (inject a known error, see which way it moves);
:func:`seed_framework_dynamics`, :func:`velocity_rate`
    the lecture notes' framework block −C_nb[f_n]× written literally, and the velocity
    rate with gravity entering with either sign;
:func:`example_case`, :func:`mixing_table`
    the seeded, simulated state the appendix checks everything on, and a text table.

The error state is ordered [δp, δv, δθ, δb_a, δb_ω] (15) in every convention; states are
:class:`kalman_course.filters.eskf.NominalState` (also for the true state).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core import so3
from kalman_course.core.validation import as_real, as_rotation, as_scalar, as_seed, as_vector
from kalman_course.filters import eskf
from kalman_course.filters.eskf import IDX_BA, IDX_BW, IDX_P, IDX_TH, IDX_V, NominalState

__all__ = ["ERROR_SIGNS", "SIDES", "Convention", "CONVENTIONS", "COURSE", "as_convention", "error_state",
           "nominal_with_error", "inject", "attitude_error_to_left", "error_dynamics", "flow", "error_rate",
           "dynamics_residual", "injection_error", "injection_miss", "identify_injection", "seed_framework_dynamics",
           "velocity_rate", "Case", "example_case", "mixing_table"]

#: The two error signs: the course's (lecture 08) first.
ERROR_SIGNS = ("nominal - true", "true - nominal")
#: The two attitude sides: right (δθ in the body frame), left (δθ in the navigation frame).
SIDES = ("right", "left")

_FRAME = {"right": "body", "left": "navigation"}
# nodes and weights of 8-point Gauss–Legendre quadrature, mapped from [−1, 1] to [0, 1]
_GL_NODES, _GL_WEIGHTS = np.polynomial.legendre.leggauss(8)
_GL_NODES, _GL_WEIGHTS = 0.5 * (_GL_NODES + 1.0), 0.5 * _GL_WEIGHTS


@dataclass(frozen=True)
class Convention:
    """One error-state convention: an error sign and an attitude side.

    Attributes
    ----------
    error : str
        ``"nominal - true"`` or ``"true - nominal"``.
    side : str
        ``"right"`` (Exp(δθ) right of the attitude, δθ in the body frame) or ``"left"``
        (Exp(δθ) left of it, δθ in the navigation frame).
    """

    error: str
    side: str

    def __post_init__(self):
        if self.error not in ERROR_SIGNS:
            raise ValueError(f"error must be one of {ERROR_SIGNS}, got {self.error!r}")
        if self.side not in SIDES:
            raise ValueError(f"side must be one of {SIDES}, got {self.side!r}")

    @property
    def sign(self) -> float:
        """+1 for nominal − true, −1 for true − nominal: δp = sign · (p̌ − p)."""
        return 1.0 if self.error == ERROR_SIGNS[0] else -1.0

    @property
    def frame(self) -> str:
        """The frame δθ is resolved in: ``"body"`` (right) or ``"navigation"`` (left)."""
        return _FRAME[self.side]

    @property
    def label(self) -> str:
        """A short name, e.g. ``"nominal - true, right (body)"``."""
        return f"{self.error}, {self.side} ({self.frame})"


#: The four conventions: (nominal − true, true − nominal) × (right, left).
CONVENTIONS = tuple(Convention(e, s) for e in ERROR_SIGNS for s in SIDES)
#: The course's convention (lecture 08, :mod:`kalman_course.filters.eskf`).
COURSE = Convention(ERROR_SIGNS[0], "right")


def as_convention(value, name: str = "convention") -> Convention:
    """Return ``value`` as a :class:`Convention` (a Convention or an (error, side) pair).

    Raises
    ------
    ValueError
        Naming ``name``, if ``value`` is neither, or names an unknown sign or side.
    """
    if isinstance(value, Convention):
        return value
    if isinstance(value, (tuple, list)) and len(value) == 2:
        try:
            return Convention(*value)
        except ValueError as exc:
            raise ValueError(f"{name}: {exc}") from None
    raise ValueError(f"{name} must be a Convention or an (error, side) pair such as "
                     f"('nominal - true', 'right'), got {value!r}")


def _as_state(value, name: str) -> NominalState:
    if not isinstance(value, NominalState):
        raise ValueError(f"{name} must be a NominalState (position, velocity, rotation, biases), "
                         f"got {type(value).__name__}")
    return NominalState(np.array(as_vector(value.position, f"{name}.position", 3)),
                        np.array(as_vector(value.velocity, f"{name}.velocity", 3)),
                        np.array(as_rotation(value.rotation, f"{name}.rotation")),
                        np.array(as_vector(value.accel_bias, f"{name}.accel_bias", 3)),
                        np.array(as_vector(value.gyro_bias, f"{name}.gyro_bias", 3)))


def _rotate(R: np.ndarray, phi: np.ndarray, side: str) -> np.ndarray:
    """R Exp(φ) (right) or Exp(φ) R (left)."""
    E = so3.exp(phi)
    return R @ E if side == "right" else E @ R


def _compose(state: NominalState, dx: np.ndarray, side: str) -> NominalState:
    """Add dx (15,) to a state: vectors add, the attitude is multiplied by Exp(dx_θ) on ``side``."""
    return NominalState(state.position + dx[IDX_P], state.velocity + dx[IDX_V],
                        _rotate(state.rotation, dx[IDX_TH], side),
                        state.accel_bias + dx[IDX_BA], state.gyro_bias + dx[IDX_BW])


def error_state(nominal, true, convention) -> np.ndarray:
    """The exact error δx (15,) between a nominal and a true state, in ``convention``.

    nominal − true: δp = p̌ − p, δv = v̌ − v, δb = b̌ − b and Ř = R Exp(δθ) (right) or
    Ř = Exp(δθ) R (left); true − nominal: the vectors the other way and R = Ř Exp(δθ) (right)
    or R = Exp(δθ) Ř (left). δθ is taken with Log, so it is exact for rotation angles below π.

    Parameters
    ----------
    nominal, true : NominalState
        The two states (p, v (3,) in the navigation frame, R = R_nb (3, 3), b_a, b_ω (3,)).
    convention : Convention or (str, str)

    Returns
    -------
    numpy.ndarray, shape (15,)
        [δp, δv, δθ, δb_a, δb_ω].
    """
    x, t = _as_state(nominal, "nominal"), _as_state(true, "true")
    c = as_convention(convention)
    first, second = (x, t) if c.sign > 0 else (t, x)        # the error is "first − second"
    if c.side == "right":
        dtheta = so3.log(second.rotation.T @ first.rotation)   # first = second Exp(δθ)
    else:
        dtheta = so3.log(first.rotation @ second.rotation.T)   # first = Exp(δθ) second
    return np.concatenate([first.position - second.position, first.velocity - second.velocity, dtheta,
                           first.accel_bias - second.accel_bias, first.gyro_bias - second.gyro_bias])


def nominal_with_error(true, dx, convention) -> NominalState:
    """The nominal state whose error from ``true`` is ``dx`` in ``convention`` (the definition
    solved for the nominal state): :func:`error_state` of the result is ``dx``.

    Parameters
    ----------
    true : NominalState
    dx : array_like, shape (15,)
        [δp, δv, δθ, δb_a, δb_ω] (m, m/s, rad, m/s², rad/s).
    convention : Convention or (str, str)
    """
    t = _as_state(true, "true")
    c = as_convention(convention)
    return _compose(t, c.sign * as_vector(dx, "dx", 15), c.side)


def inject(nominal, dx_hat, convention) -> NominalState:
    """The injection of ``convention``: the estimate of the true state from the nominal state
    and the estimated error δx̂.

    nominal − true: p̂ = p̌ − δp̂ (and v, b), R̂ = Ř Exp(−δθ̂) (right) or Exp(−δθ̂) Ř (left);
    true − nominal: p̂ = p̌ + δp̂, R̂ = Ř Exp(δθ̂) (right) or Exp(δθ̂) Ř (left). With the exact
    error (:func:`error_state`) it returns the true state exactly.

    Parameters
    ----------
    nominal : NominalState
    dx_hat : array_like, shape (15,)
    convention : Convention or (str, str)
    """
    x = _as_state(nominal, "nominal")
    c = as_convention(convention)
    return _compose(x, -c.sign * as_vector(dx_hat, "dx_hat", 15), c.side)


def attitude_error_to_left(R_check, dtheta_right) -> np.ndarray:
    """δθ_left = Ř δθ_right (3,): the navigation-frame attitude error of the same pair of states.

    Exact in both error signs, because Ř Exp(φ) Řᵀ = Exp(Ř φ) for every rotation Ř (and, for
    nominal − true, Ř φ = R φ since Exp(φ) φ = φ).

    Parameters
    ----------
    R_check : array_like, shape (3, 3)
        The nominal attitude Ř = R_nb.
    dtheta_right : array_like, shape (3,)
        The body-frame (right) attitude error, rad.
    """
    return as_rotation(R_check, "R_check") @ as_vector(dtheta_right, "dtheta_right", 3)


def error_dynamics(nominal, specific_force, angular_rate, convention) -> np.ndarray:
    """F_t (15, 15) of δẋ = F_t δx in ``convention``, at the nominal state.

    The right-side F_t is the course's (:func:`kalman_course.filters.eskf.error_dynamics`,
    velocity–attitude block −Ř[ǎ]×). Flipping the sign of every error leaves F_t unchanged
    (δx → −δx on both sides of δẋ = F_t δx), so only the side matters. The left error is
    δx_left = T δx_right with T = diag(I, I, Ř, I, I) and Ṫ = diag(0, 0, Ř[ω̌]×, 0, 0), so
    F_left = (T F_right + Ṫ) T⁻¹: velocity–attitude block −[Ř ǎ]×, attitude block 0 and
    gyro-bias block −Ř.

    Parameters
    ----------
    nominal : NominalState
        Ř (3, 3) and the nominal biases b̌_a, b̌_ω (3,).
    specific_force, angular_rate : array_like, shape (3,)
        The IMU readings f (m/s²) and ω_m (rad/s), body frame; ǎ = f − b̌_a, ω̌ = ω_m − b̌_ω.
    convention : Convention or (str, str)
    """
    x = _as_state(nominal, "nominal")
    c = as_convention(convention)
    f = as_vector(specific_force, "specific_force", 3)
    w = as_vector(angular_rate, "angular_rate", 3)
    F = eskf.error_dynamics(x.rotation, f, w, x.accel_bias, x.gyro_bias)
    if c.side == "left":
        T, T_dot = np.eye(15), np.zeros((15, 15))
        T[IDX_TH, IDX_TH] = x.rotation
        T_dot[IDX_TH, IDX_TH] = x.rotation @ so3.hat(w - x.gyro_bias)
        T_inv = T.T.copy()                   # T is orthogonal: identity blocks and one rotation
        F = (T @ F + T_dot) @ T_inv
    return F


def flow(state, specific_force, angular_rate, gravity, t: float) -> NominalState:
    """The state after ``t`` seconds (t may be negative) of exact kinematics with constant readings.

    With a = f − b_a and ω = ω_m − b_ω (the state's own biases, which stay constant):
    R(t) = R Exp(ω t), v(t) = v + g t + t R J_l(ω t) a and p(t) = p + v t + ½ g t² + R I(t) a
    with I(t) = t² ∫₀¹ u J_l(ω t u) du (8-point Gauss–Legendre, exact to rounding for the
    short times used here), since ∫₀ᵗ Exp(ω s) ds = t J_l(ω t) (J_l the left Jacobian).

    Parameters
    ----------
    state : NominalState
    specific_force, angular_rate : array_like, shape (3,)
        f (m/s²) and ω_m (rad/s), body frame, held constant.
    gravity : array_like, shape (3,)
        g (m/s²), navigation frame, entering as v̇ = R a + g.
    t : float
        Time, s.
    """
    x = _as_state(state, "state")
    f = as_vector(specific_force, "specific_force", 3)
    w = as_vector(angular_rate, "angular_rate", 3)
    g = as_vector(gravity, "gravity", 3)
    t = as_real(t, "t")
    if not np.isfinite(t):
        raise ValueError(f"t must be a finite number of seconds, got {t!r}")
    a, omega = f - x.accel_bias, w - x.gyro_bias
    R = x.rotation
    inner = t * t * np.einsum("k,kij->ij", _GL_WEIGHTS * _GL_NODES,
                              so3.left_jacobian(np.outer(_GL_NODES, omega * t)))
    return NominalState(x.position + x.velocity * t + 0.5 * g * t * t + R @ inner @ a,
                        x.velocity + g * t + t * (R @ so3.left_jacobian(omega * t) @ a),
                        R @ so3.exp(omega * t), x.accel_bias, x.gyro_bias)


def error_rate(nominal, true, specific_force, angular_rate, gravity, convention, h: float = 1e-3) -> np.ndarray:
    """d(δx)/dt (15,) at t = 0 by central differences of the exact error.

    Both states are moved ±h seconds by :func:`flow` with the same readings (each subtracts
    its own biases); the rate is (δx(h) − δx(−h)) / 2h, with δx from :func:`error_state`.

    Parameters
    ----------
    nominal, true : NominalState
    specific_force, angular_rate, gravity : array_like, shape (3,)
        See :func:`flow`.
    convention : Convention or (str, str)
    h : float
        Half the difference interval, s (positive).
    """
    h = as_scalar(h, "h")
    ahead = error_state(flow(nominal, specific_force, angular_rate, gravity, h),
                        flow(true, specific_force, angular_rate, gravity, h), convention)
    behind = error_state(flow(nominal, specific_force, angular_rate, gravity, -h),
                         flow(true, specific_force, angular_rate, gravity, -h), convention)
    return (ahead - behind) / (2.0 * h)


def dynamics_residual(F, nominal, true, specific_force, angular_rate, gravity, convention,
                      h: float = 1e-3) -> float:
    """|F δx − d(δx)/dt| / |d(δx)/dt|: how far a candidate F_t is from the exact error rate.

    δx is the exact error of the pair in ``convention``; the rate comes from
    :func:`error_rate`. For the F_t of that convention the result is of the order of the
    error itself (the terms F_t drops are quadratic); for a wrong F_t it is of order one.

    Parameters
    ----------
    F : array_like, shape (15, 15)
        The candidate F_t.
    nominal, true, specific_force, angular_rate, gravity, convention, h
        As in :func:`error_rate`.
    """
    F = np.asarray(F, dtype=float)
    if F.shape != (15, 15) or not np.isfinite(F).all():
        raise ValueError(f"F must be a finite (15, 15) matrix, got shape {F.shape}")
    dx = error_state(nominal, true, convention)
    rate = error_rate(nominal, true, specific_force, angular_rate, gravity, convention, h)
    return float(np.linalg.norm(F @ dx - rate) / np.linalg.norm(rate))


def injection_error(true, dx, made_in, injected_with) -> np.ndarray:
    """The error (15,) left when an error made in one convention is injected with the formula
    of another.

    The nominal state is ``true`` carrying ``dx`` in ``made_in`` (:func:`nominal_with_error`);
    :func:`inject` of ``injected_with`` then estimates the true state. The result is the
    estimate's error in the course's convention (nominal − true, right): zero (to rounding)
    when the two conventions agree, and twice the injected error (±2·dx) when only the sign
    differs on the right side.

    Parameters
    ----------
    true : NominalState
    dx : array_like, shape (15,)
    made_in, injected_with : Convention or (str, str)
    """
    nominal = nominal_with_error(true, dx, as_convention(made_in, "made_in"))
    estimate = inject(nominal, dx, as_convention(injected_with, "injected_with"))
    return error_state(estimate, true, COURSE)


def injection_miss(true, dx, made_in, injected_with) -> float:
    """|error left after injection| / |dx| (see :func:`injection_error`).

    Zero (to rounding) when the two conventions agree; 2 for the opposite sign on the same
    side (the correction went the wrong way); of order one for the other side.

    Parameters
    ----------
    true : NominalState
    dx : array_like, shape (15,)
        Not all zero.
    made_in, injected_with : Convention or (str, str)
    """
    dx = as_vector(dx, "dx", 15)
    size = float(np.linalg.norm(dx))
    if size == 0.0:
        raise ValueError("dx must not be zero (the miss is relative to |dx|)")
    return float(np.linalg.norm(injection_error(true, dx, made_in, injected_with))) / size


def identify_injection(inject_fn, true, dx) -> dict:
    """Which convention an injection function uses: inject a known error, see which way it moves.

    For each of :data:`CONVENTIONS`, a nominal state is made from ``true`` with the error
    ``dx`` in that convention, ``inject_fn(nominal, dx)`` is called, and the miss
    |error left| / |dx| is recorded (as in :func:`injection_miss`). The function's own
    convention gives a miss near zero (exactly zero for an exact formula, of the order of
    |dx| for a first-order one such as R(I − [δθ]×)); the others give misses of order one.

    Parameters
    ----------
    inject_fn : callable
        ``inject_fn(nominal: NominalState, dx: ndarray (15,)) -> NominalState``.
    true : NominalState
    dx : array_like, shape (15,)
        A known error, not zero, with every block non-zero to tell the conventions apart.

    Returns
    -------
    dict
        Convention -> miss (float).
    """
    if not callable(inject_fn):
        raise ValueError(f"inject_fn must be callable (nominal, dx) -> NominalState, got {type(inject_fn).__name__}")
    dx = as_vector(dx, "dx", 15)
    size = float(np.linalg.norm(dx))
    if size == 0.0:
        raise ValueError("dx must not be zero (the miss is relative to |dx|)")
    misses = {}
    for c in CONVENTIONS:
        estimate = inject_fn(nominal_with_error(true, dx, c), dx.copy())
        misses[c] = float(np.linalg.norm(error_state(estimate, true, COURSE))) / size
    return misses


def seed_framework_dynamics(nominal, specific_force, angular_rate, force_frame: str = "navigation") -> np.ndarray:
    """The course's F_t with the velocity–attitude block written as the notes' framework writes
    it, −C_nb[f_n]× (C_nb = Ř), taking f_n in ``force_frame``.

    ``"navigation"``: f_n = Ř ǎ, the navigation-frame specific force its name announces;
    ``"body"``: f_n = ǎ, the bias-corrected body-frame reading (then the block is the
    course's −Ř[ǎ]×).

    Parameters
    ----------
    nominal : NominalState
    specific_force, angular_rate : array_like, shape (3,)
        f (m/s²), ω_m (rad/s), body frame.
    force_frame : str
        ``"navigation"`` or ``"body"``.
    """
    if force_frame not in ("navigation", "body"):
        raise ValueError(f"force_frame must be 'navigation' or 'body', got {force_frame!r}")
    x = _as_state(nominal, "nominal")
    F = error_dynamics(x, specific_force, angular_rate, COURSE)
    a = as_vector(specific_force, "specific_force", 3) - x.accel_bias
    f_n = x.rotation @ a if force_frame == "navigation" else a
    F[IDX_V, IDX_TH] = -x.rotation @ so3.hat(f_n)
    return F


def velocity_rate(rotation, specific_force, gravity, gravity_sign: float = 1.0) -> np.ndarray:
    """v̇ = R f + s g (3,): the mechanisation's velocity rate with gravity entering with sign s.

    The course (and Solà, the Toronto project) write v̇ = R f + g with g the gravitational
    acceleration (pointing down); the lecture notes write v̇ = R a − g, so their g points up.

    Parameters
    ----------
    rotation : array_like, shape (3, 3)
        R = R_nb.
    specific_force : array_like, shape (3,)
        Bias-corrected accelerometer reading, body frame, m/s².
    gravity : array_like, shape (3,)
        The gravity vector as the source defines it, navigation frame, m/s².
    gravity_sign : float
        +1 or −1.
    """
    if isinstance(gravity_sign, (bool, np.bool_, str)) or gravity_sign not in (1, -1):
        raise ValueError(f"gravity_sign must be +1 or -1, got {gravity_sign!r}")
    R = as_rotation(rotation, "rotation")
    return R @ as_vector(specific_force, "specific_force", 3) + gravity_sign * as_vector(gravity, "gravity", 3)


@dataclass(frozen=True)
class Case:
    """A simulated pair of states and IMU readings to check the conventions on.

    Attributes
    ----------
    true, nominal : NominalState
        The true state and a nominal state close to it.
    dx : numpy.ndarray, shape (15,)
        The error of ``nominal`` in the course's convention (nominal − true, right).
    specific_force, angular_rate : numpy.ndarray, shape (3,)
        Constant IMU readings f (m/s²) and ω_m (rad/s), body frame.
    gravity : numpy.ndarray, shape (3,)
        g (m/s²), navigation frame (z up).
    seed : int
    """

    true: NominalState
    nominal: NominalState
    dx: np.ndarray
    specific_force: np.ndarray
    angular_rate: np.ndarray
    gravity: np.ndarray
    seed: int


def example_case(seed: int = 0, error_scale: float = 1e-4, gravity=(0.0, 0.0, -9.8092)) -> Case:
    """A seeded, simulated case: a random attitude, a turning and accelerating IMU, small errors.

    The true attitude is Exp(φ) with φ uniform on a ball of radius π (so any rotation);
    the readings are a non-zero specific force (gravity's reaction plus about 1 m/s² of
    manoeuvre) and an angular rate of a few tenths of rad/s; the biases are non-zero. The
    error (course convention) has every component of size ``error_scale`` times a standard
    normal draw, in its own unit (m, m/s, rad, m/s², rad/s).

    Parameters
    ----------
    seed : int
        Seed of ``numpy.random.default_rng``.
    error_scale : float
        Size of the error, positive.
    gravity : array_like, shape (3,)
        g, m/s², navigation frame.
    """
    rng = np.random.default_rng(as_seed(seed))
    error_scale = as_scalar(error_scale, "error_scale")
    g = np.array(as_vector(gravity, "gravity", 3))
    axis = rng.normal(size=3)
    phi = axis / np.linalg.norm(axis) * np.pi * rng.uniform() ** (1.0 / 3.0)
    R = so3.exp(phi)
    true = NominalState(rng.normal(scale=10.0, size=3), rng.normal(scale=5.0, size=3), R,
                        rng.normal(scale=0.05, size=3), rng.normal(scale=2e-3, size=3))
    f = R.T @ (-g) + rng.normal(scale=1.0, size=3)
    w = rng.normal(scale=0.3, size=3)
    dx = error_scale * rng.normal(size=15)
    return Case(true, nominal_with_error(true, dx, COURSE), dx, f, w, g, int(seed))


def mixing_table(values: dict, row_title: str, column_title: str, fmt: str = ".1e") -> str:
    """A fixed-width text table of ``values[(row, column)]`` over the four conventions.

    Parameters
    ----------
    values : dict
        (Convention, Convention) -> float, for every pair of :data:`CONVENTIONS`.
    row_title, column_title : str
        What the rows and the columns are (printed above them).
    fmt : str
        Format of each number.
    """
    missing = [(r.label, c.label) for r in CONVENTIONS for c in CONVENTIONS if (r, c) not in values]
    if missing:
        raise ValueError(f"values must hold every pair of conventions; missing {missing[:2]}")
    short = {c: f"{'n-t' if c.sign > 0 else 't-n'} {c.side}" for c in CONVENTIONS}
    width = 34
    lines = [f"rows: {row_title}; columns: {column_title}",
             f"{'':{width}s}" + "".join(f"{short[c]:>13s}" for c in CONVENTIONS)]
    for r in CONVENTIONS:
        lines.append(f"{r.label:{width}s}" + "".join(f"{format(values[(r, c)], fmt):>13s}" for c in CONVENTIONS))
    return "\n".join(lines)
