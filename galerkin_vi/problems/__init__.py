"""Library of test problems with exact solutions or trusted references and invariants."""

from __future__ import annotations

from .base import Problem, ode_reference
from .gravitation import central_force, kepler, kepler_position, n_body
from .mechanics import double_pendulum, harmonic_oscillator, pendulum

__all__ = [
    "Problem",
    "central_force",
    "double_pendulum",
    "harmonic_oscillator",
    "kepler",
    "kepler_position",
    "n_body",
    "ode_reference",
    "pendulum",
]
