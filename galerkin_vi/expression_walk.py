"""Walks over SymPy expression trees that visit each distinct subexpression once.

A large system's derivatives share most of their subtrees (a lattice repeats a
spring's distance in every entry of its rows); SymPy caches the hashes of its
nodes, so a walk with a set of seen nodes costs a fraction of ``atoms``,
``has`` or ``free_symbols`` called per expression.
"""

from __future__ import annotations

import io
import pickle
from collections.abc import Iterable, Iterator
from typing import Any

import sympy as sp

__all__ = ["distinct_nodes", "structural_bytes", "symbols_of"]


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


class _StructuralPickler(pickle.Pickler):
    """A pickler that writes each distinct SymPy node once, by equality, not identity.

    Pickle's own memo shares objects by ``id``: an expression holding two equal
    but distinct ``Symbol('q')`` objects (one of them from a ``Pow`` that SymPy's
    cache kept after the symbol itself was evicted) pickles to other bytes than
    the same expression with one shared symbol. A repeated node is written here as
    the index of its first occurrence, whichever object it is.
    """

    def __init__(self, file: io.BytesIO) -> None:
        super().__init__(file, protocol=4)
        self._index: dict[sp.Basic, int] = {}

    def persistent_id(self, obj: Any) -> int | None:
        if isinstance(obj, sp.Basic):
            first = self._index.get(obj)
            if first is not None:
                return first
            self._index[obj] = len(self._index)
        return None


def structural_bytes(obj: Any) -> bytes:
    """Bytes that name ``obj`` for a cache key, the same in every process.

    Equal SymPy nodes give equal bytes whichever objects they are, so the bytes do
    not depend on the state of SymPy's cache; tuples, dicts and arrays of
    expressions are taken as they are. What is inside a node is pickled as it is:
    equal symbols whose assumptions were given in another order, or whose names are
    distinct string objects, can still give other bytes. That costs a cache miss,
    never a wrong hit (unequal expressions never give equal bytes). An object that
    does not pickle (an expression holding a lambda) is named by ``srepr``. For
    keys, not for loading: the persistent references are not resolved by
    :func:`pickle.loads`.
    """
    buffer = io.BytesIO()
    try:
        _StructuralPickler(buffer).dump(obj)
    except Exception:  # noqa: BLE001 - pickling fails in many ways (lambdas, locals)
        return sp.srepr(obj).encode()
    return buffer.getvalue()
