"""Rigid bodies and multibody systems (:mod:`galerkin_vi.multibody`).

Closed forms and defining properties: the rotation helpers against SciPy, the
kinetic energy on the manifold and the regularity of the quaternion
augmentation, Noether's momenta of free bodies to round-off, the degrees of
freedom each joint leaves, consistent initial states, loads (linear growth of
momentum under constant forces and torques), contacts (restitution, a die at
rest, an exchange of velocities) and every run option on a heavy top.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

import galerkin_vi as gvi
from galerkin_vi.rotations import (
    body_rates_matrix,
    hat,
    matrix_to_quaternion,
    quaternion_rate,
    quaternion_to_matrix,
    space_rates_matrix,
)

RNG_SEED = 29
GRAVITY = [0.0, 0.0, -9.81]


# ------------------------------------------------------------------ helpers
def random_rotations(n: int, seed: int = RNG_SEED) -> np.ndarray:
    return Rotation.random(n, random_state=seed).as_matrix()


def rot_x(a: float) -> np.ndarray:
    return Rotation.from_rotvec([a, 0.0, 0.0]).as_matrix()


def rot_y(a: float) -> np.ndarray:
    return Rotation.from_rotvec([0.0, a, 0.0]).as_matrix()


def scalar_first(quat_xyzw: np.ndarray) -> np.ndarray:
    return np.roll(quat_xyzw, 1, axis=-1)


def numeric(expr, symbols):
    return sp.lambdify(list(symbols), expr, "numpy")


def relative_spread(x: np.ndarray) -> float:
    return float(np.abs(x - x[0]).max() / max(np.abs(x).max(), 1e-300))


def symplectic_form(n: int) -> np.ndarray:
    return np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])


def points_of(motion: gvi.BodyMotion, r_body) -> np.ndarray:
    return motion.position + motion.rotation @ np.asarray(r_body, dtype=float)


# ------------------------------------------------------------------ 1. rotation helpers
def test_quaternion_to_matrix_agrees_with_scipy():
    rot = Rotation.random(50, random_state=RNG_SEED)
    e = scalar_first(rot.as_quat())
    np.testing.assert_allclose(quaternion_to_matrix(e), rot.as_matrix(), atol=1e-14)
    # normalised first: a scaled quaternion is the same rotation
    np.testing.assert_allclose(quaternion_to_matrix(3.0 * e), rot.as_matrix(), atol=1e-14)
    # vectorised over leading axes
    assert quaternion_to_matrix(e.reshape(5, 10, 4)).shape == (5, 10, 3, 3)


def test_matrix_to_quaternion_agrees_with_scipy_on_every_branch():
    # random rotations, and half turns about each axis and near them (the trace is -1 there,
    # so each diagonal branch of Shepperd's method is taken)
    R = list(random_rotations(50))
    for axis in np.eye(3):
        for angle in (np.pi, np.pi - 1e-3):
            R.append(Rotation.from_rotvec(angle * axis).as_matrix())
    R = np.array(R)
    e = matrix_to_quaternion(R)
    expected = scalar_first(Rotation.from_matrix(R).as_quat())
    expected *= np.where(expected[:, :1] < 0, -1.0, 1.0)
    sign = np.sign(np.sum(e * expected, axis=1))[:, None]  # e0 = 0 leaves the sign free
    np.testing.assert_allclose(e, sign * expected, atol=1e-14)
    assert np.all(e[:, 0] >= 0)
    np.testing.assert_allclose(quaternion_to_matrix(e), R, atol=1e-14)
    assert matrix_to_quaternion(R.reshape(4, -1, 3, 3)).shape == (4, R.shape[0] // 4, 4)


def test_quaternion_rate_inverts_G_and_E_and_is_the_derivative_of_R():
    e = sp.symbols("e0:4")
    G, E = numeric(body_rates_matrix(e), e), numeric(space_rates_matrix(e), e)
    rng = np.random.default_rng(RNG_SEED)
    for R in random_rotations(10):
        q = matrix_to_quaternion(R)
        w = rng.normal(size=3)
        qd = quaternion_rate(q, w, "body")
        qd_space = quaternion_rate(q, R @ w, "space")
        np.testing.assert_allclose(2 * np.array(G(*q)) @ qd, w, atol=1e-14)
        np.testing.assert_allclose(2 * np.array(E(*q)) @ qd, R @ w, atol=1e-14)
        np.testing.assert_allclose(qd_space, qd, atol=1e-14)
        assert abs(q @ qd) < 1e-15
        # dR/dt = R hat(w) along e(t) with e' = quaternion_rate(e, w)
        eps = 1e-5
        dR = (quaternion_to_matrix(q + eps * qd) - quaternion_to_matrix(q - eps * qd)) / (2 * eps)
        np.testing.assert_allclose(dR, R @ hat(w), atol=1e-9)


def test_hat_is_the_cross_product():
    rng = np.random.default_rng(RNG_SEED)
    w, r = rng.normal(size=(2, 7, 3))
    W = hat(w)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", W, r), np.cross(w, r), atol=1e-15)
    np.testing.assert_array_equal(W, -np.swapaxes(W, 1, 2))


# ------------------------------------------------------------------ 2. RigidBody
def full_inertia(moments=(1.0, 2.0, 2.5)) -> np.ndarray:
    Q = random_rotations(1, seed=3)[0]
    return Q @ np.diag(moments) @ Q.T


@pytest.mark.parametrize("rotation", ["quaternion", "matrix"])
@pytest.mark.parametrize("tensor", [False, True])
def test_kinetic_energy_on_the_manifold_is_translation_plus_rotation(rotation, tensor):
    J = full_inertia() if tensor else np.diag([1.0, 2.0, 2.5])
    body = gvi.RigidBody("b", mass=1.5, inertia=J if tensor else [1.0, 2.0, 2.5], rotation=rotation)
    T = numeric(body.kinetic_energy, body.q + body.v)
    omega = numeric(body.angular_velocity, body.q + body.v)
    rng = np.random.default_rng(RNG_SEED)
    for R in random_rotations(8):
        x, xd, w = rng.normal(size=(3, 3))
        q = body.coordinates_of(x, R)
        v = body.velocities_of(q, xd, w, "body")
        expected = 0.75 * xd @ xd + 0.5 * w @ J @ w
        assert T(*q, *v) == pytest.approx(expected, rel=1e-13)
        np.testing.assert_allclose(np.ravel(omega(*q, *v)), w, atol=1e-13)


@pytest.mark.parametrize("tensor", [False, True])
def test_quaternion_augmentation_makes_the_mass_matrix_regular_with_eigenvalues_4J_and_c(tensor):
    J = full_inertia() if tensor else np.diag([1.0, 2.0, 2.5])
    body = gvi.RigidBody("b", mass=1.0, inertia=J, rotation="quaternion")
    rd = body.v[3:]
    Lvv = numeric(sp.hessian(body.kinetic_energy, rd), body.q)
    c = 4.0 / 3.0 * np.trace(J)
    expected = np.sort(np.r_[4 * np.linalg.eigvalsh(J), c])
    for R in random_rotations(6):
        q = body.coordinates_of(np.zeros(3), R)
        eig = np.linalg.eigvalsh(np.array(Lvv(*q), dtype=float))
        np.testing.assert_allclose(eig, expected, rtol=1e-13)


def test_flat_plate_in_matrix_form_is_augmented_and_integrates():
    plate = gvi.RigidBody("plate", mass=1.0, inertia=[1.0, 2.0, 3.0], rotation="matrix")
    assert plate.needs_augmentation
    Lvv = numeric(sp.hessian(plate.kinetic_energy, plate.v[3:]), plate.q)
    R = random_rotations(1)[0]
    mass_matrix = np.array(Lvv(*plate.coordinates_of(np.zeros(3), R)), dtype=float)
    assert np.linalg.eigvalsh(mass_matrix).min() > 0.1
    # the same plate, its tensor given in a rotated frame (J3 = J1 + J2 up to round-off)
    gvi.RigidBody("tilted", mass=1.0, inertia=full_inertia((1.0, 2.0, 3.0)), rotation="matrix")
    mb = gvi.Multibody([plate])
    q0, v0 = mb.state(rotations={"plate": R}, angular_velocities={"plate": [0.3, 1.0, 0.5]})
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.01, n_steps=300)
    assert traj.success
    assert traj.constraint_residual().max() < 1e-14
    assert relative_spread(traj.energy()) < 1e-9
    for axis in np.eye(3):
        assert relative_spread(traj.momentum(mb.angular_momentum(axis).xi)) < 1e-12


@pytest.mark.parametrize(
    "kwargs, match",
    [
        (dict(rotation="euler"), "rotation must be one of"),
        (dict(mass=-1.0), "mass must be > 0"),
        (dict(mass=0.0), "mass must be > 0"),
        (dict(inertia=[[1, 0.1, 0], [0, 1, 0], [0, 0, 1]]), "symmetric"),
        (dict(inertia=[-1.0, 2.0, 2.0]), "positive definite"),
        (dict(inertia=[1.0, 1.0, 5.0]), "triangle inequality"),
        (dict(inertia=[1.0, 2.0]), "3 principal moments"),
        (dict(name="2b"), "identifier"),
        (dict(name="a b"), "identifier"),
    ],
)
def test_bad_bodies_are_refused_with_a_clear_message(kwargs, match):
    args = dict(name="b", mass=1.0, inertia=[1.0, 2.0, 2.5], rotation="quaternion") | kwargs
    with pytest.raises(ValueError, match=match):
        gvi.RigidBody(**args)


def test_a_body_with_symbolic_mass_and_inertia_takes_its_values_from_params():
    m, j1, j2, j3, t = sp.symbols("m j1 j2 j3 t")
    body = gvi.RigidBody("b", mass=m, inertia=[j1, j2, j3], rotation="matrix")
    assert body.needs_augmentation  # the triangle inequality is unknown for symbols
    torque = gvi.BodyForce(body, torque=[0, 0, sp.sin(t)])
    values = {m: 2.0, j1: 1.0, j2: 2.0, j3: 2.5}
    mb = gvi.Multibody([body], gravity=GRAVITY, forces=[torque], params=values, t=t)
    q0, v0 = mb.state(rotations={"b": FREE_R0}, angular_velocities={"b": FREE_W0})
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(2))
    traj = integrator.integrate(q0, v0=v0, h=0.01, n_steps=300)
    assert traj.constraint_residual().max() <= 1e-14
    # L_z grows by the integral of the torque, 1 - cos t; gravity along z exerts none about z
    L = traj.momentum(mb.angular_momentum([0, 0, 1]).xi)
    np.testing.assert_allclose(L - L[0], 1 - np.cos(traj.t), atol=1e-10)
    # the rotational energy J w . w / 2 with the parameter values, against a run with other ones
    heavier = integrator.integrate(q0, v0=v0, h=0.01, n_steps=1, params={j3: 5.0})
    w = mb.motion(heavier, "b").angular_velocity[0]
    omega_b = np.ravel(FREE_W0)
    np.testing.assert_allclose(w, omega_b, atol=1e-13)
    assert heavier.p[0, 3:] @ heavier.velocities()[0, 3:] == pytest.approx(
        omega_b @ np.diag([1.0, 2.0, 5.0]) @ omega_b, rel=1e-12
    )


# ------------------------------------------------------------------ 3. free bodies
FREE_W0 = np.array([0.4, 1.2, -0.6])
FREE_R0 = rot_x(0.3) @ rot_y(-0.7)
FREE_X0, FREE_XD0 = np.array([0.1, -0.2, 0.3]), np.array([0.5, -0.25, 1.0])


def free_body(rotation: str):
    body = gvi.RigidBody("b", mass=2.0, inertia=[1.0, 2.0, 2.5], rotation=rotation)
    mb = gvi.Multibody([body])
    q0, v0 = mb.state(
        positions={"b": FREE_X0}, rotations={"b": FREE_R0}, velocities={"b": FREE_XD0},
        angular_velocities={"b": FREE_W0},
    )  # fmt: skip
    return mb, gvi.Integrator(mb.system, gvi.Galerkin(2)), q0, v0


@pytest.fixture(scope="module", params=["quaternion", "matrix"])
def free_run(request):
    mb, integrator, q0, v0 = free_body(request.param)
    traj = integrator.integrate(q0, v0=v0, h=0.01, n_steps=2000)
    assert traj.success
    return mb, traj


def test_free_body_conserves_the_space_angular_momentum_to_round_off(free_run):
    mb, traj = free_run
    L = np.stack([traj.momentum(mb.angular_momentum(axis).xi) for axis in np.eye(3)], axis=1)
    size = np.linalg.norm(L[0])
    assert size > 1.0
    assert np.abs(L - L[0]).max() <= 1e-12 * size


def test_free_body_energy_is_bounded_and_the_body_momentum_norm_constant(free_run):
    mb, traj = free_run
    E = traj.energy()
    assert relative_spread(E) < 1e-8
    motion = mb.motion(traj, "b")
    M = motion.angular_velocity * np.array([1.0, 2.0, 2.5])
    norm = np.linalg.norm(M, axis=1)
    assert relative_spread(norm) < 1e-12
    # the body momentum is the space one about the centre of mass, carried by R^T
    L_space = np.stack(
        [traj.momentum(mb.angular_momentum(a).xi) for a in np.eye(3)], axis=1
    ) - 2.0 * np.cross(motion.position, motion.velocity)
    np.testing.assert_allclose(np.einsum("kij,kj->ki", motion.rotation, M), L_space, atol=1e-12)


def test_body_frame_momentum_is_the_body_angular_momentum(free_run):
    mb, traj = free_run
    motion = mb.motion(traj, "b")
    M = motion.angular_velocity * np.array([1.0, 2.0, 2.5])
    for k, axis in enumerate(np.eye(3)):
        about = traj.momentum(mb.angular_momentum(axis, body="b", frame="body").xi)
        np.testing.assert_allclose(about, M[:, k], atol=1e-12)
    with pytest.raises(ValueError, match="needs the body"):
        mb.angular_momentum([0, 0, 1], frame="body")


def test_free_body_stays_on_its_constraints_and_its_centre_moves_uniformly(free_run):
    mb, traj = free_run
    assert traj.constraint_residual().max() <= 1e-14
    motion = mb.motion(traj, "b")
    np.testing.assert_allclose(motion.position, FREE_X0 + np.outer(traj.t, FREE_XD0), atol=1e-12)
    np.testing.assert_allclose(motion.velocity, np.broadcast_to(FREE_XD0, (len(traj.t), 3)),
                               atol=1e-13)  # fmt: skip
    det = np.linalg.det(motion.rotation)
    np.testing.assert_allclose(det, 1.0, atol=1e-14)


def test_quaternion_and_matrix_give_the_same_rotation_at_the_order_2s():
    runs = {rotation: free_body(rotation) for rotation in ("quaternion", "matrix")}
    T = 2.0
    errors = []
    for h in (0.1, 0.05):
        R = {}
        for rotation, (mb, integrator, q0, v0) in runs.items():
            traj = integrator.integrate(q0, v0=v0, h=h, n_steps=round(T / h))
            R[rotation] = mb.motion(traj, "b").rotation
        errors.append(np.abs(R["quaternion"] - R["matrix"]).max())
    order = np.log2(errors[0] / errors[1])
    assert errors[1] < 1e-5
    assert abs(order - 4) <= 0.5, (errors, order)


# ------------------------------------------------------------------ 4. joints
def chain_system():
    """Hinges, a Cardan joint and a ball joint, to the ground and between bodies, mixed
    rotation coordinates, under gravity."""
    h1 = gvi.RigidBody("h1", mass=1.0, inertia=[0.3, 0.2, 0.15], rotation="quaternion")
    h2 = gvi.RigidBody("h2", mass=0.8, inertia=[0.2, 0.3, 0.15], rotation="matrix")
    u1 = gvi.RigidBody("u1", mass=0.6, inertia=[0.1, 0.12, 0.05], rotation="quaternion")
    s1 = gvi.RigidBody("s1", mass=0.5, inertia=[0.05, 0.06, 0.07], rotation="matrix")
    u0 = gvi.RigidBody("u0", mass=0.7, inertia=[0.1, 0.1, 0.05], rotation="matrix")
    s0 = gvi.RigidBody("s0", mass=0.9, inertia=[0.2, 0.25, 0.1], rotation="quaternion")
    J = gvi.joints
    joints = [
        J.Revolute(None, h1, point_a=[0, 0, 0], point_b=[0, 0, 0.5], axis_a=[1, 0, 0]),
        J.Revolute(h1, h2, point_a=[0, 0, -0.5], point_b=[0, 0, 0.5], axis_a=[0, 1, 0]),
        J.Universal(h2, u1, point_a=[0, 0, -0.5], point_b=[0, 0, 0.4], axis_a=[1, 0, 0],
                    axis_b=[0, 1, 0]),
        J.Spherical(u1, s1, point_a=[0, 0, -0.4], point_b=[0.1, 0, 0.3]),
        J.Universal(None, u0, point_a=[2, 0, 0], point_b=[0, 0, 0.5], axis_a=[1, 0, 0],
                    axis_b=[0, 1, 0]),
        J.Spherical(None, s0, point_a=[-2, 0, 0], point_b=[0, 0.2, 0.5]),
    ]  # fmt: skip
    mb = gvi.Multibody([h1, h2, u1, s1, u0, s0], joints=joints, gravity=GRAVITY)
    R1 = rot_x(0.4)
    R2 = R1 @ rot_y(0.3)
    q0, v0 = mb.state(
        rotations={"h1": R1, "h2": R2, "u1": R2 @ rot_x(0.2), "s1": random_rotations(1)[0],
                   "u0": rot_x(0.3) @ rot_y(0.2), "s0": rot_y(0.5)},
        angular_velocities={"h1": [1.0, 0, 0], "h2": [1.0, 0.8, 0], "u1": [0.5, 1.0, 0.3],
                            "s1": [0.3, -0.5, 2.0], "u0": [0.5, 1.0, 0.0], "s0": [1.0, 0.5, 3.0]},
        frame="space",
    )  # fmt: skip
    return mb, q0, v0


def slide_weld_system():
    """Prismatic and fixed joints, to the ground and between bodies, under gravity."""
    p1 = gvi.RigidBody("p1", mass=1.0, inertia=[0.3, 0.2, 0.15], rotation="quaternion")
    p2 = gvi.RigidBody("p2", mass=0.5, inertia=[0.1, 0.2, 0.15], rotation="matrix")
    f0 = gvi.RigidBody("f0", mass=1.0, inertia=[0.1, 0.1, 0.1], rotation="matrix")
    f1 = gvi.RigidBody("f1", mass=1.0, inertia=[0.3, 0.2, 0.15], rotation="quaternion")
    f2 = gvi.RigidBody("f2", mass=2.0, inertia=[0.2, 0.4, 0.3], rotation="matrix")
    C = rot_x(0.5) @ rot_y(0.2)
    J = gvi.joints
    joints = [
        J.Prismatic(None, p1, point_a=[0, 0, 0], point_b=[0, 0, 0], axis=[1, 0, 1],
                    rotation=rot_y(0.3)),
        J.Prismatic(p1, p2, point_a=[0, 0.3, 0], point_b=[0, 0, 0], axis=[0, 1, 1]),
        J.Fixed(None, f0, point_a=[0, -2, 0], point_b=[0.1, 0.2, 0.3], rotation=rot_x(-0.2)),
        J.Fixed(f1, f2, point_a=[0.5, 0, 0], point_b=[-0.5, 0.1, 0], rotation=C),
    ]  # fmt: skip
    mb = gvi.Multibody([p1, p2, f0, f1, f2], joints=joints, gravity=GRAVITY)
    Rf1 = random_rotations(1, seed=5)[0]
    ws = np.array([0.7, -1.5, 2.0])
    q0, v0 = mb.state(
        positions={"p1": [0.2, 0.0, 0.2], "p2": [0.2, 0.5, 0.7], "f1": [0, 3, 1]},
        rotations={"p1": rot_y(0.3), "p2": rot_y(0.3), "f0": rot_x(-0.2), "f1": Rf1,
                   "f2": Rf1 @ C},
        velocities={"p1": [0.5, 0, 0.5], "p2": [0.5, 0.3, 0.8], "f1": [1.0, 0.0, 2.0]},
        angular_velocities={"f1": ws, "f2": ws},
        frame="space",
    )  # fmt: skip
    return mb, q0, v0, C


@pytest.fixture(scope="module")
def chain_run():
    mb, q0, v0 = chain_system()
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.005, n_steps=400)
    assert traj.success
    return mb, traj


@pytest.fixture(scope="module")
def slide_weld_run():
    mb, q0, v0, C = slide_weld_system()
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.005, n_steps=400)
    assert traj.success
    return mb, traj, C


@pytest.mark.parametrize("name", ["chain_run", "slide_weld_run"])
def test_joints_hold_to_round_off_and_energy_is_conserved(name, request):
    mb, traj = request.getfixturevalue(name)[:2]
    assert traj.constraint_residual().max() <= 1e-13
    assert traj.hidden_constraint_residual().max() <= 1e-10
    E = traj.energy()
    assert relative_spread(E) < 1e-7
    # the run moves: gravity does work on the bodies
    assert np.ptp(traj.q, axis=0).max() > 0.05


def test_revolute_joints_leave_rotation_about_the_hinge_only(chain_run):
    mb, traj = chain_run
    h1, h2 = mb.motion(traj, "h1"), mb.motion(traj, "h2")
    # to the ground: omega_s along the space x axis, the hinge point at the origin
    np.testing.assert_allclose(h1.angular_velocity_space[:, 1:], 0.0, atol=1e-11)
    assert np.abs(h1.angular_velocity_space[:, 0]).max() > 0.5
    np.testing.assert_allclose(points_of(h1, [0, 0, 0.5]), 0.0, atol=1e-13)
    # between bodies: the relative angular velocity along h1's y axis, which h2's y axis keeps
    axis = h1.rotation[:, :, 1]
    relative = h2.angular_velocity_space - h1.angular_velocity_space
    np.testing.assert_allclose(np.cross(relative, axis), 0.0, atol=1e-11)
    np.testing.assert_allclose(h2.rotation[:, :, 1], axis, atol=1e-13)
    assert np.abs(np.sum(relative * axis, axis=1)).max() > 0.1
    np.testing.assert_allclose(points_of(h1, [0, 0, -0.5]), points_of(h2, [0, 0, 0.5]),
                               atol=1e-13)  # fmt: skip


def test_universal_joints_keep_their_axes_perpendicular(chain_run):
    mb, traj = chain_run
    h2, u1, u0 = (mb.motion(traj, n) for n in ("h2", "u1", "u0"))
    dot = np.sum(h2.rotation[:, :, 0] * u1.rotation[:, :, 1], axis=1)
    np.testing.assert_allclose(dot, 0.0, atol=1e-13)
    np.testing.assert_allclose(u0.rotation[:, 0, 1], 0.0, atol=1e-13)  # x . (R e_y) = 0
    np.testing.assert_allclose(points_of(h2, [0, 0, -0.5]), points_of(u1, [0, 0, 0.4]),
                               atol=1e-13)  # fmt: skip
    np.testing.assert_allclose(points_of(u0, [0, 0, 0.5]), np.broadcast_to([2.0, 0, 0], (401, 3)),
                               atol=1e-13)  # fmt: skip
    # two degrees of freedom left: the relative rotation is not about one fixed axis
    relative = u1.angular_velocity_space - h2.angular_velocity_space
    assert np.linalg.matrix_rank(relative[::50], tol=1e-3) >= 2


def test_spherical_joints_keep_the_points_together(chain_run):
    mb, traj = chain_run
    u1, s1, s0 = (mb.motion(traj, n) for n in ("u1", "s1", "s0"))
    np.testing.assert_allclose(points_of(u1, [0, 0, -0.4]), points_of(s1, [0.1, 0, 0.3]),
                               atol=1e-13)  # fmt: skip
    np.testing.assert_allclose(points_of(s0, [0, 0.2, 0.5]),
                               np.broadcast_to([-2.0, 0, 0], (401, 3)), atol=1e-13)  # fmt: skip


def test_prismatic_joints_slide_without_rotating(slide_weld_run):
    mb, traj, _ = slide_weld_run
    p1, p2 = mb.motion(traj, "p1"), mb.motion(traj, "p2")
    np.testing.assert_allclose(p1.rotation, np.broadcast_to(rot_y(0.3), (401, 3, 3)), atol=1e-13)
    np.testing.assert_allclose(p2.rotation, p1.rotation, atol=1e-13)
    # to the ground: the point moves along the space axis (1, 0, 1) only
    axis = np.array([1.0, 0, 1.0]) / np.sqrt(2)
    x = p1.position
    np.testing.assert_allclose(x - np.outer(x @ axis, axis), 0.0, atol=1e-13)
    assert np.ptp(x @ axis) > 0.1
    # between bodies: the separation along p1's body axis (0, 1, 1)
    d = p2.position - points_of(p1, [0, 0.3, 0])
    axis_a = p1.rotation @ (np.array([0.0, 1.0, 1.0]) / np.sqrt(2))
    np.testing.assert_allclose(np.cross(d, axis_a), 0.0, atol=1e-13)
    assert np.ptp(np.sum(d * axis_a, axis=1)) > 0.01


def test_fixed_joints_move_the_pair_as_one_body(slide_weld_run):
    mb, traj, C = slide_weld_run
    f0, f1, f2 = (mb.motion(traj, n) for n in ("f0", "f1", "f2"))
    np.testing.assert_allclose(f0.rotation, np.broadcast_to(rot_x(-0.2), (401, 3, 3)), atol=1e-13)
    np.testing.assert_allclose(points_of(f0, [0.1, 0.2, 0.3]),
                               np.broadcast_to([0, -2.0, 0], (401, 3)), atol=1e-13)  # fmt: skip
    relative = np.einsum("kji,kjl->kil", f1.rotation, f2.rotation)
    np.testing.assert_allclose(relative, np.broadcast_to(C, (401, 3, 3)), atol=1e-13)
    offset = np.einsum("kji,kj->ki", f1.rotation, f2.position - f1.position)
    np.testing.assert_allclose(offset, offset[:1].repeat(401, 0), atol=1e-13)
    np.testing.assert_allclose(f1.angular_velocity_space, f2.angular_velocity_space, atol=1e-11)
    assert np.ptp(f1.rotation, axis=0).max() > 0.5  # the pair tumbles


# ------------------------------------------------------------------ 5. Multibody.state
def three_link_chain():
    links = [gvi.RigidBody(f"l{i}", mass=1.0, inertia=[0.1, 0.1, 0.02],
                           rotation=("quaternion", "matrix")[i % 2]) for i in range(3)]  # fmt: skip
    joints = [gvi.joints.Spherical(None, links[0], point_b=[0, 0, 0.5])]
    joints += [gvi.joints.Spherical(a, b, point_a=[0, 0, -0.5], point_b=[0, 0, 0.5])
               for a, b in zip(links, links[1:], strict=False)]  # fmt: skip
    return gvi.Multibody(links, joints=joints, gravity=GRAVITY)


@pytest.fixture(scope="module")
def chain3():
    return three_link_chain()


def test_state_places_a_chain_through_its_joints(chain3):
    mb = chain3
    R = dict(zip(("l0", "l1", "l2"), random_rotations(3, seed=11), strict=True))
    W = dict(zip(("l0", "l1", "l2"), np.random.default_rng(1).normal(size=(3, 3)), strict=True))
    q0, v0 = mb.state(rotations=R, angular_velocities=W, frame="space", project=False)
    system = mb.system
    assert np.abs(system.constraint_values(q0)).max() <= 1e-12
    assert np.abs(system.constraint_jacobian(q0) @ v0).max() <= 1e-12
    # the joint points by hand, and the angular velocities read back
    tip = np.zeros(3)
    for name in ("l0", "l1", "l2"):
        x = q0[mb.coordinates(name)][:3]
        np.testing.assert_allclose(x + R[name] @ [0, 0, 0.5], tip, atol=1e-14)
        tip = x - R[name] @ [0, 0, 0.5]
    q_rows, v_rows = q0[None], v0[None]
    for name in ("l0", "l1", "l2"):
        sl = mb.coordinates(name)
        motion = gvi.multibody.motion.body_motion(mb.bodies[name], [0.0], q_rows[:, sl],
                                                  v_rows[:, sl])  # fmt: skip
        np.testing.assert_allclose(motion.angular_velocity_space[0], W[name], atol=1e-13)
        np.testing.assert_allclose(motion.rotation[0], R[name], atol=1e-14)

    # velocities of the joined points agree
    def point_velocity(name, r):
        sl = mb.coordinates(name)
        body = mb.bodies[name]
        f = numeric(body.point_velocity(r), body.q + body.v)
        return np.ravel(f(*q0[sl], *v0[sl]))

    np.testing.assert_allclose(point_velocity("l0", [0, 0, 0.5]), 0.0, atol=1e-14)
    np.testing.assert_allclose(point_velocity("l0", [0, 0, -0.5]),
                               point_velocity("l1", [0, 0, 0.5]), atol=1e-13)  # fmt: skip


def test_state_in_the_space_and_body_frames_agree(chain3):
    R = dict(zip(("l0", "l1", "l2"), random_rotations(3, seed=12), strict=True))
    W = dict(zip(("l0", "l1", "l2"), np.random.default_rng(2).normal(size=(3, 3)), strict=True))
    body = chain3.state(rotations=R, angular_velocities=W, frame="body")
    space = chain3.state(rotations=R, angular_velocities={n: R[n] @ W[n] for n in W},
                         frame="space")  # fmt: skip
    for a, b in zip(body, space, strict=True):
        np.testing.assert_allclose(a, b, atol=1e-14)


def test_state_refuses_inconsistent_data_and_unknown_names(chain3):
    with pytest.raises(ValueError):
        chain3.state(positions={"l1": [5.0, 0.0, 0.0]}, project=False)
    # projected instead, the joints hold
    q0, _ = chain3.state(positions={"l1": [0.2, 0.0, -1.4]})
    assert np.abs(chain3.system.constraint_values(q0)).max() <= 1e-12
    for kwargs in (
        dict(positions={"nobody": [0, 0, 0]}),
        dict(rotations={"l9": np.eye(3)}),
        dict(velocities={"x": [0, 0, 0]}),
        dict(angular_velocities={"y": [0, 0, 1]}),
    ):
        with pytest.raises(KeyError, match="no body named"):
            chain3.state(**kwargs)
    with pytest.raises(KeyError):
        chain3.coordinates("nobody")
    with pytest.raises(ValueError, match="frame"):
        chain3.state(frame="world")
    with pytest.raises(ValueError, match="unit norm"):
        chain3.state(rotations={"l0": [1.0, 1.0, 0.0, 0.0]})
    with pytest.raises(ValueError, match="proper rotation"):
        chain3.state(rotations={"l1": -np.eye(3)})


# ------------------------------------------------------------------ 6. loads
@pytest.mark.parametrize("rotation", ["quaternion", "matrix"])
def test_a_constant_torque_makes_the_angular_momentum_grow_linearly(rotation):
    tau = np.array([0.0, 0.0, 0.7])
    body = gvi.RigidBody("b", mass=1.0, inertia=[1.0, 2.0, 2.5], rotation=rotation)
    mb = gvi.Multibody([body], forces=[gvi.BodyForce(body, torque=tau)])
    q0, v0 = mb.state(rotations={"b": FREE_R0}, angular_velocities={"b": FREE_W0})
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.01, n_steps=500)
    assert traj.success
    for axis, rate in zip(np.eye(3), tau, strict=True):
        L = traj.momentum(mb.angular_momentum(axis).xi)
        np.testing.assert_allclose(L - L[0], rate * traj.t, atol=1e-10)


def test_a_force_at_an_offset_point_gives_a_force_and_a_torque():
    F, r = np.array([0.3, -0.2, 0.5]), np.array([0.2, 0.1, -0.3])
    body = gvi.RigidBody("b", mass=2.0, inertia=[1.0, 2.0, 2.5])
    mb = gvi.Multibody([body], forces=[gvi.BodyForce(body, force=F, point=r)])
    q0, v0 = mb.state(rotations={"b": FREE_R0}, angular_velocities={"b": FREE_W0},
                      velocities={"b": FREE_XD0})  # fmt: skip
    traj = gvi.Integrator(mb.system, gvi.Galerkin(3)).integrate(q0, v0=v0, h=0.01, n_steps=200)
    assert traj.success
    for axis, f in zip(np.eye(3), F, strict=True):
        P = traj.momentum(mb.linear_momentum(axis).xi)
        np.testing.assert_allclose(P - P[0], f * traj.t, atol=1e-12)
    # dL/dt = x_P x F, integrated by Simpson's rule over the saved rows
    lever = np.cross(points_of(mb.motion(traj, "b"), r), F)
    h = traj.t[1] - traj.t[0]
    simpson = h / 3 * (lever[0] + 4 * lever[1:-1:2].sum(0) + 2 * lever[2:-1:2].sum(0) + lever[-1])
    L = np.array([traj.momentum(mb.angular_momentum(a).xi) for a in np.eye(3)])
    np.testing.assert_allclose(L[:, -1] - L[:, 0], simpson, atol=1e-8)
    assert np.abs(simpson).max() > 0.1


def test_a_damping_torque_decays_the_energy_monotonically():
    body = gvi.RigidBody("b", mass=1.0, inertia=[1.0, 2.0, 2.5])
    damping = gvi.BodyForce(body, torque=-0.3 * body.angular_velocity_space)
    mb = gvi.Multibody([body], forces=[damping])
    q0, v0 = mb.state(rotations={"b": FREE_R0}, angular_velocities={"b": FREE_W0})
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.01, n_steps=500)
    E = traj.energy()
    assert np.all(np.diff(E) < 0)
    # the rate: dE/dt = -c |omega_s|^2
    ws = mb.motion(traj, "b").angular_velocity_space
    rate = -0.3 * np.sum(ws**2, axis=1)
    np.testing.assert_allclose(np.gradient(E, traj.t)[1:-1], rate[1:-1], rtol=1e-3)


# ------------------------------------------------------------------ 7. contacts
def test_a_sphere_bounces_to_e_squared_times_its_height():
    e, radius, h0, g = 0.6, 0.1, 1.0, 9.81
    ball = gvi.RigidBody("ball", mass=1.0, inertia=[0.004, 0.004, 0.004])
    floor = gvi.BodyContact(gvi.Sphere(ball, radius), gvi.Plane([0, 0, 1], 0.0), restitution=e)
    mb = gvi.Multibody([ball], gravity=[0, 0, -g], contacts=[floor])
    q0, v0 = mb.state(positions={"ball": [0, 0, radius + h0]},
                      angular_velocities={"ball": [0.0, 0.0, 1.0]})  # fmt: skip
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.01, n_steps=80)
    assert traj.success
    motion = mb.motion(traj, "ball")
    apex = motion.position[:, 2] - radius + motion.velocity[:, 2] ** 2 / (2 * g)
    after = motion.velocity[:, 2] > 0
    assert after.any() and (~after).any()
    np.testing.assert_allclose(apex[~after & (traj.t < 0.3)], h0, atol=1e-8)
    np.testing.assert_allclose(apex[after], e**2 * h0, atol=1e-8)
    # frictionless: the spin about the vertical is untouched
    np.testing.assert_allclose(motion.angular_velocity_space[:, 2], 1.0, atol=1e-10)


def test_equal_spheres_in_an_elastic_head_on_collision_exchange_velocities():
    a = gvi.RigidBody("a", mass=1.0, inertia=[0.01, 0.01, 0.01])
    b = gvi.RigidBody("b", mass=1.0, inertia=[0.01, 0.01, 0.01], rotation="matrix")
    hit = gvi.BodyContact(gvi.Sphere(a, 0.2), gvi.Sphere(b, 0.2), restitution=1.0)
    mb = gvi.Multibody([a, b], contacts=[hit])
    q0, v0 = mb.state(positions={"a": [-1.0, 0, 0], "b": [0.0, 0, 0]},
                      velocities={"a": [1.0, 0, 0]})  # fmt: skip
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.01, n_steps=150)
    assert traj.success
    va, vb = mb.motion(traj, "a").velocity, mb.motion(traj, "b").velocity
    np.testing.assert_allclose(va[-1], [0, 0, 0], atol=1e-10)
    np.testing.assert_allclose(vb[-1], [1.0, 0, 0], atol=1e-10)
    xa, xb = mb.motion(traj, "a").position, mb.motion(traj, "b").position
    np.testing.assert_allclose(xb[-1] - xa[-1], [0.4 + (1.5 - 0.6), 0, 0], atol=1e-8)


@pytest.mark.parametrize("rotation", ["quaternion", "matrix"])
def test_a_tumbling_corner_hits_the_floor_by_newtons_law(rotation):
    e, a, m, g = 0.5, 0.05, 0.1, 9.81
    body = gvi.RigidBody("die", mass=m, inertia=[2 * m * (2 * a) ** 2 / 12] * 3, rotation=rotation)
    corner = gvi.BodyPoint(body, [a, a, a])
    floor = gvi.BodyContact(corner, gvi.Plane([0, 0, 1], 0.0), restitution=e)
    mb = gvi.Multibody([body], gravity=[0, 0, -g], contacts=[floor])
    q0, v0 = mb.state(
        positions={"die": [0, 0, 0.3]},
        rotations={"die": random_rotations(1)[0]},
        velocities={"die": [0.5, 0.2, 0.0]},
        angular_velocities={"die": [4.0, -3.0, 2.0]},
    )
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.002, n_steps=150)
    assert traj.success and traj.impacts
    first = traj.impacts[0]
    before, after = first.normal_velocity
    assert before < -0.5
    assert after == pytest.approx(-e * before, rel=1e-12)
    assert first.energy_lost > 0
    assert traj.constraint_residual().max() <= 1e-14
    # between impacts the energy is conserved; across the first, it drops by energy_lost
    E = traj.energy()
    cut = np.searchsorted(traj.t, first.t)
    assert relative_spread(E[:cut]) < 1e-9
    assert E[0] - E[cut + 1] == pytest.approx(first.energy_lost, rel=1e-6)


@pytest.mark.slow
def test_a_die_thrown_on_a_table_comes_to_rest_on_a_face():
    a, m, g = 0.05, 0.1, 9.81  # half side, mass
    die = gvi.RigidBody("die", mass=m, inertia=[2 * m * (2 * a) ** 2 / 12] * 3)
    table = gvi.Plane([0, 0, 1], 0.0)
    corners = [[sx * a, sy * a, sz * a] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
    contacts = [gvi.BodyContact(gvi.BodyPoint(die, c), table, restitution=0.3, friction=0.4)
                for c in corners]  # fmt: skip
    mb = gvi.Multibody([die], gravity=[0, 0, -g], contacts=contacts)
    q0, v0 = mb.state(positions={"die": [0, 0, 0.3]}, rotations={"die": random_rotations(1)[0]},
                      velocities={"die": [0.5, 0.2, 0.0]},
                      angular_velocities={"die": [4.0, -3.0, 2.0]})  # fmt: skip
    traj = gvi.Integrator(mb.system, gvi.Galerkin(2)).integrate(q0, v0=v0, h=0.002, n_steps=2000)
    assert traj.success
    motion = mb.motion(traj, "die")
    assert motion.position[-1, 2] == pytest.approx(a, abs=1e-8)
    assert traj.energy()[-1] == pytest.approx(m * g * a, rel=1e-6)
    np.testing.assert_allclose(np.linalg.norm(traj.q[:, 3:7], axis=1), 1.0, atol=1e-14)


# ------------------------------------------------------------------ 8. run options on a heavy top
def heavy_top():
    top = gvi.RigidBody("top", mass=1.0, inertia=[1.0, 1.0, 0.5])
    mb = gvi.Multibody([top], joints=[gvi.joints.Spherical(None, top, point_b=[0, 0, -1])],
                       gravity=GRAVITY)  # fmt: skip
    q0, v0 = mb.state(rotations={"top": rot_x(0.3)}, angular_velocities={"top": [0.5, 0, 8.0]})
    return top, mb, q0, v0


@pytest.fixture(scope="module")
def top_setup():
    top, mb, q0, v0 = heavy_top()
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(2))
    traj = integrator.integrate(q0, v0=v0, h=0.01, n_steps=200)
    assert traj.success
    return top, mb, integrator, q0, v0, traj


def test_top_conserves_its_two_noether_momenta_and_saves_every_kth_row(top_setup):
    top, mb, integrator, q0, v0, traj = top_setup
    vertical = traj.momentum(mb.angular_momentum([0, 0, 1]).xi)
    spin = traj.momentum(mb.angular_momentum([0, 0, 1], body="top", frame="body").xi)
    assert relative_spread(vertical) < 1e-12 and relative_spread(spin) < 1e-12
    every = integrator.integrate(q0, v0=v0, h=0.01, n_steps=200, save_every=7)
    rows = np.r_[np.arange(0, 201, 7), 200]
    np.testing.assert_array_equal(every.t, traj.t[rows])
    np.testing.assert_array_equal(every.q, traj.q[rows])
    spanned = integrator.integrate(q0, v0=v0, h=0.01, t_span=(0.0, 2.0))
    assert spanned.t[-1] == 2.0
    np.testing.assert_allclose(spanned.q, traj.q, atol=1e-14)


def test_top_terminal_event_on_the_nutation_angle(top_setup):
    top, mb, integrator, q0, v0, traj = top_setup
    cos_theta = top.axis([0, 0, 1])[2]
    level = float(np.cos(0.3)) - 0.01
    event = gvi.Event(cos_theta - level, terminal=True, direction=-1)
    stopped = integrator.integrate(q0, v0=v0, h=0.01, n_steps=200, events=event)
    assert stopped.success
    (t_event,) = stopped.t_events[0]
    assert 0 < t_event < 2.0 and stopped.t[-1] == pytest.approx(t_event, abs=1e-15)
    motion = mb.motion(stopped, "top")
    assert motion.rotation[-1, 2, 2] == pytest.approx(level, abs=1e-9)


def test_top_dense_output_interpolates_on_the_manifold(top_setup):
    top, mb, integrator, q0, v0, traj = top_setup
    dense = integrator.integrate(q0, v0=v0, h=0.01, n_steps=200, dense_output=True).dense()
    np.testing.assert_allclose(dense(traj.t[:50]), traj.q[:50], atol=1e-13)
    half = integrator.integrate(q0, v0=v0, h=0.005, n_steps=400)
    mid = half.t[1:-1:2]
    np.testing.assert_allclose(dense(mid), half.q[1:-1:2], atol=1e-6)
    assert np.abs(mb.system.constraint_values(dense(mid))).max() < 1e-6


def test_top_ensembles_are_the_single_runs_bit_for_bit(top_setup):
    top, mb, integrator, q0, v0, _ = top_setup
    starts = [mb.state(rotations={"top": rot_x(a)}, angular_velocities={"top": [0.5, 0, 8.0]})
              for a in (0.2, 0.3, 0.5)]  # fmt: skip
    q0s, v0s = np.array([s[0] for s in starts]), np.array([s[1] for s in starts])
    ensemble = integrator.integrate_many(q0s, v0s, h=0.01, n_steps=100, workers=1)
    assert np.all(ensemble.success)
    for member, (q, v) in zip(ensemble.trajectories, starts, strict=True):
        single = integrator.integrate(q, v0=v, h=0.01, n_steps=100)
        np.testing.assert_array_equal(member.q, single.q)
        np.testing.assert_array_equal(member.p, single.p)


def test_top_and_its_parts_pickle_after_a_run(top_setup):
    top, mb, integrator, q0, v0, traj = top_setup
    fresh = gvi.Integrator(mb.system, gvi.Galerkin(2))
    mb2, system2, top2, fresh2 = pickle.loads(pickle.dumps((mb, mb.system, top, fresh)))
    assert top2.q == top.q and top2.kinetic_energy == top.kinetic_energy
    assert system2.n == 7 and system2.m == 4
    for copy in (
        fresh2,
        gvi.Integrator(mb2.system, gvi.Galerkin(2)),
        gvi.Integrator(system2, gvi.Galerkin(2)),
    ):
        again = copy.integrate(q0, v0=v0, h=0.01, n_steps=200)
        np.testing.assert_array_equal(again.q, traj.q)
        np.testing.assert_array_equal(again.p, traj.p)
    np.testing.assert_array_equal(mb2.motion(traj, "top").rotation, mb.motion(traj, "top").rotation)
    q_b, v_b = mb2.state(rotations={"top": rot_x(0.3)}, angular_velocities={"top": [0.5, 0, 8.0]})
    np.testing.assert_array_equal(q_b, q0)
    np.testing.assert_array_equal(v_b, v0)


def test_a_used_integrator_of_a_multibody_system_pickles(top_setup):
    top, mb, integrator, q0, v0, traj = top_setup
    copy = pickle.loads(pickle.dumps(integrator))
    np.testing.assert_array_equal(copy.integrate(q0, v0=v0, h=0.01, n_steps=200).q, traj.q)


def manifold_basis(system, q: np.ndarray, p: np.ndarray) -> np.ndarray:
    """A basis of the tangent space at (q, p) of the constraint manifold in T*Q:
    the kernel of the Jacobian of (g(q), G(q) v(q, p)), by central differences."""
    n = system.n

    def phi(x):
        qx, px = x[:n], x[n:]
        v = system.inverse_legendre(qx, px)
        return np.r_[system.constraint_values(qx), system.constraint_jacobian(qx) @ v]

    x0, eps = np.r_[q, p], 1e-6
    jac = np.array([(phi(x0 + eps * d) - phi(x0 - eps * d)) / (2 * eps) for d in np.eye(2 * n)]).T
    _, sv, vt = np.linalg.svd(jac)
    rank = int(np.sum(sv > 1e-8 * sv[0]))
    return vt[rank:].T


def test_top_tangent_is_symplectic_on_the_constraint_manifold(top_setup):
    top, mb, integrator, q0, v0, _ = top_setup
    traj = integrator.integrate(q0, v0=v0, h=0.01, n_steps=100, tangent=True)
    system = mb.system
    basis = manifold_basis(system, traj.q[0], traj.p[0])
    assert basis.shape == (14, 6)  # 7 coordinates, 4 constraints: 2 * 3 dimensions
    J = symplectic_form(system.n)
    for row in (50, 100):
        moved = traj.tangent[row] @ basis
        np.testing.assert_allclose(moved.T @ J @ moved, basis.T @ J @ basis, atol=1e-10)
        # the image lies in the tangent space at the row
        there = manifold_basis(system, traj.q[row], traj.p[row])
        outside = moved - there @ (there.T @ moved)
        assert np.abs(outside).max() < 1e-7


def test_top_gradient_in_forward_mode_matches_differences(top_setup):
    top, mb, integrator, q0, v0, _ = top_setup
    run = dict(h=0.01, n_steps=50)
    p0 = mb.system.legendre(q0, v0)
    height = top.point([0, 0, 0])[2]
    grad = gvi.gradient(integrator, height, q0, p0=p0, wrt=("q0", "p0"), **run)
    assert grad.success and grad.mode == "forward"

    def value(x):
        other = integrator.integrate(x[:7], p0=x[7:], project=True, **run)
        return other.q[-1, 2]

    x0 = np.r_[q0, p0]
    for direction in manifold_basis(mb.system, q0, p0).T:
        eps = 1e-6
        expected = (value(x0 + eps * direction) - value(x0 - eps * direction)) / (2 * eps)
        assert np.r_[grad.q0, grad.p0] @ direction == pytest.approx(expected, rel=1e-5, abs=1e-9)


def test_top_boundary_value_problem_recovers_the_run(top_setup):
    top, mb, integrator, q0, v0, traj = top_setup
    N = 20
    res = gvi.solve_bvp(mb.system, gvi.Galerkin(2), traj.q[0], traj.q[N], (0.0, traj.t[N]), N,
                        guess=traj.q[: N + 1] + 1e-3)  # fmt: skip
    assert res.success
    np.testing.assert_allclose(res.trajectory.q, traj.q[: N + 1], atol=1e-9)


# ------------------------------------------------------------------ errors of the assembly
def test_bad_joints_loads_and_systems_are_refused_with_a_clear_message():
    a = gvi.RigidBody("a", mass=1.0, inertia=[1.0, 1.0, 1.0])
    b = gvi.RigidBody("b", mass=1.0, inertia=[1.0, 1.0, 1.0])
    stranger = gvi.RigidBody("c", mass=1.0, inertia=[1.0, 1.0, 1.0])
    J = gvi.joints
    with pytest.raises(ValueError, match="cannot both be the ground"):
        J.Spherical(None, None)
    with pytest.raises(ValueError, match="joined to itself"):
        J.Fixed(a, a)
    with pytest.raises(TypeError, match="RigidBody or None"):
        J.Spherical("a", b)
    with pytest.raises(ValueError, match="point_b must be a 3-vector"):
        J.Spherical(a, b, point_b=[0, 1])
    with pytest.raises(ValueError, match="nonzero direction"):
        J.Revolute(a, b, axis_a=[0, 0, 0])
    with pytest.raises(ValueError, match="give axis_b"):
        J.Universal(a, b, axis_a=[1, 0, 0])
    with pytest.raises(ValueError, match="give a force, a torque or both"):
        gvi.BodyForce(a)
    with pytest.raises(ValueError, match="torque must be a 3-vector"):
        gvi.BodyForce(a, torque=[1, 2])
    with pytest.raises(ValueError, match="radius must be >= 0"):
        gvi.Sphere(a, -0.1)
    with pytest.raises(ValueError, match="nonzero 3-vector"):
        gvi.Plane([0, 0, 0])
    with pytest.raises(ValueError, match="same body"):
        gvi.BodyContact(gvi.Sphere(a, 0.1), gvi.Sphere(a, 0.1, center=[1, 0, 0]))
    with pytest.raises(ValueError, match="at least one body"):
        gvi.Multibody([])
    with pytest.raises(ValueError, match="distinct"):
        gvi.Multibody([a, gvi.RigidBody("a", mass=2.0, inertia=[1.0, 1.0, 1.0])])
    with pytest.raises(TypeError, match="must be a RigidBody"):
        gvi.Multibody([a, "b"])
    with pytest.raises(ValueError, match="not a body of the system"):
        gvi.Multibody([a, b], joints=[J.Spherical(a, stranger)])
    with pytest.raises(ValueError, match="not a body of this system"):
        gvi.Multibody([a], forces=[gvi.BodyForce(stranger, torque=[0, 0, 1])])
    with pytest.raises(ValueError, match="not a body of the system"):
        gvi.Multibody([a], contacts=[gvi.BodyContact(gvi.BodyPoint(stranger, [0, 0, 0]),
                                                     gvi.Plane())])  # fmt: skip
    with pytest.raises(TypeError, match="joint of galerkin_vi.joints"):
        gvi.Multibody([a], joints=["hinge"])


@pytest.mark.parametrize(
    ("make", "match"),
    [
        (
            lambda b: gvi.joints.Revolute(None, b, axis_a=[sp.Symbol("a"), 0, 1]),
            "numeric direction",
        ),
        (lambda b: gvi.joints.Prismatic(None, b, rotation=[[1, 2], [3, 4]]), "3x3 rotation"),
        (lambda b: gvi.joints.Fixed(None, b, rotation=np.diag([1.0, 2.0, 1.0])), "proper rotation"),
        (lambda b: gvi.joints.Universal(None, b, axis_a=[1, 0, 0], axis_b=[1, 0, 0]), "perpendic"),
    ],
    ids=["symbolic axis", "rotation shape", "not a rotation", "parallel axes"],
)
def test_joints_refuse_axes_and_rotations_they_cannot_use(make, match):
    body = gvi.RigidBody("b", mass=1.0, inertia=[1.0, 2.0, 2.5])
    with pytest.raises(ValueError, match=match):
        make(body)


def test_quaternion_rate_refuses_an_unknown_frame():
    with pytest.raises(ValueError, match="frame"):
        quaternion_rate([1.0, 0, 0, 0], [1.0, 0, 0], "Body")


@pytest.mark.parametrize("rotation", ["quaternion", "matrix"])
def test_body_rotation_is_the_rotation_matrix_in_the_coordinates(rotation):
    body = gvi.RigidBody("b", mass=1.0, inertia=[1.0, 2.0, 2.5], rotation=rotation)
    assert body.embedding == rotation
    R = random_rotations(1)[0]
    coords = body.coordinates_of([0.1, 0.2, 0.3], R)
    value = np.array(body.rotation.subs(dict(zip(body.q, coords, strict=True))), dtype=float)
    np.testing.assert_allclose(value, R, atol=1e-14)
