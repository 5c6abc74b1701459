"""Integrator: known equivalences, backend agreement, the run loop, bad input, failures.

Four Lagrangians are compiled (about 9 s each when the kernel cache is cold): a pendulum,
the double pendulum of theory.md §9, a separable 2-dof system with a constant non-diagonal
mass matrix and a quartic potential that blows up in finite time. Parameters (``params=``)
are used instead of new expressions wherever a variant is needed.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi

BACKENDS = ["numba", "numpy"]

# ------------------------------------------------------------------- models
q_, v_, g_ = sp.symbols("q v g")
a_, b_, va_, vb_ = sp.symbols("a b va vb")
x_, y_, vx_, vy_ = sp.symbols("x y vx vy")
m11, m12, m22, k_ = sp.symbols("m11 m12 m22 k")

PENDULUM_L = v_**2 / 2 + g_ * sp.cos(q_)
DOUBLE_PENDULUM_L = (
    (2 * va_**2 + vb_**2 + 2 * sp.cos(a_ - b_) * va_ * vb_) / 2 + 2 * sp.cos(a_) + sp.cos(b_)
)
SEPARABLE_M = np.array([[2.0, 0.5], [0.5, 1.0]])
SEPARABLE_L = (m11 * vx_**2 + 2 * m12 * vx_ * vy_ + m22 * vy_**2) / 2 - (
    x_**4 / 4 + y_**4 / 4 + sp.cos(x_ - y_)
)
BLOW_UP_L = v_**2 / 2 + k_ * q_**4  # q'' = 4 k q^3: q -> infinity in finite time


@pytest.fixture(scope="module")
def pendulum():
    return gvi.LagrangianSystem(PENDULUM_L, [q_], [v_], params={g_: 1.0})


@pytest.fixture(scope="module")
def double_pendulum():
    return gvi.LagrangianSystem(DOUBLE_PENDULUM_L, [a_, b_], [va_, vb_])


@pytest.fixture(scope="module")
def separable():
    return gvi.LagrangianSystem(
        SEPARABLE_L,
        [x_, y_],
        [vx_, vy_],
        params={m11: SEPARABLE_M[0, 0], m12: SEPARABLE_M[0, 1], m22: SEPARABLE_M[1, 1]},
    )


@pytest.fixture(scope="module")
def blow_up():
    return gvi.LagrangianSystem(BLOW_UP_L, [q_], [v_], params={k_: 1.0})


@pytest.fixture(scope="module")
def problems(pendulum, double_pendulum, separable):
    """name -> (system, q0, v0, h)."""
    return {
        "pendulum": (pendulum, np.array([1.5]), np.array([0.3]), 0.1),
        "double_pendulum": (double_pendulum, np.array([1.0, 0.5]), np.array([0.0, 0.3]), 0.05),
        "separable": (separable, np.array([0.8, -0.3]), np.array([0.2, 0.5]), 0.05),
    }


def _max_rel(a, b):
    return np.abs(np.asarray(a) - np.asarray(b)).max() / max(1.0, np.abs(b).max())


# ------------------------------------------------ independent reference maps
class MidpointReference:
    r"""(q, p) map of L_d = h L((q0 + q1)/2, (q1 - q0)/h), derived and solved here.

    p0 = -D_1 L_d = L_v - h/2 L_q and p1 = D_2 L_d = L_v + h/2 L_q at the midpoint.
    """

    def __init__(self, L, q, v, subs):
        L = L.subs(subs)
        qm, vm = sp.Matrix(q), sp.Matrix(v)
        Lq = sp.Matrix([L]).jacobian(qm).T
        Lv = sp.Matrix([L]).jacobian(vm).T
        args = [*q, *v]
        self.n = len(q)
        self.Lq = sp.lambdify(args, Lq, "numpy")
        self.Lv = sp.lambdify(args, Lv, "numpy")
        self.Lqq = sp.lambdify(args, Lq.jacobian(qm), "numpy")
        self.Lqv = sp.lambdify(args, Lq.jacobian(vm), "numpy")
        self.Lvv = sp.lambdify(args, Lv.jacobian(vm), "numpy")

    def _at(self, f, m, w):
        return np.array(f(*m, *w), dtype=float)

    def step(self, q0, p0, h):
        q1 = q0 + h * np.linalg.solve(self._at(self.Lvv, q0, 0 * q0), p0)
        previous = np.inf
        for _ in range(50):
            m, w = (q0 + q1) / 2, (q1 - q0) / h
            Lq = self._at(self.Lq, m, w)[:, 0]
            Lv = self._at(self.Lv, m, w)[:, 0]
            Lqq, Lqv, Lvv = (self._at(f, m, w) for f in (self.Lqq, self.Lqv, self.Lvv))
            R = p0 + h / 2 * Lq - Lv
            dLq = Lqq / 2 + Lqv / h
            dLv = Lqv.T / 2 + Lvv / h
            J = h / 2 * dLq - dLv
            dq = np.linalg.solve(J, -R)
            q1 = q1 + dq
            inc = np.abs(dq).max()
            if inc == 0.0 or (inc < 1e-13 and inc >= previous):
                break
            previous = inc
        m, w = (q0 + q1) / 2, (q1 - q0) / h
        return q1, self._at(self.Lv, m, w)[:, 0] + h / 2 * self._at(self.Lq, m, w)[:, 0]


def double_pendulum_vector_field(y):
    """Hamilton's equations of the double pendulum, y = (a, b, p_a, p_b)."""
    a, b, pa, pb = y
    c, s = np.cos(a - b), np.sin(a - b)
    M = np.array([[2.0, c], [c, 1.0]])
    va, vb = np.linalg.solve(M, [pa, pb])
    return np.array([va, vb, -s * va * vb - 2 * np.sin(a), s * va * vb - np.sin(b)])


def gauss_collocation_tableau(s):
    """Butcher tableau of the s-stage Gauss method from the Gauss-Legendre nodes."""
    x, _ = np.polynomial.legendre.leggauss(s)
    c = (1 + x) / 2
    A = np.empty((s, s))
    bw = np.empty(s)
    for j in range(s):
        others = np.delete(c, j)
        ell = np.polynomial.Polynomial.fromroots(others) / np.prod(c[j] - others)
        prim = ell.integ()
        A[:, j] = prim(c) - prim(0.0)
        bw[j] = prim(1.0) - prim(0.0)
    return A, bw, c


def gauss_rk_step(f, y0, h, s):
    A, bw, _ = gauss_collocation_tableau(s)
    K = np.tile(f(y0), (s, 1))
    previous = np.inf
    for _ in range(1000):  # fixed point iteration, contractive at h = 0.2
        K_new = np.array([f(y0 + h * A[i] @ K) for i in range(s)])
        change = np.abs(K_new - K).max()
        K = K_new
        if change == 0.0 or (change < 1e-14 and change >= previous):
            break
        previous = change
    return y0 + h * bw @ K


# ------------------------------------------------------- known equivalences
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("name", ["pendulum", "double_pendulum"])
def test_gauss1_is_the_midpoint_discrete_lagrangian(problems, name, backend):
    system, q0, v0, _ = problems[name]
    h = 0.1
    ref = MidpointReference(system.L, list(system.q), list(system.v), {g_: 1.0})
    p0 = system.legendre(q0, v0)
    integrator = gvi.Integrator(system, gvi.Galerkin(1, gvi.gauss_legendre(1)), backend=backend)
    traj = integrator.integrate(q0, p0=p0, h=h, n_steps=50)
    qs, ps = [q0], [p0]
    for _ in range(50):
        q1, p1 = ref.step(qs[-1], ps[-1], h)
        qs.append(q1)
        ps.append(p1)
    assert np.abs(traj.q - np.array(qs)).max() <= 1e-13  # measured 0 / 2.4e-15 (double)
    assert np.abs(traj.p - np.array(ps)).max() <= 1e-13  # measured 0 / 2.0e-15
    # the comparison discriminates: the Lobatto-2 (trapezoidal) map is another method
    other = gvi.Integrator(system, gvi.Galerkin(1), backend=backend)
    assert np.abs(other.integrate(q0, p0=p0, h=h, n_steps=50).q - traj.q).max() > 1e-5


@pytest.mark.parametrize("backend", BACKENDS)
def test_lobatto2_is_stormer_verlet(separable, backend):
    M = SEPARABLE_M

    def grad_V(q):
        x, y = q
        s = np.sin(x - y)
        return np.array([x**3 - s, y**3 + s])

    h, n_steps = 0.05, 200
    q, p = np.array([0.8, -0.3]), np.array([0.2, 0.5])
    qs, ps = [q], [p]
    for _ in range(n_steps):
        p_half = p - h / 2 * grad_V(q)
        q = q + h * np.linalg.solve(M, p_half)
        p = p_half - h / 2 * grad_V(q)
        qs.append(q)
        ps.append(p)
    assert separable.structure.separable
    integrator = gvi.Integrator(separable, gvi.Galerkin(1, gvi.gauss_lobatto(2)), backend=backend)
    traj = integrator.integrate(qs[0], p0=ps[0], h=h, n_steps=n_steps)
    assert _max_rel(traj.q, np.array(qs)) <= 1e-12  # measured 2.2e-14
    assert _max_rel(traj.p, np.array(ps)) <= 1e-12  # measured 6.2e-14


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("s", [2, 3])
def test_gauss_s_is_gauss_collocation_runge_kutta(double_pendulum, s, backend):
    # theory.md §9: degree s with Gauss s points == s-stage Gauss-Legendre RK on Hamilton's eqs
    h = 0.2
    q0 = np.array([1.0, 0.5])
    p0 = double_pendulum.legendre(q0, np.array([0.0, 0.3]))
    y1 = gauss_rk_step(double_pendulum_vector_field, np.concatenate([q0, p0]), h, s)
    integrator = gvi.Integrator(
        double_pendulum, gvi.Galerkin(s, gvi.gauss_legendre(s)), backend=backend
    )
    q1, p1 = integrator.step(q0, p0, h)
    assert np.abs(q1 - y1[:2]).max() <= 1e-12  # measured 1.1e-16 (s=2), 1.1e-16 (s=3)
    assert np.abs(p1 - y1[2:]).max() <= 1e-12  # measured 1.4e-15, 3.3e-15
    # the default (Lobatto s + 1) method is a different map of the same order
    q1_lob, _ = gvi.Integrator(double_pendulum, gvi.Galerkin(s), backend=backend).step(q0, p0, h)
    assert np.abs(q1_lob - y1[:2]).max() > 1e-9  # measured 7.0e-6 (s=2), 1.4e-8 (s=3)


STEP_METHODS = [(s, "lobatto") for s in range(1, 5)] + [(s, "gauss") for s in range(1, 5)]


def _method(s, family):
    if family == "lobatto":
        return gvi.Galerkin(s, gvi.gauss_lobatto(s + 1))
    return gvi.Galerkin(s, gvi.gauss_legendre(s))


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(("s", "family"), STEP_METHODS)
def test_step_agrees_with_step_del(double_pendulum, s, family, backend):
    h = 0.1
    integrator = gvi.Integrator(double_pendulum, _method(s, family), backend=backend)
    q0 = np.array([1.0, 0.5])
    p0 = double_pendulum.legendre(q0, np.array([0.0, 0.3]))
    q1, p1 = integrator.step(q0, p0, h)
    q2, _ = integrator.step(q1, p1, h, t0=h)
    q2_del = integrator.step_del(q0, q1, h)
    assert np.abs(q2 - q2_del).max() <= 1e-12  # measured <= 6.7e-16 over all cases
    assert np.abs(q2 - q1).max() > 1e-3  # not a fixed point: the check has content


@pytest.mark.parametrize(
    "method",
    [
        gvi.Galerkin(1),
        gvi.Galerkin(2, gvi.gauss_legendre(2)),
        gvi.Galerkin(3),
        gvi.Galerkin(4, gvi.gauss_lobatto(6)),
        gvi.Galerkin(3, gvi.gauss_legendre(4), nodes="equidistant"),
    ],
    ids=repr,
)
@pytest.mark.parametrize("name", ["pendulum", "double_pendulum", "separable"])
def test_numpy_and_numba_backends_agree(problems, name, method):
    system, q0, v0, h = problems[name]
    runs = [
        # the general Newton loop in both; specialised loops are compared in test_specialized
        gvi.Integrator(system, method, backend=backend, specialize=False).integrate(
            q0, v0, h=h, n_steps=100
        )
        for backend in BACKENDS
    ]
    assert np.abs(runs[0].q - runs[1].q).max() <= 1e-13  # measured <= 3.2e-13 before increments
    assert np.abs(runs[0].p - runs[1].p).max() <= 1e-13  # (control points as increments)
    np.testing.assert_array_equal(runs[0].t, runs[1].t)
    assert runs[0].newton_iterations.shape == runs[1].newton_iterations.shape == (100,)
    # numba: simplified Newton (factors kept while the increments contract 100x per
    # iteration), stopped when the positions q_k + C stop moving; numpy: exact Newton,
    # stopped when C stops moving. Measured: numba 0.99 fewer to 1.06 more per step
    simplified, exact = runs[0].mean_newton_iterations, runs[1].mean_newton_iterations
    assert abs(simplified - exact) <= 1.5


def test_auto_backend_is_numba(pendulum):
    assert gvi.Integrator(pendulum, gvi.Galerkin(1)).backend == "numba"
    assert gvi.Integrator(pendulum, gvi.Galerkin(1), backend="numpy").backend == "numpy"


# ------------------------------------------------------------------ the run
@pytest.fixture(scope="module")
def pendulum_integrator(pendulum):
    return gvi.Integrator(pendulum, gvi.Galerkin(2), backend="numba")


@pytest.mark.parametrize(("n_steps", "save_every"), [(10, 3), (9, 3), (10, 1), (5, 7), (12, 4)])
def test_save_every(pendulum_integrator, n_steps, save_every):
    h, t0 = 0.1, 0.25
    full = pendulum_integrator.integrate([1.5], [0.3], h=h, n_steps=n_steps, t0=t0)
    part = pendulum_integrator.integrate(
        [1.5], [0.3], h=h, n_steps=n_steps, t0=t0, save_every=save_every
    )
    rows = sorted(set(range(0, n_steps + 1, save_every)) | {n_steps})
    assert len(part) == len(rows)
    np.testing.assert_array_equal(part.q, full.q[rows])
    np.testing.assert_array_equal(part.p, full.p[rows])
    np.testing.assert_allclose(part.t, t0 + h * np.array(rows), rtol=0, atol=1e-15)  # meas. 0
    # per saved interval: the worst step of each; the mean over all steps
    intervals = -(-n_steps // save_every)
    assert part.newton_iterations.shape == (intervals,)
    worst = [
        full.newton_iterations[j * save_every : (j + 1) * save_every].max()
        for j in range(intervals)
    ]
    np.testing.assert_array_equal(part.newton_iterations, worst)
    assert part.total_newton_iterations == full.newton_iterations.sum()
    assert part.mean_newton_iterations == pytest.approx(full.newton_iterations.mean())


def test_full_run_shapes_and_times(pendulum_integrator):
    traj = pendulum_integrator.integrate(
        np.array([1.5]), np.array([0.3]), h=0.1, n_steps=30, t0=-1.0
    )
    assert traj.t.shape == (31,) and traj.q.shape == (31, 1) and traj.p.shape == (31, 1)
    np.testing.assert_allclose(traj.t, -1.0 + 0.1 * np.arange(31), rtol=0, atol=1e-15)  # measured 0
    assert traj.q[0, 0] == 1.5
    assert traj.p[0, 0] == 0.3  # p0 = dL/dv = v0
    assert np.all(traj.newton_iterations >= 1)
    assert 0 <= traj.max_residual < 1e-12  # measured 5.5e-15
    np.testing.assert_allclose(traj.velocities(), traj.p, rtol=0, atol=1e-15)  # M = 1
    np.testing.assert_allclose(traj.momentum([1]), traj.p[:, 0], rtol=0, atol=0)


def test_energy_is_bounded(pendulum_integrator):
    traj = pendulum_integrator.integrate([1.5], [0.3], h=0.1, n_steps=500, save_every=5)
    energy = traj.energy()
    assert energy.shape == (101,)
    assert energy[0] == pytest.approx(0.045 - np.cos(1.5), abs=1e-15)
    assert np.abs(energy - energy[0]).max() < 3e-6  # measured 2.9e-7 (order 4, h = 0.1)


def test_zero_steps(pendulum_integrator):
    traj = pendulum_integrator.integrate([1.5], [0.3], h=0.1, n_steps=0, t0=2.0)
    np.testing.assert_array_equal(traj.t, [2.0])
    np.testing.assert_array_equal(traj.q, [[1.5]])
    np.testing.assert_array_equal(traj.p, [[0.3]])
    assert traj.newton_iterations.shape == (0,)


@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize(
    "method", [gvi.Galerkin(3), gvi.Galerkin(2, gvi.gauss_legendre(2))], ids=repr
)
def test_negative_h_runs_backward_and_recovers_the_start(double_pendulum, method, backend):
    # symmetric methods: the map with -h is the inverse of the map with h
    integrator = gvi.Integrator(double_pendulum, method, backend=backend)
    q0, v0, h, n = np.array([1.0, 0.5]), np.array([0.0, 0.3]), 0.05, 40
    forward = integrator.integrate(q0, v0, h=h, n_steps=n)
    back = integrator.integrate(forward.q[-1], p0=forward.p[-1], h=-h, n_steps=n, t0=forward.t[-1])
    np.testing.assert_allclose(back.t, forward.t[::-1], rtol=0, atol=1e-14)
    assert np.abs(back.q - forward.q[::-1]).max() <= 1e-12  # measured 5.4e-14
    assert np.abs(back.p - forward.p[::-1]).max() <= 1e-12  # measured 1.8e-13
    assert np.abs(forward.q[-1] - q0).max() > 0.1  # it went somewhere


@pytest.mark.parametrize("backend", BACKENDS)
def test_params_override(pendulum, backend):
    integrator = gvi.Integrator(pendulum, gvi.Galerkin(2), backend=backend)
    default = integrator.integrate([1.5], [0.3], h=0.1, n_steps=40)
    by_symbol = integrator.integrate([1.5], [0.3], h=0.1, n_steps=40, params={g_: 4.0})
    by_name = integrator.integrate([1.5], [0.3], h=0.1, n_steps=40, params={"g": 4.0})
    assert np.abs(by_symbol.q - default.q).max() > 0.1
    np.testing.assert_array_equal(by_name.q, by_symbol.q)
    np.testing.assert_array_equal(by_symbol.params, [4.0])
    # the same as a system whose default is g = 4 (same kernel, no recompilation)
    strong = gvi.LagrangianSystem(PENDULUM_L, [q_], [v_], params={g_: 4.0})
    reference = gvi.Integrator(strong, gvi.Galerkin(2), backend=backend).integrate(
        [1.5], [0.3], h=0.1, n_steps=40
    )
    np.testing.assert_array_equal(by_symbol.q, reference.q)
    np.testing.assert_array_equal(by_symbol.p, reference.p)
    # energy uses the run's parameters: H = p^2/2 - 4 cos q
    np.testing.assert_allclose(by_symbol.energy()[0], 0.045 - 4 * np.cos(1.5), rtol=1e-15)
    # ... and the override did not change the system's defaults
    np.testing.assert_array_equal(pendulum.parameter_vector(), [1.0])


def test_v0_and_p0_give_the_same_run_when_consistent(double_pendulum):
    integrator = gvi.Integrator(double_pendulum, gvi.Galerkin(2), backend="numba")
    q0, v0 = np.array([1.0, 0.5]), np.array([0.0, 0.3])
    by_v = integrator.integrate(q0, v0, h=0.05, n_steps=20)
    by_p = integrator.integrate(q0, p0=double_pendulum.legendre(q0, v0), h=0.05, n_steps=20)
    np.testing.assert_array_equal(by_v.p[0], double_pendulum.legendre(q0, v0))
    assert np.abs(by_v.q - by_p.q).max() <= 1e-14  # measured 0


# ----------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        (dict(q0=[1.0, 2.0], v0=[0.0]), ValueError, r"q0 must have shape \(1,\), got \(2,\)"),
        (dict(q0=[[1.0]], v0=[0.0]), ValueError, r"q0 must have shape \(1,\)"),
        (dict(q0=1.0, v0=[0.0]), ValueError, r"q0 must have shape \(1,\), got \(\)"),
        (dict(q0=[np.nan], v0=[0.0]), ValueError, "q0 contains NaN or inf"),
        (dict(q0=[np.inf], v0=[0.0]), ValueError, "q0 contains NaN or inf"),
        (dict(q0=["a"], v0=[0.0]), TypeError, "q0 must be an array of real numbers"),
        (dict(q0=[1.0], v0=[np.nan]), ValueError, "v0 contains NaN or inf"),
        (dict(q0=[1.0], v0=[0.0, 1.0]), ValueError, r"v0 must have shape \(1,\)"),
        (dict(q0=[1.0], p0=[np.nan]), ValueError, "p0 contains NaN or inf"),
        (dict(q0=[1.0], v0=[0.0], p0=[0.0]), ValueError, "exactly one of v0.*and p0"),
        (dict(q0=[1.0]), ValueError, "exactly one of v0.*and p0"),
        (dict(q0=[1.0], v0=[0.0], h=0.0), ValueError, "h must be finite and nonzero"),
        (dict(q0=[1.0], v0=[0.0], h=np.nan), ValueError, "h must be finite and nonzero"),
        (dict(q0=[1.0], v0=[0.0], h=np.inf), ValueError, "h must be finite and nonzero"),
        (dict(q0=[1.0], v0=[0.0], h="0.1"), TypeError, "h must be a real number"),
        (dict(q0=[1.0], v0=[0.0], h=None), TypeError, "h must be a real number"),
        (dict(q0=[1.0], v0=[0.0], n_steps=2.5), ValueError, "n_steps must be a non-negative int"),
        (dict(q0=[1.0], v0=[0.0], n_steps=10.0), ValueError, "n_steps must be a non-negative"),
        (dict(q0=[1.0], v0=[0.0], n_steps=-1), ValueError, "n_steps must be a non-negative int"),
        (dict(q0=[1.0], v0=[0.0], n_steps=True), ValueError, "n_steps must be a non-negative"),
        (dict(q0=[1.0], v0=[0.0], n_steps="5"), ValueError, "n_steps must be a non-negative"),
        (dict(q0=[1.0], v0=[0.0], save_every=0), ValueError, "save_every must be a positive"),
        (dict(q0=[1.0], v0=[0.0], save_every=1.5), ValueError, "save_every must be a positive"),
        (dict(q0=[1.0], v0=[0.0], t0=np.nan), ValueError, "t0 must be finite"),
        (dict(q0=[1.0], v0=[0.0], params={"gg": 1.0}), ValueError, "gg is not a declared"),
        (dict(q0=[1.0], v0=[0.0], params={g_: np.nan}), ValueError, r"params\[g\] must be finite"),
    ],
)
def test_integrate_bad_input(pendulum, kwargs, error, match):
    integrator = gvi.Integrator(pendulum, gvi.Galerkin(1), backend="numpy")
    kwargs = {"h": 0.1, "n_steps": 3, **kwargs}
    with pytest.raises(error, match=match):
        integrator.integrate(**kwargs)


def test_integrate_requires_keyword_h_and_n_steps(pendulum):
    integrator = gvi.Integrator(pendulum, gvi.Galerkin(1), backend="numpy")
    with pytest.raises(TypeError):
        integrator.integrate([1.0], [0.0], None, 0.1, 3)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        (dict(backend="cuda"), ValueError, "backend must be one of.*'cuda'"),
        (dict(backend="NUMBA"), ValueError, "backend must be one of"),
        (dict(tol=0.0), ValueError, r"tol must be a real number in \(0, 1\)"),
        (dict(tol=-1e-14), ValueError, "tol must be"),
        (dict(tol=np.nan), ValueError, "tol must be"),
        (dict(tol="1e-14"), ValueError, "tol must be"),
        (dict(maxiter=0), ValueError, "maxiter must be an int in"),
        (dict(maxiter=2.0), ValueError, "maxiter must be an int in"),
        (dict(method="galerkin"), TypeError, "method must be a Galerkin or Composition method"),
    ],
)
def test_integrator_bad_arguments(pendulum, kwargs, error, match):
    with pytest.raises(error, match=match):
        gvi.Integrator(pendulum, **kwargs)


def test_integrator_requires_a_system():
    with pytest.raises(TypeError, match="system must be a LagrangianSystem"):
        gvi.Integrator(PENDULUM_L)


def test_degenerate_initial_velocity_is_reported():
    # L_vv = q^2 - 1 is singular at q0 = 1 although regular at random points
    system = gvi.LagrangianSystem((q_**2 - 1) * v_**2 / 2, [q_], [v_])
    integrator = gvi.Integrator(system, gvi.Galerkin(1), backend="numpy")
    with pytest.raises(gvi.DegenerateLagrangianError, match="singular at q0"):
        integrator.integrate([1.0], [0.5], h=0.1, n_steps=2)


@pytest.mark.parametrize(
    ("call", "error", "match"),
    [
        (lambda it: it.step([1.0, 2.0], [0.0], 0.1), ValueError, "q0 must have shape"),
        (lambda it: it.step([1.0], [np.nan], 0.1), ValueError, "p0 contains NaN"),
        (lambda it: it.step([1.0], [0.0], 0.0), ValueError, "h must be finite and nonzero"),
        (lambda it: it.step_del([1.0], [np.inf], 0.1), ValueError, "q1 contains NaN or inf"),
        (lambda it: it.step_del([1.0], [1.1, 2.0], 0.1), ValueError, "q1 must have shape"),
        (lambda it: it.step_del([1.0], [1.1], np.nan), ValueError, "h must be finite"),
    ],
)
def test_step_bad_input(pendulum, call, error, match):
    with pytest.raises(error, match=match):
        call(gvi.Integrator(pendulum, gvi.Galerkin(2), backend="numpy"))


# ---------------------------------------------------------------- failures
@pytest.mark.parametrize("backend", BACKENDS)
@pytest.mark.parametrize("save_every", [1, 3, 4])
def test_convergence_error_mid_run_keeps_the_partial_trajectory(blow_up, backend, save_every):
    integrator = gvi.Integrator(blow_up, gvi.Galerkin(2), backend=backend)
    h, t0 = 0.05, 0.5
    with np.errstate(all="ignore"), pytest.raises(gvi.ConvergenceError) as info:
        integrator.integrate(
            [1.0], [0.0], h=h, n_steps=1000, t0=t0, save_every=save_every, on_failure="raise"
        )
    err = info.value
    assert 5 <= err.step < 1000  # measured 18: q runs off to infinity near t = 0.9
    assert err.t == pytest.approx(t0 + err.step * h, rel=1e-15)
    assert np.isnan(err.residual) or err.residual > 1e-8  # measured 442 (last increment)
    assert f"step {err.step}" in str(err)
    assert "smaller h" in str(err)
    partial = err.partial
    assert isinstance(partial, gvi.Trajectory)
    # every saved state before the failing step plus the last good state, nothing after it
    assert len(partial) == err.step // save_every + 1 + (err.step % save_every != 0)
    assert partial.t[-1] == pytest.approx(t0 + err.step * h, rel=1e-15)
    due = t0 + h * save_every * np.arange(err.step // save_every + 1)
    np.testing.assert_allclose(partial.t[: due.size], due, rtol=1e-15)
    # one entry per saved interval, the failing step's included
    assert partial.newton_iterations.shape == (err.step // save_every + 1,)
    assert partial.n_steps == err.step + 1
    # ... and equal to a successful run that stops just before the failure
    shorter = integrator.integrate(
        [1.0], [0.0], h=h, n_steps=err.step, t0=t0, save_every=save_every
    )
    rows = [i for i, time in enumerate(shorter.t) if time in set(partial.t)]
    np.testing.assert_array_equal(shorter.q[rows], partial.q)
    np.testing.assert_array_equal(shorter.p[rows], partial.p)
    np.testing.assert_array_equal(partial.t, shorter.t[rows])


def test_convergence_error_same_step_in_both_backends(blow_up):
    # the compiled loop iterates by fixed point (constant mass) where the reference
    # runs Newton: near the blow-up their domains of convergence differ by one step
    errors = []
    for backend in BACKENDS:
        integrator = gvi.Integrator(
            blow_up, gvi.Galerkin(2, gvi.gauss_legendre(2)), backend=backend
        )
        with np.errstate(all="ignore"), pytest.raises(gvi.ConvergenceError) as info:
            integrator.integrate([1.0], [0.0], h=0.02, n_steps=1000, on_failure="raise")
        errors.append(info.value)
    steps = [e.step for e in errors]
    assert abs(steps[0] - steps[1]) <= 1  # measured 47 (compiled) and 46 (reference)
    common = min(steps)
    np.testing.assert_allclose(
        errors[0].partial.q[:common], errors[1].partial.q[:common], rtol=1e-10
    )


@pytest.mark.parametrize("backend", BACKENDS)
def test_convergence_error_at_the_first_step(pendulum, backend):
    # one Newton iteration from the linear guess cannot meet tol
    integrator = gvi.Integrator(pendulum, gvi.Galerkin(3), backend=backend, tol=1e-15, maxiter=1)
    with pytest.raises(gvi.ConvergenceError) as info:
        integrator.integrate([1.5], [0.3], h=0.3, n_steps=10, t0=1.0, on_failure="raise")
    err = info.value
    assert err.step == 0
    assert err.t == 1.0
    assert err.residual > 1e-15
    np.testing.assert_array_equal(err.partial.t, [1.0])
    np.testing.assert_array_equal(err.partial.q, [[1.5]])
    np.testing.assert_array_equal(err.partial.p, [[0.3]])


def test_convergence_error_is_a_runtime_error():
    assert issubclass(gvi.ConvergenceError, RuntimeError)


# -------------------------------------------------------------------- source
@pytest.mark.parametrize("backend", BACKENDS)
def test_source_contains_the_generated_point_functions(pendulum, backend):
    source = gvi.Integrator(pendulum, gvi.Galerkin(2), backend=backend).source
    for name in ("def point_gradient", "def point_hessian", "def lagrangian"):
        assert name in source
    # only point functions: the loops are package modules, compiled once per machine
    assert "def general_loop" not in source and "def lu_factor" not in source
    assert "math.sin" in source  # L_q = -g sin(q) is in the printed code
    assert "prm[0]" in source  # the parameter g is run-time data, not a baked-in constant
    assert "Lqv[" not in source  # the pendulum has no q-v coupling
    compile(source, "<generated>", "exec")


def test_source_of_coupled_system_keeps_the_Lqv_block(double_pendulum):
    integrator = gvi.Integrator(double_pendulum, gvi.Galerkin(2), backend="numba")
    source = integrator.source
    assert integrator._spec.has_Lqv
    assert "Lqv[1] =" in source  # entry (0, 1), flat
