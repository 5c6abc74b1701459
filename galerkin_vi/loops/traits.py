"""The run-time description of a system's structure that the loops branch on.

Loops are compiled once for every system, so what used to be constants of a
generated module is data: an int64 vector ``traits`` with the slots below,
the sparsity ``pattern`` of the second derivatives (banded storage only) and
the mask ``periodic`` of the angle coordinates. Each test is taken once per
block or per step, never in an innermost loop over coordinates.
"""

from __future__ import annotations

__all__ = [
    "AUTONOMOUS",
    "BAND",
    "DIAGONAL_MASS",
    "HAS_FV",
    "HAS_LQV",
    "HAS_PERIODIC",
    "N_TRAITS",
]

#: coordinate half-bandwidth w of banded storage, or -1 for dense storage
BAND = 0
#: 1 when d2L/dq dv is not identically zero
HAS_LQV = 1
#: 1 when the forces depend on v (df/dv is written into Fv)
HAS_FV = 2
#: 1 when neither L nor the forces depend on t
AUTONOMOUS = 3
#: 1 when d2L/dv2 is a constant diagonal matrix (point masses)
DIAGONAL_MASS = 4
#: 1 when some coordinate is an angle (kept in [-pi, pi), whole turns counted)
HAS_PERIODIC = 5
N_TRAITS = 6
