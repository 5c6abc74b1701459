"""Long runs in chunks: the same result as one call, a progress bar, Ctrl-C that stops."""

from __future__ import annotations

import signal
import subprocess
import sys
import textwrap
import time
import warnings

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.run import chunks

q, v, k = sp.symbols("q v k")
PENDULUM = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])


@pytest.fixture
def small_chunks(monkeypatch):
    """Chunks of a few steps, whatever the machine's speed."""
    monkeypatch.setattr(chunks, "FIRST_CHUNK", 40)
    monkeypatch.setattr(chunks, "MIN_CHUNK", 50)
    monkeypatch.setattr(chunks, "CHUNK_WORK", 1)
    monkeypatch.setattr(chunks, "JOIN", 1)


def _run(save_every=1, **kw):
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(2))
    # a rotating pendulum: the angle passes many turns, across the joins
    return integrator.integrate([0.3], [2.5], h=0.1, n_steps=1000, save_every=save_every, **kw)


@pytest.mark.parametrize("save_every", [1, 7])
def test_a_chunked_run_equals_one_call_up_to_round_off(small_chunks, save_every, monkeypatch):
    chunked = _run(save_every)
    monkeypatch.setattr(chunks, "FIRST_CHUNK", 10**9)
    whole = _run(save_every)
    assert chunked.success and whole.success
    np.testing.assert_array_equal(chunked.t, whole.t)
    np.testing.assert_allclose(chunked.q, whole.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(chunked.p, whole.p, rtol=0, atol=1e-12)
    assert chunked.q[-1, 0] > 40.0  # continuous angle: six turns and more
    assert chunked.n_steps == whole.n_steps == 1000
    assert chunked.newton_iterations.shape == whole.newton_iterations.shape
    # each of the ~20 chunks starts its iteration cold: about one iteration more
    assert abs(chunked.total_newton_iterations - whole.total_newton_iterations) <= 40


def test_a_failure_in_a_later_chunk_counts_the_whole_runs_steps(small_chunks):
    blow_up = gvi.LagrangianSystem(v**2 / 2 + k * q**4, [q], [v], params={k: 1.0})
    integrator = gvi.Integrator(blow_up, gvi.Galerkin(2))
    with np.errstate(all="ignore"), pytest.warns(gvi.RunFailureWarning) as caught:
        traj = integrator.integrate([1.0], [0.0], h=0.005, n_steps=1000)
    assert not traj.success and traj.t[-1] > 0.5  # measured 0.885: many chunks in
    step = round(traj.t[-1] / 0.005)
    assert str(caught[0].message).startswith(f"step {step} ")


def test_progress_bar(small_chunks, capsys):
    _run(progress=True)
    assert "step" in capsys.readouterr().err
    _run(progress=False)
    assert capsys.readouterr().err == ""
    with pytest.raises(TypeError, match="progress must be True, False or None"):
        _run(progress="yes")


CHILD = textwrap.dedent(
    """
    import signal, time, warnings
    import sympy as sp, galerkin_vi as gvi
    # a terminal's Python: SIGINT raises KeyboardInterrupt (under pytest-xdist the child
    # inherits an ignored SIGINT, and Python then installs no handler)
    signal.signal(signal.SIGINT, signal.default_int_handler)
    q, v = sp.symbols("q v")
    integ = gvi.Integrator(gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v]), gvi.Galerkin(2))
    integ.integrate([1.0], [0.0], h=0.1, n_steps=10)
    print("started", flush=True)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        traj = integ.integrate([1.0], [0.0], h=0.01, n_steps=10**9, save_every=1000)
    print(traj.status.name, traj.n_steps, len(traj), traj.t[-1], len(caught), flush=True)
    """
)


def test_ctrl_c_stops_a_long_compiled_run_and_keeps_its_states():
    child = subprocess.Popen([sys.executable, "-c", CHILD], stdout=subprocess.PIPE, text=True)
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(1.5)
        sent = time.perf_counter()
        child.send_signal(signal.SIGINT)
        out, _ = child.communicate(timeout=60)
        waited = time.perf_counter() - sent
    finally:
        child.kill()
    status, n_steps, rows, t_last, warned = out.split()
    assert status == "INTERRUPTED" and int(warned) == 1
    # a chunk of a pendulum is 2e5 steps, 0.1 s here: measured 1.0 s from SIGINT to exit
    assert waited < 5.0
    assert int(n_steps) > 10_000 and int(rows) == int(n_steps) // 1000 + 1
    assert float(t_last) == pytest.approx(int(n_steps) * 0.01, rel=1e-12)


def test_a_short_run_is_one_call(monkeypatch):
    calls = []
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(2))
    from galerkin_vi.run import smooth

    original = smooth.run_once
    monkeypatch.setattr(
        smooth,
        "run_once",
        lambda spec, segment: calls.append(segment.n_steps) or original(spec, segment),
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        integrator.integrate([0.3], [0.0], h=0.1, n_steps=chunks.FIRST_CHUNK)
    assert calls == [chunks.FIRST_CHUNK]


def test_chunks_do_not_depend_on_the_clock():
    # the same run twice, whatever the machine's load: bitwise the same (chunk sizes
    # came from a clock once, and a chaotic orbit's crossings changed from call to call)
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(2))
    runs = [
        integrator.integrate(
            [0.3], [2.5], h=0.1, n_steps=3 * chunks.chunk_steps(1, 1), save_every=997
        )
        for _ in range(2)
    ]
    np.testing.assert_array_equal(runs[0].q, runs[1].q)
    assert chunks.chunk_steps(1, 1) == 201_600 and chunks.chunk_steps(100, 7) == 5040


def test_a_terminal_event_stops_the_computation(small_chunks):
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(2))
    crossing = gvi.Event(q, terminal=True, direction=-1)
    traj = integrator.integrate([1.5], [0.0], h=0.01, n_steps=100_000, events=crossing)
    # the pendulum passes the vertical at t = 1.83: the run stopped in the chunk after it
    assert traj.status == gvi.RunStatus.TERMINATED and traj.t[-1] == pytest.approx(1.83, abs=0.01)
    assert traj.n_steps < 300


@pytest.mark.parametrize("save_every", [3, 7, 10])
def test_long_runs_keep_every_kth_row_bit_for_bit(save_every):
    # the chunks join at the same steps whatever save_every (a divisor of JOIN) is
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(2))
    steps = 2 * chunks.FIRST_CHUNK + 70
    every = integrator.integrate([1.0], [0.5], h=0.1, n_steps=steps)
    sparse = integrator.integrate([1.0], [0.5], h=0.1, n_steps=steps, save_every=save_every)
    rows = np.append(np.arange(0, steps + 1, save_every), steps)
    rows = np.unique(rows)
    np.testing.assert_array_equal(sparse.t, every.t[rows])
    np.testing.assert_array_equal(sparse.q, every.q[rows])
    np.testing.assert_array_equal(sparse.p, every.p[rows])
