"""The settings of the contact step's primal–dual interior point, shared by its two forms.

The NumPy step (:mod:`galerkin_vi.contact.time_stepping`, the reference) and the
compiled one (:mod:`galerkin_vi.loops.contact_step`) take the same iterates with
these tolerances; this module imports nothing, so that either reads them.
"""

from __future__ import annotations

__all__ = [
    "ACCEPTABLE",
    "CENTRING",
    "COMPLEMENTARITY",
    "DEGENERATE",
    "FRACTION_TO_BOUNDARY",
    "LINE_SEARCH",
    "MAX_ITERATIONS",
    "POLISHED",
    "RESIDUAL",
    "TO_BOUNDARY",
]

#: interior-point iterations per step at most
MAX_ITERATIONS = 50
#: largest entry of z o y at which a step is solved, relative to the coordinates' scale
#: max(1, |q_k|) (a gap of a resting contact to round-off)
COMPLEMENTARITY = 1e-13
#: largest block duality gap z_b . y_b, relative likewise, at which a step whose iteration
#: stalls (degenerate contacts: redundant points of a face at rest) is accepted (the
#: issue's bound)
ACCEPTABLE = 1e-10
#: the least centring target kappa, relative to the complementarity's tolerance
CENTRING = 1e-3
#: a cone's Jordan determinant relative to its scalar squared below which the
#: Nesterov-Todd scaling of its block is not formed (its rows stay unscaled)
DEGENERATE = 1e-26
#: relative residual of the stage and slack equations at which a step is solved
RESIDUAL = 1e-12
#: the fraction of the way to the cones' boundary a step goes at least; at most Dojo's
#: 1 - max(residual, complementarity)^2, but not beyond 1 - TO_BOUNDARY (Dojo's rounds
#: to 1 at these tolerances and lands the iterates on the boundary, where the
#: Nesterov-Todd scaling cannot be formed)
FRACTION_TO_BOUNDARY = 0.995
TO_BOUNDARY = 1e-8
#: relative residual below which a solved step takes no polishing Newton step
POLISHED = 1e-15
#: halvings of a step at most in the line search
LINE_SEARCH = 10
