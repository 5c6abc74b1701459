"""Oscillators and pendulums."""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from ..model.system import LagrangianSystem
from .base import Problem

__all__ = [
    "double_pendulum",
    "harmonic_oscillator",
    "henon_heiles",
    "pendulum",
    "spherical_pendulum",
]

ROTATION_Z = "rotation_z"
HENON_HEILES_ENERGY = 0.125


@cache
def _oscillator_system() -> LagrangianSystem:
    q, v, w = sp.symbols("q v omega")
    return LagrangianSystem(v**2 / 2 - w**2 * q**2 / 2, [q], [v], params={w: 1.0})


def harmonic_oscillator(omega: float = 1.0, q0: float = 1.0, v0: float = 0.5) -> Problem:
    r"""Harmonic oscillator :math:`L = \tfrac12 v^2 - \tfrac12\omega^2 q^2` (exact solution)."""
    system = _oscillator_system()

    def exact(t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        return (q0 * np.cos(omega * t) + v0 / omega * np.sin(omega * t))[..., None]

    return Problem(
        name="harmonic_oscillator",
        system=system,
        q0=np.array([q0]),
        v0=np.array([v0]),
        t_final=2.0,
        params={system.params[0]: omega},
        exact=exact,
    )


@cache
def _pendulum_system() -> LagrangianSystem:
    q, v = sp.symbols("q v")
    return LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])


def pendulum(q0: float = 1.5, v0: float = 0.3) -> Problem:
    r"""Mathematical pendulum :math:`L = \tfrac12 v^2 + \cos q`."""
    return Problem(
        name="pendulum",
        system=_pendulum_system(),
        q0=np.array([q0]),
        v0=np.array([v0]),
        t_final=2.0,
    )


@cache
def _double_pendulum_system() -> LagrangianSystem:
    a, b, va, vb = sp.symbols("theta1 theta2 omega1 omega2")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g", positive=True)
    kinetic = (
        (m1 + m2) * l1**2 * va**2 / 2
        + m2 * l2**2 * vb**2 / 2
        + m2 * l1 * l2 * sp.cos(a - b) * va * vb
    )
    potential = -(m1 + m2) * g * l1 * sp.cos(a) - m2 * g * l2 * sp.cos(b)
    return LagrangianSystem(
        kinetic - potential,
        [a, b],
        [va, vb],
        params={m1: 1.0, m2: 1.0, l1: 1.0, l2: 1.0, g: 1.0},
    )


def double_pendulum(
    m1: float = 1.0,
    m2: float = 1.0,
    l1: float = 1.0,
    l2: float = 1.0,
    q0: tuple[float, float] = (1.0, 0.5),
    v0: tuple[float, float] = (0.0, 0.3),
) -> Problem:
    """Planar double pendulum in absolute angles (non-constant mass matrix)."""
    system = _double_pendulum_system()
    values = dict(zip(system.params, (m1, m2, l1, l2, 1.0), strict=True))
    return Problem(
        name="double_pendulum",
        system=system,
        q0=np.array(q0, dtype=float),
        v0=np.array(v0, dtype=float),
        t_final=2.0,
        params=values,
    )


@cache
def _henon_heiles_system() -> LagrangianSystem:
    x, y, vx, vy = sp.symbols("x y vx vy")
    potential = (x**2 + y**2) / 2 + x**2 * y - y**3 / 3
    return LagrangianSystem((vx**2 + vy**2) / 2 - potential, [x, y], [vx, vy])


def henon_heiles(
    q0: tuple[float, float] = (0.0, -0.2),
    v0: tuple[float, float] | None = None,
    t_final: float = 10.0,
) -> Problem:
    r"""Hénon–Heiles system, a chaotic two-degree-of-freedom Hamiltonian system.

    .. math::

        L = \tfrac12 (\dot x^2 + \dot y^2) - \tfrac12 (x^2 + y^2) - x^2 y + \tfrac13 y^3 .

    Parameters
    ----------
    q0 : tuple of float
        Initial position :math:`(x, y)`.
    v0 : tuple of float, optional
        Initial velocity. By default :math:`\dot y = 0` and :math:`\dot x > 0`
        chosen so that the energy is :data:`HENON_HEILES_ENERGY` :math:`= 1/8`,
        the chaotic regime of [1]_. The default ``q0 = (0, -0.2)``
        lies in the chaotic sea of the Poincaré section :math:`x = 0`
        (largest Lyapunov exponent about 0.08, measured over :math:`t \le 1000`;
        against below 0.006 for the starts :math:`y = 0, 0.1, 0.2` on regular tori).
    t_final : float
        Default length of the time span.

    Notes
    -----
    No exact solution: :meth:`Problem.reference` integrates the Euler–Lagrange
    equations (:func:`ode_reference`). Chaos amplifies errors exponentially,
    so compare with the reference over short spans only.

    References
    ----------
    .. [1] E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*,
       2nd ed., Springer 2006, Section I.3.
    """
    x, y = (float(c) for c in q0)
    if v0 is None:
        potential = (x**2 + y**2) / 2 + x**2 * y - y**3 / 3
        kinetic = HENON_HEILES_ENERGY - potential
        if kinetic < 0:
            raise ValueError(f"q0={q0} lies outside the energy surface H = 1/8; give v0")
        v0 = (float(np.sqrt(2 * kinetic)), 0.0)
    return Problem(
        name="henon_heiles",
        system=_henon_heiles_system(),
        q0=np.array([x, y]),
        v0=np.array(v0, dtype=float),
        t_final=t_final,
    )


@cache
def _spherical_pendulum_system() -> LagrangianSystem:
    theta, phi, vtheta, vphi = sp.symbols("theta phi vtheta vphi")
    g, length = sp.symbols("g l", positive=True)
    kinetic = length**2 * (vtheta**2 + sp.sin(theta) ** 2 * vphi**2) / 2
    return LagrangianSystem(
        kinetic + g * length * sp.cos(theta),
        [theta, phi],
        [vtheta, vphi],
        params={g: 1.0, length: 1.0},
    )


def spherical_pendulum(
    g: float = 1.0,
    length: float = 1.0,
    q0: tuple[float, float] = (1.0, 0.0),
    v0: tuple[float, float] = (0.0, 1.0),
    t_final: float = 5.0,
) -> Problem:
    r"""Spherical pendulum of unit mass in spherical angles :math:`(\theta, \varphi)`.

    .. math::

        L = \tfrac12 \ell^2 (\dot\theta^2 + \sin^2\theta\,\dot\varphi^2)
            + g \ell \cos\theta,

    with :math:`\theta` measured from the downward vertical: the bob is at
    :math:`\ell(\sin\theta\cos\varphi, \sin\theta\sin\varphi, -\cos\theta)`, so
    :math:`\theta = 0` is the stable (hanging) equilibrium. Parameters ``g`` and
    ``l`` (the length).

    The Lagrangian is invariant under rotations about the vertical,
    :math:`\varphi \mapsto \varphi + \alpha`, generator :math:`(0, 1)` (key
    ``"rotation_z"``): the momentum :math:`p_\varphi = \ell^2 \sin^2\theta\,
    \dot\varphi` is conserved.

    Notes
    -----
    The mass matrix :math:`\mathrm{diag}(\ell^2, \ell^2\sin^2\theta)` is singular
    at the poles :math:`\theta \in \{0, \pi\}` (a coordinate singularity); the
    default data :math:`\theta = 1, \dot\theta = 0, \dot\varphi = 1` keep
    :math:`\theta` in about :math:`[0.74, 1]`, well away from them. No exact
    solution in elementary functions: the reference is :func:`ode_reference`.
    """
    system = _spherical_pendulum_system()
    return Problem(
        name="spherical_pendulum",
        system=system,
        q0=np.array(q0, dtype=float),
        v0=np.array(v0, dtype=float),
        t_final=t_final,
        params=dict(zip(system.params, (g, length), strict=True)),
        symmetries={ROTATION_Z: (sp.Integer(0), sp.Integer(1))},
    )
