"""Physics as a stationary action: boundary-value problems through the discrete action.

The discrete action :math:`S_d = \\sum_k L_d(q_k, q_{k+1}, h)` of a whole path,
with its exact derivatives (:mod:`.elements`), made stationary at once by
Newton's method on a condensed, banded system (:mod:`.condensation`):
:func:`solve_bvp` for two-point boundary-value problems, :func:`solve_periodic`
for periodic orbits (:mod:`.periodic`), :func:`solve_optimal_control` for
optimal control by the discrete Lagrange–d'Alembert principle (:mod:`.control`).
"""

from .bvp import ActionStatus, BoundaryValueResult, solve_bvp
from .control import OptimalControl, solve_optimal_control
from .periodic import OrbitFamily, PeriodicOrbit, follow_family, solve_periodic

__all__ = [
    "ActionStatus",
    "BoundaryValueResult",
    "OptimalControl",
    "OrbitFamily",
    "PeriodicOrbit",
    "follow_family",
    "solve_bvp",
    "solve_optimal_control",
    "solve_periodic",
]
