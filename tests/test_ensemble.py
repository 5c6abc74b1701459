"""Ensembles: many members in one call, each bitwise its one-by-one run."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest

import galerkin_vi as gvi
from galerkin_vi.ensemble import member_parameters
from galerkin_vi.problems import mechanics


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


def test_a_process_pool_gives_the_same_members(double_pendulum):
    problem, integrator = double_pendulum
    q0s, v0s = _members(problem, 4)
    threads = integrator.integrate_many(q0s, v0s, h=0.01, n_steps=100)
    threads.trajectories[0].velocities()  # NumPy evaluators built: they must not travel
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=2, mp_context=context) as pool:
        processes = integrator.integrate_many(q0s, v0s, h=0.01, n_steps=100, executor=pool)
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
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        with distributed.Client(cluster) as client:
            many = integrator.integrate_many(
                q0s, v0s, h=0.01, n_steps=100, executor=client.get_executor()
            )
    for i in range(4):
        np.testing.assert_array_equal(many.q[i], serial[i].q)
