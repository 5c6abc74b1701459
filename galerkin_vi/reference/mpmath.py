r"""Extended-precision reference: the position–momentum map in mpmath.

Orders 8 to 12 cannot be measured reliably in float64: the errors that lie
above the round-off floor are still pre-asymptotic on nonlinear problems. This
backend runs the same equations as the compiled kernel (increment form,
Newton with the exact Jacobian) at ``dps`` significant digits, so the
asymptotic range can be reached. It is slow (pure Python, about 10 ms per
Newton iteration for 12 unknowns) and meant for order studies only.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import mpmath
import sympy as sp

from ..errors import ConvergenceError
from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem

__all__ = ["MpComposition", "MpIntegrator"]

_GUARD_DIGITS = 10


class MpIntegrator:
    """Galerkin integrator of ``system`` in mpmath arithmetic at ``dps`` digits.

    Parameters
    ----------
    system : LagrangianSystem
    method : Galerkin
    dps : int
        Significant decimal digits (default 32).
    """

    def __init__(self, system: LagrangianSystem, method: Galerkin, dps: int = 32) -> None:
        if system.m:
            raise NotImplementedError(
                "the mpmath backend does not support constraints; measure constrained "
                "orders in float64 (dps=None)"
            )
        self.system = system
        self.method = method
        self.dps = int(dps)
        self.tables = method.exact_tables(self.dps + _GUARD_DIGITS)
        p = system.pieces
        args = list(system.arguments)
        n = system.n
        self._n = n
        # generalised force L_q + f and its q-derivative; f_v joins the (q, v) block row
        Lqv_row = p.Lqv.as_mutable() + (p.fv if p.fv is not None else sp.zeros(n, n))
        self._hessian: Callable = sp.lambdify(
            args,
            [*p.force, *p.Lv, *p.force_q.as_mutable(), *p.Lqv, *p.Lvv, *Lqv_row],
            modules="mpmath",
            cse=True,
        )
        self._gradient: Callable = sp.lambdify(args, [*p.force, *p.Lv], modules="mpmath", cse=True)
        self._legendre: Callable = sp.lambdify(args, list(p.Lv), modules="mpmath", cse=True)

    def _points(self, t0, h, qk, C):
        tb, n = self.tables, self._n
        s1 = len(tb.d)
        out = []
        for i in range(len(tb.b)):
            Q = [
                qk[a] + mpmath.fsum(tb.Phi[i][nu] * C[nu][a] for nu in range(1, s1))
                for a in range(n)
            ]
            V = [mpmath.fsum(tb.D[i][nu] * C[nu][a] for nu in range(1, s1)) / h for a in range(n)]
            out.append((t0 + tb.c[i] * h, Q, V))
        return out

    def _gradient_G(self, t0, h, qk, C, prm):
        tb, n = self.tables, self._n
        s1 = len(tb.d)
        G = [[mpmath.mpf(0)] * n for _ in range(s1)]
        for i, (t, Q, V) in enumerate(self._points(t0, h, qk, C)):
            vals = self._gradient(t, *Q, *V, *prm)
            for nu in range(s1):
                wq, wv = tb.b[i] * h * tb.Phi[i][nu], tb.b[i] * tb.D[i][nu]
                for a in range(n):
                    G[nu][a] += wq * vals[a] + wv * vals[n + a]
        return G

    def _newton_system(self, t0, h, qk, pk, C, prm):
        tb, n = self.tables, self._n
        s1 = len(tb.d)
        s = s1 - 1
        G = [[mpmath.mpf(0)] * n for _ in range(s1)]
        K = mpmath.zeros(s * n, s * n)
        for i, (t, Q, V) in enumerate(self._points(t0, h, qk, C)):
            vals = self._hessian(t, *Q, *V, *prm)
            Lq, Lv = vals[:n], vals[n : 2 * n]
            block = [vals[2 * n + k * n * n : 2 * n + (k + 1) * n * n] for k in range(4)]
            Lqq, Lqv, Lvv, Lqv_row = block
            bi, Phi, D = tb.b[i], tb.Phi[i], tb.D[i]
            for nu in range(s1):
                for a in range(n):
                    G[nu][a] += bi * (h * Phi[nu] * Lq[a] + D[nu] * Lv[a])
            for nu in range(s):
                for mu in range(1, s1):
                    w_qq = bi * h * Phi[nu] * Phi[mu]
                    w_qv = bi * Phi[nu] * D[mu]
                    w_vq = bi * D[nu] * Phi[mu]
                    w_vv = bi * D[nu] * D[mu] / h
                    for a in range(n):
                        for c in range(n):
                            K[nu * n + a, (mu - 1) * n + c] += (
                                w_qq * Lqq[a * n + c]
                                + w_qv * Lqv_row[a * n + c]
                                + w_vq * Lqv[c * n + a]
                                + w_vv * Lvv[a * n + c]
                            )
        R = mpmath.matrix(
            [G[nu][a] + (pk[a] if nu == 0 else 0) for nu in range(s) for a in range(n)]
        )
        return R, K

    def final_state(
        self,
        q0: Sequence,
        v0: Sequence,
        t0: float,
        t_final: float,
        n_steps: int,
        params: Sequence[float] = (),
        maxiter: int = 40,
    ) -> tuple[list, list]:
        """Positions and momenta at ``t0 + t_final`` after ``n_steps`` equal steps from (q0, v0).

        Returns mpmath numbers. The step :math:`h = T/N` and the initial momentum
        (the continuous Legendre transform of ``v0``) are formed at ``dps``
        digits, so float inputs are taken as exact.
        """
        with mpmath.workdps(self.dps):
            n, tb = self._n, self.tables
            s1 = len(tb.d)
            s = s1 - 1
            h = mpmath.mpf(t_final) / n_steps
            t0 = mpmath.mpf(t0)
            prm = [mpmath.mpf(x) for x in params]
            qk = [mpmath.mpf(x) for x in q0]
            v = [mpmath.mpf(x) for x in v0]
            pk = list(self._legendre(t0, *qk, *v, *prm))
            C = [[tb.d[nu] * h * v[a] for a in range(n)] for nu in range(s1)]
            tol = mpmath.mpf(10) ** (-self.dps + 3)
            for k in range(n_steps):
                tk = t0 + k * h
                if k > 0:
                    C = [
                        [
                            mpmath.fsum(tb.extrapolation[nu][mu] * C[mu][a] for mu in range(1, s1))
                            - C[s][a]
                            for a in range(n)
                        ]
                        for nu in range(s1)
                    ]
                    C[0] = [mpmath.mpf(0)] * n
                for _iteration in range(maxiter):
                    R, K = self._newton_system(tk, h, qk, pk, C, prm)
                    dx = mpmath.lu_solve(K, -R)
                    size = max(abs(x) for row in C for x in row)
                    for nu in range(1, s1):
                        for a in range(n):
                            C[nu][a] += dx[(nu - 1) * n + a]
                    if max(abs(x) for x in dx) <= tol * (1 + size):
                        break
                else:
                    raise ConvergenceError(
                        f"mpmath Newton did not converge at step {k}",
                        step=k,
                        t=float(tk),
                        residual=float(max(abs(x) for x in dx)),
                    )
                pk = self._gradient_G(tk, h, qk, C, prm)[s]
                qk = [qk[a] + C[s][a] for a in range(n)]
            return qk, pk


class MpComposition:
    r"""A :class:`~galerkin_vi.Composition` in mpmath arithmetic.

    The kicks and drifts of :mod:`galerkin_vi.loops.explicit` (:math:`M^{-1}` solved at
    ``dps`` digits), with the composition's coefficients at ``dps`` + 20 digits: the
    order studies of orders 8 and 10 and of the splittings, whose float64 errors above
    round-off are still pre-asymptotic.
    """

    def __init__(self, system: LagrangianSystem, method: Composition, dps: int = 32) -> None:
        self.system = system
        self.method = method
        self.dps = int(dps)
        p = system.pieces
        args = list(system.arguments)
        self._n = system.n
        self._gradient: Callable = sp.lambdify(args, [*p.force, *p.Lv], modules="mpmath", cse=True)
        self._legendre: Callable = sp.lambdify(args, list(p.Lv), modules="mpmath", cse=True)
        self._mass: Callable = sp.lambdify(args, list(p.Lvv), modules="mpmath", cse=True)

    def final_state(
        self,
        q0: Sequence,
        v0: Sequence,
        t0: float,
        t_final: float,
        n_steps: int,
        params: Sequence[float] = (),
        maxiter: int = 40,
    ) -> tuple[list, list]:
        """Positions and momenta at ``t0 + t_final`` after ``n_steps`` equal steps from
        (q0, v0), as :meth:`MpIntegrator.final_state` (``maxiter`` is not used: nothing
        iterates)."""
        from ..method.composition import exact_splitting

        n = self._n
        with mpmath.workdps(self.dps + _GUARD_DIGITS):
            drifts, kicks = exact_splitting(self.method.order, self.method.scheme, self.dps + 20)
        with mpmath.workdps(self.dps):
            h = mpmath.mpf(t_final) / n_steps
            t0 = mpmath.mpf(t0)
            prm = [mpmath.mpf(x) for x in params]
            q = [mpmath.mpf(x) for x in q0]
            v = [mpmath.mpf(x) for x in v0]
            zero = [mpmath.mpf(0)] * n
            p = list(self._legendre(t0, *q, *v, *prm))
            mass = mpmath.matrix(n, n)
            for k, value in enumerate(self._mass(t0, *q, *zero, *prm)):
                mass[k // n, k % n] = value
            inverse = mass**-1
            values = self._gradient(t0, *q, *zero, *prm)
            force, a_start = values[:n], values[n:]
            for k in range(n_steps):
                start = t0 + k * h
                # kick b_1 h F, then per drift: drift, force, kick b_{i+1} h F
                p = [p[a] + kicks[0] * h * force[a] for a in range(n)]
                for drift, kick in zip(drifts, kicks[1:], strict=True):
                    eta = drift * h
                    end = start + eta
                    a_end = self._gradient(end, *q, *zero, *prm)[n:]
                    rhs = mpmath.matrix([p[a] - (a_start[a] + a_end[a]) / 2 for a in range(n)])
                    velocity = inverse * rhs
                    q = [q[a] + eta * velocity[a] for a in range(n)]
                    values = self._gradient(end, *q, *zero, *prm)
                    force, a_start = values[:n], values[n:]
                    p = [p[a] + kick * h * force[a] for a in range(n)]
                    start = end
            return q, p
