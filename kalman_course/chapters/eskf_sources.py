"""What is real and what is simulated in an ESKF result on KITTI, said in one line.

Chapter 08's numbers mix real and simulated inputs. The IMU (OXTS RT3003, 100 Hz), the
ground truth and the ORB-SLAM2 / S-PTAM trajectories are real KITTI sequence-00 data. The
lidar map-matching poses are simulated (the truth plus seeded noise), and so is the noise
of the GNSS fixes (the recorded positions are the OXTS INS solution, as good as the truth).
When the simulated noise is white with exactly the standard deviations of the filter's R,
the filter is in the most favourable case it can meet; the labels here say so whenever it
holds. Tables and prints in the lecture and the benchmark report carry these labels.
"""

from __future__ import annotations

import numpy as np

__all__ = ["REAL_INPUTS", "lidar_source", "gnss_source", "sources_line"]

#: The real streams every chapter-08 result rests on.
REAL_INPUTS = "real: KITTI IMU (100 Hz) and ground truth"


def _matches(a: float, b: float) -> bool:
    return bool(np.isclose(a, b, rtol=1e-9, atol=0.0))


def lidar_source(lidar, config=None) -> str:
    """How the lidar poses were made, e.g. "lidar poses simulated: truth + white noise σ 0.2 m / 0.3°
    (seed 3002), exactly the filter's R".

    Parameters
    ----------
    lidar : LidarData
        Simulated poses (``sigma_position`` m, ``sigma_attitude_deg`` °, ``seed``; the
        ``error_model`` description when present, "white" otherwise).
    config : EskfConfig, optional
        The filter's settings; when given, the label says whether the simulated noise is
        white with exactly its R (``config.lidar_std``).

    Raises
    ------
    ValueError
        If ``lidar`` lacks the fields of simulated poses.
    """
    for attr in ("sigma_position", "sigma_attitude_deg", "seed"):
        if not hasattr(lidar, attr):
            raise ValueError(f"lidar must be simulated poses (LidarData) with sigma_position, "
                             f"sigma_attitude_deg and seed; missing {attr!r}")
    model = getattr(lidar, "error_model", "white")
    text = (f"lidar poses simulated: truth + {model} noise σ {lidar.sigma_position:g} m / "
            f"{lidar.sigma_attitude_deg:g}° (seed {lidar.seed})")
    if config is not None:
        std = config.lidar_std
        same = (model == "white" and _matches(std[0], lidar.sigma_position)
                and _matches(std[3], np.deg2rad(lidar.sigma_attitude_deg)))
        text += ", exactly the filter's R (the most favourable case)" if same else ", not the filter's R"
    return text


def gnss_source(gnss, config=None) -> str:
    """How the GNSS fixes were made, e.g. "GNSS fixes: recorded INS positions (real) + simulated
    white noise σ 1 m (seed 4002), exactly the filter's R".

    Parameters
    ----------
    gnss : GnssData
        ``sigma`` m and ``seed`` of the simulated noise.
    config : EskfConfig, optional
        When given, the label says whether σ equals ``config.gnss_std``.

    Raises
    ------
    ValueError
        If ``gnss`` lacks ``sigma`` or ``seed``.
    """
    for attr in ("sigma", "seed"):
        if not hasattr(gnss, attr):
            raise ValueError(f"gnss must be GnssData with sigma and seed; missing {attr!r}")
    text = f"GNSS fixes: recorded INS positions (real) + simulated white noise σ {gnss.sigma:g} m (seed {gnss.seed})"
    if config is not None:
        text += ", exactly the filter's R" if _matches(config.gnss_std, gnss.sigma) else ", not the filter's R"
    return text


def sources_line(lidar=None, gnss=None, config=None) -> str:
    """One line naming the real inputs and each simulated one given.

    Parameters
    ----------
    lidar : LidarData, optional
    gnss : GnssData, optional
    config : EskfConfig, optional
        Passed to :func:`lidar_source` / :func:`gnss_source`.

    Returns
    -------
    str
        ``"inputs: real: KITTI IMU (100 Hz) and ground truth; lidar poses simulated: ..."``.
    """
    parts = [REAL_INPUTS]
    if lidar is not None:
        parts.append(lidar_source(lidar, config))
    if gnss is not None:
        parts.append(gnss_source(gnss, config))
    return "inputs: " + "; ".join(parts)
