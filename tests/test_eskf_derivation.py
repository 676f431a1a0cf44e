"""SymPy derivations of the ESKF: proved, and equal to the numbers the filter uses."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

from kalman_course.core import so3
from kalman_course.filters import eskf
from kalman_course.symbolic import eskf as eskf_derivation

BUILDERS = (eskf_derivation.eskf_error_dynamics, eskf_derivation.eskf_discretisation, eskf_derivation.eskf_reset)


@pytest.mark.parametrize("build", BUILDERS, ids=lambda b: b.__name__)
def test_every_derivation_verifies_and_exports(build):
    d = build()
    assert d.verify(), d.check()
    md = d.to_markdown()
    assert d.title in md and "$$" in md


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
    R_syms = sorted(d.results["B_d"].free_symbols - set(values), key=str)
    values.update({s: R[int(str(s)[2]) - 1, int(str(s)[3]) - 1] for s in R_syms})
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


@pytest.mark.parametrize("build", BUILDERS, ids=lambda b: b.__name__)
def test_every_checked_equation_can_fail(build):
    import dataclasses

    d = build()
    for eq in (e for e in d.equations if e.checked):
        rhs = eq.rhs
        if isinstance(rhs, sp.MatrixBase):
            bump = sp.zeros(*rhs.shape)
            bump[0, 0] = sp.Rational(1, 7)
            wrong = dataclasses.replace(eq, rhs=sp.Matrix(rhs) + bump)
        else:
            wrong = dataclasses.replace(eq, rhs=rhs + sp.Rational(1, 7))
        assert not wrong.holds(), eq.label


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
