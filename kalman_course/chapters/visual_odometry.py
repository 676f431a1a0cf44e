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
from kalman_course.core.validation import as_scalar, as_seed, as_vector
from kalman_course.data.kitti import load_kitti
from kalman_course.evaluation.drift import DriftResult, drift
from kalman_course.evaluation.metrics import chi2_ppf, nis
from kalman_course.evaluation.pose import evaluate
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import load_config
from kalman_course.filters.eskf_relative import run_relative

__all__ = [
    "VO_SYSTEMS", "METHODS", "CALIBRATION_S", "VoSetup", "setup", "anchor",
    "ABSOLUTE_BLOCKS", "RELATIVE_BLOCKS",
    "run_absolute", "run_relative_vo", "run_imu_gnss", "block_nis", "TunedStd", "tune_std",
    "Score", "score", "VoRow", "VoComparison", "compare", "table",
    "white_increment_track", "white_increment_runs",
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
    p = np.asarray(position, dtype=float)
    R = np.asarray(rotation, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or R.shape != (p.shape[0], 3, 3):
        raise ValueError(f"position must be (K, 3) and rotation (K, 3, 3), got {p.shape} and {R.shape}")
    if isinstance(frame, (bool, np.bool_)) or not isinstance(frame, (int, np.integer)) or not 0 <= frame < len(p):
        raise ValueError(f"frame must be an index into the track (0 … {len(p) - 1}), got {frame!r}")
    p_true = as_vector(true_position, "true_position", 3)
    C = np.asarray(true_rotation, dtype=float) @ R[frame].T          # the correcting rotation
    return p_true + (p - p[frame]) @ C.T, C @ R


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
    ex = s.excerpt
    return run_relative(ex.imu, s.initial, _CONFIG, ex.gravity, vo=s.vo,
                        relative_std=_stds(std, "std", (2, 6)), gnss=ex.gnss.observations() if gnss else None,
                        start=s.start, t_end=s.t_stop if t_end is None else t_end)


def run_imu_gnss(s: VoSetup) -> eskf.EskfResult:
    """The reference without VO: the chapter-08 ESKF with the GNSS fixes, states at the VO frames."""
    ex = s.excerpt
    return eskf.run(ex.imu, s.initial, _CONFIG, ex.gravity, gnss=ex.gnss.observations(), start=s.start,
                    t_end=s.t_stop, output_times=s.t)


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
    y = np.asarray(innovation, dtype=float)
    S = np.asarray(S, dtype=float)
    if y.ndim != 2 or S.shape != (y.shape[0], y.shape[1], y.shape[1]):
        raise ValueError(f"innovation must be (N, m) and S (N, m, m), got {y.shape} and {S.shape}")
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
    """A simulated VO track whose frame-to-frame increments are the true ones plus white noise.

    Increment k is Δp = R_{k−1}ᵀ (p_k − p_{k−1}) + n_p and ΔR = R_{k−1}ᵀ R_k Exp(n_θ), from
    the true poses of the evaluated frames, with n ~ N(0, diag(std²)) drawn anew at every
    frame: exactly the noise model of :func:`run_relative_vo`, with no correlation in time.
    The track is the sum of these increments from the true pose of the anchor frame.

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
    sig = np.array(_stds(std, "std", (2, 6)))
    sig = np.repeat(sig, 3) if sig.size == 2 else sig
    rng = np.random.default_rng(as_seed(seed))
    truth = s.excerpt.truth
    p_true, R_true = truth.position[s.frames], truth.rotation[s.frames]
    p, R = np.empty_like(p_true), np.empty_like(R_true)
    p[0], R[0] = p_true[0], R_true[0]
    noise = rng.standard_normal((len(p_true) - 1, 6)) * sig
    for k in range(1, len(p_true)):
        dp = R_true[k - 1].T @ (p_true[k] - p_true[k - 1]) + noise[k - 1, :3]
        dR = R_true[k - 1].T @ R_true[k] @ so3.exp(noise[k - 1, 3:])
        p[k], R[k] = p[k - 1] + R[k - 1] @ dp, R[k - 1] @ dR
    return PoseObservations(s.vo.t.copy(), p, R)


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
