"""Butcher tables of Gauss collocation and Lobatto IIIA–IIIB, computed here at 40 digits.

Independent of the library's own tables (and of the hand-written benchmark kernels in
``benchmarks/``): the nodes are roots of shifted Legendre polynomials from
``mpmath.polyroots``, and ``A[i, j] = ∫_0^{c_i} l_j`` comes from solving a Vandermonde
system in mpmath, rounded once to float64.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import mpmath
import numpy as np
from numpy.typing import NDArray

__all__ = ["GaussTables", "LobattoTables", "gauss_tables", "lobatto_tables"]

_DIGITS = 40


@dataclass(frozen=True)
class GaussTables:
    """s-stage Gauss: ``c``, ``b``, ``A``, ``A2 = A @ A`` and ``bA = b @ A``."""

    A: NDArray[np.float64]
    A2: NDArray[np.float64]
    b: NDArray[np.float64]
    bA: NDArray[np.float64]
    c: NDArray[np.float64]


@dataclass(frozen=True)
class LobattoTables:
    """r-stage Lobatto IIIA–IIIB: ``c``, ``b`` and ``AB = A @ Abar`` (IIIA times IIIB)."""

    AB: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]


def _shifted_legendre(n: int) -> list:
    """Coefficients (ascending powers) of P_n(2x - 1)."""
    return [
        (-1) ** (n + k) * mpmath.binomial(n, k) * mpmath.binomial(n + k, k) for k in range(n + 1)
    ]


def _roots(ascending: list) -> list:
    roots = mpmath.polyroots(ascending[::-1], maxsteps=200, extraprec=200)
    return sorted(mpmath.re(r) for r in roots)


def _integration_matrix(c: list) -> mpmath.matrix:
    """``A[i, j] = ∫_0^{c_i} l_j`` for the Lagrange basis l_j on the nodes ``c``."""
    m = len(c)
    V = mpmath.matrix(m, m)
    W = mpmath.matrix(m, m)
    for i, ci in enumerate(c):
        for k in range(m):
            V[i, k] = ci**k
            W[i, k] = ci ** (k + 1) / (k + 1)
    # a polynomial with values y on c has monomial coefficients V^{-1} y
    return W * mpmath.inverse(V)


def _weights(c: list) -> list:
    m = len(c)
    V = mpmath.matrix(m, m)
    for i, ci in enumerate(c):
        for k in range(m):
            V[i, k] = ci**k
    moments = mpmath.matrix([mpmath.mpf(1) / (k + 1) for k in range(m)])
    return list(mpmath.lu_solve(V.T, moments))


def _array(x) -> NDArray[np.float64]:
    if isinstance(x, mpmath.matrix):
        return np.array(x.tolist(), dtype=float)
    return np.array([float(v) for v in x])


@cache
def gauss_tables(s: int) -> GaussTables:
    """Tables of the s-stage Gauss method (s >= 1)."""
    with mpmath.workdps(_DIGITS):
        c = _roots(_shifted_legendre(s)) if s > 1 else [mpmath.mpf(1) / 2]
        A = _integration_matrix(c)
        b = _weights(c)
        bA = [sum(b[i] * A[i, j] for i in range(s)) for j in range(s)]
        return GaussTables(A=_array(A), A2=_array(A * A), b=_array(b), bA=_array(bA), c=_array(c))


@cache
def lobatto_tables(r: int) -> LobattoTables:
    """Tables of the r-stage Lobatto IIIA–IIIB pair (r >= 2)."""
    with mpmath.workdps(_DIGITS):
        # interior nodes: roots of d/dx P_{r-1}(2x - 1)
        p = _shifted_legendre(r - 1)
        interior = _roots([k * p[k] for k in range(1, len(p))]) if r > 2 else []
        c = [mpmath.mpf(0), *interior, mpmath.mpf(1)]
        A = _integration_matrix(c)
        b = _weights(c)
        Abar = mpmath.matrix(r, r)
        for i in range(r):
            for j in range(r):
                Abar[i, j] = b[j] * (1 - A[j, i] / b[i])
        AB = _array(A * Abar)
        AB[:, -1] = 0.0  # exactly zero in exact arithmetic
        return LobattoTables(AB=AB, b=_array(b), c=_array(c))
