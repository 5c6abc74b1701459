"""Dense output: Hermite interpolation of the nodal (q, v) at the method's order."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import galerkin_vi as gvi
from galerkin_vi.run import dense
from galerkin_vi.run.dense import hermite, stencil_nodes

q, v = sp.symbols("q v")
OSCILLATOR = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])  # q = cos t from (1, 0)
PENDULUM = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])


@settings(max_examples=30, deadline=None)
@given(
    size=st.integers(2, 5),
    seed=st.integers(0, 2**31 - 1),
)
def test_hermite_is_exact_for_polynomials_of_degree_2n_minus_1(size, seed):
    rng = np.random.default_rng(seed)
    nodes = np.sort(rng.uniform(-1.0, 1.0, size))
    while np.min(np.diff(nodes)) < 0.05:  # distinct, not nearly confluent
        nodes = np.sort(rng.uniform(-1.0, 1.0, size))
    poly = np.polynomial.Polynomial(rng.normal(size=2 * size))
    t = rng.uniform(nodes[0], nodes[-1], 7)  # dense output interpolates, never extrapolates
    y, dy = hermite(
        np.tile(nodes, (7, 1)),
        np.tile(poly(nodes)[:, None], (7, 1, 1)),
        np.tile(poly.deriv()(nodes)[:, None], (7, 1, 1)),
        t,
    )
    scale = np.abs(poly.coef).sum()
    # divided differences over nodes 0.05 apart lose digits: worst of 3000 draws
    # 3.2e-11 * scale (values), 1.3e-10 * scale (derivatives)
    np.testing.assert_allclose(y[:, 0], poly(t), rtol=0, atol=2e-10 * scale)
    np.testing.assert_allclose(dy[:, 0], poly.deriv()(t), rtol=0, atol=1e-9 * scale)


def test_stencil_gives_the_derivative_the_methods_order():
    assert [stencil_nodes(p) for p in (1, 2, 4, 6, 8)] == [2, 2, 3, 4, 5]
    for p in range(1, 12):
        assert 2 * stencil_nodes(p) - 1 >= p
    with pytest.raises(ValueError, match="positive int"):
        stencil_nodes(0)


@pytest.mark.parametrize(
    ("family", "s", "counts"),
    [
        ("gauss", 1, (32, 64, 128)),
        ("gauss", 2, (8, 16, 32)),
        ("gauss", 3, (8, 16, 32)),
        ("lobatto", 2, (8, 16, 32)),
        ("lobatto", 3, (8, 16, 32)),
        ("gauss", 4, (4, 6, 8)),
    ],
)
def test_dense_output_has_the_methods_order_between_the_nodes(family, s, counts):
    quad = gvi.gauss_legendre(s) if family == "gauss" else gvi.gauss_lobatto(s + 1)
    integrator = gvi.Integrator(OSCILLATOR, gvi.Galerkin(s, quad), backend="numpy")
    span = 4.0
    errors_q, errors_v, steps = [], [], []
    for n in counts:
        h = span / n
        traj = integrator.integrate([1.0], [0.0], h=h, n_steps=n, dense_output=True)
        between = traj.t[:-1] + 0.37 * h  # off the nodes, every interval
        errors_q.append(np.max(np.abs(traj.sol(between)[:, 0] - np.cos(between))))
        errors_v.append(np.max(np.abs(traj.sol.velocity(between)[:, 0] + np.sin(between))))
        steps.append(h)
    order = integrator.method.order
    # measured: q 1.98-9.3, v 2.0-7.9 against orders 2-8 (docs/howto/dense-output.md)
    for errors in (errors_q, errors_v):
        slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
        assert slope > order - 0.35, (errors, slope)


def test_dense_output_passes_through_the_saved_states():
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(3))
    traj = integrator.integrate([1.5], [0.3], h=0.2, n_steps=40, dense_output=True)
    np.testing.assert_allclose(traj.sol(traj.t), traj.q, rtol=0, atol=1e-14)
    np.testing.assert_allclose(traj.sol.velocity(traj.t), traj.velocities(), rtol=0, atol=1e-13)
    # p = dL/dv = v here: the momenta of the interpolant at the nodes are the run's
    np.testing.assert_allclose(traj.sol.momentum(traj.t), traj.p, rtol=0, atol=1e-13)
    assert traj.sol(0.5).shape == (1,) and traj.sol([0.5, 0.7]).shape == (2, 1)
    assert traj.sol(np.zeros((3, 2))).shape == (3, 2, 1)


def test_long_runs_build_the_stencils_they_use_and_agree_bitwise(monkeypatch):
    # runs beyond the cache size build only the Newton tables their query points need
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(3))
    traj = integrator.integrate([1.5], [0.3], h=0.2, n_steps=40, dense_output=True)
    t = np.linspace(0.0, 8.0, 333)
    cached = traj.sol.state(t)
    monkeypatch.setattr(dense, "_CACHED_STENCILS", 10)
    fresh = gvi.Integrator(PENDULUM, gvi.Galerkin(3)).integrate(
        [1.5], [0.3], h=0.2, n_steps=40, dense_output=True
    )
    for a, b in zip(cached, fresh.sol.state(t), strict=True):
        np.testing.assert_array_equal(a, b)


def test_dense_output_of_a_backward_run():
    integrator = gvi.Integrator(OSCILLATOR, gvi.Galerkin(2), backend="numpy")
    traj = integrator.integrate([1.0], [0.0], h=-0.05, n_steps=40, dense_output=True)
    t = np.linspace(-1.99, -0.01, 50)
    np.testing.assert_allclose(traj.sol(t)[:, 0], np.cos(t), rtol=0, atol=1e-7)
    np.testing.assert_allclose(traj.sol.velocity(t)[:, 0], -np.sin(t), rtol=0, atol=1e-7)


def test_dense_output_arguments():
    integrator = gvi.Integrator(OSCILLATOR, gvi.Galerkin(2), backend="numpy")
    plain = integrator.integrate([1.0], [0.0], h=0.1, n_steps=5)
    assert plain.sol is None
    with pytest.raises(ValueError, match="needs save_every=1, got 2"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=4, save_every=2, dense_output=True)
    with pytest.raises(TypeError, match="dense_output must be True or False"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=4, dense_output=1)
    sol = integrator.integrate([1.0], [0.0], h=0.1, n_steps=5, dense_output=True).sol
    with pytest.raises(ValueError, match="outside the run's span"):
        sol(0.6)
    with pytest.raises(ValueError, match="finite"):
        sol(np.nan)
    # any trajectory, after the fact, with a chosen stencil
    assert plain.dense(stencil=2).stencil == 2
    with pytest.raises(ValueError, match="at least 2 saved states"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=0).dense()
