"""Rigid bodies and multibody systems in 3-D, built into a :class:`~galerkin_vi.LagrangianSystem`.

The stage above :mod:`galerkin_vi.model`: bodies (:mod:`.body`) with embedded
rotations, joints (:mod:`.joints`), loads (:mod:`.loads`), contact shapes
(:mod:`.shapes`), their assembly (:mod:`.system`) and the motion of each body
read back from a trajectory (:mod:`.motion`). The rotations' formulas are
:mod:`galerkin_vi.rotations`; :mod:`sympy.physics.mechanics` bodies oriented by
quaternions or direction cosines convert in :mod:`galerkin_vi.model.rigid_frames`.
"""

from . import joints
from .body import RigidBody
from .loads import BodyForce
from .motion import BodyMotion
from .shapes import (
    BodyContact,
    BodyPlane,
    BodyPoint,
    Box,
    Plane,
    Sphere,
    standing_contacts,
)
from .system import Multibody

__all__ = [
    "BodyContact",
    "BodyForce",
    "BodyMotion",
    "BodyPlane",
    "BodyPoint",
    "Box",
    "Multibody",
    "Plane",
    "RigidBody",
    "Sphere",
    "joints",
    "standing_contacts",
]
