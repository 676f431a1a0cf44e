"""Evaluation layer: how estimates are scored. Imports ``core`` only.

``metrics`` (RMSE, NEES, NIS, chi-square distribution and bounds), ``consistency``
(summaries and verdicts of NEES/NIS sequences, innovation gating), ``pose`` (position and
attitude errors of a pose trajectory: APE, RPE, pose NEES) and ``trajectory`` (alignment,
ATE).
"""
