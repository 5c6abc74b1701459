"""Time to the first steps: a never-seen system, and a cached one in a new process.

For each of five kinds of system (non-separable, separable many-body,
constrained, forced, a 60-mass nonlinear chain) a new Python process builds the
system from its SymPy Lagrangian and runs two steps with each of two methods;
the time is measured from ``LagrangianSystem(...)`` (the Lagrangian already
built as a SymPy expression) to the end of the second method's steps, apart
from ``import galerkin_vi``. Each Lagrangian carries a
coefficient drawn afresh for this run, so the first process sees a system no
cache holds (the loops are compiled once per machine and are not rebuilt); a
second process with the same coefficient finds it cached.

Run ``galerkin-vi warmup`` first (a machine that has used the library once),
then ``python benchmarks/first_step.py``. Not a test: it prints a table.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import subprocess
import sys
import textwrap

SYSTEMS = {
    "elastic pendulum (2, non-separable)": """
        r, th, vr, vth = sp.symbols("r th vr vth")
        L = (vr**2 + r**2 * vth**2) / 2 + 9.81 * r * sp.cos(th) - C * (r - 1) ** 2 / 2
        system = gvi.LagrangianSystem(L, [r, th], [vr, vth])
        q0, v0 = [1.1, 0.5], [0.0, 0.1]
    """,
    "three bodies (6, separable)": """
        q = sp.symbols("x0:3 y0:3"); v = sp.symbols("u0:3 w0:3")
        T = sum(v[i] ** 2 + v[i + 3] ** 2 for i in range(3)) / 2
        U = sum(C / sp.sqrt((q[i] - q[j]) ** 2 + (q[i + 3] - q[j + 3]) ** 2)
                for i in range(3) for j in range(i))
        system = gvi.LagrangianSystem(T + U, list(q), list(v))
        q0 = [1.0, -0.5, -0.5, 0.0, 0.87, -0.87]; v0 = [0.0, -0.5, 0.5, 0.6, -0.3, -0.3]
    """,
    "spherical pendulum (3, constrained)": """
        x, y, z, vx, vy, vz = sp.symbols("x y z vx vy vz")
        L = (vx**2 + vy**2 + vz**2) / 2 - C * z
        system = gvi.LagrangianSystem(L, [x, y, z], [vx, vy, vz],
                                      constraints=[(x**2 + y**2 + z**2 - 1) / 2])
        q0, v0 = [0.6, 0.0, -0.8], [0.0, 1.0, 0.0]
    """,
    "damped pendulum (1, forced)": """
        q, v = sp.symbols("q v")
        system = gvi.LagrangianSystem(v**2 / 2 + C * sp.cos(q), [q], [v], forces=[-0.1 * v])
        q0, v0 = [1.0], [0.0]
    """,
    "nonlinear chain (60, banded)": """
        n = 60
        q = sp.symbols(f"q0:{n}"); v = sp.symbols(f"v0:{n}")
        d = [q[0]] + [q[i + 1] - q[i] for i in range(n - 1)] + [-q[-1]]
        L = sum(vi**2 for vi in v) / 2 - sum(e**2 / 2 + C * e**4 / 4 for e in d)
        system = gvi.LagrangianSystem(L, list(q), list(v))
        q0 = [0.1 * ((i % 7) - 3) for i in range(n)]; v0 = [0.0] * n
    """,
}

TEMPLATE = """
import json, time
begin = time.perf_counter()
import sympy as sp
import galerkin_vi as gvi
imported = time.perf_counter()
C = {coefficient!r}
{body}
kinds = []
for method in (gvi.Galerkin(2), gvi.Galerkin(3)):
    integrator = gvi.Integrator(system, method)
    integrator.integrate(q0, v0, h=0.01, n_steps=2)
    kinds.append(integrator.kernel_path)
done = time.perf_counter()
print(json.dumps({{"import": imported - begin, "first_steps": done - start, "loops": kinds}}))
"""


def _run(name: str, coefficient: float) -> dict:
    body = textwrap.dedent(SYSTEMS[name]).replace(
        "system = gvi.LagrangianSystem(",
        "start = time.perf_counter()\nsystem = gvi.LagrangianSystem(",
    )
    script = TEMPLATE.format(coefficient=coefficient, body=body)
    out = subprocess.run(
        [sys.executable, "-c", script], capture_output=True, text=True, env=dict(os.environ)
    )
    if out.returncode:
        raise RuntimeError(f"{name}: {out.stderr.strip().splitlines()[-1]}")
    return json.loads(out.stdout.strip().splitlines()[-1])


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", help="write the numbers to this file")
    args = parser.parse_args(argv)
    rows = []
    print("| system | loops | import (s) | never seen (s) | cached, new process (s) |")
    print("|---|---|---|---|---|")
    for name in SYSTEMS:
        coefficient = round(1.0 + random.random(), 12)
        cold = _run(name, coefficient)
        warm = _run(name, coefficient)
        rows.append({"system": name, "cold": cold, "warm": warm})
        print(
            f"| {name} | {', '.join(cold['loops'])} | {warm['import']:.2f} | "
            f"{cold['first_steps']:.2f} | {warm['first_steps']:.2f} |",
            flush=True,
        )
    if args.json:
        with open(args.json, "w") as fh:
            json.dump(rows, fh, indent=1)
    return 0


if __name__ == "__main__":
    sys.exit(main())
