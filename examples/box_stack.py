"""A stack of boxes dropped onto the floor: each face lands flat, and the stack stands.

Three cubes of side 0.5 m and mass 1 kg (``gvi.Box``), each 1 cm sideways from the
one below and dropped from 1 mm above it. The four lower corners of the bottom
cube touch the floor (``gvi.Plane``); those of each cube above touch the upper face
of the cube below (``gvi.standing_contacts``: ``Box.face("+z")``, a plane that moves
with that cube), all with
Coulomb friction mu = 0.5 and no restitution. Each face lands flat: its four
corners are hit at once (:func:`galerkin_vi.contact.impact.simultaneous_impulse`),
which stops the cube without turning it; then the stack rests in the
complementarity steps, at heights 0.25, 0.75, 1.25 m to round-off.

The script prints the impacts and the final state, and draws the stack from the
side beside each cube's largest speed against time (down to round-off).

Run::

    python examples/box_stack.py [--boxes 3] [--seconds 2] [--output docs/_static]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi

PLOT_NAME = "box_stack.png"
HALF, MASS, GRAVITY, FRICTION = 0.25, 1.0, 9.81, 0.5


def model(boxes: int) -> tuple[gvi.Multibody, dict]:
    """The stack and the start: cube i centred 1 cm sideways per level, 1 mm up per level."""
    inertia = [MASS * (2 * HALF) ** 2 / 6] * 3
    cubes = [
        gvi.Box(gvi.RigidBody(f"box{i}", mass=MASS, inertia=inertia), [HALF] * 3)
        for i in range(boxes)
    ]
    contacts = gvi.standing_contacts(cubes[0], gvi.Plane([0, 0, 1], 0.0), friction=FRICTION)
    for lower, upper in zip(cubes, cubes[1:], strict=False):
        contacts += gvi.standing_contacts(upper, lower, friction=FRICTION)
    mb = gvi.Multibody([c.body for c in cubes], gravity=[0, 0, -GRAVITY], contacts=contacts)
    start = {f"box{i}": [0.01 * i, 0.0, HALF * (2 * i + 1) + 1e-3 * (i + 1)] for i in range(boxes)}
    return mb, start


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--boxes", type=int, default=3)
    parser.add_argument("--seconds", type=float, default=2.0)
    parser.add_argument("--h", type=float, default=0.01)
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)

    mb, start = model(args.boxes)
    q0, v0 = mb.state(positions=start)
    began = time.perf_counter()
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(1))
    traj = integrator.integrate(q0, v0=v0, h=args.h, t_span=(0.0, args.seconds))
    elapsed = time.perf_counter() - began
    print(f"{traj.message} ({elapsed:.1f} s with building and compiling)")
    for impact in traj.impacts:
        print(
            f"  t = {impact.t:.6f}  contact {impact.contact:2d}  {impact.mode:5s}"
            f"  impulse {impact.normal_impulse:.4f}  energy lost {impact.energy_lost:.2e}"
        )
    motions = {name: mb.motion(traj, name) for name in start}
    result = {"success": traj.success, "impacts": len(traj.impacts)}
    for i, (name, motion) in enumerate(motions.items()):
        height = motion.position[-1, 2] - HALF * (2 * i + 1)
        speed = max(np.abs(motion.velocity[-1]).max(), np.abs(motion.angular_velocity[-1]).max())
        print(f"{name}: height error {height:.1e} m, largest |v|, |omega| at the end {speed:.1e}")
        result[name] = (height, speed)
    path = plot(traj, motions, args.output or Path(tempfile.mkdtemp()))
    print(f"plot: {path}")
    return result


def plot(traj, motions, output: Path) -> Path:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Rectangle

    fig, (side, speeds) = plt.subplots(1, 2, figsize=(10, 4.2), width_ratios=[1, 1.6])
    colours = plt.cm.viridis(np.linspace(0.15, 0.85, len(motions)))
    for colour, (name, motion) in zip(colours, motions.items(), strict=True):
        x, z = motion.position[-1, 0], motion.position[-1, 2]
        side.add_patch(Rectangle((x - HALF, z - HALF), 2 * HALF, 2 * HALF, color=colour, alpha=0.8))
        side.text(x, z, name, ha="center", va="center", color="white")
        fast = np.maximum(
            np.abs(motion.velocity).max(axis=1), np.abs(motion.angular_velocity).max(axis=1)
        )
        speeds.semilogy(traj.t, np.maximum(fast, 1e-17), color=colour, label=name)
    side.axhline(0.0, color="k")
    side.set_xlim(-0.6, 0.6 + 0.01 * len(motions))
    side.set_ylim(-0.05, 2 * HALF * len(motions) + 0.1)
    side.set_aspect("equal")
    side.set_xlabel("x (m)")
    side.set_ylabel("z (m)")
    side.set_title(f"at t = {traj.t[-1]:g} s")
    speeds.set_xlabel("t (s)")
    speeds.set_ylabel("largest |v|, |omega| of the box")
    speeds.set_title("each face lands flat, then the stack rests")
    speeds.legend()
    fig.tight_layout()
    output.mkdir(parents=True, exist_ok=True)
    path = output / PLOT_NAME
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path


if __name__ == "__main__":
    main()
