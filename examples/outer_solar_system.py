"""The outer solar system (Hairer, Lubich & Wanner, ch. I.2) over 200 000 days.

Six bodies (the Sun with the inner planets, Jupiter, Saturn, Uranus, Neptune,
Pluto) in 3D, units AU, days and solar masses, initial data of HLW Table I.2.1
(``galerkin_vi.problems.outer_solar_system``). Two Galerkin variational
integrators run over the book's span; the script prints the largest relative
energy error, the drift of the three components of the total angular momentum
(conserved by discrete Noether to round-off), the run time, and how far the
two runs' final positions of Jupiter and Pluto lie apart (an estimate of the
coarser run's error). ``--plot orbits.png`` draws the orbits (x-y projection).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.problems.gravitation import OUTER_SOLAR_SYSTEM_BODIES


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--days", type=float, default=200_000.0)
    parser.add_argument("--h", type=float, default=100.0, help="step of the s=4 run (days)")
    parser.add_argument("--plot", metavar="PNG")
    args = parser.parse_args()

    problem = problems.outer_solar_system(t_final=args.days)
    rotations = {k: xi for k, xi in problem.symmetries.items() if k.startswith("rotation")}
    runs = {
        f"s=2 Gauss(2), h={args.h / 4:g}": (gvi.Galerkin(2, gvi.gauss_legendre(2)), args.h / 4),
        f"s=4 Gauss(4), h={args.h:g}": (gvi.Galerkin(4, gvi.gauss_legendre(4)), args.h),
    }
    print(f"outer solar system over {args.days:g} days")
    print(f"{'method':>24} {'steps':>7} {'max|dH|/|H|':>12} {'max|dJ|/|J|':>12} {'time [s]':>8}")
    finals = {}
    trajectories = {}
    for name, (method, h) in runs.items():
        n_steps = int(round(args.days / h))
        integrator = gvi.Integrator(problem.system, method)
        integrator.integrate(problem.q0, problem.v0, h=h, n_steps=1, params=problem.params)
        start = time.perf_counter()
        traj = integrator.integrate(
            problem.q0,
            problem.v0,
            h=h,
            n_steps=n_steps,
            save_every=max(1, n_steps // 2000),
            params=problem.params,
        )
        elapsed = time.perf_counter() - start
        energy = traj.energy()
        dH = np.max(np.abs(energy - energy[0])) / abs(energy[0])
        dJ = max(
            np.max(np.abs(J - J[0])) / max(abs(J[0]), 1e-300)
            for J in (traj.momentum(xi) for xi in rotations.values())
        )
        print(f"{name:>24} {n_steps:7d} {dH:12.2e} {dJ:12.2e} {elapsed:8.2f}")
        finals[name] = traj.q[-1].reshape(-1, 3)
        trajectories[name] = traj
    a, b = finals.values()
    for body in ("Jupiter", "Pluto"):
        j = OUTER_SOLAR_SYSTEM_BODIES.index(body)
        print(f"final {body} position, the two runs apart by {np.linalg.norm(a[j] - b[j]):.2e} AU")
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        q = list(trajectories.values())[-1].q.reshape(-1, len(OUTER_SOLAR_SYSTEM_BODIES), 3)
        fig, ax = plt.subplots(figsize=(6, 6))
        for j, body in enumerate(OUTER_SOLAR_SYSTEM_BODIES):
            ax.plot(q[:, j, 0], q[:, j, 1], lw=0.5, label=body)
        ax.set_aspect("equal")
        ax.set_xlabel("x [AU]")
        ax.set_ylabel("y [AU]")
        ax.legend(fontsize=7)
        fig.savefig(args.plot, dpi=120)
        print(f"plot written to {args.plot}")


if __name__ == "__main__":
    main()
