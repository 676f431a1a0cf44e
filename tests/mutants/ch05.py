"""Chapter 05 (the EKF): plausible mistakes in radar h(x), its Jacobian, the wrapped residual
and the EKF update (whose measurement may lack entries: NaN in y, not measured), and correct
variants of each."""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "05_ekf"

_PHI = "phi = np.arctan2(py, px)"
_RATE = "rho_dot = (px * v * np.cos(psi) + py * v * np.sin(psi)) / rho"
_BEARING_ROW = "G[1, 0], G[1, 1] = -py / r2, px / r2"
_HEADING = "G[2, 3] = (py * vx - px * vy) / r"
_WRAP = "e[1] = np.pi - np.mod(np.pi - e[1], 2 * np.pi)"
_DIFF = "e = np.asarray(y, dtype=float) - np.asarray(y_pred, dtype=float)"
_MEASURED = "measured = np.isfinite(y)"
_YPRED = "y_pred = g(x_check)"
_INNOVATION = "innovation = residual(np.where(measured, y, y_pred), y_pred)[measured]"
_GK = "G_k = G(x_check)[measured]"
_RK = "R_k = R[np.ix_(measured, measured)]"
_S = "S = G_k @ P_check @ G_k.T + R_k"
_K = "K = P_check @ G_k.T @ np.linalg.inv(S)"
_X = "x_hat = x_check + K @ innovation"
_P = "P_hat = (np.eye(len(x_check)) - K @ G_k) @ P_check"
# the measured entries' residual, rows of G and block of R (NaN entries of y were not measured)
_SELECT = _INNOVATION + "\n    " + _GK + "\n    " + _RK
# the whole update, the exercise's multi-line section
_UPDATE = ("measured = np.isfinite(y)                      # the entries the sensor delivered\n    "
           + _YPRED + "\n    " + _SELECT + "\n    " + _S + "\n    " + _K + "\n    " + _X + "\n    " + _P)
# the lecture's five equations typed in as they stand, for a y without NaN
_LECTURE = ("G_k = G(x_check)\n    S = G_k @ P_check @ G_k.T + R\n    " + _K
            + "\n    innovation = residual(y, g(x_check))\n    " + _X + "\n    " + _P)
# the range rate's derivatives with respect to the CTRV velocity components (v, ψ)
_VELOCITY_COLUMNS = "G[2, 2] = (px * np.cos(psi) + py * np.sin(psi)) / r\n    " + _HEADING

MUTANTS = [
    Edit("radar_jacobian", "r = np.sqrt(r2)", "r = r2", keyword="∂ρ/∂p_x",
         mistake="ρ without the square root in the Jacobian", cell="jac"),
    # --- radar_h -------------------------------------------------------------------------
    Edit("radar_h", _PHI, "phi = np.arctan(py / px)", keyword="atan2",
         mistake="arctan(p_y / p_x) instead of atan2 (quadrant lost for p_x < 0) (the stub)"),
    Edit("radar_h", _PHI, "phi = np.arctan2(px, py)", keyword="swapped",
         mistake="atan2 arguments swapped"),
    Edit("radar_h", _PHI, "phi = np.degrees(np.arctan2(py, px))", keyword="radians",
         mistake="bearing in degrees"),
    Edit("radar_h", "return np.array([rho, phi, rho_dot])", "return np.array([rho, phi, rho_dot], dtype=np.float32)",
         keyword="single precision", mistake="h returned in float32"),
    Edit("radar_h", "rho = np.hypot(px, py)", "px, py, v, psi = (np.float32(c) for c in (px, py, v, psi))\n"
         "    rho = np.hypot(px, py)", keyword="single precision", mistake="h computed in float32 throughout"),
    Edit("radar_h", "return np.array([rho, phi, rho_dot])",
         "return np.array([rho, phi, rho_dot], dtype=np.float32).astype(float)", keyword="single precision",
         mistake="h rounded to float32 and handed back as float64 (the dtype does not show it)"),
    Edit("radar_h", _RATE, "rho_dot = (px * v * np.cos(psi) + py * v * np.sin(psi)) / max(rho, 0.01)",
         keyword="ρ̇ is wrong", mistake="the range rate guarded by max(ρ, 0.01), wrong next to the radar"),
    Edit("radar_h", "rho = np.hypot(px, py)", "rho = px**2 + py**2", keyword="square root",
         mistake="range without the square root"),
    Edit("radar_h", _RATE, "rho_dot = v", keyword="not the speed",
         mistake="range rate = speed, not projected on the line of sight (the stub)"),
    Edit("radar_h", _RATE, "rho_dot = -(px * v * np.cos(psi) + py * v * np.sin(psi)) / rho",
         keyword="moves away", mistake="range rate with the wrong sign"),
    Edit("radar_h", _RATE, "rho_dot = px * v * np.cos(psi) + py * v * np.sin(psi)",
         keyword="divide by ρ", mistake="range rate not divided by ρ"),
    Edit("radar_h", _RATE, "rho_dot = (px * v * np.cos(psi) + py * v * np.sin(psi)) / rho**2",
         keyword="not by ρ²", mistake="range rate divided by ρ²"),
    Edit("radar_h", _RATE, "rho_dot = (px * v * np.sin(psi) + py * v * np.cos(psi)) / rho",
         keyword="cos and sin are swapped", mistake="v_x = v sin ψ, v_y = v cos ψ"),
    Edit("radar_h", _RATE, "rho_dot = (px * v * np.cos(psi) - py * v * np.sin(psi)) / rho",
         keyword="p_y v_y term", mistake="sign of the p_y v_y term"),
    Edit("radar_h", _RATE, "rho_dot = (px * v * np.sin(psi) - py * v * np.cos(psi)) / rho",
         keyword="ρ̇ is wrong", mistake="range rate projected on the normal of the line of sight"),
    Edit("radar_h", "return np.array([rho, phi, rho_dot])", "return np.array([phi, rho, rho_dot])",
         keyword="range first", mistake="measurement order [φ, ρ, ρ̇]"),
    Edit("radar_h", "rho = np.hypot(px, py)", "rho = abs(px) + abs(py)", keyword="the range ρ and the range rate",
         mistake="range as the L1 norm"),
    Edit("radar_h", "return np.array([rho, phi, rho_dot])", "return np.array([rho, phi, rho_dot * rho])",
         keyword="divide by ρ", mistake="range rate multiplied back by ρ"),
    # --- radar_jacobian --------------------------------------------------------------------
    Edit("radar_jacobian", _BEARING_ROW, "G[1, 0], G[1, 1] = py / r2, -px / r2", keyword="signs of the bearing row",
         mistake="bearing row with flipped signs"),
    Edit("radar_jacobian", _BEARING_ROW, "G[1, 0], G[1, 1] = -py / r, px / r", keyword="divided by ρ², not ρ",
         mistake="bearing row divided by ρ"),
    Edit("radar_jacobian", _BEARING_ROW, "G[1, 0], G[1, 1] = -px / r2, py / r2", keyword="swapped in the bearing row",
         mistake="p_x and p_y swapped in the bearing row"),
    Edit("radar_jacobian", _BEARING_ROW, "G[1, 0], G[1, 1] = px / r2, -py / r2", keyword="∂φ/∂p_x",
         mistake="bearing row swapped and negated"),
    Edit("radar_jacobian", _HEADING, "G[2, 3] = 0.0", keyword="not 0",
         mistake="∂ρ̇/∂ψ left at 0"),
    Edit("radar_jacobian", _VELOCITY_COLUMNS, "G[2, 2], G[2, 3] = px / r, py / r", keyword="CV state",
         mistake="the article's CV entries ∂ρ̇/∂v_x, ∂ρ̇/∂v_y used for the CTRV state's v and ψ (the stub)"),
    Edit("radar_jacobian", _VELOCITY_COLUMNS, "G[2, 2] = (px * np.cos(psi) + py * np.sin(psi)) / r\n    G[2, 3] = 0.0",
         keyword="depends on the heading", mistake="∂ρ̇/∂v by the chain rule, ∂ρ̇/∂ψ left at 0"),
    Edit("radar_jacobian", _HEADING, "G[2, 3] = (px * vy - py * vx) / r", keyword="sign of ∂ρ̇/∂ψ",
         mistake="∂ρ̇/∂ψ with the wrong sign"),
    Edit("radar_jacobian", _HEADING, "G[2, 3] = py / r", keyword="CV state",
         mistake="the lecture's CV Jacobian entry ∂ρ̇/∂v_y used as ∂ρ̇/∂ψ"),
    Edit("radar_jacobian", "G[2, 2] = (px * np.cos(psi) + py * np.sin(psi)) / r", "G[2, 2] = px / r",
         keyword="CV state", mistake="the lecture's CV Jacobian entry ∂ρ̇/∂v_x used as ∂ρ̇/∂v"),
    Edit("radar_jacobian", "G[2, 2] = (px * np.cos(psi) + py * np.sin(psi)) / r",
         "G[2, 2] = px * np.cos(psi) + py * np.sin(psi)", keyword="∂ρ̇/∂v",
         mistake="∂ρ̇/∂v not divided by ρ"),
    Edit("radar_jacobian", "G[0, 0], G[0, 1] = px / r, py / r", "G[0, 0], G[0, 1] = px / r2, py / r2",
         keyword="unit vector", mistake="range row divided by ρ²", cell="jac"),
    Edit("radar_jacobian", "G[2, 0] = py * (vx * py - vy * px) / r**3", "G[2, 0] = py * (vx * py - vy * px) / r2",
         keyword="∂ρ̇/∂p_x", mistake="∂ρ̇/∂p_x over ρ² instead of ρ³", cell="jac"),
    Edit("radar_jacobian", "G[2, 1] = px * (vy * px - vx * py) / r**3", "G[2, 1] = px * (vx * py - vy * px) / r**3",
         keyword="∂ρ̇/∂p_y", mistake="∂ρ̇/∂p_y with the wrong sign", cell="jac"),
    Edit("radar_jacobian", "vx, vy = v * np.cos(psi), v * np.sin(psi)", "vx, vy = v * np.sin(psi), v * np.cos(psi)",
         keyword="∂ρ̇/∂", mistake="v_x, v_y with sin and cos swapped", cell="jac"),
    Edit("radar_jacobian", "return G",
         "return np.array([(radar_h(x + d) - radar_h(x)) / 1e-2 for d in 1e-2 * np.eye(5)]).T",
         keyword="central difference", mistake="forward difference with a step of 1e-2 (too coarse)", cell="jac"),
    # --- radar_residual --------------------------------------------------------------------
    Edit("radar_residual", _WRAP, "e[1] = e[1]", keyword="must be wrapped",
         mistake="bearing not wrapped (the stub)"),
    Edit("radar_residual", _DIFF, "e = np.asarray(y_pred, dtype=float) - np.asarray(y, dtype=float)",
         keyword="measured minus predicted", mistake="predicted minus measured"),
    Edit("radar_residual", _WRAP, "e[1] = np.mod(e[1], 2 * np.pi)", keyword="[0, 2π)",
         mistake="wrapped into [0, 2π)"),
    Edit("radar_residual", _WRAP, "e[1] = e[1] - 2 * np.pi if e[1] > np.pi else e[1]", keyword="both directions",
         mistake="wrapped only above π"),
    Edit("radar_residual", _WRAP, "e[1] = e[1] + 2 * np.pi if e[1] < -np.pi else e[1]", keyword="both directions",
         mistake="wrapped only below −π"),
    Edit("radar_residual", _WRAP, "e[1] = e[1] - 2 * np.pi if abs(e[1]) > np.pi else e[1]",
         keyword="both directions", mistake="always subtracts 2π when |Δφ| > π"),
    Edit("radar_residual", _WRAP, "e = np.pi - np.mod(np.pi - e, 2 * np.pi)", keyword="only the bearing",
         mistake="every component wrapped"),
    Edit("radar_residual", _WRAP, "e[0] = np.pi - np.mod(np.pi - e[0], 2 * np.pi)", keyword="not the range",
         mistake="wrapped index 0 instead of 1"),
    Edit("radar_residual", _WRAP, "e[2] = np.pi - np.mod(np.pi - e[2], 2 * np.pi)", keyword="not the range rate",
         mistake="wrapped index 2 instead of 1"),
    Edit("radar_residual", _WRAP, "e[1] = np.arctan(np.tan(e[1]))", keyword="not π",
         mistake="arctan(tan(Δφ)): period π"),
    Edit("radar_residual", _WRAP, "e[1] = np.pi / 2 - np.mod(np.pi / 2 - e[1], np.pi)", keyword="not π",
         mistake="wrapped with period π"),
    Edit("radar_residual", _WRAP, "e[1] = 180 - np.mod(180 - e[1], 360)", keyword="must be wrapped",
         mistake="wrapped in degrees"),
    Edit("radar_residual", _WRAP, "e[1] = np.fmod(e[1], 2 * np.pi)", keyword="must be wrapped",
         mistake="fmod by 2π (does nothing to differences inside (−2π, 2π))"),
    Edit("radar_residual", _WRAP, "e[1] = np.pi - np.mod(np.pi - y[1], 2 * np.pi) - y_pred[1]",
         keyword="must be wrapped", mistake="the measured bearing wrapped, not the difference"),
    # --- ekf_update ------------------------------------------------------------------------
    Edit("ekf_update", _YPRED, "y_pred = G(x_check) @ x_check", keyword="g(x̌)",
         mistake="predicted measurement G x̌"),
    Edit("ekf_update", _UPDATE, "x_hat, P_hat = x_check, P_check", keyword="measurement was not used",
         mistake="the posterior is the prior, the measurement ignored (the stub of the whole update)"),
    Edit("ekf_update", _X, "x_hat = x_check", keyword="measurement was not used",
         mistake="covariance updated, mean left at the prior"),
    Edit("ekf_update", _INNOVATION, "innovation = (y - G(x_check) @ x_check)[measured]", keyword="nonlinear model",
         mistake="the linear KF's residual y − G x̌"),
    Edit("ekf_update", _INNOVATION, "innovation = (y - y_pred)[measured]", keyword="residual function",
         mistake="plain difference instead of the residual function"),
    Edit("ekf_update", _INNOVATION, "innovation = residual(y_pred, np.where(measured, y, y_pred))[measured]",
         keyword="sign", mistake="residual predicted minus measured"),
    # --- ekf_update: the entries of y that were not measured (NaN) -------------------------
    Edit("ekf_update", _UPDATE, _LECTURE, keyword="full-length vectors of numbers",
         mistake="the lecture's equations as they stand: the NaN of a missing entry handed to the residual"),
    Edit("ekf_update", _SELECT, "innovation = residual(np.where(measured, y, y_pred), y_pred)\n    "
         "G_k = G(x_check)\n    R_k = R", keyword="residual of 0",
         mistake="missing entries filled with the prediction and kept: a residual of 0 that shrinks P̂"),
    Edit("ekf_update", _SELECT, "innovation = residual(np.nan_to_num(y), y_pred)\n    G_k = G(x_check)\n    R_k = R",
         keyword="number 0", mistake="NaN set to 0 (np.nan_to_num) and kept as a measurement of 0"),
    Edit("ekf_update", _SELECT, "innovation = residual(np.where(measured, y, y_pred), y_pred)\n    "
         "G_k = G(x_check) * measured[:, None]\n    R_k = R", keyword="correlations",
         mistake="the missing rows of G zeroed, R kept whole (its correlations change the gain)"),
    Edit("ekf_update", _RK, "R_k = R[measured]", keyword="both the rows and the columns",
         mistake="R's rows of the measured entries, all its columns (a shape error)"),
    Edit("ekf_update", _RK, "R_k = np.diag(np.diag(R)[measured])", keyword="diagonal",
         mistake="the measured entries' variances alone, R's correlations dropped"),
    Edit("ekf_update", _INNOVATION, "innovation = residual(y[measured], y_pred[measured])", keyword="by its position",
         mistake="the residual function called on the shortened vectors (the bearing is no longer entry 1)"),
    Edit("ekf_update", _MEASURED, "measured = np.isfinite(y)\n    if not measured.all():\n"
         "        return x_check.copy(), P_check.copy()", keyword="the others were measured",
         mistake="any missing entry makes the whole measurement be skipped"),
    Edit("ekf_update", _UPDATE, _LECTURE.replace("G_k = G(x_check)", "y = np.nan_to_num(y)\n    G_k = G(x_check)"),
         keyword="number 0", mistake="the lecture's equations with NaN replaced by 0 first"),
    Edit("ekf_update", _X, "x_hat = x_check - K @ innovation", keyword="sign",
         mistake="correction subtracted"),
    Edit("ekf_update", _X, "x_hat = K @ innovation", keyword="prior mean x̌ is missing",
         mistake="prior mean left out of x̂"),
    Edit("ekf_update", _S, "S = G_k @ P_check @ G_k.T", keyword="noise R",
         mistake="R left out of S"),
    Edit("ekf_update", _S, "S = G_k @ P_check @ G_k.T + np.sqrt(R_k)", keyword="variances",
         mistake="√R (standard deviations) in S"),
    Edit("ekf_update", _S, "S = G_k @ P_check @ G_k.T + R_k @ R_k", keyword="squares it",
         mistake="R R in S"),
    Edit("ekf_update", _S, "S = G_k @ P_check @ G_k.T + np.diag(np.diag(R_k))", keyword="diagonal",
         mistake="only the diagonal of R"),
    Edit("ekf_update", _K, "K = G_k.T @ np.linalg.inv(S)", keyword="factor P̌",
         mistake="P̌ missing from the gain"),
    Edit("ekf_update", _P, "P_hat = P_check", keyword="shrink",
         mistake="covariance not updated"),
    Edit("ekf_update", _P, "P_hat = np.eye(len(x_check)) - K @ G_k", keyword="product with P̌",
         mistake="(I − K G) without P̌"),
    Edit("ekf_update", _P, "P_hat = (np.eye(len(x_check)) + K @ G_k) @ P_check", keyword="minus, not plus",
         mistake="(I + K G) P̌"),
    Edit("ekf_update", _P, "P_hat = K @ G_k @ P_check", keyword="part that is removed",
         mistake="K G P̌"),
    Edit("ekf_update", _P, "P_hat = (np.eye(len(x_check)) - K @ G_k) @ P_check @ (np.eye(len(x_check)) - K @ G_k).T",
         keyword="K R Kᵀ", mistake="Joseph form without K R Kᵀ"),
    Edit("ekf_update", _P, "P_hat = (np.eye(len(x_check)) - K @ G(x_hat)[measured]) @ P_check",
         keyword="linearisation point",
         mistake="G re-evaluated at x̂ for the covariance"),
    # the caller's arrays changed in place (the values are right: the harness names the side effect)
    Edit("ekf_update", _X, "x_check += K @ innovation\n    x_hat = x_check", keyword="in place",
         mistake="x̌ corrected in place (x_check += K @ e)"),
    Edit("ekf_update", _P, "P_check -= K @ G_k @ P_check\n    P_hat = P_check", keyword="in place",
         mistake="P̂ written into the caller's P̌"),
    Edit("radar_residual", _DIFF, "e = y\n    e -= np.asarray(y_pred, dtype=float)", keyword="in place",
         mistake="the residual subtracted into the caller's measurement"),
]

EQUIVALENTS = [
    # radar_h
    Edit("radar_h", _PHI, "import math\n    phi = math.atan2(py, px)", mistake="math.atan2"),
    Edit("radar_h", _PHI, "phi = np.angle(px + 1j * py)", mistake="bearing as the angle of a complex number"),
    # the bearing is a point on the circle and every use of h wraps the residual (checks/ekf.py)
    Edit("radar_h", _PHI, "phi = np.arctan2(py, px) % (2 * np.pi)", mistake="bearing in [0, 2π) instead of (−π, π]"),
    Edit("radar_h", _RATE, "rho_dot = v * np.cos(psi - phi)", mistake="ρ̇ = v cos(ψ − φ)"),
    Edit("radar_h", "rho = np.hypot(px, py)", "rho = np.sqrt(px**2 + py**2)", mistake="√(p_x² + p_y²)"),
    Edit("radar_h", "return np.array([rho, phi, rho_dot])", "return [rho, phi, rho_dot]", mistake="a list"),
    Edit("radar_h", "return np.array([rho, phi, rho_dot])", "return rho, phi, rho_dot", mistake="a tuple"),
    # radar_jacobian: the seed lecture's c1, c2, c3 and finite differences (tolerance in the check)
    Edit("radar_jacobian", "G[2, 0] = py * (vx * py - vy * px) / r**3", "G[2, 0] = py * (vx * py - vy * px) / (r2 * r)",
         mistake="the lecture's c3 = c1 c2", cell="jac"),
    Edit("radar_jacobian", _HEADING, "G[2, 3] = v * np.sin(np.arctan2(py, px) - psi)", mistake="∂ρ̇/∂ψ = v sin(φ − ψ)"),
    Edit("radar_jacobian", "return G",
         "return np.array([(radar_h(x + d) - radar_h(x - d)) / 2e-6 for d in 1e-6 * np.eye(5)]).T",
         mistake="central difference, h = 1e-6", cell="jac"),
    Edit("radar_jacobian", "return G",
         "return np.array([(radar_h(x + d) - radar_h(x)) / 1e-6 for d in 1e-6 * np.eye(5)]).T",
         mistake="forward difference, h = 1e-6", cell="jac"),
    Edit("radar_jacobian", "return G",
         "return np.array([(radar_h(x + d) - radar_h(x)) / 1e-5 for d in 1e-5 * np.eye(5)]).T",
         mistake="forward difference, h = 1e-5", cell="jac"),
    Edit("radar_jacobian", "return G",
         "return np.array([(radar_h(x + d) - radar_h(x - d)) / 2e-4 for d in 1e-4 * np.eye(5)]).T",
         mistake="central difference, h = 1e-4", cell="jac"),
    # radar_residual: the seed lecture's while loops, and other correct wraps
    Edit("radar_residual", _WRAP, "while e[1] > np.pi:\n        e[1] -= 2 * np.pi\n"
         "    while e[1] <= -np.pi:\n        e[1] += 2 * np.pi", mistake="the lecture's while loops"),
    Edit("radar_residual", _WRAP, "e[1] = np.arctan2(np.sin(e[1]), np.cos(e[1]))", mistake="atan2(sin, cos)"),
    Edit("radar_residual", _WRAP, "e[1] = (e[1] + np.pi) % (2 * np.pi) - np.pi", mistake="wrap into [−π, π)"),
    Edit("radar_residual", _WRAP, "e[1] = np.angle(np.exp(1j * e[1]))", mistake="angle of a unit complex number"),
    Edit("radar_residual", _WRAP, "if e[1] > np.pi:\n        e[1] -= 2 * np.pi\n"
         "    elif e[1] <= -np.pi:\n        e[1] += 2 * np.pi", mistake="one if/elif"),
    Edit("radar_residual", "return e", "return list(e)", mistake="a list"),
    # ekf_update
    Edit("ekf_update", _K, "K = np.linalg.solve(S, G_k @ P_check).T", mistake="gain by a solve"),
    Edit("ekf_update", _K, "K = np.linalg.solve(S.T, (P_check @ G_k.T).T).T", mistake="gain by a solve of Sᵀ"),
    Edit("ekf_update", _K, "K = P_check @ G_k.T @ np.linalg.pinv(S)", mistake="pseudo-inverse"),
    Edit("ekf_update", _K, "L = np.linalg.cholesky(S)\n    K = np.linalg.solve(L.T, np.linalg.solve(L, G_k @ P_check)).T",
         mistake="Cholesky solve"),
    Edit("ekf_update", _P, "I_KG = np.eye(len(x_check)) - K @ G_k\n    P_hat = I_KG @ P_check @ I_KG.T + K @ R_k @ K.T",
         mistake="Joseph form"),
    Edit("ekf_update", _P, "P_hat = P_check - K @ S @ K.T", mistake="P̌ − K S Kᵀ"),
    Edit("ekf_update", _P, "P_hat = P_check - K @ G_k @ P_check", mistake="P̌ − K G P̌"),
    Edit("ekf_update", "return x_hat, 0.5 * (P_hat + P_hat.T)", "return [x_hat, P_hat]",
         mistake="a list, not symmetrised"),
    Edit("ekf_update", _X, "x_hat = x_check + np.einsum('ij,j->i', K, innovation)", mistake="einsum"),
    Edit("ekf_update", _X, "x_hat = x_check + P_check @ G_k.T @ np.linalg.solve(S, innovation)",
         mistake="S⁻¹ r by a solve"),
    Edit("ekf_update", _UPDATE,
         "m = ~np.isnan(y)\n    y_pred = g(x_check)\n    G_k = G(x_check)[m]\n"
         "    R_inv = np.linalg.inv(R[m][:, m])\n"
         "    P_hat = np.linalg.inv(np.linalg.inv(P_check) + G_k.T @ R_inv @ G_k)\n"
         "    x_hat = x_check + P_hat @ G_k.T @ R_inv @ residual(np.where(m, y, 0.0), y_pred)[m]",
         mistake="the whole update in information form (np.isnan, R[m][:, m], the missing entries filled with 0)"),
    Edit("ekf_update", _UPDATE,
         "idx = np.flatnonzero(np.isfinite(y))\n    y_full = np.array(y, dtype=float)\n"
         "    y_full[np.isnan(y_full)] = g(x_check)[np.isnan(y_full)]\n"
         "    G_k = G(x_check)[idx]\n    PGt = P_check @ G_k.T\n"
         "    K = np.linalg.solve(G_k @ PGt + R[np.ix_(idx, idx)], PGt.T).T\n"
         "    x_hat = x_check + K @ residual(y_full, g(x_check))[idx]\n    P_hat = P_check - K @ G_k @ P_check",
         mistake="the whole update with indices, a solve and P̌ − K G P̌"),
    Edit("ekf_update", _UPDATE,
         "measured = np.isfinite(y)\n    if not measured.any():\n        return x_check.copy(), P_check.copy()\n"
         "    " + _YPRED + "\n    " + _SELECT + "\n    " + _S + "\n    " + _K + "\n    " + _X + "\n    " + _P,
         mistake="nothing measured handled on its own: the prior, copied"),
    Edit("ekf_update", _SELECT, "innovation = residual(np.where(measured, y, y_pred), y_pred)\n    G_k = G(x_check)\n"
         "    R_k = R.copy()\n    R_k[~measured, :] = 0.0\n    R_k[:, ~measured] = 0.0\n"
         "    R_k[~measured, ~measured] = 1e12",
         mistake="missing entries kept with a residual of 0 and a variance of 1e12, uncorrelated (an approximation "
                 "within the tolerance: 1e-12 relative)"),
    Edit("ekf_update", _MEASURED, "measured = ~np.isnan(y)", mistake="~np.isnan instead of np.isfinite"),
    Edit("radar_residual", _WRAP, "e[1] = np.unwrap([0.0, e[1]])[1]", mistake="numpy's unwrap"),
    Edit("radar_h", _RATE, "rho_dot = np.dot([px, py], [v * np.cos(psi), v * np.sin(psi)]) / np.linalg.norm([px, py])",
         mistake="ρ̇ by a dot product and a norm"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("radar_h", "px, py, v, psi, _ = x", "px, py, v, psi, omega = x",
               reason="naming the unused turn rate changes nothing"),
    Equivalent("radar_jacobian", "G = np.zeros((3, 5))", "G = np.zeros((3, 5))\n    G[:, 4] = 0.0",
               reason="the ω column is already zero", cell="jac"),
    Equivalent("radar_residual", _DIFF, "e = np.array(y, dtype=float) - np.array(y_pred, dtype=float)",
               reason="asarray vs array: the difference is a new array either way"),
    Equivalent("ekf_update", "return x_hat, 0.5 * (P_hat + P_hat.T)", "return x_hat, P_hat",
               reason="(I − K G) P̌ with the optimal gain is symmetric to round-off; the check allows round-off"),
    Equivalent("ekf_update", _K, "K = P_check @ G_k.T @ np.linalg.inv(S).T",
               reason="S is symmetric, so S⁻ᵀ = S⁻¹"),
]

# Mistakes that also make the notebook's demo cell raise (a shape error, NaN, a singular
# matrix): the harness re-runs only later cells' definitions, so the check still sees them.
MUTANTS += [
    Edit("ekf_update", "return x_hat, 0.5 * (P_hat + P_hat.T)", "return 0.5 * (P_hat + P_hat.T), x_hat",
         keyword="covariance first", mistake="(P̂, x̂) returned in the wrong order"),
    Edit("radar_jacobian", "return G", "return G.T", keyword="transpose",
         mistake="the Jacobian returned transposed, (5, 3)", cell="jac"),
    Edit("radar_jacobian", "return G", "return G[:, :4]", keyword="ω column",
         mistake="4 columns, as in the lecture's CV Jacobian", cell="jac"),
    Edit("ekf_update", _X, "x_hat = x_check + innovation @ K", keyword="Kᵀ",
         mistake="r @ K instead of K @ r"),
    Edit("ekf_update", _S, "S = G_k @ P_check @ G_k + R_k", keyword="transpose",
         mistake="G P̌ G instead of G P̌ Gᵀ"),
    Edit("ekf_update", _K, "K = P_check @ G_k.T @ np.linalg.inv(R_k)", keyword="R⁻¹",
         mistake="R⁻¹ instead of S⁻¹"),
    Edit("ekf_update", _K, "K = P_check @ G_k.T @ S", keyword="inverse",
         mistake="S instead of S⁻¹"),
    Edit("ekf_update", _P, "P_hat = (np.eye(len(x_check)) - G_k @ K) @ P_check", keyword="not G K",
         mistake="(I − G K) P̌"),
    Edit("ekf_update", _P, "P_hat = P_check - K @ S @ K", keyword="transpose",
         mistake="P̌ − K S K (transpose missing)"),
]

EQUIVALENTS += [
    Edit("radar_jacobian", "return G", "return G.tolist()", mistake="nested list", cell="jac"),
]
