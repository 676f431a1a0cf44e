"""Motion models against real driving (chapter 04): true planar states from KITTI and
how far each model's prediction drifts from the ground truth as the horizon grows.

The model states are read off the KITTI ground truth (10 Hz poses with velocities) and the
IMU: position and velocity from the truth; speed v and heading ψ from the horizontal
velocity; acceleration from a centred difference of the velocity over ±``half_window`` s;
turn rate ω from the gyro's z axis (body z is close to vertical on these roads).

Each model's discrete step is the exact flow of its ODE (``symbolic.motion_step``), so a
prediction over any horizon is one call with T = horizon, noise zero.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from kalman_course import symbolic
from kalman_course.core.validation import as_scalar, as_vector
from kalman_course.data import load_kitti
from kalman_course.evaluation.metrics import position_rmse

__all__ = ["kitti_model_states", "HorizonErrors", "horizon_errors", "predicted_paths"]


def _check_model(model: str) -> None:
    if model not in symbolic.MOTION_MODELS:
        raise ValueError(f"model must be one of {symbolic.MOTION_MODELS}, got {model!r}")


def kitti_model_states(name: str, model: str, t=None, half_window: float = 0.5):
    """True states of ``model`` on KITTI excerpt ``name``.

    Parameters
    ----------
    name : str
        Excerpt ("cruise", "turns", "stop_go" or "seq00").
    model : {"cv", "ca", "ctrv", "ctra"}
    t : array_like, optional
        Times (inside the excerpt, away from its ends by ``half_window``); default: the
        ground-truth times that allow it.
    half_window : float
        Half-width of the centred difference that gives accelerations, s.

    Returns
    -------
    t : ndarray, shape (N,)
    states : ndarray, shape (N, n)
        In the order of ``symbolic.motion_state_names(model)``.
    """
    _check_model(model)
    half_window = as_scalar(half_window, "half_window")
    ex = load_kitti(name)
    truth = ex.truth
    if t is None:
        t = truth.t[(truth.t >= truth.t[0] + half_window) & (truth.t <= truth.t[-1] - half_window)]
    t = as_vector(t, "t")
    now = truth.interpolate(t)
    before = truth.interpolate(t - half_window).velocity[:, :2]
    after = truth.interpolate(t + half_window).velocity[:, :2]
    p, vel = now.position[:, :2], now.velocity[:, :2]
    acc = (after - before) / (2 * half_window)
    speed = np.linalg.norm(vel, axis=1)
    yaw = np.arctan2(vel[:, 1], vel[:, 0])
    long_acc = (np.linalg.norm(after, axis=1) - np.linalg.norm(before, axis=1)) / (2 * half_window)
    omega = np.interp(t, ex.imu.t, ex.imu.angular_rate[:, 2])
    columns = {
        "cv": (p[:, 0], p[:, 1], vel[:, 0], vel[:, 1]),
        "ca": (p[:, 0], p[:, 1], vel[:, 0], vel[:, 1], acc[:, 0], acc[:, 1]),
        "ctrv": (p[:, 0], p[:, 1], speed, yaw, omega),
        "ctra": (p[:, 0], p[:, 1], speed, yaw, omega, long_acc),
    }
    return t, np.column_stack(columns[model])


@dataclass(frozen=True, eq=False)
class HorizonErrors:
    """Position error of each model's prediction, per horizon.

    Attributes
    ----------
    horizons : ndarray, shape (H,)
        Prediction horizons, s.
    models : tuple of str
    rms : ndarray, shape (M, H)
        RMS horizontal position error over all start times, m.
    p95 : ndarray, shape (M, H)
        95th percentile of the error, m.
    n_starts : int
    """

    horizons: np.ndarray
    models: tuple
    rms: np.ndarray
    p95: np.ndarray
    n_starts: int


def horizon_errors(name: str, horizons=(0.5, 1.0, 2.0, 3.0, 5.0), models=symbolic.MOTION_MODELS,
                   start_every: float = 1.0, speed_min: float = 1.0) -> HorizonErrors:
    """Predict the KITTI truth ahead from true states and measure the position error.

    Start times are every ``start_every`` s where the car moves faster than
    ``speed_min`` m/s (heading is undefined at rest) and the longest horizon still lies
    inside the excerpt.

    Parameters
    ----------
    name : str
        KITTI excerpt.
    horizons : array_like, shape (H,)
        Prediction horizons, s, each > 0.
    models : sequence of str
        Models to compare, from ``symbolic.MOTION_MODELS``.
    start_every : float
        Spacing of the start times, s.
    speed_min : float
        Slowest speed at a start time, m/s.

    Returns
    -------
    HorizonErrors
    """
    horizons = as_vector(horizons, "horizons")
    if (horizons <= 0).any():
        raise ValueError(f"horizons must be positive, got {horizons}")
    for model in models:
        _check_model(model)
    start_every = as_scalar(start_every, "start_every")
    speed_min = as_scalar(speed_min, "speed_min", allow_zero=True)
    truth = load_kitti(name).truth
    margin = 0.5
    starts = np.arange(truth.t[0] + margin, truth.t[-1] - margin - horizons.max(), start_every)
    _, cv_states = kitti_model_states(name, "cv", starts)
    starts = starts[np.linalg.norm(cv_states[:, 2:4], axis=1) > speed_min]
    rms = np.empty((len(models), len(horizons)))
    p95 = np.empty_like(rms)
    for j, h in enumerate(horizons):
        target = truth.interpolate(starts + h).position[:, :2]
        for i, model in enumerate(models):
            _, states = kitti_model_states(name, model, starts)
            pred = np.array([symbolic.motion_step(model, s, h)[:2] for s in states])
            rms[i, j] = position_rmse(pred, target)
            p95[i, j] = np.percentile(np.linalg.norm(pred - target, axis=1), 95)
    return HorizonErrors(horizons, tuple(models), rms, p95, len(starts))


def predicted_paths(name: str, t0: float, horizon: float, models=symbolic.MOTION_MODELS, n: int = 31):
    """Each model's predicted path from the true state at ``t0``, and the true path.

    Returns
    -------
    t : ndarray, shape (n,)
        Times t0 … t0 + horizon, s.
    truth : ndarray, shape (n, 2)
        True horizontal positions, m.
    paths : dict of str to ndarray, shape (n, 2)
        Predicted positions per model, m.
    """
    truth = load_kitti(name).truth
    steps = np.linspace(0.0, horizon, n)
    paths = {}
    for model in models:
        _, state = kitti_model_states(name, model, [t0])
        paths[model] = np.array([symbolic.motion_step(model, state[0], h)[:2] for h in steps])
    return t0 + steps, truth.interpolate(t0 + steps).position[:, :2], paths

