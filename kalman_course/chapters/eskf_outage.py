"""A GNSS outage in the chapter-08 ESKF: how far the filter drifts, and why (chapter 08).

The GNSS-aided ESKF of lecture 08 starts at the true state, takes 1 Hz fixes (the recorded
INS positions plus simulated white noise, σ 1 m) and then loses them for a while. During the
outage it dead-reckons from whatever state the fixes left it in. :func:`outage_study`
measures that drift against the IMU alone integrated from the truth, and attributes it:

- the filter's horizontal error at the end of the outage, and the IMU alone (the same
  mechanisation, no observations) from the true state at the run's start and at the
  outage's start;
- the filter's attitude error at the outage start, split into heading and tilt
  (:func:`kalman_course.evaluation.attitude.heading_tilt_error`), with its own σ of each,
  next to the attitude error of the IMU alone from the truth over the same time;
- its velocity error and gyro-bias estimate there;
- "swaps": the IMU alone from the true state at the outage start with one part of it
  (position, velocity, attitude, accelerometer or gyro bias) replaced by the filter's, so
  each part's share of the drift is measured, not guessed.

:func:`outage_seed_errors` repeats the filter's part over several GNSS noise seeds.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_seed
from kalman_course.data import simulate_gnss
from kalman_course.evaluation.attitude import heading_tilt_error
from kalman_course.evaluation.spread import Spread, spread
from kalman_course.filters import eskf
from kalman_course.filters.eskf import NominalState

__all__ = ["OutageStudy", "outage_study", "outage_seed_errors", "SWAP_FIELDS"]

#: The parts of the nominal state the swaps replace, in the order reported.
SWAP_FIELDS = ("position", "velocity", "rotation", "accel_bias", "gyro_bias")

_RAD_PER_S_TO_DEG_PER_H = float(np.rad2deg(1.0) * 3600.0)


@dataclass(frozen=True)
class OutageStudy:
    """What a GNSS outage did to the ESKF, measured against the truth.

    Attributes
    ----------
    outage : (float, float)
        (t0, t1), s: no fix is used with t0 <= t <= t1.
    t_start : float
        First IMU sample at or after t0, s: where the outage starts.
    t_end : float
        Last truth time at or before t1, s: where the errors "at the end" are taken.
    filter_error : float
        The filter's horizontal position error at ``t_end``, m.
    filter_peak : float
        Its largest horizontal error at the truth times inside the outage, m.
    imu_from_run_start, imu_from_outage_start : float
        Horizontal error at ``t_end``, m, of the IMU alone (no observations, zero biases)
        integrated from the true state at the filter's start and at ``t_start``.
    heading_deg, tilt_deg : float
        The filter's attitude error at ``t_start``: heading (signed) and tilt, degrees.
    heading_sigma_deg, tilt_sigma_deg : float
        The filter's σ of them there: sqrt of the up entry, and of the trace of the
        horizontal block, of R P_θθ Rᵀ, degrees.
    imu_heading_deg, imu_tilt_deg : float
        The attitude error at ``t_start`` of the IMU alone from the truth at the run's start.
    velocity_error : float
        |v̂ − v_true| of the filter at ``t_start``, m/s.
    gyro_bias_deg_h, gyro_bias_sigma_deg_h : numpy.ndarray, shape (3,)
        The filter's gyro-bias estimate at ``t_start`` and its σ, °/h.
    swapped : dict of str to float
        For each of :data:`SWAP_FIELDS`: horizontal error at ``t_end``, m, of the IMU alone
        from the true state at ``t_start`` with only that field taken from the filter.
    """

    outage: tuple
    t_start: float
    t_end: float
    filter_error: float
    filter_peak: float
    imu_from_run_start: float
    imu_from_outage_start: float
    heading_deg: float
    tilt_deg: float
    heading_sigma_deg: float
    tilt_sigma_deg: float
    imu_heading_deg: float
    imu_tilt_deg: float
    velocity_error: float
    gyro_bias_deg_h: np.ndarray
    gyro_bias_sigma_deg_h: np.ndarray
    swapped: dict


def _outage(ex, outage) -> tuple[float, float]:
    try:
        t0, t1 = (float(v) for v in outage)
    except (TypeError, ValueError):
        raise ValueError(f"outage must be (t0, t1) in s, got {outage!r}") from None
    lo, hi = float(ex.truth.t[0]), float(ex.truth.t[-1])
    if not (lo < t0 < t1 <= hi):
        raise ValueError(f"outage must satisfy {lo:.3f} < t0 < t1 <= {hi:.3f} s (inside the excerpt's truth), "
                         f"got ({t0}, {t1})")
    return t0, t1


def _fixes_outside(gnss, t0: float, t1: float):
    fixes = gnss.observations()
    return fixes.select((fixes.t < t0) | (fixes.t > t1))


def _horizontal_error_at(res, truth, t: float) -> float:
    """|p̂ − p_true| in the horizontal plane at the row of ``res`` at time ``t`` (a truth time), m."""
    i = int(np.argmin(np.abs(res.t - t)))
    k = int(np.argmin(np.abs(truth.t - t)))
    return float(np.linalg.norm(res.position[i, :2] - truth.position[k, :2]))


def _imu_alone(ex, state, k: int, config, t_end: float) -> float:
    """Horizontal error at ``t_end`` of the IMU integrated from ``state`` at ``imu.t[k]``, m.

    The timeline has a node at every truth time, as the filter's run has, so that the IMU is
    integrated in the same steps as inside the filter.
    """
    t = ex.truth.t
    res = eskf.run(ex.imu, state, config, ex.gravity, start=k, output_times=t[(t > ex.imu.t[k]) & (t <= t_end)])
    return _horizontal_error_at(res, ex.truth, t_end)


def _filter_through(ex, config, gnss, t0: float, t1: float):
    """The GNSS-aided ESKF from the true state with the fixes of (t0, t1) removed.

    Returns the run at the truth times and at the outage start (the timeline nodes are the
    same whatever is read from it), the outage start and the time of its end.
    """
    truth = ex.truth
    k0, s0 = ex.initial_state()
    t_start = float(ex.imu.t[np.searchsorted(ex.imu.t, t0, side="left")])
    t_end = float(truth.t[np.searchsorted(truth.t, t1, side="right") - 1])
    times = np.union1d(truth.t, [t_start])
    res = eskf.run(ex.imu, s0, config, ex.gravity, gnss=_fixes_outside(gnss, t0, t1), start=k0,
                   output_times=times, clip_output_times=True).at(times)
    return res, t_start, t_end


def outage_study(ex, config, outage, gnss=None) -> OutageStudy:
    """Run the GNSS-aided ESKF through an outage and attribute its drift.

    Parameters
    ----------
    ex : KittiExcerpt
        Real IMU and truth (for example ``load_kitti("turns")``); the filter starts from the
        true state (``ex.initial_state()``).
    config : EskfConfig or str
        The GNSS filter's settings (for example ``"kitti_gnss"``).
    outage : (float, float)
        (t0, t1), s, inside the excerpt.
    gnss : GnssData, optional
        The fixes (default ``ex.gnss``, the shipped simulated-noise draw).

    Returns
    -------
    OutageStudy

    Raises
    ------
    ValueError
        If the outage does not lie inside the excerpt's truth.
    """
    t0, t1 = _outage(ex, outage)
    truth = ex.truth
    k0, s0 = ex.initial_state()
    res, t_start, t_end = _filter_through(ex, config, ex.gnss if gnss is None else gnss, t0, t1)
    k_out = int(np.searchsorted(ex.imu.t, t_start, side="left"))
    inside = (truth.t >= t0) & (truth.t <= t1)
    at_truth = res.at(truth.t[inside])
    peak = float(np.max(np.linalg.norm(at_truth.position[:, :2] - truth.position[inside, :2], axis=1)))

    i = int(np.argmin(np.abs(res.t - t_start)))
    filt = NominalState(res.position[i], res.velocity[i], res.rotation[i], res.accel_bias[i], res.gyro_bias[i])
    true_start = truth.state_at(t_start)
    true_nominal = NominalState.from_nav(true_start)
    heading, tilt = heading_tilt_error(filt.rotation, true_start.rotation)
    P_nav = filt.rotation @ res.P[i][6:9, 6:9] @ filt.rotation.T
    sd = np.sqrt(np.diag(res.P[i]))

    alone = eskf.run(ex.imu, s0, config, ex.gravity, start=k0, output_times=[t_start])
    imu_heading, imu_tilt = heading_tilt_error(alone.rotation[-1], true_start.rotation)

    swapped = {name: _imu_alone(ex, dataclasses.replace(true_nominal, **{name: getattr(filt, name)}), k_out,
                                config, t_end)
               for name in SWAP_FIELDS}
    return OutageStudy(
        outage=(t0, t1), t_start=t_start, t_end=t_end,
        filter_error=_horizontal_error_at(res, truth, t_end), filter_peak=peak,
        imu_from_run_start=_imu_alone(ex, s0, k0, config, t_end),
        imu_from_outage_start=_imu_alone(ex, true_nominal, k_out, config, t_end),
        heading_deg=float(heading), tilt_deg=float(tilt),
        heading_sigma_deg=float(np.rad2deg(np.sqrt(P_nav[2, 2]))),
        tilt_sigma_deg=float(np.rad2deg(np.sqrt(P_nav[0, 0] + P_nav[1, 1]))),
        imu_heading_deg=float(imu_heading), imu_tilt_deg=float(imu_tilt),
        velocity_error=float(np.linalg.norm(filt.velocity - true_start.velocity)),
        gyro_bias_deg_h=filt.gyro_bias * _RAD_PER_S_TO_DEG_PER_H,
        gyro_bias_sigma_deg_h=sd[12:15] * _RAD_PER_S_TO_DEG_PER_H,
        swapped=swapped)


def outage_seed_errors(ex, config, outage, seeds) -> dict:
    """The filter's state at the outage start and its error at the end, over GNSS noise seeds.

    Each seed draws new simulated noise on the recorded positions
    (``simulate_gnss(ex.gnss, seed, ex.gnss.sigma)``); IMU and truth stay the real ones.

    Parameters
    ----------
    ex : KittiExcerpt
    config : EskfConfig or str
    outage : (float, float)
        (t0, t1), s.
    seeds : iterable of int
        At least one.

    Returns
    -------
    dict of str to Spread
        ``"filter_error"`` (m, at the end), ``"heading_deg"`` (absolute) and ``"tilt_deg"``
        (at the start), each over the seeds.

    Raises
    ------
    ValueError
        If ``seeds`` is empty or the outage does not lie inside the excerpt.
    """
    t0, t1 = _outage(ex, outage)
    seeds = [as_seed(s) for s in seeds]
    if not seeds:
        raise ValueError("seeds must hold at least one seed")
    errors, headings, tilts = [], [], []
    for seed in seeds:
        res, t_start, t_end = _filter_through(ex, config, simulate_gnss(ex.gnss, seed, ex.gnss.sigma), t0, t1)
        i = int(np.argmin(np.abs(res.t - t_start)))
        heading, tilt = heading_tilt_error(res.rotation[i], ex.truth.state_at(t_start).rotation)
        headings.append(abs(float(heading)))
        tilts.append(float(tilt))
        errors.append(_horizontal_error_at(res, ex.truth, t_end))
    return {"filter_error": spread(errors, "filter_error"), "heading_deg": spread(headings, "heading_deg"),
            "tilt_deg": spread(tilts, "tilt_deg")}
