"""CPU time per step and per sub-step of the explicit loop: Störmer–Verlet and its compositions.

For the pendulum (an angle), Kepler and the 100-mass spring chain: the time per
step of ``Galerkin(1)`` (Störmer–Verlet) and of ``Composition(8)`` (17 sub-steps),
from a long run minus a one-step run (the fixed cost of a call), minimum of
``--repeats``. Run it with two checkouts on ``PYTHONPATH`` in turn to compare the
loop before and after a change::

    PYTHONPATH=/path/to/a python benchmarks/explicit_per_step.py
    PYTHONPATH=/path/to/b python benchmarks/explicit_per_step.py
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems.chains import spring_chain
from galerkin_vi.problems.gravitation import kepler
from galerkin_vi.problems.mechanics import pendulum


def per_step(integrator: gvi.Integrator, problem, n_steps: int, repeats: int) -> float:
    """Seconds of CPU per step: a run of ``n_steps`` minus a one-step run, minimum."""
    q0, v0 = problem.q0, problem.v0
    integrator.integrate(q0, v0, h=1e-3, n_steps=10, save_every=10)
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        integrator.integrate(q0, v0, h=1e-3, n_steps=n_steps, save_every=n_steps)
        long_run = time.process_time() - start
        start = time.process_time()
        integrator.integrate(q0, v0, h=1e-3, n_steps=1, save_every=1)
        one = time.process_time() - start
        best = min(best, (long_run - one) / (n_steps - 1))
    return best


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/explicit_per_step.py")
    parser.add_argument("--repeats", type=int, default=7)
    args = parser.parse_args(argv)
    print("| problem | method | sub-steps | ns/step | ns/sub-step |")
    print("|---|---|---:|---:|---:|")
    for name, problem, n_steps in (
        ("pendulum", pendulum(), 400_000),
        ("kepler", kepler(0.5), 400_000),
        ("spring chain N = 100", spring_chain(100), 40_000),
    ):
        # a checkout before the compositions runs Stormer-Verlet only
        composed = (gvi.Composition(8),) if hasattr(gvi, "Composition") else ()
        for method in (gvi.Galerkin(1), *composed):
            stages = getattr(method, "stages", 1)
            steps = max(n_steps // stages, 1000)
            seconds = per_step(gvi.Integrator(problem.system, method), problem, steps, args.repeats)
            print(
                f"| {name} | {method!r} | {stages} | {1e9 * seconds:.1f} | "
                f"{1e9 * seconds / stages:.1f} |"
            )
    return 0


if __name__ == "__main__":
    sys.exit(main())
