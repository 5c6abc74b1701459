"""A short run's Python cost and a long run's cost per step, through ``Integrator.integrate``.

The double pendulum with Gauss(2) (the general Newton loop): 10 steps (best of 200
calls: what every short run pays, e.g. event and contact cuts, adaptive landing steps,
ensemble members run one by one) and 34 000 steps (best of 7: per step). Run it in two
trees one after the other to compare them::

    PYTHONPATH=BEFORE python benchmarks/per_call.py
    PYTHONPATH=AFTER python benchmarks/per_call.py
"""

from __future__ import annotations

import time

import galerkin_vi as gvi
from galerkin_vi.problems import mechanics


def main() -> None:
    problem = mechanics.double_pendulum()
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    print(f"loop: {integrator.kernel_path}")
    for n_steps, calls in ((10, 200), (34_000, 7)):
        run = dict(h=0.02, n_steps=n_steps, save_every=n_steps)
        integrator.integrate(problem.q0, problem.v0, **run)  # compiled and cached
        best = float("inf")
        for _ in range(calls):
            start = time.perf_counter()
            integrator.integrate(problem.q0, problem.v0, **run)
            best = min(best, time.perf_counter() - start)
        per_step = best / n_steps * 1e9
        print(f"{n_steps:6d} steps: {best * 1e6:9.1f} us per call, {per_step:7.1f} ns per step")


if __name__ == "__main__":
    main()
