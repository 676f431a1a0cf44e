"""Data for the course: KITTI sequence 00 excerpts and seeded synthetic scenarios.

KITTI (real data, shipped in ``kalman_course/data/kitti/``; KITTI is CC BY-NC-SA 3.0,
Geiger et al., IJRR 2013)::

    from kalman_course.data import load_kitti, EXCERPTS
    ex = load_kitti("turns")        # "cruise", "turns", "stop_go" or "seq00"
    ex.imu.t, ex.imu.specific_force, ex.imu.angular_rate, ex.imu.interpolated
    ex.gnss.position, ex.gnss.position_noisy
    ex.truth.position, ex.truth.velocity, ex.truth.quaternion, ex.truth.rotation
    ex.lidar.position, ex.lidar.rotation     # SIMULATED: truth + seeded noise
    ex.orb_slam2, ex.sptam                   # real visual-SLAM estimates

Synthetic scenarios (seeded, exact truth): ``random_walk_1d``, ``cv_target``,
``ctrv_lidar_radar`` and ``imu_trajectory``.

Rebuild the shipped files with ``python -m kalman_course.data.build``.
"""

from kalman_course.data.kitti import (EXCERPTS, SCHEMA_VERSION, FrameInfo, GnssData, ImuData,
                                      KittiExcerpt, LidarData, SlamData, TruthData, kitti_dir,
                                      load_excerpt_file, load_kitti, read_manifest, simulate_gnss,
                                      simulate_lidar_poses)
from kalman_course.data.synthetic import (CTRVScenario, CVTarget, ImuScenario, Measurement,
                                          RandomWalk1D, ctrv_lidar_radar, ctrv_step, cv_target,
                                          imu_trajectory, radar_measurement, random_walk_1d)

__all__ = [
    "EXCERPTS", "SCHEMA_VERSION", "FrameInfo", "GnssData", "ImuData", "KittiExcerpt", "LidarData",
    "SlamData", "TruthData", "kitti_dir", "load_excerpt_file", "load_kitti", "read_manifest",
    "simulate_gnss", "simulate_lidar_poses",
    "CTRVScenario", "CVTarget", "ImuScenario", "Measurement", "RandomWalk1D", "ctrv_lidar_radar",
    "ctrv_step", "cv_target", "imu_trajectory", "radar_measurement", "random_walk_1d",
]
