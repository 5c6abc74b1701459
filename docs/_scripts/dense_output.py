"""Measured orders of the dense output, and the figure of the how-to "dense output".

For each method, Gauss s = 1..4 (``Galerkin(s, gauss_legendre(s))``) and
Lobatto s = 2..4 (``Galerkin(s, gauss_lobatto(s + 1))``), and two problems:

* the harmonic oscillator L = v²/2 - q²/2 from (1, 0), exact q = cos t;
* the pendulum L = v²/2 + cos q from q0 = 1.5, v0 = 0, against DOP853 at
  scipy's tightest tolerance (rtol 2.3e-14, atol 1e-16; its dense output);

the largest error of ``traj.sol(t)`` and ``traj.sol.velocity(t)`` at
t = t_k + theta h, theta = 1/18, 3/18, ..., 17/18, in every step of a run over
[0, 6], for three step sizes. The
order is the least-squares slope of log error against log h. On the oscillator
the script also evaluates the step's own Galerkin polynomial at the same points
(control points from the NumPy backend's step solver,
``galerkin_vi.reference.numpy.solve_step``, started from each saved (q_k, p_k)),
the interpolant that is *not* offered.

Prints the table and draws ``docs/_static/dense_output.png``: a coarse run of
Gauss s = 2 (order 4, h = 0.75) on the oscillator, its dense output and step
polynomials against cos t, the errors of both in positions and velocities along
the run, and the largest errors against h for Gauss s = 3 (order 6).

Run from the repository root::

    python docs/_scripts/dense_output.py
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import sympy as sp
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

import galerkin_vi as gvi
from galerkin_vi.method.basis import LagrangeBasis
from galerkin_vi.reference.numpy import solve_step
from galerkin_vi.run.dense import stencil_nodes

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "dense_output.png"
SPAN = 6.0
#: where in each step the error is measured: 9 points, off the nodes (one point per step
#: gives a ragged maximum: slopes from 3.8 to 9 between successive h on the pendulum)
THETA = (np.arange(1, 10) - 0.5) / 9

q, v = sp.symbols("q v")
OSCILLATOR = gvi.LagrangianSystem(v**2 / 2 - q**2 / 2, [q], [v])
PENDULUM = gvi.LagrangianSystem(v**2 / 2 + sp.cos(q), [q], [v])
#: (label, method, step counts over SPAN on the oscillator, on the pendulum): errors
#: above round-off; on the pendulum s = 3, 4 need finer steps to leave the pre-asymptotic
#: range (slopes between 4 and 12 from one doubling to the next at 16-32 steps)
METHODS = (
    ("Gauss s=1", gvi.Galerkin(1, gvi.gauss_legendre(1)), (48, 96, 192), (48, 96, 192)),
    ("Gauss s=2", gvi.Galerkin(2, gvi.gauss_legendre(2)), (24, 48, 96), (24, 48, 96)),
    ("Gauss s=3", gvi.Galerkin(3, gvi.gauss_legendre(3)), (16, 32, 64), (48, 64, 96)),
    ("Gauss s=4", gvi.Galerkin(4, gvi.gauss_legendre(4)), (12, 18, 24), (32, 48, 64)),
    ("Lobatto s=2", gvi.Galerkin(2, gvi.gauss_lobatto(3)), (24, 48, 96), (24, 48, 96)),
    ("Lobatto s=3", gvi.Galerkin(3, gvi.gauss_lobatto(4)), (16, 32, 64), (48, 64, 96)),
    ("Lobatto s=4", gvi.Galerkin(4, gvi.gauss_lobatto(5)), (12, 18, 24), (32, 48, 64)),
)


def pendulum_reference():
    """(q, v) of the pendulum at any t in [0, SPAN], from DOP853's dense output."""

    def rhs(t, y):
        return [y[1], -np.sin(y[0])]

    sol = solve_ivp(
        rhs, (0.0, SPAN), [1.5, 0.0], method="DOP853", rtol=2.3e-14, atol=1e-16, dense_output=True
    )
    return lambda t: (sol.sol(t)[0], sol.sol(t)[1])


def oscillator_exact(t):
    return np.cos(t), -np.sin(t)


def step_polynomial(integ: gvi.Integrator, traj: gvi.Trajectory, theta: NDArray):
    """The step's own Galerkin polynomial and its derivative at t_k + theta h, shape (steps, m)."""
    tables = integ.method.tables
    basis = LagrangeBasis(tables.d)
    phi, dphi = basis.values(theta), basis.derivatives(theta)
    prm = integ.system.parameter_vector(None)
    qs, vs = [], []
    for k in range(len(traj) - 1):
        h = traj.t[k + 1] - traj.t[k]
        guess = tables.d[:, None] * (traj.q[k + 1] - traj.q[k])  # the chord, as increments
        C, _ = solve_step(
            integ.system, tables, traj.t[k], h, traj.q[k], traj.p[k], guess, prm, 1e-15, 50
        )
        # the solver's step lands where the run's did (same equations, same start)
        assert np.allclose(traj.q[k] + C[-1], traj.q[k + 1], rtol=0, atol=1e-12)
        qs.append(traj.q[k] + phi @ C)
        vs.append(dphi @ C / h)
    return np.array(qs)[:, :, 0], np.array(vs)[:, :, 0]


def slope(steps: Sequence[float], errors: Sequence[float]) -> float:
    return float(np.polyfit(np.log(steps), np.log(errors), 1)[0])


def measure(system, q0, v0, exact, method, counts, with_polynomial=False) -> dict:
    """Errors at t_k + THETA h and their slopes: dense output (and the step polynomial)."""
    integ = gvi.Integrator(system, method)
    errors: dict[str, list] = {"q": [], "v": [], "poly q": [], "poly v": []}
    steps = []
    for n in counts:
        h = SPAN / n
        traj = integ.integrate([q0], [v0], h=h, n_steps=n, dense_output=True)
        t = (traj.t[:-1, None] + THETA[None, :] * h).ravel()
        q_true, v_true = exact(t)
        errors["q"].append(np.max(np.abs(traj.sol(t)[:, 0] - q_true)))
        errors["v"].append(np.max(np.abs(traj.sol.velocity(t)[:, 0] - v_true)))
        if with_polynomial:
            q_poly, v_poly = step_polynomial(integ, traj, THETA)
            errors["poly q"].append(np.max(np.abs(q_poly.ravel() - q_true)))
            errors["poly v"].append(np.max(np.abs(v_poly.ravel() - v_true)))
        steps.append(h)
    return {key: (slope(steps, errs), errs[-1]) for key, errs in errors.items() if errs} | {
        "order": method.order,
        "stencil": stencil_nodes(method.order),
    }


def table() -> list[dict]:
    """Measure every method; print the table of slopes (and the finest errors)."""
    reference = pendulum_reference()
    rows = []
    for label, method, osc_counts, pen_counts in METHODS:
        osc = measure(OSCILLATOR, 1.0, 0.0, oscillator_exact, method, osc_counts, True)
        pen = measure(PENDULUM, 1.5, 0.0, reference, method, pen_counts)
        rows.append({"method": label, "oscillator": osc, "pendulum": pen})
    head = ("method", "order", "N", "osc. q", "osc. v", "pend. q", "pend. v", "poly q", "poly v")
    print("measured orders between the nodes, least-squares slopes over 3 step sizes;")
    print("N: nodes of the Hermite stencil; poly: the step's own polynomial (oscillator)\n")
    print("| " + " | ".join(head) + " |")
    print("|" + "---|" * len(head))
    for r in rows:
        osc, pen = r["oscillator"], r["pendulum"]
        cells = [r["method"], str(osc["order"]), str(osc["stencil"])]
        cells += [f"{osc['q'][0]:.2f}", f"{osc['v'][0]:.2f}", f"{pen['q'][0]:.2f}"]
        cells += [f"{pen['v'][0]:.2f}", f"{osc['poly q'][0]:.2f}", f"{osc['poly v'][0]:.2f}"]
        print("| " + " | ".join(cells) + " |")
    print("\nthe errors at the smallest h (dense q, dense v; step polynomial q, v, oscillator):")
    for r in rows:
        osc, pen = r["oscillator"], r["pendulum"]
        print(
            f"  {r['method']:<12} oscillator {osc['q'][1]:.1e}, {osc['v'][1]:.1e}; "
            f"pendulum {pen['q'][1]:.1e}, {pen['v'][1]:.1e}; "
            f"polynomial {osc['poly q'][1]:.1e}, {osc['poly v'][1]:.1e}"
        )
    return rows


def convergence(method: gvi.Galerkin, counts: Sequence[int]) -> dict[str, list]:
    """Largest errors between the nodes on the oscillator against h: dense output, polynomial."""
    integ = gvi.Integrator(OSCILLATOR, method)
    out: dict[str, list] = {"h": [], "dense q": [], "dense v": [], "poly q": [], "poly v": []}
    for n in counts:
        h = SPAN / n
        traj = integ.integrate([1.0], [0.0], h=h, n_steps=n, dense_output=True)
        t = (traj.t[:-1, None] + THETA[None, :] * h).ravel()
        q_poly, v_poly = (x.ravel() for x in step_polynomial(integ, traj, THETA))
        out["h"].append(h)
        out["dense q"].append(np.max(np.abs(traj.sol(t)[:, 0] - np.cos(t))))
        out["dense v"].append(np.max(np.abs(traj.sol.velocity(t)[:, 0] + np.sin(t))))
        out["poly q"].append(np.max(np.abs(q_poly - np.cos(t))))
        out["poly v"].append(np.max(np.abs(v_poly + np.sin(t))))
    return out


def plot(path: Path, h: float = 0.75) -> None:
    """A coarse Gauss s = 2 run on the oscillator, and errors against h for Gauss s = 3."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    integ = gvi.Integrator(OSCILLATOR, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    n = round(SPAN / h)
    traj = integ.integrate([1.0], [0.0], h=h, n_steps=n, dense_output=True)
    theta = np.linspace(0.0, 1.0, 41)[1:-1]
    t = (traj.t[:-1, None] + theta[None, :] * h).ravel()  # step by step: increasing
    q_poly, v_poly = (x.ravel() for x in step_polynomial(integ, traj, theta))
    q_dense, v_dense = traj.sol(t)[:, 0], traj.sol.velocity(t)[:, 0]

    fig = plt.figure(figsize=(10, 7.2))
    grid = fig.add_gridspec(2, 2)
    ax = fig.add_subplot(grid[0, :])
    ax_e, ax_h = fig.add_subplot(grid[1, 0]), fig.add_subplot(grid[1, 1])
    fine = np.linspace(0.0, SPAN, 600)
    ax.plot(fine, np.cos(fine), color="0.75", lw=4, label="exact: cos t")
    ax.plot(t, q_dense, lw=1.2, label="traj.sol(t)")
    ax.plot(t, q_poly, "--", lw=1.0, label="step polynomial")
    ax.plot(traj.t, traj.q[:, 0], "ko", ms=4, label="saved states")
    ax.set_xlabel("t")
    ax.set_ylabel("q")
    ax.legend(loc="lower left", fontsize="small", ncol=2)
    ax.set_title(f"oscillator, Gauss s = 2 (order 4), h = {h}: {n} steps")
    for values, exact, style, label in (
        (q_dense, np.cos(t), "-", "dense q"),
        (v_dense, -np.sin(t), "-", "dense v"),
        (q_poly, np.cos(t), "--", "polynomial q"),
        (v_poly, -np.sin(t), "--", "polynomial v"),
    ):
        ax_e.semilogy(t, np.abs(values - exact), style, lw=1.0, label=label)
    ax_e.set_xlabel("t")
    ax_e.set_ylabel("|error|")
    ax_e.set_title(f"errors of the run above (h = {h})")
    ax_e.legend(loc="lower right", fontsize="small", ncol=2)
    errors = convergence(gvi.Galerkin(3, gvi.gauss_legendre(3)), (8, 12, 16, 24, 32, 48, 64))
    for key, style in (("dense q", "o-"), ("dense v", "s-"), ("poly q", "o--"), ("poly v", "s--")):
        ax_h.loglog(errors["h"], errors[key], style, ms=4, label=key.replace("poly", "polynomial"))
    ax_h.xaxis.set_minor_formatter(matplotlib.ticker.NullFormatter())
    ax_h.set_xlabel("h")
    ax_h.set_ylabel("largest |error| between the nodes")
    ax_h.set_title("Gauss s = 3 (order 6): slopes 6, 6 against 4, 3")
    ax_h.legend(loc="lower right", fontsize="small")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> list[dict]:
    """Print the table of measured orders, draw the figure; return the table's rows."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=OUTPUT, help="the PNG to write")
    args = parser.parse_args(argv)
    rows = table()
    plot(args.output)
    print(f"\nplot written to {args.output}")
    return rows


if __name__ == "__main__":
    main()
