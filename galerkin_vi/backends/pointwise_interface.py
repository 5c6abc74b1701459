"""The contract between generated code and the compiled time loop.

Every generated kernel module defines the names below (with ``N`` the number of
coordinates); :mod:`galerkin_vi.backends.kernel_template` is written against
them. The stubs here only document the interface and make the template a
valid, lintable Python module; the generator replaces them.

All point functions evaluate at one point ``(t, q, v)`` with parameter vector
``prm`` and write into preallocated arrays, so the time loop allocates nothing.
Entries of ``Lqq``, ``Lqv``, ``Lvv`` that are identically zero are never
written: the caller zeroes those arrays once. The second derivatives are stored
flat, dense (entry (a, b) at ``a * N + b``) or, for banded systems, in the
order of the sparsity pattern.
"""

from __future__ import annotations

import numpy as np

HAS_LQV = True  # False when d2L/dq dv is identically zero: the kernel skips that block
HAS_FV = False  # True when the forces depend on v: df/dv is written into Fv
DIAGONAL_MASS = False  # True when L_vv is a constant diagonal matrix (point masses)
AUTONOMOUS = False  # True when L does not depend on t: no time is formed or passed
# coordinates in which L, the forces and the constraints are 2 pi-periodic (angles):
# the loops keep them in [-pi, pi) and count the whole turns removed
PERIODIC = np.zeros(1, dtype=np.bool_)
HAS_PERIODIC = False
TWO_PI_HI = 6.283185307179586  # float(2 pi)
TWO_PI_LO = 2.4492935982947064e-16  # 2 pi - TWO_PI_HI
M_CONSTRAINTS = 0  # number of holonomic constraints (the constrained loop exists when > 0)
BANDED = False  # True: the stage Jacobian is stored and factorised as a band matrix
BAND = 0  # coordinate half-bandwidth w: L_qq, L_qv, L_vv vanish for |a - b| > w
NNZ = 1  # length of the flat arrays Lqq, Lqv, Lvv (N*N dense, the pattern size banded)
# banded only: row, column and position of the transposed entry of each stored entry
PATTERN_ROW = np.zeros(1, dtype=np.int64)
PATTERN_COL = np.zeros(1, dtype=np.int64)
PATTERN_T = np.zeros(1, dtype=np.int64)


def kernel(function):
    """Decorator applied to every kernel function (``numba.njit`` when compiled)."""
    return function


def point_kernel(function):
    """Decorator of the point functions (not inlined when they are large)."""
    return function


def point_gradient(t, q, v, prm, Lq, Lv):
    """Write dL/dq + f into ``Lq`` and dL/dv into ``Lv`` (shape (N,) each)."""
    raise NotImplementedError("generated per system")


def point_hessian(t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv):
    """Write the gradient and the second derivatives, flat (shape (NNZ,) each).

    With forces f, ``Lq`` receives dL/dq + f and ``Lqq`` d2L/dq2 + df/dq;
    ``Fv`` receives df/dv when ``HAS_FV`` (otherwise it is not touched).

    Entry (a, b) sits at ``a * N + b`` (dense) or at its position in the
    pattern (banded).
    """
    raise NotImplementedError("generated per system")


def lagrangian(t, q, v, prm):
    """Return L(t, q, v)."""
    raise NotImplementedError("generated per system")


def point_constraint(t, q, prm, g):
    """Write the constraint values g_j(t, q) into ``g`` (shape (M_CONSTRAINTS,))."""
    raise NotImplementedError("generated per constrained system")


def point_constraint_jacobian(t, q, prm, Gq):
    """Write dg_j/dq_a into ``Gq[j * N + a]`` (nonzero entries only)."""
    raise NotImplementedError("generated per constrained system")


def point_constraint_rate(t, q, prm, gt):
    """Write dg_j/dt into ``gt`` (nonzero entries only)."""
    raise NotImplementedError("generated per constrained system")


def point_constraint_hessian(t, q, lam, prm, Hg):
    """Write sum_j lam[j] d2g_j/dq_a dq_b into ``Hg[a * N + b]`` (nonzero entries only)."""
    raise NotImplementedError("generated per constrained system")
