"""Checks for chapter 04: the CTRV step, its Jacobian and (the challenge) its process noise,
graded on KITTI states.

The states are the car's true CTRV states [p_x, p_y, v, ψ, ω] on the KITTI excerpts
(ω from the gyro), then the same car driving straight (ω = 0 exactly), then a sweep of
turn rates towards ω = 0 — just above and below the lecture's switch to the series
(``symbolic.OMEGA_SERIES_THRESHOLD`` on |ω T|), 1e-3 … 1e-12 — at headings in all four
quadrants and near ±π. The sweep is where lecture 04's failure lives: the closed form
subtracts two nearly equal sines and divides by a tiny ω, so code that branches on
``omega != 0`` is fine at ω = 0 and at real turn rates and wrong in between.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) the cases are drawn anew from
the same families: other KITTI states (the hardest-turning one of each excerpt stays, at other
steps), the two steps T (0.05–0.3 s and 0.7–1.5 s, log-uniform), the sweep's headings (in the
same quadrants, π − 10^-U(2, 6) and −10^-U(1, 3) next to ±π and 0) and its turn rates (the
switch at |ω T| = THRESHOLD · (1 ± 10^-U(4, 7)), each rate of the sweep within a factor 10^±0.25
of its fixed value, the one just above |ω| = 1e-6 kept just above it); the process noise's
three (T, σ_a, σ_ψ̈) settings (T below 1, around 1 and above 2, each σ on the fixed one's side
of 1) and its four headings (one per quadrant, at least 0.2 rad from the diagonals, where
cos ψ and sin ψ would agree in size).
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course import symbolic
from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.core.angles import wrap_angle
from kalman_course.checks.harness import CheckFailed, as_array, call, check, expect_close, expect_shape
from kalman_course.chapters.motion import kitti_model_states

EXCERPTS = ("turns", "stop_go")
STEPS = (0.1, 1.0)
THRESHOLD = symbolic.OMEGA_SERIES_THRESHOLD

# Turn rates of the sweep, as fractions of the switch (|ω T| = THRESHOLD, just above and just
# below it) and as absolute rates in rad/s, largest |ω T| first: a mistake in the series
# branch shows just below the switch, where cancellation cannot be the cause; cancellation
# shows at the tiny rates, where the series terms beyond the straight line vanish.
SWITCH_FRACTIONS = (1.0 + 1e-6, -(1.0 - 1e-6))
SWEEP_RATES = (1e-3, -1e-4, 1e-5, -1.01e-6, 1e-7, -1e-9, 1e-12, -1e-12)
# headings of the sweep: all four quadrants, and near ±π where ψ wraps
SWEEP_HEADINGS = ((0.3, -2.9), (2.0, -1.2), (3.1, -0.05))

# ctrv_step tolerance, on the step's increment f(x) − x: 1e-6 of the distance travelled
# v T (plus 1e-12 m of round-off). The closed form above the switch and the lecture's series
# below it are exact to ~1e-13 of v T; the straight line (the exercise's ω → 0 limit) errs by
# v T |ω T| / 2, so it is accepted for |ω T| ≲ 2e-6 (its first-order form, where the closed
# form would already lose digits) and rejected further out; the closed form at |ω T| = 1e-12
# loses ~1e-4 of v T to cancellation, which must fail.
STEP_RTOL = 1e-6
# ctrv_jacobian tolerance: 2e-5 of each column's largest entry (every column holds a 1 on the
# diagonal, so this is at least 2e-5 absolute). A forward difference of the step errs by up to
# 5e-7 (h = 1e-6) … 8e-6 (h = 1e-8, round-off on positions of ~400 m) of that scale and must
# pass, a central difference by ~1e-8; the closed form just above |ω| = 1e-6 errs by ~4e-2 of
# it, and at ω = 1e-9 by 4.5e2 absolute, which must fail.
JACOBIAN_RTOL = 2e-5


def _kitti_states(count: int, rng) -> np.ndarray:
    """Moving KITTI CTRV states: the hardest-turning one and ``count - 1`` random ones per excerpt."""
    picked = []
    for name in EXCERPTS:
        _, states = kitti_model_states(name, "ctrv")
        moving = states[states[:, 2] > 2.0]
        hardest = moving[np.argmax(np.abs(moving[:, 4]))]
        others = moving[rng.choice(len(moving), size=count - 1, replace=False)]
        picked.append(np.vstack([hardest, others]))
    return np.vstack(picked)


@functools.lru_cache(maxsize=None)
def kitti_ctrv_cases(count: int = 3, seed: int = 4):
    """(state, T, f(x), F) of the checks, in the order they are tried.

    Parameters
    ----------
    count : int
        KITTI states per excerpt turning at their gyro rate.
    seed : int
        Seed of the random choice of states.

    Returns
    -------
    tuple of (ndarray (5,), float, ndarray (5,), ndarray (5, 5))
        State, step T (s), the reference step and Jacobian.

    Notes
    -----
    KITTI states turning at their gyro rate (``count`` per excerpt, two steps each), the
    first two of them driving straight (ω = 0), then the ω sweep on two further KITTI states
    at the headings of ``SWEEP_HEADINGS``. The references are computed once.
    """
    rng = inputs.rng("motion.ctrv", seed)
    steps = inputs.fixed_or_drawn(STEPS, _drawn_steps, "motion.steps")
    fractions, sweep_rates, headings = inputs.fixed_or_drawn((SWITCH_FRACTIONS, SWEEP_RATES, SWEEP_HEADINGS),
                                                             _drawn_sweep, "motion.sweep")
    turning = _kitti_states(count, rng)
    states = [(x, T) for x in turning for T in steps]
    for x in turning[:2]:
        straight = x.copy()
        straight[4] = 0.0
        states += [(straight, T) for T in steps]
    base = _kitti_states(1, rng)
    for T in steps:
        rates = [THRESHOLD / T * f for f in fractions] + list(sweep_rates)
        for k, om in enumerate(rates):
            x = base[k % 2].copy()
            x[3] = headings[k % 3][(k // 3) % 2]
            x[4] = om
            states.append((x, T))
    return tuple((x, T, symbolic.ctrv_step(x, T), symbolic.ctrv_jacobian(x, T)) for x, T in states)


def _drawn_steps(rng) -> tuple:
    """(short, long) steps of a graded run: 0.05–0.3 s and 0.7–1.5 s. The long one stays below
    2 s, where the straight line at |ω| ≤ 1e-6 (a correct first-order limit) would err by more
    than the tolerance; the short one keeps |ω T| small enough at |ω| = 1e-6 for the closed
    form's Jacobian to lose its digits there."""
    return (float(inputs.log_uniform(rng, 0.05, 0.3)), float(inputs.log_uniform(rng, 0.7, 1.5)))


def _drawn_sweep(rng) -> tuple:
    """(switch fractions, sweep rates, sweep headings) like the fixed ones, drawn.

    The fractions stay just either side of the switch; each rate keeps its sign and decade
    (a factor 10^±0.25), so that every regime of the fixed sweep is met: the one just above
    1e-6 rad/s, where code switching to the limit at |ω| = 1e-6 still takes the closed form, is
    1e-6 · (1 + U(0.005, 0.05)). The headings are in the fixed ones' quadrants, two of them
    next to ±π and one next to 0.
    """
    fractions = (1.0 + 10.0 ** -rng.uniform(4.0, 7.0), -(1.0 - 10.0 ** -rng.uniform(4.0, 7.0)))
    rates = []
    for rate in SWEEP_RATES:
        if abs(rate) == 1.01e-6:
            rates.append(float(np.sign(rate) * 1e-6 * (1.0 + rng.uniform(0.005, 0.05))))
        else:
            rates.append(float(rate * 10.0 ** rng.uniform(-0.25, 0.25)))
    headings = ((rng.uniform(0.1, 1.4), -np.pi + 10.0 ** -rng.uniform(1.0, 3.0)),
                (rng.uniform(1.7, 3.0), -rng.uniform(0.2, 1.4)),
                (np.pi - 10.0 ** -rng.uniform(2.0, 6.0), -(10.0 ** -rng.uniform(1.0, 3.0))))
    return fractions, tuple(rates), headings


def _where(x, T) -> str:
    om = x[4]
    if om == 0.0:
        return f"driving straight (ω = 0), T = {T} s"
    return f"turning at ω = {om:.3g} rad/s (|ω T| = {abs(om * T):.3g} rad), T = {T} s"


def _straight_line(x, T):
    px, py, v, psi, om = x
    return np.array([px + v * T * np.cos(psi), py + v * T * np.sin(psi), v, psi + om * T, om])


def _near_zero_hint(x, T, what: str) -> str:
    """The hint for a wrong result at 0 < |ω T| < THRESHOLD that matches no known formula.

    Parameters
    ----------
    x : ndarray, shape (5,)
        The state of the case; T : float, its step (s).
    what : str
        "step" or "Jacobian".

    Returns
    -------
    str
        For |ω T| ≥ 1e-4, where cancellation costs nothing measurable, a hint on the series
        branch; below, a hint naming the cancellation of the closed form.
    """
    wt = abs(x[4] * T)
    if wt >= 1e-4:
        # cancellation costs at most ~1e-12 here: the series branch itself is wrong
        return (f"just below the switch to the series (|ω T| < {THRESHOLD}) your {what} disagrees "
                "with the closed form: check the series branch — the integrand's Taylor series "
                "v T Σ_k (ω T)^k / (k+1)! · (cos, sin)(ψ + k π/2), with enough terms (the lecture "
                "keeps 8; the straight line is only the k = 0 term)")
    return (f"at |ω T| = {wt:.1g} the closed form loses its digits to cancellation: sin(ψ + ω T) − "
            "sin ψ subtracts two nearly equal numbers and the tiny ω divides the round-off up (by "
            "1/ω in the step, 1/ω² in its Jacobian). Switching to the limit only at ω = 0 (omega "
            "!= 0) or at a tiny |ω| such as 1e-6 is not enough: below the lecture's switch |ω T| < "
            f"symbolic.OMEGA_SERIES_THRESHOLD = {THRESHOLD} use the ω → 0 limit (the series)")


def _finite_or_limit(value, shape, x, T, what: str) -> np.ndarray:
    """``expect_shape``, but a NaN or inf near ω = 0 is named: the missing ω → 0 limit.

    Parameters
    ----------
    value : object
        The learner's result.
    shape : tuple of int
        The expected shape.
    x : ndarray, shape (5,)
        The state of the case; T : float, its step (s).
    what : str
        The quantity's name for the message.

    Returns
    -------
    ndarray
        ``value`` as a finite float array of ``shape``.
    """
    arr = as_array(value, what)
    if arr.shape == tuple(shape) and not np.all(np.isfinite(arr)) and abs(x[4] * T) < THRESHOLD:
        raise CheckFailed(f"{what} contains NaN or inf {_where(x, T)}. Hint: the closed form divides "
                          "by ω; the ω → 0 limit is missing. For |ω T| below the lecture's switch "
                          f"(symbolic.OMEGA_SERIES_THRESHOLD = {THRESHOLD}) use the limit: the Taylor "
                          "series in ω, whose first term is the straight line p += v T (cos ψ, sin ψ)")
    return expect_shape(arr, shape, what)


def _call_near_zero(fn, x, T):
    """Call the learner's ``fn(x, T)``; a division by ω = 0 is named as the missing limit.

    Parameters
    ----------
    fn : callable
        The learner's ``ctrv_step`` or ``ctrv_jacobian``.
    x : ndarray, shape (5,)
        The CTRV state; T : float, the step (s).

    Returns
    -------
    object
        What ``fn`` returned.

    Raises
    ------
    CheckFailed
        If ``fn`` raises; at ω = 0 a ``ZeroDivisionError`` is named as the missing ω → 0 limit.
    """
    try:
        return call(fn, x, T)
    except CheckFailed as exc:
        if x[4] == 0.0 and "ZeroDivision" in str(exc):
            raise CheckFailed(f"{exc} {_where(x, T)}. Hint: the closed form divides by ω; the ω → 0 "
                              "limit is missing (below |ω T| < symbolic.OMEGA_SERIES_THRESHOLD use "
                              "the series, whose first term is the straight line)") from None
        raise


def _step_mistakes(x, T, expected):
    """(wrong increment, hint) of known wrong steps; a generator, so built only on failure."""
    px, py, v, psi, om = x
    x = np.asarray(x, dtype=float)
    wt = om * T

    def variant(**parts):
        wrong = expected.copy()
        for i, value in parts.items():
            wrong[int(i[1:])] = value
        return wrong - x

    if om != 0.0:
        straight = _straight_line(x, T) - x
        if abs(wt) < THRESHOLD:
            yield straight, (f"at |ω T| = {abs(wt):.3g} your step is the straight line, which errs by "
                             f"v T |ω T| / 2 = {abs(v * T * wt) / 2:.2g} m here: the straight line is only "
                             "the first term of the ω → 0 series; below the switch keep the series' "
                             "terms in ω T (or use the straight line only where |ω T| ≲ 1e-6)")
        else:
            yield straight, ("your step drives straight along the initial heading (the placeholder "
                             "does): with ω ≠ 0 the car turns during the step, so integrate its "
                             "velocity v (cos, sin)(ψ + ω t) over the step, the closed form of "
                             "lecture 04 §2; the straight line is only the ω → 0 limit")
        yield variant(i1=py + v / om * (np.cos(psi + wt) - np.cos(psi))), (
            "p_y: the integral of v sin(ψ + ω t) is v/ω (cos ψ − cos(ψ + ω T)); check the order "
            "of the cosines")
        yield variant(i0=px + v / om * (np.sin(psi) - np.sin(psi + wt))), (
            "p_x: the integral of v cos(ψ + ω t) is v/ω (sin(ψ + ω T) − sin ψ); check the order "
            "of the sines")
        yield variant(i0=px + v / om * (np.cos(psi) - np.cos(psi + wt)),
                      i1=py + v / om * (np.sin(psi + wt) - np.sin(psi))), (
            "p_x and p_y are swapped: p_x integrates v cos(ψ + ω t), p_y integrates v sin(ψ + ω t)")
        no_t = "T is missing inside the sine/cosine: the heading after the step is ψ + ω T"
        px_no_t = px + v / om * (np.sin(psi + om) - np.sin(psi))
        py_no_t = py + v / om * (np.cos(psi) - np.cos(psi + om))
        yield variant(i0=px_no_t), no_t
        yield variant(i1=py_no_t), no_t
        yield variant(i0=px_no_t, i1=py_no_t), no_t
    yield variant(i3=psi + om), "the heading turns by ω T over the step: ψ += ω T (T is missing)"
    yield variant(i3=psi), "the heading must turn over the step: ψ += ω T"
    yield variant(i0=px + v * T * np.cos(psi + wt), i1=py + v * T * np.sin(psi + wt)), (
        "you moved along the heading at the end of the step; the car turns during the step: "
        "integrate v (cos, sin)(ψ + ω t) over t in [0, T] (a series whose terms are divided by k! "
        "instead of (k+1)! sums to exactly this: ∫₀ᵀ (ω t)^k / k! dt = T (ω T)^k / (k+1)!)")
    per_second = expected[:2] + (expected[:2] - x[:2]) * (1.0 / T - 1.0)
    yield variant(i0=per_second[0], i1=per_second[1]), (
        "the distance travelled over the step is v T, not v (a factor T is missing in front)")
    yield variant(i0=px + v * T, i1=py), ("the car moves along its heading: p_x += v T cos ψ and "
                                          "p_y += v T sin ψ (the heading is missing)")
    yield variant(i0=px + v * T * np.sin(psi), i1=py + v * T * np.cos(psi)), (
        "cos and sin swapped: p_x moves by v T cos ψ and p_y by v T sin ψ (ψ from the x axis)")
    yield expected[[0, 1, 3, 2, 4]] - x, ("the state order is [p_x, p_y, v, ψ, ω]: v and ψ are "
                                          "swapped in the returned state")


@check
def check_ctrv_step(ctrv_step):
    """The learner's ``ctrv_step(x, T)`` (noise-free) against the derived model.

    Turning KITTI states, the same driving straight, and the sweep of turn rates down to
    ±1e-12 rad/s (see :data:`STEP_RTOL` for the tolerance and its reason).
    """
    for x, T, expected, _ in kitti_ctrv_cases():
        what = f"ctrv_step(x, T={T})"
        got = _finite_or_limit(_call_near_zero(ctrv_step, x, T), (5,), x, T, what)
        # a heading wrapped into (−π, π] is the same heading: compare ψ modulo 2π (only when it
        # is a whole number of turns off, so that other wrong values still match their mistakes)
        unwrapped = expected[3] + wrap_angle(got[3] - expected[3])
        if abs(unwrapped - expected[3]) < 1e-9 and unwrapped != got[3]:
            got = got.copy()
            got[3] = unwrapped
        # compare increments: the tolerance is a fraction of the distance travelled, not of the
        # KITTI coordinates (hundreds of metres), which would hide the ω → 0 errors
        atol = STEP_RTOL * abs(x[2]) * T + 1e-12
        hint = (_near_zero_hint(x, T, "step") if 0.0 < abs(x[4] * T) < THRESHOLD else
                "p_x += v/ω (sin(ψ + ω T) − sin ψ), p_y += v/ω (cos ψ − cos(ψ + ω T)), ψ += ω T; "
                f"below |ω T| < {THRESHOLD} the ω → 0 limit (the series)")
        expect_close(got - x, expected - x, f"the increment of ctrv_step at a KITTI state {_where(x, T)}",
                     rtol=0.0, atol=atol, mistakes=_step_mistakes(x, T, expected), hint=hint)


def _jacobian_mistakes(x, T, expected):
    """(wrong Jacobian, hint) of known wrong Jacobians; a generator, built only on failure."""
    v, psi, om = x[2], x[3], x[4]
    no_omega = expected.copy()
    no_omega[:2, 4] = 0.0
    bend = ("the turn rate still bends the path over the step: ∂p_x/∂ω → −v T² sin ψ / 2 and "
            "∂p_y/∂ω → v T² cos ψ / 2 as ω → 0 (the limit of the turning Jacobian), not 0 — "
            "differentiate first, then let ω → 0 (substituting ω = 0 before differentiating "
            "loses the ω column)")
    if abs(om * T) < THRESHOLD:
        # the hand-typed straight-line Jacobian (first order in ω) used up to the switch
        first_order = np.eye(5)
        first_order[0, 2], first_order[1, 2] = T * np.cos(psi), T * np.sin(psi)
        first_order[0, 3], first_order[1, 3] = -v * T * np.sin(psi), v * T * np.cos(psi)
        first_order[3, 4] = T
        first_order[0, 4], first_order[1, 4] = -0.5 * v * T**2 * np.sin(psi), 0.5 * v * T**2 * np.cos(psi)
        # the ω column lost (ω = 0 substituted before differentiating), here or at ω = 0
        for base in (expected, first_order):
            lost = base.copy()
            lost[:2, 4] = 0.0
            yield lost, bend
            lost[3, 4] = 0.0
            yield lost, bend + "; and ∂ψ/∂ω = T"
            lost[4, 4] = 0.0
            yield lost, bend + "; the whole ω column is gone (∂ψ/∂ω = T, ∂ω/∂ω = 1)"
        if om != 0.0:
            yield first_order, (f"at |ω T| = {abs(om * T):.3g} you used the Jacobian of the straight "
                                "line (first order in ω), which errs by ~v T³ |ω| / 3 in ∂p/∂ω: below "
                                "the switch differentiate the ω-series, not only its straight-line term")
    for wrong_t in (0.0, 1.0):
        missing_t = expected.copy()
        missing_t[3, 4] = wrong_t
        yield missing_t, "∂ψ/∂ω = T: the heading after the step is ψ + ω T"
    if abs(om * T) >= THRESHOLD:
        # the Jacobian of a closed form with p_y's cosines in the wrong order (row 1 flips sign
        # in its ∂/∂v, ∂/∂ψ and ∂/∂ω entries)
        flipped = expected.copy()
        flipped[1, 2:5] = -flipped[1, 2:5]
        yield flipped, ("p_y's derivatives have the wrong sign: p_y integrates v sin(ψ + ω t), which "
                        "gives v/ω (cos ψ − cos(ψ + ω T)); check the sign of p_y's velocity (or the "
                        "order of the cosines) in the model you differentiate")
    yield symbolic.ctrv_jacobian(np.asarray(x, dtype=float)[[0, 1, 3, 2, 4]], T), (
        "the Jacobian is evaluated with v and ψ exchanged: the arguments of the lambdified "
        "function are in another order than the call (p_x, p_y, v, ψ, ω, T)")
    yield expected.T, "the Jacobian is transposed: F[i, j] = ∂f_i/∂x_j (row = output, column = state)"
    yield expected - np.eye(5), ("the identity is missing: f(x) = x + Δ(x), so F = I + ∂Δ/∂x "
                                 "(∂p_x/∂p_x = 1, ∂v/∂v = 1, ...)")
    yield symbolic.ctrv_jacobian(symbolic.ctrv_step(x, T), T), (
        "wrong point of linearisation: F is evaluated at the state x the step starts from, not at "
        "the predicted state f(x)")


@check(uses=("ctrv_step",))
def check_ctrv_jacobian(ctrv_jacobian):
    """The learner's ``ctrv_jacobian(x, T)`` against SymPy's, turning, at ω = 0 and towards it.

    Finite differences of a correct step pass (see :data:`JACOBIAN_RTOL`). A Jacobian that
    calls the learner's ``ctrv_step`` (finite differences) is blamed on ``ctrv_step`` first
    when that one fails its own check.
    """
    for x, T, _, expected in kitti_ctrv_cases():
        what = f"ctrv_jacobian(x, T={T})"
        got = _call_near_zero(ctrv_jacobian, x, T)
        if np.shape(got) == (5, 4):
            raise CheckFailed("ctrv_jacobian has shape (5, 4): differentiate with respect to all five "
                              "state components, ω included")
        got = _finite_or_limit(got, (5, 5), x, T, what)
        atol = JACOBIAN_RTOL * np.abs(expected).max(axis=0)   # per column, broadcast over rows
        hint = (_near_zero_hint(x, T, "Jacobian") if 0.0 < abs(x[4] * T) < THRESHOLD else
                "compare your Jacobian with finite differences of your ctrv_step")
        expect_close(got, expected, f"ctrv_jacobian at a KITTI state {_where(x, T)}", rtol=0.0,
                     atol=atol, mistakes=_jacobian_mistakes(x, T, expected), hint=hint)


# ---------------------------------------------------------------------------------------
# challenge: the CTRV process noise
# ---------------------------------------------------------------------------------------

#: (T, σ_a, σ_ψ̈) of the process-noise check: T on both sides of 1 (T, T²/2 and T² differ,
#: T = 2 where T²/2 = T is avoided), each σ ≠ 1 and on both sides of it, σ_a ≠ σ_ψ̈.
NOISE_SETTINGS = ((0.1, 3.0, 0.3), (1.0, 0.6, 1.7), (2.5, 1.5, 0.4))
#: Headings of the process-noise check, one per quadrant: cos ψ and sin ψ differ in size and
#: in sign, so a frame mistake or swapped cos/sin shows.
NOISE_HEADINGS = (0.4, 2.2, -2.7, -1.1)
STATE_NAMES = ("p_x", "p_y", "v", "ψ", "ω")


@functools.lru_cache(maxsize=None)
def _noise_cases():
    """(state, T, σ_a, σ_ψ̈, Q) of the process-noise check: the first two turning KITTI states
    of :func:`kitti_ctrv_cases` (the hardest-turning one of the 'turns' excerpt and another;
    speed and gyro turn rate real) at the headings of :data:`NOISE_HEADINGS`, for every
    setting of :data:`NOISE_SETTINGS`."""
    turning = [x for x, T, _, _ in kitti_ctrv_cases()[::len(STEPS)]][:2]
    settings = inputs.fixed_or_drawn(NOISE_SETTINGS, _drawn_noise_settings, "motion.noise.settings")
    headings = inputs.fixed_or_drawn(NOISE_HEADINGS, _drawn_noise_headings, "motion.noise.headings")
    cases = []
    for T, sigma_a, sigma_yaw in settings:
        for k, psi in enumerate(headings):
            x = turning[k % 2].copy()
            x[3] = psi
            x.flags.writeable = False
            cases.append((x, T, sigma_a, sigma_yaw,
                          symbolic.motion_process_noise("ctrv", x, T, (sigma_a, sigma_yaw))))
    return tuple(cases)


def _drawn_noise_settings(rng) -> tuple:
    """Three (T, σ_a, σ_ψ̈) like :data:`NOISE_SETTINGS`: T below 1, around it and above 2 (never
    2, where T²/2 = T), each σ on its fixed counterpart's side of 1 and σ_a ≠ σ_ψ̈."""
    def lu(low, high):
        return float(inputs.log_uniform(rng, low, high))

    return ((lu(0.05, 0.3), lu(2.0, 5.0), lu(0.15, 0.5)), (lu(0.5, 1.5), lu(0.3, 0.8), lu(1.3, 3.0)),
            (lu(2.3, 3.5), lu(1.2, 2.5), lu(0.2, 0.7)))


def _drawn_noise_headings(rng) -> tuple:
    """One heading per quadrant, in the fixed order (first, second, third, fourth), at least
    0.15 rad from the axes and 0.2 rad from the diagonals (where |cos ψ| = |sin ψ| and a
    swapped cos/sin would agree)."""
    headings = []
    for start in (0.0, np.pi / 2, -np.pi, -np.pi / 2):
        offset = rng.uniform(0.15, np.pi / 2 - 0.15)
        while abs(offset - np.pi / 4) < 0.2:
            offset = rng.uniform(0.15, np.pi / 2 - 0.15)
        headings.append(float(start + offset))
    return tuple(headings)


def _noise_jacobian(T, heading, half=0.5, rate=None):
    """A CTRV noise Jacobian (5, 2) of the lecture's shape, with the push of ν_a along
    ``heading`` = (c, s), position factor ``half`` · T² and rate factor ``rate`` (default T)."""
    rate = T if rate is None else rate
    c, s = heading
    return np.array([[half * T**2 * c, 0.0], [half * T**2 * s, 0.0], [rate, 0.0],
                     [0.0, half * T**2], [0.0, rate]])


def _noise_mistakes(x, T, sigma_a, sigma_yaw):
    """(wrong Q, hint) of the known wrong process noises; a generator, built only on failure."""
    psi, om = x[3], x[4]
    var = np.array([sigma_a**2, sigma_yaw**2])

    def through(B, variances=var):
        return (B * variances) @ B.T

    B = _noise_jacobian(T, (np.cos(psi), np.sin(psi)))
    yield np.diag([0.0, 0.0, (sigma_a * T)**2, 0.0, (sigma_yaw * T)**2]), (
        "your Q puts the noise on the speed and the turn rate only (the placeholder does): an "
        "acceleration held over the step also moves the position (by T²/2 along the heading) and "
        "the heading (by T²/2), and since one noise moves both, Q has cross terms. Build "
        "B = ∂f/∂w (5, 2) and map the noise's covariance through it, Q = B diag(σ_a², σ_ψ̈²) Bᵀ "
        "(lecture 04 §2)")
    yield np.diag(np.diag(through(B))), (
        "the cross terms are missing: the same acceleration moves the position and the speed (and "
        "the heading and the turn rate), so they are correlated: Q = B diag(σ_a², σ_ψ̈²) Bᵀ, not "
        "its diagonal")
    yield through(_noise_jacobian(T, (1.0, 0.0))), (
        "ν_a is the longitudinal acceleration: it pushes the car along its heading ψ, so it moves "
        "p_x and p_y by T²/2 (cos ψ, sin ψ), not along the x axis of the navigation frame")
    yield through(_noise_jacobian(T, (np.sin(psi), np.cos(psi)))), (
        "cos and sin are swapped: ψ is measured from the x axis, so ν_a moves p_x by T²/2 cos ψ "
        "and p_y by T²/2 sin ψ")
    for turned in (psi + om * T, psi + om * T / 2):
        yield through(_noise_jacobian(T, (np.cos(turned), np.sin(turned)))), (
            "by the lecture's convention ν_a pushes along the heading at the start of the step, ψ "
            "(the turn during the step is neglected), not the heading at its end or middle")
    yield through(_noise_jacobian(T, (np.cos(psi), np.sin(psi)), half=1.0 / T, rate=0.5 * T**2)), (
        "T and T²/2 are swapped: an acceleration held over T changes the speed (or the turn rate) "
        "by T times it and moves the position (or the heading) by T²/2 times it")
    no_half = ("the position and heading rows of B are T²/2 (∫₀ᵀ t dt: the held acceleration's "
               "push builds up over the step), not T²")
    for rows in ((0, 1), (3,), (0, 1, 3)):
        doubled = B.copy()
        doubled[rows, :] *= 2.0
        yield through(doubled), no_half
    yield through(B, np.array([sigma_a, sigma_yaw])), (
        "sigma_a and sigma_yaw are standard deviations: the noise's covariance is "
        "diag(σ_a², σ_ψ̈²)")
    yield through(B, var[::-1]), (
        "the variances are swapped: the first noise component is ν_a (sigma_a, m/s²), the second "
        "ν_ψ̈ (sigma_yaw, rad/s²)")


@check
def check_ctrv_process_noise(ctrv_process_noise):
    """The learner's ``ctrv_process_noise(x, T, sigma_a, sigma_yaw)`` against
    ``symbolic.motion_process_noise("ctrv", ...)``, on turning KITTI states at four headings.

    Tolerance: expect_close's rtol 1e-7 with atol 1e-12. A correct Q (B by hand or by SymPy,
    any bracketing) agrees to ~1e-15 relative; the smallest mistake in the list,
    the heading at mid-step at T = 0.1 s, moves the position entries by ~1e-2 relative.
    """
    for x, T, sigma_a, sigma_yaw, expected in _noise_cases():
        where = f"ψ = {x[3]} rad, T = {T} s, σ_a = {sigma_a}, σ_ψ̈ = {sigma_yaw}"
        try:
            result = call(ctrv_process_noise, x.copy(), T, sigma_a, sigma_yaw)
        except CheckFailed as exc:  # usually a shape mismatch in a product
            raise CheckFailed(f"{exc}. Hint: B = ∂f/∂w is (5, 2) (one column per noise), the "
                              "noise's covariance diag(σ_a², σ_ψ̈²) is (2, 2), and Q = B Σ_w Bᵀ "
                              "is (5, 5)") from None
        got = as_array(result, f"ctrv_process_noise ({where})")
        if got.shape == (2, 2):
            raise CheckFailed("Q has shape (2, 2), expected (5, 5): that is Bᵀ Σ B (or the noise's "
                              "own covariance); B is (5, 2) and Q = B diag(σ_a², σ_ψ̈²) Bᵀ is (5, 5)")
        got = expect_shape(got, (5, 5), f"Q ({where})")
        rows = [name for i, name in enumerate(STATE_NAMES)
                if not np.allclose(got[i], expected[i], rtol=1e-7, atol=1e-12)]
        expect_close(got, expected, f"Q at a KITTI state ({where})", rtol=1e-7, atol=1e-12,
                     mistakes=_noise_mistakes(x, T, sigma_a, sigma_yaw),
                     hint="Q = B diag(σ_a², σ_ψ̈²) Bᵀ with B = ∂f/∂w (5, 2) of lecture 04 §2; the "
                          f"rows that differ: {', '.join(rows) or 'none'}")
