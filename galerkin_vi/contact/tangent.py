r"""The tangent map of a run with impacts: the steps' tangent maps and the saltation matrices.

Between impacts a run is steps of the method, whose tangent maps the tangent
loop gives (:mod:`galerkin_vi.run.tangent`); the step cut at an impact is a
step of length :math:`t^* - t_k` to the impact and one of :math:`t_{k+1} - t^*`
after it. At the impact the tangent jumps by the saltation matrix
(Aizerman & Gantmacher 1958; Müller 1995; the hybrid-systems literature)

.. math::

    S = D\Delta + \frac{(f^+ - D\Delta\, f^-)\,\nabla\tilde\varphi^T}
                       {\nabla\tilde\varphi^T f^- + \partial_t\varphi},

in the state :math:`x = (q, p)`: :math:`\Delta(q, p^-) = (q, p^+)` the impact law,
:math:`f^\pm = (v^\pm, L_q + f)` the vector field before and after it,
:math:`\tilde\varphi(q, p) = \varphi(t, q)` the gap. The second term moves the
impact time with the start: a start that reaches the contact earlier has
longer to move with the velocity after the impact. For the frictionless
Newton law :math:`L_v(q, v^+) = p^- + \lambda\nabla\varphi`,
:math:`\nabla\varphi^T v^+ = -e\,\nabla\varphi^T v^-`, the Jacobian :math:`D\Delta`
follows from the saddle-point system differentiated at :math:`(q, p^-)`:

.. math::

    \begin{pmatrix} L_{vv}^+ & -\nabla\varphi \\ \nabla\varphi^T & 0 \end{pmatrix}
    \begin{pmatrix}\delta v^+\\ \delta\lambda\end{pmatrix} =
    \begin{pmatrix}\delta p + (\lambda\nabla^2\varphi - L_{qv}^{+T})\,\delta q\\
    -e\nabla\varphi^T\delta v^- - (\nabla^2\varphi\,(v^+ + e v^-))^T\delta q\end{pmatrix},
    \quad \delta p^+ = \delta p + \lambda\nabla^2\varphi\,\delta q + \nabla\varphi\,\delta\lambda,

with :math:`\delta v^- = (L_{vv}^-)^{-1}(\delta p - L_{qv}^{-T}\delta q)`. The vector
fields are the continuous ones: the tangent is the derivative of the discrete
run to the method's order (exactly so where the method is exact between impacts).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..run.spec import Segment
from ..run.start import initial_state
from ..run.tangent import TangentRunner, VariationRequest, Variations

__all__ = ["check_contact_variations", "contact_variations", "saltation_matrix"]


def check_contact_variations(system, request: VariationRequest, contact_mode: str, h: float):
    """Refuse, with the reason, what the tangent of runs with impacts does not cover."""
    reasons = []
    if request.parameters:
        reasons.append("parameter sensitivities through impacts (the impact law's and the "
                       "impact time's derivatives in the parameters) are not built")  # fmt: skip
    if request.renormalize_every:
        reasons.append("renormalize_every is for smooth runs (chaos indicators)")
    if contact_mode == "time-stepping":
        reasons.append("the tangent of complementarity steps is not built (use 'event')")
    if any(c.friction > 0.0 for c in system.contacts):
        reasons.append("the saltation matrix of impacts with friction is not built")
    if system.m:
        reasons.append("the saltation matrix of constrained impacts is not built")
    if h < 0:
        reasons.append("backward runs with impacts carry no tangent")
    if reasons:
        raise ValueError("tangent with contacts: " + "; ".join(reasons))


def _gap_rates(system, functions):
    """The gaps' time derivatives (zero for autonomous gaps), lambdified once per system."""
    if system.t is None:
        return None
    args = (system.t, *system.q, *system.v, *system.params)
    return sp.lambdify(args, [sp.diff(c.gap, system.t) for c in system.contacts], "numpy")


def _point_blocks(system, t, q, v, prm):
    """(L_q + f, L_v, L_qv, L_vv) at one state."""
    n = system.n
    flat = np.asarray(system.evaluate("hessian", t, q, v, prm), dtype=float).ravel()
    force, lv = flat[:n], flat[n : 2 * n]
    lqv = flat[2 * n + n * n : 2 * n + 2 * n * n].reshape(n, n)
    lvv = flat[2 * n + 2 * n * n : 2 * n + 3 * n * n].reshape(n, n)
    return force, lv, lqv, lvv


def saltation_matrix(system, functions, impact, q, p_minus, p_plus, prm) -> NDArray:
    """The saltation matrix S (2n, 2n) of a frictionless ``impact`` at (q, p^-) -> p^+."""
    n = system.n
    t, j = impact.t, impact.contact
    params = dict(zip(system.params, prm, strict=True))
    v_minus = system.inverse_legendre(q, p_minus, t, params)
    v_plus = system.inverse_legendre(q, p_plus, t, params)
    g = functions.gradient(j, t, q, prm)
    hess = functions.at(functions.hessians, t, q, np.zeros(n), prm)[j]
    e = system.contacts[j].restitution
    lam = impact.normal_impulse
    force_m, _, lqv_m, lvv_m = _point_blocks(system, t, q, v_minus, prm)
    force_p, _, lqv_p, lvv_p = _point_blocks(system, t, q, v_plus, prm)
    # d v^- / d(q, p) and the right-hand side of the differentiated law, columns (q, p)
    dv_minus = np.linalg.solve(lvv_m, np.hstack([-lqv_m.T, np.eye(n)]))
    top = np.hstack([lam * hess - lqv_p.T, np.eye(n)])
    bottom = -e * (g @ dv_minus) - np.r_[hess @ (v_plus + e * v_minus), np.zeros(n)]
    matrix = np.block([[lvv_p, -g[:, None]], [g[None, :], np.zeros((1, 1))]])
    solution = np.linalg.solve(matrix, np.vstack([top, bottom[None, :]]))
    d_lam = solution[n]
    jump = np.eye(2 * n)
    jump[n:, :n] += lam * hess + np.outer(g, d_lam[:n])
    jump[n:, n:] += np.outer(g, d_lam[n:])
    f_minus = np.r_[v_minus, force_m]
    f_plus = np.r_[v_plus, force_p]
    normal = np.r_[g, np.zeros(n)]
    rate = 0.0
    rates = system.derived.get(("contact", "gap rates"), lambda: _gap_rates(system, functions))
    if rates is not None:
        rate = float(np.asarray(rates(t, *q, *v_minus, *prm), dtype=float).ravel()[j])
    return jump + np.outer(f_plus - jump @ f_minus, normal) / (normal @ f_minus + rate)


def contact_variations(integrator, traj, request: VariationRequest, functions, h: float):
    """:class:`Variations` at every row of a run with impacts (its rows before any option).

    Consecutive rows at the same time are an impact's (momentum before, after:
    the saltation matrix between them); other consecutive rows are one step of
    the method, of length h (grouped into one call of the tangent loop) or cut
    at an impact.
    """
    spec = integrator.tangent_run_spec
    system, prm = traj.system, traj.params
    t, q, p = traj.t, traj.q, traj.p
    rows = len(t)
    frames = np.empty((rows, 2 * system.n, request.directions.shape[1]))
    frames[0] = request.directions
    impacts = iter(traj.impacts or [])
    i = 0
    while i < rows - 1:
        if t[i + 1] == t[i]:
            frames[i + 1] = frames[i]
            if not np.array_equal(p[i + 1], p[i]):
                impact = next(impacts)
                salt = saltation_matrix(system, functions, impact, q[i], p[i], p[i + 1], prm)
                frames[i + 1] = salt @ frames[i]
            i += 1
            continue
        m, step = 1, float(t[i + 1] - t[i])
        if _is_step(t, i, h):
            step = h
            while i + m < rows - 1 and _is_step(t, i + m, h):
                m += 1
        q0, p0, v0 = initial_state(spec, q[i], None, p[i], float(t[i]), prm)
        runner = TangentRunner(spec, replace(request, directions=frames[i].copy()), float(t[i]))
        part, result = runner(Segment(q0, p0, v0, float(t[i]), step, m, 1, prm))
        if result.status != 0:
            raise RuntimeError(
                f"the tangent of the step from t = {t[i]:.6g} failed: {part.message}"
            )
        frames[i + 1 : i + m + 1] = part.variations.tangent[1:]
        i += m
    return Variations(tangent=frames, sensitivity=None, parameters=())


def _is_step(t: NDArray, i: int, h: float) -> bool:
    """Whether rows i, i + 1 are one full step of size h apart."""
    return abs((t[i + 1] - t[i]) - h) <= 1e-12 * max(1.0, abs(t[i + 1]))
