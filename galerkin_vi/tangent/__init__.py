"""What the tangent map gives: gradients by the discrete adjoint, chaos indicators,
the stability of periodic orbits, parameter fitting (:mod:`galerkin_vi.run.tangent`
carries the tangent map through runs)."""

from .adjoint import Gradient, Loss, gradient
from .chaos import (
    ChaosMap,
    LyapunovSpectrum,
    Megno,
    lyapunov_map,
    lyapunov_spectrum,
    megno,
    megno_map,
)
from .floquet import StabilityChange

__all__ = [
    "ChaosMap",
    "Gradient",
    "Loss",
    "LyapunovSpectrum",
    "Megno",
    "StabilityChange",
    "gradient",
    "lyapunov_map",
    "lyapunov_spectrum",
    "megno",
    "megno_map",
]
