r"""The tangent map of compositions of Störmer–Verlet against the general Newton loop's.

Per step, best of ``--repeats`` CPU times of interleaved runs in this process (only
the ratios compare across machines): the plain run, ``tangent=V`` with one direction
(MEGNO, a largest exponent) and ``tangent=True`` (the full :math:`\Phi`), for

- ``Composition(4, "yoshida")`` (explicit loop; its tangent: the explicit tangent loop),
- ``Galerkin(1)`` (Störmer–Verlet: plain on the explicit loop, tangent on the general
  Newton loop), and
- ``Galerkin(2)`` (order 4, as the composition; tangent on the general Newton loop),

on Hénon–Heiles (n = 2) and a nonlinear spring chain of 20 masses (n = 20, banded
Hessian). The column "per SV sub-step" divides by the Störmer–Verlet sub-steps per step
(3 for the triple jump).

Usage::

    python benchmarks/composition_tangent.py --repeats 5
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import henon_heiles, spring_chain


def _best(run, repeats: int) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        run()
        best = min(best, time.process_time() - start)
    return best


def measure(problem, n_steps: int, h: float, repeats: int) -> list[tuple[str, str, float]]:
    """(method, run, microseconds per step) for the three methods and three runs."""
    q0, v0 = np.asarray(problem.q0, float), np.asarray(problem.v0, float)
    n = q0.shape[0]
    direction = np.zeros((2 * n, 1))
    direction[0] = 1.0
    methods = {
        "Composition(4, yoshida)": gvi.Composition(4, "yoshida"),
        "Galerkin(1)": gvi.Galerkin(1),
        "Galerkin(2)": gvi.Galerkin(2),
    }
    runs = {
        "plain": {},
        "tangent r = 1": {"tangent": direction},
        "tangent = True": {"tangent": True},
    }
    rows = []
    for name, method in methods.items():
        integrator = gvi.Integrator(problem.system, method)
        for label, extra in runs.items():
            run = dict(h=h, n_steps=n_steps, save_every=n_steps, params=problem.params, **extra)
            integrator.integrate(q0, v0, **run)  # compile / load
            seconds = _best(lambda: integrator.integrate(q0, v0, **run), repeats)  # noqa: B023
            rows.append((name, label, 1e6 * seconds / n_steps))
    return rows


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=5)
    args = parser.parse_args()
    cases = [
        ("Hénon–Heiles, h = 0.1", henon_heiles(), 20_000, 0.1),
        ("spring chain N = 20 (beta = 1), h = 0.05", spring_chain(20, beta=1.0), 5_000, 0.05),
    ]
    for title, problem, n_steps, h in cases:
        print(f"\n{title}, {n_steps} steps")
        print("| method | run | us / step | / plain |")
        print("|---|---|---:|---:|")
        rows = measure(problem, n_steps, h, args.repeats)
        plain = {m: us for m, label, us in rows if label == "plain"}
        for method, label, us in rows:
            print(f"| {method} | {label} | {us:.2f} | {us / plain[method]:.1f} |")


if __name__ == "__main__":
    main()
