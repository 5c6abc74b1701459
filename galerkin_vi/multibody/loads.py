r"""Forces and torques on bodies, as generalised forces by partial velocities.

A force :math:`F` applied at the body point :math:`r` and a torque :math:`\tau`
(space vectors, expressions in :math:`t, q, v` and parameters) do the virtual
work :math:`F\cdot\delta x_P + \tau\cdot\delta\theta_s`; with the partial
velocities of the point and of the space angular velocity,

.. math::

    Q_i = F\cdot\frac{\partial \dot x_P}{\partial v_i}
        + \tau\cdot\frac{\partial \omega_s}{\partial v_i},

which enter the discrete Lagrange–d'Alembert principle as the system's ``forces``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import sympy as sp

from .body import RigidBody

__all__ = ["BodyForce", "generalised_forces"]


@dataclass(frozen=True, eq=False)
class BodyForce:
    r"""A force at a body point and a torque on a body, in space coordinates.

    Parameters
    ----------
    body : RigidBody
    force : 3 expressions, optional
        :math:`F(t, q, v)` in space coordinates (drag: ``-c * body.velocity``).
    point : 3 numbers, optional
        The body-fixed point where :math:`F` acts (default the centre of mass).
    torque : 3 expressions, optional
        :math:`\tau(t, q, v)` in space coordinates.
    """

    body: RigidBody
    force: Sequence | None = None
    point: Sequence = (0, 0, 0)
    torque: Sequence | None = None

    def __post_init__(self) -> None:
        if not isinstance(self.body, RigidBody):
            raise TypeError(f"BodyForce: body must be a RigidBody, got {self.body!r}")
        for name in ("force", "torque"):
            value = getattr(self, name)
            if value is not None:
                m = sp.Matrix(value)
                if m.shape not in ((3, 1), (1, 3)):
                    raise ValueError(f"BodyForce: {name} must be a 3-vector, got shape {m.shape}")
                object.__setattr__(self, name, m.reshape(3, 1))
        if self.force is None and self.torque is None:
            raise ValueError("BodyForce: give a force, a torque or both")

    def generalised(self, v: Sequence[sp.Symbol]) -> list[sp.Expr]:
        """The generalised forces :math:`Q_i` on every velocity ``v`` (module notes)."""
        out = [sp.S.Zero] * len(v)
        if self.force is not None:
            xd = self.body.point_velocity(self.point)
            out = [o + self.force.dot(xd.diff(vi)) for o, vi in zip(out, v, strict=True)]
        if self.torque is not None:
            ws = self.body.angular_velocity_space
            out = [o + self.torque.dot(ws.diff(vi)) for o, vi in zip(out, v, strict=True)]
        return out


def generalised_forces(loads: Sequence[BodyForce], v: Sequence[sp.Symbol]) -> list[sp.Expr] | None:
    """The sum of the loads' generalised forces, or None without loads."""
    if not loads:
        return None
    total = [sp.S.Zero] * len(v)
    for j, load in enumerate(loads):
        if not isinstance(load, BodyForce):
            raise TypeError(f"forces[{j}] must be a galerkin_vi.BodyForce, got {load!r}")
        total = [a + b for a, b in zip(total, load.generalised(v), strict=True)]
    return total
