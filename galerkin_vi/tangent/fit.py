r"""Fitting parameters (and the initial state) to observed positions, with exact Jacobians.

The data model. Positions :math:`y_i \in \mathbb{R}^n` are observed at times
:math:`t_0 < t_1 < \dots < t_{m-1}` (any spacing), with noise. The model is the
discrete flow of the variational integrator started at :math:`t_0` from
:math:`x_0 = (q_0, p_0)`, with :math:`p_0` either the Legendre transform of a
velocity, :math:`p_0 = L_v(t_0, q_0, v_0; \theta)` (``v0`` given or fitted), or a
momentum given or fitted as such (``p0``). Its positions at the observation
times are :math:`Q_i(\theta, z_0)`, :math:`z_0` the fitted part of the initial
state (none, or :math:`(q_0, v_0)`, or :math:`(q_0, p_0)`). The fit minimises

.. math::

    \tfrac12 \|r\|^2, \qquad r = \big(\sqrt{w_{ij}}\,(Q_{ij} - y_{ij})\big)_{ij}

over :math:`x = (\theta, z_0)` by :func:`scipy.optimize.least_squares` (trust
region) with the exact Jacobian :math:`\partial Q_i / \partial x` from the
tangent map and the parameter sensitivities of the discrete flow
(``Integrator.integrate(tangent=..., sensitivity=...)``):

.. math::

    \frac{\partial x_i}{\partial (\theta, z_0)} = \Phi_i D_0 + \big[S_i,\ 0\big],
    \qquad D_0 = \frac{\partial x_0}{\partial(\theta, z_0)} =
    \begin{pmatrix} 0 & I & 0 \\ L_{v\theta} & L_{vq} & L_{vv} \end{pmatrix}

(for the velocity model; :math:`D_0 = \left(\begin{smallmatrix} 0 & I & 0 \\ 0 & 0 & I
\end{smallmatrix}\right)` for the momentum model, and only the columns of the fitted
unknowns), :math:`\Phi_i = \partial x_i / \partial x_0` and :math:`S_i = \partial x_i
/ \partial\theta` at fixed :math:`x_0`, both computed by the integrator.

The step grid contains every observation time. When every :math:`t_i - t_0` is a
multiple of the step ``h`` (to round-off), one run of step ``h`` saves the
observation rows. Otherwise each gap :math:`t_{i+1} - t_i` is integrated on its
own with the fewest equal steps not longer than ``h``; the state and its
derivative chain across the gaps: the tangent of gap :math:`i + 1` starts from
:math:`D = \partial x_i / \partial(\theta, z_0)`, so
:math:`\partial x_{i+1} = \Phi^{(i+1)} D + [S^{(i+1)}, 0]`.

The covariance at the solution is Gauss–Newton's,
:math:`C = s^2 (J^\top J)^{-1}`, :math:`s^2 = \|r\|^2 / (m_r - k)` with
:math:`m_r` the number of residuals and :math:`k` the number of unknowns
(with ``absolute_weights=True``, the weights are :math:`1/\sigma^2` and
:math:`C = (J^\top J)^{-1}`), as :func:`scipy.optimize.curve_fit`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..errors import ConvergenceError
from ..integrator import Integrator
from ..run.status import SolverResult
from ..run.tangent import legendre_derivatives
from ..run.trajectory import Trajectory
from .estimate import estimate_parameters
from .observations import FitStatus, check_observations, parameter_symbols

__all__ = ["ParameterFit", "fit_parameters"]

#: observation times within this fraction of the span of a multiple of h are on the grid
GRID_TOLERANCE = 1e-9

_DEFAULT_OPTIONS = {"ftol": 1e-12, "xtol": 1e-12, "gtol": 1e-12, "x_scale": "jac"}
_FORBIDDEN_OPTIONS = {"fun", "x0", "jac", "bounds", "args", "kwargs", "method"}


@dataclass(frozen=True)
class ParameterFit(SolverResult):
    r"""The result of :func:`fit_parameters`.

    Attributes
    ----------
    params : dict
        Parameter symbol -> fitted value.
    values : ndarray, shape (P,)
        The fitted values in the order of ``symbols`` (the order of ``params0``).
    symbols : tuple of sympy.Symbol
    standard_errors : ndarray, shape (P,)
        Square roots of the diagonal of ``covariance``.
    covariance : ndarray, shape (P, P)
        The parameters' block of ``full_covariance``.
    full_covariance : ndarray, shape (k, k)
        Covariance of all unknowns :math:`x = (\theta, q_0, v_0 \text{ or } p_0)`
        (the initial state only when fitted), :math:`s^2 (J^\top J)^{-1}`;
        ``inf`` where :math:`J` is rank-deficient.
    q0 : ndarray, shape (n,)
        The initial positions (fitted or given).
    v0 : ndarray, shape (n,), or None
        The initial velocities of the velocity model (fitted or given).
    p0 : ndarray, shape (n,)
        The initial momenta of the run.
    trajectory : Trajectory
        The run at the fitted values from ``t_obs[0]`` to ``t_obs[-1]``, every
        step saved: the fit's own run when the observations lie on one grid of
        step ``h``; otherwise a run of equal steps of at most ``h`` (its nodes
        need not contain the observation times; ``q_model`` has the fit's values).
        On ``RUN_FAILED``, the failed run up to its failure.
    q_model : ndarray, shape (m, n)
        The model positions at the observation times.
    residuals : ndarray, shape (m, n)
        ``q_model - q_obs`` (unweighted).
    cost : float
        :math:`\tfrac12\|r\|^2` with the weighted residuals :math:`r`.
    residual_variance : float
        :math:`s^2 = \|r\|^2 / (m_r - k)` (nan when :math:`m_r \le k`).
    nfev, njev : int
        Evaluations of the residuals and of the Jacobian (each one run).
    status : FitStatus
    message : str
    """

    params: dict
    values: NDArray[np.float64]
    symbols: tuple
    standard_errors: NDArray[np.float64]
    covariance: NDArray[np.float64]
    full_covariance: NDArray[np.float64]
    q0: NDArray[np.float64]
    v0: NDArray[np.float64] | None
    p0: NDArray[np.float64]
    trajectory: Trajectory
    q_model: NDArray[np.float64]
    residuals: NDArray[np.float64]
    cost: float
    residual_variance: float
    nfev: int
    njev: int
    status: FitStatus
    message: str


@dataclass(frozen=True)
class Segment:
    """One run of the fit's model: ``n_steps`` steps of ``h`` from ``t0``.

    ``rows`` are the saved rows (with ``save_every``) that are observations,
    ``observations`` their indices in ``t_obs``.
    """

    t0: float
    h: float
    n_steps: int
    save_every: int
    rows: NDArray[np.int64]
    observations: NDArray[np.int64]


def plan_segments(t: NDArray[np.float64], h: float) -> tuple[list[Segment], bool]:
    """The runs whose step grid contains every observation time, and whether it is one grid.

    One run of step ``h`` when every :math:`t_i - t_0` is a multiple of ``h``
    (within :data:`GRID_TOLERANCE` of the span), saving every ``g``-th step,
    ``g`` the greatest common divisor of the multiples; otherwise one run per
    gap with :math:`\\lceil (t_{i+1} - t_i)/h \\rceil` equal steps.
    """
    if not (np.isfinite(h) and h > 0):
        raise ValueError(f"h must be a positive finite step size, got {h}")
    span = t[-1] - t[0]
    K = (t - t[0]) / h
    k = np.rint(K).astype(np.int64)
    if np.all(np.abs(K - k) * h <= GRID_TOLERANCE * span) and np.all(np.diff(k) > 0):
        g = int(np.gcd.reduce(k[1:]))
        segment = Segment(float(t[0]), h, int(k[-1]), g, k // g, np.arange(t.size))
        return [segment], True
    segments = []
    for i, gap in enumerate(np.diff(t)):
        steps = max(1, math.ceil(gap / h * (1.0 - GRID_TOLERANCE)))
        segments.append(
            Segment(float(t[i]), gap / steps, steps, steps, np.array([1]), np.array([i + 1]))
        )
    return segments, False


class InitialState:
    r"""The initial state :math:`x_0 = (q_0, p_0)` and its derivative in the unknowns.

    ``kind`` is ``"velocity"`` (:math:`p_0 = L_v(t_0, q_0, v_0; \theta)`) or
    ``"momentum"``; with ``fitted``, the unknowns after the parameters are
    :math:`(q_0, v_0)` or :math:`(q_0, p_0)`, else ``q0`` and ``w0`` (the
    velocity or momentum) are fixed.
    """

    def __init__(self, system, symbols: tuple, t0: float, kind: str, fitted: bool,
                 q0: NDArray, w0: NDArray) -> None:  # fmt: skip
        self.kind, self.fitted, self.t0 = kind, fitted, t0
        self.q0, self.w0 = q0, w0
        self.n, self.n_params = system.n, len(symbols)
        self._index = [system.params.index(s) for s in symbols]
        self._prm = system.parameter_vector()
        self._system, self._symbols = system, tuple(symbols)

    @property
    def size(self) -> int:
        """Number of unknowns of the initial state (0 or 2n)."""
        return 2 * self.n if self.fitted else 0

    def parameters(self, theta: NDArray) -> NDArray:
        """The system's full parameter vector with ``theta`` in place."""
        prm = self._prm.copy()
        prm[self._index] = theta
        return prm

    def split(self, x: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """:math:`\\theta`, :math:`q_0` and the velocity or momentum from the unknowns."""
        n, P = self.n, self.n_params
        if self.fitted:
            return x[:P], x[P : P + n], x[P + n :]
        return x[:P], self.q0, self.w0

    def state(self, x: NDArray) -> tuple[NDArray, NDArray, NDArray]:
        """:math:`q_0`, :math:`p_0` and :math:`D_0 = \\partial x_0 / \\partial x`, (2n, k)."""
        theta, q0, w0 = self.split(x)
        n, P = self.n, self.n_params
        D = np.zeros((2 * n, P + self.size))
        if self.kind == "momentum":
            if self.fitted:
                D[:, P:] = np.eye(2 * n)
            return q0, w0, D
        legendre = legendre_derivatives(
            self._system, self._symbols, self.t0, q0, w0, self.parameters(theta)
        )
        D[n:, :P] = legendre.dtheta
        if self.fitted:
            D[:n, P : P + n] = np.eye(n)
            D[n:, P : P + n] = legendre.dq
            D[n:, P + n :] = legendre.dv
        return q0, legendre.p, D


class RunFailed(Exception):
    """A run of the model failed; ``partial`` is the trajectory up to the failure."""

    def __init__(self, message: str, partial: Trajectory | None) -> None:
        super().__init__(message)
        self.partial = partial


class TrajectoryModel:
    """The model positions at the observation times and their exact Jacobian."""

    def __init__(self, integrator: Integrator, symbols: tuple, initial: InitialState,
                 segments: list[Segment], m: int) -> None:  # fmt: skip
        self.integrator, self.symbols, self.initial = integrator, symbols, initial
        self.segments, self.m = segments, m
        self._cache: tuple[bytes, NDArray, NDArray] | None = None

    def evaluate(self, x: NDArray) -> tuple[NDArray, NDArray]:
        """Positions (m, n) and their derivatives (m, n, k) in the unknowns ``x``."""
        key = np.asarray(x, dtype=float).tobytes()
        if self._cache is not None and self._cache[0] == key:
            return self._cache[1], self._cache[2]
        theta = self.initial.split(x)[0]
        params = dict(zip(self.symbols, (float(v) for v in theta), strict=True))
        q, p, D = self.initial.state(x)
        n, P = self.initial.n, len(self.symbols)
        Q = np.empty((self.m, n))
        dQ = np.empty((self.m, n, D.shape[1]))
        Q[0], dQ[0] = q, D[:n]
        for seg in self.segments:
            traj = self._run(seg, q, p, D, params)
            dX = np.zeros((len(traj.t), 2 * n, D.shape[1]))
            if traj.tangent is not None:
                dX += traj.tangent
            dX[:, :, :P] += traj.sensitivity
            Q[seg.observations] = traj.q[seg.rows]
            dQ[seg.observations] = dX[seg.rows, :n]
            q, p, D = traj.q[-1], traj.p[-1], dX[-1]
        self._cache = (key, Q, dQ)
        return Q, dQ

    def _run(self, seg: Segment, q, p, D, params) -> Trajectory:
        options = {"tangent": D} if np.any(D) else {}
        try:
            traj = self.integrator.integrate(
                q, p0=p, h=seg.h, n_steps=seg.n_steps, t0=seg.t0, params=params,
                save_every=seg.save_every, sensitivity=list(self.symbols),
                on_failure="raise", progress=False, **options,
            )  # fmt: skip
        except ConvergenceError as exc:
            raise RunFailed(str(exc), exc.partial) from None
        if not traj.success:
            raise RunFailed(traj.message, traj)
        return traj


def fit_parameters(
    system,
    method,
    t_obs: ArrayLike,
    q_obs: ArrayLike,
    params0: Mapping[sp.Symbol | str, float] | Iterable[sp.Symbol | str],
    *,
    h: float | None = None,
    q0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    fit_initial_state: bool = False,
    weights: ArrayLike | None = None,
    absolute_weights: bool = False,
    bounds: Mapping[sp.Symbol | str, tuple[float, float]] | None = None,
    options: Mapping[str, object] | None = None,
) -> ParameterFit:
    r"""Fit parameters of ``system`` to observed positions by least squares with exact Jacobians.

    The model and the maths are in the module docstring: the positions of the
    discrete flow at the observation times, with the initial state at
    ``t_obs[0]`` given or fitted, against ``q_obs``; the Jacobian comes from the
    integrator's tangent map and parameter sensitivities.

    Parameters
    ----------
    system : LagrangianSystem
        Parameters not fitted keep the system's values.
    method : Galerkin
        The integrator's method.
    t_obs : array_like, shape (m,)
        Strictly increasing observation times, any spacing.
    q_obs : array_like, shape (m, n)
        Observed positions (shape (m,) for n = 1).
    params0 : mapping or sequence
        The parameters to fit (symbols or names) with their starting values;
        a sequence without values starts from :func:`estimate_parameters` on
        the observations (densely sampled, unconstrained systems).
    h : float, optional
        The step: one grid of step ``h`` if the observation times lie on one,
        else the largest step of each gap's equal steps (module docstring).
        Default: the smallest gap of ``t_obs``.
    q0 : array_like, shape (n,), optional
        Initial positions; given and not fitted: default ``q_obs[0]`` (then the
        first observation is the initial state and no residual); fitted: the
        starting value, default ``q_obs[0]``.
    v0, p0 : array_like, shape (n,), optional
        At most one: initial velocities (the velocity model, :math:`p_0 = L_v`)
        or momenta (the momentum model). Without ``fit_initial_state`` one of
        them is required; with it, the starting value (default: ``v0`` from
        the quadratic through the first three observations).
    fit_initial_state : bool
        Fit :math:`(q_0, v_0)` (or :math:`(q_0, p_0)` when ``p0`` is given)
        with the parameters.
    weights : array_like, optional
        Non-negative weights of the squared residuals: a scalar, (m,) per
        observation or (m, n) per entry; zero drops an entry.
    absolute_weights : bool
        The weights are :math:`1/\sigma^2` of known noise levels: the covariance
        is :math:`(J^\top J)^{-1}`, not scaled by the residual variance.
    bounds : mapping, optional
        Parameter -> (lower, upper); unbounded parameters are omitted.
    options : mapping, optional
        Keyword arguments for :func:`scipy.optimize.least_squares` (``ftol``,
        ``xtol``, ``gtol`` default 1e-12, ``x_scale`` default ``"jac"``,
        ``max_nfev``, ``loss``, ``verbose``...). The covariance assumes the
        default linear loss.

    Returns
    -------
    ParameterFit
        ``status`` ``CONVERGED``, ``MAX_EVALUATIONS``, ``RUN_FAILED`` (the run at
        the start failed; a run failing at a trial point only shortens the
        trust region) or ``NOT_IDENTIFIABLE`` (rank-deficient Jacobian at the
        solution: covariance ``inf``).
    """
    integrator = method if isinstance(method, Integrator) else Integrator(system, method)
    t, q = check_observations(t_obs, q_obs, system.n)
    symbols, start = _start_values(system, t, q, params0)
    initial = _initial_state(system, symbols, t, q, q0, v0, p0, fit_initial_state)
    segments, on_grid = plan_segments(t, float(np.min(np.diff(t))) if h is None else float(h))
    model = TrajectoryModel(integrator, symbols, initial, segments, t.size)
    sqrt_w = _residual_weights(weights, t.size, system.n)
    if q0 is None and not fit_initial_state:
        sqrt_w[0] = 0.0  # the first observation is the initial state
    used = sqrt_w > 0
    x0 = np.concatenate([start, initial.q0, initial.w0]) if initial.fitted else start
    lower, upper = _bounds(system, symbols, bounds, x0)

    def residual(x: NDArray) -> NDArray:
        try:
            Q, _ = model.evaluate(x)
        except RunFailed:
            return np.full(int(used.sum()), np.nan)
        return (sqrt_w * (Q - q))[used]

    def jacobian(x: NDArray) -> NDArray:
        _, dQ = model.evaluate(x)
        return (sqrt_w[..., None] * dQ)[used]

    try:
        model.evaluate(x0)
    except RunFailed as exc:
        return _failed(model, x0, q, exc)
    from scipy.optimize import least_squares  # scipy.optimize: loaded when fitting

    sol = least_squares(residual, x0, jac=jacobian, bounds=(lower, upper), method="trf",
                        **_least_squares_options(options))  # fmt: skip
    return _result(model, sol, q, sqrt_w, used, absolute_weights, on_grid)


def _start_values(system, t, q, params0) -> tuple[tuple, NDArray]:
    """The fitted symbols and their starting values (from the estimator for a bare list)."""
    symbols = parameter_symbols(system, params0)
    if isinstance(params0, Mapping):
        start = np.array([float(params0[key]) for key in params0], dtype=float)
        if not np.all(np.isfinite(start)):
            raise ValueError(f"params0: starting values must be finite, got {dict(params0)}")
        return symbols, start
    estimate = estimate_parameters(system, t, q, symbols)
    if not np.all(np.isfinite(estimate.values)):
        raise ValueError(
            "params0: the discrete Euler-Lagrange estimator gave no finite starting values "
            f"({estimate.message}); give params0 as a mapping to starting values"
        )
    return symbols, estimate.values


def _initial_state(system, symbols, t, q, q0, v0, p0, fitted: bool) -> InitialState:
    """The data model of the initial state (see :class:`InitialState`)."""
    n = system.n
    if v0 is not None and p0 is not None:
        raise ValueError("give at most one of v0 and p0")
    if v0 is None and p0 is None and not fitted:
        raise ValueError(
            "the initial velocity is unknown: give v0 or p0, or fit_initial_state=True"
        )
    if fitted and (system.constraints is not None or system.contacts):
        raise ValueError(
            "fit_initial_state: a constrained system's initial state lies on the constraint "
            "manifold, not in a vector space of 2n free unknowns; fix q0 and v0 or p0"
        )
    q_start = q[0] if q0 is None else _vector("q0", q0, n)
    if p0 is not None:
        return InitialState(system, symbols, t[0], "momentum", fitted, q_start,
                            _vector("p0", p0, n))  # fmt: skip
    v_start = _initial_velocity(t, q) if v0 is None else _vector("v0", v0, n)
    return InitialState(system, symbols, t[0], "velocity", fitted, q_start, v_start)


def _vector(name: str, value: ArrayLike, n: int) -> NDArray:
    x = np.asarray(value, dtype=float).reshape(-1)
    if x.shape != (n,) or not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be a finite vector of length n = {n}, got {value!r}")
    return x


def _initial_velocity(t: NDArray, q: NDArray) -> NDArray:
    """:math:`\\dot q(t_0)` of the polynomial through the first (up to) three observations."""
    if t.size < 3:
        return (q[1] - q[0]) / (t[1] - t[0])
    t0, t1, t2 = t[:3]
    c0 = (2 * t0 - t1 - t2) / ((t0 - t1) * (t0 - t2))
    c1 = (t0 - t2) / ((t1 - t0) * (t1 - t2))
    c2 = (t0 - t1) / ((t2 - t0) * (t2 - t1))
    return c0 * q[0] + c1 * q[1] + c2 * q[2]


def _residual_weights(weights, m: int, n: int) -> NDArray:
    """Square roots of the weights, broadcast to (m, n)."""
    if weights is None:
        return np.ones((m, n))
    w = np.asarray(weights, dtype=float)
    if w.ndim == 1:
        w = w[:, None] if w.size == m else w
    try:
        w = np.broadcast_to(w, (m, n)).copy()
    except ValueError:
        raise ValueError(
            f"weights must be a scalar or have shape (m,) or (m, n) = ({m}, {n}), "
            f"got {np.shape(weights)}"
        ) from None
    if not np.all(np.isfinite(w)) or np.any(w < 0):
        raise ValueError("weights must be finite and non-negative")
    return np.sqrt(w)


def _bounds(system, symbols, bounds, x0) -> tuple[NDArray, NDArray]:
    """Lower and upper bounds of the unknowns (the initial state is unbounded)."""
    lower, upper = np.full(x0.size, -np.inf), np.full(x0.size, np.inf)
    for key, pair in (bounds or {}).items():
        (s,) = parameter_symbols(system, [key])
        if s not in symbols:
            raise ValueError(f"bounds: {key!r} is not among the fitted parameters")
        i = symbols.index(s)
        lower[i], upper[i] = (float(b) for b in pair)
        if not lower[i] < x0[i] < upper[i]:
            raise ValueError(
                f"bounds: the starting value {x0[i]} of {s} is not inside ({lower[i]}, {upper[i]})"
            )
    return lower, upper


def _least_squares_options(options) -> dict:
    merged = dict(_DEFAULT_OPTIONS)
    for key, value in (options or {}).items():
        if key in _FORBIDDEN_OPTIONS:
            raise ValueError(f"options: {key!r} is set by fit_parameters")
        merged[key] = value
    return merged


def _covariance(J: NDArray, scale: float) -> tuple[NDArray, bool]:
    """:math:`\\mathrm{scale}\\,(J^\\top J)^{-1}` by the SVD, and whether J has full rank."""
    _, s, Vt = np.linalg.svd(J, full_matrices=False)
    k = J.shape[1]
    if s.size < k or s[-1] <= s[0] * max(J.shape) * np.finfo(float).eps:
        return np.full((k, k), np.inf), False
    return scale * (Vt.T / s**2) @ Vt, True


def _result(model, sol, q_obs, sqrt_w, used, absolute_weights, on_grid) -> ParameterFit:
    """The fit's result at the least-squares solution ``sol``."""
    Q, dQ = model.evaluate(sol.x)
    J = (sqrt_w[..., None] * dQ)[used]
    r = (sqrt_w * (Q - q_obs))[used]
    dof = r.size - sol.x.size
    variance = float(r @ r / dof) if dof > 0 else float("nan")
    scale = 1.0 if absolute_weights else variance
    full, regular = _covariance(J, scale)
    if sol.status <= 0:
        status = FitStatus.MAX_EVALUATIONS
    else:
        status = FitStatus.CONVERGED if regular else FitStatus.NOT_IDENTIFIABLE
    message = status.cause + (f" ({sol.message})" if status == FitStatus.CONVERGED else "")
    P = len(model.symbols)
    return ParameterFit(
        **_values_and_state(model, sol.x),
        standard_errors=np.sqrt(np.diag(full)[:P]),
        covariance=full[:P, :P],
        full_covariance=full,
        trajectory=_final_run(model, sol.x, on_grid),
        q_model=Q,
        residuals=Q - q_obs,
        cost=0.5 * float(r @ r),
        residual_variance=variance,
        nfev=int(sol.nfev),
        njev=int(sol.njev),
        status=status,
        message=message,
    )


def _values_and_state(model, x) -> dict:
    """The fields params, values, symbols, q0, v0, p0 at the unknowns ``x``."""
    initial = model.initial
    theta, q0, w0 = initial.split(x)
    _, p0, _ = initial.state(x)
    return {
        "params": dict(zip(model.symbols, (float(v) for v in theta), strict=True)),
        "values": np.array(theta, dtype=float),
        "symbols": model.symbols,
        "q0": np.array(q0, dtype=float),
        "v0": np.array(w0, dtype=float) if initial.kind == "velocity" else None,
        "p0": np.array(p0, dtype=float),
    }


def _final_run(model, x, on_grid: bool) -> Trajectory:
    """The run at ``x`` over the observations' span, every step saved."""
    initial = model.initial
    theta = initial.split(x)[0]
    q0, p0, _ = initial.state(x)
    params = dict(zip(model.symbols, (float(v) for v in theta), strict=True))
    first, last = model.segments[0], model.segments[-1]
    t_end = last.t0 + last.h * last.n_steps
    if on_grid:
        return model.integrator.integrate(
            q0, p0=p0, h=first.h, n_steps=first.n_steps, t0=first.t0, params=params, progress=False
        )
    h = max(seg.h for seg in model.segments)
    return model.integrator.integrate(q0, p0=p0, h=h, t_span=(first.t0, t_end),
                                      params=params, progress=False)  # fmt: skip


def _failed(model, x0, q_obs, exc: RunFailed) -> ParameterFit:
    """The result when the run at the starting values fails."""
    k, m, n = x0.size, q_obs.shape[0], q_obs.shape[1]
    P = len(model.symbols)
    nan = np.full((m, n), np.nan)
    full = np.full((k, k), np.nan)
    status = FitStatus.RUN_FAILED
    return ParameterFit(
        **_values_and_state(model, x0),
        standard_errors=np.full(P, np.nan),
        covariance=full[:P, :P],
        full_covariance=full,
        trajectory=exc.partial,
        q_model=nan,
        residuals=nan,
        cost=float("nan"),
        residual_variance=float("nan"),
        nfev=1,
        njev=0,
        status=status,
        message=f"{status.cause}: {exc}",
    )
