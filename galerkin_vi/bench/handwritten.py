r"""Hand-written numba kernels: the "compiled limit" the generated code is measured against.

Everything here is written by hand for the separable Hamiltonian
:math:`H(q, p) = \tfrac12|p|^2 + V(q)` of two problems, with hand-derived
gradient and Hessian of the potential:

* pendulum, :math:`V(q) = -\cos q` (``PENDULUM``, one degree of freedom);
* Kepler, :math:`V(q) = -1/|q|` (``KEPLER``, two degrees of freedom).

Kernels
-------
:func:`stormer_verlet`
    Explicit Störmer–Verlet (velocity Verlet, one force evaluation per step).
    Equal to galerkin_vi's degree 1 with ``gauss_lobatto(2)``.
:func:`gauss_collocation`
    :math:`s`-stage Gauss–Legendre collocation on Hamilton's equations, the
    momenta eliminated: the unknowns are the stage increments
    :math:`Z_i = Q_i - q_k` with
    :math:`Z_i - h c_i p_k + h^2 \sum_j (A^2)_{ij} \nabla V(q_k + Z_j) = 0`,
    solved by full Newton (exact Hessian of :math:`V` at every stage, every
    iteration) or simplified Newton (Hessian at :math:`q_k`, factorised once
    per step). Equal to galerkin_vi's degree :math:`s` with
    ``gauss_legendre(s)``.
:func:`lobatto_iiia_iiib`
    The partitioned :math:`r`-stage Lobatto IIIA–IIIB pair (order
    :math:`2r-2`) for separable :math:`H`, full Newton on the positions of the
    interior stages. Equal to galerkin_vi's degree :math:`r-1` with
    ``gauss_lobatto(r)``.

All kernels follow galerkin_vi's Newton policy so that "the same method at the
same h and Newton tolerance" is a like-for-like comparison: the initial guess
is the previous step's collocation polynomial extrapolated (on the first step
the straight line :math:`q_k + c_i h p_k`); the iteration stops when the
increment is exactly zero, or once it is below
:math:`\mathrm{tol}\,(1 + \|Z\|_\infty)` when it stops decreasing, capped at
``maxiter``; after convergence the gradients are evaluated once more at the
converged stages to form :math:`(q_{k+1}, p_{k+1})`.

The problem is selected by an integer id rather than by passing a jitted force
function: numba cannot cache a kernel that takes a function argument (it
recompiles it in every process), and the branch on a loop-invariant id costs
nothing measurable (Störmer–Verlet on Kepler: 24.5 ns/step either way). The
number of degrees of freedom is a run-time value, as in galerkin_vi's kernel;
hard-coding d = 2 makes that Störmer–Verlet 12 % faster (21.6 ns/step). Method
tables are computed with mpmath at 40 digits and rounded once
(:func:`gauss_tables`, :func:`lobatto_tables`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import mpmath
import numba as nb
import numpy as np
from numpy.typing import NDArray

from .. import newton

__all__ = [
    "KEPLER",
    "PENDULUM",
    "GaussTables",
    "KernelRun",
    "LobattoTables",
    "energy",
    "gauss_collocation",
    "gauss_tables",
    "kepler_jac",
    "kepler_rhs",
    "lobatto_iiia_iiib",
    "lobatto_tables",
    "pendulum_jac",
    "pendulum_rhs",
    "potential",
    "run_gauss",
    "run_lobatto",
    "run_verlet",
    "stormer_verlet",
]

PENDULUM = 0
KEPLER = 1

STATUS_OK = 0
STATUS_NEWTON_FAILED = 1
STATUS_SINGULAR = 2
STATUS_NONFINITE = 3

_TABLE_DIGITS = 40


# --------------------------------------------------------------------- potentials
@nb.njit(cache=True)
def potential(problem, q):
    """V(q): -cos q (pendulum) or -1/|q| (Kepler)."""
    if problem == PENDULUM:
        return -np.cos(q[0])
    return -1.0 / np.sqrt(q[0] * q[0] + q[1] * q[1])


@nb.njit(cache=True)
def grad_v(problem, q, g):
    """g = grad V(q)."""
    if problem == PENDULUM:
        g[0] = np.sin(q[0])
    else:
        r2 = q[0] * q[0] + q[1] * q[1]
        ir3 = 1.0 / (r2 * np.sqrt(r2))
        g[0] = q[0] * ir3
        g[1] = q[1] * ir3


@nb.njit(cache=True)
def grad_hess_v(problem, q, g, H):
    """g = grad V(q) and H = Hessian of V at q."""
    if problem == PENDULUM:
        g[0] = np.sin(q[0])
        H[0, 0] = np.cos(q[0])
    else:
        x = q[0]
        y = q[1]
        r2 = x * x + y * y
        ir3 = 1.0 / (r2 * np.sqrt(r2))
        ir5 = 3.0 * ir3 / r2
        g[0] = x * ir3
        g[1] = y * ir3
        H[0, 0] = ir3 - ir5 * x * x
        H[1, 1] = ir3 - ir5 * y * y
        H[0, 1] = -ir5 * x * y
        H[1, 0] = H[0, 1]


@nb.njit(cache=True)
def energy(problem, q, p):
    """H(q, p) = |p|^2/2 + V(q) for every row of q, p (shape (N, d))."""
    out = np.empty(q.shape[0])
    for k in range(q.shape[0]):
        kin = 0.0
        for a in range(q.shape[1]):
            kin += 0.5 * p[k, a] * p[k, a]
        out[k] = kin + potential(problem, q[k])
    return out


# -------------------------------------------------------- right-hand sides (scipy)
@nb.njit(cache=True)
def pendulum_rhs(t, y):
    """y = (q, v): (v, -sin q)."""
    return np.array([y[1], -np.sin(y[0])])


@nb.njit(cache=True)
def pendulum_jac(t, y):
    """Jacobian of :func:`pendulum_rhs`."""
    J = np.zeros((2, 2))
    J[0, 1] = 1.0
    J[1, 0] = -np.cos(y[0])
    return J


@nb.njit(cache=True)
def kepler_rhs(t, y):
    """y = (x, y, vx, vy): (vx, vy, -x/r^3, -y/r^3)."""
    r2 = y[0] * y[0] + y[1] * y[1]
    ir3 = 1.0 / (r2 * np.sqrt(r2))
    return np.array([y[2], y[3], -y[0] * ir3, -y[1] * ir3])


@nb.njit(cache=True)
def kepler_jac(t, y):
    """Jacobian of :func:`kepler_rhs`."""
    x = y[0]
    z = y[1]
    r2 = x * x + z * z
    ir3 = 1.0 / (r2 * np.sqrt(r2))
    ir5 = 3.0 * ir3 / r2
    J = np.zeros((4, 4))
    J[0, 2] = 1.0
    J[1, 3] = 1.0
    J[2, 0] = -(ir3 - ir5 * x * x)
    J[3, 1] = -(ir3 - ir5 * z * z)
    J[2, 1] = ir5 * x * z
    J[3, 0] = J[2, 1]
    return J


# ------------------------------------------------------------- linear algebra
# The generated kernels' own LU (galerkin_vi.newton), so that a per-step ratio measures the
# rest of the step, not two implementations of the same elimination.
_lu_factor = nb.njit(cache=True)(newton.lu_factor_inplace)
_lu_solve = nb.njit(cache=True)(newton.lu_solve_inplace)


_newton_status = nb.njit(cache=True)(newton.newton_status)


@nb.njit(cache=True)
def _newton_continue(increment, previous, size, tol, it, maxiter):
    """0 continue, 1 converged, 2 failed: galerkin_vi's own stopping rule."""
    status = _newton_status(increment, previous, 1.0 + size, tol, it, maxiter)
    return 2 if status >= 2 else status


# --------------------------------------------------------------- Störmer–Verlet
@nb.njit(cache=True)
def stormer_verlet(problem, q0, p0, h, n_steps, save_every, q_out, p_out):
    """Velocity Verlet; saves rows at k % save_every == 0 and the last step. Returns rows saved."""
    d = q0.shape[0]
    q = q0.copy()
    p = p0.copy()
    g = np.empty(d)
    grad_v(problem, q, g)
    half = 0.5 * h
    q_out[0, :] = q
    p_out[0, :] = p
    saved = 1
    for k in range(n_steps):
        for a in range(d):
            p[a] -= half * g[a]
            q[a] += h * p[a]
        grad_v(problem, q, g)
        for a in range(d):
            p[a] -= half * g[a]
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            for a in range(d):
                q_out[saved, a] = q[a]
                p_out[saved, a] = p[a]
            saved += 1
    return saved


# ------------------------------------------------------------ Gauss collocation
@dataclass(frozen=True)
class GaussTables:
    """Tables of s-stage Gauss–Legendre collocation, rounded once from 40 digits.

    ``A2 = A @ A``, ``bA = b @ A``; ``E[i, j]`` evaluates the Lagrange basis on
    the nodes (0, c_1..c_s) (the node-0 function dropped: its value is zero
    relative to q_k) at ``1 + c_i``, the previous step's polynomial extrapolated.
    """

    A: NDArray[np.float64]
    A2: NDArray[np.float64]
    b: NDArray[np.float64]
    bA: NDArray[np.float64]
    c: NDArray[np.float64]
    E: NDArray[np.float64]


def _lagrange(nodes, x):
    """Lagrange basis functions on ``nodes`` at the point ``x`` (mpmath)."""
    out = []
    for j, xj in enumerate(nodes):
        val = mpmath.mpf(1)
        for m, xm in enumerate(nodes):
            if m != j:
                val *= (x - xm) / (xj - xm)
        out.append(val)
    return out


def _integrated_lagrange(nodes, upper):
    """Exact integrals over [0, upper] of each Lagrange basis function on ``nodes`` (mpmath)."""
    out = []
    for j, xj in enumerate(nodes):
        coeffs = [mpmath.mpf(1)]  # ascending powers
        denom = mpmath.mpf(1)
        for m, xm in enumerate(nodes):
            if m == j:
                continue
            shifted = [mpmath.mpf(0)] + coeffs
            for k in range(len(coeffs)):
                shifted[k] -= xm * coeffs[k]
            coeffs = shifted
            denom *= xj - xm
        out.append(sum(a * upper ** (k + 1) / (k + 1) for k, a in enumerate(coeffs)) / denom)
    return out


def _legendre(n: int, x):
    """(P_n(x), P_n'(x), P_n''(x)) by the three-term recurrence (mpmath), |x| < 1."""
    p0, p1 = mpmath.mpf(1), x
    if n == 0:
        return p0, mpmath.mpf(0), mpmath.mpf(0)
    for k in range(2, n + 1):
        p0, p1 = p1, ((2 * k - 1) * x * p1 - (k - 1) * p0) / k
    dp = n * (x * p1 - p0) / (x * x - 1)
    d2p = (2 * x * dp - n * (n + 1) * p1) / (1 - x * x)
    return p1, dp, d2p


def _newton_roots(f, guesses) -> list:
    """Newton's method from each guess; f(x) -> (value, derivative)."""
    roots = []
    for x in guesses:
        for _ in range(100):
            val, der = f(x)
            dx = val / der
            x -= dx
            if abs(dx) < mpmath.mpf(10) ** (-mpmath.mp.dps + 3):
                break
        roots.append(x)
    return sorted(roots)


def _gauss_nodes_mp(s: int) -> list:
    """Gauss–Legendre nodes on [0, 1]: roots of P_s mapped by c = (1 + x)/2."""
    guesses = [
        mpmath.cos(mpmath.pi * (i - mpmath.mpf(1) / 4) / (s + mpmath.mpf(1) / 2))
        for i in range(1, s + 1)
    ]
    roots = _newton_roots(lambda x: _legendre(s, x)[:2], guesses)
    return [(1 + x) / 2 for x in roots]


def _lobatto_nodes_mp(r: int) -> list:
    """Gauss–Lobatto nodes on [0, 1]: 0, 1 and the roots of P'_{r-1}."""
    n = r - 1
    guesses = [-mpmath.cos(mpmath.pi * i / n) for i in range(1, n)]
    roots = _newton_roots(lambda x: _legendre(n, x)[1:], guesses)
    return [mpmath.mpf(0)] + [(1 + x) / 2 for x in roots] + [mpmath.mpf(1)]


@cache
def gauss_tables(s: int) -> GaussTables:
    """Butcher tables of the s-stage Gauss method (any s >= 1)."""
    if s < 1:
        raise ValueError(f"s must be >= 1, got {s}")
    with mpmath.workdps(_TABLE_DIGITS + 10):
        c = _gauss_nodes_mp(s)
        A = [_integrated_lagrange(c, ci) for ci in c]
        b = _integrated_lagrange(c, mpmath.mpf(1))
        A2 = [[sum(A[i][k] * A[k][j] for k in range(s)) for j in range(s)] for i in range(s)]
        bA = [sum(b[i] * A[i][j] for i in range(s)) for j in range(s)]
        nodes0 = [mpmath.mpf(0), *c]
        E = [_lagrange(nodes0, 1 + ci)[1:] for ci in c]

    def rnd(x):
        return np.array(x, dtype=float)

    return GaussTables(A=rnd(A), A2=rnd(A2), b=rnd(b), bA=rnd(bA), c=rnd(c), E=rnd(E))


@nb.njit(cache=True)
def gauss_collocation(
    problem, q0, p0, h, n_steps, save_every, A2, bA, b, c, E, full, tol, maxiter, q_out, p_out, its
):
    """s-stage Gauss collocation for H = |p|^2/2 + V(q).

    ``full``: full Newton (True) or simplified Newton with the Hessian at q_k
    (False). Saves rows at k % save_every == 0 and the last step; ``its[k]``
    receives the Newton iterations of step k. Returns (status, steps done, rows saved).
    """
    d = q0.shape[0]
    s = c.shape[0]
    m = s * d
    q = q0.copy()
    p = p0.copy()
    Z = np.zeros((s, d))
    Zold = np.zeros((s, d))
    dq = np.zeros(d)
    Qi = np.zeros(d)
    g = np.zeros((s, d))
    Hs = np.zeros((s, d, d))
    J = np.zeros((m, m))
    R = np.zeros(m)
    piv = np.zeros(m, dtype=np.int64)
    h2 = h * h
    for i in range(s):
        for a in range(d):
            Z[i, a] = c[i] * h * p[a]
    q_out[0, :] = q
    p_out[0, :] = p
    saved = 1
    for k in range(n_steps):
        if k > 0:
            for i in range(s):
                for a in range(d):
                    Zold[i, a] = Z[i, a]
            for i in range(s):
                for a in range(d):
                    acc = 0.0
                    for j in range(s):
                        acc += E[i, j] * Zold[j, a]
                    Z[i, a] = acc - dq[a]
        if not full:
            grad_hess_v(problem, q, g[0], Hs[0])
            J[:, :] = 0.0
            for i in range(s):
                for j in range(s):
                    w = h2 * A2[i, j]
                    for a in range(d):
                        for e in range(d):
                            J[i * d + a, j * d + e] = w * Hs[0, a, e]
                for a in range(d):
                    J[i * d + a, i * d + a] += 1.0
            if not _lu_factor(J, piv):
                return STATUS_SINGULAR, k, saved
        previous = np.inf
        status = 2
        it = 0
        while True:
            it += 1
            for j in range(s):
                for a in range(d):
                    Qi[a] = q[a] + Z[j, a]
                if full:
                    grad_hess_v(problem, Qi, g[j], Hs[j])
                else:
                    grad_v(problem, Qi, g[j])
            for i in range(s):
                for a in range(d):
                    acc = Z[i, a] - h * c[i] * p[a]
                    for j in range(s):
                        acc += h2 * A2[i, j] * g[j, a]
                    R[i * d + a] = -acc
            if full:
                for i in range(s):
                    for j in range(s):
                        w = h2 * A2[i, j]
                        for a in range(d):
                            for e in range(d):
                                J[i * d + a, j * d + e] = w * Hs[j, a, e]
                    for a in range(d):
                        J[i * d + a, i * d + a] += 1.0
                if not _lu_factor(J, piv):
                    return STATUS_SINGULAR, k, saved
            _lu_solve(J, piv, R)
            increment = 0.0
            size = 0.0
            for i in range(s):
                for a in range(d):
                    Z[i, a] += R[i * d + a]
                    if abs(R[i * d + a]) > increment:
                        increment = abs(R[i * d + a])
                    if abs(Z[i, a]) > size:
                        size = abs(Z[i, a])
            status = _newton_continue(increment, previous, size, tol, it, maxiter)
            if status != 0:
                break
            previous = increment
        its[k] = it
        if status != 1:
            return STATUS_NEWTON_FAILED, k, saved
        for j in range(s):
            for a in range(d):
                Qi[a] = q[a] + Z[j, a]
            grad_v(problem, Qi, g[j])
        for a in range(d):
            fq = 0.0
            fp = 0.0
            for j in range(s):
                fq += bA[j] * g[j, a]
                fp += b[j] * g[j, a]
            dq[a] = h * p[a] - h2 * fq
            q[a] += dq[a]
            p[a] -= h * fp
            if not abs(q[a]) < 1e300 or not abs(p[a]) < 1e300:
                return STATUS_NONFINITE, k, saved
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            for a in range(d):
                q_out[saved, a] = q[a]
                p_out[saved, a] = p[a]
            saved += 1
    return STATUS_OK, n_steps, saved


# ----------------------------------------------------------- Lobatto IIIA–IIIB
@dataclass(frozen=True)
class LobattoTables:
    """Tables of the r-stage Lobatto IIIA–IIIB pair, rounded once from 40 digits.

    ``AB = A @ Abar`` (IIIA times IIIB; its last column is zero), ``b``, ``c``
    and ``E[i, j] = l_j(1 + c_i)``, the Lagrange basis on the Lobatto nodes.
    """

    AB: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    E: NDArray[np.float64]


@cache
def lobatto_tables(r: int) -> LobattoTables:
    """Tables of the r-stage Lobatto IIIA–IIIB pair (r >= 2, order 2r - 2)."""
    if r < 2:
        raise ValueError(f"r must be >= 2, got {r}")
    with mpmath.workdps(_TABLE_DIGITS + 10):
        c = _lobatto_nodes_mp(r)
        A = [_integrated_lagrange(c, ci) for ci in c]
        b = _integrated_lagrange(c, mpmath.mpf(1))
        Abar = [[b[j] * (1 - A[j][i] / b[i]) for j in range(r)] for i in range(r)]
        AB = [[sum(A[i][k] * Abar[k][j] for k in range(r)) for j in range(r)] for i in range(r)]
        E = [_lagrange(c, 1 + ci) for ci in c]

    def rnd(x):
        return np.array(x, dtype=float)

    AB = rnd(AB)
    AB[:, -1] = 0.0  # exactly zero in exact arithmetic
    return LobattoTables(AB=AB, b=rnd(b), c=rnd(c), E=rnd(E))


@nb.njit(cache=True)
def lobatto_iiia_iiib(
    problem, q0, p0, h, n_steps, save_every, AB, b, c, E, tol, maxiter, q_out, p_out, its
):
    """r-stage Lobatto IIIA–IIIB for H = |p|^2/2 + V(q), full Newton on the interior stages.

    With the momenta eliminated, the stage positions are
    Q_i = q_k + h c_i p_k - h^2 sum_j (A Abar)_ij grad V(Q_j); Q_1 = q_k and
    Q_r = q_{k+1} are explicit, so Newton runs on the r - 2 interior stages only
    (r = 2 is Störmer–Verlet, no Newton). The last stage's gradient is reused
    as the next step's first (one gradient evaluation saved per step).
    Returns (status, steps done, rows saved).
    """
    d = q0.shape[0]
    r = c.shape[0]
    ni = r - 2
    m = ni * d
    q = q0.copy()
    p = p0.copy()
    Z = np.zeros((r, d))
    Zold = np.zeros((r, d))
    Qi = np.zeros(d)
    g = np.zeros((r, d))
    Hs = np.zeros((r, d, d))
    J = np.zeros((max(m, 1), max(m, 1)))
    R = np.zeros(max(m, 1))
    piv = np.zeros(max(m, 1), dtype=np.int64)
    h2 = h * h
    for i in range(r):
        for a in range(d):
            Z[i, a] = c[i] * h * p[a]
    grad_v(problem, q, g[0])
    q_out[0, :] = q
    p_out[0, :] = p
    saved = 1
    for k in range(n_steps):
        if k > 0 and ni > 0:
            for i in range(r):
                for a in range(d):
                    Zold[i, a] = Z[i, a]
            for i in range(1, r - 1):
                for a in range(d):
                    acc = 0.0
                    for j in range(1, r):
                        acc += E[i, j] * Zold[j, a]
                    Z[i, a] = acc - Zold[r - 1, a]
        it = 0
        if ni > 0:
            previous = np.inf
            while True:
                it += 1
                for j in range(1, r - 1):
                    for a in range(d):
                        Qi[a] = q[a] + Z[j, a]
                    grad_hess_v(problem, Qi, g[j], Hs[j])
                for i in range(1, r - 1):
                    for a in range(d):
                        acc = Z[i, a] - h * c[i] * p[a]
                        for j in range(r - 1):
                            acc += h2 * AB[i, j] * g[j, a]
                        R[(i - 1) * d + a] = -acc
                for i in range(1, r - 1):
                    for j in range(1, r - 1):
                        w = h2 * AB[i, j]
                        for a in range(d):
                            for e in range(d):
                                J[(i - 1) * d + a, (j - 1) * d + e] = w * Hs[j, a, e]
                    for a in range(d):
                        J[(i - 1) * d + a, (i - 1) * d + a] += 1.0
                if not _lu_factor(J, piv):
                    return STATUS_SINGULAR, k, saved
                _lu_solve(J, piv, R)
                increment = 0.0
                size = 0.0
                for i in range(1, r - 1):
                    for a in range(d):
                        Z[i, a] += R[(i - 1) * d + a]
                        if abs(R[(i - 1) * d + a]) > increment:
                            increment = abs(R[(i - 1) * d + a])
                        if abs(Z[i, a]) > size:
                            size = abs(Z[i, a])
                status = _newton_continue(increment, previous, size, tol, it, maxiter)
                if status == 1:
                    break
                if status == 2:
                    its[k] = it
                    return STATUS_NEWTON_FAILED, k, saved
                previous = increment
            for j in range(1, r - 1):
                for a in range(d):
                    Qi[a] = q[a] + Z[j, a]
                grad_v(problem, Qi, g[j])
        its[k] = it
        for a in range(d):
            acc = h * p[a]
            for j in range(r - 1):
                acc -= h2 * AB[r - 1, j] * g[j, a]
            Z[r - 1, a] = acc
            q[a] += acc
        grad_v(problem, q, g[r - 1])
        for a in range(d):
            fp = 0.0
            for j in range(r):
                fp += b[j] * g[j, a]
            p[a] -= h * fp
            g[0, a] = g[r - 1, a]
            if not abs(q[a]) < 1e300 or not abs(p[a]) < 1e300:
                return STATUS_NONFINITE, k, saved
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            for a in range(d):
                q_out[saved, a] = q[a]
                p_out[saved, a] = p[a]
            saved += 1
    return STATUS_OK, n_steps, saved


# ------------------------------------------------------------ Python wrappers
@dataclass(frozen=True)
class KernelRun:
    """Saved rows of a hand-written kernel run (like galerkin_vi's Trajectory)."""

    q: NDArray[np.float64]
    p: NDArray[np.float64]
    newton_iterations: NDArray[np.int64]

    @property
    def mean_newton_iterations(self) -> float:
        its = self.newton_iterations
        return float(its.mean()) if its.size else 0.0


def _buffers(q0, p0, n_steps: int, save_every: int):
    q0 = np.ascontiguousarray(q0, dtype=float)
    p0 = np.ascontiguousarray(p0, dtype=float)
    rows = n_steps // save_every + 1 + (1 if n_steps % save_every else 0)
    return q0, p0, np.empty((rows, q0.size)), np.empty((rows, q0.size))


def _check(status: int, done: int, name: str) -> None:
    if status != STATUS_OK:
        raise RuntimeError(f"{name}: failed at step {done} (status {status})")


def run_verlet(problem: int, q0, p0, h: float, n_steps: int, save_every: int = 1) -> KernelRun:
    """Störmer–Verlet from (q0, p0); see :func:`stormer_verlet`."""
    q0, p0, q_out, p_out = _buffers(q0, p0, n_steps, save_every)
    saved = stormer_verlet(problem, q0, p0, float(h), int(n_steps), int(save_every), q_out, p_out)
    return KernelRun(q_out[:saved], p_out[:saved], np.zeros(n_steps, dtype=np.int64))


def run_gauss(
    problem: int,
    s: int,
    q0,
    p0,
    h: float,
    n_steps: int,
    save_every: int = 1,
    full: bool = True,
    tol: float = 1e-14,
    maxiter: int = 30,
) -> KernelRun:
    """s-stage Gauss collocation from (q0, p0); see :func:`gauss_collocation`."""
    tb = gauss_tables(s)
    q0, p0, q_out, p_out = _buffers(q0, p0, n_steps, save_every)
    its = np.zeros(n_steps, dtype=np.int64)
    status, done, saved = gauss_collocation(
        problem,
        q0,
        p0,
        float(h),
        int(n_steps),
        int(save_every),
        tb.A2,
        tb.bA,
        tb.b,
        tb.c,
        tb.E,
        bool(full),
        float(tol),
        int(maxiter),
        q_out,
        p_out,
        its,
    )
    _check(status, done, f"gauss_collocation(s={s})")
    return KernelRun(q_out[:saved], p_out[:saved], its)


def run_lobatto(
    problem: int,
    r: int,
    q0,
    p0,
    h: float,
    n_steps: int,
    save_every: int = 1,
    tol: float = 1e-14,
    maxiter: int = 30,
) -> KernelRun:
    """r-stage Lobatto IIIA–IIIB from (q0, p0); see :func:`lobatto_iiia_iiib`."""
    tb = lobatto_tables(r)
    q0, p0, q_out, p_out = _buffers(q0, p0, n_steps, save_every)
    its = np.zeros(n_steps, dtype=np.int64)
    status, done, saved = lobatto_iiia_iiib(
        problem,
        q0,
        p0,
        float(h),
        int(n_steps),
        int(save_every),
        tb.AB,
        tb.b,
        tb.c,
        tb.E,
        float(tol),
        int(maxiter),
        q_out,
        p_out,
        its,
    )
    _check(status, done, f"lobatto_iiia_iiib(r={r})")
    return KernelRun(q_out[:saved], p_out[:saved], its)
