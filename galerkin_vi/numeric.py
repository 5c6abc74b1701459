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
    args : sequence of sympy.Symbol
        Argument symbols; each call passes one array (or scalar) per argument.

    Notes
    -----
    Calling the evaluator with broadcastable arrays of shape ``S`` returns an
    array of shape ``S + (len(exprs),)``; constant expressions are broadcast.
    """

    def __init__(self, exprs: Sequence[sp.Expr], args: Sequence[sp.Symbol]) -> None:
        self.n_out = len(exprs)
        self._fn: Callable = sp.lambdify(list(args), list(exprs), modules="numpy", cse=True)

    def __call__(self, *values: NDArray | float) -> NDArray[np.float64]:
        shape = np.broadcast_shapes(*(np.shape(x) for x in values))
        results = self._fn(*values)
        out = np.empty(shape + (self.n_out,))
        for j, r in enumerate(results):
            out[..., j] = r
        return out
