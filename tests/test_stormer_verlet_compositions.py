"""Symmetric compositions of Störmer–Verlet (``gvi.Composition``): coefficients against their
order conditions, measured orders, Noether momenta and energy, every run option, bad input."""

from __future__ import annotations

import pickle
import warnings

import mpmath
import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.method.composition import (
    SCHEMES,
    VERLET_SCHEMES,
    exact_coefficients,
    exact_splitting,
)
from galerkin_vi.problems.forced import driven_oscillator
from galerkin_vi.problems.gravitation import kepler
from galerkin_vi.problems.mechanics import harmonic_oscillator, pendulum
from galerkin_vi.run.events import Event
from galerkin_vi.run.loop_choice import composition_for

ALL = sorted(SCHEMES)
SPLITTINGS = [key for key in ALL if SCHEMES[key].splitting]


@pytest.fixture(scope="module")
def orbit():
    return kepler(0.5)


# ------------------------------------------------------------------ coefficients
@pytest.mark.parametrize(("order", "scheme"), [k for k in ALL if k not in SPLITTINGS])
def test_coefficients_satisfy_the_power_sum_conditions_of_their_order(order, scheme):
    # consistency sum = 1; symmetric order p needs sum g^(2j+1) = 0 for 2j+1 < p
    # (HLW06 V.3.2); the tabulated digits satisfy them to their 26 digits
    exact = exact_coefficients(order, scheme)
    with mpmath.workdps(40):
        assert abs(mpmath.fsum(exact) - 1) < 1e-25
        for power in range(3, order, 2):
            assert abs(mpmath.fsum(g**power for g in exact)) < 1e-24
    method = gvi.Composition(order, scheme)
    gamma = method.coefficients
    assert gamma.shape == (method.stages,)
    assert np.array_equal(gamma, gamma[::-1])
    assert abs(gamma.sum() - 1.0) < 1e-14 * method.stages
    assert method.nodes[-1] == 1.0
    assert np.allclose(np.cumsum(gamma), method.nodes, atol=1e-14 * method.stages)
    assert all(float(g) == x for g, x in zip(exact, gamma, strict=True))  # rounded once


@pytest.mark.parametrize(("order", "scheme"), SPLITTINGS)
def test_splitting_coefficients_are_consistent_palindromes_and_the_loop_tables_sum_to_them(
    order, scheme
):
    drifts, kicks = exact_splitting(order, scheme)
    with mpmath.workdps(40):
        assert abs(mpmath.fsum(drifts) - 1) < 1e-35 and abs(mpmath.fsum(kicks) - 1) < 1e-35
    method = gvi.Composition(order, scheme)
    assert method.splitting and len(drifts) == method.stages and len(kicks) == method.stages + 1
    tables = method.substeps()
    for a in (tables.drift, tables.kicks):
        assert np.array_equal(a, a[::-1])
    assert all(float(a) == x for a, x in zip(drifts, tables.drift, strict=True))
    assert all(float(b) == x for b, x in zip(kicks, tables.kicks, strict=True))
    # each kick of the scheme is the sum of the sub-steps' kicks that meet there
    assert tables.kick_before[0] == tables.kicks[0] and tables.kick_after[-1] == tables.kicks[-1]
    assert np.array_equal(tables.kick_after[:-1] + tables.kick_before[1:], tables.kicks[1:-1])
    assert "Blanes" in method.reference


def test_blanes_moan_coefficients_completed_by_consistency_are_the_published_ones():
    # the coefficient of each half that the free ones fix (Blanes & Moan 2002, Table 3,
    # as Principia transcribes them)
    drifts, kicks = gvi.Composition(4, "blanes_moan").coefficients, gvi.Composition(4).kicks
    assert drifts[2] == pytest.approx(-0.350171622895351, abs=1e-15)
    assert kicks[3] == pytest.approx(0.1195241940131508, abs=1e-15)
    drifts, kicks = gvi.Composition(6).coefficients, gvi.Composition(6).kicks
    assert drifts[5] == pytest.approx(0.20477705429147, abs=1e-14)
    assert kicks[5] == kicks[6] == pytest.approx(0.2366699247869311, abs=1e-15)


def test_a_composition_of_stormer_verlet_is_a_splitting_with_averaged_kicks():
    method = gvi.Composition(6, "kahan_li")
    gamma, kicks = method.coefficients, method.kicks
    assert not method.splitting
    np.testing.assert_allclose(kicks, np.r_[gamma[0] / 2, (gamma[:-1] + gamma[1:]) / 2,
                                            gamma[-1] / 2], rtol=0, atol=1e-16)  # fmt: skip
    tables = method.substeps()
    assert np.array_equal(tables.kick_before, tables.kick_after)


def test_yoshida_triple_jump_closed_form():
    gamma = gvi.Composition(4, "yoshida").coefficients
    root = 2.0 ** (1 / 3)
    assert gamma == pytest.approx([1 / (2 - root), -root / (2 - root), 1 / (2 - root)], rel=1e-15)


def test_defaults_are_the_splittings_up_to_order_6():
    assert gvi.Composition(4).scheme == gvi.Composition(6).scheme == "blanes_moan"
    assert (gvi.Composition(4).stages, gvi.Composition(6).stages) == (6, 11)
    assert gvi.Composition(8).scheme == VERLET_SCHEMES[8] == "kahan_li"


def test_suzuki_closed_form():
    gamma = gvi.Composition(4, "suzuki").coefficients
    g = 1 / (4 - 4 ** (1 / 3))
    assert gamma == pytest.approx([g, g, 1 - 4 * g, g, g], rel=1e-14)


def test_method_object_repr_equality_hash_pickling():
    a, b = gvi.Composition(8), gvi.Composition(8, "kahan_li")
    assert a == b and hash(a) == hash(b) and a != gvi.Composition(8, "mclachlan")
    assert a != gvi.Galerkin(1)
    assert repr(a) == "Composition(order=8, scheme='kahan_li')"
    assert pickle.loads(pickle.dumps(a)) == a
    assert (a.order, a.stages) == (8, 17) and "Kahan" in a.reference
    assert gvi.Composition(10).stages == 35 and "Sofroniou" in gvi.Composition(10).reference


@pytest.mark.parametrize(
    ("args", "error", "match"),
    [
        ((5,), ValueError, "order must be one of"),
        ((True,), TypeError, "order must be an int"),
        ((8, "yoshida"), ValueError, "scheme for order 8 must be one of"),
        ((4, 3), TypeError, "scheme must be a str"),
    ],
)
def test_bad_arguments(args, error, match):
    with pytest.raises(error, match=match):
        gvi.Composition(*args)


# ------------------------------------------------------------------------ orders
# SRKN6b's h^4 term is made small by design: on Kepler its errors follow the higher terms
# (apparent orders 6-7, then 3.4) down to h = T/250, where round-off begins; its order is
# measured in mpmath below
@pytest.mark.parametrize(
    ("order", "scheme"), [k for k in ALL if k[0] <= 6 and k != (4, "blanes_moan")]
)
def test_measured_order_on_kepler_float64(orbit, order, scheme):
    result = gvi.measure_order(
        orbit.system, gvi.Composition(order, scheme), orbit.q0, orbit.v0,
        t_final=orbit.t_final, reference=orbit.exact, step_counts="auto", norm="max",
        window=(1e-11, 1e-4),
    )  # fmt: skip
    assert result.mask.sum() >= 3
    assert abs(result.order - order) <= 0.3


@pytest.mark.parametrize(("order", "scheme"), [k for k in ALL if k[0] >= 8] + SPLITTINGS)
def test_measured_order_in_mpmath(order, scheme):
    # float64 errors above round-off are pre-asymptotic at orders 8 and 10; the triple
    # jumps' large coefficients (|gamma| up to 3) need smaller steps to be asymptotic
    problem = pendulum()
    counts = [32, 64, 128] if scheme == "triple_jump" else [8, 16, 32]
    result = gvi.measure_order(
        problem.system, gvi.Composition(order, scheme), problem.q0, problem.v0,
        t_final=problem.t_final, step_counts=counts, dps=40,
    )  # fmt: skip
    assert result.mask.sum() == 3
    assert abs(result.order - order) <= 0.3


def test_time_dependent_lagrangian_keeps_the_order():
    # a(t) and V(t, q) at the sub-steps' own times: order 8 in float64 on the driven oscillator
    problem = driven_oscillator()
    integrator = gvi.Integrator(problem.system, gvi.Composition(8))
    errors = []
    for n in (40, 80):
        traj = integrator.integrate(problem.q0, problem.v0, h=problem.t_final / n, n_steps=n)
        errors.append(np.max(np.abs(traj.q - problem.exact(traj.t))))
    assert 7.5 < np.log2(errors[0] / errors[1]) < 8.7


@pytest.mark.parametrize("order", [4, 6])
def test_a_splitting_keeps_its_order_with_a_time_dependent_potential(order):
    # V(t, q) kicked at the drifts' own times tau_i = t_k + c_i h
    problem = driven_oscillator()
    integrator = gvi.Integrator(problem.system, gvi.Composition(order))
    errors = []
    for n in (20, 40):
        traj = integrator.integrate(problem.q0, problem.v0, h=problem.t_final / n, n_steps=n)
        errors.append(np.max(np.abs(traj.q - problem.exact(traj.t))))
    assert order - 0.4 < np.log2(errors[0] / errors[1]) < order + 0.7


# ------------------------------------------------- the explicit loop, stage by stage
def test_one_stage_composition_is_the_stormer_verlet_loop_bitwise(orbit):
    runs = [
        gvi.Integrator(orbit.system, m).integrate(orbit.q0, orbit.v0, h=0.05, n_steps=300)
        for m in (gvi.Galerkin(1), gvi.Composition(2))
    ]
    assert np.array_equal(runs[0].q, runs[1].q) and np.array_equal(runs[0].p, runs[1].p)


def _gauge_system() -> gvi.LagrangianSystem:
    # a(t) . v with a(t) = cos t: p = v + cos t, and q'' = -q + sin t
    q, v, t = sp.symbols("q v t")
    return gvi.LagrangianSystem(v**2 / 2 + sp.cos(t) * v - q**2 / 2, [q], [v], t=t)


@pytest.mark.parametrize(
    ("system", "q0", "p0"),
    [
        (kepler(0.5).system, kepler(0.5).q0, kepler(0.5).v0),
        (driven_oscillator().system, [1.0], [0.0]),
        (_gauge_system(), [1.0], [0.5]),
    ],
    ids=["kepler", "driven", "a(t).v"],
)
def test_a_step_is_the_stormer_verlet_steps_of_the_coefficients(system, q0, p0):
    # independent of the sub-step loop: Galerkin(1) steps of gamma_i h from t_{i-1}
    method = gvi.Composition(6, "yoshida")
    composed = gvi.Integrator(system, method)
    verlet = gvi.Integrator(system, gvi.Galerkin(1))
    h, t0 = 0.3, 0.7
    q, p = composed.step(q0, p0, h, t0=t0)
    q1, p1 = np.asarray(q0, float), np.asarray(p0, float)
    t = t0
    for g, end in zip(method.coefficients, method.nodes, strict=True):
        q1, p1 = verlet.step(q1, p1, g * h, t0=t)
        t = t0 + end * h
    assert np.allclose(q, q1, rtol=0, atol=1e-14) and np.allclose(p, p1, rtol=0, atol=1e-14)


@pytest.mark.parametrize("order", [4, 6])
@pytest.mark.parametrize("problem", [kepler(0.5), driven_oscillator()], ids=["kepler", "driven"])
def test_a_splitting_step_is_its_kicks_and_drifts(problem, order):
    # independent of the loop: b_1 h F, then per drift a_i h M^-1 p and b_{i+1} h F(tau_i)
    method = gvi.Composition(order, "blanes_moan")
    system = problem.system
    q0 = np.asarray(problem.q0, float)
    p0 = np.asarray(problem.v0, float)  # unit masses: p = v
    h, t0 = 0.3, 0.7
    q, p = gvi.Integrator(system, method).step(q0, p0, h, t0=t0)
    prm = system.parameter_vector(None)

    def force(t, x):
        return system.evaluate("gradient", t, x, np.zeros_like(x), prm)[: system.n]

    x, y, t = q0.copy(), p0.copy(), t0
    y = y + method.kicks[0] * h * force(t, x)
    for a, b in zip(method.coefficients, method.kicks[1:], strict=True):
        x, t = x + a * h * y, t + a * h
        y = y + b * h * force(t, x)
    assert np.allclose(q, x, rtol=0, atol=1e-14) and np.allclose(p, y, rtol=0, atol=1e-14)


def test_a_gyroscopic_term_varying_in_time_refuses_splittings_by_name_not_compositions():
    system = _gauge_system()
    with pytest.raises(ValueError, match=r"a\(t\)\.v .* varies with t.*Composition\(order=4, "
                       r"scheme='suzuki'\)"):  # fmt: skip
        gvi.Integrator(system, gvi.Composition(4))
    assert composition_for(system, 6) == gvi.Composition(6, "kahan_li")
    assert composition_for(kepler(0.5).system, 6) == gvi.Composition(6)
    # the composition of Stormer-Verlet keeps its order on it: q'' = -q + sin t
    integrator = gvi.Integrator(system, gvi.Composition(4, "suzuki"))
    fine = integrator.integrate([1.0], p0=[1.5], h=4.0 / 640, n_steps=640)
    errors = []
    for n in (20, 40):
        traj = integrator.integrate([1.0], p0=[1.5], h=4.0 / n, n_steps=n)
        errors.append(abs(traj.q[-1, 0] - fine.q[-1, 0]))
    assert 3.6 < np.log2(errors[0] / errors[1]) < 4.6
    picked = gvi.choose_method(
        system, [1.0], [0.5], t_final=2.0, tol=1e-6, degrees=(1,), families=("lobatto",),
        compositions=(4,), timing_steps=200, repeats=1,
    )  # fmt: skip
    studied = [candidate.method for candidate in picked.candidates]
    assert gvi.Composition(4, "suzuki") in studied and gvi.Composition(4) not in studied


# ------------------------------------------------------------ geometric properties
def test_angular_momentum_conserved_to_round_off(orbit):
    traj = gvi.Integrator(orbit.system, gvi.Composition(8)).integrate(
        orbit.q0, orbit.v0, h=0.1, n_steps=10_000
    )
    x, y = orbit.system.q
    J = traj.momentum((-y, x))
    assert np.max(np.abs(J - J[0])) < 2e-13


def test_energy_bounded_without_drift_over_1e5_steps(orbit):
    traj = gvi.Integrator(orbit.system, gvi.Composition(6)).integrate(
        orbit.q0, orbit.v0, h=0.1, n_steps=100_000, save_every=10
    )
    error = np.abs(traj.energy() - traj.energy()[0])
    half = len(error) // 2
    assert error.max() < 5e-6  # O(h^6) at h = 0.1, e = 0.5
    # bounded oscillation, no drift: the second half's band is the first half's
    assert error[half:].max() < 1.5 * error[:half].max()


# --------------------------------------------------------------------- run options
@pytest.fixture(scope="module")
def swing():
    problem = pendulum()
    return problem, gvi.Integrator(problem.system, gvi.Composition(6))


def test_save_every_t_span_and_backwards(swing):
    problem, integrator = swing
    full = integrator.integrate(problem.q0, problem.v0, h=0.1, n_steps=40)
    strided = integrator.integrate(problem.q0, problem.v0, h=0.1, n_steps=40, save_every=8)
    assert np.array_equal(strided.q, full.q[::8]) and np.array_equal(strided.t, full.t[::8])
    spanned = integrator.integrate(problem.q0, problem.v0, h=0.1, t_span=(0.0, 3.95))
    assert spanned.t[-1] == pytest.approx(3.95) and len(spanned.t) == 41
    back = integrator.integrate(spanned.q[-1], p0=spanned.p[-1], h=-spanned.t[1], t0=3.95,
                                n_steps=40)  # fmt: skip
    # symmetric method: backwards retraces the run to round-off
    assert np.allclose(back.q[-1], problem.q0, atol=1e-13)


def test_dense_output_and_t_eval_have_the_method_order():
    problem = harmonic_oscillator()
    integrator = gvi.Integrator(problem.system, gvi.Composition(6))
    errors = []
    for h in (0.2, 0.1):
        traj = integrator.integrate(problem.q0, problem.v0, h=h, t_span=(0.0, 4.0),
                                    dense_output=True)  # fmt: skip
        t = np.linspace(0.05, 3.95, 97)
        errors.append(np.max(np.abs(traj.sol(t)[:, 0] - problem.exact(t)[:, 0])))
        at = integrator.integrate(problem.q0, problem.v0, h=h, t_span=(0.0, 4.0), t_eval=t)
        assert np.array_equal(at.q, traj.sol(t))
    assert np.log2(errors[0] / errors[1]) > 5.6


def test_events_located_at_the_method_order():
    problem = harmonic_oscillator(q0=1.0, v0=0.0)
    integrator = gvi.Integrator(problem.system, gvi.Composition(8))
    q = problem.system.q[0]
    traj = integrator.integrate(problem.q0, problem.v0, h=0.25, t_span=(0.0, 10.0),
                                events=Event(q))  # fmt: skip
    # zeros of cos t
    assert np.allclose(traj.t_events[0], np.pi / 2 + np.pi * np.arange(3), atol=1e-9)
    stop = integrator.integrate(problem.q0, problem.v0, h=0.25, t_span=(0.0, 10.0),
                                events=Event(q, terminal=True))  # fmt: skip
    assert stop.t[-1] == pytest.approx(np.pi / 2, abs=1e-9)


def test_integrate_many_equals_one_by_one(swing):
    problem, integrator = swing
    starts = np.array([[0.5], [1.0], [1.5]])
    ensemble = integrator.integrate_many(starts, [0.3], h=0.1, n_steps=30, workers=1)
    for start, traj in zip(starts, ensemble.trajectories, strict=True):
        alone = integrator.integrate(start, [0.3], h=0.1, n_steps=30)
        assert np.array_equal(traj.q, alone.q)


def test_pickling_integrators_before_and_after_use(swing):
    problem, integrator = swing
    fresh = pickle.loads(pickle.dumps(gvi.Integrator(problem.system, gvi.Composition(4))))
    assert fresh.method == gvi.Composition(4)
    run = integrator.integrate(problem.q0, problem.v0, h=0.1, n_steps=10)
    copy = pickle.loads(pickle.dumps(integrator))
    assert np.array_equal(copy.integrate(problem.q0, problem.v0, h=0.1, n_steps=10).q, run.q)


def test_step_del_reproduces_the_run(orbit):
    integrator = gvi.Integrator(orbit.system, gvi.Composition(6))
    traj = integrator.integrate(orbit.q0, orbit.v0, h=0.2, n_steps=3, t0=0.5)
    q2 = integrator.step_del(traj.q[0], traj.q[1], 0.2, t0=0.5)
    assert np.allclose(q2, traj.q[2], rtol=0, atol=1e-13)


def test_step_del_with_time_dependence():
    problem = driven_oscillator()
    integrator = gvi.Integrator(problem.system, gvi.Composition(4))
    traj = integrator.integrate(problem.q0, problem.v0, h=0.3, n_steps=2, t0=1.0)
    q2 = integrator.step_del(traj.q[0], traj.q[1], 0.3, t0=1.0)
    assert np.allclose(q2, traj.q[2], rtol=0, atol=1e-13)


# -------------------------------------------------------------------- bad input
def test_structures_without_explicit_sub_steps_are_refused_by_name():
    q, v = sp.symbols("q v")
    varying = gvi.LagrangianSystem((1 + q**2) * v**2 / 2 - q**2 / 2, [q], [v])
    with pytest.raises(ValueError, match="mass matrix d2L/dv2 varies"):
        gvi.Integrator(varying, gvi.Composition(4))
    x, y, vx, vy = sp.symbols("x y vx vy")
    coupled = gvi.LagrangianSystem((vx**2 + vy**2) / 2 + x * vy - y * vx, [x, y], [vx, vy])
    with pytest.raises(ValueError, match="couples positions and velocities"):
        gvi.Integrator(coupled, gvi.Composition(4))
    damped = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v], forces=[-0.1 * v])
    with pytest.raises(ValueError, match="forces depend on the velocities"):
        gvi.Integrator(damped, gvi.Composition(4))
    pendulum_xy = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - y, [x, y], [vx, vy], constraints=[x**2 + y**2 - 1]
    )
    with pytest.raises(ValueError, match="constraints"):
        gvi.Integrator(pendulum_xy, gvi.Composition(4))


def test_numpy_backend_and_adaptive_are_refused_by_name():
    problem = pendulum()
    with pytest.raises(ValueError, match="backend must be 'numba'"):
        gvi.Integrator(problem.system, gvi.Composition(4), backend="numpy")
    orbit = kepler(0.5)
    x, y = orbit.system.q
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with pytest.raises(ValueError, match="AdaptiveIntegrator"):
            gvi.AdaptiveIntegrator(orbit.system, gvi.Composition(4), g=(x**2 + y**2) ** 0.75)


def test_method_type_error_names_both_kinds():
    with pytest.raises(TypeError, match="Galerkin or Composition"):
        gvi.Integrator(pendulum().system, "verlet")
