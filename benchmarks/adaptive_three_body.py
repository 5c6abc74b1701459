r"""Adaptive steps on a restricted three-body orbit with close approaches to both primaries.

The Arenstorf orbit of the planar circular restricted three-body problem in the
rotating frame (Hairer, Nørsett & Wanner, *Solving ODEs I*, section II.0):

.. math::

    L = \tfrac12\big((\dot x - y)^2 + (\dot y + x)^2\big) + \frac{1-\mu}{r_1} + \frac{\mu}{r_2},
    \qquad r_1 = |(x + \mu, y)|,\quad r_2 = |(x - 1 + \mu, y)|,

:math:`\mu = 0.012277471`, velocity-linear Coriolis terms in L. From
:math:`q_0 = (0.994, 0)`, :math:`v_0 = (0, -2.0015851063790825\ldots)` the orbit is
periodic with period :math:`T = 17.06521656015796\ldots`; it starts 0.006 from
the Moon and passes the Earth. For each method and step-size function g
(both distances, the Moon's or the Earth's only, the default read off L) and
each fictitious step h the table gives the return error
:math:`\max|q(T) - q_0|`, the steps, CPU time, iterations per step and CPU
time per step; then per (method, g) whether the error decreases with h down to
the floor 1e-12 and whether any h failed after a larger one succeeded; and the
CPU time to a return error of 1e-10 (log-log interpolation), default g against
the best hand-chosen g. ``--fixed-point`` picks the stage iteration:
``persistent`` (the adaptive integrator's default: the fixed point, handing over to
Newton only when it diverges), ``on`` (``fixed_point=True``: it hands over as soon as
its sweeps contract slowly) or ``off`` (Newton only, the loop the adaptive runs took
before issue 30).

Usage::

    python benchmarks/adaptive_three_body.py
    python benchmarks/adaptive_three_body.py --methods 4 --g both moon default
    python benchmarks/adaptive_three_body.py --fixed-point off
"""

from __future__ import annotations

import argparse
import math
import sys
import time
import warnings
from collections.abc import Sequence

import numpy as np
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.tools.benchmark import time_to_error

MU = 0.012277471
Q0 = np.array([0.994, 0.0])
V0 = np.array([0.0, -2.00158510637908252240537862224])
PERIOD = 17.0652165601579625588917206249
STEPS = (0.1, 0.05, 0.02, 0.01, 0.005, 0.002)
FLOOR = 1e-12
TARGET = 1e-10


def arenstorf() -> tuple[gvi.LagrangianSystem, sp.Expr, sp.Expr]:
    """The system in the rotating frame and the distances to the Earth and the Moon."""
    x, y, vx, vy = sp.symbols("x y vx vy")
    r1 = sp.sqrt((x + MU) ** 2 + y**2)
    r2 = sp.sqrt((x - 1 + MU) ** 2 + y**2)
    L = ((vx - y) ** 2 + (vy + x) ** 2) / 2 + (1 - MU) / r1 + MU / r2
    return gvi.LagrangianSystem(L, [x, y], [vx, vy]), r1, r2


def step_functions(r1: sp.Expr, r2: sp.Expr) -> dict[str, sp.Expr | None]:
    return {
        "both": gvi.encounter_scaling([r1, r2], 1.5),
        "moon": gvi.encounter_scaling([r2], 1.5),
        "earth": gvi.encounter_scaling([r1], 1.5),
        "default": None,
    }


def sweep(adaptive: gvi.AdaptiveIntegrator, steps: Sequence[float], repeats: int) -> list[dict]:
    """One row per h: status, steps, return error, best-of CPU time, iterations."""
    adaptive.integrate(Q0, V0, h=steps[0], n_steps=2)  # compile / load before timing
    rows = []
    for h in steps:
        best = math.inf
        for _ in range(repeats):
            start = time.process_time()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                traj = adaptive.integrate(Q0, V0, h=h, t_final=PERIOD, save_every=1000)
            best = min(best, time.process_time() - start)
        steps_taken = max(int(traj.n_steps), 1)
        rows.append({
            "h": h,
            "ok": bool(traj.success),
            "t_end": float(traj.t[-1]),
            "steps": int(traj.n_steps),
            "error": float(np.abs(traj.q[-1] - Q0).max()) if traj.success else math.nan,
            "time": best,
            "its": traj.total_newton_iterations / steps_taken,
            "us_per_step": 1e6 * best / steps_taken,
        })  # fmt: skip
    return rows


def behaves(rows: list[dict]) -> tuple[bool, bool]:
    """(error monotone in h down to FLOOR, no failure after a larger h succeeded)."""
    monotone = True
    worst = math.inf
    for row in rows:
        if not row["ok"]:
            continue
        if row["error"] > max(worst, FLOOR):
            monotone = False
        worst = min(worst, max(row["error"], FLOOR))
    succeeded = False
    no_failure = True
    for row in rows:
        succeeded |= row["ok"]
        if succeeded and not row["ok"]:
            no_failure = False
    return monotone, no_failure


#: --fixed-point: the Integrator's fixed_point of each choice
FIXED_POINT = {"persistent": "persistent", "on": True, "off": False}


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--methods", nargs="+", type=int, default=[2, 4, 6], help="Gauss(s)")
    parser.add_argument("--g", nargs="+", default=["both", "moon", "earth", "default"])
    parser.add_argument("--steps", nargs="+", type=float, default=list(STEPS))
    parser.add_argument("--fixed-point", choices=list(FIXED_POINT), default="persistent")
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args(argv)
    system, r1, r2 = arenstorf()
    choices = step_functions(r1, r2)
    print(f"fixed_point={args.fixed_point}")
    head = ("method", "g", "h", "ok", "steps", "error", "CPU ms", "its/step", "us/step")
    print("{:<9} {:<8} {:>6} {:>3} {:>7} {:>9} {:>8} {:>8} {:>8}".format(*head))
    summary = []
    for s in args.methods:
        method = gvi.Galerkin(s, gvi.gauss_legendre(s))
        costs = {}
        for name in args.g:
            adaptive = gvi.AdaptiveIntegrator(
                system, method, g=choices[name], fixed_point=FIXED_POINT[args.fixed_point]
            )
            rows = sweep(adaptive, args.steps, args.repeats)
            for row in rows:
                print(
                    f"Gauss({s})  {name:<8} {row['h']:>6} {'yes' if row['ok'] else 'NO':>3} "
                    f"{row['steps']:>7d} {row['error']:>9.2e} {1e3 * row['time']:>8.2f} "
                    f"{row['its']:>8.2f} {row['us_per_step']:>8.2f}"
                )
            monotone, no_failure = behaves(rows)
            hit = time_to_error([r for r in rows if r["ok"]], TARGET)
            costs[name] = None if hit is None else hit["time"]
            summary.append((f"Gauss({s})", name, monotone, no_failure, costs[name]))
        hand = [costs[n] for n in ("both", "moon", "earth") if costs.get(n) is not None]
        if costs.get("default") is not None and hand:
            print(f"Gauss({s}): default g / best hand-chosen g in CPU time to {TARGET:.0e}: "
                  f"{costs['default'] / min(hand):.2f}")  # fmt: skip
    print("\nmethod    g        monotone  no-failure  CPU ms to 1e-10")
    for label, name, monotone, no_failure, cost in summary:
        cost_text = "not reached" if cost is None else f"{1e3 * cost:.2f}"
        print(f"{label:<9} {name:<8} {str(monotone):<9} {str(no_failure):<11} {cost_text}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
