"""Derivations on SO(3) written as compact steps and proved with explicit 3 × 3 matrices.

A step such as δv̇ ≈ −R[a]×δθ − R δb_a + R n_a is displayed in matrix symbols (R, a, δθ,
...) and the rotation operators of this module ([v]×, Exp, Log, ...), as a learner reads it
on paper. SymPy cannot prove it in that form, so every :class:`Step` carries an
:class:`ExplicitModel`: the meaning of each displayed symbol as an explicit matrix of
scalar symbols (a rotation R(q) of a unit quaternion, 3-vectors of symbols, the nominal and
true dynamics, the error definitions). :meth:`Step.holds` replaces both sides by their
meanings, computes in the field of rational functions of the symbols, and proves the
difference zero:

- an **exact** step (no ``orders``, displayed with ``=``) must hold identically. In an
  exact step ``Exp(v)`` stands for a matrix of fresh symbols, so the step holds for any
  matrix in its place (it uses no property of the exponential);
- an **approximate** step (``orders=((eps, 1),)``, displayed with ``≈``) must agree in
  every Taylor coefficient up to the given powers of the small parameters (``eps`` scales
  every error and noise). Values are power series truncated at those powers; ``Exp`` is its
  series Σ [v]×ⁿ/n! (its argument must be small), and ``Log(M)`` the vector of the
  antisymmetric part of M, which is Log(M) up to terms of third order for a rotation M
  near I. Meanings that are themselves approximations (``valid_to``) are accepted only in
  steps compared to that order or less.

A model may carry one polynomial relation its symbols satisfy (qᵀq = 1 for the unit
quaternion of a rotation): a residual whose numerators are multiples of it is zero. Nothing
is sampled numerically: a step that holds is proved for all admissible values of its
symbols (denominators non-zero).
"""

from __future__ import annotations

import functools
import itertools
import math
import operator
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

import sympy as sp
from sympy.matrices.expressions import (BlockDiagMatrix, BlockMatrix, Identity, MatAdd, MatMul, MatPow, MatrixExpr,
                                        MatrixSymbol, Transpose, ZeroMatrix)
from sympy.polys.fields import field
from sympy.printing.latex import LatexPrinter

from kalman_course.symbolic.equations import Derivation, Equation

__all__ = ["Skew", "Vee", "Cross", "Exp", "Log", "MatExp", "TimeDerivative", "MatIntegral", "vec", "mat", "add",
           "mul", "skew_matrix", "vee_matrix", "unit_quaternion_rotation", "ExplicitModel", "Step", "steps_markdown",
           "step_latex"]


# --------------------------------------------------------------------------------------
# Display operators (matrix expressions that print as on paper)
# --------------------------------------------------------------------------------------

def _as_expr(x):
    return x if isinstance(x, sp.Basic) else sp.sympify(x)


def _require_vector(v, what: str):
    if getattr(v, "shape", None) != (3, 1):
        raise ValueError(f"{what} needs a 3-vector (shape (3, 1)), got shape {getattr(v, 'shape', None)}")


class Skew(MatrixExpr):
    """[v]×, the 3 × 3 skew-symmetric matrix with [v]× w = v × w."""

    def __new__(cls, v):
        v = _as_expr(v)
        _require_vector(v, "Skew")
        return super().__new__(cls, v)

    @property
    def shape(self):
        return (3, 3)

    def _latex(self, printer):
        return r"\left[%s\right]_{\times}" % printer._print(self.args[0])


class Vee(MatrixExpr):
    """M^∨, the 3-vector of a skew-symmetric matrix (of the antisymmetric part of M)."""

    def __new__(cls, M):
        M = _as_expr(M)
        if getattr(M, "shape", None) != (3, 3):
            raise ValueError(f"Vee needs a 3 x 3 matrix, got shape {getattr(M, 'shape', None)}")
        return super().__new__(cls, M)

    @property
    def shape(self):
        return (3, 1)

    def _latex(self, printer):
        return r"\left(%s\right)^{\vee}" % printer._print(self.args[0])


class Cross(MatrixExpr):
    """x × y of two 3-vectors."""

    precedence = 45  # between a sum and a product: parenthesised inside products

    def __new__(cls, x, y):
        x, y = _as_expr(x), _as_expr(y)
        _require_vector(x, "Cross")
        _require_vector(y, "Cross")
        return super().__new__(cls, x, y)

    @property
    def shape(self):
        return (3, 1)

    def _latex(self, printer):
        x, y = self.args
        return r"%s \times %s" % (printer.parenthesize(x, 50), printer.parenthesize(y, 50))


class Exp(MatrixExpr):
    """Exp(v) = exp([v]×), the rotation of angle |v| about v / |v|."""

    def __new__(cls, v):
        v = _as_expr(v)
        _require_vector(v, "Exp")
        return super().__new__(cls, v)

    @property
    def shape(self):
        return (3, 3)

    def _latex(self, printer):
        return r"\operatorname{Exp}\left(%s\right)" % printer._print(self.args[0])


class Log(MatrixExpr):
    """Log(M), the rotation vector of a rotation M (the inverse of :class:`Exp` near I)."""

    def __new__(cls, M):
        M = _as_expr(M)
        if getattr(M, "shape", None) != (3, 3):
            raise ValueError(f"Log needs a 3 x 3 matrix, got shape {getattr(M, 'shape', None)}")
        return super().__new__(cls, M)

    @property
    def shape(self):
        return (3, 1)

    def _latex(self, printer):
        return r"\operatorname{Log}\left(%s\right)" % printer._print(self.args[0])


class MatExp(MatrixExpr):
    """e^X of a square matrix X."""

    def __new__(cls, X):
        X = _as_expr(X)
        if X.shape[0] != X.shape[1]:
            raise ValueError(f"MatExp needs a square matrix, got shape {X.shape}")
        return super().__new__(cls, X)

    @property
    def shape(self):
        return self.args[0].shape

    def _latex(self, printer):
        return r"e^{%s}" % printer._print(self.args[0])


class TimeDerivative(MatrixExpr):
    """d/dt of a matrix expression (evaluated by differentiating in the model's time)."""

    def __new__(cls, X):
        return super().__new__(cls, _as_expr(X))

    @property
    def shape(self):
        return self.args[0].shape

    def _latex(self, printer):
        return r"\frac{d}{dt} %s" % printer.parenthesize(self.args[0], 50)


class MatIntegral(MatrixExpr):
    """∫_lower^upper X(s) ds of a matrix expression in the scalar s."""

    def __new__(cls, X, s, lower, upper):
        return super().__new__(cls, _as_expr(X), s, _as_expr(lower), _as_expr(upper))

    @property
    def shape(self):
        return self.args[0].shape

    def _latex(self, printer):
        X, s, lower, upper = self.args
        return r"\int_{%s}^{%s} %s \, d%s" % (printer._print(lower), printer._print(upper), printer._print(X),
                                              printer._print(s))


# --------------------------------------------------------------------------------------
# Building displayed expressions
# --------------------------------------------------------------------------------------

def vec(name: str) -> MatrixSymbol:
    """A displayed 3-vector named by its LaTeX, for example ``vec(r"\\delta\\theta")``."""
    return MatrixSymbol(name, 3, 1)


def mat(name: str, rows: int = 3, cols: int = 3) -> MatrixSymbol:
    """A displayed matrix named by its LaTeX (3 × 3 unless told)."""
    return MatrixSymbol(name, rows, cols)


def add(*terms) -> MatAdd:
    """A sum kept in the order written (SymPy would sort its terms)."""
    return MatAdd(*terms, evaluate=False)


def mul(*factors) -> MatMul:
    """A product kept as written (no scalar or matrix is merged)."""
    return MatMul(*factors, evaluate=False)


# --------------------------------------------------------------------------------------
# Explicit matrices
# --------------------------------------------------------------------------------------

def skew_matrix(v) -> sp.Matrix:
    """[v]× of an explicit 3-vector."""
    v = sp.Matrix(v)
    return sp.Matrix([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]])


def vee_matrix(M) -> sp.Matrix:
    """The vector of the antisymmetric part (M − Mᵀ)/2 of an explicit 3 × 3 matrix."""
    M = sp.Matrix(M)
    return sp.Matrix([(M[2, 1] - M[1, 2]) / 2, (M[0, 2] - M[2, 0]) / 2, (M[1, 0] - M[0, 1]) / 2])


def unit_quaternion_rotation(name: str = "q") -> tuple[sp.Matrix, sp.Expr, tuple]:
    """A general rotation: the matrix R(q) of a unit quaternion q, with its constraint.

    R(q) is the Euler–Rodrigues matrix, polynomial in q = (w, x, y, z); it is a rotation
    whenever qᵀq = 1, and every rotation is R(q) for some unit q. An identity proved for
    R(q) modulo the relation qᵀq − 1 = 0 (RᵀR = I used explicitly, as that relation)
    therefore holds for every rotation.

    Returns
    -------
    R : sympy.Matrix, shape (3, 3)
    relation : sympy.Expr
        w² + x² + y² + z² − 1, which vanishes on unit quaternions.
    q : tuple of four sympy.Symbol
        (w, x, y, z).
    """
    w, x, y, z = sp.symbols(f"{name}_w {name}_x {name}_y {name}_z", real=True)
    R = sp.Matrix([[w ** 2 + x ** 2 - y ** 2 - z ** 2, 2 * (x * y - w * z), 2 * (x * z + w * y)],
                   [2 * (x * y + w * z), w ** 2 - x ** 2 + y ** 2 - z ** 2, 2 * (y * z - w * x)],
                   [2 * (x * z - w * y), 2 * (y * z + w * x), w ** 2 - x ** 2 - y ** 2 + z ** 2]])
    return R, w ** 2 + x ** 2 + y ** 2 + z ** 2 - 1, (w, x, y, z)


# --------------------------------------------------------------------------------------
# The model: what every displayed symbol means
# --------------------------------------------------------------------------------------

class ExplicitModel:
    """The meaning of displayed symbols as explicit matrices, the small parameters, and the
    relation the symbols satisfy.

    Parameters
    ----------
    small : iterable of sympy.Symbol
        The parameters that scale the small quantities (errors, noises, a time step); a
        first-order :class:`Step` gives an order for each of them.
    time : sympy.Symbol, optional
        The time variable for :class:`TimeDerivative` nodes that have no meaning of their own
        (the meanings are then polynomials in it).
    relation : sympy.Expr, optional
        A polynomial that vanishes for every admissible value of the symbols, for example
        qᵀq − 1 of :func:`unit_quaternion_rotation`. A step holds if the numerator of every
        entry of its residual is a multiple of it (a single polynomial is a Gröbner basis of
        the ideal it generates, so the remainder of the division decides).
    exact_substitution : mapping, optional
        Scalar substitutions applied in exact steps only, to make every entry a rational
        function, for example ``{T: tau**2}`` so that √T becomes τ.
    """

    def __init__(self, small: Iterable[sp.Symbol] = (), time: sp.Symbol | None = None,
                 relation: sp.Expr | None = None, exact_substitution: Mapping | None = None):
        self.small = tuple(small)
        self.time = time
        self.relation = relation
        self.exact_substitution = dict(exact_substitution or {})
        self._meaning: dict = {}
        self._valid_to: dict = {}

    def define(self, node, meaning, *, valid_to: int | None = None) -> "ExplicitModel":
        """Give ``node`` (a displayed symbol or any displayed expression) its meaning.

        Parameters
        ----------
        node : sympy matrix expression
        meaning : sympy Matrix or matrix expression
            An explicit matrix or an expression in other displayed symbols.
        valid_to : int, optional
            If the meaning is an approximation, the total order in the small parameters to
            which it is exact; it is then refused in exact steps and in steps compared to a
            higher total order.
        """
        if getattr(node, "shape", None) != getattr(meaning, "shape", None):
            raise ValueError(f"meaning of {node} has shape {getattr(meaning, 'shape', None)}, "
                             f"expected {getattr(node, 'shape', None)}")
        if isinstance(meaning, sp.MatrixBase):
            meaning = sp.ImmutableMatrix(meaning)
        self._meaning[node] = meaning
        if valid_to is not None:
            self._valid_to[node] = valid_to
        return self

    def __contains__(self, node) -> bool:
        return node in self._meaning

    def meaning(self, node):
        """The meaning given to ``node`` (KeyError if none)."""
        return self._meaning[node]

    def explicit(self, expr):
        """``expr`` as an explicit SymPy matrix, with SymPy's own arithmetic (for results such
        as F_t; no exponential, logarithm, derivative or integral)."""
        x = expr
        if isinstance(x, sp.MatrixBase):
            return sp.Matrix(x)
        if not isinstance(x, MatrixExpr):
            return x
        if x in self._meaning:
            return self.explicit(self._meaning[x])
        if isinstance(x, Identity):
            return sp.eye(x.shape[0])
        if isinstance(x, ZeroMatrix):
            return sp.zeros(*x.shape)
        if isinstance(x, MatAdd):
            return functools.reduce(operator.add, [self.explicit(a) for a in x.args])
        if isinstance(x, MatMul):
            return functools.reduce(operator.mul, [self.explicit(a) for a in x.args])
        if isinstance(x, Transpose):
            return self.explicit(x.arg).T
        if isinstance(x, (BlockMatrix, BlockDiagMatrix)):
            b = x.blocks
            return sp.Matrix.vstack(*[sp.Matrix.hstack(*[self.explicit(b[i, j]) for j in range(b.shape[1])])
                                      for i in range(b.shape[0])])
        if isinstance(x, Skew):
            return skew_matrix(self.explicit(x.args[0]))
        if isinstance(x, Vee):
            return vee_matrix(self.explicit(x.args[0]))
        if isinstance(x, Cross):
            return sp.Matrix(self.explicit(x.args[0])).cross(sp.Matrix(self.explicit(x.args[1])))
        raise TypeError(f"explicit() cannot make {type(x).__name__} explicit: {x}")


    def series(self, expr, orders) -> dict:
        """The Taylor coefficients of ``expr`` in the small parameters, as a first-order step
        computes them.

        Parameters
        ----------
        expr : matrix expression
        orders : sequence of (sympy.Symbol, int)
            Every small parameter of the model once, with the highest power of it to keep.

        Returns
        -------
        dict
            ``{exponents: sympy.Matrix}``, the exponents a tuple in the order of ``orders``;
            the coefficients not listed are zero.
        """
        orders = tuple(orders)
        if not orders or sorted(map(str, (p for p, _ in orders))) != sorted(map(str, self.small)):
            raise ValueError(f"orders must give every small parameter {self.small} once, got {orders!r}")
        engine, (series,) = _evaluate(self, orders, expr)
        return {e: engine.to_sympy(v) for e, v in series.items()}


class _FMat:
    """A small dense matrix of elements of a rational function field."""

    __slots__ = ("rows", "K")

    def __init__(self, rows, K):
        self.rows, self.K = rows, K

    @property
    def shape(self):
        return (len(self.rows), len(self.rows[0]))

    @classmethod
    def zeros(cls, shape, K):
        return cls([[K.zero] * shape[1] for _ in range(shape[0])], K)

    @classmethod
    def eye(cls, n, K):
        return cls([[K.one if i == j else K.zero for j in range(n)] for i in range(n)], K)

    def __add__(self, other):
        return _FMat([[a + b for a, b in zip(r1, r2)] for r1, r2 in zip(self.rows, other.rows)], self.K)

    def __sub__(self, other):
        return _FMat([[a - b for a, b in zip(r1, r2)] for r1, r2 in zip(self.rows, other.rows)], self.K)

    def scale(self, c):
        return _FMat([[c * a for a in r] for r in self.rows], self.K)

    def __matmul__(self, other):
        cols = list(zip(*other.rows))
        zero = self.K.zero
        return _FMat([[sum((a * b for a, b in zip(r, c) if a and b), zero) for c in cols] for r in self.rows], self.K)

    @property
    def T(self):
        return _FMat([list(c) for c in zip(*self.rows)], self.K)

    def map(self, fn):
        return _FMat([[fn(a) for a in r] for r in self.rows], self.K)

    def entries(self):
        return [a for r in self.rows for a in r]


def _times(a, b):
    """Product of two values, each a field element (scalar) or an :class:`_FMat`."""
    if isinstance(a, _FMat) and isinstance(b, _FMat):
        return a @ b
    if isinstance(a, _FMat):
        return a.scale(b)
    if isinstance(b, _FMat):
        return b.scale(a)
    return a * b


def _fskew(v: _FMat) -> _FMat:
    (x,), (y,), (z,) = v.rows
    o = v.K.zero
    return _FMat([[o, -z, y], [z, o, -x], [-y, x, o]], v.K)


def _fvee(M: _FMat) -> _FMat:
    r = M.rows
    half = M.K.one / 2
    return _FMat([[(r[2][1] - r[1][2]) * half], [(r[0][2] - r[2][0]) * half], [(r[1][0] - r[0][1]) * half]], M.K)


def _fcross(u: _FMat, v: _FMat) -> _FMat:
    return _fskew(u) @ v


class _Engine:
    """Explicit evaluation in a rational function field, as truncated power series.

    With ``orders`` empty the step is exact: the small parameters are ordinary symbols and
    an ``Exp`` stands for a matrix of fresh symbols. Otherwise values are power series in the
    small parameters ``{exponents: coefficient}``, every coefficient beyond the orders dropped
    as soon as it appears (exact for the coefficients compared: a product's coefficient needs
    only lower ones).
    """

    def __init__(self, model: ExplicitModel, orders, exprs=()):
        self.model = model
        self.exact = not orders
        self.params = tuple(p for p, _ in orders)
        self.box = tuple(k for _, k in orders)
        self.total = sum(self.box)
        self.zero_exp = (0,) * len(self.box)
        self.u = sp.Dummy("u")
        self.opaque: dict = {}
        self.cache: dict = {}
        parts = [x for pair in model._meaning.items() for x in pair] + list(exprs)
        if self.exact:
            # an exact step may use no property of the exponential: any matrix stands for it
            for part in parts:
                for node in sp.preorder_traversal(part):
                    if isinstance(node, (Exp, MatExp)) and node not in self.opaque:
                        k = len(self.opaque)
                        self.opaque[node] = sp.ImmutableMatrix(*node.shape, lambda i, j: sp.Dummy(f"E{k}_{i}{j}"))
        symbols = self._symbols(parts + list(self.opaque.values()))
        symbols |= {self.u} | ({model.time} if model.time is not None else set())
        if self.exact:
            for old, new in model.exact_substitution.items():
                if old in symbols:
                    symbols = (symbols - {old}) | sp.sympify(new).free_symbols
        gens = sorted(symbols - set(self.params), key=str)
        if model.relation is not None:
            tied = sorted(model.relation.free_symbols, key=str)
            gens = tied + [g for g in gens if g not in tied]
        self.K, *_ = field(gens, sp.QQ)
        self.rel = None if model.relation is None else self.K.ring.from_expr(model.relation)

    @staticmethod
    def _symbols(parts) -> set:
        """Every scalar symbol in explicit matrices and scalar factors of ``parts``."""
        out: set = set()
        for part in parts:
            for node in sp.preorder_traversal(part):
                if isinstance(node, sp.MatrixBase):
                    for entry in node:
                        out |= sp.sympify(entry).free_symbols
                elif isinstance(node, sp.Symbol):
                    out.add(node)
        return out

    def _subst(self, expr):
        expr = sp.sympify(expr)
        if self.exact and self.model.exact_substitution:
            expr = expr.xreplace(self.model.exact_substitution)
        return expr

    def _scalar(self, expr):
        expr = self._subst(expr)
        try:
            return self.K.from_expr(expr)
        except (ValueError, TypeError, sp.polys.polyerrors.CoercionFailed, sp.polys.polyerrors.GeneratorsError):
            raise ValueError(f"{expr} is not a rational function of the model's symbols") from None

    def to_sympy(self, value):
        if isinstance(value, _FMat):
            return sp.Matrix([[a.as_expr() for a in r] for r in value.rows])
        return value.as_expr()

    def is_zero(self, value) -> bool:
        entries = value.entries() if isinstance(value, _FMat) else [value]
        for a in entries:
            if a == self.K.zero:
                continue
            if self.rel is None or a.numer.rem([self.rel]) != 0:
                return False
        return True

    # -- series arithmetic
    def _inside(self, e) -> bool:
        return all(i <= k for i, k in zip(e, self.box))

    def _leaf(self, value, shape):
        if self.exact:
            if isinstance(value, sp.MatrixBase):
                return {(): _FMat([[self._scalar(value[i, j]) for j in range(value.cols)]
                                   for i in range(value.rows)], self.K)}
            return {(): self._scalar(value)}
        terms_of = [[self._terms(value[i, j]) for j in range(value.cols)] for i in range(value.rows)] \
            if isinstance(value, sp.MatrixBase) else None
        if terms_of is None:
            return self._terms(value)
        out: dict = {}
        for i, row in enumerate(terms_of):
            for j, terms in enumerate(row):
                for e, c in terms.items():
                    out.setdefault(e, _FMat.zeros(shape, self.K)).rows[i][j] = c
        return out

    def _terms(self, entry) -> dict:
        entry = sp.sympify(entry)
        if entry == 0:
            return {}
        if not entry.free_symbols & set(self.params):
            return {self.zero_exp: self._scalar(entry)}
        try:
            poly = sp.Poly(entry, *self.params)
        except sp.PolynomialError:
            raise ValueError(f"{entry} is not a polynomial in the small parameters {self.params}") from None
        return {e: self._scalar(c) for e, c in poly.terms() if self._inside(e)}

    @staticmethod
    def _map(a: dict, fn) -> dict:
        return {e: fn(v) for e, v in a.items()}

    @staticmethod
    def _sum(a: dict, b: dict) -> dict:
        out = dict(a)
        for e, v in b.items():
            out[e] = out[e] + v if e in out else v
        return out

    def _product(self, a: dict, b: dict, op=_times) -> dict:
        out: dict = {}
        for e1, v1 in a.items():
            for e2, v2 in b.items():
                e = tuple(i + j for i, j in zip(e1, e2))
                if self._inside(e):
                    v = op(v1, v2)
                    out[e] = out[e] + v if e in out else v
        return out

    def _exp(self, K: dict, n: int) -> dict:
        one = {self.zero_exp: _FMat.eye(n, self.K)}
        out, power = one, one
        for k in range(1, self.total + 1):                  # higher powers lie outside the orders
            power = self._product(power, K)
            out = self._sum(out, self._map(power, lambda v, k=k: v.scale(self.K.one / math.factorial(k))))
        return out

    # -- evaluation
    def ev(self, x) -> dict:
        if isinstance(x, sp.MatrixBase) or not isinstance(x, MatrixExpr):
            return self._leaf(x, getattr(x, "shape", None))
        if x not in self.cache:
            self.cache[x] = self._ev(x)
        return self.cache[x]

    def _ev(self, x) -> dict:
        m = self.model
        if x in m._meaning:
            limit = m._valid_to.get(x)
            if limit is not None and (self.exact or self.total > limit):
                raise ValueError(f"{x} is defined only to order {limit} in {m.small}; it cannot be used in "
                                 + ("an exact step" if self.exact else f"a step of total order {self.total}"))
            return self.ev(m._meaning[x])
        if isinstance(x, MatrixSymbol):
            raise KeyError(f"the model gives no meaning to {x.name!r}")
        if isinstance(x, Identity):
            return {self.zero_exp: _FMat.eye(x.shape[0], self.K)}
        if isinstance(x, ZeroMatrix):
            return {}
        if isinstance(x, MatAdd):
            return functools.reduce(self._sum, [self.ev(a) for a in x.args])
        if isinstance(x, MatMul):
            return functools.reduce(self._product, [self.ev(a) for a in x.args])
        if isinstance(x, MatPow):
            return functools.reduce(self._product, [self.ev(x.base)] * int(x.exp))
        if isinstance(x, Transpose):
            return self._map(self.ev(x.arg), lambda v: v.T)
        if isinstance(x, (BlockMatrix, BlockDiagMatrix)):
            b = x.blocks
            parts = [[(self.ev(b[i, j]), b[i, j].shape) for j in range(b.shape[1])] for i in range(b.shape[0])]
            exps = set().union(*[p for row in parts for p, _ in row])
            out = {}
            for e in exps:
                rows = []
                for row in parts:
                    blocks = [p.get(e) or _FMat.zeros(shape, self.K) for p, shape in row]
                    for r in range(blocks[0].shape[0]):
                        rows.append([a for blk in blocks for a in blk.rows[r]])
                out[e] = _FMat(rows, self.K)
            return out
        if isinstance(x, Skew):
            return self._map(self.ev(x.args[0]), _fskew)
        if isinstance(x, Vee):
            return self._map(self.ev(x.args[0]), _fvee)
        if isinstance(x, Cross):
            return self._product(self.ev(x.args[0]), self.ev(x.args[1]), op=_fcross)
        if isinstance(x, (Exp, MatExp)):
            if self.exact:
                return self._leaf(self.opaque[x], x.shape)
            arg = self.ev(x.args[0])
            if not self.is_zero(arg.get(self.zero_exp, self.K.zero)):
                raise ValueError(f"{x}: its argument must vanish with the small parameters {m.small} "
                                 "for a series expansion")
            return self._exp(self._map(arg, _fskew) if isinstance(x, Exp) else arg, x.shape[0])
        if isinstance(x, Log):
            if self.exact or self.total > 2:
                raise ValueError(f"{x}: Log is made explicit only in steps compared to total order 1 or 2")
            M = self.ev(x.args[0])
            if not self.is_zero(M.get(self.zero_exp, _FMat.zeros((3, 3), self.K)) - _FMat.eye(3, self.K)):
                raise ValueError(f"{x}: the argument must be I when the small parameters vanish")
            # Log(M) = theta / sin(theta) * vee((M - M^T) / 2) = vee((M - M^T) / 2) + O(theta^3)
            return self._map(M, _fvee)
        if isinstance(x, TimeDerivative):
            if m.time is None:
                raise KeyError(f"the model gives no meaning to {x} and has no time variable")
            t = self.K.from_expr(m.time)
            return self._map(self.ev(x.args[0]), lambda v: v.map(lambda a: a.diff(t)))
        if isinstance(x, MatIntegral):
            X, s, lower, upper = x.args
            u = self.u
            # s = lower + (upper - lower) u: what is small in the integrand stays small
            inner = self.ev(X.xreplace({s: lower + (upper - lower) * u}))

            ring = self.K.ring
            iu = ring.gens.index(ring.from_expr(u))

            def integrate(a):                                 # over u from 0 to 1, monomial by monomial
                if a.denom.degree(iu) > 0:
                    raise ValueError(f"{x}: the integrand must be polynomial in {s}")
                terms = {}
                for monom, c in a.numer.terms():
                    k = monom[iu]
                    rest = monom[:iu] + (0,) + monom[iu + 1:]
                    terms[rest] = terms.get(rest, 0) + c / (k + 1)
                return self.K(ring.from_dict(terms)) / self.K(a.denom)
            inner = self._map(inner, lambda v: v.map(integrate))
            return self._product(self._leaf(upper - lower, None), inner)
        raise TypeError(f"cannot make {type(x).__name__} explicit: {x}")


def _evaluate(model: ExplicitModel, orders, *exprs):
    """(engine, [series of each expression]) with one engine, so that an Exp is the same
    matrix on every side."""
    engine = _Engine(model, orders, exprs)
    return engine, [engine.ev(x) for x in exprs]


# --------------------------------------------------------------------------------------
# The step
# --------------------------------------------------------------------------------------

class _StepPrinter(LatexPrinter):
    """LaTeX as written: sums and products in their order, names verbatim, I and 0 plain,
    ½ without parentheses."""

    def __init__(self):
        super().__init__({"order": "none"})

    def _print_MatrixSymbol(self, expr):
        return expr.name                                  # the names are LaTeX already

    def _print_Identity(self, expr):
        return "I"

    def _print_ZeroMatrix(self, expr):
        return "0"

    def _print_MatAdd(self, expr):
        out = ""
        for i, term in enumerate(expr.args):
            tex = self._print(term)
            if tex.startswith("- "):
                out += ("- " if i == 0 else " - ") + tex[2:]
            else:
                out += ("" if i == 0 else " + ") + tex
        return out

    def _print_MatMul(self, expr):
        args = list(expr.args)
        sign = ""
        if args and args[0].is_number and args[0].is_negative:
            sign, args[0] = "- ", -args[0]
        if len(args) > 1 and args[0] == 1:
            args = args[1:]
        parts = []
        for a in args:
            if a.is_Rational and not a.is_Integer:
                parts.append(r"\tfrac{%s}{%s}" % (a.p, a.q))
            elif isinstance(a, (MatAdd, sp.Add)):
                parts.append(r"\left(%s\right)" % self._print(a))
            elif not isinstance(a, (MatrixExpr, sp.MatrixBase)):
                parts.append(self._print(a))                  # a scalar factor such as T or sigma^2 / T
            else:
                tex = self._print(a)
                parts.append(r"\left(%s\right)" % tex if getattr(a, "precedence", 1000) < 50 else tex)
        return sign + " ".join(parts)


def step_latex(expr) -> str:
    """LaTeX of a displayed expression, as :class:`Step` prints its sides."""
    return _StepPrinter().doprint(expr)


@dataclass(frozen=True, repr=False)
class Step(Equation):
    """An :class:`~kalman_course.symbolic.equations.Equation` in displayed symbols, proved
    through an :class:`ExplicitModel`.

    Parameters
    ----------
    label, lhs, rhs, description
        As for :class:`Equation`.
    kind : {"check", "definition"}
        ``"check"`` (the default) is proved with explicit matrices; a definition is not.
    model : ExplicitModel
        The meaning of every displayed symbol.
    orders : tuple of (sympy.Symbol, int)
        Empty for an exact step (displayed ``=``); otherwise every small parameter of the
        model with the highest power of it to which both sides must agree (displayed ``≈``).
    """

    kind: str = "check"
    model: Any = None
    orders: tuple = ()

    def __post_init__(self):
        super().__post_init__()
        if self.kind == "identity":
            raise ValueError(f"step {self.label!r}: a Step is a 'check' or a 'definition'")
        if self.checked and not isinstance(self.model, ExplicitModel):
            raise ValueError(f"step {self.label!r}: a checked step needs an ExplicitModel")
        if self.orders:
            params = [p for p, _ in self.orders]
            if (sorted(map(str, params)) != sorted(map(str, self.model.small))
                    or not all(isinstance(k, int) and k >= 0 for _, k in self.orders)):
                raise ValueError(f"step {self.label!r}: orders must give every small parameter of the model "
                                 f"{self.model.small} a non-negative integer, got {self.orders!r}")

    @property
    def approximate(self) -> bool:
        """True for a step that holds to the given orders only (displayed with ≈)."""
        return bool(self.orders)

    def _differences(self):
        engine, (lhs, rhs) = _evaluate(self.model, self.orders, self.lhs, self.rhs)
        zero = _FMat.zeros(self.lhs.shape, engine.K)
        exps = list(itertools.product(*[range(k + 1) for _, k in self.orders]))
        return engine, exps, [(lhs.get(e) or zero) - (rhs.get(e) or zero) for e in exps]

    def coefficients(self) -> list:
        """What must vanish, as SymPy matrices: ``lhs − rhs`` (exact step) or its Taylor
        coefficients up to the orders (one per combination of powers, in
        ``itertools.product`` order), before the relation is applied."""
        engine, _, diffs = self._differences()
        return [engine.to_sympy(D) for D in diffs]

    def residual(self):
        """``lhs − rhs`` as an explicit matrix (exact step) or its Taylor polynomial up to the orders."""
        engine, exps, diffs = self._differences()
        out = sp.zeros(*self.lhs.shape)
        for e, D in zip(exps, diffs):
            out += engine.to_sympy(D) * sp.Mul(*[p ** i for (p, _), i in zip(self.orders, e)])
        return out

    def holds(self) -> bool:
        """True if every coefficient that must vanish does (modulo the model's relation)."""
        engine, _, diffs = self._differences()
        return all(engine.is_zero(D) for D in diffs)

    def latex(self) -> str:
        relation = r"\approx" if self.approximate else "="
        return f"{step_latex(self.lhs)} {relation} {step_latex(self.rhs)}"

    def __repr__(self) -> str:
        return f"Step({self.label!r}, kind={self.kind!r}, {'approximate' if self.approximate else 'exact'})"


# --------------------------------------------------------------------------------------
# Display
# --------------------------------------------------------------------------------------

_ORDINAL = {1: "first", 2: "second", 3: "third", 4: "fourth"}


def _order_words(orders) -> str:
    ks = {k for _, k in orders}
    if len(ks) == 1:
        (k,) = ks
        word = f"{_ORDINAL.get(k, f'{k}th')} order"
        return f"equal to {word}" + (" in each small quantity" if len(orders) > 1 else "")
    return "equal to order " + ", ".join(f"{k} in ${sp.latex(p)}$" for p, k in orders)


def steps_markdown(derivation: Derivation, labels: Iterable[str] | None = None, *, prove: bool = True,
                   start: int | None = None) -> str:
    """Some steps of a derivation as Markdown, each with its caption and how it is proved.

    Parameters
    ----------
    derivation : Derivation
    labels : iterable of str, optional
        The steps to show, in order (all if omitted).
    prove : bool
        If True (default) every checked step is proved first; one that fails raises.
    start : int, optional
        Number the shown steps consecutively from ``start`` (a lecture that shows several
        derivations, or one derivation in another order, numbers its steps as it shows
        them). By default each step keeps its number in the whole derivation.

    Returns
    -------
    str
        A numbered list with ``$$...$$`` displays.

    Raises
    ------
    KeyError
        An unknown label.
    AssertionError
        A checked step that SymPy does not prove.
    """
    chosen = [derivation[label] for label in labels] if labels is not None else list(derivation.equations)
    if start is None:
        number = {e.label: i for i, e in enumerate(derivation.equations, 1)}
    else:
        if isinstance(start, bool) or not isinstance(start, int) or start < 1:
            raise ValueError(f"start must be a positive int, got {start!r}")
        number = {e.label: i for i, e in enumerate(chosen, start)}
    lines = []
    for eq in chosen:
        if prove and eq.checked and not eq.holds():
            raise AssertionError(f"{derivation.name}: step {eq.label!r} does not hold")
        if not eq.checked:
            how = "definition"
        elif getattr(eq, "approximate", False):
            how = "SymPy: " + _order_words(eq.orders)
        else:
            how = "SymPy: exact"
        lines += [f"**({number[eq.label]})** {eq.description} *[{how}]*", "", f"$${eq.latex()}$$", ""]
    return "\n".join(lines)
