"""The tangent map of runs with impacts: steps' tangents and saltation matrices.

A ball under gravity is integrated exactly by the method between impacts, so the
tangent equals the derivative of the discrete run (central differences) to their
own error; a pendulum against a wall checks a nonlinear flow and an impact
inside a step, with ``save_every`` and a terminal event.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi

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


def test_the_tangent_across_bounces_is_the_derivative_of_the_run():
    integrator = gvi.Integrator(ball(), gvi.Galerkin(2))
    run = dict(h=0.01, n_steps=500)
    x0 = np.array([0.0, 1.0, 0.3, 0.2])
    traj = integrator.integrate(x0[:2], p0=x0[2:], tangent=True, **run)
    assert len(traj.impacts) >= 2
    assert traj.tangent.shape == (len(traj.t), 4, 4)
    np.testing.assert_allclose(traj.tangent[-1], differences(integrator, x0, 2, run), atol=1e-7)
    # the horizontal motion is untouched by the impacts
    np.testing.assert_allclose(traj.tangent[-1][0], [1.0, 0.0, 5.0, 0.0], atol=1e-12)
    # each impact scales the vertical phase-space area by e^2 (velocity and time of flight)
    area = np.linalg.det(traj.tangent[-1][np.ix_([1, 3], [1, 3])])
    assert area == pytest.approx(0.8 ** (2 * len(traj.impacts)), rel=1e-9)


def test_a_nonlinear_flow_with_save_every_and_a_terminal_event():
    integrator = gvi.Integrator(pendulum_at_a_wall(), gvi.Galerkin(2))
    run = dict(h=0.01, n_steps=300)
    x0 = np.array([0.5, 0.0])
    traj = integrator.integrate(x0[:1], p0=x0[1:], tangent=True, save_every=7, **run)
    assert len(traj.impacts) == 1
    assert traj.tangent.shape == (len(traj.t), 2, 2)
    np.testing.assert_allclose(traj.tangent[-1], differences(integrator, x0, 1, run), atol=1e-8)
    # the impact scales phase-space area by e^2
    assert np.linalg.det(traj.tangent[-1]) == pytest.approx(0.81, rel=1e-9)
    stop = gvi.Event(th, terminal=True, direction=1)  # upwards through 0 after the impact
    cut = integrator.integrate(x0[:1], p0=x0[1:], tangent=True, events=stop, **run)
    assert cut.status == 1 and cut.tangent.shape == (len(cut.t), 2, 2)
    assert np.linalg.det(cut.tangent[-1]) == pytest.approx(0.81, rel=1e-9)


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
