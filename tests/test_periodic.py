"""Angles: detection of 2 pi-periodic coordinates and their reduction inside the loops."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.backends.numpy import unwrapped, wrap_angles
from galerkin_vi.symbolic import periodic_coordinates

x, y, th, ph = sp.symbols("x y th ph")
vx, vy, w, wp = sp.symbols("vx vy w wp")


@pytest.mark.parametrize(
    ("expr", "expected"),
    [
        (w**2 / 2 + sp.cos(th), (True,)),
        (w**2 / 2 + sp.cos(2 * th) + sp.sin(3 * th) ** 2, (True,)),
        (w**2 / 2 + sp.cos(th / 2), (False,)),  # period 4 pi
        (w**2 / 2 - th**2 / 2, (False,)),
        (w**2 / 2 + th * sp.sin(th), (False,)),
    ],
)
def test_periodic_coordinates_are_found_symbolically(expr, expected):
    assert periodic_coordinates([expr], [th]) == expected


def test_a_coordinate_that_appears_nowhere_is_not_an_angle():
    assert periodic_coordinates([w**2 / 2], [th]) == (False,)


def test_every_expression_must_be_periodic():
    # L is periodic in th, a constraint is not: th is then no angle
    assert periodic_coordinates([sp.cos(th), th - x], [th, x]) == (False, False)
    system = gvi.LagrangianSystem(
        (wp**2 + w**2) / 2 + sp.cos(th) + sp.cos(ph), [th, ph], [w, wp], forces=[-w, ph]
    )
    assert system.periodic == (True, False)


def test_wrapping_removes_whole_turns_exactly():
    # 2 pi is removed as hi + lo, so the compensated value keeps its low-order bits
    q = np.array([50.0, 0.5, -20.0])
    lost, turns = np.zeros(3), np.zeros(3)
    qk = q.copy()
    wrap_angles(np.array([True, True, True]), qk, lost, turns)
    assert np.all(qk >= -np.pi) and np.all(qk < np.pi)
    np.testing.assert_array_equal(turns, [8.0, 0.0, -3.0])
    np.testing.assert_allclose(unwrapped(qk - lost, turns), q, rtol=0, atol=4e-15)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
@pytest.mark.parametrize("degree", [1, 2])
def test_rotating_pendulum_output_is_continuous_and_state_is_reduced(backend, degree):
    pendulum = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])
    assert pendulum.periodic == (True,)
    integrator = gvi.Integrator(pendulum, gvi.Galerkin(degree), backend=backend)
    traj = integrator.integrate([0.0], v0=[3.0], h=0.05, n_steps=400)
    # above the separatrix (v0 > 2): the angle grows monotonically through many turns
    assert np.all(np.diff(traj.q[:, 0]) > 0)
    assert traj.q[-1, 0] > 6 * np.pi
    assert np.all(np.abs(traj.q_reduced) <= np.pi)
    turns = np.round((traj.q - traj.q_reduced) / (2 * np.pi))
    np.testing.assert_allclose(traj.q, traj.q_reduced + 2 * np.pi * turns, rtol=0, atol=1e-13)
    energy = traj.energy()
    assert np.ptp(energy) < (5e-3 if degree == 1 else 1e-5)  # O(h^2s) error, no drift


def test_backends_agree_on_a_rotating_pendulum_with_the_explicit_loop():
    pendulum = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])
    explicit = gvi.Integrator(pendulum, gvi.Galerkin(1), backend="numba")
    assert explicit.kernel_path == "explicit"
    reference = gvi.Integrator(pendulum, gvi.Galerkin(1), backend="numpy")
    a = explicit.integrate([3.0], v0=[3.0], h=0.05, n_steps=300)
    b = reference.integrate([3.0], v0=[3.0], h=0.05, n_steps=300)
    np.testing.assert_allclose(a.q, b.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(a.p, b.p, rtol=0, atol=1e-12)


def test_whole_turns_in_the_initial_angle_do_not_change_the_motion():
    # the loop reduces the state, so a start 1000 turns further on gives the same
    # reduced trajectory; unreduced, sin at angles of ~6e3 would lose ~1e-12 per step
    rotor = gvi.LagrangianSystem(w**2 / 2 + 0.3 * sp.cos(th), [th], [w])
    integrator = gvi.Integrator(rotor, gvi.Galerkin(2))
    near = integrator.integrate([0.5], v0=[2.0], h=0.05, n_steps=5_000)
    shift = 2 * np.pi * 1000
    far = integrator.integrate([0.5 + shift], v0=[2.0], h=0.05, n_steps=5_000)
    # the only difference is the rounding of the start, |d0| ~ ulp(6e3) = 1e-12, carried
    # along and amplified (phase error growing linearly) by at most ~40x over this run
    d0 = max(abs(far.q_reduced[0, 0] - near.q_reduced[0, 0]), 1e-16)
    assert d0 < 1e-12
    np.testing.assert_allclose(far.q_reduced, near.q_reduced, rtol=0, atol=100 * d0)
    np.testing.assert_allclose(far.p, near.p, rtol=0, atol=100 * d0)
    np.testing.assert_allclose(far.q - shift, near.q, rtol=0, atol=1e-9)
