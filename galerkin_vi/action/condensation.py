r"""Newton's linear system for a whole path: interior points condensed, a banded chain solved.

The stationarity equations of the discrete action couple each element's
control points only with one another, and neighbouring elements only through
their shared node. Per element, with the end points :math:`e = (q_k, q_{k+1})`
and the interior points :math:`i` (:math:`\nu = 1..s-1`; with constraints,
each point's multipliers beside it), the Newton system reads

.. math::

    \begin{pmatrix} H_{ee} & H_{ei} \\ H_{ie} & H_{ii} \end{pmatrix}
    \begin{pmatrix} \Delta_e \\ \Delta_i \end{pmatrix}
    = -\begin{pmatrix} G_e \\ G_i \end{pmatrix}.

:math:`H_{ii}` is the Jacobian of the stage equations of a single step
(invertible wherever a step is), so the interior unknowns are eliminated
element by element (static condensation),

.. math::

    K = H_{ee} - H_{ei} H_{ii}^{-1} H_{ie}, \qquad
    r = G_e - H_{ei} H_{ii}^{-1} G_i, \qquad
    \Delta_i = -H_{ii}^{-1}(G_i + H_{ie}\Delta_e),

leaving one block-tridiagonal system in the nodes, assembled from the
:math:`2 \times 2` blocks of :math:`K`. It is indefinite beyond the first
conjugate point, so it is solved for stationarity by LU with partial pivoting
in band storage (LAPACK ``gbsv``): bandwidth :math:`2n' - 1` for :math:`n'`
unknowns per node, :math:`O(N n'^3)` work, batched over elements for the
condensation.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = ["Condensed", "condense", "solve_node_chain"]


@dataclass(frozen=True)
class Condensed:
    r"""The condensed element systems and what the back-substitution needs.

    Attributes
    ----------
    K : ndarray, shape (N, 2, w, 2, w)
        :math:`K` in node blocks (first and last node of each element), ``w``
        unknowns per point.
    r : ndarray, shape (N, 2, w)
        The condensed right-hand sides :math:`r`.
    interior : ndarray, shape (N, (s - 1) w, 2 w + 1)
        :math:`H_{ii}^{-1}[H_{ie}\ G_i]`.
    """

    K: NDArray[np.float64]
    r: NDArray[np.float64]
    interior: NDArray[np.float64]

    def interior_step(self, node_step: NDArray) -> NDArray[np.float64]:
        r""":math:`\Delta_i` (N, s - 1, w) from the node steps ``node_step`` (N + 1, w)."""
        N, _, w = self.r.shape
        ends = np.concatenate([node_step[:-1], node_step[1:]], axis=1)  # (N, 2 w)
        inner = self.interior[..., -1] + np.einsum("kij,kj->ki", self.interior[..., :-1], ends)
        return -inner.reshape(N, -1, w)


def condense(H: NDArray, G: NDArray) -> Condensed:
    """Eliminate the interior points of every element.

    Parameters
    ----------
    H : ndarray, shape (N, s + 1, w, s + 1, w)
        Element Jacobians (with constraints: the multipliers' rows and columns).
    G : ndarray, shape (N, s + 1, w)
        Element residuals.

    Raises
    ------
    numpy.linalg.LinAlgError
        If some element's interior block is singular.
    """
    N, s1, w = G.shape
    s = s1 - 1
    ends = [0, s]
    Hee = H[:, ends][:, :, :, ends]
    Ge = G[:, ends]
    if s == 1:
        return Condensed(Hee, Ge, np.zeros((N, 0, 2 * w + 1)))
    inner = w * (s - 1)
    Hii = H[:, 1:s][:, :, :, 1:s].reshape(N, inner, inner)
    Hie = H[:, 1:s][:, :, :, ends].reshape(N, inner, 2 * w)
    Hei = H[:, ends][:, :, :, 1:s].reshape(N, 2 * w, inner)
    rhs = np.concatenate([Hie, G[:, 1:s].reshape(N, inner, 1)], axis=2)
    Y = np.linalg.solve(Hii, rhs)
    K = Hee.reshape(N, 2 * w, 2 * w) - Hei @ Y[..., :-1]
    r = Ge.reshape(N, 2 * w) - np.einsum("kij,kj->ki", Hei, Y[..., -1])
    return Condensed(K.reshape(N, 2, w, 2, w), r.reshape(N, 2, w), Y)


def solve_node_chain(condensed: Condensed, free: NDArray) -> NDArray[np.float64]:
    r"""Solve the assembled node system :math:`\sum_k K_k \Delta = -\sum_k r_k`.

    Parameters
    ----------
    condensed : Condensed
    free : ndarray of bool, shape (N + 1,)
        Which nodes are unknowns; the others (the two ends of a boundary-value
        problem) keep :math:`\Delta = 0`.

    Returns
    -------
    ndarray, shape (N + 1, w)
        The node steps, zero at the fixed nodes.

    Raises
    ------
    numpy.linalg.LinAlgError
        If the assembled system is singular.
    """
    import scipy.linalg  # here: SciPy costs 35 MB and a quarter second on import

    K, r = condensed.K, condensed.r
    N, _, w = r.shape
    index = np.full(N + 1, -1)
    index[free] = np.arange(int(free.sum()))
    size = int(free.sum()) * w
    step = np.zeros((N + 1, w))
    if size == 0:
        return step
    rhs = np.zeros(size)
    a = np.arange(w)
    k = np.arange(N)
    for alpha in (0, 1):
        node = index[k + alpha]
        keep = node >= 0
        rows = (node[keep, None] * w + a[None, :]).ravel()
        np.add.at(rhs, rows, -r[keep, alpha].ravel())
    band = 2 * w - 1
    ab = np.zeros((2 * band + 1, size))
    for alpha in (0, 1):
        for beta in (0, 1):
            row_node, col_node = index[k + alpha], index[k + beta]
            keep = (row_node >= 0) & (col_node >= 0)
            rows = row_node[keep, None, None] * w + a[None, :, None]
            cols = col_node[keep, None, None] * w + a[None, None, :]
            rows, cols = np.broadcast_arrays(rows, cols)
            np.add.at(ab, (band + rows - cols, cols), K[keep, alpha, :, beta, :])
    x = scipy.linalg.solve_banded((band, band), ab, rhs, check_finite=False)
    step[free] = x.reshape(-1, w)
    return step
