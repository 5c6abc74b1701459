r"""scipy's DOP853 on Euler's equations with quaternion kinematics: the classical ODE peer.

State :math:`y = (\omega, e)`: body angular velocity and the unit quaternion
:math:`e = (e_0, e_1, e_2, e_3)` (scalar first) of the attitude :math:`R(e)` (body to space),

.. math::

    J\dot\omega = (J\omega)\times\omega + M, \qquad
    \dot e = \tfrac12\, e \otimes (0, \omega),

with :math:`M = 0` for the free body and :math:`M = m\,\rho\times(R(e)^\top\mathbf g)` for a body
about a fixed point in uniform gravity (heavy top; :math:`J` about the fixed point,
:math:`\rho` the centre of mass from it in the body frame). The quaternion's norm is left to
the integrator, as a user of ``solve_ivp`` would; :class:`EulerResult` reports its drift.
The right-hand side is one numba function of the state (no NumPy temporaries per call).
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numba
import numpy as np
from scipy.integrate import solve_ivp

__all__ = ["EulerResult", "euler_dop853", "quaternion_to_matrix"]


@dataclass
class EulerResult:
    """A DOP853 run on Euler's equations.

    Attributes
    ----------
    t : ndarray, shape (rows,)
    omega : ndarray, shape (rows, 3)
        Body angular velocity.
    e : ndarray, shape (rows, 4)
        Quaternion (scalar first), not renormalised.
    nfev : int
        Right-hand-side evaluations.
    cpu_time : float
        CPU seconds of ``solve_ivp``.
    success, status, message
        From ``solve_ivp``.
    """

    t: np.ndarray
    omega: np.ndarray
    e: np.ndarray
    nfev: int
    cpu_time: float
    success: bool
    status: int
    message: str


def quaternion_to_matrix(e: np.ndarray) -> np.ndarray:
    r"""Rotation matrices of rows of scalar-first quaternions (normalised first).

    .. math:: R(e) = (e_0^2 - |\mathbf e|^2) I + 2\mathbf e\mathbf e^\top + 2 e_0\hat{\mathbf e}.
    """
    e = np.asarray(e, dtype=float)
    e = e / np.linalg.norm(e, axis=-1, keepdims=True)
    w, x, y, z = np.moveaxis(e, -1, 0)
    R = np.empty(e.shape[:-1] + (3, 3))
    R[..., 0, 0] = 1 - 2 * (y * y + z * z)
    R[..., 0, 1] = 2 * (x * y - w * z)
    R[..., 0, 2] = 2 * (x * z + w * y)
    R[..., 1, 0] = 2 * (x * y + w * z)
    R[..., 1, 1] = 1 - 2 * (x * x + z * z)
    R[..., 1, 2] = 2 * (y * z - w * x)
    R[..., 2, 0] = 2 * (x * z - w * y)
    R[..., 2, 1] = 2 * (y * z + w * x)
    R[..., 2, 2] = 1 - 2 * (x * x + y * y)
    return R


@numba.njit(cache=True)
def _rhs(
    t: float,
    y: np.ndarray,
    J: np.ndarray,
    Jinv: np.ndarray,
    mg: np.ndarray,
    rho: np.ndarray,
    heavy: bool,
) -> np.ndarray:
    w0, w1, w2 = y[0], y[1], y[2]
    e0, e1, e2, e3 = y[3], y[4], y[5], y[6]
    L0 = J[0, 0] * w0 + J[0, 1] * w1 + J[0, 2] * w2
    L1 = J[1, 0] * w0 + J[1, 1] * w1 + J[1, 2] * w2
    L2 = J[2, 0] * w0 + J[2, 1] * w1 + J[2, 2] * w2
    m0 = L1 * w2 - L2 * w1
    m1 = L2 * w0 - L0 * w2
    m2 = L0 * w1 - L1 * w0
    if heavy:
        # gravity in the body frame, R(e)^T mg (R(e) of the unnormalised e scaled by |e|^2)
        n2 = e0 * e0 + e1 * e1 + e2 * e2 + e3 * e3
        r00 = (e0 * e0 + e1 * e1 - e2 * e2 - e3 * e3) / n2
        r01 = 2 * (e1 * e2 - e0 * e3) / n2
        r02 = 2 * (e1 * e3 + e0 * e2) / n2
        r10 = 2 * (e1 * e2 + e0 * e3) / n2
        r11 = (e0 * e0 - e1 * e1 + e2 * e2 - e3 * e3) / n2
        r12 = 2 * (e2 * e3 - e0 * e1) / n2
        r20 = 2 * (e1 * e3 - e0 * e2) / n2
        r21 = 2 * (e2 * e3 + e0 * e1) / n2
        r22 = (e0 * e0 - e1 * e1 - e2 * e2 + e3 * e3) / n2
        a0 = r00 * mg[0] + r10 * mg[1] + r20 * mg[2]
        a1 = r01 * mg[0] + r11 * mg[1] + r21 * mg[2]
        a2 = r02 * mg[0] + r12 * mg[1] + r22 * mg[2]
        m0 += rho[1] * a2 - rho[2] * a1
        m1 += rho[2] * a0 - rho[0] * a2
        m2 += rho[0] * a1 - rho[1] * a0
    out = np.empty(7)
    out[0] = Jinv[0, 0] * m0 + Jinv[0, 1] * m1 + Jinv[0, 2] * m2
    out[1] = Jinv[1, 0] * m0 + Jinv[1, 1] * m1 + Jinv[1, 2] * m2
    out[2] = Jinv[2, 0] * m0 + Jinv[2, 1] * m1 + Jinv[2, 2] * m2
    # e ⊗ (0, w) / 2
    out[3] = 0.5 * (-e1 * w0 - e2 * w1 - e3 * w2)
    out[4] = 0.5 * (e0 * w0 + e2 * w2 - e3 * w1)
    out[5] = 0.5 * (e0 * w1 + e3 * w0 - e1 * w2)
    out[6] = 0.5 * (e0 * w2 + e1 * w1 - e2 * w0)
    return out


def euler_dop853(
    J: np.ndarray | list[float],
    omega0: np.ndarray | list[float],
    e0: np.ndarray | list[float],
    t_final: float,
    rtol: float = 1e-10,
    atol: float = 1e-10,
    t_eval: np.ndarray | None = None,
    m: float = 0.0,
    g: np.ndarray | list[float] = (0.0, 0.0, 0.0),
    rho: np.ndarray | list[float] = (0.0, 0.0, 0.0),
) -> EulerResult:
    r"""Euler's equations and the quaternion kinematics by ``solve_ivp(method="DOP853")``.

    Parameters
    ----------
    J : array_like
        Inertia (3 principal moments or a 3x3 tensor), about the fixed point when ``m > 0``.
    omega0 : array_like, shape (3,)
        Initial body angular velocity.
    e0 : array_like, shape (4,)
        Initial attitude quaternion, scalar first.
    t_final : float
        Final time.
    rtol, atol : float
        DOP853 tolerances.
    t_eval : array_like, optional
        Output times (default: the accepted steps).
    m, g, rho
        Heavy top: mass, gravity vector (space), centre of mass from the fixed point (body);
        ``m = 0`` is the free body.
    """
    J = np.asarray(J, dtype=float)
    if J.shape == (3,):
        J = np.diag(J)
    if J.shape != (3, 3):
        raise ValueError(f"J must be 3 principal moments or a 3x3 tensor, got shape {J.shape}")
    y0 = np.concatenate([np.asarray(omega0, dtype=float), np.asarray(e0, dtype=float)])
    if y0.shape != (7,):
        raise ValueError("omega0 must be a 3-vector and e0 a 4-vector")
    mg = float(m) * np.asarray(g, dtype=float)
    args = (J, np.linalg.inv(J), mg, np.asarray(rho, dtype=float), bool(m != 0.0))
    _rhs(0.0, y0, *args)  # load or compile before the clock starts
    start = time.process_time()
    sol = solve_ivp(
        _rhs,
        (0.0, float(t_final)),
        y0,
        method="DOP853",
        rtol=rtol,
        atol=atol,
        t_eval=t_eval,
        args=args,
    )
    cpu = time.process_time() - start
    return EulerResult(
        t=sol.t,
        omega=sol.y[:3].T.copy(),
        e=sol.y[3:].T.copy(),
        nfev=int(sol.nfev),
        cpu_time=cpu,
        success=bool(sol.success),
        status=int(sol.status),
        message=str(sol.message),
    )
