"""Central forces, the Kepler problem and N bodies."""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from ..system import LagrangianSystem
from .base import Problem

__all__ = ["central_force", "kepler", "kepler_position", "n_body"]

ROTATION_XY = "rotation"


def kepler_position(t: float | np.ndarray, e: float) -> np.ndarray:
    r"""Exact Kepler orbit with :math:`a = \mu = 1`, at perihelion :math:`(1-e, 0)` when t = 0.

    Solves Kepler's equation :math:`E - e\sin E = t` by Newton's method.
    """
    mean = np.fmod(np.asarray(t, dtype=float), 2 * np.pi)
    E = mean + e * np.sin(mean) if e < 0.8 else np.full_like(mean, np.pi)
    for _ in range(60):
        dE = (E - e * np.sin(E) - mean) / (1 - e * np.cos(E))
        E = E - dE
        if np.all(np.abs(dE) < 1e-15):
            break
    return np.stack([np.cos(E) - e, np.sqrt(1 - e * e) * np.sin(E)], axis=-1)


@cache
def _kepler_system() -> LagrangianSystem:
    x, y, vx, vy = sp.symbols("x y vx vy")
    return LagrangianSystem((vx**2 + vy**2) / 2 + 1 / sp.sqrt(x**2 + y**2), [x, y], [vx, vy])


def kepler(e: float = 0.5) -> Problem:
    r"""Kepler problem :math:`L = \tfrac12|v|^2 + 1/|q|`, eccentricity ``e``.

    Semi-major axis 1, period :math:`2\pi`, exact solution by Kepler's equation.
    """
    if not 0 <= e < 1:
        raise ValueError(f"eccentricity must be in [0, 1), got {e}")
    system = _kepler_system()
    x, y = system.q
    return Problem(
        name="kepler",
        system=system,
        q0=np.array([1 - e, 0.0]),
        v0=np.array([0.0, np.sqrt((1 + e) / (1 - e))]),
        t_final=2.0,
        exact=lambda t: kepler_position(t, e),
        symmetries={ROTATION_XY: (-y, x)},
    )


@cache
def _central_force_system() -> LagrangianSystem:
    x, y, vx, vy = sp.symbols("x y vx vy")
    a, b, c = sp.symbols("a b c")
    r2 = x**2 + y**2
    potential = a * r2 / 2 + c * r2**2 / 4 - b / sp.sqrt(r2)
    return LagrangianSystem(
        (vx**2 + vy**2) / 2 - potential, [x, y], [vx, vy], params={a: 1.0, b: 1.0, c: 0.1}
    )


def central_force(
    a: float = 1.0,
    b: float = 1.0,
    c: float = 0.1,
    q0: tuple[float, float] = (1.0, 0.0),
    v0: tuple[float, float] = (0.1, 1.0),
) -> Problem:
    r"""Planar particle in :math:`V(r) = \tfrac a2 r^2 + \tfrac c4 r^4 - b/r`.

    Rotation symmetric: the angular momentum is conserved.
    """
    system = _central_force_system()
    x, y = system.q
    return Problem(
        name="central_force",
        system=system,
        q0=np.array(q0, dtype=float),
        v0=np.array(v0, dtype=float),
        t_final=2.0,
        params=dict(zip(system.params, (a, b, c), strict=True)),
        symmetries={ROTATION_XY: (-y, x)},
    )


@cache
def _n_body_system(n_bodies: int, softening: float) -> LagrangianSystem:
    masses = sp.symbols(f"m0:{n_bodies}", positive=True)
    xs = sp.symbols(f"x0:{n_bodies}")
    ys = sp.symbols(f"y0:{n_bodies}")
    vxs = sp.symbols(f"vx0:{n_bodies}")
    vys = sp.symbols(f"vy0:{n_bodies}")
    kinetic = sum(m * (u**2 + w**2) / 2 for m, u, w in zip(masses, vxs, vys, strict=True))
    potential = 0
    for i in range(n_bodies):
        for j in range(i + 1, n_bodies):
            r2 = (xs[i] - xs[j]) ** 2 + (ys[i] - ys[j]) ** 2 + softening
            potential -= masses[i] * masses[j] / sp.sqrt(r2)
    q = [s for pair in zip(xs, ys, strict=True) for s in pair]
    v = [s for pair in zip(vxs, vys, strict=True) for s in pair]
    return LagrangianSystem(kinetic - potential, q, v, params=dict.fromkeys(masses, 1.0))


def n_body(
    masses: tuple[float, ...] = (1.0, 1.0, 1.0), softening: float = 0.01, seed: int = 0
) -> Problem:
    r"""Planar softened N-body problem, :math:`V = -\sum m_im_j/\sqrt{r_{ij}^2 + \epsilon}`.

    Conserves total linear momentum (translations in x and y) and angular momentum.
    Initial data: bodies on a perturbed circle with a rotation, seeded.
    """
    k = len(masses)
    system = _n_body_system(k, softening)
    rng = np.random.default_rng(seed)
    angles = 2 * np.pi * np.arange(k) / k + rng.uniform(-0.2, 0.2, k)
    radius = 1.0 + rng.uniform(-0.1, 0.1, k)
    pos = np.stack([radius * np.cos(angles), radius * np.sin(angles)], axis=1)
    vel = 0.5 * np.stack([-np.sin(angles), np.cos(angles)], axis=1) + rng.normal(0, 0.05, (k, 2))
    q = system.q
    xs, ys = q[0::2], q[1::2]
    zero, one = sp.Integer(0), sp.Integer(1)
    return Problem(
        name="n_body",
        system=system,
        q0=pos.ravel(),
        v0=vel.ravel(),
        t_final=2.0,
        params=dict(zip(system.params, masses, strict=True)),
        symmetries={
            "translation_x": tuple(one if i % 2 == 0 else zero for i in range(2 * k)),
            "translation_y": tuple(zero if i % 2 == 0 else one for i in range(2 * k)),
            ROTATION_XY: tuple(e for x, y in zip(xs, ys, strict=True) for e in (-y, x)),
        },
    )
