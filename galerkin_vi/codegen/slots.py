"""Where each point function goes in the address array a compiled loop receives.

The code generator fills the array (:meth:`.compiled.PointFunctions.addresses`);
the loops read it by the names of :mod:`galerkin_vi.loops.abi`, which are taken
from this table. The loops' compiled code has the slot numbers built in, so
this file is one of the sources their cache is keyed by
(:mod:`galerkin_vi.loops._jit`).
"""

from __future__ import annotations

__all__ = ["POINT_SLOTS"]

#: the slot of each point function in the address array the loops receive
#: (:mod:`galerkin_vi.loops.abi` names them, :mod:`galerkin_vi.loops.point` calls them)
POINT_SLOTS = {
    "point_gradient": 0,
    "point_hessian": 1,
    "lagrangian": 2,
    "point_constraint": 3,
    "point_constraint_jacobian": 4,
    "point_constraint_rate": 5,
    "point_constraint_hessian": 6,
    "point_mass": 7,
    "point_velocity": 8,
    "point_contact": 9,
    "point_slip": 10,
}
