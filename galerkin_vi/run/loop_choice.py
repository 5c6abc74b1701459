"""Which compiled loop a run takes, from the structure the analysis found."""

from __future__ import annotations

from collections.abc import Callable

from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..method.stage_form import has_stage_form
from ..method.velocity_stages import MIN_FIXED_POINT_DEGREE, has_velocity_stages
from ..model.system import LagrangianSystem

__all__ = ["composition_obstacle", "loop_path"]


def composition_obstacle(system: LagrangianSystem) -> str | None:
    r"""Why a :class:`~galerkin_vi.Composition` of Störmer–Verlet cannot run on ``system``,
    or None when it can.

    The sub-steps are explicit only for :math:`L = \tfrac12 v^TMv + a(t)\cdot v - V(t, q)`
    with constant :math:`M` and forces :math:`f(t, q)`, without constraints or contacts.
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
    return None


def loop_path(
    system: LagrangianSystem,
    method: Galerkin | Composition,
    backend: str,
    specialize: bool,
    fixed_point: bool,
    banded: Callable[[], bool],
) -> str:
    r"""Which time loop runs: constrained, explicit, linear, separable, varying_mass or newton.

    ``"constrained"`` for every system with constraints (multipliers in the
    stage equations, momentum projected at each step's end; both backends).
    Otherwise, with the compiled backend and ``specialize=True`` (default):

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
