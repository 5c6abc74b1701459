r"""Work-precision of galerkin_vi's methods on a user's model.

:func:`work_precision` answers "which method and step size is cheapest for the
accuracy I need, on my model and my machine?": for each method it sweeps the
number of steps :math:`N` (:math:`h = T/N`) geometrically from a coarse start
until the error reaches the round-off floor (below 1e-13, or three times in a
row not below 0.7 times the best error once that is below 1e-9) or one run took
longer than ``time_cap``. Each point records

* the wall time (``time.perf_counter``, minimum over ``repeats`` runs; the
  points of all methods are re-timed in interleaved rounds, so a burst of load
  hits every method alike), of runs that save only the first and last state;
* the final relative position error :math:`|q_N - q(T)| / |q(T)|`;
* the maximum relative energy error :math:`\max_k |H_k - H_0| / |H_0|` over
  about ``energy_samples`` saved states of one extra, untimed run.

From the curves: the time to reach each target error (first crossing,
interpolated linearly in log time against log error) and the fastest method
per target. :func:`markdown` and :func:`write_outputs` turn the result into a
table, JSON and plots. The command line is ``galerkin-vi bench --problem
module:attr``.

The comparison with hand-written kernels, scipy, numbalsoda and REBOUND on
fixed problems lives in the repository's ``benchmarks/`` folder (``python
benchmarks/run.py``); it builds on the helpers here.
"""

from __future__ import annotations

import json
import math
import os
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConvergenceError
from ..integrator import Integrator
from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..method.quadrature import QuadratureRule, gauss_legendre, gauss_lobatto
from ..model.system import LagrangianSystem
from ..run.trajectory import Trajectory

__all__ = [
    "TARGETS",
    "Curve",
    "Sample",
    "galerkin_curve",
    "markdown",
    "method_label",
    "plot",
    "step_counts",
    "sweep",
    "time_to_error",
    "tolerances",
    "work_precision",
    "write_outputs",
]

#: final relative errors at which the time to error is reported
TARGETS = (1e-4, 1e-8, 1e-11)

_FLOOR = 1e-13  # relative position errors below this are round-off: finer sweeps are wasted
# below this error, a fixed-step sweep that stops improving has reached round-off (the
# pre-asymptotic Kepler errors are not monotone down to about 1e-8)
_STALL_BELOW = 1e-9


# ---------------------------------------------------------------------- curves
@dataclass
class Sample:
    """Result of one untimed error run: final position, energies (or None), statistics."""

    q_final: NDArray[np.float64]
    energy: NDArray[np.float64] | None
    stats: dict


@dataclass
class Curve:
    """One line of a work-precision diagram.

    ``param_key`` names the swept parameter (``"n_steps"``, ``"rtol"`` or
    ``"epsilon"``), ``sweep`` its values in sweep order; ``sample`` makes the
    untimed error run, ``timed`` the timed one, ``warm`` compiles or loads.
    """

    label: str
    family: str  # "galerkin_vi", or a peer's family in benchmarks/
    kind: str  # "fixed-step" | "adaptive"
    order: int | None
    sample: Callable[[float], Sample]
    timed: Callable[[float], object]
    warm: Callable[[], object]
    param_key: str = "n_steps"
    sweep: Sequence[float] = ()
    points: list[dict] = field(default_factory=list)


def quadrature(s: int, family: str) -> QuadratureRule:
    """``gauss_lobatto(s + 1)`` for ``family="lobatto"``, ``gauss_legendre(s)`` for ``"gauss"``."""
    if family == "lobatto":
        return gauss_lobatto(s + 1)
    if family == "gauss":
        return gauss_legendre(s)
    raise ValueError(f"unknown quadrature family {family!r}")


def method_label(method: Galerkin | Composition) -> str:
    """Curve label of ``method``, e.g. ``"galerkin_vi s=2 Gauss(2)"`` or
    ``"galerkin_vi composition p=8 kahan_li(17)"``."""
    if isinstance(method, Composition):
        return f"galerkin_vi composition p={method.order} {method.scheme}({method.stages})"
    rule = method.quadrature
    name = "Lobatto" if rule.family == "gauss_lobatto" else "Gauss"
    nodes = "" if method.nodes == "lobatto" else f", {method.nodes} nodes"
    return f"galerkin_vi s={method.degree} {name}({rule.npoints}){nodes}"


def every(n: int, samples: int) -> int:
    """``save_every`` that keeps about ``samples`` of ``n`` steps."""
    return max(1, n // samples)


def step_counts(n_start: int, factor: float, n_max: int = 50_000_000) -> list[int]:
    """Step counts from ``n_start`` up by ``factor`` (rounded, increasing), at most ``n_max``."""
    out: list[int] = []
    x = float(n_start)
    while x <= n_max:
        n = int(round(x))
        if not out or n > out[-1]:
            out.append(n)
        x *= factor
    return out


def tolerances(start: float, min_rtol: float, factor: float) -> list[float]:
    """Tolerances from ``start`` down by ``factor``, ending at ``min_rtol`` itself."""
    out = []
    x = start
    while x >= min_rtol * 0.999:
        out.append(float(f"{x:.3g}"))
        x /= factor
    if not out or out[-1] > min_rtol * 1.001:
        out.append(min_rtol)
    return out


def galerkin_curve(
    system: LagrangianSystem,
    method: Galerkin | Composition,
    q0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    *,
    params: Mapping | None = None,
    n_start: int = 16,
    step_factor: float = 2.0,
    energy_samples: int = 1000,
    energy: Callable[[Trajectory], NDArray | None] | None = None,
    warm_h: float | None = None,
    specialize: bool | str = True,
) -> Curve:
    """The work-precision curve of one galerkin_vi method (not yet swept).

    Parameters
    ----------
    system : LagrangianSystem
    method : Galerkin or Composition
    q0, v0 : array_like, shape (n,)
        Initial positions and velocities.
    t_final : float
        Length of the span; a run of ``N`` steps has ``h = t_final / N``.
    params : mapping, optional
        Parameter values.
    n_start, step_factor : int, float
        First step count of the sweep and ratio of successive ones.
    energy_samples : int
        About this many states of the error run are saved for the energy error.
    energy : callable, optional
        ``trajectory -> H`` at its saved states (default ``Trajectory.energy``).
    warm_h : float, optional
        Step of the 10-step warm-up run (default ``t_final / n_start``).
    specialize : bool or "system"
        The integrator's (:class:`~galerkin_vi.Integrator`); the warm-up run compiles
        what it generates.
    """
    integ = Integrator(system, method, specialize=specialize)
    prm = params
    warm_step = t_final / n_start if warm_h is None else warm_h

    def energy_of(traj: Trajectory) -> NDArray | None:
        return traj.energy() if energy is None else energy(traj)

    def timed(n: float) -> Trajectory:
        n = int(n)
        return integ.integrate(
            q0, v0, h=t_final / n, n_steps=n, save_every=n, params=prm, on_failure="raise"
        )

    def sample(n: float) -> Sample:
        n = int(n)
        traj = integ.integrate(
            q0,
            v0,
            h=t_final / n,
            n_steps=n,
            save_every=every(n, energy_samples),
            params=prm,
            on_failure="raise",
        )
        return Sample(
            traj.q[-1], energy_of(traj), {"newton_iterations": traj.mean_newton_iterations}
        )

    def warm() -> Trajectory:
        return integ.integrate(q0, v0, h=warm_step, n_steps=10, params=prm, on_failure="raise")

    return Curve(
        method_label(method),
        "galerkin_vi",
        "fixed-step",
        method.order,
        sample,
        timed,
        warm,
        sweep=step_counts(n_start, step_factor),
    )


# ---------------------------------------------------------------------- sweeps
def clock(fn: Callable[[], object]) -> float:
    """Wall seconds of one call of ``fn``."""
    start = time.perf_counter()
    fn()
    return time.perf_counter() - start


def _relative(value: float, scale: float) -> float:
    return value / scale if scale != 0 else value


def sweep(
    curve: Curve,
    q_ref: NDArray,
    energy0: float,
    t_final: float,
    time_cap: float,
    adaptive_time_cap: float | None = None,
    log: Callable[[str], None] = print,
) -> None:
    """Fill ``curve.points`` by one sweep (error run and one timed run per point).

    Errors are relative to ``|q_ref|`` and ``|energy0|`` (absolute when those are 0).
    A sweep stops at the round-off floor or once a run took longer than ``time_cap``
    (``adaptive_time_cap`` for adaptive curves); more than four failures before the
    first point end it too.
    """
    best = math.inf
    failures = stalled = 0
    q_scale = float(np.linalg.norm(q_ref))
    cap = time_cap if curve.kind == "fixed-step" or adaptive_time_cap is None else adaptive_time_cap
    for param in curve.sweep:
        try:
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                smp = curve.sample(param)
            elapsed = clock(lambda p=param: curve.timed(p))
        except (ConvergenceError, RuntimeError, FloatingPointError, ValueError) as exc:
            failures += 1
            log(f"    {curve.label}: {param:g} failed ({type(exc).__name__})")
            if failures > 4 and not curve.points:
                return
            continue
        err = _relative(float(np.linalg.norm(smp.q_final - q_ref)), q_scale)
        energy_error = None
        if smp.energy is not None and smp.energy.size:
            energy_error = _relative(float(np.max(np.abs(smp.energy - energy0))), abs(energy0))
        point = {
            curve.param_key: param,
            "time": elapsed,
            "error": err,
            "energy_error": energy_error,
            **smp.stats,
        }
        if curve.kind == "fixed-step":
            point["h"] = t_final / param
        curve.points.append(point)
        if not math.isfinite(err):
            continue
        if err < _FLOOR:
            break
        # at the round-off floor: three times no real improvement on an accurate fixed-step
        # curve (adaptive sweeps run to their tightest rtol: their error falls slowly and
        # unevenly with rtol)
        if best < _STALL_BELOW and err > 0.7 * best:
            stalled += 1
        if curve.kind == "fixed-step" and stalled >= 3:
            break
        best = min(best, err)
        if elapsed > cap:
            break


def retime(curves: Sequence[Curve], repeats: int) -> None:
    """Re-time every point in ``repeats - 1`` further interleaved rounds; keep the minimum."""
    jobs = [(c, p) for c in curves for p in c.points]
    for rnd in range(repeats - 1):
        for curve, point in jobs if rnd % 2 else reversed(jobs):
            param = point[curve.param_key]
            try:
                elapsed = clock(lambda c=curve, p=param: c.timed(p))
            except (ConvergenceError, RuntimeError, ValueError):
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


def summarise(curves: Sequence[Curve], targets: Sequence[float]) -> dict:
    """Time to each target per curve, the best galerkin_vi curve, and each other curve's ratio.

    Returns ``{"time_to_error": {label: {target: ...}}, "best_galerkin_vi": {target:
    {"config", "time", "bound"} or None}, "ratio_peer_over_best": {target: {label: ratio}}}``
    with targets as ``f"{t:g}"`` strings; the ratios cover the curves whose family is not
    ``"galerkin_vi"`` (none for a galerkin_vi-only study).
    """
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


# ------------------------------------------------------------------------ study
def _final_reference(
    system: LagrangianSystem,
    q0: NDArray,
    v0: NDArray,
    t_final: float,
    reference: ArrayLike | Callable | None,
    params: Mapping | None,
) -> NDArray[np.float64]:
    if reference is None:
        from ..problems import ode_reference

        return np.asarray(ode_reference(system, q0, v0, t_final, params), dtype=float)
    if callable(reference):
        return np.asarray(reference(t_final), dtype=float)
    return np.asarray(reference, dtype=float)


def work_precision(
    system: LagrangianSystem,
    q0: ArrayLike,
    v0: ArrayLike,
    t_final: float,
    methods: Sequence[Galerkin | tuple[int, str]],
    reference: ArrayLike | Callable[[float], ArrayLike] | None = None,
    *,
    params: Mapping | None = None,
    targets: Sequence[float] = TARGETS,
    n_start: int = 16,
    step_factor: float = 2.0,
    time_cap: float = 0.2,
    repeats: int = 2,
    energy_samples: int = 1000,
    log: Callable[[str], None] | None = None,
) -> dict:
    """Work-precision curves of galerkin_vi ``methods`` on a model.

    Parameters
    ----------
    system : LagrangianSystem
    q0, v0 : array_like, shape (n,)
        Initial positions and velocities at t = 0.
    t_final : float
        Length of the span; errors are measured at its end.
    methods : sequence of Galerkin or (int, str)
        Methods, or (degree, ``"lobatto"`` | ``"gauss"``) pairs for
        ``Galerkin(s, gauss_lobatto(s + 1))`` and ``Galerkin(s, gauss_legendre(s))``.
    reference : array_like or callable, optional
        The exact (or trusted) final position q(t_final), or ``t -> q(t)``.
        Default: DOP853 on the Euler–Lagrange equations at rtol 1e-13
        (:func:`~galerkin_vi.problems.ode_reference`; unconstrained systems only).
    params : mapping, optional
        Parameter values.
    targets : sequence of float
        Final relative errors for the time-to-error table.
    n_start, step_factor : int, float
        First step count of every sweep and the ratio of successive ones.
    time_cap : float
        A sweep stops once one run took longer than this (seconds).
    repeats : int
        Timed runs per point (minimum reported), in interleaved rounds.
    energy_samples : int
        States saved by the untimed error run, for the energy error.
    log : callable, optional
        Receives progress lines (default: silent).

    Returns
    -------
    dict
        ``{"t_final", "reference_position", "energy0", "targets", "first_call_seconds",
        "seconds", "curves": {label: {"family", "kind", "order", "param", "points"}},
        "time_to_error": {label: {target: {"time", "bound"} or None}},
        "best_galerkin_vi": {target: {"config", "time", "bound"} or None}}``; every point
        has ``n_steps``, ``h``, ``time``, ``error``, ``energy_error`` and
        ``newton_iterations``. Plain data, ready for JSON.
    """
    say = log if log is not None else (lambda _msg: None)
    start = time.perf_counter()
    q0 = np.asarray(q0, dtype=float)
    v0 = np.asarray(v0, dtype=float)
    t_final = float(t_final)
    chosen = [m if isinstance(m, Galerkin) else Galerkin(m[0], quadrature(*m)) for m in methods]
    q_ref = _final_reference(system, q0, v0, t_final, reference, params)
    curves = [
        galerkin_curve(
            system,
            m,
            q0,
            v0,
            t_final,
            params=params,
            n_start=n_start,
            step_factor=step_factor,
            energy_samples=energy_samples,
        )
        for m in chosen
    ]
    first_call = {c.label: clock(c.warm) for c in curves}
    energy0 = float(system.hamiltonian(q0, system.legendre(q0, v0, 0.0, params), 0.0, params))
    for curve in curves:
        sweep(curve, q_ref, energy0, t_final, time_cap, log=say)
        if curve.points:
            last = curve.points[-1]
            say(
                f"  {curve.label:40s} {len(curve.points):3d} points, last: "
                f"{last['time']:.3g} s, error {last['error']:.2e}"
            )
    curves = [c for c in curves if c.points]
    retime(curves, repeats)
    summary = summarise(curves, targets)
    return {
        "t_final": t_final,
        "reference_position": q_ref.tolist(),
        "energy0": energy0,
        "targets": [f"{t:g}" for t in targets],
        "first_call_seconds": first_call,
        "seconds": time.perf_counter() - start,
        "curves": {
            c.label: {
                "family": c.family,
                "kind": c.kind,
                "order": c.order,
                "param": c.param_key,
                "points": c.points,
            }
            for c in curves
        },
        "time_to_error": summary["time_to_error"],
        "best_galerkin_vi": summary["best_galerkin_vi"],
    }


# ---------------------------------------------------------------------- output
def format_time(entry: dict | None) -> str:
    """A time-to-error cell: seconds, ``≤`` for an upper bound, ``—`` when not reached."""
    if entry is None:
        return "—"
    return ("≤ " if entry["bound"] else "") + f"{entry['time']:.3g}"


def points_lines(curves: Mapping[str, dict]) -> list[str]:
    """Markdown table of every measured point of ``curves`` (a result's ``"curves"``)."""
    lines = [
        "| curve | h or rtol | time (s) | error | energy error | Newton its / nfev |",
        "|---|---|---|---|---|---|",
    ]
    for label, curve in curves.items():
        for p in curve["points"]:
            key = curve.get("param", "n_steps" if "h" in p else "rtol")
            x = f"h={p['h']:.3g}" if "h" in p else f"{key}={p[key]:.0e}"
            ee = "—" if p["energy_error"] is None else f"{p['energy_error']:.1e}"
            st = (
                f"{p['newton_iterations']:.2f}"
                if "newton_iterations" in p
                else f"{p.get('nfev', '')}"
            )
            lines.append(f"| {label} | {x} | {p['time']:.3g} | {p['error']:.2e} | {ee} | {st} |")
    return lines


def markdown(result: dict, title: str = "model", points: bool = True) -> str:
    """A :func:`work_precision` result as Markdown: time to error, fastest method, all points.

    ``points=False`` leaves out the table of every measured point.
    """
    targets = list(result["targets"])
    lines = [
        f"# galerkin_vi work-precision: {title}",
        "",
        f"T = {result['t_final']:.6g}; error: final relative position error "
        "|q_N - q(T)| / |q(T)|; times: minimum over repeats, seconds.",
        "",
        "## Time to reach a final relative error (seconds)",
        "",
        "| method | " + " | ".join(targets) + " |",
        "|---|" + "---|" * len(targets),
    ]
    for label, tte in result["time_to_error"].items():
        lines.append(f"| {label} | " + " | ".join(format_time(tte[t]) for t in targets) + " |")
    best = result["best_galerkin_vi"]
    lines.append(
        "| **fastest** | "
        + " | ".join("—" if best[t] is None else best[t]["config"] for t in targets)
        + " |"
    )
    lines.append("")
    if points:
        lines += ["## All points", "", *points_lines(result["curves"]), ""]
    return "\n".join(lines)


def plot(
    entry: dict,
    folder: str,
    name: str,
    title: str | None = None,
    styles: Mapping[str, str] | None = None,
) -> list[str] | None:
    """``<name>_precision.png`` and ``<name>_energy.png`` in ``folder``; None without matplotlib.

    ``entry`` has ``"curves"`` as in a :func:`work_precision` result; ``styles`` maps a
    curve family to a line style.
    """
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    styles = styles or {}
    written = []
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
        ax.set_xlabel("wall seconds (minimum of repeats)")
        ax.set_ylabel(ylabel)
        ax.set_title(f"{title or name}: {ylabel} against time")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
        path = os.path.join(folder, f"{name}_{kind}.png")
        fig.savefig(path, dpi=110, bbox_inches="tight")
        plt.close(fig)
        written.append(path)
    return written


def jsonable(x: object) -> object:
    """``x`` with numpy scalars made Python numbers and non-finite floats None."""
    if isinstance(x, dict):
        return {str(k): jsonable(v) for k, v in x.items()}
    if isinstance(x, (list, tuple)):
        return [jsonable(v) for v in x]
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    if isinstance(x, float) and not math.isfinite(x):
        return None
    return x


def write_outputs(results: Mapping[str, dict], folder: str) -> list[str]:
    """Write ``work_precision.json``, ``work_precision.md`` and per-model PNG plots.

    ``results`` maps a model's name to its :func:`work_precision` result. Returns the
    paths written.
    """
    os.makedirs(folder, exist_ok=True)
    path = os.path.join(folder, "work_precision.json")
    with open(path, "w") as fh:
        json.dump(jsonable(dict(results)), fh, indent=1)
    written = [path]
    path = os.path.join(folder, "work_precision.md")
    with open(path, "w") as fh:
        fh.write("\n".join(markdown(r, name) for name, r in results.items()))
    written.append(path)
    for name, result in results.items():
        written += plot(result, folder, name) or []
    return written
