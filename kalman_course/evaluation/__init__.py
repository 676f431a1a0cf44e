"""Evaluation layer: how estimates are scored. Imports ``core`` only.

``metrics`` (RMSE, NEES, NIS, chi-square bounds) and ``trajectory`` (alignment, ATE).
"""
