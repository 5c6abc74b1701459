"""Fit a damped pendulum's length and damping to noisy measurements of its angle.

The model (unit mass, g = 9.81): ``L = l**2 w**2 / 2 + g l cos(theta)`` with the
damping force ``-c w``. The "measurements" are the angle of a reference run
(degree 3, h = 1e-3, l = 0.75, c = 0.2, theta0 = 1.0, w0 = 0) at ``--n-obs``
random instants in [0, 6] s, plus Gaussian noise of ``--noise`` rad.

:func:`galerkin_vi.tangent.fit_parameters` fits ``l``, ``c`` and the initial
state ``(theta0, w0)`` with a degree-2 Galerkin integrator of step at most
``--h``, by least squares with the exact Jacobian of the discrete flow (the
tangent map and the parameter sensitivities). The observation times are not on
the step grid: each gap between them is integrated with its own equal steps.
The script prints the estimates with their standard errors against the truth,
and saves the data, the fitted trajectory and the residuals to
``fit_damped_pendulum.png`` in ``--output`` (when matplotlib is installed).
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.tangent import fit_parameters

PLOT_NAME = "fit_damped_pendulum.png"
TRUTH = {"l": 0.75, "c": 0.2}
THETA0, OMEGA0, T_END = 1.0, 0.0, 6.0


def damped_pendulum() -> tuple[gvi.LagrangianSystem, tuple[sp.Symbol, sp.Symbol]]:
    """The model; l and c are parameters (defaults 1 and 0.1)."""
    theta, omega, length, c, g = sp.symbols("theta omega l c g")
    L = length**2 * omega**2 / 2 + g * length * sp.cos(theta)
    system = gvi.LagrangianSystem(
        L, q=[theta], v=[omega], params={length: 1.0, c: 0.1, g: 9.81}, forces=[-c * omega]
    )
    return system, (length, c)


def measurements(system, n_obs: int, noise: float, seed: int):
    """Noisy angles at random instants of a reference run (exact to about 1e-12)."""
    h_ref = 1e-3
    steps = int(round(T_END / h_ref))
    ref = gvi.Integrator(system, gvi.Galerkin(3)).integrate(
        [THETA0], v0=[OMEGA0], h=h_ref, n_steps=steps, params=TRUTH
    )
    rng = np.random.default_rng(seed)
    rows = np.r_[0, np.sort(rng.choice(np.arange(1, steps + 1), n_obs - 1, replace=False))]
    return ref.t[rows], ref.q[rows] + noise * rng.standard_normal((n_obs, 1)), ref


def report(fit, symbols) -> None:
    print(f"{fit.message}; {fit.nfev} runs, {fit.njev} Jacobians")
    print(f"{'':10}{'estimate':>12}{'std. error':>12}{'truth':>10}")
    for s, value, error in zip(symbols, fit.values, fit.standard_errors, strict=True):
        print(f"{str(s):10}{value:12.5f}{error:12.5f}{TRUTH[str(s)]:10.4f}")
    se0 = np.sqrt(np.diag(fit.full_covariance)[2:])
    print(f"{'theta0':10}{fit.q0[0]:12.5f}{se0[0]:12.5f}{THETA0:10.4f}")
    print(f"{'omega0':10}{fit.v0[0]:12.5f}{se0[1]:12.5f}{OMEGA0:10.4f}")
    print(f"residual rms {np.sqrt(np.mean(fit.residuals**2)):.4f} rad "
          f"(noise level s = {np.sqrt(fit.residual_variance):.4f})")  # fmt: skip


def plot(path: Path, t_obs, q_obs, fit, ref) -> None:
    """Data, fitted trajectory and truth; residuals below."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: skipping the plot ({path} not written)")
        return
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True,
                                      gridspec_kw={"height_ratios": [3, 1]})  # fmt: skip
    top.plot(ref.t, ref.q[:, 0], color="0.7", lw=3, label="truth")
    top.plot(fit.trajectory.t, fit.trajectory.q[:, 0], color="C1", label="fit")
    top.plot(t_obs, q_obs[:, 0], ".", color="C0", label="measurements")
    top.set_ylabel("angle (rad)")
    top.legend(loc="upper right")
    bottom.axhline(0.0, color="0.5", lw=0.8)
    bottom.plot(t_obs, fit.residuals[:, 0], ".", color="C0")
    bottom.set_ylabel("residual (rad)")
    bottom.set_xlabel("t (s)")
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n-obs", type=int, default=80, help="number of measurements")
    parser.add_argument("--noise", type=float, default=0.01, help="noise level (rad)")
    parser.add_argument("--h", type=float, default=0.02, help="largest step of the fit")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument(
        "--output", type=Path, default=None, help="directory for the PNG (default: a new temp dir)"
    )
    args = parser.parse_args(argv)
    system, symbols = damped_pendulum()
    t_obs, q_obs, ref = measurements(system, args.n_obs, args.noise, args.seed)
    fit = fit_parameters(system, gvi.Galerkin(2), t_obs, q_obs, {"l": 1.0, "c": 0.05},
                         h=args.h, fit_initial_state=True)  # fmt: skip
    report(fit, symbols)
    output = args.output or Path(tempfile.mkdtemp(prefix="fit_damped_pendulum-"))
    output.mkdir(parents=True, exist_ok=True)
    plot(output / PLOT_NAME, t_obs, q_obs, fit, ref)
    return fit


if __name__ == "__main__":
    main()
