"""The rimless wheel walking down a slope: a limit cycle of plastic impacts.

A hub of mass m with N massless spokes of length l (and inertia I about the
hub) rolls down a slope of angle gamma on its spoke tips: each spoke tip is a
contact (the tip's height above the slope) with restitution 0 and friction
enough to stick, and the stance spoke is a persistent contact, handled by the
complementarity step of :mod:`galerkin_vi.contact`. Each new spoke hits the
ground during a time-stepping phase; the step is cut at the impact, whose
plastic, sticking impulse keeps the angular momentum about the new tip:

    omega+ / omega- = r = (m l^2 cos 2 alpha + I) / (m l^2 + I),  alpha = pi / N.

Between impacts the wheel vaults over the stance tip and gains the energy of a
drop of 2 l sin(alpha) sin(gamma), so the motion settles on the limit cycle

    omega-^2 = 4 m g l sin(alpha) sin(gamma) / ((m l^2 + I) (1 - r^2)),

the classic result of McGeer's passive walkers. The script prints the angular
velocity before and after each impact beside these closed forms and, with
``--plot PATH``, draws them with the energy lost at each impact against the
drop of one stride (it takes about 15 s: the complementarity
steps of ten contacts run in Python).

Run::

    python examples/rimless_wheel.py [--plot docs/_static/rimless_wheel.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import sympy as sp

import galerkin_vi as gvi

N, LENGTH, MASS, INERTIA, SLOPE, FRICTION, G = 10, 1.0, 1.0, 0.1, 0.2, 1.5, 9.81


def rimless_wheel() -> gvi.LagrangianSystem:
    """Hub (x along the slope, y off it), spoke angle theta; one contact per spoke tip."""
    x, y, th, vx, vy, w = sp.symbols("x y theta vx vy w")
    L = (
        MASS * (vx**2 + vy**2) / 2
        + INERTIA * w**2 / 2
        + MASS * G * (x * sp.sin(SLOPE) - y * sp.cos(SLOPE))
    )
    contacts = []
    for i in range(N):
        angle = th + 2 * sp.pi * i / N
        tip_height = y - LENGTH * sp.cos(angle)
        tip_speed = vx + LENGTH * sp.cos(angle) * w  # along the slope
        contacts.append(gvi.Contact(tip_height, friction=FRICTION, slip=[tip_speed]))
    return gvi.LagrangianSystem(L, [x, y, th], [vx, vy, w], contacts=contacts)


def limit_cycle() -> tuple[float, float, float]:
    """(r, omega-, omega+) of the closed form."""
    alpha = np.pi / N
    r = (MASS * LENGTH**2 * np.cos(2 * alpha) + INERTIA) / (MASS * LENGTH**2 + INERTIA)
    gain = 4 * MASS * G * LENGTH * np.sin(alpha) * np.sin(SLOPE)
    before = np.sqrt(gain / ((MASS * LENGTH**2 + INERTIA) * (1 - r**2)))
    return r, before, r * before


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", help="write the figure here (needs matplotlib)")
    parser.add_argument("--seconds", type=float, default=4.0)
    args = parser.parse_args()
    integrator = gvi.Integrator(rimless_wheel(), gvi.Galerkin(2))
    # on spoke 0, its tip ahead of the hub (theta = alpha - 0.05), rolling forward
    theta0, omega0 = np.pi / N - 0.05, -2.2
    q0 = [0.0, LENGTH * np.cos(theta0), theta0]
    v0 = [-LENGTH * np.cos(theta0) * omega0, -LENGTH * np.sin(theta0) * omega0, omega0]
    start = time.perf_counter()
    traj = integrator.integrate(q0, v0, h=0.01, t_span=(0.0, args.seconds))
    seconds = time.perf_counter() - start
    r, before, after = limit_cycle()
    print(
        f"{len(traj.impacts)} impacts in {args.seconds} s ({seconds:.1f} s of CPU); {traj.message}"
    )
    print(f"closed form: omega- = {before:.6f}, omega+ = {after:.6f}, ratio r = {r:.6f}")
    print(f"{'t':>8s} {'spoke':>5s} {'omega-':>10s} {'omega+':>10s} {'ratio':>10s}")
    rows = []
    for impact in traj.impacts:
        at = np.flatnonzero(traj.t == impact.t)
        w_minus, w_plus = -traj.p[at[0], 2] / INERTIA, -traj.p[at[1], 2] / INERTIA
        rows.append((impact.t, w_minus, w_plus))
        print(f"{impact.t:8.4f} {impact.contact:5d} {w_minus:10.6f} {w_plus:10.6f} "
              f"{w_plus / w_minus:10.6f}")  # fmt: skip
    forces = traj.contact_forces
    print(
        f"interior point: {forces.iterations.max()} iterations at most, "
        f"{forces.iterations.mean():.1f} on average; complementarity "
        f"{forces.complementarity.max():.1e} at most"
    )
    if args.plot:
        _plot(traj, np.array(rows), before, after, args.plot)


def _plot(traj, rows, before, after, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, middle, bottom) = plt.subplots(3, 1, figsize=(7, 7), sharex=True)
    top.plot(traj.t, -traj.p[:, 2] / INERTIA, lw=1, label=r"$-\omega$ (forward)")
    top.axhline(before, color="C3", ls="--", lw=0.8, label=r"limit cycle $\omega^-$")
    top.axhline(after, color="C2", ls="--", lw=0.8, label=r"limit cycle $\omega^+$")
    top.set_ylabel("angular velocity (rad/s)")
    top.legend(loc="lower right", fontsize=8)
    top.set_title(f"rimless wheel, {N} spokes, slope {SLOPE} rad: plastic impacts, sticking feet")
    # on the cycle each impact takes what one stride's drop gives: m g 2 l sin(alpha) sin(gamma)
    stride = 2 * MASS * G * LENGTH * np.sin(np.pi / N) * np.sin(SLOPE)
    lost = [impact.energy_lost for impact in traj.impacts]
    middle.plot(rows[:, 0], lost, "o", ms=3, label="energy lost at each impact")
    middle.axhline(stride, color="k", ls="--", lw=0.8, label="drop of one stride (limit cycle)")
    middle.set_ylabel("J")
    middle.legend(loc="upper right", fontsize=8)
    bottom.semilogy(rows[:, 0], np.abs(rows[:, 1] - before), "o-", ms=3,
                    label=r"$|\omega^-_k - \omega^-_\ast|$")  # fmt: skip
    bottom.set_xlabel("t (s)")
    bottom.set_ylabel("distance to the cycle")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
