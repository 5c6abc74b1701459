"""Shooting with exact gradients: the initial velocity that sends a double pendulum to a target.

The double pendulum (unit masses and lengths, g = 9.81),
``L = v1**2 + v2**2/2 + v1 v2 cos(q1 - q2) + 2 g cos q1 + g cos q2``, starts at
rest angles ``q0 = (0.5, 0)``. We look for the initial angular velocities
``v0`` such that the angles at ``T = 1.5`` s hit the target ``(0, -1)``, by
minimising the terminal loss

    Lambda(v0) = |q(T; v0) - target|^2 / 2

with ``scipy.optimize.minimize`` (BFGS). Each evaluation is one call of
:func:`galerkin_vi.gradient`: a forward run and the discrete adjoint's reverse
pass, which give the loss and its exact gradient with respect to ``v0`` (the
gradient of the discrete flow, not of a finite-difference approximation).

The script checks that gradient against central differences at the initial
guess, prints the iterations (loss and miss distance), the final miss distance
and the number of gradient evaluations, and draws the second bob's path before
and after, with the target, to ``gradient_shooting.png`` in ``--output`` (when
matplotlib is installed).

Run::

    python examples/gradient_shooting.py [--t-final 1.5] [--h 0.01] [--output DIR]
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import sympy as sp
from scipy.optimize import minimize

import galerkin_vi as gvi

PLOT_NAME = "gradient_shooting.png"
Q0 = np.array([0.5, 0.0])
TARGET = np.array([0.0, -1.0])


def double_pendulum() -> tuple[gvi.LagrangianSystem, tuple[sp.Symbol, sp.Symbol]]:
    """The model and its angle symbols (q1, q2)."""
    q1, q2, v1, v2, g = sp.symbols("q1 q2 v1 v2 g")
    L = v1**2 + v2**2 / 2 + v1 * v2 * sp.cos(q1 - q2) + 2 * g * sp.cos(q1) + g * sp.cos(q2)
    return gvi.LagrangianSystem(L, [q1, q2], [v1, v2], params={g: 9.81}), (q1, q2)


class Shooting:
    """The loss and its gradient in v0, counting the gradient evaluations."""

    def __init__(self, integrator: gvi.Integrator, angles, target, h: float, n_steps: int):
        q1, q2 = angles
        self.integrator, self.h, self.n_steps, self.target = integrator, h, n_steps, target
        self.loss = gvi.Loss(terminal=((q1 - target[0]) ** 2 + (q2 - target[1]) ** 2) / 2)
        self.evaluations = 0
        self.last: dict[bytes, gvi.Gradient] = {}

    def __call__(self, v0: np.ndarray) -> tuple[float, np.ndarray]:
        """Lambda(v0) and d Lambda / d v0 by the discrete adjoint."""
        self.evaluations += 1
        grad = gvi.gradient(self.integrator, self.loss, Q0, v0, h=self.h,
                            n_steps=self.n_steps, wrt=("v0",))  # fmt: skip
        if not grad.success:
            raise RuntimeError(grad.message)
        self.last = {np.asarray(v0, dtype=float).tobytes(): grad}
        return grad.value, grad.v0

    def final_angles(self, v0: np.ndarray) -> np.ndarray:
        return self.run(v0).q[-1]

    def run(self, v0: np.ndarray) -> gvi.Trajectory:
        return self.integrator.integrate(Q0, v0=v0, h=self.h, n_steps=self.n_steps)

    def value(self, v0: np.ndarray) -> float:
        return 0.5 * float(np.sum((self.final_angles(v0) - self.target) ** 2))


def check_against_differences(shooting: Shooting, v0: np.ndarray, eps: float = 1e-6) -> float:
    """The largest relative difference between the adjoint gradient and central differences."""
    _, exact = shooting(v0)
    columns = [
        (shooting.value(v0 + eps * e) - shooting.value(v0 - eps * e)) / (2 * eps)
        for e in np.eye(v0.size)
    ]
    difference = np.abs(exact - np.array(columns)).max() / np.abs(exact).max()
    print(f"gradient at the guess: adjoint {np.array2string(exact, precision=8)}, "
          f"central differences {np.array2string(np.array(columns), precision=8)}, "
          f"relative difference {difference:.1e}")  # fmt: skip
    return difference


def solve(shooting: Shooting, v_guess: np.ndarray):
    """BFGS on Lambda with the exact gradient; prints one line per iteration."""
    print(f"{'iter':>4}{'loss':>14}{'miss':>12}   v0")

    def report(v0):
        report.k += 1
        grad = shooting.last.get(np.asarray(v0, dtype=float).tobytes())
        value = grad.value if grad is not None else shooting.value(v0)
        print(f"{report.k:4d}{value:14.3e}{np.sqrt(2 * value):12.3e}   "
              f"{np.array2string(v0, precision=6)}")  # fmt: skip

    report.k = 0
    return minimize(shooting, v_guess, jac=True, method="BFGS", callback=report,
                    options={"gtol": 1e-11, "maxiter": 100})  # fmt: skip


def plot(path: Path, before: gvi.Trajectory, after: gvi.Trajectory, target) -> None:
    """The second bob's path for the guess and the solution, the arms at T, the target."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: skipping the plot ({path} not written)")
        return

    def joints(q):
        elbow = np.c_[np.sin(q[..., 0]), -np.cos(q[..., 0])]
        return elbow, elbow + np.c_[np.sin(q[..., 1]), -np.cos(q[..., 1])]

    fig, ax = plt.subplots(figsize=(5.5, 5.5))
    for traj, colour, label in ((before, "0.6", "initial guess"), (after, "C0", "solution")):
        _, tip = joints(traj.q)
        ax.plot(tip[:, 0], tip[:, 1], color=colour, label=f"{label}: second bob")
        elbow, end = joints(traj.q[-1:])
        ax.plot([0, elbow[0, 0], end[0, 0]], [0, elbow[0, 1], end[0, 1]], "o-", color=colour)
    elbow, end = joints(np.asarray(target)[None])
    ax.plot([0, elbow[0, 0], end[0, 0]], [0, elbow[0, 1], end[0, 1]], "x--", color="C3",
            ms=10, label="target at T")  # fmt: skip
    _, start = joints(Q0[None])
    ax.plot(*start[0], "ks", label="start")
    ax.set_aspect("equal")
    ax.set_xlabel("x")
    ax.set_ylabel("y")
    ax.legend(loc="upper left", fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-final", type=float, default=1.5, help="time of the target (s)")
    parser.add_argument("--h", type=float, default=0.01, help="step size")
    parser.add_argument("--degree", type=int, default=3, help="Galerkin degree (order 2s)")
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)
    system, angles = double_pendulum()
    integrator = gvi.Integrator(system, gvi.Galerkin(args.degree))
    n_steps = int(round(args.t_final / args.h))
    shooting = Shooting(integrator, angles, TARGET, args.t_final / n_steps, n_steps)
    v_guess = np.zeros(2)
    check_against_differences(shooting, v_guess)
    shooting.evaluations = 0
    result = solve(shooting, v_guess)
    final = shooting.run(result.x)
    miss = float(np.linalg.norm(final.q[-1] - TARGET))
    print(f"{result.message} v0 = {np.array2string(result.x, precision=10)}")
    print(f"final miss distance |q(T) - target| = {miss:.2e} rad after {result.nit} iterations "
          f"and {shooting.evaluations} gradient evaluations")  # fmt: skip
    output = args.output or Path(tempfile.mkdtemp(prefix="gradient_shooting-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, shooting.run(v_guess), final, TARGET)
    return result, miss


if __name__ == "__main__":
    main()
