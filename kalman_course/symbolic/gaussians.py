"""Gaussian algebra, derived: the Schur-complement block inverse, the moments of a linear
map and the conditional of a joint Gaussian (chapter 02).

Each builder returns a :class:`~kalman_course.symbolic.equations.Derivation` proved by
``verify()``, in SymPy matrix symbols of any size and, where the proof needs a symmetric
covariance, with small explicit symbolic matrices. The numeric counterparts live in
:mod:`kalman_course.core.gaussians`; the tests compare the two.
"""

from __future__ import annotations

import sympy as sp
from sympy.matrices.expressions import BlockMatrix, Identity, MatrixSymbol, ZeroMatrix

from kalman_course.symbolic.equations import (
    Derivation,
    Equation,
    canonical,
    derivation_builder,
    exact_inverse,
    symbol_matrix,
)

__all__ = ["schur_block_inverse", "linear_map_moments", "gaussian_conditioning"]


@derivation_builder
def schur_block_inverse() -> Derivation:
    """Block inverse of M = [[A, B], [C, D]] through the Schur complement of D.

    Proved twice: in matrix symbols of any size (the block LDU factorisation and
    M · M⁻¹ = I) and with explicit symbolic 3 × 3 and 4 × 4 matrices whose inverse is
    assembled from the formula and multiplied out.
    """
    n, m = sp.symbols("n m", integer=True, positive=True)
    A, B = MatrixSymbol("A", n, n), MatrixSymbol("B", n, m)
    C, D = MatrixSymbol("C", m, n), MatrixSymbol("D", m, m)
    In, Im, Znm, Zmn = Identity(n), Identity(m), ZeroMatrix(n, m), ZeroMatrix(m, n)
    Delta = MatrixSymbol(r"\Delta_D", n, n)
    delta_expr = A - B * D.I * C

    M = BlockMatrix([[A, B], [C, D]])
    upper = BlockMatrix([[In, B * D.I], [Zmn, Im]])
    middle = BlockMatrix([[delta_expr, Znm], [Zmn, D]])
    lower = BlockMatrix([[In, Znm], [D.I * C, Im]])
    upper_inv = BlockMatrix([[In, -B * D.I], [Zmn, Im]])
    lower_inv = BlockMatrix([[In, Znm], [-D.I * C, Im]])
    middle_inv = BlockMatrix([[delta_expr.I, Znm], [Zmn, D.I]])
    identity = BlockMatrix([[In, Znm], [Zmn, Im]])
    M_inv_factored = lower_inv * middle_inv * upper_inv
    M_inv_blocks = BlockMatrix([[delta_expr.I, -delta_expr.I * B * D.I],
                          [-D.I * C * delta_expr.I, D.I + D.I * C * delta_expr.I * B * D.I]])

    def explicit(nn: int, mm: int, tag: str) -> list[Equation]:
        Ae, Be = symbol_matrix("a", nn, nn), symbol_matrix("b", nn, mm)
        Ce, De = symbol_matrix("c", mm, nn), symbol_matrix("d", mm, mm)
        Me = sp.BlockMatrix([[Ae, Be], [Ce, De]]).as_explicit()
        Di = exact_inverse(De)
        Dsi = exact_inverse(Ae - Be * Di * Ce)  # inverse of the Schur complement
        Mi = canonical(sp.BlockMatrix([[Dsi, -Dsi * Be * Di],
                                    [-Di * Ce * Dsi, Di + Di * Ce * Dsi * Be * Di]]).as_explicit())
        size = nn + mm
        return [
            Equation(f"inverse_{tag}", Me * Mi, sp.eye(size),
                     f"explicit ${size} \\times {size}$ matrix (blocks of size {nn} and {mm}): "
                     "$M$ times the block formula is $I$",
                     "check"),
            Equation(f"inverse_left_{tag}", Mi * Me, sp.eye(size),
                     f"explicit ${size} \\times {size}$ matrix: the block formula is also a left inverse",
                     "check"),
        ]

    equations = [
        Equation("schur_complement", Delta, delta_expr,
                 "the Schur complement of $D$ in $M$", "definition"),
        Equation("ldu", M, upper * middle * lower,
                 "block LDU factorisation: upper-triangular, block-diagonal, lower-triangular"),
        Equation("upper_inverse", upper * upper_inv, identity,
                 "a unit upper-triangular block matrix is inverted by negating its corner"),
        Equation("lower_inverse", lower * lower_inv, identity,
                 "a unit lower-triangular block matrix is inverted by negating its corner"),
        Equation("inverse_factored", M * M_inv_factored, identity,
                 "$M^{-1}$ is the product of the three inverted factors in reverse order"),
        Equation("inverse_blocks", M_inv_factored, M_inv_blocks,
                 "multiplying the factors out gives the four blocks of $M^{-1}$"),
        *explicit(1, 1, "1x1"),
        *explicit(2, 1, "2x1"),
        *explicit(2, 2, "2x2"),
    ]
    return Derivation(
        name="schur_block_inverse",
        title="Block inverse through the Schur complement",
        model=(r"$M = \begin{bmatrix} A & B \\ C & D \end{bmatrix}$ with square blocks $A$ "
               r"($n\times n$) and $D$ ($m\times m$); $D$ and its Schur complement "
               r"$\Delta_D = A - B D^{-1} C$ are invertible."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "A": A, "B": B, "C": C, "D": D},
        results={"M": M, "schur_complement": delta_expr, "M_inv": M_inv_blocks},
    )


@derivation_builder
def linear_map_moments() -> Derivation:
    """Mean, covariance and cross-covariance of y = G x + n (x and n independent)."""
    n, m = sp.symbols("n m", integer=True, positive=True)
    mu_x = MatrixSymbol(r"\mu_x", n, 1)
    Sxx = MatrixSymbol(r"\Sigma_{xx}", n, n)
    G = MatrixSymbol("G", m, n)
    R = MatrixSymbol("R", m, m)
    In, Im, Znm, Zmn = Identity(n), Identity(m), ZeroMatrix(n, m), ZeroMatrix(m, n)
    # [x; y] = T [x; n]  with  T = [[I, 0], [G, I]];  Cov([x; n]) = blkdiag(Sxx, R)
    T = BlockMatrix([[In, Znm], [G, Im]])
    mean_xn = BlockMatrix([[mu_x], [ZeroMatrix(m, 1)]])
    cov_xn = BlockMatrix([[Sxx, Znm], [Zmn, R]])
    joint_mean = BlockMatrix([[mu_x], [G * mu_x]])
    joint_cov = BlockMatrix([[Sxx, Sxx * G.T], [G * Sxx, G * Sxx * G.T + R]])

    # explicit check: 2 states, 1 and 2 observations, symmetric covariances
    checks = []
    for mm in (1, 2):
        Se = symbol_matrix("s", 2, 2, symmetric=True)
        Ge = symbol_matrix("g", mm, 2)
        Re = symbol_matrix("r", mm, mm, symmetric=True)
        Te = sp.BlockMatrix([[sp.eye(2), sp.zeros(2, mm)], [Ge, sp.eye(mm)]]).as_explicit()
        cov = sp.diag(Se, Re)
        checks.append(Equation(
            f"joint_cov_2x{mm}", Te * cov * Te.T,
            sp.BlockMatrix([[Se, Se * Ge.T], [Ge * Se, Ge * Se * Ge.T + Re]]).as_explicit(),
            f"explicit check with a 2-D $x$ and a {mm}-D $y$", "check"))

    equations = [
        Equation("stacked", BlockMatrix([[MatrixSymbol("x", n, 1)], [MatrixSymbol("y", m, 1)]]),
                 T * BlockMatrix([[MatrixSymbol("x", n, 1)], [MatrixSymbol(r"\mathbf{n}", m, 1)]]),
                 "$x$ and $y$ are a linear map of the independent pair $(x, n)$", "definition"),
        Equation("joint_mean", T * mean_xn, joint_mean,
                 r"mean: $E[y] = G E[x] + E[n] = G \mu_x$"),
        Equation("joint_cov", T * cov_xn * T.T, joint_cov,
                 r"covariance of a linear map, $T \operatorname{Cov}([x; n]) T^T$: "
                 r"$\Sigma_{yy} = G \Sigma_{xx} G^T + R$, $\Sigma_{xy} = \Sigma_{xx} G^T$"),
        *checks,
    ]
    return Derivation(
        name="linear_map_moments",
        title="Moments of a linear map $y = G x + n$",
        model=(r"$x \sim \mathcal{N}(\mu_x, \Sigma_{xx})$ and $n \sim \mathcal{N}(0, R)$ are "
               r"independent, $y = G x + n$."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "mu_x": mu_x, "Sigma_xx": Sxx, "G": G, "R": R},
        results={"mu_y": G * mu_x, "Sigma_yy": G * Sxx * G.T + R, "Sigma_xy": Sxx * G.T},
    )


def _quadratic_split_check(nx: int, ny: int) -> list[Equation]:
    """Explicit proof that the joint quadratic form splits into conditional + marginal."""
    S = symbol_matrix("s", nx + ny, nx + ny, symmetric=True)
    Sxx, Sxy, Syy = S[:nx, :nx], S[:nx, nx:], S[nx:, nx:]
    ex, ey = symbol_matrix("e", nx, 1), symbol_matrix("f", ny, 1)  # e = x - mu_x, f = y - mu_y
    Syy_inv = exact_inverse(Syy)
    S_cond = canonical(Sxx - Sxy * Syy_inv * Sxy.T)
    r = canonical(ex - Sxy * Syy_inv * ey)  # x - conditional mean
    e = ex.col_join(ey)
    joint = (e.T * exact_inverse(S) * e)[0, 0]
    split = (r.T * exact_inverse(S_cond) * r)[0, 0] + (ey.T * Syy_inv * ey)[0, 0]
    tag = f"{nx}+{ny}"
    return [
        Equation(f"quadratic_split_{tag}", joint, split,
                 f"explicit ${nx}$-D $x$ and ${ny}$-D $y$: the joint exponent (with SymPy's own inverse) "
                 "is the conditional exponent plus the marginal one", "check"),
        Equation(f"determinant_split_{tag}", S.det(), S_cond.det() * Syy.det(),
                 f"explicit ${nx}$-D $x$ and ${ny}$-D $y$: "
                 r"$\det \Sigma = \det \Sigma_{x|y} \det \Sigma_{yy}$, so the normalising "
                 "constants split too", "check"),
    ]


@derivation_builder
def gaussian_conditioning() -> Derivation:
    """Conditional of a joint Gaussian: p(x, y) = p(x | y) p(y) through the Schur complement."""
    n, m = sp.symbols("n m", integer=True, positive=True)
    Sxx = MatrixSymbol(r"\Sigma_{xx}", n, n)
    Sxy = MatrixSymbol(r"\Sigma_{xy}", n, m)
    Syx = MatrixSymbol(r"\Sigma_{yx}", m, n)
    Syy = MatrixSymbol(r"\Sigma_{yy}", m, m)
    mu_x, mu_y = MatrixSymbol(r"\mu_x", n, 1), MatrixSymbol(r"\mu_y", m, 1)
    x, y = MatrixSymbol("x", n, 1), MatrixSymbol("y", m, 1)
    ex, ey = MatrixSymbol("e_x", n, 1), MatrixSymbol("e_y", m, 1)
    In, Im, Znm, Zmn = Identity(n), Identity(m), ZeroMatrix(n, m), ZeroMatrix(m, n)

    S_cond = Sxx - Sxy * Syy.I * Syx
    mu_cond = mu_x + Sxy * Syy.I * (y - mu_y)
    Sigma = BlockMatrix([[Sxx, Sxy], [Syx, Syy]])
    left = BlockMatrix([[In, Znm], [-Syy.I * Syx, Im]])
    middle = BlockMatrix([[S_cond.I, Znm], [Zmn, Syy.I]])
    right = BlockMatrix([[In, -Sxy * Syy.I], [Zmn, Im]])
    identity = BlockMatrix([[In, Znm], [Zmn, Im]])
    e = BlockMatrix([[ex], [ey]])
    e_row = BlockMatrix([[ex.T, ey.T]])
    quad_factored = e_row * left * middle * right * e
    quad_split = ((ex.T - ey.T * Syy.I * Syx) * S_cond.I * (ex - Sxy * Syy.I * ey)
                  + ey.T * Syy.I * ey)

    equations = [
        Equation("errors", BlockMatrix([[ex], [ey]]), BlockMatrix([[x - mu_x], [y - mu_y]]),
                 "deviations from the means", "definition"),
        Equation("inverse_factored", Sigma * (left * middle * right), identity,
                 "the Schur-complement factorisation inverts the joint covariance"),
        Equation("quadratic_form", quad_factored, quad_split,
                 "the joint exponent splits into a term in $x$ given $y$ plus a term in $y$ alone"),
        *_quadratic_split_check(1, 1),
        *_quadratic_split_check(2, 1),
        *_quadratic_split_check(1, 2),
        Equation("conditional_mean", MatrixSymbol(r"\mu_{x|y}", n, 1), mu_cond,
                 "so the first term is a Gaussian in $x$ with this mean ...", "definition"),
        Equation("conditional_cov", MatrixSymbol(r"\Sigma_{x|y}", n, n), S_cond,
                 r"... and this covariance (the Schur complement of $\Sigma_{yy}$); the second term is $p(y)$",
                 "definition"),
    ]
    return Derivation(
        name="gaussian_conditioning",
        title="Conditioning a joint Gaussian",
        model=(r"$\begin{bmatrix} x \\ y \end{bmatrix} \sim \mathcal{N}\left("
               r"\begin{bmatrix} \mu_x \\ \mu_y \end{bmatrix}, "
               r"\begin{bmatrix} \Sigma_{xx} & \Sigma_{xy} \\ \Sigma_{yx} & \Sigma_{yy} "
               r"\end{bmatrix}\right)$ with $\Sigma_{yx} = \Sigma_{xy}^T$; since "
               r"$p(x, y) = p(x \mid y)\, p(y)$, splitting the exponent and the determinant "
               r"identifies $p(x \mid y)$."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "mu_x": mu_x, "mu_y": mu_y, "Sigma_xx": Sxx, "Sigma_xy": Sxy,
                 "Sigma_yy": Syy, "y": y},
        results={"mean": mu_cond, "cov": Sxx - Sxy * Syy.I * Sxy.T},
    )
