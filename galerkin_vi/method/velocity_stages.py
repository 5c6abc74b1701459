r"""Velocity-stage form of the Galerkin method for a mass matrix that varies with q.

For :math:`L = \tfrac12 v^TM(t, q)v + a(t, q)\cdot v - U(t, q)` the stage form of
:mod:`galerkin_vi.method.stage_form` does not apply (it needs a constant :math:`M`), but
the Galerkin method with Gauss quadrature of :math:`s` points and degree :math:`s`
is :math:`s`-stage Gauss collocation [1]_, whose stage equations a fixed-point
iteration solves without any Jacobian. Write
:math:`F_j = (L_q + f)(t_k + c_j h, Q_j, V_j)`; then

.. math::

    Q_i = q_k + h\sum_j a_{ij} V_j, \qquad
    P_i = p_k + h\sum_j \bar a_{ij} F_j, \qquad
    L_v(t_k + c_i h, Q_i, V_i) = P_i,

    q_{k+1} = q_k + h\sum_j b_j V_j, \qquad p_{k+1} = p_k + h\sum_j b_j F_j,

with :math:`a_{ij} = \int_0^{c_i}\ell_j`, :math:`b_j = \int_0^1 \ell_j`
(:math:`\ell_j` the Lagrange basis on the nodes) and the symplectic partner
:math:`\bar a_{ij} = b_j(1 - a_{ji}/b_i)`, equal to :math:`a_{ij}` for Gauss (the
loop takes both tables). Since :math:`L_v = M(Q)V + a(Q)` is linear in
:math:`V`, one sweep

.. math::

    V_i \leftarrow V_i + M(Q_i)^{-1}\big(P_i - L_v(Q_i, V_i)\big)

solves the last equation exactly for the current :math:`Q_i, P_i`: the
iteration is the fixed-point iteration of the Gauss method on Hamilton's
equations, :math:`\dot q = H_p`, :math:`\dot p = -H_q`, without forming :math:`H`.
It contracts like :math:`h` times the Lipschitz constant of the vector field,
costs per stage one call of the gradient with :math:`L_{qv} + f_v` and
:math:`L_{vv}` and an :math:`n\times n` solve, and no Hessian, no assembly and
no :math:`(sn)^2` factorisation.

With :math:`s + 1` Lobatto points the Galerkin method is not the Lobatto IIIA–IIIB
pair of :math:`s + 1` stages for a mass matrix that varies (its velocity is a
polynomial of degree :math:`s - 1`, the pair's stage velocities carry one more degree
of freedom; on the double pendulum the maps differ by 5e-8 after one step of
h = 0.02, where they agree to round-off for a constant mass): Lobatto methods keep the
Newton loop there.

All tables are computed at 40 digits from the exact nodes and rounded once.

References
----------
.. [1] J. E. Marsden and M. West, "Discrete mechanics and variational
   integrators", Acta Numerica 10 (2001), section 2.6.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import mpmath
import numpy as np
from numpy.typing import NDArray

from .galerkin import Galerkin
from .stage_form import lagrange_values_mp

__all__ = [
    "MIN_FIXED_POINT_DEGREE",
    "VaryingMassTables",
    "has_velocity_stages",
    "varying_mass_tables",
]

_DIGITS = 40


@dataclass(frozen=True)
class VaryingMassTables:
    r"""Tables of the velocity-stage form (module docstring), rounded once from 40 digits.

    Attributes
    ----------
    A, Abar : ndarray, shape (r, r)
        :math:`a_{ij}` (positions) and :math:`\bar a_{ij}` (momenta).
    b, c : ndarray, shape (r,)
        Weights and nodes.
    X : ndarray, shape (r, r)
        :math:`\ell_j(1 + c_i)`: a step's stage values extrapolated to the next
        step's nodes (its first iterate).
    """

    A: NDArray[np.float64]
    Abar: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    X: NDArray[np.float64]

    @property
    def loop_arguments(self) -> tuple:
        """The tables in the order :func:`galerkin_vi.loops.varying_mass_loop` takes them."""
        return (self.b, self.c, self.A, self.Abar, self.X)


def has_velocity_stages(method: Galerkin) -> bool:
    """Whether ``method`` is a collocation method in velocity-stage form for any mass matrix.

    Gauss quadrature with as many points as the degree (Gauss collocation).
    """
    family, r, s = method.quadrature.family, method.quadrature.npoints, method.degree
    return family == "gauss_legendre" and r == s


#: the varying-mass loop is chosen from this degree on: below, Newton's Jacobian is
#: small (s n = 4 unknowns on the double pendulum) and simplified Newton takes less
#: time at every step size (docs/design-notes.md, "The varying-mass loop")
MIN_FIXED_POINT_DEGREE = 3


def varying_mass_tables(method: Galerkin) -> VaryingMassTables:
    """The velocity-stage tables of ``method`` (computed once per method value).

    Raises
    ------
    ValueError
        If ``method`` has no velocity-stage form (:func:`has_velocity_stages`).
    """
    if not has_velocity_stages(method):
        raise ValueError(
            f"{method!r} has no velocity-stage form: it needs Gauss quadrature with as "
            "many points as the degree"
        )
    return _tables(method)


@lru_cache(maxsize=64)
def _tables(method: Galerkin) -> VaryingMassTables:
    # per method value, shared by equal methods like Galerkin.tables (plain arrays)
    return _compute(method)


def _integrated_basis(c, x) -> list:
    r""":math:`\int_0^x \ell_j` for every j, by Gauss–Legendre quadrature exact for the degree."""
    r = len(c)
    # the integrand has degree r - 1: ceil(r / 2) + 1 Gauss points integrate it exactly
    m = r // 2 + 1
    xs, ws = _gauss_mp(m)
    out = []
    for j in range(r):
        total = mpmath.mpf(0)
        for xk, wk in zip(xs, ws, strict=True):
            total += wk * lagrange_values_mp(c, x * xk)[j]
        out.append(x * total)
    return out


def _gauss_mp(m: int) -> tuple[list, list]:
    from .quadrature import gauss_legendre_mp

    return gauss_legendre_mp(m, _DIGITS + 10)


def _compute(method: Galerkin) -> VaryingMassTables:
    exact = method.exact_tables(_DIGITS)
    with mpmath.workdps(_DIGITS + 10):
        c = [mpmath.mpf(x) for x in exact.c]
        r = len(c)
        A = [_integrated_basis(c, ci) for ci in c]
        b = _integrated_basis(c, mpmath.mpf(1))
        Abar = [[b[j] * (1 - A[j][i] / b[i]) for j in range(r)] for i in range(r)]
        X = [lagrange_values_mp(c, 1 + ci) for ci in c]

    def rounded(rows) -> NDArray[np.float64]:
        return np.array([[float(x) for x in row] for row in rows], dtype=float)

    return VaryingMassTables(
        A=rounded(A),
        Abar=rounded(Abar),
        b=np.array([float(x) for x in b]),
        c=np.array([float(x) for x in c]),
        X=rounded(X),
    )
