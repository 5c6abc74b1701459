"""The velocity-stage loop generated per system and method
(``galerkin_vi.codegen.velocity_steps``): the shared varying-mass loop's states, sweeps
and rows bit for bit, its hand-overs and failures, which systems and methods get it,
pickling and ensembles, and its text run uncompiled."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.codegen.method_steps import METHOD_UNROLLED
from galerkin_vi.run import segment
from galerkin_vi.run.smooth import integrate_smooth

pytest.importorskip("numba")

GAUSS = {s: gvi.Galerkin(s, gvi.gauss_legendre(s)) for s in (3, 4, 6)}


def _spherical() -> gvi.LagrangianSystem:
    # a diagonal M = diag(1, r^2, r^2 sin^2 theta) of three coordinates
    r, th, ph, vr, vth, vph = sp.symbols("r theta phi v_r v_theta v_phi")
    L = (vr**2 + r**2 * vth**2 + r**2 * sp.sin(th) ** 2 * vph**2) / 2 + 1 / r
    return gvi.LagrangianSystem(L, [r, th, ph], [vr, vth, vph])


def _damped_coriolis() -> gvi.LagrangianSystem:
    # M = diag(1 + y^2, 2), a(q) = (y, -x), forces that depend on v
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = ((1 + y**2) * vx**2 + 2 * vy**2) / 2 + y * vx - x * vy - x**4 / 4 - y**2
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], forces=[-0.1 * vx, -0.2 * vy * x])


def _driven_full_mass() -> gvi.LagrangianSystem:
    # a full 2 x 2 M that varies with t and q, a(t, q), a force depending on t and v
    t, x, y, vx, vy = sp.symbols("t x y vx vy")
    m11, m12, m22 = 2 + sp.sin(t), sp.cos(x) / 2, 1 + y**2
    L = (m11 * vx**2 + 2 * m12 * vx * vy + m22 * vy**2) / 2 + t * y * vx - x**2 - y**4
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], t=t, forces=[-t * vy, -0.3 * vx])


def _double_pendulum():
    p = problems.double_pendulum()
    return p.system, [2.0, -0.5], [3.0, 1.5], p.params


CASES = {
    # the pendulums swing over the top: their angles wrap
    "double_pendulum": _double_pendulum(),
    "spherical": (_spherical(), [1.0, 1.0, 0.2], [0.1, 0.3, 0.9], None),
    "damped_coriolis": (_damped_coriolis(), [0.5, -0.3], [0.2, 0.4], None),
    "driven_full_mass": (_driven_full_mass(), [0.3, 0.2], [0.1, -0.2], None),
}


def _shared(integrator: gvi.Integrator):
    return dataclasses.replace(integrator.run_spec, stage_steps=None)


def _assert_same(generated, shared) -> None:
    for field in ("t", "q", "p", "newton_iterations"):
        np.testing.assert_array_equal(getattr(generated, field), getattr(shared, field))
    assert generated.total_newton_iterations == shared.total_newton_iterations
    assert generated.success == shared.success and generated.status == shared.status


# each system and method is a loop of its own (two to three seconds of compilation):
# every system with Gauss(3), the double pendulum (the benchmark's) with Gauss(6) too
@pytest.mark.parametrize(
    ("name", "s"), [*((name, 3) for name in sorted(CASES)), ("double_pendulum", 6)]
)
@pytest.mark.parametrize(("h", "save_every"), [(0.05, 1), (-0.04, 6)])
def test_the_generated_loop_takes_the_shared_loops_steps_and_sweeps(name, s, h, save_every):
    system, q0, v0, params = CASES[name]
    integrator = gvi.Integrator(system, GAUSS[s], specialize="system")
    assert integrator.kernel_path == "varying_mass"
    assert integrator.run_spec.stage_steps.py_func.__name__ == "velocity_steps"
    run = dict(h=h, n_steps=300, save_every=save_every, params=params)
    generated = integrator.integrate(q0, v0, **run)
    shared = integrate_smooth(_shared(integrator), q0, v0, None, **run)
    assert generated.success
    _assert_same(generated, shared)
    np.testing.assert_array_equal(generated.q_reduced, shared.q_reduced)


def test_the_double_pendulums_angles_wrap_in_the_generated_loop():
    system, q0, v0, params = CASES["double_pendulum"]
    traj = gvi.Integrator(system, GAUSS[3], specialize="system").integrate(
        q0, v0, h=0.05, n_steps=400, params=params
    )
    assert system.periodic[0] and np.abs(traj.q[:, 0]).max() > np.pi
    assert np.abs(traj.q_reduced).max() <= np.pi


def test_only_the_default_keeps_the_shared_loop_and_large_methods_do_too():
    system, _, _, _ = CASES["double_pendulum"]
    assert gvi.Integrator(system, GAUSS[4]).run_spec.stage_steps is None
    assert gvi.Integrator(system, GAUSS[4], specialize=False).kernel_path == "newton"
    # stages times coordinates past METHOD_UNROLLED: the shared loop
    s = METHOD_UNROLLED // 2 + 1
    large = gvi.Integrator(system, gvi.Galerkin(s, gvi.gauss_legendre(s)), specialize="system")
    assert large.kernel_path == "varying_mass" and large.run_spec.stage_steps is None
    # a full M of three rows has no closed-form velocity: the shared loop
    q, v = sp.symbols("q0:3"), sp.symbols("v0:3")
    kinetic = sum((1 + sp.cos(q[a] - q[b]) / 2) * v[a] * v[b] for a in range(3) for b in range(3))
    full = gvi.LagrangianSystem(kinetic / 2 + sum(sp.cos(x) for x in q), list(q), list(v))
    integrator = gvi.Integrator(full, GAUSS[3], specialize="system")
    assert integrator.kernel_path == "varying_mass" and integrator.run_spec.stage_steps is None


@pytest.mark.parametrize("fixed_point", [True, "persistent"])
def test_a_step_the_fixed_point_cannot_take_goes_to_newton_as_from_the_shared_loop(
    fixed_point, monkeypatch
):
    # damping that grows with t: late in the run the sweeps contract too slowly
    q, v, t = sp.symbols("q v t")
    system = gvi.LagrangianSystem(
        (2 + sp.sin(q)) * v**2 / 2 + sp.cos(q), [q], [v], t=t, forces=[-40 * t * v]
    )
    integrator = gvi.Integrator(system, GAUSS[3], specialize="system", fixed_point=fixed_point)
    assert integrator.run_spec.stage_steps is not None
    handed = []
    original = segment.continue_from_last_row

    def spy(spec, run, out, result, path):
        handed.append((spec.stage_steps is not None, result.steps, path))
        return original(spec, run, out, result, path)

    monkeypatch.setattr(segment, "continue_from_last_row", spy)
    run = dict(h=0.05, n_steps=60, save_every=3)
    generated = integrator.integrate([3.0], [3.0], **run)
    from_generated = list(handed)
    handed.clear()
    shared = integrate_smooth(_shared(integrator), [3.0], [3.0], None, **run)
    # the same hand-over, at the same step, and then the same Newton run
    assert len(from_generated) == 1 and from_generated[0][0] and from_generated[0][2] == "newton"
    assert [h[1:] for h in from_generated] == [h[1:] for h in handed]
    assert 8 < from_generated[0][1] < 60
    _assert_same(generated, shared)


def test_a_run_that_overflows_fails_where_the_shared_loop_fails():
    # V = -exp(q^2) / 2 with a mass that grows with q: thrown outwards ever faster
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem((1 + q**2) * v**2 / 2 + sp.exp(q**2) / 2, [q], [v])
    integrator = gvi.Integrator(system, GAUSS[3], specialize="system")
    assert integrator.run_spec.stage_steps is not None
    run = dict(h=0.02, n_steps=4000, save_every=4, on_failure="warn")
    with pytest.warns(gvi.RunFailureWarning):
        generated = integrator.integrate([2.0], [0.0], **run)
    with pytest.warns(gvi.RunFailureWarning):
        shared = integrate_smooth(_shared(integrator), [2.0], [0.0], None, **run)
    assert not generated.success and generated.n_steps == shared.n_steps < 4000
    assert generated.message == shared.message
    np.testing.assert_array_equal(generated.t, shared.t)
    np.testing.assert_array_equal(generated.q, shared.q)
    np.testing.assert_array_equal(generated.newton_iterations, shared.newton_iterations)


def test_it_pickles_and_its_ensembles_run_the_shared_member_loop():
    system, q0, v0, params = CASES["double_pendulum"]
    integrator = gvi.Integrator(system, GAUSS[3], specialize="system")
    first = integrator.integrate(q0, v0, h=0.05, n_steps=40, params=params)
    copy = pickle.loads(pickle.dumps(integrator))
    assert copy.run_spec.stage_steps is not None
    again = copy.integrate(q0, v0, h=0.05, n_steps=40, params=params)
    np.testing.assert_array_equal(again.q, first.q)
    many = integrator.integrate_many(
        np.array([q0, q0]), np.array([v0, v0]), h=0.05, n_steps=40, params=params, workers=1
    )
    np.testing.assert_array_equal(many.q[1], first.q)


def test_the_generated_text_runs_uncompiled_on_numpy_arrays():
    system, q0, v0, _ = CASES["damped_coriolis"]
    integrator = gvi.Integrator(system, GAUSS[3], specialize="system")
    function = integrator.run_spec.stage_steps.py_func
    namespace: dict = {"__name__": "uncompiled"}
    with open(function.__globals__["__file__"]) as f:
        exec(compile(f.read(), "<generated>", "exec"), namespace)
    compiled = integrator.integrate(q0, v0, h=0.1, n_steps=12, save_every=5)
    _, _, after = integrator.run_spec.loop_parts()
    t_out, q_out, p_out, turns = np.zeros(4), np.zeros((4, 2)), np.zeros((4, 2)), np.zeros((4, 2))
    iterations, total = np.zeros(3, dtype=np.uint8), np.zeros(1, dtype=np.int64)
    q = np.array(q0, float)
    status, steps, saved, _, _ = namespace["velocity_steps"](
        q, compiled.p[0].copy(), np.array(v0, float), 0.0, 0.1, 12, 5,
        system.parameter_vector(None), *after, t_out, q_out, p_out, turns, iterations, total,
    )  # fmt: skip
    assert (status, steps, saved) == (0, 12, 4)
    # Python's x**4 is pow(), numba's a product: the states agree to round-off, and a
    # step's sweeps by one (a last sweep that moves a bit in one and not the other)
    np.testing.assert_array_equal(t_out, compiled.t)
    np.testing.assert_allclose(q_out, compiled.q, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(p_out, compiled.p, rtol=1e-14, atol=1e-16)
    np.testing.assert_allclose(iterations, compiled.newton_iterations, atol=1)


def test_run_options_give_the_shared_loops_results():
    # t_eval, events and dense output read the generated loop's rows as the shared one's
    system, q0, v0, params = CASES["double_pendulum"]
    method = GAUSS[3]
    generated = gvi.Integrator(system, method, specialize="system")
    shared = gvi.Integrator(system, method)
    assert generated.run_spec.stage_steps is not None and shared.run_spec.stage_steps is None
    times = np.linspace(0.0, 4.9, 37)

    def crossing(t, q, v):
        return q[1]

    run = dict(h=0.01, n_steps=500, params=params, t_eval=times, events=[crossing])
    a, b = generated.integrate(q0, v0, **run), shared.integrate(q0, v0, **run)
    np.testing.assert_array_equal(a.q, b.q)
    assert len(a.t_events[0]) > 0
    np.testing.assert_array_equal(a.t_events[0], b.t_events[0])
    dense = dict(t_span=(0.0, 3.3), h=0.01, params=params, dense_output=True)
    a, b = generated.integrate(q0, v0, **dense), shared.integrate(q0, v0, **dense)
    np.testing.assert_array_equal(a.sol(1.234), b.sol(1.234))
