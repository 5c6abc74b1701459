"""The figure of the how-to "contact": a bouncing ball with restitution e = 0.8.

Runs the ball dropped from 1 m (Galerkin degree 3, h = 1e-3) for 5 s: isolated
impacts until they accumulate before the Zeno time, then time-stepping with
the ball at rest (``contact_mode="auto"``). Draws ``docs/_static/bouncing_ball.png``:
height against time with the impacts marked, and the energy with the closed
form e^(2k) m g h0 after k impacts. Prints the largest error of the impact
times against t_k = t1 [1 + 2e (1 - e^(k-1)) / (1 - e)].

Run from the repository root::

    python docs/_scripts/bouncing_ball.py
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import sympy as sp

import galerkin_vi as gvi

OUTPUT = Path(__file__).resolve().parents[1] / "_static" / "bouncing_ball.png"


def main() -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    y, vy, g = sp.symbols("y vy g")
    e, h0, gravity = 0.8, 1.0, 9.81
    ball = gvi.LagrangianSystem(
        vy**2 / 2 - g * y, [y], [vy], params={g: gravity}, contacts=[gvi.Contact(y, restitution=e)]
    )
    integrator = gvi.Integrator(ball, gvi.Galerkin(3))
    traj = integrator.integrate([h0], [0.0], h=1e-3, n_steps=5000)
    switch = traj.contact_forces.t[0]
    # the isolated impacts, before the switch to time-stepping
    times = np.array([i.t for i in traj.impacts if i.t < switch])
    k = np.arange(1, len(times) + 1)
    t1 = np.sqrt(2 * h0 / gravity)
    exact = t1 * (1 + 2 * e * (1 - e ** (k - 1)) / (1 - e))
    print(f"{len(times)} impacts, largest impact-time error {np.abs(times - exact).max():.2e}")
    print(f"time-stepping from t = {switch:.6f} s; {traj.message}")
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(traj.t, traj.q[:, 0], lw=1)
    top.plot(times, np.zeros_like(times), "|", color="C3", ms=8, label="impacts")
    top.set_ylabel("height (m)")
    top.legend(loc="upper right")
    bottom.plot(traj.t, traj.energy(), lw=1, label="galerkin_vi")
    steps = gravity * h0 * e ** (2 * np.concatenate([[0], k]))
    bottom.step(np.concatenate([[0], times]), steps, where="post", ls="--", color="k",
                lw=0.8, label=r"$e^{2k} m g h_0$")  # fmt: skip
    bottom.set_yscale("symlog", linthresh=1e-6)
    bottom.set_ylabel("energy (J/kg)")
    bottom.set_xlabel("t (s)")
    bottom.legend(loc="upper right")
    zeno = t1 * (1 + e) / (1 - e)
    for ax in (top, bottom):
        ax.axvline(zeno, color="0.6", lw=0.8, ls=":")
        ax.axvspan(switch, traj.t[-1], color="C2", alpha=0.1, lw=0)
    top.set_title(
        f"e = {e}: {len(times)} isolated impacts, at rest after the Zeno time {zeno:.3f} s"
    )
    fig.tight_layout()
    fig.savefig(OUTPUT, dpi=120)
    print(f"wrote {OUTPUT}")


if __name__ == "__main__":
    main()
