"""The tennis-racket (Dzhanibekov) flip: a free body spinning about its intermediate axis.

A free rigid body with principal moments J = (1, 2, 3) spins at omega_2 = 2
about the intermediate axis e_2, with a small perturbation about the other two.
Rotation about e_2 is unstable (Euler's equations, linearised: perturbations
grow like exp(lambda t) with lambda = omega_2 sqrt((J2 - J1)(J3 - J2) / (J1 J3))),
so the body turns over by half a turn again and again, at regular intervals,
while its angular momentum stays fixed in space.

The body is a ``gvi.RigidBody`` with a unit quaternion (the default); the
integrator keeps the energy and the body angular momentum norm |J omega| to
round-off-level bounded errors and the space angular momentum (Noether) to
round-off. The script prints those errors and the times of the flips (where
omega_2 changes sign), and draws omega(t) beside the trace of the tip of the
intermediate axis R e_2 on the unit sphere: it jumps between the poles +-L/|L|.

Run::

    python examples/tennis_racket.py [--t-final 40] [--h 0.01] [--output docs/_static]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi

PLOT_NAME = "tennis_racket.png"
INERTIA = (1.0, 2.0, 3.0)
OMEGA0 = (0.05, 2.0, 0.05)  # body frame: mostly about the intermediate axis
# the body frame turned by a quarter turn about x: e_2 (and so nearly L) along space z
ROTATION0 = ((1.0, 0.0, 0.0), (0.0, 0.0, -1.0), (0.0, 1.0, 0.0))


def simulate(t_final: float, h: float, degree: int = 2):
    """The free body's trajectory, its multibody model and its motion."""
    body = gvi.RigidBody("racket", mass=1.0, inertia=INERTIA)
    mb = gvi.Multibody([body])
    q0, v0 = mb.state(
        rotations={"racket": ROTATION0}, angular_velocities={"racket": OMEGA0}, frame="body"
    )
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(degree))
    traj = integrator.integrate(q0, v0=v0, h=h, n_steps=int(round(t_final / h)))
    return mb, traj, mb.motion(traj, "racket")


def flip_times(t: np.ndarray, omega_2: np.ndarray) -> np.ndarray:
    """The times where omega_2 changes sign, by linear interpolation between rows."""
    k = np.flatnonzero(np.sign(omega_2[1:]) != np.sign(omega_2[:-1]))
    return t[k] - omega_2[k] * (t[k + 1] - t[k]) / (omega_2[k + 1] - omega_2[k])


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-final", type=float, default=40.0)
    parser.add_argument("--h", type=float, default=0.01)
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)

    start = time.perf_counter()
    mb, traj, motion = simulate(args.t_final, args.h)
    seconds = time.perf_counter() - start
    J = np.array(INERTIA)
    w = motion.angular_velocity
    energy = traj.energy()
    body_momentum = np.linalg.norm(w * J, axis=1)
    space = np.column_stack([traj.momentum(mb.angular_momentum(axis).xi) for axis in np.eye(3)])
    rate = OMEGA0[1] * np.sqrt((J[1] - J[0]) * (J[2] - J[1]) / (J[0] * J[2]))
    flips = flip_times(traj.t, w[:, 1])
    print(f"{len(traj.t) - 1} steps of h = {args.h:g} (Galerkin(2), order 4) in {seconds:.2f} s")
    print(f"instability rate of the intermediate axis: lambda = {rate:.4f}")
    print(f"flips (omega_2 = 0) at t = {np.array2string(flips, precision=3)}")
    if len(flips) > 2:
        print(f"mean time between flips: {np.mean(np.diff(flips)):.4f}")
    print(f"max relative energy error:          {np.abs(energy / energy[0] - 1).max():.2e}")
    print(f"max relative error of |J omega|:    "
          f"{np.abs(body_momentum / body_momentum[0] - 1).max():.2e}")  # fmt: skip
    print(f"max drift of the space momentum:    {np.abs(space - space[0]).max():.2e}")
    print(f"max | |q| - 1 | of the quaternion:  "
          f"{np.abs(np.linalg.norm(motion.quaternion, axis=1) - 1).max():.2e}")  # fmt: skip
    output = args.output or Path(tempfile.mkdtemp(prefix="tennis_racket-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, motion, space[0])
    return {"flips": flips, "energy": energy, "space_momentum": space}


def plot(path: Path, motion, momentum: np.ndarray) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11, 4.6))
    ax = fig.add_subplot(1, 2, 1)
    for i, colour in enumerate(("tab:blue", "tab:orange", "tab:green")):
        ax.plot(motion.t, motion.angular_velocity[:, i], color=colour, label=rf"$\omega_{i + 1}$")
    ax.set_xlabel("t")
    ax.set_ylabel("body angular velocity")
    ax.set_title(r"$\omega(t)$, $J = (1, 2, 3)$: $\omega_2$ flips sign")
    ax.legend(loc="upper right")
    ax.grid(alpha=0.3)

    ax3 = fig.add_subplot(1, 2, 2, projection="3d")
    _unit_sphere(ax3)
    tip = motion.rotation[:, :, 1]  # R e_2, the intermediate axis in space
    dots = ax3.scatter(*tip.T, c=motion.t, cmap="viridis", s=2, depthshade=False)
    fig.colorbar(dots, ax=ax3, shrink=0.7, pad=0.1, label="t")
    ell = momentum / np.linalg.norm(momentum)
    ax3.plot(*np.column_stack([-1.3 * ell, 1.3 * ell]), color="k", lw=1.5)
    ax3.text(*(1.35 * ell), r"$L$", fontsize=12)
    ax3.set_title(r"tip of the intermediate axis $R e_2$ in space")
    _equal_axes(ax3, 1.1)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure written to {path}")


def _unit_sphere(ax) -> None:
    u, v = np.meshgrid(np.linspace(0, 2 * np.pi, 25), np.linspace(0, np.pi, 13))
    ax.plot_wireframe(np.cos(u) * np.sin(v), np.sin(u) * np.sin(v), np.cos(v), color="0.8", lw=0.5)


def _equal_axes(ax, r: float) -> None:
    ax.set_xlim(-r, r)
    ax.set_ylim(-r, r)
    ax.set_zlim(-r, r)
    ax.set_box_aspect((1, 1, 1))
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.set_zlabel("z")


if __name__ == "__main__":
    main()
