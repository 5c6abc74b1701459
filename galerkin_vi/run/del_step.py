r"""One step of the position-only form of the discrete Euler–Lagrange equations.

.. math::

    D_2 L_d(q_{k-1}, q_k) + D_1 L_d(q_k, q_{k+1}) = 0,

solved together with the interior stationarity conditions of both steps, as
one Newton system in the interior points of step :math:`k-1` and all free
control points of step :math:`k` (exact Jacobian from the NumPy reference's
discrete Hessian).
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray

from ..errors import ConvergenceError
from ..newton import CONVERGED, newton_solve
from ..reference import numpy as numpy_backend
from .plan import state_vector, step_size

__all__ = ["del_step"]


def del_step(system, tb, q0, q1, h, t0, prm, tol: float, maxiter: int) -> NDArray[np.float64]:
    """:math:`q_{k+1}` from :math:`(q_{k-1}, q_k) =` ``(q0, q1)``, ``q0`` at time ``t0``.

    ``tb`` are the method's tables, ``prm`` the parameter vector.
    """
    qa, qb = state_vector("q0", q0, system.n), state_vector("q1", q1, system.n)
    h = step_size(h)
    t0 = float(t0)
    if not np.isfinite(t0):
        raise ValueError(f"t0 must be finite, got {t0}")
    s = tb.d.size - 1
    n = system.n
    t1 = float(t0) + h
    # unknowns as increments: interior points of step k-1 from q0, all of step k from q1;
    # guess: the line through q0, q1 for step k-1, continued for step k
    step = qb - qa
    x0 = np.concatenate([(tb.d[1:s, None] * step).ravel(), (tb.d[1:, None] * step).ravel()])
    m = (s - 1) * n
    zero = np.zeros((1, n))

    def residual_and_jacobian(x: NDArray) -> tuple[NDArray, NDArray]:
        Ca = np.vstack([zero, x[:m].reshape(s - 1, n), step[None, :]])
        Cb = np.vstack([zero, x[m:].reshape(s, n)])
        Ga, Ha = numpy_backend.discrete_hessian(system, tb, float(t0), h, qa, Ca, prm)
        Gb, Hb = numpy_backend.discrete_hessian(system, tb, t1, h, qb, Cb, prm)
        # equations: interior of step k-1, DEL at q_k, interior of step k
        R = np.concatenate([Ga[1:s].ravel(), Ga[s] + Gb[0], Gb[1:s].ravel()])
        J = np.zeros((R.size, x.size))
        J[:m, :m] = Ha[1:s, :, 1:s, :].reshape(m, m)
        J[m : m + n, :m] = Ha[s, :, 1:s, :].reshape(n, m)
        J[m : m + n, m:] = Hb[0, :, 1:, :].reshape(n, s * n)
        J[m + n :, m:] = Hb[1:s, :, 1:, :].reshape(m, s * n)
        return R, J

    result = newton_solve(residual_and_jacobian, x0, tol=tol, maxiter=maxiter)
    if result.status != CONVERGED:
        raise ConvergenceError(
            f"step_del: Newton iteration did not converge (increment {result.increment:.3g})",
            step=0,
            t=t1,
            residual=result.increment,
        )
    return qb + result.x[-n:]
