"""The ``galerkin-vi`` command line.

``galerkin-vi verify`` runs the order study (the project's main job);
``galerkin-vi bench`` measures work-precision curves of galerkin_vi's methods on a
model (:mod:`galerkin_vi.tools.benchmark`). The comparison with hand-written kernels,
scipy and REBOUND is ``python benchmarks/run.py`` in the repository.
``galerkin-vi warmup`` compiles the time loops once for the machine.
"""

from __future__ import annotations

import argparse
import sys
import time
from collections.abc import Sequence

from . import report

__all__ = ["main"]

# kept here for callers of the command line (and its tests)
PROBLEMS = report.PROBLEMS
FAMILIES = report.FAMILIES


def _selected(args: argparse.Namespace) -> list:
    chosen = []
    for name in args.problems:
        entry = PROBLEMS[name]
        chosen.append((name, entry.factory(), entry.mp_step_counts))
    for spec in args.problem or []:
        problem = report.load_problem(spec)
        chosen.append((problem.name, problem, (16, 32, 64)))
    return chosen


def _progress_bar(total: int):
    """A tqdm bar on stderr, shown for runs longer than 2 s on a terminal (None otherwise)."""
    try:
        from tqdm import tqdm
    except ImportError:  # pragma: no cover - tqdm is a dependency
        return None
    return tqdm(total=total, delay=2.0, unit="study", leave=False, disable=None)


def study_count(
    selected: list, degrees: Sequence[int], families: Sequence[str],
    compositions: Sequence[int] = (),
) -> int:  # fmt: skip
    """Order studies ``verify`` runs: every degree and family, Lobatto only with constraints,
    and every composition order on the problems that allow compositions."""
    from ..run.loop_choice import composition_obstacle

    galerkin = len(degrees) * sum(
        len(families) if not problem.system.m else int("lobatto" in families)
        for _, problem, _ in selected
    )
    separable = sum(composition_obstacle(problem.system) is None for _, problem, _ in selected)
    return galerkin + len(compositions) * separable


def _positive_int(text: str) -> int:
    """argparse type: an int of at least 1 (a usage error, exit status 2, otherwise)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be at least 1, got {value}")
    return value


def _verify(args: argparse.Namespace) -> int:
    try:
        selected = _selected(args)
    except ValueError as exc:
        print(f"galerkin-vi verify: {exc}", file=sys.stderr)
        return 2
    total = study_count(selected, args.degrees, args.families, args.compositions)
    if total == 0:
        # a CI gate that tested nothing must not pass
        what = "no problem" if not selected else "no study for the selected families"
        print(
            f"galerkin-vi verify: {what} selected (give --problems NAME ..., --problem "
            "MODULE:ATTR, or a family that applies; constrained problems run Lobatto only)",
            file=sys.stderr,
        )
        return 2
    bar = _progress_bar(total)
    first = [True]

    def progress(label: str) -> None:
        if bar is None:
            return
        if not first[0]:
            bar.update(1)
        first[0] = False
        bar.set_description(label)

    start = time.perf_counter()
    from .warmup import prefetch

    prefetch(report.loop_labels(selected, args.degrees, args.families))
    try:
        rows = report.verify(
            selected, args.degrees, args.families, args.step_counts, progress, args.compositions
        )
    finally:
        if bar is not None:
            bar.close()
    elapsed = time.perf_counter() - start
    print(report.format_table(rows))
    failures = sum(not r.passed for r in rows)
    print(
        f"\n{failures} of {len(rows)} studies fail (measured order off the prediction by more "
        f"than {report.ORDER_TOLERANCE}, or a momentum drift above "
        f"{report.MOMENTUM_TOLERANCE:g}) ({elapsed:.1f} s)"
    )
    if args.output:
        for path in report.write_outputs(rows, args.output):
            print(f"wrote {path}")
    return 1 if failures else 0


def _bench(args: argparse.Namespace) -> int:
    from . import benchmark

    try:
        chosen = [PROBLEMS[name].factory() for name in args.problems]
        chosen += [report.load_problem(spec) for spec in args.problem or []]
    except ValueError as exc:
        print(f"galerkin-vi bench: {exc}", file=sys.stderr)
        return 2
    if not chosen:
        print(
            "galerkin-vi bench: name a model with --problem MODULE:ATTR (or --problems NAME)",
            file=sys.stderr,
        )
        return 2

    def log(msg: str) -> None:
        print(msg, file=sys.stderr, flush=True)

    start = time.perf_counter()
    results = {}
    for problem in chosen:
        # holonomic constraints: collocated Lobatto only
        families = ["lobatto"] if problem.system.m else args.families
        methods = [(s, family) for s in args.degrees for family in families]
        t_final = args.t_final if args.t_final is not None else problem.t_final
        log(f"[{problem.name}] T = {t_final:g}, {len(methods)} methods")
        try:
            results[problem.name] = benchmark.work_precision(
                problem.system,
                problem.q0,
                problem.v0,
                t_final,
                methods,
                problem.reference,
                params=problem.params,
                targets=args.targets,
                n_start=args.n_start,
                step_factor=args.step_factor,
                time_cap=args.time_cap,
                repeats=args.repeats,
                log=log,
            )
        except (ValueError, NotImplementedError) as exc:
            print(f"galerkin-vi bench: {problem.name}: {exc}", file=sys.stderr)
            return 2
        print(benchmark.markdown(results[problem.name], problem.name, points=False))
    print(f"finished in {time.perf_counter() - start:.1f} s")
    if args.output:
        for path in benchmark.write_outputs(results, args.output):
            print(f"wrote {path}")
    return 0


def _add_bench(sub: argparse._SubParsersAction) -> None:
    from .benchmark import TARGETS

    parser = sub.add_parser(
        "bench",
        help="work-precision curves of galerkin_vi's methods on your model",
        description=(
            "For each degree and quadrature family: run time (minimum of repeats) against the "
            "final relative position error over a geometric sweep of step counts, the largest "
            "relative energy error, and the time to reach each target error; prints a table "
            "per model and, with --output, writes work_precision.json, work_precision.md and "
            "plots. The comparison with hand-written kernels, scipy and REBOUND is "
            "'python benchmarks/run.py' in the repository. Exit status 2 on bad arguments."
        ),
    )
    parser.add_argument(
        "--problem",
        action="append",
        metavar="MODULE:ATTR",
        help="a galerkin_vi.problems.Problem (or a callable returning one); repeatable",
    )
    parser.add_argument(
        "--problems",
        nargs="*",
        choices=sorted(PROBLEMS),
        default=[],
        metavar="NAME",
        help=f"library problems (default: none); one of {', '.join(sorted(PROBLEMS))}",
    )
    parser.add_argument(
        "--degrees",
        nargs="+",
        type=_positive_int,
        default=[1, 2, 3, 4],
        help="degrees s (default 1-4)",
    )
    parser.add_argument(
        "--families",
        nargs="+",
        choices=sorted(FAMILIES),
        default=list(FAMILIES),
        help="lobatto: Gauss-Lobatto with s+1 points; gauss: Gauss-Legendre with s points",
    )
    parser.add_argument(
        "--t-final", type=float, metavar="T", help="span (default: the problem's t_final)"
    )
    parser.add_argument(
        "--targets",
        nargs="+",
        type=float,
        default=list(TARGETS),
        help="final relative errors of the time-to-error table",
    )
    parser.add_argument("--n-start", type=_positive_int, default=16, help="first step count (16)")
    parser.add_argument(
        "--step-factor", type=float, default=2.0, help="ratio of successive step counts (2)"
    )
    parser.add_argument(
        "--time-cap",
        type=float,
        default=0.2,
        metavar="SECONDS",
        help="a sweep stops once one run took longer than this (0.2)",
    )
    parser.add_argument("--repeats", type=_positive_int, default=2, help="timed runs per point (2)")
    parser.add_argument(
        "--output", metavar="DIR", help="write work_precision.json, .md and <model>_*.png"
    )
    parser.set_defaults(run=_bench)


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
            "float64; higher degrees in mpmath at 40 digits (minutes). Also reports the largest "
            "energy error and momentum-map drift at the finest step. Exit status 1 when any "
            "measured order misses its prediction by more than 0.3 or a momentum map drifts "
            "by more than 1e-10; 2 on bad arguments or when nothing is selected."
        ),
    )
    verify.add_argument(
        "--problems",
        nargs="*",
        choices=sorted(PROBLEMS),
        default=list(PROBLEMS),
        help="library problems to study (default: all; none with --problem only)",
    )
    verify.add_argument(
        "--problem",
        action="append",
        metavar="MODULE:ATTR",
        help="a user's galerkin_vi.problems.Problem (or a callable returning one); repeatable",
    )
    verify.add_argument(
        "--degrees",
        nargs="+",
        type=_positive_int,
        default=[1, 2, 3],
        help="degrees s (1 to 6 or more)",
    )
    verify.add_argument(
        "--families",
        "--quadratures",
        nargs="+",
        choices=sorted(FAMILIES),
        default=list(FAMILIES),
        help="lobatto: Gauss-Lobatto with s+1 points; gauss: Gauss-Legendre with s points",
    )
    verify.add_argument(
        "--compositions",
        nargs="*",
        type=int,
        choices=[2, 4, 6, 8, 10],
        default=[],
        metavar="ORDER",
        help=(
            "also study Composition(ORDER) (explicit splittings and compositions of "
            "Stormer-Verlet, default schemes; splittings in mpmath) on the problems with a "
            "separable L and constant mass: e.g. 4 6 8 10"
        ),
    )
    verify.add_argument(
        "--step-counts",
        nargs="+",
        type=_positive_int,
        metavar="N",
        help="fixed numbers of steps instead of the automatic choice",
    )
    verify.add_argument(
        "--output",
        metavar="DIR",
        help="write verify.json and <problem>_convergence.png (log-log error against h)",
    )
    verify.set_defaults(run=_verify)
    _add_bench(sub)
    warmup = sub.add_parser(
        "warmup",
        help="compile every time loop once for this machine (otherwise done on first use)",
        description=(
            "Compile (or load from the cache) every variant of the time loops, which are shared "
            "by all systems; afterwards a new Lagrangian only compiles its point functions."
        ),
    )
    warmup.add_argument(
        "--clear",
        action="store_true",
        help="delete the whole cache (loops and every system's point functions) first",
    )
    warmup.add_argument(
        "--jobs",
        type=int,
        default=None,
        help="processes to compile in (default: the number of cores, at most 2)",
    )
    warmup.set_defaults(run=_warmup)
    return parser


def _warmup(args: argparse.Namespace) -> int:
    import shutil

    from ..cache import cache_root

    if args.clear:
        shutil.rmtree(cache_root(), ignore_errors=True)
        print(f"cleared {cache_root()}")
    from ..loops import loop_cache_dir
    from ..loops.readiness import compile_all

    print(f"compiling the time loops into {loop_cache_dir()}")
    seconds = compile_all(jobs=args.jobs, verbose=True)
    print(f"done in {seconds:.1f} s")
    return 0


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``galerkin-vi`` command."""
    args = build_parser().parse_args(argv)
    return args.run(args)


if __name__ == "__main__":
    sys.exit(main())
