"""Chapter 02 (Gaussians): plausible mistakes in the exercise's functions.

The solution's cells: ``conditional`` (gaussian_conditional, graded by conditional_mean and
conditional_covariance), ``linear`` (linear_map_moments, one fix region for the whole step:
the moments of y = G x + n for a noise correlated with x, derived by the learner)
and ``challenge`` (gaussian_fusion, the optional challenge).
"""

from mutation_harness import Edit, Equivalent

NOTEBOOK = "02_gaussians"

_MEAN = "mean = mu_x + Sigma_xy @ np.linalg.solve(Sigma_yy, y - mu_y)"
_COV = "cov = Sigma_xx - Sigma_xy @ np.linalg.solve(Sigma_yy, Sigma_xy.T)"
_RET = "return mean, 0.5 * (cov + cov.T)"
# the linear map, with a noise correlated with x (cross-covariance Sigma_xn)
_CROSS = "G @ Sigma_xn + Sigma_xn.T @ G.T"
_SYY = f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + R"
_SXY = "Sigma_xy = Sigma_xx @ G.T + Sigma_xn"
_DEF = "def linear_map_moments(mu_x, Sigma_xx, G, R, Sigma_xn):"
_MUY = "mu_y = G @ mu_x"
_LRET = "return mu_y, Sigma_yy, Sigma_xy"
# the linear map's fix region: the whole step
_MOMENTS = _MUY + "\n    " + _SYY + "\n    " + _SXY
# the challenge's fix region
_FUSE = ("gain = Sigma_a @ np.linalg.inv(Sigma_a + Sigma_b)    # how far to move from a towards b\n"
         "    mean = mu_a + gain @ (mu_b - mu_a)\n"
         "    cov = Sigma_a - gain @ Sigma_a")

MUTANTS = [
    # --- behaviour: arguments changed in place, single precision (issue 25) -----------------
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx\n    cov -= Sigma_xy @ np.linalg.solve(Sigma_yy, Sigma_xy.T)",
         keyword="in place", mistake="the Schur complement subtracted into the caller's Σ_xx"),
    Edit("conditional_mean", _MEAN,
         "y -= mu_y\n    mean = mu_x + Sigma_xy @ np.linalg.solve(Sigma_yy, y)",
         keyword="in place", mistake="the mean of y subtracted into the caller's y"),
    Edit("linear_map_moments", _SYY, f"R += G @ Sigma_xx @ G.T + {_CROSS}\n    Sigma_yy = R",
         keyword="in place", mistake="the mapped covariance added into the caller's R"),
    Edit("linear_map_moments", _MUY, "mu_y = (G @ mu_x).astype(np.float32)",
         keyword="single precision", mistake="μ_y in float32"),
    # --- conditional_mean ---------------------------------------------------------------
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy @ (y - mu_y)",
         keyword="inverse of Σ_yy", mistake="Σ_yy⁻¹ left out"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy @ Sigma_yy @ (y - mu_y)",
         keyword="where its inverse belongs", mistake="Σ_yy instead of Σ_yy⁻¹"),
    Edit("conditional_mean", _MEAN, "mean = mu_x - Sigma_xy @ np.linalg.solve(Sigma_yy, y - mu_y)",
         keyword="sign", mistake="the correction subtracted"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy @ np.linalg.solve(Sigma_yy, mu_y - y)",
         keyword="sign", mistake="innovation μ_y − y"),
    Edit("conditional_mean", _MEAN, "mean = mu_x",
         keyword="did not move", mistake="the prior mean returned"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy @ np.linalg.solve(Sigma_yy, y)",
         keyword="mean of y is missing", mistake="innovation y instead of y − μ_y"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy @ ((y - mu_y) / np.diag(Sigma_yy))",
         keyword="diagonal",
         mistake="the scalar formula σ_xy / σ_yy² per component, diagonal only (the stub)"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy.T @ np.linalg.solve(Sigma_yy, y - mu_y)",
         keyword="transposed", mistake="Σ_xy transposed in the gain"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + Sigma_xy @ np.linalg.solve(Sigma_yy, y - mu_x)",
         keyword="not μ_x", mistake="innovation y − μ_x"),
    Edit("conditional_mean", _MEAN, "mean = mu_y + Sigma_xy @ np.linalg.solve(Sigma_yy, y - mu_y)",
         keyword="starts from μ_x", mistake="starts from μ_y"),
    Edit("conditional_mean", _MEAN, "mean = mu_x + np.linalg.solve(Sigma_yy, Sigma_xy) @ (y - mu_y)",
         keyword="transpose", mistake="gain as solve(Σ_yy, Σ_xy) (Σ_yy⁻¹ Σ_xy, shapes only fit for n = m)"),
    # a transposed Σ_xy in the covariance line breaks the whole function when n ≠ m: the mean
    # check must say so rather than show numpy's solve error
    Edit("conditional_mean", _COV, "cov = Sigma_xx - Sigma_xy @ np.linalg.solve(Sigma_yy, Sigma_xy)",
         keyword="transposed", mistake="Σ_xy instead of Σ_yx in the covariance (raises for n ≠ m)"),
    Edit("conditional_mean", _RET, "return cov, mean",
         keyword="order", mistake="(cov, mean) returned"),

    # --- conditional_covariance ---------------------------------------------------------
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx + Sigma_xy @ np.linalg.solve(Sigma_yy, Sigma_xy.T)",
         keyword="sign", mistake="the Schur term added"),
    Edit("conditional_covariance", _COV, "cov = Sigma_xx",
         keyword="did not shrink", mistake="the prior covariance returned"),
    Edit("conditional_covariance", _COV, "cov = Sigma_xx - Sigma_xy @ Sigma_xy.T",
         keyword="Σ_yy⁻¹ is missing", mistake="Σ_yy⁻¹ left out"),
    Edit("conditional_covariance", _COV, "cov = Sigma_xx - Sigma_xy @ Sigma_yy @ Sigma_xy.T",
         keyword="where its inverse belongs", mistake="Σ_yy instead of Σ_yy⁻¹"),
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx - Sigma_xy @ (Sigma_xy.T / np.diag(Sigma_yy)[:, None])",
         keyword="diagonal", mistake="only the variances of y used"),
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx - Sigma_xy @ np.linalg.solve(Sigma_yy, Sigma_xy)",
         keyword="transposed", mistake="Σ_xy where Σ_yx belongs (the issue's raw solve error)"),
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx - Sigma_xy.T @ np.linalg.solve(Sigma_yy, Sigma_xy)",
         keyword="transposed", mistake="Σ_xy and Σ_yx swapped"),
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx - np.linalg.inv(Sigma_yy) @ Sigma_xy.T @ Sigma_xy",
         keyword="wrong order", mistake="factors in the wrong order, Σ_yy⁻¹ Σ_yx Σ_xy"),
    Edit("conditional_covariance", _COV,
         "cov = Sigma_yy - Sigma_xy.T @ np.linalg.solve(Sigma_xx, Sigma_xy)",
         keyword="y given x", mistake="the Schur complement of the other block, Σ_y|x (the stub)"),
    Edit("conditional_covariance", _RET, "return mean, Sigma_xx",
         keyword="did not shrink", mistake="the prior covariance returned at the end"),
    Edit("conditional_covariance", _RET, "return cov, mean",
         keyword="order", mistake="(cov, mean) returned"),

    # --- linear_map_moments: y = G x + n with the noise correlated with x ----------------
    # the noise's covariance R, added wrongly (the cross terms right)
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS}",
         keyword="R is missing", mistake="R left out"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + R @ R",
         keyword="not R R", mistake="R R instead of R"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + np.sqrt(R)",
         keyword="standard deviation", mistake="√R (element-wise) instead of R"),
    Edit("linear_map_moments", _SYY,
         f"w, V = np.linalg.eigh(R)\n    Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + (V * np.sqrt(w)) @ V.T",
         keyword="standard deviation", mistake="the matrix square root of R instead of R"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + np.linalg.inv(R)",
         keyword="R⁻¹", mistake="R⁻¹ instead of R"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} - R",
         keyword="sign", mistake="R subtracted"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + np.diag(np.diag(R))",
         keyword="diagonal of R", mistake="only the noise variances (diagonal of R) added"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + R ** 2",
         keyword="do not square", mistake="R squared element-wise"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + np.eye(len(R))",
         keyword="identity", mistake="unit noise assumed (R = I)"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G.T @ Sigma_xx @ G + {_CROSS} + R",
         keyword="transposed", mistake="Gᵀ Σ_xx G"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G + {_CROSS} + R",
         keyword="transpose", mistake="the last G not transposed"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + G @ R @ G.T",
         keyword="after the map", mistake="noise pushed through the map"),
    Edit("linear_map_moments", _SYY, "Sigma_yy = Sigma_xx + Sigma_xn + Sigma_xn.T + R",
         keyword="map G must appear", mistake="G left out of Σ_yy, also of its cross terms"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ (Sigma_xx + R) @ G.T + {_CROSS}",
         keyword="after the map", mistake="the noise added to x before the map, y = G (x + n)"),
    # the cross terms of the correlation: the derivation the exercise asks for
    Edit("linear_map_moments", _SYY, "Sigma_yy = G @ Sigma_xx @ G.T + R",
         keyword="correlated", mistake="Σ_yy of an independent noise (lecture 02 §5's formula)"),
    Edit("linear_map_moments", _SYY, "Sigma_yy = G @ Sigma_xx @ G.T + G @ Sigma_xn + R",
         keyword="only one of the two cross terms", mistake="the cross term G Σ_xn alone"),
    Edit("linear_map_moments", _SYY, "Sigma_yy = G @ Sigma_xx @ G.T + Sigma_xn.T @ G.T + R",
         keyword="only one of the two cross terms", mistake="the cross term Σ_xnᵀ Gᵀ alone"),
    Edit("linear_map_moments", _SYY,
         "Sigma_yy = G @ Sigma_xx @ G.T + G @ Sigma_xn + R\n    Sigma_yy = (Sigma_yy + Sigma_yy.T) / 2",
         keyword="half of the cross terms", mistake="one cross term, then symmetrised (half of both)"),
    Edit("linear_map_moments", _SYY, "Sigma_yy = G @ Sigma_xx @ G.T + 2 * G @ Sigma_xn + R",
         keyword="transposes of each other", mistake="2 G Σ_xn: the cross terms taken as equal"),
    Edit("linear_map_moments", _SYY, "Sigma_yy = G @ Sigma_xx @ G.T + 2 * Sigma_xn.T @ G.T + R",
         keyword="transposes of each other", mistake="2 Σ_xnᵀ Gᵀ: the cross terms taken as equal"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T - ({_CROSS}) + R",
         keyword="sign", mistake="the cross terms subtracted"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + 2 * ({_CROSS}) + R",
         keyword="counted twice", mistake="each cross term counted twice"),
    Edit("linear_map_moments", _SYY,
         "Sigma_yy = G @ Sigma_xx @ G.T + G @ Sigma_xn.T + Sigma_xn @ G.T + R",
         keyword="Σ_xn is transposed", mistake="Σ_xn transposed in the cross terms (a shape error for n ≠ m)"),
    Edit("linear_map_moments", _SYY,
         "Sigma_yy = G @ Sigma_xx @ G.T + G.T @ Sigma_xn + Sigma_xn.T @ G + R",
         keyword="Gᵀ stands where G belongs", mistake="Gᵀ Σ_xn + Σ_xnᵀ G as the cross terms"),
    Edit("linear_map_moments", _SYY, "Sigma_yy = G @ Sigma_xx @ G.T + Sigma_xn + Sigma_xn.T + R",
         keyword="missing from the cross terms", mistake="Σ_xn + Σ_xnᵀ as the cross terms, without G"),
    # the cross-covariance Σ_xy
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T",
         keyword="correlated", mistake="Σ_xy of an independent noise (lecture 02 §5's formula)"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T - Sigma_xn",
         keyword="sign", mistake="Σ_xn subtracted in Σ_xy"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T + Sigma_xn.T",
         keyword="Σ_xn is transposed", mistake="Σ_nx = Σ_xnᵀ added (a shape error for n ≠ m)"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T + G @ Sigma_xn",
         keyword="added after the map", mistake="G Σ_xn in Σ_xy"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T + Sigma_xn @ G.T",
         keyword="added after the map", mistake="Σ_xn Gᵀ in Σ_xy"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T + 2 * Sigma_xn",
         keyword="counted twice", mistake="Σ_xn counted twice in Σ_xy"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = G @ Sigma_xx + Sigma_xn.T",
         keyword="Σ_yx", mistake="Σ_yx = G Σ_xx + Σ_xnᵀ instead of Σ_xy"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = G @ Sigma_xx + Sigma_xn",
         keyword="Σ_yx", mistake="G Σ_xx + Σ_xn"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx + Sigma_xn",
         keyword="map G must appear", mistake="G left out of Σ_xy"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx",
         keyword="map G must appear", mistake="Σ_xy = Σ_xx"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = G.T @ Sigma_xx + Sigma_xn",
         keyword="comes first", mistake="Gᵀ Σ_xx + Σ_xn"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx @ G.T + Sigma_xn + R",
         keyword="no part of Σ_xy", mistake="R added to the cross-covariance"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = (Sigma_xx @ G.T + Sigma_xn) @ np.linalg.inv(Sigma_yy)",
         keyword="gain", mistake="the Kalman gain instead of the cross-covariance"),
    Edit("linear_map_moments", _MUY, "mu_y = mu_x",
         keyword="through the map", mistake="μ_y = μ_x"),
    Edit("linear_map_moments", _MUY, "mu_y = mu_x @ G",
         keyword="transposed", mistake="μ_x G, i.e. Gᵀ μ_x"),
    Edit("linear_map_moments", _LRET, "return mu_y, Sigma_xy, Sigma_yy",
         keyword="swapped", mistake="Σ_yy and Σ_xy returned in the wrong order"),
    Edit("linear_map_moments", _DEF, "def linear_map_moments(mu_x, Sigma_xx, G, R):",
         keyword="five arguments", mistake="the lecture's four-argument signature kept"),
    # the whole step (issue 14): its placeholder and its plausible mistakes
    Edit("linear_map_moments", _MOMENTS, "mu_y, Sigma_yy, Sigma_xy = mu_x, Sigma_xx, Sigma_xx",
         keyword="moments of x itself", mistake="the moments of x returned as those of y (the stub)"),
    Edit("linear_map_moments", _MOMENTS,
         "mu_y = G @ mu_x\n    Sigma_yy = G @ Sigma_xx @ G.T + R\n    Sigma_xy = Sigma_xx @ G.T",
         keyword="correlated", mistake="the whole step of lecture 02 §5, for an independent noise"),
    Edit("linear_map_moments", _MOMENTS,
         "mu_y, Sigma_yy, Sigma_xy = G @ mu_x, R, Sigma_xx @ G.T + Sigma_xn",
         keyword="only the noise", mistake="Σ_yy = R, the uncertainty of x forgotten"),
    Edit("linear_map_moments", _MOMENTS,
         f"mu_y = G @ mu_x\n    Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + R\n"
         "    Sigma_xy = G @ Sigma_xx + Sigma_xn.T",
         keyword="Σ_yx", mistake="the whole step with Σ_yx for Σ_xy"),
    Edit("linear_map_moments", _MOMENTS,
         "mu_y, Sigma_yy, Sigma_xy = G @ mu_x, G @ Sigma_xx @ G.T, Sigma_xx @ G.T",
         keyword="R is missing", mistake="a noise-free sensor (neither R nor the correlation)"),

    # --- gaussian_fusion (optional challenge) -------------------------------------------
    Edit("gaussian_fusion", _FUSE,
         "cov = 1.0 / (1.0 / Sigma_a + 1.0 / Sigma_b)\n"
         "    mean = cov @ (mu_a / np.diag(Sigma_a) + mu_b / np.diag(Sigma_b))",
         keyword="element by element", mistake="the 1-D formulas applied entry by entry (the stub)"),
    Edit("gaussian_fusion", _FUSE,
         "cov = np.linalg.inv(np.linalg.inv(Sigma_a) + np.linalg.inv(Sigma_b))\n"
         "    mean = cov @ (mu_a / np.diag(Sigma_a) + mu_b / np.diag(Sigma_b))",
         keyword="variances alone", mistake="the right covariance, the means weighed by variances only"),
    Edit("gaussian_fusion", _FUSE, "cov = Sigma_a + Sigma_b\n    mean = (mu_a + mu_b) / 2",
         keyword="smaller than both", mistake="covariances added as for a sum of variables"),
    Edit("gaussian_fusion", _FUSE, "cov = (Sigma_a + Sigma_b) / 2\n    mean = (mu_a + mu_b) / 2",
         keyword="average", mistake="both averaged"),
    Edit("gaussian_fusion", _FUSE,
         "cov = np.linalg.inv(Sigma_a + Sigma_b)\n    mean = mu_a + cov @ Sigma_a @ (mu_b - mu_a)",
         keyword="sum of the inverses", mistake="the inverse of the sum"),
    Edit("gaussian_fusion", "gain = Sigma_a @ np.linalg.inv(Sigma_a + Sigma_b)",
         "gain = Sigma_b @ np.linalg.inv(Sigma_a + Sigma_b)",
         keyword="swapped", mistake="the gain built with Σ_b (the weights swapped)"),
    Edit("gaussian_fusion", "mean = mu_a + gain @ (mu_b - mu_a)",
         "mean = mu_a + (np.eye(len(mu_a)) - gain) @ (mu_b - mu_a)",
         keyword="swapped", mistake="the mean moved by I − K: towards the less certain estimate"),
    Edit("gaussian_fusion", "mean = mu_a + gain @ (mu_b - mu_a)", "mean = (mu_a + mu_b) / 2",
         keyword="plain average", mistake="the right covariance, an unweighted mean"),
    Edit("gaussian_fusion", "mean = mu_a + gain @ (mu_b - mu_a)", "mean = mu_a",
         keyword="did not move", mistake="the first estimate's mean kept"),
    Edit("gaussian_fusion", "cov = Sigma_a - gain @ Sigma_a", "cov = Sigma_a",
         keyword="did not shrink", mistake="the first estimate's covariance kept"),
    Edit("gaussian_fusion", "cov = Sigma_a - gain @ Sigma_a",
         "cov = Sigma_a @ Sigma_b @ np.linalg.inv(Sigma_a + Sigma_b)",
         keyword="wrong order", mistake="Σ_a Σ_b (Σ_a + Σ_b)⁻¹, factors out of order"),
    Edit("gaussian_fusion", "return mean, 0.5 * (cov + cov.T)", "return cov, mean",
         keyword="order", mistake="(cov, mean) returned"),
]

EQUIVALENTS = [
    Edit("conditional_mean", _MEAN,
         "mean = mu_x + Sigma_xy @ np.linalg.inv(Sigma_yy) @ (y - mu_y)",
         mistake="an explicit inverse (the lecture's Σ_yy⁻¹)"),
    Edit("conditional_mean", _MEAN,
         "K = np.linalg.solve(Sigma_yy, Sigma_xy.T).T\n    mean = mu_x + K @ (y - mu_y)",
         mistake="the gain form K = Σ_xy Σ_yy⁻¹ by a solve with Σ_yx"),
    Edit("conditional_mean", _MEAN,
         "L = np.linalg.cholesky(Sigma_yy)\n"
         "    w = np.linalg.solve(L.T, np.linalg.solve(L, y - mu_y))\n"
         "    mean = mu_x + Sigma_xy @ w",
         mistake="two triangular solves with the Cholesky factor"),
    Edit("conditional_mean", _MEAN,
         "mean = mu_x + Sigma_xy @ np.linalg.lstsq(Sigma_yy, y - mu_y, rcond=None)[0]",
         mistake="least squares"),
    Edit("conditional_mean", _MEAN,
         "n = len(mu_x)\n"
         "    Lam = np.linalg.inv(np.block([[Sigma_xx, Sigma_xy], [Sigma_xy.T, Sigma_yy]]))\n"
         "    mean = mu_x - np.linalg.solve(Lam[:n, :n], Lam[:n, n:] @ (y - mu_y))",
         mistake="the precision form from the inverse of the joint covariance (lecture's Schur route)"),
    Edit("conditional_mean", _MEAN,
         "mean = mu_x + np.linalg.solve(Sigma_yy, y - mu_y) @ Sigma_xy.T",
         mistake="row vector times Σ_xyᵀ (a 1-D vector on the left)"),
    Edit("conditional_mean", _RET, "return [mean, 0.5 * (cov + cov.T)]",
         mistake="a list instead of a tuple"),
    Edit("conditional_mean", _MEAN,
         "mean = mu_x + np.einsum('ij,j->i', Sigma_xy, np.linalg.solve(Sigma_yy, y - mu_y))",
         mistake="einsum"),
    Edit("conditional_covariance", _COV,
         "cov = Sigma_xx - Sigma_xy @ np.linalg.inv(Sigma_yy) @ Sigma_xy.T",
         mistake="an explicit inverse"),
    Edit("conditional_covariance", _COV,
         "K = np.linalg.solve(Sigma_yy, Sigma_xy.T).T\n    cov = Sigma_xx - K @ Sigma_yy @ K.T",
         mistake="Σ_xx − K Σ_yy Kᵀ"),
    Edit("conditional_covariance", _COV,
         "K = np.linalg.solve(Sigma_yy, Sigma_xy.T).T\n"
         "    cov = Sigma_xx - K @ Sigma_xy.T - Sigma_xy @ K.T + K @ Sigma_yy @ K.T",
         mistake="the expanded (Joseph-like) form"),
    Edit("conditional_covariance", _COV,
         "L = np.linalg.cholesky(Sigma_yy)\n    W = np.linalg.solve(L, Sigma_xy.T)\n"
         "    cov = Sigma_xx - W.T @ W",
         mistake="Cholesky: Σ_xy L⁻ᵀ L⁻¹ Σ_yx as WᵀW"),
    Edit("conditional_covariance", _COV,
         "n = len(mu_x)\n"
         "    cov = np.linalg.inv(np.linalg.inv(np.block([[Sigma_xx, Sigma_xy], "
         "[Sigma_xy.T, Sigma_yy]]))[:n, :n])",
         mistake="the precision form: the inverse of the xx block of the joint precision"),
    Edit("conditional_covariance", _RET, "return [mean, cov]",
         mistake="a list, without the final symmetrisation"),
    Edit("linear_map_moments", _SXY, "Sigma_xy = (G @ Sigma_xx).T + Sigma_xn",
         mistake="Σ_xy as (G Σ_xx)ᵀ + Σ_xn"),
    Edit("linear_map_moments", _SYY,
         f"Sigma_yy = np.einsum('ij,jk,lk->il', G, Sigma_xx, G) + {_CROSS} + R",
         mistake="einsum"),
    Edit("linear_map_moments", _SYY, f"Sigma_yy = G @ (G @ Sigma_xx).T + {_CROSS} + R",
         mistake="G (G Σ_xx)ᵀ + the cross terms + R"),
    Edit("linear_map_moments", _SYY,
         "cross = G @ Sigma_xn\n    Sigma_yy = G @ Sigma_xx @ G.T + cross + cross.T + R",
         mistake="one cross term and its transpose"),
    Edit("linear_map_moments", _SYY,
         f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + R\n    Sigma_yy = (Sigma_yy + Sigma_yy.T) / 2",
         mistake="Σ_yy symmetrised"),
    Edit("linear_map_moments", _LRET, "return [mu_y, Sigma_yy, Sigma_xy]",
         mistake="a list instead of a tuple"),
    Edit("linear_map_moments", _MUY, "mu_y = np.dot(G, mu_x)", mistake="np.dot"),
    Edit("linear_map_moments", _MOMENTS,
         "n = len(mu_x)\n"
         "    T = np.block([[np.eye(n), np.zeros((n, len(R)))], [G, np.eye(len(R))]])   # [x; y] = T [x; n]\n"
         "    joint = T @ np.block([[Sigma_xx, Sigma_xn], [Sigma_xn.T, R]]) @ T.T\n"
         "    mu_y = G @ mu_x\n"
         "    Sigma_yy = joint[n:, n:]\n"
         "    Sigma_xy = joint[:n, n:]",
         mistake="the blocks of T Cov([x; n]) Tᵀ, lecture 02 §5's compact form with Cov([x; n]) full"),
    Edit("linear_map_moments", _MOMENTS,
         "mu_y = G @ mu_x\n    Sigma_xy = Sigma_xx @ G.T + Sigma_xn\n"
         "    Sigma_yy = G @ Sigma_xy + Sigma_xn.T @ G.T + R",
         mistake="Σ_yy from Σ_xy, as G Σ_xy + Σ_xnᵀ Gᵀ + R"),
    Edit("linear_map_moments", _MOMENTS,
         "mu_y = G @ mu_x\n    Sigma_xy = Sigma_xx @ G.T + Sigma_xn\n"
         "    Sigma_yy = G @ Sigma_xy + (G @ Sigma_xn).T + R",
         mistake="Σ_yy from Σ_xy, with the second cross term as (G Σ_xn)ᵀ"),
    Edit("gaussian_fusion", _FUSE,
         "mean, cov = gaussian_conditional(mu_a, mu_a, Sigma_a, Sigma_a, Sigma_a + Sigma_b, mu_b)",
         mistake="conditioning with G = I: b is a reading of x with noise Σ_b"),
    Edit("gaussian_fusion", _FUSE,
         "mu_y, Sigma_yy, Sigma_xy = linear_map_moments(mu_a, Sigma_a, np.eye(len(mu_a)), Sigma_b,\n"
         "                                                np.zeros_like(Sigma_a))\n"
         "    mean, cov = gaussian_conditional(mu_a, mu_y, Sigma_a, Sigma_xy, Sigma_yy, mu_b)",
         mistake="the exercise's two functions chained, G = I"),
    Edit("gaussian_fusion", _FUSE,
         "info = np.linalg.inv(Sigma_a) + np.linalg.inv(Sigma_b)\n"
         "    cov = np.linalg.inv(info)\n"
         "    mean = cov @ (np.linalg.solve(Sigma_a, mu_a) + np.linalg.solve(Sigma_b, mu_b))",
         mistake="the information form"),
    Edit("gaussian_fusion", _FUSE,
         "gain = np.linalg.solve(Sigma_a + Sigma_b, Sigma_b).T\n"
         "    mean = mu_b + gain @ (mu_a - mu_b)\n"
         "    cov = Sigma_b - gain @ Sigma_b",
         mistake="the roles of a and b exchanged"),
    Edit("gaussian_fusion", _FUSE,
         "gain = Sigma_a @ np.linalg.inv(Sigma_a + Sigma_b)\n"
         "    mean = mu_a + gain @ (mu_b - mu_a)\n"
         "    cov = gain @ Sigma_b",
         mistake="Σ = Σ_a (Σ_a + Σ_b)⁻¹ Σ_b"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("conditional_covariance", _RET, "return mean, cov",
               reason="Σ_xx − Σ_xy Σ_yy⁻¹ Σ_xyᵀ is symmetric up to round-off (~1e-15 relative): "
                      "symmetrising it, or not, changes nothing the check's tolerance sees"),
    Equivalent("linear_map_moments", _SYY, f"Sigma_yy = G @ Sigma_xx @ G.T + {_CROSS} + R.T",
               reason="R is symmetric, so R.T is R"),
    Equivalent("linear_map_moments", _SXY, "Sigma_xy = Sigma_xx.T @ G.T + Sigma_xn",
               reason="Σ_xx is symmetric, so Σ_xxᵀ Gᵀ is Σ_xx Gᵀ"),
]
