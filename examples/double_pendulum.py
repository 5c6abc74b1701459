"""Double pendulum: bounded energy over long times, and time reversibility.

The planar double pendulum (unit masses and lengths, absolute angles; its mass
matrix depends on the configuration, so every Newton step re-evaluates it) is
integrated from ``q0 = (1.0, 0.5)``, ``v0 = (0.0, 0.3)`` for ``--steps`` steps
of size ``--h`` with two Galerkin variational integrators, and for contrast with
scipy's adaptive RK45 at ``rtol = 1e-8`` (not symplectic). The script prints

* the largest relative energy error over the first and the last 10% of the run:
  bounded for the variational integrators, growing for RK45;
* for the symmetric Galerkin methods, the distance to the initial state after
  integrating forward for ``--reverse-time`` and back again: round-off,
  amplified by the motion's sensitivity to perturbations.

Run ``python examples/double_pendulum.py --help`` for the options.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.integrate import solve_ivp

import galerkin_vi as gvi
from galerkin_vi import problems


def energy_drift(energy: np.ndarray) -> tuple[float, float]:
    """Largest relative ``|H - H_0|`` over the first and over the last 10% of the run."""
    error = np.abs(energy - energy[0]) / abs(energy[0])
    tenth = max(len(error) // 10, 1)
    return float(error[:tenth].max()), float(error[-tenth:].max())


def rk45_energy(problem: problems.Problem, t_final: float, samples: int) -> np.ndarray:
    """Energy along scipy's RK45 solution of the Euler-Lagrange equations."""
    system, n = problem.system, problem.system.n
    prm = system.parameter_vector(problem.params)

    def rhs(_t: float, y: np.ndarray) -> np.ndarray:
        q, v = y[:n], y[n:]
        values = system.evaluate("hessian", 0.0, q, v, prm)
        Lq, Lqv = values[:n], values[2 * n + n * n : 2 * n + 2 * n * n].reshape(n, n)
        Lvv = values[2 * n + 2 * n * n :].reshape(n, n)
        return np.concatenate([v, np.linalg.solve(Lvv, Lq - Lqv.T @ v)])

    t = np.linspace(0.0, t_final, samples)
    sol = solve_ivp(
        rhs,
        (0.0, t_final),
        np.concatenate([problem.q0, problem.v0]),
        method="RK45",
        rtol=1e-8,
        atol=1e-10,
        t_eval=t,
    )
    q, v = sol.y[:n].T, sol.y[n:].T
    p = system.legendre(q, v, 0.0, problem.params)
    return system.hamiltonian(q, p, 0.0, problem.params)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--h", type=float, default=0.05)
    parser.add_argument("--steps", type=int, default=20_000)
    parser.add_argument("--reverse-time", type=float, default=20.0)
    args = parser.parse_args()

    problem = problems.double_pendulum()
    t_final = args.h * args.steps
    print(f"double pendulum, q0 = {problem.q0}, v0 = {problem.v0}, h = {args.h}, T = {t_final:g}")
    print(
        f"{'method':>22} {'max|dH|/|H| first 10%':>22} {'last 10%':>10} "
        f"{'back to start':>13} {'time [s]':>8}"
    )
    methods = {
        "s=2 Gauss(2)": gvi.Galerkin(2, gvi.gauss_legendre(2)),
        "s=3 Lobatto(4)": gvi.Galerkin(3),
    }
    for name, method in methods.items():
        integrator = gvi.Integrator(problem.system, method)
        integrator.integrate(problem.q0, problem.v0, h=args.h, n_steps=1)  # compile or load
        start = time.perf_counter()
        traj = integrator.integrate(
            problem.q0,
            problem.v0,
            h=args.h,
            n_steps=args.steps,
            save_every=max(1, args.steps // 2000),
        )
        elapsed = time.perf_counter() - start
        first, last = energy_drift(traj.energy())
        # forward, then backward from the end state: a symmetric method retraces its steps
        n_back = int(round(args.reverse_time / args.h))
        out = integrator.integrate(problem.q0, problem.v0, h=args.h, n_steps=n_back)
        back = integrator.integrate(out.q[-1], p0=out.p[-1], h=-args.h, n_steps=n_back)
        distance = np.linalg.norm(back.q[-1] - problem.q0)
        print(f"{name:>22} {first:22.2e} {last:10.2e} {distance:13.1e} {elapsed:8.2f}")
    start = time.perf_counter()
    first, last = energy_drift(rk45_energy(problem, t_final, 2000))
    print(
        f"{'scipy RK45 rtol 1e-8':>22} {first:22.2e} {last:10.2e} {'':>13} "
        f"{time.perf_counter() - start:8.2f}"
    )


if __name__ == "__main__":
    main()
