"""The data model of every derivation: :class:`Equation`, :class:`Derivation`, the zero test
that proves them, and the helpers for explicit symbolic matrices.

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

A function that builds a derivation is decorated with :func:`derivation_builder`: the
function's name is the derivation's name, and :mod:`kalman_course.symbolic.registry` finds
every builder of its topic modules by that mark.
"""

from __future__ import annotations

import functools
import types
from dataclasses import dataclass, field
from typing import Any, Callable, Mapping

import numpy as np
import sympy as sp

from kalman_course.core.validation import as_int
from sympy.matrices.expressions import BlockMatrix, MatrixExpr, MatrixSymbol, ZeroMatrix
from sympy.polys.fields import sfield
from sympy.polys.matrices import DomainMatrix

__all__ = ["EQUATION_KINDS", "Equation", "Derivation", "derivation_builder", "is_zero",
           "has_matrix_symbols", "symbol_matrix", "canonical", "exact_inverse", "ExactArithmetic"]

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


def has_matrix_symbols(expr) -> bool:
    """True if ``expr`` contains a ``MatrixSymbol`` (a statement about matrices of any size)."""
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
        if has_matrix_symbols(self.lhs) or has_matrix_symbols(self.rhs):
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
# Builders
# --------------------------------------------------------------------------------------

def derivation_builder(build: Callable[[], Derivation]) -> Callable[[], Derivation]:
    """Mark ``build`` as the builder of the derivation named after it, and cache its result.

    Parameters
    ----------
    build : callable returning Derivation
        A function without arguments whose name is the name of the derivation it returns,
        for example ``def kalman_gain() -> Derivation``. That name is written only there.

    Returns
    -------
    callable returning Derivation
        The cached builder (the derivation is built once), carrying the attribute
        ``derivation_name``. :mod:`kalman_course.symbolic.registry` lists every function so
        marked in its topic modules.

    Raises
    ------
    ValueError
        When called, if ``build`` returns something other than a :class:`Derivation` named
        like the function.
    """
    name = build.__name__

    @functools.cache
    @functools.wraps(build)
    def cached() -> Derivation:
        built = build()
        if not isinstance(built, Derivation) or built.name != name:
            raise ValueError(f"builder {name}() must return a Derivation named {name!r}, "
                             f"got {built!r}")
        return built

    cached.derivation_name = name
    return cached


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
    if not isinstance(name, str) or not name:
        raise ValueError(f"name must be a non-empty str, got {name!r}")
    rows, cols = as_int(rows, "rows", minimum=1), as_int(cols, "cols", minimum=1)
    if symmetric and rows != cols:
        raise ValueError(f"a symmetric matrix must be square, got {rows}x{cols}")

    def entry(i, j):
        if cols == 1 and not symmetric:
            return sp.Symbol(f"{name}_{i + 1}")
        if symmetric and j < i:
            i, j = j, i
        return sp.Symbol(f"{name}_{i + 1}{j + 1}")

    return sp.Matrix(rows, cols, lambda i, j: entry(i, j))


def canonical(M: sp.Matrix) -> sp.Matrix:
    """Return M with every entry as one cancelled fraction (keeps explicit algebra small)."""
    return DomainMatrix.from_Matrix(sp.Matrix(M)).to_field().to_Matrix()


def exact_inverse(M: sp.Matrix) -> sp.Matrix:
    """Exact inverse of an explicit symbolic matrix, computed over rational functions."""
    return DomainMatrix.from_Matrix(sp.Matrix(M)).to_field().inv().to_Matrix()


class ExactArithmetic:
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
