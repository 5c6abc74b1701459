r"""Work-precision benchmark: galerkin_vi against hand-written kernels and scipy.

What is measured
----------------
For each problem (pendulum :math:`q_0 = 1.5, v_0 = 0, T = 100`; Kepler
:math:`e = 0.6` over 50 periods) and each *curve* (one galerkin_vi method, one
hand-written kernel or one scipy ``solve_ivp`` method):

* fixed-step curves sweep the number of steps :math:`N` geometrically
  (:math:`h = T/N`) from a coarse start until the error reaches the round-off
  floor (below 1e-13, or three times in a row not below 0.7 times the best error
  once that is below 1e-9) or one run took longer than the configured time cap;
* adaptive curves (scipy) sweep ``rtol`` (``atol = rtol``) the same way.

Each point records the wall time (``time.perf_counter``, minimum over
``repeats`` runs; all points of all curves are re-timed in interleaved rounds,
so a burst of load on the shared machine hits every curve alike), the final
relative position error :math:`|q_N - q(T)| / |q(T)|`, and the maximum relative
energy error :math:`\max_k |H_k - H_0| / |H_0|`. Timing runs store only the
first and last state (``save_every = n_steps``); the error and energy are taken
from one extra, untimed run that saves about ``energy_samples`` evenly spaced
states (scipy: every accepted step).

From the curves: the time to reach a final error of 1e-4, 1e-8 and 1e-11
(first crossing, interpolated linearly in log time against log error), the
best galerkin_vi configuration at each target, and the ratio of each peer's
time to it (> 1: galerkin_vi is faster).

A separate per-step table compares galerkin_vi with the hand-written kernel of
the same method at the same h and Newton tolerance (time per step, interleaved
repeats, minimum).

References
----------
* Kepler: exact, by Kepler's equation solved with mpmath at 40 digits (the mean
  anomaly reduced in extended precision); :func:`galerkin_vi.problems.kepler_position`
  (float64) agrees to 6e-14.
* Pendulum: exact, :math:`q(t) = 2\arcsin(k\,\mathrm{cd}(t \mid k^2))` with
  :math:`k = \sin(q_0/2)` (released from rest), evaluated with mpmath at 40
  digits. It is cross-checked in every run against galerkin_vi degree 6 with
  ``gauss_legendre(6)`` at h = 0.1 and scipy DOP853 at rtol = atol = 1e-14;
  both differences are reported.
"""

from __future__ import annotations

import json
import math
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field

import mpmath
import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

import galerkin_vi as gvi
from galerkin_vi import problems

from . import handwritten as hw

__all__ = [
    "PER_STEP_PAIRS",
    "TARGETS",
    "BenchConfig",
    "Case",
    "full_config",
    "make_case",
    "quick_config",
    "run_benchmark",
    "time_to_error",
    "tiny_config",
    "write_outputs",
]

TARGETS = (1e-4, 1e-8, 1e-11)

#: per-step comparisons: label -> (galerkin_vi (degree, family), hand-written kernel)
PER_STEP_PAIRS: dict[str, tuple[tuple[int, str], str]] = {
    "s=1 Lobatto(2) vs Störmer–Verlet": ((1, "lobatto"), "verlet"),
    "s=1 Gauss(1) vs 1-stage Gauss": ((1, "gauss"), "gauss1"),
    "s=2 Gauss(2) vs 2-stage Gauss": ((2, "gauss"), "gauss2"),
    "s=3 Gauss(3) vs 3-stage Gauss": ((3, "gauss"), "gauss3"),
    "s=2 Lobatto(3) vs 3-stage Lobatto IIIA–IIIB": ((2, "lobatto"), "lobatto3"),
    "s=3 Lobatto(4) vs 4-stage Lobatto IIIA–IIIB": ((3, "lobatto"), "lobatto4"),
}

_HW_LABELS = {
    "verlet": "Störmer–Verlet",
    **{f"gauss{s}": f"{s}-stage Gauss" for s in range(1, 9)},
    **{f"gauss{s}-simplified": f"{s}-stage Gauss (simplified Newton)" for s in range(1, 9)},
    **{f"lobatto{r}": f"{r}-stage Lobatto IIIA–IIIB" for r in range(2, 9)},
}


# ----------------------------------------------------------------- configuration
@dataclass(frozen=True)
class BenchConfig:
    """What to run and how long to spend on it.

    Attributes
    ----------
    problems : tuple of str
        ``"pendulum"`` and/or ``"kepler"``.
    gvi_methods : tuple of (int, str)
        galerkin_vi degree and quadrature family (``"lobatto"``: ``gauss_lobatto(s + 1)``,
        ``"gauss"``: ``gauss_legendre(s)``).
    handwritten : tuple of str
        ``"verlet"``, ``"gaussS"``, ``"gaussS-simplified"``, ``"lobattoR"``.
    ivp_methods : tuple of str
        scipy ``solve_ivp`` methods.
    ivp_min_rtol : dict
        Tightest rtol per scipy method.
    step_factor : float
        Ratio of successive step counts.
    rtol_factor : float
        Ratio of successive rtols (scipy sweeps start at 1e-3).
    time_cap, ivp_time_cap : float
        A fixed-step (scipy) sweep stops once its last run took longer than this (seconds).
    repeats : int
        Timed runs per point (minimum reported), in interleaved rounds.
    energy_samples : int
        States saved by the untimed error run, for the energy error.
    per_step_pairs : tuple of str
        Keys of :data:`PER_STEP_PAIRS` for the per-step table.
    per_step_time : float
        Target duration (s) of one galerkin_vi run in the per-step table.
    per_step_repeats : int
    """

    problems: tuple[str, ...] = ("pendulum", "kepler")
    gvi_methods: tuple[tuple[int, str], ...] = ()
    handwritten: tuple[str, ...] = ()
    ivp_methods: tuple[str, ...] = ()
    ivp_min_rtol: dict[str, float] = field(
        default_factory=lambda: {"DOP853": 3e-14, "RK45": 1e-11, "Radau": 1e-10}
    )
    step_factor: float = 2.0
    rtol_factor: float = 10.0
    time_cap: float = 0.2
    ivp_time_cap: float = 1.0
    repeats: int = 2
    energy_samples: int = 1000
    per_step_pairs: tuple[str, ...] = tuple(PER_STEP_PAIRS)
    per_step_time: float = 0.05
    per_step_repeats: int = 5
    targets: tuple[float, ...] = TARGETS


def quick_config() -> BenchConfig:
    """``--quick``: a few methods per family, coarse sweeps, short caps (about 65 s)."""
    return BenchConfig(
        gvi_methods=((1, "lobatto"), (2, "gauss"), (3, "lobatto"), (4, "gauss"), (6, "gauss")),
        handwritten=("verlet", "gauss2", "gauss3", "lobatto4"),
        ivp_methods=("DOP853", "RK45"),
        step_factor=2.0,
        rtol_factor=math.sqrt(10.0),
        time_cap=0.2,
        ivp_time_cap=1.0,
        repeats=2,
        per_step_time=0.04,
        per_step_repeats=5,
    )


def full_config() -> BenchConfig:
    """The full run: every configuration, finer sweeps, longer caps (about 10 minutes)."""
    return BenchConfig(
        gvi_methods=tuple((s, fam) for s in (1, 2, 3, 4, 6) for fam in ("lobatto", "gauss")),
        handwritten=(
            "verlet",
            "gauss1",
            "gauss2",
            "gauss3",
            "gauss3-simplified",
            "gauss4",
            "gauss6",
            "lobatto3",
            "lobatto4",
        ),
        ivp_methods=("DOP853", "RK45", "Radau"),
        step_factor=math.sqrt(2.0),
        rtol_factor=10.0**0.25,
        time_cap=1.5,
        ivp_time_cap=5.0,
        repeats=3,
        per_step_time=0.25,
        per_step_repeats=7,
    )


def tiny_config() -> BenchConfig:
    """A seconds-long smoke configuration (Kepler only), for tests."""
    return BenchConfig(
        problems=("kepler",),
        gvi_methods=((1, "lobatto"), (2, "gauss")),
        handwritten=("verlet", "gauss2"),
        ivp_methods=("DOP853",),
        ivp_min_rtol={"DOP853": 1e-6},
        step_factor=4.0,
        time_cap=0.01,
        ivp_time_cap=0.01,
        repeats=1,
        energy_samples=50,
        per_step_pairs=("s=2 Gauss(2) vs 2-stage Gauss",),
        per_step_time=0.005,
        per_step_repeats=1,
    )


# ------------------------------------------------------------------------ cases
@dataclass(frozen=True)
class Case:
    """One benchmark problem: initial data, span, exact final position."""

    name: str
    problem_id: int
    problem: problems.Problem
    q0: NDArray[np.float64]
    p0: NDArray[np.float64]
    t_final: float
    q_ref: NDArray[np.float64]
    reference: str
    energy0: float
    n_start: int
    per_step_h: float
    rhs: Callable
    jac: Callable


def _pendulum_exact(q0: float, t: float, dps: int = 40) -> float:
    """Pendulum released from rest at ``q0``: 2 asin(k cd(t | k^2)), k = sin(q0/2)."""
    with mpmath.workdps(dps):
        k = mpmath.sin(mpmath.mpf(q0) / 2)
        return float(2 * mpmath.asin(k * mpmath.ellipfun("cd", mpmath.mpf(t), m=k * k)))


def _kepler_exact(t: float, e: float, dps: int = 40) -> NDArray[np.float64]:
    """Kepler orbit (a = mu = 1, perihelion at t = 0) at the float time ``t``, mpmath at 40 digits.

    The mean anomaly is reduced modulo 2 pi in extended precision, so the only
    error is the final rounding (``kepler_position`` reduces in float64: 6e-14 off here).
    """
    with mpmath.workdps(dps):
        ecc = mpmath.mpf(e)
        mean = mpmath.fmod(mpmath.mpf(t), 2 * mpmath.pi)
        E = mpmath.findroot(lambda x: x - ecc * mpmath.sin(x) - mean, mean + ecc * mpmath.sin(mean))
        return np.array(
            [float(mpmath.cos(E) - ecc), float(mpmath.sqrt(1 - ecc * ecc) * mpmath.sin(E))]
        )


def make_case(name: str) -> Case:
    """The benchmark problems: ``"pendulum"`` or ``"kepler"``."""
    if name == "pendulum":
        prob = problems.pendulum(1.5, 0.0)
        t_final = 100.0
        q_ref = np.array([_pendulum_exact(1.5, t_final)])
        return Case(
            name="pendulum",
            problem_id=hw.PENDULUM,
            problem=prob,
            q0=prob.q0.copy(),
            p0=prob.v0.copy(),
            t_final=t_final,
            q_ref=q_ref,
            reference="exact: 2 asin(k cd(T | k^2)), k = sin(0.75), mpmath at 40 digits",
            energy0=float(hw.energy(hw.PENDULUM, prob.q0[None, :], prob.v0[None, :])[0]),
            n_start=50,
            per_step_h=0.1,
            rhs=hw.pendulum_rhs,
            jac=hw.pendulum_jac,
        )
    if name == "kepler":
        e = 0.6
        prob = problems.kepler(e)
        t_final = 50 * 2 * np.pi
        return Case(
            name="kepler",
            problem_id=hw.KEPLER,
            problem=prob,
            q0=prob.q0.copy(),
            p0=prob.v0.copy(),
            t_final=t_final,
            q_ref=_kepler_exact(t_final, e),
            reference="exact: Kepler's equation solved with mpmath at 40 digits",
            energy0=float(hw.energy(hw.KEPLER, prob.q0[None, :], prob.v0[None, :])[0]),
            n_start=50 * 16,
            per_step_h=2 * np.pi / 200,
            rhs=hw.kepler_rhs,
            jac=hw.kepler_jac,
        )
    raise ValueError(f"unknown benchmark problem {name!r}; use 'pendulum' or 'kepler'")


# ---------------------------------------------------------------------- solvers
@dataclass
class Sample:
    """Result of one untimed error run."""

    q_final: NDArray[np.float64]
    energy: NDArray[np.float64] | None
    stats: dict


@dataclass
class Curve:
    """One line of a work-precision diagram."""

    label: str
    family: str  # "galerkin_vi" | "hand-written" | "scipy"
    kind: str  # "fixed-step" | "adaptive"
    order: int | None
    sample: Callable[[float], Sample]  # error run (saves states for the energy)
    timed: Callable[[float], object]  # timing run (final state only)
    warm: Callable[[], object]  # compile or load, on a short run
    points: list[dict] = field(default_factory=list)


def _quadrature(s: int, family: str):
    if family == "lobatto":
        return gvi.gauss_lobatto(s + 1)
    if family == "gauss":
        return gvi.gauss_legendre(s)
    raise ValueError(f"unknown quadrature family {family!r}")


def gvi_label(s: int, family: str) -> str:
    """Curve label of galerkin_vi degree ``s`` with the given quadrature family."""
    return f"galerkin_vi s={s} " + (f"Lobatto({s + 1})" if family == "lobatto" else f"Gauss({s})")


def _every(n: int, samples: int) -> int:
    return max(1, n // samples)


def _gvi_curve(case: Case, s: int, family: str, samples: int) -> Curve:
    integ = gvi.Integrator(case.problem.system, gvi.Galerkin(s, _quadrature(s, family)))
    q0, v0, T, prm = case.q0, case.p0, case.t_final, case.problem.params

    def timed(n):
        return integ.integrate(q0, v0, h=T / n, n_steps=int(n), save_every=int(n), params=prm)

    def sample(n):
        n = int(n)
        traj = integ.integrate(
            q0, v0, h=T / n, n_steps=n, save_every=_every(n, samples), params=prm
        )
        return Sample(traj.q[-1], traj.energy(), {"newton_iterations": traj.mean_newton_iterations})

    def warm():
        return integ.integrate(q0, v0, h=case.per_step_h, n_steps=10, params=prm)

    return Curve(gvi_label(s, family), "galerkin_vi", "fixed-step", 2 * s, sample, timed, warm)


def _hw_runner(case: Case, kernel: str) -> tuple[Callable, int]:
    pid, q0, p0 = case.problem_id, case.q0, case.p0
    if kernel == "verlet":
        return (lambda h, n, every: hw.run_verlet(pid, q0, p0, h, n, every)), 2
    if kernel.startswith("gauss"):
        s = int(kernel[5:].split("-")[0])
        full = not kernel.endswith("-simplified")
        return (lambda h, n, every: hw.run_gauss(pid, s, q0, p0, h, n, every, full=full)), 2 * s
    if kernel.startswith("lobatto"):
        r = int(kernel[7:])
        return (lambda h, n, every: hw.run_lobatto(pid, r, q0, p0, h, n, every)), 2 * r - 2
    raise ValueError(f"unknown hand-written kernel {kernel!r}")


def _hw_curve(case: Case, kernel: str, samples: int) -> Curve:
    run, order = _hw_runner(case, kernel)
    T = case.t_final

    def timed(n):
        return run(T / n, int(n), int(n))

    def sample(n):
        n = int(n)
        res = run(T / n, n, _every(n, samples))
        e = hw.energy(case.problem_id, res.q, res.p)
        return Sample(res.q[-1], e, {"newton_iterations": res.mean_newton_iterations})

    def warm():
        return run(case.per_step_h, 10, 1)

    return Curve(
        f"hand-written {_HW_LABELS[kernel]}",
        "hand-written",
        "fixed-step",
        order,
        sample,
        timed,
        warm,
    )


def _ivp_curve(case: Case, method: str) -> Curve:
    y0 = np.concatenate([case.q0, case.p0])
    d = case.q0.size
    extra = {"jac": case.jac} if method == "Radau" else {}

    def timed(rtol):
        sol = solve_ivp(
            case.rhs, (0.0, case.t_final), y0, method=method, rtol=rtol, atol=rtol, **extra
        )
        if not sol.success:
            raise RuntimeError(f"solve_ivp({method}) failed: {sol.message}")
        return sol

    def sample(rtol):
        sol = timed(rtol)
        e = hw.energy(
            case.problem_id, np.ascontiguousarray(sol.y[:d].T), np.ascontiguousarray(sol.y[d:].T)
        )
        return Sample(sol.y[:d, -1].copy(), e, {"nfev": int(sol.nfev), "steps": sol.t.size - 1})

    def warm():
        return solve_ivp(case.rhs, (0.0, 1.0), y0, method=method, rtol=1e-6, atol=1e-6, **extra)

    return Curve(f"scipy {method}", "scipy", "adaptive", None, sample, timed, warm)


# ---------------------------------------------------------------------- sweeps
def _clock(fn: Callable[[], object]) -> float:
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def _relative_error(case: Case, q: NDArray) -> float:
    return float(np.linalg.norm(q - case.q_ref) / np.linalg.norm(case.q_ref))


def _energy_error(case: Case, energy: NDArray | None) -> float | None:
    if energy is None or energy.size == 0:
        return None
    return float(np.max(np.abs(energy - case.energy0)) / abs(case.energy0))


_FLOOR = 1e-13  # relative position errors below this are round-off: finer sweeps are wasted
# below this error, a fixed-step sweep that stops improving has reached round-off (the
# pre-asymptotic Kepler errors are not monotone down to about 1e-8)
_STALL_BELOW = 1e-9


def _sweep(case: Case, curve: Curve, cfg: BenchConfig, log: Callable[[str], None]) -> None:
    """Fill ``curve.points`` by one sweep (error run + one timed run per point)."""
    if curve.kind == "fixed-step":
        params: Sequence[float] = _step_counts(case.n_start, cfg.step_factor)
    else:
        method = curve.label.split()[-1]
        params = _rtols(cfg.ivp_min_rtol.get(method, 1e-10), cfg.rtol_factor)
    best = math.inf
    failures = stalled = 0
    for param in params:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                smp = curve.sample(param)
            elapsed = _clock(lambda p=param: curve.timed(p))
        except (gvi.ConvergenceError, RuntimeError, FloatingPointError) as exc:
            failures += 1
            log(f"    {curve.label}: {param:g} failed ({type(exc).__name__})")
            if failures > 4 and not curve.points:
                return
            continue
        err = _relative_error(case, smp.q_final)
        point = {
            ("n_steps" if curve.kind == "fixed-step" else "rtol"): param,
            "time": elapsed,
            "error": err,
            "energy_error": _energy_error(case, smp.energy),
            **smp.stats,
        }
        if curve.kind == "fixed-step":
            point["h"] = case.t_final / param
        curve.points.append(point)
        if not math.isfinite(err):
            continue
        if err < _FLOOR:
            break
        # at the round-off floor: three times in a row no real improvement on an accurate
        # fixed-step curve (adaptive sweeps run to their tightest rtol: their error falls slowly
        # and unevenly with rtol)
        stalled = stalled + 1 if (best < _STALL_BELOW and err > 0.7 * best) else 0
        if curve.kind == "fixed-step" and stalled >= 3:
            break
        best = min(best, err)
        if elapsed > (cfg.time_cap if curve.kind == "fixed-step" else cfg.ivp_time_cap):
            break


def _step_counts(n_start: int, factor: float, n_max: int = 50_000_000) -> list[int]:
    out = []
    x = float(n_start)
    while x <= n_max:
        n = int(round(x))
        if not out or n > out[-1]:
            out.append(n)
        x *= factor
    return out


def _rtols(min_rtol: float, factor: float) -> list[float]:
    out = []
    x = 1e-3
    while x >= min_rtol * 0.999:
        out.append(float(f"{x:.3g}"))
        x /= factor
    return out


def _retime(curves: Sequence[Curve], repeats: int) -> None:
    """Re-time every point in ``repeats - 1`` further interleaved rounds; keep the minimum."""
    jobs = [(c, p) for c in curves for p in c.points]
    for rnd in range(repeats - 1):
        for curve, point in jobs if rnd % 2 else reversed(jobs):
            param = point.get("n_steps", point.get("rtol"))
            try:
                elapsed = _clock(lambda c=curve, p=param: c.timed(p))
            except (gvi.ConvergenceError, RuntimeError):
                continue
            point["time"] = min(point["time"], elapsed)


# ----------------------------------------------------------------- time to error
def time_to_error(points: Sequence[dict], target: float) -> dict | None:
    """Time at which a curve first reaches ``target`` final error.

    Points are ordered by time; between the last point above the target and the
    first at or below it, log(time) is interpolated linearly in log(error).
    Returns ``{"time": t, "bound": False}``, or ``bound: True`` when already the
    cheapest point is below the target (its time is then an upper bound), or
    None when the curve never reaches the target.
    """
    pts = sorted(
        (p for p in points if math.isfinite(p["error"]) and p["error"] > 0), key=lambda p: p["time"]
    )
    previous = None
    for p in pts:
        if p["error"] <= target:
            if previous is None:
                return {"time": p["time"], "bound": True}
            lt0, lt1 = math.log(previous["time"]), math.log(p["time"])
            le0, le1 = math.log(previous["error"]), math.log(p["error"])
            frac = (math.log(target) - le0) / (le1 - le0)
            return {"time": math.exp(lt0 + frac * (lt1 - lt0)), "bound": False}
        previous = p
    return None


def _summarise(curves: Sequence[Curve], targets: Sequence[float]) -> dict:
    tte = {c.label: {f"{t:g}": time_to_error(c.points, t) for t in targets} for c in curves}
    best: dict[str, dict | None] = {}
    ratios: dict[str, dict[str, float | None]] = {}
    for t in targets:
        key = f"{t:g}"
        gvi_times = [
            (tte[c.label][key]["time"], c.label)
            for c in curves
            if c.family == "galerkin_vi" and tte[c.label][key] is not None
        ]
        if not gvi_times:
            best[key] = None
            ratios[key] = {c.label: None for c in curves if c.family != "galerkin_vi"}
            continue
        t_best, label = min(gvi_times)
        best[key] = {"config": label, "time": t_best, "bound": tte[label][key]["bound"]}
        ratios[key] = {
            c.label: (tte[c.label][key]["time"] / t_best if tte[c.label][key] else None)
            for c in curves
            if c.family != "galerkin_vi"
        }
    return {"time_to_error": tte, "best_galerkin_vi": best, "ratio_peer_over_best": ratios}


# ------------------------------------------------------------------- per-step
def _per_step_row(case: Case, key: str, cfg: BenchConfig) -> dict:
    """galerkin_vi against its hand-written twin at the same h: interleaved repeats, minimum."""
    (s, family), kernel = PER_STEP_PAIRS[key]
    h = case.per_step_h
    integ = gvi.Integrator(case.problem.system, gvi.Galerkin(s, _quadrature(s, family)))
    run_hw, _ = _hw_runner(case, kernel)
    simplified = _hw_runner(case, kernel + "-simplified")[0] if kernel.startswith("gauss") else None

    def gvi_run(n, every):
        return integ.integrate(case.q0, case.p0, h=h, n_steps=n, save_every=every)

    # warm up, then size the runs so that one galerkin_vi run takes about per_step_time
    gvi_run(10, 10)
    run_hw(h, 10, 10)
    if simplified is not None:
        simplified(h, 10, 10)
    probe = 2000
    t_probe = _clock(lambda: gvi_run(probe, probe))
    n = int(min(2_000_000, max(1000, probe * cfg.per_step_time / max(t_probe, 1e-9))))
    t_gvi = t_hw = t_simp = math.inf
    for _ in range(cfg.per_step_repeats):
        t_gvi = min(t_gvi, _clock(lambda: gvi_run(n, n)))
        t_hw = min(t_hw, _clock(lambda: run_hw(h, n, n)))
        if simplified is not None:
            t_simp = min(t_simp, _clock(lambda: simplified(h, n, n)))
    overhead = min(_clock(lambda: gvi_run(1, 1)) for _ in range(5))
    return {
        "problem": case.name,
        "pair": key,
        "h": h,
        "n_steps": n,
        "gvi_ns_per_step": 1e9 * t_gvi / n,
        "hw_ns_per_step": 1e9 * t_hw / n,
        "ratio": t_gvi / t_hw,
        "gvi_newton_iterations": gvi_run(n, n).mean_newton_iterations,
        "hw_newton_iterations": run_hw(h, n, n).mean_newton_iterations,
        "hw_simplified_ns_per_step": (1e9 * t_simp / n if simplified is not None else None),
        "gvi_call_overhead_us": 1e6 * overhead,
    }


def _per_step(case: Case, cfg: BenchConfig, log: Callable[[str], None]) -> list[dict]:
    rows = []
    for key in cfg.per_step_pairs:
        row = _per_step_row(case, key, cfg)
        log(
            f"  per step {case.name:8s} {key:45s} gvi {row['gvi_ns_per_step']:9.1f} ns  "
            f"hand-written {row['hw_ns_per_step']:9.1f} ns  ratio {row['ratio']:5.2f}"
        )
        rows.append(row)
    return rows


# ----------------------------------------------------------------- references
def _reference_checks(case: Case) -> dict:
    """Independent checks of the exact references."""
    if case.name == "kepler":
        q = np.asarray(problems.kepler_position(case.t_final, 0.6), dtype=float)
        return {"kepler_position_float64_relative_difference": _relative_error(case, q)}
    if case.name != "pendulum":
        return {}
    n = int(round(case.t_final / 0.1))
    integ = gvi.Integrator(case.problem.system, gvi.Galerkin(6, gvi.gauss_legendre(6)))
    traj = integ.integrate(case.q0, case.p0, h=case.t_final / n, n_steps=n, save_every=n)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy raises rtol to 100 eps
        sol = solve_ivp(
            case.rhs,
            (0.0, case.t_final),
            np.concatenate([case.q0, case.p0]),
            method="DOP853",
            rtol=1e-14,
            atol=1e-14,
        )
    return {
        "gvi_s6_gauss6_h0.1_relative_difference": _relative_error(case, traj.q[-1]),
        "dop853_rtol1e-14_relative_difference": _relative_error(case, sol.y[:1, -1]),
    }


# ------------------------------------------------------------------------ run
def _machine() -> dict:
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numba
    import scipy

    return {
        "cpu": cpu,
        "cpus": os.cpu_count(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "galerkin_vi": gvi.__version__,
    }


def _load() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def run_benchmark(cfg: BenchConfig, quick: bool, log: Callable[[str], None] = print) -> dict:
    """Run the whole benchmark described by ``cfg``; return the results as plain data."""
    start = time.perf_counter()
    results: dict = {
        "meta": {
            "quick": quick,
            "date": time.strftime("%Y-%m-%d %H:%M:%S %z"),
            "machine": _machine(),
            "load_average_start": _load(),
            "config": asdict(cfg),
            "timer": "time.perf_counter, minimum over repeats in interleaved rounds",
            "error": "final relative position error |q_N - q(T)| / |q(T)| (2-norm)",
            "energy_error": "max_k |H_k - H_0| / |H_0| over the saved states",
        },
        "problems": {},
        "per_step": [],
    }
    for name in cfg.problems:
        case = make_case(name)
        log(f"[{name}] T = {case.t_final:.6g}, reference: {case.reference}")
        curves = [_gvi_curve(case, s, fam, cfg.energy_samples) for s, fam in cfg.gvi_methods]
        curves += [_hw_curve(case, kernel, cfg.energy_samples) for kernel in cfg.handwritten]
        curves += [_ivp_curve(case, method) for method in cfg.ivp_methods]
        warm = {c.label: _clock(c.warm) for c in curves}
        log(f"  warm-up (compile or load) {time.perf_counter() - start:.1f} s since start")
        checks = _reference_checks(case)
        for curve in curves:
            _sweep(case, curve, cfg, log)
            if curve.points:
                last = curve.points[-1]
                log(
                    f"  {curve.label:52s} {len(curve.points):3d} points, last: "
                    f"{last['time']:.3g} s, error {last['error']:.2e}"
                )
        _retime(curves, cfg.repeats)
        entry = {
            "t_final": case.t_final,
            "reference": case.reference,
            "reference_position": case.q_ref.tolist(),
            "reference_checks": checks,
            "energy0": case.energy0,
            "first_call_seconds": warm,
            "curves": {
                c.label: {"family": c.family, "kind": c.kind, "order": c.order, "points": c.points}
                for c in curves
            },
        }
        entry.update(_summarise(curves, cfg.targets))
        results["problems"][name] = entry
    for name in cfg.problems:
        if cfg.per_step_pairs:
            results["per_step"] += _per_step(make_case(name), cfg, log)
    results["meta"]["load_average_end"] = _load()
    results["meta"]["elapsed_seconds"] = time.perf_counter() - start
    return results


# --------------------------------------------------------------------- output
def _fmt_time(entry: dict | None) -> str:
    if entry is None:
        return "—"
    return ("≤ " if entry["bound"] else "") + f"{entry['time']:.3g}"


def _fmt_ratio(x: float | None) -> str:
    return "—" if x is None else f"{x:.3g}"


def markdown(results: dict) -> str:
    """The results as Markdown tables."""
    meta = results["meta"]
    m = meta["machine"]
    lines = [
        "# galerkin_vi benchmark" + (" (quick)" if meta["quick"] else ""),
        "",
        f"{meta['date']}; {m['cpu']} ({m['cpus']} cores, shared); Python {m['python']}, "
        f"numpy {m['numpy']}, scipy {m['scipy']}, numba {m['numba']}; "
        f"load average {meta['load_average_start']} → {meta.get('load_average_end')}; "
        f"total {meta.get('elapsed_seconds', 0):.0f} s.",
        "",
        f"Times: {meta['timer']}. Error: {meta['error']}. Energy error: {meta['energy_error']}.",
        "",
    ]
    if results["per_step"]:
        lines += [
            "## Per step: galerkin_vi / hand-written kernel of the same method",
            "",
            "Same h, same Newton tolerance (1e-14, then until the increment stops decreasing), "
            "same initial guess (previous step's polynomial extrapolated); "
            "`save_every = n_steps`.",
            "",
            "| problem | method | h | steps | galerkin_vi ns/step | hand-written ns/step | "
            "ratio | Newton its gvi / hw | hw simplified Newton ns/step |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in results["per_step"]:
            simp = r["hw_simplified_ns_per_step"]
            lines.append(
                f"| {r['problem']} | {r['pair']} | {r['h']:.4g} | {r['n_steps']} | "
                f"{r['gvi_ns_per_step']:.1f} | {r['hw_ns_per_step']:.1f} | "
                f"**{r['ratio']:.2f}** | {r['gvi_newton_iterations']:.2f} / "
                f"{r['hw_newton_iterations']:.2f} | {'—' if simp is None else f'{simp:.1f}'} |"
            )
        overheads = [r["gvi_call_overhead_us"] for r in results["per_step"]]
        lines += [
            "",
            f"galerkin_vi's fixed cost per `integrate` call (1 step): "
            f"{min(overheads):.0f}–{max(overheads):.0f} µs.",
            "",
        ]
    for name, entry in results["problems"].items():
        targets = list(next(iter(entry["time_to_error"].values())).keys())
        lines += [
            f"## {name}: time to reach a final relative error (seconds)",
            "",
            f"T = {entry['t_final']:.6g}; reference: {entry['reference']}.",
        ]
        if entry["reference_checks"]:
            checks = ", ".join(f"{k} = {v:.1e}" for k, v in entry["reference_checks"].items())
            lines.append(f"Reference cross-checks: {checks}.")
        lines += [
            "",
            "| curve | " + " | ".join(targets) + " |",
            "|---|" + "---|" * len(targets),
        ]
        for label, tte in entry["time_to_error"].items():
            lines.append(f"| {label} | " + " | ".join(_fmt_time(tte[t]) for t in targets) + " |")
        lines += [
            "",
            "Best galerkin_vi configuration and peer time / best galerkin_vi time "
            "(> 1: galerkin_vi is faster; — : the peer or galerkin_vi did not reach the target "
            "within its sweep):",
            "",
            "| | " + " | ".join(targets) + " |",
            "|---|" + "---|" * len(targets),
        ]
        best = entry["best_galerkin_vi"]
        lines.append(
            "| best galerkin_vi | "
            + " | ".join(
                "—" if best[t] is None else f"{best[t]['config']}: {_fmt_time(best[t])} s"
                for t in targets
            )
            + " |"
        )
        peers = list(next(iter(entry["ratio_peer_over_best"].values())).keys())
        for peer in peers:
            lines.append(
                f"| {peer} | "
                + " | ".join(_fmt_ratio(entry["ratio_peer_over_best"][t][peer]) for t in targets)
                + " |"
            )
        lines.append("")
    lines += ["## All points", ""]
    for name, entry in results["problems"].items():
        lines += [
            f"### {name}",
            "",
            "| curve | h or rtol | time (s) | error | energy error | Newton its / nfev |",
            "|---|---|---|---|---|---|",
        ]
        for label, curve in entry["curves"].items():
            for p in curve["points"]:
                x = f"h={p['h']:.3g}" if "h" in p else f"rtol={p['rtol']:.0e}"
                ee = "—" if p["energy_error"] is None else f"{p['energy_error']:.1e}"
                st = (
                    f"{p['newton_iterations']:.2f}"
                    if "newton_iterations" in p
                    else f"{p.get('nfev', '')}"
                )
                lines.append(
                    f"| {label} | {x} | {p['time']:.3g} | {p['error']:.2e} | {ee} | {st} |"
                )
        lines.append("")
    return "\n".join(lines)


def _plots(results: dict, folder: str) -> list[str]:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    styles = {"galerkin_vi": "-", "hand-written": "--", "scipy": ":"}
    written = []
    for name, entry in results["problems"].items():
        for kind, ykey, ylabel in (
            ("precision", "error", "final relative position error"),
            ("energy", "energy_error", "max relative energy error"),
        ):
            fig, ax = plt.subplots(figsize=(9, 6.5))
            ax.set_prop_cycle(color=plt.get_cmap("tab20").colors)
            for label, curve in entry["curves"].items():
                pts = [p for p in curve["points"] if p.get(ykey) is not None]
                if not pts:
                    continue
                ax.loglog(
                    [p["time"] for p in pts],
                    [p[ykey] for p in pts],
                    styles.get(curve["family"], "-"),
                    marker="o",
                    markersize=3,
                    label=label,
                )
            ax.set_xlabel("CPU seconds (wall, min of repeats)")
            ax.set_ylabel(ylabel)
            ax.set_title(f"{name}: {ylabel} against time")
            ax.grid(True, which="both", alpha=0.3)
            ax.legend(fontsize=7)
            path = os.path.join(folder, f"{name}_{kind}.png")
            fig.savefig(path, dpi=110, bbox_inches="tight")
            plt.close(fig)
            written.append(path)
    return written


def _jsonable(x):
    if isinstance(x, dict):
        return {str(k): _jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [_jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def write_outputs(results: dict, folder: str, log: Callable[[str], None] = print) -> list[str]:
    """Write results.json, results.md and (if matplotlib is importable) PNG plots."""
    os.makedirs(folder, exist_ok=True)
    written = []
    path = os.path.join(folder, "results.json")
    with open(path, "w") as fh:
        json.dump(_jsonable(results), fh, indent=1)
    written.append(path)
    path = os.path.join(folder, "results.md")
    with open(path, "w") as fh:
        fh.write(markdown(results) + "\n")
    written.append(path)
    pngs = _plots(results, folder)
    if pngs:
        written += pngs
    else:
        log("matplotlib is not installed: PNG plots skipped (pip install matplotlib to get them)")
    return written
