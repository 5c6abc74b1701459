"""Time-adaptive steps by the Poincaré transformation (galerkin_vi.adaptive)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.adaptive import CLOCK, CLOCK_WEIGHT, ENERGY
from galerkin_vi.problems import gravitation

x, y, vx, vy = sp.symbols("x y vx vy")
R = sp.sqrt(x**2 + y**2)
GAUSS2 = gvi.Galerkin(2, gvi.gauss_legendre(2))


@pytest.fixture(scope="module")
def kepler():
    return gravitation.kepler(0.9)


@pytest.fixture(scope="module")
def adaptive(kepler):
    return gvi.AdaptiveIntegrator(kepler.system, GAUSS2, g=gvi.encounter_scaling([R], 1.5))


def angular_momentum(traj):
    return traj.q[:, 0] * traj.p[:, 1] - traj.q[:, 1] * traj.p[:, 0]


# ------------------------------------------------------------------ the extended Lagrangian
def test_extended_lagrangian_has_the_physical_momenta_and_vanishes_on_the_energy_level():
    """L~ = g [L(q, w/g) + E]: dL~/dw = L_v(q, w/g), and L~ + (c/2)(zeta - g)^2 with the
    clock's momentum c (zeta - g)."""
    g = gvi.encounter_scaling([R], 1.5)
    kepler = gravitation.kepler(0.5).system
    ext = gvi.PoincareTransform(kepler, g).extended
    assert ext.q == (x, y, CLOCK)
    assert ENERGY in ext.params and CLOCK_WEIGHT in ext.params
    w = sp.symbols("wx wy")
    L_ext = ext.L.subs({vx: w[0], vy: w[1]})
    for a, v in enumerate((vx, vy)):
        physical = sp.diff(kepler.L, v).subs({vx: w[0] / g, vy: w[1] / g})
        assert sp.simplify(sp.diff(L_ext, w[a]) - physical) == 0
    clock_rate = ext.v[2]
    assert sp.simplify(sp.diff(ext.L, clock_rate) - CLOCK_WEIGHT * (clock_rate - g)) == 0


def test_encounter_scaling():
    d1, d2 = sp.symbols("d1 d2", positive=True)
    assert gvi.encounter_scaling([d1], 1.5) == d1 ** sp.Rational(3, 2)
    g = sp.lambdify([d1, d2], gvi.encounter_scaling([d1, d2], 1.0))
    rng = np.random.default_rng(1)
    for a, b in rng.uniform(0.01, 10.0, size=(50, 2)):
        assert g(a, b) <= min(a, b) + 1e-15  # at most the smaller distance
        assert g(a, b) >= min(a, b) / 2 - 1e-15  # and at least half of it
    with pytest.raises(ValueError, match="alpha"):
        gvi.encounter_scaling([d1], 0.0)
    with pytest.raises(ValueError, match="at least one"):
        gvi.encounter_scaling([], 1.0)


# ------------------------------------------------------------------ runs
def test_lands_on_the_final_time_with_steps_following_g(kepler, adaptive):
    t_final = 2 * math.pi
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=0.05, t_final=t_final)
    assert traj.t[-1] == t_final
    assert np.all(np.diff(traj.t) > 0)
    np.testing.assert_array_equal(traj.step_sizes, np.diff(traj.t))
    # the physical step is the quadrature of g over the step: g(q_k) h to O(h)
    h = np.diff(traj.tau)[:-1]
    g = adaptive.transform.rate(traj.q[:-2])
    ratio = np.diff(traj.t)[:-1] / (g * h)
    assert np.abs(ratio - 1).max() < 0.1  # measured 0.041
    # the clock's Noether momentum stays 0: z' = g
    assert np.abs(traj.clock_momentum).max() <= 1e-14  # measured 0 (Gauss)
    # steps 200x shorter at pericentre (r = 0.1) than at apocentre (r = 1.9)
    steps = np.diff(traj.t)[:-1]
    assert steps.max() / steps.min() > 50  # (1.9 / 0.1)^1.5 = 83


def test_order_in_the_fictitious_step_and_conserved_angular_momentum(kepler, adaptive):
    t_final = 2 * math.pi
    exact = gravitation.kepler_position(t_final, 0.9)
    errors = []
    for h in (0.05, 0.025):
        traj = adaptive.integrate(kepler.q0, kepler.v0, h=h, t_final=t_final)
        errors.append(np.abs(traj.q[-1] - exact).max())
        momentum = angular_momentum(traj)
        # g = r^alpha is rotation invariant, so is L~: Noether to round-off
        assert np.abs(momentum - momentum[0]).max() <= 1e-13  # measured 1.1e-16
    order = math.log2(errors[0] / errors[1])
    assert order >= 2 * GAUSS2.degree - 0.3  # measured 4.0 (Gauss, 2 points: order 4)
    assert errors[1] < 1e-7  # measured 9.4e-9


def test_energy_bounded_without_drift_over_many_periods(kepler, adaptive):
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=0.1, t_final=2 * math.pi * 40)
    energy = traj.energy()
    error = np.abs(energy - energy[0])
    tenth = len(error) // 10
    assert error.max() < 1e-5  # measured 1.8e-6
    assert error[-tenth:].max() <= 2.0 * error[:tenth].max()  # measured 1.00


def test_fewer_steps_than_fixed_steps_at_the_same_error(kepler, adaptive):
    """At e = 0.9 the pericentre sets the fixed step: with 10x the steps, 300x the error."""
    t_final = 2 * math.pi * 4
    exact = gravitation.kepler_position(t_final, 0.9)
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=0.05, t_final=t_final)
    adaptive_error = np.abs(traj.q[-1] - exact).max()
    n_fixed = 10 * traj.n_steps
    fixed = gvi.Integrator(kepler.system, GAUSS2).integrate(
        kepler.q0, kepler.v0, h=t_final / n_fixed, n_steps=n_fixed, save_every=n_fixed
    )
    fixed_error = np.abs(fixed.q[-1] - exact).max()
    assert fixed_error > 100 * adaptive_error  # measured 1.9e-4 against 6.0e-7


def test_fixed_number_of_steps_and_saving(kepler, adaptive):
    traj = adaptive.integrate(kepler.q0, p0=kepler.v0, h=0.1, n_steps=50, save_every=7)
    assert traj.n_steps == 50
    np.testing.assert_allclose(np.diff(traj.tau), [0.7] * 7 + [0.1], rtol=1e-12, atol=0)
    assert traj.tau[-1] == pytest.approx(5.0)
    assert traj.t[0] == 0.0 and np.all(np.diff(traj.t) > 0)
    landed = adaptive.integrate(kepler.q0, kepler.v0, h=0.1, t_final=3.0, save_every=7)
    assert landed.t[-1] == 3.0
    assert len(landed) == math.ceil(landed.n_steps / 7) + 1


# ------------------------------------------------------------------ bad input
def test_bad_input_is_named(kepler, adaptive):
    t = sp.Symbol("t")
    timed = gvi.LagrangianSystem(vx**2 / 2 - sp.cos(t) * x**2, [x], [vx], t=t)
    with pytest.raises(ValueError, match="autonomous"):
        gvi.AdaptiveIntegrator(timed, g=x**2 + 1)
    with pytest.raises(ValueError, match="depend on q"):
        gvi.AdaptiveIntegrator(kepler.system, g=R * vx)
    with pytest.raises(TypeError, match="g must be"):
        gvi.AdaptiveIntegrator(kepler.system, g="r")
    damped = gvi.LagrangianSystem(vx**2 / 2 - x**2 / 2, [x], [vx], forces=[-vx / 10])
    with pytest.raises(ValueError, match="constraints or forces"):
        gvi.AdaptiveIntegrator(damped, g=x**2 + 1)
    clock = sp.Symbol("t_clock")
    clashing = gvi.LagrangianSystem(vx**2 / 2 - clock**2 / 2, [clock], [vx])
    with pytest.raises(ValueError, match="reserved symbols"):
        gvi.AdaptiveIntegrator(clashing, g=clock**2 + 1)
    with pytest.raises(ValueError, match="q0 must have shape"):
        adaptive.integrate([1.0], kepler.v0, h=0.1, n_steps=3)
    with pytest.raises(ValueError, match="exactly one of n_steps and t_final"):
        adaptive.integrate(kepler.q0, kepler.v0, h=0.1)
    with pytest.raises(ValueError, match="h must be"):
        adaptive.integrate(kepler.q0, kepler.v0, h=0.0, n_steps=3)
    with pytest.raises(ValueError, match="t_final must be after"):
        adaptive.integrate(kepler.q0, kepler.v0, h=0.1, t_final=-1.0)
    with pytest.raises(ValueError, match="g\\(q0\\) must be positive"):
        gvi.AdaptiveIntegrator(kepler.system, g=x).integrate(
            [-1.0, 0.0], [0.0, 1.0], h=0.1, n_steps=2
        )


def test_a_failed_run_keeps_its_states_in_physical_time(kepler, adaptive):
    """h = 1.5 is far too long at pericentre: an early step fails, the ones before are kept."""
    for run in ({"n_steps": 400}, {"t_final": 300.0}):
        with pytest.raises(gvi.ConvergenceError, match="physical time") as failure:
            adaptive.integrate(kepler.q0, kepler.v0, h=1.5, on_failure="raise", **run)
        error = failure.value
        assert 1 <= error.step <= 3  # measured 2
        partial = error.partial
        assert isinstance(partial, gvi.AdaptiveTrajectory) and partial.system is kepler.system
        assert partial.q.shape == (error.step + 1, 2) and partial.tau[-1] == 1.5 * error.step
        assert error.t == partial.t[-1] > 0.0  # physical time of the last good state
        np.testing.assert_array_equal(partial.q[0], kepler.q0)
        # the partial run says it failed, and where, in physical time
        assert not partial.success and partial.status < 0
        assert "physical time" in partial.message and ".partial" not in partial.message


def test_landing_on_t_final_computes_few_steps_past_it(kepler, adaptive):
    """The chunks before t_final follow the run's mean dt/dtau: the work done (iterations of
    every step computed, dropped ones and the landing included) stays close to the work of
    the steps kept. Sized from the last chunk's dt/dtau, which can end at pericentre (g
    small), the dropped steps were 14x the kept ones on Kepler e = 0.9."""
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=0.00625, t_final=40 * math.pi)
    kept = int(np.sum(traj.newton_iterations))
    assert traj.n_steps > 1000  # several chunks
    assert kept <= traj.total_newton_iterations <= 1.5 * kept
