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

Two implementations share these formulas:

- :class:`ESKF`, one step at a time, for lectures and exercises (readable, validated);
- :func:`run`, the fast batch runner used on whole sequences: it merges IMU and observation
  times into one timeline (an observation between two IMU samples gets the IMU reading
  interpolated at its time, so the filter is propagated exactly to it), propagates the
  nominal state in vectorised segments between observations and keeps P symmetric.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kalman_course.core import so3
from kalman_course.filters.eskf_config import EskfConfig, load_config
from kalman_course.core.validation import as_matrix, as_vector

__all__ = [
    "NominalState", "ESKF", "EskfResult", "run", "evaluate",
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
        """From anything with position, velocity and rotation (e.g. an ``imu.NavState``)."""
        return cls(np.array(nav.position, dtype=float), np.array(nav.velocity, dtype=float),
                   np.array(nav.rotation, dtype=float),
                   np.zeros(3) if accel_bias is None else np.array(accel_bias, dtype=float),
                   np.zeros(3) if gyro_bias is None else np.array(gyro_bias, dtype=float))


# ---------------------------------------------------------------------------------------
# The building blocks (one formula each)
# ---------------------------------------------------------------------------------------

def error_dynamics(R, specific_force, angular_rate, accel_bias, gyro_bias) -> np.ndarray:
    """Continuous-time error-state matrix F_t (15, 15) of δẋ = F_t δx + B_t w.

    Parameters
    ----------
    R : array_like, shape (3, 3)
        Nominal attitude R_nb.
    specific_force, angular_rate : array_like, shape (3,)
        The IMU readings f (m/s²) and ω_m (rad/s), body frame.
    accel_bias, gyro_bias : array_like, shape (3,)
        Nominal biases b_a (m/s²), b_ω (rad/s); subtracted from the readings.
    """
    R = np.asarray(R, dtype=float)
    a = np.asarray(specific_force, dtype=float) - np.asarray(accel_bias, dtype=float)
    w = np.asarray(angular_rate, dtype=float) - np.asarray(gyro_bias, dtype=float)
    F = np.zeros((15, 15))
    F[IDX_P, IDX_V] = _I3
    F[IDX_V, IDX_TH] = -R @ so3.hat(a)          # body-frame specific force inside the hat
    F[IDX_V, IDX_BA] = -R
    F[IDX_TH, IDX_TH] = -so3.hat(w)
    F[IDX_TH, IDX_BW] = -_I3
    return F


def noise_jacobian(R, bias_model: str = "random_walk") -> np.ndarray:
    """Continuous-time noise Jacobian B_t: (15, 12) for a random-walk bias, (15, 6) constant.

    Columns: n_a (3), n_ω (3) and, for the random walk, n_ba (3), n_bω (3).
    """
    R = np.asarray(R, dtype=float)
    if bias_model not in ("random_walk", "constant"):
        raise ValueError(f"bias_model must be 'random_walk' or 'constant', got {bias_model!r}")
    B = np.zeros((15, 12 if bias_model == "random_walk" else 6))
    B[IDX_V, 0:3] = R
    B[IDX_TH, 3:6] = _I3
    if bias_model == "random_walk":
        B[IDX_BA, 6:9] = _I3
        B[IDX_BW, 9:12] = _I3
    return B


def discretise(F_t, B_t, T: float) -> tuple[np.ndarray, np.ndarray]:
    """Lecture discretisation: F = I + F_t T; B: white-noise columns × T, bias columns × √T.

    Parameters
    ----------
    F_t : array_like, shape (15, 15)
    B_t : array_like, shape (15, 12) or (15, 6)
        Its first six columns belong to n_a and n_ω; any further ones to the bias random walks.
    T : float
        Step length, s.

    Returns
    -------
    F : numpy.ndarray, shape (15, 15)
    B : numpy.ndarray, same shape as B_t
    """
    F_t = np.asarray(F_t, dtype=float)
    B = np.array(B_t, dtype=float)
    T = float(T)
    B[:, :6] *= T
    B[:, 6:] *= math.sqrt(T)
    return np.eye(15) + F_t * T, B


def process_noise(density, T: float, bias_model: str = "random_walk") -> np.ndarray:
    """Q_k for the discretised B: per-sample variances of the noise w_k.

    Parameters
    ----------
    density : array_like, shape (4,)
        Continuous densities (σ_a, σ_ω, σ_ba, σ_bω) in m/s²/√Hz, rad/s/√Hz, m/s³/√Hz,
        rad/s²/√Hz (``EskfConfig.process_density``).
    T : float
        Step length, s.
    bias_model : str
        "random_walk" → (12, 12); "constant" → (6, 6) (no bias noise).

    Returns
    -------
    numpy.ndarray
        diag(σ_a²/T ×3, σ_ω²/T ×3[, σ_ba² ×3, σ_bω² ×3]). With B from :func:`discretise`,
        B Q Bᵀ has σ²·T on each block.
    """
    s = np.asarray(density, dtype=float)
    T = float(T)
    d = [s[0] ** 2 / T] * 3 + [s[1] ** 2 / T] * 3
    if bias_model == "random_walk":
        d += [s[2] ** 2] * 3 + [s[3] ** 2] * 3
    elif bias_model != "constant":
        raise ValueError(f"bias_model must be 'random_walk' or 'constant', got {bias_model!r}")
    return np.diag(d)


def propagate_covariance(P, F, B, Q) -> np.ndarray:
    """P̌ = F P̂ Fᵀ + B Q Bᵀ, returned exactly symmetric."""
    P = np.asarray(P, dtype=float)
    out = F @ P @ F.T + B @ Q @ B.T
    return 0.5 * (out + out.T)


def pose_residual(p_check, R_check, p_meas, R_meas) -> np.ndarray:
    """y = [p̌ − p_m; Log(R_mᵀ Ř)], shape (6,): prediction minus measurement (m, rad)."""
    p_check = np.asarray(p_check, dtype=float)
    dp = p_check - np.asarray(p_meas, dtype=float)
    dth = so3.log(np.asarray(R_meas, dtype=float).T @ np.asarray(R_check, dtype=float))
    return np.concatenate([dp, dth])


def position_residual(p_check, p_meas) -> np.ndarray:
    """y = p̌ − p_m, shape (3,), m."""
    return np.asarray(p_check, dtype=float) - np.asarray(p_meas, dtype=float)


def kalman_gain(P, G, R) -> np.ndarray:
    """K = P Gᵀ (G P Gᵀ + R)⁻¹ (observation-noise Jacobian C = I)."""
    P, G, R = np.asarray(P, dtype=float), np.asarray(G, dtype=float), np.asarray(R, dtype=float)
    S = G @ P @ G.T + R
    return np.linalg.solve(S, G @ P).T


def update_covariance(P, K, G, R) -> np.ndarray:
    """Joseph form P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ, returned exactly symmetric."""
    P, K, G, R = (np.asarray(x, dtype=float) for x in (P, K, G, R))
    A = np.eye(P.shape[0]) - K @ G
    out = A @ P @ A.T + K @ R @ K.T
    return 0.5 * (out + out.T)


def inject(nominal: NominalState, dx) -> NominalState:
    """Correct the nominal state with the estimated error δx̂ (15,): x̂ = x̌ ⊖ δx̂.

    p̂ = p̌ − δp̂, v̂ = v̌ − δv̂, R̂ = Ř Exp(−δθ̂), b̂_a = b̌_a − δb̂_a, b̂_ω = b̌_ω − δb̂_ω.
    """
    dx = np.asarray(dx, dtype=float)
    return NominalState(nominal.position - dx[IDX_P], nominal.velocity - dx[IDX_V],
                        nominal.rotation @ so3.exp(-dx[IDX_TH]),
                        nominal.accel_bias - dx[IDX_BA], nominal.gyro_bias - dx[IDX_BW])


def reset_jacobian(dx) -> np.ndarray:
    """∂δx⁺/∂δx of the reset after injecting δx̂ (15, 15), for error = nominal − true.

    With Ř = R Exp(δθ) and R̂ = Ř Exp(−δθ̂), the new error obeys Exp(δθ⁺) = Exp(δθ) Exp(−δθ̂),
    whose derivative at δθ = δθ̂ is the left Jacobian J_l(δθ̂) = I + ½[δθ̂]× + O(|δθ̂|²);
    every other block is the identity.
    """
    dx = np.asarray(dx, dtype=float)
    G = np.eye(15)
    G[IDX_TH, IDX_TH] = so3.left_jacobian(dx[IDX_TH])
    return G


def reset_covariance(P, dx, exact: bool = True) -> np.ndarray:
    """Covariance after the reset δx̂ ← 0: G_r P G_rᵀ (exact) or P unchanged (lecture)."""
    P = np.asarray(P, dtype=float)
    if not exact:
        return P.copy()
    G = reset_jacobian(dx)
    out = G @ P @ G.T
    return 0.5 * (out + out.T)


def nominal_step(nominal: NominalState, f0, w0, f1, w1, dt: float, gravity) -> NominalState:
    """Propagate the nominal state over one IMU interval (midpoint rule; biases constant).

    R' = R Exp((½(ω₀ + ω₁) − b_ω) T); a_i = R_i (f_i − b_a) + g; v' = v + ½(a₀ + a₁) T;
    p' = p + v T + ¼(a₀ + a₁) T².
    """
    f0, f1, w0, w1, g = (np.asarray(x, dtype=float) for x in (f0, f1, w0, w1, gravity))
    R = nominal.rotation
    R1 = R @ so3.exp((0.5 * (w0 + w1) - nominal.gyro_bias) * dt)
    a0 = R @ (f0 - nominal.accel_bias) + g
    a1 = R1 @ (f1 - nominal.accel_bias) + g
    am = 0.5 * (a0 + a1)
    return NominalState(nominal.position + nominal.velocity * dt + 0.5 * am * dt * dt,
                        nominal.velocity + am * dt, R1, nominal.accel_bias.copy(),
                        nominal.gyro_bias.copy())


def initial_covariance(config: EskfConfig) -> np.ndarray:
    """P̂₀ = diag(prior std²) from the configuration, (15, 15)."""
    return np.diag(config.prior_std ** 2)


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
        Initial covariance (default: from ``config.prior``).

    Attributes
    ----------
    nominal : NominalState
    P : numpy.ndarray, shape (15, 15)
    dx : numpy.ndarray, shape (15,)
        The error-state mean; zero after every reset.
    """

    def __init__(self, config, initial, gravity, P0=None):
        self.config = config if isinstance(config, EskfConfig) else load_config(config)
        if not isinstance(initial, NominalState):
            initial = NominalState.from_nav(initial)
        self.nominal = initial
        self.gravity = as_vector(gravity, "gravity", 3)
        self.P = initial_covariance(self.config) if P0 is None else as_matrix(P0, "P0", (15, 15)).copy()
        self.dx = np.zeros(15)

    def predict(self, f0, w0, f1, w1, dt: float, interpolated: bool = False) -> None:
        """Propagate the nominal state and P̌ = F P̂ Fᵀ + B Q Bᵀ over one IMU interval.

        F is evaluated at the state and readings at the start of the interval (the
        bias-corrected body-frame specific force f0 − b_a and the mean rate ½(ω₀ + ω₁) − b_ω).
        ``interpolated`` selects the inflated noise of the configuration's ``interpolated_imu``.
        """
        cfg = self.config
        x = self.nominal
        F_t = error_dynamics(x.rotation, f0, 0.5 * (np.asarray(w0) + np.asarray(w1)),
                             x.accel_bias, x.gyro_bias)
        B_t = noise_jacobian(x.rotation, cfg.bias_model)
        F, B = discretise(F_t, B_t, dt)
        density = cfg.interpolated_density if interpolated else cfg.process_density
        Q = process_noise(density, dt, cfg.bias_model)
        self.P = propagate_covariance(self.P, F, B, Q)
        self.dx = F @ self.dx
        self.nominal = nominal_step(x, f0, w0, f1, w1, dt, self.gravity)

    def _correct(self, y, G, Rn) -> dict:
        S = G @ self.P @ G.T + Rn
        K = kalman_gain(self.P, G, Rn)
        innovation = y - G @ self.dx
        self.dx = self.dx + K @ innovation
        self.P = update_covariance(self.P, K, G, Rn)
        self.nominal = inject(self.nominal, self.dx)
        self.P = reset_covariance(self.P, self.dx, self.config.exact_reset)
        self.dx = np.zeros(15)
        return {"innovation": innovation, "S": S}

    def update_pose(self, p_meas, R_meas) -> dict:
        """Lidar pose update, injection and reset; returns the innovation (6,) and S (6, 6)."""
        y = pose_residual(self.nominal.position, self.nominal.rotation, p_meas, R_meas)
        return self._correct(y, POSE_G, np.diag(self.config.lidar_std ** 2))

    def update_position(self, p_meas) -> dict:
        """GNSS position update, injection and reset; returns the innovation (3,) and S (3, 3)."""
        y = position_residual(self.nominal.position, p_meas)
        return self._correct(y, POSITION_G, np.eye(3) * self.config.gnss_std ** 2)


# ---------------------------------------------------------------------------------------
# Fast batch runner
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

    def at(self, times) -> "EskfResult":
        """The rows whose time is one of ``times`` (within 1 µs), e.g. the truth's times."""
        times = np.asarray(times, dtype=float)
        k = np.clip(np.searchsorted(times, self.t - 1e-6), 0, len(times) - 1)
        keep = np.abs(times[k] - self.t) <= 1e-6
        return EskfResult(self.t[keep], self.position[keep], self.velocity[keep], self.rotation[keep],
                          self.accel_bias[keep], self.gyro_bias[keep], self.P[keep], self.updated[keep],
                          self.innovation, self.S, self.t_all, self.position_all, self.rotation_all)

    def std(self) -> np.ndarray:
        """Standard deviations sqrt(diag P), shape (K, 15)."""
        return np.sqrt(np.maximum(np.diagonal(self.P, axis1=1, axis2=2), 0.0))


def _exp_batch(phi: np.ndarray) -> np.ndarray:
    """Rodrigues for a stack (n, 3) without validation: cos θ I + A [φ]× + B φφᵀ.

    A = sin θ/θ and B = (1 − cos θ)/θ² lose relative accuracy for tiny θ, but B multiplies
    φφᵀ = O(θ²), so the result stays exact to round-off (θ = 0 gives the identity).
    """
    th2 = np.einsum("ij,ij->i", phi, phi)
    th = np.sqrt(th2)
    ts = np.maximum(th, 1e-150)
    A = np.sin(ts) / ts
    C = np.cos(th)
    B = (1.0 - C) / (ts * ts)
    Ap = A[:, None] * phi
    E = B[:, None, None] * (phi[:, :, None] * phi[:, None, :])
    E[:, 0, 0] += C
    E[:, 1, 1] += C
    E[:, 2, 2] += C
    E[:, 0, 1] -= Ap[:, 2]
    E[:, 0, 2] += Ap[:, 1]
    E[:, 1, 0] += Ap[:, 2]
    E[:, 1, 2] -= Ap[:, 0]
    E[:, 2, 0] -= Ap[:, 1]
    E[:, 2, 1] += Ap[:, 0]
    return E


def _hat_batch(v: np.ndarray) -> np.ndarray:
    K = np.zeros((len(v), 3, 3))
    K[:, 0, 1] = -v[:, 2]
    K[:, 0, 2] = v[:, 1]
    K[:, 1, 0] = v[:, 2]
    K[:, 1, 2] = -v[:, 0]
    K[:, 2, 0] = -v[:, 1]
    K[:, 2, 1] = v[:, 0]
    return K


def _exp1(phi: np.ndarray) -> np.ndarray:
    x, y, z = float(phi[0]), float(phi[1]), float(phi[2])
    th2 = x * x + y * y + z * z
    if th2 < 1e-8:
        A, B = 1.0 - th2 / 6.0, 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        A, B = math.sin(th) / th, (1.0 - math.cos(th)) / th2
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return _I3 + A * K + B * (K @ K)


def _log1(R: np.ndarray) -> np.ndarray:
    """Log of one rotation whose angle is well below π (pose residuals, a few degrees)."""
    s = 0.5 * np.array([R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]])
    sin_t = math.sqrt(s @ s)
    cos_t = 0.5 * (R[0, 0] + R[1, 1] + R[2, 2] - 1.0)
    th = math.atan2(sin_t, cos_t)
    if th > 3.0:                       # not expected for residuals; use the robust version
        return so3.log(R)
    return s * (1.0 + th * th / 6.0 if th < 1e-4 else th / sin_t)


def _left_jacobian1(phi: np.ndarray) -> np.ndarray:
    th2 = float(phi @ phi)
    K = np.array([[0.0, -phi[2], phi[1]], [phi[2], 0.0, -phi[0]], [-phi[1], phi[0], 0.0]])
    if th2 < 1e-8:
        return _I3 + 0.5 * K + (K @ K) / 6.0
    th = math.sqrt(th2)
    return _I3 + (1.0 - math.cos(th)) / th2 * K + (th - math.sin(th)) / (th2 * th) * (K @ K)


def run(imu, initial, config="kitti_lidar", gravity=(0.0, 0.0, -9.8092), *, lidar=None, gnss=None,
        start: int = 0, t_end: float | None = None, output_times=None, P0=None,
        use_interpolation_flags: bool = True, record_all: bool = False) -> EskfResult:
    """Run the ESKF over an IMU record, fusing lidar poses and/or GNSS positions.

    Parameters
    ----------
    imu : object
        ``t`` (N,) s, ``specific_force`` (N, 3) m/s², ``angular_rate`` (N, 3) rad/s and
        optionally ``interpolated`` (N,) bool (for example ``load_kitti("turns").imu``).
    initial : NominalState or NavState
        The state at ``imu.t[start]``.
    config : EskfConfig or str
    gravity : array_like, shape (3,)
    lidar : object, optional
        ``t`` (K,), ``position`` (K, 3), ``rotation`` (K, 3, 3) (for example ``ex.lidar``).
        Observations at or before ``imu.t[start]`` or after the end are ignored.
    gnss : object, optional
        ``t`` (M,) and ``position`` (M, 3) (use ``position_noisy`` through a small
        wrapper, e.g. ``types.SimpleNamespace(t=g.t, position=g.position_noisy)``).
    start : int
        Index of the first IMU sample.
    t_end : float, optional
        Stop at this time (default: the last IMU sample).
    output_times : array_like, optional
        Extra times at which to record the state without an update (for example the truth's
        times, to evaluate a GNSS run at 10 Hz).
    P0 : array_like (15, 15), optional
    use_interpolation_flags : bool
        Use ``config.interpolated_density`` on IMU steps touching an interpolated sample.
    record_all : bool
        Also keep the nominal position and attitude at every timeline node.

    Returns
    -------
    EskfResult
        One row per observation or output time (after the update where there is one);
        IMU samples after the last such time are not integrated. Pass ``output_times`` to
        get states where no observation is used.
    """
    cfg = config if isinstance(config, EskfConfig) else load_config(config)
    x0 = initial if isinstance(initial, NominalState) else NominalState.from_nav(initial)
    g = as_vector(gravity, "gravity", 3)
    t_imu = np.asarray(imu.t, dtype=float)[start:]
    f_imu = np.asarray(imu.specific_force, dtype=float)[start:]
    w_imu = np.asarray(imu.angular_rate, dtype=float)[start:]
    flag_imu = (np.asarray(imu.interpolated, dtype=bool)[start:] if hasattr(imu, "interpolated")
                else np.zeros(len(t_imu), dtype=bool))
    if t_end is not None:
        keep = t_imu <= t_end
        t_imu, f_imu, w_imu, flag_imu = t_imu[keep], f_imu[keep], w_imu[keep], flag_imu[keep]
    if len(t_imu) < 2:
        raise ValueError("run needs at least two IMU samples after start/t_end")
    if np.any(np.diff(t_imu) <= 0.0):
        raise ValueError("imu.t must be strictly increasing")
    t0, t1 = t_imu[0], t_imu[-1]
    step_flag = (flag_imu[:-1] | flag_imu[1:]) if use_interpolation_flags else np.zeros(len(t_imu) - 1, bool)

    # ---- events: (time, kind, index) with kind 0 = lidar, 1 = gnss, 2 = output only ----
    ev_t, ev_kind, ev_idx = [], [], []
    if lidar is not None:
        lt = np.asarray(lidar.t, dtype=float)
        sel = np.nonzero((lt > t0) & (lt <= t1))[0]
        ev_t.append(lt[sel]); ev_kind.append(np.zeros(len(sel), int)); ev_idx.append(sel)
        lidar_p = np.asarray(lidar.position, dtype=float)
        lidar_R = np.asarray(lidar.rotation, dtype=float)
    if gnss is not None:
        gt = np.asarray(gnss.t, dtype=float)
        sel = np.nonzero((gt > t0) & (gt <= t1))[0]
        ev_t.append(gt[sel]); ev_kind.append(np.ones(len(sel), int)); ev_idx.append(sel)
        gnss_p = np.asarray(gnss.position, dtype=float)
    if output_times is not None:
        ot = np.asarray(output_times, dtype=float)
        sel = np.nonzero((ot > t0) & (ot <= t1))[0]
        ev_t.append(ot[sel]); ev_kind.append(np.full(len(sel), 2)); ev_idx.append(sel)
    if ev_t:
        ev_t, ev_kind, ev_idx = np.concatenate(ev_t), np.concatenate(ev_kind), np.concatenate(ev_idx)
    else:
        ev_t, ev_kind, ev_idx = np.zeros(0), np.zeros(0, int), np.zeros(0, int)
    order = np.lexsort((ev_kind, ev_t))
    ev_t, ev_kind, ev_idx = ev_t[order], ev_kind[order], ev_idx[order]

    # ---- merged timeline: IMU samples plus a node at every event time not on a sample ----
    tol = 1e-9
    pos = np.searchsorted(t_imu, ev_t)
    on_sample = (pos < len(t_imu)) & (np.abs(t_imu[np.minimum(pos, len(t_imu) - 1)] - ev_t) <= tol)
    new_t = np.unique(ev_t[~on_sample])
    t_nodes = np.concatenate([t_imu, new_t])
    node_order = np.argsort(t_nodes, kind="stable")
    t_nodes = t_nodes[node_order]
    f_nodes = np.column_stack([np.interp(t_nodes, t_imu, f_imu[:, i]) for i in range(3)])
    w_nodes = np.column_stack([np.interp(t_nodes, t_imu, w_imu[:, i]) for i in range(3)])
    # step j (node j → j+1) inherits the flag of the IMU interval it lies in
    imu_step = np.clip(np.searchsorted(t_imu, t_nodes[:-1], side="right") - 1, 0, len(t_imu) - 2)
    flags = step_flag[imu_step]
    dt_nodes = np.diff(t_nodes)
    w_mid = 0.5 * (w_nodes[:-1] + w_nodes[1:])
    # [ω̄ − b_ω]× = [ω̄]× − [b_ω]× and [f − b_a]× = [f]× − [b_a]×: the state-free parts once
    hat_w = _hat_batch(w_mid)
    hat_f = _hat_batch(f_nodes)
    dt_col = dt_nodes[:, None]
    dt_mat = dt_nodes[:, None, None]
    ev_node = np.searchsorted(t_nodes, ev_t - tol)

    # per-step diagonal of B Q Bᵀ (density² · T); bias blocks zero for a constant bias
    dens = np.where(flags[:, None], cfg.interpolated_density[None, :], cfg.process_density[None, :])
    if cfg.bias_model == "constant":
        dens = dens.copy()
        dens[:, 2:] = 0.0
    qd = np.repeat(dens ** 2, 3, axis=1) * dt_nodes[:, None]
    qd = np.concatenate([np.zeros((len(dt_nodes), 3)), qd], axis=1)         # δp gets none

    # ---- state ----
    p = np.array(x0.position, dtype=float)
    v = np.array(x0.velocity, dtype=float)
    R = np.array(x0.rotation, dtype=float)
    ba = np.array(x0.accel_bias, dtype=float)
    bw = np.array(x0.gyro_bias, dtype=float)
    P = initial_covariance(cfg) if P0 is None else np.array(P0, dtype=float)
    hat_ba, hat_bw = so3.hat(ba), so3.hat(bw)
    R_lidar = np.diag(cfg.lidar_std ** 2)
    R_gnss = np.eye(3) * cfg.gnss_std ** 2
    r_lidar, r_gnss = np.diag(R_lidar).copy(), np.diag(R_gnss).copy()
    pose_idx = np.array([0, 1, 2, 6, 7, 8])
    exact = cfg.exact_reset

    # outputs: one row per distinct event node
    out_nodes, first = np.unique(ev_node, return_index=True)
    K_out = len(out_nodes)
    o_t = t_nodes[out_nodes]
    o_p, o_v, o_ba, o_bw = (np.zeros((K_out, 3)) for _ in range(4))
    o_R = np.zeros((K_out, 3, 3))
    o_P = np.zeros((K_out, 15, 15))
    o_upd = np.zeros(K_out, dtype=bool)
    innovations, S_list = [], []
    if record_all:
        all_p = np.zeros((len(t_nodes), 3)); all_R = np.zeros((len(t_nodes), 3, 3))
        all_p[0], all_R[0] = p, R

    F_template = np.tile(_I15, (int(np.max(np.diff(np.concatenate([[0], out_nodes])), initial=1)), 1, 1))
    e = 0                       # index into the sorted events
    node = 0
    for oi, target in enumerate(out_nodes):
        # ---- propagate node → target in one vectorised segment ----
        n = target - node
        if n > 0:
            sl = slice(node, target)
            dt = dt_nodes[sl]
            dtc = dt_col[sl]
            dt3 = dt_mat[sl]
            E = _exp_batch((w_mid[sl] - bw) * dtc)
            Rs = np.empty((n + 1, 3, 3))
            Rs[0] = R
            for i in range(n):
                Rs[i + 1] = Rs[i] @ E[i]
            a_b = f_nodes[node:target + 1] - ba
            acc = np.einsum("kij,kj->ki", Rs, a_b) + g
            am = 0.5 * (acc[:-1] + acc[1:])
            dv = am * dtc
            vs = np.empty((n + 1, 3))
            vs[0] = v
            np.cumsum(dv, axis=0, out=vs[1:])
            vs[1:] += v
            p_new = p + np.sum((vs[:-1] + 0.5 * dv) * dtc, axis=0)
            if record_all:
                all_p[node + 1:target + 1] = p + np.cumsum((vs[:-1] + 0.5 * dv) * dtc, axis=0)
                all_R[node + 1:target + 1] = Rs[1:]
            # discrete F for each step, evaluated at the start of the step
            Fs = F_template[:n].copy()
            Rdt = Rs[:-1] * dt3
            Fs[:, 0, 3] = Fs[:, 1, 4] = Fs[:, 2, 5] = dt
            Fs[:, 3:6, 6:9] = Rdt @ (hat_ba - hat_f[sl])
            Fs[:, 3:6, 9:12] = -Rdt
            Fs[:, 6:9, 6:9] -= (hat_w[sl] - hat_bw) * dt3
            Fs[:, 6, 12] = Fs[:, 7, 13] = Fs[:, 8, 14] = -dt
            # P_n = Φ P Φᵀ + Σ_i Ψ_i Q_i Ψ_iᵀ with Ψ_i = F_{n−1} ⋯ F_{i+1} and Φ = Ψ_0 F_0: the
            # same as n sequential steps F P Fᵀ + Q, with one matrix product per step
            Psi = np.empty((n, 15, 15))
            Psi[n - 1] = _I15
            for i in range(n - 2, -1, -1):
                np.matmul(Psi[i + 1], Fs[i + 1], out=Psi[i])
            Phi = Psi[0] @ Fs[0]
            Pq = (Psi * qd[sl][:, None, :]) @ np.swapaxes(Psi, 1, 2)
            P = Phi @ P @ Phi.T + Pq.sum(axis=0)
            P = 0.5 * (P + P.T)
            p, v, R = p_new, vs[-1].copy(), Rs[-1]
            node = target
        # ---- every observation at this node ----
        updated = False
        while e < len(ev_t) and ev_node[e] == target:
            kind, idx = ev_kind[e], ev_idx[e]
            e += 1
            if kind == 2:
                continue
            if kind == 0:
                Rm = lidar_R[idx]
                y = np.concatenate([p - lidar_p[idx], _log1(Rm.T @ R)])
                Pc = P[:, pose_idx]
                S = Pc[pose_idx] + R_lidar
                K = np.linalg.solve(S, Pc.T).T
                A = _I15.copy()
                A[:, pose_idx] -= K
                P = A @ P @ A.T + (K * r_lidar) @ K.T
            else:
                y = p - gnss_p[idx]
                Pc = P[:, 0:3]
                S = Pc[0:3] + R_gnss
                K = np.linalg.solve(S, Pc.T).T
                A = _I15.copy()
                A[:, 0:3] -= K
                P = A @ P @ A.T + (K * r_gnss) @ K.T
            innovations.append(y)
            S_list.append(S)
            dx = K @ y
            p = p - dx[0:3]
            v = v - dx[3:6]
            R = R @ _exp1(-dx[6:9])
            ba = ba - dx[9:12]
            bw = bw - dx[12:15]
            hat_ba = np.array([[0.0, -ba[2], ba[1]], [ba[2], 0.0, -ba[0]], [-ba[1], ba[0], 0.0]])
            hat_bw = np.array([[0.0, -bw[2], bw[1]], [bw[2], 0.0, -bw[0]], [-bw[1], bw[0], 0.0]])
            if exact:
                # G_r P G_rᵀ with G_r = I except its attitude block J: only rows/columns 6:9 change
                J = _left_jacobian1(dx[6:9])
                P[6:9] = J @ P[6:9]
                P[:, 6:9] = P[:, 6:9] @ J.T
            P = 0.5 * (P + P.T)
            updated = True
        if record_all:
            all_p[target], all_R[target] = p, R
        o_p[oi], o_v[oi], o_R[oi], o_ba[oi], o_bw[oi], o_P[oi] = p, v, R, ba, bw, P
        o_upd[oi] = updated

    return EskfResult(o_t, o_p, o_v, o_R, o_ba, o_bw, o_P, o_upd, innovations, S_list,
                      t_nodes if record_all else np.zeros(0),
                      all_p if record_all else np.zeros((0, 3)),
                      all_R if record_all else np.zeros((0, 3, 3)))


# ---------------------------------------------------------------------------------------
# Evaluation against ground truth
# ---------------------------------------------------------------------------------------

def _angle(R: np.ndarray) -> np.ndarray:
    c = 0.5 * (np.trace(R, axis1=-2, axis2=-1) - 1.0)
    s = 0.5 * np.linalg.norm(np.stack([R[..., 2, 1] - R[..., 1, 2], R[..., 0, 2] - R[..., 2, 0],
                                       R[..., 1, 0] - R[..., 0, 1]], -1), axis=-1)
    return np.arctan2(s, c)


def evaluate(t, position, rotation, truth, P=None, rpe_delta: float = 1.0) -> dict:
    """Pose errors of an estimate against the truth at the same times.

    Parameters
    ----------
    t : array_like, shape (K,)
        Times of the estimate; each must be one of ``truth.t`` (within 1 µs).
    position : array_like, shape (K, 3)
    rotation : array_like, shape (K, 3, 3)
    truth : TruthData
    P : array_like, shape (K, 15, 15) or (K, 6, 6), optional
        The filter covariance (or just its [δp, δθ] block), for the 6-dof pose NEES.
    rpe_delta : float
        Time separation of the relative pose error, s.

    Returns
    -------
    dict
        ``ape_position`` (RMSE of |p − p_true|, m), ``ape_attitude_deg`` (RMS rotation angle
        of R_trueᵀ R, degrees), ``rpe_position`` and ``rpe_attitude_deg`` (RMSE of the
        relative pose error over ``rpe_delta``), ``nees_pose`` (mean 6-dof NEES; NaN without
        P), ``position_error`` (K, 3), ``attitude_error`` (K, 3) = Log(R_trueᵀ R) (nominal −
        true, rad), ``nees`` (K,).
    """
    t = np.asarray(t, dtype=float)
    p = np.asarray(position, dtype=float)
    Rm = np.asarray(rotation, dtype=float)
    k = np.searchsorted(truth.t, t - 1e-6)
    k = np.clip(k, 0, len(truth.t) - 1)
    if np.any(np.abs(truth.t[k] - t) > 1e-6):
        raise ValueError("evaluate needs estimates at the truth's times")
    pt, Rt = truth.position[k], truth.rotation[k]
    ep = p - pt
    dR = np.swapaxes(Rt, -1, -2) @ Rm
    eth = so3.log(dR)
    out = {
        "ape_position": float(np.sqrt(np.mean(np.sum(ep ** 2, axis=1)))),
        "ape_attitude_deg": float(np.rad2deg(np.sqrt(np.mean(_angle(dR) ** 2)))),
        "position_error": ep,
        "attitude_error": eth,
    }
    # relative pose error over rpe_delta seconds
    j = np.searchsorted(t, t + rpe_delta - 1e-3)
    ok = j < len(t)
    i, j = np.nonzero(ok)[0], j[ok]
    Rti, Rtj, Ri, Rj = Rt[i], Rt[j], Rm[i], Rm[j]
    rel_t_p = np.einsum("kji,kj->ki", Rti, pt[j] - pt[i])
    rel_e_p = np.einsum("kji,kj->ki", Ri, p[j] - p[i])
    rel_t_R = np.swapaxes(Rti, -1, -2) @ Rtj
    rel_e_R = np.swapaxes(Ri, -1, -2) @ Rj
    out["rpe_position"] = float(np.sqrt(np.mean(np.sum((rel_e_p - rel_t_p) ** 2, axis=1))))
    out["rpe_attitude_deg"] = float(np.rad2deg(np.sqrt(np.mean(
        _angle(np.swapaxes(rel_t_R, -1, -2) @ rel_e_R) ** 2))))
    if P is not None:
        P = np.asarray(P, dtype=float)
        idx = [0, 1, 2, 6, 7, 8]
        Pp = P if P.shape[-1] == 6 else P[:, idx][:, :, idx]
        e6 = np.concatenate([ep, eth], axis=1)
        nees = np.einsum("ki,ki->k", e6, np.linalg.solve(Pp, e6[..., None])[..., 0])
        out["nees"] = nees
        out["nees_pose"] = float(np.mean(nees))
    else:
        out["nees"] = np.full(len(t), np.nan)
        out["nees_pose"] = float("nan")
    return out
