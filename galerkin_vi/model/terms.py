r"""Repeated terms of a Lagrangian: one template on many index tuples.

The Lagrangian of a lattice, a chain or a particle system is a sum of terms
that are one expression on different coordinates: a spring between masses
:math:`i` and :math:`j` is

.. math::

    \tfrac k2 (r_{ij} - 1)^2,\qquad
    r_{ij} = \sqrt{(x_j - x_i)^2 + (y_j - y_i)^2},

the same function :math:`T(z_0, z_1, z_2, z_3)` of
:math:`(x_i, y_i, x_j, y_j)` for every spring. :func:`repeated_terms` writes

.. math::

    L = \sum_g \sum_{k=1}^{K_g} T_g\bigl(w_{g,k}\bigr) + R,

where :math:`w_{g,k}` are the arguments of the :math:`k`-th instance of
template :math:`T_g` (coordinates, velocities and parameters, named by their
indices in a table) and :math:`R` the terms that do not repeat. The
derivatives of :math:`L` are then the derivatives of each template, taken
once, scattered to the instances' indices: code generation turns them into a
loop over the table instead of one statement per entry.

A term's template is the term with its coordinates, velocities and
parameters renamed to placeholders in the order (coordinates by index,
velocities by index, parameters by index); the time symbol stays itself. Two
terms share a template when the renamed expressions are equal (SymPy's
structural equality), so a spring written :math:`(x_j - x_i)` and one written
:math:`(x_i - x_j)` may form two groups: correct, a little less compact.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
import sympy as sp
from numpy.typing import NDArray

__all__ = [
    "KINDS",
    "TermGroup",
    "derivative",
    "repeated_terms",
    "substitute",
]

#: the kinds of a template's arguments, in the order they are numbered
KINDS = ("q", "v", "prm")


@dataclass(frozen=True, eq=False)
class TermGroup:
    r"""One template and the index tuples of its instances.

    Attributes
    ----------
    template : sympy.Expr
        :math:`T(z_0, \dots, z_{m-1})` in the placeholder symbols ``arguments``.
    arguments : tuple of sympy.Symbol
        The placeholders :math:`z_i`, real.
    kinds : tuple of str
        Per argument, what it stands for: ``"q"`` (a coordinate), ``"v"`` (a
        velocity) or ``"prm"`` (a parameter); grouped in that order.
    table : numpy.ndarray of int64, shape (K, m)
        ``table[k, i]`` is the index (into ``q``, ``v`` or the parameters) of
        argument :math:`z_i` in the :math:`k`-th instance.
    """

    template: sp.Expr
    arguments: tuple[sp.Symbol, ...]
    kinds: tuple[str, ...]
    table: NDArray[np.int64]

    @property
    def count(self) -> int:
        """Number of instances :math:`K`."""
        return int(self.table.shape[0])

    def instance(self, k: int, symbols: dict[str, tuple[sp.Symbol, ...]]) -> sp.Expr:
        """The ``k``-th term in the system's own ``symbols`` (``{"q": q, "v": v, "prm": ...}``)."""
        values = {
            z: symbols[kind][int(i)]
            for z, kind, i in zip(self.arguments, self.kinds, self.table[k], strict=True)
        }
        return self.template.xreplace(values)


def _placeholder(k: int, symbol: sp.Symbol | None = None) -> sp.Symbol:
    """The ``k``-th placeholder, real, with the other assumptions of ``symbol``."""
    assumptions = {} if symbol is None else dict(symbol.assumptions0)
    if assumptions.get("real") is None:
        assumptions["real"] = True
    return sp.Symbol(f"_gvi_z{k}", **assumptions)


def _shape(term: sp.Expr, index: dict[sp.Symbol, tuple[int, int]]):
    """``(template, kinds, indices)`` of ``term``, or None if it has other symbols than
    ``index``'s (the time symbol aside, which the template keeps)."""
    found = []
    for s in term.free_symbols:
        where = index.get(s)
        if where is None:
            return None
        if where[0] >= 0:
            found.append((where, s))
    found.sort(key=lambda item: item[0])
    mapping = {s: _placeholder(k, s) for k, (_, s) in enumerate(found)}
    template = term.xreplace(mapping)
    kinds = tuple(KINDS[kind] for (kind, _), _ in found)
    return template, kinds, tuple(i for (_, i), _ in found)


def _distributed_terms(expr: sp.Expr, min_count: int) -> list[sp.Expr]:
    r"""The terms of ``expr``, a common factor distributed over a long sum.

    :math:`k (1 + \varepsilon\cos t) \sum_i (q_{i+1} - q_i)^2` is one term to
    SymPy; written :math:`\sum_i k (1 + \varepsilon\cos t) (q_{i+1} - q_i)^2`
    its terms repeat. A product with one sum of at least ``min_count`` terms
    among its factors is distributed (recursively); other terms stay whole.
    """
    out = []
    for term in sp.Add.make_args(expr):
        if term.is_Mul:
            sums = [f for f in term.args if f.is_Add and len(f.args) >= min_count]
            if len(sums) == 1:
                others = [f for f in term.args if f is not sums[0]]
                distributed = sp.Add(*(sp.Mul(*others, a) for a in sums[0].args))
                out += _distributed_terms(distributed, min_count)
                continue
        out.append(term)
    return out


def _placeholders(template: sp.Expr) -> set[sp.Symbol]:
    return {s for s in template.free_symbols if s.name.startswith("_gvi_z")}


def repeated_terms(
    L: sp.Expr,
    q: tuple[sp.Symbol, ...],
    v: tuple[sp.Symbol, ...],
    params: tuple[sp.Symbol, ...] = (),
    t: sp.Symbol | None = None,
    min_count: int = 8,
) -> tuple[tuple[TermGroup, ...], sp.Expr]:
    r"""Split ``L`` into groups of repeated terms and the remainder (see the module docstring).

    Parameters
    ----------
    L : sympy.Expr
    q, v, params : tuple of sympy.Symbol
        Coordinates, velocities and parameters, in the order of their indices.
    t : sympy.Symbol or None
        The time symbol (kept as itself in the templates).
    min_count : int
        The fewest instances a template needs to form a group; fewer stay in
        the remainder.

    Returns
    -------
    groups : tuple of TermGroup
        In the order of their first term in ``L``.
    remainder : sympy.Expr
        :math:`R = L - \sum_g \sum_k T_g(w_{g,k})`, the terms of no group.
    """
    if min_count < 1:
        raise ValueError(f"min_count must be at least 1, got {min_count}")
    index: dict[sp.Symbol, tuple[int, int]] = {}
    for kind, symbols in enumerate((q, v, params)):
        index.update({s: (kind, i) for i, s in enumerate(symbols)})
    if t is not None:
        index[t] = (-1, 0)
    buckets: dict[tuple, list] = {}
    rest: list[sp.Expr] = []
    for term in _distributed_terms(L, min_count):
        shape = _shape(term, index)
        if shape is None or not shape[1]:
            rest.append(term)
            continue
        template, kinds, indices = shape
        buckets.setdefault((template, kinds), []).append((term, indices))
    # templates on the same index tuples (the two powers of one spring) are summed
    # into one: their loop then evaluates what they share (the distance) once
    merged: dict[tuple, list[sp.Expr]] = {}
    for (template, kinds), members in buckets.items():
        arguments = tuple(sorted(_placeholders(template), key=lambda z: int(z.name[6:])))
        # renaming may evaluate a symbol away (Piecewise((x, x > x)) is nan): no template
        if len(members) < min_count or len(arguments) != len(kinds):
            rest.extend(term for term, _ in members)
            continue
        key = (kinds, arguments, tuple(indices for _, indices in members))
        merged.setdefault(key, []).append(template)
    groups = []
    for (kinds, arguments, rows), templates in merged.items():
        table = np.array(rows, dtype=np.int64).reshape(len(rows), len(kinds))
        groups.append(TermGroup(sp.Add(*templates), arguments, kinds, table))
    return tuple(groups), sp.Add(*rest)


def substitute(exprs: list[sp.Expr], mapping: dict[sp.Symbol, sp.Symbol]) -> list[sp.Expr]:
    """``[e.xreplace(mapping) for e in exprs]`` for a renaming of symbols, built fast.

    The derivatives of one template share most of their subexpressions (a
    spring's distance and its powers occur in every entry of its Hessian):
    here a node is rebuilt once per call and reused wherever it recurs. And
    it is rebuilt without SymPy's evaluation: renaming symbols to distinct
    symbols with the same assumptions (or fewer: the placeholders are real)
    leaves a canonical expression canonical up to the order of its
    arguments, while evaluating each rebuilt node (the assumption queries of
    every power of a sum) costs ten times the rest.
    """
    if len(set(mapping.values())) != len(mapping):
        raise ValueError("mapping must rename symbols to distinct symbols")
    memo: dict[sp.Basic, sp.Basic] = dict(mapping)

    def rebuilt(node: sp.Basic) -> sp.Basic:
        done = memo.get(node)
        if done is not None:
            return done
        if not node.args:
            memo[node] = node
            return node
        args = [rebuilt(arg) for arg in node.args]
        if all(a is b for a, b in zip(args, node.args, strict=True)):
            out = node
        elif isinstance(node, sp.core.operations.AssocOp):
            # a sum or product: its arguments as they are (no flattening, no sorting)
            out = node.func._from_args(args, node.is_commutative)
        else:
            out = node.func(*args)
        memo[node] = out
        return out

    with sp.evaluate(False):
        return [rebuilt(e) for e in exprs]


@lru_cache(maxsize=4096)
def derivative(expr: sp.Expr, symbol: sp.Symbol) -> sp.Expr:
    """``sp.diff(expr, symbol)``, remembered: the analysis of the model and the code
    generation both differentiate each template (hundreds of milliseconds for a
    spring's Hessian)."""
    return sp.diff(expr, symbol)
