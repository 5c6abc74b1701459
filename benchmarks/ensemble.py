"""Ensembles: the cost per member over its steps, and the speed-up of threads.

The issue's target: 10^4 double-pendulum members of 10^3 steps, per-member
overhead at most 20 us over the compiled step cost, at least 1.8x on 2 cores.
Measured here, in one run: the compiled cost per step (one long run), the
time of ``integrate_many`` with 1 and with all threads, and from them the
overhead per member, ``time / members - steps x cost per step``.

Usage::

    python benchmarks/ensemble.py                 # 10^4 members of 10^3 steps
    python benchmarks/ensemble.py --members 2000  # quicker
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from collections.abc import Sequence

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import mechanics


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/ensemble.py", description=__doc__)
    parser.add_argument("--members", type=int, default=10_000)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    problem = mechanics.double_pendulum()
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    rng = np.random.default_rng(3)
    q0s = problem.q0 + 0.1 * rng.standard_normal((args.members, 2))
    run = {"h": 0.01, "n_steps": args.steps, "save_every": args.steps}
    long = 200 * args.steps
    integrator.integrate(problem.q0, problem.v0, **run)
    per_step = (
        min(
            _seconds(
                lambda: integrator.integrate(
                    problem.q0, problem.v0, h=0.01, n_steps=long, save_every=long, progress=False
                )
            )
            for _ in range(args.repeats)  # fmt: skip
        )
        / long
    )
    cores = os.cpu_count() or 1
    times = {}
    for workers in sorted({1, cores}):
        times[workers] = min(
            _seconds(lambda w=workers: integrator.integrate_many(q0s, problem.v0, workers=w, **run))
            for _ in range(args.repeats)  # fmt: skip
        )
    print(f"double pendulum, Gauss(2), {args.members} members of {args.steps} steps")
    print(f"compiled cost per step (one run of {long} steps): {1e6 * per_step:.2f} us")
    print(
        f"{'threads':>8s} {'seconds':>9s} {'us/member':>10s} {'overhead us':>12s} {'speed-up':>9s}"
    )
    for workers, seconds in times.items():
        member = seconds / args.members
        overhead = workers * member - args.steps * per_step
        print(
            f"{workers:8d} {seconds:9.3f} {1e6 * member:10.1f} {1e6 * overhead:12.1f}"
            f" {times[1] / seconds:9.2f}"
        )
    print("(overhead = threads x seconds per member - steps x cost per step)")
    return 0


def _seconds(fn) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


if __name__ == "__main__":
    sys.exit(main())
