r"""The Galerkin method: degree, quadrature, control nodes and their tables."""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from functools import lru_cache

import mpmath
import numpy as np
from numpy.typing import NDArray

from ..errors import ConditioningWarning, OrderReductionWarning
from .basis import (
    equidistant_control_nodes_mp,
    lagrange_tables_mp,
    lobatto_control_nodes_mp,
)
from .quadrature import QuadratureRule, gauss_legendre_mp, gauss_lobatto, gauss_lobatto_mp

__all__ = ["ExactTables", "Galerkin", "MethodTables"]

_NODE_FAMILIES = ("lobatto", "equidistant")
_EQUIDISTANT_MAX_DEGREE = 6
_TABLE_DIGITS = 40


@dataclass(frozen=True)
class MethodTables:
    r"""Numeric tables of a Galerkin method, computed in extended precision.

    With control nodes :math:`d_\nu` (:math:`\nu = 0..s`), Lagrange basis
    :math:`\ell_\nu` and quadrature :math:`(c_i, b_i)` (:math:`i = 1..r`):

    Attributes
    ----------
    b, c : ndarray, shape (r,)
        Quadrature weights and nodes on [0, 1].
    d : ndarray, shape (s + 1,)
        Control nodes, ``d[0] = 0`` and ``d[s] = 1``.
    Phi : ndarray, shape (r, s + 1)
        :math:`\Phi_{i\nu} = \ell_\nu(c_i)`.
    D : ndarray, shape (r, s + 1)
        :math:`D_{i\nu} = \ell'_\nu(c_i)`.
    extrapolation : ndarray, shape (s + 1, s + 1)
        :math:`E_{\nu\mu} = \ell_\mu(1 + d_\nu)`: the previous step's polynomial
        evaluated at this step's control nodes (the Newton initial guess).
    """

    b: NDArray[np.float64]
    c: NDArray[np.float64]
    d: NDArray[np.float64]
    Phi: NDArray[np.float64]
    D: NDArray[np.float64]
    extrapolation: NDArray[np.float64]


@dataclass(frozen=True)
class ExactTables:
    """The fields of :class:`MethodTables` as (nested) lists of mpmath numbers."""

    b: list
    c: list
    d: list
    Phi: list
    D: list
    extrapolation: list


class Galerkin:
    r"""Galerkin variational integrator of polynomial degree ``s``.

    The discrete Lagrangian over one step of size :math:`h` is

    .. math::

        L_d(q^0, \dots, q^s) = h \sum_{i=1}^r b_i\,
        L\Big(t_k + c_i h,\ \sum_\nu \ell_\nu(c_i) q^\nu,\
        \frac1h \sum_\nu \ell'_\nu(c_i) q^\nu\Big),

    with :math:`q^0 = q_k`, :math:`q^s = q_{k+1}` and the interior control points
    eliminated by stationarity.

    Parameters
    ----------
    degree : int
        Polynomial degree :math:`s \ge 1`.
    quadrature : QuadratureRule, optional
        Defaults to ``gauss_lobatto(degree + 1)``, collocated with the default
        control nodes. It needs at least ``degree`` points.
    nodes : {"lobatto", "equidistant"}
        Control nodes of the Lagrange basis. Gauss–Lobatto–Legendre nodes
        (default) keep the stage equations well conditioned at any degree;
        equidistant nodes are warned about above degree 6.

    Attributes
    ----------
    order : int
        Predicted global order :math:`\min(2s, u)` with :math:`u` the order of
        the quadrature (Gauss :math:`m` points: :math:`2m`; Lobatto: :math:`2m-2`).

    Warns
    -----
    OrderReductionWarning
        If the quadrature order is below :math:`2s`.
    ConditioningWarning
        For equidistant nodes above degree 6.

    References
    ----------
    .. [1] S. Ober-Blöbaum, N. Saake, "Construction and analysis of higher order
       Galerkin variational integrators", Adv. Comput. Math. 41 (2015) 955–986.
    .. [2] S. Ober-Blöbaum, "Galerkin variational integrators and modified
       symplectic Runge–Kutta methods", IMA J. Numer. Anal. 37 (2017) 375–406.

    Examples
    --------
    >>> from galerkin_vi import Galerkin, gauss_legendre
    >>> Galerkin(3).order
    6
    >>> Galerkin(2, gauss_legendre(2)).order
    4
    """

    def __init__(
        self,
        degree: int,
        quadrature: QuadratureRule | None = None,
        nodes: str = "lobatto",
    ) -> None:
        if isinstance(degree, bool) or not isinstance(degree, (int, np.integer)):
            raise TypeError(f"degree must be an int, got {type(degree).__name__}")
        if degree < 1:
            raise ValueError(f"degree must be >= 1, got {degree}")
        degree = int(degree)
        if quadrature is None:
            quadrature = gauss_lobatto(degree + 1)
        if not isinstance(quadrature, QuadratureRule):
            raise TypeError(
                "quadrature must be a QuadratureRule (gauss_lobatto(m) or gauss_legendre(m)), "
                f"got {type(quadrature).__name__}"
            )
        if nodes not in _NODE_FAMILIES:
            raise ValueError(f"nodes must be one of {_NODE_FAMILIES}, got {nodes!r}")
        if quadrature.npoints < degree:
            raise ValueError(
                f"{quadrature!r} has {quadrature.npoints} points, fewer than degree={degree}: "
                "the stage equations are singular or ill-posed; use at least degree points "
                f"(gauss_lobatto({degree + 1}) or gauss_legendre({degree}) give order {2 * degree})"
            )
        if quadrature.order < 2 * degree:
            warnings.warn(
                f"{quadrature!r} has order {quadrature.order} < 2*degree = {2 * degree}: "
                f"the method has order {quadrature.order}, not {2 * degree}",
                OrderReductionWarning,
                stacklevel=2,
            )
        if nodes == "equidistant" and degree > _EQUIDISTANT_MAX_DEGREE:
            warnings.warn(
                f"equidistant control nodes at degree {degree} > {_EQUIDISTANT_MAX_DEGREE} make "
                "the stage Jacobian ill-conditioned (growth about 3.6x per degree); "
                "use nodes='lobatto'",
                ConditioningWarning,
                stacklevel=2,
            )
        self.degree = degree
        self.quadrature = quadrature
        self.nodes = nodes

    @property
    def order(self) -> int:
        """Predicted global order of accuracy, ``min(2 * degree, quadrature.order)``."""
        return min(2 * self.degree, self.quadrature.order)

    @property
    def collocated(self) -> bool:
        """Control nodes coincide with the quadrature nodes (then ``Phi`` is the identity)."""
        q = self.quadrature
        return (
            self.nodes == "lobatto" and q.family == "gauss_lobatto" and q.npoints == self.degree + 1
        )

    def __repr__(self) -> str:
        return (
            f"Galerkin(degree={self.degree}, quadrature={self.quadrature!r}, nodes={self.nodes!r})"
        )

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Galerkin):
            return NotImplemented
        return (self.degree, self.quadrature, self.nodes) == (
            other.degree,
            other.quadrature,
            other.nodes,
        )

    def __hash__(self) -> int:
        return hash((self.degree, self.quadrature, self.nodes))

    def exact_tables(self, dps: int) -> ExactTables:
        """The tables of :class:`MethodTables` as mpmath numbers at ``dps`` digits."""
        s = self.degree
        if self.nodes == "lobatto":
            d = lobatto_control_nodes_mp(s, dps)
        else:
            d = equidistant_control_nodes_mp(s, dps)
        q = self.quadrature
        rule_mp = gauss_lobatto_mp if q.family == "gauss_lobatto" else gauss_legendre_mp
        c, b = rule_mp(q.npoints, dps)
        Phi, D = lagrange_tables_mp(d, c, dps)
        with mpmath.workdps(dps):
            shifted = [1 + x for x in d]
        E, _ = lagrange_tables_mp(d, shifted, dps)
        return ExactTables(b=b, c=c, d=d, Phi=Phi, D=D, extrapolation=E)

    @property
    def tables(self) -> MethodTables:
        """The method's tables, computed at 40 digits and rounded once.

        Shared by equal methods (``Galerkin(4)`` written twice computes them
        once: 2.5 ms of mpmath); the arrays must not be written to.
        """
        return _rounded_tables(self)


@lru_cache(maxsize=64)
def _rounded_tables(method: Galerkin) -> MethodTables:
    exact = method.exact_tables(_TABLE_DIGITS)

    def rounded(x: list) -> NDArray[np.float64]:
        return np.array(x, dtype=float)

    return MethodTables(
        b=rounded(exact.b),
        c=rounded(exact.c),
        d=rounded(exact.d),
        Phi=rounded(exact.Phi),
        D=rounded(exact.D),
        extrapolation=rounded(exact.extrapolation),
    )
