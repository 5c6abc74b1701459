r"""Time-adaptive steps that stay symplectic: the Poincaré time transformation.

:class:`~.transform.PoincareTransform` builds the extended system (the maths is in
:mod:`galerkin_vi.adaptive.transform`); :class:`~.integrator.AdaptiveIntegrator` runs it
with fixed fictitious steps and reports in physical time
(:class:`~.trajectory.AdaptiveTrajectory`), every run option of
:meth:`galerkin_vi.Integrator.integrate` included (:mod:`.physical`).
"""

from .integrator import AdaptiveIntegrator, adaptive_block
from .step_function import StepFunction, default_step_function
from .trajectory import AdaptiveTrajectory
from .transform import (
    CLOCK,
    CLOCK_RATE,
    CLOCK_WEIGHT,
    ENERGY,
    PoincareTransform,
    encounter_scaling,
)

__all__ = [
    "CLOCK",
    "CLOCK_RATE",
    "CLOCK_WEIGHT",
    "ENERGY",
    "AdaptiveIntegrator",
    "AdaptiveTrajectory",
    "PoincareTransform",
    "StepFunction",
    "adaptive_block",
    "default_step_function",
    "encounter_scaling",
]
