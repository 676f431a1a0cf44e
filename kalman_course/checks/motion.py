"""Checks for chapter 04: the CTRV step, its Jacobian and (the challenge) its process noise,
graded on KITTI states.

The states are the car's true CTRV states [p_x, p_y, v, ψ, ω] on the KITTI excerpts
(ω from the gyro) over steps up to the exercise's own 2 s horizon, then the same car driving
straight (ω = 0 exactly), then a dense sweep of turn rates: log-spaced |ω| from 1e-13 rad/s
(below any cut-off a learner might special-case) to 1 rad/s, two per decade (just above a
round cut-off 1e-k and in mid-decade), both signs, at steps from 1e-5 s to 2 s, plus just
above and below the lecture's switch to the series (``symbolic.OMEGA_SERIES_THRESHOLD`` on
|ω T|), at headings in all four quadrants and near ±π. The sweep is where lecture 04's
failure lives: the closed form subtracts two nearly equal sines and divides by a tiny ω, so
code that branches on ``omega != 0`` or on a tiny |ω| is fine at ω = 0 and at real turn rates
and wrong in between. Sweeping ω at steps over five decades judges a switch on |ω| and on
|ω T| alike: a cut-off on |ω| alone (1e-6, say) leaves the closed form at |ω T| = 1e-11 for a
step of 1e-5 s. The 2 s steps are where a switch without ``abs()`` shows: every right turn
then takes the series, which is exact only for small |ω T|.

Under a graded run's seed (:mod:`kalman_course.checks.cases`) the cases are drawn anew from
the same families: other KITTI states (the hardest-turning one of each excerpt stays, at other
steps), the KITTI steps T (0.05–0.3 s, 0.7–1.5 s and 1.5–2 s, log-uniform), the sweep's steps
(5e-6–1.5e-5 s and those three ranges), its headings (in the same quadrants, π − 10^-U(2, 6)
and −10^-U(1, 3) next to ±π and 0) and its turn rates (the switch at |ω T| = THRESHOLD ·
(1 ± 10^-U(4, 7)); in each decade one rate 10^k · (1 + U(0.01, 0.1)) just above the round
cut-off and one 10^k · U(2, 6)); the process noise's three (T, σ_a, σ_ψ̈) settings (T below 1,
around 1 and above 2, each σ on the fixed one's side of 1) and its four headings (one per
quadrant, at least 0.2 rad from the diagonals, where cos ψ and sin ψ would agree in size).
"""

from __future__ import annotations

import functools

import numpy as np

from kalman_course import symbolic
from kalman_course.checks import cases as inputs  # `cases` names the lists of cases below
from kalman_course.checks import hints
from kalman_course.core.angles import wrap_angle
from kalman_course.checks.harness import CheckFailed, as_array, call, check, expect_close, expect_shape
from kalman_course.chapters.motion import kitti_model_states

EXCERPTS = ("turns", "stop_go")
#: Steps of the KITTI cases: a filter's, a second, and the exercise's own 2 s prediction horizon
#: (solutions/04: ``ctrv_step(s, 2.0)`` on the KITTI states).
STEPS = (0.1, 1.0, 2.0)
THRESHOLD = symbolic.OMEGA_SERIES_THRESHOLD

# The sweep of turn rates, run at each step of SWEEP_STEPS. The switch first (|ω T| = THRESHOLD,
# just above and just below it: a mistake in the series branch shows just below the switch,
# where cancellation cannot be the cause), then |ω| = m · 10^k for every decade k of
# SWEEP_DECADES and mantissa m of SWEEP_MANTISSAS, each with both signs. 1.05 · 10^k sits just
# above the round cut-off 10^k a learner may choose (|ω| > 1e-9: the closed form there loses
# 3e-16 / |ω T| of v T, which the tiny step makes large); 3 · 10^k is mid-decade. No rate sits
# on a round number, where > and ≥ would decide.
SWITCH_FRACTIONS = (1.0 + 1e-6, -(1.0 - 1e-6))
SWEEP_DECADES = tuple(range(-13, 1))
SWEEP_MANTISSAS = (1.05, 3.0)
#: Largest |ω| of the sweep (rad/s): about the KITTI excerpts' hardest turn (0.71 rad/s) and more.
SWEEP_MAX_RATE = 1.5
# Steps of the sweep (s): 1e-5 s (chapter 05's fusion predicts to each measurement's own time,
# and rows of an irregular log can be microseconds apart), a filter's 0.1 s, 1 s, and the
# exercise's 2 s horizon. The switch fractions are swept at the steps of at least 0.1 s only:
# at 1e-5 s the switch is |ω| = 2000 rad/s, no car's turn rate.
SWEEP_STEPS = (1e-5, 0.1, 1.0, 2.0)
# headings of the sweep: all four quadrants, and near ±π where ψ wraps
SWEEP_HEADINGS = ((0.3, -2.9), (2.0, -1.2), (3.1, -0.05))

# ctrv_step tolerance, on the step's increment f(x) − x: 1e-6 of the distance travelled
# v T (plus 1e-12 m of round-off on KITTI coordinates of ~400 m, whose ulp is 6e-14 m). The
# reference (symbolic.ctrv_step: the closed form above the switch, the lecture's 8-term series
# below it, whose first dropped term is below 0.02⁸/9! ≈ 7e-20 of v T) agrees with a 40-digit
# evaluation of the closed form to 1e-13 of v T over the whole sweep (tests/test_checks_ch04_06_sweeps.py),
# so every bit of the tolerance is the learner's. Why 1e-6: the straight line (the exercise's
# former ω → 0 limit) errs by v T |ω T| / 2, so it is accepted for |ω T| ≲ 2e-6 (where the
# closed form would already lose digits), and rejected further out; the closed form errs by
# ~3e-16 / |ω T| of v T, so it is accepted down to |ω T| ≈ 1e-9 and rejected below: at the
# sweep's 1.05e-6 rad/s and 1e-5 s (|ω T| = 1e-11) it loses ~1e-5, at 1.05e-9 rad/s and 0.1 s
# ~1e-6 … 1e-2 (cut-offs at |ω| = 1e-6, 1e-9, 1e-12 all fail). The lecture's series used for
# a right turn at the 2 s horizon (a switch without abs()) errs by (ω T)⁸/9! of v T, 7e-4 at
# |ω T| = 2.1.
STEP_RTOL = 1e-6
# ctrv_jacobian tolerance: 2e-5 of each column's largest entry (every column holds a 1 on the
# diagonal, so this is at least 2e-5 absolute). A forward difference of the step errs by up to
# 5e-7 (h = 1e-6) … 8e-6 (h = 1e-8, round-off on positions of ~400 m) of that scale and must
# pass, a central difference by ~1e-8; the closed form just above |ω| = 1e-6 errs by ~4e-2 of
# it, and at ω = 1e-9 by 4.5e2 absolute, which must fail. A forward difference with h = 1e-2
# errs by h/2 · ∂²f of up to ~1e-2 of the scale (the ψ column at 2 s), which must fail, and is
# named as a coarse step (FD_STEPS).
JACOBIAN_RTOL = 2e-5
#: Steps h of the coarse finite differences the Jacobian check recognises (forward and central).
FD_STEPS = (1e-1, 3e-2, 1e-2, 3e-3, 1e-3, 1e-4)


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


def _sweep_rates(mantissas) -> list[tuple[float, int]]:
    """The sweep's turn rates and their slot: ``mantissas[i][j] · 10^SWEEP_DECADES[i]`` (slot j),
    each with both signs, those above :data:`SWEEP_MAX_RATE` left out."""
    rates = []
    for k, decade in zip(SWEEP_DECADES, mantissas):
        for slot, m in enumerate(decade):
            magnitude = float(m * 10.0 ** k)
            if magnitude <= SWEEP_MAX_RATE:
                rates += [(magnitude, slot), (-magnitude, slot)]
    return rates


def _in_step_sweep(om: float, T: float) -> bool:
    """Whether the step's sweep tries the rate ``om`` at the step ``T``.

    Every rate at 0.1 s. At the tiny step only |ω T| ≤ 2e-8, where the closed form loses ≥ 1e-8
    of v T (the closed form is exact above, and the correct code takes the series at any rate
    there); at the long steps only |ω| ≥ 1e-3, where a series used in place of the closed form
    shows (the tiny rates' |ω| and |ω T| are both met at 0.1 s and at the tiny step). This keeps
    the learner's function to ~150 calls.
    """
    if T < 0.05:
        return abs(om * T) <= 2e-8
    return T < 0.5 or abs(om) >= 1e-3


def _in_jacobian_sweep(om: float, slot: int) -> bool:
    """Whether the Jacobian's check tries a sweep rate: the one just above each round cut-off
    (slot 0), of one sign per decade below 0.1 rad/s and of both above. The Jacobian's
    cancellation grows as 1/(ω T)², so one rate per decade shows a cut-off with a wide margin
    (at the rate just above 1e-6 rad/s and 0.1 s the closed form is off by 4e-2 of the scale)."""
    if slot != 0:
        return False
    return abs(om) >= 0.1 or (om > 0) == (int(np.floor(np.log10(abs(om)))) % 2 == 0)


@functools.lru_cache(maxsize=None)
def _ctrv_cases(count: int = 3, seed: int = 4):
    """(state, T, f(x), F, whether the Jacobian's check uses it) of :func:`kitti_ctrv_cases`."""
    rng = inputs.rng("motion.ctrv", seed)
    steps = inputs.fixed_or_drawn(STEPS, _drawn_steps, "motion.steps")
    fractions, mantissas, headings, sweep_steps = inputs.fixed_or_drawn(
        (SWITCH_FRACTIONS, tuple((SWEEP_MANTISSAS,) * len(SWEEP_DECADES)), SWEEP_HEADINGS, SWEEP_STEPS),
        _drawn_sweep, "motion.sweep")
    turning = _kitti_states(count, rng)
    states = [(x, T, True) for x in turning for T in steps]
    for x in turning[:2]:
        straight = x.copy()
        straight[4] = 0.0
        states += [(straight, T, True) for T in steps]
    base = _kitti_states(1, rng)
    flat_headings = [psi for pair in headings for psi in pair]
    for T in sweep_steps:
        switch = [(THRESHOLD / T * f, None) for f in fractions] if T >= 0.05 else []
        swept = [(om, slot) for om, slot in _sweep_rates(mantissas) if _in_step_sweep(om, T)]
        for k, (om, slot) in enumerate(switch + swept):
            x = base[k % 2].copy()
            x[3] = flat_headings[k % len(flat_headings)]
            x[4] = om
            states.append((x, T, slot is None or _in_jacobian_sweep(om, slot)))
    return tuple((x, T, symbolic.ctrv_step(x, T), symbolic.ctrv_jacobian(x, T), jacobian)
                 for x, T, jacobian in states)


def kitti_ctrv_cases(count: int = 3, seed: int = 4):
    """(state, T, f(x), F) of the step's check, in the order they are tried.

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
    KITTI states turning at their gyro rate (``count`` per excerpt, at every step of
    :data:`STEPS`), the first two of them driving straight (ω = 0), then the ω sweep on two
    further KITTI states at the headings of ``SWEEP_HEADINGS``, at the steps of
    :data:`SWEEP_STEPS` (which rates at which step: :func:`_in_step_sweep`). The references
    are computed once. The Jacobian's check uses a subset (:func:`jacobian_cases`).
    """
    return tuple(case[:4] for case in _ctrv_cases(count, seed))


def jacobian_cases():
    """(state, T, f(x), F) of the Jacobian's check: the KITTI and straight cases, the switch,
    and the sweep's rates of :func:`_in_jacobian_sweep`."""
    return tuple(case[:4] for case in _ctrv_cases() if case[4])


def _drawn_steps(rng) -> tuple:
    """The KITTI cases' steps of a graded run: 0.05–0.3 s, 0.7–1.5 s and 1.5–2 s (the exercise's
    horizon). At 2 s the straight line at |ω| ≤ 6e-7 (a correct first-order limit, the largest
    rate of the sweep below 1e-6) errs by at most 6e-7 of v T, inside the tolerance."""
    return (float(inputs.log_uniform(rng, 0.05, 0.3)), float(inputs.log_uniform(rng, 0.7, 1.5)),
            float(rng.uniform(1.5, 2.0)))


def _drawn_sweep(rng) -> tuple:
    """(switch fractions, mantissas per decade, sweep headings, sweep steps) like the fixed ones, drawn.

    The fractions stay just either side of the switch; in each decade one rate is just above
    the round cut-off (1 + U(0.01, 0.1)), where code switching to the limit at |ω| = 10^k still
    takes the closed form, and one is mid-decade (U(2, 6)). The headings are in the fixed
    ones' quadrants, two of them next to ±π and one next to 0; the steps are 5e-6–1.5e-5 s
    (the tiny step that exposes a cut-off on |ω| alone), 0.05–0.3 s, 0.7–1.5 s and 1.5–2 s.
    """
    fractions = (1.0 + 10.0 ** -rng.uniform(4.0, 7.0), -(1.0 - 10.0 ** -rng.uniform(4.0, 7.0)))
    mantissas = tuple((float(1.0 + rng.uniform(0.01, 0.1)), float(rng.uniform(2.0, 6.0))) for _ in SWEEP_DECADES)
    headings = ((rng.uniform(0.1, 1.4), -np.pi + 10.0 ** -rng.uniform(1.0, 3.0)),
                (rng.uniform(1.7, 3.0), -rng.uniform(0.2, 1.4)),
                (np.pi - 10.0 ** -rng.uniform(2.0, 6.0), -(10.0 ** -rng.uniform(1.0, 3.0))))
    steps = (float(inputs.log_uniform(rng, 5e-6, 1.5e-5)),) + _drawn_steps(rng)
    return fractions, mantissas, headings, steps


def _where(x, T) -> str:
    om = x[4]
    if om == 0.0:
        return f"driving straight (ω = 0), T = {T:.3g} s"
    return f"turning at ω = {om:.3g} rad/s (|ω T| = {abs(om * T):.3g} rad), T = {T:.3g} s"


def _straight_line(x, T):
    px, py, v, psi, om = x
    return np.array([px + v * T * np.cos(psi), py + v * T * np.sin(psi), v, psi + om * T, om])


#: The lecture's series (tier 2 of the hints that name it).
SERIES = ("the integrand's Taylor series v T Σ_k (ω T)^k / (k+1)! · (cos, sin)(ψ + k π/2), with enough "
          "terms (the lecture keeps 8; the straight line is only the k = 0 term)")
#: The closed form of the step (tier 2 of the hints that name it).
CLOSED_FORM = ("p_x += v/ω (sin(ψ + ω T) − sin ψ), p_y += v/ω (cos ψ − cos(ψ + ω T)), ψ += ω T; "
               f"below |ω T| < {THRESHOLD} the ω → 0 limit (the series)")


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
        branch; below, a hint naming the cancellation of the closed form (and, when |ω| itself
        is not tiny, that a cut-off on |ω| alone does not see the step).
    """
    wt = abs(x[4] * T)
    if wt >= 1e-4:
        # cancellation costs at most ~1e-12 here: the series branch itself is wrong
        return (f"just below the switch to the series (|ω T| < {THRESHOLD}) your {what} disagrees "
                "with the closed form: check the series branch, the ω → 0 limit of lecture 04 §3: "
                + hints.formula(SERIES))
    by_rate = (f" Here |ω| = {abs(x[4]):.3g} rad/s is not tiny, the step is: a cut-off on |ω| alone does "
               "not see that, one on |ω T| does." if abs(x[4]) >= 1e-7 else "")
    return (f"at |ω T| = {wt:.1g} the closed form loses its digits to cancellation (lecture 04 §3): "
            "sin(ψ + ω T) − sin ψ subtracts two nearly equal numbers and the tiny ω divides the round-off "
            f"up (by 1/ω in the step, 1/ω² in its Jacobian). Switching to the limit only at ω = 0 (omega "
            "!= 0) or at a tiny |ω| such as 1e-6 or 1e-9 is not enough: below the lecture's switch |ω T| < "
            f"symbolic.OMEGA_SERIES_THRESHOLD = {THRESHOLD} use the ω → 0 limit (the series).{by_rate}")


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
                          "by ω; the ω → 0 limit is missing (lecture 04 §3). For |ω T| below the lecture's "
                          f"switch (symbolic.OMEGA_SERIES_THRESHOLD = {THRESHOLD}) use the limit, the "
                          "Taylor series in ω, whose first term is the straight line"
                          + hints.formula(" p += v T (cos ψ, sin ψ)"))
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
                              "limit is missing (lecture 04 §3: below |ω T| < symbolic.OMEGA_SERIES_THRESHOLD "
                              "use the series, whose first term is the straight line)") from None
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
                             "the first term of the ω → 0 series (lecture 04 §3); below the switch keep the "
                             "series' terms in ω T (or use the straight line only where |ω T| ≲ 1e-6)")
        else:
            yield straight, ("your step drives straight along the initial heading (the placeholder "
                             "does): with ω ≠ 0 the car turns during the step, so integrate its "
                             "velocity over the step, the closed form of lecture 04 §2"
                             + hints.formula(" (v (cos, sin)(ψ + ω t) over t in [0, T])")
                             + "; the straight line is only the ω → 0 limit")
        if wt < -THRESHOLD:
            # the lecture's series where the closed form belongs: a switch `omega * T > threshold`
            # sends every right turn to the series, exact only for small |ω T|
            K = np.arange(symbolic.SERIES_ORDER)
            c = v * T * wt ** K / np.cumprod(K + 1)
            yield variant(i0=px + c @ np.cos(psi + K * np.pi / 2), i1=py + c @ np.sin(psi + K * np.pi / 2)), (
                f"in this right turn (ω < 0, |ω T| = {abs(wt):.3g}) your step took the series: the switch "
                "must compare the size |ω T| (abs()) with the threshold, or every right turn takes the series, "
                "which is exact only near ω T = 0 (lecture 04 §3)")
    if om != 0.0 and abs(wt) >= 1e-4:
        # the closed form's own mistakes, evaluated by the closed form: below |ω T| = 1e-4 its
        # cancellation would make them all look alike (at |ω T| = 1e-18 every one of them is 0)
        yield variant(i1=py + v / om * (np.cos(psi + wt) - np.cos(psi))), (
            "p_y: check the order of the cosines in the closed form (lecture 04 §2): "
            + hints.formula("the integral of v sin(ψ + ω t) is v/ω (cos ψ − cos(ψ + ω T))"))
        yield variant(i0=px + v / om * (np.sin(psi) - np.sin(psi + wt))), (
            "p_x: check the order of the sines in the closed form (lecture 04 §2): "
            + hints.formula("the integral of v cos(ψ + ω t) is v/ω (sin(ψ + ω T) − sin ψ)"))
        yield variant(i0=px + v / om * (np.cos(psi) - np.cos(psi + wt)),
                      i1=py + v / om * (np.sin(psi + wt) - np.sin(psi))), (
            "p_x and p_y are swapped: p_x integrates the velocity's x component, p_y its y component "
            "(lecture 04 §2)" + hints.formula(": v cos(ψ + ω t) and v sin(ψ + ω t)"))
        no_t = ("T is missing inside the sine/cosine: the heading after the step is the heading turned by "
                "the turn rate over the whole step (lecture 04 §2)" + hints.formula(", ψ + ω T"))
        px_no_t = px + v / om * (np.sin(psi + om) - np.sin(psi))
        py_no_t = py + v / om * (np.cos(psi) - np.cos(psi + om))
        yield variant(i0=px_no_t), no_t
        yield variant(i1=py_no_t), no_t
        yield variant(i0=px_no_t, i1=py_no_t), no_t
    yield variant(i3=psi + om), ("the heading turns by the turn rate times the step: T is missing "
                                 "(lecture 04 §2)" + hints.formula(": ψ += ω T"))
    yield variant(i3=psi), "the heading must turn over the step (lecture 04 §2)" + hints.formula(": ψ += ω T")
    yield variant(i0=px + v * T * np.cos(psi + wt), i1=py + v * T * np.sin(psi + wt)), (
        "you moved along the heading at the end of the step; the car turns during the step: integrate "
        "its velocity over the step (lecture 04 §2). A series whose terms are divided by k! instead of "
        "(k+1)! sums to exactly this" + hints.formula(": ∫₀ᵀ (ω t)^k / k! dt = T (ω T)^k / (k+1)!"))
    per_second = expected[:2] + (expected[:2] - x[:2]) * (1.0 / T - 1.0)
    yield variant(i0=per_second[0], i1=per_second[1]), (
        "the distance travelled over the step is v T, not v (a factor T is missing in front)")
    yield variant(i0=px + v * T, i1=py), ("the car moves along its heading: the heading is missing "
                                          "(lecture 04 §2)" + hints.formula(": p_x += v T cos ψ, p_y += v T sin ψ"))
    yield variant(i0=px + v * T * np.sin(psi), i1=py + v * T * np.cos(psi)), (
        "cos and sin swapped: ψ is measured from the x axis (lecture 04 §2)"
        + hints.formula(", so p_x moves by v T cos ψ and p_y by v T sin ψ"))
    yield expected[[0, 1, 3, 2, 4]] - x, ("the state order is [p_x, p_y, v, ψ, ω]: v and ψ are "
                                          "swapped in the returned state")


@check
def check_ctrv_step(ctrv_step):
    """The learner's ``ctrv_step(x, T)`` (noise-free) against the derived model.

    Turning KITTI states over steps up to 2 s, the same driving straight, and the dense sweep
    of turn rates from ±1e-13 to ±1.5 rad/s at steps from 1e-5 s to 2 s (:func:`_in_step_sweep`;
    see :data:`STEP_RTOL` for the tolerance and its reason).
    """
    for x, T, expected, _ in kitti_ctrv_cases():
        what = f"ctrv_step(x, T={T:.3g})"
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
        if 0.0 < abs(x[4] * T) < THRESHOLD:
            hint = _near_zero_hint(x, T, "step")
        elif x[4] * T <= -THRESHOLD:
            hint = (f"this is a right turn (ω < 0, |ω T| = {abs(x[4] * T):.3g}): does your switch to the series "
                    "compare |ω T| (abs()) with the threshold? Else the closed form of lecture 04 §2"
                    + hints.formula(": " + CLOSED_FORM))
        else:
            hint = "the closed form of lecture 04 §2, the car's velocity integrated over the step" + hints.formula(
                ": " + CLOSED_FORM)
        expect_close(got - x, expected - x, f"the increment of ctrv_step at a KITTI state {_where(x, T)}",
                     rtol=0.0, atol=atol, mistakes=_step_mistakes(x, T, expected), hint=hint)


def _forward_difference(x, T, h):
    """The forward-difference Jacobian of the reference step with step ``h`` in every component."""
    x = np.asarray(x, dtype=float)
    f0 = symbolic.ctrv_step(x, T)
    return np.column_stack([(symbolic.ctrv_step(x + h * e, T) - f0) / h for e in np.eye(5)])


def _central_difference(x, T, h):
    """The central-difference Jacobian of the reference step with step ``h`` in every component."""
    x = np.asarray(x, dtype=float)
    return np.column_stack([(symbolic.ctrv_step(x + h * e, T) - symbolic.ctrv_step(x - h * e, T)) / (2 * h)
                            for e in np.eye(5)])


def _coarse_difference_hint(h: float, central: bool) -> str:
    kind = "central" if central else "forward"
    return (f"your Jacobian is a {kind} difference of the step with a step too coarse (h = {h:g}): its "
            "error grows with h (the curvature of f times h), and here it is larger than the Jacobian's "
            "tolerance. The lecture derives F exactly, by SymPy (lecture 04 §2); if you difference, "
            "use a small step" + hints.formula(": h ≈ 1e-6 forward, or a central difference "
                                               "(f(x + h e_j) − f(x − h e_j)) / (2h) with h ≈ 1e-5"))


def _jacobian_mistakes(x, T, expected):
    """(wrong Jacobian, hint) of known wrong Jacobians; a generator, built only on failure.

    At 0 < |ω T| < 1e-4 only the mistakes of the ω → 0 limit are tried: there a closed form's
    cancellation gives values of any size, and the other mistakes (which the KITTI cases, tried
    first, name) can differ from the right Jacobian by less than that noise, so they would be
    matched by accident.
    """
    v, psi, om = x[2], x[3], x[4]
    generic = om == 0.0 or abs(om * T) >= 1e-4
    bend = ("the ω column lost the turn rate's effect on the position: the turn rate still bends the path "
            "over the step, also as ω → 0 (lecture 04 §3). Differentiate first, then let ω → 0 "
            "(substituting ω = 0 before differentiating loses the ω column)"
            + hints.formula("; the limit is ∂p_x/∂ω → −v T² sin ψ / 2, ∂p_y/∂ω → v T² cos ψ / 2, not 0"))
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
            yield lost, bend + "; and ∂ψ/∂ω is lost too"
            lost[4, 4] = 0.0
            yield lost, bend + "; the whole ω column is gone (∂ψ/∂ω and ∂ω/∂ω too)"
        if om != 0.0:
            yield first_order, (f"at |ω T| = {abs(om * T):.3g} you used the Jacobian of the straight "
                                "line (first order in ω), which errs by ~v T³ |ω| / 3 in ∂p/∂ω: below "
                                "the switch differentiate the ω-series, not only its straight-line term "
                                "(lecture 04 §3)")
    if not generic:
        return
    for wrong_t in (0.0, 1.0):
        missing_t = expected.copy()
        missing_t[3, 4] = wrong_t
        yield missing_t, ("∂ψ/∂ω is wrong: the heading after the step is the heading turned by ω over the "
                          "whole step (lecture 04 §2)" + hints.formula(", ψ + ω T, so ∂ψ/∂ω = T"))
    if abs(om * T) >= THRESHOLD:
        # the Jacobian of a closed form with p_y's cosines in the wrong order (row 1 flips sign
        # in its ∂/∂v, ∂/∂ψ and ∂/∂ω entries)
        flipped = expected.copy()
        flipped[1, 2:5] = -flipped[1, 2:5]
        yield flipped, ("p_y's derivatives have the wrong sign: check the sign of p_y's velocity (or the "
                        "order of the cosines) in the model you differentiate (lecture 04 §2)"
                        + hints.formula(": p_y integrates v sin(ψ + ω t), which gives v/ω (cos ψ − cos(ψ + ω T))"))
    yield symbolic.ctrv_jacobian(np.asarray(x, dtype=float)[[0, 1, 3, 2, 4]], T), (
        "the Jacobian is evaluated with v and ψ exchanged: the arguments of the lambdified "
        "function are in another order than the call (p_x, p_y, v, ψ, ω, T)")
    yield expected.T, "the Jacobian is transposed: F[i, j] = ∂f_i/∂x_j (row = output, column = state)"
    yield expected - np.eye(5), ("the identity is missing: f(x) = x + Δ(x), so F = I + ∂Δ/∂x "
                                 "(∂p_x/∂p_x = 1, ∂v/∂v = 1, ...)")
    yield symbolic.ctrv_jacobian(symbolic.ctrv_step(x, T), T), (
        "wrong point of linearisation: F is evaluated at the state x the step starts from, not at "
        "the predicted state f(x)")
    # finite differences of a correct step, with a step h too coarse for the tolerance
    for h in FD_STEPS:
        yield _forward_difference(x, T, h), _coarse_difference_hint(h, central=False)
    for h in FD_STEPS[:3]:
        yield _central_difference(x, T, h), _coarse_difference_hint(h, central=True)


@check(uses=("ctrv_step",))
def check_ctrv_jacobian(ctrv_jacobian):
    """The learner's ``ctrv_jacobian(x, T)`` against SymPy's, turning, at ω = 0 and towards it.

    On :func:`jacobian_cases`, the KITTI cases and a sweep of one rate per decade. Finite
    differences of a correct step with a small step h pass (see :data:`JACOBIAN_RTOL`);
    those with a coarse step (h = 1e-2) fail and are named as such. A Jacobian that calls the
    learner's ``ctrv_step`` (finite differences) is blamed on ``ctrv_step`` first when that one
    fails its own check.
    """
    for x, T, _, expected in jacobian_cases():
        what = f"ctrv_jacobian(x, T={T:.3g})"
        got = _call_near_zero(ctrv_jacobian, x, T)
        if np.shape(got) == (5, 4):
            raise CheckFailed("ctrv_jacobian has shape (5, 4): differentiate with respect to all five "
                              "state components, ω included")
        got = _finite_or_limit(got, (5, 5), x, T, what)
        scale = np.abs(expected).max(axis=0)
        atol = JACOBIAN_RTOL * scale   # per column, broadcast over rows
        if 0.0 < abs(x[4] * T) < THRESHOLD:
            hint = _near_zero_hint(x, T, "Jacobian")
        else:
            error = np.abs(got - expected) / scale
            bad = [f"∂{STATE_NAMES[i]}/∂{STATE_NAMES[j]}" for i, j in zip(*np.nonzero(error > JACOBIAN_RTOL))]
            near = ("close to the reference: if you use finite differences, your step is too coarse (the "
                    "difference's error grows with h); " if error.max() < 0.05 else "")
            if x[4] * T <= -THRESHOLD:
                near = (f"this is a right turn (ω < 0, |ω T| = {abs(x[4] * T):.3g}): does your switch to the "
                        "series compare |ω T| (abs()) with the threshold? Else every right turn takes the series, "
                        "exact only near ω T = 0 (lecture 04 §3). ") + near
            hint = (f"the entries that differ: {', '.join(bad[:6])}; {near}F = ∂f/∂x is derived from the "
                    "closed form by SymPy in lecture 04 §2" + hints.formula(" (sp.Matrix.jacobian of the step "
                                                                           "in the state [p_x, p_y, v, ψ, ω])"))
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
        "acceleration held over the step also moves the position along the heading and the heading, "
        "and since one noise moves both, Q has cross terms. Build the process-noise Jacobian "
        "B = ∂f/∂w (5, 2) and map the noise's covariance through it (lecture 04 §2 derives B, §4b maps "
        "the covariance)" + hints.formula(": Q = B diag(σ_a², σ_ψ̈²) Bᵀ"))
    yield np.diag(np.diag(through(B))), (
        "the cross terms are missing: the same acceleration moves the position and the speed (and "
        "the heading and the turn rate), so they are correlated (lecture 04 §4b): keep the whole "
        "matrix, not its diagonal" + hints.formula(", Q = B diag(σ_a², σ_ψ̈²) Bᵀ"))
    yield through(_noise_jacobian(T, (1.0, 0.0))), (
        "ν_a is the longitudinal acceleration: it pushes the car along its heading ψ, not along the x "
        "axis of the navigation frame (lecture 04 §2)" + hints.formula(": it moves p_x and p_y by T²/2 (cos ψ, sin ψ)"))
    yield through(_noise_jacobian(T, (np.sin(psi), np.cos(psi)))), (
        "cos and sin are swapped: ψ is measured from the x axis (lecture 04 §2)"
        + hints.formula(", so ν_a moves p_x by T²/2 cos ψ and p_y by T²/2 sin ψ"))
    for turned in (psi + om * T, psi + om * T / 2):
        yield through(_noise_jacobian(T, (np.cos(turned), np.sin(turned)))), (
            "by the lecture's convention (lecture 04 §2) ν_a pushes along the heading at the start of the "
            "step, ψ (the turn during the step is neglected), not the heading at its end or middle")
    yield through(_noise_jacobian(T, (np.cos(psi), np.sin(psi)), half=1.0 / T, rate=0.5 * T**2)), (
        "T and T²/2 are swapped: an acceleration held over the step changes the speed (or the turn "
        "rate) in proportion to the step and moves the position (or the heading) in proportion to "
        "its square (lecture 04 §2)" + hints.formula(": by T times it, and by T²/2 times it"))
    no_half = ("the position and heading rows of B lack the factor ½: the held acceleration's push "
               "builds up over the step (lecture 04 §2)" + hints.formula(": ∫₀ᵀ t dt = T²/2, not T²"))
    for rows in ((0, 1), (3,), (0, 1, 3)):
        doubled = B.copy()
        doubled[rows, :] *= 2.0
        yield through(doubled), no_half
    yield through(B, np.array([sigma_a, sigma_yaw])), (
        "sigma_a and sigma_yaw are standard deviations: the noise's covariance holds their squares "
        "(lecture 04 §4b)" + hints.formula(", diag(σ_a², σ_ψ̈²)"))
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
                              "noise's covariance is (2, 2), and Q is (5, 5) (lecture 04 §4b)"
                              + hints.formula(": Q = B Σ_w Bᵀ")) from None
        got = as_array(result, f"ctrv_process_noise ({where})")
        if got.shape == (2, 2):
            raise CheckFailed("Q has shape (2, 2), expected (5, 5): that is Bᵀ Σ B (or the noise's "
                              "own covariance); B is (5, 2) and Q, in state space, is (5, 5) (lecture 04 §4b)"
                              + hints.formula(": Q = B diag(σ_a², σ_ψ̈²) Bᵀ"))
        got = expect_shape(got, (5, 5), f"Q ({where})")
        rows = [name for i, name in enumerate(STATE_NAMES)
                if not np.allclose(got[i], expected[i], rtol=1e-7, atol=1e-12)]
        expect_close(got, expected, f"Q at a KITTI state ({where})", rtol=1e-7, atol=1e-12,
                     mistakes=_noise_mistakes(x, T, sigma_a, sigma_yaw),
                     hint="the noise's covariance mapped through the process-noise Jacobian B = ∂f/∂w "
                          f"(5, 2) of lecture 04 §2 (§4b); the rows that differ: {', '.join(rows) or 'none'}"
                          + hints.formula(". Q = B diag(σ_a², σ_ψ̈²) Bᵀ"))
