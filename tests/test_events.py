"""Events (solve_ivp's conventions) located on the dense output, and integration to a time."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.run.events import Event, as_events

q, v, k = sp.symbols("q v k")
# q = cos t from (1, 0): zeros of q at pi/2 + j pi, downward ones of v at 2 pi j
OSCILLATOR = gvi.LagrangianSystem(v**2 / 2 - k * q**2 / 2, [q], [v], params={k: 1.0})
BACKEND = "numpy"  # events are backend-independent; the loops are tested elsewhere


def _integrator(s=2):
    return gvi.Integrator(OSCILLATOR, gvi.Galerkin(s), backend=BACKEND)


def test_event_times_and_states_of_the_oscillator():
    traj = _integrator().integrate(
        [1.0], [0.0], h=0.05, t_span=(0.0, 20.0), events=[Event(q), Event(v, direction=-1)]
    )
    zeros = np.pi / 2 + np.pi * np.arange(6)  # the last before t = 20
    # v = -sin t starts at 0 and decreases: an event at t0, as solve_ivp reports it
    turns = 2 * np.pi * np.arange(0, 4)
    np.testing.assert_allclose(traj.t_events[0], zeros, rtol=0, atol=5e-8)  # measured 3.8e-8
    np.testing.assert_allclose(traj.t_events[1], turns, rtol=0, atol=5e-8)
    # the states are the dense output's at the event times: g = 0 to round-off there
    assert np.max(np.abs(traj.q_events[0])) < 1e-14
    assert np.max(np.abs(traj.v_events[1])) < 1e-14
    np.testing.assert_allclose(np.abs(traj.v_events[0][:, 0]), 1.0, rtol=0, atol=1e-7)
    np.testing.assert_allclose(traj.p_events[0], traj.v_events[0], rtol=0, atol=1e-15)  # p = v
    assert traj.status == gvi.RunStatus.COMPLETED and traj.t[-1] == pytest.approx(20.0)


@pytest.mark.parametrize("exact", [False, True])
def test_event_times_converge_at_the_methods_order(exact):
    errors, steps = [], [0.2, 0.1, 0.05]
    for s, order in ((2, 4), (3, 6)):
        errors = []
        for h in steps:
            traj = _integrator(s).integrate(
                [1.0], [0.0], h=h, t_span=(0.0, 20.0), events=Event(q, exact=exact)
            )
            t = traj.t_events[0]
            errors.append(np.max(np.abs(t - (np.pi / 2 + np.pi * np.arange(t.size)))))
        slope = np.polyfit(np.log(steps), np.log(errors), 1)[0]
        assert slope > order - 0.3, (s, errors)  # measured 4.0 (s = 2)


def test_an_exact_event_is_a_state_of_the_method():
    integrator = _integrator()
    traj = integrator.integrate([1.0], [0.0], h=0.1, t_span=(0.0, 5.0), events=Event(q, exact=True))
    # one step from the node before, cut to the event time, lands on the event state
    for t_e, q_e in zip(traj.t_events[0], traj.q_events[0], strict=True):
        j = int(np.searchsorted(traj.t, t_e)) - 1
        q1, _ = integrator.step(traj.q[j], traj.p[j], t_e - traj.t[j], t0=traj.t[j])
        # (t_e - t_j here and the step length there differ by an ulp)
        np.testing.assert_allclose(q1, q_e, rtol=0, atol=1e-15)
        assert abs(q_e[0]) < 1e-15


def test_a_terminal_event_ends_the_run_at_the_event():
    integrator = _integrator()
    traj = integrator.integrate(
        [1.0], [0.0], h=0.1, n_steps=400, events=Event(q, terminal=2, direction=1)
    )
    # the second upward zero of cos t is at 7 pi / 2
    assert traj.status == gvi.RunStatus.TERMINATED == 1 and traj.success
    assert "terminal event 0" in traj.message
    assert traj.t[-1] == pytest.approx(3.5 * np.pi, abs=1e-6)
    assert traj.t[-2] < traj.t[-1] < traj.t[-2] + 0.1
    assert abs(traj.q[-1, 0]) < 1e-14 and traj.p[-1, 0] == pytest.approx(1.0, abs=1e-6)
    assert traj.t_events[0].size == 2
    # the dense output ends there too
    assert traj.sol.t_max == traj.t[-1]
    np.testing.assert_allclose(traj.sol(traj.t[-1]), traj.q[-1], rtol=0, atol=1e-15)


def test_a_callable_with_solve_ivp_attributes():
    def crossing(t, qq, vv):
        return qq[0] - 0.5

    crossing.terminal = True
    crossing.direction = -1.0
    traj = _integrator().integrate([1.0], [0.0], h=0.05, n_steps=200, events=crossing)
    assert traj.status == 1 and traj.t[-1] == pytest.approx(np.pi / 3, abs=1e-6)


def test_events_with_time_and_parameters_and_backwards():
    t = OSCILLATOR.time_symbol
    traj = _integrator().integrate(
        [1.0], [0.0], h=-0.05, t_span=(0.0, -10.0), params={k: 4.0}, events=Event(t + 3 + 0 * q)
    )
    assert traj.t_events[0] == pytest.approx([-3.0], abs=1e-14)
    np.testing.assert_allclose(traj.q_events[0][0], np.cos(2 * 3.0), rtol=0, atol=1e-6)  # omega = 2


def test_t_span_lands_on_its_end_with_equal_steps():
    traj = _integrator().integrate([1.0], [0.0], h=0.3, t_span=(1.0, 2.0))
    assert len(traj) == 5 and traj.t[0] == 1.0  # h reduced to 0.25
    assert traj.t[-1] == pytest.approx(2.0, abs=1e-15)
    np.testing.assert_allclose(np.diff(traj.t), 0.25, rtol=1e-14)


def test_bad_event_and_span_arguments():
    integrator = _integrator()
    x = sp.Symbol("x")
    with pytest.raises(ValueError, match="not the system's: x"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=5, events=Event(q - x))
    with pytest.raises(TypeError, match="SymPy expression or a callable"):
        Event(3.0)
    with pytest.raises(ValueError, match="terminal must be"):
        Event(q, terminal=-1)
    with pytest.raises(TypeError, match="events"):
        as_events([q, "q"])
    with pytest.raises(ValueError, match="needs save_every=1"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=4, save_every=2, events=q)
    with pytest.raises(ValueError, match="give n_steps or t_span"):
        integrator.integrate([1.0], [0.0], h=0.1)
    with pytest.raises(ValueError, match="not both"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=3, t_span=(0, 1))
    with pytest.raises(ValueError, match="points away"):
        integrator.integrate([1.0], [0.0], h=-0.1, t_span=(0, 1))
    with pytest.raises(ValueError, match="two different finite times"):
        integrator.integrate([1.0], [0.0], h=0.1, t_span=(1, 1))
    with pytest.raises(ValueError, match="disagree"):
        integrator.integrate([1.0], [0.0], h=0.1, t_span=(0, 1), t0=0.5)


def test_t_eval_gives_the_dense_output_at_the_requested_times():
    integrator = _integrator()
    times = np.linspace(0.0, 3.0, 7) + 0.013
    traj = integrator.integrate([1.0], [0.0], h=0.1, t_span=(0.0, 3.1), t_eval=times)
    np.testing.assert_array_equal(traj.t, times)
    np.testing.assert_allclose(traj.q[:, 0], np.cos(times), rtol=0, atol=2e-6)
    np.testing.assert_allclose(traj.p[:, 0], -np.sin(times), rtol=0, atol=2e-6)  # p = v
    assert traj.sol.t_max == pytest.approx(3.1)  # every step is kept in the dense output
    with pytest.raises(ValueError, match="in the run's span"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=10, t_eval=[0.5, 1.5])
    with pytest.raises(ValueError, match="sorted in the direction"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=10, t_eval=[0.5, 0.2])
    with pytest.raises(ValueError, match="needs save_every=1"):
        integrator.integrate([1.0], [0.0], h=0.1, n_steps=10, save_every=2, t_eval=[0.5])
