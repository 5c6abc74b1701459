r"""Poincaré sections of Hénon–Heiles: galerkin_vi against solve_ivp, CPU time to an accuracy.

The section is x = 0 with p_x > 0 (the upward crossings of x) of the orbit from
the library default, ``problems.henon_heiles()``: q0 = (0, -0.2), H = 1/8, in
the chaotic sea. The span has about ``--crossings`` crossings (10^4;
t_final = crossings x 6.64, the mean return time measured over t <= 66 000).
All curves run in this process:

* galerkin_vi Gauss(s), s = 2, 3, 4, at several h:
  ``integrate(q0, v0, h=h, t_span=(0, t_final), events=gvi.Event(x, direction=1))``,
  which locates the crossings on the dense output;
* scipy ``solve_ivp`` DOP853 and RK45 at several rtol = atol, with the event
  function ``g(t, y) = y[0]``, ``g.direction = 1``, and a numba-compiled
  right-hand side (state (x, y, v_x, v_y); p = v here).

**Time** is the CPU time (``time.process_time``) of the whole call, from the
initial state to the list of crossings, in interleaved rounds over all points,
best of ``--repeats``. A point whose first run took longer than
``--repeat-budget`` seconds is timed once: the solve_ivp runs take 20-80 s each.
On the shared 2-core development machine the same solve_ivp run took 4.0 s to
5.0 s in one process, and 20.2 s and 24.2 s in two full runs: the ratios carry
about 20 % of noise. Each galerkin_vi integrator is warmed (loops loaded, point
functions compiled) before timing, and its run without events is timed too, to
show what locating the events costs.

**Error** of a run: the largest difference, over the first N crossings, matched
by index, of the crossing time, y and p_y from the reference, as the maximum of
the three (each is in the JSON). The table also gives the largest energy error
|H - 1/8| over *all* the run's crossings, which measures the whole section.

**Why the first N crossings only.** The orbit is chaotic (largest Lyapunov
exponent about 0.08): two float64 solutions separate by a factor of about
e^(0.08 x 6.64) = 1.7 per return, so after a few dozen returns no solution,
reference included, is close to the true one pointwise: the two references
below differ by at most 1.6e-13 over the first 10 crossings, 3.7e-11 over 20,
2.9e-8 over 30 and 1.5e-5 over 40 (every run prints these). The reference is
DOP853 at scipy's tightest tolerance (rtol 2.3e-14 = 100 eps, atol 1e-16),
checked against galerkin_vi Gauss(6) at h = 0.025 (order 12), both over the
first 300 time units. N is the number of leading crossings on which the two
agree to ``--agree`` (1e-12, 100 times below the smallest target): 11, up to
t = 78. The time is still that of the whole run of 10^4 crossings: the error
over the first N crossings measures each method's accuracy, amplified by the
chaos alike for all of them, and the whole run what it costs to draw the
section at that accuracy.

Also measured while designing this benchmark, not by it: on a regular orbit of
the same energy (start (0, 0.1), on a torus) all 10^4 crossings can be compared.
There, galerkin_vi Gauss(4) at h = 0.05 and Gauss(6) at h = 0.05 and 0.1 agree
to 9e-10 over all of them, while DOP853 at its tightest tolerance is 4.7e-8 off
the Gauss(6) run at the end (4.6e-10 after 1000 crossings; 177 s of CPU) and
2e-7 at rtol 1e-13, 3e-5 at 1e-12.

solve_ivp counts the start, which lies on the section (x = 0, v_x > 0), as a
crossing at t = 0 (g = 0 there, increasing after); galerkin_vi counts a zero at
a node on arrival only. The benchmark drops solve_ivp's event at t = 0.

From the curves: the time to reach each target error (1e-6, 1e-8, 1e-10),
interpolated linearly in log time against log error between the two points
around it (``galerkin_vi.tools.benchmark.time_to_error``), the best galerkin_vi curve
at each target, and the ratio solve_ivp time / galerkin_vi time (> 1:
galerkin_vi is faster). Only ratios measured in the same run mean anything on a
shared machine.

Usage::

    python benchmarks/events.py --output events-results      # 4-6 minutes
    python benchmarks/events.py --quick --output events-quick # about a minute
    python benchmarks/events.py --crossings 3000 --repeats 2

Writes ``results.json`` (configuration, machine, references, every point,
the ratios) and ``workprecision.png`` (error against CPU time, and the section
drawn by the most accurate galerkin_vi run) to ``--output``.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import subprocess
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass
from pathlib import Path

import numba
import numpy as np
import scipy
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.tools.benchmark import time_to_error

#: mean time between upward crossings of x = 0 on this orbit (measured over t <= 66 000)
RETURN_TIME = 6.64
ENERGY = 0.125
TARGETS = (1e-6, 1e-8, 1e-10)
#: scipy refuses rtol below 100 eps (it raises it, with a warning): its tightest setting
REFERENCE_RTOL = 2.3e-14
REFERENCE_ATOL = 1e-16
#: the references run this long: about 45 crossings, past where they stop agreeing
REFERENCE_SPAN = 300.0
#: the cross-check of the reference: galerkin_vi Gauss(CHECK_DEGREE) at CHECK_H (order 12)
CHECK_DEGREE, CHECK_H = 6, 0.025
PEERS = ("DOP853", "RK45")


@dataclass(frozen=True)
class Config:
    """What one run measures."""

    crossings: int
    gauss: dict[int, tuple[float, ...]]  # degree s -> step sizes h
    dop853: tuple[float, ...]  # rtol = atol
    rk45: tuple[float, ...]
    repeats: int
    repeat_budget: float  # seconds: a point slower than this is timed once
    agree: float  # the references' agreement that sets N

    @property
    def t_final(self) -> float:
        return self.crossings * RETURN_TIME


def full_config() -> Config:
    return Config(
        crossings=10_000,
        gauss={2: (0.1, 0.05, 0.025), 3: (0.2, 0.1, 0.05, 0.025), 4: (0.6, 0.4, 0.2, 0.1)},
        dop853=(1e-7, 1e-9, 1e-12),
        rk45=(1e-5, 1e-6),
        repeats=3,
        repeat_budget=10.0,
        agree=1e-12,
    )


def quick_config() -> Config:
    return Config(
        crossings=2_000,
        gauss={2: (0.1, 0.05), 3: (0.2, 0.1, 0.05), 4: (0.6, 0.4, 0.2, 0.1)},
        dop853=(1e-7, 1e-9, 1e-12),
        rk45=(1e-6,),
        repeats=2,
        repeat_budget=8.0,
        agree=1e-12,
    )


@numba.njit(cache=False)
def _rhs(y):
    x, yy, vx, vy = y[0], y[1], y[2], y[3]
    return np.array([vx, vy, -x - 2.0 * x * yy, -yy - x * x + yy * yy])


def rhs(t, y):
    """Hénon–Heiles as a first-order system in (x, y, v_x, v_y)."""
    return _rhs(y)


def section(t, y):
    """solve_ivp's event function: x, upward crossings only."""
    return y[0]


section.direction = 1


def energy(q: NDArray, v: NDArray) -> NDArray:
    """H at states (m, 2) of positions and velocities (= momenta)."""
    x, y = q[:, 0], q[:, 1]
    return 0.5 * (v**2).sum(axis=1) + 0.5 * (x**2 + y**2) + x**2 * y - y**3 / 3


@dataclass
class Crossings:
    """A run's crossings: times, (y, p_y) and the energy there."""

    t: NDArray
    y: NDArray
    py: NDArray
    energy: NDArray

    def __len__(self) -> int:
        return self.t.size

    def points(self) -> NDArray:
        return np.column_stack([self.t, self.y, self.py])


def gvi_crossings(traj: gvi.Trajectory) -> Crossings:
    q, p = traj.q_events[0], traj.p_events[0]
    return Crossings(traj.t_events[0], q[:, 1], p[:, 1], energy(q, p))


def ivp_crossings(sol) -> Crossings:
    t, y = sol.t_events[0], sol.y_events[0]
    keep = t > 0.0  # the start lies on the section: solve_ivp counts it, galerkin_vi does not
    t, y = t[keep], y[keep]
    return Crossings(t, y[:, 1], y[:, 3], energy(y[:, :2], y[:, 2:]))


def gauss(s: int) -> gvi.Integrator:
    return gvi.Integrator(problems.henon_heiles().system, gvi.Galerkin(s, gvi.gauss_legendre(s)))


def gvi_run(integ: gvi.Integrator, h: float, t_final: float, events: bool = True):
    prob = problems.henon_heiles()
    x = prob.system.q[0]
    return integ.integrate(
        prob.q0,
        prob.v0,
        h=h,
        t_span=(0.0, t_final),
        events=gvi.Event(x, direction=1) if events else None,
        on_failure="raise",
    )


def ivp_run(method: str, rtol: float, atol: float, t_final: float):
    prob = problems.henon_heiles()
    sol = solve_ivp(
        rhs,
        (0.0, t_final),
        np.concatenate([prob.q0, prob.v0]),
        method=method,
        rtol=rtol,
        atol=atol,
        events=section,
    )
    if not sol.success:
        raise RuntimeError(f"solve_ivp {method} rtol={rtol}: {sol.message}")
    return sol


def references(agree: float) -> dict:
    """The reference crossings, the cross-check's agreement and N, the crossings compared."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy's note that rtol is at its floor
        ref = ivp_crossings(ivp_run("DOP853", REFERENCE_RTOL, REFERENCE_ATOL, REFERENCE_SPAN))
    check = gvi_crossings(gvi_run(gauss(CHECK_DEGREE), CHECK_H, REFERENCE_SPAN))
    m = min(len(ref), len(check))
    gap = np.maximum.accumulate(np.abs(ref.points()[:m] - check.points()[:m]).max(axis=1))
    n = int(np.searchsorted(gap, agree, side="right"))
    if n < 3:
        raise RuntimeError(f"the references agree to {agree:g} on {n} crossings only")
    shown = [k for k in (5, 10, 15, 20, 25, 30, 40) if k <= m]
    return {
        "points": ref.points()[:n],
        "n": n,
        "t_last": float(ref.t[n - 1]),
        "agreement_over_first": {str(k): float(gap[k - 1]) for k in shown},
        "agreement_at_n": float(gap[n - 1]),
        "reference": f"solve_ivp DOP853 rtol={REFERENCE_RTOL:g} atol={REFERENCE_ATOL:g}",
        "check": f"galerkin_vi Gauss({CHECK_DEGREE}) h={CHECK_H}",
    }


def errors(run: Crossings, ref: NDArray) -> dict:
    """Largest differences over the first len(ref) crossings (inf if the run has fewer)."""
    n = ref.shape[0]
    if len(run) < n:
        return {"error": math.inf, "error_t": math.inf, "error_y": math.inf, "error_py": math.inf}
    diff = np.abs(run.points()[:n] - ref).max(axis=0)
    return {
        "error": float(diff.max()),
        "error_t": float(diff[0]),
        "error_y": float(diff[1]),
        "error_py": float(diff[2]),
    }


@dataclass
class Point:
    """One run to time: a curve and its parameter (h or rtol)."""

    curve: str
    family: str  # "galerkin_vi" or "solve_ivp"
    param: float
    run: Callable[[], object]
    plain: Callable[[], object] | None = None  # galerkin_vi without events
    times: list | None = None
    plain_times: list | None = None
    result: dict | None = None


def _cpu(fn: Callable[[], object]) -> tuple[float, object]:
    start = time.process_time()
    out = fn()
    return time.process_time() - start, out


def plan(cfg: Config) -> list[Point]:
    points = []
    for s, steps in cfg.gauss.items():
        integ = gauss(s)
        gvi_run(integ, steps[0], 20.0)  # load the loops, compile the point functions
        gvi_run(integ, steps[0], 20.0, events=False)
        for h in steps:
            points.append(
                Point(
                    f"Gauss({s})",
                    "galerkin_vi",
                    h,
                    run=lambda i=integ, h=h: gvi_run(i, h, cfg.t_final),
                    plain=lambda i=integ, h=h: gvi_run(i, h, cfg.t_final, events=False),
                )
            )
    rhs(0.0, np.zeros(4))  # compile the right-hand side
    for method, tolerances in (("DOP853", cfg.dop853), ("RK45", cfg.rk45)):
        for rtol in tolerances:
            points.append(
                Point(
                    method,
                    "solve_ivp",
                    rtol,
                    run=lambda m=method, r=rtol: ivp_run(m, r, r, cfg.t_final),
                )
            )
    return points


def measure(cfg: Config, ref: NDArray, log: Callable[[str], None] = print) -> tuple[list, dict]:
    """Time every point in interleaved rounds; errors from the first round."""
    points = plan(cfg)
    best = {"error": math.inf, "section": None, "label": None}
    for round_ in range(cfg.repeats):
        for p in points:
            if round_ and min(p.times) > cfg.repeat_budget:
                continue
            try:
                seconds, out = _cpu(p.run)
            except gvi.ConvergenceError as exc:
                log(f"  {p.curve} {p.param:g}: no convergence ({exc}); point dropped")
                p.times = [math.inf]
                continue
            p.times = [*(p.times or []), seconds]
            if p.plain is not None:
                p.plain_times = [*(p.plain_times or []), _cpu(p.plain)[0]]
            if round_:
                continue
            crossings = gvi_crossings(out) if p.family == "galerkin_vi" else ivp_crossings(out)
            steps = out.n_steps if p.family == "galerkin_vi" else out.t.size - 1
            p.result = {
                "crossings": len(crossings),
                "steps": int(steps),
                **errors(crossings, ref),
                "energy": float(np.abs(crossings.energy - ENERGY).max()),
            }
            if p.family == "galerkin_vi" and p.result["error"] < best["error"]:
                best = {
                    "error": p.result["error"],
                    "section": crossings,
                    "label": f"{p.curve} h={p.param:g}",
                }
            log(
                f"  {p.curve:<9} {p.param:<8g} {seconds:8.3f} s  error {p.result['error']:.2e}"
                f"  {len(crossings)} crossings"
            )
            del out, crossings
    return points, best


def curves(points: Sequence[Point]) -> dict[str, dict]:
    out: dict[str, dict] = {}
    for p in points:
        if p.result is None:
            continue
        curve = out.setdefault(p.curve, {"family": p.family, "points": []})
        row = {"param": p.param, "time": min(p.times), "timed": len(p.times), **p.result}
        if p.plain_times:
            row["time_without_events"] = min(p.plain_times)
        curve["points"].append(row)
    return out


def summary(all_curves: dict[str, dict]) -> dict:
    """Time to each target per curve, the best galerkin_vi curve, the peers' ratios to it."""
    rows = {}
    for target in TARGETS:
        reached = {label: time_to_error(c["points"], target) for label, c in all_curves.items()}
        ours = [
            (hit["time"], label, hit["bound"])
            for label, hit in reached.items()
            if hit is not None and all_curves[label]["family"] == "galerkin_vi"
        ]
        best = min(ours) if ours else None
        ratios = {}
        for peer in PEERS:
            hit = reached.get(peer)
            if best is None or hit is None:
                ratios[peer] = None
                continue
            # an upper bound on a time (cheapest point already below the target) bounds the ratio
            bound = "<=" if hit["bound"] else ">=" if best[2] else ""
            ratios[peer] = {"ratio": hit["time"] / best[0], "bound": bound or None}
        rows[f"{target:g}"] = {
            "time_to_error": reached,
            "best_galerkin_vi": None
            if best is None
            else {"curve": best[1], "time": best[0], "bound": best[2]},
            "ratio_solve_ivp_over_galerkin_vi": ratios,
        }
    return rows


def print_points(all_curves: dict[str, dict], n: int) -> None:
    print(f"\nerror: largest difference over the first {n} crossings (t, y, p_y);")
    print("|dH|: largest |H - 1/8| over all the run's crossings; CPU s: best of 'timed'\n")
    head = ("curve", "h / rtol", "steps", "crossings", "CPU s", "timed", "no events s",
            "error", "err t", "err y", "err p_y", "|dH|")  # fmt: skip
    print("{:<9} {:>8} {:>9} {:>9} {:>9} {:>5} {:>11} {:>9} {:>9} {:>9} {:>9} {:>9}".format(*head))
    for label, curve in all_curves.items():
        for r in curve["points"]:
            plain = r.get("time_without_events")
            print(
                f"{label:<9} {r['param']:>8g} {r['steps']:>9d} {r['crossings']:>9d} "
                f"{r['time']:>9.3f} {r['timed']:>5d} "
                f"{'-' if plain is None else f'{plain:.3f}':>11} {r['error']:>9.2e} "
                f"{r['error_t']:>9.2e} {r['error_y']:>9.2e} {r['error_py']:>9.2e} "
                f"{r['energy']:>9.2e}"
            )


def print_summary(rows: dict) -> None:
    print("\nCPU time to reach each error (interpolated in log-log); solve_ivp / galerkin_vi\n")
    print(f"{'error':>7}  {'best galerkin_vi':<26} " + " ".join(f"{p:<24}" for p in PEERS))

    def seconds(hit) -> str:
        if hit is None:
            return "not reached"
        return f"{'<=' if hit['bound'] else ''}{hit['time']:.3g} s"

    for target, row in rows.items():
        best = row["best_galerkin_vi"]
        ours = "not reached" if best is None else f"{seconds(best)} ({best['curve']})"
        cells = []
        for peer in PEERS:
            hit = row["time_to_error"].get(peer)
            ratio = row["ratio_solve_ivp_over_galerkin_vi"][peer]
            text = seconds(hit)
            if ratio is not None:
                text += f" ({ratio['bound'] or ''}{ratio['ratio']:.0f}x)"
            cells.append(f"{text:<24}")
        print(f"{target:>7}  {ours:<26} " + " ".join(cells))


def plot(all_curves: dict[str, dict], best: dict, n: int, path: Path) -> bool:
    """Error against CPU time, and the section of the most accurate galerkin_vi run."""
    try:
        import matplotlib
    except ImportError:
        print("matplotlib is not installed: no plot")
        return False
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax, ax_s) = plt.subplots(1, 2, figsize=(11, 4.6))
    for label, curve in all_curves.items():
        pts = [r for r in curve["points"] if math.isfinite(r["error"])]
        style = "o-" if curve["family"] == "galerkin_vi" else "s--"
        ax.loglog([r["time"] for r in pts], [r["error"] for r in pts], style, label=label, ms=4)
    for target in TARGETS:
        ax.axhline(target, color="0.8", lw=0.6, zorder=0)
    ax.set_xlabel("CPU time of the whole run [s]")
    ax.set_ylabel(f"error over the first {n} crossings")
    ax.set_title("Hénon–Heiles, H = 1/8: section x = 0, p_x > 0")
    ax.legend(fontsize="small")
    if best["section"] is not None:
        s = best["section"]
        ax_s.plot(s.y, s.py, ".", color="k", ms=1.0)
        ax_s.set_title(f"{len(s)} crossings, galerkin_vi {best['label']}")
    ax_s.set_xlabel("y")
    ax_s.set_ylabel("p_y")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return True


def _machine() -> dict:
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as fh:
            cpu = next(
                (ln.split(":", 1)[1].strip() for ln in fh if ln.startswith("model name")), cpu
            )
    except OSError:
        pass
    try:
        load = [round(x, 2) for x in os.getloadavg()]
    except OSError:
        load = None
    try:
        commit = subprocess.run(
            ["git", "describe", "--always", "--dirty"],
            cwd=Path(__file__).resolve().parent,
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = None
    return {
        "cpu": cpu,
        "cpus": os.cpu_count(),
        "load_average_start": load,
        "commit": commit,
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "galerkin_vi": gvi.__version__,
    }


def run(cfg: Config, output: Path | None, quick: bool = False) -> dict:
    """Measure, print, write; return the results as plain data."""
    start = time.perf_counter()
    meta = {
        "date": time.strftime("%Y-%m-%d %H:%M:%S %z"),
        "command": " ".join(sys.argv),
        "quick": quick,
        "machine": _machine(),
        "config": {**asdict(cfg), "gauss": {str(k): v for k, v in cfg.gauss.items()}},
        "t_final": cfg.t_final,
        "timer": "time.process_time, best of the timed runs, interleaved rounds",
    }
    print(f"Hénon–Heiles, H = 1/8, q0 = (0, -0.2); t_final = {cfg.t_final:g} "
          f"(about {cfg.crossings} crossings)")  # fmt: skip
    ref = references(cfg.agree)
    print(f"reference: {ref['reference']}; check: {ref['check']}")
    agreement = ", ".join(f"{k}: {v:.1e}" for k, v in ref["agreement_over_first"].items())
    print(f"  their largest difference over the first k crossings: {agreement}")
    print(f"  compared: the first N = {ref['n']} crossings (t <= {ref['t_last']:.1f}), "
          f"where they agree to {ref['agreement_at_n']:.1e}")  # fmt: skip
    print("timing (first round):")
    points, best = measure(cfg, ref["points"])
    all_curves = curves(points)
    rows = summary(all_curves)
    print_points(all_curves, ref["n"])
    print_summary(rows)
    elapsed = time.perf_counter() - start
    print(f"\nwall time of the benchmark: {elapsed:.0f} s")
    results = {
        "meta": {**meta, "wall_seconds": elapsed},
        "reference": {k: v for k, v in ref.items() if k != "points"},
        "curves": all_curves,
        "summary": rows,
    }
    if output is not None:
        output.mkdir(parents=True, exist_ok=True)
        (output / "results.json").write_text(json.dumps(results, indent=1, default=float))
        drawn = plot(all_curves, best, ref["n"], output / "workprecision.png")
        print(f"written: {output / 'results.json'}" + (", workprecision.png" if drawn else ""))
    return results


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", type=Path, default=Path("events-results"), metavar="DIR")
    parser.add_argument("--quick", action="store_true", help="2000 crossings, fewer points")
    parser.add_argument("--crossings", type=int, help="about this many crossings (10000)")
    parser.add_argument("--repeats", type=int, help="timed runs per point, at most (3)")
    parser.add_argument("--repeat-budget", type=float, help="seconds: slower points run once")
    parser.add_argument("--agree", type=float, help="agreement of the references that sets N")
    args = parser.parse_args(argv)
    cfg = quick_config() if args.quick else full_config()
    changes = {
        "crossings": args.crossings,
        "repeats": args.repeats,
        "repeat_budget": args.repeat_budget,
        "agree": args.agree,
    }
    cfg = Config(**{**asdict(cfg), **{k: v for k, v in changes.items() if v is not None}})
    run(cfg, args.output, quick=args.quick)
    return 0


if __name__ == "__main__":
    sys.exit(main())
