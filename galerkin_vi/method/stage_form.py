r"""Stage form of the Galerkin method for separable Lagrangians.

For :math:`L = \tfrac12 v^TMv + a(t)\cdot v + U(t, q)` with a constant,
regular :math:`M` (and forces :math:`f(t, q)` that do not depend on
:math:`v`), the velocity enters the stage equations linearly, and they can be
solved for the control points. Write :math:`F_i = (L_q + f)(t_k + c_i h, Q_i)`
and :math:`a_i = a(t_k + c_i h)` at the quadrature points, :math:`C^\mu =
q^\mu - q_k` (:math:`\mu = 1..s`) and

.. math::

    \tilde S_{\nu\mu} = \sum_i b_i D_{i\nu} D_{i\mu},
    \qquad \nu = 0..s-1,\ \mu = 1..s,\qquad T = \tilde S^{-1}.

Then :math:`G^\nu + \delta_{\nu0}p_k = 0` (:math:`\nu < s`) reads

.. math::

    M C^\mu = h\,\hat c_\mu\, p_k + h \sum_i \hat Y_{\mu i}\, a_i
              + h^2 \sum_i \hat W_{\mu i}\, F_i,

    \hat c = -T e_0,\quad
    \hat Y = -T D_{:,0:s}^T \operatorname{diag}(b),\quad
    \hat W = -T \Phi_{:,0:s}^T \operatorname{diag}(b),

and the stage increments :math:`Z_i = Q_i - q_k = \sum_\mu \Phi_{i\mu} C^\mu`
satisfy the same relation with the tables multiplied by :math:`\Phi_{:,1:s}`.
Only the points whose force enters some :math:`C^\mu` and whose position is
not :math:`q_k` itself are unknowns of the Newton iteration (the implicit
points). For Gauss quadrature these are all its points (with
``gauss_legendre(s)`` the tables are :math:`c` and :math:`A^2` of
:math:`s`-stage collocation); for collocated Lobatto quadrature they are the
:math:`s - 1` interior nodes (the first node is
:math:`q_k`, and the last one, :math:`q_{k+1}`, is explicit once they are
known: the Lobatto IIIA–IIIB pair). Summing all :math:`G^\nu` (partition of
unity, :math:`\sum_\nu \ell_\nu = 1`) gives the new momentum in increment form,

.. math::

    p_{k+1} = G^s = p_k + h \sum_i b_i F_i,

which the loop adds with compensated summation.

All tables are computed at 40 digits from the exact method tables and rounded once.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import mpmath
import numpy as np
from numpy.typing import NDArray

from .galerkin import Galerkin

__all__ = ["TWO_STEP_POINTS", "SeparableTables", "has_stage_form", "separable_tables"]

_DIGITS = 40

#: the most quadrature points of a method whose steps start from forces extrapolated
#: over two steps (Gauss(1)-Gauss(3), Lobatto(3)). Measured on the benchmark problems:
#: fewer sweeps at small and benchmark steps, at small steps often one instead of two,
#: for u r n more multiply-adds per step; a few more sweeps on a stiff chain at coarse
#: steps. With more points the one-step start already needs about one sweep at small
#: steps, and the longer sums and larger weights cost more than they save
#: (docs/design-notes.md, "The first iterate from two steps")
TWO_STEP_POINTS = 3


@dataclass(frozen=True)
class SeparableTables:
    r"""Tables of the stage form (module docstring), rounded once from 40 digits.

    Attributes
    ----------
    implicit : ndarray of int, shape (u,)
        Quadrature points whose stage increments are Newton unknowns.
    known : ndarray of int
        Points at :math:`q_k` itself (:math:`\Phi_{i,1:s} = 0`).
    rest : ndarray of int
        The remaining points: explicit once the control points are known.
    stage_p, stage_a, stage_force : ndarray, shapes (u,), (u, r), (u, r)
        :math:`\Phi\hat c`, :math:`\Phi\hat Y`, :math:`\Phi\hat W` at the implicit points.
    control_p, control_a, control_force : ndarray, shapes (s,), (s, r), (s, r)
        :math:`\hat c`, :math:`\hat Y`, :math:`\hat W` (rows :math:`\mu = 1..s`).
    Phi1 : ndarray, shape (r, s)
        :math:`\Phi_{i\mu}`, :math:`\mu = 1..s`.
    force_extrapolation : ndarray, shape (u, r) or (u, 3 r)
        The forces of earlier steps extrapolated to the implicit points of the
        next step, whose first iterate they give,
        :math:`Z_i = M^{-1}(\text{offset}_i + h^2\sum_j \hat W_{ij} \tilde F_j)`.
        Columns :math:`0..r-1`: :math:`\ell_j(1 + c_i)`, the Lagrange basis on
        the last step's nodes :math:`c_1..c_r`,
        :math:`\tilde F_i = \sum_j \ell_j(1 + c_i) F_j` (error
        :math:`O(h^r)`). For methods of at most :data:`TWO_STEP_POINTS` points,
        columns :math:`r..3r-1` too: the Lagrange basis on the nodes of the last
        two steps, :math:`c_j - 1` (columns :math:`r..2r-1`, the step before the
        last) and :math:`c_j` (columns :math:`2r..3r-1`, the last), at
        :math:`1 + c_i` (error :math:`O(h^{2r})`, :math:`O(h^{2r-1})` with a
        shared node), which every step after the second starts from when it starts
        with the fixed point (a step after a hand-over to Newton starts from the
        one-step columns). A node of the older step that is also one of the
        last step (Lobatto's end, :math:`c_r - 1 = c_1 = 0`) is left out, its
        column zero. The first iterate's error is :math:`h^2` times that of the
        extrapolated forces, so with small steps the first sweep often leaves
        the stage positions bit-identical (docs/design-notes.md, "The first iterate
        from two steps"); extrapolating the position polynomial instead is off by
        :math:`O(h^{s+1})`: one sweep more per step.
    reuse_endpoint : bool
        The first point is :math:`q_k` and the last is :math:`q_{k+1}`
        (Lobatto quadrature, collocated ends), so the force at the end of one
        step is the force at the start of the next (autonomous systems).
    """

    implicit: NDArray[np.int64]
    known: NDArray[np.int64]
    rest: NDArray[np.int64]
    stage_p: NDArray[np.float64]
    stage_a: NDArray[np.float64]
    stage_force: NDArray[np.float64]
    control_p: NDArray[np.float64]
    control_a: NDArray[np.float64]
    control_force: NDArray[np.float64]
    Phi1: NDArray[np.float64]
    force_extrapolation: NDArray[np.float64]
    reuse_endpoint: bool

    @property
    def loop_arguments(self) -> tuple:
        """The tables in the order :func:`galerkin_vi.loops.stage_form_loop` takes them."""
        return (
            self.implicit,
            self.known,
            self.rest,
            self.stage_p,
            self.stage_a,
            self.stage_force,
            self.control_p,
            self.control_a,
            self.control_force,
            self.Phi1,
            self.force_extrapolation,
            self.reuse_endpoint,
        )


def has_stage_form(system) -> bool:
    r"""Whether ``system`` gets the compiled stage-form loop.

    Separable (constant :math:`L_{vv}`, :math:`L_{qv} \equiv 0`), forces free
    of :math:`v`, no constraints, and not quadratic (a quadratic Lagrangian
    has the cheaper one-solve loop).
    """
    structure = system.structure
    return bool(
        structure.separable and structure.zero_fv and not structure.quadratic and system.m == 0
    )


def lagrange_values_mp(nodes, x) -> list:
    """The Lagrange basis on ``nodes`` at ``x`` (product form; one node: the constant 1)."""
    out = []
    for j, xj in enumerate(nodes):
        value = mpmath.mpf(1)
        for m, xm in enumerate(nodes):
            if m != j:
                value *= (x - xm) / (xj - xm)
        out.append(value)
    return out


def two_step_extrapolation_mp(c, x) -> list:
    """The Lagrange basis on the nodes of two steps, ``c - 1`` and ``c``, at ``x``: ``2 r``
    weights, the older step's first. An older node equal to a newer one (a Lobatto end) is
    left out of the basis and gets the weight 0."""
    tiny = mpmath.mpf(10) ** (-_DIGITS + 5)
    older = [cj - 1 for cj in c]
    kept = [j for j, node in enumerate(older) if all(abs(node - cm) > tiny for cm in c)]
    values = lagrange_values_mp([older[j] for j in kept] + list(c), x)
    weights = [mpmath.mpf(0)] * len(c)
    for place, j in enumerate(kept):
        weights[j] = values[place]
    return weights + values[len(kept) :]


def _matrix(rows) -> mpmath.matrix:
    return mpmath.matrix([list(r) for r in rows])


def separable_tables(method: Galerkin) -> SeparableTables:
    """The stage-form tables of ``method`` (computed once per method value)."""
    return _tables(method)


@lru_cache(maxsize=64)
def _tables(method: Galerkin) -> SeparableTables:
    # per method value, shared by equal methods like Galerkin.tables (plain arrays)
    return _compute(method)


def _compute(method: Galerkin) -> SeparableTables:
    s = method.degree
    exact = method.exact_tables(_DIGITS)
    with mpmath.workdps(_DIGITS + 10):
        b, c = exact.b, exact.c
        r = len(b)
        Phi = _matrix(exact.Phi)  # r x (s + 1)
        D = _matrix(exact.D)
        S = mpmath.matrix(s, s)
        for nu in range(s):
            for mu in range(s):
                S[nu, mu] = mpmath.fsum(b[i] * D[i, nu] * D[i, mu + 1] for i in range(r))
        T = S**-1
        control_p = mpmath.matrix(s, 1)
        control_a = mpmath.matrix(s, r)
        control_force = mpmath.matrix(s, r)
        for mu in range(s):
            control_p[mu] = -T[mu, 0]
            for i in range(r):
                control_a[mu, i] = -mpmath.fsum(T[mu, nu] * D[i, nu] * b[i] for nu in range(s))
                control_force[mu, i] = -mpmath.fsum(
                    T[mu, nu] * Phi[i, nu] * b[i] for nu in range(s)
                )
        Phi1 = mpmath.matrix(r, s)
        for i in range(r):
            for mu in range(s):
                Phi1[i, mu] = Phi[i, mu + 1]
        stage_p = Phi1 * control_p
        stage_a = Phi1 * control_a
        stage_force = Phi1 * control_force
        tiny = mpmath.mpf(10) ** (-_DIGITS + 5)
        moves = [any(abs(Phi1[i, mu]) > tiny for mu in range(s)) for i in range(r)]
        drives = [any(abs(control_force[mu, i]) > tiny for mu in range(s)) for i in range(r)]
        implicit = [i for i in range(r) if moves[i] and drives[i]]
        known = [i for i in range(r) if not moves[i]]
        rest = [i for i in range(r) if moves[i] and not drives[i]]
        two_steps = r <= TWO_STEP_POINTS
        X = [
            lagrange_values_mp(c, 1 + c[i])
            + (two_step_extrapolation_mp(c, 1 + c[i]) if two_steps else [])
            for i in implicit
        ]
        last_is_end = r - 1 in rest and all(
            abs(Phi1[r - 1, mu] - (mu == s - 1)) <= tiny for mu in range(s)
        )
        reuse_endpoint = bool(c[0] == 0 and 0 in known and last_is_end)

    def rounded(m, rows, cols=None) -> NDArray[np.float64]:
        if cols is None:
            return np.array([float(m[i]) for i in rows], dtype=float)
        return np.array([[float(m[i, j]) for j in cols] for i in rows], dtype=float).reshape(
            len(rows), len(cols)
        )

    return SeparableTables(
        implicit=np.array(implicit, dtype=np.int64),
        known=np.array(known, dtype=np.int64),
        rest=np.array(rest, dtype=np.int64),
        stage_p=rounded(stage_p, implicit),
        stage_a=rounded(stage_a, implicit, range(r)),
        stage_force=rounded(stage_force, implicit, range(r)),
        control_p=rounded(control_p, range(s)),
        control_a=rounded(control_a, range(s), range(r)),
        control_force=rounded(control_force, range(s), range(r)),
        Phi1=rounded(Phi1, range(r), range(s)),
        force_extrapolation=np.array(X, dtype=float).reshape(
            len(implicit), 3 * r if two_steps else r
        ),
        reuse_endpoint=reuse_endpoint,
    )
