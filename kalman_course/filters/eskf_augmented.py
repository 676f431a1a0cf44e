"""The ESKF with its error state augmented by a Gauss–Markov model of the pose observation's error.

Why
---
The filter of :mod:`kalman_course.filters.eskf` assumes that each lidar pose's error is
white: independent of the one before. A map-matching error is not: it drifts slowly and
is nearly the same 0.1 s later. Modelled as a first-order Gauss–Markov process per
component (as :class:`kalman_course.data.GaussMarkovErrors` simulates it), the error
e = [e_p, e_θ] (6) of the reported pose, p_m = p + e_p and R_m = R Exp(e_θ), obeys

    ė = −e / τ + white noise,   stationary covariance diag(σ²)

and over a step of T seconds

    e_k = φ e_{k−1} + w_k,   φ = exp(−T / τ),   Cov(w_k) = diag(σ² (1 − φ²)).

This filter estimates e with the navigation errors: it keeps a nominal ê (6) beside the
nominal state x = (p, v, R, b_a, b_ω), and its error state is

    δx = [δp, δv, δθ, δb_a, δb_ω, δe]  (21),   δe = ê − e  (nominal − true, as for δx).

Propagation (one step of T seconds, or a stack of IMU steps composed)
--------------------------------------------------------------------
The 15 navigation rows are those of the plain ESKF (the same kernel, ``eskf._propagate``):
Φ = ∏ F_i and P_xx ← Φ P_xx Φᵀ + Σ noise. The observation-error rows are

    ê ← φ ê,   F_aug = [[Φ, 0], [0, φ I₆]],   Q_aug = blockdiag(noise, σ² (1 − φ²))

so P_xe ← φ Φ P_xe and P_ee ← φ² P_ee + diag(σ² (1 − φ²)) (:func:`augmented_transition`,
:func:`augmented_process_noise`). Over n IMU steps the φ's multiply to exp(−ΣT/τ) and the
added variances telescope to σ² (1 − φ_total²), so one composed step equals n single ones.

Update (a lidar pose)
---------------------
The pose residual y = [p̌ − p_m; Log(R_mᵀ Ř)] of the plain ESKF is, to first order,
y = G δx − e = G δx − ê + δe. The filter adds its prediction of the error back,

    r = y + ê = G_aug δx + n_w,   G_aug = [G, I₆] (6, 21),

where n_w is an optional small white part with covariance R_w = diag(white_std²) (0 by
default: the Gauss–Markov state carries the whole error). The update is the plain ESKF's,
K = P G_augᵀ S⁻¹ and the Joseph form, with the injection x̂ = x̌ ⊖ δx̂[:15] of the plain
filter, ê ← ê − δê, and the reset δx̂ ← 0 (the exact reset changes the attitude block only;
the δe block of the reset Jacobian is the identity).

One set of formulas
-------------------
Every navigation formula comes from :mod:`kalman_course.filters.eskf` (its kernels
``_propagate``, ``_pose_residual``, ``_gain``, ``_inject``, ``_reset_covariance``, its
argument checks and its IMU-gap rule); the two Gauss–Markov formulas are written once here
(``_gm_decay``, ``_gm_noise``). Without augmentation (``time_constant=None``) the drivers
run the 15-state filter through the same code, and :func:`run` then reproduces
:func:`kalman_course.filters.eskf.run` to the last bit; as τ → 0 (φ = 0 between
observations) it reproduces the plain filter with R = diag(σ² + white_std²) to round-off.

Drivers: :class:`AugmentedESKF` (one step at a time) and :func:`run` (a whole IMU record,
lidar poses only).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy import dot

from kalman_course.core.linalg import joseph_update
from kalman_course.core.observations import PoseObservations
from kalman_course.core.validation import as_covariance, as_flag, as_matrix, as_scalar, as_vector
from kalman_course.filters import eskf
from kalman_course.filters.eskf import (IDX_TH, IMU_GAP_FACTOR, POSE_G, EskfResult, NominalState,
                                        initial_covariance)
from kalman_course.filters.eskf_config import EskfConfig

__all__ = ["AugmentedESKF", "AugmentedResult", "run", "gauss_markov_decay", "gauss_markov_noise",
           "augmented_transition", "augmented_process_noise", "augmented_observation_matrix",
           "augmented_residual", "augmented_initial_covariance", "IDX_E", "N_AUGMENTED"]

#: Rows of δe (observation error [e_p, e_θ]) in the augmented error state.
IDX_E = slice(15, 21)
#: Size of the augmented error state.
N_AUGMENTED = 21

_I6 = np.eye(6)
_G_AUG = np.hstack([POSE_G, _I6])
_G_AUG.setflags(write=False)


# ---------------------------------------------------------------------------------------
# Argument checks
# ---------------------------------------------------------------------------------------

def _as_time_constant(value) -> float | None:
    """τ in s (> 0), or None for no augmentation."""
    if value is None:
        return None
    return as_scalar(value, "time_constant")


def _as_sigmas(value, name: str, default: np.ndarray, allow_zero: bool) -> np.ndarray:
    """A (6,) vector of standard deviations [m ×3, rad ×3] (``default`` if None)."""
    if value is None:
        return np.array(default, dtype=float)
    s = np.array(as_vector(value, name, 6))
    if (s < 0.0).any() or (not allow_zero and (s == 0.0).any()):
        kind = "non-negative" if allow_zero else "positive"
        raise ValueError(f"{name} must hold six {kind} standard deviations [m, m, m, rad, rad, rad], got {s}")
    return s


@dataclass(frozen=True)
class _Model:
    """The validated observation-error model: τ (None: no augmentation), σ (6,), white std (6,)."""

    time_constant: float | None
    sigma: np.ndarray
    white_std: np.ndarray

    @property
    def n(self) -> int:
        return 15 if self.time_constant is None else N_AUGMENTED


def _as_model(config: EskfConfig, time_constant, sigma, white_std) -> _Model:
    tau = _as_time_constant(time_constant)
    lidar_std = config.lidar_std
    if tau is None:
        if sigma is not None or white_std is not None:
            raise ValueError("sigma and white_std describe the Gauss–Markov state: give them only with a "
                             "time_constant (without one the filter uses the configuration's lidar R)")
        return _Model(None, lidar_std, np.zeros(6))
    return _Model(tau, _as_sigmas(sigma, "sigma", lidar_std, allow_zero=False),
                  _as_sigmas(white_std, "white_std", np.zeros(6), allow_zero=True))


# ---------------------------------------------------------------------------------------
# Kernels (unvalidated): the two Gauss–Markov formulas, propagation, update
# ---------------------------------------------------------------------------------------

def _gm_decay(T, tau: float):
    """φ = exp(−T/τ) for a step of T s (scalar or array)."""
    return np.exp(-np.asarray(T, dtype=float) / tau)


def _gm_noise(sigma: np.ndarray, phi) -> np.ndarray:
    """Variance added over a step with decay φ: σ² (1 − φ²), shape (6,)."""
    return sigma ** 2 * (1.0 - phi ** 2)


def _measurement_noise(config: EskfConfig, model: _Model) -> np.ndarray:
    """R of the update: the configuration's lidar R (no augmentation) or diag(white_std²)."""
    if model.time_constant is None:
        return eskf._lidar_noise(config)
    return np.diag(model.white_std ** 2)


def _propagate(x: NominalState, P, e_hat, f, w_mean, dt, q, g, bias_model: str, model: _Model):
    """Nominal state, ê and P over n IMU steps (``f`` (n+1, 3), ``w_mean``, ``dt``, ``q`` as in
    ``eskf._propagate``). Returns (x, P, ê, positions (n+1, 3), rotations (n+1, 3, 3))."""
    x, P_xx, Phi, ps, Rs = eskf._propagate(x, P[:15, :15], f, w_mean, dt, q, g, bias_model)
    if model.time_constant is None:
        return x, P_xx, e_hat, ps, Rs
    phi = float(_gm_decay(dt.sum(), model.time_constant))
    P_new = np.empty_like(P)
    P_new[:15, :15] = P_xx
    P_new[:15, IDX_E] = phi * dot(Phi, P[:15, IDX_E])
    P_new[IDX_E, :15] = P_new[:15, IDX_E].T
    P_new[IDX_E, IDX_E] = phi ** 2 * P[IDX_E, IDX_E] + np.diag(_gm_noise(model.sigma, phi))
    return x, P_new, phi * e_hat, ps, Rs


def _correct(x: NominalState, P, e_hat, y, R, exact_reset: bool, G15=None):
    """Pose update with the plain residual y (6,): r = y + ê, gain, Joseph form, inject, reset.

    Without augmentation (P 15 × 15, ê empty) the same operations as ``eskf._correct``.
    ``G15`` (m, 15) marks an update from another stream, whose errors are white: r = y and
    G = [G15, 0]. Returns (x̂, P̂, ê, innovation r, S).
    """
    n = P.shape[0]
    if G15 is not None:
        G = G15 if n == 15 else np.hstack([G15, np.zeros((G15.shape[0], n - 15))])
        r = y
    else:
        G = POSE_G if n == 15 else _G_AUG
        r = y if n == 15 else y + e_hat
    K, S = eskf._gain(P, G, R)
    dx = dot(K, r)
    P = joseph_update(P, K, G, R, np.eye(n))
    x = eskf._inject(x, dx[:15])
    e_hat = e_hat - dx[15:]
    return x, eskf._reset_covariance(P, dx[IDX_TH], exact_reset, overwrite=True), e_hat, r, S


def _initial_covariance(config: EskfConfig, model: _Model, P0) -> np.ndarray:
    """P̂₀: the navigation block from ``P0`` or the configuration, δe block diag(σ²) (stationary)."""
    P_xx = initial_covariance(config) if P0 is None else np.array(as_covariance(P0, "P0", 15, psd=True))
    if model.time_constant is None:
        return P_xx
    P = np.zeros((N_AUGMENTED, N_AUGMENTED))
    P[:15, :15] = P_xx
    P[IDX_E, IDX_E] = np.diag(model.sigma ** 2)
    return P


# ---------------------------------------------------------------------------------------
# Building blocks (validated), for lectures and exercises
# ---------------------------------------------------------------------------------------

def gauss_markov_decay(T: float, time_constant: float) -> float:
    """φ = exp(−T/τ): how much of the observation error survives a step of T seconds.

    Parameters
    ----------
    T : float
        Step length, s (> 0).
    time_constant : float
        τ, s (> 0).
    """
    return float(_gm_decay(as_scalar(T, "T"), as_scalar(time_constant, "time_constant")))


def gauss_markov_noise(sigma, T: float, time_constant: float) -> np.ndarray:
    """Variance σ² (1 − φ²) (6,) that keeps the process stationary over a step of T seconds.

    Parameters
    ----------
    sigma : array_like, shape (6,)
        Stationary standard deviations [σ_p ×3 (m), σ_θ ×3 (rad)], positive.
    T, time_constant : float
        Step length and τ, s (> 0).
    """
    sigma = _as_sigmas(sigma, "sigma", np.zeros(6), allow_zero=False)
    return _gm_noise(sigma, _gm_decay(as_scalar(T, "T"), as_scalar(time_constant, "time_constant")))


def augmented_transition(F, T: float, time_constant: float) -> np.ndarray:
    """F_aug = [[F, 0], [0, φ I₆]] (21, 21), φ = exp(−T/τ).

    Parameters
    ----------
    F : array_like, shape (15, 15)
        The plain ESKF's discrete transition over the step (:func:`eskf.discretise`).
    T, time_constant : float
        Step length and τ, s (> 0).
    """
    F = as_matrix(F, "F", (15, 15))
    phi = gauss_markov_decay(T, time_constant)
    F_aug = np.zeros((N_AUGMENTED, N_AUGMENTED))
    F_aug[:15, :15] = F
    F_aug[IDX_E, IDX_E] = phi * _I6
    return F_aug


def augmented_process_noise(BQBt, sigma, T: float, time_constant: float) -> np.ndarray:
    """Q_aug = blockdiag(B Q Bᵀ, diag(σ² (1 − φ²))) (21, 21), added to P̌ over one step.

    Parameters
    ----------
    BQBt : array_like, shape (15, 15)
        The plain ESKF's process noise in state space (B Q Bᵀ), symmetric.
    sigma : array_like, shape (6,)
        Stationary standard deviations of the observation error [m ×3, rad ×3].
    T, time_constant : float
        Step length and τ, s (> 0).
    """
    BQBt = as_covariance(BQBt, "BQBt", 15, psd=True)
    Q = np.zeros((N_AUGMENTED, N_AUGMENTED))
    Q[:15, :15] = BQBt
    Q[IDX_E, IDX_E] = np.diag(gauss_markov_noise(sigma, T, time_constant))
    return Q


def augmented_observation_matrix() -> np.ndarray:
    """G_aug = [G, I₆] (6, 21): the residual y + ê depends on δp, δθ and δe (a copy)."""
    return _G_AUG.copy()


def augmented_residual(p_check, R_check, e_hat, p_meas, R_meas) -> np.ndarray:
    """r = [p̌ − p_m; Log(R_mᵀ Ř)] + ê (6,): the plain residual plus the predicted error.

    Parameters
    ----------
    p_check : array_like, shape (3,)
        Predicted position, m.
    R_check : array_like, shape (3, 3)
        Predicted attitude (rotation matrix).
    e_hat : array_like, shape (6,)
        The nominal observation error ê = [ê_p (m), ê_θ (rad)].
    p_meas, R_meas : array_like, shapes (3,) and (3, 3)
        The reported pose.
    """
    return eskf.pose_residual(p_check, R_check, p_meas, R_meas) + as_vector(e_hat, "e_hat", 6)


def augmented_initial_covariance(config="kitti_lidar", sigma=None, P0=None) -> np.ndarray:
    """P̂₀ (21, 21): the navigation prior and the stationary σ² of the observation error.

    Parameters
    ----------
    config : EskfConfig or str
    sigma : array_like, shape (6,), optional
        Default: the configuration's lidar standard deviations.
    P0 : array_like, shape (15, 15), optional
        Navigation prior (default: from the configuration).
    """
    cfg = eskf._as_config(config)
    return _initial_covariance(cfg, _as_model(cfg, 1.0, sigma, None), P0)


# ---------------------------------------------------------------------------------------
# Step-by-step filter
# ---------------------------------------------------------------------------------------

class AugmentedESKF:
    """The ESKF plus six Gauss–Markov observation-error states, one call per IMU step or pose.

    Parameters
    ----------
    config : EskfConfig or str
        The navigation configuration (process noise, prior; its lidar R only without
        augmentation).
    initial : NominalState or NavState
    gravity : array_like, shape (3,)
        m/s², navigation frame.
    time_constant : float or None
        τ of the observation error, s (> 0). None: no augmentation (the plain 15-state ESKF).
    sigma : array_like, shape (6,), optional
        Stationary σ of the observation error [m ×3, rad ×3] (default: the configuration's
        lidar standard deviations).
    white_std : array_like, shape (6,), optional
        Standard deviations of an extra white part of the observation error (default 0).
    P0 : array_like, shape (15, 15), optional
        Navigation prior (default: from the configuration); the δe block is diag(σ²).

    Attributes
    ----------
    nominal : NominalState
    error_estimate : numpy.ndarray, shape (6,) or (0,)
        ê = [ê_p (m), ê_θ (rad)], the estimated error of the next lidar pose.
    P : numpy.ndarray, shape (21, 21) or (15, 15)
    """

    def __init__(self, config, initial, gravity, time_constant=None, sigma=None, white_std=None, P0=None):
        self.config = eskf._as_config(config)
        self.model = _as_model(self.config, time_constant, sigma, white_std)
        self.nominal = eskf._as_nominal(initial, "initial")
        self.gravity = eskf._as_gravity(gravity)
        self.P = _initial_covariance(self.config, self.model, P0)
        self.error_estimate = np.zeros(self.model.n - 15)

    def predict(self, f0, w0, f1, w1, dt: float, interpolated: bool = False) -> None:
        """Propagate x, ê and P over one IMU interval (as :meth:`eskf.ESKF.predict`, plus the δe rows).

        Parameters
        ----------
        f0, w0, f1, w1 : array_like, shape (3,)
            Specific force (m/s²) and angular rate (rad/s) at the start and end.
        dt : float
            Step length, s (> 0).
        interpolated : bool
            Use the configuration's inflated ``interpolated_imu`` noise.
        """
        f = np.stack([as_vector(f0, "f0", 3), as_vector(f1, "f1", 3)])
        w = np.stack([as_vector(w0, "w0", 3), as_vector(w1, "w1", 3)])
        dt = as_scalar(dt, "dt")
        cfg = self.config
        density = cfg.interpolated_density if as_flag(interpolated, "interpolated") else cfg.process_density
        q = eskf._process_noise(density, dt, cfg.bias_model)
        self.nominal, self.P, self.error_estimate, _, _ = _propagate(
            self.nominal, self.P, self.error_estimate, f, 0.5 * (w[:1] + w[1:]), np.array([dt]), q[None],
            self.gravity, cfg.bias_model, self.model)

    def update_pose(self, p_meas, R_meas) -> dict:
        """Lidar pose update, injection and reset; returns the innovation r (6,) and S (6, 6).

        ``p_meas`` (3,) m; ``R_meas`` (3, 3) a rotation matrix.
        """
        y = eskf.pose_residual(self.nominal.position, self.nominal.rotation, p_meas, R_meas)
        self.nominal, self.P, self.error_estimate, r, S = _correct(
            self.nominal, self.P, self.error_estimate, y, _measurement_noise(self.config, self.model),
            self.config.exact_reset)
        return {"innovation": r, "S": S}


# ---------------------------------------------------------------------------------------
# Batch runner
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class AugmentedResult(EskfResult):
    """Output of :func:`run`: an :class:`~kalman_course.filters.eskf.EskfResult` (``P`` is
    the 15 × 15 navigation block, so every evaluation of the plain filter applies) plus the
    observation-error state.

    Attributes
    ----------
    error_estimate : numpy.ndarray, shape (K, 6) or (K, 0)
        ê = [ê_p (m), ê_θ (rad)] at ``t`` (after the update): the filter's estimate of the
        error of the pose reported at t (empty columns without augmentation).
    P_full : numpy.ndarray, shape (K, 21, 21) or (K, 15, 15)
        The whole covariance.
    time_constant : float or None
        τ of the model, s (None: no augmentation).
    """

    error_estimate: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 6)))
    P_full: np.ndarray = field(repr=False, default_factory=lambda: np.zeros((0, 21, 21)))
    time_constant: float | None = None

    def at(self, times) -> "AugmentedResult":
        """The rows whose time is one of ``times`` (within 1 µs, in any order), e.g. the truth's times."""
        keep = eskf._rows_at(self.t, times)
        return AugmentedResult(self.t[keep], self.position[keep], self.velocity[keep], self.rotation[keep],
                               self.accel_bias[keep], self.gyro_bias[keep], self.P[keep], self.updated[keep],
                               self.innovation, self.S, sources=self.sources, error_estimate=self.error_estimate[keep],
                               P_full=self.P_full[keep], time_constant=self.time_constant)


def _timeline(t_imu, f_imu, w_imu, step_flag, event_sources, cfg: EskfConfig):
    """``eskf.run``'s merged timeline and events, with each step's length and process noise.

    The last of ``event_sources`` is the output-only times (kept from the start, as there).
    Returns t_nodes, f_nodes, the mean rates, the steps, the per-step Q diagonals and the
    sorted events as plain lists (node, kind, index).
    """
    ev_t, ev_kind, ev_idx = eskf._sorted_events(event_sources, t_imu[0], t_imu[-1],
                                                from_start=(len(event_sources) - 1,))
    t_nodes, f_nodes, w_mean, flags, ev_node = eskf._timeline(t_imu, f_imu, w_imu, step_flag, ev_t)
    dt_nodes = np.diff(t_nodes)
    q = eskf._process_noise(np.where(flags[:, None], cfg.interpolated_density, cfg.process_density),
                            dt_nodes, cfg.bias_model)
    return t_nodes, f_nodes, w_mean, dt_nodes, q, ev_node.tolist(), ev_kind.tolist(), ev_idx.tolist()


def run(imu, initial, config="kitti_lidar", gravity=(0.0, 0.0, -9.8092), *, lidar, time_constant=None,
        sigma=None, white_std=None, streams=None, start: int = 0, t_end: float | None = None, output_times=None,
        clip_output_times: bool = False, P0=None,
        use_interpolation_flags: bool = True, gap_factor: float | None = IMU_GAP_FACTOR) -> AugmentedResult:
    """Run the augmented ESKF over an IMU record, fusing lidar poses with Gauss–Markov errors.

    The timeline is :func:`kalman_course.filters.eskf.run`'s (IMU samples plus a node at each
    observation, with the IMU reading interpolated there; gaps and interpolated samples get
    the configuration's inflated noise); each stretch between two nodes is propagated as one
    stack of steps.

    Parameters
    ----------
    imu : object
        ``t`` (N,) s strictly increasing, ``specific_force`` (N, 3) m/s², ``angular_rate``
        (N, 3) rad/s, optionally ``interpolated`` (N,) bool (e.g. ``load_kitti("turns").imu``).
    initial : NominalState or NavState
        The state at ``imu.t[start]``.
    config : EskfConfig or str
        Navigation configuration; without augmentation also the lidar R.
    gravity : array_like, shape (3,)
    lidar : PoseObservations
        Reported poses ``t`` (K,), ``position`` (K, 3), ``rotation`` (K, 3, 3); other
        objects with these attributes are converted (and validated).
    time_constant : float or None
        τ of the observation error's Gauss–Markov model, s (> 0). None: no augmentation;
        the result then equals :func:`eskf.run` with the same arguments.
    sigma : array_like, shape (6,), optional
        Its stationary σ [m ×3, rad ×3], positive (default: the configuration's lidar std).
    white_std : array_like, shape (6,), optional
        σ of an extra white part [m ×3, rad ×3], ≥ 0 (default 0).
    streams : list of ObservationStream, optional
        Further sensors with white errors (e.g. GNSS positions with a lever arm), as in
        :func:`kalman_course.filters.eskf.run`; used after the lidar pose at equal times.
    start : int
        Index of the first IMU sample.
    t_end : float, optional
        Stop at this time (default: the last IMU sample).
    output_times : array_like, optional
        Extra times at which to record the state without an update, as in
        :func:`kalman_course.filters.eskf.run` (strictly increasing; a time equal to
        ``imu.t[start]`` gives the initial state; times outside the run a warning).
    clip_output_times : bool
        Drop the ``output_times`` outside the run without a warning.
    P0 : array_like (15, 15), optional
        Navigation prior, symmetric (default: the configuration's); δe starts at diag(σ²).
    use_interpolation_flags : bool
        Inflate the process noise on steps touching an interpolated IMU sample.
    gap_factor : float or None
        An IMU step longer than this many median steps is a gap (see :mod:`eskf`); None: off.

    Returns
    -------
    AugmentedResult
        One row per observation or output time (after the update where there is one).

    Raises
    ------
    ValueError
        Naming the argument: bad IMU samples, observations, ``time_constant``, ``sigma``,
        ``white_std`` (or either of them without a time constant), ``P0``, ``start``,
        ``t_end`` or ``gap_factor``.
    """
    cfg = eskf._as_config(config)
    model = _as_model(cfg, time_constant, sigma, white_std)
    x = eskf._as_nominal(initial, "initial")
    g = eskf._as_gravity(gravity)
    t_imu, f_imu, w_imu, flag_imu = eskf._imu_samples(imu, start, t_end)
    eskf._gravity_against_imu(g, x.rotation, f_imu)
    if gap_factor is not None:
        gap_factor = as_scalar(gap_factor, "gap_factor")
    if lidar is None:
        raise ValueError("lidar must be a PoseObservations (t, position, rotation), got None")
    lidar = eskf._as_observations(lidar, "lidar", PoseObservations)
    others = eskf._as_streams(lidar, None, streams, cfg)[1:]
    P = _initial_covariance(cfg, model, P0)
    e_hat = np.zeros(model.n - 15)
    step_flag = eskf._imu_gaps(np.diff(t_imu), gap_factor)
    if as_flag(use_interpolation_flags, "use_interpolation_flags"):
        step_flag |= flag_imu[:-1] | flag_imu[1:]
    outputs = eskf._as_output_times(output_times, t_imu[0], t_imu[-1], clip_output_times)

    # kinds in eskf.run's order (lidar, the other streams, output only), so that ties are ordered alike
    t_nodes, f_nodes, w_mean, dt_nodes, q, ev_node, ev_kind, ev_idx = _timeline(
        t_imu, f_imu, w_imu, step_flag, [lidar.t] + [s.t for s in others] + [outputs], cfg)
    R = _measurement_noise(cfg, model)
    exact = cfg.exact_reset

    rows, innovations, S_list, used_sources = [], [], [], []
    e, node, n_events = 0, 0, len(ev_node)
    for target in np.unique(ev_node).tolist():
        if target > node:
            sl = slice(node, target)
            x, P, e_hat, _, _ = _propagate(x, P, e_hat, f_nodes[node:target + 1], w_mean[sl], dt_nodes[sl],
                                           q[sl], g, cfg.bias_model, model)
            node = target
        updated = False
        while e < n_events and ev_node[e] == target:
            kind, idx = ev_kind[e], ev_idx[e]
            e += 1
            if kind == 0:
                y = eskf._pose_residual(x.position, x.rotation, lidar.position[idx], lidar.rotation[idx])
                x, P, e_hat, r, S = _correct(x, P, e_hat, y, R, exact)
                used_sources.append("lidar")
            elif kind <= len(others):
                stream = others[kind - 1]
                y = stream.residual(idx, x.position, x.rotation)
                x, P, e_hat, r, S = _correct(x, P, e_hat, y, stream.R, exact,
                                             G15=eskf._stream_jacobian(stream, x.rotation))
                used_sources.append(stream.name)
            else:
                continue
            innovations.append(r)
            S_list.append(S)
            updated = True
        rows.append((x, P, e_hat, updated))

    out_nodes = np.unique(np.asarray(ev_node, dtype=int))

    def stacked(name, shape):
        return np.array([getattr(state, name) for state, _, _, _ in rows]).reshape(-1, *shape)

    P_full = np.array([P_k for _, P_k, _, _ in rows]).reshape(-1, model.n, model.n)
    return AugmentedResult(t_nodes[out_nodes], stacked("position", (3,)), stacked("velocity", (3,)),
                           stacked("rotation", (3, 3)), stacked("accel_bias", (3,)), stacked("gyro_bias", (3,)),
                           np.ascontiguousarray(P_full[:, :15, :15]),
                           np.array([used for _, _, _, used in rows], dtype=bool), innovations, S_list,
                           sources=used_sources, error_estimate=np.array([e_k for _, _, e_k, _ in rows]).reshape(len(rows), model.n - 15),
                           P_full=P_full, time_constant=model.time_constant)
