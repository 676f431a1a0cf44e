"""Generated mutants (``tests/mutation_generator.py``) that cannot change any result the check
sees, each with the reason; ``tests/test_generated_mutants.py`` grades each and requires it to
pass (an entry that a check starts rejecting was not equivalent: move it out and report it),
and requires every entry to be one the generator still makes.

An entry names its mutant by the check and the generated edit's ``mistake`` (``"<class>:
<what changed>"``, as ``python tests/test_generated_mutants.py`` prints it). Real mistakes that
a check misses are never listed here: they are reported to the check's owner.
"""

from dataclasses import dataclass


@dataclass(frozen=True)
class GeneratedEquivalent:
    """A generated mutant that cannot change any result, and why.

    Parameters
    ----------
    check : str
        The grader check of the mutated region.
    mutant : str
        The generated edit's ``mistake``.
    reason : str
        Why no input the check may give can tell it from the solution.
    """

    check: str
    mutant: str
    reason: str


SYMMETRIC = ("transposes a covariance (or its inverse, or a diagonal matrix), which is symmetric by the "
             "function's contract: Aᵀ = A for every input a caller may give")
ONE_D = "transposes a 1-D array, which .T returns unchanged"
CLIPPED = ("moves a slice's end one past the array's last index along that axis, which slicing clips back "
           "to the same slice")
NORMALISED = ("negates the product before it is normalised: the sum changes sign with it, so the posterior "
              "is the same")
PRODUCT_COMMUTES = ("histogram_update multiplies its two arguments element by element before normalising, so "
                    "their order cannot matter")
NOT_THIS_CHECK = ("changes the mean's shape, which conditional_covariance does not judge (conditional_mean, the "
                  "same function's other check, rejects it)")
SQUARED_SIGN = "negates I − KG, which the Joseph form uses twice: (−A) P (−A)ᵀ = A P Aᵀ"
MIDPOINT = ("swaps the readings at the start and the end of the step of a midpoint step, which uses only their "
            "mean")
NOISE_SIGN = ("negates a block of the noise Jacobian B, which enters only as B Q Bᵀ: the block's sign cancels "
              "(a sign choice the lecture's conventions allow, accepted as issue 25 asks)")

EQUIVALENTS = [
    # --- chapter 01 ---
    GeneratedEquivalent('histogram_update',
                        "flip_sign: the value of 'unnormalised = likelihood * belief' negated",
                        NORMALISED),
    GeneratedEquivalent('histogram_predict',
                        "transpose: 'belief' transposed in 'transition @ belief'",
                        ONE_D),
    GeneratedEquivalent('histogram_filter',
                        "swap_args: arguments 1 and 2 of 'histogram_update(belief, likelihood)' swapped",
                        PRODUCT_COMMUTES),
    # --- chapter 02 ---
    GeneratedEquivalent('conditional_mean',
                        "transpose: 'np.linalg.solve(Sigma_yy, y - mu_y)' transposed in 'Sigma_xy @ np.linalg.solve(Sigma_yy, y - mu_y)'",
                        ONE_D),
    GeneratedEquivalent('conditional_covariance',
                        "reshape: 'mean' returned as a column (n, 1)",
                        NOT_THIS_CHECK),
    GeneratedEquivalent('linear_map_moments',
                        "transpose: 'mu_x' transposed in 'G @ mu_x'",
                        ONE_D),
    GeneratedEquivalent('linear_map_moments',
                        "transpose: 'Sigma_xx' transposed in 'G @ Sigma_xx @ G.T'",
                        SYMMETRIC),
    GeneratedEquivalent('linear_map_moments',
                        "transpose: 'Sigma_xx' transposed in 'Sigma_xx @ G.T'",
                        SYMMETRIC),
    GeneratedEquivalent('gaussian_fusion',
                        "transpose: 'Sigma_a' transposed in 'Sigma_a @ np.linalg.inv(Sigma_a + Sigma_b)'",
                        SYMMETRIC),
    GeneratedEquivalent('gaussian_fusion',
                        "transpose: 'np.linalg.inv(Sigma_a + Sigma_b)' transposed in 'Sigma_a @ np.linalg.inv(Sigma_a + Sigma_b)'",
                        SYMMETRIC),
    GeneratedEquivalent('gaussian_fusion',
                        "transpose: 'mu_b - mu_a' transposed in 'gain @ (mu_b - mu_a)'",
                        ONE_D),
    GeneratedEquivalent('gaussian_fusion',
                        "transpose: 'Sigma_a' transposed in 'gain @ Sigma_a'",
                        SYMMETRIC),
    # --- chapter 03 ---
    GeneratedEquivalent('cv_process_noise',
                        "transpose: 'sigma_a ** 2 * I' transposed in 'B @ (sigma_a ** 2 * I) @ B.T'",
                        SYMMETRIC),
    GeneratedEquivalent('kf_predict',
                        "transpose: 'P_hat' transposed in 'F @ P_hat @ F.T'",
                        SYMMETRIC),
    GeneratedEquivalent('kf_gain',
                        "transpose: 'P_check' transposed in 'G @ P_check @ G.T'",
                        SYMMETRIC),
    GeneratedEquivalent('kf_gain',
                        "transpose: 'P_check' transposed in 'P_check @ G.T @ np.linalg.inv(S)'",
                        SYMMETRIC),
    GeneratedEquivalent('kf_gain',
                        "transpose: 'np.linalg.inv(S)' transposed in 'P_check @ G.T @ np.linalg.inv(S)'",
                        SYMMETRIC),
    GeneratedEquivalent('kf_update',
                        "flip_sign: the value of 'I_KG = np.eye(len(x_check)) - K @ G' negated",
                        SQUARED_SIGN),
    GeneratedEquivalent('kf_update',
                        "transpose: 'x_check' transposed in 'G @ x_check'",
                        ONE_D),
    GeneratedEquivalent('kf_update',
                        "transpose: 'innovation' transposed in 'K @ innovation'",
                        ONE_D),
    GeneratedEquivalent('kf_update',
                        "transpose: 'P_check' transposed in 'I_KG @ P_check @ I_KG.T'",
                        SYMMETRIC),
    GeneratedEquivalent('kf_update',
                        "transpose: 'R' transposed in 'K @ R @ K.T'",
                        SYMMETRIC),
    # --- chapter 04 ---
    GeneratedEquivalent('ctrv_step',
                        "transpose: 'c' transposed in 'c @ np.cos(psi + K * np.pi / 2)'",
                        ONE_D),
    GeneratedEquivalent('ctrv_step',
                        "transpose: 'np.cos(psi + K * np.pi / 2)' transposed in 'c @ np.cos(psi + K * np.pi / 2)'",
                        ONE_D),
    GeneratedEquivalent('ctrv_step',
                        "transpose: 'c' transposed in 'c @ np.sin(psi + K * np.pi / 2)'",
                        ONE_D),
    GeneratedEquivalent('ctrv_step',
                        "transpose: 'np.sin(psi + K * np.pi / 2)' transposed in 'c @ np.sin(psi + K * np.pi / 2)'",
                        ONE_D),
    GeneratedEquivalent('ctrv_process_noise',
                        "transpose: 'np.diag([sigma_a ** 2, sigma_yaw ** 2])' transposed in 'B @ np.diag([sigma_a ** 2, sigma_yaw ** 2]) @ B.T'",
                        SYMMETRIC),
    # --- chapter 05 ---
    GeneratedEquivalent('ekf_update',
                        "transpose: 'P_check' transposed in 'G_k @ P_check @ G_k.T'",
                        SYMMETRIC),
    GeneratedEquivalent('ekf_update',
                        "transpose: 'P_check' transposed in 'P_check @ G_k.T @ np.linalg.inv(S)'",
                        SYMMETRIC),
    GeneratedEquivalent('ekf_update',
                        "transpose: 'np.linalg.inv(S)' transposed in 'P_check @ G_k.T @ np.linalg.inv(S)'",
                        SYMMETRIC),
    GeneratedEquivalent('ekf_update',
                        "transpose: 'innovation' transposed in 'K @ innovation'",
                        ONE_D),
    GeneratedEquivalent('ekf_update',
                        "transpose: 'P_check' transposed in '(np.eye(len(x_check)) - K @ G_k) @ P_check'",
                        SYMMETRIC),
    # --- chapter 06 ---
    GeneratedEquivalent('iekf_mean_step',
                        "transpose: 'P_check' transposed in 'P_check @ G_op.T @ np.linalg.inv(G_op @ P_check @ G_op.T + R)'",
                        SYMMETRIC),
    GeneratedEquivalent('iekf_mean_step',
                        "transpose: 'np.linalg.inv(G_op @ P_check @ G_op.T + R)' transposed in 'P_check @ G_op.T @ np.linalg.inv(G_op @ P_check @ G_op.T + R)'",
                        SYMMETRIC),
    GeneratedEquivalent('iekf_mean_step',
                        "transpose: 'P_check' transposed in 'G_op @ P_check @ G_op.T'",
                        SYMMETRIC),
    GeneratedEquivalent('iekf_mean_step',
                        "transpose: 'x_check - x_op' transposed in 'G_op @ (x_check - x_op)'",
                        ONE_D),
    GeneratedEquivalent('iekf_mean_step',
                        "transpose: 'correction' transposed in 'K @ correction'",
                        ONE_D),
    GeneratedEquivalent('iekf_converged',
                        "transpose: 'step' transposed in 'step @ np.linalg.solve(P_check, step)'",
                        ONE_D),
    GeneratedEquivalent('iekf_converged',
                        "transpose: 'np.linalg.solve(P_check, step)' transposed in 'step @ np.linalg.solve(P_check, step)'",
                        ONE_D),
    # --- chapter 07 ---
    GeneratedEquivalent('velocity_step',
                        "transpose: 'f0 - b_a' transposed in 'R0 @ (f0 - b_a)'",
                        ONE_D),
    GeneratedEquivalent('velocity_step',
                        "transpose: 'f1 - b_a' transposed in 'R1 @ (f1 - b_a)'",
                        ONE_D),
    GeneratedEquivalent('mechanisation_run',
                        "swap_args: arguments 2 and 3 of 'attitude_step(R[i - 1], imu.angular_rate[k - 1], imu.angular_rate[k], zero, dt)' swapped",
                        MIDPOINT),
    GeneratedEquivalent('mechanisation_run',
                        "swap_args: arguments 2 and 3 of 'position_step(p[i - 1], v[i - 1], v[i], dt)' swapped",
                        MIDPOINT),
    GeneratedEquivalent('level_attitude',
                        "transpose: 'up_body' transposed in 'up_body @ UP'",
                        ONE_D),
    GeneratedEquivalent('level_attitude',
                        "transpose: 'UP' transposed in 'up_body @ UP'",
                        ONE_D),
    # --- chapter 08 ---
    GeneratedEquivalent('eskf_noise_jacobian',
                        "flip_sign: the value of 'B[3:6, 0:3] = R' negated",
                        NOISE_SIGN),
    GeneratedEquivalent('eskf_propagate',
                        "transpose: 'P' transposed in 'F @ P @ F.T'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_propagate',
                        "transpose: 'Q' transposed in 'B @ Q @ B.T'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_gain',
                        "transpose: 'P' transposed in 'G @ P @ G.T'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_gain',
                        "transpose: 'P' transposed in 'P @ G.T @ np.linalg.inv(S)'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_gain',
                        "transpose: 'np.linalg.inv(S)' transposed in 'P @ G.T @ np.linalg.inv(S)'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_covariance_update',
                        "transpose: 'P' transposed in 'I_KG @ P @ I_KG.T'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_covariance_update',
                        "transpose: 'R' transposed in 'K @ R @ K.T'",
                        SYMMETRIC),
    GeneratedEquivalent('eskf_inject',
                        "index: index 15 → 16 in 'dx[12:15]'",
                        CLIPPED),
    GeneratedEquivalent('eskf_run',
                        "transpose: 'y' transposed in 'K @ y'",
                        ONE_D),
    GeneratedEquivalent('nominal_ekf_observation',
                        "transpose: 'q_meas' transposed in 'q_meas @ q_check'",
                        ONE_D),
    GeneratedEquivalent('nominal_ekf_observation',
                        "transpose: 'q_check' transposed in 'q_meas @ q_check'",
                        ONE_D),
    GeneratedEquivalent('nominal_ekf_jacobian',
                        "index: index 16 → 17 in 'A[6:10, 13:16]'",
                        CLIPPED),
    # --- chapter 09 ---
    GeneratedEquivalent('consistency_nees',
                        "transpose: 'error' transposed in 'error @ np.linalg.solve(P, error)'",
                        ONE_D),
    GeneratedEquivalent('consistency_nees',
                        "transpose: 'np.linalg.solve(P, error)' transposed in 'error @ np.linalg.solve(P, error)'",
                        ONE_D),
    GeneratedEquivalent('consistency_nis',
                        "transpose: 'P_check' transposed in 'G @ P_check @ G.T'",
                        SYMMETRIC),
    GeneratedEquivalent('innovation_gate',
                        "transpose: 'innovation' transposed in 'innovation @ np.linalg.solve(S, innovation)'",
                        ONE_D),
    GeneratedEquivalent('innovation_gate',
                        "transpose: 'np.linalg.solve(S, innovation)' transposed in 'innovation @ np.linalg.solve(S, innovation)'",
                        ONE_D),
    # --- chapter 10 ---
    GeneratedEquivalent('relative_motion',
                        "transpose: 'p1 - p0' transposed in 'R0.T @ (p1 - p0)'",
                        ONE_D),
    GeneratedEquivalent('relative_pose_jacobian',
                        "index: index 21 → 22 in 'G[0:3, 18:21]'",
                        CLIPPED),
    GeneratedEquivalent('relative_pose_jacobian',
                        "index: index 6 → 7 in 'G[3:6, 18:21]'",
                        CLIPPED),
    GeneratedEquivalent('relative_pose_jacobian',
                        "index: index 21 → 22 in 'G[3:6, 18:21]'",
                        CLIPPED),
    GeneratedEquivalent('nis_rescaled_std',
                        "transpose: 'v' transposed in 'v @ np.linalg.solve(S_k, v)'",
                        ONE_D),
    GeneratedEquivalent('nis_rescaled_std',
                        "transpose: 'np.linalg.solve(S_k, v)' transposed in 'v @ np.linalg.solve(S_k, v)'",
                        ONE_D),
    # the cast comes after the subtraction: the error of a state perturbed by h keeps float32's 7
    # significant digits of a value of size h, so J changes by ~1e-7 relative, far below the check's
    # tolerance (1e-5) and the differences' own truncation error: harmless, not a missed mistake
    GeneratedEquivalent('eskf_fd_transition',
                        "float32: 'np.concatenate([nominal.position - true.position, nominal.velocity - true.velocity, so3.Log(true.rotation.T @ nominal.rotation), nominal.accel_bias - true.accel_bias, nominal.gyro_bias - true.gyro_bias])' returned as float32",
                        "casts the error vector, a difference of size h taken in float64, to float32: J keeps "
                        "about 7 significant digits, a change far below the central differences' own error"),
]
