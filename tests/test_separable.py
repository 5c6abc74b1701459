"""The stage form for separable Lagrangians (``kernel_path == "separable"``).

Its tables must be those of the classical methods it reduces to (Gauss
collocation, Lobatto IIIA–IIIB), and its compiled loop must give the general
Newton loop's map to round-off on every kind of separable system: time-dependent
potentials, a gauge term a(t)·v, forces f(t, q), non-diagonal and banded mass
matrices, any quadrature.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen, problems
from galerkin_vi import integrator as integrator_module
from galerkin_vi.method.stage_form import TWO_STEP_POINTS, has_stage_form, separable_tables

from .butcher_tables import gauss_tables, lobatto_tables

x, y, vx, vy, t = sp.symbols("x y vx vy t")

METHODS = [
    gvi.Galerkin(1, gvi.gauss_legendre(1)),
    gvi.Galerkin(2, gvi.gauss_legendre(2)),
    gvi.Galerkin(3, gvi.gauss_legendre(3)),
    gvi.Galerkin(2),
    gvi.Galerkin(3),
    gvi.Galerkin(4),
    gvi.Galerkin(3, gvi.gauss_legendre(4)),
    gvi.Galerkin(3, gvi.gauss_lobatto(5), nodes="equidistant"),
]


# ---------------------------------------------------------------------- tables
@pytest.mark.parametrize("s", [1, 2, 3, 5])
def test_gauss_tables_are_collocation(s):
    # Z_i = h c_i v_k + h^2 sum_j (A^2)_ij F_j / m and q_{k+1} - q_k = h v_k + h^2 sum_j (bA)_j F_j
    tables = separable_tables(gvi.Galerkin(s, gvi.gauss_legendre(s)))
    butcher = gauss_tables(s)
    assert tables.implicit.tolist() == list(range(s))
    assert tables.known.size == tables.rest.size == 0
    np.testing.assert_allclose(tables.stage_p, butcher.c, rtol=0, atol=1e-15)
    np.testing.assert_allclose(tables.stage_force, butcher.A2, rtol=0, atol=1e-15)
    np.testing.assert_allclose(tables.control_force[-1], butcher.bA, rtol=0, atol=1e-15)
    assert tables.control_p[-1] == pytest.approx(1.0, abs=1e-15)
    assert not tables.reuse_endpoint


@pytest.mark.parametrize("s", [1, 2, 3, 5])
def test_collocated_lobatto_tables_are_iiia_iiib(s):
    # Newton on the s - 1 interior nodes only; the first is q_k, the last explicit
    tables = separable_tables(gvi.Galerkin(s))
    pair = lobatto_tables(s + 1)
    assert tables.implicit.tolist() == list(range(1, s))
    assert tables.known.tolist() == [0]
    assert tables.rest.tolist() == [s]
    assert tables.reuse_endpoint
    np.testing.assert_allclose(tables.stage_p, pair.c[1:s], rtol=0, atol=1e-15)
    np.testing.assert_allclose(tables.stage_force, pair.AB[1:s], rtol=0, atol=1e-15)


@pytest.mark.parametrize("method", METHODS, ids=str)
def test_force_extrapolation_is_exact_for_polynomials_of_degree_r_minus_1(method):
    # F~_i = sum_j l_j(1 + c_i) F_j: forces that are polynomials in time of degree < r
    # (r quadrature points) are continued into the next step exactly
    tables = separable_tables(method)
    c = method.tables.c
    X = tables.force_extrapolation[:, : c.size]
    two_steps = c.size <= TWO_STEP_POINTS
    assert tables.force_extrapolation.shape == (
        tables.implicit.size,
        (3 if two_steps else 1) * c.size,
    )
    ahead = 1.0 + c[tables.implicit]
    for degree in range(c.size):
        np.testing.assert_allclose(X @ c**degree, ahead**degree, rtol=1e-12, atol=1e-12)


@pytest.mark.parametrize(
    "method", [m for m in METHODS if m.tables.c.size <= TWO_STEP_POINTS], ids=str
)
def test_two_step_force_extrapolation_is_exact_to_one_below_its_number_of_nodes(method):
    # from the nodes c - 1 and c of the last two steps (a node they share, Lobatto's end,
    # once): exact for polynomials of degree below the number of distinct nodes, 2r or
    # 2r - 1, and zero weight on the older copy of a shared node
    tables = separable_tables(method)
    c = method.tables.c
    r = c.size
    Y = tables.force_extrapolation[:, r:]
    nodes = np.concatenate([c - 1, c])
    shared = np.isclose(c - 1, c[:, None], atol=1e-14).any(axis=0)
    assert np.all(Y[:, :r][:, shared] == 0.0)
    distinct = 2 * r - int(shared.sum())
    ahead = 1.0 + c[tables.implicit]
    for degree in range(distinct):
        # the weights grow with the degree: relative to the sum of their sizes
        size = np.abs(Y) @ np.abs(nodes) ** degree
        np.testing.assert_array_less(
            np.abs(Y @ nodes**degree - ahead**degree), 1e-13 * size + 1e-13
        )
    # one degree more is not exact: the basis has no more nodes
    top = np.abs(Y @ nodes**distinct - ahead**distinct)
    assert top.max() > 1e-8


@pytest.mark.parametrize(
    ("method", "most"),
    [
        (gvi.Galerkin(3), 1.01),
        (gvi.Galerkin(3, gvi.gauss_legendre(3)), 1.1),
        (gvi.Galerkin(2, gvi.gauss_legendre(2)), 1.3),
    ],
    ids=["lobatto4", "gauss3", "gauss2"],
)
def test_extrapolated_forces_leave_about_one_sweep_per_step(method, most):
    # with the first iterate from extrapolated forces and the stop at bit-identical stage
    # positions, a small step needs about one force sweep: measured 1.001 (Lobatto(4),
    # one step), 1.00 and 1.17 (Gauss(3) and Gauss(2), from two steps; 1.30 and 2.00
    # from one) at h = 1e-3; the position polynomial extrapolated took >= 2
    p = problems.pendulum()
    traj = gvi.Integrator(p.system, method).integrate(
        p.q0, p.v0, h=1e-3, n_steps=2000, save_every=2000
    )
    assert 1.0 <= traj.mean_newton_iterations <= most


@pytest.mark.parametrize("method", METHODS, ids=str)
def test_tables_reproduce_constant_acceleration_exactly(method):
    # q'' = g (F = g, M = 1, a = 0) is solved exactly by every method of degree >= 2:
    # Z_i = h c_i v + h^2 c_i^2 g / 2, whatever the quadrature
    tables = separable_tables(method)
    c = method.tables.c
    r = c.size
    stages = tables.stage_p + tables.stage_force @ np.ones(r)  # h = v = g = 1
    exact = c + c**2 / 2
    if method.degree >= 2:
        np.testing.assert_allclose(stages, exact[tables.implicit], rtol=0, atol=1e-14)
        end = tables.control_p[-1] + tables.control_force[-1] @ np.ones(r)
        assert end == pytest.approx(1.5, abs=1e-14)
    # the points partition: every point is implicit, at q_k, or explicit afterwards
    every = np.concatenate([tables.implicit, tables.known, tables.rest])
    assert sorted(every.tolist()) == list(range(r))


# ---------------------------------------------------------------- which loop
def test_diagonal_mass_is_a_compile_time_constant():
    # point masses divide instead of solving with M; the non-diagonal case keeps the solve
    assert codegen.kernel_spec(problems.pendulum().system).diagonal_mass
    assert codegen.kernel_spec(problems.outer_solar_system().system).diagonal_mass
    assert not codegen.kernel_spec(_coupled_mass()[0]).diagonal_mass
    assert not codegen.kernel_spec(problems.double_pendulum().system).diagonal_mass  # M(q)


def test_stage_form_follows_structure():
    assert has_stage_form(problems.pendulum().system)
    assert has_stage_form(problems.outer_solar_system().system)
    assert not has_stage_form(problems.double_pendulum().system)  # M(q)
    assert not has_stage_form(problems.harmonic_oscillator().system)  # quadratic: linear loop
    assert not has_stage_form(problems.damped_oscillator().system)  # f depends on v
    assert not has_stage_form(problems.cartesian_pendulum().system)  # constraints
    pendulum = problems.pendulum().system
    assert gvi.Integrator(pendulum, gvi.Galerkin(2)).kernel_path == "separable"
    assert gvi.Integrator(pendulum, gvi.Galerkin(1)).kernel_path == "explicit"
    assert gvi.Integrator(pendulum, gvi.Galerkin(2), specialize=False).kernel_path == "newton"
    assert gvi.Integrator(pendulum, gvi.Galerkin(2), backend="numpy").kernel_path == "newton"


# ------------------------------------------------------- same map as Newton
def _driven() -> tuple[gvi.LagrangianSystem, list, list]:
    # time-dependent potential, a gauge term a(t).v and a force f(t, q)
    system = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 + sp.cos(t) * vx - sp.sin(t) * vy / 3 - (x**4 + y**2) / 4 + x * y / 5,
        [x, y],
        [vx, vy],
        t=t,
        forces=[sp.sin(2 * t) * y / 4, -(x**3) / 10],
    )
    return system, [0.7, -0.2], [0.1, 0.5]


def _coupled_mass() -> tuple[gvi.LagrangianSystem, list, list]:
    # a constant, non-diagonal mass matrix with an anharmonic potential
    system = gvi.LagrangianSystem(
        (2 * vx**2 + vx * vy + vy**2) / 2 - (x**2 + 3 * y**2) / 2 - x**4 / 4 + sp.cos(y) / 5,
        [x, y],
        [vx, vy],
    )
    return system, [0.8, -0.4], [0.3, 0.2]


def _chain(n: int) -> tuple[gvi.LagrangianSystem, np.ndarray, np.ndarray]:
    q = sp.symbols(f"q0:{n}")
    v = sp.symbols(f"v0:{n}")
    ends = [0, *q, 0]
    potential = sum(
        (ends[a + 1] - ends[a]) ** 2 / 2 + (ends[a + 1] - ends[a]) ** 4 / 4 for a in range(n + 1)
    )
    system = gvi.LagrangianSystem(sum(w**2 for w in v) / 2 - potential, list(q), list(v))
    s = np.arange(1, n + 1) / (n + 1)
    return system, 0.3 * np.sin(np.pi * s), 0.2 * np.sin(2 * np.pi * s)


SYSTEMS = {
    "pendulum": lambda: (problems.pendulum().system, [1.5], [0.3]),
    "henon-heiles": lambda: (problems.henon_heiles().system, [0.1, -0.2], [0.3, 0.1]),
    "driven": _driven,
    "coupled-mass": _coupled_mass,
    "chain-12": lambda: _chain(12),
}


@pytest.fixture(scope="module")
def systems():
    return {name: build() for name, build in SYSTEMS.items()}


@pytest.mark.parametrize("name", list(SYSTEMS))
@pytest.mark.parametrize("method", METHODS, ids=str)
def test_stage_form_is_the_map_of_the_reference(systems, name, method):
    system, q0, v0 = systems[name]
    fast = gvi.Integrator(system, method)
    assert fast.kernel_path == "separable"
    run = {"h": 0.05, "n_steps": 120, "save_every": 7}
    a = fast.integrate(q0, v0, **run)
    b = gvi.Integrator(system, method, backend="numpy").integrate(q0, v0, **run)
    np.testing.assert_array_equal(a.t, b.t)
    # the two solve the same equations in different unknowns: measured <= 1.5e-15
    assert np.abs(a.q - b.q).max() <= 1e-13
    assert np.abs(a.p - b.p).max() <= 1e-13


@pytest.mark.parametrize("cheap", [True, False], ids=["constant-mass", "full-newton"])
def test_both_iterations_give_the_same_map(systems, monkeypatch, cheap):
    system, q0, v0 = systems["chain-12"]
    if not cheap:  # the stage form with full Newton from the first iterate
        monkeypatch.setattr(integrator_module.Integrator, "uses_constant_mass", False)
    method = gvi.Galerkin(3, gvi.gauss_legendre(3))
    fast = gvi.Integrator(system, method)
    assert fast.uses_constant_mass is cheap
    run = {"h": 0.05, "n_steps": 200}
    a = fast.integrate(q0, v0, **run)
    b = gvi.Integrator(system, method, specialize=False).integrate(q0, v0, **run)
    assert np.abs(a.q - b.q).max() <= 1e-13
    assert np.abs(a.p - b.p).max() <= 1e-13


def test_noether_momenta_are_conserved_to_round_off():
    # Kepler's angular momentum and the outer solar system's total momentum
    kepler = problems.kepler(0.6)
    traj = gvi.Integrator(kepler.system, gvi.Galerkin(3)).integrate(
        kepler.q0, kepler.v0, h=2 * np.pi / 200, n_steps=4000, save_every=40
    )
    angular = traj.q[:, 0] * traj.p[:, 1] - traj.q[:, 1] * traj.p[:, 0]
    assert np.abs(angular - angular[0]).max() <= 1e-13
    solar = problems.outer_solar_system()
    traj = gvi.Integrator(solar.system, gvi.Galerkin(2, gvi.gauss_legendre(2))).integrate(
        solar.q0, solar.v0, h=20.0, n_steps=2000, save_every=100, params=solar.params
    )
    total = traj.p.reshape(len(traj.t), -1, 3).sum(axis=1)
    assert np.abs(total - total[0]).max() <= 1e-16 + 1e-13 * np.abs(traj.p).max()


def test_compiles_once_for_every_method_and_step(systems):
    system, q0, v0 = systems["henon-heiles"]
    from numba.core import event

    gvi.Integrator(system, METHODS[0]).integrate(q0, v0, h=0.1, n_steps=2)  # loads the loop
    with event.install_recorder("numba:compile") as compiled:
        for method, h in zip(METHODS, (0.1, 0.05, 0.2, 0.07, 0.1, 0.03, 0.1, 0.05), strict=True):
            integrator = gvi.Integrator(system, method)
            assert integrator.kernel_path == "separable"
            integrator.integrate(q0, v0, h=h, n_steps=5, t0=h, save_every=2)
    assert compiled.buffer == []  # nothing compiled: the stage form's variant was loaded


def test_failure_keeps_the_last_good_state():
    # V = -q^6 blows up in finite time: Newton fails; .partial is a shorter successful run
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + q**6, [q], [v])
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    assert integrator.kernel_path == "separable"
    with np.errstate(all="ignore"), pytest.raises(gvi.ConvergenceError) as info:
        integrator.integrate([1.0], [0.0], h=0.05, n_steps=400, save_every=3, on_failure="raise")
    partial = info.value.partial
    done = partial.n_steps - 1
    assert done == info.value.step and done > 5
    shorter = integrator.integrate([1.0], [0.0], h=0.05, n_steps=done)
    np.testing.assert_array_equal(partial.q[-1], shorter.q[-1])
    np.testing.assert_array_equal(partial.p[-1], shorter.p[-1])


# ------------------------------------------------------- the switch to full Newton
def test_the_constant_mass_iteration_hands_over_by_its_contraction_and_budget():
    from galerkin_vi.loops.stage_form import too_slow

    target = 1e-14
    # no rate after one sweep, nothing to do at the target
    assert not too_slow(1e-3, np.inf, 1, 0.2, 24, target)
    assert not too_slow(1e-15, 1e-10, 5, 0.2, 24, target)
    # contracting by 0.5 per sweep: too slow where a Newton iteration is cheap (cap 0.2) ...
    assert too_slow(1e-6, 2e-6, 3, 0.2, 24, target)
    # ... not where it is dear (cap 0.9), as long as the 27 sweeps to 1e-14 fit: 3 + 26.6
    assert not too_slow(1e-6, 2e-6, 3, 0.9, 30, target)
    assert too_slow(1e-6, 2e-6, 3, 0.9, 24, target)
    # fast contraction always stays; divergence never does
    assert not too_slow(1e-8, 1e-6, 2, 0.02, 15, target)
    assert too_slow(2e-6, 1e-6, 2, 0.9, 24, target)


@pytest.mark.parametrize("s", [4, 6])
def test_a_long_chain_keeps_the_cheap_iteration_at_coarse_steps(monkeypatch, s):
    # 60 masses, s - 1 implicit stages (Lobatto), h = 0.7: the sweeps contract by about
    # 0.3-0.5, and a full Newton iteration costs tens of sweeps. Measured: 12.9 (s = 6)
    # and 15.0 (s = 4) sweeps per step, 7x faster than full Newton's 7.1 and 6.8
    # iterations; with the earlier cap of 0.2 the steps switched to full Newton (7.1, 6.9)
    chain = problems.spring_chain(60, beta=1.0)
    v0 = 0.5 * np.random.default_rng(3).standard_normal(60)
    method = gvi.Galerkin(s, gvi.gauss_lobatto(s + 1))
    run = {"h": 0.7, "n_steps": 60}
    cheap = gvi.Integrator(chain.system, method).integrate(chain.q0, v0, **run)
    monkeypatch.setattr(integrator_module.Integrator, "uses_constant_mass", False)
    newton = gvi.Integrator(chain.system, method).integrate(chain.q0, v0, **run)
    assert np.abs(cheap.q - newton.q).max() <= 1e-12
    # sweeps, not Newton iterations: the cheap iteration ran to the end of the steps
    assert cheap.mean_newton_iterations > newton.mean_newton_iterations + 3


def test_fast_contraction_needs_no_prediction():
    from galerkin_vi.loops.stage_form import FAST_SWEEP, FAST_SWEEPS_LEFT, too_slow

    # a sweep at FAST_SWEEP or faster gains 1.3 digits: FAST_SWEEPS_LEFT of them take an
    # increment the size of q (1) to below 1e-16, so the shortcut never changes a decision
    assert FAST_SWEEP**FAST_SWEEPS_LEFT < 1e-16
    for its in range(2, 12):
        assert not too_slow(1.0, 1.0 / FAST_SWEEP, its, 0.9, 24, 1e-16)
