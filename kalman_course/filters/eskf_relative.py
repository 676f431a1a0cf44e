"""The ESKF fed relative pose increments (visual odometry) by stochastic cloning.

A visual odometry (VO) system reports where the camera is in *its own* map. Its error
grows with the distance travelled, so feeding its poses to the ESKF as absolute
observations (as the lidar poses of chapter 08) makes the filter inherit that drift and
believe it is small. What VO measures well is the motion between two frames,

    ΔT_m = T_{k−1}⁻¹ T_k:   Δp_m = R_{k−1}ᵀ (p_k − p_{k−1}),   ΔR_m = R_{k−1}ᵀ R_k,

whose error does not accumulate. This module fuses exactly that (loosely coupled
visual-inertial odometry), with stochastic cloning (Roumeliotis & Burdick, ICRA 2002):

- at every VO frame the filter's current pose is *cloned*: the error state is augmented
  to δx_a = [δx (15); δp_c, δθ_c] (21) with P_a = [[P, P Jᵀ], [J P, J P Jᵀ]],
  J = :data:`~kalman_course.filters.eskf.POSE_G` (the clone is the same random variable as
  the current pose, so it is fully correlated with it);
- between frames only the 15-state part moves: P ← Φ P Φᵀ + Q on the 15 × 15 block,
  the cross-covariance P_xc ← Φ P_xc, the clone block unchanged (the clone is a constant);
- at the next frame the predicted increment Δp̌ = Ř_cᵀ (p̌ − p̌_c), ΔŘ = Ř_cᵀ Ř gives the
  residual (prediction minus measurement, as the ESKF's)

      y = [Δp̌ − Δp_m;  Log(ΔR_mᵀ ΔŘ)]  ≈  G_rel δx_a + n,

  with (error = nominal − true, Ř = R Exp(δθ), Ř_c = R_c Exp(δθ_c), first order)

      ∂y_p/∂δp = Ř_cᵀ,   ∂y_p/∂δp_c = −Ř_cᵀ,   ∂y_p/∂δθ_c = [Δp̌]×,
      ∂y_θ/∂δθ = I,      ∂y_θ/∂δθ_c = −ΔŘᵀ

  (:func:`relative_pose_residual`, :func:`relative_pose_jacobian`); the update, the
  injection into the current state *and* the clone, and the reset follow; then the
  clone is replaced by the new pose.

GNSS fixes (``gnss``) update the same augmented state with G = [I, 0, 0, 0, 0 | 0, 0]; the
clone is corrected through its cross-covariance like every other part.

Where the Jacobians are linearised (``linearise_at``)
---------------------------------------------------
With increments only, the global position and the heading (a rotation about gravity) are
unobservable: moving the whole trajectory, or turning it about the vertical, changes no
increment. In error coordinates that turn is the direction (u = unit vector along g)

    N(p, v, R) = [[u]× p;  [u]× v;  Rᵀ u;  0;  0]      (15, per radian),

and for the clone [[u]× p_c; R_cᵀ u]. G_rel annihilates [N(x); N(clone)] at any pair of
poses, and the transition over one frame interval maps N at its start to N at its end
when its pose blocks are those of the nominal trajectory from a to b (T seconds):

    Φ_pθ = −[p_b − p_a − v_a T − ½ g T²]× R_a,   Φ_vθ = −[v_b − v_a − g T]× R_a,   Φ_θθ = R_bᵀ R_a

(:func:`pose_transition_blocks`; exact for the continuous error dynamics). The default
(``linearise_at=None``) evaluates everything at the current estimates, so Φ starts from the
*updated* state at frame k while the covariance's unobservable direction was carried to the
*predicted* one; the difference is the update's correction, and it lets the filter gain
information along N that no measurement carries (the inconsistency of Huang, Mourikis and
Roumeliotis). Two other choices are offered:

- ``"first_estimates"`` (FEJ): every Jacobian at the first estimate of the state it
  belongs to: the clone at its prediction before the update of its frame, and over each
  interval the three pose blocks of Φ replaced by the ones above with a = that prediction
  and b = the prediction at the end (the rest of Φ and the process noise as computed);
- a truth (anything with ``t``, ``position``, ``velocity``, ``rotation`` at every VO frame's
  time): the same with a, b and both poses of G_rel taken from it, the "ideal EKF"
  diagnostic, which needs the truth and so only serves to find the cause.

The residual y is always formed at the estimates.

Everything else is :mod:`kalman_course.filters.eskf`'s, used as it is: the propagation
kernel (nominal midpoint mechanisation, F, B, Q), the gain, the Joseph update, the
injection and the reset (the clone's attitude reset is the ESKF's, applied to the clone's
rows and columns), the position residual, the IMU checks and the inflated noise on
interpolated IMU samples and gaps.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy import dot

from kalman_course.core import so3
from kalman_course.core.linalg import joseph_update, symmetrise
from kalman_course.core.observations import PoseObservations
from kalman_course.core.validation import as_covariance, as_flag, as_rotation, as_scalar, as_vector
from kalman_course.filters.eskf import (IDX_P, IDX_TH, IDX_V, IMU_GAP_FACTOR, POSE_G, EskfResult, NominalState,
                                        initial_covariance)
# the ESKF's kernels and argument checks: every formula of the filter is eskf.py's
from kalman_course.filters.eskf import (_as_config, _as_gravity, _as_nominal, _as_observations, _as_streams,
                                        _correct, _gain, _gravity_against_imu, _imu_gaps, _imu_samples, _inject,
                                        _process_noise, _propagate, _reset_covariance, _sorted_events,
                                        _stream_jacobian, _timeline)

__all__ = ["IDX_PC", "IDX_THC", "relative_motion", "relative_pose_residual", "relative_pose_jacobian",
           "clone_covariance", "yaw_nullspace", "pose_transition_blocks", "RelativeRunResult", "run_relative"]

#: Rows of the clone's position and attitude errors in the augmented 21-state.
IDX_PC, IDX_THC = slice(15, 18), slice(18, 21)

_I3 = np.eye(3)
_I21 = np.eye(21)
# swaps the current attitude rows (6:9) with the clone's (18:21): the ESKF's reset, written
# for rows 6:9, then resets the clone
_SWAP_THETA = np.r_[0:6, 18:21, 9:18, 6:9]


# ---------------------------------------------------------------------------------------
# Kernels (unvalidated)
# ---------------------------------------------------------------------------------------

def _relative_motion(p0, R0, p1, R1):
    """ΔT = T0⁻¹ T1: (Δp = R0ᵀ (p1 − p0), ΔR = R0ᵀ R1)."""
    return dot(R0.T, p1 - p0), dot(R0.T, R1)


def _relative_residual(p_c, R_c, p, R, dp_meas, dR_meas):
    """y (6,) and the predicted increment (Δp̌, ΔŘ) it was made from."""
    dp_check, dR_check = _relative_motion(p_c, R_c, p, R)
    y = np.concatenate([dp_check - dp_meas, so3.log(dot(dR_meas.T, dR_check), check=False)])
    return y, dp_check, dR_check


def _relative_jacobian(R_c, dp_check, dR_check) -> np.ndarray:
    G = np.zeros((6, 21))
    G[0:3, IDX_P] = R_c.T
    G[0:3, IDX_PC] = -R_c.T
    G[0:3, IDX_THC] = so3.hat(dp_check, check=False)
    G[3:6, IDX_TH] = _I3
    G[3:6, IDX_THC] = -dR_check.T
    return G


def _yaw_nullspace(p, v, R, g) -> np.ndarray:
    """N (15,): the error of turning the state by one radian about the gravity direction."""
    u = g / np.sqrt(dot(g, g))
    n = np.zeros(15)
    n[IDX_P] = np.cross(u, p)
    n[IDX_V] = np.cross(u, v)
    n[IDX_TH] = dot(R.T, u)
    return n


def _pose_blocks(a, b, T, g):
    """(Φ_pθ, Φ_vθ, Φ_θθ) of an interval of T s from a = (p, v, R) to b along the nominal trajectory."""
    (p_a, v_a, R_a), (p_b, v_b, R_b) = a, b
    dp = p_b - p_a - v_a * T - 0.5 * g * T * T
    dv = v_b - v_a - g * T
    return (-dot(so3.hat(dp, check=False), R_a), -dot(so3.hat(dv, check=False), R_a), dot(R_b.T, R_a))


def _with_pose_blocks(Phi, a, b, T, g) -> np.ndarray:
    """Φ with its three pose blocks replaced by :func:`_pose_blocks` at (a, b)."""
    Phi = Phi.copy()
    Phi[IDX_P, IDX_TH], Phi[IDX_V, IDX_TH], Phi[IDX_TH, IDX_TH] = _pose_blocks(a, b, T, g)
    return Phi


def _clone(P15) -> np.ndarray:
    """P_a (21, 21) = [[P, P Jᵀ], [J P, J P Jᵀ]] with J = POSE_G."""
    JP = dot(POSE_G, P15)
    P = np.empty((21, 21))
    P[:15, :15] = P15
    P[15:, :15] = JP
    P[:15, 15:] = JP.T
    P[15:, 15:] = dot(JP, POSE_G.T)
    return P


def _correct_augmented(x: NominalState, clone, P, y, G, R, exact_reset: bool):
    """Update the 21-state with residual y (Jacobian G, noise R), inject into x and the clone, reset.

    Returns (x̂, clone, P̂, S).
    """
    K, S = _gain(P, G, R)
    dx = dot(K, y)
    P = joseph_update(P, K, G, R, _I21)
    x = _inject(x, dx[:15])
    p_c, R_c = clone
    clone = (p_c - dx[IDX_PC], dot(R_c, so3.exp(-dx[IDX_THC], check=False)))
    P = _reset_covariance(P, dx[IDX_TH], exact_reset, overwrite=True)
    swap = np.ix_(_SWAP_THETA, _SWAP_THETA)
    P = _reset_covariance(P[swap], dx[IDX_THC], exact_reset, overwrite=True)[swap]
    return x, clone, P, S


# ---------------------------------------------------------------------------------------
# The building blocks (validated)
# ---------------------------------------------------------------------------------------

def relative_motion(p0, R0, p1, R1) -> tuple[np.ndarray, np.ndarray]:
    """The relative pose ΔT = T0⁻¹ T1 of two poses.

    Parameters
    ----------
    p0, p1 : array_like, shape (3,)
        Positions, navigation frame, m.
    R0, R1 : array_like, shape (3, 3)
        Attitudes R_nb.

    Returns
    -------
    dp : numpy.ndarray, shape (3,)
        Δp = R0ᵀ (p1 − p0): where pose 1 is, seen from pose 0's body frame, m.
    dR : numpy.ndarray, shape (3, 3)
        ΔR = R0ᵀ R1.
    """
    return _relative_motion(as_vector(p0, "p0", 3), as_rotation(R0, "R0"), as_vector(p1, "p1", 3),
                            as_rotation(R1, "R1"))


def relative_pose_residual(p_clone, R_clone, p_check, R_check, dp_meas, dR_meas) -> np.ndarray:
    """y = [Δp̌ − Δp_m; Log(ΔR_mᵀ ΔŘ)] (6,): predicted minus measured increment (m, rad).

    Δp̌ = Ř_cᵀ (p̌ − p̌_c) and ΔŘ = Ř_cᵀ Ř from the clone (p_clone (3,), R_clone (3, 3))
    and the current nominal pose (p_check, R_check); ``dp_meas`` (3,) and ``dR_meas``
    (3, 3) are the measured increment (:func:`relative_motion` of two VO poses).
    """
    return _relative_residual(as_vector(p_clone, "p_clone", 3), as_rotation(R_clone, "R_clone"),
                              as_vector(p_check, "p_check", 3), as_rotation(R_check, "R_check"),
                              as_vector(dp_meas, "dp_meas", 3), as_rotation(dR_meas, "dR_meas"))[0]


def relative_pose_jacobian(R_clone, dp_check, dR_check) -> np.ndarray:
    """G_rel (6, 21) = ∂y/∂[δp, δv, δθ, δb_a, δb_ω, δp_c, δθ_c] of the relative residual.

    Parameters
    ----------
    R_clone : array_like, shape (3, 3)
        Ř_c, the clone's nominal attitude.
    dp_check : array_like, shape (3,)
        Δp̌ = Ř_cᵀ (p̌ − p̌_c), m.
    dR_check : array_like, shape (3, 3)
        ΔŘ = Ř_cᵀ Ř.
    """
    return _relative_jacobian(as_rotation(R_clone, "R_clone"), as_vector(dp_check, "dp_check", 3),
                              as_rotation(dR_check, "dR_check"))


def clone_covariance(P) -> np.ndarray:
    """The augmented covariance (21, 21) after cloning the pose of a 15-state P (15, 15)."""
    return _clone(as_covariance(P, "P", 15, psd=True))


def yaw_nullspace(position, velocity, R, gravity=(0.0, 0.0, -9.8092)) -> np.ndarray:
    """The unobservable heading direction N (15,) of the error state at one state.

    Turning the true state by a small angle φ about the gravity direction u = g/|g| changes
    the error (nominal − true) by −φ N with N = [[u]× p; [u]× v; Rᵀ u; 0; 0]; no increment,
    and no IMU reading, can see it.

    Parameters
    ----------
    position, velocity : array_like, shape (3,)
        p (m) and v (m/s), navigation frame.
    R : array_like, shape (3, 3)
        Attitude R_nb.
    gravity : array_like, shape (3,)
        g, m/s² (only its direction is used).
    """
    g = _as_gravity(gravity)
    return _yaw_nullspace(as_vector(position, "position", 3), as_vector(velocity, "velocity", 3),
                          as_rotation(R, "R"), g)


def pose_transition_blocks(start, end, T, gravity=(0.0, 0.0, -9.8092)):
    """The pose blocks of the transition Φ over T s along a nominal trajectory from ``start`` to ``end``.

    Parameters
    ----------
    start, end : tuple of (array_like (3,), array_like (3,), array_like (3, 3))
        (p, v, R) at the interval's two ends: position m, velocity m/s, attitude R_nb.
    T : float
        Length of the interval, s.
    gravity : array_like, shape (3,)
        g in the navigation frame, m/s².

    Returns
    -------
    Phi_p_theta, Phi_v_theta, Phi_theta_theta : numpy.ndarray, shape (3, 3) each
        −[p_b − p_a − v_a T − ½ g T²]× R_a, −[v_b − v_a − g T]× R_a and R_bᵀ R_a: ∂δp_b/∂δθ_a,
        ∂δv_b/∂δθ_a and ∂δθ_b/∂δθ_a of the continuous error dynamics (noise and biases
        aside). With them Φ maps :func:`yaw_nullspace` at ``start`` onto the one at ``end``.
    """
    def pose(value, name):
        if not isinstance(value, (tuple, list)) or len(value) != 3:
            raise ValueError(f"{name} must be a tuple (p (3,), v (3,), R (3, 3)), got {value!r}")
        return (as_vector(value[0], f"{name} position", 3), as_vector(value[1], f"{name} velocity", 3),
                as_rotation(value[2], f"{name} rotation"))

    T = as_scalar(T, "T")
    return _pose_blocks(pose(start, "start"), pose(end, "end"), T, _as_gravity(gravity))


# ---------------------------------------------------------------------------------------
# Batch runner
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class RelativeRunResult(EskfResult):
    """Output of :func:`run_relative`: an :class:`~kalman_course.filters.eskf.EskfResult`
    with one row per VO frame or GNSS fix (``P`` is the 15 × 15 marginal of the current
    state, the clone left out).

    ``innovation`` and ``S`` hold the relative updates only (6-vectors and (6, 6), in time
    order); the absolute updates' (GNSS and any other stream) are in ``gnss_innovation``
    ((3,) or (6,)) and ``gnss_S``, with the name of each one's stream in ``sources``.
    """

    gnss_innovation: list = field(repr=False, default_factory=list)
    gnss_S: list = field(repr=False, default_factory=list)


def _as_relative_std(value) -> np.ndarray:
    std = as_vector(value, "relative_std")
    if std.shape == (2,):
        std = np.repeat(std, 3)
    if std.shape != (6,) or (std <= 0.0).any():
        raise ValueError(f"relative_std must be 2 (σ_p m, σ_θ rad) or 6 positive standard deviations "
                         f"(m ×3, rad ×3) of one VO increment, got {value!r}")
    return std


class _TruthLookup:
    """(p, v, R) of a reference trajectory at exactly its own times (for ``linearise_at``)."""

    def __init__(self, ref):
        try:
            t, p, v, R = (np.asarray(getattr(ref, f), dtype=float) for f in ("t", "position", "velocity", "rotation"))
        except AttributeError:
            raise ValueError("linearise_at must be None, 'first_estimates' or a trajectory with t, position, "
                             f"velocity and rotation (e.g. the truth), got {type(ref).__name__}") from None
        n = t.shape[0] if t.ndim == 1 else -1
        if n < 1 or p.shape != (n, 3) or v.shape != (n, 3) or R.shape != (n, 3, 3):
            raise ValueError(f"linearise_at: t (K,), position (K, 3), velocity (K, 3) and rotation (K, 3, 3) "
                             f"must agree, got {t.shape}, {p.shape}, {v.shape}, {R.shape}")
        self.t, self.p, self.v, self.R = t, p, v, R

    def __call__(self, time: float):
        k = int(np.clip(np.searchsorted(self.t, time), 0, len(self.t) - 1))
        for j in (k - 1, k):
            if 0 <= j < len(self.t) and abs(self.t[j] - time) <= 1e-6:
                return self.p[j], self.v[j], self.R[j]
        raise ValueError(f"linearise_at has no state at τ = {time:.6f} s: it must hold every VO frame's "
                         f"(and GNSS fix's) time")


def _as_linearisation(value):
    """None (the estimates), "fej" for first estimates, or a :class:`_TruthLookup`."""
    if value is None:
        return None
    if isinstance(value, str):
        if value != "first_estimates":
            raise ValueError(f"linearise_at must be None, 'first_estimates' or a trajectory, got {value!r}")
        return "fej"
    return _TruthLookup(value)


def run_relative(imu, initial, config="kitti_lidar", gravity=(0.0, 0.0, -9.8092), *, vo, relative_std,
                 gnss=None, streams=None, start: int = 0, t_end: float | None = None, P0=None,
                 use_interpolation_flags: bool = True, gap_factor: float | None = IMU_GAP_FACTOR,
                 linearise_at=None) -> RelativeRunResult:
    """Run the ESKF on an IMU record, fusing VO pose increments (and optionally GNSS fixes).

    Parameters
    ----------
    imu : object
        ``t`` (N,) s, ``specific_force`` (N, 3) m/s², ``angular_rate`` (N, 3) rad/s and
        optionally ``interpolated`` (N,) bool, as for :func:`kalman_course.filters.eskf.run`.
    initial : NominalState or NavState
        The state at ``imu.t[start]``.
    config : EskfConfig or str
        Process noise, prior, reset and the GNSS σ (its lidar entries are not used).
    gravity : array_like, shape (3,)
        g in the navigation frame, m/s².
    vo : PoseObservations
        The VO poses (``t`` (K,), ``position`` (K, 3), ``rotation`` (K, 3, 3)) in any frame
        that differs from the navigation frame by a fixed transform: only the increments
        T_{k−1}⁻¹ T_k between consecutive frames used are fused. The first frame after
        ``imu.t[start]`` only starts the chain (its pose is cloned).
    relative_std : array_like, shape (2,) or (6,)
        Standard deviations of one increment's noise: (σ_p m, σ_θ rad), or per axis of
        [Δp (m) ×3, δθ (rad) ×3], body frame of the earlier pose.
    gnss : PositionObservations, optional
        Position fixes, navigation frame (e.g. ``ex.gnss.observations()``), with
        ``config.gnss_std``.
    streams : list of ObservationStream, optional
        Further absolute sensors (positions or poses in the navigation frame, each with its
        own noise and extrinsics), as in :func:`kalman_course.filters.eskf.run`. At equal
        times GNSS is used first, then the streams in order, and the VO frame last.
    start : int
        Index of the first IMU sample.
    t_end : float, optional
        Stop at this time (default: the last IMU sample).
    P0 : array_like, shape (15, 15), optional
        Initial covariance (default: the configuration's prior).
    use_interpolation_flags : bool
        Use ``config.interpolated_density`` on IMU steps touching an interpolated sample.
    gap_factor : float or None
        IMU steps longer than this many median steps are gaps (inflated noise, warning), as
        in :func:`kalman_course.filters.eskf.run`.
    linearise_at : None, "first_estimates" or trajectory
        Where Φ's pose blocks and G_rel are evaluated once a clone exists (module
        docstring): None (default) at the current estimates; "first_estimates" (FEJ) at
        each state's first estimate; a trajectory (``t`` (K,), ``position`` (K, 3),
        ``velocity`` (K, 3), ``rotation`` (K, 3, 3), e.g. the truth, holding every VO
        frame's and GNSS fix's time) at its states: the ideal-EKF diagnostic.

    Returns
    -------
    RelativeRunResult
        One row per VO frame and GNSS fix inside (imu.t[start], t_end], after its update.

    Raises
    ------
    ValueError
        Naming the argument, as :func:`kalman_course.filters.eskf.run`, and for a bad
        ``relative_std``.
    """
    cfg = _as_config(config)
    x = _as_nominal(initial, "initial")
    g = _as_gravity(gravity)
    t_imu, f_imu, w_imu, flag_imu = _imu_samples(imu, start, t_end)
    _gravity_against_imu(g, x.rotation, f_imu)
    vo = _as_observations(vo, "vo", PoseObservations)
    if vo is None:
        raise ValueError("vo must be a PoseObservations (the VO poses), got None")
    absolute = _as_streams(None, gnss, streams, cfg)
    R_rel = np.diag(_as_relative_std(relative_std) ** 2)
    P = initial_covariance(cfg) if P0 is None else np.array(as_covariance(P0, "P0", 15, psd=True))
    if gap_factor is not None:
        gap_factor = as_scalar(gap_factor, "gap_factor")
    step_flag = _imu_gaps(np.diff(t_imu), gap_factor)
    if as_flag(use_interpolation_flags, "use_interpolation_flags"):
        step_flag |= flag_imu[:-1] | flag_imu[1:]

    # events: the absolute streams (kinds 0 … n−1) before VO (kind n) at equal times, so the clone is taken last
    n_absolute = len(absolute)
    ev_t, ev_kind, ev_idx = _sorted_events([s.t for s in absolute] + [vo.t], t_imu[0], t_imu[-1])
    t_nodes, f_nodes, w_mean, flags, ev_node = _timeline(t_imu, f_imu, w_imu, step_flag, ev_t)
    dt = np.diff(t_nodes)
    q = _process_noise(np.where(flags[:, None], cfg.interpolated_density, cfg.process_density), dt,
                       cfg.bias_model)

    exact = cfg.exact_reset
    lin = _as_linearisation(linearise_at)
    lin_node = (x.position, x.velocity, x.rotation)   # first estimate at the current node (before its updates)
    clone_lin = None                                   # where G_rel takes the clone's pose
    zero15 = np.zeros((15, 15))
    clone, vo_prev = None, None          # cloned nominal pose and the VO pose at the same frame
    rows, innovations, S_rel, gnss_innovations, S_gnss, absolute_sources = [], [], [], [], [], []
    node = 0
    for e, target in enumerate(ev_node.tolist()):
        if target > node:                 # propagate: the 15-state as the ESKF, the cross-covariance by Φ
            sl = slice(node, target)
            if lin is None or clone is None:
                x, P15, Phi, _, _ = _propagate(x, P[:15, :15], f_nodes[node:target + 1], w_mean[sl], dt[sl],
                                               q[sl], g, cfg.bias_model)
            else:                         # Φ's pose blocks from the chosen linearisation points
                P_old = P[:15, :15]
                x, noise, Phi, _, _ = _propagate(x, zero15, f_nodes[node:target + 1], w_mean[sl], dt[sl],
                                                 q[sl], g, cfg.bias_model)
                if lin == "fej":
                    a, b = lin_node, (x.position, x.velocity, x.rotation)
                else:
                    a, b = lin(t_nodes[node]), lin(t_nodes[target])
                Phi = _with_pose_blocks(Phi, a, b, t_nodes[target] - t_nodes[node], g)
                P15 = symmetrise(dot(dot(Phi, P_old), Phi.T) + noise)
            lin_node = (x.position, x.velocity, x.rotation)
            if clone is None:
                P = P15
            else:
                P = P.copy()
                P[:15, :15] = P15
                P[:15, 15:] = dot(Phi, P[:15, 15:])
                P[15:, :15] = P[:15, 15:].T
            node = target
        kind, k = int(ev_kind[e]), int(ev_idx[e])
        updated = False
        if kind < n_absolute:             # an absolute fix (GNSS or another stream)
            stream = absolute[kind]
            y = stream.residual(k, x.position, x.rotation)
            G = _stream_jacobian(stream, x.rotation)
            if clone is None:
                x, P, _, S = _correct(x, P, y, G, stream.R, exact)
            else:
                G = np.hstack([G, np.zeros((stream.m, 6))])
                x, clone, P, S = _correct_augmented(x, clone, P, y, G, stream.R, exact)
            gnss_innovations.append(y)
            S_gnss.append(S)
            absolute_sources.append(stream.name)
            updated = True
        else:                             # VO frame: relative update, then a new clone
            p_vo, R_vo = vo.position[k], vo.rotation[k]
            if clone is not None:
                dp_m, dR_m = _relative_motion(*vo_prev, p_vo, R_vo)
                y, dp_check, dR_check = _relative_residual(*clone, x.position, x.rotation, dp_m, dR_m)
                if lin is None:
                    G = _relative_jacobian(clone[1], dp_check, dR_check)
                else:
                    p_l, _, R_l = lin_node if lin == "fej" else lin(t_nodes[target])
                    dp_l, dR_l = _relative_motion(*clone_lin, p_l, R_l)
                    G = _relative_jacobian(clone_lin[1], dp_l, dR_l)
                x, clone, P, S = _correct_augmented(x, clone, P, y, G, R_rel, exact)
                innovations.append(y)
                S_rel.append(S)
                updated = True
            clone, vo_prev = (x.position, x.rotation), (p_vo, R_vo)
            if lin is not None:
                p_l, _, R_l = lin_node if lin == "fej" else lin(t_nodes[target])
                clone_lin = (p_l, R_l)
            P = _clone(P[:15, :15])
        if rows and rows[-1][0] == target:            # a second event at the same node
            updated = updated or rows.pop()[3]
        rows.append((target, x, P[:15, :15].copy(), updated))

    states = [row[1] for row in rows]

    def stacked(name, shape):
        return np.array([getattr(s, name) for s in states]).reshape(-1, *shape)

    return RelativeRunResult(t_nodes[[row[0] for row in rows]], stacked("position", (3,)),
                             stacked("velocity", (3,)), stacked("rotation", (3, 3)), stacked("accel_bias", (3,)),
                             stacked("gyro_bias", (3,)), np.array([row[2] for row in rows]).reshape(-1, 15, 15),
                             np.array([row[3] for row in rows], dtype=bool), innovations, S_rel,
                             sources=absolute_sources, gnss_innovation=gnss_innovations, gnss_S=S_gnss)
