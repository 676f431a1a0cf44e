"""SymPy derivations of the ESKF: displayed step by step, every step proved, every plausible
wrong step refused, and the results equal to the numbers the filter uses."""

from __future__ import annotations

import dataclasses
import re

import numpy as np
import pytest
import sympy as sp

from kalman_course.core import so3
from kalman_course.filters import eskf
from kalman_course.symbolic import eskf as eskf_derivation
from kalman_course.symbolic.equations import Derivation
from kalman_course.symbolic.eskf import SYMBOLS as S
from kalman_course.symbolic.stepwise import (Cross, Exp, ExplicitModel, Log, Skew, Step, add, mat, mul, step_latex,
                                             steps_markdown, unit_quaternion_rotation, vec)

BUILDERS = (eskf_derivation.eskf_error_dynamics, eskf_derivation.eskf_discretisation, eskf_derivation.eskf_reset)
I3 = sp.Identity(3)


def _wrong(d: Derivation, label: str, rhs) -> Step:
    return dataclasses.replace(d[label], rhs=rhs)


# ---------------------------------------------------------------- proofs and display

@pytest.mark.parametrize("build", BUILDERS, ids=lambda b: b.__name__)
def test_every_derivation_verifies_and_exports(build):
    d = build()
    assert d.verify(), d.check()
    md = d.to_markdown(details=True)
    assert d.title in md and "$$" in md


@pytest.mark.parametrize("build", BUILDERS, ids=lambda b: b.__name__)
def test_every_line_is_a_compact_genuine_step(build):
    """Each displayed line says something: its two sides differ, and it is short enough to
    read (no expanded 3 x 3 components)."""
    d = build()
    assert all(isinstance(eq, Step) for eq in d.equations)
    for eq in d.equations:
        lhs, rhs = step_latex(eq.lhs), step_latex(eq.rhs)
        assert lhs != rhs and eq.lhs != eq.rhs, eq.label
        assert len(eq.latex()) < 600, (eq.label, len(eq.latex()))
        assert eq.description, eq.label


@pytest.mark.parametrize("build", BUILDERS, ids=lambda b: b.__name__)
def test_symbols_render_as_the_lecture_writes_them(build):
    text = "\n".join(eq.latex() for eq in build().equations)
    assert not re.search(r"(?<!\\)delta", text), "a bare 'delta' would print as a word"
    assert "_{1}" not in text and "_1" not in text, "no components of explicit vectors are displayed"
    assert "\\mathbb" not in text


def test_the_chain_of_delta_v_reads_as_in_the_lecture():
    d = eskf_derivation.eskf_error_dynamics()
    assert d["dv_definition"].latex() == r"\delta\dot{v} = \dot{\check{v}} - \dot{v}"
    assert d["dv_collect"].latex() == (r"\delta\dot{v} \approx - R \left[a\right]_{\times} \delta\theta "
                                       r"- R \delta b_{a} + R n_{a}")
    assert d["dth_nominal"].latex() == (r"\delta\dot{\theta} \approx - \left[\check{\omega}\right]_{\times} "
                                        r"\delta\theta - \delta b_{\omega} + n_{\omega}")
    assert d["nav_frame_form"].latex() == r"\left[R a\right]_{\times} = R \left[a\right]_{\times} R^{T}"
    # first-order steps are marked as such
    assert [eq.label for eq in d.equations if eq.checked and not eq.approximate][:3] == \
        ["cross_antisymmetry", "skew_commutator", "dv_dynamics"]


def test_steps_markdown_numbers_proves_and_says_how():
    d = eskf_derivation.eskf_error_dynamics()
    md = steps_markdown(d, ["dv_definition", "dv_dynamics", "dv_collect"])
    assert md.startswith(f"**({d.labels.index('dv_definition') + 1})** ")
    assert "[definition]" in md and "[SymPy: exact]" in md and "[SymPy: equal to first order]" in md
    assert md.count("$$") == 6
    bad = Derivation("bad", "t", "m", (_wrong(d, "dv_collect", mul(S.R, Skew(S.a), S.dth)),))
    with pytest.raises(AssertionError, match="dv_collect"):
        steps_markdown(bad)
    with pytest.raises(KeyError):
        steps_markdown(d, ["no_such_step"])
    # numbered as shown: a lecture showing steps in its own order counts on from where it was
    shown = steps_markdown(d, ["dv_collect", "dv_definition"], start=7)
    assert re.findall(r"\*\*\((\d+)\)\*\*", shown) == ["7", "8"]
    assert shown.startswith("**(7)** " + d["dv_collect"].description)
    for bad_start in (0, -1, 1.5, True):
        with pytest.raises(ValueError, match="start"):
            steps_markdown(d, ["dv_collect"], start=bad_start)


def test_the_handout_renders_delta_theta(tmp_path):
    from kalman_course.tooling import export

    tex = export.derivations_latex({b.__name__: b() for b in BUILDERS})
    assert r"\delta\theta" in tex and r"\delta b_{\omega}" in tex
    assert "deltaθ" not in tex and not re.search(r"(?<![\\a-zA-Z])delta", tex.replace(r"\delta", ""))


# ---------------------------------------------------------------- every step can fail

@pytest.mark.parametrize("build", BUILDERS, ids=lambda b: b.__name__)
def test_every_checked_equation_can_fail(build):
    d = build()
    for eq in (e for e in d.equations if e.checked):
        bump = sp.zeros(*eq.rhs.shape)
        bump[0, 0] = sp.Rational(1, 7)
        rhs = sp.Matrix(eq.rhs) + bump if isinstance(eq.rhs, sp.MatrixBase) else add(eq.rhs, sp.ImmutableMatrix(bump))
        assert not dataclasses.replace(eq, rhs=rhs).holds(), eq.label


def _mistakes():
    """(derivation, label, wrong right-hand side, the mistake) of plausible errors."""
    d, r, q = eskf_derivation.eskf_error_dynamics(), eskf_derivation.eskf_reset(), eskf_derivation.eskf_discretisation()
    R, a, dth, dba, n_a, w = S.R, S.a, S.dth, S.dba, S.n_a, S.w
    dth_hat = vec(r"\delta\hat{\theta}")
    e = vec("e")
    T = q.symbols["T"]
    sa = q.symbols["sigma_a"]
    return [
        (d, "dv_collect", add(mul(R, Skew(a), dth), -mul(R, dba), mul(R, n_a)), "sign of the attitude block"),
        (d, "dv_collect", add(-mul(Skew(mul(R, a)), dth), -mul(R, dba), mul(R, n_a)),
         "navigation-frame block with the body-frame error"),
        (d, "dv_collect", add(-mul(R, Skew(S.f), dth), -mul(R, dba), mul(R, n_a)), "specific force not bias-corrected"),
        (d, "dv_collect", add(-mul(R, Skew(a), dth), -dba, mul(R, n_a)), "bias error not rotated"),
        (d, "dv_drop", add(mul(R, Skew(dth), a), mul(R, dba), mul(R, n_a)), "sign of the bias error"),
        (d, "dv_global", add(-mul(R, Skew(a), S.dth_g), -mul(R, dba), mul(R, n_a)),
         "body-frame block with the global error"),
        (d, "dth_product_rule", add(mul(S.R_dot, S.R_check), mul(R.T, S.R_check_dot)), "transpose forgotten"),
        (d, "dth_rate", add(mul(Skew(w), dth), -S.dbw, S.n_w), "sign of -[w]x"),
        (d, "dth_rate", add(-mul(Skew(S.w_m), dth), -S.dbw, S.n_w), "rate not bias-corrected"),
        (d, "dth_commutator", add(Skew(Cross(w, dth)), Skew(add(S.n_w, -S.dbw))), "commutator reversed"),
        (d, "exp_first_order", add(I3, -Skew(dth)), "Exp expanded with the wrong sign"),
        (d, "nav_frame_form", mul(R, Skew(a)), "R^T forgotten"),
        (d, "nav_frame_form", mul(R.T, Skew(a), R), "conjugated the wrong way"),
        (d, "pose_attitude", add(dth, S.n_th), "noise sign in the attitude residual"),
        (d, "pose_attitude", add(-dth, S.n_th), "residual the other way round"),
        (d, "global_adjoint", Exp(mul(R.T, dth)), "R^T instead of R"),
        (r, "reset_jacobian", mul(add(I3, mul(-sp.Rational(1, 2), Skew(dth_hat))), e),
         "the other error convention's sign"),
        (r, "reset_jacobian", e, "no reset correction (the lecture's P unchanged)"),
        (r, "keep", add(I3, Skew(e)), "the cross term dropped"),
        (q, "pv_block_first_order", sp.ImmutableMatrix([[0, 0], [0, sa ** 2 * T ** 2]]), "T^2 where T belongs"),
        (q, "F_first_order", add(sp.Identity(15), S.F_t), "step T missing"),
    ]


@pytest.mark.parametrize("case", range(len(_mistakes())))
def test_plausible_wrong_steps_fail(case):
    d, label, rhs, mistake = _mistakes()[case]
    assert d[label].holds()
    assert not _wrong(d, label, rhs).holds(), mistake


def test_nav_frame_form_needs_a_rotation_and_holds_for_every_one():
    """Proved for R(q) with q^T q = 1 (every rotation); false for a general matrix."""
    d = eskf_derivation.eskf_error_dynamics()
    eq = d["nav_frame_form"]
    assert eq.holds() and eq.model.relation is not None
    general = ExplicitModel()
    general.define(S.R, sp.Matrix(3, 3, sp.symbols("m:9")))
    general.define(S.a, sp.Matrix(sp.symbols("a:3")))
    assert not dataclasses.replace(eq, model=general).holds()
    # numerically, at random rotations, as a cross-check of the symbolic proof
    rng = np.random.default_rng(1)
    for _ in range(5):
        Rn, an = so3.exp(rng.normal(size=3) * 2), rng.normal(size=3)
        np.testing.assert_allclose(so3.hat(Rn @ an), Rn @ so3.hat(an) @ Rn.T, atol=1e-12)


def test_unit_quaternion_rotation_is_a_rotation():
    R, relation, q = unit_quaternion_rotation("p")
    rng = np.random.default_rng(2)
    for _ in range(3):
        v = rng.normal(size=4)
        v /= np.linalg.norm(v)
        Rn = np.array(R.subs(dict(zip(q, v))), dtype=float)
        assert so3.is_rotation(Rn, tol=1e-12)
        assert abs(float(relation.subs(dict(zip(q, v))))) < 1e-12


# ---------------------------------------------------------------- the engine behind the steps

def test_series_of_exp_matches_the_exponential_map():
    eps = sp.Symbol("epsilon")
    m = ExplicitModel(small=(eps,))
    v = np.array([0.3, -0.2, 0.5])
    m.define(S.dth, eps * sp.ImmutableMatrix(v.tolist()))
    coeffs = m.series(Exp(S.dth), ((eps, 4),))
    for e in (1e-1, 1e-2):
        approx = sum(np.array(C, dtype=float) * e ** k for (k,), C in coeffs.items())
        assert np.abs(approx - so3.exp(e * v)).max() < 10 * (e * np.linalg.norm(v)) ** 5


def test_the_engine_refuses_what_it_cannot_prove():
    eps = sp.Symbol("epsilon")
    m = ExplicitModel(small=(eps,))
    x, y = vec("x"), vec("y")
    m.define(x, eps * sp.Matrix(sp.symbols("x1:4")))
    m.define(y, sp.Matrix(sp.symbols("y1:4")))                       # not small
    m.define(vec("z"), add(x, y), valid_to=0)
    with pytest.raises(ValueError, match="Log is made explicit only"):
        Step("log_exact", Log(Exp(x)), x, "", "check", m).holds()
    with pytest.raises(ValueError, match="must vanish"):
        Step("exp_of_large", Exp(y), add(I3, Skew(y)), "", "check", m, ((eps, 1),)).holds()
    with pytest.raises(ValueError, match="defined only to order 0"):
        Step("too_far", vec("z"), add(x, y), "", "check", m, ((eps, 1),)).holds()
    with pytest.raises(ValueError, match="orders must give every small parameter"):
        Step("no_order", x, x, "", "check", m, ((sp.Symbol("other"), 1),))
    with pytest.raises(ValueError, match="a Step is a 'check' or a 'definition'"):
        Step("identity", x, x, "", "identity", m)
    with pytest.raises(ValueError, match="needs an ExplicitModel"):
        Step("no_model", x, y, "", "check")
    with pytest.raises(KeyError, match="no meaning"):
        Step("unknown", vec("w"), x, "", "check", m).holds()
    # Log of a small rotation is its vector, to second order
    assert Step("log", Log(Exp(x)), x, "", "check", m, ((eps, 2),)).holds()


def test_printing_keeps_the_written_order():
    f, b = vec("f"), vec("b_{a}")
    assert step_latex(add(f, -b)) == "f - b_{a}"
    assert step_latex(mul(sp.Rational(1, 2), Skew(f))) == r"\tfrac{1}{2} \left[f\right]_{\times}"
    assert step_latex(mul(-1, mat("R"), add(f, -b))) == r"- R \left(f - b_{a}\right)"


# ---------------------------------------------------------------- the numbers the filter uses

def test_symbolic_F_t_equals_the_filters_F_t():
    F_sym = eskf_derivation.error_dynamics_function()
    rng = np.random.default_rng(0)
    for _ in range(5):
        R = so3.exp(rng.normal(size=3))
        f, w, ba, bw = (rng.normal(size=3) for _ in range(4))
        np.testing.assert_allclose(F_sym(R, f, w, ba, bw), eskf.error_dynamics(R, f, w, ba, bw), atol=1e-14)


def test_discretised_noise_matches_the_filter():
    d = eskf_derivation.eskf_discretisation()
    T, sa, sw, sba, sbw = (d.symbols[k] for k in ("T", "sigma_a", "sigma_omega", "sigma_ba", "sigma_bomega"))
    R = so3.exp(np.array([0.3, -0.2, 0.5]))
    values = {T: 0.01, sa: 0.03, sw: 1e-3, sba: 1.67e-4, sbw: 2.91e-6}
    values.update(dict(zip(d.symbols["R"], R.ravel())))
    B_d = np.array(d.results["B_d"].subs(values), dtype=float)
    Q_k = np.array(d.results["Q_k"].subs(values), dtype=float)
    _, B = eskf.discretise(np.zeros((15, 15)), eskf.noise_jacobian(R), 0.01)
    Q = eskf.process_noise([0.03, 1e-3, 1.67e-4, 2.91e-6], 0.01)
    np.testing.assert_allclose(B_d, B, atol=1e-15)
    np.testing.assert_allclose(Q_k, Q, rtol=1e-12)


def test_reset_jacobian_first_order_form_agrees_with_the_filter():
    d = eskf_derivation.eskf_reset()
    J = d.results["J"]
    lam = sp.Symbol("lambda")
    h = sorted(J.free_symbols - {lam}, key=str)
    v = np.array([0.01, -0.02, 0.015])
    Jn = np.array(J.subs({lam: 1, **dict(zip(h, v))}), dtype=float)
    G = eskf.reset_jacobian(np.concatenate([np.zeros(6), v, np.zeros(6)]))
    np.testing.assert_allclose(Jn, G[6:9, 6:9], atol=3e-4)          # differs at O(|δθ̂|²) = 1e-4
    assert np.abs(Jn - (np.eye(3) - 0.5 * so3.hat(v))).max() > 0.005  # the other sign is wrong


def test_the_eskf_derivations_close_the_course_registry():
    from kalman_course import symbolic

    names = [build.__name__ for build in BUILDERS]
    assert list(symbolic.registry.builders())[-3:] == names
    for build in BUILDERS:
        assert symbolic.derivation(build.__name__) is build()
        assert build().name == build.__name__


def test_F_t_function_validates_its_arguments():
    F_sym = eskf_derivation.error_dynamics_function()
    with pytest.raises(ValueError, match=r"R must have shape \(3, 3\)"):
        F_sym(np.eye(2), np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))
    with pytest.raises(ValueError, match="omega_m must be finite"):
        F_sym(np.eye(3), np.zeros(3), [0.0, np.nan, 0.0], np.zeros(3), np.zeros(3))
