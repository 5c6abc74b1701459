"""The Poincaré section of the how-to "events and Poincaré sections", computed and drawn.

Hénon–Heiles at H = 1/8 (``galerkin_vi.problems.henon_heiles``), the section
x = 0 with p_x > 0, located as the upward crossings of x by
``gvi.Event(x, direction=1)``. Orbits start on the section at (0, y0) with
momentum (p_x, p_y0), p_x > 0 from the energy. The library default (y0 = -0.2,
p_y0 = 0, in the chaotic sea) runs for about 10^4 crossings; seven orbits in
the three large islands and the outer band for about 500 each. The method is
Gauss s = 4 (order 8) at h = 0.2.

Draws ``docs/_static/poincare_henon_heiles.png`` (y against p_y at the crossings)
and prints, per orbit, the number of crossings, the CPU time of the run and the
largest energy error at the crossings.

Run from the repository root::

    python docs/_scripts/poincare_section.py
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

import galerkin_vi as gvi
from galerkin_vi import problems

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "poincare_henon_heiles.png"
ENERGY = 0.125
H = 0.2
METHOD = gvi.Galerkin(4, gvi.gauss_legendre(4))  # order 8
#: (y0, p_y0, t_final): the chaotic default for about 10^4 crossings, then regular orbits
ORBITS = ((-0.2, 0.0, 66_400.0), (0.1, 0.0, 3_300.0), (0.2, 0.0, 3_300.0),
          (-0.05, 0.22, 3_300.0), (-0.1, 0.25, 3_300.0), (-0.05, -0.28, 3_300.0),
          (0.0, -0.3, 3_300.0), (-0.36, 0.0, 3_300.0))  # fmt: skip


def energy(q, p):
    x, y = q[:, 0], q[:, 1]
    return 0.5 * (p**2).sum(axis=1) + 0.5 * (x**2 + y**2) + x**2 * y - y**3 / 3


def sections(integrator: gvi.Integrator) -> list[dict]:
    """Each orbit's crossings (y, p_y), CPU time and largest energy error at the crossings."""
    out = []
    x = integrator.system.q[0]
    for y0, py0, t_final in ORBITS:
        potential = y0**2 / 2 - y0**3 / 3  # V(0, y0)
        px0 = np.sqrt(2 * (ENERGY - potential) - py0**2)
        start = time.process_time()
        traj = integrator.integrate(
            [0.0, y0], [px0, py0], h=H, t_span=(0.0, t_final), events=gvi.Event(x, direction=1)
        )
        seconds = time.process_time() - start
        q, p = traj.q_events[0], traj.p_events[0]
        out.append({
            "y0": y0,
            "py0": py0,
            "t_final": t_final,
            "y": q[:, 1],
            "py": p[:, 1],
            "seconds": seconds,
            "energy_error": float(np.max(np.abs(energy(q, p) - ENERGY))),
        })  # fmt: skip
    return out


def plot(orbits: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7.5, 6.2))
    for orbit in orbits:
        chaotic = orbit is orbits[0]
        ax.plot(
            orbit["y"],
            orbit["py"],
            ".",
            ms=0.8 if chaotic else 1.2,
            color="0.25" if chaotic else None,
            label=f"({orbit['y0']:g}, {orbit['py0']:g}): {orbit['y'].size} crossings",
        )
    ax.set_xlabel("y")
    ax.set_ylabel("p_y")
    ax.set_title("Hénon–Heiles, H = 1/8: section x = 0, p_x > 0 (Gauss s = 4, h = 0.2)")
    ax.legend(loc="upper right", fontsize="x-small", markerscale=8, title="(y0, p_y0)")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> list[dict]:
    """Compute the sections, print a line per orbit, draw the figure."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=OUTPUT, help="the PNG to write")
    args = parser.parse_args(argv)
    integrator = gvi.Integrator(problems.henon_heiles().system, METHOD)
    integrator.integrate([0.0, -0.2], [0.45, 0.0], h=H, n_steps=10)  # warm: untimed
    orbits = sections(integrator)
    for o in orbits:
        print(
            f"(y0, p_y0) = ({o['y0']:>5g}, {o['py0']:>5g}): t_final = {o['t_final']:>5g}, "
            f"{o['y'].size:>4} crossings, {o['seconds']:.2f} s CPU, "
            f"max |H - 1/8| at the crossings {o['energy_error']:.1e}"
        )
    plot(orbits, args.output)
    print(f"plot written to {args.output}")
    return orbits


if __name__ == "__main__":
    main()
