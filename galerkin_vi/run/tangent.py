r"""Runs with the tangent map: variations of the state and of the parameters along a run.

``integrate(..., tangent=..., sensitivity=..., renormalize_every=...)`` runs the
general Newton loop's map with its tangent map (:mod:`galerkin_vi.loops.tangent`):
the same discrete flow as every other loop of the system (the same discrete
Lagrangian; the loops differ in how they solve the stage equations), whose
derivative needs the exact stage Jacobian at the solution. The state is
:math:`x = (q, p)`; the results are

- ``tangent``: :math:`\partial x_k/\partial x_0\, V` at every saved row,
  :math:`V` the identity (``tangent=True``) or the given directions;
- ``sensitivity``: :math:`\partial x_k/\partial\theta` for the parameters listed;
- with ``renormalize_every = m``: the frame orthonormalised every m steps, the
  accumulated :math:`\log r_{jj}` and MEGNO of its first column.

:class:`VariationRequest` is what the user asked for, checked;
:class:`Variations` what a run returns in :attr:`Trajectory.variations`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..errors import DegenerateLagrangianError
from ..loops.abi import LoopResult
from ..numeric import FlatEvaluator
from .outputs import RunOutputs
from .spec import RunSpec, Segment
from .trajectory import Trajectory

__all__ = [
    "LegendreDerivatives",
    "VariationRequest",
    "Variations",
    "legendre_derivatives",
    "members_with_variations",
    "variation_request",
]


@dataclass(frozen=True, eq=False)
class Variations:
    r"""The variations a run carried, one entry per saved row.

    Attributes
    ----------
    tangent : ndarray, shape (rows, 2n, r), or None
        :math:`\Phi_k V`, :math:`\Phi_k = \partial(q_k, p_k)/\partial(q_0, p_0)`
        (renormalised frames with ``renormalize_every``).
    sensitivity : ndarray, shape (rows, 2n, P), or None
        :math:`\partial(q_k, p_k)/\partial\theta`.
    parameters : tuple of sympy.Symbol
        :math:`\theta`, in the order of the sensitivity's columns.
    log_growth : ndarray, shape (rows, r), or None
        :math:`\sum \log r_{jj}` of the renormalisations up to each row.
    megno, megno_mean : ndarray, shape (rows,), or None
        MEGNO :math:`Y(t_k)` of the frame's first column and its running mean.
    """

    tangent: NDArray[np.float64] | None
    sensitivity: NDArray[np.float64] | None
    parameters: tuple
    log_growth: NDArray[np.float64] | None = None
    megno: NDArray[np.float64] | None = None
    megno_mean: NDArray[np.float64] | None = None

    FIELDS = ("tangent", "sensitivity", "log_growth", "megno", "megno_mean")

    def rows(self, index) -> Variations:
        """The variations at the saved rows ``index`` (a slice or an index array)."""
        return replace(self, **{f: _take(getattr(self, f), index) for f in self.FIELDS})

    @staticmethod
    def joined(parts: Sequence[Variations]) -> Variations:
        """One record from consecutive chunks' (each later chunk's first row is the join)."""
        head = parts[0]
        changes = {}
        for f in Variations.FIELDS:
            if getattr(head, f) is not None:
                changes[f] = np.concatenate(
                    [getattr(head, f)] + [getattr(p, f)[1:] for p in parts[1:]]
                )
        return replace(head, **changes)


def _take(array, index):
    return None if array is None else array[index]


@dataclass(frozen=True)
class VariationRequest:
    """What a run is asked to carry: start directions, parameters, renormalisation."""

    directions: NDArray[np.float64]  # (2n, r)
    parameters: tuple
    parameter_index: tuple[int, ...]
    renormalize_every: int
    keep_tangent: bool

    @property
    def sensitivities(self) -> int:
        return len(self.parameters)


def variation_request(system, tangent, sensitivity, renormalize_every) -> VariationRequest | None:
    """Check the run options of the tangent map; None when none is asked for."""
    plain = renormalize_every is None or (type(renormalize_every) is int and renormalize_every == 0)
    if plain and (tangent is None or tangent is False) and sensitivity is None:
        return None  # the common case, checked first: every run pays for this call
    n = system.n
    if renormalize_every is None:
        renormalize_every = 0
    if isinstance(renormalize_every, bool) or not isinstance(renormalize_every, int | np.integer):
        raise TypeError(f"renormalize_every must be an int, got {renormalize_every!r}")
    if renormalize_every < 0:
        raise ValueError(f"renormalize_every must be >= 0, got {renormalize_every}")
    if tangent is None or tangent is False:
        if renormalize_every:
            raise ValueError("renormalize_every needs tangent=True or tangent=V")
        directions = np.zeros((2 * n, 0))
    elif tangent is True:
        directions = np.eye(2 * n)
    else:
        directions = np.array(tangent, dtype=float, ndmin=1)
        if directions.ndim == 1:
            directions = directions[:, None]
        if directions.ndim != 2 or directions.shape[0] != 2 * n or directions.shape[1] == 0:
            raise ValueError(
                f"tangent must be True or an array of shape (2n, r) = ({2 * n}, r), r >= 1 "
                f"(columns: variations of (q0, p0)), got shape {np.shape(tangent)}"
            )
        if not np.all(np.isfinite(directions)):
            raise ValueError("tangent has entries that are not finite")
    parameters, index = _parameters(system, sensitivity)
    if directions.shape[1] == 0 and not parameters:
        return None
    return VariationRequest(
        np.ascontiguousarray(directions), parameters, index, int(renormalize_every),
        keep_tangent=directions.shape[1] > 0,
    )  # fmt: skip


def _parameters(system, sensitivity) -> tuple[tuple, tuple[int, ...]]:
    if sensitivity is None:
        return (), ()
    if isinstance(sensitivity, str | sp.Symbol):
        sensitivity = [sensitivity]
    by_name = {str(s): s for s in system.params}
    chosen = []
    for item in sensitivity:
        symbol = by_name.get(str(item)) if not isinstance(item, sp.Symbol) else item
        if symbol not in system.params:
            raise ValueError(
                f"sensitivity: {item!r} is not a parameter of the system "
                f"(its parameters: {', '.join(map(str, system.params)) or 'none'})"
            )
        if symbol in chosen:
            raise ValueError(f"sensitivity lists {symbol} twice")
        chosen.append(symbol)
    if not chosen:
        raise ValueError("sensitivity is empty: list parameter symbols, or leave it None")
    params = list(system.params)
    return tuple(chosen), tuple(params.index(s) for s in chosen)


class LegendreDerivatives(NamedTuple):
    r""":math:`p = L_v(t, q, v; \theta)` and its derivatives at one state."""

    p: NDArray[np.float64]
    dq: NDArray[np.float64]  # (n, n): d p / d q
    dv: NDArray[np.float64]  # (n, n): d p / d v
    dtheta: NDArray[np.float64]  # (n, P): d p / d theta


def legendre_derivatives(system, parameters: tuple, t, q, v, prm) -> LegendreDerivatives:
    """The Legendre transform and its derivatives in q, v and ``parameters`` at one state
    (generated once per system and parameter list, kept with the system)."""
    n, P = system.n, len(parameters)  # noqa: N806

    def build():
        lv = sp.Matrix(system.pieces.Lv)
        blocks = [lv, lv.jacobian(list(system.q)), lv.jacobian(list(system.v))]
        if parameters:
            blocks.append(lv.jacobian(list(parameters)))
        return FlatEvaluator.from_blocks(blocks, system.arguments)

    evaluator = system.derived.get(("tangent", "legendre derivatives", parameters), build)
    values = np.asarray(evaluator(t, *q, *v, *prm), dtype=float).ravel()
    p, dq, dv, dtheta = np.split(values, np.cumsum([n, n * n, n * n]))
    return LegendreDerivatives(p, dq.reshape(n, n), dv.reshape(n, n), dtheta.reshape(n, P))


def initial_sensitivity(system, parameters: tuple, t0: float, q, v, prm) -> NDArray[np.float64]:
    r""":math:`\partial(q_0, p_0)/\partial\theta` of a start given by its velocity:
    :math:`p_0 = L_v(t_0, q_0, v_0; \theta)`, so the momenta's rows are
    :math:`\partial L_v/\partial\theta` (the positions' are zero)."""
    n = system.n
    out = np.zeros((2 * n, len(parameters)))
    out[n:] = legendre_derivatives(system, parameters, t0, q, v, prm).dtheta
    return out


def parameter_addresses(system, parameters: tuple) -> NDArray[np.int64]:
    """Point-function addresses of the parameter derivatives (slot GRADIENT), compiled once
    per system and parameter list and kept with the system's derived data."""
    from ..codegen.compiled import load_point_functions, point_key
    from ..codegen.spec import parameter_derivative_spec

    def build():
        spec = parameter_derivative_spec(system, parameters)
        return load_point_functions(spec, point_key(spec)).addresses(("point_gradient",))

    return system.derived.get(("parameter_points", parameters), build)


def saved_variations(request, saved: int, T_out, S_out, growth_out, megno_out) -> Variations:  # noqa: N803
    """The :class:`Variations` of the first ``saved`` rows the tangent loop wrote."""
    chaos = growth_out.shape[0] > 0
    return Variations(
        tangent=T_out[:saved] if request.keep_tangent else None,
        sensitivity=S_out[:saved] if request.parameters else None,
        parameters=request.parameters,
        log_growth=growth_out[:saved] if chaos else None,
        megno=megno_out[:saved, 0] if chaos else None,
        megno_mean=megno_out[:saved, 1] if chaos else None,
    )


def tangent_loop_parts(spec: RunSpec) -> tuple:
    """``(loop, before, after)`` of the tangent loop for ``spec``'s system (as
    :meth:`RunSpec.loop_parts`): the constrained one, or the general one."""
    from .. import loops

    if spec.path == "constrained":
        _, before, after = spec.loop_parts("constrained")
        # the tangent loop factorises its dense stage matrix at the solution: no band
        return loops.constrained_tangent_loop, before[:-1], after
    _, before, after = spec.loop_parts("newton")
    return loops.tangent_loop, tangent_couplings(before), after


def explicit_tangent_parts(spec: RunSpec, fnp, prm) -> tuple[tuple, tuple]:
    r"""``(before, after)`` of :func:`galerkin_vi.loops.explicit_tangent_loop` around the
    segment's arguments: the model (addresses, Hessian storage, angles, time switch) and
    the method (:math:`M^{-1}`, its diagonal when :math:`M` is diagonal or an empty
    array, the sub-steps): the products the explicit loop forms, so the states agree
    with a run without variations bit for bit.
    """
    from .segment import substeps

    mass, inverse, diagonal = spec.legendre.inverse_mass(prm)
    if inverse is None:
        raise DegenerateLagrangianError(f"the mass matrix d2L/dv2 = {mass} is singular")
    fn, _, pattern, periodic = spec.model
    diagonal = diagonal if spec.diagonal_mass else np.zeros(0)
    periodic = periodic if periodic.any() else None
    before = (fn, fnp, pattern, periodic, not spec.autonomous)
    return before, (np.ascontiguousarray(inverse), diagonal, *substeps(spec.method))


def check_constant_mass_parameters(system, parameters: tuple) -> None:
    r"""Refuse sensitivities to parameters of the mass matrix on the explicit path.

    There :math:`p = Mv + a(t)`; a parameter of :math:`M` would move the velocity
    of the drift at fixed momentum (:math:`\partial M^{-1}/\partial\theta`), a term
    the explicit tangent loop does not carry.
    """
    mass = sp.Matrix(system.pieces.Lv).jacobian(list(system.v))
    inside = [p for p in parameters if mass.has(p)]
    if inside:
        raise ValueError(
            f"sensitivity to {', '.join(map(str, inside))}: with a Composition the mass "
            "matrix d2L/dv2 must not depend on the parameters differentiated (use a "
            "Galerkin method for them)"
        )


def tangent_couplings(before: tuple) -> tuple:
    """The general loop's model part with its couplings as run-time flags always: the
    tangent loop's work per step dwarfs their tests, and one compiled variant fewer
    per storage kind halves what the warm-up compiles for it."""
    fn, traits, pattern, periodic, couplings = before
    return fn, traits, pattern, periodic, couplings or (False, False)


class TangentRunner:
    """One compiled call of the tangent loop per chunk, the variations carried across."""

    def __init__(
        self, spec: RunSpec, request: VariationRequest, t_origin: float, sensitivity=None
    ) -> None:
        system = spec.system
        self.spec, self.request, self.t_origin = spec, request, t_origin
        n = system.n
        self.T = request.directions.copy()
        self.S = np.zeros((2 * n, request.sensitivities))
        if sensitivity is not None:
            self.S[:] = sensitivity
        self.chaos = np.zeros(self.T.shape[1] + 2)
        if request.renormalize_every:
            # Benettin's frame starts orthonormal; its own lengths are not growth
            frame, upper = np.linalg.qr(self.T)
            self.T = np.ascontiguousarray(frame * np.sign(np.diag(upper)))
        self.fnp = np.zeros(1, dtype=np.int64)
        if system.m and request.parameters:
            inside = [
                p
                for p in request.parameters
                if any(sp.sympify(g).has(p) for g in system.constraints)
            ]
            if inside:
                raise ValueError(
                    f"sensitivity to {', '.join(map(str, inside))}: parameters inside the "
                    "constraints are not supported (their derivatives are not generated)"
                )
        if request.parameters:
            if spec.path == "explicit":
                check_constant_mass_parameters(system, request.parameters)
            self.fnp = parameter_addresses(system, request.parameters)

    def __call__(self, segment: Segment) -> tuple[Trajectory, LoopResult]:
        from ..loops.readiness import ensure_loops

        ensure_loops()
        spec, request = self.spec, self.request
        system = spec.system
        out = RunOutputs.allocate(segment.n_steps, segment.save_every, system.n, spec.periodic)
        rows = out.t.shape[0]
        r, n2 = self.T.shape[1], 2 * system.n
        chaos_rows = rows if request.renormalize_every else 0
        T_out = np.zeros((rows, n2, r))  # noqa: N806
        S_out = np.zeros((rows, n2, self.S.shape[1]))  # noqa: N806
        growth_out = np.zeros((chaos_rows, r))
        megno_out = np.zeros((chaos_rows, 2))
        if spec.path == "explicit":
            from ..loops import explicit_tangent_loop

            s = segment
            before, after = explicit_tangent_parts(spec, self.fnp, s.prm)
            result = LoopResult(
                *explicit_tangent_loop(
                    *before, s.q0, s.p0, s.t0, s.h, s.n_steps, s.save_every, s.prm, *after,
                    self.T, self.S, request.renormalize_every, self.t_origin, self.chaos,
                    out.t, out.q, out.p, out.turns, T_out, S_out, growth_out, megno_out,
                )
            )  # fmt: skip
        else:
            s1 = spec.method.tables.d.shape[0]
            loop, before, after = tangent_loop_parts(spec)
            result = LoopResult(
                *loop(
                    *before, self.fnp, *segment.arguments, *after, self.T, self.S,
                    request.renormalize_every, self.t_origin, self.chaos,
                    np.zeros((0, s1, system.n)), *out.arrays, T_out, S_out, growth_out,
                    megno_out, out.iterations, out.iteration_total,
                )
            )  # fmt: skip
        traj = out.trajectory(
            result.status, result.steps, result.saved, result.worst_residual,
            segment.save_every, system, segment.prm, spec.order,
        )  # fmt: skip
        saved = result.saved
        variations = saved_variations(request, saved, T_out, S_out, growth_out, megno_out)
        return replace(traj, variations=variations), result


def with_event_row(spec: RunSpec, request: VariationRequest, traj: Trajectory) -> Trajectory:
    """``traj`` cut at a terminal event, with the variations at its last row (the event).

    The event's row is the state at the event time :math:`t_e`, between steps k
    and k + 1; its variations are those of the step of length :math:`t_e - t_k`
    from row k: the derivative of the state at the time :math:`t_e` held fixed
    (the event time's own dependence on the start is not included). NaN if that
    step fails.
    """
    var = traj.variations
    rows = len(traj.t)
    if var is None or var.tangent is None and var.sensitivity is None:
        return traj
    k = rows - 2
    kept = var.rows(slice(0, rows))
    tau = float(traj.t[-1] - traj.t[k])
    if tau == 0.0 or rows < 2:
        return replace(traj, variations=var.rows(np.r_[np.arange(rows - 1), k]))
    directions = var.tangent[k] if var.tangent is not None else request.directions
    from .start import initial_state

    prm = traj.params
    q_k, p_k = traj.q[k], traj.p[k]
    q0, p0, v0 = initial_state(spec, q_k, None, p_k, float(traj.t[k]), prm)
    runner = TangentRunner(
        spec, replace(request, directions=np.ascontiguousarray(directions), renormalize_every=0),
        float(traj.t[k]), None if var.sensitivity is None else var.sensitivity[k],
    )  # fmt: skip
    step, result = runner(Segment(q0, p0, v0, float(traj.t[k]), tau, 1, 1, prm))
    last = {}
    for name in Variations.FIELDS:
        whole = getattr(kept, name)
        if whole is None:
            continue
        value = getattr(step.variations, name)
        if result.status != 0:
            value = np.full_like(whole[k], np.nan)  # the step to the event failed
        else:
            value = whole[k] if value is None else value[-1]
        last[name] = np.concatenate([whole[: rows - 1], value[None]])
    return replace(traj, variations=replace(kept, **last))


@dataclass(frozen=True)
class Recording:
    """The states and control points of every step of a segment, for the reverse pass.

    ``q_kept`` are the positions as the loop keeps them (angles reduced), at which
    the reverse pass evaluates; ``trajectory`` has the continuous ones.
    """

    trajectory: Trajectory
    q_kept: NDArray[np.float64]
    stages: NDArray[np.float64]
    result: LoopResult


def recorded_steps(spec: RunSpec, segment: Segment, fnp: NDArray[np.int64]) -> Recording:
    """Run ``segment`` (saving every step) through the tangent loop, recording each step's
    control points; no directions are carried."""
    from ..loops import tangent_loop
    from ..loops.readiness import ensure_loops

    ensure_loops()
    system = spec.system
    n, n_steps = system.n, segment.n_steps
    out = RunOutputs.allocate(n_steps, 1, n, spec.periodic)
    rows = out.t.shape[0]
    stages = np.zeros((n_steps, spec.method.tables.d.shape[0], n))
    _, before, after = spec.loop_parts("newton")
    before = tangent_couplings(before)
    empty = np.zeros((2 * n, 0))
    result = LoopResult(
        *tangent_loop(
            *before, fnp, *segment._replace(save_every=1).arguments, *after, empty, empty.copy(),
            0, segment.t0, np.zeros(2), stages, *out.arrays, np.zeros((rows, 2 * n, 0)),
            np.zeros((rows, 2 * n, 0)), np.zeros((0, 0)), np.zeros((0, 2)), out.iterations,
            out.iteration_total,
        )
    )  # fmt: skip
    traj = out.trajectory(
        result.status, result.steps, result.saved, result.worst_residual, 1, system,
        segment.prm, spec.order,
    )  # fmt: skip
    return Recording(traj, out.q[: result.saved].copy(), stages[: result.steps], result)


def constrained_tangent_spec(spec: RunSpec) -> RunSpec:
    """``spec`` of a constrained system, checked for what its tangent map differentiates:
    constraints that depend on time (their rate's derivative in q is not generated)
    are refused with the reason."""
    system = spec.system
    time = system.time_symbol
    if time is not None and any(sp.sympify(g).has(time) for g in system.constraints):
        raise ValueError(
            "tangent and sensitivity of systems with time-dependent constraints are not "
            "supported: the derivative of the constraint rate dg/dt in q is not generated"
        )
    return spec


def members_with_variations(
    spec: RunSpec, request: VariationRequest, q0s, p0s, v0s, t0: float, h: float,
    n_steps: int, save_every: int, prms, starts=None, workers: int = 1,
) -> list[tuple[Trajectory, LoopResult]]:  # fmt: skip
    """Every member's run with the tangent map, blocks of members in one compiled call
    each (:func:`galerkin_vi.loops.members.tangent_members`), blocks on threads.

    ``starts`` (m, 2n, P): the members' initial sensitivities (None: zero). One call
    per block: runs of at most one chunk (:func:`galerkin_vi.run.chunks.single_call`).
    """
    from concurrent.futures import ThreadPoolExecutor

    from ..loops.members import tangent_members
    from ..loops.readiness import ensure_loops

    ensure_loops()
    system = spec.system
    m, n = q0s.shape
    runner = TangentRunner(spec, request, t0)  # the start frame, checks, addresses
    r, P = runner.T.shape[1], runner.S.shape[1]  # noqa: N806
    frames = np.repeat(runner.T[None], m, axis=0)
    sensitivities = np.zeros((m, 2 * n, P)) if starts is None else np.array(starts, dtype=float)
    chaos = np.zeros((m, r + 2))
    out = RunOutputs.allocate(n_steps, save_every, n, spec.periodic)
    rows = out.t.shape[0]
    chaos_rows = rows if request.renormalize_every else 0
    t_out, q_out, p_out = np.empty((m, rows)), np.empty((m, rows, n)), np.empty((m, rows, n))
    turns_out = np.zeros((m, rows if spec.periodic else 1, n))
    T_out, S_out = np.zeros((m, rows, 2 * n, r)), np.zeros((m, rows, 2 * n, P))  # noqa: N806
    growth_out, megno_out = np.zeros((m, chaos_rows, r)), np.zeros((m, chaos_rows, 2))
    iterations = np.zeros((m, out.iterations.shape[0]), dtype=np.uint8)
    totals, results = np.zeros((m, 1), dtype=np.int64), np.zeros((m, 5))
    loop, before, after = tangent_loop_parts(spec)
    constrained = spec.path == "constrained"
    switches = (None, True) if constrained else (True, None)
    stages = np.zeros((0, spec.method.tables.d.shape[0], n))

    def block(rows_of):
        tangent_members(
            *switches, before, runner.fnp, q0s[rows_of], p0s[rows_of], v0s[rows_of], t0, h,
            n_steps, save_every, prms[rows_of], after, frames[rows_of], sensitivities[rows_of],
            request.renormalize_every, t0, chaos[rows_of], stages, t_out[rows_of],
            q_out[rows_of], p_out[rows_of], turns_out[rows_of], T_out[rows_of],
            S_out[rows_of], growth_out[rows_of], megno_out[rows_of], iterations[rows_of],
            totals[rows_of], results[rows_of],
        )  # fmt: skip

    size = max(1, -(-m // (4 * max(1, workers))))
    blocks = [slice(i, min(i + size, m)) for i in range(0, m, size)]
    if workers > 1 and len(blocks) > 1:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(block, blocks))
    else:
        for rows_of in blocks:
            block(rows_of)
    members = []
    for i in range(m):
        result = LoopResult(*(int(v) for v in results[i, :3]), *results[i, 3:])
        outputs = RunOutputs(t_out[i], q_out[i], p_out[i], turns_out[i], iterations[i],
                             totals[i], spec.periodic)  # fmt: skip
        traj = outputs.trajectory(
            result.status, result.steps, result.saved, result.worst_residual, save_every,
            system, prms[i], spec.order,
        )  # fmt: skip
        saved = result.saved
        variations = saved_variations(
            request, saved, T_out[i], S_out[i], growth_out[i], megno_out[i]
        )
        members.append((replace(traj, variations=variations), result))
    return members
