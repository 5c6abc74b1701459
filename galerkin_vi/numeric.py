"""Vectorised NumPy evaluation of SymPy expressions over many points.

Used by the NumPy reference backend, by the diagnostics (energy, momentum maps)
and by the Python-level solvers (``step_del``, Legendre transforms). Compiled
kernels do not use it.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
import sympy as sp
from numpy.typing import NDArray

__all__ = ["FlatEvaluator"]


class FlatEvaluator:
    """Evaluate a list of scalar expressions at many points at once.

    Parameters
    ----------
    exprs : sequence of sympy.Expr
        The expressions, evaluated jointly (one common-subexpression pass).
        Entries that are identically zero are not compiled, only filled in.
    args : sequence of sympy.Symbol
        Argument symbols; each call passes one array (or scalar) per argument.

    Notes
    -----
    Calling the evaluator with broadcastable arrays of shape ``S`` returns an
    array of shape ``S + (len(exprs),)``; constant expressions are broadcast.
    """

    def __init__(self, exprs: Sequence[sp.Expr], args: Sequence[sp.Symbol]) -> None:
        entries = {j: e for j, e in enumerate(exprs) if e != 0}
        self._setup(len(exprs), entries, args)

    @classmethod
    def from_blocks(
        cls, blocks: Sequence[sp.MatrixBase], args: Sequence[sp.Symbol]
    ) -> FlatEvaluator:
        """Evaluator of the row-major concatenation of matrices (dense or sparse).

        Only the stored nonzero entries are visited, so a sparse N x N block
        costs O(nonzeros), not O(N^2), to build.
        """
        entries: dict[int, sp.Expr] = {}
        offset = 0
        for block in blocks:
            cols = block.shape[1]
            for (i, j), e in block.todok().items():
                if e != 0:
                    entries[offset + i * cols + j] = e
            offset += block.shape[0] * cols
        self = cls.__new__(cls)
        self._setup(offset, entries, args)
        return self

    def _setup(self, n_out: int, entries: dict[int, sp.Expr], args: Sequence[sp.Symbol]) -> None:
        self.n_out = n_out
        # long sums are evaluated in parts and added up: Python's compiler recurses once
        # per "+" and fails on a Lagrangian of a thousand springs
        slots, parts = [], []
        for slot, expr in entries.items():
            terms = sp.Add.make_args(expr)
            for k in range(0, len(terms), _SUM_CHUNK):
                slots.append(slot)
                parts.append(sp.Add(*terms[k : k + _SUM_CHUNK]))
        self._slots = np.array(slots, dtype=np.int64)
        # the module object, not "numpy": lambdify would run "from numpy import *", which
        # imports all of NumPy's lazily loaded submodules (0.15 s)
        self._fn: Callable = sp.lambdify(list(args), parts, modules=[np], cse=True)

    def __call__(self, *values: NDArray | float) -> NDArray[np.float64]:
        shape = np.broadcast_shapes(*(np.shape(x) for x in values))
        results = self._fn(*values)
        out = np.zeros(shape + (self.n_out,))
        for j, r in zip(self._slots, results, strict=True):
            out[..., j] += r
        return out


_SUM_CHUNK = 64
