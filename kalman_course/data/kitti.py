"""KITTI sequence 00 excerpts: typed records, validated loaders and noise generators.

The shipped files live in ``kalman_course/data/kitti/`` and are rebuilt from PyPI packages
by ``python -m kalman_course.data.build`` (see that module and ``ATTRIBUTION.md``).
Every stream is on one clock and in one frame:

- time ``tau``: seconds since KITTI odometry frame 0 of sequence 00;
- navigation frame n: the local metric frame of the OXTS GNSS/INS solution, z up, with
  gravity ``g_n = (0, 0, −9.8092)`` m/s²;
- body frame b: the OXTS IMU (x forward, y left, z up). Poses are IMU poses: ``position``
  is the IMU origin in n (m), ``rotation`` is R_nb, ``quaternion`` the same attitude as
  (w, x, y, z), Hamilton, w ≥ 0.

The lidar map-matching poses are **simulated**: ground truth plus seeded noise
(``simulate_lidar_poses``); KITTI has no such stream. The shipped excerpts hold white
noise (σ 0.2 m, 0.3°); ``simulate_lidar_poses(..., errors=...)`` draws other, equally
simulated errors from :mod:`kalman_course.data.observation_errors` (Gauss–Markov errors
correlated in time, map-matching jumps and outliers), and the record says which
(``LidarData.error_model``, ``LidarData.failures``). The noisy GNSS copy is simulated as
well (``simulate_gnss``). Data: KITTI (Geiger et al., IJRR 2013), CC BY-NC-SA 3.0.

What a filter may see: ``ex.lidar`` is a :class:`~kalman_course.core.observations.PoseObservations`
(the reported poses, noise included) and ``ex.gnss.observations()`` returns a
:class:`~kalman_course.core.observations.PositionObservations` of the noisy fixes. The
recorded GNSS/INS solution is ``ex.gnss.position_true``: as accurate as the ground truth, so
it is for checking, never a filter input.
"""

from __future__ import annotations

import functools
import hashlib
import json
import os
import zipfile
import zlib
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kalman_course.core import so3
from kalman_course.core.imu import NavState, NavTrajectory
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.core.validation import as_path, as_rotations, as_rows, as_scalar, as_seed, require_file
from kalman_course.data.observation_errors import ObservationErrors, WhiteErrors

__all__ = [
    "EXCERPTS", "SCHEMA_VERSION", "ImuData", "GnssData", "TruthData", "LidarData", "SlamData",
    "FrameInfo", "KittiExcerpt", "kitti_dir", "read_manifest", "load_kitti", "load_excerpt_file",
    "simulate_lidar_poses", "simulate_gnss", "file_sha256",
]

#: Names accepted by :func:`load_kitti`: three excerpts and the whole sequence 00.
EXCERPTS = ("cruise", "turns", "stop_go", "seq00")

#: Version of the file layout below; bumped whenever a field is added, removed or changed.
SCHEMA_VERSION = 1

#: Median time steps a valid excerpt's clocks may have, s (100 Hz IMU, 1 Hz GNSS, 10 Hz poses).
_TIME_STEP_RANGE = {"imu/t": (1e-3, 0.1), "gnss/t": (0.1, 10.0), "truth/t": (0.01, 1.0)}

# field name -> (dtype kind, shape with symbolic sizes: N IMU samples, M GNSS fixes,
# K ground-truth poses)
_SCHEMA: dict[str, tuple[str, tuple]] = {
    "meta": ("U", ()),
    "gravity": ("f", (3,)),
    "imu/t": ("f", ("N",)),
    "imu/specific_force": ("f", ("N", 3)),
    "imu/angular_rate": ("f", ("N", 3)),
    "imu/interpolated": ("b", ("N",)),
    "gnss/t": ("f", ("M",)),
    "gnss/position": ("f", ("M", 3)),
    "gnss/position_noisy": ("f", ("M", 3)),
    "truth/t": ("f", ("K",)),
    "truth/position": ("f", ("K", 3)),
    "truth/velocity": ("f", ("K", 3)),
    "truth/quaternion": ("f", ("K", 4)),
    "lidar/position": ("f", ("K", 3)),
    "lidar/quaternion": ("f", ("K", 4)),
    "orb_slam2/position": ("f", ("K", 3)),
    "orb_slam2/quaternion": ("f", ("K", 4)),
    "sptam/position": ("f", ("K", 3)),
    "sptam/quaternion": ("f", ("K", 4)),
    "frames/R_cam_imu": ("f", (3, 3)),
    "frames/t_cam_imu": ("f", (3,)),
    "frames/R_nav_world": ("f", (3, 3)),
    "frames/t_nav_world": ("f", (3,)),
    "frames/scale": ("f", ()),
}

_META_KEYS = ("name", "schema_version", "tau_range", "lidar", "gnss", "provenance")


def _frozen(arr: np.ndarray) -> np.ndarray:
    """Return ``arr`` marked read-only (records are shared, e.g. by the load cache)."""
    arr.setflags(write=False)
    return arr


# ---------------------------------------------------------------------------------------
# Records
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ImuData:
    """IMU samples (OXTS RT3003 as provided by GTSAM), about 100 Hz.

    Attributes
    ----------
    t : numpy.ndarray, shape (N,)
        Sample times tau, s. Irregular: dt ranges from 2.6 ms to 20 ms; use each
        sample's own dt.
    specific_force : numpy.ndarray, shape (N, 3)
        Accelerometer reading f = R_nbᵀ (a_n − g_n) in the body frame, m/s².
    angular_rate : numpy.ndarray, shape (N, 3)
        Gyroscope reading ω in the body frame, rad/s.
    interpolated : numpy.ndarray of bool, shape (N,)
        True for samples that are linear interpolations filling a dropout of the
        original recording (8 spans, 1,257 samples in all of sequence 00). Their gyro
        disagrees with the truth by up to 0.36 rad/s; trust them less.
    """

    t: np.ndarray
    specific_force: np.ndarray
    angular_rate: np.ndarray
    interpolated: np.ndarray

    @property
    def dt(self) -> np.ndarray:
        """Intervals t[k+1] − t[k], s, shape (N−1,)."""
        return np.diff(self.t)

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True)
class GnssData:
    """GNSS positions at 1 Hz.

    A filter takes :meth:`observations`, the noisy fixes; ``position_true`` is the
    noise-free recorded solution and is there for checking only. (There is deliberately
    no ``position`` attribute: code written for an observation record fails loudly on a
    ``GnssData`` instead of reading the noise-free values.)

    Attributes
    ----------
    t : numpy.ndarray, shape (M,)
        Fix times tau, s.
    position_true : numpy.ndarray, shape (M, 3)
        The OXTS GNSS/INS position as recorded, navigation frame, m. It is an INS solution,
        as accurate as the ground truth (millimetres), not raw GNSS: noise-free for the
        purposes of the course. Stored in the excerpt files as ``gnss/position``.
    position_noisy : numpy.ndarray, shape (M, 3)
        ``position_true`` plus simulated white noise N(0, sigma² I): what a GNSS receiver
        would report, m.
    sigma : float
        Standard deviation of the simulated noise per axis, m.
    seed : int
        Seed of ``numpy.random.default_rng`` that drew the noise.
    simulated_noise : bool
        Always True: the noise of ``position_noisy`` is simulated.
    """

    t: np.ndarray
    position_true: np.ndarray
    position_noisy: np.ndarray
    sigma: float
    seed: int
    simulated_noise: bool = True

    def __len__(self) -> int:
        return len(self.t)

    def observations(self) -> PositionObservations:
        """The fixes as a filter receives them: times and the noisy positions.

        Returns
        -------
        PositionObservations
            ``t`` (M,) s and ``position`` (M, 3) m equal to :attr:`position_noisy`. Use
            ``.select(mask)`` on it to drop fixes, e.g. for a simulated outage.
        """
        return PositionObservations(self.t, self.position_noisy)


@dataclass(frozen=True)
class TruthData:
    """Ground-truth IMU poses at about 10 Hz (the KITTI odometry ground truth).

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Camera frame times tau, s.
    position : numpy.ndarray, shape (K, 3)
        IMU origin in the navigation frame, m.
    velocity : numpy.ndarray, shape (K, 3)
        Velocity in the navigation frame, m/s, from a local cubic least-squares fit over 9
        poses (±0.4 s); its noise is a few cm/s, so grade consistency on the pose.
    quaternion : numpy.ndarray, shape (K, 4)
        Attitude R_nb as a unit quaternion (w, x, y, z), w ≥ 0.
    rotation : numpy.ndarray, shape (K, 3, 3)
        Attitude R_nb (body → navigation), computed from ``quaternion``.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    quaternion: np.ndarray
    rotation: np.ndarray

    def __len__(self) -> int:
        return len(self.t)

    def interpolate(self, t) -> NavTrajectory:
        """Truth at arbitrary times inside [t[0], t[-1]].

        Position: cubic Hermite through the positions and velocities of the two
        neighbouring poses; velocity: linear; attitude: geodesic (slerp).

        Parameters
        ----------
        t : array_like, shape (n,)
            Query times tau, s.

        Returns
        -------
        NavTrajectory
            Position (n, 3) m, velocity (n, 3) m/s, rotation (n, 3, 3) at ``t``.
        """
        tq = np.atleast_1d(np.asarray(t, dtype=float))
        if tq.ndim != 1 or not np.all(np.isfinite(tq)):
            raise ValueError(f"t must be a finite scalar or 1-D array of times, got shape {tq.shape}")
        lo, hi = float(self.t[0]), float(self.t[-1])
        if tq.size and (tq.min() < lo or tq.max() > hi):
            raise ValueError(f"t must lie inside the truth's time span [{lo:.4f}, {hi:.4f}] s, "
                             f"got values in [{tq.min():.4f}, {tq.max():.4f}]")
        k = np.clip(np.searchsorted(self.t, tq, side="right") - 1, 0, len(self.t) - 2)
        h = self.t[k + 1] - self.t[k]
        s = ((tq - self.t[k]) / h)[:, None]
        p0, p1 = self.position[k], self.position[k + 1]
        v0, v1 = self.velocity[k], self.velocity[k + 1]
        hh = h[:, None]
        pos = ((2 * s**3 - 3 * s**2 + 1) * p0 + (s**3 - 2 * s**2 + s) * hh * v0
               + (-2 * s**3 + 3 * s**2) * p1 + (s**3 - s**2) * hh * v1)
        vel = (1 - s) * v0 + s * v1
        rot = so3.interpolate(self.rotation[k], self.rotation[k + 1], s[:, 0])
        return NavTrajectory(tq, pos, vel, rot)

    def state_at(self, t: float) -> NavState:
        """The interpolated truth (see :meth:`interpolate`) at one time ``t``, s."""
        traj = self.interpolate(np.array([float(t)]))
        return traj.state(0)


@dataclass(frozen=True, eq=False, repr=False)
class LidarData(PoseObservations):
    """Simulated lidar map-matching pose observations at the ground-truth times (~10 Hz).

    Made from the truth as ``p_obs = p + δp`` and ``R_obs = R Exp(δθ)`` (the attitude
    error on the right, in the body frame), with the errors [δp, δθ] drawn from
    ``default_rng(seed)`` by an error model of
    :mod:`kalman_course.data.observation_errors` (see :func:`simulate_lidar_poses`). The
    shipped excerpts use white errors, δp = σ_p n_p and δθ = σ_θ n_θ with n_p, n_θ ~
    N(0, I₃) drawn in that order. KITTI has no such stream: every error here is simulated.

    It is a :class:`~kalman_course.core.observations.PoseObservations` (validated on
    construction, read-only arrays), so it goes to a filter as it is.

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Observation times tau, s (equal to the truth's).
    position : numpy.ndarray, shape (K, 3)
        Observed IMU position, navigation frame, m.
    rotation : numpy.ndarray, shape (K, 3, 3)
        Observed attitude R_nb.
    quaternion : numpy.ndarray, shape (K, 4)
        The same attitude as (w, x, y, z), w ≥ 0.
    sigma_position : float
        σ_p, position noise per axis, m (for map-matching failures: of the base model).
    sigma_attitude_deg : float
        σ_θ, attitude noise per axis of the rotation vector, degrees (likewise).
    seed : int
        The generator's seed.
    simulated : bool
        Always True.
    error_model : str
        The error model's ``describe()``: "white" (the shipped excerpts), e.g.
        "Gauss–Markov, τ = 1 s", or a base model plus jumps and outliers.
    failures : numpy.ndarray of bool, shape (K,), or None
        For map-matching failures, True at the observations a jump or an outlier touched
        (read-only); None for models without failures.
    """

    quaternion: np.ndarray
    sigma_position: float
    sigma_attitude_deg: float
    seed: int
    simulated: bool = True
    error_model: str = "white"
    failures: np.ndarray | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        q = np.array(self.quaternion, dtype=np.float64)
        if q.shape != (len(self), 4) or not np.isfinite(q).all():
            raise ValueError(f"quaternion must be a finite array of shape ({len(self)}, 4), "
                             f"got shape {q.shape}")
        q.setflags(write=False)
        object.__setattr__(self, "quaternion", q)
        if not isinstance(self.error_model, str) or not self.error_model:
            raise ValueError(f"error_model must be a non-empty string, got {self.error_model!r}")
        if self.failures is not None:
            mask = np.array(self.failures)
            if mask.dtype != bool or mask.shape != (len(self),):
                raise ValueError(f"failures must be None or a boolean array of shape ({len(self)},), "
                                 f"got dtype {mask.dtype} and shape {mask.shape}")
            mask.setflags(write=False)
            object.__setattr__(self, "failures", mask)

    @property
    def sigma_attitude(self) -> float:
        """σ_θ in radians."""
        return float(np.deg2rad(self.sigma_attitude_deg))


@dataclass(frozen=True)
class SlamData:
    """A real visual-SLAM estimate (from the evo test data), as IMU poses in the nav frame.

    The camera poses were mapped exactly like the ground truth, so the estimate starts at
    the true pose of frame 0 and then drifts.

    Attributes
    ----------
    name : str
        "ORB-SLAM2" or "S-PTAM".
    t : numpy.ndarray, shape (K,)
        Times tau, s (equal to the truth's).
    position : numpy.ndarray, shape (K, 3)
        Estimated IMU position, navigation frame, m.
    quaternion : numpy.ndarray, shape (K, 4)
        Estimated attitude R_nb as (w, x, y, z), w ≥ 0.
    rotation : numpy.ndarray, shape (K, 3, 3)
        Estimated attitude R_nb.
    """

    name: str
    t: np.ndarray
    position: np.ndarray
    quaternion: np.ndarray
    rotation: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True)
class FrameInfo:
    """The calibration and frame constants used to build the excerpt.

    Attributes
    ----------
    R_cam_imu : numpy.ndarray, shape (3, 3)
        Rotation of T_cam_imu (IMU → rectified cam0), orthonormalised.
    t_cam_imu : numpy.ndarray, shape (3,)
        Translation of T_cam_imu, m: the IMU origin in cam0 coordinates.
    R_nav_world : numpy.ndarray, shape (3, 3)
        Rotation from the KITTI ground-truth world frame (cam0 at frame 0) to the nav frame.
    t_nav_world : numpy.ndarray, shape (3,)
        Translation of that map, m.
    scale : float
        Scale s of that map: p_n = s R_nav_world p_w + t_nav_world (s = 0.998106, measured).
    """

    R_cam_imu: np.ndarray
    t_cam_imu: np.ndarray
    R_nav_world: np.ndarray
    t_nav_world: np.ndarray
    scale: float

    def cam0_position(self, position, rotation) -> np.ndarray:
        """Position of the cam0 origin, nav frame (m), from IMU poses (K, 3) and (K, 3, 3)."""
        offset = -self.R_cam_imu.T @ self.t_cam_imu          # cam0 origin in IMU coordinates
        return (np.asarray(position, dtype=float)
                + self.scale * np.einsum("...ij,j->...i", np.asarray(rotation, dtype=float), offset))


@dataclass(frozen=True)
class KittiExcerpt:
    """One excerpt of KITTI sequence 00 (or the whole sequence), ready for filtering.

    Attributes
    ----------
    name : str
        One of :data:`EXCERPTS`.
    tau_range : tuple of float
        (start, end) in s; every stream lies inside it.
    gravity : numpy.ndarray, shape (3,)
        g_n, gravity in the navigation frame, m/s².
    imu : ImuData
    gnss : GnssData
    truth : TruthData
    lidar : LidarData
        Simulated pose observations (``lidar.simulated`` is True).
    orb_slam2, sptam : SlamData
        Real visual-SLAM estimates in the same frame.
    frames : FrameInfo
    provenance : dict
        For each stream: PyPI package, version, file inside it, its sha256, and how it was
        transformed; plus the licence and citation.
    path : str
        The file it was loaded from.
    """

    name: str
    tau_range: tuple[float, float]
    gravity: np.ndarray
    imu: ImuData
    gnss: GnssData
    truth: TruthData
    lidar: LidarData
    orb_slam2: SlamData
    sptam: SlamData
    frames: FrameInfo
    provenance: dict = field(repr=False)
    path: str = ""

    @property
    def duration(self) -> float:
        """tau_range[1] − tau_range[0], s."""
        return float(self.tau_range[1] - self.tau_range[0])

    def initial_state(self) -> tuple[int, NavState]:
        """Index of the first IMU sample at or after the first truth pose, and the truth there.

        Returns
        -------
        k0 : int
            Index into ``imu`` where a filter or dead reckoning can start.
        state : NavState
            The interpolated true state at ``imu.t[k0]``.
        """
        k0 = int(np.searchsorted(self.imu.t, self.truth.t[0], side="left"))
        return k0, self.truth.state_at(self.imu.t[k0])


# ---------------------------------------------------------------------------------------
# Noise generators
# ---------------------------------------------------------------------------------------

def _rotations_of(record, name: str, K: int) -> np.ndarray:
    """The K attitudes of ``record`` (its ``rotation`` or, failing that, its ``quaternion``), checked."""
    if hasattr(record, "rotation"):
        return as_rotations(record.rotation, f"{name}.rotation", K)
    if hasattr(record, "quaternion"):
        q = as_rows(record.quaternion, f"{name}.quaternion", (4,), K)
        norm = np.linalg.norm(q, axis=1)
        if K and np.abs(norm - 1.0).max() > 1e-6:
            k = int(np.argmax(np.abs(norm - 1.0)))
            raise ValueError(f"{name}.quaternion[{k}] must be a unit quaternion (w, x, y, z), got |q| = {norm[k]:.6g}")
        return so3.quat_to_matrix(q)
    raise ValueError(f"{name} must have a rotation (K, 3, 3) or quaternion (K, 4) attribute")


def simulate_lidar_poses(truth, seed: int, sigma_position: float = 0.2,
                         sigma_attitude_deg: float = 0.3, *, errors: ObservationErrors | None = None
                         ) -> LidarData:
    """Simulate lidar map-matching pose observations from true poses.

    ``p_obs = p + δp`` and ``R_obs = R Exp(δθ)`` (the attitude error on the right, in the
    body frame), with the errors [δp, δθ] (K, 6) drawn by ``errors.draw(t,
    numpy.random.default_rng(seed))``. The default is white noise, δp = σ_p n_p and
    δθ = σ_θ n_θ with n_p then n_θ, each (K, 3) standard normal: the shipped excerpts hold
    that draw for their stored seed, so ``simulate_lidar_poses(ex.truth, ex.lidar.seed)``
    reproduces ``ex.lidar``.

    Parameters
    ----------
    truth : object
        Anything with ``t`` (K,) s, ``position`` (K, 3) m and ``rotation`` (K, 3, 3) or
        ``quaternion`` (K, 4) (for example ``load_kitti("turns").truth``).
    seed : int
        Seed for ``numpy.random.default_rng``.
    sigma_position : float
        σ_p per axis, m, of the white noise used when ``errors`` is None.
    sigma_attitude_deg : float
        σ_θ per axis of the attitude noise rotation vector, degrees, likewise.
    errors : ObservationErrors, keyword-only, optional
        The error model: :class:`~kalman_course.data.observation_errors.WhiteErrors`,
        :class:`~kalman_course.data.observation_errors.GaussMarkovErrors` or
        :class:`~kalman_course.data.observation_errors.MapMatchingFailures`. None means
        ``WhiteErrors(sigma_position, sigma_attitude_deg)``. When given, it sets the noise
        size: leave ``sigma_position`` and ``sigma_attitude_deg`` at their defaults or
        equal to the model's.

    Returns
    -------
    LidarData
        With ``error_model`` = ``errors.describe()`` and, for map-matching failures,
        ``failures``, the (K,) mask of the observations a jump or outlier touched.

    Raises
    ------
    ValueError
        For a bad seed, σ or truth record, an ``errors`` that is no error model, or σ's
        that contradict the model's.
    """
    seed = as_seed(seed)
    sp = as_scalar(sigma_position, "sigma_position", allow_zero=True)
    sa = as_scalar(sigma_attitude_deg, "sigma_attitude_deg", allow_zero=True)
    errors = _lidar_error_model(errors, sp, sa)
    for attr in ("t", "position"):
        if not hasattr(truth, attr):
            raise ValueError(f"truth must have t (K,) and position (K, 3); missing {attr!r}")
    t = _increasing_times(truth.t, "truth.t")
    K = len(t)
    p = as_rows(truth.position, "truth.position", (3,), K)
    R = _rotations_of(truth, "truth", K)
    draw = errors.draw(t, np.random.default_rng(seed))
    position = p + draw.position
    rotation = R @ so3.exp(draw.attitude)
    quaternion = so3.matrix_to_quat(rotation)
    return LidarData(t, position, so3.quat_to_matrix(quaternion), quaternion, errors.sigma_position,
                     errors.sigma_attitude_deg, seed, error_model=errors.describe(), failures=draw.failures)


def _increasing_times(value, name: str) -> np.ndarray:
    """``value`` as finite, strictly increasing times (K,), else a ValueError naming ``name``."""
    t = as_rows(value, name, count="K")
    step = np.diff(t)
    if (step <= 0.0).any():
        k = int(np.argmax(step <= 0.0)) + 1
        raise ValueError(f"{name} must be strictly increasing: {name}[{k}] = {t[k]:g} <= {name}[{k - 1}] = {t[k - 1]:g}")
    return t


def _lidar_error_model(errors, sigma_position: float, sigma_attitude_deg: float) -> ObservationErrors:
    """The model :func:`simulate_lidar_poses` draws from, checked against its σ arguments."""
    if errors is None:
        return WhiteErrors(sigma_position, sigma_attitude_deg)
    if not isinstance(errors, ObservationErrors):
        raise ValueError(f"errors must be None or an error model of kalman_course.data.observation_errors "
                         f"(WhiteErrors, GaussMarkovErrors, MapMatchingFailures), got {type(errors).__name__}")
    given = (sigma_position, sigma_attitude_deg)
    # the σ arguments are either untouched (the signature's defaults) or agree with the model
    if given not in (simulate_lidar_poses.__defaults__, (errors.sigma_position, errors.sigma_attitude_deg)):
        raise ValueError(f"sigma_position = {sigma_position:g} m and sigma_attitude_deg = {sigma_attitude_deg:g}° "
                         f"contradict errors ({errors.describe()}, σ {errors.sigma_position:g} m, "
                         f"{errors.sigma_attitude_deg:g}°); with errors given, set σ in the model only")
    return errors


def simulate_gnss(gnss, seed: int, sigma: float = 1.0) -> GnssData:
    """Add seeded white noise N(0, σ² I₃) to noise-free GNSS positions.

    Parameters
    ----------
    gnss : object
        Anything with ``t`` (M,) s and the noise-free positions (M, 3) m as
        ``position_true`` (a :class:`GnssData`, for example ``load_kitti("turns").gnss``)
        or, failing that, as ``position``.
    seed : int
        Seed for ``numpy.random.default_rng``; the noise is one (M, 3) standard normal draw.
    sigma : float
        σ per axis, m.

    Returns
    -------
    GnssData
        A copy with ``position_noisy``, ``sigma`` and ``seed`` set.
    """
    seed = as_seed(seed)
    sigma = as_scalar(sigma, "sigma", allow_zero=True)
    noise_free = "position_true" if hasattr(gnss, "position_true") else "position"
    for attr in ("t", noise_free):
        if not hasattr(gnss, attr):
            raise ValueError(f"gnss must have t (M,) and {noise_free} (M, 3); missing {attr!r}")
    t = as_rows(gnss.t, "gnss.t", count="M")
    p = as_rows(getattr(gnss, noise_free), f"gnss.{noise_free}", (3,), len(t), count="M")
    rng = np.random.default_rng(seed)
    noisy = p + sigma * rng.standard_normal(p.shape)
    return GnssData(t.copy(), p.copy(), noisy, sigma, seed)


# ---------------------------------------------------------------------------------------
# Files
# ---------------------------------------------------------------------------------------

def kitti_dir() -> Path:
    """The folder holding the shipped excerpts and ``MANIFEST.json``."""
    return Path(__file__).resolve().parent / "kitti"


def file_sha256(path) -> str:
    """Hex sha256 of the bytes of the file at ``path``.

    Raises
    ------
    FileNotFoundError
        If there is no file at ``path``.
    ValueError
        If ``path`` is not a path, or names a directory.
    """
    path = require_file(as_path(path, "path"), "a file to checksum")
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        for chunk in iter(lambda: fh.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def read_manifest(path=None) -> dict:
    """Read and check a ``MANIFEST.json`` (default: the shipped one).

    Returns
    -------
    dict
        ``{"schema_version": int, "files": {file name: {"sha256", "size", "schema_version",
        ...}}}``.
    """
    path = as_path(path, "path") if path is not None else kitti_dir() / "MANIFEST.json"
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not a manifest (MANIFEST.json)")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: manifest not found (rebuild the data with "
                                f"`python -m kalman_course.data.build`)")
    try:
        manifest = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ValueError(f"{path}: manifest is not valid JSON ({exc})") from None
    _check_manifest(manifest, str(path))
    return manifest


def _check_manifest(manifest, where: str) -> None:
    """Raise a ValueError naming ``where`` unless ``manifest`` has the layout :func:`read_manifest` returns."""
    files = manifest.get("files") if isinstance(manifest, dict) else None
    if not isinstance(files, dict):
        raise ValueError(f"{where}: manifest must hold an object 'files' mapping file names to entries")
    for fname, entry in files.items():
        if not isinstance(entry, dict) or not {"sha256", "size", "schema_version"} <= set(entry):
            raise ValueError(f"{where}: manifest entry {fname!r} must have sha256, size and schema_version")
        sha, size, version = entry["sha256"], entry["size"], entry["schema_version"]
        if not isinstance(sha, str) or len(sha) != 64:
            raise ValueError(f"{where}: manifest entry {fname!r}: sha256 must be 64 hex digits, got {sha!r}")
        for key, value in (("size", size), ("schema_version", version)):
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ValueError(f"{where}: manifest entry {fname!r}: {key} must be a non-negative integer, "
                                 f"got {value!r}")


def _verify_against_manifest(path: Path, manifest) -> None:
    if isinstance(manifest, dict):
        _check_manifest(manifest, "manifest")
    elif isinstance(manifest, (str, os.PathLike)):
        manifest = read_manifest(manifest)
    else:
        raise ValueError(f"manifest must be None, a parsed manifest (dict) or the path of a MANIFEST.json, "
                         f"got {type(manifest).__name__}")
    entry = manifest["files"].get(path.name)
    if entry is None:
        raise ValueError(f"{path}: not listed in the manifest (listed: {', '.join(sorted(manifest['files']))})")
    size = path.stat().st_size
    if size < entry["size"]:
        raise ValueError(f"{path}: file is truncated or modified ({size} bytes, the manifest says "
                         f"{entry['size']}); reinstall the package or rebuild the data")
    if size != entry["size"]:
        raise ValueError(f"{path}: file size {size} bytes differs from the manifest's {entry['size']}")
    digest = file_sha256(path)
    if digest != entry["sha256"]:
        raise ValueError(f"{path}: checksum mismatch (sha256 {digest}, the manifest says {entry['sha256']}); "
                         f"the file is corrupt or was modified")
    if entry["schema_version"] != SCHEMA_VERSION:
        raise ValueError(f"{path}: the manifest lists schema version {entry['schema_version']}, "
                         f"this loader reads version {SCHEMA_VERSION}")


def _read_arrays(path: Path) -> dict[str, np.ndarray]:
    try:
        loaded = np.load(path, allow_pickle=False)
        if not isinstance(loaded, np.lib.npyio.NpzFile):      # a single .npy array
            raise ValueError(f"it holds one array of shape {np.shape(loaded)}, not an archive of fields")
        with loaded as npz:
            return {key: npz[key] for key in npz.files}
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, ValueError, KeyError) as exc:
        raise ValueError(f"{path}: file is truncated or corrupt, not a readable .npz archive "
                         f"({type(exc).__name__}: {exc})") from None


def _check_schema(path: Path, arrays: dict[str, np.ndarray]) -> dict:
    missing = [key for key in _SCHEMA if key not in arrays]
    if missing:
        raise ValueError(f"{path}: missing field {missing[0]!r}"
                         + (f" (and {len(missing) - 1} more)" if len(missing) > 1 else ""))
    if arrays["meta"].dtype.kind != "U" or arrays["meta"].shape != ():
        raise ValueError(f"{path}: field 'meta' must be one JSON text, got dtype {arrays['meta'].dtype} and "
                         f"shape {arrays['meta'].shape}")
    try:
        meta = json.loads(str(arrays["meta"]))
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: field 'meta' is not valid JSON ({exc})") from None
    if not isinstance(meta, dict) or any(k not in meta for k in _META_KEYS):
        raise ValueError(f"{path}: field 'meta' must be an object with keys {', '.join(_META_KEYS)}")
    _check_meta_types(path, meta)
    if meta["schema_version"] != SCHEMA_VERSION:
        raise ValueError(f"{path}: schema version {meta['schema_version']}, this loader reads version "
                         f"{SCHEMA_VERSION}")
    sizes: dict[str, tuple[int, str]] = {}
    for key, (kind, shape) in _SCHEMA.items():
        arr = arrays[key]
        if arr.dtype.kind != kind:
            raise ValueError(f"{path}: field {key!r} has dtype {arr.dtype}, expected kind {kind!r}")
        expected = tuple(sizes[s][0] if isinstance(s, str) and s in sizes else s for s in shape)
        shown = "(" + ", ".join(str(s) for s in shape) + ("," if len(shape) == 1 else "") + ")"
        ok = arr.ndim == len(shape) and all(isinstance(e, str) or e == a for e, a in zip(expected, arr.shape))
        if not ok:
            hint = ""
            for s, a in zip(shape, arr.shape):
                if isinstance(s, str) and s in sizes and sizes[s][0] != a:
                    hint = f"; {s} = {sizes[s][0]} from {sizes[s][1]!r}"
            raise ValueError(f"{path}: field {key!r} has shape {arr.shape}, expected {shown}{hint}")
        for s, a in zip(shape, arr.shape):
            if isinstance(s, str) and s not in sizes:
                sizes[s] = (a, key)
        if kind == "f" and not np.all(np.isfinite(arr)):
            raise ValueError(f"{path}: field {key!r} contains NaN or inf")
    for key in ("imu/t", "gnss/t", "truth/t"):
        if len(arrays[key]) < 2 or np.any(np.diff(arrays[key]) <= 0.0):
            raise ValueError(f"{path}: field {key!r} must hold at least 2 strictly increasing times")
        # times in seconds: the IMU's 100 Hz, the GNSS's 1 Hz and the 10 Hz poses, within a factor of 10
        step = float(np.median(np.diff(arrays[key])))
        low, high = _TIME_STEP_RANGE[key]
        if not low <= step <= high:
            raise ValueError(f"{path}: field {key!r} has a median step of {step:g}, expected {low:g}–{high:g} s "
                             "(times in milliseconds or microseconds?)")
    for section, keys in (("gnss", ("sigma",)), ("lidar", ("sigma_position", "sigma_attitude_deg"))):
        for key in keys:
            value = meta.get(section, {}).get(key) if isinstance(meta.get(section), dict) else None
            if not isinstance(value, (int, float)) or isinstance(value, bool) or not np.isfinite(value) or value < 0:
                raise ValueError(f"{path}: metadata {section}.{key} must be a number ≥ 0, got {value!r}")
    for key in ("truth/quaternion", "lidar/quaternion", "orb_slam2/quaternion", "sptam/quaternion"):
        err = np.abs(np.linalg.norm(arrays[key], axis=1) - 1.0).max()
        if err > 1e-9:
            raise ValueError(f"{path}: field {key!r} must hold unit quaternions (max | |q| − 1 | = {err:.3g})")
    for key in ("frames/R_cam_imu", "frames/R_nav_world"):
        try:
            as_rotations(arrays[key][None], key)
        except ValueError as exc:
            raise ValueError(f"{path}: field {exc}") from None
    return meta


def _check_meta_types(path: Path, meta: dict) -> None:
    """The metadata fields the loader reads, each of the type it reads (a ValueError naming file and field)."""
    def bad(field: str, expected: str, value):
        raise ValueError(f"{path}: metadata {field} must be {expected}, got {value!r:.60}")

    if not isinstance(meta["name"], str):
        bad("name", "a string", meta["name"])
    version = meta["schema_version"]
    if isinstance(version, bool) or not isinstance(version, int):
        bad("schema_version", "an integer", version)
    tau = meta["tau_range"]
    if (not isinstance(tau, list) or len(tau) != 2 or any(isinstance(v, bool) or not isinstance(v, (int, float))
                                                          or not np.isfinite(v) for v in tau)):
        bad("tau_range", "a list of two finite numbers (start, end) in s", tau)
    if not isinstance(meta["provenance"], dict):
        bad("provenance", "an object", meta["provenance"])
    for section in ("gnss", "lidar"):
        if not isinstance(meta[section], dict):
            bad(section, "an object", meta[section])
        seed = meta[section].get("seed")
        if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
            bad(f"{section}.seed", "a non-negative integer", seed)


def load_excerpt_file(path, manifest=None) -> KittiExcerpt:
    """Load and validate one excerpt file.

    Parameters
    ----------
    path : str or Path
        An excerpt ``.npz`` written by ``kalman_course.data.build``.
    manifest : dict, str, Path or None
        A manifest (parsed, or the path of a ``MANIFEST.json``) to check the file's size
        and sha256 against; None skips the checksum (the schema is always checked).

    Returns
    -------
    KittiExcerpt

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        If the file is truncated, corrupt, fails its checksum, or lacks a field or has one
        of the wrong shape; the message names the file and the problem.
    """
    path = as_path(path, "path")
    if path.is_dir():
        raise ValueError(f"{path} is a directory, not a KITTI excerpt file (.npz)")
    if not path.is_file():
        raise FileNotFoundError(f"{path}: KITTI excerpt file not found (rebuild the data with "
                                f"`python -m kalman_course.data.build`)")
    if manifest is not None:
        _verify_against_manifest(path, manifest)
    arrays = _read_arrays(path)
    meta = _check_schema(path, arrays)
    a = {key: _frozen(np.asarray(value, dtype=float if value.dtype.kind == "f" else None, order="C"))
         for key, value in arrays.items()}

    def rotations(key: str) -> np.ndarray:
        return _frozen(so3.quat_to_matrix(a[key]))

    imu = ImuData(a["imu/t"], a["imu/specific_force"], a["imu/angular_rate"], a["imu/interpolated"])
    gnss = GnssData(a["gnss/t"], position_true=a["gnss/position"], position_noisy=a["gnss/position_noisy"],
                    sigma=float(meta["gnss"]["sigma"]), seed=int(meta["gnss"]["seed"]))
    truth = TruthData(a["truth/t"], a["truth/position"], a["truth/velocity"], a["truth/quaternion"],
                      rotations("truth/quaternion"))
    lidar = LidarData(a["truth/t"], a["lidar/position"], rotations("lidar/quaternion"), a["lidar/quaternion"],
                      float(meta["lidar"]["sigma_position"]), float(meta["lidar"]["sigma_attitude_deg"]),
                      int(meta["lidar"]["seed"]))
    orb = SlamData("ORB-SLAM2", a["truth/t"], a["orb_slam2/position"], a["orb_slam2/quaternion"],
                   rotations("orb_slam2/quaternion"))
    sptam = SlamData("S-PTAM", a["truth/t"], a["sptam/position"], a["sptam/quaternion"],
                     rotations("sptam/quaternion"))
    frames = FrameInfo(a["frames/R_cam_imu"], a["frames/t_cam_imu"], a["frames/R_nav_world"],
                       a["frames/t_nav_world"], float(a["frames/scale"]))
    tau_range = (float(meta["tau_range"][0]), float(meta["tau_range"][1]))
    return KittiExcerpt(meta["name"], tau_range, a["gravity"], imu, gnss, truth, lidar, orb, sptam,
                        frames, meta["provenance"], str(path))


@functools.lru_cache(maxsize=8)
def _load_cached(path: str, stamp: tuple, manifest_path: str, manifest_stamp: tuple) -> KittiExcerpt:
    # the stamps (size, mtime) only make the cache notice a changed file
    return load_excerpt_file(path, manifest=manifest_path)


def _stamp(path: Path) -> tuple:
    try:
        st = path.stat()
    except OSError:
        return ()
    return (st.st_size, st.st_mtime_ns)


def load_kitti(name: str) -> KittiExcerpt:
    """Load a shipped KITTI excerpt by name, verifying its checksum and schema.

    Parameters
    ----------
    name : str
        "cruise" (tau 421.5–452.0 s: steady speed, one gentle curve), "turns"
        (310–370 s: 534° of heading change), "stop_go" (40–100 s: a short stop and turns)
        or "seq00" (the whole sequence, 0–470.6 s).

    Returns
    -------
    KittiExcerpt
        Arrays are read-only; repeated loads of an unchanged file return the same object.
    """
    if not isinstance(name, str) or name not in EXCERPTS:
        raise ValueError(f"unknown KITTI excerpt {name!r}; valid names: {', '.join(EXCERPTS)} "
                         f"(name must be one of them; load_excerpt_file reads a file by its path)")
    folder = kitti_dir()
    path = folder / f"{name}.npz"
    if not path.is_file():
        raise FileNotFoundError(f"{path}: KITTI excerpt file not found (rebuild the data with "
                                f"`python -m kalman_course.data.build`)")
    manifest = folder / "MANIFEST.json"
    return _load_cached(str(path), _stamp(path), str(manifest), _stamp(manifest))
