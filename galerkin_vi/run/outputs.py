"""What a run writes and how its rows are reshaped: the loops' output arrays, rows at
requested times, a chunk without its join row."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import NDArray

from ..reference import numpy as numpy_backend
from .trajectory import Trajectory

__all__ = ["RunOutputs", "at_times", "without_first_row"]


@dataclass
class RunOutputs:
    """The arrays a loop writes into, allocated once per run.

    Angles are saved in [-pi, pi) with the whole turns apart (``turns``; see
    :func:`galerkin_vi.loops.common.save_row`). Iteration counts are kept per
    saved interval, not per step: a 1e7-step run with ``save_every`` stores
    nothing per step.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    p: NDArray[np.float64]
    turns: NDArray[np.float64]
    iterations: NDArray[np.uint8]
    iteration_total: NDArray[np.int64]
    periodic: bool
    #: whether the loop generated for the system wrote them (set by the run)
    generated: bool = False

    @classmethod
    def allocate(cls, n_steps: int, save_every: int, n: int, periodic: bool) -> RunOutputs:
        n_saved = n_steps // save_every + 1 + (1 if n_steps % save_every else 0)
        return cls(
            t=np.empty(n_saved),
            q=np.empty((n_saved, n)),
            p=np.empty((n_saved, n)),
            turns=np.zeros((n_saved if periodic else 1, n)),
            iterations=np.zeros(-(-n_steps // save_every), dtype=np.uint8),
            iteration_total=np.zeros(1, dtype=np.int64),
            periodic=periodic,
        )

    @property
    def arrays(self) -> tuple:
        """(t, q, p, turns), in the loops' argument order."""
        return self.t, self.q, self.p, self.turns

    def trajectory(
        self, status, done, saved, worst, save_every, system, prm, order=None, kernel_path=None
    ) -> Trajectory:
        """The saved rows as a :class:`Trajectory` (angles continued across turns)."""
        q_saved, q_reduced = self.q[:saved], None
        if self.periodic:
            q_reduced = q_saved
            q_saved = numpy_backend.unwrapped(q_saved, self.turns[:saved])
        attempted = int(done + (status != 0))
        return Trajectory(
            t=self.t[:saved],
            q=q_saved,
            q_reduced=q_reduced,
            p=self.p[:saved],
            newton_iterations=self.iterations[: -(-attempted // save_every)],
            total_newton_iterations=int(self.iteration_total[0]),
            n_steps=attempted,
            max_residual=float(worst),
            system=system,
            params=prm,
            order=order,
            kernel_path=kernel_path,
        )


def at_times(traj: Trajectory, times: NDArray) -> Trajectory:
    """``traj`` with rows at ``times`` from its dense output (a run cut short: those reached).

    ``traj.sol`` is anything with ``t_min``, ``t_max``, ``__call__`` and ``momentum``
    (:class:`~galerkin_vi.run.dense.DenseOutput`,
    :class:`~galerkin_vi.run.piecewise.PiecewiseDenseOutput`).
    """
    sol = traj.sol
    reached = times[(times >= sol.t_min) & (times <= sol.t_max)]
    return replace(traj, t=reached, q=sol(reached), p=sol.momentum(reached), q_reduced=None)


def without_first_row(traj: Trajectory) -> Trajectory:
    """The trajectory minus its first saved row (a chunk's start, the previous chunk's end)."""
    return replace(
        traj,
        variations=None if traj.variations is None else traj.variations.rows(slice(1, None)),
        t=traj.t[1:],
        q=traj.q[1:],
        p=traj.p[1:],
        q_reduced=None if traj.q_reduced is None else traj.q_reduced[1:],
    )
