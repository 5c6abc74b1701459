r"""Contact shapes on bodies: the gaps and slip velocities of :class:`~galerkin_vi.Contact`.

A sphere of radius :math:`r` centred at the body point :math:`c` (a point is a
sphere of radius 0) against the plane :math:`\{y : n\cdot y = d\}` (unit
:math:`n`, pointing to the free side):

.. math::

    \varphi = n\cdot(x + R c) - d - r,\qquad
    w_j = t_j\cdot\bigl(\dot x + \dot R c - r\,\omega_s\times n\bigr),\ j = 1, 2,

with :math:`t_1, t_2` completing :math:`n` to an orthonormal frame: the slip is the
velocity of the sphere's material point touching the plane. Two spheres:

.. math::

    \varphi = |c_a - c_b| - r_a - r_b,\qquad
    w_j = t_j\cdot\bigl(\dot c_a - r_a\,\omega_{s,a}\times\nu - \dot c_b
    - r_b\,\omega_{s,b}\times\nu\bigr)

with :math:`\nu = (c_a - c_b)/|c_a - c_b|` and :math:`t_1 = \nu\times e/|\nu\times e|`,
:math:`t_2 = \nu\times t_1` for the fixed axis :math:`e` (``reference_axis``): the
tangent frame is singular where :math:`\nu \parallel e`, which friction between two
spheres must avoid.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..model.contacts import Contact
from ..rotations import orthonormal_complement, symbolic_hat, symbolic_vector
from .body import RigidBody

__all__ = ["BodyContact", "BodyPoint", "Plane", "Sphere"]


@dataclass(frozen=True, eq=False)
class Sphere:
    """A sphere of ``radius`` centred at the body point ``center``."""

    body: RigidBody
    radius: float
    center: Sequence = (0, 0, 0)

    def __post_init__(self) -> None:
        if not isinstance(self.body, RigidBody):
            raise TypeError(f"{type(self).__name__}: body must be a RigidBody, got {self.body!r}")
        r = float(self.radius)
        if not np.isfinite(r) or r < 0:
            raise ValueError(f"{type(self).__name__}: radius must be >= 0, got {self.radius!r}")
        object.__setattr__(self, "radius", r)
        object.__setattr__(self, "center", symbolic_vector(self.center, "center"))

    def center_position(self) -> sp.Matrix:
        return self.body.point(self.center)

    def surface_velocity(self, normal: sp.Matrix) -> sp.Matrix:
        r"""Velocity of the material point at :math:`c - r\,n` (``normal`` pointing away)."""
        ws = self.body.angular_velocity_space
        return self.body.point_velocity(self.center) - self.radius * symbolic_hat(ws) * normal


class BodyPoint(Sphere):
    """A body-fixed point (a sphere of radius 0): ``BodyPoint(body, point)``."""

    def __init__(self, body: RigidBody, point: Sequence) -> None:
        super().__init__(body, 0.0, point)

    def __reduce__(self):
        return (type(self), (self.body, self.center))


@dataclass(frozen=True, eq=False)
class Plane:
    r"""The fixed plane :math:`n\cdot y = d` (``normal`` toward the free side, ``offset`` d)."""

    normal: Sequence = (0, 0, 1)
    offset: float = 0.0

    def __post_init__(self) -> None:
        n = np.asarray(self.normal, dtype=float).reshape(3)
        norm = np.linalg.norm(n)
        if not np.isfinite(norm) or norm == 0:
            raise ValueError(f"Plane: normal must be a nonzero 3-vector, got {self.normal!r}")
        object.__setattr__(self, "normal", tuple(n / norm))
        object.__setattr__(self, "offset", float(self.offset))

    def tangents(self) -> tuple[sp.Matrix, sp.Matrix]:
        t1, t2 = orthonormal_complement(self.normal)
        return sp.Matrix(t1), sp.Matrix(t2)


@dataclass(frozen=True, eq=False)
class BodyContact:
    r"""A unilateral contact of a body's sphere (or point) with a plane or another sphere.

    Parameters
    ----------
    shape : Sphere or BodyPoint
    other : Plane or Sphere
    restitution, friction : float
        As in :class:`~galerkin_vi.Contact` (Newton's e, Coulomb's :math:`\mu`).
    reference_axis : 3 floats
        The axis :math:`e` of the tangent frame between two spheres (module notes).
    """

    shape: Sphere
    other: Plane | Sphere
    restitution: float = 0.0
    friction: float = 0.0
    reference_axis: Sequence = (0, 0, 1)

    def __post_init__(self) -> None:
        if not isinstance(self.shape, Sphere):
            raise TypeError(f"BodyContact: shape must be a Sphere or BodyPoint, got {self.shape!r}")
        if not isinstance(self.other, (Plane, Sphere)):
            raise TypeError(f"BodyContact: other must be a Plane or a Sphere, got {self.other!r}")
        if isinstance(self.other, Sphere) and self.other.body is self.shape.body:
            raise ValueError("BodyContact: the two spheres are on the same body")

    def contact(self) -> Contact:
        """The :class:`~galerkin_vi.Contact` (gap, restitution, friction, slip)."""
        if isinstance(self.other, Plane):
            n = sp.Matrix(self.other.normal)
            gap = n.dot(self.shape.center_position()) - self.other.offset - self.shape.radius
            rel = self.shape.surface_velocity(n)
            tangents = self.other.tangents()
        else:
            ca, cb = self.shape.center_position(), self.other.center_position()
            d = ca - cb
            dist = sp.sqrt(d.dot(d))
            nu = d / dist
            gap = dist - self.shape.radius - self.other.radius
            rel = self.shape.surface_velocity(nu) - self.other.surface_velocity(-nu)
            e = symbolic_vector(self.reference_axis, "reference_axis")
            t1 = nu.cross(e)
            t1 = t1 / sp.sqrt(t1.dot(t1))
            tangents = (t1, nu.cross(t1))
        slip = tuple(t.dot(rel) for t in tangents) if self.friction > 0 else None
        return Contact(gap=gap, restitution=self.restitution, friction=self.friction, slip=slip)
