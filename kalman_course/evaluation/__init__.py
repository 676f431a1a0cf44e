"""Evaluation layer: how estimates are scored. Imports ``core`` only.

``metrics`` (RMSE, NEES, NIS, chi-square distribution and bounds), ``consistency``
(summaries and verdicts of NEES/NIS sequences, innovation gating), ``pose`` (position and
attitude errors of a pose trajectory: APE, RPE, pose NEES), ``attitude`` (an attitude
error split into heading and tilt), ``trajectory`` (point and pose alignment: SE(3), Sim(3), first pose, yaw only; ATE), ``drift`` (KITTI's
odometry drift metric over 100–800 m segments) and ``spread`` (median and range of a
result over seeds). The functions that take attitudes refuse a matrix that is not a
rotation (scaled, sheared, a reflection) with a ValueError naming the argument and index.
"""
