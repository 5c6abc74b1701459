"""Ensembles: many members in one call, each bitwise its one-by-one run."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.problems import mechanics
from galerkin_vi.run.chunks import FIRST_CHUNK
from galerkin_vi.run.ensemble import compile_statistics, member_parameters, parameter_matrix


@pytest.fixture(scope="module")
def double_pendulum():
    problem = mechanics.double_pendulum()
    return problem, gvi.Integrator(problem.system, gvi.Galerkin(2, gvi.gauss_legendre(2)))


def _members(problem, m):
    rng = np.random.default_rng(7)
    q0s = problem.q0 + 0.1 * rng.standard_normal((m, problem.system.n))
    return q0s, np.tile(problem.v0, (m, 1))


def test_members_equal_their_one_by_one_runs(double_pendulum):
    problem, integrator = double_pendulum
    q0s, v0s = _members(problem, 6)
    name = str(problem.system.params[0])
    sweep = {name: np.linspace(0.8, 1.2, 6)}
    many = integrator.integrate_many(q0s, v0s, params=sweep, h=0.01, n_steps=200, workers=2)
    assert len(many) == 6 and many.q.shape == (6, 201, 2) and many.success.all()
    for i in range(6):
        one = integrator.integrate(
            q0s[i], v0s[i], h=0.01, n_steps=200, params={name: sweep[name][i]}
        )
        np.testing.assert_array_equal(many.q[i], one.q)
        np.testing.assert_array_equal(many.p[i], one.p)
    # the parameter mattered: different members, different ends
    assert len({float(x) for x in many.q[:, -1, 0]}) == 6


def _same_run(member, one):
    """Every field a run returns, bitwise."""
    for name in ("t", "q", "p", "newton_iterations", "params"):
        np.testing.assert_array_equal(getattr(member, name), getattr(one, name), err_msg=name)
    if one.q_reduced is None:
        assert member.q_reduced is None
    else:
        np.testing.assert_array_equal(member.q_reduced, one.q_reduced)
    assert member.total_newton_iterations == one.total_newton_iterations
    assert (member.n_steps, member.max_residual) == (one.n_steps, one.max_residual)
    assert (member.status, member.message) == (one.status, one.message)


def _systems():
    t = sp.Symbol("t")
    q, v, x, y, vx, vy, k = sp.symbols("q v x y vx vy k")
    pendulum = gvi.LagrangianSystem(v**2 / 2 + k * sp.cos(q), [q], [v], params={k: 1.0})
    driven = gvi.LagrangianSystem(
        (1 + q**2) * v**2 / 2 + k * sp.cos(q) * (1 + sp.sin(t) / 10), [q], [v], t=t,
        params={k: 1.0},
    )  # fmt: skip
    linear = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - k * (x**2 + y**2 + x * y) / 2, [x, y], [vx, vy], params={k: 1.0}
    )
    rod = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - k * y, [x, y], [vx, vy], constraints=[(x**2 + y**2 - 1) / 2],
        params={k: 1.0},
    )  # fmt: skip
    # not quadratic in v: the general Newton loop
    general = gvi.LagrangianSystem(
        (1 + q**2) * v**2 / 2 + v**4 / 24 + k * sp.cos(q) * (1 + sp.sin(t) / 10), [q], [v],
        t=t, params={k: 1.0},
    )  # fmt: skip
    return {
        "separable": (pendulum, [[0.5], [2.9], [-1.0]], [[0.1], [1.0], [0.0]]),
        "varying_mass": (driven, [[0.5], [2.9], [-1.0]], [[0.1], [1.0], [0.0]]),
        "general": (general, [[0.5], [2.9], [-1.0]], [[0.1], [1.0], [0.0]]),
        "linear": (linear, [[0.5, 0.1], [-0.2, 0.3], [0.0, 1.0]], [[0.1, 0.0]] * 3),
        "constrained": (
            rod,
            [[0.6, -0.8], [0.8, -0.6], [0.0, -1.0]],
            [[0.8, 0.6], [0.6, 0.8], [1, 0]],
        ),
    }


@pytest.mark.parametrize("path", ["separable", "general", "linear", "constrained", "varying_mass"])
@pytest.mark.parametrize("start", ["v0", "p0"])
def test_every_compiled_loop_gives_the_one_by_one_runs(path, start):
    system, q0s, v0s = _systems()[path]
    # the varying-mass loop takes Gauss collocation of degree 3 and more only
    gauss = path == "varying_mass"
    method = gvi.Galerkin(3, gvi.gauss_legendre(3)) if gauss else gvi.Galerkin(2)
    integrator = gvi.Integrator(system, method)
    assert integrator.kernel_path == {"general": "newton"}.get(
        path, path
    )  # each branch of the member loop is exercised
    q0s, v0s = np.array(q0s, dtype=float), np.array(v0s, dtype=float)
    if start == "p0":
        x = np.array(
            [
                integrator.integrate(q, v, h=0.1, n_steps=0).p[0]
                for q, v in zip(q0s, v0s, strict=True)
            ]
        )
    else:
        x = v0s
    sweep = {"k": [0.5, 1.0, 2.0]}
    many = integrator.integrate_many(
        q0s, **{f"{start}s": x}, params=sweep, h=0.05, n_steps=120, save_every=7, workers=2
    )
    assert many.success.all() and many.q.shape == (3, 19, system.n)
    for i in range(3):
        one = integrator.integrate(
            q0s[i], **{start: x[i]}, h=0.05, n_steps=120, save_every=7,
            params={"k": sweep["k"][i]},
        )  # fmt: skip
        _same_run(many[i], one)
        np.testing.assert_array_equal(many.q[i], one.q)


def test_runs_longer_than_one_call_are_chunked_as_one_by_one():
    system, q0s, v0s = _systems()["separable"]
    integrator = gvi.Integrator(system, gvi.Galerkin(1, gvi.gauss_legendre(1)))
    steps = FIRST_CHUNK + 3
    many = integrator.integrate_many(q0s, v0s, h=0.05, n_steps=steps, save_every=steps)
    for i in range(3):
        _same_run(
            many[i], integrator.integrate(q0s[i], v0s[i], h=0.05, n_steps=steps, save_every=steps)
        )


def test_a_singular_start_names_the_member():
    q, v = sp.symbols("q v")
    # L_vv = q^2 vanishes at q = 0: the second member's Legendre transform is singular
    system = gvi.LagrangianSystem(q**2 * v**2 / 2 - q**2 / 2, [q], [v])
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    with pytest.raises(gvi.DegenerateLagrangianError, match="q0=\\[0."):
        integrator.integrate_many([[1.0], [0.0]], [[0.1], [0.1]], h=0.1, n_steps=3)


def test_parameter_matrix_is_the_one_by_one_vectors(double_pendulum):
    problem, _ = double_pendulum
    system = problem.system
    name = str(system.params[0])
    sweep = {name: np.linspace(0.8, 1.2, 4)}
    expected = [system.parameter_vector({name: g}) for g in sweep[name]]
    np.testing.assert_array_equal(parameter_matrix(system, sweep, 4), expected)
    np.testing.assert_array_equal(
        parameter_matrix(system, member_parameters(sweep, 4), 4), expected
    )
    with pytest.raises(ValueError, match="must be finite"):
        parameter_matrix(system, {name: [1.0, np.nan]}, 2)
    with pytest.raises(ValueError, match="not a declared parameter"):
        parameter_matrix(system, {"nonsense": [1.0, 2.0]}, 2)


def test_a_process_pool_gives_the_same_members(double_pendulum):
    problem, integrator = double_pendulum
    q0s, v0s = _members(problem, 4)
    threads = integrator.integrate_many(q0s, v0s, h=0.01, n_steps=100)
    threads.trajectories[0].velocities()  # NumPy evaluators built: they must not travel
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=2, mp_context=context) as pool:
        processes = integrator.integrate_many(q0s, v0s, h=0.01, n_steps=100, executor=pool)
        counts = [pool.submit(compile_statistics).result() for _ in range(4)]
    # the workers loaded the member loop and the point functions, compiling nothing
    assert all(c["loops_compiled"] == 0 and c["points_compiled"] == 0 for c in counts), counts
    assert any(c["loops_loaded"] >= 1 and c["points_loaded"] >= 1 for c in counts), counts
    np.testing.assert_array_equal(processes.q, threads.q)
    np.testing.assert_array_equal(processes.p, threads.p)


def test_failures_and_unequal_members_are_reported_per_member(double_pendulum):
    problem, integrator = double_pendulum
    q0s, v0s = _members(problem, 3)
    v0s[1] = 1e6  # absurd speed: this member fails, the others not
    with pytest.warns(gvi.RunFailureWarning):
        many = integrator.integrate_many(q0s, v0s, h=0.05, n_steps=100)
    assert list(many.success) == [True, False, True]
    assert many.q is None and many.status[1] < 0  # the failed member is shorter


def test_arguments():
    assert member_parameters(None, 2) == [None, None]
    assert member_parameters({"g": 9.8}, 2) == [{"g": 9.8}, {"g": 9.8}]
    with pytest.raises(ValueError, match="one value per member"):
        member_parameters({"g": [1.0, 2.0, 3.0]}, 2)
    with pytest.raises(ValueError, match="one mapping per member"):
        member_parameters([{"g": 1.0}], 2)
    problem = mechanics.double_pendulum()
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(1))
    with pytest.raises(ValueError, match="exactly one of v0s and p0s"):
        integrator.integrate_many([problem.q0], h=0.1, n_steps=2)
    with pytest.raises(ValueError, match="q0s must have shape"):
        integrator.integrate_many([[1.0, 2.0, 3.0]], [0.0, 0.0], h=0.1, n_steps=2)


def test_dask_local_cluster_matches_the_serial_run(double_pendulum):
    distributed = pytest.importorskip("dask.distributed")
    problem, integrator = double_pendulum
    q0s, v0s = _members(problem, 4)
    serial = [integrator.integrate(q0s[i], v0s[i], h=0.01, n_steps=100) for i in range(4)]
    integrator.integrate_many(q0s, v0s, h=0.01, n_steps=1)  # the member loop in the cache
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        with distributed.Client(cluster) as client:
            many = integrator.integrate_many(
                q0s, v0s, h=0.01, n_steps=100, executor=client.get_executor()
            )
            statistics = client.run(compile_statistics)
    for i in range(4):
        np.testing.assert_array_equal(many.q[i], serial[i].q)
    # the workers loaded everything from the cache folder: nothing was compiled there
    assert len(statistics) == 2
    for counts in statistics.values():
        assert counts["loops_compiled"] == 0 and counts["points_compiled"] == 0, counts
        assert counts["loops_loaded"] >= 1 and counts["points_loaded"] >= 1, counts
