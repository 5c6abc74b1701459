r"""Holonomic constraints :math:`g(t, q) = 0`: consistent initial data and projections.

With :math:`m` constraints :math:`g : \mathbb R \times \mathbb R^n \to \mathbb R^m`
and :math:`\mathcal G = \partial g/\partial q` (shape :math:`m \times n`), the
constrained Galerkin integrator (collocated Lobatto nodes, :math:`\Phi = I`)
augments the discrete Lagrangian by :math:`-h\sum_\nu b_\nu \lambda^\nu\cdot g(t_\nu, q^\nu)`
and solves, per step, for :math:`q^1..q^s` and :math:`\lambda^0..\lambda^{s-1}`:

.. math::

    p_k + G^0 - h b_0 \mathcal G(q^0)^T\lambda^0 = 0,\qquad
    G^\nu - h b_\nu \mathcal G(q^\nu)^T\lambda^\nu = 0\ (0<\nu<s),\qquad
    g(t_\nu, q^\nu) = 0\ (1\le\nu\le s).

The momentum is then projected onto the hidden constraint (RATTLE-like):
:math:`p_{k+1} = G^s - \mathcal G(q_{k+1})^T\mu` with :math:`\mu` such that
:math:`\mathcal G\,v + \partial_t g = 0` for :math:`v = (\mathbb FL)^{-1}(q_{k+1}, p_{k+1})`,
i.e. the saddle-point system

.. math::

    L_v(t, q, v) + \mathcal G^T\mu = G^s,\qquad \mathcal G v + g_t = 0,

solved by Newton with the matrix :math:`\begin{pmatrix} L_{vv} & \mathcal G^T \\
\mathcal G & 0\end{pmatrix}` (one step when :math:`L` is quadratic in :math:`v`).

Initial data must lie on the constraint manifold and satisfy the hidden
constraint; :func:`consistent_initial_state` checks this and, on request,
projects them there.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from .symbolic import ConstraintPieces, constraint_pieces
from .system import LagrangianSystem

__all__ = [
    "INITIAL_TOLERANCE",
    "ConstraintPieces",
    "consistent_initial_state",
    "constraint_pieces",
    "project_momentum",
]

#: largest violation of the constraint and of the hidden constraint by the initial
#: data that is accepted without ``project=True`` (relative to the size of q and v)
INITIAL_TOLERANCE = 1e-10
# smallest singular value of the constraint Jacobian, relative to the largest, that
# still counts as full rank (below it the constraints are redundant at that point)
_RANK_TOLERANCE = 1e-10
_PROJECTION_MAXITER = 50


def _full_rank(jacobian: NDArray) -> bool:
    s = np.linalg.svd(jacobian, compute_uv=False)
    return bool(s.size and s[-1] > _RANK_TOLERANCE * max(s[0], 1.0))


def _check_rank(system: LagrangianSystem, t: float, q: NDArray, prm: NDArray) -> NDArray:
    jac = system.constraint_jacobian(q, t, prm)
    if not np.all(np.isfinite(jac)):
        raise ValueError(f"the constraint Jacobian is not finite at q = {q}")
    if not _full_rank(jac):
        rank = np.linalg.matrix_rank(jac, tol=_RANK_TOLERANCE * max(1.0, np.abs(jac).max()))
        raise ValueError(
            f"the {system.m} constraints are redundant at q = {q}: their Jacobian has rank "
            f"{rank} < {system.m} (remove dependent constraints)"
        )
    return jac


def _project_position(system: LagrangianSystem, t: float, q: NDArray, prm: NDArray) -> NDArray:
    r"""A nearby point of :math:`g(t, \cdot) = 0` by Gauss–Newton with minimum-norm
    corrections, :math:`q \leftarrow q - \mathcal G^T(\mathcal G\mathcal G^T)^{-1} g(q)`
    (the nearest point up to the curvature of the manifold)."""
    scale = 1.0 + np.abs(q).max()
    for _ in range(_PROJECTION_MAXITER):
        g = system.constraint_values(q, t, prm)
        jac = _check_rank(system, t, q, prm)
        dq = jac.T @ np.linalg.solve(jac @ jac.T, g)
        q = q - dq
        if not np.all(np.isfinite(q)):
            break
        if np.abs(dq).max() <= 1e-15 * scale:
            break
    g = system.constraint_values(q, t, prm)
    if not (np.all(np.isfinite(q)) and np.abs(g).max() <= 1e-13 * scale):
        raise ValueError(
            "project=True: no configuration near q0 satisfies all constraints "
            f"(|g| = {np.abs(g).max():.3g} after {_PROJECTION_MAXITER} Gauss-Newton steps); "
            "the constraints may be inconsistent"
        )
    return q


def project_momentum(
    system: LagrangianSystem, t: float, q: NDArray, p: NDArray, v: NDArray, prm: NDArray
) -> tuple[NDArray, NDArray]:
    r"""Project ``p`` onto the hidden constraint at ``q`` (see the module notes).

    Returns :math:`(p - \mathcal G^T\mu, v)` with :math:`v` the velocity of the
    projected momentum; ``v`` on entry is the Newton starting guess.

    Raises
    ------
    ValueError
        If the saddle-point system is singular (:math:`L_{vv}` or the
        constraint Jacobian degenerate at ``q``) or Newton does not converge.
    """
    n, m = system.n, system.m
    jac = system.constraint_jacobian(q, t, prm)
    rate = system.constraint_rate(q, t, prm)
    mu = np.zeros(m)
    for _ in range(_PROJECTION_MAXITER):
        lv = system.evaluate("Lv", t, q, v, prm)
        lvv = system.evaluate("Lvv", t, q, v, prm).reshape(n, n)
        r = np.concatenate([lv + jac.T @ mu - p, jac @ v + rate])
        a = np.block([[lvv, jac.T], [jac, np.zeros((m, m))]])
        try:
            dx = np.linalg.solve(a, -r)
        except np.linalg.LinAlgError as exc:
            raise ValueError(
                f"hidden-constraint projection: singular saddle-point matrix at q = {q} "
                "(degenerate L_vv or constraint Jacobian)"
            ) from exc
        v, mu = v + dx[:n], mu + dx[n:]
        if not np.all(np.isfinite(dx)):
            break
        if np.abs(dx).max() <= 1e-15 * (1.0 + np.abs(v).max() + np.abs(mu).max()):
            return p - jac.T @ mu, v
    raise ValueError(f"hidden-constraint projection did not converge at q = {q}")


def consistent_initial_state(
    system: LagrangianSystem,
    t0: float,
    q0: NDArray,
    p0: NDArray,
    v0: NDArray,
    prm: NDArray,
    project: bool,
) -> tuple[NDArray, NDArray, NDArray]:
    r"""Check, or with ``project`` establish, consistent initial data.

    Consistent means :math:`g(t_0, q_0) = 0` and :math:`\mathcal G v_0 + g_t = 0`.

    Returns ``(q0, p0, v0)``, projected when ``project`` is true.

    Raises
    ------
    ValueError
        If the constraints are redundant at ``q0`` (rank-deficient Jacobian),
        if ``q0`` or ``v0`` violates them by more than
        :data:`INITIAL_TOLERANCE` and ``project`` is false, or if no nearby
        consistent configuration exists.
    """
    if project:
        q0 = _project_position(system, t0, q0, prm)
        v_guess = system.inverse_legendre(q0, p0, t0, dict(zip(system.params, prm, strict=True)))
        p0, v0 = project_momentum(system, t0, q0, p0, v_guess, prm)
        return q0, p0, v0
    jac = _check_rank(system, t0, q0, prm)
    g = system.constraint_values(q0, t0, prm)
    scale = 1.0 + np.abs(q0).max()
    if np.abs(g).max() > INITIAL_TOLERANCE * scale:
        raise ValueError(
            f"q0 is off the constraint manifold: max|g(q0)| = {np.abs(g).max():.3g} "
            f"(tolerance {INITIAL_TOLERANCE:g}); pass project=True to project it"
        )
    hidden = jac @ v0 + system.constraint_rate(q0, t0, prm)
    if np.abs(hidden).max() > INITIAL_TOLERANCE * (1.0 + np.abs(v0).max()) * scale:
        raise ValueError(
            "the initial velocity violates the hidden constraint dg/dt = G(q0) v0 + g_t = 0: "
            f"max residual {np.abs(hidden).max():.3g}; pass project=True to project the momentum"
        )
    return q0, p0, v0
