"""One compiled call: a :class:`~galerkin_vi.run.spec.Segment` of a run through its loop.

The loop is the one :attr:`RunSpec.path <galerkin_vi.run.spec.RunSpec>` names,
or the NumPy reference on that backend. Every path returns the loops' one
result shape, :class:`LoopResult`. A varying-mass run that the fixed-point
iteration gives up on is handed over to the general Newton loop from its last
saved row, a run of a system's generated stage-form loop to the shared one
(:func:`continue_from_last_row`); their failures are the run's.
"""

from __future__ import annotations

import numpy as np

from ..errors import DegenerateLagrangianError
from ..loops.abi import STATUS_NEWTON_FAILED, LoopResult
from ..method.composition import VERLET_SUBSTEPS, Composition
from ..reference import numpy as numpy_backend
from ..reference import numpy_constrained
from .generated_choice import choose_generated, kernel_path
from .outputs import RunOutputs
from .spec import RunSpec, Segment
from .trajectory import Trajectory

__all__ = ["LoopResult", "run_once", "run_segment", "substeps"]

#: Störmer–Verlet as the one-stage composition (drift, kicks, nodes); writable, as numba types
#: a read-only array as another compiled variant
_VERLET = tuple(table.copy() for table in VERLET_SUBSTEPS.loop_tables)
#: the sub-steps of each composition run so far (a copy per call would cost a microsecond)
_COMPOSED: dict = {}


def run_once(spec: RunSpec, segment: Segment) -> tuple[Trajectory, LoopResult]:
    """The loop's trajectory of ``segment`` as it came (failures included) and its result."""
    system = spec.system
    out = RunOutputs.allocate(segment.n_steps, segment.save_every, system.n, spec.periodic)
    result = run_segment(spec, segment, out)
    traj = out.trajectory(
        result.status, result.steps, result.saved, result.worst_residual, segment.save_every,
        system, segment.prm, spec.order, kernel_path(spec.path, out.generated),
    )  # fmt: skip
    return traj, result


def run_segment(spec: RunSpec, segment: Segment, out: RunOutputs) -> LoopResult:
    """Run ``segment`` through the loop of ``spec`` (compiled, or the NumPy reference)."""
    counters = (out.iterations, out.iteration_total)
    if spec.backend != "numba":
        solver = numpy_constrained if spec.path == "constrained" else numpy_backend
        return LoopResult(
            *solver.integrate(
                spec.system, spec.method.tables, *segment.arguments, spec.tol, spec.maxiter,
                *out.arrays, *counters,
            )
        )  # fmt: skip
    from ..loops.readiness import ensure_loops

    ensure_loops()
    if spec.path == "explicit":
        return _explicit(spec, segment, out)
    loop, before, after = spec.loop_parts()
    shared = (*before, *segment.arguments, *after, *out.arrays, *counters)
    # the generated loop takes the shared loop's arguments less its work space (before)
    arguments = shared[len(before) :]
    steps = spec.stage_steps
    if steps is not None and spec.stage_steps_when_compiled:
        steps = choose_generated(steps, arguments, segment.n_steps, loop, shared)
    out.generated = steps is not None
    result = LoopResult(*(steps(*arguments) if steps is not None else loop(*shared)))
    if spec.path == "separable" and steps is not None:
        if result.status == STATUS_NEWTON_FAILED:
            # a step the constant-mass fixed point cannot take: the shared loop's Newton
            return continue_from_last_row(spec, segment, out, result, "separable")
        return result
    if spec.path == "varying_mass" and result.status != 0:
        return continue_from_last_row(spec, segment, out, result, "newton")
    return result


def substeps(method) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    r"""The explicit loop's sub-steps of ``method``: drifts :math:`(a_i)`, kicks
    :math:`(\beta^-_i)`, :math:`(\beta^+_i)` and ends :math:`(c_i)`
    (:class:`~galerkin_vi.method.composition.SubSteps`); Störmer–Verlet
    (``Galerkin(1)``) is ``([1.0], [0.5], [0.5], [1.0])``."""
    if isinstance(method, Composition):
        if method not in _COMPOSED:
            # writable copies: the loops are compiled for writable arrays
            _COMPOSED[method] = tuple(t.copy() for t in method.substeps().loop_tables)
        return _COMPOSED[method]
    return _VERLET


def _explicit(spec: RunSpec, segment: Segment, out: RunOutputs) -> LoopResult:
    """A composition of Störmer–Verlet (one stage: itself) with :math:`M^{-1}` formed once
    per parameter vector (a diagonal M as its diagonal only), kept by the run spec's
    Legendre transform; the system's generated explicit loop where it has one."""
    mass, inverse, diagonal = spec.legendre.inverse_mass(segment.prm)
    if inverse is None:
        raise DegenerateLagrangianError(f"the mass matrix d2L/dv2 = {mass} is singular")
    s = segment
    if spec.explicit_steps is not None:
        return LoopResult(
            *spec.explicit_steps(
                s.q0, s.p0, s.t0, s.h, s.n_steps, s.save_every, s.prm, inverse,
                *substeps(spec.method), *out.arrays,
            )
        )  # fmt: skip
    from ..loops import explicit_loop

    fn, _, _, periodic = spec.model
    # switches (loops.traits): a run-time test of either costs a quarter of a step here
    periodic = periodic if periodic.any() else None
    diagonal = diagonal if spec.diagonal_mass else None
    time_dependent = None if spec.autonomous else True
    return LoopResult(
        *explicit_loop(
            fn, periodic, time_dependent, s.q0, s.p0, s.t0, s.h, s.n_steps, s.save_every, s.prm,
            inverse, diagonal, *substeps(spec.method), *out.arrays,
        )
    )  # fmt: skip


def continue_from_last_row(
    spec: RunSpec, segment: Segment, out: RunOutputs, result: LoopResult, path: str
) -> LoopResult:
    """Continue a run a fixed-point loop gave up on with the loop of ``path``, from step k.

    The varying-mass loop's fixed-point iteration (continued by the general
    loop, ``path="newton"``) and the generated stage-form loop's (continued by
    the shared stage-form loop, ``"separable"``, which switches to Newton there)
    stop before a step on which they contract too slowly (or fail), and leave
    the state before it as their last row, due for saving or not. The loop of
    ``path`` runs the rest of the segment from there in one call (a join like a
    chunk's: the compensation bits and the extrapolated stages start afresh),
    saving every step into work arrays (a segment is at most a chunk long); the
    rows due are copied into the run's. These are the steps, and the one call,
    that the run saving every step takes, so a run with ``save_every = k`` saves
    every k-th of its rows bit for bit. Its failures are the run's.
    """
    s = segment
    k, row = result.steps, result.saved - 1
    t_k = s.t0 + k * s.h
    q_row, p_row = out.q[row].copy(), out.p[row].copy()
    # the velocities only start Newton's first guess: the compiled transform, the
    # NumPy one where there is none
    v_row = None
    if spec.legendre is not None:
        v_row = spec.legendre.velocities_of_quadratic(t_k, q_row, p_row, s.prm)
    if v_row is None:
        prm_map = dict(zip(spec.system.params, s.prm, strict=True))
        v_row = spec.system.inverse_legendre(q_row, p_row, t_k, prm_map)
    tail = RunOutputs.allocate(s.n_steps - k, 1, spec.system.n, out.periodic)
    loop, before, after = spec.loop_parts(path)
    status, done, saved, worst, increment = loop(
        *before, q_row, p_row, np.asarray(v_row, dtype=float), t_k, s.h, s.n_steps - k, 1,
        s.prm, *after, *tail.arrays, tail.iterations, tail.iteration_total,
    )  # fmt: skip
    steps = k + np.arange(saved)  # tail row j is step k + j
    due = (steps % s.save_every == 0) | (steps == s.n_steps)
    due[-1] |= status != 0  # a failure keeps its last good state, as the loops do
    rows = slice(row, row + int(due.sum()))
    out.t[rows] = s.t0 + steps[due] * s.h
    out.q[rows], out.p[rows] = tail.q[:saved][due], tail.p[:saved][due]
    if out.periodic:
        out.turns[rows] = tail.turns[:saved][due] + out.turns[row]
    # iterations per saved interval: the tail's steps join the intervals they fall in
    if k % s.save_every == 0:
        out.iterations[k // s.save_every :] = 0  # the interval holds only the step not taken
    attempted = done + (status != 0)
    np.maximum.at(
        out.iterations, (k + np.arange(attempted)) // s.save_every, tail.iterations[:attempted]
    )
    out.iteration_total[0] += tail.iteration_total[0]
    return LoopResult(status, k + done, rows.stop, max(result.worst_residual, worst), increment)
