"""The tangent map of runs with impacts: the derivative of the discrete run.

Central differences of whole runs with impacts are the oracle: the cut steps'
lengths move with the start (the impact time is a root along the method's
step), so the tangent must include their derivative in the step length, or
it is the continuous saltation matrix's approximation only (first order in h
for Störmer–Verlet, checked below to fail the tolerance the discrete one meets).
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.contact.impact import ContactFunctions
from galerkin_vi.contact.tangent import saltation_matrix

x, y, vx, vy, th, w, k = sp.symbols("x y vx vy th w k")


def ball(restitution=0.8, friction=0.0):
    contact = gvi.Contact(gap=y, restitution=restitution, friction=friction,
                          slip=[vx] if friction else None)  # fmt: skip
    return gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - k * y, [x, y], [vx, vy], contacts=[contact], params={k: 1.0}
    )


def pendulum_at_a_wall():
    contact = gvi.Contact(gap=th + 0.3, restitution=0.9)
    return gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w], contacts=[contact])


def differences(integrator, x0, n, run, eps=1e-6):
    def final(z):
        traj = integrator.integrate(z[:n], p0=z[n:], **run)
        return np.r_[traj.q[-1], traj.p[-1]]

    columns = [(final(x0 + eps * e) - final(x0 - eps * e)) / (2 * eps) for e in np.eye(x0.size)]
    return np.stack(columns, axis=1)


@pytest.mark.parametrize("degree, h", [(1, 0.05), (2, 0.01)])
def test_the_tangent_across_bounces_is_the_derivative_of_the_run(degree, h):
    integrator = gvi.Integrator(ball(), gvi.Galerkin(degree))
    run = dict(h=h, n_steps=int(round(5 / h)))
    x0 = np.array([0.0, 1.0, 0.3, 0.2])
    traj = integrator.integrate(x0[:2], p0=x0[2:], tangent=True, **run)
    assert len(traj.impacts) >= 2
    assert traj.tangent.shape == (len(traj.t), 4, 4)
    np.testing.assert_allclose(traj.tangent[-1], differences(integrator, x0, 2, run), atol=1e-7)
    # the horizontal motion is untouched by the impacts
    np.testing.assert_allclose(traj.tangent[-1][0], [1.0, 0.0, 5.0, 0.0], atol=1e-12)


@pytest.mark.parametrize("degree, h", [(1, 0.1), (1, 0.025), (2, 0.1), (3, 0.2)])
def test_a_nonlinear_flow_against_a_wall(degree, h):
    integrator = gvi.Integrator(pendulum_at_a_wall(), gvi.Galerkin(degree))
    run = dict(h=h, n_steps=int(round(3 / h)))
    x0 = np.array([0.5, 0.0])
    traj = integrator.integrate(x0[:1], p0=x0[1:], tangent=True, save_every=7, **run)
    assert len(traj.impacts) == 1
    assert traj.tangent.shape == (len(traj.t), 2, 2)
    np.testing.assert_allclose(traj.tangent[-1], differences(integrator, x0, 1, run), atol=1e-8)


def test_the_continuous_saltation_matrix_is_only_first_order_for_stormer_verlet():
    # what the discrete treatment of the impact time fixes: the impact's continuous
    # saltation matrix between the steps' tangents misses the run's derivative by O(h)
    system = pendulum_at_a_wall()
    integrator = gvi.Integrator(system, gvi.Galerkin(1))
    run = dict(h=0.1, n_steps=30)
    x0 = np.array([0.5, 0.0])
    traj = integrator.integrate(x0[:1], p0=x0[1:], **run)
    j = int(np.flatnonzero(np.diff(traj.t) == 0)[0])
    S = saltation_matrix(system, ContactFunctions(system), traj.impacts[0], traj.q[j],
                         traj.p[j], traj.p[j + 1], np.zeros(0))  # fmt: skip
    before = integrator.integrate(x0[:1], p0=x0[1:], h=0.1, n_steps=1, tangent=True)
    assert np.isfinite(S).all() and before.success
    exact = integrator.integrate(x0[:1], p0=x0[1:], tangent=True, **run).tangent[-1]
    assert np.abs(exact - differences(integrator, x0, 1, run)).max() < 1e-8
    # the continuous matrix's determinant is e^2 exactly; the run's is not
    assert np.linalg.det(S) == pytest.approx(0.81, rel=1e-12)
    assert abs(np.linalg.det(exact) - 0.81) > 1e-4


def test_a_terminal_event_after_an_impact_keeps_the_tangent_rows():
    integrator = gvi.Integrator(pendulum_at_a_wall(), gvi.Galerkin(2))
    stop = gvi.Event(th, terminal=True, direction=1)  # upwards through 0 after the impact
    cut = integrator.integrate([0.5], p0=[0.0], h=0.01, n_steps=300, tangent=True, events=stop)
    assert cut.status == 1 and len(cut.impacts) == 1
    assert cut.tangent.shape == (len(cut.t), 2, 2)


def test_gradients_through_impacts_in_forward_mode():
    integrator = gvi.Integrator(ball(), gvi.Galerkin(2))
    run = dict(h=0.01, n_steps=300)
    loss = gvi.Loss(terminal=x * y + y**2)
    grad = gvi.gradient(integrator, loss, [0.0, 1.0], p0=[0.3, 0.2], wrt=("q0", "p0"), **run)
    assert grad.success and grad.mode == "forward"

    def value(z):
        traj = integrator.integrate(z[:2], p0=z[2:], **run)
        return traj.q[-1, 0] * traj.q[-1, 1] + traj.q[-1, 1] ** 2

    x0 = np.array([0.0, 1.0, 0.3, 0.2])
    eps = 1e-6
    expected = [(value(x0 + eps * e) - value(x0 - eps * e)) / (2 * eps) for e in np.eye(4)]
    np.testing.assert_allclose(np.r_[grad.q0, grad.p0], expected, rtol=1e-6, atol=1e-9)
    with pytest.raises(ValueError, match="running loss terms"):
        gvi.gradient(integrator, gvi.Loss(running=y), [0.0, 1.0], p0=[0.3, 0.2], wrt="q0", **run)


def test_what_the_tangent_with_contacts_does_not_cover_names_the_reason():
    integrator = gvi.Integrator(ball(), gvi.Galerkin(2))
    run = dict(h=0.01, n_steps=10)
    with pytest.raises(ValueError, match="parameter sensitivities through impacts"):
        integrator.integrate([0.0, 1.0], v0=[0.0, 0.0], sensitivity=[k], **run)
    with pytest.raises(ValueError, match="complementarity"):
        integrator.integrate(
            [0.0, 1.0], v0=[0.0, 0.0], tangent=True, contact_mode="time-stepping", **run
        )
    rough = gvi.Integrator(ball(friction=0.3), gvi.Galerkin(2))
    with pytest.raises(ValueError, match="friction"):
        rough.integrate([0.0, 1.0], v0=[0.0, 0.0], tangent=True, **run)
    with pytest.raises(ValueError, match="t_eval"):
        integrator.integrate([0.0, 1.0], v0=[0.0, 0.0], tangent=True, t_eval=[0.05], **run)


def test_time_dependent_systems_take_the_continuous_saltation_matrix():
    t = sp.Symbol("t")
    contact = gvi.Contact(gap=y, restitution=0.8)
    system = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - (1 + sp.cos(t) / 10) * y, [x, y], [vx, vy], t=t,
        contacts=[contact],
    )  # fmt: skip
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    run = dict(h=0.01, n_steps=300)
    x0 = np.array([0.0, 1.0, 0.3, 0.2])
    traj = integrator.integrate(x0[:2], p0=x0[2:], tangent=True, **run)
    assert len(traj.impacts) == 1
    # the run's derivative to the method's accuracy (the impact time moves the cut steps)
    np.testing.assert_allclose(traj.tangent[-1], differences(integrator, x0, 2, run), atol=1e-5)
