"""One compiled call: a :class:`~galerkin_vi.run.spec.Segment` of a run through its loop.

The loop is the one :attr:`RunSpec.path <galerkin_vi.run.spec.RunSpec>` names,
or the NumPy reference on that backend. Every path returns the loops' one
result shape, :class:`LoopResult`. A varying-mass run that the fixed-point
iteration gives up on is handed over to the general Newton loop from its last
saved row (:func:`newton_from_last_row`); its failures are the run's.
"""

from __future__ import annotations

import numpy as np

from ..errors import DegenerateLagrangianError
from ..loops.abi import LoopResult
from ..model.system import is_regular
from ..reference import numpy as numpy_backend
from ..reference import numpy_constrained
from .outputs import RunOutputs
from .spec import RunSpec, Segment
from .trajectory import Trajectory

__all__ = ["LoopResult", "run_once", "run_segment"]


def run_once(spec: RunSpec, segment: Segment) -> tuple[Trajectory, LoopResult]:
    """The loop's trajectory of ``segment`` as it came (failures included) and its result."""
    system = spec.system
    out = RunOutputs.allocate(segment.n_steps, segment.save_every, system.n, spec.periodic)
    result = run_segment(spec, segment, out)
    traj = out.trajectory(
        result.status, result.steps, result.saved, result.worst_residual, segment.save_every,
        system, segment.prm, spec.order,
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
    result = LoopResult(*loop(*before, *segment.arguments, *after, *out.arrays, *counters))
    if spec.path == "varying_mass" and result.status != 0:
        return newton_from_last_row(spec, segment, out, result)
    return result


def _explicit(spec: RunSpec, segment: Segment, out: RunOutputs) -> LoopResult:
    """Störmer–Verlet with :math:`M^{-1}` formed once (a diagonal M as its diagonal only)."""
    from ..loops import explicit_loop

    system, n = spec.system, spec.system.n
    mass = system.evaluate("Lvv", segment.t0, segment.q0, np.zeros(n), segment.prm).reshape(n, n)
    if not is_regular(mass):
        raise DegenerateLagrangianError(f"the mass matrix d2L/dv2 = {mass} is singular")
    fn, _, _, periodic = spec.model
    # switches (loops.traits): a run-time test of either costs a quarter of a step here
    periodic = periodic if periodic.any() else None
    inverse = np.linalg.inv(mass)
    # a writable copy: numba types a read-only view as another (compiled) variant
    diagonal = np.diag(inverse).copy() if spec.diagonal_mass else None
    time_dependent = None if spec.autonomous else True
    s = segment
    return LoopResult(
        *explicit_loop(
            fn, periodic, time_dependent, s.q0, s.p0, s.t0, s.h, s.n_steps, s.save_every, s.prm,
            inverse, diagonal, *out.arrays,
        )
    )  # fmt: skip


def newton_from_last_row(
    spec: RunSpec, segment: Segment, out: RunOutputs, result: LoopResult
) -> LoopResult:
    """Continue a run the varying-mass loop gave up on with Newton, from its last saved row.

    The fixed-point iteration stops before a step on which it contracts too
    slowly (or fails); the general loop then runs the rest from the last
    saved state (a join like a chunk's: the compensation bits and the
    extrapolated stages start afresh). Its failures are the run's.
    """
    from .. import loops

    s = segment
    row = result.saved - 1
    start = row * s.save_every
    t_row = s.t0 + start * s.h
    q_row, p_row = out.q[row].copy(), out.p[row].copy()
    turns = out.turns[row].copy() if out.periodic else None
    # the velocities only start Newton's first guess: the compiled transform, the
    # NumPy one where there is none
    v_row = None
    if spec.legendre is not None:
        v_row = spec.legendre.velocities_of_quadratic(t_row, q_row, p_row, s.prm)
    if v_row is None:
        prm_map = dict(zip(spec.system.params, s.prm, strict=True))
        v_row = spec.system.inverse_legendre(q_row, p_row, t_row, prm_map)
    out.iterations[row:] = 0
    turns_tail = out.turns[row:] if out.periodic else out.turns
    tail = (out.t[row:], out.q[row:], out.p[row:], turns_tail)
    _, before, after = spec.loop_parts("newton")
    status, done, saved_tail, worst_tail, increment = loops.general_loop(
        *before, q_row, p_row, np.asarray(v_row, dtype=float), t_row, s.h,
        s.n_steps - start, s.save_every, s.prm, *after, *tail, out.iterations[row:],
        out.iteration_total,
    )  # fmt: skip
    if turns is not None:
        out.turns[row : row + saved_tail] += turns
    # the times as the run's own clock gives them (t0 + k h, not (t0 + start h) + j h)
    steps = np.minimum(np.arange(saved_tail) * s.save_every, done)
    out.t[row : row + saved_tail] = s.t0 + (start + steps) * s.h
    return LoopResult(
        status, start + done, row + saved_tail, max(result.worst_residual, worst_tail), increment
    )
