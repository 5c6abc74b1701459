"""Parameter fitting (galerkin_vi.tangent.fit) and the DEL-residual estimator (tangent.estimate)."""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.tangent import FitStatus, estimate_parameters, fit_parameters
from galerkin_vi.tangent.fit import InitialState, TrajectoryModel, plan_segments

th, om, ell, c, g = sp.symbols("theta omega l c g")
x, v, k, b, m, a = sp.symbols("x v k b m a")


@pytest.fixture(scope="module")
def pendulum():
    """Damped pendulum, unit mass: L = ell^2 w^2 / 2 + g ell cos(theta), force -c w."""
    return gvi.LagrangianSystem(
        ell**2 * om**2 / 2 + g * ell * sp.cos(th), q=[th], v=[om],
        params={ell: 1.0, c: 0.1, g: 9.81}, forces=[-c * om],
    )  # fmt: skip


@pytest.fixture(scope="module")
def oscillator():
    """Damped harmonic oscillator: L = v^2/2 - k x^2/2, force -b v."""
    return gvi.LagrangianSystem(
        v**2 / 2 - k * x**2 / 2, q=[x], v=[v], params={k: 1.0, b: 0.0}, forces=[-b * v]
    )


def _gap_by_gap(integrator, t, q0, v0, params, h):
    """Positions at t from runs gap by gap, ceil(gap / h) equal steps each (the fit's grid)."""
    traj = integrator.integrate(q0, v0=v0, h=1e-3, n_steps=1, params=params)
    q, p = np.asarray(q0, float), traj.p[0]
    out = [q]
    for t0, t1 in zip(t[:-1], t[1:], strict=True):
        steps = math.ceil((t1 - t0) / h * (1 - 1e-9))
        run = integrator.integrate(q, p0=p, h=(t1 - t0) / steps, n_steps=steps, t0=t0,
                                   params=params)  # fmt: skip
        q, p = run.q[-1], run.p[-1]
        out.append(q)
    return np.array(out)


# ------------------------------------------------------------ same method: round-off
def test_pendulum_length_and_damping_recovered_on_the_grid(pendulum):
    method = gvi.Galerkin(2)
    truth = {ell: 0.8, c: 0.25}
    traj = gvi.Integrator(pendulum, method).integrate([1.2], v0=[0.0], h=0.02, n_steps=250,
                                                      params=truth)  # fmt: skip
    rows = np.r_[0, np.sort(np.random.default_rng(0).choice(np.arange(1, 251), 40, False))]
    fit = fit_parameters(pendulum, method, traj.t[rows], traj.q[rows], {ell: 1.0, c: 0.05},
                         h=0.02, v0=[0.0])  # fmt: skip
    assert fit.success and fit.status == FitStatus.CONVERGED
    np.testing.assert_allclose(fit.values, [0.8, 0.25], rtol=1e-9)
    assert fit.params == {ell: fit.values[0], c: fit.values[1]}
    assert np.max(np.abs(fit.residuals)) < 1e-12
    last = rows[-1] + 1  # the fit's own run, up to the last observation
    np.testing.assert_allclose(fit.trajectory.q, traj.q[:last], atol=1e-12)


def test_oscillator_and_initial_state_recovered_at_irregular_times(oscillator):
    method = gvi.Galerkin(2)
    integrator = gvi.Integrator(oscillator, method)
    t = np.r_[0.0, np.sort(np.random.default_rng(1).uniform(0.05, 6.0, 25))]
    q = _gap_by_gap(integrator, t, [0.7], [-0.4], {k: 3.0, b: 0.0}, h=0.05)
    fit = fit_parameters(oscillator, method, t, q, {"k": 2.0}, h=0.05, fit_initial_state=True)
    assert fit.success, fit.message
    np.testing.assert_allclose(fit.values, [3.0], rtol=1e-9)
    np.testing.assert_allclose(fit.q0, [0.7], rtol=1e-9)
    np.testing.assert_allclose(fit.v0, [-0.4], rtol=1e-9)
    assert fit.full_covariance.shape == (3, 3)
    assert fit.trajectory.t[0] == 0.0 and fit.trajectory.t[-1] == pytest.approx(t[-1])


def test_momentum_model(pendulum):
    method = gvi.Galerkin(1)
    traj = gvi.Integrator(pendulum, method).integrate([0.5], p0=[0.3], h=0.05, n_steps=100,
                                                      params={ell: 1.3})  # fmt: skip
    fit = fit_parameters(pendulum, method, traj.t, traj.q, {ell: 1.0}, p0=[0.3])
    np.testing.assert_allclose(fit.values, [1.3], rtol=1e-9)
    assert fit.v0 is None and fit.p0 == pytest.approx([0.3])


@pytest.mark.parametrize("fitted", [False, True])
def test_jacobian_matches_central_differences(pendulum, fitted):
    """dQ/d(ell, c, q0, v0) through p0 = L_v(q0, v0; ell) and chained across gaps."""
    integrator = gvi.Integrator(pendulum, gvi.Galerkin(2))
    t = np.r_[0.0, np.sort(np.random.default_rng(2).uniform(0.1, 3.0, 12))]
    segments, on_grid = plan_segments(t, 0.03)
    assert not on_grid and len(segments) == t.size - 1
    initial = InitialState(pendulum, (ell, c), 0.0, "velocity", fitted, np.array([1.0]),
                           np.array([0.5]))  # fmt: skip
    model = TrajectoryModel(integrator, (ell, c), initial, segments, t.size)
    z = np.array([0.8, 0.3] + ([1.0, 0.5] if fitted else []))
    _, dQ = model.evaluate(z)
    for j in range(z.size):
        e = np.zeros_like(z)
        e[j] = 1e-6
        fd = (model.evaluate(z + e)[0] - model.evaluate(z - e)[0]) / 2e-6
        np.testing.assert_allclose(dQ[..., j], fd, atol=1e-7 * np.max(np.abs(dQ)))


# ------------------------------------------------------------ exact flow: the method's order
@pytest.mark.parametrize("degree, order", [(1, 2), (2, 4)])
def test_exact_flow_error_falls_at_the_method_order(oscillator, degree, order):
    omega, q0, v0 = 2.0, 1.0, 0.5
    t = np.arange(0, 41) * 0.1
    q = (q0 * np.cos(omega * t) + v0 / omega * np.sin(omega * t))[:, None]
    steps = [0.1, 0.05, 0.025]
    errors = []
    for h in steps:
        fit = fit_parameters(oscillator, gvi.Galerkin(degree), t, q, {k: 3.0}, h=h, v0=[v0])
        assert fit.success
        errors.append(abs(fit.values[0] - omega**2))
    slopes = np.diff(np.log(errors)) / np.diff(np.log(steps))
    assert errors[-1] > 1e-11  # above round-off, so the slope is the method's
    np.testing.assert_allclose(slopes, order, atol=0.15)


# ------------------------------------------------------------ covariance
def test_covariance_of_a_linear_model_is_the_regression_formula():
    """q = q0 + v0 t + a t^2/2 is the discrete flow exactly: ordinary linear regression."""
    fall = gvi.LagrangianSystem(v**2 / 2 + a * x, q=[x], v=[v], params={a: -1.0})
    t = np.linspace(0.0, 2.0, 21)
    rng = np.random.default_rng(3)
    q = 1.0 + 0.5 * t - 9.81 * t**2 / 2 + 0.01 * rng.standard_normal(t.size)
    fit = fit_parameters(fall, gvi.Galerkin(2), t, q, {a: -5.0}, fit_initial_state=True)
    X = np.column_stack([t**2 / 2, np.ones_like(t), t])
    coef, res, *_ = np.linalg.lstsq(X, q, rcond=None)
    s2 = res[0] / (t.size - 3)
    np.testing.assert_allclose(fit.values, coef[:1], rtol=1e-9)
    np.testing.assert_allclose([fit.q0[0], fit.v0[0]], coef[1:], rtol=1e-9)
    np.testing.assert_allclose(fit.residual_variance, s2, rtol=1e-8)
    np.testing.assert_allclose(fit.full_covariance, s2 * np.linalg.inv(X.T @ X), rtol=1e-7)
    np.testing.assert_allclose(fit.standard_errors, np.sqrt(fit.full_covariance[0, 0]))


def test_standard_error_against_monte_carlo(oscillator):
    """The spread of k over noisy data sets matches the predicted standard error."""
    method = gvi.Galerkin(1)
    traj = gvi.Integrator(oscillator, method).integrate([1.0], v0=[0.0], h=0.1, n_steps=60,
                                                        params={k: 2.0})  # fmt: skip
    rng = np.random.default_rng(4)
    sigma, estimates, predicted = 0.02, [], []
    for _ in range(150):
        noisy = traj.q + sigma * rng.standard_normal(traj.q.shape)
        fit = fit_parameters(oscillator, method, traj.t, noisy, {k: 2.0}, q0=[1.0], v0=[0.0],
                             weights=1 / sigma**2, absolute_weights=True)  # fmt: skip
        estimates.append(fit.values[0])
        predicted.append(fit.standard_errors[0])
    assert np.std(estimates) == pytest.approx(np.mean(predicted), rel=0.15)
    assert abs(np.mean(estimates) - 2.0) < 3 * np.mean(predicted) / np.sqrt(150)


def test_not_identifiable(oscillator):
    """m and k of m v^2/2 - k x^2/2 enter the motion only as k/m."""
    scaled = gvi.LagrangianSystem(m * v**2 / 2 - k * x**2 / 2, q=[x], v=[v],
                                  params={m: 1.0, k: 1.0})  # fmt: skip
    t = np.linspace(0, 3, 31)
    q = np.cos(t)
    fit = fit_parameters(scaled, gvi.Galerkin(1), t, q, {m: 1.2, k: 1.0}, p0=[0.0])
    assert not fit.success and fit.status == FitStatus.NOT_IDENTIFIABLE
    assert np.all(np.isinf(fit.covariance))
    est = estimate_parameters(scaled, t, q, [m, k])
    assert est.status == FitStatus.NOT_IDENTIFIABLE


# ------------------------------------------------------------ the DEL-residual estimator
def test_estimator_is_exact_on_midpoint_data(pendulum):
    """Data of the midpoint discrete Lagrangian (Galerkin(1), one Gauss point) solve its DEL."""
    method = gvi.Galerkin(1, quadrature=gvi.gauss_legendre(1))
    traj = gvi.Integrator(pendulum, method).integrate([1.0], v0=[0.0], h=0.05, n_steps=80,
                                                      params={ell: 0.7, c: 0.3})  # fmt: skip
    est = estimate_parameters(pendulum, traj.t, traj.q, ["l", "c"])
    assert est.success and not est.linear  # ell^2 in L_v
    np.testing.assert_allclose(est.values, [0.7, 0.3], rtol=1e-12)
    assert est.residual_norm < 1e-12


def test_estimator_linear_model_second_order(oscillator):
    """Exact damped oscillation, dense samples: one linear solve, error O(h^2)."""
    kk, bb = 4.0, 0.25
    wd = math.sqrt(kk - bb**2 / 4)
    errors = []
    for h in (0.02, 0.01):
        t = np.arange(0, 3 + h / 2, h)
        q = np.exp(-bb / 2 * t) * np.cos(wd * t)
        est = estimate_parameters(oscillator, t, q, [k, b])
        assert est.linear and est.success
        errors.append(np.max(np.abs(est.values - [kk, bb])))
    assert errors[0] < 2e-3
    assert math.log2(errors[0] / errors[1]) == pytest.approx(2.0, abs=0.05)


def test_estimate_as_starting_point(pendulum):
    method = gvi.Galerkin(2)
    traj = gvi.Integrator(pendulum, method).integrate([1.0], v0=[0.0], h=0.02, n_steps=200,
                                                      params={ell: 0.7, c: 0.3})  # fmt: skip
    fit = fit_parameters(pendulum, method, traj.t, traj.q, ["l", "c"], v0=[0.0])
    np.testing.assert_allclose(fit.values, [0.7, 0.3], rtol=1e-9)


# ------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    "t_obs, q_obs, params0, kwargs, match",
    [
        ([0.0, 0.2, 0.1], [1.0, 0.9, 0.8], {k: 1.0}, {"v0": [0.0]}, "strictly increasing"),
        ([0.0, 0.1, 0.2], [[1.0, 0.0]] * 3, {k: 1.0}, {"v0": [0.0]}, "q_obs must have shape"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {"spring": 1.0}, {"v0": [0.0]}, "not a parameter"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {k: 1.0}, {}, "give v0 or p0"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {k: 1.0}, {"v0": [0], "p0": [0]}, "at most one"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {k: 1.0}, {"v0": [0.0], "weights": [1, 2]},
         "weights must"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {k: 1.0}, {"v0": [0.0], "bounds": {k: (2, 3)}},
         "not inside"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {k: 1.0}, {"v0": [0.0], "h": -0.1}, "h must"),
        ([0.0, 0.1, 0.2], [1.0, 0.9, 0.8], {k: 1.0}, {"v0": [0.0], "options": {"jac": 1}},
         "options"),
    ],
)  # fmt: skip
def test_bad_input(oscillator, t_obs, q_obs, params0, kwargs, match):
    with pytest.raises(ValueError, match=match):
        fit_parameters(oscillator, gvi.Galerkin(1), t_obs, q_obs, params0, **kwargs)


def test_estimator_bad_input(oscillator):
    with pytest.raises(ValueError, match="at least 3"):
        estimate_parameters(oscillator, [0.0, 0.1], [1.0, 0.9], [k])
    with pytest.raises(ValueError, match="repeated"):
        estimate_parameters(oscillator, [0.0, 0.1, 0.2], [1.0, 0.9, 0.8], [k, "k"])


def test_time_dependent_forcing_amplitude_and_stiffness():
    """A driven oscillator, started at t0 = 0.3: L = v^2/2 - k x^2/2 + A x cos t."""
    t = sp.Symbol("t")
    driven = gvi.LagrangianSystem(v**2 / 2 - k * x**2 / 2 + a * x * sp.cos(t), q=[x], v=[v],
                                  t=t, params={k: 1.0, a: 0.5})  # fmt: skip
    method = gvi.Galerkin(2)
    traj = gvi.Integrator(driven, method).integrate([1.0], v0=[0.0], h=0.05, n_steps=100, t0=0.3,
                                                    params={k: 2.0, a: 0.7})  # fmt: skip
    fit = fit_parameters(driven, method, traj.t, traj.q, {k: 1.5, a: 0.3}, v0=[0.0], h=0.05)
    np.testing.assert_allclose(fit.values, [2.0, 0.7], rtol=1e-9)


def test_failed_start_run_is_reported():
    quartic = gvi.LagrangianSystem(v**2 / 2 - k * x**4 / 4, q=[x], v=[v], params={k: 1.0})
    t = np.linspace(0.0, 10.0, 11)
    fit = fit_parameters(quartic, gvi.Galerkin(3), t, np.cos(t), {k: 1e8}, q0=[1.0], v0=[0.0])
    assert not fit.success and fit.status == FitStatus.RUN_FAILED
    assert "stability limit" in fit.message and np.isnan(fit.cost)
