r"""Exact gradients of a loss through a run: the discrete adjoint, with checkpointing.

For a loss :math:`\Lambda = \varphi(t_N, x_N) + \sum_{k=0}^{N-1} \ell(t_k, x_k)` of the
states :math:`x_k = (q_k, p_k)` of a run (SymPy expressions in :math:`t, q, p`
and the parameters :math:`\theta`), the reverse pass

.. math::

    \lambda_N = \nabla_x\varphi(x_N),\qquad
    \lambda_k = \Big(\frac{\partial x_{k+1}}{\partial x_k}\Big)^T\lambda_{k+1}
        + \nabla_x \ell(x_k),\qquad
    \nabla_\theta\Lambda = \sum_{k<N}\Big(\frac{\partial x_{k+1}}{\partial\theta}\Big)^T
        \lambda_{k+1} + \partial_\theta\varphi + \sum_k \partial_\theta\ell

gives :math:`\nabla_{x_0}\Lambda = \lambda_0` at the cost of one transposed step
per step (:func:`galerkin_vi.loops.tangent.adjoint_sweep`: one factorisation
of the stage Jacobian and one solve with its transpose). For a symplectic
step this is the discretisation of the continuous adjoint equations by the
same method (Sanz-Serna, SIAM Rev. 58 (2016) 3–33), and
:math:`\langle\lambda_k, \delta x_k\rangle` is the same at every k, which
tests it against the tangent map to round-off.

**Checkpointing.** The reverse pass needs each step's control points. A run of
N steps is cut into segments of :math:`M \approx \sqrt N` steps; the forward
pass (the system's fastest loop) keeps only the segments' first states, and
the reverse pass runs each segment again from its first state through the
tangent loop, recording its control points, then sweeps it backwards.
Memory :math:`O(\sqrt N)` states and stages, cost one extra forward pass
(the two-level scheme that Griewank's revolve generalises). The segments'
recorded steps agree with the forward pass's to round-off, not bit for bit
(another loop solves the same stage equations).

Systems with constraints or contacts, and compositions of Störmer–Verlet
(:class:`~galerkin_vi.Composition`, whose sub-steps have no stage equations to
transpose), take forward mode instead: the tangent map and the sensitivities
carried along the run (:func:`_forward_mode`), ``Gradient.mode == "forward"``.

With the initial velocity given, :math:`p_0 = L_v(t_0, q_0, v_0; \theta)`, and the
gradients with respect to :math:`q_0`, :math:`v_0` and :math:`\theta` take its
derivatives: :math:`\nabla_{v_0}\Lambda = L_{vv}\lambda_{p}`,
:math:`\nabla_{q_0}\Lambda = \lambda_q + L_{vq}^T\lambda_p`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
import sympy as sp
from numpy.typing import NDArray

from ..run.spec import Segment
from ..run.start import initial_state
from ..run.status import RunStatus, SolverResult, loop_status
from ..run.tangent import (
    legendre_derivatives,
    parameter_addresses,
    recorded_steps,
    tangent_couplings,
)
from ..run.trajectory import Trajectory

__all__ = ["Gradient", "Loss", "gradient", "warm_up_adjoint"]

#: runs whose recorded steps (states and control points) take at most this many bytes
#: are recorded whole: no checkpoints, and no extra forward pass
RECORD_BYTES = 32 * 2**20

WRT = ("q0", "v0", "p0", "params")


@dataclass(frozen=True)
class Loss:
    r"""A loss :math:`\varphi(t_N, q_N, p_N) + \sum_{k<N} \ell(t_k, q_k, p_k)`.

    Parameters
    ----------
    terminal, running : sympy.Expr, optional
        :math:`\varphi` and :math:`\ell`, in the system's time, coordinates and
        parameters, and the momentum symbols ``p``. A sum approximating an
        integral :math:`\int \ell\,dt` includes the step: ``running = h * ell``.
    p : sequence of sympy.Symbol, optional
        The symbols that stand for the momenta :math:`p_1..p_n` in the
        expressions (none if they do not appear).
    """

    terminal: sp.Expr | None = None
    running: sp.Expr | None = None
    p: Sequence[sp.Symbol] = field(default=())

    def __post_init__(self) -> None:
        # hashable: the compiled loss is kept with the system under these expressions
        object.__setattr__(self, "p", tuple(self.p))
        for name in ("terminal", "running"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, sp.sympify(value))


@dataclass(frozen=True, eq=False)
class Gradient(SolverResult):
    r"""The loss and its gradient with respect to the initial state and the parameters.

    Attributes
    ----------
    value : float
        :math:`\Lambda`.
    q0, v0, p0 : ndarray or None
        :math:`\nabla_{q_0}\Lambda`, and :math:`\nabla_{v_0}\Lambda` (initial
        velocity given) or :math:`\nabla_{p_0}\Lambda` (momentum given); None when
        not asked for in ``wrt``.
    params : dict
        :math:`\partial\Lambda/\partial\theta` by parameter symbol.
    adjoint : ndarray, shape (2n,)
        :math:`\lambda_0`, the cotangent of :math:`(q_0, p_0)`.
    trajectory : Trajectory
        The forward run's segment starts and its last state.
    mode : {"adjoint", "forward"}
        How the sums were formed: the reverse pass, or (constrained systems,
        whose momentum projection has no reverse pass yet, and systems with
        contacts, whose impacts do not either) the tangent map carried
        forward with 2n + P directions: the same derivatives, at n times the
        cost.
    status : RunStatus
    message : str
    """

    value: float
    q0: NDArray[np.float64] | None
    v0: NDArray[np.float64] | None
    p0: NDArray[np.float64] | None
    params: dict
    adjoint: NDArray[np.float64]
    trajectory: Trajectory
    mode: str = "adjoint"
    status: RunStatus = RunStatus.COMPLETED
    message: str = "the gradient of the whole run"


def gradient(
    integrator,
    loss: Loss | sp.Expr,
    q0,
    v0=None,
    p0=None,
    *,
    h: float,
    n_steps: int,
    t0: float = 0.0,
    params=None,
    wrt: Sequence[str] = ("q0", "v0", "params"),
    checkpoint_every: int | None = None,
) -> Gradient:
    r"""The gradient of ``loss`` along the run ``integrator.integrate(q0, v0 or p0, h, n_steps)``
    by the discrete adjoint (module docstring).

    Parameters
    ----------
    integrator : Integrator
    loss : Loss or sympy.Expr
        A bare expression is the terminal term.
    q0, v0, p0 : array_like
        The initial state (exactly one of ``v0``, ``p0``).
    h, n_steps, t0, params
        As for :meth:`Integrator.integrate` (``params``: parameter values).
    wrt : sequence of {"q0", "v0", "p0", "params"}
        What to differentiate with respect to; ``"v0"`` needs ``v0`` given,
        ``"p0"`` needs ``p0``; ``"params"`` means every parameter of the system.
    checkpoint_every : int, optional
        Steps per recorded segment; default the whole run when its record fits in
        ``RECORD_BYTES`` (32 MiB), else :math:`4\lceil\sqrt N\rceil`.

    Returns
    -------
    Gradient
        ``success`` False (and the gradient of nothing) if a step of the run failed.
    """
    system = integrator.system
    wrt = _checked_wrt(wrt, v0, p0)
    loss = loss if isinstance(loss, Loss) else Loss(terminal=loss)
    if not isinstance(n_steps, int | np.integer) or n_steps < 1:
        raise ValueError(f"n_steps must be a positive int, got {n_steps!r}")
    spec = integrator.tangent_run_spec
    prm = system.parameter_vector(params)
    thetas = tuple(system.params) if "params" in wrt else ()
    terms = system.derived.get(
        ("adjoint", "loss", loss.terminal, loss.running, loss.p, thetas),
        lambda: LossTerms(system, loss, thetas),
    )
    q, p, v = initial_state(spec, q0, v0, p0, t0, prm, False)
    # a composition's sub-steps have no stage equations to transpose: forward mode
    forward = bool(system.m or system.contacts) or spec.path == "explicit"
    n = system.n
    s1 = 2 if spec.path == "explicit" else spec.method.tables.d.shape[0]
    whole = n_steps * (s1 * n + 2 * n + 1) * 8 <= RECORD_BYTES
    M = int(checkpoint_every or (n_steps if whole else 4 * (math.isqrt(n_steps - 1) + 1)))  # noqa: N806
    if M < 1:
        raise ValueError(f"checkpoint_every must be >= 1, got {checkpoint_every}")
    if system.contacts and loss.running is not None:
        raise ValueError(
            "gradient with contacts: running loss terms are not supported (a run with "
            "impacts has rows off the step grid); give a terminal loss"
        )
    if forward:
        outcome = _forward_mode(
            integrator, terms, q, p, float(t0), float(h), n_steps, M, thetas, prm
        )
        if isinstance(outcome, Trajectory):
            return _failed(outcome, thetas, system.n)
        value, lam, grad, traj_end = outcome
        start = Segment(q, p, v, float(t0), float(h), n_steps, 1, prm)
        return replace(
            _result(system, terms, value, lam, grad, thetas, q, v, p0, t0, prm, wrt, [start],
                    traj_end),
            mode="forward",
        )  # fmt: skip
    fnp = parameter_addresses(system, thetas) if thetas else np.zeros(1, dtype=np.int64)
    starts = _checkpoints(integrator, q, p, v, float(t0), float(h), n_steps, M, prm)
    if isinstance(starts, Trajectory):
        return _failed(starts, thetas, system.n)
    from ..loops import adjoint_sweep

    _, before, after = spec.loop_parts("newton")
    fn, traits, pattern, _periodic, couplings = tangent_couplings(before)
    tb = spec.method.tables
    traj_end = None
    for index in range(len(starts) - 1, -1, -1):
        start = starts[index]
        if start.v0 is None:
            q_s, p_s, v_s = initial_state(spec, start.q0, None, start.p0, start.t0, prm)
            start = start._replace(q0=q_s, p0=p_s, v0=v_s)
        record = recorded_steps(spec, start, fnp)
        steps = record.trajectory
        if record.result.status != 0:
            cause = loop_status(record.result.status)
            step = int(round((start.t0 - t0) / h)) + record.result.steps
            failed = replace(steps, status=cause, message=f"step {step}: {cause.cause}")
            return _failed(failed, thetas, system.n)
        if traj_end is None:  # the run's last segment: the terminal term
            traj_end = steps
            value = terms.terminal_value(steps, -1)
            lam = terms.terminal_gradient(steps, -1)
            grad = terms.terminal_parameter_gradient(steps, -1)
        running = terms.running_gradients(steps)
        value += terms.running_value(steps)
        grad += terms.running_parameter_gradient(steps)
        sweep_grad = np.zeros(len(thetas))
        ok = adjoint_sweep(
            fn, traits, pattern, couplings, fnp, steps.t, record.q_kept, record.stages, prm,
            tb.b, tb.c, tb.Phi, tb.D, float(h), lam, running, sweep_grad,
        )  # fmt: skip
        if not ok:
            raise RuntimeError("a stage Jacobian of the recorded run is singular")
        grad += sweep_grad
    return _result(system, terms, value, lam, grad, thetas, q, v, p0, t0, prm, wrt, starts,
                   traj_end)  # fmt: skip


def _checked_wrt(wrt, v0, p0) -> tuple[str, ...]:
    if isinstance(wrt, str):
        wrt = (wrt,)
    wrt = tuple(wrt)
    for item in wrt:
        if item not in WRT:
            raise ValueError(f"wrt: {item!r} is not one of {WRT}")
    if "v0" in wrt and v0 is None:
        raise ValueError("wrt contains 'v0' but the initial state is given by p0")
    if "p0" in wrt and p0 is None:
        raise ValueError("wrt contains 'p0' but the initial state is given by v0")
    return wrt


def _forward_mode(integrator, terms, q, p, t0, h, n_steps, M, thetas, prm):  # noqa: N803
    r"""The same sums in forward mode: :math:`\lambda_0 = \sum_k \Phi_k^T\nabla\ell_k +
    \Phi_N^T\nabla\varphi`, with the frame :math:`[\Phi, S]` (2n + P directions) carried
    through segments of M steps; (value, lambda_0, gradient, last segment) or the failed run.
    """
    n, P = integrator.system.n, len(thetas)  # noqa: N806
    frame = np.hstack([np.eye(2 * n), np.zeros((2 * n, P))])
    value, lam, grad = 0.0, np.zeros(2 * n), np.zeros(P)
    done, t_s = 0, t0
    params = dict(zip(integrator.system.params, prm, strict=True))
    while done < n_steps:
        m = min(M, n_steps - done)
        steps = integrator.integrate(
            q, p0=p, h=h, n_steps=m, t0=t_s, params=params, tangent=frame,
            sensitivity=list(thetas) or None, on_failure="warn",
        )  # fmt: skip
        if not steps.success:
            return steps
        phi = steps.tangent[:, :, : 2 * n]
        sens = steps.tangent[:, :, 2 * n :]
        if P:
            sens = sens + steps.sensitivity
        running = terms.running_gradients(steps)
        value += terms.running_value(steps)
        lam += np.einsum("kij,ki->j", phi[:-1], running)
        grad += np.einsum("kij,ki->j", sens[:-1], running) + terms.running_parameter_gradient(steps)
        frame = np.hstack([phi[-1], sens[-1]])
        q, p, t_s, done = steps.q[-1], steps.p[-1], t0 + (done + m) * h, done + m
    terminal = terms.terminal_gradient(steps, -1)
    value += terms.terminal_value(steps, -1)
    lam += phi[-1].T @ terminal
    grad += sens[-1].T @ terminal + terms.terminal_parameter_gradient(steps, -1)
    return value, lam, grad, steps


def _checkpoints(integrator, q, p, v, t0, h, n_steps, M, prm):  # noqa: N803
    """The segments' starts: the run's start alone, or every M-th state of a plain run
    (their velocities found when a segment is recorded), or that run if it failed."""
    if n_steps <= M:
        return [Segment(q, p, v, t0, h, n_steps, 1, prm)]
    system = integrator.system
    plain = integrator.integrate(
        q, p0=p, h=h, n_steps=n_steps, t0=t0, save_every=M, on_failure="warn",
        params=dict(zip(system.params, prm, strict=True)),
    )  # fmt: skip
    if not plain.success:
        return plain
    return [
        Segment(plain.q[i], plain.p[i], None, t0 + i * M * h, h, min(M, n_steps - i * M), 1, prm)
        for i in range(len(plain.t) - 1)
    ]


def _failed(traj, thetas, n) -> Gradient:
    code = traj.status
    message = f"the forward run failed: {traj.message}; no gradient"
    nan = np.full(n, np.nan)
    return Gradient(
        value=np.nan, q0=nan, v0=None, p0=None, params=dict.fromkeys(thetas, np.nan),
        adjoint=np.full(2 * n, np.nan), trajectory=traj, status=code,
        message=message,
    )  # fmt: skip


def _result(system, terms, value, lam, grad, thetas, q, v, p0, t0, prm, wrt, starts, traj_end):
    n = system.n
    lam_q, lam_p = lam[:n].copy(), lam[n:].copy()
    g_q0, g_v0, g_p0 = lam_q, None, None
    if p0 is None:
        # p0 = L_v(t0, q0, v0; theta): its derivatives carry lambda_p back
        legendre = legendre_derivatives(system, thetas, t0, q, v, prm)
        g_q0 = lam_q + legendre.dq.T @ lam_p
        g_v0 = legendre.dv.T @ lam_p
        grad = grad + legendre.dtheta.T @ lam_p
    else:
        g_p0 = lam_p
    t_rows = np.array([s.t0 for s in starts] + [traj_end.t[-1]])
    q_rows = np.array([s.q0 for s in starts] + [traj_end.q[-1]])
    p_rows = np.array([s.p0 for s in starts] + [traj_end.p[-1]])
    traj = Trajectory(
        t=t_rows, q=q_rows, p=p_rows, newton_iterations=np.zeros(0, dtype=np.uint8),
        max_residual=traj_end.max_residual, system=system, params=prm,
    )  # fmt: skip
    return Gradient(
        value=float(value),
        q0=g_q0 if "q0" in wrt else None,
        v0=g_v0 if "v0" in wrt else None,
        p0=g_p0 if "p0" in wrt else None,
        params=dict(zip(thetas, grad.tolist(), strict=True)),
        adjoint=lam.copy(),
        trajectory=traj,
    )


class LossTerms:
    """The loss's expressions and their gradients, compiled for arrays of rows."""

    def __init__(self, system, loss: Loss, thetas: tuple) -> None:
        n = system.n
        p_symbols = tuple(loss.p)
        if p_symbols and len(p_symbols) != n:
            raise ValueError(f"Loss.p must list {n} momentum symbols, got {len(p_symbols)}")
        if not p_symbols:
            p_symbols = tuple(sp.symbols(f"_p0:{n}"))
        t = system.t if system.t is not None else sp.Symbol("_t")
        self.system, self.n = system, n
        self.arguments = (t, *system.q, *p_symbols, *system.params)
        known = set(self.arguments)
        state = (*system.q, *p_symbols)
        for name, expr in (("terminal", loss.terminal), ("running", loss.running)):
            if expr is None:
                continue
            unknown = sp.sympify(expr).free_symbols - known
            if unknown:
                raise ValueError(
                    f"the {name} loss has symbols that are neither t, q, the momenta of "
                    f"Loss.p nor parameters: {sorted(map(str, unknown))}"
                )
        self.terminal = self._pieces(loss.terminal, state, thetas)
        self.running = self._pieces(loss.running, state, thetas)
        self.thetas = thetas

    def _pieces(self, expr, state, thetas):
        if expr is None:
            return None
        expr = sp.sympify(expr)
        parts = [expr, *(sp.diff(expr, s) for s in state), *(sp.diff(expr, s) for s in thetas)]
        return sp.lambdify(self.arguments, parts, "numpy")

    def _evaluate(self, function, traj: Trajectory, rows) -> NDArray[np.float64]:
        t = np.atleast_1d(traj.t[rows])
        q = np.atleast_2d(traj.q[rows])
        p = np.atleast_2d(traj.p[rows])
        values = function(t, *q.T, *p.T, *traj.params)
        return np.stack([np.broadcast_to(np.asarray(v, dtype=float), t.shape) for v in values], 1)

    def terminal_value(self, traj, row) -> float:
        if self.terminal is None:
            return 0.0
        return float(self._evaluate(self.terminal, traj, row)[0, 0])

    def terminal_gradient(self, traj, row) -> NDArray[np.float64]:
        if self.terminal is None:
            return np.zeros(2 * self.n)
        return self._evaluate(self.terminal, traj, row)[0, 1 : 1 + 2 * self.n].copy()

    def terminal_parameter_gradient(self, traj, row) -> NDArray[np.float64]:
        if self.terminal is None:
            return np.zeros(len(self.thetas))
        return self._evaluate(self.terminal, traj, row)[0, 1 + 2 * self.n :].copy()

    def _running_table(self, steps: Trajectory) -> NDArray[np.float64] | None:
        if self.running is None:
            return None
        return self._evaluate(self.running, steps, slice(0, len(steps) - 1))

    def running_value(self, steps) -> float:
        table = self._running_table(steps)
        return 0.0 if table is None else float(table[:, 0].sum())

    def running_gradients(self, steps) -> NDArray[np.float64]:
        table = self._running_table(steps)
        if table is None:
            return np.zeros((len(steps) - 1, 2 * self.n))
        return np.ascontiguousarray(table[:, 1 : 1 + 2 * self.n])

    def running_parameter_gradient(self, steps) -> NDArray[np.float64]:
        table = self._running_table(steps)
        if table is None:
            return np.zeros(len(self.thetas))
        return table[:, 1 + 2 * self.n :].sum(axis=0)


def warm_up_adjoint(integrator, q0, v0) -> None:
    """Compile the reverse pass for the loop variant of ``integrator`` (a two-step gradient)."""
    q = integrator.system.q[0]
    gradient(integrator, Loss(terminal=q**2), q0, v0, h=0.01, n_steps=2, wrt=("q0",))
