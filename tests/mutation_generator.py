"""Mutants generated from the reference solutions, beside the hand-written catalogues.

The hand-written catalogues (``tests/mutants/chNN.py``) hold the mistakes someone thought of;
this module makes the mechanical ones: each *operator* below walks the solution region of a
graded function (the code between ``# BEGIN SOLUTION <check>`` and ``# STUB`` in a solution
cell) with :mod:`ast` and proposes one edit per site, written as the harness's
:class:`~mutation_harness.Edit` (a text edit of the cell). The operators and their classes:

``in_place``
    ``a = a <op> b`` → ``a <op>= b`` where ``a`` is a parameter of the graded function (or an
    alias of one), and ``c = p <op> b`` → ``p <op>= b; c = p`` (also ``c = b <op> p`` for the
    commutative ``+`` and ``*``).
``float32``
    the returned value (the first element of a returned tuple) cast to float32, where it holds
    floats (told by the caller, like the 1-D values for ``reshape``).
``reshape``
    a returned 1-D array reshaped to (n, 1); which returned values are 1-D is told by the
    caller (it needs a run, see :func:`returned_shapes`).
``swap_args``
    two positional arguments of a call swapped.
``drop_term``
    ``a + b`` → ``a`` and ``a - b`` → ``a``.
``flip_sign``
    ``+`` ↔ ``-`` in a binary operation or an augmented assignment; a unary minus removed, or
    added to the value of an assignment or a ``return`` (unless the value is a call).
``transpose``
    a ``.T`` dropped, or added to an operand of ``@``.
``index``
    a constant index (also a slice bound) one more or one less, kept within the array's
    length where the length is known from the code and never wrapped around to the other end.

``float32`` and ``reshape`` act on the ``return`` statements of the function that holds the
region (most regions end before the ``return``); the others act inside the region only.
"""

from __future__ import annotations

import ast
import copy
import re
from dataclasses import dataclass, field
from typing import Callable, Iterator

from mutation_harness import Edit

#: The operator classes, in the order the generator applies them.
CLASSES = ("in_place", "float32", "reshape", "swap_args", "drop_term", "flip_sign", "transpose", "index")

#: For the classes that the harness reports by a generic property, the word its message
#: contains (kalman_course/checks/harness.py); the other classes need a hint of the check's own.
CLASS_KEYWORD = {"in_place": "in place", "float32": "single precision", "reshape": "shape"}

# no "@=": NumPy's in-place matrix product refuses any shape change, so `G @= x` is not a mistake
# a learner's code could keep (it raises at once), only an invalid edit
_IN_PLACE_OPERATORS = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/"}
_COMMUTATIVE = (ast.Add, ast.Mult)
_ATOMIC = (ast.Name, ast.Attribute, ast.Call, ast.Subscript, ast.Constant)


@dataclass(frozen=True)
class Region:
    """The solution region of one graded check in one cell, parsed.

    Parameters
    ----------
    check : str
        The grader check the region answers (``kf_update``).
    cell_id : str
        Id of the notebook cell that holds it.
    source : str
        The cell's whole source.
    tree : ast.Module
        The cell parsed.
    function : ast.FunctionDef or None
        The innermost function that holds the region (None for module-level code).
    statements : tuple of ast.stmt
        The outermost statements that start inside the region.
    """

    check: str
    cell_id: str
    source: str
    tree: ast.Module
    function: ast.FunctionDef | None
    statements: tuple = field(default=())

    @property
    def parameters(self) -> tuple[str, ...]:
        """Names of the holding function's parameters (none outside a function)."""
        if self.function is None:
            return ()
        arguments = self.function.args
        every = [*arguments.posonlyargs, *arguments.args, *arguments.kwonlyargs]
        every += [a for a in (arguments.vararg, arguments.kwarg) if a is not None]
        return tuple(a.arg for a in every)

    def nodes(self) -> Iterator[ast.AST]:
        """Every node of the region's statements, outer before inner, in source order."""
        for statement in self.statements:
            yield from _walk_in_order(statement)

    def statement_values(self) -> list[ast.AST]:
        """The values of the region's assignments and expression statements and of the holding
        function's returns (what may be replaced without parentheses)."""
        values = [n.value for n in self.nodes() if isinstance(n, (ast.Assign, ast.AugAssign, ast.Expr))]
        return values + [r.value for r in self.returns()]

    def returns(self) -> list[ast.Return]:
        """The ``return`` statements with a value of the holding function (not of functions
        nested in it), in source order."""
        if self.function is None:
            return []
        found = []
        pending = list(self.function.body)
        while pending:
            node = pending.pop(0)
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda, ast.ClassDef)):
                continue
            if isinstance(node, ast.Return) and node.value is not None:
                found.append(node)
            pending.extend(ast.iter_child_nodes(node))
        return sorted(found, key=lambda n: (n.lineno, n.col_offset))


@dataclass(frozen=True)
class Mutation:
    """One generated mistake: a span of a cell's source replaced.

    Parameters
    ----------
    operator : str
        Its class (one of :data:`CLASSES`).
    node : ast.AST
        The node whose source span is replaced.
    replacement : str
        The code written in its place.
    description : str
        What changed, in words (``"-" for "+" in ...``).
    """

    operator: str
    node: ast.AST
    replacement: str
    description: str


def _walk_in_order(node: ast.AST) -> Iterator[ast.AST]:
    """``node`` and its descendants, depth first, children in source order (``ast.walk`` is
    breadth first, which would number the sites less readably)."""
    yield node
    for child in ast.iter_child_nodes(node):
        yield from _walk_in_order(child)


def _code(node: ast.AST) -> str:
    return ast.unparse(node)


def _wrapped_as(new: ast.AST, old: ast.AST, region: "Region") -> str:
    """The code of ``new``, written where ``old`` was: in parentheses unless it is atomic or
    ``old`` is the whole value of one of the region's statements."""
    whole_value = any(old is value for value in region.statement_values())
    return _code(new) if isinstance(new, _ATOMIC) or whole_value else f"({_code(new)})"


def _wrapped(node: ast.AST) -> str:
    """The code of ``node``, in parentheses unless it is atomic (so that it can stand as an
    operand without changing how its surroundings parse)."""
    text = _code(node)
    return text if isinstance(node, _ATOMIC) else f"({text})"


# --- finding the regions ------------------------------------------------------------------

_BEGIN = re.compile(r"^\s*# BEGIN SOLUTION (\S+)\s*$")
_END = re.compile(r"^\s*# (STUB|END SOLUTION)\b")


def regions(cell_id: str, source: str) -> list[Region]:
    """Every solution region in a cell's source, in order.

    Parameters
    ----------
    cell_id : str
        The cell's id (kept on each region, for the edits).
    source : str
        The cell's source.

    Returns
    -------
    list of Region
        One per ``# BEGIN SOLUTION <check>`` marker; the region ends at the next ``# STUB`` or
        ``# END SOLUTION`` line.
    """
    tree = ast.parse(source)
    lines = source.splitlines()
    found = []
    for number, line in enumerate(lines, start=1):
        begin = _BEGIN.match(line)
        if not begin:
            continue
        end = next((k for k in range(number + 1, len(lines) + 1) if _END.match(lines[k - 1])), len(lines) + 1)
        inside = [s for s in _statements(tree) if number < s.lineno < end]
        outermost = [s for s in inside if not any(o is not s and _contains(o, s) for o in inside)]
        function = _holding_function(tree, number)
        found.append(Region(begin.group(1), cell_id, source, tree, function, tuple(outermost)))
    return found


def _statements(tree: ast.AST) -> list[ast.stmt]:
    return [n for n in ast.walk(tree) if isinstance(n, ast.stmt)]


def _contains(outer: ast.AST, inner: ast.AST) -> bool:
    return outer.lineno <= inner.lineno and inner.end_lineno <= outer.end_lineno and any(
        n is inner for n in ast.walk(outer))


def _holding_function(tree: ast.Module, line: int) -> ast.FunctionDef | None:
    holders = [n for n in ast.walk(tree) if isinstance(n, ast.FunctionDef) and n.lineno < line <= n.end_lineno]
    return max(holders, key=lambda n: n.lineno, default=None)


# --- the operators --------------------------------------------------------------------------

def _aliases_of_parameters(region: Region) -> set[str]:
    """The parameters and the names bound to one of them unchanged (``x = x_hat``), anywhere
    in the holding function before the region ends."""
    names = set(region.parameters)
    if region.function is None:
        return names
    changed = True
    while changed:
        changed = False
        for node in ast.walk(region.function):
            if (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                    and isinstance(node.value, ast.Name) and node.value.id in names
                    and node.targets[0].id not in names):
                names.add(node.targets[0].id)
                changed = True
    return names


def in_place_mutants(region: Region) -> Iterator[Mutation]:
    """``a = a <op> b`` → ``a <op>= b`` and ``c = p <op> b`` → ``p <op>= b; c = p`` where ``a``
    and ``p`` are parameters of the graded function or aliases of them.

    Parameters
    ----------
    region : Region
        The region to mutate.

    Yields
    ------
    Mutation
        One per assignment whose operand is a parameter (the left operand, or either operand
        of ``+`` and ``*``).
    """
    aliases = _aliases_of_parameters(region)
    for node in region.nodes():
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)
                and isinstance(node.value, ast.BinOp) and type(node.value.op) in _IN_PLACE_OPERATORS):
            continue
        target, value = node.targets[0].id, node.value
        symbol = _IN_PLACE_OPERATORS[type(value.op)]
        candidates = [(value.left, value.right)]
        if isinstance(value.op, _COMMUTATIVE):
            candidates.append((value.right, value.left))
        for operand, other in candidates:
            if not (isinstance(operand, ast.Name) and operand.id in aliases):
                continue
            name = operand.id
            if name == target:
                replacement = f"{name} {symbol}= {_code(other)}"
            else:
                replacement = f"{name} {symbol}= {_code(other)}; {target} = {name}"
            yield Mutation("in_place", node, replacement, f"{replacement!r} for {_code(node)!r}")


def _returned_values(region: Region) -> Iterator[tuple[ast.AST, int]]:
    """(value, position) of what each ``return`` of the holding function hands back: the
    value itself (position 0) or each element of a returned tuple (its position)."""
    for statement in region.returns():
        if isinstance(statement.value, ast.Tuple):
            for position, element in enumerate(statement.value.elts):
                yield element, position
        else:
            yield statement.value, 0


def _cannot_be_a_float_array(node: ast.AST) -> bool:
    """A returned expression that is surely not numbers (a comparison, a string, a dict...)."""
    if isinstance(node, ast.Constant):
        return not isinstance(node.value, (int, float)) or isinstance(node.value, bool)
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.Not):
        return True
    return isinstance(node, (ast.Compare, ast.BoolOp, ast.Dict, ast.DictComp, ast.JoinedStr, ast.Set))


def float32_mutants(region: Region, floating: Callable[[int], bool] | None = None) -> Iterator[Mutation]:
    """The returned value, or the first element of a returned tuple, cast to float32.

    Parameters
    ----------
    region : Region
        The region whose holding function's ``return`` statements are mutated.
    floating : callable, optional
        ``floating(position)`` tells whether what the function returns at that position holds
        floats (a boolean verdict cast to float32 is another mistake than lost precision);
        without it, every value that could be numbers.

    Yields
    ------
    Mutation
        One per ``return`` whose (first) value could be an array of floats.
    """
    for value, position in _returned_values(region):
        if position == 0 and not _cannot_be_a_float_array(value) and (floating is None or floating(0)):
            replacement = f"np.asarray({_code(value)}, dtype=np.float32)"
            yield Mutation("float32", value, replacement, f"{_code(value)!r} returned as float32")


def reshape_mutants(region: Region, one_dimensional: Callable[[int], bool]) -> Iterator[Mutation]:
    """A returned 1-D array reshaped to a column, (n, 1).

    Parameters
    ----------
    region : Region
        The region whose holding function's ``return`` statements are mutated.
    one_dimensional : callable
        ``one_dimensional(position)`` tells whether the value the function returns at that
        position of its returned tuple (0 for a single value) is a 1-D array.

    Yields
    ------
    Mutation
        One per returned 1-D value.
    """
    for value, position in _returned_values(region):
        if one_dimensional(position) and not _cannot_be_a_float_array(value):
            replacement = f"np.reshape({_code(value)}, (-1, 1))"
            yield Mutation("reshape", value, replacement, f"{_code(value)!r} returned as a column (n, 1)")


def swap_args_mutants(region: Region) -> Iterator[Mutation]:
    """Two positional arguments of a call swapped (every pair whose code differs).

    Parameters
    ----------
    region : Region
        The region to mutate.

    Yields
    ------
    Mutation
        One per pair of differing positional arguments of each call without ``*args``.
    """
    for node in region.nodes():
        if not isinstance(node, ast.Call) or any(isinstance(a, ast.Starred) for a in node.args):
            continue
        for i in range(len(node.args)):
            for j in range(i + 1, len(node.args)):
                if _code(node.args[i]) == _code(node.args[j]):
                    continue
                swapped = copy.deepcopy(node)
                swapped.args[i], swapped.args[j] = swapped.args[j], swapped.args[i]
                yield Mutation("swap_args", node, _code(swapped),
                               f"arguments {i + 1} and {j + 1} of {_code(node)!r} swapped")


def drop_term_mutants(region: Region) -> Iterator[Mutation]:
    """``a + b`` → ``a`` and ``a - b`` → ``a``.

    Parameters
    ----------
    region : Region
        The region to mutate.

    Yields
    ------
    Mutation
        One per addition or subtraction.
    """
    for node in region.nodes():
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
            yield Mutation("drop_term", node, _wrapped_as(node.left, node, region),
                           f"{_code(node.right)!r} dropped from {_code(node)!r}")


def flip_sign_mutants(region: Region) -> Iterator[Mutation]:
    """``+`` ↔ ``-`` (binary or augmented), a unary minus removed, or one added to the value of
    an assignment or a ``return``.

    Parameters
    ----------
    region : Region
        The region to mutate.

    Yields
    ------
    Mutation
        One per ``+``/``-`` operation, one per unary minus, one per assigned or returned value.
    """
    flipped = {ast.Add: ast.Sub, ast.Sub: ast.Add}
    for node in region.nodes():
        if isinstance(node, (ast.BinOp, ast.AugAssign)) and type(node.op) in flipped:
            changed = copy.deepcopy(node)
            changed.op = flipped[type(node.op)]()
            replacement = _code(changed) if isinstance(node, ast.AugAssign) else _wrapped_as(changed, node, region)
            yield Mutation("flip_sign", node, replacement,
                           f"{_code(changed)!r} for {_code(node)!r}")
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub):
            yield Mutation("flip_sign", node, _wrapped_as(node.operand, node, region),
                           f"the minus of {_code(node)!r} removed")
        if (isinstance(node, (ast.Assign, ast.Return)) and node.value is not None
                and not isinstance(node.value, (ast.Tuple, ast.Call)) and not _cannot_be_a_float_array(node.value)
                and not (isinstance(node.value, ast.UnaryOp) and isinstance(node.value.op, ast.USub))):
            # a call's value is left alone: negating what a helper returns is a sign error in
            # the helper, which the helper's own check judges (and an augmented assignment's
            # value negated is the flipped operator above)
            yield Mutation("flip_sign", node.value, f"-{_wrapped(node.value)}",
                           f"the value of {_code(node)!r} negated")


def _matmul_operands(node: ast.BinOp) -> list[ast.AST]:
    """The factors of a chain ``A @ B @ C`` (left-associated in the tree), in order."""
    factors = []
    for side in (node.left, node.right):
        if isinstance(side, ast.BinOp) and isinstance(side.op, ast.MatMult):
            factors.extend(_matmul_operands(side))
        else:
            factors.append(side)
    return factors


def transpose_mutants(region: Region) -> Iterator[Mutation]:
    """A ``.T`` dropped, or added to a factor of a ``@`` product that has none.

    Parameters
    ----------
    region : Region
        The region to mutate.

    Yields
    ------
    Mutation
        One per ``.T`` and one per untransposed factor of each (outermost) ``@`` chain.
    """
    inside_a_chain = set()  # ids of the `@` nodes that are part of a longer chain already seen
    for node in region.nodes():
        if isinstance(node, ast.Attribute) and node.attr == "T":
            yield Mutation("transpose", node, _wrapped_as(node.value, node, region),
                           f"the transpose of {_code(node)!r} dropped")
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.MatMult) and id(node) not in inside_a_chain:
            pending = [node]
            while pending:
                link = pending.pop()
                for side in (link.left, link.right):
                    if isinstance(side, ast.BinOp) and isinstance(side.op, ast.MatMult):
                        inside_a_chain.add(id(side))
                        pending.append(side)
            for factor in _matmul_operands(node):
                if not (isinstance(factor, ast.Attribute) and factor.attr == "T"):
                    yield Mutation("transpose", factor, f"{_wrapped(factor)}.T",
                                   f"{_code(factor)!r} transposed in {_code(node)!r}")


def _integer_constant(node: ast.AST) -> int | None:
    """The value of an integer literal (``3`` or ``-1``), else None."""
    if isinstance(node, ast.Constant) and type(node.value) is int:
        return node.value
    if (isinstance(node, ast.UnaryOp) and isinstance(node.op, ast.USub) and isinstance(node.operand, ast.Constant)
            and type(node.operand.value) is int):
        return -node.operand.value
    return None


def _known_lengths(region: Region) -> dict[str, int]:
    """Lengths of the names the holding function binds to a literal list or tuple, or to
    ``np.array``/``np.zeros``/``np.ones``/``np.empty`` of one (or of an integer length)."""
    lengths = {}
    scope = region.function if region.function is not None else region.tree
    for node in ast.walk(scope):
        if not (isinstance(node, ast.Assign) and len(node.targets) == 1 and isinstance(node.targets[0], ast.Name)):
            continue
        value = node.value
        if (isinstance(value, ast.Call) and isinstance(value.func, ast.Attribute)
                and value.func.attr in ("array", "asarray", "zeros", "ones", "empty") and value.args):
            value = value.args[0]
        if isinstance(value, (ast.List, ast.Tuple)):
            lengths[node.targets[0].id] = len(value.elts)
        elif (size := _integer_constant(value)) is not None and size >= 0:
            lengths[node.targets[0].id] = size
    return lengths


def _index_positions(subscript: ast.Subscript) -> Iterator[ast.AST]:
    """The integer literals among a subscript's indices and slice bounds."""
    elements = subscript.slice.elts if isinstance(subscript.slice, ast.Tuple) else [subscript.slice]
    for element in elements:
        parts = [element.lower, element.upper] if isinstance(element, ast.Slice) else [element]
        for part in parts:
            if part is not None and _integer_constant(part) is not None:
                yield part


def index_mutants(region: Region) -> Iterator[Mutation]:
    """A constant index or slice bound one more or one less.

    An index never crosses zero (``x[0]`` → ``x[-1]`` and ``x[-1]`` → ``x[0]`` jump to the
    other end of the array, a different mistake), and an index of the first axis of a name
    whose length the code shows stays below that length.

    Parameters
    ----------
    region : Region
        The region to mutate.

    Yields
    ------
    Mutation
        Up to two per integer literal in a subscript.
    """
    lengths = _known_lengths(region)
    for node in region.nodes():
        if not isinstance(node, ast.Subscript):
            continue
        first_axis = node.slice.elts[0] if isinstance(node.slice, ast.Tuple) and node.slice.elts else node.slice
        length = lengths.get(node.value.id) if isinstance(node.value, ast.Name) else None
        for part in _index_positions(node):
            value = _integer_constant(part)
            for shifted in (value + 1, value - 1):
                if (value >= 0) != (shifted >= 0):  # x[0] -> x[-1] jumps to the other end
                    continue
                if length is not None and part is first_axis and not -length <= shifted < length:
                    continue
                yield Mutation("index", part, str(shifted) if shifted >= 0 else f"-{-shifted}",
                               f"index {value} → {shifted} in {_code(node)!r}")


#: The operators that need nothing besides the region, by class.
OPERATORS: dict[str, Callable[[Region], Iterator[Mutation]]] = {
    "in_place": in_place_mutants,
    "float32": float32_mutants,
    "swap_args": swap_args_mutants,
    "drop_term": drop_term_mutants,
    "flip_sign": flip_sign_mutants,
    "transpose": transpose_mutants,
    "index": index_mutants,
}


# --- from a mutation to an edit --------------------------------------------------------------

def _offset(source: str, line: int, column: int) -> int:
    """The string offset of (1-based line, 0-based UTF-8 byte column) in ``source``."""
    lines = source.splitlines(keepends=True)
    start = sum(len(text) for text in lines[:line - 1])
    return start + len(lines[line - 1].encode()[:column].decode())


def as_edit(region: Region, mutation: Mutation) -> Edit:
    """The harness edit that writes ``mutation`` into the region's cell.

    The edit's ``old`` is the whole lines that hold the mutated span, widened by the lines
    before it until it occurs once in the cell.

    Parameters
    ----------
    region : Region
        Where the mutation was found.
    mutation : Mutation
        What to change.

    Returns
    -------
    Edit
        With ``cell`` set, ``keyword`` the class's word (:data:`CLASS_KEYWORD`; ``"Hint:"``
        for the other classes) and ``mistake`` ``"<class>: <description>"``.
    """
    source, node = region.source, mutation.node
    start = _offset(source, node.lineno, node.col_offset)
    end = _offset(source, node.end_lineno, node.end_col_offset)
    line_start = source.rfind("\n", 0, start) + 1
    line_end = source.find("\n", end)
    line_end = len(source) if line_end < 0 else line_end
    while source.count(source[line_start:line_end]) != 1 and line_start > 0:
        line_start = source.rfind("\n", 0, line_start - 1) + 1
    old = source[line_start:line_end]
    new = source[line_start:start] + mutation.replacement + source[end:line_end]
    keyword = CLASS_KEYWORD.get(mutation.operator, "Hint:")
    return Edit(region.check, old, new, keyword=keyword, mistake=f"{mutation.operator}: {mutation.description}",
                cell=region.cell_id)


def mutations(region: Region, one_dimensional: Callable[[int], bool] | None = None,
              floating: Callable[[int], bool] | None = None) -> list[Mutation]:
    """Every mutation of a region, by class in :data:`CLASSES` order, duplicates removed.

    Parameters
    ----------
    region : Region
        The region to mutate.
    one_dimensional : callable, optional
        For the ``reshape`` class (see :func:`reshape_mutants`); without it, no reshape.
    floating : callable, optional
        For the ``float32`` class (see :func:`float32_mutants`).

    Returns
    -------
    list of Mutation
        Each edit that compiles and changes the code; two sites that give the same code are
        kept once.
    """
    found, seen = [], set()
    for operator in CLASSES:
        if operator == "reshape":
            produced = reshape_mutants(region, one_dimensional) if one_dimensional else iter(())
        elif operator == "float32":
            produced = float32_mutants(region, floating)
        else:
            produced = OPERATORS[operator](region)
        for mutation in produced:
            edit = as_edit(region, mutation)
            edited = region.source.replace(edit.old, edit.new)
            try:
                code = ast.dump(ast.parse(edited))
            except SyntaxError:  # pragma: no cover - a generator bug, made loud below
                raise AssertionError(f"{region.check}: the mutation {mutation.description} does not compile")
            if code == ast.dump(region.tree) or code in seen:
                continue
            seen.add(code)
            found.append(mutation)
    return found


def returned_shapes(run_check: Callable[[], object], namespace: dict, function_name: str) -> dict[int, tuple]:
    """The number of dimensions and the kind of numbers of what a function returns, position
    by position, the first time it returns while a check runs.

    The function is swapped, in the namespace its callers look it up in, for a stand-in that
    calls it and notes what it returned the first time. (Stopping the check there would not
    be cheaper: a check that fails looks for the mistake that explains it, which costs more
    than the rest of the check.)

    Parameters
    ----------
    run_check : callable
        Runs the check once on ``namespace``'s functions.
    namespace : dict
        The globals of the notebook's functions; restored before returning.
    function_name : str
        The name of the function whose results are wanted.

    Returns
    -------
    dict
        position in the returned tuple (0 for a single value) → ``(ndim, kind)`` of the value
        there (``np.ndim`` and the dtype's kind, ``"f"`` for floats; ``(None, None)`` for a value
        that is not numbers); empty when the function did not return.
    """
    import functools

    import numpy as np

    def described(value) -> tuple:
        try:
            array = np.asarray(value)
        except Exception:  # an object NumPy cannot take: not numbers
            return (None, None)
        return (array.ndim, array.dtype.kind) if array.dtype.kind in "biuf" else (None, None)

    seen: dict[int, tuple] = {}
    original = namespace[function_name]

    @functools.wraps(original)
    def stand_in(*args, **kwargs):
        result = original(*args, **kwargs)
        if not seen:
            values = result if isinstance(result, tuple) else (result,)
            seen.update((k, described(v)) for k, v in enumerate(values))
        return result

    namespace[function_name] = stand_in
    try:
        run_check()
    finally:
        namespace[function_name] = original
    return seen
