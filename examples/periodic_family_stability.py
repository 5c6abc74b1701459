"""A family of periodic orbits and where its stability changes: Mathieu's instability tongues.

The two-degree-of-freedom system

    L = (vx**2 + vy**2)/2 - x**2/2 - 0.81 y**2/2 - x**2 y**2

has the periodic orbits ``x = A cos t, y = 0`` of period 2 pi at every amplitude
(energy ``E = A**2/2``). Across such an orbit a small ``y`` obeys Mathieu's
equation ``y'' + (a - 2 q cos 2t) y = 0`` with ``a = 0.81 + 2E`` and ``q = -E``:
the orbit is unstable where ``(q, a)`` lies in an instability tongue, between
the Mathieu characteristic values ``b_k(|q|)`` and ``a_k(|q|)``.

``gvi.solve_periodic`` finds the orbit at a low energy, ``gvi.follow_family``
continues it in energy, and each orbit's ``floquet_multipliers`` (the
eigenvalues of its monodromy matrix, the tangent map over one period) say
whether it is linearly stable. ``family.stability_changes`` lists where the
multipliers leave or enter the unit circle; the script prints them next to the
tongue boundaries from ``scipy.special.mathieu_a`` / ``mathieu_b``, and plots
the stability index ``k = (tr M - 2)/2`` (the trivial pair of multipliers at 1
contributes 2 to the trace; the orbit is stable for ``|k| <= 1``) and the largest
multiplier modulus against the energy, to ``periodic_family_stability.png`` in
``--output`` (when matplotlib is installed).

Run::

    python examples/periodic_family_stability.py [--e-max 2.5] [--de 0.02] [--output DIR]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.optimize import brentq
from scipy.special import mathieu_a, mathieu_b

import galerkin_vi as gvi

PLOT_NAME = "periodic_family_stability.png"
OMEGA_Y2 = 0.81  # the square of y's frequency at zero amplitude


def coupled_oscillators() -> gvi.LagrangianSystem:
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx**2 + vy**2) / 2 - x**2 / 2 - sp.Rational(81, 100) * y**2 / 2 - x**2 * y**2
    return gvi.LagrangianSystem(L, [x, y], [vx, vy])


def tongue_boundaries(e_max: float) -> list[tuple[int, float, float]]:
    """The energies where a = 0.81 + 2E crosses b_k(E) and a_k(E) (E = |q|), for the
    tongues k = 1, 2, ... that start below ``e_max``."""
    tongues = []
    for k in range(1, 10):
        gap_b = lambda e, k=k: OMEGA_Y2 + 2 * e - mathieu_b(k, e)  # noqa: E731
        gap_a = lambda e, k=k: OMEGA_Y2 + 2 * e - mathieu_a(k, e)  # noqa: E731
        if gap_b(e_max) < 0:
            break
        enter = brentq(gap_b, 1e-9, e_max)
        leave = brentq(gap_a, 1e-9, 4 * e_max) if gap_a(4 * e_max) > 0 else np.inf
        tongues.append((k, enter, leave))
    return tongues


def stability_index(orbit) -> float:
    """k = (tr M - 2)/2: the transverse pair's (mu + 1/mu)/2."""
    return (float(np.trace(orbit.monodromy)) - 2.0) / 2.0


def report(family, tongues) -> None:
    print(f"{len(family)} orbits, energies {energy(family[0]):.3f} .. {energy(family[-1]):.3f}, "
          f"all converged: {all(o.success for o in family)}")  # fmt: skip
    print("stability changes (between the energies of two consecutive orbits):")
    boundaries = sorted([e for _, a, b in tongues for e in (a, b) if np.isfinite(e)])
    for change in family.stability_changes:
        low, high = change.energies
        inside = [e for e in boundaries if low <= e <= high]
        closed = f"Mathieu boundary E = {inside[0]:.4f}" if inside else "no Mathieu boundary"
        word = "becomes stable  " if change.stable else "becomes unstable"
        print(f"  {word} between E = {low:.3f} and {high:.3f}   ({closed})")
    worst = max(family, key=lambda o: abs(o.floquet_multipliers[0]))
    largest = abs(worst.floquet_multipliers[0])
    print(f"largest |multiplier| {largest:.3f} at E = {energy(worst):.3f}")


def energy(orbit) -> float:
    return float(orbit.trajectory.energy()[0])


def plot(path: Path, family, tongues) -> None:
    """Stability index and largest |multiplier| against the energy, changes marked."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: skipping the plot ({path} not written)")
        return
    orbits = [o for o in family if o.success]
    e = np.array([energy(o) for o in orbits])
    k = np.array([stability_index(o) for o in orbits])
    largest = np.array([abs(o.floquet_multipliers[0]) for o in orbits])
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5.5), sharex=True)
    top.axhspan(-1, 1, color="C2", alpha=0.12, label="stable, |k| <= 1")
    top.plot(e, k, ".-", color="C0", label="k = (tr M - 2)/2")
    bottom.semilogy(e, largest, ".-", color="C0", label="largest |multiplier|")
    for number, (_, enter, leave) in enumerate(tongues):
        for ax in (top, bottom):
            ax.axvspan(enter, min(leave, e[-1]), color="C3", alpha=0.1,
                       label="Mathieu tongue" if number == 0 and ax is top else None)  # fmt: skip
    for number, change in enumerate(family.stability_changes):
        for ax in (top, bottom):
            ax.axvline(np.mean(change.energies), color="C3", ls="--", lw=1,
                       label="stability change" if number == 0 and ax is top else None)  # fmt: skip
    top.set_ylabel("stability index k")
    top.legend(loc="upper center", fontsize=8)
    bottom.set_ylabel("max |mu|")
    bottom.set_xlabel("energy E")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--e-max", type=float, default=2.5, help="largest energy of the family")
    parser.add_argument("--de", type=float, default=0.02, help="energy step of the continuation")
    parser.add_argument("--steps", type=int, default=40, help="steps per period")
    parser.add_argument("--degree", type=int, default=3, help="Galerkin degree")
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)
    system, method = coupled_oscillators(), gvi.Galerkin(args.degree)
    start = gvi.solve_periodic(system, method, [0.2, 0.0], [0.0, 0.0], 2 * np.pi, args.steps,
                               energy=0.02)  # fmt: skip
    energies = np.arange(0.02 + args.de, args.e_max + args.de / 2, args.de)
    family = gvi.follow_family(system, method, start, energies)
    tongues = tongue_boundaries(args.e_max)
    report(family, tongues)
    output = args.output or Path(tempfile.mkdtemp(prefix="periodic_family_stability-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, family, tongues)
    return family, tongues


if __name__ == "__main__":
    main()
