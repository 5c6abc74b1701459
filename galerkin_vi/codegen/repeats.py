r"""Repeated entries of large point functions, emitted as loops.

In a chain of N masses, :math:`(L_q)_i` for every interior :math:`i` is the same
expression of :math:`q_{i-1}, q_i, q_{i+1}`. Printed entry by entry, a point
function of a 1000-mass chain is thousands of statements, and numba's compile
time grows faster than linearly with that. Here each entry is rewritten
relative to its row :math:`r` (``q[m]`` becomes ``q[_i + (m - r)]``); entries
of one output array whose rewritten expression (template) and column offset
agree, at consecutive rows and evenly spaced slots, form a run, printed as

.. code-block:: python

    for _i in range(r0, r0 + length):
        Lq[stride * _i + offset] = <template>

Only runs of at least ``MIN_RUN`` entries become loops; the rest stay
straight-line code with joint common-subexpression elimination. The loop body
has its own elimination, but shares nothing with its neighbours (a spring
force is evaluated by both masses it joins), so only large systems use it.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import sympy as sp

__all__ = ["MIN_RUN", "Run", "find_runs"]

#: the fewest entries a loop replaces
MIN_RUN = 8

_SLOT = re.compile(r"^(\w+)\[(\d+)\]$")
_SHIFTED = re.compile(r"^([qv])\[(\d+)\]$")


@dataclass(frozen=True)
class Run:
    """``array[stride * _i + offset] = template`` for ``_i`` in ``range(start, stop)``."""

    array: str
    start: int
    stop: int
    stride: int
    offset: int
    template: sp.Expr


def _row_and_column(array: str, index: int, n: int, pattern) -> tuple[int, int]:
    """Row and column offset of a slot: vectors by index, matrices by storage."""
    if array in ("Lqq", "Lqv", "Lvv", "Fv"):
        if pattern:
            a, b = pattern[index]
        else:
            a, b = divmod(index, n)
        return a, b - a
    return index, 0


def _template(expr: sp.Expr, row: int, cache: dict) -> sp.Expr | None:
    """``expr`` with ``q[m]``, ``v[m]`` renamed relative to ``row`` (None if it has other
    indexed symbols)."""
    mapping = {}
    for symbol in expr.free_symbols:
        match = _SHIFTED.match(symbol.name)
        if match is None:
            if symbol.name == "t" or symbol.name.startswith("prm["):
                continue
            return None
        shift = int(match.group(2)) - row
        name = f"{match.group(1)}[_i{shift:+d}]" if shift else f"{match.group(1)}[_i]"
        if name not in cache:
            cache[name] = sp.Symbol(name, real=True)
        mapping[symbol] = cache[name]
    return expr.xreplace(mapping)


def find_runs(
    entries: list[tuple[str, sp.Expr]], n: int, pattern=()
) -> tuple[list[Run], list[tuple[str, sp.Expr]]]:
    """Split ``entries`` into loops over repeated templates and the remaining entries."""
    groups: dict[tuple, list[tuple[int, int, str, sp.Expr]]] = {}
    rest: list[tuple[str, sp.Expr]] = []
    cache: dict[str, sp.Symbol] = {}
    for slot, expr in entries:
        match = _SLOT.match(slot)
        if match is None:
            rest.append((slot, expr))
            continue
        array, index = match.group(1), int(match.group(2))
        row, column = _row_and_column(array, index, n, pattern)
        template = _template(expr, row, cache)
        if template is None:
            rest.append((slot, expr))
            continue
        groups.setdefault((array, column, template), []).append((row, index, slot, expr))
    runs: list[Run] = []
    for (array, _, template), members in groups.items():
        members.sort()
        start = 0
        while start < len(members):
            stop = start + 1
            stride = None
            while stop < len(members):
                (r0, i0, *_), (r1, i1, *_) = members[stop - 1], members[stop]
                step = i1 - i0
                if r1 != r0 + 1 or (stride is not None and step != stride):
                    break
                stride = step
                stop += 1
            if stop - start >= MIN_RUN and stride is not None:
                first_row, first_index = members[start][0], members[start][1]
                runs.append(
                    Run(
                        array=array,
                        start=first_row,
                        stop=first_row + (stop - start),
                        stride=stride,
                        offset=first_index - stride * first_row,
                        template=template,
                    )
                )
            else:
                rest.extend((slot, expr) for _, _, slot, expr in members[start:stop])
            start = stop
    return runs, rest
