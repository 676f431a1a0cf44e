"""Tuning and consistency (chapter 09): Monte Carlo, sensitivity, gating, numerical failures.

A filter is *consistent* when its errors are as large as its covariance says. The
statistics that test this (NEES/NIS summaries, verdicts, the chi-square gate) are
:mod:`kalman_course.evaluation.consistency`; this module builds the chapter's experiments
on them and on :mod:`kalman_course.filters.eskf`:

- :func:`monte_carlo` — the ESKF on the synthetic IMU trajectory (exact truth), n seeded
  runs, 15-state NEES and 6-dof NIS per step;
- :func:`scaled_config` and :func:`sensitivity` — the KITTI ESKF over several noise settings,
  each judged by its pose NEES (against the truth, time-correlated band) and its NIS;
- :func:`whiteness_runs` — the innovation whiteness test on the KITTI ESKF over seeds, with
  white or Gauss–Markov (coloured) simulated lidar errors;
- :func:`inject_outliers` and :func:`run_gated` — chi-square innovation gating against
  seeded map-matching failures in the lidar poses;
- :func:`simple_update`, :func:`joseph_update`, :func:`symmetrise`,
  :func:`covariance_health` and :func:`roundoff_experiment` — the numerical-failure gallery.

Everything random comes from ``numpy.random.default_rng(seed)``.
"""

from __future__ import annotations

import dataclasses
import os
import re
from dataclasses import dataclass

import numpy as np

from kalman_course.core import linalg, so3
from kalman_course.core.observations import PoseObservations
from kalman_course.core.validation import as_covariance, as_flag, as_int, as_scalar
from kalman_course.data import GaussMarkovErrors, WhiteErrors, imu_trajectory, simulate_lidar_poses
from kalman_course.evaluation import metrics
from kalman_course.evaluation.consistency import (VERDICTS, Whiteness, average_band, gate_threshold,
                                                  innovation_whiteness, verdict)
from kalman_course.evaluation.pose import evaluate
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import EskfConfig, load_config

__all__ = [
    "MonteCarloResult", "monte_carlo", "full_state_error",
    "scaled_config", "SensitivityRow", "sensitivity", "combined_verdict",
    "WhitenessRuns", "whiteness_runs",
    "inject_outliers", "GatedRun", "run_gated",
    "simple_update", "joseph_update", "symmetrise", "covariance_health", "roundoff_experiment",
]

_POSE_IDX = np.array([0, 1, 2, 6, 7, 8])


# ---------------------------------------------------------------------------------------
# Monte Carlo on the synthetic IMU trajectory
# ---------------------------------------------------------------------------------------

def full_state_error(result, truth, k) -> np.ndarray:
    """15-state error nominal − true, [δp, δv, δθ, δb_a, δb_ω], shape (K, 15).

    Parameters
    ----------
    result : eskf.EskfResult
    truth : data.ImuScenario
        Exact truth (position, velocity, rotation and biases at every sample).
    k : array_like of int, shape (K,)
        Index into ``truth`` of each row of ``result``.
    """
    k = np.asarray(k)
    dth = so3.log(np.swapaxes(truth.rotation[k], -1, -2) @ result.rotation)
    return np.concatenate([result.position - truth.position[k], result.velocity - truth.velocity[k], dth,
                           result.accel_bias - truth.accel_bias[k], result.gyro_bias - truth.gyro_bias[k]],
                          axis=1)


@dataclass(frozen=True)
class MonteCarloResult:
    """Per-step NEES and NIS of n seeded runs of the ESKF on the synthetic trajectory.

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Update times, s.
    nees : numpy.ndarray, shape (n_runs, K)
        15-state NEES after each update.
    nees_pose : numpy.ndarray, shape (n_runs, K)
        6-dof pose NEES ([δp, δθ]) after each update.
    nis : numpy.ndarray, shape (n_runs, K)
        6-dof NIS of each lidar innovation.
    position_error : numpy.ndarray, shape (n_runs, K)
        |p̂ − p|, m.
    position_std : numpy.ndarray, shape (n_runs, K)
        sqrt(trace of the δp block of P), m.
    """

    t: np.ndarray
    nees: np.ndarray
    nees_pose: np.ndarray
    nis: np.ndarray
    position_error: np.ndarray
    position_std: np.ndarray

    @property
    def n_runs(self) -> int:
        return int(self.nees.shape[0])


def _synthetic_config(scenario, process_scale: float, lidar_sigma, lidar_attitude_deg) -> EskfConfig:
    base = load_config("kitti_lidar")
    return base.replace(
        process__accel_noise=scenario.accel_noise_density * process_scale,
        process__gyro_noise=scenario.gyro_noise_density * process_scale,
        process__accel_bias_noise=scenario.accel_bias_density,
        process__gyro_bias_noise=scenario.gyro_bias_density,
        observation__lidar_position=lidar_sigma,
        observation__lidar_attitude=np.deg2rad(lidar_attitude_deg))


def monte_carlo(n_runs: int = 20, seed: int = 0, duration: float = 20.0, *, process_scale: float = 1.0,
                lidar_sigma: float = 0.2, lidar_attitude_deg: float = 0.3, lidar_every: int = 10,
                ) -> MonteCarloResult:
    """Run the ESKF ``n_runs`` times on independently seeded synthetic IMU trajectories.

    Run i uses seed ``seed + i`` for everything it draws: the true biases at t = 0 and the
    initial error (both from the filter's prior), the IMU noise
    (:func:`kalman_course.data.imu_trajectory`) and the lidar pose noise
    (:func:`kalman_course.data.simulate_lidar_poses`, every ``lidar_every``-th sample). The
    filter uses the simulator's own noise densities times ``process_scale`` (1 gives a
    correctly tuned filter), so its NEES should be χ²(15).
    """
    if n_runs < 1:
        raise ValueError(f"n_runs must be at least 1, got {n_runs!r}")
    rows = {"nees": [], "nees_pose": [], "nis": [], "err": [], "std": []}
    t_out = None
    for i in range(n_runs):
        rng = np.random.default_rng(seed + i)
        cfg0 = load_config("kitti_lidar")
        prior = cfg0.prior_std
        ba0, bw0 = prior[9:12] * rng.standard_normal(3), prior[12:15] * rng.standard_normal(3)
        dx0 = prior * rng.standard_normal(15)
        sc = imu_trajectory(seed + i, duration=duration, accel_bias0=ba0, gyro_bias0=bw0)
        cfg = _synthetic_config(sc, process_scale, lidar_sigma, lidar_attitude_deg)
        sel = np.arange(lidar_every, len(sc.t), lidar_every)
        poses = PoseObservations(sc.t[sel], sc.position[sel], sc.rotation[sel])
        lidar = simulate_lidar_poses(poses, seed + i, lidar_sigma, lidar_attitude_deg)
        # nominal = true + error (error = nominal − true)
        x0 = eskf.NominalState(sc.position[0] + dx0[0:3], sc.velocity[0] + dx0[3:6],
                               sc.rotation[0] @ so3.exp(dx0[6:9]), ba0 + dx0[9:12], bw0 + dx0[12:15])
        res = eskf.run(sc.imu, x0, cfg, sc.gravity, lidar=lidar)
        k = np.searchsorted(sc.t, res.t - 1e-9)
        e = full_state_error(res, sc, k)
        rows["nees"].append(metrics.normalised_squared(e, res.P, "error", "P"))
        ep = e[:, _POSE_IDX]
        rows["nees_pose"].append(metrics.normalised_squared(ep, res.P[:, _POSE_IDX][:, :, _POSE_IDX], "error", "P"))
        rows["nis"].append(metrics.normalised_squared(np.array(res.innovation), np.array(res.S), "innovation", "S"))
        rows["err"].append(np.linalg.norm(e[:, 0:3], axis=1))
        rows["std"].append(np.sqrt(np.trace(res.P[:, 0:3, 0:3], axis1=1, axis2=2)))
        t_out = res.t
    return MonteCarloResult(t_out, *(np.array(rows[k]) for k in ("nees", "nees_pose", "nis", "err", "std")))


# ---------------------------------------------------------------------------------------
# Sensitivity of the KITTI ESKF to its noise settings
# ---------------------------------------------------------------------------------------

def scaled_config(config="kitti_lidar", q_factor: float = 1.0, r_factor: float = 1.0) -> EskfConfig:
    """The configuration with Q multiplied by ``q_factor`` and R by ``r_factor``.

    Q scales the white-noise densities of the accelerometer and gyroscope (densities × √q);
    R scales the lidar and GNSS variances (standard deviations × √r). Bias random walks and
    the prior are left alone.
    """
    cfg = _config(config)
    q_factor, r_factor = as_scalar(q_factor, "q_factor"), as_scalar(r_factor, "r_factor")
    q, r = float(np.sqrt(q_factor)), float(np.sqrt(r_factor))
    d, lid = cfg.process_density, cfg.lidar_std
    return cfg.replace(process__accel_noise=d[0] * q, process__gyro_noise=d[1] * q,
                       observation__lidar_position=lid[0] * r, observation__lidar_attitude=lid[3] * r,
                       observation__gnss_position=cfg.gnss_std * r)


@dataclass(frozen=True)
class SensitivityRow:
    """One setting of :func:`sensitivity`.

    Attributes
    ----------
    label : str
    q_factor, r_factor : float
    ape_position : float
        Position APE (RMSE), m.
    ape_attitude_deg : float
        Attitude APE (RMS angle), degrees.
    nees_pose : float
        Mean 6-dof pose NEES.
    nees_share : float
        Share of steps whose pose NEES lies inside the 95 % bounds of χ²(6).
    nis : float
        Mean 6-dof NIS.
    verdict : str
        Both tests together, :func:`combined_verdict` of ``nees_verdict`` and
        ``nis_verdict``: "consistent (NEES and NIS)" only when both pass, otherwise each
        failure named with its statistic, e.g. "overconfident (NEES)".
    nees_band : (float, float)
        95 % interval of the time-averaged pose NEES,
        :func:`~kalman_course.evaluation.consistency.average_band` (its samples are
        correlated in time; the interval counts them by their correlation time).
    nees_verdict : str
        The mean pose NEES against ``nees_band``.
    nis_band : (float, float)
        95 % interval of the mean NIS for white innovations, ``chi2_bounds(6, K)`` (a
        consistent filter's innovations are white).
    nis_verdict : str
        :func:`~kalman_course.evaluation.consistency.verdict` of the NIS record.
    """

    label: str
    q_factor: float
    r_factor: float
    ape_position: float
    ape_attitude_deg: float
    nees_pose: float
    nees_share: float
    nis: float
    verdict: str
    nees_band: tuple
    nees_verdict: str
    nis_band: tuple
    nis_verdict: str


def _config(config) -> EskfConfig:
    """``config`` (an EskfConfig, a configuration name, a YAML path or a mapping) loaded;
    anything else is a ValueError naming ``config``."""
    if isinstance(config, EskfConfig):
        return config
    if not isinstance(config, (str, os.PathLike, dict)):
        raise ValueError(f"config must be an EskfConfig, a configuration name, a path to a YAML file or a "
                         f"mapping, got {type(config).__name__}: {config!r:.60}")
    try:
        return load_config(config)
    except ValueError as exc:
        if re.search(r"(?<![\w.])config(?![\w])", str(exc)):
            raise
        raise ValueError(f"config: {exc}") from None


def combined_verdict(nees_verdict: str, nis_verdict: str) -> str:
    """One verdict from the NEES test and the NIS test, saying which statistic failed.

    Parameters
    ----------
    nees_verdict, nis_verdict : str
        Each one of :data:`~kalman_course.evaluation.consistency.VERDICTS`.

    Returns
    -------
    str
        "consistent (NEES and NIS)" when both are consistent; "overconfident (NEES and
        NIS)" (or underconfident) when both fail the same way; otherwise the failures
        only, joined by ", ", e.g. "overconfident (NEES)" or
        "underconfident (NEES), overconfident (NIS)".
    """
    for v, name in ((nees_verdict, "nees_verdict"), (nis_verdict, "nis_verdict")):
        if not isinstance(v, str) or v not in VERDICTS:
            raise ValueError(f"{name}: a verdict must be one of {VERDICTS}, got {v!r}")
    if nees_verdict == nis_verdict:
        return f"{nees_verdict} (NEES and NIS)"
    return ", ".join(f"{v} ({name})" for v, name in ((nees_verdict, "NEES"), (nis_verdict, "NIS"))
                     if v != "consistent")


def sensitivity(excerpt, settings, config="kitti_lidar", lidar=None) -> list[SensitivityRow]:
    """Run the ESKF on a KITTI excerpt for each setting (label, q_factor, r_factor).

    Parameters
    ----------
    excerpt : KittiExcerpt
    settings : iterable of (str, float, float)
    config : EskfConfig or str
        The configuration the factors scale.
    lidar : LidarData, optional
        Pose observations (default: the excerpt's shipped draw).

    Returns
    -------
    list of SensitivityRow
        One per setting. The NEES uses the excerpt's ground truth (KITTI's, with its own
        small errors), which the filter never sees.
    """
    lidar = excerpt.lidar if lidar is None else lidar
    k0, s0 = excerpt.initial_state()
    lo, hi = metrics.chi2_bounds(6)
    rows = []
    for label, qf, rf in settings:
        res = eskf.run(excerpt.imu, s0, scaled_config(config, qf, rf), excerpt.gravity, lidar=lidar, start=k0)
        m = evaluate(res.t, res.position, res.rotation, excerpt.truth, res.P)
        nis = metrics.normalised_squared(np.array(res.innovation), np.array(res.S), "innovation", "S")
        band = average_band(m["nees"], 6)
        nis_v = verdict(nis, 6)
        rows.append(SensitivityRow(label, float(qf), float(rf), m["ape_position"], m["ape_attitude_deg"],
                                   m["nees_pose"], metrics.share_inside(m["nees"], lo, hi),
                                   float(np.mean(nis)), combined_verdict(band.verdict, nis_v),
                                   (band.lo, band.hi), band.verdict, metrics.chi2_bounds(6, len(nis)), nis_v))
    return rows


# ---------------------------------------------------------------------------------------
# Whiteness of the innovations over seeds
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class WhitenessRuns:
    """Output of :func:`whiteness_runs`: one whiteness test (and, for comparison, one NEES) per seed.

    Attributes
    ----------
    seeds : tuple of int
        The lidar-noise seeds.
    time_constant : float or None
        τ of the simulated Gauss–Markov lidar errors, s; None for white errors.
    tests : tuple of Whiteness
        :func:`~kalman_course.evaluation.consistency.innovation_whiteness` of each run.
    nees_pose : numpy.ndarray, shape (n_seeds,)
        Mean pose NEES of each run against the excerpt's ground truth.
    nees_verdicts : tuple of str
        Each run's mean pose NEES against its
        :func:`~kalman_course.evaluation.consistency.average_band`.
    nis : numpy.ndarray, shape (n_seeds,)
        Mean 6-dof NIS of each run.
    nis_verdicts : tuple of str
        Each run's NIS record, :func:`~kalman_course.evaluation.consistency.verdict` (the
        band of white innovations).
    """

    seeds: tuple
    time_constant: float | None
    tests: tuple
    nees_pose: np.ndarray
    nees_verdicts: tuple
    nis: np.ndarray
    nis_verdicts: tuple

    @property
    def n_white(self) -> int:
        """How many runs pass the whiteness test."""
        return sum(w.white for w in self.tests)

    @property
    def statistics(self) -> np.ndarray:
        """Ljung–Box statistic of each run, shape (n_seeds,)."""
        return np.array([w.statistic for w in self.tests])


def whiteness_runs(excerpt, seeds, time_constant: float | None = None, config="kitti_lidar", *,
                   max_lag: int = 10, confidence: float = 0.95) -> WhitenessRuns:
    """The ESKF on a KITTI excerpt with freshly simulated lidar poses, its innovations tested for whiteness.

    For each seed the lidar poses are the excerpt's true poses plus simulated errors of
    σ 0.2 m, 0.3° (the filter's R): white (``time_constant`` None) or first-order
    Gauss–Markov with time constant τ (:class:`~kalman_course.data.GaussMarkovErrors`),
    which the filter does not model. The IMU and the truth are KITTI's; the filter runs with
    ``config`` unchanged and never sees the truth. Its 6-dof innovations go to
    :func:`~kalman_course.evaluation.consistency.innovation_whiteness`.

    Parameters
    ----------
    excerpt : KittiExcerpt
    seeds : iterable of int
        One run per seed (``simulate_lidar_poses(excerpt.truth, seed, errors=...)``).
    time_constant : float or None
        τ of the lidar errors, s, or None for white errors.
    config : EskfConfig or str
    max_lag : int
        Largest lag tested, in lidar updates.
    confidence : float
        Confidence of the whiteness test.

    Returns
    -------
    WhitenessRuns
    """
    seeds = tuple(int(s) for s in seeds)
    if not seeds:
        raise ValueError("seeds must name at least one seed")
    errors = (WhiteErrors(0.2, 0.3) if time_constant is None
              else GaussMarkovErrors(0.2, 0.3, float(time_constant)))
    cfg = config if isinstance(config, EskfConfig) else load_config(config)
    k0, s0 = excerpt.initial_state()
    tests, nees, verdicts, nis_means, nis_verdicts = [], [], [], [], []
    for seed in seeds:
        lidar = simulate_lidar_poses(excerpt.truth, seed, errors=errors)
        res = eskf.run(excerpt.imu, s0, cfg, excerpt.gravity, lidar=lidar, start=k0)
        innovation, S = np.array(res.innovation), np.array(res.S)
        tests.append(innovation_whiteness(innovation, S, max_lag, confidence))
        m = evaluate(res.t, res.position, res.rotation, excerpt.truth, res.P)
        nees.append(m["nees_pose"])
        verdicts.append(average_band(m["nees"], 6).verdict)
        nis = metrics.normalised_squared(innovation, S, "innovation", "S")
        nis_means.append(float(np.mean(nis)))
        nis_verdicts.append(verdict(nis, 6))
    return WhitenessRuns(seeds, None if time_constant is None else float(time_constant), tuple(tests),
                         np.array(nees), tuple(verdicts), np.array(nis_means), tuple(nis_verdicts))


# ---------------------------------------------------------------------------------------
# Innovation gating
# ---------------------------------------------------------------------------------------

def inject_outliers(lidar, seed: int, n_bursts: int = 3, burst_length: int = 5, offset: float = 3.0,
                    yaw_deg: float = 3.0, skip: int = 20):
    """Turn a few bursts of lidar poses into map-matching failures.

    The observations are split after the first ``skip`` into ``n_bursts`` equal slots; in
    each, a burst of ``burst_length`` consecutive poses starts at a seeded position, and all
    its poses are moved by ``offset`` metres in one seeded horizontal direction and turned
    by ±``yaw_deg`` degrees about the vertical (as when the scan is matched to the wrong
    place of the map). Draws from ``default_rng(seed)``, in order: slot positions
    (n_bursts integers), directions (n_bursts angles), yaw signs (n_bursts).

    Returns
    -------
    lidar : LidarData
        A copy with the corrupted poses.
    outlier : numpy.ndarray of bool, shape (K,)
        True for each corrupted pose.
    """
    K = len(lidar.t)
    slot = (K - skip) // max(n_bursts, 1)
    if n_bursts < 1 or burst_length < 1 or slot < burst_length:
        raise ValueError(f"cannot place {n_bursts} bursts of {burst_length} in {K} poses after skipping {skip}")
    rng = np.random.default_rng(seed)
    starts = skip + slot * np.arange(n_bursts) + rng.integers(0, slot - burst_length + 1, size=n_bursts)
    angles = rng.uniform(0.0, 2.0 * np.pi, size=n_bursts)
    signs = rng.choice([-1.0, 1.0], size=n_bursts)
    position = np.array(lidar.position, dtype=float)
    rotation = np.array(lidar.rotation, dtype=float)
    outlier = np.zeros(K, dtype=bool)
    for s, a, sg in zip(starts, angles, signs):
        idx = np.arange(s, s + burst_length)
        outlier[idx] = True
        position[idx] += offset * np.array([np.cos(a), np.sin(a), 0.0])
        rotation[idx] = so3.exp(np.array([0.0, 0.0, sg * np.deg2rad(yaw_deg)])) @ rotation[idx]
    quaternion = so3.matrix_to_quat(rotation)
    return dataclasses.replace(lidar, position=position, quaternion=quaternion,
                               rotation=so3.quat_to_matrix(quaternion)), outlier


@dataclass(frozen=True)
class GatedRun:
    """Output of :func:`run_gated`.

    Attributes
    ----------
    result : eskf.EskfResult
        The filter, with a row at every lidar time inside the run (prior where rejected).
    t : numpy.ndarray, shape (K,)
        Times of the lidar poses inside the run.
    index : numpy.ndarray of int, shape (K,)
        Their index into the lidar record.
    accepted : numpy.ndarray of bool, shape (K,)
        Whether each pose was used.
    innovation : numpy.ndarray, shape (K, 6)
        Innovation of every pose against the filter's prior at its time.
    S : numpy.ndarray, shape (K, 6, 6)
        Its covariance.
    nis : numpy.ndarray, shape (K,)
    threshold : float
        The gate (inf for an ungated run).
    reruns : int
        How many batch runs the exact sequential decision took.
    """

    result: object
    t: np.ndarray
    index: np.ndarray
    accepted: np.ndarray
    innovation: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    threshold: float
    reruns: int


def run_gated(excerpt, lidar=None, config="kitti_lidar", confidence: float | None = 0.99) -> GatedRun:
    """Run the ESKF on an excerpt with lidar poses, rejecting those that fail the χ² gate.

    Each pose is tested against the filter's prior at its time, as a sequential gated
    filter would. The fast batch runner :func:`kalman_course.filters.eskf.run` has no gate, so the
    sequential decision is found by re-running it: start by accepting every pose, find the
    first pose whose gate decision disagrees with that choice, flip it (and the disagreeing
    poses right after it) and run again. A choice that agrees with every decision it leads
    to is the sequential filter's; the decisions up to the first flipped pose cannot change,
    so this ends after at most K runs, in practice one more than the number of bursts of
    rejected poses.

    Parameters
    ----------
    excerpt : KittiExcerpt
    lidar : LidarData, optional
        Poses (default: the excerpt's own); for example from :func:`inject_outliers`.
    config : EskfConfig or str
    confidence : float or None
        Gate confidence; None accepts every pose (the ungated filter).
    """
    lidar = excerpt.lidar if lidar is None else lidar
    cfg = config if isinstance(config, EskfConfig) else load_config(config)
    k0, s0 = excerpt.initial_state()
    t_imu = excerpt.imu.t
    lt = np.asarray(lidar.t, dtype=float)
    index = np.nonzero((lt > t_imu[k0]) & (lt <= t_imu[-1]))[0]
    times = lt[index]
    p_obs = np.asarray(lidar.position, dtype=float)[index]
    R_obs = np.asarray(lidar.rotation, dtype=float)[index]
    R_noise = np.diag(cfg.lidar_std ** 2)
    threshold = np.inf if confidence is None else gate_threshold(6, confidence)
    accepted = np.ones(len(index), dtype=bool)
    reruns = 0
    while True:
        used = PoseObservations(times[accepted], p_obs[accepted], R_obs[accepted])
        res = eskf.run(excerpt.imu, s0, cfg, excerpt.gravity, lidar=used, start=k0, output_times=times)
        reruns += 1
        rows = np.searchsorted(res.t, times - 1e-9)
        innovation = np.empty((len(index), 6))
        S = np.empty((len(index), 6, 6))
        if np.any(accepted):
            innovation[accepted] = np.array(res.innovation)
            S[accepted] = np.array(res.S)
        rej = np.nonzero(~accepted)[0]
        if rej.size:
            r = rows[rej]
            innovation[rej, 0:3] = res.position[r] - p_obs[rej]
            innovation[rej, 3:6] = so3.log(np.swapaxes(R_obs[rej], -1, -2) @ res.rotation[r])
            S[rej] = res.P[r][:, _POSE_IDX][:, :, _POSE_IDX] + R_noise
        nis = metrics.normalised_squared(innovation, S, "innovation", "S")
        wrong = (nis <= threshold) != accepted
        if not np.any(wrong):
            return GatedRun(res, times, index, accepted, innovation, S, nis, float(threshold), reruns)
        # flip the first disagreement (certainly right) and the ones right after it (a burst of
        # outliers, usually right too; any wrong guess is corrected by a later run)
        first = int(np.argmax(wrong))
        last = first
        while last + 1 < len(wrong) and wrong[last + 1]:
            last += 1
        accepted[first:last + 1] = ~accepted[first:last + 1]


# ---------------------------------------------------------------------------------------
# Numerical failures of the covariance update and their repair
# ---------------------------------------------------------------------------------------

def _float(value, name: str = "value") -> np.ndarray:
    """``value`` as an array of its own floating type (float32 stays float32), else float64;
    anything that holds no real numbers is a ValueError naming ``name``."""
    try:
        arr = np.asarray(value)
    except ValueError:                       # ragged nested sequences
        raise ValueError(f"{name} must be a real matrix, got a ragged sequence") from None
    if arr.dtype.kind not in "fiub" or arr.dtype.kind == "b":
        raise ValueError(f"{name} must be a real matrix, got {type(value).__name__} of dtype {arr.dtype}")
    return arr if np.issubdtype(arr.dtype, np.floating) else arr.astype(float)


def simple_update(P, K, G) -> np.ndarray:
    """The short form P̂ = (I − K G) P̌: right only for the optimal gain, and not symmetrised.

    Deliberately not :func:`kalman_course.core.linalg.short_update`, which symmetrises: the
    gallery shows what this form does on its own (an asymmetric P for a gain that is not
    proportional to P̌Gᵀ, and the round-off asymmetry of :func:`roundoff_experiment`).
    Computed in the inputs' floating type.

    Parameters
    ----------
    P : array_like, shape (n, n)
        Prior covariance P̌.
    K : array_like, shape (n, m)
        The gain used, optimal or not.
    G : array_like, shape (m, n)
        Observation Jacobian.

    Returns
    -------
    numpy.ndarray, shape (n, n)
    """
    P, K, G = _gallery_inputs(P, K, G)
    return (np.eye(P.shape[0], dtype=P.dtype) - K @ G) @ P


def joseph_update(P, K, G, R) -> np.ndarray:
    """Joseph form P̂ = (I − K G) P̌ (I − K G)ᵀ + K R Kᵀ: valid for any gain, PSD by construction.

    :func:`kalman_course.core.linalg.joseph_form` for array_like inputs, computed in the
    inputs' floating type and, like :func:`simple_update`, not symmetrised: the round-off
    experiment shows the small asymmetry it leaves (every filter of the course then calls
    :func:`symmetrise`, as :func:`kalman_course.core.linalg.joseph_update` does).

    Parameters
    ----------
    P : array_like, shape (n, n)
        Prior covariance P̌.
    K : array_like, shape (n, m)
        The gain used, optimal or not.
    G : array_like, shape (m, n)
        Observation Jacobian.
    R : array_like, shape (m, m)
        Observation noise covariance.

    Returns
    -------
    numpy.ndarray, shape (n, n)
    """
    P, K, G = _gallery_inputs(P, K, G)
    R = _float(R, "R")
    if R.shape == (G.shape[0], G.shape[0]) and not np.isfinite(R).all():
        raise ValueError("R must be finite, got NaN or inf")
    if R.shape == (G.shape[0], G.shape[0]):
        as_covariance(R, "R", G.shape[0], psd=True)
    if R.shape != (G.shape[0], G.shape[0]):
        raise ValueError(f"R must have shape ({G.shape[0]}, {G.shape[0]}) to match G, got {R.shape}")
    return linalg.joseph_form(P, K, G, R, I=np.eye(P.shape[0], dtype=P.dtype))


def _gallery_inputs(P, K, G) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """P (n, n), K (n, m), G (m, n) of matching shapes, in their floating type."""
    P, K, G = _float(P, "P"), _float(K, "K"), _float(G, "G")
    for arr, name in ((P, "P"), (K, "K"), (G, "G")):
        if arr.ndim != 2 or not np.isfinite(arr).all() or arr.size == 0:
            raise ValueError(f"{name} must be a finite, non-empty 2-D matrix, got shape {arr.shape}")
    n = P.shape[0]
    if P.shape != (n, n) or K.shape[0] != n or G.shape != (K.shape[1], n):
        raise ValueError(f"need P (n, n), K (n, m) and G (m, n); got P {P.shape}, K {K.shape}, G {G.shape}")
    return P, K, G


def symmetrise(P) -> np.ndarray:
    """½ (P + Pᵀ): removes the antisymmetric part that round-off or a wrong form left.

    :func:`kalman_course.core.linalg.symmetrise` (what every filter in the course calls),
    for any array_like square matrix; computed in its floating type.
    """
    P = _float(P, "P")
    if P.ndim != 2 or P.shape[0] != P.shape[1] or P.size == 0:
        raise ValueError(f"P must be a square matrix, got shape {P.shape}")
    if not np.isfinite(P).all():
        raise ValueError("P must be finite, got NaN or inf")
    return linalg.symmetrise(P)


def covariance_health(P) -> tuple[float, float]:
    """(asymmetry max|P − Pᵀ| / max|P|, smallest eigenvalue of the symmetric part ½(P + Pᵀ))."""
    P = _float(P, "P").astype(float)
    if P.ndim != 2 or P.shape[0] != P.shape[1] or P.size == 0:
        raise ValueError(f"P must be a square matrix, got shape {P.shape}")
    if not np.isfinite(P).all():
        raise ValueError("P must be finite, got NaN or inf")
    scale = max(float(np.max(np.abs(P))), 1e-300)
    return float(np.max(np.abs(P - P.T)) / scale), float(np.linalg.eigvalsh(symmetrise(P)).min())


def roundoff_experiment(dtype=np.float64, form: str = "simple", symmetric: bool = False, steps: int = 200,
                        T: float = 0.1, q: float = 1e-6, r: float = 1e-4, p0: float = 1e4) -> tuple[float, float]:
    """A 1-D constant-velocity filter with precise position fixes, computed in ``dtype``.

    A vague prior (variance ``p0``) meets fixes of variance ``r`` over ``steps`` steps with
    the optimal gain; the covariance update is ``form``: "simple" (:func:`simple_update`,
    not symmetrised) or "joseph" (:func:`joseph_update`, not symmetrised either), optionally
    followed by a symmetrisation, as every filter of the course does. Returns the worst
    asymmetry and the smallest eigenvalue seen (see :func:`covariance_health`); a negative
    eigenvalue means P lost positive definiteness.
    """
    try:
        dtype = np.dtype(dtype).type
    except TypeError:
        raise ValueError(f"dtype must be a floating type such as numpy.float32, got {dtype!r}") from None
    if not np.issubdtype(dtype, np.floating):
        raise ValueError(f"dtype must be a floating type such as numpy.float32, got {dtype!r}")
    if not isinstance(form, str) or form not in ("simple", "joseph"):
        raise ValueError(f"form must be 'simple' or 'joseph', got {form!r}")
    symmetric = as_flag(symmetric, "symmetric")
    steps = as_int(steps, "steps", minimum=1)
    T, r, p0 = as_scalar(T, "T"), as_scalar(r, "r"), as_scalar(p0, "p0")
    q = as_scalar(q, "q", allow_zero=True)
    F = np.array([[1.0, T], [0.0, 1.0]], dtype=dtype)
    Q = (q * np.array([[T ** 3 / 3, T ** 2 / 2], [T ** 2 / 2, T]])).astype(dtype)
    G = np.array([[1.0, 0.0]], dtype=dtype)
    R = np.array([[r]], dtype=dtype)
    P = np.diag([p0, p0]).astype(dtype)
    worst_asym, worst_eig = 0.0, np.inf
    for _ in range(steps):
        # not core.linalg.predict_covariance: it symmetrises P̌, which would hide what the
        # unsymmetrised short form does to P (the point of the experiment)
        P = F @ P @ F.T + Q
        # K = P̌ Gᵀ S⁻¹. The kernel reads P̌ Gᵀ as (G P̌)ᵀ, true for a symmetric P̌; after an
        # unsymmetrised short-form update P̌ is not symmetric, so hand it G P̌ᵀ = (P̌ Gᵀ)ᵀ
        K = linalg.gain(G @ P.T, linalg.innovation_covariance(G @ P, G, R))
        P = simple_update(P, K, G) if form == "simple" else joseph_update(P, K, G, R)
        if symmetric:
            P = symmetrise(P)
        asym, eig = covariance_health(P.astype(float))
        worst_asym, worst_eig = max(worst_asym, asym), min(worst_eig, eig)
    return worst_asym, worst_eig
