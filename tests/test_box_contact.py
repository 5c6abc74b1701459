"""Boxes on boxes, faces landing flat, and friction in a vertical pile of spheres.

The shapes' gaps and slips against closed forms; a face landing flat hit at once
(no spin from corners hit one after another); a stack of boxes coming to rest at
its exact heights; friction between two moving boxes conserving the horizontal
momentum; and the sphere–sphere tangent frame regular on a vertical pile.
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp
from scipy.spatial.transform import Rotation

import galerkin_vi as gvi
from galerkin_vi.contact.impact import ContactFunctions, simultaneous_impulse
from galerkin_vi.multibody.motion import body_motion
from galerkin_vi.multibody.shapes import least_rotation_frame

G = 9.81
A = 0.25  # half side of the boxes


def cube(name: str, mass: float = 1.0) -> gvi.Box:
    body = gvi.RigidBody(name, mass=mass, inertia=[mass * (2 * A) ** 2 / 6] * 3)
    return gvi.Box(body, [A, A, A])


def stack(n: int, floor_friction: float = 0.5, friction: float = 0.5):
    boxes = [cube(f"b{i}") for i in range(n)]
    floor = gvi.Plane([0, 0, 1], 0.0)
    contacts = gvi.standing_contacts(boxes[0], floor, friction=floor_friction)
    for lower, upper in zip(boxes, boxes[1:], strict=False):
        contacts += gvi.standing_contacts(upper, lower, friction=friction)
    return gvi.Multibody([b.body for b in boxes], gravity=[0, 0, -G], contacts=contacts)


def quiet_run(mb, q0, v0, h, n_steps, backend="numba", **options):
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(1), backend=backend)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return integrator.integrate(q0, v0=v0, h=h, n_steps=n_steps, **options)


# --- shapes -----------------------------------------------------------------


def test_standing_contacts_put_a_face_s_corners_on_a_plane_or_a_box_face():
    lower, upper = cube("lower"), cube("upper")
    on_floor = gvi.standing_contacts(lower, gvi.Plane([0, 0, 1], 0.0), friction=0.3)
    on_box = gvi.standing_contacts(upper, lower, restitution=0.2, face="+x", on="-x")
    assert [c.friction for c in on_floor] == [0.3] * 4
    assert all(c.other.body is lower.body and c.other.normal == (-1.0, 0, 0) for c in on_box)
    assert all(float(c.shape.center[0]) == A and c.restitution == 0.2 for c in on_box)


def test_box_corners_and_faces_are_where_the_half_extents_put_them():
    box = gvi.Box(gvi.RigidBody("b", mass=1.0, inertia=[1, 1, 1]), [1, 2, 3], center=[0.5, 0, 0])
    corners = np.array([[float(x) for x in c.center] for c in box.corners()])
    assert corners.shape == (8, 3)
    np.testing.assert_allclose(corners.min(axis=0), [-0.5, -2, -3])
    np.testing.assert_allclose(corners.max(axis=0), [1.5, 2, 3])
    lower = np.array([[float(x) for x in c.center] for c in box.corners("-z")])
    np.testing.assert_allclose(lower[:, 2], -3.0)
    face = box.face("+x")
    assert face.normal == (1.0, 0.0, 0.0)
    np.testing.assert_allclose([float(x) for x in face.point], [1.5, 0, 0])


def test_bad_boxes_planes_and_contacts_are_refused_with_a_clear_message():
    body = gvi.RigidBody("b", mass=1.0, inertia=[1, 1, 1])
    with pytest.raises(ValueError, match="half_extents must be 3 positive"):
        gvi.Box(body, [1, 0, 1])
    with pytest.raises(ValueError, match="face must be one of"):
        gvi.Box(body, [1, 1, 1]).face("up")
    with pytest.raises(ValueError, match="normal must be a nonzero"):
        gvi.BodyPlane(body, [0, 0, 0])
    with pytest.raises(ValueError, match="same body 'b'"):
        gvi.BodyContact(gvi.BodyPoint(body, [1, 1, 1]), gvi.Box(body, [1, 1, 1]).face("+z"))
    with pytest.raises(ValueError, match="reference_axis must be a nonzero"):
        other = gvi.RigidBody("c", mass=1.0, inertia=[1, 1, 1])
        gvi.BodyContact(gvi.Sphere(body, 1), gvi.Sphere(other, 1), reference_axis=[0, 0, 0])
    stranger = gvi.Box(gvi.RigidBody("s", mass=1.0, inertia=[1, 1, 1]), [1, 1, 1])
    point = gvi.BodyPoint(body, [0, 0, -1])
    with pytest.raises(ValueError, match="on 's', not a body of the system"):
        gvi.Multibody([body], contacts=[gvi.BodyContact(point, stranger.face("+z"))])


def test_a_point_on_a_moving_face_has_the_closed_form_gap_and_slip():
    """phi = (R_b n).(x_a + R_a c - x_b - R_b p); the slip is the relative velocity
    of the corner over the face's material point, in the face's turning tangents."""
    upper, lower = cube("u"), cube("l")
    corner = upper.corners("-z")[0]
    contact = gvi.BodyContact(corner, lower.face("+z"), friction=0.3)
    mb = gvi.Multibody([upper.body, lower.body], contacts=[contact])
    system = mb.system
    # the gap and slips alone (ContactFunctions would also build their Hessians)
    args = (*system.q, *system.v)
    gap_of = sp.lambdify(args, system.contacts[0].gap)
    slip_of = sp.lambdify(args, list(system.contacts[0].slip))
    rng = np.random.default_rng(3)
    for _ in range(5):
        Ru, Rl = Rotation.random(2, random_state=rng)
        xu, xl = rng.normal(size=3), rng.normal(size=3)
        vu, vl, wu, wl = rng.normal(size=(4, 3))
        q0, v0 = mb.state(
            positions={"u": xu, "l": xl},
            rotations={"u": Ru.as_matrix(), "l": Rl.as_matrix()},
            velocities={"u": vu, "l": vl},
            angular_velocities={"u": wu, "l": wl},
            frame="space",
        )
        c = np.array([float(x) for x in corner.center])
        y = xu + Ru.apply(c)
        n = Rl.apply([0, 0, 1])
        gap = n @ (y - xl - Rl.apply([0, 0, A]))
        assert gap_of(*q0, *v0) == pytest.approx(gap, abs=1e-13)
        rel = (vu + np.cross(wu, y - xu)) - (vl + np.cross(wl, y - xl))
        tangents = [Rl.apply(np.array([float(x) for x in t.subs({})])) for t in _body_tangents()]
        np.testing.assert_allclose(slip_of(*q0, *v0), [t @ rel for t in tangents], atol=1e-13)


def _body_tangents():
    from galerkin_vi.rotations import orthonormal_complement

    return [sp.Matrix(t) for t in orthonormal_complement([0, 0, 1])]


def test_the_sphere_pair_frame_is_orthonormal_and_regular_on_a_vertical_pile():
    e = sp.Matrix([0, 0, 1])
    rng = np.random.default_rng(7)
    directions = [np.array([0.0, 0.0, 1.0]), *rng.normal(size=(20, 3))]
    for nu in directions:
        nu = nu / np.linalg.norm(nu)
        if nu[2] < -0.99:
            continue  # the frame's one singular direction is nu = -e
        t1, t2 = (np.array([float(x) for x in t]) for t in least_rotation_frame(sp.Matrix(nu), e))
        frame = np.array([t1, t2, nu])
        np.testing.assert_allclose(frame @ frame.T, np.eye(3), atol=1e-14)
        assert np.linalg.det(frame) == pytest.approx(1.0)
    # on the pile's line itself the frame is the fixed one, with finite derivatives
    x, y = sp.symbols("x y", real=True)
    nu = sp.Matrix([x, y, 1]) / sp.sqrt(x**2 + y**2 + 1)
    t1, _ = least_rotation_frame(nu, e)
    jac = t1.jacobian([x, y]).subs({x: 0, y: 0})
    assert all(np.isfinite(float(v)) for v in jac)


# --- a face landing flat -----------------------------------------------------


@pytest.fixture(scope="module", params=["auto", "time-stepping"])
def flat_landing(request):
    mb = stack(1)
    q0, v0 = mb.state(positions={"b0": [0.0, 0.0, A + 1e-3]})
    traj = quiet_run(mb, q0, v0, h=0.01, n_steps=30, contact_mode=request.param)
    return mb, traj


def test_a_face_landing_flat_is_hit_at_once_and_does_not_turn(flat_landing):
    mb, traj = flat_landing
    assert traj.success, traj.message
    touch = np.sqrt(2 * 1e-3 / G)
    assert len(traj.impacts) == 4
    assert {i.contact for i in traj.impacts} == {0, 1, 2, 3}
    for impact in traj.impacts:
        # the touch is looked for on steps that keep every open corner apart
        assert impact.t == pytest.approx(touch, abs=1e-13)
        assert impact.normal_velocity[0] == pytest.approx(-G * touch, rel=1e-11)
        assert abs(impact.normal_velocity[1]) < 1e-12  # plastic: stopped, none pulls
        assert impact.normal_impulse >= 0.0
        assert np.linalg.norm(impact.tangential_impulse) <= 0.5 * impact.normal_impulse + 1e-15
    # the whole kinetic energy is lost, at the first of the four
    assert traj.impacts[0].energy_lost == pytest.approx(0.5 * (G * touch) ** 2, rel=1e-11)
    assert sum(i.energy_lost for i in traj.impacts[1:]) == 0.0
    motion = mb.motion(traj, "b0")
    assert np.abs(motion.angular_velocity).max() < 1e-7
    assert np.abs(motion.velocity[-1]).max() < 1e-8
    assert motion.position[-1, 2] == pytest.approx(A, abs=1e-12)
    assert np.abs(motion.position[-1, :2]).max() < 1e-12


def test_the_simultaneous_law_stops_the_face_and_keeps_each_impulse_in_its_cone():
    """The law alone: a tumbling box's face hit at four corners at once with a slip."""
    mb = stack(1, floor_friction=0.2)
    q0, v0 = mb.state(
        positions={"b0": [0.0, 0.0, A]}, velocities={"b0": [0.3, -0.1, -1.0]}, frame="space"
    )
    p0 = mb.system.legendre(q0, v0)
    functions = ContactFunctions(mb.system)
    p, impacts = simultaneous_impulse(mb.system, functions, [0, 1, 2, 3], 0.0, q0, p0, [])
    v = mb.system.inverse_legendre(q0, p)
    normals = functions.at(functions.gradients, 0.0, q0, v, [])
    assert np.all(normals @ v > -1e-12)
    # sliding against friction mu: the normal impulse m*1 stops the fall, the tangential
    # impulse mu*m*1 slows the slide 0.316 m/s to 0.316 - 0.2
    motion = body_motion(mb.bodies["b0"], [0.0], q0[None], v[None])
    speed = np.linalg.norm(motion.velocity[-1, :2])
    assert speed == pytest.approx(np.hypot(0.3, 0.1) - 0.2, rel=1e-9)
    assert np.abs(motion.angular_velocity[-1]).max() < 1e-9
    total = sum(i.normal_impulse for i in impacts)
    assert total == pytest.approx(1.0, rel=1e-12)


# --- stacks ------------------------------------------------------------------


# each two-box system compiles its point functions for about a minute on a cold cache:
# the stacks and the pile run with the slow studies (pytest -m slow)
@pytest.fixture(scope="module", params=["auto", "time-stepping"])
def two_box_stack(request):
    mb = stack(2)
    q0, v0 = mb.state(positions={"b0": [0.0, 0.0, A + 1e-3], "b1": [0.02, 0.0, 3 * A + 2e-3]})
    traj = quiet_run(mb, q0, v0, h=0.01, n_steps=60, contact_mode=request.param)
    return mb, traj


@pytest.mark.slow
def test_a_stack_of_two_boxes_dropped_comes_to_rest_at_its_exact_heights(two_box_stack):
    mb, traj = two_box_stack
    assert traj.success, traj.message
    for i, height in enumerate([A, 3 * A]):
        motion = mb.motion(traj, f"b{i}")
        assert motion.position[-1, 2] == pytest.approx(height, abs=1e-9)
        assert np.abs(motion.velocity[-1]).max() < 1e-8
        assert np.abs(motion.angular_velocity[-1]).max() < 1e-8
    upper = mb.motion(traj, "b1")
    np.testing.assert_allclose(upper.position[-1, :2], [0.02, 0.0], atol=1e-9)


@pytest.mark.slow
def test_friction_between_two_moving_boxes_keeps_the_horizontal_momentum():
    """The lower box on a frictionless floor, the upper pushed across it: friction
    between them is internal, so the total horizontal momentum stays to round-off;
    their relative speed falls at 2 mu g until they move together at half the push."""
    mb = stack(2, floor_friction=0.0, friction=0.5)
    q0, v0 = mb.state(
        positions={"b0": [0.0, 0.0, A], "b1": [0.0, 0.0, 3 * A]},
        velocities={"b1": [0.5, 0.0, 0.0]},
    )
    traj = quiet_run(mb, q0, v0, h=0.01, n_steps=100, contact_mode="time-stepping")
    assert traj.success, traj.message
    lower, upper = mb.motion(traj, "b0"), mb.motion(traj, "b1")
    momentum = lower.velocity[:, :2] + upper.velocity[:, :2]
    np.testing.assert_allclose(momentum, np.tile([0.5, 0.0], (len(traj.t), 1)), atol=1e-12)
    at = np.flatnonzero(np.isclose(traj.t, 0.03))[0]
    relative = upper.velocity[at, 0] - lower.velocity[at, 0]
    assert relative == pytest.approx(0.5 - 2 * 0.5 * G * 0.03, abs=1e-3)
    # the friction's torque rocks the pair on their faces after they stick; the
    # rocking dies away
    np.testing.assert_allclose(upper.velocity[-1, :2], [0.25, 0.0], atol=1e-8)
    np.testing.assert_allclose(lower.velocity[-1, :2], [0.25, 0.0], atol=1e-8)
    assert np.abs(upper.position[:, 2] - 3 * A).max() < 1e-12


@pytest.mark.slow
def test_a_vertical_pile_of_spheres_with_friction_stands_at_its_exact_heights():
    r, m = 0.1, 0.2
    balls = [gvi.RigidBody(f"s{i}", mass=m, inertia=[0.4 * m * r**2] * 3) for i in range(3)]
    floor = gvi.Plane([0, 0, 1], 0.0)
    contacts = [gvi.BodyContact(gvi.Sphere(balls[0], r), floor, friction=0.5)]
    contacts += [
        gvi.BodyContact(gvi.Sphere(upper, r), gvi.Sphere(lower, r), friction=0.5)
        for lower, upper in zip(balls, balls[1:], strict=False)
    ]
    mb = gvi.Multibody(balls, gravity=[0, 0, -G], contacts=contacts)
    q0, v0 = mb.state(positions={f"s{i}": [0.0, 0.0, r + 2 * r * i] for i in range(3)})
    traj = quiet_run(mb, q0, v0, h=0.01, n_steps=50, contact_mode="time-stepping")
    assert traj.success, traj.message
    assert np.all(np.isfinite(traj.q))
    for i in range(3):
        motion = mb.motion(traj, f"s{i}")
        assert motion.position[-1, 2] == pytest.approx(r + 2 * r * i, abs=1e-9)
        assert np.abs(motion.velocity[-1]).max() < 1e-8
