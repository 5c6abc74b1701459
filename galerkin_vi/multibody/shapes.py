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

with :math:`\nu = (c_a - c_b)/|c_a - c_b|` and the tangents :math:`t_j = Q(\nu)\,f_j`
carried from a fixed frame :math:`(f_1, f_2, e)` (``reference_axis`` :math:`e`) by the
least rotation taking :math:`e` to :math:`\nu`,

.. math::

    Q(\nu)\,x = c\,x + k\times x + \frac{(k\cdot x)\,k}{1 + c},\qquad
    k = e\times\nu,\ c = e\cdot\nu .

No tangent field on the sphere is smooth everywhere; this one is smooth and
orthonormal except at the single direction :math:`\nu = -e`, so a vertical pile
of spheres (:math:`\nu = \pm e`) has a regular frame when each pair is listed
upper sphere first (:math:`\nu = e` for the default :math:`e = (0, 0, 1)`).

A plane fixed in a moving body (:class:`BodyPlane`: the body-frame normal
:math:`n` through the body point :math:`p`), against a sphere of another body:

.. math::

    \varphi = (R_b n)\cdot(x_a + R_a c - x_b - R_b p) - r,\qquad
    w_j = (R_b f_j)\cdot\bigl(\dot x_a + \dot R_a c - r\,\omega_{s,a}\times R_b n
    - \dot x_b - \omega_{s,b}\times(y - x_b)\bigr),

with :math:`y = x_a + R_a c - r R_b n` the touching point and :math:`(f_1, f_2)`
completing :math:`n` in the body frame: the slip of the sphere's material point
over the plane's, in tangents that turn with the plane. The plane is unbounded:
it stands for a face of a box (:meth:`Box.face`) while the points touching it
project inside the face, as the corners of a box standing on another do.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..model.contacts import Contact
from ..rotations import orthonormal_complement, symbolic_hat, symbolic_vector
from .body import RigidBody

__all__ = [
    "BodyContact",
    "BodyPlane",
    "BodyPoint",
    "Box",
    "Plane",
    "Sphere",
    "standing_contacts",
]


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
class BodyPlane:
    r"""The plane of a moving body through the body point ``point``, body-frame ``normal``
    toward the free side (module notes); unbounded, as a face while the touching
    points project inside it."""

    body: RigidBody
    normal: Sequence = (0, 0, 1)
    point: Sequence = (0, 0, 0)

    def __post_init__(self) -> None:
        if not isinstance(self.body, RigidBody):
            raise TypeError(f"BodyPlane: body must be a RigidBody, got {self.body!r}")
        n = np.asarray(self.normal, dtype=float).reshape(3)
        norm = np.linalg.norm(n)
        if not np.isfinite(norm) or norm == 0:
            raise ValueError(f"BodyPlane: normal must be a nonzero 3-vector, got {self.normal!r}")
        object.__setattr__(self, "normal", tuple(n / norm))
        object.__setattr__(self, "point", symbolic_vector(self.point, "point"))

    def space_normal(self) -> sp.Matrix:
        return self.body.axis(self.normal)

    def tangents(self) -> tuple[sp.Matrix, sp.Matrix]:
        """The body-frame completion of the normal, turned with the body."""
        return tuple(self.body.axis(f) for f in orthonormal_complement(self.normal))

    def material_velocity(self, y: sp.Matrix) -> sp.Matrix:
        r"""The velocity :math:`\dot x + \omega_s\times(y - x)` of the body's point at ``y``."""
        b = self.body
        return b.velocity + symbolic_hat(b.angular_velocity_space) * (y - b.position)


_FACES = {"+x": (0, 1), "-x": (0, -1), "+y": (1, 1), "-y": (1, -1), "+z": (2, 1), "-z": (2, -1)}


@dataclass(frozen=True, eq=False)
class Box:
    r"""A box of half sides ``half_extents`` along the body axes, centred at the body
    point ``center``: its corners as :class:`BodyPoint` and its faces as :class:`BodyPlane`.

    Examples
    --------
    The four lower corners of ``top`` standing on the upper face of ``base``:

    >>> import galerkin_vi as gvi
    >>> base = gvi.Box(gvi.RigidBody("base", mass=1.0, inertia=[1, 1, 1]), [0.5, 0.5, 0.5])
    >>> top = gvi.Box(gvi.RigidBody("top", mass=1.0, inertia=[1, 1, 1]), [0.5, 0.5, 0.5])
    >>> contacts = [gvi.BodyContact(c, base.face("+z"), friction=0.5) for c in top.corners("-z")]
    >>> len(contacts)
    4
    """

    body: RigidBody
    half_extents: Sequence
    center: Sequence = (0, 0, 0)

    def __post_init__(self) -> None:
        if not isinstance(self.body, RigidBody):
            raise TypeError(f"Box: body must be a RigidBody, got {self.body!r}")
        a = np.asarray(self.half_extents, dtype=float)
        if a.shape != (3,) or not np.all(np.isfinite(a)) or not np.all(a > 0):
            raise ValueError(
                f"Box: half_extents must be 3 positive numbers, got {self.half_extents!r}"
            )
        object.__setattr__(self, "half_extents", tuple(a))
        object.__setattr__(self, "center", tuple(float(c) for c in np.reshape(self.center, 3)))

    def corners(self, face: str | None = None) -> list[BodyPoint]:
        """The eight corners, or the four of ``face`` (``"+x"``, ``"-x"``, ..., ``"-z"``)."""
        signs = [(sx, sy, sz) for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
        if face is not None:
            axis, side = _face(face)
            signs = [s for s in signs if s[axis] == side]
        offsets = [np.multiply(sg, self.half_extents) + self.center for sg in signs]
        return [BodyPoint(self.body, list(r)) for r in offsets]

    def face(self, face: str) -> BodyPlane:
        """The plane of ``face`` (``"+x"``, ..., ``"-z"``), normal pointing out of the box."""
        axis, side = _face(face)
        normal = [0.0, 0.0, 0.0]
        normal[axis] = float(side)
        point = list(self.center)
        point[axis] += side * self.half_extents[axis]
        return BodyPlane(self.body, normal, point)


def standing_contacts(
    box: Box,
    support: Box | Plane,
    friction: float = 0.0,
    restitution: float = 0.0,
    face: str = "-z",
    on: str = "+z",
) -> list[BodyContact]:
    """The contacts of ``box``'s corners of ``face`` with ``support``: a fixed plane, or
    the face ``on`` of another box (a stack; the faces' planes, right while the corners
    stay over the face).

    Examples
    --------
    >>> import galerkin_vi as gvi
    >>> cube = lambda name: gvi.Box(gvi.RigidBody(name, mass=1.0, inertia=[1, 1, 1]), [0.5] * 3)
    >>> lower, upper = cube("lower"), cube("upper")
    >>> floor = gvi.Plane([0, 0, 1], 0.0)
    >>> contacts = gvi.standing_contacts(lower, floor, friction=0.5)
    >>> contacts += gvi.standing_contacts(upper, lower, friction=0.5)
    >>> len(contacts)
    8
    """
    other = support.face(on) if isinstance(support, Box) else support
    return [
        BodyContact(c, other, restitution=restitution, friction=friction) for c in box.corners(face)
    ]


def _face(face: str) -> tuple[int, int]:
    if face not in _FACES:
        raise ValueError(f"Box: face must be one of {sorted(_FACES)}, got {face!r}")
    return _FACES[face]


def least_rotation_frame(nu: sp.Matrix, e: sp.Matrix) -> tuple[sp.Matrix, sp.Matrix]:
    r"""The tangents :math:`Q(\nu) f_1, Q(\nu) f_2` of the module notes (unit ``nu``, ``e``)."""
    k = e.cross(nu)
    c = e.dot(nu)
    f1, f2 = (sp.Matrix(f) for f in orthonormal_complement([float(x) for x in e]))
    return tuple(c * f + k.cross(f) + k.dot(f) * k / (1 + c) for f in (f1, f2))


@dataclass(frozen=True, eq=False)
class BodyContact:
    r"""A unilateral contact of a body's sphere (or point) with a plane, a body's plane or
    another sphere.

    Parameters
    ----------
    shape : Sphere or BodyPoint
    other : Plane, BodyPlane or Sphere
        A fixed plane, a plane of another body (a :meth:`Box.face`), or a sphere of
        another body.
    restitution, friction : float
        As in :class:`~galerkin_vi.Contact` (Newton's e, Coulomb's :math:`\mu`).
    reference_axis : 3 floats
        The axis :math:`e` of the tangent frame between two spheres (module notes):
        the frame is regular except where the centres' line points along :math:`-e`.
    """

    shape: Sphere
    other: Plane | BodyPlane | Sphere
    restitution: float = 0.0
    friction: float = 0.0
    reference_axis: Sequence = (0, 0, 1)

    def __post_init__(self) -> None:
        if not isinstance(self.shape, Sphere):
            raise TypeError(f"BodyContact: shape must be a Sphere or BodyPoint, got {self.shape!r}")
        if not isinstance(self.other, (Plane, BodyPlane, Sphere)):
            raise TypeError(
                f"BodyContact: other must be a Plane, a BodyPlane or a Sphere, got {self.other!r}"
            )
        if not isinstance(self.other, Plane) and self.other.body is self.shape.body:
            raise ValueError(
                f"BodyContact: the shape and {type(self.other).__name__} are on the same body "
                f"{self.shape.body.name!r}"
            )
        e = np.asarray(self.reference_axis, dtype=float).reshape(3)
        norm = np.linalg.norm(e)
        if not np.isfinite(norm) or norm == 0:
            raise ValueError(
                "BodyContact: reference_axis must be a nonzero 3-vector, "
                f"got {self.reference_axis!r}"
            )
        object.__setattr__(self, "reference_axis", tuple(e / norm))

    @property
    def bodies(self) -> tuple[RigidBody, ...]:
        """The bodies whose coordinates the gap depends on."""
        if isinstance(self.other, Plane):
            return (self.shape.body,)
        return (self.shape.body, self.other.body)

    def contact(self) -> Contact:
        """The :class:`~galerkin_vi.Contact` (gap, restitution, friction, slip)."""
        r = self.shape.radius
        if isinstance(self.other, Plane):
            n = sp.Matrix(self.other.normal)
            gap = n.dot(self.shape.center_position()) - self.other.offset - r
            rel = self.shape.surface_velocity(n)
            tangents = self.other.tangents()
        elif isinstance(self.other, BodyPlane):
            plane = self.other
            n = plane.space_normal()
            c = self.shape.center_position()
            gap = n.dot(c - plane.body.point(plane.point)) - r
            rel = self.shape.surface_velocity(n) - plane.material_velocity(c - r * n)
            tangents = plane.tangents()
        else:
            ca, cb = self.shape.center_position(), self.other.center_position()
            d = ca - cb
            dist = sp.sqrt(d.dot(d))
            nu = d / dist
            gap = dist - r - self.other.radius
            rel = self.shape.surface_velocity(nu) - self.other.surface_velocity(-nu)
            tangents = least_rotation_frame(nu, sp.Matrix(self.reference_axis))
        slip = tuple(t.dot(rel) for t in tangents) if self.friction > 0 else None
        return Contact(gap=gap, restitution=self.restitution, friction=self.friction, slip=slip)
