r"""The discrete action of a whole path, element by element, with its exact derivatives.

A path of ``N`` elements on the mesh :math:`t_k = t_0 + kh` is given by the
control points :math:`X_{k\nu} = q_k^\nu` (:math:`\nu = 0..s`), with
:math:`q_k^s = q_{k+1}^0` shared between neighbours. Element :math:`k`
contributes

.. math::

    S_k = h \sum_i b_i\, L\Big(t_k + c_i h,\ \sum_\nu \Phi_{i\nu} q_k^\nu,\
          \frac1h \sum_\nu D_{i\nu} q_k^\nu\Big),

and the discrete action is :math:`S_d = \sum_k S_k`. Its gradient with
respect to the element's control points is

.. math::

    G_k^\nu = h \sum_i b_i\, (L_q + f)^{(i)} \Phi_{i\nu} + \sum_i b_i\, L_v^{(i)} D_{i\nu},

where the forces :math:`f` enter as in the discrete Lagrange–d'Alembert
principle (so with forces :math:`G` is not a gradient and its Jacobian not
symmetric), and the Jacobian
:math:`H_k^{\nu a, \mu c} = \partial G_k^{\nu a} / \partial q_k^{\mu c}` follows
from :math:`L_{qq}, L_{qv}, L_{vv}` (and :math:`f_q, f_v`). Every quadrature
point of every element is evaluated in one vectorised call of the system's
NumPy evaluators, so a Newton iteration costs a fixed number of array passes
whatever ``N`` is.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..method.galerkin import MethodTables
from ..model.system import LagrangianSystem

__all__ = ["ElementPoints", "element_actions", "element_gradients", "element_jacobians"]


@dataclass(frozen=True)
class ElementPoints:
    """Times, positions and velocities at every quadrature point of every element.

    Attributes
    ----------
    t : ndarray, shape (N, r)
    q, v : ndarray, shape (N, r, n)
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    v: NDArray[np.float64]

    @classmethod
    def of(cls, tables: MethodTables, t_nodes: NDArray, h: float, X: NDArray) -> ElementPoints:
        """Interpolate the control points ``X`` (N, s + 1, n) at the quadrature nodes.

        The increments :math:`q_k^\\nu - q_k^0` carry the velocities, which keeps
        them free of the rounding :math:`\\varepsilon |q| / h` of differences
        of large positions (as the time loops do).
        """
        base = X[:, :1, :]
        C = X[:, 1:, :] - base
        q = base + np.einsum("iv,kva->kia", tables.Phi[:, 1:], C)
        v = np.einsum("iv,kva->kia", tables.D[:, 1:], C) / h
        t = t_nodes[:-1, None] + tables.c[None, :] * h
        return cls(t, q, v)


def _evaluate(system: LagrangianSystem, name: str, points: ElementPoints, prm: NDArray):
    return system.evaluate(name, points.t, points.q, points.v, prm)


def element_actions(
    system: LagrangianSystem, tables: MethodTables, points: ElementPoints, h: float, prm: NDArray
) -> NDArray[np.float64]:
    """:math:`S_k` of every element, shape (N,)."""
    values = _evaluate(system, "L", points, prm)[..., 0]
    return h * (values @ tables.b)


def element_gradients(
    system: LagrangianSystem, tables: MethodTables, points: ElementPoints, h: float, prm: NDArray
) -> NDArray[np.float64]:
    r""":math:`G_k^\nu` of every element, shape (N, s + 1, n)."""
    n = system.n
    values = _evaluate(system, "gradient", points, prm)
    force, lv = values[..., :n], values[..., n:]
    b = tables.b[None, :, None]
    return h * np.einsum("iv,kia->kva", tables.Phi, b * force) + np.einsum(
        "iv,kia->kva", tables.D, b * lv
    )


def element_jacobians(
    system: LagrangianSystem, tables: MethodTables, points: ElementPoints, h: float, prm: NDArray
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r""":math:`G_k` (N, s + 1, n) and :math:`H_k` (N, s + 1, n, s + 1, n) of every element."""
    n = system.n
    values = _evaluate(system, "hessian", points, prm)
    force, lv = values[..., :n], values[..., n : 2 * n]
    blocks = (values.shape[-1] - 2 * n) // (n * n)
    lqq, lqv, lvv, *fv = (
        values[..., 2 * n + j * n * n : 2 * n + (j + 1) * n * n].reshape(values.shape[:-1] + (n, n))
        for j in range(blocks)
    )
    # the row of q-derivatives of (L_q + f) by v carries f_v; L_v's row by q is L_qv^T
    lqv_row = lqv + fv[0] if fv else lqv
    b, Phi, D = tables.b, tables.Phi, tables.D
    G = h * np.einsum("iv,kia->kva", Phi, b[None, :, None] * force) + np.einsum(
        "iv,kia->kva", D, b[None, :, None] * lv
    )
    PP = b[:, None, None] * Phi[:, :, None] * Phi[:, None, :]
    PD = b[:, None, None] * Phi[:, :, None] * D[:, None, :]
    DP = b[:, None, None] * D[:, :, None] * Phi[:, None, :]
    DD = b[:, None, None] * D[:, :, None] * D[:, None, :]
    H = (
        h * np.einsum("ivu,kiac->kvauc", PP, lqq)
        + np.einsum("ivu,kiac->kvauc", PD, lqv_row)
        + np.einsum("ivu,kica->kvauc", DP, lqv)
        + np.einsum("ivu,kiac->kvauc", DD, lvv) / h
    )
    return G, H
