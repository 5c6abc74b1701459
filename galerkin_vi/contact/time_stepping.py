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

and, for friction in the plane (one slip velocity :math:`w`, mean
:math:`\bar w = \sum_i b_i w(Q_i, V_i)` over the step), by Coulomb's law as
maximum dissipation, exact in one dimension (the cone is an interval):
:math:`\beta = \beta^+ - \beta^-` with

.. math::

    0 \le \bar w + \zeta \perp \beta^+ \ge 0,\quad
    0 \le -\bar w + \zeta \perp \beta^- \ge 0,\quad
    0 \le \mu\lambda - \beta^+ - \beta^- \perp \zeta \ge 0

(:math:`\zeta` is the slip speed: sticking :math:`\bar w = 0` inside the cone,
sliding on its edge against :math:`\bar w`). With slacks :math:`z` for the
left-hand sides and duals :math:`y` for the right, the step solves
:math:`F(x, y) = 0`, :math:`z = c(x, y)`, :math:`z \circ y = \kappa` for
:math:`\kappa \to 0` by a primal–dual interior-point method with Mehrotra's
predictor–corrector and the fraction-to-boundary rule (as Dojo does), with
the exact Jacobians of the stage equations and of the gaps and slips.

Spatial friction (two slip velocities, a second-order cone) is not here yet.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..backends import numpy as numpy_backend

__all__ = ["ContactForces", "ContactStep", "ContactStepper", "StepResult"]

#: interior-point iterations per step at most
MAX_ITERATIONS = 50
#: complementarity z . y / pairs at which a step is solved (the issue's bound: 1e-10)
COMPLEMENTARITY = 1e-12
#: relative residual of the stage and slack equations at which a step is solved
RESIDUAL = 1e-12


@dataclass(frozen=True)
class ContactForces:
    r"""The contact forces of the time-stepping steps of a run (constant over each step).

    Attributes
    ----------
    t : ndarray, shape (k,)
        The steps' start times.
    normal, tangential : ndarray, shape (k, contacts)
        :math:`\lambda_c` and :math:`\beta_c` (0 without friction).
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
    """Per contact: where its unknowns sit in the duals (and slacks) of a step."""

    normal: int
    friction: tuple[int, int, int] | None  # beta+, beta-, zeta


class ContactStepper:
    """The interior-point step of a system with contacts and a Galerkin method."""

    def __init__(self, system, tables, prm) -> None:
        self.system, self.tables, self.prm = system, tables, prm
        n = system.n
        t = system.t if system.t is not None else sp.Dummy("t")
        args = (t, *system.q, *system.v, *system.params)
        self.layout: list[ContactStep] = []
        self._gap, self._grad, self._hess = [], [], []
        self._slip = []
        pairs = 0
        for contact in system.contacts:
            gap = contact.gap
            self._gap.append(sp.lambdify(args, gap, "numpy"))
            self._grad.append(sp.lambdify(args, [sp.diff(gap, a) for a in system.q], "numpy"))
            hess = [[sp.diff(gap, a, b) for b in system.q] for a in system.q]
            self._hess.append(sp.lambdify(args, hess, "numpy"))
            if contact.friction > 0.0:
                if len(contact.slip) != 1:
                    raise NotImplementedError(
                        f"contact (gap {gap}): persistent contact with friction in space (two "
                        "slip velocities, a second-order cone) is not available yet"
                    )
                (w,) = contact.slip
                w_q = [sp.diff(w, a) for a in system.q]
                w_v = [sp.diff(w, a) for a in system.v]
                w_vq = [[sp.diff(w, b, a) for a in system.q] for b in system.v]
                self._slip.append(tuple(sp.lambdify(args, e, "numpy") for e in (w, w_q, w_v, w_vq)))
                self.layout.append(ContactStep(pairs, (pairs + 1, pairs + 2, pairs + 3)))
                pairs += 4
            else:
                self._slip.append(None)
                self.layout.append(ContactStep(pairs, None))
                pairs += 1
        self.pairs = pairs
        self.n = n

    # ----------------------------------------------------------- evaluation
    def _at(self, f, t, q, v):
        return np.asarray(f(t, *q, *v, *self.prm), dtype=float)

    def _each(self, f, t, Q, V, shape=()) -> NDArray[np.float64]:
        """``f`` at every quadrature point, stacked: shape (r, *shape)."""
        return np.array(
            [self._at(f, ti, Qi, Vi).reshape(shape) for ti, Qi, Vi in zip(t, Q, V, strict=True)]
        )

    def _equations(self, t0, h, qk, pk, x, y):
        """Residuals F (stage equations with the contact forces), c (the slacks' values)
        and their Jacobians in (x, y)."""
        system, tb, n = self.system, self.tables, self.n
        s = tb.d.size - 1
        C = np.vstack([np.zeros((1, n)), x.reshape(s, n)])
        G, H = numpy_backend.discrete_hessian(system, tb, t0, h, qk, C, self.prm)
        t, Q, V = numpy_backend._points(tb, t0, h, qk, C)
        b, Phi, D = tb.b, tb.Phi, tb.D
        F = G[:s].copy()
        F[0] += pk
        Fx = H[:s, :, 1:, :].reshape(s * n, s * n).copy()
        Fy = np.zeros((s * n, self.pairs))
        c = np.zeros(self.pairs)
        cx = np.zeros((self.pairs, s * n))
        cy = np.zeros((self.pairs, self.pairs))
        end = qk + C[s]
        forces_end = np.zeros(n)
        zeros_v = np.zeros(n)
        for j, layout in enumerate(self.layout):
            lam = y[layout.normal]
            grads = self._each(self._grad[j], t, Q, V, (n,))
            hess = self._each(self._hess[j], t, Q, V, (n, n))
            # the normal force at every quadrature point, weighted into every node
            weights = h * b[:, None] * Phi  # (r, s+1)
            node_force = weights.T @ grads  # (s+1, n)
            F += lam * node_force[:s]
            forces_end += lam * node_force[s]
            Fy[:, layout.normal] = node_force[:s].ravel()
            curvature = np.einsum("iv,iu,iab->vaub", weights, Phi, hess) * lam
            Fx += curvature[:s, :, 1:, :].reshape(s * n, s * n)
            # the gap at the step's end: q_{k+1} = q_k + C^s
            t_end = t0 + h
            c[layout.normal] = float(self._at(self._gap[j], t_end, end, zeros_v))
            cx[layout.normal, (s - 1) * n :] = self._at(self._grad[j], t_end, end, zeros_v)
            if layout.friction is None:
                continue
            plus, minus, zeta = layout.friction
            mu = system.contacts[j].friction
            w_fn, wq_fn, wv_fn, wvq_fn = self._slip[j]
            w = self._each(w_fn, t, Q, V)
            wq = self._each(wq_fn, t, Q, V, (n,))
            wv = self._each(wv_fn, t, Q, V, (n,))
            wvq = self._each(wvq_fn, t, Q, V, (n, n))
            beta = y[plus] - y[minus]
            tangent_force = weights.T @ wv  # (s+1, n): T^T at the points, into the nodes
            F += beta * tangent_force[:s]
            forces_end += beta * tangent_force[s]
            Fy[:, plus] = tangent_force[:s].ravel()
            Fy[:, minus] = -tangent_force[:s].ravel()
            bend = np.einsum("iv,iu,iab->vaub", weights, Phi, wvq) * beta
            Fx += bend[:s, :, 1:, :].reshape(s * n, s * n)
            # the mean slip over the step and its derivative in the control points
            w_mean = float(b @ w)
            dw = np.einsum("i,iu,ia->ua", b, Phi, wq) + np.einsum("i,iu,ia->ua", b, D, wv) / h
            dw = dw[1:].ravel()
            c[plus], c[minus] = w_mean + y[zeta], -w_mean + y[zeta]
            cx[plus], cx[minus] = dw, -dw
            cy[plus, zeta] = cy[minus, zeta] = 1.0
            c[zeta] = mu * lam - y[plus] - y[minus]
            cy[zeta, layout.normal] = mu
            cy[zeta, plus] = cy[zeta, minus] = -1.0
        return F.ravel(), Fx, Fy, c, cx, cy, G[s] + forces_end, C

    # ---------------------------------------------------------------- solve
    def step(self, t0: float, h: float, qk, pk, guess_C, duals) -> StepResult:
        """One step of length h from (q_k, p_k): Mehrotra's predictor–corrector."""
        s = self.tables.d.size - 1
        nx, m = s * self.n, self.pairs
        x = np.asarray(guess_C, dtype=float)[1:].ravel().copy()
        y = np.maximum(np.asarray(duals, dtype=float), 1e-6)
        F, Fx, Fy, c, cx, cy, p_new, C = self._equations(t0, h, qk, pk, x, y)
        z = np.maximum(c, 1e-6)
        scale = 1.0 + float(np.max(np.abs(pk)))
        iterations, converged = 0, False
        while iterations < MAX_ITERATIONS:
            iterations += 1
            K = np.zeros((nx + 2 * m, nx + 2 * m))
            K[:nx, :nx], K[:nx, nx : nx + m] = Fx, Fy
            K[nx : nx + m, :nx], K[nx : nx + m, nx : nx + m] = -cx, -cy
            K[nx : nx + m, nx + m :] = np.eye(m)
            K[nx + m :, nx : nx + m] = np.diag(z)
            K[nx + m :, nx + m :] = np.diag(y)
            mu = float(z @ y) / m
            r1, r2 = F, z - c
            # predictor: the affine-scaling direction (kappa = 0)
            affine = np.linalg.solve(K, -np.concatenate([r1, r2, z * y]))
            dy_a, dz_a = affine[nx : nx + m], affine[nx + m :]
            alpha = _to_boundary(np.concatenate([y, z]), np.concatenate([dy_a, dz_a]), 1.0)
            mu_aff = float((z + alpha * dz_a) @ (y + alpha * dy_a)) / m
            sigma = (mu_aff / mu) ** 3 if mu > 0 else 0.0
            # corrector: centred towards sigma mu, second-order term of the predictor
            r3 = z * y + dz_a * dy_a - sigma * mu
            step = np.linalg.solve(K, -np.concatenate([r1, r2, r3]))
            dx, dy, dz = step[:nx], step[nx : nx + m], step[nx + m :]
            tau = max(0.99, 1.0 - mu)
            alpha = _to_boundary(np.concatenate([y, z]), np.concatenate([dy, dz]), tau)
            x, y, z = x + alpha * dx, y + alpha * dy, z + alpha * dz
            F, Fx, Fy, c, cx, cy, p_new, C = self._equations(t0, h, qk, pk, x, y)
            residual = max(np.max(np.abs(F)) / scale, np.max(np.abs(z - c)))
            if residual <= RESIDUAL and float(np.max(z * y)) <= COMPLEMENTARITY:
                converged = True
                break
        normal = np.array([y[layout.normal] for layout in self.layout])
        tangential = np.array(
            [
                y[layout.friction[0]] - y[layout.friction[1]] if layout.friction else 0.0
                for layout in self.layout
            ]
        )
        # a frictional contact sticks when its slip speed is zero (zeta's impulse below
        # round-off): its force lies inside the cone
        sticking = np.array(
            [
                layout.friction is not None
                and y[layout.normal] * h > RESIDUAL
                and y[layout.friction[2]] * h <= RESIDUAL
                for layout in self.layout
            ]
        )
        return StepResult(
            q=qk + C[s],
            p=p_new,
            C=C,
            normal=normal,
            tangential=tangential,
            duals=y,
            sticking=sticking,
            iterations=iterations,
            complementarity=float(np.max(z * y)),
            converged=converged,
        )


def _to_boundary(v: NDArray, dv: NDArray, tau: float) -> float:
    """Largest alpha in (0, 1] with v + alpha dv >= (1 - tau) v (fraction to the boundary)."""
    shrinking = dv < 0
    if not shrinking.any():
        return 1.0
    return float(min(1.0, np.min(-tau * v[shrinking] / dv[shrinking])))
