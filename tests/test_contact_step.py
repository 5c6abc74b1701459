"""The compiled time-stepping contact step against the NumPy step it reproduces.

:func:`galerkin_vi.loops.contact_step.contact_step` takes the iterates of
:meth:`ContactStepper.numpy_step` with the Newton systems reduced blockwise, so
the two agree to the round-off of their solves on every kind of contact: planar
and spatial friction cones, gaps alone, holonomic constraints (a cube in
quaternions), Galerkin(1) and (2), a contact kept apart, a start from the cones'
centres.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.contact.impact import ContactFunctions
from galerkin_vi.contact.runs import compiled_step_addresses
from galerkin_vi.contact.time_stepping import ContactStepper

G = 9.81


def _puck(friction: float = 0.4):
    """A point mass on the floor y = 0, sliding in x and z (a spatial cone)."""
    x, y, z, vx, vy, vz = sp.symbols("x y z vx vy vz")
    L = (vx**2 + vy**2 + vz**2) / 2 - G * y
    contact = gvi.Contact(y, friction=friction, slip=[vx, vz])
    return gvi.LagrangianSystem(L, [x, y, z], [vx, vy, vz], contacts=[contact])


def _block_on_an_incline(friction: float, angle: float):
    """A planar block on an incline: a planar cone (an interval) and a second, open gap."""
    x, y, vx, vy = sp.symbols("x y vx vy")
    s, c = np.sin(angle), np.cos(angle)
    L = (vx**2 + vy**2) / 2 - G * (s * x + c * y)
    contacts = [
        gvi.Contact(y, friction=friction, slip=[vx]),
        gvi.Contact(5 - y),  # a ceiling far above: its gap stays open
    ]
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], contacts=contacts)


def _cube(friction: float, a: float = 0.05, tilt: float = 0.3):
    """A cube with its eight corners against the table (quaternions), standing on an edge
    (tilted about x): two contacts carry it, their forces determined (on a face, four
    would share the load in a way the equations leave open)."""
    mass = 0.1
    cube = gvi.RigidBody("cube", mass=mass, inertia=[mass * (2 * a) ** 2 / 6] * 3)
    corners = [[sx * a, sy * a, sz * a] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    table = gvi.Plane([0, 0, 1], 0.0)
    contacts = [
        gvi.BodyContact(gvi.BodyPoint(cube, corner), table, restitution=0.0, friction=friction)
        for corner in corners
    ]
    mb = gvi.Multibody([cube], gravity=[0, 0, -G], contacts=contacts)
    c, s = np.cos(tilt), np.sin(tilt)
    rotation = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
    q0, v0 = mb.state(
        positions={"cube": [0.0, 0.0, a * (s + c)]},
        rotations={"cube": rotation},
        velocities={"cube": [0.3, 0.0, 0.0]},
        frame="space",
    )
    return mb.system, q0, v0


def _steppers(system, method):
    integrator = gvi.Integrator(system, method)
    functions = ContactFunctions(system)
    prm = np.zeros(len(system.params))
    tables = method.tables
    numpy_step = ContactStepper(functions, tables, prm)
    compiled = ContactStepper(functions, tables, prm, compiled_step_addresses(integrator))
    assert compiled.addresses is not None
    return integrator, numpy_step, compiled


def _compare(numpy_stepper, compiled_stepper, t, h, q, p, guess, duals, excluded=()):
    ref = numpy_stepper.numpy_step(t, h, q, p, guess, duals, excluded)
    got = compiled_stepper.step(t, h, q, p, guess, duals, excluded)
    assert ref.converged and got.converged
    scale = 1.0 + np.abs(ref.p).max()
    # both solved to the stopping rule, their Newton systems eliminated in different
    # orders: not the same iterates, and a momentum residual of RESIDUAL turns a light
    # cube's quaternion by h / I times it
    np.testing.assert_allclose(got.q, ref.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(got.p, ref.p, rtol=0, atol=1e-10 * scale)
    impulse = h * (1.0 + np.abs(ref.normal).max())
    # a sliding spatial contact's force direction converges as the square root of the
    # duality gap (the vector part of z o y): its last digits follow the iterates
    np.testing.assert_allclose(got.normal * h, ref.normal * h, rtol=0, atol=1e-7 * impulse)
    np.testing.assert_allclose(got.tangential * h, ref.tangential * h, rtol=0, atol=1e-7 * impulse)
    np.testing.assert_array_equal(got.sticking, ref.sticking)
    # (the iteration counts may differ: where the iterates near the cones' boundary the
    # round-off of the two solves decides the line searches, 18 against 50 seen)
    return ref


def _march(system, method, q0, p0, h, steps, duals=None, excluded=()):
    """Steps from (q0, p0), each compared; the next starts from the NumPy step."""
    integrator, numpy_stepper, compiled = _steppers(system, method)
    s = method.tables.d.size - 1
    q, p = np.asarray(q0, dtype=float), np.asarray(p0, dtype=float)
    for k in range(steps):
        guess = np.zeros((s + 1, system.n))
        ref = _compare(numpy_stepper, compiled, k * h, h, q, p, guess, duals, excluded)
        q, p, duals = ref.q, ref.p, ref.duals
    return q, p


@pytest.mark.parametrize("degree", [1, 2])
def test_a_sliding_puck_in_the_spatial_cone(degree):
    system = _puck()
    q, p = _march(system, gvi.Galerkin(degree), [0.0, 0.0, 0.0], [1.2, 0.0, 0.9], 0.01, 4)
    # kinetic friction mu g against the motion, in its direction, over four steps
    speed = np.hypot(1.2, 0.9) - 0.4 * G * 0.04
    np.testing.assert_allclose(np.hypot(p[0], p[2]), speed, rtol=1e-10)
    assert abs(q[1]) < 1e-12


@pytest.mark.parametrize(("friction", "angle"), [(0.8, 0.3), (0.2, 0.3)])
def test_a_block_on_an_incline_sticks_or_slides(friction, angle):
    system = _block_on_an_incline(friction, angle)
    _march(system, gvi.Galerkin(2), [0.0, 0.0], [0.0, 0.0], 0.01, 3)


def test_gaps_alone_and_a_contact_kept_apart():
    system = _block_on_an_incline(0.0, 0.3)
    _march(system, gvi.Galerkin(2), [0.0, 0.0], [0.0, -0.5], 0.01, 2)
    # the ceiling kept apart: its force stays 0
    integrator, numpy_stepper, compiled = _steppers(system, gvi.Galerkin(2))
    guess = np.zeros((3, 2))
    ref = _compare(numpy_stepper, compiled, 0.0, 0.01, [0.0, 0.0], [0.0, -0.5], guess, None, [1])
    assert ref.normal[1] == 0.0


@pytest.mark.parametrize("degree", [1, 2])
def test_a_cube_on_an_edge_slides_and_tips(degree):
    system, q0, v0 = _cube(friction=0.4)
    # the continuous momentum of the state: the first step's p_k (the runs start so)
    p0 = system.legendre(q0, v0)
    _march(system, gvi.Galerkin(degree), q0, p0, 0.005, 3)


def test_a_run_compiled_and_in_numpy_takes_the_same_steps():
    system = _puck(friction=0.3)
    method = gvi.Galerkin(2)
    runs = {}
    for backend in ("numba", "numpy"):
        integrator = gvi.Integrator(system, method, backend=backend)
        runs[backend] = integrator.integrate(
            [0.0, 0.0, 0.0], [1.0, 0.0, 0.5], h=0.01, n_steps=60, contact_mode="time-stepping"
        )
    compiled, reference = runs["numba"], runs["numpy"]
    assert compiled.success and reference.success
    np.testing.assert_allclose(compiled.q, reference.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(compiled.p, reference.p, rtol=0, atol=1e-9)
    # at rest after v / (mu g) = 0.38 s, on the straight line of its first velocity
    assert np.abs(compiled.p[-1]).max() < 1e-12
    along = compiled.q[-1, [0, 2]] @ np.array([1.0, 0.5]) / np.hypot(1.0, 0.5)
    assert along == pytest.approx(1.25 / (2 * 0.3 * G), abs=0.3 * G * 0.01**2)
    forces_c, forces_r = compiled.contact_forces, reference.contact_forces
    np.testing.assert_allclose(forces_c.normal, forces_r.normal, rtol=1e-8, atol=1e-12)
    np.testing.assert_allclose(forces_c.tangential, forces_r.tangential, rtol=1e-7, atol=1e-10)


def test_an_ensemble_with_contacts_runs_the_compiled_step_in_threads():
    system = _puck(friction=0.3)
    integrator = gvi.Integrator(system, gvi.Galerkin(1))
    starts = np.array([[1.0, 0.0, 0.5], [0.4, 0.0, -0.9], [0.0, 0.0, 1.5]])
    q0s = np.zeros((3, 3))
    run = {"h": 0.01, "n_steps": 30, "contact_mode": "time-stepping"}
    together = integrator.integrate_many(q0s, starts, workers=3, **run)
    for member, v0 in zip(together, starts, strict=True):
        alone = integrator.integrate(np.zeros(3), v0, **run)
        np.testing.assert_array_equal(member.q, alone.q)


def test_a_tumbling_cube_runs_compiled_as_in_numpy():
    # a cube tipping over its edge with sliding friction, in quaternions (the hidden
    # constraint's projection in the compiled loop), up to its far edge's first touch at
    # t = 0.102 s. (The touch times of the two backends differ by 1.3e-7 s, more than the
    # 3e-11 of their states before it: the first touch's cut, in Python, is issue 43's)
    system, q0, v0 = _cube(friction=0.8)
    runs = {}
    for backend in ("numba", "numpy"):
        integrator = gvi.Integrator(system, gvi.Galerkin(1), backend=backend)
        runs[backend] = integrator.integrate(q0, v0, h=0.005, n_steps=20)
    compiled, reference = runs["numba"], runs["numpy"]
    assert compiled.success and reference.success
    assert not compiled.impacts and not reference.impacts
    np.testing.assert_allclose(compiled.q, reference.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled.p, reference.p, rtol=0, atol=1e-10)
    # the resultant normal force per step (once on its face, how four corners share the
    # load is left open by the equations: each stepper picks its own split)
    forces_c, forces_r = compiled.contact_forces, reference.contact_forces
    np.testing.assert_allclose(
        forces_c.normal.sum(axis=1), forces_r.normal.sum(axis=1), rtol=0, atol=1e-7
    )


def test_a_tumbling_cube_comes_to_rest_on_a_face_at_its_height():
    a = 0.05
    system, q0, v0 = _cube(friction=0.8, a=a)
    traj = gvi.Integrator(system, gvi.Galerkin(1)).integrate(q0, v0, h=0.005, n_steps=80)
    assert traj.success
    # at rest (position, quaternion and momentum still) with its face on the table
    assert np.abs(traj.p[-5:]).max() < 1e-12
    assert abs(traj.q[-1, 2] - a) < 1e-12
    assert abs(np.linalg.norm(traj.q[-1, 3:]) - 1.0) < 1e-14


@pytest.mark.parametrize("tilt", [0.0, 0.3])
def test_the_broad_phase_keeps_far_corners_apart_and_changes_nothing(monkeypatch, tilt):
    # a cube sliding on a face (four corners far above the table) or tipping over an edge
    # (corners closing during the run: kept apart, then taken in again, and a step redone
    # where one ends closed)
    from galerkin_vi.contact import runs

    a = 0.05
    system, q0, v0 = _cube(friction=0.8, a=a, tilt=tilt)
    integrator = gvi.Integrator(system, gvi.Galerkin(1))
    run = {"h": 0.005, "n_steps": 20, "contact_mode": "time-stepping"}
    monkeypatch.setattr(runs, "BROAD_PHASE", False)
    everything = integrator.integrate(q0, v0, **run)
    monkeypatch.setattr(runs, "BROAD_PHASE", True)
    broad = integrator.integrate(q0, v0, **run)
    assert everything.success and broad.success
    # to the stopping rule's accuracy (a light cube's quaternion: h / I times the momentum
    # residual per step), over 20 steps of tipping
    np.testing.assert_allclose(broad.q, everything.q, rtol=0, atol=1e-9)
    np.testing.assert_allclose(broad.p, everything.p, rtol=0, atol=1e-9)
    upper = [j for j in range(8) if j % 2 == 0]  # the corners with +a in z: never touch
    # kept apart by the loop's broad phase: no force at all (the first step is Python's:
    # the loop starts from the second)
    assert np.abs(broad.contact_forces.normal[1:, upper]).max() == 0.0


@pytest.mark.parametrize(("restitution", "friction"), [(0.0, 0.0), (0.6, 0.0), (0.5, 0.3)])
def test_first_touches_are_cut_out_of_the_steps_in_the_compiled_loop(
    monkeypatch, restitution, friction
):
    # a puck dropped at an angle onto the floor: each touch falls inside a step, which the
    # loop cuts at the touch (regula falsi on steps keeping the contact apart), applying
    # the impact law there (frictionless, or sticking/sliding) and taking the rest again;
    # no step goes back to Python, and the impacts are those of the NumPy step's run
    x, y, z, vx, vy, vz = sp.symbols("x y z vx vy vz")
    L = (vx**2 + vy**2 + vz**2) / 2 - G * y
    contact = gvi.Contact(
        y, restitution=restitution, friction=friction, slip=[vx, vz] if friction else None
    )
    system = gvi.LagrangianSystem(L, [x, y, z], [vx, vy, vz], contacts=[contact])
    run = {"h": 0.01, "n_steps": 80, "contact_mode": "time-stepping"}
    start = ([0.0, 0.3, 0.0], [1.0, -0.4, 0.5])
    reference = gvi.Integrator(system, gvi.Galerkin(1), backend="numpy").integrate(*start, **run)
    calls = []
    original = ContactStepper.compiled_step

    def counted(self, *args, **kwargs):
        calls.append(args[0])
        return original(self, *args, **kwargs)

    monkeypatch.setattr(ContactStepper, "compiled_step", counted)
    compiled = gvi.Integrator(system, gvi.Galerkin(1)).integrate(*start, **run)
    assert compiled.success and reference.success
    # the first step is Python's (the loop starts on the grid from the second)
    assert len(calls) <= 1
    assert len(compiled.impacts) == len(reference.impacts) >= 1
    for got, want in zip(compiled.impacts, reference.impacts, strict=True):
        assert got.contact == want.contact and got.mode == want.mode
        assert got.t == pytest.approx(want.t, abs=1e-12)
        assert got.normal_impulse == pytest.approx(want.normal_impulse, rel=1e-9)
        np.testing.assert_allclose(got.normal_velocity, want.normal_velocity, atol=1e-9)
        assert got.energy_lost == pytest.approx(want.energy_lost, rel=1e-8, abs=1e-12)
    # Newton's law at the first touch, u+ = -e u-, with the exact time of a free fall
    first = compiled.impacts[0]
    assert first.normal_velocity[1] == pytest.approx(-restitution * first.normal_velocity[0])
    assert first.t == pytest.approx((-0.4 + np.sqrt(0.16 + 2 * G * 0.3)) / G, abs=1e-12)
    np.testing.assert_allclose(compiled.t, reference.t, rtol=0, atol=1e-12)
    np.testing.assert_allclose(compiled.q, reference.q, rtol=0, atol=1e-10)
    np.testing.assert_allclose(compiled.p, reference.p, rtol=0, atol=1e-10)
