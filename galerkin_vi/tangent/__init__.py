"""What the tangent map gives: gradients by the discrete adjoint, chaos indicators,
parameter fitting (:mod:`galerkin_vi.run.tangent` carries the tangent map through runs)."""

from .adjoint import Gradient, Loss, gradient

__all__ = ["Gradient", "Loss", "gradient"]
