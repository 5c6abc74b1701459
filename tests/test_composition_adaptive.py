"""Adaptive (Poincaré) runs with every run option, each checked against the closed-form
Kepler orbit (the solution of Kepler's equation): t_eval, dense output, events, save_every,
t_span, backward runs, Ctrl-C, integrate_many and step."""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.problems import gravitation

x, y, vx, vy = sp.symbols("x y vx vy")
R = sp.sqrt(x**2 + y**2)
RADIAL = x * vx + y * vy  # r r': zero at the pericentres (rising) and apocentres (falling)
GAUSS3 = gvi.Galerkin(3, gvi.gauss_legendre(3))  # order 6
GAUSS2 = gvi.Galerkin(2, gvi.gauss_legendre(2))  # order 4
#: fictitious step at which Gauss(3) reaches 1e-10 on e = 0.5 .. 0.9 over three periods
#: (measured errors 3e-11 at the nodes, 3e-11 for the event times)
H = 0.05
PERIOD = 2 * np.pi
T_FINAL = 3 * PERIOD + 1.0


def kepler_velocity(t, e: float) -> np.ndarray:
    """The exact velocity of :func:`gravitation.kepler_position` (a = mu = 1)."""
    mean = np.fmod(np.asarray(t, dtype=float), 2 * np.pi)
    E = mean + e * np.sin(mean) if e < 0.8 else np.full_like(mean, np.pi)
    for _ in range(60):
        E = E - (E - e * np.sin(E) - mean) / (1 - e * np.cos(E))
    rate = 1.0 / (1 - e * np.cos(E))
    return np.stack([-np.sin(E) * rate, np.sqrt(1 - e * e) * np.cos(E) * rate], axis=-1)


@pytest.fixture(scope="module")
def adaptive():
    system = gravitation.kepler(0.5).system
    return gvi.AdaptiveIntegrator(system, GAUSS3, g=gvi.encounter_scaling([R], 1.5))


@pytest.fixture(scope="module", params=[0.5, 0.9], ids=["e=0.5", "e=0.9"])
def orbit(request):
    return request.param, gravitation.kepler(request.param)


# ------------------------------------------------------------------ t_eval
@pytest.mark.parametrize("span", ["t_final", "t_span", "n_steps"])
def test_t_eval_rows_are_the_orbit_at_the_requested_times(adaptive, orbit, span):
    e, kepler = orbit
    times = np.linspace(0.0, 3 * PERIOD, 61)
    run = {"t_final": {"t_final": T_FINAL}, "t_span": {"t_span": (0.0, T_FINAL)},
           "n_steps": {"n_steps": 700}}[span]  # fmt: skip
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=H, t_eval=times, **run)
    assert isinstance(traj, gvi.AdaptiveTrajectory) and traj.status == 0
    np.testing.assert_array_equal(traj.t, times)
    assert np.abs(traj.q - kepler.exact(times)).max() < 1e-9
    assert np.abs(traj.p - kepler_velocity(times, e)).max() < 1e-8  # p = v for Kepler
    # the fictitious times of the rows: increasing, between those of the steps around them
    assert traj.tau.shape == times.shape and np.all(np.diff(traj.tau) > 0)
    assert traj.sol is not None and traj.sol.t[-1] >= 3 * PERIOD
    k = np.searchsorted(traj.sol.t, times[1:-1])
    steps = adaptive.integrate(kepler.q0, kepler.v0, h=H, **run)
    assert np.all((steps.tau[k - 1] <= traj.tau[1:-1]) & (traj.tau[1:-1] <= steps.tau[k]))
    # at the steps' own times the rows are the steps (interpolants through the nodes)
    nodes = adaptive.integrate(kepler.q0, kepler.v0, h=H, t_eval=steps.t[:40], **run)
    np.testing.assert_allclose(nodes.tau, steps.tau[:40], rtol=0, atol=1e-12)
    np.testing.assert_allclose(nodes.q, steps.q[:40], rtol=0, atol=1e-13)


def test_t_eval_outside_the_span_is_named(adaptive, orbit):
    _, kepler = orbit
    with pytest.raises(ValueError, match="t_eval must lie in the run's span"):
        adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=1.0, t_eval=[0.5, 2.0])
    with pytest.raises(ValueError, match="t_eval must lie in the run's span"):
        adaptive.integrate(kepler.q0, kepler.v0, h=H, n_steps=10, t_eval=[0.5, 50.0])
    with pytest.raises(ValueError, match="sorted in the direction"):
        adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=1.0, t_eval=[0.5, 0.2])


# ------------------------------------------------------------------ dense output
def test_dense_output_between_steps_has_the_methods_order(orbit):
    """Gauss(2), order 4: the error at the midpoints of the steps falls 16x per halving."""
    e, kepler = orbit
    adaptive = gvi.AdaptiveIntegrator(kepler.system, GAUSS2, g=gvi.encounter_scaling([R], 1.5))
    errors = []
    for h in (0.05, 0.025):
        traj = adaptive.integrate(kepler.q0, kepler.v0, h=h, t_final=2 * PERIOD, dense_output=True)
        mid = 0.5 * (traj.t[1:] + traj.t[:-1])
        errors.append(np.abs(traj.sol(mid) - kepler.exact(mid)).max())
        velocity = np.abs(traj.sol.velocity(mid) - kepler_velocity(mid, e)).max()
        assert velocity < 100 * errors[-1] / (1 - e)  # the derivative: order 4 as well
    assert 12 < errors[0] / errors[1] < 20  # measured 16.0
    assert errors[1] < 1e-6


# ------------------------------------------------------------------ events
EVENTS = {
    "pericentre": ([gvi.Event(RADIAL, direction=1)], [np.arange(4) * PERIOD]),
    "apocentre": ([gvi.Event(RADIAL, direction=-1)], [(np.arange(3) + 0.5) * PERIOD]),
    "both": (
        [gvi.Event(RADIAL, direction=1), gvi.Event(RADIAL, direction=-1), gvi.Event(RADIAL)],
        [np.arange(4) * PERIOD, (np.arange(3) + 0.5) * PERIOD, np.arange(7) * PERIOD / 2],
    ),
    "exact": ([gvi.Event(RADIAL, direction=1, exact=True)], [np.arange(4) * PERIOD]),
}


@pytest.mark.parametrize("which", list(EVENTS))
def test_event_times_are_the_closed_form_ones(adaptive, orbit, which):
    e, kepler = orbit
    events, expected = EVENTS[which]
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=T_FINAL, events=events)
    assert traj.status == 0 and traj.t[-1] == T_FINAL
    for found, times, q in zip(traj.t_events, expected, traj.q_events, strict=True):
        assert found.shape == times.shape
        assert np.abs(found - times).max() < 1e-10
        assert np.abs(q - kepler.exact(times)).max() < 1e-9


def test_a_terminal_event_ends_the_run_there_and_soon(adaptive, orbit):
    _, kepler = orbit
    second_apocentre = 1.5 * PERIOD
    event = gvi.Event(RADIAL, direction=-1, terminal=2)
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=100 * PERIOD, events=event)
    assert traj.status == gvi.RunStatus.TERMINATED and traj.success
    assert abs(traj.t[-1] - second_apocentre) < 1e-10 and traj.t[-1] == traj.t_events[0][-1]
    np.testing.assert_array_equal(traj.q[-1], traj.q_events[0][-1])
    assert np.all(np.diff(traj.t) > 0) and len(traj.tau) == len(traj.t)
    assert np.all(np.diff(traj.tau) > 0) and traj.tau[-1] - traj.tau[-2] <= H
    # 100 periods take about 18 000 steps: the run is watched in chunks and stops early
    assert traj.n_steps < 4500
    # a terminal event in a run of n_steps, with t_eval: rows only up to the event
    times = np.linspace(0.0, 3 * PERIOD, 31)
    cut = adaptive.integrate(kepler.q0, kepler.v0, h=H, n_steps=5000, events=event, t_eval=times)
    assert cut.status == gvi.RunStatus.TERMINATED
    np.testing.assert_array_equal(cut.t, times[times <= traj.t[-1]])
    assert np.abs(cut.q - kepler.exact(cut.t)).max() < 1e-9


# ------------------------------------------------------------------ save_every
@pytest.mark.parametrize("run", [{"t_final": T_FINAL}, {"n_steps": 301}], ids=["t_final", "n"])
def test_save_every_keeps_every_kth_row_bit_for_bit(adaptive, orbit, run):
    _, kepler = orbit
    every = adaptive.integrate(kepler.q0, kepler.v0, h=H, **run)
    sparse = adaptive.integrate(kepler.q0, kepler.v0, h=H, save_every=7, **run)
    rows = np.append(np.arange(0, len(every), 7), len(every) - 1)
    rows = np.unique(rows)
    for name in ("t", "q", "p", "tau", "clock_momentum"):
        np.testing.assert_array_equal(getattr(sparse, name), getattr(every, name)[rows])
    assert sparse.n_steps == every.n_steps
    assert np.abs(every.q - kepler.exact(every.t)).max() < 1e-9
    for option in ({"dense_output": True}, {"events": RADIAL}, {"t_eval": [1.0]}):
        with pytest.raises(ValueError, match="needs save_every=1"):
            adaptive.integrate(kepler.q0, kepler.v0, h=H, save_every=7, **run, **option)


# ------------------------------------------------------------------ backwards, t_span
def test_a_backward_run_returns_to_the_start(adaptive, orbit):
    _, kepler = orbit
    ahead = adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=T_FINAL)
    back = adaptive.integrate(
        ahead.q[-1], p0=ahead.p[-1], t0=T_FINAL, h=-H, t_final=-1.0,
        events=gvi.Event(RADIAL, direction=-1), t_eval=[T_FINAL, 2.0, 0.0, -1.0],
    )  # fmt: skip
    assert back.status == 0 and back.sol.t[-1] == -1.0
    np.testing.assert_array_equal(back.t, [T_FINAL, 2.0, 0.0, -1.0])
    np.testing.assert_allclose(back.q[2], kepler.q0, rtol=0, atol=1e-9)
    assert np.abs(back.q - kepler.exact(back.t)).max() < 1e-9
    assert np.all(np.diff(back.tau) < 0) and np.all(np.diff(back.sol.t) < 0)
    # backwards in time, r r' falls through 0 at the pericentres
    pericentres = [3 * PERIOD, 2 * PERIOD, PERIOD, 0.0]
    np.testing.assert_allclose(back.t_events[0], pericentres, rtol=0, atol=1e-10)
    with pytest.raises(ValueError, match="before t0"):
        adaptive.integrate(kepler.q0, kepler.v0, h=-H, t_final=1.0)
    # n steps backwards from the end retrace the run to the method's accuracy
    steps = adaptive.integrate(ahead.q[-1], p0=ahead.p[-1], t0=T_FINAL, h=-H, n_steps=120)
    assert steps.t[-1] < T_FINAL and np.all(np.diff(steps.t) < 0)
    assert np.abs(steps.q - kepler.exact(steps.t)).max() < 1e-9


def test_t_span_is_t0_and_t_final(adaptive):
    kepler = gravitation.kepler(0.7)
    q0, v0 = kepler.exact(np.array([1.0]))[0], kepler_velocity(np.array([1.0]), 0.7)[0]
    spanned = adaptive.integrate(q0, v0, h=H, t_span=(1.0, 4.0))
    direct = adaptive.integrate(q0, v0, h=H, t0=1.0, t_final=4.0)
    np.testing.assert_array_equal(spanned.q, direct.q)
    assert spanned.t[0] == 1.0 and spanned.t[-1] == 4.0
    assert np.abs(spanned.q - kepler.exact(spanned.t)).max() < 1e-9
    with pytest.raises(ValueError, match="not both"):
        adaptive.integrate(q0, v0, h=H, t_span=(1.0, 4.0), t_final=4.0)
    with pytest.raises(ValueError, match="disagree"):
        adaptive.integrate(q0, v0, h=H, t_span=(1.0, 4.0), t0=2.0)


# ------------------------------------------------------------------ Ctrl-C, progress, failure
def test_ctrl_c_keeps_the_states_so_far(adaptive, monkeypatch):
    kepler = gravitation.kepler(0.5)
    inner = adaptive.integrator
    original = inner.integrate
    calls = []

    def interrupted_third_chunk(*args, **kwargs):
        calls.append(1)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return original(*args, **kwargs)

    monkeypatch.setattr(inner, "integrate", interrupted_third_chunk)
    with pytest.warns(gvi.RunFailureWarning, match="interrupted"):
        traj = adaptive.integrate(
            kepler.q0, kepler.v0, h=H, t_final=50 * PERIOD, dense_output=True,
            events=gvi.Event(RADIAL, direction=1),
        )  # fmt: skip
    assert traj.status == gvi.RunStatus.INTERRUPTED and not traj.success
    assert traj.n_steps == 256 + 1024  # the two chunks before Ctrl-C
    assert f"t = {traj.t[-1]:.6g}" in traj.message
    assert np.abs(traj.q - kepler.exact(traj.t)).max() < 1e-9
    found = traj.t_events[0]
    np.testing.assert_allclose(found, np.arange(found.size) * PERIOD, atol=1e-10)


def test_progress_bar_and_failure_with_events(adaptive, capsys):
    kepler = gravitation.kepler(0.9)
    adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=T_FINAL, progress=True)
    assert "%|" in capsys.readouterr().err  # a bar was drawn
    adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=T_FINAL, progress=False)
    assert capsys.readouterr().err == ""
    with pytest.raises(TypeError, match="progress must be"):
        adaptive.integrate(kepler.q0, kepler.v0, h=H, t_final=1.0, progress="yes")
    # h = 1.5 fails at the first pericentre passage after one step: the partial run has its
    # dense output and events
    with pytest.warns(gvi.RunFailureWarning, match="physical time"):
        failed = adaptive.integrate(kepler.q0, kepler.v0, h=1.5, n_steps=40, events=RADIAL)
    assert not failed.success and failed.sol is not None and len(failed.t_events) == 1


# ------------------------------------------------------------------ ensembles, step
@pytest.mark.parametrize("executor", [None, ThreadPoolExecutor, ProcessPoolExecutor])
def test_integrate_many_equals_one_run_per_member(adaptive, executor):
    eccentricities = (0.5, 0.7, 0.9)
    problems = [gravitation.kepler(e) for e in eccentricities]
    q0s = np.array([k.q0 for k in problems])
    v0s = np.array([k.v0 for k in problems])
    times = np.linspace(0.0, PERIOD, 9)
    pool = executor(2) if executor else None
    try:
        ensemble = adaptive.integrate_many(
            q0s, v0s, h=H, t_final=PERIOD, t_eval=times, executor=pool, workers=2
        )
    finally:
        if pool is not None:
            pool.shutdown()
    assert ensemble.q.shape == (3, 9, 2) and ensemble.success.all()
    for i, kepler in enumerate(problems):
        member = ensemble[i]
        assert isinstance(member, gvi.AdaptiveTrajectory)
        one = adaptive.integrate(q0s[i], v0s[i], h=H, t_final=PERIOD, t_eval=times)
        np.testing.assert_array_equal(member.q, one.q)
        assert np.abs(member.q - kepler.exact(times)).max() < 1e-9


def test_step_is_one_step_of_the_run(adaptive):
    kepler = gravitation.kepler(0.9)
    run = adaptive.integrate(kepler.q0, kepler.v0, h=H, n_steps=20)
    energy = float(run.energy()[0])
    q, p, t = kepler.q0, kepler.v0, 0.0
    for k in range(1, 21):
        q, p, t = adaptive.step(q, p, H, t, energy=energy)
        np.testing.assert_allclose(q, run.q[k], rtol=0, atol=1e-13)
        np.testing.assert_allclose(t, run.t[k], rtol=0, atol=1e-13)
    back = adaptive.step(q, p, -H, t, energy=energy)
    np.testing.assert_allclose(back[0], run.q[19], rtol=0, atol=1e-13)


def test_combinations_without_meaning_say_why(adaptive, orbit):
    _, problem = orbit
    q0, v0 = problem.q0, problem.v0
    # no constraints under the Poincaré transformation: nothing to project onto
    with pytest.raises(ValueError, match="project=True needs a system with constraints"):
        adaptive.integrate(q0, v0, h=H, n_steps=3, project=True)
    # a system with contacts: impacts change H, which the transformation keeps fixed
    floor = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - 1 / R, [x, y], [vx, vy], contacts=[gvi.Contact(gap=y + 2.0)]
    )
    with pytest.raises(ValueError, match="impact"):
        gvi.AdaptiveIntegrator(floor, gvi.Galerkin(2, gvi.gauss_legendre(2)), g=R**1.5)


def test_stream_chunks_join_to_one_run(adaptive, orbit):
    _, problem = orbit
    run = dict(h=H, n_steps=600, save_every=3)
    whole = adaptive.integrate(problem.q0, problem.v0, **run)
    chunks = list(adaptive.stream(problem.q0, problem.v0, chunk_steps=150, **run))
    assert [len(c) for c in chunks] == [51, 50, 50, 50]
    assert all(isinstance(c, gvi.AdaptiveTrajectory) for c in chunks)
    # the first chunk is a run of its own, bit for bit; the joins restart the iteration
    first = adaptive.integrate(problem.q0, problem.v0, h=H, n_steps=150, save_every=3)
    np.testing.assert_array_equal(chunks[0].q, first.q)
    np.testing.assert_array_equal(chunks[0].t, first.t)
    joined_t = np.concatenate([c.t for c in chunks])
    joined_q = np.concatenate([c.q for c in chunks])
    np.testing.assert_allclose(joined_t, whole.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(joined_q, whole.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(np.concatenate([c.tau for c in chunks]), whole.tau, atol=1e-12)
    # physical time and the orbit: the stream's last row is on the exact orbit
    exact = problem.exact(np.array([chunks[-1].t[-1]]))
    assert np.abs(chunks[-1].q[-1] - exact[0]).max() < 1e-8
