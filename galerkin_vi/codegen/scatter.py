r"""Repeated terms of a Lagrangian as scatter loops over index tables.

For each group of :func:`galerkin_vi.model.terms.repeated_terms`, a template
:math:`T(z)` with instances :math:`w_k` (rows of an index table), the point
functions need

.. math::

    (L_q)_a \mathrel{+}= \sum_{k,\,i:\ w_{k,i} = q_a} \partial_{z_i} T(w_k),\qquad
    (L_{qq})_{ab} \mathrel{+}= \sum_{k,\,i,\,j:\ w_{k,i} = q_a,\ w_{k,j} = q_b}
    \partial_{z_i}\partial_{z_j} T(w_k),

and likewise for :math:`L_v`, :math:`L_{qv}`, :math:`L_{vv}`: the template's
derivatives are taken once (SymPy), and each instance adds them into the
slots its indices name. A :class:`ScatterGroup` holds the template's nonzero
derivatives and, per instance and derivative, the flat slot it adds into
(dense ``a n + b`` or the position of ``(a, b)`` in the sparsity pattern), so
that the generated code is one loop per group whatever the number of
instances (:mod:`.source`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..model.terms import TermGroup, derivative

__all__ = ["ScatterGroup", "scatter_group"]

# second derivatives: the block they belong to, by the kinds of the two arguments
_BLOCKS = {("q", "q"): "Lqq", ("q", "v"): "Lqv", ("v", "v"): "Lvv"}


@dataclass(frozen=True, eq=False)
class ScatterGroup:
    """One repeated template, its derivatives and the slots each instance adds into.

    Attributes
    ----------
    name : str
        Prefix of the group's names in the generated module (``_g0``).
    reads : tuple of (str, str)
        Per template argument, the loop variable's name and the array it is
        read from (``"q"``, ``"v"`` or ``"prm"``), at ``table[k, i]``.
    table : numpy.ndarray of int64, shape (K, m)
        The instances' argument indices.
    value : sympy.Expr
        The template in the loop variables (for the Lagrangian).
    entries : tuple of (str, sympy.Expr)
        The template's nonzero derivatives: the array they add into (``Lq``,
        ``Lv``, ``Lqq``, ``Lqv``, ``Lvv``) and the expression.
    slots : numpy.ndarray of int64, shape (K, len(entries))
        ``slots[k, e]``: the flat slot of instance ``k``'s derivative ``e``.
    """

    name: str
    reads: tuple[tuple[str, str], ...]
    table: NDArray[np.int64]
    value: sp.Expr
    entries: tuple[tuple[str, sp.Expr], ...]
    slots: NDArray[np.int64]

    @property
    def count(self) -> int:
        """Number of instances."""
        return int(self.table.shape[0])


def _without_deltas(expr: sp.Expr) -> sp.Expr:
    """The point-wise second derivative: Dirac deltas of kinks set to zero (as in
    :func:`galerkin_vi.model.symbolic.without_point_masses`)."""
    if not expr.has(sp.DiracDelta):
        return expr
    return expr.replace(sp.DiracDelta, lambda *args: sp.S.Zero)


def _derivatives(group: TermGroup) -> list[tuple[str, int, int, sp.Expr]]:
    """``(array, i, j, d)``: first (``j = -1``) and second derivatives of the template by
    its coordinate and velocity arguments ``i`` (and ``j``), the nonzero ones."""
    out = []
    args = group.arguments
    active = [i for i, kind in enumerate(group.kinds) if kind in ("q", "v")]
    for i in active:
        first = derivative(group.template, args[i])
        if first == 0:
            continue
        out.append(("Lq" if group.kinds[i] == "q" else "Lv", i, -1, first))
        for j in active:
            block = _BLOCKS.get((group.kinds[i], group.kinds[j]))
            if block is None:
                continue  # d/dv d/dq: L_qv holds it with the arguments swapped
            second = _without_deltas(derivative(first, args[j]))
            if second != 0:
                out.append((block, i, j, second))
    return out


def scatter_group(
    group: TermGroup,
    name: str,
    n: int,
    position: dict[tuple[int, int], int] | None,
    rename: dict[sp.Symbol, sp.Symbol] | None = None,
) -> ScatterGroup | None:
    """The :class:`ScatterGroup` of ``group``, or None if a slot is not stored.

    Parameters
    ----------
    group : TermGroup
    name : str
        The group's prefix in the generated module.
    n : int
        Number of coordinates (dense storage puts ``(a, b)`` at ``a n + b``).
    position : dict or None
        Banded storage: the position of each stored ``(a, b)`` in the sparsity
        pattern; None for dense storage. A second derivative of the template
        outside the pattern (terms whose sum cancels) makes the group unfit
        (None): its terms then stay straight-line code.
    rename : dict, optional
        Further renaming of the template's other symbols (time).
    """
    loop_vars = [sp.Symbol(f"{name}_z{i}", real=True) for i in range(len(group.arguments))]
    rename = dict(rename or {}) | dict(zip(group.arguments, loop_vars, strict=True))
    table = group.table
    entries, columns = [], []
    for array, i, j, expr in _derivatives(group):
        rows = table[:, i]
        if j < 0:
            column = rows
        elif position is None:
            column = rows * n + table[:, j]
        else:
            pairs = zip(rows.tolist(), table[:, j].tolist(), strict=True)
            try:
                column = np.array([position[pair] for pair in pairs])
            except KeyError:
                return None
        entries.append((array, expr.xreplace(rename)))
        columns.append(np.asarray(column, dtype=np.int64))
    slots = np.stack(columns, axis=1) if columns else np.zeros((group.count, 0), np.int64)
    return ScatterGroup(
        name=name,
        reads=tuple((str(z), kind) for z, kind in zip(loop_vars, group.kinds, strict=True)),
        table=table,
        value=group.template.xreplace(rename),
        entries=tuple(entries),
        slots=slots,
    )
