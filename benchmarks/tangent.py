r"""The tangent map's cost, the adjoint gradient's cost and memory, and MEGNO against REBOUND.

Three parts (issue 28, "Targets"), each measured in this process with the things
compared interleaved, best of ``--repeats`` CPU times: only the ratios compare
across machines.

``cost``
    Per step: the plain run (``integrate`` with the system's fastest loop), the
    tangent loop with r = 1, 2 and 2n directions (``tangent=V``, the last
    ``tangent=True``: the full :math:`\Phi`). The marginal cost of a direction is
    :math:`(T(r) - T(1))/(r - 1)`, reported relative to the plain step (target
    :math:`\le 0.5`), and the full :math:`\Phi` relative to the plain run (target
    :math:`\le 4` for n = 3). Newton iterations per step beside the times.
``gradient``
    ``gvi.gradient`` of a terminal loss against the plain forward run for
    N = 10³, 10⁴, 10⁵ steps, recorded whole (the default while the record fits in
    32 MiB) and with checkpoints every 4⌈√N⌉ steps: the time ratio
    (target :math:`\le 3`) and the peak of the memory Python and NumPy allocate
    (``tracemalloc``) against :math:`\sqrt N`.
``megno``
    A star with two planets (masses 10⁻³ and 3·10⁻⁴ of the star, period ratio
    2.4: between the 7:3 and 5:2 resonances, a regular orbit) over 10⁴ inner
    orbits: REBOUND's ``init_megno`` with WHFast at ``--rebound-step`` of the
    inner period, and galerkin_vi's ``tangent=V, renormalize_every=1`` from the
    same initial deviation, the method and step chosen on a probe run as the
    cheapest reaching REBOUND's energy error. Both MEGNO values (galerkin_vi's in
    its own norm of :math:`(\delta q, \delta p)` and recomputed in REBOUND's norm of
    :math:`(\delta x, \delta v)` from the saved deviations), CPU times and their ratio.

Usage::

    python benchmarks/tangent.py                          # all three parts
    python benchmarks/tangent.py --parts cost --repeats 9 --json tangent.json
    python benchmarks/tangent.py --parts megno --plot megno.png
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import tracemalloc
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.problems import chains, mechanics

PARTS = ("cost", "gradient", "megno")


def _clock(fn: Callable[[], object]) -> float:
    # CPU time of this process: a shared machine's other tenants steal wall time
    start = time.process_time()
    fn()
    return time.process_time() - start


def _best_interleaved(runs: dict[str, Callable[[], object]], repeats: int) -> dict[str, float]:
    """The best CPU time of each run, the runs taking turns within every repeat."""
    best = dict.fromkeys(runs, math.inf)
    for _ in range(repeats):
        for name, fn in runs.items():
            best[name] = min(best[name], _clock(fn))
    return best


# ----------------------------------------------------------------------- systems
@dataclass(frozen=True)
class Case:
    """A system, its start and the run of the cost part."""

    name: str
    system: gvi.LagrangianSystem
    q0: np.ndarray
    v0: np.ndarray
    h: float
    params: dict | None = None


def triple_pendulum() -> gvi.LagrangianSystem:
    r"""Three unit masses on unit rods in absolute angles: non-separable, n = 3.

    .. math:: L = \sum_i \tfrac12 |\dot r_i|^2 + g \sum_i \sum_{j \le i} \cos\theta_j,
        \quad r_i = \sum_{j\le i} (\sin\theta_j, -\cos\theta_j).
    """
    th = sp.symbols("theta1:4")
    om = sp.symbols("omega1:4")
    g = sp.Symbol("g", positive=True)
    kinetic = 0
    potential = 0
    for i in range(3):
        vx = sum(sp.cos(th[j]) * om[j] for j in range(i + 1))
        vy = sum(sp.sin(th[j]) * om[j] for j in range(i + 1))
        kinetic += (vx**2 + vy**2) / 2
        potential -= g * sum(sp.cos(th[j]) for j in range(i + 1))
    return gvi.LagrangianSystem(
        sp.expand(sp.trigsimp(sp.expand(kinetic))) - potential, list(th), list(om), params={g: 1.0}
    )


def cost_cases() -> list[Case]:
    dp = mechanics.double_pendulum()
    chain = chains.spring_chain(20, beta=1.0)
    return [
        Case("double pendulum", dp.system, dp.q0, dp.v0, 0.01, dp.params),
        Case(
            "triple pendulum",
            triple_pendulum(),
            np.array([0.6, 0.3, -0.2]),
            np.array([0.0, 0.2, 0.1]),
            0.01,
        ),  # fmt: skip
        Case("FPU chain N=20", chain.system, chain.q0, chain.v0, 0.05, chain.params),
    ]


# -------------------------------------------------------------------- part: cost
def cost_row(case: Case, method: gvi.Galerkin, seconds: float, repeats: int) -> dict:
    """Per-step times of the plain run and the tangent loop with r = 1, 2, 2n directions."""
    integ = gvi.Integrator(case.system, method)
    general = gvi.Integrator(case.system, method, specialize=False)
    n = case.system.n
    rng = np.random.default_rng(1)
    V = rng.standard_normal((2 * n, 2))

    def run(n_steps: int, tangent=None):
        return integ.integrate(case.q0, v0=case.v0, h=case.h, n_steps=n_steps, save_every=n_steps,
                               params=case.params, tangent=tangent)  # fmt: skip

    def run_general(n_steps: int):
        return general.integrate(case.q0, v0=case.v0, h=case.h, n_steps=n_steps,
                                 save_every=n_steps, params=case.params)  # fmt: skip

    variants = {"plain": None, "r=1": V[:, :1], "r=2": V, f"r={2 * n}": True}
    for tangent in variants.values():
        run(20, tangent)  # compiled and cached
    run_general(20)
    probe = 200
    n_steps = int(min(200_000, max(500, probe * seconds / max(_clock(lambda: run(probe)), 1e-9))))
    runs = {k: (lambda tg=tg: run(n_steps, tg)) for k, tg in variants.items()}
    runs["general"] = lambda: run_general(n_steps)
    best = _best_interleaved(runs, repeats)
    ns = {k: 1e9 * t / n_steps for k, t in best.items()}
    plain, one, two, full = ns["plain"], ns["r=1"], ns["r=2"], ns[f"r={2 * n}"]
    newton = ns["general"]
    marginal = (full - one) / (2 * n - 1)
    return {
        "system": case.name,
        "n": n,
        "loop": integ.kernel_path,
        "banded": bool(integ.uses_banded_storage),
        "h": case.h,
        "n_steps": n_steps,
        "plain_ns": plain,
        "r1_ns": one,
        "r2_ns": two,
        "full_ns": full,
        "newton_ns": newton,
        "plain_iterations": run(n_steps).mean_newton_iterations,
        "newton_iterations": run_general(n_steps).mean_newton_iterations,
        "tangent_iterations": run(n_steps, V[:, :1]).mean_newton_iterations,
        "per_direction_r2": (two - one) / plain,
        "per_direction": marginal / plain,
        "base_over_plain": (one - marginal) / plain,
        "full_over_plain": full / plain,
        "per_direction_newton": marginal / newton,
        "full_over_newton": full / newton,
    }


def part_cost(args) -> list[dict]:
    method = gvi.Galerkin(2, gvi.gauss_legendre(2))
    header = (
        f"{'system':16s} {'n':>3s} {'loop':8s} {'plain ns':>9s} {'its':>5s} {'r=1 ns':>9s}"
        f" {'its':>5s} {'r=2 ns':>9s} {'2n ns':>9s} {'dir/step':>8s} {'(r=2)':>6s}"
        f" {'base/step':>9s} {'Phi/plain':>9s} {'newton ns':>9s} {'its':>5s} {'dir/N':>6s}"
        f" {'Phi/N':>6s}"
    )
    print(f"\n## Cost of the tangent map, Gauss(2) (s = 2), best of {args.repeats}\n")
    print(header)
    print("-" * len(header))
    rows = []
    for case in cost_cases():
        r = cost_row(case, method, args.seconds, args.repeats)
        rows.append(r)
        print(
            f"{r['system']:16s} {r['n']:3d} {r['loop']:8s} {r['plain_ns']:9.0f}"
            f" {r['plain_iterations']:5.2f} {r['r1_ns']:9.0f} {r['tangent_iterations']:5.2f}"
            f" {r['r2_ns']:9.0f} {r['full_ns']:9.0f} {r['per_direction']:8.2f}"
            f" {r['per_direction_r2']:6.2f} {r['base_over_plain']:9.2f}"
            f" {r['full_over_plain']:9.2f} {r['newton_ns']:9.0f} {r['newton_iterations']:5.2f}"
            f" {r['per_direction_newton']:6.2f} {r['full_over_newton']:6.2f}",
            flush=True,
        )
    print(
        "\ndir/step: (T(2n) - T(1)) / (2n - 1) over the plain step, (r=2): T(2) - T(1) over it;"
        "\nbase/step: the tangent loop without directions (T(1) - one direction) over the plain"
        " step;\nPhi/plain: T(2n) / plain. its: mean Newton iterations per step (sweeps on the"
        " separable loop);\nnewton: the general Newton loop (specialize=False), the loop the"
        " tangent loop extends; dir/N, Phi/N: over it."
    )
    return rows


# ---------------------------------------------------------------- part: gradient
def _traced_peak(fn: Callable[[], object]) -> int:
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def part_gradient(args) -> list[dict]:
    problem = mechanics.double_pendulum()
    system = problem.system
    integ = gvi.Integrator(system, gvi.Galerkin(2, gvi.gauss_legendre(2)))
    th1, th2 = system.q
    loss = gvi.Loss(terminal=sp.cos(th1) + th2**2)
    h = 0.01
    common = dict(h=h, params=problem.params)

    def forward(n_steps: int):
        return integ.integrate(problem.q0, v0=problem.v0, n_steps=n_steps, save_every=n_steps,
                               **common)  # fmt: skip

    def adjoint(n_steps: int, segment: int | None = None):
        return gvi.gradient(integ, loss, problem.q0, problem.v0, n_steps=n_steps,
                            wrt=("q0", "v0"), checkpoint_every=segment, **common)  # fmt: skip

    def forward_saved(n_steps: int):
        return integ.integrate(problem.q0, v0=problem.v0, n_steps=n_steps, **common)

    adjoint(30)
    print(f"\n## Gradient by the adjoint, double pendulum, Gauss(2), h = {h}, best of "
          f"{args.repeats}\n")  # fmt: skip
    header = (
        f"{'N':>7s} {'segment':>7s} {'forward s':>10s} {'gradient s':>10s} {'ratio':>6s}"
        f" {'peak MB':>8s} {'peak/sqrtN kB':>13s} {'all rows MB':>11s}"
    )
    print(header)
    print("-" * len(header))
    rows = []
    for n_steps in args.gradient_steps:
        reps = max(1, args.repeats if n_steps <= 10_000 else min(args.repeats, 3))
        # the default (recorded whole while the record fits in RECORD_BYTES), and
        # checkpoints every 4 ceil(sqrt N) steps (what longer runs take)
        checkpointed = 4 * (math.isqrt(n_steps - 1) + 1)
        for segment in (None, checkpointed) if checkpointed < n_steps else (None,):
            best = _best_interleaved(
                {
                    "forward": partial(forward, n_steps),
                    "gradient": partial(adjoint, n_steps, segment),
                },
                reps,
            )
            peak = _traced_peak(partial(adjoint, n_steps, segment))
            saved_peak = _traced_peak(partial(forward_saved, n_steps))
            result = adjoint(n_steps, segment)
            shown = n_steps if segment is None else segment
            r = {
                "n_steps": n_steps,
                "segment": shown,
                "forward_s": best["forward"],
                "gradient_s": best["gradient"],
                "ratio": best["gradient"] / best["forward"],
                "peak_bytes": peak,
                "forward_all_rows_peak_bytes": saved_peak,
                "success": bool(result.success),
            }
            rows.append(r)
            print(
                f"{n_steps:7d} {shown:7d} {r['forward_s']:10.4f} {r['gradient_s']:10.4f}"
                f" {r['ratio']:6.2f} {peak / 1e6:8.2f} {peak / math.sqrt(n_steps) / 1e3:13.2f}"
                f" {saved_peak / 1e6:11.2f}",
                flush=True,
            )
    print(
        "\npeak: tracemalloc's peak during one gvi.gradient call (NumPy arrays included);"
        "\nall rows: the peak of a forward run that saves every step, for comparison."
    )
    return rows


# ------------------------------------------------------------------- part: megno
STAR, INNER, OUTER = 1.0, 1e-3, 3e-4
A_INNER, A_OUTER = 1.0, 1.0 * 2.4 ** (2 / 3)  # period ratio 2.4
ECC_INNER, ECC_OUTER = 0.02, 0.03


def two_planet_system() -> gvi.LagrangianSystem:
    r"""A star and two planets in the plane, barycentric Cartesian coordinates, G = 1.

    .. math:: L = \sum_i \tfrac12 m_i |\dot r_i|^2 + \sum_{i<j} \frac{m_i m_j}{|r_i - r_j|}
    """
    m = sp.symbols("m0:3", positive=True)
    q = sp.symbols("x0 y0 x1 y1 x2 y2")
    v = sp.symbols("vx0 vy0 vx1 vy1 vx2 vy2")
    terms = [m[i] * (v[2 * i] ** 2 + v[2 * i + 1] ** 2) / 2 for i in range(3)]
    for i in range(3):
        for j in range(i + 1, 3):
            r2 = (q[2 * i] - q[2 * j]) ** 2 + (q[2 * i + 1] - q[2 * j + 1]) ** 2
            terms.append(m[i] * m[j] / sp.sqrt(r2))
    return gvi.LagrangianSystem(
        sp.Add(*terms), list(q), list(v), params=dict(zip(m, (STAR, INNER, OUTER), strict=True))
    )


def rebound_simulation(dt: float, integrator: str = "whfast"):
    """The REBOUND twin: the same bodies, moved to the barycentre, MEGNO on."""
    import rebound

    sim = rebound.Simulation()
    sim.G = 1.0
    sim.add(m=STAR)
    sim.add(m=INNER, a=A_INNER, e=ECC_INNER, f=0.0, omega=0.0)
    sim.add(m=OUTER, a=A_OUTER, e=ECC_OUTER, f=2.0, omega=1.0)
    sim.move_to_com()
    sim.integrator = integrator
    sim.dt = dt
    sim.init_megno(seed=7)
    # a planar deviation: the z parts of REBOUND's random one set to 0
    for particle in sim.var_config[0].particles:
        particle.z = 0.0
        particle.vz = 0.0
    return sim


def rebound_state(sim) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(x, v) of the three bodies and (dx, dv) of the variation, planar, flat."""
    ps = sim.particles
    var = sim.var_config[0].particles
    x = np.array([[ps[i].x, ps[i].y] for i in range(3)]).ravel()
    v = np.array([[ps[i].vx, ps[i].vy] for i in range(3)]).ravel()
    dx = np.array([[var[i].x, var[i].y] for i in range(3)]).ravel()
    dv = np.array([[var[i].vx, var[i].vy] for i in range(3)]).ravel()
    return x, v, dx, dv


def rebound_run(dt: float, t_end: float, samples: int) -> dict:
    """REBOUND's MEGNO at t_end, its CPU time (one call) and its energy error (sampled)."""
    sim = rebound_simulation(dt)
    cpu = _clock(lambda: sim.integrate(t_end, exact_finish_time=0))
    megno = sim.megno()
    sampled = rebound_simulation(dt)
    e0 = sampled.energy()
    err = 0.0
    for t in np.linspace(t_end / samples, t_end, samples):
        sampled.integrate(t, exact_finish_time=0)
        err = max(err, abs(sampled.energy() / e0 - 1.0))
    x, _, _, _ = rebound_state(sim)
    return {"megno": megno, "cpu_s": cpu, "energy_error": err, "t": sim.t,
            "steps": int(round(sim.t / dt)), "x": x}  # fmt: skip


def reference_run(t_end: float) -> dict:
    """IAS15 (adaptive, to round-off) to exactly t_end: the reference orbit and MEGNO."""
    sim = rebound_simulation(1e-3, "ias15")
    cpu = _clock(lambda: sim.integrate(t_end))
    x, _, _, _ = rebound_state(sim)
    return {"megno": sim.megno(), "cpu_s": cpu, "x": x, "steps": sim.steps_done}


def position_error(x: np.ndarray, ref: np.ndarray) -> float:
    """The largest distance of a planet from its reference position."""
    d = (x - ref).reshape(3, 2)[1:]
    return float(np.max(np.hypot(d[:, 0], d[:, 1])))


def energy_error(traj) -> float:
    e = traj.energy()
    return float(np.max(np.abs(e / e[0] - 1.0)))


def megno_of_deviations(t: np.ndarray, norms: np.ndarray) -> tuple[float, float]:
    r"""MEGNO's discrete form from the deviation's norms at every step (the loop's formula):
    :math:`Y_N = \frac{2}{t_N} \sum_{k<N} t_{k+1} \log(\|\delta_{k+1}\|/\|\delta_k\|)`,
    :math:`\bar Y_N = \frac1N\sum_{k=1}^N Y_k`. Returns :math:`(Y_N, \bar Y_N)`."""
    tt = t - t[0]
    increments = tt[1:] * np.diff(np.log(norms))
    y = 2.0 * np.cumsum(increments) / tt[1:]
    return float(y[-1]), float(y.mean())


def megno_methods() -> list[tuple[str, object]]:
    """(name, method) of the MEGNO candidates: Gauss(2-4) (the tangent on the general
    Newton loop) and compositions of Störmer–Verlet of orders 4-8 (the explicit tangent
    loop)."""
    gauss = [(f"Gauss({s})", gvi.Galerkin(s, gvi.gauss_legendre(s))) for s in (2, 3, 4)]
    composed = [(f"Composition({p})", gvi.Composition(p)) for p in (4, 6, 8)]
    return gauss + composed


def part_megno(args) -> dict:
    import rebound

    period = 2 * math.pi * math.sqrt(A_INNER**3 / (STAR + INNER))
    t_end = args.orbits * period
    dt = period * args.rebound_step
    reb = rebound_run(dt, t_end, 100)
    ref = reference_run(t_end)
    # WHFast's last step may overshoot t_end: its reference is REBOUND's end time
    ref_reb = ref if abs(reb["t"] - t_end) < 1e-9 * t_end else reference_run(reb["t"])
    # galerkin_vi's start: REBOUND's barycentric bodies and deviation, p = m v
    sim0 = rebound_simulation(dt)
    x0, v0, dx0, dv0 = rebound_state(sim0)
    masses = np.repeat([STAR, INNER, OUTER], 2)
    direction = np.r_[dx0, masses * dv0][:, None]
    system = two_planet_system()
    # the probe: REBOUND's energy and position errors over probe_orbits, against IAS15
    probe_reb = rebound_run(dt, args.probe_orbits * period, 20)
    probe_dr = position_error(probe_reb["x"], reference_run(probe_reb["t"])["x"])
    probe_ref = reference_run(args.probe_orbits * period)["x"]
    candidates = []
    for s, method in megno_methods():
        integ = gvi.Integrator(system, method)
        for per_orbit in (10, 20, 40, 80, 160, 320):
            h = period / per_orbit
            n_probe = args.probe_orbits * per_orbit
            traj = integ.integrate(x0, v0=v0, h=h, n_steps=n_probe, save_every=per_orbit // 10)
            err = energy_error(traj)
            dr = position_error(traj.q[-1], probe_ref)
            if err <= probe_reb["energy_error"] and dr <= probe_dr:
                cost = min(_clock(lambda integ=integ, h=h, n=n_probe: integ.integrate(
                    x0, v0=v0, h=h, n_steps=n, save_every=n, tangent=direction,
                    renormalize_every=1)) for _ in range(3))  # fmt: skip
                candidates.append((cost, s, per_orbit, err, dr))
                break  # a smaller step of the same degree costs more
    candidates.sort()
    if not candidates:
        raise RuntimeError("no galerkin_vi method reaches REBOUND's energy error on the probe")
    _, s, per_orbit, _, _ = candidates[0]
    integ = gvi.Integrator(system, dict(megno_methods())[s])
    h = period / per_orbit
    n_steps = int(round(t_end / h))

    def gvi_megno():
        return integ.integrate(x0, v0=v0, h=h, n_steps=n_steps, save_every=n_steps,
                               tangent=direction, renormalize_every=1)  # fmt: skip

    def reb_megno():
        sim = rebound_simulation(dt)
        sim.integrate(t_end, exact_finish_time=0)
        return sim

    def gvi_plain():
        return integ.integrate(x0, v0=v0, h=h, n_steps=n_steps, save_every=n_steps)

    best = _best_interleaved(
        {"gvi": gvi_megno, "rebound": reb_megno, "plain": gvi_plain}, args.megno_repeats
    )
    fast = gvi_megno()
    # the same run saving every step: the deviation delta_k = exp(log growth) * frame column
    every = integ.integrate(x0, v0=v0, h=h, n_steps=n_steps, save_every=1,
                            tangent=direction, renormalize_every=1)  # fmt: skip
    var = every.variations
    delta = var.tangent[:, :, 0] * np.exp(var.log_growth[:, :1])
    n = system.n
    reb_norm = np.sqrt(np.sum(delta[:, :n] ** 2, axis=1)
                       + np.sum((delta[:, n:] / masses) ** 2, axis=1))  # fmt: skip
    y_reb_norm, mean_reb_norm = megno_of_deviations(every.t, reb_norm)
    result = {
        "orbits": args.orbits,
        "t_end": t_end,
        "rebound": {"integrator": "whfast", "dt": dt, "steps": reb["steps"],
                    "megno": reb["megno"], "cpu_s": best["rebound"],
                    "energy_error": reb["energy_error"], "version": rebound.__version__,
                    "position_error": position_error(reb["x"], ref_reb["x"])},
        "ias15": {"megno": ref["megno"], "cpu_s": ref["cpu_s"], "steps": ref["steps"]},
        "gvi": {"method": s, "h": h, "steps_per_orbit": per_orbit,
                "steps": n_steps, "megno_mean": float(fast.variations.megno_mean[-1]),
                "megno_mean_rebound_norm": mean_reb_norm, "megno_y_rebound_norm": y_reb_norm,
                "cpu_s": best["gvi"], "plain_cpu_s": best["plain"],
                "plain_loop": integ.kernel_path, "energy_error": energy_error(every),
                "position_error": position_error(every.q[-1], ref["x"]),
                "mean_newton_iterations": fast.mean_newton_iterations},
        "probe": {"orbits": args.probe_orbits, "rebound_energy_error": probe_reb["energy_error"],
                  "rebound_position_error": probe_dr},
        "candidates": [{"cpu_probe_s": c, "s": ss, "steps_per_orbit": po, "energy_error": e,
                        "position_error": d} for c, ss, po, e, d in candidates],
        "cpu_ratio": best["gvi"] / best["rebound"],
    }  # fmt: skip
    g = result["gvi"]
    print(
        f"\n## MEGNO against REBOUND {rebound.__version__}: star + two planets, "
        f"{args.orbits} inner orbits (t = {t_end:.0f}), best of {args.megno_repeats}\n"
    )
    header = (
        f"{'code':34s} {'steps':>8s} {'max |dE/E|':>10s} {'final dr':>9s} {'<Y>':>9s} {'CPU s':>8s}"
    )
    print(header)
    print("-" * len(header))
    print(
        f"{'REBOUND whfast, dt = P/' + str(round(1 / args.rebound_step)):34s}"
        f" {reb['steps']:8d} {reb['energy_error']:10.1e}"
        f" {result['rebound']['position_error']:9.1e} {reb['megno']:9.4f}"
        f" {best['rebound']:8.3f}"
    )
    print(
        f"{'galerkin_vi ' + g['method'] + ', h = P/' + str(per_orbit):34s} {n_steps:8d}"
        f" {g['energy_error']:10.1e} {g['position_error']:9.1e} {g['megno_mean']:9.4f}"
        f" {best['gvi']:8.3f}"
    )
    print(f"{'  same deviations, REBOUND norm':34s} {'':8s} {'':10s} {'':9s} {mean_reb_norm:9.4f}")
    print(
        f"{'  the same run without the tangent':34s} {n_steps:8d} {'':10s} {'':9s} {'':9s}"
        f" {best['plain']:8.3f}"
    )
    print(
        f"{'REBOUND ias15 (reference)':34s} {ref['steps']:8d} {'':10s} {'':9s}"
        f" {ref['megno']:9.4f} {ref['cpu_s']:8.3f}"
    )
    print(
        f"\nCPU ratio galerkin_vi / REBOUND: {result['cpu_ratio']:.1f}; "
        f"|<Y> difference| = {abs(g['megno_mean'] - reb['megno']):.1e} "
        f"(REBOUND norm: {abs(mean_reb_norm - reb['megno']):.1e})"
    )
    print(f"probe over {args.probe_orbits} orbits, REBOUND: |dE/E| {probe_reb['energy_error']:.1e},"
          f" dr {probe_dr:.1e}; the largest step per degree at least as accurate in both: "
          + ", ".join(f"{c['s']} P/{c['steps_per_orbit']} ({c['energy_error']:.1e},"
                      f" {c['position_error']:.1e}) {c['cpu_probe_s']:.3f} s"
                      for c in result["candidates"]))  # fmt: skip
    result["rebound_at_gvi_accuracy"] = _rebound_at_accuracy(
        period, t_end, ref, g["energy_error"], g["position_error"], best["gvi"]
    )
    if args.plot:
        _plot_megno(every, var, reb_norm, dt, t_end, args.plot)
    return result


def _rebound_at_accuracy(period, t_end, ref, energy, position, gvi_cpu) -> dict | None:
    """The other side of "equal accuracy": WHFast with smaller steps until it is at least as
    accurate as galerkin_vi's run in both the energy error and the final positions."""
    print("\nREBOUND whfast with smaller steps, to galerkin_vi's accuracy "
          f"(|dE/E| {energy:.1e}, dr {position:.1e}):")  # fmt: skip
    for per_orbit in (40, 80, 160, 320, 640, 1280, 2560):
        dt = period / per_orbit
        run = rebound_run(dt, t_end, 100)
        ref_t = ref if abs(run["t"] - t_end) < 1e-9 * t_end else reference_run(run["t"])
        dr = position_error(run["x"], ref_t["x"])
        cpu = min(run["cpu_s"], _clock(lambda dt=dt: rebound_simulation(dt).integrate(
            t_end, exact_finish_time=0)))  # fmt: skip
        print(
            f"  dt = P/{per_orbit:<5d} |dE/E| {run['energy_error']:.1e}  dr {dr:.1e}  "
            f"<Y> {run['megno']:.4f}  CPU {cpu:.3f} s"
        )
        if run["energy_error"] <= energy and dr <= position:
            print(f"  -> at equal accuracy galerkin_vi / REBOUND CPU: {gvi_cpu / cpu:.2f}")
            return {"steps_per_orbit": per_orbit, "energy_error": run["energy_error"],
                    "position_error": dr, "megno": run["megno"], "cpu_s": cpu,
                    "cpu_ratio": gvi_cpu / cpu}  # fmt: skip
    print("  (not reached by P/2560)")
    return None


def _plot_megno(every, var, reb_norm, dt, t_end, path: Path) -> None:
    try:
        import matplotlib
    except ImportError:
        print("matplotlib is not installed: no plot")
        return
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    sim = rebound_simulation(dt)
    times = np.linspace(t_end / 200, t_end, 200)
    reb_curve = []
    for t in times:
        sim.integrate(t, exact_finish_time=0)
        reb_curve.append(sim.megno())
    tt = every.t - every.t[0]
    y = 2.0 * np.cumsum(tt[1:] * np.diff(np.log(reb_norm))) / tt[1:]
    mean = np.cumsum(y) / np.arange(1, y.size + 1)
    fig, ax = plt.subplots(figsize=(7, 4))
    ax.plot(every.t, var.megno_mean, label="galerkin_vi <Y>, (dq, dp) norm")
    ax.plot(every.t[1:], mean, "--", label="galerkin_vi <Y>, (dx, dv) norm")
    ax.plot(times, reb_curve, ":", label="REBOUND whfast <Y>")
    ax.axhline(2.0, color="k", lw=0.5)
    ax.set_xlabel("t")
    ax.set_ylabel("mean MEGNO")
    ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot: {path}")


# -------------------------------------------------------------------------- main
def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        prog="benchmarks/tangent.py",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--parts", nargs="+", default=list(PARTS), choices=PARTS)
    parser.add_argument("--seconds", type=float, default=0.1, help="length of one timed run")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--gradient-steps", type=int, nargs="+", default=[1_000, 10_000, 100_000])
    parser.add_argument("--orbits", type=int, default=10_000, help="inner orbits for MEGNO")
    parser.add_argument("--probe-orbits", type=int, default=50)
    parser.add_argument(
        "--rebound-step",
        type=float,
        default=0.05,
        help="WHFast's step as a fraction of the inner period",
    )
    parser.add_argument("--megno-repeats", type=int, default=3)
    parser.add_argument("--plot", type=Path, default=None, help="PNG of <Y>(t) (megno part)")
    parser.add_argument("--json", type=Path, default=None)
    args = parser.parse_args(argv)  # fmt: skip
    out: dict = {}
    if "cost" in args.parts:
        out["cost"] = part_cost(args)
    if "gradient" in args.parts:
        out["gradient"] = part_gradient(args)
    if "megno" in args.parts:
        out["megno"] = part_megno(args)
    if args.json:
        args.json.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
