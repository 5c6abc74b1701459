"""Oscillators and pendulums."""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from ..system import LagrangianSystem
from .base import Problem

__all__ = ["double_pendulum", "harmonic_oscillator", "pendulum"]


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
