"""Chapter 06 (the iterated EKF): plausible mistakes in the iterated mean step and the
iterated update, and correct variants of each."""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "06_iterated_ekf"

_GOP = "G_op = G(x_op)"
_GAIN = "K = P_check @ G_op.T @ np.linalg.inv(G_op @ P_check @ G_op.T + R)"
_R = "r = residual(y, g(x_op))"
_CORR = "correction = r - G_op @ (x_check - x_op)"
_NEXT = "x_next = x_check + K @ correction"
_CALL = "x_op = iekf_mean_step(x_check, P_check, x_lin, y, g, G, R, residual)"
_STOP = "if np.max(np.abs(x_op - x_lin)) <= tol:"
_LOOP = "for iteration in range(1, max_iter + 1):"
_GK = "G_k = G(x_lin)"
_PHAT = "P_hat = (np.eye(len(x_check)) - K @ G_k) @ P_check"
_RETURN = "return x_op, 0.5 * (P_hat + P_hat.T), iteration"
# the whole mean step (the exercise's multi-line section) and its placeholder, the EKF's step
_MEAN_STEP = "\n    ".join([_GOP, _GAIN, _R, _CORR, _NEXT])
_EKF_STEP = ("G_0 = G(x_check)\n    K = P_check @ G_0.T @ np.linalg.inv(G_0 @ P_check @ G_0.T + R)\n"
             "    x_next = x_check + K @ residual(y, g(x_check))")
# the challenge: the convergence test in the prior's standard deviations
_DISTANCE = "distance = np.sqrt(step @ np.linalg.solve(P_check, step))"
_VERDICT = "return bool(distance <= tol)"
_STD = "np.sqrt(np.diag(P_check))"

MUTANTS = [
    # --- iekf_mean_step --------------------------------------------------------------------
    Edit("iekf_mean_step", _NEXT, "x_next = x_op + K @ correction", keyword="not from x_op",
         mistake="step from x_op instead of x̌"),
    Edit("iekf_mean_step", _MEAN_STEP, _EKF_STEP, keyword="EKF's step",
         mistake="the EKF's step, linearised at x̌ whatever x_op is (the stub of the whole mean step)"),
    Edit("iekf_mean_step", _MEAN_STEP,
         "G_op = G(x_op)\n    K = P_check @ G_op.T @ np.linalg.inv(G_op @ P_check @ G_op.T + R)\n"
         "    x_next = x_op + K @ residual(y, g(x_op))",
         keyword="only enters through", mistake="the EKF's step re-taken from each iterate, x_op + K r(x_op)"),
    Edit("iekf_mean_step", _CORR, "correction = r", keyword="missing",
         mistake="the term − G (x̌ − x_op) left out"),
    Edit("iekf_mean_step", _NEXT, "x_next = x_op + K @ r", keyword="only enters through",
         mistake="Newton-like step x_op + K r"),
    Edit("iekf_mean_step", _GAIN, "G_0 = G(x_check)\n    K = P_check @ G_0.T @ np.linalg.inv(G_0 @ P_check @ G_0.T + R)",
         keyword="gain K_i", mistake="gain from G at x̌"),
    Edit("iekf_mean_step", _GOP, "G_op = G(x_check)", keyword="re-evaluated",
         mistake="G evaluated at x̌ instead of x_op"),
    Edit("iekf_mean_step", _R, "r = residual(y, g(x_check))", keyword="not y − g(x̌)",
         mistake="residual at x̌"),
    Edit("iekf_mean_step", _R, "r = y - g(x_op)", keyword="residual function",
         mistake="unwrapped residual"),
    Edit("iekf_mean_step", _GAIN, "K = P_check @ G_op.T @ np.linalg.inv(G_op @ P_check @ G_op.T + np.sqrt(R))",
         keyword="variances", mistake="√R in the gain"),
    Edit("iekf_mean_step", _NEXT, "x_next = x_check - K @ correction", keyword="iekf_mean_step",
         mistake="correction subtracted"),
    Edit("iekf_mean_step", _CORR, "correction = r - G_op @ x_check", keyword="not G x̌",
         mistake="− G x̌ instead of − G (x̌ − x_op)"),
    Edit("iekf_mean_step", _GAIN, "K = P_check @ G_op.T @ np.linalg.inv(R)",
         keyword="R⁻¹ instead of S⁻¹", mistake="R⁻¹ instead of S⁻¹ in the gain"),
    Edit("iekf_mean_step", _NEXT, "x_op[:] = x_check + K @ correction\n    x_next = x_op", keyword="in place",
         mistake="the new iterate written into the caller's x_op"),
    Edit("iekf_mean_step", _NEXT, "x_op += K @ correction + (x_check - x_op)\n    x_next = x_op", keyword="in place",
         mistake="x_op moved to the new iterate in place"),
    # --- iekf_update -----------------------------------------------------------------------
    Edit("iekf_update", _STOP, "if np.max(np.abs(x_op - x_check)) <= tol:", keyword="previous one",
         mistake="step measured from the prior (the stub)"),
    Edit("iekf_update", _GK, "G_k = G(x_check)", keyword="last linearisation",
         mistake="final covariance from G at x̌ (the stub)"),
    Edit("iekf_update", _CALL, "x_op = iekf_mean_step(x_check, P_check, x_check, y, g, G, R, residual)",
         keyword="EKF's", mistake="always linearised at x̌"),
    Edit("iekf_update", _CALL, "x_op = iekf_mean_step(x_lin, P_check, x_lin, y, g, G, R, residual)",
         keyword="walks away", mistake="the iterate passed as the prior"),
    Edit("iekf_update", _CALL,
         "x_op = iekf_mean_step(x_check, P_check, x_lin, y, g, G, R, residual)\n"
         "        G_i = G(x_lin)\n"
         "        P_check = P_check - P_check @ G_i.T @ np.linalg.inv(G_i @ P_check @ G_i.T + R) @ G_i @ P_check",
         keyword="only the mean iterates", mistake="P̌ shrunk inside the loop"),
    Edit("iekf_update", _LOOP, "for iteration in range(max_iter):", keyword="count one per linearisation",
         mistake="iterations counted from 0"),
    Edit("iekf_update", _RETURN, "return x_op, 0.5 * (P_hat + P_hat.T), iteration + 1",
         keyword="count one per linearisation", mistake="iterations one too many"),
    Edit("iekf_update", _LOOP, "for iteration in range(1, 21):", keyword="max_iter",
         mistake="max_iter ignored (fixed 20)"),
    Edit("iekf_update", _LOOP, "for iteration in range(1, max_iter):", keyword="max_iter",
         mistake="one linearisation fewer than max_iter"),
    Edit("iekf_update", _STOP, "if np.max(np.abs(x_op - x_lin)) <= 1e-6:", keyword="tol",
         mistake="tol ignored (fixed 1e-6)"),
    Edit("iekf_update", _CALL, "x_op = iekf_mean_step(x_check, P_check, x_op, y, g, G, R, residual)\n        x_lin = x_op",
         keyword="EKF's", mistake="previous iterate overwritten before the step test (stops after one step)"),
    Edit("iekf_update", _PHAT, "P_hat = P_check", keyword="shrink",
         mistake="covariance not updated"),
    Edit("iekf_update", _STOP, "if np.max(np.abs(x_op - x_lin)) > tol:", keyword="until the step",
         mistake="stopping test inverted"),
    Edit("iekf_update", "x_op = x_check\n", "x_op = np.zeros_like(x_check)\n", keyword="x_op = x̌",
         mistake="iteration started from zero instead of x̌"),
    Edit("iekf_update", _GK, "G_k = G(x_op)", keyword="last linearisation point",
         mistake="final covariance from G at the new iterate (wrong when the loop stops at max_iter)"),
    Edit("iekf_update", _RETURN, "return x_lin, 0.5 * (P_hat + P_hat.T), iteration", keyword="newest iterate",
         mistake="x̂ = the last linearisation point (wrong when the loop stops at max_iter)"),
    # dependency-aware hint: a wrong mean step is named, not the loop
    Edit("iekf_update", _NEXT, "x_next = x_op + K @ correction", keyword="fix iekf_mean_step first",
         mistake="mean step from x_op, loop correct", cell="step"),
    Edit("iekf_update", _MEAN_STEP, _EKF_STEP, keyword="fix iekf_mean_step first",
         mistake="the mean step's placeholder left in, loop correct", cell="step"),
    Edit("iekf_update", _NEXT, "x_op[:] = x_check + K @ correction\n    x_next = x_op", keyword="fix iekf_mean_step first",
         mistake="the mean step writes into x_op, which the loop keeps as x_lin (every step then looks like 0)",
         cell="step"),
    # --- iekf_converged (the challenge) ----------------------------------------------------
    Edit("iekf_converged", _DISTANCE, "distance = np.max(np.abs(step))", keyword="own units",
         mistake="the largest absolute change, units mixed (the stub)"),
    Edit("iekf_converged", _DISTANCE, "distance = np.linalg.norm(step)", keyword="own units",
         mistake="the Euclidean length of the step, units mixed"),
    Edit("iekf_converged", _DISTANCE, "distance = np.sqrt(step @ P_check @ step)", keyword="instead of its inverse",
         mistake="the step weighed by P̌, not P̌⁻¹"),
    Edit("iekf_converged", _DISTANCE, "distance = step @ np.linalg.solve(P_check, step)", keyword="squared distance",
         mistake="d² compared with tol"),
    Edit("iekf_converged", _DISTANCE, f"distance = np.max(np.abs(step) / {_STD})", keyword="correlations",
         mistake="each component in its own standard deviations, correlations ignored"),
    Edit("iekf_converged", _DISTANCE, f"distance = np.linalg.norm(step / {_STD})", keyword="correlations",
         mistake="Mahalanobis distance under the diagonal of P̌ only"),
    Edit("iekf_converged", _DISTANCE, "distance = np.max(np.abs(step) / np.diag(P_check))", keyword="variances",
         mistake="each component divided by its variance"),
    Edit("iekf_converged", _VERDICT, "return bool(distance > tol)", keyword="inverted",
         mistake="True when the step is long"),
    Edit("iekf_converged", _VERDICT, "return distance", keyword="True or False",
         mistake="the distance returned, not the verdict"),
    Edit("iekf_converged", _VERDICT, f"return np.abs(step) / {_STD} <= tol",
         keyword="one verdict per state component", mistake="a verdict per component"),
]

EQUIVALENTS = [
    Edit("iekf_mean_step", _GAIN,
         "K = np.linalg.solve(G_op @ P_check @ G_op.T + R, G_op @ P_check).T", mistake="gain by a solve"),
    Edit("iekf_mean_step", _NEXT,
         "x_next = x_op + K @ r + (np.eye(len(x_check)) - K @ G_op) @ (x_check - x_op)",
         mistake="the step written from x_op: x_op + K r + (I − K G)(x̌ − x_op)"),
    Edit("iekf_mean_step", _NEXT, "x_next = x_check + K @ r - K @ G_op @ (x_check - x_op)",
         mistake="the product expanded"),
    Edit("iekf_update", _STOP, "if np.linalg.norm(x_op - x_lin, np.inf) <= tol:", mistake="∞-norm of the step"),
    Edit("iekf_update", _PHAT,
         "I_KG = np.eye(len(x_check)) - K @ G_k\n    P_hat = I_KG @ P_check @ I_KG.T + K @ R @ K.T",
         mistake="Joseph form"),
    Edit("iekf_update", _PHAT, "P_hat = P_check - K @ (G_k @ P_check @ G_k.T + R) @ K.T", mistake="P̌ − K S Kᵀ"),
    Edit("iekf_update", _RETURN, "return [x_op, P_hat, iteration]", mistake="a list, not symmetrised"),
    Edit("iekf_mean_step", _MEAN_STEP,
         "G_op = G(x_op)\n    S = G_op @ P_check @ G_op.T + R\n"
         "    x_next = x_check + P_check @ G_op.T @ np.linalg.solve(S, residual(y, g(x_op)) + G_op @ (x_op - x_check))",
         mistake="the whole step by a solve, the correction written as + G (x_op − x̌)"),
    Edit("iekf_mean_step", _MEAN_STEP,
         "G_op = G(x_op)\n    R_inv = np.linalg.inv(R)\n"
         "    H = np.linalg.inv(P_check) + G_op.T @ R_inv @ G_op\n"
         "    gradient = G_op.T @ R_inv @ residual(y, g(x_op)) - np.linalg.solve(P_check, x_op - x_check)\n"
         "    x_next = x_op + np.linalg.solve(H, gradient)",
         mistake="a Gauss–Newton step on the MAP cost J written from x_op (lecture 06 §2)"),
    # iekf_converged (the challenge)
    Edit("iekf_converged", _DISTANCE, "distance = np.sqrt(step @ np.linalg.inv(P_check) @ step)",
         mistake="P̌⁻¹ by an inverse"),
    Edit("iekf_converged", _DISTANCE, "distance = np.linalg.norm(np.linalg.solve(np.linalg.cholesky(P_check), step))",
         mistake="whitened by the Cholesky factor"),
    Edit("iekf_converged", _VERDICT, "return step @ np.linalg.solve(P_check, step) <= tol**2",
         mistake="d² against tol², a numpy bool"),
    Edit("iekf_converged", "step = np.asarray(x_next, dtype=float) - np.asarray(x_op, dtype=float)",
         "step = x_op - x_next", mistake="the step the other way round"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("iekf_update", _STOP, "if np.max(np.abs(x_op - x_lin)) < tol:",
               reason="a step exactly equal to tol does not occur in floating point on these cases"),
    Equivalent("iekf_mean_step", _GAIN, "K = P_check @ G_op.T @ np.linalg.inv(G_op @ P_check.T @ G_op.T + R)",
               reason="P̌ is symmetric"),
    Equivalent("iekf_converged", _VERDICT, "return bool(distance < tol)",
               reason="no case has a step length within 10 % of tol"),
]

# Mistakes that also make the notebook's demo cell raise (a shape error, NaN, a singular
# matrix): the harness re-runs only later cells' definitions, so the check still sees them.
MUTANTS += [
    Edit("iekf_update", _RETURN, "return 0.5 * (P_hat + P_hat.T), x_op, iteration", keyword="covariance first",
         mistake="(P̂, x̂, iterations) in the wrong order"),
    Edit("iekf_mean_step", _CORR, "correction = r + G_op @ (x_check - x_op)", keyword="sign",
         mistake="+ G (x̌ − x_op)"),
    Edit("iekf_mean_step", _CORR, "correction = r - G_op @ (x_op - x_check)", keyword="sign",
         mistake="x_op − x̌ instead of x̌ − x_op"),
    Edit("iekf_mean_step", _R, "r = residual(g(x_op), y)", keyword="measured minus predicted",
         mistake="residual predicted minus measured"),
    Edit("iekf_mean_step", _GAIN, "K = P_check @ G_op.T @ np.linalg.inv(G_op @ P_check @ G_op.T)",
         keyword="noise R", mistake="R left out of the gain"),
    Edit("iekf_update", _CORR, "correction = r + G_op @ (x_check - x_op)", keyword="fix iekf_mean_step first",
         mistake="mean step with the wrong sign, loop correct", cell="step"),
]

EQUIVALENTS += [
    Edit("iekf_mean_step", "return x_next", "return list(x_next)", mistake="a list"),
]
