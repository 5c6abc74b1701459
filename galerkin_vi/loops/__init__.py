"""The time loops, compiled once per machine and shared by every system.

Each loop family is one module of plain numba code: :mod:`.general` (Newton on
the stage equations, any regular Lagrangian, forces, time dependence, dense or
banded Jacobians), :mod:`.linear` (quadratic Lagrangians: one factorisation
per run), :mod:`.explicit` (Störmer–Verlet and its compositions; with the
tangent map: :mod:`.explicit_tangent`), :mod:`.stage_form` (separable
Lagrangians: Newton on the implicit stages only) and :mod:`.constrained`
(holonomic constraints with momentum projection). Their shared pieces:
:mod:`.common`, :mod:`.linalg`, :mod:`.point` (calls of the per-system point
functions by address) and :mod:`.traits` (the structure flags, as data).

A loop's arguments never name a system: the point functions arrive as
addresses in an int64 array, the structure as ``traits``, ``pattern`` and
``periodic``, the method as its tables. So numba compiles each loop once per
machine and argument types and caches it (:mod:`._jit` says where);
:mod:`galerkin_vi.tools.warmup` compiles all of them ahead of use, inside
:func:`compiling` (numba's compiler made faster for them, for that time only).
:mod:`.abi` writes down the calling convention every loop follows.
"""

from __future__ import annotations

from ._jit import cache_locators, compiling, discard_unreadable_loops, loop_cache_dir
from .constrained import constrained_loop
from .constrained_tangent import constrained_tangent_loop
from .explicit import explicit_loop
from .explicit_tangent import explicit_tangent_loop
from .general import general_loop
from .linear import linear_loop
from .stage_form import stage_form_loop
from .tangent import adjoint_sweep, tangent_loop
from .varying_mass import varying_mass_loop

__all__ = [
    "adjoint_sweep",
    "cache_locators",
    "compiling",
    "constrained_loop",
    "constrained_tangent_loop",
    "discard_unreadable_loops",
    "explicit_loop",
    "explicit_tangent_loop",
    "general_loop",
    "linear_loop",
    "loop_cache_dir",
    "stage_form_loop",
    "tangent_loop",
    "varying_mass_loop",
]
