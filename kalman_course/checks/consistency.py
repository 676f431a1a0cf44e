"""Checks for chapter 09: NEES, NIS, chi-square bounds, the innovation gate and a verdict.

Every case comes from the reference ESKF on the KITTI ``cruise`` excerpt: pose errors and
covariances of the shipped run, priors at held-out lidar poses, innovations of the run
with seeded map-matching failures, and NIS records of three noise settings.
"""

from __future__ import annotations

import functools
import math

import numpy as np

from kalman_course.chapters import consistency
from kalman_course.filters import eskf
from kalman_course.evaluation import metrics
from kalman_course.evaluation import consistency as consistency_stats
from kalman_course.evaluation.pose import POSE_INDEX, evaluate
from kalman_course.checks.harness import CheckFailed, call, check, expect_close
from kalman_course.data import load_kitti
from kalman_course.filters.eskf_config import load_config

#: The excerpt the checks run on, the outlier seed and the verdict cases (label, Q factor, R factor).
EXCERPT = "cruise"
OUTLIER_SEED = 0
VERDICT_SETTINGS = (("reference", 1.0, 1.0), ("R / 4", 1.0, 0.25), ("R x 4", 1.0, 4.0))


@functools.lru_cache(maxsize=None)
def nees_cases():
    """(error, P) pairs: 6-dof pose errors of the reference run and 3-dof position errors."""
    ex = load_kitti(EXCERPT)
    k0, s0 = ex.initial_state()
    res = eskf.run(ex.imu, s0, load_config("kitti_lidar"), ex.gravity, lidar=ex.lidar, start=k0)
    m = evaluate(res.t, res.position, res.rotation, ex.truth, res.P)
    e6 = np.concatenate([m["position_error"], m["attitude_error"]], axis=1)
    cases = []
    for k in np.linspace(5, len(res.t) - 1, 5).astype(int):
        P6 = res.P[k][np.ix_(POSE_INDEX, POSE_INDEX)]
        cases.append((e6[k], P6))
        cases.append((e6[k, :3], P6[:3, :3]))
    return tuple(cases)


@functools.lru_cache(maxsize=None)
def prior_cases():
    """(innovation, P_check (15, 15), G (6, 15), R (6, 6)) at held-out lidar poses.

    The filter uses every other pose; at the poses in between, its row is a prior (no
    update there), so the pose residual against the held-out pose is a true innovation.
    """
    ex = load_kitti(EXCERPT)
    k0, s0 = ex.initial_state()
    cfg = load_config("kitti_lidar")
    lid = ex.lidar
    used = lid.select(slice(None, None, 2))
    held = np.arange(1, len(lid.t), 2)
    res = eskf.run(ex.imu, s0, cfg, ex.gravity, lidar=used, start=k0, output_times=lid.t[held])
    R = np.diag(cfg.lidar_std ** 2)
    cases = []
    for j in held[np.linspace(3, len(held) - 2, 6).astype(int)]:
        r = int(np.searchsorted(res.t, lid.t[j] - 1e-9))
        y = eskf.pose_residual(res.position[r], res.rotation[r], lid.position[j], lid.rotation[j])
        cases.append((y, res.P[r], np.array(eskf.POSE_G), R))
    return tuple(cases)


@functools.lru_cache(maxsize=None)
def gate_cases():
    """(innovation, S, accepted by the reference) for the outlier run and borderline cases."""
    ex = load_kitti(EXCERPT)
    bad, _ = consistency.inject_outliers(ex.lidar, OUTLIER_SEED)
    run = consistency.run_gated(ex, bad)
    cases = [(run.innovation[i], run.S[i]) for i in range(len(run.t))]
    # borderline: rescale some innovations to NIS just inside / outside the 99 % gate, 6 and 3 dof
    for i, factor in zip(range(10, 60, 10), (0.97, 1.03, 0.9, 1.1, 0.99)):
        for dims in (slice(0, 6), slice(0, 3)):
            y, S = run.innovation[i][dims], run.S[i][dims, dims]
            target = factor * consistency_stats.gate_threshold(len(y), 0.99)
            cases.append((y * math.sqrt(target / metrics.nis(y, S)), S))
    return tuple(cases)


@functools.lru_cache(maxsize=None)
def verdict_cases():
    """(label, NIS record (N,)) of the reference ESKF on the excerpt for each verdict setting."""
    ex = load_kitti(EXCERPT)
    k0, s0 = ex.initial_state()
    out = []
    for label, qf, rf in VERDICT_SETTINGS:
        res = eskf.run(ex.imu, s0, consistency.scaled_config("kitti_lidar", qf, rf), ex.gravity,
                       lidar=ex.lidar, start=k0)
        out.append((label, metrics.nis(np.array(res.innovation), np.array(res.S))))
    return tuple(out)


def _scalar(value, what: str) -> float:
    arr = np.asarray(value, dtype=float) if not isinstance(value, (str, bytes)) else None
    if arr is None or arr.size != 1:
        shape = "a string" if arr is None else f"shape {arr.shape}"
        raise CheckFailed(f"{what} should be one number, got {shape}. Hint: eᵀ P⁻¹ e is a scalar; "
                          "did you return P⁻¹ e (a vector) or forget a product?")
    return float(arr.reshape(()))


@check
def check_consistency_nees(nees):
    """The learner's ``nees(error, P)`` on KITTI pose and position errors."""
    for e, P in nees_cases():
        n = len(e)
        value = _scalar(call(nees, e, P), f"nees for a {n}-dof error")
        ref = float(e @ np.linalg.solve(P, e))
        expect_close(value, ref, f"NEES of a {n}-dof KITTI error", rtol=1e-6, mistakes=[
            (float(e @ P @ e), "that is eᵀ P e: the NEES weights the error by the INVERSE covariance, eᵀ P⁻¹ e"),
            (float(e @ e), "the error must be weighted by P⁻¹: eᵀ P⁻¹ e, not eᵀ e"),
            (ref / n, "do not divide by the dimension: the NEES is χ²(n) with mean n"),
            (math.sqrt(ref), "that is the Mahalanobis distance; the NEES is its square"),
        ], hint="ε = eᵀ P⁻¹ e (np.linalg.solve(P, e) avoids forming the inverse)")


@check
def check_consistency_nis(nis):
    """The learner's ``nis(innovation, P_check, G, R)`` at held-out KITTI lidar poses."""
    for y, P, G, R in prior_cases():
        value = _scalar(call(nis, y, P, G, R), "nis")
        S = G @ P @ G.T + R
        ref = float(metrics.nis(y, S))
        GPG = G @ P @ G.T
        expect_close(value, ref, "NIS of a KITTI lidar innovation", rtol=1e-6, mistakes=[
            (float(y @ np.linalg.solve(GPG, y)), "S = G P̌ Gᵀ + R: the innovation also carries the "
                                                 "observation noise R, which is missing"),
            (float(y @ np.linalg.solve(R, y)), "S = G P̌ Gᵀ + R: the prior's uncertainty G P̌ Gᵀ is missing"),
            (float(y @ S @ y), "weight by S⁻¹, not S: νᵀ S⁻¹ ν"),
            (ref / len(y), "do not divide by the dimension: the NIS is χ²(m) with mean m"),
        ], hint="ν̃ = νᵀ S⁻¹ ν with S = G P̌ Gᵀ + R")


@check
def check_chi2_interval(chi2_interval):
    """The learner's ``chi2_interval(dof, n_runs, confidence)`` for KITTI-sized records."""
    n_updates = len(load_kitti(EXCERPT).lidar.t) - 1          # one NIS per lidar pose after the first
    for dof, n_runs, confidence in ((6, 1, 0.95), (6, n_updates, 0.95), (15, 20, 0.95), (3, 50, 0.99),
                                    (6, 20, 0.99)):
        result = call(chi2_interval, dof, n_runs, confidence)
        if not isinstance(result, tuple) or len(result) != 2:
            raise CheckFailed("chi2_interval must return a tuple (lo, hi)")
        lo, hi = metrics.chi2_bounds(dof, n_runs, confidence)
        a, c = (1 - confidence) / 2, (1 + confidence) / 2
        ppf = metrics.chi2_ppf
        what = f"(lo, hi) for dof={dof}, n_runs={n_runs}, confidence={confidence}"
        expect_close(np.array(result, dtype=float), [lo, hi], what, rtol=1e-6, mistakes=[
            ([0.0, ppf(confidence, dof * n_runs) / n_runs],
             "that is a one-sided interval [0, q_c]; a two-sided interval leaves (1 − c)/2 "
             "in each tail: lo at (1 − c)/2, hi at (1 + c)/2"),
            ([ppf(1 - confidence, dof * n_runs) / n_runs, ppf(confidence, dof * n_runs) / n_runs],
             "the tails are (1 − c)/2 each, not 1 − c: lo at (1 − c)/2, hi at (1 + c)/2"),
            ([ppf(a, dof), ppf(c, dof)], "n_runs is ignored: the SUM of n_runs values is "
                                         "χ²(dof · n_runs); divide its quantiles by n_runs for the mean"),
            ([ppf(a, dof * n_runs), ppf(c, dof * n_runs)],
             "these are bounds for the sum of the n_runs values; divide by n_runs for the mean"),
            ([ppf(a, n_runs) / n_runs, ppf(c, n_runs) / n_runs],
             "degrees of freedom: the sum has dof · n_runs of them, not n_runs"),
        ], hint="lo, hi = F⁻¹((1 ∓ c)/2; dof · n_runs) / n_runs")


@check
def check_innovation_gate(gate):
    """The learner's ``gate(innovation, S, confidence)`` on the KITTI outlier run."""
    cases = gate_cases()
    values = np.array([metrics.nis(y, S) for y, S in cases])
    dims = np.array([len(y) for y, _ in cases])
    answers = []
    for y, S in cases:
        answer = call(gate, y, S, 0.99)
        if not isinstance(answer, (bool, np.bool_)):
            raise CheckFailed(f"gate must return True or False, got {type(answer).__name__}")
        answers.append(bool(answer))
    answers = np.array(answers)
    threshold = np.array([metrics.chi2_ppf(0.99, m) for m in dims])
    wrong = np.nonzero(answers != (values <= threshold))[0]
    if wrong.size == 0:
        return
    i = wrong[0]
    hint = (f"an innovation of {dims[i]} components with NIS {values[i]:.2f} (99 % gate "
            f"{threshold[i]:.2f}) was {'accepted' if answers[i] else 'rejected'}; {wrong.size} of "
            f"{len(cases)} decisions are wrong. ")
    known = (
        (values <= metrics.chi2_ppf(0.99, 1),
         "The threshold is the χ² quantile for ONE degree of freedom; use the innovation's dimension."),
        (values >= threshold, "The comparison is reversed: accept when the NIS is at most the threshold."),
        (values <= np.array([metrics.chi2_ppf(0.01, m) for m in dims]),
         "That threshold is the 1 % quantile; the gate uses the `confidence` quantile (99 %)."),
        (values <= 0.99, "Compare the NIS with the χ² quantile F⁻¹(confidence; m), not with the confidence."),
    )
    for decisions, why in known:
        if np.array_equal(decisions, answers):
            hint += why
            break
    else:
        hint += "Accept when νᵀ S⁻¹ ν ≤ F⁻¹(confidence; m), m = len(innovation)."
    raise CheckFailed("wrong gate decisions. Hint: " + hint)


@check
def check_consistency_verdict(verdict):
    """The learner's ``verdict(nis_values, dof, confidence)`` on NIS records of three KITTI runs."""
    for label, values in verdict_cases():
        answer = call(verdict, values, 6, 0.95)
        ref = consistency_stats.verdict(values, 6, 0.95)
        if answer != ref:
            lo, hi = metrics.chi2_bounds(6, len(values), 0.95)
            raise CheckFailed(
                f"for the KITTI run with {label} the mean NIS is {np.mean(values):.3f} and its 95 % "
                f"interval [{lo:.3f}, {hi:.3f}]: expected {ref!r}, got {answer!r}. Hint: a mean above "
                "the interval means the errors are larger than S says, so the filter is "
                "OVERconfident (S too small); below it, underconfident")
