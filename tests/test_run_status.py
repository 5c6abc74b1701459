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
from galerkin_vi.run.status import RunStatus, loop_status
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
    # near the blow-up the growth is explosive: the last trusted step names the failure
    fail_step = round(whole.t[-1] / 0.01)
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
    # h = 1.5 is far too long at pericentre: an early step fails, the ones before are kept
    with pytest.warns(gvi.RunFailureWarning, match="physical time"):
        traj = adaptive.integrate(kepler.q0, kepler.v0, h=1.5, n_steps=400)
    assert isinstance(traj, gvi.AdaptiveTrajectory) and not traj.success
    steps = len(traj.q) - 1
    assert 1 <= steps <= 3 and traj.tau[-1] == 1.5 * steps and traj.t[-1] > 0.0
    assert traj.status < 0 and ".partial" not in traj.message


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


# ------------------------------------------------------------ explosive growth
STIFF_QUARTIC = gvi.LagrangianSystem(v**2 / 2 - 1e4 * q**2 / 2 - q**4, [q], [v])
VERLET = gvi.Galerkin(1, gvi.gauss_lobatto(2))


@pytest.mark.parametrize("save_every", [1, 3, 10])
def test_explosive_steps_are_dropped_whatever_save_every(save_every):
    # h omega = 50: Verlet went 1, -1.2e3, 2.0e9, -7.5e27, 4.2e83, then inf; those
    # states were returned unflagged
    integrator = gvi.Integrator(STIFF_QUARTIC, VERLET)
    assert integrator.kernel_path == "explicit"
    with np.errstate(all="ignore"), pytest.warns(gvi.RunFailureWarning) as caught:
        traj = integrator.integrate([1.0], [0.0], h=0.5, n_steps=400, save_every=save_every)
    assert traj.status == RunStatus.UNSTABLE and not traj.success
    assert len(traj) == 1 and traj.q[0, 0] == 1.0  # only the initial state is trusted
    message = str(caught[0].message)
    assert message.startswith("step 0 (t = 0, h = 0.5): the solution grew explosively")
    # the explicit loop's own failure follows, and it is not called a Newton failure
    assert "then step 4 (t = 2, h = 0.5): non-finite values" in message
    assert "Newton" not in message and "increment" not in message


@pytest.mark.parametrize("save_every", [1, 5, 50])
def test_the_last_trusted_step_is_found_between_saved_states(save_every):
    integrator = gvi.Integrator(STIFF_QUARTIC, VERLET)
    traj = _quietly(
        lambda: integrator.integrate([1.0], [0.0], h=0.021, n_steps=400, save_every=save_every)
    )
    # measured: step 8 grows by a factor 9e3; step 7 (t = 0.147) is the last one kept
    assert traj.status == RunStatus.UNSTABLE and traj.message.startswith("step 7 (t = 0.147")
    assert traj.t[-1] == pytest.approx(0.147, rel=1e-14)
    assert np.all(np.abs(traj.q) < 100)


def test_a_run_that_overflows_without_failing_is_flagged():
    stiff = gvi.LagrangianSystem(v**2 / 2 - 1e4 * q**2 / 2, [q], [v])
    traj = _quietly(
        lambda: gvi.Integrator(stiff, VERLET).integrate([1.0], [0.0], h=0.5, n_steps=50)
    )
    # growth by (h omega)^2 = 2500 per step to 1e169, all finite: not a result
    assert traj.status == RunStatus.UNSTABLE and len(traj) == 1


def test_legitimate_growth_is_not_flagged():
    g = sp.Symbol("g")
    fall = gvi.LagrangianSystem(v**2 / 2 - g * q, [q], [v], params={g: 9.81})
    with warnings.catch_warnings():
        warnings.simplefilter("error", gvi.RunFailureWarning)
        traj = gvi.Integrator(fall, gvi.Galerkin(2)).integrate(
            [0.0], [0.0], h=0.01, n_steps=100_000, save_every=20_000
        )
    # from rest to q = -4.9e6 with p_0 = 0: a factor 1e5 between saved states, not per step
    assert traj.success and traj.q[-1, 0] == pytest.approx(-9.81 * 1000.0**2 / 2, rel=1e-9)


def test_explosive_row():
    from galerkin_vi.run.trust import explosive_row

    steps = np.arange(4)
    calm = np.array([[0.0], [1e-8], [1e-3], [0.5]])  # from rest: measured against 1
    assert explosive_row(calm, calm, steps) is None
    wild = np.array([[1.0], [2.0], [5e3], [1e9]])
    assert explosive_row(wild, wild, steps) == 2
    assert explosive_row(wild, wild, steps * 10) is None  # factors over 10 steps each
    broken = np.array([[1.0], [np.nan]])
    assert explosive_row(broken, broken, np.arange(2)) == 1
