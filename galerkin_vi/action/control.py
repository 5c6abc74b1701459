r"""Optimal control through the discrete action (DMOC, Ober-Blöbaum, Junge, Marsden 2011).

Controls :math:`u` enter the system as forces :math:`f(t, q, v, u)` (declared
as parameters of the :class:`LagrangianSystem` that the forces depend on),
with a value at every quadrature point of every element. The discrete
Lagrange–d'Alembert equations of all steps (:mod:`.elements`: the residual
:math:`G` at every free control point, and the discrete Legendre transforms
at the ends where momenta are prescribed) are the equality constraints of a
nonlinear program whose objective is the running cost by the method's
quadrature,

.. math::

    J = \sum_k h \sum_i b_i\, C(t_{ki}, q_{ki}, v_{ki}, u_{ki}).

Every derivative is exact: the constraint Jacobian from the generated second
derivatives and :math:`\partial f/\partial u`, and the Hessian of the NLP's
Lagrangian :math:`J + \lambda\cdot c` point by point. At quadrature point
:math:`(k, i)` both depend on the point's :math:`w = (q, v, u)` only, through

.. math::

    \varphi_{ki}(w) = h b_i C(w) + \mu_q \cdot (L_q + f)(w) + \mu_v \cdot L_v(w),
    \qquad \mu_q = h b_i \sum_\nu \Phi_{i\nu}\Lambda_{k\nu},\quad
    \mu_v = b_i \sum_\nu D_{i\nu}\Lambda_{k\nu},

with :math:`\Lambda_{k\nu}` the multipliers of the rows of element
:math:`k`'s control points; its Hessian in :math:`w` is generated once by
SymPy, and the NLP Hessian is :math:`\sum A_{ki}^{\mathsf T}\nabla^2\varphi_{ki}A_{ki}`
with :math:`A_{ki}` the (linear) interpolation to the point.
"""

from __future__ import annotations

import numbers
import warnings
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem
from ..numeric import FlatEvaluator
from ..run.status import RunStatus, SolverResult
from ..run.trajectory import Trajectory
from .bvp import ActionStatus
from .elements import ElementPoints, element_gradients, element_jacobians

__all__ = ["OptimalControl", "solve_optimal_control"]

#: largest violation of the discrete equations and boundary conditions of a success
_FEASIBLE = 1e-8


@dataclass(frozen=True)
class OptimalControl(SolverResult):
    r"""The result of :func:`solve_optimal_control`.

    Attributes
    ----------
    trajectory : Trajectory
        Nodes and the momenta of the discrete Legendre transforms.
    control_points : ndarray, shape (N, s + 1, n)
    controls : ndarray, shape (N, r, m)
        The controls at every quadrature point, times in ``control_times``.
    control_times : ndarray, shape (N, r)
    cost : float
    multipliers : ndarray, shape (N + 1, n)
        The multipliers of the discrete equations at the nodes (the discrete
        costate, up to sign: :math:`\lambda_k \approx -\text{costate}(t_k)`),
        including those of prescribed end momenta.
    status : ActionStatus
        ``CONVERGED``; ``MAX_ITERATIONS`` when the optimizer reached ``maxiter``;
        ``INFEASIBLE`` when it stopped otherwise or left a constraint violation
        of 1e-8 or more. ``success`` is ``status >= 0``.
    message : str
        The optimizer's message, after the cause for a failure.
    iterations : int
    constraint_violation : float
    """

    trajectory: Trajectory
    control_points: NDArray[np.float64]
    controls: NDArray[np.float64]
    control_times: NDArray[np.float64]
    cost: float
    multipliers: NDArray[np.float64]
    status: ActionStatus
    message: str
    iterations: int
    constraint_violation: float


class _Problem:
    """Index maps, constraints, derivatives of one discretised optimal-control problem."""

    def __init__(self, system, method, controls, cost, t0, t1, N, q_start, q_end, p_start,
                 p_end, prm):  # fmt: skip
        self.system, self.method, self.N = system, method, N
        self.tables = tables = method.tables
        self.s, self.n, self.r, self.m = method.degree, system.n, tables.b.size, len(controls)
        self.h = (t1 - t0) / N
        self.t_nodes = t0 + self.h * np.arange(N + 1)
        self.q_start, self.q_end, self.p_start, self.p_end = q_start, q_end, p_start, p_end
        self.prm = prm
        names = list(system.params)
        self.control_slots = [names.index(u) for u in controls]
        s, n = self.s, self.n
        # unknown points: nodes 1..N-1, every element's interior points, then the end
        # nodes whose positions are free; each of the first (core) has its equation row
        point = -np.ones((N, s + 1), dtype=np.int64)
        point[1:, 0] = np.arange(N - 1)
        point[:-1, s] = np.arange(N - 1)
        point[:, 1:s] = (N - 1) + np.arange(N * (s - 1)).reshape(N, s - 1)
        core = (N - 1) + N * (s - 1)
        extra = core
        if q_start is None:
            point[0, 0], extra = extra, extra + 1
        if q_end is None:
            point[N - 1, s], extra = extra, extra + 1
        self.point = point
        self.n_points = extra
        self.n_core_rows = core * n
        self.n_states = self.n_points * n
        self.n_controls = N * self.r * self.m
        self.size = self.n_states + self.n_controls
        a = np.arange(n)
        self.state_index = np.where(point[..., None] >= 0, point[..., None] * n + a, -1)
        self.control_index = self.n_states + np.arange(self.n_controls).reshape(N, self.r, self.m)
        # rows: the core points' equations, then p_0 and p_N where prescribed
        self.p_start_rows = self.p_end_rows = None
        at = self.n_core_rows
        if p_start is not None:
            self.p_start_rows, at = at + a, at + n
        if p_end is not None:
            self.p_end_rows, at = at + a, at + n
        self.n_rows = at
        self._hessian_pieces(controls, cost)

    # -------------------------------------------------------------- layout
    def unpack(self, x: NDArray) -> tuple[NDArray, NDArray]:
        N, s, n = self.N, self.s, self.n
        X = np.empty((N, s + 1, n))
        free = self.state_index >= 0
        X[free] = x[self.state_index[free]]
        if self.q_start is not None:
            X[0, 0] = self.q_start
        if self.q_end is not None:
            X[-1, s] = self.q_end
        U = x[self.n_states :].reshape(N, self.r, self.m)
        return X, U

    def parameters(self, U: NDArray) -> list:
        values: list = list(self.prm)
        for j, slot in enumerate(self.control_slots):
            values[slot] = U[..., j]
        return values

    def points(self, X) -> ElementPoints:
        return ElementPoints.of(self.tables, self.t_nodes, self.h, X)

    # -------------------------------------------------------- constraints
    def constraints(self, x: NDArray) -> NDArray:
        X, U = self.unpack(x)
        G = element_gradients(self.system, self.tables, self.points(X), self.h,
                              self.parameters(U))  # fmt: skip
        return self._rows(G)

    def _rows(self, G: NDArray) -> NDArray:
        c = np.zeros(self.n_rows)
        rows, sign = self._row_of()
        keep = rows >= 0
        np.add.at(c, rows[keep], (sign * G)[keep])
        if self.p_start is not None:
            c[self.p_start_rows] -= self.p_start
        if self.p_end is not None:
            c[self.p_end_rows] -= self.p_end
        return c

    def _row_of(self) -> tuple[NDArray, NDArray]:
        """Row of each (element, point, coordinate) entry of G, with its sign; -1: none.

        The end nodes' entries are the discrete Legendre transforms: rows of the
        prescribed momenta (:math:`-G_0^0 = p_0`, :math:`G_{N-1}^s = p_N`), or none.
        """
        N, s = self.N, self.s
        rows = np.where(self.state_index >= 0, self.state_index, -1)
        sign = np.ones(rows.shape)
        rows[0, 0] = self.p_start_rows if self.p_start is not None else -1
        sign[0, 0] = -1.0
        rows[N - 1, s] = self.p_end_rows if self.p_end is not None else -1
        return rows, sign

    def constraint_jacobian(self, x: NDArray):
        import scipy.sparse

        X, U = self.unpack(x)
        prm = self.parameters(U)
        points = self.points(X)
        _, H = element_jacobians(self.system, self.tables, points, self.h, prm)
        rows, sign = self._row_of()
        entries_r, entries_c, values = [], [], []
        # d G_k^{nu a} / d X_k^{mu c}
        R = np.broadcast_to(rows[:, :, :, None, None], H.shape)
        S = np.broadcast_to(sign[:, :, :, None, None], H.shape)
        C = np.broadcast_to(self.state_index[:, None, None, :, :], H.shape)
        keep = (R >= 0) & (C >= 0)
        entries_r.append(R[keep])
        entries_c.append(C[keep])
        values.append((S * H)[keep])
        # d G_k^{nu a} / d u_{k i j} = h b_i Phi_{i nu} df_a/du_j
        dfdu = self._force_in_controls(points, prm)  # (N, r, n, m)
        b, Phi = self.tables.b, self.tables.Phi
        block = self.h * np.einsum("i,iv,kiaj->kvaij", b, Phi, dfdu)  # (N, s+1, n, r, m)
        R = np.broadcast_to(rows[:, :, :, None, None], block.shape)
        S = np.broadcast_to(sign[:, :, :, None, None], block.shape)
        C = np.broadcast_to(self.control_index[:, None, None, :, :], block.shape)
        keep = R >= 0
        entries_r.append(R[keep])
        entries_c.append(C[keep])
        values.append((S * block)[keep])
        return scipy.sparse.csr_matrix(
            (np.concatenate(values), (np.concatenate(entries_r), np.concatenate(entries_c))),
            shape=(self.n_rows, self.size),
        )

    def _force_in_controls(self, points: ElementPoints, prm) -> NDArray:
        values = self._dfdu(points.t, *np.moveaxis(points.q, -1, 0), *np.moveaxis(points.v, -1, 0),
                            *prm)  # fmt: skip
        return values.reshape(values.shape[:-1] + (self.n, self.m))

    # --------------------------------------------------------------- cost
    def cost(self, x: NDArray) -> float:
        X, U = self.unpack(x)
        values = self._point_cost(X, U)
        return float(self.h * (values @ self.tables.b).sum())

    def _point_cost(self, X, U) -> NDArray:
        p = self.points(X)
        prm = self.parameters(U)
        return self._cost(p.t, *np.moveaxis(p.q, -1, 0), *np.moveaxis(p.v, -1, 0), *prm)[..., 0]

    def cost_gradient(self, x: NDArray) -> NDArray:
        X, U = self.unpack(x)
        p = self.points(X)
        prm = self.parameters(U)
        grad = self._cost_grad(p.t, *np.moveaxis(p.q, -1, 0), *np.moveaxis(p.v, -1, 0), *prm)
        n, m = self.n, self.m
        cq, cv, cu = grad[..., :n], grad[..., n : 2 * n], grad[..., 2 * n :]
        t = self.tables
        w = self.h * t.b[None, :, None]
        local = np.einsum("iv,kia->kva", t.Phi, w * cq) + np.einsum(
            "iv,kia->kva", t.D, t.b[None, :, None] * cv
        )
        out = np.zeros(self.size)
        free = self.state_index >= 0
        np.add.at(out, self.state_index[free], local[free])
        out[self.n_states :] = (w * cu).reshape(-1) if m else 0.0
        return out

    # ------------------------------------------------------------ Hessian
    def _hessian_pieces(self, controls, cost) -> None:
        pieces = _control_pieces(self.system, tuple(controls), cost)
        self._phi_hessian, self._dfdu, self._cost, self._cost_grad = pieces

    def lagrangian_hessian(self, x: NDArray, cost_weight: float, lam: NDArray):
        """Sparse Hessian of cost_weight J + lam . c in x."""
        import scipy.sparse

        X, U = self.unpack(x)
        p = self.points(X)
        prm = self.parameters(U)
        N, s, n, r, m = self.N, self.s, self.n, self.r, self.m
        t = self.tables
        # the multipliers of each element's rows, per point nu (with the signs of the ends)
        rows, sign = self._row_of()
        Lam = np.where(rows >= 0, sign * lam[np.maximum(rows, 0)], 0.0)  # (N, s+1, n)
        mu_q = self.h * t.b[None, :, None] * np.einsum("iv,kva->kia", t.Phi, Lam)
        mu_v = t.b[None, :, None] * np.einsum("iv,kva->kia", t.D, Lam)
        weight = cost_weight * self.h * np.broadcast_to(t.b[None, :], (N, r))
        values = self._phi_hessian(
            p.t, *np.moveaxis(p.q, -1, 0), *np.moveaxis(p.v, -1, 0), *prm,
            *np.moveaxis(mu_q, -1, 0), *np.moveaxis(mu_v, -1, 0), weight,
        )  # fmt: skip
        dim = 2 * n + m
        Hw = values.reshape(N, r, dim, dim)
        # A_i maps (X_k (s+1, n), U_k (r, m)) to w_ki = (Phi X, D X / h, u_i)
        local_size = (s + 1) * n + r * m
        A = np.zeros((r, dim, local_size))
        for i in range(r):
            for nu in range(s + 1):
                for a in range(n):
                    A[i, a, nu * n + a] = t.Phi[i, nu]
                    A[i, n + a, nu * n + a] = t.D[i, nu] / self.h
            for j in range(m):
                A[i, 2 * n + j, (s + 1) * n + i * m + j] = 1.0
        local = np.einsum("ipx,kipq,iqy->kxy", A, Hw, A)
        index = np.concatenate(
            [self.state_index.reshape(N, -1), self.control_index.reshape(N, -1)], axis=1
        )
        R = np.broadcast_to(index[:, :, None], local.shape)
        C = np.broadcast_to(index[:, None, :], local.shape)
        keep = (R >= 0) & (C >= 0)
        return scipy.sparse.csr_matrix(
            (local[keep], (R[keep], C[keep])), shape=(self.size, self.size)
        )


def _control_pieces(system: LagrangianSystem, controls: tuple, cost: sp.Expr) -> tuple:
    """The evaluators of a control problem: the point Hessian of phi, df/du, C and its gradient.

    Derived and lambdified once per (controls, cost) and kept in ``system.derived``
    (a SymPy Hessian with CSE: a tenth of a second for the cart-pole).
    """
    return system.derived.get(
        ("control", controls, cost), lambda: _build_control_pieces(system, controls, cost)
    )


def _build_control_pieces(system: LagrangianSystem, controls: tuple, cost: sp.Expr) -> tuple:
    n = system.n
    p = system.pieces
    mu_q = sp.symbols(f"_mu_q0:{n}")
    mu_v = sp.symbols(f"_mu_v0:{n}")
    weight = sp.Symbol("_weight")
    w = [*system.q, *system.v, *controls]
    force = list(p.force)  # L_q + f
    phi = (
        weight * cost
        + sum(mq * e for mq, e in zip(mu_q, force, strict=True))
        + sum(mv * e for mv, e in zip(mu_v, p.Lv, strict=True))
    )
    args = system.arguments
    return (
        FlatEvaluator(list(sp.hessian(phi, w)), (*args, *mu_q, *mu_v, weight)),
        FlatEvaluator([sp.diff(e, u) for e in force for u in controls], args),
        FlatEvaluator([cost], args),
        FlatEvaluator([sp.diff(cost, y) for y in w], args),
    )


def solve_optimal_control(
    system: LagrangianSystem,
    method: Galerkin,
    controls: Sequence[sp.Symbol],
    cost: sp.Expr,
    t_span: tuple[float, float],
    n_steps: int,
    q_start: ArrayLike | None,
    q_end: ArrayLike | None,
    p_start: ArrayLike | None = None,
    p_end: ArrayLike | None = None,
    *,
    control_bounds: tuple[ArrayLike, ArrayLike] | None = None,
    state_bounds: tuple[ArrayLike, ArrayLike] | None = None,
    params=None,
    tol: float = 1e-10,
    maxiter: int = 1000,
    solver: str = "trust-constr",
) -> OptimalControl:
    r"""Controls and path that minimise a running cost subject to the discrete mechanics.

    Parameters
    ----------
    system : LagrangianSystem
        With forces depending on the control symbols, declared as parameters
        (their declared values are not used); no constraints, no contacts.
    method : Galerkin
    controls : sequence of sympy.Symbol
        The parameters that are controls: a value at every quadrature point.
    cost : sympy.Expr
        Running cost :math:`C(t, q, v, u)`.
    t_span, n_steps
        The horizon and the number of elements N.
    q_start, q_end : array_like, shape (n,), or None
        Positions at the ends; None leaves that end's position free.
    p_start, p_end : array_like, shape (n,), optional
        Momenta at the ends (discrete Legendre transforms), where prescribed;
        a free end without a momentum is left to the optimum.
    control_bounds : (lower, upper), optional
        Bounds on every control, each an array of shape (m,).
    state_bounds : (lower, upper), optional
        Bounds on the positions at every free control point, shape (n,) each.
    params : mapping, optional
        Values of the other parameters.
    tol, maxiter
        The solver's stopping tolerance (``trust-constr``: ``gtol`` and
        ``xtol``; IPOPT: ``tol``) and iteration limit.
    solver : {"trust-constr", "ipopt"}
        ``"trust-constr"``: SciPy, with the exact sparse Jacobian and Hessian
        above. ``"ipopt"``: IPOPT through CasADi (``pip install casadi``): the
        same discrete equations and cost written as CasADi expressions (the
        SymPy pieces printed for CasADi), differentiated exactly by its
        automatic differentiation, sparse.

    Returns
    -------
    OptimalControl
        Never raises for a solve that does not converge (``status``, ``message``).
    """
    import scipy.optimize

    if not isinstance(system, LagrangianSystem):
        raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    if not isinstance(method, Galerkin):
        raise TypeError(f"method must be a Galerkin method, got {type(method).__name__}")
    if system.m or system.contacts:
        raise ValueError("solve_optimal_control: constraints and contacts are not supported")
    controls = list(controls)
    if not controls or any(u not in system.params for u in controls):
        raise ValueError(f"controls must be parameters of the system {list(system.params)}, "
                         f"got {controls}")  # fmt: skip
    if set(controls) & system.L.free_symbols:
        raise ValueError("controls must enter through the forces only, not the Lagrangian")
    cost = sp.sympify(cost)
    allowed = set(system.arguments)
    if not cost.free_symbols <= allowed:
        raise ValueError(f"cost may depend on t, q, v and parameters only, not "
                         f"{cost.free_symbols - allowed}")  # fmt: skip
    t0, t1 = (float(x) for x in t_span)
    if not (np.isfinite(t0) and np.isfinite(t1) and t1 > t0):
        raise ValueError(f"t_span must have finite t0 < t1, got {t_span!r}")
    if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 1:
        raise ValueError(f"n_steps must be a positive int, got {n_steps!r}")
    n = system.n

    def vector(value, name):
        if value is None:
            return None
        x = np.asarray(value, dtype=float)
        if x.shape != (n,) or not np.all(np.isfinite(x)):
            raise ValueError(f"{name} must be {n} finite numbers, got {value!r}")
        return x

    prm = system.parameter_vector(params)
    problem = _Problem(
        system, method, controls, cost, t0, t1, int(n_steps), vector(q_start, "q_start"),
        vector(q_end, "q_end"), vector(p_start, "p_start"), vector(p_end, "p_end"), prm,
    )  # fmt: skip
    # first guess: the straight line in time, zero controls
    times = problem.t_nodes[:-1, None] + problem.tables.d[None, :] * problem.h
    fraction = (times - t0) / (t1 - t0)
    first = problem.q_start if problem.q_start is not None else problem.q_end
    last = problem.q_end if problem.q_end is not None else first
    first = first if first is not None else np.zeros(n)
    last = last if last is not None else first
    X0 = first + fraction[..., None] * (last - first)
    x0 = np.zeros(problem.size)
    free = problem.state_index >= 0
    x0[problem.state_index[free]] = X0[free]
    constraint = scipy.optimize.NonlinearConstraint(
        problem.constraints, 0.0, 0.0, jac=problem.constraint_jacobian,
        hess=lambda x, lam: problem.lagrangian_hessian(x, 0.0, lam),
    )  # fmt: skip
    constraints = [constraint]
    for name, bounds, first, count, width in (
        ("control_bounds", control_bounds, problem.n_states, problem.n_controls, problem.m),
        ("state_bounds", state_bounds, 0, problem.n_states, problem.n),
    ):
        if bounds is not None:
            constraints.append(_box(name, bounds, first, count, width, problem.size))
    if solver == "ipopt":
        return _result(problem, _ipopt(problem, controls, cost, x0, control_bounds, state_bounds,
                                       tol, maxiter))  # fmt: skip
    if solver != "trust-constr":
        raise ValueError(f"solver must be 'trust-constr' or 'ipopt', got {solver!r}")
    # with bounds, trust-constr's interior point: started with a small barrier and a wide
    # region (the bounded double integrator: 100 iterations against 1000 unconverged)
    barrier = {"initial_barrier_parameter": 1e-2, "initial_tr_radius": 10.0}
    if len(constraints) == 1:
        barrier = {}
    zeros = np.zeros(problem.n_rows)
    with warnings.catch_warnings():
        # scipy's projections fall back to an SVD when the active rows are dependent, and
        # say so at every iteration: nothing for the caller to act on
        warnings.filterwarnings("ignore", "Singular Jacobian matrix", UserWarning)
        solution = scipy.optimize.minimize(
            problem.cost, x0, method="trust-constr", jac=problem.cost_gradient,
            hess=lambda x: problem.lagrangian_hessian(x, 1.0, zeros),
            constraints=constraints,
            options={"gtol": tol, "xtol": tol, "maxiter": maxiter, **barrier},
        )  # fmt: skip
    return _result(problem, solution)


_CASADI_FUNCTIONS = ("sin", "cos", "tan", "asin", "acos", "atan", "sinh", "cosh", "tanh", "exp",
                     "log", "sqrt")  # fmt: skip


def _ipopt(problem: _Problem, controls, cost, x0, control_bounds, state_bounds, tol, maxiter):
    """Solve the NLP with IPOPT: the residuals and cost as CasADi expressions of the unknowns."""
    try:
        import casadi as ca
    except ImportError:
        raise ImportError("solver='ipopt' needs casadi: pip install casadi") from None
    from types import SimpleNamespace

    system = problem.system
    functions = {name: getattr(ca, name) for name in _CASADI_FUNCTIONS}
    functions.update(Abs=ca.fabs, atan2=ca.atan2)
    pieces = system.pieces
    point = sp.lambdify(system.arguments, [*pieces.force, *pieces.Lv, cost],
                        modules=[functions, "math"])  # fmt: skip
    N, s, n, r, m = problem.N, problem.s, problem.n, problem.r, problem.m
    t = problem.tables
    h = problem.h
    x = ca.SX.sym("x", problem.size)
    X = [[None] * (s + 1) for _ in range(N)]
    for k in range(N):
        for nu in range(s + 1):
            idx = problem.state_index[k, nu]
            if idx[0] >= 0:
                X[k][nu] = ca.vertcat(*[x[int(i)] for i in idx])
            else:  # a fixed end
                X[k][nu] = ca.DM(problem.q_start if (k, nu) == (0, 0) else problem.q_end)
    rows = [0] * problem.n_rows
    row_of, sign = problem._row_of()
    total = 0
    for k in range(N):
        G = [ca.SX.zeros(n) for _ in range(s + 1)]
        for i in range(r):
            q_i = sum(t.Phi[i, nu] * (X[k][nu] - X[k][0]) for nu in range(1, s + 1)) + X[k][0]
            v_i = sum(t.D[i, nu] * (X[k][nu] - X[k][0]) for nu in range(1, s + 1)) / h
            prm = list(problem.prm)
            for j, slot in enumerate(problem.control_slots):
                prm[slot] = x[int(problem.control_index[k, i, j])]
            values = point(problem.t_nodes[k] + t.c[i] * h, *[q_i[a] for a in range(n)],
                           *[v_i[a] for a in range(n)], *prm)  # fmt: skip
            force, lv, c_i = ca.vertcat(*values[:n]), ca.vertcat(*values[n : 2 * n]), values[-1]
            total += h * t.b[i] * c_i
            for nu in range(s + 1):
                G[nu] += h * t.b[i] * t.Phi[i, nu] * force + t.b[i] * t.D[i, nu] * lv
        for nu in range(s + 1):
            for a in range(n):
                row = int(row_of[k, nu, a])
                if row >= 0:
                    rows[row] = rows[row] + sign[k, nu, a] * G[nu][a]
    for at, value in ((problem.p_start_rows, problem.p_start), (problem.p_end_rows, problem.p_end)):
        if value is not None:
            for a in range(n):
                rows[int(at[a])] = rows[int(at[a])] - value[a]
    c = ca.vertcat(*rows)
    lower = np.full(problem.size, -np.inf)
    upper = np.full(problem.size, np.inf)
    for bounds, first, count, width in (
        (control_bounds, problem.n_states, problem.n_controls, m),
        (state_bounds, 0, problem.n_states, n),
    ):
        if bounds is not None:
            lo, hi = (np.broadcast_to(np.asarray(b, dtype=float), (width,)) for b in bounds)
            lower[first : first + count] = np.tile(lo, count // width)
            upper[first : first + count] = np.tile(hi, count // width)
    nlp = ca.nlpsol("dmoc", "ipopt", {"x": x, "f": total, "g": c},
                    {"print_time": False, "ipopt": {"print_level": 0, "sb": "yes", "tol": tol,
                                                    "max_iter": maxiter}})  # fmt: skip
    out = nlp(x0=x0, lbx=lower, ubx=upper, lbg=0.0, ubg=0.0)
    stats = nlp.stats()
    return SimpleNamespace(
        x=np.asarray(out["x"]).ravel(), v=[np.asarray(out["lam_g"]).ravel()],
        status=_ipopt_status(stats), nit=stats.get("iter_count", 0),
        message=stats["return_status"],
    )  # fmt: skip


def _ipopt_status(stats: dict) -> int:
    """IPOPT's outcome as a ``trust-constr`` status: 1 solved, 0 maxiter, -1 otherwise."""
    if stats["success"]:
        return 1
    return 0 if stats["return_status"] == "Maximum_Iterations_Exceeded" else -1


def _control_status(solver_status: int, violation: float) -> ActionStatus:
    """The status of a solve from the optimizer's (``trust-constr``'s codes) and the violation.

    ``trust-constr``: 1 and 2 its tolerances met, 0 ``maxiter`` reached.
    """
    if solver_status in (1, 2) and violation < _FEASIBLE:
        return ActionStatus.CONVERGED
    if solver_status == 0:
        return ActionStatus.MAX_ITERATIONS
    return ActionStatus.INFEASIBLE


def _box(name: str, bounds, first: int, count: int, width: int, size: int):
    """Linear constraint lower <= x[first:first + count] <= upper, bounds per component."""
    import scipy.optimize
    import scipy.sparse

    try:
        lo, hi = (np.broadcast_to(np.asarray(b, dtype=float), (width,)) for b in bounds)
    except (TypeError, ValueError):
        raise ValueError(f"{name} must be (lower, upper), each of {width} numbers") from None
    if np.any(lo > hi):
        raise ValueError(f"{name}: lower {lo} above upper {hi}")
    # on these variables alone: Bounds would put every variable in the barrier
    select = scipy.sparse.csr_matrix(
        (np.ones(count), (np.arange(count), first + np.arange(count))), shape=(count, size)
    )
    reps = count // width
    return scipy.optimize.LinearConstraint(select, np.tile(lo, reps), np.tile(hi, reps))


def _result(problem: _Problem, solution) -> OptimalControl:
    X, U = problem.unpack(solution.x)
    prm = problem.parameters(U)
    G = element_gradients(problem.system, problem.tables, problem.points(X), problem.h, prm)
    nodes = np.concatenate([X[:, 0], X[-1:, -1]])
    p = np.concatenate([-G[:, 0], G[-1:, -1]])
    lam = np.asarray(solution.v[0]) if getattr(solution, "v", None) else np.zeros(problem.n_rows)
    rows, sign = problem._row_of()
    ends = np.concatenate([rows[:, 0], rows[-1:, -1]])  # (N + 1, n): node k's row
    signs = np.concatenate([sign[:, 0], sign[-1:, -1]])
    node_multipliers = np.where(ends >= 0, signs * lam[np.maximum(ends, 0)], 0.0)
    violation = float(np.abs(problem.constraints(solution.x)).max(initial=0.0))
    status = _control_status(int(solution.status), violation)
    success = status == ActionStatus.CONVERGED
    message = str(solution.message)
    if not success:
        message = f"{status.cause} ({message}; constraint violation {violation:.1e})"
    trajectory = Trajectory(
        t=problem.t_nodes.copy(), q=nodes, p=p, newton_iterations=np.zeros(0, dtype=np.uint8),
        max_residual=violation, system=problem.system, params=problem.prm,
        total_newton_iterations=int(solution.nit), n_steps=problem.N,
        status=RunStatus.COMPLETED if success else RunStatus.NO_CONVERGENCE,
        message=message, order=problem.method.order,
    )  # fmt: skip
    control_times = problem.t_nodes[:-1, None] + problem.tables.c[None, :] * problem.h
    return OptimalControl(
        trajectory=trajectory, control_points=X, controls=U, control_times=control_times,
        cost=problem.cost(solution.x), multipliers=node_multipliers, status=status,
        message=message, iterations=int(solution.nit),
        constraint_violation=violation,
    )  # fmt: skip
