r"""Which states of a run to trust: explosive growth per step.

Past its stability limit a method's discrete solution grows by the spectral
radius :math:`\rho` of its step per step; at :math:`h\omega = 50` Störmer–Verlet
multiplies the state by about :math:`(h\omega)^2 = 2500` per step. Past the
domain where the stage equations have the right solution, the iteration may
also "converge" to a spurious one: on a stiff quartic spring at too large h
the positions went :math:`-1.2\cdot10^3, 2.0\cdot10^9, -7.5\cdot10^{27},
4.2\cdot10^{83}` and then overflowed. No state of a physical system that the
step size resolves grows by a factor of :data:`EXPLOSIVE_GROWTH` = 1000 in one
step; the states from the first such step on are not to be trusted.

The size of a state is :math:`\max(|q|_\infty, |p|_\infty)`, measured against
at least :math:`\max(1, \text{size of the initial state})`, so that growth from
near zero (a start at rest) is not taken for an explosion. Between saved
states ``m`` steps apart the test is on the mean factor per step,
:math:`(\text{ratio})^{1/m}`.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

__all__ = ["EXPLOSIVE_GROWTH", "INSTABILITY_GROWTH", "explosive_row"]

#: growth of a state's size in one step beyond which the step is not trusted
EXPLOSIVE_GROWTH = 1e3
#: momenta grown by more than this factor over a run (first against last tenth of the
#: saved states) signal a step size past the stability limit (``InstabilityWarning``)
INSTABILITY_GROWTH = 1e6


def explosive_row(
    q: NDArray[np.float64], p: NDArray[np.float64], steps: NDArray[np.int64]
) -> int | None:
    """The first saved row reached by explosive growth, or None.

    Parameters
    ----------
    q, p : ndarray, shape (N, n)
        Saved positions and momenta.
    steps : ndarray of int, shape (N,)
        The step index of each saved row (increasing).

    Returns
    -------
    int or None
        Index ``r >= 1`` of the first row whose size exceeds that of row
        ``r - 1`` (or the initial scale, whichever is larger) by more than
        ``EXPLOSIVE_GROWTH`` per step on average; rows from ``r`` on are
        not to be trusted.
    """
    if len(q) < 2:
        return None
    with np.errstate(all="ignore"):
        # a bound first: no state beyond 1e3 times the initial scale, no explosion
        # (the full test below cost 60 us per call, a third of a short run's)
        start = max(float(np.max(np.abs(q[0]))), float(np.max(np.abs(p[0]))), 1.0)
        top = max(float(np.max(np.abs(q))), float(np.max(np.abs(p))))
        if top <= EXPLOSIVE_GROWTH * start:
            return None
        size = np.maximum(np.max(np.abs(q), axis=1), np.max(np.abs(p), axis=1))
        floor = max(1.0, float(size[0])) if np.isfinite(size[0]) else 1.0
        base = np.maximum(size[:-1], floor)
        gaps = np.maximum(np.diff(steps), 1)
        per_step = np.log(size[1:] / base) / gaps
        # NaN or inf sizes are explosive too
        explosive = ~(per_step <= np.log(EXPLOSIVE_GROWTH))
    rows = np.flatnonzero(explosive)
    return int(rows[0]) + 1 if rows.size else None
