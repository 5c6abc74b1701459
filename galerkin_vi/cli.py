"""The ``galerkin-vi`` command line.

``galerkin-vi verify`` runs the order study (the project's main job);
``galerkin-vi bench`` the work-precision benchmark.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from collections.abc import Sequence

from . import bench, problems
from .errors import OrderReductionWarning
from .method import Galerkin
from .quadrature import gauss_legendre, gauss_lobatto
from .verification import measure_order

__all__ = ["main"]

PROBLEMS = {
    "harmonic_oscillator": lambda: problems.harmonic_oscillator(1.3),
    "pendulum": problems.pendulum,
    "kepler": lambda: problems.kepler(0.5),
    "double_pendulum": problems.double_pendulum,
}
# Degrees above FLOAT64_MAX_DEGREE are measured in mpmath: in float64 their errors above the
# round-off floor are still pre-asymptotic. Step counts over T = 2 that reach the asymptotic
# range at 40 digits (measured; see tests/test_order.py).
FLOAT64_MAX_DEGREE = 3
MP_DIGITS = 40
MP_STEP_COUNTS = {
    "harmonic_oscillator": [8, 16, 32],
    "pendulum": [8, 16, 32],
    "kepler": [32, 64, 128],
    "double_pendulum": [32, 64, 128],
}
FAMILIES = {
    "lobatto": lambda s: gauss_lobatto(s + 1),
    "gauss": gauss_legendre,
}
ORDER_TOLERANCE = 0.3


def _verify(args: argparse.Namespace) -> int:
    header = (
        f"{'problem':<20} {'s':>2} {'quadrature':<18} {'predicted':>9} {'measured':>9} "
        f"{'points':>6} {'finest error':>12} {'verdict':>7}"
    )
    print(header)
    print("-" * len(header))
    failures = 0
    start = time.perf_counter()
    for name in args.problems:
        problem = PROBLEMS[name]()
        for s in args.degrees:
            for family in args.families:
                rule = FAMILIES[family](s)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", OrderReductionWarning)
                    method = Galerkin(s, rule)
                result = _order_study(name, problem, method)
                ok = result.mask.sum() >= 3 and abs(result.order - method.order) <= ORDER_TOLERANCE
                failures += not ok
                finest = result.errors[result.mask].min() if result.mask.any() else float("nan")
                print(
                    f"{name:<20} {s:>2} {rule!r:<18} {method.order:>9d} {result.order:>9.2f} "
                    f"{int(result.mask.sum()):>6d} {finest:>12.2e} {'pass' if ok else 'FAIL':>7}",
                    flush=True,
                )
    elapsed = time.perf_counter() - start
    print(
        f"\n{failures} of {len(args.problems) * len(args.degrees) * len(args.families)} "
        f"measured orders miss the prediction by more than {ORDER_TOLERANCE} ({elapsed:.1f} s)"
    )
    return 1 if failures else 0


def _order_study(name: str, problem: problems.Problem, method: Galerkin):
    if method.degree > FLOAT64_MAX_DEGREE:
        return measure_order(
            problem.system,
            method,
            problem.q0,
            problem.v0,
            t_final=problem.t_final,
            step_counts=MP_STEP_COUNTS[name],
            params=problem.params,
            dps=MP_DIGITS,
        )
    return measure_order(
        problem.system,
        method,
        problem.q0,
        problem.v0,
        t_final=problem.t_final,
        step_counts="auto",
        reference=problem.reference,
        params=problem.params,
        norm="max",
        window=(1e-12 if problem.exact is not None else 1e-10, 1e-4),
    )


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``galerkin-vi``."""
    parser = argparse.ArgumentParser(
        prog="galerkin-vi", description="Galerkin variational integrators from SymPy Lagrangians."
    )
    sub = parser.add_subparsers(dest="command", required=True)
    verify = sub.add_parser(
        "verify",
        help="measure convergence orders of the built-in problems against the theory",
        description=(
            "Order study: for each problem, degree and quadrature family, fit the order from "
            "runs whose errors lie above the round-off floor and below the pre-asymptotic "
            "range, and compare with min(2s, quadrature order). Degrees up to 3 run in "
            "float64; higher degrees in mpmath at 40 digits (minutes). Exit status 1 when any "
            "measured order misses its prediction by more than 0.3."
        ),
    )
    verify.add_argument("--problems", nargs="+", choices=sorted(PROBLEMS), default=list(PROBLEMS))
    verify.add_argument(
        "--degrees", nargs="+", type=int, default=[1, 2, 3], help="degrees s (1 to 6 or more)"
    )
    verify.add_argument("--families", nargs="+", choices=sorted(FAMILIES), default=list(FAMILIES))
    verify.set_defaults(run=_verify)
    bench_parser = sub.add_parser(
        "bench",
        help="work-precision benchmark against hand-written kernels and scipy",
        description=(
            "Run-time against error for galerkin_vi methods and, in the same run, hand-written "
            "numba kernels and scipy's solve_ivp; prints ratios and writes a table, JSON and "
            "(with matplotlib) plots."
        ),
    )
    bench.add_arguments(bench_parser)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``galerkin-vi`` command."""
    args = build_parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
