r"""Gauss–Legendre and Gauss–Lobatto quadrature rules on :math:`[0, 1]`.

A rule with nodes :math:`c_i` and weights :math:`b_i`, :math:`i = 1, \dots, m`, approximates

.. math::

    \int_0^1 f(\tau)\,\mathrm{d}\tau \approx \sum_{i=1}^{m} b_i f(c_i).

Nodes and weights are computed with Newton's method on the three-term Legendre recurrence in
extended precision (mpmath, 40 significant digits plus guard digits), mapped from
:math:`[-1, 1]` to :math:`[0, 1]` by :math:`c = (1 + x)/2`, :math:`b = w/2`, and rounded to
float64 once.  Only the upper half :math:`c_i \ge 1/2` is rounded; the lower half is its exact
reflection, so :math:`c_{m+1-i} = 1 - c_i` and :math:`b_{m+1-i} = b_i` hold exactly in floating
point (for :math:`c \in [1/2, 1]`, :math:`1 - c` is exact by Sterbenz's lemma).

The extended-precision values are public too (:func:`gauss_legendre_mp`,
:func:`gauss_lobatto_mp`): method tables built from them in mpmath and rounded once are more
accurate than tables built from the float64 rules.

References
----------
.. [1] W. H. Press, S. A. Teukolsky, W. T. Vetterling, B. P. Flannery, *Numerical Recipes*,
   3rd ed., Cambridge University Press, 2007, §4.6 (Newton on the Legendre recurrence).
.. [2] M. Abramowitz, I. A. Stegun, *Handbook of Mathematical Functions*, 1964, 25.4.29–25.4.32
   (Gauss and Lobatto weights and error terms).
"""

from __future__ import annotations

import functools
import math
import numbers
from collections.abc import Callable
from dataclasses import dataclass
from typing import TypeVar

import mpmath
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "QuadratureRule",
    "gauss_legendre",
    "gauss_legendre_mp",
    "gauss_lobatto",
    "gauss_lobatto_mp",
]

#: Significant digits of the mpmath computation behind the float64 rules.
FLOAT_RULE_DPS = 40

# Extra working digits for the Newton iteration and the weight formulas; results are rounded
# back to the requested ``dps`` before they are returned.
_GUARD_DIGITS = 10

# family -> (smallest number of points, exactness degree as a function of the number of points)
_FAMILIES: dict[str, tuple[int, Callable[[int], int]]] = {
    "gauss_legendre": (1, lambda m: 2 * m - 1),
    "gauss_lobatto": (2, lambda m: 2 * m - 3),
}

# Newton iterations allowed per root.  From the starting guesses used below convergence is
# quadratic after at most a few steps; the cap only turns a hypothetical failure into an error.
_MAX_NEWTON_ITERATIONS = 100

# float during the cheap first Newton phase, mpmath.mpf afterwards
_Real = TypeVar("_Real", float, mpmath.mpf)


def require_int(value: object, name: str, minimum: int) -> int:
    """Validate an integer argument and return it as a built-in ``int``.

    Parameters
    ----------
    value : object
        The argument.  Python and NumPy integers are accepted; ``bool`` is not.
    name : str
        Argument name used in the error messages.
    minimum : int
        Smallest allowed value.

    Returns
    -------
    int
        ``value`` converted to ``int``.

    Raises
    ------
    TypeError
        If ``value`` is not an integer, or is a ``bool``.
    ValueError
        If ``value < minimum``.
    """
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise TypeError(f"{name} must be an int, got {type(value).__name__}")
    value = int(value)
    if value < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return value


@dataclass(frozen=True, eq=False, repr=False, slots=True)
class QuadratureRule:
    r"""A quadrature rule on :math:`[0, 1]`.

    .. math::

        \int_0^1 f(\tau)\,\mathrm{d}\tau \approx \sum_{i=1}^{m} b_i f(c_i),

    exact for polynomials of degree at most ``degree``.  Build rules with
    :func:`gauss_legendre` and :func:`gauss_lobatto`; they are memoised, so there is one object
    per rule.

    Parameters
    ----------
    family : {"gauss_legendre", "gauss_lobatto"}
        The family of the rule.
    nodes : array_like, shape (m,)
        Nodes :math:`c_i`, strictly increasing, in :math:`[0, 1]`.  Stored as a read-only
        float64 copy.
    weights : array_like, shape (m,)
        Positive weights :math:`b_i`, summing to 1.  Stored as a read-only float64 copy.
    degree : int
        Exactness degree: :math:`2m - 1` for Gauss–Legendre, :math:`2m - 3` for Gauss–Lobatto.

    Attributes
    ----------
    order : int
        ``degree + 1``: the quadrature order :math:`u` of theory.md §1.
    npoints : int
        Number of points :math:`m`.

    Raises
    ------
    ValueError
        If the family is unknown, the arrays are not one-dimensional of equal length, a node
        lies outside :math:`[0, 1]` or the nodes are not increasing, a weight is not positive,
        the weights do not sum to 1 (to 1e-12), or ``degree`` does not match the family.
    TypeError
        If ``degree`` is not an int.

    Notes
    -----
    Equality and hashing are by ``(family, npoints)``: a family and a size determine the rule.
    The constructor does not check that the nodes are the family's own, so build rules with
    the two factory functions.
    """

    family: str
    nodes: NDArray[np.float64]
    weights: NDArray[np.float64]
    degree: int

    def __post_init__(self) -> None:
        """Validate the fields and store read-only float64 copies of the arrays."""
        if self.family not in _FAMILIES:
            raise ValueError(f"family must be one of {sorted(_FAMILIES)}, got {self.family!r}")
        nodes = np.array(self.nodes, dtype=np.float64)
        weights = np.array(self.weights, dtype=np.float64)
        if nodes.ndim != 1 or weights.shape != nodes.shape:
            raise ValueError(
                "nodes and weights must be one-dimensional arrays of the same length, got "
                f"shapes {nodes.shape} and {weights.shape}"
            )
        minimum, degree_of = _FAMILIES[self.family]
        m = nodes.size
        if m < minimum:
            raise ValueError(f"a {self.family} rule needs at least {minimum} points, got {m}")
        if not (np.all(np.isfinite(nodes)) and np.all(np.isfinite(weights))):
            raise ValueError("nodes and weights must be finite")
        if nodes[0] < 0.0 or nodes[-1] > 1.0 or np.any(np.diff(nodes) <= 0.0):
            raise ValueError("nodes must be strictly increasing and lie in [0, 1]")
        if np.any(weights <= 0.0) or abs(math.fsum(weights.tolist()) - 1.0) > 1e-12:
            raise ValueError("weights must be positive and sum to 1")
        degree = require_int(self.degree, "degree", -1)
        if degree != degree_of(m):
            raise ValueError(
                f"a {m}-point {self.family} rule has degree {degree_of(m)}, got {degree}"
            )
        nodes.setflags(write=False)
        weights.setflags(write=False)
        object.__setattr__(self, "nodes", nodes)
        object.__setattr__(self, "weights", weights)
        object.__setattr__(self, "degree", degree)

    @property
    def order(self) -> int:
        """Quadrature order :math:`u` = ``degree + 1`` (exact for degree :math:`< u`)."""
        return self.degree + 1

    @property
    def npoints(self) -> int:
        """Number of quadrature points :math:`m`."""
        return int(self.nodes.size)

    def __eq__(self, other: object) -> bool:
        """Compare by ``(family, npoints)``."""
        if not isinstance(other, QuadratureRule):
            return NotImplemented
        return (self.family, self.npoints) == (other.family, other.npoints)

    def __hash__(self) -> int:
        """Hash of ``(family, npoints)``."""
        return hash((self.family, self.npoints))

    def __repr__(self) -> str:
        """Return the constructor call, e.g. ``gauss_lobatto(4)``."""
        return f"{self.family}({self.npoints})"


def _legendre_with_derivative(n: int, x: _Real) -> tuple[_Real, _Real, _Real]:
    r"""Evaluate :math:`P_n(x)`, :math:`P_{n-1}(x)` and :math:`P_n'(x)` for :math:`n \ge 1`.

    Uses the three-term recurrence :math:`kP_k = (2k-1)xP_{k-1} - (k-1)P_{k-2}` and
    :math:`P_k' = P_{k-2}' + (2k-1)P_{k-1}`, which stays accurate near :math:`x = \pm 1`
    (unlike :math:`P_n' = n(xP_n - P_{n-1})/(x^2 - 1)`).  Works for ``float`` and ``mpf``.
    """
    p_prev, p = 1, x
    dp_prev, dp = 0, 1
    for k in range(2, n + 1):
        p_prev, p = p, ((2 * k - 1) * x * p - (k - 1) * p_prev) / k
        dp_prev, dp = dp, dp_prev + (2 * k - 1) * p_prev
    return p, p_prev, dp


def _newton(step: Callable[[_Real], _Real], guess: float, tol: mpmath.mpf) -> mpmath.mpf:
    """Newton's method ``x -= step(x)``: in float64 first (cheap), then in mpmath.

    The float64 phase stops at a step of 1e-12; the mpmath phase (at the current precision)
    stops after applying a step of at most ``tol``, which takes three steps from there.
    """
    x = guess
    for _ in range(_MAX_NEWTON_ITERATIONS):
        dx = step(x)
        x -= dx
        if abs(dx) <= 1e-12:
            break
    x = mpmath.mpf(x)
    for _ in range(_MAX_NEWTON_ITERATIONS):
        dx = step(x)
        x -= dx
        if abs(dx) <= tol:
            return x
    raise RuntimeError("Newton iteration for a quadrature node did not converge")


def _assemble(
    upper: list[tuple[mpmath.mpf, mpmath.mpf]],
    middle: tuple[mpmath.mpf, mpmath.mpf] | None,
    dps: int,
) -> tuple[tuple[mpmath.mpf, ...], tuple[mpmath.mpf, ...]]:
    """Round the upper half ``(c, b)`` to ``dps`` digits and reflect it to a symmetric rule.

    ``upper`` holds the pairs with :math:`c > 1/2` in increasing order of :math:`c`; ``middle``
    the pair at :math:`c = 1/2` for an odd number of points.
    """
    with mpmath.workdps(dps):
        c_up = [mpmath.mpf(c) for c, _ in upper]
        b_up = [mpmath.mpf(b) for _, b in upper]
        # 1 - c is exact for c in [1/2, 1], so the reflection is exact at this precision.
        nodes = [1 - c for c in reversed(c_up)]
        weights = list(reversed(b_up))
        if middle is not None:
            nodes.append(mpmath.mpf(middle[0]))
            weights.append(mpmath.mpf(middle[1]))
        nodes.extend(c_up)
        weights.extend(b_up)
    return tuple(nodes), tuple(weights)


@functools.cache
def _gauss_legendre_mp_cached(
    m: int, dps: int
) -> tuple[tuple[mpmath.mpf, ...], tuple[mpmath.mpf, ...]]:
    with mpmath.workdps(dps + _GUARD_DIGITS):
        tol = mpmath.mpf(10) ** (-(dps + _GUARD_DIGITS // 2))

        def step(x: _Real) -> _Real:
            p, _, dp = _legendre_with_derivative(m, x)
            return p / dp

        def pair(x: mpmath.mpf) -> tuple[mpmath.mpf, mpmath.mpf]:
            # b = w/2 with w = 2 / ((1 - x^2) P_m'(x)^2) on [-1, 1]; c = (1 + x)/2.
            _, _, dp = _legendre_with_derivative(m, x)
            return (1 + x) / 2, 1 / ((1 - x) * (1 + x) * dp**2)

        upper = []
        # Roots x_k > 0 in increasing order, from the starting guesses cos(pi(4k-1)/(4m+2)).
        for k in range(m // 2, 0, -1):
            x = _newton(step, math.cos(math.pi * (4 * k - 1) / (4 * m + 2)), tol)
            if not 0 < x < 1:
                raise RuntimeError(f"Gauss-Legendre node {k} of {m} outside (0, 1)")
            upper.append(pair(x))
        middle = pair(mpmath.mpf(0)) if m % 2 else None
    _check_distinct(upper, m)
    return _assemble(upper, middle, dps)


@functools.cache
def _gauss_lobatto_mp_cached(
    m: int, dps: int
) -> tuple[tuple[mpmath.mpf, ...], tuple[mpmath.mpf, ...]]:
    n = m - 1  # interior nodes are the roots of P_n' (equivalently of x P_n - P_{n-1})
    with mpmath.workdps(dps + _GUARD_DIGITS):
        tol = mpmath.mpf(10) ** (-(dps + _GUARD_DIGITS // 2))

        def step(x: _Real) -> _Real:
            # d/dx (x P_n - P_{n-1}) = (n + 1) P_n
            p, p_prev, _ = _legendre_with_derivative(n, x)
            return (x * p - p_prev) / ((n + 1) * p)

        def pair(x: mpmath.mpf) -> tuple[mpmath.mpf, mpmath.mpf]:
            # b = w/2 with w = 2 / (n (n + 1) P_n(x)^2); P_n is stationary at the node.
            p, _, _ = _legendre_with_derivative(n, x)
            return (1 + x) / 2, 1 / (n * (n + 1) * p**2)

        upper = []
        # Interior roots x_j > 0 in increasing order, from the guesses cos(pi j / n).
        for j in range((n - 1) // 2, 0, -1):
            x = _newton(step, math.cos(math.pi * j / n), tol)
            if not 0 < x < 1:
                raise RuntimeError(f"Gauss-Lobatto node {j} of {m} outside (0, 1)")
            upper.append(pair(x))
        upper.append((mpmath.mpf(1), mpmath.mpf(1) / (n * (n + 1))))
        middle = pair(mpmath.mpf(0)) if m % 2 else None
    _check_distinct(upper, m)
    return _assemble(upper, middle, dps)


def _check_distinct(upper: list[tuple[mpmath.mpf, mpmath.mpf]], m: int) -> None:
    """Raise if Newton converged to the same root twice (strictly increasing upper half)."""
    if any(a[0] >= b[0] for a, b in zip(upper, upper[1:], strict=False)):
        raise RuntimeError(f"Newton iteration produced repeated nodes for m = {m}")


def gauss_legendre_mp(m: int, dps: int = 40) -> tuple[list[mpmath.mpf], list[mpmath.mpf]]:
    r"""Nodes and weights of the :math:`m`-point Gauss–Legendre rule on :math:`[0, 1]` in mpmath.

    The nodes are :math:`c_i = (1 + x_i)/2` with :math:`x_i` the roots of the Legendre
    polynomial :math:`P_m`, and the weights are

    .. math::

        b_i = \frac{1}{(1 - x_i^2)\,P_m'(x_i)^2}.

    Parameters
    ----------
    m : int
        Number of points, :math:`m \ge 1`.
    dps : int, optional
        Significant decimal digits of the result (default 40), :math:`\ge 1`.

    Returns
    -------
    nodes : list of mpmath.mpf, length m
        Increasing nodes with :math:`c_{m+1-i} = 1 - c_i` exactly.
    weights : list of mpmath.mpf, length m
        Weights with :math:`b_{m+1-i} = b_i` exactly.

    Raises
    ------
    TypeError
        If ``m`` or ``dps`` is not an int (``bool`` is rejected).
    ValueError
        If ``m < 1`` or ``dps < 1``.

    Notes
    -----
    Memoised by ``(m, dps)``; each call returns new lists of the same (immutable) numbers.
    The values carry ``dps`` digits; do arithmetic with them under ``mpmath.workdps(dps)``.

    Examples
    --------
    >>> nodes, weights = gauss_legendre_mp(2, dps=20)
    >>> mpmath.nstr(nodes[0], 20)  # (3 - sqrt(3)) / 6
    '0.21132486540518711775'
    """
    m = require_int(m, "m", 1)
    dps = require_int(dps, "dps", 1)
    nodes, weights = _gauss_legendre_mp_cached(m, dps)
    return list(nodes), list(weights)


def gauss_lobatto_mp(m: int, dps: int = 40) -> tuple[list[mpmath.mpf], list[mpmath.mpf]]:
    r"""Nodes and weights of the :math:`m`-point Gauss–Lobatto rule on :math:`[0, 1]` in mpmath.

    With :math:`N = m - 1`, the nodes are :math:`c_i = (1 + x_i)/2` where :math:`x_1 = -1`,
    :math:`x_m = 1` and the interior :math:`x_i` are the roots of :math:`P_N'`
    (equivalently of :math:`xP_N - P_{N-1}`).  The weights are

    .. math::

        b_i = \frac{1}{N(N+1)\,P_N(x_i)^2},

    which gives :math:`b_1 = b_m = 1/(N(N+1))` at the end points.

    Parameters
    ----------
    m : int
        Number of points, :math:`m \ge 2`.
    dps : int, optional
        Significant decimal digits of the result (default 40), :math:`\ge 1`.

    Returns
    -------
    nodes : list of mpmath.mpf, length m
        Increasing nodes, ``nodes[0] == 0`` and ``nodes[-1] == 1`` exactly, and
        :math:`c_{m+1-i} = 1 - c_i` exactly.
    weights : list of mpmath.mpf, length m
        Weights with :math:`b_{m+1-i} = b_i` exactly.

    Raises
    ------
    TypeError
        If ``m`` or ``dps`` is not an int (``bool`` is rejected).
    ValueError
        If ``m < 2`` or ``dps < 1``.

    Notes
    -----
    Memoised by ``(m, dps)``; each call returns new lists of the same (immutable) numbers.

    Examples
    --------
    >>> nodes, weights = gauss_lobatto_mp(3, dps=20)
    >>> nodes == [0, 0.5, 1]
    True
    >>> mpmath.nstr(weights[0], 20)
    '0.16666666666666666667'
    """
    m = require_int(m, "m", 2)
    dps = require_int(dps, "dps", 1)
    nodes, weights = _gauss_lobatto_mp_cached(m, dps)
    return list(nodes), list(weights)


def _round_symmetric(
    nodes: tuple[mpmath.mpf, ...], weights: tuple[mpmath.mpf, ...]
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Round a symmetric mpmath rule to float64, reflecting the rounded upper half."""
    c = np.array([float(v) for v in nodes])
    b = np.array([float(v) for v in weights])
    half = c.size // 2
    c[:half] = 1.0 - c[::-1][:half]
    b[:half] = b[::-1][:half]
    return c, b


@functools.cache
def _gauss_legendre_cached(m: int) -> QuadratureRule:
    nodes, weights = _round_symmetric(*_gauss_legendre_mp_cached(m, FLOAT_RULE_DPS))
    return QuadratureRule("gauss_legendre", nodes, weights, 2 * m - 1)


@functools.cache
def _gauss_lobatto_cached(m: int) -> QuadratureRule:
    nodes, weights = _round_symmetric(*_gauss_lobatto_mp_cached(m, FLOAT_RULE_DPS))
    return QuadratureRule("gauss_lobatto", nodes, weights, 2 * m - 3)


def gauss_legendre(m: int) -> QuadratureRule:
    r"""Return the :math:`m`-point Gauss–Legendre rule on :math:`[0, 1]` (exact to degree 2m-1).

    Nodes and weights are those of :func:`gauss_legendre_mp` at 40 digits, rounded to float64
    once (upper half rounded, lower half reflected exactly).

    Parameters
    ----------
    m : int
        Number of points, :math:`m \ge 1`.

    Returns
    -------
    QuadratureRule
        ``family == "gauss_legendre"``, ``degree == 2*m - 1``.  Memoised: equal ``m`` returns
        the same object.

    Raises
    ------
    TypeError
        If ``m`` is not an int (``bool`` is rejected).
    ValueError
        If ``m < 1``.

    Examples
    --------
    >>> rule = gauss_legendre(1)
    >>> rule, rule.nodes, rule.weights, rule.order
    (gauss_legendre(1), array([0.5]), array([1.]), 2)
    """
    return _gauss_legendre_cached(require_int(m, "m", 1))


def gauss_lobatto(m: int) -> QuadratureRule:
    r"""Return the :math:`m`-point Gauss–Lobatto rule on :math:`[0, 1]` (exact to degree 2m-3).

    The end points are exactly 0.0 and 1.0.  Interior nodes and all weights are those of
    :func:`gauss_lobatto_mp` at 40 digits, rounded to float64 once (upper half rounded, lower
    half reflected exactly).

    Parameters
    ----------
    m : int
        Number of points, :math:`m \ge 2`.

    Returns
    -------
    QuadratureRule
        ``family == "gauss_lobatto"``, ``degree == 2*m - 3``.  Memoised: equal ``m`` returns
        the same object.

    Raises
    ------
    TypeError
        If ``m`` is not an int (``bool`` is rejected).
    ValueError
        If ``m < 2``.

    Examples
    --------
    >>> rule = gauss_lobatto(3)
    >>> rule, rule.nodes, rule.order
    (gauss_lobatto(3), array([0. , 0.5, 1. ]), 4)
    """
    return _gauss_lobatto_cached(require_int(m, "m", 2))
