"""The double pendulum of the how-to "models from sympy.physics.mechanics", run and plotted.

Builds the pendulum with reference frames, points and particles, takes its
Lagrangian from ``sympy.physics.mechanics.Lagrangian``, integrates it with
``gvi.LagrangianSystem.from_lagranges_method`` and draws
``docs/_static/mechanics_double_pendulum.png``: the paths of both bobs in the
plane (positions mapped back through ``system.mechanics_symbols``) and the
energy error against time. Prints the largest energy error.

Run from the repository root::

    python docs/_scripts/mechanics_models.py
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import sympy as sp
import sympy.physics.mechanics as me

import galerkin_vi as gvi

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "mechanics_double_pendulum.png"
m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g")
PARAMS = {m1: 1.0, m2: 1.0, l1: 1.0, l2: 1.0, g: 9.81}
Q0 = [1.5, 2.0]  # absolute angles from the downward vertical
V0 = [0.0, 0.0]
H = 0.01
METHOD = gvi.Galerkin(3, gvi.gauss_legendre(3))  # order 6


def double_pendulum():
    """The LagrangesMethod of the double pendulum, its frame, pivot and bobs."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    N = me.ReferenceFrame("N")
    pivot = me.Point("pivot")
    pivot.set_vel(N, 0)
    P1 = pivot.locatenew("P1", l1 * (sp.sin(q1) * N.x - sp.cos(q1) * N.y))
    P2 = P1.locatenew("P2", l2 * (sp.sin(q2) * N.x - sp.cos(q2) * N.y))
    bob1, bob2 = me.Particle("bob1", P1, m1), me.Particle("bob2", P2, m2)
    bob1.potential_energy = m1 * g * P1.pos_from(pivot).dot(N.y)
    bob2.potential_energy = m2 * g * P2.pos_from(pivot).dot(N.y)
    lm = me.LagrangesMethod(me.Lagrangian(N, bob1, bob2), [q1, q2], frame=N)
    return lm, N, pivot, (P1, P2)


def bob_paths(system: gvi.LagrangianSystem, traj: gvi.Trajectory, N, pivot, bobs) -> list:
    """(x, y) of each bob along the run, from the mechanics positions in plain symbols."""
    paths = []
    for bob in bobs:
        position = bob.pos_from(pivot).to_matrix(N)[:2]
        plain = [system.mechanics_symbols.to_plain(e) for e in position]
        place = sp.lambdify([*system.q, *PARAMS], plain, "numpy")
        paths.append(place(*traj.q.T, *PARAMS.values()))
    return paths


def plot(traj: gvi.Trajectory, paths: list, path: Path) -> None:
    """Bob paths in the plane (left) and the relative energy error (right)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_xy, ax_e) = plt.subplots(1, 2, figsize=(10, 4.2))
    for (x, y), label in zip(paths, ("bob 1", "bob 2"), strict=True):
        ax_xy.plot(x, y, lw=0.6, label=label)
    ax_xy.plot([0.0], [0.0], "ko", ms=4)
    ax_xy.set_aspect("equal")
    ax_xy.set_xlabel("x")
    ax_xy.set_ylabel("y")
    ax_xy.legend(loc="lower right", fontsize="small")
    ax_xy.set_title("paths of the bobs")
    energy = traj.energy()
    change = np.abs(energy - energy[0]) / abs(energy[0])
    shown = change > 0.0  # a log scale cannot show the exact zero at t = 0
    ax_e.semilogy(traj.t[shown], change[shown], lw=0.5)
    ax_e.set_xlabel("t")
    ax_e.set_ylabel("|H - H0| / |H0|")
    ax_e.set_title(f"energy error, Gauss s = 3 (order 6), h = {H}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> gvi.Trajectory:
    """Integrate, plot, print the largest energy error; return the trajectory."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=2000, help="number of steps (default 2000)")
    parser.add_argument("--output", type=Path, default=OUTPUT, help="the PNG to write")
    parser.add_argument("--backend", default="auto", choices=["auto", "numba", "numpy"])
    args = parser.parse_args(argv)

    lm, N, pivot, bobs = double_pendulum()
    system = gvi.LagrangianSystem.from_lagranges_method(lm, params=PARAMS)
    integrator = gvi.Integrator(system, METHOD, backend=args.backend)
    traj = integrator.integrate(Q0, v0=V0, h=H, n_steps=args.steps)
    energy = traj.energy()
    print(f"q = {list(system.q)}, v = {list(system.v)}")
    error = np.max(np.abs(energy / energy[0] - 1))
    print(f"max |H - H0| / |H0| over {args.steps} steps: {error:.1e}")
    plot(traj, bob_paths(system, traj, N, pivot, bobs), args.output)
    print(f"plot written to {args.output}")
    return traj


if __name__ == "__main__":
    main()
