"""The numbers of the nonlinear chapters (04–06).

Run ``python benchmarks/ekf_report.py``. It prints

1. the reference CTRV EKF's RMSE per state ([p_x, p_y, v_x, v_y], as in the seed
   article) on the seeded lidar + radar scenario (seed 0), with each sensor alone for
   comparison, and the spread of the fused RMSE over seeds 0–9; targets 0.11 m and
   0.52 m/s;
2. EKF vs iterated EKF on the chapter 06 KITTI case (precise range–bearing to beacons
   along the ``turns`` excerpt): position RMSE, mean NEES (4 for a consistent filter) and
   iterations per update, plus the near-linear control case (far beacons);
3. the CTRV EKF on the KITTI excerpts with 1 Hz GNSS and the gyro's yaw rate;
4. the median wall time of one EKF update (radar, 5-state CTRV, SymPy-derived g and G,
   validated public ``ekf.ekf_update``) and of one prediction, over many calls.
"""

from __future__ import annotations

import time

import numpy as np

from kalman_course import symbolic
from kalman_course.chapters import beacons, lidar_radar
from kalman_course.chapters.lidar_radar import ctrv_lidar_radar
from kalman_course.data import load_kitti
from kalman_course.filters import ekf
from kalman_course.tooling.bench import median_time

TARGET_POS, TARGET_VEL = 0.11, 0.52


def lidar_radar_table() -> None:
    sc = ctrv_lidar_radar(seed=0)
    print("1. Lidar + radar CTRV EKF, ctrv_lidar_radar(seed=0): RMSE")
    print(f"   {'':14} {'px [m]':>8} {'py [m]':>8} {'vx [m/s]':>9} {'vy [m/s]':>9}")
    for name, kwargs in (("lidar + radar", {}), ("lidar only", {"use_radar": False}),
                         ("radar only", {"use_lidar": False}), ("IEKF (radar)", {"iterated": True})):
        r = lidar_radar.fuse_lidar_radar(sc, **kwargs).rmse
        print(f"   {name:14} {r['px']:8.3f} {r['py']:8.3f} {r['vx']:9.3f} {r['vy']:9.3f}")
    print(f"   {'target':14} {TARGET_POS:8.3f} {TARGET_POS:8.3f} {TARGET_VEL:9.3f} {TARGET_VEL:9.3f}")
    rows = np.array([[lidar_radar.fuse_lidar_radar(ctrv_lidar_radar(seed)).rmse[k] for k in ("px", "py", "vx", "vy")]
                     for seed in range(10)])
    ok = (rows[:, :2].max(axis=1) <= TARGET_POS) & (rows[:, 2:].max(axis=1) <= TARGET_VEL)
    print(f"   seeds 0-9, fused: median {np.array2string(np.median(rows, axis=0), precision=3)}, "
          f"max {np.array2string(rows.max(axis=0), precision=3)}; {ok.sum()}/10 seeds meet both targets")


def beacon_table() -> None:
    print("\n2. Chapter 06, KITTI 'turns', range-bearing to the 2 nearest beacons (4 m off the road)")
    print(f"   {'case':22} {'filter':6} {'pos RMSE [m]':>13} {'mean NEES':>10} {'iter/update':>12}")
    for case, kwargs in (("precise, near (seed 1)", {}),
                         ("far beacons (100 m)", {"offset": 100.0, "sigma_range": 0.5})):
        sc = beacons.kitti_beacons("turns", 1, **kwargs)
        for name, iterated in (("EKF", False), ("IEKF", True)):
            r = beacons.run_beacon_filter(sc, iterated=iterated)
            print(f"   {case:22} {name:6} {r.position_rmse:13.3f} {r.mean_nees:10.2f} {r.iterations.mean():12.2f}")
    wins = 0
    for seed in range(10):
        sc = beacons.kitti_beacons("turns", seed)
        e, i = beacons.run_beacon_filter(sc), beacons.run_beacon_filter(sc, iterated=True)
        wins += i.position_rmse < 0.5 * e.position_rmse
    print(f"   seeds 0-9 (near beacons): the IEKF halves the EKF's RMSE in {wins}/10")


def kitti_ctrv_table() -> None:
    print("\n3. CTRV EKF on KITTI, 1 Hz GNSS (sigma 1 m) + gyro yaw rate: horizontal RMSE")
    print(f"   {'excerpt':8} {'GNSS [m]':>9} {'EKF at fixes [m]':>17} {'EKF all steps [m]':>18}")
    for name in ("cruise", "turns", "stop_go"):
        r = lidar_radar.run_kitti_ctrv(load_kitti(name))
        print(f"   {name:8} {r.gnss_rmse:9.3f} {r.ekf_rmse:17.3f} {r.ekf_rmse_all:18.3f}")


def timing() -> None:
    x = np.array([5.0, 2.0, 5.0, 0.5, 0.1])
    P = np.diag([0.1, 0.1, 1.0, 0.2, 0.05])
    R = np.diag([0.09, 0.0009, 0.09])
    y = symbolic.radar_observation(x) + np.array([0.1, 0.01, -0.1])
    Qw = np.diag([9.0, 0.09])
    dt = 0.05

    def update():
        ekf.ekf_update(x, P, y, symbolic.radar_observation, symbolic.radar_jacobian, R,
                       residual=ekf.radar_residual, joseph=True)

    def iterated():
        ekf.iekf_update(x, P, y, symbolic.radar_observation, symbolic.radar_jacobian, R,
                        residual=ekf.radar_residual, joseph=True)

    def predict():
        ekf.ekf_predict(x, P, lambda s: symbolic.ctrv_step(s, dt), symbolic.ctrv_jacobian(x, dt), Qw,
                        symbolic.ctrv_noise_jacobian(x, dt))

    print("\n4. Median wall time per call (5-state CTRV, radar, SymPy-lambdified models, validated API)")
    print(f"   EKF update (radar, Joseph)   {median_time(update) * 1e6:8.1f} us")
    print(f"   IEKF update (radar, Joseph)  {median_time(iterated) * 1e6:8.1f} us")
    print(f"   EKF predict (CTRV, F and B)  {median_time(predict) * 1e6:8.1f} us")
    sc = ctrv_lidar_radar(seed=0)
    t0 = time.perf_counter()
    lidar_radar.fuse_lidar_radar(sc)
    print(f"   whole lidar + radar run ({len(sc)} measurements): {time.perf_counter() - t0:.3f} s")


def main() -> None:
    lidar_radar_table()
    beacon_table()
    kitti_ctrv_table()
    timing()


if __name__ == "__main__":
    main()
