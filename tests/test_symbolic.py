"""Tests for kalman_course.symbolic: every derivation proves, wrong formulas fail, and the
symbolic results agree numerically with the library and with independent numerics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import sympy as sp
from sympy.matrices.expressions import BlockMatrix, Identity, ZeroMatrix

from kalman_course import symbolic
from kalman_course.symbolic import Derivation, Equation, equations, registry
from kalman_course.symbolic.equations import exact_inverse

#: Every derivation of the course, in course order: chapters 02, 03, 04, 05, 08.
EXPECTED_NAMES = ["schur_block_inverse", "linear_map_moments", "gaussian_conditioning",
                  "kalman_gain", "kf_update_conditioning", "cv_model",
                  "cv_planar_model", "ca_model", "ctrv_model", "ctra_model", "radar_model",
                  "eskf_error_dynamics", "eskf_discretisation", "eskf_reset"]
NAMES = list(registry.builders())


def random_spd(rng, n):
    A = rng.normal(size=(n, n))
    return A @ A.T + n * np.eye(n)


# ---------------------------------------------------------------- registry and proofs

def test_registry_has_every_derivation_in_course_order():
    assert NAMES == EXPECTED_NAMES
    built = symbolic.derivations()
    assert list(built) == EXPECTED_NAMES
    for name, d in built.items():
        assert isinstance(d, Derivation) and d.name == name
        assert symbolic.derivation(name) is d
        assert d.title and d.model
        assert any(e.checked for e in d.equations)


def test_no_builder_of_the_package_is_left_out_of_the_registry():
    import importlib
    import pkgutil

    marked = set()
    for info in pkgutil.iter_modules(symbolic.__path__):
        module = importlib.import_module(f"{symbolic.__name__}.{info.name}")
        marked |= {obj.derivation_name for obj in vars(module).values()
                   if hasattr(obj, "derivation_name") and obj.__module__ == module.__name__}
    assert marked == set(EXPECTED_NAMES)


def test_registry_refuses_two_builders_of_one_name(monkeypatch):
    import types

    from kalman_course.symbolic import gaussians

    other = types.ModuleType("other_topic")

    def schur_block_inverse():
        return gaussians.schur_block_inverse()

    schur_block_inverse.__module__ = other.__name__
    other.schur_block_inverse = symbolic.derivation_builder(schur_block_inverse)
    monkeypatch.setattr(registry, "TOPICS", (gaussians, other))
    registry.builders.cache_clear()
    try:
        with pytest.raises(RuntimeError, match="two derivation builders are named 'schur_block_inverse'"):
            registry.builders()
    finally:
        monkeypatch.undo()
        registry.builders.cache_clear()
    assert list(registry.builders()) == EXPECTED_NAMES


def test_builder_must_return_the_derivation_of_its_name():
    @symbolic.derivation_builder
    def misnamed():
        return Derivation("other", "t", "m", (Equation("a", sp.Integer(1), sp.Integer(1)),))

    assert misnamed.derivation_name == "misnamed"
    with pytest.raises(ValueError, match="misnamed"):
        misnamed()


def test_unknown_derivation_names_the_known_ones():
    with pytest.raises(ValueError, match="schur_block_inverse"):
        symbolic.derivation("no_such_thing")


@pytest.mark.parametrize("name", NAMES)
def test_every_derivation_verifies(name):
    d = symbolic.derivation(name)
    results = d.check()
    assert results and all(results.values()), {k: v for k, v in results.items() if not v}
    assert d.verify() is True


def _perturbed(eq: Equation) -> Equation:
    """The same equation with a wrong right-hand side (explicit or scalar sides only)."""
    rhs = eq.rhs
    if isinstance(rhs, sp.MatrixBase):
        bump = sp.zeros(*rhs.shape)
        bump[0, 0] = sp.Rational(1, 7)
        return dataclasses.replace(eq, rhs=sp.Matrix(rhs) + bump)
    return dataclasses.replace(eq, rhs=rhs + sp.Rational(1, 7))


@pytest.mark.parametrize("name", NAMES)
def test_every_explicit_equation_can_fail(name):
    d = symbolic.derivation(name)
    explicit = [e for e in d.equations if e.checked and not equations.has_matrix_symbols(e.lhs)
                and (isinstance(e.rhs, sp.MatrixBase) or not isinstance(e.rhs, sp.MatrixExpr))]
    if not explicit:
        pytest.skip(f"{name} has only matrix-symbol identities")
    for eq in explicit:
        assert not _perturbed(eq).holds(), eq.label
        broken = dataclasses.replace(d, equations=tuple(_perturbed(e) if e is eq else e
                                                         for e in d.equations))
        assert broken.verify() is False


def test_wrong_block_formulas_fail():
    d = symbolic.schur_block_inverse()
    A, B, C, D = (d.symbols[k] for k in "ABCD")
    n, m = d.symbols["n"], d.symbols["m"]
    eye = BlockMatrix([[Identity(n), ZeroMatrix(n, m)], [ZeroMatrix(m, n), Identity(m)]])
    upper = BlockMatrix([[Identity(n), B * D.I], [ZeroMatrix(m, n), Identity(m)]])
    not_negated = BlockMatrix([[Identity(n), B * D.I], [ZeroMatrix(m, n), Identity(m)]])
    negated = BlockMatrix([[Identity(n), -B * D.I], [ZeroMatrix(m, n), Identity(m)]])
    assert Equation("ok", upper * negated, eye).holds()
    assert not Equation("wrong", upper * not_negated, eye).holds()
    # explicit 3x3 (exact arithmetic): the Schur complement with the wrong sign is wrong
    a, b = symbolic.symbol_matrix("a", 2, 2), symbolic.symbol_matrix("b", 2, 1)
    c, dd = symbolic.symbol_matrix("c", 1, 2), symbolic.symbol_matrix("d", 1, 1)
    f = equations.ExactArithmetic(a, b, c, dd)
    a, b, c, dd = f(a), f(b), f(c), f(dd)
    M = a.hstack(b).vstack(c.hstack(dd))
    Di = dd.inv()
    for schur, expected in ((a - b * Di * c, True), (a + b * Di * c, False)):
        Si = schur.inv()
        Mi = Si.hstack(-Si * b * Di).vstack((-Di * c * Si).hstack(Di + Di * c * Si * b * Di))
        assert Equation("inv", f.back(M * Mi), sp.eye(3), kind="check").holds() is expected


def test_wrong_gain_is_not_stationary():
    P = symbolic.symbol_matrix("p", 2, 2, symmetric=True)
    G = symbolic.symbol_matrix("g", 1, 2)
    R = symbolic.symbol_matrix("r", 1, 1)
    K = symbolic.symbol_matrix("k", 2, 1)
    trace = ((sp.eye(2) - K * G) * P * (sp.eye(2) - K * G).T + K * R * K.T).trace()
    grad = sp.Matrix([sp.diff(trace, k) for k in K])
    for gain, expected in ((P * G.T * exact_inverse(G * P * G.T + R), True),
                           (P * G.T * exact_inverse(R), False),
                           (P * G.T * exact_inverse(G * P * G.T), False)):
        at = dict(zip(K, gain))
        assert Equation("stationary", grad.subs(at, simultaneous=True), sp.zeros(2, 1)).holds() is expected


def test_wrong_conditional_covariance_fails():
    d = symbolic.gaussian_conditioning()
    eq = d["quadratic_split_2+1"]
    S = symbolic.symbol_matrix("s", 3, 3, symmetric=True)
    e = symbolic.symbol_matrix("e", 2, 1)
    f = symbolic.symbol_matrix("f", 1, 1)
    Sxx, Sxy, Syy = S[:2, :2], S[:2, 2:], S[2:, 2:]
    wrong_cov = Sxx + Sxy * exact_inverse(Syy) * Sxy.T  # sign flipped
    r = e - Sxy * exact_inverse(Syy) * f
    wrong_split = (r.T * exact_inverse(wrong_cov) * r)[0, 0] + (f.T * exact_inverse(Syy) * f)[0, 0]
    assert not dataclasses.replace(eq, rhs=wrong_split).holds()


def test_wrong_continuous_q_fails():
    d = symbolic.cv_model()
    T, q = d.symbols["T"], d.symbols["q"]
    eq = d["Q_continuous"]
    wrong = q * sp.Matrix([[T**3 / 2, T**2 / 2], [T**2 / 2, T]])
    assert eq.holds() and not dataclasses.replace(eq, rhs=wrong).holds()


def test_is_zero_does_not_sample():
    x = sp.Symbol("x")
    assert symbolic.is_zero(sp.sin(x) ** 2 + sp.cos(x) ** 2 - 1)
    assert not symbolic.is_zero(sp.sin(x) ** 2 - 1)
    assert symbolic.is_zero((x**2 - 1) / (x - 1) - x - 1)
    assert not symbolic.is_zero(sp.Matrix([[0, 1e-30]]))


# ---------------------------------------------------------------- data model

def test_equation_validation():
    with pytest.raises(ValueError, match="kind"):
        Equation("a", sp.Integer(1), sp.Integer(1), kind="theorem")
    with pytest.raises(ValueError, match="shape"):
        Equation("a", sp.eye(2), sp.eye(3))
    with pytest.raises(ValueError, match="label"):
        Equation("", sp.Integer(1), sp.Integer(1))
    eq = Equation("a", sp.Integer(1), sp.Integer(1))
    with pytest.raises(ValueError, match="duplicate"):
        Derivation("d", "t", "m", (eq, eq))
    with pytest.raises(ValueError, match="Equation"):
        Derivation("d", "t", "m", ("not an equation",))


def test_derivation_without_checked_equations_does_not_verify():
    d = Derivation("d", "t", "m", (Equation("a", sp.Integer(1), sp.Integer(2), kind="definition"),))
    assert d.check() == {} and d.verify() is False


def test_lookup_display_and_immutability():
    d = symbolic.kalman_gain()
    assert d["gain"].kind == "definition"
    with pytest.raises(KeyError, match="labels"):
        d["nope"]
    assert d.labels[0] == "error"
    md = d.to_markdown()
    assert md.startswith(f"**{d.title}**") and "$$" in md and "`gain`" in md
    assert d._repr_markdown_() == md
    assert len(d.to_markdown(details=True)) > len(md)
    assert repr(d) == "Derivation('kalman_gain': 12 equations, 9 proved by verify())"
    assert "K" in d["gain"].latex()
    with pytest.raises(TypeError):
        d.results["K"] = None
    with pytest.raises(dataclasses.FrozenInstanceError):
        d.name = "other"


def test_derivations_are_built_once():
    assert symbolic.derivations()["cv_model"] is symbolic.cv_model()


def test_symbol_matrix():
    S = symbolic.symbol_matrix("s", 3, 3, symmetric=True)
    assert S == S.T and len(S.free_symbols) == 6
    assert symbolic.symbol_matrix("v", 2, 1)[1, 0] == sp.Symbol("v_2")
    with pytest.raises(ValueError, match="square"):
        symbolic.symbol_matrix("s", 2, 3, symmetric=True)


# ---------------------------------------------------------------- numeric agreement

@pytest.mark.parametrize("n, m", [(1, 1), (2, 3), (3, 2)])
def test_block_inverse_numerically(n, m):
    from kalman_course.core import gaussians

    rng = np.random.default_rng(10 * n + m)
    M = rng.normal(size=(n + m, n + m)) + 3 * np.eye(n + m)
    d = symbolic.schur_block_inverse()
    Minv = d.evaluate("M_inv", A=M[:n, :n], B=M[:n, n:], C=M[n:, :n], D=M[n:, n:])
    np.testing.assert_allclose(Minv, np.linalg.inv(M), rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(Minv, gaussians.block_inverse(M, n), rtol=1e-10, atol=1e-12)
    schur = d.evaluate("schur_complement", A=M[:n, :n], B=M[:n, n:], C=M[n:, :n], D=M[n:, n:])
    np.testing.assert_allclose(schur, gaussians.schur_complement(M, n), rtol=1e-10, atol=1e-12)


@pytest.mark.parametrize("n, m", [(1, 1), (2, 1), (3, 2)])
def test_conditioning_numerically(n, m):
    from kalman_course.core import gaussians

    rng = np.random.default_rng(7 + n + m)
    J = random_spd(rng, n + m)
    mu, y = rng.normal(size=n + m), rng.normal(size=m)
    blocks = dict(Sigma_xx=J[:n, :n], Sigma_xy=J[:n, n:], Sigma_yy=J[n:, n:])
    d = symbolic.gaussian_conditioning()
    mean = d.evaluate("mean", mu_x=mu[:n], mu_y=mu[n:], y=y, **blocks)
    cov = d.evaluate("cov", **blocks)
    ref_mean, ref_cov = gaussians.conditional(mu[:n], mu[n:], J[:n, :n], J[:n, n:], J[n:, n:], y)
    np.testing.assert_allclose(mean, ref_mean, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cov, ref_cov, rtol=1e-10, atol=1e-12)
    # the split of the log density: log p(x, y) = log p(x | y) + log p(y)
    x = rng.normal(size=n)
    z = np.concatenate([x, y])
    lhs = gaussians.gaussian_logpdf(z, mu, J)
    rhs = gaussians.gaussian_logpdf(x, mean, cov) + gaussians.gaussian_logpdf(y, mu[n:], J[n:, n:])
    assert abs(lhs - rhs) < 1e-10


def test_linear_map_numerically():
    from kalman_course.core import gaussians

    rng = np.random.default_rng(3)
    mu, Sxx, G, R = rng.normal(size=3), random_spd(rng, 3), rng.normal(size=(2, 3)), random_spd(rng, 2)
    d = symbolic.linear_map_moments()
    mu_y, S_yy, S_xy = gaussians.linear_map(mu, Sxx, G, R)
    np.testing.assert_allclose(d.evaluate("mu_y", mu_x=mu, G=G), mu_y, atol=1e-12)
    np.testing.assert_allclose(d.evaluate("Sigma_yy", Sigma_xx=Sxx, G=G, R=R), S_yy, atol=1e-12)
    np.testing.assert_allclose(d.evaluate("Sigma_xy", Sigma_xx=Sxx, G=G), S_xy, atol=1e-12)


@pytest.mark.parametrize("n, m", [(2, 1), (2, 2), (4, 2)])
def test_gain_minimises_the_trace_numerically(n, m):
    from kalman_course.filters import kf

    rng = np.random.default_rng(100 + 10 * n + m)
    P, G, R = random_spd(rng, n), rng.normal(size=(m, n)), random_spd(rng, m)
    d = symbolic.kalman_gain()
    K = d.evaluate("K", P_check=P, G=G, R=R)
    S = d.evaluate("S", P_check=P, G=G, R=R)
    np.testing.assert_allclose(K, kf.kf_gain(P, G, S), rtol=1e-10, atol=1e-12)

    def trace(K_):
        return np.trace(d.evaluate("P_hat", P_check=P, G=G, R=R, K=K_))

    # central finite differences of the trace vanish at K ...
    h = 1e-5
    grad = np.zeros_like(K)
    for idx in np.ndindex(*K.shape):
        E = np.zeros_like(K)
        E[idx] = h
        grad[idx] = (trace(K + E) - trace(K - E)) / (2 * h)
    assert np.max(np.abs(grad)) < 1e-6
    # ... and every random perturbation increases it
    t0 = trace(K)
    for _ in range(20):
        assert trace(K + 1e-2 * rng.normal(size=K.shape)) > t0


def test_kf_update_as_conditioning_numerically():
    from kalman_course.filters import kf

    rng = np.random.default_rng(5)
    n, m, l = 4, 2, 3
    x, P = rng.normal(size=n), random_spd(rng, n)
    G, C, R, y = rng.normal(size=(m, n)), rng.normal(size=(m, l)), random_spd(rng, l), rng.normal(size=m)
    d = symbolic.kf_update_conditioning()
    values = dict(x_check=x, P_check=P, G=G, C=C, R=R, y=y)
    ref = kf.kf_update(x, P, y, G, R, C=C)
    np.testing.assert_allclose(d.evaluate("x_hat", **values), ref.x_hat, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(d.evaluate("P_hat", x_check=x, P_check=P, G=G, C=C, R=R), ref.P_hat,
                               rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(d.evaluate("S", P_check=P, G=G, C=C, R=R), ref.S, rtol=1e-10)


def test_evaluate_errors():
    d = symbolic.kalman_gain()
    with pytest.raises(KeyError, match="results"):
        d.evaluate("nothing")
    with pytest.raises(KeyError, match="symbols"):
        d.evaluate("K", Q=np.eye(2))
    with pytest.raises(ValueError, match="missing"):
        d.evaluate("K", P_check=np.eye(2), G=np.ones((1, 2)))
    with pytest.raises(ValueError, match="fixed"):
        d.evaluate("K", P_check=np.eye(2), G=np.ones((1, 3)), R=np.eye(1))


# ---------------------------------------------------------------- the CV model

def test_cv_matrices_from_sympy():
    T, sa = 0.7, 1.3
    np.testing.assert_array_equal(symbolic.cv_transition(T), [[1, T], [0, 1]])
    Q = symbolic.cv_process_noise(T, sa)
    np.testing.assert_allclose(Q, sa**2 * np.array([[T**4 / 4, T**3 / 2], [T**3 / 2, T**2]]))
    B = symbolic.cv_noise_jacobian(T)
    np.testing.assert_allclose(B @ B.T * sa**2, Q)
    assert abs(np.linalg.det(Q)) < 1e-12  # rank one
    np.testing.assert_allclose(symbolic.cv_model().evaluate("Q_piecewise", T=T, sigma_a=sa), Q)


def test_cv_state_order_is_blocked():
    T = 0.5
    F = symbolic.cv_transition(T, dim=2)
    np.testing.assert_array_equal(F, [[1, 0, T, 0], [0, 1, 0, T], [0, 0, 1, 0], [0, 0, 0, 1]])
    G = symbolic.cv_observation_matrix(2)
    np.testing.assert_array_equal(G, [[1, 0, 0, 0], [0, 1, 0, 0]])
    Q = symbolic.cv_process_noise(T, 2.0, dim=3)
    assert Q.shape == (6, 6)
    # axes are independent; position x and velocity x are coupled
    assert Q[0, 1] == 0 and Q[0, 3] == pytest.approx(4 * T**3 / 2)
    x = np.array([1.0, 2.0, 10.0, -4.0])
    np.testing.assert_allclose(F @ x, [1 + 10 * T, 2 - 4 * T, 10, -4])


def test_cv_step_matches_integrated_kinematics():
    from scipy.integrate import solve_ivp

    T, a = 0.8, np.array([0.9, -1.7])
    x0 = np.array([1.0, -2.0, 3.0, 0.5])
    sol = solve_ivp(lambda t, x: np.concatenate([x[2:], a]), (0, T), x0, rtol=1e-12, atol=1e-12)
    x_T = symbolic.cv_transition(T, 2) @ x0 + symbolic.cv_noise_jacobian(T, 2) @ a
    np.testing.assert_allclose(x_T, sol.y[:, -1], rtol=1e-9, atol=1e-9)


def test_cv_continuous_q_matches_numerical_integral():
    from scipy.integrate import quad_vec
    from scipy.linalg import expm

    T, q = 1.7, 0.35
    A = np.array([[0.0, 1.0], [0.0, 0.0]])
    L = np.array([[0.0], [1.0]])
    Q_num, err = quad_vec(lambda s: expm(A * s) @ L @ L.T @ expm(A * s).T * q, 0.0, T, epsabs=1e-13)
    np.testing.assert_allclose(symbolic.cv_process_noise_continuous(T, q), Q_num, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(symbolic.cv_transition(T), expm(A * T), atol=1e-12)
    assert np.linalg.det(Q_num) == pytest.approx(q**2 * T**4 / 12, rel=1e-9)


def test_cv_piecewise_q_matches_sampled_discretisation():
    # Q of the piecewise model is the covariance of Gamma a: check it as an exact sum over
    # a two-point distribution of a (+-sigma_a with equal probability), no Monte Carlo.
    T, sa = 0.4, 2.5
    B = symbolic.cv_noise_jacobian(T)
    cov = sum(0.5 * np.outer(B @ [s], B @ [s]) for s in (sa, -sa))
    np.testing.assert_allclose(symbolic.cv_process_noise(T, sa), cov, rtol=1e-12)


@pytest.mark.parametrize("bad", [-0.1, np.nan, np.inf, "1", True, None])
def test_cv_rejects_bad_time_steps(bad):
    with pytest.raises(ValueError, match="T must be"):
        symbolic.cv_transition(bad)


@pytest.mark.parametrize("bad", ["2", True, None, -1.0, np.inf])
def test_cv_rejects_bad_noise_levels(bad):
    with pytest.raises(ValueError, match="sigma_a must be"):
        symbolic.cv_process_noise(0.1, bad)


def test_cv_rejects_bad_arguments():
    with pytest.raises(ValueError, match="dim"):
        symbolic.cv_transition(1.0, dim=0)
    with pytest.raises(ValueError, match="dim"):
        symbolic.cv_observation_matrix(1.5)
    with pytest.raises(ValueError, match="sigma_a"):
        symbolic.cv_process_noise(1.0, -1.0)
    with pytest.raises(ValueError, match="q must"):
        symbolic.cv_process_noise_continuous(1.0, np.nan)
    np.testing.assert_array_equal(symbolic.cv_process_noise(0.0, 1.0), np.zeros((2, 2)))


def test_lambdified_functions_are_cached():
    from kalman_course.symbolic import kalman

    assert kalman._cv_functions() is kalman._cv_functions()
