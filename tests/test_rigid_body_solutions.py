"""Closed-form rigid-body solutions (galerkin_vi.problems.rigid_bodies) against DOP853."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp
from scipy.linalg import eigh, expm

from galerkin_vi.problems.rigid_bodies import (
    ball_joint_frequencies,
    ball_joint_modes,
    free_body_angular_velocity,
    free_body_period,
    free_body_rotation,
    lagrange_top_nutation,
    lagrange_top_theta,
    tennis_racket_flip_time,
    tennis_racket_period,
)

TOL = dict(method="DOP853", rtol=1e-13, atol=1e-13)

# (moments, omega0): both families (about the largest and the smallest axis), every
# ordering of the moments, a symmetric body of each kind, close to the separatrix
FREE_BODIES = [
    ((1.0, 2.0, 3.0), (0.3, 1.0, -0.4)),
    ((3.0, 2.0, 1.0), (0.3, 1.0, -0.4)),
    ((2.0, 3.0, 1.0), (1.0, 0.1, 0.2)),
    ((1.0, 2.0, 3.0), (-1.0, 0.1, 0.2)),
    ((2.0, 1.0, 3.0), (-0.5, 0.2, 0.1)),
    ((1.5, 4.0, 2.5), (0.2, -0.7, 1.1)),
    ((1.0, 1.0, 3.0), (0.5, 0.2, 0.7)),
    ((1.0, 3.0, 3.0), (0.5, 0.2, 0.7)),
    ((1.0, 2.0, 3.0), (1e-3, 1.0, -1e-3)),
]


def _hat(w: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _vee(a: np.ndarray) -> np.ndarray:
    return np.array([a[2, 1] - a[1, 2], a[0, 2] - a[2, 0], a[1, 0] - a[0, 1]]) / 2


def _free_body_ode(J: np.ndarray, w0: np.ndarray, R0: np.ndarray, t: np.ndarray, **kw):
    """Euler's equations J w' = (J w) x w with R' = R hat(w), by DOP853."""

    def rhs(_: float, y: np.ndarray) -> np.ndarray:
        w, R = y[:3], y[3:].reshape(3, 3)
        return np.concatenate([np.cross(J * w, w) / J, (R @ _hat(w)).ravel()])

    y0 = np.concatenate([w0, R0.ravel()])
    return solve_ivp(rhs, (0.0, t[-1]), y0, t_eval=t, **TOL, **kw)


def _random_rotation(seed: int) -> np.ndarray:
    return expm(_hat(np.random.default_rng(seed).normal(size=3)))


@pytest.mark.parametrize(("J", "w0"), FREE_BODIES)
def test_free_body_matches_dop853(J, w0):
    J, w0, R0 = np.array(J), np.array(w0), _random_rotation(3)
    t = np.linspace(0.0, 25.0, 51)
    ode = _free_body_ode(J, w0, R0, t)
    omega = free_body_angular_velocity(J, w0, t)
    R = free_body_rotation(J, w0, R0, t)
    assert omega.shape == (51, 3) and R.shape == (51, 3, 3)
    assert np.max(np.abs(omega - ode.y[:3].T)) < 1e-10
    assert np.max(np.abs(R - ode.y[3:].T.reshape(-1, 3, 3))) < 1e-10


@pytest.mark.parametrize(("J", "w0"), [*FREE_BODIES[:6], ((1.0, 2.0, 3.0), (3e-5, 2.0, 3e-5))])
def test_free_body_invariants(J, w0):
    J, w0, R0 = np.array(J), np.array(w0), _random_rotation(5)
    t = np.linspace(-40.0, 400.0, 2001)
    omega = free_body_angular_velocity(J, w0, t)
    R = free_body_rotation(J, w0, R0, t)
    energy = np.einsum("i,ti,ti->t", J, omega, omega)
    momentum = np.linalg.norm(J * omega, axis=-1)
    space_momentum = np.einsum("tij,tj->ti", R, J * omega)
    assert np.max(np.abs(energy / (J @ w0**2) - 1)) < 1e-13
    assert np.max(np.abs(momentum / np.linalg.norm(J * w0) - 1)) < 1e-13
    assert np.max(np.abs(space_momentum - R0 @ (J * w0))) < 1e-12
    assert np.max(np.abs(R @ np.swapaxes(R, 1, 2) - np.eye(3))) < 1e-14
    np.testing.assert_allclose(free_body_angular_velocity(J, w0, 0.0), w0, atol=1e-15)
    np.testing.assert_allclose(free_body_rotation(J, w0, R0, 0.0), R0, atol=1e-15)


def test_free_body_scalar_and_grid_shapes():
    J, w0 = (1.0, 2.0, 3.0), (0.3, 1.0, -0.4)
    t = np.linspace(0.0, 3.0, 12).reshape(3, 4)
    assert free_body_angular_velocity(J, w0, t).shape == (3, 4, 3)
    assert free_body_rotation(J, w0, np.eye(3), t).shape == (3, 4, 3, 3)
    np.testing.assert_array_equal(
        free_body_rotation(J, w0, np.eye(3), t)[1, 2], free_body_rotation(J, w0, np.eye(3), t[1, 2])
    )


@pytest.mark.parametrize(("J", "w0"), FREE_BODIES[:6] + FREE_BODIES[-1:])
def test_free_body_period_is_the_integrated_return(J, w0):
    J, w0 = np.array(J), np.array(w0)
    period = free_body_period(J, w0)
    ode = _free_body_ode(J, w0, np.eye(3), np.array([0.0, period / 2, period]))
    # one full period returns omega, and half of it does not (the period is not a multiple)
    assert np.max(np.abs(ode.y[:3, -1] - w0)) < 1e-10 * np.linalg.norm(w0)
    assert np.max(np.abs(ode.y[:3, 1] - w0)) > 1e-3 * np.linalg.norm(w0)


def test_tennis_racket_flips_near_the_intermediate_axis():
    J = np.array([1.0, 2.0, 3.0])
    # 1 - k^2 = 5e-7: the flips are sharp, and DOP853 still resolves them to 1e-10 (closer
    # to the separatrix its error grows like 1/sqrt(1 - k^2))
    w0 = np.array([1e-3, 2.0, 1e-3])
    period, flip = tennis_racket_period(J, w0), tennis_racket_flip_time(J, w0)
    assert flip == period / 2

    def omega2(_: float, y: np.ndarray) -> float:
        return y[1]

    ode = _free_body_ode(J, w0, np.eye(3), np.array([0.0, 2.2 * period]), events=omega2)
    crossings = ode.t_events[0]
    assert len(crossings) == 4  # two flips per period
    np.testing.assert_allclose(np.diff(crossings), flip, rtol=1e-9)
    # between the flips omega2 stays near +-2: the flip is sharp
    t = np.linspace(crossings[0] + 0.2 * flip, crossings[1] - 0.2 * flip, 50)
    assert np.all(np.abs(free_body_angular_velocity(J, w0, t)[:, 1]) > 1.9)
    # a period after the start omega2 is back at its initial value, half of it opposite
    w = free_body_angular_velocity(J, w0, [period / 2, period])
    assert w[0, 1] == pytest.approx(-2.0, abs=1e-2) and w[1, 1] == pytest.approx(2.0, abs=1e-12)


def test_free_body_special_motions():
    R0 = _random_rotation(7)
    t = np.linspace(0.0, 5.0, 11)
    w0 = np.array([0.2, -0.3, 0.5])
    # a sphere: omega constant, R = R0 exp(t hat(omega0))
    np.testing.assert_allclose(
        free_body_angular_velocity((2.0, 2.0, 2.0), w0, t), np.tile(w0, (11, 1))
    )
    expected = np.array([R0 @ expm(s * _hat(w0)) for s in t])
    np.testing.assert_allclose(free_body_rotation((2.0, 2.0, 2.0), w0, R0, t), expected, atol=1e-14)
    assert free_body_period((2.0, 2.0, 2.0), w0) == np.inf
    # a permanent rotation about the largest axis
    w_axis = np.array([0.0, 0.0, 1.5])
    np.testing.assert_allclose(
        free_body_angular_velocity((1.0, 2.0, 3.0), w_axis, t), np.tile(w_axis, (11, 1))
    )
    expected = np.array([R0 @ expm(s * _hat(w_axis)) for s in t])
    np.testing.assert_allclose(
        free_body_rotation((1.0, 2.0, 3.0), w_axis, R0, t), expected, atol=1e-14
    )
    # at rest
    np.testing.assert_array_equal(free_body_rotation((1.0, 2.0, 3.0), np.zeros(3), R0, t)[-1], R0)


@pytest.mark.parametrize(
    "w0",
    [
        (0.0, 1.0, 0.0),  # the unstable rotation about the intermediate axis
        (1.0, 0.5, np.sqrt(1.0 * (2.0 - 1.0) / (3.0 * (3.0 - 2.0)))),  # M^2 = 2 E J2
        (1e-5, 2.0, 1e-5),  # 1 - k^2 = 5e-11
    ],
)
def test_free_body_separatrix_is_refused(w0):
    with pytest.raises(ValueError, match="separatrix"):
        free_body_angular_velocity((1.0, 2.0, 3.0), w0, 1.0)


@pytest.mark.parametrize(
    ("inertia", "R0", "match"),
    [
        ((1.0, 2.0), np.eye(3), "inertia"),
        ((1.0, -2.0, 3.0), np.eye(3), "inertia"),
        ((1.0, 2.0, 3.0), 2 * np.eye(3), "R0"),
    ],
)
def test_free_body_bad_arguments(inertia, R0, match):
    with pytest.raises(ValueError, match=match):
        free_body_rotation(inertia, (0.1, 0.2, 0.3), R0, 1.0)


# ------------------------------------------------------------------ Lagrange top
def _euler_zxz(phi: float, theta: float, psi: float) -> np.ndarray:
    return (
        expm(phi * _hat([0, 0, 1.0]))
        @ expm(theta * _hat([1.0, 0, 0]))
        @ expm(psi * _hat([0, 0, 1.0]))
    )


def _top_ode(I1, I3, m, g, arm, theta0, theta_dot0, phi_dot0, psi_dot0, t_final, **kw):
    """The top as a rigid body about its fixed point: J w' = (J w) x w + l e3 x R^T(-m g ez)."""
    phi0, psi0 = 0.4, -1.1
    R0 = _euler_zxz(phi0, theta0, psi0)
    # body angular velocity of R = Rz(phi) Rx(theta) Rz(psi): vee(R^T R')
    Rz_psi, Rx_theta = expm(psi0 * _hat([0, 0, 1.0])), expm(theta0 * _hat([1.0, 0, 0]))
    w0 = (
        phi_dot0 * Rz_psi.T @ Rx_theta.T @ [0, 0, 1.0]
        + theta_dot0 * Rz_psi.T @ [1.0, 0, 0]
        + psi_dot0 * np.array([0, 0, 1.0])
    )
    J = np.array([I1, I1, I3])
    e3 = np.array([0.0, 0.0, 1.0])

    def rhs(_: float, y: np.ndarray) -> np.ndarray:
        w, R = y[:3], y[3:].reshape(3, 3)
        torque = arm * np.cross(e3, R.T @ np.array([0.0, 0.0, -m * g]))
        return np.concatenate([(np.cross(J * w, w) + torque) / J, (R @ _hat(w)).ravel()])

    return solve_ivp(rhs, (0.0, t_final), np.concatenate([w0, R0.ravel()]), **TOL, **kw), J


TOPS = [
    # I1, I3, m, g, arm, theta0, theta_dot0, phi_dot0, psi_dot0
    (1.2, 0.5, 1.0, 9.81, 0.3, 0.7, 0.0, 0.0, 25.0),  # released at rest: cusps
    (1.2, 0.5, 1.0, 9.81, 0.3, 0.7, 0.0, 8.0, 25.0),  # at rest in theta, rising: theta0 = max
    (1.2, 0.5, 1.0, 9.81, 0.3, 0.7, 0.8, 1.5, 20.0),  # waves
    (1.0, 0.4, 2.0, 9.81, 0.5, 1.2, -0.5, -2.0, 30.0),  # loops
    (0.8, 0.6, 1.0, 9.81, 0.4, 2.0, 1.0, 0.5, 5.0),  # slow top below the horizontal
]


@pytest.mark.parametrize("top", TOPS)
def test_lagrange_top_against_rigid_body_dop853(top):
    I1, I3, m, g, arm, theta0, theta_dot0, phi_dot0, psi_dot0 = top
    nutation = lagrange_top_nutation(*top)

    def u_extreme(_: float, y: np.ndarray) -> float:  # d/dt (R e3)_z
        return (y[3:].reshape(3, 3) @ np.cross(y[:3], [0.0, 0.0, 1.0]))[2]

    t_final = 3.3 * nutation.period
    t = np.linspace(0.0, t_final, 41)
    ode, J = _top_ode(*top, t_final, t_eval=t, events=u_extreme, dense_output=True)
    R = ode.y[3:].T.reshape(-1, 3, 3)
    w = ode.y[:3].T
    theta = np.arccos(R[:, 2, 2])
    assert np.max(np.abs(lagrange_top_theta(*top, t) - theta)) < 1e-9
    # the momenta and the energy
    space_momentum = np.einsum("tij,tj->ti", R, J * w)
    np.testing.assert_allclose(space_momentum[:, 2], nutation.p_phi, rtol=0, atol=1e-11)
    np.testing.assert_allclose(I3 * w[:, 2], nutation.p_psi, rtol=0, atol=1e-11)
    energy = 0.5 * np.einsum("ti,ti->t", J * w, w) + m * g * arm * R[:, 2, 2]
    np.testing.assert_allclose(energy, nutation.energy, rtol=1e-12)
    # the turning points: u alternates between u1 (theta_max) and u2 (theta_min), a period apart
    events = ode.t_events[0]
    events = events[events > 1e-9]  # at rest at t = 0 the start is itself a turning point
    u_at = np.array([ode.sol(s)[3:].reshape(3, 3)[2, 2] for s in events])
    low = u_at < (u_at.min() + u_at.max()) / 2
    np.testing.assert_allclose(np.arccos(u_at[low]), nutation.theta_max, atol=1e-9)
    np.testing.assert_allclose(np.arccos(u_at[~low]), nutation.theta_min, atol=1e-9)
    lower_times = events[low]
    assert len(lower_times) >= 3 and np.all(np.diff(low.astype(int)) != 0)  # alternating
    np.testing.assert_allclose(np.diff(lower_times), nutation.period, rtol=1e-9)


def test_lagrange_top_period_is_the_elliptic_integral():
    from scipy.integrate import quad

    nutation = lagrange_top_nutation(*TOPS[1])
    I1, I3, m, g, arm = TOPS[1][:5]
    u1, u2, u3 = nutation.roots
    beta = 2 * m * g * arm / I1
    # T = 2 int du / sqrt(beta (u - u1)(u2 - u)(u3 - u)); u = u1 + (u2 - u1) sin^2 s removes
    # the endpoint singularities
    integrand = lambda s: 2.0 / np.sqrt(beta * (u3 - u1 - (u2 - u1) * np.sin(s) ** 2))  # noqa: E731
    period = 2 * quad(integrand, 0.0, np.pi / 2, epsabs=0, epsrel=2e-14)[0]
    assert nutation.period == pytest.approx(period, rel=1e-13)
    assert -1 <= u1 < u2 <= 1 <= u3


def test_lagrange_top_steady_precession():
    # theta' = 0 and phi' at a root of the steady-precession condition: theta stays constant
    I1, I3, m, g, arm, theta0, psi_dot0 = 1.2, 0.5, 1.0, 9.81, 0.3, 0.7, 25.0
    # I1 phi'^2 cos - I3 (psi' + phi' cos) phi' + m g l = 0 (the theta equation at rest)
    c = np.cos(theta0)
    coeffs = [I1 * c - I3 * c, -I3 * psi_dot0, m * g * arm]
    phi_dot0 = min(np.roots(coeffs), key=abs)  # the slow precession
    nutation = lagrange_top_nutation(I1, I3, m, g, arm, theta0, 0.0, phi_dot0, psi_dot0)
    assert nutation.theta_max - nutation.theta_min < 1e-7
    t = np.linspace(0.0, 10.0, 7)
    np.testing.assert_allclose(nutation.theta(t), theta0, atol=1e-7)


@pytest.mark.parametrize(
    ("args", "match"),
    [
        ((1.0, 0.5, 1.0, 9.81, -0.3, 0.7, 0.0, 0.0, 20.0), "m g l"),
        ((1.0, 0.5, 1.0, 9.81, 0.3, 0.0, 0.0, 0.0, 20.0), "theta0"),
        ((-1.0, 0.5, 1.0, 9.81, 0.3, 0.7, 0.0, 0.0, 20.0), "I1"),
    ],
)
def test_lagrange_top_bad_arguments(args, match):
    with pytest.raises(ValueError, match=match):
        lagrange_top_nutation(*args)


# ------------------------------------------------------------------ ball joint
def test_ball_joint_principal_axes_is_the_compound_pendulum():
    m, arm, g = 2.0, 0.5, 9.81
    J = np.array([0.1, 0.3, 0.2])
    frequencies = ball_joint_frequencies(m, J, [0.0, 0.0, -arm], g=g)
    expected = np.sqrt(m * g * arm / (J[:2] + m * arm**2))
    np.testing.assert_allclose(frequencies, [0.0, *np.sort(expected)], rtol=1e-14)


def _tilted_inertia() -> np.ndarray:
    """A tensor with strong x-z and y-z products: the 2x2 block alone gives wrong frequencies."""
    Q = _random_rotation(11)
    return Q @ np.diag([0.05, 0.4, 0.3]) @ Q.T


def test_ball_joint_general_tensor_matches_the_3x3_eigenproblem():
    m, arm, g = 1.5, 0.4, 9.81
    J = _tilted_inertia()
    r = np.array([0.0, 0.0, -arm])
    J_O = J + m * (r @ r * np.eye(3) - np.outer(r, r))
    eigenvalues = eigh(m * g * arm * np.diag([1.0, 1.0, 0.0]), J_O, eigvals_only=True)
    frequencies = ball_joint_frequencies(m, J, r, g=g)
    np.testing.assert_allclose(frequencies[1:], np.sqrt(eigenvalues[1:]), rtol=1e-12)
    assert frequencies[0] == 0.0 and abs(eigenvalues[0]) < 1e-12
    # the coupling to the spin matters here (a test of the Schur complement)
    naive = np.sqrt(m * g * arm / np.linalg.eigvalsh(J_O[:2, :2]))
    assert np.max(np.abs(np.sort(naive) - frequencies[1:])) > 1e-2 * frequencies[1]


@pytest.mark.parametrize("mode", [1, 2])
def test_ball_joint_small_oscillation_returns_after_its_period(mode):
    m, arm, g = 1.5, 0.4, 9.81
    J = _tilted_inertia()
    r = np.array([0.0, 0.0, -arm])
    frequencies, modes = ball_joint_modes(m, J, r, g=g)
    J_O = J + m * (r @ r * np.eye(3) - np.outer(r, r))
    # eps small: the gyroscopic terms, quadratic, perturb the mode at relative order eps
    eps = 1e-6
    v = modes[:, mode]
    R0 = expm(_hat(eps * v))
    period = 2 * np.pi / frequencies[mode]

    def rhs(_: float, y: np.ndarray) -> np.ndarray:
        w, R = y[:3], y[3:].reshape(3, 3)
        torque = np.cross(r, R.T @ np.array([0.0, 0.0, -m * g]))
        dw = np.linalg.solve(J_O, np.cross(J_O @ w, w) + torque)
        return np.concatenate([dw, (R @ _hat(w)).ravel()])

    y0 = np.concatenate([np.zeros(3), R0.ravel()])
    t = period * np.array([0.25, 0.5, 0.75, 1.0])
    ode = solve_ivp(rhs, (0.0, period), y0, t_eval=t, **TOL)
    rotation = np.array([_vee(ode.y[3:, i].reshape(3, 3)) for i in range(4)])
    speed = frequencies[mode] * eps
    # theta(t) = eps v cos(omega t): through 0 at T/4 and 3T/4 (a relative frequency error
    # delta moves these by about eps delta), at -eps v and at rest at T/2, back at T
    np.testing.assert_allclose(rotation[[0, 2]], 0.0, atol=1e-5 * eps)
    np.testing.assert_allclose(rotation[[1, 3]], [-eps * v, eps * v], atol=1e-5 * eps)
    np.testing.assert_allclose(ode.y[:3, [1, 3]], 0.0, atol=1e-5 * speed)
    np.testing.assert_allclose(ode.y[:3, 0], -speed * v, atol=1e-5 * speed)
