"""Contact scenes against their closed forms, galerkin_vi beside MuJoCo, in one run.

Three scenes of the contact issue, each with a closed form:

- **ball**: a ball dropped from 1 m bouncing with e = 0.8; error: the largest
  error of the first five impact times t_k = t1 [1 + 2e(1 - e^(k-1))/(1 - e)];
- **incline**: a block released on a slope a = 0.5 with mu = 0.3; error of the
  distance slid after 1 s, g (sin a - mu cos a) / 2;
- **roll**: a ball (I = 2/5 m R^2) launched sliding at 3 m/s without spin,
  mu = 0.2; error of its speed at 1.5 s, rolling at 5/7 of the launch speed.

galerkin_vi runs ``Integrator.integrate`` (Galerkin degree 3 for the ball, 2
otherwise); MuJoCo (the ``mujoco`` package, optional: ``pip install -e
".[bench]"``) runs ``mj_step(..., nstep=N)`` in C with an elliptic friction
cone; its contacts are soft, and for the ball its restitution is set through
``solref`` (negative: stiffness and damping) from the damping ratio of e = 0.8,
as a user would. Each row gives the step size, the error against the closed
form and the CPU seconds (best of three); MuJoCo's rows come from the same
process, so the ratios hold on a noisy machine.

Usage::

    python benchmarks/contact.py
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from functools import cache

import numpy as np
import sympy as sp

import galerkin_vi as gvi

G = 9.81
E_BALL, SLOPE, MU_SLOPE, MU_ROLL, V_ROLL, R = 0.8, 0.5, 0.3, 0.2, 3.0, 0.1


def _best(fn: Callable[[], float], repeats: int = 3) -> tuple[float, float]:
    """(error, CPU seconds): the best time of ``repeats`` calls of ``fn`` -> error."""
    best, error = np.inf, np.nan
    for _ in range(repeats):
        start = time.process_time()
        error = fn()
        best = min(best, time.process_time() - start)
    return error, best


def ball_times() -> np.ndarray:
    t1 = np.sqrt(2 / G)
    k = np.arange(1, 6)
    return t1 * (1 + 2 * E_BALL * (1 - E_BALL ** (k - 1)) / (1 - E_BALL))


# ---------------------------------------------------------------- galerkin_vi
@cache
def _integrators() -> dict[str, gvi.Integrator]:
    """The scenes' integrators, built once as a user would."""
    y, vy = sp.symbols("y vy")
    ball = gvi.LagrangianSystem(
        vy**2 / 2 - G * y, [y], [vy], contacts=[gvi.Contact(y, restitution=E_BALL)]
    )
    block, rolling = _plane_systems()
    return {
        "ball": gvi.Integrator(ball, gvi.Galerkin(3)),
        "incline": gvi.Integrator(block, gvi.Galerkin(2)),
        "roll": gvi.Integrator(rolling, gvi.Galerkin(2)),
    }


def gvi_ball(h: float) -> float:
    traj = _integrators()["ball"].integrate(
        [1.0], [0.0], h=h, t_span=(0.0, 2.8), contact_mode="event"
    )
    times = np.array([i.t for i in traj.impacts[:5]])
    return float(np.abs(times - ball_times()).max())


def _plane_systems():
    x, y, th, vx, vy, w = sp.symbols("x y theta vx vy w")
    slope = (vx**2 + vy**2) / 2 + G * (x * sp.sin(SLOPE) - y * sp.cos(SLOPE))
    block = gvi.LagrangianSystem(
        slope, [x, y], [vx, vy], contacts=[gvi.Contact(y, friction=MU_SLOPE, slip=[vx])]
    )
    inertia = 2 * R**2 / 5
    rolling = (vx**2 + vy**2) / 2 + inertia * w**2 / 2 - G * y
    ball = gvi.LagrangianSystem(
        rolling, [x, y, th], [vx, vy, w],
        contacts=[gvi.Contact(y - R, friction=MU_ROLL, slip=[vx + R * w])],
    )  # fmt: skip
    return block, ball


def gvi_incline(h: float) -> float:
    traj = _integrators()["incline"].integrate([0.0, 0.0], [0.0, 0.0], h=h, t_span=(0.0, 1.0))
    exact = G * (np.sin(SLOPE) - MU_SLOPE * np.cos(SLOPE)) / 2
    return float(abs(traj.q[-1, 0] - exact))


def gvi_roll(h: float) -> float:
    traj = _integrators()["roll"].integrate(
        [0.0, R, 0.0], [V_ROLL, 0.0, 0.0], h=h, t_span=(0.0, 1.5)
    )
    return float(abs(traj.p[-1, 0] - 5 * V_ROLL / 7))


# --------------------------------------------------------------------- MuJoCo
def _mujoco(xml: str, h: float, seconds: float, record: Callable | None = None):
    import mujoco

    model = mujoco.MjModel.from_xml_string(xml.replace("TIMESTEP", repr(h)))
    data = mujoco.MjData(model)
    steps = int(round(seconds / h))
    if record is None:
        mujoco.mj_step(model, data, nstep=steps)
        return model, data, None
    trace = np.empty(steps)
    for i in range(steps):
        mujoco.mj_step(model, data)
        trace[i] = record(data)
    return model, data, trace


BALL_XML = """<mujoco><option timestep="TIMESTEP" gravity="0 0 -9.81"/>
<worldbody><geom type="plane" size="5 5 .1" solref="-{k} -{b}" friction="0 0 0"/>
<body pos="0 0 1.1"><freejoint/><geom type="sphere" size=".1" mass="1" friction="0 0 0"
 solref="-{k} -{b}"/></body></worldbody></mujoco>"""


def mujoco_ball(h: float) -> float:
    k = 2e4  # stiff; the damping for e = 0.8 from the damping ratio of a spring-damper
    zeta = -np.log(E_BALL) / np.sqrt(np.pi**2 + np.log(E_BALL) ** 2)
    xml = BALL_XML.format(k=k, b=2 * zeta * np.sqrt(k))
    _, _, height = _mujoco(xml, h, 2.8, record=lambda d: d.qpos[2] - 0.1)
    t = h * np.arange(1, height.size + 1)
    onsets = t[1:][(height[1:] <= 0) & (height[:-1] > 0)][:5]
    if onsets.size < 5:
        return np.inf
    return float(np.abs(onsets - ball_times()).max())


SLOPE_XML = """<mujoco><option timestep="TIMESTEP" gravity="0 0 -9.81" cone="elliptic"/>
<worldbody><geom type="plane" size="50 50 .1" zaxis="{n}" friction="{mu} 0 0"/>
<body pos="{p}" zaxis="{n}"><freejoint/><geom type="box" size=".05 .05 .05" mass="1"
 friction="{mu} 0 0"/></body></worldbody></mujoco>"""


def mujoco_incline(h: float) -> float:
    import mujoco

    normal = np.array([np.sin(SLOPE), 0.0, np.cos(SLOPE)])
    xml = SLOPE_XML.format(
        n=" ".join(map(str, normal)), mu=MU_SLOPE, p=" ".join(map(str, 0.05 * normal))
    )
    model = mujoco.MjModel.from_xml_string(xml.replace("TIMESTEP", repr(h)))
    data = mujoco.MjData(model)
    start = data.qpos[:3].copy()
    mujoco.mj_step(model, data, nstep=int(round(1.0 / h)))
    down = np.array([np.cos(SLOPE), 0.0, -np.sin(SLOPE)])
    exact = G * (np.sin(SLOPE) - MU_SLOPE * np.cos(SLOPE)) / 2
    return float(abs((data.qpos[:3] - start) @ down - exact))


ROLL_XML = """<mujoco><option timestep="TIMESTEP" gravity="0 0 -9.81" cone="elliptic"/>
<worldbody><geom type="plane" size="50 50 .1" friction="{mu} 0 0"/>
<body pos="0 0 {r}"><freejoint/><geom type="sphere" size="{r}" mass="1" friction="{mu} 0 0"/>
</body></worldbody></mujoco>"""


def mujoco_roll(h: float) -> float:
    import mujoco

    model = mujoco.MjModel.from_xml_string(
        ROLL_XML.format(mu=MU_ROLL, r=R).replace("TIMESTEP", repr(h))
    )
    data = mujoco.MjData(model)
    data.qvel[0] = V_ROLL
    mujoco.mj_step(model, data, nstep=int(round(1.5 / h)))
    return float(abs(data.qvel[0] - 5 * V_ROLL / 7))


SCENES = {
    "ball": (gvi_ball, mujoco_ball, (0.1, 1e-2, 1e-3), (1e-3, 1e-4)),
    "incline": (gvi_incline, mujoco_incline, (0.5, 0.1, 0.01), (1e-2, 1e-3, 1e-4)),
    "roll": (gvi_roll, mujoco_roll, (0.5, 0.2, 0.05), (1e-2, 1e-3, 1e-4)),
}


def main() -> int:
    try:
        import mujoco
    except ImportError:
        mujoco = None
        print("mujoco is not installed (pip install -e '.[bench]'): galerkin_vi only")
    for scene, (ours, theirs, our_hs, their_hs) in SCENES.items():
        ours(our_hs[0])  # loaded and compiled once, not timed
        print(f"\n{scene}")
        print(f"{'':12s} {'h':>8s} {'error':>10s} {'CPU s':>9s}")
        rows = [("galerkin_vi", h, *_best(lambda h=h, f=ours: f(h))) for h in our_hs]
        if mujoco is not None:
            rows += [(f"MuJoCo {mujoco.__version__}", h, *_best(lambda h=h, f=theirs: f(h)))
                     for h in their_hs]  # fmt: skip
        for name, h, error, seconds in rows:
            print(f"{name:12s} {h:8.0e} {error:10.2e} {seconds:9.4f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
