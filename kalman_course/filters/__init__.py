"""Filters layer: the estimators the course builds. Imports ``core`` and ``symbolic``.

``bayes`` (histogram filter), ``kf``, ``ekf`` (EKF and iterated EKF), ``eskf`` (with its
configuration in ``eskf_config``) and ``nominal_ekf``.
"""
