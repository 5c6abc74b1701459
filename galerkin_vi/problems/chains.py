"""Chains of masses and springs: the Fermi–Pasta–Ulam problem and a linear/FPU-beta chain."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from functools import cache

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..model.system import LagrangianSystem
from .base import Problem

__all__ = ["fermi_pasta_ulam", "spring_chain"]


def _differences(q: Sequence[sp.Symbol]) -> list[sp.Expr]:
    """Spring elongations :math:`q_{i+1} - q_i`, i = 0..N, with fixed ends q_0 = q_{N+1} = 0."""
    padded = [sp.Integer(0), *q, sp.Integer(0)]
    return [b - a for a, b in zip(padded[:-1], padded[1:], strict=True)]


@cache
def _fpu_system(m: int) -> LagrangianSystem:
    q = sp.symbols(f"q1:{2 * m + 1}")
    v = sp.symbols(f"v1:{2 * m + 1}")
    omega = sp.Symbol("omega", positive=True)
    diffs = _differences(q)
    # diffs[2i - 1] = q_{2i} - q_{2i-1} (stiff, i = 1..m); diffs[2i] = q_{2i+1} - q_{2i} (soft)
    stiff = sp.Add(*(d**2 for d in diffs[1::2]))
    soft = sp.Add(*(d**4 for d in diffs[0::2]))
    kinetic = sp.Add(*(w**2 for w in v)) / 2
    return LagrangianSystem(
        kinetic - omega**2 * stiff / 4 - soft, list(q), list(v), params={omega: 50.0}
    )


def fermi_pasta_ulam(m: int = 3, omega: float = 50.0, t_final: float = 200.0) -> Problem:
    r"""Fermi–Pasta–Ulam problem: 2m unit masses, alternately stiff linear and soft cubic springs.

    .. math::

        L = \tfrac12 \sum_{i=1}^{2m} \dot q_i^2
            - \frac{\omega^2}{4} \sum_{i=1}^{m} (q_{2i} - q_{2i-1})^2
            - \sum_{i=0}^{m} (q_{2i+1} - q_{2i})^4,
        \qquad q_0 = q_{2m+1} = 0,

    the Hamiltonian of [1]_ (Section I.5.1) as a Lagrangian; :math:`\omega` is
    the parameter ``omega``.

    Parameters
    ----------
    m : int
        Number of stiff springs (``2 m`` coordinates).
    omega : float
        Stiffness frequency (default 50 as in [1]_).
    t_final : float
        Default span 200, as in the experiments of [1]_: the stiff springs
        exchange their energy on the time scale :math:`\omega`.

    Notes
    -----
    Initial data of [1]_: in the coordinates
    :math:`x_{0,i} = (q_{2i} + q_{2i-1})/\sqrt2` (centre of the stiff spring) and
    :math:`x_{1,i} = (q_{2i} - q_{2i-1})/\sqrt2` (its elongation), with
    :math:`y = \dot x`,

    .. math::

        x_{0,1} = 1,\quad y_{0,1} = 1,\quad x_{1,1} = \omega^{-1},\quad y_{1,1} = 1,

    all others zero; that is :math:`q_1 = (1 - \omega^{-1})/\sqrt2`,
    :math:`q_2 = (1 + \omega^{-1})/\sqrt2`, :math:`\dot q_1 = 0`,
    :math:`\dot q_2 = \sqrt2`. The oscillatory energy of the first stiff
    spring, :math:`I_1 = \tfrac12(y_{1,1}^2 + \omega^2 x_{1,1}^2)`, is 1. (Setting
    :math:`q_1 = 1, q_2 = \omega^{-1}` directly would put an energy of about
    :math:`\omega^2/4` into that spring.)

    No exact solution: the reference is :func:`ode_reference`, which must
    resolve the period :math:`\pi/\omega` of the stiff springs.

    References
    ----------
    .. [1] E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*,
       2nd ed., Springer 2006, Section I.5.1.
    """
    if isinstance(m, bool) or not isinstance(m, (int, np.integer)) or m < 1:
        raise ValueError(f"m must be a positive int, got {m!r}")
    system = _fpu_system(int(m))
    q0 = np.zeros(2 * m)
    v0 = np.zeros(2 * m)
    x0, y0, x1, y1 = 1.0, 1.0, 1.0 / omega, 1.0
    q0[0], q0[1] = (x0 - x1) / np.sqrt(2), (x0 + x1) / np.sqrt(2)
    v0[0], v0[1] = (y0 - y1) / np.sqrt(2), (y0 + y1) / np.sqrt(2)
    return Problem(
        name="fermi_pasta_ulam",
        system=system,
        q0=q0,
        v0=v0,
        t_final=t_final,
        params={system.params[0]: omega},
    )


@cache
def _spring_chain_system(n_masses: int, nonlinear: bool) -> LagrangianSystem:
    q = sp.symbols(f"q1:{n_masses + 1}")
    v = sp.symbols(f"v1:{n_masses + 1}")
    mass, stiffness, beta = sp.symbols("m k beta", positive=True)
    diffs = _differences(q)
    half = sp.Rational(1, 2)
    # flat sums (sp.Add of all terms at once): building them term by term is quadratic in N
    terms = [half * mass * w**2 for w in v]
    terms += [-half * stiffness * d**2 for d in diffs]
    params = {mass: 1.0, stiffness: 1.0}
    if nonlinear:
        terms += [-beta * d**4 / 4 for d in diffs]
        params[beta] = 1.0
    return LagrangianSystem(sp.Add(*terms), list(q), list(v), params=params)


def _normal_mode_solution(
    q0: NDArray, v0: NDArray, mass: float, stiffness: float
) -> Callable[[float | NDArray], NDArray[np.float64]]:
    """Exact solution of the linear chain (formula in :func:`spring_chain`)."""
    n = q0.size
    j = np.arange(1, n + 1)
    phi = np.sqrt(2.0 / (n + 1)) * np.sin(np.outer(j, j) * np.pi / (n + 1))
    omega = 2.0 * np.sqrt(stiffness / mass) * np.sin(j * np.pi / (2 * (n + 1)))
    a0, adot0 = phi @ q0, phi @ v0

    def exact(t: float | NDArray) -> NDArray[np.float64]:
        wt = np.multiply.outer(np.asarray(t, dtype=float), omega)
        return (a0 * np.cos(wt) + adot0 / omega * np.sin(wt)) @ phi

    return exact


def spring_chain(
    n_masses: int = 10,
    stiffness: float = 1.0,
    beta: float = 0.0,
    mass: float = 1.0,
    q0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    t_final: float = 10.0,
) -> Problem:
    r"""N equal masses on a line between two walls, joined by N + 1 springs.

    .. math::

        L = \sum_{i=1}^{N} \tfrac12 m \dot q_i^2
            - \sum_{i=0}^{N} \Big[\tfrac k2 (q_{i+1} - q_i)^2
            + \tfrac\beta4 (q_{i+1} - q_i)^4\Big],
        \qquad q_0 = q_{N+1} = 0,

    with parameters ``m``, ``k`` and (only if ``beta != 0``, the FPU-:math:`\beta`
    chain) ``beta``.

    Parameters
    ----------
    n_masses : int
        N, the number of coordinates. :math:`L` is one flat sum, cheap to
        differentiate: N = 1000 builds (with its structure analysis) in about 2 s.
    stiffness, beta, mass : float
        :math:`k`, :math:`\beta`, :math:`m`.
    q0, v0 : array_like, shape (N,), optional
        Default: the first two modes, :math:`q_i = \sin(\pi x_i) + \tfrac12
        \sin(2\pi x_i)` with :math:`x_i = i/(N+1)`, at rest.
    t_final : float

    Notes
    -----
    The system is cached per ``(n_masses, beta != 0)``: for ``beta == 0`` it is
    built without the quartic term, so that :math:`L` is quadratic
    (``structure.quadratic``) and the integrator takes its linear path.

    With :math:`\beta = 0` the equations :math:`m\ddot q = -kTq`,
    :math:`T = \mathrm{tridiag}(-1, 2, -1)`, are solved exactly by normal modes:
    :math:`T = \Phi\,\mathrm{diag}(\lambda_j)\,\Phi` with the orthonormal, symmetric
    :math:`\Phi_{ij} = \sqrt{2/(N+1)}\sin(ij\pi/(N+1))` and
    :math:`\lambda_j = 4\sin^2(j\pi/(2(N+1)))`, so with :math:`a = \Phi q`,
    :math:`\omega_j = \sqrt{k\lambda_j/m}`,

    .. math::

        q(t) = \Phi\Big(a_j(0)\cos\omega_j t
               + \frac{\dot a_j(0)}{\omega_j}\sin\omega_j t\Big)_j .

    For :math:`\beta \ne 0` the reference is :func:`ode_reference`.
    """
    if isinstance(n_masses, bool) or not isinstance(n_masses, (int, np.integer)) or n_masses < 1:
        raise ValueError(f"n_masses must be a positive int, got {n_masses!r}")
    n = int(n_masses)
    x = np.arange(1, n + 1) / (n + 1)
    q_init = np.sin(np.pi * x) + 0.5 * np.sin(2 * np.pi * x) if q0 is None else np.array(q0, float)
    v_init = np.zeros(n) if v0 is None else np.array(v0, dtype=float)
    for name, arr in (("q0", q_init), ("v0", v_init)):
        if arr.shape != (n,):
            raise ValueError(f"{name} must have shape ({n},), got {arr.shape}")
    nonlinear = beta != 0.0
    system = _spring_chain_system(n, nonlinear)
    params = dict(zip(system.params, (mass, stiffness, beta)[: len(system.params)], strict=True))

    return Problem(
        name="spring_chain",
        system=system,
        q0=q_init,
        v0=v_init,
        t_final=t_final,
        params=params,
        exact=None if nonlinear else _normal_mode_solution(q_init, v_init, mass, stiffness),
    )
