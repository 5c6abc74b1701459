"""Library of test problems with exact solutions or trusted references and invariants."""

from __future__ import annotations

from .base import Problem, ode_reference
from .chains import fermi_pasta_ulam, spring_chain
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
    "central_force",
    "double_pendulum",
    "fermi_pasta_ulam",
    "harmonic_oscillator",
    "henon_heiles",
    "kepler",
    "kepler_position",
    "n_body",
    "ode_reference",
    "outer_solar_system",
    "pendulum",
    "spherical_pendulum",
    "spring_chain",
]
