r"""Newton iteration for the stage equations, independent of any Lagrangian.

The stopping rule follows the reference measurements in the project's theory
notes: a relative increment tolerance alone cannot be met once
:math:`\kappa(K)\,\varepsilon` exceeds it, and stopping as soon as the increment
is a few ulps leaves a systematic energy drift over long runs. So, once the
increment :math:`\|\Delta X\|_\infty` is below :math:`\mathrm{tol}\,(1+\|X\|_\infty)`,
the iteration goes on until the increment is zero (below
:math:`\varepsilon^2(1+\|X\|_\infty)`, ``NEGLIGIBLE``) or stops decreasing.
An increment that stops decreasing above the tolerance but within ``STAGNATION``
times it is the round-off floor :math:`\kappa(K)\,\varepsilon` of an
ill-conditioned step and is accepted too.

Everything from the ``# ---- kernel ----`` marker on is plain, allocation-free
Python that the compiled backend copies into each generated module and jits;
the NumPy backend calls the same functions uncompiled.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "CONTINUE",
    "CONVERGED",
    "DIVERGED",
    "NOT_CONVERGED",
    "NewtonResult",
    "band_lu_factor",
    "band_lu_solve",
    "band_lu_solve_transpose",
    "lu_factor_inplace",
    "lu_solve_inplace",
    "lu_solve_transpose",
    "newton_solve",
    "newton_status",
]

# ---- kernel ----
# an increment that stops decreasing within this factor of the tolerance is at the
# round-off floor of the solve and accepted
STAGNATION = 100.0
NEGLIGIBLE = 2.0**-104  # eps^2: see newton_status
CONTINUE = 0
CONVERGED = 1
DIVERGED = 2
NOT_CONVERGED = 3


def newton_status(increment, previous, scale, tol, iteration, maxiter):
    """Decide after Newton iteration ``iteration`` (1-based) what to do next.

    ``increment`` is the max-norm of the latest update, ``previous`` the one
    before (``inf`` on the first iteration) and ``scale`` is ``1 + |X|``.
    """
    if not increment < 1e300:
        return DIVERGED
    # only a zero increment ends the iteration early: increments far below an ulp of q
    # still reach the compensated sum of the positions (a threshold of 1e-18 |q| made
    # the solar system's energy drift twice as fast over 2e5 steps). Below eps^2 |q| an
    # increment can move the energy by no more than eps^2 per step, and iterating on
    # would only refine coordinates that are themselves below eps |q| (the far end of
    # a chain at rest: 21 full Newton iterations per step instead of 5)
    if increment <= NEGLIGIBLE * scale:
        return CONVERGED
    if increment <= tol * scale:
        if increment >= previous:
            return CONVERGED
        if iteration >= maxiter:
            return CONVERGED
        return CONTINUE
    if iteration >= 3 and previous <= increment <= STAGNATION * tol * scale:
        # stopped decreasing just above tol: the round-off floor kappa(K) eps of an
        # ill-conditioned step (close encounters), not a failure to converge
        return CONVERGED
    if iteration >= maxiter:
        return NOT_CONVERGED
    if iteration >= 3 and increment > 2.0 * previous:
        return DIVERGED
    return CONTINUE


def lu_factor_inplace(a, piv):
    """LU factorisation with partial pivoting, in place. Returns False if singular.

    The strict lower triangle holds L (unit diagonal), the strict upper triangle U,
    and the diagonal the reciprocals 1/u_ii: the back substitution multiplies
    instead of dividing (a chain of dependent divisions, profiled at a tenth of the
    general loop's own time on small systems).
    """
    n = a.shape[0]
    for k in range(n):
        p = k
        big = abs(a[k, k])
        for i in range(k + 1, n):
            if abs(a[i, k]) > big:
                big = abs(a[i, k])
                p = i
        piv[k] = p
        if big == 0.0 or not big < 1e300:
            return False
        if p != k:
            for j in range(n):
                tmp = a[k, j]
                a[k, j] = a[p, j]
                a[p, j] = tmp
        inv = 1.0 / a[k, k]
        for i in range(k + 1, n):
            a[i, k] *= inv
            f = a[i, k]
            if f != 0.0:
                for j in range(k + 1, n):
                    a[i, j] -= f * a[k, j]
        a[k, k] = inv
    return True


def lu_solve_inplace(lu, piv, x):
    """Solve ``A y = x`` in place given ``lu_factor_inplace``'s output."""
    lu_permute(piv, x)
    lu_forward(lu, x)
    lu_backward(lu, x)


# The solve in three pieces of one loop nest each: compiled into a loop, a helper of
# several loops that takes arrays leaves numba's reference counts of its arguments in
# the caller's loop (3 atomic pairs per call measured), one of a single loop nest not.
def lu_permute(piv, x):
    """Apply the row interchanges of :func:`lu_factor_inplace` to ``x``."""
    for k in range(x.shape[0]):
        p = piv[k]
        if p != k:
            tmp = x[k]
            x[k] = x[p]
            x[p] = tmp


def lu_forward(lu, x):
    """x <- L^{-1} x with the unit lower triangle of ``lu``."""
    n = lu.shape[0]
    for i in range(n):
        acc = x[i]
        for j in range(i):
            acc -= lu[i, j] * x[j]
        x[i] = acc


def lu_backward(lu, x):
    """x <- U^{-1} x with the upper triangle of ``lu`` (its diagonal holds 1/u_ii)."""
    n = lu.shape[0]
    for i in range(n - 1, -1, -1):
        acc = x[i]
        for j in range(i + 1, n):
            acc -= lu[i, j] * x[j]
        x[i] = acc * lu[i, i]


def band_lu_factor(ab, piv, kl, ku):
    """Banded LU with partial pivoting, in place (LAPACK ``gbtf2`` layout).

    ``ab`` has shape ``(2 kl + ku + 1, m)``; entry ``A[i, j]`` is stored in
    ``ab[kl + ku + i - j, j]`` and the top ``kl`` rows are zero on entry (room
    for the fill-in that pivoting creates). On return row ``kl + ku`` (the
    diagonal) holds the reciprocal pivots, as in :func:`lu_factor_inplace`.
    Cost ``O(m kl (kl + ku))``. Returns False if a pivot is zero or not finite.
    """
    m = ab.shape[1]
    kv = kl + ku
    last = 0  # last column touched by the row interchanges so far
    for j in range(m):
        below = min(kl, m - 1 - j)
        p = 0
        big = abs(ab[kv, j])
        for i in range(1, below + 1):
            if abs(ab[kv + i, j]) > big:
                big = abs(ab[kv + i, j])
                p = i
        piv[j] = j + p
        if big == 0.0 or not big < 1e300:
            return False
        last = max(last, min(j + ku + p, m - 1))
        if p != 0:
            for c in range(j, last + 1):
                tmp = ab[kv + j - c, c]
                ab[kv + j - c, c] = ab[kv + j + p - c, c]
                ab[kv + j + p - c, c] = tmp
        inv = 1.0 / ab[kv, j]
        ab[kv, j] = inv
        for i in range(1, below + 1):
            ab[kv + i, j] *= inv
        for c in range(j + 1, last + 1):
            f = ab[kv + j - c, c]
            if f != 0.0:
                for i in range(1, below + 1):
                    ab[kv + j + i - c, c] -= ab[kv + i, j] * f
    return True


def band_lu_solve(ab, piv, kl, ku, x):
    """Solve ``A y = x`` in place given :func:`band_lu_factor`'s output."""
    band_lu_forward(ab, piv, kl, ku, x)
    band_lu_backward(ab, kl, ku, x)


def band_lu_forward(ab, piv, kl, ku, x):
    """Interchanges and x <- L^{-1} x of :func:`band_lu_factor`'s factors."""
    m = ab.shape[1]
    kv = kl + ku
    for j in range(m):
        p = piv[j]
        if p != j:
            tmp = x[j]
            x[j] = x[p]
            x[p] = tmp
        xj = x[j]
        if xj != 0.0:
            for i in range(1, min(kl, m - 1 - j) + 1):
                x[j + i] -= ab[kv + i, j] * xj


def band_lu_backward(ab, kl, ku, x):
    """x <- U^{-1} x with the band upper triangle of :func:`band_lu_factor`'s factors."""
    m = ab.shape[1]
    kv = kl + ku
    for j in range(m - 1, -1, -1):
        x[j] *= ab[kv, j]
        xj = x[j]
        if xj != 0.0:
            for i in range(max(0, j - kv), j):
                x[i] -= ab[kv + i - j, j] * xj


def lu_solve_transpose(lu, piv, x):
    r"""Solve :math:`A^T y = x` in place with :func:`lu_factor_inplace`'s factors.

    With :math:`A = P^T L U`, :math:`A^{-T} = P^T L^{-T} U^{-T}`: a forward
    substitution with :math:`U^T` (whose diagonal is stored as reciprocals), a
    backward one with the unit :math:`L^T`, then the interchanges in reverse
    order. The discrete adjoint's transposed step is one such solve.
    """
    n = lu.shape[0]
    for i in range(n):
        acc = x[i]
        for j in range(i):
            acc -= lu[j, i] * x[j]
        x[i] = acc * lu[i, i]
    for i in range(n - 1, -1, -1):
        acc = x[i]
        for j in range(i + 1, n):
            acc -= lu[j, i] * x[j]
        x[i] = acc
    for k in range(n - 1, -1, -1):
        p = piv[k]
        if p != k:
            tmp = x[k]
            x[k] = x[p]
            x[p] = tmp


def band_lu_solve_transpose(ab, piv, kl, ku, x):
    r"""Solve :math:`A^T y = x` in place with :func:`band_lu_factor`'s factors.

    :func:`band_lu_factor` writes :math:`A = (L_0 P_0)^{-1} \cdots` column by
    column; the transpose applies :math:`U^{-T}` (forward, band of width
    ``kl + ku``), then for ``j = m-1 .. 0`` the transposed elimination of column
    ``j`` and its interchange.
    """
    m = ab.shape[1]
    kv = kl + ku
    for j in range(m):
        acc = x[j]
        for i in range(max(0, j - kv), j):
            acc -= ab[kv + i - j, j] * x[i]
        x[j] = acc * ab[kv, j]
    for j in range(m - 1, -1, -1):
        acc = x[j]
        for i in range(1, min(kl, m - 1 - j) + 1):
            acc -= ab[kv + i, j] * x[j + i]
        x[j] = acc
        p = piv[j]
        if p != j:
            tmp = x[j]
            x[j] = x[p]
            x[p] = tmp


# ---- end kernel ----


@dataclass(frozen=True)
class NewtonResult:
    """Outcome of :func:`newton_solve`."""

    x: NDArray[np.float64]
    iterations: int
    increment: float
    residual: float
    status: int

    @property
    def converged(self) -> bool:
        """True when the stopping rule declared convergence."""
        return self.status == CONVERGED


def newton_solve(
    residual_and_jacobian: Callable[[NDArray], tuple[NDArray, NDArray]],
    x0: NDArray,
    tol: float = 1e-14,
    maxiter: int = 30,
    watched: int | None = None,
    base: float = 0.0,
) -> NewtonResult:
    r"""Solve :math:`R(x) = 0` by Newton's method with the stagnation stopping rule.

    Parameters
    ----------
    residual_and_jacobian : callable
        ``x -> (R(x), J(x))`` with ``J`` the exact Jacobian, shape (n, n).
    x0 : ndarray, shape (n,)
        Initial guess.
    tol : float
        Relative increment tolerance, :math:`\|\Delta x\|_\infty \le
        \mathrm{tol}\,(1 + \|x\|_\infty)`; see the module notes.
    maxiter : int
        Iteration cap.
    watched : int, optional
        Apply the stopping test to the first ``watched`` unknowns only (all by
        default). Auxiliary unknowns, such as constraint multipliers whose
        round-off floor lies above the positions', then converge with them
        without holding up the test.
    base : float
        Size of the point the unknowns are increments from (``max|q_k|``):
        the scale of the test becomes ``1 + max(base, |x|)``, since far from
        the origin the round-off floor of the increments is that of ``q``.
    """
    x = np.array(x0, dtype=float)
    previous = np.inf
    residual = np.inf
    for iteration in range(1, maxiter + 1):
        r, jac = residual_and_jacobian(x)
        residual = float(np.max(np.abs(r), initial=0.0))
        try:
            dx = np.linalg.solve(jac, -r)
        except np.linalg.LinAlgError:
            return NewtonResult(x, iteration, np.inf, residual, DIVERGED)
        x = x + dx
        if not np.all(np.isfinite(x)):
            return NewtonResult(x, iteration, np.inf, residual, DIVERGED)
        increment = float(np.max(np.abs(dx[:watched]), initial=0.0))
        scale = 1.0 + float(np.max(np.abs(x[:watched]), initial=base))
        status = newton_status(increment, previous, scale, tol, iteration, maxiter)
        if status != CONTINUE:
            return NewtonResult(x, iteration, increment, residual, status)
        previous = increment
    return NewtonResult(x, maxiter, previous, residual, NOT_CONVERGED)
