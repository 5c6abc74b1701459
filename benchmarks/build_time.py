"""Build time of never-seen large systems: from ``LagrangianSystem(...)`` to the first step.

Times are the child process's CPU time (``time.process_time``): on a
machine shared with other jobs, wall time measures the load as much as the
build (everything here runs in the one process, single-threaded).

Each system is built in a fresh Python process with a fresh cache root
(``GALERKIN_VI_CACHE_DIR``) whose ``loops/`` folder links to the warm loop
cache of this machine (:func:`galerkin_vi.loops.loop_cache_dir`): the time
loops are compiled once per machine, the per-system point functions are what
is built. Every Lagrangian carries a coefficient drawn afresh for the run, so
no cache holds it. The stages timed:

* ``analysis``: ``LagrangianSystem(L, q, v)`` (SymPy derivatives and structure);
* ``codegen``: the point functions' spec and source (:func:`render_module`);
* ``compile``: numba's compilation of the point functions a loop needs;
* ``first step``: the whole first ``integrate(..., n_steps=1)`` call, codegen
  and compile included, plus ``Integrator(...)``;
* ``total``: analysis + first step.

Systems: ``lattice`` (2-D lattice of n x n masses, two coordinates each, nearest
neighbour springs :math:`k/2 (r-1)^2 + \\beta/4 (r-1)^4` of the distance
:math:`r`, a free lattice of unit rest length), ``fpu`` (a 1-D
FPU-beta chain), ``gravity`` (N bodies in the plane, softened gravity between
all pairs).

Run ``galerkin-vi warmup`` first, then e.g.::

    python benchmarks/build_time.py --kind lattice --sizes 3 5 8 11 15 21 30 --method gauss2
    python benchmarks/build_time.py --kind lattice fpu gravity --plot docs/_static/build_time.png

Not a test: it prints a table (and, with ``--plot``, a log-log plot).
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import tempfile
import textwrap
from pathlib import Path

SYSTEMS = {
    "lattice": """
        n = SIZE
        idx = lambda i, j: i * n + j
        x = sp.symbols(f"x0:{n * n}"); y = sp.symbols(f"y0:{n * n}")
        u = sp.symbols(f"u0:{n * n}"); w = sp.symbols(f"w0:{n * n}")
        q = [c for a in range(n * n) for c in (x[a], y[a])]
        v = [c for a in range(n * n) for c in (u[a], w[a])]
        k, beta = 1.0, C
        def spring(dx, dy):
            e = sp.sqrt(dx**2 + dy**2) - 1
            return k / 2 * e**2 + beta / 4 * e**4
        springs = []  # summed once: V += ... re-sorts the growing sum per spring
        for i in range(n):
            for j in range(n):
                a = idx(i, j)
                X, Y = x[a] + j, y[a] + i   # displacements from the rest lattice
                if j + 1 < n:
                    springs.append(spring(x[idx(i, j + 1)] + j + 1 - X, y[idx(i, j + 1)] + i - Y))
                if i + 1 < n:
                    springs.append(spring(x[idx(i + 1, j)] + j - X, y[idx(i + 1, j)] + i + 1 - Y))
        V = sp.Add(*springs)
        T = sum(c**2 for c in v) / 2
        system = gvi.LagrangianSystem(T - V, q, v)
        rng = np.random.default_rng(1)
        q0 = 0.05 * rng.standard_normal(2 * n * n); v0 = np.zeros(2 * n * n)
    """,
    "fpu": """
        n = SIZE
        q = sp.symbols(f"q0:{n}"); v = sp.symbols(f"v0:{n}")
        d = [q[0]] + [q[i + 1] - q[i] for i in range(n - 1)] + [-q[-1]]
        L = sum(c**2 for c in v) / 2 - sum(e**2 / 2 + C * e**4 / 4 for e in d)
        system = gvi.LagrangianSystem(L, list(q), list(v))
        q0 = [0.1 * ((i % 7) - 3) for i in range(n)]; v0 = [0.0] * n
    """,
    "gravity": """
        n = SIZE
        x = sp.symbols(f"x0:{n}"); y = sp.symbols(f"y0:{n}")
        u = sp.symbols(f"u0:{n}"); w = sp.symbols(f"w0:{n}")
        q = [c for a in range(n) for c in (x[a], y[a])]
        v = [c for a in range(n) for c in (u[a], w[a])]
        T = sum(c**2 for c in v) / 2
        U = sum(C / sp.sqrt((x[a] - x[b]) ** 2 + (y[a] - y[b]) ** 2 + 0.01)
                for a in range(n) for b in range(a))
        system = gvi.LagrangianSystem(T + U, q, v)
        rng = np.random.default_rng(1)
        q0 = 3 * rng.standard_normal(2 * n); v0 = 0.1 * rng.standard_normal(2 * n)
    """,
}

#: coordinates per size unit and default sizes
DEFAULT_SIZES = {
    "lattice": [3, 5, 8, 11, 15, 21, 30],
    "fpu": [30, 100, 300, 1000],
    "gravity": [4, 8, 16, 24],
}

METHODS = {
    "gauss2": "gvi.Galerkin(2, gvi.gauss_legendre(2), nodes='equidistant')",
    "galerkin2": "gvi.Galerkin(2)",
    "galerkin1": "gvi.Galerkin(1)",
}

CHILD = """
import time, json
t0 = time.process_time()
import numpy as np, sympy as sp
import galerkin_vi as gvi
from galerkin_vi.codegen import compiled
stages = {"codegen": 0.0, "compile": 0.0}
render = compiled.render_module
def timed_render(*args, **kwargs):
    s = time.process_time()
    try:
        return render(*args, **kwargs)
    finally:
        stages["codegen"] += time.process_time() - s
compiled.render_module = timed_render
addresses = compiled.PointFunctions.addresses
def timed_addresses(self, names):
    s = time.process_time()
    try:
        return addresses(self, names)
    finally:
        stages["compile"] += time.process_time() - s
compiled.PointFunctions.addresses = timed_addresses
C = COEFFICIENT
BUILD
t1 = time.process_time()
SYSTEM_BUILT
t2 = time.process_time()
integrator = gvi.Integrator(system, METHOD)
traj = integrator.integrate(q0, v0=v0, h=0.01, n_steps=1)
t3 = time.process_time()
assert np.all(np.isfinite(traj.q[-1]))
L = system.pieces.L
print(json.dumps({
    "n": system.n, "terms": len(sp.Add.make_args(L)), "import+L": t1 - t0,
    "analysis": t2 - t1, "first step": t3 - t2, "total": t3 - t1, **stages,
    "loop": integrator.loop_name if hasattr(integrator, "loop_name") else "",
}))
"""


def child_source(kind: str, size: int, method: str, coefficient: float) -> str:
    """The child process's program: build one system and take its first step."""
    build = textwrap.dedent(SYSTEMS[kind]).replace("SIZE", str(size))
    # the system's construction is timed on its own: split the build at that line
    head, _, rest = build.partition("system = ")
    statement, _, tail = rest.partition("\n")
    return (
        CHILD.replace("BUILD", head)
        .replace("SYSTEM_BUILT", f"system = {statement}\n{tail}")
        .replace("METHOD", METHODS[method])
        .replace("COEFFICIENT", repr(coefficient))
    )


def warm_loop_dir() -> Path:
    """The loop cache of this machine (under the default cache root)."""
    out = subprocess.run(
        [
            sys.executable,
            "-c",
            "from galerkin_vi.loops import loop_cache_dir; print(loop_cache_dir())",
        ],
        capture_output=True,
        text=True,
        check=True,
    )
    return Path(out.stdout.strip())


def run_one(kind: str, size: int, method: str, loops: Path) -> dict:
    """Build one never-seen system in a fresh process with a fresh per-system cache."""
    with tempfile.TemporaryDirectory(prefix="gvi-build-") as root:
        (Path(root) / "loops").mkdir()
        os.symlink(loops, Path(root) / "loops" / loops.name)
        env = dict(os.environ, GALERKIN_VI_CACHE_DIR=root)
        env.pop("NUMBA_CACHE_DIR", None)
        coefficient = round(random.uniform(0.5, 1.5), 6)
        program = child_source(kind, size, method, coefficient)
        # run outside the source tree: "python -c" puts the working directory first on
        # sys.path, which would shadow PYTHONPATH (the tree under test)
        out = subprocess.run(
            [sys.executable, "-c", program], env=env, capture_output=True, text=True, cwd=root
        )
        if out.returncode:
            raise RuntimeError(f"{kind} {size} {method} failed:\n{out.stderr[-3000:]}")
        return json.loads(out.stdout.strip().splitlines()[-1])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--kind", nargs="+", default=["lattice"], choices=list(SYSTEMS))
    parser.add_argument("--sizes", nargs="+", type=int, default=None)
    parser.add_argument(
        "--method", nargs="+", default=["gauss2", "galerkin1"], choices=list(METHODS)
    )
    parser.add_argument("--plot", type=Path, default=None)
    parser.add_argument("--json", type=Path, default=None, help="write the rows here")
    args = parser.parse_args()
    loops = warm_loop_dir()
    if not (loops / "complete").exists():
        print(f"warning: the loop cache {loops} is not complete: run galerkin-vi warmup")
    rows = []
    header = (
        f"{'system':8} {'method':9} {'n':>5} {'terms':>6} {'analysis':>8} {'codegen':>8} "
        f"{'compile':>8} {'1st step':>8} {'total':>7}"
    )
    print(header)
    for kind in args.kind:
        for size in args.sizes or DEFAULT_SIZES[kind]:
            for method in args.method:
                r = run_one(kind, size, method, loops)
                r.update(kind=kind, size=size, method=method)
                rows.append(r)
                print(
                    f"{kind:8} {method:9} {r['n']:5d} {r['terms']:6d} {r['analysis']:8.2f} "
                    f"{r['codegen']:8.2f} {r['compile']:8.2f} {r['first step']:8.2f} "
                    f"{r['total']:7.2f}",
                    flush=True,
                )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    if args.plot:
        plot(rows, args.plot)


def plot(rows: list[dict], path: Path) -> None:
    """Log-log plot of the total build time against the number of coordinates."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    for key in sorted({(r["kind"], r["method"]) for r in rows}):
        sel = [r for r in rows if (r["kind"], r["method"]) == key]
        ax.loglog([r["n"] for r in sel], [r["total"] for r in sel], "o-", label=" ".join(key))
    ax.set_xlabel("coordinates")
    ax.set_ylabel("LagrangianSystem(...) to first step [CPU s]")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=120)


if __name__ == "__main__":
    main()
