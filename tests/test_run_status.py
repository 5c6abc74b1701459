"""A run's status, message and success, and what ``on_failure`` does with a failure.

A failed run returns the states before the failing step, flagged, with a
warning (solve_ivp's convention), unless ``on_failure="raise"`` asks for the
:class:`ConvergenceError` of earlier versions; both hold the same states.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.problems import gravitation
from galerkin_vi.status import RunStatus, loop_status
from galerkin_vi.testing import assert_conserved

q, v, k = sp.symbols("q v k")
BLOW_UP = gvi.LagrangianSystem(v**2 / 2 + k * q**4, [q], [v], params={k: 1.0})
OSCILLATOR = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])
BACKENDS = ["numba", "numpy"]


def _quietly(fn):
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.RunFailureWarning)
        return fn()


def test_a_completed_run_says_so():
    traj = gvi.Integrator(OSCILLATOR, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=10)
    assert traj.success and traj.status == RunStatus.COMPLETED == 0
    assert traj.message == "the run reached its last step"


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("save_every", [1, 4])
def test_a_failed_run_returns_its_states_flagged_and_warns(backend, save_every):
    integrator = gvi.Integrator(BLOW_UP, gvi.Galerkin(2), backend=backend)
    h, t0 = 0.05, 0.5
    run = {"h": h, "n_steps": 1000, "t0": t0, "save_every": save_every}
    with np.errstate(all="ignore"), pytest.warns(gvi.RunFailureWarning, match=r"step \d+"):
        traj = integrator.integrate([1.0], [0.0], **run)
    assert not traj.success and traj.status < 0
    assert traj.status in (RunStatus.NO_CONVERGENCE, RunStatus.NON_FINITE)
    # q runs off to infinity near t = 0.9: the message names the step, its time and the cause
    step = traj.n_steps - 1
    assert 5 <= step < 1000
    assert f"step {step} (t = {t0 + step * h:.6g}" in traj.message
    assert traj.status.cause in traj.message
    assert np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.p))
    assert traj.t[-1] == pytest.approx(t0 + step * h, rel=1e-15)
    # the same states as the ConvergenceError of on_failure="raise"
    with np.errstate(all="ignore"), pytest.raises(gvi.ConvergenceError) as info:
        integrator.integrate([1.0], [0.0], **run, on_failure="raise")
    partial = info.value.partial
    assert info.value.step == step and partial.status == traj.status
    np.testing.assert_array_equal(partial.q, traj.q)
    np.testing.assert_array_equal(partial.p, traj.p)
    np.testing.assert_array_equal(partial.t, traj.t)


def test_on_failure_must_be_warn_or_raise():
    integrator = gvi.Integrator(OSCILLATOR, gvi.Galerkin(2))
    with pytest.raises(ValueError, match="on_failure must be one of"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=2, on_failure="ignore")
    with pytest.raises(ValueError, match="on_failure must be one of"):
        integrator.stream([1.0], [0.0], h=0.1, n_steps=2, on_failure=None)


def test_a_failed_stream_ends_with_the_flagged_chunk():
    integrator = gvi.Integrator(BLOW_UP, gvi.Galerkin(2))
    with np.errstate(all="ignore"), pytest.warns(gvi.RunFailureWarning):
        chunks = list(integrator.stream([1.0], [0.0], h=0.01, n_steps=1000, chunk_steps=20))
    assert all(c.success for c in chunks[:-1]) and not chunks[-1].success
    whole = _quietly(lambda: integrator.integrate([1.0], [0.0], h=0.01, n_steps=1000))
    # the chunks' steps end where one run's do, and the message counts the whole run's steps
    fail_step = whole.n_steps - 1
    assert f"step {fail_step} of the whole run" in chunks[-1].message
    assert chunks[-1].t[-1] == pytest.approx(whole.t[-1], rel=1e-14)
    assert sum(len(c) for c in chunks) == len(whole)


def test_a_failed_adaptive_run_returns_its_physical_states():
    kepler = gravitation.kepler(0.9)
    x, y = kepler.system.q
    adaptive = gvi.AdaptiveIntegrator(
        kepler.system, gvi.Galerkin(2, gvi.gauss_legendre(2)),
        g=gvi.encounter_scaling([sp.sqrt(x**2 + y**2)], 1.5),
    )  # fmt: skip
    # h = 1.5 is far too long at pericentre: the second step fails, the first is kept
    with pytest.warns(gvi.RunFailureWarning, match="physical time"):
        traj = adaptive.integrate(kepler.q0, kepler.v0, h=1.5, n_steps=400)
    assert isinstance(traj, gvi.AdaptiveTrajectory) and not traj.success
    assert traj.q.shape == (2, 2) and traj.tau[-1] == 1.5 and traj.t[-1] > 0.0


def test_assert_conserved_fails_a_failed_run_unless_allowed():
    integrator = gvi.Integrator(BLOW_UP, gvi.Galerkin(2))
    traj = _quietly(lambda: integrator.integrate([1.0], [0.0], h=0.05, n_steps=1000))
    with pytest.raises(AssertionError, match="the run failed"):
        assert_conserved(traj, energy=1.0)
    # the early states conserve energy well: checked when asked for
    early = _quietly(lambda: integrator.integrate([0.1], [0.0], h=0.05, n_steps=5))
    assert early.success
    assert assert_conserved(early, energy=1e-6)["energy"] < 1e-6


def test_loop_codes_map_to_statuses():
    assert loop_status(0) is RunStatus.COMPLETED
    assert loop_status(1) is RunStatus.NO_CONVERGENCE
    assert loop_status(2) is RunStatus.SINGULAR_JACOBIAN
    assert loop_status(3) is RunStatus.NON_FINITE
    with pytest.raises(ValueError, match="unknown loop status code 7"):
        loop_status(7)
    assert all(s.cause for s in RunStatus)
    assert [s for s in RunStatus if s >= 0] == [RunStatus.COMPLETED, RunStatus.TERMINATED]
