"""Library of test problems with exact solutions or trusted references and invariants."""

from __future__ import annotations

from .base import Problem, ode_interpolant, ode_reference
from .chains import fermi_pasta_ulam, spring_chain
from .constrained import (
    cartesian_pendulum,
    constrained_spherical_pendulum,
    four_bar_linkage,
    four_bar_positions,
    pendulum_angle,
    rotating_hoop,
)
from .forced import damped_oscillator, driven_oscillator, forced_pendulum, kapitza_pendulum
from .gravitation import central_force, kepler, kepler_position, n_body, outer_solar_system
from .mechanics import (
    double_pendulum,
    harmonic_oscillator,
    henon_heiles,
    pendulum,
    spherical_pendulum,
)

__all__ = [
    "Problem",
    "cartesian_pendulum",
    "central_force",
    "constrained_spherical_pendulum",
    "damped_oscillator",
    "double_pendulum",
    "driven_oscillator",
    "fermi_pasta_ulam",
    "forced_pendulum",
    "four_bar_linkage",
    "four_bar_positions",
    "harmonic_oscillator",
    "henon_heiles",
    "kapitza_pendulum",
    "kepler",
    "kepler_position",
    "n_body",
    "ode_interpolant",
    "ode_reference",
    "outer_solar_system",
    "pendulum",
    "pendulum_angle",
    "rotating_hoop",
    "spherical_pendulum",
    "spring_chain",
]
