r"""Rigid bodies against their peers, in one run: a free asymmetric body and a 10-link chain.

Free body: :math:`J = \mathrm{diag}(2, 3, 4.5)`, :math:`\omega_0 = (0.4, 0.2, 1)` (body frame),
:math:`R_0 = I`; it turns about the major axis, :math:`|\Pi|^2/(2E) = 4.30` is far from the
intermediate moment 3 (the separatrix). Two studies:

1. **error at a fixed time** ``--t-error``: the body angular velocity against the exact
   solution (``galerkin_vi.problems.rigid_bodies.free_body_angular_velocity`` when it exists,
   else DOP853 at rtol = atol = 3e-14), for every h of ``--h`` and DOP853's tolerance sweep;
   then, from these work-precision points, the CPU time each family needs to reach an error
   target, as a ratio over the baseline (galerkin_vi's best when its rows are there, else the
   2nd-order LGVI);
2. **long run**: ``--n-steps`` steps (default 1e5) at every h: the largest relative errors of
   the energy :math:`\tfrac12\omega^\top J\omega` and of :math:`|J\omega|` (a Casimir), CPU
   time per step; DOP853 over ``n_steps * --dop-h`` time units at each tolerance.

Chain: ``--chain-links`` equal links (cylinders 0.5 m, 1 kg) on ball joints hanging under
gravity, contacts off (:class:`peers.mujoco_bodies.ChainSpec`); CPU time per step and the
largest energy error over ``--chain-steps`` steps for each MuJoCo integrator.

Peers: the LGVI of Lee, Leok & McClamroch (orders 2 and 4, ``peers/lgvi.py``), scipy DOP853 on
Euler's equations with quaternion kinematics (``peers/euler_dop853.py``) and MuJoCo's
integrators (``peers/mujoco_bodies.py``). galerkin_vi's rows (``gvi.RigidBody`` with
``rotation="quaternion"`` and ``"matrix"``, ``gvi.Galerkin(s)``, s = 1..4) appear once
``gvi.RigidBody`` exists; they plug in at :func:`galerkin_vi_free_body` and
:func:`galerkin_vi_chain`.

Usage::

    python benchmarks/rigid_body.py --quick --plot rigid_body.png
    python benchmarks/rigid_body.py --n-steps 100000 --chain-steps 100000
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from peers import mujoco_bodies as mjb  # noqa: E402
from peers.euler_dop853 import euler_dop853  # noqa: E402
from peers.lgvi import lgvi_free  # noqa: E402

import galerkin_vi as gvi  # noqa: E402
from galerkin_vi.tools import benchmark as bm  # noqa: E402

INERTIA = np.array([2.0, 3.0, 4.5])
OMEGA0 = np.array([0.4, 0.2, 1.0])
TARGETS = (1e-3, 1e-5, 1e-7, 1e-9)


@dataclass
class Row:
    """One run of one method: what the tables print."""

    family: str
    label: str
    setting: float  # h, or DOP853's rtol
    steps: int
    cpu: float
    work_per_step: float = math.nan  # Newton iterations or right-hand-side evaluations per step
    error: float = math.nan
    energy: float = math.nan
    casimir: float = math.nan
    message: str = ""
    extra: dict = field(default_factory=dict)

    @property
    def ns_per_step(self) -> float:
        return 1e9 * self.cpu / max(self.steps, 1)


# ------------------------------------------------------------------------------------ reference
def reference_omega(times: np.ndarray) -> tuple[np.ndarray, str]:
    """Body angular velocity of the free body at ``times``: the closed form, else tight DOP853."""
    try:
        from galerkin_vi.problems.rigid_bodies import free_body_angular_velocity
    except ImportError:
        ref = euler_dop853(
            INERTIA,
            OMEGA0,
            [1.0, 0.0, 0.0, 0.0],
            float(np.max(times)),
            rtol=3e-14,
            atol=3e-14,
            t_eval=np.asarray(times, dtype=float),
        )
        return ref.omega, "DOP853 at rtol = atol = 3e-14"
    omega = np.asarray(free_body_angular_velocity(INERTIA, OMEGA0, np.asarray(times)))
    return omega.reshape(len(np.atleast_1d(times)), 3), "closed form (Jacobi elliptic functions)"


def drifts(omega: np.ndarray) -> tuple[float, float]:
    """Largest relative errors of the energy and of :math:`|J\\omega|` along rows of omega."""
    energy = 0.5 * (omega**2) @ INERTIA
    casimir = np.linalg.norm(omega * INERTIA, axis=1)
    return (
        float(np.max(np.abs(energy / energy[0] - 1))),
        float(np.max(np.abs(casimir / casimir[0] - 1))),
    )


def save_stride(n_steps: int, rows: int = 2000) -> int:
    return max(1, n_steps // rows)


# ----------------------------------------------------------------------------- peers: free body
def lgvi_row(order: int, h: float, n_steps: int, save_every: int) -> tuple[Row, np.ndarray]:
    res = lgvi_free(INERTIA, np.eye(3), INERTIA * OMEGA0, h, n_steps, save_every, order=order)
    row = Row(
        "LGVI",
        f"LGVI order {order}",
        h,
        res.steps,
        res.cpu_time,
        res.iterations_per_step,
        message="" if res.success else res.message,
    )
    return row, res.omega


def mujoco_row(integrator: str, h: float, n_steps: int, save_every: int) -> tuple[Row, np.ndarray]:
    res = mjb.run_free_body(INERTIA, OMEGA0, h, n_steps, integrator, save_every=save_every)
    row = Row(
        "MuJoCo",
        f"MuJoCo {integrator}",
        h,
        res.steps,
        res.cpu_time,
        message="" if res.success else res.message,
    )
    return row, res.omega


def dop853_row(tol: float, t_final: float, t_eval: np.ndarray) -> tuple[Row, np.ndarray]:
    res = euler_dop853(
        INERTIA, OMEGA0, [1.0, 0.0, 0.0, 0.0], t_final, rtol=tol, atol=tol, t_eval=t_eval
    )
    # solve_ivp does not report its step count: the "steps" of a DOP853 row are its
    # right-hand-side evaluations (12 per step), so ns/step reads per evaluation
    row = Row(
        "DOP853",
        "scipy DOP853",
        tol,
        res.nfev,
        res.cpu_time,
        float(res.nfev),
        message="" if res.success else res.message,
    )
    return row, res.omega


# ------------------------------------------------------------------- galerkin_vi plug-in points
def galerkin_vi_free_body(
    rotation: str, s: int, h: float, n_steps: int, save_every: int
) -> tuple[Row, np.ndarray]:
    """galerkin_vi on the free body (``gvi.RigidBody``, ``gvi.Multibody``, ``gvi.Galerkin(s)``).

    The body starts at the origin at rest in translation, :math:`R_0 = I`, body angular
    velocity :data:`OMEGA0`; the returned angular velocity is the body frame's
    (``mb.motion(traj, "b").angular_velocity``). CPU time excludes a one-step warm-up run that
    compiles the system's point functions.
    """
    body = gvi.RigidBody("b", mass=1.0, inertia=list(INERTIA), rotation=rotation)
    mb = gvi.Multibody([body])
    q0, v0 = mb.state(
        positions={"b": [0.0, 0.0, 0.0]},
        rotations={"b": np.eye(3)},
        velocities={"b": [0.0, 0.0, 0.0]},
        angular_velocities={"b": OMEGA0},
        frame="body",
    )
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(s))
    integrator.integrate(q0, v0=v0, h=h, n_steps=1)
    start = time.process_time()
    traj = integrator.integrate(q0, v0=v0, h=h, n_steps=n_steps, save_every=save_every)
    cpu = time.process_time() - start
    omega = np.asarray(mb.motion(traj, "b").angular_velocity)
    row = Row(
        "galerkin_vi",
        f"galerkin_vi {rotation} s={s}",
        h,
        traj.n_steps,
        cpu,
        traj.mean_newton_iterations,
        message="" if traj.success else traj.message,
    )
    return row, omega


def galerkin_vi_configs() -> list[tuple[str, Callable[[float, int, int], tuple[Row, np.ndarray]]]]:
    """The galerkin_vi configurations of the free-body tables."""
    configs = []
    for rotation in ("quaternion", "matrix"):
        for s in (1, 2, 3, 4):
            configs.append(
                (
                    f"galerkin_vi {rotation} s={s}",
                    lambda h, n, k, r=rotation, s=s: galerkin_vi_free_body(r, s, h, n, k),
                )
            )
    return configs


def galerkin_vi_chain(
    spec: mjb.ChainSpec, s: int, h: float, n_steps: int, save_every: int, rotation: str
) -> Row:
    """galerkin_vi on the chain of ``spec``: links with ``rotation`` on ``joints.Spherical``.

    Link i's joint is at body point ``(0, 0, +l/2)`` from its centre of mass (its upper end)
    and link i+1 hangs from link i's ``(0, 0, -l/2)``; poses from
    :func:`peers.mujoco_bodies.chain_initial_poses`, all at rest; energy ``traj.energy()``.
    """
    half = spec.length / 2
    inertia = list(spec.principal_inertia())
    bodies = [
        gvi.RigidBody(f"l{i}", mass=spec.mass, inertia=inertia, rotation=rotation)
        for i in range(spec.n_links)
    ]
    joints = [
        gvi.joints.Spherical(None, bodies[0], point_a=[0.0, 0.0, 0.0], point_b=[0.0, 0.0, half])
    ]
    joints += [
        gvi.joints.Spherical(
            bodies[i], bodies[i + 1], point_a=[0.0, 0.0, -half], point_b=[0.0, 0.0, half]
        )
        for i in range(spec.n_links - 1)
    ]
    mb = gvi.Multibody(bodies, joints=joints, gravity=list(spec.gravity))
    poses = mjb.chain_initial_poses(spec)
    names = [b.name if hasattr(b, "name") else f"l{i}" for i, b in enumerate(bodies)]
    zero = [0.0, 0.0, 0.0]
    q0, v0 = mb.state(
        positions=dict(zip(names, poses["com"], strict=True)),
        rotations=dict(zip(names, poses["rotation"], strict=True)),
        velocities={n: zero for n in names},
        angular_velocities={n: zero for n in names},
        frame="body",
    )
    integrator = gvi.Integrator(mb.system, gvi.Galerkin(s))
    integrator.integrate(q0, v0=v0, h=h, n_steps=1)
    start = time.process_time()
    traj = integrator.integrate(q0, v0=v0, h=h, n_steps=n_steps, save_every=save_every)
    cpu = time.process_time() - start
    energy = traj.energy()
    return Row(
        "galerkin_vi",
        f"galerkin_vi {rotation} s={s}",
        h,
        traj.n_steps,
        cpu,
        traj.mean_newton_iterations,
        energy=float(np.max(np.abs(energy - energy[0]))),
        message="" if traj.success else traj.message,
        extra={"energy0": float(energy[0])},
    )


# ------------------------------------------------------------------------------------- studies
def fixed_step_configs(orders: Sequence[int]) -> list[tuple[str, Callable]]:
    configs: list[tuple[str, Callable]] = [
        (f"LGVI order {o}", lambda h, n, k, o=o: lgvi_row(o, h, n, k)) for o in orders
    ]
    configs += [
        (f"MuJoCo {name}", lambda h, n, k, name=name: mujoco_row(name, h, n, k))
        for name in mjb.available_integrators()
    ]
    return configs + galerkin_vi_configs()


def _guarded(label: str, fn: Callable[[], tuple[Row, np.ndarray]]) -> tuple[Row, np.ndarray] | None:
    """Run one configuration; a failure is printed and the configuration skipped."""
    try:
        return fn()
    except Exception as exc:  # a peer's failure must not end the benchmark
        print(f"  {label}: skipped ({type(exc).__name__}: {exc})", flush=True)
        return None


def error_study(
    hs: Sequence[float], tols: Sequence[float], t_error: float, configs: list[tuple[str, Callable]]
) -> tuple[list[Row], str]:
    """Every configuration at every h (and DOP853 at every tol) to ``t_error``: error there."""
    omega_ref, source = reference_omega(np.array([0.0, t_error]))
    rows = []
    for label, run in configs:
        for h in hs:
            n = int(round(t_error / h))
            out = _guarded(label, lambda run=run, h=h, n=n: run(t_error / n, n, n))
            if out is not None:
                row, omega = out
                failed = bool(row.message)  # a failed run has no state at t_error
                row.error = math.nan if failed else float(np.max(np.abs(omega[-1] - omega_ref[-1])))
                rows.append(row)
    for tol in tols:
        row, omega = dop853_row(tol, t_error, np.array([0.0, t_error]))
        row.error = float(np.max(np.abs(omega[-1] - omega_ref[-1])))
        rows.append(row)
    return rows, source


def long_study(
    hs: Sequence[float],
    tols: Sequence[float],
    n_steps: int,
    dop_h: float,
    configs: list[tuple[str, Callable]],
) -> list[Row]:
    """``n_steps`` steps at every h: the largest energy and Casimir errors; DOP853 to n h_dop."""
    rows = []
    k = save_stride(n_steps)
    for label, run in configs:
        for h in hs:
            out = _guarded(label, lambda run=run, h=h: run(h, n_steps, k))
            if out is not None:
                row, omega = out
                row.energy, row.casimir = drifts(omega)
                rows.append(row)
    t_final = n_steps * dop_h
    for tol in tols:
        row, omega = dop853_row(tol, t_final, np.linspace(0.0, t_final, 2001))
        row.energy, row.casimir = drifts(omega)
        row.extra["t_final"] = t_final
        rows.append(row)
    return rows


def chain_study(
    spec: mjb.ChainSpec, hs: Sequence[float], n_steps: int, gvi_degrees: Sequence[int]
) -> list[Row]:
    """MuJoCo's integrators (and galerkin_vi when it has multibody) on the chain."""
    rows = []
    k = save_stride(n_steps, 1000)
    for h in hs:
        for name in mjb.available_integrators():
            res = mjb.run_chain(spec, h, n_steps, name, save_every=k)
            rows.append(
                Row(
                    "MuJoCo",
                    f"MuJoCo {name}",
                    h,
                    res.steps,
                    res.cpu_time,
                    energy=res.max_energy_error,
                    message="" if res.success else res.message,
                    extra={"energy0": float(res.energy[0])},
                )
            )
        for rotation in ("quaternion", "matrix"):
            for s in gvi_degrees:
                rows.append(galerkin_vi_chain(spec, s, h, n_steps, k, rotation))
    return rows


# -------------------------------------------------------------------------------------- output
def _fmt(x: float) -> str:
    return "—" if not math.isfinite(x) else f"{x:.2e}"


def print_table(title: str, header: Sequence[str], lines: list[Sequence[str]]) -> None:
    print(f"\n## {title}\n")
    print("| " + " | ".join(header) + " |")
    print("|" + "---|" * len(header))
    for line in lines:
        print("| " + " | ".join(line) + " |")


def setting_label(row: Row) -> str:
    return f"tol {row.setting:.0e}" if row.family == "DOP853" else f"h {row.setting:g}"


def work_label(row: Row) -> str:
    if not math.isfinite(row.work_per_step):
        return ""
    if row.family == "DOP853":
        return f"{row.work_per_step:.0f} f-evals in all"
    return f"{row.work_per_step:.2f} Newton it."


def time_to_error_table(rows: list[Row], targets: Sequence[float]) -> None:
    """CPU time to reach each error target per configuration, and its ratio over the baseline."""
    curves: dict[str, list[dict]] = {}
    for row in rows:
        curves.setdefault(row.label, []).append({"time": row.cpu, "error": row.error})
    times = {label: {t: bm.time_to_error(pts, t) for t in targets} for label, pts in curves.items()}
    gvi_labels = [label for label in curves if label.startswith("galerkin_vi")]

    def baseline(target: float) -> tuple[str, float] | None:
        pool = gvi_labels or [label for label in curves if label.startswith("LGVI")]
        found = [(times[lb][target]["time"], lb) for lb in pool if times[lb][target] is not None]
        return None if not found else min(found)[::-1]

    base = {t: baseline(t) for t in targets}
    lines = []
    for label in curves:
        cells = [label]
        for t in targets:
            entry, ref = times[label][t], base[t]
            if entry is None:
                cells.append("—")
            elif ref is None:
                cells.append(f"{entry['time']:.2e} s")
            else:
                bound = "≤" if entry["bound"] else ""
                cells.append(f"{bound}{entry['time']:.2e} s ({entry['time'] / ref[1]:.3g})")
        lines.append(cells)
    who = "the fastest galerkin_vi configuration" if gvi_labels else "the fastest LGVI"
    print_table(
        f"Free body: CPU time to reach the error (ratio over {who} at the same error)",
        ["configuration"] + [f"err ≤ {t:.0e}" for t in targets],
        lines,
    )
    named = ", ".join(f"{t:.0e}: {b[0]}" for t, b in base.items() if b is not None)
    print(f"\nbaseline per target: {named}")


def _style(label: str, index: int) -> dict:
    """galerkin_vi solid (quaternion) or dash-dotted (matrix), peers dashed; colours by family."""
    import matplotlib.pyplot as plt

    colours = plt.get_cmap("tab20").colors
    if label.startswith("galerkin_vi"):
        return {"ls": "-" if "quaternion" in label else "-.", "color": colours[index % 20]}
    return {"ls": "--", "color": colours[index % 20], "marker": "s"}


def plot(path: str, err_rows: list[Row], long_rows: list[Row]) -> None:
    """Work–precision of the free body, and the energy error of the long runs against h:
    runs that failed (MuJoCo's unstable ones) are left out, not drawn at zero."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(13, 5.5))
    labels = list(dict.fromkeys(r.label for r in err_rows + long_rows))
    for label in labels:
        style = {"marker": "o", "ms": 4, **_style(label, labels.index(label))}
        pts = sorted(
            (r.cpu, r.error) for r in err_rows if r.label == label and r.error > 0 and not r.message
        )
        if pts:
            ax1.loglog(*zip(*pts, strict=True), label=label, **style)
        pts = sorted(
            (r.setting, r.energy)
            for r in long_rows
            if r.label == label and r.family != "DOP853" and r.energy > 0 and not r.message
        )
        if pts:
            ax2.loglog(*zip(*pts, strict=True), label=label, **style)
    ax1.set_xlabel("CPU seconds")
    ax1.set_ylabel("max |ω − ω_exact| at t_error")
    ax1.set_title("free body: error against CPU time (lower left is better)")
    ax1.grid(True, which="major", alpha=0.3)
    ax2.set_xlabel("h")
    ax2.set_ylabel("max relative energy error over the run")
    ax2.set_title("free body: energy error over the long run")
    ax2.grid(True, which="major", alpha=0.3)
    # one legend for both panels: DOP853 is on the left only (its energy is over time, not h)
    handles = {}
    for ax in (ax1, ax2):
        for handle, label in zip(*ax.get_legend_handles_labels(), strict=True):
            handles.setdefault(label, handle)
    ax2.legend(handles.values(), handles.keys(), fontsize=7, loc="center left",
               bbox_to_anchor=(1.01, 0.5))  # fmt: skip
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"\nwrote {path}")


# ------------------------------------------------------------------------------------------ main
def parse_args(argv: Sequence[str] | None = None) -> argparse.Namespace:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--quick",
        action="store_true",
        help="short run: 1e4 steps, coarse grids, 2000 chain steps (about a minute)",
    )
    p.add_argument("--h", type=float, nargs="+", default=None, help="step sizes (free body)")
    p.add_argument("--tols", type=float, nargs="+", default=None, help="DOP853 tolerances")
    p.add_argument("--t-error", type=float, default=20.0, help="time of the error comparison")
    p.add_argument("--n-steps", type=int, default=None, help="steps of the long run (1e5)")
    p.add_argument(
        "--dop-h",
        type=float,
        default=0.01,
        help="DOP853's long run spans n_steps * dop_h time units",
    )
    p.add_argument("--orders", type=int, nargs="+", default=[2, 4], help="LGVI orders")
    p.add_argument("--chain-links", type=int, default=10)
    p.add_argument("--chain-h", type=float, nargs="+", default=[1e-3, 1e-2])
    p.add_argument("--chain-steps", type=int, default=None, help="chain steps (1e5)")
    p.add_argument(
        "--chain-degrees",
        type=int,
        nargs="+",
        default=[1, 2],
        help="galerkin_vi degrees on the chain",
    )
    p.add_argument("--no-chain", action="store_true")
    p.add_argument("--plot", metavar="PATH", default=None, help="write a PNG there")
    args = p.parse_args(argv)
    if args.h is None:
        args.h = [0.1, 0.05, 0.02, 0.01] if args.quick else [0.2, 0.1, 0.05, 0.02, 0.01, 0.005]
    if args.tols is None:
        exps = range(-4, -13, -2) if args.quick else range(-3, -14, -1)
        args.tols = [10.0**e for e in exps]
    if args.n_steps is None:
        args.n_steps = 10_000 if args.quick else 100_000
    if args.chain_steps is None:
        args.chain_steps = 2_000 if args.quick else 100_000
    return args


def main(argv: Sequence[str] | None = None) -> int:
    args = parse_args(argv)
    start = time.perf_counter()
    configs = fixed_step_configs(args.orders)
    print(
        "(DOP853 rows: steps = right-hand-side evaluations, ns/step = ns per evaluation; "
        "work: Newton iterations per step, or DOP853's evaluations)"
    )
    print(f"# Rigid bodies: J = {INERTIA.tolist()}, omega0 = {OMEGA0.tolist()}")

    err_rows, source = error_study(args.h, args.tols, args.t_error, configs)
    print_table(
        f"Free body: error of ω at t = {args.t_error:g} (reference: {source})",
        ["configuration", "h / tol", "steps", "max |ω − ω_ref|", "CPU s", "ns/step", "work"],
        [
            [
                r.label,
                setting_label(r),
                str(r.steps),
                _fmt(r.error),
                f"{r.cpu:.3g}",
                f"{r.ns_per_step:.0f}",
                work_label(r) + (f" {r.message}" if r.message else ""),
            ]
            for r in err_rows
        ],
    )
    time_to_error_table(err_rows, TARGETS)

    long_rows = long_study(args.h, args.tols, args.n_steps, args.dop_h, configs)
    print_table(
        f"Free body: {args.n_steps} steps at each h (DOP853: t in [0, "
        f"{args.n_steps * args.dop_h:g}]); relative errors, largest over the run",
        ["configuration", "h / tol", "steps", "energy", "|Jω|", "CPU s", "ns/step", "work"],
        [
            [
                r.label,
                setting_label(r),
                str(r.steps),
                _fmt(r.energy),
                _fmt(r.casimir),
                f"{r.cpu:.3g}",
                f"{r.ns_per_step:.0f}",
                work_label(r) + (f" {r.message}" if r.message else ""),
            ]
            for r in long_rows
        ],
    )

    if not args.no_chain:
        spec = mjb.ChainSpec(n_links=args.chain_links)
        chain_rows = chain_study(spec, args.chain_h, args.chain_steps, args.chain_degrees)
        e0 = chain_rows[0].extra["energy0"] if chain_rows else math.nan
        print_table(
            f"Chain of {spec.n_links} links on ball joints: {args.chain_steps} steps "
            f"(E0 = {e0:.4g} J)",
            [
                "configuration",
                "h",
                "steps",
                "max |E − E0| (J)",
                "relative to |E0|",
                "CPU s",
                "µs/step",
                "work/step",
            ],
            [
                [
                    r.label,
                    f"{r.setting:g}",
                    str(r.steps),
                    _fmt(r.energy),
                    _fmt(r.energy / abs(r.extra.get("energy0", e0))),
                    f"{r.cpu:.3g}",
                    f"{r.ns_per_step / 1e3:.2f}",
                    work_label(r) + (f" {r.message}" if r.message else ""),
                ]
                for r in chain_rows
            ],
        )
    if args.plot:
        plot(args.plot, err_rows, long_rows)
    print(f"\nfinished in {time.perf_counter() - start:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
