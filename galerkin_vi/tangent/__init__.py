"""The tangent map's applications: parameter fitting and estimation."""

from .estimate import ParameterEstimate, estimate_parameters
from .fit import ParameterFit, fit_parameters
from .observations import FitStatus

__all__ = [
    "FitStatus",
    "ParameterEstimate",
    "ParameterFit",
    "estimate_parameters",
    "fit_parameters",
]
