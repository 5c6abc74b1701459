"""Ensembles: the cost per member beyond its steps, the speed-up of threads, Dask.

The issue's targets: 10^4 double-pendulum members of 10^3 steps, per-member
overhead at most 20 us over the compiled step cost, at least 1.8x on 2 cores,
and on a 2-worker Dask ``LocalCluster`` results identical to the serial run with
nothing compiled on the workers. Measured here, in one run:

- ``integrate_many`` of the members with 1 and with all threads (min of repeats);
- the overhead per member: ``integrate_many`` of the same members with zero
  steps (everything a member costs but its steps: start checks, Legendre
  transforms, allocation, loop entry, end checks). The cost per step of one long
  run is printed beside it, not subtracted: on this shared machine it moved
  between 1.09 and 1.65 us from one run to the next, more than the overhead,
  and a short run's steps include its cold start (the first Jacobian);
- building the members' ``Trajectory`` objects (``Ensemble.trajectories``,
  done on first access only);
- with ``--dask``: the same members on a ``LocalCluster`` of 2 worker
  processes, compared bitwise with the serial run, and each worker's numba
  cache statistics (``galerkin_vi.run.ensemble.compile_statistics``).

Usage::

    python benchmarks/ensemble.py                 # 10^4 members of 10^3 steps
    python benchmarks/ensemble.py --members 2000  # quicker
    python benchmarks/ensemble.py --dask          # and on a 2-worker LocalCluster
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Callable, Sequence

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import mechanics
from galerkin_vi.run.ensemble import compile_statistics


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/ensemble.py", description=__doc__)
    parser.add_argument("--members", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--dask", action="store_true", help="also run on a LocalCluster")
    args = parser.parse_args(argv)
    problem = mechanics.double_pendulum()
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    rng = np.random.default_rng(3)
    q0s = problem.q0 + 0.1 * rng.standard_normal((args.members, 2))
    run = {"h": 0.01, "n_steps": args.steps, "save_every": args.steps}
    integrator.integrate_many(q0s[:2], problem.v0, **run)  # loaded, not timed
    long = 200 * args.steps
    per_step = _best(
        args.repeats,
        lambda: integrator.integrate(problem.q0, problem.v0, h=0.01, n_steps=long, save_every=long),
    ) / long  # fmt: skip
    cores = os.cpu_count() or 1
    times, ensembles = {}, {}
    for workers in sorted({1, cores}):
        times[workers] = _best(
            args.repeats,
            lambda w=workers: ensembles.__setitem__(
                w, integrator.integrate_many(q0s, problem.v0, workers=w, **run)
            ),
        )
    empty = _best(
        args.repeats,
        lambda: integrator.integrate_many(q0s, problem.v0, h=0.01, n_steps=0, workers=1),
    )
    built = _best(1, lambda: ensembles[1].trajectories)
    m = args.members
    print(f"double pendulum, Gauss(2), {m} members of {args.steps} steps, h = 0.01")
    print(f"compiled cost per step (one run of {long} steps): {1e6 * per_step:.2f} us")
    print(f"{'threads':>8s} {'seconds':>9s} {'us/member':>10s} {'speed-up':>9s}")
    for workers, seconds in times.items():
        print(f"{workers:8d} {seconds:9.3f} {1e6 * seconds / m:10.1f} {times[1] / seconds:9.2f}")
    print(f"overhead per member, a run of 0 steps:            {1e6 * empty / m:8.1f} us")
    print(f"building the Trajectory objects, per member:      {1e6 * built / m:8.1f} us")
    same = all(
        np.array_equal(ensembles[1].q, ensembles[w].q) and np.array_equal(ensembles[1].p, e.p)
        for w, e in ensembles.items()
    )
    print(f"threads' results bitwise equal to one thread's: {same}")
    if args.dask:
        _dask(integrator, q0s, problem.v0, run, ensembles[1])
    return 0


def _dask(integrator, q0s, v0, run, serial) -> None:
    from dask.distributed import Client, LocalCluster

    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True) as cluster:
        with Client(cluster) as client:
            before = client.run(compile_statistics)
            start = time.perf_counter()
            many = integrator.integrate_many(q0s, v0, executor=client.get_executor(), **run)
            seconds = time.perf_counter() - start
            after = client.run(compile_statistics)
    equal = np.array_equal(many.q, serial.q) and np.array_equal(many.p, serial.p)
    print(f"Dask LocalCluster, 2 workers: {seconds:.3f} s, bitwise equal to serial: {equal}")
    for worker, counts in after.items():
        print(f"  {worker}: {counts} (before the run: {before[worker]})")


def _best(repeats: int, fn: Callable[[], object]) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - start)
    return best


if __name__ == "__main__":
    sys.exit(main())
