"""Optimal control through the discrete action (DMOC): closed forms, orders of states, controls
and costates."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

import galerkin_vi as gvi

q, v, u = sp.symbols("q v u")


def test_the_double_integrator_is_exact_from_degree_two():
    # q'' = u from rest at 0 to rest at 1 in unit time, min int u^2/2: u = 6 - 12 t,
    # q = 3t^2 - 2t^3, cost 6, costate of p: lambda_p = -u (polynomials the method holds)
    system = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    res = gvi.solve_optimal_control(system, gvi.Galerkin(2), [u], u**2 / 2, (0.0, 1.0), 8,
                                    [0.0], [1.0], [0.0], [0.0], tol=1e-12)  # fmt: skip
    assert res.success and res.constraint_violation < 1e-13
    t = res.trajectory.t
    np.testing.assert_allclose(res.trajectory.q[:, 0], 3 * t**2 - 2 * t**3, rtol=0, atol=1e-10)
    np.testing.assert_allclose(res.trajectory.p[:, 0], 6 * t - 6 * t**2, rtol=0, atol=1e-9)
    np.testing.assert_allclose(res.controls[..., 0], 6 - 12 * res.control_times, rtol=0, atol=1e-7)
    np.testing.assert_allclose(res.multipliers[:, 0], 12 * t - 6, rtol=0, atol=1e-7)
    assert res.cost == pytest.approx(6.0, abs=1e-10)


def _steered_oscillator():
    """q'' = -q + u from (1, 0) to (0, 0) in T = 2, min int u^2/2: its closed form.

    Pontryagin: u = -lambda_p, lambda_p'' = -lambda_p, so u = -(A cos t + B sin t) and
    q = C cos t + D sin t - A t sin t / 2 + B t cos t / 2 (resonant forcing).
    """
    T = 2.0

    def state(t, A, B, C, D):
        q_ = C * np.cos(t) + D * np.sin(t) - A * t * np.sin(t) / 2 + B * t * np.cos(t) / 2
        p_ = (-C * np.sin(t) + D * np.cos(t) - A * (np.sin(t) + t * np.cos(t)) / 2
              + B * (np.cos(t) - t * np.sin(t)) / 2)  # fmt: skip
        return q_, p_

    rows = [[state(t, *e)[j] for e in np.eye(4)] for t, j in ((0, 0), (0, 1), (T, 0), (T, 1))]
    A, B, C, D = np.linalg.solve(np.array(rows), [1.0, 0.0, 0.0, 0.0])

    def control(t):
        return -(A * np.cos(t) + B * np.sin(t))

    cost = quad(lambda t: control(t) ** 2 / 2, 0, T, epsabs=1e-14, epsrel=1e-14)[0]
    return T, (lambda t: state(t, A, B, C, D)[0]), control, cost


@pytest.mark.parametrize("degree", [1, 2])
def test_states_controls_costates_and_cost_converge_at_the_methods_order(degree):
    T, exact_q, exact_u, exact_cost = _steered_oscillator()
    system = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    errors = []
    for N in (8, 16):
        res = gvi.solve_optimal_control(system, gvi.Galerkin(degree), [u], u**2 / 2, (0.0, T),
                                        N, [1.0], [0.0], [0.0], [0.0], tol=1e-12)  # fmt: skip
        assert res.success
        t = res.trajectory.t
        errors.append([
            np.abs(res.trajectory.q[:, 0] - exact_q(t)).max(),
            np.abs(res.controls[..., 0] - exact_u(res.control_times)).max(),
            np.abs(res.multipliers[:, 0] + exact_u(t)).max(),  # lambda_p = -u
            abs(res.cost - exact_cost),
        ])  # fmt: skip
    slopes = np.log2(np.array(errors[0]) / np.array(errors[1]))
    # measured: degree 1: 2.0, 2.0, 2.0, 2.0; degree 2: 4.0, 4.0, 4.0, 4.0
    assert np.all(np.abs(slopes - 2 * degree) < 0.3), slopes


def test_free_ends_take_their_natural_conditions():
    system = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    method = gvi.Galerkin(2)
    # to q(1) = 1 from rest, the final speed free: the costate vanishes there, u = 3 (1 - t),
    # cost 3/2, arriving with p = 3/2
    speed_free = gvi.solve_optimal_control(system, method, [u], u**2 / 2, (0.0, 1.0), 8, [0.0],
                                           [1.0], [0.0], None, tol=1e-12)  # fmt: skip
    assert speed_free.success and speed_free.cost == pytest.approx(1.5, abs=1e-9)
    np.testing.assert_allclose(speed_free.controls[..., 0], 3 * (1 - speed_free.control_times),
                               rtol=0, atol=1e-6)  # fmt: skip
    # the controls are optimal to 1e-6 (above): the momentum they reach agrees to 2.5e-9
    # (SciPy 1.17), 1e-10 with older SciPy
    assert speed_free.trajectory.p[-1, 0] == pytest.approx(1.5, abs=1e-8)
    # to speed 1 from rest, wherever it gets: u = 1, cost 1/2, at q(1) = 1/2
    place_free = gvi.solve_optimal_control(system, method, [u], u**2 / 2, (0.0, 1.0), 8, [0.0],
                                           None, [0.0], [1.0], tol=1e-12)  # fmt: skip
    assert place_free.success and place_free.cost == pytest.approx(0.5, abs=1e-9)
    np.testing.assert_allclose(place_free.controls, 1.0, rtol=0, atol=1e-6)
    assert place_free.trajectory.q[-1, 0] == pytest.approx(0.5, abs=1e-9)


def test_control_bounds_saturate_the_control():
    # |u| <= 5: u = 5 until t1 = (1 - sqrt(0.6))/2, then linear to -5 at 1 - t1, then -5;
    # cost 25 t1 + 25 (1 - 2 t1)/6 (the kinks cost the method its order)
    system = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    t1 = (1 - np.sqrt(0.6)) / 2
    exact = 25 * t1 + 25 * (1 - 2 * t1) / 6
    bounds = (-5.0, 5.0)
    res = gvi.solve_optimal_control(system, gvi.Galerkin(2), [u], u**2 / 2, (0.0, 1.0), 16,
                                    [0.0], [1.0], [0.0], [0.0], control_bounds=bounds)  # fmt: skip
    assert res.success and res.constraint_violation < 1e-12
    assert np.abs(res.controls).max() <= 5.0 + 1e-8
    assert abs(res.cost - exact) < 3e-4  # measured 1.6e-4 (N = 16), 2.8e-5 (N = 32)
    assert res.cost > 6.0  # above the unbounded optimum


def test_state_bounds_hold_at_every_control_point():
    # launched at p = 1 from 0, back at rest at 0 in unit time: unbounded, u = 6t - 4 (cost 2)
    # and q peaks at 4/27 = 0.148; with q <= 0.1 the path flattens against the bound
    system = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    free, capped = (
        gvi.solve_optimal_control(system, gvi.Galerkin(2), [u], u**2 / 2, (0.0, 1.0), 16, [0.0],
                                  [0.0], [1.0], [0.0], state_bounds=bounds)
        for bounds in (None, (-1.0, 0.1))
    )  # fmt: skip
    assert free.success and capped.success
    assert free.cost == pytest.approx(2.0, abs=1e-9)
    assert free.control_points[..., 0].max() > 0.14
    assert capped.control_points[..., 0].max() <= 0.1 + 1e-8
    assert capped.cost > free.cost + 0.3  # measured 2.376


@pytest.mark.parametrize("bounded", [False, True])
def test_ipopt_solves_the_same_program(bounded):
    pytest.importorskip("casadi")
    system = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    bounds = (-5.0, 5.0) if bounded else None
    runs = [
        gvi.solve_optimal_control(system, gvi.Galerkin(2), [u], u**2 / 2, (0.0, 1.0), 16, [0.0],
                                  [1.0], [0.0], [0.0], control_bounds=bounds, solver=solver,
                                  tol=1e-12)
        for solver in ("trust-constr", "ipopt")
    ]  # fmt: skip
    assert all(r.success for r in runs)
    assert runs[0].cost == pytest.approx(runs[1].cost, abs=1e-8)
    np.testing.assert_allclose(runs[0].controls, runs[1].controls, rtol=0, atol=1e-5)
    np.testing.assert_allclose(runs[0].multipliers, runs[1].multipliers, rtol=0, atol=1e-5)


def test_bad_input_is_named():
    system = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})
    method = gvi.Galerkin(2)
    w = sp.Symbol("w")
    with pytest.raises(ValueError, match="controls must be parameters of the system"):
        gvi.solve_optimal_control(system, method, [w], u**2, (0, 1), 4, [0.0], [1.0])
    with pytest.raises(ValueError, match="cost may depend on t, q, v and parameters only"):
        gvi.solve_optimal_control(system, method, [u], w**2, (0, 1), 4, [0.0], [1.0])
    with pytest.raises(ValueError, match="p_start must be 1 finite numbers"):
        gvi.solve_optimal_control(system, method, [u], u**2, (0, 1), 4, [0.0], [1.0], [0.0, 1.0])
    with pytest.raises(ValueError, match="state_bounds: lower"):
        gvi.solve_optimal_control(system, method, [u], u**2, (0, 1), 4, [0.0], [1.0],
                                  state_bounds=(1.0, 0.0))  # fmt: skip
    with pytest.raises(ValueError, match="solver must be 'trust-constr' or 'ipopt'"):
        gvi.solve_optimal_control(system, method, [u], u**2, (0, 1), 4, [0.0], [1.0],
                                  solver="snopt")  # fmt: skip
    in_lagrangian = gvi.LagrangianSystem(v**2 / 2 + u * q, [q], [v], params={u: 0.0})
    with pytest.raises(ValueError, match="through the forces only"):
        gvi.solve_optimal_control(in_lagrangian, method, [u], u**2, (0, 1), 4, [0.0], [1.0])


def test_a_cart_pole_swings_up():
    # underactuated and nonlinear: the force acts on the cart, the pole goes from hanging to
    # upright in 2 s; the converged optimum is 58.8076675 (benchmarks/cart_pole.py, where
    # CasADi + IPOPT Hermite-Simpson collocation converges to the same value)
    x, th, vx, w = sp.symbols("x theta vx w")
    mc, mp, length, g = 1.0, 0.3, 0.5, 9.81
    kinetic = (mc + mp) * vx**2 / 2 + mp * length * vx * w * sp.cos(th) + mp * length**2 * w**2 / 2
    system = gvi.LagrangianSystem(kinetic + mp * g * length * sp.cos(th), [x, th], [vx, w],
                                  forces=[u, 0], params={u: 0.0})  # fmt: skip
    res = gvi.solve_optimal_control(system, gvi.Galerkin(3), [u], u**2, (0.0, 2.0), 40,
                                    [0.0, 0.0], [1.0, np.pi], [0.0, 0.0], [0.0, 0.0],
                                    control_bounds=(-20.0, 20.0))  # fmt: skip
    assert res.success and res.constraint_violation < 1e-12
    assert res.cost == pytest.approx(58.8076675, abs=1e-4)  # measured error 4.9e-5 at N = 40
    np.testing.assert_allclose(res.trajectory.q[-1], [1.0, np.pi], rtol=0, atol=1e-14)
    np.testing.assert_allclose(res.trajectory.p[-1], [0.0, 0.0], rtol=0, atol=1e-10)
