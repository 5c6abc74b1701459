"""Periodic orbits through the discrete action: pendulum closed forms, the figure eight."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp
from scipy.special import ellipk

import galerkin_vi as gvi
from galerkin_vi.action import ActionStatus
from galerkin_vi.problems import n_body

th, w = sp.symbols("theta w")
PENDULUM = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])


def _libration_period(theta0: float) -> float:
    return 4 * ellipk(np.sin(theta0 / 2) ** 2)


@pytest.mark.parametrize("degree", [2, 3])
def test_the_period_at_a_given_energy_converges_at_the_methods_order(degree):
    theta0 = 1.0
    energy, period = -np.cos(theta0), _libration_period(theta0)  # 4 K(sin^2(theta0/2))
    errors = []
    for N in (20, 40):
        orbit = gvi.solve_periodic(PENDULUM, gvi.Galerkin(degree), [0.9], [0.0], 6.0, N,
                                   energy=energy)  # fmt: skip
        assert orbit.success and orbit.residual < 1e-13
        traj = orbit.trajectory
        np.testing.assert_array_equal(traj.q[-1], traj.q[0])  # closed
        # E* at node 0, where it is imposed; along the orbit it oscillates at O(h^2s)
        assert traj.energy()[0] == pytest.approx(energy, abs=1e-13)
        assert np.ptp(traj.energy()) < 1e-2 * (10 / N) ** (2 * degree)  # measured 2e-5, 2e-8
        errors.append(abs(orbit.period - period))
    assert abs(np.log2(errors[0] / errors[1]) - 2 * degree) < 0.5


def test_the_orbit_of_a_given_period_has_the_closed_form_amplitude():
    theta0 = 1.0
    errors = []
    for N in (20, 40):
        orbit = gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0],
                                   _libration_period(theta0), N)  # fmt: skip
        assert orbit.success and orbit.period == _libration_period(theta0)
        errors.append(abs(orbit.trajectory.energy()[0] + np.cos(theta0)))
        # the energy of the discrete orbit is constant along it to the method's order
        assert np.ptp(orbit.trajectory.energy()) < 2e-5
    assert np.log2(errors[0] / errors[1]) > 3.8


def test_the_border_multiplier_of_the_time_shift_vanishes_with_h():
    # the time shift is a symmetry of the discrete action only as h -> 0: the border's
    # multiplier measures the defect, which falls fast
    energy = -np.cos(1.0)
    coarse, fine = (gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, N,
                                       energy=energy) for N in (10, 20))  # fmt: skip
    assert abs(coarse.multipliers[0]) > 1e-9 and abs(fine.multipliers[0]) < 1e-14


def _three_bodies():
    """Three unit masses, G = 1, no softening: the library's planar N-body problem."""
    problem = n_body(masses=(1.0, 1.0, 1.0), softening=0.0)
    names = ("translation_x", "translation_y", "rotation")
    return problem.system, [problem.symmetries[name] for name in names]


def test_the_figure_eight_from_its_eight_digit_guess():
    system, symmetries = _three_bodies()
    period, energy = 6.32591398292621, -1.287141995631852
    x1 = np.array([0.97000436, -0.24308753])
    v3 = np.array([-0.93240737, -0.86473146])
    q0 = np.concatenate([x1, -x1, [0.0, 0.0]])
    v0 = np.concatenate([-v3 / 2, -v3 / 2, v3])
    N = 60
    orbit = gvi.solve_periodic(system, gvi.Galerkin(6), q0, v0, period, N, symmetries=symmetries)
    assert orbit.success and orbit.iterations <= 6 and orbit.residual < 1e-12
    traj = orbit.trajectory
    np.testing.assert_allclose(traj.energy(), energy, rtol=0, atol=1e-12)
    assert np.abs(traj.momentum(symmetries[2])).max() < 1e-13  # zero angular momentum
    # a choreography: q3(t) = q1(t + T/3), q2(t) = q1(t + 2T/3)
    nodes = traj.q[:-1]
    np.testing.assert_allclose(nodes[:, 4:6], np.roll(nodes[:, 0:2], -N // 3, axis=0), atol=1e-12)
    np.testing.assert_allclose(nodes[:, 2:4], np.roll(nodes[:, 0:2], -2 * N // 3, axis=0),
                               atol=1e-12)  # fmt: skip
    # the action over one period, 24.42704864453, is -3 E T by the virial theorem
    assert orbit.action == pytest.approx(24.42704864453, abs=1e-10)
    assert orbit.action == pytest.approx(-3 * energy * period, abs=1e-11)
    assert np.abs(orbit.multipliers).max() < 1e-14


def test_following_the_pendulums_family_along_the_energy():
    start = gvi.solve_periodic(PENDULUM, gvi.Galerkin(3), [0.5], [0.0], 6.5, 40,
                               energy=-np.cos(0.5))  # fmt: skip
    amplitudes = np.linspace(0.6, 1.6, 6)
    family = gvi.follow_family(PENDULUM, gvi.Galerkin(3), start, -np.cos(amplitudes))
    assert len(family) == 6 and all(orbit.success for orbit in family)
    periods = np.array([orbit.period for orbit in family])
    np.testing.assert_allclose(periods, [_libration_period(a) for a in amplitudes], rtol=1e-7)
    assert np.all(np.diff(periods) > 0)  # the period grows with the amplitude


def test_an_unconverged_solve_says_why_and_bad_input_is_named():
    orbit = gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20,
                               energy=-np.cos(1.0), maxiter=1)  # fmt: skip
    assert orbit.status == ActionStatus.MAX_ITERATIONS and not orbit.success
    assert not orbit.trajectory.success and np.isfinite(orbit.period)
    with pytest.raises(ValueError, match="period must be a positive number"):
        gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], -1.0, 20)
    with pytest.raises(ValueError, match="n_steps must be an int >= 2"):
        gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, 1)
    with pytest.raises(ValueError, match=r"symmetries\[0\] must have 1 components"):
        gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20, symmetries=[[1, 0]])
    t = sp.Symbol("t")
    driven = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th) * sp.cos(t), [th], [w], t=t)
    with pytest.raises(ValueError, match="energy: an orbit of given energy needs an autonomous"):
        gvi.solve_periodic(driven, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20, energy=0.0)
    x, y, vx, vy = sp.symbols("x y vx vy")
    circle = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2, [x, y], [vx, vy], constraints=[x**2 + y**2 - 1]
    )
    with pytest.raises(ValueError, match="constraints or contacts are not supported"):
        gvi.solve_periodic(circle, gvi.Galerkin(2), [1.0, 0.0], [0.0, 1.0], 6.0, 20)
