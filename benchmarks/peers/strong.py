r"""The strongest hand-written kernels of galerkin_vi's methods: fixed-point iteration to round-off.

These are the baselines of the same-method table (``benchmarks/same_method.py``):
what a careful person writes by hand for one method, with the iteration policy of
the fastest published codes (IRKGL16 and Hairer–Lubich–Wanner's GNI codes):

* the stage equations are solved by **fixed-point iteration** (no Jacobian, no
  linear solve), which contracts like :math:`h^2 \|\nabla^2 V\|` on second-order
  problems and like :math:`h\|f'\|` on first-order ones;
* the first iterate comes from the previous step's **stage forces extrapolated**
  with the Lagrange basis on the stage nodes, :math:`\tilde g_i = \sum_j
  \ell_j(1 + c_i)\, g_j`, pushed through the integration table: it is off by
  :math:`O(h^{s+2})` in the positions, often below an ulp, so the first sweep
  usually changes nothing; with ``two_step`` (:func:`run_nystrom`) from the stage
  forces of the last two steps, the Lagrange basis on their nodes, as galerkin_vi's
  stage form starts methods of at most three points;
* the iteration stops as soon as a sweep leaves every stage position
  **bit-identical** (the forces of the last sweep are then exact at the stages
  and are reused for the update, no extra evaluation), or when the largest
  change stops decreasing (round-off oscillation of an ulp);
* positions and velocities (or momenta) are advanced with compensated summation.

Kernels
-------
:func:`nystrom_fixed_point`
    Separable :math:`H = \tfrac12 p^TM^{-1}p + V(q)` (diagonal constant M), on
    :math:`\ddot q = g(q) = -M^{-1}\nabla V`: :math:`Q_i = q_k + h c_i v_k + h^2
    \sum_j \bar A_{ij} g(Q_j)`, :math:`v_{k+1} = v_k + h\sum_j b_j g_j`,
    :math:`q_{k+1} = q_k + h v_k + h^2 \sum_j \bar b_j g_j`. With Gauss tables
    (:math:`\bar A = A^2`) it is the s-stage Gauss method; with Lobatto
    IIIA–IIIB tables (:math:`\bar A = A^{\rm IIIA}A^{\rm IIIB}`: first row and last
    column zero) the first stage is :math:`q_k` (its force is the last stage's of
    the previous step: first same as last) and the last stage is
    :math:`q_{k+1}`, evaluated once after the interior stages have converged.
:func:`irk_fixed_point`
    Any first-order system :math:`y' = f(y)`: :math:`Y_i = y_k + h\sum_j A_{ij}
    f(Y_j)`, :math:`y_{k+1} = y_k + h \sum_j b_j f(Y_j)`, with the stage
    derivatives extrapolated. On Hamilton's equations in :math:`(q, p)` with
    Gauss tables it is the Gauss method for non-separable H (the double pendulum).

``sweeps[k]`` counts the force evaluations of step k in units of one sweep over
the implicit stages, the number compared with galerkin_vi's iterations per step.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import mpmath
import numba as nb
import numpy as np
from numpy.typing import NDArray

from . import handwritten as hw

__all__ = [
    "FixedPointTables",
    "StrongRun",
    "gauss_fixed_point_tables",
    "hamilton_rhs",
    "irk_fixed_point",
    "lobatto_fixed_point_tables",
    "nystrom_fixed_point",
    "run_irk",
    "extrapolate_stages",
    "run_nystrom",
    "stage_sweep",
]

_DIGITS = 40


@dataclass(frozen=True)
class FixedPointTables:
    """Tables of one method, rounded once from 40 digits.

    ``Abar`` (stage positions; for :func:`irk_fixed_point` the Runge–Kutta ``A``),
    ``bbar = b (1 - c)`` (the position update), ``b``, ``c``, ``X[i, j] =
    l_j(1 + c_i)`` (the previous step's stage forces extrapolated to this step's
    nodes), ``lobatto`` (first stage q_k, last stage q_{k+1}), ``Y`` (r, 2 r): the
    stage forces of the last two steps extrapolated (their nodes ``c - 1`` and ``c``;
    a repeated node, Lobatto's end, once).
    """

    Abar: NDArray[np.float64]
    bbar: NDArray[np.float64]
    b: NDArray[np.float64]
    c: NDArray[np.float64]
    X: NDArray[np.float64]
    lobatto: bool
    Y: NDArray[np.float64]


def _two_step(c, x) -> list:
    """The Lagrange basis on the nodes of the last two steps, ``c - 1`` (less those that
    are also nodes ``c``: Lobatto's end) and ``c``, at ``x``: the older step's weights
    first, 0 for a node left out."""
    older = [cj - 1 for cj in c]
    kept = [j for j, node in enumerate(older) if all(abs(node - cm) > 1e-30 for cm in c)]
    values = hw._lagrange([older[j] for j in kept] + list(c), x)
    weights = [mpmath.mpf(0)] * len(c)
    for place, j in enumerate(kept):
        weights[j] = values[place]
    return weights + values[len(kept) :]


def _tables(c, A, Abar, b, lobatto: bool) -> FixedPointTables:
    r = len(c)
    X = [hw._lagrange(c, 1 + ci) for ci in c]
    Y = [_two_step(c, 1 + ci) for ci in c]
    bbar = [b[j] * (1 - c[j]) for j in range(r)]

    def rnd(x):
        return np.array(x, dtype=float)

    out = rnd(Abar)
    if lobatto:
        out[0, :] = 0.0
        out[:, -1] = 0.0  # exactly zero in exact arithmetic
    return FixedPointTables(rnd(out), rnd(bbar), rnd(b), rnd(c), rnd(X), lobatto, rnd(Y))


@cache
def gauss_fixed_point_tables(s: int, first_order: bool = False) -> FixedPointTables:
    """s-stage Gauss: ``Abar = A @ A`` (Nyström form) or ``A`` (``first_order``)."""
    with mpmath.workdps(_DIGITS + 10):
        c = hw._gauss_nodes_mp(s)
        A = [hw._integrated_lagrange(c, ci) for ci in c]
        b = hw._integrated_lagrange(c, mpmath.mpf(1))
        A2 = [[sum(A[i][k] * A[k][j] for k in range(s)) for j in range(s)] for i in range(s)]
        return _tables(c, A, A if first_order else A2, b, lobatto=False)


@cache
def lobatto_fixed_point_tables(r: int) -> FixedPointTables:
    """r-stage Lobatto IIIA–IIIB in Nyström form (r >= 3; r = 2 is Störmer–Verlet)."""
    if r < 3:
        raise ValueError(f"r must be >= 3 (r = 2 is explicit), got {r}")
    with mpmath.workdps(_DIGITS + 10):
        c = hw._lobatto_nodes_mp(r)
        A = [hw._integrated_lagrange(c, ci) for ci in c]
        b = hw._integrated_lagrange(c, mpmath.mpf(1))
        B = [[b[j] * (1 - A[j][i] / b[i]) for j in range(r)] for i in range(r)]
        AB = [[sum(A[i][k] * B[k][j] for k in range(r)) for j in range(r)] for i in range(r)]
        return _tables(c, A, AB, b, lobatto=True)


@nb.njit(cache=True, inline="always")
def _two_sum_add(x, lost, dx):
    """x += dx with the rounding error carried in ``lost`` (Kahan)."""
    y = dx + lost
    t = x + y
    return t, (x - t) + y


@nb.njit(cache=True)
def nystrom_fixed_point(
    problem, prm, q0, v0, h, n_steps, save_every, Abar, bbar, b, c, X, lobatto, maxiter,
    q_out, v_out, sweeps, Y, two_step,
):  # fmt: skip
    """Fixed-point Nyström step (Gauss or Lobatto IIIA–IIIB tables) from (q0, v0).

    Saves rows at k % save_every == 0 and the last step. With ``two_step``, every
    step from the third on starts from the forces of the last two steps (``Y``).
    Returns (status, steps done, rows saved).
    """
    d = q0.shape[0]
    r = c.shape[0]
    first = 1 if lobatto else 0  # the implicit stages are first .. last - 1
    last = r - 1 if lobatto else r
    q = q0.copy()
    v = v0.copy()
    q_lost = np.zeros(d)
    v_lost = np.zeros(d)
    G = np.zeros((r, d))  # M^-1 grad V at the stages (the acceleration is -G)
    Gold = np.zeros((r, d))
    G2 = np.zeros((r, d))  # the step before the last
    Q = np.zeros((r, d))
    Qi = np.zeros(d)
    base = np.zeros(d)
    h2 = h * h
    hw.grad_v(problem, q, G[0], prm)
    for j in range(1, r):
        G[j, :] = G[0, :]
    q_out[0, :] = q
    v_out[0, :] = v
    saved = 1
    for k in range(n_steps):
        if k > 0:
            # the previous step's stage forces, extrapolated to this step's nodes
            Gold[:, :] = G
            for i in range(first, last):
                for a in range(d):
                    acc = 0.0
                    if two_step and k > 1:
                        for j in range(r):
                            acc += Y[i, j] * G2[j, a]
                        for j in range(r):
                            acc += Y[i, r + j] * Gold[j, a]
                    else:
                        for j in range(r):
                            acc += X[i, j] * Gold[j, a]
                    G[i, a] = acc
            if lobatto:
                G[0, :] = Gold[r - 1, :]  # first same as last
            G2[:, :] = Gold
        it = 0
        previous = np.inf
        while True:
            change = 0.0
            for i in range(first, last):
                for a in range(d):
                    acc = 0.0
                    for j in range(r):
                        acc += Abar[i, j] * G[j, a]
                    new = q[a] + h * c[i] * v[a] - h2 * acc
                    delta = abs(new - Q[i, a])
                    if delta > change:
                        change = delta
                    Q[i, a] = new
            if it > 0 and (change == 0.0 or (change >= previous and change < 1e-10)):
                break  # the forces of the last sweep are those at Q
            if it >= maxiter or not change < 1e300:
                return hw.STATUS_NEWTON_FAILED, k, saved
            previous = change if it > 0 else np.inf
            it += 1
            for i in range(first, last):
                hw.grad_v(problem, Q[i], G[i], prm)
        sweeps[k] = it
        if lobatto:
            for a in range(d):
                acc = 0.0
                for j in range(r):
                    acc += bbar[j] * G[j, a]
                Qi[a] = q[a] + h * v[a] - h2 * acc
            hw.grad_v(problem, Qi, G[r - 1], prm)
        for a in range(d):
            accq = 0.0
            accv = 0.0
            for j in range(r):
                accq += bbar[j] * G[j, a]
                accv += b[j] * G[j, a]
            base[a] = h * v[a]
            q[a], q_lost[a] = _two_sum_add(q[a], q_lost[a], base[a] - h2 * accq)
            v[a], v_lost[a] = _two_sum_add(v[a], v_lost[a], -h * accv)
            if not abs(q[a]) < 1e300 or not abs(v[a]) < 1e300:
                return hw.STATUS_NONFINITE, k, saved
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            q_out[saved, :] = q
            v_out[saved, :] = v
            saved += 1
    return hw.STATUS_OK, n_steps, saved


@nb.njit(cache=True)
def hamilton_rhs(problem, y, dy, prm):
    """dy = (H_p, -H_q) at y = (q, p); the double pendulum, or a separable problem."""
    n = y.shape[0] // 2
    if problem == hw.DOUBLE_PENDULUM:
        m1, m2, l1, l2, g = prm[0], prm[1], prm[2], prm[3], prm[4]
        s = np.sin(y[0] - y[1])
        cs = np.cos(y[0] - y[1])
        k = m2 * l1 * l2
        M11 = (m1 + m2) * l1 * l1
        M22 = m2 * l2 * l2
        M12 = k * cs
        det = M11 * M22 - M12 * M12
        v1 = (M22 * y[2] - M12 * y[3]) / det
        v2 = (M11 * y[3] - M12 * y[2]) / det
        dy[0] = v1
        dy[1] = v2
        dy[2] = -k * s * v1 * v2 - (m1 + m2) * g * l1 * np.sin(y[0])
        dy[3] = k * s * v1 * v2 - m2 * g * l2 * np.sin(y[1])
        return
    hw.grad_v(problem, y[:n], dy[n:], prm)
    for a in range(n):
        dy[a] = y[n + a] * hw._inverse_mass(problem, a, prm)
        dy[n + a] = -dy[n + a] / hw._inverse_mass(problem, a, prm)


@nb.njit(cache=True, inline="always")
def stage_sweep(y, h, A, K, Y):
    """Y_i = y + h sum_j A_ij K_j for every stage i; returns the largest change of an entry."""
    change = 0.0
    for i in range(K.shape[0]):
        for a in range(y.shape[0]):
            acc = 0.0
            for j in range(K.shape[0]):
                acc += A[i, j] * K[j, a]
            new = y[a] + h * acc
            delta = abs(new - Y[i, a])
            if delta > change:
                change = delta
            Y[i, a] = new
    return change


@nb.njit(cache=True, inline="always")
def extrapolate_stages(X, K, Kold):
    """K_i <- sum_j X_ij K_j: the last step's stage values extrapolated to this step's
    nodes (``Kold`` is work space)."""
    Kold[:, :] = K
    for i in range(K.shape[0]):
        for a in range(K.shape[1]):
            acc = 0.0
            for j in range(K.shape[0]):
                acc += X[i, j] * Kold[j, a]
            K[i, a] = acc


@nb.njit(cache=True)
def irk_fixed_point(
    problem, prm, y0, h, n_steps, save_every, A, b, X, maxiter, y_out, sweeps,
):  # fmt: skip
    """Fixed-point implicit Runge–Kutta on Hamilton's equations in y = (q, p)."""
    m = y0.shape[0]
    s = b.shape[0]
    y = y0.copy()
    lost = np.zeros(m)
    K = np.zeros((s, m))
    Kold = np.zeros((s, m))
    Y = np.zeros((s, m))
    hamilton_rhs(problem, y, K[0], prm)
    for j in range(1, s):
        K[j, :] = K[0, :]
    y_out[0, :] = y
    saved = 1
    for k in range(n_steps):
        if k > 0:
            extrapolate_stages(X, K, Kold)
        it = 0
        previous = np.inf
        while True:
            change = stage_sweep(y, h, A, K, Y)
            if it > 0 and (change == 0.0 or (change >= previous and change < 1e-10)):
                break
            if it >= maxiter or not change < 1e300:
                return hw.STATUS_NEWTON_FAILED, k, saved
            previous = change if it > 0 else np.inf
            it += 1
            for i in range(s):
                hamilton_rhs(problem, Y[i], K[i], prm)
        sweeps[k] = it
        for a in range(m):
            acc = 0.0
            for j in range(s):
                acc += b[j] * K[j, a]
            y[a], lost[a] = _two_sum_add(y[a], lost[a], h * acc)
            if not abs(y[a]) < 1e300:
                return hw.STATUS_NONFINITE, k, saved
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            y_out[saved, :] = y
            saved += 1
    return hw.STATUS_OK, n_steps, saved


@dataclass(frozen=True)
class StrongRun:
    """Saved rows (q, p) of a strong kernel's run and its sweeps per step."""

    q: NDArray[np.float64]
    p: NDArray[np.float64]
    sweeps: NDArray[np.int64]

    @property
    def mean_sweeps(self) -> float:
        return float(self.sweeps.mean()) if self.sweeps.size else 0.0


def _rows(n_steps: int, save_every: int) -> int:
    return n_steps // save_every + 1 + (1 if n_steps % save_every else 0)


def run_nystrom(
    problem: int, tables: FixedPointTables, q0, p0, h: float, n_steps: int,
    save_every: int = 1, params=None, maxiter: int = 100, two_step: bool = False,
) -> StrongRun:  # fmt: skip
    """:func:`nystrom_fixed_point` from (q0, p0) (momenta; M diagonal and constant)."""
    prm = hw._prm(params)
    q0 = np.ascontiguousarray(q0, dtype=float)
    inv_mass = hw.inverse_masses(problem, q0.size, prm)
    v0 = np.ascontiguousarray(p0, dtype=float) * inv_mass
    rows = _rows(n_steps, save_every)
    q_out, v_out = np.empty((rows, q0.size)), np.empty((rows, q0.size))
    sweeps = np.zeros(n_steps, dtype=np.int64)
    t = tables
    status, done, saved = nystrom_fixed_point(
        problem, prm, q0, v0, float(h), int(n_steps), int(save_every), t.Abar, t.bbar, t.b,
        t.c, t.X, t.lobatto, int(maxiter), q_out, v_out, sweeps, t.Y, bool(two_step),
    )  # fmt: skip
    hw._check(status, done, "nystrom_fixed_point")
    return StrongRun(q_out[:saved], v_out[:saved] / inv_mass, sweeps)


def run_irk(
    problem: int, tables: FixedPointTables, q0, p0, h: float, n_steps: int,
    save_every: int = 1, params=None, maxiter: int = 100,
) -> StrongRun:  # fmt: skip
    """:func:`irk_fixed_point` on Hamilton's equations from (q0, p0)."""
    prm = hw._prm(params)
    y0 = np.concatenate([np.asarray(q0, dtype=float), np.asarray(p0, dtype=float)])
    n = y0.size // 2
    y_out = np.empty((_rows(n_steps, save_every), y0.size))
    sweeps = np.zeros(n_steps, dtype=np.int64)
    t = tables
    status, done, saved = irk_fixed_point(
        problem, prm, y0, float(h), int(n_steps), int(save_every), t.Abar, t.b, t.X,
        int(maxiter), y_out, sweeps,
    )  # fmt: skip
    hw._check(status, done, "irk_fixed_point")
    return StrongRun(y_out[:saved, :n], y_out[:saved, n:], sweeps)
