"""Stress suite: long runs, chaos and many degrees of freedom.

Not a test (``tests/test_stress.py`` asserts the same properties): measures and
reports the figures of the three scenarios.

- **Long runs.** 1e7 pendulum steps (s = 2, h = 0.1) and 1e6 outer-solar-system
  steps (s = 2, h = 10 days), each streamed (:meth:`Integrator.stream`) with
  ``save_every`` in a fresh subprocess: peak resident memory
  (``resource.getrusage``), wall time, and the energy-error drift ratio
  max |E - E0| over the last tenth of the saved states / over the first tenth
  (no drift: <= 2). The pendulum also runs a tenth as many steps, to show that
  the peak memory does not grow with the length of the run. A diagnostic row
  runs the solar system at s = 3 (order 6), where the energy error is at
  round-off level.
- **Chaos.** Hénon–Heiles (H = 1/8) and the double pendulum (both arms
  horizontal at rest): the energy error over 1e6 steps (drift ratio); the
  largest Lyapunov exponent from two nearby trajectories renormalised every
  time unit (Benettin), with the log stretch factor S(t) it accumulates; and
  forward-then-backward runs over spans T: the return error |q_back(0) - q0|
  against eps exp(S(T)) and eps exp(lambda T). A symmetric method returns to
  round-off amplified by the dynamics, so the error grows at the Lyapunov rate.
- **Many degrees of freedom.** The FPU-beta spring chain of the peer benchmark
  (:func:`peers.cases.chain_problem` in ``benchmarks/peers/cases.py``) with
  N = 10 ... 1000 masses: cost per step (best of interleaved repeats, compilation and the
  fixed cost of an ``integrate`` call excluded) of the default loop
  (constant-mass iteration) and of full Newton (``specialize=False``, a banded
  LU of the stage Jacobian every iteration), the log-log slope of cost
  against N, and for scale the time of one dense LU of the s N x s N stage
  Jacobian. Timed in a child process with one BLAS thread (see
  :data:`ONE_BLAS_THREAD`).

Writes ``stress.json`` (every figure), ``stress.md`` (tables) and PNG plots
into ``--output``.

Run: ``python benchmarks/stress.py [--quick] [--output DIR]``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import platform
import resource
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import scipy.linalg
from numpy.typing import NDArray

import galerkin_vi as gvi
from galerkin_vi import problems

_HERE = str(Path(__file__).resolve().parent)
if _HERE not in sys.path:  # loaded from a file path (tests) rather than run as a script
    sys.path.insert(0, _HERE)

from peers import cases  # noqa: E402

EPS = float(np.finfo(float).eps)
DRIFT_BOUND = 2.0  # the criterion: max over the last tenth <= 2x the first tenth


@dataclass(frozen=True)
class Config:
    """Sizes of one run of the suite (:data:`FULL` or :data:`QUICK`)."""

    pendulum_steps: int = 10_000_000
    pendulum_h: float = 0.1
    pendulum_save_every: int = 1000
    solar_steps: int = 1_000_000
    solar_h: float = 10.0
    solar_save_every: int = 100
    chunk_steps: int = 100_000
    chaos_steps: int = 1_000_000
    chaos_save_every: int = 100
    hh_h: float = 0.1
    hh_spans: tuple[float, ...] = (10, 25, 50, 75, 100, 150, 200, 250, 300)
    hh_lyapunov_time: float = 2000.0
    dp_h: float = 0.05
    dp_spans: tuple[float, ...] = (5, 10, 20, 30, 40, 50, 60, 70, 80)
    dp_lyapunov_time: float = 1000.0
    chain_sizes: tuple[int, ...] = (10, 30, 100, 300, 1000)
    chain_steps: int = 200
    chain_repeats: int = 5


FULL = Config()
QUICK = dataclasses.replace(
    FULL,
    pendulum_steps=1_000_000,
    solar_steps=100_000,
    chaos_steps=100_000,
    hh_lyapunov_time=500.0,
    dp_lyapunov_time=300.0,
    chain_sizes=(10, 30, 100, 300),
)


# ------------------------------------------------------------------ helpers
def peak_rss_mb() -> float:
    """Peak resident set size of this process in MB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def rss_mb(field: str = "VmRSS") -> float:
    """``VmRSS`` (current) or ``VmHWM`` (peak since start or reset) in MB; the peak RSS
    of ``getrusage`` where /proc is missing."""
    try:
        with open("/proc/self/status") as status:
            for line in status:
                if line.startswith(f"{field}:"):
                    return int(line.split()[1]) / 1024
    except OSError:
        pass
    return peak_rss_mb()


def reset_peak_rss() -> bool:
    """Reset the kernel's peak-RSS mark to the current RSS (Linux >= 4.0); False if refused."""
    try:
        with open("/proc/self/clear_refs", "w") as clear_refs:
            clear_refs.write("5")
    except OSError:
        return False
    return True


def drift_ratio(error: NDArray[np.float64]) -> tuple[float, float, float]:
    """(max over the first tenth, max over the last tenth, their ratio) of saved errors.

    Row 0 is the initial state (error 0 by definition) and is left out.
    """
    err = np.asarray(error, dtype=float)[1:]
    k = max(1, err.size // 10)
    first, last = float(err[:k].max()), float(err[-k:].max())
    return first, last, (last / first if first > 0 else math.inf)


def loglog_slope(x: Sequence[float], y: Sequence[float]) -> float:
    """Least-squares slope of log y against log x."""
    return float(np.polyfit(np.log(np.asarray(x, float)), np.log(np.asarray(y, float)), 1)[0])


def method_label(method: gvi.Galerkin) -> str:
    """Short name of a method, e.g. ``s=2 Lobatto(3)``."""
    family = {"gauss_lobatto": "Lobatto", "gauss_legendre": "Gauss"}
    quadrature = method.quadrature
    name = family.get(quadrature.family, quadrature.family)
    return f"s={method.degree} {name}({quadrature.npoints})"


def warm_up(problem: str, degree: int, h: float) -> None:
    """Load (or compile and cache) the kernel of ``problem``: ten steps, two rows saved."""
    prob = _problem(problem)
    integ = gvi.Integrator(prob.system, gvi.Galerkin(degree))
    integ.integrate(prob.q0, prob.v0, h=h, n_steps=10, save_every=10, params=prob.params)


def _problem(name: str) -> problems.Problem:
    if name == "pendulum":
        return problems.pendulum()
    if name == "outer_solar_system":
        return problems.outer_solar_system()
    if name == "henon_heiles":
        return problems.henon_heiles()
    if name == "double_pendulum":
        # both arms horizontal at rest: chaotic (lambda about 0.3; the library's
        # default start is close to quasi-periodic, lambda < 0.01)
        return problems.double_pendulum(q0=(math.pi / 2, math.pi / 2), v0=(0.0, 0.0))
    raise ValueError(f"unknown problem {name!r}")


# ------------------------------------------------------------------ long runs
def long_run(
    problem: str,
    degree: int,
    h: float,
    n_steps: int,
    save_every: int,
    chunk_steps: int = 100_000,
    relative: bool = True,
) -> dict[str, Any]:
    """Stream ``n_steps`` steps, keeping only the saved rows' times and energy errors.

    Meant to run in a fresh process (:func:`run_in_subprocess`), so that the
    memory figures are this run's: ``peak_rss_mb``, the process's peak RSS
    (imports, the kernel's load and the run); ``rss_ready_mb``, the RSS once
    the kernel is loaded; ``run_peak_rss_mb``, the peak during the run alone
    (the peak mark is reset when it starts, where Linux allows it:
    ``peak_reset``), and ``run_growth_mb``, its excess over ``rss_ready_mb``.
    """
    prob = _problem(problem)
    integ = gvi.Integrator(prob.system, gvi.Galerkin(degree))
    integ.integrate(prob.q0, prob.v0, h=h, n_steps=10, save_every=10, params=prob.params)
    load_peak = peak_rss_mb()
    rss_ready = rss_mb()
    peak_reset = reset_peak_rss()
    times: list[NDArray] = []
    energies: list[NDArray] = []
    iterations = steps = 0
    start = time.perf_counter()
    for chunk in integ.stream(
        prob.q0,
        prob.v0,
        h=h,
        n_steps=n_steps,
        chunk_steps=chunk_steps,
        save_every=save_every,
        params=prob.params,
    ):
        times.append(chunk.t)
        energies.append(chunk.energy())
        iterations += chunk.total_newton_iterations
        steps += chunk.n_steps
    seconds = time.perf_counter() - start
    run_peak = rss_mb("VmHWM") if peak_reset else peak_rss_mb()
    energy = np.concatenate(energies)
    error = np.abs(energy - energy[0])
    if relative:
        error /= abs(energy[0])
    first, last, ratio = drift_ratio(error)
    n = prob.q0.size
    return {
        "problem": problem,
        "method": method_label(integ.method),
        "h": h,
        "n_steps": n_steps,
        "save_every": save_every,
        "chunk_steps": chunk_steps,
        "rows": int(energy.size),
        "seconds": seconds,
        "ns_per_step": 1e9 * seconds / n_steps,
        "mean_newton_iterations": iterations / steps,
        "rss_ready_mb": rss_ready,
        "peak_rss_mb": max(load_peak, peak_rss_mb()),
        "run_peak_rss_mb": run_peak,
        "run_growth_mb": run_peak - rss_ready,
        "peak_reset": peak_reset,
        # what integrate() with save_every=1 would hold: t, q, p and one uint8 per step
        "save_all_mb": n_steps * ((2 * n + 1) * 8 + 1) / 2**20,
        "energy0": float(energy[0]),
        "relative": relative,
        "max_error": float(error.max()),
        "first_tenth": first,
        "last_tenth": last,
        "drift_ratio": ratio,
        "t": np.concatenate(times).tolist(),
        "error": error.tolist(),
    }


def run_in_subprocess(
    function: str,
    env: dict[str, str] | None = None,
    log: Callable[[str], None] | None = None,
    **kwargs: Any,
) -> dict[str, Any]:
    """Run ``CHILD_FUNCTIONS[function](**kwargs)`` in a fresh Python; return its dict.

    ``env`` adds to (or overrides) this process's environment in the child;
    ``log`` receives the lines the child printed before its result.
    """
    payload = json.dumps({"function": function, "kwargs": kwargs})
    command = [sys.executable, str(Path(__file__).resolve()), "--child", payload]
    environment = {**os.environ, **(env or {})}
    done = subprocess.run(command, capture_output=True, text=True, check=False, env=environment)
    if done.returncode != 0:
        raise RuntimeError(f"{function}({kwargs}) failed:\n{done.stderr[-4000:]}")
    *lines, result = done.stdout.strip().splitlines()
    for line in lines if log else ():
        log(line)
    return json.loads(result)


def long_runs(cfg: Config, log: Callable[[str], None] = print) -> dict[str, Any]:
    """The pendulum (at n and n/10 steps), the solar system and its round-off diagnostic."""
    out: dict[str, Any] = {}
    pendulum = {
        "problem": "pendulum",
        "degree": 2,
        "h": cfg.pendulum_h,
        "save_every": cfg.pendulum_save_every,
        "chunk_steps": cfg.chunk_steps,
    }
    # compile (or load) here, so that no child's memory figures include a compilation
    warm_up("pendulum", 2, cfg.pendulum_h)
    warm_up("outer_solar_system", 2, cfg.solar_h)
    warm_up("outer_solar_system", 3, cfg.solar_h)
    out["pendulum"] = run_in_subprocess("long_run", n_steps=cfg.pendulum_steps, **pendulum)
    out["pendulum_tenth"] = run_in_subprocess(
        "long_run", n_steps=cfg.pendulum_steps // 10, **pendulum
    )
    solar = {
        "problem": "outer_solar_system",
        "h": cfg.solar_h,
        "n_steps": cfg.solar_steps,
        "save_every": cfg.solar_save_every,
        "chunk_steps": cfg.chunk_steps,
    }
    out["solar"] = run_in_subprocess("long_run", degree=2, **solar)
    out["solar_roundoff"] = run_in_subprocess("long_run", degree=3, **solar)
    for key, row in out.items():
        log(
            f"  {key}: {row['n_steps']:.0e} steps {row['method']} h={row['h']:g}: "
            f"{row['seconds']:.1f} s ({row['ns_per_step']:.0f} ns/step), peak RSS "
            f"{row['peak_rss_mb']:.0f} MB, {row['run_peak_rss_mb']:.0f} MB in the run "
            f"(+{row['run_growth_mb']:.1f} MB over the loaded kernel), "
            f"drift ratio {row['drift_ratio']:.2f} (max err {row['max_error']:.2e})"
        )
    return out


# ------------------------------------------------------------------ chaos
def energy_span(
    problem: str,
    degree: int,
    h: float,
    n_steps: int,
    save_every: int,
    chunk_steps: int = 100_000,
    relative: bool = True,
) -> dict[str, Any]:
    """Energy error over a long span, in this process (no memory figures)."""
    row = long_run(problem, degree, h, n_steps, save_every, chunk_steps, relative)
    memory = ("rss_ready_mb", "peak_rss_mb", "run_peak_rss_mb", "run_growth_mb", "peak_reset")
    for key in (*memory, "save_all_mb"):
        del row[key]
    return row


def _last_state(integ, prob, q, p, h, n_steps) -> tuple[NDArray, NDArray]:
    traj = integ.integrate(q, p0=p, h=h, n_steps=n_steps, save_every=n_steps, params=prob.params)
    return traj.q[-1].copy(), traj.p[-1].copy()


def initial_state(integ, prob) -> tuple[NDArray, NDArray]:
    """(q0, p0) of ``prob``, with p0 the Legendre transform of its v0."""
    traj = integ.integrate(prob.q0, prob.v0, h=0.1, n_steps=0, params=prob.params)
    return traj.q[0].copy(), traj.p[0].copy()


def lyapunov(
    integ: gvi.Integrator,
    prob: problems.Problem,
    h: float,
    t_end: float,
    tau: float = 1.0,
    d0: float = 1e-8,
    seed: int = 0,
) -> dict[str, Any]:
    """Largest Lyapunov exponent by Benettin's method on the (q, p) phase space.

    A companion trajectory starts ``d0`` away in a random direction; every
    ``tau`` time units the distance d is measured, ``log(d / d0)`` added to the
    log stretch factor S(t), and the companion pulled back to distance ``d0``
    along the separation. lambda = S(t_end) / t_end.
    """
    q, p = initial_state(integ, prob)
    rng = np.random.default_rng(seed)
    n = q.size
    delta = rng.standard_normal(2 * n)
    delta *= d0 / np.linalg.norm(delta)
    qc, pc = q + delta[:n], p + delta[n:]
    m = round(tau / h)
    k_max = round(t_end / tau)
    stretch = np.zeros(k_max + 1)
    for k in range(k_max):
        q, p = _last_state(integ, prob, q, p, h, m)
        qc, pc = _last_state(integ, prob, qc, pc, h, m)
        delta = np.concatenate([qc - q, pc - p])
        d = float(np.linalg.norm(delta))
        stretch[k + 1] = stretch[k] + math.log(d / d0)
        delta *= d0 / d
        qc, pc = q + delta[:n], p + delta[n:]
    t = np.arange(k_max + 1) * m * h
    return {"lambda": float(stretch[-1] / t[-1]), "t": t.tolist(), "stretch": stretch.tolist()}


def round_trip(
    integ: gvi.Integrator, prob: problems.Problem, h: float, spans: Sequence[float]
) -> list[dict[str, float]]:
    """Integrate T forward with h, then back with -h: |q_back - q0| and |p_back - p0|."""
    q0, p0 = initial_state(integ, prob)
    rows = []
    for span in spans:
        n = round(span / h)
        q, p = _last_state(integ, prob, q0, p0, h, n)
        qb, pb = _last_state(integ, prob, q, p, -h, n)
        rows.append(
            {
                "T": n * h,
                "q_error": float(np.linalg.norm(qb - q0)),
                "p_error": float(np.linalg.norm(pb - p0)),
            }
        )
    return rows


def growth_fit(
    t: Sequence[float], error: Sequence[float], floor: float = 1e-13, ceiling: float = 1e-3
) -> tuple[float, list[bool]]:
    """Slope of log(error) against t over the points between the round-off floor and
    the nonlinear regime, and which points were used (nan with fewer than two)."""
    t, error = np.asarray(t, float), np.asarray(error, float)
    mask = (error > floor) & (error < ceiling)
    if mask.sum() < 2:
        return math.nan, mask.tolist()
    return float(np.polyfit(t[mask], np.log(error[mask]), 1)[0]), mask.tolist()


def chaos_case(
    problem: str,
    h: float,
    spans: Sequence[float],
    lyapunov_time: float,
    energy_steps: int,
    save_every: int,
    relative: bool,
    degree: int = 2,
    chunk_steps: int = 100_000,
) -> dict[str, Any]:
    """Energy over ``energy_steps`` steps, lambda, and the forward-backward return errors."""
    prob = _problem(problem)
    integ = gvi.Integrator(prob.system, gvi.Galerkin(degree))
    start = time.perf_counter()
    energy = energy_span(problem, degree, h, energy_steps, save_every, chunk_steps, relative)
    lyap = lyapunov(integ, prob, h, max(lyapunov_time, max(spans)))
    trips = round_trip(integ, prob, h, spans)
    t_grid, stretch = np.array(lyap["t"]), np.array(lyap["stretch"])
    for row in trips:
        s_t = float(np.interp(row["T"], t_grid, stretch))
        row["stretch"] = s_t
        row["ratio_to_stretch"] = row["q_error"] / (EPS * math.exp(s_t))
    t_span = [r["T"] for r in trips]
    window = max(t_span)
    lambda_window = float(np.interp(window, t_grid, stretch) / window)
    for row in trips:
        row["ratio_to_lambda"] = row["q_error"] / (EPS * math.exp(lambda_window * row["T"]))
    rate, used = growth_fit(t_span, [r["q_error"] for r in trips])
    # the stretch rate over the fitted points: the finite-time exponent the error should follow
    t_used = np.array(t_span)[np.array(used, dtype=bool)]
    stretch_rate = (
        float(np.polyfit(t_used, np.interp(t_used, t_grid, stretch), 1)[0])
        if t_used.size >= 2
        else math.nan
    )
    return {
        "problem": problem,
        "method": method_label(integ.method),
        "h": h,
        "energy": energy,
        "lambda": lyap["lambda"],
        "lambda_time": lyap["t"][-1],
        "lambda_window": lambda_window,
        "window": window,
        "lyapunov_t": lyap["t"],
        "lyapunov_stretch": lyap["stretch"],
        "round_trip": trips,
        "fitted_rate": rate,
        "fit_points": used,
        "stretch_rate": stretch_rate,
        "seconds": time.perf_counter() - start,
    }


def chaos(cfg: Config, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Hénon–Heiles and the double pendulum."""
    out = {
        "henon_heiles": chaos_case(
            "henon_heiles",
            cfg.hh_h,
            cfg.hh_spans,
            cfg.hh_lyapunov_time,
            cfg.chaos_steps,
            cfg.chaos_save_every,
            relative=True,
            chunk_steps=cfg.chunk_steps,
        ),
        "double_pendulum": chaos_case(
            "double_pendulum",
            cfg.dp_h,
            cfg.dp_spans,
            cfg.dp_lyapunov_time,
            cfg.chaos_steps,
            cfg.chaos_save_every,
            relative=False,  # E0 = 0 for this start
            chunk_steps=cfg.chunk_steps,
        ),
    }
    for key, row in out.items():
        e = row["energy"]
        trips = ", ".join(f"{r['T']:g}: {r['q_error']:.1e}" for r in row["round_trip"])
        log(
            f"  {key}: energy over {e['n_steps']:.0e} steps drift ratio {e['drift_ratio']:.2f} "
            f"(max err {e['max_error']:.2e}); lambda {row['lambda']:.4f} over t <= "
            f"{row['lambda_time']:g}, {row['lambda_window']:.4f} over t <= {row['window']:g}; "
            f"return error growth {row['fitted_rate']:.4f} against stretch rate "
            f"{row['stretch_rate']:.4f}; |q_back - q0| by T: {trips}"
        )
    return out


# ------------------------------------------------------------------ many degrees of freedom
def _clock(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def dense_lu_seconds(size: int, repeats: int = 3) -> float:
    """Best time of one dense LU factorisation of a ``size`` x ``size`` matrix (scale for N^3)."""
    a = np.random.default_rng(0).standard_normal((size, size)) + size * np.eye(size)
    return min(
        _clock(lambda: scipy.linalg.lu_factor(a, check_finite=False)) for _ in range(repeats)
    )


# The chain is timed in a child with one BLAS thread. galerkin_vi's kernels are
# single-threaded, but every integrate() call checks the N x N mass matrix with a
# dense LU (Integrator._initial_momentum -> system.is_regular); with OpenBLAS's
# default threads on a busy 2-core machine that LU took 160 ms at N = 300 (3 ms on
# one thread), and its spinning threads doubled the cost per step of the kernel
# that followed (275-309 against 134 us/step).
ONE_BLAS_THREAD = {k: "1" for k in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")}


CHAIN_PATHS = {"constant_mass": True, "full_newton": False}  # name -> Integrator(specialize=)


def chain_cost(
    sizes: Sequence[int],
    n_steps: int = 200,
    repeats: int = 5,
    h: float = 0.1,
    degree: int = 2,
    dense_reference: bool = True,
    log: Callable[[str], None] = print,
) -> list[dict[str, Any]]:
    """Cost per step of the FPU-beta chain against N, for both Newton paths.

    Every N runs the same ``n_steps`` steps (the same stretch of motion, so
    comparable iteration counts). Per step: (best time of ``n_steps`` steps -
    best time of 1 step) / (``n_steps`` - 1), so that neither compilation nor
    the fixed cost of an ``integrate`` call (Legendre transform, allocations)
    counts. Best of ``repeats`` rounds, each round timing every N and path in
    turn, so that a burst of load on the shared machine hits every N alike.
    """
    setups = {}
    for n_masses in sizes:
        start = time.perf_counter()
        prob = cases.chain_problem(int(n_masses))
        integs = {
            name: gvi.Integrator(prob.system, gvi.Galerkin(degree), specialize=flag)
            for name, flag in CHAIN_PATHS.items()
        }
        newton = {}
        for name, integ in integs.items():  # compiles or loads the kernel
            newton[name] = _chain_run(integ, prob, h, n_steps).mean_newton_iterations
        setups[n_masses] = (prob, integs, newton, time.perf_counter() - start)
        log(f"  N = {n_masses}: set up in {setups[n_masses][3]:.1f} s")
    best = {(n, name, k): math.inf for n in sizes for name in CHAIN_PATHS for k in (1, n_steps)}
    for _ in range(repeats):
        for n in sizes:
            prob, integs = setups[n][:2]
            # untimed: the previous N left the caches cold, which would inflate the
            # 1-step time, that is subtracted, and so deflate the cost per step
            _chain_run(integs["constant_mass"], prob, h, 1)
            for name, integ in integs.items():
                for k in (1, n_steps):
                    seconds = _clock(lambda i=integ, p=prob, k=k: _chain_run(i, p, h, k))
                    best[n, name, k] = min(best[n, name, k], seconds)
    rows = []
    for n_masses in sizes:
        _, integs, newton, setup = setups[n_masses]
        some = next(iter(integs.values()))
        row: dict[str, Any] = {
            "n_masses": int(n_masses),
            "unknowns": degree * int(n_masses),
            "banded": bool(some._spec.banded),
            "kernel_path": some.kernel_path,
            "uses_constant_mass": {name: i.uses_constant_mass for name, i in integs.items()},
            "setup_s": setup,
            "call_ms": 1e3 * best[n_masses, "constant_mass", 1],
        }
        for name in integs:
            per_step = (best[n_masses, name, n_steps] - best[n_masses, name, 1]) / (n_steps - 1)
            row[f"{name}_us_per_step"] = 1e6 * per_step
            row[f"{name}_newton_iterations"] = newton[name]
        if dense_reference:
            row["dense_lu_us"] = 1e6 * dense_lu_seconds(degree * int(n_masses))
        rows.append(row)
        log(
            f"  N = {n_masses}: {row['constant_mass_us_per_step']:.1f} us/step (constant-mass, "
            f"{newton['constant_mass']:.2f} its), {row['full_newton_us_per_step']:.1f} us/step "
            f"(full Newton, {newton['full_newton']:.2f} its), banded {row['banded']}"
        )
    return rows


def _chain_run(integ: gvi.Integrator, prob: problems.Problem, h: float, steps: int):
    return integ.integrate(
        prob.q0, prob.v0, h=h, n_steps=steps, save_every=steps, params=prob.params
    )


def chain_cost_in_subprocess(
    sizes: Sequence[int],
    n_steps: int = 200,
    repeats: int = 5,
    dense_reference: bool = True,
    log: Callable[[str], None] | None = print,
) -> list[dict[str, Any]]:
    """:func:`chain_cost` in a fresh process with one BLAS thread (:data:`ONE_BLAS_THREAD`)."""
    out = run_in_subprocess(
        "chain_cost",
        env=ONE_BLAS_THREAD,
        log=log,
        sizes=[int(n) for n in sizes],
        n_steps=n_steps,
        repeats=repeats,
        dense_reference=dense_reference,
    )
    return out["rows"]


def _chain_cost_child(**kwargs: Any) -> dict[str, Any]:
    return {"rows": chain_cost(**kwargs)}


CHILD_FUNCTIONS: dict[str, Callable[..., dict[str, Any]]] = {
    "long_run": long_run,
    "chain_cost": _chain_cost_child,
}


def many_dof(cfg: Config, log: Callable[[str], None] = print) -> dict[str, Any]:
    """Chain cost per step against N and the cost-vs-N exponents."""
    rows = chain_cost_in_subprocess(cfg.chain_sizes, cfg.chain_steps, cfg.chain_repeats, log=log)
    sizes = [r["n_masses"] for r in rows]
    out: dict[str, Any] = {"rows": rows, "n_steps": cfg.chain_steps, "repeats": cfg.chain_repeats}
    for name in CHAIN_PATHS:
        cost = [r[f"{name}_us_per_step"] for r in rows]
        out[f"{name}_exponent"] = loglog_slope(sizes, cost)
        # cost per Newton iteration: the solve itself, apart from changes in iteration counts
        per_iteration = [
            c / r[f"{name}_newton_iterations"] for c, r in zip(cost, rows, strict=True)
        ]
        out[f"{name}_per_iteration_exponent"] = loglog_slope(sizes, per_iteration)
    if "dense_lu_us" in rows[0]:
        out["dense_lu_exponent"] = loglog_slope(sizes, [r["dense_lu_us"] for r in rows])
    log(
        f"  cost-vs-N exponent: constant-mass {out['constant_mass_exponent']:.2f}, full Newton "
        f"{out['full_newton_exponent']:.2f} (dense LU {out.get('dense_lu_exponent', math.nan):.2f})"
    )
    return out


# ------------------------------------------------------------------ report
def _plots(results: dict[str, Any], output: Path) -> list[str]:
    try:
        import matplotlib
    except ImportError:
        print("matplotlib is not installed: no plots")
        return []
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    files = []
    lr = results["long_runs"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    ax = axes[0]
    row = lr["pendulum"]
    ax.semilogy(row["t"][1:], row["error"][1:], lw=0.5)
    ax.set(xlabel="t", ylabel="|E - E0| / |E0|", title=f"pendulum, {row['method']}, h = {row['h']}")
    ax = axes[1]
    for key in ("solar", "solar_roundoff"):
        row = lr[key]
        t_years = np.array(row["t"][1:]) / 365.25
        ax.semilogy(t_years, row["error"][1:], lw=0.5, label=f"{row['method']}")
    ax.set(
        xlabel="t (years)",
        ylabel="|E - E0| / |E0|",
        title=f"outer solar system, h = {lr['solar']['h']:g} days",
    )
    ax.legend(fontsize=8)
    files.append(_save(fig, output / "long_runs_energy.png"))

    ch = results["chaos"]
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for ax, (key, row) in zip(axes, ch.items(), strict=True):
        e = row["energy"]
        ax.semilogy(e["t"][1:], e["error"][1:], lw=0.3)
        label = "|E - E0| / |E0|" if e["relative"] else "|E - E0|"
        ax.set(xlabel="t", ylabel=label, title=f"{key}, {row['method']}, h = {row['h']}")
    files.append(_save(fig, output / "chaos_energy.png"))

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5))
    for ax, (key, row) in zip(axes, ch.items(), strict=True):
        t = np.array([r["T"] for r in row["round_trip"]])
        err = np.array([r["q_error"] for r in row["round_trip"]])
        ax.semilogy(t, err, "o", label="|q_back(0) - q0|")
        grid_t = np.array(row["lyapunov_t"])
        keep = grid_t <= t.max() * 1.05
        ax.semilogy(
            grid_t[keep],
            EPS * np.exp(np.array(row["lyapunov_stretch"])[keep]),
            lw=1,
            label="eps exp(S(T)) (Benettin stretch)",
        )
        ax.semilogy(
            t,
            EPS * np.exp(row["lambda_window"] * t),
            "--",
            label=f"eps exp({row['lambda_window']:.3f} T): lambda over t <= {row['window']:g}",
        )
        ax.set(
            xlabel="T",
            ylabel="return error",
            title=f"{key}: return error grows at {row['fitted_rate']:.3f}",
        )
        ax.legend(fontsize=8)
    files.append(_save(fig, output / "chaos_round_trip.png"))

    md = results["many_dof"]
    sizes = np.array([r["n_masses"] for r in md["rows"]], float)
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for name in CHAIN_PATHS:
        cost = np.array([r[f"{name}_us_per_step"] for r in md["rows"]])
        ax.loglog(sizes, cost, "o-", label=f"{name} (slope {md[f'{name}_exponent']:.2f})")
    if "dense_lu_us" in md["rows"][0]:
        dense = np.array([r["dense_lu_us"] for r in md["rows"]])
        ax.loglog(sizes, dense, "s:", label=f"one dense LU (slope {md['dense_lu_exponent']:.2f})")
    base = md["rows"][0]["constant_mass_us_per_step"]
    ax.loglog(sizes, base * (sizes / sizes[0]) ** 3, "k:", lw=0.8, label="N^3")
    ax.loglog(sizes, base * sizes / sizes[0], "k--", lw=0.8, label="N")
    ax.set(xlabel="N (masses)", ylabel="us per step", title="FPU-beta chain, s = 2, h = 0.1")
    ax.legend(fontsize=8)
    files.append(_save(fig, output / "chain_cost.png"))
    plt.close("all")
    return files


def _save(fig, path: Path) -> str:
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    return str(path)


def markdown(results: dict[str, Any]) -> str:
    """The figures as Markdown tables."""
    meta = results["meta"]
    lines = [
        "# galerkin_vi stress suite",
        "",
        f"{'quick' if meta['quick'] else 'full'} run, {meta['date']}, {meta['seconds']:.0f} s "
        f"in all; load average {meta['load_before']} before, {meta['load_after']} after.",
        "",
        "## Long runs (each in its own process, streamed with save_every)",
        "",
        "| run | method | h | steps | save_every | rows | time (s) | ns/step | Newton its "
        "| peak RSS (MB) | RSS loaded (MB) | peak RSS in run (MB) | growth in run (MB) "
        "| save_every=1 would hold (MB) | max err | first tenth | last tenth | drift ratio |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, r in results["long_runs"].items():
        lines.append(
            f"| {key} | {r['method']} | {r['h']:g} | {r['n_steps']:.0e} | {r['save_every']} "
            f"| {r['rows']} | {r['seconds']:.1f} | {r['ns_per_step']:.0f} "
            f"| {r['mean_newton_iterations']:.2f} | {r['peak_rss_mb']:.0f} "
            f"| {r['rss_ready_mb']:.0f} | {r['run_peak_rss_mb']:.0f} | {r['run_growth_mb']:.1f} "
            f"| {r['save_all_mb']:.0f} | {r['max_error']:.2e} "
            f"| {r['first_tenth']:.2e} | {r['last_tenth']:.2e} | **{r['drift_ratio']:.2f}** |"
        )
    lines += [
        "",
        "Errors are relative, |E - E0| / |E0|. `solar_roundoff` is a diagnostic: at order 6 the "
        "energy error is at round-off level, where the drift ratio measures round-off "
        "accumulation, not the method.",
        "",
        "## Chaos",
        "",
        "| problem | method | h | energy steps | max energy err | drift ratio | lambda (t range) "
        "| lambda over the round-trip window | fitted return-error growth | stretch rate "
        "over the fitted points |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for key, r in results["chaos"].items():
        e = r["energy"]
        lines.append(
            f"| {key} | {r['method']} | {r['h']:g} | {e['n_steps']:.0e} | {e['max_error']:.2e} "
            f"| **{e['drift_ratio']:.2f}** | {r['lambda']:.4f} (t <= {r['lambda_time']:g}) "
            f"| {r['lambda_window']:.4f} (t <= {r['window']:g}) | **{r['fitted_rate']:.4f}** "
            f"| {r['stretch_rate']:.4f} |"
        )
    lines += [
        "",
        "Forward-then-backward return error |q_back(0) - q0| against eps exp(S(T)), S the log "
        "stretch factor of a perturbation (Benettin), and against eps exp(lambda_window T):",
        "",
    ]
    for key, r in results["chaos"].items():
        lines += [
            f"**{key}** (fit points marked *)",
            "",
            "| T | abs q error | abs p error | S(T) | error / (eps exp S(T)) "
            "| error / (eps exp(lambda_window T)) |",
            "|---|---|---|---|---|---|",
        ]
        for row, used in zip(r["round_trip"], r["fit_points"], strict=True):
            lines.append(
                f"| {row['T']:g}{' *' if used else ''} | {row['q_error']:.2e} "
                f"| {row['p_error']:.2e} | {row['stretch']:.2f} | {row['ratio_to_stretch']:.2g} "
                f"| {row['ratio_to_lambda']:.2g} |"
            )
        lines.append("")
    md = results["many_dof"]
    lines += [
        "## Many degrees of freedom: FPU-beta chain, s = 2 Lobatto(3), h = 0.1",
        "",
        f"{md['n_steps']} steps per N, best of {md['repeats']} interleaved repeats, compilation "
        "and the fixed cost of an integrate call (column call) excluded; in a child process "
        "with one BLAS thread.",
        "",
        "| N | unknowns | banded | us/step constant-mass | Newton its | us/step full Newton "
        "| Newton its | call (ms) | one dense LU (us) | setup (s) |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for r in md["rows"]:
        lines.append(
            f"| {r['n_masses']} | {r['unknowns']} | {r['banded']} "
            f"| {r['constant_mass_us_per_step']:.1f} | {r['constant_mass_newton_iterations']:.2f} "
            f"| {r['full_newton_us_per_step']:.1f} | {r['full_newton_newton_iterations']:.2f} "
            f"| {r['call_ms']:.2f} | {r.get('dense_lu_us', math.nan):.0f} | {r['setup_s']:.1f} |"
        )
    lines += [
        "",
        f"Cost-vs-N exponent (log-log least squares): constant-mass "
        f"**{md['constant_mass_exponent']:.2f}** (per Newton iteration "
        f"{md['constant_mass_per_iteration_exponent']:.2f}), full Newton "
        f"**{md['full_newton_exponent']:.2f}** (per iteration "
        f"{md['full_newton_per_iteration_exponent']:.2f}); one dense LU "
        f"{md.get('dense_lu_exponent', math.nan):.2f}.",
        "",
        "## Files",
        "",
    ]
    lines += [f"- `{f}`" for f in results["files"]]
    return "\n".join(lines) + "\n"


def _strip_arrays(results: dict[str, Any]) -> dict[str, Any]:
    """The results without the per-row series (kept in the plots), for the JSON."""
    out = json.loads(json.dumps(results))
    for row in [*out["long_runs"].values(), *(c["energy"] for c in out["chaos"].values())]:
        del row["t"], row["error"]
    return out


def _load() -> list[float]:
    return [round(x, 2) for x in os.getloadavg()]


def run(quick: bool = False, output: str | None = "stress-results") -> dict[str, Any]:
    """Run the three scenarios; write JSON, Markdown and plots into ``output``."""
    cfg = QUICK if quick else FULL
    start = time.perf_counter()
    load_before = _load()
    results: dict[str, Any] = {}
    timings: dict[str, float] = {}
    for name, scenario in (("long_runs", long_runs), ("chaos", chaos), ("many_dof", many_dof)):
        print(f"{name}:", flush=True)
        t0 = time.perf_counter()
        results[name] = scenario(cfg, log=lambda s: print(s, flush=True))
        timings[name] = time.perf_counter() - t0
    results["meta"] = {
        "quick": quick,
        "config": dataclasses.asdict(cfg),
        "date": time.strftime("%Y-%m-%d %H:%M:%S %Z"),
        "seconds": time.perf_counter() - start,
        "scenario_seconds": timings,
        "load_before": load_before,
        "load_after": _load(),
        "python": sys.version.split()[0],
        "numpy": np.__version__,
        "platform": platform.platform(),
        "cpus": os.cpu_count(),
        "galerkin_vi": getattr(gvi, "__version__", "unknown"),
    }
    results["files"] = []
    if output is not None:
        out = Path(output)
        out.mkdir(parents=True, exist_ok=True)
        results["files"] = _plots(results, out)
        results["files"] += [str(out / "stress.json"), str(out / "stress.md")]
        (out / "stress.json").write_text(json.dumps(_strip_arrays(results), indent=1))
        (out / "stress.md").write_text(markdown(results))
    print(f"done in {results['meta']['seconds']:.0f} s; files: {', '.join(results['files'])}")
    return results


def main(argv: Sequence[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="smaller sizes, under 3 minutes")
    parser.add_argument("--output", default="stress-results", help="folder for the results")
    parser.add_argument("--child", help=argparse.SUPPRESS)  # internal: one long run, JSON out
    args = parser.parse_args(argv)
    if args.child:
        task = json.loads(args.child)
        print(json.dumps(CHILD_FUNCTIONS[task["function"]](**task["kwargs"])))
        return
    run(quick=args.quick, output=args.output)


if __name__ == "__main__":
    main()
