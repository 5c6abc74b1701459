r"""Holonomic constraints on a whole path: a multiplier at every control point.

The path is stationary for :math:`S_d` subject to :math:`g(t, q) = 0` at every
control point (the points where the time-stepping constrained loop imposes
them too): stationarity of

.. math::

    S_d + \sum_{\text{points } c} \lambda_c \cdot g(t_c, q_c),

that is :math:`G + g_q^{\mathsf T}\lambda = 0` and :math:`g = 0` at each point.
Each point's unknowns become :math:`(q_c, \lambda_c)`, ``w = n + m`` of them,
and its Jacobian block gains :math:`\sum_j \lambda_j \partial^2 g_j/\partial q^2`
and the constraint Jacobian on both sides. Element :math:`k` owns its points
:math:`\nu = 0..s-1` (node :math:`k` and the interior points), so that each
shared node's constraint is counted once.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..method.galerkin import MethodTables
from ..model.system import LagrangianSystem

__all__ = ["augment", "constraint_values"]


def _owned_times(tables: MethodTables, t_nodes: NDArray, h: float) -> NDArray:
    return t_nodes[:-1, None] + tables.d[None, :-1] * h


def constraint_values(
    system: LagrangianSystem, tables: MethodTables, t_nodes: NDArray, h: float, X: NDArray,
    prm: NDArray,
) -> NDArray[np.float64]:  # fmt: skip
    """:math:`g` at every owned control point, shape (N, s, m)."""
    t = _owned_times(tables, t_nodes, h)
    q = X[:, :-1]
    return system.evaluate("g", t, q, np.zeros_like(q), prm)


def augment(
    system: LagrangianSystem,
    tables: MethodTables,
    t_nodes: NDArray,
    h: float,
    X: NDArray,
    lam: NDArray,
    prm: NDArray,
    G: NDArray,
    H: NDArray | None = None,
) -> tuple[NDArray, NDArray | None]:
    r"""Residuals (and Jacobians) with every point's multipliers beside its position.

    Parameters
    ----------
    X : ndarray, shape (N, s + 1, n)
        Control points.
    lam : ndarray, shape (N, s, m)
        Multipliers of the owned points.
    G, H : ndarray
        The element residuals (N, s + 1, n) and Jacobians (N, s + 1, n, s + 1, n)
        of :mod:`.elements`; ``H`` may be None (residuals only).

    Returns
    -------
    (ndarray, ndarray or None)
        Shapes (N, s + 1, w) and (N, s + 1, w, s + 1, w), ``w = n + m``; the
        multiplier rows of point :math:`\nu = s` are zero (its next element
        owns it).
    """
    n, m = system.n, system.m
    N, s1, _ = G.shape
    s = s1 - 1
    t = _owned_times(tables, t_nodes, h)
    q = X[:, :-1]
    zeros = np.zeros_like(q)
    g = system.evaluate("g", t, q, zeros, prm)
    gq = system.evaluate("g_q", t, q, zeros, prm).reshape(N, s, m, n)
    Ge = np.zeros((N, s1, n + m))
    Ge[..., :n] = G
    Ge[:, :s, :n] += np.einsum("kvja,kvj->kva", gq, lam)
    Ge[:, :s, n:] = g
    if H is None:
        return Ge, None
    gqq = system.evaluate("g_qq", t, q, zeros, prm).reshape(N, s, m, n, n)
    curvature = np.einsum("kvjac,kvj->kvac", gqq, lam)
    He = np.zeros((N, s1, n + m, s1, n + m))
    He[:, :, :n, :, :n] = H
    for nu in range(s):
        He[:, nu, :n, nu, :n] += curvature[:, nu]
        He[:, nu, :n, nu, n:] = np.swapaxes(gq[:, nu], 1, 2)
        He[:, nu, n:, nu, :n] = gq[:, nu]
    return Ge, He
