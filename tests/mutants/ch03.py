"""Chapter 03 (the Kalman filter): plausible mistakes in the exercise's functions."""

from mutation_harness import Edit

NOTEBOOK = "03_kalman_filter"

MUTANTS = [
    Edit("kf_predict", "P_check = F @ P_hat @ F.T + Q", "P_check = F @ P_hat @ F.T",
         keyword="process noise", mistake="Q left out of the prediction"),
    Edit("kf_gain", "K = P_check @ G.T @ np.linalg.inv(S)", "K = P_check @ G.T @ np.linalg.inv(R)",
         keyword="R⁻¹", mistake="R⁻¹ instead of S⁻¹"),
]

EQUIVALENTS = [
    Edit("kf_gain", "K = P_check @ G.T @ np.linalg.inv(S)", "K = np.linalg.solve(S, G @ P_check).T",
         mistake="gain by a solve instead of an inverse"),
]

EQUIVALENT_MUTANTS = []
