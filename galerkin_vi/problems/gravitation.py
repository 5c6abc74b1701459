"""Central forces, the Kepler problem and N bodies."""

from __future__ import annotations

import json
from functools import cache
from importlib import resources

import numpy as np
import sympy as sp

from ..model.system import LagrangianSystem
from .base import Problem

__all__ = ["central_force", "kepler", "kepler_position", "n_body", "outer_solar_system"]

ROTATION_XY = "rotation"
OUTER_SOLAR_SYSTEM_BODIES = ("Sun+inner", "Jupiter", "Saturn", "Uranus", "Neptune", "Pluto")


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


def _outer_solar_system_data() -> dict:
    """The JSON record of the outer solar system (a fresh copy on every call)."""
    source = resources.files(__package__).joinpath("data", "outer_solar_system.json")
    return json.loads(source.read_text(encoding="utf-8"))


@cache
def _outer_solar_system_system() -> LagrangianSystem:
    data = _outer_solar_system_data()
    k = len(data["masses"])
    masses = sp.symbols(f"m0:{k}", positive=True)
    G = sp.Symbol("G", positive=True)
    q = sp.symbols(" ".join(f"x{i} y{i} z{i}" for i in range(k)))
    v = sp.symbols(" ".join(f"vx{i} vy{i} vz{i}" for i in range(k)))
    terms = [masses[i] * sp.Add(*(w**2 for w in v[3 * i : 3 * i + 3])) / 2 for i in range(k)]
    for i in range(k):
        for j in range(i + 1, k):
            r2 = sp.Add(*((q[3 * i + c] - q[3 * j + c]) ** 2 for c in range(3)))
            terms.append(G * masses[i] * masses[j] / sp.sqrt(r2))
    params = dict(zip(masses, data["masses"], strict=True))
    params[G] = data["G"]
    return LagrangianSystem(sp.Add(*terms), list(q), list(v), params=params)


def outer_solar_system(t_final: float = 200_000.0) -> Problem:
    r"""The outer solar system: six bodies in 3D under Newtonian gravity.

    .. math::

        L = \sum_{i=0}^{5} \tfrac12 m_i |\dot q_i|^2
            + G \sum_{i<j} \frac{m_i m_j}{|q_i - q_j|},
        \qquad q = (x_0, y_0, z_0, x_1, \dots, z_5),

    for the bodies :data:`OUTER_SOLAR_SYSTEM_BODIES`: the Sun with the inner
    planets lumped into it, Jupiter, Saturn, Uranus, Neptune and Pluto. Units:
    astronomical units, days and solar masses. Masses (parameters ``m0`` ..
    ``m5``), ``G`` and the initial positions and velocities are those of [1]_
    (Table I.2.1), read from the package file ``data/outer_solar_system.json``.

    Parameters
    ----------
    t_final : float
        Default span in days, 200 000 as in the experiments of [1]_.

    Notes
    -----
    Symmetries: translations along each axis (keys ``"translation_x"``,
    ``"translation_y"``, ``"translation_z"``, conserved total linear momentum)
    and rotations about each axis (``"rotation_x"``, ``"rotation_y"``,
    ``"rotation_z"``, conserved angular momentum), with generators
    :math:`e_c` and :math:`e_c \times q_i` for every body.

    No exact solution: the reference is :func:`ode_reference`. Over the
    default span it is expensive: about 35 000 right-hand-side calls (each a
    Hessian evaluation and an 18-by-18 solve), about 14 s; short spans
    (a few thousand days) take well under a second.

    References
    ----------
    .. [1] E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*,
       2nd ed., Springer 2006, Section I.2.4.
    """
    data = _outer_solar_system_data()
    system = _outer_solar_system_system()
    q = system.q
    k = len(data["masses"])
    zero, one = sp.Integer(0), sp.Integer(1)
    symmetries: dict[str, tuple[sp.Expr, ...]] = {}
    for c, axis in enumerate("xyz"):
        symmetries[f"translation_{axis}"] = tuple(
            one if a == c else zero for _ in range(k) for a in range(3)
        )
    for c, axis in enumerate("xyz"):
        # e_c x (x, y, z): rotation about axis c
        a, b = (c + 1) % 3, (c + 2) % 3
        generator = []
        for i in range(k):
            component = [zero, zero, zero]
            component[a] = -q[3 * i + b]
            component[b] = q[3 * i + a]
            generator += component
        symmetries[f"rotation_{axis}"] = tuple(generator)
    return Problem(
        name="outer_solar_system",
        system=system,
        q0=np.array(data["positions"], dtype=float).ravel(),
        v0=np.array(data["velocities"], dtype=float).ravel(),
        t_final=t_final,
        params=dict(zip(system.params, [*data["masses"], data["G"]], strict=True)),
        symmetries=symmetries,
    )
