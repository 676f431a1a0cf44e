"""Data for the course: KITTI sequence 00 excerpts and seeded synthetic scenarios.

KITTI (real data, shipped in ``kalman_course/data/kitti/``; KITTI is CC BY-NC-SA 3.0,
Geiger et al., IJRR 2013)::

    from kalman_course.data import load_kitti, EXCERPTS
    ex = load_kitti("turns")        # "cruise", "turns", "stop_go" or "seq00"
    ex.imu.t, ex.imu.specific_force, ex.imu.angular_rate, ex.imu.interpolated
    ex.gnss.position_noisy           # SIMULATED fixes (σ = 1 m); ex.gnss.position_true: the solution
    ex.gnss.observations()           # the fixes as a filter takes them (PositionObservations)
    ex.truth.position, ex.truth.velocity, ex.truth.quaternion, ex.truth.rotation
    ex.lidar.position, ex.lidar.rotation     # SIMULATED: truth + seeded white noise (a PoseObservations)
    ex.orb_slam2, ex.sptam                   # real visual-SLAM estimates

Simulated lidar errors other than the shipped white noise (``observation_errors``)::

    from kalman_course.data import GaussMarkovErrors, MapMatchingFailures, WhiteErrors
    lidar = simulate_lidar_poses(ex.truth, seed=7, errors=GaussMarkovErrors(0.2, 0.3, time_constant=1.0))
    lidar.error_model, lidar.failures        # "Gauss–Markov, τ = 1 s", None (a mask for failures)

Synthetic scenarios (seeded, exact truth): ``random_walk_1d``, ``cv_target`` and
``imu_trajectory``. The chapter 05 lidar + radar scenario, built on the symbolic CTRV and
radar models, is ``kalman_course.chapters.lidar_radar.ctrv_lidar_radar``.

Rebuild the shipped files with ``python -m kalman_course.data.build``.
"""

from kalman_course.data.kitti import (EXCERPTS, SCHEMA_VERSION, FrameInfo, GnssData, ImuData,
                                      KittiExcerpt, LidarData, SlamData, TruthData, kitti_dir,
                                      load_excerpt_file, load_kitti, read_manifest, simulate_gnss,
                                      simulate_lidar_poses)
from kalman_course.data.observation_errors import (ErrorDraw, GaussMarkovErrors, MapMatchingFailures,
                                                   ObservationErrors, WhiteErrors)
from kalman_course.data.synthetic import (CVTarget, ImuScenario, RandomWalk1D, cv_target, imu_trajectory,
                                          random_walk_1d)

__all__ = [
    "EXCERPTS", "SCHEMA_VERSION", "FrameInfo", "GnssData", "ImuData", "KittiExcerpt", "LidarData",
    "SlamData", "TruthData", "kitti_dir", "load_excerpt_file", "load_kitti", "read_manifest",
    "simulate_gnss", "simulate_lidar_poses",
    "ErrorDraw", "GaussMarkovErrors", "MapMatchingFailures", "ObservationErrors", "WhiteErrors",
    "CVTarget", "ImuScenario", "RandomWalk1D", "cv_target", "imu_trajectory", "random_walk_1d",
]
