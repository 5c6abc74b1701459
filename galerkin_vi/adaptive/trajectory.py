"""The result of an adaptive run: states at physical times that are not equally spaced."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from ..run.trajectory import Trajectory

__all__ = ["AdaptiveTrajectory"]


@dataclass(frozen=True, eq=False)
class AdaptiveTrajectory(Trajectory):
    r"""A :class:`Trajectory` at physical times that are not equally spaced.

    Attributes
    ----------
    tau : ndarray, shape (N,)
        The fictitious times of the saved states (equally spaced but for a
        landing step on ``t_final``; at a terminal event and at the rows of
        ``t_eval``, interpolated).
    clock_momentum : ndarray, shape (N,)
        :math:`p_z = \zeta - g`, 0 in exact arithmetic; its size is the
        round-off of the clock's Noether momentum.
    """

    tau: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    clock_momentum: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))

    @property
    def step_sizes(self) -> NDArray[np.float64]:
        """Physical time between consecutive saved states."""
        return np.diff(self.t)
