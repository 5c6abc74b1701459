"""Whether the loops are compiled on this machine, and compiling all of them at once.

Every loop variant is compiled by :mod:`galerkin_vi.tools.warmup`, run as separate
processes (``python -m galerkin_vi.tools.warmup --group g --of G``, one group per
core, at most two): numba compiles one function at a time per process, and the
variants are independent. A marker file in the loops' cache folder records that
all of them are there. :func:`ensure_loops` is what an integrator calls before
its first run: on a machine where the marker is missing it compiles every loop,
with a one-line message on stderr, instead of compiling a different loop at
each new kind of problem.
"""

from __future__ import annotations

import os
import subprocess
import sys
import time

from ._jit import discard_unreadable_loops, loop_cache_dir

__all__ = ["MARKER", "compile_all", "ensure_loops", "loops_ready"]

#: written into the loops' cache folder once every loop is compiled
MARKER = "complete"
_ENSURED = False


def loops_ready() -> bool:
    """Whether every loop has been compiled and cached on this machine."""
    return (loop_cache_dir() / MARKER).exists()


def compile_all(jobs: int | None = None, verbose: bool = False) -> float:
    """Compile (or load) every loop variant in ``jobs`` processes; return the seconds taken.

    Safe to run from several processes at once: numba writes its cache files
    through temporary files, and the last complete one wins.
    """
    jobs = jobs or max(1, min(2, os.cpu_count() or 1))
    # the children must use this process's loop folder, fixed when the loops were imported
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(loop_cache_dir().parent.parent))
    start = time.perf_counter()
    processes = [
        subprocess.Popen(
            [
                sys.executable,
                "-m",
                "galerkin_vi.tools.warmup",
                "--group",
                str(g),
                "--of",
                str(jobs),
            ],
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
    marker = loop_cache_dir() / MARKER
    marker.parent.mkdir(parents=True, exist_ok=True)
    marker.write_text("every loop compiled\n")
    return time.perf_counter() - start


def ensure_loops() -> None:
    """Before the first integration on a machine: compile every loop, saying so.

    First deletes the loops' cache files that cannot be read back
    (:func:`galerkin_vi.loops.discard_unreadable_loops`). Cheap after the first
    call in a process (a flag) and on a machine where the loops are cached (one
    file test).
    """
    global _ENSURED
    if _ENSURED:
        return
    _ENSURED = True
    discard_unreadable_loops()
    if loops_ready() or os.environ.get("GALERKIN_VI_WARMUP_CHILD"):
        return
    sys.stderr.write(
        "galerkin_vi: compiling the time loops once for this machine (about a minute; "
        "`galerkin-vi warmup` does this ahead of use)...\n"
    )
    seconds = compile_all()
    sys.stderr.write(f"galerkin_vi: time loops compiled in {seconds:.0f} s\n")
