"""Loop variants compiled at first use, once per machine, by a child process.

A tiny driver in a temporary module stands in for a loop (it compiles in a
fraction of a second); its module notes in a log file every process that
imports it to compile (the children), so the tests count compilations across
processes.
"""

from __future__ import annotations

import fcntl
import os
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest
from numba.core import event

from galerkin_vi.loops import on_demand

_MODULE = """
import os
from galerkin_vi.loops.on_demand import driver

if os.environ.get("GALERKIN_VI_WARMUP_CHILD"):
    with open(os.environ["TINY_LOG"], "a") as log:
        log.write(f"{os.getpid()}\\n")


@driver
def tiny(x):
    return 2.0 * x + 1.0
"""

_CALL = "import tiny_loops; print(tiny_loops.tiny(2.0))"


@pytest.fixture
def tiny(tmp_path, monkeypatch):
    """The folder of the tiny driver's module, and the environment that finds it."""
    (tmp_path / "tiny_loops.py").write_text(_MODULE)
    log = tmp_path / "children.log"
    env = dict(os.environ, PYTHONPATH=os.pathsep.join([str(tmp_path), *sys.path]))
    env["TINY_LOG"] = str(log)
    env.pop("GALERKIN_VI_WARMUP_CHILD", None)
    env.pop("GALERKIN_VI_QUIET", None)
    env.pop("NUMBA_CACHE_DIR", None)  # numba caches the tiny driver beside its module
    return tmp_path, env, log


def _import_here(folder: Path, monkeypatch):
    """The tiny module of ``folder`` imported into this process, fresh for the test."""
    import importlib

    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.delenv("GALERKIN_VI_WARMUP_CHILD", raising=False)
    monkeypatch.delitem(sys.modules, "tiny_loops", raising=False)
    module = importlib.import_module("tiny_loops")
    monkeypatch.setitem(sys.modules, "tiny_loops", module)  # removed after the test
    return module


def _children(log: Path) -> int:
    return len(log.read_text().split()) if log.exists() else 0


def _run(env, code=_CALL):
    return subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)


def test_first_call_compiles_in_a_child_then_loads_from_the_cache(tiny):
    folder, env, log = tiny
    # the user's process loads the child's result: it compiles nothing itself
    code = textwrap.dedent(
        """
        from numba.core import event
        import tiny_loops
        with event.install_recorder("numba:compile") as recorder:
            value = tiny_loops.tiny(2.0)
        print(value, len(recorder.buffer))
        """
    )
    first = _run(env, code)
    assert first.returncode == 0, first.stderr
    assert first.stdout.split() == ["5.0", "0"]
    assert "compiling the time loop tiny" in first.stderr
    assert _children(log) == 1
    second = _run(env, code)
    assert second.stdout.split() == ["5.0", "0"]
    assert "compiling" not in second.stderr
    assert _children(log) == 1  # cached: no child


def test_messages_are_silenced_by_the_environment(tiny):
    _, env, _ = tiny
    done = _run(dict(env, GALERKIN_VI_QUIET="1"))
    assert done.returncode == 0, done.stderr
    assert "compiling" not in done.stderr


def test_processes_started_together_compile_each_variant_once(tiny):
    _, env, log = tiny
    processes = [
        subprocess.Popen([sys.executable, "-c", _CALL], env=env, stdout=subprocess.PIPE, text=True)
        for _ in range(3)
    ]
    outputs = [p.communicate()[0].strip() for p in processes]
    assert outputs == ["5.0"] * 3
    assert _children(log) == 1


def test_a_waiting_process_survives_the_lock_holder_being_killed(tiny):
    folder, env, log = tiny
    holder = subprocess.Popen(
        [
            sys.executable,
            "-c",
            textwrap.dedent(
                """
                import time, numba
                import tiny_loops
                from galerkin_vi.loops.on_demand import variant_lock
                with variant_lock(tiny_loops.tiny, (numba.float64,)) as locked:
                    print(locked, flush=True)
                    time.sleep(60)
                """
            ),
        ],
        env=env,
        stdout=subprocess.PIPE,
        text=True,
    )
    try:
        assert holder.stdout.readline().strip() == "True"
        waiting = subprocess.Popen(
            [sys.executable, "-c", _CALL], env=env, stdout=subprocess.PIPE, text=True
        )
        time.sleep(3.0)
        assert waiting.poll() is None  # blocked on the holder's lock
        holder.kill()  # mid-"compile": the kernel drops its lock
        out, _ = waiting.communicate(timeout=120)
    finally:
        holder.kill()
        holder.wait()
    assert waiting.returncode == 0
    assert out.strip() == "5.0"
    assert _children(log) == 1  # the waiting process compiled it, once


def test_an_unwritable_cache_compiles_in_memory(tiny, monkeypatch, capsys):
    folder, env, log = tiny
    tiny_loops = _import_here(folder, monkeypatch)

    def refuse(*args, **kwargs):
        raise PermissionError("read-only file system")

    monkeypatch.setattr(on_demand.os, "open", refuse)
    with event.install_recorder("numba:compile") as recorder:
        assert tiny_loops.tiny(2.0) == 5.0
    started = [e.data["dispatcher"].py_func.__name__ for _, e in recorder.buffer if e.is_start]
    assert started == ["tiny"]
    assert _children(log) == 0  # compiled here
    assert "in memory" in capsys.readouterr().err
    cache = Path(tiny_loops.tiny._cache.cache_path)
    assert not list(cache.glob("*.nbc"))  # nothing written


def test_a_failing_child_leaves_the_variant_to_this_process(tiny, monkeypatch, capsys):
    folder, env, log = tiny
    tiny_loops = _import_here(folder, monkeypatch)
    monkeypatch.setattr(on_demand, "_CHILD", "import sys; sys.exit('no compiler here')")
    assert tiny_loops.tiny(3.0) == 7.0
    assert "no compiler here; compiling in this process" in capsys.readouterr().err


def test_set_messages_returns_the_previous_setting():
    previous = on_demand.set_messages(False)
    try:
        assert on_demand.set_messages(True) is False
    finally:
        on_demand.set_messages(previous)


def test_importing_the_package_imports_none_of_its_dependencies():
    code = (
        "import sys, galerkin_vi; "
        "print(sorted(m for m in ('numba', 'sympy', 'scipy', 'numpy', 'matplotlib') "
        "if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


def test_a_compiling_child_imports_the_loops_without_sympy():
    # the child of compile_in_child imports on_demand and the loop modules; SymPy and the
    # code printer would add about half a second to every first use of a loop kind
    code = (
        "import sys; from galerkin_vi.loops.on_demand import compile_request; "
        "import galerkin_vi.loops.tangent, galerkin_vi.loops.constrained; "
        "print(sorted(m for m in ('sympy', 'galerkin_vi.printer') if m in sys.modules))"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.strip() == "[]"


_PENDULUM = textwrap.dedent(
    """
    import sympy as sp
    import galerkin_vi as gvi
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), q=[q], v=[v])
    traj = gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=10)
    print(traj.kernel_path if hasattr(traj, "kernel_path") else "", traj.q.shape)
    """
)


def test_the_first_pendulum_run_compiles_its_own_loop_and_the_shared_one_behind_it(tmp_path):
    # on an empty cache the run waits for the stage-form loop written for its system and
    # method (seconds), while a child compiles the shared stage-form loop (ten seconds)
    # for the systems after it; nothing else is compiled
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(tmp_path), GALERKIN_VI_BACKGROUND="1")
    env.pop("GALERKIN_VI_WARMUP_CHILD", None)
    env.pop("GALERKIN_VI_QUIET", None)
    command = [sys.executable, "-c", _PENDULUM]
    done = subprocess.run(command, env=env, capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split()[0] == "separable:system"
    compiled = [line for line in done.stderr.splitlines() if "compiling" in line]
    assert len(compiled) == 1 and "method_steps" in compiled[0]
    (folder,) = (tmp_path / "loops").iterdir()
    deadline = time.monotonic() + 300
    while not list(folder.glob("*.nbi")) and time.monotonic() < deadline:
        time.sleep(0.5)
    lock = next((folder / "locks").glob("*.lock"))
    with open(lock) as held:  # the child holds it until its result is written
        fcntl.flock(held, fcntl.LOCK_EX)
    drivers = {path.name.split("-")[0] for path in folder.glob("*.nbi")}
    assert drivers == {"stage_form.stage_form_loop"}
