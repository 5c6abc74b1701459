r"""Measuring the order of convergence.

The error of a run with :math:`N` steps over :math:`[t_0, t_0 + T]` is the max-norm
of the final position error. The order is the least-squares slope of
:math:`\log e` against :math:`\log h` over the points that lie in the
asymptotic range: points at the round-off floor (:math:`e \le 10^{3} N
\varepsilon\,(1 + |q|)`) or where the error stops decreasing are masked out.
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..errors import ConvergenceError
from ..integrator import Integrator
from ..method.galerkin import Galerkin
from ..model.system import LagrangianSystem
from ..run.trajectory import Trajectory

__all__ = ["OrderResult", "fit_order", "measure_order"]

_EPS = np.finfo(float).eps


@dataclass(frozen=True)
class OrderResult:
    """Outcome of :func:`measure_order`.

    Attributes
    ----------
    order : float
        Fitted slope of log(error) against log(h) over the masked points.
    predicted : int
        The method's predicted order.
    errors, step_sizes : ndarray
        Final position errors (max-norm) and step sizes, one per step count.
    step_counts : ndarray of int
    mask : ndarray of bool
        Points used in the fit.
    reference : ndarray, shape (n,)
        The reference final position.
    """

    order: float
    predicted: int
    errors: NDArray[np.float64]
    step_sizes: NDArray[np.float64]
    step_counts: NDArray[np.int64]
    mask: NDArray[np.bool_]
    reference: NDArray[np.float64]

    def table(self) -> str:
        """The errors and pairwise orders as a small text table."""
        lines = [f"{'N':>8} {'h':>11} {'error':>11} {'order':>7}"]
        for j, (n, h, e) in enumerate(
            zip(self.step_counts, self.step_sizes, self.errors, strict=True)
        ):
            if j == 0:
                rate = ""
            else:
                rate = f"{np.log(self.errors[j - 1] / e) / np.log(self.step_sizes[j - 1] / h):7.2f}"
            flag = "" if self.mask[j] else "  (excluded)"
            lines.append(f"{n:8d} {h:11.4e} {e:11.3e} {rate:>7}{flag}")
        lines.append(f"fitted order {self.order:.2f}, predicted {self.predicted}")
        return "\n".join(lines)


def fit_order(
    step_sizes: ArrayLike,
    errors: ArrayLike,
    floor: ArrayLike | float = 0.0,
    finest: int | None = None,
) -> tuple[float, NDArray[np.bool_]]:
    """Least-squares slope of log(error) on log(h) over the asymptotic points.

    A point is used when its error is above ``floor`` and below the error of the
    next larger step (errors must decrease as h decreases). With ``finest``,
    only that many of the smallest valid step sizes are used: the asymptotic
    range is at the small-h end.

    Returns
    -------
    order : float
        NaN when fewer than two points remain.
    mask : ndarray of bool
    """
    h = np.asarray(step_sizes, dtype=float)
    e = np.asarray(errors, dtype=float)
    order = np.argsort(-h)
    h, e = h[order], e[order]
    floor = np.broadcast_to(np.asarray(floor, dtype=float), e.shape)[order]
    mask = np.isfinite(e) & (e > floor)
    for j in range(1, e.size):
        if mask[j] and not e[j] < e[j - 1]:
            mask[j] = False
    if finest is not None and mask.sum() > finest:
        mask[np.flatnonzero(mask)[:-finest]] = False
    inverse = np.empty_like(order)
    inverse[order] = np.arange(order.size)
    if mask.sum() < 2:
        return float("nan"), mask[inverse]
    slope = np.polyfit(np.log(h[mask]), np.log(e[mask]), 1)[0]
    return float(slope), mask[inverse]


def measure_order(
    system: LagrangianSystem,
    method: Galerkin,
    q0: ArrayLike,
    v0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    *,
    t_final: float = 2.0,
    step_counts: Sequence[int] | str = (8, 16, 32),
    reference: Callable[[float], ArrayLike] | ArrayLike | None = None,
    window: tuple[float, float] = (1e-10, 1e-4),
    norm: str = "final",
    dps: int | None = None,
    t0: float = 0.0,
    params: Mapping | None = None,
    backend: str = "auto",
    integrator: Integrator | None = None,
) -> OrderResult:
    r"""Measure the order of ``method`` on ``system`` from the final position error.

    Parameters
    ----------
    system, method
        What to test.
    q0, v0, p0
        Initial data (exactly one of ``v0``, ``p0``).
    t_final : float
        Length of the time interval.
    step_counts : sequence of int or "auto"
        Numbers of steps; at least two. ``"auto"`` (needs ``reference``) probes
        :math:`N = 2, \dots` (ratio :math:`10^{0.8/p}`) and keeps the runs whose errors
        lie inside ``window``: above the round-off floor and the reference's
        accuracy, below the pre-asymptotic range; the order is fitted on the
        three finest of them.
    window : (float, float)
        Error window of the ``"auto"`` mode.
    norm : {"final", "max"}
        ``"final"``: max-norm error at :math:`t_0 + T`. ``"max"``: the largest
        error over all step points (needs a callable ``reference`` that accepts
        an array of times and returns shape (len(t), n)); smoother in :math:`h`,
        as single-time errors of oscillatory problems can pass through zero.
    reference : callable, array or None
        Exact final position: a function ``t -> q(t)`` or the array
        :math:`q(t_0 + T)`. ``None`` computes a reference with the same method
        at ``4 * max(step_counts)`` and ``2 * max(step_counts)`` steps, combined
        by Richardson extrapolation with the predicted order:
        :math:`q_{\rm ref} = q_{4N} + (q_{4N} - q_{2N})/(2^p - 1)`.
    integrator : Integrator, optional
        Reuse an integrator (and its compiled kernel) instead of building one.
    dps : int, optional
        Run in mpmath at ``dps`` significant digits instead of float64 (slow;
        explicit ``step_counts``, ``v0`` and ``norm="final"`` only). This is
        how orders 8 to 12 are measured on nonlinear problems, whose float64
        errors above the round-off floor are still pre-asymptotic. A callable
        ``reference`` then receives an ``mpmath.mpf`` time and must return
        values accurate to ``dps`` digits; ``None`` gives the Richardson
        reference in mpmath.

    Returns
    -------
    OrderResult

    Examples
    --------
    >>> import sympy as sp, numpy as np, galerkin_vi as gvi
    >>> x, v = sp.symbols("x v")
    >>> system = gvi.LagrangianSystem(v**2 / 2 - x**2 / 2, [x], [v])
    >>> exact = lambda t: [np.cos(t)]
    >>> result = gvi.measure_order(system, gvi.Galerkin(1), [1.0], [0.0], t_final=2.0,
    ...                            step_counts=[10, 20, 40], reference=exact, backend="numpy")
    >>> round(result.order, 1)
    2.0
    """
    auto = isinstance(step_counts, str)
    counts = _checked_step_counts(step_counts, reference)
    if not (np.isfinite(t_final) and t_final != 0):
        raise ValueError(f"t_final must be finite and nonzero, got {t_final}")
    if dps is not None:
        return _measure_order_mp(
            system,
            method,
            q0,
            v0,
            p0,
            t_final,
            counts,
            reference,
            t0,
            params,
            norm,
            dps,
        )
    if integrator is None:
        integrator = Integrator(system, method, backend=backend)

    if norm not in ("final", "max"):
        raise ValueError(f"norm must be 'final' or 'max', got {norm!r}")
    if norm == "max" and not callable(reference):
        raise ValueError("norm='max' needs a callable reference t -> q(t)")

    def run(n_steps: int) -> Trajectory:
        return integrator.integrate(
            q0,
            v0,
            p0,
            h=t_final / n_steps,
            n_steps=n_steps,
            t0=t0,
            params=params,
            save_every=1 if norm == "max" else n_steps,
            on_failure="raise",
        )

    ref = _reference_position(run, system.n, method.order, counts, reference, t0 + t_final)
    error = _error_function(run, reference, ref, norm)
    if auto:
        counts, errors = _probe_window(error, window, method.order)
    else:
        errors = np.array([error(int(n)) for n in counts])
    step_sizes = t_final / counts
    floor = 1e3 * counts * _EPS * (1.0 + np.max(np.abs(ref)))
    if auto:
        floor = np.maximum(floor, window[0])
    order, mask = fit_order(step_sizes, errors, floor, finest=3 if auto else None)
    if np.isnan(order):
        warnings.warn(
            "fewer than two step counts are in the asymptotic range (errors at the round-off "
            "floor or not decreasing): choose fewer steps or a longer t_final",
            RuntimeWarning,
            stacklevel=2,
        )
    return OrderResult(
        order=order,
        predicted=method.order,
        errors=errors,
        step_sizes=step_sizes,
        step_counts=counts,
        mask=mask,
        reference=ref,
    )


def _checked_step_counts(
    step_counts: Sequence[int] | str, reference: object
) -> NDArray[np.int64] | None:
    """The step counts sorted, or None for ``"auto"`` (which needs a reference)."""
    if isinstance(step_counts, str):
        if step_counts != "auto":
            raise ValueError(
                f"step_counts must be a sequence of ints or 'auto', got {step_counts!r}"
            )
        if reference is None:
            raise ValueError("step_counts='auto' needs a reference solution")
        return None
    counts = np.array(sorted(int(n) for n in step_counts), dtype=np.int64)
    if counts.size < 2 or counts[0] < 1:
        raise ValueError(f"step_counts needs at least two positive counts, got {list(step_counts)}")
    return counts


def _reference_position(
    run: Callable[[int], Trajectory],
    n: int,
    order: int,
    counts: NDArray[np.int64] | None,
    reference: Callable[[float], ArrayLike] | ArrayLike | None,
    t_end: float,
) -> NDArray[np.float64]:
    r"""The reference position at ``t_end``, shape (n,).

    Without ``reference``: Richardson extrapolation of the runs with :math:`2N` and
    :math:`4N` steps (:math:`N` the largest count),
    :math:`q_{\rm ref} = q_{4N} + (q_{4N} - q_{2N})/(2^p - 1)`.
    """
    if reference is None:
        fine, finer = run(2 * counts[-1]).q[-1], run(4 * counts[-1]).q[-1]
        ref = finer + (finer - fine) / (2.0**order - 1.0)
    elif callable(reference):
        ref = np.asarray(reference(t_end), dtype=float)
    else:
        ref = np.asarray(reference, dtype=float)
    if ref.shape != (n,):
        raise ValueError(f"reference must give shape ({n},), got {ref.shape}")
    return ref


def _error_function(
    run: Callable[[int], Trajectory],
    reference: Callable[[float], ArrayLike] | ArrayLike | None,
    ref: NDArray[np.float64],
    norm: str,
) -> Callable[[int], float]:
    """The error of a run as a function of its step count, in the max-norm.

    ``norm="final"``: at the final time, against ``ref``; ``norm="max"``: the largest
    over all step points, against the callable ``reference``.
    """

    def error(n_steps: int) -> float:
        if norm == "max":
            traj = run(n_steps)
            exact = np.asarray(reference(traj.t), dtype=float).reshape(traj.q.shape)
            return float(np.max(np.abs(traj.q - exact)))
        return float(np.max(np.abs(run(n_steps).q[-1] - ref)))

    return error


def _probe_window(
    error: Callable[[int], float],
    window: tuple[float, float],
    order: int,
    max_points: int = 6,
    max_steps: int = 20000,
) -> tuple[NDArray[np.int64], NDArray[np.float64]]:
    """Step counts whose errors fall inside ``window`` (plus the first one below it).

    Counts grow from 2 by the ratio :math:`10^{0.8/p}` (about 0.8 decades of
    error per probe at order :math:`p`), so that several points land in a
    six-decade window at any order.
    """
    low, high = window
    ratio = max(1.1, 10.0 ** (0.8 / order))
    counts: list[int] = []
    errors: list[float] = []
    n = 2
    while n <= max_steps and len(counts) < max_points:
        try:
            e = error(n)
        except ConvergenceError:
            e = np.inf
        if e < high:
            counts.append(n)
            errors.append(e)
        if e < low:
            break
        n = max(n + 1, int(np.ceil(ratio * n)))
    if len(counts) < 2:
        raise RuntimeError(
            f"could not find two step counts with errors inside {window} (tried up to {n} steps)"
        )
    return np.array(counts, dtype=np.int64), np.array(errors)


def _measure_order_mp(
    system: LagrangianSystem,
    method: Galerkin,
    q0: ArrayLike,
    v0: ArrayLike | None,
    p0: ArrayLike | None,
    t_final: float,
    counts: NDArray[np.int64] | None,
    reference: Callable | ArrayLike | None,
    t0: float,
    params: Mapping | None,
    norm: str,
    dps: int,
) -> OrderResult:
    """:func:`measure_order` in mpmath arithmetic (see its ``dps`` parameter)."""
    import mpmath

    from ..method.composition import Composition
    from ..reference.mpmath import MpComposition, MpIntegrator

    if counts is None:
        raise ValueError("dps mode needs explicit step_counts")
    if v0 is None or p0 is not None:
        raise ValueError("dps mode starts from v0 (give v0, not p0)")
    if norm != "final":
        raise ValueError("dps mode measures the final error only (norm='final')")
    extended = MpComposition if isinstance(method, Composition) else MpIntegrator
    mp_integrator = extended(system, method, dps=dps)
    prm = system.parameter_vector(params)
    q0 = np.asarray(q0, dtype=float)
    v0 = np.asarray(v0, dtype=float)

    def final_position(n_steps: int) -> list:
        return mp_integrator.final_state(q0, v0, t0, t_final, int(n_steps), prm)[0]

    with mpmath.workdps(dps):
        if reference is None:
            fine, finer = final_position(2 * counts[-1]), final_position(4 * counts[-1])
            factor = mpmath.mpf(2) ** method.order - 1
            ref = [b + (b - a) / factor for a, b in zip(fine, finer, strict=True)]
        elif callable(reference):
            ref = list(reference(mpmath.mpf(t0) + mpmath.mpf(t_final)))
        else:
            ref = [mpmath.mpf(x) for x in np.asarray(reference, dtype=float)]
        if len(ref) != system.n:
            raise ValueError(f"reference must give {system.n} values, got {len(ref)}")
        errors = np.array(
            [
                float(max(abs(x - r) for x, r in zip(final_position(n), ref, strict=True)))
                for n in counts
            ]
        )
        size = float(max(abs(r) for r in ref))
    step_sizes = t_final / counts
    floor = 1e3 * counts * 10.0 ** (-dps) * (1.0 + size)
    order, mask = fit_order(step_sizes, errors, floor)
    return OrderResult(
        order=order,
        predicted=method.order,
        errors=errors,
        step_sizes=step_sizes,
        step_counts=counts,
        mask=mask,
        reference=np.array([float(r) for r in ref]),
    )
