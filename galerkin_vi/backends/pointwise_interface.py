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
AUTONOMOUS = False  # True when L does not depend on t: no time is formed or passed
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
    """Write dL/dq into ``Lq`` and dL/dv into ``Lv`` (shape (N,) each)."""
    raise NotImplementedError("generated per system")


def point_hessian(t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv):
    """Write the gradient and the second derivatives, flat (shape (NNZ,) each).

    Entry (a, b) sits at ``a * N + b`` (dense) or at its position in the
    pattern (banded).
    """
    raise NotImplementedError("generated per system")


def lagrangian(t, q, v, prm):
    """Return L(t, q, v)."""
    raise NotImplementedError("generated per system")
