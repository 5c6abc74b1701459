"""Stacks of boxes and piles of spheres: cost per step against the number of bodies, drift.

A stack of n cubes (side 0.5 m, 1 kg, each offset 1 cm sideways from the one below,
the four lower corners of each against the floor or the upper face of the box
below, mu = 0.5) dropped from 1 mm gaps; a pile of n spheres (radius 0.1 m, 0.2 kg,
mu = 0.5, each pair in contact, listed upper sphere first) dropped in a box of
walls 0.25 m from the pile's axis, from a loose column with small sideways offsets.
galerkin_vi: Galerkin(1), quaternions, ``contact_mode="time-stepping"``, compiled;
MuJoCo (``pip install -e ".[bench]"``): the same bodies as free joints with box and
sphere geoms and an elliptic cone, ``mj_step`` at the same h, in the same run.

Each row: whether the run reached its end, the largest |v| and |omega| of any body
over its last second (0 to round-off is rest), the drift (the largest distance of a
centre from where it was at t = 1 s, after the landing), the stack's height error
(centres against 0.25, 0.75, ...; MuJoCo's soft contact shows here), the
interior-point iterations per contact step, the steps handed to Python, the first
run's wall time (the model built, its point functions generated and compiled, the
run) and the wall time per step of a second run; ``x MuJoCo`` is its ratio to
MuJoCo's time per step in this process.

Usage::

    python benchmarks/stacks.py                          # 1..5 boxes, 10 s
    python benchmarks/stacks.py --duration 100 --boxes 5 --spheres
    python benchmarks/stacks.py --boxes --spheres 2 4 8  # spheres only
"""

from __future__ import annotations

import argparse
import time
import warnings

import numpy as np

import galerkin_vi as gvi

G, FRICTION, A, MASS = 9.81, 0.5, 0.25, 1.0
RADIUS, BALL_MASS, WALL = 0.1, 0.2, 0.25


def box_stack(n: int) -> tuple[gvi.Multibody, dict]:
    inertia = [MASS * (2 * A) ** 2 / 6] * 3
    boxes = [gvi.Box(gvi.RigidBody(f"b{i}", mass=MASS, inertia=inertia), [A] * 3) for i in range(n)]
    contacts = gvi.standing_contacts(boxes[0], gvi.Plane([0, 0, 1], 0.0), friction=FRICTION)
    for lower, upper in zip(boxes, boxes[1:], strict=False):
        contacts += gvi.standing_contacts(upper, lower, friction=FRICTION)
    mb = gvi.Multibody([b.body for b in boxes], gravity=[0, 0, -G], contacts=contacts)
    start = {f"b{i}": [0.01 * (i % 2), 0.0, A + 2 * A * i + 1e-3 * (i + 1)] for i in range(n)}
    return mb, start


def sphere_pile(n: int) -> tuple[gvi.Multibody, dict]:
    balls = [
        gvi.RigidBody(f"s{i}", mass=BALL_MASS, inertia=[0.4 * BALL_MASS * RADIUS**2] * 3)
        for i in range(n)
    ]
    walls = [gvi.Plane([0, 0, 1], 0.0)] + [
        gvi.Plane(normal, -WALL) for normal in ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0])
    ]
    contacts = [
        gvi.BodyContact(gvi.Sphere(ball, RADIUS), wall, friction=FRICTION)
        for ball in balls
        for wall in walls
    ]
    contacts += [
        gvi.BodyContact(
            gvi.Sphere(balls[j], RADIUS), gvi.Sphere(balls[i], RADIUS), friction=FRICTION
        )
        for i in range(n)
        for j in range(i + 1, n)
    ]
    mb = gvi.Multibody(balls, gravity=[0, 0, -G], contacts=contacts)
    rng = np.random.default_rng(1)
    start = {
        f"s{i}": [*(0.03 * rng.uniform(-1, 1, 2)), RADIUS + 2.2 * RADIUS * i + 1e-3]
        for i in range(n)
    }
    return mb, start


def galerkin_run(kind: str, n: int, h: float, duration: float) -> dict:
    started = time.perf_counter()
    mb, start = box_stack(n) if kind == "boxes" else sphere_pile(n)
    q0, v0 = mb.state(positions=start)
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(1), backend="numba")
    built = started
    n_steps = int(round(duration / h))
    best, traj = np.inf, None
    handed = 0
    for repeat in range(2):  # the first run compiles what remains
        from galerkin_vi.contact import runs

        calls = []
        through = runs._Run._through_stepping

        def counted(self, *args, _through=through, _calls=calls):
            _calls.append(1)
            return _through(self, *args)

        runs._Run._through_stepping = counted
        try:
            started = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                traj = integrator.integrate(
                    q0, v0=v0, h=h, n_steps=n_steps, on_failure="warn",
                    contact_mode="time-stepping",
                )  # fmt: skip
            elapsed = time.perf_counter() - started
            if not repeat:
                first = elapsed + (started - built)
        finally:
            runs._Run._through_stepping = through
        if repeat:
            best, handed = elapsed, len(calls)
    motions = [mb.motion(traj, name) for name in start]
    tail = traj.t >= traj.t[-1] - 1.0
    settled = int(np.searchsorted(traj.t, 1.0))
    drift = (
        max(
            float(np.linalg.norm(m.position[settled:] - m.position[settled], axis=1).max())
            for m in motions
        )
        if settled < len(traj.t)
        else float("nan")
    )
    forces = traj.contact_forces
    its = forces.iterations if forces is not None else np.zeros(1)
    height = (
        max(abs(m.position[-1, 2] - (A + 2 * A * i)) for i, m in enumerate(motions))
        if kind == "boxes"
        else float("nan")
    )
    return {
        "completed": bool(traj.success) and traj.t[-1] >= duration - 1e-9,
        "t_end": float(traj.t[-1]),
        "v": max(float(np.abs(m.velocity[tail]).max()) for m in motions),
        "w": max(float(np.abs(m.angular_velocity[tail]).max()) for m in motions),
        "drift": drift,
        "height": height,
        "iterations": float(its.mean()),
        "handed": handed,
        "first": first,
        "us_per_step": 1e6 * best / max(1, int(round((traj.t[-1] - traj.t[0]) / h))),
        "contacts": len(mb.system.contacts),
    }


def mujoco_run(kind: str, n: int, h: float, duration: float) -> dict | None:
    try:
        import mujoco
    except ImportError:
        return None
    _, start = box_stack(n) if kind == "boxes" else sphere_pile(n)
    friction = f'friction="{FRICTION} 0.005 0.0001"'
    if kind == "boxes":
        geom = f'<geom type="box" size="{A} {A} {A}" mass="{MASS}" {friction}/>'
        walls = ""
    else:
        geom = f'<geom type="sphere" size="{RADIUS}" mass="{BALL_MASS}" {friction}/>'
        walls = "".join(
            f'<geom type="plane" size="1 1 0.1" pos="{x} {y} 0" zaxis="{-x} {-y} 0"/>'
            for x, y in ((WALL, 0), (-WALL, 0), (0, WALL), (0, -WALL))
        )
    bodies = "".join(
        f'<body name="{name}" pos="{" ".join(map(str, pos))}"><freejoint/>{geom}</body>'
        for name, pos in start.items()
    )
    xml = f"""
    <mujoco>
      <option timestep="{h}" cone="elliptic" gravity="0 0 -{G}"/>
      <worldbody>
        <geom type="plane" size="10 10 0.1" {friction}/>{walls}{bodies}
      </worldbody>
    </mujoco>"""
    model = mujoco.MjModel.from_xml_string(xml)
    data = mujoco.MjData(model)
    n_steps = int(round(duration / h))
    settled = int(round(1.0 / h))
    mujoco.mj_step(model, data, nstep=settled)
    at_one = data.qpos.reshape(n, 7)[:, :3].copy()
    started = time.perf_counter()
    mujoco.mj_step(model, data, nstep=n_steps - settled)
    elapsed = time.perf_counter() - started
    pos = data.qpos.reshape(n, 7)[:, :3]
    vel = data.qvel.reshape(n, 6)
    height = (
        float(np.abs(pos[:, 2] - (A + 2 * A * np.arange(n))).max())
        if kind == "boxes"
        else float("nan")
    )
    return {
        "completed": True,
        "v": float(np.abs(vel[:, :3]).max()),
        "w": float(np.abs(vel[:, 3:]).max()),
        "drift": float(np.linalg.norm(pos - at_one, axis=1).max()),
        "height": height,
        "us_per_step": 1e6 * elapsed / (n_steps - settled),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--boxes", type=int, nargs="*", default=[1, 2, 3, 4, 5])
    parser.add_argument("--spheres", type=int, nargs="*", default=[])
    parser.add_argument("--step", type=float, default=0.01)
    parser.add_argument("--duration", type=float, default=10.0)
    args = parser.parse_args(argv)
    print(
        "| scene | bodies | contacts | run | reached end | end max abs v | end max abs omega |"
        " drift after 1 s | height error | its per step | Python steps | first run s |"
        " us per step | x MuJoCo |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    scenes = [("boxes", n) for n in args.boxes] + [("spheres", n) for n in args.spheres]
    for kind, n in scenes:
        ours = galerkin_run(kind, n, args.step, args.duration)
        peer = mujoco_run(kind, n, args.step, args.duration)
        rows = [("galerkin_vi", ours)] + ([("MuJoCo (soft contact)", peer)] if peer else [])
        for name, row in rows:
            ratio = row["us_per_step"] / peer["us_per_step"] if peer else float("nan")
            reached = "yes" if row["completed"] else f"no (t = {row.get('t_end', 0):.3f})"
            print(
                f"| {kind} | {n} | {ours['contacts']} | {name} | {reached} | {row['v']:.1e} |"
                f" {row['w']:.1e} | {row['drift']:.1e} | {row['height']:.1e} |"
                f" {row.get('iterations', float('nan')):.1f} | {row.get('handed', '')} |"
                f" {row.get('first', float('nan')):.1f} | {row['us_per_step']:.0f} |"
                f" {ratio:.0f} |",
                flush=True,
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
