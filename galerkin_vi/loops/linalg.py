r"""Storage, assembly and LU factorisation of the stage Jacobian, dense or banded.

The Newton iterations of :mod:`galerkin_vi.newton` (the stopping rule, dense
and banded LU) are plain Python shared with the NumPy reference backend; here
they are compiled into the loops. The stage Jacobian is stored dense,
``(s n, s n)`` node-major, or, when the coordinates couple only within a band
of half-width :math:`w` (``traits[BAND] = w``), as a LAPACK band matrix
ordered coordinate-major, with half-bandwidth :math:`(w + 1) s - 1`.

Banded storage is chosen by the type of ``pattern``, a switch
(:mod:`.traits`): the sparsity pattern of the blocks, or ``None`` (dense).
The couplings :math:`L_{qv}` and :math:`f_v` are one switch, ``couplings``:
``None`` where the system has neither (compiled out), else the pair of
run-time flags (has :math:`L_{qv}`, has :math:`f_v`).
"""

# ruff: noqa: N803, N806
from __future__ import annotations

import numpy as np

from .. import newton
from ._jit import kernel, scalar
from .traits import BAND

__all__ = [
    "CONTINUE",
    "CONVERGED",
    "add_block",
    "factor_jacobian",
    "lu_factor_inplace",
    "lu_solve_inplace",
    "new_jacobian",
    "newton_status",
    "solve_jacobian",
    "unknown",
]

CONTINUE = newton.CONTINUE
CONVERGED = newton.CONVERGED
newton_status = scalar(newton.newton_status)
lu_factor_inplace = kernel(newton.lu_factor_inplace)
band_lu_factor = kernel(newton.band_lu_factor)
lu_permute = kernel(newton.lu_permute)
lu_forward = kernel(newton.lu_forward)
lu_backward = kernel(newton.lu_backward)
band_lu_forward = kernel(newton.band_lu_forward)
band_lu_backward = kernel(newton.band_lu_backward)


@kernel
def lu_solve_inplace(lu, piv, x):
    """Solve ``A y = x`` in place with :func:`lu_factor_inplace`'s factors.

    As :func:`galerkin_vi.newton.lu_solve_inplace`, composed of its one-loop pieces
    (see there: no reference counts in the caller's loop).
    """
    lu_permute(piv, x)
    lu_forward(lu, x)
    lu_backward(lu, x)


@kernel
def band_lu_solve(ab, piv, kl, ku, x):
    """Solve ``A y = x`` in place with :func:`band_lu_factor`'s factors (one-loop pieces)."""
    band_lu_forward(ab, piv, kl, ku, x)
    band_lu_backward(ab, kl, ku, x)


@scalar
def band_half_width(s, band):
    """Half-bandwidth of the stage Jacobian ordered coordinate-major, (w + 1) s - 1."""
    return (band + 1) * s - 1


@scalar
def unknown(nu, a, s, n, banded):
    """Position of coordinate a of control point nu (0-based among the unknowns).

    Node-major (nu n + a) for dense storage; coordinate-major (a s + nu) for
    banded storage, which keeps coupled coordinates' unknowns close together.
    """
    # ``banded`` is ``pattern is not None`` in the caller, a constant of each compiled
    # variant: a bool, not the pattern itself, because every array passed into an
    # inlined helper costs an atomic reference count increment and decrement
    if banded:
        return a * s + nu
    return nu * n + a


@kernel
def block_size(n, pattern):
    """Length of the flat second-derivative arrays: n^2 dense, the pattern's size banded."""
    if pattern is not None:
        return pattern.shape[0]
    return n * n


@kernel
def new_jacobian(s, n, traits, pattern):
    """Zero stage Jacobian: banded storage (3 kb + 1, s n) or dense (s n, s n)."""
    if pattern is not None:
        return np.zeros((3 * band_half_width(s, traits[BAND]) + 1, s * n))
    return np.zeros((s * n, s * n))


@kernel
def add_block(
    K, nu, mu, s, n, w_vv, Lvv, w_qq, Lqq, w_qv, w_vq, Lqv, Fv, traits, pattern, couplings
):
    r"""Add to block (equation nu, control point mu) of K the point-wise second derivatives.

    Block :math:`(\nu, \mu)` gains
    :math:`w_{vv} L_{vv} + w_{qq} (L_{qq} + f_q) + w_{qv} (L_{qv} + f_v) + w_{vq} L_{qv}^T`,
    with the blocks stored flat (``a n + c``, or the pattern position when banded;
    ``pattern[k] = (row, column, position of the transposed entry)``).
    ``couplings``: ``None``, or whether :math:`L_{qv}` and :math:`f_v` are present.
    """
    has_lqv = False
    has_fv = False
    if couplings is not None:
        has_lqv, has_fv = couplings
    if pattern is not None:
        add_band_block(
            K, nu, mu, s, band_half_width(s, traits[BAND]), w_vv, Lvv, w_qq, Lqq, w_qv, w_vq,
            Lqv, Fv, has_lqv, has_fv, pattern,
        )  # fmt: skip
    else:
        add_dense_block(K, nu * n, (mu - 1) * n, n, w_vv, Lvv, w_qq, Lqq, w_qv, w_vq, Lqv, Fv,
                        has_lqv, has_fv)  # fmt: skip


@kernel
def add_dense_block(K, row0, col0, n, w_vv, Lvv, w_qq, Lqq, w_qv, w_vq, Lqv, Fv, has_lqv, has_fv):
    """:func:`add_block` in dense storage, the block at (row0, col0): one loop nest."""
    # collocated Lobatto nodes (Phi = I): L_qq only on the diagonal blocks, w_qq = 0
    # elsewhere (the tests of w_qq and the flags are loop-invariant: hoisted)
    for a in range(n):
        for cc in range(n):
            value = w_vv * Lvv[a * n + cc]
            if w_qq != 0.0:
                value += w_qq * Lqq[a * n + cc]
            if has_lqv:
                value += w_qv * Lqv[a * n + cc] + w_vq * Lqv[cc * n + a]
            if has_fv:
                value += w_qv * Fv[a * n + cc]
            K[row0 + a, col0 + cc] += value


@kernel
def add_band_block(
    K, nu, mu, s, kb, w_vv, Lvv, w_qq, Lqq, w_qv, w_vq, Lqv, Fv, has_lqv, has_fv, pattern
):
    """:func:`add_block` in banded storage of half-bandwidth ``kb``: one loop."""
    for k in range(pattern.shape[0]):
        a = pattern[k, 0]
        cc = pattern[k, 1]
        value = w_vv * Lvv[k]
        if w_qq != 0.0:
            value += w_qq * Lqq[k]
        if has_lqv:
            value += w_qv * Lqv[k] + w_vq * Lqv[pattern[k, 2]]
        if has_fv:
            value += w_qv * Fv[k]
        i = a * s + nu
        j = cc * s + mu - 1
        K[2 * kb + i - j, j] += value


@kernel
def factor_jacobian(K, piv, s, traits, pattern):
    """LU-factorise K in place (banded or dense); False if singular."""
    if pattern is not None:
        kb = band_half_width(s, traits[BAND])
        return band_lu_factor(K, piv, kb, kb)
    return lu_factor_inplace(K, piv)


@kernel
def solve_jacobian(K, piv, s, R, traits, pattern):
    """Overwrite R with K^{-1} R from :func:`factor_jacobian`'s factors."""
    if pattern is not None:
        kb = band_half_width(s, traits[BAND])
        band_lu_solve(K, piv, kb, kb, R)
    else:
        lu_solve_inplace(K, piv, R)
