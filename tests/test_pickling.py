"""Every system pickles, and runs in a process pool, after any solver has used it.

Derived data (lambdified and compiled functions, solver pieces) lives in
``system.derived`` and never pickles: a copy rebuilds it on first use.
"""

from __future__ import annotations

import multiprocessing
import pickle
import threading
import time
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.model.derived import DerivedData

q, v, u, k = sp.symbols("q v u k")
y, vy, g = sp.symbols("y vy g")
x1, x2, v1, v2 = sp.symbols("x1 x2 v1 v2")


@dataclass(frozen=True)
class Case:
    """A system, a solver that uses it, and members for ``integrate_many`` on it."""

    system: Callable[[], gvi.LagrangianSystem]
    solve: Callable[[gvi.LagrangianSystem], object]
    owner: str  # an owner of derived data the solve leaves in system.derived
    q0s: tuple
    v0s: tuple
    h: float = 0.01


def _oscillator() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(v**2 / 2 - k * q**2 / 2, [q], [v], params={k: 1.0})


def _pendulum() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])


def _controlled() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v], forces=[u], params={u: 0.0})


def _ball() -> gvi.LagrangianSystem:
    contact = gvi.Contact(y, restitution=0.8)
    return gvi.LagrangianSystem(vy**2 / 2 - g * y, [y], [vy], params={g: 9.81}, contacts=[contact])


def _integrate(system):
    gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=20)
    system.hamiltonian([1.0], [0.0])  # the NumPy evaluators: lambdified functions


def _events(system):
    event = gvi.Event(q, terminal=True, direction=-1)
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    traj = integrator.integrate([1.0], [0.0], h=0.1, t_span=(0.0, 5.0), events=[event])
    assert traj.status == gvi.RunStatus.TERMINATED


def _contacts(system):
    traj = gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=1e-2, n_steps=60)
    assert len(traj.impacts) == 1


def _bvp(system):
    assert gvi.solve_bvp(system, gvi.Galerkin(2), [1.0], [0.5], (0.0, 1.0), 8).success


def _periodic(system):
    orbit = gvi.solve_periodic(system, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20, energy=-np.cos(1.0))
    assert orbit.success


def _control(system):
    res = gvi.solve_optimal_control(system, gvi.Galerkin(2), [u], u**2 / 2, (0.0, 1.0), 6,
                                    [0.0], [1.0], [0.0], [0.0])  # fmt: skip
    assert res.success


def _adaptive(system):
    adaptive = gvi.AdaptiveIntegrator(
        system, gvi.Galerkin(2, gvi.gauss_legendre(2)), g=gvi.encounter_scaling([x1], 1.5)
    )
    traj = adaptive.integrate([0.5, 0.0], [0.0, np.sqrt(3.0)], h=0.05, n_steps=50)
    assert traj.success


def _kepler_xy() -> gvi.LagrangianSystem:
    # the Kepler problem in x1, x2 so that the scaling's distance is a plain symbol
    r = sp.sqrt(x1**2 + x2**2)
    return gvi.LagrangianSystem((v1**2 + v2**2) / 2 + 1 / r, [x1, x2], [v1, v2])


ONE_DOF = dict(q0s=((1.0,), (0.8,), (0.6,)), v0s=((0.0,), (0.1,), (-0.2,)))
CASES = {
    "integrate": Case(_oscillator, _integrate, "evaluators", **ONE_DOF),
    "events": Case(_oscillator, _events, "events", **ONE_DOF),
    "contacts": Case(_ball, _contacts, "contact", **ONE_DOF),
    "solve_bvp": Case(_oscillator, _bvp, "action", **ONE_DOF),
    "solve_periodic": Case(_pendulum, _periodic, "points", **ONE_DOF),
    "solve_optimal_control": Case(_controlled, _control, "control", **ONE_DOF),
    "adaptive": Case(
        _kepler_xy,
        _adaptive,
        "evaluators",
        q0s=((0.5, 0.0), (0.6, 0.0)),
        v0s=((0.0, 1.7), (0.0, 1.5)),
        h=0.002,
    ),  # fmt: skip
}


@pytest.fixture(scope="module")
def pool():
    # spawn: a worker shares nothing with this process but what is pickled
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=2, mp_context=context) as executor:
        yield executor


@pytest.mark.parametrize("name", list(CASES))
def test_a_used_system_pickles_and_runs_in_a_process_pool(name, pool):
    case = CASES[name]
    system = case.system()
    case.solve(system)
    assert any(True for _ in system.derived.owned_by(case.owner)), system.derived
    copy = pickle.loads(pickle.dumps(system))
    assert len(copy.derived) == 0  # derived data never travels
    assert copy.hamiltonian(case.q0s[0], case.v0s[0]) == system.hamiltonian(
        case.q0s[0], case.v0s[0]
    )  # and is rebuilt on first use
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    run = dict(h=case.h, n_steps=30)
    q0s, v0s = np.array(case.q0s), np.array(case.v0s)
    threads = integrator.integrate_many(q0s, v0s, **run)
    processes = integrator.integrate_many(q0s, v0s, executor=pool, **run)
    for a, b in zip(threads.trajectories, processes.trajectories, strict=True):
        np.testing.assert_array_equal(a.t, b.t)
        np.testing.assert_array_equal(a.q, b.q)
        np.testing.assert_array_equal(a.p, b.p)


def test_a_used_system_runs_on_dask():
    distributed = pytest.importorskip("dask.distributed")
    system = _controlled()
    _control(system)
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    q0s, v0s = np.array(ONE_DOF["q0s"]), np.array(ONE_DOF["v0s"])
    threads = integrator.integrate_many(q0s, v0s, h=0.01, n_steps=30)
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True) as cluster:
        with distributed.Client(cluster) as client:
            on_dask = integrator.integrate_many(
                q0s, v0s, h=0.01, n_steps=30, executor=client.get_executor()
            )
    for a, b in zip(threads.trajectories, on_dask.trajectories, strict=True):
        np.testing.assert_array_equal(a.q, b.q)


# ------------------------------------------------------------------------ the cache
def test_concurrent_gets_build_once_and_share_the_value():
    cache = DerivedData()
    builds = []
    start = threading.Barrier(8)

    def build():
        builds.append(1)
        time.sleep(0.05)  # long enough for every thread to arrive while it builds
        return object()

    def get(_):
        start.wait()
        return cache.get(("test", "slow"), build)

    with ThreadPoolExecutor(8) as threads:
        values = list(threads.map(get, range(8)))
    assert len(builds) == 1 and all(value is values[0] for value in values)


def test_a_builder_may_get_other_keys_and_a_copy_is_empty():
    cache = DerivedData()
    outer = cache.get(("test", "outer"), lambda: cache.get(("test", "inner"), lambda: 2) + 1)
    assert outer == 3 and len(cache) == 2 and cache.peek(("test", "inner")) == 2
    assert dict(cache.owned_by("test")) == {("test", "outer"): 3, ("test", "inner"): 2}
    assert len(pickle.loads(pickle.dumps(cache))) == 0
    with pytest.raises(TypeError, match="non-empty tuple"):
        cache.get("test", lambda: 1)
    with pytest.raises(TypeError, match="hashable"):
        cache.get(("test", []), lambda: 1)
