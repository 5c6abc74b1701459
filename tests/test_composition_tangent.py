"""The tangent map of compositions of Störmer–Verlet (``gvi.Composition`` with ``tangent=``,
``sensitivity=``, ``renormalize_every=``): against central differences and an independent
NumPy tangent, symplecticity, the general Newton loop's tangent of Störmer–Verlet, Lyapunov
exponents and MEGNO, gradients, and the other run options."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.problems.chains import spring_chain
from galerkin_vi.problems.mechanics import henon_heiles, pendulum
from galerkin_vi.run.composed_del import composition_map
from galerkin_vi.run.segment import substeps

t, q, v, x, y, vx, vy = sp.symbols("t q v x y vx vy")
k, c, m = sp.symbols("k c m")

CHAOTIC = henon_heiles()  # q0 = (0, -0.2) at E = 1/8: in the chaotic sea
REGULAR = henon_heiles(q0=(0.0, 0.1))  # on a KAM torus
SCHEMES = [
    (2, "verlet"), (4, "yoshida"), (4, "blanes_moan"), (6, "kahan_li"), (6, "blanes_moan"),
    (8, "mclachlan"),
]  # fmt: skip
J4 = np.block([[np.zeros((2, 2)), np.eye(2)], [-np.eye(2), np.zeros((2, 2))]])


def driven():
    """Two coupled anharmonic springs, the first driven through a(t) = c cos t: a spring
    constant in the force and a parameter in the momentum's a(t)."""
    L = (
        (vx**2 + vy**2) / 2 + c * sp.cos(t) * vx
        - k * x**2 / 2 - (y - x) ** 2 / 2 - y**4 / 4
    )  # fmt: skip
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], t=t, params={k: 1.3, c: 0.4})


def pushed():
    """The springs of :func:`driven` pushed through the potential, x cos t, with a
    momentum term c vx constant in time: what a splitting takes."""
    L = (
        (vx**2 + vy**2) / 2 + c * vx
        - k * x**2 / 2 - (y - x) ** 2 / 2 - y**4 / 4 + x * sp.cos(t)
    )  # fmt: skip
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], t=t, params={k: 1.3, c: 0.4})


#: a composition of Störmer–Verlet on a(t) = c cos t, a splitting on a constant a = c
WITH_PARAMETERS = [
    pytest.param(4, "suzuki", driven, id="suzuki-driven"),
    pytest.param(4, "blanes_moan", pushed, id="blanes_moan-pushed"),
]


def composed(order: int = 4, scheme: str | None = None, system=None) -> gvi.Integrator:
    return gvi.Integrator(system or CHAOTIC.system, gvi.Composition(order, scheme))


def end_state(integrator, x0, **run):
    traj = integrator.integrate(x0[:2], p0=x0[2:], **run)
    return np.r_[traj.q[-1], traj.p[-1]]


def central_differences(f, x0, eps=1e-6):
    return np.column_stack([(f(x0 + eps * e) - f(x0 - eps * e)) / (2 * eps) for e in np.eye(4)])


@pytest.mark.parametrize(("order", "scheme"), SCHEMES)
def test_tangent_matches_differences_and_leaves_the_states_bit_for_bit(order, scheme):
    integrator = composed(order, scheme)
    run = dict(h=0.1, n_steps=50)
    plain = integrator.integrate(CHAOTIC.q0, CHAOTIC.v0, **run)
    traj = integrator.integrate(CHAOTIC.q0, CHAOTIC.v0, tangent=True, **run)
    np.testing.assert_array_equal(traj.q, plain.q)
    np.testing.assert_array_equal(traj.p, plain.p)
    x0 = np.r_[traj.q[0], traj.p[0]]
    expected = central_differences(lambda z: end_state(integrator, z, **run), x0)
    phi = traj.tangent[-1]
    assert np.abs(phi - expected).max() <= 1e-7 * np.abs(phi).max()
    np.testing.assert_array_equal(traj.tangent[0], np.eye(4))


@pytest.mark.parametrize(("order", "scheme"), SCHEMES)
def test_tangent_is_symplectic_after_100_steps(order, scheme):
    traj = composed(order, scheme).integrate(
        CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=100, tangent=True, save_every=100
    )
    phi = traj.tangent[-1]
    assert np.abs(phi - np.eye(4)).max() > 1  # far from the identity: the test has teeth
    assert np.abs(phi.T @ J4 @ phi - J4).max() < 1e-12 * max(1.0, np.abs(phi).max() ** 2)


@pytest.mark.parametrize("problem", [pendulum(q0=3.0, v0=1.5), spring_chain(8, beta=1.0)],
                         ids=["angles", "banded"])  # fmt: skip
def test_tangent_across_whole_turns_and_with_banded_hessians_matches_differences(problem):
    integrator = gvi.Integrator(problem.system, gvi.Composition(6))
    q0, v0 = np.asarray(problem.q0, float), np.asarray(problem.v0, float)
    n = q0.shape[0]
    run = dict(h=0.1, n_steps=60, params=problem.params)
    traj = integrator.integrate(q0, v0, tangent=True, **run)
    if n == 1:
        assert traj.q[-1, 0] > 2 * np.pi  # the angle went over the top: the turns are kept

    def end(z):
        other = integrator.integrate(z[:n], p0=z[n:], **run)
        return np.r_[other.q[-1], other.p[-1]]

    z0, eps = np.r_[traj.q[0], traj.p[0]], 1e-6
    expected = np.column_stack(
        [(end(z0 + eps * e) - end(z0 - eps * e)) / (2 * eps) for e in np.eye(2 * n)]
    )
    assert np.abs(traj.tangent[-1] - expected).max() <= 1e-7 * np.abs(expected).max()


@pytest.mark.parametrize(
    ("scheme", "make"), [("kahan_li", driven), ("blanes_moan", pushed)], ids=["kahan_li", "bm"]
)
def test_one_step_equals_the_independent_numpy_tangent_of_the_composition(scheme, make):
    method = gvi.Composition(6, scheme)
    system = make()
    integrator = gvi.Integrator(system, method)
    q0, p0, h = np.array([0.3, -0.5]), np.array([0.2, 0.7]), 0.2
    prm = system.parameter_vector(None)
    traj = integrator.integrate(q0, p0=p0, h=h, n_steps=1, t0=0.4, tangent=True)
    q1, p1, dq, dp = composition_map(system, substeps(method), 0.4, h, q0, p0, prm, tangent=True)
    np.testing.assert_allclose(traj.q[-1], q1, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(traj.p[-1], p1, rtol=1e-14, atol=1e-15)
    np.testing.assert_allclose(traj.tangent[-1][:, 2:], np.vstack([dq, dp]), atol=1e-13)


@pytest.mark.parametrize(("order", "scheme", "make"), WITH_PARAMETERS)
def test_sensitivities_to_a_spring_constant_and_a_momentum_term_match_differences(
    order, scheme, make
):
    system = make()
    integrator = gvi.Integrator(system, gvi.Composition(order, scheme))
    q0, v0, run = [0.3, -0.5], [0.2, 0.7], dict(h=0.05, n_steps=80, t0=0.1)
    traj = integrator.integrate(q0, v0, tangent=True, sensitivity=[k, "c"], **run)
    assert traj.sensitivity.shape == (81, 4, 2)
    assert traj.variations.parameters == (k, c)

    def end(params):
        other = integrator.integrate(q0, v0, params=params, **run)
        return np.r_[other.q[-1], other.p[-1]]

    for j, (symbol, value) in enumerate(((k, 1.3), (c, 0.4))):
        eps = 1e-6
        expected = (end({symbol: value + eps}) - end({symbol: value - eps})) / (2 * eps)
        got = traj.sensitivity[-1][:, j]
        assert np.abs(got - expected).max() <= 1e-7 * np.abs(got).max()
    # the start's momentum p0 = v0 + a(t0), a = c cos(t) e_x or c e_x, moves with c at fixed v0
    moved = np.cos(0.1) if make is driven else 1.0
    np.testing.assert_allclose(traj.sensitivity[0][:, 1], [0, 0, moved, 0], atol=1e-15)
    x0 = np.r_[traj.q[0], traj.p[0]]
    expected = central_differences(lambda z: end_state(integrator, z, **run), x0)
    assert np.abs(traj.tangent[-1] - expected).max() <= 1e-7 * np.abs(expected).max()


@pytest.mark.parametrize("system", [CHAOTIC.system, driven()], ids=["henon_heiles", "driven"])
def test_stormer_verlet_as_a_composition_has_the_general_loops_tangent(system):
    run = dict(h=0.05, n_steps=200, tangent=True, save_every=50)
    if system.params:
        run["sensitivity"] = [k, c]
    x0 = ([0.1, -0.2], [0.3, 0.2])
    verlet = gvi.Integrator(system, gvi.Composition(2, "verlet")).integrate(*x0, **run)
    newton = gvi.Integrator(system, gvi.Galerkin(1)).integrate(*x0, **run)
    np.testing.assert_allclose(verlet.q, newton.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(verlet.tangent, newton.tangent, rtol=0, atol=1e-12)
    if system.params:
        np.testing.assert_allclose(verlet.sensitivity, newton.sensitivity, rtol=0, atol=1e-12)


def test_lyapunov_exponents_and_megno_separate_regular_from_chaotic_orbits():
    integrator = composed(4, "yoshida")
    run = dict(h=0.1, n_steps=20_000, directions=1)
    chaotic = gvi.lyapunov_spectrum(integrator, CHAOTIC.q0, CHAOTIC.v0, **run)
    regular = gvi.lyapunov_spectrum(integrator, REGULAR.q0, REGULAR.v0, **run)
    assert chaotic.success and regular.success
    # Henon-Heiles' docstring: about 0.08 in the chaotic sea, below 0.006 on the tori
    assert 0.03 < chaotic.exponents[0] < 0.2
    assert abs(regular.exponents[0]) < 0.01
    full = gvi.lyapunov_spectrum(integrator, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=5_000)
    # the spectrum of a symplectic map comes in pairs +-lambda: it sums to zero
    assert abs(full.exponents.sum()) < 1e-10
    frame = full.trajectory.tangent[-1]
    np.testing.assert_allclose(frame.T @ frame, np.eye(4), atol=1e-12)
    quasi = gvi.megno(integrator, REGULAR.q0, REGULAR.v0, h=0.1, n_steps=20_000, save_every=100)
    wild = gvi.megno(integrator, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=20_000, save_every=100)
    assert quasi.final == pytest.approx(2.0, abs=0.3)
    assert wild.final > 10


def test_save_every_t_span_chunks_and_ensembles_carry_the_same_variations():
    integrator = composed(6)
    start = (CHAOTIC.q0, CHAOTIC.v0)
    every = integrator.integrate(*start, h=0.1, n_steps=40, tangent=True, sensitivity=None)
    sparse = integrator.integrate(*start, h=0.1, n_steps=40, tangent=True, save_every=7)
    rows = np.r_[np.arange(0, 41, 7), 40]
    np.testing.assert_array_equal(sparse.t, every.t[rows])
    np.testing.assert_array_equal(sparse.tangent, every.tangent[rows])
    span = integrator.integrate(*start, h=0.11, t_span=(0.0, 4.0), tangent=True)
    equal = integrator.integrate(*start, h=4.0 / 37, n_steps=37, tangent=True)  # 37 >= 4 / 0.11
    assert span.t[-1] == 4.0 and span.tangent.shape == (38, 4, 4)
    np.testing.assert_allclose(span.tangent, equal.tangent, rtol=1e-13, atol=1e-13)
    # a second run from the first's end composes: Phi(0, 40) = Phi(20, 40) Phi(0, 20)
    first = integrator.integrate(*start, h=0.1, n_steps=20, tangent=True)
    second = integrator.integrate(
        first.q[-1], p0=first.p[-1], t0=2.0, h=0.1, n_steps=20, tangent=True
    )
    np.testing.assert_allclose(
        second.tangent[-1] @ first.tangent[-1], every.tangent[-1], rtol=1e-12, atol=1e-12
    )
    many = integrator.integrate_many(
        [CHAOTIC.q0, REGULAR.q0], [CHAOTIC.v0, REGULAR.v0], h=0.1, n_steps=40, tangent=True
    )
    np.testing.assert_array_equal(many[0].tangent, every.tangent)


def test_events_dense_output_and_pickling_with_the_tangent_map():
    integrator = composed(4)
    crossing = gvi.Event(x, terminal=True, direction=-1)
    traj = integrator.integrate(
        CHAOTIC.q0, CHAOTIC.v0, h=0.05, t_span=(0.0, 20.0), tangent=True, events=crossing
    )
    assert traj.status == 1 and len(traj.t_events[0]) == 1
    assert traj.tangent.shape == (len(traj.t), 4, 4) and np.isfinite(traj.tangent).all()
    assert traj.sol is not None
    # the event row's variations are the step's from the row before, of length t_e - t_k
    tail = integrator.integrate(
        traj.q[-2], p0=traj.p[-2], t0=traj.t[-2], h=traj.t[-1] - traj.t[-2], n_steps=1,
        tangent=traj.tangent[-2],
    )  # fmt: skip
    np.testing.assert_allclose(traj.tangent[-1], tail.tangent[-1], rtol=1e-14, atol=1e-14)
    again = pickle.loads(pickle.dumps(integrator))
    run = dict(h=0.1, n_steps=30, tangent=True)
    np.testing.assert_array_equal(
        again.integrate(CHAOTIC.q0, CHAOTIC.v0, **run).tangent,
        integrator.integrate(CHAOTIC.q0, CHAOTIC.v0, **run).tangent,
    )


@pytest.mark.parametrize(("order", "scheme", "make"), WITH_PARAMETERS)
def test_the_gradient_of_a_composed_run_is_forward_mode_and_matches_differences(
    order, scheme, make
):
    system = make()
    integrator = gvi.Integrator(system, gvi.Composition(order, scheme))
    run = dict(h=0.05, n_steps=60)
    q0, v0 = np.array([0.3, -0.5]), np.array([0.2, 0.7])
    loss = gvi.Loss(terminal=x**2 * y, running=0.05 * k * y**2)
    grad = gvi.gradient(integrator, loss, q0, v0, wrt=("q0", "v0", "params"), **run)
    assert grad.success and grad.mode == "forward"

    def value(q_start, v_start, kv=1.3):
        other = integrator.integrate(q_start, v_start, params={k: kv}, **run)
        return other.q[-1, 0] ** 2 * other.q[-1, 1] + 0.05 * kv * np.sum(other.q[:-1, 1] ** 2)

    eps = 1e-6
    for i in range(2):
        e = np.eye(2)[i] * eps
        assert grad.q0[i] == pytest.approx((value(q0 + e, v0) - value(q0 - e, v0)) / (2 * eps),
                                           rel=1e-6)  # fmt: skip
        assert grad.v0[i] == pytest.approx((value(q0, v0 + e) - value(q0, v0 - e)) / (2 * eps),
                                           rel=1e-6)  # fmt: skip
    expected = (value(q0, v0, 1.3 + eps) - value(q0, v0, 1.3 - eps)) / (2 * eps)
    assert grad.params[k] == pytest.approx(expected, rel=1e-6)


def test_what_the_explicit_tangent_cannot_do_is_refused_by_name():
    heavy = gvi.LagrangianSystem(m * v**2 / 2 - q**2 / 2 - q**4 / 4, [q], [v], params={m: 1.5})
    integrator = gvi.Integrator(heavy, gvi.Composition(4))
    with pytest.raises(ValueError, match=r"sensitivity to m: .*mass matrix"):
        integrator.integrate([0.3], [0.1], h=0.1, n_steps=5, sensitivity=[m])
    # the tangent alone needs no derivative in m
    traj = integrator.integrate([0.3], [0.1], h=0.1, n_steps=5, tangent=True)
    phi = traj.tangent[-1]
    assert np.linalg.det(phi) == pytest.approx(1.0, abs=1e-13)
    with pytest.raises(ValueError, match="t_eval"):
        integrator.integrate([0.3], [0.1], h=0.1, n_steps=5, tangent=True, t_eval=[0.25])
