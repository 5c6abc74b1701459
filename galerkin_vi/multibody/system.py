r"""Multibody systems: rigid bodies, joints, gravity, loads and contacts as one Lagrangian system.

The Lagrangian of bodies :math:`b` with kinetic energies :math:`T_b` (:mod:`.body`)
in the uniform gravity field :math:`g` and a user potential :math:`U(t, q)` is

.. math::

    L = \sum_b T_b + \sum_b m_b\, g\cdot x_b - U,

constrained by every body's normalisation (:attr:`RigidBody.constraints`) and
every joint's constraints (:mod:`.joints`), in that order; loads become
generalised forces (:mod:`.loads`) and body contacts :class:`~galerkin_vi.Contact`
gaps (:mod:`.shapes`). :attr:`Multibody.system` is the resulting
:class:`~galerkin_vi.LagrangianSystem`: every integrator, run option, ensemble,
boundary-value and tangent solver applies to it unchanged.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..model.constraints import consistent_initial_state
from ..model.contacts import Contact
from ..model.system import LagrangianSystem, MomentumMap
from ..rotations import (
    body_rates_matrix,
    hat,
    quaternion_to_matrix,
    space_rates_matrix,
    symbolic_hat,
)
from .body import RigidBody
from .joints import Joint
from .loads import BodyForce, generalised_forces
from .motion import BodyMotion, body_motion
from .shapes import BodyContact

__all__ = ["Multibody"]


class Multibody:
    r"""Rigid bodies joined by joints, under gravity, loads and contacts.

    Parameters
    ----------
    bodies : sequence of RigidBody
        Distinct names; their coordinates are concatenated in this order.
    joints : sequence of Joint, optional
        :class:`~galerkin_vi.joints.Spherical`, ``Revolute``, ``Universal``,
        ``Prismatic``, ``Fixed`` between these bodies or the ground.
    gravity : 3 numbers or expressions, optional
        The uniform field :math:`g` (e.g. ``[0, 0, -9.81]``).
    forces : sequence of BodyForce, optional
        Forces and torques on the bodies (:mod:`.loads`).
    contacts : sequence of BodyContact or Contact, optional
        Unilateral contacts of body shapes (:mod:`.shapes`), or contacts with
        gaps written by hand in the bodies' symbols.
    potential : sympy.Expr, optional
        A further potential energy :math:`U(t, q)` (springs between body points, say).
    params : mapping of sympy.Symbol to float, optional
        Values of the parameters in masses, inertias, gravity, potential and loads.
    t : sympy.Symbol, optional
        The time symbol, for loads or potentials that depend on time.

    Attributes
    ----------
    system : LagrangianSystem
    bodies : dict of str to RigidBody

    Examples
    --------
    A heavy top: a body on a ball joint at the origin, centre of mass 1 above it.

    >>> import galerkin_vi as gvi
    >>> top = gvi.RigidBody("top", mass=1.0, inertia=[1.0, 1.0, 0.5])
    >>> mb = gvi.Multibody([top], joints=[gvi.joints.Spherical(None, top, point_b=[0, 0, -1])],
    ...                    gravity=[0, 0, -9.81])
    >>> mb.system.n, mb.system.m
    (7, 4)
    """

    def __init__(
        self,
        bodies: Sequence[RigidBody],
        joints: Sequence[Joint] = (),
        gravity: Sequence | None = None,
        forces: Sequence[BodyForce] = (),
        contacts: Sequence[BodyContact | Contact] = (),
        potential: sp.Expr | float = 0,
        params: Mapping[sp.Symbol, float] | None = None,
        t: sp.Symbol | None = None,
    ) -> None:
        if isinstance(bodies, RigidBody):
            bodies = [bodies]
        bodies = list(bodies)
        if not bodies:
            raise ValueError("Multibody: give at least one body")
        for j, b in enumerate(bodies):
            if not isinstance(b, RigidBody):
                raise TypeError(f"bodies[{j}] must be a RigidBody, got {b!r}")
        names = [b.name for b in bodies]
        if len(set(names)) != len(names):
            raise ValueError(f"Multibody: body names must be distinct, got {names}")
        self.bodies: dict[str, RigidBody] = dict(zip(names, bodies, strict=True))
        self.joints = tuple(_checked_joints(joints, bodies))
        self.gravity = None if gravity is None else sp.Matrix(gravity).reshape(3, 1)
        self.loads = tuple(forces or ())
        for j, load in enumerate(self.loads):
            if isinstance(load, BodyForce) and not any(load.body is b for b in bodies):
                raise ValueError(
                    f"forces[{j}] acts on {load.body.name!r}, not a body of this system"
                )
        self.body_contacts = tuple(contacts or ())
        q = [s for b in bodies for s in b.q]
        v = [s for b in bodies for s in b.v]
        L = sum((b.kinetic_energy for b in bodies), sp.S.Zero) - sp.sympify(potential)
        if self.gravity is not None:
            L += sum((b.mass * self.gravity.dot(b.position) for b in bodies), sp.S.Zero)
        constraints = [g for b in bodies for g in b.constraints]
        constraints += [g for joint in self.joints for g in joint.constraints()]
        self.system = LagrangianSystem(
            L,
            q=q,
            v=v,
            t=t,
            params=params,
            constraints=constraints,
            forces=generalised_forces(self.loads, v),
            contacts=[_contact(c, j, bodies) for j, c in enumerate(self.body_contacts)] or None,
        )
        offsets = np.cumsum([0] + [len(b.q) for b in bodies])
        self._slices = {
            b.name: slice(int(offsets[i]), int(offsets[i + 1])) for i, b in enumerate(bodies)
        }

    def __repr__(self) -> str:
        return (
            f"Multibody(bodies={list(self.bodies)}, joints={len(self.joints)}, "
            f"n={self.system.n}, m={self.system.m})"
        )

    def coordinates(self, body: str) -> slice:
        """The slice of ``body``'s coordinates in the system's ``q`` (and ``v``)."""
        return self._slices[self._name(body)]

    def _name(self, body) -> str:
        name = body.name if isinstance(body, RigidBody) else body
        if name not in self.bodies:
            raise KeyError(f"no body named {name!r}; the bodies are {list(self.bodies)}")
        return name

    def state(
        self,
        positions: Mapping[str, ArrayLike] | None = None,
        rotations: Mapping[str, ArrayLike] | None = None,
        velocities: Mapping[str, ArrayLike] | None = None,
        angular_velocities: Mapping[str, ArrayLike] | None = None,
        frame: str = "body",
        t: float = 0.0,
        params: Mapping[sp.Symbol, float] | None = None,
        project: bool = True,
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        r"""Consistent initial coordinates and velocities ``(q0, v0)`` from poses and rates.

        Parameters
        ----------
        positions, velocities : mapping of body name to 3 numbers, optional
            Centre of mass and its velocity. A body without a given position is
            placed by a joint whose other body is placed (the ground is):
            :math:`x_b = x_a + R_a p_a - R_b p_b`, and its velocity likewise,
            :math:`\dot x_b = \dot x_a + \omega_{s,a}\times R_a p_a - \omega_{s,b}\times R_b p_b`;
            otherwise at the origin, at rest.
        rotations : mapping of body name to a 3×3 matrix or a unit quaternion, optional
            Attitudes (identity by default).
        angular_velocities : mapping of body name to 3 numbers, optional
            Angular velocities (zero by default), in the ``frame`` ``"body"`` or ``"space"``.
        t, params
            Time and parameter values of the projection.
        project : bool
            Project the result onto the constraints and the hidden constraints
            (:func:`~galerkin_vi.model.constraints.consistent_initial_state`), which
            makes joints hold to round-off; otherwise raise if they do not.

        Raises
        ------
        KeyError
            If a name is not a body of the system.
        ValueError
            If a rotation is not a rotation, or the state is not consistent and
            ``project`` is false.
        """
        if frame not in ("body", "space"):
            raise ValueError(f"frame must be 'body' or 'space', got {frame!r}")
        positions = {self._name(k): np.asarray(x, float) for k, x in (positions or {}).items()}
        velocities = {self._name(k): np.asarray(x, float) for k, x in (velocities or {}).items()}
        rotations = {self._name(k): np.asarray(x, float) for k, x in (rotations or {}).items()}
        omegas = {
            self._name(k): np.asarray(x, float) for k, x in (angular_velocities or {}).items()
        }
        R = {}
        ws = {}
        for name, body in self.bodies.items():
            coords = body.coordinates_of(np.zeros(3), rotations.get(name, np.eye(3)))
            R[name] = _rotation_of(body, coords)
            w = omegas.get(name, np.zeros(3))
            ws[name] = R[name] @ w if frame == "body" else w
        x, xd = _placed(self, positions, velocities, R, ws)
        q0 = np.concatenate(
            [b.coordinates_of(x[n], rotations.get(n, np.eye(3))) for n, b in self.bodies.items()]
        )
        v0 = np.concatenate(
            [
                b.velocities_of(q0[self._slices[n]], xd[n], ws[n], "space")
                for n, b in self.bodies.items()
            ]
        )
        system = self.system
        values = dict(zip(system.params, system.param_defaults, strict=True))
        values.update(params or {})
        prm = np.array([float(values[s]) for s in system.params])
        p0 = system.legendre(q0, v0, t, values)
        q0, _, v0 = consistent_initial_state(system, t, q0, p0, v0, prm, project)
        return q0, v0

    def motion(self, trajectory, body) -> BodyMotion:
        """The pose and angular velocity of ``body`` at the rows of ``trajectory``
        (:class:`~galerkin_vi.multibody.motion.BodyMotion`)."""
        name = self._name(body)
        sl = self._slices[name]
        v = trajectory.velocities()
        return body_motion(self.bodies[name], trajectory.t, trajectory.q[:, sl], v[:, sl])

    def angular_momentum(self, axis: Sequence, body=None, frame: str = "space") -> MomentumMap:
        r"""The momentum map of rotations about ``axis``.

        ``frame="space"``: all bodies (or only ``body``) rotated about the space
        axis through the origin, :math:`\delta x = a\times x`, :math:`\delta R = \hat a R`
        (:math:`\delta\mathsf q = \tfrac12 E^\top a`); conserved when gravity, joints
        to the ground, loads and contacts are invariant under that rotation.
        ``frame="body"``: ``body`` rotated about its own body axis,
        :math:`\delta R = R\hat a` (:math:`\delta\mathsf q = \tfrac12 G^\top a`): the
        momentum about the symmetry axis of a symmetric top.
        """
        if frame not in ("body", "space"):
            raise ValueError(f"frame must be 'body' or 'space', got {frame!r}")
        a = sp.Matrix(axis).reshape(3, 1)
        if frame == "body" and body is None:
            raise ValueError("a body-frame momentum needs the body (body=...)")
        chosen = set(self.bodies) if body is None else {self._name(body)}
        xi: list[sp.Expr] = []
        for name, b in self.bodies.items():
            if name not in chosen:
                xi += [sp.S.Zero] * len(b.q)
                continue
            xi += list(a.cross(b.position)) if frame == "space" else [sp.S.Zero] * 3
            xi += _rotation_generator(b, a, frame)
        return self.system.momentum_map(xi)

    def linear_momentum(self, direction: Sequence) -> MomentumMap:
        r"""The momentum map of translations of every body along ``direction``."""
        d = list(sp.Matrix(direction))
        xi: list[sp.Expr] = []
        for b in self.bodies.values():
            xi += d + [sp.S.Zero] * (len(b.q) - 3)
        return self.system.momentum_map(xi)


def _rotation_generator(body: RigidBody, a: sp.Matrix, frame: str) -> list[sp.Expr]:
    r = body.q[3:]
    if body.embedding == "quaternion":
        M = space_rates_matrix(r) if frame == "space" else body_rates_matrix(r)
        return list(M.T * a / 2)
    R = body.rotation
    delta = symbolic_hat(a) * R if frame == "space" else R * symbolic_hat(a)
    return list(delta)


def _rotation_of(body: RigidBody, coords: NDArray) -> NDArray:
    r = coords[3:]
    return quaternion_to_matrix(r) if body.embedding == "quaternion" else r.reshape(3, 3)


def _placed(mb: Multibody, positions, velocities, R, ws) -> tuple[dict, dict]:
    """Centres of mass and their velocities: given, or placed through joints."""
    x = dict(positions)
    xd = {n: velocities.get(n, np.zeros(3)) for n in mb.bodies}
    ground = (np.zeros(3), np.eye(3), np.zeros(3), np.zeros(3))

    def frame(body):
        if body is None:
            return ground
        n = body.name
        return x.get(n), R[n], xd[n], ws[n]

    changed = True
    while changed:
        changed = False
        for joint in mb.joints:
            if not joint.places_b():
                continue
            for known, unknown, p_known, p_unknown in (
                (joint.a, joint.b, joint.point_a, joint.point_b),
                (joint.b, joint.a, joint.point_b, joint.point_a),
            ):
                if unknown is None or unknown.name in x:
                    continue
                xk, Rk, vk, wk = frame(known)
                if xk is None:
                    continue
                pk = Rk @ np.array(p_known, dtype=float).ravel()
                pu = R[unknown.name] @ np.array(p_unknown, dtype=float).ravel()
                x[unknown.name] = xk + pk - pu
                if unknown.name not in velocities:
                    xd[unknown.name] = vk + hat(wk) @ pk - hat(ws[unknown.name]) @ pu
                changed = True
    for n in mb.bodies:
        x.setdefault(n, np.zeros(3))
    return x, xd


def _checked_joints(joints, bodies) -> list[Joint]:
    out = []
    for j, joint in enumerate(joints or ()):
        if not isinstance(joint, Joint):
            raise TypeError(f"joints[{j}] must be a joint of galerkin_vi.joints, got {joint!r}")
        for b in joint.bodies:
            if not any(b is c for c in bodies):
                raise ValueError(f"joints[{j}] joins {b.name!r}, which is not a body of the system")
        out.append(joint)
    return out


def _contact(c, j: int, bodies) -> Contact:
    if isinstance(c, Contact):
        return c
    if not isinstance(c, BodyContact):
        raise TypeError(f"contacts[{j}] must be a BodyContact or a Contact, got {c!r}")
    shapes = [c.shape] + ([c.other] if hasattr(c.other, "body") else [])
    for s in shapes:
        if not any(s.body is b for b in bodies):
            raise ValueError(f"contacts[{j}] is on {s.body.name!r}, not a body of the system")
    return c.contact()
