"""Whether the loops are compiled on this machine, and compiling all of them at once.

A run compiles the loop variants it uses at their first use
(:mod:`galerkin_vi.loops.on_demand`). :func:`compile_all` compiles every variant
ahead of use (``galerkin-vi warmup``, for images and CI): the runs of
:mod:`galerkin_vi.tools.warmup` in separate processes, one group per core, at
most two (numba compiles one function at a time per process), each variant
under its own lock so that no two processes compile the same one. A marker
file in the loops' cache folder records that all of them are there.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Sequence

from ._jit import discard_unreadable_loops, loop_cache_dir
from .on_demand import COMPILE_CHILD

__all__ = [
    "MARKER",
    "compile_all",
    "ensure_all_loops",
    "ensure_loops",
    "loops_ready",
]

#: written into the loops' cache folder once every loop is compiled
MARKER = "complete"
_ENSURED = False


def loops_ready() -> bool:
    """Whether every loop has been compiled and cached on this machine."""
    return (loop_cache_dir() / MARKER).exists()


def compile_all(
    jobs: int | None = None,
    verbose: bool = False,
    runs: Sequence[int] | None = None,
    ensembles: bool = True,
) -> float:
    """Compile (or load) every loop variant in ``jobs`` processes; return the seconds taken.

    With ``runs``, only the variants of the warm-up runs of those indices
    (:mod:`galerkin_vi.tools.warmup`, which names them); with ``ensembles=False``
    without the member loops of ensembles. Each variant is compiled under its own lock
    (:mod:`.on_demand`), so processes that run this at once compile it once.
    """
    jobs = jobs or max(1, min(2, os.cpu_count() or 1))
    chosen = [] if runs is None else ["--runs", ",".join(map(str, runs))]
    if not ensembles:
        chosen.append("--no-ensembles")
    # the children must use this process's loop folder, fixed when the loops were imported
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(loop_cache_dir().parent.parent))
    start = time.perf_counter()
    command = [sys.executable, "-m", "galerkin_vi.tools.warmup", "--of", str(jobs), *chosen]
    processes = [
        subprocess.Popen(
            [*command, "--group", str(g)],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for g in range(jobs)
    ]
    failures = []
    for process in processes:
        out, err = process.communicate()
        if verbose and out:
            sys.stdout.write(out)
        if process.returncode != 0:
            failures.append(err.strip().splitlines()[-1] if err.strip() else "no message")
    if failures:
        raise RuntimeError(f"compiling the time loops failed: {'; '.join(failures)}")
    if runs is None and ensembles:
        marker = loop_cache_dir() / MARKER
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.write_text("every loop compiled\n")
    return time.perf_counter() - start


def ensure_loops() -> None:
    """Before the first integration in a process: delete unreadable loop cache files.

    Each loop variant is compiled at its first use
    (:mod:`galerkin_vi.loops.on_demand`); this only deletes the cache files that
    cannot be read back (:func:`galerkin_vi.loops.discard_unreadable_loops`),
    once per process, so that numba compiles instead of raising.
    """
    global _ENSURED
    if _ENSURED:
        return
    _ENSURED = True
    discard_unreadable_loops()


def ensure_all_loops() -> None:
    """Compile every loop variant in parallel unless they are all cached, saying so.

    For a process that knows it will need most variants (a test session): the
    warm-up's processes compile them at once on all cores, where first use would
    compile them one at a time.
    """
    ensure_loops()
    if loops_ready() or os.environ.get(COMPILE_CHILD):
        return
    sys.stderr.write(
        "galerkin_vi: compiling every time loop for this machine in parallel "
        "(`galerkin-vi warmup`)...\n"
    )
    seconds = compile_all()
    sys.stderr.write(f"galerkin_vi: time loops compiled in {seconds:.0f} s\n")
