"""Kepler problem: energy, angular momentum and position error over 100 periods.

The Kepler problem ``L = |v|**2/2 + 1/|q|`` with eccentricity ``e = 0.5`` starts
at the pericentre, ``q0 = (1 - e, 0)``, ``v0 = (0, sqrt((1 + e)/(1 - e)))``. The
orbit has semi-major axis 1, energy ``H = -1/2``, angular momentum
``sqrt(1 - e**2)`` and period ``T = 2*pi``, so after a whole number of periods
the exact solution is back at ``q0``.

Two order-4 and order-8 Galerkin variational integrators are run for 100
periods with ``h = T/200``:

* degree 2 with Gauss-Legendre(2) quadrature (equal to the 2-stage Gauss
  collocation method, order 4);
* degree 4 with Gauss-Lobatto(5) quadrature (order 8).

For each the script prints the largest energy error, the drift of the angular
momentum ``J = <p, xi_Q(q)>`` with ``xi_Q = (-y, x)`` (the generator of
rotations; discrete Noether says it is conserved up to round-off), the position
error after 100 periods and the numerical precession of the orbit: the exact
ellipse does not precess, so the turning of the Runge-Lenz vector
``A = p x (q x p) - q/|q|`` (which points to the pericentre) is the method's
phase error of the orbit's orientation, in radians per period.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import sympy as sp

import galerkin_vi as gvi

ECCENTRICITY = 0.5
PERIOD = 2 * math.pi


def kepler() -> tuple[gvi.LagrangianSystem, list[sp.Expr]]:
    """The Kepler Lagrangian and the generator of rotations ``xi_Q = (-y, x)``."""
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx**2 + vy**2) / 2 + 1 / sp.sqrt(x**2 + y**2)
    return gvi.LagrangianSystem(L, q=[x, y], v=[vx, vy]), [-y, x]


def precession_per_period(q: np.ndarray, p: np.ndarray, t: np.ndarray) -> float:
    """Least-squares rate (radians per period) of the Runge-Lenz vector's angle."""
    J = q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0]
    r = np.linalg.norm(q, axis=1)
    A = np.stack([p[:, 1] * J - q[:, 0] / r, -p[:, 0] * J - q[:, 1] / r], axis=1)
    angle = np.unwrap(np.arctan2(A[:, 1], A[:, 0]))
    return float(np.polyfit(t / PERIOD, angle - angle[0], 1)[0])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--periods", type=int, default=100)
    parser.add_argument("--steps-per-period", type=int, default=200)
    parser.add_argument("--backend", choices=["auto", "numba", "numpy"], default="auto")
    args = parser.parse_args()

    e = ECCENTRICITY
    q0 = np.array([1 - e, 0.0])
    v0 = np.array([0.0, math.sqrt((1 + e) / (1 - e))])
    h = PERIOD / args.steps_per_period
    n_steps = args.periods * args.steps_per_period
    exact_energy = -0.5
    exact_momentum = math.sqrt(1 - e**2)

    system, rotation = kepler()
    methods = {
        "s=2, Gauss(2)": gvi.Galerkin(2, gvi.gauss_legendre(2)),
        "s=4, Lobatto(5)": gvi.Galerkin(4, gvi.gauss_lobatto(5)),
    }
    print(f"L = {system.L},  e = {e},  h = T/{args.steps_per_period},  {args.periods} periods")
    print(f"exact H = {exact_energy}, exact J = {exact_momentum:.15f}")
    print(
        f"{'method':>16} {'order':>5} {'max|H - H0|':>12} {'max|J - J0|':>12} "
        f"{'|q(NT) - q0|':>12} {'precession/T':>12} {'Newton it.':>10} {'time [s]':>8}"
    )
    for name, method in methods.items():
        integrator = gvi.Integrator(system, method, backend=args.backend)
        start = time.perf_counter()
        traj = integrator.integrate(q0, v0=v0, h=h, n_steps=n_steps)
        elapsed = time.perf_counter() - start
        energy = traj.energy()
        momentum = traj.momentum(rotation)
        # the orbit is periodic: after a whole number of periods q is back at q0
        position_error = np.linalg.norm(traj.q[-1] - q0)
        print(
            f"{name:>16} {method.order:5d} {np.max(np.abs(energy - energy[0])):12.3e} "
            f"{np.max(np.abs(momentum - momentum[0])):12.3e} {position_error:12.3e} "
            f"{precession_per_period(traj.q, traj.p, traj.t):12.2e} "
            f"{traj.mean_newton_iterations:10.2f} {elapsed:8.2f}"
        )
    print("(the first run of a new system also compiles its kernel, about 10 s)")


if __name__ == "__main__":
    main()
