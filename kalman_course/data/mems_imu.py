"""A consumer-grade MEMS IMU simulated on the KITTI motion: datasheet errors, seeded.

The real KITTI IMU (an OXTS RT3003) is a tactical-grade unit: its biases are so small and
so steady that constant and random-walk bias models give the same answer on it. This
module makes an IMU on which they differ, in two steps.

1. **A noise-free reference from the ground truth** (:func:`reference_imu`). The 10 Hz
   KITTI truth poses are smoothed by least-squares cubic B-splines with knots every
   ``knot_spacing`` seconds (default 0.3 s): position p(t) in the navigation frame and the
   yaw–pitch–roll angles (ψ, θ, φ) of the attitude R_nb = R_z(ψ) R_y(θ) R_x(φ) (fine for a
   car: |θ| stays below 2° on KITTI). Being polynomials, they are differentiated exactly:

       specific force  f(t) = R(t)ᵀ (p̈(t) − g)                      (body frame, m/s²)
       angular rate    ω(t) = R_xᵀ R_yᵀ (0, 0, ψ̇) + R_xᵀ (0, θ̇, 0) + (φ̇, 0, 0)   (rad/s)

   sampled at the real IMU's own timestamps inside the truth's time span. Smoothing is
   needed because the truth positions jitter by a few millimetres from pose to pose
   (camera timestamps): an interpolating spline turns that into ±2 m/s² of fake
   acceleration. The smoothed motion is the truth of the simulation: on the three
   excerpts it stays within 3–7 mm RMS (up to 3.6 cm at one pose) and 0.07–0.10° RMS (up
   to 0.34°) of the KITTI poses; the course's midpoint mechanisation of its readings
   reproduces it to under 1 cm over 10 s, and its 1 s mean readings agree with the real
   OXTS ones to under 0.1 m/s² and 0.1 °/s RMS (``tests/test_mems_imu.py`` checks all
   three). The real OXTS readings are *not* used as the noise-free reference: over each
   excerpt their mean z rate differs from the truth's by 21–26 °/h, with a sign that
   changes from excerpt to excerpt (Earth rotation, the unit's own bias and the truth's
   errors together), which is the size of the bias drift simulated here and could not be
   told apart from it.
   The reference does not contain Earth rotation either: its navigation frame is treated
   as inertial, as the course's filters assume (see
   :func:`kalman_course.chapters.bias_models.earth_rotation`).

2. **Simulated MEMS errors** (:func:`simulate_mems_imu`), per axis and sensor, drawn from
   ``numpy.random.default_rng(seed)``: reading = reference + bias + white noise, where the
   bias is a turn-on value plus a first-order Gauss–Markov drift d (:func:`gauss_markov_drift`):

       bias:   b_k = b_0 + d_k,   b_0 ~ N(0, σ_turn-on²)
       drift:  d_0 = 0,   d_{k+1} = φ_k d_k + σ_b √(1 − φ_k²) · N(0, 1),   φ_k = exp(−dt_k / τ)
       noise:  n_k ~ N(0, σ_n² / dt_nom)   (σ_n the white-noise density, dt_nom the median step)

   with dt_k = t[k+1] − t[k] the IMU's own (irregular) intervals: the discretisation is
   exact for every step, whatever its length. The bias *drifts during the run*, so a
   filter that models it as a constant cannot follow; but the drift stays bounded: its
   spread grows as σ_b √(1 − exp(−2(t − t_0)/τ)) and levels off at σ_b after a few τ.

The spec (:class:`MemsSpec`) is written in datasheet units; its properties give the
continuous densities that the ESKF configuration takes (``process.*`` of
:mod:`kalman_course.filters.eskf_config`). Conversions, with g₀ = 9.80665 m/s²:

==========================  ===================  ==========================================
datasheet                   SI                   conversion
==========================  ===================  ==========================================
gyro ARW N_ω [°/√h]         rad/s/√Hz            N_ω · (π/180) / 60     (√h = 60 √s)
gyro BI B_ω [°/h]           rad/s                σ_bω = B_ω · (π/180) / 3600  (GM stationary σ)
… with τ_ω [s]              rad/s²/√Hz           q_bω = σ_bω √(2/τ_ω)  (GM driving density)
gyro turn-on [°/h]          rad/s                · (π/180) / 3600
accel noise N_a [µg/√Hz]    m/s²/√Hz             N_a · 1e-6 g₀   (VRW in m/s/√h = that · 60)
accel BI B_a [mg]           m/s²                 σ_ba = B_a · 1e-3 g₀  (GM stationary σ)
… with τ_a [s]              m/s³/√Hz             q_ba = σ_ba √(2/τ_a)  (GM driving density)
accel turn-on [mg]          m/s²                 · 1e-3 g₀
==========================  ===================  ==========================================

**The bias instability as a Gauss–Markov process.** A bias-instability figure B with a
correlation time τ is modelled, as is usual in navigation, by the first-order
Gauss–Markov process

    ḃ = −b/τ + w,   E[w(t) w(t′)] = q² δ(t − t′),   q² = 2σ_b²/τ,

whose stationary standard deviation is σ_b and whose autocorrelation is σ_b² exp(−|Δt|/τ).
This module takes **σ_b = B**: the datasheet number is read as the size the bias wanders
to over times of the order of τ, the simplest reading and a common one. It is an
assumption, not a fit: a datasheet's B is strictly the flat floor of the Allan deviation,
and a Gauss–Markov process of stationary σ_b has an Allan deviation that peaks at
0.62 σ_b (at an averaging time of 1.89 τ), so matching the floor instead would take
σ_b = 1.62 B. σ_b = B is the milder of the two readings. The exact discrete form over a step Δt is
b_{k+1} = e^{−Δt/τ} b_k + w_k, Var(w_k) = σ_b²(1 − e^{−2Δt/τ}).

For Δt and t − t_0 ≪ τ, e^{−Δt/τ} ≈ 1 and σ_b²(1 − e^{−2Δt/τ}) ≈ q² Δt: over short
horizons the drift looks like a **random walk of density q = σ_b √(2/τ)**. That random
walk is what the ESKF's ``bias_model="random_walk"`` assumes, and q is the density
:attr:`MemsSpec.densities` hands it: the filter's model approximates the drift that made
the data, it is not that model (the random walk's spread grows as q √t without bound;
the drift's stops at σ_b).

Everything this module returns says it is simulated: the motion comes from the real
KITTI ground truth; the readings' errors are simulated; Earth rotation is absent.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import numpy as np

from kalman_course.core import so3
from kalman_course.core.imu import NavState, NavTrajectory
from kalman_course.core.validation import as_rotations, as_rows, as_scalar, as_seed, as_vector

__all__ = ["MemsSpec", "CONSUMER_MEMS", "STANDARD_GRAVITY", "SmoothTruth", "ReferenceImu", "MemsImuData",
           "reference_imu", "gauss_markov_drift", "simulate_mems_imu"]

#: Standard gravity g₀, m/s²: what datasheets mean by "g" (mg, µg).
STANDARD_GRAVITY = 9.80665

_DEG = math.pi / 180.0
_DEG_PER_H = _DEG / 3600.0          # 1 °/h in rad/s
_SQRT_HOUR = 60.0                   # √(3600 s)


# ---------------------------------------------------------------------------------------
# The datasheet
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MemsSpec:
    """IMU error specification in datasheet units (all values 1σ, per axis).

    Attributes
    ----------
    name : str
        A label for tables and legends.
    gyro_arw_deg_rth : float
        Gyroscope angle random walk N_ω, °/√h (white rate noise; °/s/√Hz × 60).
    gyro_bias_instability_deg_h : float
        Gyroscope bias instability B_ω, °/h: taken as the stationary σ of the bias's
        first-order Gauss–Markov drift (see the module docstring).
    gyro_bias_time_s : float
        Correlation time τ_ω of that drift, s: drift values Δt apart correlate by
        exp(−Δt/τ_ω).
    gyro_turn_on_deg_h : float
        Gyroscope bias at switch-on (turn-on to turn-on), °/h.
    accel_noise_ug_rthz : float
        Accelerometer white-noise density N_a, µg/√Hz (velocity random walk
        N_a · 1e-6 g₀ · 60 m/s/√h).
    accel_bias_instability_mg : float
        Accelerometer bias instability B_a, mg: taken as the stationary σ of the bias's
        Gauss–Markov drift.
    accel_bias_time_s : float
        Correlation time τ_a of that drift, s.
    accel_turn_on_mg : float
        Accelerometer bias at switch-on, mg.

    Every value must be finite and positive (a zero gives an error-free term: use a tiny
    value to switch a term off). The SI properties below are what a filter takes.
    """

    name: str
    gyro_arw_deg_rth: float
    gyro_bias_instability_deg_h: float
    gyro_bias_time_s: float
    gyro_turn_on_deg_h: float
    accel_noise_ug_rthz: float
    accel_bias_instability_mg: float
    accel_bias_time_s: float
    accel_turn_on_mg: float

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name.strip():
            raise ValueError(f"name must be a non-empty string, got {self.name!r}")
        for f in fields(self):
            if f.name != "name":
                object.__setattr__(self, f.name, as_scalar(getattr(self, f.name), f.name))

    # ---- continuous densities and standard deviations in SI units -------------------
    @property
    def gyro_noise_density(self) -> float:
        """σ_ω, gyroscope white-noise density, rad/s/√Hz."""
        return self.gyro_arw_deg_rth * _DEG / _SQRT_HOUR

    @property
    def accel_noise_density(self) -> float:
        """σ_a, accelerometer white-noise density, m/s²/√Hz."""
        return self.accel_noise_ug_rthz * 1e-6 * STANDARD_GRAVITY

    @property
    def gyro_bias_sigma(self) -> float:
        """σ_bω = B_ω in rad/s: the stationary standard deviation of the gyroscope bias drift."""
        return self.gyro_bias_instability_deg_h * _DEG_PER_H

    @property
    def accel_bias_sigma(self) -> float:
        """σ_ba = B_a in m/s²: the stationary standard deviation of the accelerometer bias drift."""
        return self.accel_bias_instability_mg * 1e-3 * STANDARD_GRAVITY

    @property
    def gyro_bias_density(self) -> float:
        """q_bω = σ_bω √(2/τ_ω), rad/s²/√Hz.

        The density of the white noise that drives the gyroscope's Gauss–Markov bias drift
        (ḃ = −b/τ + w, E[w w′] = q² δ), and so also the density of the random walk that
        the drift looks like over times ≪ τ_ω: the value a filter with a random-walk bias
        takes (:attr:`densities`) as its short-horizon approximation of the drift.
        """
        return self.gyro_bias_sigma * math.sqrt(2.0 / self.gyro_bias_time_s)

    @property
    def accel_bias_density(self) -> float:
        """q_ba = σ_ba √(2/τ_a), m/s³/√Hz: the accelerometer's counterpart of :attr:`gyro_bias_density`."""
        return self.accel_bias_sigma * math.sqrt(2.0 / self.accel_bias_time_s)

    @property
    def gyro_turn_on(self) -> float:
        """Standard deviation of the gyroscope bias at switch-on, rad/s."""
        return self.gyro_turn_on_deg_h * _DEG_PER_H

    @property
    def accel_turn_on(self) -> float:
        """Standard deviation of the accelerometer bias at switch-on, m/s²."""
        return self.accel_turn_on_mg * 1e-3 * STANDARD_GRAVITY

    @property
    def accel_vrw_m_s_rth(self) -> float:
        """Velocity random walk, m/s/√h (the accelerometer density in another unit)."""
        return self.accel_noise_density * _SQRT_HOUR

    @property
    def densities(self) -> np.ndarray:
        """(σ_a, σ_ω, q_ba, q_bω), shape (4,): the order of ``EskfConfig.process_density``.

        The white-noise densities and the bias densities q = σ_b √(2/τ) that a random-walk
        bias model takes as its approximation of the Gauss–Markov drift.
        """
        return np.array([self.accel_noise_density, self.gyro_noise_density, self.accel_bias_density,
                         self.gyro_bias_density])

    def describe(self) -> str:
        """The spec as a Markdown table: datasheet value and unit, SI value and unit."""
        root_h = _SQRT_HOUR
        rows = [
            ("gyro angle random walk", self.gyro_arw_deg_rth, "°/√h", self.gyro_noise_density, "rad/s/√Hz"),
            ("gyro bias instability B_ω = Gauss–Markov stationary σ_bω", self.gyro_bias_instability_deg_h, "°/h",
             self.gyro_bias_sigma, "rad/s"),
            ("gyro bias correlation time τ_ω", self.gyro_bias_time_s, "s", self.gyro_bias_time_s, "s"),
            ("→ Gauss–Markov driving density q_bω = σ_bω √(2/τ_ω) (the random walk of t ≪ τ_ω)",
             self.gyro_bias_density / _DEG_PER_H * root_h, "°/h/√h", self.gyro_bias_density, "rad/s²/√Hz"),
            ("gyro turn-on bias", self.gyro_turn_on_deg_h, "°/h", self.gyro_turn_on, "rad/s"),
            ("accel noise density", self.accel_noise_ug_rthz, "µg/√Hz", self.accel_noise_density, "m/s²/√Hz"),
            ("→ velocity random walk", self.accel_vrw_m_s_rth, "m/s/√h", None, ""),
            ("accel bias instability B_a = Gauss–Markov stationary σ_ba", self.accel_bias_instability_mg, "mg",
             self.accel_bias_sigma, "m/s²"),
            ("accel bias correlation time τ_a", self.accel_bias_time_s, "s", self.accel_bias_time_s, "s"),
            ("→ Gauss–Markov driving density q_ba = σ_ba √(2/τ_a) (the random walk of t ≪ τ_a)",
             self.accel_bias_density / (1e-3 * STANDARD_GRAVITY), "mg/√s", self.accel_bias_density, "m/s³/√Hz"),
            ("accel turn-on bias", self.accel_turn_on_mg, "mg", self.accel_turn_on, "m/s²"),
        ]
        lines = [f"MEMS spec `{self.name}` (simulated errors, 1σ per axis)", "",
                 "| term | datasheet | unit | SI | SI unit |", "|---|---|---|---|---|"]
        for term, value, unit, si, si_unit in rows:
            shown = "" if si is None else f"{si:.3g}"
            lines.append(f"| {term} | {value:.3g} | {unit} | {shown} | {si_unit} |")
        return "\n".join(lines)


#: A consumer-grade 6-axis MEMS IMU of the smartphone / automotive class (parts such as
#: Bosch's BMI0xx or TDK InvenSense's ICM-2xxxx/4xxxx families). Typical values:
#:
#: - gyro noise: datasheets give 0.003–0.014 °/s/√Hz, i.e. an ARW of 0.2–0.8 °/√h; 0.3 °/√h;
#: - gyro bias instability: Allan-deviation floors of such parts are 5–50 °/h; 20 °/h;
#: - accel noise: datasheets give 70–300 µg/√Hz; 150 µg/√Hz (VRW 0.088 m/s/√h);
#: - accel bias instability: 0.05–0.2 mg; 0.1 mg;
#: - correlation time 100 s for both (an assumption, stated as such): the drift is a
#:   Gauss–Markov process of σ = the bias instability and τ = 100 s, driven by
#:   q = σ √(2/τ) (gyro 170 °/h/√h ≈ 1.4e-5 rad/s²/√Hz, of the order of the 1.9e-5
#:   random walk used for the ADIS16448 of the EuRoC data set);
#: - turn-on biases: datasheet zero-rate and zero-g offsets are ±0.5–3 °/s and ±20–80 mg
#:   before calibration; the preset assumes a one-time calibration that leaves about a
#:   tenth of that: 0.1 °/s = 360 °/h and 5 mg (an assumption, stated as such).
CONSUMER_MEMS = MemsSpec(
    name="consumer MEMS",
    gyro_arw_deg_rth=0.3,
    gyro_bias_instability_deg_h=20.0,
    gyro_bias_time_s=100.0,
    gyro_turn_on_deg_h=360.0,
    accel_noise_ug_rthz=150.0,
    accel_bias_instability_mg=0.1,
    accel_bias_time_s=100.0,
    accel_turn_on_mg=5.0,
)


# ---------------------------------------------------------------------------------------
# Smoothing splines (uniform cubic B-splines fitted by least squares)
# ---------------------------------------------------------------------------------------

def _bspline_weights(u: np.ndarray, order: int) -> np.ndarray:
    """Weights (n, 4) of the 4 control points of a uniform cubic B-spline at local u ∈ [0, 1],
    or of its ``order``-th derivative with respect to u (order 0, 1 or 2)."""
    u2, u3 = u * u, u * u * u
    if order == 0:
        w = [(1 - u) ** 3, 3 * u3 - 6 * u2 + 4, -3 * u3 + 3 * u2 + 3 * u + 1, u3]
        return np.stack(w, axis=-1) / 6.0
    if order == 1:
        w = [-3 * (1 - u) ** 2, 9 * u2 - 12 * u, -9 * u2 + 6 * u + 3, 3 * u2]
        return np.stack(w, axis=-1) / 6.0
    w = [1 - u, 3 * u - 2, 1 - 3 * u, u]
    return np.stack(w, axis=-1)


@dataclass(frozen=True)
class _Spline:
    """A uniform cubic B-spline on [t0, t0 + n·step]: control points ``c`` (n + 3, m)."""

    t0: float
    step: float
    n: int
    c: np.ndarray

    def _locate(self, t: np.ndarray):
        s = (t - self.t0) / self.step
        k = np.clip(np.floor(s).astype(int), 0, self.n - 1)
        return k, s - k

    def __call__(self, t: np.ndarray, order: int = 0) -> np.ndarray:
        """Value (order 0) or time derivative (1, 2) at times ``t`` (n,), shape (n, m)."""
        k, u = self._locate(t)
        w = _bspline_weights(u, order) / self.step ** order
        idx = k[:, None] + np.arange(4)
        return np.einsum("nj,njm->nm", w, self.c[idx])


def _fit_spline(t: np.ndarray, y: np.ndarray, spacing: float) -> _Spline:
    """Least-squares uniform cubic B-spline through samples y (K, m) at times t (K,).

    Knots split [t[0], t[-1]] into n = ceil(span / spacing) equal segments; the normal
    equations (banded, (n + 3)²) are built from each sample's 4 weights and solved densely.
    """
    n = max(1, int(math.ceil((t[-1] - t[0]) / spacing - 1e-9)))
    step = (t[-1] - t[0]) / n
    proto = _Spline(float(t[0]), step, n, np.zeros((n + 3, y.shape[1])))
    k, u = proto._locate(t)
    w = _bspline_weights(u, 0)
    idx = k[:, None] + np.arange(4)
    normal = np.zeros((n + 3, n + 3))
    np.add.at(normal, (idx[:, :, None], idx[:, None, :]), w[:, :, None] * w[:, None, :])
    rhs = np.zeros((n + 3, y.shape[1]))
    np.add.at(rhs, idx, w[:, :, None] * y[:, None, :])
    return _Spline(proto.t0, step, n, np.linalg.solve(normal, rhs))


def _yaw_pitch_roll(R: np.ndarray) -> np.ndarray:
    """(ψ, θ, φ) (K, 3) of R = R_z(ψ) R_y(θ) R_x(φ); ψ and φ unwrapped along the sequence."""
    pitch = -np.arcsin(np.clip(R[:, 2, 0], -1.0, 1.0))
    roll = np.unwrap(np.arctan2(R[:, 2, 1], R[:, 2, 2]))
    yaw = np.unwrap(np.arctan2(R[:, 1, 0], R[:, 0, 0]))
    return np.column_stack([yaw, pitch, roll])


def _axis_rotation(angle: np.ndarray, axis: int) -> np.ndarray:
    """Rotations (n, 3, 3) by ``angle`` (n,) rad about body axis 0 (x), 1 (y) or 2 (z)."""
    phi = np.zeros((len(angle), 3))
    phi[:, axis] = angle
    return so3.exp(phi, check=False)


# ---------------------------------------------------------------------------------------
# The noise-free reference
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class SmoothTruth:
    """The smoothed reference motion at the KITTI truth times: the truth of the simulation.

    Made from the real KITTI ground truth by :func:`reference_imu`; score a filter fed by a
    :class:`MemsImuData` against this (``evaluate(..., mems.truth)``), and simulate its
    observations from it, so that every error is one the simulation put there.

    Attributes
    ----------
    t : numpy.ndarray, shape (K,)
        Times tau, s (the KITTI truth times inside the IMU record).
    position : numpy.ndarray, shape (K, 3)
        p, navigation frame, m.
    velocity : numpy.ndarray, shape (K, 3)
        v = ṗ, m/s.
    rotation : numpy.ndarray, shape (K, 3, 3)
        R_nb.
    quaternion : numpy.ndarray, shape (K, 4)
        The same attitude as (w, x, y, z), w ≥ 0.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    rotation: np.ndarray
    quaternion: np.ndarray

    def __len__(self) -> int:
        return len(self.t)


@dataclass(frozen=True)
class ReferenceImu:
    """Noise-free IMU readings of the smoothed KITTI motion (see the module docstring).

    Attributes
    ----------
    t : numpy.ndarray, shape (N,)
        The real IMU's timestamps inside the truth's span, s.
    specific_force : numpy.ndarray, shape (N, 3)
        f = Rᵀ (p̈ − g), body frame, m/s²; no errors.
    angular_rate : numpy.ndarray, shape (N, 3)
        ω, body frame, rad/s; no errors, no Earth rotation.
    trajectory : NavTrajectory
        The reference motion (p, v, R_nb) at ``t``.
    truth : SmoothTruth
        The reference motion at the KITTI truth times.
    gravity : numpy.ndarray, shape (3,)
        g in the navigation frame, m/s².
    knot_spacing : float
        Knot spacing of the smoothing splines, s.
    """

    t: np.ndarray
    specific_force: np.ndarray
    angular_rate: np.ndarray
    trajectory: NavTrajectory
    truth: SmoothTruth
    gravity: np.ndarray
    knot_spacing: float

    def __len__(self) -> int:
        return len(self.t)


def _check_excerpt(excerpt, name: str = "excerpt"):
    """(IMU times (N,), truth t (K,), position (K, 3), rotation (K, 3, 3), gravity (3,)).

    ``name`` is the argument the record was passed as (``excerpt``, ``source``), for the messages.
    """
    for attr in ("imu", "truth", "gravity"):
        if not hasattr(excerpt, attr):
            raise ValueError(f"{name} must have imu, truth and gravity (a KittiExcerpt); missing {attr!r}")
    truth = excerpt.truth
    for attr in ("t", "position", "rotation"):
        if not hasattr(truth, attr):
            raise ValueError(f"{name}.truth must have t, position and rotation; missing {attr!r}")
    if not hasattr(excerpt.imu, "t"):
        raise ValueError(f"{name}.imu must have t (N,), the IMU timestamps")
    t_imu = as_rows(excerpt.imu.t, f"{name}.imu.t")
    t_truth = as_rows(truth.t, f"{name}.truth.t")
    K = len(t_truth)
    position = as_rows(truth.position, f"{name}.truth.position", (3,), K)
    rotation = as_rotations(truth.rotation, f"{name}.truth.rotation", K, count="N")
    gravity = as_vector(excerpt.gravity, f"{name}.gravity", 3)
    for label, t in ((f"{name}.imu.t", t_imu), (f"{name}.truth.t", t_truth)):
        if len(t) < 2 or (np.diff(t) <= 0.0).any():
            raise ValueError(f"{label} must hold at least 2 strictly increasing times")
    return t_imu, t_truth, position, rotation, gravity


def reference_imu(excerpt, knot_spacing: float = 0.3) -> ReferenceImu:
    """Noise-free specific force and angular rate generated from an excerpt's ground truth.

    Parameters
    ----------
    excerpt : KittiExcerpt
        Anything with ``imu.t`` (N,) s, ``truth`` (``t`` (K,) s, ``position`` (K, 3) m,
        ``rotation`` (K, 3, 3)) and ``gravity`` (3,) m/s², for example
        ``load_kitti("turns")``. Only the IMU's timestamps are used, not its readings.
    knot_spacing : float
        Knot spacing of the smoothing B-splines, s; at least twice the longest truth
        interval (so every segment holds truth poses). 0.3 s (default) keeps the
        position residual at the level of the truth's jitter; larger values smooth more.

    Returns
    -------
    ReferenceImu
        Readings at the IMU timestamps inside [truth.t[0], truth.t[-1]].

    Raises
    ------
    ValueError
        If the excerpt lacks a field, a field has the wrong shape or is not finite or
        increasing, ``knot_spacing`` is too small, the attitude pitches beyond ±60° (the
        yaw–pitch–roll angles would be ill-conditioned), or no IMU sample lies in the
        truth's span.
    """
    return _reference(excerpt, knot_spacing, "excerpt")


def _reference(excerpt, knot_spacing, name: str) -> ReferenceImu:
    """:func:`reference_imu`, its messages naming the excerpt ``name`` (the caller's argument)."""
    t_imu, t_truth, position, rotation, gravity = _check_excerpt(excerpt, name)
    spacing = as_scalar(knot_spacing, "knot_spacing")
    longest = float(np.diff(t_truth).max())
    if spacing < 2.0 * longest:
        raise ValueError(f"knot_spacing must be at least twice the longest truth interval "
                         f"({2.0 * longest:.3g} s), got {spacing:g}")
    angles = _yaw_pitch_roll(rotation)
    if np.abs(angles[:, 1]).max() > np.deg2rad(60.0):
        raise ValueError(f"{name}.truth.rotation pitches beyond ±60°: the yaw–pitch–roll "
                         "reference is meant for a ground vehicle")
    inside = (t_imu >= t_truth[0]) & (t_imu <= t_truth[-1])
    if inside.sum() < 2:
        raise ValueError(f"fewer than two IMU timestamps lie inside the truth's time span: {name}.imu.t "
                         f"covers [{t_imu[0]:.4f}, {t_imu[-1]:.4f}] s, {name}.truth.t "
                         f"[{t_truth[0]:.4f}, {t_truth[-1]:.4f}] s")
    t = t_imu[inside].copy()

    p_spline = _fit_spline(t_truth, position, spacing)
    a_spline = _fit_spline(t_truth, angles, spacing)

    def motion(times):
        p, v, acc = p_spline(times), p_spline(times, 1), p_spline(times, 2)
        ang, rate = a_spline(times), a_spline(times, 1)
        Rx, Ry, Rz = (_axis_rotation(ang[:, i], axis) for i, axis in ((2, 0), (1, 1), (0, 2)))
        R = Rz @ Ry @ Rx
        n = len(times)
        z_rate, y_rate, x_rate = np.zeros((n, 3)), np.zeros((n, 3)), np.zeros((n, 3))
        z_rate[:, 2], y_rate[:, 1], x_rate[:, 0] = rate[:, 0], rate[:, 1], rate[:, 2]
        Rxt = np.swapaxes(Rx, 1, 2)
        omega = (np.einsum("nij,nj->ni", Rxt @ np.swapaxes(Ry, 1, 2), z_rate)
                 + np.einsum("nij,nj->ni", Rxt, y_rate) + x_rate)
        f = np.einsum("nji,nj->ni", R, acc - gravity)
        return p, v, R, f, omega

    p, v, R, f, omega = motion(t)
    keep = (t_truth >= t[0]) & (t_truth <= t[-1])
    pk, vk, Rk, _, _ = motion(t_truth[keep])
    truth = SmoothTruth(t_truth[keep].copy(), pk, vk, Rk, so3.matrix_to_quat(Rk))
    return ReferenceImu(t, f, omega, NavTrajectory(t, p, v, R), truth, gravity.copy(), spacing)


# ---------------------------------------------------------------------------------------
# The simulated MEMS IMU
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MemsImuData:
    """A simulated MEMS IMU record: the KITTI motion read by a sensor with datasheet errors.

    It has the fields of :class:`kalman_course.data.kitti.ImuData` (``t``,
    ``specific_force``, ``angular_rate``, ``interpolated``), so it goes to
    :func:`kalman_course.filters.eskf.run` as it is, plus the simulation's truth.

    Attributes
    ----------
    t : numpy.ndarray, shape (N,)
        The real KITTI IMU timestamps inside the truth's span, s.
    specific_force : numpy.ndarray, shape (N, 3)
        f̃ = f + b_a + n_a, body frame, m/s² (simulated errors).
    angular_rate : numpy.ndarray, shape (N, 3)
        ω̃ = ω + b_ω + n_ω, body frame, rad/s (simulated errors).
    interpolated : numpy.ndarray of bool, shape (N,)
        All False: every reading is generated, none fills a dropout.
    accel_bias, gyro_bias : numpy.ndarray, shape (N, 3)
        The simulated biases b_a (m/s²) and b_ω (rad/s) at each sample: the turn-on bias
        (row 0) plus the Gauss–Markov drift (:attr:`accel_drift`, :attr:`gyro_drift`).
    accel_noise, gyro_noise : numpy.ndarray, shape (N, 3)
        The simulated white noise n_a (m/s²) and n_ω (rad/s) of each sample.
    reference : ReferenceImu
        The noise-free readings, the reference motion and its truth (``truth``).
    spec : MemsSpec
    seed : int
    noise_dt : float
        dt_nom, the median sample interval, s: the white noise has variance density² / dt_nom.
    simulated : bool
        Always True: the errors are simulated; the motion is KITTI's.
    """

    t: np.ndarray
    specific_force: np.ndarray
    angular_rate: np.ndarray
    interpolated: np.ndarray
    accel_bias: np.ndarray
    gyro_bias: np.ndarray
    accel_noise: np.ndarray
    gyro_noise: np.ndarray
    reference: ReferenceImu
    spec: MemsSpec
    seed: int
    noise_dt: float
    simulated: bool = True

    def __len__(self) -> int:
        return len(self.t)

    @property
    def dt(self) -> np.ndarray:
        """Intervals t[k+1] − t[k], s, shape (N−1,)."""
        return np.diff(self.t)

    @property
    def gyro_drift(self) -> np.ndarray:
        """d_ω = b_ω − b_ω[0], rad/s (N, 3): the gyroscope bias's Gauss–Markov drift (0 at t[0])."""
        return self.gyro_bias - self.gyro_bias[0]

    @property
    def accel_drift(self) -> np.ndarray:
        """d_a = b_a − b_a[0], m/s² (N, 3): the accelerometer bias's Gauss–Markov drift (0 at t[0])."""
        return self.accel_bias - self.accel_bias[0]

    @property
    def truth(self) -> SmoothTruth:
        """The reference motion at the KITTI truth times: score filters against this."""
        return self.reference.truth

    @property
    def gravity(self) -> np.ndarray:
        """g in the navigation frame, m/s², shape (3,)."""
        return self.reference.gravity

    def initial_state(self) -> tuple[int, NavState]:
        """(0, the reference state at t[0]): where a filter on this record starts."""
        return 0, self.reference.trajectory.state(0)

    def bias_at(self, times) -> tuple[np.ndarray, np.ndarray]:
        """The simulated biases linearly interpolated at ``times`` (n,) s inside [t[0], t[-1]].

        Returns
        -------
        accel_bias : numpy.ndarray, shape (n, 3)
            m/s².
        gyro_bias : numpy.ndarray, shape (n, 3)
            rad/s.
        """
        tq = as_rows([times] if np.isscalar(times) else times, "times")
        if tq.size and (tq.min() < self.t[0] or tq.max() > self.t[-1]):
            raise ValueError(f"times must lie inside [{self.t[0]:.4f}, {self.t[-1]:.4f}] s, got values in "
                             f"[{tq.min():.4f}, {tq.max():.4f}]")

        def interp(b):
            return np.column_stack([np.interp(tq, self.t, b[:, i]) for i in range(3)])

        return interp(self.accel_bias), interp(self.gyro_bias)


#: Longest stretch, in correlation times, that :func:`gauss_markov_drift` sums in closed
#: form: the factors exp(±s) it uses stay within e^±30.
_GM_BLOCK = 30.0


def _as_normals(normals, rows: int) -> np.ndarray:
    """``normals`` as a finite float array of shape (rows, m), else a ValueError naming it."""
    try:
        n = np.asarray(normals)
        ok = n.dtype.kind in "iuf" and n.ndim == 2 and n.shape[0] == rows and bool(np.isfinite(n).all())
    except (TypeError, ValueError):                      # a ragged list
        n, ok = None, False
    if not ok:
        shown = f"shape {n.shape}, dtype {n.dtype}" if n is not None else repr(normals)[:60]
        raise ValueError(f"normals must be a finite real array of shape ({rows}, m), one row per step, got {shown}")
    return n.astype(float, copy=False)


def gauss_markov_drift(t, sigma: float, time_constant: float, normals) -> np.ndarray:
    """A first-order Gauss–Markov drift at irregular times, started at zero, exactly discretised.

    Per column, with φ_k = exp(−(t[k+1] − t[k]) / τ)::

        d_0 = 0,   d_{k+1} = φ_k d_k + σ √(1 − φ_k²) n_k

    the exact discrete form of ḃ = −b/τ + w, E[w w′] = (2σ²/τ) δ, for every step length.
    Its variance is σ² (1 − exp(−2 (t_k − t_0) / τ)): it grows like a random walk of
    density σ √(2/τ) while t_k − t_0 ≪ τ and levels off at σ² after a few τ. Values Δt
    apart (once levelled off) correlate by exp(−Δt/τ).

    The recursion is evaluated in closed form over blocks of at most 30 τ,
    d_k = e^{−s_k} (d_a + Σ_{a ≤ j < k} σ √(1 − φ_j²) n_j e^{s_{j+1}}) with
    s_k = (t_k − t_a)/τ from the block's first time t_a, so long records need no Python
    loop over samples; it equals the recursion to rounding.

    Parameters
    ----------
    t : array_like, shape (N,)
        Strictly increasing times, s.
    sigma : float
        σ, the stationary standard deviation (> 0), in the drift's unit.
    time_constant : float
        τ, s (> 0).
    normals : array_like, shape (N − 1, m)
        The standard normal draws n_k, one row per step.

    Returns
    -------
    numpy.ndarray, shape (N, m)
        d at the times t; row 0 is zero.
    """
    t = as_rows(t, "t")
    if len(t) < 2 or (np.diff(t) <= 0.0).any():
        raise ValueError("t must hold at least 2 strictly increasing times")
    sigma = as_scalar(sigma, "sigma")
    tau = as_scalar(time_constant, "time_constant")
    n = _as_normals(normals, len(t) - 1)
    elapsed = (t - t[0]) / tau
    step = np.diff(elapsed)
    w = sigma * np.sqrt(-np.expm1(-2.0 * step))[:, None] * n        # σ √(1 − φ²) n
    d = np.zeros((len(t), n.shape[1]))
    a, last = 0, len(t) - 1
    while a < last:
        b = int(np.searchsorted(elapsed, elapsed[a] + _GM_BLOCK, side="right")) - 1
        b = min(max(b, a + 1), last)
        if b == a + 1:                                   # one step (possibly longer than 30 τ)
            d[b] = math.exp(-step[a]) * d[a] + w[a]
        else:
            s = elapsed[a + 1:b + 1] - elapsed[a]
            d[a + 1:b + 1] = (d[a] + np.cumsum(w[a:b] * np.exp(s)[:, None], axis=0)) * np.exp(-s)[:, None]
        a = b
    return d


def simulate_mems_imu(source, spec: MemsSpec = CONSUMER_MEMS, seed: int = 0, *,
                      knot_spacing: float = 0.3) -> MemsImuData:
    """Read the KITTI motion with a simulated MEMS IMU: reference + Gauss–Markov bias + white noise.

    Parameters
    ----------
    source : KittiExcerpt or ReferenceImu
        An excerpt (its reference is built with :func:`reference_imu`) or a reference
        already built (to draw several seeds on one reference without refitting).
    spec : MemsSpec
        The errors, in datasheet units (default :data:`CONSUMER_MEMS`).
    seed : int
        Seed of ``numpy.random.default_rng``. Draws, in this order, all standard normal:
        gyro turn-on bias (3,), accel turn-on bias (3,), gyro drift innovations (N−1, 3),
        accel drift innovations (N−1, 3), gyro white noise (N, 3), accel white noise (N, 3).
    knot_spacing : float
        Passed to :func:`reference_imu` when ``source`` is an excerpt.

    Returns
    -------
    MemsImuData
        Per sample k, with dt_k = t[k+1] − t[k], φ_k = exp(−dt_k/τ) and dt_nom the median
        of dt: b_k = b_0 + d_k with b_0 = σ_turn-on · N(0, I), d_0 = 0 and
        d_{k+1} = φ_k d_k + σ_b √(1 − φ_k²) · N(0, I) (:func:`gauss_markov_drift`, σ_b the
        bias instability, τ its correlation time), n_k = σ_n / √dt_nom · N(0, I),
        reading = reference + b_k + n_k.

    Raises
    ------
    ValueError
        If ``spec`` is not a MemsSpec, ``seed`` is not a non-negative integer, or the
        excerpt does not validate (see :func:`reference_imu`).
    """
    if not isinstance(spec, MemsSpec):
        raise ValueError(f"spec must be a MemsSpec (for example CONSUMER_MEMS), got {type(spec).__name__}")
    seed = as_seed(seed)
    ref = source if isinstance(source, ReferenceImu) else _reference(source, knot_spacing, "source")
    t = ref.t
    n = len(t)
    dt_nom = float(np.median(np.diff(t)))

    rng = np.random.default_rng(seed)
    gyro_b0 = spec.gyro_turn_on * rng.standard_normal(3)
    accel_b0 = spec.accel_turn_on * rng.standard_normal(3)
    gyro_drift = gauss_markov_drift(t, spec.gyro_bias_sigma, spec.gyro_bias_time_s, rng.standard_normal((n - 1, 3)))
    accel_drift = gauss_markov_drift(t, spec.accel_bias_sigma, spec.accel_bias_time_s,
                                     rng.standard_normal((n - 1, 3)))
    gyro_noise = spec.gyro_noise_density / math.sqrt(dt_nom) * rng.standard_normal((n, 3))
    accel_noise = spec.accel_noise_density / math.sqrt(dt_nom) * rng.standard_normal((n, 3))

    gyro_bias = gyro_b0 + gyro_drift
    accel_bias = accel_b0 + accel_drift
    return MemsImuData(t, ref.specific_force + accel_bias + accel_noise, ref.angular_rate + gyro_bias + gyro_noise,
                       np.zeros(n, dtype=bool), accel_bias, gyro_bias, accel_noise, gyro_noise, ref, spec, seed,
                       dt_nom)
