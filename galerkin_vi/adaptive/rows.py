"""The rows of an adaptive run in chunks: the extended system's states as they come."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from ..model.system import LagrangianSystem
from ..run.trajectory import Trajectory

__all__ = ["ExtendedRows"]


@dataclass
class ExtendedRows:
    """The states of a run assembled from several integrations (save_every = 1).

    Kept as the runs' own arrays, joined once at the end: a list of rows, one
    array object per state, cost more than the steps of a short run.
    """

    tau: list[NDArray[np.float64]]
    q: list[NDArray[np.float64]]
    p: list[NDArray[np.float64]]
    iterations: list[NDArray]
    steps: int = 0
    work: int = 0
    worst: float = 0.0

    @classmethod
    def start(cls, q: NDArray, p: NDArray) -> ExtendedRows:
        return cls(tau=[np.zeros(1)], q=[np.array(q, float)[None, :]],
                   p=[np.array(p, float)[None, :]], iterations=[])  # fmt: skip

    @property
    def last_q(self) -> NDArray[np.float64]:
        return self.q[-1][-1]

    @property
    def last_p(self) -> NDArray[np.float64]:
        return self.p[-1][-1]

    @property
    def last_tau(self) -> float:
        return float(self.tau[-1][-1])

    @property
    def first_clock(self) -> float:
        return float(self.q[0][0, -1])

    def last_clock_before(self) -> float | None:
        """The clock of the row before the last, or None when there is one row only."""
        if len(self.q[-1]) >= 2:
            return float(self.q[-1][-2, -1])
        if len(self.q) >= 2:
            return float(self.q[-2][-1, -1])
        return None

    def extend(self, run: Trajectory, steps: int) -> None:
        """Append the states after the first ``steps`` steps of ``run``."""
        if steps <= 0:
            return
        self.tau.append(run.t[1 : steps + 1].copy())
        self.q.append(run.q[1 : steps + 1].copy())
        self.p.append(run.p[1 : steps + 1].copy())
        self.iterations.append(run.newton_iterations[:steps])
        self.steps += steps

    def trajectory(self, system: LagrangianSystem, save_every: int) -> Trajectory:
        steps = self.steps
        keep = np.unique(np.append(np.arange(0, steps + 1, save_every), steps))
        its = np.concatenate(self.iterations).astype(np.uint8) if self.iterations else np.zeros(0)
        groups = np.arange(0, steps, save_every)
        largest = np.maximum.reduceat(its, groups) if steps else its
        return Trajectory(
            t=np.concatenate(self.tau)[keep],
            q=np.concatenate(self.q)[keep],
            p=np.concatenate(self.p)[keep],
            newton_iterations=largest.astype(np.uint8),
            max_residual=self.worst,
            system=system,
            params=np.zeros(0),
            total_newton_iterations=self.work,
            n_steps=steps,
        )
