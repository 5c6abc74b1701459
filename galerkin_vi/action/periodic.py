r"""Periodic orbits: closed discrete paths at which the discrete action is stationary.

A periodic orbit of period :math:`T` is a closed path: :math:`N` elements of
length :math:`h = T/N` whose last node is the first, :math:`q_N = q_0`. Its
equations are those of :mod:`.bvp` at every control point, node 0 included
(:math:`D_2 L_d(q_{N-1}, q_0) + D_1 L_d(q_0, q_1) = 0`): a cyclic system.

Symmetries make it singular. A symmetry of the Lagrangian with generator
:math:`\xi` (a translation, a rotation acting linearly) moves a closed path
along a family of closed paths, so :math:`J\xi = 0`; so does, nearly, a shift
in time of an autonomous system (exactly only in the limit :math:`h \to 0`).
Each such direction is removed by a border: the Newton step is kept
orthogonal to it, and a multiplier :math:`\mu_j` takes up the residual's
component along it,

.. math::

    \begin{pmatrix} J & B \\ B^{\mathsf T} & 0 \end{pmatrix}
    \begin{pmatrix} \Delta \\ \mu \end{pmatrix}
    = -\begin{pmatrix} R \\ 0 \end{pmatrix},

with the columns of :math:`B` the generators at every control point (for the
time shift: the path's velocity). At a solution :math:`R = 0` and
:math:`\mu = 0`.

With ``energy`` given, the period is an unknown too (periodic orbits of a
conservative system come in one-parameter families along the energy), with
the equation :math:`E(q_0, p_0) = E^*`, :math:`p_0 = -\partial S_0/\partial q_0`,
and the exact derivative of every residual in :math:`h`,

.. math::

    \frac{\partial G^\nu_a}{\partial h} = \sum_i b_i \big[\Phi_{i\nu} L_{q_a}
    - \Phi_{i\nu} L_{q_a v_c} V_c - D_{i\nu} L_{v_a v_c} V_c / h\big]^{(i)},

since the velocities at the quadrature points are :math:`V = \sum_\nu D_{i\nu}
q^\nu / h`. The sparse bordered system is solved by sparse LU
(:func:`scipy.sparse.linalg.splu`); its band and one corner block (the cycle)
keep the fill-in linear in N.
"""

from __future__ import annotations

import numbers
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cached_property

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..method.basis import LagrangeBasis
from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem
from ..numeric import FlatEvaluator
from ..run.status import RunStatus, SolverResult
from ..run.trajectory import Trajectory
from .bvp import ActionStatus
from .elements import ElementPoints, element_actions, element_gradients, element_jacobians

__all__ = ["OrbitFamily", "PeriodicOrbit", "follow_family", "solve_periodic"]


@dataclass(frozen=True)
class PeriodicOrbit(SolverResult):
    r"""The result of :func:`solve_periodic`.

    Attributes
    ----------
    period : float
        :math:`T` (the given one, or the solved one with ``energy``).
    trajectory : Trajectory
        Nodes :math:`t_k = kT/N`, :math:`k = 0..N` (:math:`q_N = q_0`), and the
        momenta of the discrete Legendre transforms.
    control_points : ndarray, shape (N, s + 1, n)
    action : float
        The discrete action over one period.
    status : ActionStatus
    message : str
    iterations : int
    residual : float
        Largest stationarity residual (and energy residual, with ``energy``).
    multipliers : ndarray
        The borders' :math:`\mu` (zero at a solution; large values flag a
        symmetry the system does not have).
    method : Galerkin
    monodromy : ndarray, shape (2n, 2n)
        The tangent map over one period, :math:`\partial(q_N, p_N)/\partial(q_0, p_0)`
        (:func:`galerkin_vi.tangent.floquet.monodromy`; computed on first access).
    floquet_multipliers : ndarray of complex, shape (2n,)
        Its eigenvalues, by modulus descending.
    is_linearly_stable : bool
        All multipliers on the unit circle to
        :data:`~galerkin_vi.tangent.floquet.STABILITY_TOLERANCE`
        (:meth:`linearly_stable` takes another tolerance).
    """

    period: float
    trajectory: Trajectory
    control_points: NDArray[np.float64]
    action: float
    status: ActionStatus
    message: str
    iterations: int
    residual: float
    multipliers: NDArray[np.float64]
    method: Galerkin

    @cached_property
    def monodromy(self) -> NDArray[np.float64]:
        """The monodromy matrix (see the class docstring)."""
        from ..tangent.floquet import monodromy

        return monodromy(self)

    @cached_property
    def floquet_multipliers(self) -> NDArray[np.complex128]:
        """The Floquet multipliers, by modulus descending."""
        from ..tangent.floquet import floquet_multipliers

        return floquet_multipliers(self.monodromy)

    @property
    def is_linearly_stable(self) -> bool:
        """Whether every Floquet multiplier lies on the unit circle (default tolerance)."""
        return self.linearly_stable()

    def linearly_stable(self, tol: float | None = None) -> bool:
        """Whether every Floquet multiplier has ``| |mu| - 1 | <= tol``
        (default :data:`~galerkin_vi.tangent.floquet.STABILITY_TOLERANCE`)."""
        from ..tangent.floquet import STABILITY_TOLERANCE, is_linearly_stable

        return is_linearly_stable(self.floquet_multipliers, STABILITY_TOLERANCE if tol is None
                                  else tol)  # fmt: skip


class _Cycle:
    """Indices, residuals and Jacobians of a closed path of N elements."""

    def __init__(self, system: LagrangianSystem, method: Galerkin, N: int, prm: NDArray):
        self.system, self.method, self.N, self.prm = system, method, N, prm
        self.tables = method.tables
        s, n = method.degree, system.n
        self.s, self.n = s, n
        self.size = N * s * n
        k, nu, a = np.meshgrid(np.arange(N), np.arange(s + 1), np.arange(n), indexing="ij")
        # control point (k, nu) is node k's slot for nu = 0, node k + 1 (mod N) for nu = s
        owner = np.where(nu == s, (k + 1) % N, k)
        slot = np.where(nu == s, 0, nu)
        self.index = (owner * s + slot) * n + a  # (N, s + 1, n)
        self.slopes = LagrangeBasis(self.tables.d).derivatives(self.tables.d)

    def path(self, z: NDArray) -> NDArray:
        """Control points (N, s + 1, n) of the unknowns ``z`` (the first ``size`` entries)."""
        return z[: self.size][self.index]

    def at_points(self, local: NDArray) -> NDArray:
        """One value per control point (N, s + 1, n) as a vector of the unknowns (not summed)."""
        out = np.zeros(self.size)
        out[self.index[:, :-1].ravel()] = local[:, :-1].ravel()
        return out

    def assemble(self, local: NDArray) -> NDArray:
        """Sum element contributions (N, s + 1, n) into the unknowns' rows."""
        out = np.zeros(self.size)
        np.add.at(out, self.index.ravel(), local.ravel())
        return out

    def points(self, X: NDArray, h: float) -> ElementPoints:
        t_nodes = h * np.arange(self.N + 1)
        return ElementPoints.of(self.tables, t_nodes, h, X)

    def jacobian(self, H: NDArray):
        """The sparse matrix of the element Jacobians H (N, s + 1, n, s + 1, n)."""
        import scipy.sparse

        rows = np.broadcast_to(self.index[:, :, :, None, None], H.shape).ravel()
        cols = np.broadcast_to(self.index[:, None, None, :, :], H.shape).ravel()
        return scipy.sparse.coo_matrix((H.ravel(), (rows, cols)), shape=(self.size,) * 2)

    def velocities(self, X: NDArray, h: float) -> NDArray:
        """The path's velocity at every control point (N, s + 1, n): the time-shift generator."""
        return np.einsum("vu,kua->kva", self.slopes, X) / h

    def residual_in_h(self, points: ElementPoints, h: float) -> NDArray:
        r""":math:`\partial G / \partial h` (N, s + 1, n) of an autonomous system."""
        n = self.n
        values = self.system.evaluate("hessian", points.t, points.q, points.v, self.prm)
        lq = values[..., :n]
        lqv = values[..., 2 * n + n * n : 2 * n + 2 * n * n].reshape(values.shape[:-1] + (n, n))
        lvv = values[..., 2 * n + 2 * n * n : 2 * n + 3 * n * n].reshape(values.shape[:-1] + (n, n))
        t = self.tables
        b = t.b[None, :, None]
        lqv_v = np.einsum("kiac,kic->kia", lqv, points.v)
        lvv_v = np.einsum("kiac,kic->kia", lvv, points.v)
        return (
            np.einsum("iv,kia->kva", t.Phi, b * (lq - lqv_v))
            - np.einsum("iv,kia->kva", t.D, b * lvv_v) / h
        )


def _symmetry_generators(system: LagrangianSystem, symmetries) -> list:
    generators = []
    for j, xi in enumerate(symmetries):
        exprs = [sp.sympify(e) for e in xi]
        if len(exprs) != system.n:
            raise ValueError(
                f"symmetries[{j}] must have {system.n} components (one per coordinate), "
                f"got {len(exprs)}"
            )
        allowed = set(system.q) | set(system.params)
        stray = set().union(*(e.free_symbols for e in exprs)) - allowed
        if stray:
            raise ValueError(f"symmetries[{j}] may depend on q and parameters only, not {stray}")
        generators.append(FlatEvaluator(exprs, (*system.q, *system.params)))
    return generators


def solve_periodic(
    system: LagrangianSystem,
    method: Galerkin,
    q_guess: ArrayLike | Trajectory,
    v_guess: ArrayLike | None,
    period: float,
    n_steps: int,
    energy: float | None = None,
    *,
    symmetries: Sequence[Sequence[sp.Expr]] = (),
    params=None,
    tol: float = 1e-12,
    maxiter: int = 50,
) -> PeriodicOrbit:
    r"""A periodic orbit: the closed path of ``n_steps`` elements with stationary discrete action.

    Parameters
    ----------
    system : LagrangianSystem
        Without constraints or contacts; with ``energy``: autonomous, without forces.
    method : Galerkin
    q_guess, v_guess : array_like, shape (n,)
        A state on (or near) the orbit; the first guess of the path is the
        time-stepping run from it over one period. Or ``q_guess`` a
        :class:`Trajectory` over one period (its positions are interpolated
        at the control points), a callable ``q(t)`` on :math:`[0, T]` (a
        closed curve drawn by hand will do), or a :class:`PeriodicOrbit`
        (its control points, with the same N and degree: continuation); then
        ``v_guess`` None.
    period : float
        The period; with ``energy``, its first guess.
    n_steps : int
        Elements N per period.
    energy : float, optional
        Solve for the orbit of this energy, the period an unknown.
    symmetries : sequence of generators
        Generators :math:`\xi(q)` (SymPy expressions in q, one per coordinate,
        as :meth:`Trajectory.momentum` takes them) of symmetries of L whose
        action is linear in q (translations, rotations of Cartesian
        coordinates): each removes its direction by a border. The time shift
        of an autonomous system is always removed.
    params, tol, maxiter
        As :func:`~galerkin_vi.action.bvp.solve_bvp`.

    Returns
    -------
    PeriodicOrbit
        Never raises for a solve that does not converge (``status`` says why).
    """
    from ..integrator import Integrator

    if not isinstance(system, LagrangianSystem):
        raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    if not isinstance(method, Galerkin):
        raise TypeError(f"method must be a Galerkin method, got {type(method).__name__}")
    if system.m or system.contacts:
        raise ValueError("solve_periodic: systems with constraints or contacts are not "
                         "supported; use coordinates without them")  # fmt: skip
    if isinstance(n_steps, bool) or not isinstance(n_steps, numbers.Integral) or n_steps < 2:
        raise ValueError(f"n_steps must be an int >= 2, got {n_steps!r}")
    if not (isinstance(period, numbers.Real) and np.isfinite(period) and period > 0):
        raise ValueError(f"period must be a positive number, got {period!r}")
    forces = system.forces or ()
    autonomous = all(system.time_symbol not in e.free_symbols for e in (system.L, *forces))
    if energy is not None:
        if not autonomous or system.forces is not None:
            raise ValueError("energy: an orbit of given energy needs an autonomous system "
                             "without forces (the energy is conserved only then)")  # fmt: skip
        if not (isinstance(energy, numbers.Real) and np.isfinite(energy)):
            raise ValueError(f"energy must be a finite number, got {energy!r}")
    generators = _symmetry_generators(system, symmetries)
    N, n, s = int(n_steps), system.n, method.degree
    prm = system.parameter_vector(params)
    cycle = _Cycle(system, method, N, prm)
    T = float(period)
    # ---- first guess of the closed path
    if isinstance(q_guess, PeriodicOrbit):
        if v_guess is not None:
            raise ValueError("v_guess must be None when q_guess is a PeriodicOrbit")
        q_guess = q_guess if q_guess.control_points.shape == (N, s + 1, n) else q_guess.trajectory
    h = T / N
    times = h * np.arange(N)[:, None] + cycle.tables.d[None, :] * h
    if isinstance(q_guess, PeriodicOrbit):
        X0 = q_guess.control_points
    elif callable(q_guess):
        if v_guess is not None:
            raise ValueError("v_guess must be None when q_guess is a callable q(t)")
        X0 = np.array([np.asarray(q_guess(t), dtype=float) for t in times.ravel()])
        if X0.shape != (times.size, n):
            raise ValueError(f"q_guess(t) must return {n} coordinates, got shape {X0.shape[1:]}")
        X0 = X0.reshape(N, s + 1, n)
    elif isinstance(q_guess, Trajectory):
        if v_guess is not None:
            raise ValueError("v_guess must be None when q_guess is a Trajectory")
        guess_t, guess_q = q_guess.t - q_guess.t[0], q_guess.q
    else:
        q0 = np.asarray(q_guess, dtype=float)
        v0 = np.asarray(v_guess, dtype=float)
        if q0.shape != (n,) or v0.shape != (n,):
            raise ValueError(f"q_guess and v_guess must have shape ({n},), got {q0.shape}, "
                             f"{v0.shape}")  # fmt: skip
        run = Integrator(system, method).integrate(q0, v0=v0, h=T / N, n_steps=N, params=params)
        guess_t, guess_q = run.t - run.t[0], run.q
    if not (isinstance(q_guess, PeriodicOrbit) or callable(q_guess)):
        X0 = np.stack([np.interp(times, guess_t * (T / guess_t[-1]), guess_q[:, a])
                       for a in range(n)], axis=-1)  # fmt: skip
    z = cycle.at_points(X0)
    status, iterations, mu = ActionStatus.MAX_ITERATIONS, 0, np.zeros(0)
    residual = np.inf
    for iterations in range(1, maxiter + 1):  # noqa: B007 (the count is reported)
        try:
            step, mu, residual, merit = _newton_step(cycle, z, T, energy, generators, autonomous)
        except (RuntimeError, np.linalg.LinAlgError):
            status = ActionStatus.SINGULAR_JACOBIAN
            break
        if not np.all(np.isfinite(step)):
            status = ActionStatus.NON_FINITE
            break
        dz, dT = step[: cycle.size], (step[cycle.size] if energy is not None else 0.0)
        size = max(np.abs(dz).max(), abs(dT))
        scale = 1.0 + max(np.abs(z).max(), T if energy is not None else 0.0)
        alpha = 1.0
        if size > 1e-6 * scale:
            while (
                _merit(cycle, z + alpha * dz, T + alpha * dT, energy) > (1 - 2e-4 * alpha) * merit
            ):
                alpha /= 2
                if alpha < 1e-4:
                    break
            if alpha < 1e-4:
                status = ActionStatus.NO_DESCENT
                break
        z, T = z + alpha * dz, T + alpha * dT
        if not T > 0:
            status = ActionStatus.NON_FINITE
            break
        if size <= tol * scale:
            status = ActionStatus.CONVERGED
            break
    return _orbit(cycle, z, T, status, iterations, mu, energy)


def _residuals(cycle: _Cycle, z: NDArray, T: float, energy, with_jacobian: bool):
    h = T / cycle.N
    X = cycle.path(z)
    points = cycle.points(X, h)
    system, tables, prm = cycle.system, cycle.tables, cycle.prm
    if with_jacobian:
        G, H = element_jacobians(system, tables, points, h, prm)
    else:
        G, H = element_gradients(system, tables, points, h, prm), None
    R = cycle.assemble(G)
    energy_residual = None
    if energy is not None:
        p0 = -G[0, 0]
        q0 = X[0, 0]
        v0 = system.inverse_legendre(q0, p0, 0.0, dict(zip(system.params, prm, strict=True)))
        L0 = system.evaluate("L", 0.0, q0, v0, prm)[0]
        energy_residual = float(p0 @ v0 - L0 - energy)
    return X, points, G, H, R, energy_residual, h


def _merit(cycle: _Cycle, z: NDArray, T: float, energy) -> float:
    if not T > 0:
        return np.inf
    *_, R, e, _ = _residuals(cycle, z, T, energy, with_jacobian=False)
    value = float(R @ R) + (e * e if e is not None else 0.0)
    return value if np.isfinite(value) else np.inf


def _newton_step(cycle: _Cycle, z, T, energy, generators, autonomous):
    """(step in (z, T), border multipliers, largest residual, merit) of one Newton iteration."""
    import scipy.sparse
    import scipy.sparse.linalg

    X, points, G, H, R, e, h = _residuals(cycle, z, T, energy, with_jacobian=True)
    system, prm = cycle.system, cycle.prm
    J = cycle.jacobian(H).tocsr()  # duplicates (shared nodes) summed
    rhs = [-R]
    columns = []  # extra unknowns: T (energy) and the border multipliers
    rows = []  # extra equations: energy and the border conditions
    if energy is not None:
        dG_dT = cycle.residual_in_h(points, h) / cycle.N
        columns.append(cycle.assemble(dG_dT))
        # dE = -L_q . dq0 + v0 . dp0, p0 = -G_0^0: dp0 = -(H_0[0] dX_0 + dG_0^0/dT dT)
        values = dict(zip(system.params, prm, strict=True))
        p0 = -G[0, 0]
        v0 = system.inverse_legendre(X[0, 0], p0, 0.0, values)
        lq = system.evaluate("gradient", 0.0, X[0, 0], v0, prm)[: cycle.n]
        local = np.zeros_like(X)
        local[0] = -np.einsum("a,aub->ub", v0, H[0, 0])
        local[0, 0] -= lq
        energy_row = np.zeros(cycle.size)
        np.add.at(energy_row, cycle.index[0].ravel(), local[0].ravel())
        rows.append(np.append(energy_row, -(v0 @ dG_dT[0, 0])))
        rhs.append(np.array([-e]))
    borders = []
    if autonomous:
        borders.append(cycle.at_points(cycle.velocities(X, h)))
    for generator in generators:
        xi = generator(*np.moveaxis(X, -1, 0), *prm)
        borders.append(cycle.at_points(xi))
    n_c, n_b = len(columns), len(borders)
    B = np.column_stack(borders) if n_b else np.zeros((cycle.size, 0))
    top = [J, *([scipy.sparse.csr_matrix(np.column_stack(columns))] if n_c else []),
           scipy.sparse.csr_matrix(B)]  # fmt: skip
    blocks = [top]
    if n_c:
        energy_rows = np.vstack(rows)
        blocks.append([scipy.sparse.csr_matrix(energy_rows[:, : cycle.size]),
                       scipy.sparse.csr_matrix(energy_rows[:, cycle.size :]),
                       scipy.sparse.csr_matrix((n_c, n_b))])  # fmt: skip
    bottom = [scipy.sparse.csr_matrix(B.T), *([scipy.sparse.csr_matrix((n_b, n_c))] if n_c else []),
              scipy.sparse.csr_matrix((n_b, n_b))]  # fmt: skip
    blocks.append(bottom)
    A = scipy.sparse.bmat(blocks, format="csc")
    full_rhs = np.concatenate([*rhs, np.zeros(n_b)])
    solution = scipy.sparse.linalg.splu(A).solve(full_rhs)
    step = solution[: cycle.size + n_c]
    mu = solution[cycle.size + n_c :]
    largest = max(np.abs(R).max(), abs(e) if e is not None else 0.0)
    merit = float(R @ R) + (e * e if e is not None else 0.0)
    return step, mu, largest, merit


def _orbit(cycle: _Cycle, z, T, status, iterations, mu, energy) -> PeriodicOrbit:
    system, tables, prm = cycle.system, cycle.tables, cycle.prm
    X, points, G, _, R, e, h = _residuals(cycle, z, T, energy, with_jacobian=False)
    action = float(element_actions(system, tables, points, h, prm).sum())
    nodes = np.concatenate([X[:, 0], X[:1, 0]])
    p = np.concatenate([-G[:, 0], -G[:1, 0]])
    t = h * np.arange(cycle.N + 1)
    residual = max(np.abs(R).max(), abs(e) if e is not None else 0.0)
    success = status == ActionStatus.CONVERGED
    trajectory = Trajectory(
        t=t, q=nodes, p=p, newton_iterations=np.zeros(0, dtype=np.uint8),
        max_residual=residual, system=system, params=prm, total_newton_iterations=iterations,
        n_steps=cycle.N, status=RunStatus.COMPLETED if success else RunStatus.NO_CONVERGENCE,
        message=status.cause, order=cycle.method.order,
    )  # fmt: skip
    return PeriodicOrbit(
        period=T, trajectory=trajectory, control_points=X, action=action, status=status,
        message=status.cause, iterations=iterations, residual=residual, multipliers=mu,
        method=cycle.method,
    )  # fmt: skip


class OrbitFamily(list):
    """The orbits of :func:`follow_family` (a list), and where their stability changes.

    Attributes
    ----------
    stability_changes : list of StabilityChange
        Between which consecutive converged orbits the Floquet multipliers leave
        or enter the unit circle (:func:`galerkin_vi.tangent.floquet.stability_changes`,
        default tolerance); computed on first access.
    stable : ndarray of bool
        Each orbit's :attr:`PeriodicOrbit.is_linearly_stable` (False for a failed one).
    """

    @cached_property
    def stability_changes(self) -> list:
        from ..tangent.floquet import stability_changes

        return stability_changes(self)

    @property
    def stable(self) -> NDArray[np.bool_]:
        return np.array([orbit.success and orbit.is_linearly_stable for orbit in self], dtype=bool)


def follow_family(
    system: LagrangianSystem,
    method: Galerkin,
    start: PeriodicOrbit,
    energies: ArrayLike,
    **options,
) -> OrbitFamily:
    """Follow a family of periodic orbits along the energy (natural-parameter continuation).

    Each orbit of ``energies`` is solved from the previous one (its control
    points and period), starting from ``start``; the steps in energy must be
    small enough for Newton to converge from there. Stops at the first solve
    that fails and returns the orbits found so far, the failed one last, as an
    :class:`OrbitFamily`: a list that also says where the orbits' linear stability
    changes (``stability_changes``, from their Floquet multipliers).

    ``options``: ``symmetries``, ``params``, ``tol``, ``maxiter`` as in
    :func:`solve_periodic`.
    """
    N = start.control_points.shape[0]
    orbits = OrbitFamily()
    previous = start
    for value in np.asarray(energies, dtype=float):
        orbit = solve_periodic(system, method, previous, None, previous.period, N,
                               energy=float(value), **options)  # fmt: skip
        orbits.append(orbit)
        if not orbit.success:
            break
        previous = orbit
    return orbits
