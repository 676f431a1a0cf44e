"""Core layer: what every other layer builds on. Imports numpy only.

``validation`` (the argument checks every public function uses), ``linalg`` (predicted
covariance, innovation covariance, gain, Joseph and short updates, symmetrisation: each
written once), ``numdiff`` (finite-difference Jacobians), ``angles`` (the one wrapping
convention), ``so3`` (rotations and quaternions), ``observations`` (the records of what a
sensor reported, as filters take them), ``gaussians`` (Gaussian algebra) and ``imu``
(strapdown mechanisation).
"""
