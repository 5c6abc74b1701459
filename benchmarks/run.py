"""Run the peer benchmark: galerkin_vi against hand-written kernels, scipy, numbalsoda, REBOUND.

Usage::

    python benchmarks/run.py --quick --output bench-results
    python benchmarks/run.py --output bench-results          # full run, 17-22 minutes

The code is the ``peers`` package next to this script (not part of the installed
galerkin_vi). Your own model's work-precision curves: ``galerkin-vi bench --problem
module:attr``.
"""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence
from pathlib import Path

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:  # imported rather than run as a script
    sys.path.insert(0, _HERE)

import peers  # noqa: E402


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv`` and run :func:`peers.main`."""
    parser = argparse.ArgumentParser(
        prog="benchmarks/run.py",
        description="Work-precision benchmark of galerkin_vi against hand-written numba "
        "kernels, scipy's solve_ivp, numbalsoda and REBOUND (see benchmarks/README.md).",
    )
    peers.add_arguments(parser)
    return peers.main(parser.parse_args(argv))


if __name__ == "__main__":
    sys.exit(main())
