r"""The order-verification report: ``galerkin-vi verify`` as a library.

For each problem, degree :math:`s` and quadrature family the report

1. measures the convergence order of the final (or maximal) position error
   with :func:`~galerkin_vi.tools.verification.measure_order` and compares it with
   the prediction :math:`\min(2s, \text{quadrature order})`;
2. runs the method once more at the finest step of the order study and records
   the largest energy error :math:`\max_k |H_k - H_0| / \max(1, |H_0|)` (only
   for conservative problems: none with forces or a time-dependent Lagrangian,
   whose energy changes) and the largest drift of the momentum maps of the
   problem's symmetries,
   :math:`\max_k |J_k - J_0| / \max(1, |J_0|)`, which discrete Noether keeps at
   solver tolerance.

A row passes when the measured order is within :data:`ORDER_TOLERANCE` of the
prediction (fitted on at least three runs) and every momentum drift is below
:data:`MOMENTUM_TOLERANCE`.
"""

from __future__ import annotations

import functools
import importlib
import json
import math
import warnings
from collections.abc import Callable, Iterable, Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from .. import problems
from ..errors import OrderReductionWarning
from ..integrator import Integrator
from ..method.composition import Composition
from ..method.galerkin import Galerkin
from ..method.quadrature import gauss_legendre, gauss_lobatto
from ..model.system import LagrangianSystem
from ..run.loop_choice import composition_for, composition_obstacle
from .verification import OrderResult, measure_order

__all__ = [
    "FAMILIES",
    "MOMENTUM_TOLERANCE",
    "ORDER_TOLERANCE",
    "PROBLEMS",
    "VerificationRow",
    "format_table",
    "load_problem",
    "verify",
    "write_outputs",
]

ORDER_TOLERANCE = 0.3
MOMENTUM_TOLERANCE = 1e-10
# Degrees above FLOAT64_MAX_DEGREE are measured in mpmath: in float64 their errors above the
# round-off floor are still pre-asymptotic (see tests/test_order.py).
FLOAT64_MAX_DEGREE = 3
MP_DIGITS = 40
#: compositions of at least this order are studied in mpmath, at these step counts
MP_COMPOSITION_ORDER = 8
MP_COMPOSITION_COUNTS = (16, 32, 64)
#: splittings (free kicks, Composition.splitting) are studied in mpmath at these counts,
#: by order: their leading error terms are small by design, so errors above float64
#: round-off follow the higher terms (Blanes-Moan's order 4 shows 6-7 on Kepler down to
#: h = T/50, 3.4 at T/80); order 6 stops short of 1e-18, below which the 15 published
#: digits of its coefficients show as an h^4 term
MP_SPLITTING_COUNTS = {4: (256, 512, 1024), 6: (32, 64, 128)}


@dataclass(frozen=True)
class ProblemEntry:
    """A library problem as the report runs it: factory and mpmath step counts."""

    factory: Callable[[], problems.Problem]
    mp_step_counts: tuple[int, ...]


PROBLEMS: dict[str, ProblemEntry] = {
    "harmonic_oscillator": ProblemEntry(lambda: problems.harmonic_oscillator(1.3), (8, 16, 32)),
    "pendulum": ProblemEntry(problems.pendulum, (8, 16, 32)),
    "kepler": ProblemEntry(lambda: problems.kepler(0.5), (32, 64, 128)),
    "double_pendulum": ProblemEntry(problems.double_pendulum, (32, 64, 128)),
    "henon_heiles": ProblemEntry(lambda: problems.henon_heiles(t_final=2.0), (8, 16, 32)),
    "spherical_pendulum": ProblemEntry(
        lambda: problems.spherical_pendulum(t_final=2.0), (8, 16, 32)
    ),
    # forces (discrete Lagrange-d'Alembert) and a time-dependent L, with exact solutions
    "damped_oscillator": ProblemEntry(lambda: problems.damped_oscillator(t_final=2.0), (8, 16, 32)),
    "driven_oscillator": ProblemEntry(lambda: problems.driven_oscillator(t_final=2.0), (8, 16, 32)),
    # time-dependent L with a mixed term L_qv and d(L_v)/dt; the fast pivot period
    # 2 pi / 20 sets the step sizes (s = 4 in mpmath: 7.55 for Gauss at 16, 32, 64 steps,
    # 7.95 at 24, 48, 96)
    "kapitza_pendulum": ProblemEntry(lambda: problems.kapitza_pendulum(t_final=1.0), (24, 48, 96)),
    # holonomic constraints: collocated Lobatto only (Gauss rows are skipped), float64 at
    # every degree (no mpmath path). The four-bar linkage has no trusted reference (its
    # Richardson estimate is pre-asymptotic at affordable steps); tests cover it instead
    "cartesian_pendulum": ProblemEntry(lambda: problems.cartesian_pendulum(t_final=2.0), ()),
    "constrained_spherical_pendulum": ProblemEntry(
        lambda: problems.constrained_spherical_pendulum(t_final=2.0), ()
    ),
    "rotating_hoop": ProblemEntry(lambda: problems.rotating_hoop(t_final=2.0), ()),
}
FAMILIES = {
    "lobatto": lambda s: gauss_lobatto(s + 1),
    "gauss": gauss_legendre,
}


@dataclass(frozen=True)
class VerificationRow:
    """One line of the report (all numbers plain Python, ready for JSON)."""

    problem: str
    degree: int
    quadrature: str
    predicted: int
    measured: float
    points_fitted: int
    finest_error: float
    max_energy_error: float | None
    max_momentum_drift: float | None
    passed: bool
    precision: str
    step_counts: list[int] = field(default_factory=list)
    step_sizes: list[float] = field(default_factory=list)
    errors: list[float] = field(default_factory=list)
    fitted: list[bool] = field(default_factory=list)


def load_problem(spec: str) -> problems.Problem:
    """A user's problem from ``"module:attribute"``.

    The attribute may be a :class:`~galerkin_vi.problems.Problem` or a callable
    returning one. A bare :class:`LagrangianSystem` has no initial data, so it is
    rejected with a hint.
    """
    module_name, sep, attribute = spec.partition(":")
    if not sep or not module_name or not attribute:
        raise ValueError(f"--problem expects 'module:attribute', got {spec!r}")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ValueError(f"--problem {spec}: cannot import module {module_name!r}: {exc}") from exc
    try:
        obj = getattr(module, attribute)
    except AttributeError as exc:
        raise ValueError(f"--problem {spec}: {module_name} has no attribute {attribute!r}") from exc
    if callable(obj) and not isinstance(obj, problems.Problem | LagrangianSystem):
        obj = obj()
    if isinstance(obj, LagrangianSystem):
        raise ValueError(
            f"--problem {spec} is a LagrangianSystem without initial data: wrap it in "
            "galerkin_vi.problems.Problem(name, system, q0, v0, t_final) (or a function "
            "returning one)"
        )
    if not isinstance(obj, problems.Problem):
        raise ValueError(
            f"--problem {spec} must be a galerkin_vi.problems.Problem or a callable returning "
            f"one, got {type(obj).__name__}"
        )
    return obj


def _reference(problem: problems.Problem) -> Callable[[float | np.ndarray], np.ndarray] | None:
    """The problem's trusted reference ``t -> q(t)``, or None (constrained, no exact solution).

    Without an exact solution, one DOP853 run over the problem's span
    (:func:`~galerkin_vi.problems.ode_interpolant`) serves every run of every
    study of the problem: the values equal :meth:`Problem.reference`'s, without
    a new integration per run.
    """
    if problem.exact is not None:
        return problem.reference
    if problem.system.constraints is not None:
        return None
    return problems.ode_interpolant(
        problem.system, problem.q0, problem.v0, problem.t_final, problem.params
    )


def _order_study(
    problem: problems.Problem,
    method: Galerkin | Composition,
    mp_step_counts: Sequence[int],
    step_counts: Sequence[int] | None,
    integrator: Integrator,
    reference: Callable[[], Callable[[float | np.ndarray], np.ndarray] | None],
) -> tuple[OrderResult, str]:
    common = {"t_final": problem.t_final, "params": problem.params}
    if isinstance(method, Composition) and (
        method.order >= MP_COMPOSITION_ORDER or method.splitting
    ):
        # float64 errors above round-off are still pre-asymptotic for these
        counts = MP_COMPOSITION_COUNTS
        if method.splitting:
            counts = MP_SPLITTING_COUNTS.get(method.order, counts)
        result = measure_order(
            problem.system, method, problem.q0, problem.v0,
            step_counts=list(step_counts or counts), dps=MP_DIGITS, **common,
        )  # fmt: skip
        return result, f"mpmath {MP_DIGITS} digits"
    if isinstance(method, Galerkin) and method.degree > FLOAT64_MAX_DEGREE and not problem.system.m:
        result = measure_order(
            problem.system,
            method,
            problem.q0,
            problem.v0,
            step_counts=list(step_counts or mp_step_counts),
            dps=MP_DIGITS,
            **common,
        )
        return result, f"mpmath {MP_DIGITS} digits"
    trusted = reference()
    if trusted is None:
        # no trusted reference: Richardson extrapolation of the method itself
        result = measure_order(
            problem.system,
            method,
            problem.q0,
            problem.v0,
            step_counts=list(step_counts or (16, 32, 64)),
            integrator=integrator,
            **common,
        )
        return result, "float64, Richardson reference"
    result = measure_order(
        problem.system,
        method,
        problem.q0,
        problem.v0,
        step_counts=list(step_counts) if step_counts else "auto",
        reference=trusted,
        norm="max",
        window=(1e-12 if problem.exact is not None else 1e-10, 1e-4),
        integrator=integrator,
        **common,
    )
    return result, "float64"


def _invariants(
    problem: problems.Problem, integrator: Integrator, n_steps: int
) -> tuple[float | None, float | None]:
    """Largest relative energy error and momentum-map drift at ``n_steps`` steps.

    The energy error is None when the energy is not an invariant: with forces,
    a time-dependent Lagrangian or time-dependent constraints.
    """
    traj = integrator.integrate(
        problem.q0,
        problem.v0,
        h=problem.t_final / n_steps,
        n_steps=n_steps,
        params=problem.params,
        on_failure="raise",
    )
    structure = problem.system.structure
    energy_error = None
    moving_constraints = problem.system.t is not None and any(
        problem.system.t in g.free_symbols for g in problem.system.constraints or ()
    )
    if structure.autonomous and not structure.forced and not moving_constraints:
        energy = traj.energy()
        energy_error = float(np.max(np.abs(energy - energy[0])) / max(1.0, abs(energy[0])))
    drifts = []
    for xi in problem.symmetries.values():
        J = traj.momentum(xi)
        drifts.append(float(np.max(np.abs(J - J[0])) / max(1.0, abs(J[0]))))
    return energy_error, (max(drifts) if drifts else None)


def verify(
    selected: Iterable[tuple[str, problems.Problem, Sequence[int]]],
    degrees: Sequence[int],
    families: Sequence[str],
    step_counts: Sequence[int] | None = None,
    progress: Callable[[str], None] | None = None,
    compositions: Sequence[int] = (),
) -> list[VerificationRow]:
    """Run the order study of every (problem, degree, family), and of every composition
    order on the problems that allow compositions.

    Parameters
    ----------
    selected : iterable of (name, Problem, mpmath step counts)
    degrees : sequence of int
    families : sequence of {"lobatto", "gauss"}
        Lobatto with :math:`s + 1` points or Gauss with :math:`s` points
        (constrained problems run Lobatto only).
    step_counts : sequence of int, optional
        Fixed step counts instead of the automatic choice (float64) or the
        problem's mpmath step counts.
    progress : callable, optional
        Called with a short label before each study (progress bars).
    compositions : sequence of int
        Orders of :class:`~galerkin_vi.Composition` (default scheme) to study on
        every problem with a separable Lagrangian and constant mass (rows of
        degree 1, quadrature ``"composition <scheme>"``).
    """
    rows = []
    for name, problem, mp_counts in selected:
        reference = functools.cache(functools.partial(_reference, problem))
        for s in degrees:
            for family in families:
                if problem.system.m and family != "lobatto":
                    continue  # constraints need the collocated Lobatto method
                if progress is not None:
                    progress(f"{name} s={s} {family}")
                rule = FAMILIES[family](s)
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", OrderReductionWarning)
                    method = Galerkin(s, rule)
                study = (problem, method, mp_counts, step_counts, reference)
                rows.append(_study_row(name, s, repr(rule), *study))
        if composition_obstacle(problem.system) is not None:
            continue  # compositions need a separable L with constant mass
        for order in compositions:
            method = composition_for(problem.system, order)
            if progress is not None:
                progress(f"{name} {method!r}")
            label = f"composition {method.scheme}"
            study = (problem, method, mp_counts, step_counts, reference)
            rows.append(_study_row(name, 1, label, *study))
    return rows


def loop_labels(
    selected: Iterable[tuple[str, problems.Problem, Sequence[int]]],
    degrees: Sequence[int],
    families: Sequence[str],
) -> list[str]:
    """The warm-up runs whose loops the Galerkin studies of :func:`verify` run.

    ``galerkin-vi verify`` compiles them in parallel at its start
    (:func:`galerkin_vi.tools.warmup.prefetch`); a study whose loop variant
    differs still compiles it at first use.
    """
    from .warmup import variant_labels

    labels: dict[str, None] = {}
    for _, problem, _ in selected:
        for s in degrees:
            for family in families:
                if problem.system.m and family != "lobatto":
                    continue
                with warnings.catch_warnings():
                    warnings.simplefilter("ignore", OrderReductionWarning)
                    method = Galerkin(s, FAMILIES[family](s))
                integrator = Integrator(problem.system, method)
                labels.update(dict.fromkeys(variant_labels(integrator.run_spec)))
    return list(labels)


def _study_row(
    name: str, degree: int, label: str, problem: problems.Problem,
    method: Galerkin | Composition, mp_counts, step_counts, reference,
) -> VerificationRow:  # fmt: skip
    """The order study and invariants of ``method`` on ``problem`` as one report row."""
    integrator = Integrator(problem.system, method)
    result, precision = _order_study(problem, method, mp_counts, step_counts, integrator, reference)
    fitted = int(result.mask.sum())
    finest_index = int(np.max(np.nonzero(result.mask)[0])) if fitted else -1
    n_finest = int(result.step_counts[finest_index])
    energy_error, drift = _invariants(problem, integrator, n_finest)
    ok_order = fitted >= 3 and abs(result.order - method.order) <= ORDER_TOLERANCE
    ok_momentum = drift is None or drift <= MOMENTUM_TOLERANCE
    return VerificationRow(
        problem=name,
        degree=degree,
        quadrature=label,
        predicted=int(method.order),
        measured=float(result.order),
        points_fitted=fitted,
        finest_error=float(result.errors[finest_index]) if fitted else math.nan,
        max_energy_error=energy_error,
        max_momentum_drift=drift,
        passed=bool(ok_order and ok_momentum),
        precision=precision,
        step_counts=[int(n) for n in result.step_counts],
        step_sizes=[float(h) for h in result.step_sizes],
        errors=[float(e) for e in result.errors],
        fitted=[bool(m) for m in result.mask],
    )


def format_table(rows: Sequence[VerificationRow]) -> str:
    """The report as a fixed-width text table."""
    width = max([20, *(len(r.problem) for r in rows)])
    rule = max([18, *(len(r.quadrature) for r in rows)])
    header = (
        f"{'problem':<{width}} {'s':>2} {'quadrature':<{rule}} {'predicted':>9} {'measured':>9} "
        f"{'max energy err':>14} {'max momentum drift':>18} {'verdict':>7}"
    )
    lines = [header, "-" * len(header)]
    for r in rows:
        energy = "—" if r.max_energy_error is None else f"{r.max_energy_error:.1e}"
        drift = "—" if r.max_momentum_drift is None else f"{r.max_momentum_drift:.1e}"
        lines.append(
            f"{r.problem:<{width}} {r.degree:>2} {r.quadrature:<{rule}} {r.predicted:>9d} "
            f"{r.measured:>9.2f} {energy:>14} {drift:>18} "
            f"{'pass' if r.passed else 'FAIL':>7}"
        )
    return "\n".join(lines)


def write_outputs(rows: Sequence[VerificationRow], folder: str | Path) -> list[Path]:
    """Write ``verify.json`` and one convergence plot per problem into ``folder``.

    Each plot shows the error against :math:`h` on log–log axes for every
    method of the problem, the fitted points filled, with the predicted slope
    drawn through the finest fitted point. Returns the paths written.
    """
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    written = [folder / "verify.json"]
    payload = {
        "order_tolerance": ORDER_TOLERANCE,
        "momentum_tolerance": MOMENTUM_TOLERANCE,
        "rows": [asdict(r) for r in rows],
    }
    written[0].write_text(json.dumps(payload, indent=1, allow_nan=True))
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    for name in dict.fromkeys(r.problem for r in rows):
        fig, ax = plt.subplots(figsize=(6.4, 4.8))
        for r in (r for r in rows if r.problem == name):
            h, e, used = np.array(r.step_sizes), np.array(r.errors), np.array(r.fitted)
            label = f"s={r.degree} {r.quadrature}: {r.measured:.2f} (pred. {r.predicted})"
            (line,) = ax.loglog(h, e, "o-", mfc="none", label=label)
            ax.loglog(h[used], e[used], "o", color=line.get_color())
            if used.any():
                h0, e0 = h[used].min(), e[used][np.argmin(h[used])]
                slope_h = np.array([h0, h[used].max()])
                ax.loglog(slope_h, e0 * (slope_h / h0) ** r.predicted, ":", color="k", lw=0.8)
        ax.set_xlabel("step size h")
        ax.set_ylabel("position error")
        ax.set_title(f"{name}: measured order (dotted: predicted slope)")
        ax.legend(fontsize=7)
        fig.tight_layout()
        path = folder / f"{name}_convergence.png"
        fig.savefig(path, dpi=110)
        plt.close(fig)
        written.append(path)
    return written
