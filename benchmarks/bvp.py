"""Boundary-value problems: galerkin_vi's solve_bvp beside scipy's, and its cost against N.

Two parts, both in one run:

- **against scipy.integrate.solve_bvp** on the pendulum theta'' = -sin theta
  with theta(0) = 0.3, theta(3) = -1.2 (reference: shooting with DOP853 at
  rtol = atol = 1e-14 from the initial velocity that hits the end) and on the
  catenary y = cosh x on [-1, 1] (closed form). scipy gets its strongest
  setting: the analytic Jacobians ``fun_jac`` and ``bc_jac`` (its default is
  finite differences) and room for a million nodes; each solver runs a ladder
  of settings (scipy: ``tol``; galerkin_vi: the number of elements N at
  degree 4) from the same straight-line guess. The table gives the error
  against the reference at 201 points (scipy: ``sol``; galerkin_vi: the
  dense output of its nodes and momenta, ``trajectory.sol``, which keeps
  the nodes' order 2s; the element polynomials between the nodes have the
  stage error, order s + 1) and the CPU time, best of three; then the cheapest run of each that
  reaches 1e-10 and the ratio.
- **cost per Newton iteration** for N = 10^4 and 10^5 elements of a
  two-coordinate system (the Hénon–Heiles potential, degree 2), and their ratio
  (linear cost: 10).

Usage::

    python benchmarks/bvp.py
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable

import numpy as np
import sympy as sp
from scipy.integrate import solve_bvp as scipy_solve_bvp
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import galerkin_vi as gvi

TARGET = 1e-10
THETA_A, THETA_B, T_PENDULUM = 0.3, -1.2, 3.0


def _best(scene: tuple[Callable, Callable], repeats: int = 3) -> tuple[float, float, float]:
    """(error, CPU s of the solve, CPU s of the solve and the evaluation at 201 points)."""
    solve, error_of = scene
    best_solve = best_total = np.inf
    error = np.nan
    for _ in range(repeats):
        start = time.process_time()
        result = solve()
        middle = time.process_time()
        error = error_of(result)
        end = time.process_time()
        best_solve = min(best_solve, middle - start)
        best_total = min(best_total, end - start)
    return error, best_solve, best_total


# ------------------------------------------------------------------ references
def pendulum_reference(x: np.ndarray) -> np.ndarray:
    def end(v0):
        sol = solve_ivp(lambda t, y: [y[1], -np.sin(y[0])], (0, T_PENDULUM), [THETA_A, v0],
                        method="DOP853", rtol=1e-14, atol=1e-14)  # fmt: skip
        return sol.y[0, -1] - THETA_B

    v0 = brentq(end, -3.0, 0.5, xtol=1e-15)
    sol = solve_ivp(lambda t, y: [y[1], -np.sin(y[0])], (0, T_PENDULUM), [THETA_A, v0],
                    method="DOP853", rtol=1e-14, atol=1e-14, dense_output=True)  # fmt: skip
    return sol.sol(x)[0]


# --------------------------------------------------------------------- scenes
def _pendulum_gvi(N: int) -> Callable[[], float]:
    th, w = sp.symbols("theta w")
    system = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])
    x = np.linspace(0, T_PENDULUM, 201)
    exact = pendulum_reference(x)

    def solve():
        return gvi.solve_bvp(system, gvi.Galerkin(4), [THETA_A], [THETA_B], (0, T_PENDULUM), N)

    def error(res) -> float:
        return float(np.abs(res.trajectory.sol(x)[:, 0] - exact).max()) if res.success else np.inf

    return solve, error


def _pendulum_scipy(tol: float) -> Callable[[], float]:
    x = np.linspace(0, T_PENDULUM, 201)
    exact = pendulum_reference(x)

    def solve():
        mesh = np.linspace(0, T_PENDULUM, 11)
        guess = np.vstack([THETA_A + (THETA_B - THETA_A) * mesh / T_PENDULUM,
                           np.full_like(mesh, (THETA_B - THETA_A) / T_PENDULUM)])  # fmt: skip
        return scipy_solve_bvp(
            lambda t, y: np.vstack([y[1], -np.sin(y[0])]),
            lambda ya, yb: np.array([ya[0] - THETA_A, yb[0] - THETA_B]),
            mesh, guess, tol=tol, max_nodes=10**6,
            fun_jac=lambda t, y: np.array([[np.zeros_like(t), np.ones_like(t)],
                                           [-np.cos(y[0]), np.zeros_like(t)]]),
            bc_jac=lambda ya, yb: (np.array([[1.0, 0.0], [0.0, 0.0]]),
                                   np.array([[0.0, 0.0], [1.0, 0.0]])),
        )  # fmt: skip

    def error(sol) -> float:
        return float(np.abs(sol.sol(x)[0] - exact).max()) if sol.success else np.inf

    return solve, error


def _catenary_gvi(N: int) -> Callable[[], float]:
    x_, y, vy = sp.symbols("x y vy")
    system = gvi.LagrangianSystem(y * sp.sqrt(1 + vy**2), [y], [vy], t=x_)
    c1 = np.cosh(1.0)
    x = np.linspace(-1, 1, 201)

    def solve():
        return gvi.solve_bvp(system, gvi.Galerkin(4), [c1], [c1], (-1.0, 1.0), N)

    def error(res) -> float:
        if not res.success:
            return np.inf
        return float(np.abs(res.trajectory.sol(x)[:, 0] - np.cosh(x)).max())

    return solve, error


def _catenary_scipy(tol: float) -> Callable[[], float]:
    c1 = np.cosh(1.0)
    x = np.linspace(-1, 1, 201)

    def solve():
        mesh = np.linspace(-1, 1, 11)
        return scipy_solve_bvp(
            lambda t, y: np.vstack([y[1], (1 + y[1] ** 2) / y[0]]),
            lambda ya, yb: np.array([ya[0] - c1, yb[0] - c1]),
            mesh, np.vstack([np.full_like(mesh, c1), np.zeros_like(mesh)]), tol=tol,
            max_nodes=10**6,
            fun_jac=lambda t, y: np.array([[np.zeros_like(t), np.ones_like(t)],
                                           [-(1 + y[1] ** 2) / y[0] ** 2, 2 * y[1] / y[0]]]),
            bc_jac=lambda ya, yb: (np.array([[1.0, 0.0], [0.0, 0.0]]),
                                   np.array([[0.0, 0.0], [1.0, 0.0]])),
        )  # fmt: skip

    def error(sol) -> float:
        return float(np.abs(sol.sol(x)[0] - np.cosh(x)).max()) if sol.success else np.inf

    return solve, error


SCENES = {
    "pendulum": (_pendulum_gvi, (8, 16, 24, 32), _pendulum_scipy, (1e-6, 1e-8, 1e-10, 1e-12)),
    "catenary": (_catenary_gvi, (4, 8, 16, 24), _catenary_scipy, (1e-6, 1e-8, 1e-10, 1e-12)),
}


def compare() -> None:
    names = ("galerkin_vi deg 4", "scipy solve_bvp")
    for scene, (ours, our_settings, theirs, their_settings) in SCENES.items():
        print(f"\n{scene}: error at 201 points; CPU s of the solve, and with the evaluation")
        rows = [(names[0], f"N = {N}", *_best(ours(N))) for N in our_settings]
        rows += [(names[1], f"tol = {tol:.0e}", *_best(theirs(tol))) for tol in their_settings]
        for name, setting, error, solve, total in rows:
            print(f"{name:18s} {setting:12s} {error:10.2e} {solve:9.4f} {total:9.4f}")
        for column, label in ((3, "solve"), (4, "solve + evaluation")):
            best = {}
            for row in rows:
                if row[2] <= TARGET and row[column] < best.get(row[0], np.inf):
                    best[row[0]] = row[column]
            if len(best) == 2:
                ratio = best[names[1]] / best[names[0]]
                print(f"to reach {TARGET:.0e} ({label}): galerkin_vi {best[names[0]]:.4f} s, "
                      f"scipy {best[names[1]]:.4f} s: {ratio:.1f}x")  # fmt: skip
            else:
                print(f"to reach {TARGET:.0e} ({label}): reached by {sorted(best)} only")
        print("best error reached: " + ", ".join(
            f"{name} {min(r[2] for r in rows if r[0] == name):.1e}" for name in names))  # fmt: skip


def scaling() -> None:
    x, y, vx, vy = sp.symbols("x y vx vy")
    henon_heiles = gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - (x**2 + y**2) / 2 - x**2 * y + y**3 / 3, [x, y], [vx, vy]
    )
    method = gvi.Galerkin(2)
    print("\ncost per Newton iteration, Hénon–Heiles (n = 2), degree 2, h = 0.01")
    per = {}
    for N in (10**4, 10**5):
        T = 0.01 * N
        # a run from a guess near a solution: the trajectory from (0.1, 0, 0, 0.3)
        traj = gvi.Integrator(henon_heiles, method).integrate(
            [0.1, 0.0], [0.0, 0.3], h=0.01, n_steps=N
        )
        start = time.process_time()
        res = gvi.solve_bvp(henon_heiles, method, traj.q[0], traj.q[-1], (0, T), N,
                            guess=traj.q + 1e-6)  # fmt: skip
        seconds = time.process_time() - start
        per[N] = seconds / res.iterations
        print(f"N = {N:>6d}: {res.iterations} iterations, {seconds:.2f} s, "
              f"{per[N] * 1e3:.1f} ms per iteration; {res.message}")  # fmt: skip
    print(f"ratio 10^5 / 10^4: {per[10**5] / per[10**4]:.1f} (linear: 10, target <= 12)")


def main() -> int:
    compare()
    scaling()
    return 0


if __name__ == "__main__":
    sys.exit(main())
