"""A short run's fixed cost and a long run's cost per step, through ``Integrator.integrate``.

Cases (minimum over repeated calls, ``save_every = n_steps``):

- the double pendulum with Gauss(2) (the general Newton loop): 10 steps (best of
  200 calls: what every short run pays, e.g. event and contact cuts, adaptive
  landing steps, ensemble members run one by one) and 34 000 steps (best of 7);
- the 100-mass benchmark chain with Störmer–Verlet (``Galerkin(1)``, the explicit
  loop) and with Lobatto(5): 1 and 1 000 steps (best of 20), the floor of the
  work-precision curves.

Run it in two trees at the same time to compare them::

    PYTHONPATH=BEFORE python benchmarks/per_call.py &
    PYTHONPATH=AFTER python benchmarks/per_call.py
"""

from __future__ import annotations

import argparse
import time

from peers.cases import chain_problem

import galerkin_vi as gvi
from galerkin_vi.problems import mechanics


def best_call(integrator, q0, v0, h: float, n_steps: int, calls: int) -> float:
    """Least wall time of ``calls`` calls of ``integrate`` (after one untimed call)."""
    run = dict(h=h, n_steps=n_steps, save_every=n_steps)
    integrator.integrate(q0, v0, **run)  # compiled and cached
    best = float("inf")
    for _ in range(calls):
        start = time.perf_counter()
        integrator.integrate(q0, v0, **run)
        best = min(best, time.perf_counter() - start)
    return best


def cases():
    """(name, integrator, q0, v0, h, [(n_steps, calls), ...])."""
    pendulum = mechanics.double_pendulum()
    yield (
        "double pendulum Gauss(2)",
        gvi.Integrator(pendulum.system, gvi.Galerkin(2, gvi.gauss_legendre(2))),
        pendulum.q0, pendulum.v0, 0.02, ((10, 200), (34_000, 7)),
    )  # fmt: skip
    chain = chain_problem(100)  # the benchmark chain (cubic springs)
    for label, method in (("Verlet", gvi.Galerkin(1)), ("Lobatto(5)", gvi.Galerkin(4))):
        yield (
            f"chain N=100 {label}",
            gvi.Integrator(chain.system, method),
            chain.q0, chain.v0, 0.01, ((1, 20), (1000, 20)),
        )  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.parse_args()
    print(f"{'case':28s} {'loop':10s} {'steps':>6s} {'us/call':>10s} {'ns/step':>10s}")
    for name, integrator, q0, v0, h, runs in cases():
        for n_steps, calls in runs:
            best = best_call(integrator, q0, v0, h, n_steps, calls)
            print(
                f"{name:28s} {integrator.kernel_path:10s} {n_steps:6d} {best * 1e6:10.1f} "
                f"{best / n_steps * 1e9:10.1f}"
            )


if __name__ == "__main__":
    main()
