"""Walks over SymPy expression trees that visit each distinct subexpression once.

A large system's derivatives share most of their subtrees (a lattice repeats a
spring's distance in every entry of its rows); SymPy caches the hashes of its
nodes, so a walk with a set of seen nodes costs a fraction of ``atoms``,
``has`` or ``free_symbols`` called per expression.
"""

from __future__ import annotations

from collections.abc import Iterable, Iterator

import sympy as sp

__all__ = ["distinct_nodes", "symbols_of"]


def distinct_nodes(exprs: Iterable[sp.Basic]) -> Iterator[sp.Basic]:
    """Every distinct subexpression of ``exprs``, once (pre-order, shared subtrees skipped).

    The derivatives of a lattice repeat a spring's distance in every entry of
    its rows: a walk that visits each distinct node once (SymPy caches their
    hashes) costs a fraction of ``atoms``, ``has`` or ``free_symbols`` per
    expression.
    """
    seen: set[sp.Basic] = set()
    stack = list(exprs)
    while stack:
        node = stack.pop()
        if node in seen:
            continue
        seen.add(node)
        yield node
        stack.extend(node.args)


def symbols_of(exprs: Iterable[sp.Basic]) -> set[sp.Symbol]:
    """The free symbols of ``exprs`` (of expressions without bound variables: no
    integrals, sums or lambdas, which derivatives of a Lagrangian never hold)."""
    return {node for node in distinct_nodes(exprs) if isinstance(node, sp.Symbol)}
