r"""Dense output: positions, velocities and momenta between the steps of a run.

A Galerkin step's own polynomial :math:`q_d(t)` is accurate to
:math:`O(h^{s+1})` only, far below the method's nodal order :math:`2s` (the
nodes are superconvergent, the stages are not). The nodal data are better:
:math:`q_k` and :math:`v_k = (\mathbb FL)^{-1}(q_k, p_k)` both carry the
method's full order, and the global error is a smooth function of :math:`t`.
So the interpolant offered here is the **Hermite interpolant through**
:math:`(t_j, q_j, v_j)` **at N consecutive nodes around the step**: the
polynomial of degree :math:`2N - 1` matching positions and velocities at each.
Interpolating exact data it errs by :math:`O(h^{2N})`, its derivative by
:math:`O(h^{2N-1})`; with the method's data of order :math:`p` the errors are
:math:`O(h^{\min(2N,\,p)})` and :math:`O(h^{\min(2N-1,\,p)})`.
:func:`stencil_nodes` chooses the least N with :math:`2N - 1 \ge p`: cubic
Hermite (N = 2) for order 2, N = 3 for order 4, N = 4 for order 6. The
measured orders are in ``docs/howto/dense-output.md``.

Near the ends of the run the stencil shifts inwards (one-sided, same degree);
the nodes need not be equally spaced (adaptive runs, a final landing step).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..model.system import LagrangianSystem

__all__ = ["DenseOutput", "StateInterpolant", "hermite", "query_times", "stencil_nodes"]

#: dense outputs of at most this many nodes keep the Newton tables of all their stencils
#: (computed on the first call; about 2 stencil x n numbers per node): repeated calls on
#: a short run then only evaluate
_CACHED_STENCILS = 4096


def stencil_nodes(order: int) -> int:
    """Nodes N of the Hermite stencil for a method of global order ``order``.

    The least N with ``2 N - 1 >= order``: the interpolant's derivative, of
    error :math:`O(h^{2N-1})`, then has the method's order too (the cubic
    Hermite interpolant of an order-4 method gives velocities of order 3 only,
    measured). At least 2.
    """
    if isinstance(order, bool) or not isinstance(order, int) or order < 1:
        raise ValueError(f"order must be a positive int, got {order!r}")
    return max(2, order // 2 + 1)


def hermite(
    nodes: NDArray, values: NDArray, slopes: NDArray, t: NDArray
) -> tuple[NDArray, NDArray]:
    r"""Hermite interpolant through values and slopes at nodes, and its derivative.

    Parameters
    ----------
    nodes : ndarray, shape (m, N)
        For each of m query points, its N distinct nodes :math:`t_j`.
    values, slopes : ndarray, shape (m, N, n)
        :math:`y(t_j)` and :math:`y'(t_j)`.
    t : ndarray, shape (m,)
        The query points.

    Returns
    -------
    y, dy : ndarray, shape (m, n)
        The interpolant :math:`P(t)` of degree :math:`2N - 1` with
        :math:`P(t_j) = y_j`, :math:`P'(t_j) = y'_j`, and :math:`P'(t)`.

    Notes
    -----
    Newton's form on the doubled nodes :math:`z = (t_1, t_1, t_2, t_2, \dots)`:
    confluent divided differences :math:`f[t_j, t_j] = y'_j`, then the usual
    recursion, evaluated by Horner's rule with its derivative.
    """
    z, coef = hermite_coefficients(nodes, values, slopes)
    return hermite_evaluate(z, coef, t)


def hermite_coefficients(nodes: NDArray, values: NDArray, slopes: NDArray):
    """Newton coefficients of :func:`hermite`'s interpolants: (z (m, 2N), coef (m, 2N, n)).

    Computed once per stencil, they serve every query point in its interval
    (:meth:`DenseOutput.state` groups the points by stencil).
    """
    m, N, n = values.shape
    z = np.repeat(nodes, 2, axis=1)  # (m, 2N)
    # column k of the table holds f[z_i, ..., z_{i+k}]; updated in place, top down
    coef = np.repeat(values, 2, axis=1)  # (m, 2N, n)
    table = coef.copy()
    for k in range(1, 2 * N):
        span = (z[:, k:] - z[:, :-k])[:, :, None]
        differences = table[:, 1 : 2 * N - k + 1] - table[:, : 2 * N - k]
        with np.errstate(divide="ignore", invalid="ignore"):
            new = differences / span
        if k == 1:
            # repeated nodes: the first divided difference is the slope
            new[:, 0::2] = slopes
        table = new
        coef[:, k] = table[:, 0]
    return z, coef


def hermite_evaluate(z: NDArray, coef: NDArray, t: NDArray) -> tuple[NDArray, NDArray]:
    """The interpolants of :func:`hermite_coefficients` and their derivatives at ``t`` (m,)."""
    x = t[:, None]
    y = coef[:, -1].copy()
    dy = np.zeros_like(y)
    for k in range(z.shape[1] - 2, -1, -1):
        step = x - z[:, k : k + 1]
        dy = dy * step + y
        y = y * step + coef[:, k]
    return y, dy


def query_times(t: ArrayLike, t_min: float, t_max: float) -> tuple[NDArray, NDArray]:
    """``t`` as an array and flattened, checked: finite and in ``[t_min, t_max]`` (to a
    few ulps: a dense output does not extrapolate)."""
    times = np.asarray(t, dtype=float)
    flat = np.atleast_1d(times).ravel()
    if not np.all(np.isfinite(flat)):
        raise ValueError("t must be finite")
    tiny = 8 * np.finfo(float).eps * max(1.0, abs(t_min), abs(t_max))
    outside = (flat < t_min - tiny) | (flat > t_max + tiny)
    if np.any(outside):
        raise ValueError(
            f"t = {float(flat[outside][0])!r} is outside the run's span "
            f"[{t_min!r}, {t_max!r}]: dense output does not extrapolate"
        )
    return times, flat


class StateInterpolant:
    """Positions, velocities and momenta from ``state(t) -> (q, v)``: the calls every
    dense output shares (it provides ``state``, ``system`` and ``params``)."""

    def __call__(self, t: ArrayLike) -> NDArray[np.float64]:
        """Positions at ``t``."""
        return self.state(t)[0]

    def velocity(self, t: ArrayLike) -> NDArray[np.float64]:
        """Velocities at ``t``: the interpolant's derivative."""
        return self.state(t)[1]

    def momentum(self, t: ArrayLike) -> NDArray[np.float64]:
        r"""Momenta :math:`p = \partial L/\partial v` of the interpolated (q, v) at ``t``."""
        q, v = self.state(t)
        prm = dict(zip(self.system.params, self.params, strict=True))
        return self.system.legendre(q, v, np.asarray(t, dtype=float), prm)


@dataclass(frozen=True, eq=False)
class DenseOutput(StateInterpolant):
    r"""Positions, velocities and momenta of a run at any time in its span.

    Call it like :class:`scipy.integrate.OdeSolution`, with one difference in
    layout: results are **t-major**, as ``Trajectory.q`` is: ``sol(t)`` has
    shape ``(n,)`` for a scalar ``t`` and ``(len(t), n)`` for an array
    (``OdeSolution`` returns ``(n, len(t))``). Built by
    :meth:`Trajectory.dense` (and ``integrate(..., dense_output=True)``).

    Attributes
    ----------
    t, q, v : ndarray
        The nodes: saved times, positions and velocities, shapes (N,), (N, n).
    stencil : int
        Nodes per interpolant (see :func:`stencil_nodes`).
    system : LagrangianSystem
        The run's system (for the momenta).
    params : ndarray
        The run's parameter values.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]
    stencil: int
    system: LagrangianSystem
    params: NDArray[np.float64]

    @property
    def t_min(self) -> float:
        return float(min(self.t[0], self.t[-1]))

    @property
    def t_max(self) -> float:
        return float(max(self.t[0], self.t[-1]))

    @cached_property
    def _tables(self) -> tuple[NDArray, NDArray]:
        """The Newton tables of every stencil (first node 0 .. len(t) - size)."""
        size = min(self.stencil, len(self.t))
        index = np.arange(len(self.t) - size + 1)[:, None] + np.arange(size)
        return hermite_coefficients(self.t[index], self.q[index], self.v[index])

    def state(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions and velocities at ``t`` (scalar or array), t-major."""
        times, flat = query_times(t, self.t_min, self.t_max)
        forward = self.t[-1] >= self.t[0]
        nodes = self.t if forward else self.t[::-1]
        k = np.clip(np.searchsorted(nodes, flat, side="right") - 1, 0, len(nodes) - 2)
        if not forward:
            k = len(nodes) - 2 - k  # interval [t_{k}, t_{k+1}] of the run's own order
        size = min(self.stencil, len(self.t))
        # the stencil's nodes around the interval [t_k, t_k+1], shifted inwards at the ends
        first = np.clip(k - (size - 1) // 2, 0, len(self.t) - size)
        if len(self.t) <= _CACHED_STENCILS:
            # every stencil's Newton table, computed once per dense output
            z, coef = self._tables
            y, dy = hermite_evaluate(z[first], coef[first], flat)
        else:
            # one Newton table per stencil used, shared by the query points that use it
            stencils, which = np.unique(first, return_inverse=True)
            index = stencils[:, None] + np.arange(size)
            z, coef = hermite_coefficients(self.t[index], self.q[index], self.v[index])
            y, dy = hermite_evaluate(z[which], coef[which], flat)
        self._keep_nodes(k, flat, y, dy)
        shape = times.shape + (self.q.shape[1],)
        return y.reshape(shape), dy.reshape(shape)

    def _keep_nodes(self, k: NDArray, flat: NDArray, y: NDArray, dy: NDArray) -> None:
        """Put the nodal data at the query points that are nodes of interval k, in place.

        Horner's rule on Newton's form reproduces only the stencil's first node
        exactly; at the others it rounds, and ``sol(t_k)`` must be ``q_k``.
        """
        for j in (k, k + 1):
            at = self.t[j] == flat
            y[at] = self.q[j[at]]
            dy[at] = self.v[j[at]]
