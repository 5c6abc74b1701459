"""Per-step gain of the structure-specialised loops over the general Newton loop.

For each system and method: ``Integrator.kernel_path``, the largest difference
between the specialised and the Newton loop over 2000 steps (round-off), and the
speed-up ``time(specialize=False) / time(specialize=True)`` over 20 000 steps,
h = 0.05, in the same run. Not a test.

Run: ``python benchmarks/specialised_loops.py``.
"""

from __future__ import annotations

import time

import numpy as np
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems


def systems() -> dict:
    x, y, vx, vy, t = sp.symbols("x y vx vy t")
    return {
        "pendulum": (problems.pendulum().system, [1.5], [0.3]),
        "kepler": (problems.kepler(0.5).system, [0.5, 0.0], [0.0, 1.7]),
        "4 bodies (constant mass, 8 coordinates)": (
            problems.n_body((1.0, 1.0, 1.0, 1.0)).system,
            problems.n_body((1.0, 1.0, 1.0, 1.0)).q0,
            problems.n_body((1.0, 1.0, 1.0, 1.0)).v0,
        ),
        "coupled oscillators (M non-diagonal)": (
            gvi.LagrangianSystem(
                (2 * vx**2 + vx * vy + vy**2) / 2 - (x**2 + 3 * y**2 + x * y) / 2, [x, y], [vx, vy]
            ),
            [1.0, -0.5],
            [0.2, 0.1],
        ),
        "driven oscillator with a(t).v": (
            gvi.LagrangianSystem(
                (vx**2 + vy**2) / 2 + sp.cos(t) * vx - (x**2 + y**2) / 2 + x * sp.cos(2 * t),
                [x, y],
                [vx, vy],
                t=t,
            ),
            [1.0, 0.0],
            [0.0, 1.0],
        ),
    }


def best_time(integrator: gvi.Integrator, q0, v0, n_steps: int, repeats: int = 5) -> float:
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        integrator.integrate(q0, v0, h=0.05, n_steps=n_steps, save_every=n_steps)
        best = min(best, time.perf_counter() - start)
    return best


def main() -> None:
    methods = [
        gvi.Galerkin(1),
        gvi.Galerkin(2),
        gvi.Galerkin(3, gvi.gauss_legendre(3)),
        gvi.Galerkin(4, gvi.gauss_legendre(4)),
    ]
    for name, (system, q0, v0) in systems().items():
        for method in methods:
            fast = gvi.Integrator(system, method)
            general = gvi.Integrator(system, method, specialize=False)
            a = fast.integrate(q0, v0, h=0.05, n_steps=2000)
            b = general.integrate(q0, v0, h=0.05, n_steps=2000)
            speedup = best_time(general, q0, v0, 20_000) / best_time(fast, q0, v0, 20_000)
            print(
                f"{name:40s} s={method.degree} {fast.kernel_path:8s} "
                f"{'constant-mass' if fast.uses_constant_mass else '':13s} "
                f"max|dq|={np.abs(a.q - b.q).max():.1e} max|dp|={np.abs(a.p - b.p).max():.1e} "
                f"speed-up {speedup:.1f}x",
                flush=True,
            )


if __name__ == "__main__":
    main()
