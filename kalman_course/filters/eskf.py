"""The error-state Kalman filter (ESKF): IMU mechanisation corrected by pose or position fixes.

State and conventions (chapter 08, following the lecture)
---------------------------------------------------------
Nominal state x = (p, v, R, b_a, b_ω): position (m) and velocity (m/s) in the navigation
frame, attitude R = R_nb (body → nav), accelerometer bias b_a (m/s²) and gyroscope bias
b_ω (rad/s). The nominal state is propagated by the midpoint mechanisation of
:mod:`kalman_course.core.imu` and carries no uncertainty; the filter estimates the error

    δx = [δp, δv, δθ, δb_a, δb_ω]  (15),   error = nominal − true:
    δp = p̌ − p,  δv = v̌ − v,  Ř = R Exp(δθ),  δb = b̌ − b.

Continuous error dynamics (a = f − b_a and ω = ω_m − b_ω are the bias-corrected BODY-frame
specific force and angular rate), with noise w = [n_a, n_ω, n_ba, n_bω]:

    δṗ = δv
    δv̇ = −R [a]× δθ − R δb_a + R n_a
    δθ̇ = −[ω]× δθ − δb_ω + n_ω
    δḃ_a = n_ba,  δḃ_ω = n_bω      (random walk; 0 for the constant-bias model)

so δẋ = F_t δx + B_t w (:func:`error_dynamics`, :func:`noise_jacobian`). Discretised over a
step of T seconds as the lecture does: F = I + F_t T; the white-noise columns of B are
scaled by T and the bias random-walk columns by √T; Q holds per-sample variances
(density²/T for n_a, n_ω; density² for the random walks), so that B Q Bᵀ adds density²·T to
every block (:func:`discretise`, :func:`process_noise`).

Observations: a lidar pose (p_m, R_m) gives y = [p̌ − p_m; Log(R_mᵀ Ř)] ≈ G δx + n with
G = [[I, 0, 0, 0, 0], [0, 0, I, 0, 0]]; a GNSS position gives y = p̌ − p_m, G = [I, 0, 0, 0, 0].
After the (Joseph-form) update the estimated error is injected, p̂ = p̌ − δp̂, v̂ = v̌ − δv̂,
R̂ = Ř Exp(−δθ̂), b̂ = b̌ − δb̂, and reset, δx̂ ← 0, optionally with P̂ ← G_r P̂ G_rᵀ where the
reset Jacobian G_r is the identity except its attitude block J_l(δθ̂) ≈ I + ½[δθ̂]× (for
this sign convention; :func:`reset_jacobian`).

One set of formulas, two drivers
--------------------------------
Each formula above is written once, in a private kernel that works on one step or on a
stack of steps (``_error_dynamics``, ``_noise_jacobian``, ``_discretise``,
``_process_noise``, ``_propagate_covariance``, ``_gain``, ``_inject``,
``_reset_covariance``); rotations go through :mod:`kalman_course.core.so3`, the nominal
midpoint integration through :func:`kalman_course.core.imu.integrate_midpoint` (shared with
chapter 07's mechanisation) and the Kalman update through :mod:`kalman_course.core.linalg`. The public functions validate their
arguments and call these kernels, and so do both drivers:

- :class:`ESKF`, one step at a time, for lectures and exercises;
- :func:`run`, the batch runner used on whole sequences: it merges IMU and observation
  times into one timeline (an observation between two IMU samples gets the IMU reading
  interpolated at its time, so the filter is propagated exactly to it) and hands every
  stretch between two observations to the same propagation kernel as
  :meth:`ESKF.predict`, as one stack of steps.

Gaps in the IMU stream
----------------------
A step of the IMU clock longer than ``gap_factor`` (default :data:`IMU_GAP_FACTOR` = 3)
times the median step is a gap: at least two samples in a row are missing, and the
midpoint rule bridges it with readings that may be far from what happened in between.
:func:`run` propagates such a step (and every inserted node inside it) with the inflated
``interpolated_imu`` noise of the configuration, as it does for interpolated samples, and
emits an :class:`ImuGapWarning` saying how many gaps there were and how long.
Timestamp jitter and a single missed sample (a step of up to about twice the median on
KITTI) are not gaps.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from numpy import dot

from kalman_course.core import so3
from kalman_course.core.imu import integrate_midpoint
from kalman_course.core.linalg import gain, innovation_covariance, joseph_update, symmetrise
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.core.validation import (as_covariance, as_flag, as_matrix, as_rotation, as_rows, as_scalar,
                                           as_vector)
from kalman_course.filters.eskf_config import BIAS_MODELS, EskfConfig, load_config
from kalman_course.filters.eskf_streams import ObservationStream

__all__ = [
    "NominalState", "ESKF", "EskfResult", "run", "ImuGapWarning", "OutputTimesWarning", "IMU_GAP_FACTOR",
    "ObservationStream",
    "error_dynamics", "noise_jacobian", "discretise", "process_noise", "propagate_covariance",
    "pose_residual", "position_residual", "kalman_gain", "update_covariance", "inject",
    "reset_jacobian", "reset_covariance", "nominal_step", "initial_covariance",
    "POSE_G", "POSITION_G", "IDX_P", "IDX_V", "IDX_TH", "IDX_BA", "IDX_BW",
]

IDX_P, IDX_V, IDX_TH, IDX_BA, IDX_BW = (slice(0, 3), slice(3, 6), slice(6, 9), slice(9, 12),
                                        slice(12, 15))
_I3 = np.eye(3)
_I15 = np.eye(15)

#: Observation Jacobian of the lidar pose residual [δp̄; δθ̄] (6, 15).
POSE_G = np.zeros((6, 15))
POSE_G[0:3, IDX_P] = _I3
POSE_G[3:6, IDX_TH] = _I3
POSE_G.setflags(write=False)
#: Observation Jacobian of the GNSS position residual δp̄ (3, 15).
POSITION_G = np.zeros((3, 15))
POSITION_G[:, IDX_P] = _I3
POSITION_G.setflags(write=False)

# The blocks of F_t that do not depend on the state: ∂δṗ/∂δv = I and ∂δθ̇/∂δb_ω = −I.
_F_T_CONSTANT = np.zeros((15, 15))
_F_T_CONSTANT[IDX_P, IDX_V] = _I3
_F_T_CONSTANT[IDX_TH, IDX_BW] = -_I3
_F_T_CONSTANT.setflags(write=False)

# Columns of B_t: n_a and n_ω are white noise (scaled by T), n_ba and n_bω random walks (√T).
_WHITE_NOISE_COLUMN = np.arange(12) < 6

#: An IMU step longer than this many median steps is a gap (see the module docstring).
IMU_GAP_FACTOR = 3.0

#: |g| accepted for gravity, m/s²: the Earth's surface spans 9.78–9.83 (a margin for models).
GRAVITY_RANGE = (9.7, 9.9)
#: IMU samples averaged at the start to check gravity's sign against the specific force.
GRAVITY_CHECK_SAMPLES = 20


class ImuGapWarning(UserWarning):
    """:func:`run` found gaps in the IMU timestamps and bridged them with inflated noise."""


class OutputTimesWarning(UserWarning):
    """Some ``output_times`` lie outside the run and have no row in the result."""


@dataclass(frozen=True)
class NominalState:
    """The nominal state x = (p, v, R, b_a, b_ω).

    Attributes
    ----------
    position : numpy.ndarray, shape (3,)
        p, navigation frame, m.
    velocity : numpy.ndarray, shape (3,)
        v, navigation frame, m/s.
    rotation : numpy.ndarray, shape (3, 3)
        R = R_nb, body → navigation.
    accel_bias : numpy.ndarray, shape (3,)
        b_a, m/s².
    gyro_bias : numpy.ndarray, shape (3,)
        b_ω, rad/s.
    """

    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    accel_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))
    gyro_bias: np.ndarray = field(default_factory=lambda: np.zeros(3))

    @classmethod
    def from_nav(cls, nav, accel_bias=None, gyro_bias=None) -> "NominalState":
        """From anything with position, velocity and rotation (e.g. an ``imu.NavState``).

        Raises
        ------
        ValueError
            If ``nav`` lacks one of the fields, a field has the wrong shape or is not
            finite, ``nav.rotation`` is not a rotation, or a bias is not a finite (3,) vector.
        """
        for name in ("position", "velocity", "rotation"):
            if not hasattr(nav, name):
                raise ValueError(f"nav must have position (3,), velocity (3,) and rotation (3, 3); "
                                 f"missing {name!r}")
        return cls(np.array(as_vector(nav.position, "nav.position", 3)),
                   np.array(as_vector(nav.velocity, "nav.velocity", 3)),
                   np.array(as_rotation(nav.rotation, "nav.rotation")),
                   np.zeros(3) if accel_bias is None else np.array(as_vector(accel_bias, "accel_bias", 3)),
                   np.zeros(3) if gyro_bias is None else np.array(as_vector(gyro_bias, "gyro_bias", 3)))


# ---------------------------------------------------------------------------------------
# Argument checks (every public function validates at its boundary with these)
# ---------------------------------------------------------------------------------------

def _as_nominal(value, name: str) -> NominalState:
    """Return ``value`` (a NominalState, or a NavState with zero biases) with every field checked."""
    if not isinstance(value, NominalState):
        if not all(hasattr(value, f) for f in ("position", "velocity", "rotation")):
            raise ValueError(f"{name} must be a NominalState or have position (3,), velocity (3,) and "
                             f"rotation (3, 3), got {type(value).__name__}")
        value = NominalState(value.position, value.velocity, value.rotation)
    fields = (as_vector(value.position, f"{name}.position", 3),
              as_vector(value.velocity, f"{name}.velocity", 3),
              as_rotation(value.rotation, f"{name}.rotation"),
              as_vector(value.accel_bias, f"{name}.accel_bias", 3),
              as_vector(value.gyro_bias, f"{name}.gyro_bias", 3))
    if all(new is old for new, old in zip(fields, (value.position, value.velocity, value.rotation,
                                                      value.accel_bias, value.gyro_bias))):
        return value
    return NominalState(*(np.array(f) for f in fields))


def _as_bias_model(bias_model) -> str:
    if bias_model not in BIAS_MODELS:
        raise ValueError(f"bias_model must be 'random_walk' or 'constant', got {bias_model!r}")
    return bias_model


def _as_density(density) -> np.ndarray:
    d = as_vector(density, "density", 4)
    if (d < 0.0).any():
        raise ValueError(f"density must hold four non-negative noise densities (σ_a, σ_ω, σ_ba, σ_bω), got {d}")
    return d


def _as_config(config) -> EskfConfig:
    if isinstance(config, EskfConfig):
        return config
    if isinstance(config, (str, dict)) or hasattr(config, "__fspath__"):
        return load_config(config)
    raise ValueError(f"config must be an EskfConfig or the name or path of a configuration file, "
                     f"got {type(config).__name__}")


def _as_gravity(value) -> np.ndarray:
    """Gravity g (3,) in the navigation frame; a NaN or inf is reported with its index."""
    try:
        shape = np.shape(value)
    except (TypeError, ValueError):
        shape = None
    if shape != (3,):
        raise ValueError(f"gravity must have shape (3,) (m/s², navigation frame), got {shape}")
    g = as_rows(value, "gravity")
    size = float(np.sqrt(g.dot(g)))
    if not GRAVITY_RANGE[0] <= size <= GRAVITY_RANGE[1]:
        hint = " (given in g? in m/s² it is about 9.81)" if 0.9 <= size <= 1.1 else ""
        raise ValueError(f"gravity must be the Earth's, |g| between {GRAVITY_RANGE[0]:g} and {GRAVITY_RANGE[1]:g} "
                         f"m/s², got |g| = {size:.4g}{hint}")
    return g


def _gravity_against_imu(g, rotation, f_imu, name: str = "gravity") -> None:
    """Raise if ``g`` points along the specific force the IMU measured at the start.

    Whatever the car does, the specific force f = R_nbᵀ (a − g) points, in the navigation
    frame, against gravity to within the vehicle's vertical acceleration, which is far below
    g: R f̄ · ĝ is close to −|g|. A gravity of the wrong sign (+9.81 "up" in a z-up frame)
    gives +|g|, and every filter would then double gravity instead of removing it.
    """
    f_nav = rotation @ np.mean(f_imu[:GRAVITY_CHECK_SAMPLES], axis=0)
    along = float(f_nav.dot(g) / np.sqrt(g.dot(g)))
    if along > 0.5 * np.sqrt(g.dot(g)):
        raise ValueError(f"{name} points along the specific force the IMU measured at the start (R f̄ · ĝ = "
                         f"{along:+.2f} m/s², expected near −{np.sqrt(g.dot(g)):.2f}): its sign is flipped, or the "
                         "initial attitude is upside down; in a z-up navigation frame gravity is (0, 0, −9.81)")


def _as_time(value, name: str) -> float:
    if isinstance(value, (bool, np.bool_, str, bytes)):          # float("2") and float(True) work
        raise ValueError(f"{name} must be a finite time in seconds, got {value!r}")
    try:
        t = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be a finite time in seconds, got {value!r}") from None
    if not math.isfinite(t):
        raise ValueError(f"{name} must be a finite time in seconds, got {value!r}")
    return t


def _as_observations(value, name: str, record: type):
    """``value`` as a ``record`` (PoseObservations or PositionObservations), validated there."""
    if value is None or isinstance(value, record):
        return value
    fields = ("t", "position", "rotation") if record is PoseObservations else ("t", "position")
    missing = [f for f in fields if not hasattr(value, f)]
    if missing:
        raise ValueError(f"{name} must be a {record.__name__} (or have {', '.join(fields)}); "
                         f"missing {', '.join(missing)}")
    try:
        return record(**{f: getattr(value, f) for f in fields})
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None


# ---------------------------------------------------------------------------------------
# Kernels: each formula once, for one step or a stack of steps (leading axis), unvalidated
# (their callers validate at the public boundary, so they call so3 with check=False too)
# ---------------------------------------------------------------------------------------

def _error_dynamics(R, a, w) -> np.ndarray:
    """F_t (..., 15, 15) at attitude R (..., 3, 3), corrected force a and rate w (..., 3)."""
    F = np.empty((*R.shape[:-2], 15, 15))
    F[...] = _F_T_CONSTANT                                      # zeros and the state-free blocks I, −I
    np.negative(R @ so3.hat(a, check=False), out=F[..., IDX_V, IDX_TH])   # −R[a]×: body-frame force
    np.negative(R, out=F[..., IDX_V, IDX_BA])                            # −R
    np.negative(so3.hat(w, check=False), out=F[..., IDX_TH, IDX_TH])     # −[ω]×
    return F


def _noise_jacobian(R, bias_model: str) -> np.ndarray:
    """B_t (..., 15, 12) or (..., 15, 6): columns n_a, n_ω[, n_ba, n_bω]."""
    B = np.zeros((*R.shape[:-2], 15, 12 if bias_model == "random_walk" else 6))
    B[..., IDX_V, 0:3] = R
    B[..., IDX_TH, 3:6] = _I3
    if bias_model == "random_walk":
        B[..., IDX_BA, 6:9] = _I3
        B[..., IDX_BW, 9:12] = _I3
    return B


def _discretise(F_t, B_t, T, overwrite: bool = False):
    """F = I + F_t T and B with white-noise columns × T, random-walk columns × √T (T scalar or (n,)).

    ``overwrite`` lets a caller that made F_t and B_t for this purpose have them scaled in place.
    """
    T = np.asarray(T, dtype=float)[..., None, None]
    F = np.multiply(F_t, T, out=F_t if overwrite else None)
    F.reshape(-1, 225)[:, ::16] += 1.0                     # + I: every 16th entry of a 15 × 15 block
    column_scale = np.where(_WHITE_NOISE_COLUMN[:B_t.shape[-1]], T, np.sqrt(T))      # T or √T, (..., 1, k)
    B = np.multiply(B_t, column_scale, out=B_t if overwrite else None)
    return F, B


def _process_noise(density, T, bias_model: str) -> np.ndarray:
    """The diagonal of Q (..., 12) or (..., 6): σ_a²/T ×3, σ_ω²/T ×3[, σ_ba² ×3, σ_bω² ×3].

    ``density`` (..., 4) and ``T`` (...) broadcast against each other.
    """
    d2 = np.asarray(density, dtype=float) ** 2
    T = np.asarray(T, dtype=float)[..., None]
    white = np.repeat(d2[..., 0:2], 3, axis=-1) / T
    if bias_model == "constant":
        return white
    walk = np.broadcast_to(np.repeat(d2[..., 2:4], 3, axis=-1), white.shape)
    return np.concatenate([white, walk], axis=-1)


def _propagate_covariance(P, F, B, Q) -> tuple[np.ndarray, np.ndarray]:
    """P after n steps P ← F_i P F_iᵀ + B_i Q_i B_iᵀ (F (n, 15, 15), B (n, 15, k)).

    ``Q`` is (n, k, k), or (n, k) for the diagonal Q of :func:`_process_noise`. Composed:
    with Ψ_i = F_{n−1} ⋯ F_{i+1} (Ψ_{n−1} = I) and Φ = Ψ_0 F_0,
    P_n = Φ P Φᵀ + Σ_i (Ψ_i B_i) Q_i (Ψ_i B_i)ᵀ, one matrix product per step instead of
    two; for n = 1 it is F P Fᵀ + B Q Bᵀ. Returns (P_n, Φ).
    """
    n = F.shape[0]
    Psi = np.empty((n, 15, 15))
    Psi[n - 1] = _I15
    for i in range(n - 2, -1, -1):
        dot(Psi[i + 1], F[i + 1], out=Psi[i])
    Phi = dot(Psi[0], F[0])
    if Q.ndim == 2:
        # diagonal Q: Σ_i (Ψ_i B_i √Q_i)(Ψ_i B_i √Q_i)ᵀ = L Lᵀ with the L_i side by side, one product
        L = Psi @ (B * np.sqrt(Q)[:, None, :])
        L = np.swapaxes(L, 0, 1).reshape(15, -1)
        noise = dot(L, L.T)
    else:
        M = Psi @ B
        noise = (M @ Q @ np.swapaxes(M, 1, 2)).sum(axis=0)
    return symmetrise(dot(dot(Phi, P), Phi.T) + noise), Phi


def _propagate(x: NominalState, P, f, w_mean, dt, q, g, bias_model: str):
    """Nominal state and covariance over n steps.

    ``f`` (n+1, 3): the specific force at the nodes; ``w_mean`` (n, 3): each step's mean
    rate ½(ω_i + ω_{i+1}); ``dt`` (n,); ``q`` (n, k): the diagonal of each step's Q from
    :func:`_process_noise`. F and B are evaluated at the start of each step: the state
    there, the bias-corrected specific force f_i − b_a and the mean rate ω̄_i − b_ω.
    Returns (x at the last node, P there, Φ = ∏ F, positions (n+1, 3), rotations (n+1, 3, 3)).
    """
    a = f - x.accel_bias
    w = w_mean - x.gyro_bias
    ps, vs, Rs = integrate_midpoint(x.position, x.velocity, x.rotation, a, w, dt, g)
    R_start = Rs[:-1]
    F, B = _discretise(_error_dynamics(R_start, a[:-1], w), _noise_jacobian(R_start, bias_model), dt,
                       overwrite=True)
    P, Phi = _propagate_covariance(P, F, B, q)
    return NominalState(ps[-1], vs[-1], Rs[-1], x.accel_bias, x.gyro_bias), P, Phi, ps, Rs


def _pose_residual(p_check, R_check, p_meas, R_meas) -> np.ndarray:
    return np.concatenate([p_check - p_meas, so3.log(dot(R_meas.T, R_check), check=False)])


def _position_residual(p_check, p_meas) -> np.ndarray:
    return p_check - p_meas


def _gain(P, G, R):
    """K = P Gᵀ S⁻¹ and S = G P Gᵀ + R; a singular S is a ValueError saying why it can be."""
    GP = dot(G, P)
    S = innovation_covariance(GP, G, R)
    try:
        return gain(GP, S), S
    except np.linalg.LinAlgError:
        raise ValueError("the innovation covariance S = G P̌ Gᵀ + R is singular: the filter is already certain "
                         "of what a sensor with zero noise measures (a zero σ in R where P̌ has no uncertainty "
                         "either); give that sensor or the prior some uncertainty") from None


def _inject(x: NominalState, dx) -> NominalState:
    return NominalState(x.position - dx[IDX_P], x.velocity - dx[IDX_V],
                        dot(x.rotation, so3.exp(-dx[IDX_TH], check=False)),
                        x.accel_bias - dx[IDX_BA], x.gyro_bias - dx[IDX_BW])


def _reset_jacobian(dtheta) -> np.ndarray:
    G = _I15.copy()
    G[IDX_TH, IDX_TH] = so3.left_jacobian(dtheta)
    return G


def _reset_covariance(P, dtheta, exact: bool, overwrite: bool = False) -> np.ndarray:
    """G_r P G_rᵀ (exact) or a copy of P. G_r (:func:`_reset_jacobian`) differs from I only in
    its attitude block J = J_l(δθ̂), so only the attitude rows and columns of P change:
    J P[θ, :] and then P[:, θ] Jᵀ. ``overwrite`` lets a caller that owns P have it changed in place."""
    if not overwrite:
        P = P.copy()
    if not exact:
        return P
    J = so3.left_jacobian(dtheta, check=False)
    P[IDX_TH] = dot(J, P[IDX_TH])
    P[:, IDX_TH] = dot(P[:, IDX_TH], J.T)
    return symmetrise(P)


def _correct(x: NominalState, P, y, G, R, exact_reset: bool, dx_prior=None):
    """Update with residual y (observation Jacobian G, noise R), inject, reset.

    Returns (x̂, P̂, innovation y − G δx̌, S). ``dx_prior`` None means δx̌ = 0.
    """
    K, S = _gain(P, G, R)
    innovation = y if dx_prior is None else y - dot(G, dx_prior)
    dx = dot(K, innovation) if dx_prior is None else dx_prior + dot(K, innovation)
    P = joseph_update(P, K, G, R, _I15)
    return _inject(x, dx), _reset_covariance(P, dx[IDX_TH], exact_reset, overwrite=True), innovation, S


def _lidar_noise(config: EskfConfig) -> np.ndarray:
    return np.diag(config.lidar_std ** 2)


def _gnss_noise(config: EskfConfig) -> np.ndarray:
    return np.eye(3) * config.gnss_std ** 2


# ---------------------------------------------------------------------------------------
# The building blocks (validated; one formula each, in the kernels above)
# ---------------------------------------------------------------------------------------

def error_dynamics(R, specific_force, angular_rate, accel_bias, gyro_bias) -> np.ndarray:
    """Continuous-time error-state matrix F_t (15, 15) of δẋ = F_t δx + B_t w.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Nominal attitude R_nb (a rotation matrix).
    specific_force, angular_rate : array_like, shape (3,)
        The IMU readings f (m/s²) and ω_m (rad/s), body frame.
    accel_bias, gyro_bias : array_like, shape (3,)
        Nominal biases b_a (m/s²), b_ω (rad/s); subtracted from the readings.
    """
    R = as_rotation(R, "R")
    a = as_vector(specific_force, "specific_force", 3) - as_vector(accel_bias, "accel_bias", 3)
    w = as_vector(angular_rate, "angular_rate", 3) - as_vector(gyro_bias, "gyro_bias", 3)
    return _error_dynamics(R, a, w)


def noise_jacobian(R, bias_model: str = "random_walk") -> np.ndarray:
    """Continuous-time noise Jacobian B_t: (15, 12) for a random-walk bias, (15, 6) constant.

    Columns: n_a (3), n_ω (3) and, for the random walk, n_ba (3), n_bω (3). ``R`` (3, 3) is
    the nominal attitude.
    """
    bias_model = _as_bias_model(bias_model)
    return _noise_jacobian(as_rotation(R, "R"), bias_model)


def discretise(F_t, B_t, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Lecture discretisation: F = I + F_t T; B: white-noise columns × T, bias columns × √T.

    Parameters
    ----------
    F_t : array_like, shape (15, 15)
    B_t : array_like, shape (15, 12) or (15, 6)
        Its first six columns belong to n_a and n_ω; any further ones to the bias random walks.
    T : float
        Step length, s (> 0).

    Returns
    -------
    F : numpy.ndarray, shape (15, 15)
    B : numpy.ndarray, same shape as B_t
    """
    F_t = as_matrix(F_t, "F_t", (15, 15))
    B_t = as_matrix(B_t, "B_t", (15, None))
    if B_t.shape[1] not in (6, 12):
        raise ValueError(f"B_t must have shape (15, 12) (random-walk bias) or (15, 6) (constant bias), "
                         f"got {B_t.shape}")
    return _discretise(F_t, B_t, as_scalar(T, "T"))


def process_noise(density, T: float, bias_model: str = "random_walk") -> np.ndarray:
    """Q_k for the discretised B: per-sample variances of the noise w_k.

    Parameters
    ----------
    density : array_like, shape (4,)
        Continuous densities (σ_a, σ_ω, σ_ba, σ_bω) in m/s²/√Hz, rad/s/√Hz, m/s³/√Hz,
        rad/s²/√Hz (``EskfConfig.process_density``).
    T : float
        Step length, s (> 0).
    bias_model : str
        "random_walk" → (12, 12); "constant" → (6, 6) (no bias noise).

    Returns
    -------
    numpy.ndarray
        diag(σ_a²/T ×3, σ_ω²/T ×3[, σ_ba² ×3, σ_bω² ×3]). With B from :func:`discretise`,
        B Q Bᵀ has σ²·T on each block.
    """
    density = _as_density(density)
    T = as_scalar(T, "T")
    return np.diag(_process_noise(density, T, _as_bias_model(bias_model)))


def propagate_covariance(P, F, B, Q) -> np.ndarray:
    """P̌ = F P̂ Fᵀ + B Q Bᵀ, returned exactly symmetric.

    Parameters
    ----------
    P : array_like, shape (15, 15)
        P̂, symmetric.
    F : array_like, shape (15, 15)
    B : array_like, shape (15, k)
    Q : array_like, shape (k, k)
        Symmetric positive semi-definite (an indefinite Q would make P̌ indefinite).
    """
    P = as_covariance(P, "P", 15, psd=True)
    F = as_matrix(F, "F", (15, 15))
    B = as_matrix(B, "B", (15, None))
    Q = as_covariance(Q, "Q", B.shape[1], psd=True)
    return _propagate_covariance(P, F[None], B[None], Q[None])[0]


def pose_residual(p_check, R_check, p_meas, R_meas) -> np.ndarray:
    """y = [p̌ − p_m; Log(R_mᵀ Ř)], shape (6,): prediction minus measurement (m, rad).

    ``p_check``, ``p_meas`` (3,); ``R_check``, ``R_meas`` (3, 3) rotation matrices.
    """
    return _pose_residual(as_vector(p_check, "p_check", 3), as_rotation(R_check, "R_check"),
                          as_vector(p_meas, "p_meas", 3), as_rotation(R_meas, "R_meas"))


def position_residual(p_check, p_meas) -> np.ndarray:
    """y = p̌ − p_m, shape (3,), m."""
    return _position_residual(as_vector(p_check, "p_check", 3), as_vector(p_meas, "p_meas", 3))


def kalman_gain(P, G, R) -> np.ndarray:
    """K = P Gᵀ (G P Gᵀ + R)⁻¹ (observation-noise Jacobian C = I).

    Parameters
    ----------
    P : array_like, shape (n, n)
        P̌, symmetric.
    G : array_like, shape (m, n)
    R : array_like, shape (m, m)
        Observation noise, symmetric positive definite.

    Returns
    -------
    numpy.ndarray, shape (n, m)
    """
    P = as_covariance(P, "P", psd=True)
    G = as_matrix(G, "G", (None, P.shape[0]))
    R = as_covariance(R, "R", G.shape[0], positive_definite=True)
    return _gain(P, G, R)[0]


def update_covariance(P, K, G, R) -> np.ndarray:
    """Joseph form P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ, returned exactly symmetric.

    ``P`` (n, n), ``K`` (n, m), ``G`` (m, n), ``R`` (m, m) positive semi-definite (singular
    where a component is known exactly); valid for any gain K.
    """
    P = as_covariance(P, "P", psd=True)
    n = P.shape[0]
    G = as_matrix(G, "G", (None, n))
    K = as_matrix(K, "K", (n, G.shape[0]))
    R = as_covariance(R, "R", G.shape[0], psd=True)
    return joseph_update(P, K, G, R)


def inject(nominal: NominalState, dx) -> NominalState:
    """Correct the nominal state with the estimated error δx̂ (15,): x̂ = x̌ ⊖ δx̂.

    p̂ = p̌ − δp̂, v̂ = v̌ − δv̂, R̂ = Ř Exp(−δθ̂), b̂_a = b̌_a − δb̂_a, b̂_ω = b̌_ω − δb̂_ω.
    """
    return _inject(_as_nominal(nominal, "nominal"), as_vector(dx, "dx", 15))


def reset_jacobian(dx) -> np.ndarray:
    """∂δx⁺/∂δx of the reset after injecting δx̂ (15, 15), for error = nominal − true.

    With Ř = R Exp(δθ) and R̂ = Ř Exp(−δθ̂), the new error obeys Exp(δθ⁺) = Exp(δθ) Exp(−δθ̂),
    whose derivative at δθ = δθ̂ is the left Jacobian J_l(δθ̂) = I + ½[δθ̂]× + O(|δθ̂|²);
    every other block is the identity.
    """
    return _reset_jacobian(as_vector(dx, "dx", 15)[IDX_TH])


def reset_covariance(P, dx, exact: bool = True) -> np.ndarray:
    """Covariance after the reset δx̂ ← 0: G_r P G_rᵀ (exact) or P unchanged (lecture).

    ``P`` (15, 15) symmetric, ``dx`` (15,) the injected δx̂, ``exact`` a bool.
    """
    P = as_covariance(P, "P", 15, psd=True)
    dx = as_vector(dx, "dx", 15)
    return _reset_covariance(P, dx[IDX_TH], as_flag(exact, "exact"))


def nominal_step(nominal: NominalState, f0, w0, f1, w1, dt: float, gravity) -> NominalState:
    """Propagate the nominal state over one IMU interval (midpoint rule; biases constant).

    R' = R Exp((½(ω₀ + ω₁) − b_ω) T); a_i = R_i (f_i − b_a) + g; v' = v + ½(a₀ + a₁) T;
    p' = p + v T + ¼(a₀ + a₁) T².

    Parameters
    ----------
    nominal : NominalState
    f0, w0, f1, w1 : array_like, shape (3,)
        Specific force (m/s²) and angular rate (rad/s) at the start and end of the step.
    dt : float
        Step length T, s (> 0).
    gravity : array_like, shape (3,)
    """
    x = _as_nominal(nominal, "nominal")
    f = np.stack([as_vector(f0, "f0", 3), as_vector(f1, "f1", 3)])
    w_mean = 0.5 * (as_vector(w0, "w0", 3) + as_vector(w1, "w1", 3))
    ps, vs, Rs = integrate_midpoint(x.position, x.velocity, x.rotation, f - x.accel_bias,
                                    w_mean[None] - x.gyro_bias, np.array([as_scalar(dt, "dt")]),
                                    _as_gravity(gravity))
    return NominalState(ps[1], vs[1], Rs[1], x.accel_bias.copy(), x.gyro_bias.copy())


def initial_covariance(config: EskfConfig) -> np.ndarray:
    """P̂₀ = diag(prior std²) from the configuration (or a configuration's name), (15, 15)."""
    return np.diag(_as_config(config).prior_std ** 2)


# ---------------------------------------------------------------------------------------
# Step-by-step filter
# ---------------------------------------------------------------------------------------

class ESKF:
    """The 15-state error-state Kalman filter, one call per IMU interval or observation.

    Parameters
    ----------
    config : EskfConfig or str
        Configuration (or the name of a shipped one).
    initial : NominalState or NavState
        Nominal state at the start (biases zero if a NavState is given).
    gravity : array_like, shape (3,)
        g in the navigation frame, m/s².
    P0 : array_like, shape (15, 15), optional
        Initial covariance, symmetric (default: from ``config.prior``).

    Attributes
    ----------
    nominal : NominalState
    P : numpy.ndarray, shape (15, 15)
    dx : numpy.ndarray, shape (15,)
        The error-state mean; zero after every reset.
    """

    def __init__(self, config, initial, gravity, P0=None):
        self.config = _as_config(config)
        self.nominal = _as_nominal(initial, "initial")
        self.gravity = _as_gravity(gravity)
        self.P = (initial_covariance(self.config) if P0 is None
                  else np.array(as_covariance(P0, "P0", 15, psd=True)))
        self.dx = np.zeros(15)

    def predict(self, f0, w0, f1, w1, dt: float, interpolated: bool = False) -> None:
        """Propagate the nominal state and P̌ = F P̂ Fᵀ + B Q Bᵀ over one IMU interval.

        F is evaluated at the state and readings at the start of the interval (the
        bias-corrected body-frame specific force f0 − b_a and the mean rate ½(ω₀ + ω₁) − b_ω).
        ``interpolated`` selects the inflated noise of the configuration's ``interpolated_imu``
        (for samples interpolated over a dropout, and for gaps in the IMU clock).

        Parameters
        ----------
        f0, w0, f1, w1 : array_like, shape (3,)
            Specific force (m/s²) and angular rate (rad/s) at the start and end.
        dt : float
            Step length, s; must be positive and finite.
        interpolated : bool
        """
        f = np.stack([as_vector(f0, "f0", 3), as_vector(f1, "f1", 3)])
        w = np.stack([as_vector(w0, "w0", 3), as_vector(w1, "w1", 3)])
        dt = as_scalar(dt, "dt")
        cfg = self.config
        density = cfg.interpolated_density if as_flag(interpolated, "interpolated") else cfg.process_density
        q = _process_noise(density, dt, cfg.bias_model)
        self.nominal, self.P, Phi, _, _ = _propagate(self.nominal, self.P, f, 0.5 * (w[:1] + w[1:]),
                                                     np.array([dt]), q[None], self.gravity, cfg.bias_model)
        self.dx = dot(Phi, self.dx)

    def _update(self, y, G, R) -> dict:
        self.nominal, self.P, innovation, S = _correct(self.nominal, self.P, y, G, R,
                                                       self.config.exact_reset, self.dx)
        self.dx = np.zeros(15)
        return {"innovation": innovation, "S": S}

    def update_pose(self, p_meas, R_meas) -> dict:
        """Lidar pose update, injection and reset; returns the innovation (6,) and S (6, 6).

        ``p_meas`` (3,) m; ``R_meas`` (3, 3) a rotation matrix.
        """
        y = pose_residual(self.nominal.position, self.nominal.rotation, p_meas, R_meas)
        return self._update(y, POSE_G, _lidar_noise(self.config))

    def update_position(self, p_meas) -> dict:
        """GNSS position update, injection and reset; returns the innovation (3,) and S (3, 3)."""
        y = position_residual(self.nominal.position, p_meas)
        return self._update(y, POSITION_G, _gnss_noise(self.config))

    def update_stream(self, stream: ObservationStream, k: int) -> dict:
        """Update with report ``k`` of ``stream`` (its own noise and extrinsics), inject, reset.

        Returns the innovation (m,) and S (m, m), m = 3 (positions) or 6 (poses).
        """
        if not isinstance(stream, ObservationStream):
            raise ValueError(f"stream must be an ObservationStream, got {type(stream).__name__}")
        if isinstance(k, (bool, np.bool_)) or not isinstance(k, (int, np.integer)) or not 0 <= k < len(stream):
            raise ValueError(f"k must be the index of one of {stream.name}'s {len(stream)} reports, got {k!r}")
        y = stream.residual(k, self.nominal.position, self.nominal.rotation)
        return self._update(y, _stream_jacobian(stream, self.nominal.rotation), stream.R)


# ---------------------------------------------------------------------------------------
# Batch runner
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EskfResult:
    """Output of :func:`run`.

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Output times (observation times and any requested ``output_times``), s.
    position, velocity : numpy.ndarray, shape (K, 3)
    rotation : numpy.ndarray, shape (K, 3, 3)
    accel_bias, gyro_bias : numpy.ndarray, shape (K, 3)
        The filter's state at ``t`` (after the update if an observation was used there).
    P : numpy.ndarray, shape (K, 15, 15)
        Its covariance.
    updated : numpy.ndarray of bool, shape (K,)
        True where an observation was used.
    innovation, S : list of numpy.ndarray
        Innovation and its covariance of every update, in time order.
    sources : list of str
        The name of the stream each update came from ("lidar", "gnss", or a stream's name).
    t_all, position_all, rotation_all : numpy.ndarray
        The nominal trajectory at every timeline node (IMU samples plus inserted nodes),
        posterior at update nodes; only if ``record_all`` was set, else empty.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    P: np.ndarray
    updated: np.ndarray
    innovation: list = field(repr=False, default_factory=list)
    S: list = field(repr=False, default_factory=list)
    t_all: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(0))
    position_all: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 3)))
    rotation_all: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 3, 3)))
    sources: list = field(repr=False, default_factory=list)

    def at(self, times) -> "EskfResult":
        """The rows whose time is one of ``times`` (within 1 µs, in any order), e.g. the truth's times."""
        keep = _rows_at(self.t, times)
        return EskfResult(self.t[keep], self.position[keep], self.velocity[keep], self.rotation[keep],
                          self.accel_bias[keep], self.gyro_bias[keep], self.P[keep], self.updated[keep],
                          self.innovation, self.S, self.t_all, self.position_all, self.rotation_all, self.sources)

    def std(self) -> np.ndarray:
        """Standard deviations sqrt(diag P), shape (K, 15)."""
        return np.sqrt(np.maximum(np.diagonal(self.P, axis1=1, axis2=2), 0.0))


def _rows_at(t, times) -> np.ndarray:
    """Mask of the entries of ``t`` (sorted) that equal one of ``times`` (any order) within 1 µs."""
    times = np.sort(as_vector(times, "times"))
    k = np.clip(np.searchsorted(times, t - 1e-6), 0, len(times) - 1)
    return np.abs(times[k] - t) <= 1e-6


def _imu_samples(imu, start, t_end):
    """Validated IMU samples from ``start`` up to ``t_end``: t (n,), f (n, 3), ω (n, 3), flags (n,).

    A NaN or inf is reported with its index into the full record, e.g. ``imu.angular_rate[12]``.
    """
    for name in ("t", "specific_force", "angular_rate"):
        if not hasattr(imu, name):
            raise ValueError(f"imu must have t (N,), specific_force (N, 3) and angular_rate (N, 3); "
                             f"missing {name!r}")
    for name in ("t", "specific_force", "angular_rate"):
        try:
            ndim = np.ndim(getattr(imu, name))
        except ValueError:                      # a ragged list
            ndim = None
        if ndim != (1 if name == "t" else 2):
            shape = "(N,)" if name == "t" else "(N, 3)"
            raise ValueError(f"imu.{name} must be an array of shape {shape}, got {getattr(imu, name)!r:.60}")
    n_imu = len(np.asarray(imu.t))
    if isinstance(start, (bool, np.bool_)) or not isinstance(start, (int, np.integer)) or not 0 <= start < n_imu:
        raise ValueError(f"start must be an integer index into imu.t (0 ≤ start < {n_imu}), got {start!r}")
    t = as_rows(np.asarray(imu.t, dtype=float)[start:], "imu.t", offset=start)
    f = as_rows(np.asarray(imu.specific_force, dtype=float)[start:], "imu.specific_force", (3,), offset=start)
    w = as_rows(np.asarray(imu.angular_rate, dtype=float)[start:], "imu.angular_rate", (3,), offset=start)
    if not len(f) == len(w) == len(t):
        raise ValueError(f"imu.t, imu.specific_force and imu.angular_rate must have the same length, got "
                         f"{n_imu}, {len(f) + start} and {len(w) + start}")
    flags = (np.asarray(imu.interpolated, dtype=bool)[start:] if hasattr(imu, "interpolated")
             else np.zeros(len(t), dtype=bool))
    if flags.shape != t.shape:
        raise ValueError(f"imu.interpolated must have shape ({n_imu},), got {np.shape(imu.interpolated)}")
    if t_end is not None:
        keep = t <= _as_time(t_end, "t_end")
        t, f, w, flags = t[keep], f[keep], w[keep], flags[keep]
    if len(t) < 2:
        raise ValueError("the filter needs at least two IMU samples after start and up to t_end")
    step = np.diff(t)
    if (step <= 0.0).any():
        k = int(np.argmax(step <= 0.0)) + 1 + start
        raise ValueError(f"imu.t must be strictly increasing: imu.t[{k}] <= imu.t[{k - 1}]")
    return t, f, w, flags


def _imu_gaps(dt: np.ndarray, gap_factor) -> np.ndarray:
    """Steps longer than ``gap_factor`` × the median step (bool (N−1,)); warns if there are any."""
    if gap_factor is None or len(dt) == 0:
        return np.zeros(len(dt), dtype=bool)
    nominal = float(np.median(dt))
    gaps = dt > gap_factor * nominal
    if gaps.any():
        lengths = dt[gaps]
        warnings.warn(ImuGapWarning(
            f"imu.t has {int(gaps.sum())} gap(s) longer than {gap_factor:g} × the median step "
            f"({nominal * 1e3:.3g} ms): {lengths.sum():.3g} s in all, the longest {lengths.max():.3g} s. "
            "They are propagated with the inflated interpolated_imu noise of the configuration."),
            stacklevel=3)
    return gaps



def _sorted_events(event_sources, t0: float, t1: float, from_start=()):
    """The observation events inside (t0, t1], sorted by time and then by kind.

    ``event_sources`` is a sequence of time vectors (or None); a vector's position in it is
    its events' kind. The kinds in ``from_start`` (output-only times) also keep a time equal
    to t0, which gets a row with the initial state. Returns (times (E,), kinds (E,), indices
    into their source (E,)).
    """
    ev_t, ev_kind, ev_idx = [np.zeros(0)], [np.zeros(0, int)], [np.zeros(0, int)]
    for kind, times in enumerate(event_sources):
        if times is not None:
            after_start = times >= t0 if kind in from_start else times > t0
            sel = np.nonzero(after_start & (times <= t1))[0]
            ev_t.append(times[sel])
            ev_kind.append(np.full(len(sel), kind))
            ev_idx.append(sel)
    ev_t, ev_kind, ev_idx = np.concatenate(ev_t), np.concatenate(ev_kind), np.concatenate(ev_idx)
    order = np.lexsort((ev_kind, ev_t))
    return ev_t[order], ev_kind[order], ev_idx[order]


def _timeline(t_imu, f_imu, w_imu, step_flag, event_t, tol: float = 1e-9):
    """The merged timeline: IMU samples plus a node at every event time not on a sample.

    Returns t_nodes (n,), the specific force at the nodes (n, 3), each step's mean rate
    (n−1, 3), each step's flag (n−1,) (that of the IMU interval it lies in) and each event's
    node (E,).
    """
    pos = np.searchsorted(t_imu, event_t)
    on_sample = (pos < len(t_imu)) & (np.abs(t_imu[np.minimum(pos, len(t_imu) - 1)] - event_t) <= tol)
    t_nodes = np.sort(np.concatenate([t_imu, np.unique(event_t[~on_sample])]), kind="stable")
    f_nodes = np.column_stack([np.interp(t_nodes, t_imu, f_imu[:, i]) for i in range(3)])
    w_nodes = np.column_stack([np.interp(t_nodes, t_imu, w_imu[:, i]) for i in range(3)])
    imu_step = np.clip(np.searchsorted(t_imu, t_nodes[:-1], side="right") - 1, 0, len(t_imu) - 2)
    return (t_nodes, f_nodes, 0.5 * (w_nodes[:-1] + w_nodes[1:]), step_flag[imu_step],
            np.searchsorted(t_nodes, event_t - tol))


def _stream_jacobian(stream: ObservationStream, R_check) -> np.ndarray:
    """G (m, 15) of ``stream`` at the nominal attitude: its [δp, δθ] Jacobian placed in the 15-state."""
    if stream.plain:
        return POSE_G if stream.kind == "pose" else POSITION_G
    H = stream.jacobian(R_check)
    G = np.zeros((stream.m, 15))
    G[:, IDX_P], G[:, IDX_TH] = H[:, :3], H[:, 3:]
    return G


def _as_streams(lidar, gnss, streams, config: EskfConfig) -> list[ObservationStream]:
    """Every observation source as a stream: ``lidar`` (poses, the configuration's lidar σ),
    ``gnss`` (positions, its GNSS σ), then each of ``streams`` in order."""
    out = []
    if lidar is not None:
        out.append(ObservationStream(_as_observations(lidar, "lidar", PoseObservations), config.lidar_std,
                                     kind="pose", name="lidar"))
    if gnss is not None:
        out.append(ObservationStream(_as_observations(gnss, "gnss", PositionObservations),
                                     np.full(3, config.gnss_std), kind="position", name="gnss"))
    if streams is None:
        return out
    if isinstance(streams, ObservationStream) or not isinstance(streams, (list, tuple)):
        raise ValueError(f"streams must be a list of ObservationStream, got {type(streams).__name__}")
    for i, stream in enumerate(streams):
        if not isinstance(stream, ObservationStream):
            raise ValueError(f"streams[{i}] must be an ObservationStream (observations, noise, kind, lever arm), "
                             f"got {type(stream).__name__}")
    names = [s.name for s in out] + [s.name for s in streams]
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise ValueError(f"streams: each stream needs its own name (lidar and gnss are taken by those "
                         f"arguments); repeated: {', '.join(repeated)}")
    return out + list(streams)


def _as_output_times(output_times, t0: float, t1: float, clip, stacklevel: int = 3):
    """``output_times`` validated: strictly increasing; a warning names those outside [t0, t1]
    unless the caller asked for them to be dropped (``clip``)."""
    clip = as_flag(clip, "clip_output_times")
    if output_times is None:
        return None
    times = as_vector(output_times, "output_times")
    step = np.diff(times)
    if (step <= 0.0).any():
        k = int(np.argmax(step <= 0.0)) + 1
        raise ValueError(f"output_times must be strictly increasing (one row per time): output_times[{k}] = "
                         f"{times[k]:.9g} <= output_times[{k - 1}] = {times[k - 1]:.9g}")
    outside = (times < t0) | (times > t1)
    if outside.any() and not clip:
        warnings.warn(OutputTimesWarning(
            f"{int(outside.sum())} of {len(times)} output_times lie outside the run [{t0:.9g}, {t1:.9g}] s and "
            "get no row; pass only times inside it, or clip_output_times=True to drop them"), stacklevel=stacklevel)
    return times


def run(imu, initial, config="kitti_lidar", gravity=(0.0, 0.0, -9.8092), *, lidar=None, gnss=None,
        streams=None, start: int = 0, t_end: float | None = None, output_times=None,
        clip_output_times: bool = False, P0=None, use_interpolation_flags: bool = True,
        record_all: bool = False, gap_factor: float | None = IMU_GAP_FACTOR) -> EskfResult:
    """Run the ESKF over an IMU record, fusing lidar poses and/or GNSS positions.

    The same kernels as :class:`ESKF` (one F, one Q, one update, injection and reset): the
    result equals calling :meth:`ESKF.predict` on every step of the merged timeline and
    :meth:`ESKF.update_pose` / :meth:`ESKF.update_position` at every observation, to
    round-off.

    Parameters
    ----------
    imu : object
        ``t`` (N,) s strictly increasing, ``specific_force`` (N, 3) m/s², ``angular_rate``
        (N, 3) rad/s, all finite, and optionally ``interpolated`` (N,) bool (for example
        ``load_kitti("turns").imu``).
    initial : NominalState or NavState
        The state at ``imu.t[start]``.
    config : EskfConfig or str
    gravity : array_like, shape (3,)
    lidar : PoseObservations, optional
        Reported poses: ``t`` (K,), ``position`` (K, 3), ``rotation`` (K, 3, 3) (for example
        ``ex.lidar``). Another object with these attributes is converted to a
        PoseObservations, which validates it. Observations at or before ``imu.t[start]`` or
        after the end are ignored.
    gnss : PositionObservations, optional
        Reported positions: ``t`` (M,), ``position`` (M, 3) (for example
        ``ex.gnss.observations()``); converted like ``lidar``.
    streams : list of ObservationStream, optional
        Further sensors, each with its own reports, noise, kind (positions or poses) and
        extrinsics (lever arm, R_bs): see :mod:`kalman_course.filters.eskf_streams`. At equal
        times ``lidar`` is used first, then ``gnss``, then the streams in list order.
    start : int
        Index of the first IMU sample.
    t_end : float, optional
        Stop at this time (default: the last IMU sample).
    output_times : array_like, optional
        Extra times at which to record the state without an update (for example the truth's
        times, to evaluate a GNSS run at 10 Hz); strictly increasing. A time equal to
        ``imu.t[start]`` gets a row holding ``initial`` and the prior covariance; times
        outside the run get no row and an :class:`OutputTimesWarning`.
    clip_output_times : bool
        Drop the ``output_times`` outside the run without a warning (for example the truth's
        times of the whole excerpt, for a run that starts later).
    P0 : array_like (15, 15), optional
        Initial covariance, symmetric (default: from the configuration's prior).
    use_interpolation_flags : bool
        Use ``config.interpolated_density`` on IMU steps touching an interpolated sample.
    record_all : bool
        Also keep the nominal position and attitude at every timeline node.
    gap_factor : float or None
        An IMU step longer than ``gap_factor`` × the median step of ``imu.t`` (after
        ``start`` and ``t_end``) is a gap: it is propagated with
        ``config.interpolated_density`` like an interpolated span, and an
        :class:`ImuGapWarning` gives the number and length of the gaps. None turns the
        detection off.

    Returns
    -------
    EskfResult
        One row per observation or output time (after the update where there is one);
        IMU samples after the last such time are not integrated. Pass ``output_times`` to
        get states where no observation is used.

    Raises
    ------
    ValueError
        Naming the argument: a NaN or inf in the IMU samples (with its index) or in
        ``gravity``, a ``gravity`` that is not the Earth's in size (|g| outside 9.7–9.9 m/s²)
        or whose sign disagrees with the IMU's specific force at the start, non-increasing
        ``imu.t``, an observation record that does not validate, a non-symmetric ``P0``, a
        bad ``start``, ``t_end`` or ``gap_factor``.
    """
    cfg = _as_config(config)
    x = _as_nominal(initial, "initial")
    g = _as_gravity(gravity)
    t_imu, f_imu, w_imu, flag_imu = _imu_samples(imu, start, t_end)
    _gravity_against_imu(g, x.rotation, f_imu)
    dt_imu = np.diff(t_imu)
    if gap_factor is not None:
        gap_factor = as_scalar(gap_factor, "gap_factor")
    sources = _as_streams(lidar, gnss, streams, cfg)
    P = initial_covariance(cfg) if P0 is None else np.array(as_covariance(P0, "P0", 15, psd=True))
    use_interpolation_flags = as_flag(use_interpolation_flags, "use_interpolation_flags")
    record_all = as_flag(record_all, "record_all")

    t0, t1 = t_imu[0], t_imu[-1]
    outputs = _as_output_times(output_times, t0, t1, clip_output_times)
    step_flag = _imu_gaps(dt_imu, gap_factor)
    if use_interpolation_flags:
        step_flag |= flag_imu[:-1] | flag_imu[1:]

    # ---- events: (time, kind, index); kind k < len(sources) is sources[k], the last kind output only ----
    n_sources = len(sources)
    ev_t, ev_kind, ev_idx = _sorted_events([s.t for s in sources] + [outputs], t0, t1, from_start=(n_sources,))
    t_nodes, f_nodes, w_mean, flags, ev_node = _timeline(t_imu, f_imu, w_imu, step_flag, ev_t)
    dt_nodes = np.diff(t_nodes)
    q = _process_noise(np.where(flags[:, None], cfg.interpolated_density, cfg.process_density),
                       dt_nodes, cfg.bias_model)
    # plain lists: the event loop reads them one element at a time
    ev_node_l, ev_kind_l, ev_idx_l = ev_node.tolist(), ev_kind.tolist(), ev_idx.tolist()
    exact = cfg.exact_reset

    # outputs: one row per distinct event node
    out_nodes = np.unique(ev_node)
    n_events = len(ev_node_l)
    rows = []                   # (x, P, updated) at every output node
    innovations, S_list, used_sources = [], [], []
    if record_all:
        all_p = np.zeros((len(t_nodes), 3))
        all_R = np.zeros((len(t_nodes), 3, 3))
        all_p[0], all_R[0] = x.position, x.rotation

    e = 0                       # index into the sorted events
    node = 0
    for target in out_nodes.tolist():
        if target > node:       # propagate node → target as one stack of steps
            sl = slice(node, target)
            x, P, _, ps, Rs = _propagate(x, P, f_nodes[node:target + 1], w_mean[sl], dt_nodes[sl], q[sl],
                                         g, cfg.bias_model)
            if record_all:
                all_p[node + 1:target + 1], all_R[node + 1:target + 1] = ps[1:], Rs[1:]
            node = target
        updated = False
        while e < n_events and ev_node_l[e] == target:       # every observation at this node
            kind, idx = ev_kind_l[e], ev_idx_l[e]
            e += 1
            if kind == n_sources:
                continue
            stream = sources[kind]
            y = stream.residual(idx, x.position, x.rotation)
            try:
                x, P, y, S = _correct(x, P, y, _stream_jacobian(stream, x.rotation), stream.R, exact)
            except ValueError as exc:
                raise ValueError(f"{stream.name}[{idx}] at t = {stream.t[idx]:.9g} s: {exc}") from None
            innovations.append(y)
            S_list.append(S)
            used_sources.append(stream.name)
            updated = True
        if record_all:
            all_p[target], all_R[target] = x.position, x.rotation
        rows.append((x, P, updated))

    states = [state for state, _, _ in rows]

    def stacked(name, shape):
        return np.array([getattr(state, name) for state in states]).reshape(-1, *shape)

    return EskfResult(t_nodes[out_nodes], stacked("position", (3,)), stacked("velocity", (3,)),
                      stacked("rotation", (3, 3)), stacked("accel_bias", (3,)), stacked("gyro_bias", (3,)),
                      np.array([P_k for _, P_k, _ in rows]).reshape(-1, 15, 15),
                      np.array([used for _, _, used in rows], dtype=bool), innovations, S_list,
                      t_nodes if record_all else np.zeros(0),
                      all_p if record_all else np.zeros((0, 3)),
                      all_R if record_all else np.zeros((0, 3, 3)), used_sources)
