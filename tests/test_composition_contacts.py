"""Systems with contacts take every run option: each cell checks a property.

The bouncing ball under gravity has closed-form impact times and states, and
the Galerkin methods of degree >= 2 reproduce its parabolic flights to
round-off, so its results are compared with the closed form at 1e-10. The
pendulum against an elastic wall (Jacobi elliptic functions) checks the
method's accuracy where the flights are not polynomials.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np
import pytest
import sympy as sp
from scipy.special import ellipj, ellipk

import galerkin_vi as gvi
from galerkin_vi.contact import runs
from galerkin_vi.run.piecewise import PiecewiseDenseOutput, smooth_segments

G = 9.81
y, vy, g = sp.symbols("y vy g")
T1 = np.sqrt(2 / G)  # the first impact of the ball dropped from rest at height 1


def _ball(e: float, friction: float = 0.0) -> gvi.LagrangianSystem:
    slip = None if friction == 0.0 else [vy]
    contact = gvi.Contact(y, restitution=e, friction=friction, slip=slip)
    return gvi.LagrangianSystem(vy**2 / 2 - g * y, [y], [vy], params={g: G}, contacts=[contact])


def _impact_times(e: float, count: int) -> np.ndarray:
    """t_k = t_1 (1 + 2 e + ... + 2 e^(k-1)) for the ball dropped from height 1 at rest."""
    return T1 * (1 + 2 * np.concatenate(([0.0], np.cumsum(e ** np.arange(1, count)))))


def _ball_exact(e: float, t) -> tuple[np.ndarray, np.ndarray]:
    """Height and velocity of the ball at t, right-continuous at the impacts."""
    t = np.asarray(t, dtype=float)
    hits = _impact_times(e, 60)
    k = np.searchsorted(hits, t, side="right")  # impacts at or before t
    start = np.where(k == 0, 0.0, hits[np.maximum(k - 1, 0)])
    speed = np.where(k == 0, 0.0, e**k * G * T1)
    height = np.where(k == 0, 1.0, 0.0)
    s = t - start
    return height + speed * s - G * s**2 / 2, speed - G * s


q, v = sp.symbols("q v")
WALL = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v], contacts=[gvi.Contact(q, 1.0)])


def _wall_exact(t) -> tuple[np.ndarray, np.ndarray]:
    """The pendulum released at 1 rad from rest against an elastic wall at 0: |theta_free|."""
    k = np.sin(0.5)
    sn, cn, _, _ = ellipj(ellipk(k * k) - np.asarray(t, dtype=float), k * k)
    theta = 2 * np.arcsin(k * sn)
    return np.abs(theta), np.sign(theta) * (-2 * k * cn)


#: (name, system, degree, q0, v0, h, n_steps, exact, tolerance of positions and velocities)
MODELS = {
    "ball e=1": (_ball(1.0), 3, 1e-2, 300, lambda t: _ball_exact(1.0, t), 1e-10),
    "ball e=0.8": (_ball(0.8), 2, 1e-2, 300, lambda t: _ball_exact(0.8, t), 1e-10),
    # order 6 at h = 0.05: measured 2e-9 in positions and velocities over two impacts
    "wall pendulum": (WALL, 3, 0.05, 160, _wall_exact, 1e-7),
}
START = ([1.0], [0.0])


def _run(name: str, **options):
    system, degree, h, n_steps, _, _ = MODELS[name]
    integrator = gvi.Integrator(system, gvi.Galerkin(degree))
    return integrator.integrate(*START, h=h, n_steps=n_steps, **options)


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("k", [3, 7])
def test_save_every_keeps_every_kth_grid_row_bit_for_bit(name, k):
    full = _run(name)
    sparse = _run(name, save_every=k)
    impact_times = np.array([i.t for i in full.impacts])
    assert len(impact_times) >= 2
    h, t0 = MODELS[name][2], 0.0
    grid = ~np.isin(full.t, impact_times)
    keep = grid & (np.round((full.t - t0) / h).astype(int) % k == 0)
    keep[-1] = True
    np.testing.assert_array_equal(sparse.t, full.t[keep])
    np.testing.assert_array_equal(sparse.q, full.q[keep])
    np.testing.assert_array_equal(sparse.p, full.p[keep])
    assert [i.t for i in sparse.impacts] == list(impact_times)
    assert sparse.status == full.status == gvi.RunStatus.COMPLETED


@pytest.mark.parametrize("name", list(MODELS))
def test_t_eval_rows_are_the_closed_form_across_impacts(name):
    *_, exact, tol = MODELS[name]
    span = MODELS[name][2] * MODELS[name][3]
    full = _run(name)
    hits = [i.t for i in full.impacts]
    # random times, the run's own impact times (right-continuous: the state after) and the ends
    times = np.sort(
        np.concatenate([np.random.default_rng(1).uniform(0, span, 40), hits, [0, span]])
    )
    traj = _run(name, t_eval=times)
    np.testing.assert_array_equal(traj.t, times)
    q_exact, v_exact = exact(times)
    # at a hit the closed form after the impact: the located time may lie an ulp before
    # the closed-form one, where the closed form is still before the impact
    at_hit = np.isin(times, hits)
    v_exact[at_hit] = exact(times[at_hit] + 1e-12)[1]
    np.testing.assert_allclose(traj.q[:, 0], q_exact, rtol=0, atol=tol)
    # p = v for these Lagrangians: the post-impact velocity at the impacts
    np.testing.assert_allclose(traj.p[:, 0], v_exact, rtol=0, atol=10 * tol)
    after = full.p[[int(np.flatnonzero(full.t == t)[1]) for t in hits]]
    np.testing.assert_allclose(traj.p[np.isin(times, hits)], after, rtol=0, atol=1e-13)
    assert traj.sol is not None and [i.t for i in traj.impacts] == hits


@pytest.mark.parametrize("name", list(MODELS))
def test_dense_output_is_piecewise_and_right_continuous_at_impacts(name):
    *_, exact, tol = MODELS[name]
    traj = _run(name, dense_output=True)
    sol = traj.sol
    assert isinstance(sol, PiecewiseDenseOutput)
    hits = np.array([i.t for i in traj.impacts])
    np.testing.assert_array_equal(sol.breakpoints, hits)
    # between the steps (midpoints of the grid intervals)
    h = MODELS[name][2]
    mid = (np.arange(MODELS[name][3]) + 0.5) * h
    q_exact, v_exact = exact(mid)
    np.testing.assert_allclose(sol(mid)[:, 0], q_exact, rtol=0, atol=tol)
    np.testing.assert_allclose(sol.velocity(mid)[:, 0], v_exact, rtol=0, atol=10 * tol)
    for t_hit, impact in zip(hits, traj.impacts, strict=True):
        before, after = impact.normal_velocity
        assert sol.velocity(t_hit)[0] == pytest.approx(after, abs=1e-12)  # right-continuous
        assert sol.velocity(t_hit - 1e-9)[0] == pytest.approx(before, abs=1e-7)
        assert abs(sol(t_hit)[0]) < 1e-12
    # vectorised, t-major, scalar in scalar out
    assert sol(mid).shape == (mid.size, 1) and sol(0.5).shape == (1,)
    np.testing.assert_allclose(sol.momentum(mid)[:, 0], sol.velocity(mid)[:, 0], rtol=1e-14)
    assert (sol.t_min, sol.t_max) == (0.0, traj.t[-1])
    with pytest.raises(ValueError, match="outside the run's span"):
        sol(traj.t[-1] + 1.0)


def _flight_crossings(e: float, c: float, count: int) -> tuple[np.ndarray, np.ndarray]:
    """Times the ball (dropped from 1) passes height c going down, and going up."""
    hits = _impact_times(e, count + 1)
    down = [np.sqrt(2 * (1 - c) / G)]
    up = []
    for k in range(1, count + 1):
        u = e**k * G * T1
        if u * u < 2 * G * c:  # the flight stays below c
            break
        root = np.sqrt(u * u - 2 * G * c)
        up.append(hits[k - 1] + (u - root) / G)
        down.append(hits[k - 1] + (u + root) / G)
    return np.array(down), np.array(up)


@pytest.mark.parametrize("e", [1.0, 0.8])
def test_events_on_each_segment_match_the_closed_form_to_1e_10(e):
    integrator = gvi.Integrator(_ball(e), gvi.Galerkin(3))
    apex = gvi.Event(vy, direction=-1.0)  # +/- only at the apexes: never across an impact
    height = 0.5
    traj = integrator.integrate(
        *START, h=1e-2, n_steps=300, events=[y - height, apex, lambda t, q, v: q[0] - 0.25]
    )
    hits = np.array([i.t for i in traj.impacts])
    np.testing.assert_allclose(hits, _impact_times(e, len(hits)), rtol=0, atol=1e-12)
    down, up = _flight_crossings(e, height, len(hits))
    both = np.sort(np.concatenate([down, up]))
    both = both[both <= traj.t[-1]]
    np.testing.assert_allclose(traj.t_events[0], both, rtol=0, atol=1e-10)
    # the start at rest counts (solve_ivp's convention: g = 0 there, then decreasing)
    apexes = np.concatenate(([0.0], hits + e ** np.arange(1, len(hits) + 1) * T1))
    np.testing.assert_allclose(traj.t_events[1], apexes[apexes <= traj.t[-1]], atol=1e-10)
    down4, up4 = _flight_crossings(e, 0.25, len(hits))
    quarter = np.sort(np.concatenate([down4, up4]))
    np.testing.assert_allclose(traj.t_events[2], quarter[quarter <= traj.t[-1]], atol=1e-10)
    np.testing.assert_allclose(traj.q_events[0][:, 0], height, rtol=0, atol=1e-12)
    assert traj.status == gvi.RunStatus.COMPLETED and len(traj) == 301 + 2 * len(hits)


@pytest.mark.parametrize("direction", [-1.0, 1.0])
def test_a_terminal_event_in_the_step_of_an_impact_comes_in_time_order(direction):
    # the impact at t1 = 0.4515 lies in step [0.4, 0.5]; y = 1e-3 is crossed just before
    # it going down and just after it going up
    integrator = gvi.Integrator(_ball(0.8), gvi.Galerkin(3))
    event = gvi.Event(y - 1e-3, terminal=True, direction=direction)
    traj = integrator.integrate(*START, h=0.1, n_steps=1000, events=event)
    down, up = _flight_crossings(0.8, 1e-3, 1)
    expected = down[0] if direction < 0 else up[0]
    assert 0.4 < expected < 0.5 and traj.status == gvi.RunStatus.TERMINATED
    np.testing.assert_allclose(traj.t_events[0], [expected], rtol=0, atol=1e-10)
    assert traj.t[-1] == traj.t_events[0][0] and traj.q[-1, 0] == pytest.approx(1e-3, abs=1e-12)
    if direction < 0:  # before the impact: not applied, not listed
        assert traj.impacts == [] and traj.p[-1, 0] < 0
        assert np.all(np.diff(traj.t) > 0)
    else:  # after it: listed, the run's rows in time order
        assert [i.t for i in traj.impacts] == pytest.approx([T1], abs=1e-12)
        assert traj.t_events[0][0] > traj.impacts[0].t and traj.p[-1, 0] > 0
    assert traj.sol.t_max == traj.t[-1]


def test_a_terminal_event_stops_the_run_soon_after_it(monkeypatch):
    integrator = gvi.Integrator(_ball(1.0), gvi.Galerkin(3))
    calls = []
    smooth = runs.integrate_smooth

    def counted(*args, **kwargs):
        traj = smooth(*args, **kwargs)
        calls.append(len(traj) - 1)  # the steps it took
        return traj

    monkeypatch.setattr(runs, "integrate_smooth", counted)
    event = gvi.Event(y - 0.5, terminal=3)
    traj = integrator.integrate(*START, h=1e-3, n_steps=1_000_000, events=event)
    down, up = _flight_crossings(1.0, 0.5, 2)
    third = np.sort(np.concatenate([down, up]))[2]
    assert traj.status == gvi.RunStatus.TERMINATED
    np.testing.assert_allclose(traj.t[-1], third, rtol=0, atol=1e-10)
    # steps computed: those up to the event and at most one more piece of 128 (the step
    # of the impact is taken twice: to the impact, then from it)
    assert third / 1e-3 < sum(calls) < third / 1e-3 + 128 + 3
    assert len(traj.impacts) == 1  # the impact after the event is not listed


@pytest.mark.parametrize("e", [1.0, 0.8])
def test_a_backward_run_returns_to_the_initial_state(e):
    integrator = gvi.Integrator(_ball(e), gvi.Galerkin(3))
    forward = integrator.integrate(*START, h=1e-2, n_steps=250)
    back = integrator.integrate(forward.q[-1], p0=forward.p[-1], t0=forward.t[-1], h=-1e-2,
                                n_steps=250, dense_output=True)  # fmt: skip
    assert back.status == gvi.RunStatus.COMPLETED and back.t[-1] == pytest.approx(0, abs=1e-13)
    np.testing.assert_allclose(back.q[-1], START[0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(back.p[-1], START[1], rtol=0, atol=1e-11)
    # the same impacts, met in reverse order, reported in physical time
    fw, bw = forward.impacts, back.impacts[::-1]
    assert len(fw) == len(bw) >= 2
    for a, b in zip(fw, bw, strict=True):
        assert b.t == pytest.approx(a.t, abs=1e-12)
        np.testing.assert_allclose(b.normal_velocity, a.normal_velocity, rtol=1e-10)
        assert b.energy_lost == pytest.approx(a.energy_lost, rel=1e-9, abs=1e-12)
    # its dense output is right-continuous in physical time: the velocity after the impact
    t_hit = bw[0].t
    assert back.sol.velocity(t_hit)[0] == pytest.approx(fw[0].normal_velocity[1], rel=1e-10)
    mid = np.linspace(0.0, forward.t[-1], 31)
    np.testing.assert_allclose(back.sol(mid)[:, 0], _ball_exact(e, mid)[0], rtol=0, atol=1e-10)
    assert back.sol.velocity(t_hit - 1e-9)[0] < 0 < back.sol.velocity(t_hit)[0]


@pytest.mark.parametrize(
    ("contact", "reason"),
    [((0.0, 0.0), "restitution e = 0"), ((0.5, 0.3), "friction mu = 0.3")],
)
def test_a_backward_run_without_an_inverse_impact_law_is_refused(contact, reason):
    integrator = gvi.Integrator(_ball(*contact), gvi.Galerkin(2))
    with pytest.raises(ValueError, match=f"h < 0 .*{reason}"):
        integrator.integrate(*START, h=-1e-2, n_steps=10)
    with pytest.raises(ValueError, match="time-stepping' does not run backwards"):
        gvi.Integrator(_ball(1.0), gvi.Galerkin(2)).integrate(
            *START, h=-1e-2, n_steps=10, contact_mode="time-stepping"
        )


def test_project_moves_q0_onto_the_constraint_and_the_run_bounces():
    # a pendulum of length 1 in Cartesian coordinates above a floor at y = -0.8
    x, yy, vx, vyy = sp.symbols("x yy vx vyy")
    system = gvi.LagrangianSystem(
        (vx**2 + vyy**2) / 2 - G * yy, [x, yy], [vx, vyy], constraints=[(x**2 + yy**2 - 1) / 2],
        contacts=[gvi.Contact(yy + 0.8, restitution=1.0)],
    )  # fmt: skip
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    q0 = [1.02, 0.01]  # off the circle
    with pytest.raises(ValueError):
        integrator.integrate(q0, [0.0, 0.0], h=1e-2, n_steps=200)
    traj = integrator.integrate(q0, [0.0, 0.0], h=1e-2, n_steps=200, project=True)
    assert np.abs(traj.constraint_residual()).max() < 1e-12
    assert traj.success and len(traj.impacts) >= 1
    assert np.abs(np.diff(traj.energy())).max() < 1e-6  # elastic impacts
    with pytest.raises(ValueError, match="project=True needs a system with constraints"):
        gvi.Integrator(_ball(1.0), gvi.Galerkin(2)).integrate(
            *START, h=1e-2, n_steps=10, project=True
        )


def test_t_span_and_progress_give_the_plain_runs_rows():
    integrator = gvi.Integrator(_ball(0.8), gvi.Galerkin(2))
    plain = integrator.integrate(*START, h=1e-2, n_steps=200)
    spanned = integrator.integrate(*START, h=1e-2, t_span=(0.0, 2.0))
    shown = integrator.integrate(*START, h=1e-2, n_steps=200, progress=True)
    for traj in (spanned, shown):
        np.testing.assert_array_equal(traj.t, plain.t)
        np.testing.assert_array_equal(traj.p, plain.p)
    with pytest.raises(TypeError, match="progress must be"):
        integrator.integrate(*START, h=1e-2, n_steps=2, progress="yes")


def test_ctrl_c_between_pieces_keeps_the_states_so_far(monkeypatch):
    integrator = gvi.Integrator(_ball(1.0), gvi.Galerkin(2))
    plain = integrator.integrate(*START, h=1e-2, n_steps=1000)
    smooth = runs.integrate_smooth
    calls = []

    def interrupted(*args, **kwargs):
        calls.append(1)
        if len(calls) == 6:
            raise KeyboardInterrupt
        return smooth(*args, **kwargs)

    monkeypatch.setattr(runs, "integrate_smooth", interrupted)
    for mode in ("warn", "raise"):
        calls.clear()
        with pytest.warns(gvi.RunFailureWarning, match="interrupted"):
            traj = integrator.integrate(
                *START, h=1e-2, n_steps=1000, on_failure=mode, dense_output=True
            )
        assert traj.status == gvi.RunStatus.INTERRUPTED and 10 < len(traj) < len(plain)
        np.testing.assert_array_equal(traj.t, plain.t[: len(traj)])
        np.testing.assert_array_equal(traj.p, plain.p[: len(traj)])
        assert traj.sol.t_max == traj.t[-1]
        assert [i.t for i in traj.impacts] == [i.t for i in plain.impacts if i.t <= traj.t[-1]]


def test_newtons_cradle_has_segments_of_one_node_at_the_impact_instant():
    x1, x2, x3, v1, v2, v3 = sp.symbols("x1 x2 x3 v1 v2 v3")
    touching = [gvi.Contact(x2 - x1 - 1, restitution=1.0), gvi.Contact(x3 - x2 - 1, 1.0)]
    system = gvi.LagrangianSystem((v1**2 + v2**2 + v3**2) / 2, [x1, x2, x3], [v1, v2, v3],
                                  contacts=touching)  # fmt: skip
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    times = np.array([0.0, 0.55, 1.0, 1.45, 2.5])
    traj = integrator.integrate([-1.0, 1.0, 2.0], [1.0, 0.0, 0.0], h=0.1, n_steps=25,
                                t_eval=times)  # fmt: skip
    lengths = [s.stop - s.start for s in smooth_segments(traj.sol.t)]
    assert 1 in lengths and len(lengths) == 4
    np.testing.assert_array_equal(traj.sol.breakpoints, [1.0])
    expected_v = [[1, 0, 0], [1, 0, 0], [0, 0, 1], [0, 0, 1], [0, 0, 1]]
    np.testing.assert_allclose(traj.p, expected_v, rtol=0, atol=1e-14)
    expected_q = [[-1, 1, 2], [-0.45, 1, 2], [0, 1, 2], [0, 1, 2.45], [0, 1, 3.5]]
    np.testing.assert_allclose(traj.q, expected_q, rtol=0, atol=1e-14)
    assert traj.sol.velocity(1.0 - 1e-12).tolist() == pytest.approx([1, 0, 0])


def test_events_and_dense_output_need_every_step_saved():
    integrator = gvi.Integrator(_ball(0.8), gvi.Galerkin(2))
    with pytest.raises(ValueError, match="events are located between consecutive steps"):
        integrator.integrate(*START, h=1e-2, n_steps=10, save_every=2, events=y)
    with pytest.raises(ValueError, match="t_eval must lie in the run's span"):
        integrator.integrate(*START, h=1e-2, n_steps=10, t_eval=[0.5])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        traj = integrator.integrate(*START, h=1e-2, n_steps=10, events=y, dense_output=True)
    assert traj.t_events[0].size == 0 and traj.sol is not None


def test_a_failed_step_keeps_the_rows_before_with_their_dense_output_and_events(monkeypatch):
    integrator = gvi.Integrator(_ball(1.0), gvi.Galerkin(2))
    plain = integrator.integrate(*START, h=1e-2, n_steps=400)
    smooth = runs.integrate_smooth
    calls = []

    def failing(*args, **kwargs):
        # the first smooth piece after the fifth call fails after its steps, as a loop
        # reports it (a piece ended by an impact is not a failed one)
        calls.append(1)
        traj = smooth(*args, **kwargs)
        if len(calls) >= 5 and traj.status == gvi.RunStatus.COMPLETED:
            partial = replace(traj, status=gvi.RunStatus.NO_CONVERGENCE, message="failed")
            raise gvi.ConvergenceError("failed", step=0, t=0.0, residual=1.0, partial=partial)
        return traj

    monkeypatch.setattr(runs, "integrate_smooth", failing)
    options = dict(h=1e-2, n_steps=400, events=y - 0.5, dense_output=True)
    calls.clear()
    with pytest.warns(gvi.RunFailureWarning, match="failed"):
        traj = integrator.integrate(*START, **options)
    assert traj.status == gvi.RunStatus.NO_CONVERGENCE and 10 < len(traj) < len(plain)
    np.testing.assert_array_equal(traj.p, plain.p[: len(traj)])
    assert traj.sol.t_max == traj.t[-1]
    down, up = _flight_crossings(1.0, 0.5, 3)
    crossings = np.sort(np.concatenate([down, up]))
    np.testing.assert_allclose(traj.t_events[0], crossings[crossings <= traj.t[-1]], atol=1e-10)
    calls.clear()
    with pytest.raises(gvi.ConvergenceError) as raised:
        integrator.integrate(*START, **options, on_failure="raise")
    np.testing.assert_array_equal(raised.value.partial.t, traj.t)
    assert raised.value.partial.sol is not None


def test_trajectory_dense_of_a_run_with_impacts_is_piecewise():
    # Trajectory.dense() on a run with impacts equals the run's own dense output:
    # one interpolant per smooth segment, never across an impact
    integrator = gvi.Integrator(_ball(0.8), gvi.Galerkin(3))
    traj = integrator.integrate(*START, h=1e-2, n_steps=300, dense_output=True)
    assert traj.impacts
    again = traj.dense()
    times = np.linspace(traj.t[0], traj.t[-1], 777)
    np.testing.assert_array_equal(again(times), traj.sol(times))
    np.testing.assert_array_equal(again.velocity(times), traj.sol.velocity(times))


def test_step_applies_the_impacts_inside_it():
    # a ball 1e-3 above the floor falling at speed 1: the floor is reached within the step
    integrator = gvi.Integrator(_ball(1.0), gvi.Galerkin(3))
    q1, p1 = integrator.step([1e-3], [-1.0], 0.01)
    one = integrator.integrate([1e-3], p0=[-1.0], h=0.01, n_steps=1)
    assert len(one.impacts) == 1
    np.testing.assert_array_equal(q1, one.q[-1])
    np.testing.assert_array_equal(p1, one.p[-1])
    assert q1[0] > 0.0 and p1[0] > 0.0  # bounced: above the floor, moving up


def test_stream_of_a_bouncing_ball_joins_to_one_run():
    integrator = gvi.Integrator(_ball(0.8), gvi.Galerkin(3))
    run = dict(h=1e-2, n_steps=400)
    whole = integrator.integrate(*START, **run)
    chunks = list(integrator.stream(*START, chunk_steps=100, **run))
    assert len(chunks) == 4
    impacts = [i.t for c in chunks for i in c.impacts]
    np.testing.assert_allclose(impacts, [i.t for i in whole.impacts], rtol=0, atol=1e-12)
    # the grid rows of the chunks are the whole run's (joins restart the iteration)
    grid = np.concatenate([c.t for c in chunks])
    keep = np.isin(np.round(whole.t / 1e-2, 6), np.round(grid / 1e-2, 6))
    np.testing.assert_allclose(np.concatenate([c.t for c in chunks]), whole.t[keep], atol=1e-12)
    np.testing.assert_allclose(np.concatenate([c.q for c in chunks]), whole.q[keep], atol=1e-10)
