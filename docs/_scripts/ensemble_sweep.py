"""The parameter sweep of the how-to "ensembles": a double pendulum's chaos against its energy.

Runs 400 double pendulums released from rest at initial angles q1 = q2 = a for
400 values of a in [0.2, 2.4] with ``Integrator.integrate_many`` (one call,
threads over the cores), and draws ``docs/_static/ensemble_sweep.png``: the
angle of the outer bob after 20 time units against a, smooth where the motion
is regular and scattered where it is chaotic. Prints the times of one thread
and of all cores.

Run from the repository root::

    python docs/_scripts/ensemble_sweep.py
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import numpy as np

import galerkin_vi as gvi
from galerkin_vi.problems import mechanics

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "ensemble_sweep.png"


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    problem = mechanics.double_pendulum()
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    angles = np.linspace(0.2, 2.4, 400)
    q0s = np.column_stack([angles, angles])
    run = {"h": 0.01, "n_steps": 2000, "save_every": 2000}
    integrator.integrate(q0s[0], [0.0, 0.0], **run)  # load the compiled loop once
    seconds = {}
    for workers in (1, os.cpu_count() or 1):
        start = time.perf_counter()
        many = integrator.integrate_many(q0s, [0.0, 0.0], workers=workers, **run)
        seconds[workers] = time.perf_counter() - start
    for workers, s in seconds.items():
        print(f"{workers} thread(s): {s:.2f} s for {len(many)} members")
    print(f"all members succeeded: {bool(many.success.all())}; q shape {many.q.shape}")
    final = np.mod(many.q[:, -1, 1] + np.pi, 2 * np.pi) - np.pi
    fig, ax = plt.subplots(figsize=(6.5, 3.5))
    ax.plot(angles, final, ".", markersize=3)
    ax.set_xlabel("initial angles q1 = q2 = a (released from rest)")
    ax.set_ylabel("outer angle q2 at t = 20")
    ax.set_title("400 double pendulums in one integrate_many call")
    fig.tight_layout()
    fig.savefig(OUTPUT, dpi=120)
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    main()
