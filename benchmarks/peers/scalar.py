r"""Scalar hand-written kernels: one method on one problem, every array replaced by scalars.

The strongest form of :mod:`.strong`'s fixed-point Gauss–Nyström kernel for the
two-stage Gauss method (order 4) on the pendulum (:math:`\ddot q = -\sin q`) and
the Kepler problem (:math:`\ddot q = -q/|q|^3`): what a careful person writes
for one method and one problem, with no loop over stages or coordinates, no
array indexing and no problem dispatch. The iteration policy is
:mod:`.strong`'s (extrapolated stage forces, stop when a sweep leaves the stage
positions bit-identical or stops improving below 1e-10, compensated sums), so
the steps and sweeps are the same as there. With ``two_step`` the first iterate
of every step from the third on comes from the stage forces of the last two
steps (the Lagrange basis on their four nodes), as galerkin_vi's stage-form
loops start: the same sweeps as galerkin_vi's again.

These kernels set the per-step bar of the same-method table in the regime of
small steps, where one sweep converges and a step's fixed costs (everything but
the force evaluations) decide.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math
from functools import cache

import mpmath
import numba as nb
import numpy as np

from .handwritten import _lagrange
from .strong import StrongRun, gauss_fixed_point_tables

__all__ = ["SCALAR_KERNELS", "run_scalar"]


@nb.njit(cache=True, inline="always")
def _add(x, lost, dx):
    y = dx + lost
    t = x + y
    return t, (x - t) + y


@nb.njit(cache=True, inline="always")
def _next_forces(T, k, o1, o2, g1, g2):
    """(last step's forces, first iterate's forces) at step ``k``: the last step's
    forces (g1, g2) extrapolated with ``X``, or from the third step on with ``two_step``
    together with the step before's (o1, o2), with ``Y`` (tables as :func:`_flat_tables`)."""
    if k > 1 and T[14] != 0.0:
        return (
            g1, g2,
            T[15] * o1 + T[16] * o2 + T[17] * g1 + T[18] * g2,
            T[19] * o1 + T[20] * o2 + T[21] * g1 + T[22] * g2,
        )  # fmt: skip
    return g1, g2, T[10] * g1 + T[11] * g2, T[12] * g1 + T[13] * g2


@nb.njit(cache=True)
def pendulum_gauss2(q0, v0, h, n_steps, save_every, T, maxiter, q_out, v_out, sweeps):
    """Gauss(2) on the pendulum; ``T`` = (A11, A12, A21, A22, bb1, bb2, b1, b2, c1, c2,
    X11, X12, X21, X22, two_step, Y11, .., Y14, Y21, .., Y24) of :func:`_flat_tables`
    (``two_step`` 1.0: the first iterate from the forces of the last two steps, the
    ``Y`` weights, from the third step on). Returns (status, steps done, rows saved)."""
    A11, A12, A21, A22 = T[0], T[1], T[2], T[3]
    bb1, bb2, b1, b2, c1, c2 = T[4], T[5], T[6], T[7], T[8], T[9]
    q, v = q0[0], v0[0]
    ql = vl = 0.0
    g1 = g2 = math.sin(q)
    o1 = o2 = 0.0  # the forces of the step before the last
    Q1 = Q2 = 0.0
    h2 = h * h
    q_out[0, 0], v_out[0, 0] = q, v
    saved = 1
    for k in range(n_steps):
        if k > 0:
            o1, o2, g1, g2 = _next_forces(T, k, o1, o2, g1, g2)
        it = 0
        previous = np.inf
        while True:
            n1 = q + h * c1 * v - h2 * (A11 * g1 + A12 * g2)
            n2 = q + h * c2 * v - h2 * (A21 * g1 + A22 * g2)
            change = max(abs(n1 - Q1), abs(n2 - Q2))
            Q1, Q2 = n1, n2
            if it > 0 and (change == 0.0 or (change >= previous and change < 1e-10)):
                break
            if it >= maxiter or not change < 1e300:
                return 1, k, saved
            previous = change if it > 0 else np.inf
            it += 1
            g1, g2 = math.sin(Q1), math.sin(Q2)
        sweeps[k] = it
        q, ql = _add(q, ql, h * v - h2 * (bb1 * g1 + bb2 * g2))
        v, vl = _add(v, vl, -h * (b1 * g1 + b2 * g2))
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            q_out[saved, 0], v_out[saved, 0] = q, v
            saved += 1
    return 0, n_steps, saved


@nb.njit(cache=True, inline="always")
def _kepler_force(x, y):
    r2 = x * x + y * y
    ir3 = 1.0 / (r2 * math.sqrt(r2))
    return x * ir3, y * ir3


@nb.njit(cache=True)
def kepler_gauss2(q0, v0, h, n_steps, save_every, T, maxiter, q_out, v_out, sweeps):
    """Gauss(2) on the Kepler problem (tables as :func:`pendulum_gauss2`)."""
    A11, A12, A21, A22 = T[0], T[1], T[2], T[3]
    bb1, bb2, b1, b2, c1, c2 = T[4], T[5], T[6], T[7], T[8], T[9]
    x, y, u, w = q0[0], q0[1], v0[0], v0[1]
    xl = yl = ul = wl = 0.0
    gx1, gy1 = _kepler_force(x, y)
    gx2, gy2 = gx1, gy1
    ox1 = oy1 = ox2 = oy2 = 0.0  # the forces of the step before the last
    X1 = Y1 = X2 = Y2 = 0.0
    h2 = h * h
    q_out[0, 0], q_out[0, 1], v_out[0, 0], v_out[0, 1] = x, y, u, w
    saved = 1
    for k in range(n_steps):
        if k > 0:
            ox1, ox2, gx1, gx2 = _next_forces(T, k, ox1, ox2, gx1, gx2)
            oy1, oy2, gy1, gy2 = _next_forces(T, k, oy1, oy2, gy1, gy2)
        it = 0
        previous = np.inf
        while True:
            nx1 = x + h * c1 * u - h2 * (A11 * gx1 + A12 * gx2)
            ny1 = y + h * c1 * w - h2 * (A11 * gy1 + A12 * gy2)
            nx2 = x + h * c2 * u - h2 * (A21 * gx1 + A22 * gx2)
            ny2 = y + h * c2 * w - h2 * (A21 * gy1 + A22 * gy2)
            change = max(abs(nx1 - X1), abs(ny1 - Y1), abs(nx2 - X2), abs(ny2 - Y2))
            X1, Y1, X2, Y2 = nx1, ny1, nx2, ny2
            if it > 0 and (change == 0.0 or (change >= previous and change < 1e-10)):
                break
            if it >= maxiter or not change < 1e300:
                return 1, k, saved
            previous = change if it > 0 else np.inf
            it += 1
            gx1, gy1 = _kepler_force(X1, Y1)
            gx2, gy2 = _kepler_force(X2, Y2)
        sweeps[k] = it
        x, xl = _add(x, xl, h * u - h2 * (bb1 * gx1 + bb2 * gx2))
        y, yl = _add(y, yl, h * w - h2 * (bb1 * gy1 + bb2 * gy2))
        u, ul = _add(u, ul, -h * (b1 * gx1 + b2 * gx2))
        w, wl = _add(w, wl, -h * (b1 * gy1 + b2 * gy2))
        if (k + 1) % save_every == 0 or k + 1 == n_steps:
            q_out[saved, 0], q_out[saved, 1], v_out[saved, 0], v_out[saved, 1] = x, y, u, w
            saved += 1
    return 0, n_steps, saved


#: (problem name, method label) -> kernel
SCALAR_KERNELS = {("pendulum", "Gauss(2)"): pendulum_gauss2, ("kepler", "Gauss(2)"): kepler_gauss2}


def two_step_weights(c) -> np.ndarray:
    """The Lagrange basis on the nodes of the last two steps, ``c - 1`` and ``c``, at the
    next step's nodes ``1 + c_i``: shape (r, 2 r), the older step's weights first."""
    with mpmath.workdps(50):
        nodes = [mpmath.mpf(x) - 1 for x in c] + [mpmath.mpf(x) for x in c]
        return np.array([[float(w) for w in _lagrange(nodes, 1 + mpmath.mpf(x))] for x in c])


@cache
def _flat_tables(two_step: bool = False) -> np.ndarray:
    t = gauss_fixed_point_tables(2)
    # the nodes from strong's exact tables: c rounded once is all the weights need here
    Y = two_step_weights(_gauss2_nodes())
    return np.array(
        [*t.Abar.ravel(), *t.bbar, *t.b, *t.c, *t.X.ravel(), float(two_step), *Y.ravel()]
    )


def _gauss2_nodes() -> list:
    with mpmath.workdps(50):
        return [mpmath.mpf(1) / 2 - mpmath.sqrt(3) / 6, mpmath.mpf(1) / 2 + mpmath.sqrt(3) / 6]


def run_scalar(
    problem: str, method: str, q0, p0, h: float, n_steps: int, save_every: int = 1,
    maxiter: int = 100, two_step: bool = False,
) -> StrongRun:  # fmt: skip
    """The scalar kernel of (problem, method) from (q0, p0) (unit masses: p = v)."""
    kernel = SCALAR_KERNELS[(problem, method)]
    q0 = np.ascontiguousarray(q0, dtype=float)
    v0 = np.ascontiguousarray(p0, dtype=float)
    rows = n_steps // save_every + 1 + (1 if n_steps % save_every else 0)
    q_out, v_out = np.empty((rows, q0.size)), np.empty((rows, q0.size))
    sweeps = np.zeros(n_steps, dtype=np.int64)
    status, done, saved = kernel(
        q0, v0, float(h), int(n_steps), int(save_every), _flat_tables(two_step), int(maxiter),
        q_out, v_out, sweeps,
    )  # fmt: skip
    if status != 0:
        raise RuntimeError(f"{problem} {method}: the scalar kernel failed at step {done}")
    return StrongRun(q_out[:saved], v_out[:saved], sweeps)
