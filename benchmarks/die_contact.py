"""A die thrown onto a table: how robust and how costly the persistent-contact step is.

A cube of half side a (mass m, J = m (2a)^2 / 6 about every axis) carries its
eight corners (``gvi.BodyPoint``) against the table ``gvi.Plane([0, 0, 1], 0)``
with restitution 0.3. It is thrown from rest at height 6a, tilted at random,
with a random horizontal velocity and spin; the throws of the large die are
the small one's scaled by Froude similarity (lengths x L, times and
velocities x sqrt(L), spins / sqrt(L)), so every size sees the same motion.
The sweep covers a in {0.05, 0.5} (m 0.1, 1.0), h in {0.002, 0.005, 0.01},
friction in {0, 0.4, 1.0}, Galerkin(1) and Galerkin(2), quaternion and
matrix rotations, and three throws each.

Per case it prints whether the run succeeded, where it stopped if not, the
number of complementarity (time-stepping) steps, their interior-point
iterations (mean and largest), the wall seconds per such step (the whole run's
time divided by their number: the event-driven steps between them are compiled
and cost microseconds), and, for a run that completed, how far the die is from
rest on a face (height - a, and the energy's distance from m g a, relative).

Usage::

    python benchmarks/die_contact.py                 # the whole sweep (216 runs)
    python benchmarks/die_contact.py --quick         # one throw, quaternions only
    python benchmarks/die_contact.py --sizes 0.05 --steps 0.002 --frictions 0.4
"""

from __future__ import annotations

import argparse
import itertools
import time
import warnings

import numpy as np
from scipy.spatial.transform import Rotation

import galerkin_vi as gvi

GRAVITY, RESTITUTION = 9.81, 0.3
#: half sides and their masses
SIZES = {0.05: 0.1, 0.5: 1.0}
#: seconds of the small die's run (the large one's: times sqrt(10), Froude)
DURATION = 1.5


def die_system(a: float, m: float, friction: float, rotation: str) -> gvi.Multibody:
    """The die with its eight corners against the table."""
    die = gvi.RigidBody("die", mass=m, inertia=[m * (2 * a) ** 2 / 6] * 3, rotation=rotation)
    corners = [[sx * a, sy * a, sz * a] for sx in (1, -1) for sy in (1, -1) for sz in (1, -1)]
    table = gvi.Plane([0, 0, 1], 0.0)
    contacts = [
        gvi.BodyContact(gvi.BodyPoint(die, c), table, restitution=RESTITUTION, friction=friction)
        for c in corners
    ]
    return gvi.Multibody([die], gravity=[0, 0, -GRAVITY], contacts=contacts)


def throw(a: float, seed: int) -> dict:
    """A random throw of the die of half side a, Froude-scaled from a = 0.05."""
    scale = np.sqrt(a / 0.05)
    rng = np.random.default_rng(seed)
    return {
        "positions": {"die": [0.0, 0.0, 6 * a]},
        "rotations": {"die": Rotation.random(random_state=seed).as_matrix()},
        "velocities": {"die": [*(scale * rng.uniform(-0.6, 0.6, 2)), 0.0]},
        "angular_velocities": {"die": list(rng.uniform(-5.0, 5.0, 3) / scale)},
    }


def run_case(a: float, h: float, friction: float, order: int, rotation: str, seed: int) -> dict:
    """One throw: the run's outcome and the cost of its complementarity steps."""
    m = SIZES[a]
    mb = die_system(a, m, friction, rotation)
    q0, v0 = mb.state(**throw(a, seed))
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(order))
    duration = DURATION * np.sqrt(a / 0.05)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            traj = integrator.integrate(q0, v0=v0, h=h, n_steps=int(round(duration / h)))
    except (ValueError, np.linalg.LinAlgError) as exc:  # a failure the run did not catch
        return {
            "a": a, "h": h, "mu": friction, "order": order, "rotation": rotation, "seed": seed,
            "success": False, "t_end": np.nan, "steps": 0, "mean_it": np.nan, "max_it": 0,
            "s_per_step": np.nan, "seconds": time.perf_counter() - start, "height": np.nan,
            "energy": np.nan, "error": type(exc).__name__,
        }  # fmt: skip
    seconds = time.perf_counter() - start
    forces = traj.contact_forces
    iterations = forces.iterations if forces is not None else np.zeros(1, dtype=int)
    row = {
        "a": a, "h": h, "mu": friction, "order": order, "rotation": rotation, "seed": seed,
        "success": bool(traj.success), "t_end": float(traj.t[-1]),
        "steps": int(len(iterations)) if forces is not None else 0,
        "mean_it": float(iterations.mean()), "max_it": int(iterations.max()),
        "s_per_step": seconds / max(1, len(iterations)), "seconds": seconds,
        "height": np.nan, "energy": np.nan,
    }  # fmt: skip
    if traj.success:
        motion = mb.motion(traj, "die")
        row["height"] = float(motion.position[-1, 2] - a)
        row["energy"] = float(traj.energy()[-1] / (m * GRAVITY * a) - 1.0)
    return row


def print_row(row: dict) -> None:
    outcome = "ok  " if row["success"] else f"FAIL t={row['t_end']:.3f}"
    if "error" in row:
        outcome = f"RAISED {row['error']}"
    print(
        f"a={row['a']:<5g} h={row['h']:<6g} mu={row['mu']:<4g} G({row['order']}) "
        f"{row['rotation']:10s} throw {row['seed']}  {outcome:13s} steps {row['steps']:5d} "
        f"it {row['mean_it']:5.1f}/{row['max_it']:3d}  {1e3 * row['s_per_step']:6.2f} ms/step  "
        f"height-a {row['height']:9.1e}  E/mga-1 {row['energy']:9.1e}",
        flush=True,
    )


def summary(rows: list[dict]) -> None:
    """Successes per (size, h, friction, order) over the rotations and throws."""
    print("\n a      h       mu    order  ok/runs  mean it  ms/step")
    key = lambda r: (r["a"], r["h"], r["mu"], r["order"])  # noqa: E731
    for k, group in itertools.groupby(sorted(rows, key=key), key=key):
        group = list(group)
        ok = sum(r["success"] for r in group)
        it = np.mean([r["mean_it"] for r in group])
        ms = 1e3 * np.nanmean([r["s_per_step"] for r in group])
        print(f" {k[0]:<6g} {k[1]:<7g} {k[2]:<5g} G({k[3]})   {ok:2d}/{len(group):<2d}    "
              f"{it:5.1f}   {ms:6.2f}")  # fmt: skip
    ok = sum(r["success"] for r in rows)
    print(f"\n{ok}/{len(rows)} runs completed")


def main(argv: list[str] | None = None) -> list[dict]:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", type=float, nargs="+", default=list(SIZES))
    parser.add_argument("--steps", type=float, nargs="+", default=[0.002, 0.005, 0.01])
    parser.add_argument("--frictions", type=float, nargs="+", default=[0.0, 0.4, 1.0])
    parser.add_argument("--orders", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--rotations", nargs="+", default=["quaternion", "matrix"])
    parser.add_argument("--throws", type=int, default=3)
    parser.add_argument("--quick", action="store_true", help="one throw, quaternions only")
    args = parser.parse_args(argv)
    throws, rotations = (1, ["quaternion"]) if args.quick else (args.throws, args.rotations)
    rows = []
    for a, h, mu, order, rotation, seed in itertools.product(
        args.sizes, args.steps, args.frictions, args.orders, rotations, range(throws)
    ):
        row = run_case(a, h, mu, order, rotation, seed)
        print_row(row)
        rows.append(row)
    summary(rows)
    return rows


if __name__ == "__main__":
    main()
