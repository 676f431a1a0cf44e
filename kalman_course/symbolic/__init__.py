"""SymPy derivations behind the course: each one stated once, proved, and reusable.

A :class:`Derivation` is a short chain of :class:`Equation` objects. Each equation is one
of three kinds:

``"definition"``
    introduces a name (for example the Schur complement Δ = A − B D⁻¹ C); not checked.
``"identity"``
    a general statement, usually in SymPy matrix symbols of arbitrary size, that
    :meth:`Derivation.verify` proves by simplifying ``lhs − rhs`` to zero;
``"check"``
    the same kind of statement written out with small explicit symbolic matrices
    (2 × 2, 3 × 3, ...) where matrix symbols cannot carry the proof, for example because
    a covariance must be symmetric. Also proved by :meth:`Derivation.verify`.

:func:`derivations` returns every derivation by name; later chapters add their builders
to ``_BUILDERS``. The constant-velocity (CV) model's numeric matrices are generated from
its SymPy expressions (``lambdify``, cached): :func:`cv_transition`,
:func:`cv_process_noise`, :func:`cv_process_noise_continuous`, :func:`cv_noise_jacobian`
and :func:`cv_observation_matrix`.

CV state order
--------------
For ``dim`` spatial axes the CV state is **blocked**: all positions first, then all
velocities, ``x = [p_1, ..., p_dim, v_1, ..., v_dim]`` (in 2-D: ``[p_x, p_y, v_x, v_y]``).
This matches the ESKF error state ``[δp, δv, ...]`` and makes the position observation
``G = [I, 0]``. Per axis the model is the 2-state ``[p, v]``; the ``dim``-axis matrices
are Kronecker products ``kron(M_axis, I_dim)``.

Notation follows the course: prior x̌, P̌; posterior x̂, P̂; motion Jacobian F,
process-noise Jacobian B, process noise Q; observation Jacobian G, observation-noise
Jacobian C, observation noise R; gain K; innovation covariance S.
"""

from __future__ import annotations

import functools
import numbers
import types
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np
import sympy as sp
from sympy.matrices.expressions import BlockMatrix, Identity, MatrixExpr, MatrixSymbol, ZeroMatrix
from sympy.polys.fields import sfield
from sympy.polys.matrices import DomainMatrix

__all__ = [
    "Equation",
    "Derivation",
    "derivations",
    "derivation",
    "schur_block_inverse",
    "linear_map_moments",
    "gaussian_conditioning",
    "kalman_gain",
    "kf_update_conditioning",
    "cv_model",
    "cv_transition",
    "cv_process_noise",
    "cv_process_noise_continuous",
    "cv_noise_jacobian",
    "cv_observation_matrix",
    "symbol_matrix",
    "is_zero",
]

#: The kinds an :class:`Equation` may have; the last two are proved by ``verify()``.
EQUATION_KINDS = ("definition", "identity", "check")


# --------------------------------------------------------------------------------------
# Zero tests
# --------------------------------------------------------------------------------------

def _scalar_is_zero(expr) -> bool:
    """Decide whether a scalar SymPy expression is identically zero (no numeric sampling)."""
    expr = sp.sympify(expr)
    if expr == 0:
        return True
    if expr.has(sp.Integral, sp.Derivative):
        expr = expr.doit()
    if expr.is_rational_function():
        # exact arithmetic in the field of rational functions: canonical, so == 0 is a proof
        return sfield(expr)[1] == 0
    return sp.simplify(sp.expand(expr)) == 0


def _matexpr_is_zero(expr: MatrixExpr) -> bool:
    """Decide whether a matrix expression in matrix symbols is the zero matrix."""
    expr = sp.block_collapse(expr)
    if isinstance(expr, BlockMatrix):
        return all(_matexpr_is_zero(block) for block in expr.blocks)
    if isinstance(expr, sp.MatrixBase):
        return all(_scalar_is_zero(e) for e in expr)
    for candidate in (expr, sp.expand(expr).doit()):
        if isinstance(candidate, ZeroMatrix) or candidate == 0:
            return True
        if isinstance(candidate, sp.MatrixBase):
            return all(_scalar_is_zero(e) for e in candidate)
    simplified = sp.simplify(sp.expand(expr).doit())
    return isinstance(simplified, ZeroMatrix) or simplified == 0


def is_zero(expr) -> bool:
    """Return True if ``expr`` simplifies to zero exactly.

    Parameters
    ----------
    expr : sympy expression, explicit sympy Matrix, or matrix expression
        A scalar, an explicit matrix (every entry is tested) or an expression in
        ``MatrixSymbol`` objects (block matrices are collapsed first, then every block
        is expanded and tested).

    Returns
    -------
    bool
        True only if SymPy reduces the expression to zero symbolically. Random numeric
        sampling is never used, so True is a proof for generic values of the symbols
        (denominators are assumed non-zero).
    """
    if isinstance(expr, MatrixExpr) and not isinstance(expr, sp.MatrixBase):
        return _matexpr_is_zero(expr)
    if isinstance(expr, sp.MatrixBase):
        return all(_scalar_is_zero(e) for e in expr)
    return _scalar_is_zero(expr)


def _has_matrix_symbols(expr) -> bool:
    return hasattr(expr, "atoms") and bool(expr.atoms(MatrixSymbol))


def _evaluate(expr):
    """Carry out unevaluated operations (integrals, derivatives, determinants, products)."""
    expr = expr.doit() if hasattr(expr, "doit") else sp.sympify(expr)
    if isinstance(expr, MatrixExpr) and not isinstance(expr, sp.MatrixBase):
        expr = expr.as_explicit()
    return expr


# --------------------------------------------------------------------------------------
# Data model
# --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Equation:
    """One labelled step of a derivation: ``lhs = rhs``.

    Parameters
    ----------
    label : str
        Short identifier, unique within its derivation (used for lookup and export).
    lhs, rhs : sympy expression, Matrix or matrix expression
        The two sides. They must have the same shape.
    description : str
        One sentence saying what the equation states or why it holds.
    kind : {"definition", "identity", "check"}
        ``"definition"`` names something and is not checked; ``"identity"`` and
        ``"check"`` (explicit small-matrix form) are proved by :meth:`holds`.
    """

    label: str
    lhs: Any
    rhs: Any
    description: str = ""
    kind: str = "identity"

    def __post_init__(self):
        if not isinstance(self.label, str) or not self.label:
            raise ValueError("label must be a non-empty string")
        if self.kind not in EQUATION_KINDS:
            raise ValueError(f"kind must be one of {EQUATION_KINDS}, got {self.kind!r}")
        lshape = getattr(self.lhs, "shape", None)
        rshape = getattr(self.rhs, "shape", None)
        if lshape is not None and rshape is not None and lshape != rshape:
            raise ValueError(f"equation {self.label!r}: lhs has shape {lshape}, rhs has shape {rshape}")

    @property
    def checked(self) -> bool:
        """True for identities and checks (the kinds :meth:`Derivation.verify` proves)."""
        return self.kind != "definition"

    def residual(self):
        """Return ``lhs − rhs``, evaluated: block matrices collapsed, integrals, derivatives
        and determinants carried out, unevaluated products multiplied."""
        if _has_matrix_symbols(self.lhs) or _has_matrix_symbols(self.rhs):
            return sp.block_collapse(self.lhs - self.rhs)
        return _evaluate(self.lhs) - _evaluate(self.rhs)

    def holds(self) -> bool:
        """Return True if ``lhs − rhs`` simplifies to zero exactly (see :func:`is_zero`)."""
        return is_zero(self.residual())

    def latex(self) -> str:
        """Return the equation as LaTeX, ``lhs = rhs``."""
        return f"{sp.latex(self.lhs)} = {sp.latex(self.rhs)}"

    def __repr__(self) -> str:
        return f"Equation({self.label!r}, kind={self.kind!r})"


@dataclass(frozen=True)
class Derivation:
    """A named chain of equations with a proof method.

    Parameters
    ----------
    name : str
        Registry key, for example ``"schur_block_inverse"``.
    title : str
        Human-readable title.
    model : str
        The setting and its assumptions, in words with inline LaTeX (``$...$``).
    equations : tuple of Equation
        The steps, in reading order; labels are unique.
    symbols : mapping of str to sympy.Symbol, optional
        Named free symbols (for example ``T``, ``sigma_a``) needed to evaluate results.
    results : mapping of str to sympy object, optional
        Named results for reuse, for example the CV model's ``F`` and ``Q``.
    """

    name: str
    title: str
    model: str
    equations: tuple
    symbols: Mapping[str, Any] = field(default_factory=dict)
    results: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self):
        eqs = tuple(self.equations)
        if not all(isinstance(e, Equation) for e in eqs):
            raise ValueError("equations must all be Equation instances")
        labels = [e.label for e in eqs]
        duplicates = sorted({label for label in labels if labels.count(label) > 1})
        if duplicates:
            raise ValueError(f"derivation {self.name!r} has duplicate labels: {duplicates}")
        object.__setattr__(self, "equations", eqs)
        object.__setattr__(self, "symbols", types.MappingProxyType(dict(self.symbols)))
        object.__setattr__(self, "results", types.MappingProxyType(dict(self.results)))

    def __getitem__(self, label: str) -> Equation:
        for eq in self.equations:
            if eq.label == label:
                return eq
        raise KeyError(f"derivation {self.name!r} has no equation {label!r}; "
                       f"labels: {[e.label for e in self.equations]}")

    @property
    def labels(self) -> list[str]:
        """Labels of all equations, in order."""
        return [e.label for e in self.equations]

    def evaluate(self, result: str, **values):
        """Evaluate a named result numerically.

        Parameters
        ----------
        result : str
            A key of :attr:`results`, for example ``"K"``.
        **values : array_like or float
            A value for every symbol the result depends on, keyed as in :attr:`symbols`
            (for example ``P_check=..., G=..., R=...``). Matrix symbols take arrays
            (a 1-D array for a column vector); their sizes fix the dimension symbols.

        Returns
        -------
        ndarray or float
            The result as a float array (1-D for a column vector) or a float.

        Raises
        ------
        KeyError
            Unknown result or symbol name.
        ValueError
            Inconsistent sizes, or a value missing for a symbol the result needs.
        """
        if result not in self.results:
            raise KeyError(f"derivation {self.name!r} has no result {result!r}; "
                           f"results: {sorted(self.results)}")
        expr = self.results[result]
        # a column vector in matrix symbols (shape (n, 1)) comes back 1-D
        is_vector = (isinstance(expr, MatrixExpr) and not isinstance(expr, sp.MatrixBase)
                     and expr.shape[1] == 1)
        dims: dict = {}
        matrices: dict = {}
        scalars: dict = {}
        for key, value in values.items():
            if key not in self.symbols:
                raise KeyError(f"derivation {self.name!r} has no symbol {key!r}; "
                               f"symbols: {sorted(self.symbols)}")
            sym = self.symbols[key]
            if isinstance(sym, MatrixSymbol):
                arr = np.asarray(value, dtype=float)
                if arr.ndim == 1 and sym.shape[1] == 1:
                    arr = arr[:, None]
                if arr.ndim != 2:
                    raise ValueError(f"{key} must be a matrix of shape {sym.shape}, got shape {arr.shape}")
                for dim, size in zip(sym.shape, arr.shape):
                    if isinstance(dim, sp.Symbol):
                        if dims.setdefault(dim, size) != size:
                            raise ValueError(f"{key} has size {size} along {dim}, but another "
                                             f"argument fixed {dim} = {dims[dim]}")
                    elif int(dim) != size:
                        raise ValueError(f"{key} must have shape {sym.shape}, got {arr.shape}")
                matrices[sym] = arr
            else:
                scalars[sym] = float(value)
        expr = expr.subs(dims) if dims else expr
        args = [sym.subs(dims) for sym in matrices] + list(scalars)
        if hasattr(expr, "atoms"):
            given = set(args)
            missing = sorted(str(a) for a in expr.atoms(MatrixSymbol) if a not in given)
            missing += sorted(str(a) for a in expr.free_symbols
                              if not isinstance(a, MatrixSymbol) and a not in given
                              and not any(a in b.free_symbols for b in given))
            if missing:
                raise ValueError(f"values missing for {missing} to evaluate {result!r}")
        # plain identifiers for lambdify (names such as \\check{P} are not valid Python)
        plain = [MatrixSymbol(f"_m{i}", *a.shape) if isinstance(a, MatrixSymbol) else sp.Symbol(f"_s{i}")
                 for i, a in enumerate(args)]
        expr = expr.xreplace(dict(zip(args, plain)))
        if isinstance(expr, MatrixExpr) and not isinstance(expr, sp.MatrixBase):
            expr = sp.block_collapse(expr)
        fn = sp.lambdify(plain, expr, modules="numpy")
        out = fn(*matrices.values(), *scalars.values())
        if isinstance(expr, (MatrixExpr, sp.MatrixBase)):
            out = np.asarray(out, dtype=float).reshape(expr.shape)
            return out[:, 0] if is_vector else out
        return float(out)

    def check(self) -> dict[str, bool]:
        """Prove every identity and check; return ``{label: holds}`` in order."""
        return {e.label: e.holds() for e in self.equations if e.checked}

    def verify(self) -> bool:
        """Return True only if every identity and check holds (and there is at least one)."""
        checked = [e for e in self.equations if e.checked]
        return bool(checked) and all(e.holds() for e in checked)

    def to_markdown(self, *, details: bool = False) -> str:
        """Return the derivation as Markdown with ``$$...$$`` display maths.

        Parameters
        ----------
        details : bool
            If False (default) explicit small-matrix checks are listed by description
            only; if True their full equations are printed as well.
        """
        lines = [f"**{self.title}**", "", self.model, ""]
        for i, eq in enumerate(self.equations, 1):
            tag = {"definition": "definition", "identity": "identity", "check": "check"}[eq.kind]
            lines.append(f"{i}. *{eq.description}* ({tag} `{eq.label}`)")
            if eq.kind != "check" or details:
                lines.append("")
                lines.append(f"   $${eq.latex()}$$")
            lines.append("")
        return "\n".join(lines).rstrip() + "\n"

    def _repr_markdown_(self) -> str:
        return self.to_markdown()

    def __repr__(self) -> str:
        n_checked = sum(e.checked for e in self.equations)
        return (f"Derivation({self.name!r}: {len(self.equations)} equations, "
                f"{n_checked} proved by verify())")


# --------------------------------------------------------------------------------------
# Helpers for explicit symbolic matrices
# --------------------------------------------------------------------------------------

def symbol_matrix(name: str, rows: int, cols: int, *, symmetric: bool = False) -> sp.Matrix:
    """Return an explicit ``rows × cols`` matrix of fresh symbols ``name_ij``.

    Parameters
    ----------
    name : str
        Base name; entries are ``name_ij`` (1-based), or ``name_i`` for a column vector.
    rows, cols : int
        Shape.
    symmetric : bool
        If True (requires a square shape) entries ``(i, j)`` and ``(j, i)`` share one
        symbol, as in a covariance matrix.
    """
    if symmetric and rows != cols:
        raise ValueError(f"a symmetric matrix must be square, got {rows}x{cols}")

    def entry(i, j):
        if cols == 1 and not symmetric:
            return sp.Symbol(f"{name}_{i + 1}")
        if symmetric and j < i:
            i, j = j, i
        return sp.Symbol(f"{name}_{i + 1}{j + 1}")

    return sp.Matrix(rows, cols, lambda i, j: entry(i, j))


def _canon(M: sp.Matrix) -> sp.Matrix:
    """Return M with every entry as one cancelled fraction (keeps explicit algebra small)."""
    return DomainMatrix.from_Matrix(sp.Matrix(M)).to_field().to_Matrix()


def _inv(M: sp.Matrix) -> sp.Matrix:
    """Exact inverse of an explicit symbolic matrix, computed over rational functions."""
    return DomainMatrix.from_Matrix(sp.Matrix(M)).to_field().inv().to_Matrix()


class _Exact:
    """Exact arithmetic over the rational functions in the symbols of some matrices.

    ``f(M)`` converts an explicit SymPy matrix into a ``DomainMatrix`` whose entries are
    cancelled fractions; ``f.back(D)`` converts the result of exact arithmetic back.
    Forming products and inverses this way keeps the explicit checks fast.
    """

    def __init__(self, *matrices: sp.Matrix):
        symbols = sorted(set().union(*(M.free_symbols for M in matrices)), key=str)
        self.field = sp.QQ.frac_field(*symbols)

    def __call__(self, M: sp.Matrix) -> DomainMatrix:
        return DomainMatrix.from_Matrix(sp.Matrix(M)).convert_to(self.field)

    @staticmethod
    def back(D: DomainMatrix) -> sp.Matrix:
        return D.to_Matrix()


def _who(nx: int, ny: int) -> str:
    """'explicit, 2 states and 1 observation' style prefix for check descriptions."""
    return (f"explicit, {nx} state{'s' if nx != 1 else ''} and "
            f"{ny} observation{'s' if ny != 1 else ''}")


def _trace_gradient(expr, K: sp.Matrix) -> sp.Matrix:
    """Matrix of partial derivatives ∂expr/∂K_ij (same shape as K)."""
    return sp.Matrix(K.shape[0], K.shape[1], lambda i, j: sp.diff(expr, K[i, j]))


def _bmat(rows) -> BlockMatrix:
    return BlockMatrix(rows)


# --------------------------------------------------------------------------------------
# Derivations
# --------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
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

    M = _bmat([[A, B], [C, D]])
    upper = _bmat([[In, B * D.I], [Zmn, Im]])
    middle = _bmat([[delta_expr, Znm], [Zmn, D]])
    lower = _bmat([[In, Znm], [D.I * C, Im]])
    upper_inv = _bmat([[In, -B * D.I], [Zmn, Im]])
    lower_inv = _bmat([[In, Znm], [-D.I * C, Im]])
    middle_inv = _bmat([[delta_expr.I, Znm], [Zmn, D.I]])
    identity = _bmat([[In, Znm], [Zmn, Im]])
    M_inv_factored = lower_inv * middle_inv * upper_inv
    M_inv_blocks = _bmat([[delta_expr.I, -delta_expr.I * B * D.I],
                          [-D.I * C * delta_expr.I, D.I + D.I * C * delta_expr.I * B * D.I]])

    def explicit(nn: int, mm: int, tag: str) -> list[Equation]:
        Ae, Be = symbol_matrix("a", nn, nn), symbol_matrix("b", nn, mm)
        Ce, De = symbol_matrix("c", mm, nn), symbol_matrix("d", mm, mm)
        Me = sp.BlockMatrix([[Ae, Be], [Ce, De]]).as_explicit()
        Di = _inv(De)
        Dsi = _inv(Ae - Be * Di * Ce)  # inverse of the Schur complement
        Mi = _canon(sp.BlockMatrix([[Dsi, -Dsi * Be * Di],
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


@functools.lru_cache(maxsize=None)
def linear_map_moments() -> Derivation:
    """Mean, covariance and cross-covariance of y = G x + n (x and n independent)."""
    n, m = sp.symbols("n m", integer=True, positive=True)
    mu_x = MatrixSymbol(r"\mu_x", n, 1)
    Sxx = MatrixSymbol(r"\Sigma_{xx}", n, n)
    G = MatrixSymbol("G", m, n)
    R = MatrixSymbol("R", m, m)
    In, Im, Znm, Zmn = Identity(n), Identity(m), ZeroMatrix(n, m), ZeroMatrix(m, n)
    # [x; y] = T [x; n]  with  T = [[I, 0], [G, I]];  Cov([x; n]) = blkdiag(Sxx, R)
    T = _bmat([[In, Znm], [G, Im]])
    mean_xn = _bmat([[mu_x], [ZeroMatrix(m, 1)]])
    cov_xn = _bmat([[Sxx, Znm], [Zmn, R]])
    joint_mean = _bmat([[mu_x], [G * mu_x]])
    joint_cov = _bmat([[Sxx, Sxx * G.T], [G * Sxx, G * Sxx * G.T + R]])

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
        Equation("stacked", _bmat([[MatrixSymbol("x", n, 1)], [MatrixSymbol("y", m, 1)]]),
                 T * _bmat([[MatrixSymbol("x", n, 1)], [MatrixSymbol(r"\mathbf{n}", m, 1)]]),
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
    Syy_inv = _inv(Syy)
    S_cond = _canon(Sxx - Sxy * Syy_inv * Sxy.T)
    r = _canon(ex - Sxy * Syy_inv * ey)  # x - conditional mean
    e = ex.col_join(ey)
    joint = (e.T * _inv(S) * e)[0, 0]
    split = (r.T * _inv(S_cond) * r)[0, 0] + (ey.T * Syy_inv * ey)[0, 0]
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


@functools.lru_cache(maxsize=None)
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
    Sigma = _bmat([[Sxx, Sxy], [Syx, Syy]])
    left = _bmat([[In, Znm], [-Syy.I * Syx, Im]])
    middle = _bmat([[S_cond.I, Znm], [Zmn, Syy.I]])
    right = _bmat([[In, -Sxy * Syy.I], [Zmn, Im]])
    identity = _bmat([[In, Znm], [Zmn, Im]])
    e = _bmat([[ex], [ey]])
    e_row = _bmat([[ex.T, ey.T]])
    quad_factored = e_row * left * middle * right * e
    quad_split = ((ex.T - ey.T * Syy.I * Syx) * S_cond.I * (ex - Sxy * Syy.I * ey)
                  + ey.T * Syy.I * ey)

    equations = [
        Equation("errors", _bmat([[ex], [ey]]), _bmat([[x - mu_x], [y - mu_y]]),
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


def _gain_checks(nx: int, ny: int) -> list[Equation]:
    """Explicit proof that K* = P̌ Gᵀ S⁻¹ minimises tr P̂(K) for an nx-state, ny-obs system."""
    P = symbol_matrix("p", nx, nx, symmetric=True)
    G = symbol_matrix("g", ny, nx)
    R = symbol_matrix("r", ny, ny, symmetric=True)
    K = symbol_matrix("k", nx, ny)
    I = sp.eye(nx)
    P_hat = (I - K * G) * P * (I - K * G).T + K * R * K.T
    trace = P_hat.trace()
    grad = _trace_gradient(trace, K)
    # the expressions at the optimum are formed exactly over rational functions
    f = _Exact(P, G, R, K)
    Pd, Gd, Rd, Kd, Id = f(P), f(G), f(R), f(K), f(I)
    Sd = Gd * Pd * Gd.transpose() + Rd
    K_opt_d = Pd * Gd.transpose() * Sd.inv()
    A_opt = Id - K_opt_d * Gd
    P_hat_opt = f.back(A_opt * Pd * A_opt.transpose() + K_opt_d * Rd * K_opt_d.transpose())
    K_opt = f.back(K_opt_d)
    at_opt = {K[i, j]: K_opt[i, j] for i in range(nx) for j in range(ny)}
    dK = Kd - K_opt_d
    tag = f"{nx}x{ny}"
    who = _who(nx, ny)
    return [
        Equation(f"gradient_{tag}", grad, -2 * (I - K * G) * P * G.T + 2 * K * R,
                 f"{who}: SymPy's entry-wise derivative of the trace matches the matrix formula", "check"),
        Equation(f"stationary_{tag}", grad.subs(at_opt, simultaneous=True), sp.zeros(nx, ny),
                 f"{who}: the gradient vanishes at $K^*$", "check"),
        Equation(f"minimum_{tag}", trace - P_hat_opt.trace(),
                 f.back(dK * Sd * dK.transpose()).trace(),
                 f"{who}: " r"$\operatorname{tr} \hat P(K) - \operatorname{tr} \hat P(K^*) = "
                 r"\operatorname{tr}((K - K^*) S (K - K^*)^T) \ge 0$, so $K^*$ is the global minimum",
                 "check"),
        Equation(f"short_form_{tag}", P_hat_opt, f.back(A_opt * Pd),
                 f"{who}: " r"at $K^*$ the Joseph form equals $(I - K G) \check P$", "check"),
    ]


@functools.lru_cache(maxsize=None)
def kalman_gain() -> Derivation:
    """The Kalman gain as the minimiser of the trace of the posterior covariance."""
    n, m = sp.symbols("n m", integer=True, positive=True)
    P = MatrixSymbol(r"\check{P}", n, n)
    G = MatrixSymbol("G", m, n)
    R = MatrixSymbol("R", m, m)
    K = MatrixSymbol("K", n, m)
    In, Im, Znm, Zmn = Identity(n), Identity(m), ZeroMatrix(n, m), ZeroMatrix(m, n)
    A = In - K * G
    # posterior error  e_hat = (I - K G) e_check - K n,  Cov([e_check; n]) = blkdiag(P, R)
    T = _bmat([[A, -K]])
    P_hat = A * P * A.T + K * R * K.T
    S = G * P * G.T + R
    K_opt = P * G.T * S.I

    equations = [
        Equation("error", MatrixSymbol(r"\hat{e}", n, 1),
                 A * MatrixSymbol(r"\check{e}", n, 1) - K * MatrixSymbol(r"\mathbf{n}", m, 1),
                 r"with any gain $K$, $\hat x = \check x + K (y - G \check x)$ leaves this error",
                 "definition"),
        Equation("joseph", T * _bmat([[P, Znm], [Zmn, R]]) * T.T, P_hat,
                 "its covariance for any gain (the Joseph form), as prior error and noise are independent"),
        Equation("innovation_cov", MatrixSymbol("S", m, m), S,
                 "innovation covariance", "definition"),
        *_gain_checks(2, 1),
        *_gain_checks(2, 2),
        Equation("gain", K, K_opt,
                 r"setting $\partial \operatorname{tr} \hat P / \partial K = -2 (I - K G) \check P G^T + 2 K R$ "
                 "to zero gives the Kalman gain",
                 "definition"),
    ]
    return Derivation(
        name="kalman_gain",
        title="The Kalman gain minimises the trace of the posterior covariance",
        model=(r"Prior error $\check{e} \sim \mathcal{N}(0, \check{P})$, observation "
               r"$y = G x + n$ with $n \sim \mathcal{N}(0, R)$ independent; update "
               r"$\hat{x} = \check{x} + K (y - G \check{x})$ with a gain $K$ to be chosen "
               r"so that $\operatorname{tr} \hat{P}$, the expected squared error, is smallest."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "P_check": P, "G": G, "R": R, "K": K},
        results={"P_hat": P_hat, "S": S, "K": K_opt},
    )


def _update_checks(nx: int, ny: int) -> list[Equation]:
    """Explicit proof that conditioning the joint prior on y is the KF update."""
    P = symbol_matrix("p", nx, nx, symmetric=True)
    G = symbol_matrix("g", ny, nx)
    R = symbol_matrix("r", ny, ny, symmetric=True)
    x_check, y = symbol_matrix("x", nx, 1), symbol_matrix("y", ny, 1)
    f = _Exact(P, G, R, x_check, y)
    Pd, Gd, Rd, xd, yd, Id = f(P), f(G), f(R), f(x_check), f(y), f(sp.eye(nx))
    # the joint of [x; y] from the linear map, then the conditioning formula
    mu_y, S_yy, S_xy = Gd * xd, Gd * Pd * Gd.transpose() + Rd, Pd * Gd.transpose()
    cond_mean = f.back(xd + S_xy * S_yy.inv() * (yd - mu_y))
    cond_cov = f.back(Pd - S_xy * S_yy.inv() * S_xy.transpose())
    # the KF formulas, written independently
    S = Gd * Pd * Gd.transpose() + Rd
    K = Pd * Gd.transpose() * S.inv()
    kf_mean = f.back(xd + K * (yd - Gd * xd))
    kf_cov = f.back((Id - K * Gd) * Pd)
    tag = f"{nx}x{ny}"
    who = _who(nx, ny)
    return [
        Equation(f"mean_{tag}", cond_mean, kf_mean,
                 f"{who}: the conditional mean is the KF mean update", "check"),
        Equation(f"cov_{tag}", cond_cov, kf_cov,
                 f"{who}: " r"the conditional covariance is $(I - K G) \check P$", "check"),
        Equation(f"cov_sym_{tag}", kf_cov, f.back(Pd - K * S * K.transpose()),
                 f"{who}: " r"$(I - K G) \check P = \check P - K S K^T$ (the symmetric form)", "check"),
        Equation(f"information_{tag}", f.back((Pd.inv() + Gd.transpose() * Rd.inv() * Gd).inv()), kf_cov,
                 f"{who}: " r"information form, $\hat P^{-1} = \check P^{-1} + G^T R^{-1} G$",
                 "check"),
    ]


@functools.lru_cache(maxsize=None)
def kf_update_conditioning() -> Derivation:
    """The Kalman filter update obtained by conditioning the joint prior of state and observation."""
    n, m, l = sp.symbols("n m l", integer=True, positive=True)
    x_check = MatrixSymbol(r"\check{x}", n, 1)
    P = MatrixSymbol(r"\check{P}", n, n)
    G = MatrixSymbol("G", m, n)
    C = MatrixSymbol("C", m, l)
    R = MatrixSymbol("R", l, l)
    y = MatrixSymbol("y", m, 1)
    In, Im, Il = Identity(n), Identity(m), Identity(l)
    S = G * P * G.T + C * R * C.T
    K = P * G.T * S.I
    # [x; y] = T [x; n] with T = [[I, 0], [G, C]], Cov([x; n]) = blkdiag(P, R)
    T = _bmat([[In, ZeroMatrix(n, l)], [G, C]])
    joint_cov = _bmat([[P, P * G.T], [G * P, S]])
    x_hat = x_check + K * (y - G * x_check)
    P_hat_cond = P - (P * G.T) * S.I * (G * P)
    P_hat = (In - K * G) * P

    equations = [
        Equation("joint_cov", T * _bmat([[P, ZeroMatrix(n, l)], [ZeroMatrix(l, n), R]]) * T.T, joint_cov,
                 "the joint covariance of the predicted state and the observation $y = G x + C n$"),
        Equation("innovation_cov", MatrixSymbol("S", m, m), S,
                 r"innovation covariance: the $\Sigma_{yy}$ block", "definition"),
        Equation("gain", MatrixSymbol("K", n, m), K,
                 r"gain: $\Sigma_{xy} \Sigma_{yy}^{-1}$", "definition"),
        Equation("posterior_mean", MatrixSymbol(r"\hat{x}", n, 1), x_hat,
                 r"posterior mean: the conditional mean with $\mu_x = \check x$, $\mu_y = G \check x$",
                 "definition"),
        Equation("posterior_cov", P_hat_cond, P_hat,
                 r"posterior covariance: the conditional covariance factorises as $(I - K G) \check P$"),
        *_update_checks(2, 1),
        *_update_checks(2, 2),
    ]
    return Derivation(
        name="kf_update_conditioning",
        title="The Kalman update is Gaussian conditioning",
        model=(r"Prior $x \sim \mathcal{N}(\check{x}, \check{P})$; observation "
               r"$y = G x + C n$ with $n \sim \mathcal{N}(0, R)$ independent of $x$. The "
               r"posterior is $p(x \mid y)$ of the joint Gaussian of $[x; y]$ (in the explicit "
               r"checks $C = I$)."),
        equations=tuple(equations),
        symbols={"n": n, "m": m, "l": l, "x_check": x_check, "P_check": P, "G": G, "C": C,
                 "R": R, "y": y},
        results={"S": S, "K": K, "x_hat": x_hat, "P_hat": P_hat},
    )


@functools.lru_cache(maxsize=None)
def cv_model() -> Derivation:
    """The constant-velocity model per axis: F, the noise Jacobian and both process-noise Q."""
    T, s, t = sp.symbols("T s t", nonnegative=True)
    sigma_a, q = sp.symbols(r"sigma_a q", positive=True)
    p0, v0, a = sp.symbols("p_0 v_0 a", real=True)
    A = sp.Matrix([[0, 1], [0, 0]])  # d/dt [p, v] = A [p, v] + L a
    L = sp.Matrix([0, 1])
    F = sp.Matrix([[1, T], [0, 1]])
    Phi_s = F.subs(T, s)

    def integral(M: sp.Matrix, var=s) -> sp.Matrix:
        """Entry-wise unevaluated integral from 0 to T (evaluated by verify())."""
        return M.applyfunc(lambda e: sp.Integral(e, (var, 0, T)))

    Gamma = sp.Matrix([T**2 / 2, T])
    G_imm = sp.ImmutableMatrix(Gamma)
    Q_pw = sigma_a**2 * sp.Matrix([[T**4 / 4, T**3 / 2], [T**3 / 2, T**2]])
    Q_c = q * sp.Matrix([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
    # exact kinematics under an acceleration a held over one step
    kinematics = sp.Matrix([p0 + sp.Integral(v0 + sp.Integral(a, (s, 0, t)), (t, 0, T)),
                            v0 + sp.Integral(a, (s, 0, T))])

    equations = [
        Equation("transition_ode", sp.Derivative(sp.ImmutableMatrix(F), T), sp.MatMul(
                     sp.ImmutableMatrix(A), sp.ImmutableMatrix(F), evaluate=False),
                 r"$F(T) = \begin{bmatrix} 1 & T \\ 0 & 1 \end{bmatrix}$ solves "
                 r"$\dot F = A F$ ...", "identity"),
        Equation("transition_initial", sp.Subs(sp.ImmutableMatrix(F), T, 0), sp.eye(2),
                 r"... with $F(0) = I$, so $F(T) = \Phi(T) = e^{A T}$", "identity"),
        Equation("transition_exp", (A * T).exp(), F,
                 r"SymPy's matrix exponential $e^{A T}$ agrees", "check"),
        Equation("noise_jacobian", integral(Phi_s * L), Gamma,
                 r"an acceleration held over the step enters through "
                 r"$\Gamma = \int_0^T \Phi(s) L \, ds$"),
        Equation("constant_acceleration", F * sp.Matrix([p0, v0]) + Gamma * a, kinematics,
                 r"$F x + \Gamma a$ is exactly the motion under a constant acceleration $a$"),
        Equation("Q_piecewise", sp.MatMul(G_imm, sigma_a**2, G_imm.T, evaluate=False), Q_pw,
                 r"piecewise-constant white acceleration of variance $\sigma_a^2$: "
                 r"$Q = \Gamma \sigma_a^2 \Gamma^T$"),
        Equation("Q_continuous", integral(Phi_s * L * q * L.T * Phi_s.T), Q_c,
                 r"continuous white acceleration of spectral density $q$: "
                 r"$Q = \int_0^T \Phi(s) L q L^T \Phi(s)^T ds$"),
        Equation("Q_piecewise_rank", sp.Determinant(sp.ImmutableMatrix(Q_pw)), sp.Integer(0),
                 r"the piecewise $Q$ has rank one: a single acceleration moves $p$ and $v$ together"),
        Equation("Q_continuous_det", sp.Determinant(sp.ImmutableMatrix(Q_c)), q**2 * T**4 / 12,
                 r"the continuous $Q$ is positive definite for $T > 0$"),
    ]
    return Derivation(
        name="cv_model",
        title="Constant-velocity model and its process noise",
        model=(r"Per axis the state is $[p, v]$ with $\dot p = v$, $\dot v = a$, that is "
               r"$\dot x = A x + L a$ with "
               r"$A = \begin{bmatrix} 0 & 1 \\ 0 & 0 \end{bmatrix}$, "
               r"$L = \begin{bmatrix} 0 \\ 1 \end{bmatrix}$; time step $T$. "
               r"For several axes the state is blocked, $[p_1 \dots p_d, v_1 \dots v_d]$, and "
               r"every matrix becomes $M \otimes I_d$."),
        equations=tuple(equations),
        symbols={"T": T, "sigma_a": sigma_a, "q": q},
        results={"F": F, "Gamma": Gamma, "Q_piecewise": Q_pw, "Q_continuous": Q_c},
    )


#: Builders of every registered derivation, in course order. Later chapters append theirs.
_BUILDERS: tuple[Callable[[], Derivation], ...] = (
    schur_block_inverse,
    linear_map_moments,
    gaussian_conditioning,
    kalman_gain,
    kf_update_conditioning,
    cv_model,
)


def _all_builders() -> tuple:
    """This module's builders, then the ESKF's (imported late: that module builds on this one)."""
    from kalman_course.symbolic.eskf import BUILDERS as eskf_builders

    return _BUILDERS + tuple(eskf_builders)


def derivations() -> dict[str, Derivation]:
    """Return every derivation of the course, keyed by name, in course order."""
    return {d.name: d for d in (build() for build in _all_builders())}


def derivation(name: str) -> Derivation:
    """Return the derivation called ``name`` (``KeyError`` lists the known names)."""
    builders = _all_builders()
    for build in builders:
        if build.__name__ == name:
            return build()
    raise KeyError(f"unknown derivation {name!r}; known: {[b.__name__ for b in builders]}")


# --------------------------------------------------------------------------------------
# Numeric CV matrices, generated from the SymPy expressions above
# --------------------------------------------------------------------------------------

@functools.lru_cache(maxsize=None)
def _cv_functions() -> dict[str, Callable]:
    """Lambdified per-axis CV matrices (built once)."""
    d = cv_model()
    T, sigma_a, q = d.symbols["T"], d.symbols["sigma_a"], d.symbols["q"]
    return {
        "F": sp.lambdify((T,), d.results["F"], modules="numpy"),
        "Gamma": sp.lambdify((T,), d.results["Gamma"], modules="numpy"),
        "Q_piecewise": sp.lambdify((T, sigma_a), d.results["Q_piecewise"], modules="numpy"),
        "Q_continuous": sp.lambdify((T, q), d.results["Q_continuous"], modules="numpy"),
    }


def _check_step(T) -> float:
    if isinstance(T, bool) or not isinstance(T, numbers.Real):
        raise ValueError(f"T must be a real time step in seconds, got {T!r}")
    T = float(T)
    if not np.isfinite(T) or T < 0:
        raise ValueError(f"T must be a finite time step >= 0 s, got {T}")
    return T


def _check_dim(dim) -> int:
    if isinstance(dim, bool) or not isinstance(dim, numbers.Integral) or dim < 1:
        raise ValueError(f"dim must be a positive integer (number of spatial axes), got {dim!r}")
    return int(dim)


def _check_scale(value, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ValueError(f"{name} must be a real number >= 0, got {value!r}")
    value = float(value)
    if not np.isfinite(value) or value < 0:
        raise ValueError(f"{name} must be finite and >= 0, got {value}")
    return value


def _per_axis(block, dim: int) -> np.ndarray:
    return np.kron(np.asarray(block, dtype=float), np.eye(dim))


def cv_transition(T, dim: int = 1) -> np.ndarray:
    """Return the constant-velocity transition matrix F.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    F : ndarray, shape (2*dim, 2*dim)
        ``[[I, T I], [0, I]]`` for the blocked state ``[p_1..p_dim, v_1..v_dim]``.
    """
    T, dim = _check_step(T), _check_dim(dim)
    return _per_axis(_cv_functions()["F"](T), dim)


def cv_noise_jacobian(T, dim: int = 1) -> np.ndarray:
    """Return the process-noise Jacobian B of a piecewise-constant acceleration.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    B : ndarray, shape (2*dim, dim)
        ``[[T²/2 I], [T I]]``: how one acceleration per axis, held over the step, moves
        the blocked state. ``B @ (sigma_a**2 * I) @ B.T`` equals :func:`cv_process_noise`.
    """
    T, dim = _check_step(T), _check_dim(dim)
    return _per_axis(_cv_functions()["Gamma"](T), dim)


def cv_process_noise(T, sigma_a, dim: int = 1) -> np.ndarray:
    """Return Q of the CV model driven by piecewise-constant white acceleration.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    sigma_a : float
        Standard deviation of the acceleration held over each step, in m/s² (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    Q : ndarray, shape (2*dim, 2*dim)
        ``sigma_a² [[T⁴/4 I, T³/2 I], [T³/2 I, T² I]]`` in the blocked state order.
    """
    T, dim = _check_step(T), _check_dim(dim)
    sigma_a = _check_scale(sigma_a, "sigma_a")
    return _per_axis(_cv_functions()["Q_piecewise"](T, sigma_a), dim)


def cv_process_noise_continuous(T, q, dim: int = 1) -> np.ndarray:
    """Return Q of the CV model driven by continuous white acceleration.

    Parameters
    ----------
    T : float
        Time step in seconds (>= 0).
    q : float
        Spectral density of the acceleration noise in m²/s³ (>= 0).
    dim : int
        Number of spatial axes.

    Returns
    -------
    Q : ndarray, shape (2*dim, 2*dim)
        ``q [[T³/3 I, T²/2 I], [T²/2 I, T I]]`` in the blocked state order.
    """
    T, dim = _check_step(T), _check_dim(dim)
    q = _check_scale(q, "q")
    return _per_axis(_cv_functions()["Q_continuous"](T, q), dim)


def cv_observation_matrix(dim: int = 1) -> np.ndarray:
    """Return the position-observation Jacobian G of the CV model.

    Parameters
    ----------
    dim : int
        Number of spatial axes.

    Returns
    -------
    G : ndarray, shape (dim, 2*dim)
        ``[I, 0]``: positions are observed, velocities are not.
    """
    dim = _check_dim(dim)
    return np.hstack([np.eye(dim), np.zeros((dim, dim))])


# ======================================================================================
# Chapters 04–05: planar motion models (CV, CA, CTRV, CTRA) and the radar observation
# ======================================================================================
#
# Each model is written once as a continuous-time ODE. SymPy integrates it over a step T
# (with the process noise held constant over the step), gives the exact discrete model
# x_k = f(x_{k-1}, w_k, T), and differentiates it for the motion Jacobian F = ∂f/∂x and
# the process-noise Jacobian B = ∂f/∂w (both at w = 0). The turning models divide by the
# yaw rate ω; for |ω T| below ``OMEGA_SERIES_THRESHOLD`` the numeric functions switch to a
# Taylor series in ω, derived symbolically from the same integrand, so the model and its
# Jacobians stay finite and continuous through ω = 0.
#
# State orders (units m, m/s, m/s², rad, rad/s):
#   cv   [p_x, p_y, v_x, v_y]            noise w = [a_x, a_y]        (m/s²)
#   ca   [p_x, p_y, v_x, v_y, a_x, a_y]  noise w = [j_x, j_y]        (m/s³)
#   ctrv [p_x, p_y, v, ψ, ω]             noise w = [ν_a, ν_ψ̈]        (m/s², rad/s²)
#   ctra [p_x, p_y, v, ψ, ω, a]          noise w = [ν_j, ν_ψ̈]        (m/s³, rad/s²)
# The CTRV order and noise are those of ``kalman_course.data.ctrv_step``.

from kalman_course.core.validation import as_vector  # noqa: E402  (below symbolic in the layering)

#: The planar motion models, in the order the course introduces them.
MOTION_MODELS = ("cv", "ca", "ctrv", "ctra")

#: Below this |ω T| (rad) the turning models use their Taylor series in ω.
OMEGA_SERIES_THRESHOLD = 0.02

#: Order of that series: terms up to ω^(SERIES_ORDER − 1) are kept. At the threshold the
#: first dropped term is below 1e-15 of the step's displacement.
SERIES_ORDER = 8


def _motion_symbols():
    """The shared symbols of the planar models (one set, so the models compose)."""
    T, t = sp.symbols("T t", nonnegative=True)
    px, py, vx, vy, ax, ay, v, a, psi, om = sp.symbols(
        r"p_x p_y v_x v_y a_x a_y v a psi omega", real=True)
    jx, jy, nu_a, nu_yaw, nu_j = sp.symbols(r"j_x j_y nu_a nu_psiddot nu_j", real=True)
    return types.SimpleNamespace(T=T, t=t, px=px, py=py, vx=vx, vy=vy, ax=ax, ay=ay, v=v, a=a,
                                 psi=psi, om=om, jx=jx, jy=jy, nu_a=nu_a, nu_yaw=nu_yaw, nu_j=nu_j)


def _turn_integrals(s, speed, order=None):
    """∫₀ᵀ speed(t) (cos ψ(t), sin ψ(t)) dt with ψ(t) = ψ + ω t.

    With ``order`` None SymPy integrates in closed form (ω ≠ 0); otherwise the integrand's
    Taylor polynomial in ω, cos(ψ + ω t) = Σ (ω t)^k / k! · cos(ψ + k π/2), is integrated
    term by term (exact to that order, and finite at ω = 0).
    """
    t, T, om, psi = s.t, s.T, s.om, s.psi
    if order is None:
        nonzero = sp.Symbol("w_nz", real=True, nonzero=True)  # ω ≠ 0 for the closed form
        cx = sp.integrate(speed * sp.cos(psi + nonzero * t), (t, 0, T)).subs(nonzero, om)
        cy = sp.integrate(speed * sp.sin(psi + nonzero * t), (t, 0, T)).subs(nonzero, om)
        return cx, cy
    cos_terms = sum((om * t) ** k / sp.factorial(k) * sp.cos(psi + k * sp.pi / 2) for k in range(order))
    sin_terms = sum((om * t) ** k / sp.factorial(k) * sp.sin(psi + k * sp.pi / 2) for k in range(order))
    cx = sp.integrate(sp.expand(speed * cos_terms), (t, 0, T))
    cy = sp.integrate(sp.expand(speed * sin_terms), (t, 0, T))
    return sp.expand(cx), sp.expand(cy)


def _model_parts(name: str) -> dict:
    """Symbols, continuous dynamics and exact (and series) discrete model of one planar model."""
    s = _motion_symbols()
    T = s.T
    h2, h3 = T**2 / 2, T**3 / 6
    if name == "cv":
        x = [s.px, s.py, s.vx, s.vy]
        w = [s.ax, s.ay]
        dyn = sp.Matrix([s.vx, s.vy, 0, 0])
        f0 = sp.Matrix([s.px + s.vx * T, s.py + s.vy * T, s.vx, s.vy])
        noise = sp.Matrix([h2 * s.ax, h2 * s.ay, T * s.ax, T * s.ay])
        series = None
        title = "Constant velocity (CV), planar"
    elif name == "ca":
        x = [s.px, s.py, s.vx, s.vy, s.ax, s.ay]
        w = [s.jx, s.jy]
        dyn = sp.Matrix([s.vx, s.vy, s.ax, s.ay, 0, 0])
        f0 = sp.Matrix([s.px + s.vx * T + s.ax * h2, s.py + s.vy * T + s.ay * h2,
                        s.vx + s.ax * T, s.vy + s.ay * T, s.ax, s.ay])
        noise = sp.Matrix([h3 * s.jx, h3 * s.jy, h2 * s.jx, h2 * s.jy, T * s.jx, T * s.jy])
        series = None
        title = "Constant acceleration (CA), planar"
    elif name in ("ctrv", "ctra"):
        accel = name == "ctra"
        x = [s.px, s.py, s.v, s.psi, s.om] + ([s.a] if accel else [])
        w = [s.nu_j if accel else s.nu_a, s.nu_yaw]
        speed = s.v + s.a * s.t if accel else s.v
        dyn = sp.Matrix([s.v * sp.cos(s.psi), s.v * sp.sin(s.psi), s.a if accel else 0, s.om, 0]
                        + ([0] if accel else []))
        nu = w[0]
        cx, cy = _turn_integrals(s, speed)
        sx, sy = _turn_integrals(s, speed, SERIES_ORDER)
        tail = [s.v + s.a * T, s.psi + s.om * T, s.om, s.a] if accel else [s.v, s.psi + s.om * T, s.om]
        f0 = sp.Matrix([s.px + cx, s.py + cy] + tail)
        series = sp.Matrix([s.px + sx, s.py + sy] + tail)
        if accel:   # a jerk ν_j held over the step, along the heading
            noise = sp.Matrix([h3 * sp.cos(s.psi) * nu, h3 * sp.sin(s.psi) * nu, h2 * nu, T * nu,
                               h2 * s.nu_yaw, T * s.nu_yaw])
        else:       # an acceleration ν_a held over the step, along the heading
            noise = sp.Matrix([h2 * sp.cos(s.psi) * nu, h2 * sp.sin(s.psi) * nu, T * nu,
                               h2 * s.nu_yaw, T * s.nu_yaw])
        title = ("Constant turn rate and acceleration (CTRA)" if accel
                 else "Constant turn rate and velocity (CTRV)")
    else:
        raise KeyError(f"unknown motion model {name!r}; known: {MOTION_MODELS}")
    return dict(s=s, x=x, w=w, dyn=dyn, f0=f0, series=series, noise=noise, title=title)


def _model_derivation(name: str, registry_name: str) -> Derivation:
    parts = _model_parts(name)
    s, x, w, dyn, f0, series, noise = (parts[k] for k in ("s", "x", "w", "dyn", "f0", "series", "noise"))
    T = s.T
    X, W = sp.Matrix(x), sp.Matrix(w)
    f = f0 + noise
    at_zero_noise = {wi: 0 for wi in w}
    F = f.jacobian(X).subs(at_zero_noise)
    B = f.jacobian(W).subs(at_zero_noise)
    flow = dyn.subs(dict(zip(x, list(f0))), simultaneous=True)
    state = r"[" + ", ".join(sp.latex(xi) for xi in x) + r"]"
    equations = [
        Equation("dynamics", sp.Matrix([sp.Symbol(r"\dot{" + sp.latex(xi) + "}") for xi in x]), dyn,
                 "the continuous-time model (noise-free)", "definition"),
        Equation("flow", sp.Derivative(sp.ImmutableMatrix(f0), T), flow,
                 r"the discrete model $f(x, 0, T)$ solves the ODE: $\partial f / \partial T$ is the "
                 r"dynamics evaluated at $f$ ..."),
        Equation("initial", sp.Subs(sp.ImmutableMatrix(f0), T, 0), X,
                 r"... and starts at the state: $f(x, 0, 0) = x$"),
        Equation("noise_linear", f - f0, B * W,
                 r"the noise held over the step enters linearly, $f(x, w) = f(x, 0) + B w$"),
        Equation("motion_jacobian", sp.MatrixSymbol("F", len(x), len(x)), F,
                 r"$F = \partial f / \partial x$ at $w = 0$, derived by SymPy", "definition"),
        Equation("noise_jacobian", sp.MatrixSymbol("B", len(x), len(w)), B,
                 r"$B = \partial f / \partial w$ at $w = 0$", "definition"),
    ]
    results = {"f": f0, "f_noisy": f, "F": F, "B": B, "dynamics": dyn}
    if series is not None:
        om = s.om
        Fs = (series + noise).jacobian(X).subs(at_zero_noise)
        straight = f0.applyfunc(lambda e: sp.Limit(e, om, 0))
        equations += [
            Equation("limit_straight", straight, series.subs(om, 0),
                     r"as $\omega \to 0$ the turn becomes a straight line, and the series branch "
                     r"at $\omega = 0$ is that limit"),
            Equation("series", sp.Matrix([sp.Symbol(r"f_{\mathrm{series}}")]), sp.Matrix([sp.Integer(0)]),
                     rf"for $|\omega T| < {OMEGA_SERIES_THRESHOLD}$ the numeric model uses the Taylor "
                     rf"series of the integrand in $\omega$ up to $\omega^{{{SERIES_ORDER - 1}}}$",
                     "definition"),
        ]
        results.update({"f_series": series, "F_series": Fs})
    symbols = {str(xi): xi for xi in x} | {str(wi): wi for wi in w} | {"T": T}
    return Derivation(
        name=registry_name,
        title=parts["title"],
        model=(rf"Planar state ${state}$, noise $w = [{', '.join(sp.latex(wi) for wi in w)}]$ held "
               r"constant over a step of $T$ seconds. The exact discrete model is the ODE's flow; "
               r"its Jacobians are derived, never typed."),
        equations=tuple(equations),
        symbols=symbols,
        results=results,
    )


@functools.lru_cache(maxsize=None)
def cv_planar_model() -> Derivation:
    """Planar constant velocity, state [p_x, p_y, v_x, v_y], noise [a_x, a_y]."""
    return _model_derivation("cv", "cv_planar_model")


@functools.lru_cache(maxsize=None)
def ca_model() -> Derivation:
    """Planar constant acceleration, state [p_x, p_y, v_x, v_y, a_x, a_y], noise [j_x, j_y]."""
    return _model_derivation("ca", "ca_model")


@functools.lru_cache(maxsize=None)
def ctrv_model() -> Derivation:
    """Constant turn rate and velocity, state [p_x, p_y, v, ψ, ω], noise [ν_a, ν_ψ̈]."""
    return _model_derivation("ctrv", "ctrv_model")


@functools.lru_cache(maxsize=None)
def ctra_model() -> Derivation:
    """Constant turn rate and acceleration, state [p_x, p_y, v, ψ, ω, a], noise [ν_j, ν_ψ̈]."""
    return _model_derivation("ctra", "ctra_model")


_MODEL_BUILDERS = {"cv": cv_planar_model, "ca": ca_model, "ctrv": ctrv_model, "ctra": ctra_model}


@functools.lru_cache(maxsize=None)
def radar_model() -> Derivation:
    """The radar observation (range, bearing, range rate) and its Jacobian.

    Written for the Cartesian state [p_x, p_y, v_x, v_y]; the CTRV/CTRA form follows by
    substituting v_x = v cos ψ, v_y = v sin ψ.
    """
    px, py, vx, vy = sp.symbols("p_x p_y v_x v_y", real=True)
    v, psi = sp.symbols("v psi", real=True)
    rho = sp.sqrt(px**2 + py**2)
    h = sp.Matrix([rho, sp.atan2(py, px), (px * vx + py * vy) / rho])
    X = sp.Matrix([px, py, vx, vy])
    G = h.jacobian(X)
    c1 = px**2 + py**2
    c2 = sp.sqrt(c1)
    c3 = c1 * c2
    # the Jacobian as the seed article writes it out by hand
    G_hand = sp.Matrix([[px / c2, py / c2, 0, 0],
                        [-py / c1, px / c1, 0, 0],
                        [py * (vx * py - vy * px) / c3, px * (px * vy - py * vx) / c3, px / c2, py / c2]])
    polar = {vx: v * sp.cos(psi), vy: v * sp.sin(psi)}
    h_turn = h.subs(polar)
    om, a = sp.symbols("omega a", real=True)
    X_turn = sp.Matrix([px, py, v, psi, om])
    G_turn = h_turn.jacobian(X_turn)
    chain = G.subs(polar) * sp.Matrix([px, py, v * sp.cos(psi), v * sp.sin(psi)]).jacobian(X_turn)
    equations = [
        Equation("observation", sp.Matrix(sp.symbols("rho phi rhodot")), h,
                 r"range, bearing (atan2, in $(-\pi, \pi]$) and range rate, the velocity projected on "
                 r"the line of sight", "definition"),
        Equation("jacobian_hand", G, G_hand,
                 "SymPy's Jacobian equals the hand-derived one of the lecture"),
        Equation("range_rate_is_derivative", h[2], (sp.diff(rho, px) * vx + sp.diff(rho, py) * vy),
                 r"the range rate is $d\rho/dt = \nabla \rho \cdot v$"),
        Equation("jacobian_turn_chain", G_turn, chain,
                 r"for the CTRV state the Jacobian is the Cartesian one times the Jacobian of "
                 r"$(v, \psi) \mapsto (v \cos\psi, v \sin\psi)$ (chain rule)"),
    ]
    return Derivation(
        name="radar_model",
        title="Radar observation: range, bearing, range rate",
        model=(r"A radar at the origin measures $y = h(x) + n$, $n \sim \mathcal{N}(0, R)$, of a target "
               r"with position $(p_x, p_y)$ and velocity $(v_x, v_y)$ (for the turning models "
               r"$v_x = v \cos\psi$, $v_y = v \sin\psi$)."),
        equations=tuple(equations),
        symbols={"p_x": px, "p_y": py, "v_x": vx, "v_y": vy, "v": v, "psi": psi, "omega": om, "a": a},
        results={"h": h, "G": G, "h_turn": h_turn, "G_turn": G_turn},
    )


_BUILDERS = _BUILDERS + (cv_planar_model, ca_model, ctrv_model, ctra_model, radar_model)


# --------------------------------------------------------------------------------------
# Numeric planar models and radar, lambdified once from the expressions above
# --------------------------------------------------------------------------------------

def _lambdify(args, expr):
    fn = sp.lambdify(args, sp.ImmutableMatrix(expr), modules="numpy", cse=True)
    return fn


@functools.lru_cache(maxsize=None)
def _model_functions(name: str) -> dict:
    d = _MODEL_BUILDERS[name]()
    parts = _model_parts(name)
    x, w, T = parts["x"], parts["w"], parts["s"].T
    args = list(x) + list(w) + [T]
    fns = {
        "n": len(x), "m": len(w),
        "f": _lambdify(args, d.results["f_noisy"]),
        "F": _lambdify(list(x) + [T], d.results["F"]),
        "B": _lambdify(list(x) + [T], d.results["B"]),
    }
    if "f_series" in d.results:
        noise = d.results["f_noisy"] - d.results["f"]
        fns["f_series"] = _lambdify(args, d.results["f_series"] + noise)
        fns["F_series"] = _lambdify(list(x) + [T], d.results["F_series"])
        fns["omega_index"] = x.index(parts["s"].om)
    return fns


def motion_state_names(model: str) -> tuple[str, ...]:
    """Names of the state components of ``model`` ("cv", "ca", "ctrv" or "ctra"), in order."""
    names = {"cv": ("p_x", "p_y", "v_x", "v_y"), "ca": ("p_x", "p_y", "v_x", "v_y", "a_x", "a_y"),
             "ctrv": ("p_x", "p_y", "v", "psi", "omega"),
             "ctra": ("p_x", "p_y", "v", "psi", "omega", "a")}
    if model not in names:
        raise ValueError(f"model must be one of {MOTION_MODELS}, got {model!r}")
    return names[model]


def _model_args(model, x, T):
    if model not in MOTION_MODELS:
        raise ValueError(f"model must be one of {MOTION_MODELS}, got {model!r}")
    fns = _model_functions(model)
    n = fns["n"]
    if not (type(x) is np.ndarray and x.dtype == np.float64 and x.shape == (n,) and np.isfinite(x).all()):
        x = np.asarray(x, dtype=float)
        if x.shape != (n,):
            raise ValueError(f"x must have shape ({n},) for the {model} model "
                             f"{list(motion_state_names(model))}, got {x.shape}")
        if not np.isfinite(x).all():
            raise ValueError("x must be finite, got NaN or inf")
    T = _check_step(T)
    series = "omega_index" in fns and abs(x[fns["omega_index"]] * T) < OMEGA_SERIES_THRESHOLD
    return fns, x, T, series


def motion_step(model: str, x, T, w=None) -> np.ndarray:
    """Propagate a planar state over one step: :math:`f(x, w, T)`.

    Parameters
    ----------
    model : {"cv", "ca", "ctrv", "ctra"}
    x : array_like, shape (n,)
        State in the order of :func:`motion_state_names`.
    T : float
        Step, s (>= 0).
    w : array_like, shape (2,), optional
        Process noise held constant over the step (see the module notes); default zero.

    Returns
    -------
    ndarray, shape (n,)
        The exact flow of the model. The turning models use their ω-series for
        ``|ω T| < OMEGA_SERIES_THRESHOLD``.
    """
    fns, x, T, series = _model_args(model, x, T)
    w = np.zeros(fns["m"]) if w is None else as_vector(w, "w", fns["m"])
    fn = fns["f_series"] if series else fns["f"]
    return np.asarray(fn(*x, *w, T), dtype=float).reshape(-1)


def motion_jacobian(model: str, x, T) -> np.ndarray:
    """Motion Jacobian :math:`F = \\partial f / \\partial x` at (x, w = 0), shape (n, n)."""
    fns, x, T, series = _model_args(model, x, T)
    fn = fns["F_series"] if series else fns["F"]
    return np.asarray(fn(*x, T), dtype=float)


def motion_noise_jacobian(model: str, x, T) -> np.ndarray:
    """Process-noise Jacobian :math:`B = \\partial f / \\partial w` at (x, w = 0), shape (n, 2)."""
    fns, x, T, _ = _model_args(model, x, T)
    return np.asarray(fns["B"](*x, T), dtype=float)


def motion_process_noise(model: str, x, T, sigmas) -> np.ndarray:
    """Process noise in state space, :math:`B \\, \\mathrm{diag}(\\sigma^2) \\, B^T`, shape (n, n).

    ``sigmas`` are the standard deviations of the two noise components of ``model``
    (for CTRV: σ_a in m/s² and σ_ψ̈ in rad/s²).
    """
    sigmas = as_vector(sigmas, "sigmas", 2)
    B = motion_noise_jacobian(model, x, T)
    return (B * sigmas**2) @ B.T


def ctrv_step(x, T, w=None) -> np.ndarray:
    """CTRV step :math:`f(x, w, T)`, state [p_x, p_y, v, ψ, ω]; see :func:`motion_step`."""
    return motion_step("ctrv", x, T, w)


def ctrv_jacobian(x, T) -> np.ndarray:
    """CTRV motion Jacobian F (5, 5); see :func:`motion_jacobian`."""
    return motion_jacobian("ctrv", x, T)


def ctrv_noise_jacobian(x, T) -> np.ndarray:
    """CTRV process-noise Jacobian B (5, 2) for w = [ν_a, ν_ψ̈]."""
    return motion_noise_jacobian("ctrv", x, T)


@functools.lru_cache(maxsize=None)
def _radar_functions() -> dict:
    d = radar_model()
    sy = d.symbols
    cart = [sy["p_x"], sy["p_y"], sy["v_x"], sy["v_y"]]
    turn = [sy["p_x"], sy["p_y"], sy["v"], sy["psi"]]
    G_turn = d.results["G_turn"][:, :4]       # ∂h/∂ω = 0
    return {"h_cart": _lambdify(cart, d.results["h"]), "G_cart": _lambdify(cart, d.results["G"]),
            "h_turn": _lambdify(turn, d.results["h_turn"]), "G_turn": _lambdify(turn, G_turn)}


def _radar_state(x, model: str):
    if model not in MOTION_MODELS:
        raise ValueError(f"model must be one of {MOTION_MODELS}, got {model!r}")
    n = len(motion_state_names(model))
    x = as_vector(x, "x", n)
    if np.hypot(x[0], x[1]) < 1e-9:
        raise ValueError("x must not be at the radar's position (range 0 has no bearing)")
    return x, n


def radar_observation(x, model: str = "ctrv") -> np.ndarray:
    """Radar measurement function h(x) = [ρ (m), φ (rad, in (−π, π]), ρ̇ (m/s)], shape (3,).

    ``model`` names the state layout (see :func:`motion_state_names`); the radar sits at
    the origin.
    """
    x, _ = _radar_state(x, model)
    fn = _radar_functions()["h_cart" if model in ("cv", "ca") else "h_turn"]
    return np.asarray(fn(*x[:4]), dtype=float).reshape(-1)


def radar_jacobian(x, model: str = "ctrv") -> np.ndarray:
    """Radar observation Jacobian G = ∂h/∂x, shape (3, n) for the state layout of ``model``."""
    x, n = _radar_state(x, model)
    G = np.zeros((3, n))
    fn = _radar_functions()["G_cart" if model in ("cv", "ca") else "G_turn"]
    G[:, :4] = np.asarray(fn(*x[:4]), dtype=float)
    return G


__all__ += [
    "MOTION_MODELS", "OMEGA_SERIES_THRESHOLD", "cv_planar_model", "ca_model", "ctrv_model",
    "ctra_model", "radar_model", "motion_state_names", "motion_step", "motion_jacobian",
    "motion_noise_jacobian", "motion_process_noise", "ctrv_step", "ctrv_jacobian",
    "ctrv_noise_jacobian", "radar_observation", "radar_jacobian",
]
