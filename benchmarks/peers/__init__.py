"""Peer benchmark: galerkin_vi against hand-written numba kernels, scipy, numbalsoda and REBOUND.

This package lives in the repository's ``benchmarks/`` folder, not in the installed
galerkin_vi (which keeps the user tool :mod:`galerkin_vi.tools.benchmark`); it imports
galerkin_vi, never the reverse. Put ``benchmarks/`` on ``sys.path`` to import it
(``python benchmarks/run.py`` does so by running from there).

Entry points
------------
:func:`run`
    Run the work-precision benchmark and the per-step comparison; return the
    results as plain data and optionally write results.json, results.md and
    (when matplotlib is importable) PNG work-precision plots to a folder.
:func:`add_arguments`, :func:`main`
    The ``python benchmarks/run.py [--quick] [--output DIR]`` command: ``add_arguments``
    fills an ``argparse`` parser, ``main(args)`` runs it and returns an exit status.

Modules: :mod:`.workprecision` (what is measured, configurations, curves, per-step and
chain-cost tables), :mod:`.cases` (the problems and their references),
:mod:`.handwritten` (the hand-written kernels), :mod:`.output` (tables, JSON, plots).
"""

from __future__ import annotations

import argparse
import dataclasses
import time
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from .workprecision import BenchConfig

__all__ = [
    "PROBLEMS",
    "BenchConfig",
    "add_arguments",
    "full_config",
    "main",
    "quick_config",
    "run",
    "tiny_config",
]

DEFAULT_OUTPUT = "bench-results"

#: the benchmark problems (the same tuple as ``workprecision.PROBLEMS``, kept here so that the
#: command line can offer them without importing numba)
PROBLEMS = (
    "pendulum",
    "kepler",
    "outer_solar_system",
    "henon_heiles",
    "double_pendulum",
    "fpu",
    "spring_chain_100",
    "spring_chain_1000",
)

# numba, scipy and mpmath load only when a benchmark runs, so that wiring the sub-command into
# the CLI (add_arguments) costs nothing at start-up.
_LAZY = {"BenchConfig", "full_config", "quick_config", "tiny_config"}


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        from . import workprecision

        return getattr(workprecision, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def run(
    quick: bool = False,
    output: str | None = None,
    *,
    config: BenchConfig | None = None,
    problems: tuple[str, ...] | None = None,
    chain_cost: bool = True,
    verbose: bool = True,
    specialize: bool | str | None = None,
) -> dict:
    """Run the benchmark and return its results.

    Parameters
    ----------
    quick : bool
        The quick configuration (under 2 minutes including compilation) instead
        of the full one (under 30 minutes).
    output : str, optional
        Folder for results.json, results.md and PNG plots; nothing is written when None.
    config : BenchConfig, optional
        Overrides the configuration chosen by ``quick``.
    problems : tuple of str, optional
        Subset of :data:`PROBLEMS` (default: the configuration's; the quick one leaves
        out ``spring_chain_1000``).
    chain_cost : bool
        Whether to measure the spring chain's cost per step against N.
    verbose : bool
        Print progress.
    specialize : bool or "system", optional
        ``Integrator(specialize=...)`` of the galerkin_vi curves (default: the
        configuration's, ``"system"``).

    Returns
    -------
    dict
        ``{"meta": ..., "problems": {name: {"curves", "time_to_error",
        "best_galerkin_vi", "ratio_peer_over_best", ...}}, "per_step": [...],
        "chain_cost": [...], "files": [...]}``.
    """
    from .output import write_outputs
    from .workprecision import full_config, quick_config, run_benchmark

    cfg = config if config is not None else (quick_config() if quick else full_config())
    if problems is not None:
        cfg = dataclasses.replace(cfg, problems=tuple(problems))
    if not chain_cost:
        cfg = dataclasses.replace(cfg, chain_cost_sizes=())
    if specialize is not None:
        cfg = dataclasses.replace(cfg, specialize=specialize)

    def log(msg: str) -> None:
        if verbose:
            print(msg, flush=True)

    results = run_benchmark(cfg, quick=quick, log=log)
    results["files"] = write_outputs(results, output, log=log) if output else []
    return results


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """Add the benchmark's options to ``parser`` (and set ``run=main`` as its default action)."""
    parser.add_argument(
        "--quick",
        action="store_true",
        help="a short run (under 2 minutes, compilation included) instead of the full one",
    )
    parser.add_argument(
        "--output",
        metavar="DIR",
        default=DEFAULT_OUTPUT,
        help=f"folder for results.json, results.md and PNG plots (default: {DEFAULT_OUTPUT})",
    )
    parser.add_argument(
        "--problems",
        nargs="+",
        choices=PROBLEMS,
        default=None,
        help="benchmark problems (default: all; --quick leaves out spring_chain_1000)",
    )
    parser.add_argument(
        "--no-chain-cost",
        action="store_true",
        help="skip the spring chain's cost-per-step table",
    )
    parser.add_argument(
        "--specialize",
        choices=("true", "system"),
        default="system",
        help='galerkin_vi\'s Integrator(specialize=...): "system" (default) runs the loops '
        "generated per small system and method, compiled before the timed runs",
    )
    parser.set_defaults(run=main)
    return parser


def main(args: argparse.Namespace) -> int:
    """Run the benchmark with parsed ``args``; return the exit status (0)."""
    start = time.perf_counter()
    problems = tuple(args.problems) if getattr(args, "problems", None) else None
    results = run(
        quick=args.quick,
        output=args.output,
        problems=problems,
        chain_cost=not getattr(args, "no_chain_cost", False),
        specialize=True if getattr(args, "specialize", "system") == "true" else "system",
    )
    for path in results["files"]:
        print(f"wrote {path}")
    print(f"benchmark finished in {time.perf_counter() - start:.1f} s")
    return 0
