r"""Point-wise symbolic pieces of the discrete Euler–Lagrange equations.

Every residual and Jacobian of a Galerkin variational integrator is a weighted
sum, over quadrature points :math:`(t_i, Q_i, V_i)`, of a handful of point-wise
derivatives of the Lagrangian :math:`L(t, q, v)`:

.. math::

    L_q = \partial_q L,\quad L_v = \partial_v L,\quad
    L_{qq} = \partial_q^2 L,\quad L_{qv} = \partial_q\partial_v L,\quad
    L_{vv} = \partial_v^2 L .

This module derives them with SymPy (never by finite differences) and reads off
the structure that lets the kernels skip work.
"""

from __future__ import annotations

from dataclasses import dataclass

import sympy as sp

__all__ = ["PointwisePieces", "Structure", "analyse_structure", "pointwise_pieces"]


@dataclass(frozen=True)
class PointwisePieces:
    """SymPy expressions for :math:`L` and its first and second derivatives.

    Attributes
    ----------
    L : sympy.Expr
    Lq, Lv : sympy.Matrix, shape (n, 1)
    Lqq, Lqv, Lvv : sympy.Matrix, shape (n, n)
        ``Lqv[a, b]`` is :math:`\\partial^2 L / \\partial q_a \\partial v_b`.
    """

    L: sp.Expr
    Lq: sp.Matrix
    Lv: sp.Matrix
    Lqq: sp.Matrix
    Lqv: sp.Matrix
    Lvv: sp.Matrix


@dataclass(frozen=True)
class Structure:
    """Structure of a Lagrangian that the integrator can exploit.

    Attributes
    ----------
    autonomous : bool
        :math:`L` does not depend on time.
    zero_Lqv : bool
        :math:`\\partial_q\\partial_v L \\equiv 0` (no velocity–position coupling).
    quadratic_in_v : bool
        :math:`L = \\tfrac12 v^T M(t, q) v + a(t, q)\\cdot v - V(t, q)`.
    constant_mass : bool
        :math:`L_{vv}` depends on parameters at most (constant mass matrix).
    separable : bool
        :math:`L = \\tfrac12 v^T M v - V(q)` with constant :math:`M` (``zero_Lqv``
        and ``constant_mass``); the setting of Störmer–Verlet.
    quadratic : bool
        :math:`L` is a polynomial of degree at most two in :math:`(q, v)`, so the
        stage equations are linear.
    """

    autonomous: bool
    zero_Lqv: bool
    quadratic_in_v: bool
    constant_mass: bool
    separable: bool
    quadratic: bool


def pointwise_pieces(L: sp.Expr, q: list[sp.Symbol], v: list[sp.Symbol]) -> PointwisePieces:
    """Differentiate ``L`` once and twice with respect to ``q`` and ``v``."""
    qm, vm = sp.Matrix(q), sp.Matrix(v)
    Lq = sp.Matrix([sp.diff(L, s) for s in q])
    Lv = sp.Matrix([sp.diff(L, s) for s in v])
    return PointwisePieces(
        L=L,
        Lq=Lq,
        Lv=Lv,
        Lqq=Lq.jacobian(qm),
        Lqv=Lq.jacobian(vm),
        Lvv=Lv.jacobian(vm),
    )


def _is_zero_matrix(m: sp.Matrix) -> bool:
    return all(sp.simplify(e) == 0 for e in m)


def analyse_structure(
    pieces: PointwisePieces,
    q: list[sp.Symbol],
    v: list[sp.Symbol],
    t: sp.Symbol | None,
) -> Structure:
    """Find the structure flags of :class:`Structure` from the derivatives."""
    qv = set(q) | set(v)
    autonomous = t is None or t not in pieces.L.free_symbols
    zero_Lqv = _is_zero_matrix(pieces.Lqv)
    lvv_symbols = set().union(*(e.free_symbols for e in pieces.Lvv))
    quadratic_in_v = not (lvv_symbols & set(v))
    constant_mass = not (lvv_symbols & (qv | ({t} if t is not None else set())))
    hess_symbols = set().union(
        *(e.free_symbols for m in (pieces.Lqq, pieces.Lqv, pieces.Lvv) for e in m)
    )
    quadratic = not (hess_symbols & (qv | ({t} if t is not None else set())))
    return Structure(
        autonomous=autonomous,
        zero_Lqv=zero_Lqv,
        quadratic_in_v=quadratic_in_v,
        constant_mass=constant_mass,
        separable=zero_Lqv and constant_mass,
        quadratic=quadratic,
    )
