"""Structure-specialised time loops and the compile-once property of the compiled backend.

Each specialised loop must give the general Newton loop's map to round-off.
Measured speed-ups per step against ``specialize=False`` (20 000 steps, h = 0.05,
one run, ``python benchmarks/specialised_loops.py``): explicit Störmer–Verlet
9-18x (pendulum, Kepler, coupled and driven oscillators); linear stage equations
for quadratic L 3.2-5.4x (s = 2, 3).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen, problems
from galerkin_vi import integrator as integrator_module

x, y, vx, vy, t = sp.symbols("x y vx vy t")


@pytest.fixture(scope="module")
def systems():
    """name -> (system, q0, v0); none of these is chaotic over the compared spans."""
    return {
        "pendulum": (problems.pendulum().system, [1.5], [0.3]),
        "kepler": (problems.kepler(0.5).system, [0.5, 0.0], [0.0, np.sqrt(3.0)]),
        "coupled": (
            gvi.LagrangianSystem(
                (2 * vx**2 + vx * vy + vy**2) / 2 - (x**2 + 3 * y**2 + x * y) / 2,
                [x, y],
                [vx, vy],
            ),
            [1.0, -0.5],
            [0.2, 0.1],
        ),
        "driven": (
            gvi.LagrangianSystem(
                (vx**2 + vy**2) / 2 + sp.cos(t) * vx - (x**2 + y**2) / 2 + x * sp.cos(2 * t),
                [x, y],
                [vx, vy],
                t=t,
            ),
            [1.0, 0.0],
            [0.0, 1.0],
        ),
    }


@pytest.mark.parametrize(
    ("name", "method", "path"),
    [
        ("pendulum", gvi.Galerkin(1), "explicit"),
        ("pendulum", gvi.Galerkin(1, gvi.gauss_legendre(1)), "separable"),
        ("pendulum", gvi.Galerkin(2), "separable"),
        ("kepler", gvi.Galerkin(1), "explicit"),
        ("coupled", gvi.Galerkin(1), "explicit"),
        ("coupled", gvi.Galerkin(3), "linear"),
        ("driven", gvi.Galerkin(1), "explicit"),
        ("driven", gvi.Galerkin(2, gvi.gauss_legendre(2)), "linear"),
    ],
    ids=str,
)
def test_kernel_path_follows_structure(systems, name, method, path):
    system = systems[name][0]
    assert gvi.Integrator(system, method).kernel_path == path
    assert gvi.Integrator(system, method, specialize=False).kernel_path == "newton"
    assert gvi.Integrator(system, method, backend="numpy").kernel_path == "newton"


@pytest.mark.parametrize(
    ("name", "method"),
    [
        ("pendulum", gvi.Galerkin(1)),
        ("kepler", gvi.Galerkin(1)),
        ("coupled", gvi.Galerkin(1)),
        ("driven", gvi.Galerkin(1)),
        ("coupled", gvi.Galerkin(2)),
        ("coupled", gvi.Galerkin(3, gvi.gauss_legendre(3))),
        ("driven", gvi.Galerkin(2)),
        ("driven", gvi.Galerkin(4, gvi.gauss_legendre(5))),
    ],
    ids=str,
)
def test_specialised_loop_is_the_same_map(systems, name, method):
    system, q0, v0 = systems[name]
    fast = gvi.Integrator(system, method)
    general = gvi.Integrator(system, method, specialize=False)
    assert fast.kernel_path != "newton"
    a = fast.integrate(q0, v0, h=0.05, n_steps=500, save_every=7)
    b = general.integrate(q0, v0, h=0.05, n_steps=500, save_every=7)
    np.testing.assert_array_equal(a.t, b.t)
    # measured <= 3.2e-12 (Kepler, Verlet), <= 4.8e-13 elsewhere, over 2000 steps
    assert np.abs(a.q - b.q).max() <= 1e-11
    assert np.abs(a.p - b.p).max() <= 1e-11


def test_explicit_loop_reports_no_newton_iterations(systems):
    system, q0, v0 = systems["pendulum"]
    traj = gvi.Integrator(system, gvi.Galerkin(1)).integrate(q0, v0, h=0.1, n_steps=10)
    assert traj.newton_iterations.tolist() == [0] * 10
    traj = gvi.Integrator(systems["coupled"][0], gvi.Galerkin(2)).integrate(
        systems["coupled"][1], systems["coupled"][2], h=0.1, n_steps=10
    )
    assert traj.newton_iterations.tolist() == [1] * 10


def test_explicit_loop_fails_cleanly_on_blow_up():
    # V = -q^6: an explicit step from a large q overflows; a ConvergenceError, never NaN
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + q**6, [q], [v])
    with np.errstate(all="ignore"), pytest.raises(gvi.ConvergenceError, match="non-finite"):
        gvi.Integrator(system, gvi.Galerkin(1)).integrate(
            [2.0], [0.0], h=0.5, n_steps=100, on_failure="raise"
        )


def test_changing_method_step_and_parameters_never_recompiles():
    # one compiled signature per kernel, whatever degree, quadrature, nodes, h, t0,
    # parameters and initial data: they are run-time data
    problem = problems.double_pendulum()
    system = problem.system
    runs = [
        (gvi.Galerkin(1, gvi.gauss_legendre(1)), 0.1, {}),
        (gvi.Galerkin(2), 0.05, {"m1": 2.0}),
        (gvi.Galerkin(3, gvi.gauss_legendre(4)), 0.2, {"l2": 0.5}),
        (gvi.Galerkin(4, nodes="equidistant"), 0.07, {"g": 9.81}),
        (gvi.Galerkin(6, gvi.gauss_lobatto(9)), 0.3, {}),
    ]
    from numba.core import event

    gvi.Integrator(system, runs[0][0]).integrate(problem.q0, problem.v0, h=0.1, n_steps=2)
    with event.install_recorder("numba:compile") as compiled:
        for method, h, params in runs:
            integrator = gvi.Integrator(system, method)
            integrator.integrate(
                problem.q0 * h, problem.v0 + h, h=h, n_steps=5, t0=h, params=params, save_every=2
            )
    # neither the loop nor its helpers (solve_stages, point_hessian, ...) compiled again
    assert compiled.buffer == []


# ------------------------------------------------------- constant-mass iteration
q1, v1 = sp.symbols("q v")


@pytest.mark.parametrize(
    ("problem", "method", "expected"),
    [
        (problems.kepler(0.5), gvi.Galerkin(3, gvi.gauss_legendre(3)), True),
        (problems.kepler(0.5), gvi.Galerkin(2), True),  # fixed point at any size
        (problems.pendulum(), gvi.Galerkin(6), True),
        (problems.double_pendulum(), gvi.Galerkin(4), False),  # M(q) is not constant
        (problems.n_body((1.0, 2.0, 0.5)), gvi.Galerkin(2), True),
    ],
    ids=["kepler-gauss3", "kepler-lobatto3", "pendulum-s6", "double-pendulum", "3-body"],
)
def test_constant_mass_iteration_follows_structure(problem, method, expected):
    assert gvi.Integrator(problem.system, method).uses_constant_mass is expected
    assert not gvi.Integrator(problem.system, method, specialize=False).uses_constant_mass
    assert not gvi.Integrator(problem.system, method, backend="numpy").uses_constant_mass


@pytest.mark.parametrize(
    ("problem", "method", "h"),
    [
        (problems.kepler(0.5), gvi.Galerkin(3, gvi.gauss_legendre(3)), 0.05),
        (problems.kepler(0.5), gvi.Galerkin(4), 0.1),
        (problems.n_body((1.0, 2.0, 0.5)), gvi.Galerkin(2, gvi.gauss_legendre(2)), 0.01),
    ],
    ids=["kepler-gauss3", "kepler-s4-lobatto5", "3-body-gauss2"],
)
def test_constant_mass_iteration_is_the_same_map(problem, method, h, monkeypatch):
    fast = gvi.Integrator(problem.system, method)
    general = gvi.Integrator(problem.system, method, specialize=False)
    assert fast.uses_constant_mass
    run = {"h": h, "n_steps": 300, "params": problem.params}
    a = fast.integrate(problem.q0, problem.v0, **run)
    b = general.integrate(problem.q0, problem.v0, **run)
    # both iterate to round-off; the difference grows through the pericentre passages:
    # measured 4.4e-13 (Kepler, 2.4 periods), 1e-15 (3 bodies)
    assert np.abs(a.q - b.q).max() <= 1e-11
    assert np.abs(a.p - b.p).max() <= 1e-11
    # the cheap iteration ran: the same loop with full Newton iterates differently
    monkeypatch.setattr(integrator_module.Integrator, "uses_constant_mass", False)
    newton = gvi.Integrator(problem.system, method)
    assert not newton.uses_constant_mass and newton.kernel_path == "separable"
    c = newton.integrate(problem.q0, problem.v0, **run)
    assert not np.array_equal(a.newton_iterations, c.newton_iterations)
    assert np.abs(a.q - c.q).max() <= 1e-11


def test_constant_mass_iteration_hands_over_to_newton_when_stiff():
    # omega h = 2.5: the constant matrix misses the dominant h^2 omega^2 term, so the
    # cheap iteration alone would not converge; full Newton takes over on the first
    # step and runs the next MASS_RETRY = 64 steps before the cheap one is retried
    system = gvi.LagrangianSystem(v1**2 / 2 - 2500 * q1**2 / 2 - q1**4 / 4, [q1], [v1])
    method = gvi.Galerkin(6, gvi.gauss_legendre(6))
    fast = gvi.Integrator(system, method)
    general = gvi.Integrator(system, method, specialize=False)
    assert fast.uses_constant_mass
    a = fast.integrate([0.1], [1.0], h=0.05, n_steps=200)
    b = general.integrate([0.1], [1.0], h=0.05, n_steps=200)
    assert np.abs(a.q - b.q).max() <= 1e-14
    # the failed cheap attempt: two sweeps to see it contract too slowly, then Newton
    # (measured 6 on the first step, 4 to 7 on the next 64, which start with Newton)
    assert a.newton_iterations[0] >= a.newton_iterations[1:65].min() + 2
    # a handover costs ~2 iterations once per 65 steps; the general loop's simplified
    # Newton takes more iterations here (measured means 4.8 and 6.1)
    assert a.mean_newton_iterations <= b.mean_newton_iterations + 0.5


# ------------------------------------------------------------ banded Jacobians
def _chain(n: int, beta: float, coupled: bool = False) -> gvi.LagrangianSystem:
    """Fixed-end chain; ``coupled`` adds a position-dependent mass and a q_a v_{a+1} term."""
    q = sp.symbols(f"q0:{n}")
    v = sp.symbols(f"v0:{n}")
    ends = [0, *q, 0]
    kinetic = sum(w**2 / 2 for w in v)
    if coupled:
        kinetic += sum(qa**2 * w**2 / 20 for qa, w in zip(q, v, strict=True))
        kinetic += sum(q[a] * v[a + 1] / 3 for a in range(n - 1))
    potential = sum(
        (ends[a + 1] - ends[a]) ** 2 / 2 + beta * (ends[a + 1] - ends[a]) ** 4 / 4
        for a in range(n + 1)
    )
    return gvi.LagrangianSystem(kinetic - potential, list(q), list(v))


def _chain_data(n: int) -> tuple[np.ndarray, np.ndarray]:
    x = np.arange(1, n + 1) / (n + 1)
    return 0.3 * np.sin(np.pi * x), 0.2 * np.sin(2 * np.pi * x)


@pytest.mark.parametrize(
    ("beta", "coupled", "method", "path"),
    [
        (1.0, False, gvi.Galerkin(2, gvi.gauss_legendre(2)), "separable"),
        (1.0, True, gvi.Galerkin(2), "newton"),  # M(q) and L_qv: full Newton
        (0.0, False, gvi.Galerkin(3), "linear"),
    ],
    ids=["quartic", "coupled", "linear"],
)
def test_banded_chain_matches_dense_reference(beta, coupled, method, path):
    n = 12
    system = _chain(n, beta, coupled)
    spec = codegen.kernel_spec(system)
    assert spec.banded and spec.half_bandwidth == 1
    assert spec.nnz == 3 * n - 2  # tridiagonal pattern
    fast = gvi.Integrator(system, method)
    assert fast.kernel_path == path
    q0, v0 = _chain_data(n)
    a = fast.integrate(q0, v0, h=0.05, n_steps=60)
    b = gvi.Integrator(system, method, backend="numpy").integrate(q0, v0, h=0.05, n_steps=60)
    # the NumPy reference assembles the dense Jacobian: measured <= 4e-16
    assert np.abs(a.q - b.q).max() <= 1e-13
    assert np.abs(a.p - b.p).max() <= 1e-13


def test_dense_coupling_keeps_dense_storage():
    spec = codegen.kernel_spec(problems.n_body((1.0, 1.0, 1.0, 1.0)).system)
    assert not spec.banded and spec.half_bandwidth == 7 and spec.nnz == 64
