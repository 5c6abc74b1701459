"""galerkin_vi: arbitrary-order Galerkin variational integrators from SymPy Lagrangians."""

from __future__ import annotations

from .choice import MethodChoice, choose_method
from .errors import (
    ConditioningWarning,
    ConvergenceError,
    DegenerateLagrangianError,
    InstabilityWarning,
    OrderReductionWarning,
)
from .integrator import Integrator
from .method import Galerkin
from .quadrature import QuadratureRule, gauss_legendre, gauss_lobatto
from .system import LagrangianSystem
from .trajectory import Trajectory
from .verification import OrderResult, measure_order

__all__ = [
    "ConditioningWarning",
    "ConvergenceError",
    "DegenerateLagrangianError",
    "Galerkin",
    "InstabilityWarning",
    "Integrator",
    "LagrangianSystem",
    "MethodChoice",
    "OrderReductionWarning",
    "OrderResult",
    "QuadratureRule",
    "Trajectory",
    "choose_method",
    "gauss_legendre",
    "gauss_lobatto",
    "measure_order",
]

__version__ = "0.1.0"
