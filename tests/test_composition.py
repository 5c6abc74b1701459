"""Every smooth model kind takes every run option: each cell of kind x option checks a property.

The kinds cover every time loop (``Integrator.kernel_path``): plain (the
separable stage-form loop), forced (velocity-dependent damping: the general
Newton loop), time-dependent, constrained, varying mass (Gauss(3), the
fixed-point loop), banded (a 12-mass FPU chain with banded storage), linear,
explicit (Störmer–Verlet) and the NumPy reference backend. Systems with
contacts and adaptive runs have their own matrices
(``test_composition_contacts.py``, ``test_composition_adaptive.py``).

Accuracy cells compare with the same method at ``h / 8``: the method of order
``p`` has global error :math:`\\approx C h^p` (:math:`p = 2s` for ``Galerkin(s)``),
so the tolerance is ``C h^p`` with ``C = ACCURACY`` for the implicit kinds (their
measured constants lie 3 to 30 times below it) and ``ACCURACY_EXPLICIT`` for
Störmer–Verlet; the reference's own error is :math:`8^{-p}` of that. Event times
are compared with a run at half the step: their difference is
:math:`(1 - 2^{-p})` times the error of the run at the larger step.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.run import chunks, smooth

t_sym = sp.Symbol("t")
q, v, c = sp.symbols("q v c")
x, y, vx, vy = sp.symbols("x y vx vy")

#: error constant C of t_eval rows and dense output (error < C h**order against the h/8
#: reference): the measured constants are 6e-4 to 6e-3 for the kinds of order 4 and 6
ACCURACY = 0.02
#: the explicit (Störmer–Verlet) kind's constant: measured 0.05 on the Duffing oscillator
ACCURACY_EXPLICIT = 0.5
#: the momenta's constant relative to the positions': they come from the interpolant's
#: derivative through M(q) (measured 6e-3 h^6 for the double pendulum, 3e-3 h^6 in q)
MOMENTA = 10.0
#: a forward run followed by the backward run returns to its start to this (round-off)
ROUND_TRIP = 1e-13
#: event times against the reference run at half the step
EVENT_TOLERANCE = 1e-10
N_CHAIN = 12


def _pendulum() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])


def _chain_start() -> tuple[np.ndarray, np.ndarray]:
    """The chain's fastest normal mode (period about 3.2), displaced by 0.1."""
    j = np.arange(1, N_CHAIN + 1)
    return -0.1 * np.sin(N_CHAIN * np.pi * j / (N_CHAIN + 1)), np.zeros(N_CHAIN)


@dataclass(frozen=True)
class Kind:
    """A model kind of the matrix and what its cells need.

    The event coordinate ``q[watch]`` starts at rest above ``centre`` and
    oscillates about it: in its first period it crosses the centre going
    down, passes one minimum or more, and crosses it going up (the terminal
    event), all before t = 12.
    """

    build: Callable[[], gvi.Integrator]
    q0: tuple[float, ...]
    v0: tuple[float, ...]
    path: str
    order: int
    h: float
    n_steps: int
    reversible: bool
    #: a step size at which the run fails, or the reason why none does
    failing_h: float | str
    #: step size at which event times agree with the h/2 run's to EVENT_TOLERANCE
    event_h: float
    watch: int = 0
    centre: float = 0.0


KINDS: dict[str, Kind] = {
    "plain": Kind(
        lambda: gvi.Integrator(_pendulum(), gvi.Galerkin(2)),
        (1.0,), (0.0,), "separable", 4, 0.1, 20, True, 5.0, 1e-2,
    ),
    "forced": Kind(
        lambda: gvi.Integrator(
            gvi.LagrangianSystem(
                v**2 / 2 + sp.cos(q), [q], [v], params={c: 0.2}, forces=[-c * v]
            ),
            gvi.Galerkin(2),
        ),
        (1.0,), (0.0,), "newton", 4, 0.1, 20, False, 5.0, 1e-2,
    ),
    "time-dependent": Kind(
        lambda: gvi.Integrator(
            gvi.LagrangianSystem(
                v**2 / 2 + (1 + sp.sin(t_sym) / 2) * sp.cos(q), [q], [v], t=t_sym
            ),
            gvi.Galerkin(2),
        ),
        (1.0,), (0.0,), "separable", 4, 0.1, 20, False, 5.0, 1e-2,
    ),
    "constrained": Kind(
        lambda: gvi.Integrator(
            gvi.LagrangianSystem(
                (vx**2 + vy**2) / 2 - y, [x, y], [vx, vy], constraints=[(x**2 + y**2 - 1) / 2]
            ),
            gvi.Galerkin(2),
        ),
        (np.sin(1.0), -np.cos(1.0)), (0.0, 0.0), "constrained", 4, 0.1, 20, True, 5.0, 5e-3,
    ),
    "varying mass": Kind(
        lambda: gvi.Integrator(
            problems.double_pendulum().system, gvi.Galerkin(3, gvi.gauss_legendre(3))
        ),
        (1.0, 0.5), (0.0, 0.0), "varying_mass", 6, 0.1, 20, True, 5.0, 1e-2,
    ),
    "banded": Kind(
        lambda: gvi.Integrator(problems.spring_chain(N_CHAIN, beta=1.0).system, gvi.Galerkin(2)),
        tuple(_chain_start()[0]), tuple(_chain_start()[1]), "separable", 4, 0.1, 20, True,
        5.0, 5e-3, watch=5,
    ),
    "linear": Kind(
        lambda: gvi.Integrator(
            gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v]), gvi.Galerkin(2)
        ),
        (1.0,), (0.0,), "linear", 4, 0.1, 20, True,
        "the linear loop solves each step's linear equations with one LU factorisation: "
        "nothing iterates, so no step size makes it fail (an unstable one only grows)",
        1e-2,
    ),
    "explicit": Kind(
        lambda: gvi.Integrator(
            gvi.LagrangianSystem(v**2 / 2 - q**2 / 2 - q**4 / 4, [q], [v]), gvi.Galerkin(1)
        ),
        (1.0,), (0.0,), "explicit", 2, 0.05, 40, True, 3.0, 1e-5,
    ),
    "numpy reference": Kind(
        lambda: gvi.Integrator(_pendulum(), gvi.Galerkin(2), backend="numpy"),
        (1.0,), (0.0,), "newton", 4, 0.1, 20, True, 5.0, 1e-2,
    ),
}  # fmt: skip
NAMES = list(KINDS)


@cache
def _integrator(name: str) -> gvi.Integrator:
    return KINDS[name].build()


def _run(name: str, **options) -> gvi.Trajectory:
    kind = KINDS[name]
    run = dict(h=kind.h, n_steps=kind.n_steps) | options
    return _integrator(name).integrate(kind.q0, kind.v0, **run)


@cache
def _fine(name: str, t0: float = 0.0, sign: float = 1.0) -> gvi.Trajectory:
    """The reference: the same method at h / 8 over the same span (every 8th row on the grid)."""
    kind = KINDS[name]
    return _run(name, h=sign * kind.h / 8, n_steps=8 * kind.n_steps, t0=t0)


def _tolerance(name: str) -> float:
    kind = KINDS[name]
    constant = ACCURACY_EXPLICIT if kind.path == "explicit" else ACCURACY
    return constant * kind.h**kind.order


def _assert_same_rows(a: gvi.Trajectory, b: gvi.Trajectory) -> None:
    np.testing.assert_array_equal(a.t, b.t)
    np.testing.assert_array_equal(a.q, b.q)
    np.testing.assert_array_equal(a.p, b.p)


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of 5 steps: a 20-step run goes through four, whatever the machine's speed."""
    monkeypatch.setattr(chunks, "FIRST_CHUNK", 5)
    monkeypatch.setattr(chunks, "MIN_CHUNK", 5)
    monkeypatch.setattr(chunks, "CHUNK_WORK", 1)
    monkeypatch.setattr(chunks, "JOIN", 1)


@pytest.mark.parametrize("name", NAMES)
def test_each_kind_runs_its_own_loop(name):
    integrator, kind = _integrator(name), KINDS[name]
    assert integrator.kernel_path == kind.path
    assert integrator.backend == ("numpy" if name == "numpy reference" else "numba")
    if integrator.backend == "numba":
        assert integrator.uses_banded_storage == (name == "banded")
    traj = _run(name)
    assert traj.status == gvi.RunStatus.COMPLETED and len(traj) == kind.n_steps + 1


@pytest.mark.parametrize("name", NAMES)
@pytest.mark.parametrize("k", [3, 4])
def test_save_every_keeps_every_kth_row_bit_for_bit(name, k):
    # the varying-mass kind hands over to Newton at step 14 (h = 0.1): the rows after it
    # are Newton's from the state at step 14, whatever save_every is
    _assert_every_kth_row(_run(name), _run(name, save_every=k), k)


@pytest.mark.parametrize("k", [3, 4])
def test_save_every_of_the_fixed_point_loop_without_hand_over_is_bitwise(k):
    # h = 0.05: the fixed-point iteration contracts on every step, no hand-over to Newton
    full = _run("varying mass", h=0.05, n_steps=40)
    _assert_every_kth_row(full, _run("varying mass", h=0.05, n_steps=40, save_every=k), k)


def _assert_every_kth_row(full: gvi.Trajectory, sparse: gvi.Trajectory, k: int) -> None:
    keep = np.zeros(len(full), dtype=bool)
    keep[::k] = True
    keep[-1] = True  # the last row always (n_steps = 20, 40: not a multiple of 3)
    np.testing.assert_array_equal(sparse.t, full.t[keep])
    np.testing.assert_array_equal(sparse.q, full.q[keep])
    np.testing.assert_array_equal(sparse.p, full.p[keep])


@pytest.mark.parametrize("name", NAMES)
def test_t_span_lands_on_its_end_with_the_resolved_step(name):
    kind = KINDS[name]
    t0, t1 = 0.5, 0.5 + kind.h * kind.n_steps * 0.93  # not a whole number of steps
    n = int(np.ceil((t1 - t0) / kind.h))
    spanned = _run(name, n_steps=None, t_span=(t0, t1))
    stepped = _run(name, h=(t1 - t0) / n, n_steps=n, t0=t0)
    assert len(spanned) == n + 1 and spanned.t[0] == t0
    assert spanned.t[-1] == t1  # exactly: the last time is the span's end
    _assert_same_rows(spanned, stepped)


def _between_steps(name: str) -> np.ndarray:
    """Times off the step grid and on the h/8 reference's: 3/8 and 5/8 of each step."""
    kind = KINDS[name]
    k = np.arange(kind.n_steps)
    return np.sort(np.concatenate([(k + 3 / 8) * kind.h, (k + 5 / 8) * kind.h]))


def _reference_rows(name: str, times: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    fine = _fine(name)
    rows = np.rint(times / (KINDS[name].h / 8)).astype(int)
    np.testing.assert_allclose(fine.t[rows], times, rtol=0, atol=1e-13)
    return fine.q[rows], fine.p[rows]


@pytest.mark.parametrize("name", NAMES)
def test_t_eval_rows_match_the_fine_reference_to_the_methods_order(name):
    times = _between_steps(name)
    traj = _run(name, t_eval=times)
    np.testing.assert_array_equal(traj.t, times)
    q_ref, p_ref = _reference_rows(name, times)
    tol = _tolerance(name)
    np.testing.assert_allclose(traj.q, q_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(traj.p, p_ref, rtol=0, atol=MOMENTA * tol)
    assert traj.sol is not None


@pytest.mark.parametrize("name", NAMES)
def test_dense_output_interpolates_the_nodes_and_matches_the_fine_run(name):
    traj = _run(name, dense_output=True)
    _assert_same_rows(traj, _run(name))  # dense output changes no row
    np.testing.assert_array_equal(traj.sol(traj.t), traj.q)
    times = _between_steps(name)
    q_ref, p_ref = _reference_rows(name, times)
    tol = _tolerance(name)
    np.testing.assert_allclose(traj.sol(times), q_ref, rtol=0, atol=tol)
    np.testing.assert_allclose(traj.sol.momentum(times), p_ref, rtol=0, atol=MOMENTA * tol)


def _events(name: str) -> list[gvi.Event]:
    """Crossings of the centre both ways, the minima, and (terminal) the first upward crossing."""
    kind, system = KINDS[name], _integrator(name).system
    g = system.q[kind.watch] - kind.centre
    return [
        gvi.Event(g),
        gvi.Event(system.v[kind.watch], direction=1.0),
        gvi.Event(g, terminal=True, direction=1.0),
    ]


@pytest.mark.parametrize("name", NAMES)
def test_several_events_and_a_terminal_one_match_a_run_at_half_the_step(name):
    kind = KINDS[name]
    span = 12.0
    runs = [
        _run(name, h=h, n_steps=int(round(span / h)), events=_events(name))
        for h in (kind.event_h, kind.event_h / 2)
    ]
    for traj in runs:
        assert traj.status == gvi.RunStatus.TERMINATED
        down_up, minima, terminal = traj.t_events
        # the double pendulum's first angle has two minima before it comes back up
        assert len(down_up) == 2 and len(minima) >= 1 and len(terminal) == 1
        assert down_up[0] < minima[0] < down_up[1] == terminal[0] == traj.t[-1]
        np.testing.assert_allclose(traj.q_events[0][:, kind.watch], kind.centre, rtol=0, atol=1e-12)
    for coarse, fine in zip(runs[0].t_events, runs[1].t_events, strict=True):
        np.testing.assert_allclose(coarse, fine, rtol=0, atol=EVENT_TOLERANCE)


@pytest.mark.parametrize("name", NAMES)
def test_progress_bar_changes_no_row(name, small_chunks, capsys):
    shown = _run(name, progress=True)
    assert "step" in capsys.readouterr().err
    hidden = _run(name, progress=False)
    assert capsys.readouterr().err == ""
    _assert_same_rows(shown, hidden)
    assert shown.status == hidden.status == gvi.RunStatus.COMPLETED


@pytest.mark.parametrize("name", NAMES)
def test_ctrl_c_between_chunks_keeps_the_rows_so_far(name, small_chunks, monkeypatch):
    whole = _run(name)  # in chunks of 5 steps too
    calls = []
    original = smooth.run_once

    def interrupted(spec, segment):
        calls.append(segment.n_steps)
        if len(calls) == 3:
            raise KeyboardInterrupt
        return original(spec, segment)

    monkeypatch.setattr(smooth, "run_once", interrupted)
    with pytest.warns(gvi.RunFailureWarning, match="interrupt"):
        traj = _run(name)
    assert traj.status == gvi.RunStatus.INTERRUPTED and not traj.success
    assert len(traj) == 11  # the two chunks of 5 steps done before
    np.testing.assert_array_equal(traj.t, whole.t[:11])
    np.testing.assert_array_equal(traj.q, whole.q[:11])
    np.testing.assert_array_equal(traj.p, whole.p[:11])


def _failing(name: str):
    failing_h = KINDS[name].failing_h
    if isinstance(failing_h, str):
        return pytest.param(name, marks=pytest.mark.skip(reason=failing_h))
    return name


@pytest.mark.parametrize("name", [_failing(name) for name in NAMES])
def test_a_failing_run_warns_or_raises_with_the_rows_before(name):
    h = KINDS[name].failing_h
    with np.errstate(all="ignore"), pytest.warns(gvi.RunFailureWarning) as caught:
        warned = _run(name, h=h, n_steps=50)
    assert not warned.success and warned.status < 0 and len(warned) < 51
    step = len(warned) - 1  # the failing step's index: the rows before it are kept
    assert str(caught[0].message).startswith(f"step {step} ")
    with np.errstate(all="ignore"), pytest.raises(gvi.ConvergenceError) as raised:
        _run(name, h=h, n_steps=50, on_failure="raise")
    error = raised.value
    assert error.step == step and error.t == pytest.approx(step * h)
    _assert_same_rows(error.partial, warned)
    assert error.partial.status == warned.status


@pytest.mark.parametrize("name", NAMES)
def test_a_negative_step_runs_backwards(name):
    kind, integrator = KINDS[name], _integrator(name)
    forward = _run(name)
    t_end = forward.t[-1]
    if kind.reversible:
        back = integrator.integrate(
            forward.q[-1], p0=forward.p[-1], t0=t_end, h=-kind.h, n_steps=kind.n_steps
        )
        assert back.t[-1] == pytest.approx(0.0, abs=1e-14)
        np.testing.assert_allclose(back.q[-1], forward.q[0], rtol=0, atol=ROUND_TRIP)
        np.testing.assert_allclose(back.p[-1], forward.p[0], rtol=0, atol=ROUND_TRIP)
        np.testing.assert_allclose(back.q[::-1], forward.q, rtol=0, atol=ROUND_TRIP)
    else:  # dissipation or a clock: compare with the same method at h / 8, backwards
        back = _run(name, h=-kind.h, t0=t_end)
        fine = _fine(name, t0=t_end, sign=-1.0)
        np.testing.assert_allclose(back.t, fine.t[::8], rtol=0, atol=1e-13)
        assert back.t[-1] == pytest.approx(0.0, abs=1e-14) and np.all(np.diff(back.t) < 0)
        np.testing.assert_allclose(back.q, fine.q[::8], rtol=0, atol=_tolerance(name))


@pytest.mark.parametrize("name", NAMES)
def test_project_needs_constraints_and_projects_onto_them(name):
    kind, integrator = KINDS[name], _integrator(name)
    if not integrator.system.m:
        with pytest.raises(ValueError, match="project=True needs a system with constraints"):
            _run(name, project=True)
        return
    off = np.array(kind.q0) * 1.03 + [0.01, 0.0]  # off the circle by 0.03
    with pytest.raises(ValueError):
        integrator.integrate(off, kind.v0, h=kind.h, n_steps=kind.n_steps)
    traj = integrator.integrate(off, kind.v0, h=kind.h, n_steps=kind.n_steps, project=True)
    assert traj.success and np.abs(traj.constraint_residual()).max() < 1e-12
    assert np.linalg.norm(traj.q[0] - off) < 0.05  # a nearby point


@pytest.mark.parametrize("name", NAMES)
def test_integrate_many_members_equal_single_runs_bit_for_bit(name):
    kind, integrator = KINDS[name], _integrator(name)
    q0s = np.array(kind.q0) * np.array([[1.0], [0.9], [0.8]])
    if integrator.system.m:  # back onto the circle
        q0s /= np.linalg.norm(q0s, axis=1, keepdims=True)
    many = integrator.integrate_many(q0s, kind.v0, h=kind.h, n_steps=kind.n_steps, workers=2)
    assert len(many) == 3 and np.all(many.success)
    for q0, member in zip(q0s, many.trajectories, strict=True):
        single = integrator.integrate(q0, kind.v0, h=kind.h, n_steps=kind.n_steps)
        _assert_same_rows(member, single)


@pytest.mark.parametrize("name", NAMES)
def test_stream_chunks_joined_equal_one_run(name):
    kind, integrator = KINDS[name], _integrator(name)
    whole = _run(name)
    parts = list(integrator.stream(kind.q0, kind.v0, h=kind.h, n_steps=kind.n_steps, chunk_steps=6))
    steps = [6] * (kind.n_steps // 6) + [kind.n_steps % 6]
    assert [len(part) for part in parts] == [steps[0] + 1, *steps[1:]]
    _assert_same_rows(parts[0], _run(name, n_steps=6))  # the first chunk is a run of its own
    joined_t = np.concatenate([part.t for part in parts])
    np.testing.assert_allclose(joined_t, whole.t, rtol=0, atol=1e-14)
    # each chunk restarts the iteration: equal up to round-off at the joins (Integrator.stream)
    np.testing.assert_allclose(np.concatenate([p.q for p in parts]), whole.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(np.concatenate([p.p for p in parts]), whole.p, rtol=0, atol=1e-13)


@pytest.mark.parametrize("name", NAMES)
def test_step_equals_a_one_step_run_bit_for_bit(name):
    kind, integrator = KINDS[name], _integrator(name)
    start = _run(name, n_steps=3)
    t0 = start.t[2]
    q1, p1 = integrator.step(start.q[2], start.p[2], kind.h, t0=t0)
    one = integrator.integrate(start.q[2], p0=start.p[2], h=kind.h, n_steps=1, t0=t0)
    np.testing.assert_array_equal(q1, one.q[-1])
    np.testing.assert_array_equal(p1, one.p[-1])
    np.testing.assert_allclose(q1, start.q[3], rtol=0, atol=1e-13)  # the run's own next step
