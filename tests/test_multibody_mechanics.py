"""sympy.physics.mechanics rigid bodies on quaternion or direction-cosine frames.

Each model converts with ``LagrangianSystem.from_lagranges_method`` and is
compared with the same body built by ``gvi.RigidBody`` in a ``gvi.Multibody``,
started from the same state: to round-off where the Lagrangians are the same
expression, to the method's order where they differ only off the constraint
manifold. NumPy backend, Galerkin(2) (order 4), at most 200 steps per run.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me

import galerkin_vi as gvi
from galerkin_vi.model.mechanics import to_plain_symbols
from galerkin_vi.model.rigid_frames import mechanics_rotations

MASS = 2.0
MOMENTS = (1.0, 2.0, 3.0)
m, arm, g, J1, J3 = sp.symbols("m l g J1 J3", positive=True)
TOP_PARAMS = {m: 1.0, arm: 0.5, g: 9.81, J1: 0.3, J3: 0.2}


def integrate(system, q0, v0, h=0.01, n_steps=100):
    return gvi.Integrator(system, gvi.Galerkin(2), backend="numpy").integrate(
        q0, v0=v0, h=h, n_steps=n_steps
    )


def free_body(rotation: str, bodies: bool = True, hol_coneqs=None):
    """A free body in mechanics: centre of mass x, y, z, frame by quaternion or DCM;
    ``hol_coneqs(r)`` gives constraints in the rotation coordinates ``r``."""
    x = me.dynamicsymbols("x y z")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    if rotation == "quaternion":
        r = me.dynamicsymbols("e0:4")
        B.orient_quaternion(N, r)
    else:
        r = me.dynamicsymbols("r1:10")
        B.orient_explicit(N, sp.Matrix(3, 3, r))
    origin = me.Point("O")
    origin.set_vel(N, 0)
    P = origin.locatenew("P", x[0] * N.x + x[1] * N.y + x[2] * N.z)
    P.set_vel(N, P.pos_from(origin).dt(N))
    body = me.RigidBody("b", P, B, MASS, (me.inertia(B, *MOMENTS), P))
    lm = me.LagrangesMethod(
        me.Lagrangian(N, body),
        list(x) + list(r),
        bodies=[body] if bodies else None,
        frame=N,
        hol_coneqs=None if hol_coneqs is None else hol_coneqs(r),
    )
    return lm, r


@cache
def gvi_free_body(rotation: str):
    body = gvi.RigidBody("b", mass=MASS, inertia=list(MOMENTS), rotation=rotation)
    mb = gvi.Multibody([body])
    q0, v0 = mb.state(
        positions={"b": [0.1, -0.2, 0.3]},
        rotations={"b": [np.cos(0.3), 0.0, np.sin(0.3), 0.0]},
        velocities={"b": [0.5, 0.1, -0.2]},
        angular_velocities={"b": [0.2, 3.0, 0.4]},
    )
    return mb, q0, v0, integrate(mb.system, q0, v0)


def same_expression(system, reference) -> bool:
    rename = dict(zip(system.q, reference.q, strict=True))
    rename.update(zip(system.v, reference.v, strict=True))
    return sp.expand(system.L.xreplace(rename) - reference.L) == 0


# ----------------------------------------------------------------- quaternions
def test_free_body_quaternion_is_the_gvi_rigid_body_to_round_off():
    lm, _ = free_body("quaternion")
    system = gvi.LagrangianSystem.from_lagranges_method(lm)
    mb, q0, v0, reference = gvi_free_body("quaternion")
    assert (system.n, system.m) == (7, 1)
    assert same_expression(system, mb.system)
    traj = integrate(system, q0, v0)
    assert np.abs(traj.q - reference.q).max() < 1e-12
    assert np.abs(np.linalg.norm(traj.q[:, 3:], axis=1) - 1).max() < 1e-13


def test_detected_quaternion_reports_frame_body_and_constant():
    lm, e = free_body("quaternion")
    (rotation,) = mechanics_rotations(lm)
    assert rotation.kind == "quaternion"
    assert rotation.coordinates == tuple(e)
    assert rotation.frames == ("B",) and rotation.bodies == ("b",)
    assert float(rotation.augmentation_constant) == pytest.approx(4 / 3 * sum(MOMENTS))


def test_explicit_quaternion_without_bodies_reads_the_constant_from_the_lagrangian():
    """c = tr(d2L/de_dot2)/3 at the identity = 4/3 tr J: the gvi body's Lagrangian again."""
    lm, e = free_body("quaternion", bodies=False)
    assert mechanics_rotations(lm) == ()
    system = gvi.LagrangianSystem.from_lagranges_method(lm, quaternions=[e])
    assert (system.n, system.m) == (7, 1)
    assert same_expression(system, gvi_free_body("quaternion")[0].system)


def test_heavy_top_on_a_fixed_point_agrees_with_the_ball_joint_at_the_method_order():
    """Four quaternion coordinates (mass centre at l B.z, gravity in the Lagrangian)
    against gvi's seven coordinates with a spherical joint: equal on the manifold,
    so the quaternions differ by the method's O(h^4), shrinking 16-fold per halving."""
    e = me.dynamicsymbols("e0:4")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_quaternion(N, e)
    origin = me.Point("O")
    origin.set_vel(N, 0)
    P = origin.locatenew("P", arm * B.z)
    P.v2pt_theory(origin, N, B)
    body = me.RigidBody("top", P, B, m, (me.inertia(B, J1, J1, J3), P))
    body.potential_energy = m * g * P.pos_from(origin).dot(N.z)
    lm = me.LagrangesMethod(me.Lagrangian(N, body), e, bodies=[body], frame=N)
    system = gvi.LagrangianSystem.from_lagranges_method(lm, TOP_PARAMS)
    assert (system.n, system.m) == (4, 1)

    top = gvi.RigidBody("top", mass=1.0, inertia=[0.3, 0.3, 0.2])
    joint = gvi.joints.Spherical(None, top, point_b=[0, 0, -0.5])
    mb = gvi.Multibody([top], joints=[joint], gravity=[0, 0, -9.81])
    q0, v0 = mb.state(
        rotations={"top": [np.cos(0.2), np.sin(0.2), 0, 0]},
        angular_velocities={"top": [0.5, 0.0, 8.0]},
    )
    gaps = []
    for h, n in ((0.01, 50), (0.005, 100)):
        reference = integrate(mb.system, q0, v0, h, n)
        traj = integrate(system, q0[3:], v0[3:], h, n)
        gaps.append(np.abs(traj.q - reference.q[:, 3:]).max())
        assert np.abs(np.linalg.norm(traj.q, axis=1) - 1).max() < 1e-13
    assert gaps[0] < 1e-8
    assert 10 < gaps[0] / gaps[1] < 25


def test_stated_unit_norm_is_not_added_twice():
    lm, _ = free_body("quaternion", hol_coneqs=lambda e: [sum(x**2 for x in e) - 1])
    system = gvi.LagrangianSystem.from_lagranges_method(lm)
    assert system.m == 1
    (rotation,) = mechanics_rotations(lm)
    assert rotation.constraints == ()


# ----------------------------------------------------------------- direction cosines
def test_direction_cosines_of_a_body_become_the_gvi_matrix_body_to_round_off():
    """The rotational energy mechanics derives from the DCM is replaced by
    tr(R' J_d R'^T)/2: the Lagrangian is then gvi.RigidBody(rotation="matrix")'s."""
    lm, _ = free_body("matrix")
    system = gvi.LagrangianSystem.from_lagranges_method(lm)
    mb, q0, v0, reference = gvi_free_body("matrix")
    assert (system.n, system.m) == (12, 6)
    assert same_expression(system, mb.system)
    traj = integrate(system, q0, v0)
    assert np.abs(traj.q - reference.q).max() < 1e-11


def test_direction_cosines_without_bodies_are_regularised_by_the_augmentation():
    """No body listed: mechanics' own energy (rank 3 in the nine rates, singular even
    on the manifold's normal space) plus c/2 |sym(R^T R')|^2, c = 2/3 tr J read from L.
    Differs from the J_d form only off the tangent bundle: agreement at the method order."""
    lm, r = free_body("matrix", bodies=False)
    with pytest.raises(gvi.DegenerateLagrangianError):
        gvi.LagrangianSystem.from_lagranges_method(lm)
    R = sp.Matrix(3, 3, r)
    (rotation,) = mechanics_rotations(lm, direction_cosines=[R])
    assert float(rotation.augmentation_constant) == pytest.approx(2 / 3 * sum(MOMENTS))
    system = gvi.LagrangianSystem.from_lagranges_method(lm, direction_cosines=[R])
    assert (system.n, system.m) == (12, 6)
    _, q0, v0, reference = gvi_free_body("matrix")
    traj = integrate(system, q0, v0)
    Rs = traj.q[:, 3:].reshape(-1, 3, 3)
    assert np.abs(Rs.transpose(0, 2, 1) @ Rs - np.eye(3)).max() < 1e-13
    assert 1e-13 < np.abs(traj.q - reference.q).max() < 1e-7


def test_partial_orthogonality_constraints_are_refused():
    def column_norms(r):
        R = sp.Matrix(3, 3, r)
        return [R[:, j].dot(R[:, j]) - 1 for j in range(3)]

    lm, _ = free_body("matrix", hol_coneqs=column_norms)
    with pytest.raises(ValueError, match="state all of them"):
        gvi.LagrangianSystem.from_lagranges_method(lm)


# ----------------------------------------------------------------- angles, errors
def test_euler_angles_convert_as_before():
    a = me.dynamicsymbols("a b c")
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_body_fixed(N, a, "123")
    origin = me.Point("O")
    origin.set_vel(N, 0)
    body = me.RigidBody("b", origin, B, 1, (me.inertia(B, *MOMENTS), origin))
    L = me.Lagrangian(N, body)
    lm = me.LagrangesMethod(L, a, bodies=[body], frame=N)
    assert mechanics_rotations(lm) == ()
    system = gvi.LagrangianSystem.from_lagranges_method(lm)
    assert system.m == 0
    assert system.L == to_plain_symbols(L, a).L


def body_on(orientation, r):
    N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    B.orient_explicit(N, orientation)
    origin = me.Point("O")
    origin.set_vel(N, 0)
    body = me.RigidBody("b", origin, B, 1, (me.inertia(B, *MOMENTS), origin))
    return me.LagrangesMethod(me.Lagrangian(N, body), r, bodies=[body], frame=N)


def test_orientation_by_an_unrecognised_homogeneous_polynomial_is_refused():
    r = me.dynamicsymbols("r1:6")
    D = sp.Matrix([[r[0], r[1], 0], [r[2], r[3], 0], [0, 0, r[4]]])
    with pytest.raises(ValueError, match="neither a quaternion"):
        gvi.LagrangianSystem.from_lagranges_method(body_on(D, r))


def test_linearised_rotation_converts_as_before():
    """I + hat(theta) in three small angles: not an embedding, nothing is added."""
    r = me.dynamicsymbols("a b c")
    D = sp.Matrix([[1, -r[2], r[1]], [r[2], 1, -r[0]], [-r[1], r[0], 1]])
    lm = body_on(D, r)
    assert mechanics_rotations(lm) == ()
    system = gvi.LagrangianSystem.from_lagranges_method(lm)
    assert system.m == 0
    assert system.L == to_plain_symbols(lm.bodies[0].kinetic_energy(lm.inertial), r).L


def test_explicit_quaternion_must_list_coordinates():
    lm, e = free_body("quaternion")
    other = me.dynamicsymbols("w")
    with pytest.raises(ValueError, match=r"quaternions\[0\] holds w\(t\), which is not"):
        gvi.LagrangianSystem.from_lagranges_method(lm, quaternions=[(e[0], e[1], e[2], other)])
    with pytest.raises(ValueError, match=r"direction_cosines\[0\] must be a 3x3"):
        gvi.LagrangianSystem.from_lagranges_method(lm, direction_cosines=[sp.Matrix(e)])
