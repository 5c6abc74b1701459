"""Compile time of every loop variant, each alone in a process on an empty cache.

Each warm-up run of :mod:`galerkin_vi.tools.warmup` compiles one loop variant
(``--no-ensembles``); with ``--ensembles`` also the member loop of ensembles for
it. Each run here is a fresh process on its own empty cache folder, one at a
time (the figure a user waits for at that loop's first use, less the ~1.5 s of
the child's start), and the table gives the seconds the warm-up run reports.

``python benchmarks/compile_time.py [--ensembles] [--only LABEL ...]`` prints a
Markdown table and the total.
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile


def _labels() -> list[str]:
    from galerkin_vi.tools.warmup import _runs

    return [run[0] for run in _runs()]


def compile_seconds(index: int, ensembles: bool) -> float:
    """Seconds warm-up run ``index`` reports, alone in a process on an empty cache."""
    with tempfile.TemporaryDirectory() as cache:
        env = dict(os.environ, GALERKIN_VI_CACHE_DIR=cache)
        command = [sys.executable, "-m", "galerkin_vi.tools.warmup", "--runs", str(index)]
        if not ensembles:
            command.append("--no-ensembles")
        done = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    match = re.search(r"^\s*([0-9.]+) s", done.stdout, re.MULTILINE)
    if match is None:
        raise RuntimeError(f"no time in the warm-up's output: {done.stdout!r}")
    return float(match.group(1))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--ensembles", action="store_true", help="with the member loops")
    parser.add_argument("--only", nargs="+", help="labels of the runs to time")
    args = parser.parse_args(argv)
    labels = _labels()
    chosen = labels if not args.only else args.only
    rows = []
    for label in chosen:
        seconds = compile_seconds(labels.index(label), args.ensembles)
        rows.append((label, seconds))
        print(f"  {seconds:6.1f} s  {label}", file=sys.stderr, flush=True)
    print("| loop variant (warm-up run) | compile seconds, alone |\n|---|---|")
    for label, seconds in rows:
        print(f"| {label} | {seconds:.1f} |")
    print(f"| total | {sum(s for _, s in rows):.1f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
