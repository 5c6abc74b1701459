r"""Dense output of a run whose velocity jumps: one interpolant per smooth segment.

A run with impacts stores each impact as two rows at the same time, the
state arriving at it and the state leaving it (:mod:`galerkin_vi.contact`).
Between such pairs the motion is smooth and
:class:`~galerkin_vi.run.dense.DenseOutput` interpolates it at the method's
order; across them it must not (the Hermite interpolant of a velocity jump
rings over its whole stencil). :func:`smooth_segments` cuts the rows at every
pair of equal times, and :class:`PiecewiseDenseOutput` evaluates, at each
time, the segment that holds it, **right-continuous** in physical time: at an
impact time :math:`t_i` it returns the state just after the impact,
:math:`\lim_{t \downarrow t_i}`, the post-impact velocity (in a backward run too,
where that state is the one the run arrives with).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike, NDArray

from .dense import DenseOutput, StateInterpolant, query_times

__all__ = ["PiecewiseDenseOutput", "smooth_segments"]


def smooth_segments(t: NDArray) -> list[slice]:
    """The rows of each smooth segment of a run: cut between consecutive rows of equal time.

    Several impacts at one instant (Newton's cradle) give segments of one row
    there; a run that ends on an impact ends with one.
    """
    t = np.asarray(t, dtype=float)
    if t.size == 0:
        return []
    cuts = np.flatnonzero(t[1:] == t[:-1]) + 1
    bounds = np.concatenate(([0], cuts, [t.size]))
    return [slice(int(a), int(b)) for a, b in zip(bounds[:-1], bounds[1:], strict=True)]


@dataclass(frozen=True, eq=False)
class PiecewiseDenseOutput(StateInterpolant):
    r"""Positions, velocities and momenta of a run with velocity jumps, at any time.

    The interface of :class:`~galerkin_vi.run.dense.DenseOutput` (t-major
    results, vectorised in t), one interpolant per smooth segment.

    Attributes
    ----------
    pieces : tuple of DenseOutput
        The smooth segments in the run's order; a segment of one node (an instant
        between two impacts, or the run's end on an impact) is a ``DenseOutput``
        of one node, evaluated only at its time.
    """

    pieces: tuple[DenseOutput, ...]

    def __post_init__(self) -> None:
        if not self.pieces:
            raise ValueError("a piecewise dense output needs at least one segment")

    @classmethod
    def from_rows(cls, t, q, v, stencil: int, system, params) -> PiecewiseDenseOutput:
        """One piece per :func:`smooth_segments` of the rows ``(t, q, v)``."""
        pieces = tuple(
            DenseOutput(t=t[s], q=q[s], v=v[s], stencil=stencil, system=system, params=params)
            for s in smooth_segments(t)
        )
        return cls(pieces)

    @property
    def t(self) -> NDArray[np.float64]:
        """Every node, in the run's order (an impact's time twice)."""
        return np.concatenate([p.t for p in self.pieces])

    @property
    def q(self) -> NDArray[np.float64]:
        return np.concatenate([p.q for p in self.pieces])

    @property
    def v(self) -> NDArray[np.float64]:
        return np.concatenate([p.v for p in self.pieces])

    @property
    def system(self):
        return self.pieces[0].system

    @property
    def params(self) -> NDArray[np.float64]:
        return self.pieces[0].params

    @property
    def t_min(self) -> float:
        return min(p.t_min for p in self.pieces)

    @property
    def t_max(self) -> float:
        return max(p.t_max for p in self.pieces)

    @cached_property
    def breakpoints(self) -> NDArray[np.float64]:
        """The impact times (where the velocity jumps), ascending, each once."""
        ends = [p.t[-1] for p in self.pieces[:-1]]
        return np.unique(np.asarray(ends, dtype=float))

    @cached_property
    def _order(self) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
        """Pieces sorted by their physical start, the one after an impact last among equals.

        ``searchsorted(starts, t, "right") - 1`` then picks, at an impact time,
        the piece that leaves it forward in time: right-continuity.
        """
        forward = self.pieces[0].t[0] <= self.pieces[-1].t[-1]
        index = np.arange(len(self.pieces))
        if not forward:
            # in physical order the run's pieces come reversed; the run arrives at an
            # impact with its physically later state, which must then sort last
            index = index[::-1]
        starts = np.array([self.pieces[i].t_min for i in index])
        order = np.argsort(starts, kind="stable")
        return index[order], starts[order]

    def state(self, t: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Positions and velocities at ``t`` (scalar or array), t-major; at an impact
        time the state after it (right-continuous)."""
        times, flat = query_times(t, self.t_min, self.t_max)
        index, starts = self._order
        which = index[np.clip(np.searchsorted(starts, flat, side="right") - 1, 0, None)]
        n = self.pieces[0].q.shape[1]
        y, dy = np.empty((flat.size, n)), np.empty((flat.size, n))
        for i in np.unique(which):
            at = which == i
            piece = self.pieces[i]
            if len(piece.t) == 1:  # an instant: its state
                y[at], dy[at] = piece.q[0], piece.v[0]
            else:
                y[at], dy[at] = piece.state(flat[at])
        shape = times.shape + (n,)
        return y.reshape(shape), dy.reshape(shape)
