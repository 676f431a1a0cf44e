"""Bad input at every public boundary: a plain ValueError that names the argument.

Table-driven: each public function of core.gaussians, core.numdiff, filters.kf,
filters.bayes, evaluation.metrics and evaluation.trajectory is listed once with good
arguments and the kind of each argument; every argument is then replaced, one at a time,
by each bad value of its kind (wrong shape, transposed, NaN, inf, wrong type, empty,
non-symmetric, negative variance, indefinite, ...). Each call must raise exactly
``ValueError`` (not numpy's LinAlgError or AxisError, which subclass it) whose message
names the argument and none of numpy's internal phrases. Then the validators
themselves: the positive semi-definite rule and the fast paths.
"""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from kalman_course.core import gaussians, numdiff, validation
from kalman_course.core.validation import PSD_RTOL, as_covariance, as_matrix, as_vector
from kalman_course.evaluation import metrics, trajectory
from kalman_course.filters import bayes, kf

# Phrases of numpy's own exceptions, which say nothing about the caller's argument.
NUMPY_PHRASES = ("could not broadcast", "could not convert", "setting an array element",
                 "Singular matrix", "out of bounds", "inhomogeneous", "Matrix is not positive",
                 "not supported for the input types", "object of type")


# ---------------------------------------------------------------------------------------
# bad values by kind. Each entry: (label, value, dimension_error) — dimension_error marks
# a value whose only fault is its size, which a function may report against the argument
# that fixed that size instead (see `sized_by` in the specs).
# ---------------------------------------------------------------------------------------

def bad_vectors(n: int):
    good = np.arange(1.0, n + 1)
    with_nan, with_inf = good.copy(), good.copy()
    with_nan[-1], with_inf[0] = np.nan, -np.inf
    return [
        ("wrong length", np.zeros(n + 1), True),
        ("column (n, 1)", good[:, None], False),
        ("row (1, n)", good[None, :], False),
        ("NaN", with_nan, False),
        ("inf", with_inf, False),
        ("string", "abc", False),
        ("None", None, False),
        ("empty", np.zeros(0), True),
        ("complex", good + 1j, False),
        ("ragged", [[1.0], [1.0, 2.0]], False),
        ("list of strings", ["a"] * n, False),
        ("scalar", 1.0, False),
    ]


def bad_matrices(rows: int, cols: int):
    good = np.arange(1.0, rows * cols + 1).reshape(rows, cols)
    with_nan, with_inf = good.copy(), good.copy()
    with_nan[0, -1], with_inf[-1, 0] = np.nan, np.inf
    cases = [
        ("wrong rows", np.ones((rows + 1, cols)), True),
        ("wrong columns", np.ones((rows, cols + 1)), True),
        ("1-D", good.ravel(), False),
        ("3-D", good[None], False),
        ("NaN", with_nan, False),
        ("inf", with_inf, False),
        ("string", "abc", False),
        ("None", None, False),
        ("empty", np.zeros((0, cols)), True),
        ("complex", good + 1j, False),
        ("ragged", [[1.0] * cols, [1.0] * (cols + 1)], False),
    ]
    if rows != cols:
        cases.append(("transposed", good.T, True))
    return cases


def bad_covariances(n: int, rule: str):
    """``rule``: "psd" (may be singular) or "pd" (inverted, so must be positive definite)."""
    eye = np.eye(n)
    asym = eye.copy()
    asym[0, -1] = 0.5
    negative = eye.copy()
    negative[0, 0] = -1.0
    indefinite = 2.0 * np.ones((n, n)) - eye          # eigenvalues 2n - 1 and -1: symmetric, diag > 0
    with_nan, with_inf = eye.copy(), eye.copy()
    with_nan[0, 0], with_inf[-1, -1] = np.nan, np.inf
    cases = [
        ("negative variance", negative, False),
        ("wrong size", np.eye(n + 1), True),
        ("non-square", np.ones((n, n + 1)), False),
        ("1-D variances", np.ones(n), False),
        ("NaN", with_nan, False),
        ("inf", with_inf, False),
        ("string", "abc", False),
        ("None", None, False),
        ("empty", np.zeros((0, 0)), True),
        ("complex", eye + 1j, False),
    ]
    if n > 1:                                          # a 1x1 with a variance >= 0 is a covariance
        cases += [("non-symmetric", asym, False), ("indefinite", indefinite, False)]
    if rule == "pd":
        cases.append(("singular", np.ones((n, n)) if n > 1 else np.zeros((1, 1)), False))
    return cases


def bad_positive_scalars():
    return [("zero", 0.0, False), ("negative", -1.0, False), ("NaN", math.nan, False),
            ("inf", math.inf, False), ("string", "2", False), ("None", None, False),
            ("bool", True, False), ("list", [1.0, 2.0], False)]


def bad_flags():
    return [("int 1", 1, False), ("string", "yes", False), ("None", None, False)]


def bad_real_arrays():
    """For arrays in which NaN has a meaning (RMSE, chi-square arguments)."""
    return [("string", "abc", False), ("None", None, False), ("complex", [1 + 1j], False),
            ("ragged", [[1.0], [1.0, 2.0]], False), ("empty", [], False)]


def bad_ints(valid_range: tuple[int, int]):
    lo, hi = valid_range
    return [("float", lo + 0.5, False), ("string", str(lo), False), ("bool", True, False),
            ("None", None, False), ("below range", lo - 1, False), ("above range", hi + 1, False)]


KINDS = {
    "vector": bad_vectors, "matrix": bad_matrices, "psd": lambda n: bad_covariances(n, "psd"),
    "pd": lambda n: bad_covariances(n, "pd"), "scalar": bad_positive_scalars, "flag": bad_flags,
    "real": bad_real_arrays, "int": bad_ints,
}


# ---------------------------------------------------------------------------------------
# the public functions: good arguments, the kind of each, and which argument fixes a size
# ---------------------------------------------------------------------------------------

I2 = np.eye(2)
Z2 = np.zeros(2)
F2 = np.array([[1.0, 0.1], [0.0, 1.0]])
G12 = np.array([[1.0, 0.0]])
R1 = np.array([[0.5]])
ROUTE = np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 2.0, 0.0], [0.0, 1.0, 3.0]])
TRIANGLE = np.array([[0.5, 0.25, 0.25], [0.25, 0.5, 0.25], [0.25, 0.25, 0.5]])
M4 = np.array([[4.0, 1.0, 0.5, 0.0], [1.0, 3.0, 0.0, 0.5], [0.5, 0.0, 2.0, 0.3], [0.0, 0.5, 0.3, 1.0]])

HIST4 = kf.run_kf(Z2, I2, F2, 0.1 * I2, G12, R1, np.array([[0.1], [0.3], [0.2], [0.4]]))
ROT4 = np.stack([np.eye(3), np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.eye(3)])

# (function, good keyword arguments, {argument: (kind, kind parameters)}, sized_by)
# sized_by[arg] = the argument a size-only fault of ``arg`` may be reported against.
SPECS = [
    # core.gaussians
    (gaussians.gaussian_pdf, dict(x=Z2, mean=Z2, cov=I2),
     {"x": ("vector", (2,)), "mean": ("vector", (2,)), "cov": ("pd", (2,))}, {"mean": "cov"}),
    (gaussians.gaussian_logpdf, dict(x=Z2, mean=Z2, cov=I2),
     {"x": ("vector", (2,)), "mean": ("vector", (2,)), "cov": ("pd", (2,))}, {"mean": "cov"}),
    (gaussians.marginal, dict(mean=Z2, cov=I2, indices=[0]),
     {"mean": ("vector", (2,)), "cov": ("psd", (2,)), "indices": ("int", ((0, 1),))}, {"mean": "cov"}),
    (gaussians.conditional, dict(mu_x=Z2, mu_y=np.zeros(1), Sigma_xx=I2, Sigma_xy=np.zeros((2, 1)),
                                 Sigma_yy=R1, y=np.zeros(1)),
     {"mu_x": ("vector", (2,)), "mu_y": ("vector", (1,)), "Sigma_xx": ("psd", (2,)),
      "Sigma_xy": ("matrix", (2, 1)), "Sigma_yy": ("pd", (1,)), "y": ("vector", (1,))},
     {"mu_x": "Sigma_xx", "mu_y": "Sigma_xy", "Sigma_xy": "Sigma_xy"}),
    (gaussians.linear_map, dict(mu_x=Z2, Sigma_xx=I2, G=G12, R=R1),
     {"mu_x": ("vector", (2,)), "Sigma_xx": ("psd", (2,)), "G": ("matrix", (1, 2)), "R": ("psd", (1,))},
     {"mu_x": "Sigma_xx", "G": "R"}),
    (gaussians.joint_linear, dict(mu_x=Z2, Sigma_xx=I2, G=G12, R=R1),
     {"mu_x": ("vector", (2,)), "Sigma_xx": ("psd", (2,)), "G": ("matrix", (1, 2)), "R": ("psd", (1,))},
     {"mu_x": "Sigma_xx", "G": "R"}),
    (gaussians.product, dict(mu_a=Z2, Sigma_a=I2, mu_b=Z2, Sigma_b=2 * I2),
     {"mu_a": ("vector", (2,)), "Sigma_a": ("pd", (2,)), "mu_b": ("vector", (2,)),
      "Sigma_b": ("pd", (2,))}, {"mu_a": "Sigma_a"}),
    (gaussians.schur_complement, dict(M=M4, k=2),
     {"M": ("matrix", (4, 4)), "k": ("int", ((1, 3),))}, {"M": "k"}),
    (gaussians.block_inverse, dict(M=M4, k=2),
     {"M": ("matrix", (4, 4)), "k": ("int", ((1, 3),))}, {"M": "k"}),
    # core.numdiff
    (numdiff.numerical_jacobian, dict(f=np.sin, x=Z2, h=1e-6),
     {"x": ("vector", (2,)), "h": ("scalar", ())}, {"x": "x"}),
    # filters.kf
    (kf.kf_predict, dict(x_hat=Z2, P_hat=I2, F=F2, Q=0.1 * I2),
     {"x_hat": ("vector", (2,)), "P_hat": ("psd", (2,)), "F": ("matrix", (2, 2)), "Q": ("psd", (2,))},
     {"x_hat": "P_hat"}),
    (kf.innovation_covariance, dict(P_check=I2, G=G12, R=R1),
     {"P_check": ("psd", (2,)), "G": ("matrix", (1, 2)), "R": ("pd", (1,))}, {"P_check": "G", "G": "R"}),
    (kf.kf_gain, dict(P_check=I2, G=G12, S=np.array([[1.5]])),
     {"P_check": ("psd", (2,)), "G": ("matrix", (1, 2)), "S": ("pd", (1,))}, {"P_check": "G", "G": "S"}),
    (kf.kf_update, dict(x_check=Z2, P_check=I2, y=np.zeros(1), G=G12, R=R1),
     {"x_check": ("vector", (2,)), "P_check": ("psd", (2,)), "y": ("vector", (1,)),
      "G": ("matrix", (1, 2)), "R": ("pd", (1,)), "joseph": ("flag", ())},
     {"x_check": "P_check", "y": "G"}),
    (kf.run_kf, dict(x0=Z2, P0=I2, F=F2, Q=0.1 * I2, G=G12, R=R1, ys=np.zeros((3, 1))),
     {"x0": ("vector", (2,)), "P0": ("psd", (2,)), "F": ("matrix", (2, 2)), "Q": ("psd", (2,)),
      "G": ("matrix", (1, 2)), "R": ("pd", (1,)), "ys": ("matrix", (3, 1)), "joseph": ("flag", ())},
     {"x0": "P0", "G": "R", "ys": "ys"}),
    (kf.rts_smooth, dict(history=HIST4, F=F2, Q=0.1 * I2),
     {"F": ("matrix", (2, 2)), "Q": ("psd", (2,))}, {"F": "history"}),
    # filters.bayes
    (bayes.normalise, dict(belief=[0.2, 0.3]), {"belief": ("vector", (2,))}, {"belief": "belief"}),
    (bayes.histogram_update, dict(belief=[0.5, 0.5], likelihood=[0.2, 0.9]),
     {"belief": ("vector", (2,)), "likelihood": ("vector", (2,))}, {"belief": "likelihood"}),
    (bayes.histogram_predict, dict(belief=[0.5, 0.5], transition=[[0.9, 0.2], [0.1, 0.8]]),
     {"belief": ("vector", (2,)), "transition": ("matrix", (2, 2))}, {"belief": "transition"}),
    # evaluation.metrics
    (metrics.rmse, dict(estimate=np.ones((3, 2)), truth=np.zeros((3, 2))),
     {"estimate": ("real", ()), "truth": ("real", ())}, {}),
    (metrics.position_rmse, dict(estimate=np.ones((3, 2)), truth=np.zeros((3, 2))),
     {"estimate": ("real", ()), "truth": ("real", ())}, {}),
    (metrics.nees, dict(error=np.ones(2), P=I2),
     {"error": ("vector", (2,)), "P": ("pd", (2,))}, {"error": "P"}),
    (metrics.nis, dict(innovation=np.ones(2), S=I2),
     {"innovation": ("vector", (2,)), "S": ("pd", (2,))}, {"innovation": "S"}),
    (metrics.normalised_squared, dict(vec=np.ones(2), cov=I2, vec_name="vec", cov_name="cov"),
     {"vec": ("vector", (2,)), "cov": ("pd", (2,))}, {"vec": "cov"}),
    (metrics.chi2_cdf, dict(x=1.0, dof=2), {"x": ("real", ()), "dof": ("scalar", ())}, {}),
    (metrics.chi2_ppf, dict(p=0.5, dof=2), {"p": ("real", ()), "dof": ("scalar", ())}, {}),
    (metrics.chi2_bounds, dict(dof=2, n_runs=3, confidence=0.95),
     {"dof": ("scalar", ()), "confidence": ("scalar", ())}, {}),
    (metrics.share_inside, dict(values=[1.0, 2.0, 5.0], lo=0.5, hi=3.0),
     {"values": ("real", ())}, {}),
    # evaluation.trajectory
    (trajectory.umeyama, dict(src=ROUTE, dst=ROUTE + 1.0, with_scale=False),
     {"src": ("matrix", (4, 3)), "dst": ("matrix", (4, 3)), "with_scale": ("flag", ())},
     {"src": "dst"}),
    (trajectory.apply_alignment, dict(points=ROUTE, R=np.eye(3), t=np.zeros(3), s=1.0),
     {"points": ("matrix", (4, 3)), "R": ("matrix", (3, 3)), "t": ("vector", (3,)), "s": ("scalar", ())},
     {"points": "points"}),
    (trajectory.ate_rmse, dict(estimate=ROUTE, reference=ROUTE + 0.1, align="se3"),
     {"estimate": ("matrix", (4, 3)), "reference": ("matrix", (4, 3))}, {"estimate": "reference"}),
    (trajectory.align_poses, dict(position=ROUTE, rotation=ROT4, ref_position=ROUTE + 1.0, ref_rotation=ROT4,
                                  align="se3"),
     {"position": ("matrix", (4, 3)), "ref_position": ("matrix", (4, 3))}, {"position": "ref_position"}),
]

# A few bad values are fine for some arguments: a row count of N (any N >= 1 steps or
# points) is free, and a 1-point batch is a valid input of the batch functions.
ALLOWED = {
    ("run_kf", "ys", "wrong rows"), ("apply_alignment", "points", "wrong rows"),
    ("run_kf", "ys", "NaN"),           # a NaN row of a 1-component series is a missing measurement
    ("gaussian_pdf", "x", "row (1, n)"), ("gaussian_logpdf", "x", "row (1, n)"),
    ("nees", "error", "row (1, n)"), ("nis", "innovation", "row (1, n)"), ("normalised_squared", "vec", "row (1, n)"),
    # any length is right where the vector itself fixes the dimension
    ("numerical_jacobian", "x", "wrong length"), ("normalise", "belief", "wrong length"),
    # dof may be an array, broadcast against x or p
    ("chi2_cdf", "dof", "list"), ("chi2_ppf", "dof", "list"),
    # Q of the smoother is optional (given, it is checked against the record)
    ("rts_smooth", "Q", "None"),
}


def _cases():
    for fn, good, kinds, sized_by in SPECS:
        for arg, (kind, params) in kinds.items():
            for label, bad, size_only in KINDS[kind](*params):
                if (fn.__name__, arg, label) in ALLOWED:
                    continue
                expected = {arg, sized_by.get(arg, arg)} if size_only else {arg}
                yield pytest.param(fn, good, arg, bad, expected, id=f"{fn.__name__}-{arg}-{label}")


CASES = list(_cases())


def assert_names(exc: BaseException, names: set[str]) -> None:
    """The error is a plain ValueError, names one of ``names``, and is not numpy's own."""
    assert type(exc) is ValueError, f"{type(exc).__name__}: {exc}"
    message = str(exc)
    assert any(re.search(rf"(?<![\w.]){re.escape(name)}(?![\w])", message) for name in names), \
        f"message does not name {sorted(names)}: {message!r}"
    assert not any(phrase in message for phrase in NUMPY_PHRASES), message


def test_the_table_is_large_and_covers_every_public_function():
    covered = {fn for fn, *_ in SPECS} | {bayes.circular_motion_model}
    for module in (gaussians, kf, bayes, metrics, trajectory):
        for name in module.__all__:
            obj = getattr(module, name)
            if callable(obj) and not isinstance(obj, type):
                assert obj in covered, f"{module.__name__}.{name} has no bad-input cases"
    assert len(CASES) >= 350


def assert_refused(fn, kwargs: dict, names: set[str]) -> None:
    """``fn(**kwargs)`` raises a plain ValueError naming one of ``names`` (:func:`assert_names`)."""
    with np.errstate(all="raise"):               # no silent NaN from a warning either
        with pytest.raises(Exception) as info:
            fn(**kwargs)
    assert_names(info.value, names)


@pytest.mark.parametrize("fn, good, arg, bad, names", CASES)
def test_bad_argument_is_a_value_error_naming_it(fn, good, arg, bad, names):
    assert_refused(fn, dict(good, **{arg: bad}), names)


@pytest.mark.parametrize("fn, good", [(fn, good) for fn, good, *_ in SPECS],
                         ids=[fn.__name__ for fn, *_ in SPECS])
def test_the_good_arguments_are_good(fn, good):
    # the table's good arguments pass, so each failure above comes from the one bad value
    with np.errstate(all="raise"):
        fn(**good)


# ---------------------------------------------------------------------------------------
# cases the generic table cannot express
# ---------------------------------------------------------------------------------------

SPECIAL = [
    # a 1-D series for a one-component measurement: the hint says how to reshape it
    (lambda: kf.run_kf(Z2, I2, F2, 0.1 * I2, G12, R1, np.zeros(3)), {"ys"}),
    # a partly missing measurement row, and inf where NaN means "missing"
    (lambda: kf.run_kf(Z2, I2, F2, 0.1 * I2, I2, I2, [[0.0, 0.0], [np.nan, 1.0]]), {"ys"}),
    (lambda: kf.run_kf(Z2, I2, F2, 0.1 * I2, G12, R1, [[0.0], [np.inf]]), {"ys"}),
    (lambda: kf.run_kf(Z2, I2, F2, 0.1 * I2, G12, R1, np.zeros((3, 1)), vs=np.full((3, 2), np.nan)), {"vs"}),
    (lambda: kf.run_kf(Z2, I2, F2, 0.1 * I2, G12, R1, np.zeros((3, 1)), B=np.ones((2, 1))), {"Q"}),
    (lambda: kf.kf_predict(Z2, I2, F2, 0.1 * I2, v=[np.nan, 0.0]), {"v"}),
    (lambda: kf.kf_predict(Z2, I2, F2, [[1.0]], B=np.ones((2, 2))), {"Q"}),
    (lambda: kf.kf_predict(Z2, I2, F2, [[1.0]], B=np.ones((1, 2))), {"B"}),
    (lambda: kf.kf_update(Z2, I2, np.zeros(1), G12, [[1.0]], C=np.ones((2, 1))), {"C"}),
    # gaussians: blocks that do not form a joint covariance; a singular D block
    (lambda: gaussians.conditional(Z2, np.zeros(1), I2, np.array([[2.0], [0.0]]), R1, np.zeros(1)),
     {"Sigma_xx", "Sigma_xy", "Sigma_yy"}),
    (lambda: gaussians.schur_complement(np.ones((4, 4)), 2), {"M"}),
    (lambda: gaussians.block_inverse(np.eye(4) * [1.0, 0.0, 1.0, 1.0], 2), {"M"}),
    (lambda: gaussians.marginal(Z2, I2, [0, 0]), {"indices"}),
    (lambda: gaussians.marginal(Z2, I2, []), {"indices"}),
    (lambda: gaussians.marginal(Z2, I2, [[0], [0, 1]]), {"indices"}),
    (lambda: gaussians.gaussian_pdf(np.zeros((3, 2, 2)), Z2, I2), {"x"}),
    (lambda: gaussians.gaussian_pdf(np.zeros((3, 3)), Z2, I2), {"x"}),
    # numdiff: f's output
    (lambda: numdiff.numerical_jacobian(lambda z: np.outer(z, z), Z2), {"f"}),
    # bayes: probabilities
    (lambda: bayes.normalise([0.0, 0.0]), {"belief"}),
    (lambda: bayes.normalise([-0.1, 1.1]), {"belief"}),
    (lambda: bayes.histogram_update([0.6, 0.6], [1.0, 1.0]), {"belief"}),
    (lambda: bayes.histogram_update([1.0, 0.0], [0.0, 1.0]), {"likelihood"}),
    (lambda: bayes.histogram_predict([0.5, 0.5], [[0.9, 0.5], [0.5, 0.5]]), {"transition"}),
    (lambda: bayes.histogram_predict([0.5, 0.5], [[1.1, 0.0], [-0.1, 1.0]]), {"transition"}),
    (lambda: bayes.circular_motion_model(0, {0: 1.0}), {"n"}),
    (lambda: bayes.circular_motion_model(2.5, {0: 1.0}), {"n"}),
    (lambda: bayes.circular_motion_model(3, {}), {"step_probs"}),
    (lambda: bayes.circular_motion_model(3, [0.5, 0.5]), {"step_probs"}),
    (lambda: bayes.circular_motion_model(3, {0.5: 1.0}), {"step_probs"}),
    (lambda: bayes.circular_motion_model(3, {0: "half", 1: 0.5}), {"step_probs[0]"}),
    (lambda: bayes.circular_motion_model(3, {0: math.nan, 1: 0.5}), {"step_probs[0]"}),
    (lambda: bayes.circular_motion_model(3, {0: 0.5, 1: 0.6}), {"step_probs"}),
    # metrics: shapes, axes, batches, intervals
    (lambda: metrics.rmse(np.ones((3, 2)), np.ones((2, 3))), {"truth"}),
    (lambda: metrics.rmse(np.ones((3, 2)), np.ones(2)), {"truth"}),
    (lambda: metrics.rmse(np.ones((3, 2)), np.ones((3, 2)), axis=2), {"axis"}),
    (lambda: metrics.rmse(np.ones((3, 2)), np.ones((3, 2)), axis="rows"), {"axis"}),
    (lambda: metrics.nees(np.ones((3, 2)), np.ones((2, 2, 2))), {"P"}),
    (lambda: metrics.nees(np.ones((3, 2)), np.stack([I2, I2, [[1.0, 2.0], [2.0, 1.0]]])), {"P"}),
    (lambda: metrics.nees(np.ones((3, 2)), np.stack([I2, I2, [[1.0, 0.5], [0.0, 1.0]]])), {"P"}),
    (lambda: metrics.nees(np.ones((3, 2)), np.stack([I2, I2, np.full((2, 2), np.nan)])), {"P"}),
    (lambda: metrics.nees(np.array([[1.0, np.inf]]), I2), {"error"}),
    (lambda: metrics.nees(np.ones((2, 2, 2)), I2), {"error"}),
    (lambda: metrics.nis(np.ones((3, 2)), "S"), {"S"}),
    (lambda: metrics.chi2_cdf([1.0, 2.0, 3.0], [1, 2]), {"x", "dof"}),
    (lambda: metrics.chi2_ppf([0.1, 0.2, 0.3], [1, 2]), {"p", "dof"}),
    (lambda: metrics.chi2_ppf(1.5, 2), {"p"}),
    (lambda: metrics.chi2_ppf(-0.1, 2), {"p"}),
    (lambda: metrics.chi2_bounds(2, confidence=1.0), {"confidence"}),
    (lambda: metrics.chi2_bounds(2, n_runs=0), {"n_runs"}),
    (lambda: metrics.chi2_bounds(2, n_runs=2.5), {"n_runs"}),
    (lambda: metrics.share_inside([1.0], "low", 2.0), {"lo"}),
    (lambda: metrics.share_inside([1.0], 0.0, None), {"hi"}),
    (lambda: metrics.share_inside([1.0], math.nan, 2.0), {"lo"}),
    (lambda: metrics.share_inside([1.0], 3.0, 2.0), {"lo", "hi"}),
    (lambda: metrics.share_inside([np.nan], 0.0, 2.0), {"values"}),
    # trajectory: a rotation that is not one, too few points, all points equal
    (lambda: trajectory.apply_alignment(ROUTE, 2 * np.eye(3), np.zeros(3)), {"R"}),
    (lambda: trajectory.apply_alignment(ROUTE, np.diag([1.0, 1.0, -1.0]), np.zeros(3)), {"R"}),
    (lambda: trajectory.umeyama(ROUTE[:2], ROUTE[:2]), {"src"}),
    (lambda: trajectory.umeyama(np.ones((4, 3)), ROUTE), {"src"}),
    (lambda: trajectory.ate_rmse(ROUTE, ROUTE, align="affine"), {"align"}),
    # align_poses: rotations that are not, a stack of another length, an unknown alignment
    (lambda: trajectory.align_poses(ROUTE, -ROT4, ROUTE, ROT4), {"rotation[0]"}),
    (lambda: trajectory.align_poses(ROUTE, ROT4, ROUTE, 1.1 * ROT4), {"ref_rotation[0]"}),
    (lambda: trajectory.align_poses(ROUTE, ROT4[:3], ROUTE, ROT4), {"position"}),
    (lambda: trajectory.align_poses(ROUTE, ROT4, ROUTE, ROT4[:3]), {"ref_rotation"}),
    (lambda: trajectory.align_poses(ROUTE, ROT4, ROUTE, ROT4, align="se2"), {"align"}),
    (lambda: trajectory.align_poses(ROUTE, ROT4, ROUTE, ROT4, "yaw", vertical_axis=3), {"vertical_axis"}),
    # rts_smooth: a stack of F of another length than the record, a record that is not one
    (lambda: kf.rts_smooth(HIST4, np.stack([F2] * 4)), {"F", "history"}),
    (lambda: kf.rts_smooth(HIST4, np.ones((3, 3, 3))), {"F"}),
    (lambda: kf.rts_smooth(None, F2), {"history"}),
    (lambda: kf.rts_smooth(HIST4, F2, 0.1 * I2, B=np.ones((3, 2))), {"B"}),
]


@pytest.mark.parametrize("call, names", SPECIAL, ids=[f"special-{i}" for i in range(len(SPECIAL))])
def test_special_bad_input_is_a_value_error_naming_it(call, names):
    with np.errstate(all="raise"):
        with pytest.raises(Exception) as info:
            call()
    assert_names(info.value, names)


# ---------------------------------------------------------------------------------------
# the positive semi-definite rule (issue 11, item 7: kf_predict/run_kf accepted it)
# ---------------------------------------------------------------------------------------

SYMMETRIC_INDEFINITE = np.array([[1.0, 2.0], [2.0, 1.0]])          # eigenvalues 3 and -1


@pytest.mark.parametrize("call, name", [
    (lambda P: kf.kf_predict(Z2, P, F2, 0.1 * I2), "P_hat"),
    (lambda P: kf.run_kf(Z2, P, F2, 0.1 * I2, G12, R1, np.zeros((3, 1))), "P0"),
    (lambda P: kf.kf_update(Z2, P, np.zeros(1), G12, R1), "P_check"),
    (lambda P: kf.kf_gain(P, G12, [[1.0]]), "P_check"),
    (lambda P: kf.innovation_covariance(P, G12, R1), "P_check"),
    (lambda P: kf.kf_predict(Z2, I2, F2, P), "Q"),
    (lambda P: gaussians.linear_map(Z2, P, G12, R1), "Sigma_xx"),
])
def test_a_symmetric_indefinite_covariance_is_rejected(call, name):
    with pytest.raises(ValueError, match=rf"^{name} must be positive semi-definite.*smallest "
                                         rf"eigenvalue is -1\b"):
        call(SYMMETRIC_INDEFINITE)


def test_a_singular_covariance_is_accepted_where_nothing_is_inverted():
    # a state known exactly (zero variance) and a rank-deficient process noise
    P_known = np.diag([0.0, 1.0])
    T = 0.1
    gamma = np.array([[T**2 / 2], [T]])
    Q_rank_one = gamma @ gamma.T
    x_check, P_check = kf.kf_predict(Z2, P_known, F2, Q_rank_one)
    assert np.linalg.matrix_rank(Q_rank_one) == 1
    np.testing.assert_allclose(P_check, F2 @ P_known @ F2.T + Q_rank_one, rtol=1e-14, atol=1e-16)
    hist = kf.run_kf(Z2, P_known, F2, Q_rank_one, G12, R1, np.ones((4, 1)))
    assert np.all(np.isfinite(hist.P_hat))
    kf.kf_update(Z2, P_known, np.zeros(1), G12, R1)


def test_round_off_below_the_tolerance_passes_and_above_it_fails():
    # eigenvalues 1 and -eps: within PSD_RTOL of the largest passes, 10x beyond fails
    U = np.array([[np.cos(0.3), -np.sin(0.3)], [np.sin(0.3), np.cos(0.3)]])

    def with_eigenvalues(a, b):
        P = U @ np.diag([a, b]) @ U.T
        return 0.5 * (P + P.T)

    as_covariance(with_eigenvalues(1.0, -0.1 * PSD_RTOL), "P", psd=True)
    with pytest.raises(ValueError, match=r"^P must be positive semi-definite"):
        as_covariance(with_eigenvalues(1.0, -10 * PSD_RTOL), "P", psd=True)
    # the same matrices pass without psd: the option is what adds the rule
    as_covariance(with_eigenvalues(1.0, -10 * PSD_RTOL), "P")


def test_the_psd_rule_agrees_on_the_fast_and_the_slow_path():
    rng = np.random.default_rng(11)
    for _ in range(200):
        n = int(rng.integers(1, 6))
        A = rng.standard_normal((n, n))
        eigenvalues = rng.choice([-1.0, 0.0, 0.5, 2.0], size=n)
        P = A @ np.diag(eigenvalues) @ A.T
        P = 0.5 * (P + P.T)                          # exactly symmetric: eligible for the fast path
        if np.any(np.diag(P) < 0):
            continue
        outcomes = []
        for value in (P, P.tolist()):                # ndarray (fast path) and list (slow path)
            try:
                as_covariance(value, "P", psd=True)
                outcomes.append(True)
            except ValueError:
                outcomes.append(False)
        assert outcomes[0] == outcomes[1], (P, outcomes)
        smallest, largest = np.linalg.eigvalsh(P)[[0, -1]]
        assert outcomes[0] == (smallest >= -PSD_RTOL * max(largest, 0.0))


# ---------------------------------------------------------------------------------------
# the fast paths: what they let through and what they return
# ---------------------------------------------------------------------------------------

def test_fast_paths_return_the_callers_array_itself():
    v, M, P = np.arange(3.0), np.ones((2, 3)), np.eye(3)
    assert as_vector(v, "v") is v
    assert as_matrix(M, "M") is M
    assert as_covariance(P, "P", psd=True) is P
    assert as_covariance(P, "P", positive_definite=True) is P


def _read_only(a):
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def test_non_contiguous_and_read_only_arrays_are_fine():
    v = np.arange(1.0, 7.0)[::2]                               # a strided view
    assert not v.flags.c_contiguous and as_vector(v, "v", 3) is v
    P = np.kron(np.diag([1.0, 2.0, 3.0]), np.ones((2, 2)))[::2, ::2]
    assert not P.flags.c_contiguous and as_covariance(P, "P", 3, psd=True) is P
    Pf = np.asfortranarray(np.diag([1.0, 0.0, 2.0]))          # singular, Fortran order
    assert as_covariance(Pf, "P", psd=True) is Pf
    frozen = [_read_only(a) for a in (Z2, I2, F2, 0.1 * I2)]
    x_check, P_check = kf.kf_predict(*frozen)
    np.testing.assert_allclose(P_check, F2 @ F2.T + 0.1 * I2, rtol=1e-15)
    update = kf.kf_update(x_check, _read_only(P_check), _read_only([1.0]), _read_only(G12), _read_only(R1))
    assert np.all(np.isfinite(update.P_hat))


@pytest.mark.parametrize("bad_entry", [np.nan, np.inf, -np.inf])
@pytest.mark.parametrize("where", ["diagonal", "off-diagonal"])
def test_float64_covariance_with_nan_or_inf_never_slips_through(bad_entry, where):
    P = np.eye(3)
    if where == "diagonal":
        P[1, 1] = bad_entry
    else:
        P[0, 2] = P[2, 0] = bad_entry
    for options in ({}, {"psd": True}, {"positive_definite": True}):
        with pytest.raises(ValueError, match=r"^P must be finite"):
            as_covariance(P, "P", **options)


@pytest.mark.parametrize("bad_entry", [np.nan, np.inf])
def test_float64_vector_and_matrix_with_nan_or_inf_never_slip_through(bad_entry):
    v = np.zeros(4)
    v[2] = bad_entry
    with pytest.raises(ValueError, match=r"^v must be finite, got NaN or inf at index 2"):
        as_vector(v, "v")
    M = np.zeros((2, 3))
    M[1, 0] = bad_entry
    with pytest.raises(ValueError, match=r"^M must be finite, got NaN or inf at \[1, 0\]"):
        as_matrix(M, "M")


def test_subclasses_and_other_dtypes_take_the_full_path_and_pass():
    assert as_vector(np.arange(3, dtype=np.float32), "v").dtype == np.float64
    assert as_vector([1, 2, 3], "v").dtype == np.float64
    assert type(as_matrix(np.ma.masked_array([[1.0, 2.0]]), "M")) is np.ndarray
    P = as_covariance(np.eye(2, dtype=int), "P", psd=True)
    assert P.dtype == np.float64
    with pytest.raises(ValueError, match=r"^v must be a 1-D vector"):
        as_vector(np.ma.masked_array([[1.0, 2.0]]), "v")


def test_a_covariance_symmetric_only_to_round_off_is_accepted():
    A = np.random.default_rng(3).standard_normal((4, 4))
    P = A @ A.T + np.eye(4)
    P[0, 1] *= 1 + 1e-13                              # the fast path's exact test fails
    assert not np.array_equal(P, P.T)
    assert np.array_equal(as_covariance(P, "P", psd=True), P)


def test_missing_rows_option():
    ys = np.array([[1.0, 2.0], [np.nan, np.nan], [3.0, 4.0]])
    assert as_matrix(ys, "ys", ("N", 2), missing_rows=True) is ys
    with pytest.raises(ValueError, match=r"^ys must be finite"):
        as_matrix(ys, "ys", ("N", 2))
    with pytest.raises(ValueError, match=r"^ys must have shape \(N, 3\), got \(3, 2\)"):
        as_matrix(ys, "ys", ("N", 3), missing_rows=True)


def test_transposed_matrix_gets_a_hint():
    with pytest.raises(ValueError, match=r"^G must have shape \(1, 2\), got \(2, 1\) \(the transpose"):
        as_matrix(np.ones((2, 1)), "G", (1, 2))


def test_as_flag_and_as_real_array():
    assert validation.as_flag(np.bool_(True), "joseph") is True
    with pytest.raises(ValueError, match=r"^joseph must be True or False, got 1"):
        validation.as_flag(1, "joseph")
    assert validation.as_real_array([[1, np.nan]], "x").dtype == np.float64
    with pytest.raises(ValueError, match=r"^x must not be empty"):
        validation.as_real_array([], "x")


@pytest.mark.parametrize("value, kwargs, message", [
    (np.zeros((6, 1)), {}, r"^r must be a 1-D array of shape \(N,\), got shape \(6, 1\)$"),
    (np.zeros((4, 2)), {"tail": (3,)}, r"^r must have shape \(N, 3\), got shape \(4, 2\)$"),
    (np.zeros((4, 3)), {"tail": (3,), "n": 5, "count": "K"}, r"^r must have shape \(K=5, 3\)"),
    ("abc", {}, r"^r must be a 1-D array of shape \(N,\), got 'abc'$"),
    ([0.0, 1.0, np.inf], {"offset": 100}, r"^r\[102\] is inf$"),
    ([[0.0, 1.0], [np.nan, 2.0]], {"tail": (2,)}, r"^r\[1\] is NaN$"),
])
def test_as_rows_names_the_shape_or_the_first_bad_row(value, kwargs, message):
    from kalman_course.core.validation import as_rows

    with pytest.raises(ValueError, match=message):
        as_rows(value, "r", **kwargs)


def test_as_rows_returns_the_record_as_floats():
    from kalman_course.core.validation import as_rows

    out = as_rows([[1, 2, 3], [4, 5, 6]], "r", (3,), 2)
    assert out.dtype == np.float64 and out.shape == (2, 3)
