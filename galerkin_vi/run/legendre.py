r"""The continuous Legendre transform at one state, through the compiled point functions.

Every :meth:`Integrator.integrate` call starts from :math:`p_0 = L_v(t_0, q_0,
v_0)` (or the velocities of given momenta) and checks that :math:`L_{vv}` is
regular there. Evaluated with the NumPy expressions of the system (and the
regularity test), these would be a large part of a short run. The system's
compiled Hessian point function (:mod:`galerkin_vi.loops.point`) gives
:math:`L_v` and :math:`L_{vv}` in one call of a few microseconds, through
:mod:`ctypes` and the C wrapper numba builds around it.

Banded systems (chains) keep the second derivatives as the entries of their
sparsity pattern, in its order; they are scattered into a dense :math:`L_{vv}`
for the regularity test (:func:`~galerkin_vi.model.system.is_regular`: an SVD up to
64 coordinates, an LU condition estimate beyond). The numbers behind this choice
are in docs/performance.md, "Measurements behind design choices".
"""

from __future__ import annotations

import ctypes
import threading

import numpy as np
from numpy.typing import NDArray

from ..model.system import are_regular, is_regular

__all__ = ["ConstantMassLegendre", "PointLegendre"]

#: the Hessian point function's C signature: void(t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv)
_HESSIAN = ctypes.CFUNCTYPE(None, ctypes.c_double, *([ctypes.c_void_p] * 9))
#: the gradient point function's C signature: void(t, q, v, prm, Lq, Lv)
_GRADIENT = ctypes.CFUNCTYPE(None, ctypes.c_double, *([ctypes.c_void_p] * 5))
#: mass matrices kept per system (one per parameter vector in use)
_MASSES_KEPT = 16


def _vector(x) -> NDArray[np.float64]:
    return np.ascontiguousarray(x, dtype=np.float64)


class PointLegendre:
    r""":math:`L_v` and :math:`L_{vv}` at one state from a compiled Hessian point function.

    Parameters
    ----------
    address : int
        Address of the C wrapper of the system's ``point_hessian`` ``cfunc``.
    n : int
        Number of coordinates.
    pattern : sequence of (int, int), optional
        Banded storage: the (row, column) of each stored second-derivative
        entry, in storage order (``SpecSummary.pattern``). Omitted: dense
        storage, n x n entries row by row.
    """

    def __init__(self, address: int, n: int, pattern=None) -> None:
        self._call = _HESSIAN(address)
        self.n = n
        size = n * n if pattern is None else len(pattern)
        self._rows = self._columns = None
        if pattern is not None:
            entries = np.asarray(pattern, dtype=np.intp).reshape(-1, 2)
            self._rows, self._columns = entries[:, 0].copy(), entries[:, 1].copy()
        # one buffer for the inputs and outputs, its addresses taken once (``.ctypes``
        # builds an object per access: 10 of them cost more than the call)
        self._work = np.zeros(4 * n + 4 * size)
        base, itemsize = self._work.ctypes.data, self._work.itemsize
        offsets = [0, n, 2 * n, 3 * n, 4 * n] + [4 * n + k * size for k in range(1, 4)]
        self._q, self._v = self._work[:n], self._work[n : 2 * n]
        self._Lv = self._work[3 * n : 4 * n]
        self._Lvv = self._work[4 * n : 4 * n + size]
        # q, v, Lq, Lv, Lvv, then Lqq, Lqv and Fv (not read)
        self._addresses = [base + itemsize * k for k in offsets]
        # the stored L_vv entries last found regular: a constant mass matrix is
        # tested once, not per call (100 coordinates: an LU, ~0.1 ms)
        self._regular_entries: NDArray[np.float64] | None = None
        # the buffer is shared: threads of an ensemble (integrate_many) take turns
        self._lock = threading.Lock()

    def at(self, t: float, q, v, prm) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(L_v, L_vv) at (t, q, v) with parameter vector ``prm``."""
        n = self.n
        prm = _vector(prm)
        self._work[2 * n :] = 0.0  # entries that are identically zero are never written
        self._q[:] = q
        self._v[:] = v
        a = self._addresses
        # the C signature's order: t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv
        self._call(
            float(t), a[0], a[1], prm.ctypes.data, a[2], a[3], a[5], a[6], a[4], a[7],
        )  # fmt: skip
        if self._rows is None:
            return self._Lv.copy(), self._Lvv.reshape(n, n).copy()
        dense = np.zeros((n, n))
        dense[self._rows, self._columns] = self._Lvv
        return self._Lv.copy(), dense

    def _regular(self, m: NDArray[np.float64]) -> bool:
        """Whether the L_vv just evaluated (dense ``m``) is finite and regular."""
        entries = self._Lvv
        if self._regular_entries is not None and np.array_equal(entries, self._regular_entries):
            return True
        if not (np.isfinite(m).all() and is_regular(m)):
            return False
        self._regular_entries = entries.copy()
        return True

    def momenta(self, t: float, q, v, prm) -> NDArray[np.float64] | None:
        r""":math:`p = L_v(t, q, v)`; None where :math:`L_{vv}` is not regular or not finite."""
        with self._lock:
            p, m = self.at(t, q, v, prm)
            return p if self._regular(m) else None

    def many(self, fn, t0: float, q, v, prms) -> tuple[NDArray, NDArray, NDArray[np.bool_]]:
        r"""(L_v, L_vv, regular) at ``(t0, q[i], v[i])`` with parameters ``prms[i]``, stacked.

        One compiled call for all rows (:func:`galerkin_vi.loops.members.legendre_members`,
        through ``fn``, the loops' tuple of point-function addresses), the same
        values as :meth:`at` row by row; ``regular[i]``: :math:`L_{vv}` finite and
        regular (:func:`~galerkin_vi.model.system.are_regular`).
        """
        from ..loops.members import legendre_members

        q, v, prms = _vector(q), _vector(v), _vector(prms)
        m, n = q.shape
        size = n * n if self._rows is None else len(self._rows)
        Lv, entries = np.zeros((m, n)), np.zeros((m, size))
        legendre_members(fn, float(t0), q, v, prms, Lv, entries)
        if self._rows is None:
            Lvv = entries.reshape(m, n, n)
        else:
            Lvv = np.zeros((m, n, n))
            Lvv[:, self._rows, self._columns] = entries
        return Lv, Lvv, are_regular(Lvv)

    def velocities_of_quadratic(self, t: float, q, p, prm) -> NDArray[np.float64] | None:
        r"""Velocities of momenta ``p`` when L is quadratic in v: one solve,
        :math:`v = L_{vv}^{-1} (p - L_v(t, q, 0))`; None where :math:`L_{vv}` is singular."""
        with self._lock:
            base, m = self.at(t, q, np.zeros(self.n), prm)
            if not self._regular(m):
                return None
        return np.linalg.solve(m, _vector(p) - base)


class ConstantMassLegendre:
    r"""The Legendre transform of a separable L with constant mass, from its gradient alone.

    For :math:`L = \tfrac12 v^T M v + a(t, q)\cdot v - V(t, q)` with :math:`M`
    constant in :math:`(t, q, v)` (it may depend on the parameters),

    .. math::

        p = L_v(t, q, v), \qquad v = M^{-1}\big(p - L_v(t, q, 0)\big),

    so one call of the compiled gradient point function gives either
    direction, and :math:`M`, its regularity test and :math:`M^{-1}` are
    computed once per parameter vector (the explicit loop's systems compile
    no Hessian point function).

    Parameters
    ----------
    address : int
        Address of the C wrapper of the system's ``point_gradient`` ``cfunc``.
    n : int
        Number of coordinates.
    mass : callable
        ``mass(prm)``: the dense :math:`M` (n, n) at parameter vector ``prm``.
    """

    def __init__(self, address: int, n: int, mass) -> None:
        self._call = _GRADIENT(address)
        self.n = n
        self._mass = mass
        # inputs and outputs in one buffer, their addresses taken once: q, v, Lq, Lv
        self._work = np.zeros(4 * n)
        base, itemsize = self._work.ctypes.data, self._work.itemsize
        self._addresses = [base + itemsize * k * n for k in range(4)]
        self._q, self._v, self._Lv = self._work[:n], self._work[n : 2 * n], self._work[3 * n :]
        #: parameter vector (bytes) -> (M, M^-1 or None when singular, diagonal of M^-1 or None)
        self._inverses: dict[bytes, tuple] = {}
        self._lock = threading.Lock()

    def _gradient(self, t: float, q, v, prm) -> NDArray[np.float64]:
        r""":math:`L_v(t, q, v)` (the caller holds the lock)."""
        prm = _vector(prm)
        self._q[:] = q
        self._v[:] = v
        a = self._addresses
        self._call(float(t), a[0], a[1], prm.ctypes.data, a[2], a[3])
        return self._Lv.copy()

    def inverse_mass(self, prm) -> tuple[NDArray, NDArray | None, NDArray | None]:
        r"""``(M, M^{-1}, diag(M^{-1}))`` at ``prm``; the last two None when :math:`M` is
        singular or not finite."""
        prm = _vector(prm)
        key = prm.tobytes()
        with self._lock:
            found = self._inverses.get(key)
        if found is not None:
            return found
        mass = np.asarray(self._mass(prm), dtype=float).reshape(self.n, self.n)
        inverse = diagonal = None
        if np.isfinite(mass).all() and is_regular(mass):
            inverse = np.linalg.inv(mass)
            # a writable copy: numba types a read-only view as another (compiled) variant
            diagonal = np.diag(inverse).copy()
        found = (mass, inverse, diagonal)
        with self._lock:
            if len(self._inverses) >= _MASSES_KEPT:
                self._inverses.pop(next(iter(self._inverses)))
            self._inverses[key] = found
        return found

    def momenta(self, t: float, q, v, prm) -> NDArray[np.float64] | None:
        r""":math:`p = L_v(t, q, v)`; None where :math:`M` is singular."""
        if self.inverse_mass(prm)[1] is None:
            return None
        with self._lock:
            return self._gradient(t, q, v, prm)

    def velocities_of_quadratic(self, t: float, q, p, prm) -> NDArray[np.float64] | None:
        r""":math:`v = M^{-1}(p - L_v(t, q, 0))`; None where :math:`M` is singular."""
        inverse = self.inverse_mass(prm)[1]
        if inverse is None:
            return None
        with self._lock:
            base = self._gradient(t, q, np.zeros(self.n), prm)
        return inverse @ (_vector(p) - base)

    def many(self, fn, t0: float, q, v, prms) -> tuple[NDArray, NDArray, NDArray[np.bool_]]:
        r"""(L_v, M, regular) at ``(t0, q[i], v[i])`` with parameters ``prms[i]``, stacked
        (the interface of :meth:`PointLegendre.many`; ``fn`` is not needed)."""
        q, v, prms = _vector(q), _vector(v), _vector(prms)
        m, n = q.shape
        Lv, masses = np.zeros((m, n)), np.zeros((m, n, n))
        regular = np.zeros(m, dtype=bool)
        with self._lock:
            for i in range(m):
                Lv[i] = self._gradient(t0, q[i], v[i], prms[i])
        for i in range(m):
            masses[i], inverse, _ = self.inverse_mass(prms[i])
            regular[i] = inverse is not None
        return Lv, masses, regular
