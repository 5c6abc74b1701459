"""The tangent map of runs, parameter sensitivities and gradients by the discrete adjoint.

Closed forms where they exist (the harmonic oscillator's step matrix), and
otherwise the defining properties: symplecticity, the first-order prediction
against a run from a shifted start, agreement with central differences, and
reverse mode against forward mode to round-off.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi

q, v, k, c, w = sp.symbols("q v k c w")
q1, q2, v1, v2, g = sp.symbols("q1 q2 v1 v2 g")
t = sp.Symbol("t")


def symplectic_form(n: int) -> np.ndarray:
    return np.block([[np.zeros((n, n)), np.eye(n)], [-np.eye(n), np.zeros((n, n))]])


def oscillator():
    return gvi.LagrangianSystem(v**2 / 2 - k * q**2 / 2, [q], [v], params={k: 1.0})


def double_pendulum():
    L = v1**2 + v2**2 / 2 + v1 * v2 * sp.cos(q1 - q2) + 2 * g * sp.cos(q1) + g * sp.cos(q2)
    return gvi.LagrangianSystem(L, [q1, q2], [v1, v2], params={g: 9.81})


def padé_gauss2(z: np.ndarray) -> np.ndarray:
    """The stability function of 2-stage Gauss collocation, (1 + z/2 + z²/12)/(1 - z/2 + z²/12),
    at a matrix argument."""
    identity = np.eye(z.shape[0])
    z2 = z @ z
    return np.linalg.solve(identity - z / 2 + z2 / 12, identity + z / 2 + z2 / 12)


# ------------------------------------------------------------------ closed forms
@pytest.mark.parametrize(
    "method, step_matrix",
    [
        # Stormer-Verlet: the s = 1 Lobatto method
        (
            gvi.Galerkin(1),
            lambda h, om2: np.array(
                [[1 - h**2 * om2 / 2, h], [-h * om2 * (1 - h**2 * om2 / 4), 1 - h**2 * om2 / 2]]
            ),
        ),
        # Gauss collocation with 2 stages: the diagonal Padé approximant of exp(hA)
        (
            gvi.Galerkin(2, gvi.gauss_legendre(2), nodes="lobatto"),
            lambda h, om2: padé_gauss2(h * np.array([[0.0, 1.0], [-om2, 0.0]])),
        ),
    ],
    ids=["stormer-verlet", "gauss2"],
)
def test_oscillator_tangent_is_the_power_of_the_closed_form_step(method, step_matrix):
    integrator = gvi.Integrator(oscillator(), method)
    h, n_steps, om2 = 0.1, 50, 2.0
    traj = integrator.integrate(
        [0.3], v0=[0.2], h=h, n_steps=n_steps, params={k: om2}, tangent=True
    )
    one_step = step_matrix(h, om2)
    for row in (1, 7, n_steps):
        np.testing.assert_allclose(
            traj.tangent[row], np.linalg.matrix_power(one_step, row), rtol=0, atol=1e-13
        )
    # a linear map: the state itself is the tangent applied to the start
    x0 = np.array([traj.q[0, 0], traj.p[0, 0]])
    np.testing.assert_allclose(traj.tangent[-1] @ x0, [traj.q[-1, 0], traj.p[-1, 0]], atol=1e-14)


def test_symplectic_over_ten_thousand_steps_on_a_non_separable_system():
    # position-dependent mass (L_qv != 0 in the stage equations), a regular orbit
    system = gvi.LagrangianSystem((1 + q**2 / 4) * v**2 / 2 + sp.cos(q), [q], [v])
    traj = gvi.Integrator(system, gvi.Galerkin(2)).integrate(
        [0.4], v0=[0.0], h=0.05, n_steps=10_000, tangent=True, save_every=2500
    )
    assert traj.success
    J = symplectic_form(1)
    for phi in traj.tangent:
        assert np.abs(phi.T @ J @ phi - J).max() < 1e-12


def test_symplectic_and_first_order_prediction_on_the_double_pendulum():
    integrator = gvi.Integrator(double_pendulum(), gvi.Galerkin(3))
    q0, v0 = np.array([0.5, 0.3]), np.array([0.1, -0.2])
    run = dict(h=0.01, n_steps=200)
    traj = integrator.integrate(q0, v0=v0, tangent=True, **run)
    J = symplectic_form(2)
    assert np.abs(traj.tangent[-1].T @ J @ traj.tangent[-1] - J).max() < 1e-12
    x0 = np.r_[traj.q[0], traj.p[0]]
    xN = np.r_[traj.q[-1], traj.p[-1]]
    direction = np.array([1.0, -0.5, 0.3, 0.8])
    errors = []
    for eps in (1e-3, 5e-4, 2.5e-4):
        shifted = x0 + eps * direction
        other = integrator.integrate(shifted[:2], p0=shifted[2:], **run)
        moved = np.r_[other.q[-1], other.p[-1]] - xN
        errors.append(np.abs(moved - eps * traj.tangent[-1] @ direction).max())
    # the first-order prediction is off by O(|dx|^2): a quarter per halving
    ratios = np.array(errors[:-1]) / np.array(errors[1:])
    np.testing.assert_allclose(ratios, 4.0, rtol=0.05)


def test_directions_are_the_columns_of_the_full_tangent():
    integrator = gvi.Integrator(double_pendulum(), gvi.Galerkin(2))
    run = dict(h=0.02, n_steps=40)
    full = integrator.integrate([0.5, 0.3], v0=[0.1, -0.2], tangent=True, **run)
    V = np.array([[1.0, 0.0], [0.0, 2.0], [0.5, 0.0], [0.0, -1.0]])
    some = integrator.integrate([0.5, 0.3], v0=[0.1, -0.2], tangent=V, **run)
    assert some.tangent.shape == (41, 4, 2)
    np.testing.assert_allclose(some.tangent, full.tangent @ V, atol=1e-13)


# -------------------------------------------------------------- every model kind
def central_difference(run, x0, eps=1e-6):
    """d run(x0) / d x0 by central differences, column by column."""
    columns = []
    for i in range(x0.size):
        e = np.zeros_like(x0)
        e[i] = eps
        columns.append((run(x0 + e) - run(x0 - e)) / (2 * eps))
    return np.stack(columns, axis=-1)


KINDS = {
    "forced": lambda: gvi.LagrangianSystem(
        v**2 / 2 - q**4 / 4, [q], [v], forces=[-c * v], params={c: 0.3}
    ),
    "time-dependent": lambda: gvi.LagrangianSystem(
        v**2 / 2 + (1 + c * sp.cos(t) / 3) * sp.cos(q), [q], [v], t=t, params={c: 1.0}
    ),
    "angles": lambda: gvi.LagrangianSystem(v**2 / 2 + c * sp.cos(q), [q], [v], params={c: 1.0}),
    "gyroscopic": lambda: gvi.LagrangianSystem(
        (1 + q**2) * v**2 / 2 + c * sp.cos(q) + w * q * v, [q], [v], params={c: 1.0, w: 0.2}
    ),
}


@pytest.mark.parametrize("kind", list(KINDS))
def test_tangent_and_sensitivity_match_central_differences(kind):
    system = KINDS[kind]()
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    run = dict(h=0.05, n_steps=60, t0=0.3)
    # the angle turns over (it is kept in [-pi, pi) with its turns apart)
    start = np.array([2.5, 2.5]) if kind == "angles" else np.array([0.7, 0.4])
    traj = integrator.integrate(
        start[:1], p0=start[1:], tangent=True, sensitivity=list(system.params), **run
    )

    def final(x, prm=None):
        other = integrator.integrate(x[:1], p0=x[1:], params=prm, **run)
        return np.r_[other.q[-1], other.p[-1]]

    np.testing.assert_allclose(traj.tangent[-1], central_difference(final, start), rtol=1e-6,
                               atol=1e-8)  # fmt: skip
    values = system.parameter_vector(None)
    for j, theta in enumerate(system.params):

        def by_parameter(x, j=j, theta=theta):
            prm = dict(zip(system.params, values, strict=True))
            prm[theta] = x[0]
            return final(start, prm)

        expected = central_difference(by_parameter, values[j : j + 1])[:, 0]
        np.testing.assert_allclose(traj.sensitivity[-1][:, j], expected, rtol=1e-6, atol=1e-8)


def test_banded_chain_tangent_is_symplectic_and_matches_differences():
    n = 10
    qs, vs = sp.symbols(f"x0:{n}"), sp.symbols(f"u0:{n}")
    springs = [qs[0], *(qs[i + 1] - qs[i] for i in range(n - 1)), -qs[-1]]
    system = gvi.LagrangianSystem(
        sum(u**2 for u in vs) / 2 - sum(e**2 / 2 + e**4 / 4 for e in springs), qs, vs
    )
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    assert integrator.uses_banded_storage
    x0 = np.r_[np.linspace(-0.2, 0.3, n), np.zeros(n)]
    run = dict(h=0.05, n_steps=30)
    V = np.eye(2 * n)[:, [0, 3, n + 4]]
    traj = integrator.integrate(x0[:n], p0=x0[n:], tangent=V, **run)

    def final(x):
        other = integrator.integrate(x[:n], p0=x[n:], **run)
        return np.r_[other.q[-1], other.p[-1]]

    full = central_difference(final, x0)
    np.testing.assert_allclose(traj.tangent[-1], full @ V, rtol=1e-6, atol=1e-8)
    whole = integrator.integrate(x0[:n], p0=x0[n:], tangent=True, **run).tangent[-1]
    J = symplectic_form(n)
    assert np.abs(whole.T @ J @ whole - J).max() < 1e-12


def rod():
    return gvi.LagrangianSystem(
        (v1**2 + v2**2) / 2 - g * q2, [q1, q2], [v1, v2],
        constraints=[(q1**2 + q2**2 - 1) / 2], params={g: 1.0},
    )  # fmt: skip


def test_constrained_tangent_stays_on_the_manifold_and_is_symplectic_there():
    integrator = gvi.Integrator(rod(), gvi.Galerkin(2))
    run = dict(h=0.05, n_steps=400)
    traj = integrator.integrate([0.6, -0.8], v0=[0.8, 0.6], tangent=True, sensitivity=[g], **run)
    q, p = traj.q[0], traj.p[0]
    # a basis of the tangent space of the constraint manifold in T*Q at the start:
    # q . dq = 0 and the hidden constraint q . p = 0 linearised, dq . p + q . dp = 0
    along = np.r_[-q[1], q[0], 0.0, 0.0]
    along[2:] = -(along[:2] @ p) * q / (q @ q)
    basis = np.c_[along, np.r_[0.0, 0.0, -q[1], q[0]]]
    J = symplectic_form(2)
    for row in (100, 400):
        moved = traj.tangent[row] @ basis
        qk, pk = traj.q[row], traj.p[row]
        assert np.abs(qk @ moved[:2]).max() < 1e-14
        assert np.abs(moved[:2].T @ pk + qk @ moved[2:]).max() < 1e-13
        assert np.abs(moved.T @ J @ moved - basis.T @ J @ basis).max() < 1e-12

    def final(x):
        other = integrator.integrate(x[:2], p0=x[2:], project=True, **run)
        return np.r_[other.q[-1], other.p[-1]]

    x0 = np.r_[q, p]
    for direction in basis.T:
        eps = 1e-6
        expected = (final(x0 + eps * direction) - final(x0 - eps * direction)) / (2 * eps)
        np.testing.assert_allclose(traj.tangent[-1] @ direction, expected, atol=1e-8)

    def by_g(value):
        other = integrator.integrate([0.6, -0.8], v0=[0.8, 0.6], params={g: value}, **run)
        return np.r_[other.q[-1], other.p[-1]]

    expected = (by_g(1 + 1e-6) - by_g(1 - 1e-6)) / 2e-6
    np.testing.assert_allclose(traj.sensitivity[-1][:, 0], expected, atol=1e-8)


def test_runs_longer_than_a_chunk_carry_the_tangent_across_joins():
    integrator = gvi.Integrator(double_pendulum(), gvi.Galerkin(2))
    long = integrator.integrate(
        [0.1, 0.05], v0=[0.0, 0.0], h=0.01, n_steps=6000, tangent=True, save_every=1000
    )
    assert long.tangent.shape == (7, 4, 4)
    # the product of the tangents of the two halves, run separately
    first = integrator.integrate(
        [0.1, 0.05], v0=[0.0, 0.0], h=0.01, n_steps=3000, tangent=True, save_every=3000
    )
    second = integrator.integrate(
        first.q[-1], p0=first.p[-1], t0=30.0, h=0.01, n_steps=3000, tangent=True, save_every=3000
    )
    np.testing.assert_allclose(
        long.tangent[-1], second.tangent[-1] @ first.tangent[-1], rtol=1e-9, atol=1e-9
    )
    np.testing.assert_allclose(long.tangent[3], first.tangent[-1], rtol=1e-10, atol=1e-12)


def test_tangent_runs_take_the_other_run_options():
    integrator = gvi.Integrator(double_pendulum(), gvi.Galerkin(2))
    q1_crosses = gvi.Event(q1, terminal=True, direction=-1)
    traj = integrator.integrate(
        [0.5, 0.0], v0=[0.0, 0.0], h=0.01, t_span=(0.0, 5.0), tangent=True, events=q1_crosses
    )
    assert traj.status == 1 and len(traj.t_events[0]) == 1
    assert traj.tangent.shape == (len(traj.t), 4, 4)
    assert traj.sol is not None
    with pytest.raises(ValueError, match="t_eval"):
        integrator.integrate(
            [0.5, 0.0], v0=[0.0, 0.0], h=0.01, n_steps=10, tangent=True, t_eval=[0.05]
        )


def test_bad_tangent_arguments_name_the_problem():
    integrator = gvi.Integrator(oscillator(), gvi.Galerkin(2))
    run = dict(h=0.1, n_steps=3)
    with pytest.raises(ValueError, match="shape"):
        integrator.integrate([1.0], v0=[0.0], tangent=np.ones((3, 1)), **run)
    with pytest.raises(ValueError, match="not a parameter"):
        integrator.integrate([1.0], v0=[0.0], sensitivity=["mass"], **run)
    with pytest.raises(ValueError, match="renormalize_every needs"):
        integrator.integrate([1.0], v0=[0.0], renormalize_every=5, **run)
    moving = gvi.LagrangianSystem(
        (v1**2 + v2**2) / 2 - q2, [q1, q2], [v1, v2], t=t,
        constraints=[(q1**2 + q2**2 - (1 + t / 10) ** 2) / 2],
    )  # fmt: skip
    with pytest.raises(ValueError, match="time-dependent constraints"):
        gvi.Integrator(moving, gvi.Galerkin(2)).integrate(
            [0.6, -0.8], v0=[0.8, 0.6], tangent=True, **run
        )
    with pytest.raises(ValueError, match="numba backend"):
        gvi.Integrator(oscillator(), gvi.Galerkin(2), backend="numpy").integrate(
            [1.0], v0=[0.0], tangent=True, **run
        )


# ---------------------------------------------------------------- the adjoint
def test_adjoint_equals_the_tangent_and_central_differences():
    system = double_pendulum()
    integrator = gvi.Integrator(system, gvi.Galerkin(3))
    q0, v0 = np.array([0.5, 0.3]), np.array([0.1, -0.2])
    run = dict(h=0.01, n_steps=150)
    loss = gvi.Loss(terminal=sp.sin(q1) + q2**2, running=0.01 * g * q1**2)
    grad = gvi.gradient(integrator, loss, q0, v0, wrt=("q0", "v0", "params"), **run)
    assert grad.success
    # forward mode: the same derivative from the tangent map and the sensitivities
    traj = integrator.integrate(q0, v0=v0, tangent=True, sensitivity=[g], **run)
    terminal = np.r_[np.cos(traj.q[-1, 0]), 2 * traj.q[-1, 1], 0.0, 0.0]
    forward = traj.tangent[-1].T @ terminal
    forward_g = terminal @ traj.sensitivity[-1][:, 0]
    for k_row in range(run["n_steps"]):
        running = np.r_[0.02 * 9.81 * traj.q[k_row, 0], 0.0, 0.0, 0.0]
        forward += traj.tangent[k_row].T @ running
        forward_g += running @ traj.sensitivity[k_row][:, 0] + 0.01 * traj.q[k_row, 0] ** 2
    np.testing.assert_allclose(grad.adjoint, forward, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(grad.params[g], forward_g, rtol=1e-12)

    def value(q0, v0, gv=9.81):
        other = integrator.integrate(q0, v0=v0, params={g: gv}, **run)
        return (
            np.sin(other.q[-1, 0]) + other.q[-1, 1] ** 2 + 0.01 * gv * np.sum(other.q[:-1, 0] ** 2)
        )

    eps = 1e-6
    for i in range(2):
        e = eps * np.eye(2)[i]
        fd_q = (value(q0 + e, v0) - value(q0 - e, v0)) / (2 * eps)
        fd_v = (value(q0, v0 + e) - value(q0, v0 - e)) / (2 * eps)
        np.testing.assert_allclose(grad.q0[i], fd_q, rtol=1e-6)
        np.testing.assert_allclose(grad.v0[i], fd_v, rtol=1e-6)
    fd_g = (value(q0, v0, 9.81 + eps) - value(q0, v0, 9.81 - eps)) / (2 * eps)
    np.testing.assert_allclose(grad.params[g], fd_g, rtol=1e-6)
    assert grad.value == pytest.approx(value(q0, v0), rel=1e-12)


def test_the_adjoint_pairing_is_conserved_and_checkpoints_change_nothing():
    integrator = gvi.Integrator(double_pendulum(), gvi.Galerkin(2))
    q0, p0 = np.array([0.4, -0.1]), np.array([0.2, 0.1])
    run = dict(h=0.02, n_steps=120)
    loss = gvi.Loss(terminal=q1 * q2)
    whole = gvi.gradient(integrator, loss, q0, p0=p0, wrt=("q0", "p0"), **run)
    pieces = gvi.gradient(integrator, loss, q0, p0=p0, wrt=("q0", "p0"), checkpoint_every=7, **run)
    np.testing.assert_allclose(pieces.adjoint, whole.adjoint, rtol=1e-13, atol=1e-15)
    # <lambda_k, dx_k> is the same at k = 0 and k = N (Sanz-Serna 2016)
    traj = integrator.integrate(q0, p0=p0, tangent=True, **run)
    dx0 = np.array([0.3, -0.2, 0.5, 0.1])
    lam_n = np.r_[traj.q[-1, 1], traj.q[-1, 0], 0.0, 0.0]
    assert whole.adjoint @ dx0 == pytest.approx(lam_n @ (traj.tangent[-1] @ dx0), rel=1e-13)


def test_a_used_system_with_tangent_data_pickles():
    system = oscillator()
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    integrator.integrate([1.0], v0=[0.0], h=0.1, n_steps=3, sensitivity=[k])
    copy = pickle.loads(pickle.dumps(system))
    assert len(copy.derived) == 0
    again = gvi.Integrator(copy, gvi.Galerkin(2)).integrate(
        [1.0], v0=[0.0], h=0.1, n_steps=3, sensitivity=[k]
    )
    traj = integrator.integrate([1.0], v0=[0.0], h=0.1, n_steps=3, sensitivity=[k])
    np.testing.assert_array_equal(again.sensitivity, traj.sensitivity)


def test_sensitivity_to_a_constant_force_is_its_closed_form():
    # run after another system's sensitivities with the same shape: their generated
    # parameter derivatives (-q here, 1 below) must not share a cache entry
    gvi.Integrator(oscillator(), gvi.Galerkin(2)).integrate(
        [1.0], v0=[0.0], h=0.1, n_steps=2, sensitivity=[k]
    )
    a = sp.Symbol("a")
    fall = gvi.LagrangianSystem(v**2 / 2 + a * q, [q], [v], params={a: -1.0})
    traj = gvi.Integrator(fall, gvi.Galerkin(2)).integrate(
        [1.0], v0=[0.5], h=0.1, n_steps=20, sensitivity=[a]
    )
    # q = q0 + v0 t + a t^2 / 2, p = v0 + a t: the method is exact for them
    np.testing.assert_allclose(traj.sensitivity[:, 0, 0], traj.t**2 / 2, atol=1e-13)
    np.testing.assert_allclose(traj.sensitivity[:, 1, 0], traj.t, atol=1e-13)


def test_ensembles_carry_the_tangent_and_adaptive_runs_say_why_not():
    system = oscillator()
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    run = dict(h=0.1, n_steps=10, tangent=True, sensitivity=[k])
    many = integrator.integrate_many([[1.0], [0.5]], [[0.0], [0.1]], **run)
    for member, (q0, v0) in zip(many, [(1.0, 0.0), (0.5, 0.1)], strict=True):
        alone = integrator.integrate([q0], v0=[v0], **run)
        np.testing.assert_array_equal(member.tangent, alone.tangent)
        np.testing.assert_array_equal(member.sensitivity, alone.sensitivity)
    adaptive = gvi.AdaptiveIntegrator(system, gvi.Galerkin(2), g=1 + q**2)
    with pytest.raises(ValueError, match="adaptive runs"):
        adaptive.integrate([1.0], v0=[0.0], h=0.1, n_steps=10, tangent=True)


def test_the_gradient_of_a_constrained_run_in_forward_mode_matches_differences():
    integrator = gvi.Integrator(rod(), gvi.Galerkin(2))
    run = dict(h=0.05, n_steps=60)
    q0, p0 = np.array([0.6, -0.8]), np.array([0.8, 0.6])
    loss = gvi.Loss(terminal=q1**2 * q2, running=0.05 * g * q1**2)
    wrt = ("q0", "p0", "params")
    grad = gvi.gradient(integrator, loss, q0, p0=p0, wrt=wrt, checkpoint_every=25, **run)
    assert grad.success and grad.mode == "forward"

    def value(x, gv=1.0):
        other = integrator.integrate(x[:2], p0=x[2:], params={g: gv}, project=True, **run)
        return other.q[-1, 0] ** 2 * other.q[-1, 1] + 0.05 * gv * np.sum(other.q[:-1, 0] ** 2)

    x0 = np.r_[q0, p0]
    along = np.r_[-q0[1], q0[0], 0.0, 0.0]
    along[2:] = -(along[:2] @ p0) * q0
    for direction in (along, np.r_[0.0, 0.0, -q0[1], q0[0]]):
        eps = 1e-6
        expected = (value(x0 + eps * direction) - value(x0 - eps * direction)) / (2 * eps)
        assert np.r_[grad.q0, grad.p0] @ direction == pytest.approx(expected, rel=1e-6)
    expected = (value(x0, 1 + 1e-6) - value(x0, 1 - 1e-6)) / 2e-6
    assert grad.params[g] == pytest.approx(expected, rel=1e-6)
    assert grad.value == pytest.approx(value(x0), rel=1e-12)


def test_sensitivity_of_a_start_given_by_its_velocity_holds_the_velocity_fixed():
    m = sp.Symbol("m")
    system = gvi.LagrangianSystem(
        m * v**2 / 2 - k * q**2 / 2 - q**4 / 4, [q], [v], params={k: 1.0, m: 1.5}
    )
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    run = dict(h=0.05, n_steps=40)
    traj = integrator.integrate([0.5], v0=[0.3], sensitivity=[m], **run)

    def final(mass):
        other = integrator.integrate([0.5], v0=[0.3], params={m: mass}, **run)
        return np.r_[other.q[-1], other.p[-1]]

    expected = (final(1.5 + 1e-6) - final(1.5 - 1e-6)) / 2e-6
    np.testing.assert_allclose(traj.sensitivity[-1][:, 0], expected, rtol=1e-7)
    # and the row of the start: p0 = m v0
    np.testing.assert_allclose(traj.sensitivity[0][:, 0], [0.0, 0.3], atol=1e-15)


def test_a_run_cut_for_instability_keeps_its_tangent_rows_in_step():
    integrator = gvi.Integrator(oscillator(), gvi.Galerkin(1))
    for save_every in (1, 7):
        with pytest.warns(gvi.RunFailureWarning):
            traj = integrator.integrate(
                [1.0], v0=[0.0], h=60.0, n_steps=400, tangent=True, save_every=save_every
            )
        assert not traj.success
        assert traj.tangent.shape == (len(traj.t), 2, 2)


def test_streamed_chunks_carry_the_tangent_and_the_sensitivities():
    integrator = gvi.Integrator(double_pendulum(), gvi.Galerkin(2))
    run = dict(h=0.01, n_steps=250)
    whole = integrator.integrate([0.5, 0.3], v0=[0.1, -0.2], tangent=True, sensitivity=[g], **run)
    chunks = list(
        integrator.stream(
            [0.5, 0.3], v0=[0.1, -0.2], chunk_steps=100, tangent=True, sensitivity=[g], **run
        )  # fmt: skip
    )
    assert [len(c) for c in chunks] == [101, 100, 50]
    tangent = np.concatenate([c.tangent for c in chunks])
    sensitivity = np.concatenate([c.sensitivity for c in chunks])
    # equal up to the round-off of the joins (each chunk starts Newton afresh)
    np.testing.assert_allclose(tangent, whole.tangent, rtol=1e-9, atol=1e-10)
    np.testing.assert_allclose(sensitivity, whole.sensitivity, rtol=1e-9, atol=1e-10)
    with pytest.raises(ValueError, match="shape"):
        integrator.stream([0.5, 0.3], v0=[0.1, -0.2], chunk_steps=100, tangent=np.ones(3), **run)


@pytest.mark.parametrize("kind", ["general", "constrained"])
def test_ensembles_with_the_tangent_run_in_compiled_blocks_bit_for_bit(kind):
    if kind == "constrained":
        system, q0s, v0s = rod(), [[0.6, -0.8], [0.8, -0.6]], [[0.8, 0.6], [0.6, 0.8]]
        run = dict(h=0.05, n_steps=40, tangent=True, sensitivity=[g])
    else:
        system = double_pendulum()
        q0s, v0s = [[0.5, 0.3], [0.1, -0.2], [1.0, 0.0]], [[0.1, -0.2], [0.0, 0.0], [0.3, 0.1]]
        run = dict(h=0.01, n_steps=60, tangent=np.eye(4)[:, :2], renormalize_every=5,
                   sensitivity=[g], save_every=7)  # fmt: skip
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    many = integrator.integrate_many(q0s, v0s, workers=2, **run)
    for member, q0, v0 in zip(many, q0s, v0s, strict=True):
        alone = integrator.integrate(q0, v0=v0, **run)
        np.testing.assert_array_equal(member.q, alone.q)
        for name in ("tangent", "sensitivity", "log_growth", "megno", "megno_mean"):
            a, b = getattr(member.variations, name), getattr(alone.variations, name)
            assert (a is None) == (b is None)
            if a is not None:
                np.testing.assert_array_equal(a, b)
