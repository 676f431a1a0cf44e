"""Anchor numbers on the shipped KITTI sequence 00 data.

Run ``python benchmarks/kitti_anchors.py``. It prints

1. the ATE RMSE of the ORB-SLAM2 and S-PTAM estimates over all of sequence 00
   (SE(3) Umeyama alignment without scale, cam0 positions), in the KITTI ground-truth frame
   (the published figures: 1.30 m and 3.74 m) and in the navigation frame;
2. the position error of pure IMU dead reckoning (midpoint integration, no bias
   estimation) after 10 s and 30 s on each excerpt, started from the true state at the
   first IMU sample after the excerpt's first ground-truth pose.
"""

from __future__ import annotations

import sys
import time

import numpy as np

from kalman_course.data import load_kitti
from kalman_course.core.imu import dead_reckon
from kalman_course.evaluation.trajectory import ate_rmse


def slam_ate() -> list[tuple[str, float, float, float]]:
    """(name, ATE cam0 in the GT frame, ATE cam0 in the nav frame, ATE of IMU positions) in m."""
    seq = load_kitti("seq00")
    f = seq.frames
    cam_truth = f.cam0_position(seq.truth.position, seq.truth.rotation)
    rows = []
    for track in (seq.orb_slam2, seq.sptam):
        cam = f.cam0_position(track.position, track.rotation)
        ate_nav = ate_rmse(cam, cam_truth)
        # the nav frame is the GT frame scaled by s, so distances there are s times larger
        rows.append((track.name, ate_nav / f.scale, ate_nav, ate_rmse(track.position, seq.truth.position)))
    return rows


def dead_reckoning_drift(name: str, horizons=(10.0, 30.0)) -> list[float]:
    """Position error (m) of pure dead reckoning after each horizon (s) on excerpt ``name``."""
    ex = load_kitti(name)
    k0, state = ex.initial_state()
    traj = dead_reckon(ex.imu, state, ex.gravity, start=k0)
    errors = []
    for horizon in horizons:
        k = int(np.searchsorted(traj.t, traj.t[0] + horizon))
        if k >= len(traj.t) or traj.t[k] > ex.truth.t[-1]:
            errors.append(float("nan"))
            continue
        truth = ex.truth.interpolate(traj.t[k:k + 1]).position[0]
        errors.append(float(np.linalg.norm(traj.position[k] - truth)))
    return errors


def main() -> int:
    start = time.perf_counter()
    print("ATE RMSE over all of KITTI sequence 00 (SE(3) Umeyama, no scale)")
    print(f"  {'estimate':10s} {'cam0, GT frame':>15s} {'cam0, nav frame':>16s} {'IMU, nav frame':>15s}")
    for name, gt_frame, nav_frame, imu in slam_ate():
        print(f"  {name:10s} {gt_frame:13.3f} m {nav_frame:14.3f} m {imu:13.3f} m")
    print()
    print("Pure-IMU dead reckoning from the true initial state (midpoint, no bias estimation)")
    print(f"  {'excerpt':10s} {'after 10 s':>11s} {'after 30 s':>11s}")
    for name in ("cruise", "turns", "stop_go"):
        e10, e30 = dead_reckoning_drift(name)
        print(f"  {name:10s} {e10:9.2f} m {e30:9.2f} m")
    print()
    print(f"({time.perf_counter() - start:.2f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
