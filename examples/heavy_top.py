"""A heavy symmetric top (Lagrange top) precessing and nutating on a ball joint.

A symmetric body (moments J1 = J2 about its centre of mass, J3 about its
symmetry axis) with its tip held at the origin by a ``gvi.joints.Spherical``
joint to the ground, its centre of mass at distance l along the symmetry axis,
in gravity g. It starts tilted by theta0 from the vertical, spinning at
omega3 about its axis, without precession: the axis falls, then precesses
about the vertical while it nods between two angles (nutation), tracing
cusps.

Two Noether momenta are conserved: about the vertical (rotations of the whole
system about the space z axis leave gravity and the joint invariant) and
about the symmetry axis (rotations of the body about its own axis). The
integrator keeps both to round-off; the script prints their drift, the
energy error and the nutation bounds theta_min, theta_max against the closed
form: with u = cos(theta), I1 = J1 + m l^2 the moment about the tip, and the
energy E and momenta p_z, p_3 of the start,

    I1^2 u'^2 = f(u) = (1 - u^2) I1 (2 E - p_3^2 / J3 - 2 m g l u) - (p_z - p_3 u)^2,

whose two roots in [-1, 1] are cos(theta_max) and cos(theta_min).

Run::

    python examples/heavy_top.py [--t-final 8] [--h 0.002] [--output docs/_static]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi

PLOT_NAME = "heavy_top.png"
MASS, LENGTH, GRAVITY = 1.0, 1.0, 9.81
J1, J3 = 0.2, 0.4  # about the centre of mass; J3 about the symmetry axis
THETA0, SPIN = 0.6, 30.0


def model() -> gvi.Multibody:
    """The top: its tip (body point (0, 0, -l)) at the origin."""
    top = gvi.RigidBody("top", mass=MASS, inertia=[J1, J1, J3])
    tip = gvi.joints.Spherical(None, top, point_a=[0, 0, 0], point_b=[0, 0, -LENGTH])
    return gvi.Multibody([top], joints=[tip], gravity=[0, 0, -GRAVITY])


def tilt(theta: float) -> np.ndarray:
    """The rotation by theta about the space x axis."""
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def nutation_bounds(energy: float, p_z: float, p_3: float) -> tuple[float, float]:
    """(theta_min, theta_max) from the roots of the cubic f(u) of the module notes."""
    i1 = J1 + MASS * LENGTH**2
    a = 2 * energy - p_3**2 / J3
    b = 2 * MASS * GRAVITY * LENGTH
    # f(u) = (1 - u^2) i1 (a - b u) - (p_z - p_3 u)^2, expanded in powers of u
    cubic = [i1 * b, -i1 * a - p_3**2, -i1 * b + 2 * p_z * p_3, i1 * a - p_z**2]
    roots = np.roots(cubic)
    real = np.sort(roots[np.abs(roots.imag) < 1e-9].real)
    inside = real[(real >= -1 - 1e-12) & (real <= 1 + 1e-12)]
    return float(np.arccos(inside.max())), float(np.arccos(inside.min()))


def main(argv: list[str] | None = None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-final", type=float, default=8.0)
    parser.add_argument("--h", type=float, default=0.002)
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)

    mb = model()
    q0, v0 = mb.state(
        rotations={"top": tilt(THETA0)}, angular_velocities={"top": [0, 0, SPIN]}, frame="body"
    )
    start = time.perf_counter()
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(2))
    traj = integrator.integrate(q0, v0=v0, h=args.h, n_steps=int(round(args.t_final / args.h)))
    seconds = time.perf_counter() - start
    motion = mb.motion(traj, "top")
    energy = traj.energy()
    vertical = traj.momentum(mb.angular_momentum([0, 0, 1]).xi)
    spin = traj.momentum(mb.angular_momentum([0, 0, 1], body="top", frame="body").xi)
    axis = motion.rotation[:, :, 2]  # R e_3, the symmetry axis in space
    theta = np.arccos(np.clip(axis[:, 2], -1, 1))
    low, high = nutation_bounds(energy[0], vertical[0], spin[0])

    print(f"{len(traj.t) - 1} steps of h = {args.h:g} (Galerkin(2)) with the run's setup "
          f"in {seconds:.2f} s")  # fmt: skip
    print(f"momentum about the vertical:      p_z = {vertical[0]:.12f}, "
          f"max drift {np.abs(vertical - vertical[0]).max():.2e}")  # fmt: skip
    print(f"momentum about the symmetry axis: p_3 = {spin[0]:.12f}, "
          f"max drift {np.abs(spin - spin[0]).max():.2e}")  # fmt: skip
    print(f"max relative energy error: {np.abs(energy / energy[0] - 1).max():.2e}")
    print(f"nutation: theta in [{theta.min():.6f}, {theta.max():.6f}] rad; "
          f"closed form [{low:.6f}, {high:.6f}]")  # fmt: skip
    print(f"max joint residual |g|: {traj.constraint_residual().max():.2e}")
    output = args.output or Path(tempfile.mkdtemp(prefix="heavy_top-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, motion.t, LENGTH * axis, theta, (low, high))
    return {"vertical": vertical, "spin": spin, "energy": energy, "theta": theta,
            "bounds": (low, high)}  # fmt: skip


def plot(path: Path, t, tip, theta, bounds) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig = plt.figure(figsize=(11, 4.6))
    ax3 = fig.add_subplot(1, 2, 1, projection="3d")
    ax3.plot(*tip.T, lw=0.8, color="tab:blue")
    ax3.plot(tip[:, 0], tip[:, 1], 0 * tip[:, 2], lw=0.5, color="0.6")  # its shadow
    for k, colour in ((0, "tab:green"), (len(t) - 1, "tab:red")):
        ax3.plot(*np.column_stack([np.zeros(3), tip[k]]), color=colour, lw=2,
                 label="axis at t = 0" if k == 0 else f"axis at t = {t[k]:g}")  # fmt: skip
    ax3.scatter([0], [0], [0], color="k", s=20)
    r = 1.05 * LENGTH
    ax3.set_xlim(-r, r)
    ax3.set_ylim(-r, r)
    ax3.set_zlim(0, r)
    ax3.set_box_aspect((2, 2, 1))
    ax3.set_xlabel("x")
    ax3.set_ylabel("y")
    ax3.set_zlabel("z")
    ax3.set_title("trace of the symmetry axis tip")
    ax3.legend(loc="upper left", fontsize=8)

    ax = fig.add_subplot(1, 2, 2)
    ax.plot(t, theta, color="tab:blue", label=r"$\theta(t)$")
    for value, name in zip(bounds, (r"$\theta_{\min}$", r"$\theta_{\max}$"), strict=True):
        ax.axhline(value, color="k", ls="--", lw=0.8)
        ax.annotate(f"{name} (closed form)", (t[-1], value), ha="right", va="bottom", fontsize=8)
    ax.set_xlabel("t")
    ax.set_ylabel(r"angle $\theta$ from the vertical (rad)")
    ax.set_title("nutation between the roots of the cubic")
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)
    print(f"figure written to {path}")


if __name__ == "__main__":
    main()
