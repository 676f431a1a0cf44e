"""What the bias states of the chapter-08 ESKF find on KITTI, and what they cannot see.

Three measurements that say how much the bias model matters on this (real) IMU:

- :func:`bias_in_sigmas` — the final bias estimates in units of the filter's own σ of them:
  an estimate within about one σ of zero is indistinguishable from no bias;
- :func:`frozen_bias` — a filter with no bias to estimate: the constant-bias model with the
  bias blocks of P₀ set to zero, so the gain on the biases is zero and they stay at zero.
  If it does as well as the reference, the data carry no information about the biases;
- :func:`earth_rate` — the Earth's rotation, which the filter neglects (its gyro model has
  no Earth-rate term): its size at a latitude, to compare with the gyro-bias σ reached.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course.chapters.consistency import _config
from kalman_course.core.validation import as_scalar
from kalman_course.filters import eskf

__all__ = ["bias_in_sigmas", "frozen_bias", "EarthRate", "earth_rate", "EARTH_RATE", "RAD_PER_S_TO_DEG_PER_H"]

#: The Earth's sidereal rotation rate Ω_E (WGS-84), rad/s.
EARTH_RATE = 7.292115e-5

#: Factor from rad/s to °/h.
RAD_PER_S_TO_DEG_PER_H = float(np.rad2deg(1.0) * 3600.0)

_ACCEL_BIAS = slice(9, 12)
_GYRO_BIAS = slice(12, 15)


def bias_in_sigmas(result) -> tuple[np.ndarray, np.ndarray]:
    """The last bias estimates divided by the filter's own σ of them.

    Parameters
    ----------
    result : EskfResult
        A filter run (``accel_bias`` (K, 3) m/s², ``gyro_bias`` (K, 3) rad/s, ``P`` (K, 15, 15)).

    Returns
    -------
    accel, gyro : numpy.ndarray, shape (3,)
        b̂_a / σ(b_a) and b̂_ω / σ(b_ω) at the last row, per axis, dimensionless.

    Raises
    ------
    ValueError
        If the result has no rows, or a bias σ is zero (the biases were frozen).
    """
    if len(result.t) == 0:
        raise ValueError("result must hold at least one row")
    sd = np.sqrt(np.diag(result.P[-1]))
    if np.any(sd[9:15] <= 0.0):
        raise ValueError("the result's bias σ is zero (a frozen-bias run): the estimate has no σ to compare with")
    return result.accel_bias[-1] / sd[_ACCEL_BIAS], result.gyro_bias[-1] / sd[_GYRO_BIAS]


def frozen_bias(config) -> tuple:
    """Settings and P₀ of a filter whose biases stay at zero.

    The constant-bias model has no noise driving δb (its B has no bias columns), and with
    the bias rows and columns of P₀ zero, P keeps them zero at every prediction and update:
    the gain on the biases is zero and their estimates never leave zero. The other blocks of
    P₀ are the configuration's prior.

    Parameters
    ----------
    config : EskfConfig or str

    Returns
    -------
    config : EskfConfig
        ``config`` with ``bias_model="constant"``.
    P0 : numpy.ndarray, shape (15, 15)
        Diagonal prior with zero bias blocks.
    """
    cfg = _config(config)
    frozen = cfg.replace(bias_model="constant")
    P0 = eskf.initial_covariance(frozen)
    P0[9:, :] = 0.0
    P0[:, 9:] = 0.0
    return frozen, P0


@dataclass(frozen=True)
class EarthRate:
    """The Earth's rotation seen from a local level frame, rad/s.

    Attributes
    ----------
    latitude_deg : float
        Geodetic latitude φ, degrees.
    total : float
        Ω_E.
    horizontal : float
        Ω_E cos φ, along the local north.
    vertical : float
        Ω_E sin φ, along the local up.
    """

    latitude_deg: float
    total: float
    horizontal: float
    vertical: float

    def deg_per_hour(self) -> tuple[float, float, float]:
        """(total, horizontal, vertical) in °/h."""
        return tuple(v * RAD_PER_S_TO_DEG_PER_H for v in (self.total, self.horizontal, self.vertical))


def earth_rate(latitude_deg: float, rate: float = EARTH_RATE) -> EarthRate:
    """The Earth's rotation rate and its north and up components at a latitude.

    A gyroscope at rest measures the Earth's rotation: Ω_E cos φ about north and Ω_E sin φ
    about up. A filter that neglects it reads both as vehicle rotation (or, when they stay
    fixed in the body frame, as a gyro bias).

    Parameters
    ----------
    latitude_deg : float
        Geodetic latitude φ in degrees, in [−90, 90].
    rate : float
        Ω_E, rad/s (default WGS-84, 7.292115e-5).

    Returns
    -------
    EarthRate

    Raises
    ------
    ValueError
        If the latitude is not finite or outside [−90, 90], or the rate is not positive.
    """
    try:
        phi = float(latitude_deg) if not isinstance(latitude_deg, (str, bytes, bool, np.bool_)) else np.nan
    except (TypeError, ValueError):
        phi = np.nan
    if not np.isfinite(phi) or abs(phi) > 90.0:
        raise ValueError(f"latitude_deg must be a number of degrees in [-90, 90], got {latitude_deg!r}")
    omega = as_scalar(rate, "rate")
    return EarthRate(phi, omega, omega * np.cos(np.deg2rad(phi)), omega * np.sin(np.deg2rad(phi)))
