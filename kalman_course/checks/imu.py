"""Checks for chapter 07: the three midpoint steps of IMU mechanisation, a whole run, and the
optional challenge's levelling (the attitude a resting accelerometer gives).

The attitude step is written twice: for C = R_bn = R_nbᵀ (``attitude_step_bn``, which the
lecture does not write out: the learner derives it), and for R_nb (``attitude_step``, which the
exercise builds from the first and the loop uses). ``attitude_step_bn`` is graded on the same
cases as the R_nb step, handed Rᵀ, its result transposed back: its mistakes (the lecture's step
applied to C, the rotation on the right side with the wrong sign, or the wrong side with the
right sign) are R_nb mistakes seen through the transpose, with hints of their own.

Each step is compared on several cases with the closed form of the midpoint rule: synthetic
motion (a constant rate, a resting IMU, constant acceleration), synthetic cases whose rates,
readings, biases and attitudes all differ (so that a dropped bias, a start-point rate, a
transposed or left-multiplied rotation or a T² change the value), rates from exactly zero
down to 1e-12 rad/s, and KITTI samples with made-up biases. The whole run is compared with
:func:`kalman_course.core.imu.dead_reckon` on synthetic motion (constant dt, whose truth the
midpoint rule reproduces exactly) and on a KITTI slice (irregular dt, not at the start of
the data); a run whose rows never leave the initial state is named as the loop's placeholder.
Levelling is judged by what defines it, R f/|f| = up (any heading), on tilts from 0 to 150° and exactly 180°,
a reading longer than g and KITTI means.

When a result is wrong, the check looks for the plausible mistake that reproduces the
learner's value on *every* case (a wrong formula is consistent; a coincidence on one case is
not; :func:`harness.known_mistake`) and names it; otherwise it reports the first case that
differs, with what the step computes. Hints come in tiers (:mod:`hints`): the concept, the
mistake and the lecture section first, the formula on request. A result in single precision
is named as such before any value is compared (the tolerances are below float32's rounding).

After the attitude step's cases pass, a sweep of the singular regimes runs (48 calls):
angles |ω̄ T| from 1e-13 to 3 rad, two per decade where a small-angle switch lives (1e-11 …
1e-2), about an axis and its opposite, with steps of 1e-4, 0.01 and 0.5 s (rates from 2e-13
to 20 rad/s), rotation vectors within 1e-9 and 1e-3 rad of π on both sides, and large turns
from an attitude just short of a half turn. It names a cut-off or series that errs beyond the
tolerance (a step returned unchanged below 1e-9 rad errs by 1e-9, ten tolerances).

Under a graded run's seed (:mod:`kalman_course.checks.cases`) every case is drawn anew from
its family: other KITTI samples (real readings, true attitudes) with other made-up biases;
the synthetic cases' attitudes, rates, readings, biases and time steps; the written-out
cases' values (a constant rate and its step, the bias that cancels the rate, a zero rate at
an attitude within 10⁻³ … 10⁻⁸ rad of a half turn, random directions of the tiny rates at
about 1e-12, 1e-6 and 1e-3 rad/s, the resting IMU's velocity, heading and step, the constant
acceleration); the attitude sweep's axes, start attitude and angles (each within its
half-decade); the whole run's simulated trajectory (another seed, 3–5 s, clean readings) and
its KITTI slice (another start and 300–500 samples of the real ``turns`` readings, redrawn
until every listed loop mistake changes the run and no two of them agree); and the
levelling's tilts (10–30°, 55–85°, 0.5 … 10⁻³ rad short of upside down, 5e-7 … 1e-5 rad),
headings, |f|/g (below and above 1, and a level reading) and the two KITTI windows it
averages (real ``cruise`` readings).
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course.core import so3
from kalman_course.core.angles import wrap_angle
from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.checks import hints
from kalman_course.checks.harness import (CheckFailed, as_array, call, check, expect_shape, known_mistake,
                                          referenced_names)
from kalman_course.data import imu_trajectory, load_kitti
from kalman_course.core.imu import NavState, dead_reckon

#: The KITTI slice the whole-run check integrates: excerpt, first sample, number of samples.
RUN_SLICE = ("turns", 1000, 500)

#: Gravity of the synthetic cases (navigation frame z up, as KITTI), m/s².
GRAVITY = np.array([0.0, 0.0, -9.8092])

# Tolerances, absolute on entries (all of order 1 for rotations, 10 for velocities and
# 100 for positions), with the reason for each:
#: R_next: Rodrigues, a unit quaternion, scipy's expm or Rotation all agree with so3.Exp to
#: ~1e-15; the smallest mistake kept apart is a first-order I + [φ]× re-orthonormalised,
#: which errs by θ³/3 ≈ 3e-6 on the "tumbling" case (θ = 0.023 rad); every other listed
#: mistake changes R_next by ≥ 3e-3 on some case.
ATTITUDE_ATOL = 1e-10
#: v_next: any order of the sums and products rounds to ~1e-14 m/s; every listed mistake
#: changes v_next by ≥ 2e-3 m/s on some case.
VELOCITY_ATOL = 1e-10
#: p_next: round-off ~1e-13 m on KITTI's ~100 m coordinates; every listed mistake changes
#: p_next by ≥ 0.2 m on some case.
POSITION_ATOL = 1e-9


def reference_attitude_step(R, w0, w1, b_w, dt):
    """R Exp((½(ω₀ + ω₁) − b_ω) T)."""
    return R @ so3.exp((0.5 * (w0 + w1) - b_w) * dt)


def reference_velocity_step(v, R0, R1, f0, f1, b_a, g, dt):
    """v + ½(R₀(f₀ − b_a) + R₁(f₁ − b_a)) T + g T."""
    return v + 0.5 * (R0 @ (f0 - b_a) + R1 @ (f1 - b_a)) * dt + g * dt


def reference_position_step(p, v0, v1, dt):
    """p + ½(v₀ + v₁) T."""
    return p + 0.5 * (v0 + v1) * dt


# ----------------------------------------------------------------------------------------
# Cases (built once: the checks' own run time stays that of the learner's calls)
# ----------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _kitti_cases(count: int = 6, seed: int = 0):
    """Consecutive KITTI IMU sample pairs with the true attitude there and made-up biases."""
    ex = load_kitti("turns")
    rng = inputs.rng("imu.kitti", seed)  # under a run seed: other samples and other biases
    cases = []
    for k in rng.choice(np.arange(10, len(ex.imu) - 10), size=count, replace=False):
        nav = ex.truth.state_at(float(np.clip(ex.imu.t[k], ex.truth.t[0], ex.truth.t[-1])))
        cases.append(dict(name=f"KITTI sample {k}", R=nav.rotation, v=nav.velocity, p=nav.position,
                          f0=ex.imu.specific_force[k].copy(), f1=ex.imu.specific_force[k + 1].copy(),
                          w0=ex.imu.angular_rate[k].copy(), w1=ex.imu.angular_rate[k + 1].copy(),
                          b_a=rng.normal(size=3) * 0.05, b_w=rng.normal(size=3) * 0.01,
                          dt=float(ex.imu.t[k + 1] - ex.imu.t[k]), g=ex.gravity.copy()))
    return tuple(cases)


def _synthetic_case(name, seed, rate, spread, bias, dt):
    """A case with a random attitude, two different rates and readings, and biases (drawn
    anew under a run seed, the step too: within a factor 2 of ``dt``)."""
    rng = inputs.rng("imu.synthetic", seed)
    w0 = rate * rng.normal(size=3)
    case = dict(name=name, R=so3.exp(rng.normal(size=3)), v=rng.normal(size=3) * 5.0,
                p=rng.normal(size=3) * 50.0, w0=w0, w1=w0 + spread * rng.normal(size=3),
                b_w=bias * rng.normal(size=3), f0=rng.normal(size=3) * 3.0 - GRAVITY,
                f1=rng.normal(size=3) * 3.0 - GRAVITY, b_a=rng.normal(size=3) * 0.3,
                dt=dt, g=GRAVITY.copy())
    if inputs.drawing():  # drawn after the rest, so that the fixed stream stays as it was
        case["dt"] = float(inputs.log_uniform(rng, 0.5 * dt, 2.0 * dt))
    return case


def _random_axis(rng):
    """A unit vector of uniformly drawn direction."""
    u = rng.normal(size=3)
    return u / np.linalg.norm(u)


def _fixed_attitude_literals():
    """The written-out attitude cases of the self-check: (name, R, w0, w1, b_w, dt)."""
    R0 = so3.exp(np.array([0.2, -0.4, 1.0]))
    w = np.array([0.3, -0.1, 0.7])
    still = np.array([0.01, -0.02, 0.005])
    return [
        ("constant rate", R0, w, w, np.zeros(3), 0.5),
        ("bias-cancelled rate (ω̄ = 0)", R0, still, still, still, 0.01),
        ("zero rate", so3.exp(np.array([-1.0, 0.3, 2.5])), np.zeros(3), np.zeros(3), np.zeros(3), 0.01),
        ("rate 1e-12 rad/s", R0, 1e-12 * np.array([1.0, -2.0, 0.5]), 1e-12 * np.array([0.5, 1.0, -1.5]),
         np.zeros(3), 0.01),
        ("rate 1e-6 rad/s", R0, 1e-6 * np.array([-1.0, 2.0, 0.5]), 1e-6 * np.array([1.0, 1.0, 1.5]),
         1e-7 * np.array([1.0, 0.0, -1.0]), 0.01),
        ("rate 1e-3 rad/s", R0, 1e-3 * np.array([0.7, -0.2, 0.4]), 1e-3 * np.array([0.9, 0.2, -0.4]),
         1e-4 * np.array([1.0, 2.0, 3.0]), 0.1),
    ]


def _drawn_attitude_literals(rng):
    """The same family under a run seed: a random attitude, random directions and sizes."""
    R0 = so3.exp(rng.uniform(0.3, 3.0) * _random_axis(rng))
    # an attitude just short of a half turn, where a hand-made Log/Exp pair is least exact
    R_pi = so3.exp((np.pi - inputs.log_uniform(rng, 1e-8, 1e-3)) * _random_axis(rng))
    w = rng.uniform(0.3, 1.2) * _random_axis(rng)
    still = rng.uniform(0.005, 0.03) * _random_axis(rng)
    raw = [("constant rate", R0, w, w, np.zeros(3), float(rng.uniform(0.2, 0.8))),
           ("bias-cancelled rate (ω̄ = 0)", R0, still, still, still, float(inputs.log_uniform(rng, 0.005, 0.02))),
           ("zero rate", R_pi, np.zeros(3), np.zeros(3), np.zeros(3), float(inputs.log_uniform(rng, 0.005, 0.02)))]
    for size, bias in ((1e-12, 0.0), (1e-6, 1e-7), (1e-3, 1e-4)):
        scale = inputs.log_uniform(rng, 0.5 * size, 2.0 * size)   # stays within a factor 2 of the label
        raw.append((f"rate {size:.0e} rad/s".replace("e-0", "e-"), R0, scale * rng.normal(size=3),
                    scale * rng.normal(size=3), bias * rng.normal(size=3),
                    float(inputs.log_uniform(rng, 0.005, 0.1))))
    return raw


@functools.lru_cache(maxsize=None)
def _attitude_cases():
    """(name, R, w0, w1, b_w, dt, R_next) for the attitude step."""
    # a constant rate ω about a fixed axis for T seconds is exactly Exp(ω T); the bias that
    # cancels the rate exactly gives ω̄ = 0, where Rodrigues' formula divides 0 by 0; tiny
    # rates, where a series or a small-angle switch must still be exact
    constant, cancelled, zero, *tiny = inputs.fixed_or_drawn(_fixed_attitude_literals(),
                                                             _drawn_attitude_literals, "imu.attitude")
    raw = [
        constant,
        # every term differs: a start-point rate, a dropped bias or a wrong order all show
        _pick(_synthetic_case("tumbling", 71, 0.8, 0.5, 0.1, 0.05), "R", "w0", "w1", "b_w", "dt"),
        _pick(_synthetic_case("slow turn", 72, 0.2, 0.05, 0.02, 0.02), "R", "w0", "w1", "b_w", "dt"),
        cancelled, zero, *tiny,
    ] + [_pick(c, "R", "w0", "w1", "b_w", "dt") for c in _kitti_cases()]
    return tuple(dict(name=n, R=R, w0=w0, w1=w1, b_w=b, dt=dt, ref=reference_attitude_step(R, w0, w1, b, dt))
                 for n, R, w0, w1, b, dt in raw)


def _drawn_rest(rest, rng):
    """A level IMU at rest under a run seed: another horizontal velocity, heading and step
    (a heading turns about up, so the resting reading −g stays that of a level IMU)."""
    v = np.r_[rng.normal(size=2) * 3.0, 0.0]
    return dict(rest, v=v, R=so3.exp(rng.uniform(-np.pi, np.pi) * np.array([0.0, 0.0, 1.0])),
                dt=float(inputs.log_uniform(rng, 0.02, 0.3)))


@functools.lru_cache(maxsize=None)
def _velocity_cases():
    """Cases for the velocity step, each with R1 = the reference attitude step and ``ref``."""
    rest = dict(name="level IMU at rest", v=np.array([1.0, 2.0, 0.0]), R=np.eye(3), w0=np.zeros(3),
                w1=np.zeros(3), b_w=np.zeros(3), f0=-GRAVITY, f1=-GRAVITY, b_a=np.zeros(3), dt=0.1,
                g=GRAVITY.copy())
    rest = inputs.fixed_or_drawn(rest, lambda rng: _drawn_rest(rest, rng), "imu.velocity.rest")
    raw = [rest, _synthetic_case("tumbling", 81, 0.8, 0.5, 0.1, 0.05),
           _synthetic_case("braking on a slope", 82, 0.3, 0.2, 0.05, 0.02)] + list(_kitti_cases())
    # standard gravity in one case, so that a hard-coded g differs from the one handed in
    raw[2] = dict(raw[2], g=np.array([0.0, 0.0, -9.80665]))
    cases = []
    for c in raw:
        R1 = reference_attitude_step(c["R"], c["w0"], c["w1"], c["b_w"], c["dt"])
        args = (c["v"], c["R"], R1, c["f0"], c["f1"], c["b_a"], c["g"], c["dt"])
        cases.append(dict(name=c["name"], args=args, ref=reference_velocity_step(*args)))
    return tuple(cases)


@functools.lru_cache(maxsize=None)
def _position_cases():
    """Cases for the position step: constant acceleration, random velocities, KITTI."""
    p, v0, a, T, steps, dv = inputs.fixed_or_drawn(
        (np.array([1.0, -2.0, 0.5]), np.array([3.0, 1.0, 0.0]), np.array([0.5, -1.0, 0.2]), 0.2,
         (0.05, 0.013), np.array([0.01, -0.02, 0.003])), _drawn_position_literals, "imu.position.literals")
    raw = [("constant acceleration", p, v0, v0 + a * T, T)]
    rng = inputs.rng("imu.position", 90)
    for k, T in enumerate(steps):
        raw.append((f"random velocities {k}", rng.normal(size=3) * 30.0, rng.normal(size=3) * 8.0,
                    rng.normal(size=3) * 8.0, T))
    for c in _kitti_cases():
        raw.append((c["name"], c["p"], c["v"], c["v"] + dv, c["dt"]))
    return tuple(dict(name=n, args=(p, v0, v1, T), ref=reference_position_step(p, v0, v1, T))
                 for n, p, v0, v1, T in raw)


def _drawn_position_literals(rng):
    """(p, v0, a, T, the random cases' steps, the KITTI cases' velocity change) under a run seed."""
    return (rng.normal(size=3) * 5.0, rng.normal(size=3) * 5.0, rng.normal(size=3),
            float(inputs.log_uniform(rng, 0.05, 0.5)), tuple(inputs.log_uniform(rng, 0.005, 0.1, 2)),
            rng.normal(size=3) * 0.02)


def _pick(case, *keys):
    return (case["name"],) + tuple(case[k] for k in keys)


# ----------------------------------------------------------------------------------------
# Grading: compare on every case, then name the mistake that explains every case
# ----------------------------------------------------------------------------------------

def _same(value, ref, atol):
    return value.shape == np.shape(ref) and bool(np.allclose(value, ref, rtol=0.0, atol=atol))


def _grade(values, cases, what, atol, mistakes, hint, patterns=()):
    """Fail unless every value matches its case's ``ref``; name the mistake if one fits all.

    Parameters
    ----------
    values : list of numpy.ndarray
        The learner's results, one per case (already of the right shape and finite).
    cases : sequence of dict
        Each with ``name`` and ``ref``.
    what : str
        The quantity, for the message.
    atol : float
        Absolute tolerance on every entry.
    mistakes : sequence of (callable, str)
        ``(case -> wrong value, hint)``; computed only when a value is wrong.
    hint : str
        What the step computes, given when no listed mistake explains the values (its
        formula marked with :func:`hints.formula`).
    patterns : sequence of (callable, str)
        ``(predicate(value, case) -> bool, hint)`` for a mistake that no single wrong value
        describes (an approximation): it is named if the predicate holds on every case.
    """
    failing = [k for k, (v, c) in enumerate(zip(values, cases)) if not _same(v, c["ref"], atol)]
    if not failing:
        return
    def close(value, wrong, _):
        return wrong is not None and _same(value, np.asarray(wrong, dtype=float), atol)

    why = known_mistake(values, cases, mistakes, close=close)
    # a pattern is "evaluated" on a case into the test of the learner's value there
    why = why or known_mistake(values, cases, patterns, evaluate=lambda pattern, c: lambda value: pattern(value, c),
                               close=_holds)
    if why:
        raise CheckFailed(f"{what} is wrong. Hint: {why}")
    k = failing[0]
    err = np.max(np.abs(values[k] - cases[k]["ref"]))
    raise CheckFailed(f"{what} differs from the reference on the case '{cases[k]['name']}' "
                      f"(max abs error {err:.3g}). Hint: {hint}")


def _holds(value, test, _=None) -> bool:
    """Whether ``test(value)`` is true (False when it could not be built or raises)."""
    try:
        return test is not None and bool(test(value))
    except Exception:  # a pattern may not apply to a malformed value
        return False


_BROADCAST = ("the vectors are of shape (3,) and the rotations (3, 3); a mean of two of them, "
              "np.mean([a, b], axis=0), is over axis 0, which keeps shape (3,)")


def _call_step(fn, *args, hint=""):
    """``call(fn, *args)``; numpy's shape errors and ``hint`` (if given) name the likely cause."""
    try:
        return call(fn, *args)
    except CheckFailed as exc:
        if "broadcast" in str(exc) or "matmul" in str(exc):  # numpy's words for mismatched shapes
            raise CheckFailed(f"{exc}. Hint: {_BROADCAST}") from None
        if hint:
            raise CheckFailed(f"{exc}. Hint: {hint}") from None
        raise


def _expect_double(value, what) -> None:
    """Fail on a floating result narrower than float64 before its values are compared: the
    tolerances (1e-9 … 1e-10 on entries of order 1 … 100) are below float32's rounding (about
    6e-8 relative), so a comparison would report a wrong value instead of the cause."""
    dtypes = [np.asarray(v).dtype for v in (value if isinstance(value, (tuple, list)) else (value,))
              if isinstance(v, (np.ndarray, np.generic))]
    narrow = [d for d in dtypes if d.kind in "fc" and d.itemsize < (8 if d.kind == "f" else 16)]
    if narrow:
        raise CheckFailed(f"{what} is {narrow[0].name}: it was computed in single precision. Hint: keep "
                          "NumPy's default float64 (no .astype(np.float32), no dtype=np.float32); float32 keeps "
                          "about 7 digits, and dead reckoning accumulates its rounding at every step")


def _result(value, shape, what, nan_hint=""):
    """The learner's value as an array of ``shape``; single precision fails first, NaN/inf
    with ``nan_hint``."""
    _expect_double(value, what)
    try:
        return expect_shape(value, shape, what)
    except CheckFailed as exc:
        if nan_hint and "NaN" in str(exc):
            raise CheckFailed(f"{exc}. Hint: {nan_hint}") from None
        raise


# ----------------------------------------------------------------------------------------
# The attitude step
# ----------------------------------------------------------------------------------------

def _phi(c, rate=None, dt=None):
    rate = 0.5 * (c["w0"] + c["w1"]) - c["b_w"] if rate is None else rate
    return rate * (c["dt"] if dt is None else dt)


def _first_order(value, c):
    """A rotation that agrees with R Exp(φ) only to first order in φ (error ≤ |φ|², > 1e-13)."""
    err = float(np.linalg.norm(so3.log(so3.orthonormalise(c["ref"].T @ value), check=False)))
    theta = float(np.linalg.norm(_phi(c)))
    return err <= max(theta * theta, 1e-13)


_MIDPOINT_RATE = "½(ω₀ + ω₁) − b_ω"
_F = hints.formula
_ZERO_RATE = ("at ω̄ T = 0 Rodrigues' formula divides 0 by 0: below a small angle use its series, or "
              "so3.Exp, which does (lecture 07 §1)" + _F(": Exp(φ) ≈ I + [φ]× + ½[φ]×²"))
_STEP_ROTATION = _F(f": R_next = R Exp(ω̄ T) with ω̄ = {_MIDPOINT_RATE}")
#: Mistakes in the rate (bias, midpoint, step, units): a step R Exp(φ′) with a wrong φ′, seen
#: the same way through C's step (Exp(−φ′) C, transposed).
_RATE_MISTAKES = [
    (lambda c: c["R"] @ so3.exp(_phi(c, 0.5 * (c["w0"] + c["w1"]))),
     "subtract the gyro bias: the bias was left out of the rate (lecture 07 §4)" + _F(f": ω̄ = {_MIDPOINT_RATE}")),
    (lambda c: c["R"] @ so3.exp(_phi(c, 0.5 * (c["w0"] + c["w1"]) + c["b_w"])),
     "the gyro bias is subtracted, not added (lecture 07 §4)" + _F(f": ω̄ = {_MIDPOINT_RATE}")),
    (lambda c: c["R"] @ so3.exp(_phi(c, 0.5 * (c["w0"] + c["w1"] - c["b_w"]))),
     "the gyro bias is subtracted in full from each rate, not halved (lecture 07 §4)" + _F(f": ω̄ = {_MIDPOINT_RATE}")),
    (lambda c: c["R"] @ so3.exp(_phi(c, c["w0"] - c["b_w"])),
     "midpoint rule: use the mean of the two rates, not the rate at the start of the step (that is Euler's "
     "rule; lecture 07 §4)" + _F(f": ω̄ = {_MIDPOINT_RATE}")),
    (lambda c: c["R"] @ so3.exp(_phi(c, c["w1"] - c["b_w"])),
     "midpoint rule: use the mean of the two rates, not the rate at the end of the step (lecture 07 §4)"
     + _F(f": ω̄ = {_MIDPOINT_RATE}")),
    (lambda c: c["R"] @ so3.exp(_phi(c, c["w0"] + c["w1"] - c["b_w"])),
     "midpoint rule: the mean of the two rates is half their sum (lecture 07 §4)" + _F(f": ω̄ = {_MIDPOINT_RATE}")),
    (lambda c: c["R"] @ so3.exp(_phi(c, dt=1.0)),
     "the rotation vector is a rate times the step (rad/s × s): multiply by dt (lecture 07 §4)" + _F(": φ = ω̄ T")),
    (lambda c: c["R"] @ so3.exp(_phi(c, dt=c["dt"] ** 2)),
     "the rotation vector is the rate times T, not T² (lecture 07 §4)" + _F(": φ = ω̄ T")),
    (lambda c: c["R"] @ so3.exp(_phi(c, dt=0.5 * c["dt"])),
     "the rotation over the step is the rate times the whole step, not half of it (lecture 07 §4)"
     + _F(": φ = ω̄ T")),
    (lambda c: c["R"] @ so3.exp(np.deg2rad(_phi(c))),
     "the gyro reads radians per second already: do not convert from degrees (lecture 07 §4)"),
    (lambda c: c["R"] @ so3.exp(np.rad2deg(_phi(c))),
     "the gyro reads radians per second already: do not convert to degrees (Exp takes radians; lecture 07 §1)"),
    (lambda c: c["R"] @ so3.exp((np.mean([c["w0"], c["w1"]]) - c["b_w"]) * c["dt"]),
     "the mean is over the two rates (axis 0 of [ω₀, ω₁]), not over all six numbers: "
     "np.mean([w0, w1], axis=0)"),
]

_ATTITUDE_MISTAKES = [
    (lambda c: so3.exp(_phi(c)) @ c["R"],
     "ω is measured in the body frame, so its rotation multiplies on the right (lecture 07 §3: Ṙ = R[ω]×)"
     + _F(": R_next = R Exp(ω̄ T), not Exp(ω̄ T) R") + " (the left would rotate about navigation-frame axes)"),
    (lambda c: c["R"].T @ so3.exp(_phi(c)),
     "do not transpose R: R is R_nb (body → navigation), and the step turns it as it is (lecture 07 §3)"
     + _F(": R_next = R Exp(ω̄ T)")),
    (lambda c: (c["R"] @ so3.exp(_phi(c))).T,
     "R_next is transposed: return R_nb, which maps body to navigation coordinates (lecture 07 §3)"
     + _F(": R_next = R Exp(ω̄ T), not its transpose")),
    (lambda c: c["R"] @ so3.exp(_phi(c)).T,
     "sign: the body turns forwards by the measured rate; the transpose of the step's rotation turns it back "
     "(lecture 07 §3)" + _F(": R_next = R Exp(+ω̄ T); Exp(−ω̄ T) = Exp(ω̄ T)ᵀ")),
] + _RATE_MISTAKES[:-1] + [
    (lambda c: c["R"] @ so3.exp(0.5 * (c["w0"] - c["b_w"]) * c["dt"]) @ so3.exp(0.5 * (c["w1"] - c["b_w"]) * c["dt"]),
     "the midpoint rule turns once, by the mean rate, not by two half-steps (rotations do not commute; "
     "lecture 07 §4)" + _F(f": R Exp(ω̄ T) with ω̄ = {_MIDPOINT_RATE}, not Exp(ω₀T/2) Exp(ω₁T/2)")),
] + _RATE_MISTAKES[-1:] + [
    (lambda c: c["R"],
     "the attitude did not change: the step must turn R by the step's rotation (lecture 07 §3)" + _STEP_ROTATION),
    (lambda c: so3.exp(_phi(c)),
     "compose with the previous attitude: the step's rotation alone is not the new attitude (lecture 07 §3)"
     + _F(": R_next = R Exp(ω̄ T), not Exp(ω̄ T) alone")),
]

#: Angles |ω̄ T| (rad) of the attitude step's sweep: one per decade where nothing switches, two
#: per decade from 1e-11 to 1e-2, where a learner's small-angle switch or series cut-off lies.
_SWEPT_ANGLES = np.r_[1e-13, 1e-12, np.logspace(-11, -2, 19), 0.1, 1.0, 3.0]

#: Steps (s) the sweep cycles through: far above, at and far below an IMU's interval (the
#: smallest angle with the longest step: a rate of 2e-13 rad/s).
_SWEPT_DT = (0.5, 0.01, 1e-4)


def _sweep_cases():
    """The attitude step's sweep: (name, R, w0, w1, b_w, dt) over the singular regimes.

    Each angle of :data:`_SWEPT_ANGLES` below 1e-2 rad about an axis and about its opposite
    (every third axis the diagonal, so that all components change sign), the two with two
    different steps from :data:`_SWEPT_DT`, so that the mean rates |ω̄| run from 2e-13 to
    20 rad/s (the larger angles about one of the two); rotation vectors within 1e-9 and 1e-3
    rad of π on both sides; large turns from an attitude within 1e-9 rad of a half turn. A
    small-angle switch or a series kept too far up errs there by the term it drops; a cut-off
    below 1e-10 rad errs by less than the tolerance (and passes: it is harmless).
    """
    rng = inputs.rng("imu.attitude.sweep", 17)
    R0 = so3.exp(rng.uniform(0.3, 3.0) * _random_axis(rng))
    R_half = so3.exp((np.pi - 1e-9) * _random_axis(rng))
    angles = _SWEPT_ANGLES
    if inputs.drawing():      # under a run seed every angle moves within its half-decade too
        angles = angles * inputs.log_uniform(rng, 0.8, 1.25, len(angles))
    raw = []
    for k, angle in enumerate(angles):
        u = np.ones(3) / np.sqrt(3.0) if k % 3 == 0 else _random_axis(rng)
        for j, sign in enumerate((1.0, -1.0) if angle < 1e-2 else (1.0 if k % 2 else -1.0,)):
            # the two signs with two different steps: a switch on the rate, not the angle, shows too
            dt = max(_SWEPT_DT[(k + j) % len(_SWEPT_DT)], angle / 20.0)     # no rate above 20 rad/s
            w = sign * angle / dt * u
            # two different rates and a bias: the bias-corrected mean is what the step turns by
            spread = 0.3 * angle / dt * _random_axis(rng)
            bias = 0.01 * _random_axis(rng)
            raw.append((f"|ω̄ T| = {angle:.2g} rad ({'+' if sign > 0 else '−'} axis, dt = {dt:g} s)",
                        R_half if angle >= 1.0 else R0, w + bias + spread, w + bias - spread, bias, dt))
    for k, gap in enumerate((1e-9, 1e-3)):
        u = _random_axis(rng)
        sign = 1.0 if k % 2 == 0 else -1.0
        for angle in (np.pi - gap, np.pi + gap):
            raw.append((f"|ω̄ T| = π {'−' if angle < np.pi else '+'} {gap:.0e} rad", R0,
                        sign * angle * u, sign * angle * u, np.zeros(3), 1.0))
    return raw


@functools.lru_cache(maxsize=None)
def _attitude_sweep():
    """The sweep's cases with their references (see :func:`_sweep_cases`)."""
    return tuple(dict(name=n, R=R, w0=w0, w1=w1, b_w=b, dt=dt, ref=reference_attitude_step(R, w0, w1, b, dt))
                 for n, R, w0, w1, b, dt in _sweep_cases())


def _judge_sweep(values, cases, matrix="R") -> None:
    """Fail on the first sweep case that differs, naming the regime (the main cases passed).

    ``values`` are R_nb attitudes (those of C's step transposed back); ``matrix`` names the
    learner's matrix in the message, ``"R"`` or ``"C"``."""
    failing = [k for k, (v, c) in enumerate(zip(values, cases)) if not _same(v, c["ref"], ATTITUDE_ATOL)]
    if not failing:
        return
    angles = [float(np.linalg.norm(_phi(c))) for c in cases]
    small = [k for k in failing if angles[k] < 1e-2]
    if small:
        k = max(small, key=lambda j: angles[j])
        unchanged = all(_same(values[j], cases[j]["R"], 1e-15) for j in small)
        err = float(np.max(np.abs(values[k] - cases[k]["ref"])))
        what = (f"your step returns {matrix} unchanged there, which drops the whole rotation" if unchanged else
                "your small-angle branch (a truncated series) drops a term that is larger than the tolerance "
                "there")
        raise CheckFailed(
            f"{matrix}_next is wrong for small rotations, up to |ω̄ T| = {angles[k]:.2g} rad (case '{cases[k]['name']}', "
            f"max abs error {err:.3g}): {what}. Hint: small rotations: below a small angle, a series must keep "
            "every term that exceeds about 1e-10 (lecture 07 §1); switch over at a smaller angle, or keep more "
            "terms, or use so3.Exp" + _F(": Exp(φ) ≈ I + [φ]× + ½[φ]×² errs by |φ|³/6"))
    k = failing[0]
    err = float(np.max(np.abs(values[k] - cases[k]["ref"])))
    raise CheckFailed(
        f"{matrix}_next is wrong for a large rotation, |ω̄ T| = {angles[k]:.3g} rad (case '{cases[k]['name']}', max abs "
        f"error {err:.3g}). Hint: Exp is defined for every angle, π and beyond included: no wrapping of the "
        "angle or of the axis is needed, and a hand-made Log/Exp pair must stay exact near π (lecture 07 §1)"
        + _F(": Exp(φ) = I + (sin θ/θ)[φ]× + ((1 − cos θ)/θ²)[φ]×²"))


_SMALL_UNCHANGED = ("small rotations: your step returns R unchanged below some angle, which drops the whole "
                    "rotation (an error of |φ|, above the tolerance 1e-10 from |φ| = 1e-10 on); below a small "
                    "angle, a series must keep every term that exceeds about 1e-10 (lecture 07 §1), or use so3.Exp"
                    + _F(": Exp(φ) ≈ I + [φ]× + ½[φ]×²"))


def _unchanged_when_small(value, c) -> bool:
    """Whether ``value`` is right, or R unchanged on a case whose rotation is small (< 1e-2 rad)."""
    return _same(value, c["ref"], ATTITUDE_ATOL) or (float(np.linalg.norm(_phi(c))) < 1e-2
                                                    and _same(value, c["R"], 1e-15))


def _attitude_values(attitude_step, cases, matrix="R"):
    """The learner's R_next on each case, as (3, 3) rotations.

    With ``matrix="C"`` the learner's step turns C = R_bn: it is handed Rᵀ (a copy) and its
    result is transposed back, so that every value, mistake and pattern is an R_nb attitude."""
    values = []
    for c in cases:
        zero = not np.any(_phi(c))
        start = c["R"] if matrix == "R" else np.array(c["R"].T)
        # at ω̄ = 0 a learner's own Rodrigues may raise (so3.hat(φ / θ) refusing a NaN)
        got = _call_step(attitude_step, start, c["w0"], c["w1"], c["b_w"], c["dt"],
                         hint=f"on the case '{c['name']}', {_ZERO_RATE}" if zero else "")
        got = _result(got, (3, 3), f"{matrix}_next on the case '{c['name']}'", nan_hint=_ZERO_RATE if zero else "")
        if not so3.is_rotation(got, tol=1e-9):
            err = np.max(np.abs(got.T @ got - np.eye(3)))
            raise CheckFailed(
                f"{matrix}_next on the case '{c['name']}' is not a rotation matrix (|{matrix}ᵀ{matrix} − I| = {err:.2g}). "
                "Hint: compose with the exponential of the step's rotation vector, not with the first-order "
                "I + [φ]× or another truncated series (lecture 07 §3); a quaternion must be normalised to unit "
                "length before it becomes a matrix")
        values.append(got if matrix == "R" else got.T)
    return values


_FROM_BN = _F(": R_next = attitude_step_bn(Rᵀ, …)ᵀ")

#: Mistakes of an ``attitude_step`` built from the learner's ``attitude_step_bn`` (a right one):
#: the conversions between R and C = Rᵀ forgotten on the way in, on the way out, or both.
_WRAPPER_MISTAKES = [
    (lambda c: so3.exp(-_phi(c)) @ c["R"],
     "attitude_step_bn takes and returns C = R_bn = Rᵀ, while attitude_step takes and returns R = R_nb: hand "
     "it the transpose of R, and transpose what it returns" + _FROM_BN),
    (lambda c: so3.exp(-_phi(c)) @ c["R"].T,
     "attitude_step_bn returns C_next = R_nextᵀ: transpose it back into R_nb before returning it" + _FROM_BN),
    (lambda c: c["R"].T @ so3.exp(_phi(c)),
     "attitude_step_bn takes C = Rᵀ: hand it the transpose of R, not R itself" + _FROM_BN),
]


@check(uses=("attitude_step_bn",))
def check_attitude_step(attitude_step):
    """``attitude_step(R, w0, w1, b_w, dt)`` returns the attitude at the next sample.

    The main cases name the mistakes; then a sweep of the singular regimes
    (:func:`_sweep_cases`) finds a small-angle switch or series that errs beyond the tolerance.
    An ``attitude_step`` that calls ``attitude_step_bn`` (the exercise builds it so) is also
    judged for the conversions between R and C, and is told to fix ``attitude_step_bn`` first
    when that fails its own check.
    """
    cases = _attitude_cases()
    wrapper = "attitude_step_bn" in referenced_names(attitude_step)
    _grade(_attitude_values(attitude_step, cases), cases, "R_next", ATTITUDE_ATOL,
           (_WRAPPER_MISTAKES if wrapper else []) + _ATTITUDE_MISTAKES,
           hint="the step composes R with the exponential of the step's rotation, the bias-corrected mean "
                "rate times T (lecture 07 §3–4)" + _STEP_ROTATION, patterns=[(
               _first_order, "R_next agrees with the exponential only to first order in φ = ω̄ T: a "
               "first-order I + [φ]× (even re-orthonormalised) or a truncated series is not the "
               "exponential (lecture 07 §3); use Rodrigues' formula or so3.Exp(φ)"),
               (_unchanged_when_small, _SMALL_UNCHANGED)])
    sweep = _attitude_sweep()
    _judge_sweep(_attitude_values(attitude_step, sweep), sweep)


# ----------------------------------------------------------------------------------------
# The attitude step for C = R_bn (the learner derives it)
# ----------------------------------------------------------------------------------------

_BN_STEP = _F(f": C_next = Exp(φ)ᵀ C = Exp(−ω̄ T) C with ω̄ = {_MIDPOINT_RATE}")

#: C = R_bn's mistakes, each as the R_nb attitude it amounts to (the learner's C_next
#: transposed): the learner's expression is in the comment. φ = ω̄ T.
_ATTITUDE_BN_MISTAKES = [
    # C Exp(φ): lecture 07's step for R, applied to C
    (lambda c: so3.exp(-_phi(c)) @ c["R"],
     "this is lecture 07's step for R = R_nb, applied to C = R_bn. C is the transpose of R, so its step is the "
     "transpose of the lecture's: transpose both sides of the lecture's step (§3), using what the transpose of "
     "Exp(φ) is (§1)" + _BN_STEP),
    # Exp(φ) C: the right side, the wrong sign
    (lambda c: c["R"] @ so3.exp(-_phi(c)),
     "the side is right (transposing a product reverses its order), but the step's rotation must be transposed "
     "too: the transpose of a rotation turns back by the same angle (lecture 07 §1)"
     + _F(": Exp(φ)ᵀ = Exp(−φ), so C_next = Exp(−φ) C")),
    # C Exp(−φ): the right sign, the wrong side
    (lambda c: so3.exp(_phi(c)) @ c["R"],
     "the sign is right, but transposing a product also reverses the order of its factors: C maps navigation "
     "coordinates to body coordinates, so the body frame, where the gyro measures, is on C's left "
     "(lecture 07 §3)" + _F(": Ċ = Ṙᵀ = (R[ω]×)ᵀ = −[ω]× C, so C_next = Exp(−φ) C")),
    # Cᵀ Exp(φ): the lecture's step of R = Cᵀ, returned as it is
    (lambda c: so3.exp(-_phi(c)) @ c["R"].T,
     "your step returns the new R_nb (the lecture's step of R = Cᵀ): attitude_step_bn takes and returns "
     "C = R_bn, so transpose the result, or better, turn C itself" + _BN_STEP),
    # Exp(−φ) Cᵀ: C transposed on the way in
    (lambda c: c["R"].T @ so3.exp(_phi(c)),
     "do not transpose C: it is R_bn already, and its step turns it as it is" + _BN_STEP),
] + _RATE_MISTAKES[:-1] + [
    # Exp(−φ₁/2) Exp(−φ₀/2) C: two half steps
    (lambda c: c["R"] @ so3.exp(0.5 * (c["w0"] - c["b_w"]) * c["dt"]) @ so3.exp(0.5 * (c["w1"] - c["b_w"]) * c["dt"]),
     "the midpoint rule turns once, by the mean rate, not by two half-steps (rotations do not commute; "
     "lecture 07 §4)" + _BN_STEP),
] + _RATE_MISTAKES[-1:] + [
    (lambda c: c["R"],
     "the attitude did not change: the step must turn C by the step's rotation (lecture 07 §3)" + _BN_STEP),
    (lambda c: so3.exp(_phi(c)),
     "compose with the previous attitude: the step's rotation alone is not the new attitude (lecture 07 §3)"
     + _BN_STEP),
    (lambda c: so3.exp(-_phi(c)),
     "compose with the previous attitude: the step's rotation alone is not the new attitude (lecture 07 §3)"
     + _BN_STEP),
]

_BN_SMALL_UNCHANGED = ("small rotations: your step returns C unchanged below some angle, which drops the whole "
                       "rotation (an error of |φ|, above the tolerance 1e-10 from |φ| = 1e-10 on); below a small "
                       "angle, a series must keep every term that exceeds about 1e-10 (lecture 07 §1), or use "
                       "so3.Exp" + _F(": Exp(φ) ≈ I + [φ]× + ½[φ]×²"))


@check
def check_attitude_step_bn(attitude_step_bn):
    """``attitude_step_bn(C, w0, w1, b_w, dt)`` returns C = R_bn at the next sample.

    The cases and the sweep are the R_nb step's: the learner's step is handed C = Rᵀ and its
    result is transposed back (:func:`_attitude_values`), so that the tolerance, the patterns
    of a first-order step and of a small-angle cut-off, and the rate mistakes are those of
    :func:`check_attitude_step`; the mistakes of the convention (:data:`_ATTITUDE_BN_MISTAKES`)
    have hints of their own.
    """
    cases = _attitude_cases()
    _grade(_attitude_values(attitude_step_bn, cases, matrix="C"), cases, "C_next", ATTITUDE_ATOL,
           _ATTITUDE_BN_MISTAKES,
           hint="C = R_bn is the transpose of lecture 07's R_nb: its step is the transpose of the lecture's step, "
                "with the bias-corrected mean rate times T (lecture 07 §3–4)" + _BN_STEP, patterns=[(
               _first_order, "C_next agrees with the exponential only to first order in φ = ω̄ T: a "
               "first-order I − [φ]× (even re-orthonormalised) or a truncated series is not the "
               "exponential (lecture 07 §3); use Rodrigues' formula or so3.Exp"),
               (_unchanged_when_small, _BN_SMALL_UNCHANGED)])
    sweep = _attitude_sweep()
    _judge_sweep(_attitude_values(attitude_step_bn, sweep, matrix="C"), sweep, matrix="C")


# ----------------------------------------------------------------------------------------
# The velocity step
# ----------------------------------------------------------------------------------------

def _acc(c, R0=None, R1=None, bias=None):
    """½(R₀(f₀ − b) + R₁(f₁ − b)) of a velocity case, with any of its parts replaced."""
    v, R0_, R1_, f0, f1, b_a, g, T = c["args"]
    R0 = R0_ if R0 is None else R0
    R1 = R1_ if R1 is None else R1
    b = b_a if bias is None else bias
    return 0.5 * (R0 @ (f0 - b) + R1 @ (f1 - b))


def _mid_step_attitude(c):
    """The attitude half-way between R₀ and R₁ of a velocity case: R₀ Exp(½ Log(R₀ᵀ R₁))."""
    R0, R1 = c["args"][1], c["args"][2]
    return R0 @ so3.exp(0.5 * so3.log(R0.T @ R1, check=False))


def _v(c, acc, gravity=None, T=None, v0=None):
    v, R0, R1, f0, f1, b_a, g, dt = c["args"]
    g = g if gravity is None else gravity
    T = dt if T is None else T
    v = v if v0 is None else v0
    return v + (acc + g) * T


_A = _F(": a = R (f − b_a) + g")
_V_NEXT = _F(": v_next = v + (½(a₀ + a₁) + g) T, with aᵢ = Rᵢ(fᵢ − b_a)")
_GRAVITY_SIGN = ("gravity: lecture 07 §4 adds g with g = (0, 0, −9.81) pointing down (the seed notes subtract "
                 "it with g pointing up: the same formula for the other sign of g). A resting accelerometer "
                 "reads f = +9.81 up, and then the acceleration is zero" + _A)
_HARD_CODED = ("use the gravity vector g handed in (it differs between the cases), not a hard-coded "
               "constant (lecture 07 §4)" + _A)
_VELOCITY_MISTAKES = [
    (lambda c: _v(c, _acc(c), gravity=-c["args"][6]), _GRAVITY_SIGN),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, -9.81])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, 9.81])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, -9.8])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, 9.8])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, -9.80665])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, 9.80665])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, -9.8092])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.array([0.0, 0.0, 9.8092])), _HARD_CODED),
    (lambda c: _v(c, _acc(c), gravity=np.zeros(3)),
     "gravity is missing: the accelerometer measures specific force, not acceleration (lecture 07 §4)" + _A),
    (lambda c: _v(c, _acc(c), gravity=0.5 * c["args"][6]),
     "gravity is added once, in full, not halved with the readings (lecture 07 §4)" + _V_NEXT),
    (lambda c: _v(c, _acc(c), gravity=2.0 * c["args"][6]),
     "gravity is added once, not once per reading (lecture 07 §4)" + _V_NEXT),
    (lambda c: _v(c, 0.5 * (c["args"][1] @ (c["args"][3] - c["args"][5] + c["args"][6])
                            + c["args"][2] @ (c["args"][4] - c["args"][5] + c["args"][6])), gravity=np.zeros(3)),
     "gravity is a navigation-frame vector: add g after rotating the body-frame reading, not before "
     "(lecture 07 §4)" + _F(": a = R (f − b_a) + g, not R (f − b_a + g)")),
    (lambda c: _v(c, _acc(c)) - c["args"][6] * c["args"][7] + c["args"][6],
     "gravity is an acceleration too: it changes the velocity by g T, not by g (lecture 07 §4)"),
    (lambda c: _v(c, _acc(c, bias=np.zeros(3))),
     "subtract the accelerometer bias from each reading (lecture 07 §4)" + _F(": R (f − b_a)")),
    (lambda c: _v(c, 0.5 * (c["args"][1] + c["args"][2]) @ (0.5 * (c["args"][3] + c["args"][4]) - c["args"][5])),
     "rotate each reading with the attitude at its own time, then average; not the mean attitude times the "
     "mean reading (lecture 07 §4)" + _F(": ½(R₀(f₀ − b_a) + R₁(f₁ − b_a))")),
    (lambda c: _v(c, _mid_step_attitude(c) @ (0.5 * (c["args"][3] + c["args"][4]) - c["args"][5])),
     "the midpoint rule rotates each reading with the attitude at its own time, R₀ for f₀ and R₁ for f₁, "
     "then averages; one mid-step attitude for the mean reading is another (not the lecture's) rule "
     "(lecture 07 §4)"),
    (lambda c: _v(c, _acc(c) + 0.5 * c["args"][2] @ c["args"][5]),
     "subtract the accelerometer bias from each reading, not from one only (lecture 07 §4)"
     + _F(": R₀(f₀ − b_a) and R₁(f₁ − b_a)")),
    (lambda c: _v(c, _acc(c) + 0.5 * c["args"][1] @ c["args"][5]),
     "subtract the accelerometer bias from each reading, not from one only (lecture 07 §4)"
     + _F(": R₀(f₀ − b_a) and R₁(f₁ − b_a)")),
    (lambda c: _v(c, _acc(c, bias=-c["args"][5])),
     "the accelerometer bias is subtracted, not added (lecture 07 §4)" + _F(": R (f − b_a)")),
    (lambda c: _v(c, _acc(c, bias=np.zeros(3)) - c["args"][5]),
     "the accelerometer bias is a body-frame quantity: subtract it before rotating (lecture 07 §4)"
     + _F(": R (f − b_a), not R f − b_a")),
    (lambda c: _v(c, _acc(c, R1=c["args"][1])),
     "the acceleration at the end of the step uses the NEW attitude, not R₀ (lecture 07 §4)"
     + _F(": a₁ = R₁(f₁ − b_a)")),
    (lambda c: _v(c, _acc(c, R0=c["args"][2])),
     "the acceleration at the start of the step uses the OLD attitude, not R₁ (lecture 07 §4)"
     + _F(": a₀ = R₀(f₀ − b_a)")),
    (lambda c: _v(c, 0.5 * (c["args"][2] @ (c["args"][3] - c["args"][5])
                            + c["args"][1] @ (c["args"][4] - c["args"][5]))),
     "each reading is rotated with the attitude at its own time: R₀ with f₀, R₁ with f₁ (they are swapped; "
     "lecture 07 §4)"),
    (lambda c: _v(c, _acc(c, R0=np.eye(3), R1=np.eye(3))),
     "the readings are in the body frame: rotate them into the navigation frame (lecture 07 §4)" + _A),
    (lambda c: _v(c, _acc(c, R0=c["args"][1].T, R1=c["args"][2].T)),
     "do not transpose R: R = R_nb maps body-frame readings to the navigation frame (lecture 07 §4)" + _A),
    (lambda c: _v(c, c["args"][1] @ (c["args"][3] - c["args"][5])),
     "midpoint rule: average the accelerations at both ends of the step, not the start one only (that is "
     "Euler's rule; lecture 07 §4)" + _F(": ½(a₀ + a₁)")),
    (lambda c: _v(c, c["args"][2] @ (c["args"][4] - c["args"][5])),
     "midpoint rule: average the accelerations at both ends of the step, not the end one only (lecture 07 §4)"
     + _F(": ½(a₀ + a₁)")),
    (lambda c: _v(c, 2.0 * _acc(c)),
     "midpoint rule: the mean acceleration is half the sum (lecture 07 §4)" + _F(": ½(R₀(f₀ − b_a) + R₁(f₁ − b_a))")),
    (lambda c: _v(c, 2.0 * _acc(c), gravity=2.0 * c["args"][6]),
     "midpoint rule: the mean of the two accelerations is half their sum (gravity included, it counts once; "
     "lecture 07 §4)" + _F(": ½(a₀ + a₁)")),
    (lambda c: _v(c, _acc(c), T=c["args"][7] ** 2),
     "the velocity changes by the acceleration times T, not T² (lecture 07 §4)" + _V_NEXT),
    (lambda c: _v(c, _acc(c), T=1.0),
     "multiply the acceleration by the step (m/s² × s; lecture 07 §4)" + _V_NEXT),
    (lambda c: _v(c, _acc(c), T=0.5 * c["args"][7]),
     "the velocity changes by the acceleration over the whole step, not by a T/2 (lecture 07 §4)" + _V_NEXT),
    (lambda c: _v(c, _acc(c), v0=np.zeros(3)),
     "v_next is the previous velocity plus the increment (lecture 07 §4)" + _V_NEXT),
]


@check
def check_velocity_step(velocity_step):
    """``velocity_step(v, R0, R1, f0, f1, b_a, g, dt)`` returns the velocity at the next sample."""
    cases = _velocity_cases()
    values = [_result(_call_step(velocity_step, *c["args"]), (3,), f"v_next on the case '{c['name']}'")
              for c in cases]
    _grade(values, cases, "v_next", VELOCITY_ATOL, _VELOCITY_MISTAKES,
           hint="the velocity step averages the navigation-frame accelerations at both ends of the step, each "
                "reading rotated with the attitude at its own time, and adds gravity (lecture 07 §4)"
                + _F(": v_next = v + ½(R₀(f₀ − b_a) + R₁(f₁ − b_a)) T + g T, with R₁ the attitude at the end of "
                     "the step and g = (0, 0, −9.81) added"))


# ----------------------------------------------------------------------------------------
# The position step
# ----------------------------------------------------------------------------------------

_P_NEXT = _F(": p_next = p + ½(v₀ + v₁) T")
_POSITION_MISTAKES = [
    (lambda c: c["args"][0] + c["args"][2] * c["args"][3],
     "midpoint rule: use the mean velocity of the step, not the new one (lecture 07 §4)" + _P_NEXT),
    (lambda c: c["args"][0] + c["args"][1] * c["args"][3],
     "midpoint rule: use the mean velocity of the step, not the old one (that is Euler's rule; lecture 07 §4)"
     + _P_NEXT),
    (lambda c: c["args"][0] + (c["args"][1] + c["args"][2]) * c["args"][3],
     "the ½ is missing: the mean velocity is half the sum (lecture 07 §4)" + _P_NEXT),
    (lambda c: c["args"][0] + 0.5 * (c["args"][1] + c["args"][2]) * c["args"][3] ** 2,
     "the position changes by the velocity times T, not T² (lecture 07 §4)" + _P_NEXT),
    (lambda c: c["args"][0] + 0.5 * (c["args"][1] + c["args"][2]),
     "multiply the mean velocity by the step (m/s × s; lecture 07 §4)" + _P_NEXT),
    (lambda c: c["args"][0] + 0.25 * (c["args"][1] + c["args"][2]) * c["args"][3],
     "the ½ of the mean velocity is applied once (lecture 07 §4)" + _P_NEXT),
    (lambda c: c["args"][0] + c["args"][1] * c["args"][3] + 0.5 * (c["args"][2] - c["args"][1]) * c["args"][3] ** 2,
     "units: ½(v₁ − v₀) T² is in m·s, not m. p + v₀T + ½aT² needs the acceleration a = (v₁ − v₀)/T, "
     "not the velocity change v₁ − v₀ (lecture 07 §4)"
     + _F(": this gives p + v₀T + ½(v₁ − v₀)T = p + ½(v₀ + v₁) T")),
    (lambda c: c["args"][0] + 0.5 * (c["args"][2] - c["args"][1]) * c["args"][3],
     "sign: the mean velocity is a sum, not a difference (lecture 07 §4)" + _F(": ½(v₀ + v₁)")),
    (lambda c: c["args"][0] + 0.5 * (c["args"][1] - c["args"][2]) * c["args"][3],
     "sign: the mean velocity is a sum, not a difference (lecture 07 §4)" + _F(": ½(v₀ + v₁)")),
    (lambda c: c["args"][0] - 0.5 * (c["args"][1] + c["args"][2]) * c["args"][3],
     "sign: the position moves along the velocity (lecture 07 §4)" + _P_NEXT),
    (lambda c: 0.5 * (c["args"][1] + c["args"][2]) * c["args"][3],
     "p_next is the previous position plus the displacement (lecture 07 §4)" + _P_NEXT),
    (lambda c: c["args"][0] + np.mean([c["args"][1], c["args"][2]]) * c["args"][3],
     "the mean is over the two velocities (axis 0 of [v₀, v₁]), not over all six numbers: "
     "np.mean([v0, v1], axis=0)"),
]


@check
def check_position_step(position_step):
    """``position_step(p, v0, v1, dt)`` returns the position at the next sample."""
    cases = _position_cases()
    values = []
    for c in cases:
        values.append(_result(_call_step(position_step, *c["args"]), (3,), f"p_next on the case '{c['name']}'"))
    _grade(values, cases, "p_next", POSITION_ATOL, _POSITION_MISTAKES,
           hint="the position step moves by the step's mean velocity times its length, exact for a constant "
                "acceleration (lecture 07 §4)" + _P_NEXT)


# ----------------------------------------------------------------------------------------
# The whole run
# ----------------------------------------------------------------------------------------

def _variant_run(imu, state, g, start, stop, *, dt="own", w_at=(-1, 0), f_at=(-1, 0), offset=True, pair="midpoint",
                 turn=True, gravity=True, bias=None, vpair="midpoint", from_start=False):
    """A mechanisation run with one plausible loop mistake (the reference when no flag is set).

    Parameters
    ----------
    dt : {"own", "first", "slice", "next", "since"}
        Each step's own t[k] − t[k−1]; the data's first t[1] − t[0]; the slice's first
        t[start+1] − t[start]; the next interval t[k+1] − t[k]; or the time since the start.
    w_at, f_at : (int, int)
        The rates (specific forces) of the step to sample k are taken at k + w_at[0] and
        k + w_at[1]: (−1, 0) is right.
    offset : bool
        False: the step index ignores ``start`` (k = i).
    pair : {"midpoint", "old", "new", "swapped"}
        The attitudes handed to the velocity step.
    turn : bool
        False: the attitude is never updated.
    from_start : bool
        True: every attitude step starts from the initial attitude instead of the previous one.
    gravity : bool
        False: zero gravity handed to the velocity step.
    bias : array_like, optional
        The accelerometer bias handed to the velocity step (g when g and the bias are swapped).
    vpair : {"midpoint", "old", "new"}
        The velocities handed to the position step.
    """
    n = stop - start
    p, v, R = np.empty((n, 3)), np.empty((n, 3)), np.empty((n, 3, 3))
    p[0], v[0], R[0] = state.position, state.velocity, state.rotation
    zero = np.zeros(3)
    b_a = zero if bias is None else bias
    g_used = g if gravity else zero
    t, f, w = imu.t, imu.specific_force, imu.angular_rate
    for i in range(1, n):
        k = (start if offset else 0) + i
        T = {"own": lambda: t[k] - t[k - 1], "first": lambda: t[1] - t[0],
             "slice": lambda: t[start + 1] - t[start], "next": lambda: t[k + 1] - t[k],
             "since": lambda: t[k] - t[start]}[dt]()
        a, b = k + w_at[0], k + w_at[1]
        R[i] = reference_attitude_step(R[0] if from_start else R[i - 1], w[a], w[b], zero, T) if turn else R[i - 1]
        a, b = k + f_at[0], k + f_at[1]
        R0, R1 = {"midpoint": (R[i - 1], R[i]), "old": (R[i - 1], R[i - 1]), "new": (R[i], R[i]),
                  "swapped": (R[i], R[i - 1])}[pair]
        v[i] = reference_velocity_step(v[i - 1], R0, R1, f[a], f[b], b_a, g_used, T)
        v0, v1 = {"midpoint": (v[i - 1], v[i]), "old": (v[i - 1], v[i - 1]), "new": (v[i], v[i])}[vpair]
        p[i] = reference_position_step(p[i - 1], v0, v1, T)
    return p, v, R


_OFF_BY_ONE = ("off by one: the step from sample k−1 to sample k uses the readings at both of its ends and its "
               "own length (lecture 07 §4)" + _F(": the readings at k−1 and k, dt = imu.t[k] − imu.t[k−1]"))
_OWN_DT = _F(": dt = imu.t[k] − imu.t[k−1]")
_RUN_MISTAKES = [
    (dict(dt="first"), "KITTI's IMU timestamps are irregular (dt from {dt_range} here): give every step its "
                       "own length, not the first interval (lecture 07 §4)" + _OWN_DT),
    (dict(dt="slice"), "KITTI's IMU timestamps are irregular (dt from {dt_range} here): give every step its "
                       "own length, not one interval for all (lecture 07 §4)" + _OWN_DT),
    (dict(dt="next"), _OFF_BY_ONE + " (your dt is the next interval, imu.t[k+1] − imu.t[k])"),
] + [
    (dict(w_at=(0, 1), f_at=(0, 1)), _OFF_BY_ONE + " (your readings are those at k and k+1)"),
    (dict(w_at=(0, 1)), _OFF_BY_ONE + " (your rates are those at k and k+1)"),
    (dict(f_at=(0, 1)), _OFF_BY_ONE + " (your specific forces are those at k and k+1)"),
    (dict(w_at=(-2, -1), f_at=(-2, -1)), _OFF_BY_ONE + " (your readings are those at k−2 and k−1)"),
    (dict(w_at=(-2, -1)), _OFF_BY_ONE + " (your rates are those at k−2 and k−1)"),
    (dict(f_at=(-2, -1)), _OFF_BY_ONE + " (your specific forces are those at k−2 and k−1)"),
] + [
    (dict(w_at=at, f_at=at2), "midpoint rule: the step from k−1 to k uses the readings at both ends, k−1 and k "
                              f"(you passed one reading twice{note}; lecture 07 §4)")
    for at, at2, note in (((-1, -1), (-1, -1), ": Euler's rule"), ((0, 0), (0, 0), ""),
                          ((-1, -1), (-1, 0), ", the rate"), ((0, 0), (-1, 0), ", the rate"),
                          ((-1, 0), (-1, -1), ", the specific force"), ((-1, 0), (0, 0), ", the specific force"))
] + [
    (dict(offset=False), "the run starts at sample `start`, not at sample 0: the step to row i uses sample "
                         "k = start + i, not k = i (exercise §4)"),
    (dict(pair="old"), "hand the velocity step the attitudes at both ends of the step, R[i−1] and the new "
                       "R[i] (you passed the old attitude twice; lecture 07 §4)"),
    (dict(pair="new"), "hand the velocity step the attitudes at both ends of the step, R[i−1] and the new "
                       "R[i] (you passed the new attitude twice; lecture 07 §4)"),
    (dict(pair="swapped"), "hand the velocity step the attitudes in the order of the readings: R[i−1] (with "
                           "the reading at k−1), then R[i] (they are swapped; lecture 07 §4)"),
    (dict(dt="since"), "dt is the length of this step, not the time since the start (lecture 07 §4)" + _OWN_DT),
    (dict(from_start=True), "each attitude step starts from the previous row's attitude R[i−1], not from "
                            "the initial one (lecture 07 §4)"),
    (dict(turn=False), "the attitude is never updated: each row's attitude comes from attitude_step applied to "
                       "the row before (lecture 07 §4)" + _F(": R[i] = attitude_step(R[i−1], ...)")),
    (dict(gravity=False), "gravity is missing from the run: hand g to the velocity step (lecture 07 §4)"),
    (dict(gravity=False, bias="g"), "gravity and the accelerometer bias are swapped in the call of "
                                    "velocity_step(v, R0, R1, f0, f1, b_a, g, dt)"),
    (dict(vpair="old"), "hand the position step the velocities at both ends of the step, v[i−1] and the new "
                        "v[i] (you passed the old velocity twice; lecture 07 §4)"),
    (dict(vpair="new"), "hand the position step the velocities at both ends of the step, v[i−1] and the new "
                        "v[i] (you passed the new velocity twice; lecture 07 §4)"),
]


def _synthetic_scenario(seed, duration):
    """Synthetic motion whose truth the midpoint rule reproduces exactly, with a constant dt;
    run to the last sample, so that an index one past the end raises."""
    sc = imu_trajectory(seed, duration=duration)
    state = NavState(sc.position[0], sc.velocity[0], sc.rotation[0])
    return ("synthetic motion with clean readings", sc.imu_clean, state, GRAVITY.copy(), 0,
            len(sc.t), (sc.position, sc.velocity, sc.rotation))


def _kitti_scenario(name, k0, n):
    """KITTI: irregular dt, a slice that starts at sample k0 and ends before the data's end."""
    ex = load_kitti(name)
    nav = ex.truth.state_at(ex.imu.t[k0])
    ref = dead_reckon(ex.imu, nav, ex.gravity, start=k0, stop=k0 + n)
    return (f"KITTI '{name}' samples {k0}..{k0 + n - 1}", ex.imu, nav, ex.gravity.copy(), k0, k0 + n,
            (ref.position, ref.velocity, ref.rotation))


def _same_runs(a, b) -> bool:
    return all(np.allclose(x, y, rtol=0.0, atol=tol) for x, y, tol in zip(a, b, RUN_ATOL))


def _mistakes_stay_apart(scenario) -> bool:
    """Whether, on ``scenario``, no two listed loop mistakes give the same run and (on KITTI,
    where every one of them must show) none gives the reference's: otherwise a drawn slice
    could pass a mistake or name the wrong one."""
    name, imu, state, g, start, stop, ref = scenario
    runs = []
    for flags, _ in _RUN_MISTAKES:
        flags = dict(flags, bias=g) if flags.get("bias") == "g" else flags
        try:
            runs.append(_variant_run(imu, state, g, start, stop, **flags))
        except IndexError:          # (the synthetic run reaches the data's end: skipped there too)
            continue
    kitti = start > 0
    if kitti and any(_same_runs(run, ref) for run in runs):
        return False
    moved = [run for run in runs if not _same_runs(run, ref)]
    return not any(_same_runs(a, b) for i, a in enumerate(moved) for b in moved[i + 1:])


def _drawn_scenarios():
    """The two runs under a run seed: another simulated trajectory (3–5 s, no longer than the
    fixed one) and another slice of the real KITTI readings, each redrawn until the listed
    loop mistakes stay apart on it."""
    rng = inputs.rng("imu.run")
    name, _, n_fixed = RUN_SLICE
    size = len(load_kitti(name).imu)
    while True:
        synthetic = _synthetic_scenario(int(rng.integers(10, 2**31)), float(rng.uniform(3.0, 5.0)))
        if _mistakes_stay_apart(synthetic):
            break
    while True:
        n = int(rng.integers(300, n_fixed + 1))
        kitti = _kitti_scenario(name, int(rng.integers(10, size - n - 10)), n)
        if _mistakes_stay_apart(kitti):
            break
    return synthetic, kitti


@functools.lru_cache(maxsize=None)
def _run_scenarios():
    """(name, imu, initial state, g, start, stop, reference (p, v, R)) of the two runs."""
    if inputs.drawing():
        return _drawn_scenarios()
    return _synthetic_scenario(3, 5.0), _kitti_scenario(*RUN_SLICE)


def _dt_range(imu, start, stop) -> str:
    """The spread of the slice's sample intervals, in words for a hint (ms)."""
    dt = 1e3 * np.diff(imu.t[start:stop])
    return f"{dt.min():.2g} to {dt.max():.2g} ms"


#: Tolerances of the run, m, m/s and on rotation entries: the learner's loop of steps and
#: the vectorised reference round differently; 500 steps accumulate ~1e-13 m. Every mistake
#: above changes the KITTI positions by ≥ 4e-4 m within the run.
RUN_ATOL = (1e-6, 1e-8, 1e-10)


def _diagnose_run(result, scenario):
    """Raise CheckFailed naming the loop mistake that reproduces the learner's run, if any."""
    name, imu, state, g, start, stop, ref = scenario
    p, v, R = result
    if not (np.allclose(p[0], state.position) and np.allclose(v[0], state.velocity)
            and np.allclose(R[0], state.rotation)):
        raise CheckFailed(f"the first row on {name} is not the initial state. Hint: row 0 of positions, "
                          "velocities and rotations is the state handed in (at imu.t[start]; exercise §4)")
    frozen = [bool(np.allclose(x, x[0], rtol=0.0, atol=tol)) for x, tol in zip(result, RUN_ATOL)]
    if all(frozen):
        raise CheckFailed(f"on {name} every row equals the initial state: the loop makes no step (is the "
                          "placeholder still there?). Hint: each row i is one mechanisation step from row i − 1 "
                          "with the readings at k − 1 and k, made by your attitude_step, velocity_step and "
                          "position_step (lecture 07 §4)")
    def run_with(flags, _):
        # a swapped bias and gravity is the only mistake that needs this scenario's g
        return _variant_run(imu, state, g, start, stop, **(dict(flags, bias=g) if flags.get("bias") == "g" else flags))

    # a mistake that indexes past the data (IndexError) cannot be the learner's: known_mistake skips it
    why = known_mistake([result], [scenario], _RUN_MISTAKES, evaluate=run_with,
                        close=lambda mine, wrong, _: wrong is not None and _same_runs(mine, wrong))
    if why:
        why = why.format(dt_range=_dt_range(imu, start, stop)) if "{dt_range}" in why else why
        raise CheckFailed(f"the run on {name} is wrong. Hint: {why}")
    if np.allclose(R, np.swapaxes(ref[2], 1, 2), rtol=0.0, atol=RUN_ATOL[2]):
        raise CheckFailed(f"rotations on {name} are transposed. Hint: return R_nb (body → navigation), "
                          "as attitude_step computes it (lecture 07 §3)")
    if all(np.allclose(x[:-1], y[:-1], rtol=0.0, atol=tol) for x, y, tol in zip(result, ref, RUN_ATOL)):
        raise CheckFailed(f"the last state on {name} is wrong. Hint: the loop fills rows 1 .. n−1 (did it stop "
                          "one step early?)" + _F(": for i in range(1, n)"))
    for still, what, step in zip(frozen, ("positions", "velocities"), ("position_step", "velocity_step")):
        if still:
            raise CheckFailed(f"the {what} on {name} never change from the initial state. Hint: every step "
                              f"must fill row i with {step}, from row i − 1 (lecture 07 §4)")


@check(uses=("attitude_step", "velocity_step", "position_step"))
def check_mechanisation_run(mechanise):
    """``mechanise(imu, state, g, start, stop)`` returns positions (n, 3), velocities, rotations."""
    for scenario in _run_scenarios():
        name, imu, state, g, start, stop, ref = scenario
        try:
            result = call(mechanise, imu, state, g, start, stop)
        except CheckFailed as exc:
            if "IndexError" in str(exc):
                raise CheckFailed(f"{exc} (on {name}, samples {start}..{stop - 1}). Hint: " + _OFF_BY_ONE
                                  + "; the loop makes n − 1 steps, for i in range(1, n)") from None
            raise
        n = stop - start
        result = _run_arrays(result, n, name)
        if all(np.allclose(x, y, rtol=0.0, atol=tol) for x, y, tol in zip(result, ref, RUN_ATOL)):
            continue
        _diagnose_run(result, scenario)
        for x, what in zip(result, ("positions", "velocities", "rotations")):
            if not np.all(np.isfinite(x)):
                raise CheckFailed(f"{what} on {name} contain NaN or inf. Hint: the arrays start as NaN, so a "
                                  "row used before it is filled turns into NaN: within a step, a function that "
                                  "needs the new attitude or velocity must come after the step that computes "
                                  "it; every row 1 .. n−1 is filled by one step from the row before it "
                                  "(lecture 07 §4: attitude, then velocity, then position)")
        for x, y, what, tol in zip(result, ref, ("positions", "velocities", "rotations"), RUN_ATOL):
            if not np.allclose(x, y, rtol=0.0, atol=tol):
                k = int(np.argmax(np.abs(x - y).reshape(n, -1).max(axis=1) > tol))
                raise CheckFailed(
                    f"{what} on {name} differ from the reference from row {k} on (max abs error "
                    f"{np.max(np.abs(x - y)):.3g}). Hint: each row i ≥ 1 is one midpoint step from row i − 1, "
                    "with the readings at both ends of the step and its own length (lecture 07 §4)"
                    + _F(": the readings at k − 1 and k = start + i, and dt = imu.t[k] − imu.t[k−1]"))


def _run_arrays(result, n, name):
    """The three returned arrays, of shapes (n, 3), (n, 3), (n, 3, 3) (NaN allowed here)."""
    if not isinstance(result, (tuple, list)) or len(result) != 3:
        raise CheckFailed("mechanise must return a tuple (positions (n, 3), velocities (n, 3), "
                          "rotations (n, 3, 3))")
    arrays = []
    for value, what, shape in zip(result, ("positions", "velocities", "rotations"),
                                  ((n, 3), (n, 3), (n, 3, 3))):
        _expect_double(value, f"{what} on {name}")
        arr = as_array(value, f"{what} on {name}")
        if arr.shape != shape:
            raise CheckFailed(f"{what} on {name} have shape {arr.shape}, expected {shape}. Hint: return "
                              "(positions, velocities, rotations), in this order, one row per sample "
                              f"start .. stop−1 (n = {n})")
        arrays.append(arr)
    return tuple(arrays)


# ----------------------------------------------------------------------------------------
# Challenge: levelling (the attitude a resting accelerometer gives)
# ----------------------------------------------------------------------------------------

#: The navigation frame's up (z up, as KITTI).
UP = np.array([0.0, 0.0, 1.0])

#: R f/|f| against UP, absolute on entries: an atan2 construction, Euler angles, a quaternion or
#: scipy agree with UP to ~1e-15; arccos of the cosine loses up to ~1e-16/θ, 1e-10 on the
#: "nearly level" case (θ = 1e-6); every listed mistake is off by ≥ 0.05 rad on some case.
LEVEL_ATOL = 1e-9

_LEVEL_NAN = ("when the IMU is level, f is parallel to up and the axis f × up is zero: normalising it "
              "divides 0 by 0. A level IMU needs no rotation: return the identity there (lecture 07 §1)")
_LEVEL_UPSIDE_DOWN = ("when the IMU is exactly upside down, f points straight down: the axis f × up is zero, as "
                      "for a level IMU, but the tilt is 180°, not 0. Every horizontal axis turns down onto up "
                      "by half a turn: handle this case on its own (lecture 07 §1)"
                      + _F(": a half turn about x, R = diag(1, −1, −1)"))
_LEVEL_NORMALISE = ("arccos of a number outside [−1, 1] is NaN: the cosine of the tilt is the dot product "
                    "of UNIT vectors (|f| ≈ 9.81 m/s²; lecture 07 §1)" + _F(": f/|f| · up"))


def _tilt(u, target=UP):
    """The angle (rad) between unit vectors ``u`` and ``target``, accurate at 0 and π."""
    return float(np.arctan2(np.linalg.norm(np.cross(u, target)), u @ target))


def _fold(angle):
    """The angle between two directions that differ by a turn of ``angle`` in one plane."""
    return float(abs(wrap_angle(angle)))


#: The self-check's levelling cases: ((name, tilt, heading, |f|/g), ...), the level reading's
#: |f|/g, and the first samples of the two KITTI windows averaged.
_FIXED_LEVEL = ((("tilted 17°, heading 40°", np.radians(17.0), np.radians(40.0), 1.0),
                 ("tilted 70°, heading −120°", np.radians(70.0), np.radians(-120.0), 1.0),
                 ("mounted upside down, tilted 150°", np.radians(150.0), 0.5, 1.0),
                 ("nearly level (tilt 1e-6 rad)", 1e-6, 2.0, 1.0),
                 ("accelerating: |f| = 1.08 g, tilted 8°", np.radians(8.0), -0.7, 1.08)),
                1.0, (200, 2500))


def _drawn_level(rng):
    """The levelling family under a run seed: tilts in the same bands (upside down up to 1e-3 rad
    short of a half turn), any heading, |f| below or above g, other windows of ``cruise``."""
    def heading():
        return float(rng.uniform(-np.pi, np.pi))

    tilts = []
    for low, high in ((10.0, 30.0), (55.0, 85.0)):
        tilt, psi = np.radians(rng.uniform(low, high)), heading()
        heading_text = f"{np.degrees(psi):.0f}".replace("-", "−")    # the minus sign of the fixed names
        tilts.append((f"tilted {np.degrees(tilt):.1f}°, heading {heading_text}°", tilt, psi, 1.0))
    short = float(inputs.log_uniform(rng, 1e-3, 0.5))      # how far from upside down (rad)
    tilts.append((f"mounted upside down, tilted π − {short:.2g} rad", np.pi - short, heading(), 1.0))
    tiny = float(inputs.log_uniform(rng, 5e-7, 1e-5))
    tilts.append((f"nearly level (tilt {tiny:.2g} rad)", tiny, heading(), 1.0))
    scale = float(rng.choice([-1.0, 1.0]) * rng.uniform(0.04, 0.15) + 1.0)
    tilt = np.radians(rng.uniform(3.0, 15.0))
    tilts.append((f"accelerating: |f| = {scale:.3g} g, tilted {np.degrees(tilt):.1f}°", tilt, heading(), scale))
    size = len(load_kitti("cruise").imu)
    windows = tuple(int(k) for k in rng.choice(np.arange(0, size - 100), size=2, replace=False))
    return tuple(tilts), float(rng.uniform(0.9, 1.1)), windows


@functools.lru_cache(maxsize=None)
def _level_cases():
    """(name, f, unit f, tilt) of the levelling check: tilts from 0 to 180°, |f| ≠ g, KITTI means."""
    g = 9.8092
    tilts, level, windows = inputs.fixed_or_drawn(_FIXED_LEVEL, _drawn_level, "imu.level")
    raw = []
    for name, tilt, heading, scale in tilts:
        # a true attitude: heading about up, then a tilt about a horizontal axis
        axis = np.array([np.cos(heading + 1.0), np.sin(heading + 1.0), 0.0])
        R_true = so3.exp(tilt * axis) @ so3.exp(heading * UP)
        raw.append((name, scale * R_true.T @ (g * UP)))         # a resting IMU reads R_trueᵀ (−g)
    raw.append(("level (f straight up)", np.array([0.0, 0.0, level * g])))
    # f × up is zero here too: a guard for the level IMU alone returns the identity, or a reflection
    raw.append(("exactly upside down (f straight down)", np.array([0.0, 0.0, -level * g])))
    ex = load_kitti("cruise")
    for k in windows:  # KITTI's readings averaged over 1 s: real tilt, noise and motion
        raw.append((f"KITTI, mean of samples {k}..{k + 99}", ex.imu.specific_force[k:k + 100].mean(axis=0)))
    cases = []
    for name, f in raw:
        u = f / np.linalg.norm(f)
        cases.append(dict(name=name, f=f, u=u, tilt=_tilt(u)))
    return tuple(cases)


def _turned(R, c):
    """R applied to the measured direction f/|f| of a case: UP when R levels the IMU."""
    return R @ c["u"]


_LEVEL_MISTAKES = [
    (lambda R, c: np.allclose(R, np.eye(3), atol=LEVEL_ATOL),
     "R is the identity: that assumes the IMU is level. The accelerometer tells the tilt: find the "
     "rotation R_nb that turns the measured direction onto the navigation frame's up (lecture 07 §4: what "
     "a resting accelerometer reads)" + _F(": R f/|f| = (0, 0, 1)")),
    (lambda R, c: np.allclose(_turned(R, c), -UP, atol=LEVEL_ATOL),
     "your R turns f onto DOWN. At rest the accelerometer reads the specific force, the push that holds "
     "the IMU against gravity: it points up (lecture 07 §4)" + _F(": f = −Rᵀg, so R f/|f| = (0, 0, 1)")),
    (lambda R, c: np.allclose(R.T @ c["u"], UP, atol=LEVEL_ATOL),
     "your R is transposed: R = R_nb maps body coordinates to navigation ones; yours maps up back onto f "
     "(R_bn; lecture 07 §1)" + _F(": R applied to the body-frame f/|f| gives up, R f/|f| = (0, 0, 1)")),
    (lambda R, c: np.isclose(_tilt(_turned(R, c)), abs(c["tilt"] - np.arcsin(np.sin(c["tilt"]))), atol=1e-7),
     "quadrant: arcsin(|f × up| / |f|) cannot tell a tilt θ from 180° − θ (an IMU upside down; lecture 07 "
     "§1)" + _F(": take the angle with atan2(|u × up|, u · up) or arccos(u · up)")),
    (lambda R, c: np.isclose(_tilt(_turned(R, c)), abs(c["tilt"] - np.sin(c["tilt"])), atol=1e-7),
     "the cross product u × up has length sin θ, not θ: the rotation vector is the tilt θ times a UNIT "
     "axis (lecture 07 §1)" + _F(": θ (u × up)/|u × up|")),
    (lambda R, c: np.isclose(_tilt(_turned(R, c)), abs(c["tilt"] - c["tilt"] * np.sin(c["tilt"])), atol=1e-7),
     "the axis u × up has length sin θ: normalise it before multiplying by the tilt θ (lecture 07 §1)"),
    (lambda R, c: np.isclose(_tilt(_turned(R, c)), _fold(np.degrees(c["tilt"]) - c["tilt"]), atol=1e-7),
     "so3.Exp takes radians: do not convert the tilt to degrees (lecture 07 §1)"),
]


@check
def check_level_attitude(level_attitude):
    """``level_attitude(f)`` returns an attitude R_nb (3, 3) with R f/|f| = (0, 0, 1), any heading."""
    cases = _level_cases()
    turned = []
    rotations = []
    for c in cases:
        # f × up = 0 on these two: the singular cases have hints of their own
        singular = {0.0: _LEVEL_NAN, np.pi: _LEVEL_UPSIDE_DOWN}.get(c["tilt"])
        what = f"R on the case '{c['name']}'"
        try:
            got = _call_step(level_attitude, c["f"], hint=f"on the case '{c['name']}', {singular}" if singular else "")
        except CheckFailed as exc:
            # a NaN handed on (to so3.Exp, say) raises before we see it: the same hint as for a NaN result
            if not singular and "nan" in str(exc).lower():
                raise CheckFailed(f"{exc} (on the case '{c['name']}'). Hint: {_LEVEL_NORMALISE}") from None
            raise
        _expect_double(got, what)
        try:
            R = expect_shape(got, (3, 3), what)
        except CheckFailed as exc:
            if "NaN" in str(exc):
                raise CheckFailed(f"{exc}. Hint: {singular or _LEVEL_NORMALISE}") from None
            raise
        if not so3.is_rotation(R, tol=1e-9):
            err = np.max(np.abs(R.T @ R - np.eye(3)))
            det = np.linalg.det(R)
            kind = (f"a reflection, not a rotation (det R = {det:.3g})" if err < 1e-9 else
                    f"not a rotation matrix (|RᵀR − I| = {err:.2g})")
            raise CheckFailed(f"{what} is {kind}. "
                              "Hint: " + (_LEVEL_UPSIDE_DOWN if c["tilt"] == np.pi else
                                          "build it as so3.Exp of a rotation vector (lecture 07 §1)"
                                          + _F(": the tilt angle (rad) times a UNIT axis")))
        rotations.append(R)
        turned.append(_turned(R, c))
    failing = [k for k, v in enumerate(turned) if not np.allclose(v, UP, rtol=0.0, atol=LEVEL_ATOL)]
    if not failing:
        return
    upside_down = [k for k, c in enumerate(cases) if c["tilt"] == np.pi]
    if failing == upside_down:
        raise CheckFailed(f"R does not level the IMU on the case '{cases[failing[0]]['name']}' (R f/|f| is "
                          f"{np.degrees(_tilt(turned[failing[0]])):.3g}° away from up). Hint: {_LEVEL_UPSIDE_DOWN}")
    # a predicate is "evaluated" on a case into the test of the learner's R there; the upside-down
    # case is left out (a guard for f × up = 0 makes most mistakes right there)
    kept = [k for k in range(len(cases)) if k not in upside_down]
    why = known_mistake([rotations[k] for k in kept], [cases[k] for k in kept], _LEVEL_MISTAKES,
                        evaluate=lambda fits, c: lambda R: fits(R, c), close=_holds)
    if why:
        raise CheckFailed(f"R does not level the IMU. Hint: {why}")
    beyond_90 = [k for k, c in enumerate(cases) if 0.5 * np.pi < c["tilt"] < np.pi]
    if [k for k in failing if k not in upside_down] == beyond_90:
        raise CheckFailed("R levels the IMU up to 90° of tilt but not beyond (case "
                          f"'{cases[beyond_90[0]]['name']}'). Hint: quadrant: arcsin or arctan(y/x) cannot tell a "
                          "tilt θ from 180° − θ (lecture 07 §1)"
                          + _F("; use np.arctan2 with both arguments, or arccos of the cosine"))
    k = failing[0]
    off = np.degrees(_tilt(turned[k]))
    raise CheckFailed(f"on the case '{cases[k]['name']}' R f/|f| is {off:.3g}° away from up (0, 0, 1). Hint: "
                      "R = R_nb must turn the direction the accelerometer measures (body frame) onto the "
                      "navigation frame's up (lecture 07 §1, §4)"
                      + _F("; one such R turns about the axis u × up by the angle between u = f/|f| and up"))
