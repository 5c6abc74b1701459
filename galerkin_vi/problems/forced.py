"""Forced and time-dependent models: damping, driving, a vibrating pivot.

External forces enter by the discrete Lagrange–d'Alembert principle and
time-dependent Lagrangians are evaluated at the quadrature times (theory.md §7),
so these problems check the parts of the integrator that conservative,
autonomous models never touch: the force terms of the stage equations, their
Jacobians :math:`f_q, f_v`, and the time argument of the kernels.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import sympy as sp

from ..model.system import LagrangianSystem
from .base import Problem

__all__ = [
    "damped_oscillator",
    "driven_oscillator",
    "forced_pendulum",
    "kapitza_pendulum",
]


@cache
def _damped_oscillator_system() -> LagrangianSystem:
    x, v = sp.symbols("x v")
    c, omega = sp.symbols("c omega")
    return LagrangianSystem(
        v**2 / 2 - omega**2 * x**2 / 2,
        [x],
        [v],
        params={c: 0.2, omega: 1.0},
        forces=[-c * v],
    )


def damped_oscillator(
    c: float = 0.2,
    omega: float = 1.0,
    q0: float = 1.0,
    v0: float = 0.0,
    t_final: float = 10.0,
) -> Problem:
    r"""Linearly damped harmonic oscillator (exact solution).

    .. math::

        L = \tfrac12 v^2 - \tfrac12 \omega^2 x^2, \qquad f = -c\,v,
        \qquad \ddot x + c\,\dot x + \omega^2 x = 0 .

    Parameters ``c`` and ``omega``. In the underdamped case
    :math:`0 \le c < 2\omega`, with :math:`\gamma = c/2` and
    :math:`\omega_d = \sqrt{\omega^2 - \gamma^2}`,

    .. math::

        x(t) = e^{-\gamma t}\Big(x_0 \cos\omega_d t
               + \frac{v_0 + \gamma x_0}{\omega_d} \sin\omega_d t\Big).

    The energy :math:`E = \tfrac12 v^2 + \tfrac12\omega^2 x^2` is not conserved:
    :math:`E(t) - E(0) = \int_0^t f\,v\,dt = -c\int_0^t v^2\,dt`.

    Parameters
    ----------
    c : float
        Damping coefficient, :math:`0 \le c < 2\omega`.
    omega : float
        Undamped angular frequency, positive.
    q0, v0 : float
        Initial position and velocity.
    t_final : float
        Default length of the time span.

    Raises
    ------
    ValueError
        If ``omega`` is not positive or ``c`` is outside :math:`[0, 2\omega)`
        (critically or over-damped: the exact solution above does not apply).
    """
    if not omega > 0:
        raise ValueError(f"omega must be positive, got {omega}")
    if not 0 <= c < 2 * omega:
        raise ValueError(
            f"damped_oscillator needs 0 <= c < 2 omega (underdamped), got c={c}, omega={omega}"
        )
    system = _damped_oscillator_system()
    gamma = c / 2
    omega_d = float(np.sqrt(omega**2 - gamma**2))
    b = (v0 + gamma * q0) / omega_d

    def exact(t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        x = np.exp(-gamma * t) * (q0 * np.cos(omega_d * t) + b * np.sin(omega_d * t))
        return x[..., None]

    return Problem(
        name="damped_oscillator",
        system=system,
        q0=np.array([q0], dtype=float),
        v0=np.array([v0], dtype=float),
        t_final=t_final,
        params=dict(zip(system.params, (c, omega), strict=True)),
        exact=exact,
    )


@cache
def _driven_oscillator_system() -> LagrangianSystem:
    x, v, t = sp.symbols("x v t")
    omega, amplitude, frequency = sp.symbols("omega F Omega")
    return LagrangianSystem(
        v**2 / 2 - omega**2 * x**2 / 2 + amplitude * x * sp.cos(frequency * t),
        [x],
        [v],
        t=t,
        params={omega: 1.0, amplitude: 1.0, frequency: 2.0},
    )


def driven_oscillator(
    omega: float = 1.0,
    amplitude: float = 1.0,
    frequency: float = 2.0,
    q0: float = 1.0,
    v0: float = 0.0,
    t_final: float = 10.0,
) -> Problem:
    r"""Harmonic oscillator driven through a time-dependent Lagrangian (exact solution).

    .. math::

        L(t, x, v) = \tfrac12 v^2 - \tfrac12\omega^2 x^2 + F x \cos\Omega t,
        \qquad \ddot x + \omega^2 x = F \cos\Omega t,

    parameters ``omega``, ``F`` (the amplitude) and ``Omega`` (the driving
    frequency); the defaults give :math:`L = \tfrac12 v^2 - \tfrac12 x^2 + x\cos 2t`
    of theory.md §7. Away from resonance (:math:`\Omega \ne \omega`) the solution
    is the particular plus the homogeneous one,

    .. math::

        x(t) = \frac{F}{\omega^2 - \Omega^2}\cos\Omega t
               + \Big(x_0 - \frac{F}{\omega^2 - \Omega^2}\Big)\cos\omega t
               + \frac{v_0}{\omega}\sin\omega t .

    Parameters
    ----------
    omega : float
        Natural angular frequency, positive.
    amplitude : float
        Driving amplitude :math:`F`.
    frequency : float
        Driving angular frequency :math:`\Omega`.
    q0, v0 : float
        Initial position and velocity (at :math:`t = 0`).
    t_final : float
        Default length of the time span.

    Raises
    ------
    ValueError
        If ``omega`` is not positive, or at resonance
        (:math:`|\omega^2 - \Omega^2| \le 10^{-8}\omega^2`), where the solution
        grows secularly and the formula above breaks down.
    """
    if not omega > 0:
        raise ValueError(f"omega must be positive, got {omega}")
    detuning = omega**2 - frequency**2
    if abs(detuning) <= 1e-8 * omega**2:
        raise ValueError(
            f"driven_oscillator: frequency={frequency} is at resonance with omega={omega}"
        )
    system = _driven_oscillator_system()
    particular = amplitude / detuning

    def exact(t: float | np.ndarray) -> np.ndarray:
        t = np.asarray(t, dtype=float)
        x = (
            particular * np.cos(frequency * t)
            + (q0 - particular) * np.cos(omega * t)
            + v0 / omega * np.sin(omega * t)
        )
        return x[..., None]

    return Problem(
        name="driven_oscillator",
        system=system,
        q0=np.array([q0], dtype=float),
        v0=np.array([v0], dtype=float),
        t_final=t_final,
        params=dict(zip(system.params, (omega, amplitude, frequency), strict=True)),
        exact=exact,
    )


@cache
def _kapitza_system() -> LagrangianSystem:
    phi, vphi, t = sp.symbols("phi vphi t")
    g, length, a, frequency = sp.symbols("g l a Omega")
    pivot_velocity = sp.diff(a * sp.cos(frequency * t), t)
    lagrangian = (
        length**2 * vphi**2 / 2
        + length * pivot_velocity * sp.sin(phi) * vphi
        + g * length * sp.cos(phi)
    )
    return LagrangianSystem(
        lagrangian,
        [phi],
        [vphi],
        t=t,
        params={g: 1.0, length: 1.0, a: 0.1, frequency: 20.0},
    )


def kapitza_pendulum(
    g: float = 1.0,
    length: float = 1.0,
    amplitude: float = 0.1,
    frequency: float = 20.0,
    q0: float = np.pi - 0.1,
    v0: float = 0.0,
    t_final: float = 10.0,
) -> Problem:
    r"""Kapitza's pendulum: a pendulum whose pivot oscillates vertically.

    The pivot moves as :math:`y_p(t) = a\cos\Omega t`; the bob of unit mass on
    a rod of length :math:`\ell` is at
    :math:`(\ell\sin\varphi,\ y_p(t) - \ell\cos\varphi)`, so :math:`\varphi = 0`
    hangs down and :math:`\varphi = \pi` is the inverted position. Dropping the
    terms that depend on :math:`t` alone (they do not change the equations of
    motion),

    .. math::

        L(t, \varphi, \dot\varphi) = \tfrac12 \ell^2 \dot\varphi^2
            + \ell\,\dot y_p(t) \sin\varphi\,\dot\varphi + g\ell\cos\varphi,
        \qquad \dot y_p = -a\Omega\sin\Omega t,

    with Euler–Lagrange equation
    :math:`\ell\ddot\varphi = -(g + \ddot y_p(t))\sin\varphi`. Parameters
    ``g``, ``l``, ``a`` and ``Omega``. The Lagrangian is time dependent and has
    a mixed term :math:`\partial^2 L/\partial\varphi\,\partial\dot\varphi \ne 0`
    and :math:`\partial_t L_v \ne 0`.

    Parameters
    ----------
    g, length : float
        Gravity and rod length.
    amplitude, frequency : float
        Pivot amplitude :math:`a` and angular frequency :math:`\Omega`.
    q0, v0 : float
        Initial angle and angular velocity; by default 0.1 off the inverted
        position, at rest.
    t_final : float
        Default length of the time span.

    Notes
    -----
    Averaging over the fast vibration (:math:`a \ll \ell`,
    :math:`\Omega \gg \sqrt{g/\ell}`) gives the effective potential
    :math:`-g\ell\cos\varphi + \tfrac14 a^2\Omega^2\sin^2\varphi` per unit mass
    [1]_; the inverted position is stable when :math:`a^2\Omega^2 > 2g\ell`,
    where it oscillates slowly with
    :math:`\omega_{\rm eff}^2 = a^2\Omega^2/(2\ell^2) - g/\ell`. The defaults
    (:math:`a = 0.1, \Omega = 20`: :math:`a^2\Omega^2 = 4 = 2 \cdot 2g\ell`,
    :math:`\omega_{\rm eff} = 1`) keep the pendulum upright: over
    :math:`t \le 10`, :math:`|\varphi - \pi|` stays below about 0.1, while
    without vibration it falls. (:math:`\Omega = 10` would give
    :math:`a^2\Omega^2 = 1 < 2`: no stabilisation.)

    No exact solution: :meth:`Problem.reference` integrates the Euler–Lagrange
    equations (:func:`ode_reference`), which must resolve the fast period
    :math:`2\pi/\Omega`.

    References
    ----------
    .. [1] L. D. Landau, E. M. Lifshitz, *Mechanics*, 3rd ed., Pergamon 1976, §30.
    """
    system = _kapitza_system()
    return Problem(
        name="kapitza_pendulum",
        system=system,
        q0=np.array([q0], dtype=float),
        v0=np.array([v0], dtype=float),
        t_final=t_final,
        params=dict(zip(system.params, (g, length, amplitude, frequency), strict=True)),
    )


@cache
def _forced_pendulum_system() -> LagrangianSystem:
    # real symbols: d|v|/dv is then sign(v), not an expression in re(v) and im(v)
    phi, vphi = sp.symbols("phi vphi", real=True)
    t = sp.Symbol("t", real=True)
    damping, drag, amplitude, frequency = sp.symbols("b k A Omega", real=True)
    force = -damping * vphi - drag * vphi * sp.Abs(vphi) + amplitude * sp.cos(frequency * t)
    return LagrangianSystem(
        vphi**2 / 2 + sp.cos(phi),
        [phi],
        [vphi],
        t=t,
        params={damping: 0.1, drag: 0.2, amplitude: 0.5, frequency: 1.0},
        forces=[force],
    )


def forced_pendulum(
    damping: float = 0.1,
    drag: float = 0.2,
    amplitude: float = 0.5,
    frequency: float = 1.0,
    q0: float = 1.0,
    v0: float = 0.0,
    t_final: float = 10.0,
) -> Problem:
    r"""Pendulum with linear damping, quadratic drag and a periodic torque.

    .. math::

        L = \tfrac12 v^2 + \cos\varphi, \qquad
        f(t, \varphi, v) = -b\,v - k\,v|v| + A\cos\Omega t,

    parameters ``b`` (linear damping), ``k`` (quadratic drag), ``A`` and
    ``Omega`` (amplitude and angular frequency of the actuation). The Lagrangian
    is autonomous, the force is not: the system is non-autonomous, with a
    velocity-dependent, nonlinear force. The drag :math:`v|v|` is only once
    continuously differentiable at :math:`v = 0` (:math:`f_v = -b - 2k|v|`),
    which limits the order of convergence: with the default data, about 3 for
    :math:`s = 2` and :math:`s = 3` (measured for :math:`h = 0.2` to
    :math:`0.025` over :math:`t \le 10`). A test of the force terms and the
    backends, not of the order.

    Parameters
    ----------
    damping, drag : float
        Coefficients :math:`b` and :math:`k`.
    amplitude, frequency : float
        Actuation :math:`A\cos\Omega t`.
    q0, v0 : float
        Initial angle and angular velocity.
    t_final : float
        Default length of the time span.

    Notes
    -----
    No exact solution: the reference is :func:`ode_reference`. The energy
    :math:`E = \tfrac12 v^2 - \cos\varphi` satisfies
    :math:`E(t) - E(0) = \int_0^t f\,v\,dt`.
    """
    system = _forced_pendulum_system()
    return Problem(
        name="forced_pendulum",
        system=system,
        q0=np.array([q0], dtype=float),
        v0=np.array([v0], dtype=float),
        t_final=t_final,
        params=dict(zip(system.params, (damping, drag, amplitude, frequency), strict=True)),
    )
