r"""Persistent contact: one complementarity problem per step, by a primal–dual interior point.

Where impacts accumulate or a contact persists (resting, sliding, sticking),
each step carries contact forces that are constant over the step: a normal
force :math:`\lambda_c \ge 0` and, with friction, a tangential force
:math:`\beta_c` per contact. They enter the Galerkin step as the external
forces of the discrete Lagrange–d'Alembert principle do, at every quadrature
point,

.. math::

    f_i = \sum_c \nabla\varphi_c(Q_i)\,\lambda_c + T_c(Q_i)^{\mathsf T}\beta_c,
    \qquad G^\nu \mathrel{+}= h \sum_i b_i \Phi_{i\nu} f_i,

so that the stage equations :math:`p_k + G^0 = 0`, :math:`G^\nu = 0` and the
update :math:`p_{k+1} = G^s` hold with them, and are complemented by

.. math::

    0 \le \varphi_c(q_{k+1}) \perp \lambda_c \ge 0,

and, with friction (slip velocities :math:`w`, one in a plane, two in space;
their mean :math:`\bar w = \sum_i b_i w(Q_i, V_i)` over the step), by Coulomb's
law as maximum dissipation in the exact friction cone: with :math:`\zeta` the
slip speed,

.. math::

    \mathcal K \ni (\mu\lambda_c, \beta_c) \perp (\zeta_c, \bar w_c) \in \mathcal K,
    \qquad \mathcal K = \{(a, b) : a \ge \|b\|\},

the second-order cone (an interval in the plane): sticking :math:`\bar w = 0`
inside the cone, sliding on its edge against :math:`\bar w`. With slacks
:math:`z` (the gaps, :math:`(\zeta, \bar w)`) and duals :math:`y`
(:math:`\lambda`, :math:`(\mu\lambda, \beta)`), the step solves the stage
equations, the slacks' definitions and :math:`z \circ y = \kappa e` (the Jordan
product of the cones) for :math:`\kappa \to 0` by a primal–dual interior-point
method with Mehrotra's predictor–corrector, the fraction-to-boundary rule and
backtracking (as Dojo does), with the exact Jacobians of the stage equations,
the gaps and the slips. The complementarity rows are linearised in
Nesterov–Todd scaled variables (Vandenberghe 2010), which keeps a sliding
contact's iterates off its cone's boundary, and :math:`\kappa` stays above a
floor, so that the redundant contacts of a face at rest do not jam the
iteration.

"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

from ..interior_point import (
    ACCEPTABLE,
    CENTRING,
    COMPLEMENTARITY,
    DEGENERATE,
    FRACTION_TO_BOUNDARY,
    LINE_SEARCH,
    MAX_ITERATIONS,
    POLISHED,
    RESIDUAL,
    TO_BOUNDARY,
)
from ..model.constraints import project_momentum
from ..reference import numpy as numpy_backend
from .impact import ContactFunctions

__all__ = ["ContactForces", "ContactStep", "ContactStepper", "StepResult"]


@dataclass(frozen=True)
class ContactForces:
    r"""The contact forces of the time-stepping steps of a run (constant over each step).

    Attributes
    ----------
    t : ndarray, shape (k,)
        The steps' start times.
    normal : ndarray, shape (k, contacts)
        :math:`\lambda_c`.
    tangential : ndarray, shape (k, contacts, d)
        :math:`\beta_c` (d = 2 when a contact has two slip velocities; zeros
        without friction).
    iterations : ndarray, shape (k,)
        Interior-point iterations of each step.
    complementarity : ndarray, shape (k,)
        The largest :math:`z_j y_j` each step ended with.
    """

    t: NDArray[np.float64]
    normal: NDArray[np.float64]
    tangential: NDArray[np.float64]
    iterations: NDArray[np.int64]
    complementarity: NDArray[np.float64]


@dataclass(frozen=True)
class StepResult:
    """One step: the new state, the contact forces, the solver's statistics."""

    q: NDArray[np.float64]
    p: NDArray[np.float64]
    C: NDArray[np.float64]
    normal: NDArray[np.float64]
    tangential: NDArray[np.float64]
    duals: NDArray[np.float64]
    sticking: NDArray[np.bool_]
    iterations: int
    complementarity: float
    converged: bool


@dataclass(frozen=True)
class ContactStep:
    """Per contact: where its unknowns sit in the duals y and slacks z of a step.

    ``normal`` indexes :math:`\\lambda` (y) and the gap (z); ``cone`` is the slice
    of the friction cone's block, :math:`(\\mu\\lambda, \\beta)` in y and
    :math:`(\\zeta, \\bar w)` in z, or None without friction.
    """

    normal: int
    cone: slice | None


#: the point functions the compiled step calls
COMPILED_POINTS = (
    "point_hessian",
    "point_contact",
    "point_slip",
    "point_constraint",
    "point_constraint_jacobian",
    "point_constraint_rate",
    "point_constraint_hessian",
)


class ContactStepper:
    """The interior-point step of a system with contacts and a Galerkin method.

    With ``addresses`` (the system's compiled point functions :data:`COMPILED_POINTS`
    in the slots of :mod:`galerkin_vi.loops.point`, dense storage) a step runs
    compiled (:func:`galerkin_vi.loops.contact_step.contact_step`, the same
    iteration with the Newton systems reduced blockwise); without, in NumPy.
    """

    def __init__(self, functions: ContactFunctions, tables, prm, addresses=None) -> None:
        system = functions.system
        self.system, self.tables, self.prm, self.functions = system, tables, prm, functions
        self.addresses = None if addresses is None else np.asarray(addresses, dtype=np.int64)
        n = system.n
        self.layout: list[ContactStep] = []
        size = 0
        for contact in system.contacts:
            if contact.friction > 0.0:
                k = len(contact.slip)
                self.layout.append(ContactStep(size, slice(size + 1, size + 2 + k)))
                size += 2 + k
            else:
                self.layout.append(ContactStep(size, None))
                size += 1
        self._normal = np.array([layout.normal for layout in self.layout], dtype=np.int64)
        # the y (and z) index of every slip row, and (first index, normal index, mu) per cone
        self._slip_rows = np.array(
            [
                i
                for layout in self.layout
                if layout.cone
                for i in range(layout.cone.start + 1, layout.cone.stop)
            ],
            dtype=np.intp,
        )
        self._cones = [
            (layout.cone.start, layout.normal, contact.friction)
            for layout, contact in zip(self.layout, system.contacts, strict=True)
            if layout.cone is not None
        ]
        self.size = size
        self.n = n
        # the compiled step's layout: cone start (or -1) and length per contact, the
        # first row of its slips among every contact's declared slips, the frictions
        self._cone_start = np.array(
            [layout.cone.start if layout.cone else -1 for layout in self.layout], dtype=np.int64
        )
        self._cone_length = np.array(
            [layout.cone.stop - layout.cone.start if layout.cone else 0 for layout in self.layout],
            dtype=np.int64,
        )
        declared = [len(contact.slip or ()) for contact in system.contacts]
        self._slip_start = np.concatenate([[0], np.cumsum(declared)[:-1]]).astype(np.int64)
        self._slip_rows_declared = int(sum(declared))
        self._friction = np.array([contact.friction for contact in system.contacts], dtype=float)
        self.tangential_size = max(
            (len(c.slip) for c in system.contacts if c.friction > 0.0), default=1
        )

    # ----------------------------------------------------------- evaluation
    def _each(self, f, t, Q, V) -> NDArray[np.float64]:
        """``f`` (all contacts at once) at every quadrature point, stacked on axis 0."""
        at, prm = self.functions.at, self.prm
        return np.array([at(f, ti, Qi, Vi, prm) for ti, Qi, Vi in zip(t, Q, V, strict=True)])

    def _equations(self, t0, h, qk, pk, x, y, z):
        """The residuals and Jacobians of a step: the stage equations with the contact
        forces F(x, y), the slacks' definitions E(x, y, z); and p_{k+1}, C."""
        system, tb, n = self.system, self.tables, self.n
        s = tb.d.size - 1
        m = self.size
        C = np.vstack([np.zeros((1, n)), x[: s * n].reshape(s, n)])
        G, H = numpy_backend.discrete_hessian(system, tb, t0, h, qk, C, self.prm)
        t, Q, V = numpy_backend.quadrature_points(tb, t0, h, qk, C)
        b, Phi, D = tb.b, tb.Phi, tb.D
        F = G[:s].copy()
        F[0] += pk
        Fx = H[:s, :, 1:, :].reshape(s * n, s * n).copy()
        Fy = np.zeros((s * n, m))
        E = z.copy()
        Ex, Ey, Ez = np.zeros((m, s * n)), np.zeros((m, m)), np.eye(m)
        end, t_end = qk + C[s], t0 + h
        forces_end = np.zeros(n)
        weights = h * b[:, None] * Phi  # (r, s+1): a force at the points, into the nodes
        fn = self.functions
        all_grads = self._each(fn.gradients, t, Q, V)  # (r, contacts, n)
        all_hess = self._each(fn.hessians, t, Q, V)  # (r, contacts, n, n)
        zeros_v = np.zeros(n)
        gaps_end = fn.at(fn.gaps, t_end, end, zeros_v, self.prm)
        grads_end = fn.at(fn.gradients, t_end, end, zeros_v, self.prm)
        sn = s * n

        def into_nodes(values):  # (r, k, n) at the points -> (k, s+1, n) weighted node forces
            return np.einsum("iv,ika->kva", weights, values)

        def bend(matrices):  # (r, n, n) derivative of the point forces -> (sn, sn)
            full = np.einsum("iv,iu,iab->vaub", weights, Phi, matrices)
            return full[:s, :, 1:, :].reshape(sn, sn)

        # the normal forces lambda_c grad(phi_c) at the points, all contacts at once
        normal = self._normal
        lam = y[normal]
        node_force = into_nodes(all_grads)
        F += np.einsum("j,jva->va", lam, node_force[:, :s])
        forces_end += lam @ node_force[:, s]
        Fy[:, normal] = node_force[:, :s].reshape(len(normal), sn).T
        Fx += bend(np.einsum("j,ijab->iab", lam, all_hess))
        # the gaps at the step's end, q_{k+1} = q_k + C^s
        E[normal] -= gaps_end
        Ex[normal, (s - 1) * n :] = -grads_end
        if fn.slips is not None:
            all_w, all_wq, all_wv, all_wvq = (self._each(f, t, Q, V) for f in fn.slips)
            # the tangential forces beta T^T at the points, every slip row at once
            rows = self._slip_rows
            beta = y[rows]
            tangent = into_nodes(all_wv)
            F += np.einsum("k,kva->va", beta, tangent[:, :s])
            forces_end += beta @ tangent[:, s]
            Fy[:, rows] = tangent[:, :s].reshape(len(rows), sn).T
            Fx += bend(np.einsum("k,ikab->iab", beta, all_wvq))
            # the mean slips over the step and their derivatives in the control points
            dw = (
                np.einsum("i,iu,ika->kua", b, Phi, all_wq)
                + np.einsum("i,iu,ika->kua", b, D, all_wv) / h
            )
            E[rows] -= b @ all_w
            Ex[rows] = -dw[:, 1:].reshape(len(rows), sn)
            # the cones' scalars: y0 = mu lambda (defined by E), z0 = zeta (free)
            for first, i, mu in self._cones:
                E[first] = y[first] - mu * y[i]
                Ez[first, first] = 0.0
                Ey[first, first], Ey[first, i] = 1.0, -mu
        F = F.ravel()
        if system.m:
            F, Fx, Fy, Ex = self._with_constraints(t0, h, qk, C, x[s * n :], F, Fx, Fy, Ex)
        return F, Fx, Fy, E, Ex, Ey, Ez, G[s] + forces_end, C

    def _with_constraints(self, t0, h, qk, C, impulses, F, Fx, Fy, Ex):
        r"""The stage equations with the holonomic constraints' impulses
        :math:`-\mathcal G(q^\nu)^{\mathsf T}\Lambda^\nu` (:math:`\nu < s`) and the
        constraints :math:`g(q^\nu) = 0` (:math:`\nu \ge 1`), as in
        :mod:`galerkin_vi.loops.constrained`."""
        system, n, s, mh = self.system, self.n, C.shape[0] - 1, self.system.m
        sn = s * n
        lam = impulses.reshape(s, mh)
        t_nodes = t0 + self.tables.d * h
        q_nodes = qk + C
        jac = system.constraint_jacobian(q_nodes, t_nodes, self.prm)
        hess = system.constraint_hessians(q_nodes, t_nodes, self.prm)
        F = F - np.einsum("vja,vj->va", jac[:s], lam).ravel()
        size = s * (n + mh)
        J = np.zeros((size, size))
        J[:sn, :sn] = Fx
        for nu in range(s):
            rows = slice(nu * n, (nu + 1) * n)
            if nu >= 1:
                J[rows, (nu - 1) * n : nu * n] -= np.einsum("j,jab->ab", lam[nu], hess[nu])
            J[rows, sn + nu * mh : sn + (nu + 1) * mh] = -jac[nu].T
            J[sn + nu * mh : sn + (nu + 1) * mh, nu * n : (nu + 1) * n] = jac[nu + 1]
        g = system.constraint_values(q_nodes[1:], t_nodes[1:], self.prm).ravel()
        Fy = np.vstack([Fy, np.zeros((s * mh, Fy.shape[1]))])
        Ex = np.hstack([Ex, np.zeros((Ex.shape[0], s * mh))])
        return np.concatenate([F, g]), J, Fy, Ex

    def _projected(self, t: float, q, p) -> NDArray[np.float64]:
        """The momentum projected onto the hidden constraint at the step's end."""
        params = dict(zip(self.system.params, self.prm, strict=True))
        v = self.system.inverse_legendre(q, p, t, params)
        return project_momentum(self.system, t, q, p, v, self.prm)[0]

    def _jordan(self, z, y) -> NDArray[np.float64]:
        """z o y blockwise: products on the gaps, the cones' Jordan product."""
        out = z * y
        for layout in self.layout:
            if layout.cone is not None:
                zc, yc = z[layout.cone], y[layout.cone]
                out[layout.cone] = np.concatenate([[zc @ yc], zc[0] * yc[1:] + yc[0] * zc[1:]])
        return out

    def _arrow(self, v) -> NDArray[np.float64]:
        """The matrix of u -> v o u (diagonal on the gaps, arrow matrices on the cones)."""
        A = np.diag(v)
        for layout in self.layout:
            if layout.cone is not None:
                vc = v[layout.cone]
                block = vc[0] * np.eye(vc.size)
                block[0, 1:] = block[1:, 0] = vc[1:]
                A[layout.cone, layout.cone] = block
        return A

    def _identity(self) -> NDArray[np.float64]:
        """The Jordan identity e: ones on the gaps, (1, 0, ...) on each cone."""
        e = np.ones(self.size)
        for layout in self.layout:
            if layout.cone is not None:
                e[layout.cone.start + 1 : layout.cone.stop] = 0.0
        return e

    def _blocks(self, fixed: NDArray[np.bool_]) -> int:
        """The number of blocks (gaps and cones) in the problem, those kept apart left out."""
        count = 0
        for layout in self.layout:
            count += not fixed[layout.normal]
            count += layout.cone is not None and not fixed[layout.cone.start]
        return int(count)

    def _to_boundary(self, v, dv, tau: float) -> float:
        """Largest alpha <= 1 keeping v + alpha dv inside every orthant and cone, by tau."""
        alpha = 1.0
        for layout in self.layout:
            alpha = min(alpha, _orthant_step(v[layout.normal], dv[layout.normal]))
            if layout.cone is not None:
                alpha = min(alpha, _cone_step(v[layout.cone], dv[layout.cone]))
        return min(1.0, tau * alpha)

    def _interior(self, v, floor: float, margin: float = 0.0) -> NDArray[np.float64]:
        """``v`` moved strictly inside its orthants and cones; a spatial cone's scalar
        at least ``margin`` inside, relative to the size of its vector part (on a
        circular cone's boundary, the first steps of the iteration are cut to nothing)."""
        v = v.copy()
        for layout in self.layout:
            v[layout.normal] = max(v[layout.normal], floor)
            if layout.cone is not None:
                c = v[layout.cone]
                size = np.linalg.norm(c[1:])
                inside = margin if c.size > 2 else 0.0
                c[0] = max(c[0], size * (1.0 + inside) + floor)
                v[layout.cone] = c
        return v

    # ---------------------------------------------------------------- solve
    def _fixed(self, excluded: Sequence[int] = ()) -> NDArray[np.bool_]:
        """The entries of y and z of the contacts kept apart (none: all False)."""
        fixed = np.zeros(self.size, dtype=bool)
        for j in excluded:
            layout = self.layout[j]
            fixed[layout.normal] = True
            if layout.cone is not None:
                fixed[layout.cone] = True
        return fixed

    def _newton_matrix(self, equations, P, Q, z, y, fixed) -> NDArray[np.float64]:
        r"""The Jacobian of (stage equations, slacks' definitions, :math:`u \circ v`) in
        (x, y, z), :math:`u = P z`, :math:`v = Q y` (:meth:`_scaling`): the
        complementarity rows are :math:`u \circ (Q\,dy) + v \circ (P\,dz)`; the rows
        of a contact kept apart say dy = dz = 0 (its y stays 0)."""
        F, Fx, Fy, E, Ex, Ey, Ez = equations[:7]
        nx, m = Fx.shape[0], self.size
        K = np.zeros((nx + 2 * m, nx + 2 * m))
        K[:nx, :nx], K[:nx, nx : nx + m] = Fx, Fy
        K[nx : nx + m, :nx], K[nx : nx + m, nx : nx + m] = Ex, Ey
        K[nx : nx + m, nx + m :] = Ez
        K[nx + m :, nx : nx + m] = self._arrow(P @ z) @ Q
        K[nx + m :, nx + m :] = self._arrow(Q @ y) @ P
        rows = nx + np.flatnonzero(fixed)
        K[rows] = 0.0
        K[rows, rows + m] = 1.0  # dz = 0
        K[rows + m] = 0.0
        K[rows + m, rows] = 1.0  # dy = 0
        return K

    def _scaling(self, z, y, fixed) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        r"""The block-diagonal scalings (P, Q) of the slacks z and duals y.

        Nesterov–Todd where it can be formed: P = W, Q = W^{-1} with
        :math:`W z = W^{-1} y = \lambda` (:func:`_nesterov_todd`); on a gap
        :math:`w = \sqrt{y / z}`. Newton's equation for :math:`\lambda \circ
        \lambda = \kappa e` keeps the iterates well inside the cones where the
        unscaled :math:`z \circ y` jams against a cone's boundary (a sliding
        contact). Where a block is on its boundary to round-off (its scaling
        would overflow) and for a contact kept apart, P = Q = I: the unscaled
        rows :math:`z \circ dy + y \circ dz`.
        """
        m = self.size
        P, Q = np.eye(m), np.eye(m)
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
            for layout in self.layout:
                i = layout.normal
                if not fixed[i]:
                    w = np.sqrt(y[i] / z[i])
                    if 0.0 < w < np.inf and 1.0 / w < np.inf:
                        P[i, i], Q[i, i] = w, 1.0 / w
                if layout.cone is not None and not fixed[layout.cone.start]:
                    block = _nesterov_todd(z[layout.cone], y[layout.cone])
                    if block is not None:
                        P[layout.cone, layout.cone], Q[layout.cone, layout.cone] = block
        return P, Q

    def _block_gaps(self, z, y, fixed) -> NDArray[np.float64]:
        r"""Per block b (gap or cone, those kept apart left out) the duality gap
        :math:`z_b \cdot y_b`, the scalar part of :math:`z_b \circ y_b` (in the cones,
        zero exactly when :math:`z_b \circ y_b = 0`)."""
        gaps = []
        for layout in self.layout:
            i = layout.normal
            if not fixed[i]:
                gaps.append(z[i] * y[i])
            if layout.cone is not None and not fixed[layout.cone.start]:
                gaps.append(z[layout.cone] @ y[layout.cone])
        return np.array(gaps)

    def _measures(self, equations, y, z, fixed, scale: float, tolerance: float):
        r"""(residual of the equations, largest :math:`|z \circ y|` and largest block
        duality gap :math:`z_b \cdot y_b`, both relative to ``tolerance``; the largest
        block duality gap) of an iterate.

        A step is solved when every entry of :math:`z \circ y` is below the
        tolerance; one whose iteration stalls is accepted when the block
        duality gaps are below ACCEPTABLE (on a sliding contact the vector part
        of :math:`z_b \circ y_b`, the misalignment of force and slip, falls only
        as the square root of the gap).
        """
        F, E = equations[0], equations[3]
        residual = max(np.max(np.abs(F)) / scale, np.max(np.abs(E), initial=0.0))
        gaps = self._block_gaps(z, y, fixed)
        jordan = float(np.max(np.abs(self._jordan(z, y)[~fixed]), initial=0.0))
        largest = float(np.max(gaps, initial=0.0))
        return residual, jordan / tolerance, largest / tolerance, largest

    def step(
        self, t0: float, h: float, qk, pk, guess_C, duals, excluded: Sequence[int] = ()
    ) -> StepResult:
        """One step of length h from (q_k, p_k): Mehrotra's predictor–corrector.

        ``excluded``: the contacts kept apart (no force: their y is 0 and their rows
        drop out), as when the first touch of the open contacts is looked for.
        ``duals`` None starts from the cones' centres (the Jordan identity).
        Compiled when the stepper has the point functions' addresses, else NumPy.
        """
        if self.addresses is not None:
            return self.compiled_step(t0, h, qk, pk, guess_C, duals, excluded)
        return self.numpy_step(t0, h, qk, pk, guess_C, duals, excluded)

    def compiled_layout(self) -> tuple:
        """The arguments of the compiled loops from the tables to the restitutions:
        b, c, Phi, D, d, prm, n, s, m, the layout of y and z (:meth:`compiled_step`),
        the frictions, the restitutions and the number of declared slip rows."""
        tb = self.tables
        tables = tuple(
            np.ascontiguousarray(a, dtype=float) for a in (tb.b, tb.c, tb.Phi, tb.D, tb.d)
        )
        restitution = np.array([c.restitution for c in self.system.contacts], dtype=float)
        return (
            *tables, np.ascontiguousarray(self.prm, dtype=float), self.n, tb.d.size - 1,
            self.system.m, self._normal, self._cone_start, self._cone_length,
            self._slip_start, self._friction, restitution, self._slip_rows_declared,
        )  # fmt: skip

    def compiled_step(
        self, t0: float, h: float, qk, pk, guess_C, duals, excluded: Sequence[int] = ()
    ) -> StepResult:
        """:meth:`step` by :func:`galerkin_vi.loops.contact_step.contact_step`."""
        from ..loops.contact_step import contact_step

        tb, n, mh = self.tables, self.n, self.system.m
        s = tb.d.size - 1
        qk = np.ascontiguousarray(qk, dtype=float)
        pk = np.ascontiguousarray(pk, dtype=float)
        x = np.zeros(s * (n + mh))
        x[: s * n] = np.asarray(guess_C, dtype=float)[1:].ravel()
        y = np.zeros(self.size) if duals is None else np.array(duals, dtype=float)
        z = np.zeros(self.size)
        p_end, stats = np.zeros(n), np.zeros(3)
        layout = self.compiled_layout()
        contact_step(
            self.addresses, float(t0), float(h), qk, pk, x, y, z, duals is not None,
            self._apart(excluded), *layout[:-2], layout[-1],
            bool(self.system.structure.quadratic_in_v), p_end, stats,
        )  # fmt: skip
        C = np.vstack([np.zeros((1, n)), x[: s * n].reshape(s, n)])
        # projected onto the hidden constraint in the compiled step already
        return self._result(
            t0, h, qk, p_end, C, y, z, int(stats[0]), stats[1], bool(stats[2]), projected=True
        )

    def _apart(self, excluded: Sequence[int]) -> NDArray[np.bool_]:
        """Per contact: whether it is kept apart (the compiled step's mask)."""
        apart = np.zeros(len(self.layout), dtype=np.bool_)
        apart[list(excluded)] = True
        return apart

    def numpy_step(
        self, t0: float, h: float, qk, pk, guess_C, duals, excluded: Sequence[int] = ()
    ) -> StepResult:
        """:meth:`step` in NumPy, the full Newton system solved by LU."""
        s = self.tables.d.size - 1
        nx, m = s * (self.n + self.system.m), self.size
        fixed = self._fixed(excluded)
        e = self._identity()
        x = np.zeros(nx)
        x[: s * self.n] = np.asarray(guess_C, dtype=float)[1:].ravel()
        start = e if duals is None else np.asarray(duals, dtype=float)
        y = self._interior(start, 1e-6, margin=1.0)
        y[fixed] = 0.0

        def equations(x, y, z):
            eq = list(self._equations(t0, h, qk, pk, x, y, z))
            eq[3][fixed] = 0.0  # E: the fixed slacks stay where they are
            return eq

        if duals is None:  # both at the Jordan identity: the centre of the orthants and cones
            z = y.copy()
        else:  # E(z = 0) = -(the slacks' values); the slip speed zeta is free
            z = self._interior(-equations(x, y, np.zeros(m))[3], 1e-6, margin=1.0)
        z[fixed] = e[fixed]
        e[fixed] = 0.0
        blocks = max(self._blocks(fixed), 1)
        scale = 1.0 + float(np.max(np.abs(pk)))
        # a gap of COMPLEMENTARITY relative to the coordinates' scale
        length = max(1.0, float(np.max(np.abs(qk))))
        eq = equations(x, y, z)
        tolerance = COMPLEMENTARITY * length
        residual, unsolved, loose, complementarity = self._measures(
            eq, y, z, fixed, scale, tolerance
        )
        iterations, converged = 0, False
        while iterations < MAX_ITERATIONS:
            iterations += 1
            if residual <= RESIDUAL and unsolved <= 1.0:
                # solved; once more unless at round-off (a contact's gap and an impact's
                # time to round-off, not to the tolerance: one more Newton step)
                if converged or residual <= POLISHED:
                    break
                converged = True
            if not np.isfinite(residual + unsolved):
                break
            gap = float(z @ y) / blocks
            P, Q = self._scaling(z, y, fixed)
            K = self._newton_matrix(eq, P, Q, z, y, fixed)
            u, v = P @ z, Q @ y
            rhs = -np.concatenate([eq[0], eq[3], self._jordan(u, v)])
            rhs[nx + m :][fixed] = 0.0
            with warnings.catch_warnings():  # a singular K: the direction is not finite
                warnings.simplefilter("ignore", scipy.linalg.LinAlgWarning)
                lu = scipy.linalg.lu_factor(K, check_finite=False)
            # predictor: the affine-scaling direction (kappa = 0)
            affine = scipy.linalg.lu_solve(lu, rhs, check_finite=False)
            if not np.all(np.isfinite(affine)):
                break
            dy_a, dz_a = affine[nx : nx + m], affine[nx + m :]
            alpha = min(self._to_boundary(y, dy_a, 1.0), self._to_boundary(z, dz_a, 1.0))
            gap_aff = float((z + alpha * dz_a) @ (y + alpha * dy_a)) / blocks
            sigma = min(1.0, max(gap_aff, 0.0) / gap) ** 3 if gap > 0 else 0.0
            # corrector: centred towards kappa = sigma mu (never below CENTRING times the
            # tolerance: aiming at 0 ends on the cones' boundary where the contacts are
            # degenerate; a resting contact's gap is left at kappa / lambda), with the
            # predictor's second-order term
            kappa = max(sigma * gap, CENTRING * tolerance)
            rhs[nx + m :] -= self._jordan(P @ dz_a, Q @ dy_a) - kappa * e
            rhs[nx + m :][fixed] = 0.0
            direction = scipy.linalg.lu_solve(lu, rhs, check_finite=False)
            if not np.all(np.isfinite(direction)):
                break
            dx, dy, dz = direction[:nx], direction[nx : nx + m], direction[nx + m :]
            tau = max(FRACTION_TO_BOUNDARY, 1.0 - max(residual, complementarity) ** 2)
            tau = min(tau, 1.0 - TO_BOUNDARY)
            alpha = min(self._to_boundary(y, dy, tau), self._to_boundary(z, dz, tau))
            # backtracking (as Dojo's): halved while both measures grow
            for _ in range(LINE_SEARCH):
                trial = (x + alpha * dx, y + alpha * dy, z + alpha * dz)
                eq_trial = equations(*trial)
                measures = self._measures(eq_trial, trial[1], trial[2], fixed, scale, tolerance)
                if measures[0] <= residual or measures[1] <= unsolved:
                    break
                alpha /= 2
            if not (alpha > 1e-12 and np.isfinite(measures[0] + measures[1])):
                break  # stalled at a boundary: the caller starts the step afresh
            if converged and not (measures[0] <= RESIDUAL and measures[1] <= 1.0):
                break  # the polishing step would leave the solution: not taken
            (x, y, z), eq, (residual, unsolved, loose, complementarity) = trial, eq_trial, measures
        if not converged:  # stalled or out of iterations: the looser bound
            converged = residual <= RESIDUAL and loose <= ACCEPTABLE / COMPLEMENTARITY
        return self._result(t0, h, qk, eq[7], eq[8], y, z, iterations, complementarity, converged)

    def _result(
        self, t0, h, qk, p_new, C, y, z, iterations, complementarity, converged,
        projected: bool = False,
    ) -> StepResult:  # fmt: skip
        """The step's result from its solution: the momentum projected onto the hidden
        constraint (unless ``projected``), the forces by contact, which frictional
        contacts stick."""
        s = C.shape[0] - 1
        if self.system.m and converged and not projected:
            try:
                p_new = self._projected(t0 + h, qk + C[s], p_new)
            except ValueError:
                converged = False
        normal = np.array([y[layout.normal] for layout in self.layout])
        tangential = np.zeros((len(self.layout), self.tangential_size))
        sticking = np.zeros(len(self.layout), dtype=bool)
        for j, layout in enumerate(self.layout):
            if layout.cone is not None:
                beta = y[layout.cone][1:]
                tangential[j, : beta.size] = beta
                # the slip speed zeta is zero (to round-off): the force lies inside the cone
                sticking[j] = normal[j] * h > RESIDUAL and z[layout.cone][0] * h <= RESIDUAL
        return StepResult(
            q=qk + C[s],
            p=p_new,
            C=C,
            normal=normal,
            tangential=tangential,
            duals=y,
            sticking=sticking,
            iterations=iterations,
            complementarity=float(complementarity),
            converged=bool(converged),
        )


def _orthant_step(v: float, dv: float) -> float:
    return -v / dv if dv < 0 else np.inf


def _cone_step(v: NDArray, dv: NDArray) -> float:
    """Largest alpha with v + alpha dv in the second-order cone {a >= |b|} (v inside)."""
    # (v0 + a dv0)^2 - |v1 + a dv1|^2 = 0 and v0 + a dv0 = 0: the smallest positive root
    a = dv[0] ** 2 - dv[1:] @ dv[1:]
    b = 2 * (v[0] * dv[0] - v[1:] @ dv[1:])
    size = np.linalg.norm(v[1:])
    c = (v[0] - size) * (v[0] + size)
    roots = [-v[0] / dv[0]] if dv[0] < 0 else []
    if abs(a) > 1e-300:
        disc = b * b - 4 * a * c
        if disc >= 0:
            sq = np.sqrt(disc)
            roots += [(-b - sq) / (2 * a), (-b + sq) / (2 * a)]
    elif b < 0:
        roots.append(-c / b)
    positive = [r for r in roots if r > 0]
    return min(positive) if positive else np.inf


def _jordan_norm(v: NDArray) -> float:
    r""":math:`\sqrt{v_0^2 - |v_1|^2}` as :math:`\sqrt{(v_0 - |v_1|)(v_0 + |v_1|)}`, free of
    the cancellation of the squares near the cone's boundary (as CVXOPT's ``jnrm2``)."""
    size = float(np.linalg.norm(v[1:]))
    return float(np.sqrt(max((v[0] - size) * (v[0] + size), 0.0)))


def _nesterov_todd(z: NDArray, y: NDArray) -> tuple[NDArray, NDArray] | None:
    r"""The Nesterov–Todd scaling (W, W^{-1}) of a cone's slack z and dual y, or None
    where it cannot be formed (z or y on the boundary to round-off).

    With :math:`J = \operatorname{diag}(1, -1, \dots)`, the Jordan norms
    :math:`\|z\|_J = \sqrt{z^{\mathsf T} J z}` (:func:`_jordan_norm`),
    :math:`\bar z = z / \|z\|_J`, :math:`\bar y = y / \|y\|_J`,
    :math:`\gamma = \sqrt{(1 + \bar z^{\mathsf T} \bar y) / 2}`,
    :math:`w = (J \bar z + \bar y) / (2\gamma)`,
    :math:`\eta = \sqrt{\|y\|_J / \|z\|_J}`,

    .. math::

        W = \eta \begin{pmatrix} w_0 & w_1^{\mathsf T} \\
            w_1 & I + w_1 w_1^{\mathsf T} / (1 + w_0) \end{pmatrix},
        \qquad W z = W^{-1} y

    (Vandenberghe, *The CVXOPT linear and quadratic cone program solvers*,
    2010, §4); :math:`W^{-1}` is W with :math:`w_1 \to -w_1`, :math:`\eta \to 1/\eta`.
    """
    zz, yy = _jordan_norm(z), _jordan_norm(y)
    limit = np.sqrt(DEGENERATE)
    if not (zz > limit * z[0] and yy > limit * y[0]):
        return None
    zb, yb = z / zz, y / yy
    gamma = np.sqrt((1.0 + zb @ yb) / 2.0)
    w = (yb + np.concatenate([zb[:1], -zb[1:]])) / (2.0 * gamma)
    eta = np.sqrt(yy / zz)
    lower = np.outer(w[1:], w[1:]) / (1.0 + w[0]) + np.eye(z.size - 1)
    scaled = np.block([[w[:1, None], w[None, 1:]], [w[1:, None], lower]])
    inverse = scaled.copy()
    inverse[0, 1:], inverse[1:, 0] = -w[1:], -w[1:]
    W, Winv = eta * scaled, inverse / eta
    if not (np.all(np.isfinite(W)) and np.all(np.isfinite(Winv))):
        return None
    return W, Winv
