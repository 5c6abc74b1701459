r"""Models with holonomic constraints :math:`g(t, q) = 0` (theory.md §6).

Each model is written in redundant (mostly Cartesian) coordinates with
constraints, and, where possible, related to an unconstrained model in
minimal coordinates that serves as the reference:

- :func:`cartesian_pendulum`: planar pendulum, :math:`(x, y)` and the length
  constraint; exact solution by Jacobi elliptic functions
  (:func:`pendulum_angle`).
- :func:`constrained_spherical_pendulum`: a particle on a sphere in
  :math:`\mathbb R^3`; reference from the angle form
  (:func:`~galerkin_vi.problems.mechanics.spherical_pendulum`).
- :func:`rotating_hoop`: a bead on a hoop spinning about the vertical, a
  time-dependent constraint; reference from the reduced one-angle Lagrangian.
- :func:`four_bar_linkage`: a closed Grashof crank–rocker under gravity, one
  degree of freedom, in joint positions (three distance constraints) or link
  angles (two loop-closure constraints).

The constrained integrator needs the collocated method (``Galerkin(s)``, Lobatto
nodes and ``gauss_lobatto(s + 1)``); positions and momenta then converge with
order :math:`2s`, and the constraints and the hidden constraints
:math:`\mathcal G v + g_t = 0` hold to round-off at every step.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..model.system import LagrangianSystem
from .base import Problem, ode_interpolant, ode_reference
from .mechanics import ROTATION_Z, spherical_pendulum

__all__ = [
    "cartesian_pendulum",
    "constrained_spherical_pendulum",
    "four_bar_linkage",
    "four_bar_positions",
    "pendulum_angle",
    "rotating_hoop",
]


# ------------------------------------------------------------------ pendulum
def pendulum_angle(
    t: float | ArrayLike, theta0: float, omega0: float = 0.0, frequency: float = 1.0
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r"""Exact solution of :math:`\ddot\theta = -\omega^2\sin\theta` by Jacobi elliptic functions.

    With :math:`k^2 = \sin^2(\theta_0/2) + \dot\theta_0^2/(4\omega^2)` (the energy),

    - libration (:math:`k < 1`): :math:`\sin(\theta/2) = k\,\mathrm{sn}(\omega t + u_0 \mid k^2)`,
      :math:`\dot\theta = 2k\omega\,\mathrm{cn}(\omega t + u_0 \mid k^2)`, with
      :math:`u_0 = F(\varphi_0 \mid k^2)`, :math:`\sin\varphi_0 = \sin(\theta_0/2)/k`,
      :math:`\cos\varphi_0 = \dot\theta_0/(2k\omega)`;
    - rotation (:math:`k > 1`): :math:`\theta/2 = \sigma\,\mathrm{am}(k\omega t + u_0 \mid k^{-2})`,
      :math:`\dot\theta = 2\sigma k\omega\,\mathrm{dn}(\cdot)`, :math:`\sigma = \mathrm{sign}\,
      \dot\theta_0`, :math:`u_0 = F(\sigma\theta_0/2 \mid k^{-2})`.

    Parameters
    ----------
    t : float or array_like
        Times.
    theta0, omega0 : float
        Initial angle (from the stable equilibrium, :math:`|\theta_0| < \pi` for
        libration) and angular velocity.
    frequency : float
        :math:`\omega = \sqrt{g/\ell}`, positive.

    Returns
    -------
    theta, theta_dot : ndarray
        Shaped like ``t``. SciPy's ``ellipj`` is accurate to about ``1e-15``
        per unit of :math:`|\omega t|` in the argument's rounding (about
        ``1e-14`` at :math:`\omega t = 50`).

    Raises
    ------
    ValueError
        On the separatrix :math:`k = 1` (within ``1e-12``), where the motion is
        not periodic, or for a non-positive ``frequency``.
    """
    from scipy.special import ellipj, ellipkinc  # here: SciPy adds 35 MB to every process

    if not frequency > 0:
        raise ValueError(f"frequency must be positive, got {frequency}")
    t = np.asarray(t, dtype=float)
    w = float(frequency)
    k2 = np.sin(theta0 / 2) ** 2 + omega0**2 / (4 * w**2)
    if abs(k2 - 1.0) <= 1e-12:
        raise ValueError("pendulum_angle: the data lie on the separatrix (k = 1)")
    if k2 == 0.0:
        return np.zeros_like(t), np.zeros_like(t)
    k = np.sqrt(k2)
    if k < 1:
        phi0 = np.arctan2(np.sin(theta0 / 2) / k, omega0 / (2 * k * w))
        u0 = ellipkinc(phi0, k2)
        sn, cn, _, _ = ellipj(w * t + u0, k2)
        return 2 * np.arcsin(k * sn), 2 * k * w * cn
    sigma = 1.0 if omega0 > 0 else -1.0
    # theta0 may lie beyond (-pi, pi) for a rotating pendulum: F is odd and F(x + pi) = F(x) + 2K
    u0 = ellipkinc(sigma * theta0 / 2, 1 / k2)
    _, _, dn, am = ellipj(k * w * t + u0, 1 / k2)
    return 2 * sigma * am, 2 * sigma * k * w * dn


@cache
def _cartesian_pendulum_system(damped: bool) -> LagrangianSystem:
    x, y, vx, vy = sp.symbols("x y vx vy")
    g, length = sp.symbols("g l", positive=True)
    params = {g: 1.0, length: 1.0}
    forces = None
    if damped:
        c = sp.Symbol("c")
        params[c] = 0.1
        forces = [-c * vx, -c * vy]
    return LagrangianSystem(
        (vx**2 + vy**2) / 2 - g * y,
        [x, y],
        [vx, vy],
        params=params,
        constraints=[(x**2 + y**2 - length**2) / 2],
        forces=forces,
    )


def cartesian_pendulum(
    theta0: float = 1.0,
    omega0: float = 0.0,
    length: float = 1.0,
    g: float = 1.0,
    t_final: float = 5.0,
    damping: float = 0.0,
) -> Problem:
    r"""Planar pendulum of unit mass in Cartesian coordinates with a length constraint.

    .. math::

        L = \tfrac12(\dot x^2 + \dot y^2) - g\,y, \qquad
        g_1(x, y) = \tfrac12(x^2 + y^2 - \ell^2) = 0,

    the pivot at the origin and :math:`y` pointing up. The angle :math:`\theta`
    from the downward vertical, :math:`(x, y) = \ell(\sin\theta, -\cos\theta)`,
    obeys :math:`\ddot\theta = -(g/\ell)\sin\theta`: the library's ``pendulum``
    problem for :math:`g = \ell = 1`. Parameters ``g``, ``l`` (and ``c`` with
    damping).

    Parameters
    ----------
    theta0, omega0 : float
        Initial angle and angular velocity; the initial data are
        :math:`q_0 = \ell(\sin\theta_0, -\cos\theta_0)`,
        :math:`v_0 = \ell\dot\theta_0(\cos\theta_0, \sin\theta_0)` (consistent).
    length, g : float
        Pendulum length and gravitational acceleration, positive.
    t_final : float
        Default length of the time span.
    damping : float
        Linear damping :math:`f = -c\,v` (a separate system with forces when
        nonzero: a force normal to the circle is taken up by the constraint, so
        the angle obeys :math:`\ddot\theta = -(g/\ell)\sin\theta - c\dot\theta`).

    Notes
    -----
    Without damping, ``exact`` is the Cartesian image of the exact pendulum
    solution, :func:`pendulum_angle`, librating or rotating (not on the
    separatrix, where ``exact`` is None). With damping there is no exact
    solution (``exact`` is None) and the energy decreases.
    """
    if not (length > 0 and g > 0):
        raise ValueError(f"length and g must be positive, got length={length}, g={g}")
    if damping < 0:
        raise ValueError(f"damping must be non-negative, got {damping}")
    damped = damping != 0.0
    system = _cartesian_pendulum_system(damped)
    values = [g, length] + ([damping] if damped else [])
    frequency = float(np.sqrt(g / length))
    k2 = np.sin(theta0 / 2) ** 2 + omega0**2 / (4 * frequency**2)
    exact: Callable | None = None
    if not damped and abs(k2 - 1.0) > 1e-12:

        def exact(t: float | ArrayLike) -> NDArray[np.float64]:
            theta, _ = pendulum_angle(t, theta0, omega0, frequency)
            return length * np.stack([np.sin(theta), -np.cos(theta)], axis=-1)

    return Problem(
        name="cartesian_pendulum" + ("_damped" if damped else ""),
        system=system,
        q0=length * np.array([np.sin(theta0), -np.cos(theta0)]),
        v0=length * omega0 * np.array([np.cos(theta0), np.sin(theta0)]),
        t_final=t_final,
        params=dict(zip(system.params, values, strict=True)),
        exact=exact,
    )


# --------------------------------------------------------- spherical pendulum
@cache
def _constrained_spherical_system() -> LagrangianSystem:
    x, y, z, vx, vy, vz = sp.symbols("x y z vx vy vz")
    g, length = sp.symbols("g l", positive=True)
    return LagrangianSystem(
        (vx**2 + vy**2 + vz**2) / 2 - g * z,
        [x, y, z],
        [vx, vy, vz],
        params={g: 1.0, length: 1.0},
        constraints=[(x**2 + y**2 + z**2 - length**2) / 2],
    )


def _sphere_point(length: float, theta, phi) -> NDArray[np.float64]:
    st = np.sin(theta)
    return length * np.stack([st * np.cos(phi), st * np.sin(phi), -np.cos(theta)], axis=-1)


def _lazy_reference(
    system: LagrangianSystem, q0: NDArray, v0: NDArray, t_final: float, params
) -> Callable[[NDArray], NDArray]:
    """``t -> q(t)`` of an unconstrained system by DOP853, solved on first use.

    Dense output over ``[0, t_final]``; times beyond it get a new solve.
    """
    interpolant: list[Callable] = []

    def reference(t: float | ArrayLike) -> NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        if t.size and float(t.max()) > t_final:
            return ode_reference(system, q0, v0, t, params)
        if not interpolant:
            interpolant.append(ode_interpolant(system, q0, v0, t_final, params))
        return interpolant[0](t)

    return reference


def constrained_spherical_pendulum(
    g: float = 1.0,
    length: float = 1.0,
    angles: tuple[float, float] = (1.0, 0.0),
    angle_rates: tuple[float, float] = (0.0, 1.0),
    t_final: float = 5.0,
) -> Problem:
    r"""Spherical pendulum as a particle in :math:`\mathbb R^3` constrained to a sphere.

    .. math::

        L = \tfrac12|\dot{\mathbf x}|^2 - g\,z, \qquad
        g_1(\mathbf x) = \tfrac12(x^2 + y^2 + z^2 - \ell^2) = 0 .

    The rotations about the vertical act linearly,
    :math:`\xi_Q = (-y, x, 0)` (key ``"rotation_z"``), so the discrete
    Noether theorem conserves :math:`J_z = x p_y - y p_x` to round-off (the
    constraint is invariant: it adds nothing, theory.md §4). Parameters ``g``, ``l``.

    Parameters
    ----------
    g, length : float
        Gravitational acceleration and radius, positive.
    angles, angle_rates : tuple of float
        Initial :math:`(\theta, \varphi)` and :math:`(\dot\theta, \dot\varphi)` of the
        angle form :func:`~galerkin_vi.problems.mechanics.spherical_pendulum`
        (:math:`\theta` from the downward vertical); mapped to
        :math:`\mathbf x = \ell(\sin\theta\cos\varphi, \sin\theta\sin\varphi, -\cos\theta)`
        and its velocity (consistent data).
    t_final : float
        Default length of the time span.

    Notes
    -----
    ``exact`` is the angle form's DOP853 solution (:func:`ode_interpolant`,
    ``rtol = 1e-13``, about ``1e-12`` accurate) mapped to Cartesian
    coordinates, computed on first use; the angles must stay away from the
    poles (the default data keep :math:`\theta \in [0.74, 1]`).
    """
    if not (length > 0 and g > 0):
        raise ValueError(f"length and g must be positive, got length={length}, g={g}")
    system = _constrained_spherical_system()
    x, y, _ = system.q
    theta, phi = (float(a) for a in angles)
    dtheta, dphi = (float(a) for a in angle_rates)
    q0 = _sphere_point(length, theta, phi)
    v0 = length * np.array(
        [
            np.cos(theta) * np.cos(phi) * dtheta - np.sin(theta) * np.sin(phi) * dphi,
            np.cos(theta) * np.sin(phi) * dtheta + np.sin(theta) * np.cos(phi) * dphi,
            np.sin(theta) * dtheta,
        ]
    )
    angle_form = spherical_pendulum(g, length, (theta, phi), (dtheta, dphi), t_final)
    angle_reference = _lazy_reference(
        angle_form.system, angle_form.q0, angle_form.v0, t_final, angle_form.params
    )

    def exact(t: float | ArrayLike) -> NDArray[np.float64]:
        q = angle_reference(t)
        return _sphere_point(length, q[..., 0], q[..., 1])

    return Problem(
        name="constrained_spherical_pendulum",
        system=system,
        q0=q0,
        v0=v0,
        t_final=t_final,
        params=dict(zip(system.params, (g, length), strict=True)),
        exact=exact,
        symmetries={ROTATION_Z: (-y, x, sp.Integer(0))},
    )


# ------------------------------------------------------------ rotating hoop
@cache
def _rotating_hoop_system() -> LagrangianSystem:
    x, y, z, vx, vy, vz, t = sp.symbols("x y z vx vy vz t")
    g, radius, spin = sp.symbols("g R Omega")
    return LagrangianSystem(
        (vx**2 + vy**2 + vz**2) / 2 - g * z,
        [x, y, z],
        [vx, vy, vz],
        t=t,
        params={g: 1.0, radius: 1.0, spin: 1.5},
        constraints=[
            (x**2 + y**2 + z**2 - radius**2) / 2,
            x * sp.sin(spin * t) - y * sp.cos(spin * t),
        ],
    )


@cache
def _hoop_angle_system() -> LagrangianSystem:
    psi, vpsi = sp.symbols("psi vpsi")
    g, radius, spin = sp.symbols("g R Omega")
    return LagrangianSystem(
        radius**2 * (vpsi**2 + spin**2 * sp.sin(psi) ** 2) / 2 + g * radius * sp.cos(psi),
        [psi],
        [vpsi],
        params={g: 1.0, radius: 1.0, spin: 1.5},
    )


def rotating_hoop(
    psi0: float = 0.5,
    psi_rate0: float = 0.0,
    spin: float = 1.5,
    radius: float = 1.0,
    g: float = 1.0,
    t_final: float = 5.0,
) -> Problem:
    r"""Bead on a circular hoop spinning about the vertical axis: a time-dependent constraint.

    .. math::

        L = \tfrac12|\dot{\mathbf x}|^2 - g\,z, \qquad
        g_1 = \tfrac12(|\mathbf x|^2 - R^2) = 0, \qquad
        g_2(t, \mathbf x) = x\sin\Omega t - y\cos\Omega t = 0,

    the hoop (radius :math:`R`, centre at the origin) lying in the vertical
    plane at angle :math:`\Omega t`. With :math:`\psi` the angle from the
    bottom, :math:`\mathbf x = R(\sin\psi\cos\Omega t, \sin\psi\sin\Omega t, -\cos\psi)`
    and the reduced Lagrangian
    :math:`\tfrac12R^2(\dot\psi^2 + \Omega^2\sin^2\psi) + gR\cos\psi` is
    autonomous: the Jacobi integral :math:`E - \Omega J_z` (with
    :math:`E = \tfrac12|v|^2 + gz`, :math:`J_z = xv_y - yv_x`) is conserved, the
    energy :math:`E` is not (the hoop does work). For :math:`\Omega^2 > g/R` the
    bottom is unstable and the bead oscillates about
    :math:`\cos\psi^* = g/(R\Omega^2)`. Parameters ``g``, ``R``, ``Omega``.

    Parameters
    ----------
    psi0, psi_rate0 : float
        Initial angle on the hoop and its rate (at :math:`t = 0` the hoop lies
        in the :math:`xz`-plane).
    spin, radius, g : float
        :math:`\Omega`, :math:`R` (positive) and :math:`g`.
    t_final : float
        Default length of the time span.

    Notes
    -----
    ``exact`` is the reduced one-angle model solved by DOP853
    (:func:`ode_interpolant`, about ``1e-12`` accurate) and mapped to
    Cartesian coordinates, computed on first use.
    """
    if not radius > 0:
        raise ValueError(f"radius must be positive, got {radius}")
    system = _rotating_hoop_system()
    values = (g, radius, spin)
    psi0, psi_rate0 = float(psi0), float(psi_rate0)
    q0 = radius * np.array([np.sin(psi0), 0.0, -np.cos(psi0)])
    v0 = radius * np.array(
        [np.cos(psi0) * psi_rate0, np.sin(psi0) * spin, np.sin(psi0) * psi_rate0]
    )
    reduced = _hoop_angle_system()
    reduced_params = dict(zip(reduced.params, values, strict=True))
    angle_reference = _lazy_reference(
        reduced, np.array([psi0]), np.array([psi_rate0]), t_final, reduced_params
    )

    def exact(t: float | ArrayLike) -> NDArray[np.float64]:
        t = np.asarray(t, dtype=float)
        psi = angle_reference(t)[..., 0]
        r = radius * np.sin(psi)
        return np.stack(
            [r * np.cos(spin * t), r * np.sin(spin * t), -radius * np.cos(psi)], axis=-1
        )

    return Problem(
        name="rotating_hoop",
        system=system,
        q0=q0,
        v0=v0,
        t_final=t_final,
        params=dict(zip(system.params, values, strict=True)),
        exact=exact,
    )


# ---------------------------------------------------------- four-bar linkage
_FOUR_BAR_DEFAULTS = {
    "l0": 1.0,
    "l1": 0.3,
    "l2": 1.0,
    "l3": 0.9,
    "m1": 1.0,
    "m2": 1.0,
    "m3": 1.0,
    "g": 1.0,
}


def _four_bar_symbols() -> tuple[sp.Symbol, ...]:
    return tuple(sp.symbols("l0 l1 l2 l3 m1 m2 m3 g", positive=True))


@cache
def _four_bar_cartesian_system() -> LagrangianSystem:
    xb, yb, xc, yc, vxb, vyb, vxc, vyc = sp.symbols("xB yB xC yC vxB vyB vxC vyC")
    l0, l1, l2, l3, m1, m2, m3, g = _four_bar_symbols()
    vb2 = vxb**2 + vyb**2
    vc2 = vxc**2 + vyc**2
    kinetic = (
        m1 * vb2 / 6  # crank about A: (1/2)(m1 l1^2/3) w1^2
        + m2 * (vb2 + vxb * vxc + vyb * vyc + vc2) / 6  # uniform bar with ends B and C
        + m3 * vc2 / 6  # rocker about D
    )
    potential = g * (m1 * yb + m2 * (yb + yc) + m3 * yc) / 2
    return LagrangianSystem(
        kinetic - potential,
        [xb, yb, xc, yc],
        [vxb, vyb, vxc, vyc],
        params=dict(zip(_four_bar_symbols(), _FOUR_BAR_DEFAULTS.values(), strict=True)),
        constraints=[
            (xb**2 + yb**2 - l1**2) / 2,
            ((xc - xb) ** 2 + (yc - yb) ** 2 - l2**2) / 2,
            ((xc - l0) ** 2 + yc**2 - l3**2) / 2,
        ],
    )


@cache
def _four_bar_angle_system() -> LagrangianSystem:
    a1, a2, a3, w1, w2, w3 = sp.symbols("theta1 theta2 theta3 omega1 omega2 omega3")
    l0, l1, l2, l3, m1, m2, m3, g = _four_bar_symbols()
    kinetic = (
        m1 * l1**2 * w1**2 / 6
        # coupler: centre B + (l2/2) e2 moving, plus rotation about the centre
        + m2 * (l1**2 * w1**2 + l1 * l2 * sp.cos(a1 - a2) * w1 * w2 + l2**2 * w2**2 / 4) / 2
        + m2 * l2**2 * w2**2 / 24
        + m3 * l3**2 * w3**2 / 6
    )
    yb, yc = l1 * sp.sin(a1), l3 * sp.sin(a3)
    potential = g * (m1 * yb + m2 * (yb + yc) + m3 * yc) / 2
    return LagrangianSystem(
        kinetic - potential,
        [a1, a2, a3],
        [w1, w2, w3],
        params=dict(zip(_four_bar_symbols(), _FOUR_BAR_DEFAULTS.values(), strict=True)),
        constraints=[
            l1 * sp.cos(a1) + l2 * sp.cos(a2) - l3 * sp.cos(a3) - l0,
            l1 * sp.sin(a1) + l2 * sp.sin(a2) - l3 * sp.sin(a3),
        ],
    )


def _cross(a: NDArray, b: NDArray) -> float:
    return float(a[0] * b[1] - a[1] * b[0])


def four_bar_positions(
    crank_angle: float,
    crank_rate: float,
    l0: float,
    l1: float,
    l2: float,
    l3: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    r"""Joint positions :math:`(B, C)` and velocities of a four-bar from the crank's state.

    :math:`B = \ell_1(\cos\theta_1, \sin\theta_1)`; :math:`C` is the intersection
    of the circles of radius :math:`\ell_2` about :math:`B` and :math:`\ell_3`
    about :math:`D = (\ell_0, 0)` to the left of :math:`B \to D` (the upper
    assembly branch when :math:`B` is near the ground line); the velocity of
    :math:`C` solves :math:`(C-B)\cdot(\dot C - \dot B) = 0`,
    :math:`(C-D)\cdot\dot C = 0`.

    Returns
    -------
    q, v : ndarray, shape (4,)
        :math:`(x_B, y_B, x_C, y_C)` and their rates.

    Raises
    ------
    ValueError
        If the linkage cannot be assembled at this crank angle.
    """
    b = l1 * np.array([np.cos(crank_angle), np.sin(crank_angle)])
    vb = l1 * crank_rate * np.array([-np.sin(crank_angle), np.cos(crank_angle)])
    d = np.array([l0, 0.0])
    span = d - b
    dist = float(np.hypot(*span))
    along = (l2**2 - l3**2 + dist**2) / (2 * dist)
    height2 = l2**2 - along**2
    if not height2 > 0:
        raise ValueError(f"the four-bar cannot be assembled at crank angle {crank_angle}")
    unit = span / dist
    c = b + along * unit + np.sqrt(height2) * np.array([-unit[1], unit[0]])
    rows = np.array([c - b, c - d])
    vc = np.linalg.solve(rows, np.array([(c - b) @ vb, 0.0]))
    return np.concatenate([b, c]), np.concatenate([vb, vc])


def four_bar_linkage(
    crank_angle: float = 0.0,
    crank_rate: float = 2.0,
    lengths: tuple[float, float, float, float] = (1.0, 0.3, 1.0, 0.9),
    masses: tuple[float, float, float] = (1.0, 1.0, 1.0),
    g: float = 1.0,
    coordinates: str = "cartesian",
    t_final: float = 10.0,
) -> Problem:
    r"""Closed four-bar linkage (Grashof crank–rocker) of uniform bars under gravity.

    Ground pivots :math:`A = (0, 0)` and :math:`D = (\ell_0, 0)`; the crank
    :math:`AB` (length :math:`\ell_1`, mass :math:`m_1`), the coupler :math:`BC`
    (:math:`\ell_2, m_2`) and the rocker :math:`DC` (:math:`\ell_3, m_3`) are
    uniform bars; gravity :math:`g` points along :math:`-y`. One degree of freedom.

    ``coordinates="cartesian"``: the joints :math:`q = (x_B, y_B, x_C, y_C)`, a
    constant mass matrix and three distance constraints,

    .. math::

        L = \frac{m_1}{6}|\dot B|^2 + \frac{m_2}{6}(|\dot B|^2 + \dot B\cdot\dot C
            + |\dot C|^2) + \frac{m_3}{6}|\dot C|^2
            - \frac g2\big(m_1 y_B + m_2(y_B + y_C) + m_3 y_C\big),

        g_1 = \tfrac12(|B|^2 - \ell_1^2),\quad
        g_2 = \tfrac12(|C - B|^2 - \ell_2^2),\quad
        g_3 = \tfrac12(|C - D|^2 - \ell_3^2).

    ``coordinates="angles"``: the absolute link angles
    :math:`q = (\theta_1, \theta_2, \theta_3)` of :math:`AB`, :math:`BC` and
    :math:`DC`, a configuration-dependent mass matrix and two trigonometric
    loop-closure constraints,

    .. math::

        L = \frac{m_1\ell_1^2}{6}\dot\theta_1^2
            + \frac{m_2}{2}\Big(\ell_1^2\dot\theta_1^2
            + \ell_1\ell_2\cos(\theta_1-\theta_2)\dot\theta_1\dot\theta_2
            + \frac{\ell_2^2}{4}\dot\theta_2^2\Big) + \frac{m_2\ell_2^2}{24}\dot\theta_2^2
            + \frac{m_3\ell_3^2}{6}\dot\theta_3^2 - V,

        \ell_1\cos\theta_1 + \ell_2\cos\theta_2 - \ell_3\cos\theta_3 - \ell_0 = 0,\quad
        \ell_1\sin\theta_1 + \ell_2\sin\theta_2 - \ell_3\sin\theta_3 = 0,

    with the same potential :math:`V` (:math:`y_B = \ell_1\sin\theta_1`,
    :math:`y_C = \ell_3\sin\theta_3`). Both describe the same motion (the
    kinetic energies agree on the constraint manifold). In the angle form the
    crank angle :math:`\theta_1` grows without bound (:math:`L` and the constraints
    are :math:`2\pi`-periodic in every angle).

    Parameters ``l0, l1, l2, l3, m1, m2, m3, g``; the energy is
    ``problem.system.hamiltonian``.

    Parameters
    ----------
    crank_angle, crank_rate : float
        Initial crank angle :math:`\theta_1` and rate :math:`\dot\theta_1`;
        the coupler and rocker follow from :func:`four_bar_positions` (the
        branch with :math:`C` left of :math:`B \to D`), so the data are consistent.
    lengths : tuple of float
        :math:`(\ell_0, \ell_1, \ell_2, \ell_3)` = ground, crank, coupler, rocker.
        Must satisfy Grashof's condition with the crank shortest (a crank–rocker):
        :math:`\ell_1 + \ell_{\max} < ` the sum of the other two.
    masses : tuple of float
        :math:`(m_1, m_2, m_3)`, positive.
    g : float
        Gravitational acceleration.
    coordinates : {"cartesian", "angles"}
    t_final : float
        Default length of the time span.

    Raises
    ------
    ValueError
        For non-positive lengths or masses, a linkage that is not a Grashof
        crank–rocker, or unknown ``coordinates``.

    Notes
    -----
    The configuration space is a circle parametrised by the crank angle. The
    constraint Jacobian loses rank only when all bars are parallel (a change
    point, excluded by Grashof's strict inequality), and the coupler and
    rocker are never collinear (toggle): the transmission angle :math:`\mu`
    between them satisfies :math:`\cos\mu = (\ell_2^2 + \ell_3^2 - |BD|^2)/(2\ell_2\ell_3)`
    with :math:`\ell_0 - \ell_1 \le |BD| \le \ell_0 + \ell_1`; for the default
    lengths :math:`\mu \in [42.8°, 86.2°]`.

    With the defaults (:math:`\dot\theta_1 = 2` at :math:`\theta_1 = 0`, energy
    :math:`E_0 = 1.211`) the crank turns fully: the potential rises by at most
    0.310 above its value at :math:`\theta_1 = 0`, the crank rate stays in
    :math:`[0.65, 5.4]`, and one revolution takes :math:`T = 3.27`.

    No exact solution; ``exact`` is None.
    """
    l0, l1, l2, l3 = (float(x) for x in lengths)
    m1, m2, m3 = (float(x) for x in masses)
    if min(l0, l1, l2, l3) <= 0 or min(m1, m2, m3) <= 0:
        raise ValueError(f"lengths and masses must be positive, got {lengths}, {masses}")
    if not (l1 < min(l0, l2, l3) and l1 + max(l0, l2, l3) < l0 + l2 + l3 - max(l0, l2, l3)):
        raise ValueError(
            f"lengths {lengths} are not a Grashof crank-rocker: the crank l1 must be the "
            "shortest bar and l1 + longest < sum of the other two"
        )
    if coordinates not in ("cartesian", "angles"):
        raise ValueError(f"coordinates must be 'cartesian' or 'angles', got {coordinates!r}")
    q0, v0 = four_bar_positions(crank_angle, crank_rate, l0, l1, l2, l3)
    if coordinates == "cartesian":
        system = _four_bar_cartesian_system()
    else:
        system = _four_bar_angle_system()
        b, c, vb, vc = q0[:2], q0[2:], v0[:2], v0[2:]
        coupler, rocker = c - b, c - np.array([l0, 0.0])
        q0 = np.array(
            [
                crank_angle,
                np.arctan2(coupler[1], coupler[0]),
                np.arctan2(rocker[1], rocker[0]),
            ]
        )
        v0 = np.array(
            [
                crank_rate,
                _cross(coupler, vc - vb) / l2**2,
                _cross(rocker, vc) / l3**2,
            ]
        )
    return Problem(
        name=f"four_bar_linkage_{coordinates}",
        system=system,
        q0=q0,
        v0=v0,
        t_final=t_final,
        params=dict(zip(system.params, (l0, l1, l2, l3, m1, m2, m3, g), strict=True)),
    )
