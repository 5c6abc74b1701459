r"""The tangent map of a run with impacts: the derivative of the discrete run.

Between impacts a run is steps of the method, whose tangent maps the tangent
loop gives (:mod:`galerkin_vi.run.tangent`). The step cut at an impact is a
step of length :math:`\tau - t_k` to the impact time :math:`\tau`, the impact
law :math:`\Delta`, and a step of length :math:`t_{k+1} - \tau` after it, with
:math:`\tau` the root of the gap along the method's step,
:math:`\varphi(\Psi_{\tau - t_k}(x_k)) = 0`. Differentiated,

.. math::

    \delta\tau = -\frac{\nabla\varphi^T(D\Psi_1\,\delta x_k)_q}{\nabla\varphi^T(\psi_1)_q},
    \qquad \delta x^- = D\Psi_1\,\delta x_k + \psi_1\,\delta\tau,
    \qquad \delta x^+ = D\Delta\,\delta x^-,
    \qquad \delta x_{k+1} = D\Psi_2\,\delta x^+ - \psi_2\,\delta\tau,

with :math:`\psi = \partial_\tau\Psi_\tau` the derivative of a step in its length,
the sensitivity of the same step of the system in scaled time
(:func:`length_system`). This is the discrete counterpart of the saltation
matrix (Aizerman & Gantmacher 1958; Müller 1995),

.. math::

    S = D\Delta + \frac{(f^+ - D\Delta\, f^-)\,\nabla\tilde\varphi^T}
                       {\nabla\tilde\varphi^T f^- + \partial_t\varphi},

which :func:`saltation_matrix` gives with the continuous vector fields
:math:`f^\pm = (v^\pm, L_q + f)` and which time-dependent systems use (there the
tangent is the run's derivative to the method's accuracy only). For the
frictionless Newton law :math:`L_v(q, v^+) = p^- + \lambda\nabla\varphi`,
:math:`\nabla\varphi^T v^+ = -e\,\nabla\varphi^T v^-`, the Jacobian :math:`D\Delta`
follows from the saddle-point system differentiated at :math:`(q, p^-)`:

.. math::

    \begin{pmatrix} L_{vv}^+ & -\nabla\varphi \\ \nabla\varphi^T & 0 \end{pmatrix}
    \begin{pmatrix}\delta v^+\\ \delta\lambda\end{pmatrix} =
    \begin{pmatrix}\delta p + (\lambda\nabla^2\varphi - L_{qv}^{+T})\,\delta q\\
    -e\nabla\varphi^T\delta v^- - (\nabla^2\varphi\,(v^+ + e v^-))^T\delta q\end{pmatrix},
    \quad \delta p^+ = \delta p + \lambda\nabla^2\varphi\,\delta q + \nabla\varphi\,\delta\lambda,

with :math:`\delta v^- = (L_{vv}^-)^{-1}(\delta p - L_{qv}^{-T}\delta q)`.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..run.spec import Segment
from ..run.start import initial_state
from ..run.tangent import TangentRunner, VariationRequest, Variations, legendre_derivatives

__all__ = [
    "check_contact_variations",
    "contact_variations",
    "impact_jacobian",
    "length_system",
    "saltation_matrix",
]


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
    """(L_q + f, dL_v/dq, L_vv) at one state."""
    n = system.n
    force = np.asarray(system.evaluate("gradient", t, q, v, prm), dtype=float).ravel()[:n]
    legendre = legendre_derivatives(system, (), t, q, v, prm)
    return force, legendre.dq, legendre.dv


def impact_jacobian(system, functions, impact, q, p_minus, p_plus, prm):
    r""":math:`D\Delta` (2n, 2n) of a frictionless ``impact`` at (q, p^-) -> p^+, and the
    vector fields :math:`f^\pm` before and after it (module docstring)."""
    n = system.n
    t, j = impact.t, impact.contact
    params = dict(zip(system.params, prm, strict=True))
    v_minus = system.inverse_legendre(q, p_minus, t, params)
    v_plus = system.inverse_legendre(q, p_plus, t, params)
    g = functions.gradient(j, t, q, prm)
    hess = functions.at(functions.hessians, t, q, np.zeros(n), prm)[j]
    e = system.contacts[j].restitution
    lam = impact.normal_impulse
    force_m, lvq_m, lvv_m = _point_blocks(system, t, q, v_minus, prm)
    force_p, lvq_p, lvv_p = _point_blocks(system, t, q, v_plus, prm)
    # d v^- / d(q, p) and the right-hand side of the differentiated law, columns (q, p)
    dv_minus = np.linalg.solve(lvv_m, np.hstack([-lvq_m, np.eye(n)]))
    top = np.hstack([lam * hess - lvq_p, np.eye(n)])
    bottom = -e * (g @ dv_minus) - np.r_[hess @ (v_plus + e * v_minus), np.zeros(n)]
    matrix = np.block([[lvv_p, -g[:, None]], [g[None, :], np.zeros((1, 1))]])
    solution = np.linalg.solve(matrix, np.vstack([top, bottom[None, :]]))
    d_lam = solution[n]
    jump = np.eye(2 * n)
    jump[n:, :n] += lam * hess + np.outer(g, d_lam[:n])
    jump[n:, n:] += np.outer(g, d_lam[n:])
    return jump, np.r_[v_minus, force_m], np.r_[v_plus, force_p]


def saltation_matrix(system, functions, impact, q, p_minus, p_plus, prm) -> NDArray:
    """The saltation matrix S (2n, 2n) of a frictionless ``impact`` at (q, p^-) -> p^+, with
    the continuous vector fields (module docstring)."""
    n = system.n
    jump, f_minus, f_plus = impact_jacobian(system, functions, impact, q, p_minus, p_plus, prm)
    g = functions.gradient(impact.contact, impact.t, q, prm)
    normal = np.r_[g, np.zeros(n)]
    rate = 0.0
    rates = system.derived.get(("contact", "gap rates"), lambda: _gap_rates(system, functions))
    if rates is not None:
        params = dict(zip(system.params, prm, strict=True))
        v_minus = system.inverse_legendre(q, p_minus, impact.t, params)
        rate = float(
            np.asarray(rates(impact.t, *q, *v_minus, *prm), dtype=float).ravel()[impact.contact]
        )
    return jump + np.outer(f_plus - jump @ f_minus, normal) / (normal @ f_minus + rate)


def length_system(system):
    r"""The system in time scaled by :math:`\sigma`: :math:`\tilde L = \sigma L(q, v/\sigma)`,
    :math:`\tilde f = \sigma f(q, v/\sigma)`, and :math:`\sigma`.

    A Galerkin step of length h of it is, at any :math:`\sigma`, the step of
    length :math:`\sigma h` of the system (its discrete Lagrangian is
    :math:`h\sum_i b_i \sigma L(Q_i, \dot Q_i/\sigma) = L_d(q_0, q_1, \sigma h)`, with
    the same momenta): the sensitivity to :math:`\sigma` at 1 of a step of length
    :math:`\tau` is :math:`\tau\,\partial_\tau\Psi_\tau`, the derivative of the
    discrete flow in its step length. Autonomous systems only.
    """
    sigma = sp.Symbol("_gvi_step_scale")
    scaled = {v: v / sigma for v in system.v}
    forces = None
    if system.forces is not None:
        forces = [sigma * f.xreplace(scaled) for f in system.forces]
    params = dict(zip(system.params, system.param_defaults, strict=True))
    params[sigma] = 1.0
    scaled_system = type(system)(
        sigma * system.L.xreplace(scaled), list(system.q), list(system.v), params=params,
        forces=forces,
    )  # fmt: skip
    return scaled_system, sigma


def contact_variations(integrator, traj, request: VariationRequest, functions, h: float):
    """:class:`Variations` at every row of a run with impacts (its rows before any option).

    Consecutive rows at the same time are an impact's (momentum before, after);
    other consecutive rows are one step of the method, of length h (grouped
    into one call of the tangent loop) or cut at an impact. Autonomous
    systems: the derivative of the discrete run, the impact times varied
    with the start through the cut steps (:func:`length_system`); otherwise
    the saltation matrix with the continuous vector fields.
    """
    system, prm = traj.system, traj.params
    discrete = system.t is None
    if discrete:
        scaled_system = system.derived.get(
            ("contact", "length system"), lambda: length_system(system)
        )
        scaled = system.derived.get(
            ("contact", "length system", integrator.method, integrator.tol, integrator.maxiter),
            lambda: _scaled_integrator(integrator, scaled_system),
        )
    t, q, p = traj.t, traj.q, traj.p
    rows = len(t)
    frames = np.empty((rows, 2 * system.n, request.directions.shape[1]))
    frames[0] = request.directions
    shift = np.zeros(request.directions.shape[1])  # d(time of the row) / d(start), per column
    impacts = iter(traj.impacts or [])
    i = 0
    while i < rows - 1:
        if t[i + 1] == t[i]:
            frames[i + 1] = frames[i]
            if not np.array_equal(p[i + 1], p[i]):
                impact = next(impacts)
                law = impact_jacobian if discrete else saltation_matrix
                matrix = law(system, functions, impact, q[i], p[i], p[i + 1], prm)
                frames[i + 1] = (matrix[0] if discrete else matrix) @ frames[i]
            i += 1
            continue
        before_impact = _impact_next(t, i)
        if not discrete or (_is_step(t, i, h) and not before_impact and not shift.any()):
            # steps of fixed length (of h, grouped; or cut, one by one, without moving)
            m, length = 1, float(t[i + 1] - t[i])
            if _is_step(t, i, h):
                length = h
                while i + m < rows - 1 and _is_step(t, i + m, h) and not _impact_next(t, i + m):
                    m += 1
            frames[i + 1 : i + m + 1] = _steps(integrator, request, frames[i], t[i], q[i], p[i],
                                               length, m, prm)  # fmt: skip
            i += m
            continue
        # a step whose start or end is an impact: its length varies with the start
        moved, rate = _cut_step(scaled, frames[i], t[i], q[i], p[i], float(t[i + 1] - t[i]), prm)
        new_shift = np.zeros_like(shift)
        if before_impact:
            j = next_contact(traj, t[i + 1])
            g = functions.gradient(j, t[i + 1], q[i + 1], prm)
            new_shift = shift - (g @ moved[: system.n]) / (g @ rate[: system.n])
        frames[i + 1] = moved + np.outer(rate, new_shift - shift)
        shift = new_shift
        i += 1
    return Variations(tangent=frames, sensitivity=None, parameters=())


def next_contact(traj, t_hit: float) -> int:
    """The contact of the first impact at time ``t_hit``."""
    return next(imp.contact for imp in traj.impacts if imp.t == t_hit)


def _impact_next(t, i: int) -> bool:
    """Whether the row after row i + 1 is an impact's second row (row i + 1 meets it)."""
    return i + 2 < len(t) and t[i + 2] == t[i + 1]


def _steps(integrator, request, frame, t0, q0, p0, h, m, prm):
    """The frames after m steps of length h from (t0, q0, p0)."""
    spec = integrator.tangent_run_spec
    q, p, v = initial_state(spec, q0, None, p0, float(t0), prm)
    runner = TangentRunner(spec, replace(request, directions=frame.copy()), float(t0))
    part, result = runner(Segment(q, p, v, float(t0), h, m, 1, prm))
    if result.status != 0:
        raise RuntimeError(f"the tangent of the steps from t = {t0:.6g} failed: {part.message}")
    return part.variations.tangent[1:]


def _scaled_integrator(integrator, scaled):
    system, sigma = scaled
    return type(integrator)(system, integrator.method, tol=integrator.tol,
                            maxiter=integrator.maxiter), sigma  # fmt: skip


def _cut_step(scaled, frame, t0, q0, p0, length, prm):
    r"""A step of ``length`` from (q0, p0): the frame moved by its tangent map, and
    :math:`\partial_\tau\Psi_\tau` there (the derivative in the step's length)."""
    aux, sigma = scaled
    params = dict(zip(aux.system.params, [*prm, 1.0], strict=True))
    run = aux.integrate(
        q0, p0=p0, h=length, n_steps=1, t0=float(t0), params=params, tangent=frame,
        sensitivity=[sigma], on_failure="raise",
    )  # fmt: skip
    return run.tangent[-1], run.sensitivity[-1][:, 0] / length


def _is_step(t: NDArray, i: int, h: float) -> bool:
    """Whether rows i, i + 1 are one full step of size h apart."""
    return abs((t[i + 1] - t[i]) - h) <= 1e-12 * max(1.0, abs(t[i + 1]))
