"""The figure-eight choreography of three equal masses, found from a curve drawn by hand.

Three unit masses attract as 1/r (G = 1). ``gvi.solve_periodic`` looks for
a closed path of the discrete action with the period fixed at
T = 6.32591398292621 (Chenciner & Montgomery's orbit), starting from a
lemniscate (sin phi, 0.35 sin 2 phi) that every body runs a third of a period
apart: no initial state at all. The translations and the rotation of the
plane are symmetries of L: their directions are removed from Newton's steps
(``symmetries=``), as is the shift in time. The script prints the orbit's
energy, angular momentum, action and how far it is from a choreography
(q2(t) = q1(t + T/3), q3(t) = q1(t + 2T/3)), beside the known values E = -1.287141995631852,
L = 0 and S = -3 E T = 24.42704864453 (virial theorem), for two meshes.

Run::

    python examples/figure_eight.py [--plot docs/_static/figure_eight.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import n_body

PERIOD, ENERGY = 6.32591398292621, -1.287141995631852


def three_bodies() -> tuple[gvi.LagrangianSystem, list]:
    """Three unit masses, G = 1, unsoftened (the library's planar N-body problem), and the
    generators of its symmetries: the translations in x and y and the rotation."""
    problem = n_body(masses=(1.0, 1.0, 1.0), softening=0.0)
    names = ("translation_x", "translation_y", "rotation")
    return problem.system, [problem.symmetries[name] for name in names]


def lemniscate(t: float) -> np.ndarray:
    """The rough guess: a figure eight drawn by hand, the bodies a third of a period apart."""
    phases = 2 * np.pi * t / PERIOD + np.array([0.0, 2.0, 4.0]) * np.pi / 3
    return np.column_stack([np.sin(phases), 0.35 * np.sin(2 * phases)]).ravel()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", help="write the figure here (needs matplotlib)")
    args = parser.parse_args()
    system, symmetries = three_bodies()
    print(f"{'mesh':>14s} {'its':>4s} {'E - E*':>10s} {'max|L|':>9s} {'S - (-3ET)':>11s} "
          f"{'choreography':>12s} {'CPU s':>6s}")  # fmt: skip
    orbit = None
    for degree, N in ((4, 60), (6, 90)):
        start = time.process_time()
        orbit = gvi.solve_periodic(system, gvi.Galerkin(degree), lemniscate, None, PERIOD, N,
                                   symmetries=symmetries)  # fmt: skip
        seconds = time.process_time() - start
        traj = orbit.trajectory
        nodes = traj.q[:-1]
        # the guess runs body 2 a third of a period ahead of body 1, body 3 two thirds
        ahead = [np.roll(nodes[:, 0:2], -j * N // 3, axis=0) for j in (1, 2)]
        choreography = max(np.abs(nodes[:, 2:4] - ahead[0]).max(),
                           np.abs(nodes[:, 4:6] - ahead[1]).max())  # fmt: skip
        angular = np.abs(traj.momentum(symmetries[2])).max()
        virial = orbit.action + 3 * ENERGY * PERIOD
        print(f"{f'Galerkin({degree}), N={N}':>14s} {orbit.iterations:4d} "
              f"{traj.energy()[0] - ENERGY:10.1e} {angular:9.1e} "
              f"{virial:11.1e} {choreography:12.1e} {seconds:6.2f}")  # fmt: skip
    print(f"{orbit.message}; action {orbit.action:.11f} (24.42704864453)")
    if args.plot:
        _plot(orbit, args.plot)


def _plot(orbit, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 3.6))
    t = np.linspace(0, PERIOD, 400)
    guess = np.array([lemniscate(s) for s in t])
    ax.plot(guess[:, 0], guess[:, 1], color="0.6", ls=":", label="guess (drawn by hand)")
    x = np.linspace(0, PERIOD, 600)
    path_ = orbit.trajectory.dense()(x)
    ax.plot(path_[:, 0], path_[:, 1], lw=1.5, color="C0", label="solve_periodic")
    for body, colour in zip(range(3), ("C0", "C1", "C2"), strict=True):
        ax.plot(*orbit.trajectory.q[0, 2 * body : 2 * body + 2], "o", color=colour, ms=7)
    ax.set_aspect("equal")
    ax.set_title(f"figure eight: T = {PERIOD}, E = {orbit.trajectory.energy()[0]:.12f}")
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
