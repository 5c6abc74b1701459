"""Per step against the strongest hand-written kernel of the same method, at the same h.

For every problem and method: galerkin_vi's CPU time per step and iterations per
step, the same for the hand-written kernel of the same method iterated to
round-off (``peers/strong.py``: fixed-point Gauss–Nyström or Lobatto IIIA–IIIB
with first-same-as-last for separable H, fixed-point Gauss IRK on (q, p) for the
double pendulum, all started from extrapolated stage forces), the ratio, and the
largest difference of the final states (both runs take the same steps: a large
difference would mean the two do not compute the same method).

The hand-written side is the fastest of the fixed-point kernel of
``peers/strong.py`` (any problem and table) and, where one exists, the scalar
kernel of ``peers/scalar.py`` written for that one method and problem (Gauss(2)
on the pendulum and Kepler: no arrays, no loops over stages or coordinates),
each also with its first iterate from the last two steps' forces (``2-step``,
separable problems); the column ``hw kernel`` says which. Both sides run in this process,
interleaved in alternating order: ``ratio`` is that of the best of ``--repeats``
runs each, ``paired ratio`` the median and quartiles of the ratios of the runs of
one repeat (a slow phase of a shared machine falls on both of a pair); only the
ratios compare across machines.

Usage::

    python benchmarks/same_method.py                         # all problems, s = 2..4
    python benchmarks/same_method.py --problems pendulum kepler --json out.json
    python benchmarks/same_method.py --specialize system     # the generated stage loops
    python benchmarks/same_method.py --specialize auto       # the default, second run on
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path

import numpy as np

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:
    sys.path.insert(0, _HERE)

from peers import cases, scalar, strong  # noqa: E402

import galerkin_vi as gvi  # noqa: E402

PROBLEMS = ("pendulum", "kepler", "henon_heiles", "fpu", "outer_solar_system", "double_pendulum")
#: (label, degree s, quadrature family)
METHODS = (
    ("Gauss(2)", 2, "gauss"),
    ("Gauss(3)", 3, "gauss"),
    ("Gauss(4)", 4, "gauss"),
    ("Lobatto(3)", 2, "lobatto"),
    ("Lobatto(4)", 3, "lobatto"),
    ("Lobatto(5)", 4, "lobatto"),
)


def _clock(fn) -> float:
    # CPU time of this process: a shared machine's other tenants steal wall time
    start = time.process_time()
    fn()
    return time.process_time() - start


def row(
    case: cases.Case,
    label: str,
    s: int,
    family: str,
    seconds: float,
    repeats: int,
    h_scale: float = 1.0,
    specialize: bool | str = True,
) -> dict:
    """One problem and method at ``h_scale`` times the problem's per-step h: times,
    iterations, final-state difference."""
    quad = gvi.gauss_legendre(s) if family == "gauss" else gvi.gauss_lobatto(s + 1)
    integ = gvi.Integrator(case.problem.system, gvi.Galerkin(s, quad), specialize=specialize)
    h, prm = h_scale * case.per_step_h, case.problem.params

    def gvi_run(n):
        return integ.integrate(case.q0, case.v0, h=h, n_steps=n, save_every=n, params=prm)

    p0 = gvi_run(1).p[0]
    if not case.separable:
        if family != "gauss":
            return {}
        tables = strong.gauss_fixed_point_tables(s, first_order=True)

        def hw_run(n):
            return strong.run_irk(case.problem_id, tables, case.q0, p0, h, n, n, case.hw_params)
    else:
        tables = (
            strong.gauss_fixed_point_tables(s)
            if family == "gauss"
            else strong.lobatto_fixed_point_tables(s + 1)
        )

        def hw_run(n):
            return strong.run_nystrom(case.problem_id, tables, case.q0, p0, h, n, n, case.hw_params)

    kernels = {"fixed-point": hw_run}
    if case.separable:
        # the first iterate from the last two steps' forces, as galerkin_vi's stage form

        def hw_two_step_run(n):
            return strong.run_nystrom(
                case.problem_id, tables, case.q0, p0, h, n, n, case.hw_params, two_step=True
            )

        kernels["fixed-point 2-step"] = hw_two_step_run
    if (case.name, label) in scalar.SCALAR_KERNELS:

        def scalar_run(n):
            return scalar.run_scalar(case.name, label, case.q0, p0, h, n, n)

        kernels["scalar"] = scalar_run

        def scalar_two_step_run(n):
            return scalar.run_scalar(case.name, label, case.q0, p0, h, n, n, two_step=True)

        kernels["scalar 2-step"] = scalar_two_step_run
    gvi_run(10)
    if specialize == "auto":
        # the regime from a system's second run on: its own loop compiled in the
        # background, then loaded (the first run's regime is specialize=True's)
        from galerkin_vi.loops.on_demand import wait_for_background

        gvi_run(10)
        wait_for_background()
    for run in kernels.values():
        run(10)
    probe = 500
    n = int(min(1_000_000, max(500, probe * seconds / max(_clock(lambda: gvi_run(probe)), 1e-9))))
    # the runs interleaved, in alternating order, so that a slow phase of a shared
    # machine falls on both sides; the paired ratios (one per repeat) give the spread
    runs = {
        "gvi": lambda: gvi_run(n),
        **{name: (lambda run=run: run(n)) for name, run in kernels.items()},
    }
    times: dict[str, list[float]] = {name: [] for name in runs}
    for repeat in range(repeats):
        order = list(runs) if repeat % 2 == 0 else list(runs)[::-1]
        for name in order:
            times[name].append(_clock(runs[name]))
    t_gvi = min(times["gvi"])
    t_kernels = {name: min(times[name]) for name in kernels}
    strongest = min(t_kernels, key=t_kernels.get)
    t_hw = t_kernels[strongest]
    paired = np.array(times["gvi"]) / np.array(times[strongest])
    a, b = gvi_run(n), kernels[strongest](n)
    scale = 1.0 + float(np.max(np.abs(b.q[-1])))
    return {
        "problem": case.name,
        "method": label,
        "h": h,
        "n_steps": n,
        "gvi_ns": 1e9 * t_gvi / n,
        "hw_ns": 1e9 * t_hw / n,
        "ratio": t_gvi / t_hw,
        "paired_ratio": [float(x) for x in np.quantile(paired, [0.25, 0.5, 0.75])],
        "gvi_iterations": a.mean_newton_iterations,
        "hw_sweeps": b.mean_sweeps,
        "final_q_difference": float(np.max(np.abs(a.q[-1] - b.q[-1]))) / scale,
        "loop": a.kernel_path or integ.kernel_path,
        "kernel": strongest,
        "kernel_ns": {name: 1e9 * t / n for name, t in t_kernels.items()},
    }


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="benchmarks/same_method.py", description=__doc__)
    parser.add_argument("--problems", nargs="+", default=list(PROBLEMS), choices=PROBLEMS)
    parser.add_argument("--methods", nargs="+", default=[m[0] for m in METHODS])
    parser.add_argument("--seconds", type=float, default=0.05, help="length of one timed run")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--json", type=Path, default=None)
    parser.add_argument(
        "--h-scale",
        type=float,
        default=1.0,
        help="step size as a multiple of the problem's per-step h (0.01: the regime where "
        "the extrapolated start is nearly exact and one or two sweeps converge)",
    )
    parser.add_argument(
        "--specialize",
        choices=("true", "system", "auto"),
        default="true",
        help='galerkin_vi\'s specialize: "system" runs the stage-form loop generated for '
        'the system (compiled once per system); "auto" (the default of Integrator) from a '
        "system's second run on, its own loop compiled in the background",
    )
    args = parser.parse_args(argv)
    specialize = True if args.specialize == "true" else args.specialize
    header = (
        f"{'problem':20s} {'method':11s} {'loop':17s} {'gvi ns':>9s} {'hw ns':>9s} {'ratio':>6s}"
        f" {'gvi its':>8s} {'hw sweeps':>9s} {'final dq':>9s} {'hw kernel':>18s}"
        f" {'paired ratio: median [quartiles]':>33s}"
    )
    print(header)
    print("-" * len(header))
    rows = []
    for name in args.problems:
        case = cases.make_case(name)
        for label, s, family in METHODS:
            if label not in args.methods:
                continue
            r = row(case, label, s, family, args.seconds, args.repeats, args.h_scale, specialize)
            if not r:
                continue
            rows.append(r)
            print(
                f"{name:20s} {label:11s} {r['loop']:17s} {r['gvi_ns']:9.1f} {r['hw_ns']:9.1f}"
                f" {r['ratio']:6.2f} {r['gvi_iterations']:8.2f} {r['hw_sweeps']:9.2f}"
                f" {r['final_q_difference']:9.1e} {r['kernel']:>18s}"
                "    {1:.3f} [{0:.3f}, {2:.3f}]".format(*r["paired_ratio"]),
                flush=True,
            )
    if args.json:
        args.json.write_text(json.dumps(rows, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
