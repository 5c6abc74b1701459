r"""The start of a run: the user's :math:`(q_0, v_0)` or :math:`(q_0, p_0)` as the loops'
:math:`(q_0, p_0, v_0)`.

The continuous Legendre transform :math:`p = \partial L/\partial v` (or its
inverse) maps the given data; the compiled point functions do it in
microseconds (:mod:`galerkin_vi.run.legendre`), the NumPy evaluators are the
fallback that also names a singular :math:`\partial^2 L/\partial v^2`. On a
constrained system the state is checked against (or, with ``project``, moved
onto) the constraint manifold and the momentum projected onto the hidden
constraint.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import DegenerateLagrangianError
from ..model.constraints import consistent_initial_state, project_momentum
from ..model.system import is_regular
from .plan import all_finite, state_vector
from .spec import RunSpec

__all__ = ["initial_momentum", "initial_state"]


def initial_momentum(spec: RunSpec, q0, v0, p0, t0: float, prm) -> tuple[NDArray, NDArray]:
    """``(p0, v0)`` at ``q0`` from exactly one of ``v0`` and ``p0``."""
    if (v0 is None) == (p0 is None):
        raise ValueError("give exactly one of v0 (velocities) and p0 (momenta)")
    system = spec.system
    n = system.n
    fast = spec.legendre
    if fast is not None:
        # None means singular or not finite, which the NumPy path below reports
        if v0 is not None:
            v = state_vector("v0", v0, n)
            p = fast.momenta(t0, q0, v, prm)
        elif system.structure.quadratic_in_v:
            p = state_vector("p0", p0, n)
            v = fast.velocities_of_quadratic(t0, q0, p, prm)
            p = p if v is not None else None
        else:
            p = None
        if p is not None:
            p, v = np.asarray(p, dtype=float), np.asarray(v, dtype=float)
            if all_finite(p) and all_finite(v):
                return p, v
    prm_dict = dict(zip(system.params, prm, strict=True))
    if v0 is not None:
        v = state_vector("v0", v0, n)
        m = system.evaluate("Lvv", t0, q0, v, system.parameter_vector(prm_dict))
        if not np.all(np.isfinite(m)) or not is_regular(m.reshape(n, n)):
            raise DegenerateLagrangianError(
                f"d2L/dv2 is singular at q0={q0}, v0={v}: the Lagrangian is degenerate there"
            )
        p = system.legendre(q0, v, t0, prm_dict)
    else:
        p = state_vector("p0", p0, n)
        v = system.inverse_legendre(q0, p, t0, prm_dict)
    if not (np.all(np.isfinite(p)) and np.all(np.isfinite(v))):
        raise ValueError(f"the Legendre transform at q0={q0} is not finite")
    return np.asarray(p, dtype=float), np.asarray(v, dtype=float)


def initial_state(spec: RunSpec, q0, v0, p0, t0: float, prm, project: bool = False):
    """``(q0, p0, v0)`` of a run from the user's data, constraints checked.

    Parameters
    ----------
    q0 : array_like, shape (n,)
    v0, p0 : array_like or None
        Exactly one.
    project : bool
        Constrained systems: move ``q0`` onto the constraint manifold first
        (:func:`galerkin_vi.model.constraints.consistent_initial_state`). A
        system without constraints has nothing to project onto: ValueError.
    """
    system = spec.system
    q0 = state_vector("q0", q0, system.n)
    p, v = initial_momentum(spec, q0, v0, p0, t0, prm)
    if system.m:
        q0, p, v = consistent_initial_state(system, t0, q0, p, v, prm, bool(project))
        p, v = project_momentum(system, t0, q0, p, v, prm)
    elif project:
        raise ValueError("project=True needs a system with constraints")
    return q0, p, v
