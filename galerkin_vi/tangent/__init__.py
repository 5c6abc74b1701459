"""What the tangent map gives: gradients by the discrete adjoint, chaos indicators,
parameter fitting (:mod:`galerkin_vi.run.tangent` carries the tangent map through runs)."""

from .adjoint import Gradient, Loss, gradient
from .estimate import ParameterEstimate, estimate_parameters
from .fit import ParameterFit, fit_parameters
from .observations import FitStatus

__all__ = [
    "FitStatus",
    "Gradient",
    "Loss",
    "ParameterEstimate",
    "ParameterFit",
    "estimate_parameters",
    "fit_parameters",
    "gradient",
]
