"""Evaluation layer: how estimates are scored. Imports ``core`` only.

``metrics`` (RMSE, NEES, NIS, chi-square distribution and bounds), ``consistency``
(summaries and verdicts of NEES/NIS sequences, innovation gating), ``pose`` (position and
attitude errors of a pose trajectory: APE, RPE, pose NEES), ``attitude`` (an attitude
error split into heading and tilt), ``trajectory`` (alignment, ATE), ``drift`` (KITTI's
odometry drift metric over 100–800 m segments) and ``spread`` (median and range of a
result over seeds).
"""
