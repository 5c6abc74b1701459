"""galerkin_vi: arbitrary-order Galerkin variational integrators from SymPy Lagrangians.

Importing the package imports nothing else: each public name is imported from
its module at first use (PEP 562), so ``import galerkin_vi`` costs no SymPy,
SciPy or numba start-up until a name that needs them is used.
"""

from __future__ import annotations

import importlib
import importlib.util
from typing import TYPE_CHECKING

__version__ = "0.1.0"

#: each public name and the submodule it lives in
_SOURCES: dict[str, str] = {
    "BodyContact": "multibody",
    "BodyForce": "multibody",
    "BodyMotion": "multibody",
    "BodyPlane": "multibody",
    "BodyPoint": "multibody",
    "Box": "multibody",
    "Multibody": "multibody",
    "Plane": "multibody",
    "RigidBody": "multibody",
    "Sphere": "multibody",
    "joints": "multibody",
    "standing_contacts": "multibody",
    "ActionStatus": "action",
    "AdaptiveIntegrator": "adaptive",
    "AdaptiveTrajectory": "adaptive",
    "BoundaryValueResult": "action",
    "ChaosMap": "tangent",
    "Composition": "method.composition",
    "ConditioningWarning": "errors",
    "Contact": "model.contacts",
    "ConvergenceError": "errors",
    "DegenerateLagrangianError": "errors",
    "Event": "run.events",
    "FitStatus": "tangent",
    "Galerkin": "method.galerkin",
    "Gradient": "tangent",
    "InstabilityWarning": "errors",
    "Integrator": "integrator",
    "LagrangianSystem": "model.system",
    "Loss": "tangent",
    "LyapunovSpectrum": "tangent",
    "Megno": "tangent",
    "MethodChoice": "tools.choice",
    "OptimalControl": "action",
    "OrbitFamily": "action",
    "OrderReductionWarning": "errors",
    "OrderResult": "tools.verification",
    "ParameterEstimate": "tangent",
    "ParameterFit": "tangent",
    "PeriodicOrbit": "action",
    "PoincareTransform": "adaptive",
    "QuadratureRule": "method.quadrature",
    "RunFailureWarning": "errors",
    "RunStatus": "run.status",
    "SolverResult": "run.status",
    "SolverStatus": "run.status",
    "StabilityChange": "tangent",
    "Trajectory": "run.trajectory",
    "choose_method": "tools.choice",
    "encounter_scaling": "adaptive",
    "estimate_parameters": "tangent",
    "fit_parameters": "tangent",
    "follow_family": "action",
    "gauss_legendre": "method.quadrature",
    "gauss_lobatto": "method.quadrature",
    "gradient": "tangent",
    "lyapunov_map": "tangent",
    "lyapunov_spectrum": "tangent",
    "measure_order": "tools.verification",
    "megno": "tangent",
    "megno_map": "tangent",
    "solve_bvp": "action",
    "solve_optimal_control": "action",
    "solve_periodic": "action",
}

__all__ = list(_SOURCES)


def __getattr__(name: str):
    module = _SOURCES.get(name)
    if module is None:
        # a subpackage or module, e.g. ``galerkin_vi.problems``
        if name.startswith("_") or importlib.util.find_spec(f"{__name__}.{name}") is None:
            raise AttributeError(f"module 'galerkin_vi' has no attribute {name!r}")
        return importlib.import_module(f".{name}", __name__)
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_SOURCES})


if TYPE_CHECKING:  # the names for type checkers and editors
    from .action import (
        ActionStatus,
        BoundaryValueResult,
        OptimalControl,
        OrbitFamily,
        PeriodicOrbit,
        follow_family,
        solve_bvp,
        solve_optimal_control,
        solve_periodic,
    )
    from .adaptive import (
        AdaptiveIntegrator,
        AdaptiveTrajectory,
        PoincareTransform,
        encounter_scaling,
    )
    from .errors import (
        ConditioningWarning,
        ConvergenceError,
        DegenerateLagrangianError,
        InstabilityWarning,
        OrderReductionWarning,
        RunFailureWarning,
    )
    from .integrator import Integrator
    from .method.composition import Composition
    from .method.galerkin import Galerkin
    from .method.quadrature import QuadratureRule, gauss_legendre, gauss_lobatto
    from .model.contacts import Contact
    from .model.system import LagrangianSystem
    from .multibody import (
        BodyContact,
        BodyForce,
        BodyMotion,
        BodyPlane,
        BodyPoint,
        Box,
        Multibody,
        Plane,
        RigidBody,
        Sphere,
        joints,
        standing_contacts,
    )
    from .run.events import Event
    from .run.status import RunStatus, SolverResult, SolverStatus
    from .run.trajectory import Trajectory
    from .tangent import (
        ChaosMap,
        FitStatus,
        Gradient,
        Loss,
        LyapunovSpectrum,
        Megno,
        ParameterEstimate,
        ParameterFit,
        StabilityChange,
        estimate_parameters,
        fit_parameters,
        gradient,
        lyapunov_map,
        lyapunov_spectrum,
        megno,
        megno_map,
    )
    from .tools.choice import MethodChoice, choose_method
    from .tools.verification import OrderResult, measure_order
