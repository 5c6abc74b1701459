"""The Legendre transform at the initial state through the compiled Hessian point function."""

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.errors import DegenerateLagrangianError


def _systems():
    t = sp.Symbol("t")
    q1, q2, v1, v2, k = sp.symbols("q1 q2 v1 v2 k")
    # non-separable (mass depends on q), a gauge term a(t).v, a parameter
    coupled = gvi.LagrangianSystem(
        (2 + sp.cos(q2)) * v1**2 / 2 + v1 * v2 * sp.sin(q1) / 3 + v2**2 / 2
        + sp.cos(t) * v1 / 5 - k * (q1**2 + q2**2) / 2,
        [q1, q2], [v1, v2], t=t, params={k: 1.5},
    )  # fmt: skip
    # not quadratic in v: the momenta's velocities need Newton (the NumPy path)
    quartic = gvi.LagrangianSystem(v1**2 / 2 + v1**4 / 12 - q1**2 / 2, [q1], [v1])
    return {"coupled": coupled, "quartic": quartic}


@pytest.mark.parametrize("name", ["coupled", "quartic"])
def test_initial_momenta_equal_the_numpy_transform(name):
    system = _systems()[name]
    integ = gvi.Integrator(system, gvi.Galerkin(2))
    n = system.n
    q0, v0 = np.linspace(0.3, 0.7, n), np.linspace(-0.4, 0.2, n)
    t0 = 0.25
    traj = integ.integrate(q0, v0, h=0.01, n_steps=3, t0=t0, params={"k": 2.0} if n == 2 else None)
    assert integ.run_spec.legendre is not None  # the compiled path was taken
    expected = system.legendre(q0, v0, t0, {"k": 2.0} if n == 2 else None)
    np.testing.assert_allclose(traj.p[0], expected, rtol=1e-14, atol=1e-15)
    # and back: from the momenta, the same run (velocities by one solve or by Newton)
    again = integ.integrate(
        q0, p0=traj.p[0], h=0.01, n_steps=3, t0=t0, params={"k": 2.0} if n == 2 else None
    )
    np.testing.assert_allclose(again.q, traj.q, rtol=0, atol=1e-14)


def test_singular_mass_matrix_is_still_reported():
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(q**2 * v**2 / 2 - q**2 / 2, [q], [v])
    integ = gvi.Integrator(system, gvi.Galerkin(2))
    with pytest.raises(DegenerateLagrangianError, match="singular"):
        integ.integrate([0.0], [0.1], h=0.01, n_steps=2)


def test_the_compiled_path_skips_the_numpy_expressions(monkeypatch):
    system = _systems()["coupled"]
    integ = gvi.Integrator(system, gvi.Galerkin(2))
    q0, v0 = np.array([0.3, 0.7]), np.array([-0.4, 0.2])
    before = integ.integrate(q0, v0, h=0.01, n_steps=3)

    def refuse(*args, **kwargs):
        raise AssertionError("NumPy evaluation on the compiled path")

    monkeypatch.setattr(system, "evaluate", refuse)
    after = integ.integrate(q0, v0, h=0.01, n_steps=3)
    from_momenta = integ.integrate(q0, p0=before.p[0], h=0.01, n_steps=3)
    np.testing.assert_array_equal(after.q, before.q)
    np.testing.assert_allclose(from_momenta.q, before.q, rtol=0, atol=1e-14)


def test_a_matrix_found_regular_once_does_not_hide_a_singular_one():
    # L_vv = q^2: regular at q = 1, singular at q = 0; the same integrator for both
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(q**2 * v**2 / 2 - q**2 / 2, [q], [v])
    integ = gvi.Integrator(system, gvi.Galerkin(2))
    integ.integrate([1.0], [0.1], h=0.01, n_steps=2)
    with pytest.raises(DegenerateLagrangianError, match="singular"):
        integ.integrate([0.0], [0.1], h=0.01, n_steps=2)


def test_banded_systems_take_the_compiled_path(monkeypatch):
    # a 70-mass chain: banded storage of the second derivatives, more than 64 coordinates
    chain = problems.spring_chain(70, beta=1.0)
    system = chain.system
    integ = gvi.Integrator(system, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    before = integ.integrate(chain.q0, chain.v0, h=0.1, n_steps=3)
    assert integ._summary.banded
    np.testing.assert_allclose(
        before.p[0], system.legendre(chain.q0, chain.v0, 0.0), rtol=1e-15, atol=1e-15
    )

    def refuse(*args, **kwargs):
        raise AssertionError("NumPy evaluation on the compiled path")

    monkeypatch.setattr(system, "evaluate", refuse)
    after = integ.integrate(chain.q0, chain.v0, h=0.1, n_steps=3)
    from_momenta = integ.integrate(chain.q0, p0=before.p[0], h=0.1, n_steps=3)
    np.testing.assert_array_equal(after.q, before.q)
    np.testing.assert_allclose(from_momenta.q, before.q, rtol=0, atol=1e-14)


def _explicit_system():
    """Separable, constant mass depending on a parameter, a gauge term a(t) . v."""
    t = sp.Symbol("t")
    q1, q2, v1, v2, m, c = sp.symbols("q1 q2 v1 v2 m c")
    L = (
        m * v1**2 / 2 + c * v1 * v2 + v2**2 / 2 + sp.sin(t) * v2 / 3
        - (q1**2 + q2**4) / 2
    )  # fmt: skip
    return gvi.LagrangianSystem(L, [q1, q2], [v1, v2], t=t, params={m: 2.0, c: 0.5})


@pytest.mark.parametrize("params", [None, {"m": 3.0, "c": -0.25}])
def test_the_explicit_path_transform_equals_the_numpy_one_for_each_parameter_vector(params):
    system = _explicit_system()
    integ = gvi.Integrator(system, gvi.Galerkin(1))
    assert integ.kernel_path == "explicit"
    q0, v0, t0 = np.array([0.3, -0.2]), np.array([0.1, 0.4]), 0.7
    traj = integ.integrate(q0, v0, h=0.01, n_steps=5, t0=t0, params=params)
    np.testing.assert_allclose(traj.p[0], system.legendre(q0, v0, t0, params), rtol=1e-14)
    again = integ.integrate(q0, p0=traj.p[0], h=0.01, n_steps=5, t0=t0, params=params)
    np.testing.assert_allclose(again.q, traj.q, rtol=0, atol=1e-14)
    expected_v = system.inverse_legendre(q0, traj.p[0], t0, params)
    v = integ.run_spec.legendre.velocities_of_quadratic(
        t0, q0, traj.p[0], system.parameter_vector(params)
    )
    np.testing.assert_allclose(v, expected_v, rtol=1e-13)


def test_the_explicit_path_forms_the_mass_matrix_once_per_parameter_vector(monkeypatch):
    system = _explicit_system()
    integ = gvi.Integrator(system, gvi.Galerkin(1))
    q0, v0 = np.array([0.3, -0.2]), np.array([0.1, 0.4])
    before = integ.integrate(q0, v0, h=0.01, n_steps=5)

    def refuse(*args, **kwargs):
        raise AssertionError("NumPy evaluation on a repeated explicit call")

    monkeypatch.setattr(system, "evaluate", refuse)
    after = integ.integrate(q0, v0, h=0.01, n_steps=5)
    np.testing.assert_array_equal(after.q, before.q)
    with pytest.raises(AssertionError, match="repeated explicit call"):
        integ.integrate(q0, v0, h=0.01, n_steps=5, params={"m": 5.0})  # a new M is formed


def test_the_explicit_path_reports_a_singular_mass_matrix_for_its_parameters():
    system = _explicit_system()
    integ = gvi.Integrator(system, gvi.Galerkin(1))
    integ.integrate([0.3, -0.2], [0.1, 0.4], h=0.01, n_steps=2)  # regular at m = 2, c = 0.5
    # det [[m, c], [c, 1]] = m - c^2 = 0 at m = 0.25, c = 0.5
    for start in ({"v0": [0.1, 0.4]}, {"p0": [0.1, 0.4]}):
        with pytest.raises(DegenerateLagrangianError, match="singular"):
            integ.integrate([0.3, -0.2], **start, h=0.01, n_steps=2, params={"m": 0.25})
