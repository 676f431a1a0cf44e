"""Observation streams for the error-state filters: what a sensor reports, its noise, where it sits.

A stream is one sensor's record (:class:`~kalman_course.core.observations.PositionObservations`
or :class:`~kalman_course.core.observations.PoseObservations`) together with

- its noise: a standard deviation per component, or a full covariance R;
- its kind: ``"position"`` (y ∈ ℝ³) or ``"pose"`` (position and attitude, y ∈ ℝ⁶);
- its extrinsics: the lever arm l (the sensor's origin in the body frame, m) and the
  rotation R_bs (sensor frame → body frame). By default the sensor sits at the body origin,
  axes aligned.

The measurement model, with the body's pose (p, R = R_nb) in the navigation frame:

    position:  p_s = p + R l                      (the sensor's position)
    attitude:  R_ns = R R_bs                      (the sensor's attitude)

and, with the ESKF's error convention (p̌ = p + δp, Ř = R Exp(δθ)), the residual of a
report (p_m, R_m) and its Jacobian with respect to [δp, δθ]:

    y_p = p̌ + Ř l − p_m                ≈ δp − Ř [l]× δθ
    y_θ = Log(R_mᵀ Ř R_bs)             ≈ R_bsᵀ δθ

because p + R l = p̌ − δp + Ř Exp(−δθ) l ≈ p̌ + Ř l − δp + Ř [l]× δθ, and
Ř R_bs = R R_bs Exp(R_bsᵀ δθ). With l = 0 and R_bs = I these are the filters' plain lidar
pose and GNSS position residuals, and this module computes them with the same operations.

A zero standard deviation is allowed: it says that component is known exactly. The update
then needs the innovation covariance S = G P̌ Gᵀ + R to be non-singular, which holds while
the filter is uncertain about what the sensor measures.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy import dot

from kalman_course.core import so3
from kalman_course.core.observations import PoseObservations, PositionObservations
from kalman_course.core.validation import as_covariance, as_rotation, as_scalar, as_vector

__all__ = ["ObservationStream", "STREAM_KINDS"]

#: The kinds of stream and the size of their residual.
STREAM_KINDS = {"position": 3, "pose": 6}

_I3 = np.eye(3)


def _as_record(observations, kind: str, name: str):
    """``observations`` as the record ``kind`` needs, validated there."""
    if kind == "pose":
        if isinstance(observations, PoseObservations):
            return observations
        if not all(hasattr(observations, f) for f in ("t", "position", "rotation")):
            raise ValueError(f"{name}: a pose stream needs observations with t, position and rotation "
                             f"(a PoseObservations), got {type(observations).__name__}")
        fields = ("t", "position", "rotation")
        record = PoseObservations
    else:
        if isinstance(observations, PositionObservations):
            return observations
        if not all(hasattr(observations, f) for f in ("t", "position")):
            raise ValueError(f"{name}: a position stream needs observations with t and position "
                             f"(a PositionObservations), got {type(observations).__name__}")
        fields = ("t", "position")
        record = PositionObservations
    try:
        return record(**{f: getattr(observations, f) for f in fields})
    except ValueError as exc:
        raise ValueError(f"{name}: {exc}") from None


def _as_noise(noise, m: int, name: str) -> np.ndarray:
    """R (m, m) from standard deviations (m,) or a covariance (m, m); zeros allowed."""
    try:
        shape = np.shape(noise)
    except ValueError:                          # a ragged list
        shape = None
    if shape is not None and len(shape) == 2:
        return np.array(as_covariance(noise, f"{name}.noise", m, psd=True))
    if shape == () and m == 3:
        std = np.full(3, as_scalar(noise, f"{name}.noise", allow_zero=True))
    elif shape == (m,):
        std = as_vector(noise, f"{name}.noise", m)
    else:
        raise ValueError(f"{name}.noise must be {m} standard deviations (m{', then rad' if m == 6 else ''}) "
                         f"or an ({m}, {m}) covariance, got shape {shape}")
    if (std < 0.0).any():
        raise ValueError(f"{name}.noise: standard deviations must be ≥ 0 (0 = known exactly), got {std}")
    return np.diag(std ** 2)


@dataclass(frozen=True, eq=False)
class ObservationStream:
    """One sensor's observations with their noise and the sensor's mounting on the body.

    Parameters
    ----------
    observations : PositionObservations or PoseObservations
        The reports: ``t`` (K,), ``position`` (K, 3) and for a pose stream ``rotation``
        (K, 3, 3), navigation frame. Another object with these attributes is converted
        (and validated).
    noise : float or array_like, shape (m,) or (m, m)
        Standard deviations per component (m: position, then rad: attitude), or the
        covariance R. One number is accepted for a position stream (the same σ on each
        axis). Zero means known exactly.
    kind : {"position", "pose"}, optional
        Default: ``"pose"`` for a record with rotations, else ``"position"``. A pose record
        may be fused as ``"position"`` (its attitudes are then not used).
    lever_arm : array_like, shape (3,), optional
        l: the sensor's origin in the body frame, m (default 0).
    rotation : array_like, shape (3, 3), optional
        R_bs: sensor frame → body frame (default I); only a pose stream's attitude uses it.
    name : str, optional
        Used in error messages and in the filter result's ``sources``.

    Attributes
    ----------
    R : numpy.ndarray, shape (m, m)
        The noise covariance.
    m : int
        The residual's size (3 or 6).
    """

    observations: object
    noise: object
    kind: str | None = None
    lever_arm: object = None
    rotation: object = None
    name: str = "stream"

    def __post_init__(self) -> None:
        name = self.name
        if not isinstance(name, str) or not name:
            raise ValueError(f"name must be a non-empty string, got {name!r}")
        kind = self.kind
        if kind is None:
            kind = "pose" if hasattr(self.observations, "rotation") else "position"
        if kind not in STREAM_KINDS:
            raise ValueError(f"{name}.kind must be 'position' or 'pose', got {kind!r}")
        record = _as_record(self.observations, kind, name)
        lever = np.zeros(3) if self.lever_arm is None else np.array(as_vector(self.lever_arm, f"{name}.lever_arm", 3))
        R_bs = _I3 if self.rotation is None else np.array(as_rotation(self.rotation, f"{name}.rotation"))
        if kind == "position" and self.rotation is not None:
            raise ValueError(f"{name}.rotation (R_bs) only applies to a pose stream; a position stream "
                             "measures the sensor's position, which the lever arm alone fixes")
        R = _as_noise(self.noise, STREAM_KINDS[kind], name)
        for attr, value in (("kind", kind), ("observations", record), ("lever_arm", lever),
                            ("rotation", R_bs), ("R", R)):
            object.__setattr__(self, attr, value)
        object.__setattr__(self, "_plain_position", not lever.any())
        object.__setattr__(self, "_plain_rotation", R_bs is _I3)

    @property
    def plain(self) -> bool:
        """True for a sensor at the body origin with its axes aligned (l = 0, R_bs = I)."""
        return self._plain_position and self._plain_rotation

    @property
    def m(self) -> int:
        return STREAM_KINDS[self.kind]

    @property
    def t(self) -> np.ndarray:
        return self.observations.t

    def __len__(self) -> int:
        return len(self.observations)

    def __repr__(self) -> str:
        return f"ObservationStream({self.name!r}, {self.kind}, {len(self)} reports)"

    # the measurement model (unvalidated: the filters call these per update)

    def residual(self, k: int, p_check, R_check) -> np.ndarray:
        """y (m,) of report ``k`` against the nominal pose (p̌ (3,), Ř (3, 3)); see the module docstring."""
        p_m = self.observations.position[k]
        y_p = p_check - p_m if self._plain_position else p_check + dot(R_check, self.lever_arm) - p_m
        if self.kind == "position":
            return y_p
        R_s = R_check if self._plain_rotation else dot(R_check, self.rotation)
        return np.concatenate([y_p, so3.log(dot(self.observations.rotation[k].T, R_s), check=False)])

    def jacobian(self, R_check) -> np.ndarray:
        """∂y/∂[δp, δθ] (m, 6) at the nominal attitude Ř (3, 3)."""
        H = np.zeros((self.m, 6))
        H[:3, :3] = _I3
        if not self._plain_position:
            H[:3, 3:] = -dot(R_check, so3.hat(self.lever_arm, check=False))
        if self.kind == "pose":
            H[3:, 3:] = self.rotation.T
        return H
