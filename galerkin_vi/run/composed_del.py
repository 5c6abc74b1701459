r"""The position-only DEL form of a composition of Störmer–Verlet steps or a splitting.

A composition :math:`\Psi_h` (:class:`~galerkin_vi.Composition`) is variational:
its discrete Lagrangian :math:`L_d(q_0, q_1)` is the sum of its sub-steps' with the
inner positions eliminated, and :math:`p_0 = -D_1L_d(q_0, q_1)`,
:math:`p_1 = D_2L_d(q_0, q_1)` are the momenta of the map :math:`(q_0, p_0) \mapsto
(q_1, p_1)`. So the discrete Euler–Lagrange equation
:math:`D_2L_d(q_{k-1}, q_k) + D_1L_d(q_k, q_{k+1}) = 0` is solved in two moves:

1. :math:`p_{k-1}` from :math:`\Psi_h^q(q_{k-1}, p_{k-1}) = q_k` by Newton's method with the
   exact Jacobian :math:`\partial q_k/\partial p_{k-1}` (the tangent of the sub-steps,
   :func:`composition_map`), started from the Legendre transform of the difference
   quotient; then :math:`p_k = \Psi_h^p(q_{k-1}, p_{k-1})`;
2. :math:`q_{k+1} = \Psi_h^q(q_k, p_k)`, explicit.

Evaluated with the system's NumPy evaluators: one call costs a few milliseconds.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import ConvergenceError
from .plan import state_vector, step_size

__all__ = ["composition_del_step", "composition_map"]

_MAXITER = 30


def composition_map(
    system, tables: tuple, t0: float, h: float, q: NDArray, p: NDArray, prm: NDArray,
    tangent: bool = False,
) -> tuple[NDArray, NDArray, NDArray | None, NDArray | None]:  # fmt: skip
    r"""One step :math:`(q, p) \mapsto (q', p')` of the composition, and optionally
    :math:`\partial q'/\partial p` and :math:`\partial p'/\partial p`.

    ``tables`` are the sub-steps ``(drift, kick_before, kick_after, nodes)``
    (:func:`.segment.substeps`). Each sub-step with drift :math:`\eta = a_i h` and
    kicks :math:`\beta^\pm = \beta^\pm_i h` (force :math:`F = L_q + f`,
    :math:`K = \partial F/\partial q`, :math:`a(t) = L_v(t, q, 0)`):

    .. math::

        v = M^{-1}\big(p + \beta^- F_0 - \tfrac12(a_0 + a_1)\big),\ q' = q + \eta v,\
        p' = p + \beta^- F_0 + \beta^+ F_1,

        \delta q' = \delta q + \eta M^{-1}\big(\delta p + \beta^- K_0\,\delta q\big),\
        \delta p' = \delta p + \beta^- K_0\,\delta q + \beta^+ K_1\,\delta q'.
    """
    n = system.n
    zero = np.zeros(n)
    mass = system.evaluate("Lvv", t0, q, zero, prm).reshape(n, n)
    inverse = np.linalg.inv(mass)

    def force(t: float, x: NDArray) -> tuple[NDArray, NDArray]:
        g = system.evaluate("gradient", t, x, zero, prm)
        return g[:n], g[n : 2 * n]

    def stiffness(t: float, x: NDArray) -> NDArray:
        return system.evaluate("hessian", t, x, zero, prm)[2 * n : 2 * n + n * n].reshape(n, n)

    q, p = q.copy(), p.copy()
    dq = np.zeros((n, n)) if tangent else None
    dp = np.eye(n) if tangent else None
    start = t0
    f0, a0 = force(start, q)
    k0 = stiffness(start, q) if tangent else None
    for drift, kick_before, kick_after, end_fraction in zip(*tables, strict=True):
        eta, before, after = drift * h, kick_before * h, kick_after * h
        end = t0 + end_fraction * h
        _, a1 = force(end, q)
        q = q + eta * (inverse @ (p + before * f0 - 0.5 * (a0 + a1)))
        f1, a1 = force(end, q)
        p = p + before * f0 + after * f1
        if tangent:
            k1 = stiffness(end, q)
            dq_next = dq + eta * (inverse @ (dp + before * (k0 @ dq)))
            dp = dp + before * (k0 @ dq) + after * (k1 @ dq_next)
            dq, k0 = dq_next, k1
        f0, a0 = f1, a1
    return q, p, dq, dp


def composition_del_step(integrator, q0, q1, h: float, t0: float, prm: NDArray) -> NDArray:
    """``q2`` of the DEL equation from ``q0`` (at ``t0``) and ``q1`` (at ``t0 + h``)."""
    from .segment import substeps

    system = integrator.system
    n = system.n
    q0, q1 = state_vector("q0", q0, n), state_vector("q1", q1, n)
    h = step_size(h)
    t0 = float(t0)
    tables = substeps(integrator.method)
    prm_map = dict(zip(system.params, prm, strict=True))
    p0 = system.legendre(q0, (q1 - q0) / h, t0, prm_map)
    scale = max(1.0, float(np.max(np.abs(q1))))
    for _ in range(_MAXITER):
        q_end, p_end, dq, _ = composition_map(system, tables, t0, h, q0, p0, prm, True)
        residual = q_end - q1
        if np.max(np.abs(residual)) <= 4 * np.finfo(float).eps * scale:
            break
        step = np.linalg.solve(dq, residual)
        p0 = p0 - step
        if np.max(np.abs(step)) <= 4 * np.finfo(float).eps * max(1.0, float(np.max(np.abs(p0)))):
            q_end, p_end, _, _ = composition_map(system, tables, t0, h, q0, p0, prm)
            break
    else:
        raise ConvergenceError(
            f"step_del: Newton on the momentum p0 with q(t0 + h) = q1 did not converge in "
            f"{_MAXITER} iterations (residual {np.max(np.abs(residual)):.3g}); try a smaller h",
            step=0, t=t0, residual=float(np.max(np.abs(residual))),
        )  # fmt: skip
    q2, _, _, _ = composition_map(system, tables, t0 + h, h, q1, p_end, prm)
    return q2
