r"""Choosing the order and step size that reach an error tolerance at the least cost.

:func:`choose_method` runs short pilot integrations of every candidate method,
fits an error model to them, predicts the step size each candidate needs over the
whole span and the time that run would take, and returns the cheapest.

The model
---------
**Error.** The error is the final position error in the max-norm,
:math:`e = \|q_N - q(t_0 + T)\|_\infty` (absolute; with ``relative=True`` the
tolerance is multiplied by the size of the solution, :math:`\max_k \|q(t_k)\|_\infty`
over the pilot span). For a method of predicted order :math:`p = 2s` (degree
:math:`s` with Gauss :math:`s` or Lobatto :math:`s + 1` points) the pilot runs
over the span :math:`T_p` measure

.. math::

    E_p(h) = \max_{j = 1..m} \|q_h(t_0 + jT_p/m) - q(t_0 + jT_p/m)\|_\infty
    \approx C\,h^{p}

at 2–4 step sizes, with :math:`m = 8` sample times (the maximum over samples,
unlike the error at one time, cannot pass through zero by a chance of phase).
The error over the whole span is extrapolated by **linear growth in time**,

.. math::

    e(T; h) \approx \frac{T}{T_p}\, E_p(h),

the behaviour of symplectic integrators on integrable (and near-integrable)
problems, whose error is dominated by a phase drift [1]_. This is a model: a
chaotic problem's error grows exponentially and is underestimated, a problem
whose error stays bounded is overestimated. The pilot span should cover at
least one characteristic period, so that the maximum over it sees a whole
oscillation of the error.

**Fit.** :math:`E_p` is anchored at the finest pilot step :math:`h_f` that is
above the noise floor. Towards smaller :math:`h` the error is assumed to fall
no faster than :math:`h^{k}` with :math:`k = \min(p, \hat p)`, where
:math:`\hat p` is the slope measured between the two finest pilot runs (so
pre-asymptotic or round-off-limited pilots make the prediction conservative,
never optimistic); towards larger :math:`h` it grows no slower than
:math:`h^{\max(p, \hat p)}`, and :math:`h` never exceeds the coarsest pilot
step that converged. The step size is the largest :math:`h = T/N` with
:math:`e(T; h) \le \mathrm{tol}/\mathrm{safety}` (default safety factor 4).

**Reference.** The pilot errors are measured against ``reference`` (a
function :math:`t \mapsto q(t)`) when given, otherwise against a run of the
degree-:math:`\max(6, s_{\max})` Gauss method at :math:`N` and :math:`2N`
steps combined by Richardson extrapolation, :math:`N` doubled until the
estimated reference error stops falling. Pilot errors below ten times the
reference error or the round-off allowance :math:`10 N \varepsilon \max|q|`
are not used.

**Round-off** is not in the model: a run of :math:`N` steps carries a
round-off error that grows with :math:`N` (on Kepler: up to
:math:`5\times10^{-11}` after :math:`7\times10^{4}` steps), so tolerances within a
few orders of magnitude of :math:`N\varepsilon\max|q|` are not reliably met;
a ``RuntimeWarning`` says when the aimed-at error is below that estimate for
the chosen run.

**Cost.** The predicted cost is :math:`t_1 + (N - 1)\,\tau`: the measured wall
time :math:`t_1` of a one-step call (the fixed cost of a call) plus :math:`N - 1`
times the measured time per step :math:`\tau`, timed at the candidate's own
step size over :math:`\min(N, 2000)` steps (minimum of five rounds that
interleave the candidates, after the pilots, so that compilation is never timed;
nothing is compiled again, whatever the method or step size). On a
loaded machine this is the uncontended time: long runs take longer than
predicted, for every candidate alike.

References
----------
.. [1] E. Hairer, C. Lubich, G. Wanner, *Geometric Numerical Integration*,
   2nd ed., Springer 2006, Section X.3 (linear error growth of symplectic
   methods for integrable systems).
"""

from __future__ import annotations

import math
import numbers
import time
import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConvergenceError
from ..integrator import Integrator
from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..method.quadrature import gauss_legendre, gauss_lobatto
from ..model.system import LagrangianSystem
from ..reference import resolve_backend
from ..run.loop_choice import composition_for, composition_obstacle

__all__ = ["Candidate", "MethodChoice", "choose_method"]

_EPS = float(np.finfo(float).eps)
_FAMILIES = ("gauss", "lobatto")
#: sample times per pilot span (pilot step counts are multiples of it)
SAMPLES = 8
#: pilot errors above this fraction of the solution's size are not asymptotic
UPPER_ERROR = 1e-3
#: most pilot runs per candidate, and most of them that are used in the fit
MAX_PROBES = 12
MAX_POINTS = 4
#: largest ratio between successive pilot step counts
MAX_JUMP = 8.0
REFERENCE_MIN_DEGREE = 6
REFERENCE_MAX_STEPS = 1 << 16


@dataclass(frozen=True)
class Candidate:
    """One candidate method of :func:`choose_method`: its pilots and its prediction.

    Attributes
    ----------
    method : Galerkin | Composition
    label : str
        Short name, e.g. ``"s=2 Gauss(2)"``.
    order : int
        Predicted order :math:`p`.
    pilot_steps : tuple of int
        Step counts over the pilot span of the pilot runs used in the fit.
    pilot_errors : tuple of float
        Their errors :math:`E_p` (maximum over the sample times).
    measured_order : float
        Slope between the two finest pilot runs (NaN with fewer than two).
    h : float
        Predicted step size for the whole span (NaN if the candidate failed).
    n_steps : int
        Steps of size ``h`` over ``t_final`` (0 if failed).
    predicted_error : float
        Model error :math:`e(T; h)`.
    time_per_step : float
        Measured seconds per step at ``h``.
    predicted_cost : float
        Predicted wall time of the whole run in seconds (inf if failed).
    status : str
        ``"ok"`` or why the candidate was dropped.
    """

    method: Galerkin | Composition
    label: str
    order: int
    pilot_steps: tuple[int, ...]
    pilot_errors: tuple[float, ...]
    measured_order: float
    h: float
    n_steps: int
    predicted_error: float
    time_per_step: float
    predicted_cost: float
    status: str = "ok"

    @property
    def ok(self) -> bool:
        """Whether the candidate has a prediction."""
        return self.status == "ok"


@dataclass(frozen=True)
class MethodChoice:
    """Result of :func:`choose_method`: the cheapest method and step size for the tolerance.

    Attributes
    ----------
    method : Galerkin | Composition
        The chosen method.
    h : float
        Its step size, ``t_final / n_steps``.
    n_steps : int
    predicted_error : float
        Model prediction of the final position error (absolute, max-norm).
    predicted_cost : float
        Predicted wall time of the run, seconds.
    candidates : tuple of Candidate
        Every candidate, in the order tried.
    tol : float
        The requested tolerance; ``atol`` is the absolute error it means
        (``tol`` itself, or ``tol`` times the solution's size when ``relative``).
    atol : float
    t_final, pilot_span : float
    safety : float
        The prediction aims at ``atol / safety``.
    reference_error : float
        Estimated error of the pilot reference (0 for a given reference).
    elapsed : float
        Seconds spent choosing (pilots, reference and timings).
    """

    method: Galerkin | Composition
    h: float
    n_steps: int
    predicted_error: float
    predicted_cost: float
    candidates: tuple[Candidate, ...]
    tol: float
    atol: float
    t_final: float
    pilot_span: float
    safety: float
    reference_error: float
    elapsed: float

    @property
    def order(self) -> int:
        """Predicted order of the chosen method."""
        return self.method.order

    @property
    def chosen(self) -> Candidate:
        """The chosen candidate's row."""
        return next(c for c in self.candidates if c.method == self.method and c.ok)

    def markdown(self) -> str:
        """The candidates as a markdown table, cheapest first; the choice is marked ``*``."""
        header = (
            "| | method | order | pilot N | pilot errors | slope | h | N | "
            "pred. error | time/step | pred. cost |\n"
            "|---|---|---:|---|---|---:|---:|---:|---:|---:|---:|"
        )
        rows = [header]
        ranked = sorted(self.candidates, key=lambda c: (not c.ok, c.predicted_cost))
        for c in ranked:
            mark = "*" if c.ok and c.method == self.method else ""
            pilots = ", ".join(str(n) for n in c.pilot_steps)
            errors = ", ".join(f"{e:.1e}" for e in c.pilot_errors)
            if not c.ok:
                rows.append(
                    f"| | {c.label} | {c.order} | {pilots} | {errors} | | | | | | {c.status} |"
                )
                continue
            slope = "" if math.isnan(c.measured_order) else f"{c.measured_order:.2f}"
            rows.append(
                f"| {mark} | {c.label} | {c.order} | {pilots} | {errors} | {slope} | "
                f"{c.h:.3e} | {c.n_steps} | {c.predicted_error:.2e} | "
                f"{_fmt_seconds(c.time_per_step)} | {_fmt_seconds(c.predicted_cost)} |"
            )
        return "\n".join(rows)

    def __str__(self) -> str:
        relative = "" if self.atol == self.tol else f" (absolute {self.atol:.3g})"
        return (
            f"MethodChoice: {_label(self.method)} (order {self.order}), h = {self.h:.6g}, "
            f"n_steps = {self.n_steps}; predicted error {self.predicted_error:.2e} "
            f"<= tol/{self.safety:g} for tol = {self.tol:.3g}{relative} over "
            f"t_final = {self.t_final:g}; predicted cost {_fmt_seconds(self.predicted_cost)}\n"
            f"(pilot span {self.pilot_span:g}, reference error {self.reference_error:.1e}, "
            f"chosen in {self.elapsed:.2f} s)\n\n" + self.markdown()
        )


def _fmt_seconds(x: float) -> str:
    if not math.isfinite(x):
        return "inf"
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if x >= scale:
            return f"{x / scale:.3g} {unit}"
    return f"{x * 1e9:.3g} ns"


def _label(method: Galerkin | Composition) -> str:
    if isinstance(method, Composition):
        return f"composition {method.scheme} p={method.order} ({method.stages} stages)"
    q = method.quadrature
    family = "Gauss" if q.family == "gauss_legendre" else "Lobatto"
    nodes = "" if method.nodes == "lobatto" else f", {method.nodes} nodes"
    return f"s={method.degree} {family}({q.npoints}){nodes}"


def _candidate_methods(
    degrees: Sequence[int],
    families: Sequence[str],
    methods: Sequence[Galerkin | Composition] | None,
    compositions: Sequence[int] = (),
) -> list[Galerkin | Composition]:
    if methods is not None:
        methods = list(methods)
        if not methods or not all(isinstance(m, (Galerkin, Composition)) for m in methods):
            raise TypeError(
                "methods must be a non-empty sequence of Galerkin or Composition methods"
            )
        return methods
    if isinstance(families, str):
        raise TypeError(f"families must be a sequence of names, got the string {families!r}")
    families = list(families)
    if not families or any(f not in _FAMILIES for f in families):
        raise ValueError(f"families must be a non-empty subset of {_FAMILIES}, got {families}")
    degrees = list(degrees)
    if not degrees or any(
        isinstance(s, bool) or not isinstance(s, numbers.Integral) or s < 1 for s in degrees
    ):
        raise ValueError(f"degrees must be a non-empty sequence of ints >= 1, got {degrees}")
    out = []
    for s in sorted(set(int(s) for s in degrees)):
        for family in families:
            rule = gauss_legendre(s) if family == "gauss" else gauss_lobatto(s + 1)
            out.append(Galerkin(s, rule))
    if isinstance(compositions, str):
        raise TypeError(f"compositions must be a sequence of orders, got {compositions!r}")
    out.extend(Composition(order) for order in sorted(set(compositions)))
    return out


def _positive(name: str, x: object) -> float:
    if isinstance(x, bool) or not isinstance(x, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {x!r}")
    value = float(x)
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"{name} must be finite and > 0, got {x!r}")
    return value


class _Pilot:
    """Runs of one system from one initial state over the pilot span, with timing."""

    def __init__(self, system, q0, v0, p0, t0, params, span, backend):
        self.system, self.q0, self.v0, self.p0 = system, q0, v0, p0
        self.t0, self.params, self.span, self.backend = t0, params, span, backend
        self.integrators: dict[Galerkin | Composition, Integrator] = {}

    def integrator(self, method: Galerkin | Composition) -> Integrator:
        if method not in self.integrators:
            self.integrators[method] = Integrator(self.system, method, backend=self.backend)
        return self.integrators[method]

    def samples(self, method: Galerkin | Composition, n_steps: int) -> NDArray[np.float64]:
        """Positions at the ``SAMPLES`` sample times, shape (SAMPLES, n)."""
        traj = self.integrator(method).integrate(
            self.q0,
            self.v0,
            self.p0,
            h=self.span / n_steps,
            n_steps=n_steps,
            t0=self.t0,
            params=self.params,
            save_every=n_steps // SAMPLES,
            on_failure="raise",
        )
        return traj.q[1:]

    def wall_time(self, method: Galerkin | Composition, h: float, n_steps: int) -> float:
        """Seconds of one call integrating ``n_steps`` steps of size ``h``."""
        integrator = self.integrator(method)
        start = time.perf_counter()
        integrator.integrate(
            self.q0,
            self.v0,
            self.p0,
            h=h,
            n_steps=n_steps,
            t0=self.t0,
            params=self.params,
            save_every=n_steps,
            on_failure="raise",
        )
        return time.perf_counter() - start


def _given_reference(reference: Callable, times: NDArray, n: int) -> NDArray[np.float64]:
    try:
        values = np.asarray(reference(times), dtype=float)
    except (TypeError, ValueError):
        values = None
    if values is None or values.shape != (times.size, n):
        values = np.array([np.asarray(reference(t), dtype=float).ravel() for t in times])
    if values.shape != (times.size, n):
        raise ValueError(
            f"reference(t) must return the {n} positions at time t, got shape {values.shape}"
        )
    if not np.all(np.isfinite(values)):
        raise ValueError("reference returned NaN or inf")
    return values


def _richardson_reference(pilot: _Pilot, degree: int) -> tuple[NDArray[np.float64], float]:
    """Reference samples by Richardson extrapolation of a high-order Gauss method.

    Doubles the step count until the error estimate :math:`|q_{2N} - q_N|/(2^p - 1)`
    of :math:`q_{2N}` stops falling (round-off) or is at the round-off level.
    """
    method = Galerkin(degree, gauss_legendre(degree))
    factor = 2.0**method.order - 1.0
    n = 8 * SAMPLES
    coarse = None
    best: tuple[NDArray[np.float64], float] | None = None
    while n <= REFERENCE_MAX_STEPS:
        try:
            fine = pilot.samples(method, n)
        except ConvergenceError:
            if best is not None:
                break
            coarse, n = None, 2 * n  # too coarse for Newton: refine
            continue
        if coarse is None:
            coarse, n = fine, 2 * n
            continue
        estimate = float(np.max(np.abs(fine - coarse))) / factor
        candidate = (fine + (fine - coarse) / factor, estimate)
        if best is not None and estimate > 0.25 * best[1]:
            break
        best = candidate
        scale = max(1.0, float(np.max(np.abs(fine))))
        if estimate <= 0.1 * n * _EPS * scale:  # at the round-off level of the run
            break
        coarse, n = fine, 2 * n
    if best is None:
        raise RuntimeError(
            f"could not compute a reference solution over the pilot span {pilot.span:g} "
            f"(degree {degree} Gauss, up to {REFERENCE_MAX_STEPS} steps); pass reference="
        )
    return best


def _probe(
    pilot: _Pilot,
    method: Galerkin | Composition,
    reference: NDArray[np.float64],
    reference_error: float,
    scale: float,
    pilot_target: float,
    max_pilot_steps: int,
) -> tuple[list[tuple[int, float]], str]:
    """Pilot runs of ``method``: the points ``(n_steps, error)`` to fit and a status."""
    p = method.order
    upper = UPPER_ERROR * scale
    points: list[tuple[int, float]] = []
    n = SAMPLES
    failures = 0
    for _ in range(MAX_PROBES):
        if n > max_pilot_steps:
            break
        try:
            error = float(np.max(np.abs(pilot.samples(method, n) - reference)))
        except ConvergenceError:
            error = math.inf
            failures += 1
        floor = max(10.0 * reference_error, 10.0 * n * _EPS * scale)
        if not error <= upper:
            if points:
                break
            n *= 2
            continue
        if error <= floor:
            if not points:
                # already at the floor: the floor bounds the error (conservative)
                points.append((n, floor))
            break
        points.append((n, error))
        goal = max(pilot_target, 10.0 * floor)
        if error <= goal or len(points) >= MAX_POINTS:
            break
        jump = 2.0 if len(points) == 1 else min(max((error / goal) ** (1.0 / p), 1.5), MAX_JUMP)
        n = SAMPLES * math.ceil(n * jump / SAMPLES)
    if len(points) == 1 and points[0][0] >= 2 * SAMPLES:
        # one point only: add a coarser one for the slope
        n = points[0][0] // 2
        n -= n % SAMPLES
        try:
            error = float(np.max(np.abs(pilot.samples(method, n) - reference)))
        except ConvergenceError:
            error = math.inf
        if points[0][1] < error <= upper:
            points.insert(0, (n, error))
    if not points:
        reason = "Newton failed" if failures else f"pilot errors above {upper:.1e}"
        return [], f"dropped: {reason} up to {min(n, max_pilot_steps)} pilot steps"
    return points, "ok"


def _predict(
    points: list[tuple[int, float]],
    order: int,
    span: float,
    t_final: float,
    target: float,
) -> tuple[float, int, float, float]:
    """Step size, step count, predicted error and measured slope from the pilot points."""
    steps = np.array([n for n, _ in points], dtype=float)
    errors = np.array([e for _, e in points])
    h_pilot = span / steps
    if len(points) >= 2:
        slope = float(np.log(errors[-2] / errors[-1]) / np.log(h_pilot[-2] / h_pilot[-1]))
    else:
        slope = math.nan
    measured = order if math.isnan(slope) else slope
    k_fine = min(max(measured, 1.0), order)
    k_coarse = max(measured, order)
    growth = t_final / span
    h_f, e_f = h_pilot[-1], errors[-1]

    def model(h: float) -> float:
        k = k_fine if h <= h_f else k_coarse
        return e_f * (h / h_f) ** k * growth

    if model(h_f) > target:
        h = h_f * (target / (e_f * growth)) ** (1.0 / k_fine)
    else:
        h = min(h_f * (target / (e_f * growth)) ** (1.0 / k_coarse), h_pilot[0])
    n_steps = max(1, math.ceil(t_final / h * (1.0 - 1e-12)))
    h = t_final / n_steps
    return h, n_steps, model(h), slope


def _timed(
    pilot: _Pilot, rows: list[Candidate], timing_steps: int, repeats: int
) -> list[Candidate]:
    """``rows`` with the measured time per step and the predicted cost filled in.

    Each candidate runs ``min(n_steps, timing_steps)`` steps at its own ``h``
    (and one step, for the fixed cost of a call) once per round; the rounds
    interleave the candidates, so a burst of load on the machine hits all alike,
    and the minimum over the rounds is kept.
    """
    best = {i: [math.inf, math.inf] for i, c in enumerate(rows) if c.ok}
    failed: dict[int, str] = {}
    for _ in range(repeats):
        for i, c in enumerate(rows):
            if i not in best or i in failed:
                continue
            n_time = min(c.n_steps, timing_steps)
            try:
                best[i][0] = min(best[i][0], pilot.wall_time(c.method, c.h, n_time))
                if n_time < c.n_steps:
                    best[i][1] = min(best[i][1], pilot.wall_time(c.method, c.h, 1))
            except ConvergenceError as exc:
                failed[i] = f"dropped: Newton failed at the chosen h (t = {exc.t:g})"
    out = []
    for i, c in enumerate(rows):
        if i in failed:
            c = replace(c, status=failed[i])
        elif i in best:
            run_time, one = best[i]
            n_time = min(c.n_steps, timing_steps)
            if n_time < c.n_steps:
                per_step = max(run_time - one, 0.0) / (n_time - 1)
                cost = one + (c.n_steps - 1) * per_step
            else:
                per_step, cost = run_time / c.n_steps, run_time
            c = replace(c, time_per_step=per_step, predicted_cost=cost)
        out.append(c)
    return out


def _check_counts(max_pilot_steps: object, timing_steps: object, repeats: object) -> None:
    """Raise ``ValueError`` unless the pilot and timing counts are large enough ints."""
    for name, value, least in (
        ("max_pilot_steps", max_pilot_steps, 4 * SAMPLES),
        ("timing_steps", timing_steps, 2),
        ("repeats", repeats, 1),
    ):
        if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < least:
            raise ValueError(f"{name} must be an int >= {least}, got {value!r}")


def _check_arguments(
    system: object,
    q0: ArrayLike,
    v0: ArrayLike | None,
    p0: ArrayLike | None,
    *,
    t_final: object,
    tol: object,
    safety: object,
    pilot_span: object,
    reference: object,
    max_pilot_steps: object,
    timing_steps: object,
    repeats: object,
    t0: object,
) -> tuple[float, float, float, float, NDArray[np.float64], float]:
    """Validate the arguments of :func:`choose_method`.

    Returns ``(t_final, tol, safety, span, q0, t0)`` as floats and a float array.
    """
    if not isinstance(system, LagrangianSystem):
        raise TypeError(f"system must be a LagrangianSystem, got {type(system).__name__}")
    t_final = _positive("t_final", t_final)
    tol = _positive("tol", tol)
    safety = _positive("safety", safety)
    if safety < 1:
        raise ValueError(f"safety must be >= 1, got {safety}")
    span = t_final / 10 if pilot_span is None else _positive("pilot_span", pilot_span)
    if span > t_final:
        raise ValueError(f"pilot_span must be <= t_final = {t_final}, got {span}")
    _check_counts(max_pilot_steps, timing_steps, repeats)
    if reference is not None and not callable(reference):
        raise TypeError("reference must be a callable t -> q(t)")
    if (v0 is None) == (p0 is None):
        raise ValueError("give exactly one of v0 (velocities) and p0 (momenta)")
    q0 = np.asarray(q0, dtype=float)
    if q0.shape != (system.n,):
        raise ValueError(f"q0 must have shape ({system.n},), got {q0.shape}")
    return t_final, tol, safety, span, q0, float(t0)


def _reference_samples(
    pilot: _Pilot, reference: Callable | None, candidates: Sequence[Galerkin | Composition]
) -> tuple[NDArray[np.float64], float]:
    """Reference positions at the pilot sample times and their estimated error."""
    times = pilot.t0 + pilot.span * np.arange(1, SAMPLES + 1) / SAMPLES
    if reference is not None:
        return _given_reference(reference, times, pilot.system.n), 0.0
    # at least as accurate as the most accurate candidate
    degree = max(REFERENCE_MIN_DEGREE, *(m.order // 2 for m in candidates))
    return _richardson_reference(pilot, degree)


def _absolute_tolerance(
    ref: NDArray[np.float64], q0: NDArray[np.float64], tol: float, relative: bool
) -> tuple[float, float]:
    """The solution's scale (1 if it is zero) and the absolute tolerance ``tol`` means."""
    size = float(max(np.max(np.abs(ref)), np.max(np.abs(q0))))
    scale = size if size > 0 else 1.0
    atol = tol * size if relative else tol
    if atol <= 0:
        raise ValueError("relative=True needs a solution that is not identically zero")
    return scale, atol


def _dropped(method: Galerkin | Composition, status: str) -> Candidate:
    """The row of a candidate without usable pilots, dropped for ``status``."""
    return Candidate(
        method=method,
        label=_label(method),
        order=method.order,
        pilot_steps=(),
        pilot_errors=(),
        measured_order=math.nan,
        h=math.nan,
        n_steps=0,
        predicted_error=math.nan,
        time_per_step=math.nan,
        predicted_cost=math.inf,
        status=status,
    )


def _predicted(
    method: Galerkin | Composition,
    points: list[tuple[int, float]],
    span: float,
    t_final: float,
    target: float,
) -> Candidate:
    """The row of a candidate with its step size predicted from the pilot ``points``."""
    h, n_steps, predicted, slope = _predict(points, method.order, span, t_final, target)
    return Candidate(
        method=method,
        label=_label(method),
        order=method.order,
        pilot_steps=tuple(n for n, _ in points),
        pilot_errors=tuple(e for _, e in points),
        measured_order=slope,
        h=h,
        n_steps=n_steps,
        predicted_error=predicted,
        time_per_step=math.nan,
        predicted_cost=math.inf,
    )


def _candidate_rows(
    pilot: _Pilot,
    methods: Sequence[Galerkin | Composition],
    ref: NDArray[np.float64],
    reference_error: float,
    scale: float,
    target: float,
    t_final: float,
    max_pilot_steps: int,
) -> list[Candidate]:
    """Pilot runs and prediction of every method, in order; not yet timed."""
    # the whole-span target scaled down by the linear error growth of the model
    pilot_target = target * pilot.span / t_final
    rows: list[Candidate] = []
    for method in methods:
        points, status = _probe(
            pilot, method, ref, reference_error, scale, pilot_target, max_pilot_steps
        )
        if status != "ok":
            rows.append(_dropped(method, status))
        else:
            rows.append(_predicted(method, points, pilot.span, t_final, target))
    return rows


def _cheapest(rows: Sequence[Candidate]) -> Candidate:
    """The usable candidate of least predicted cost; ``RuntimeError`` if there is none."""
    usable = [c for c in rows if c.ok]
    if not usable:
        raise RuntimeError(
            "no candidate method gave usable pilot runs:\n"
            + "\n".join(f"  {c.label}: {c.status}" for c in rows)
        )
    return min(usable, key=lambda c: c.predicted_cost)


def _warn_near_roundoff(best: Candidate, target: float, scale: float) -> None:
    """Warn if ``target`` is below the round-off estimate of the ``best`` run."""
    roundoff = best.n_steps * _EPS * scale  # one rounding per step, accumulated
    if target < roundoff:
        warnings.warn(
            f"the aimed-at error {target:.2e} (tol / safety) is near the float64 round-off "
            f"floor of a {best.n_steps}-step run (about {roundoff:.1e}): the tolerance may "
            "not be reachable",
            RuntimeWarning,
            stacklevel=3,  # the caller of choose_method, not choose_method
        )


def choose_method(
    system: LagrangianSystem,
    q0: ArrayLike,
    v0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    *,
    t_final: float,
    tol: float,
    params: Mapping | None = None,
    degrees: Sequence[int] = (1, 2, 3, 4, 6),
    families: Sequence[str] = ("gauss", "lobatto"),
    methods: Sequence[Galerkin | Composition] | None = None,
    compositions: Sequence[int] = (4, 6, 8, 10),
    relative: bool = False,
    safety: float = 4.0,
    pilot_span: float | None = None,
    reference: Callable[[NDArray[np.float64]], ArrayLike] | None = None,
    max_pilot_steps: int = 20_000,
    timing_steps: int = 2000,
    repeats: int = 5,
    t0: float = 0.0,
    backend: str = "auto",
) -> MethodChoice:
    r"""Choose the method and step size that reach ``tol`` over ``t_final`` at the least cost.

    See the module docstring (:mod:`galerkin_vi.tools.choice`) for the error and
    cost model, and its limits.

    Parameters
    ----------
    system : LagrangianSystem
    q0 : array_like, shape (n,)
    v0, p0 : array_like, shape (n,)
        Exactly one: initial velocities or momenta.
    t_final : float
        Length of the time span (> 0), starting at ``t0``.
    tol : float
        Tolerance on the final position error :math:`\|q_N - q(t_0 + T)\|_\infty`
        (> 0): absolute, or relative to :math:`\max_k\|q(t_k)\|_\infty` over the
        pilot span when ``relative=True``.
    params : mapping, optional
        Parameter values (symbols or names) overriding the system's defaults.
    degrees : sequence of int
        Candidate degrees :math:`s`, each with every family in ``families``.
    families : sequence of {"gauss", "lobatto"}
        ``"gauss"``: ``gauss_legendre(s)``; ``"lobatto"``: ``gauss_lobatto(s + 1)``;
        both of order :math:`2s`.
    methods : sequence of Galerkin or Composition, optional
        Explicit candidates instead of ``degrees`` × ``families`` (and ``compositions``).
    compositions : sequence of int
        Orders of :class:`~galerkin_vi.Composition` (explicit splittings and
        compositions of Störmer–Verlet, default schemes, or the order's composition
        of Störmer–Verlet where a splitting is refused) that join the candidates when the system
        allows them (separable :math:`L`, constant mass, no constraints, contacts or
        velocity-dependent forces) and the backend is numba; ``()`` for none.
    relative : bool
        Whether ``tol`` is relative to the size of the solution.
    safety : float
        Aim at ``tol / safety`` (>= 1).
    pilot_span : float, optional
        Span of the pilot runs, default ``t_final / 10`` (at most ``t_final``).
        Make it cover at least one period of the motion.
    reference : callable, optional
        ``t -> q(t)``, the exact solution, called with an array of times
        (returning shape (m, n)) or, failing that, one time at a time. By
        default a Richardson-extrapolated high-order run is the reference.
    max_pilot_steps : int
        Largest step count of a pilot run.
    timing_steps : int
        Steps of the timing runs (fewer when the predicted run is shorter).
    repeats : int
        Timing rounds (the minimum is kept).
    t0 : float
    backend : {"auto", "numba", "numpy"}

    Returns
    -------
    MethodChoice
        ``print(choice)`` shows the choice and the table of all candidates.

    Raises
    ------
    ValueError, TypeError
        For bad input.
    RuntimeError
        If no candidate gave a usable pilot (all diverged or failed to converge).

    Warns
    -----
    RuntimeWarning
        If the aimed-at error is near the float64 round-off floor of the run.

    Examples
    --------
    >>> import numpy as np, galerkin_vi as gvi
    >>> from galerkin_vi import problems
    >>> kepler = problems.kepler(0.5)
    >>> choice = gvi.choose_method(kepler.system, kepler.q0, kepler.v0,
    ...                            t_final=20 * np.pi, tol=1e-8, degrees=(1, 2, 4),
    ...                            reference=kepler.reference)  # doctest: +SKIP
    >>> print(choice)  # doctest: +SKIP
    """
    start = time.perf_counter()
    t_final, tol, safety, span, q0, t0 = _check_arguments(
        system,
        q0,
        v0,
        p0,
        t_final=t_final,
        tol=tol,
        safety=safety,
        pilot_span=pilot_span,
        reference=reference,
        max_pilot_steps=max_pilot_steps,
        timing_steps=timing_steps,
        repeats=repeats,
        t0=t0,
    )
    allowed = composition_obstacle(system) is None and resolve_backend(backend) == "numba"
    candidates = _candidate_methods(degrees, families, methods, compositions if allowed else ())
    if methods is None:  # each order's default, or its Stormer-Verlet composition if refused
        candidates = [
            composition_for(system, m.order) if isinstance(m, Composition) else m
            for m in candidates
        ]

    pilot = _Pilot(system, q0, v0, p0, t0, params, span, backend)
    ref, reference_error = _reference_samples(pilot, reference, candidates)
    scale, atol = _absolute_tolerance(ref, q0, tol, relative)
    target = atol / safety

    rows = _candidate_rows(
        pilot, candidates, ref, reference_error, scale, target, t_final, int(max_pilot_steps)
    )
    rows = _timed(pilot, rows, int(timing_steps), int(repeats))
    best = _cheapest(rows)
    _warn_near_roundoff(best, target, scale)
    return MethodChoice(
        method=best.method,
        h=best.h,
        n_steps=best.n_steps,
        predicted_error=best.predicted_error,
        predicted_cost=best.predicted_cost,
        candidates=tuple(rows),
        tol=tol,
        atol=atol,
        t_final=t_final,
        pilot_span=span,
        safety=safety,
        reference_error=reference_error,
        elapsed=time.perf_counter() - start,
    )
