"""The caches across processes: concurrent builds, warm loads, corrupt numba files."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np

SCRIPT = textwrap.dedent(
    """
    import json, sys, time
    import sympy as sp
    import galerkin_vi as gvi
    start = time.perf_counter()
    # a Lagrangian of its own, so that no other test has compiled it
    q, v, w = sp.symbols("q v w")
    system = gvi.LagrangianSystem(v**2 / 2 - w * q**4 / 4 - q**2 / 2, [q], [v], params={w: 0.3})
    from numba.core import event
    with event.install_recorder("numba:compile") as recorder:
        integrator = gvi.Integrator(system, gvi.Galerkin(2))
        traj = integrator.integrate([1.0], [0.1], h=0.05, n_steps=200)
    compiled = [e.data["dispatcher"].py_func.__name__ for _, e in recorder.buffer if e.is_start]
    print(json.dumps({"q": traj.q[-1].tolist(), "p": traj.p[-1].tolist(),
                      "seconds": time.perf_counter() - start, "path": traj.kernel_path,
                      "compiled": compiled}))
    """
)


def _run(cache: Path, count: int) -> list[dict]:
    env = {**os.environ, "GALERKIN_VI_CACHE_DIR": str(cache)}
    procs = [
        subprocess.Popen(
            [sys.executable, "-c", SCRIPT],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for _ in range(count)
    ]
    results = []
    for proc in procs:
        out, err = proc.communicate(timeout=600)
        assert proc.returncode == 0, err
        results.append(json.loads(out.strip().splitlines()[-1]) | {"stderr": err[-2000:]})
    return results


def test_two_processes_build_the_same_entry_at_once(warm_cache):
    tmp_path = warm_cache
    first, second = _run(tmp_path, 2)
    assert first["q"] == second["q"] and first["p"] == second["p"]
    modules = list(tmp_path.rglob("gvi_*.py"))
    # one entry each, no leftover temporary files: the system's point functions and the
    # stage-form loop written for it and Gauss(2) (specialize="auto" keeps it ready)
    assert len(modules) == 2
    assert not list(tmp_path.rglob("*.tmp"))
    # a third process loads what they built and computes the same numbers
    (third,) = _run(tmp_path, 1)
    assert third["q"] == first["q"]


def test_corrupt_numba_cache_files_are_rebuilt(warm_cache):
    tmp_path = warm_cache
    (reference,) = _run(tmp_path, 1)
    points = tmp_path / "points"
    numba_files = [p for p in points.rglob("*") if p.suffix in (".nbi", ".nbc")]
    assert numba_files, "numba wrote no cache files beside the module"
    for path in numba_files:
        path.write_bytes(b"\0garbage" * 7)
    (again,) = _run(tmp_path, 1)
    np.testing.assert_array_equal(again["q"], reference["q"])
    np.testing.assert_array_equal(again["p"], reference["p"])


def test_corrupt_loop_cache_files_are_found(warm_cache):
    # rebuilding a loop takes seconds to minutes: here only that a damaged file is
    # recognised (and deleted) before numba would fail on it
    from galerkin_vi.cache import discard_unreadable

    (folder,) = (warm_cache / "loops").iterdir()
    assert not discard_unreadable(folder)
    index = sorted(folder.glob("*.nbi"))[0]
    data = sorted(folder.glob("*.nbc"))[-1]
    index.write_bytes(b"\0garbage" * 7)
    data.write_bytes(data.read_bytes()[:1000])
    removed = discard_unreadable(folder)
    assert index in removed and data in removed
    assert not index.exists() and not data.exists()


def test_cached_system_in_a_new_process_is_fast(warm_cache):
    first, second = _run(warm_cache, 1), _run(warm_cache, 1)
    # the first process compiles the system's point functions, the second loads them and
    # the loops: nothing compiled (measured 0.5 s on 2 quiet cores, numba's start-up
    # included; a loaded CI machine has stretched it to 15 s, so the time is not asserted)
    assert second[0]["compiled"] == [], second
    assert "compiling" not in second[0]["stderr"], second
    assert first[0]["q"] == second[0]["q"]
