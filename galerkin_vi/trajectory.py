"""The result of a run: saved states, solver statistics and diagnostics on demand."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from .system import LagrangianSystem

__all__ = ["Trajectory"]


@dataclass(frozen=True, eq=False)
class Trajectory:
    r"""Saved states :math:`(t_k, q_k, p_k)` of a run.

    Attributes
    ----------
    t : ndarray, shape (N,)
    q, p : ndarray, shape (N, n)
        Positions and discrete momenta :math:`p_k = D_2 L_d(q_{k-1}, q_k)`.
    newton_iterations : ndarray of uint8, shape (ceil(steps / save_every),)
        Largest Newton iteration count among the steps between consecutive
        saved states (one entry per step when ``save_every = 1``), the failing
        step of a failed run included.
    total_newton_iterations : int
        Newton iterations of all steps taken.
    n_steps : int
        Steps taken (the failing one included).
    max_residual : float
        Largest stage-equation residual (max-norm) at the last Newton
        iteration of any step.
    system : LagrangianSystem
    params : ndarray
        The parameter values of the run.
    """

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    p: NDArray[np.float64]
    newton_iterations: NDArray[np.uint8]
    max_residual: float
    system: LagrangianSystem
    params: NDArray[np.float64]
    total_newton_iterations: int = 0
    n_steps: int = 0

    def __len__(self) -> int:
        return self.t.shape[0]

    @property
    def mean_newton_iterations(self) -> float:
        """Mean number of Newton iterations per step."""
        return self.total_newton_iterations / self.n_steps if self.n_steps else 0.0

    def _param_dict(self) -> dict[sp.Symbol, float]:
        return dict(zip(self.system.params, self.params, strict=True))

    def velocities(self) -> NDArray[np.float64]:
        r"""Velocities :math:`v_k = (\mathbb FL)^{-1}(q_k, p_k)`.

        These have the method's full order, unlike the polynomial's :math:`\dot q_d`.
        """
        return self.system.inverse_legendre(self.q, self.p, self.t, self._param_dict())

    def energy(self) -> NDArray[np.float64]:
        """Energy :math:`H(t_k, q_k, p_k)` at every saved point."""
        return self.system.hamiltonian(self.q, self.p, self.t, self._param_dict())

    def momentum(self, xi: Sequence[sp.Expr]) -> NDArray[np.float64]:
        r"""Momentum map :math:`\langle p_k, \xi_Q(q_k)\rangle` of the generator ``xi``."""
        return self.system.momentum_map(xi)(self.q, self.p, self.params)
