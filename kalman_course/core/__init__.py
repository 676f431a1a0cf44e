"""Core layer: what every other layer builds on. Imports numpy only.

``validation`` (the argument checks every public function uses), ``so3`` (rotations),
``linalg`` (gain, Joseph update, symmetrisation: each written once), ``angles``,
``gaussians`` (Gaussian algebra) and ``imu`` (strapdown mechanisation).
"""
