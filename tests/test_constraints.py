"""Holonomic constraints g(t, q) = 0 (theory.md §6): orders, invariants, long runs, errors.

The constrained Galerkin integrator (collocated Lobatto nodes, multipliers at the control
points, momentum projected onto the hidden constraint at each step's end) is checked on
the models of ``galerkin_vi.problems.constrained``:

- the Cartesian pendulum against the exact (elliptic-function) solution of the angle form:
  positions, momenta and the angle atan2(x, -y) converge with order 2s for s = 1..4;
- the spherical pendulum as a constrained particle against the angle form, with J_z
  conserved to round-off and bounded energy;
- a bead on a spinning hoop (a time-dependent constraint) against the reduced model;
- a four-bar linkage (Grashof crank-rocker, Cartesian joints, three distance constraints)
  over 1e5 steps: constraints and hidden constraints at round-off, no energy drift; and its
  angle form (trigonometric constraints, non-constant mass matrix) against it;
- the compiled and NumPy backends against each other, a damped (forced) constrained
  pendulum, and the errors for inconsistent data and unsupported uses.

Compiled systems: the Cartesian pendulum (plain and damped), the spherical pendulum, the
hoop and both four-bar forms, 12-19 s each with a cold kernel cache (the file then takes
about 95 s on two workers); with a warm one, about 6 s. The 1e6-step four-bar run is marked
slow (6 s). ``python -m tests.test_constraints`` prints the order table of the
Cartesian pendulum (q, p and angle errors for s = 1..4).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cache

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.problems.constrained import (
    cartesian_pendulum,
    constrained_spherical_pendulum,
    four_bar_linkage,
    four_bar_positions,
    pendulum_angle,
    rotating_hoop,
)
from galerkin_vi.testing import assert_conserved
from galerkin_vi.tools.verification import fit_order

ORDER_TOLERANCE = 0.3
# constraint and hidden-constraint residuals of short runs (measured <= 4.5e-16)
ROUND_OFF = 1e-14
# the same over long runs (measured <= 1.8e-15 over 1e5 four-bar steps; 5.7e-14 for the hoop
# at t = 200, where sin(Omega t) is only as accurate as its argument)
LONG_RUN_RESIDUAL = 1e-12
EPS = np.finfo(float).eps


@cache
def _integrator(system: gvi.LagrangianSystem, s: int, backend: str = "numba") -> gvi.Integrator:
    """One integrator per system, degree and backend (the kernel spec is built once)."""
    return gvi.Integrator(system, gvi.Galerkin(s), backend=backend)


def _run(problem, s, h, n_steps, backend="numba", **kwargs) -> gvi.Trajectory:
    return _integrator(problem.system, s, backend).integrate(
        problem.q0, problem.v0, h=h, n_steps=n_steps, params=problem.params, **kwargs
    )


def _fit(step_sizes, errors, counts) -> float:
    """Order fitted over the points above the round-off floor 100 N eps."""
    order, mask = fit_order(step_sizes, errors, floor=100 * np.asarray(counts) * EPS)
    assert mask.sum() >= 2, (errors, mask)
    return order


# ----------------------------------------------------------------- Cartesian pendulum
# Step counts over T = 5 (theta0 = 1, at rest), all above the round-off floor. Measured
# (compiled backend; pairwise orders of the max error over all steps, q / p / angle):
#   s = 1  N = 20..160: 2.02, 2.01, 2.00 / 2.01, 2.00, 2.00 / 2.02, 2.01, 2.00  (finest q 4.3e-4)
#   s = 2  N = 10..80:  4.00, 4.00, 4.00 for all three                          (2.0e-7)
#   s = 3  N = 10..40:  5.97, 5.99 for all three                                (1.3e-9)
#   s = 4  N = 10..40:  7.97, 7.99 for all three                                (5.3e-13)
#          (N = 80 is at round-off, 4.1e-15: order 8 shows only between N = 10 and 40)
# No order reduction for any s: positions and momenta have order 2s, as theory.md §6.
PENDULUM_STEP_COUNTS = {1: (20, 40, 80, 160), 2: (10, 20, 40, 80), 3: (10, 20, 40), 4: (10, 20, 40)}
PENDULUM_THETA0 = 1.0


@dataclass(frozen=True)
class OrderStudy:
    """Errors (max over all steps) of the Cartesian pendulum against the exact solution."""

    degree: int
    step_counts: tuple[int, ...]
    step_sizes: np.ndarray
    q_errors: np.ndarray
    p_errors: np.ndarray
    angle_errors: np.ndarray
    constraint: float  # max |g| over all runs and steps
    hidden: float  # max |G v + g_t|

    def order(self, errors: np.ndarray) -> float:
        return _fit(self.step_sizes, errors, self.step_counts)

    def table(self) -> str:
        lines = [f"s = {self.degree} (predicted order {2 * self.degree})"]
        lines.append(
            f"{'N':>5} {'h':>8} {'err q':>10} {'ord':>5} {'err p':>10} {'ord':>5}"
            f" {'err angle':>10} {'ord':>5}"
        )
        for j, n in enumerate(self.step_counts):
            cells = [f"{n:5d} {self.step_sizes[j]:8.4f}"]
            for e in (self.q_errors, self.p_errors, self.angle_errors):
                rate = "" if j == 0 else f"{np.log2(e[j - 1] / e[j]):5.2f}"
                cells.append(f"{e[j]:10.3e} {rate:>5}")
            lines.append(" ".join(cells))
        lines.append(
            f"fitted orders q {self.order(self.q_errors):.2f}, p {self.order(self.p_errors):.2f},"
            f" angle {self.order(self.angle_errors):.2f}; max |g| {self.constraint:.1e},"
            f" max |G v + g_t| {self.hidden:.1e}"
        )
        return "\n".join(lines)


def pendulum_order_study(
    s: int, step_counts: tuple[int, ...] | None = None, backend: str = "numba"
) -> OrderStudy:
    """Run the Cartesian pendulum at each step count and measure the errors."""
    counts = PENDULUM_STEP_COUNTS[s] if step_counts is None else tuple(step_counts)
    problem = cartesian_pendulum(theta0=PENDULUM_THETA0)
    T = problem.t_final
    q_err, p_err, a_err = [], [], []
    constraint = hidden = 0.0
    for n in counts:
        traj = _integrator(problem.system, s, backend).integrate(
            problem.q0, problem.v0, h=T / n, n_steps=n, params=problem.params
        )
        theta, rate = pendulum_angle(traj.t, PENDULUM_THETA0)
        p_exact = rate[:, None] * np.stack([np.cos(theta), np.sin(theta)], axis=-1)
        angle = np.arctan2(traj.q[:, 0], -traj.q[:, 1])
        q_err.append(np.max(np.abs(traj.q - problem.exact(traj.t))))
        p_err.append(np.max(np.abs(traj.p - p_exact)))
        a_err.append(np.max(np.abs(angle - theta)))
        constraint = max(constraint, float(traj.constraint_residual().max()))
        hidden = max(hidden, float(traj.hidden_constraint_residual().max()))
    return OrderStudy(
        s,
        counts,
        T / np.asarray(counts, dtype=float),
        np.array(q_err),
        np.array(p_err),
        np.array(a_err),
        constraint,
        hidden,
    )


@pytest.mark.parametrize(
    ("theta0", "omega0"), [(1.0, 0.0), (-0.4, 0.9), (2.5, -1.0), (0.3, 2.5), (1.0, -3.0)]
)
def test_exact_pendulum_solution_solves_the_angle_equation(theta0, omega0):
    # librating (k < 1) and rotating (k > 1, both senses) against DOP853 on the library's
    # pendulum L = v^2/2 + cos q; measured differences 1.1e-13 .. 1.2e-12 over [0, 8]
    t = np.linspace(0.0, 8.0, 81)
    theta, rate = pendulum_angle(t, theta0, omega0)
    assert theta[0] == pytest.approx(theta0, abs=1e-15)
    assert rate[0] == pytest.approx(omega0, abs=1e-15)
    pendulum = problems.pendulum(theta0, omega0)
    reference = problems.ode_reference(pendulum.system, pendulum.q0, pendulum.v0, t)[:, 0]
    np.testing.assert_allclose(theta, reference, rtol=0, atol=1e-10)
    # the rate is the derivative of the angle (central differences)
    dt = 1e-5
    slope = pendulum_angle(t + dt, theta0, omega0)[0] - pendulum_angle(t - dt, theta0, omega0)[0]
    np.testing.assert_allclose(rate, slope / (2 * dt), rtol=0, atol=1e-8)
    with pytest.raises(ValueError, match="separatrix"):
        pendulum_angle(t, 0.0, 2.0)


def test_cartesian_pendulum_data_and_exact_solution():
    problem = cartesian_pendulum(theta0=0.7, omega0=0.4, length=2.0, g=3.0)
    system = problem.system
    assert system.m == 1 and system.n == 2
    np.testing.assert_allclose(problem.q0, 2.0 * np.array([np.sin(0.7), -np.cos(0.7)]))
    assert abs(system.constraint_values(problem.q0, 0.0, problem.params)[0]) < 1e-15
    assert abs(system.constraint_jacobian(problem.q0, 0.0, problem.params)[0] @ problem.v0) < 1e-15
    np.testing.assert_allclose(problem.exact(0.0), problem.q0, rtol=0, atol=1e-15)
    # the exact motion stays on the circle of radius l and has period 4K / sqrt(g / l)
    t = np.linspace(0, 10, 50)
    np.testing.assert_allclose(np.hypot(*problem.exact(t).T), 2.0, rtol=1e-15)
    assert cartesian_pendulum(theta0=0.0, omega0=2.0).exact is None  # the separatrix
    assert cartesian_pendulum(damping=0.1).exact is None
    assert cartesian_pendulum(damping=0.1).system.forces is not None


@pytest.mark.parametrize("s", [1, 2, 3, 4])
def test_cartesian_pendulum_converges_with_order_2s(s):
    study = pendulum_order_study(s)
    for name, errors in (
        ("q", study.q_errors),
        ("p", study.p_errors),
        ("angle", study.angle_errors),
    ):
        order = study.order(errors)
        assert abs(order - 2 * s) <= ORDER_TOLERANCE, (name, study.table())
    assert study.constraint <= ROUND_OFF and study.hidden <= ROUND_OFF, study.table()


def test_cartesian_pendulum_follows_a_rotating_pendulum():
    # k = 1.13 (theta0 = 0.5, omega0 = 2.2): the pendulum goes over the top; s = 3,
    # h = 0.05 over T = 10: measured max position error 7.0e-10
    problem = cartesian_pendulum(theta0=0.5, omega0=2.2, t_final=10.0)
    traj = _run(problem, 3, 0.05, 200)
    assert np.max(np.abs(traj.q - problem.exact(traj.t))) <= 1e-8
    angle = np.unwrap(np.arctan2(traj.q[:, 0], -traj.q[:, 1]))
    assert angle[-1] > 2 * np.pi  # it did turn over


# ---------------------------------------------------------- spherical pendulum, hoop
# Max position errors over all steps against the angle-form references (DOP853, about
# 1e-13 accurate), T = 5. Measured pairwise orders (N = 10, 20, 40, 80, 160):
#   spherical s = 1: 2.12 2.03 2.01 2.00   s = 2: 4.00 4.00 4.00 4.00   s = 3: 5.98 6.00 6.00 6.09
#   hoop      s = 1: 2.03 1.99 2.00 2.00   s = 2: 3.87 3.99 4.00 4.00   s = 3: 5.89 5.98 5.99 5.95
# (s = 4 reaches the references' accuracy at N = 40; its order is tested on the pendulum.)
REFERENCE_STEP_COUNTS = {1: (20, 40, 80), 2: (20, 40, 80), 3: (20, 40, 80)}


@pytest.mark.parametrize("make", [constrained_spherical_pendulum, rotating_hoop])
@pytest.mark.parametrize("s", [1, 2, 3])
def test_sphere_and_hoop_converge_to_the_minimal_coordinate_models(make, s):
    problem = make()
    counts = REFERENCE_STEP_COUNTS[s]
    errors = []
    for n in counts:
        traj = _integrator(problem.system, s).integrate(
            problem.q0, problem.v0, h=problem.t_final / n, n_steps=n, params=problem.params
        )
        errors.append(np.max(np.abs(traj.q - problem.exact(traj.t))))
        assert traj.constraint_residual().max() <= ROUND_OFF
        assert traj.hidden_constraint_residual().max() <= ROUND_OFF
    order = _fit(problem.t_final / np.array(counts), errors, counts)
    assert abs(order - 2 * s) <= ORDER_TOLERANCE, (errors, order)


def test_constrained_spherical_pendulum_conserves_jz_and_bounds_energy():
    # s = 2, h = 0.1, 5000 steps (T = 500, about 70 swings), so that the energy error is the
    # method's O(h^4) oscillation, well above round-off. Measured: max |dJ_z| 2.7e-14 (6.3e-14
    # over 20000 steps); max |dH| 2.004e-8 in both the first and the last tenth (ratio 1.00).
    # (theory.md §4's setting s = 3, h = 0.05: |dJ_z| 2.3e-14, |dH| 3.1e-13, at round-off.)
    problem = constrained_spherical_pendulum()
    x, y, z = problem.system.q
    assert tuple(problem.symmetries["rotation_z"]) == (-y, x, 0)
    traj = _run(problem, 2, 0.1, 5000)
    drifts = assert_conserved(
        traj, energy=5e-8, momenta=problem.symmetries, momentum_tol=1e-12, bounded=True
    )
    assert drifts["rotation_z"] <= 1e-12
    J = traj.momentum(problem.symmetries["rotation_z"])
    assert np.max(np.abs(J - J[0])) <= 1e-12
    assert traj.constraint_residual().max() <= LONG_RUN_RESIDUAL
    assert traj.hidden_constraint_residual().max() <= LONG_RUN_RESIDUAL
    # the polar angle stays in the band of the angle form's default data (theta in [0.74, 1])
    theta = np.arccos(-traj.q[:, 2])
    assert 0.7 < theta.min() and theta.max() < 1.0 + 1e-9


def test_rotating_hoop_keeps_the_jacobi_integral():
    # time-dependent constraint: the energy E is not conserved (the hoop does work), the
    # Jacobi integral E - Omega J_z is, up to O(h^2s) without drift. Measured (s = 2,
    # h = 0.05, 4000 steps): E varies by 1.73, E - Omega J_z by 4.9e-8 (last tenth / first
    # tenth 1.00); max |g| 5.7e-14 and |G v + g_t| 2.2e-14, larger than elsewhere because
    # sin(Omega t) at t = 200 is only as accurate as the argument, ulp(300) = 5.7e-14
    problem = rotating_hoop()
    spin = problem.params[sp.Symbol("Omega")]
    traj = _run(problem, 2, 0.05, 4000)
    x, y, _ = problem.system.q
    energy = traj.energy()
    jacobi = energy - spin * traj.momentum((-y, x, 0))
    assert np.ptp(energy) > 1.0
    deviation = np.abs(jacobi - jacobi[0])
    tenth = deviation.size // 10
    assert deviation.max() <= 2e-7
    assert deviation[-tenth:].max() <= 2 * deviation[1 : tenth + 1].max()
    assert traj.constraint_residual().max() <= LONG_RUN_RESIDUAL
    assert traj.hidden_constraint_residual().max() <= LONG_RUN_RESIDUAL


# ------------------------------------------------------------------ four-bar linkage
FOUR_BAR_H = 0.02  # about 160 steps per crank revolution (T = 3.27)


def _four_bar_geometry(q: np.ndarray, l0: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Transmission angle (degrees) and crank angle (unwrapped) along joint positions (B, C)."""
    b, c = q[:, :2], q[:, 2:]
    coupler, rocker = c - b, c - np.array([l0, 0.0])
    cos_mu = np.sum(coupler * rocker, axis=1) / (
        np.linalg.norm(coupler, axis=1) * np.linalg.norm(rocker, axis=1)
    )
    return np.degrees(np.arccos(cos_mu)), np.unwrap(np.arctan2(b[:, 1], b[:, 0]))


def _joints(q: np.ndarray, coordinates: str) -> np.ndarray:
    """Joint positions (x_B, y_B, x_C, y_C) of default four-bar states in either form."""
    if coordinates == "cartesian":
        return q
    crank, rocker = q[:, 0], q[:, 2]
    return np.stack(
        [0.3 * np.cos(crank), 0.3 * np.sin(crank), 1 + 0.9 * np.cos(rocker), 0.9 * np.sin(rocker)],
        axis=-1,
    )


def test_four_bar_initial_data_geometry_and_errors():
    cartesian, angles = four_bar_linkage(), four_bar_linkage(coordinates="angles")
    for problem in (cartesian, angles):
        system = problem.system
        assert system.m == system.n - 1  # one degree of freedom
        g = system.constraint_values(problem.q0, 0.0, problem.params)
        hidden = system.constraint_jacobian(problem.q0, 0.0, problem.params) @ problem.v0
        assert np.abs(g).max() <= 1e-15 and np.abs(hidden).max() <= 1e-15
    # the same state: equal energies (the kinetic energies agree on the manifold)
    energies = [
        p.system.hamiltonian(p.q0, p.system.legendre(p.q0, p.v0, 0.0, p.params), 0.0, p.params)
        for p in (cartesian, angles)
    ]
    assert energies[0] == pytest.approx(energies[1], rel=1e-14)
    assert energies[0] == pytest.approx(1.2108523247791712, rel=1e-14)
    # transmission angle over a full crank turn: no toggle; the constraints keep full rank
    states = np.array(
        [four_bar_positions(a, 0.0, 1.0, 0.3, 1.0, 0.9)[0] for a in np.linspace(0, 7, 701)]
    )
    mu, _ = _four_bar_geometry(states)
    assert 42.8 < mu.min() < 42.9 and 86.1 < mu.max() < 86.2
    jac = cartesian.system.constraint_jacobian(states, 0.0, cartesian.params)
    assert np.linalg.svd(jac, compute_uv=False)[:, -1].min() > 0.17
    with pytest.raises(ValueError, match="Grashof"):
        four_bar_linkage(lengths=(1.0, 0.3, 0.5, 0.4))  # 0.3 + 1.0 > 0.5 + 0.4
    with pytest.raises(ValueError, match="Grashof"):
        four_bar_linkage(lengths=(1.0, 1.2, 1.0, 0.9))  # crank not the shortest
    with pytest.raises(ValueError, match="coordinates"):
        four_bar_linkage(coordinates="polar")


def test_four_bar_formulations_agree():
    # Cartesian joints and link angles are two discretisations of the same motion: the
    # crank pins differ by O(h^4) at s = 2. Measured max differences over T = 3 at
    # h = 0.1, 0.05, 0.025: 3.7e-4, 2.2e-5, 1.4e-6 (ratios 16.8, 15.8)
    differences = []
    for h in (0.1, 0.05, 0.025):
        n = round(3.0 / h)
        a = _run(four_bar_linkage(), 2, h, n)
        b = _run(four_bar_linkage(coordinates="angles"), 2, h, n)
        pin = 0.3 * np.stack([np.cos(b.q[:, 0]), np.sin(b.q[:, 0])], axis=-1)
        differences.append(np.max(np.abs(a.q[:, :2] - pin)))
        assert b.constraint_residual().max() <= ROUND_OFF
        assert b.hidden_constraint_residual().max() <= ROUND_OFF
    assert differences[-1] <= 3e-6, differences
    assert differences[0] / differences[1] >= 13 and differences[1] / differences[2] >= 13


def _check_four_bar_run(traj: gvi.Trajectory, coordinates: str) -> dict[str, float]:
    residual = traj.constraint_residual()
    hidden = traj.hidden_constraint_residual()
    assert residual.max() <= LONG_RUN_RESIDUAL, residual.max()
    assert hidden.max() <= LONG_RUN_RESIDUAL, hidden.max()
    energy = traj.energy()
    deviation = np.abs(energy - energy[0])
    tenth = deviation.size // 10
    first, last = deviation[1 : tenth + 1].max(), deviation[-tenth:].max()
    assert last <= 2 * first, (first, last)
    mu, crank = _four_bar_geometry(_joints(traj.q, coordinates))
    assert 42.5 < mu.min() and mu.max() < 86.5  # never near a toggle position
    assert np.all(np.diff(crank) > 0)  # the crank keeps turning
    return {"first": first, "last": last, "turns": crank[-1] / (2 * np.pi)}


@pytest.mark.parametrize("coordinates", ["cartesian", "angles"])
def test_four_bar_linkage_1e5_steps(coordinates):
    # s = 2, h = 0.02, 1e5 steps (T = 2000, 612 crank turns), every state saved: 0.7-1.3 s
    # compiled, 0.3 s of diagnostics. Measured (about 4.9 Newton iterations per step):
    #   cartesian: max |g| 3.9e-16, |G v| 7.8e-16, max |dE| 3.536e-7 in the first tenth and
    #              in the last (ratio 1.00)
    #   angles:    max |g| 7.8e-16, |G v| 1.8e-15, max |dE| 2.864e-7 and 2.865e-7 (1.00);
    #              the crank angle reaches 3846 rad
    problem = four_bar_linkage(coordinates=coordinates)
    traj = _run(problem, 2, FOUR_BAR_H, 10**5)
    result = _check_four_bar_run(traj, coordinates)
    assert result["turns"] > 600
    assert result["first"] <= 1e-6


@pytest.mark.slow
def test_four_bar_linkage_1e6_steps():
    # 1e6 steps (6121 crank turns), every tenth state saved: 5.7 s compiled. Measured: max |g|
    # 3.9e-16, |G v| 7.8e-16, max |dE| 3.536e-7 in the first and the last tenth (ratio 1.00)
    traj = _run(four_bar_linkage(), 2, FOUR_BAR_H, 10**6, save_every=10)
    assert len(traj) == 10**5 + 1
    result = _check_four_bar_run(traj, "cartesian")
    assert result["turns"] > 6000


# ------------------------------------------------------------------------ backends
BACKEND_CASES = {
    "spherical": constrained_spherical_pendulum,
    "hoop": rotating_hoop,  # time-dependent constraint
    "four_bar_angles": lambda: four_bar_linkage(coordinates="angles"),  # M(q), trig g
}


@pytest.mark.parametrize("s", [1, 2, 3])
@pytest.mark.parametrize("name", BACKEND_CASES)
def test_compiled_and_numpy_backends_agree(name, s):
    # 20 steps of h = 0.1. The hoop starts at t0 = 0.3 from data projected onto its moving
    # constraints (project=True). Measured max differences (q, p): spherical and hoop
    # <= 1.4e-15, 2.0e-15; four-bar angles (q in radians, up to 2) <= 6.7e-15, 1.2e-15
    problem = BACKEND_CASES[name]()
    kwargs = {"t0": 0.3, "project": True} if name == "hoop" else {}
    runs = [_run(problem, s, 0.1, 20, backend=backend, **kwargs) for backend in ("numba", "numpy")]
    np.testing.assert_allclose(runs[0].t, runs[1].t, rtol=0, atol=1e-15)
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(runs[0].p, runs[1].p, rtol=0, atol=1e-13)
    for traj in runs:
        assert traj.constraint_residual().max() <= ROUND_OFF
        assert traj.hidden_constraint_residual().max() <= ROUND_OFF


# ------------------------------------------------------------------------- forces
def test_damped_cartesian_pendulum():
    # f = -c v (c = 0.1): the force's normal part is taken up by the constraint, so the angle
    # obeys theta'' = -sin(theta) - c theta'. s = 2, h = 0.05, 400 steps (T = 20).
    # Measured: max |g| 1.7e-16, |G v| 1.1e-16, energy strictly decreasing (largest
    # difference -1.9e-7, total -0.393), max angle error against DOP853 6.8e-8
    c = 0.1
    problem = cartesian_pendulum(damping=c)
    traj = _run(problem, 2, 0.05, 400)
    assert traj.constraint_residual().max() <= LONG_RUN_RESIDUAL
    assert traj.hidden_constraint_residual().max() <= LONG_RUN_RESIDUAL
    energy = traj.energy()
    assert np.all(np.diff(energy) < 0)
    assert energy[-1] - energy[0] < -0.3
    theta_s, rate_s = sp.symbols("theta omega")
    angle_form = gvi.LagrangianSystem(
        rate_s**2 / 2 + sp.cos(theta_s), [theta_s], [rate_s], forces=[-c * rate_s]
    )
    theta = problems.ode_reference(angle_form, [PENDULUM_THETA0], [0.0], traj.t)[:, 0]
    angle = np.arctan2(traj.q[:, 0], -traj.q[:, 1])
    assert np.max(np.abs(angle - theta)) <= 3e-7


# ------------------------------------------------------------------------- errors
@cache
def _planar(*constraints: str) -> gvi.LagrangianSystem:
    x, y, vx, vy = sp.symbols("x y vx vy")
    names = {"x": x, "y": y}
    return gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - y,
        [x, y],
        [vx, vy],
        constraints=[sp.sympify(g, locals=names) for g in constraints],
    )


def _numpy(system: gvi.LagrangianSystem, s: int = 1) -> gvi.Integrator:
    return gvi.Integrator(system, gvi.Galerkin(s), backend="numpy")


ON_CIRCLE = np.array([0.6, -0.8])


def test_redundant_constraints_are_rejected():
    integrator = _numpy(_planar("x**2 + y**2 - 1", "2*x**2 + 2*y**2 - 2"))
    for project in (False, True):
        with pytest.raises(ValueError, match="redundant"):
            integrator.integrate(ON_CIRCLE, [0.0, 0.0], h=0.1, n_steps=1, project=project)


def test_inconsistent_constraints_are_rejected():
    integrator = _numpy(_planar("x**2 + y**2 - 1", "x - 2"))  # the line misses the circle
    with pytest.raises(ValueError, match="off the constraint manifold"):
        integrator.integrate(ON_CIRCLE, [0.0, 0.0], h=0.1, n_steps=1)
    with pytest.raises(ValueError, match="inconsistent"):
        integrator.integrate(ON_CIRCLE, [0.0, 0.0], h=0.1, n_steps=1, project=True)
    x, y, vx, vy = sp.symbols("x y vx vy")
    with pytest.raises(ValueError, match="inconsistent"):
        gvi.LagrangianSystem(vx**2 / 2 + vy**2 / 2, [x, y], [vx, vy], constraints=[sp.Integer(1)])


def test_inconsistent_initial_data_are_rejected():
    integrator = _numpy(_planar("(x**2 + y**2 - 1) / 2"))
    with pytest.raises(ValueError, match="off the constraint manifold.*project=True"):
        integrator.integrate([0.6, -0.81], [0.0, 0.0], h=0.1, n_steps=1)
    with pytest.raises(ValueError, match="hidden constraint.*project=True"):
        integrator.integrate(ON_CIRCLE, [0.8, 0.1], h=0.1, n_steps=1)  # radial part 0.4
    # within the tolerance 1e-10 the data are accepted (and projected silently)
    traj = integrator.integrate(ON_CIRCLE * (1 + 1e-12), [0.8, 0.6], h=0.1, n_steps=3)
    assert traj.hidden_constraint_residual().max() <= ROUND_OFF


def test_unsupported_uses_are_rejected():
    x, y, vx, vy, r = sp.symbols("x y vx vy r")
    L = (vx**2 + vy**2) / 2 - y
    with pytest.raises(ValueError, match="may not depend on"):
        gvi.LagrangianSystem(L, [x, y], [vx, vy], constraints=[x * vx + y * vy])
    with pytest.raises(ValueError, match="constraints\\[0\\] contains symbols r"):
        gvi.LagrangianSystem(L, [x, y], [vx, vy], constraints=[x**2 + y**2 - r**2])
    circle = _planar("(x**2 + y**2 - 1) / 2")
    for method in (gvi.Galerkin(2, gvi.gauss_legendre(2)), gvi.Galerkin(2, gvi.gauss_lobatto(4))):
        with pytest.raises(ValueError, match="collocated"):
            gvi.Integrator(circle, method, backend="numpy")
    free = gvi.LagrangianSystem(L, [x, y], [vx, vy])
    with pytest.raises(ValueError, match="project=True needs a system with constraints"):
        _numpy(free).integrate(ON_CIRCLE, [0.0, 0.0], h=0.1, n_steps=1, project=True)
    with pytest.raises(ValueError, match="constrained"):
        _numpy(circle).step_del(ON_CIRCLE, [0.61, -0.79], h=0.1)
    assert _numpy(circle).kernel_path == "constrained"


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_projection_produces_consistent_data(backend):
    # q0 off the sphere and v0 with a radial part: project=True moves both onto the
    # (hidden) constraints; measured residuals <= 2.2e-16 over 40 steps
    problem = constrained_spherical_pendulum()
    integrator = _integrator(problem.system, 2, backend)
    q0 = problem.q0 * 1.05 + np.array([0.01, -0.02, 0.0])
    v0 = problem.v0 + 0.3 * problem.q0
    with pytest.raises(ValueError, match="project=True"):
        integrator.integrate(q0, v0, h=0.05, n_steps=1, params=problem.params)
    traj = integrator.integrate(q0, v0, h=0.05, n_steps=40, params=problem.params, project=True)
    assert traj.constraint_residual()[0] <= 1e-14
    assert traj.hidden_constraint_residual()[0] <= 1e-14
    assert traj.constraint_residual().max() <= 1e-14
    assert traj.hidden_constraint_residual().max() <= 1e-14
    # the projection is the nearest point of the sphere (radial), and removes the radial velocity
    np.testing.assert_allclose(traj.q[0], q0 / np.linalg.norm(q0), rtol=0, atol=1e-15)
    radial = q0 / np.linalg.norm(q0)
    np.testing.assert_allclose(traj.p[0], v0 - (v0 @ radial) * radial, rtol=0, atol=1e-15)


def _shifted_pendulum(shift: float) -> tuple[gvi.Integrator, np.ndarray, dict]:
    """The Cartesian pendulum with its pivot at (shift, 0): the same motion, translated."""
    x, y, vx, vy, pivot = sp.symbols("x y vx vy X0")
    system = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - y,
        [x, y],
        [vx, vy],
        params={pivot: 0.0},
        constraints=[((x - pivot) ** 2 + y**2 - 1) / 2],
    )
    q0 = np.array([shift + np.sin(1.0), -np.cos(1.0)])
    return _numpy(system, 2), q0, {pivot: shift}


@pytest.mark.parametrize("shift", [1e2, 1e3, 1e4])
def test_pendulum_far_from_the_origin(shift):
    # Newton's stopping rule is relative to max|q_k|: the round-off floor eps |q| of a
    # constraint evaluated far from the origin (before, this failed from shift = 10)
    integrator, q0, params = _shifted_pendulum(shift)
    traj = integrator.integrate(q0, [0.0, 0.0], h=0.01, n_steps=20, params=params)
    # |g| cannot be below the rounding of x itself: ulp(1e4) = 1.8e-12
    assert traj.constraint_residual().max() <= 1e-12 * shift
    np.testing.assert_allclose(
        traj.q - [shift, 0.0], cartesian_pendulum().exact(traj.t), rtol=0, atol=1e-9
    )


# ------------------------------------------------------------------- order table
def main() -> None:
    """Print the measured orders of the Cartesian pendulum for s = 1..4."""
    for s in (1, 2, 3, 4):
        counts = PENDULUM_STEP_COUNTS[s] + ((80,) if s == 4 else ())
        print(pendulum_order_study(s, counts).table())
        print()


if __name__ == "__main__":
    main()
