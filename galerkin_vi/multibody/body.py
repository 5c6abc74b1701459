r"""A rigid body in 3-D: coordinates, kinetic energy and pose as SymPy expressions.

A body's configuration is the position :math:`x \in \mathbb R^3` of its centre of
mass and its attitude :math:`R \in SO(3)` (body → space). The rotation is
*embedded*: written in redundant coordinates held on :math:`SO(3)` by holonomic
constraints, which the constrained Galerkin integrator enforces at every control
point with multipliers (a RATTLE-type method of any order). Two embeddings:

**Rotation matrix** (9 coordinates, 6 constraints :math:`R^\top R = I`).
With :math:`J` the inertia tensor in the body frame and
:math:`J_d = \tfrac12\operatorname{tr}(J)\,I - J`,

.. math::

    T = \tfrac12 m |\dot x|^2 + \tfrac12\operatorname{tr}(\dot R J_d \dot R^\top),

since :math:`\operatorname{tr}(\hat\omega J_d\hat\omega^\top) = \omega^\top J\omega` for
:math:`\dot R = R\hat\omega`. The mass matrix is constant, so the step is the
Moser–Veselov / RATTLE construction at :math:`s = 1` and its Galerkin extension
at higher degree. :math:`J_d` is positive definite iff the moments satisfy the
strict triangle inequalities; when they do not (a flat plate, :math:`J_3 = J_1 + J_2`)
the term :math:`\tfrac{c}{2}\|\operatorname{sym}(R^\top\dot R)\|_F^2`, zero on the
constraint manifold, is added.

**Unit quaternion** (4 coordinates, 1 constraint :math:`|\mathsf q|^2 = 1`). With
:math:`\omega = 2G(\mathsf q)\dot{\mathsf q}` (:mod:`galerkin_vi.rotations`),
:math:`\tfrac12\omega^\top J\omega = 2\dot{\mathsf q}^\top G^\top J G\dot{\mathsf q}` is singular
along :math:`\mathsf q` (:math:`G\mathsf q = 0`). The body's kinetic energy is augmented,

.. math::

    T = \tfrac12 m |\dot x|^2 + 2\dot{\mathsf q}^\top G^\top J G\,\dot{\mathsf q}
        + \tfrac{c}{2}(\mathsf q^\top\dot{\mathsf q})^2,
    \qquad c = \tfrac43\operatorname{tr} J .

For a unit :math:`\mathsf q` the matrix :math:`\binom{G}{\mathsf q^\top}` is orthogonal, so
:math:`L_{vv} = 4G^\top J G + c\,\mathsf q\mathsf q^\top` has the eigenvalues
:math:`4J_1, 4J_2, 4J_3, c`: regular, and no worse conditioned than :math:`J`.
The added term changes nothing on the constraint manifold: it vanishes to second
order there (:math:`\mathsf q^\top\dot{\mathsf q} = \tfrac12\frac{d}{dt}|\mathsf q|^2 = 0`), and its
Euler–Lagrange term :math:`c\,\frac{d}{dt}(\mathsf q^\top\dot{\mathsf q})\,\mathsf q` is normal to
the sphere, where the multiplier of the constraint absorbs it. The same holds
for the discrete equations up to the method's order (the constraint holds at the
control points, not between them).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cached_property

import numpy as np
import sympy as sp

from ..rotations import (
    body_rates_matrix,
    hat,
    matrix_to_quaternion,
    quaternion_rate,
    quaternion_to_matrix,
    space_rates_matrix,
    symbolic_quaternion_matrix,
    symbolic_vector,
    symbolic_vee,
)

__all__ = ["ROTATIONS", "RigidBody"]

#: the rotation coordinates a body can have
ROTATIONS = ("quaternion", "matrix")


def _inertia_tensor(inertia, name: str) -> sp.Matrix:
    """The 3×3 body-frame inertia from three principal moments or a symmetric tensor."""
    try:
        arr = sp.Matrix(inertia)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"RigidBody({name!r}): inertia must be 3 moments or a 3x3 tensor") from exc
    if arr.shape in ((3, 1), (1, 3)):
        J = sp.diag(*list(arr))
    elif arr.shape == (3, 3):
        J = arr
    else:
        raise ValueError(
            f"RigidBody({name!r}): inertia must be 3 principal moments or a 3x3 tensor, "
            f"got shape {arr.shape}"
        )
    if J.free_symbols:
        if J != J.T:
            raise ValueError(f"RigidBody({name!r}): the inertia tensor must be symmetric")
        return J
    # a numeric tensor rotated into the body frame (Q diag(J) Q^T) is symmetric only to
    # round-off: accepted within a relative 1e-12, and symmetrised
    arr = np.array(J, dtype=float)
    scale = np.abs(arr).max()
    if np.abs(arr - arr.T).max() > 1e-12 * scale:
        raise ValueError(f"RigidBody({name!r}): the inertia tensor must be symmetric")
    J = (J + J.T) / 2
    values = np.linalg.eigvalsh((arr + arr.T) / 2)
    if values.min() <= 0:
        raise ValueError(
            f"RigidBody({name!r}): the inertia tensor must be positive definite, "
            f"its principal moments are {values}"
        )
    # a flat plate (J_3 = J_1 + J_2) sits on the bound: equality within round-off is allowed
    s = values.sum() / 2
    if np.any(values > s + 1e-12 * scale):
        raise ValueError(
            f"RigidBody({name!r}): the principal moments {values} violate the triangle "
            "inequality J_i <= J_j + J_k that every rigid body satisfies"
        )
    return J


class RigidBody:
    r"""A rigid body: mass, inertia and the coordinates of its pose.

    Parameters
    ----------
    name : str
        Prefix of the body's symbols (``"b"`` gives ``b_x, b_y, b_z, b_e0, ...``);
        also the key of the body in :meth:`~galerkin_vi.Multibody.state` and
        :meth:`~galerkin_vi.Multibody.motion`.
    mass : float or sympy.Expr
        :math:`m > 0` (an expression in parameters is allowed).
    inertia : 3 floats or 3×3 array
        The inertia tensor :math:`J` about the centre of mass in the body frame,
        as principal moments (the body frame is then principal) or a symmetric
        positive definite tensor.
    rotation : {"quaternion", "matrix"}
        The embedding of the attitude (module notes). ``"quaternion"``, the
        default, is faster per step and more accurate at equal step on the
        benchmarks (docs/performance.md, "Rigid bodies").

    Attributes
    ----------
    q, v : tuple of sympy.Symbol
        Coordinates and their velocities: ``x, y, z`` of the centre of mass,
        then ``e0..e3`` (quaternion, scalar first) or ``r11..r33`` (the rotation
        matrix, row major), each prefixed by ``name + "_"``; velocities end in
        ``_dot``.
    position, velocity : sympy.Matrix
        :math:`x` and :math:`\dot x`.
    embedding : str
        ``"quaternion"`` or ``"matrix"`` (the ``rotation`` argument).
    rotation : sympy.Matrix
        :math:`R` in the coordinates (:math:`R(\mathsf q)` for quaternions).
    angular_velocity, angular_velocity_space : sympy.Matrix
        :math:`\omega` (body frame) and :math:`\omega_s = R\omega` in the coordinates
        and velocities.
    kinetic_energy : sympy.Expr
        :math:`T` of the module notes.
    constraints : tuple of sympy.Expr
        The normalisation of the rotation coordinates:
        :math:`(|\mathsf q|^2 - 1)/2`, or the upper triangle of :math:`(R^\top R - I)/2`.

    Examples
    --------
    >>> import galerkin_vi as gvi
    >>> b = gvi.RigidBody("b", mass=1.0, inertia=[2.0, 3.0, 4.0])
    >>> b.q
    (b_x, b_y, b_z, b_e0, b_e1, b_e2, b_e3)
    >>> b.point([0, 0, 1])[2]
    b_e0**2 - b_e1**2 - b_e2**2 + b_e3**2 + b_z
    """

    def __init__(
        self, name: str, mass: float | sp.Expr, inertia: object, rotation: str = "quaternion"
    ) -> None:
        if not isinstance(name, str) or not name.isidentifier():
            raise ValueError(f"RigidBody: name must be an identifier, got {name!r}")
        if rotation not in ROTATIONS:
            raise ValueError(
                f"RigidBody({name!r}): rotation must be one of {ROTATIONS}, got {rotation!r}"
            )
        value = sp.sympify(mass)
        if not value.free_symbols and not float(value) > 0:
            raise ValueError(f"RigidBody({name!r}): mass must be > 0, got {mass!r}")
        self.name = name
        self.mass = value
        self.inertia = inertia
        #: the embedding of the attitude, ``"quaternion"`` or ``"matrix"``
        self.embedding = rotation
        #: :math:`J`, the 3x3 body-frame inertia tensor (sympy.Matrix)
        self.inertia_tensor = _inertia_tensor(inertia, name)

    def __repr__(self) -> str:
        return (
            f"RigidBody({self.name!r}, mass={self.mass}, inertia={self.inertia!r}, "
            f"rotation={self.embedding!r})"
        )

    def __reduce__(self):
        return (type(self), (self.name, self.mass, self.inertia, self.embedding))

    @cached_property
    def rotation_coordinates(self) -> tuple[sp.Symbol, ...]:
        """The symbols of the attitude (quaternion ``e0..e3`` or matrix ``r11..r33``)."""
        if self.embedding == "quaternion":
            names = [f"{self.name}_e{i}" for i in range(4)]
        else:
            names = [f"{self.name}_r{i}{j}" for i in range(1, 4) for j in range(1, 4)]
        return tuple(sp.Symbol(s, real=True) for s in names)

    @cached_property
    def q(self) -> tuple[sp.Symbol, ...]:
        xyz = tuple(sp.Symbol(f"{self.name}_{c}", real=True) for c in "xyz")
        return xyz + self.rotation_coordinates

    @cached_property
    def v(self) -> tuple[sp.Symbol, ...]:
        return tuple(sp.Symbol(f"{s.name}_dot", real=True) for s in self.q)

    @property
    def position(self) -> sp.Matrix:
        return sp.Matrix(self.q[:3])

    @property
    def velocity(self) -> sp.Matrix:
        return sp.Matrix(self.v[:3])

    @cached_property
    def rotation(self) -> sp.Matrix:
        r = self.q[3:]
        if self.embedding == "quaternion":
            return symbolic_quaternion_matrix(r)
        return sp.Matrix(3, 3, r)

    @cached_property
    def rotation_rate(self) -> sp.Matrix:
        r""":math:`\dot R` in the coordinates and velocities."""
        R = self.rotation
        rate = sp.zeros(3, 3)
        for s, sd in zip(self.q[3:], self.v[3:], strict=True):
            rate += R.diff(s) * sd
        return rate

    @cached_property
    def angular_velocity(self) -> sp.Matrix:
        r"""Body angular velocity :math:`\omega`: :math:`2G\dot{\mathsf q}` or
        :math:`\operatorname{vee}(R^\top\dot R)` (its skew part)."""
        if self.embedding == "quaternion":
            return 2 * body_rates_matrix(self.q[3:]) * sp.Matrix(self.v[3:])
        return symbolic_vee(self.rotation.T * self.rotation_rate)

    @cached_property
    def angular_velocity_space(self) -> sp.Matrix:
        r"""Space angular velocity :math:`\omega_s = R\omega`: :math:`2E\dot{\mathsf q}` or
        :math:`\operatorname{vee}(\dot R R^\top)`."""
        if self.embedding == "quaternion":
            return 2 * space_rates_matrix(self.q[3:]) * sp.Matrix(self.v[3:])
        return symbolic_vee(self.rotation_rate * self.rotation.T)

    def point(self, r_body: Sequence) -> sp.Matrix:
        r"""The space position :math:`x + R\,r` of the body-fixed point ``r_body``."""
        return self.position + self.rotation * symbolic_vector(r_body, "r_body")

    def point_velocity(self, r_body: Sequence) -> sp.Matrix:
        r"""The space velocity :math:`\dot x + \dot R\,r` of the body-fixed point ``r_body``."""
        return self.velocity + self.rotation_rate * symbolic_vector(r_body, "r_body")

    def axis(self, a_body: Sequence) -> sp.Matrix:
        r"""The space direction :math:`R\,a` of the body-fixed direction ``a_body``."""
        return self.rotation * symbolic_vector(a_body, "a_body")

    @cached_property
    def augmentation_constant(self) -> sp.Expr:
        r"""The constant :math:`c` of the augmentation (module notes)."""
        J = self.inertia_tensor
        if self.embedding == "quaternion":
            return sp.Rational(4, 3) * J.trace()
        return sp.Rational(2, 3) * J.trace()

    @cached_property
    def needs_augmentation(self) -> bool:
        r"""Whether the kinetic energy carries the augmentation term (module notes)."""
        if self.embedding == "quaternion":
            return True
        Jd = self.inertia_tensor.trace() / 2 * sp.eye(3) - self.inertia_tensor
        if Jd.free_symbols:
            return True
        return bool(
            np.linalg.eigvalsh(np.array(Jd, dtype=float)).min()
            <= 1e-12 * float(self.inertia_tensor.trace())
        )

    @cached_property
    def kinetic_energy(self) -> sp.Expr:
        m, J = self.mass, self.inertia_tensor
        xd = self.velocity
        T = m * xd.dot(xd) / 2
        c = self.augmentation_constant
        rd = sp.Matrix(self.v[3:])
        if self.embedding == "quaternion":
            G = body_rates_matrix(self.q[3:])
            T += 2 * (rd.T * G.T * J * G * rd)[0, 0]
            T += c / 2 * sp.Matrix(self.q[3:]).dot(rd) ** 2
            return T
        Rd = sp.Matrix(3, 3, self.v[3:])
        Jd = J.trace() / 2 * sp.eye(3) - J
        T += (Rd * Jd * Rd.T).trace() / 2
        if self.needs_augmentation:
            W = self.rotation.T * Rd
            S = (W + W.T) / 2
            T += c / 2 * sum(x**2 for x in S)
        return T

    @cached_property
    def constraints(self) -> tuple[sp.Expr, ...]:
        r = self.q[3:]
        if self.embedding == "quaternion":
            return ((sum(x**2 for x in r) - 1) / 2,)
        R = self.rotation
        C = (R.T * R - sp.eye(3)) / 2
        return tuple(C[i, j] for i in range(3) for j in range(i, 3))

    def coordinates_of(self, position, rotation) -> np.ndarray:
        """The coordinate values of a pose: ``position`` (3) and ``rotation`` (a 3×3
        matrix or a scalar-first unit quaternion)."""
        x = np.asarray(position, dtype=float).reshape(3)
        rot = np.asarray(rotation, dtype=float)
        if rot.shape == (4,):
            norm = np.linalg.norm(rot)
            if not np.isfinite(norm) or abs(norm - 1.0) > 1e-6:
                raise ValueError(
                    f"{self.name}: a rotation given as a quaternion must have unit norm, "
                    f"got |q| = {norm}"
                )
            rot = rot / norm
            R = quaternion_to_matrix(rot)
        elif rot.shape == (3, 3):
            R = rot
            if np.abs(R.T @ R - np.eye(3)).max() > 1e-6 or np.linalg.det(R) < 0:
                raise ValueError(f"{self.name}: the rotation matrix is not a proper rotation")
        else:
            raise ValueError(
                f"{self.name}: a rotation must be a 3x3 matrix or a quaternion, got shape "
                f"{rot.shape}"
            )
        if self.embedding == "quaternion":
            e = rot if rot.shape == (4,) else matrix_to_quaternion(R)
            return np.concatenate([x, e])
        return np.concatenate([x, R.ravel()])

    def velocities_of(self, coords, velocity, angular_velocity, frame: str = "body") -> np.ndarray:
        r"""The velocity values at the coordinates ``coords`` for a centre-of-mass velocity
        and an angular velocity in the ``"body"`` or ``"space"`` frame:
        :math:`\dot{\mathsf q} = \tfrac12 G^\top\omega`,
        :math:`\dot R = R\hat\omega = \hat\omega_s R`."""
        if frame not in ("body", "space"):
            raise ValueError(f"frame must be 'body' or 'space', got {frame!r}")
        xd = np.asarray(velocity, dtype=float).reshape(3)
        w = np.asarray(angular_velocity, dtype=float).reshape(3)
        r = np.asarray(coords, dtype=float)[3:]
        if self.embedding == "quaternion":
            return np.concatenate([xd, quaternion_rate(r, w, frame)])
        R = r.reshape(3, 3)
        Rd = R @ hat(w) if frame == "body" else hat(w) @ R
        return np.concatenate([xd, Rd.ravel()])
