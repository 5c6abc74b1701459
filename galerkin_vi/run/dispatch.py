"""Which run spec and which driver serve a call of an :class:`~galerkin_vi.Integrator`.

The integrator keeps its settings and caches (the run specs, the system's point
functions); this module decides, from those, what a run executes: the reference or the
compiled loops, the loop that carries the tangent map, and the driver (smooth runs,
runs with contacts, the position-only DEL step).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..codegen import SpecSummary
from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem
from .del_step import del_step
from .loop_choice import hand_over
from .smooth import integrate_smooth
from .spec import RunSpec, compiled_run_spec, reference_run_spec
from .tangent import constrained_tangent_spec, variation_request
from .trajectory import Trajectory

__all__ = [
    "IntegratorSettings",
    "integrate_run",
    "position_step",
    "run_spec_for",
    "tangent_spec_for",
]


class IntegratorSettings(Protocol):
    """What the drivers read of an :class:`~galerkin_vi.Integrator` (an interface, so that
    this module, below the integrator, does not import it)."""

    system: LagrangianSystem
    method: Galerkin | Composition
    backend: str
    tol: float
    maxiter: int
    run_spec: RunSpec
    tangent_run_spec: RunSpec
    kernel_path: str


def run_spec_for(
    system: LagrangianSystem,
    method: Galerkin | Composition,
    backend: str,
    path: str,
    tol: float,
    maxiter: int,
    *,
    summary: Callable[[], SpecSummary],
    points: Callable[[], object],
    constant_mass: bool,
    fixed_point: bool | str,
    specialize: bool | str,
) -> RunSpec:
    """The :class:`RunSpec` of an integrator's runs (``Integrator.run_spec``).

    Parameters
    ----------
    system, method, backend, tol, maxiter
        The integrator's (``backend`` resolved).
    path : str
        The loop (``Integrator.kernel_path``).
    summary, points : callable
        Return the system's spec summary and point functions
        (:mod:`galerkin_vi.run.points`); called on the numba backend only, since they
        generate, compile or load code.
    constant_mass : bool
        ``Integrator.uses_constant_mass``.
    fixed_point, specialize
        The integrator's settings: the varying-mass loop's hand-over rule
        (:func:`~galerkin_vi.run.loop_choice.hand_over`, which also depends on whether
        the system's sweep is in closed form), and which generated loops run.

    Returns
    -------
    RunSpec
        The NumPy reference's on that backend, else the compiled loops'.
    """
    if backend != "numba":
        return reference_run_spec(system, method, path, tol, maxiter)
    known = summary()
    return compiled_run_spec(
        system, method, path, tol, maxiter, known, points(), constant_mass=constant_mass,
        hand_over=hand_over(fixed_point, bool(known.explicit_velocity)), specialize=specialize,
    )  # fmt: skip


def tangent_spec_for(
    system: LagrangianSystem,
    method: Galerkin | Composition,
    backend: str,
    tol: float,
    maxiter: int,
    *,
    summary: Callable[[], SpecSummary],
    points: Callable[[], object],
    constant_mass: bool,
    run_spec: Callable[[], RunSpec],
) -> RunSpec:
    """The :class:`RunSpec` of the loop that carries the tangent map
    (``Integrator.tangent_run_spec``).

    A :class:`~galerkin_vi.Composition` takes the shared explicit loop with the point
    Hessian; a constrained system the constrained loop (from ``run_spec()``, the
    integrator's run spec); any other system the general Newton loop, whose stage
    Jacobian the implicit function theorem needs, whatever loop its plain runs take.
    Arguments as for :func:`run_spec_for`.

    Raises
    ------
    ValueError
        On the NumPy backend: the tangent loops are compiled only.
    """
    if backend != "numba":
        raise ValueError("tangent and sensitivity need the numba backend (compiled loops)")
    if isinstance(method, Composition):
        return compiled_run_spec(
            system, method, "explicit", tol, maxiter, summary(), points(),
            constant_mass=constant_mass, hessian=True,
        )  # fmt: skip
    if system.m:
        return constrained_tangent_spec(run_spec())
    return compiled_run_spec(
        system, method, "newton", tol, maxiter, summary(), points(), constant_mass=constant_mass
    )


def integrate_run(
    integrator: IntegratorSettings,
    q0: ArrayLike,
    v0: ArrayLike | None,
    p0: ArrayLike | None,
    *,
    contact_mode: str,
    tangent: bool | ArrayLike | None,
    sensitivity: object,
    renormalize_every: int,
    **run: object,
) -> Trajectory:
    """``integrator.integrate(q0, v0, p0, **arguments)``: the run of a system with
    contacts (:mod:`galerkin_vi.contact`), else a smooth run (:mod:`.smooth`) on the run
    spec, or on the tangent run spec when variations are asked for.

    Parameters
    ----------
    integrator : IntegratorSettings
    q0, v0, p0, contact_mode, tangent, sensitivity, renormalize_every
        As for :meth:`Integrator.integrate`.
    **run
        The other arguments of :meth:`Integrator.integrate`, passed to the driver.

    Raises
    ------
    ValueError
        For a ``contact_mode`` other than ``"auto"`` on a system without contacts, and
        for bad variations (:func:`~galerkin_vi.run.tangent.variation_request`).
    """
    request = variation_request(integrator.system, tangent, sensitivity, renormalize_every)
    if integrator.system.contacts:
        # imported on the first run with contacts: `import galerkin_vi` leaves the contact
        # driver unloaded
        from ..contact.runs import integrate_with_contacts

        traj = integrate_with_contacts(
            integrator, q0, v0, p0, contact_mode=contact_mode, variations=request, **run
        )
    elif contact_mode != "auto":
        raise ValueError(f"contact_mode={contact_mode!r} needs a system with contacts")
    elif request is not None:
        traj = integrate_smooth(integrator.tangent_run_spec, q0, v0, p0, variations=request, **run)
    else:
        traj = integrate_smooth(integrator.run_spec, q0, v0, p0, **run)
    if traj.kernel_path is None:  # runs that do not go through one loop call of a segment
        traj = replace(traj, kernel_path=integrator.kernel_path)
    return traj


def position_step(
    integrator: IntegratorSettings,
    q0: ArrayLike,
    q1: ArrayLike,
    h: float,
    t0: float,
    params: object,
) -> NDArray[np.float64]:
    """``integrator.step_del(q0, q1, h, t0, params)``: :math:`q_{k+1}` of the
    position-only DEL form, by the composition's two moves
    (:mod:`galerkin_vi.run.composed_del`) or the Galerkin method's Newton system
    (:mod:`galerkin_vi.run.del_step`).

    Raises
    ------
    ValueError
        For a constrained system and a Galerkin method: the form has no multipliers.
    """
    system = integrator.system
    if isinstance(integrator.method, Composition):
        from .composed_del import composition_del_step

        prm = system.parameter_vector(params)
        return composition_del_step(integrator, q0, q1, h, t0, prm)
    if system.m:
        raise ValueError(
            "step_del: the position-only DEL form has no multipliers, so it does not "
            "apply to constrained systems; use integrate or step (position-momentum "
            "form with multipliers)"
        )
    prm = system.parameter_vector(params)
    return del_step(
        system, integrator.method.tables, q0, q1, h, t0, prm,
        tol=integrator.tol, maxiter=integrator.maxiter,
    )  # fmt: skip
