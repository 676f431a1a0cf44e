"""Chapter 10 (real sensors): plausible mistakes in the exercise's functions.

Checks and tolerances (``kalman_course/checks/real_sensors.py``):

- gauss_markov_blocks, augmented_matrices, relative_motion: rtol 1e-9, atol 1e-12 (round-off
  only); every mistake below is off by more than 1e-3 relative on some case (steps longer than
  τ, σ different per component, tilted KITTI attitudes, a rigidly moved track).
  gauss_markov_blocks is then judged across a sweep of T/τ from 1e-6 to 1e3, which catches the
  special cases for short or long steps below ("sweep"); relative_motion and the residual also
  meet increments of 1e-8 rad and of π − 1e-6 rad, about an axis and its opposite.
- relative_pose_residual: position part 1e-9 m; attitude part |y_θ|² (the first-order
  (ΔR_mᵀ ΔŘ − I)^∨ passes, see EQUIVALENTS); the mistakes err by O(|y_θ|) or O(|ΔŘ| |y_θ|) on
  increments of up to 1.45 rad.
- augmented_matrices: the observation error's six components each have their own τ and a
  stationary covariance Σ with correlations (up to 0.61): Q_e = Σ − F_e Σ F_eᵀ, entry by entry
  Σ_ij (1 − φ_i φ_j); the lecture's one-τ, diagonal blocks are mistakes here ("correlations",
  "one time constant").
- relative_pose_residual and relative_pose_jacobian also meet a camera's increments at a lever
  arm t (KITTI's cam0, and a made-up one), whose Jacobian gains −ΔŘ [t]× in the δθ columns and
  [Δp̌ + ΔŘ t]× in the δθ_c columns; the lecture's t = 0 blocks are mistakes there.
- relative_pose_jacobian: 1e-6 absolute against central differences of the residual.
- drift_segments: rtol 1e-7 on every segment's errors of the real ORB-SLAM2 / S-PTAM tracks
  (an arccos of the trace at the smallest rotational error, 1e-3 rad, loses up to 1.8e-9 relative).
- nis_rescaled_std (challenge): rtol 1e-9 on the new σ, real relative-VO innovations.
"""

from mutation_harness import Edit

NOTEBOOK = "10_real_sensors"

# ---- the reference lines of each fix region (and their neighbours)
PHI = "    phi = np.exp(-T / tau)\n"
F_E = "    F_e = phi * np.eye(6)\n"
Q_E = "    Q_e = np.diag(sigma**2 * (1.0 - phi**2))\n"
GM_RET = "    return F_e, Q_e"

A_PHI = "    phi = np.exp(-T / tau)\n"
F_NAV = "    F_aug[:15, :15] = F\n"
F_ERR = "    F_aug[15:, 15:] = np.diag(phi)\n"
Q_NEW = "    Q_aug = np.zeros((21, 21))\n"
Q_NAV = "    Q_aug[:15, :15] = BQBt\n"
Q_ERR = "    Q_aug[15:, 15:] = Sigma - phi[:, None] * Sigma * phi[None, :]\n"
AUG_BODY = A_PHI + "    F_aug = np.zeros((21, 21))\n" + F_NAV + F_ERR + Q_NEW + Q_NAV + Q_ERR
ERR_BLOCKS = F_ERR + Q_NEW + Q_NAV + Q_ERR          # the error block of F to the error block of Q
#: the augmented function's first lines, down to its fix region
AUG_HEAD = ("def augmented_matrices(F, BQBt, Sigma, T, tau):\n"
            "    # F (15, 15), BQBt (15, 15): the plain ESKF's transition and process noise over T seconds;\n"
            "    # Sigma (6, 6): the observation error's stationary covariance; tau (6,): its time constants (s).\n"
            "    # Returns (F_aug (21, 21), Q_aug (21, 21)).\n"
            "    # BEGIN SOLUTION augmented_matrices\n")
#: the per-component blocks of the learner's own gauss_markov_blocks, taking σ from Σ's diagonal
GM_PER_COMPONENT = "    F_e, Q_e = gauss_markov_blocks(np.sqrt(np.diag(Sigma)), T, tau)\n"

DP = "    dp = R0.T @ (p1 - p0)\n"
DR = "    dR = R0.T @ R1\n"
REL_RET = "    return dp, dR"

RES_CALL = "    dp_check, dR_check = relative_motion(p_clone, R_clone, p_check, R_check)\n"
THETA = "    dtheta = so3.Log(dR_meas.T @ dR_check)\n"
RES_RET = "    return np.concatenate([dp_camera - dp_meas, dtheta])"

G_NEW = "    G = np.zeros((6, 21))\n"
G_SWING = "    G[0:3, 6:9] = -dR_check @ so3.hat(lever_arm)\n"
G_PC = "    G[0:3, 15:18] = -R_clone.T\n"
G_LEVER = "    G[0:3, 18:21] = so3.hat(dp_check + dR_check.dot(lever_arm))\n"
G_THC = "    G[3:6, 18:21] = -dR_check.T\n"
JAC_BODY = G_SWING + G_PC + G_LEVER + G_THC

D_REL = "        dp, dR = relative_motion(position[i], rotation[i], position[j], rotation[j])\n"
D_REL_TRUE = ("        dp_true, dR_true = relative_motion(true_position[i], true_rotation[i], true_position[j], "
              "true_rotation[j])\n")
D_T = "        t_err[s] = 100.0 * np.linalg.norm(dp_true - dp) / L\n"
D_R = "        r_err[s] = np.rad2deg(np.linalg.norm(so3.Log(dR.T @ dR_true))) * 100.0 / L\n"
DRIFT_BODY = D_REL + D_REL_TRUE + D_T + D_R
DRIFT_RET = "    return t_err, r_err"

NIS_LINE = "    nis = np.array([v @ np.linalg.solve(S_k, v) for v, S_k in zip(innovation, S)])\n"
RATIO = "    ratio = np.median(nis) / chi2_ppf(0.5, innovation.shape[1])\n"
STD_RET = "    return std * np.sqrt(ratio)"
NIS_BODY = NIS_LINE + RATIO + STD_RET

# a learner's own wrong building blocks, defined where a later function calls them (dependencies)
BROKEN_GM = ("def gauss_markov_blocks(sigma, T, tau):\n"
             "    phi = 1.0 - T / tau\n"
             "    return phi * np.eye(6), np.diag(sigma**2 * (1.0 - phi**2))\n\n\n")
BROKEN_REL = ("def relative_motion(p0, R0, p1, R1):\n"
              "    return p1 - p0, R1 @ R0.T\n\n\n")


def _gm(old, new, keyword, mistake):
    return Edit("gauss_markov_blocks", old, new, keyword=keyword, mistake=mistake)


def _aug(old, new, keyword, mistake):
    return Edit("augmented_matrices", old, new, keyword=keyword, mistake=mistake)


def _rel(old, new, keyword, mistake):
    return Edit("relative_motion", old, new, keyword=keyword, mistake=mistake)


def _res(old, new, keyword, mistake):
    return Edit("relative_pose_residual", old, new, keyword=keyword, mistake=mistake)


def _jac(old, new, keyword, mistake):
    return Edit("relative_pose_jacobian", old, new, keyword=keyword, mistake=mistake)


def _drift(old, new, keyword, mistake):
    return Edit("drift_segments", old, new, keyword=keyword, mistake=mistake)


def _nis(old, new, keyword, mistake):
    return Edit("nis_rescaled_std", old, new, keyword=keyword, mistake=mistake)


MUTANTS = [
    # ---- gauss_markov_blocks: F_e = φ I, Q_e = diag(σ² (1 − φ²)), φ = exp(−T/τ)
    _gm(PHI, "    phi = 1.0 - T / tau\n", "first-order", "the Euler decay 1 − T/τ (the stub)"),
    _gm(Q_E, "    Q_e = np.diag(2.0 * sigma**2 / tau * T)\n", "first-order",
        "the first-order variance 2σ²T/τ (the stub)"),
    _gm(PHI, "    phi = np.exp(-tau / T)\n", "upside down", "exp(−τ/T)"),
    _gm(PHI, "    phi = np.exp(-T * tau)\n", "dimensionless", "exp(−T τ)"),
    _gm(PHI, "    phi = np.exp(T / tau)\n", "sign", "exp(+T/τ)"),
    _gm(PHI, "    phi = np.exp(-2.0 * T / tau)\n", "VARIANCE", "φ² as the decay of the error"),
    _gm(F_E, "    F_e = np.exp(-T / tau * np.eye(6))\n", "element-wise", "np.exp of a matrix"),
    _gm(F_E, "    F_e = np.eye(6)\n", "for ever", "F_e = I (a random constant or walk)"),
    _gm(F_E, "    F_e = np.zeros((6, 6))\n", "white noise", "F_e = 0"),
    _gm(Q_E, "    Q_e = np.diag(sigma**2 * T)\n", "units", "σ²T, the white-noise integral"),
    _gm(Q_E, "    Q_e = np.diag(sigma**2)\n", "whole stationary variance", "σ² every step"),
    _gm(Q_E, "    Q_e = np.diag(sigma**2 * (1.0 - phi))\n", "not φ σ²", "σ²(1 − φ)"),
    _gm(Q_E, "    Q_e = np.diag(sigma**2 * (1.0 - phi)**2)\n", "σ²(1 − φ)²", "σ²(1 − φ)²"),
    _gm(Q_E, "    Q_e = np.diag(sigma * (1.0 - phi**2))\n", "standard deviation", "σ instead of σ²"),
    _gm(Q_E, "    Q_e = np.diag(sigma * np.sqrt(1.0 - phi**2))\n", "standard deviation of the new part",
        "the new part's standard deviation"),
    _gm(Q_E, "    Q_e = np.diag(sigma**2 * phi**2)\n", "CARRIED OVER", "the carried-over variance φ²σ²"),
    _gm(Q_E, "    Q_e = np.diag(np.full(6, sigma[0]**2) * (1.0 - phi**2))\n", "one σ for all six",
        "the first component's σ for all six"),
    _gm(Q_E, "    Q_e = np.zeros((6, 6))\n", "nothing new enters", "Q_e = 0"),
    _gm(Q_E, "    Q_e = sigma**2 * (1.0 - phi**2)\n", "np.diag", "the diagonal as a vector"),
    _gm(GM_RET, "    return Q_e, F_e", "swapped", "(Q_e, F_e) returned"),
    _gm(GM_RET, "    return F_e", "tuple", "only F_e returned"),
    _gm(Q_E, "    sigma **= 2  # the variances, in place\n    Q_e = np.diag(sigma * (1.0 - phi**2))\n", "in place",
        "σ squared into the caller's array"),
    _gm(F_E, "    F_e = (phi * np.eye(6)).astype(np.float32)\n", "single precision", "F_e in float32"),
    _gm(PHI, "    phi = np.float32(np.exp(-T / tau))\n", "single precision", "φ in float32 (both blocks follow it)"),
    # special cases for short or long steps, right on the main cases, wrong across the sweep of T/τ
    _gm(PHI, "    phi = 1.0 - T / tau if T < 1e-3 * tau else np.exp(-T / tau)\n", "sweep",
        "the first-order decay below T/τ = 1e-3"),
    _gm(PHI, "    phi = 0.0 if T > 20 * tau else np.exp(-T / tau)\n", "sweep",
        "no memory left beyond T = 20 τ (exp(−20) = 2e-9 is not 0)"),
    _gm(Q_E, "    Q_e = np.diag(2.0 * sigma**2 * T / tau if T < 1e-4 * tau else sigma**2 * (1.0 - phi**2))\n",
        "sweep", "the first-order variance below T/τ = 1e-4"),

    # ---- augmented_matrices: F_aug = blockdiag(F, diag(φ_i)), Q_aug = blockdiag(B Q Bᵀ, Σ − F_e Σ F_eᵀ)
    _aug(AUG_BODY, "    F_aug, Q_aug = np.eye(21), np.zeros((21, 21))\n", "placeholder",
         "the step that does nothing (the stub)"),
    _aug(ERR_BLOCKS, "    F_aug[15:, 15:] = np.eye(6)\n" + Q_NEW + Q_NAV, "random constant",
         "the observation error held constant (F block I, no noise)"),
    _aug(F_ERR, "    F_aug[15:, 15:] = np.eye(6)\n", "random walk", "F block I with the Gauss–Markov noise"),
    _aug(Q_ERR, "", "only decays", "no Gauss–Markov noise"),
    _aug(ERR_BLOCKS, Q_NEW + Q_NAV + "    Q_aug[15:, 15:] = Sigma\n", "white", "the observation error as white noise"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = Sigma\n", "whole stationary covariance", "all of Σ added at every step"),
    _aug(F_NAV, "    F_aug[:15, :15] = np.eye(15)\n", "identity", "the navigation block of F_aug left I"),
    _aug(F_NAV, "", "plain ESKF's F", "the navigation block of F_aug left zero"),
    _aug(Q_NAV, "", "IMU's noise", "the navigation block of Q_aug left zero"),
    _aug(AUG_BODY, A_PHI + "    F_aug = np.zeros((21, 21))\n    F_aug[:6, :6] = np.diag(phi)\n    F_aug[6:, 6:] = F\n"
         + Q_NEW + "    Q_aug[:6, :6] = Sigma - phi[:, None] * Sigma * phi[None, :]\n    Q_aug[6:, 6:] = BQBt\n",
         "order of the states", "the observation error first"),
    _aug(A_PHI, "    phi = np.exp(-tau / T)\n", "swapped", "T and τ swapped"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = np.diag(np.diag(Sigma) * (1.0 - phi**2))\n", "correlations",
         "only the diagonal of Q_e (the lecture's σ²(1 − φ²) per component)"),
    _aug(AUG_BODY, GM_PER_COMPONENT + "    F_aug = np.zeros((21, 21))\n" + F_NAV + "    F_aug[15:, 15:] = F_e\n"
         + Q_NEW + Q_NAV + "    Q_aug[15:, 15:] = Q_e\n", "correlations",
         "the learner's per-component gauss_markov_blocks with σ from Σ's diagonal"),
    _aug(AUG_BODY, "    F_e, Q_e = gauss_markov_blocks(np.diag(Sigma), T, tau)\n    F_aug = np.zeros((21, 21))\n"
         + F_NAV + "    F_aug[15:, 15:] = F_e\n" + Q_NEW + Q_NAV + "    Q_aug[15:, 15:] = Q_e\n", "variances",
         "Σ's diagonal (variances) passed as σ, correlations dropped"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = (1.0 - phi**2)[:, None] * Sigma\n", "row", "Σ − F_e² Σ: one decay per row"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = Sigma * (1.0 - phi**2)\n", "column", "(1 − φ²) broadcast over Σ's columns"),
    _aug(Q_ERR, "    Q_e = (1.0 - phi**2)[:, None] * Sigma\n    Q_aug[15:, 15:] = 0.5 * (Q_e + Q_e.T)\n",
         "symmetrising", "one decay per row, symmetrised afterwards"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = Sigma - phi[:, None] * Sigma\n", "both sides", "Σ − F_e Σ"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = Sigma**2 - phi[:, None] * Sigma**2 * phi[None, :]\n", "squared",
         "Σ squared entry by entry"),
    _aug(A_PHI, "    phi = np.full(6, np.exp(-T / np.mean(tau)))\n", "one time constant", "the mean τ for all"),
    _aug(A_PHI, "    phi = np.full(6, np.exp(-T / tau[0]))\n", "one time constant", "τ_0 for all"),
    _aug(A_PHI, "    phi = 1.0 - T / tau\n", "first order", "the first-order decay 1 − T/τ_i in both blocks"),
    _aug(F_ERR, "    F_aug[15:, 15:] = np.eye(6) - T * np.diag(1.0 / tau)\n", "Euler",
         "the first-order F_e with the exact Q_e"),
    _aug(F_ERR, "    F_aug[15:, 15:] = np.exp(-T / tau * np.eye(6))\n", "element-wise", "np.exp of a matrix"),
    _aug(F_ERR, "    F_aug[15:, 15:] = np.diag(phi**2)\n", "VARIANCE", "φ² in F_e"),
    _aug(ERR_BLOCKS, "    F_aug[15:, 15:] = Sigma - phi[:, None] * Sigma * phi[None, :]\n" + Q_NEW + Q_NAV
         + "    Q_aug[15:, 15:] = np.diag(phi)\n", "swapped", "F_e and Q_e swapped"),
    _aug(F_ERR, F_ERR + "    F_aug[15:, :15] = eskf.POSE_G\n", "POSE_G in rows",
         "the observation error coupled to the pose error"),
    _aug(F_ERR, F_ERR + "    F_aug[:15, 15:] = eskf.POSE_G.T\n", "POSE_Gᵀ",
         "the pose error coupled to the observation error"),
    _aug(F_ERR, F_ERR + "    F_aug[15:, :15] = np.ones((6, 15)) * 1e-3\n", "should be zero",
         "some made-up coupling"),
    _aug(Q_ERR, "    Q_aug[15:, 15:] = np.triu(Sigma - phi[:, None] * Sigma * phi[None, :])\n", "not symmetric",
         "only the upper triangle of Q_e filled"),
    _aug(AUG_HEAD + A_PHI, BROKEN_GM + AUG_HEAD + "    phi = np.diag(gauss_markov_blocks(np.sqrt(np.diag(Sigma)), T, tau)[0])\n",
         "fix gauss_markov_blocks first",
         "F_e through the learner's own gauss_markov_blocks, which is wrong (dependency)"),
    # ---- relative_motion: Δp = R0ᵀ (p1 − p0), ΔR = R0ᵀ R1
    _rel(DP, "    dp = p1 - p0\n", "navigation frame", "the navigation-frame displacement (the stub)"),
    _rel(DR, "    dR = R1 @ R0.T\n", "NAVIGATION frame", "the navigation-frame rotation (the stub)"),
    _rel(DP, "    dp = R0 @ (p1 - p0)\n", "inverse map", "R0 instead of R0ᵀ"),
    _rel(DP, "    dp = R1.T @ (p1 - p0)\n", "pose 1's body", "seen from pose 1"),
    _rel(DP, "    dp = R0.T @ (p0 - p1)\n", "sign", "p0 − p1"),
    _rel(DP, "    dp = R1.T @ (p0 - p1)\n", "pose 0 is seen from pose 1", "the inverse relative position"),
    _rel(DP, "    dp = R0.T @ p1 - p0\n", "only p1", "only p1 rotated"),
    _rel(DR, "    dR = R0 @ R1.T\n", "back to pose 0", "R0 R1ᵀ"),
    _rel(DR, "    dR = R1.T @ R0\n", "inverse, pose 0 seen from pose 1", "R1ᵀ R0"),
    _rel(DR, "    dR = R0 @ R1\n", "inverse of R0 is missing", "R0 R1"),
    _rel(DR, "    dR = R1 @ R0\n", "order and inverse", "R1 R0"),
    _rel(REL_RET, "    return dR, dp", "shape", "(ΔR, Δp) returned"),
    _rel(DP, "    p1 -= p0  # the displacement, in place\n    dp = R0.T @ p1\n", "in place",
         "the displacement subtracted into the caller's p1"),
    _rel(DR, "    R1[:] = R0.T @ R1  # composed into the caller's pose\n    dR = R1\n", "in place",
         "ΔR composed into the caller's R1"),
    _rel(DR, "    dR = (R0.T @ R1).astype(np.float32)\n", "single precision", "ΔR in float32"),

    # ---- relative_pose_residual: [Δp̌_camera − Δp_m; Log(ΔR_mᵀ ΔŘ)]
    _res(THETA, "    dtheta = so3.Log(dR_check) - so3.Log(dR_meas)\n", "do not subtract",
         "difference of rotation vectors (the stub)"),
    _res(THETA, "    dtheta = so3.Log(dR_check.T @ dR_meas)\n", "sign of the attitude", "Log(ΔŘᵀ ΔR_m)"),
    _res(THETA, "    dtheta = so3.Log(dR_check @ dR_meas.T)\n", "wrong side", "Log(ΔŘ ΔR_mᵀ)"),
    _res(THETA, "    dtheta = so3.Log(dR_meas @ dR_check.T)\n", "side and sign", "Log(ΔR_m ΔŘᵀ)"),
    _res(THETA, "    dtheta = so3.Log(dR_meas @ dR_check)\n", "transpose is missing", "Log(ΔR_m ΔŘ)"),
    _res(RES_RET, "    return np.concatenate([dp_meas - dp_camera, so3.Log(dR_check.T @ dR_meas)])", "both parts",
         "measurement minus prediction"),
    _res(RES_RET, "    return np.concatenate([dp_meas - dp_camera, dtheta])", "position part",
         "sign of the position part"),
    _res(RES_RET, "    return np.zeros(6)", "nothing was compared", "zero residual"),
    _res(RES_RET, "    dp_meas -= dp_camera  # in place\n    return np.concatenate([-dp_meas, dtheta])", "in place",
         "the prediction subtracted into the caller's measured Δp"),
    _res(RES_RET, "    return np.concatenate([dtheta, dp_camera - dp_meas])", "order", "[θ; p]"),
    _res(RES_RET, "    return np.concatenate([dp_check - dp_meas, dtheta])", "lever arm is ignored",
         "the IMU's predicted displacement against the camera's measured one"),
    _res(RES_CALL, "    dp_check, dR_check = relative_motion(p_check, R_check, p_clone, R_clone)\n",
         "current pose to the clone", "the increment predicted backwards"),
    _res(RES_CALL, "    dp_check, dR_check = p_check - p_clone, R_clone.T @ R_check\n", "navigation frame",
         "the displacement predicted in the navigation frame"),
    _res("def relative_pose_residual(", BROKEN_REL + "def relative_pose_residual(", "fix relative_motion first",
         "through the learner's own relative_motion, which is wrong (dependency)"),
    _res("lever_arm=np.zeros(3)):\n    # Clone", "):\n    lever_arm = np.zeros(3)\n    # Clone", "lever arm too",
         "the lever arm dropped from the signature (fixed at zero)"),

    # ---- relative_pose_jacobian: the clone's columns and the lever arm's
    _jac(JAC_BODY, "    pass\n", "treated as exactly known", "the blocks left empty (the stub)"),
    _jac(G_PC, "    G[0:3, 15:18] = R_clone.T\n", "minus", "+Ř_cᵀ for δp_c"),
    _jac(G_PC, G_PC + "    G = G.astype(np.float32)\n", "single precision", "G returned in float32"),
    _jac(G_PC, "    G[0:3, 15:18] = -np.eye(3)\n", "rotated like the current one", "−I for δp_c"),
    _jac(G_PC, "    G[0:3, 15:18] = -R_clone\n", "R_c = R_nb", "−Ř_c for δp_c"),
    _jac(G_PC, "", "missing", "δp_c block left zero"),
    _jac(G_LEVER, "    G[0:3, 18:21] = -so3.hat(dp_check + dR_check @ lever_arm)\n", "sign of the lever arm",
         "−[Δp̌ + ΔŘ t]×"),
    _jac(G_LEVER, "", "lever arm", "the clone's lever-arm block left out"),
    _jac(G_LEVER, "    G[0:3, 18:21] = so3.hat(R_clone @ (dp_check + dR_check @ lever_arm))\n", "BODY frame",
         "the lever arm in the navigation frame"),
    _jac(G_SWING + G_PC + G_LEVER, G_PC + "    G[0:3, 18:21] = so3.hat(dp_check)\n", "swings the camera",
         "the lecture's blocks for t = 0, the lever arm ignored"),
    _jac(G_LEVER, "    G[0:3, 18:21] = so3.hat(dp_check)\n", "the current CAMERA",
         "[Δp̌]× for the clone's attitude, the camera ignored there"),
    _jac(G_LEVER, "    G[0:3, 18:21] = so3.hat(dp_check + dR_check @ lever_arm - lever_arm)\n", "does not move",
         "[Δp̌_camera]×: the camera's displacement as the lever arm"),
    _jac(G_LEVER, "    G[0:3, 18:21] = so3.hat(dp_check + lever_arm)\n", "CURRENT body frame", "[Δp̌ + t]×"),
    _jac(G_SWING, "", "swings the camera", "the current attitude's lever-arm block left out"),
    _jac(G_SWING, "    G[0:3, 6:9] = dR_check @ so3.hat(lever_arm)\n", "sign of the lever arm's block", "+ΔŘ[t]×"),
    _jac(G_SWING, "    G[0:3, 6:9] = -so3.hat(lever_arm)\n", "turned across the increment", "−[t]×"),
    _jac(G_SWING, "    G[0:3, 6:9] = -so3.hat(dR_check @ lever_arm)\n", "order", "−[ΔŘ t]×"),
    _jac(G_SWING, "    G[0:3, 6:9] = -R_clone.T @ so3.hat(lever_arm)\n", "not by Ř_cᵀ alone", "−Ř_cᵀ[t]×"),
    _jac(G_THC, "    G[3:6, 18:21] = -np.eye(3)\n", "rotate it across", "−I for δθ_c"),
    _jac(G_THC, "    G[3:6, 18:21] = -dR_check\n", "transpose", "−ΔŘ for δθ_c"),
    _jac(G_THC, "    G[3:6, 18:21] = dR_check.T\n", "sign", "+ΔŘᵀ for δθ_c"),
    _jac(G_THC, "    G[3:6, 18:21] = np.eye(3)\n", "sign and frame", "+I for δθ_c"),
    _jac(G_THC, "    G[3:6, 12:15] = -dR_check.T\n", "should be zero", "δθ_c's block in the δb_ω columns"),
    _jac(G_NEW + "    G[0:3, 0:3] = R_clone.T        # y_p with respect to the current position error\n"
         "    G[3:6, 6:9] = np.eye(3)        # y_theta with respect to the current attitude error\n"
         "    # BEGIN SOLUTION relative_pose_jacobian\n" + JAC_BODY,
         "    G = np.zeros((6, 15))\n    G[0:3, 0:3] = R_clone.T\n    G[3:6, 6:9] = np.eye(3)\n"
         "    G[0:3, 6:9] = -dR_check @ so3.hat(lever_arm)\n", "(6, 15)", "the 15-state G, no clone columns"),
    _jac("lever_arm=np.zeros(3)):\n    # R_clone", "):\n    lever_arm = np.zeros(3)\n    # R_clone", "lever arm too",
         "the lever arm dropped from the signature (fixed at zero)"),

    # ---- drift_segments: 100 |Δp_true − Δp| / L (%), angle(ΔRᵀ ΔR_true) / L (°/100 m)
    _drift(DRIFT_BODY, "        t_err[s] = np.linalg.norm(position[j] - true_position[j])\n"
                       "        r_err[s] = np.linalg.norm(so3.Log(true_rotation[j].T @ rotation[j]))\n",
           "placeholder", "the absolute errors at the segment's end in m and rad (the stub)"),
    _drift(DRIFT_BODY, "        t_err[s] = 100.0 * np.linalg.norm(position[j] - true_position[j]) / L\n"
                       "        r_err[s] = np.rad2deg(np.linalg.norm(so3.Log(true_rotation[j].T @ rotation[j]))) "
                       "* 100.0 / L\n",
           "absolute error at the segment's end", "the absolute errors at the end, per length"),
    _drift(D_T, "        t_err[s] = 100.0 * np.linalg.norm((position[j] - position[i]) - (true_position[j] - "
                "true_position[i])) / L\n", "navigation frame", "displacements compared in the navigation frame"),
    _drift(D_REL + D_REL_TRUE,
           "        dp, dR = relative_motion(position[j], rotation[j], position[i], rotation[i])\n"
           "        dp_true, dR_true = relative_motion(true_position[j], true_rotation[j], true_position[i], "
           "true_rotation[i])\n", "END", "the segment's relative poses taken from its end"),
    _drift(D_T, "        t_err[s] = 100.0 * abs(np.linalg.norm(dp_true) - np.linalg.norm(dp)) / L\n",
           "only the lengths", "difference of the lengths"),
    _drift(D_T, "        t_err[s] = 100.0 * np.linalg.norm(dp_true - dp) / np.linalg.norm(dp_true)\n",
           "straight-line", "divided by the straight-line distance"),
    _drift(D_T, "        t_err[s] = np.linalg.norm(dp_true - dp) / L\n", "fraction", "no × 100"),
    _drift(D_T, "        t_err[s] = 100.0 * np.linalg.norm(dp_true - dp)\n", "not divided", "not divided by L"),
    _drift(D_T, "        t_err[s] = np.linalg.norm(dp_true - dp)\n", "metres", "the error in metres"),
    _drift(D_R, "        r_err[s] = np.linalg.norm(so3.Log(dR.T @ dR_true)) * 100.0 / L\n", "radians",
           "radians per 100 m"),
    _drift(D_R, "        r_err[s] = np.rad2deg(np.linalg.norm(so3.Log(dR.T @ dR_true))) / L\n", "per METRE",
           "degrees per metre"),
    _drift(D_R, "        r_err[s] = np.rad2deg(np.linalg.norm(so3.Log(dR.T @ dR_true)))\n", "not divided",
           "degrees, not divided by L"),
    _drift(D_R, "        r_err[s] = np.linalg.norm(so3.Log(dR.T @ dR_true)) / L\n", "radians per metre",
           "radians per metre"),
    _drift(D_R, "        r_err[s] = np.rad2deg(abs(np.linalg.norm(so3.Log(dR_true)) - np.linalg.norm(so3.Log(dR))))"
                " * 100.0 / L\n", "angles do not subtract", "difference of the angles"),
    _drift(D_R, "        r_err[s] = np.rad2deg(np.linalg.norm(so3.Log(dR_true) - so3.Log(dR))) * 100.0 / L\n",
           "rotation vectors do not subtract", "difference of the rotation vectors"),
    _drift(D_R, "        r_err[s] = np.rad2deg(np.linalg.norm(so3.Log((rotation[j] @ rotation[i].T).T @ "
                "(true_rotation[j] @ true_rotation[i].T)))) * 100.0 / L\n", "navigation frame",
           "rotations compared in the navigation frame"),
    _drift(DRIFT_RET, "    return r_err, t_err", "swapped", "outputs swapped"),
    _drift("def segment_errors(", BROKEN_REL + "def segment_errors(", "fix relative_motion first",
           "through the learner's own relative_motion, which is wrong (dependency)"),

    # ---- nis_rescaled_std (challenge): σ √(median NIS / χ²-median(m))
    _nis(NIS_BODY, "    return std", "placeholder", "σ unchanged (the stub)"),
    _nis(RATIO, "    ratio = np.mean(nis) / chi2_ppf(0.5, innovation.shape[1])\n", "MEAN NIS", "the mean NIS"),
    _nis(RATIO, "    ratio = np.median(nis) / innovation.shape[1]\n", "MEAN of χ²", "median against m"),
    _nis(RATIO, "    ratio = np.mean(nis) / innovation.shape[1]\n", "mean NIS against m", "mean against m"),
    _nis(STD_RET, "    return std * ratio", "square root", "σ scaled by the ratio"),
    _nis(STD_RET, "    return std / np.sqrt(ratio)", "upside down", "σ divided by √ratio"),
    _nis(STD_RET, "    return std**2 * ratio", "variance", "σ² returned"),
    _nis(RATIO, "    ratio = np.median(nis) / chi2_ppf(0.5, 6)\n", "6 degrees", "dof 6 for every block"),
    _nis(RATIO, "    ratio = np.median(nis) / chi2_ppf(0.5, 3)\n", "3 degrees", "dof 3 for every block"),
    _nis(NIS_LINE, "    nis = np.array([np.sum(v**2 / np.diag(S_k)) for v, S_k in zip(innovation, S)])\n",
         "diagonal", "only the diagonal of S"),
    _nis(STD_RET, "    return std * np.clip(np.sqrt(ratio), 0.5, 2.0)", "clipped", "the step clipped to [½, 2]"),
    _nis(NIS_BODY, "    return std * np.sqrt(np.array([v @ np.linalg.solve(S_k, v) for v, S_k in zip(innovation, S)])"
                   " / chi2_ppf(0.5, innovation.shape[1]))", "one number", "one σ per increment"),
]

EQUIVALENTS = [
    Edit("gauss_markov_blocks", Q_E, "    Q_e = np.diag(-sigma**2 * np.expm1(-2.0 * T / tau))\n",
         mistake="1 − φ² by expm1"),
    Edit("gauss_markov_blocks", Q_E, "    Q_e = np.diag(sigma**2) - F_e @ np.diag(sigma**2) @ F_e.T\n",
         mistake="Q_e from stationarity, σ² − F_e σ² F_eᵀ"),
    Edit("gauss_markov_blocks", F_E, "    F_e = np.diag(np.full(6, phi))\n", mistake="np.diag of a full vector"),
    Edit("gauss_markov_blocks", Q_E, "    Q_e = np.eye(6) * sigma**2 * (1 - phi * phi)\n",
         mistake="a broadcast identity"),
    Edit("augmented_matrices", AUG_BODY,
         "    from scipy.linalg import block_diag\n    F_e = np.diag(np.exp(-T / tau))\n"
         "    F_aug = block_diag(F, F_e)\n    Q_aug = block_diag(BQBt, Sigma - F_e @ Sigma @ F_e.T)\n",
         mistake="scipy's block_diag, Q_e = Σ − F_e Σ F_eᵀ"),
    Edit("augmented_matrices", AUG_BODY,
         A_PHI + "    F_e, Q_e = np.diag(phi), Sigma * (1.0 - np.outer(phi, phi))\n"
         "    Z = np.zeros((15, 6))\n    F_aug = np.block([[F, Z], [Z.T, F_e]])\n"
         "    Q_aug = np.block([[BQBt, Z], [Z.T, Q_e]])\n", mistake="np.block, Σ ∘ (1 − φ φᵀ)"),
    Edit("augmented_matrices", Q_ERR,
         "    rate = 1.0 / tau\n    Q_aug[15:, 15:] = -np.expm1(-T * (rate[:, None] + rate[None, :])) * Sigma\n",
         mistake="1 − φ_i φ_j by expm1"),
    Edit("augmented_matrices", A_PHI + "    F_aug = np.zeros((21, 21))\n" + F_NAV + F_ERR,
         GM_PER_COMPONENT + "    phi = np.diag(F_e)\n    F_aug = np.zeros((21, 21))\n" + F_NAV
         + "    F_aug[15:, 15:] = F_e\n", mistake="F_e from the learner's own gauss_markov_blocks (vector τ)"),
    Edit("relative_motion", DP, "    dp = (p1 - p0) @ R0\n", mistake="row vector times R0"),
    Edit("relative_motion", DP, "    dp = np.linalg.solve(R0, p1 - p0)\n", mistake="R0⁻¹ by solve"),
    Edit("relative_motion", DR, "    dR = np.linalg.inv(R0) @ R1\n", mistake="R0⁻¹ by inv"),
    Edit("relative_pose_residual", THETA, "    dtheta = -so3.Log(dR_check.T @ dR_meas)\n",
         mistake="Log of the inverse, negated"),
    Edit("relative_pose_residual", THETA,
         "    E = dR_meas.T @ dR_check\n    dtheta = 0.5 * np.array([E[2, 1] - E[1, 2], E[0, 2] - E[2, 0], "
         "E[1, 0] - E[0, 1]])\n", mistake="the first-order vee of the antisymmetric part (lecture 08's form)"),
    Edit("relative_pose_residual", THETA, "    dtheta = so3.vee(dR_meas.T @ dR_check - np.eye(3))\n",
         mistake="the first-order (ΔR_mᵀ ΔŘ − I)^∨"),
    Edit("relative_pose_jacobian", G_LEVER, "    G[0:3, 18:21] = -so3.hat(dp_check + dR_check @ lever_arm).T\n",
         mistake="−[Δp̌ + ΔŘ t]×ᵀ"),
    Edit("relative_pose_jacobian", G_LEVER, "    G[0:3, 18:21] = so3.hat(dp_check) + so3.hat(dR_check @ lever_arm)\n",
         mistake="the hat of a sum as a sum of hats"),
    Edit("relative_pose_jacobian", G_SWING, "    G[0:3, 6:9] = -so3.hat(dR_check @ lever_arm) @ dR_check\n",
         mistake="−[ΔŘ t]× ΔŘ = −ΔŘ [t]×"),
    Edit("relative_pose_jacobian", G_THC, "    G[3:6, 18:21] = -np.linalg.inv(dR_check)\n", mistake="−ΔŘ⁻¹"),
    Edit("relative_pose_jacobian", G_PC + G_LEVER,
         "    G[0:3, 15:21] = np.hstack([-R_clone.T, np.cross(np.eye(3), dp_check + dR_check @ lever_arm)])\n",
         mistake="the two y_p blocks at once, the lever arm by cross products (e_i × q = −q × e_i)"),
    Edit("drift_segments", D_R, "        r_err[s] = np.degrees(np.linalg.norm(so3.Log(dR_true @ dR.T))) * 100.0 / L\n",
         mistake="ΔR_true ΔRᵀ (the same angle), np.degrees"),
    Edit("drift_segments", D_R, "        r_err[s] = np.degrees(np.arccos(np.clip((np.trace(dR.T @ dR_true) - 1.0) / 2.0, "
                                "-1.0, 1.0))) / (L / 100.0)\n",
         mistake="the angle from the trace"),
    Edit("drift_segments", D_T, "        t_err[s] = np.linalg.norm(dR.T @ (dp_true - dp)) / L * 100.0\n",
         mistake="the translation of ΔT_est⁻¹ ΔT_true (the devkit's form: same length)"),
    Edit("nis_rescaled_std", NIS_LINE,
         "    nis = np.einsum('ni,nij,nj->n', innovation, np.linalg.inv(S), innovation)\n", mistake="einsum with inv"),
    Edit("nis_rescaled_std", NIS_LINE,
         "    z = np.linalg.solve(np.linalg.cholesky(S), innovation[..., None])[..., 0]\n"
         "    nis = np.sum(z**2, axis=1)\n", mistake="whitened by the Cholesky factor"),
    Edit("nis_rescaled_std", RATIO,
         "    from scipy.stats import chi2\n    ratio = np.median(nis) / chi2.median(innovation.shape[1])\n",
         mistake="scipy's χ² median"),
]
