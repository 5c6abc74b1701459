r"""Two-point boundary-value problems: the path at which the discrete action is stationary.

Given :math:`q(t_0) = q_a` and :math:`q(t_1) = q_b`, :func:`solve_bvp` finds
every node :math:`q_1, \dots, q_{N-1}` and every element's interior control
points at once, from :math:`\partial S_d / \partial q_c = 0` at each free
control point :math:`c` (see :mod:`.elements`): the discrete Euler–Lagrange
equations of all steps together. Newton's method with the exact Jacobian,
condensed element by element and solved as a banded chain
(:mod:`.condensation`), costs :math:`O(N n^3)` per iteration. The path is a
stationary point, not a minimum: beyond the first conjugate point the
Jacobian is indefinite, and Newton does not care.

The nodes inherit the method's superconvergence: for a regular problem the
nodal error is :math:`O(h^{2s})` with full quadrature (the method's
``order``), as in time-stepping, and the discrete action converges at the
same order. The momenta at the nodes are the discrete Legendre transforms,
:math:`p_k = -\partial S_k / \partial q_k` and :math:`p_N = \partial S_{N-1} / \partial q_N`.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..method.basis import LagrangeBasis
from ..method.galerkin import Galerkin, MethodTables
from ..model.constraints import project_momentum
from ..model.system import LagrangianSystem
from ..numeric import FlatEvaluator
from ..run.dense import DenseOutput, stencil_nodes
from ..run.status import RunStatus, SolverResult, SolverStatus
from ..run.trajectory import Trajectory
from .condensation import condense, solve_node_chain
from .elements import ElementPoints, element_actions, element_gradients, element_jacobians
from .multipliers import augment

__all__ = ["ActionStatus", "BoundaryValueResult", "solve_bvp"]


class ActionStatus(SolverStatus):
    """How a solve of the discrete action's stationarity (or an optimal control) ended.

    As every :class:`~galerkin_vi.run.status.SolverStatus`: 0 success, negative
    a failure, ``success == (status >= 0)``.
    """

    CONVERGED = 0
    MAX_ITERATIONS = -1
    SINGULAR_JACOBIAN = -2
    NON_FINITE = -3
    NO_DESCENT = -4
    INFEASIBLE = -5

    @property
    def cause(self) -> str:
        """The cause in words, for messages."""
        return _CAUSES[self]


_CAUSES = {
    ActionStatus.CONVERGED: "the Newton iteration converged",
    ActionStatus.MAX_ITERATIONS: "the Newton iteration reached maxiter without converging",
    ActionStatus.SINGULAR_JACOBIAN: "the Jacobian of the stationarity equations is singular "
    "(a conjugate point, or a degenerate guess)",
    ActionStatus.NON_FINITE: "non-finite values (NaN or inf) appeared",
    ActionStatus.NO_DESCENT: "no step along Newton's direction reduced the residual "
    "(a guess too far from a solution)",
    ActionStatus.INFEASIBLE: "the optimizer stopped without meeting the discrete equations "
    "and the boundary conditions",
}

# the compiled Newton iteration (loops/action.py) returns these codes
_LOOP_CODES = {
    0: ActionStatus.CONVERGED,
    1: ActionStatus.MAX_ITERATIONS,
    2: ActionStatus.SINGULAR_JACOBIAN,
    3: ActionStatus.NON_FINITE,
    4: ActionStatus.NO_DESCENT,
}


@dataclass(frozen=True)
class BoundaryValueResult(SolverResult):
    r"""The result of :func:`solve_bvp` (fields as scipy's results name them).

    Attributes
    ----------
    trajectory : Trajectory
        Nodes :math:`t_k, q_k` and the momenta of the discrete Legendre
        transforms (projected on the hidden constraint where there are
        constraints).
    control_points : ndarray, shape (N, s + 1, n)
        Every element's control points (the nodes are ``[:, 0]`` and ``[-1, -1]``).
    multipliers : ndarray, shape (N, s, m), or None
        The constraints' multipliers at each element's points :math:`\nu = 0..s-1`.
    action : float
        :math:`S_d = \sum_k S_k`, the discrete action of the path.
    status : ActionStatus
    message : str
    iterations : int
        Newton iterations taken.
    residual : float
        Largest stationarity residual at the returned path (momentum units).
    method : Galerkin
        The method whose discrete action was made stationary.
    """

    trajectory: Trajectory
    control_points: NDArray[np.float64]
    multipliers: NDArray[np.float64] | None
    action: float
    status: ActionStatus
    message: str
    iterations: int
    residual: float
    method: Galerkin

    def positions(self, t: ArrayLike) -> NDArray[np.float64]:
        """The path :math:`q(t)` between the nodes: each element's polynomial, shape (m, n).

        ``t`` (m,) inside ``t_span``; a time on a node takes the element that
        starts there. The polynomials are the solution's, not an interpolant
        of its nodes: their error is the method's stage error, :math:`O(h^{s+1})`
        (between nodes) against :math:`O(h^{2s})` at the nodes.
        """
        nodes = self.trajectory.t
        t = np.atleast_1d(np.asarray(t, dtype=float))
        if (
            t.ndim != 1
            or t.min() < nodes[0] - 1e-12 * abs(nodes[-1] - nodes[0])
            or (t.max() > nodes[-1] + 1e-12 * abs(nodes[-1] - nodes[0]))
        ):
            raise ValueError(f"t must be a 1-d array inside [{nodes[0]}, {nodes[-1]}]")
        h = (nodes[-1] - nodes[0]) / (nodes.size - 1)
        k = np.clip(((t - nodes[0]) // h).astype(int), 0, nodes.size - 2)
        weights = LagrangeBasis(self.method.tables.d).values(np.clip((t - nodes[k]) / h, 0, 1))
        return np.einsum("mv,mva->ma", weights, self.control_points[k])

    def path_integral(self, expr: sp.Expr) -> float:
        r""":math:`\int_{t_0}^{t_1} f(t, q, v)\,dt` along the path, by the method's quadrature.

        ``expr`` is a SymPy expression in the system's t, q, v and parameters
        (a length :math:`\int\sqrt{1 + y'^2}\,dx`, a cost); evaluated on every
        element's polynomial, so it converges at the method's order.
        """
        traj = self.trajectory
        tables = self.method.tables
        h = (traj.t[-1] - traj.t[0]) / (traj.t.size - 1)
        points = ElementPoints.of(tables, traj.t, h, self.control_points)
        system = traj.system
        values = FlatEvaluator([sp.sympify(expr)], system.arguments)(
            points.t, *np.moveaxis(points.q, -1, 0), *np.moveaxis(points.v, -1, 0), *traj.params
        )[..., 0]
        return float(h * (values @ tables.b).sum())


def _vector(value: ArrayLike, n: int, name: str) -> NDArray[np.float64]:
    x = np.asarray(value, dtype=float)
    if x.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},) (one entry per coordinate), got {x.shape}")
    if not np.all(np.isfinite(x)):
        raise ValueError(f"{name} must be finite, got {x}")
    return x


def _check_arguments(system, method, t_span, n_steps) -> tuple[float, float, int]:
    if not isinstance(system, LagrangianSystem):
        raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    if not isinstance(method, Galerkin):
        raise TypeError(f"method must be a Galerkin method, got {type(method).__name__}")
    if system.contacts:
        raise ValueError("solve_bvp: a system with contacts is not supported (unilateral "
                         "constraints make the action non-smooth); drop contacts=")  # fmt: skip
    try:
        t0, t1 = (float(x) for x in t_span)
    except (TypeError, ValueError):
        raise ValueError(f"t_span must be a pair of numbers (t0, t1), got {t_span!r}") from None
    if not (np.isfinite(t0) and np.isfinite(t1) and t1 > t0):
        raise ValueError(f"t_span must have finite t0 < t1, got {t_span!r}")
    if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 1:
        raise ValueError(f"n_steps must be a positive int, got {n_steps!r}")
    return t0, t1, int(n_steps)


def initial_path(
    guess, q_start: NDArray, q_end: NDArray, times: NDArray, t_nodes: NDArray
) -> NDArray[np.float64]:
    """Control points (N, s + 1, n) of the guess at the control-point ``times`` (N, s + 1).

    ``guess`` is None (the straight line in time from ``q_start`` to ``q_end``),
    a callable ``q(t)``, an array of the N + 1 nodes (interpolated linearly in
    between), a :class:`Trajectory` (interpolated linearly in its times) or a
    :class:`BoundaryValueResult` (its control points, on the same mesh; its
    nodes otherwise).
    """
    N, s1 = times.shape
    n = q_start.size
    if isinstance(guess, BoundaryValueResult):
        if guess.control_points.shape == (N, s1, n):
            return guess.control_points.copy()
        guess = guess.trajectory
    if guess is None:
        fraction = (times - t_nodes[0]) / (t_nodes[-1] - t_nodes[0])
        return q_start + fraction[..., None] * (q_end - q_start)
    if isinstance(guess, Trajectory):
        t, q = guess.t, guess.q
        if q.shape[1] != n:
            raise ValueError(f"guess: a trajectory of {q.shape[1]} coordinates, expected {n}")
        if t[0] > t_nodes[0] + 1e-12 or t[-1] < t_nodes[-1] - 1e-12:
            raise ValueError(f"guess: the trajectory spans [{t[0]}, {t[-1]}], not t_span")
        return np.stack([np.interp(times, t, q[:, a]) for a in range(n)], axis=-1)
    if callable(guess):
        values = np.array([np.asarray(guess(t), dtype=float) for t in times.ravel()])
        if values.shape != (times.size, n):
            raise ValueError(f"guess(t) must return {n} coordinates, got shape {values.shape[1:]}")
        return values.reshape(N, s1, n)
    nodes = np.asarray(guess, dtype=float)
    if nodes.shape != (N + 1, n):
        raise ValueError(
            f"guess must be None, a callable q(t), a Trajectory or an array of the {N + 1} "
            f"nodes, shape ({N + 1}, {n}); got shape {nodes.shape}"
        )
    return np.stack([np.interp(times, t_nodes, nodes[:, a]) for a in range(n)], axis=-1)


@dataclass
class _Path:
    """The unknowns: nodes (N + 1, n), interior points (N, s - 1, n), multipliers (N, s, m)."""

    nodes: NDArray
    interior: NDArray
    lam: NDArray

    @property
    def X(self) -> NDArray:
        return np.concatenate([self.nodes[:-1, None], self.interior, self.nodes[1:, None]], axis=1)

    def moved(self, node_step: NDArray, interior_step: NDArray, n: int, alpha: float) -> _Path:
        lam = self.lam.copy()
        lam[:, 0] += alpha * node_step[:-1, n:]
        lam[:, 1:] += alpha * interior_step[..., n:]
        return _Path(
            self.nodes + alpha * node_step[:, :n], self.interior + alpha * interior_step[..., :n],
            lam,
        )  # fmt: skip


class _Stationarity:
    """Residuals and Newton steps of one boundary-value problem."""

    def __init__(self, system, method: Galerkin, t_nodes, h, prm):
        self.system, self.t_nodes, self.h, self.prm = system, t_nodes, h, prm
        self.method = method
        self.tables: MethodTables = method.tables
        self.order = method.order
        N = t_nodes.size - 1
        self.free = np.ones(N + 1, dtype=bool)
        self.free[[0, -1]] = False

    def _points(self, path: _Path) -> tuple[NDArray, ElementPoints]:
        X = path.X
        return X, ElementPoints.of(self.tables, self.t_nodes, self.h, X)

    def _with_constraints(self, path, X, G, H=None):
        if not self.system.m:
            return G, H
        return augment(self.system, self.tables, self.t_nodes, self.h, X, path.lam, self.prm, G, H)

    def residuals(self, path: _Path, G: NDArray | None = None) -> NDArray[np.float64]:
        """The free points' equations, flattened: node sums and interior points."""
        if G is None:
            X, points = self._points(path)
            G, _ = self._with_constraints(
                path, X, element_gradients(self.system, self.tables, points, self.h, self.prm)
            )
        s = G.shape[1] - 1
        nodes = np.zeros((G.shape[0] + 1, G.shape[2]))
        nodes[:-1] += G[:, 0]
        nodes[1:] += G[:, s]
        return np.concatenate([nodes[self.free].ravel(), G[:, 1:s].ravel()])

    @staticmethod
    def merit(R: NDArray) -> float:
        """Sum of squares: Newton's direction descends on it, whatever the Jacobian's inertia."""
        value = float(R @ R)
        return value if np.isfinite(value) else np.inf

    def residual(self, path: _Path) -> float:
        """Largest residual of the free points' equations."""
        value = np.abs(self.residuals(path)).max(initial=0.0)
        return float(value) if np.isfinite(value) else np.inf

    def newton_step(self, path: _Path) -> tuple[float, NDArray, NDArray]:
        """(merit, node step (N + 1, w), interior step (N, s - 1, w)) at ``path``."""
        X, points = self._points(path)
        G, H = element_jacobians(self.system, self.tables, points, self.h, self.prm)
        G, H = self._with_constraints(path, X, G, H)
        residual = self.merit(self.residuals(path, G))
        if not np.isfinite(residual) or not np.all(np.isfinite(H)):
            raise FloatingPointError
        condensed = condense(H, G)
        node_step = solve_node_chain(condensed, self.free)
        return residual, node_step, condensed.interior_step(node_step)


def solve_bvp(
    system: LagrangianSystem,
    method: Galerkin,
    q_start: ArrayLike,
    q_end: ArrayLike,
    t_span: tuple[float, float],
    n_steps: int,
    guess: None | Callable | ArrayLike | Trajectory = None,
    *,
    params=None,
    tol: float = 1e-12,
    maxiter: int = 50,
    backend: str = "auto",
) -> BoundaryValueResult:
    r"""The path from ``q_start`` to ``q_end`` at which the discrete action is stationary.

    Parameters
    ----------
    system : LagrangianSystem
        Without contacts; constraints and forces as in time-stepping (forces
        by the discrete Lagrange–d'Alembert principle).
    method : Galerkin
    q_start, q_end : array_like, shape (n,)
        :math:`q(t_0)` and :math:`q(t_1)`; with constraints they must satisfy them.
    t_span : (float, float)
    n_steps : int
        Number of elements N, each of length :math:`h = (t_1 - t_0)/N`.
    guess : None, callable, array_like, Trajectory or BoundaryValueResult
        Initial path: None for the straight line in time, a callable
        ``q(t)``, the N + 1 nodes (shape (N + 1, n)), a trajectory, or an
        earlier result (continuation: its control points on the same mesh).
    params : mapping, optional
        Parameter values (the system's defaults otherwise).
    tol : float
        Converged when the Newton step is below ``tol (1 + max|q|)``.
    maxiter : int
        Newton iterations at most.
    backend : {"auto", "numba", "numpy"}
        ``"auto"``: the compiled Newton iteration (:mod:`galerkin_vi.loops.action`)
        where it applies (numba, no constraints, dense second derivatives),
        else NumPy, vectorised over the elements; the two agree to round-off.

    Returns
    -------
    BoundaryValueResult
        Never raises for a solve that does not converge: ``status`` says why
        and the last iterate is kept.

    Raises
    ------
    ValueError, TypeError
        For bad input: shapes, a t_span with t1 <= t0, ends off the constraints.

    Examples
    --------
    >>> import sympy as sp, galerkin_vi as gvi
    >>> q, v = sp.symbols("q v")
    >>> oscillator = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])
    >>> res = gvi.solve_bvp(oscillator, gvi.Galerkin(3), [1.0], [0.5], (0.0, 2.0), 10)
    >>> res.status, res.iterations
    (<ActionStatus.CONVERGED: 0>, 2)
    """
    t0, t1, N = _check_arguments(system, method, t_span, n_steps)
    n, m = system.n, system.m
    q_start = _vector(q_start, n, "q_start")
    q_end = _vector(q_end, n, "q_end")
    if not (isinstance(tol, numbers.Real) and 0 < tol < 1):
        raise ValueError(f"tol must be a real number in (0, 1), got {tol!r}")
    if isinstance(maxiter, bool) or not isinstance(maxiter, numbers.Integral) or maxiter < 1:
        raise ValueError(f"maxiter must be a positive int, got {maxiter!r}")
    prm = system.parameter_vector(params)
    for name, q, t in (("q_start", q_start, t0), ("q_end", q_end, t1)):
        if m:
            g = system.evaluate("g", t, q, np.zeros(n), prm)
            if np.abs(g).max() > 1e-10 * (1 + np.abs(q).max()):
                raise ValueError(f"{name} = {q} violates the constraints: g = {g}")
    tables = method.tables
    s = method.degree
    h = (t1 - t0) / N
    t_nodes = t0 + h * np.arange(N + 1)
    t_nodes[-1] = t1
    X0 = initial_path(guess, q_start, q_end, t_nodes[:-1, None] + tables.d * h, t_nodes)
    nodes = np.concatenate([X0[:, 0], X0[-1:, s]])
    nodes[0], nodes[-1] = q_start, q_end
    path = _Path(nodes, X0[:, 1:s].copy(), np.zeros((N, s, m)))
    problem = _Stationarity(system, method, t_nodes, h, prm)
    if backend not in ("auto", "numba", "numpy"):
        raise ValueError(f"backend must be 'auto', 'numba' or 'numpy', got {backend!r}")
    compiled = None if backend == "numpy" else _compiled_points(system, method)
    if backend == "numba" and compiled is None:
        raise ValueError("backend='numba': the compiled iteration needs numba, no constraints "
                         "and dense second derivatives; use backend='auto'")  # fmt: skip
    if compiled is not None:
        return _compiled_solve(problem, compiled, path, tol, maxiter)
    status, iterations = ActionStatus.MAX_ITERATIONS, 0
    for iterations in range(1, maxiter + 1):  # noqa: B007 (the count is reported)
        try:
            residual, node_step, interior_step = problem.newton_step(path)
        except np.linalg.LinAlgError:
            status = ActionStatus.SINGULAR_JACOBIAN
            break
        except FloatingPointError:
            status = ActionStatus.NON_FINITE
            break
        if not (np.all(np.isfinite(node_step)) and np.all(np.isfinite(interior_step))):
            status = ActionStatus.NON_FINITE
            break
        size = max(np.abs(node_step).max(), np.abs(interior_step).max(initial=0.0))
        scale = 1.0 + np.abs(path.nodes).max()
        trial, alpha = path.moved(node_step, interior_step, n, 1.0), 1.0
        if size > 1e-6 * scale:  # far out: backtrack on the residual; near: Newton as it is
            while problem.merit(problem.residuals(trial)) > (1 - 2e-4 * alpha) * residual:
                alpha /= 2
                if alpha < 1e-4:
                    break
                trial = path.moved(node_step, interior_step, n, alpha)
            if alpha < 1e-4:
                status = ActionStatus.NO_DESCENT
                break
        path = trial
        if size <= tol * scale:
            status = ActionStatus.CONVERGED
            break
    return _result(problem, path, status, iterations)


def _compiled_points(system: LagrangianSystem, method: Galerkin):
    """(fn, traits) for the compiled Newton iteration, or None where the NumPy path serves.

    Compiled: numba available, no constraints, dense second derivatives. Kept on
    the system per method (looking the addresses up costs about half a millisecond).
    """
    if system.m:
        return None
    return system.derived.get(("action", "points", method), lambda: _load_points(system, method))


def _load_points(system: LagrangianSystem, method: Galerkin):
    """(fn, traits) of the Newton iteration's point functions, or None without numba."""
    from ..integrator import Integrator

    integrator = Integrator(system, method)
    if integrator.backend != "numba" or integrator.uses_banded_storage:
        return None
    return integrator.compiled_point_functions(("point_gradient", "point_hessian", "lagrangian"))


def _compiled_solve(problem: _Stationarity, compiled, path: _Path, tol, maxiter):
    from ..loops.action import stationary_path
    from ..loops.readiness import ensure_loops

    ensure_loops()  # unreadable cache files go before the loop loads

    fn, traits = compiled
    tables = problem.tables
    X = np.ascontiguousarray(path.X)
    info = np.zeros(4)
    P = np.zeros_like(path.nodes)
    W = np.zeros_like(path.nodes)
    slopes = LagrangeBasis(tables.d).derivatives(np.array([0.0, 1.0]))
    code = stationary_path(
        fn, traits, problem.t_nodes, problem.h, tables.b, tables.c, tables.Phi, tables.D, X,
        problem.prm, float(tol), int(maxiter), info, P, slopes[0].copy(), slopes[1].copy(), W,
    )  # fmt: skip
    s = X.shape[1] - 1
    nodes = np.concatenate([X[:, 0], X[-1:, s]])
    solved = _Path(nodes, X[:, 1:s].copy(), path.lam)
    return _result(problem, solved, _LOOP_CODES[int(code)], int(info[0]),
                   computed=(P, float(info[3]), float(info[2])), velocities=W)  # fmt: skip


def _result(
    problem: _Stationarity, path: _Path, status, iterations, computed=None, velocities=None
) -> BoundaryValueResult:
    """The result at ``path``; ``computed``: (momenta, action, residual) if known already.

    With the node ``velocities`` known (the compiled path), the trajectory
    carries its dense output (``trajectory.sol``) without inverting the
    Legendre transform again.
    """
    system, tables, h, prm = problem.system, problem.tables, problem.h, problem.prm
    X = path.X
    if computed is None:
        points = ElementPoints.of(tables, problem.t_nodes, h, X)
        G = element_gradients(system, tables, points, h, prm)
        action = float(element_actions(system, tables, points, h, prm).sum())
        residual = problem.residual(path)
        p = np.concatenate([-G[:, 0], G[-1:, -1]])
    else:
        p, action, residual = computed
    t = problem.t_nodes
    if system.m:
        values = dict(zip(system.params, prm, strict=True))
        guesses = [system.inverse_legendre(qk, pk, tk, values)
                   for tk, qk, pk in zip(t, path.nodes, p, strict=True)]  # fmt: skip
        p = np.array([
            project_momentum(system, tk, qk, pk, vk, prm)[0]
            for tk, qk, pk, vk in zip(t, path.nodes, p, guesses, strict=True)
        ])  # fmt: skip
    success = status == ActionStatus.CONVERGED
    sol = None
    if velocities is not None:
        stencil = stencil_nodes(problem.order)
        sol = DenseOutput(
            t=t.copy(), q=path.nodes.copy(), v=velocities, stencil=stencil, system=system,
            params=prm,
        )  # fmt: skip
    trajectory = Trajectory(
        t=t.copy(),
        q=path.nodes.copy(),
        p=p,
        newton_iterations=np.zeros(0, dtype=np.uint8),
        max_residual=residual,
        system=system,
        params=prm,
        total_newton_iterations=iterations,
        n_steps=t.size - 1,
        status=RunStatus.COMPLETED if success else RunStatus.NO_CONVERGENCE,
        message=status.cause,
        order=problem.order,
        sol=sol,
    )

    return BoundaryValueResult(
        trajectory=trajectory,
        control_points=X,
        multipliers=path.lam if system.m else None,
        action=action,
        status=status,
        message=status.cause,
        iterations=iterations,
        residual=residual,
        method=problem.method,
    )
