"""One result convention: every solver's result has ``status``, ``message`` and ``success``.

As scipy's results: ``status`` a member of an int enum (a :class:`gvi.SolverStatus`),
0 done, positive stopped where the user asked, negative a failure;
``success == (status >= 0)``; ``message`` the status in words.
"""

from __future__ import annotations

import warnings
from enum import IntEnum

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi

q, v, u = sp.symbols("q v u")
x1, x2, v1, v2 = sp.symbols("x1 x2 v1 v2")
OSCILLATOR = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])
PENDULUM = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
CONTROLLED = gvi.LagrangianSystem(v**2 / 2, [q], [v], forces=[u], params={u: 0.0})


def _trajectory(kind: str):
    integrator = gvi.Integrator(OSCILLATOR, gvi.Galerkin(2))
    if kind == "completed":
        return integrator.integrate([1.0], [0.0], h=0.1, n_steps=10)
    if kind == "terminal event":
        event = gvi.Event(q, terminal=True, direction=-1)
        return integrator.integrate([1.0], [0.0], h=0.1, t_span=(0.0, 5.0), events=[event])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return integrator.integrate([1.0], [0.0], h=50.0, n_steps=200)  # far past stability


def _adaptive(kind: str):
    r = sp.sqrt(x1**2 + x2**2)
    kepler = gvi.LagrangianSystem((v1**2 + v2**2) / 2 + 1 / r, [x1, x2], [v1, v2])
    adaptive = gvi.AdaptiveIntegrator(
        kepler, gvi.Galerkin(2, gvi.gauss_legendre(2)), g=gvi.encounter_scaling([r], 1.5)
    )
    return adaptive.integrate([0.5, 0.0], [0.0, np.sqrt(3.0)], h=0.05, n_steps=20)


def _bvp(kind: str):
    maxiter = 50 if kind == "converged" else 1
    return gvi.solve_bvp(PENDULUM, gvi.Galerkin(2), [1.0], [-1.0], (0.0, 3.0), 8, maxiter=maxiter)


def _periodic(kind: str):
    maxiter = 50 if kind == "converged" else 1
    return gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20,
                              energy=-np.cos(1.0), maxiter=maxiter)  # fmt: skip


def _control(kind: str):
    maxiter = 1000 if kind == "converged" else 2
    return gvi.solve_optimal_control(CONTROLLED, gvi.Galerkin(2), [u], u**2 / 2, (0.0, 1.0), 6,
                                     [0.0], [1.0], [0.0], [0.0], maxiter=maxiter)  # fmt: skip


RUNS = [
    (_trajectory, "completed", gvi.RunStatus.COMPLETED),
    (_trajectory, "terminal event", gvi.RunStatus.TERMINATED),
    (_trajectory, "unstable", gvi.RunStatus.UNSTABLE),
    (_adaptive, "completed", gvi.RunStatus.COMPLETED),
    (_bvp, "converged", gvi.ActionStatus.CONVERGED),
    (_bvp, "maxiter", gvi.ActionStatus.MAX_ITERATIONS),
    (_periodic, "converged", gvi.ActionStatus.CONVERGED),
    (_periodic, "maxiter", gvi.ActionStatus.MAX_ITERATIONS),
    (_control, "converged", gvi.ActionStatus.CONVERGED),
    (_control, "maxiter", gvi.ActionStatus.MAX_ITERATIONS),
]
RESULT_TYPES = {
    _trajectory: gvi.Trajectory,
    _adaptive: gvi.AdaptiveTrajectory,
    _bvp: gvi.BoundaryValueResult,
    _periodic: gvi.PeriodicOrbit,
    _control: gvi.OptimalControl,
}


@pytest.mark.parametrize(
    ("solve", "kind", "expected"), RUNS, ids=[f"{s.__name__[1:]}-{k}" for s, k, _ in RUNS]
)
def test_every_result_follows_the_convention(solve, kind, expected):
    result = solve(kind)
    assert type(result) is RESULT_TYPES[solve] and isinstance(result, gvi.SolverResult)
    assert result.status is expected
    assert isinstance(result.status, gvi.SolverStatus) and isinstance(result.status, IntEnum)
    assert result.success is (int(result.status) >= 0)
    assert isinstance(result.message, str) and result.message.strip()


def test_status_codes_keep_scipys_sign_convention():
    assert gvi.RunStatus.COMPLETED == gvi.ActionStatus.CONVERGED == 0
    assert gvi.RunStatus.TERMINATED > 0  # stopped where the user asked: a success
    failures = [s for s in (*gvi.RunStatus, *gvi.ActionStatus) if s.name not in
                ("COMPLETED", "TERMINATED", "CONVERGED")]  # fmt: skip
    assert all(s < 0 for s in failures)
    assert all(s.cause for s in (*gvi.RunStatus, *gvi.ActionStatus))
