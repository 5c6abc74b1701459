"""Time-adaptive (Poincaré) against fixed steps: CPU time to a final error.

For each problem and method, two work-precision curves in this process: fixed
steps of the method on the system, and fixed fictitious steps on the Poincaré
transformed system (:class:`galerkin_vi.AdaptiveIntegrator`, ``g = r^alpha``)
landing exactly on the final time. Error: the largest position error at the
final time against the exact solution (Kepler) or a tight reference (outer
solar system). The table gives the CPU time to reach each target, interpolated
in log-log between measured points, the steps taken, the largest energy error
along the run, and the ratio best fixed / best adaptive.

Usage::

    python benchmarks/adaptive.py                              # Kepler e = 0.6, 0.9
    python benchmarks/adaptive.py --problems kepler-0.9 --periods 100 --json out.json
    python benchmarks/adaptive.py --rounds 3     # three alternating rounds of both curves
    python benchmarks/adaptive.py --problems outer_solar_system
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.benchmark import time_to_error
from galerkin_vi.problems import gravitation
from galerkin_vi.problems.base import ode_reference

TARGETS = (1e-6, 1e-8)
METHODS = (("Gauss(3)", 3, "gauss"), ("Gauss(4)", 4, "gauss"), ("Lobatto(4)", 3, "lobatto"))


@dataclass
class Case:
    """A problem as the two curves need it."""

    name: str
    system: gvi.LagrangianSystem
    q0: np.ndarray
    v0: np.ndarray
    t_final: float
    exact: Callable[[], np.ndarray]  # positions at t_final
    g: sp.Expr
    fixed_steps: Sequence[int]  # step counts of the fixed-step curve
    fictitious: Sequence[float]  # fictitious step sizes of the adaptive curve
    params: dict | None = None


def kepler_case(e: float, periods: int) -> Case:
    prob = gravitation.kepler(e)
    x, y = prob.system.q
    r = sp.sqrt(x**2 + y**2)
    t_final = 2 * math.pi * periods
    per = [2**k for k in range(7, 20)]
    return Case(
        name=f"kepler-{e}",
        system=prob.system,
        q0=prob.q0,
        v0=prob.v0,
        t_final=t_final,
        exact=lambda: gravitation.kepler_position(t_final, e),
        g=gvi.encounter_scaling([r], 1.5),
        fixed_steps=[periods * n for n in per],
        fictitious=[0.4 / 2**k for k in range(0, 9)],
    )


def solar_case(days: float) -> Case:
    prob = gravitation.outer_solar_system(days)
    q = prob.system.q
    sun = sp.Matrix(q[0:3])
    # the planets' distances to the Sun: the orbits' time scales
    distances = [sp.sqrt(sum((sp.Matrix(q[3 * i : 3 * i + 3]) - sun).applyfunc(lambda c: c**2)))
                 for i in range(1, 6)]  # fmt: skip
    reference = ode_reference(prob.system, prob.q0, prob.v0, days, params=prob.params)
    return Case(
        name="outer_solar_system",
        system=prob.system,
        q0=prob.q0,
        v0=prob.v0,
        t_final=days,
        exact=lambda: reference,
        g=gvi.encounter_scaling(distances, 1.5)
        / gvi.encounter_scaling(distances, 1.5).subs(dict(zip(q, prob.q0, strict=True))),
        fixed_steps=[int(days / h) for h in (200.0, 100.0, 50.0, 25.0, 12.5)],
        fictitious=[200.0 / 2**k for k in range(0, 5)],
        params=prob.params,
    )


def method_of(s: int, family: str) -> gvi.Galerkin:
    rule = gvi.gauss_legendre(s) if family == "gauss" else gvi.gauss_lobatto(s + 1)
    return gvi.Galerkin(s, rule)


def _cpu(fn) -> tuple[float, object]:
    start = time.process_time()
    out = fn()
    return time.process_time() - start, out


def curve(run: Callable[[float], gvi.Trajectory], params: Sequence, exact, repeats: int,
          budget: float) -> list[dict]:  # fmt: skip
    """Error, energy error, steps and best-of CPU time at each parameter, cheapest first."""
    points = []
    for value in params:
        best = math.inf
        traj = None
        try:
            for _ in range(repeats):
                seconds, traj = _cpu(lambda v=value: run(v))
                best = min(best, seconds)
        except gvi.ConvergenceError:
            continue  # too coarse a step for the iteration: no point
        energy = traj.energy()
        points.append({
            "param": value,
            "steps": int(traj.n_steps),
            "time": best,
            "error": float(np.abs(traj.q[-1] - exact).max()),
            "energy": float(np.abs(energy - energy[0]).max() / max(1.0, abs(energy[0]))),
            "iterations": traj.total_newton_iterations / max(traj.n_steps, 1),
        })  # fmt: skip
        if points[-1]["error"] < 1e-12 or best > budget:
            break
    return points


def _merged(rounds: list[list[dict]]) -> list[dict]:
    """The points of several rounds of one curve, each with its least time."""
    best: dict = {}
    for points in rounds:
        for point in points:
            kept = best.get(point["param"])
            if kept is None or point["time"] < kept["time"]:
                best[point["param"]] = point
    return sorted(best.values(), key=lambda point: point["steps"])


def study(case: Case, repeats: int, budget: float, rounds: int = 2) -> dict:
    exact = case.exact()
    out: dict = {"problem": case.name, "t_final": case.t_final, "methods": {}}
    for label, s, family in METHODS:
        method = method_of(s, family)
        fixed = gvi.Integrator(case.system, method)
        adaptive = gvi.AdaptiveIntegrator(case.system, method, g=case.g)

        def run_fixed(n, fixed=fixed):
            return fixed.integrate(case.q0, case.v0, h=case.t_final / n, n_steps=n,
                                   params=case.params, save_every=max(1, n // 1000))  # fmt: skip

        def run_adaptive(h, adaptive=adaptive):
            return adaptive.integrate(case.q0, case.v0, h=h, t_final=case.t_final,
                                      params=case.params, save_every=1000)  # fmt: skip

        # compile / load before timing
        run_fixed(case.fixed_steps[-1] // 64)
        run_adaptive(case.fictitious[-1])
        # the two curves in alternating rounds, each point's least time over the rounds:
        # timed one curve after the other, a busy spell of the machine fell on one of them
        # and moved their ratio by 2x between runs
        fixed_rounds, adaptive_rounds = [], []
        for _ in range(rounds):
            fixed_rounds.append(curve(run_fixed, case.fixed_steps, exact, repeats, budget))
            adaptive_rounds.append(curve(run_adaptive, case.fictitious, exact, repeats, budget))
        out["methods"][label] = {
            "fixed": _merged(fixed_rounds),
            "adaptive": _merged(adaptive_rounds),
        }
    out["summary"] = summary(out["methods"])
    return out


def summary(methods: dict) -> dict:
    rows = {}
    for target in TARGETS:
        best = {}
        for kind in ("fixed", "adaptive"):
            times = [
                (hit["time"], label)
                for label, curves in methods.items()
                if (hit := time_to_error(curves[kind], target)) is not None
            ]
            best[kind] = min(times) if times else None
        ratio = (
            best["fixed"][0] / best["adaptive"][0] if best["fixed"] and best["adaptive"] else None
        )
        rows[f"{target:.0e}"] = {**best, "fixed_over_adaptive": ratio}
    return rows


def print_study(result: dict) -> None:
    print(f"\n## {result['problem']} (t_final = {result['t_final']:.6g})\n")
    head = ("method", "kind", "steps", "CPU s", "error", "max dH", "its")
    print("{:<11} {:<9} {:>9} {:>9} {:>9} {:>9} {:>5}".format(*head))
    for label, curves in result["methods"].items():
        for kind, points in curves.items():
            for p in points:
                print(
                    f"{label:<11} {kind:<9} {p['steps']:>9d} {p['time']:>9.4f} {p['error']:>9.2e} "
                    f"{p['energy']:>9.2e} {p['iterations']:>5.2f}"
                )
    print()
    for target, row in result["summary"].items():
        fixed, adaptive = row["fixed"], row["adaptive"]

        def fmt(best):
            return "not reached" if best is None else f"{best[0]:.4f} s ({best[1]})"

        ratio = row["fixed_over_adaptive"]
        ratio_text = "-" if ratio is None else f"{ratio:.1f}x"
        print(f"error {target}: fixed {fmt(fixed)}, adaptive {fmt(adaptive)}, "
              f"adaptive faster by {ratio_text}")  # fmt: skip


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--problems", nargs="+", default=["kepler-0.6", "kepler-0.9"])
    parser.add_argument("--periods", type=int, default=100, help="Kepler periods")
    parser.add_argument("--days", type=float, default=20_000.0, help="solar system span")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--rounds", type=int, default=2, help="alternating rounds of the curves")
    parser.add_argument("--budget", type=float, default=20.0, help="seconds per point, at most")
    parser.add_argument("--json", type=Path)
    args = parser.parse_args(argv)
    results = []
    for name in args.problems:
        if name.startswith("kepler-"):
            case = kepler_case(float(name.split("-", 1)[1]), args.periods)
        elif name == "outer_solar_system":
            case = solar_case(args.days)
        else:
            parser.error(f"unknown problem {name!r}")
        result = study(case, args.repeats, args.budget, args.rounds)
        print_study(result)
        results.append(result)
    if args.json:
        args.json.write_text(json.dumps(results, indent=1, default=str))
    return 0


if __name__ == "__main__":
    sys.exit(main())
