"""Dojo's box toss: a cube thrown tumbling onto the floor, galerkin_vi beside MuJoCo.

A cube of side 0.5 m and mass 1 kg, its eight corners against the floor, is
thrown from (0, -1, 1) m with velocity (0, 3, 1) m/s and angular velocity
(0.5, 0.5, 0) rad/s (Dojo's ``box`` example) and runs for 5 s with Coulomb
friction mu and no restitution. galerkin_vi: Galerkin(1), quaternions, the
time-stepping contact step compiled (``backend="numba"``) and, with ``--numpy``,
the same run with the NumPy step (``backend="numpy"``): the same steps, so their
ratio is the compiled loop's gain; with ``--modes`` the contact modes (``auto``:
the flights between isolated impacts by the smooth loop, each impact located by
events; ``time-stepping``: every step in the compiled contact loop, the touches
cut out of the steps there). MuJoCo (``pip install -e ".[bench]"``): a free
box with an elliptic cone, ``mj_step`` in C at the same h; its contact is soft.

Each row: whether the run reached 5 s, how far from rest it ends (the largest
|v| and |omega| over its last 0.1 s; 0 to round-off is rest on a face), its
height above the resting height a = 0.25 m (MuJoCo's penetration shows here), the
steps that carried contact, the interior-point iterations per such step, and the
wall time per step of the whole run, per step taken (the best of ``--repeats``,
after a first run that compiles and builds); ``x MuJoCo`` is the ratio to MuJoCo's time per step in
this process.

Usage::

    python benchmarks/box_toss.py                 # mu 0.1, 0.4, 0.8; h 0.01, 0.005
    python benchmarks/box_toss.py --numpy         # with the NumPy step (minutes)
    python benchmarks/box_toss.py --frictions 0.4 --steps 0.01 --modes time-stepping
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import galerkin_vi as gvi

G = 9.81
SIDE, MASS, DURATION = 0.5, 1.0, 5.0
START = {"position": [0.0, -1.0, 1.0], "velocity": [0.0, 3.0, 1.0], "spin": [0.5, 0.5, 0.0]}


def cube_system(friction: float) -> gvi.Multibody:
    a = SIDE / 2
    cube = gvi.RigidBody("box", mass=MASS, inertia=[MASS * SIDE**2 / 6] * 3)
    corners = [[sx * a, sy * a, sz * a] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    floor = gvi.Plane([0, 0, 1], 0.0)
    contacts = [
        gvi.BodyContact(gvi.BodyPoint(cube, c), floor, restitution=0.0, friction=friction)
        for c in corners
    ]
    return gvi.Multibody([cube], gravity=[0, 0, -G], contacts=contacts)


def galerkin_run(friction: float, h: float, backend: str, repeats: int, mode: str) -> dict:
    mb = cube_system(friction)
    q0, v0 = mb.state(
        positions={"box": START["position"]},
        velocities={"box": START["velocity"]},
        angular_velocities={"box": START["spin"]},
        frame="space",
    )
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(1), backend=backend)
    n_steps = int(round(DURATION / h))
    best, traj = np.inf, None
    for _ in range(1 + repeats):  # the first run builds and compiles
        start = time.perf_counter()
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            traj = integrator.integrate(
                q0, v0=v0, h=h, n_steps=n_steps, on_failure="warn", contact_mode=mode
            )
        best = min(best, time.perf_counter() - start) if _ else np.inf
    motion = mb.motion(traj, "box")
    tail = motion.t >= motion.t[-1] - 0.1
    forces = traj.contact_forces
    its = forces.iterations if forces is not None else np.zeros(1)
    return {
        "completed": bool(traj.success) and traj.t[-1] >= DURATION - 1e-9,
        "t_end": float(traj.t[-1]),
        "v": float(np.abs(motion.velocity[tail]).max()),
        "w": float(np.abs(motion.angular_velocity[tail]).max()),
        "height": float(motion.position[-1, 2] - SIDE / 2),
        "contact_steps": 0 if forces is None else len(forces.t),
        "iterations": float(its.mean()),
        # per step taken (a run that stops early took fewer)
        "us_per_step": 1e6 * best / max(1, int(round((traj.t[-1] - traj.t[0]) / h))),
    }


def mujoco_run(friction: float, h: float, repeats: int) -> dict | None:
    try:
        import mujoco
    except ImportError:
        return None
    a = SIDE / 2
    xml = f"""
    <mujoco>
      <option timestep="{h}" cone="elliptic" gravity="0 0 -{G}"/>
      <worldbody>
        <geom type="plane" size="10 10 0.1" friction="{friction} 0.005 0.0001"/>
        <body name="box" pos="{" ".join(map(str, START["position"]))}">
          <freejoint/>
          <geom type="box" size="{a} {a} {a}" mass="{MASS}" friction="{friction} 0.005 0.0001"/>
        </body>
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    n_steps = int(round(DURATION / h))
    best = np.inf
    for _ in range(repeats):
        mujoco.mj_resetData(model, data)
        data.qvel[:3] = START["velocity"]
        data.qvel[3:6] = START["spin"]  # body frame: the box starts unrotated
        start = time.perf_counter()
        mujoco.mj_step(model, data, nstep=n_steps)
        best = min(best, time.perf_counter() - start)
    return {
        "completed": True,
        "v": float(np.abs(data.qvel[:3]).max()),
        "w": float(np.abs(data.qvel[3:6]).max()),
        "height": float(data.qpos[2] - a),
        "us_per_step": 1e6 * best / n_steps,
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--frictions", type=float, nargs="+", default=[0.1, 0.4, 0.8])
    parser.add_argument("--steps", type=float, nargs="+", default=[0.01, 0.005])
    parser.add_argument("--numpy", action="store_true", help="also the NumPy step (slow)")
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument(
        "--modes", nargs="+", default=["auto", "time-stepping"],
        help="galerkin_vi's contact modes (auto: isolated impacts located by events in flight)",
    )  # fmt: skip
    args = parser.parse_args(argv)
    print(
        "| mu | h | run | reached 5 s | end max abs v | end max abs omega | height - a |"
        " contact steps | its per step | us per step | x MuJoCo |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    for friction in args.frictions:
        for h in args.steps:
            peer = mujoco_run(friction, h, args.repeats)
            runs = [
                (f"galerkin_vi {mode}", galerkin_run(friction, h, "numba", args.repeats, mode))
                for mode in args.modes
            ]
            if args.numpy:
                runs.append(
                    ("galerkin_vi NumPy step", galerkin_run(friction, h, "numpy", 1, args.modes[0]))
                )
            if peer is not None:
                runs.append(("MuJoCo (soft contact)", peer))
            for name, row in runs:
                ratio = row["us_per_step"] / peer["us_per_step"] if peer else float("nan")
                reached = "yes" if row["completed"] else f"no (t = {row.get('t_end', 0):.3f})"
                print(
                    f"| {friction} | {h} | {name} | {reached} | {row['v']:.1e} | {row['w']:.1e}"
                    f" | {row['height']:.1e} | {row.get('contact_steps', '')} |"
                    f" {row.get('iterations', float('nan')):.1f} | {row['us_per_step']:.1f} |"
                    f" {ratio:.0f} |",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
