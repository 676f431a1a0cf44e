"""Error models for simulated pose observations: white, Gauss–Markov, map-matching failures.

KITTI has no lidar stream, so the course's lidar map-matching poses are **simulated**: the
ground truth plus an error drawn from one of these models (see
:func:`kalman_course.data.simulate_lidar_poses`). A model draws, at observation times
t (K,) s, an error sequence e (K, 6) = [δp, δθ]:

- δp (K, 3): position error, navigation frame, m (``p_obs = p + δp``);
- δθ (K, 3): attitude error as a rotation vector, body frame, rad (``R_obs = R Exp(δθ)``).

The models, each a small frozen dataclass with ``draw(t, rng)`` and ``describe()``:

- :class:`WhiteErrors` — independent N(0, σ²) per component and observation: the errors of
  the shipped excerpts, and what the course's filters assume.
- :class:`GaussMarkovErrors` — each component a stationary first-order Gauss–Markov process
  with time constant τ: the same σ as white, but correlated in time,
  e_k = φ_k e_{k−1} + σ √(1 − φ_k²) n_k, φ_k = exp(−Δt_k / τ).
- :class:`MapMatchingFailures` — a white or Gauss–Markov base plus two kinds of failure:
  jumps (a wrong map match that locks on, a constant offset held for a while, starting at a
  Poisson rate per second) and outliers (single observations with a large error, each with
  a given probability). The draw marks which observations a failure touched.

All randomness comes from the ``numpy.random.Generator`` passed to ``draw``, in the order
each model documents, so a draw is fully determined by its seed. Times may be irregular;
they must increase strictly.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.core.validation import as_rows, as_scalar

__all__ = ["ErrorDraw", "ObservationErrors", "WhiteErrors", "GaussMarkovErrors", "MapMatchingFailures"]


def _as_times(t) -> np.ndarray:
    """``t`` as a finite, strictly increasing float64 vector (K,), else a ValueError."""
    t = as_rows(t, "t", count="K")
    step = np.diff(t)
    if (step <= 0.0).any():
        k = int(np.argmax(step <= 0.0)) + 1
        raise ValueError(f"t must be strictly increasing: t[{k}] = {t[k]:g} <= t[{k - 1}] = {t[k - 1]:g}")
    return t


def _as_generator(rng) -> np.random.Generator:
    if not isinstance(rng, np.random.Generator):
        raise ValueError(f"rng must be a numpy.random.Generator (numpy.random.default_rng(seed)), "
                         f"got {type(rng).__name__}")
    return rng


def _readonly(arr: np.ndarray | None) -> np.ndarray | None:
    if arr is None:
        return None
    arr = np.array(arr, copy=True)
    arr.setflags(write=False)
    return arr


def _component_sigmas(sigma_position: float, sigma_attitude_deg: float) -> np.ndarray:
    """Per-component σ (6,): σ_p (m) three times, then σ_θ (rad) three times."""
    return np.r_[np.full(3, sigma_position), np.full(3, np.deg2rad(sigma_attitude_deg))]


def _set(obj, name: str, value) -> None:
    object.__setattr__(obj, name, value)


# ---------------------------------------------------------------------------------------
# What a model draws
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True, eq=False)
class ErrorDraw:
    """One draw of an error model at K observation times (read-only arrays).

    Attributes
    ----------
    error : numpy.ndarray, shape (K, 6)
        e = [δp, δθ]: position error (m, navigation frame), then the attitude error as a
        rotation vector (rad, body frame).
    jumps : numpy.ndarray of bool, shape (K,), or None
        True where a jump (a wrong map match held for a while) offsets the observation;
        None for a model without failures.
    outliers : numpy.ndarray of bool, shape (K,), or None
        True where the observation is an outlier; None for a model without failures.
    jump_times : numpy.ndarray, shape (n,), or None
        Start times of the n jumps drawn, s, increasing (some may precede t[0]: their
        offset is still held at the first observations); None for a model without failures.
    """

    error: np.ndarray
    jumps: np.ndarray | None = None
    outliers: np.ndarray | None = None
    jump_times: np.ndarray | None = None

    def __post_init__(self) -> None:
        for name in ("error", "jumps", "outliers", "jump_times"):
            _set(self, name, _readonly(getattr(self, name)))

    def __len__(self) -> int:
        return int(self.error.shape[0])

    @property
    def position(self) -> np.ndarray:
        """δp, shape (K, 3), m."""
        return np.ascontiguousarray(self.error[:, :3])

    @property
    def attitude(self) -> np.ndarray:
        """δθ, shape (K, 3), rad, body frame."""
        return np.ascontiguousarray(self.error[:, 3:])

    @property
    def failures(self) -> np.ndarray | None:
        """``jumps | outliers``, shape (K,): the observations a failure touched (None without failures)."""
        if self.jumps is None or self.outliers is None:
            return None
        return _readonly(self.jumps | self.outliers)


class ObservationErrors:
    """Base of the error models: ``draw(t, rng)`` and ``describe()``.

    Every model has ``sigma_position`` (m) and ``sigma_attitude_deg`` (degrees), the
    standard deviation per component of its continuous part (for
    :class:`MapMatchingFailures`, of its base model).
    """

    sigma_position: float
    sigma_attitude_deg: float

    def draw(self, t, rng: np.random.Generator) -> ErrorDraw:
        """Draw the errors e (K, 6) at times ``t`` (K,) s from ``rng``."""
        raise NotImplementedError

    def describe(self) -> str:
        """A short description for tables (the σ's are in ``sigma_position``/``sigma_attitude_deg``)."""
        raise NotImplementedError


def _check_sigmas(model) -> None:
    _set(model, "sigma_position", as_scalar(model.sigma_position, "sigma_position", allow_zero=True))
    _set(model, "sigma_attitude_deg", as_scalar(model.sigma_attitude_deg, "sigma_attitude_deg",
                                                allow_zero=True))


def _standard_normals(rng: np.random.Generator, K: int) -> np.ndarray:
    """n (K, 6): n_p (K, 3) drawn first, then n_θ (K, 3), as the shipped excerpts were drawn."""
    n_p = rng.standard_normal((K, 3))
    n_theta = rng.standard_normal((K, 3))
    return np.concatenate([n_p, n_theta], axis=1)


# ---------------------------------------------------------------------------------------
# White
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class WhiteErrors(ObservationErrors):
    """White errors: δp = σ_p n_p, δθ = σ_θ n_θ, independent at every observation.

    The model of the shipped excerpts. ``draw`` takes n_p (K, 3) and then n_θ (K, 3)
    standard normals from the generator, exactly as the excerpts were drawn.

    Parameters
    ----------
    sigma_position : float
        σ_p per axis, m (≥ 0).
    sigma_attitude_deg : float
        σ_θ per axis of the rotation vector, degrees (≥ 0).
    """

    sigma_position: float
    sigma_attitude_deg: float

    def __post_init__(self) -> None:
        _check_sigmas(self)

    def draw(self, t, rng: np.random.Generator) -> ErrorDraw:
        """Draw white errors at times ``t``.

        Parameters
        ----------
        t : array_like, shape (K,)
            Observation times, s, strictly increasing (only their number matters here).
        rng : numpy.random.Generator
            Source of n_p (K, 3), then n_θ (K, 3).

        Returns
        -------
        ErrorDraw
            ``error`` (K, 6) = [σ_p n_p, σ_θ n_θ] (m, rad); no failure masks.
        """
        K = len(_as_times(t))
        rng = _as_generator(rng)
        n_p = rng.standard_normal((K, 3))
        n_theta = rng.standard_normal((K, 3))
        error = np.concatenate([self.sigma_position * n_p, np.deg2rad(self.sigma_attitude_deg) * n_theta],
                               axis=1)
        return ErrorDraw(error)

    def describe(self) -> str:
        """``"white"``."""
        return "white"


# ---------------------------------------------------------------------------------------
# First-order Gauss–Markov
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class GaussMarkovErrors(ObservationErrors):
    """Stationary first-order Gauss–Markov errors, one independent process per component.

    For each of the six components with σ (σ_p in m, σ_θ in rad)::

        e_0 = σ n_0,   e_k = φ_k e_{k−1} + σ √(1 − φ_k²) n_k,   φ_k = exp(−(t_k − t_{k−1}) / τ)

    with n_k ~ N(0, 1). Every e_k has the white model's σ, and the correlation between
    observations Δt apart is exp(−Δt / τ): τ → 0 gives white errors, a large τ an error
    that barely changes between observations. Steps may be irregular; each uses its own Δt.
    ``draw`` takes the standard normals in the white model's order (n_p (K, 3), then
    n_θ (K, 3)), so where every φ_k is 0 the draw equals :class:`WhiteErrors`'.

    Parameters
    ----------
    sigma_position : float
        σ_p per axis, m (≥ 0).
    sigma_attitude_deg : float
        σ_θ per axis of the rotation vector, degrees (≥ 0).
    time_constant : float
        τ, s (> 0).
    """

    sigma_position: float
    sigma_attitude_deg: float
    time_constant: float

    def __post_init__(self) -> None:
        _check_sigmas(self)
        _set(self, "time_constant", as_scalar(self.time_constant, "time_constant"))

    def draw(self, t, rng: np.random.Generator) -> ErrorDraw:
        """Draw Gauss–Markov errors at times ``t``.

        Parameters
        ----------
        t : array_like, shape (K,)
            Observation times, s, strictly increasing (irregular steps allowed).
        rng : numpy.random.Generator
            Source of n (K, 6): n_p (K, 3) first, then n_θ (K, 3).

        Returns
        -------
        ErrorDraw
            ``error`` (K, 6) (m, rad); no failure masks.
        """
        t = _as_times(t)
        rng = _as_generator(rng)
        n = _standard_normals(rng, len(t))
        sigma = _component_sigmas(self.sigma_position, self.sigma_attitude_deg)
        return ErrorDraw(sigma * self._unit_process(t, n))

    def _unit_process(self, t: np.ndarray, n: np.ndarray) -> np.ndarray:
        """The process with σ = 1 driven by given standard normals.

        Parameters
        ----------
        t : numpy.ndarray, shape (K,)
            Strictly increasing times, s.
        n : numpy.ndarray, shape (K, m)
            Standard normal driving noise, one column per component.

        Returns
        -------
        numpy.ndarray, shape (K, m)
            x_0 = n_0, x_k = φ_k x_{k−1} + √(1 − φ_k²) n_k.
        """
        ratio = np.diff(t) / self.time_constant
        phi = np.exp(-ratio)
        gain = np.sqrt(-np.expm1(-2.0 * ratio))          # √(1 − φ²), accurate for small Δt/τ
        x = np.empty_like(n)
        if len(n):
            x[0] = n[0]
        for k in range(1, len(n)):
            x[k] = phi[k - 1] * x[k - 1] + gain[k - 1] * n[k]
        return x

    def describe(self) -> str:
        """For example ``"Gauss–Markov, τ = 1 s"``."""
        return f"Gauss–Markov, τ = {self.time_constant:g} s"


# ---------------------------------------------------------------------------------------
# Map-matching failures
# ---------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MapMatchingFailures(ObservationErrors):
    """A base error model plus map-matching failures: jumps and outliers.

    - Jumps: a wrong map match locks on. Jumps start at the times of a Poisson process of
      ``jump_rate`` per second; each draws one offset (σ ``jump_position`` m per axis,
      ``jump_attitude_deg`` degrees per rotation-vector axis) that is added to every
      observation with start ≤ t_k < start + ``jump_duration``. A jump that starts while
      another is held replaces it. Starts are drawn over [t_0 − duration, t_{K−1}], so a
      jump may already be held at the first observation and the fraction of observations
      in a jump is 1 − exp(−rate · duration) throughout.
    - Outliers: each observation independently, with probability ``outlier_rate``, gets
      one extra error (σ ``outlier_position`` m, ``outlier_attitude_deg`` degrees per axis).

    Draw order: the base model's draw, then the number of jumps (Poisson), their start
    times (uniform), their offsets (n, 6), the outlier flags (K uniforms) and the
    outliers' errors (one row of 6 per outlier). The base draw comes first, so with both
    rates 0 the errors equal the base model's draw for the same generator state.

    Parameters
    ----------
    base : WhiteErrors or GaussMarkovErrors
        The errors of a match that works.
    jump_rate : float
        Jumps per second (≥ 0).
    jump_position : float
        σ of a jump's position offset per axis, m (≥ 0).
    jump_attitude_deg : float
        σ of a jump's attitude offset per rotation-vector axis, degrees (≥ 0).
    jump_duration : float
        How long a jump is held, s (> 0 when ``jump_rate`` > 0).
    outlier_rate : float
        Probability that an observation is an outlier, in [0, 1].
    outlier_position : float
        σ of an outlier's position error per axis, m (≥ 0).
    outlier_attitude_deg : float
        σ of an outlier's attitude error per axis, degrees (≥ 0).

    Raises
    ------
    ValueError
        If a σ or rate is negative or not finite, ``outlier_rate`` exceeds 1, ``base`` is not
        a white or Gauss–Markov model, or a failure with a positive rate would change
        nothing (zero duration, or zero size).
    """

    base: ObservationErrors
    jump_rate: float = 0.0
    jump_position: float = 0.0
    jump_attitude_deg: float = 0.0
    jump_duration: float = 0.0
    outlier_rate: float = 0.0
    outlier_position: float = 0.0
    outlier_attitude_deg: float = 0.0

    def __post_init__(self) -> None:
        if not isinstance(self.base, (WhiteErrors, GaussMarkovErrors)):
            raise ValueError(f"base must be a WhiteErrors or GaussMarkovErrors, got {type(self.base).__name__}")
        for name in ("jump_rate", "jump_position", "jump_attitude_deg", "jump_duration", "outlier_rate",
                     "outlier_position", "outlier_attitude_deg"):
            _set(self, name, as_scalar(getattr(self, name), name, allow_zero=True))
        if self.outlier_rate > 1.0:
            raise ValueError(f"outlier_rate must be a probability in [0, 1], got {self.outlier_rate!r}")
        if self.jump_rate > 0.0 and self.jump_duration == 0.0:
            raise ValueError("jump_duration must be positive when jump_rate > 0 (a jump must be held)")
        if self.jump_rate > 0.0 and self.jump_position == 0.0 and self.jump_attitude_deg == 0.0:
            raise ValueError("jump_position or jump_attitude_deg must be positive when jump_rate > 0")
        if self.outlier_rate > 0.0 and self.outlier_position == 0.0 and self.outlier_attitude_deg == 0.0:
            raise ValueError("outlier_position or outlier_attitude_deg must be positive when outlier_rate > 0")

    @property
    def sigma_position(self) -> float:
        """The base model's σ_p, m."""
        return self.base.sigma_position

    @property
    def sigma_attitude_deg(self) -> float:
        """The base model's σ_θ, degrees."""
        return self.base.sigma_attitude_deg

    def draw(self, t, rng: np.random.Generator) -> ErrorDraw:
        """Draw the base errors and the failures at times ``t``.

        Parameters
        ----------
        t : array_like, shape (K,)
            Observation times, s, strictly increasing (irregular steps allowed).
        rng : numpy.random.Generator
            Source of every random number, in the order given in the class docstring.

        Returns
        -------
        ErrorDraw
            ``error`` (K, 6) (m, rad), ``jumps`` and ``outliers`` (K,) masks, ``jump_times``.
        """
        t = _as_times(t)
        rng = _as_generator(rng)
        error = np.array(self.base.draw(t, rng).error)
        starts, offsets = self._draw_jumps(t, rng)
        jumps = self._add_jumps(error, t, starts, offsets)
        outliers = rng.random(len(t)) < self.outlier_rate
        size = _component_sigmas(self.outlier_position, self.outlier_attitude_deg)
        error[outliers] += size * rng.standard_normal((int(outliers.sum()), 6))
        return ErrorDraw(error, jumps, outliers, starts)

    def _draw_jumps(self, t: np.ndarray, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Jump start times (n,) s, increasing, and their offsets (n, 6) (m, rad)."""
        if len(t) == 0:
            return np.empty(0), np.empty((0, 6))
        first, last = t[0] - self.jump_duration, t[-1]
        count = rng.poisson(self.jump_rate * (last - first))
        starts = np.sort(rng.uniform(first, last, count))
        size = _component_sigmas(self.jump_position, self.jump_attitude_deg)
        return starts, size * rng.standard_normal((count, 6))

    def _add_jumps(self, error: np.ndarray, t: np.ndarray, starts: np.ndarray,
                   offsets: np.ndarray) -> np.ndarray:
        """Add to each row of ``error`` the offset of the jump held then; return the (K,) mask."""
        latest = np.searchsorted(starts, t, side="right") - 1        # last start ≤ t_k, or −1
        held = latest >= 0
        held[held] = t[held] < starts[latest[held]] + self.jump_duration
        error[held] += offsets[latest[held]]
        return held

    def describe(self) -> str:
        """For example ``"white + jumps 0.02/s × 2 s (2 m, 1°) + outliers 1% (5 m, 5°)"``."""
        parts = [self.base.describe()]
        if self.jump_rate > 0.0:
            parts.append(f"jumps {self.jump_rate:g}/s × {self.jump_duration:g} s "
                         f"({self.jump_position:g} m, {self.jump_attitude_deg:g}°)")
        if self.outlier_rate > 0.0:
            parts.append(f"outliers {100 * self.outlier_rate:g}% "
                         f"({self.outlier_position:g} m, {self.outlier_attitude_deg:g}°)")
        if len(parts) == 1:
            parts.append("no failures (rates 0)")
        return " + ".join(parts)
