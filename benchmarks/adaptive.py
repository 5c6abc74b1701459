"""Time-adaptive (Poincaré) against fixed steps: CPU time to a final error.

For each problem and method, two work-precision curves in this process: fixed
steps of the method on the system, and fixed fictitious steps on the Poincaré
transformed system (:class:`galerkin_vi.AdaptiveIntegrator`, ``g = r^alpha``)
landing exactly on the final time. On Kepler, a third curve per Gauss method:
the strongest hand-written baseline of the same adaptive method
(``peers/poincare.py``: fixed-point Gauss on the Poincaré-transformed
Hamiltonian, same g and fictitious steps, landing on the final time too), which
shows what ratio the method itself allows. Error: the largest position error at
the final time against the exact solution (Kepler) or a tight reference (outer
solar system). The table gives the CPU time to reach each target, interpolated
in log-log between measured points, the steps taken, the largest energy error
along the run (for the hand-written curve: at the final state), and the ratios
best fixed / best adaptive and best fixed / best hand-written adaptive.

Usage::

    python benchmarks/adaptive.py                              # Kepler e = 0.6, 0.9
    python benchmarks/adaptive.py --problems kepler-0.9 --periods 100 --json out.json
    python benchmarks/adaptive.py --rounds 3     # three alternating rounds of both curves
    python benchmarks/adaptive.py --problems outer_solar_system
"""

from __future__ import annotations

import argparse
import contextlib
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
from galerkin_vi.problems import gravitation
from galerkin_vi.problems.base import ode_reference
from galerkin_vi.tools.benchmark import time_to_error

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

from peers.poincare import kepler_poincare  # noqa: E402

TARGETS = (1e-6, 1e-8)
METHODS = (
    ("Gauss(3)", 3, "gauss"),
    ("Gauss(4)", 4, "gauss"),
    ("Gauss(6)", 6, "gauss"),
    ("Lobatto(4)", 3, "lobatto"),
)


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
    # (s, fictitious h) -> final state of the hand-written adaptive Gauss(s), if there is one
    handwritten: Callable[[int, float], object] | None = None


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
        # steps a factor sqrt(2) apart: at orders 6-12 a factor 2 in h moves the error by
        # 2^6-2^12, too coarse for the interpolation of the time to an error
        fictitious=[1.6 / 2 ** (k / 2) for k in range(0, 21)],
        handwritten=lambda s, h: kepler_poincare(prob.q0, prob.v0, s, h, t_final, alpha=1.5),
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


class _KernelResult:
    """A hand-written run's final state, read by :func:`curve` like a trajectory."""

    def __init__(self, run, q0, v0) -> None:
        self.q = run.q[None, :]
        self.n_steps = run.n_steps
        self.total_newton_iterations = run.mean_sweeps * run.n_steps
        h0 = 0.5 * float(np.dot(v0, v0)) - 1.0 / float(np.linalg.norm(q0))
        h1 = 0.5 * float(run.p @ run.p) - 1.0 / float(np.linalg.norm(run.q))
        self._energy = np.array([h0, h1])

    def energy(self) -> np.ndarray:
        return self._energy


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
        except (gvi.ConvergenceError, RuntimeError):
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
                                   params=case.params, save_every=max(1, n // 1000),
                                   on_failure="raise")  # fmt: skip

        def run_adaptive(h, adaptive=adaptive):
            return adaptive.integrate(case.q0, case.v0, h=h, t_final=case.t_final,
                                      params=case.params, save_every=1000,
                                      on_failure="raise")  # fmt: skip

        kernel = case.handwritten if family == "gauss" else None

        def run_kernel(h, s=s, kernel=kernel):
            return _KernelResult(kernel(s, h), case.q0, case.v0)

        # compile / load before timing
        run_fixed(case.fixed_steps[-1] // 64)
        run_adaptive(case.fictitious[-1])
        if kernel is not None:
            with contextlib.suppress(RuntimeError):  # compiled even when too coarse to converge
                run_kernel(case.fictitious[0])
        # the curves in alternating rounds, each point's least time over the rounds:
        # timed one curve after the other, a busy spell of the machine fell on one of them
        # and moved their ratio by 2x between runs
        kinds = {"fixed": (run_fixed, case.fixed_steps),
                 "adaptive": (run_adaptive, case.fictitious)}  # fmt: skip
        if kernel is not None:
            kinds["hand-written"] = (run_kernel, case.fictitious)
        timed: dict[str, list] = {kind: [] for kind in kinds}
        for _ in range(rounds):
            for kind, (run, params) in kinds.items():
                timed[kind].append(curve(run, params, exact, repeats, budget))
        out["methods"][label] = {kind: _merged(points) for kind, points in timed.items()}
    out["summary"] = summary(out["methods"])
    return out


def _ratio(slow, fast) -> float | None:
    return slow[0] / fast[0] if slow and fast else None


def summary(methods: dict) -> dict:
    rows = {}
    for target in TARGETS:
        best = {}
        for kind in ("fixed", "adaptive", "hand-written"):
            times = [
                (hit["time"], label)
                for label, curves in methods.items()
                if kind in curves and (hit := time_to_error(curves[kind], target)) is not None
            ]
            best[kind] = min(times) if times else None

        rows[f"{target:.0e}"] = {
            **best,
            "fixed_over_adaptive": _ratio(best["fixed"], best["adaptive"]),
            "fixed_over_handwritten": _ratio(best["fixed"], best["hand-written"]),
        }
    return rows


def print_study(result: dict) -> None:
    print(f"\n## {result['problem']} (t_final = {result['t_final']:.6g})\n")
    head = ("method", "kind", "steps", "CPU s", "error", "max dH", "its")
    print("{:<11} {:<12} {:>9} {:>9} {:>9} {:>9} {:>5}".format(*head))
    for label, curves in result["methods"].items():
        for kind, points in curves.items():
            for p in points:
                print(
                    f"{label:<11} {kind:<12} {p['steps']:>9d} {p['time']:>9.4f} {p['error']:>9.2e} "
                    f"{p['energy']:>9.2e} {p['iterations']:>5.2f}"
                )
    print()
    for target, row in result["summary"].items():
        fixed, adaptive = row["fixed"], row["adaptive"]

        def fmt(best):
            return "not reached" if best is None else f"{best[0]:.4f} s ({best[1]})"

        def times(ratio):
            return "-" if ratio is None else f"{ratio:.1f}x"

        print(f"error {target}: fixed {fmt(fixed)}, adaptive {fmt(adaptive)}, "
              f"adaptive faster by {times(row['fixed_over_adaptive'])}")  # fmt: skip
        if row.get("hand-written") is not None:
            print(f"  hand-written adaptive {fmt(row['hand-written'])}, faster than fixed by "
                  f"{times(row['fixed_over_handwritten'])}")  # fmt: skip


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
