"""Chapter 10 (real sensors): when the bias model matters, and how big Earth rotation is.

On the real KITTI IMU (a tactical-grade OXTS unit) the seed homework's comparison —
ESKF with a random-walk bias against a constant bias — says nothing: the biases are near
zero and a filter with them frozen does as well. Here the same comparison runs on an IMU
whose biases drift: :func:`kalman_course.data.mems_imu.simulate_mems_imu`, the KITTI motion
read by a simulated consumer-grade MEMS IMU.

What is real and what is simulated, in every run and table of this module:

- the motion is KITTI's (real ground truth, smoothed; the smoothed motion is the truth
  the filters are scored against);
- the IMU readings' errors (turn-on bias, a first-order Gauss–Markov bias drift, white
  noise) are simulated from a :class:`~kalman_course.data.mems_imu.MemsSpec` in
  datasheet units;
- the observations are simulated: lidar map-matching poses (10 Hz, σ 0.2 m / 0.3°, white)
  or GNSS fixes (1 Hz, σ 1 m, white), drawn from the smoothed truth.

Three filters, all started at the true state with the spec's turn-on bias as the bias
prior (:func:`config_for_spec`). None of them has the model that generated the data (a
Gauss–Markov drift of stationary σ_b and correlation time τ):

- ``random walk``: ``bias_model="random_walk"`` with the spec's densities; its bias
  density q = σ_b √(2/τ) is the random walk that the drift looks like over times ≪ τ,
  but its spread grows as q √t where the drift's levels off at σ_b;
- ``constant``: ``bias_model="constant"``, the same prior; its bias σ only shrinks;
- ``frozen at 0``: the constant model with a zero bias prior, so the biases stay at 0
  (what one gets by not estimating them at all).

:func:`compare_bias_models` runs them over several seeds and reports medians and ranges;
:func:`earth_rotation` and :func:`earth_rotation_table` state the size of the Earth's
rotation at KITTI's latitude against the spec's bias and the filter's bias σ.

What it shows (``compare_bias_models(name).table()`` prints the numbers): freezing the
biases costs an order of magnitude in accuracy everywhere. Between the random walk and
the constant bias, the difference grows with the run's length against the bias
correlation time (100 s in :data:`~kalman_course.data.mems_imu.CONSUMER_MEMS`): on the
30–60 s excerpts with lidar poses the two give the same APE, and only their consistency
differs (the constant model's final bias error is several of its σ, its bias NEES well
above 6); over the whole of sequence 00 (470 s, ``name="seq00"``) the constant model is
also less accurate and its pose NEES leaves the band, although the drift it fails to
follow has a bounded spread (σ_b); the random walk, which only approximates the drift,
stays consistent. With 1 Hz GNSS the 60 s excerpts (``turns``,
``cruise``) cannot tell the two apart at all.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from kalman_course.core.validation import as_seed
from kalman_course.data.kitti import load_kitti, simulate_gnss, simulate_lidar_poses
from kalman_course.data.mems_imu import (CONSUMER_MEMS, MemsImuData, MemsSpec, ReferenceImu, reference_imu,
                                         simulate_mems_imu)
from kalman_course.evaluation import metrics
from kalman_course.evaluation.pose import evaluate
from kalman_course.filters import eskf
from kalman_course.filters.eskf_config import EskfConfig, load_config

__all__ = [
    "VARIANTS", "OBSERVATION_SEED_OFFSET", "EARTH_RATE_DEG_H", "KITTI_LATITUDE_DEG",
    "config_for_spec", "frozen_bias_covariance", "BiasModelRun", "run_bias_models",
    "BiasModelComparison", "compare_bias_models",
    "EarthRotation", "earth_rotation", "earth_rotation_table",
]

#: The three filters compared, in table order.
VARIANTS = ("random walk", "constant", "frozen at 0")

#: The observations of seed s are drawn with seed ``OBSERVATION_SEED_OFFSET + s`` (the IMU's
#: with s), so that the two draws are independent.
OBSERVATION_SEED_OFFSET = 1000

#: The Earth's rotation rate relative to the stars, 7.2921e-5 rad/s, in °/h.
EARTH_RATE_DEG_H = math.degrees(7.2921150e-5) * 3600.0

#: Latitude of the KITTI recordings (Karlsruhe, Germany), degrees north.
KITTI_LATITUDE_DEG = 49.0

_RAD_S_TO_DEG_H = math.degrees(1.0) * 3600.0
_MS2_TO_MG = 1e3 / 9.80665
_OBSERVATIONS = ("lidar", "gnss")


# ---------------------------------------------------------------------------------------
# The filters
# ---------------------------------------------------------------------------------------

def config_for_spec(spec: MemsSpec = CONSUMER_MEMS, bias_model: str = "random_walk",
                    base="kitti_lidar") -> EskfConfig:
    """The ESKF configuration whose process noise and bias prior are the spec's.

    Parameters
    ----------
    spec : MemsSpec
        Its densities (σ_a, σ_ω, q_ba, q_bω) become ``process.*`` (q = σ_b √(2/τ), the
        random walk that approximates the Gauss–Markov drift over times ≪ τ; unused by the
        constant model); its turn-on biases the prior σ of b_a and b_ω.
    bias_model : str
        ``"random_walk"`` or ``"constant"``.
    base : EskfConfig or str
        Where the other settings (prior of p, v, θ; observation noise) come from.

    Returns
    -------
    EskfConfig
    """
    if not isinstance(spec, MemsSpec):
        raise ValueError(f"spec must be a MemsSpec, got {type(spec).__name__}")
    cfg = base if isinstance(base, EskfConfig) else load_config(base)
    sigma_a, sigma_w, sigma_ba, sigma_bw = spec.densities
    return cfg.replace(bias_model=bias_model, process__accel_noise=sigma_a, process__gyro_noise=sigma_w,
                       process__accel_bias_noise=sigma_ba, process__gyro_bias_noise=sigma_bw,
                       prior__accel_bias=spec.accel_turn_on, prior__gyro_bias=spec.gyro_turn_on)


def frozen_bias_covariance(config: EskfConfig) -> np.ndarray:
    """P̂₀ (15, 15) of ``config`` with the bias blocks set to zero.

    With the constant bias model (no bias process noise) the gain's bias rows then stay
    zero, so the bias estimates never leave their initial value.
    """
    P0 = eskf.initial_covariance(config).copy()
    P0[eskf.IDX_BA, eskf.IDX_BA] = 0.0
    P0[eskf.IDX_BW, eskf.IDX_BW] = 0.0
    return P0


@dataclass(frozen=True)
class BiasModelRun:
    """The three filters on one simulated MEMS IMU draw.

    Attributes
    ----------
    mems : MemsImuData
        The simulated IMU (its ``truth`` is what the filters are scored against).
    observations : str
        ``"lidar"`` or ``"gnss"`` (both simulated).
    results : dict of str to EskfResult
        One per entry of :data:`VARIANTS`, at the smoothed truth's times.
    metrics : dict of str to dict
        Per variant: ``ape_position`` (m), ``ape_attitude_deg``, ``nees_pose`` (mean 6-dof
        pose NEES), ``gyro_bias_error_deg_h`` and ``accel_bias_error_mg`` (|b̂ − b| at the
        last time, norm over the axes), ``gyro_bias_error_sigma`` and
        ``accel_bias_error_sigma`` (RMS over the axes of (b̂ − b)/σ at the last time; inf
        where σ = 0), ``gyro_bias_sigma_deg_h`` (RMS over the axes of the filter's final
        σ), ``gyro_bias_error_axes_deg_h`` and ``gyro_bias_sigma_axes_deg_h`` (the
        final b̂_ω − b_ω and the filter's final σ per axis x, y, z, shape (3,)) and
        ``nees_bias`` (mean 6-dof NEES of [δb_a, δb_ω]; NaN where σ = 0).
    true_accel_bias, true_gyro_bias : numpy.ndarray, shape (K, 3)
        The simulated biases at the results' times, m/s² and rad/s.
    """

    mems: MemsImuData
    observations: str
    results: dict = field(repr=False)
    metrics: dict = field(repr=False)
    true_accel_bias: np.ndarray = field(repr=False)
    true_gyro_bias: np.ndarray = field(repr=False)

    @property
    def t(self) -> np.ndarray:
        """The results' times, s (K,)."""
        return self.results[VARIANTS[0]].t


def _observations(mems: MemsImuData, config: EskfConfig, kind: str, seed: int, gnss_times):
    """Simulated lidar poses (at the truth times) or GNSS fixes (at ``gnss_times``) from the smoothed truth."""
    truth = mems.truth
    if kind == "lidar":
        return {"lidar": simulate_lidar_poses(truth, seed, config.lidar_std[0], np.rad2deg(config.lidar_std[3]))}
    t = np.asarray(gnss_times, dtype=float)
    t = t[(t > mems.t[0]) & (t <= mems.t[-1])]
    traj = mems.reference.trajectory
    position = np.column_stack([np.interp(t, traj.t, traj.position[:, i]) for i in range(3)])
    fixes = simulate_gnss(_Fixes(t, position), seed, config.gnss_std)
    return {"gnss": fixes.observations(), "output_times": truth.t, "clip_output_times": True}


@dataclass(frozen=True)
class _Fixes:
    t: np.ndarray
    position: np.ndarray


def _run_metrics(result, mems: MemsImuData, accel_true: np.ndarray, gyro_true: np.ndarray) -> dict:
    m = evaluate(result.t, result.position, result.rotation, mems.truth, result.P)
    std = result.std()
    e_a = result.accel_bias[-1] - accel_true[-1]
    e_w = result.gyro_bias[-1] - gyro_true[-1]
    s_a, s_w = std[-1, eskf.IDX_BA], std[-1, eskf.IDX_BW]

    def in_sigma(e, s):
        """The RMS over the axes of the error in units of its own σ."""
        return float(metrics.rmse(e / s, np.zeros(3), axis=None)) if (s > 0).all() else math.inf

    P_bias = result.P[:, 9:15, 9:15]
    if (np.diagonal(P_bias, axis1=1, axis2=2) > 0).all():
        e_bias = np.concatenate([result.accel_bias - accel_true, result.gyro_bias - gyro_true], axis=1)
        nees_bias = float(np.mean(metrics.nees(e_bias, P_bias)))
    else:
        nees_bias = math.nan
    return {
        "ape_position": m["ape_position"],
        "ape_attitude_deg": m["ape_attitude_deg"],
        "nees_pose": m["nees_pose"],
        "gyro_bias_error_deg_h": float(np.linalg.norm(e_w)) * _RAD_S_TO_DEG_H,
        "gyro_bias_error_sigma": in_sigma(e_w, s_w),
        "gyro_bias_sigma_deg_h": float(metrics.rmse(s_w, np.zeros(3), axis=None)) * _RAD_S_TO_DEG_H,
        "gyro_bias_error_axes_deg_h": e_w * _RAD_S_TO_DEG_H,
        "gyro_bias_sigma_axes_deg_h": s_w * _RAD_S_TO_DEG_H,
        "accel_bias_error_mg": float(np.linalg.norm(e_a)) * _MS2_TO_MG,
        "accel_bias_error_sigma": in_sigma(e_a, s_a),
        "nees_bias": nees_bias,
    }


def run_bias_models(source="turns", spec: MemsSpec = CONSUMER_MEMS, seed: int = 0, *,
                    observations: str = "lidar", base="kitti_lidar") -> BiasModelRun:
    """The three filters of :data:`VARIANTS` on one simulated MEMS draw.

    Parameters
    ----------
    source : str, KittiExcerpt or ReferenceImu
        An excerpt name (``"cruise"``, ``"turns"``, ``"stop_go"``, ``"seq00"``), a loaded excerpt, or a
        reference built by :func:`kalman_course.data.mems_imu.reference_imu` (reused
        across seeds; GNSS then needs the excerpt for its fix times and is not offered).
    spec : MemsSpec
        The simulated IMU errors, and the filters' noise: the white-noise densities and
        turn-on σ are the simulation's; the random-walk bias density is q = σ_b √(2/τ),
        the short-horizon approximation of the simulated Gauss–Markov drift.
    seed : int
        The IMU's errors use ``seed``; the observations ``OBSERVATION_SEED_OFFSET + seed``.
    observations : str
        ``"lidar"`` (10 Hz simulated poses) or ``"gnss"`` (1 Hz simulated fixes at the KITTI
        GNSS times).
    base : EskfConfig or str
        The configuration that gives the observation noise and the prior of p, v, θ.

    Returns
    -------
    BiasModelRun
    """
    seed = as_seed(seed)
    if observations not in _OBSERVATIONS:
        raise ValueError(f"observations must be 'lidar' or 'gnss', got {observations!r}")
    excerpt = load_kitti(source) if isinstance(source, str) else source
    if isinstance(excerpt, ReferenceImu):
        if observations == "gnss":
            raise ValueError("observations='gnss' needs the excerpt (for the GNSS times), not a ReferenceImu")
        gnss_times = None
    else:
        gnss_times = excerpt.gnss.t if observations == "gnss" else None
        excerpt = reference_imu(excerpt)
    mems = simulate_mems_imu(excerpt, spec, seed)
    configs = {"random walk": config_for_spec(spec, "random_walk", base),
               "constant": config_for_spec(spec, "constant", base)}
    configs["frozen at 0"] = configs["constant"]
    P0 = {"frozen at 0": frozen_bias_covariance(configs["constant"])}
    obs = _observations(mems, configs["random walk"], observations, OBSERVATION_SEED_OFFSET + seed, gnss_times)
    k0, state = mems.initial_state()
    results = {}
    for label in VARIANTS:
        res = eskf.run(mems, state, configs[label], mems.gravity, start=k0, P0=P0.get(label), **obs)
        results[label] = res.at(mems.truth.t) if observations == "gnss" else res
    t = results[VARIANTS[0]].t
    accel_true, gyro_true = mems.bias_at(t)
    table = {label: _run_metrics(res, mems, accel_true, gyro_true) for label, res in results.items()}
    return BiasModelRun(mems, observations, results, table, accel_true, gyro_true)


# ---------------------------------------------------------------------------------------
# Over several seeds
# ---------------------------------------------------------------------------------------

#: (metric key, column heading, format) of the comparison table.
_COLUMNS = (
    ("ape_position", "position APE [m]", ".3f"),
    ("ape_attitude_deg", "attitude APE [°]", ".3f"),
    ("nees_pose", "pose NEES (6 dof)", ".1f"),
    ("gyro_bias_error_deg_h", "final |b̂_ω − b_ω| [°/h]", ".1f"),
    ("gyro_bias_error_sigma", "… in its σ", ".1f"),
    ("accel_bias_error_mg", "final |b̂_a − b_a| [mg]", ".3f"),
    ("accel_bias_error_sigma", "… in its σ", ".1f"),
    ("nees_bias", "bias NEES (6 dof)", ".1f"),
)


@dataclass(frozen=True)
class BiasModelComparison:
    """The three filters over several seeds on one excerpt.

    Attributes
    ----------
    excerpt : str
        The excerpt's name.
    spec : MemsSpec
    observations : str
        ``"lidar"`` or ``"gnss"``.
    seeds : tuple of int
    metrics : dict of str to dict of str to numpy.ndarray
        variant -> metric (the keys of :attr:`BiasModelRun.metrics`) -> value per seed
        (shape (seeds,), or (seeds, 3) for the per-axis ones).
    first : BiasModelRun
        The run of the first seed (for figures).
    """

    excerpt: str
    spec: MemsSpec
    observations: str
    seeds: tuple
    metrics: dict = field(repr=False)
    first: BiasModelRun = field(repr=False)

    def median(self, variant: str, metric: str) -> float:
        """Median over the seeds of one metric of one variant."""
        return float(np.median(self.metrics[variant][metric]))

    def table(self) -> str:
        """A Markdown table: per variant, each metric's median [min – max] over the seeds."""
        obs = ("simulated lidar poses, 10 Hz (σ 0.2 m, 0.3°)" if self.observations == "lidar"
               else "simulated GNSS fixes, 1 Hz (σ 1 m)")
        lines = [f"KITTI `{self.excerpt}` motion (real ground truth, smoothed) read by a simulated "
                 f"{self.spec.name} IMU, fused with {obs}; median [min – max] over {len(self.seeds)} seeds "
                 f"{self.seeds[0]}–{self.seeds[-1]}", "",
                 "| bias model | " + " | ".join(head for _, head, _ in _COLUMNS) + " |",
                 "|---|" + "---|" * len(_COLUMNS)]
        for variant in VARIANTS:
            cells = []
            for key, _, fmt in _COLUMNS:
                values = self.metrics[variant][key]
                if not np.isfinite(values).any():
                    cells.append("— (σ = 0)")
                    continue
                med, lo, hi = np.median(values), np.min(values), np.max(values)
                cells.append(f"{med:{fmt}} [{lo:{fmt}} – {hi:{fmt}}]")
            lines.append(f"| {variant} | " + " | ".join(cells) + " |")
        return "\n".join(lines)


def compare_bias_models(name: str = "turns", spec: MemsSpec = CONSUMER_MEMS, seeds=range(8), *,
                        observations: str = "lidar", base="kitti_lidar") -> BiasModelComparison:
    """:func:`run_bias_models` over several seeds of one excerpt, summarised.

    Parameters
    ----------
    name : str
        ``"cruise"``, ``"turns"``, ``"stop_go"`` (30–60 s; about 1–6 s for 8 seeds) or
        ``"seq00"`` (470 s, where the constant model falls behind; about 30 s for 8 seeds).
    spec : MemsSpec
    seeds : iterable of int
        At least one; each gives an independent IMU error draw and observation draw.
    observations : str
        ``"lidar"`` or ``"gnss"``.
    base : EskfConfig or str

    Returns
    -------
    BiasModelComparison
    """
    seeds = tuple(as_seed(s) for s in seeds)
    if not seeds:
        raise ValueError("seeds must hold at least one seed")
    excerpt = load_kitti(name)
    source = reference_imu(excerpt) if observations == "lidar" else excerpt
    table: dict = {v: {} for v in VARIANTS}
    first = None
    for seed in seeds:
        run = run_bias_models(source, spec, seed, observations=observations, base=base)
        first = first or run
        for variant in VARIANTS:
            for key, value in run.metrics[variant].items():
                table[variant].setdefault(key, []).append(value)
    arrays = {v: {k: np.array(vals) for k, vals in m.items()} for v, m in table.items()}
    return BiasModelComparison(name, spec, observations, seeds, arrays, first)


# ---------------------------------------------------------------------------------------
# Earth rotation
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class EarthRotation:
    """The Earth's rotation seen from a point at latitude φ, in a local east–north–up frame.

    ω_ie = Ω (0, cos φ, sin φ): no east component, Ω cos φ along north, Ω sin φ up.

    Attributes
    ----------
    latitude_deg : float
        φ, degrees north.
    rate_deg_h : float
        Ω, °/h.
    north_deg_h : float
        Ω cos φ, °/h: the horizontal part. The x and y gyros of a level vehicle share it
        as Ω cos φ (cos ψ_N, −sin ψ_N)-like terms that change with the heading ψ_N.
    up_deg_h : float
        Ω sin φ, °/h: what a level yaw (z) gyro sees, whatever the heading.
    """

    latitude_deg: float
    rate_deg_h: float
    north_deg_h: float
    up_deg_h: float

    @property
    def up_rad_s(self) -> float:
        """Ω sin φ in rad/s."""
        return self.up_deg_h / _RAD_S_TO_DEG_H


def earth_rotation(latitude_deg: float = KITTI_LATITUDE_DEG) -> EarthRotation:
    """The size of the Earth's rotation at a latitude (default KITTI's, 49.0° N).

    At 49° N: Ω = 15.04 °/h, of which 9.87 °/h is horizontal (north) and 11.35 °/h vertical.

    Parameters
    ----------
    latitude_deg : float
        Latitude, degrees, in [−90, 90].
    """
    try:
        if isinstance(latitude_deg, (bool, np.bool_, str, bytes)):     # float("49") and float(True) work
            raise TypeError
        lat = float(latitude_deg)
    except (TypeError, ValueError):
        raise ValueError(f"latitude_deg must be a number of degrees in [-90, 90], got {latitude_deg!r}") from None
    if not (math.isfinite(lat) and -90.0 <= lat <= 90.0):
        raise ValueError(f"latitude_deg must be a number of degrees in [-90, 90], got {latitude_deg!r}")
    phi = math.radians(lat)
    return EarthRotation(lat, EARTH_RATE_DEG_H, EARTH_RATE_DEG_H * math.cos(phi), EARTH_RATE_DEG_H * math.sin(phi))


def _rms(values) -> float:
    """The root mean square of all the values."""
    values = np.asarray(values, dtype=float)
    return metrics.rmse(values, np.zeros_like(values), axis=None)


def earth_rotation_table(spec: MemsSpec = CONSUMER_MEMS, comparison: BiasModelComparison | None = None,
                         latitude_deg: float = KITTI_LATITUDE_DEG) -> str:
    """Earth rotation's size against the spec's gyro bias and the filters' gyro bias errors (Markdown).

    Parameters
    ----------
    spec : MemsSpec
    comparison : BiasModelComparison, optional
        Adds a second table: for the random-walk and constant filters, on the horizontal
        (x, y) and the vertical (z) gyros, the filter's own final gyro bias σ, its actual
        final bias error b̂_ω − b_ω, and that error in units of the σ, each the RMS over
        the comparison's seeds and the axes of the row; then whether the Earth-rate part
        on those axes is larger than both the actual error and the filter's σ (only then
        would it stand out of the bias error; a σ alone is what the filter believes, not
        what it achieves). The vertical part is never called separable: on a level car
        it is a constant z rate, which a z gyro bias cannot be told from.
    latitude_deg : float

    Returns
    -------
    str
        Rows in °/h, the sizes each with the ratio to the vertical Earth rate.
    """
    if not isinstance(spec, MemsSpec):
        raise ValueError(f"spec must be a MemsSpec, got {type(spec).__name__}")
    er = earth_rotation(latitude_deg)
    rows = [
        ("Earth rotation Ω", er.rate_deg_h, "always"),
        (f"… horizontal part Ω cos φ (φ = {er.latitude_deg:g}°)", er.north_deg_h,
         "x and y gyros, split by the heading"),
        ("… vertical part Ω sin φ", er.up_deg_h, "the yaw (z) gyro of a level vehicle, whatever the heading"),
        (f"{spec.name}: bias instability = stationary σ of the drift (simulated)", spec.gyro_bias_instability_deg_h,
         "each gyro, drifting"),
        (f"{spec.name}: turn-on bias σ (simulated)", spec.gyro_turn_on_deg_h, "each gyro"),
    ]
    lines = ["| quantity | °/h | seen by | ÷ Ω sin φ |", "|---|---|---|---|"]
    for label, value, seen in rows:
        lines.append(f"| {label} | {value:.2f} | {seen} | {value / er.up_deg_h:.2f} |")
    if comparison is not None:
        n = len(comparison.seeds)
        lines += ["", f"ESKF gyro bias at the end of `{comparison.excerpt}` (simulated IMU errors), RMS over "
                  f"{n} seed{'s' if n > 1 else ''} and the axes of the row:", "",
                  "| filter | gyros | filter's own final σ [°/h] | actual final error [°/h] | "
                  "actual error ÷ own σ | Earth-rate part there [°/h] | larger than the bias error? |",
                  "|---|---|---|---|---|---|---|"]
        groups = (("x, y (horizontal)", [0, 1], er.north_deg_h), ("z (vertical)", [2], er.up_deg_h))
        for variant in ("random walk", "constant"):
            error = comparison.metrics[variant]["gyro_bias_error_axes_deg_h"]
            sigma = comparison.metrics[variant]["gyro_bias_sigma_axes_deg_h"]
            for gyros, axes, part in groups:
                e, s_ = error[:, axes], sigma[:, axes]
                actual, own = _rms(e), _rms(s_)
                ratio = f"{_rms(e / s_):.1f}" if (s_ > 0).all() else "— (σ = 0)"
                if axes == [2]:
                    verdict = "not separable: on a level car a constant z rate is a z gyro bias"
                elif actual < part and own < part:
                    verdict = "yes: above both the filter's σ and its actual error"
                elif actual < part:
                    verdict = "no: within the filter's own σ"
                else:
                    verdict = "no: within the actual error"
                lines.append(f"| {variant} | {gyros} | {own:.2f} | {actual:.2f} | {ratio} | {part:.2f} | {verdict} |")
    lines += ["", "The simulated IMU contains no Earth rotation (its navigation frame is treated as "
              "inertial, as the filters assume). A real gyro would add the parts above: the vertical "
              "part is constant while the vehicle is level, so the z bias estimate absorbs it and no "
              "filter can tell it from a bias; the horizontal part moves between the x and y gyros as "
              "the vehicle turns, which neither bias model describes. A filter's own σ says how well it "
              "believes it knows a bias; only the actual error says what it could resolve."]
    return "\n".join(lines)
