"""Constraints kept exactly: a variational integrator against DAE + Baumgarte stabilisation.

Two constrained systems in Cartesian coordinates (unit masses, lengths and
gravity ``gamma = 1``):

* the planar pendulum, ``q = (x, y)``,
  ``L = (vx**2 + vy**2)/2 - gamma*y``, one constraint ``g = (x**2 + y**2 - 1)/2``,
  released from rest at 2 rad from the downward vertical;
* the planar double pendulum, ``q = (x1, y1, x2, y2)``,
  ``L = (|v1|**2 + |v2|**2)/2 - gamma*(y1 + y2)``, two constraints
  ``g1 = (x1**2 + y1**2 - 1)/2``, ``g2 = ((x2 - x1)**2 + (y2 - y1)**2 - 1)/2``,
  from the absolute angles ``(1.0, 0.5)`` and angular velocities ``(0.0, 0.3)``.

The DAE side
------------
With the mass matrix ``M = d2L/dv2``, the forces ``f = dL/dq - (d2L/dv dq) v``
and the constraint Jacobian ``G = dg/dq`` (``m x n``), the equations of motion
are the index-3 DAE

    q' = v,    M v' = f - G^T lambda,    g(q) = 0.

Differentiating the constraint along a solution gives the hidden constraints

    d/dt g = G v = 0,    d2/dt2 g = G a + G' v = 0,    a = v',

where ``G' v = (d(G v)/dq) v`` (row ``j``: ``v^T Hess(g_j) v``). Replacing
``g = 0`` by ``g'' = 0`` is the index reduction to index 1: ``(a, lambda)`` are
then the solution of a linear system at every state. Baumgarte [1] replaces
``g'' = 0`` by the damped equation ``g'' + 2 alpha g' + beta**2 g = 0``:

    [ M   G^T ] [   a    ]   [ f                                 ]
    [ G    0  ] [ lambda ] = [ -G' v - 2 alpha G v - beta**2 g   ].

By the Schur complement ``S = G M^-1 G^T`` (``m x m``):

    lambda = S^-1 (G M^-1 f + G' v + 2 alpha G v + beta**2 g),
    a      = M^-1 (f - G^T lambda).

The script forms these expressions symbolically (SymPy, common subexpressions
eliminated) and integrates ``y' = (v, a)`` with scipy's ``solve_ivp`` (RK45 and
DOP853, ``atol = rtol``, at two tolerances each on the pendulum and the looser
one on the double pendulum). The local errors ``delta`` drive the constraint
residual ``e = g(q(t))`` through ``e'' + 2 alpha e' + beta**2 e = delta``. With
``alpha = beta = 0`` (plain index reduction) they are integrated twice, so
``|g|`` drifts, growing like ``t**2``; with ``alpha, beta > 0`` the residual is
damped and stays at the level of the tolerance, at the price of more RHS
evaluations (the step-size control also has to follow the fast damped modes).
Neither variant conserves the energy: an explicit Runge-Kutta method is not
symplectic, so ``|E - E0|`` grows linearly in time.

The VI side
-----------
``galerkin_vi`` with Lobatto quadrature (collocated), ``s = 1`` (the RATTLE-like
order-2 method) and ``s = 2`` (order 4). They impose ``g(q) = 0`` at every
control point with multipliers and project the momentum onto the hidden
constraint ``G v = 0`` at the end of each step, so both stay at round-off level
for all time, and, being symplectic, they keep the energy error bounded.

Output
------
A table (method, steps, RHS evaluations for the DAE or Newton iterations for
the VI, wall time, max ``|g|``, max ``|G v|``, max ``|E - E0|``) per system, and
``constrained_dae.png`` in ``--output``: the maximum of ``|g|`` and of
``|E - E0|`` over log-spaced time windows, on log-log axes. The VI timings are
of compiled kernels (loaded from the cache before timing) and the DAE timings
of a Python RHS, so compare the steps and evaluations as well.

References
----------
[1] J. Baumgarte, Stabilization of constraints and integrals of motion in
    dynamical systems, Comput. Methods Appl. Mech. Engrg. 1 (1972) 1-16.

Run ``python examples/constrained_dae.py --help`` for the options.
"""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import matplotlib
import numpy as np
import sympy as sp
from scipy.integrate import solve_ivp

import galerkin_vi as gvi

GRAVITY = 1
ALPHA = 5.0
BETA = 5.0
# (solve_ivp method, rtol = atol): a loose and a tight tolerance per method on the
# pendulum; the loose ones only on the double pendulum, to stay within ~20 s
PENDULUM_SOLVERS = (("RK45", 1e-5), ("RK45", 1e-7), ("DOP853", 1e-8), ("DOP853", 1e-11))
DOUBLE_PENDULUM_SOLVERS = (("RK45", 1e-5), ("DOP853", 1e-8))
# (degree s, step size): less wall time than any Baumgarte run
VI_METHODS = [(1, 0.01), (2, 0.05)]
PLOT_NAME = "constrained_dae.png"


@dataclass(frozen=True)
class Model:
    """A constrained system, its initial data and the DAE right-hand side."""

    name: str
    system: gvi.LagrangianSystem
    q0: np.ndarray
    v0: np.ndarray
    # (q..., v..., alpha, beta) -> [v..., a...]
    dae_rhs: Callable[..., list[float]]
    dae_solvers: tuple[tuple[str, float], ...]


@dataclass(frozen=True)
class Run:
    """Diagnostics of one run at its saved (VI) or accepted (DAE) points."""

    model: str
    label: str
    kind: str  # "VI", "index-1" or "Baumgarte"
    steps: int
    evaluations: int  # RHS evaluations (DAE) or Newton iterations (VI)
    seconds: float
    t: np.ndarray
    constraint: np.ndarray  # max_j |g_j(q)|
    hidden: np.ndarray  # max_j |(G v)_j|
    energy_error: np.ndarray  # |E - E0|

    @property
    def max_constraint(self) -> float:
        """Largest constraint residual of the run."""
        return float(self.constraint.max())

    @property
    def max_hidden(self) -> float:
        """Largest hidden-constraint residual of the run."""
        return float(self.hidden.max())

    @property
    def max_energy_error(self) -> float:
        """Largest energy error of the run."""
        return float(self.energy_error.max())


def baumgarte_rhs(
    L: sp.Expr, q: Sequence[sp.Symbol], v: Sequence[sp.Symbol], constraints: Sequence[sp.Expr]
) -> Callable[..., list[float]]:
    """The index-1 / Baumgarte right-hand side ``(q, v, alpha, beta) -> (v, a)``.

    ``lambda = S^-1 (G M^-1 f + G' v + 2 alpha G v + beta**2 g)`` and
    ``a = M^-1 (f - G^T lambda)`` with ``S = G M^-1 G^T`` (module docstring).
    """
    alpha, beta = sp.symbols("alpha beta")
    vel = sp.Matrix(v)
    mass = sp.hessian(L, v)
    force = sp.Matrix([L.diff(a) for a in q]) - sp.Matrix([L.diff(b) for b in v]).jacobian(q) * vel
    g = sp.Matrix(constraints)
    jac = g.jacobian(q)
    curvature = (jac * vel).jacobian(q) * vel  # G' v
    mass_inv = mass.inv()
    schur = jac * mass_inv * jac.T
    lam = schur.LUsolve(jac * mass_inv * force + curvature + 2 * alpha * jac * vel + beta**2 * g)
    acceleration = mass_inv * (force - jac.T * lam)
    return sp.lambdify([*q, *v, alpha, beta], [*vel, *acceleration], modules="numpy", cse=True)


def pendulum() -> Model:
    """The planar pendulum in Cartesian coordinates, released from rest at 2 rad."""
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx**2 + vy**2) / 2 - GRAVITY * y
    constraints = [(x**2 + y**2 - 1) / 2]
    angle = 2.0
    return Model(
        name="pendulum",
        system=gvi.LagrangianSystem(L, q=[x, y], v=[vx, vy], constraints=constraints),
        q0=np.array([np.sin(angle), -np.cos(angle)]),
        v0=np.zeros(2),
        dae_rhs=baumgarte_rhs(L, [x, y], [vx, vy], constraints),
        dae_solvers=PENDULUM_SOLVERS,
    )


def double_pendulum() -> Model:
    """The planar double pendulum in Cartesian coordinates, two length constraints."""
    x1, y1, x2, y2, vx1, vy1, vx2, vy2 = sp.symbols("x1 y1 x2 y2 vx1 vy1 vx2 vy2")
    q, v = [x1, y1, x2, y2], [vx1, vy1, vx2, vy2]
    L = (vx1**2 + vy1**2 + vx2**2 + vy2**2) / 2 - GRAVITY * (y1 + y2)
    constraints = [(x1**2 + y1**2 - 1) / 2, ((x2 - x1) ** 2 + (y2 - y1) ** 2 - 1) / 2]
    (th1, th2), (w1, w2) = (1.0, 0.5), (0.0, 0.3)  # examples/double_pendulum.py's start
    q0 = np.array(
        [np.sin(th1), -np.cos(th1), np.sin(th1) + np.sin(th2), -np.cos(th1) - np.cos(th2)]
    )
    v0 = np.array(
        [
            np.cos(th1) * w1,
            np.sin(th1) * w1,
            np.cos(th1) * w1 + np.cos(th2) * w2,
            np.sin(th1) * w1 + np.sin(th2) * w2,
        ]
    )
    return Model(
        name="double pendulum",
        system=gvi.LagrangianSystem(L, q=q, v=v, constraints=constraints),
        q0=q0,
        v0=v0,
        dae_rhs=baumgarte_rhs(L, q, v, constraints),
        dae_solvers=DOUBLE_PENDULUM_SOLVERS,
    )


def diagnostics(
    system: gvi.LagrangianSystem, q: np.ndarray, v: np.ndarray, energy0: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``max_j |g_j|``, ``max_j |(G v)_j|`` and ``|E - E0|`` at states ``(q, v)``."""
    g = system.constraint_values(q)
    hidden = np.einsum("kja,ka->kj", system.constraint_jacobian(q), v)
    energy = system.hamiltonian(q, system.legendre(q, v))
    return (
        np.max(np.abs(g), axis=-1),
        np.max(np.abs(hidden), axis=-1),
        np.abs(energy - energy0),
    )


def run_dae(
    model: Model, method: str, rtol: float, alpha: float, beta: float, t_final: float
) -> Run:
    """Integrate the index-1 (``alpha = beta = 0``) or Baumgarte DAE with ``solve_ivp``."""
    rhs = model.dae_rhs

    def fun(_t: float, state: np.ndarray) -> list[float]:
        # Python floats: scalar arithmetic on them is faster than on numpy scalars
        return rhs(*state.tolist(), alpha, beta)

    start = time.perf_counter()
    y0 = np.concatenate([model.q0, model.v0])
    sol = solve_ivp(fun, (0.0, t_final), y0, method=method, rtol=rtol, atol=rtol)
    seconds = time.perf_counter() - start
    if not sol.success:
        raise RuntimeError(f"{model.name}, {method} rtol {rtol:g}: {sol.message}")
    n = model.system.n
    q, v = sol.y[:n].T, sol.y[n:].T
    energy0 = float(model.system.hamiltonian(model.q0, model.system.legendre(model.q0, model.v0)))
    kind = "Baumgarte" if alpha or beta else "index-1"
    return Run(
        model.name,
        f"{method} rtol {rtol:.0e} {kind}",
        kind,
        len(sol.t) - 1,
        sol.nfev,
        seconds,
        sol.t,
        *diagnostics(model.system, q, v, energy0),
    )


def run_vi(model: Model, degree: int, h: float, t_final: float) -> Run:
    """Integrate with the collocated Lobatto Galerkin VI of degree ``degree``."""
    integrator = gvi.Integrator(model.system, gvi.Galerkin(degree))
    integrator.integrate(model.q0, v0=model.v0, h=h, n_steps=1)  # compile or load the kernel
    n_steps = max(1, round(t_final / h))
    start = time.perf_counter()
    traj = integrator.integrate(model.q0, v0=model.v0, h=h, n_steps=n_steps)
    seconds = time.perf_counter() - start
    energy = traj.energy()
    return Run(
        model.name,
        f"VI s={degree} Lobatto({degree + 1}) h={h:g}",
        "VI",
        traj.n_steps,
        traj.total_newton_iterations,
        seconds,
        traj.t,
        traj.constraint_residual(),
        traj.hidden_constraint_residual(),
        np.abs(energy - energy[0]),
    )


def print_table(runs: Sequence[Run]) -> None:
    """One line per run: cost and the largest residuals."""
    print(
        f"{'method':>34} {'steps':>7} {'evals':>8} {'time [s]':>8} "
        f"{'max|g|':>9} {'max|Gv|':>9} {'max|E-E0|':>9}"
    )
    for r in runs:
        print(
            f"{r.label:>34} {r.steps:7d} {r.evaluations:8d} {r.seconds:8.3f} "
            f"{r.max_constraint:9.1e} {r.max_hidden:9.1e} {r.max_energy_error:9.1e}"
        )


def window_maxima(
    t: np.ndarray, values: np.ndarray, edges: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Maximum of ``values`` over each window ``(edges[i], edges[i+1]]``, at its right end."""
    index = np.searchsorted(edges, t, side="left") - 1
    keep = (index >= 0) & (index < len(edges) - 1)
    out = np.zeros(len(edges) - 1)
    np.maximum.at(out, index[keep], values[keep])
    # empty windows (a DAE step longer than the window) and exact zeros are left out
    filled = out > 0
    return edges[1:][filled], out[filled]


def plot(runs: Sequence[Run], models: Sequence[str], t_final: float, path: Path) -> None:
    """Constraint drift and energy error against time, one row per model."""
    matplotlib.use("Agg")  # no display needed
    import matplotlib.pyplot as plt

    edges = np.geomspace(t_final / 1e3, t_final, 121)
    colours = {
        f"{method} rtol {rtol:.0e}": f"C{i}" for i, (method, rtol) in enumerate(PENDULUM_SOLVERS)
    }
    fig, axes = plt.subplots(len(models), 2, figsize=(12, 4.2 * len(models)), squeeze=False)
    for row, name in zip(axes, models, strict=True):
        for r in (r for r in runs if r.model == name):
            if r.kind == "VI":
                style = {"color": "k" if "s=1" in r.label else "0.55", "lw": 2.0}
            else:
                solver = r.label.rsplit(" ", 1)[0]
                style = {"color": colours[solver], "lw": 1.2}
                style["ls"] = "--" if r.kind == "index-1" else "-"
            for ax, values in zip(row, (r.constraint, r.energy_error), strict=True):
                ax.loglog(*window_maxima(r.t, values, edges), label=r.label, **style)
        row[0].set_ylabel(f"{name}: max |g| per window")
        row[1].set_ylabel(f"{name}: max |E - E0| per window")
        for ax in row:
            ax.set_xlabel("t")
            ax.grid(True, which="major", alpha=0.3)
    axes[0, 0].set_title(f"constraint drift (dashed: alpha = beta = 0; solid: {ALPHA:g}, {BETA:g})")
    axes[0, 1].set_title("energy error")
    # the pendulum row has every DAE solver: its legend serves both rows
    fig.legend(*axes[0, 0].get_legend_handles_labels(), loc="lower center", ncol=5, fontsize=8)
    # fixed margins: tight_layout would render every log-axis label once more
    bottom = 0.6 / fig.get_figheight()
    fig.subplots_adjust(left=0.08, right=0.98, bottom=0.07 + bottom, top=0.95, hspace=0.25)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv: Sequence[str] | None = None) -> list[Run]:
    """Run every method on both systems, print the tables, save the plot; return the runs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-final", type=float, default=1000.0, help="length of the time span")
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    parser.add_argument("--alpha", type=float, default=ALPHA, help="Baumgarte damping alpha")
    parser.add_argument("--beta", type=float, default=BETA, help="Baumgarte stiffness beta")
    args = parser.parse_args(argv)
    output = args.output or Path(tempfile.mkdtemp(prefix="constrained_dae-"))
    output.mkdir(parents=True, exist_ok=True)

    models = [pendulum(), double_pendulum()]
    runs: list[Run] = []
    for model in models:
        print(
            f"\n{model.name}: n = {model.system.n}, m = {model.system.m} constraints, "
            f"t in [0, {args.t_final:g}], Baumgarte alpha = {args.alpha:g}, beta = {args.beta:g}"
        )
        model_runs = [run_vi(model, degree, h, args.t_final) for degree, h in VI_METHODS]
        for method, rtol in model.dae_solvers:
            model_runs.append(run_dae(model, method, rtol, 0.0, 0.0, args.t_final))
            model_runs.append(run_dae(model, method, rtol, args.alpha, args.beta, args.t_final))
        print_table(model_runs)
        runs += model_runs
    print("evals: RHS evaluations (DAE) or Newton iterations (VI); |Gv|: hidden constraint")
    path = output / PLOT_NAME
    plot(runs, [m.name for m in models], args.t_final, path)
    print(f"plot written to {path}")
    return runs


if __name__ == "__main__":
    main()
