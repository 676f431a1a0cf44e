"""Chapter 09 (tuning and consistency): plausible mistakes in the exercise's functions.

Checks and tolerances (``kalman_course/checks/consistency.py``):

- consistency_nees, consistency_nis, chi2_interval: rtol 1e-6 (``RTOL``). Every correct
  way of writing them (solve, inv, pinv, Cholesky, einsum, scipy's χ² quantiles) agrees to
  ~1e-12 relative on the cases; every wrong formula in the check's catalogue is off by at
  least 2 % on some case (the closest: the Wilson–Hilferty approximation, 2.5 %).
- innovation_gate, consistency_verdict: exact decisions. No NIS is closer than 1 % to its
  gate threshold and no mean closer than 0.5 % to a bound, so rounding (solve vs inv, the χ²
  quantile from scipy or the package) cannot flip a decision; ≤ vs < and > vs ≥ are therefore equivalent mutants (a NIS exactly on a
  quantile has probability zero and cannot be constructed so that every correct way of
  computing it lands on it).
- monte_carlo_nees (challenge): exact decisions per time step on Monte Carlo runs of the
  simulated ESKF; no run average lies within 1e-4 (relative) of its bound.
"""

import nbformat

from mutation_harness import SOLUTIONS, Edit, Equivalent

NOTEBOOK = "09_tuning_consistency"

NEES = "    return float(error @ np.linalg.solve(P, error))"
S_LINE = "    S = G @ P_check @ G.T + R\n"
NIS_RET = "    return nees(innovation, S)"  # the NIS through the learner's nees, with S
P_LINE = "    p_lo, p_hi = (1 - confidence) / 2, (1 + confidence) / 2\n"
LO = "    lo = chi2_ppf(p_lo, dof * n_runs) / n_runs\n"
HI = "    hi = chi2_ppf(p_hi, dof * n_runs) / n_runs\n"
LOHI = LO + HI
GATE_V = "    value = innovation @ np.linalg.solve(S, innovation)\n"
GATE_T = "    threshold = chi2_ppf(confidence, len(innovation))\n"
GATE_R = "    return bool(value <= threshold)"
BOUNDS = "    lo, hi = chi2_interval(dof, len(nis_values), confidence)  # your interval, from above\n"
MEAN = "    mean = np.mean(nis_values)\n"
IFS = ('    if mean > hi:\n        return "overconfident"\n'
       '    if mean < lo:\n        return "underconfident"\n')
CONSISTENT = '    return "consistent"\n'
# the whole steps: the gate's and the verdict's reference bodies
GATE_BODY = GATE_V + GATE_T + GATE_R
VERDICT_BODY = BOUNDS + MEAN + IFS + CONSISTENT
# the challenge (monte_carlo_inside)
MC_AVG = "    average = np.mean(nees_runs, axis=0)\n"
MC_BOUNDS = "    lo, hi = chi2_interval(dof, nees_runs.shape[0], confidence)\n"
MC_RET = "    return (average >= lo) & (average <= hi)"


def _nees(new, keyword, mistake):
    return Edit("consistency_nees", NEES, new, keyword=keyword, mistake=mistake)


def _nis(old, new, keyword, mistake):
    return Edit("consistency_nis", old, new, keyword=keyword, mistake=mistake)


def _interval(old, new, keyword, mistake):
    return Edit("chi2_interval", old, new, keyword=keyword, mistake=mistake)


def _gate(old, new, keyword, mistake):
    return Edit("innovation_gate", old, new, keyword=keyword, mistake=mistake)


def _verdict(old, new, keyword, mistake):
    return Edit("consistency_verdict", old, new, keyword=keyword, mistake=mistake)


def _mc(old, new, keyword, mistake):
    return Edit("monte_carlo_nees", old, new, keyword=keyword, mistake=mistake)


def _tail(cell_id, start):
    """The source of a solution cell from ``start`` to its end (for edits that append a def)."""
    nb = nbformat.read(SOLUTIONS / f"{NOTEBOOK}.ipynb", as_version=4)
    source = next(c.source for c in nb.cells if c.id == cell_id)
    return source[source.index(start):]


VERDICT_TAIL = _tail("verdict", BOUNDS)
NIS_TAIL = _tail("nis", S_LINE)
VIA_INTERVAL = "    lo, hi = chi2_interval(dof, len(nis_values), confidence)\n"
# a learner's own chi2_interval that ignores n_runs (the stub), used by verdict
BROKEN_INTERVAL = ("def chi2_interval(dof, n_runs, confidence=0.95):\n"
                   "    return chi2_ppf((1 - confidence) / 2, dof), chi2_ppf((1 + confidence) / 2, dof)\n")
# a learner's own nees with P instead of P⁻¹, defined where nis / gate can call it
BROKEN_NEES = "def nees(error, P):\n    return float(error @ P @ error)\n\n\n"

MUTANTS = [
    # ---- consistency_nees: ε = eᵀ P⁻¹ e
    _nees("    return float(error @ P @ error)", "INVERSE", "P instead of P⁻¹"),
    _nees("    return float(error @ error)", "not eᵀ e", "P left out"),
    _nees("    return float(error @ np.linalg.solve(P, error)) / len(error)", "dimension",
          "divided by the dimension"),
    _nees("    return float(np.sqrt(error @ np.linalg.solve(P, error)))", "Mahalanobis",
          "the Mahalanobis distance (square root)"),
    _nees("    return float(error @ np.linalg.solve(P, error)) ** 2", "squared twice", "NEES squared"),
    _nees("    return 0.5 * float(error @ np.linalg.solve(P, error))", "½",
          "the ½ of the Gaussian exponent"),
    _nees("    z = error / np.sqrt(np.diag(P))\n    return float(z @ z)", "diagonal",
          "each component's z-score, squared and summed: the correlations dropped (the stub)"),
    _nees("    return float(np.sum(error ** 2 / np.diag(P)))", "diagonal",
          "only the variances, correlations dropped"),
    _nees("    return float(np.sum(error ** 2 / np.sqrt(np.diag(P))))", "standard deviation",
          "divided by the standard deviations instead of the variances"),
    _nees("    return float(np.sum((error / np.diag(P)) ** 2))", "variance twice",
          "divided by the variance, then squared"),
    _nees("    return float(np.linalg.solve(P, error) @ np.linalg.solve(P, error))", "applied twice",
          "P⁻¹ e dotted with itself (eᵀ P⁻² e)"),
    _nees("    return float(np.sum(np.linalg.solve(P, error)))", "dot product",
          "sum of P⁻¹ e instead of its dot product with e"),
    _nees("    z = np.linalg.solve(np.linalg.cholesky(P).T, error)\n    return float(z @ z)", "Cholesky",
          "whitened with L⁻ᵀ instead of L⁻¹"),
    _nees("    return float(error @ np.linalg.solve(np.linalg.cholesky(P), error))", "one side only",
          "eᵀ L⁻¹ e with the Cholesky factor"),
    _nees("    return float(error @ np.linalg.solve(np.sqrt(P), error))", "element-wise",
          "element-wise √P (standard deviations) as the weight"),
    _nees("    return float(error @ (1 / P) @ error)", "inverts each entry", "1 / P instead of P⁻¹"),
    _nees("    return np.linalg.solve(P, error)", "vector", "returns P⁻¹ e (a vector)"),
    _nees("    return np.outer(error, np.linalg.solve(P, error))", "outer product",
          "e (P⁻¹ e)ᵀ: transpose on the wrong side"),
    _nees("    error[:] = np.linalg.solve(np.linalg.cholesky(P), error)  # whitened in place\n"
          "    return float(error @ error)", "in place", "the caller's error whitened in place"),
    _nees("    return np.float32(error @ np.linalg.solve(P, error))", "single precision", "NEES returned as float32"),
    _nees("    Pf, ef = P.astype(np.float32), error.astype(np.float32)\n"
          "    return np.linalg.solve(Pf, ef) @ ef", "single precision", "computed in float32"),

    # ---- consistency_nis: ν̃ = νᵀ S⁻¹ ν, S = G P̌ Gᵀ + R
    _nis(S_LINE, "    S = G @ P_check @ G.T\n", "observation noise", "R left out of S"),
    _nis(S_LINE, "    S = R\n", "G P̌ Gᵀ is missing", "only R"),
    _nis(S_LINE, "    S = G.T @ P_check @ G + R\n", "wrong side", "Gᵀ P̌ G"),
    _nis(S_LINE, "    S = G @ P_check @ G + R\n", "transpose of the second G", "missing transpose"),
    _nis(S_LINE, "    S = G @ G.T @ P_check + R\n", "order of the products", "G Gᵀ P̌"),
    _nis(S_LINE, "    S = G @ P_check @ G.T + np.sqrt(R)\n", "variances", "√R (standard deviations)"),
    _nis(S_LINE, "    S = G @ P_check @ G.T + R @ R\n", "variances", "R R"),
    _nis(S_LINE, "    S = G @ P_check @ G.T + R ** 2\n", "variances", "R squared element-wise"),
    _nis(S_LINE, "    S = G @ P_check @ G.T + np.diag(R)\n", "adds to every row", "np.diag(R) broadcast"),
    _nis(S_LINE, "    S = G @ P_check @ G.T + np.linalg.inv(R)\n", "R⁻¹", "R⁻¹ added"),
    _nis(S_LINE, "    S = G @ P_check @ G.T - R\n", "sign", "R subtracted"),
    _nis(S_LINE, "    S = P_check[:len(innovation), :len(innovation)] + R\n", "FIRST m error states",
         "the first m × m block of P̌ instead of G P̌ Gᵀ (the stub)"),
    _nis(S_LINE, "    S = P_check + R\n", "mapped into the measurement", "P̌ + R (fails on 15-state G)"),
    _nis(NIS_RET, "    return float(innovation @ S @ innovation)", "INVERSE", "S instead of S⁻¹"),
    _nis(NIS_RET, "    return float(innovation @ (1 / S) @ innovation)", "inverts each entry", "1 / S"),
    _nis(NIS_RET, "    return float(innovation @ np.linalg.solve(S, innovation)) / len(innovation)",
         "dimension", "divided by the dimension"),
    _nis(NIS_RET, "    return float(np.sqrt(innovation @ np.linalg.solve(S, innovation)))", "Mahalanobis",
         "square root"),
    _nis(NIS_RET, "    return float(np.sum(innovation ** 2 / np.diag(S)))", "diagonal", "diagonal of S"),
    _nis(NIS_RET, "    return float(innovation @ (np.linalg.inv(G @ P_check @ G.T) + np.linalg.inv(R)) @ innovation)",
         "add the covariances first", "(G P̌ Gᵀ)⁻¹ + R⁻¹"),
    _nis(NIS_RET, "    return float(innovation @ np.linalg.solve(P_check, innovation))", "P̌⁻¹",
         "the state's prior P̌ instead of S (only square G)"),
    _nis(NIS_RET, "    innovation[:] = np.linalg.solve(np.linalg.cholesky(S), innovation)  # whitened in place\n"
                  "    return float(innovation @ innovation)", "in place", "the caller's innovation whitened in place"),
    _nis(S_LINE, "    S = R\n    S += G @ P_check @ G.T\n", "in place", "S built in the caller's R (S = R aliases it)"),
    _nis(NIS_RET, "    return np.float32(nees(innovation, S))", "single precision", "NIS returned as float32"),
    _nis(NIS_RET, NIS_RET + "\n\n\n" + BROKEN_NEES, "fix nees first",
         "nis through the learner's own nees, which is wrong (dependency)"),

    _nis(NIS_TAIL, NIS_TAIL.replace(S_LINE, "    S = G @ P_check @ G.T\n")
                          .replace(NIS_RET, "    return float(innovation @ np.linalg.solve(S, innovation))")
         + "\n\n\n" + BROKEN_NEES,
         "observation noise", "R left out while a wrong nees, which nis does not call, is defined: "
                              "the hint must blame nis, not nees"),

    # ---- chi2_interval: F⁻¹((1 ∓ c)/2; dof · n_runs) / n_runs
    _interval(P_LINE, "    p_lo, p_hi = 0.0, confidence\n", "one-sided", "one-sided interval (the stub)"),
    _interval(P_LINE, "    p_lo, p_hi = 1 - confidence, confidence\n", "(1 − c)/2 each", "tails 1 − c"),
    _interval(P_LINE, "    p_lo, p_hi = confidence / 2, 1 - confidence / 2\n", "INSIDE", "c taken as α"),
    _interval(P_LINE, "    p_lo, p_hi = (1 - confidence) / 2, confidence\n", "hi is the c quantile",
              "upper tail 1 − c, lower (1 − c)/2"),
    _interval(P_LINE, "    p_lo, p_hi = 1 - confidence, (1 + confidence) / 2\n", "lo is the (1 − c) quantile",
              "lower tail 1 − c, upper (1 − c)/2"),
    _interval(P_LINE, "    p_lo, p_hi = (1 + confidence) / 2, (1 - confidence) / 2\n", "swapped",
              "lo and hi swapped"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof)\n    hi = chi2_ppf(p_hi, dof)\n", "n_runs is ignored",
              "n_runs ignored (the stub)"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof * n_runs)\n    hi = chi2_ppf(p_hi, dof * n_runs)\n", "sum",
              "bounds of the sum, not the mean"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, n_runs) / n_runs\n    hi = chi2_ppf(p_hi, n_runs) / n_runs\n",
              "not n_runs", "dof n_runs instead of dof · n_runs"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof) / n_runs\n    hi = chi2_ppf(p_hi, dof) / n_runs\n",
              "χ²(dof · n_runs)", "quantiles of one value divided by n_runs"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof + n_runs) / n_runs\n    hi = chi2_ppf(p_hi, dof + n_runs) / n_runs\n",
              "dof + n_runs", "dof + n_runs degrees of freedom"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof * n_runs - 1) / n_runs\n"
                    "    hi = chi2_ppf(p_hi, dof * n_runs - 1) / n_runs\n", "off by one", "dof · n_runs − 1"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof * (n_runs - 1)) / n_runs\n"
                    "    hi = chi2_ppf(p_hi, dof * (n_runs - 1)) / n_runs\n", "off by one", "dof · (n_runs − 1)"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof * n_runs) * n_runs\n    hi = chi2_ppf(p_hi, dof * n_runs) * n_runs\n",
              "multiplied", "multiplied by n_runs"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof * n_runs) / (dof * n_runs)\n"
                    "    hi = chi2_ppf(p_hi, dof * n_runs) / (dof * n_runs)\n", "n_runs only",
              "divided by dof · n_runs"),
    _interval(LOHI, "    lo = chi2_ppf(p_lo, dof * n_runs) / np.sqrt(n_runs)\n"
                    "    hi = chi2_ppf(p_hi, dof * n_runs) / np.sqrt(n_runs)\n", "√n_runs", "divided by √n_runs"),
    _interval(LOHI, "    z = {0.9: 1.6448536269514722, 0.95: 1.959963984540054, 0.99: 2.5758293035489004}[confidence]\n"
                    "    lo = dof - z * np.sqrt(2 * dof / n_runs)\n    hi = dof + z * np.sqrt(2 * dof / n_runs)\n",
              "normal approximation", "normal approximation of the χ² mean"),
    _interval(LOHI, "    from scipy.stats import norm\n    k, z = dof * n_runs, norm.ppf(p_hi)\n"
                    "    lo = k * (1 - 2 / (9 * k) - z * np.sqrt(2 / (9 * k))) ** 3 / n_runs\n"
                    "    hi = k * (1 - 2 / (9 * k) + z * np.sqrt(2 / (9 * k))) ** 3 / n_runs\n",
              "Wilson–Hilferty", "Wilson–Hilferty approximation"),
    _interval("    return lo, hi", "    return lo", "two numbers", "returns only lo"),
    _interval("    return lo, hi", "    return np.float32(lo), np.float32(hi)", "single precision",
              "the bounds as float32"),

    # ---- innovation_gate: accept iff νᵀ S⁻¹ ν ≤ F⁻¹(confidence; m)
    _gate(GATE_BODY, "    return True", "refuses nothing", "accepts every innovation (the stub)"),
    _gate(GATE_V, "    innovation[:] = np.linalg.solve(np.linalg.cholesky(S), innovation)  # whitened in place\n"
                  "    value = innovation @ innovation\n", "in place", "the caller's innovation whitened in place"),
    _gate(GATE_BODY, "    return False", "never uses its sensor", "refuses every innovation"),
    _gate(GATE_BODY, "    lo, hi = chi2_interval(len(innovation), 1, confidence)\n"
                     "    return bool(lo <= nees(innovation, S) <= hi)", "one-sided",
          "the two-sided interval of one value, through the learner's chi2_interval"),
    _gate(GATE_BODY, "    return bool(nees(innovation, S) <= chi2_interval(len(innovation), 1, confidence)[1])",
          "(1 + c)/2", "the upper end of the learner's two-sided interval"),
    _gate(GATE_BODY, "    lo, hi = chi2_interval(len(innovation), 1, confidence)\n"
                     "    return bool(lo <= nees(innovation, S) <= hi)\n\n\n" + BROKEN_INTERVAL,
          "fix chi2_interval first", "gate through the learner's own chi2_interval, which is wrong (dependency)"),
    _gate(GATE_T, "    threshold = chi2_ppf(confidence, 1)\n", "ONE degree", "dof 1"),
    _gate(GATE_T, "    threshold = chi2_ppf(confidence, S.size)\n", "m²", "S.size degrees of freedom"),
    _gate(GATE_T, "    threshold = chi2_ppf(confidence, 6)\n", "6 degrees of freedom", "dof fixed at 6"),
    _gate(GATE_T, "    threshold = chi2_ppf(confidence, len(innovation) - 1)\n", "off by one", "dof m − 1"),
    _gate(GATE_T, "    threshold = chi2_ppf(confidence, 2 * len(innovation))\n", "wrong degrees of freedom",
          "2 m degrees of freedom"),
    _gate(GATE_T, "    threshold = chi2_ppf(1 - confidence, len(innovation))\n", "(1 − confidence) quantile",
          "1 − c quantile"),
    _gate(GATE_T, "    threshold = confidence\n", "not with the confidence", "compared with c"),
    _gate(GATE_T, "    threshold = chi2_ppf((1 + confidence) / 2, len(innovation))\n", "(1 + c)/2",
          "upper end of the two-sided interval"),
    _gate(GATE_T, "    threshold = chi2_ppf(0.99, len(innovation))\n", "argument", "99 % hard-coded"),
    _gate(GATE_T, "    threshold = chi2_ppf(0.95, len(innovation))\n", "argument", "95 % hard-coded"),
    _gate(GATE_T, "    threshold = np.sqrt(chi2_ppf(confidence, len(innovation)))\n", "√", "√ of the quantile"),
    _gate(GATE_R, "    return bool(value <= threshold ** 2)", "square of the χ² quantile", "quantile squared"),
    _gate(GATE_R, "    return bool(value >= threshold)", "reversed", "comparison reversed"),
    _gate(GATE_R, "    return bool(np.sqrt(value) <= threshold)", "Mahalanobis", "distance vs χ² quantile"),
    _gate(GATE_R, "    return bool(value / len(innovation) <= threshold)", "NIS is divided by the dimension",
          "NIS / m"),
    _gate(GATE_T, "    threshold = chi2_ppf(confidence, len(innovation)) / len(innovation)\n",
          "threshold is divided by the dimension", "threshold / m"),
    _gate(GATE_R, "    lo = chi2_ppf((1 - confidence) / 2, len(innovation))\n"
                  "    return bool(lo <= value <= chi2_ppf((1 + confidence) / 2, len(innovation)))",
          "one-sided", "two-sided test"),
    _gate(GATE_V, "    value = innovation @ S @ innovation\n", "inverse", "S instead of S⁻¹"),
    _gate(GATE_V, "    value = innovation @ innovation\n", "νᵀ ν", "S left out"),
    _gate(GATE_V, "    value = np.sum(innovation ** 2 / np.diag(S))\n", "diagonal", "diagonal of S"),
    _gate(GATE_R, "    return bool(nees(innovation, S) <= threshold)\n\n\n" + BROKEN_NEES, "fix nees first",
          "gate through the learner's own nees, which is wrong (dependency)"),

    # ---- consistency_verdict: mean NIS against chi2_interval(dof, N, c)
    _verdict(VERDICT_BODY, CONSISTENT, "not tested", "always 'consistent' (the stub)"),
    _verdict(IFS, '    if mean > hi:\n        return "underconfident"\n'
                  '    if mean < lo:\n        return "overconfident"\n', "swapped",
             "over/underconfident swapped"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof, 1, confidence)\n", "ONE value",
             "interval of one value, not of the mean"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof * len(nis_values), 1, confidence)\n", "SUM",
             "bounds of the sum compared with the mean"),
    _verdict(MEAN, "    mean = np.sum(nis_values)\n", "SUM of the values is compared",
             "sum compared with the mean's bounds"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof, len(nis_values), confidence)\n"
                     "    lo, hi = lo / len(nis_values), hi / len(nis_values)\n", "divided by N once more",
             "mean's bounds divided by N again"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof * len(nis_values), len(nis_values), confidence)\n",
             "counted twice", "N · dof passed as dof"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof, len(nis_values) - 1, confidence)\n", "N − 1",
             "N − 1 values"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(len(nis_values), dof, confidence)\n", "swapped",
             "dof and N swapped in the call"),
    _verdict(MEAN, "    mean = np.mean(nis_values) / dof\n", "divided by dof", "normalised mean, raw bounds"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof, len(nis_values), confidence)\n"
                     "    lo, hi = lo / dof, hi / dof\n", "bounds are divided by dof", "normalised bounds, raw mean"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof, len(nis_values), 1 - confidence)\n", "1 − c",
             "α instead of 1 − α"),
    _verdict(BOUNDS, "    lo, hi = chi2_ppf(1 - confidence, dof * len(nis_values)) / len(nis_values), "
                     "chi2_ppf(confidence, dof * len(nis_values)) / len(nis_values)\n", "(1 − c)/2 each",
             "tails 1 − c"),
    _verdict(BOUNDS, "    lo, hi = 0.0, chi2_ppf(confidence, dof * len(nis_values)) / len(nis_values)\n",
             "one-sided", "one-sided bound"),
    _verdict(IFS, '    if mean > hi:\n        return "overconfident"\n'
                  '    return "underconfident"\n', "only the upper bound", "never consistent: lower bound unused"),
    _verdict(BOUNDS, "    lo, hi = dof, dof\n", "not with dof itself", "mean compared with dof"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(dof, len(nis_values), 0.95)\n", "`confidence` argument",
             "95 % hard-coded"),
    _verdict(BOUNDS, "    lo, hi = chi2_interval(6, len(nis_values), confidence)\n", "`dof` argument",
             "dof 6 hard-coded"),
    _verdict(IFS, '    if mean > lo:\n        return "overconfident"\n'
                  '    if mean < hi:\n        return "underconfident"\n', "lo and hi are swapped",
             "lo and hi swapped in the comparisons"),
    _verdict('        return "overconfident"\n', '        return "over-confident"\n', "one of the strings",
             "misspelled verdict"),
    _verdict('    if mean < lo:\n', '    if mean < 0.9 * lo:\n', "below the lower bound",
             "a margin on the lower bound (mean < 0.9 lo)"),
    _verdict('    if mean > hi:\n', '    if mean > 1.05 * hi:\n', "above the upper bound",
             "a margin on the upper bound (mean > 1.05 hi)"),
    # the verdict taken from single values (the share inside the interval of one value), not from the mean
    _verdict(VERDICT_BODY, "    lo, hi = chi2_interval(dof, 1, confidence)\n"
                           "    if np.mean((nis_values >= lo) & (nis_values <= hi)) >= confidence:\n"
                           '        return "consistent"\n'
                           '    return "overconfident" if np.mean(nis_values) > dof else "underconfident"\n',
             "share of single", "the share of single NIS values inside the one-value interval, the side by the mean"),
    _verdict(VERDICT_BODY, "    lo, hi = chi2_interval(dof, 1, confidence)\n"
                           "    if np.mean(nis_values > hi) > (1 - confidence) / 2:\n"
                           '        return "overconfident"\n'
                           "    if np.mean(nis_values < lo) > (1 - confidence) / 2:\n"
                           '        return "underconfident"\n'
                           '    return "consistent"\n',
             "share of single", "each tail's share of single NIS values against (1 − c)/2"),
    _verdict(VERDICT_BODY, "    lo, hi = chi2_interval(dof, 1, confidence)\n"
                           "    above, below = np.mean(nis_values > hi), np.mean(nis_values < lo)\n"
                           "    if 1 - above - below >= confidence:\n"
                           '        return "consistent"\n'
                           '    return "overconfident" if above > below else "underconfident"\n',
             "share of single", "the share inside the one-value interval, the side by the fuller tail"),
    _verdict(BOUNDS, "    lo, hi = chi2_ppf((1 - confidence) / 2, dof), chi2_ppf((1 + confidence) / 2, dof)\n",
             "ONE value", "the interval of one χ²(dof) value written out, used for the mean"),
    _verdict(BOUNDS, "    N = len(nis_values)\n"
                     "    lo, hi = chi2_ppf((1 - confidence) / 2, dof) / N, chi2_ppf((1 + confidence) / 2, dof) / N\n",
             "N · dof degrees of freedom, not dof", "the quantiles of χ²(m) divided by N (m where N · m belongs)"),
    _verdict(BOUNDS, "    N = len(nis_values)\n"
                     "    lo, hi = chi2_ppf((1 - confidence) / 2, N) / N, chi2_ppf((1 + confidence) / 2, N) / N\n",
             "N · dof of them, not N", "the quantiles of χ²(N) divided by N (N where N · m belongs)"),
    _verdict(VERDICT_BODY, "    hi = chi2_ppf(confidence, dof * len(nis_values)) / len(nis_values)\n"
                           "    if np.mean(nis_values) > hi:\n"
                           '        return "overconfident"\n'
                           '    return "consistent"\n',
             "one-sided", "a one-sided test at the c quantile of the mean (never underconfident)"),
    _verdict(MEAN, "    nis_values.sort()  # sorted in place, to look at the extremes\n" + MEAN, "in place",
             "the caller's NIS record sorted in place"),
    _verdict(VERDICT_TAIL, VERDICT_TAIL.replace(BOUNDS, VIA_INTERVAL) + "\n\n\n" + BROKEN_INTERVAL,
             "fix chi2_interval first", "verdict through the learner's own chi2_interval, which is wrong (dependency)"),

    # ---- monte_carlo_nees (challenge): per step, the run average against chi2_interval(dof, n_runs, c)
    _mc(MC_AVG + MC_BOUNDS, "    average = np.mean(nees_runs, axis=1)\n"
                            "    lo, hi = chi2_interval(dof, nees_runs.shape[1], confidence)\n",
        "over time", "each run averaged over time, as for the NIS (the stub)"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof, nees_runs.shape[1], confidence)\n", "not the number of time steps",
        "n_runs taken from the steps axis"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof, 1, confidence)\n", "ONE run", "interval of one value"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof, nees_runs.size, confidence)\n", "every run AND every step",
        "all values as independent"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof * nees_runs.shape[0], 1, confidence)\n", "SUM",
        "bounds of the sum"),
    _mc(MC_AVG, "    average = np.sum(nees_runs, axis=0)\n", "SUM over the runs", "sum vs the mean's bounds"),
    _mc(MC_AVG, "    average = np.mean(nees_runs, axis=0) / dof\n", "divided by dof", "normalised average"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(nees_runs.shape[0], dof, confidence)\n", "swapped",
        "dof and n_runs swapped"),
    _mc(MC_BOUNDS, "    lo, hi = 0.0, chi2_ppf(confidence, dof * nees_runs.shape[0]) / nees_runs.shape[0]\n",
        "one-sided", "one-sided bound"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof, nees_runs.shape[0], 1 - confidence)\n", "1 − c",
        "α instead of 1 − α"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof, nees_runs.shape[0], 0.95)\n", "`confidence` argument",
        "95 % hard-coded"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(15, nees_runs.shape[0], confidence)\n", "`dof` argument",
        "15 dof hard-coded"),
    _mc(MC_BOUNDS, "    lo, hi = chi2_interval(dof, nees_runs.shape[0] - 1, confidence)\n", "n_runs − 1",
        "n_runs − 1"),
    _mc(MC_AVG, "    average = np.median(nees_runs, axis=0)\n", "median", "median of the runs"),
    _mc(MC_RET, "    return (average < lo) | (average > hi)", "swapped", "True outside"),
    _mc(MC_RET, "    return np.mean((average >= lo) & (average <= hi))", "one number", "returns the share"),
    _mc(MC_AVG + MC_BOUNDS,
        "    lo, hi = chi2_interval(dof, 1, confidence)\n"
        "    return np.all((nees_runs >= lo) & (nees_runs <= hi), axis=0)\n", "tested alone",
        "every run inside the one-value interval"),
    _mc(MC_RET, MC_RET + "\n\n\n" + BROKEN_INTERVAL, "fix chi2_interval first",
        "through the learner's own chi2_interval, which is wrong (dependency)"),
]


def _same(check, old, new, what):
    return Edit(check, old, new, mistake=what)


EQUIVALENTS = [
    # ---- consistency_nees
    _same("consistency_nees", NEES, "    return float(error @ np.linalg.inv(P) @ error)", "inverse instead of solve"),
    _same("consistency_nees", NEES, "    return float(error @ np.linalg.pinv(P) @ error)", "pseudo-inverse"),
    _same("consistency_nees", NEES, "    z = np.linalg.solve(np.linalg.cholesky(P), error)\n    return float(z @ z)",
          "Cholesky whitening z = L⁻¹ e"),
    _same("consistency_nees", NEES, "    from scipy.linalg import cho_factor, cho_solve\n"
                                    "    return float(error @ cho_solve(cho_factor(P), error))", "scipy cho_solve"),
    _same("consistency_nees", NEES, "    from scipy.linalg import sqrtm\n"
                                    "    z = np.linalg.solve(np.real(sqrtm(P)), error)\n    return float(z @ z)",
          "whitening by the symmetric square root P^(1/2)"),
    _same("consistency_nees", NEES, '    return float(np.einsum("i,ij,j->", error, np.linalg.inv(P), error))',
          "einsum"),
    _same("consistency_nees", NEES,
          "    e = error.reshape(-1, 1)\n    return float((e.T @ np.linalg.solve(P, e))[0, 0])",
          "column vectors with an explicit transpose"),
    _same("consistency_nees", NEES, "    return np.trace(np.linalg.solve(P, np.outer(error, error)))", "trace form"),
    _same("consistency_nees", NEES, "    return error @ np.linalg.solve(P, error)", "numpy scalar, no float()"),
    _same("consistency_nees", NEES, "    e = error[:, None]\n    return e.T @ np.linalg.solve(P, e)", "a (1, 1) array"),
    _same("consistency_nees", NEES, "    return float(np.sum(error * np.linalg.solve(P, error)))", "sum of products"),
    # ---- consistency_nis
    _same("consistency_nis", NIS_RET, "    return float(innovation @ np.linalg.inv(S) @ innovation)", "inverse of S"),
    _same("consistency_nis", S_LINE, "    S = G @ (P_check @ G.T) + R\n", "other association of the product"),
    _same("consistency_nis", S_LINE, "    S = np.linalg.multi_dot([G, P_check, G.T]) + R\n", "multi_dot"),
    _same("consistency_nis", S_LINE, '    S = np.einsum("ij,jk,lk->il", G, P_check, G) + R\n', "einsum"),
    _same("consistency_nis", NIS_RET, "    L = np.linalg.cholesky(S)\n    z = np.linalg.solve(L, innovation)\n"
                                      "    return float(z @ z)", "Cholesky whitening"),
    _same("consistency_nis", NIS_RET, "    return float(innovation @ np.linalg.solve(S, innovation))",
          "the quadratic form written out, not through nees"),
    _same("consistency_nis", NIS_RET, "    return innovation @ np.linalg.solve(S, innovation)", "numpy scalar"),
    # ---- chi2_interval
    _same("chi2_interval", LOHI, "    from scipy.stats import chi2\n    lo = chi2.ppf(p_lo, dof * n_runs) / n_runs\n"
                                 "    hi = chi2.ppf(p_hi, dof * n_runs) / n_runs\n", "scipy's chi2.ppf"),
    _same("chi2_interval", LOHI, "    from scipy.stats import chi2\n"
                                 "    lo, hi = np.array(chi2.interval(confidence, dof * n_runs)) / n_runs\n",
          "scipy's chi2.interval"),
    _same("chi2_interval", LOHI, "    from scipy.special import gammaincinv\n"
                                 "    lo = 2 * gammaincinv(dof * n_runs / 2, p_lo) / n_runs\n"
                                 "    hi = 2 * gammaincinv(dof * n_runs / 2, p_hi) / n_runs\n",
          "the χ² quantile through the inverse regularised gamma function"),
    _same("chi2_interval", P_LINE, "    alpha = 1 - confidence\n    p_lo, p_hi = alpha / 2, 1 - alpha / 2\n",
          "tails written with α = 1 − c"),
    _same("chi2_interval", "    return lo, hi", "    return [lo, hi]", "a list"),
    _same("chi2_interval", "    return lo, hi", "    return np.array([lo, hi])", "an array"),
    # ---- innovation_gate
    _same("innovation_gate", GATE_V, "    value = innovation @ np.linalg.inv(S) @ innovation\n", "inverse of S"),
    _same("innovation_gate", GATE_T, "    threshold = chi2_ppf(confidence, S.shape[0])\n", "dimension from S"),
    _same("innovation_gate", GATE_T, "    from scipy.stats import chi2\n"
                                     "    threshold = chi2.isf(1 - confidence, innovation.size)\n",
          "scipy's inverse survival function"),
    _same("innovation_gate", GATE_R, "    return not value > threshold", "negated rejection test (np.bool_)"),
    _same("innovation_gate", GATE_R, "    return bool(nees(innovation, S) <= threshold)", "through the (correct) nees"),
    # (calling the package's own gate passes the self-check but earns nothing in a graded run,
    # which withholds it: tests/test_withheld.py)
    # ---- consistency_verdict
    _same("consistency_verdict", BOUNDS, VIA_INTERVAL, "bounds from the (correct) chi2_interval"),
    _same("consistency_verdict", MEAN, "    mean = np.sum(nis_values) / len(nis_values)\n", "mean written out"),
    _same("consistency_verdict", BOUNDS, "    from scipy.stats import chi2\n"
                                         "    lo, hi = np.array(chi2.interval(confidence, dof * len(nis_values))) "
                                         "/ len(nis_values)\n", "scipy's chi2.interval"),
    _same("consistency_verdict", IFS, '    if hi < mean:\n        return "overconfident"\n'
                                      '    elif lo > mean:\n        return "underconfident"\n', "comparisons mirrored"),
    _same("consistency_verdict", MEAN + IFS,
          "    total = np.sum(nis_values)\n"
          "    n = len(nis_values)\n    if total > hi * n:\n        return \"overconfident\"\n"
          "    if total < lo * n:\n        return \"underconfident\"\n", "the sum against the sum's bounds"),
    # whole steps written another way
    _same("innovation_gate", GATE_BODY,
          "    return bool(nees(innovation, S) <= chi2_ppf(confidence, innovation.shape[0]))",
          "the whole gate in one line, through the (correct) nees"),
    _same("consistency_verdict", VERDICT_BODY,
          "    mean = float(np.mean(nis_values))\n    lo, hi = chi2_interval(dof, nis_values.size, confidence)\n"
          "    return \"overconfident\" if mean > hi else \"underconfident\" if mean < lo else \"consistent\"\n",
          "the whole verdict as one conditional expression"),
    # ---- monte_carlo_nees
    _same("monte_carlo_nees", MC_AVG, "    average = nees_runs.sum(axis=0) / len(nees_runs)\n", "mean written out"),
    _same("monte_carlo_nees", MC_AVG, "    average = nees_runs.T.mean(axis=1)\n", "mean of the transpose"),
    _same("monte_carlo_nees", MC_BOUNDS, "    lo, hi = chi2_interval(dof, len(nees_runs), confidence)\n",
          "n_runs as len()"),
    _same("monte_carlo_nees", MC_RET, "    return np.logical_and(average >= lo, average <= hi)", "logical_and"),
    _same("monte_carlo_nees", MC_RET, "    return [bool(lo <= a <= hi) for a in average]", "a list of bools"),
    _same("monte_carlo_nees", MC_RET, "    return ((average >= lo) & (average <= hi)).astype(int)", "0/1 integers"),
    _same("monte_carlo_nees", MC_AVG + MC_BOUNDS,
          "    from scipy.stats import chi2\n    n_runs = nees_runs.shape[0]\n"
          "    lo, hi = chi2.interval(confidence, dof * n_runs)\n    average = nees_runs.sum(axis=0)\n",
          "the sum over the runs against the sum's bounds (scipy)"),
]

EQUIVALENT_MUTANTS = [
    Equivalent("monte_carlo_nees", MC_RET, "    return (average > lo) & (average < hi)",
               reason="strict vs non-strict: no run average of the cases lies within 1e-4 (relative) of "
                      "a bound, and one exactly on it has probability zero"),
    Equivalent("innovation_gate", GATE_R, "    return bool(value < threshold)",
               reason="< vs ≤: a NIS exactly on the χ² quantile has probability zero, and no case can put "
                      "it there for every correct way of computing the NIS (solve, inv, Cholesky round "
                      "differently)"),
    Equivalent("consistency_verdict", IFS, '    if mean >= hi:\n        return "overconfident"\n'
                                           '    if mean <= lo:\n        return "underconfident"\n',
               reason="≥ vs >: a mean exactly on a bound has probability zero (and the bound itself "
                      "depends on how the quantile is computed)"),
    Equivalent("consistency_nis", S_LINE, "    S = G @ P_check @ G.T + R\n    S = 0.5 * (S + S.T)\n",
               reason="symmetrising S, which is already symmetric"),
    Equivalent("consistency_nis", S_LINE, "    S = G @ P_check.T @ G.T + R.T\n",
               reason="P̌ and R are symmetric, so transposing them changes nothing"),
    Equivalent("consistency_nees", NEES, "    return float(-error @ np.linalg.solve(P, -error))",
               reason="the sign of the error (estimate − truth or truth − estimate) cancels in eᵀ P⁻¹ e"),
    Equivalent("consistency_nis", NIS_RET, "    return float(-innovation @ np.linalg.solve(S, -innovation))",
               reason="the sign of the innovation (y − ŷ or ŷ − y) cancels in νᵀ S⁻¹ ν"),
    Equivalent("consistency_nees", NEES, "    error /= 1.0\n" + NEES,
               reason="a division by 1 in place leaves the caller's error as it was (the same values): "
                      "nothing changed, nothing to report"),
    Equivalent("consistency_nees", NEES, "    return float(error.T @ np.linalg.solve(P.T, error))",
               reason=".T of a 1-D error is a no-op, and P is symmetric"),
]
