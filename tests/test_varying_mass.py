"""The velocity-stage loop for a mass matrix that varies with q (path "varying_mass")."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen, problems
from galerkin_vi.method.velocity_stages import has_velocity_stages, varying_mass_tables
from galerkin_vi.run.loop_choice import EARLY_HAND_OVER

numba = pytest.importorskip("numba")

GAUSS = [gvi.Galerkin(s, gvi.gauss_legendre(s)) for s in (1, 2, 3, 4)]
LOBATTO = [gvi.Galerkin(s) for s in (1, 2, 3, 4)]


def _id(method) -> str:
    return f"{method.quadrature.family}-{method.degree}"


# ------------------------------------------------------------------------ tables
@pytest.mark.parametrize("method", GAUSS, ids=_id)
def test_tables_are_a_symplectic_collocation_pair(method):
    t = varying_mass_tables(method)
    r = t.b.size
    # collocation: A 1 = c, b sums to one, and A integrates polynomials of degree < r
    np.testing.assert_allclose(t.A.sum(axis=1), t.c, rtol=0, atol=1e-15)
    np.testing.assert_allclose(t.b.sum(), 1.0, rtol=0, atol=1e-15)
    for k in range(r):
        np.testing.assert_allclose(t.A @ t.c**k, t.c ** (k + 1) / (k + 1), rtol=0, atol=1e-15)
    # the symplectic condition b_i abar_ij + b_j a_ji = b_i b_j
    B = np.outer(t.b, t.b)
    np.testing.assert_allclose(t.b[:, None] * t.Abar + (t.b[:, None] * t.A).T, B, atol=1e-15)
    # the extrapolation reproduces polynomials of degree < r at the next step's nodes
    for k in range(r):
        np.testing.assert_allclose(t.X @ t.c**k, (1 + t.c) ** k, rtol=1e-13, atol=0)
    np.testing.assert_allclose(t.Abar, t.A, rtol=0, atol=2e-16)  # Gauss: its own partner


def test_only_gauss_collocation_has_velocity_stages():
    assert has_velocity_stages(gvi.Galerkin(3, gvi.gauss_legendre(3)))
    assert not has_velocity_stages(gvi.Galerkin(3))  # Lobatto: not IIIA-IIIB for M(q)
    over = gvi.Galerkin(2, gvi.gauss_legendre(4))
    assert not has_velocity_stages(over)
    with pytest.raises(ValueError, match="no velocity-stage form"):
        varying_mass_tables(over)


# ------------------------------------------------------------------ the loop chosen
def _polar():
    """A particle in a central field in polar coordinates: M = diag(1, r^2) varies with r."""
    r, th, vr, vth, k = sp.symbols("r theta v_r v_theta k")
    L = (vr**2 + r**2 * vth**2) / 2 + k / r
    return gvi.LagrangianSystem(L, [r, th], [vr, vth], params={k: 1.0})


def test_the_loop_is_chosen_for_a_mass_matrix_that_varies():
    system = problems.double_pendulum().system
    assert gvi.Integrator(system, GAUSS[2]).kernel_path == "varying_mass"
    # s <= 2 (a small Jacobian), Lobatto, overintegrated Galerkin, specialize=False and
    # NumPy stay with Newton
    assert gvi.Integrator(system, GAUSS[1]).kernel_path == "newton"
    assert gvi.Integrator(system, LOBATTO[2]).kernel_path == "newton"
    assert gvi.Integrator(system, gvi.Galerkin(2, gvi.gauss_legendre(4))).kernel_path == "newton"
    assert gvi.Integrator(system, GAUSS[2], specialize=False).kernel_path == "newton"
    assert gvi.Integrator(system, GAUSS[2], backend="numpy").kernel_path == "newton"
    # a constant mass keeps the stage form
    assert gvi.Integrator(problems.kepler().system, GAUSS[2]).kernel_path == "separable"


# --------------------------------------------------------------- the same map
@pytest.mark.parametrize("method", GAUSS[2:], ids=_id)
def test_same_map_as_newton_on_the_double_pendulum(method):
    problem = problems.double_pendulum()
    run = dict(h=0.02, n_steps=300, params=problem.params)
    fast_integrator = gvi.Integrator(problem.system, method)
    assert fast_integrator.kernel_path == "varying_mass"
    fast = fast_integrator.integrate(problem.q0, problem.v0, **run)
    newton = gvi.Integrator(problem.system, method, specialize=False).integrate(
        problem.q0, problem.v0, **run
    )
    assert fast.success and fast.n_steps == 300
    np.testing.assert_allclose(fast.q, newton.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.p, newton.p, rtol=0, atol=1e-12)
    # a fixed point: more sweeps than Newton iterations, far below the cap
    assert newton.mean_newton_iterations < fast.mean_newton_iterations < 12


def test_noether_momentum_and_energy_in_polar_coordinates():
    system = _polar()
    method = GAUSS[2]
    traj = gvi.Integrator(system, method).integrate([1.0, 0.0], [0.1, 1.1], h=0.05, n_steps=4000)
    assert traj.success
    # theta is cyclic: p_theta = r^2 v_theta is conserved to round-off
    p_theta = traj.p[:, 1]
    assert np.abs(p_theta - p_theta[0]).max() <= 1e-14 * abs(p_theta[0])
    # energy bounded (no drift) at order 6
    energy = traj.energy()
    assert np.abs(energy - energy[0]).max() < 1e-9


def test_spherical_coordinates_take_the_diagonal_mass_path_and_conserve_p_phi():
    # n = 3, M = diag(1, r^2, r^2 sin^2 theta): the closed-form velocity, not the LU
    r, th, ph, vr, vth, vph = sp.symbols("r theta phi v_r v_theta v_phi")
    L = (vr**2 + r**2 * vth**2 + r**2 * sp.sin(th) ** 2 * vph**2) / 2 + 1 / r
    system = gvi.LagrangianSystem(L, [r, th, ph], [vr, vth, vph])
    integrator = gvi.Integrator(system, GAUSS[2])
    assert integrator.kernel_path == "varying_mass"
    run = dict(h=0.05, n_steps=2000)
    traj = integrator.integrate([1.0, 1.2, 0.0], [0.1, 0.3, 0.9], **run)
    newton = gvi.Integrator(system, GAUSS[2], specialize=False).integrate(
        [1.0, 1.2, 0.0], [0.1, 0.3, 0.9], **run
    )
    assert traj.success
    p_phi = traj.p[:, 2]
    assert np.abs(p_phi - p_phi[0]).max() <= 1e-14 * abs(p_phi[0])
    np.testing.assert_allclose(traj.q, newton.q, rtol=0, atol=1e-9)


def _chain_pendulum(links: int) -> gvi.LagrangianSystem:
    """Unit masses and lengths: M_ij = (links - max(i, j)) cos(q_i - q_j), a full M."""
    q = sp.symbols(f"q0:{links}")
    v = sp.symbols(f"v0:{links}")
    kinetic = (
        sum(
            (links - max(i, j)) * sp.cos(q[i] - q[j]) * v[i] * v[j]
            for i in range(links)
            for j in range(links)
        )
        / 2
    )
    potential = -sum((links - i) * 9.81 * sp.cos(q[i]) for i in range(links))
    return gvi.LagrangianSystem(kinetic - potential, list(q), list(v))


@pytest.mark.parametrize("method", GAUSS[2:], ids=_id)
def test_triple_pendulum_takes_the_lu_path_and_the_same_map_as_newton(method):
    system = _chain_pendulum(3)
    integrator = gvi.Integrator(system, method)
    assert integrator.kernel_path == "varying_mass"
    start = ([0.5, -0.3, 0.8], [0.0, 0.4, -0.2])
    run = dict(h=0.01, n_steps=300)
    fast = integrator.integrate(*start, **run)
    newton = gvi.Integrator(system, method, specialize=False).integrate(*start, **run)
    assert fast.success
    np.testing.assert_allclose(fast.q, newton.q, rtol=0, atol=1e-11)
    np.testing.assert_allclose(fast.p, newton.p, rtol=0, atol=1e-11)
    energy = fast.energy()
    assert np.abs(energy - energy[0]).max() < 1e-8 * abs(energy[0])


def test_a_step_the_fixed_point_cannot_take_hands_the_run_to_newton(monkeypatch):
    # damping that grows with t: late in the run the sweeps contract too slowly
    q, v, t = sp.symbols("q v t")
    system = gvi.LagrangianSystem(
        (2 + sp.sin(q)) * v**2 / 2 + sp.cos(q), [q], [v], t=t, forces=[-40 * t * v]
    )
    method = GAUSS[2]
    run = dict(h=0.05, n_steps=60, save_every=3)
    fast_integrator = gvi.Integrator(system, method)
    assert fast_integrator.kernel_path == "varying_mass"
    handovers = []
    from galerkin_vi.run import segment

    original = segment.continue_from_last_row

    def spy(spec, run, out, result, path):
        handovers.append(result.steps)  # the step the fixed point stopped before
        return original(spec, run, out, result, path)

    monkeypatch.setattr(segment, "continue_from_last_row", spy)
    fast = fast_integrator.integrate([3.0], [3.0], **run)
    # well into the run, not at the start: the closed-form sweep keeps the fixed point
    # until a step needs more than maxiter = 30 sweeps (step 25; with maxiter = 100,
    # step 51)
    assert len(handovers) == 1 and 8 < handovers[0] < 60
    newton = gvi.Integrator(system, method, specialize=False).integrate([3.0], [3.0], **run)
    assert fast.success and fast.n_steps == 60
    np.testing.assert_array_equal(fast.t, newton.t)
    # the angle wrapped before the hand-over: whole turns carried across the join
    assert np.abs(fast.q).max() > np.pi
    np.testing.assert_allclose(fast.q, newton.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.p, newton.p, rtol=0, atol=1e-12)


def test_ensemble_members_equal_single_runs():
    system = problems.double_pendulum().system
    integrator = gvi.Integrator(system, GAUSS[2])
    assert integrator.kernel_path == "varying_mass"
    q0s = [[0.5, 0.1], [1.0, -0.3], [2.0, 0.0]]
    v0s = [[0.0, 0.2], [0.1, 0.0], [-0.5, 0.5]]
    params = problems.double_pendulum().params
    many = integrator.integrate_many(q0s, v0s, h=0.02, n_steps=50, params=params, workers=1)
    for i in range(3):
        one = integrator.integrate(q0s[i], v0s[i], h=0.02, n_steps=50, params=params)
        np.testing.assert_array_equal(many.q[i], one.q)
        np.testing.assert_array_equal(many.p[i], one.p)


def test_generated_mass_function_matches_the_hessian():
    # the point function the loop calls writes L_q + f, L_v, L_qv + f_v and L_vv as the
    # Hessian function does (here with a velocity-dependent force)
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem((1 + q**2) * v**2 / 2 - q**2 / 2, [q], [v], forces=[-q * v])
    integrator = gvi.Integrator(system, GAUSS[1])
    namespace: dict = {}
    exec(integrator.source, namespace)  # noqa: S102 - our own generated module
    x, w, prm = np.array([0.7]), np.array([-1.3]), np.zeros(0)
    Lq, Lv, Lqv, Lvv = (np.zeros(k) for k in (1, 1, 1, 1))
    namespace["point_mass"](0.0, x, w, prm, Lq, Lv, Lqv, Lvv)
    Hq, Hv, Hqq, Hqv, Hvv, Fv = (np.zeros(1) for _ in range(6))
    namespace["point_hessian"](0.0, x, w, prm, Hq, Hv, Hqq, Hqv, Hvv, Fv)
    np.testing.assert_allclose(Lq, Hq, rtol=1e-15)
    np.testing.assert_allclose(Lv, Hv, rtol=1e-15)
    np.testing.assert_allclose(Lvv, Hvv, rtol=1e-15)
    np.testing.assert_allclose(Lqv, Hqv + Fv, rtol=1e-15)
    np.testing.assert_allclose(Lqv, [2 * 0.7 * -1.3 - 0.7], rtol=1e-15)


def test_fixed_point_false_keeps_newton_and_the_adaptive_integrator_does():
    system = problems.double_pendulum().system
    assert gvi.Integrator(system, GAUSS[2], fixed_point=False).kernel_path == "newton"
    x, y, vx, vy = sp.symbols("x y vx vy")
    r = sp.sqrt(x**2 + y**2)
    kepler = gvi.LagrangianSystem((vx**2 + vy**2) / 2 + 1 / r, [x, y], [vx, vy])
    g = gvi.encounter_scaling([r], 1.5)
    adaptive = gvi.AdaptiveIntegrator(kepler, GAUSS[2], g=g)
    # the time-transformed Lagrangian has a mass matrix that varies, r^(-3/2)
    assert adaptive.transform.extended.structure.quadratic_in_v
    # the fixed point by default (issue 30: Newton's carried factors crawled at small steps)
    assert adaptive.integrator.kernel_path == "varying_mass"
    chosen = gvi.AdaptiveIntegrator(kepler, GAUSS[2], g=g, fixed_point=False)
    assert chosen.integrator.kernel_path == "newton"


# ------------------------------------------------------- the velocity in closed form
def _kepler_poincare():
    x, y, vx, vy = sp.symbols("x y vx vy")
    r = sp.sqrt(x**2 + y**2)
    kepler = gvi.LagrangianSystem((vx**2 + vy**2) / 2 + 1 / r, [x, y], [vx, vy])
    return gvi.AdaptiveIntegrator(kepler, GAUSS[3], g=gvi.encounter_scaling([r], 1.5))


def _spherical():
    r, th, ph, vr, vth, vph = sp.symbols("r theta phi v_r v_theta v_phi")
    L = (vr**2 + r**2 * vth**2 + r**2 * sp.sin(th) ** 2 * vph**2) / 2 + 1 / r
    return gvi.LagrangianSystem(L, [r, th, ph], [vr, vth, vph])


def _damped_coriolis():
    # M = diag(1 + y^2, 2), a(q) = (y, -x) couples velocity and position, f depends on v
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = ((1 + y**2) * vx**2 + 2 * vy**2) / 2 + y * vx - x * vy - x**4 / 4 - y**2
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], forces=[-0.1 * vx, -0.2 * vy * x])


def _driven_full_mass():
    # a full 2 x 2 M that varies with t and q, a(t, q), and a force depending on t and v
    t, x, y, vx, vy = sp.symbols("t x y vx vy")
    m11, m12, m22 = 2 + sp.sin(t), sp.cos(x) / 2, 1 + y**2
    L = (m11 * vx**2 + 2 * m12 * vx * vy + m22 * vy**2) / 2 + t * y * vx - x**2 - y**4
    return gvi.LagrangianSystem(L, [x, y], [vx, vy], t=t, forces=[-t * vy, -0.3 * vx])


@pytest.mark.parametrize(
    "make", ["kepler_poincare", "double_pendulum", "spherical", "damped_coriolis", "driven"]
)
def test_point_velocity_solves_the_momentum_equation_and_gives_the_force_there(make):
    # V = M^-1 (p - a) makes L_v(q, V) = p, and F = (L_q + f)(q, V): checked against the
    # Lagrangian differentiated here, at random states
    system = {
        "kepler_poincare": lambda: _kepler_poincare().transform.extended,
        "double_pendulum": lambda: problems.double_pendulum().system,
        "spherical": _spherical,
        "damped_coriolis": _damped_coriolis,
        "driven": _driven_full_mass,
    }[make]()
    n = system.n
    spec = codegen.kernel_spec(system)
    assert {k[0] for k, _ in spec.velocity_entries} == {"V", "F"}
    namespace: dict = {}
    exec(codegen.render_module(spec, "k"), namespace)  # noqa: S102 - generated here
    t = 0.7
    args = [system.time_symbol, *system.q, *system.v, *system.params]
    Lv = sp.lambdify(args, list(system.pieces.Lv))
    force = sp.lambdify(args, list(system.pieces.force))
    rng = np.random.default_rng(7)
    prm = np.asarray(system.param_defaults, dtype=float) + rng.uniform(0.5, 1.0, len(system.params))
    for _ in range(5):
        q = rng.uniform(0.4, 1.3, n)
        p = rng.uniform(-1.0, 1.0, n)
        F, V = np.zeros((1, n)), np.zeros((1, n))
        namespace["point_velocity"](t, q, p, prm, F[0], V[0])
        np.testing.assert_allclose(Lv(t, *q, *V[0], *prm), p, rtol=1e-12, atol=1e-12)
        np.testing.assert_allclose(F[0], force(t, *q, *V[0], *prm), rtol=1e-12, atol=1e-12)


def test_no_closed_form_velocity_for_a_full_mass_matrix_of_three_rows_or_a_constant_mass():
    assert codegen.kernel_spec(_chain_pendulum(3)).velocity_entries == ()
    # without it a sweep costs about a Newton iteration: fixed_point=True hands over early
    three_links = gvi.Integrator(_chain_pendulum(3), GAUSS[3])
    assert three_links.kernel_path == "varying_mass"
    assert three_links.run_spec.hand_over == EARLY_HAND_OVER
    # constant mass, forces independent of v: the stage form runs it, not this loop
    assert codegen.kernel_spec(problems.henon_heiles().system).velocity_entries == ()


def _without_closed_form_velocity(monkeypatch):
    """Runs after this call sweep with the first-order correction (slot VELOCITY empty)."""
    from galerkin_vi.codegen import compiled
    from galerkin_vi.loops.abi import VELOCITY

    addresses = compiled.PointFunctions.addresses

    def without(self, names):
        out = addresses(self, names)
        out[VELOCITY] = 0
        return out

    monkeypatch.setattr(compiled.PointFunctions, "addresses", without)


def _velocity_slot(integrator) -> int:
    from galerkin_vi.loops.abi import VELOCITY

    return integrator.run_spec.model[0][VELOCITY]


@pytest.mark.parametrize("make", ["double_pendulum", "damped_coriolis", "spherical", "driven"])
def test_the_closed_form_sweep_reaches_the_fixed_point_of_the_corrected_one(make, monkeypatch):
    # the same stage equations, solved by two iterations to round-off: the same map
    system = {
        "double_pendulum": lambda: problems.double_pendulum().system,
        "spherical": _spherical,
        "damped_coriolis": _damped_coriolis,
        "driven": _driven_full_mass,
    }[make]()
    assert codegen.kernel_spec(system).velocity_entries
    start = ([0.9, 1.1, 0.2][: system.n], [0.3, -0.2, 1.2][: system.n])
    run = dict(h=0.02, n_steps=400)
    # one hand-over rule for both (fixed_point=True hands the corrected sweep over early)
    closed_integrator = gvi.Integrator(system, GAUSS[2], fixed_point="persistent")
    assert closed_integrator.kernel_path == "varying_mass"
    assert _velocity_slot(closed_integrator) != 0
    closed = closed_integrator.integrate(*start, **run)
    _without_closed_form_velocity(monkeypatch)
    corrected_integrator = gvi.Integrator(system, GAUSS[2], fixed_point="persistent")
    assert _velocity_slot(corrected_integrator) == 0
    corrected = corrected_integrator.integrate(*start, **run)
    assert closed.success and corrected.success
    assert not np.array_equal(closed.p, corrected.p)  # two different iterations ran
    # (the spherical orbit keeps r >= 0.6: with v_phi = 0.5 it passed r = 0.086, where
    # h = 0.02 is coarse and round-off grew to 1e-10 relative in two passes)
    np.testing.assert_allclose(closed.q, corrected.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(closed.p, corrected.p, rtol=0, atol=1e-12)
    # exact stage forces converge at least as fast as first-order corrected ones
    assert closed.mean_newton_iterations <= corrected.mean_newton_iterations + 0.05


def test_adaptive_kepler_with_the_closed_form_sweep_matches_the_corrected_one(monkeypatch):
    adaptive = _kepler_poincare()
    assert adaptive.integrator.kernel_path == "varying_mass"
    assert _velocity_slot(adaptive.integrator) != 0
    q0, v0 = [0.1, 0.0], [0.0, float(np.sqrt(1.9 / 0.1))]  # e = 0.9 from pericentre
    run = dict(h=0.2, t_final=2 * np.pi * 3, save_every=10**6)
    closed = adaptive.integrate(q0, v0, **run)
    _without_closed_form_velocity(monkeypatch)
    first_order = _kepler_poincare()
    assert _velocity_slot(first_order.integrator) == 0
    corrected = first_order.integrate(q0, v0, **run)
    assert closed.success and corrected.success and closed.n_steps == corrected.n_steps
    np.testing.assert_allclose(closed.q[-1], corrected.q[-1], rtol=0, atol=1e-11)
    np.testing.assert_allclose(closed.p[-1], corrected.p[-1], rtol=0, atol=1e-11)
    # back at the pericentre after three periods (the exact solution)
    np.testing.assert_allclose(closed.q[-1], q0, rtol=0, atol=1e-6)
    assert closed.mean_newton_iterations <= corrected.mean_newton_iterations + 0.05


@pytest.mark.parametrize(("maxiter", "hand_overs"), [(30, 1), (60, 0)])
def test_sweeps_that_grow_on_their_way_down_are_not_taken_for_round_off(
    maxiter, hand_overs, monkeypatch
):
    """Near r = 0.086 at h = 0.02 the sweeps contract by 0.2 and 0.6 in turn, and a sweep
    that grows the change below 1e-10 is not yet round-off: accepting it left an error of
    1e-11 that grew to 3.1e-7 after the encounter. The fixed point now sweeps on: within
    30 sweeps it hands the encounter to Newton, within 60 it converges there itself, and
    either run agrees with Newton's (8e-12 and 1.5e-11 measured)."""
    from galerkin_vi.run import segment

    system = _spherical()
    start, run = ([0.9, 1.1, 0.2], [0.3, -0.2, 0.5]), dict(h=0.02, n_steps=400)
    newton = gvi.Integrator(system, GAUSS[2], fixed_point=False).integrate(*start, **run)
    assert newton.q[:, 0].min() < 0.09  # the encounter
    calls = []
    original = segment.continue_from_last_row
    monkeypatch.setattr(
        segment, "continue_from_last_row", lambda *a: calls.append(a) or original(*a)
    )
    swept = gvi.Integrator(system, GAUSS[2], maxiter=maxiter).integrate(*start, **run)
    assert swept.success and len(calls) == hand_overs
    np.testing.assert_allclose(swept.q, newton.q, rtol=0, atol=1e-10)


@pytest.mark.parametrize("s", [4, 6])
def test_the_closed_form_sweep_keeps_the_coarse_steps_newton_fails(s, monkeypatch):
    """Double pendulum, T = 20 in 25 steps (h = 0.8): Newton fails at t = 12.8 (s = 6) or
    t = 16 (s = 4), the early rule handed over to it; ``fixed_point=True`` now keeps the
    fixed point (its sweeps are a fraction of a Newton iteration) and takes every step
    with no hand-over."""
    from galerkin_vi.run import segment

    prob = problems.double_pendulum()
    method = gvi.Galerkin(s, gvi.gauss_legendre(s))
    run = dict(h=0.8, n_steps=25, params=prob.params)
    with pytest.raises(gvi.ConvergenceError):
        gvi.Integrator(prob.system, method, fixed_point=False).integrate(
            prob.q0, prob.v0, on_failure="raise", **run
        )
    calls = []
    original = segment.continue_from_last_row
    monkeypatch.setattr(
        segment, "continue_from_last_row", lambda *a: calls.append(a) or original(*a)
    )
    kept = gvi.Integrator(prob.system, method).integrate(prob.q0, prob.v0, **run)
    assert kept.success and kept.n_steps == 25 and not calls
    # the method's solution: against Gauss(8) at h = 0.05 its error is 5.7e-3 (s = 4) and
    # 3.0e-4 (s = 6), and halving h divides it by 85 and 600
    reference = gvi.Integrator(prob.system, gvi.Galerkin(8, gvi.gauss_legendre(8))).integrate(
        prob.q0, prob.v0, h=0.05, n_steps=400, save_every=16, params=prob.params
    )
    half = gvi.Integrator(prob.system, method).integrate(
        prob.q0, prob.v0, h=0.4, n_steps=50, save_every=2, params=prob.params
    )
    error = np.abs(kept.q[-1] - reference.q[-1]).max()
    assert error < 1e-2
    assert np.abs(half.q[-1] - reference.q[-1]).max() < error / 50


def test_the_round_off_of_a_long_run_is_a_random_walk():
    """Double pendulum, Gauss(4), 1e6 steps of h = 0.005 (the truncation error is far
    below round-off): the largest energy error of the last tenth of the run is 1.6 times
    the first tenth's (1.1e-15 against 6.7e-16). Stopping the sweeps as soon as a change
    falls below the unit round-off, still decreasing, saved half a sweep per step but
    made it grow linearly: 4.5 times (5.8e-15 against 1.3e-15)."""
    prob = problems.double_pendulum()
    integrator = gvi.Integrator(prob.system, GAUSS[3])
    assert integrator.kernel_path == "varying_mass"
    n = 1_000_000
    traj = integrator.integrate(
        prob.q0, prob.v0, h=0.005, n_steps=n, save_every=1000, params=prob.params
    )
    error = np.abs(traj.energy() - traj.energy()[0])
    tenths = [part.max() for part in np.array_split(error, 10)]
    assert tenths[-1] < 3e-15
    assert tenths[-1] < 2.5 * tenths[0]
