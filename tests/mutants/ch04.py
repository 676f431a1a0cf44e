"""Chapter 04 (motion models): plausible mistakes in the CTRV step, its Jacobian and (the
challenge) its process noise.

The step's solution switches from the closed form to the ω-series at the lecture's
|ω T| = symbolic.OMEGA_SERIES_THRESHOLD (the whole switch is the exercise's fix region); the
Jacobian differentiates both branches by SymPy. Mistakes cover the formulas (signs, order
of the sines and cosines, sin/cos, the heading update, the identity, transposition, the
point of linearisation) and the ω → 0 handling (no limit, `omega != 0`, a switch too close
to 0 for the Jacobian, the straight line or a short series too far from 0); for the process
noise, the frame ν_a pushes in, the heading it pushes along, T vs T²/2, σ vs σ² and the
cross terms. Each stub of the exercise is a mutant here too, marked "(the stub)".
"""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "04_motion_models"

# the solution's lines, as they occur once in their cell (the STUB comments repeat some of
# them behind a "# ", so the leading newline and indent make each unique)
CLOSED_PX = "\n        px_new = px + v / omega * (np.sin(psi + omega * T) - np.sin(psi))"
CLOSED_PY = "\n        py_new = py + v / omega * (np.cos(psi) - np.cos(psi + omega * T))"
SWITCH = "    if abs(omega * T) > OMEGA_T_SWITCH:"
SERIES_XY = ("px_new = px + c @ np.cos(psi + K * np.pi / 2)\n"
             "        py_new = py + c @ np.sin(psi + K * np.pi / 2)")
RETURN = "return np.array([px_new, py_new, v, psi + omega * T, omega])"
# the whole step's fix region (the switch and both branches), which the stub replaces
STEP_REGION = (SWITCH + CLOSED_PX + CLOSED_PY + "\n    else:\n"
               "        # the omega -> 0 limit: v T sum_k (omega T)^k / (k+1)! (cos, sin)(psi + k pi/2)\n"
               "        c = v * T * (omega * T) ** K / np.cumprod(K + 1)\n        " + SERIES_XY)
JAC_SELECT = "    F_numeric = F_turn_numeric if abs(om_ * T) > OMEGA_T_SWITCH else F_series_numeric"
JAC_RETURN = "    return np.array(F_numeric(px_, py_, v_, psi_, om_, T), dtype=float)"
# from the switch of ctrv_jacobian to its return, with the fix region's stub in between
JAC_TAIL = (JAC_SELECT + "\n    # STUB\n    # F_numeric = F_turn_numeric if om_ != 0 else F_series_numeric"
            "  # fix this: where is the closed form's Jacobian accurate?\n    # END SOLUTION\n" + JAC_RETURN)
# the challenge: ctrv_process_noise's B and Q
NOISE_B_POS = ("B = np.array([[0.5 * T**2 * np.cos(psi), 0.0],\n"
               "                  [0.5 * T**2 * np.sin(psi), 0.0],")
NOISE_B = (NOISE_B_POS + "\n                  [T, 0.0],\n                  [0.0, 0.5 * T**2],\n"
           "                  [0.0, T]])")
NOISE_Q = "Q = B @ np.diag([sigma_a**2, sigma_yaw**2]) @ B.T"

# the former solution's hand-typed Jacobian of the straight line (first order in ω)
FIRST_ORDER = """    F = np.eye(5)
    F[0, 2], F[1, 2] = T * np.cos(psi_), T * np.sin(psi_)
    F[0, 3], F[1, 3] = -v_ * T * np.sin(psi_), v_ * T * np.cos(psi_)
    F[3, 4] = T
    F[0, 4], F[1, 4] = -0.5 * v_ * T**2 * np.sin(psi_), 0.5 * v_ * T**2 * np.cos(psi_)
    return F"""


def _first_order_below(condition: str) -> str:
    """ctrv_jacobian's body: SymPy's closed form where ``condition``, else the straight line's."""
    return (f"    if {condition}:\n"
            "        return np.array(F_turn_numeric(px_, py_, v_, psi_, om_, T), dtype=float)\n"
            + FIRST_ORDER)


def _finite_difference(h: str, central: bool) -> str:
    """ctrv_jacobian's body: a finite difference of ctrv_step with step ``h``."""
    diff = ("(ctrv_step(x + e, T) - ctrv_step(x - e, T)) / (2 * h)" if central
            else "(ctrv_step(x + e, T) - f0) / h")
    return (f"    x = np.asarray(x, dtype=float)\n    h, f0 = {h}, ctrv_step(x, T)\n"
            "    F = np.zeros((5, 5))\n    for j in range(5):\n"
            "        e = np.zeros(5)\n        e[j] = h\n"
            f"        F[:, j] = {diff}\n    return F")


MUTANTS = [
    # ---- ctrv_step: the whole step
    Edit("ctrv_step", STEP_REGION, "    px_new = px + v * T * np.cos(psi)\n    py_new = py + v * T * np.sin(psi)",
         keyword="the car turns", mistake="the straight line along the initial heading at every ω (the stub)"),
    # ---- ctrv_step: the closed form
    Edit("ctrv_step", CLOSED_PY, "\n        py_new = py + v / omega * (np.cos(psi + omega * T) - np.cos(psi))",
         keyword="order of the cosines", mistake="p_y's cosines in the wrong order"),
    Edit("ctrv_step", CLOSED_PX, "\n        px_new = px + v / omega * (np.sin(psi) - np.sin(psi + omega * T))",
         keyword="order of the sines", mistake="p_x's sines in the wrong order"),
    Edit("ctrv_step", CLOSED_PX + CLOSED_PY,
         "\n        px_new = px + v / omega * (np.cos(psi) - np.cos(psi + omega * T))"
         "\n        py_new = py + v / omega * (np.sin(psi + omega * T) - np.sin(psi))",
         keyword="swapped", mistake="p_x integrates sin and p_y cos"),
    Edit("ctrv_step", CLOSED_PX, "\n        px_new = px + v / omega * (np.sin(psi + omega) - np.sin(psi))",
         keyword="inside the sine", mistake="T missing inside the sine of the closed form"),
    Edit("ctrv_step", CLOSED_PX + CLOSED_PY,
         "\n        px_new = px + v * T * np.cos(psi)\n        py_new = py + v * T * np.sin(psi)",
         keyword="the car turns", mistake="the straight line used while turning"),
    # ---- ctrv_step: the heading and the returned state
    Edit("ctrv_step", RETURN, "return np.array([px_new, py_new, v, psi + omega, omega])",
         keyword="T is missing", mistake="heading updated by ω instead of ω T"),
    Edit("ctrv_step", RETURN, "return np.array([px_new, py_new, v, psi, omega])",
         keyword="heading must turn", mistake="heading not updated"),
    Edit("ctrv_step", RETURN, "return np.array([px_new, py_new, psi + omega * T, v, omega])",
         keyword="v and ψ are swapped", mistake="state returned as [p_x, p_y, ψ, v, ω]"),
    # ---- ctrv_step: the ω → 0 limit
    Edit("ctrv_step", SWITCH, "    if True:", keyword="ω → 0 limit is missing",
         mistake="no limit: the closed form at every ω (NaN at ω = 0)"),
    Edit("ctrv_step", SWITCH, "    if omega != 0:", keyword="cancellation",
         mistake="branch on omega != 0 (the closed form at ω = 1e-12)"),
    Edit("ctrv_step", SWITCH, "    if abs(omega) > 1e-13:", keyword="cancellation",
         mistake="switch to the limit only at |ω| < 1e-13"),
    # cut-offs on |ω| alone: the closed form kept down to a tiny rate, the series below it. The
    # closed form loses ~3e-16 / |ω T| of v T, so each shows where |ω T| is tiny: at the sweep's
    # 1.05 · 10^k rad/s with T = 1e-5 s (and, for 1e-12, at every step)
    Edit("ctrv_step", SWITCH, "    if abs(omega) > 1e-12:", keyword="cancellation",
         mistake="closed form kept down to |ω| > 1e-12 (4.7e-5 m at ω = 1e-11, T = 0.1 s)"),
    Edit("ctrv_step", SWITCH, "    if abs(omega) > 1e-9:", keyword="cancellation",
         mistake="closed form kept down to |ω| > 1e-9"),
    Edit("ctrv_step", SWITCH, "    if abs(omega) > 1e-6:", keyword="a cut-off on |ω| alone",
         mistake="closed form kept down to |ω| > 1e-6 (exact at 0.1 s, 1e-5 of v T lost at T = 1e-5 s)"),
    # the exercise's former limit: the straight line below |ω| = 1e-6 and the closed form above it,
    # whatever T; above 1e-6 it is the cut-off above, and fails where it does
    Edit("ctrv_step", SWITCH,
         "    if abs(omega) <= 1e-6:  # the former solution: the straight line below |ω| = 1e-6\n"
         "        px_new, py_new = px + v * T * np.cos(psi), py + v * T * np.sin(psi)\n"
         "    elif True:", keyword="a cut-off on |ω| alone",
         mistake="the exercise's former first-order limit: straight line below |ω| = 1e-6, closed form above "
                 "(1e-5 of v T lost at 1.05e-6 rad/s and T = 1e-5 s)"),
    Edit("ctrv_step", SWITCH, "    if omega * T > OMEGA_T_SWITCH:", keyword="right turn",
         mistake="the switch without abs(): every right turn takes the series (0.4 mm at 2 s)"),
    Edit("ctrv_step", "K = np.arange(8)", "K = np.arange(1)", keyword="straight line",
         mistake="only the straight line below the lecture's switch |ω T| < 0.02"),
    Edit("ctrv_step", SWITCH,
         "    if abs(omega) < 1e-3:\n        px_new, py_new = px + v * T * np.cos(psi), py + v * T * np.sin(psi)\n"
         "    elif True:", keyword="straight line", mistake="straight line below |ω| = 1e-3"),
    Edit("ctrv_step", "K = np.arange(8)", "K = np.arange(2)", keyword="series",
         mistake="series cut after its first-order term"),
    Edit("ctrv_step", "np.cumprod(K + 1)", "np.cumprod(np.maximum(K, 1))", keyword="(k+1)!",
         mistake="series terms divided by k! instead of (k+1)!"),
    Edit("ctrv_step", "(omega * T) ** K", "omega ** K", keyword="series",
         mistake="series in ω instead of ω T"),
    Edit("ctrv_step", "px_new = px + c @ np.cos(psi + K * np.pi / 2)",
         "px_new = px + c @ np.cos(psi - K * np.pi / 2)", keyword="series",
         mistake="series of p_x with the phase k π/2 subtracted"),
    Edit("ctrv_step", SERIES_XY, "px_new = px + v * T\n        py_new = py", keyword="heading is missing",
         mistake="straight line along the x axis, heading ignored"),
    Edit("ctrv_step", SERIES_XY,
         "px_new = px + c @ np.sin(psi + K * np.pi / 2)\n        py_new = py + c @ np.cos(psi + K * np.pi / 2)",
         keyword="swapped", mistake="series with sin and cos swapped"),
    Edit("ctrv_step", SERIES_XY,
         "px_new = px + v * T * np.cos(psi + omega * T)\n        py_new = py + v * T * np.sin(psi + omega * T)",
         keyword="heading at the end", mistake="straight line along the heading at the end of the step"),
    Edit("ctrv_step", "c = v * T * (omega * T) ** K", "c = v * (omega * T) ** K", keyword="not v",
         mistake="distance v instead of v T in the limit"),

    # ---- ctrv_jacobian: what SymPy differentiates
    Edit("ctrv_jacobian", "F_turn = f_turn.jacobian(state)\n", "F_turn = f_turn.jacobian(state[:4, :])\n",
         keyword="all five", mistake="ω left out of the differentiation"),
    Edit("ctrv_jacobian", "F_series = f_series.jacobian(state)\n",
         "F_series = f_series.subs(omega, 0).jacobian(state)\n", keyword="bends the path",
         mistake="ω = 0 substituted before differentiating (the stub)"),
    Edit("ctrv_jacobian", "F_turn = f_turn.jacobian(state)\n", "F_turn = f_turn.jacobian(state) - sp.eye(5)\n",
         keyword="identity", mistake="Jacobian of the increment, identity missing"),
    Edit("ctrv_jacobian", "v * sp.sin(psi + omega * t)])", "-v * sp.sin(psi + omega * t)])",
         keyword="p_y", mistake="p_y's velocity with the wrong sign in the SymPy model (clockwise ψ)"),
    Edit("ctrv_jacobian", "sp.series(e, omega, 0, len(K))", "sp.series(e, omega, 0, 2)", keyword="series",
         mistake="Jacobian series cut after its first-order term"),
    Edit("ctrv_jacobian", "v, psi + omega * T, omega])", "v, psi + omega, omega])",
         keyword="∂ψ/∂ω is wrong", mistake="heading ψ + ω in the SymPy model (∂ψ/∂ω = 1)"),
    # ---- ctrv_jacobian: the numeric function
    Edit("ctrv_jacobian", JAC_RETURN, "    return np.array(F_numeric(px_, py_, v_, psi_, om_, T), dtype=float).T",
         keyword="transposed", mistake="Jacobian transposed"),
    Edit("ctrv_jacobian", "    px_, py_, v_, psi_, om_ = x\n", "    px_, py_, v_, psi_, om_ = ctrv_step(x, T)\n",
         keyword="linearisation", mistake="linearised at the predicted state f(x)"),
    Edit("ctrv_jacobian", "F_turn_numeric = sp.lambdify((px, py, v, psi, omega, T)",
         "F_turn_numeric = sp.lambdify((px, py, psi, v, omega, T)", keyword="order",
         mistake="lambdify's arguments in another order than the call"),
    # ---- ctrv_jacobian: the ω → 0 limit
    Edit("ctrv_jacobian", JAC_SELECT, "    F_numeric = F_turn_numeric", keyword="ω → 0 limit is missing",
         mistake="no limit: SymPy's closed form at every ω (NaN at ω = 0)"),
    Edit("ctrv_jacobian", JAC_SELECT,
         "    F_numeric = F_turn_numeric if om_ != 0 else F_series_numeric", keyword="cancellation",
         mistake="branch on omega != 0 (the closed form at ω = 1e-9, off by 4.5e2) (the stub)"),
    Edit("ctrv_jacobian", JAC_TAIL, _first_order_below("abs(om_) > 1e-6"),
         keyword="cancellation", mistake="the former solution: closed form above |ω| = 1e-6, straight line below"),
    Edit("ctrv_jacobian", JAC_TAIL, _first_order_below("om_ != 0"),
         keyword="cancellation", mistake="closed form for ω ≠ 0, the straight line's Jacobian at ω = 0"),
    Edit("ctrv_jacobian", JAC_TAIL, _first_order_below("abs(om_ * T) > OMEGA_T_SWITCH"),
         keyword="straight line", mistake="the straight line's Jacobian below the lecture's switch"),
    Edit("ctrv_jacobian", JAC_SELECT,
         "    F_numeric = F_turn_numeric if abs(om_) > 1e-6 else F_series_numeric", keyword="cancellation",
         mistake="the former solution's switch |ω| > 1e-6 (series below): 1/ω² terms lose 8e-5 at T = 0.1 s"),
    Edit("ctrv_jacobian", JAC_SELECT,
         "    F_numeric = F_turn_numeric if om_ * T > OMEGA_T_SWITCH else F_series_numeric", keyword="right turn",
         mistake="the Jacobian's switch without abs(): the series' Jacobian for every right turn"),
    # finite differences with a coarse step: told as such, not "compare with finite differences"
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-2", central=False), keyword="too coarse",
         mistake="forward difference of ctrv_step with h = 1e-2"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-3", central=False), keyword="too coarse",
         mistake="forward difference of ctrv_step with h = 1e-3"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-1", central=True), keyword="too coarse",
         mistake="central difference of ctrv_step with h = 1e-1"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("5e-3", central=False), keyword="too coarse",
         mistake="forward difference with h = 5e-3, a step the check does not try (the close-but-wrong hint)"),

    # ---- ctrv_process_noise (the challenge): B (5, 2) and Q = B diag(σ_a², σ_ψ̈²) Bᵀ
    Edit("ctrv_process_noise", f"{NOISE_B}\n    {NOISE_Q}",
         "Q = np.diag([0.0, 0.0, (sigma_a * T)**2, 0.0, (sigma_yaw * T)**2])",
         keyword="speed and the turn rate only", mistake="noise on v and ω only (the stub)"),
    Edit("ctrv_process_noise", NOISE_Q, "Q = np.diag(np.diag(B @ np.diag([sigma_a**2, sigma_yaw**2]) @ B.T))",
         keyword="cross terms", mistake="only the diagonal of B Σ Bᵀ"),
    Edit("ctrv_process_noise", NOISE_B_POS,
         "B = np.array([[0.5 * T**2, 0.0],\n                  [0.0, 0.0],",
         keyword="navigation frame", mistake="ν_a pushing along the x axis"),
    Edit("ctrv_process_noise", NOISE_B_POS,
         "B = np.array([[0.5 * T**2 * np.sin(psi), 0.0],\n                  [0.5 * T**2 * np.cos(psi), 0.0],",
         keyword="swapped", mistake="cos ψ and sin ψ swapped"),
    Edit("ctrv_process_noise", NOISE_B_POS,
         "B = np.array([[0.5 * T**2 * np.cos(psi + omega * T), 0.0],\n"
         "                  [0.5 * T**2 * np.sin(psi + omega * T), 0.0],",
         keyword="start of the step", mistake="ν_a along the heading at the end of the step"),
    Edit("ctrv_process_noise", NOISE_B_POS,
         "B = np.array([[0.5 * T**2 * np.cos(psi + omega * T / 2), 0.0],\n"
         "                  [0.5 * T**2 * np.sin(psi + omega * T / 2), 0.0],",
         keyword="start of the step", mistake="ν_a along the heading at mid-step"),
    Edit("ctrv_process_noise", NOISE_B,
         "B = np.array([[T * np.cos(psi), 0.0],\n                  [T * np.sin(psi), 0.0],\n"
         "                  [0.5 * T**2, 0.0],\n                  [0.0, T],\n                  [0.0, 0.5 * T**2]])",
         keyword="T and T²/2 are swapped", mistake="T and T²/2 swapped in both columns"),
    Edit("ctrv_process_noise", NOISE_B_POS,
         "B = np.array([[T**2 * np.cos(psi), 0.0],\n                  [T**2 * np.sin(psi), 0.0],",
         keyword="factor ½", mistake="½ missing in the position rows (T² for T²/2)"),
    Edit("ctrv_process_noise", NOISE_Q, "Q = B @ np.diag([sigma_a, sigma_yaw]) @ B.T",
         keyword="standard deviations", mistake="σ not squared"),
    Edit("ctrv_process_noise", NOISE_Q, "Q = B @ np.diag([sigma_yaw**2, sigma_a**2]) @ B.T",
         keyword="variances are swapped", mistake="σ_a² and σ_ψ̈² swapped"),
    Edit("ctrv_process_noise", NOISE_Q, "Q = B.T @ B * np.diag([sigma_a**2, sigma_yaw**2])",
         keyword="(2, 2)", mistake="Bᵀ B Σ, (2, 2)"),
    Edit("ctrv_process_noise", NOISE_Q, "Q = B.T @ np.diag([sigma_a**2, sigma_yaw**2]) @ B",
         keyword="(5, 2)", mistake="Bᵀ Σ B (a shape error)"),
]

EQUIVALENTS = [
    # ---- ctrv_step (tolerance: 1e-6 of v T on the increment; see checks/motion.py)
    Edit("ctrv_step", RETURN,
         "d = v * T * np.sinc(omega * T / (2 * np.pi))  # 2 sin(ωT/2)/ω, exact at 0\n"
         "    return np.array([px + d * np.cos(psi + omega * T / 2), py + d * np.sin(psi + omega * T / 2),\n"
         "                     v, psi + omega * T, omega])",
         mistake="chord form with np.sinc, no branch"),
    Edit("ctrv_step", SWITCH,
         "    if abs(omega * T) < 1e-8:  # first-order limit where the closed form would lose digits\n"
         "        px_new, py_new = px + v * T * np.cos(psi), py + v * T * np.sin(psi)\n"
         "    elif True:",
         mistake="straight line below |ω T| = 1e-8, closed form above"),
    Edit("ctrv_step", "K = np.arange(8)", "K = np.arange(4)", mistake="series with 4 terms (errs ≤ 1.3e-9 v T)"),
    Edit("ctrv_step", SWITCH, "    if abs(omega * T) > 1e-7:",
         mistake="closed form down to |ω T| = 1e-7, where it loses ≤ 3e-9 of v T (series below)"),
    Edit("ctrv_step", "K = np.arange(8)", "K = np.arange(12)", mistake="series with 12 terms"),
    Edit("ctrv_step", SWITCH, "    if abs(omega) > OMEGA_T_SWITCH:", mistake="switch on |ω| instead of |ω T|"),
    Edit("ctrv_step", "c = v * T * (omega * T) ** K / np.cumprod(K + 1)\n"
         "        px_new = px + c @ np.cos(psi + K * np.pi / 2)\n"
         "        py_new = py + c @ np.sin(psi + K * np.pi / 2)",
         "import math\n        px_new, py_new = px, py\n        for k in range(8):\n"
         "            c = v * T * (omega * T) ** k / math.factorial(k + 1)\n"
         "            px_new += c * math.cos(psi + k * math.pi / 2)\n"
         "            py_new += c * math.sin(psi + k * math.pi / 2)",
         mistake="series as a Python loop with math.factorial"),
    Edit("ctrv_step", RETURN, "return [px_new, py_new, v, psi + omega * T, omega]", mistake="a list returned"),
    Edit("ctrv_step", RETURN,
         "return np.array([px_new, py_new, v, np.arctan2(np.sin(psi + omega * T), np.cos(psi + omega * T)), omega])",
         mistake="heading wrapped into (−π, π]"),
    # ---- ctrv_jacobian (tolerance: 2e-5 of each column's largest entry; see checks/motion.py)
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-6", central=False),
         mistake="forward difference of ctrv_step, h = 1e-6 (errs ≤ 5e-7)"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-8", central=False),
         mistake="forward difference, h = 1e-8 = √eps (round-off ≤ 9e-6 on 400 m positions)"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-5", central=False),
         mistake="forward difference, h = 1e-5 (errs ≤ 5e-6)"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-5", central=True),
         mistake="central difference, h = 1e-5"),
    Edit("ctrv_jacobian", JAC_TAIL, _finite_difference("1e-6", central=True),
         mistake="central difference, h = 1e-6"),
    Edit("ctrv_jacobian", JAC_TAIL, _first_order_below("abs(om_ * T) > 1e-5"),
         mistake="the lecture's first-order (straight-line) Jacobian below |ω T| = 1e-5, where it errs ≤ 7e-6"),
    Edit("ctrv_jacobian", JAC_RETURN, "    return np.asarray(F_numeric(px_, py_, v_, psi_, om_, T)).tolist()",
         mistake="nested lists returned"),
    Edit("ctrv_jacobian", "F_series = f_series.jacobian(state)\n",
         "F_series = sp.simplify(f_series.jacobian(state))\n", mistake="simplified series Jacobian"),
]

EQUIVALENTS += [
    # ---- ctrv_process_noise (tolerance: rtol 1e-7, atol 1e-12; see checks/motion.py)
    Edit("ctrv_process_noise", NOISE_Q, "Q = (B * np.array([sigma_a, sigma_yaw])**2) @ B.T",
         mistake="B Σ Bᵀ by broadcasting"),
    Edit("ctrv_process_noise", NOISE_Q,
         "Q = sigma_a**2 * np.outer(B[:, 0], B[:, 0]) + sigma_yaw**2 * np.outer(B[:, 1], B[:, 1])",
         mistake="Q as a sum of the two noises' outer products"),
    Edit("ctrv_process_noise", f"{NOISE_B}\n    {NOISE_Q}",
         "nu_a, nu_yaw, t_ = sp.symbols('nu_a nu_yaw t_')\n"
         "    psi_s, T_s = sp.symbols('psi_s T_s')\n"
         "    shift = sp.Matrix([nu_a * t_**2 / 2 * sp.cos(psi_s), nu_a * t_**2 / 2 * sp.sin(psi_s),\n"
         "                       nu_a * t_, nu_yaw * t_**2 / 2, nu_yaw * t_])\n"
         "    B_s = shift.jacobian([nu_a, nu_yaw]).subs(t_, T_s)\n"
         "    B = np.array(sp.lambdify((psi_s, T_s), B_s, modules='numpy')(psi, T), dtype=float)\n"
         "    Q = B @ np.diag([sigma_a**2, sigma_yaw**2]) @ B.T",
         mistake="B by SymPy from the noise's displacement"),
    Edit("ctrv_process_noise", NOISE_Q, "Q = np.linalg.multi_dot([B, np.diag([sigma_a, sigma_yaw])**2, B.T])",
         mistake="multi_dot, the diagonal squared"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("ctrv_step", SWITCH, "    if abs(omega * T) >= OMEGA_T_SWITCH:",
               reason="at |ω T| = the switch both branches agree to ~1e-13 of v T"),
    Equivalent("ctrv_step", "K = np.arange(8)", "K = np.arange(9)",
               reason="the 9th term is below 0.02⁸/9! ≈ 7e-20 of v T"),
    Equivalent("ctrv_jacobian", JAC_SELECT,
               "    F_numeric = F_turn_numeric if abs(om_ * T) >= OMEGA_T_SWITCH else F_series_numeric",
               reason="at the switch both Jacobians agree to ~1e-12"),
]
