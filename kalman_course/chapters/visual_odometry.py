"""Real visual odometry fused with the IMU (chapter 10, "Real sensors"): loosely coupled VIO.

The observation stream here is real: the ORB-SLAM2 and S-PTAM trajectories of KITTI
sequence 00 (:class:`~kalman_course.data.kitti.SlamData`), stereo visual SLAM run on the
camera images, as IMU poses in the navigation frame on the KITTI clock. The IMU (100 Hz)
is real too; the ground truth serves only to start the runs and to score them. The one
simulated input is the GNSS noise: the 1 Hz fixes are the recorded OXTS positions plus
seeded white noise, σ 1 m per axis (``ex.gnss.observations()``), and the filter is told
that σ.

Five estimates of the same drive, each scored the same way:

1. **VO alone**: the SLAM track as it is, anchored to the truth by one pose only;
2. **VO + IMU, absolute**: the ESKF of chapter 08 (:func:`kalman_course.filters.eskf.run`)
   with every VO pose as an absolute pose observation, as if it were a map-matching pose;
3. **VO + IMU, relative**: the ESKF fed the VO's frame-to-frame increments
   T_{k−1}⁻¹ T_k by stochastic cloning (:func:`kalman_course.filters.eskf_relative.run_relative`),
   so that the VO's accumulated drift never enters as an absolute error;
4. **VO + IMU + GNSS**: (3) plus the GNSS fixes as the absolute anchor;
5. **IMU + GNSS** (a reference): the chapter-08 GNSS filter without VO, to show what VO adds.

Where everything starts (the only use of the truth besides scoring)
-------------------------------------------------------------------
The IMU record begins at τ = 1.41 s, after frame 13, so every estimate is anchored at the
first camera frame after it (frame ``first``, τ ≈ 1.45 s): the VO track is moved rigidly so
that its pose there is the true one (:func:`anchor`; the shipped tracks are anchored at
frame 0, and the VO's first frames are ~20 % short, so this also spares it ~1.2 m of error
that is not the fusion's business), and the filters start from the true state (position,
velocity, attitude) at the last IMU sample before that frame, with zero biases and the
configuration's prior. No estimate is aligned to the truth over the whole track.

How the observation noise R is chosen (no truth)
------------------------------------------------
By the innovations, the way lecture 09 checks a filter: on a calibration stretch (the first
:data:`CALIBRATION_S` s of the run) the VO observation's standard deviations are scaled
until the median NIS of each block of the innovations equals the χ² median for that block
(:func:`tune_std`): for absolute poses one σ for position and one for attitude (3-dof
blocks, :data:`ABSOLUTE_BLOCKS`); for increments one σ per component (:data:`RELATIVE_BLOCKS`),
since a VO measures forward motion and yaw differently from the rest. Medians, because the
interpolated IMU spans and VO glitches produce a few huge values. The innovations can only
see what the IMU can check over one frame: the VO's jitter, not its slow drift, so a
consistent NIS does not make a consistent NEES (row 2 shows it). The process noise, the
prior and the GNSS σ are the configuration ``kitti_gnss`` of chapter 08 as it is (its IMU
densities were tuned there against the truth, on simulated lidar poses).

What the measurements show (sequence 00; see :func:`table`)
-----------------------------------------------------------
Absolute VO poses with an innovation-tuned R of millimetres make the filter a copy of the
VO, drift included, and its NEES is ~10⁶. Relative increments keep the VO's drift out of
the covariance's blind spot, but without an absolute reference the heading is not
observable and the gyro bias cannot be told apart from the VO's own rotational drift: the
filter learns part of the VO's early drift as a bias and on this drive ends up worse than
the VO alone (far worse for S-PTAM, whose noisier increments get a looser R, so that the
heading leans on the gyro). With the GNSS fixes as the anchor both systems end below the VO
alone in ATE and in drift; their NEES stays well above 6 (the VO's errors are not white).

Why the increments filter is overconfident: controlled experiments
------------------------------------------------------------------
One change at a time (:func:`linearisation_runs`, :func:`clock_offset_runs`,
:func:`frame_lag`, :func:`vo_tilt`, :func:`vio_variants`; seeds 1–5 where noise is drawn):

- the real VO increments replaced by white ones of exactly the filter's σ, real IMU: still
  overconfident when the Jacobians are taken at the current estimates, consistent when they
  are taken at the first estimates (FEJ) or at the truth (the ideal EKF); the heading error
  of the default filter arises almost entirely in the second after each of the IMU's eight
  dropouts, where the corrections are large (:func:`yaw_change_at_dropouts`);
- the real IMU replaced by one simulated from the smoothed truth with the filter's own noise
  and bias model (:func:`simulated_imu`): consistent with every linearisation, so it is the
  combination, real IMU errors (its dropouts) and relinearisation, that breaks the default;
- the clocks: the real IMU fits the truth best at zero offset; the frames: the gyro (no
  truth) finds the S-PTAM rows one camera frame late and both VO tracks' axes tilted by about
  0.3° in pitch against the IMU's, which makes VO + IMU climb or sink with the distance
  driven. Realigned (:func:`realigned`), VO + IMU with FEJ and a gyro-bias prior of
  5e-5 rad/s is below VO alone in ATE and both drift rates for both systems.

Scores
------
ATE: RMS position error over the evaluated frames with no alignment (``ape_position`` of
:func:`kalman_course.evaluation.pose.evaluate`); the RMS attitude error likewise; KITTI's
drift metric (:func:`kalman_course.evaluation.drift.drift`: translational error in % and
rotational error in °/100 m over 100–800 m segments, on IMU poses); the mean 6-dof pose
NEES where a filter reports a covariance (6 for a consistent filter).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from kalman_course.core.observations import PoseObservations
from kalman_course.core import so3
from kalman_course.core.imu import NavState, dead_reckon
from kalman_course.core.validation import (as_covariance, as_real_array, as_rotation, as_rotations, as_rows,
                                           as_scalar, as_seed, as_vector)
from kalman_course.data.kitti import load_kitti
from kalman_course.data.mems_imu import reference_imu
from kalman_course.evaluation.drift import DriftResult, drift
from kalman_course.evaluation.metrics import chi2_ppf, nis
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.trajectory import ate_rmse
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.eskf_relative import run_relative

__all__ = [
    "VO_SYSTEMS", "METHODS", "CALIBRATION_S", "VoSetup", "setup", "anchor",
    "ABSOLUTE_BLOCKS", "RELATIVE_BLOCKS",
    "run_absolute", "run_relative_vo", "run_imu_gnss", "block_nis", "TunedStd", "tune_std",
    "Score", "score", "VoRow", "VoComparison", "compare", "table",
    "white_increment_track", "white_increment_runs",
    "LINEARISATIONS", "IMU_KINDS", "white_increments", "SimulatedImu", "simulated_imu", "yaw_error", "yaw_variance",
    "ConsistencyScore", "consistency_score", "run_increments", "LinearisationRun", "linearisation_runs",
    "yaw_change_at_dropouts", "ClockOffsetRun", "clock_offset_runs", "rotation_increments", "gyro_increments",
    "frame_lag", "tilt_misalignment", "vo_tilt", "realigned", "tuned_relative_std", "VioVariant", "VIO_VARIANTS",
    "VioRow", "vio_variants", "linearisation_table", "vio_table",
]

#: The real visual-SLAM trajectories in the data, by name.
VO_SYSTEMS = ("ORB-SLAM2", "S-PTAM")

#: The estimates compared, in table order: key -> label.
METHODS = {
    "vo": "VO alone",
    "absolute": "VO + IMU (absolute poses)",
    "relative": "VO + IMU (relative increments)",
    "relative_gnss": "VO + IMU + GNSS",
    "imu_gnss": "IMU + GNSS (no VO, reference)",
}

#: Length of the calibration stretch on which R is tuned by the NIS, s.
CALIBRATION_S = 60.0

#: How the absolute pose noise is tuned: one σ for the position block and one for the
#: attitude block of the 6-dof innovation (the ESKF configuration has one number for each).
ABSOLUTE_BLOCKS = (slice(0, 3), slice(3, 6))

#: How the relative noise is tuned: one σ per component of the increment's innovation
#: (along, across, vertical; roll, pitch, yaw of the earlier body frame), since a VO measures
#: forward motion and yaw differently from the rest.
RELATIVE_BLOCKS = tuple(slice(i, i + 1) for i in range(6))

_CONFIG = "kitti_gnss"
# where the tuning starts: 1 cm and 0.01° (the rough size of one frame's VO jitter)
_ABSOLUTE_STD0 = (0.01, 1.7e-4)
_RELATIVE_STD0 = (0.01,) * 3 + (1.7e-4,) * 3


# ---------------------------------------------------------------------------------------
# Setup: the common start of every estimate
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class VoSetup:
    """Everything the runs of one VO system share.

    Attributes
    ----------
    excerpt : KittiExcerpt
        The KITTI data.
    system : str
        "ORB-SLAM2" or "S-PTAM".
    first, last : int
        The first and last truth frame evaluated (``first`` is the anchor frame).
    start : int
        Index of the IMU sample the filters start at (the last one before frame ``first``).
    initial : eskf.NominalState
        The true state at ``imu.t[start]`` (interpolated truth), biases zero.
    vo : PoseObservations
        The VO poses of frames ``first`` … ``last``, anchored at frame ``first`` (:func:`anchor`).
    t_end : float
        Time of frame ``last``, s.
    t_stop : float
        Time of the first IMU sample at or after it, s: the filters integrate up to there.
    """

    excerpt: object
    system: str
    first: int
    last: int
    start: int
    initial: eskf.NominalState
    vo: PoseObservations
    t_end: float
    t_stop: float

    @property
    def frames(self) -> np.ndarray:
        """Truth frame indices evaluated, ``first`` … ``last``, shape (K,)."""
        return np.arange(self.first, self.last + 1)

    @property
    def t(self) -> np.ndarray:
        """Their times, s, shape (K,)."""
        return self.excerpt.truth.t[self.first:self.last + 1]


def _slam(excerpt, system: str):
    if system not in VO_SYSTEMS:
        raise ValueError(f"system must be one of {', '.join(VO_SYSTEMS)}, got {system!r}")
    return excerpt.orb_slam2 if system == "ORB-SLAM2" else excerpt.sptam


def anchor(position, rotation, true_position, true_rotation, frame: int):
    """Move a track rigidly so that its pose at ``frame`` is the true one: T' = T_true,a T_a⁻¹ T.

    Parameters
    ----------
    position : array_like, shape (K, 3)
        Track positions, m.
    rotation : array_like, shape (K, 3, 3)
        Track attitudes R_nb.
    true_position : array_like, shape (3,)
        True position at ``frame``, m.
    true_rotation : array_like, shape (3, 3)
        True attitude at ``frame``.
    frame : int
        The anchor frame, an index into the track.

    Returns
    -------
    position : numpy.ndarray, shape (K, 3)
    rotation : numpy.ndarray, shape (K, 3, 3)
    """
    p = as_rows(position, "position", (3,), count="K")
    R = as_rotations(rotation, "rotation", len(p))
    if isinstance(frame, (bool, np.bool_)) or not isinstance(frame, (int, np.integer)) or not 0 <= frame < len(p):
        raise ValueError(f"frame must be an index into the track (0 … {len(p) - 1}), got {frame!r}")
    p_true = as_vector(true_position, "true_position", 3)
    C = as_rotation(true_rotation, "true_rotation") @ R[frame].T          # the correcting rotation
    return p_true + (p - p[frame]) @ C.T, C @ R


def _finite(value, name: str) -> np.ndarray:
    """``value`` as a float array of real, finite numbers; anything else is a ValueError naming ``name``."""
    arr = as_real_array(value, name)
    if not np.isfinite(arr).all():
        raise ValueError(f"{name} must be finite, got NaN or inf")
    return arr


def setup(excerpt="seq00", system: str = "ORB-SLAM2", t_end: float | None = None) -> VoSetup:
    """The common start of the runs: anchor frame, IMU start index, initial state, anchored VO.

    Parameters
    ----------
    excerpt : str or KittiExcerpt
        The data (a name for :func:`~kalman_course.data.kitti.load_kitti`, default the whole
        sequence 00).
    system : str
        "ORB-SLAM2" or "S-PTAM".
    t_end : float, optional
        Evaluate up to this time, s (default: the last frame the IMU covers).

    Returns
    -------
    VoSetup
    """
    ex = load_kitti(excerpt) if isinstance(excerpt, str) else excerpt
    slam = _slam(ex, system)
    truth, imu = ex.truth, ex.imu
    first = int(np.searchsorted(truth.t, imu.t[0], side="right"))     # first frame after the IMU starts
    end = imu.t[-1] if t_end is None else min(as_scalar(t_end, "t_end"), imu.t[-1])
    last = int(np.searchsorted(truth.t, end, side="right")) - 1
    if last <= first + 1:
        raise ValueError(f"t_end = {end:.3f} s leaves no frames to evaluate after frame {first} "
                         f"(τ = {truth.t[first]:.3f} s)")
    start = int(np.searchsorted(imu.t, truth.t[first], side="left")) - 1
    initial = eskf.NominalState.from_nav(truth.state_at(imu.t[start]))
    p, R = anchor(slam.position, slam.rotation, truth.position[first], truth.rotation[first], first)
    sel = slice(first, last + 1)
    t_stop = imu.t[np.searchsorted(imu.t, truth.t[last], side="left")]
    return VoSetup(ex, system, first, last, start, initial, PoseObservations(slam.t[sel], p[sel], R[sel]),
                   float(truth.t[last]), float(t_stop))


# ---------------------------------------------------------------------------------------
# The runs
# ---------------------------------------------------------------------------------------

def _stds(std, name: str, sizes=(2,)) -> tuple:
    """``std`` as a tuple of positive floats of one of the lengths ``sizes``."""
    s = as_vector(std, name)
    if s.shape[0] not in sizes or (s <= 0.0).any():
        raise ValueError(f"{name} must be {' or '.join(map(str, sizes))} positive standard deviations "
                         f"(m for position, rad for attitude), got {std!r}")
    return tuple(float(v) for v in s)


def run_absolute(s: VoSetup, std, t_end: float | None = None) -> eskf.EskfResult:
    """VO + IMU with every VO pose as an absolute pose observation (the chapter-08 ESKF).

    Parameters
    ----------
    s : VoSetup
    std : array_like, shape (2,)
        (σ_p m, σ_θ rad) per axis of the VO pose noise (the ESKF's lidar R).
    t_end : float, optional
        Stop earlier than ``s.t_stop``, s.

    Returns
    -------
    eskf.EskfResult
        One row per VO frame after ``imu.t[s.start]``.
    """
    sp, st = _stds(std, "std")
    cfg = load_config(_CONFIG).replace(observation__lidar_position=sp, observation__lidar_attitude=st)
    ex = s.excerpt
    return eskf.run(ex.imu, s.initial, cfg, ex.gravity, lidar=s.vo, start=s.start,
                    t_end=s.t_stop if t_end is None else t_end)


def run_relative_vo(s: VoSetup, std, gnss: bool = False, t_end: float | None = None):
    """VO + IMU with the VO's frame-to-frame increments (stochastic cloning), optionally + GNSS.

    Parameters
    ----------
    s : VoSetup
    std : array_like, shape (2,) or (6,)
        Standard deviations of one increment's noise: (σ_p m, σ_θ rad) for every axis, or
        one per component [Δp (m) ×3, δθ (rad) ×3] in the earlier frame's body axes.
    gnss : bool
        Also fuse the 1 Hz GNSS fixes (real OXTS positions plus simulated noise, σ 1 m).
    t_end : float, optional
        Stop earlier than ``s.t_stop``, s.

    Returns
    -------
    eskf_relative.RelativeRunResult
    """
    return run_increments(s, std, gnss=gnss, t_end=t_end)


def run_imu_gnss(s: VoSetup) -> eskf.EskfResult:
    """The reference without VO: the chapter-08 ESKF with the GNSS fixes, states at the VO frames."""
    ex = s.excerpt
    return eskf.run(ex.imu, s.initial, _CONFIG, ex.gravity, gnss=ex.gnss.observations(), start=s.start,
                    t_end=s.t_stop, output_times=s.t, clip_output_times=True)


# ---------------------------------------------------------------------------------------
# Choosing R from the innovations
# ---------------------------------------------------------------------------------------

def block_nis(innovation, S, block: slice) -> np.ndarray:
    """NIS of one block of the innovations: ν_bᵀ S_bb⁻¹ ν_b for each row.

    Parameters
    ----------
    innovation : array_like, shape (N, m)
    S : array_like, shape (N, m, m)
    block : slice
        The components, e.g. ``slice(0, 3)`` for the position part of a pose innovation.

    Returns
    -------
    numpy.ndarray, shape (N,)
        χ² with (block length) degrees of freedom for a consistent filter.
    """
    y = _finite(innovation, "innovation")
    S = _finite(S, "S")
    if y.ndim != 2 or S.shape != (y.shape[0], y.shape[1], y.shape[1]):
        raise ValueError(f"innovation must be (N, m) and S (N, m, m), got {y.shape} and {S.shape}")
    if not isinstance(block, slice):
        raise ValueError(f"block must be a slice of the innovation's components, got {type(block).__name__}")
    return nis(y[:, block], S[:, block, block])


@dataclass(frozen=True)
class TunedStd:
    """Result of :func:`tune_std`.

    Attributes
    ----------
    std : tuple of float
        One σ per block (m for position components, rad for attitude ones).
    median_nis : tuple of float
        Median NIS of each block with it.
    target : tuple of float
        The χ² median each block aims at (χ²(1): 0.455, χ²(3): 2.37).
    history : list of tuple
        (σ per block, median NIS per block) of every run, in order.
    converged : bool
        Every median within the relative tolerance of its target.
    """

    std: tuple
    median_nis: tuple
    target: tuple
    history: list = field(repr=False)
    converged: bool


def tune_std(run, std0, blocks, *, iterations: int = 10, tol: float = 0.1, bounds=(1e-6, 10.0)) -> TunedStd:
    """Scale the observation σ of each block until its median NIS is the χ² median.

    Uses no truth: only the filter's own innovations. Each step runs the filter, computes
    the median NIS of every block of the innovations (χ² with the block's length as
    degrees of freedom if the filter is consistent) and multiplies that block's σ by
    √(median / target), clipped to [½, 2] per step and to ``bounds`` overall. Since
    S = G P Gᵀ + R reacts less than R does, the step under-corrects and does not
    overshoot. It stops when every median is within ``tol`` of its target. Medians,
    because the interpolated IMU spans and VO glitches make a few NIS values huge.

    Parameters
    ----------
    run : callable
        ``run(std)`` → a result whose ``innovation`` (list of (m,)) and ``S`` (list of
        (m, m)) are those of the VO updates, e.g. ``lambda std: run_relative_vo(s, std,
        t_end=60)``; ``std`` is a tuple with one σ per block.
    std0 : array_like, shape (B,)
        Starting σ of each block.
    blocks : sequence of slice, length B
        The blocks of the innovation, e.g. :data:`ABSOLUTE_BLOCKS` or :data:`RELATIVE_BLOCKS`.
    iterations : int
        Most runs.
    tol : float
        Relative tolerance on the medians.
    bounds : (float, float)
        Limits of every σ.

    Returns
    -------
    TunedStd
        The last σ run (so that ``median_nis`` belongs to ``std``).
    """
    blocks = tuple(blocks)
    if not blocks or not all(isinstance(b, slice) for b in blocks):
        raise ValueError(f"blocks must be a non-empty sequence of slices, got {blocks!r}")
    std = np.array(_stds(std0, "std0", (len(blocks),)))
    if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
        raise ValueError(f"iterations must be a positive integer, got {iterations!r}")
    tol = as_scalar(tol, "tol")
    lo, hi = (as_scalar(v, "bounds") for v in bounds)
    history = []
    for _ in range(iterations):
        res = run(tuple(float(v) for v in std))
        y, S = np.array(res.innovation), np.array(res.S)
        if y.ndim != 2 or len(y) == 0:
            raise ValueError("run(std) must return a result with at least one innovation")
        # the χ² median of each block, with the block's length as the degrees of freedom
        target = np.array([chi2_ppf(0.5, len(range(*b.indices(y.shape[1])))) for b in blocks])
        med = np.array([np.median(block_nis(y, S, b)) for b in blocks])
        history.append((tuple(float(v) for v in std), tuple(float(v) for v in med)))
        if np.all(np.abs(med / target - 1.0) <= tol):
            break
        std = np.clip(std * np.clip(np.sqrt(med / target), 0.5, 2.0), lo, hi)
    last_std, last_med = history[-1]
    converged = bool(np.all(np.abs(np.array(last_med) / target - 1.0) <= tol))
    return TunedStd(last_std, last_med, tuple(float(v) for v in target), history, converged)


# ---------------------------------------------------------------------------------------
# Scores and the comparison
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class Score:
    """How one estimate did on the evaluated frames.

    Attributes
    ----------
    ate : float
        RMS position error, no alignment (beyond the one anchor pose), m.
    attitude_deg : float
        RMS attitude error, degrees.
    drift : DriftResult
        KITTI's drift metric (translational %, rotational °/100 m).
    nees : float
        Mean 6-dof pose NEES (NaN without a covariance).
    position_error : numpy.ndarray, shape (K, 3)
        Estimate − truth, m.
    """

    ate: float
    attitude_deg: float
    drift: DriftResult
    nees: float
    position_error: np.ndarray = field(repr=False)


def score(s: VoSetup, t, position, rotation, P=None) -> Score:
    """Score an estimate given at exactly the evaluated frames ``s.t``.

    Parameters
    ----------
    s : VoSetup
    t : array_like, shape (K,)
        Times, s; must equal ``s.t``.
    position : array_like, shape (K, 3)
    rotation : array_like, shape (K, 3, 3)
    P : array_like, shape (K, 15, 15), optional
        The filter's covariance, for the pose NEES.
    """
    t = as_vector(t, "t")
    if t.shape != s.t.shape or np.abs(t - s.t).max() > 1e-6:
        raise ValueError(f"the estimate must be given at the {len(s.t)} evaluated frames "
                         f"(τ {s.t[0]:.3f} … {s.t[-1]:.3f} s), got {len(t)} times")
    truth = s.excerpt.truth
    ev = evaluate(t, position, rotation, truth, P=P)
    k = s.frames
    d = drift(position, rotation, truth.position[k], truth.rotation[k])
    return Score(ev["ape_position"], ev["ape_attitude_deg"], d, ev["nees_pose"], ev["position_error"])


@dataclass(frozen=True, eq=False)
class VoRow:
    """One line of the comparison.

    Attributes
    ----------
    system : str
        The VO system ("ORB-SLAM2", "S-PTAM") or "—" for the reference without VO.
    method : str
        A key of :data:`METHODS`.
    score : Score
    std : tuple of float or None
        (σ_p m, σ_θ rad) of the VO observation, for the fused runs.
    tuned : TunedStd or None
        How ``std`` was chosen (None if given).
    runtime_s : float
        Wall time of the run (tuning not included), s.
    t, position, rotation : numpy.ndarray
        The estimate at the evaluated frames: (K,), (K, 3), (K, 3, 3).
    """

    system: str
    method: str
    score: Score
    std: tuple | None
    tuned: TunedStd | None
    runtime_s: float
    t: np.ndarray = field(repr=False)
    position: np.ndarray = field(repr=False)
    rotation: np.ndarray = field(repr=False)

    @property
    def label(self) -> str:
        """The estimate's name in tables and legends (:data:`METHODS`)."""
        return METHODS[self.method]


@dataclass(frozen=True, eq=False)
class VoComparison:
    """Output of :func:`compare`.

    Attributes
    ----------
    rows : list of VoRow
        In the order of the systems, then :data:`METHODS` (the reference last).
    truth_position : numpy.ndarray, shape (K, 3)
        The true positions at the evaluated frames, m.
    t : numpy.ndarray, shape (K,)
        Their times, s.
    calibration_s : float
        Length of the stretch R was tuned on, s.
    tuning_s : float
        Wall time spent choosing R, s.
    """

    rows: list
    truth_position: np.ndarray = field(repr=False)
    t: np.ndarray = field(repr=False)
    calibration_s: float = CALIBRATION_S
    tuning_s: float = 0.0

    def row(self, system: str, method: str) -> VoRow:
        """The row of ``method`` for ``system`` (``system`` ignored for "imu_gnss")."""
        for r in self.rows:
            if r.method == method and (method == "imu_gnss" or r.system == system):
                return r
        raise ValueError(f"no row {method!r} for {system!r}; rows: "
                         f"{', '.join(f'{r.system}/{r.method}' for r in self.rows)}")

    def tracks(self, system: str, methods=("vo", "relative", "relative_gnss")) -> dict:
        """{label: positions (K, 3)} for :func:`kalman_course.plotting.visual_odometry.plot_vo_tracks`."""
        return {self.row(system, m).label: self.row(system, m).position for m in methods}

    def drift_curves(self, system: str, methods=("vo", "absolute", "relative", "relative_gnss")) -> dict:
        """{label: (lengths (L,), translational % (L,), rotational °/100 m (L,))} per segment length."""
        out = {}
        for m in methods:
            d = self.row(system, m).score.drift
            out[self.row(system, m).label] = (d.lengths, d.translation_percent_by_length,
                                              d.rotation_deg_per_100m_by_length)
        return out


def _timed(fn):
    t0 = time.perf_counter()
    out = fn()
    return out, time.perf_counter() - t0


def _row(s, method, result, std=None, tuned=None, seconds=0.0, system=None) -> VoRow:
    r = result.at(s.t)
    sc = score(s, r.t, r.position, r.rotation, r.P)
    return VoRow(s.system if system is None else system, method, sc, std, tuned, seconds, r.t, r.position,
                 r.rotation)


def compare(excerpt="seq00", systems=VO_SYSTEMS, *, t_end: float | None = None,
            calibration_s: float = CALIBRATION_S, absolute_std=None, relative_std=None,
            reference: bool = True) -> VoComparison:
    """Run and score every estimate of the module docstring for each VO system.

    Parameters
    ----------
    excerpt : str or KittiExcerpt
        Default: the whole sequence 00 (about 470 s, 3.7 km).
    systems : sequence of str
        Some of :data:`VO_SYSTEMS`.
    t_end : float, optional
        Evaluate only up to this time, s (for a quick run on a slice).
    calibration_s : float
        Length of the calibration stretch for :func:`tune_std`, s from the start.
    absolute_std : array_like, shape (2,), optional
        (σ_p m, σ_θ rad) of the absolute VO poses, instead of tuning them.
    relative_std : array_like, shape (2,) or (6,), optional
        σ of the VO increments (see :func:`run_relative_vo`), instead of tuning them.
    reference : bool
        Add the IMU + GNSS row without VO.

    Returns
    -------
    VoComparison
    """
    ex = load_kitti(excerpt) if isinstance(excerpt, str) else excerpt
    if isinstance(systems, str):
        systems = (systems,)
    calibration_s = as_scalar(calibration_s, "calibration_s")
    if not systems:
        raise ValueError("systems must name at least one of " + ", ".join(VO_SYSTEMS))
    rows, tuning = [], 0.0
    for system in systems:
        s = setup(ex, system, t_end)
        t_cal = min(s.t[0] + calibration_s, s.t_end)
        abs_tuned = rel_tuned = None
        t0 = time.perf_counter()
        if absolute_std is None:
            abs_tuned = tune_std(lambda std: run_absolute(s, std, t_end=t_cal), _ABSOLUTE_STD0, ABSOLUTE_BLOCKS)
        if relative_std is None:
            rel_tuned = tune_std(lambda std: run_relative_vo(s, std, t_end=t_cal), _RELATIVE_STD0,
                                 RELATIVE_BLOCKS)
        tuning += time.perf_counter() - t0
        a_std = abs_tuned.std if abs_tuned else _stds(absolute_std, "absolute_std")
        r_std = rel_tuned.std if rel_tuned else _stds(relative_std, "relative_std", (2, 6))

        vo = s.vo
        sc = score(s, vo.t, vo.position, vo.rotation)
        rows.append(VoRow(system, "vo", sc, None, None, 0.0, vo.t, vo.position, vo.rotation))
        res, sec = _timed(lambda: run_absolute(s, a_std))
        rows.append(_row(s, "absolute", res, a_std, abs_tuned, sec))
        res, sec = _timed(lambda: run_relative_vo(s, r_std))
        rows.append(_row(s, "relative", res, r_std, rel_tuned, sec))
        res, sec = _timed(lambda: run_relative_vo(s, r_std, gnss=True))
        rows.append(_row(s, "relative_gnss", res, r_std, rel_tuned, sec))
    if reference:
        res, sec = _timed(lambda: run_imu_gnss(s))
        rows.append(_row(s, "imu_gnss", res, seconds=sec, system="—"))
    return VoComparison(rows, ex.truth.position[s.frames], s.t, calibration_s, tuning)


_INPUTS = {
    "vo": "real VO",
    "absolute": "real VO + real IMU",
    "relative": "real VO + real IMU",
    "relative_gnss": "real VO + real IMU + GNSS (real positions, simulated noise σ 1 m)",
    "imu_gnss": "real IMU + GNSS (real positions, simulated noise σ 1 m)",
}


def _format_std(std) -> str:
    """(σ_p, σ_θ) or six σ's as "p 0.004 m, θ 0.02°" / "p 0.006/0.004/0.003 m, θ 0.02/0.01/0.01°"."""
    half = len(std) // 2
    p = "/".join(f"{v:.2g}" for v in std[:half])
    th = "/".join(f"{np.rad2deg(v):.2g}" for v in std[half:])
    return f"p {p} m, θ {th}°"


def table(comparison: VoComparison, timings: bool = False) -> str:
    """The comparison as a Markdown table, saying which inputs are real and which simulated.

    Columns: VO system, estimate, ATE (m, no alignment beyond the anchor pose), RMS attitude
    error (°), KITTI drift (translational %, rotational °/100 m, 100–800 m segments), mean
    6-dof pose NEES (6 if consistent), the R used (σ_p, σ_θ) and how it was chosen, the
    inputs, and with ``timings`` the wall-clock run and tuning times (left out by default: they
    differ from run to run, and a lecture's stored output must not).
    """
    if not isinstance(comparison, VoComparison):
        raise ValueError(f"comparison must be a VoComparison (from compare), got {type(comparison).__name__}")
    K = len(comparison.t)
    lines = [
        f"KITTI sequence 00, {K} camera frames (τ {comparison.t[0]:.1f}–{comparison.t[-1]:.1f} s). "
        "Real: the KITTI IMU, the ORB-SLAM2 / S-PTAM trajectories, the ground truth (used only to "
        "start the runs and to score them) and the OXTS positions under the GNSS fixes; "
        "simulated: the GNSS noise (σ 1 m, seeded).",
        "",
        "| VO | estimate | ATE [m] | attitude [°] | drift [%] | drift [°/100 m] | mean NEES (6) "
        "| R: σ per axis | inputs |" + (" run [s] |" if timings else ""),
        "|---|---|---|---|---|---|---|---|---|" + ("---|" if timings else ""),
    ]
    for r in comparison.rows:
        sc = r.score
        nees = "—" if not np.isfinite(sc.nees) else f"{sc.nees:.3g}"
        if r.std is None:
            noise = "—"
        else:
            how = "given" if r.tuned is None else ("NIS-tuned" if r.tuned.converged else "NIS-tuned, not converged")
            noise = f"{_format_std(r.std)} ({how})"
        runtime = ("—" if r.method == "vo" else f"{r.runtime_s:.2f}") + " |" if timings else ""
        lines.append(f"| {r.system} | {r.label} | {sc.ate:.2f} | {sc.attitude_deg:.2f} | "
                     f"{sc.drift.translation_percent:.2f} | {sc.drift.rotation_deg_per_100m:.3f} | {nees} | "
                     f"{noise} | {_INPUTS[r.method]} | {runtime}")
    lines.append("")
    lines.append(f"R tuned without the truth on the first {comparison.calibration_s:g} s: absolute poses, the median "
                 f"NIS of the position and attitude blocks at the χ²(3) median; increments, the median NIS of each "
                 f"component at the χ²(1) median" + (f" (tuning took {comparison.tuning_s:.1f} s)" if timings else "")
                 + ". Process noise, prior and "
                 f"GNSS σ: configuration {_CONFIG!r} of chapter 08.")
    return "\n".join(lines)


# ---------------------------------------------------------------------------------------
# Is it the VO's correlated errors? The same filter on white increments
# ---------------------------------------------------------------------------------------

def white_increment_track(s: VoSetup, std, seed: int) -> PoseObservations:
    """:func:`white_increments` of the setup's evaluated frames: a simulated VO track with
    exactly the noise model of :func:`run_relative_vo` and no correlation in time.

    Parameters
    ----------
    s : VoSetup
        Frames, times and the truth (the real VO track is not used).
    std : array_like, shape (2,) or (6,)
        As for :func:`run_relative_vo`.
    seed : int
        Seed of the noise.

    Returns
    -------
    PoseObservations
        At the VO frames' times: positions (K, 3) m and attitudes (K, 3, 3).
    """
    truth = s.excerpt.truth
    return white_increments(truth.position[s.frames], truth.rotation[s.frames], s.vo.t, std, seed)


def white_increment_runs(s: VoSetup, std, seeds) -> list[Score]:
    """:func:`run_relative_vo` on :func:`white_increment_track` draws: one :class:`Score` per seed.

    The only change from the real run is the VO stream: the same IMU (real), start, filter
    and increment σ, but increments whose errors are white and of exactly that σ.
    """
    seeds = [as_seed(seed) for seed in seeds]
    if not seeds:
        raise ValueError("seeds must hold at least one seed")
    scores = []
    for seed in seeds:
        track = white_increment_track(s, std, seed)
        sim = VoSetup(s.excerpt, s.system, s.first, s.last, s.start, s.initial, track, s.t_end, s.t_stop)
        res = run_relative_vo(sim, std)
        scores.append(score(sim, res.t, res.position, res.rotation, res.P))
    return scores


# ---------------------------------------------------------------------------------------
# Why the increments filter is overconfident, and what lets VO + IMU beat VO alone:
# controlled experiments, one change at a time
# ---------------------------------------------------------------------------------------

#: Where the increments filter linearises (``linearise_at`` of
#: :func:`kalman_course.filters.eskf_relative.run_relative`): at the current estimates (the
#: default filter), at each state's first estimate (FEJ), or at the truth (the "ideal EKF",
#: a diagnostic only: it needs the truth).
LINEARISATIONS = ("estimates", "first_estimates", "truth")

#: The two IMU streams of the experiments: the real KITTI IMU, or one simulated from the
#: smoothed truth with exactly the filter's noise and bias model (:func:`simulated_imu`).
IMU_KINDS = ("real", "simulated")


def white_increments(true_position, true_rotation, t, std, seed: int) -> PoseObservations:
    """A VO track whose increments are the true ones plus white noise of σ ``std``.

    Increment k is Δp = R_{k−1}ᵀ (p_k − p_{k−1}) + n_p, ΔR = R_{k−1}ᵀ R_k Exp(n_θ), with
    n ~ N(0, diag(std²)) drawn anew per frame from ``numpy.random.default_rng(seed)``; the
    track is their sum from the first true pose.

    Parameters
    ----------
    true_position : array_like, shape (K, 3)
        True positions at the frames, m.
    true_rotation : array_like, shape (K, 3, 3)
        True attitudes R_nb.
    t : array_like, shape (K,)
        Frame times, s.
    std : array_like, shape (2,) or (6,)
        As for :func:`run_relative_vo`.
    seed : int

    Returns
    -------
    PoseObservations
    """
    p_true = _finite(true_position, "true_position")
    t = as_vector(t, "t")
    if p_true.shape != (len(t), 3) or len(t) < 2:
        raise ValueError(f"true_position must be (K, 3) with K = len(t) ≥ 2, got {p_true.shape} and {len(t)} times")
    R_true = as_rotations(true_rotation, "true_rotation", len(t))
    sig = np.array(_stds(std, "std", (2, 6)))
    sig = np.repeat(sig, 3) if sig.size == 2 else sig
    noise = np.random.default_rng(as_seed(seed)).standard_normal((len(t) - 1, 6)) * sig
    p, R = np.empty_like(p_true), np.empty_like(R_true)
    p[0], R[0] = p_true[0], R_true[0]
    for k in range(1, len(t)):
        dp = R_true[k - 1].T @ (p_true[k] - p_true[k - 1]) + noise[k - 1, :3]
        dR = R_true[k - 1].T @ R_true[k] @ so3.exp(noise[k - 1, 3:])
        p[k], R[k] = p[k - 1] + R[k - 1] @ dp, R[k - 1] @ dR
    return PoseObservations(t.copy(), p, R)


@dataclass(frozen=True, eq=False)
class SimulatedImu:
    """IMU readings simulated from a noise-free reference with the filter's own error model.

    Attributes
    ----------
    t : numpy.ndarray, shape (N,)
        Times, s (the real IMU's).
    specific_force, angular_rate : numpy.ndarray, shape (N, 3)
        Readings, body frame, m/s² and rad/s.
    interpolated : numpy.ndarray, shape (N,)
        All False: no dropouts.
    accel_bias, gyro_bias : numpy.ndarray, shape (N, 3)
        The true biases at each sample.
    """

    t: np.ndarray
    specific_force: np.ndarray = field(repr=False)
    angular_rate: np.ndarray = field(repr=False)
    interpolated: np.ndarray = field(repr=False)
    accel_bias: np.ndarray = field(repr=False)
    gyro_bias: np.ndarray = field(repr=False)


def simulated_imu(reference, config=_CONFIG, seed: int = 0) -> SimulatedImu:
    """The reference readings plus errors drawn from exactly the ESKF configuration's model.

    Per axis: bias b_k = b_0 + Σ_{i<k} q_b √Δt_i · N(0, 1) with b_0 ~ N(0, σ_b0²) (the
    configuration's bias prior σ_b0 and random-walk density q_b), and white noise
    σ_n / √Δt_nom · N(0, 1) per sample (its noise density σ_n, Δt_nom the median step).

    Parameters
    ----------
    reference : ReferenceImu
        Noise-free readings (:func:`kalman_course.data.mems_imu.reference_imu`).
    config : EskfConfig or str
        The filter configuration whose model the errors follow (default ``kitti_gnss``).
    seed : int
        Seed of ``numpy.random.default_rng``; draws, in order: accel b_0 (3), gyro b_0 (3),
        accel and gyro random-walk steps (N−1, 3) each, accel and gyro noise (N, 3) each.

    Returns
    -------
    SimulatedImu
    """
    for attr in ("t", "specific_force", "angular_rate"):
        if not hasattr(reference, attr):
            raise ValueError(f"reference must be a ReferenceImu (t, specific_force, angular_rate); missing {attr!r}")
    cfg = load_config(config) if isinstance(config, str) else config
    if cfg.bias_model != "random_walk":
        raise ValueError(f"config must use the random-walk bias model, got {cfg.bias_model!r}")
    rng = np.random.default_rng(as_seed(seed))
    t = np.asarray(reference.t, dtype=float)
    n, dt = len(t), np.diff(t)
    sigma_a, sigma_w, q_a, q_w = cfg.process_density
    b0_a = cfg.prior_std[9:12] * rng.standard_normal(3)
    b0_w = cfg.prior_std[12:15] * rng.standard_normal(3)

    def walk(b0, q):
        steps = q * np.sqrt(dt)[:, None] * rng.standard_normal((n - 1, 3))
        return b0 + np.vstack([np.zeros(3), np.cumsum(steps, axis=0)])

    accel_bias, gyro_bias = walk(b0_a, q_a), walk(b0_w, q_w)
    per_sample = 1.0 / np.sqrt(np.median(dt))
    f = reference.specific_force + accel_bias + sigma_a * per_sample * rng.standard_normal((n, 3))
    w = reference.angular_rate + gyro_bias + sigma_w * per_sample * rng.standard_normal((n, 3))
    return SimulatedImu(t.copy(), f, w, np.zeros(n, dtype=bool), accel_bias, gyro_bias)


def yaw_error(rotation, true_rotation) -> np.ndarray:
    """Heading error (K,), rad: the vertical component e_zᵀ R δθ of the attitude error.

    δθ = Log(R_trueᵀ R) (nominal − true, body frame); R δθ is the same error in the
    navigation frame, and its z component is the error about the vertical.

    Parameters
    ----------
    rotation, true_rotation : array_like, shape (K, 3, 3)
        Estimated and true attitudes R_nb.
    """
    R = as_rotations(rotation, "rotation")
    R_true = as_rotations(true_rotation, "true_rotation")
    if R_true.shape != R.shape:
        raise ValueError(f"rotation and true_rotation must both be (K, 3, 3), got {R.shape} and {R_true.shape}")
    dtheta = so3.log(np.swapaxes(R_true, 1, 2) @ R)
    return np.einsum("ki,ki->k", R[:, 2, :], dtheta)


def yaw_variance(rotation, P) -> np.ndarray:
    """The filter's variance of :func:`yaw_error` (K,), rad²: e_zᵀ R P_θθ Rᵀ e_z.

    Parameters
    ----------
    rotation : array_like, shape (K, 3, 3)
        Estimated attitudes R_nb.
    P : array_like, shape (K, 15, 15)
        Covariances of the ESKF error state (attitude block rows 6:9).
    """
    R = as_rotations(rotation, "rotation")
    P = as_rows(P, "P", (15, 15), len(R), count="K")
    for k in range(len(P)):
        as_covariance(P[k], f"P[{k}]", 15, psd=True)
    up = R[:, 2, :]
    return np.einsum("ki,kij,kj->k", up, P[:, 6:9, 6:9], up)


@dataclass(frozen=True)
class ConsistencyScore:
    """Accuracy and honesty of one run, with the pose NEES split by block.

    Attributes
    ----------
    nees, nees_position, nees_attitude, nees_yaw : float
        Mean NEES over the evaluated frames: 6-dof pose (6 if consistent), position (3),
        attitude (3) and heading alone (1, :func:`yaw_error` against :func:`yaw_variance`).
    ate : float
        RMS position error, m (no alignment).
    drift_percent, drift_deg_per_100m : float
        KITTI's drift metric.
    yaw_error_end_deg, yaw_sigma_end_deg : float
        Heading error and the filter's σ for it at the last frame, degrees.
    """

    nees: float
    nees_position: float
    nees_attitude: float
    nees_yaw: float
    ate: float
    drift_percent: float
    drift_deg_per_100m: float
    yaw_error_end_deg: float
    yaw_sigma_end_deg: float


def consistency_score(result, truth, t) -> ConsistencyScore:
    """Score a filter run at the frame times ``t`` against ``truth``.

    Parameters
    ----------
    result : EskfResult
        A run with covariances (``at(t)`` must give its states at ``t``).
    truth : object
        ``t`` (M,), ``position`` (M, 3), ``rotation`` (M, 3, 3), holding every time of ``t``
        (the KITTI truth, or the simulation's :class:`~kalman_course.data.mems_imu.SmoothTruth`).
    t : array_like, shape (K,)
        The evaluated frame times, s.
    """
    t = as_vector(t, "t")
    r = result.at(t)
    ev = evaluate(r.t, r.position, r.rotation, truth, P=r.P)
    k = np.searchsorted(truth.t, t - 1e-6)
    p_true, R_true = truth.position[k], truth.rotation[k]
    yaw = yaw_error(r.rotation, R_true)
    var = yaw_variance(r.rotation, r.P)
    d = drift(r.position, r.rotation, p_true, R_true)
    return ConsistencyScore(ev["nees_pose"], float(np.mean(ev["nees_position"])), float(np.mean(ev["nees_attitude"])),
                            float(np.mean(yaw ** 2 / var)), ev["ape_position"], d.translation_percent,
                            d.rotation_deg_per_100m, float(np.rad2deg(yaw[-1])), float(np.rad2deg(np.sqrt(var[-1]))))


#: The simulated IMU of seed k is drawn with seed this + k (the increments with seed k).
_IMU_SEED_OFFSET = 1000


def _evaluated(s: VoSetup, t_end):
    """(frame times evaluated (K,), the time to integrate to or None) for a run cut at ``t_end``."""
    if t_end is None:
        return s.t, None
    t_eval = s.t[s.t <= as_scalar(t_end, "t_end")]
    if len(t_eval) < 2:
        raise ValueError(f"t_end = {t_end!r} leaves fewer than two frames (the first is at τ = {s.t[0]:.3f} s)")
    imu_t = s.excerpt.imu.t
    return t_eval, float(imu_t[min(np.searchsorted(imu_t, t_eval[-1]), len(imu_t) - 1)])


def _linearisation(name: str, truth):
    if name not in LINEARISATIONS:
        raise ValueError(f"linearisation must be one of {', '.join(LINEARISATIONS)}, got {name!r}")
    return {"estimates": None, "first_estimates": "first_estimates", "truth": truth}[name]


def run_increments(s: VoSetup, std, *, vo=None, imu=None, initial=None, linearisation: str = "estimates",
                   truth=None, config=_CONFIG, gnss: bool = False, t_end: float | None = None):
    """:func:`run_relative_vo` with each ingredient replaceable, for the controlled experiments.

    Parameters
    ----------
    s : VoSetup
        Start index, stop time and the defaults of everything below.
    std : array_like, shape (2,) or (6,)
        σ of the increments, as for :func:`run_relative_vo`.
    vo : PoseObservations, optional
        The VO poses (default ``s.vo``).
    imu : object, optional
        The IMU record (default the real one, ``s.excerpt.imu``).
    initial : NominalState, optional
        The state at ``imu.t[s.start]`` (default ``s.initial``).
    linearisation : str
        One of :data:`LINEARISATIONS`.
    truth : object, optional
        The truth to linearise at for "truth" (``t``, ``position``, ``velocity``,
        ``rotation`` at every frame; default ``s.excerpt.truth``).
    config : EskfConfig or str
        Process noise and prior (default ``kitti_gnss``, that of every run of this chapter).
    gnss : bool
        Also fuse the 1 Hz GNSS fixes (real OXTS positions plus simulated noise, σ 1 m).
    t_end : float, optional
        Stop earlier than ``s.t_stop``, s.

    Returns
    -------
    eskf_relative.RelativeRunResult
    """
    ex = s.excerpt
    lin = _linearisation(linearisation, ex.truth if truth is None else truth)
    return run_relative(ex.imu if imu is None else imu, s.initial if initial is None else initial, config,
                        ex.gravity, vo=s.vo if vo is None else vo, relative_std=_stds(std, "std", (2, 6)),
                        gnss=ex.gnss.observations() if gnss else None,
                        start=s.start, t_end=s.t_stop if t_end is None else t_end, linearise_at=lin)


@dataclass(frozen=True)
class LinearisationRun:
    """One run of :func:`linearisation_runs`: which IMU, where linearised, which seed, how it
    scored, and (real IMU only, else None) :func:`yaw_change_at_dropouts`: the heading error
    that arose at the record's dropouts and elsewhere, degrees."""

    imu: str
    linearisation: str
    seed: int
    score: ConsistencyScore
    yaw_change: tuple[float, float] | None = None


def _simulation(s: VoSetup, reference):
    """(truth of the simulation, the initial state at imu.t[s.start]) from a ReferenceImu."""
    t0 = s.excerpt.imu.t[s.start]
    i = int(np.searchsorted(reference.t, t0 - 1e-9))
    if i >= len(reference.t) or abs(reference.t[i] - t0) > 1e-9:
        raise ValueError("reference must be sampled at the real IMU's times (reference_imu of the same excerpt)")
    traj = reference.trajectory
    initial = eskf.NominalState(traj.position[i], traj.velocity[i], traj.rotation[i], np.zeros(3), np.zeros(3))
    return reference.truth, initial


def linearisation_runs(s: VoSetup, std, seeds=range(1, 6), linearisations=LINEARISATIONS, imu: str = "real",
                       reference=None, t_end: float | None = None) -> list[LinearisationRun]:
    """The increments filter on white increments of exactly its σ, linearised in each of several ways.

    Every run starts at the true state with the configuration's prior and fuses
    :func:`white_increments` drawn with ``seed`` (for the real IMU these are exactly the
    tracks of :func:`white_increment_track`); only the linearisation changes within a seed.

    Parameters
    ----------
    s : VoSetup
    std : array_like, shape (2,) or (6,)
        σ of the increments, in the filter and in the simulated noise.
    seeds : iterable of int
    linearisations : sequence of str
        Some of :data:`LINEARISATIONS`.
    imu : str
        "real" (the KITTI IMU, scored against the KITTI truth) or "simulated"
        (:func:`simulated_imu` of ``reference`` with seed 1000 + ``seed``, scored against the
        smoothed truth it was made from; no dropouts).
    reference : ReferenceImu, optional
        For "simulated" (default: built from ``s.excerpt``, about 1 s).
    t_end : float, optional
        Stop (and score) earlier, s.

    Returns
    -------
    list of LinearisationRun
        Seed-major, in the order of ``linearisations``.
    """
    if imu not in IMU_KINDS:
        raise ValueError(f"imu must be one of {', '.join(IMU_KINDS)}, got {imu!r}")
    seeds = [as_seed(seed) for seed in seeds]
    linearisations = tuple(linearisations)
    if not seeds or not linearisations:
        raise ValueError("seeds and linearisations must each hold at least one entry")
    for name in linearisations:
        _linearisation(name, None)
    t_eval, stop = _evaluated(s, t_end)
    if imu == "real":
        truth, initial = s.excerpt.truth, s.initial
    else:
        if reference is None:
            reference = reference_imu(s.excerpt)
        truth, initial = _simulation(s, reference)
    k = np.searchsorted(truth.t, s.t - 1e-6)
    runs = []
    for seed in seeds:
        if imu == "real":
            track, imu_data = white_increment_track(s, std, seed), None
        else:
            track = white_increments(truth.position[k], truth.rotation[k], s.t, std, seed)
            imu_data = simulated_imu(reference, _CONFIG, seed=_IMU_SEED_OFFSET + seed)
        for name in linearisations:
            res = run_increments(s, std, vo=track, imu=imu_data, initial=initial, linearisation=name, truth=truth,
                                 t_end=stop)
            split = yaw_change_at_dropouts(res, truth, t_eval, s.excerpt.imu) if imu == "real" else None
            runs.append(LinearisationRun(imu, name, seed, consistency_score(res, truth, t_eval), split))
    return runs


def yaw_change_at_dropouts(result, truth, t, imu, settle_s: float = 1.0) -> tuple[float, float]:
    """How much of a run's heading error arose at the IMU dropouts, and how much elsewhere.

    The heading error (:func:`yaw_error`) is differenced from frame to frame; a difference
    counts as "at a dropout" if its frame interval overlaps a dropout (interpolated IMU
    samples, ``imu.interpolated``) or the ``settle_s`` seconds after one, when the filter
    re-converges from the inflated noise it used inside.

    Parameters
    ----------
    result : EskfResult
        A run with states at the times ``t``.
    truth : object
        ``t``, ``position``, ``rotation``, holding every time of ``t``.
    t : array_like, shape (K,)
        Frame times, s.
    imu : object
        ``t`` (N,) and ``interpolated`` (N,) bool.
    settle_s : float
        How long after a dropout still counts, s.

    Returns
    -------
    (float, float)
        Sum of the changes at dropouts, and elsewhere, degrees. They add up to the heading
        error at the last frame minus the one at the first.
    """
    t = as_vector(t, "t")
    settle_s = as_scalar(settle_s, "settle_s", allow_zero=True)
    r = result.at(t)
    k = np.searchsorted(truth.t, t - 1e-6)
    change = np.diff(np.rad2deg(yaw_error(r.rotation, truth.rotation[k])))
    flags = np.asarray(imu.interpolated, dtype=bool).astype(int)
    t_imu = np.asarray(imu.t, dtype=float)
    first = np.flatnonzero(np.diff(np.concatenate([[0], flags])) == 1)       # first sample of each dropout
    last = np.flatnonzero(np.diff(np.concatenate([flags, [0]])) == -1)       # its last sample
    at = np.zeros(len(change), dtype=bool)
    for a, b in zip(t_imu[first], t_imu[last] + settle_s):
        at |= (t[1:] >= a) & (t[:-1] <= b)                                  # interval (t_j, t_j+1] meets [a, b]
    return float(change[at].sum()), float(change[~at].sum())


@dataclass(frozen=True)
class ClockOffsetRun:
    """One run of :func:`clock_offset_runs`: the offset δ (s) and the score."""

    offset_s: float
    score: ConsistencyScore


def clock_offset_runs(s: VoSetup, std, offsets=(-0.02, -0.01, 0.0, 0.01, 0.02), seed: int = 1,
                      linearisation: str = "first_estimates", t_end: float | None = None) -> list[ClockOffsetRun]:
    """Is the real IMU on the truth's clock? Shift the truth by δ and see where the filter is most consistent.

    For each δ, the truth is read at τ + δ (:meth:`~kalman_course.data.kitti.TruthData.interpolate`)
    for the white increments (:func:`white_increments`, seed ``seed``), the initial state and
    the score; the real IMU stays on its own clock. If the clocks agree, the NEES is lowest
    at δ = 0.

    Parameters
    ----------
    s : VoSetup
    std : array_like, shape (2,) or (6,)
    offsets : iterable of float
        δ, s (each small enough to keep τ + δ inside the truth).
    seed : int
    linearisation : str
        One of :data:`LINEARISATIONS` except "truth" (default FEJ, consistent at δ = 0).
    t_end : float, optional
        Stop earlier, s.

    Returns
    -------
    list of ClockOffsetRun
    """
    if linearisation == "truth":
        raise ValueError("linearisation must be 'estimates' or 'first_estimates' here (the truth moves with δ)")
    offsets = [float(d) for d in offsets]
    if not offsets or not all(np.isfinite(offsets)):
        raise ValueError(f"offsets must be a non-empty sequence of finite numbers (s), got {offsets!r}")
    t_eval, stop = _evaluated(s, t_end)
    truth = s.excerpt.truth
    runs = []
    for d in offsets:
        moved = truth.interpolate(s.t + d)
        shifted = PoseObservations(s.t, moved.position, moved.rotation)     # the truth on the IMU's clock
        track = white_increments(moved.position, moved.rotation, s.t, std, seed)
        initial = eskf.NominalState.from_nav(truth.state_at(s.excerpt.imu.t[s.start] + d))
        res = run_increments(s, std, vo=track, initial=initial, linearisation=linearisation, t_end=stop)
        runs.append(ClockOffsetRun(d, consistency_score(res, shifted, t_eval)))
    return runs


def rotation_increments(rotation) -> np.ndarray:
    """Rotation vectors Log(R_{k−1}ᵀ R_k) (K−1, 3), rad, of consecutive attitudes (K, 3, 3)."""
    R = _finite(rotation, "rotation")
    if R.ndim != 3 or R.shape[1:] != (3, 3) or len(R) < 2:
        raise ValueError(f"rotation must be (K, 3, 3) with K ≥ 2, got {R.shape}")
    return so3.log(np.swapaxes(R[:-1], 1, 2) @ R[1:])


def gyro_increments(imu, t) -> tuple[np.ndarray, np.ndarray]:
    """What the gyro says the body turned between consecutive frame times (no bias removed).

    The raw rates are integrated by the midpoint mechanisation
    (:func:`kalman_course.core.imu.dead_reckon`) and the attitude read at each frame time by
    geodesic interpolation between the two neighbouring samples.

    Parameters
    ----------
    imu : object
        ``t`` (N,), ``specific_force`` (N, 3), ``angular_rate`` (N, 3) rad/s and optionally
        ``interpolated`` (N,) bool.
    t : array_like, shape (K,)
        Frame times inside the IMU record, s.

    Returns
    -------
    dtheta : numpy.ndarray, shape (K−1, 3)
        Log(R(t_{k−1})ᵀ R(t_k)), rad, body frame.
    dropout : numpy.ndarray, shape (K−1,)
        True where an interpolated sample lies in or next to the interval.
    """
    t = as_vector(t, "t")
    t_imu = np.asarray(imu.t, dtype=float)
    if len(t) < 2 or t[0] < t_imu[0] or t[-1] > t_imu[-1]:
        raise ValueError(f"t must hold at least two frame times inside the IMU record "
                         f"[{t_imu[0]:.3f}, {t_imu[-1]:.3f}] s")
    traj = dead_reckon(imu, NavState(np.zeros(3), np.zeros(3), np.eye(3)), np.zeros(3))
    i = np.clip(np.searchsorted(t_imu, t, side="right") - 1, 0, len(t_imu) - 2)
    alpha = (t - t_imu[i]) / (t_imu[i + 1] - t_imu[i])
    R = so3.interpolate(traj.rotation[i], traj.rotation[i + 1], alpha)
    flags = np.asarray(getattr(imu, "interpolated", np.zeros(len(t_imu), dtype=bool)), dtype=bool)
    count = np.concatenate([[0], np.cumsum(flags)])            # flagged samples before index j: count[j]
    dropout = count[np.minimum(i[1:] + 2, len(t_imu))] - count[i[:-1]] > 0
    return rotation_increments(R), dropout


def frame_lag(s: VoSetup, lags=(-2, -1, 0, 1, 2), t_cal: float = CALIBRATION_S) -> dict:
    """Which camera frame the VO poses belong to, from the gyro alone (no truth).

    VO increment k (rows k → k+1) is compared with the gyro's increment between frames
    k + L and k + L + 1, for each lag L, over the first ``t_cal`` seconds (intervals with
    a dropout left out). The lag with the smallest difference says that row k holds the
    pose of frame k + L.

    Parameters
    ----------
    s : VoSetup
    lags : iterable of int
    t_cal : float
        Length of the stretch used, s.

    Returns
    -------
    dict
        {L: RMS of |Δθ_VO − Δθ_gyro| in degrees}.
    """
    lags = [int(L) for L in lags]
    t_cal = as_scalar(t_cal, "t_cal")
    n = int(np.searchsorted(s.t, s.t[0] + t_cal))
    reach = max(abs(L) for L in lags)
    if n - 2 * reach < 10:
        raise ValueError(f"t_cal = {t_cal:g} s is too short for lags up to {reach}")
    d_vo = rotation_increments(s.vo.rotation)
    d_gyro, dropout = gyro_increments(s.excerpt.imu, s.t)
    out = {}
    for L in lags:
        k = np.arange(reach, n - reach - 1)
        ok = ~dropout[k + L]
        # the RMS of |Δθ_VO − Δθ_gyro| over the intervals, as the ATE of two 3-vector series
        out[L] = float(np.rad2deg(ate_rmse(d_vo[k[ok]], d_gyro[k[ok] + L], align="none")))
    return out


def tilt_misalignment(dtheta_vo, dtheta_gyro) -> tuple[np.ndarray, np.ndarray]:
    """The small roll/pitch rotation between the VO's body axes and the IMU's, from turns.

    If the VO reports attitudes R_vo = R_imu C with a fixed C, its rotation increments are
    those of the IMU seen in the turned axes: Δθ_vo = Cᵀ Δθ_imu ≈ Δθ_imu + φ × Δθ_imu with
    Exp(φ) = Cᵀ. The gyro's increments also carry its bias: Δθ_gyro = Δθ_imu + c (c = b T).
    Least squares over the frames for φ_x, φ_y and c (5 unknowns; φ_z, a turn about the
    vertical, is barely seen in a car's mostly vertical turns, and it only turns the
    whole fused track):

        Δθ_vo − Δθ_gyro = −[Δθ_gyro]× [φ_x, φ_y, 0]ᵀ − c.

    Then R_vo Exp(φ) has the IMU's axes (up to φ_z).

    Parameters
    ----------
    dtheta_vo, dtheta_gyro : array_like, shape (M, 3)
        The same intervals' rotation vectors from the VO (:func:`rotation_increments`) and
        the gyro (:func:`gyro_increments`), rad.

    Returns
    -------
    phi : numpy.ndarray, shape (3,)
        (φ_x, φ_y, 0), rad.
    offset : numpy.ndarray, shape (3,)
        c, rad per interval.
    """
    a = _finite(dtheta_vo, "dtheta_vo")
    g = _finite(dtheta_gyro, "dtheta_gyro")
    if a.ndim != 2 or a.shape[1] != 3 or g.shape != a.shape or len(a) < 5:
        raise ValueError(f"dtheta_vo and dtheta_gyro must both be (M, 3) with M ≥ 5, got {a.shape} and {g.shape}")
    A = np.zeros((len(a), 3, 5))
    A[:, :, 0:2] = -so3.hat(g)[:, :, 0:2]
    A[:, :, 2:5] = -np.eye(3)
    x = np.linalg.lstsq(A.reshape(-1, 5), (a - g).reshape(-1), rcond=None)[0]
    return np.array([x[0], x[1], 0.0]), x[2:5]


def vo_tilt(s: VoSetup, t_cal: float = CALIBRATION_S) -> np.ndarray:
    """:func:`tilt_misalignment` of the setup's VO against the real gyro over the first ``t_cal`` s (no truth).

    Returns φ (3,), rad (intervals with a dropout left out).
    """
    t_cal = as_scalar(t_cal, "t_cal")
    n = int(np.searchsorted(s.t, s.t[0] + t_cal))
    if n < 10:
        raise ValueError(f"t_cal = {t_cal:g} s holds fewer than 10 frames")
    d_gyro, dropout = gyro_increments(s.excerpt.imu, s.t[:n])
    d_vo = rotation_increments(s.vo.rotation[:n])
    return tilt_misalignment(d_vo[~dropout], d_gyro[~dropout])[0]


def realigned(s: VoSetup, lag: int = 0, tilt=None) -> VoSetup:
    """The setup with its VO track moved to the right frames and turned into the IMU's axes.

    Parameters
    ----------
    s : VoSetup
    lag : int
        Row k of the shipped track holds the pose of frame k + ``lag`` (:func:`frame_lag`):
        the pose of frame j is taken from row j − ``lag``.
    tilt : array_like, shape (3,), optional
        φ of :func:`vo_tilt`: every VO attitude becomes R_vo Exp(φ) (positions unchanged).

    Returns
    -------
    VoSetup
        Re-anchored at frame ``s.first`` (:func:`anchor`); everything else as ``s``.
    """
    if isinstance(lag, (bool, np.bool_)) or not isinstance(lag, (int, np.integer)) or not 0 <= lag < s.first:
        raise ValueError(f"lag must be an integer in [0, {s.first}), got {lag!r}")
    slam = _slam(s.excerpt, s.system)
    p = np.array(slam.position, dtype=float)
    R = np.array(slam.rotation, dtype=float)
    if lag:
        p[lag:], R[lag:] = slam.position[:-lag], slam.rotation[:-lag]
    if tilt is not None:
        R = R @ so3.exp(as_vector(tilt, "tilt", 3))
    truth = s.excerpt.truth
    p, R = anchor(p, R, truth.position[s.first], truth.rotation[s.first], s.first)
    sel = slice(s.first, s.last + 1)
    return VoSetup(s.excerpt, s.system, s.first, s.last, s.start, s.initial,
                   PoseObservations(slam.t[sel], p[sel], R[sel]), s.t_end, s.t_stop)


def tuned_relative_std(s: VoSetup, calibration_s: float = CALIBRATION_S) -> TunedStd:
    """The increments' σ chosen by the NIS on the first ``calibration_s`` seconds, as :func:`compare` does."""
    t_cal = min(s.t[0] + as_scalar(calibration_s, "calibration_s"), s.t_end)
    return tune_std(lambda std: run_relative_vo(s, std, t_end=t_cal), _RELATIVE_STD0, RELATIVE_BLOCKS)


@dataclass(frozen=True)
class VioVariant:
    """One way of running VO + IMU without GNSS.

    Attributes
    ----------
    name : str
    linearisation : str
        One of :data:`LINEARISATIONS`.
    gyro_bias_prior : float or None
        σ of the initial gyro bias, rad/s (None: the configuration's 1e-3).
    gyro_bias_noise : float or None
        Gyro bias random-walk density, rad/s²/√Hz (None: the configuration's 2.91e-6).
    """

    name: str
    linearisation: str = "estimates"
    gyro_bias_prior: float | None = None
    gyro_bias_noise: float | None = None

    def config(self):
        """The ``kitti_gnss`` configuration with this variant's gyro-bias settings."""
        changes = {}
        if self.gyro_bias_prior is not None:
            changes["prior__gyro_bias"] = self.gyro_bias_prior
        if self.gyro_bias_noise is not None:
            changes["process__gyro_bias_noise"] = self.gyro_bias_noise
        return load_config(_CONFIG).replace(**changes)


#: The variants of the second question, each change alone and then together.
VIO_VARIANTS = (
    VioVariant("as in the table"),
    VioVariant("FEJ", "first_estimates"),
    VioVariant("gyro bias prior 5e-5 rad/s", gyro_bias_prior=5e-5),
    VioVariant("gyro bias prior 5e-5 rad/s, random walk ÷ 10", gyro_bias_prior=5e-5, gyro_bias_noise=2.91e-7),
    VioVariant("FEJ + gyro bias prior 5e-5 rad/s", "first_estimates", gyro_bias_prior=5e-5),
)


@dataclass(frozen=True, eq=False)
class VioRow:
    """One line of :func:`vio_variants`.

    Attributes
    ----------
    name : str
        "VO alone" or the variant's name.
    score : Score
        ATE, attitude error, KITTI drift and mean pose NEES, as in :func:`table`.
    consistency : ConsistencyScore or None
        The NEES by block and the heading error and σ at the end (None for VO alone).
    yaw_error_end_deg : float
        Heading error at the last frame, degrees.
    vertical_error_end_m : float
        Height error at the last frame, m.
    """

    name: str
    score: Score
    consistency: ConsistencyScore | None
    yaw_error_end_deg: float
    vertical_error_end_m: float


def vio_variants(s: VoSetup, std, variants=VIO_VARIANTS, t_end: float | None = None) -> list[VioRow]:
    """VO alone and VO + IMU (increments, no GNSS) run each way of ``variants``, scored alike.

    Parameters
    ----------
    s : VoSetup
        The real VO (possibly :func:`realigned`) and the real IMU.
    std : array_like, shape (2,) or (6,)
        σ of the increments (e.g. :func:`tuned_relative_std`), the same for every variant.
    variants : sequence of VioVariant
    t_end : float, optional
        Stop earlier, s.

    Returns
    -------
    list of VioRow
        "VO alone" first, then the variants in order.
    """
    variants = tuple(variants)
    if not variants or not all(isinstance(v, VioVariant) for v in variants):
        raise ValueError("variants must be a non-empty sequence of VioVariant")
    t_eval, stop = _evaluated(s, t_end)
    n = len(t_eval)
    cut = VoSetup(s.excerpt, s.system, s.first, s.first + n - 1, s.start, s.initial,
                  PoseObservations(s.vo.t[:n], s.vo.position[:n], s.vo.rotation[:n]), float(t_eval[-1]),
                  s.t_stop if stop is None else stop)
    truth = s.excerpt.truth
    p_true, R_true = truth.position[cut.frames], truth.rotation[cut.frames]

    def row(name, position, rotation, result=None):
        sc = score(cut, t_eval, position, rotation, None if result is None else result.P)
        cs = None if result is None else consistency_score(result, truth, t_eval)
        return VioRow(name, sc, cs, float(np.rad2deg(yaw_error(rotation[-1:], R_true[-1:])[0])),
                      float(position[-1, 2] - p_true[-1, 2]))

    rows = [row("VO alone", cut.vo.position, cut.vo.rotation)]
    for v in variants:
        res = run_increments(cut, std, linearisation=v.linearisation, config=v.config()).at(t_eval)
        rows.append(row(v.name, res.position, res.rotation, res))
    return rows


def linearisation_table(runs) -> str:
    """:func:`linearisation_runs` (or several concatenated) as a Markdown table, one row per IMU and linearisation.

    Columns: the inputs (what is real, what simulated), the linearisation, the mean pose NEES
    of every seed (6 if consistent), the seeds' means of the position (3), attitude (3) and
    heading (1) NEES, the ATE range over the seeds, the heading error and σ at the end
    (mean over the seeds), and how much of that error arose at the IMU's dropouts and how much
    elsewhere (means over the seeds; "—" for the simulated IMU, which has none).
    """
    runs = list(runs)
    if not runs or not all(isinstance(r, LinearisationRun) for r in runs):
        raise ValueError("runs must be a non-empty list of LinearisationRun (from linearisation_runs)")
    inputs = {"real": "real IMU, simulated white increments (truth + noise of the filter's σ)",
              "simulated": "simulated IMU (smoothed truth + the filter's noise and bias model), simulated white "
                           "increments"}
    lines = ["| inputs | linearised at | mean NEES per seed (6) | position (3) | attitude (3) | heading (1) "
             "| ATE [m] | heading error / σ at the end [°] | of which at dropouts / elsewhere [°] |",
             "|---|---|---|---|---|---|---|---|---|"]
    keys = list(dict.fromkeys((r.imu, r.linearisation) for r in runs))
    for imu, lin in keys:
        sel = [r for r in runs if (r.imu, r.linearisation) == (imu, lin)]
        sc = [r.score for r in sel]
        ate = [c.ate for c in sc]
        lines.append(f"| {inputs[imu]} | {lin} | {', '.join(f'{c.nees:.1f}' for c in sc)} | "
                     f"{np.mean([c.nees_position for c in sc]):.2f} | {np.mean([c.nees_attitude for c in sc]):.2f} | "
                     f"{np.mean([c.nees_yaw for c in sc]):.2f} | {min(ate):.2f}–{max(ate):.2f} | "
                     f"{np.mean([c.yaw_error_end_deg for c in sc]):+.2f} / "
                     f"{np.mean([c.yaw_sigma_end_deg for c in sc]):.2f} | {_split_text(sel)} |")
    seeds = sorted({r.seed for r in runs})
    lines.append("")
    lines.append(f"KITTI sequence 00, seeds {', '.join(map(str, seeds))}; every run starts at the true state with the "
                 "configuration's prior; the truth is used to start, to score and (row 'truth') to linearise.")
    return "\n".join(lines)


def _split_text(runs) -> str:
    """Mean heading change at dropouts / elsewhere of runs of one table row, or "—"."""
    if any(r.yaw_change is None for r in runs):
        return "—"
    at, elsewhere = np.mean([r.yaw_change for r in runs], axis=0)
    return f"{at:+.2f} / {elsewhere:+.2f}"


def vio_table(rows, title: str = "") -> str:
    """:func:`vio_variants` as a Markdown table, each row compared with VO alone (the first row).

    Columns: estimate, ATE (m), KITTI drift (%, °/100 m), mean pose NEES and its position /
    attitude / heading blocks, heading and height error at the last frame, and whether the
    row is below VO alone in ATE and in both drift rates.
    """
    rows = list(rows)
    if not rows or not all(isinstance(r, VioRow) for r in rows) or rows[0].consistency is not None:
        raise ValueError("rows must be the list of VioRow from vio_variants (VO alone first)")
    ref = rows[0].score
    lines = ([title, ""] if title else []) + [
        "| estimate | ATE [m] | drift [%] | drift [°/100 m] | mean NEES (6) | position / attitude / heading "
        "| heading error at the end [°] | height error at the end [m] | below VO alone in all three? |",
        "|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        sc = r.score
        if r.consistency is None:
            nees, blocks, below = "—", "—", "(reference)"
        else:
            c = r.consistency
            nees, blocks = f"{sc.nees:.1f}", f"{c.nees_position:.1f} / {c.nees_attitude:.1f} / {c.nees_yaw:.2f}"
            yes = (sc.ate < ref.ate and sc.drift.translation_percent < ref.drift.translation_percent
                   and sc.drift.rotation_deg_per_100m < ref.drift.rotation_deg_per_100m)
            below = "yes" if yes else "no"
        lines.append(f"| {r.name} | {sc.ate:.2f} | {sc.drift.translation_percent:.2f} | "
                     f"{sc.drift.rotation_deg_per_100m:.3f} | {nees} | {blocks} | {r.yaw_error_end_deg:+.2f} | "
                     f"{r.vertical_error_end_m:+.2f} | {below} |")
    lines.append("")
    lines.append("Real: the VO track, the KITTI IMU and the truth (used only to start the runs and to score them); "
                 "no GNSS. The increments' σ is NIS-tuned on the first 60 s and the same in every row.")
    return "\n".join(lines)
