"""galerkin_vi: arbitrary-order Galerkin variational integrators from SymPy Lagrangians."""

from __future__ import annotations

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
from .adaptive import AdaptiveIntegrator, AdaptiveTrajectory, PoincareTransform, encounter_scaling
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
    BodyPoint,
    Multibody,
    Plane,
    RigidBody,
    Sphere,
    joints,
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

__all__ = [
    "BodyContact",
    "BodyForce",
    "BodyMotion",
    "BodyPoint",
    "Multibody",
    "Plane",
    "RigidBody",
    "Sphere",
    "joints",
    "ActionStatus",
    "AdaptiveIntegrator",
    "AdaptiveTrajectory",
    "BoundaryValueResult",
    "ChaosMap",
    "Composition",
    "ConditioningWarning",
    "Contact",
    "ConvergenceError",
    "DegenerateLagrangianError",
    "Event",
    "FitStatus",
    "Galerkin",
    "Gradient",
    "InstabilityWarning",
    "Integrator",
    "LagrangianSystem",
    "Loss",
    "LyapunovSpectrum",
    "Megno",
    "MethodChoice",
    "OptimalControl",
    "OrbitFamily",
    "OrderReductionWarning",
    "OrderResult",
    "ParameterEstimate",
    "ParameterFit",
    "PeriodicOrbit",
    "PoincareTransform",
    "QuadratureRule",
    "RunFailureWarning",
    "RunStatus",
    "SolverResult",
    "SolverStatus",
    "StabilityChange",
    "Trajectory",
    "choose_method",
    "encounter_scaling",
    "estimate_parameters",
    "fit_parameters",
    "follow_family",
    "gauss_legendre",
    "gauss_lobatto",
    "gradient",
    "lyapunov_map",
    "lyapunov_spectrum",
    "measure_order",
    "megno",
    "megno_map",
    "solve_bvp",
    "solve_optimal_control",
    "solve_periodic",
]

__version__ = "0.1.0"


def _prepare_compiled_backend() -> None:
    """Pay numba's one-time start-up here, at import, not at the first integration.

    Importing the loops (numba, their dispatchers, the cache locators) and numba's
    own initialisation of its CPU target (typing registries, with scipy.linalg)
    take about 0.4 s once per process; afterwards a cached system loads its loops
    and point functions in milliseconds. Without numba, the NumPy backend remains.
    """
    try:
        from numba.core.registry import cpu_target

        from . import loops  # noqa: F401
    except ImportError:
        return
    try:
        cpu_target.target_context.refresh()
    except Exception:  # noqa: BLE001 - numba's internals: an optimisation only
        pass


_prepare_compiled_backend()
