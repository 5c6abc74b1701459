r"""The fast parameter estimator: the discrete Euler–Lagrange residual at the observations.

Densely sampled positions :math:`q_0, \dots, q_{m-1}` at times
:math:`t_0 < \dots < t_{m-1}` (steps :math:`h_k = t_{k+1} - t_k`) nearly
satisfy the discrete Euler–Lagrange equations of the midpoint discrete
Lagrangian

.. math::

    L_d(q_k, q_{k+1}) = h_k\, L\big(\bar t_k, \bar q_k, \bar v_k\big), \qquad
    \bar t_k = \tfrac{t_k + t_{k+1}}{2},\ \bar q_k = \tfrac{q_k + q_{k+1}}{2},\
    \bar v_k = \tfrac{q_{k+1} - q_k}{h_k},

with the forces :math:`f` by the discrete Lagrange–d'Alembert principle
(:math:`f_d^\pm = \tfrac{h_k}{2} f(\bar t_k, \bar q_k, \bar v_k)`):

.. math::

    R_k(\theta) = \frac{2}{h_{k-1} + h_k}\Big[ L_v^{(k-1)} - L_v^{(k)}
    + \tfrac{h_{k-1}}{2}\,\big(L_q + f\big)^{(k-1)} + \tfrac{h_k}{2}\,\big(L_q + f\big)^{(k)} \Big]
    = 0, \qquad k = 1, \dots, m - 2,

a superscript :math:`(j)` meaning "at :math:`(\bar t_j, \bar q_j, \bar v_j)`". This is
:math:`D_2 L_d(q_{k-1}, q_k) + D_1 L_d(q_k, q_{k+1}) + f_d^+ + f_d^- = 0`
divided by the mean step, a second-order discretisation of
:math:`\tfrac{d}{dt} L_v = L_q + f` (force units). No integration is needed: the
parameters :math:`\theta` minimise :math:`\sum_k |R_k(\theta)|^2`. When
:math:`L_v`, :math:`L_q` and :math:`f` are affine in :math:`\theta` (detected with
SymPy: every second derivative in :math:`\theta` vanishes) the residual is
:math:`R(\theta) = R(0) + A\theta` with a constant :math:`A`, and one linear
least-squares solve gives :math:`\theta`; otherwise the same residuals are
minimised by :func:`scipy.optimize.least_squares` with their exact Jacobian.

The estimate carries the discretisation error :math:`O(h^2)` of the midpoint
rule and, with noisy positions, a bias (the residual differentiates the data
twice: noise :math:`\sigma` enters as :math:`\sigma / h^2`). It is a starting point
for :func:`~galerkin_vi.tangent.fit.fit_parameters`, which integrates.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..numeric import FlatEvaluator
from ..run.status import SolverResult
from .observations import FitStatus, check_observations, parameter_symbols

__all__ = ["ParameterEstimate", "estimate_parameters"]


@dataclass(frozen=True)
class ParameterEstimate(SolverResult):
    """The result of :func:`estimate_parameters`.

    Attributes
    ----------
    params : dict
        Parameter symbol -> estimated value.
    values : ndarray, shape (P,)
        The estimates in the order of ``symbols``.
    symbols : tuple of sympy.Symbol
        The estimated parameters, in the order asked for.
    residual_norm : float
        Root mean square of the discrete Euler–Lagrange residuals at the
        estimate (force units).
    linear : bool
        True when the residual is affine in the parameters (one linear solve).
    status : FitStatus
    message : str
    """

    params: dict
    values: NDArray[np.float64]
    symbols: tuple
    residual_norm: float
    linear: bool
    status: FitStatus
    message: str


class DELResidual:
    """The midpoint discrete Euler–Lagrange residuals of observations, and their Jacobian.

    Parameters
    ----------
    system : LagrangianSystem
        Unconstrained, without contacts.
    symbols : tuple of sympy.Symbol
        The parameters :math:`\\theta` the residual is a function of; the
        other parameters keep the system's values.
    t, q : ndarray
        Observation times (m,) and positions (m, n), checked.
    """

    def __init__(self, system, symbols: tuple, t: NDArray, q: NDArray) -> None:
        n = system.n
        forces = system.forces or (0,) * n
        lv = [sp.diff(system.L, v) for v in system.v]
        total = [sp.diff(system.L, qi) + f for qi, f in zip(system.q, forces, strict=True)]
        pieces = sp.Matrix([*lv, *total])
        gradient = pieces.jacobian(list(symbols))
        self.linear = all(sp.expand(sp.diff(e, s)) == 0 for e in gradient for s in symbols)
        args = system.arguments
        self._pieces = FlatEvaluator(list(pieces), args)
        self._gradient = FlatEvaluator.from_blocks([gradient], args)
        self._n, self._p = n, len(symbols)
        self._index = [system.params.index(s) for s in symbols]
        self._prm = system.parameter_vector()
        h = np.diff(t)
        self._h = h
        self._points = (
            0.5 * (t[1:] + t[:-1]),
            *(0.5 * (q[1:] + q[:-1])).T,
            *((q[1:] - q[:-1]) / h[:, None]).T,
        )

    def _parameters(self, theta: NDArray) -> NDArray:
        prm = self._prm.copy()
        prm[self._index] = theta
        return prm

    def _combine(self, E: NDArray) -> NDArray:
        """R_k from the pieces at the midpoints, E of shape (m - 1, 2n, ...)."""
        n, h = self._n, self._h
        shape = (-1,) + (1,) * (E.ndim - 1)
        ha, hb = h[:-1].reshape(shape), h[1:].reshape(shape)
        lv, total = E[:, :n], E[:, n:]
        bracket = lv[:-1] - lv[1:] + 0.5 * (ha * total[:-1] + hb * total[1:])
        return bracket / (0.5 * (ha + hb))

    def residual(self, theta: NDArray) -> NDArray[np.float64]:
        """The residuals :math:`R_k(\\theta)`, flattened to ((m - 2) n,)."""
        E = self._pieces(*self._points, *self._parameters(theta))
        return self._combine(E).ravel()

    def jacobian(self, theta: NDArray) -> NDArray[np.float64]:
        """:math:`\\partial R / \\partial \\theta`, shape ((m - 2) n, P)."""
        G = self._gradient(*self._points, *self._parameters(theta))
        G = G.reshape(G.shape[0], 2 * self._n, self._p)
        return self._combine(G).reshape(-1, self._p)


def estimate_parameters(
    system,
    t_obs: ArrayLike,
    q_obs: ArrayLike,
    params: Mapping[sp.Symbol | str, float] | Iterable[sp.Symbol | str],
) -> ParameterEstimate:
    r"""Estimate parameters from densely sampled positions without integrating.

    Minimises the midpoint discrete Euler–Lagrange residuals of the
    observations (module docstring): by one linear least-squares solve when
    :math:`L_v`, :math:`L_q` and the forces are affine in the parameters, else by
    :func:`scipy.optimize.least_squares` with the exact Jacobian.

    Parameters
    ----------
    system : LagrangianSystem
        Without constraints or contacts. Parameters not estimated keep the
        system's values.
    t_obs : array_like, shape (m,)
        Strictly increasing observation times (any spacing; m >= 3).
    q_obs : array_like, shape (m, n)
        Observed positions (shape (m,) for n = 1).
    params : sequence or mapping
        The parameters to estimate (symbols or names); a mapping gives the
        starting values of the nonlinear solve (default: the system's values).

    Returns
    -------
    ParameterEstimate
        ``status`` ``NOT_IDENTIFIABLE`` when the residual's Jacobian in the
        parameters is rank-deficient (then ``values`` is the minimum-norm
        solution of the linear problem, or the nonlinear solve's end point).

    Examples
    --------
    >>> import numpy as np, sympy as sp
    >>> import galerkin_vi as gvi
    >>> from galerkin_vi.tangent import estimate_parameters
    >>> x, v, k = sp.symbols("x v k")
    >>> osc = gvi.LagrangianSystem(v**2 / 2 - k * x**2 / 2, q=[x], v=[v], params={k: 1.0})
    >>> t = np.linspace(0.0, 3.0, 301)
    >>> est = estimate_parameters(osc, t, np.cos(2.0 * t), ["k"])
    >>> est.linear, round(float(est.values[0]), 3)
    (True, 4.0)
    """
    if system.constraints is not None or system.contacts:
        raise ValueError(
            "system: estimate_parameters needs a system without constraints or contacts "
            "(their multipliers and impulses are not in the observed positions); use "
            "fit_parameters"
        )
    t, q = check_observations(t_obs, q_obs, system.n, minimum=3)
    symbols = parameter_symbols(system, params)
    start = system.parameter_vector()[[system.params.index(s) for s in symbols]]
    if isinstance(params, Mapping):
        start = np.array([float(params[key]) for key in params], dtype=float)
    residual = DELResidual(system, symbols, t, q)
    if residual.linear:
        values, status = _solve_linear(residual, len(symbols))
    else:
        values, status = _solve_nonlinear(residual, start)
    r = residual.residual(values)
    return ParameterEstimate(
        params=dict(zip(symbols, (float(x) for x in values), strict=True)),
        values=values,
        symbols=symbols,
        residual_norm=float(np.sqrt(np.mean(r**2))),
        linear=residual.linear,
        status=status,
        message=status.cause
        if residual.linear or status != FitStatus.CONVERGED
        else "the nonlinear least-squares solve of the discrete Euler-Lagrange residuals converged",
    )


def _solve_linear(residual: DELResidual, p: int) -> tuple[NDArray, FitStatus]:
    """One least-squares solve of :math:`A\\theta = -R(0)`."""
    A = residual.jacobian(np.zeros(p))
    b = -residual.residual(np.zeros(p))
    values, _, rank, _ = np.linalg.lstsq(A, b, rcond=None)
    status = FitStatus.CONVERGED if rank == p else FitStatus.NOT_IDENTIFIABLE
    if status == FitStatus.CONVERGED:
        status = _identifiable(A)
    return values, status


def _solve_nonlinear(residual: DELResidual, start: NDArray) -> tuple[NDArray, FitStatus]:
    """Gauss–Newton (trust region) on the residuals, exact Jacobian."""
    from scipy.optimize import least_squares  # scipy.optimize: loaded when fitting

    sol = least_squares(
        residual.residual, start, jac=residual.jacobian, method="trf", x_scale="jac",
        ftol=1e-12, xtol=1e-12, gtol=1e-12,
    )  # fmt: skip
    if sol.status <= 0:
        return sol.x, FitStatus.MAX_EVALUATIONS
    return sol.x, _identifiable(sol.jac)


def _identifiable(J: NDArray) -> FitStatus:
    """NOT_IDENTIFIABLE when J's condition number is past the reach of double precision."""
    s = np.linalg.svd(J, compute_uv=False)
    if s.size == 0 or s[-1] <= s[0] * max(J.shape) * np.finfo(float).eps:
        return FitStatus.NOT_IDENTIFIABLE
    return FitStatus.CONVERGED
