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
from .estimate import ParameterEstimate, estimate_parameters
from .fit import ParameterFit, fit_parameters
from .floquet import StabilityChange
from .observations import FitStatus

__all__ = [
    "ChaosMap",
    "FitStatus",
    "Gradient",
    "Loss",
    "LyapunovSpectrum",
    "Megno",
    "ParameterEstimate",
    "ParameterFit",
    "StabilityChange",
    "estimate_parameters",
    "fit_parameters",
    "gradient",
    "lyapunov_map",
    "lyapunov_spectrum",
    "megno",
    "megno_map",
]
