"""Models written with sympy.physics.mechanics: exact conversion, same trajectories, clear errors.

The integrations use the NumPy backend (nothing compiled here): 200 steps each.
"""

from __future__ import annotations

import importlib.util
import sys
from functools import cache
from pathlib import Path

import numpy as np
import pytest
import sympy as sp
import sympy.physics.mechanics as me
from sympy.core.function import AppliedUndef

import galerkin_vi as gvi
from galerkin_vi.model.mechanics import generalised_forces, to_plain_symbols

T = me.dynamicsymbols._t
m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g")
m, R, alpha, c = sp.symbols("m R alpha c")
PENDULUM_PARAMS = {m1: 1.0, m2: 2.0, l1: 1.0, l2: 0.5, g: 9.81}
DISK_PARAMS = {m: 2.0, R: 0.5, g: 9.81, alpha: 0.3}
STEPS = 200
H = 0.01


# ----------------------------------------------------------------- the models
@cache
def double_pendulum_mechanics():
    """Two particles on massless rods, absolute angles q1, q2 from the downward vertical."""
    q1, q2 = me.dynamicsymbols("q1 q2")
    N = me.ReferenceFrame("N")
    pivot = me.Point("pivot")
    pivot.set_vel(N, 0)
    P1 = pivot.locatenew("P1", l1 * (sp.sin(q1) * N.x - sp.cos(q1) * N.y))
    P2 = P1.locatenew("P2", l2 * (sp.sin(q2) * N.x - sp.cos(q2) * N.y))
    bob1, bob2 = me.Particle("bob1", P1, m1), me.Particle("bob2", P2, m2)
    bob1.potential_energy = m1 * g * P1.pos_from(pivot).dot(N.y)
    bob2.potential_energy = m2 * g * P2.pos_from(pivot).dot(N.y)
    return me.Lagrangian(N, bob1, bob2), (q1, q2), N, (P1, P2)


@cache
def double_pendulum_by_hand(params: tuple = tuple(PENDULUM_PARAMS.items())) -> gvi.LagrangianSystem:
    """The same pendulum with plain symbols, M(q) = [[(m1 + m2) l1^2, m2 l1 l2 cos(a - b)], ...]."""
    a, b, va, vb = sp.symbols("a b va vb")
    L = (
        (m1 + m2) * l1**2 * va**2 / 2
        + m2 * l2**2 * vb**2 / 2
        + m2 * l1 * l2 * va * vb * sp.cos(a - b)
        + (m1 + m2) * g * l1 * sp.cos(a)
        + m2 * g * l2 * sp.cos(b)
    )
    return gvi.LagrangianSystem(L, q=[a, b], v=[va, vb], params=dict(params))


@cache
def rolling_disk(torque: bool = False):
    """A uniform disk (radius R, mass m) rolling down an incline at angle alpha.

    x is the distance travelled down the slope, theta the rotation angle; rolling
    without slipping is x - R theta = 0. Gravity acts on the centre through the
    forcelist; ``torque`` adds a damping torque -c omega on the disk.
    """
    x, th = me.dynamicsymbols("x theta")
    N = me.ReferenceFrame("N")
    A = N.orientnew("A", "Axis", [-alpha, N.z])  # A.x points down the slope
    B = A.orientnew("B", "Axis", [-th, A.z])  # rolling down turns the disk clockwise
    origin = me.Point("origin")
    origin.set_vel(N, 0)
    C = origin.locatenew("C", x * A.x + R * A.y)
    inertia = me.inertia(B, m * R**2 / 4, m * R**2 / 4, m * R**2 / 2)
    disk = me.RigidBody("disk", C, B, m, (inertia, C))
    loads = [(C, -m * g * N.y)]
    if torque:
        loads.append((B, -c * B.ang_vel_in(N)))
    lm = me.LagrangesMethod(
        me.Lagrangian(N, disk), [x, th], forcelist=loads, frame=N, hol_coneqs=[x - R * th]
    )
    return lm, (x, th)


def integrate(system: gvi.LagrangianSystem, q0, v0, method=None) -> gvi.Trajectory:
    method = gvi.Galerkin(2) if method is None else method
    integrator = gvi.Integrator(system, method, backend="numpy")
    return integrator.integrate(q0, v0=v0, h=H, n_steps=STEPS)


# ----------------------------------------------------------------- conversion
def test_conversion_is_exact_and_invertible():
    L, (q1, q2), _, _ = double_pendulum_mechanics()
    system = gvi.LagrangianSystem(L, q=[q1, q2], params=PENDULUM_PARAMS)
    names = system.mechanics_symbols

    assert [str(s) for s in system.q] == ["q1", "q2"]
    assert [str(s) for s in system.v] == ["q1_dot", "q2_dot"]
    assert system.t is None and names.t is None and names.time == T
    assert names.coordinates == (q1, q2)
    # the same tree with symbols in place of functions, and back
    assert system.L == L.xreplace({q1.diff(T): system.v[0], q2.diff(T): system.v[1]}).xreplace(
        {q1: system.q[0], q2: system.q[1]}
    )
    assert names.to_mechanics(system.L) == L
    assert not system.L.atoms(sp.Derivative, AppliedUndef)
    # and the Lagrangian one writes by hand
    hand = double_pendulum_by_hand()
    rename = dict(zip(hand.q + hand.v, system.q + system.v, strict=True))
    assert sp.simplify(system.L - hand.L.xreplace(rename)) == 0


def test_constraints_and_forces_are_converted_the_same_way():
    L, (q1, q2), _, _ = double_pendulum_mechanics()
    k = sp.Symbol("k")
    system = gvi.LagrangianSystem(
        L,
        q=[q1, q2],
        params={**PENDULUM_PARAMS, k: 0.5},
        constraints=[q1 - 2 * q2],
        forces=[-k * q1.diff(T), -k * q2.diff(T) * sp.cos(q1)],
    )
    a, b = system.q
    va, vb = system.v
    assert system.constraints == (a - 2 * b,)
    assert system.forces == (-k * va, -k * vb * sp.cos(a))
    names = system.mechanics_symbols
    assert names.to_plain(q1.diff(T) * q2) == va * b
    assert names.to_mechanics(va * b) == q1.diff(T) * q2


def test_time_dependence_is_found_from_L():
    x = me.dynamicsymbols("x")
    driven = gvi.LagrangianSystem(x.diff() ** 2 / 2 - x**2 / 2 + x * sp.cos(2 * T), q=[x])
    assert driven.t == T and driven.mechanics_symbols.t == T
    assert not driven.structure.autonomous
    assert driven.L == driven.v[0] ** 2 / 2 - driven.q[0] ** 2 / 2 + driven.q[0] * sp.cos(2 * T)
    free = gvi.LagrangianSystem(x.diff() ** 2 / 2 - x**2 / 2, q=[x])
    assert free.t is None and free.structure.autonomous
    # declared time dependent although L is not
    assert gvi.LagrangianSystem(x.diff() ** 2 / 2 - x**2 / 2, q=[x], t=T).t == T


def test_new_symbols_avoid_names_already_taken():
    x = me.dynamicsymbols("x")
    taken_q, taken_v = sp.Symbol("x"), sp.Symbol("x_dot")
    L = x.diff() ** 2 / 2 - taken_q * x**2 / 2 + taken_v * x
    system = gvi.LagrangianSystem(L, q=[x], params={taken_q: 1.0, taken_v: 0.1})
    assert [str(s) for s in (*system.q, *system.v)] == ["x_", "x_dot_"]
    assert system.L == system.v[0] ** 2 / 2 - taken_q * system.q[0] ** 2 / 2 + taken_v * system.q[0]


def test_plain_symbols_unchanged():
    a, va = sp.symbols("a va")
    system = gvi.LagrangianSystem(va**2 / 2 + sp.cos(a), [a], [va])
    assert system.mechanics_symbols is None
    assert system.q == (a,) and system.v == (va,) and system.L == va**2 / 2 + sp.cos(a)


# --------------------------------------------------------- same trajectories
def test_double_pendulum_from_mechanics_matches_the_hand_written_one():
    L, (q1, q2), N, _ = double_pendulum_mechanics()
    from_lagrangian = gvi.LagrangianSystem(L, q=[q1, q2], params=PENDULUM_PARAMS)
    lm = me.LagrangesMethod(L, [q1, q2], frame=N)
    from_lm = gvi.LagrangianSystem.from_lagranges_method(lm, params=PENDULUM_PARAMS)
    assert from_lm.L == from_lagrangian.L and from_lm.forces is None
    q0, v0 = [1.0, 0.5], [0.0, 0.3]
    method = gvi.Galerkin(2, gvi.gauss_legendre(2))
    reference = integrate(double_pendulum_by_hand(), q0, v0, method)
    for system in (from_lagrangian, from_lm):
        traj = integrate(system, q0, v0, method)
        # measured 4.4e-16 in q, 1.8e-15 in p (the two L differ in form: sin**2 + cos**2)
        assert np.max(np.abs(traj.q - reference.q)) <= 1e-12
        assert np.max(np.abs(traj.p - reference.p)) <= 1e-12


def test_rolling_disk_from_lagranges_method():
    lm, (x, th) = rolling_disk()
    system = gvi.LagrangianSystem.from_lagranges_method(lm, params=DISK_PARAMS)
    (xs, ths), (vx, vth) = system.q, system.v
    # exact: the Lagrangian, the constraint and the generalised force of gravity
    assert system.L == m * vx**2 / 2 + m * R**2 * vth**2 / 4
    assert system.constraints == (xs - R * ths,)
    assert [sp.simplify(f) for f in system.forces] == [m * g * sp.sin(alpha), 0]

    a, b, va, vb = sp.symbols("a b va vb")
    by_hand = gvi.LagrangianSystem(
        m * va**2 / 2 + (m * R**2 / 2) * vb**2 / 2,
        q=[a, b],
        v=[va, vb],
        params=DISK_PARAMS,
        constraints=[a - R * b],
        forces=[m * g * sp.sin(alpha), 0],
    )
    speed = 0.4
    q0, v0 = [0.0, 0.0], [speed, speed / DISK_PARAMS[R]]
    traj = integrate(system, q0, v0)
    reference = integrate(by_hand, q0, v0)
    # measured 0 in q and p: after conversion the two models are the same expressions
    assert np.max(np.abs(traj.q - reference.q)) <= 1e-12
    assert np.max(np.abs(traj.p - reference.p)) <= 1e-12

    # closed form: x = v0 t + a t^2 / 2 with a = g sin(alpha) / (1 + I / (m R^2)) = 2/3 g sin(alpha)
    inertia = DISK_PARAMS[m] * DISK_PARAMS[R] ** 2 / 2
    acceleration = (
        DISK_PARAMS[g]
        * np.sin(DISK_PARAMS[alpha])
        / (1 + inertia / (DISK_PARAMS[m] * DISK_PARAMS[R] ** 2))
    )
    assert acceleration == pytest.approx(2 / 3 * DISK_PARAMS[g] * np.sin(DISK_PARAMS[alpha]))
    exact = speed * traj.t + acceleration * traj.t**2 / 2
    # a quadratic in t lies in the degree-2 Galerkin space: exact up to round-off,
    # measured 2.3e-14 in x (x(2) = 4.67), 4.6e-14 in theta and 2.8e-14 in p_x / m
    assert np.max(np.abs(traj.q[:, 0] - exact)) <= 1e-12
    assert np.max(np.abs(traj.q[:, 1] - exact / DISK_PARAMS[R])) <= 1e-12
    assert np.max(np.abs(traj.p[:, 0] / DISK_PARAMS[m] - (speed + acceleration * traj.t))) <= 1e-12
    assert np.max(traj.constraint_residual()) <= 1e-13


# ------------------------------------------------------------ forces, torques
def test_damping_force_on_a_point():
    L, (q1, q2), N, (_, P2) = double_pendulum_mechanics()
    lm = me.LagrangesMethod(L, [q1, q2], frame=N, forcelist=[(P2, -c * P2.vel(N))])
    system = gvi.LagrangianSystem.from_lagranges_method(lm, params={**PENDULUM_PARAMS, c: 0.1})
    (a, b), (va, vb) = system.q, system.v
    # v_P2 = l1 va (cos a, sin a) + l2 vb (cos b, sin b); Q_i = -c v_P2 . dv_P2/dv_i
    by_hand = [
        -c * l1 * (l1 * va + l2 * vb * sp.cos(a - b)),
        -c * l2 * (l2 * vb + l1 * va * sp.cos(a - b)),
    ]
    assert len(system.forces) == 2
    for converted, expected in zip(system.forces, by_hand, strict=True):
        assert sp.simplify(converted - expected) == 0


def test_damping_torque_on_a_frame():
    lm, (x, th) = rolling_disk(torque=True)
    system = gvi.LagrangianSystem.from_lagranges_method(lm, params={**DISK_PARAMS, c: 0.2})
    vx, vth = system.v
    # omega_B = -theta' A.z, T = -c omega_B: Q_theta = T . d(omega_B)/d(theta') = -c theta'
    expected = [m * g * sp.sin(alpha), -c * vth]
    assert [sp.simplify(f - e) for f, e in zip(system.forces, expected, strict=True)] == [0, 0]
    # the same through the pure function, in dynamicsymbols
    N = lm.inertial
    torque_only = [load for load in lm.forcelist if isinstance(load[0], me.ReferenceFrame)]
    assert [sp.simplify(e) for e in generalised_forces(torque_only, [x, th], N)] == [
        0,
        -c * th.diff(T),
    ]


def test_loads_need_an_inertial_frame():
    L, (q1, q2), N, (P1, _) = double_pendulum_mechanics()
    lm = me.LagrangesMethod(L, [q1, q2], forcelist=[(P1, -c * P1.vel(N))])
    params = {**PENDULUM_PARAMS, c: 0.1}
    with pytest.raises(ValueError, match="no inertial frame: pass frame="):
        gvi.LagrangianSystem.from_lagranges_method(lm, params=params)
    system = gvi.LagrangianSystem.from_lagranges_method(lm, params=params, frame=N)
    assert system.forces[1] == 0


# --------------------------------------------------------------------- errors
def test_second_derivatives_are_rejected():
    x = me.dynamicsymbols("x")
    with pytest.raises(ValueError, match=r"L contains Derivative\(x\(t\), \(t, 2\)\)"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2 + x * x.diff(T, 2), q=[x])
    with pytest.raises(ValueError, match=r"forces\[0\] contains .*second or higher"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2, q=[x], forces=[-x.diff(T, 2)])


def test_unlisted_dynamicsymbols_are_rejected():
    x, y = me.dynamicsymbols("x y")
    with pytest.raises(ValueError, match=r"L contains y\(t\): functions of time not listed in q"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2 + y.diff() ** 2 / 2, q=[x])
    with pytest.raises(ValueError, match=r"constraints\[0\] contains y\(t\)"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2, q=[x], constraints=[x - y])


def test_nonholonomic_constraints_are_rejected():
    L, (q1, q2), N, _ = double_pendulum_mechanics()
    lm = me.LagrangesMethod(L, [q1, q2], frame=N, nonhol_coneqs=[q1.diff() - q2.diff()])
    with pytest.raises(NotImplementedError, match="nonholonomic constraints"):
        gvi.LagrangianSystem.from_lagranges_method(lm, params=PENDULUM_PARAMS)


def test_missing_params_are_named():
    lm, _ = rolling_disk()
    # g and alpha occur in the force of gravity only, m and R in L
    with pytest.raises(ValueError, match=r"symbols alpha, g without values: give them in params"):
        gvi.LagrangianSystem.from_lagranges_method(lm, params={m: 1.0, R: 1.0})


def test_v_is_required_with_plain_symbols_and_refused_with_dynamicsymbols():
    a, va = sp.symbols("a va")
    with pytest.raises(ValueError, match="v .* is required when q are plain symbols"):
        gvi.LagrangianSystem(va**2 / 2, [a])
    x = me.dynamicsymbols("x")
    with pytest.raises(ValueError, match="v must be omitted when q are dynamicsymbols"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2, [x], [va])
    with pytest.raises(ValueError, match=r"q\[1\] = a is not a function of t"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2, [x, a])
    with pytest.raises(ValueError, match="q lists x\\(t\\) more than once"):
        gvi.LagrangianSystem(x.diff() ** 2 / 2, [x, x])
    with pytest.raises(ValueError, match="t = s is not the time of the dynamicsymbols"):
        to_plain_symbols(x.diff() ** 2 / 2, [x], t=sp.Symbol("s"))
    with pytest.raises(TypeError, match="lm must be a sympy.physics.mechanics.LagrangesMethod"):
        gvi.LagrangianSystem.from_lagranges_method(object())


# ---------------------------------------------------------- the how-to figure
def test_howto_figure_script_runs(tmp_path, monkeypatch):
    path = Path(__file__).resolve().parents[1] / "docs" / "_scripts" / "mechanics_models.py"
    spec = importlib.util.spec_from_file_location("mechanics_models", path)
    script = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "mechanics_models", script)
    spec.loader.exec_module(script)

    output = tmp_path / "figure.png"
    traj = script.main(["--steps", "200", "--output", str(output), "--backend", "numpy"])
    assert output.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    by_hand = double_pendulum_by_hand(tuple(script.PARAMS.items()))
    reference = gvi.Integrator(by_hand, script.METHOD, backend="numpy").integrate(
        script.Q0, v0=script.V0, h=script.H, n_steps=200
    )
    # the page's model and run: the hand-written Lagrangian's trajectory, measured 2.2e-16
    assert np.max(np.abs(traj.q - reference.q)) <= 1e-12
