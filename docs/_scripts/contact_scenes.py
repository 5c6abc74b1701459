"""Figures of the how-to "contact": blocks on an incline, a disk that slips then rolls, a cradle.

Each scene has a closed form, drawn dashed beside the run:

- ``incline.png``: a block released at rest on a slope a = 0.5 with mu = 0.3
  (tan a > mu: it slides, s = g (sin a - mu cos a) t^2 / 2), and one launched
  down a slope a = 0.3 with mu = 0.5 at 1 m/s (tan a < mu: it stops after
  v0^2 / [2 g (mu cos a - sin a)] and sticks); the energy falls by the work of
  kinetic friction, mu g cos a per metre;
- ``rolling_disk.png``: a uniform disk (I = m R^2 / 2) launched sliding at
  3 m/s without spin, mu = 0.2: v = v0 - mu g t and R w = -2 mu g t until
  they meet at t = v0 / (3 mu g), then rolling at 2 v0 / 3; the energy falls
  by the work of friction on the slip until then, and is constant after;
- ``newtons_cradle.png``: three unit balls of diameter 1, e = 1, the first
  arriving at 1 m/s: the sequential answer (0, 0, 1) with the kinetic energy
  handed on whole.

Prints each scene's largest deviation from its closed form. Run from the
repository root::

    python docs/_scripts/contact_scenes.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

import galerkin_vi as gvi

STATIC = Path(__file__).resolve().parents[1] / "_static"
G = 9.81


def _block(angle: float, mu: float) -> gvi.LagrangianSystem:
    """A unit block on a slope: x down the slope, y off it."""
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx**2 + vy**2) / 2 + G * (x * sp.sin(angle) - y * sp.cos(angle))
    contact = gvi.Contact(y, friction=mu, slip=[vx])
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], contacts=[contact])


def _incline(plt) -> None:
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    scenes = [(0.5, 0.3, 0.0, "a = 0.5, mu = 0.3, from rest: slides"),
              (0.3, 0.5, 1.0, "a = 0.3, mu = 0.5, at 1 m/s: stops, sticks")]  # fmt: skip
    for colour, (angle, mu, v0, label) in zip(("C0", "C1"), scenes, strict=True):
        traj = gvi.Integrator(_block(angle, mu), gvi.Galerkin(2)).integrate(
            [0.0, 0.0], [v0, 0.0], h=0.01, t_span=(0.0, 1.0)
        )
        acceleration = G * (np.sin(angle) - mu * np.cos(angle))
        stop = np.inf if acceleration >= 0 else -v0 / acceleration
        t = np.minimum(traj.t, stop)
        exact = v0 * t + acceleration * t**2 / 2
        energy = traj.energy() - traj.energy()[0]
        friction_work = -mu * G * np.cos(angle) * exact
        distance_error = np.abs(traj.q[:, 0] - exact).max()
        energy_error = np.abs(energy - friction_work).max()
        print(f"incline {label}: distance off by {distance_error:.1e}, "
              f"energy off the friction work by {energy_error:.1e}")  # fmt: skip
        top.plot(traj.t, traj.q[:, 0], color=colour, lw=1.5, label=label)
        top.plot(traj.t, exact, "k--", lw=0.8)
        bottom.plot(traj.t, energy, color=colour, lw=1.5)
        bottom.plot(traj.t, friction_work, "k--", lw=0.8)
    top.plot([], [], "k--", lw=0.8, label="closed form")
    top.set_ylabel("distance down the slope (m)")
    top.legend(fontsize=8)
    top.set_title("blocks on an incline (Galerkin(2), h = 0.01)")
    bottom.set_ylabel(r"$E(t) - E(0)$ (J/kg)")
    bottom.set_xlabel("t (s)")
    bottom.text(0.02, 0.1, r"dashed: $-\mu g\cos a\, s(t)$, the work of kinetic friction",
                transform=bottom.transAxes, fontsize=8)  # fmt: skip
    fig.tight_layout()
    fig.savefig(STATIC / "incline.png", dpi=120)


def _rolling_disk(plt) -> None:
    x, y, th, vx, vy, w = sp.symbols("x y theta vx vy w")
    radius, mu, v0 = 0.5, 0.2, 3.0
    inertia = radius**2 / 2
    L = (vx**2 + vy**2) / 2 + inertia * w**2 / 2 - G * y
    contact = gvi.Contact(y - radius, friction=mu, slip=[vx + radius * w])
    disk = gvi.LagrangianSystem(L, [x, y, th], [vx, vy, w], contacts=[contact])
    traj = gvi.Integrator(disk, gvi.Galerkin(2)).integrate(
        [0.0, radius, 0.0], [v0, 0.0, 0.0], h=0.01, t_span=(0.0, 1.5)
    )
    rolling_from = v0 / (3 * mu * G)
    t = np.minimum(traj.t, rolling_from)
    v_exact = v0 - mu * G * t
    spin_exact = 2 * mu * G * t  # -R w, forward
    e_exact = v_exact**2 / 2 + inertia * (spin_exact / radius) ** 2 / 2
    v = traj.p[:, 0]
    spin = -radius * traj.p[:, 2] / inertia
    energy = traj.energy() - G * radius
    apart = np.abs(traj.t - rolling_from) > 0.02  # the switch takes its step and one more
    print(f"disk: speeds off by {np.abs(v - v_exact)[apart].max():.1e} away from the switch, "
          f"rolling at {v[-1]:.15f} (2 v0 / 3 = {2 * v0 / 3})")  # fmt: skip
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(traj.t, v, lw=1.5, label="centre speed $v$")
    top.plot(traj.t, spin, lw=1.5, label=r"rim speed $-R\omega$")
    top.plot(traj.t, v_exact, "k--", lw=0.8, label="closed form")
    top.plot(traj.t, spin_exact, "k--", lw=0.8)
    top.axvline(rolling_from, color="0.6", lw=0.8, ls=":")
    top.set_ylabel("m/s")
    top.legend(fontsize=8)
    top.set_title(r"a disk launched sliding, $\mu$ = 0.2: rolls from $v_0/(3\mu g)$ at $2v_0/3$")
    bottom.plot(traj.t, energy, lw=1.5, label="kinetic energy")
    bottom.plot(traj.t, e_exact, "k--", lw=0.8, label="closed form")
    bottom.axvline(rolling_from, color="0.6", lw=0.8, ls=":")
    bottom.set_ylabel("J/kg")
    bottom.set_xlabel("t (s)")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(STATIC / "rolling_disk.png", dpi=120)


def _cradle(plt) -> None:
    x1, x2, x3, v1, v2, v3 = sp.symbols("x1 x2 x3 v1 v2 v3")
    touching = [gvi.Contact(x2 - x1 - 1, restitution=1.0), gvi.Contact(x3 - x2 - 1, 1.0)]
    cradle = gvi.LagrangianSystem((v1**2 + v2**2 + v3**2) / 2, [x1, x2, x3], [v1, v2, v3],
                                  contacts=touching)  # fmt: skip
    traj = gvi.Integrator(cradle, gvi.Galerkin(2)).integrate(
        [-1.0, 1.0, 2.0], [1.0, 0.0, 0.0], h=0.1, n_steps=25
    )
    energy = traj.energy()
    print(f"cradle: final velocities {traj.p[-1]}, energy spread {np.ptp(energy):.1e}, "
          f"momentum spread {np.ptp(traj.p.sum(axis=1)):.1e}")  # fmt: skip
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    for a in range(3):
        top.plot(traj.t, traj.q[:, a], lw=1.5, label=f"ball {a + 1}")
        bottom.plot(traj.t, traj.p[:, a] ** 2 / 2, lw=1.5, label=f"ball {a + 1}")
    bottom.plot(traj.t, energy, "k--", lw=0.8, label="total")
    top.set_ylabel("centre (m)")
    top.legend(fontsize=8)
    top.set_title("Newton's cradle, e = 1: impacts in sequence at t = 1, answer (0, 0, v)")
    bottom.set_ylabel("kinetic energy (J/kg)")
    bottom.set_xlabel("t (s)")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(STATIC / "newtons_cradle.png", dpi=120)


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    _incline(plt)
    _rolling_disk(plt)
    _cradle(plt)
    print(f"wrote incline.png, rolling_disk.png, newtons_cradle.png in {STATIC}")


if __name__ == "__main__":
    main()
