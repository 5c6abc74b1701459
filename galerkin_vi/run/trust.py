r"""Which states of a run to trust: explosive growth per step, instability over a run.

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

import math
import warnings
from collections.abc import Callable
from dataclasses import replace

import numpy as np
from numpy.typing import NDArray

from ..errors import InstabilityWarning
from .status import RunStatus
from .trajectory import Trajectory

__all__ = [
    "EXPLOSIVE_GROWTH",
    "INSTABILITY_GROWTH",
    "explosive_row",
    "momenta_grew",
    "trusted",
    "warn_if_unstable",
    "within_growth_bound",
]

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
        # (the full test below costs about 60 us per call, a third of a short run)
        if within_growth_bound(q[:1], p[:1], q, p):
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


def within_growth_bound(q_first, p_first, q, p) -> bool | NDArray[np.bool_]:
    r"""Whether no state of ``q, p`` exceeds ``EXPLOSIVE_GROWTH`` times the first's size.

    The size of a state is :math:`\max(|q|_\infty, |p|_\infty)`, the first's at
    least 1. Explosive growth does not calm down again (it overflows), so a run
    within the bound needs no row-by-row test. The last axis is the
    coordinates; leading axes broadcast: ``q_first`` (..., 1, n) against
    ``q`` (..., N, n) answers per member of an ensemble. NaN is never within.
    """
    if np.ndim(q) == 2:
        return _one_run_within(q_first, p_first, q, p)
    start = np.maximum(np.abs(q_first).max(axis=(-2, -1)), np.abs(p_first).max(axis=(-2, -1)))
    top = np.maximum(np.abs(q).max(axis=(-2, -1)), np.abs(p).max(axis=(-2, -1)))
    return top <= EXPLOSIVE_GROWTH * np.maximum(start, 1.0)


def _one_run_within(q_first, p_first, q, p) -> bool:
    """:func:`within_growth_bound` of one run (2-D arrays), paid by every short run.

    Small states go through Python floats (1 us against 5 us for the ufunc
    reductions); a NaN or an inf makes the sum of the sizes not finite, so the
    answer is False whatever ``max`` makes of the NaN (as it is for states so large
    that their sum overflows: the caller then looks row by row).
    """
    if q.size + p.size > 64:
        # np.maximum, not max: a NaN is kept (and never within)
        start = float(np.maximum(np.abs(q_first).max(), np.abs(p_first).max()))
        top = np.maximum(np.abs(q).max(), np.abs(p).max())
        return bool(math.isfinite(start) and top <= EXPLOSIVE_GROWTH * max(1.0, start))
    first = [abs(x) for x in q_first.ravel().tolist() + p_first.ravel().tolist()]
    rest = [abs(x) for x in q.ravel().tolist() + p.ravel().tolist()]
    if not math.isfinite(sum(first) + sum(rest)):
        return False
    return max(rest, default=0.0) <= EXPLOSIVE_GROWTH * max(1.0, *first)


def momenta_grew(p: NDArray[np.float64]) -> bool | NDArray[np.bool_]:
    """Whether the momenta of the last tenth of the rows exceed those of the first tenth
    by more than ``INSTABILITY_GROWTH`` (``p``: (N, n), or (m, N, n) for m members).

    At least two rows per tenth: a start at rest has p_0 = 0, and any motion is not
    growth.
    """
    N = p.shape[-2]
    tenth = max(2, N // 10)
    early = np.abs(p[..., :tenth, :]).max(axis=(-2, -1))
    late = np.abs(p[..., -tenth:, :]).max(axis=(-2, -1))
    grew = (early > 0.0) & (late > INSTABILITY_GROWTH * early)
    return bool(grew) if np.ndim(grew) == 0 else grew


def checks_instability(system, rows: int) -> bool:
    """Whether a run of ``rows`` saved states of ``system`` is checked for instability:
    autonomous unforced systems (whose energy cannot legitimately grow), 10 rows or more."""
    structure = system.structure
    return rows >= 10 and not structure.forced and structure.autonomous


def warn_if_unstable(traj: Trajectory, h: float, stacklevel: int = 4) -> None:
    """Warn (:class:`InstabilityWarning`) when the momenta grew by more than
    ``INSTABILITY_GROWTH`` over the run (:func:`momenta_grew`).

    The growth is a ratio, so it does not depend on units (a body falling from
    rest gains momentum linearly, a factor of about 10, not 1e6).
    """
    if not checks_instability(traj.system, len(traj)) or not momenta_grew(traj.p):
        return
    tenth = max(2, len(traj) // 10)
    early = float(np.max(np.abs(traj.p[:tenth])))
    late = float(np.max(np.abs(traj.p[-tenth:])))
    warnings.warn(
        f"the momenta grew by a factor {late / max(early, 1e-300):.3g} over the run: "
        f"h = {h:.3g} is probably past the method's stability limit (the discrete "
        "solution grows exponentially); use a smaller h",
        InstabilityWarning,
        stacklevel=stacklevel,
    )


def trusted(
    traj: Trajectory, h: float, failure: str | None, rerun: Callable[[int, int], Trajectory]
) -> Trajectory:
    """``traj`` without the states reached by explosive growth.

    Growth is judged per step whatever ``save_every`` is: the steps between
    the saved rows where it shows (or, after a failure, between the last
    two) are run again one by one by ``rerun(row, m)`` (the m steps from saved
    row ``row``, every one saved, failures included), at most ``save_every``
    steps.
    """
    if len(traj) < 2:
        return traj
    if failure is None and within_growth_bound(traj.q[:1], traj.p[:1], traj.q[-1:], traj.p[-1:]):
        return traj
    steps = np.round((traj.t - traj.t[0]) / h).astype(np.int64)
    cut = explosive_row(traj.q, traj.p, steps)
    end = cut if cut is not None else len(traj) - 1 if failure is not None else None
    if end is None:
        return traj
    gap = int(steps[end] - steps[end - 1])
    if gap > 1:
        fine = rerun(end - 1, gap)
        inner = explosive_row(fine.q, fine.p, np.arange(len(fine)))
        if inner is not None:
            # the last trusted state lies between saved rows end - 1 and end
            kept = slice(0, end)
            # q_reduced dropped: the row appended below has none (diagnostics reduce)
            head = replace(
                traj, t=traj.t[kept], q=traj.q[kept], p=traj.p[kept], q_reduced=None,
                variations=_rows_of(traj.variations, kept),
            )  # fmt: skip
            # (a run carrying the tangent keeps its saved rows only: the fine rerun has none)
            if inner > 1 and traj.variations is None:
                head = replace(
                    head,
                    t=np.append(head.t, fine.t[inner - 1]),
                    q=np.vstack([head.q, fine.q[inner - 1]]),
                    p=np.vstack([head.p, fine.p[inner - 1]]),
                )
            step = int(steps[end - 1]) + inner
            return _untrusted(head, len(head), step, fine, inner, h, failure)
    if cut is None:
        return traj
    return _untrusted(traj, cut, int(steps[cut]), traj, cut, h, failure)


def _untrusted(traj, keep, step, rows, r, h, failure) -> Trajectory:
    """``traj`` cut to its first ``keep`` rows, flagged unstable from ``step`` on."""
    with np.errstate(all="ignore"):
        size = np.maximum(np.max(np.abs(rows.q[r])), np.max(np.abs(rows.p[r])))
        before = max(1.0, np.max(np.abs(rows.q[r - 1])), np.max(np.abs(rows.p[r - 1])))
    # named like a loop failure: by the step's start, the last state kept
    t_step = traj.t[0] + (step - 1) * h
    message = (
        f"step {step - 1} (t = {t_step:.6g}, h = {h:.3g}): {RunStatus.UNSTABLE.cause} (the "
        f"state grew from size {before:.3g} to {size:.3g} in one step); the states from "
        "there on are dropped"
    )
    if failure is not None:
        message += f", and then {failure}"
    message += ". Try a smaller h."
    kept = slice(0, keep)
    return replace(
        traj,
        t=traj.t[kept],
        q=traj.q[kept],
        p=traj.p[kept],
        q_reduced=None if traj.q_reduced is None else traj.q_reduced[kept],
        variations=_rows_of(traj.variations, kept),
        status=RunStatus.UNSTABLE,
        message=message,
    )


def _rows_of(variations, kept):
    """The tangent-map record at the rows kept (None without one)."""
    return None if variations is None else variations.rows(kept)
