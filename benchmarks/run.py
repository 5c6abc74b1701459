"""Run the galerkin_vi benchmark suite (same as ``galerkin-vi bench``).

Usage::

    python benchmarks/run.py --quick --output bench-results
    python benchmarks/run.py --output bench-results          # full run, 17-22 minutes
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from galerkin_vi import bench


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and run :func:`galerkin_vi.bench.main`."""
    parser = argparse.ArgumentParser(
        prog="benchmarks/run.py",
        description="Work-precision benchmark of galerkin_vi against hand-written numba "
        "kernels, scipy's solve_ivp, numbalsoda and REBOUND (see benchmarks/README.md).",
    )
    bench.add_arguments(parser)
    return bench.main(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
