r"""Time-adaptive steps that stay symplectic: the Poincaré time transformation.

:class:`~.transform.PoincareTransform` builds the extended system (the maths is in
:mod:`galerkin_vi.adaptive.transform`); :class:`~.integrator.AdaptiveIntegrator` runs it
with fixed fictitious steps and reports in physical time
(:class:`~.trajectory.AdaptiveTrajectory`), every run option of
:meth:`galerkin_vi.Integrator.integrate` included (:mod:`.physical`).
"""

from .integrator import AdaptiveIntegrator, adaptive_block
from .trajectory import AdaptiveTrajectory
from .transform import CLOCK, CLOCK_RATE, ENERGY, PoincareTransform, encounter_scaling

__all__ = [
    "CLOCK",
    "CLOCK_RATE",
    "ENERGY",
    "AdaptiveIntegrator",
    "AdaptiveTrajectory",
    "PoincareTransform",
    "adaptive_block",
    "encounter_scaling",
]
