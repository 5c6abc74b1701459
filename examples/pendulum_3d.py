"""A 3-D pendulum: an asymmetric rigid body on a ball joint, its centre of mass off the axis.

A body with principal moments J = (0.05, 0.08, 0.10) about its centre of mass
hangs from a ``gvi.joints.Spherical`` joint at the origin; the joint is at the
body point p = (0.05, 0.02, 0.4) (from the centre of mass, in the body frame),
so no principal axis passes through the pivot. Released tilted and spinning,
it swings and tumbles chaotically: the centre of mass moves on the sphere of
radius |p| about the pivot.

The script prints the energy error (bounded, without drift), the joint
residual and the momentum about the vertical (Noether: gravity and the joint
are invariant under rotations about the z axis through the pivot), and draws
the trace of the centre of mass in 3-D beside the energy error. ``--rotation
matrix`` runs the same body with the rotation-matrix embedding.

Run::

    python examples/pendulum_3d.py [--t-final 10] [--h 0.005] [--rotation quaternion]
                                   [--output docs/_static]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi

PLOT_NAME = "pendulum_3d.png"
INERTIA = (0.05, 0.08, 0.10)
PIVOT = (0.05, 0.02, 0.4)  # the joint, a body point (body frame, from the centre of mass)
OMEGA0 = (1.0, -2.0, 3.0)  # body frame


def model(rotation: str) -> gvi.Multibody:
    body = gvi.RigidBody("body", mass=1.0, inertia=INERTIA, rotation=rotation)
    joint = gvi.joints.Spherical(None, body, point_a=[0, 0, 0], point_b=PIVOT)
    return gvi.Multibody([body], joints=[joint], gravity=[0, 0, -9.81])


def initial_rotation() -> np.ndarray:
    """A turn of 1 rad about the axis (1, 1, 0)/sqrt(2), as a unit quaternion."""
    axis = np.array([1.0, 1.0, 0.0]) / np.sqrt(2.0)
    return np.concatenate([[np.cos(0.5)], np.sin(0.5) * axis])


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-final", type=float, default=10.0)
    parser.add_argument("--h", type=float, default=0.005)
    parser.add_argument("--rotation", choices=("quaternion", "matrix"), default="quaternion")
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)

    mb = model(args.rotation)
    # the centre of mass is placed by the joint: x = 0 - R p
    q0, v0 = mb.state(rotations={"body": initial_rotation()}, angular_velocities={"body": OMEGA0})
    start = time.perf_counter()
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(2))
    traj = integrator.integrate(q0, v0=v0, h=args.h, n_steps=int(round(args.t_final / args.h)))
    seconds = time.perf_counter() - start
    motion = mb.motion(traj, "body")
    energy = traj.energy()
    error = energy - energy[0]
    vertical = traj.momentum(mb.angular_momentum([0, 0, 1]).xi)
    half = len(error) // 2
    print(f"{args.rotation}: {len(traj.t) - 1} steps of h = {args.h:g} (Galerkin(2)) "
          f"in {seconds:.2f} s")  # fmt: skip
    first, second = np.abs(error[:half]).max(), np.abs(error[half:]).max()
    print(f"max |energy error|: {max(first, second):.2e} (first half {first:.2e}, "
          f"second half {second:.2e})")  # fmt: skip
    print(f"momentum about the vertical: max drift {np.abs(vertical - vertical[0]).max():.2e}")
    print(f"max joint residual |g|: {traj.constraint_residual().max():.2e}")
    radius = np.linalg.norm(motion.position, axis=1)
    print(f"distance of the centre of mass from the pivot: {radius.min():.15f} .. "
          f"{radius.max():.15f} (|p| = {np.linalg.norm(PIVOT):.15f})")  # fmt: skip
    output = args.output or Path(tempfile.mkdtemp(prefix="pendulum_3d-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, motion, error)
    return {"energy_error": error, "vertical": vertical}


def plot(path: Path, motion, error) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11, 4.6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    x = motion.position
    radius = np.linalg.norm(PIVOT)
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
    ax3.plot_wireframe(radius * np.cos(u) * np.sin(v), radius * np.sin(u) * np.sin(v),
                       radius * np.cos(v), color="0.85", lw=0.4)  # fmt: skip
    dots = ax3.scatter(*x.T, c=motion.t, cmap="viridis", s=1, depthshade=False)
    fig.colorbar(dots, ax=ax3, shrink=0.7, pad=0.1, label="t")
    ax3.plot(*np.column_stack([np.zeros(3), x[0]]), color="k", lw=2, label="pivot to centre, t = 0")
    ax3.scatter([0], [0], [0], color="k", s=20)
    r = 1.05 * radius
    ax3.set_xlim(-r, r)
    ax3.set_ylim(-r, r)
    ax3.set_zlim(-r, r)
    ax3.set_box_aspect((1, 1, 1))
    ax3.set_xlabel("x")
    ax3.set_ylabel("y")
    ax3.set_zlabel("z")
    ax3.set_title("centre of mass of the 3-D pendulum")
    ax3.legend(loc="upper left", fontsize=8)

    ax = fig.add_subplot(1, 2, 2)
    ax.plot(motion.t, error, lw=0.6)
    ax.set_xlabel("t")
    ax.set_ylabel(r"$H(q_k, p_k) - H_0$")
    ax.set_title("energy error: bounded, no drift")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure written to {path}")


if __name__ == "__main__":
    main()
