"""Swing a pole up on a cart by optimal control through the discrete action (DMOC).

A cart (mass 1) carrying a pole (point mass 0.3 at length 0.5) starts at rest
with the pole hanging down and must be at rest 1 m further on, the pole
upright, after T = 2 s, with the least int u^2 dt for the force u on the cart
(|u| <= 20). ``gvi.solve_optimal_control`` makes the discrete
Lagrange–d'Alembert equations of all steps the constraints of one nonlinear
program with exact derivatives; the pole is never told how to swing. The
script prints the optimal cost for a ladder of meshes (the error falls at the
method's order 2s; the converged optimum is 58.8076675, which CasADi + IPOPT
collocation reaches too, see benchmarks/cart_pole.py) and ``--plot PATH``
draws the motion, the force and the costate of the momentum.

Run::

    python examples/cart_pole_swing_up.py [--plot docs/_static/cart_pole.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import sympy as sp

import galerkin_vi as gvi

MC, MP, LENGTH, G, T, U_MAX = 1.0, 0.3, 0.5, 9.81, 2.0, 20.0
OPTIMUM = 58.8076675


def cart_pole():
    x, th, vx, w, u = sp.symbols("x theta vx w u")
    kinetic = (MC + MP) * vx**2 / 2 + MP * LENGTH * vx * w * sp.cos(th) + MP * LENGTH**2 * w**2 / 2
    system = gvi.LagrangianSystem(kinetic + MP * G * LENGTH * sp.cos(th), [x, th], [vx, w],
                                  forces=[u, 0], params={u: 0.0})  # fmt: skip
    return system, u


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", help="write the figure here (needs matplotlib)")
    args = parser.parse_args()
    system, u = cart_pole()
    print(f"{'method':>12s} {'N':>4s} {'cost':>15s} {'- optimum':>10s} {'its':>5s} {'CPU s':>6s}")
    res = None
    for degree, N in ((2, 20), (2, 40), (3, 20), (3, 40)):
        start = time.process_time()
        res = gvi.solve_optimal_control(
            system, gvi.Galerkin(degree), [u], u**2, (0.0, T), N, [0.0, 0.0], [1.0, np.pi],
            [0.0, 0.0], [0.0, 0.0], control_bounds=(-U_MAX, U_MAX),
        )  # fmt: skip
        seconds = time.process_time() - start
        print(f"{f'Galerkin({degree})':>12s} {N:4d} {res.cost:15.9f} {res.cost - OPTIMUM:10.1e} "
              f"{res.iterations:5d} {seconds:6.2f}")  # fmt: skip
    print(f"{res.message}; largest |u| = {np.abs(res.controls).max():.3f} (bound {U_MAX})")
    if args.plot:
        _plot(res, args.plot)


def _plot(res, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    traj = res.trajectory
    top.plot(traj.t, traj.q[:, 0], "o-", ms=3, label="cart x (m)")
    top.plot(traj.t, traj.q[:, 1], "o-", ms=3, label=r"pole $\theta$ (rad, $\pi$ upright)")
    top.legend(fontsize=8)
    top.set_title(f"cart-pole swing-up by DMOC, Galerkin(3), N = {traj.t.size - 1}: "
                  f"cost {res.cost:.6f}")  # fmt: skip
    order = np.argsort(res.control_times.ravel())
    middle.plot(res.control_times.ravel()[order], res.controls[..., 0].ravel()[order], ".-",
                ms=3, label="force u at the quadrature points")  # fmt: skip
    middle.set_ylabel("N")
    middle.legend(fontsize=8)
    bottom.plot(traj.t, res.multipliers[:, 0], "o-", ms=3, label=r"costate of $p_x$")
    bottom.plot(traj.t, res.multipliers[:, 1], "o-", ms=3, label=r"costate of $p_\theta$")
    bottom.set_xlabel("t (s)")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
