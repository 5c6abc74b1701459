"""Which compiled loop a run takes, from the structure the analysis found."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import sympy as sp

from ..method.composition import VERLET_SCHEMES, Composition
from ..method.galerkin import Galerkin
from ..method.stage_form import has_stage_form
from ..method.velocity_stages import MIN_FIXED_POINT_DEGREE, has_velocity_stages
from ..model.system import LagrangianSystem

__all__ = [
    "EARLY_HAND_OVER",
    "PERSISTENT",
    "HandOver",
    "check_composition",
    "composition_for",
    "composition_obstacle",
    "gyroscopic_term_varies",
    "hand_over",
    "loop_path",
]


@dataclass(frozen=True)
class HandOver:
    r"""When the varying-mass loop gives a run up to Newton (run-time data of the loop).

    Attributes
    ----------
    contraction : float
        Hand over when a sweep's change is more than this times the one before,
        or (infinite) never for slow sweeps,
        :math:`\theta = |\delta_k| / |\delta_{k-1}| > \theta_{\max}` (or, at the measured
        :math:`\theta`, the iteration would need more than ``maxiter`` sweeps:
        :func:`galerkin_vi.loops.stage_form.too_slow`).
    allowance : float
        Hand over when the sweeps per step, a running mean over the steps after
        the first, exceed this plus the number of stages.
    """

    contraction: float
    allowance: float

    @property
    def loop_arguments(self) -> tuple[float, float]:
        """``(contraction, allowance)`` in the loop's argument order."""
        return (self.contraction, self.allowance)


#: ``fixed_point=True``: at 0.3 a digit costs two sweeps, about one Newton iteration of a
#: small system; 7 sweeps above the stages is about where the fixed point stops beating
#: Newton on the double pendulum (smaller allowances hand over runs it is winning,
#: larger ones hand over late; docs/performance.md)
EARLY_HAND_OVER = HandOver(contraction=0.3, allowance=7.0)
#: ``fixed_point="persistent"``: only an iteration that reaches ``maxiter`` sweeps or
#: overflows hands over, as in the hand-written kernels. On the Poincaré-transformed
#: systems of :class:`galerkin_vi.AdaptiveIntegrator` a sweep near a close encounter may
#: stall or grow by a few percent before the iteration converges, and the early rule (or
#: a prediction from that sweep's contraction) handed the rest of each chunk to Newton at
#: about twice the cost per step (docs/performance.md, "Adaptive steps that behave")
PERSISTENT = HandOver(contraction=math.inf, allowance=math.inf)


def hand_over(fixed_point: bool | str, closed_form: bool = False) -> HandOver:
    """The :class:`HandOver` rule of ``Integrator(fixed_point=...)``; ``closed_form``
    says whether the system's sweep solves the momentum equations in closed form
    (``point_velocity``: one call per stage, no residual). Such a sweep costs a fraction
    of a Newton iteration, so the early rule's hand-overs made runs slower and gave
    coarse steps to a Newton that fails at them: ``fixed_point=True`` keeps the fixed
    point as :data:`PERSISTENT` does (docs/performance.md, "Fifth session of
    2026-11-27").

    Raises
    ------
    ValueError
        If ``fixed_point`` is not True, False or ``"persistent"``.
    """
    if isinstance(fixed_point, str) and fixed_point == "persistent":
        return PERSISTENT
    if isinstance(fixed_point, bool):
        return PERSISTENT if closed_form else EARLY_HAND_OVER
    raise ValueError(f"fixed_point must be True, False or 'persistent', got {fixed_point!r}")


def composition_obstacle(system: LagrangianSystem, method: Composition | None = None) -> str | None:
    r"""Why a :class:`~galerkin_vi.Composition` (``method``, or any) cannot run on
    ``system``, or None when it can.

    The sub-steps are explicit only for :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)`
    with constant :math:`M` and forces :math:`f(t, q)`, without constraints or contacts.
    A splitting (``method.splitting``) also needs :math:`a` constant in time: its drifts
    must be exact flows, and the sub-step integrates :math:`\int a\,dt` by the
    trapezoidal rule (:mod:`galerkin_vi.method.composition`).
    """
    structure = system.structure
    if system.m:
        return "the system has constraints (multipliers make every sub-step implicit)"
    if system.contacts:
        return "the system has contacts (impacts are cut out of Galerkin steps)"
    if not structure.constant_mass:
        return "its mass matrix d2L/dv2 varies with q or t"
    if not structure.zero_Lqv:
        return "L couples positions and velocities (d2L/dq dv is not zero)"
    if not structure.zero_fv:
        return "its forces depend on the velocities"
    if method is not None and method.splitting and gyroscopic_term_varies(system):
        return (
            "its term a(t).v linear in the velocities varies with t, and a splitting's "
            "drifts are exact flows only for a constant a"
        )
    return None


def check_composition(system: LagrangianSystem, method: Composition, backend: str) -> None:
    """ValueError naming why ``method`` cannot run on ``system`` with ``backend``
    (:func:`composition_obstacle`; splittings name the composition of Störmer–Verlet
    that can)."""
    obstacle = composition_obstacle(system)
    if obstacle is not None:
        raise ValueError(
            f"{method!r} runs explicit kick-drift sub-steps, which need a separable "
            f"L = v.M.v/2 + a(t).v - V(t, q) with constant M: {obstacle}; use a Galerkin method"
        )
    obstacle = composition_obstacle(system, method)
    if obstacle is not None:
        other = Composition(method.order, VERLET_SCHEMES[method.order])
        raise ValueError(
            f"{method!r} is a splitting with free kicks: {obstacle}; use {other!r} "
            "(a composition of Stormer-Verlet steps) or a Galerkin method"
        )
    if backend != "numba":
        raise ValueError(
            f"{method!r} runs in the compiled explicit loop only: backend must be 'numba' "
            f"(or 'auto' with numba installed), got {backend!r}"
        )


def gyroscopic_term_varies(system: LagrangianSystem) -> bool:
    r"""Whether :math:`a(t) = L_v(t, q, 0)` depends on :math:`t`."""
    if system.structure.autonomous or system.t is None:
        return False
    # xreplace, not subs: one pass over each entry (subs makes one per velocity, which
    # is quadratic in n: 4 s for 400 coordinates)
    at_rest = dict.fromkeys(system.v, sp.S.Zero)
    return any(system.t in e.xreplace(at_rest).free_symbols for e in system.pieces.Lv)


def composition_for(system: LagrangianSystem, order: int) -> Composition:
    """``Composition(order)``, or where ``system`` refuses its splitting the order's
    composition of Störmer–Verlet (:data:`~galerkin_vi.method.composition.VERLET_SCHEMES`)."""
    method = Composition(order)
    if method.splitting and composition_obstacle(system, method) is not None:
        return Composition(order, VERLET_SCHEMES[order])
    return method


def loop_path(
    system: LagrangianSystem,
    method: Galerkin | Composition,
    backend: str,
    specialize: bool,
    fixed_point: bool | str,
    banded: Callable[[], bool],
) -> str:
    r"""Which time loop runs: constrained, explicit, linear, separable, varying_mass or newton.

    ``"constrained"`` for every system with constraints (multipliers in the
    stage equations, momentum projected at each step's end; both backends).
    Otherwise, with the compiled backend and ``specialize`` true (``True``, ``"auto"``,
    ``"system"``):

    - ``"explicit"``: degree 1 with two Lobatto points on a separable
      :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)` (constant :math:`M`) is
      Störmer–Verlet in closed form, with :math:`M^{-1}` formed once and no Newton;
    - ``"linear"``: a Lagrangian quadratic in :math:`(q, v)` (constant
      Hessian) has linear stage equations: one LU factorisation per run and
      one triangular solve per step;
    - ``"separable"``: any other :math:`L = \tfrac12 v^TMv + a(t)\cdot v + U(t, q)`
      with constant :math:`M` and forces :math:`f(t, q)`: Newton on the
      stage increments at the implicit quadrature points only
      (:mod:`galerkin_vi.method.stage_form`; the :math:`s - 1` interior nodes for
      collocated Lobatto, the :math:`s` points for Gauss), momenta updated
      in increment form with compensated summation;
    - ``"varying_mass"``: any other :math:`L = \tfrac12 v^TM(t, q)v + a(t, q)\cdot v
      - U(t, q)` (a mass matrix that varies, or velocity couplings :math:`a(q)`;
      forces may depend on :math:`v`), stored dense, with Gauss quadrature of
      ``degree >= 3`` points (Gauss collocation): fixed-point iteration on the
      stage velocities with the exact mass matrix at every stage
      (:mod:`galerkin_vi.method.velocity_stages`), no Jacobian. A step on which the
      iteration contracts too slowly hands the run over to ``"newton"`` from the
      last saved state on;
    - ``"newton"``: the general Newton iteration (also the NumPy backend).

    A :class:`~galerkin_vi.Composition` always takes ``"explicit"`` (the integrator
    has checked :func:`composition_obstacle` and the backend).
    """
    if isinstance(method, Composition):
        return "explicit"
    if system.m:
        return "constrained"
    if backend != "numba" or not specialize:
        return "newton"
    structure = system.structure
    if (
        structure.separable
        and structure.zero_fv
        and method.degree == 1
        and method.quadrature.family == "gauss_lobatto"
        and method.quadrature.npoints == 2
    ):
        return "explicit"
    if structure.quadratic:
        return "linear"
    if has_stage_form(system):
        return "separable"
    if (
        fixed_point
        and structure.quadratic_in_v
        and has_velocity_stages(method)
        and method.degree >= MIN_FIXED_POINT_DEGREE
        and not banded()
    ):
        return "varying_mass"
    return "newton"
