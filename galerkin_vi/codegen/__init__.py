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

import importlib
from typing import TYPE_CHECKING

# names resolved at first access (PEP 562): the loops read ``codegen.slots`` alone, and a
# compiling child process then imports neither SymPy nor the printer
_SOURCES: dict[str, str] = {
    "KernelPrinter": "..printer",
    "unsupported_functions": "..printer",
    "render_module": ".source",
    **dict.fromkeys(
        (
            "GENERATOR_VERSION",
            "KernelSpec",
            "SpecSummary",
            "kernel_spec",
            "signature",
            "sparsity_pattern",
            "summarize",
            "use_banded",
        ),
        ".spec",
    ),
}

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


def __getattr__(name: str):
    module = _SOURCES.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module, __name__), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_SOURCES})


if TYPE_CHECKING:
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
