r"""The strongest hand-written adaptive baseline: Gauss on the Poincaré-transformed Kepler problem.

What a careful person writes by hand for time-adaptive symplectic steps on
Kepler's problem (:math:`H = \tfrac12|p|^2 - 1/r`): the Poincaré transformation

.. math::

    K(q, p) = g(q)\,\big(H(q, p) - E\big), \qquad g = r^\alpha,\qquad E = H(q_0, p_0),

integrated in a fictitious time :math:`\tau` with fixed steps of the s-stage Gauss
method on :math:`y = (q, p, t)`,

.. math::

    q' = g\,p,\qquad p' = -\big(\alpha\, g\, r^{-2} (H - E) + g\, r^{-3}\big)\, q,
    \qquad t' = g,

the physical time :math:`t` riding along as a passive component. The stage
equations are solved as in :mod:`.strong` (fixed-point iteration from the
previous step's stage derivatives extrapolated, until a sweep leaves every
stage bit-identical or stops decreasing; compensated summation). The last step
is shortened to land on ``t_final`` exactly: a secant iteration on its
fictitious size, as :class:`galerkin_vi.AdaptiveIntegrator` does.

On the energy surface :math:`H = E` the flow of K is that of H with
:math:`dt/d\tau = g`; Gauss on K is symplectic, so the physical energy error
stays bounded. With the same g and the same fictitious step this is the
method galerkin_vi's ``AdaptiveIntegrator`` runs with ``Galerkin(s,
gauss_legendre(s))`` (which carries time as a coordinate with a quadratic
clock term instead), so its times are the baseline of
``benchmarks/adaptive.py``.
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import math

import numba as nb
import numpy as np
from numpy.typing import NDArray

from . import handwritten as hw
from .strong import extrapolate_stages, gauss_fixed_point_tables, stage_sweep

__all__ = ["KeplerPoincareRun", "kepler_poincare"]

_STATE = 5  # x, y, px, py, t


@nb.njit(cache=True, inline="always")
def _rhs(y, dy, E, alpha):
    x, z, px, py = y[0], y[1], y[2], y[3]
    r2 = x * x + z * z
    r = math.sqrt(r2)
    g = r**alpha
    H = 0.5 * (px * px + py * py) - 1.0 / r
    # dK/dq = g'(H - E) + g dV/dq with g' = alpha r^(alpha - 2) q and dV/dq = q / r^3
    pull = alpha * g / r2 * (H - E) + g / (r2 * r)
    dy[0] = g * px
    dy[1] = g * py
    dy[2] = -pull * x
    dy[3] = -pull * z
    dy[4] = g


@nb.njit(cache=True)
def _step(y, lost, h, A, b, K, Y, E, alpha, maxiter, out, out_lost):
    """One Gauss step of size h from (y, lost) into (out, out_lost); K holds the first
    iterate of the stage derivatives and receives the converged ones. Returns the sweeps
    (-1: no convergence)."""
    s = b.shape[0]
    it = 0
    previous = np.inf
    while True:
        change = stage_sweep(y, h, A, K, Y)
        if it > 0 and (change == 0.0 or (change >= previous and change < 1e-10)):
            break
        if it >= maxiter or not change < 1e300:
            return -1
        previous = change if it > 0 else np.inf
        it += 1
        for i in range(s):
            _rhs(Y[i], K[i], E, alpha)
    for a in range(_STATE):
        acc = 0.0
        for j in range(s):
            acc += b[j] * K[j, a]
        # compensated: y + lost + h acc, the rounding of the sum kept in out_lost
        increment = h * acc + lost[a]
        total = y[a] + increment
        back = total - y[a]
        out_lost[a] = (y[a] - (total - back)) + (increment - back)
        out[a] = total
    return it


@nb.njit(cache=True)
def kepler_poincare_run(y0, h, t_final, A, b, X, E, alpha, maxiter, max_steps):
    """Fixed fictitious steps h until t reaches t_final, the last one shortened to land
    on it. Returns (status, y at t_final, steps, total sweeps)."""
    s = b.shape[0]
    y = y0.copy()
    lost = np.zeros(_STATE)
    new = np.zeros(_STATE)
    new_lost = np.zeros(_STATE)
    K = np.zeros((s, _STATE))
    Kold = np.zeros((s, _STATE))
    Kstart = np.zeros((s, _STATE))
    Y = np.zeros((s, _STATE))
    _rhs(y, K[0], E, alpha)
    for j in range(1, s):
        K[j, :] = K[0, :]
    sweeps = 0
    for k in range(max_steps):
        if k > 0:
            extrapolate_stages(X, K, Kold)
        Kstart[:, :] = K
        its = _step(y, lost, h, A, b, K, Y, E, alpha, maxiter, new, new_lost)
        if its < 0:
            return hw.STATUS_NEWTON_FAILED, y, k, sweeps
        sweeps += its
        if new[4] + new_lost[4] < t_final:
            y[:] = new
            lost[:] = new_lost
            continue
        # the landing step: secant on the fictitious size, t(0) = t_k, t(h) = new t
        t_k = y[4] + lost[4]
        lo, t_lo = 0.0, t_k
        hi, t_hi = h, new[4] + new_lost[4]
        size = h
        for _ in range(30):
            size = lo + (t_final - t_lo) * (hi - lo) / (t_hi - t_lo)
            K[:, :] = Kstart
            its = _step(y, lost, size, A, b, K, Y, E, alpha, maxiter, new, new_lost)
            if its < 0:
                return hw.STATUS_NEWTON_FAILED, y, k, sweeps
            sweeps += its
            t_new = new[4] + new_lost[4]
            if t_new == t_final or abs(t_new - t_final) <= 4e-16 * abs(t_final):
                break
            lo, t_lo, hi, t_hi = hi, t_hi, size, t_new
        for a in range(_STATE):
            y[a] = new[a] + new_lost[a]
        return hw.STATUS_OK, y, k + 1, sweeps
    return hw.STATUS_NEWTON_FAILED, y, max_steps, sweeps


class KeplerPoincareRun:
    """Final state of :func:`kepler_poincare`: ``q``, ``p``, ``t``, ``n_steps``, ``mean_sweeps``."""

    def __init__(self, y: NDArray[np.float64], n_steps: int, sweeps: int) -> None:
        self.q, self.p, self.t = y[:2].copy(), y[2:4].copy(), float(y[4])
        self.n_steps = int(n_steps)
        self.mean_sweeps = sweeps / max(1, n_steps)


def kepler_poincare(
    q0, p0, s: int, h: float, t_final: float, alpha: float = 1.5, maxiter: int = 100,
    max_steps: int = 10_000_000,
) -> KeplerPoincareRun:  # fmt: skip
    """s-stage Gauss on K = r^alpha (H - E) from (q0, p0) at t = 0 to ``t_final``."""
    q0 = np.asarray(q0, dtype=float)
    p0 = np.asarray(p0, dtype=float)
    E = 0.5 * float(p0 @ p0) - 1.0 / float(np.linalg.norm(q0))
    tables = gauss_fixed_point_tables(s, first_order=True)
    y0 = np.array([*q0, *p0, 0.0])
    status, y, steps, sweeps = kepler_poincare_run(
        y0, float(h), float(t_final), tables.Abar, tables.b, tables.X, E, float(alpha),
        int(maxiter), int(max_steps),
    )  # fmt: skip
    hw._check(status, steps, "kepler_poincare")
    return KeplerPoincareRun(y, steps, sweeps)
