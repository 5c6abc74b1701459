r"""Hand-written numba kernels: the "compiled limit" the generated code is measured against.

Everything here is written by hand for separable Hamiltonians with a constant,
diagonal mass matrix, :math:`H(q, p) = \tfrac12 p^T M^{-1} p + V(q)`, with
hand-derived gradient and Hessian of the potential. The kernels work in
positions and *velocities* :math:`v = M^{-1}p`, i.e. on
:math:`\ddot q = -M^{-1}\nabla V(q)`: ``grad_v`` returns the force per unit
mass :math:`M^{-1}\nabla V` and ``grad_hess_v`` also its Jacobian
:math:`M^{-1}\nabla^2 V`. Gauss collocation, Lobatto IIIA–IIIB and
Störmer–Verlet commute with the linear map :math:`p = Mv` (M constant), so
the kernels are still the same methods as galerkin_vi's on :math:`L = \tfrac12
v^TMv - V(q)`; their ``p`` output is the velocity. The problems, selected by
an integer id with a parameter vector ``prm``:

* ``PENDULUM``: :math:`V = -\cos q` (``prm`` empty);
* ``KEPLER``: :math:`V = -1/|q|` (``prm`` empty);
* ``HENON_HEILES``: :math:`V = \tfrac12(x^2 + y^2) + x^2y - \tfrac13y^3` (``prm`` empty);
* ``SPRINGS``: d equal masses on a line between walls, spring j
  (j = 0..d, between :math:`q_j` and :math:`q_{j+1}`, :math:`q_0 = q_{d+1} = 0`)
  with :math:`\varphi_j(e) = \tfrac{a}{2}e^2 + \tfrac{b}{4}e^4`;
  ``prm = (a_even, b_even, a_odd, b_odd, 1/m)`` (:func:`springs_params`): the
  Fermi–Pasta–Ulam problem (even springs soft cubic, odd springs stiff linear)
  and the FPU-beta spring chain (all springs alike);
* ``N_BODY``: 3-D gravitation, :math:`V = -G\sum_{i<j} m_im_j/|q_i - q_j|`,
  ``prm = (G, m_0, .., m_{K-1})`` (:func:`n_body_params`): the outer solar system;
* ``DOUBLE_PENDULUM``: non-separable, so only the scipy right-hand side
  (:func:`rhs`, :func:`jac`) and :func:`energy` exist for it, with
  ``prm = (m1, m2, l1, l2, g)``.

Kernels
-------
:func:`stormer_verlet`
    Explicit Störmer–Verlet (velocity Verlet, one force evaluation per step).
    Equal to galerkin_vi's degree 1 with ``gauss_lobatto(2)``.
:func:`gauss_collocation`
    :math:`s`-stage Gauss–Legendre collocation on Hamilton's equations, the
    momenta eliminated: the unknowns are the stage increments
    :math:`Z_i = Q_i - q_k` with
    :math:`Z_i - h c_i v_k + h^2 \sum_j (A^2)_{ij} M^{-1}\nabla V(q_k + Z_j) = 0`,
    solved by full Newton (exact Hessian of :math:`V` at every stage, every
    iteration), simplified Newton (Hessian at :math:`q_k`, factorised once
    per step) or fixed-point iteration (the Jacobian replaced by the identity:
    no Hessian, no linear solve; the usual choice for non-stiff N-body
    problems). Equal to galerkin_vi's degree :math:`s` with ``gauss_legendre(s)``.
:func:`lobatto_iiia_iiib`
    The partitioned :math:`r`-stage Lobatto IIIA–IIIB pair (order
    :math:`2r-2`) for separable :math:`H`, full Newton on the positions of the
    interior stages. Equal to galerkin_vi's degree :math:`r-1` with
    ``gauss_lobatto(r)``.

All kernels follow galerkin_vi's Newton policy so that "the same method at the
same h and Newton tolerance" is a like-for-like comparison: the initial guess
is the previous step's collocation polynomial extrapolated (on the first step
the straight line :math:`q_k + c_i h v_k`); the iteration stops when the
increment is exactly zero, or once it is below
:math:`\mathrm{tol}\,(1 + \|Z\|_\infty)` when it stops decreasing, capped at
``maxiter``; after convergence the gradients are evaluated once more at the
converged stages to form :math:`(q_{k+1}, v_{k+1})`.

The problem is selected by an integer id rather than by passing a jitted force
function: numba cannot cache a kernel that takes a function argument (it
recompiles it in every process), and the branch on a loop-invariant id costs
nothing measurable (Störmer–Verlet on Kepler: 24.5 ns/step either way). The
number of degrees of freedom is a run-time value, as in galerkin_vi's kernel;
hard-coding d = 2 makes that Störmer–Verlet 12 % faster (21.6 ns/step). Method
tables are computed with mpmath at 40 digits and rounded once
(:func:`gauss_tables`, :func:`lobatto_tables`).

The same hand-derived functions give the numba right-hand sides and Jacobians
handed to scipy's ``solve_ivp`` (:func:`rhs`, :func:`jac`, state ``y = (q, v)``)
and the C-callable right-hand side of numbalsoda (:func:`numbalsoda_rhs_address`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import mpmath
import numba as nb
import numpy as np
from numpy.typing import NDArray

from galerkin_vi import newton
from galerkin_vi.loops import linalg

__all__ = [
    "DOUBLE_PENDULUM",
    "HENON_HEILES",
    "KEPLER",
    "NO_PARAMS",
    "N_BODY",
    "PENDULUM",
    "SPRINGS",
    "GaussTables",
    "KernelRun",
    "LobattoTables",
    "energy",
    "gauss_collocation",
    "gauss_tables",
    "inverse_masses",
    "jac",
    "lobatto_iiia_iiib",
    "lobatto_tables",
    "n_body_params",
    "numbalsoda_data",
    "numbalsoda_rhs_address",
    "potential",
    "rhs",
    "run_gauss",
    "run_lobatto",
    "run_verlet",
    "springs_params",
    "stormer_verlet",
]

PENDULUM = 0
KEPLER = 1
HENON_HEILES = 2
SPRINGS = 3
N_BODY = 4
DOUBLE_PENDULUM = 5

#: Newton variants of :func:`gauss_collocation`
FULL_NEWTON = 0
SIMPLIFIED_NEWTON = 1
FIXED_POINT = 2
_ITERATIONS = {"full": FULL_NEWTON, "simplified": SIMPLIFIED_NEWTON, "fixed-point": FIXED_POINT}

STATUS_OK = 0
STATUS_NEWTON_FAILED = 1
STATUS_SINGULAR = 2
STATUS_NONFINITE = 3

_TABLE_DIGITS = 40

#: the parameter vector of the problems without parameters
NO_PARAMS = np.zeros(0)


def springs_params(
    a_even: float, b_even: float, a_odd: float, b_odd: float, mass: float = 1.0
) -> NDArray[np.float64]:
    r"""``prm`` of ``SPRINGS``: spring j has :math:`\varphi(e) = \frac a2 e^2 + \frac b4 e^4`.

    Fermi–Pasta–Ulam with stiffness :math:`\omega`: ``springs_params(0, 4, omega**2/2, 0)``
    (soft :math:`e^4` on the even springs, stiff :math:`\omega^2e^2/4` on the odd ones);
    the spring chain with ``k``, ``beta``, ``m``: ``springs_params(k, beta, k, beta, m)``.
    """
    return np.array([a_even, b_even, a_odd, b_odd, 1.0 / mass], dtype=float)


def n_body_params(G: float, masses) -> NDArray[np.float64]:
    """``prm`` of ``N_BODY``: the gravitational constant, then the masses."""
    return np.array([G, *masses], dtype=float)


# --------------------------------------------------------------------- potentials
@nb.njit(cache=True)
def _spring(prm, j):
    """(a, b) of spring j."""
    if j % 2 == 0:
        return prm[0], prm[1]
    return prm[2], prm[3]


@nb.njit(cache=True)
def potential(problem, q, prm):
    """V(q) of the problem (see the module docstring)."""
    if problem == PENDULUM:
        return -np.cos(q[0])
    if problem == KEPLER:
        return -1.0 / np.sqrt(q[0] * q[0] + q[1] * q[1])
    if problem == HENON_HEILES:
        x = q[0]
        y = q[1]
        return 0.5 * (x * x + y * y) + x * x * y - y * y * y / 3.0
    if problem == SPRINGS:
        d = q.shape[0]
        v = 0.0
        left = 0.0
        for j in range(d + 1):
            right = q[j] if j < d else 0.0
            e = right - left
            a, b = _spring(prm, j)
            v += e * e * (0.5 * a + 0.25 * b * e * e)
            left = right
        return v
    if problem == N_BODY:
        G = prm[0]
        K = q.shape[0] // 3
        v = 0.0
        for i in range(K):
            for j in range(i + 1, K):
                dx = q[3 * i] - q[3 * j]
                dy = q[3 * i + 1] - q[3 * j + 1]
                dz = q[3 * i + 2] - q[3 * j + 2]
                v -= G * prm[1 + i] * prm[1 + j] / np.sqrt(dx * dx + dy * dy + dz * dz)
        return v
    # DOUBLE_PENDULUM: prm = (m1, m2, l1, l2, g)
    return -(prm[0] + prm[1]) * prm[4] * prm[2] * np.cos(q[0]) - prm[1] * prm[4] * prm[3] * np.cos(
        q[1]
    )


@nb.njit(cache=True)
def grad_v(problem, q, g, prm):
    """g = M^-1 grad V(q) (separable problems)."""
    if problem == PENDULUM:
        g[0] = np.sin(q[0])
    elif problem == KEPLER:
        r2 = q[0] * q[0] + q[1] * q[1]
        ir3 = 1.0 / (r2 * np.sqrt(r2))
        g[0] = q[0] * ir3
        g[1] = q[1] * ir3
    elif problem == HENON_HEILES:
        x = q[0]
        y = q[1]
        g[0] = x + 2.0 * x * y
        g[1] = y + x * x - y * y
    elif problem == SPRINGS:
        d = q.shape[0]
        inv_m = prm[4]
        left = 0.0
        for j in range(d + 1):
            right = q[j] if j < d else 0.0
            e = right - left
            a, b = _spring(prm, j)
            f = e * (a + b * e * e) * inv_m
            if j < d:
                g[j] = f
            if j > 0:
                g[j - 1] -= f
            left = right
    else:  # N_BODY
        G = prm[0]
        K = q.shape[0] // 3
        for a in range(q.shape[0]):
            g[a] = 0.0
        for i in range(K):
            for j in range(i + 1, K):
                dx = q[3 * i] - q[3 * j]
                dy = q[3 * i + 1] - q[3 * j + 1]
                dz = q[3 * i + 2] - q[3 * j + 2]
                r2 = dx * dx + dy * dy + dz * dz
                ir3 = G / (r2 * np.sqrt(r2))
                fi = prm[1 + j] * ir3
                fj = prm[1 + i] * ir3
                g[3 * i] += fi * dx
                g[3 * i + 1] += fi * dy
                g[3 * i + 2] += fi * dz
                g[3 * j] -= fj * dx
                g[3 * j + 1] -= fj * dy
                g[3 * j + 2] -= fj * dz


@nb.njit(cache=True)
def grad_hess_v(problem, q, g, H, prm):
    """g = M^-1 grad V(q) and H = M^-1 (Hessian of V) at q (separable problems)."""
    if problem == PENDULUM:
        g[0] = np.sin(q[0])
        H[0, 0] = np.cos(q[0])
    elif problem == KEPLER:
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
    elif problem == HENON_HEILES:
        x = q[0]
        y = q[1]
        g[0] = x + 2.0 * x * y
        g[1] = y + x * x - y * y
        H[0, 0] = 1.0 + 2.0 * y
        H[0, 1] = 2.0 * x
        H[1, 0] = 2.0 * x
        H[1, 1] = 1.0 - 2.0 * y
    elif problem == SPRINGS:  # tridiagonal; only the band is written after zeroing it
        d = q.shape[0]
        inv_m = prm[4]
        left = 0.0
        for j in range(d):
            H[j, j] = 0.0
            if j > 0:
                H[j, j - 1] = 0.0
                H[j - 1, j] = 0.0
        for j in range(d + 1):
            right = q[j] if j < d else 0.0
            e = right - left
            a, b = _spring(prm, j)
            f = e * (a + b * e * e) * inv_m
            k = (a + 3.0 * b * e * e) * inv_m
            if j < d:
                g[j] = f
                H[j, j] += k
            if j > 0:
                g[j - 1] -= f
                H[j - 1, j - 1] += k
            if 0 < j < d:
                H[j, j - 1] -= k
                H[j - 1, j] -= k
            left = right
    else:  # N_BODY
        G = prm[0]
        d = q.shape[0]
        K = d // 3
        for a in range(d):
            g[a] = 0.0
            for c in range(d):
                H[a, c] = 0.0
        dd = np.empty(3)
        for i in range(K):
            for j in range(i + 1, K):
                for c in range(3):
                    dd[c] = q[3 * i + c] - q[3 * j + c]
                r2 = dd[0] * dd[0] + dd[1] * dd[1] + dd[2] * dd[2]
                ir3 = G / (r2 * np.sqrt(r2))
                ir5 = 3.0 * ir3 / r2
                mi = prm[1 + i]
                mj = prm[1 + j]
                for a in range(3):
                    g[3 * i + a] += mj * ir3 * dd[a]
                    g[3 * j + a] -= mi * ir3 * dd[a]
                    for c in range(3):
                        B = -ir5 * dd[a] * dd[c]
                        if a == c:
                            B += ir3
                        H[3 * i + a, 3 * i + c] += mj * B
                        H[3 * i + a, 3 * j + c] -= mj * B
                        H[3 * j + a, 3 * j + c] += mi * B
                        H[3 * j + a, 3 * i + c] -= mi * B


@nb.njit(cache=True)
def _double_pendulum_kinetic(q, v, prm):
    m1, m2, l1, l2 = prm[0], prm[1], prm[2], prm[3]
    return (
        0.5 * (m1 + m2) * l1 * l1 * v[0] * v[0]
        + 0.5 * m2 * l2 * l2 * v[1] * v[1]
        + m2 * l1 * l2 * np.cos(q[0] - q[1]) * v[0] * v[1]
    )


@nb.njit(cache=True)
def _inverse_mass(problem, a, prm):
    """(M^-1)_aa of a separable problem."""
    if problem == SPRINGS:
        return prm[4]
    if problem == N_BODY:
        return 1.0 / prm[1 + a // 3]
    return 1.0


def inverse_masses(problem: int, d: int, prm) -> NDArray[np.float64]:
    """The diagonal of M^-1 (d coordinates) of a separable problem: v = p * inverse_masses."""
    prm = np.ascontiguousarray(prm, dtype=float)
    return np.array([_inverse_mass(problem, a, prm) for a in range(d)])


@nb.njit(cache=True)
def energy(problem, q, v, prm):
    """H = T(q, v) + V(q) for every row of q, v (shape (N, d)); v are velocities."""
    out = np.empty(q.shape[0])
    for k in range(q.shape[0]):
        if problem == DOUBLE_PENDULUM:
            kin = _double_pendulum_kinetic(q[k], v[k], prm)
        else:
            kin = 0.0
            for a in range(q.shape[1]):
                kin += 0.5 * v[k, a] * v[k, a] / _inverse_mass(problem, a, prm)
        out[k] = kin + potential(problem, q[k], prm)
    return out


# -------------------------------------------------------- right-hand sides (scipy)
@nb.njit(cache=True)
def _double_pendulum_parts(y, prm):
    """Mass matrix M(theta), right-hand side f with M a = f, and its pieces."""
    m1, m2, l1, l2, g = prm[0], prm[1], prm[2], prm[3], prm[4]
    s = np.sin(y[0] - y[1])
    c = np.cos(y[0] - y[1])
    k = m2 * l1 * l2
    M11 = (m1 + m2) * l1 * l1
    M22 = m2 * l2 * l2
    M12 = k * c
    f1 = -k * s * y[3] * y[3] - (m1 + m2) * g * l1 * np.sin(y[0])
    f2 = k * s * y[2] * y[2] - m2 * g * l2 * np.sin(y[1])
    det = M11 * M22 - M12 * M12
    return M11, M12, M22, det, f1, f2, s, c, k


@nb.njit(cache=True)
def rhs_into(problem, y, dy, prm):
    """dy = f(y) for y = (q, v): (v, -M^-1 grad V(q)), or the double pendulum's equations."""
    n = y.shape[0] // 2
    if problem == DOUBLE_PENDULUM:
        M11, M12, M22, det, f1, f2, _, _, _ = _double_pendulum_parts(y, prm)
        dy[0] = y[2]
        dy[1] = y[3]
        dy[2] = (M22 * f1 - M12 * f2) / det
        dy[3] = (M11 * f2 - M12 * f1) / det
        return
    grad_v(problem, y[:n], dy[n:], prm)
    for a in range(n):
        dy[n + a] = -dy[n + a]
        dy[a] = y[n + a]


@nb.njit(cache=True)
def rhs(problem, y, prm):
    """f(y) of :func:`rhs_into` as a new array (scipy's ``fun(t, y)`` without t)."""
    dy = np.empty_like(y)
    rhs_into(problem, y, dy, prm)
    return dy


@nb.njit(cache=True)
def jac(problem, y, prm):
    """Jacobian of :func:`rhs` (dense)."""
    m = y.shape[0]
    n = m // 2
    J = np.zeros((m, m))
    for a in range(n):
        J[a, n + a] = 1.0
    if problem == DOUBLE_PENDULUM:
        # a = M^-1 f: da/dz = M^-1 (df/dz - dM/dz a)
        M11, M12, M22, det, f1, f2, s, c, k = _double_pendulum_parts(y, prm)
        g = prm[4]
        a1 = (M22 * f1 - M12 * f2) / det
        a2 = (M11 * f2 - M12 * f1) / det
        # dM12/dtheta1 = -k s, dM12/dtheta2 = k s
        w1 = y[2]
        w2 = y[3]
        dfs = np.empty((2, 4))
        dfs[0, 0] = -k * c * w2 * w2 - (prm[0] + prm[1]) * g * prm[2] * np.cos(y[0])
        dfs[0, 1] = k * c * w2 * w2
        dfs[0, 2] = 0.0
        dfs[0, 3] = -2.0 * k * s * w2
        dfs[1, 0] = k * c * w1 * w1
        dfs[1, 1] = -k * c * w1 * w1 - prm[1] * g * prm[3] * np.cos(y[1])
        dfs[1, 2] = 2.0 * k * s * w1
        dfs[1, 3] = 0.0
        for z in range(2):
            dM12 = -k * s if z == 0 else k * s
            dfs[0, z] -= dM12 * a2
            dfs[1, z] -= dM12 * a1
        for z in range(4):
            J[2, z] = (M22 * dfs[0, z] - M12 * dfs[1, z]) / det
            J[3, z] = (M11 * dfs[1, z] - M12 * dfs[0, z]) / det
        return J
    g = np.empty(n)
    H = np.zeros((n, n))
    grad_hess_v(problem, y[:n], g, H, prm)
    for a in range(n):
        for c in range(n):
            J[n + a, c] = -H[a, c]
    return J


@cache
def numbalsoda_rhs_address() -> int:
    """Address of a C right-hand side ``f(t, u, du, data)`` for numbalsoda.

    ``data = (problem, n_state, len(prm), *prm)`` (:func:`numbalsoda_data`).
    Compiled on the first call (numba ``cfunc``, not cached on disk); needs
    numbalsoda only to be called.
    """
    sig = nb.types.void(
        nb.types.double,
        nb.types.CPointer(nb.types.double),
        nb.types.CPointer(nb.types.double),
        nb.types.CPointer(nb.types.double),
    )

    @nb.cfunc(sig)
    def f(t, u, du, data):
        m = int(data[1])
        n_prm = int(data[2])
        rhs_into(
            int(data[0]), nb.carray(u, (m,)), nb.carray(du, (m,)), nb.carray(data, (n_prm + 3,))[3:]
        )

    return f.address


def numbalsoda_data(problem: int, n_state: int, prm) -> NDArray[np.float64]:
    """The ``data`` array of :func:`numbalsoda_rhs_address`: (problem, n_state, len(prm), *prm)."""
    prm = np.asarray(prm, dtype=float)
    return np.concatenate([[float(problem), float(n_state), float(prm.size)], prm])


# ------------------------------------------------------------- linear algebra
# The loops' own LU (galerkin_vi.loops.linalg: galerkin_vi.newton compiled, the solve
# composed of its one-loop pieces), so that a per-step ratio measures the rest of the step,
# not two implementations of the same elimination.
_lu_factor = linalg.lu_factor_inplace
_lu_solve = linalg.lu_solve_inplace


_newton_status = nb.njit(cache=True)(newton.newton_status)


@nb.njit(cache=True)
def _newton_continue(increment, previous, size, tol, it, maxiter):
    """0 continue, 1 converged, 2 failed: galerkin_vi's own stopping rule."""
    status = _newton_status(increment, previous, 1.0 + size, tol, it, maxiter)
    return 2 if status >= 2 else status


# --------------------------------------------------------------- Störmer–Verlet
@nb.njit(cache=True)
def stormer_verlet(problem, prm, q0, p0, h, n_steps, save_every, q_out, p_out):
    """Velocity Verlet; saves rows at k % save_every == 0 and the last step. Returns rows saved."""
    d = q0.shape[0]
    q = q0.copy()
    p = p0.copy()
    g = np.empty(d)
    grad_v(problem, q, g, prm)
    half = 0.5 * h
    q_out[0, :] = q
    p_out[0, :] = p
    saved = 1
    for k in range(n_steps):
        for a in range(d):
            p[a] -= half * g[a]
            q[a] += h * p[a]
        grad_v(problem, q, g, prm)
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
    problem,
    prm,
    q0,
    p0,
    h,
    n_steps,
    save_every,
    A2,
    bA,
    b,
    c,
    E,
    mode,
    tol,
    maxiter,
    q_out,
    p_out,
    its,
):
    """s-stage Gauss collocation for H = p^T M^-1 p / 2 + V(q), in (q, v = M^-1 p).

    ``mode``: ``FULL_NEWTON``, ``SIMPLIFIED_NEWTON`` (Hessian at q_k, factorised
    once per step) or ``FIXED_POINT`` (identity for the Jacobian: no Hessian, no
    solve). Saves rows at k % save_every == 0 and the last step; ``its[k]``
    receives the iterations of step k. Returns (status, steps done, rows saved).
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
    full = mode == FULL_NEWTON
    # the Hessians and the Jacobian only where the variant needs them (d = 1000 chains)
    nh = s if full else (1 if mode == SIMPLIFIED_NEWTON else 0)
    mj = m if mode != FIXED_POINT else 0
    Hs = np.zeros((nh, d, d))
    J = np.zeros((mj, mj))
    R = np.zeros(m)
    piv = np.zeros(mj, dtype=np.int64)
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
        if mode == SIMPLIFIED_NEWTON:
            grad_hess_v(problem, q, g[0], Hs[0], prm)
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
                    grad_hess_v(problem, Qi, g[j], Hs[j], prm)
                else:
                    grad_v(problem, Qi, g[j], prm)
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
            if mode != FIXED_POINT:
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
            grad_v(problem, Qi, g[j], prm)
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
    problem, prm, q0, p0, h, n_steps, save_every, AB, b, c, E, tol, maxiter, q_out, p_out, its
):
    """r-stage Lobatto IIIA–IIIB for H = p^T M^-1 p / 2 + V(q), full Newton on the interior stages.

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
    grad_v(problem, q, g[0], prm)
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
                    grad_hess_v(problem, Qi, g[j], Hs[j], prm)
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
                grad_v(problem, Qi, g[j], prm)
        its[k] = it
        for a in range(d):
            acc = h * p[a]
            for j in range(r - 1):
                acc -= h2 * AB[r - 1, j] * g[j, a]
            Z[r - 1, a] = acc
            q[a] += acc
        grad_v(problem, q, g[r - 1], prm)
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


def _prm(params) -> NDArray[np.float64]:
    return NO_PARAMS if params is None else np.ascontiguousarray(params, dtype=float)


def run_verlet(
    problem: int, q0, p0, h: float, n_steps: int, save_every: int = 1, params=None
) -> KernelRun:
    """Störmer–Verlet from (q0, v0); see :func:`stormer_verlet`."""
    q0, p0, q_out, p_out = _buffers(q0, p0, n_steps, save_every)
    saved = stormer_verlet(
        problem, _prm(params), q0, p0, float(h), int(n_steps), int(save_every), q_out, p_out
    )
    return KernelRun(q_out[:saved], p_out[:saved], np.zeros(n_steps, dtype=np.int64))


def run_gauss(
    problem: int,
    s: int,
    q0,
    p0,
    h: float,
    n_steps: int,
    save_every: int = 1,
    iteration: str = "full",
    tol: float = 1e-14,
    maxiter: int | None = None,
    params=None,
) -> KernelRun:
    """s-stage Gauss collocation from (q0, v0); see :func:`gauss_collocation`.

    ``iteration``: ``"full"`` (Newton), ``"simplified"`` (Newton, Hessian at q_k) or
    ``"fixed-point"``. ``maxiter`` defaults to 30 (Newton) or 100 (fixed point).
    """
    if iteration not in _ITERATIONS:
        raise ValueError(f"iteration must be one of {sorted(_ITERATIONS)}, got {iteration!r}")
    mode = _ITERATIONS[iteration]
    if maxiter is None:
        maxiter = 100 if mode == FIXED_POINT else 30
    tb = gauss_tables(s)
    q0, p0, q_out, p_out = _buffers(q0, p0, n_steps, save_every)
    its = np.zeros(n_steps, dtype=np.int64)
    status, done, saved = gauss_collocation(
        problem,
        _prm(params),
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
        mode,
        float(tol),
        int(maxiter),
        q_out,
        p_out,
        its,
    )
    _check(status, done, f"gauss_collocation(s={s}, {iteration})")
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
    params=None,
) -> KernelRun:
    """r-stage Lobatto IIIA–IIIB from (q0, v0); see :func:`lobatto_iiia_iiib`."""
    tb = lobatto_tables(r)
    q0, p0, q_out, p_out = _buffers(q0, p0, n_steps, save_every)
    its = np.zeros(n_steps, dtype=np.int64)
    status, done, saved = lobatto_iiia_iiib(
        problem,
        _prm(params),
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
