"""A pendulum's boundary-value problem solved through its discrete action.

Find theta(t) with theta'' = -sin(theta), theta(0) = 0.3 and theta(3) = -1.2:
``gvi.solve_bvp`` makes the discrete action of the whole path stationary at
once (Newton with the exact Jacobian, condensed to a banded system in the
nodes), from the straight line between the ends. The reference is shooting:
DOP853 at rtol = atol = 1e-14 from the initial velocity that lands on
theta(3). The script prints the nodal error, the error of the dense output at
201 points, the discrete action and the Newton iterations for degrees 2, 3, 4
and a ladder of element counts, with the slopes of the nodal errors (the
methods' orders 4, 6, 8); ``--plot PATH`` draws the path and the errors.

Run::

    python examples/pendulum_bvp.py [--plot docs/_static/pendulum_bvp.png]
"""

from __future__ import annotations

import argparse

import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp
from scipy.optimize import brentq

import galerkin_vi as gvi

THETA_A, THETA_B, T = 0.3, -1.2, 3.0
LADDER = (6, 12, 24, 48)


def shooting_reference():
    """The reference solution as a dense callable theta(t), and its initial velocity."""

    def rhs(t, y):
        return [y[1], -np.sin(y[0])]

    def miss(v0):
        end = solve_ivp(rhs, (0, T), [THETA_A, v0], method="DOP853", rtol=1e-13, atol=1e-14)
        return end.y[0, -1] - THETA_B

    v0 = brentq(miss, -3.0, 0.5, xtol=1e-15)
    sol = solve_ivp(rhs, (0, T), [THETA_A, v0], method="DOP853", rtol=1e-13, atol=1e-14,
                    dense_output=True)  # fmt: skip
    return (lambda t: sol.sol(t)[0]), v0


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--plot", help="write the figure here (needs matplotlib)")
    args = parser.parse_args()
    th, w = sp.symbols("theta w")
    pendulum = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])
    exact, v0 = shooting_reference()
    x = np.linspace(0, T, 201)
    print(f"shooting reference: theta'(0) = {v0:.15f}")
    print(f"{'degree':>6s} {'N':>4s} {'nodes':>10s} {'dense':>10s} {'action':>19s} {'its':>4s}")
    errors = {}
    for degree in (2, 3, 4):
        method = gvi.Galerkin(degree)
        for N in LADDER:
            res = gvi.solve_bvp(pendulum, method, [THETA_A], [THETA_B], (0.0, T), N)
            node_error = np.abs(res.trajectory.q[:, 0] - exact(res.trajectory.t)).max()
            dense_error = np.abs(res.trajectory.sol(x)[:, 0] - exact(x)).max()
            errors.setdefault(degree, []).append(node_error)
            print(f"{degree:6d} {N:4d} {node_error:10.2e} {dense_error:10.2e} "
                  f"{res.action:19.15f} {res.iterations:4d}")  # fmt: skip
        slopes = np.log2(np.array(errors[degree][:-1]) / np.array(errors[degree][1:]))
        print(f"{'':6s} nodal slopes {np.array2string(slopes, precision=2)} "
              f"(order {method.order})")  # fmt: skip
    if args.plot:
        best = gvi.solve_bvp(pendulum, gvi.Galerkin(4), [THETA_A], [THETA_B], (0.0, T), 12)
        _plot(best, x, exact, errors, args.plot)


def _plot(res, x, exact, errors, path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 6))
    top.plot(x, THETA_A + (THETA_B - THETA_A) * x / T, color="0.6", ls=":", label="guess")
    top.plot(x, res.trajectory.sol(x)[:, 0], lw=1.5, label="solve_bvp, Galerkin(4), N = 12")
    top.plot(res.trajectory.t, res.trajectory.q[:, 0], "o", ms=4, color="C0", label="nodes")
    top.plot(x, exact(x), "k--", lw=0.8, label="shooting (DOP853)")
    top.set_xlabel("t")
    top.set_ylabel(r"$\theta$")
    top.set_title(r"pendulum, $\theta(0) = 0.3$, $\theta(3) = -1.2$: the stationary discrete path")
    top.legend(fontsize=8)
    h = T / np.array(LADDER)
    for degree, values in errors.items():
        bottom.loglog(h, values, "o-", label=f"Galerkin({degree}), order {2 * degree}")
    bottom.set_xlabel("h")
    bottom.set_ylabel("largest nodal error")
    bottom.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
