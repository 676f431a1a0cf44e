"""Chapter 03 (the Kalman filter): plausible mistakes in the exercise's functions.

Each mutant is one learner mistake written into the reference solution; each equivalent a
correct way to write the same step. The cells: ``cv`` (cv_matrices), ``predict``,
``gain``, ``update`` (its fix region is the whole update), ``run`` (run_gnss_kf) and the
challenge's ``gaps`` (run_gnss_kf_gaps). B is the process-noise Jacobian, G the
observation Jacobian. Each stub of the exercise is a mutant here too, marked "(the stub)":
its edit turns the solution cell into the exercise's cell. Tolerances are stated in
``kalman_course/checks/kf.py``: rtol 1e-7 for the step functions (every correct variant
below agrees to ~1e-13), rtol 1e-6 for the runs.
"""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "03_kalman_filter"

Q = "Q = B @ (sigma_a**2 * I) @ B.T"
NOISE_JACOBIAN = "B = np.vstack([0.5 * T**2 * I, T * I])"
F = "F = np.block([[I, T * I], [np.zeros((dim, dim)), I]])"
PRED_P = "P_check = F @ P_hat @ F.T + Q"
PRED_X = "x_check = F @ x_hat"
S = "S = G @ P_check @ G.T + R"
K = "K = P_check @ G.T @ np.linalg.inv(S)"
INNOV = "innovation = y - G @ x_check"
XHAT = "x_hat = x_check + K @ innovation"
I_KG = "I_KG = np.eye(len(x_check)) - K @ G"
JOSEPH = "P_hat = I_KG @ P_check @ I_KG.T + K @ R @ K.T"
# the whole update (the exercise's fix region) and its placeholder stub
UPDATE_STEP = f"{INNOV}\n    {XHAT}\n    {I_KG}\n    {JOSEPH}"
RET_UPDATE = "return x_hat, 0.5 * (P_hat + P_hat.T)"
R_RUN = "R = sigma_gnss**2 * np.eye(3)"
P0 = "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])"
X0 = "x = np.r_[y[0], np.zeros(3)]"
CV_CALL = "F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)"
UPDATE_CALL = "x, P = kf_update(x, P, y[k], G, R)"
LOOP = "for k in range(1, len(t)):"
STORE = "xs, Ps = [x], [P]"
# the challenge's start: run_gnss_kf's row 0
GAP_START = ("x_first, P_first = run_gnss_kf(t[:1], y[:1], sigma_a, sigma_gnss, sigma_v0)\n"
             "    x, P = x_first[0], P_first[0]            # your run_gnss_kf's belief at t[0] (its row 0)")
# the challenge's loop body (run_gnss_kf_gaps)
GAP_STEP = ("F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n        x, P = kf_predict(x, P, F, Q)\n"
            "        if not np.all(np.isnan(y[k])):\n            x, P = kf_update(x, P, y[k], G, R)")

MUTANTS = [
    # --- cv_process_noise: cv_matrices(T, sigma_a) -> (F, Q) -------------------------------
    Edit("cv_process_noise", f"{NOISE_JACOBIAN}\n    {Q}", "Q = sigma_a**2 * np.eye(2 * dim)",
         keyword="process-noise Jacobian B",
         mistake="Q = σ_a² I, the acceleration's variance put on the state (the stub)"),
    Edit("cv_process_noise", Q, "Q = B @ (sigma_a * I) @ B.T",
         keyword="square it", mistake="σ_a not squared"),
    Edit("cv_process_noise", Q, "Q = B @ (sigma_a**4 * I) @ B.T",
         keyword="squared twice", mistake="σ_a squared twice"),
    Edit("cv_process_noise", Q, "Q = sigma_a**2 * B.T @ B",
         keyword="Bᵀ B", mistake="Bᵀ B (3, 3) instead of B Bᵀ (6, 6)"),
    Edit("cv_process_noise", Q, "Q = B @ (sigma_a**2 * np.eye(2 * dim)) @ B.T",
         keyword="(3, 3)", mistake="the acceleration's covariance written (6, 6) (a shape error)"),
    Edit("cv_process_noise", NOISE_JACOBIAN, "B = np.hstack([0.5 * T**2 * I, T * I])",
         keyword="(6, 3)", mistake="B built side by side, (3, 6) (a shape error)"),
    Edit("cv_process_noise", NOISE_JACOBIAN, "B = np.vstack([T * I, 0.5 * T**2 * I])",
         keyword="swapped", mistake="the blocks of B swapped"),
    Edit("cv_process_noise", NOISE_JACOBIAN, "B = np.vstack([T**2 * I, T * I])",
         keyword="position block of B", mistake="½ missing in the position block of B"),
    Edit("cv_process_noise", NOISE_JACOBIAN, "B = np.vstack([0.5 * T * I, T * I])",
         keyword="position block of B", mistake="T instead of T² in the position block of B"),
    Edit("cv_process_noise", NOISE_JACOBIAN, "B = np.vstack([0.5 * T**2 * I, I])",
         keyword="block of B", mistake="T missing in the velocity block of B"),
    Edit("cv_process_noise", NOISE_JACOBIAN, "B = np.vstack([0.5 * I, I])",
         keyword="time step", mistake="B written for T = 1"),
    Edit("cv_process_noise", Q, "Q = sigma_a**2 * np.diag(np.diag(B @ B.T))",
         keyword="cross terms", mistake="only the diagonal of B Bᵀ"),
    Edit("cv_process_noise", Q,
         "Q = sigma_a**2 * np.block([[T**3 / 3 * I, T**2 / 2 * I], [T**2 / 2 * I, T * I]])",
         keyword="continuous", mistake="the continuous-white-noise Q"),
    Edit("cv_process_noise", Q,
         "Q = sigma_a**2 * np.block([[T**4 / 4 * I, T**3 / 3 * I], [T**3 / 3 * I, T**2 * I]])",
         keyword="position–velocity", mistake="T³/3 in the cross blocks (unlisted: named by block)"),
    Edit("cv_process_noise", F, "F = np.block([[I, np.zeros((dim, dim))], [T * I, I]])",
         keyword="transposed", mistake="F transposed"),
    Edit("cv_process_noise", F, "F = np.block([[I, I], [np.zeros((dim, dim)), I]])",
         keyword="T · v", mistake="T missing in F"),
    Edit("cv_process_noise", "return F, Q", "return Q, F",
         keyword="order (F, Q)", mistake="(Q, F) returned"),

    # very short and very long steps (the sweep after the three cases)
    Edit("cv_process_noise", Q,
         "Q = B @ (sigma_a**2 * I) @ B.T if T >= 1e-3 else np.zeros((2 * dim, 2 * dim))",
         keyword="very short and very long", mistake="no process noise below a cut-off of 1 ms"),
    Edit("cv_process_noise", Q,
         "Q = B @ (sigma_a**2 * I) @ B.T\n    if T < 1e-2:  # short step: the velocity block dominates\n"
         "        Q = sigma_a**2 * np.block([[np.zeros((dim, dim)), np.zeros((dim, dim))], "
         "[np.zeros((dim, dim)), T**2 * I]])",
         keyword="very short and very long", mistake="only the velocity block kept for short steps"),
    Edit("cv_process_noise", NOISE_JACOBIAN,
         "T_noise = min(T, 10.0)  # longer steps: the acceleration is not held\n"
         "    B = np.vstack([0.5 * T_noise**2 * I, T_noise * I])",
         keyword="very short and very long", mistake="the step capped at 10 s in B"),
    # --- kf_predict ------------------------------------------------------------------------
    Edit("kf_predict", PRED_P, "P_check = F @ (P_hat + Q) @ F.T",
         keyword="propagated through F", mistake="Q added before the propagation, so propagated "
                                                "through F (the stub)"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat @ F.T",
         keyword="process noise", mistake="Q left out of the prediction"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat @ F + Q",
         keyword="transpose", mistake="F P̂ F + Q"),
    Edit("kf_predict", PRED_P, "P_check = F.T @ P_hat @ F + Q",
         keyword="order", mistake="Fᵀ P̂ F + Q"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat @ F.T - Q",
         keyword="sign", mistake="Q subtracted"),
    Edit("kf_predict", PRED_P, "P_check = P_hat + Q",
         keyword="F is missing", mistake="P̂ not propagated through F"),
    Edit("kf_predict", PRED_P, "P_check = P_hat",
         keyword="P̌ equals P̂", mistake="the covariance not predicted at all"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat + Q",
         keyword="Fᵀ is missing", mistake="F P̂ + Q"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat @ F.T + F @ Q @ F.T",
         keyword="propagated through F", mistake="Q propagated through F, as a second term"),
    Edit("kf_predict", PRED_P, "P_check = F * P_hat * F.T + Q",
         keyword="element-wise", mistake="* instead of @"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat @ F.T + np.sqrt(Q)",
         keyword="square root", mistake="√Q added"),
    Edit("kf_predict", PRED_P, "P_check = F @ P_hat @ F.T + Q @ Q",
         keyword="Q Q", mistake="Q Q added"),
    Edit("kf_predict", PRED_X, "x_check = F.T @ x_hat",
         keyword="Fᵀ x̂", mistake="x̌ = Fᵀ x̂", cell="predict"),
    Edit("kf_predict", PRED_X, "x_check = x_hat @ F",
         keyword="Fᵀ x̂", mistake="x̂ @ F", cell="predict"),
    Edit("kf_predict", PRED_X, "x_check = x_hat",
         keyword="x̌ equals x̂", mistake="the mean not predicted", cell="predict"),
    Edit("kf_predict", PRED_X, "x_check = F * x_hat",
         keyword="A @ x", mistake="F * x̂ (broadcasts to a matrix)", cell="predict"),
    Edit("kf_predict", "return x_check, P_check", "return P_check, x_check",
         keyword="in the order", mistake="(P̌, x̌) returned"),

    # --- kf_gain ---------------------------------------------------------------------------
    Edit("kf_gain", f"{S}\n    {K}", "S = R\n    K = np.linalg.solve(S, G @ P_check)",
         keyword="leaves out the prior", mistake="S = R, and Kᵀ from a solve (the stub)"),
    Edit("kf_gain", S, "S = R",
         keyword="leaves out the prior", mistake="S = R: the prior's uncertainty left out"),
    Edit("kf_gain", K, "K = np.linalg.solve(S, G @ P_check)",
         keyword="which is Kᵀ", mistake="solve(S, G P̌) = S⁻¹ G P̌ = Kᵀ returned as K"),
    Edit("kf_gain", K, "K = P_check @ G.T @ np.linalg.inv(R)",
         keyword="R⁻¹", mistake="R⁻¹ instead of S⁻¹"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T",
         keyword="noise is missing", mistake="R missing in S"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T + np.sqrt(R)",
         keyword="√R", mistake="S = G P̌ Gᵀ + √R (element-wise)"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T + R @ R",
         keyword="R R", mistake="S = G P̌ Gᵀ + R R"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T + R**2",
         keyword="R**2", mistake="S = G P̌ Gᵀ + R**2 (element-wise)"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T + np.linalg.inv(R)",
         keyword="inverse R⁻¹", mistake="S = G P̌ Gᵀ + R⁻¹"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T + np.eye(len(R))",
         keyword="identity", mistake="S with I in place of R"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T - R",
         keyword="sign", mistake="R subtracted in S"),
    Edit("kf_gain", S, "S = G.T @ P_check @ G + R",
         keyword="transposes", mistake="Gᵀ P̌ G (a shape error)"),
    Edit("kf_gain", K, "K = P_check @ G.T @ np.linalg.inv(G @ P_check @ G.T)",
         keyword="R is missing", mistake="R missing in the gain only"),
    Edit("kf_gain", K, "K = P_check @ G.T @ S",
         keyword="invert S", mistake="S instead of S⁻¹"),
    Edit("kf_gain", K, "K = G.T @ np.linalg.inv(S)",
         keyword="P̌ is missing", mistake="P̌ left out of the gain"),
    Edit("kf_gain", K, "K = np.linalg.inv(S) @ G @ P_check",
         keyword="transpose", mistake="Kᵀ = S⁻¹ G P̌ returned as K"),
    Edit("kf_gain", K, "K = P_check @ G.T / S",
         keyword="not a division", mistake="a division by the matrix S (the seed's fraction notation)"),
    Edit("kf_gain", K, "K = P_check @ G.T * np.linalg.inv(S)",
         keyword="@ (not *)", mistake="element-wise product with S⁻¹"),
    Edit("kf_gain", K, "K = P_check @ G.T @ np.linalg.inv(G @ P_check @ G.T + R @ R)",
         keyword="in the gain: R already", mistake="S right, but R R in the gain's own S"),
    Edit("kf_gain", "return K, S", "return S, K",
         keyword="in the order", mistake="(S, K) returned"),

    # --- kf_update -------------------------------------------------------------------------
    Edit("kf_update", UPDATE_STEP, "x_hat, P_hat = x_check, P_check",
         keyword="the measurement y was not used", mistake="the prior returned unchanged (the stub)"),
    Edit("kf_update", INNOV, "innovation = y - x_check[:len(y)]",
         keyword="measurement space", mistake="predicted measurement x̌[:m] instead of G x̌"),
    Edit("kf_update", I_KG, "I_KG = np.eye(len(y)) - K @ G",
         keyword="I − K G is (n, n)", mistake="I of the measurement's size (a shape error)"),
    Edit("kf_update", INNOV, "innovation = G @ x_check - y",
         keyword="sign", mistake="innovation G x̌ − y"),
    Edit("kf_update", XHAT, "x_hat = x_check - K @ innovation",
         keyword="sign", mistake="correction subtracted"),
    Edit("kf_update", INNOV, "innovation = y",
         keyword="predicted measurement", mistake="G x̌ not subtracted"),
    Edit("kf_update", XHAT, "x_hat = x_check",
         keyword="equals the prior", mistake="mean not updated"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T",
         keyword="second term", mistake="Joseph form without K R Kᵀ"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K @ K.T",
         keyword="not K Kᵀ", mistake="Joseph form with K Kᵀ"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K @ np.linalg.inv(R) @ K.T",
         keyword="K R⁻¹ Kᵀ", mistake="Joseph form with R⁻¹"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K @ S @ K.T",
         keyword="K S Kᵀ", mistake="Joseph form with S"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K @ np.sqrt(R) @ K.T",
         keyword="K √R Kᵀ", mistake="Joseph form with √R"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K @ R @ R @ K.T",
         keyword="K R R Kᵀ", mistake="Joseph form with R R"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T - K @ R @ K.T",
         keyword="sign", mistake="K R Kᵀ subtracted"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG.T @ P_check @ I_KG + K @ R @ K.T",
         keyword="wrong side", mistake="(I − K G)ᵀ P̌ (I − K G)"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG + K @ R @ K.T",
         keyword="transpose missing", mistake="(I − K G) P̌ (I − K G)"),
    Edit("kf_update", JOSEPH, "P_hat = P_check - K @ G",
         keyword="multiply by P̌", mistake="P̌ − K G"),
    Edit("kf_update", JOSEPH, "P_hat = P_check",
         keyword="equals the prior", mistake="covariance not updated"),
    Edit("kf_update", JOSEPH, "P_hat = P_check + K @ G @ P_check",
         keyword="shrinks", mistake="P̌ + K G P̌"),
    Edit("kf_update", JOSEPH, "P_hat = P_check @ I_KG",
         keyword="order", mistake="P̌ (I − K G)"),
    Edit("kf_update", JOSEPH, "P_hat = P_check - K @ R @ K.T",
         keyword="with S, not R", mistake="P̌ − K R Kᵀ"),
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K.T @ R @ K",
         keyword="shapes", mistake="Kᵀ R K (a shape error)"),
    Edit("kf_update", I_KG, "I_KG = np.eye(len(x_check)) - G @ K",
         keyword="shapes", mistake="I − G K (a shape error)", cell="update"),
    Edit("kf_update", "return x_hat, 0.5 * (P_hat + P_hat.T)", "return 0.5 * (P_hat + P_hat.T), x_hat",
         keyword="in the order", mistake="(P̂, x̂) returned"),
    Edit("kf_update", "K, S = kf_gain(P_check, G, R)",
         "S = G @ P_check @ G.T + R @ R\n    K = P_check @ G.T @ np.linalg.inv(S)", cell="update",
         keyword="gain inside kf_update", mistake="its own gain, with R R in S"),
    Edit("kf_update", "K, S = kf_gain(P_check, G, R)",
         "S = G @ P_check @ G.T + R\n    K = P_check @ G.T @ np.linalg.inv(R)", cell="update",
         keyword="gain inside kf_update", mistake="its own gain, with R⁻¹"),
    # an upstream mistake: the correct kf_update calls a wrong kf_gain
    Edit("kf_update", K, "K = P_check @ G.T @ np.linalg.inv(R)", cell="gain",
         keyword="fix kf_gain first", mistake="kf_gain uses R⁻¹ (kf_update itself right)"),
    Edit("kf_update", S, "S = G @ P_check @ G.T + np.sqrt(R)", cell="gain",
         keyword="fix kf_gain first", mistake="kf_gain adds √R (kf_update itself right)"),

    # --- gnss_kf_run -----------------------------------------------------------------------
    # row 0, the belief at t[0]: the learner decides x₀ and P₀ from what the first fix tells
    Edit("gnss_kf_run", f"{X0}\n    {P0}", "x, P = np.zeros(6), np.eye(6)",
         keyword="placeholder", mistake="x₀ = 0, P₀ = I, nothing decided (the stub)"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, 1e-4)])",
         keyword="initial velocity variance", mistake="a tiny start-velocity variance: the car taken as standing still"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.zeros(3)])",
         keyword="near zero", mistake="a zero start-velocity variance: the velocity taken as known"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.ones(3)])",
         keyword="near zero", mistake="a unit start-velocity variance (±3 m/s for a car at up to 12 m/s)"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.full(6, sigma_gnss**2))",
         keyword="not the fix's error", mistake="the fix's variance for the velocity too"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**4)])",
         keyword="squared twice", mistake="σ_v0 squared twice"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.zeros(3), np.full(3, sigma_v0**2)])",
         keyword="exact", mistake="a zero position variance: the first fix taken as exact"),
    Edit("gnss_kf_run", P0, "P = sigma_v0**2 * np.eye(6)",
         keyword="throws away", mistake="everything as unknown as the velocity: the first fix ignored"),
    Edit("gnss_kf_run", P0,
         "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])\n"
         "    P[:3, 3:] = P[3:, :3] = 0.5 * sigma_gnss * sigma_v0 * np.eye(3)",
         keyword="couples the position and velocity", mistake="position and velocity correlated at t[0]"),
    Edit("gnss_kf_run", P0,
         "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])\n"
         "    P[3:, 3:] += 0.3 * sigma_v0**2 * (np.ones((3, 3)) - np.eye(3))",
         keyword="velocity components", mistake="the velocity components correlated at t[0]"),
    Edit("gnss_kf_run", X0, "x = np.r_[y[0], (y[1] - y[0]) / (t[1] - t[0])]", cell="run",
         keyword="second fix", mistake="the start velocity from the first two fixes"),
    Edit("gnss_kf_run", X0, "x = np.r_[y[0], np.full(3, sigma_v0)]", cell="run",
         keyword="direction of travel", mistake="a start velocity of σ_v0 on each axis"),
    Edit("gnss_kf_run", X0, "x = np.r_[y[1], np.zeros(3)]", cell="run",
         keyword="first fix itself", mistake="the second fix as the start position"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss), np.full(3, sigma_v0**2)])",
         keyword="position variance must be σ²", mistake="initial position covariance σ, not σ²"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0)])",
         keyword="standard deviation σ = 15", mistake="initial velocity covariance σ_v0, not σ_v0²"),
    Edit("gnss_kf_run", P0, "P = np.diag(np.r_[np.full(3, 1.0), np.full(3, sigma_v0**2)])",
         keyword="initial position variance", mistake="initial position covariance I"),
    Edit("gnss_kf_run", X0, "x = np.r_[np.zeros(3), np.zeros(3)]", cell="run",
         keyword="first fix", mistake="start at the origin"),
    Edit("gnss_kf_run", R_RUN, "R = sigma_gnss * np.eye(3)", cell="run",
         keyword="standard deviation σ_gnss", mistake="R = σ I"),
    Edit("gnss_kf_run", R_RUN, "R = np.eye(3)", cell="run",
         keyword="not R = I", mistake="R = I"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(t[k] - t[k - 1], sigma_a**2)", cell="run",
         keyword="not sigma_a**2", mistake="σ_a² handed to cv_matrices"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(t[k] - t[k - 1], np.sqrt(sigma_a))", cell="run",
         keyword="not squared", mistake="Q proportional to σ_a (not squared) in the run"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(t[k] - t[k - 1], 1.0)", cell="run",
         keyword="sigma_a passed in", mistake="σ_a = 1 hard-coded"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(1.0, sigma_a)", cell="run",
         keyword="own time step", mistake="T = 1 s for every step"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(np.mean(np.diff(t)), sigma_a)", cell="run",
         keyword="own time step", mistake="the mean time step (as in the lecture's cell)"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(t[k], sigma_a)", cell="run",
         keyword="own time step", mistake="the time stamp for the time step"),
    Edit("gnss_kf_run", UPDATE_CALL, "x, P = kf_update(x, P, y[k - 1], G, R)", cell="run",
         keyword="off by one", mistake="update with the previous fix"),
    Edit("gnss_kf_run", "        x, P = kf_predict(x, P, F, Q)\n", "", cell="run",
         keyword="predicts", mistake="no prediction"),
    Edit("gnss_kf_run",
         "x, P = kf_predict(x, P, F, Q)\n        x, P = kf_update(x, P, y[k], G, R)\n"
         "        xs.append(x)\n        Ps.append(P)",
         "x, P = kf_predict(x, P, F, Q)\n        xs.append(x)\n        Ps.append(P)\n"
         "        x, P = kf_update(x, P, y[k], G, R)", cell="run",
         keyword="stored the prior", mistake="prior stored instead of posterior"),
    Edit("gnss_kf_run", STORE, "xs, Ps = [], []", cell="run",
         keyword="one row per fix", mistake="initial state not stored"),
    Edit("gnss_kf_run", LOOP, "for k in range(1, len(t) - 1):", cell="run",
         keyword="one row per fix", mistake="last fix skipped"),
    Edit("gnss_kf_run", STORE, "x, P = kf_update(x, P, y[0], G, R)\n    xs, Ps = [x], [P]", cell="run",
         keyword="counts twice", mistake="the first fix used twice: the prior, then updated with it"),
    Edit("gnss_kf_run",
         "xs, Ps = [x], [P]\n    for k in range(1, len(t)):\n"
         "        F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n        x, P = kf_predict(x, P, F, Q)\n",
         "xs, Ps = [], []\n    for k in range(len(t)):\n        if k > 0:\n"
         "            F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n"
         "            x, P = kf_predict(x, P, F, Q)\n", cell="run",
         keyword="counts twice",
         mistake="the first fix used twice: step 0 updates its prior (the first fix) with y[0], "
                 "as kf.run_kf's convention does"),
    # upstream mistakes: a correct run_gnss_kf calls a wrong step function
    Edit("gnss_kf_run", Q, "Q = B @ (sigma_a * I) @ B.T", cell="cv",
         keyword="fix cv_matrices first", mistake="cv_matrices does not square σ_a"),
    Edit("gnss_kf_run", PRED_P, "P_check = F @ P_hat @ F.T", cell="predict",
         keyword="fix kf_predict first", mistake="kf_predict without Q"),
    Edit("gnss_kf_run", K, "K = P_check @ G.T @ np.linalg.inv(R)", cell="gain",
         keyword="fix kf_gain first", mistake="kf_gain with R⁻¹"),
    Edit("gnss_kf_run", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T + K @ K.T", cell="update",
         keyword="fix kf_update first", mistake="kf_update's Joseph form with K Kᵀ"),

    # --- behaviour: arguments changed in place, single precision (issue 25) -----------------
    Edit("kf_predict", PRED_P, "P_hat[...] = F @ P_hat @ F.T + Q\n    P_check = P_hat",
         keyword="in place", mistake="the prior written into the caller's P̂"),
    Edit("kf_predict", PRED_P, "P_hat[:] = F @ P_hat @ F.T\n    P_hat += Q\n    P_check = P_hat",
         keyword="in place", mistake="P̂ propagated into itself, then Q added with +="),
    Edit("kf_update", INNOV, "y -= G @ x_check\n    innovation = y",
         keyword="in place", mistake="the predicted measurement subtracted into the caller's y"),
    Edit("kf_update", XHAT, "x_check += K @ innovation\n    x_hat = x_check",
         keyword="in place", mistake="the correction added into the caller's x̌ (x_check += ...)"),
    Edit("cv_process_noise", Q, "Q = (B @ (sigma_a**2 * I) @ B.T).astype(np.float32)",
         keyword="single precision", mistake="Q in float32"),
    Edit("kf_gain", K, "K = (P_check @ G.T @ np.linalg.inv(S)).astype(np.float32)",
         keyword="single precision", mistake="the gain in float32"),
    # a correct run whose kf_predict works in place: the run's rows change under it; the hint
    # must name kf_predict, not P₀ or row 0
    Edit("gnss_kf_run", PRED_P, "P_hat[...] = F @ P_hat @ F.T + Q\n    P_check = P_hat", cell="predict",
         keyword="fix kf_predict first", mistake="kf_predict writes the prior into the caller's P̂"),
    Edit("gnss_kf_run", PRED_P, "P_hat[:] = F @ P_hat @ F.T\n    P_hat += Q\n    P_check = P_hat", cell="predict",
         keyword="fix kf_predict first", mistake="kf_predict propagates P̂ into itself and adds Q with +="),
    Edit("gnss_kf_gaps", PRED_P, "P_hat[...] = F @ P_hat @ F.T + Q\n    P_check = P_hat", cell="predict",
         keyword="fix kf_predict first", mistake="kf_predict writes the prior into the caller's P̂"),

    # --- gnss_kf_gaps (the challenge): run_gnss_kf_gaps with NaN rows for missing fixes ------
    Edit("gnss_kf_gaps", GAP_STEP,
         "if np.all(np.isnan(y[k])):\n            xs.append(x)\n            Ps.append(P)\n"
         "            continue\n        F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n"
         "        x, P = kf_predict(x, P, F, Q)\n        x, P = kf_update(x, P, y[k], G, R)",
         keyword="skipped the prediction",
         mistake="at a missing fix the last posterior stored, no prediction (the stub)"),
    Edit("gnss_kf_gaps",
         "        if not np.all(np.isnan(y[k])):\n            x, P = kf_update(x, P, y[k], G, R)",
         "        x, P = kf_update(x, P, y[k], G, R)",
         keyword="makes the state NaN", mistake="updated with the NaN of a missing fix"),
    Edit("gnss_kf_gaps",
         "        if not np.all(np.isnan(y[k])):\n            x, P = kf_update(x, P, y[k], G, R)",
         "        if np.all(np.isnan(y[k])):\n            continue\n"
         "        x, P = kf_update(x, P, y[k], G, R)",
         keyword="one row per time", mistake="no row stored at a missing fix"),
    Edit("gnss_kf_gaps",
         "        if not np.all(np.isnan(y[k])):\n            x, P = kf_update(x, P, y[k], G, R)",
         "        y_k = G @ x if np.all(np.isnan(y[k])) else y[k]\n"
         "        x, P = kf_update(x, P, y_k, G, R)",
         keyword="no measurement", mistake="the predicted position used as the missing fix"),
    Edit("gnss_kf_gaps", "    xs, Ps = [x], [P]\n    for k",
         "    y = np.array(y)\n    for j in range(1, len(y)):\n        if np.all(np.isnan(y[j])):\n"
         "            y[j] = y[j - 1]\n    xs, Ps = [x], [P]\n    for k",
         keyword="last fix received", mistake="the last fix repeated where one is missing"),
    Edit("gnss_kf_gaps", "    xs, Ps = [x], [P]\n    for k",
         "    y = np.nan_to_num(y)\n    xs, Ps = [x], [P]\n    for k",
         keyword="origin", mistake="NaN replaced by 0 (np.nan_to_num)"),
    Edit("gnss_kf_gaps", "    xs, Ps = [x], [P]\n    for k in range(1, len(t)):\n        # BEGIN SOLUTION "
         "gnss_kf_gaps\n        " + GAP_STEP,
         "    xs, Ps = [x], [P]\n    t_last = t[0]\n    for k in range(1, len(t)):\n"
         "        if np.all(np.isnan(y[k])):\n            xs.append(x)\n            Ps.append(P)\n"
         "            continue\n        F, Q = cv_matrices(t[k] - t_last, sigma_a)\n        t_last = t[k]\n"
         "        x, P = kf_predict(x, P, F, Q)\n        x, P = kf_update(x, P, y[k], G, R)",
         keyword="whole gap",
         mistake="last posterior stored at a missing fix, the next fix predicts over the whole gap"),
    Edit("gnss_kf_gaps", "F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n        x, P = kf_predict",
         "F, Q = cv_matrices(1.0, sigma_a)\n        x, P = kf_predict",
         keyword="own time step", mistake="a fixed step of 1 s (the fixes are not exactly 1 s apart)"),
    # the challenge starts from run_gnss_kf's row 0: a wrong one is named as run_gnss_kf's
    Edit("gnss_kf_gaps", P0, "P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, 1e-4)])",
         cell="run", keyword="fix run_gnss_kf first",
         mistake="run_gnss_kf's P₀ with a tiny velocity variance, which the challenge starts from"),
    Edit("gnss_kf_gaps", GAP_START,
         "x = np.r_[y[0], np.zeros(3)]\n    P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, 1e-4)])",
         keyword="initial velocity variance",
         mistake="its own start belief, with a tiny velocity variance (run_gnss_kf right)"),
    # an upstream mistake: a correct run_gnss_kf_gaps calls a wrong kf_update
    Edit("gnss_kf_gaps", JOSEPH, "P_hat = I_KG @ P_check @ I_KG.T", cell="update",
         keyword="fix kf_update first", mistake="kf_update's Joseph form without K R Kᵀ"),
]

EQUIVALENTS = [
    # cv_process_noise
    Edit("cv_process_noise", Q, "Q = (sigma_a * B) @ (sigma_a * B).T",
         mistake="σ_a folded into B"),
    Edit("cv_process_noise", Q, "Q = sigma_a**2 * B @ B.T", mistake="σ_a² in front of B Bᵀ"),
    Edit("cv_process_noise", Q, "Q = sigma_a**2 * np.block([[T**4 / 4 * I, T**3 / 2 * I], "
         "[T**3 / 2 * I, T**2 * I]])", mistake="Q written out block by block"),
    Edit("cv_process_noise", Q, "Q = np.kron(sigma_a**2 * np.array([[T**4 / 4, T**3 / 2], "
         "[T**3 / 2, T**2]]), I)", mistake="Q by a Kronecker product"),
    Edit("cv_process_noise", f"{NOISE_JACOBIAN}\n    {Q}",
         "Q_a = sigma_a**2 * np.eye(dim)  # the acceleration's covariance\n"
         "    B = np.block([[T**2 / 2 * I], [T * I]])\n    Q = np.linalg.multi_dot([B, Q_a, B.T])",
         mistake="B by np.block, Q = B Q_a Bᵀ by multi_dot"),
    Edit("cv_process_noise", "return F, Q", "return [F, Q]", mistake="a list returned"),
    # kf_predict
    Edit("kf_predict", PRED_P, "P_check = np.linalg.multi_dot([F, P_hat, F.T]) + Q",
         mistake="multi_dot"),
    Edit("kf_predict", PRED_P, "P_check = np.einsum('ij,jk,lk->il', F, P_hat, F) + Q",
         mistake="einsum"),
    Edit("kf_predict", PRED_P, "P_check = F @ (F @ P_hat).T + Q", mistake="F (F P̂)ᵀ + Q"),
    Edit("kf_predict", PRED_X, "x_check = x_hat @ F.T", cell="predict", mistake="x̂ Fᵀ (= F x̂)"),
    Edit("kf_predict", PRED_X, "x_check = np.dot(F, x_hat)", cell="predict", mistake="np.dot"),
    Edit("kf_predict", "return x_check, P_check", "return [x_check, P_check]",
         mistake="a list returned"),
    # kf_gain
    Edit("kf_gain", K, "K = np.linalg.solve(S, G @ P_check).T",
         mistake="gain by a solve instead of an inverse"),
    Edit("kf_gain", K, "K = np.linalg.solve(S.T, (P_check @ G.T).T).T",
         mistake="gain by a solve of Sᵀ Kᵀ = (P̌ Gᵀ)ᵀ"),
    Edit("kf_gain", K, "K = P_check @ G.T @ np.linalg.pinv(S)", mistake="pseudo-inverse"),
    Edit("kf_gain", K, "L = np.linalg.cholesky(S)\n"
         "    K = np.linalg.solve(L.T, np.linalg.solve(L, G @ P_check)).T",
         mistake="Cholesky factor of S"),
    Edit("kf_gain", S, "S = G @ P_check @ G.T + R\n    S = 0.5 * (S + S.T)", mistake="S symmetrised"),
    Edit("kf_gain", "return K, S", "return [K, S]", mistake="a list returned"),
    # kf_update
    Edit("kf_update", JOSEPH, "P_hat = I_KG @ P_check",
         mistake="short form (I − K G) P̌, the lecture's and the seed's form: equal for the optimal gain"),
    Edit("kf_update", JOSEPH, "P_hat = P_check - K @ G @ P_check", mistake="P̌ − K G P̌"),
    Edit("kf_update", JOSEPH, "P_hat = P_check - K @ S @ K.T", mistake="P̌ − K S Kᵀ"),
    Edit("kf_update", JOSEPH,
         "P_hat = np.linalg.multi_dot([I_KG, P_check, I_KG.T]) + np.linalg.multi_dot([K, R, K.T])",
         mistake="Joseph form with multi_dot"),
    Edit("kf_update", XHAT, "x_hat = x_check + np.dot(K, innovation)", mistake="np.dot"),
    Edit("kf_update", UPDATE_STEP + "\n    # STUB\n"
         "    # # fix this: correct the prior mean and covariance with the measurement y\n"
         "    # # (the covariance in Joseph form); this placeholder ignores y\n"
         "    # x_hat, P_hat = x_check, P_check\n    # END SOLUTION\n    " + RET_UPDATE,
         f"{INNOV}\n    {XHAT}\n    P_hat = ({I_KG[7:]}) @ P_check\n    return x_hat, P_hat",
         mistake="short form, not symmetrised (asymmetric by round-off only)"),
    Edit("kf_update", UPDATE_STEP,
         "x_hat = x_check + K @ (y - G @ x_check)\n    P_hat = P_check - K @ S @ K.T",
         mistake="the whole update in two lines, P̌ − K S Kᵀ"),
    Edit("kf_update", UPDATE_STEP,
         "innovation = y - G @ x_check\n    x_hat = x_check + K @ innovation\n"
         "    A = np.eye(len(x_check)) - K @ G\n"
         "    P_hat = np.linalg.multi_dot([A, P_check, A.T]) + np.linalg.multi_dot([K, R, K.T])",
         mistake="the whole update with multi_dot"),
    Edit("kf_update", "K, S = kf_gain(P_check, G, R)",
         "S = G @ P_check @ G.T + R\n    K = np.linalg.solve(S, G @ P_check).T", cell="update",
         mistake="the gain computed inside kf_update"),
    Edit("kf_update", RET_UPDATE, "return [x_hat, 0.5 * (P_hat + P_hat.T)]", mistake="a list returned"),
    # gnss_kf_run
    Edit("gnss_kf_run", P0, "P = np.diag([sigma_gnss**2] * 3 + [sigma_v0**2] * 3)",
         mistake="P₀ from a list"),
    Edit("gnss_kf_run", P0, "P = np.block([[R, np.zeros((3, 3))], [np.zeros((3, 3)), sigma_v0**2 * np.eye(3)]])",
         mistake="P₀ as blocks: the fix's R, then the velocity's"),
    Edit("gnss_kf_run", f"{X0}\n    {P0}",
         "x = np.concatenate([y[0], np.zeros(3)])\n"
         "    P = np.diag(np.concatenate([np.diag(R), np.full(3, sigma_v0)**2]))",
         mistake="x₀ and P₀ from R's diagonal"),
    Edit("gnss_kf_run", P0, "P = np.zeros((6, 6))\n    P[:3, :3] = sigma_gnss**2 * np.eye(3)\n"
         "    P[3:, 3:] = sigma_v0**2 * np.eye(3)", mistake="P₀ filled block by block"),
    Edit("gnss_kf_run", R_RUN, "R = np.diag(np.full(3, sigma_gnss**2))", cell="run",
         mistake="R = diag(σ²)"),
    Edit("gnss_kf_run", X0, "x = np.concatenate([y[0], [0.0, 0.0, 0.0]])", cell="run",
         mistake="x₀ by concatenate"),
    Edit("gnss_kf_run", CV_CALL, "F, Q = cv_matrices(np.diff(t)[k - 1], sigma_a)", cell="run",
         mistake="time steps from np.diff"),
    Edit("gnss_kf_run", "xs, Ps = [x], [P]\n    for k in range(1, len(t)):\n"
         "        F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n"
         "        x, P = kf_predict(x, P, F, Q)\n        x, P = kf_update(x, P, y[k], G, R)\n"
         "        xs.append(x)\n        Ps.append(P)\n    return np.array(xs), np.array(Ps)",
         "N = len(t)\n    xs, Ps = np.zeros((N, 6)), np.zeros((N, 6, 6))\n    xs[0], Ps[0] = x, P\n"
         "    for k in range(1, N):\n        F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n"
         "        x, P = kf_update(*kf_predict(x, P, F, Q), y[k], G, R)\n"
         "        xs[k], Ps[k] = x, P\n    return xs, Ps", cell="run",
         mistake="preallocated arrays"),
    Edit("gnss_kf_run", "return np.array(xs), np.array(Ps)", "return np.stack(xs), np.stack(Ps)",
         cell="run", mistake="np.stack"),
    Edit("gnss_kf_run", "return np.array(xs), np.array(Ps)", "return [np.array(xs), np.array(Ps)]",
         cell="run", mistake="a list returned"),
    # a correct variant of an upstream function: the run must still pass
    Edit("gnss_kf_run", JOSEPH, "P_hat = I_KG @ P_check", cell="update",
         mistake="kf_update in the short form"),
    # gnss_kf_gaps
    Edit("gnss_kf_gaps", "        if not np.all(np.isnan(y[k])):",
         "        if np.all(np.isfinite(y[k])):", mistake="a fix is a finite row"),
    Edit("gnss_kf_gaps", "    xs, Ps = [x], [P]\n    for k in range(1, len(t)):\n        # BEGIN SOLUTION "
         "gnss_kf_gaps\n        " + GAP_STEP,
         "    has_fix = ~np.isnan(y).all(axis=1)\n    xs, Ps = [x], [P]\n    for k in range(1, len(t)):\n"
         "        F, Q = cv_matrices(t[k] - t[k - 1], sigma_a)\n        x, P = kf_predict(x, P, F, Q)\n"
         "        if has_fix[k]:\n            x, P = kf_update(x, P, y[k], G, R)",
         mistake="a mask of the fixes, computed once"),
    Edit("gnss_kf_gaps", GAP_STEP,
         "x, P = kf_predict(x, P, *cv_matrices(t[k] - t[k - 1], sigma_a))\n"
         "        if np.isnan(y[k]).any():\n            pass  # no fix: the posterior is the prior\n"
         "        else:\n            x, P = kf_update(x, P, y[k], G, R)",
         mistake="the update in an else branch"),
    Edit("gnss_kf_gaps", "return np.array(xs), np.array(Ps)", "return np.stack(xs), np.stack(Ps)",
         mistake="np.stack"),
    Edit("gnss_kf_gaps", GAP_START,
         "x = np.r_[y[0], np.zeros(3)]\n    P = np.diag(np.r_[np.full(3, sigma_gnss**2), np.full(3, sigma_v0**2)])",
         mistake="its own start belief, written out as run_gnss_kf's"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("gnss_kf_run", XHAT, "x_check += K @ innovation\n    x_hat = x_check", cell="update",
               reason="the run hands kf_update the prior that kf_predict has just returned, a new "
                      "array that nothing else holds: changing it in place changes no row of the "
                      "run (kf_update's own check names the in-place edit)"),
    Equivalent("kf_update", RET_UPDATE, "return x_hat, P_hat",
               reason="the Joseph form is symmetric to round-off (~1e-16 relative) already; "
                      "the symmetrisation changes nothing the check can see"),
    Equivalent("kf_gain", S, "S = G @ P_check @ G.T + R.T",
               reason="R is symmetric in every case (and every covariance is)"),
    Equivalent("kf_gain", K, "K = P_check.T @ G.T @ np.linalg.inv(S)",
               reason="P̌ is exactly symmetric in every case (and every covariance is)"),
    Equivalent("kf_gain", K, "K = P_check @ G.T @ np.linalg.inv(S).T",
               reason="S is symmetric to round-off, so is S⁻¹"),
    Equivalent("cv_process_noise", Q, "Q = B @ (sigma_a**2 * I) @ B.T\n    Q = 0.5 * (Q + Q.T)",
               reason="B (σ_a² I) Bᵀ is symmetric to round-off: symmetrising it changes nothing "
                      "the check can see"),
    Equivalent("kf_predict", PRED_P, "P_check = F @ P_hat.T @ F.T + Q",
               reason="P̂ is exactly symmetric in every case (and every covariance is)"),
]
