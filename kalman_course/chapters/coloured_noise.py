"""Coloured observation noise and three remedies, measured side by side (chapter 10).

The lidar-ESKF of chapter 08 assumes that each lidar pose's error is white, and the
shipped poses are simulated that way, with exactly the filter's R. A real map-matching
error drifts slowly. Here the poses are simulated from the real KITTI ground truth with
errors of the same size per component (the filter's σ: 0.2 m, 0.3°) but correlated in
time, a first-order Gauss–Markov process with time constant τ
(:class:`kalman_course.data.GaussMarkovErrors`; τ = 0 means white), and four filters
fuse them with the real KITTI IMU:

``plain``
    The chapter-08 ESKF, R unchanged: it treats ten nearly equal errors per second as ten
    independent ones, so it trusts their average far too much.
``inflated_R``
    The same filter with R multiplied by k = (1 + φ)/(1 − φ), φ = exp(−Δt/τ), Δt the
    interval between the poses it uses (0.104 s here). The mean of N ≫ τ/Δt successive
    Gauss–Markov errors has variance σ²/N · (1 + φ)/(1 − φ), not σ²/N; with R × k the
    information the filter takes from a long stretch of poses is right. Over stretches
    shorter than the correlation time it over-inflates (the filter becomes underconfident).
``fewer_observations``
    The plain filter, R unchanged, given one pose per 2τ (every m-th, m = round(2τ/Δt)):
    successive errors then correlate by exp(−mΔt/τ) ≈ e⁻² = 0.14 only. It predicts with
    the IMU between poses; it is evaluated at every pose time like the others.
``augmented``
    :mod:`kalman_course.filters.eskf_augmented`: six Gauss–Markov states for the error,
    with the τ and σ that generated it (the favourable case of a known error model).

Each runs on the same excerpt, for every τ, with several lidar seeds (the same seed draws
the same standard normals for every τ, so the τ's are compared on paired draws). Scores
(:func:`kalman_course.evaluation.pose.evaluate`, at every pose time after the start):
position and attitude APE, their ratio to the raw poses' APE of the same draw, and the mean
6-dof pose NEES. Each is reported by its median and range over the seeds
(:mod:`kalman_course.evaluation.spread`).

The consistency verdict is taken at each pose time, where the χ² interval holds: the NEES
averaged over the n_seeds runs at one time (independent draws of the lidar errors) lies in
``metrics.chi2_bounds(6, n_seeds)`` with probability 95 % for a consistent filter, 2.5 % on
either side. The share of pose times below and above that interval is counted; a share
above :data:`VERDICT_SHARE` (10 %, four times the 2.5 % expected, a margin for successive
times being correlated) on one side is the verdict. The mean over seeds *and* time is not
judged against that interval: a time average of correlated values has no χ² interval of its
own, and it varies less than one time's value, so the interval would pass filters that are
off. (The seeds share the real IMU, so they are independent only in their lidar errors.) At
τ = 0 every remedy is the plain filter (k = 1, m = 1, no augmentation) and all four rows
agree.

What is real: the KITTI IMU (100 Hz) and ground truth. What is simulated: the lidar
pose errors.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from kalman_course.chapters.eskf_sources import REAL_INPUTS
from kalman_course.core.validation import as_scalar, as_seeds
from kalman_course.data import GaussMarkovErrors, WhiteErrors, load_kitti, simulate_lidar_poses
from kalman_course.evaluation import metrics
from kalman_course.evaluation.pose import evaluate
from kalman_course.evaluation.spread import Spread, spread
from kalman_course.filters import eskf, eskf_augmented
from kalman_course.filters.eskf_config import EskfConfig, load_config

__all__ = ["REMEDIES", "VERDICT_SHARE", "ColouredNoiseResult", "coloured_noise", "inflation_factor", "decimation_step",
           "remedy_label"]

#: The four filters compared, in table order.
REMEDIES = ("plain", "inflated_R", "fewer_observations", "augmented")

#: The share of pose times outside the 95 % interval, on one side, above which a filter is
#: called over- or underconfident: four times the 2.5 % of a consistent filter.
VERDICT_SHARE = 0.10

#: Poses kept per time constant by ``fewer_observations``: one per this many τ.
_DECIMATION_SPAN = 2.0


def inflation_factor(time_constant: float, interval: float) -> float:
    """k = (1 + φ)/(1 − φ), φ = exp(−Δt/τ): the variance factor of a long average of correlated errors.

    Parameters
    ----------
    time_constant : float
        τ of the Gauss–Markov error, s (≥ 0; 0 means white, k = 1).
    interval : float
        Δt between the observations the filter uses, s (> 0).

    Returns
    -------
    float
        k ≥ 1; R × k makes N ≫ τ/Δt observations carry the information their mean has.
    """
    tau = as_scalar(time_constant, "time_constant", allow_zero=True)
    dt = as_scalar(interval, "interval")
    if tau == 0.0:
        return 1.0
    phi = eskf_augmented.gauss_markov_decay(dt, tau)
    return (1.0 + phi) / (1.0 - phi)


def decimation_step(time_constant: float, interval: float) -> int:
    """m = max(1, round(2τ/Δt)): keep every m-th observation, about one per 2τ.

    Parameters
    ----------
    time_constant : float
        τ, s (≥ 0; 0 gives m = 1).
    interval : float
        Δt between successive observations, s (> 0).
    """
    tau = as_scalar(time_constant, "time_constant", allow_zero=True)
    dt = as_scalar(interval, "interval")
    return max(1, int(round(_DECIMATION_SPAN * tau / dt)))


def remedy_label(remedy: str, time_constant: float, interval: float) -> str:
    """A short label of a remedy at τ, e.g. ``"R × 9.7"`` or ``"1 pose in 10 (1.04 s)"``.

    Raises
    ------
    ValueError
        If ``remedy`` is not one of :data:`REMEDIES`.
    """
    remedy = _as_remedy(remedy)
    if remedy == "plain":
        return "plain ESKF (white R)"
    if remedy == "inflated_R":
        return f"R × {inflation_factor(time_constant, interval):.3g}"
    if remedy == "fewer_observations":
        m = decimation_step(time_constant, interval)
        return "every pose" if m == 1 else f"1 pose in {m} ({m * interval:.2f} s)"
    return "not augmented (τ = 0)" if time_constant == 0 else "augmented with GM error"


def _as_remedy(remedy) -> str:
    if remedy not in REMEDIES:
        raise ValueError(f"remedy must be one of {', '.join(REMEDIES)}, got {remedy!r}")
    return remedy


# ---------------------------------------------------------------------------------------
# Result
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ColouredNoiseResult:
    """Scores of the four filters for every time constant and seed on one KITTI excerpt.

    Attributes
    ----------
    excerpt : str
        KITTI excerpt name (real IMU and ground truth).
    duration : float
        Its length, s.
    time_constants : tuple of float
        τ of the simulated lidar error, s (0 = white), length T.
    remedies : tuple of str
        The filters, a subset of :data:`REMEDIES` in that order, length M.
    seeds : tuple of int
        Seeds of the simulated lidar errors, length S.
    sigma_position : float
        σ of each simulated position-error component, m (the filter's R).
    sigma_attitude_deg : float
        σ of each simulated attitude-error component, degrees (the filter's R).
    interval : float
        Median interval Δt between lidar poses, s.
    raw_position, raw_attitude_deg : numpy.ndarray, shape (T, S)
        APE of the raw simulated poses: m, degrees.
    ape_position, ape_attitude_deg : numpy.ndarray, shape (T, M, S)
        APE of each filter: m, degrees.
    nees_pose : numpy.ndarray, shape (T, M, S)
        Each run's time-mean 6-dof pose NEES.
    nees_series : numpy.ndarray, shape (T, M, S, K)
        Each run's 6-dof pose NEES at each of the K pose times (the same times for every run).
    nees_band : (float, float)
        ``metrics.chi2_bounds(6, S)``: 95 % interval of the NEES averaged over the S seeds at
        one time.
    runtime : float
        Wall time of the experiment, s.
    """

    excerpt: str
    duration: float
    time_constants: tuple
    remedies: tuple
    seeds: tuple
    sigma_position: float
    sigma_attitude_deg: float
    interval: float
    raw_position: np.ndarray
    raw_attitude_deg: np.ndarray
    ape_position: np.ndarray
    ape_attitude_deg: np.ndarray
    nees_pose: np.ndarray
    nees_series: np.ndarray
    nees_band: tuple
    runtime: float

    @property
    def position_ratio(self) -> np.ndarray:
        """ESKF / raw position APE of the same draw, shape (T, M, S)."""
        return self.ape_position / self.raw_position[:, None, :]

    @property
    def attitude_ratio(self) -> np.ndarray:
        """ESKF / raw attitude APE of the same draw, shape (T, M, S)."""
        return self.ape_attitude_deg / self.raw_attitude_deg[:, None, :]

    @property
    def nees_mean(self) -> np.ndarray:
        """Pose NEES averaged over seeds and time, shape (T, M)."""
        return self.nees_pose.mean(axis=-1)

    @property
    def band_shares(self) -> np.ndarray:
        """Shares of the pose times at which the seed-averaged NEES lies below and above
        :attr:`nees_band`, shape (T, M, 2); a consistent filter's are 0.025 each."""
        lo, hi = self.nees_band
        averaged = self.nees_series.mean(axis=2)
        return np.stack([(averaged < lo).mean(axis=-1), (averaged > hi).mean(axis=-1)], axis=-1)

    def spread(self, figure: str, time_constant: float, remedy: str) -> Spread:
        """Median and range over the seeds of one figure for one τ and remedy.

        Parameters
        ----------
        figure : str
            ``"ape_position"``, ``"ape_attitude_deg"``, ``"position_ratio"``,
            ``"attitude_ratio"`` or ``"nees_pose"``.
        time_constant : float
            One of :attr:`time_constants`, s.
        remedy : str
            One of :attr:`remedies`.
        """
        figures = ("ape_position", "ape_attitude_deg", "position_ratio", "attitude_ratio", "nees_pose")
        if figure not in figures:
            raise ValueError(f"figure must be one of {', '.join(figures)}, got {figure!r}")
        return spread(getattr(self, figure)[self._tau_index(time_constant), self._remedy_index(remedy)], figure)

    def verdict(self, time_constant: float, remedy: str) -> str:
        """"consistent", "overconfident" or "underconfident": whether more than
        :data:`VERDICT_SHARE` of the pose times have the seed-averaged NEES above (or below)
        :attr:`nees_band` (the larger share decides if both do)."""
        below, above = self.band_shares[self._tau_index(time_constant), self._remedy_index(remedy)]
        if max(below, above) <= VERDICT_SHARE:
            return "consistent"
        return "overconfident" if above >= below else "underconfident"

    def _tau_index(self, time_constant) -> int:
        matches = [i for i, tau in enumerate(self.time_constants) if np.isclose(tau, time_constant)]
        if not matches:
            raise ValueError(f"time_constant must be one of {self.time_constants}, got {time_constant!r}")
        return matches[0]

    def _remedy_index(self, remedy) -> int:
        if remedy not in self.remedies:
            raise ValueError(f"remedy must be one of {', '.join(self.remedies)}, got {remedy!r}")
        return self.remedies.index(remedy)

    def table(self, timings: bool = False) -> str:
        """A fixed-width table: per τ, the raw poses and each filter, median (min–max) over the seeds.

        ``timings`` adds the wall-clock run time (left out by default: it differs from run to
        run, and a lecture's stored output must not)."""
        lo, hi = self.nees_band
        n = len(self.seeds)
        seeds = ", ".join(str(s) for s in self.seeds)
        lines = [
            f"Coloured lidar errors, KITTI excerpt '{self.excerpt}' ({self.duration:.0f} s), {n} seeds ({seeds}): "
            f"median (min–max) over the seeds",
            f"inputs: {REAL_INPUTS}; simulated: the lidar pose errors, first-order Gauss–Markov per component "
            f"(σ {self.sigma_position:g} m / {self.sigma_attitude_deg:g}°, the filter's R; τ = 0: white), "
            f"poses every {self.interval:.3f} s",
            f"pose NEES: per seed its mean over time, and the mean over seeds and time; verdict at each pose "
            f"time: the NEES averaged over the {n} seeds against the 95 % interval of an average of {n} χ²(6) "
            f"values [{lo:.2f}, {hi:.2f}] (metrics.chi2_bounds(6, {n})); 'below / above' are the shares of "
            f"times outside it (2.5 % / 2.5 % if consistent), a share over {VERDICT_SHARE * 100:g} % decides",
            "",
            f"{'τ [s]':>5s}  {'filter':26s} {'position APE [m]':>21s} {'ESKF/raw position':>21s} "
            f"{'ESKF/raw attitude':>21s} {'pose NEES per seed':>23s} {'mean':>6s} {'below / above':>14s}  verdict",
        ]
        for i, tau in enumerate(self.time_constants):
            raw = spread(self.raw_position[i], "raw_position")
            lines.append(f"{tau:5g}  {'raw simulated poses':26s} {raw.text('.3f'):>21s}")
            for j, remedy in enumerate(self.remedies):
                label = remedy_label(remedy, tau, self.interval)
                ape = self.spread("ape_position", tau, remedy).text(".3f")
                rp = self.spread("position_ratio", tau, remedy).text(".2f")
                ra = self.spread("attitude_ratio", tau, remedy).text(".2f")
                nees = self.spread("nees_pose", tau, remedy).text(".1f")
                below, above = self.band_shares[i, j]
                shares = f"{below * 100:.0f} % / {above * 100:.0f} %"
                lines.append(f"{'':5s}  {label:26s} {ape:>21s} {rp:>21s} {ra:>21s} {nees:>23s} "
                             f"{self.nees_mean[i, j]:6.1f} {shares:>14s}  {self.verdict(tau, remedy)}")
        if timings:
            lines.append(f"runtime {self.runtime:.1f} s")
        return "\n".join(lines)


# ---------------------------------------------------------------------------------------
# Experiment
# ---------------------------------------------------------------------------------------

def _as_excerpt(excerpt):
    if isinstance(excerpt, str):
        return load_kitti(excerpt)
    for attr in ("imu", "truth", "gravity", "initial_state"):
        if not hasattr(excerpt, attr):
            raise ValueError(f"excerpt must be a KITTI excerpt name or a KittiExcerpt (imu, truth, gravity, "
                             f"initial_state); missing {attr!r}")
    return excerpt


def _as_time_constants(values) -> tuple:
    try:
        taus = tuple(as_scalar(v, "time_constants", allow_zero=True) for v in values)
    except TypeError:
        raise ValueError(f"time_constants must be a sequence of times ≥ 0 s, got {values!r}") from None
    if not taus:
        raise ValueError("time_constants must hold at least one time constant")
    if len(set(taus)) != len(taus):
        raise ValueError(f"time_constants must not repeat a value, got {taus}")
    return taus


def _as_remedies(values) -> tuple:
    if isinstance(values, str):
        values = (values,)
    chosen = {_as_remedy(v) for v in values}
    if not chosen:
        raise ValueError(f"remedies must name at least one of {', '.join(REMEDIES)}")
    return tuple(r for r in REMEDIES if r in chosen)


def _error_model(sigma_position: float, sigma_attitude_deg: float, time_constant: float):
    if time_constant == 0.0:
        return WhiteErrors(sigma_position, sigma_attitude_deg)
    return GaussMarkovErrors(sigma_position, sigma_attitude_deg, time_constant)


def _run_remedy(remedy: str, ex, k0, s0, cfg: EskfConfig, lidar, tau: float, interval: float, t_eval):
    """One filter run, returned at the evaluation times ``t_eval``."""
    if remedy == "augmented":
        res = eskf_augmented.run(ex.imu, s0, cfg, ex.gravity, lidar=lidar, start=k0, output_times=t_eval,
                                 time_constant=tau if tau > 0.0 else None)
        return res.at(t_eval)
    if remedy == "inflated_R":
        k = np.sqrt(inflation_factor(tau, interval))
        std = cfg.lidar_std
        cfg = cfg.replace(observation__lidar_position=std[0] * k, observation__lidar_attitude=std[3] * k)
    elif remedy == "fewer_observations":
        m = decimation_step(tau, interval)
        lidar = lidar.select(np.arange(len(lidar)) % m == 0)
    return eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=lidar, start=k0, output_times=t_eval).at(t_eval)


def coloured_noise(excerpt="cruise", time_constants=(0.0, 0.5, 1.0, 3.0), seeds=(1, 2, 3, 4, 5), *,
                   config="kitti_lidar", remedies=REMEDIES) -> ColouredNoiseResult:
    """Run the four filters on simulated Gauss–Markov lidar errors of each time constant and seed.

    The lidar poses are ``simulate_lidar_poses(ex.truth, seed, errors=...)`` with the
    configuration's lidar σ (so only the correlation differs from the filter's model) and
    the filters start from the true state (``ex.initial_state()``). All four are scored at
    every pose time after the start, against the real ground truth.

    Parameters
    ----------
    excerpt : str or KittiExcerpt
        "cruise" (30 s, default), "turns", "stop_go"; the whole "seq00" works but is slow.
    time_constants : sequence of float
        τ of the simulated error, s (≥ 0, distinct; 0 = white).
    seeds : sequence of int
        Seeds of the lidar errors (non-negative, at least one).
    config : EskfConfig or str
        The filter's settings; its lidar σ is the simulated errors' σ too.
    remedies : sequence of str
        Which of :data:`REMEDIES` to run (kept in that order).

    Returns
    -------
    ColouredNoiseResult

    Raises
    ------
    ValueError
        For an unknown excerpt or remedy, a negative or repeated time constant, a bad seed,
        or no seeds.
    """
    start = time.perf_counter()
    ex = _as_excerpt(excerpt)
    taus = _as_time_constants(time_constants)
    seeds = as_seeds(seeds)
    remedies = _as_remedies(remedies)
    cfg = config if isinstance(config, EskfConfig) else load_config(config)
    sigma_p, sigma_deg = float(cfg.lidar_std[0]), float(np.rad2deg(cfg.lidar_std[3]))
    k0, s0 = ex.initial_state()
    interval = float(np.median(np.diff(ex.truth.t)))

    T, M, S = len(taus), len(remedies), len(seeds)
    raw_p, raw_a = np.empty((T, S)), np.empty((T, S))
    ape_p, ape_a, nees = np.empty((T, M, S)), np.empty((T, M, S)), np.empty((T, M, S))
    series = None                  # the NEES at every pose time, (T, M, S, K): the same times for every run
    for i, tau in enumerate(taus):
        errors = _error_model(sigma_p, sigma_deg, tau)
        for s, seed in enumerate(seeds):
            lidar = simulate_lidar_poses(ex.truth, seed, errors=errors)
            used = (lidar.t > ex.imu.t[k0]) & (lidar.t <= ex.imu.t[-1])
            t_eval = lidar.t[used]
            raw = evaluate(t_eval, lidar.position[used], lidar.rotation[used], ex.truth)
            raw_p[i, s], raw_a[i, s] = raw["ape_position"], raw["ape_attitude_deg"]
            for j, remedy in enumerate(remedies):
                res = _run_remedy(remedy, ex, k0, s0, cfg, lidar, tau, interval, t_eval)
                m = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
                ape_p[i, j, s], ape_a[i, j, s], nees[i, j, s] = (m["ape_position"], m["ape_attitude_deg"],
                                                                  m["nees_pose"])
                if series is None:
                    series = np.empty((T, M, S, len(m["nees"])))
                series[i, j, s] = m["nees"]
    return ColouredNoiseResult(
        excerpt=getattr(ex, "name", str(excerpt)), duration=float(ex.truth.t[-1] - ex.truth.t[0]),
        time_constants=taus, remedies=remedies, seeds=seeds, sigma_position=sigma_p,
        sigma_attitude_deg=sigma_deg, interval=interval, raw_position=raw_p, raw_attitude_deg=raw_a,
        ape_position=ape_p, ape_attitude_deg=ape_a, nees_pose=nees, nees_series=series,
        nees_band=metrics.chi2_bounds(6, S),
        runtime=time.perf_counter() - start)
