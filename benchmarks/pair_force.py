"""Per sub-step of a pair force: the loop generated for a small pair-potential system
(``specialize="system"``: the pairs side by side, square roots and divisions four at a
time) against the shared explicit loop (``specialize=True``), in the same run.

For each problem, Composition(10) (35 force evaluations per step) over ``--steps``
steps, ``save_every = n_steps``; the minimum CPU time of ``--repeats`` calls per
setting, in ns per sub-step, their ratio, and whether the final states are equal bit
for bit. Problems: the outer solar system (6 bodies in space, 15 pairs, 18
coordinates) and softened planar n-body problems of 4, 7 and 8 bodies (6-28 pairs).

Run: ``python benchmarks/pair_force.py`` (about a minute with the loops warm). Not a
test: it prints a table.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import n_body, outer_solar_system


def _problems() -> dict:
    solar = outer_solar_system()
    found = {"outer solar system (15 pairs)": (solar, solar.t_final / 540)}
    for bodies in (4, 7, 8):
        problem = n_body(masses=tuple(1.0 + 0.1 * k for k in range(bodies)))
        pairs = bodies * (bodies - 1) // 2
        found[f"{bodies} bodies (planar, {pairs} pairs)"] = (problem, problem.t_final / 2000)
    return found


def _best(integrator: gvi.Integrator, problem, h: float, steps: int, repeats: int):
    def run():
        return integrator.integrate(
            problem.q0, problem.v0, h=h, n_steps=steps, save_every=steps,
            params=problem.params, on_failure="raise",
        )  # fmt: skip

    result = run()
    best = np.inf
    for _ in range(repeats):
        start = time.process_time()
        run()
        best = min(best, time.process_time() - start)
    return best, result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=540)
    parser.add_argument("--repeats", type=int, default=15)
    args = parser.parse_args()
    method = gvi.Composition(10)
    sub_steps = args.steps * method.stages
    print(f"{'problem':32s} {'generated':>12s} {'shared':>12s} {'ratio':>7s}  equal")
    for name, (problem, h) in _problems().items():
        times, states = {}, {}
        for specialize in ("system", True):
            integrator = gvi.Integrator(problem.system, method, specialize=specialize)
            times[specialize], states[specialize] = _best(
                integrator, problem, h, args.steps, args.repeats
            )
        generated, shared = (times[s] / sub_steps * 1e9 for s in ("system", True))
        equal = np.array_equal(states["system"].q, states[True].q) and np.array_equal(
            states["system"].p, states[True].p
        )
        print(f"{name:32s} {generated:9.1f} ns {shared:9.1f} ns {shared / generated:7.2f}  {equal}")


if __name__ == "__main__":
    main()
