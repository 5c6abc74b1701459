r"""Assertions for users' own test suites: measured orders and conserved quantities.

Both functions raise :class:`AssertionError` with a table of the measured
numbers, so a failing test says what was measured, against what, and what to
try next. They do not depend on pytest (any test runner, or none, will do);
under pytest their own frames are hidden from the traceback.

>>> from galerkin_vi.testing import assert_conserved, assert_order

Nothing here is imported by ``import galerkin_vi``: import
``galerkin_vi.testing`` explicitly.
"""

from __future__ import annotations

import inspect
import numbers
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from .errors import ConvergenceError
from .method.galerkin import Galerkin
from .model.system import LagrangianSystem
from .problems.base import Problem
from .run.trajectory import Trajectory
from .tools.verification import OrderResult, measure_order

__all__ = ["assert_conserved", "assert_order"]

#: Generator :math:`\xi_Q(q)` of a symmetry: one SymPy expression per coordinate.
Generator = Sequence[sp.Expr | float]

_EPS = float(np.finfo(float).eps)

# measure_order's own arguments that assert_order fills in itself
_POSITIONAL = ("system", "method", "q0", "v0", "t_final")
_MEASURE_ORDER_OPTIONS = tuple(
    name for name in inspect.signature(measure_order).parameters if name not in _POSITIONAL
)
_DEFAULT_WINDOW = inspect.signature(measure_order).parameters["window"].default

# allowance for round-off in the no-drift test, relative to max(1, |E_0|)
# (tests/test_energy.py uses the same 1e-14)
_BOUNDED_SLACK = 1e-14
_MIN_STATES_BOUNDED = 20


# ---------------------------------------------------------------------------
# assert_order
# ---------------------------------------------------------------------------


def assert_order(
    system_or_problem: LagrangianSystem | Problem,
    method: Galerkin,
    q0: ArrayLike | None = None,
    v0: ArrayLike | None = None,
    t_final: float | None = None,
    *,
    predicted: float | None = None,
    tolerance: float = 0.3,
    min_points: int = 3,
    **measure_order_kwargs: Any,
) -> OrderResult:
    r"""Assert that ``method`` converges with the predicted order.

    Runs :func:`galerkin_vi.measure_order` and checks that the fitted slope
    :math:`\hat p` of :math:`\log e_N` against :math:`\log h_N`
    (:math:`h_N = T/N`, :math:`e_N` the position error of the run with
    :math:`N` steps) satisfies

    .. math::

        |\hat p - p| \le \text{tolerance}

    with :math:`p` the predicted order, and that at least ``min_points`` runs
    entered the fit (runs at the round-off floor or whose error does not
    decrease are left out by :func:`measure_order`).

    Parameters
    ----------
    system_or_problem : LagrangianSystem or Problem
        With a :class:`~galerkin_vi.problems.Problem` (for example
        ``galerkin_vi.problems.pendulum()``), ``q0``, ``v0``, ``t_final`` and
        ``params`` default to the problem's, and the reference is its exact
        solution when it has one and the initial data and parameters are the
        problem's own; otherwise (and always with ``dps``, as the exact
        solutions are float64 functions) the reference is Richardson
        extrapolation of the method itself. Pass ``reference=`` to choose,
        e.g. ``reference=problem.reference`` for an independent DOP853 solution.
        With a bare :class:`~galerkin_vi.LagrangianSystem`, ``q0`` and one of
        ``v0`` or ``p0`` are required.
    method : Galerkin
    q0, v0 : array_like, shape (n,), optional
        Initial positions and velocities (give ``p0=`` instead of ``v0`` to
        start from momenta).
    t_final : float, optional
        Length of the time interval: the problem's, or 2.0 for a bare system.
    predicted : float, optional
        Expected order; default ``method.order`` (:math:`\min(2s, u)`).
    tolerance : float
        Largest accepted :math:`|\hat p - p|`.
    min_points : int
        Fewest runs the fit must use (``step_counts="auto"`` fits at most 3).
    **measure_order_kwargs
        Passed on to :func:`galerkin_vi.measure_order`: ``step_counts``
        (default ``(8, 16, 32)``), ``reference``, ``norm``, ``window``,
        ``dps``, ``params``, ``p0``, ``t0``, ``backend``, ``integrator``.

    Returns
    -------
    OrderResult
        The measurement, on success.

    Raises
    ------
    AssertionError
        If the fitted order is off by more than ``tolerance`` or too few runs
        are usable. The message shows N, h, the errors, the pairwise orders
        :math:`\log(e_{N_{j-1}}/e_{N_j}) / \log(h_{j-1}/h_j)`, why runs were
        left out, the fitted and predicted orders, and hints.
    TypeError
        If an argument has the wrong type, an initial condition is missing for
        a bare system, or an option is unknown to :func:`measure_order`.
    ValueError
        If ``tolerance``, ``predicted`` or ``min_points`` are out of range, or
        fewer than ``min_points`` step counts are given.
    ConvergenceError
        From a run of the study, unchanged (as is the ``RuntimeError`` of
        ``step_counts="auto"`` when it finds no runs in its window).

    Examples
    --------
    >>> import galerkin_vi as gvi
    >>> from galerkin_vi import problems
    >>> from galerkin_vi.testing import assert_order
    >>> oscillator = problems.harmonic_oscillator()
    >>> result = assert_order(oscillator, gvi.Galerkin(2), step_counts=[10, 20, 40],
    ...                       backend="numpy")
    >>> round(result.order, 1)
    4.0

    A bare system needs its initial data:

    >>> import sympy as sp
    >>> x, v = sp.symbols("x v")
    >>> system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(x), [x], [v])
    >>> result = assert_order(system, gvi.Galerkin(1), [1.0], [0.0], t_final=2.0,
    ...                       step_counts=[10, 20, 40], backend="numpy")

    A wrong prediction fails with the measured table:

    >>> assert_order(oscillator, gvi.Galerkin(2), predicted=6,
    ...              step_counts=[10, 20, 40], backend="numpy")
    Traceback (most recent call last):
    ...
    AssertionError: assert_order: fitted order 4.00 differs from the predicted 6 by 2.00 > ...
    """
    __tracebackhide__ = True
    problem, system = _split_problem(system_or_problem)
    predicted, tolerance = _checked_order_options(
        method, predicted, tolerance, min_points, measure_order_kwargs
    )
    kwargs = dict(measure_order_kwargs)
    q0, v0, t_final = _initial_data(problem, q0, v0, t_final, kwargs)

    with warnings.catch_warnings():
        # measure_order warns when fewer than two points are usable; the assertion says more
        warnings.filterwarnings(
            "ignore", message="fewer than two step counts", category=RuntimeWarning
        )
        result = measure_order(system, method, q0, v0, t_final=t_final, **kwargs)

    used = int(result.mask.sum())
    difference = abs(result.order - predicted)
    if used >= min_points and np.isfinite(result.order) and difference <= tolerance:
        return result
    raise AssertionError(
        _order_failure(result, method, problem, t_final, predicted, tolerance, min_points, kwargs)
    )


def _checked_order_options(
    method: object,
    predicted: object,
    tolerance: object,
    min_points: object,
    measure_order_kwargs: Mapping[str, Any],
) -> tuple[float, float]:
    """Check :func:`assert_order`'s own options; return ``predicted`` and ``tolerance`` as floats.

    ``predicted`` defaults to ``method.order``. The step counts must be able to give
    ``min_points`` points of the fit, and every other keyword must be an option of
    :func:`measure_order`.
    """
    __tracebackhide__ = True
    if not isinstance(method, Galerkin):
        raise TypeError(f"method must be a galerkin_vi.Galerkin, got {type(method).__name__}")
    if predicted is None:
        predicted = method.order
    predicted = _real(predicted, "predicted")
    if not predicted > 0:
        raise ValueError(f"predicted must be positive, got {predicted}")
    tolerance = _real(tolerance, "tolerance")
    if not tolerance > 0:
        raise ValueError(f"tolerance must be positive, got {tolerance}")
    if isinstance(min_points, bool) or not isinstance(min_points, numbers.Integral):
        raise TypeError(f"min_points must be an int, got {type(min_points).__name__}")
    if min_points < 2:
        raise ValueError(
            f"min_points must be at least 2 (a slope needs two points), got {min_points}"
        )
    unknown = sorted(set(measure_order_kwargs) - set(_MEASURE_ORDER_OPTIONS))
    if unknown:
        raise TypeError(
            f"assert_order got unexpected keyword argument(s) {', '.join(unknown)}; "
            f"measure_order accepts {', '.join(_MEASURE_ORDER_OPTIONS)}"
        )
    step_counts = measure_order_kwargs.get("step_counts", (8, 16, 32))
    if not isinstance(step_counts, (str, Sequence, np.ndarray)):
        raise TypeError(
            f"step_counts must be a sequence of ints or 'auto', got {type(step_counts).__name__}"
        )
    if not isinstance(step_counts, str) and len(step_counts) < min_points:
        raise ValueError(
            f"{len(step_counts)} step counts cannot give min_points={min_points} points: "
            "give more step counts or lower min_points"
        )
    return predicted, tolerance


def _initial_data(
    problem: Problem | None,
    q0: ArrayLike | None,
    v0: ArrayLike | None,
    t_final: float | None,
    kwargs: dict[str, Any],
) -> tuple[ArrayLike, ArrayLike | None, float]:
    """``q0``, ``v0`` and ``t_final`` of the study.

    With a problem, its own values fill in what is not given (and ``kwargs`` gets its
    parameters and reference); a bare system needs ``q0`` and ``v0`` (or ``p0=``), and
    ``t_final`` defaults to 2.0.
    """
    __tracebackhide__ = True
    if problem is not None:
        q0, v0, t_final = _problem_defaults(problem, q0, v0, t_final, kwargs)
    else:
        if q0 is None:
            raise TypeError(
                "assert_order needs q0 for a bare LagrangianSystem "
                "(or pass a galerkin_vi.problems.Problem, which carries its initial data)"
            )
        if v0 is None and kwargs.get("p0") is None:
            raise TypeError("assert_order needs v0 (or p0=) for a bare LagrangianSystem")
        if t_final is None:
            t_final = 2.0
    return q0, v0, _real(t_final, "t_final")


def _order_failure(
    result: OrderResult,
    method: Galerkin,
    problem: Problem | None,
    t_final: float,
    predicted: float,
    tolerance: float,
    min_points: int,
    kwargs: Mapping[str, Any],
) -> str:
    """The message of a failed :func:`assert_order`: headline, table of runs, fit and hints."""
    used = int(result.mask.sum())
    if used < min_points:
        headline = (
            f"only {used} of {result.errors.size} runs are usable for the fit "
            f"(min_points={min_points})"
        )
    else:
        headline = (
            f"fitted order {result.order:.2f} differs from the predicted {predicted:g} "
            f"by {abs(result.order - predicted):.2f} > tolerance {tolerance:g}"
        )
    reasons = _exclusion_reasons(result, kwargs)
    label = problem.name if problem is not None else "the system"
    lines = [f"assert_order: {headline}", f"{method!r} on {label}, T = {t_final:g}"]
    lines += _order_table(result, reasons)
    lines.append(
        f"fitted order {result.order:.2f} from {used} of {result.errors.size} runs, "
        f"predicted {predicted:g} (tolerance {tolerance:g})"
    )
    hints = _order_hints(result, predicted, tolerance, min_points, reasons, kwargs)
    if predicted != method.order:
        hints.insert(0, f"predicted={predicted:g} was given; method.order is {method.order}")
    if hints:
        lines.append("hints:")
        lines += [f"  - {hint}" for hint in hints]
    return "\n".join(lines)


def _split_problem(obj: object) -> tuple[Problem | None, LagrangianSystem]:
    if isinstance(obj, Problem):
        return obj, obj.system
    if isinstance(obj, LagrangianSystem):
        return None, obj
    raise TypeError(
        "expected a galerkin_vi.LagrangianSystem or a galerkin_vi.problems.Problem, "
        f"got {type(obj).__name__}"
    )


def _problem_defaults(
    problem: Problem,
    q0: ArrayLike | None,
    v0: ArrayLike | None,
    t_final: float | None,
    kwargs: dict[str, Any],
) -> tuple[ArrayLike, ArrayLike | None, float]:
    """Fill in the problem's initial data, parameters and reference (edits ``kwargs``)."""
    own_data = (
        (q0 is None or _same(q0, problem.q0))
        and (v0 is None or _same(v0, problem.v0))
        and kwargs.get("p0") is None
    )
    if q0 is None:
        q0 = problem.q0
    if v0 is None and kwargs.get("p0") is None:
        v0 = problem.v0
    if t_final is None:
        t_final = problem.t_final
    if "params" in kwargs:
        system = problem.system
        own_params = np.array_equal(
            system.parameter_vector(kwargs["params"]), system.parameter_vector(problem.params)
        )
    else:
        kwargs["params"] = problem.params
        own_params = True
    if "reference" not in kwargs:
        # exact solutions are float64 functions of the problem's own initial data
        usable = own_data and own_params and kwargs.get("dps") is None
        kwargs["reference"] = problem.exact if usable else None
    return q0, v0, t_final


def _same(a: ArrayLike, b: ArrayLike) -> bool:
    try:
        return bool(np.array_equal(np.asarray(a, dtype=float), np.asarray(b, dtype=float)))
    except (TypeError, ValueError):
        return False


def _real(value: object, name: str) -> float:
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise TypeError(f"{name} must be a real number, got {value!r}")
    value = float(value)
    if not np.isfinite(value):
        raise ValueError(f"{name} must be finite, got {value}")
    return value


def _exclusion_reasons(result: OrderResult, kwargs: Mapping[str, Any]) -> list[str]:
    r"""Why each run was left out of the fit ("" for runs in the fit).

    The round-off floor repeats :func:`measure_order`'s rule,
    :math:`10^3 N \varepsilon (1 + |q_{\rm ref}|)`, for the message only.
    """
    dps = kwargs.get("dps")
    eps = 10.0 ** (-dps) if dps is not None else _EPS
    floor = 1e3 * result.step_counts * eps * (1.0 + np.max(np.abs(result.reference)))
    if isinstance(kwargs.get("step_counts"), str):
        floor = np.maximum(floor, kwargs.get("window", _DEFAULT_WINDOW)[0])
    reasons = []
    for j, e in enumerate(result.errors):
        if result.mask[j]:
            reasons.append("")
        elif not np.isfinite(e):
            reasons.append("run failed")
        elif e <= floor[j]:
            reasons.append("round-off floor")
        elif j > 0 and not e < result.errors[j - 1]:
            reasons.append("error not decreasing")
        else:
            reasons.append("coarser than the fitted runs")
    return reasons


def _pairwise_orders(result: OrderResult) -> list[float]:
    """Observed order between each run and the previous (coarser) one; NaN for the first."""
    e, h = result.errors, result.step_sizes
    rates = [float("nan")]
    with np.errstate(divide="ignore", invalid="ignore"):
        for j in range(1, e.size):
            rates.append(float(np.log(e[j - 1] / e[j]) / np.log(h[j - 1] / h[j])))
    return rates


def _order_table(result: OrderResult, reasons: Sequence[str]) -> list[str]:
    lines = [f"{'N':>8} {'h':>11} {'error':>11} {'order':>7}"]
    rates = _pairwise_orders(result)
    for j, (n, h, e) in enumerate(
        zip(result.step_counts, result.step_sizes, result.errors, strict=True)
    ):
        rate = f"{rates[j]:7.2f}" if np.isfinite(rates[j]) else ""
        note = f"  (excluded: {reasons[j]})" if reasons[j] else ""
        lines.append(f"{int(n):8d} {h:11.4e} {e:11.3e} {rate:>7}{note}")
    return lines


def _order_hints(
    result: OrderResult,
    predicted: float,
    tolerance: float,
    min_points: int,
    reasons: Sequence[str],
    kwargs: Mapping[str, Any],
) -> list[str]:
    hints = []
    dps = kwargs.get("dps")
    if "round-off floor" in reasons:
        hints.append(
            "the finest runs reached the round-off floor: use fewer steps (smaller "
            "step_counts or a longer t_final)"
            + (
                " or more digits (larger dps)"
                if dps is not None
                else ", or extended precision with dps=40 (explicit step_counts, v0, norm='final')"
            )
        )
    if "error not decreasing" in reasons:
        hints.append(
            "the error stops decreasing: the reference may be less accurate than the "
            "smallest errors (use an exact reference, or reference=None for Richardson "
            "extrapolation), or the runs are at the round-off floor"
        )
    if "run failed" in reasons:
        hints.append("some runs gave non-finite errors: the step size is too large for Newton")
    used = int(result.mask.sum())
    if used < min_points and isinstance(kwargs.get("step_counts"), str):
        hints.append(
            "step_counts='auto' found too few runs inside the error window: widen window= "
            "or give explicit step_counts"
        )
    elif used < min_points:
        hints.append(f"give at least {min_points} step counts in the asymptotic range")
    order = result.order
    if np.isfinite(order) and order < predicted - tolerance:
        rates = [r for r, m in zip(_pairwise_orders(result), result.mask, strict=True) if m]
        rates = [r for r in rates if np.isfinite(r)]
        if len(rates) >= 2 and all(b > a for a, b in zip(rates, rates[1:], strict=False)):
            hints.append(
                "the pairwise orders still rise toward the prediction: the coarse runs are "
                "pre-asymptotic; use more steps"
            )
        if predicted >= 8 and dps is None:
            hints.append(
                "orders of 8 and above are rarely visible in float64 above the round-off "
                "floor: use dps=40 with explicit step_counts"
            )
        if predicted <= result.predicted:
            hints.append(
                "a quadrature of order u < 2s limits the method to order u (method.order "
                "already includes this); an inaccurate reference or a Lagrangian that is "
                "not smooth along the solution also lowers the measured order"
            )
    if np.isfinite(order) and order > predicted + tolerance:
        hints.append(
            "higher than predicted: the error at one time can be superconvergent or pass "
            "near zero at t_final; try norm='max' with a callable reference, or another "
            "t_final"
        )
    if np.isfinite(order) and abs(order - predicted) > tolerance:
        if kwargs.get("reference") is None:
            hints.append(
                "the Richardson reference assumes the predicted order; pass an exact "
                "reference if one is known"
            )
        hints.append("if the method's order really differs, pass predicted=")
    return hints


# ---------------------------------------------------------------------------
# assert_conserved
# ---------------------------------------------------------------------------


def assert_conserved(
    trajectory: Trajectory,
    *,
    energy: float | None = None,
    momenta: Mapping[str, Generator | tuple[Generator, float]] | None = None,
    momentum_tol: float | None = None,
    bounded: bool = False,
    relative: bool = True,
    allow_failed: bool = False,
) -> dict[str, float]:
    r"""Assert that energy and momentum maps stay near their initial values.

    For a quantity :math:`Q` (the energy :math:`H(t_k, q_k, p_k)` or a momentum
    map :math:`J(q_k, p_k) = \langle p_k, \xi_Q(q_k)\rangle`) sampled at the
    saved states :math:`k = 0, \dots, K`, the measured drift is

    .. math::

        d_Q = \frac{\max_k |Q_k - Q_0|}{\max(1, |Q_0|)}

    (the denominator is 1 when ``relative=False``), and the check is
    :math:`d_Q \le` bound. Variational integrators conserve the momentum maps
    of affine symmetries exactly up to round-off (discrete Noether theorem),
    so their bounds can be tight (``1e-11`` over :math:`10^4` steps); the
    energy error is :math:`O(h^p)` and bounded, not zero.

    With ``bounded=True`` the energy must also show no drift: with
    :math:`e_k = |H_k - H_0|` and :math:`m` a tenth of the saved states,

    .. math::

        \max_{K-m < k \le K} e_k \le 2 \max_{1 \le k \le m} e_k
        + 10^{-14} \max(1, |H_0|),

    the criterion of the package's own energy tests. A non-symplectic method's
    energy error grows over the run and fails it; save at least 20 states
    spread over a long run.

    Parameters
    ----------
    trajectory : Trajectory
        A run, e.g. ``Integrator(...).integrate(...)``, or the ``partial``
        trajectory of a :class:`~galerkin_vi.ConvergenceError`.
    energy : float, optional
        Bound on the energy drift :math:`d_H`.
    momenta : mapping of str to generator or (generator, bound), optional
        Momentum maps to check, by name. A generator is one SymPy expression
        per coordinate, e.g. ``(-y, x)`` for rotations in the (x, y)-plane; a
        problem's ``symmetries`` mapping can be passed as it is. Entries
        without a bound use ``momentum_tol``.
    momentum_tol : float, optional
        Bound for the ``momenta`` entries that do not give their own.
    bounded : bool
        Also check that the energy error does not drift (see above).
    relative : bool
        Divide the drifts by :math:`\max(1, |Q_0|)` (default) or not.
    allow_failed : bool
        Check the states of a failed run (``trajectory.success`` False) too.
        By default a failed run fails the assertion with its message: a test
        should not pass on the part of a run that happened to go well.

    Returns
    -------
    dict of str to float
        The measured drifts :math:`d_Q`, by quantity (``"energy"`` when the
        energy was checked, then the ``momenta`` names), on success.

    Raises
    ------
    AssertionError
        If the run failed (unless ``allow_failed``), a drift exceeds its bound
        or the energy drifts. The message has a
        table of quantity, initial value, bound, measured drift and the saved
        time at which the largest deviation occurred.
    TypeError
        If ``trajectory`` is not a :class:`~galerkin_vi.Trajectory` or a bound
        is not a real number.
    ValueError
        If nothing is to be checked, a bound is negative, a momentum has no
        bound, a generator has the wrong length or undeclared symbols, or
        ``bounded=True`` with fewer than 20 saved states.

    Examples
    --------
    >>> import numpy as np
    >>> import galerkin_vi as gvi
    >>> from galerkin_vi import problems
    >>> from galerkin_vi.testing import assert_conserved
    >>> kepler = problems.kepler(0.5)
    >>> x, y = kepler.system.q
    >>> traj = gvi.Integrator(kepler.system, gvi.Galerkin(2), backend="numpy").integrate(
    ...     kepler.q0, kepler.v0, h=2 * np.pi / 100, n_steps=200)
    >>> drifts = assert_conserved(traj, energy=1e-4, momenta={"rotation": ((-y, x), 1e-12)},
    ...                           bounded=True)
    >>> sorted(drifts)
    ['energy', 'rotation']

    The problem's own symmetries, with one bound for all of them:

    >>> drifts = assert_conserved(traj, momenta=kepler.symmetries, momentum_tol=1e-12)

    A bound that is too tight fails with a table:

    >>> assert_conserved(traj, energy=1e-9)
    Traceback (most recent call last):
    ...
    AssertionError: assert_conserved: 1 of 1 checks failed (201 saved states, t = 0 .. 12.57)
    ...
    """
    __tracebackhide__ = True
    energy, checks = _checked_conserved_options(
        trajectory, energy, momenta, momentum_tol, bounded, relative, allow_failed
    )
    t = trajectory.t
    rows = []  # (name, Q0, bound, drift, time, ok)
    drifts: dict[str, float] = {}
    H = trajectory.energy() if (energy is not None or bounded) else None
    if H is not None:
        drift, when = _drift(H, t, relative)
        drifts["energy"] = drift
        if energy is not None:
            rows.append(("energy", H[0], energy, drift, when, drift <= energy))
    for name, (xi, bound) in checks.items():
        J = trajectory.momentum(xi)
        drift, when = _drift(J, t, relative)
        drifts[name] = drift
        rows.append((name, J[0], bound, drift, when, drift <= bound))
    bounded_ok, bounded_line = True, None
    if bounded:
        bounded_ok, bounded_line = _no_drift(H, t)
    failed = sum(not row[-1] for row in rows) + (bounded and not bounded_ok)
    if not failed:
        return drifts
    raise AssertionError(
        _conserved_failure(trajectory, rows, bounded_line, failed, bounded, relative)
    )


def _checked_conserved_options(
    trajectory: object,
    energy: object,
    momenta: Mapping[str, Any] | None,
    momentum_tol: object,
    bounded: object,
    relative: object,
    allow_failed: bool,
) -> tuple[float | None, dict[str, tuple[tuple[sp.Expr, ...], float]]]:
    """Check :func:`assert_conserved`'s arguments; return the energy bound and the momentum checks.

    A failed run fails the assertion here unless ``allow_failed``.
    """
    __tracebackhide__ = True
    if isinstance(trajectory, ConvergenceError):
        raise TypeError(
            "assert_conserved got a ConvergenceError: pass its .partial trajectory to check "
            "the states computed before the failure"
        )
    if not isinstance(trajectory, Trajectory):
        raise TypeError(
            f"trajectory must be a galerkin_vi.Trajectory, got {type(trajectory).__name__}"
        )
    if not isinstance(bounded, bool):
        raise TypeError(f"bounded must be True or False, got {bounded!r}")
    if not trajectory.success and not allow_failed:
        raise AssertionError(
            f"assert_conserved: the run failed ({trajectory.message}); pass "
            "allow_failed=True to check the states computed before the failure"
        )
    if not isinstance(relative, bool):
        raise TypeError(f"relative must be True or False, got {relative!r}")
    if energy is not None:
        energy = _bound(energy, "energy")
    if momentum_tol is not None:
        momentum_tol = _bound(momentum_tol, "momentum_tol")
    checks = _momentum_checks(momenta, momentum_tol)
    if energy is None and not bounded and not checks:
        raise ValueError("nothing to check: give energy=, momenta= or bounded=True")
    if len(trajectory) < 2:
        raise ValueError(f"the trajectory has {len(trajectory)} saved state(s); need at least 2")
    if bounded and len(trajectory) < _MIN_STATES_BOUNDED:
        raise ValueError(
            f"bounded=True compares the first and last tenth of the saved states: need at "
            f"least {_MIN_STATES_BOUNDED}, got {len(trajectory)} (lower save_every)"
        )
    return energy, checks


def _conserved_failure(
    trajectory: Trajectory,
    rows: Sequence[tuple[str, float, float, float, float, bool]],
    bounded_line: str | None,
    failed: int,
    bounded: bool,
    relative: bool,
) -> str:
    """The message of a failed :func:`assert_conserved`: a table of the checks and their drifts."""
    t = trajectory.t
    total = len(rows) + bounded
    scale = "max(1, |Q(t_0)|)" if relative else "1"
    lines = [
        f"assert_conserved: {failed} of {total} checks failed "
        f"({len(trajectory)} saved states, t = {t[0]:.4g} .. {t[-1]:.4g})",
    ]
    if rows:
        lines.append(f"drift = max_k |Q(t_k) - Q(t_0)| / {scale}")
        width = max(len("quantity"), *(len(row[0]) for row in rows))
        lines.append(
            f"{'quantity':<{width}} {'Q(t_0)':>12} {'bound':>9} {'max drift':>10} {'at t':>10}"
        )
        for name, q0, bound, drift, when, ok in rows:
            lines.append(
                f"{name:<{width}} {q0:12.5e} {bound:9.2e} {drift:10.3e} {when:10.4g}"
                f"  {'ok' if ok else 'FAIL'}"
            )
    if bounded_line is not None:
        lines.append(bounded_line)
    return "\n".join(lines)


def _bound(value: object, name: str) -> float:
    value = _real(value, name)
    if value < 0:
        raise ValueError(f"{name} must be a non-negative bound, got {value}")
    return value


def _is_generator_with_bound(value: object) -> bool:
    """``(xi, bound)`` rather than a generator ``xi``: xi's entries are never sequences."""
    return (
        isinstance(value, Sequence)
        and not isinstance(value, str)
        and len(value) == 2
        and isinstance(value[0], (Sequence, np.ndarray, sp.MatrixBase))
        and not isinstance(value[0], str)
        and isinstance(value[1], numbers.Real)
        and not isinstance(value[1], (bool, sp.Basic))
    )


def _momentum_checks(
    momenta: Mapping[str, Any] | None, momentum_tol: float | None
) -> dict[str, tuple[tuple[sp.Expr, ...], float]]:
    if momenta is None:
        return {}
    if not isinstance(momenta, Mapping):
        raise TypeError(
            "momenta must be a mapping of name -> generator or (generator, bound), e.g. "
            f"{{'rotation': ((-y, x), 1e-12)}}, got {type(momenta).__name__}"
        )
    checks = {}
    for name, value in momenta.items():
        if not isinstance(name, str):
            raise TypeError(f"momenta keys must be names (str), got {name!r}")
        if name == "energy":
            raise ValueError("'energy' is reserved for the energy: rename that momentum")
        if _is_generator_with_bound(value):
            xi, bound = value[0], _bound(value[1], f"the bound of momentum {name!r}")
        else:
            xi, bound = value, momentum_tol
        if isinstance(xi, (str, sp.Basic)) and not isinstance(xi, sp.MatrixBase):
            raise TypeError(
                f"the generator of momentum {name!r} must be a sequence of expressions, one "
                f"per coordinate, got {xi!r}"
            )
        if bound is None:
            raise ValueError(
                f"momentum {name!r} has no bound: give {{{name!r}: (xi, bound)}} or momentum_tol="
            )
        checks[name] = (tuple(xi), bound)
    return checks


def _drift(
    values: NDArray[np.float64], t: NDArray[np.float64], relative: bool
) -> tuple[float, float]:
    """Scaled max deviation from the first value and the time where it occurs."""
    deviation = np.abs(values - values[0])
    if relative:
        deviation = deviation / max(1.0, abs(float(values[0])))
    bad = ~np.isfinite(deviation)
    k = int(np.argmax(bad)) if bad.any() else int(np.argmax(deviation))
    return (float("inf") if bad.any() else float(deviation[k])), float(t[k])


def _no_drift(H: NDArray[np.float64], t: NDArray[np.float64]) -> tuple[bool, str]:
    """Apply the no-drift test to the energy; return the verdict and its message line."""
    error = np.abs(H - H[0])
    tenth = error.size // 10
    first_k = 1 + int(np.argmax(error[1 : tenth + 1]))
    last_k = error.size - tenth + int(np.argmax(error[-tenth:]))
    first, last = float(error[first_k]), float(error[last_k])
    allowed = 2.0 * first + _BOUNDED_SLACK * max(1.0, abs(float(H[0])))
    ok = bool(last <= allowed)
    line = (
        f"energy no-drift check: max |H - H(t_0)| over the last tenth {last:.3e} "
        f"(t = {t[last_k]:.4g}) {'<=' if ok else '>'} 2 x first tenth {first:.3e} "
        f"(t = {t[first_k]:.4g}) + round-off allowance  {'ok' if ok else 'FAIL'}"
    )
    return ok, line
