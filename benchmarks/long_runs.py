"""Long runs: memory with save_every, and energy drift at round-off level.

Not a test: prints figures for the design notes (docs/design-notes.md, "Accuracy over long runs").

- 1e7 pendulum steps (s = 2, Lobatto 3, h = 0.05) with ``save_every=1000``: peak
  resident memory of the process (``resource.getrusage``) and run time.
- 1e6 Kepler steps (e = 0.5, s = 4, Lobatto 5, h = T/500, so 2000 periods): the
  energy error sits at round-off and does not drift (max |dH| over the last
  tenth against the first tenth; least-squares slope of |dH| per period).

Run: ``python benchmarks/long_runs.py [--pendulum-steps N] [--kepler-steps N]``.
"""

from __future__ import annotations

import argparse
import resource
import time

import numpy as np

import galerkin_vi as gvi
from galerkin_vi import problems


def peak_memory_mb() -> float:
    """Peak resident set size of this process in MB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def pendulum_memory(n_steps: int) -> None:
    problem = problems.pendulum(1.5, 0.3)
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(2))
    integrator.integrate(problem.q0, problem.v0, h=0.05, n_steps=10)  # compile or load
    before = peak_memory_mb()
    start = time.perf_counter()
    traj = integrator.integrate(problem.q0, problem.v0, h=0.05, n_steps=n_steps, save_every=1000)
    seconds = time.perf_counter() - start
    energy = traj.energy()
    print(
        f"pendulum: {n_steps:.0e} steps, save_every=1000, {len(traj)} rows saved, "
        f"{seconds:.1f} s ({1e9 * seconds / n_steps:.0f} ns/step), "
        f"peak RSS {peak_memory_mb():.0f} MB (before the run {before:.0f} MB), "
        f"max|dH| {np.max(np.abs(energy - energy[0])):.2e}"
    )


def kepler_drift(n_steps: int) -> None:
    problem = problems.kepler(0.5)
    period = 2 * np.pi
    h = period / 500
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(4))
    start = time.perf_counter()
    traj = integrator.integrate(problem.q0, problem.v0, h=h, n_steps=n_steps, save_every=50)
    seconds = time.perf_counter() - start
    error = np.abs(traj.energy() - traj.energy()[0])
    tenth = error.size // 10
    first, last = error[1 : tenth + 1].max(), error[-tenth:].max()
    slope = np.polyfit(traj.t / period, traj.energy() - traj.energy()[0], 1)[0]
    momentum = traj.momentum(problem.symmetries["rotation"])
    print(
        f"kepler e=0.5, s=4 Lobatto 5, h=T/500: {n_steps:.0e} steps in {seconds:.1f} s; "
        f"max|dH| first tenth {first:.2e}, last tenth {last:.2e} (ratio {last / first:.2f}); "
        f"dH drift {slope:.1e} per period; max|dJ| {np.max(np.abs(momentum - momentum[0])):.1e}; "
        f"mean Newton iterations {traj.mean_newton_iterations:.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pendulum-steps", type=int, default=10_000_000)
    parser.add_argument("--kepler-steps", type=int, default=1_000_000)
    args = parser.parse_args()
    pendulum_memory(args.pendulum_steps)
    kepler_drift(args.kepler_steps)


if __name__ == "__main__":
    main()
