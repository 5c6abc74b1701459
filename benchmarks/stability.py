r"""Large steps and high degrees: linear stability limits, stage conditioning, accuracy.

Not a test (``tests/test_stability.py`` asserts on the same functions): writes
``stability.json``, ``stability.md`` and PNG plots for the stability part of
the robustness issue.

Run::

    python benchmarks/stability.py --output stability-out           # full: about 70 s
    python benchmarks/stability.py --quick --output stability-out   # quick: 10-20 s

(once the two systems are compiled: about 25 s more on a cold cache).

Theory: the one-step map on the harmonic oscillator
===================================================

For :math:`L = \tfrac12 v^2 - \tfrac12\omega^2 q^2` and a Galerkin method with
control nodes :math:`d_\nu`, quadrature :math:`(c_i, b_i)` and tables
:math:`\Phi_{i\nu} = \ell_\nu(c_i)`, :math:`D_{i\nu} = \ell'_\nu(c_i)`, the
discrete Lagrangian of one step is the quadratic form

.. math::

    L_d(q^0, \dots, q^s) = \frac1{2h}\, \mathbf q^T A(y)\, \mathbf q, \qquad
    A(y) = \sum_{i=1}^r b_i \big(D_{i\cdot} D_{i\cdot}^T - y\, \Phi_{i\cdot}\Phi_{i\cdot}^T\big),
    \qquad y = x^2,\ x = h\omega,

with :math:`A` of size :math:`(s+1)\times(s+1)`. With the scaled momentum
:math:`\pi = hp`, the stage equations of the position–momentum map
(:math:`\pi_k + (A\mathbf q)_0 = 0`, :math:`(A\mathbf q)_\nu = 0` for
:math:`0 < \nu < s`, :math:`\pi_{k+1} = (A\mathbf q)_s`) are linear: with
:math:`K = A_{0:s,\,1:s+1}` (the stage Jacobian up to the factor :math:`1/h`)
and :math:`X = (q^1, \dots, q^s)`,

.. math::

    K X = -(A_{0:s,\,0}\, q_k + \pi_k e_0), \qquad
    q_{k+1} = X_s, \qquad \pi_{k+1} = A_{s0}\, q_k + A_{s,\,1:s+1} X .

So :math:`(q_{k+1}, \pi_{k+1}) = M(x)\,(q_k, \pi_k)` with a :math:`2\times2`
matrix that depends on :math:`x = h\omega` only, :math:`\det M = 1`
(symplectic), and by Cramer's rule

.. math::

    \operatorname{tr} M(x) = \frac{N(y)}{\Delta(y)}, \qquad \Delta(y) = \det K(y),

with :math:`N` and :math:`\Delta` polynomials of degree at most :math:`s` in
:math:`y = x^2`. The eigenvalues solve :math:`\lambda^2 - t\lambda + 1 = 0`,
:math:`t = \operatorname{tr} M`: for :math:`|t| < 2` they are :math:`e^{\pm i\theta}`
(bounded solutions), for :math:`|t| > 2` the spectral radius is
:math:`\rho = (|t| + \sqrt{t^2 - 4})/2 > 1` (exponential growth), and
:math:`|t| = 2` at an isolated point is bounded when :math:`M = \pm I` and
grows linearly otherwise (a Jordan block).

:func:`trace_polynomials` evaluates :math:`M(x)` from the method's tables
computed by the library at 60 digits (:meth:`Galerkin.exact_tables`), at
:math:`y = 0, 1, \dots, s`, interpolates :math:`N` and :math:`\Delta` exactly
and checks them at further points. :func:`analyse` finds every boundary as a
positive root of :math:`N(y) \mp 2\Delta(y)` (and of :math:`\Delta`: none
exists for these methods, the stage equations are solvable at every
:math:`x`), classifies the intervals between them and, inside each unstable
interval, the largest spectral radius and the number of steps it needs to
grow by :math:`10^6` (the library's :data:`~galerkin_vi.run.trust.INSTABILITY_GROWTH`).
Checks: Störmer–Verlet (degree 1, Lobatto 2) has :math:`t = 2 - x^2`, limit
:math:`x = 2`; degree :math:`s` with Gauss :math:`s` points is :math:`s`-stage
Gauss collocation, :math:`t = 2\operatorname{Re} R_{ss}(ix)` with the diagonal
Padé approximant of :math:`e^z`, so :math:`|t| \le 2` for every :math:`x`
(A-stable), touching 2 only where :math:`M = \pm I`.

Measurements
============

1. Oscillator runs (compiled backend: the linear kernel, or explicit
   Störmer–Verlet for degree 1), q0 = 1, v0 = 0: each edge of every instability
   interval with :math:`x \le x_{\max}` is located by bisection on runs of
   :math:`N = \max(20000, 4 N_{10^6})` steps (:math:`N_{10^6}` the steps the peak
   needs to grow :math:`10^6`-fold; intervals needing more than ``max_steps`` are
   only run at their peak), "unstable" meaning that the run raised
   :class:`~galerkin_vi.ConvergenceError` or warned :class:`~galerkin_vi.InstabilityWarning`
   (momenta grown :math:`10^6`-fold). The bisection lags behind the edge on its
   unstable side by about :math:`(\ln 10^6 / N)^2 / |t'(x)|`, reported beside
   each edge. Runs at the middle of every stable interval and the peak of every
   unstable one; growth-rate sweeps around one interval per method (plot).
2. Fermi–Pasta–Ulam (:math:`\omega = 50`): a sweep of :math:`h\omega` for degree 1
   (explicit Verlet), degree 2 Lobatto 3 and Gauss 2 (Newton): per :math:`h`,
   bounded or not, :class:`ConvergenceError` (Newton, non-finite) or warning,
   and that every returned trajectory is finite. The largest linearised
   frequency along a stable run, :math:`\omega_{\max} = \max_t \lambda_{\max}(\nabla^2V)^{1/2}`,
   predicts the limits :math:`x^*\omega/\omega_{\max}` of the stiff springs.
3. High degree (Lobatto :math:`s+1` quadrature, :math:`s = 1..16`): the 2-norm
   condition number of the stage Jacobian (``discrete_hessian``) at
   :math:`h\omega = 0.5` and 1 for Lobatto and equidistant control nodes, and
   the error at :math:`T = 10` with the linear kernel (default) and the Newton
   kernel (``specialize=False``), and the cost per step.

Findings (development machine): the measured edges agree with the theory to
within their expected lag (relative differences 1e-10 to 1.3e-5). Lobatto
:math:`s+1` is unstable on intervals near :math:`x \approx k\pi` that shrink
fast with :math:`s` (the first is 2e-3 wide at s = 4, 1e-6 at s = 6), each
bounded one ending exactly where :math:`s`-point Gauss has :math:`M = \pm I`,
and for all large :math:`x`. Gauss stays bounded up to :math:`x = 1000`. No
run returns a non-finite state.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import time
import warnings
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import mpmath
import numpy as np
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.reference.numpy import discrete_hessian
from galerkin_vi.run.trust import INSTABILITY_GROWTH

DPS = 60  # digits of the exact trace computation
FAMILIES = ("lobatto", "gauss")
# a root of N -+ 2 Delta is real when its imaginary part is below this (double roots
# split into pairs about 10^(-DPS/2) apart)
_REAL_TOL = mpmath.mpf(10) ** (-DPS // 3)
_FAILURE_KINDS = {
    gvi.RunStatus.NO_CONVERGENCE: "newton",
    gvi.RunStatus.NON_FINITE: "non-finite",
    gvi.RunStatus.SINGULAR_JACOBIAN: "singular",
    gvi.RunStatus.UNSTABLE: "unstable",
}


def method_for(family: str, degree: int, nodes: str = "lobatto") -> gvi.Galerkin:
    """Degree ``s`` with Lobatto ``s + 1`` (``"lobatto"``) or Gauss ``s`` points (``"gauss"``)."""
    if family == "lobatto":
        quadrature = gvi.gauss_lobatto(degree + 1)
    elif family == "gauss":
        quadrature = gvi.gauss_legendre(degree)
    else:
        raise ValueError(f"family must be one of {FAMILIES}, got {family!r}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.ConditioningWarning)
        return gvi.Galerkin(degree, quadrature, nodes=nodes)


def label(family: str, degree: int) -> str:
    """``"s=2 Lobatto 3"`` or ``"s=2 Gauss 2"``."""
    points = degree + 1 if family == "lobatto" else degree
    return f"s={degree} {'Lobatto' if family == 'lobatto' else 'Gauss'} {points}"


# ----------------------------------------------------------------------------- theory
def _stage_form(tables: gvi.method.galerkin.ExactTables, y: mpmath.mpf) -> mpmath.matrix:
    """:math:`A(y) = \\sum_i b_i (D_i D_i^T - y \\Phi_i \\Phi_i^T)`, shape (s + 1, s + 1)."""
    s1, r = len(tables.d), len(tables.b)
    A = mpmath.matrix(s1, s1)
    for v in range(s1):
        for u in range(v, s1):
            A[v, u] = A[u, v] = mpmath.fsum(
                tables.b[i]
                * (tables.D[i][v] * tables.D[i][u] - y * tables.Phi[i][v] * tables.Phi[i][u])
                for i in range(r)
            )
    return A


def step_matrix(
    method: gvi.Galerkin, x: float | mpmath.mpf, tables=None
) -> tuple[mpmath.matrix, mpmath.mpf]:
    """One-step map :math:`M(x)` on :math:`(q, hp)` and :math:`\\det K`, at ``DPS`` digits."""
    with mpmath.workdps(DPS):
        tables = method.exact_tables(DPS) if tables is None else tables
        x = mpmath.mpf(x)
        A = _stage_form(tables, x * x)
        s = len(tables.d) - 1
        K = A[0:s, 1 : s + 1]
        M = mpmath.matrix(2, 2)
        for col, (q, pi) in enumerate(((1, 0), (0, 1))):
            rhs = mpmath.matrix([-(A[v, 0] * q + (pi if v == 0 else 0)) for v in range(s)])
            X = mpmath.lu_solve(K, rhs)
            M[0, col] = X[s - 1]
            M[1, col] = A[s, 0] * q + mpmath.fsum(A[s, u + 1] * X[u] for u in range(s))
        return M, mpmath.det(K)


@dataclass(frozen=True)
class TracePolynomials:
    r""":math:`\operatorname{tr} M = N(y)/\Delta(y)`; coefficients by increasing power of y."""

    numerator: tuple
    denominator: tuple

    def trace(self, x: float | mpmath.mpf) -> mpmath.mpf:
        """:math:`\\operatorname{tr} M(x)` at ``DPS`` digits."""
        with mpmath.workdps(DPS):
            y = mpmath.mpf(x) ** 2
            return mpmath.polyval(self.numerator[::-1], y) / mpmath.polyval(
                self.denominator[::-1], y
            )

    def slope(self, x: float | mpmath.mpf) -> float:
        """:math:`d\\operatorname{tr} M/dx = 2x\\,(N'\\Delta - N\\Delta')/\\Delta^2` at ``x``."""
        with mpmath.workdps(DPS):
            x = mpmath.mpf(x)
            n, dn = mpmath.polyval(self.numerator[::-1], x * x, derivative=True)
            d, dd = mpmath.polyval(self.denominator[::-1], x * x, derivative=True)
            return float(2 * x * (dn * d - n * dd) / (d * d))


def trace_polynomials(method: gvi.Galerkin) -> TracePolynomials:
    """Interpolate :math:`N` and :math:`\\Delta` at :math:`y = 0..s`; check at other points."""
    s = method.degree
    with mpmath.workdps(DPS):
        tables = method.exact_tables(DPS)
        ys = [mpmath.mpf(k) for k in range(s + 1)]
        num, den = [], []
        for y in ys:
            M, det_k = step_matrix(method, mpmath.sqrt(y), tables)
            num.append((M[0, 0] + M[1, 1]) * det_k)
            den.append(det_k)
        V = mpmath.matrix([[y**j for j in range(s + 1)] for y in ys])
        polys = TracePolynomials(
            tuple(mpmath.lu_solve(V, mpmath.matrix(num))),
            tuple(mpmath.lu_solve(V, mpmath.matrix(den))),
        )
        for x in (mpmath.mpf("0.7"), mpmath.mpf("3.3"), mpmath.mpf(s + 11)):
            M, _ = step_matrix(method, x, tables)
            exact = M[0, 0] + M[1, 1]
            if abs(polys.trace(x) - exact) > mpmath.mpf(10) ** (-DPS // 2) * (1 + abs(exact)):
                raise ArithmeticError(f"{method!r}: tr M is not N/Delta of degree {s}")
        return polys


def spectral_radius(t: float | mpmath.mpf) -> float:
    """Largest :math:`|\\lambda|` of a :math:`2\\times2` matrix with determinant 1 and trace t."""
    t = abs(mpmath.mpf(t))
    return float((t + mpmath.sqrt(t * t - 4)) / 2) if t > 2 else 1.0


def _positive_roots(coefficients: Sequence) -> list[mpmath.mpf]:
    """Distinct positive real roots in x of a polynomial in :math:`y = x^2`."""
    c = list(coefficients)
    biggest = max(abs(a) for a in c)
    while len(c) > 1 and abs(c[-1]) <= mpmath.mpf(10) ** (-DPS + 10) * biggest:
        c.pop()
    if len(c) < 2:
        return []
    roots = mpmath.polyroots(c[::-1], maxsteps=500, extraprec=4 * DPS)
    xs: list[mpmath.mpf] = []
    for r in roots:
        r = mpmath.mpc(r)
        if abs(r.imag) <= _REAL_TOL * (1 + abs(r)) and r.real > _REAL_TOL:
            x = mpmath.sqrt(r.real)
            if not any(abs(x - other) <= _REAL_TOL * x for other in xs):
                xs.append(x)
    return sorted(xs)


@dataclass(frozen=True)
class Interval:
    """An interval of :math:`x = h\\omega` where :math:`|\\operatorname{tr} M| > 2`."""

    lo: float
    hi: float | None  # None: unstable for all larger x
    sign: int  # +1: tr M > 2 (eigenvalues > 0), -1: tr M < -2
    x_peak: float  # where the spectral radius peaks (for an unbounded interval: 1.1 lo)
    rho_peak: float
    steps_to_warning: float  # ln(1e6) / ln(rho_peak)


@dataclass(frozen=True)
class Stability:
    """Linear stability of one method on the harmonic oscillator."""

    family: str
    degree: int
    label: str
    limit: float | None  # first x with |tr M| > 2 (None: never)
    unstable: tuple[Interval, ...]
    touches: tuple[float, ...]  # isolated x > 0 with |tr M| = 2
    touch_residuals: tuple[float, ...]  # max |M - (tr M / 2) I| there: 0 when M = +-I
    singular: tuple[float, ...]  # x > 0 with det K = 0
    trace_at_infinity: str  # the limit of tr M as x -> infinity


def _peak(polys: TracePolynomials, lo: mpmath.mpf, hi: mpmath.mpf) -> mpmath.mpf:
    """Maximiser of :math:`|\\operatorname{tr} M|` on [lo, hi]: grid, then golden section."""
    with mpmath.workdps(DPS):
        grid = [lo + (hi - lo) * k / 64 for k in range(1, 64)]
        best = max(range(len(grid)), key=lambda k: abs(polys.trace(grid[k])))
        a = grid[best - 1] if best > 0 else lo
        b = grid[best + 1] if best + 1 < len(grid) else hi
        golden = (mpmath.sqrt(5) - 1) / 2
        for _ in range(80):
            c, d = b - golden * (b - a), a + golden * (b - a)
            if abs(polys.trace(c)) > abs(polys.trace(d)):
                b = d
            else:
                a = c
        return (a + b) / 2


def _interval(polys: TracePolynomials, lo: mpmath.mpf, hi: mpmath.mpf | None) -> Interval:
    with mpmath.workdps(DPS):
        x_peak = _peak(polys, lo, hi) if hi is not None else lo * mpmath.mpf("1.1")
        t = polys.trace(x_peak)
        rho = spectral_radius(t)
        # ln rho from the trace keeps its digits when rho - 1 is below float resolution
        log_rho = float(mpmath.acosh(abs(t) / 2))
        return Interval(
            lo=float(lo),
            hi=None if hi is None else float(hi),
            sign=1 if t > 0 else -1,
            x_peak=float(x_peak),
            rho_peak=rho,
            steps_to_warning=math.log(INSTABILITY_GROWTH) / log_rho if log_rho > 0 else math.inf,
        )


def analyse(family: str, degree: int) -> Stability:
    """Stability intervals of degree ``degree`` in ``family`` from the exact trace of M."""
    method = method_for(family, degree)
    polys = trace_polynomials(method)
    with mpmath.workdps(DPS):
        N, D = polys.numerator, polys.denominator
        boundaries = sorted(
            set(_positive_roots([a - 2 * b for a, b in zip(N, D, strict=True)]))
            | set(_positive_roots([a + 2 * b for a, b in zip(N, D, strict=True)]))
        )
        singular = _positive_roots(D)
        edges = sorted(boundaries + singular)
        # one sample per open interval between consecutive edges (the last one unbounded)
        cuts = [mpmath.mpf(0), *edges]
        samples = [(a + b) / 2 for a, b in zip(cuts[:-1], cuts[1:], strict=True)]
        samples.append(2 * cuts[-1] + 1)
        unstable_flags = [abs(polys.trace(x)) > 2 for x in samples]
        intervals, touches, residuals = [], [], []
        for k, edge in enumerate(edges):
            left, right = unstable_flags[k], unstable_flags[k + 1]
            if not left and not right and edge not in singular:
                touches.append(float(edge))
                M, _ = step_matrix(method, edge)
                half = (M[0, 0] + M[1, 1]) / 2
                residuals.append(float(mpmath.mnorm(M - half * mpmath.eye(2), mpmath.inf)))
        k = 0
        while k < len(samples):
            if unstable_flags[k]:
                j = k
                while j + 1 < len(samples) and unstable_flags[j + 1]:
                    j += 1
                hi = edges[j] if j < len(edges) else None
                intervals.append(_interval(polys, cuts[k], hi))
                k = j + 1
            else:
                k += 1
        degree_n = max(j for j, a in enumerate(N) if abs(a) > _REAL_TOL)
        degree_d = max(j for j, a in enumerate(D) if abs(a) > _REAL_TOL)
        ratio = N[degree_n] / D[degree_d]
        if degree_n > degree_d:
            at_infinity = "+inf" if ratio > 0 else "-inf"
        else:
            at_infinity = mpmath.nstr(ratio if degree_n == degree_d else 0, 12)
    return Stability(
        family=family,
        degree=degree,
        label=label(family, degree),
        limit=intervals[0].lo if intervals else None,
        unstable=tuple(intervals),
        touches=tuple(touches),
        touch_residuals=tuple(residuals),
        singular=tuple(float(x) for x in singular),
        trace_at_infinity=at_infinity,
    )


def pade_trace(degree: int, x: float) -> float:
    """:math:`2\\operatorname{Re} R_{ss}(ix)`, the trace of ``degree``-stage Gauss collocation."""
    s = degree
    with mpmath.workdps(DPS):
        coefficients = [
            mpmath.factorial(2 * s - j)
            * mpmath.factorial(s)
            / (mpmath.factorial(2 * s) * mpmath.factorial(j) * mpmath.factorial(s - j))
            for j in range(s + 1)
        ]
        z = mpmath.mpc(0, x)
        r = mpmath.polyval(coefficients[::-1], z) / mpmath.polyval(coefficients[::-1], -z)
        return float(2 * r.real)


# ------------------------------------------------------------------- oscillator runs
@dataclass(frozen=True)
class Run:
    """Outcome of one run at :math:`x = h\\omega`."""

    x: float
    outcome: str  # "bounded", "warning" (InstabilityWarning), "error" (ConvergenceError)
    failure: str | None  # for errors: "newton", "non-finite", "singular" or "unstable"
    growth: float  # log10 of max |q| over the run (or its partial trajectory) / max |q0|
    steps: int  # steps completed (for errors: the index of the failing step)
    finite: bool  # every returned (or partial) state is finite
    mean_iterations: float | None = None

    @property
    def bounded(self) -> bool:
        return self.outcome == "bounded"


def classify(
    integrator: gvi.Integrator,
    q0: np.ndarray,
    v0: np.ndarray,
    x: float,
    omega: float,
    n_steps: int,
    params=None,
) -> Run:
    """Run ``n_steps`` steps of size ``h = x/omega`` and classify the outcome."""
    failure = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", gvi.InstabilityWarning)
        try:
            traj = integrator.integrate(
                q0, v0, h=x / omega, n_steps=n_steps, params=params, on_failure="raise"
            )
            warned = any(issubclass(w.category, gvi.InstabilityWarning) for w in caught)
            outcome = "warning" if warned else "bounded"
            steps = traj.n_steps
        except gvi.ConvergenceError as err:
            traj = err.partial
            outcome = "error"
            failure = _FAILURE_KINDS.get(traj.status, "other")
            steps = err.step
    finite = bool(np.all(np.isfinite(traj.q)) and np.all(np.isfinite(traj.p)))
    scale = float(np.max(np.abs(q0))) or 1.0
    growth = math.log10(max(float(np.max(np.abs(traj.q))), 1e-300) / scale)
    mean_it = traj.mean_newton_iterations if integrator.kernel_path == "newton" else None
    return Run(x, outcome, failure, growth, steps, finite, mean_it)


@dataclass(frozen=True)
class Edge:
    """An interval edge located by bisection on runs."""

    theory: float
    measured: float  # middle of the final bracket
    bracket: tuple[float, float]  # the final bracket, in increasing order
    n_steps: int  # steps per run
    expected_lag: float  # (ln 1e6 / N)^2 / |t'|, on the unstable side
    runs: int

    @property
    def relative_error(self) -> float:
        return abs(self.measured - self.theory) / self.theory


def bisect_edge(
    run_at, x_stable: float, x_unstable: float, xtol: float
) -> tuple[float, float, int]:
    """Bisect between a bounded and an unstable run; return both ends and the run count."""
    count = 0
    while abs(x_unstable - x_stable) > xtol * abs(x_stable):
        mid = (x_stable + x_unstable) / 2
        count += 1
        if run_at(mid).bounded:
            x_stable = mid
        else:
            x_unstable = mid
    return x_stable, x_unstable, count


@dataclass
class OscillatorCheck:
    """Theory against runs for one method."""

    label: str
    kernel_path: str
    n_steps: int
    edges: list[Edge] = field(default_factory=list)
    stable_runs: list[Run] = field(default_factory=list)  # middles of stable intervals
    unstable_runs: list[dict] = field(default_factory=list)  # peaks: run and prediction
    seconds: float = 0.0


OSCILLATOR_OMEGA = 1.0  # the map depends on h*omega only


def oscillator_runner(method: gvi.Galerkin):
    """``(x, n_steps) -> Run`` on the oscillator (q0 = 1, v0 = 0), compiled backend."""
    problem = problems.harmonic_oscillator(OSCILLATOR_OMEGA, 1.0, 0.0)
    integrator = gvi.Integrator(problem.system, method)

    def run_at(x: float, n_steps: int) -> Run:
        return classify(
            integrator, problem.q0, problem.v0, x, OSCILLATOR_OMEGA, n_steps, problem.params
        )

    return run_at, integrator


def check_against_runs(
    stability: Stability,
    n_steps: int,
    x_max: float,
    max_steps: int | None = None,
    xtol: float = 1e-8,
) -> OscillatorCheck:
    """Theory against runs: edges below ``x_max`` by bisection, runs inside every interval.

    An interval is observed with ``N = max(n_steps, 4 * steps_to_warning)`` steps per
    run when that is at most ``max_steps`` (default ``n_steps``); weaker ones are only
    run at their peak with ``n_steps`` steps, to compare the growth with the theory.
    Bisection starts at most one interval width from the edge, inside the stable
    interval next to it, and stops at a relative bracket width ``xtol``.
    """
    start = time.perf_counter()
    max_steps = n_steps if max_steps is None else max_steps
    method = method_for(stability.family, stability.degree)
    polys = trace_polynomials(method)
    run_at, integrator = oscillator_runner(method)
    check = OscillatorCheck(stability.label, integrator.kernel_path, n_steps)
    # stable intervals: (0, lo_1), (hi_1, lo_2), ...; their middles are bounded
    ends = [0.0]
    for interval in stability.unstable:
        ends += [interval.lo, interval.hi if interval.hi is not None else math.inf]
    ends.append(math.inf)
    stable = list(zip(ends[0::2], ends[1::2], strict=True))
    for lo, hi in stable:
        if lo < x_max and math.isfinite(hi):
            check.stable_runs.append(run_at((lo + hi) / 2, n_steps))
    if not stability.unstable:
        for x in (0.5, 1.0, 2.0, 5.0, 10.0, 100.0, 1000.0):
            check.stable_runs.append(run_at(x, n_steps))
    for k, interval in enumerate(stability.unstable):
        if interval.lo > x_max:
            break
        steps = max(n_steps, math.ceil(4 * interval.steps_to_warning))
        observable = steps <= max_steps
        steps = steps if observable else n_steps
        peak = run_at(interval.x_peak, steps)
        check.unstable_runs.append(
            {
                "interval": [interval.lo, interval.hi],
                "x_peak": interval.x_peak,
                "rho_peak": interval.rho_peak,
                "steps_to_warning": interval.steps_to_warning,
                "observable": observable,
                "n_steps": steps,
                "predicted_growth": steps * math.log10(interval.rho_peak),
                "run": asdict(peak),
            }
        )
        if not observable:
            continue

        def run_n(x: float, steps: int = steps) -> Run:
            return run_at(x, steps)

        lag = (math.log(INSTABILITY_GROWTH) / steps) ** 2
        width = (interval.hi if interval.hi is not None else 1.1 * interval.lo) - interval.lo
        before, after = stable[k][0], stable[k + 1][1]
        x_left = interval.lo - min(width, (interval.lo - before) / 2)
        a, b, count = bisect_edge(run_n, x_left, interval.x_peak, xtol)
        lag_x = lag / abs(polys.slope(interval.lo))
        check.edges.append(Edge(interval.lo, (a + b) / 2, (a, b), steps, lag_x, count))
        if interval.hi is not None:
            x_right = interval.hi + min(width, (after - interval.hi) / 2)
            a, b, count = bisect_edge(run_n, x_right, interval.x_peak, xtol)
            lag_x = lag / abs(polys.slope(interval.hi))
            check.edges.append(Edge(interval.hi, (a + b) / 2, (b, a), steps, lag_x, count))
    check.seconds = time.perf_counter() - start
    return check


def sweep_window(stability: Stability, n_steps: int) -> tuple[float, float, Interval]:
    """The window around the first unstable interval that grows visibly in ``n_steps`` steps.

    For an interval (lo, hi): (lo - w, hi + w) with w = hi - lo; for (lo, inf):
    (0.95 lo, 1.05 lo).
    """
    for interval in stability.unstable:
        if interval.steps_to_warning <= n_steps / 4:
            if interval.hi is None:
                return 0.95 * interval.lo, 1.05 * interval.lo, interval
            width = interval.hi - interval.lo
            return interval.lo - width, interval.hi + width, interval
    raise ValueError(f"{stability.label}: no instability observable in {n_steps} steps")


def growth_sweep(family: str, degree: int, xs: Sequence[float], n_steps: int) -> dict:
    r"""Runs over ``xs``: measured growth rate per step against :math:`\log_{10}\rho(x)`.

    The measured rate is :math:`\log_{10}(\max_k |q_k| / |q_0|) / k_{\rm done}` over the
    returned (or, after an overflow, the partial) trajectory.
    """
    method = method_for(family, degree)
    polys = trace_polynomials(method)
    run_at, _ = oscillator_runner(method)
    runs = [run_at(float(x), n_steps) for x in xs]
    return {
        "label": label(family, degree),
        "family": family,
        "n_steps": n_steps,
        "x": [float(x) for x in xs],
        "rate": [r.growth / max(r.steps, 1) for r in runs],
        "outcome": [r.outcome for r in runs],
        "finite": all(r.finite for r in runs),
        "theory_rate": [math.log10(spectral_radius(polys.trace(x))) for x in xs],
    }


# ------------------------------------------------------------------------------- FPU
FPU_OMEGA = 50.0
FPU_METHODS = (("lobatto", 1), ("lobatto", 2), ("gauss", 2))


def fpu_max_frequency(problem: problems.Problem, traj: gvi.Trajectory) -> float:
    r""":math:`\max_t \sqrt{\lambda_{\max}(\nabla^2 V(q(t)))}` over the saved states."""
    system = problem.system
    hessian = sp.hessian(-system.L.subs(dict.fromkeys(system.v, 0)), system.q)
    values = system.parameter_vector(problem.params)
    evaluate = sp.lambdify([system.q, system.params], hessian, "numpy")
    return max(
        math.sqrt(float(np.max(np.linalg.eigvalsh(np.array(evaluate(q, values), dtype=float)))))
        for q in traj.q
    )


def fpu_sweep(xs: Sequence[float], n_steps: int, xtol: float = 1e-4) -> dict:
    """Sweep :math:`h\\omega` on FPU (m = 3, omega = 50) for the methods of ``FPU_METHODS``."""
    problem = problems.fermi_pasta_ulam(3, FPU_OMEGA)
    results = {"omega": FPU_OMEGA, "n_steps": n_steps, "methods": []}
    reference_traj = None
    for family, degree in FPU_METHODS:
        start = time.perf_counter()
        method = method_for(family, degree)
        integrator = gvi.Integrator(problem.system, method)

        def run_at(x: float, integrator=integrator) -> Run:
            return classify(
                integrator, problem.q0, problem.v0, x, FPU_OMEGA, n_steps, problem.params
            )

        runs = [run_at(float(x)) for x in xs]
        first_bad = next((k for k, r in enumerate(runs) if not r.bounded), None)
        limit = None
        if first_bad is not None and first_bad > 0:
            a, b, _ = bisect_edge(run_at, runs[first_bad - 1].x, runs[first_bad].x, xtol)
            limit = {"bracket": [a, b], "stable": asdict(run_at(a)), "unstable": asdict(run_at(b))}
        newton_failures = [r.x for r in runs if r.failure == "newton"]
        if reference_traj is None:
            reference_traj = integrator.integrate(
                problem.q0,
                problem.v0,
                h=1.0 / FPU_OMEGA,
                n_steps=n_steps,
                params=problem.params,
                on_failure="raise",
            )
        theory = analyse(family, degree)
        results["methods"].append(
            {
                "label": label(family, degree),
                "kernel_path": integrator.kernel_path,
                "oscillator_limit": theory.limit,
                "runs": [asdict(r) for r in runs],
                "measured_limit": limit,
                "first_newton_failure": newton_failures[0] if newton_failures else None,
                "newton_failures": newton_failures,
                "all_finite": all(r.finite for r in runs),
                "seconds": time.perf_counter() - start,
            }
        )
    omega_max = fpu_max_frequency(problem, reference_traj)
    results["omega_max"] = omega_max
    for entry in results["methods"]:
        x_lin = entry["oscillator_limit"]
        entry["predicted_limit"] = None if x_lin is None else x_lin * FPU_OMEGA / omega_max
    return results


# ----------------------------------------------------------------------- high degree
def stage_condition(method: gvi.Galerkin, x: float) -> float:
    """2-norm condition number of the oscillator's stage Jacobian at :math:`h\\omega = x`."""
    problem = problems.harmonic_oscillator(1.0)
    prm = problem.system.parameter_vector(problem.params)
    s = method.degree
    C = np.zeros((s + 1, 1))
    _, H = discrete_hessian(problem.system, method.tables, 0.0, x, problem.q0, C, prm)
    return float(np.linalg.cond(H[:s, :, 1:, :].reshape(s, s)))


def _cost(integrator: gvi.Integrator, problem: problems.Problem, n_steps: int) -> float:
    """Microseconds per step of ``n_steps`` steps at h = 0.5, best of three, one row saved."""
    best = math.inf
    for _ in range(3):
        start = time.perf_counter()
        integrator.integrate(
            problem.q0,
            problem.v0,
            h=0.5,
            n_steps=n_steps,
            params=problem.params,
            save_every=n_steps,
        )
        best = min(best, time.perf_counter() - start)
    return 1e6 * best / n_steps


def high_degree(
    degrees: Sequence[int],
    steps: Sequence[float],
    t_final: float = 10.0,
    cost_steps: int = 2000,
) -> dict:
    """Condition numbers, errors at ``t_final`` and cost per step, Lobatto and equidistant nodes."""
    problem = problems.harmonic_oscillator(1.0, 1.0, 0.5)
    exact = float(problem.exact(t_final)[0])
    rows = []
    for s in degrees:
        row: dict = {"degree": s}
        for nodes in ("lobatto", "equidistant"):
            method = method_for("lobatto", s, nodes=nodes)
            entry: dict = {
                "cond": {str(x): stage_condition(method, x) for x in (0.5, 1.0)},
                "extrapolation_norm": float(np.abs(method.tables.extrapolation).sum(1).max()),
            }
            for kernel, specialize in (("linear", True), ("newton", False)):
                integrator = gvi.Integrator(problem.system, method, specialize=specialize)
                errors, iterations = {}, {}
                for h in steps:
                    traj = integrator.integrate(
                        problem.q0,
                        problem.v0,
                        h=h,
                        n_steps=round(t_final / h),
                        params=problem.params,
                        on_failure="raise",
                    )
                    errors[str(h)] = abs(float(traj.q[-1, 0]) - exact)
                    iterations[str(h)] = traj.mean_newton_iterations
                entry[kernel] = {
                    "error": errors,
                    "mean_iterations": iterations,
                    "us_per_step": _cost(integrator, problem, cost_steps),
                }
            row[nodes] = entry
        rows.append(row)
    return {"t_final": t_final, "steps": list(steps), "rows": rows}


# -------------------------------------------------------------------------- driver
@dataclass(frozen=True)
class Config:
    degrees: tuple[int, ...]  # theory, both families
    run_degrees: tuple[int, ...]  # edges measured by runs
    n_steps: int  # oscillator runs (at least)
    max_steps: int  # weak instabilities are observed with up to this many steps
    x_max: float  # edges measured below this x
    sweep_points: int  # runs per growth sweep
    sweep_steps: int  # steps per sweep run
    sweep_degrees: tuple[int, ...]
    fpu_xs: tuple[float, ...]
    fpu_steps: int
    high_degrees: tuple[int, ...]
    high_steps: tuple[float, ...]


FULL = Config(
    degrees=(1, 2, 3, 4, 5, 6),
    run_degrees=(1, 2, 3, 4, 5, 6),
    n_steps=20_000,
    max_steps=2_500_000,
    x_max=16.0,
    sweep_points=120,
    sweep_steps=20_000,
    sweep_degrees=(1, 2, 3, 4, 5, 6),
    fpu_xs=(
        *(0.5, 1.0, 1.5, 1.8, 1.9, 1.95, 1.98, 1.99, 2.0, 2.01, 2.05, 2.2, 2.5),
        *(2.7, 2.8, 2.85, 2.9, 3.0, 3.2, 3.4, 3.47, 3.5, 3.6, 4.0, 4.5, 4.8, 4.9, 5.0),
        *(6.0, 8.0, 10.0, 12.0, 15.0, 17.5, 20.0, 25.0, 30.0, 40.0, 50.0, 75.0, 100.0),
    ),
    fpu_steps=2000,
    high_degrees=tuple(range(1, 17)),
    high_steps=(1.0, 0.5, 0.25),
)
QUICK = Config(
    degrees=(1, 2, 3, 4, 5, 6),
    run_degrees=(1, 2, 3),
    n_steps=20_000,
    max_steps=100_000,
    x_max=10.0,
    sweep_points=60,
    sweep_steps=20_000,
    sweep_degrees=(1, 2, 3),
    fpu_xs=(1.0, 1.9, 1.99, 2.01, 2.5, 2.8, 2.9, 3.5, 4.0, 5.0, 10.0, 20.0, 50.0, 100.0),
    fpu_steps=2000,
    high_degrees=(1, 2, 4, 6, 8, 10, 12, 14, 16),
    high_steps=(1.0, 0.5),
)


def run(config: Config, log=print) -> dict:
    """All measurements of ``config`` as a JSON-ready dict."""
    timings: dict[str, float] = {}
    start = time.perf_counter()
    theory = [analyse(f, s) for f in FAMILIES for s in config.degrees]
    timings["theory"] = time.perf_counter() - start
    log(f"theory: {timings['theory']:.1f} s")

    start = time.perf_counter()
    checks = []
    for st in theory:
        if st.degree in config.run_degrees:
            checks.append(check_against_runs(st, config.n_steps, config.x_max, config.max_steps))
            log(f"runs {st.label}: {checks[-1].seconds:.1f} s")
    timings["oscillator_runs"] = time.perf_counter() - start

    start = time.perf_counter()
    sweeps = []
    for st in theory:
        if st.family == "lobatto" and st.degree in config.sweep_degrees:
            lo, hi, interval = sweep_window(st, config.sweep_steps)
            sweep = growth_sweep(
                "lobatto", st.degree, np.linspace(lo, hi, config.sweep_points), config.sweep_steps
            )
            sweep["interval"] = [interval.lo, interval.hi]
            sweep["first_limit"] = st.limit
            sweep["first_steps_to_warning"] = st.unstable[0].steps_to_warning
            sweeps.append(sweep)
        elif st.family == "gauss" and st.degree in config.sweep_degrees:
            xs = np.geomspace(0.05, 1000.0, config.sweep_points)
            sweeps.append(growth_sweep("gauss", st.degree, xs, config.sweep_steps))
    timings["growth_sweep"] = time.perf_counter() - start
    log(f"growth sweep: {timings['growth_sweep']:.1f} s")

    start = time.perf_counter()
    fpu = fpu_sweep(config.fpu_xs, config.fpu_steps)
    timings["fpu"] = time.perf_counter() - start
    log(f"FPU sweep: {timings['fpu']:.1f} s")

    start = time.perf_counter()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.ConditioningWarning)
        high = high_degree(config.high_degrees, config.high_steps)
    timings["high_degree"] = time.perf_counter() - start
    log(f"high degree: {timings['high_degree']:.1f} s")

    traces = {}
    grid = np.linspace(0.0, config.x_max, 800)
    for f in FAMILIES:
        for s in config.degrees:
            polys = trace_polynomials(method_for(f, s))
            traces[label(f, s)] = [float(polys.trace(x)) for x in grid]
    return {
        "meta": {
            "config": asdict(config),
            "python": platform.python_version(),
            "galerkin_vi": gvi.__version__,
            "machine": platform.machine(),
        },
        "theory": [asdict(st) for st in theory],
        "oscillator": [_check_dict(c) for c in checks],
        "growth_sweep": sweeps,
        "fpu": fpu,
        "high_degree": high,
        "trace_curves": {"x": [float(x) for x in grid], "trace": traces},
        "timings": timings,
    }


def _check_dict(check: OscillatorCheck) -> dict:
    out = asdict(check)
    for edge, raw in zip(check.edges, out["edges"], strict=True):
        raw["relative_error"] = edge.relative_error
    return out


# -------------------------------------------------------------------------- output
def _fmt(x: float | None, digits: int = 7) -> str:
    if x is None:
        return "—"
    if not math.isfinite(x):
        return "∞"
    return f"{x:.{digits}g}"


def markdown(results: dict) -> str:
    """The tables of ``results`` as Markdown."""
    lines = ["# Stability and high-degree conditioning", ""]
    lines += [
        "## Linear stability on the harmonic oscillator (theory: exact tr M)",
        "",
        "x = hω. Unstable intervals: |tr M| > 2; ρ = peak spectral radius; "
        "N₁₀₆ = steps to grow 10⁶-fold at the peak.",
        "",
        "| method | first limit | unstable intervals (ρ, N₁₀₆) | |tr M|=2 touches "
        "(M = ±I) | tr M at ∞ |",
        "|---|---|---|---|---|",
    ]
    for st in results["theory"]:
        intervals = "; ".join(
            f"({_fmt(iv['lo'])}, {_fmt(iv['hi']) if iv['hi'] else '∞'}) "
            f"[ρ {iv['rho_peak']:.3g}, {_fmt(iv['steps_to_warning'], 3)}]"
            for iv in st["unstable"]
            if iv["lo"] < 30
        )
        touches = ", ".join(_fmt(x) for x in st["touches"] if x < 30) or "—"
        lines.append(
            f"| {st['label']} | {_fmt(st['limit'], 10)} | {intervals or 'none'} | {touches} "
            f"| {st['trace_at_infinity']} |"
        )
    lines += [
        "",
        "## Theory against runs (oscillator, compiled backend)",
        "",
        "Edges by bisection on runs of N steps (unstable = ConvergenceError or "
        "InstabilityWarning); lag = expected shift (ln 10⁶/N)²/|t′| on the unstable side.",
        "",
        "| method | kernel | N | edge (theory) | measured | rel. diff | expected lag | runs |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for check in results["oscillator"]:
        for edge in check["edges"]:
            lines.append(
                f"| {check['label']} | {check['kernel_path']} | {edge['n_steps']} "
                f"| {edge['theory']:.9g} | {edge['measured']:.9g} "
                f"| {edge['relative_error']:.1e} | {edge['expected_lag']:.1e} | {edge['runs']} |"
            )
    lines += [
        "",
        "Runs inside the intervals: stable middles (all must be bounded) and unstable peaks.",
        "",
        "| method | stable middles: outcomes | unstable peaks: x, outcome, growth log₁₀ "
        "(predicted N log₁₀ ρ) |",
        "|---|---|---|",
    ]
    for check in results["oscillator"]:
        stable = ", ".join(f"{r['x']:.4g}: {r['outcome']}" for r in check["stable_runs"])
        peaks = "; ".join(
            f"{u['x_peak']:.6g}: {u['run']['outcome']}, {u['run']['growth']:.3g} "
            f"({min(u['predicted_growth'], 1e4):.3g})"
            for u in check["unstable_runs"]
        )
        lines.append(f"| {check['label']} | {stable} | {peaks or '—'} |")
    fpu = results["fpu"]
    lines += [
        "",
        f"## Fermi–Pasta–Ulam (ω = {fpu['omega']:g}, {fpu['n_steps']} steps per run)",
        "",
        f"Largest linearised frequency along a stable run: ω_max = {fpu['omega_max']:.5g}.",
        "",
        "| method | kernel | oscillator limit | predicted x*ω/ω_max | measured bracket "
        "| first Newton failure | all finite |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in fpu["methods"]:
        bracket = m["measured_limit"]["bracket"] if m["measured_limit"] else None
        lines.append(
            f"| {m['label']} | {m['kernel_path']} | {_fmt(m['oscillator_limit'], 6)} "
            f"| {_fmt(m['predicted_limit'], 6)} "
            f"| {'—' if bracket is None else f'[{bracket[0]:.5g}, {bracket[1]:.5g}]'} "
            f"| {_fmt(m['first_newton_failure'], 4)} | {m['all_finite']} |"
        )
    lines += [
        "",
        "Outcome per hω (b = bounded, W = InstabilityWarning, N = Newton failure, "
        "F = non-finite; step of failure in brackets):",
        "",
    ]
    header = "| hω | " + " | ".join(m["label"] for m in fpu["methods"]) + " |"
    lines += [header, "|---" * (1 + len(fpu["methods"])) + "|"]
    for k, x in enumerate(fpu["methods"][0]["runs"]):
        cells = []
        for m in fpu["methods"]:
            r = m["runs"][k]
            code = {"bounded": "b", "warning": "W"}.get(r["outcome"])
            if code is None:
                code = {"newton": "N", "non-finite": "F"}.get(r["failure"], "?")
                code += f" ({r['steps']})"
            cells.append(code)
        lines.append(f"| {x['x']:g} | " + " | ".join(cells) + " |")
    high = results["high_degree"]
    steps = high["steps"]
    lines += [
        "",
        f"## High degree (Lobatto s+1 quadrature, oscillator ω = 1, error at T = "
        f"{high['t_final']:g})",
        "",
        "κ₂ of the stage Jacobian at hω = 0.5 / 1; errors for h = "
        + ", ".join(f"{h:g}" for h in steps)
        + " with the linear kernel (default) and the Newton kernel (specialize=False).",
        "",
        "| s | κ Lobatto | κ equidistant | error Lobatto, linear | error Lobatto, Newton "
        "| error equidistant, linear | error equidistant, Newton | µs/step linear / Newton "
        "(Newton iterations) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for row in high["rows"]:
        lob, equ = row["lobatto"], row["equidistant"]

        def errs(entry: dict, kernel: str) -> str:
            return " / ".join(f"{entry[kernel]['error'][str(h)]:.1e}" for h in steps)

        lines.append(
            f"| {row['degree']} | {lob['cond']['0.5']:.3g} / {lob['cond']['1.0']:.3g} "
            f"| {equ['cond']['0.5']:.3g} / {equ['cond']['1.0']:.3g} "
            f"| {errs(lob, 'linear')} | {errs(lob, 'newton')} | {errs(equ, 'linear')} "
            f"| {errs(equ, 'newton')} | {lob['linear']['us_per_step']:.2g} / "
            f"{lob['newton']['us_per_step']:.2g} "
            f"({lob['newton']['mean_iterations'][str(steps[-1])]:.1f}) |"
        )
    lines += ["", "## Timings (s)", ""]
    lines += [f"- {k}: {v:.1f}" for k, v in results["timings"].items()]
    return "\n".join(lines) + "\n"


def plots(results: dict, folder: Path) -> list[Path]:
    """The four PNG plots; an empty list when matplotlib is missing."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return []
    written = []
    theory = {st["label"]: st for st in results["theory"]}

    # 1. |tr M(x)| per method, limit marked
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    x = np.array(results["trace_curves"]["x"])
    for ax, family in zip(axes, FAMILIES, strict=True):
        for name, trace in results["trace_curves"]["trace"].items():
            if theory[name]["family"] != family:
                continue
            (line,) = ax.plot(x, np.abs(trace), lw=1.2, label=name)
            limit = theory[name]["limit"]
            if limit is not None and limit < x[-1]:
                ax.axvline(limit, color=line.get_color(), ls=":", lw=1)
                ax.plot([limit], [2.0], "o", color=line.get_color(), ms=4)
        ax.axhline(2.0, color="k", lw=0.8)
        ax.set_ylim(0, 3)
        ax.set_xlabel("x = hω")
        ax.set_title(f"{'Lobatto s+1' if family == 'lobatto' else 'Gauss s'}: |tr M(x)|")
        ax.legend(fontsize=7, loc="lower left")
    axes[0].set_ylabel("|tr M|  (stable below 2)")
    fig.tight_layout()
    written.append(folder / "stability_trace.png")
    fig.savefig(written[-1], dpi=120)
    plt.close(fig)

    # 2. measured growth rate per step around the limits, against log10 rho(x)
    sweeps = results["growth_sweep"]
    lobatto = [sw for sw in sweeps if sw["family"] == "lobatto"]
    gauss = [sw for sw in sweeps if sw["family"] == "gauss"]
    ncols = 3
    nrows = -(-(len(lobatto) + 1) // ncols)
    fig, axes = plt.subplots(nrows, ncols, figsize=(5 * ncols, 3.6 * nrows), squeeze=False)
    for ax, sweep in zip(axes.flat, lobatto, strict=False):
        xs = np.array(sweep["x"])
        lo, hi = sweep["interval"]
        ax.axvspan(lo, hi if hi is not None else xs[-1], color="0.9")
        ax.plot(xs, sweep["theory_rate"], "-", color="C0", lw=1, label="theory log10 ρ(x)")
        ax.plot(xs, sweep["rate"], ".", color="C3", ms=4, label="measured")
        first = sweep["first_limit"]
        note = ""
        if abs(first - lo) > 1e-12:
            weak = sweep["first_steps_to_warning"]
            note = f"\n(first limit {first:.9g}: grows 1e6-fold only in {weak:.2g} steps)"
        ax.set_title(f"{sweep['label']}: interval ({lo:.6g}, {_fmt(hi, 6)}){note}", fontsize=9)
        ax.set_xlabel("x = hω")
        ax.ticklabel_format(axis="x", useOffset=False)
        ax.tick_params(axis="x", labelsize=7)
        ax.legend(fontsize=7)
    ax = axes.flat[len(lobatto)]
    for sweep in gauss:
        ax.semilogx(sweep["x"], sweep["rate"], ".", ms=3, label=sweep["label"])
    ax.axhline(0.0, color="k", lw=0.6)
    ax.set_xlabel("x = hω")
    ax.set_title("Gauss s: measured rate (theory: 0, A-stable)", fontsize=9)
    ax.legend(fontsize=7)
    for extra in list(axes.flat)[len(lobatto) + 1 :]:
        extra.set_visible(False)
    axes[0, 0].set_ylabel(f"log10 growth per step ({sweeps[0]['n_steps']} steps)")
    fig.tight_layout()
    written.append(folder / "stability_growth.png")
    fig.savefig(written[-1], dpi=120)
    plt.close(fig)

    # 3. condition numbers vs s; 4. errors vs s
    rows = results["high_degree"]["rows"]
    s = [r["degree"] for r in rows]
    fig, ax = plt.subplots(figsize=(6.5, 4.5))
    for nodes, marker in (("lobatto", "o"), ("equidistant", "s")):
        for xv, ls in (("0.5", "-"), ("1.0", "--")):
            ax.semilogy(
                s,
                [r[nodes]["cond"][xv] for r in rows],
                marker + ls,
                ms=4,
                label=f"{nodes}, hω = {xv}",
            )
    ax.set_xlabel("degree s")
    ax.set_ylabel("κ₂(stage Jacobian)")
    ax.set_title("Stage Jacobian conditioning (Lobatto s+1 quadrature)")
    ax.legend(fontsize=8)
    ax.grid(True, which="both", alpha=0.3)
    fig.tight_layout()
    written.append(folder / "stability_condition.png")
    fig.savefig(written[-1], dpi=120)
    plt.close(fig)

    fig, axes = plt.subplots(1, 2, figsize=(12, 4.5), sharey=True)
    for ax, kernel in zip(axes, ("linear", "newton"), strict=True):
        for nodes, marker in (("lobatto", "o"), ("equidistant", "s")):
            for h in results["high_degree"]["steps"]:
                err = [max(r[nodes][kernel]["error"][str(h)], 1e-17) for r in rows]
                ax.semilogy(s, err, marker + "-", ms=4, label=f"{nodes}, h = {h:g}")
        ax.set_xlabel("degree s")
        ax.set_title(f"error at T = {results['high_degree']['t_final']:g}, {kernel} kernel")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    axes[0].set_ylabel("|q_N − q(T)|")
    fig.tight_layout()
    written.append(folder / "stability_error.png")
    fig.savefig(written[-1], dpi=120)
    plt.close(fig)
    return written


def write_outputs(results: dict, folder: str | Path) -> list[Path]:
    """stability.json, stability.md and the PNG plots in ``folder``."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    paths = [folder / "stability.json", folder / "stability.md"]
    paths[0].write_text(json.dumps(_plain(results), indent=1, allow_nan=False))
    paths[1].write_text(markdown(results))
    return paths + plots(results, folder)


def _plain(obj):
    """``obj`` with mpmath and NumPy scalars as floats and non-finite floats as strings."""
    if isinstance(obj, dict):
        return {str(k): _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    if isinstance(obj, (mpmath.mpf, np.floating)):
        obj = float(obj)
    if isinstance(obj, np.integer | np.bool_):
        return obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return str(obj)
    return obj


def main(argv: Sequence[str] | None = None) -> int:
    """Parse ``argv``, run, write the outputs."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", metavar="DIR", default="stability-out")
    parser.add_argument("--quick", action="store_true", help="a shorter run (about 20 s)")
    args = parser.parse_args(argv)
    start = time.perf_counter()
    results = run(QUICK if args.quick else FULL)
    results["timings"]["total"] = time.perf_counter() - start
    for path in write_outputs(results, args.output):
        print(f"wrote {path}")
    print(f"finished in {results['timings']['total']:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
