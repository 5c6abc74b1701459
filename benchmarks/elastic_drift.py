"""Round-off in the energy of an elastic bouncing ball, galerkin_vi beside Störmer–Verlet.

A ball dropped from 1 m on a floor with e = 1 repeats the same flight for
ever; every method here is exact for free fall, so what its energy does over
many impacts is round-off alone. Because the flights repeat, so do their
rounding errors: they add up linearly (a drift of a fraction of an ulp per
flight) instead of as a random walk. The baseline is the textbook choice for
a ball: Störmer–Verlet with compensated (Kahan) sums of the increments and
each impact cut exactly at the root of the flight's parabola, in the same
run. Prints, per method, the relative energy error after the last impact and
its slope per impact (least squares).

Usage::

    python benchmarks/elastic_drift.py [--impacts 1000]
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np
import sympy as sp

import galerkin_vi as gvi

G, H = 9.81, 0.01


def verlet_impact_energies(impacts: int) -> np.ndarray:
    """Energy p^2 / 2 after each impact of Störmer–Verlet with compensated sums."""
    q, p, q_lost, p_lost = 1.0, 0.0, 0.0, 0.0
    energies = []
    half_kick = H * G / 2
    while len(energies) < impacts:
        half = p - half_kick
        dq = H * half
        if q + dq < 0:  # the step crosses the floor: cut it at the parabola's root
            tau = (p + math.sqrt(p * p + 2 * G * q)) / G
            p = -(p - G * tau)
            energies.append(p * p / 2)
            rest = H - tau
            q, p, q_lost, p_lost = rest * (p - G * rest / 2), p - G * rest, 0.0, 0.0
            continue
        y = dq - q_lost
        total = q + y
        q_lost, q = (total - q) - y, total
        y = -2 * half_kick - p_lost
        total = p + y
        p_lost, p = (total - p) - y, total
    return np.array(energies)


def galerkin_impact_energies(method: gvi.Galerkin, impacts: int) -> np.ndarray:
    y, vy = sp.symbols("y vy")
    ball = gvi.LagrangianSystem(
        vy**2 / 2 - G * y, [y], [vy], contacts=[gvi.Contact(y, restitution=1.0)]
    )
    flight = 2 * math.sqrt(2 / G)
    traj = gvi.Integrator(ball, method).integrate(
        [1.0], [0.0], h=H, t_span=(0.0, flight * (impacts - 0.5)), contact_mode="event"
    )
    after = [np.flatnonzero(traj.t == i.t)[-1] for i in traj.impacts]
    return traj.energy()[after]


def _row(name: str, energies: np.ndarray) -> str:
    error = energies / G - 1.0
    slope = np.polyfit(np.arange(error.size), error, 1)[0]
    return f"{name:32s} {error.size:8d} {error[-1]:12.2e} {slope:14.2e}"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--impacts", type=int, default=1000)
    args = parser.parse_args()
    methods = {
        "Galerkin(2), gauss_lobatto(3)": gvi.Galerkin(2),
        "Galerkin(2), gauss_legendre(2)": gvi.Galerkin(2, gvi.gauss_legendre(2)),
        "Galerkin(3), gauss_lobatto(4)": gvi.Galerkin(3),
        "Galerkin(3), gauss_legendre(3)": gvi.Galerkin(3, gvi.gauss_legendre(3)),
    }
    print(f"h = {H}, relative energy error after each impact (e = 1)")
    print(f"{'method':32s} {'impacts':>8s} {'last':>12s} {'per impact':>14s}")
    print(_row("Störmer–Verlet (Kahan)", verlet_impact_energies(args.impacts)))
    for name, method in methods.items():
        print(_row(name, galerkin_impact_energies(method, args.impacts)))
    return 0


if __name__ == "__main__":
    sys.exit(main())
