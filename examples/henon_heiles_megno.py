"""A MEGNO map of the Hénon–Heiles energy surface: regular tori at 2, the chaotic sea above.

The Hénon–Heiles system, L = (vx^2 + vy^2)/2 - (x^2 + y^2)/2 - x^2 y + y^3/3,
at energy E = 1/8 (or 1/6 with ``--energy``). Every start of a grid on the
Poincaré section x = 0, (y, vy), with vx > 0 fixed by the energy, is one
member of ``megno_map``: the run carries one deviation vector along the
discrete tangent map and returns the mean MEGNO Ybar at the final time
(Cincotta & Simó 2000). Ybar tends to 2 on a quasi-periodic orbit (KAM
torus), to 0 on an isochronous periodic one, and grows like lambda t / 2 in
the chaotic sea. The members run in threads (the compiled loops release the
GIL); ``executor=`` sends them to a process pool or a Dask cluster instead.

The script prints the fraction of chaotic starts (Ybar > 4) and the largest
Lyapunov exponents of one regular and one chaotic start, and draws the map.

Run::

    python examples/henon_heiles_megno.py [--grid 80] [--t-final 500] [--output hh_megno.png]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import henon_heiles
from galerkin_vi.tangent import lyapunov_spectrum, megno_map


def potential(x, y):
    return (x**2 + y**2) / 2 + x**2 * y - y**3 / 3


def section_grid(energy: float, size: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Starts (q0s, v0s) on x = 0 of the energy surface, and the mask of the grid's
    points (y, vy) inside it (vx^2 = 2 (E - V(0, y)) - vy^2 > 0)."""
    y, vy = np.meshgrid(np.linspace(-0.45, 0.75, size), np.linspace(-0.55, 0.55, size))
    vx2 = 2 * (energy - potential(0.0, y)) - vy**2
    inside = vx2 > 1e-6
    q0s = np.column_stack([np.zeros(inside.sum()), y[inside]])
    v0s = np.column_stack([np.sqrt(vx2[inside]), vy[inside]])
    return q0s, v0s, inside


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--grid", type=int, default=80, help="grid points per axis")
    parser.add_argument("--t-final", type=float, default=500.0)
    parser.add_argument("--h", type=float, default=0.1)
    parser.add_argument("--energy", type=float, default=0.125)
    parser.add_argument("--output", help="write the map here (PNG; needs matplotlib)")
    args = parser.parse_args()

    system = henon_heiles().system
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    q0s, v0s, inside = section_grid(args.energy, args.grid)
    n_steps = int(round(args.t_final / args.h))
    start = time.perf_counter()
    chaos = megno_map(integrator, q0s, v0s, h=args.h, n_steps=n_steps)
    seconds = time.perf_counter() - start
    print(f"E = {args.energy:g}: {len(chaos)} starts to t = {args.t_final:g} "
          f"in {seconds:.1f} s")  # fmt: skip
    print(f"runs that failed: {int((~chaos.success).sum())}")
    regular = np.abs(chaos.values - 2) < 0.5
    print(f"Ybar within 0.5 of 2 (regular): {regular.mean():.1%}; "
          f"Ybar > 4 (chaotic): {(chaos.values > 4).mean():.1%}")  # fmt: skip
    for label, i in (("most regular", np.argmin(np.abs(chaos.values - 2))),
                     ("most chaotic", np.argmax(chaos.values))):  # fmt: skip
        lyap = lyapunov_spectrum(integrator, q0s[i], v0s[i], h=args.h, n_steps=n_steps)
        exponents = np.round(lyap.exponents, 4)
        print(f"{label} start y = {q0s[i, 1]:+.3f}, vy = {v0s[i, 1]:+.3f}: "
              f"Ybar = {chaos.values[i]:.2f}, Lyapunov exponents {exponents}")  # fmt: skip
    if args.output:
        _plot(chaos.values, inside, args)


def _plot(values, inside, args) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    image = np.full(inside.shape, np.nan)
    image[inside] = values
    fig, ax = plt.subplots(figsize=(6.4, 5.2))
    shown = ax.imshow(
        np.clip(image, 0, 8), origin="lower", extent=(-0.45, 0.75, -0.55, 0.55),
        aspect="auto", cmap="viridis", vmin=0, vmax=8, interpolation="nearest",
    )  # fmt: skip
    fig.colorbar(shown, ax=ax, label=r"mean MEGNO $\bar Y$ (clipped at 8)")
    ax.set_xlabel("y")
    ax.set_ylabel(r"$\dot y$")
    ax.set_title(f"Hénon–Heiles, x = 0, E = {args.energy:g}, t = {args.t_final:g}")
    fig.tight_layout()
    fig.savefig(args.output, dpi=120)
    print(f"map written to {args.output}")


if __name__ == "__main__":
    main()
