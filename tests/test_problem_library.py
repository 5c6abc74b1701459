"""The problem library's newer models: their formulas, data, references and invariants.

Every model is integrated by ``Galerkin(2, gauss_legendre(2))`` (order 4) at step sizes h
and h/2 over a short span, and compared with ``problem.reference``. Only Hénon–Heiles runs
compiled: compiling all six systems took 100 s with a cold kernel cache on two cores (the
outer solar system 25 s, the others 5 to 23 s each), and the backends' agreement is tested
elsewhere; the NumPy reference backend checks the models in a few seconds.
"""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.problems.gravitation import OUTER_SOLAR_SYSTEM_BODIES
from galerkin_vi.problems.mechanics import HENON_HEILES_ENERGY

METHOD = gvi.Galerkin(2, gvi.gauss_legendre(2))
MOMENTUM_DRIFT = 1e-11

# name: (factory, h, steps at h, max relative position error at h/2, max relative energy
# error at h/2). Measured at h/2 (errors relative to max|q|, energy to |H_0|):
#   henon_heiles        1.2e-8  4.7e-9      spherical_pendulum  2.9e-8  3.3e-8
#   fermi_pasta_ulam    1.6e-7  2.8e-10     spring_chain        5.6e-9  5.0e-16
#   spring_chain_beta   3.3e-8  5.9e-9      outer_solar_system  1.0e-9  7.5e-10
# and err(h) / err(h/2) = 15.7 .. 16.0 throughout (order 4: 16).
CASES = {
    "henon_heiles": (problems.henon_heiles, 0.1, 20, 3e-8, 1e-8),
    "spherical_pendulum": (problems.spherical_pendulum, 0.1, 20, 6e-8, 8e-8),
    "fermi_pasta_ulam": (problems.fermi_pasta_ulam, 0.004, 250, 4e-7, 1e-9),
    # linear, so the reference is the exact normal-mode solution; the energy is a quadratic
    # invariant, kept by Gauss quadrature to round-off
    "spring_chain": (lambda: problems.spring_chain(10), 0.2, 10, 1.5e-8, 1e-13),
    "spring_chain_beta": (lambda: problems.spring_chain(10, beta=1.0), 0.2, 10, 8e-8, 1.5e-8),
    "outer_solar_system": (problems.outer_solar_system, 40.0, 25, 3e-9, 2e-9),
}


@cache
def _problem(name: str) -> problems.Problem:
    return CASES[name][0]()


@cache
def _runs(name: str) -> tuple[gvi.Trajectory, gvi.Trajectory]:
    """Trajectories at h and h/2 over the same span."""
    problem = _problem(name)
    _, h, steps, _, _ = CASES[name]
    backend = "numba" if name == "henon_heiles" else "numpy"
    integrator = gvi.Integrator(problem.system, METHOD, backend=backend)
    return tuple(
        integrator.integrate(
            problem.q0, problem.v0, h=h / k, n_steps=steps * k, params=problem.params
        )
        for k in (1, 2)
    )


def _relative_error(problem: problems.Problem, traj: gvi.Trajectory) -> float:
    return float(np.max(np.abs(traj.q - problem.reference(traj.t))) / np.max(np.abs(traj.q)))


@pytest.mark.parametrize("name", CASES)
def test_galerkin_converges_to_reference_with_order_four(name):
    problem = _problem(name)
    coarse, fine = _runs(name)
    err_coarse, err_fine = _relative_error(problem, coarse), _relative_error(problem, fine)
    assert err_fine <= CASES[name][3], (err_coarse, err_fine)
    assert err_coarse / err_fine >= 12.0, (err_coarse, err_fine)


@pytest.mark.parametrize("name", CASES)
def test_energy_and_momentum_maps_conserved(name):
    problem = _problem(name)
    _, fine = _runs(name)
    energy = fine.energy()
    assert np.max(np.abs(energy - energy[0])) <= CASES[name][4] * abs(energy[0])
    for key, xi in problem.symmetries.items():
        J = fine.momentum(xi)
        assert abs(J[0]) > 0, key
        assert np.max(np.abs(J - J[0])) <= MOMENTUM_DRIFT * abs(J[0]), key


# ------------------------------------------------------- formulas against the sources
def _random_states(n: int, scale: float = 0.5, seed: int = 1) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return scale * rng.standard_normal((5, n)), scale * rng.standard_normal((5, n))


def test_henon_heiles_hamiltonian_and_default_energy():
    problem = problems.henon_heiles()
    q, p = _random_states(2)
    x, y = q.T
    expected = (p**2).sum(axis=1) / 2 + (x**2 + y**2) / 2 + x**2 * y - y**3 / 3
    np.testing.assert_allclose(problem.system.hamiltonian(q, p), expected, rtol=1e-14)
    assert HENON_HEILES_ENERGY == 1 / 8
    assert problem.system.hamiltonian(problem.q0, problem.v0) == pytest.approx(1 / 8, abs=1e-16)
    assert problem.v0[1] == 0.0 and problem.v0[0] > 0.0
    assert problem.exact is None
    with pytest.raises(ValueError, match="energy surface"):
        problems.henon_heiles(q0=(0.0, 1.0))


def test_spherical_pendulum_hangs_down_and_circles_conically():
    problem = problems.spherical_pendulum(g=2.0, length=0.5)
    q, p = _random_states(2, seed=2)
    q[:, 0] = np.abs(q[:, 0]) + 0.3  # away from the pole theta = 0
    theta = q[:, 0]
    g, length = 2.0, 0.5
    expected = (
        p[:, 0] ** 2 / (2 * length**2)
        + p[:, 1] ** 2 / (2 * length**2 * np.sin(theta) ** 2)
        - g * length * np.cos(theta)
    )
    np.testing.assert_allclose(
        problem.system.hamiltonian(q, p, params=problem.params), expected, rtol=1e-13
    )
    # theta = 0 hangs down: conical motion at theta0 needs phi' = sqrt(g / (l cos theta0))
    theta0 = 0.8
    rate = np.sqrt(g / (length * np.cos(theta0)))
    conical = problems.spherical_pendulum(g, length, q0=(theta0, 0.0), v0=(0.0, rate))
    t = np.linspace(0.0, 3.0, 7)
    np.testing.assert_allclose(conical.reference(t), np.stack([0 * t + theta0, rate * t], 1))
    traj = gvi.Integrator(conical.system, METHOD, backend="numpy").integrate(
        conical.q0, conical.v0, h=0.05, n_steps=60, params=conical.params
    )
    # a relative equilibrium the method keeps to round-off: measured 3e-16 (theta), 2e-15 (phi)
    np.testing.assert_allclose(traj.q[:, 0], theta0, rtol=0, atol=1e-12)
    np.testing.assert_allclose(traj.q[:, 1], rate * traj.t, rtol=0, atol=1e-12)
    assert problem.symmetries == {"rotation_z": (0, 1)}


def test_fermi_pasta_ulam_matches_hairer_lubich_wanner():
    m, omega = 3, 50.0
    problem = problems.fermi_pasta_ulam()
    assert dict(problem.params) == {sp.Symbol("omega", positive=True): omega}
    assert problem.system.n == 2 * m and problem.t_final == 200.0
    q, p = _random_states(2 * m, seed=3)
    padded = np.pad(q, ((0, 0), (1, 1)))
    expected = (
        (p**2).sum(axis=1) / 2
        + omega**2 / 4 * ((q[:, 1::2] - q[:, 0::2]) ** 2).sum(axis=1)
        + ((padded[:, 1::2] - padded[:, 0::2]) ** 4).sum(axis=1)
    )
    np.testing.assert_allclose(
        problem.system.hamiltonian(q, p, params=problem.params), expected, rtol=1e-13
    )
    # HLW I.5.1 initial data in x_{0,i} = (q_2i + q_2i-1)/sqrt2, x_{1,i} = (q_2i - q_2i-1)/sqrt2
    x0 = (problem.q0[1::2] + problem.q0[0::2]) / np.sqrt(2)
    x1 = (problem.q0[1::2] - problem.q0[0::2]) / np.sqrt(2)
    y0 = (problem.v0[1::2] + problem.v0[0::2]) / np.sqrt(2)
    y1 = (problem.v0[1::2] - problem.v0[0::2]) / np.sqrt(2)
    np.testing.assert_allclose(x0, [1, 0, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(y0, [1, 0, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(x1, [1 / omega, 0, 0], rtol=0, atol=1e-15)
    np.testing.assert_allclose(y1, [1, 0, 0], rtol=0, atol=1e-15)
    oscillatory_energy = (y1**2 + omega**2 * x1**2) / 2
    np.testing.assert_allclose(oscillatory_energy, [1, 0, 0], rtol=0, atol=1e-14)
    other = problems.fermi_pasta_ulam(m=2, omega=100.0)
    assert other.system.n == 4 and other.q0[1] - other.q0[0] == pytest.approx(np.sqrt(2) / 100)


def test_outer_solar_system_data_and_hamiltonian():
    problem = problems.outer_solar_system()
    source = resources.files("galerkin_vi.problems").joinpath("data", "outer_solar_system.json")
    data = json.loads(source.read_text(encoding="utf-8"))
    assert tuple(data["names"]) == OUTER_SOLAR_SYSTEM_BODIES
    masses = np.array(data["masses"])
    values = np.array([problem.params[s] for s in problem.system.params])
    np.testing.assert_array_equal(values, [*masses, data["G"]])
    np.testing.assert_array_equal(problem.q0, np.ravel(data["positions"]))
    np.testing.assert_array_equal(problem.v0, np.ravel(data["velocities"]))
    # spot values of HLW Table I.2.1
    assert data["G"] == 2.95912208286e-4
    assert masses[1] == 0.000954786104043
    np.testing.assert_array_equal(problem.q0[3:6], [-3.5023653, -3.8169847, -1.5507963])
    assert problem.t_final == 200_000.0
    assert set(problem.symmetries) == {
        f"{kind}_{axis}" for kind in ("translation", "rotation") for axis in "xyz"
    }
    q = problem.q0.reshape(6, 3)
    p = masses[:, None] * problem.v0.reshape(6, 3)
    pairs = [(i, j) for i in range(6) for j in range(i + 1, 6)]
    potential = -data["G"] * sum(
        masses[i] * masses[j] / np.linalg.norm(q[i] - q[j]) for i, j in pairs
    )
    expected = (p**2 / masses[:, None]).sum() / 2 + potential
    H = problem.system.hamiltonian(problem.q0, p.ravel())
    assert H == pytest.approx(expected, rel=1e-13)
    J = problem.system.momentum_map(problem.symmetries["rotation_z"])(problem.q0, p.ravel())
    assert J == pytest.approx((q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0]).sum(), rel=1e-13)


# ------------------------------------------------------------------- spring chain
def test_spring_chain_exact_solution_solves_the_equations_of_motion():
    n = 12
    rng = np.random.default_rng(4)
    problem = problems.spring_chain(
        n, stiffness=3.0, mass=2.0, q0=rng.standard_normal(n), v0=rng.standard_normal(n)
    )
    assert problem.exact is not None
    np.testing.assert_allclose(problem.exact(0.0), problem.q0, rtol=0, atol=1e-14)
    dt = 1e-5
    velocity = (problem.exact(dt) - problem.exact(-dt)) / (2 * dt)
    np.testing.assert_allclose(velocity, problem.v0, rtol=0, atol=1e-8)
    t = np.array([0.7, 3.1, 10.0])
    reference = problems.ode_reference(problem.system, problem.q0, problem.v0, t, problem.params)
    # measured: 8.5e-14 (finite-difference velocity: 1.9e-10)
    np.testing.assert_allclose(problem.exact(t), reference, rtol=0, atol=1e-10)
    assert problem.exact(t).shape == (3, n)


def test_spring_chain_structure():
    linear = problems.spring_chain(10)
    structure = linear.system.structure
    assert structure.quadratic and structure.constant_mass and structure.separable
    assert gvi.Integrator(linear.system, METHOD, backend="numba").kernel_path == "linear"
    assert [str(s) for s in linear.system.params] == ["m", "k"]
    nonlinear = problems.spring_chain(10, beta=0.5)
    assert nonlinear.exact is None
    assert not nonlinear.system.structure.quadratic
    assert nonlinear.system.structure.constant_mass
    assert [str(s) for s in nonlinear.system.params] == ["m", "k", "beta"]
    assert nonlinear.params[nonlinear.system.params[2]] == 0.5
    # one system per (n_masses, beta != 0); parameter values travel with the problem
    assert problems.spring_chain(10, stiffness=2.0).system is linear.system
    q, p = _random_states(10, seed=5)
    d = np.diff(np.pad(q, ((0, 0), (1, 1))), axis=1)
    expected = (p**2).sum(axis=1) / 2 + (d**2).sum(axis=1) / 2 + 0.5 * (d**4).sum(axis=1) / 4
    np.testing.assert_allclose(
        nonlinear.system.hamiltonian(q, p, params=nonlinear.params), expected, rtol=1e-13
    )
