"""Boundary-value problems through the discrete action: closed forms, orders, failures."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import galerkin_vi as gvi
from galerkin_vi.action import ActionStatus

from .conftest import method_registry

q, v = sp.symbols("q v")
OSCILLATOR = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])  # omega = m = 1


def _oscillator_errors(method, T, q0, q1, N):
    """Largest nodal error and action error of the oscillator BVP against the closed form."""
    res = gvi.solve_bvp(OSCILLATOR, method, [q0], [q1], (0.0, T), N)
    assert res.success, res.message
    t = res.trajectory.t
    exact = (q0 * np.sin(T - t) + q1 * np.sin(t)) / np.sin(T)
    action = ((q0**2 + q1**2) * np.cos(T) - 2 * q0 * q1) / (2 * np.sin(T))
    return np.abs(res.trajectory.q[:, 0] - exact).max(), abs(res.action - action)


@pytest.mark.parametrize("method", method_registry(), ids=repr)
def test_oscillator_nodes_and_action_converge_at_the_methods_order(method):
    # T = 5 lies past the first conjugate point (pi): the Jacobian is indefinite there
    T, Ns = (5.0, (4, 8)) if method.order <= 8 else (20.0, (10, 20))
    (eq1, es1), (eq2, es2) = (_oscillator_errors(method, T, 1.0, 0.5, N) for N in Ns)
    assert abs(np.log2(eq1 / eq2) - method.order) < 0.5  # nodal superconvergence, h^order
    assert np.log2(es1 / es2) > method.order - 1  # the discrete action at the same order


@pytest.mark.parametrize("degree", [2, 3, 4])
def test_free_fall_is_exact_at_every_control_point(degree):
    g, T = 9.81, 2.0
    system = gvi.LagrangianSystem(v**2 / 2 - g * q, [q], [v])
    method = gvi.Galerkin(degree)
    res = gvi.solve_bvp(system, method, [0.0], [0.0], (0.0, T), 7)
    h = T / 7
    times = h * np.arange(7)[:, None] + method.tables.d * h
    # q = (g/2) t (T - t): a quadratic, in the Galerkin space for degree >= 2
    np.testing.assert_allclose(res.control_points[..., 0], g / 2 * times * (T - times),
                               rtol=0, atol=1e-14)  # fmt: skip
    # its momentum q' = g (T/2 - t) from the discrete Legendre transforms
    t = res.trajectory.t
    np.testing.assert_allclose(res.trajectory.p[:, 0], g * (T / 2 - t), rtol=0, atol=1e-13)
    # and the action int (q'^2/2 - g q) dt = -g^2 T^3 / 24
    assert res.action == pytest.approx(-(g**2) * T**3 / 24, rel=1e-14)


def test_the_path_is_the_time_stepping_solution_from_its_first_momentum():
    # the pendulum's BVP solution, integrated forward from (q_0, p_0), returns its own nodes
    pendulum = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
    method = gvi.Galerkin(3)
    res = gvi.solve_bvp(pendulum, method, [0.3], [-1.2], (0.0, 3.0), 30)
    assert res.success and res.iterations <= 8
    traj = gvi.Integrator(pendulum, method).integrate(
        [0.3], p0=res.trajectory.p[0], h=0.1, n_steps=30
    )
    np.testing.assert_allclose(traj.q, res.trajectory.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(traj.p, res.trajectory.p, rtol=0, atol=1e-11)


@settings(max_examples=12, deadline=None)
@given(
    degree=st.integers(1, 4),
    span=st.floats(0.3, 1.0),
    ends=st.tuples(st.floats(-1.0, 1.0), st.floats(-1.0, 1.0)),
    stiffness=st.floats(0.0, 1.0),
)
def test_every_stationary_path_is_a_time_stepping_trajectory(degree, span, ends, stiffness):
    # L = v^2/2 + cos q - k q^4/4 (a pendulum with a hardening spring), spans short of the
    # first conjugate point (frequencies up to 2 for |q| <= 1, so pi/2 > 1; longer spans can have no
    # solution near the straight line: q(0) = 0, q(2) = 1 at k = 1 has none, scipy's
    # solve_bvp fails there too): stepping forward from the path's first node and momentum
    # retraces its nodes (the same discrete equations)
    system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q) - stiffness * q**4 / 4, [q], [v])
    method = gvi.Galerkin(degree)
    N = 20
    res = gvi.solve_bvp(system, method, [ends[0]], [ends[1]], (0.0, span), N)
    assert res.success, res.message
    assert res.residual < 1e-12
    traj = gvi.Integrator(system, method).integrate(
        [ends[0]], p0=res.trajectory.p[0], h=span / N, n_steps=N
    )
    np.testing.assert_allclose(traj.q, res.trajectory.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(traj.p, res.trajectory.p, rtol=0, atol=1e-10)


def test_a_great_circle_through_the_sphere_constraint():
    x, y, z, vx, vy, vz = sp.symbols("x y z vx vy vz")
    sphere = gvi.LagrangianSystem(
        (vx**2 + vy**2 + vz**2) / 2, [x, y, z], [vx, vy, vz], constraints=[x**2 + y**2 + z**2 - 1]
    )
    a = np.array([1.0, 0.0, 0.0])
    b = np.array([0.0, np.cos(0.3), np.sin(0.3)])
    d = np.arccos(a @ b)
    e = (b - np.cos(d) * a) / np.sin(d)
    errors = []
    for N in (8, 16):
        res = gvi.solve_bvp(sphere, gvi.Galerkin(2), a, b, (0.0, 1.0), N)
        assert res.success and res.multipliers.shape == (N, 2, 1)
        t = res.trajectory.t
        # the great circle at constant speed d; every control point on the sphere
        great_circle = np.cos(d * t)[:, None] * a + np.sin(d * t)[:, None] * e
        np.testing.assert_allclose(res.trajectory.q, great_circle, rtol=0, atol=1e-14)
        radii = np.linalg.norm(res.control_points, axis=-1)
        np.testing.assert_allclose(radii, 1.0, rtol=0, atol=1e-14)
        # momenta tangent to the sphere, of size d
        assert np.abs(np.einsum("ka,ka->k", res.trajectory.p, res.trajectory.q)).max() < 1e-13
        np.testing.assert_allclose(np.linalg.norm(res.trajectory.p, axis=1), d, rtol=1e-4)
        errors.append(abs(res.action - d**2 / 2))
    assert np.log2(errors[0] / errors[1]) > 3.8  # the action d^2/2 at order 4


def test_the_catenary_is_cosh_with_its_length_and_functional():
    x, y, vy = sp.symbols("x y vy")
    # "time" is x: J[y] = int y sqrt(1 + y'^2) dx, stationary on y = cosh x
    catenary = gvi.LagrangianSystem(y * sp.sqrt(1 + vy**2), [y], [vy], t=x)
    c1 = np.cosh(1.0)
    flat = [c1]
    res = gvi.solve_bvp(
        catenary, gvi.Galerkin(4), flat, flat, (-1.0, 1.0), 16, guess=lambda x: flat
    )
    assert res.success
    x_nodes = res.trajectory.t
    np.testing.assert_allclose(res.trajectory.q[:, 0], np.cosh(x_nodes), rtol=0, atol=1e-12)
    assert res.action == pytest.approx(1 + np.sinh(2.0) / 2, abs=1e-12)  # 2.8134302039235095
    assert res.path_integral(sp.sqrt(1 + vy**2)) == pytest.approx(2 * np.sinh(1.0), abs=1e-12)


def test_the_brachistochrone_is_a_cycloid_with_its_descent_time():
    # "time" is x, y measured down from the start at rest: T[y] = int sqrt((1 + y'^2)/(2 g y)) dx,
    # stationary on the cycloid x = a (th - sin th), y = a (1 - cos th), T = sqrt(a/g) dth
    x, y, vy = sp.symbols("x y vy")
    g, a, th1, th2 = 9.81, 1.0, 1.0, 4.0
    system = gvi.LagrangianSystem(sp.sqrt((1 + vy**2) / (2 * g * y)), [y], [vy], t=x)
    ends = [a * (th - np.sin(th)) for th in (th1, th2)]
    errors = []
    for N in (128, 256):
        res = gvi.solve_bvp(system, gvi.Galerkin(3), [a * (1 - np.cos(th1))],
                            [a * (1 - np.cos(th2))], ends, N)  # fmt: skip
        assert res.success
        # the cycloid's parameter at each node, by Newton on x(th) = x_k
        th = np.full(N + 1, 2.0)
        for _ in range(60):
            th -= (a * (th - np.sin(th)) - res.trajectory.t) / (a * (1 - np.cos(th)))
        errors.append(np.abs(res.trajectory.q[:, 0] - a * (1 - np.cos(th))).max())
        assert res.action == pytest.approx(np.sqrt(a / g) * (th2 - th1), abs=1e-9)
    assert np.log2(errors[0] / errors[1]) > 5.5  # order 6 (measured 5.9)


def test_a_damped_oscillator_through_discrete_lagrange_dalembert():
    c, T, q0, q1 = 0.4, 3.0, 1.0, -0.2
    damped = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v], forces=[-c * v])
    w = np.sqrt(1 - c**2 / 4)
    # q = exp(-c t / 2) (A cos w t + B sin w t) through both ends
    B = (q1 * np.exp(c * T / 2) - q0 * np.cos(w * T)) / np.sin(w * T)
    errors = []
    for N in (6, 12):
        res = gvi.solve_bvp(damped, gvi.Galerkin(3), [q0], [q1], (0.0, T), N)
        t = res.trajectory.t
        exact = np.exp(-c * t / 2) * (q0 * np.cos(w * t) + B * np.sin(w * t))
        errors.append(np.abs(res.trajectory.q[:, 0] - exact).max())
    assert np.log2(errors[0] / errors[1]) > 5.5  # order 6 with forces too


def test_the_compiled_and_numpy_iterations_agree():
    # time dependence, a force depending on v, L_qv: every term of the element Jacobian
    t = sp.Symbol("t")
    L = v**2 / 2 + sp.cos(q) * (1 + sp.sin(t) / 3) + q * v * sp.cos(t) / 5
    system = gvi.LagrangianSystem(L, [q], [v], t=t, forces=[-0.3 * v * (1 + q**2)])
    runs = [gvi.solve_bvp(system, gvi.Galerkin(3), [0.2], [-0.7], (0.0, 2.5), 25, backend=b)
            for b in ("numba", "numpy")]  # fmt: skip
    assert all(r.success for r in runs) and runs[0].iterations == runs[1].iterations
    np.testing.assert_allclose(runs[0].control_points, runs[1].control_points, rtol=0, atol=1e-14)
    np.testing.assert_allclose(runs[0].trajectory.p, runs[1].trajectory.p, rtol=0, atol=1e-13)
    assert runs[0].action == pytest.approx(runs[1].action, abs=1e-14)
    assert max(r.residual for r in runs) < 1e-13


def test_a_guess_as_nodes_a_callable_or_a_trajectory_gives_the_same_path():
    pendulum = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
    method, span, N = gvi.Galerkin(2), (0.0, 3.0), 30
    first = gvi.solve_bvp(pendulum, method, [0.5], [1.0], span, N)
    t = first.trajectory.t
    guesses = [0.5 + t[:, None] / 6, lambda t: [0.5 + t / 6], first.trajectory]
    for guess in guesses:
        res = gvi.solve_bvp(pendulum, method, [0.5], [1.0], span, N, guess=guess)
        np.testing.assert_allclose(res.trajectory.q, first.trajectory.q, rtol=0, atol=1e-13)
    # started on the solution's control points, Newton confirms it in one step
    assert gvi.solve_bvp(pendulum, method, [0.5], [1.0], span, N, guess=first).iterations == 1


def test_an_unconverged_solve_keeps_its_last_iterate_and_says_why():
    pendulum = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
    res = gvi.solve_bvp(pendulum, gvi.Galerkin(2), [0.0], [3.0], (0.0, 2.0), 20, maxiter=1)
    assert res.status == ActionStatus.MAX_ITERATIONS and not res.success
    assert res.iterations == 1 and "maxiter" in res.message
    assert not res.trajectory.success and np.all(np.isfinite(res.trajectory.q))
    assert res.trajectory.q[0, 0] == 0.0 and res.trajectory.q[-1, 0] == 3.0
    assert res.residual > 1e-6


def test_bad_input_is_named():
    method = gvi.Galerkin(2)
    with pytest.raises(ValueError, match="t_span must have finite t0 < t1"):
        gvi.solve_bvp(OSCILLATOR, method, [0.0], [1.0], (1.0, 0.0), 10)
    with pytest.raises(ValueError, match="n_steps must be a positive int"):
        gvi.solve_bvp(OSCILLATOR, method, [0.0], [1.0], (0.0, 1.0), 0)
    with pytest.raises(ValueError, match=r"q_end must have shape \(1,\)"):
        gvi.solve_bvp(OSCILLATOR, method, [0.0], [1.0, 2.0], (0.0, 1.0), 10)
    with pytest.raises(ValueError, match="guess must be None, a callable"):
        gvi.solve_bvp(OSCILLATOR, method, [0.0], [1.0], (0.0, 1.0), 10, guess=np.zeros((3, 1)))
    x, y, vx, vy = sp.symbols("x y vx vy")
    circle = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2, [x, y], [vx, vy], constraints=[x**2 + y**2 - 1]
    )
    with pytest.raises(ValueError, match="q_start = .* violates the constraints"):
        gvi.solve_bvp(circle, method, [2.0, 0.0], [0.0, 1.0], (0.0, 1.0), 10)
    ball = gvi.LagrangianSystem(v**2 / 2 - q, [q], [v], contacts=[gvi.Contact(q)])
    with pytest.raises(ValueError, match="contacts"):
        gvi.solve_bvp(ball, method, [1.0], [1.0], (0.0, 1.0), 10)
    with pytest.raises(ValueError, match="backend must be"):
        gvi.solve_bvp(OSCILLATOR, method, [0.0], [1.0], (0.0, 1.0), 10, backend="cuda")
    with pytest.raises(ValueError, match="backend='numba': the compiled iteration needs"):
        gvi.solve_bvp(circle, method, [1.0, 0.0], [0.0, 1.0], (0.0, 1.0), 10, backend="numba")
    with pytest.raises(TypeError, match="method must be a Galerkin method"):
        gvi.solve_bvp(OSCILLATOR, "gauss", [0.0], [1.0], (0.0, 1.0), 10)
