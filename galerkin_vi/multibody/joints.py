r"""Joints: holonomic constraints between the frames of two bodies (or a body and the ground).

A joint connects a point :math:`p_a` fixed on body *a* with a point :math:`p_b`
fixed on body *b*; ``None`` for a body is the ground (space), whose points and
axes are given in space coordinates. With :math:`d = x_b + R_b p_b - x_a - R_a p_a`
the separation of the two points and :math:`n_a, n_b` body-fixed axes,

.. list-table::
   :header-rows: 1

   * - joint
     - constraints
     - removes
   * - ``Spherical``
     - :math:`d = 0`
     - 3
   * - ``Revolute``
     - :math:`d = 0`, :math:`(R_a u_a)\cdot(R_b n_b) = (R_a w_a)\cdot(R_b n_b) = 0`
     - 5
   * - ``Universal``
     - :math:`d = 0`, :math:`(R_a n_a)\cdot(R_b n_b) = 0`
     - 4
   * - ``Prismatic``
     - :math:`(R_a u_a)\cdot d = (R_a w_a)\cdot d = 0`, :math:`\rho = 0`
     - 5
   * - ``Fixed``
     - :math:`d = 0`, :math:`\rho = 0`
     - 6

where :math:`u_a, w_a` complete :math:`n_a` to an orthonormal frame (the hinge and
the slider keep :math:`R_b n_b` along :math:`R_a n_a`),
:math:`\rho = \operatorname{vee}(C^\top R_a^\top R_b)` and :math:`C` is the fixed
relative rotation (identity by default). :math:`\operatorname{vee}` of the skew part of
:math:`C^\top R_a^\top R_b` vanishes exactly when the relative rotation is :math:`C`
(within a half turn of it, where its Jacobian has full rank). For a revolute joint
the axes must be unit vectors; they are normalised.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..rotations import orthonormal_complement, symbolic_vector, symbolic_vee
from .body import RigidBody

__all__ = ["Fixed", "Joint", "Prismatic", "Revolute", "Spherical", "Universal"]


def _unit(x, what: str) -> sp.Matrix:
    m = symbolic_vector(x, what)
    if m.free_symbols:
        raise ValueError(f"{what} must be a numeric direction, got {list(m)}")
    if m.dot(m) == 0:
        raise ValueError(f"{what} must be a nonzero direction")
    return m / sp.sqrt(m.dot(m))


def _relative(C, what: str) -> sp.Matrix:
    """The fixed relative rotation of a joint: the identity, or a checked 3x3 rotation."""
    if C is None:
        return sp.eye(3)
    m = sp.Matrix(C)
    if m.shape != (3, 3):
        raise ValueError(f"{what} must be a 3x3 rotation matrix, got shape {m.shape}")
    if not m.free_symbols:
        a = np.array(m, dtype=float)
        if np.abs(a.T @ a - np.eye(3)).max() > 1e-10 or np.linalg.det(a) <= 0:
            raise ValueError(f"{what} must be a proper rotation (C^T C = I, det C = 1)")
    return m


def _complement(n: sp.Matrix) -> tuple[sp.Matrix, sp.Matrix]:
    """Two unit vectors completing the unit vector ``n`` to an orthonormal frame."""
    u, w = orthonormal_complement(np.array(n, dtype=float))
    return sp.Matrix(u), sp.Matrix(w)


def _position(body: RigidBody | None, point: sp.Matrix) -> sp.Matrix:
    return point if body is None else body.point(point)


def _direction(body: RigidBody | None, axis: sp.Matrix) -> sp.Matrix:
    return axis if body is None else body.axis(axis)


def _rotation(body: RigidBody | None) -> sp.Matrix:
    return sp.eye(3) if body is None else body.rotation


@dataclass(frozen=True, eq=False)
class Joint:
    """Common data of the joints: the two bodies (``None``: the ground) and the two points."""

    a: RigidBody | None
    b: RigidBody | None
    point_a: Sequence = (0, 0, 0)
    point_b: Sequence = (0, 0, 0)

    def __post_init__(self) -> None:
        for side in ("a", "b"):
            body = getattr(self, side)
            if body is not None and not isinstance(body, RigidBody):
                raise TypeError(
                    f"{type(self).__name__}: {side} must be a RigidBody or None (the ground), "
                    f"got {body!r}"
                )
        if self.a is None and self.b is None:
            raise ValueError(f"{type(self).__name__}: a and b cannot both be the ground")
        if self.a is self.b:
            raise ValueError(f"{type(self).__name__}: a body cannot be joined to itself")
        object.__setattr__(self, "point_a", symbolic_vector(self.point_a, "point_a"))
        object.__setattr__(self, "point_b", symbolic_vector(self.point_b, "point_b"))

    @property
    def bodies(self) -> tuple[RigidBody, ...]:
        return tuple(b for b in (self.a, self.b) if b is not None)

    def separation(self) -> sp.Matrix:
        r""":math:`d = x_b + R_b p_b - x_a - R_a p_a`."""
        return _position(self.b, self.point_b) - _position(self.a, self.point_a)

    def constraints(self) -> list[sp.Expr]:
        """The joint's constraint expressions (zero when the joint holds)."""
        raise NotImplementedError  # pragma: no cover - every joint defines it

    def places_b(self) -> bool:
        """Whether the joint fixes the point of ``b`` at the point of ``a`` (``d = 0``)."""
        return True


class Spherical(Joint):
    r"""A ball joint: :math:`p_b` on *b* stays at :math:`p_a` on *a* (3 constraints)."""

    def constraints(self) -> list[sp.Expr]:
        return list(self.separation())


@dataclass(frozen=True, eq=False)
class _AxisJoint(Joint):
    axis_a: Sequence = (0, 0, 1)
    axis_b: Sequence | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        axis_a = _unit(self.axis_a, "axis_a")
        axis_b = axis_a if self.axis_b is None else _unit(self.axis_b, "axis_b")
        object.__setattr__(self, "axis_a", axis_a)
        object.__setattr__(self, "axis_b", axis_b)


class Revolute(_AxisJoint):
    r"""A hinge: ball joint plus :math:`R_b n_b \parallel R_a n_a` (5 constraints);
    ``axis_b`` defaults to ``axis_a``."""

    def constraints(self) -> list[sp.Expr]:
        u, w = _complement(self.axis_a)
        nb = _direction(self.b, self.axis_b)
        return [*self.separation(), _direction(self.a, u).dot(nb), _direction(self.a, w).dot(nb)]


class Universal(_AxisJoint):
    r"""A Cardan joint: ball joint plus :math:`(R_a n_a)\cdot(R_b n_b) = 0` (4 constraints);
    the two axes must be perpendicular in the reference pose."""

    def __post_init__(self) -> None:
        super().__post_init__()
        if self.axis_b is self.axis_a:
            raise ValueError("Universal: give axis_b, perpendicular to axis_a")
        if abs(float(self.axis_a.dot(self.axis_b))) > 1e-12:
            raise ValueError(
                f"Universal: axis_a {list(self.axis_a)} and axis_b {list(self.axis_b)} must be "
                "perpendicular (in the reference pose)"
            )

    def constraints(self) -> list[sp.Expr]:
        na = _direction(self.a, self.axis_a)
        nb = _direction(self.b, self.axis_b)
        return [*self.separation(), na.dot(nb)]


def _relative_rotation(joint: Joint, C: sp.Matrix) -> list[sp.Expr]:
    rel = C.T * _rotation(joint.a).T * _rotation(joint.b)
    return list(symbolic_vee(rel))


@dataclass(frozen=True, eq=False)
class Prismatic(Joint):
    r"""A slider along ``axis`` (fixed on *a*): no relative rotation, :math:`d` along
    :math:`R_a n_a` (5 constraints). ``rotation`` is the fixed relative rotation
    :math:`C = R_a^\top R_b` (identity by default)."""

    axis: Sequence = (0, 0, 1)
    rotation: Sequence | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "axis", _unit(self.axis, "axis"))
        object.__setattr__(self, "rotation", _relative(self.rotation, "rotation"))

    def places_b(self) -> bool:
        return False

    def constraints(self) -> list[sp.Expr]:
        u, w = _complement(self.axis)
        d = self.separation()
        return [
            _direction(self.a, u).dot(d),
            _direction(self.a, w).dot(d),
            *_relative_rotation(self, self.rotation),
        ]


@dataclass(frozen=True, eq=False)
class Fixed(Joint):
    r"""A weld: :math:`d = 0` and relative rotation :math:`C` (6 constraints)."""

    rotation: Sequence | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        object.__setattr__(self, "rotation", _relative(self.rotation, "rotation"))

    def constraints(self) -> list[sp.Expr]:
        return [*self.separation(), *_relative_rotation(self, self.rotation)]
