"""The result of a run: saved states, solver statistics and diagnostics on demand."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..model.system import LagrangianSystem
from .dense import DenseOutput, stencil_nodes
from .piecewise import PiecewiseDenseOutput
from .status import RunStatus, SolverResult

__all__ = ["Trajectory"]


@dataclass(frozen=True, eq=False)
class Trajectory(SolverResult):
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
    q_reduced : ndarray, shape (N, n), or None
        The positions as the integrator keeps them, angles
        (``system.periodic``) in :math:`[-\pi, \pi)`; ``None`` without angles.
        ``q`` holds the continuous angles, rounded to the precision of their
        size; diagnostics evaluate at ``q_reduced``.
    status : RunStatus
        Why the run stopped, with :func:`scipy.integrate.solve_ivp`'s signs:
        0 it reached its end, 1 a terminal event stopped it, negative a failure
        (see :class:`~galerkin_vi.run.status.RunStatus`).
    message : str
        The status in words; for a failure, the step, time and cause.
    order : int or None
        The method's predicted global order (sets the dense output's stencil).
    sol : DenseOutput or None
        Positions, velocities and momenta at any time of the run
        (``integrate(..., dense_output=True)``; see :mod:`galerkin_vi.run.dense`).
    t_events, q_events, v_events, p_events : list of ndarray or None
        With ``integrate(..., events=...)``: per event, the times (m,) and
        the positions, velocities and momenta (m, n) of its occurrences.
    variations : Variations or None
        With ``integrate(..., tangent=..., sensitivity=...)``: the tangent map
        and parameter sensitivities at the saved rows, and the chaos
        indicators of a renormalised frame (:class:`galerkin_vi.run.tangent.Variations`;
        ``tangent`` and ``sensitivity`` are also attributes of the trajectory).
    impacts : list of Impact or None
        For a system with contacts: every isolated impact (located on a step,
        in either mode), in time order
        (:class:`galerkin_vi.contact.Impact`: time, contact, normal and
        tangential impulse, stick or slide, energy lost). The rows of an
        impact appear twice, at the same time and position, with the momentum
        before and after it.
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
    q_reduced: NDArray[np.float64] | None = None
    status: RunStatus = RunStatus.COMPLETED
    message: str = "the run reached its last step"
    order: int | None = None
    sol: DenseOutput | PiecewiseDenseOutput | None = None
    t_events: list[NDArray[np.float64]] | None = None
    q_events: list[NDArray[np.float64]] | None = None
    v_events: list[NDArray[np.float64]] | None = None
    p_events: list[NDArray[np.float64]] | None = None
    impacts: list | None = None
    contact_forces: object | None = None
    variations: object | None = None
    kernel_path: str | None = None

    def __len__(self) -> int:
        return self.t.shape[0]

    @property
    def tangent(self) -> NDArray[np.float64] | None:
        r""":math:`\partial(q_k, p_k)/\partial(q_0, p_0)\,V` at every saved row, shape
        (rows, 2n, r) (``integrate(..., tangent=...)``; :mod:`galerkin_vi.run.tangent`)."""
        return None if self.variations is None else self.variations.tangent

    @property
    def sensitivity(self) -> NDArray[np.float64] | None:
        r""":math:`\partial(q_k, p_k)/\partial\theta` at every saved row, shape (rows, 2n, P)
        (``integrate(..., sensitivity=[...])``)."""
        return None if self.variations is None else self.variations.sensitivity

    @property
    def mean_newton_iterations(self) -> float:
        """Mean number of Newton iterations per step."""
        return self.total_newton_iterations / self.n_steps if self.n_steps else 0.0

    def _param_dict(self) -> dict[sp.Symbol, float]:
        return dict(zip(self.system.params, self.params, strict=True))

    def _reduced_q(self) -> NDArray[np.float64]:
        """Positions with angles (``system.periodic``) reduced to [-pi, pi).

        Diagnostics evaluate sines of these instead of the continuous angle,
        whose size would cost accuracy (an angle of 1e4 loses 1e4 ulps).
        """
        if self.q_reduced is not None:
            return self.q_reduced
        periodic = np.array(self.system.periodic, dtype=bool)
        if not periodic.any():
            return self.q
        q = self.q.copy()
        q[:, periodic] -= 2 * np.pi * np.round(q[:, periodic] / (2 * np.pi))
        return q

    def velocities(self) -> NDArray[np.float64]:
        r"""Velocities :math:`v_k = (\mathbb FL)^{-1}(q_k, p_k)`.

        These have the method's full order, unlike the polynomial's :math:`\dot q_d`.
        """
        return self.system.inverse_legendre(self._reduced_q(), self.p, self.t, self._param_dict())

    def dense(self, stencil: int | None = None) -> DenseOutput | PiecewiseDenseOutput:
        """Dense output of the run from its saved states (:mod:`galerkin_vi.run.dense`).

        Parameters
        ----------
        stencil : int, optional
            Nodes per interpolant; default :func:`~galerkin_vi.run.dense.stencil_nodes`
            of the method's order (``order``; 2 when unknown). Every step saved
            (``save_every=1``) gives the method's order; sparser saves
            interpolate over their spacing.

        Returns
        -------
        DenseOutput or PiecewiseDenseOutput
            Piecewise between impacts for a run with impacts (the velocity
            jumps there; :mod:`galerkin_vi.run.piecewise`), right-continuous.
        """
        if len(self) < 2:
            raise ValueError(f"dense output needs at least 2 saved states, got {len(self)}")
        if stencil is None:
            stencil = stencil_nodes(self.order or 2)
        if isinstance(stencil, bool) or not isinstance(stencil, int) or stencil < 2:
            raise ValueError(f"stencil must be an int >= 2, got {stencil!r}")
        if self.impacts:
            # the velocity jumps at an impact: one interpolant per smooth segment
            return PiecewiseDenseOutput.from_rows(
                self.t, self.q, self.velocities(), stencil, self.system, self.params
            )
        return DenseOutput(
            t=self.t, q=self.q, v=self.velocities(), stencil=stencil, system=self.system,
            params=self.params,
        )  # fmt: skip

    def energy(self) -> NDArray[np.float64]:
        """Energy :math:`H(t_k, q_k, p_k)` at every saved point."""
        return self.system.hamiltonian(self._reduced_q(), self.p, self.t, self._param_dict())

    def momentum(self, xi: Sequence[sp.Expr]) -> NDArray[np.float64]:
        r"""Momentum map :math:`\langle p_k, \xi_Q(q_k)\rangle` of the generator ``xi``."""
        return self.system.momentum_map(xi)(self.q, self.p, self.params)

    def constraint_residual(self) -> NDArray[np.float64]:
        r""":math:`\max_j |g_j(t_k, q_k)|` at every saved point (constrained systems)."""
        self._require_constraints("constraint_residual")
        g = self.system.constraint_values(self._reduced_q(), self.t, self.params)
        return np.max(np.abs(g), axis=-1)

    def hidden_constraint_residual(self) -> NDArray[np.float64]:
        r""":math:`\max_j |(\mathcal G(q_k) v_k + \partial_t g)_j|` at every saved point.

        The velocity-level ("hidden") constraint :math:`\tfrac{d}{dt}g = 0`, with
        :math:`v_k = (\mathbb FL)^{-1}(q_k, p_k)`.
        """
        self._require_constraints("hidden_constraint_residual")
        q = self._reduced_q()
        jac = self.system.constraint_jacobian(q, self.t, self.params)
        rate = self.system.constraint_rate(q, self.t, self.params)
        hidden = np.einsum("kja,ka->kj", jac, self.velocities()) + rate
        return np.max(np.abs(hidden), axis=-1)

    def plot(self, coordinates: Sequence[int] | None = None, *, max_lines: int = 8):
        r"""Positions, energy error and momenta against t, in one figure of three panels.

        The energy panel shows :math:`|H_k - H_0| / \max(1, |H_0|)` on a log
        scale: bounded for a symplectic method on an autonomous, unforced system
        (a drift means the step is too large or the run failed); for forced or
        time-dependent systems it is the energy's change, not an error.

        Parameters
        ----------
        coordinates : sequence of int, optional
            Indices of the coordinates to draw (default: the first ``max_lines``).
        max_lines : int
            At most this many coordinates by default (a 100-mass chain would
            draw an unreadable tangle).

        Returns
        -------
        matplotlib.figure.Figure
        """
        import matplotlib.pyplot as plt

        n = self.q.shape[1]
        chosen = list(range(min(n, max_lines))) if coordinates is None else list(coordinates)
        if not chosen or any(not 0 <= a < n for a in chosen):
            raise ValueError(f"coordinates must be indices in [0, {n}), got {coordinates!r}")
        names = [str(sym) for sym in self.system.q]
        fig, (ax_q, ax_e, ax_p) = plt.subplots(3, 1, sharex=True, figsize=(7.0, 7.5))
        for a in chosen:
            ax_q.plot(self.t, self.q[:, a], label=names[a])
            ax_p.plot(self.t, self.p[:, a], label=f"p_{names[a]}")
        energy = self.energy()
        change = np.abs(energy - energy[0]) / max(1.0, abs(float(energy[0])))
        # a log scale cannot show exact zeros (the first point; steps that conserve H
        # exactly): they are left out, not drawn at some floor that squashes the rest
        shown = change > 0.0
        ax_e.semilogy(self.t[shown], change[shown])
        ax_q.set_ylabel("q")
        ax_e.set_ylabel("|H - H0| / max(1, |H0|)")
        ax_p.set_ylabel("p")
        ax_p.set_xlabel("t")
        for ax in (ax_q, ax_p):
            if len(chosen) <= max_lines:
                ax.legend(loc="upper right", fontsize="small")
        subset = "" if len(chosen) == n else f" ({len(chosen)} of {n} coordinates)"
        ax_q.set_title(f"{len(self)} saved states, {self.n_steps} steps{subset}")
        fig.tight_layout()
        return fig

    def _require_constraints(self, name: str) -> None:
        if not self.system.m:
            raise ValueError(f"{name}: the system has no constraints")
