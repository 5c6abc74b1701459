"""Rigid bodies against closed forms: Euler–Poinsot, the tennis racket, the Lagrange top,
a body on a ball joint, and a tumbling die.

The closed forms are :mod:`galerkin_vi.problems.rigid_bodies` (themselves tested
against DOP853 in tests/test_rigid_body_solutions.py).
"""

from __future__ import annotations

import numpy as np
import pytest

import galerkin_vi as gvi
from galerkin_vi.problems import rigid_bodies as closed

J_FREE = np.array([2.0, 3.0, 4.5])
OMEGA_FREE = np.array([0.4, 0.2, 1.0])


def rot_x(angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def free_body(rotation: str, inertia=J_FREE):
    body = gvi.RigidBody("b", mass=1.0, inertia=list(inertia), rotation=rotation)
    return gvi.Multibody([body])


def free_run(mb, omega0, s: int, h: float, n_steps: int, save_every: int = 1):
    q0, v0 = mb.state(rotations={"b": rot_x(0.3)}, angular_velocities={"b": omega0})
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(s))
    traj = integrator.integrate(q0, v0=v0, h=h, n_steps=n_steps, save_every=save_every)
    assert traj.success
    return traj, mb.motion(traj, "b")


@pytest.mark.parametrize("rotation", ["quaternion", "matrix"])
def test_free_body_angular_velocity_converges_to_the_elliptic_solution_at_order_2s(rotation):
    mb = free_body(rotation)
    errors = []
    for h in (0.2, 0.1):
        n = int(round(10.0 / h))
        _, motion = free_run(mb, OMEGA_FREE, 2, h, n)
        exact = closed.free_body_angular_velocity(J_FREE, OMEGA_FREE, motion.t)
        errors.append(np.abs(motion.angular_velocity - exact).max())
    order = np.log2(errors[0] / errors[1])
    assert abs(order - 4) < 0.5, (errors, order)
    _, motion = free_run(mb, OMEGA_FREE, 3, 0.1, 100)
    exact = closed.free_body_angular_velocity(J_FREE, OMEGA_FREE, motion.t)
    assert np.abs(motion.angular_velocity - exact).max() < 1e-8


def test_free_body_attitude_matches_the_exact_rotation():
    mb = free_body("quaternion")
    _, motion = free_run(mb, OMEGA_FREE, 3, 0.05, 200)
    exact = closed.free_body_rotation(J_FREE, OMEGA_FREE, rot_x(0.3), motion.t)
    assert np.abs(motion.rotation - exact).max() < 1e-9


@pytest.mark.parametrize("rotation", ["quaternion", "matrix"])
def test_free_body_invariants_over_1e5_steps(rotation):
    mb = free_body(rotation)
    traj, motion = free_run(mb, OMEGA_FREE, 2, 0.05, 100_000, save_every=100)
    E = traj.energy()
    assert np.abs(E - E[0]).max() / abs(E[0]) < 1e-8  # bounded at the method's error
    M = motion.angular_velocity * J_FREE
    norm = np.linalg.norm(M, axis=1)
    # |M| = |L| and Noether's L: to round-off, whose sum over 1e5 steps is about 1e5 eps
    rounding = 1e5 * np.finfo(float).eps
    assert np.abs(norm - norm[0]).max() / norm[0] < rounding
    for axis in np.eye(3):
        L = traj.momentum(mb.angular_momentum(axis).xi)
        assert np.abs(L - L[0]).max() < rounding * norm[0]


def test_tennis_racket_flip_time_matches_the_elliptic_formula():
    inertia = np.array([1.0, 2.0, 3.0])
    omega0 = np.array([0.01, 2.0, 0.01])
    mb = free_body("quaternion", inertia)
    flip = closed.tennis_racket_flip_time(inertia, omega0)
    traj, motion = free_run(mb, omega0, 3, 0.01, int(2.6 * flip / 0.01))
    w2 = motion.angular_velocity[:, 1]
    crossing = np.nonzero(np.sign(w2[1:]) != np.sign(w2[:-1]))[0]
    times = motion.t[crossing] - w2[crossing] * 0.01 / (w2[crossing + 1] - w2[crossing])
    assert len(times) >= 2
    assert np.diff(times) == pytest.approx(flip, rel=1e-6)


def test_lagrange_top_noether_momenta_and_nutation_match_the_closed_form():
    m, arm, g, I1cm, I3 = 1.0, 0.5, 9.81, 0.3, 0.2
    theta0, phi_dot0, psi_dot0 = 0.6, 1.0, 20.0
    top = gvi.RigidBody("top", mass=m, inertia=[I1cm, I1cm, I3])
    mb = gvi.Multibody(
        [top], joints=[gvi.joints.Spherical(None, top, point_b=[0, 0, -arm])], gravity=[0, 0, -g]
    )
    R0 = rot_x(theta0)
    # z-x-z Euler rates at phi = psi = 0: omega_s = phi' e_z + theta' e_x + psi' R e_z
    omega_s = phi_dot0 * np.array([0, 0, 1.0]) + psi_dot0 * R0[:, 2]
    q0, v0 = mb.state(rotations={"top": R0}, angular_velocities={"top": omega_s}, frame="space")
    h, n = 0.002, 3000
    traj = gvi.Integrator(mb.system, gvi.Galerkin(3)).integrate(q0, v0=v0, h=h, n_steps=n)
    assert traj.success
    for xi in (mb.angular_momentum([0, 0, 1]).xi, mb.angular_momentum([0, 0, 1], "top", "body").xi):
        J = traj.momentum(xi)
        assert np.abs(J - J[0]).max() < 1e-12 * max(1.0, abs(J[0]))
    nutation = closed.lagrange_top_nutation(I1cm + m * arm**2, I3, m, g, arm, theta0, 0.0,
                                            phi_dot0, psi_dot0)  # fmt: skip
    theta = np.arccos(np.clip(mb.motion(traj, "top").rotation[:, 2, 2], -1, 1))
    assert theta.min() == pytest.approx(nutation.theta_min, abs=1e-6)
    assert theta.max() == pytest.approx(nutation.theta_max, abs=1e-6)
    exact = closed.lagrange_top_theta(I1cm + m * arm**2, I3, m, g, arm, theta0, 0.0, phi_dot0,
                                      psi_dot0, traj.t)  # fmt: skip
    assert np.abs(theta - exact).max() < 1e-7


def test_a_body_on_a_ball_joint_oscillates_at_the_closed_form_frequencies():
    m, arm, g = 2.0, 0.4, 9.81
    inertia = [0.05, 0.08, 0.03]
    body = gvi.RigidBody("b", mass=m, inertia=inertia)
    mb = gvi.Multibody(
        [body], joints=[gvi.joints.Spherical(None, body, point_b=[0, 0, arm])], gravity=[0, 0, -g]
    )
    expected = closed.ball_joint_frequencies(m, inertia, [0, 0, -arm], g)
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(3))
    measured = []
    for axis in np.eye(3)[:2]:
        eps = 1e-4  # small: the amplitude's correction to the frequency is O(eps^2)
        c, s = np.cos(eps), np.sin(eps)
        R0 = rot_x(eps) if axis[0] else np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])
        q0, v0 = mb.state(rotations={"b": R0})
        traj = integrator.integrate(q0, v0=v0, h=0.005, n_steps=2000)
        assert traj.success
        tilt = mb.motion(traj, "b").rotation[:, 2, 1 if axis[0] else 0]
        k = np.nonzero(np.sign(tilt[1:]) != np.sign(tilt[:-1]))[0]
        times = traj.t[k] - tilt[k] * 0.005 / (tilt[k + 1] - tilt[k])
        measured.append(np.pi / np.mean(np.diff(times)))
    assert np.sort(measured) == pytest.approx(np.sort(expected[1:]), rel=1e-6)


@pytest.mark.parametrize("inertia", [[1 / 6] * 3, [0.25, 0.4, 0.55]], ids=["cube", "box"])
def test_a_free_tumbling_die_keeps_its_energy_to_1e_11_over_5_s(inertia):
    die = gvi.RigidBody("die", mass=1.0, inertia=inertia)
    mb = gvi.Multibody([die])
    q0, v0 = mb.state(rotations={"die": rot_x(0.4)}, velocities={"die": [0.3, 0, 1.0]},
                      angular_velocities={"die": [3.0, -2.0, 5.0]})  # fmt: skip
    traj = gvi.Integrator(mb.system, gvi.Galerkin(3)).integrate(q0, v0=v0, h=0.01, n_steps=500)
    E = traj.energy()
    assert np.abs(E - E[0]).max() / E[0] <= 1e-11


@pytest.mark.slow
def test_a_free_tumbling_die_stays_bounded_over_a_million_steps():
    die = gvi.RigidBody("die", mass=1.0, inertia=[0.25, 0.4, 0.55])
    mb = gvi.Multibody([die])
    q0, v0 = mb.state(rotations={"die": rot_x(0.4)}, angular_velocities={"die": [3.0, -2.0, 5.0]})
    traj = gvi.Integrator(mb.system, gvi.Galerkin(3)).integrate(
        q0, v0=v0, h=0.01, n_steps=1_000_000, save_every=1000
    )
    E = traj.energy()
    drift = np.abs(E - E[0]) / E[0]
    assert drift.max() <= 1e-11
    # bounded: the last tenth is no worse than the first
    tenth = len(drift) // 10
    assert drift[-tenth:].max() <= 2 * drift[:tenth].max() + 1e-14
