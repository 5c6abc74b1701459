r"""The loops' calling convention, in one place: what goes in, what comes out.

Every driver of :mod:`galerkin_vi.loops` (the time loops and the member loop of
ensembles) follows it, and the Python side reads the results by these names
only. This module imports no numba: a reader, a test or the NumPy reference
can use it without compiling anything.

**Results.** Every time loop returns the 5-tuple :data:`RESULT_FIELDS`,

.. math::

    (\text{status}, k, r, \max_j \|R_j\|, \|\delta\|)

``status`` one of the ``STATUS_*`` codes below; ``k`` the steps completed;
``r`` the rows saved; the largest residual of an accepted step (0.0 for loops
that solve no nonlinear equations: the linear and explicit loops); the last
Newton increment of a failed step (0.0 after a completed run, NaN where the
loop has no iteration). A failed step keeps the last good state as a saved
row. :class:`LoopResult` names the fields on the Python side; the member
loop writes them into the columns of its ``results`` array in this order.

**Iteration counts.** The implicit loops (general, stage form, linear,
constrained, varying mass) take two counters after their outputs:
``iterations_out[j]`` receives the largest iteration count of the steps
``j s .. (j + 1) s - 1`` (``s = save_every``), ``iteration_total[0]`` is
increased by every step's count. The linear loop counts one iteration per
step (one solve with the factors of its constant Jacobian). The explicit loop
takes no counters.

**Point functions.** A loop receives a system's point functions as an int64
array ``fn`` of addresses, slot :data:`GRADIENT`, :data:`HESSIAN`, ... as
listed in :data:`POINT_SLOTS` (their C signatures are in :mod:`.point`); 0
marks a function the loop does not need. The table is defined by the code
generator (:data:`galerkin_vi.codegen.slots.POINT_SLOTS`), which fills the
array; the constants here are read from it.

**Traits.** The system's structure reaches a loop as ``traits``, an int64
array of :data:`N_TRAITS` entries indexed by :data:`BAND`, :data:`HAS_LQV`,
:data:`HAS_FV` and :data:`AUTONOMOUS` (tested at run time, no compiled
variants); the *switches* that do compile variants are described in
:mod:`.traits`.
"""

from __future__ import annotations

from typing import NamedTuple

from ..codegen.slots import POINT_SLOTS

__all__ = [
    "AUTONOMOUS",
    "BAND",
    "CONSTRAINT",
    "CONTACT",
    "CONSTRAINT_HESS",
    "CONSTRAINT_JAC",
    "CONSTRAINT_RATE",
    "GRADIENT",
    "HAS_FV",
    "HAS_LQV",
    "HESSIAN",
    "LAGRANGIAN",
    "MASS",
    "VELOCITY",
    "N_SLOTS",
    "N_TRAITS",
    "POINT_SLOTS",
    "RESULT_FIELDS",
    "SLIP",
    "STATUS_NEWTON_FAILED",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_SINGULAR",
    "LoopResult",
]

# ----------------------------------------------------------------- results
#: the run reached its last step
STATUS_OK = 0
#: the iteration of the stage equations did not converge
STATUS_NEWTON_FAILED = 1
#: the stage Jacobian (or the mass matrix) is singular
STATUS_SINGULAR = 2
#: NaN or inf appeared in the state
STATUS_NONFINITE = 3

#: what every time loop returns, in this order
RESULT_FIELDS = ("status", "steps", "saved", "worst_residual", "last_increment")


class LoopResult(NamedTuple):
    """A loop's 5-tuple by name (:data:`RESULT_FIELDS`)."""

    status: int
    steps: int
    saved: int
    worst_residual: float
    last_increment: float


# --------------------------------------------------------- point functions
#: L_q + f and L_v
GRADIENT = POINT_SLOTS["point_gradient"]
#: the gradient and the flat second derivatives
HESSIAN = POINT_SLOTS["point_hessian"]
#: L itself
LAGRANGIAN = POINT_SLOTS["lagrangian"]
#: the constraint values g(t, q)
CONSTRAINT = POINT_SLOTS["point_constraint"]
#: dg/dq
CONSTRAINT_JAC = POINT_SLOTS["point_constraint_jacobian"]
#: dg/dt
CONSTRAINT_RATE = POINT_SLOTS["point_constraint_rate"]
#: sum_j lambda_j d2g_j/dq2
CONSTRAINT_HESS = POINT_SLOTS["point_constraint_hessian"]
#: the gradient, L_qv + f_v and L_vv (the varying-mass loop)
MASS = POINT_SLOTS["point_mass"]
#: the velocity v = M^-1 (p - a) and L_q + f at it, from (t, q, p) (the varying-mass
#: loop, when M is solved in closed form); 0 when the system has none
VELOCITY = POINT_SLOTS["point_velocity"]
#: the contacts' gaps, their gradients and Hessians (the time-stepping contact step)
CONTACT = POINT_SLOTS["point_contact"]
#: the stacked slip velocities and their derivatives in q, v and v then q
SLIP = POINT_SLOTS["point_slip"]
N_SLOTS = len(POINT_SLOTS)

# ------------------------------------------------------------------ traits
#: coordinate half-bandwidth w of banded storage (-1 with dense storage)
BAND = 0
#: 1 when d2L/dq dv is not identically zero
HAS_LQV = 1
#: 1 when the forces depend on v (df/dv is written into Fv)
HAS_FV = 2
#: 1 when neither L nor the forces depend on t
AUTONOMOUS = 3
N_TRAITS = 4
