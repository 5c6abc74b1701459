r"""The band order of a constrained system's step, where one exists (chains of bodies).

The constrained loop (:mod:`galerkin_vi.loops.constrained`) solves for the stage
increments :math:`C^1..C^s` (:math:`n` each) and the impulses
:math:`\Lambda^0..\Lambda^{s-1}` (:math:`m` each). Think of *groups*: a
coordinate :math:`a` (its :math:`s` increments) and a constraint :math:`j` (its
:math:`s` impulses). Two groups couple when a Hessian of :math:`L` couples the
coordinates, or when the constraint depends on the coordinate. Ordering the
groups so that coupled groups are close and then each group's :math:`s`
unknowns next to each other gives the stage Jacobian a band; the loop factorises
it in band storage (:mod:`galerkin_vi.loops.constrained_band`) when the band is
narrow against the matrix, which is the case of chains of bodies: the band is
set by one body and one joint, whatever the chain's length, and a step costs
:math:`O(N)` instead of :math:`O(N^3)`.

Three group orders are tried, and the one with the narrower band is kept:

- the coordinates in their own order, each constraint after the last
  coordinate it touches;
- the coordinates in their own order, each constraint in the middle of the
  coordinates it touches (a joint between the two bodies it joins: the order of
  a :class:`~galerkin_vi.Multibody`, whose coordinates go body by body);
- reverse Cuthill–McKee on the groups' coupling graph, for systems whose own
  order is scattered.
"""

from __future__ import annotations

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..codegen.spec import sparsity_pattern
from ..model.system import LagrangianSystem

__all__ = ["MIN_SIZE", "constrained_band"]

#: the smallest step system, s (n + m) unknowns, stored banded
MIN_SIZE = 48


def _sources_hash() -> str:
    """A hash of the code that builds the order (this module and the sparsity pattern's):
    part of the analysis cache's key, so that a change of it is a new entry."""
    import hashlib
    from pathlib import Path

    here = Path(__file__).resolve()
    h = hashlib.sha256()
    for path in (here, here.parent.parent / "codegen" / "spec.py"):
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def _pairs(matrix: sp.MatrixBase) -> list[tuple[int, int]]:
    return [(int(i), int(j)) for (i, j), e in matrix.todok().items() if e != 0]


def _group_order(n: int, hessian, jacobian) -> NDArray[np.int64]:
    """The position of each group (coordinates 0..n-1, then constraints) in the band
    order (module notes)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import reverse_cuthill_mckee

    m = 1 + max((j for j, _ in jacobian), default=-1)
    first, last = np.full(m, n), np.full(m, -1)
    for j, a in jacobian:
        first[j] = min(first[j], a)
        last[j] = max(last[j], a)
    coordinates = np.arange(n, dtype=float)
    candidates = [
        np.argsort(np.r_[coordinates, last + 0.5], kind="stable"),
        np.argsort(np.r_[coordinates, (first + last) / 2 + 0.25], kind="stable"),
    ]
    rows = [a for a, _ in hessian] + [n + j for j, _ in jacobian] + [a for _, a in jacobian]
    cols = [b for _, b in hessian] + [a for _, a in jacobian] + [n + j for j, _ in jacobian]
    graph = coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n + m, n + m)).tocsr()
    candidates.append(reverse_cuthill_mckee(graph, symmetric_mode=True))
    best, width = None, None
    for order in candidates:
        position = np.empty(n + m, dtype=np.int64)
        position[order] = np.arange(n + m)
        w = max(abs(int(position[i] - position[j])) for i, j in zip(rows, cols, strict=True))
        if width is None or w < width:
            best, width = position, w
    return best


def constrained_band(system: LagrangianSystem, degree: int) -> tuple | None:
    """The ``band`` argument of the constrained loop for ``system`` and a method of
    ``degree`` s (s unknown stages per step; :mod:`galerkin_vi.loops.constrained_band`),
    or None when dense storage is cheaper (the band is not narrower than a third of the
    matrix).

    Kept with the system's analysis (:meth:`LagrangianSystem.remember`).
    """
    key = f"constrained_band_{_sources_hash()}_{degree}"
    known = system.recalled(key)
    size = degree * (system.n + system.m)
    if known == ():
        return None
    if known is not None and len(known) == 8 and known[0].size == size:
        return known
    band = _band(system, degree)
    system.remember(key, band or ())
    return band


def _band(system: LagrangianSystem, s: int) -> tuple | None:
    n, m = system.n, system.m
    size = s * (n + m)
    if not m or size < MIN_SIZE:
        return None
    hessian = list(sparsity_pattern(system.pieces, n, not system.structure.zero_Lqv))
    pieces = system.constraint_pieces
    jacobian = _pairs(pieces.jacobian)
    lam = sp.symbols(f"lam0:{m}")
    constraint_hessian = _pairs(pieces.contracted_hessian(lam))
    group = _group_order(n, hessian + constraint_hessian, jacobian)
    sn = s * n
    place = np.empty(size, dtype=np.int64)
    for nu in range(s):
        place[nu * n : (nu + 1) * n] = group[:n] * s + nu
        place[sn + nu * m : sn + (nu + 1) * m] = group[n:] * s + nu
    # the dense positions that can be nonzero (as :func:`.loops.constrained` fills them)
    blocks = [(nu * n, mu * n) for nu in range(s) for mu in range(s)]
    kpairs = np.array([(r + a, c + b) for r, c in blocks for a, b in hessian], dtype=np.int64)
    entries = [kpairs]
    for nu in range(s):
        entries.append(np.array([(nu * n + a, sn + nu * m + j) for j, a in jacobian]))
        entries.append(np.array([(sn + nu * m + j, nu * n + a) for j, a in jacobian]))
        if nu >= 1:
            bend = [(nu * n + a, (nu - 1) * n + b) for a, b in constraint_hessian]
            entries.append(np.array(bend))
    everything = np.vstack([e.reshape(-1, 2) for e in entries])
    kb = int(np.max(np.abs(place[everything[:, 0]] - place[everything[:, 1]])))
    if 3 * (kb + 1) > size:
        return None
    vpairs = [(a, b) for a, b in _pairs(system.pieces.Lvv)] + [(a, a) for a in range(n)]
    vpairs = np.array(sorted(set(vpairs)), dtype=np.int64)
    place_b = group.astype(np.int64)
    projection = np.vstack([vpairs, np.array([(a, n + j) for j, a in jacobian])])
    kb_b = int(np.max(np.abs(place_b[projection[:, 0]] - place_b[projection[:, 1]])))
    return (
        place,
        kb,
        kpairs,
        np.array(jacobian, dtype=np.int64).reshape(-1, 2),
        np.array(constraint_hessian, dtype=np.int64).reshape(-1, 2),
        place_b,
        kb_b,
        vpairs,
    )
