"""Cart-pole swing-up: DMOC through the discrete action beside CasADi + IPOPT collocation.

A cart (mass 1) with a pole (point mass 0.3 at length 0.5) hanging down is
brought in T = 2 s from rest at x = 0 to rest at x = 1 with the pole upright,
minimising int u^2 dt with |u| <= 20 on the cart. Both sides solve the same
continuous problem from the same straight-line guess (zero controls):

- galerkin_vi: ``gvi.solve_optimal_control`` (DMOC: the discrete
  Lagrange–d'Alembert equations as constraints, exact derivatives), Galerkin
  degrees 2 and 3 with SciPy's trust-constr, and degree 3 with IPOPT (the same
  program as CasADi expressions);
- CasADi 3 (``pip install -e ".[bench]"``) with IPOPT: trapezoidal and
  Hermite–Simpson direct collocation of the equations of motion (CasADi's
  automatic derivatives), the usual choices of its users.

Each row: elements N, the optimal cost, its error against the reference (the
converged limit of the highest-order runs: Galerkin(3) at N = 320) and the
CPU seconds of the solve; then the slopes of the cost errors.

Usage::

    python benchmarks/cart_pole.py
"""

from __future__ import annotations

import sys
import time

import numpy as np
import sympy as sp

import galerkin_vi as gvi

MC, MP, LENGTH, G, T, U_MAX = 1.0, 0.3, 0.5, 9.81, 2.0, 20.0
START, END = [0.0, 0.0], [1.0, np.pi]


def cart_pole() -> tuple[gvi.LagrangianSystem, sp.Symbol]:
    x, th, vx, w, u = sp.symbols("x theta vx w u")
    kinetic = (MC + MP) * vx**2 / 2 + MP * LENGTH * vx * w * sp.cos(th) + MP * LENGTH**2 * w**2 / 2
    potential = -MP * G * LENGTH * sp.cos(th)  # theta = 0 hanging down
    system = gvi.LagrangianSystem(kinetic - potential, [x, th], [vx, w], forces=[u, 0],
                                  params={u: 0.0})  # fmt: skip
    return system, u


def galerkin(degree: int, N: int, solver: str = "trust-constr") -> tuple[float, float, bool]:
    system, u = cart_pole()
    start = time.process_time()
    res = gvi.solve_optimal_control(system, gvi.Galerkin(degree), [u], u**2, (0.0, T), N, START,
                                    END, [0.0, 0.0], [0.0, 0.0], control_bounds=(-U_MAX, U_MAX),
                                    maxiter=3000, solver=solver)  # fmt: skip
    return res.cost, time.process_time() - start, res.success


def casadi_collocation(scheme: str, N: int) -> tuple[float, float, bool]:
    import casadi as ca

    def dynamics(z, u):
        _, th, vx, w = z[0], z[1], z[2], z[3]
        mass = ca.vertcat(
            ca.horzcat(MC + MP, MP * LENGTH * ca.cos(th)),
            ca.horzcat(MP * LENGTH * ca.cos(th), MP * LENGTH**2),
        )
        rhs = ca.vertcat(u + MP * LENGTH * ca.sin(th) * w**2, -MP * G * LENGTH * ca.sin(th))
        acc = ca.solve(mass, rhs)
        return ca.vertcat(vx, w, acc[0], acc[1])

    h = T / N
    opti = ca.Opti()
    Z = opti.variable(4, N + 1)
    U = opti.variable(1, N + 1)
    cost = 0
    for k in range(N):
        fk, fk1 = dynamics(Z[:, k], U[k]), dynamics(Z[:, k + 1], U[k + 1])
        if scheme == "trapezoidal":
            opti.subject_to(Z[:, k + 1] == Z[:, k] + h / 2 * (fk + fk1))
            cost += h / 2 * (U[k] ** 2 + U[k + 1] ** 2)
        else:  # Hermite-Simpson, with the control at the midpoint as a variable
            um = opti.variable()
            zm = (Z[:, k] + Z[:, k + 1]) / 2 + h / 8 * (fk - fk1)
            fm = dynamics(zm, um)
            opti.subject_to(Z[:, k + 1] == Z[:, k] + h / 6 * (fk + 4 * fm + fk1))
            opti.subject_to(opti.bounded(-U_MAX, um, U_MAX))
            opti.set_initial(um, 0.0)
            cost += h / 6 * (U[k] ** 2 + 4 * um**2 + U[k + 1] ** 2)
    opti.minimize(cost)
    opti.subject_to(Z[:, 0] == [*START, 0.0, 0.0])
    opti.subject_to(Z[:, N] == [*END, 0.0, 0.0])
    opti.subject_to(opti.bounded(-U_MAX, U, U_MAX))
    for k in range(N + 1):
        opti.set_initial(Z[0, k], END[0] * k / N)
        opti.set_initial(Z[1, k], END[1] * k / N)
    opti.solver("ipopt", {"print_time": False}, {"print_level": 0, "tol": 1e-10})
    start = time.process_time()
    try:
        solution = opti.solve()
        ok = True
        value = float(solution.value(cost))
    except RuntimeError:
        ok, value = False, float(opti.debug.value(cost))
    return value, time.process_time() - start, ok


def main() -> int:
    reference, _, _ = galerkin(3, 320)
    print(f"reference cost (Galerkin(3), N = 320): {reference:.12f}")
    try:
        import casadi
    except ImportError:
        casadi = None
        print("casadi is not installed (pip install -e '.[bench]'): galerkin_vi only")
    runs = [(f"galerkin_vi Galerkin({d})", lambda N, d=d: galerkin(d, N)) for d in (2, 3)]
    if casadi is not None:
        runs += [("galerkin_vi Galerkin(3), IPOPT", lambda N: galerkin(3, N, "ipopt"))]
        runs += [(f"CasADi {casadi.__version__} + IPOPT, {s}",
                  lambda N, s=s: casadi_collocation(s, N))
                 for s in ("trapezoidal", "Hermite-Simpson")]  # fmt: skip
    ladder = (10, 20, 40, 80, 160)
    print(f"{'':40s} {'N':>4s} {'cost':>16s} {'error':>9s} {'CPU s':>7s}")
    for name, solve in runs:
        errors = []
        for N in ladder:
            cost, seconds, ok = solve(N)
            errors.append(abs(cost - reference))
            flag = "" if ok else "  (not converged)"
            print(f"{name:40s} {N:4d} {cost:16.12f} {errors[-1]:9.1e} {seconds:7.3f}{flag}")
        slopes = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
        print(f"{'':40s} slopes of the cost error: {np.array2string(slopes, precision=2)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
