"""The frozen description of what a run executes: system, method tables, loop, addresses.

An :class:`~galerkin_vi.Integrator` builds one :class:`RunSpec` on its first
run and keeps it; every run stage below reads it by name. Its fields are what
the compiled loops receive, grouped as the loops' calling convention groups
them (:meth:`RunSpec.loop_parts`):

``loop(*model, q0, p0, v0, t0, h, n_steps, save_every, prm, *method,
t, q, p, turns[, iterations, iteration_total])``

``model`` is the system's part (point-function addresses, traits, banded
pattern, periodic coordinates, and a switch or work space some loops take),
``method`` the method's tables and the iteration's settings, and the rest the
segment to run (:class:`Segment`) and the arrays it writes
(:class:`~galerkin_vi.run.outputs.RunOutputs`). The tuples are unpacked only
at the compiled call (:mod:`galerkin_vi.run.segment`).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
from numpy.typing import NDArray

from ..method.galerkin import Galerkin
from ..method.stage_form import separable_tables
from ..method.velocity_stages import varying_mass_tables
from ..model.system import LagrangianSystem
from .constrained_band import constrained_band
from .loop_choice import EARLY_HAND_OVER, HandOver

__all__ = [
    "LOOP_PATHS",
    "RunSpec",
    "Segment",
    "banded_pattern",
    "compiled_run_spec",
    "loop_traits",
    "periodic_mask",
    "point_function_names",
    "reference_run_spec",
]

#: the loops a run can take, named by what they solve (see ``Integrator.kernel_path``)
LOOP_PATHS = ("explicit", "linear", "separable", "varying_mass", "newton", "constrained")


class Segment(NamedTuple):
    """One compiled call's worth of a run: its start state and grid, as a named tuple
    whose fields are the loops' segment arguments in their order."""

    q0: NDArray[np.float64]
    p0: NDArray[np.float64]
    v0: NDArray[np.float64]
    t0: float
    h: float
    n_steps: int
    save_every: int
    prm: NDArray[np.float64]

    @property
    def arguments(self) -> tuple:
        """The segment's arguments of a loop, in the loops' order."""
        return tuple(self)


@dataclass(frozen=True, eq=False)
class RunSpec:
    """What every run of one integrator shares.

    Attributes
    ----------
    system, method : LagrangianSystem, Galerkin
    path : str
        The loop (one of :data:`LOOP_PATHS`).
    backend : {"numba", "numpy"}
    tol, maxiter : float, int
        The stage iteration's increment tolerance and cap per step.
    model : tuple or None
        ``(fn, traits, pattern, periodic)``: point-function addresses (ints),
        the loops' traits (:mod:`galerkin_vi.loops.traits`), the banded
        pattern or None, the periodic coordinates. None on the NumPy backend.
    diagonal_mass, autonomous, couplings : bool, bool, tuple or None
        Compiled switches: a diagonal constant mass matrix, no time argument,
        the (L_qv, f_v) terms of the general loop (None compiles them out).
    constant_mass : bool
        The stage form starts each step with the constant-mass iteration.
    legendre : PointLegendre or None
        The compiled Legendre transform (:mod:`galerkin_vi.run.legendre`).
    band : tuple or None
        The constrained loop's band order (:mod:`galerkin_vi.run.constrained_band`),
        or None: dense linear algebra.
    hand_over : HandOver
        When the varying-mass loop gives the run up to Newton.
    explicit_steps, stage_steps : callable or None
        The explicit loop generated for this system
        (:mod:`galerkin_vi.codegen.explicit_steps`), and the stage loop generated for it
        and the method (:mod:`galerkin_vi.codegen.method_steps`,
        :mod:`galerkin_vi.codegen.stage_steps`; the varying-mass path's:
        :mod:`galerkin_vi.codegen.velocity_steps`), which the explicit, separable and
        varying-mass paths run in place of the shared ones; None for every other
        system and path.
    stage_steps_when_compiled : bool
        ``specialize="auto"``: a run takes ``stage_steps`` only where it is compiled
        already, else the shared loop (:mod:`galerkin_vi.run.generated_choice`).
    """

    system: LagrangianSystem
    method: Galerkin
    path: str
    backend: str
    tol: float
    maxiter: int
    model: tuple | None
    diagonal_mass: bool
    autonomous: bool
    couplings: tuple | None
    constant_mass: bool
    legendre: Any
    band: tuple | None = None
    hand_over: HandOver = EARLY_HAND_OVER
    explicit_steps: Any = None
    stage_steps: Any = None
    stage_steps_when_compiled: bool = False

    @property
    def order(self) -> int:
        return self.method.order

    @property
    def periodic(self) -> bool:
        return any(self.system.periodic)

    def loop_parts(self, path: str | None = None) -> tuple:
        """``(loop, before, after)`` of a compiled implicit loop (default: this run's).

        ``before`` may hold work space of the loop (the stage form's diagonal
        mass): a new one per call, so that threads running the loop at once
        do not share it.
        """
        from .. import loops  # numba: imported on the first compiled run

        path = self.path if path is None else path
        tb = self.method.tables
        newton = (self.tol, self.maxiter)
        if path == "separable":
            st = separable_tables(self.method)
            # a diagonal M is a compiled variant of its own (None: a full M)
            diagonal = np.zeros(self.system.n) if self.diagonal_mass else None
            after = (tb.b, tb.c, *st.loop_arguments, *newton, self.constant_mass)
            return loops.stage_form_loop, (*self.model, diagonal), after
        if path == "varying_mass":
            stages = varying_mass_tables(self.method)
            after = (*stages.loop_arguments, *newton, *self.hand_over.loop_arguments)
            return loops.varying_mass_loop, self.model, after
        method = (tb.b, tb.c, tb.d, tb.Phi, tb.D, tb.extrapolation)
        if path == "linear":
            return loops.linear_loop, self.model, method
        if path == "constrained":
            before = (*self.model, self.system.m, self.band)
            return loops.constrained_loop, before, (*method, *newton)
        if path == "newton":
            return loops.general_loop, (*self.model, self.couplings), (*method, *newton)
        raise ValueError(f"the {path!r} loop is not called through loop_parts")


def point_function_names(
    path: str, constraints: int, hessian: bool = False, velocity: bool = False
) -> tuple[str, ...]:
    """The compiled point functions a loop reads, in the order of its address slots;
    ``hessian``: the explicit path's with the Hessian too (its tangent map reads it);
    ``velocity``: the system has ``point_velocity`` (the varying-mass loop reads it)."""
    names = ("point_gradient",)
    if path != "explicit" or hessian:
        names += ("point_hessian",)
    if path == "varying_mass":
        names += ("point_mass",) + (("point_velocity",) if velocity else ())
    if constraints:
        names += (
            "point_constraint",
            "point_constraint_jacobian",
            "point_constraint_rate",
            "point_constraint_hessian",
        )
    return names


def loop_traits(summary) -> tuple[int, ...]:
    """The loops' traits of a system (:mod:`galerkin_vi.loops.traits`), from its spec summary.

    A tuple of ints, not an array: passed by value into the loops' inlined helpers,
    where every array argument costs an atomic reference count pair per call.
    """
    from ..loops.traits import AUTONOMOUS, BAND, HAS_FV, HAS_LQV, N_TRAITS

    traits = [0] * N_TRAITS
    traits[BAND] = int(summary.half_bandwidth) if summary.banded else -1
    traits[HAS_LQV] = int(summary.has_Lqv)
    traits[HAS_FV] = int(summary.has_fv)
    traits[AUTONOMOUS] = int(summary.autonomous)
    return tuple(traits)


def banded_pattern(summary) -> NDArray[np.int64] | None:
    """The banded storage's pattern (row, column, position of the transpose), or None for
    dense storage (a compiled switch, :mod:`galerkin_vi.loops.traits`)."""
    if not summary.banded:
        return None
    pattern = np.array(summary.pattern, dtype=np.int64).reshape(-1, 2)
    if not len(pattern):
        return np.zeros((0, 3), dtype=np.int64)
    # position of (b, a) for each (a, b): a search among the entries' keys a n + b, sorted
    width = int(pattern.max(initial=0)) + 1
    keys = pattern[:, 0] * width + pattern[:, 1]
    order = np.argsort(keys, kind="stable")
    transposed = pattern[:, 1] * width + pattern[:, 0]
    at = np.minimum(np.searchsorted(keys[order], transposed), len(keys) - 1)
    found = keys[order][at] == transposed
    position = np.where(found, order[at], 0)
    return np.column_stack([pattern, position]).astype(np.int64)


def periodic_mask(system: LagrangianSystem) -> NDArray[np.bool_]:
    """Which coordinates are angles (saved in [-pi, pi) with their whole turns apart)."""
    return np.array(system.periodic or (False,) * system.n, dtype=np.bool_)


def point_legendre(system, path: str, summary, points):
    """The compiled Legendre transform of a run (:mod:`.legendre`), or None.

    The explicit loop's systems (constant mass) compile only the gradient, which
    with the mass matrix formed once gives both directions; the others read
    :math:`L_v` and :math:`L_{vv}` from the Hessian point function.
    """
    from .legendre import ConstantMassLegendre, PointLegendre

    if path == "explicit":
        gradient = points.compiled.get("point_gradient")
        if gradient is None:
            return None
        n = system.n

        def mass(prm):
            return system.evaluate("Lvv", 0.0, np.zeros(n), np.zeros(n), prm)

        return ConstantMassLegendre(gradient.address, n, mass)
    hessian = points.compiled.get("point_hessian")
    if hessian is None:
        return None
    pattern = summary.pattern if summary.banded else None
    return PointLegendre(hessian.address, system.n, pattern)


def reference_run_spec(system, method, path: str, tol: float, maxiter: int) -> RunSpec:
    """The :class:`RunSpec` of the NumPy reference backend (no compiled parts)."""
    return RunSpec(
        system, method, path, "numpy", tol, maxiter, model=None, diagonal_mass=False,
        autonomous=system.structure.autonomous, couplings=None, constant_mass=False,
        legendre=None,
    )  # fmt: skip


def compiled_run_spec(
    system,
    method,
    path: str,
    tol: float,
    maxiter: int,
    summary,
    points,
    constant_mass: bool,
    hand_over: HandOver = EARLY_HAND_OVER,
    hessian: bool = False,
    specialize: bool | str = True,
) -> RunSpec:
    """The :class:`RunSpec` of the compiled loops: ``summary`` is the system's
    :class:`~galerkin_vi.codegen.SpecSummary`, ``points`` its compiled point functions
    (loaded or compiled here, those the loop of ``path`` reads; with ``hessian``, the
    Hessian too, for the explicit path's tangent map), ``hand_over`` the varying-mass
    loop's rule (:func:`galerkin_vi.run.loop_choice.hand_over`), ``specialize`` the
    integrator's: the explicit path runs the system's generated loop where it has one
    unless it is False, the varying-mass path only with ``"system"``, the separable path
    with ``"system"``, or with ``"auto"`` where it is compiled
    (:mod:`galerkin_vi.run.generated_choice`)."""
    velocity = bool(summary.explicit_velocity)
    names = point_function_names(path, summary.m, hessian, velocity)
    fn = tuple(int(address) for address in points.addresses(names))
    model = (fn, loop_traits(summary), banded_pattern(summary), periodic_mask(system))
    legendre = point_legendre(system, path, summary, points)
    couplings = (summary.has_Lqv, summary.has_fv)
    band = constrained_band(system, method.degree) if path == "constrained" else None
    # the tangent map's explicit loop is the shared one (its states are that loop's)
    explicit = path == "explicit" and not hessian and specialize
    steps = points.generated_loop("explicit_steps") if explicit else None
    if explicit and steps is None and specialize == "system":
        # a small system of repeated terms: their scatter loops unrolled (compiled for
        # seconds, so only on request)
        steps = points.generated_loop("repeated_explicit_steps")
    # the generated stage-form loop iterates the constant-mass fixed point only
    # "auto" takes only the generated loops that take the shared loop's steps bit for bit,
    # so that a run's numbers never depend on whether the system's loop was compiled yet
    separable = path == "separable" and constant_mass and specialize in ("system", "auto")
    stages = None
    if separable:
        stages = points.stage_loop(method.tables.b, method.tables.c, separable_tables(method))
    elif path == "varying_mass" and specialize == "system":
        # the closed-form sweep of Hamilton's equations, written for the system and method
        stages = points.velocity_loop(varying_mass_tables(method))
    return RunSpec(
        system, method, path, "numba", tol, maxiter, model=model,
        diagonal_mass=bool(summary.diagonal_mass), autonomous=bool(summary.autonomous),
        couplings=couplings if any(couplings) else None, constant_mass=constant_mass,
        legendre=legendre, band=band, hand_over=hand_over, explicit_steps=steps,
        stage_steps=stages, stage_steps_when_compiled=specialize == "auto",
    )  # fmt: skip
