"""Compile every time loop once for this machine (``galerkin-vi warmup``).

The loops of :mod:`galerkin_vi.loops` are compiled by numba on their first
use and cached on disk (:func:`galerkin_vi.loops.loop_cache_dir`); after that,
any system, degree, quadrature, step size or parameter value loads them in
milliseconds. :func:`warm_up` compiles every variant ahead of use by running
a few steps of three tiny systems that between them take every loop
(general Newton, stage form, linear, explicit with a diagonal and with a full
mass matrix, constrained). :func:`ensure_loops` does the same lazily, once,
on the first integration on a machine, with a one-line message on stderr.
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

__all__ = ["MARKER", "ensure_loops", "loops_ready", "warm_up"]

#: written into the loops' cache folder once every loop is compiled
MARKER = "complete"


_ENSURED = False


def _marker() -> Path:
    from .loops import loop_cache_dir

    return loop_cache_dir() / MARKER


def loops_ready() -> bool:
    """Whether every loop has been compiled and cached on this machine."""
    return _marker().exists()


def _runs():
    """(system, method, specialize, kernel path) of the warm-up runs, one per loop variant."""
    import sympy as sp

    from .method import Galerkin
    from .system import LagrangianSystem

    q, v = sp.symbols("q v")
    pendulum = LagrangianSystem(v**2 / 2 + sp.cos(q), q=[q], v=[v])
    x, y, vx, vy = sp.symbols("x y vx vy")
    coupled = LagrangianSystem(
        (vx**2 + vx * vy + vy**2) / 2 - (x**2 + y**2) / 2, q=[x, y], v=[vx, vy]
    )
    rod = LagrangianSystem(
        (vx**2 + vy**2) / 2 - y, q=[x, y], v=[vx, vy], constraints=[(x**2 + y**2 - 1) / 2]
    )
    return [
        (pendulum, Galerkin(1), True, [1.0], [0.0]),
        (pendulum, Galerkin(2), True, [1.0], [0.0]),
        (pendulum, Galerkin(2), False, [1.0], [0.0]),
        (coupled, Galerkin(1), True, [1.0, 0.0], [0.0, 0.0]),
        (coupled, Galerkin(2), True, [1.0, 0.0], [0.0, 0.0]),
        (rod, Galerkin(2), True, [0.6, -0.8], [0.8, 0.6]),
    ]


def warm_up(verbose: bool = False) -> dict[str, float]:
    """Compile (or load) every loop variant; return the seconds each kernel path took.

    Safe to run from several processes at once: numba writes its cache files
    through temporary files, and the last complete one wins.
    """
    from .integrator import Integrator

    global _ENSURED
    _ENSURED = True  # the runs below must not start a second warm-up
    seconds: dict[str, float] = {}
    for system, method, specialize, q0, v0 in _runs():
        integrator = Integrator(system, method, specialize=specialize)
        path = integrator.kernel_path
        start = time.perf_counter()
        integrator.integrate(q0, v0=v0, h=0.01, n_steps=2)
        seconds[f"{path} ({method!r})"] = time.perf_counter() - start
        if verbose:
            print(f"  {path:12s} {method!r}: {seconds[f'{path} ({method!r})']:.1f} s")
    marker = _marker()
    marker.parent.mkdir(parents=True, exist_ok=True)
    marker.write_text("every loop compiled\n")
    return seconds


def ensure_loops() -> None:
    """Before the first integration on a machine: compile every loop, saying so.

    Cheap after the first call in a process (a flag) and on a machine where the
    loops are cached (one file test).
    """
    global _ENSURED
    if _ENSURED:
        return
    _ENSURED = True
    if loops_ready():
        return
    sys.stderr.write(
        "galerkin_vi: compiling the time loops once for this machine (about a minute; "
        "`galerkin-vi warmup` does this ahead of use)...\n"
    )
    start = time.perf_counter()
    warm_up()
    sys.stderr.write(f"galerkin_vi: time loops compiled in {time.perf_counter() - start:.0f} s\n")
