"""Code generation: a system's point functions, from SymPy to compiled C-callable functions.

Three stages, each a function of the previous one's output:

1. :mod:`.spec`: the expressions, renamed to array slots (:func:`kernel_spec`),
   and the key of their cache entry (:func:`signature`);
2. :mod:`.source`: Python source of the point functions (:func:`render_module`),
   printed by :mod:`galerkin_vi.printer`;
3. :mod:`.compiled`: the source cached on disk and compiled as numba ``cfunc``
   (imported on demand: it needs numba).

The time loops are not generated: they are ordinary modules of
:mod:`galerkin_vi.loops`, compiled once per machine.
"""

from __future__ import annotations

from ..printer import KernelPrinter, unsupported_functions
from .source import render_module
from .spec import (
    GENERATOR_VERSION,
    KernelSpec,
    SpecSummary,
    kernel_spec,
    signature,
    sparsity_pattern,
    summarize,
    use_banded,
)

__all__ = [
    "GENERATOR_VERSION",
    "KernelPrinter",
    "KernelSpec",
    "SpecSummary",
    "summarize",
    "kernel_spec",
    "render_module",
    "signature",
    "sparsity_pattern",
    "unsupported_functions",
    "use_banded",
]
