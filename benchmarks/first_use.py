"""First use on a new machine: import, first result, each new loop kind, processes at once.

Every figure is a whole process on an empty cache folder (``GALERKIN_VI_CACHE_DIR``
in a temporary directory), as a new user meets it:

- ``import galerkin_vi`` on a warm machine (median of 5);
- import to the first pendulum result, the loop compiled at first use;
- in the same cache, each further new loop kind (constrained, varying mass,
  forced, tangent map): the seconds of a process that runs it;
- two processes started together on an empty cache: the CPU seconds of both
  (compiling children included) against one process's;
- ``galerkin-vi warmup`` (every variant, in parallel) on an empty cache.

``python benchmarks/first_use.py [--skip-warmup]`` prints a Markdown table.
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import textwrap
import time

PENDULUM = """
import sympy as sp
import galerkin_vi as gvi
q, v = sp.symbols("q v")
system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), q=[q], v=[v])
gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=100)
"""

KINDS = {
    "constrained (pendulum on a rod)": """
import sympy as sp
import galerkin_vi as gvi
x, y, vx, vy = sp.symbols("x y vx vy")
rod = gvi.LagrangianSystem((vx**2 + vy**2) / 2 - y, q=[x, y], v=[vx, vy],
                           constraints=[(x**2 + y**2 - 1) / 2])
gvi.Integrator(rod, gvi.Galerkin(2)).integrate([0.6, -0.8], [0.8, 0.6], h=0.01, n_steps=100)
""",
    "varying mass (bead on a rotating hoop, Gauss(3))": """
import sympy as sp
import galerkin_vi as gvi
q, v = sp.symbols("q v")
bead = gvi.LagrangianSystem((1 + q**2) * v**2 / 2 + sp.cos(q), q=[q], v=[v])
method = gvi.Galerkin(3, gvi.gauss_legendre(3))
gvi.Integrator(bead, method).integrate([0.5], [0.1], h=0.05, n_steps=100)
""",
    "forced (damped, velocity-dependent force)": """
import sympy as sp
import galerkin_vi as gvi
q, v = sp.symbols("q v")
damped = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), q=[q], v=[v], forces=[-v / 10])
gvi.Integrator(damped, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=100)
""",
    "tangent map (pendulum sensitivities)": """
import sympy as sp
import galerkin_vi as gvi
q, v = sp.symbols("q v")
system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), q=[q], v=[v])
gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=100,
                                                  tangent=True)
""",
}


def _environment(cache: str) -> dict[str, str]:
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=cache, GALERKIN_VI_QUIET="1")
    env.pop("GALERKIN_VI_WARMUP_CHILD", None)
    return env


def _seconds(code: str, env: dict[str, str]) -> float:
    start = time.perf_counter()
    subprocess.run([sys.executable, "-c", textwrap.dedent(code)], env=env, check=True)
    return time.perf_counter() - start


def _busy_seconds() -> float:
    """CPU seconds the whole machine has been busy (``/proc/stat``): the runs' processes,
    the compile children they leave running, and whatever else runs (keep it idle)."""
    with open("/proc/stat") as stat:
        fields = stat.readline().split()[1:]
    user, nice, system = (int(x) for x in fields[:3])
    return (user + nice + system) / os.sysconf("SC_CLK_TCK")


def _settled(cache: str, timeout: float = 300.0) -> None:
    """Wait until no compile child holds a lock in ``cache`` (background compiles done)."""
    import fcntl
    from pathlib import Path

    deadline = time.monotonic() + timeout
    for lock in Path(cache).rglob("*.lock"):
        with open(lock) as held:
            while time.monotonic() < deadline:
                try:
                    fcntl.flock(held, fcntl.LOCK_EX | fcntl.LOCK_NB)
                    break
                except BlockingIOError:
                    time.sleep(0.2)


def _together(count: int) -> tuple[float, float]:
    """Wall and CPU seconds of ``count`` pendulum processes started at once, empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = _environment(cache)
        before = _busy_seconds()
        start = time.perf_counter()
        processes = [
            subprocess.Popen([sys.executable, "-c", PENDULUM], env=env) for _ in range(count)
        ]
        for process in processes:
            process.wait()
        wall = time.perf_counter() - start
        time.sleep(1.0)  # a background child takes its lock
        _settled(cache)
        return wall, _busy_seconds() - before


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-warmup", action="store_true")
    args = parser.parse_args(argv)
    rows = []
    with tempfile.TemporaryDirectory() as cache:
        env = _environment(cache)
        imports = [_seconds("import galerkin_vi", env) for _ in range(5)]
        rows.append(
            ("`import galerkin_vi` (warm machine, median of 5)", statistics.median(imports))
        )
        rows.append(("import to the first pendulum result, empty cache", _seconds(PENDULUM, env)))
        time.sleep(1.0)
        _settled(cache)  # the shared loop's background compile, not counted in the next rows
        for kind, code in KINDS.items():
            rows.append((f"then a new loop kind: {kind}", _seconds(code, env)))
        rows.append(("the pendulum again (everything cached)", _seconds(PENDULUM, env)))
    one_wall, one_cpu = _together(1)
    two_wall, two_cpu = _together(2)
    rows.append(("one pendulum process, empty cache: CPU seconds, compile children too", one_cpu))
    rows.append(("two started together, empty cache: CPU seconds of both, children too", two_cpu))
    rows.append(("  ratio to one process", two_cpu / one_cpu))
    if not args.skip_warmup:
        with tempfile.TemporaryDirectory() as cache:
            start = time.perf_counter()
            subprocess.run(
                [sys.executable, "-m", "galerkin_vi.tools.cli", "warmup"],
                env=_environment(cache),
                check=True,
                stdout=subprocess.DEVNULL,
            )
            rows.append(
                ("`galerkin-vi warmup`, empty cache (every variant)", time.perf_counter() - start)
            )
    print("| what | seconds |\n|---|---|")
    for what, seconds in rows:
        print(f"| {what} | {seconds:.2f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
