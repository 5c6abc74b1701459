"""A die thrown onto a table: it bounces, tumbles, slides and comes to rest.

A cube of side 1 and mass 1 (a ``gvi.RigidBody`` with J = m a^2 / 6 about
every axis) carries eight contact points, its corners (``gvi.BodyPoint``),
against the table ``gvi.Plane([0, 0, 1], 0)``, with Newton's restitution
e = 0.3 and Coulomb friction. It is thrown from a height of 1 m, tilted, at 3 m/s
and rolling forward. Each impact of a corner is located on the step and resolved by the
impact law (:mod:`galerkin_vi.contact`); when corners stay on the table the
run switches to time-stepping with complementarity, until the die lies on a
face at rest with its centre at height 1/2.

The script prints the impacts (time, corner, stick or slide, energy lost), the
final pose and the energy, and draws the cube along its path in 3-D beside
the height of its centre and its energy against time.

Run::

    python examples/die_on_table.py [--seconds 3] [--friction 1.0] [--order 2]
                                    [--output docs/_static]
"""

from __future__ import annotations

import argparse
import itertools
import tempfile
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi

PLOT_NAME = "die_on_table.png"
SIDE, MASS, GRAVITY, RESTITUTION = 1.0, 1.0, 9.81, 0.3
CORNERS = 0.5 * SIDE * np.array(list(itertools.product((-1.0, 1.0), repeat=3)))
EDGES = [(i, j) for i, j in itertools.combinations(range(8), 2)
         if np.count_nonzero(CORNERS[i] != CORNERS[j]) == 1]  # fmt: skip


def model(friction: float) -> gvi.Multibody:
    moment = MASS * SIDE**2 / 6
    die = gvi.RigidBody("die", mass=MASS, inertia=[moment, moment, moment])
    table = gvi.Plane([0, 0, 1], 0.0)
    contacts = [
        gvi.BodyContact(gvi.BodyPoint(die, c), table, restitution=RESTITUTION, friction=friction)
        for c in CORNERS
    ]
    return gvi.Multibody([die], gravity=[0, 0, -GRAVITY], contacts=contacts)


def throw() -> dict:
    """Tilted by 0.7 rad about (1, 2, 0.5), 1 m up, moving along x and rolling forward."""
    axis = np.array([1.0, 2.0, 0.5]) / np.linalg.norm([1.0, 2.0, 0.5])
    quaternion = np.concatenate([[np.cos(0.35)], np.sin(0.35) * axis])
    return {
        "positions": {"die": [0.0, 0.0, 1.0]},
        "rotations": {"die": quaternion},
        "velocities": {"die": [3.0, 0.0, 0.0]},
        "angular_velocities": {"die": [0.0, 4.0, 0.0]},
        "frame": "space",
    }


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0)
    parser.add_argument("--h", type=float, default=0.01)
    parser.add_argument("--friction", type=float, default=1.0)
    parser.add_argument("--order", type=int, default=2, help="s of Galerkin(s)")
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)

    mb = model(args.friction)
    q0, v0 = mb.state(**throw())
    start = time.perf_counter()
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(args.order))
    traj = integrator.integrate(q0, v0=v0, h=args.h, t_span=(0.0, args.seconds))
    seconds = time.perf_counter() - start
    motion = mb.motion(traj, "die")
    energy = traj.energy()
    print(f"{args.seconds:g} s at h = {args.h:g} (Galerkin({args.order})) in {seconds:.1f} s: "
          f"{traj.message}")  # fmt: skip
    print(f"{len(traj.impacts)} impacts; the first ones:")
    print("      t   corner  mode   energy lost")
    for impact in traj.impacts[:8]:
        print(f"  {impact.t:.4f}   {impact.contact:4d}  {impact.mode:5s}  {impact.energy_lost:.4f}")
    print(f"energy: {energy[0]:.4f} at the throw, {energy[-1]:.4f} at t = {traj.t[-1]:g} "
          f"(at rest on a face: {MASS * GRAVITY * SIDE / 2:.4f})")  # fmt: skip
    print(f"final centre: {np.array2string(motion.position[-1], precision=4)}, "
          f"speed {np.linalg.norm(motion.velocity[-1]):.1e}, "
          f"spin {np.linalg.norm(motion.angular_velocity[-1]):.1e}")  # fmt: skip
    print(f"max | |q| - 1 | of the quaternion: "
          f"{np.abs(np.linalg.norm(motion.quaternion, axis=1) - 1).max():.2e}")  # fmt: skip
    output = args.output or Path(tempfile.mkdtemp(prefix="die_on_table-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, motion, energy)
    return {"trajectory": traj, "motion": motion, "energy": energy}


def plot(path: Path, motion, energy) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(12, 5))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    times = np.array([0.0, 0.3, 0.7, 1.15, 1.5, motion.t[-1]])
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(times)))
    for t, colour in zip(times, colours, strict=True):
        k = min(int(np.searchsorted(motion.t, t)), len(motion.t) - 1)
        corners = motion.position[k] + CORNERS @ motion.rotation[k].T
        for n, (i, j) in enumerate(EDGES):
            label = f"t = {motion.t[k]:.2f}" if n == 0 else None
            ax3.plot(*corners[[i, j]].T, color=colour, lw=1.2, label=label)
    ax3.plot(*motion.position.T, color="0.5", lw=0.8, ls="--", label="centre of mass")
    lo = motion.position[:, :2].min(axis=0) - 0.9
    hi = motion.position[:, :2].max(axis=0) + 0.9
    span = max(hi - lo)
    mid = (lo + hi) / 2
    xx, yy = np.meshgrid(*[[m - span / 2, m + span / 2] for m in mid])
    ax3.plot_surface(xx, yy, 0 * xx, color="tan", alpha=0.3)
    ax3.set_xlim(mid[0] - span / 2, mid[0] + span / 2)
    ax3.set_ylim(mid[1] - span / 2, mid[1] + span / 2)
    ax3.set_zlim(0, span / 2)
    ax3.set_box_aspect((1, 1, 0.5))
    ax3.set_xlabel("x")
    ax3.set_ylabel("y")
    ax3.set_zlabel("z")
    ax3.set_title("the die along its path")
    ax3.legend(loc="upper left", fontsize=8)

    ax = fig.add_subplot(2, 2, 2)
    ax.plot(motion.t, motion.position[:, 2], color="tab:blue")
    ax.axhline(SIDE / 2, color="k", ls="--", lw=0.8)
    ax.set_ylabel("height of the centre")
    ax.set_title(f"bounces (e = {RESTITUTION}), tumbling, rest on a face")
    ax.grid(alpha=0.3)
    ax = fig.add_subplot(2, 2, 4)
    ax.plot(motion.t, energy, color="tab:red")
    ax.axhline(MASS * GRAVITY * SIDE / 2, color="k", ls="--", lw=0.8)
    ax.set_xlabel("t")
    ax.set_ylabel("energy $H$")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure written to {path}")


if __name__ == "__main__":
    main()
