"""A chain of 10 rigid links on ball joints, hanging from the ground, released from a bent pose.

Each link is a rod of length l = 0.5 (a thin cylinder: mass 1, radius 0.05)
along its body z axis. The top of link 0 is held at the origin by a
``gvi.joints.Spherical`` joint to the ground, and the bottom of link i by a
spherical joint to the top of link i + 1: 10 bodies, 70 coordinates, 10
quaternion and 30 joint constraints. The chain starts at rest, bent into a
quarter circle in the x-z plane and twisted out of it, and falls and swings
in 3-D.

``Multibody.state`` places every link from its rotation through the joints
(and projects onto the constraints). The script prints the energy error,
the largest joint residual and the time per step, and draws the chain at
several times in 3-D beside the energy error.

Run::

    python examples/chain_10.py [--links 10] [--t-final 3] [--h 0.005] [--output docs/_static]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi

PLOT_NAME = "chain_10.png"
LENGTH, MASS, RADIUS = 0.5, 1.0, 0.05


def model(n_links: int) -> gvi.Multibody:
    """Links ``link0`` (top) .. ``link{n-1}``; a link's top is its body point (0, 0, l/2)."""
    transverse = MASS * (LENGTH**2 / 12 + RADIUS**2 / 4)
    links = [
        gvi.RigidBody(f"link{i}", mass=MASS, inertia=[transverse, transverse, MASS * RADIUS**2 / 2])
        for i in range(n_links)
    ]
    top, bottom = [0, 0, LENGTH / 2], [0, 0, -LENGTH / 2]
    joints = [gvi.joints.Spherical(None, links[0], point_a=[0, 0, 0], point_b=top)]
    joints += [
        gvi.joints.Spherical(a, b, point_a=bottom, point_b=top)
        for a, b in zip(links[:-1], links[1:], strict=False)
    ]
    return gvi.Multibody(links, joints=joints, gravity=[0, 0, -9.81])


def bent_pose(n_links: int) -> dict[str, np.ndarray]:
    """Rotations of the links: turned about y by angles growing to a quarter turn along
    the chain (its axis goes from hanging down to horizontal), then about z by a twist
    growing along the chain."""
    rotations = {}
    for i in range(n_links):
        s = (i + 0.5) / n_links
        a, b = 0.5 * np.pi * s, 0.6 * s
        ry = np.array([[np.cos(a), 0, np.sin(a)], [0, 1, 0], [-np.sin(a), 0, np.cos(a)]])
        rz = np.array([[np.cos(b), -np.sin(b), 0], [np.sin(b), np.cos(b), 0], [0, 0, 1]])
        rotations[f"link{i}"] = rz @ ry
    return rotations


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--links", type=int, default=10)
    parser.add_argument("--t-final", type=float, default=3.0)
    parser.add_argument("--h", type=float, default=0.005)
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)

    start = time.perf_counter()
    mb = model(args.links)
    q0, v0 = mb.state(rotations=bent_pose(args.links))
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(2))
    integrator.integrate(q0, v0=v0, h=args.h, n_steps=1)  # builds and compiles the model
    setup = time.perf_counter() - start
    n_steps = int(round(args.t_final / args.h))
    start = time.perf_counter()
    traj = integrator.integrate(q0, v0=v0, h=args.h, n_steps=n_steps)
    seconds = time.perf_counter() - start
    energy = traj.energy()
    error = energy - energy[0]
    system = mb.system
    print(f"{args.links} links: n = {system.n} coordinates, m = {system.m} constraints; "
          f"model built and compiled in {setup:.1f} s")  # fmt: skip
    print(f"{n_steps} steps of h = {args.h:g} (Galerkin(2)) in {seconds:.2f} s "
          f"({1e6 * seconds / n_steps:.0f} us per step)")  # fmt: skip
    print(f"max |energy error|: {np.abs(error).max():.2e} (energy range of the motion "
          f"{np.ptp(mb_potential(mb, traj)):.2f})")  # fmt: skip
    print(f"max joint residual |g|: {traj.constraint_residual().max():.2e}")
    output = args.output or Path(tempfile.mkdtemp(prefix="chain_10-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, mb, traj, error, args.links)
    return {"energy_error": error}


def mb_potential(mb: gvi.Multibody, traj) -> np.ndarray:
    """The gravitational energy of the chain at every row (for the scale of the error)."""
    z = sum(mb.motion(traj, name).position[:, 2] for name in mb.bodies)
    return 9.81 * MASS * z


def link_ends(mb: gvi.Multibody, traj, rows) -> np.ndarray:
    """The joint points (n_links + 1, 3) of the chain at each of ``rows``."""
    out = []
    for k in rows:
        points = [np.zeros(3)]
        for name in mb.bodies:
            motion = mb.motion(traj, name)
            points.append(motion.position[k] + motion.rotation[k] @ [0, 0, -LENGTH / 2])
        out.append(np.array(points))
    return np.array(out)


def plot(path: Path, mb, traj, error, n_links: int) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11, 5))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    rows = np.linspace(0, len(traj.t) - 1, 6).astype(int)
    colours = plt.cm.viridis(np.linspace(0, 0.9, len(rows)))
    for chain, k, colour in zip(link_ends(mb, traj, rows), rows, colours, strict=True):
        ax3.plot(*chain.T, "-o", color=colour, ms=2.5, lw=1.5, label=f"t = {traj.t[k]:.2f}")
    ax3.scatter([0], [0], [0], color="k", s=30, marker="^")
    r = n_links * LENGTH
    ax3.set_xlim(-0.7 * r, 0.7 * r)
    ax3.set_ylim(-0.7 * r, 0.7 * r)
    ax3.set_zlim(-r, 0.1 * r)
    ax3.set_box_aspect((1.4, 1.4, 1.1))
    ax3.set_xlabel("x")
    ax3.set_ylabel("y")
    ax3.set_zlabel("z")
    ax3.set_title(f"{n_links} rigid links on ball joints")
    ax3.legend(loc="upper left", fontsize=7)

    ax = fig.add_subplot(1, 2, 2)
    ax.plot(traj.t, error, lw=0.6)
    ax.set_xlabel("t")
    ax.set_ylabel(r"$H(q_k, p_k) - H_0$")
    ax.set_title("energy error of the chain")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure written to {path}")


if __name__ == "__main__":
    main()
