"""The mutation operators of ``tests/mutation_generator.py`` on a small function: each makes
the edits it should, and none where its pattern is absent."""

import ast
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))

import mutation_generator as generator  # noqa: E402
from conftest import dedented  # noqa: E402

#: A graded function with one site (or a few) of every operator.
STEP = dedented('''
    def step(x_hat, P_hat, F, Q):
        """A prediction step, written to be mutated."""
        n = len(x_hat)
        # BEGIN SOLUTION step
        P = F @ P_hat @ F.T + Q
        x = x_hat - F[0, 1] * x_hat
        y = np.dot(x, P_hat)
        # STUB
        # P = Q  # fix this
        # END SOLUTION
        return x, P
''')

#: The same computations with none of the operators' patterns: no parameter as an operand, no
#: call with two arguments, no ``+``/``-``, no ``@`` or ``.T``, no constant index; a returned
#: comparison (never floats).
NOTHING_TO_MUTATE = dedented('''
    def ratio(a, b):
        """Nothing here matches an operator's pattern."""
        # BEGIN SOLUTION ratio
        c = a.copy()
        d = c.clip(b)
        # STUB
        # d = c  # fix this
        # END SOLUTION
        return d > 0
''')


def region(source: str) -> generator.Region:
    (found,) = generator.regions("cell", source)
    return found


def edited_lines(operator, source: str = STEP, **options) -> set[str]:
    """The edited line(s) of each mutation one operator makes of ``source``'s region."""
    where = region(source)
    if operator is generator.reshape_mutants:
        made = operator(where, **options)
    else:
        made = operator(where)
    return {generator.as_edit(where, m).new.strip() for m in made}


def test_the_region_is_the_code_between_its_marker_and_the_stub():
    where = region(STEP)
    assert where.check == "step" and where.function.name == "step"
    assert [ast.unparse(s) for s in where.statements] == [
        "P = F @ P_hat @ F.T + Q", "x = x_hat - F[0, 1] * x_hat", "y = np.dot(x, P_hat)"]
    assert where.parameters == ("x_hat", "P_hat", "F", "Q")
    assert [ast.unparse(r) for r in where.returns()] == ["return (x, P)"]


def test_in_place_writes_into_the_parameter_operand():
    assert edited_lines(generator.in_place_mutants) == {
        "Q += F @ P_hat @ F.T; P = Q",  # + is commutative: the parameter on the right too
        "x_hat -= F[0, 1] * x_hat; x = x_hat",
    }


def test_in_place_of_a_parameter_assigned_to_itself_and_of_an_alias():
    source = STEP.replace("x = x_hat - F[0, 1] * x_hat", "x = x_hat\n    x = x * 2.0")
    assert "x *= 2.0" in edited_lines(generator.in_place_mutants, source)


def test_float32_casts_the_first_returned_value():
    assert edited_lines(generator.float32_mutants) == {"return np.asarray(x, dtype=np.float32), P"}


def test_float32_only_where_the_returned_value_holds_floats():
    where = region(STEP)
    assert [m.operator for m in generator.float32_mutants(where, floating=lambda position: True)] == ["float32"]
    assert list(generator.float32_mutants(where, floating=lambda position: False)) == []


def test_reshape_only_where_the_returned_value_is_one_dimensional():
    assert edited_lines(generator.reshape_mutants, one_dimensional=lambda position: position == 0) == {
        "return np.reshape(x, (-1, 1)), P"}
    assert edited_lines(generator.reshape_mutants, one_dimensional=lambda position: False) == set()


def test_swap_args_swaps_two_positional_arguments():
    assert edited_lines(generator.swap_args_mutants) == {"y = np.dot(P_hat, x)"}


def test_drop_term_keeps_the_left_operand():
    assert edited_lines(generator.drop_term_mutants) == {"P = F @ P_hat @ F.T", "x = x_hat"}


def test_flip_sign_swaps_plus_and_minus_and_negates_assigned_values():
    assert edited_lines(generator.flip_sign_mutants) == {
        "P = F @ P_hat @ F.T - Q", "P = -(F @ P_hat @ F.T + Q)",
        "x = x_hat + F[0, 1] * x_hat", "x = -(x_hat - F[0, 1] * x_hat)",
    }


def test_flip_sign_removes_a_unary_minus():
    source = STEP.replace("y = np.dot(x, P_hat)", "y = -x")
    assert "y = x" in edited_lines(generator.flip_sign_mutants, source)


def test_transpose_drops_a_T_or_adds_one_to_a_factor_of_a_product():
    assert edited_lines(generator.transpose_mutants) == {
        "P = F @ P_hat @ F + Q", "P = F.T @ P_hat @ F.T + Q", "P = F @ P_hat.T @ F.T + Q"}


def test_index_moves_each_constant_index_by_one_without_wrapping():
    # F[0, 1]: 0 -> 1 (0 -> -1 would wrap round to the last row); 1 -> 2 and 1 -> 0
    assert edited_lines(generator.index_mutants) == {
        "x = x_hat - F[1, 1] * x_hat", "x = x_hat - F[0, 2] * x_hat", "x = x_hat - F[0, 0] * x_hat"}


def test_index_stays_within_a_length_the_code_shows():
    source = STEP.replace("n = len(x_hat)", "w = np.array([1.0, 2.0])").replace(
        "y = np.dot(x, P_hat)", "y = w[1] * x")
    lines = edited_lines(generator.index_mutants, source)
    assert "y = w[0] * x" in lines and "y = w[2] * x" not in lines


def test_index_moves_a_slice_bound_and_a_negative_index():
    source = STEP.replace("y = np.dot(x, P_hat)", "y = x[1:-1]")
    assert edited_lines(generator.index_mutants, source) >= {"y = x[2:-1]", "y = x[0:-1]", "y = x[1:-2]"}
    assert "y = x[1:0]" not in edited_lines(generator.index_mutants, source)


@pytest.mark.parametrize("operator", [op for op in generator.OPERATORS.values()], ids=list(generator.OPERATORS))
def test_no_edit_where_the_pattern_is_absent(operator):
    assert edited_lines(operator, NOTHING_TO_MUTATE) == set()


def test_no_reshape_of_a_value_that_cannot_be_floats():
    assert edited_lines(generator.reshape_mutants, NOTHING_TO_MUTATE, one_dimensional=lambda p: True) == set()


def test_an_edit_replaces_text_that_occurs_once_and_compiles():
    where = region(STEP)
    for mutation in generator.mutations(where, lambda position: True):
        edit = generator.as_edit(where, mutation)
        assert STEP.count(edit.old) == 1, edit
        ast.parse(STEP.replace(edit.old, edit.new))
        assert edit.cell == "cell" and edit.check == "step"
        assert edit.keyword == generator.CLASS_KEYWORD.get(mutation.operator, "Hint:")


def test_an_edit_widens_its_context_until_it_is_unique():
    source = STEP.replace("y = np.dot(x, P_hat)", "y = x_hat - F[0, 1] * x_hat")
    where = region(source)
    drops = [generator.as_edit(where, m) for m in generator.drop_term_mutants(where)]
    assert len(drops) == 3
    assert all(source.count(edit.old) == 1 for edit in drops)


def test_mutations_keep_one_of_two_sites_that_give_the_same_code():
    # removing either minus of -(-x) gives -x: one mutant, not two
    source = STEP.replace("y = np.dot(x, P_hat)", "y = -(-x)")
    where = region(source)
    removed = [m for m in generator.flip_sign_mutants(where) if "removed" in m.description]
    assert len(removed) == 2
    kept = [m for m in generator.mutations(where) if m.operator == "flip_sign" and "removed" in m.description]
    assert len(kept) == 1
