r"""The default step-size function :math:`g(q)`, read off the singular terms of the Lagrangian.

A close encounter is where a term of :math:`L` blows up: an inverse distance
:math:`1/|q_i - q_j|` or :math:`1/|q - c|`, also through powers and square roots
(:math:`r^{-3}`, :math:`(r^2)^{-1/2}`). Each such term is a power with a negative
exponent of a base :math:`B(q)` that can vanish; the distance is
:math:`r = \sqrt{B}` when :math:`B` is a quadratic form in q (a squared distance)
and :math:`r = \sqrt{B^2} = |B|` when :math:`B` is linear. With the distances
:math:`r_1, \dots, r_m` the default is

.. math::

    g(q) = \Big(\sum_{k=1}^m r_k^{-3/2}\Big)^{-1}
    \qquad(\text{:func:`~.transform.encounter_scaling` with } \alpha = 3/2),

about :math:`\min_k r_k^{3/2}`: near the closest encounter the physical step is
proportional to the local orbital time :math:`\sqrt{r^3/(G m)}` (Kepler's third
law), so every encounter gets the same number of steps per revolution whatever
its distance. Sundman's :math:`g = r` (:math:`\alpha = 1`) regularises the
collision of two bodies but gives a close passage
:math:`r^{-1/2}` times more steps per local orbital time than a distant one;
:math:`\alpha = 3/2` is the exponent at which the local error of a step of fixed
fictitious size is the same at every distance of a Kepler orbit (Hairer, Lubich &
Wanner, *Geometric Numerical Integration*, 2nd ed., section VIII.2.2). A system
without such a term has nothing to resolve: :math:`g = 1`, steps equal in physical
time.

A base counts as one that can vanish when it is linear in q, or quadratic with a
positive semidefinite quadratic part whose minimum over q is 0 (to round-off
at the parameters' default values); a softened :math:`1/\sqrt{r^2 + \epsilon^2}`
has a positive minimum and is not singular. Other negative powers of a base in q
(a base that vanishes on a curve, :math:`1/(x^2 + y^2 - 1)`, or of higher degree) are
not distances: :func:`default_step_function` leaves them out and warns, naming them,
so that a g can be given by hand. The test is made at the parameters' default values:
a base that reaches 0 there may not for other values (``params=`` of a run).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np
import sympy as sp

from ..model.system import LagrangianSystem
from .transform import encounter_scaling

__all__ = ["ENCOUNTER_EXPONENT", "StepFunction", "default_step_function", "singular_distances"]

#: alpha of the default g: the local orbital time r^(3/2) (module docstring)
ENCOUNTER_EXPONENT = 1.5
#: a quadratic part whose smallest eigenvalue is above -_VANISHING times the base's size is
#: positive semidefinite (the minimum itself is tested to 1e-9 of that size)
_VANISHING = 1e-12


@dataclass(frozen=True)
class StepFunction:
    """A step-size function and where it came from.

    Attributes
    ----------
    g : sympy.Expr
        :math:`g(q) > 0`.
    distances : tuple of sympy.Expr
        The distances it resolves (empty for a user's g and for g = 1).
    source : str
        ``"user"``, ``"singular terms"`` or ``"none found"``.
    """

    g: sp.Expr
    distances: tuple[sp.Expr, ...] = ()
    source: str = "user"

    def describe(self) -> str:
        """One line: the g and why it was chosen."""
        if self.source == "user":
            return f"g = {self.g} (given)"
        if self.source == "none found":
            return "g = 1 (no singular term in L: steps equal in physical time)"
        names = ", ".join(f"r{k + 1} = {d}" for k, d in enumerate(self.distances))
        if len(self.distances) == 1:
            return f"g = r1**(3/2) from the singular term of L in {names}"
        return (
            f"g = 1/sum(r_k**(-3/2)) over the {len(self.distances)} distances at which "
            f"L is singular: {names}"
        )


def default_step_function(system: LagrangianSystem) -> StepFunction:
    """The default g of ``system``: :func:`encounter_scaling` of its singular distances.

    Parameters
    ----------
    system : LagrangianSystem

    Returns
    -------
    StepFunction
        ``source="singular terms"``, or g = 1 with ``source="none found"``.
    """
    skipped: list[sp.Expr] = []
    distances = singular_distances(system, skipped)
    if skipped:
        listed = ", ".join(str(base) for base in skipped[:4])
        warnings.warn(
            f"the default step-size function leaves out the singular terms with bases {listed}"
            " (not a distance between points: a quadratic form that reaches 0 at one point, "
            "or a linear form); give g= by hand if the run comes close to where they vanish",
            RuntimeWarning,
            stacklevel=3,
        )
    if not distances:
        return StepFunction(sp.Integer(1), (), "none found")
    return StepFunction(
        encounter_scaling(distances, ENCOUNTER_EXPONENT), tuple(distances), "singular terms"
    )


def singular_distances(
    system: LagrangianSystem, skipped: list[sp.Expr] | None = None
) -> list[sp.Expr]:
    r"""The distances :math:`r_k(q)` at which a term of the Lagrangian is singular.

    Every power :math:`B^e` with :math:`e < 0` in :math:`L` whose base depends on
    q only and can vanish (module docstring) gives :math:`r = \sqrt{B}` (quadratic
    :math:`B`) or :math:`\sqrt{B^2}` (linear :math:`B`); bases that differ by a
    constant factor give one distance. In order of first appearance. The bases of
    other negative powers in q are appended to ``skipped`` when it is given.
    """
    q = list(system.q)
    defaults = dict(zip(system.params, system.param_defaults, strict=True))
    velocities = set(system.v)
    found: list[sp.Expr] = []
    seen: set[sp.Expr] = set()
    for node in sp.preorder_traversal(system.L):
        if not (isinstance(node, sp.Pow) and node.exp.is_number and node.exp < 0):
            continue
        base = node.base
        if not (base.free_symbols & set(q)) or base.free_symbols & velocities:
            continue
        # only the coordinates in the base: a pair distance of an N-body system has 4-6
        coordinates = [s for s in q if s in base.free_symbols]
        squared = _squared_distance(base, coordinates, defaults)
        if squared is None:
            unresolved = not _positive(base, coordinates, defaults)
            if skipped is not None and unresolved and base not in skipped:
                skipped.append(base)
            continue
        # one distance per base up to a constant factor: the monic polynomial is the key
        key = sp.Poly(sp.expand(squared), *coordinates).monic().as_expr()
        if key in seen:
            continue
        seen.add(key)
        found.append(sp.sqrt(squared))
    return found


def _squared_distance(base: sp.Expr, q: list[sp.Symbol], defaults: dict) -> sp.Expr | None:
    """``base`` (a quadratic form that reaches 0) or ``base**2`` (linear), else None."""
    expanded = sp.expand(base)
    if not expanded.is_polynomial(*q):
        return None
    poly = sp.Poly(expanded, *q)
    degree = poly.total_degree()
    if degree == 1:
        return base**2
    if degree == 2 and _reaches_zero(poly, defaults):
        return base
    return None


def _reaches_zero(poly: sp.Poly, defaults: dict) -> bool:
    r"""Whether :math:`B = q^T A q + b^T q + c` (at the parameters' defaults) has
    :math:`A \succeq 0` and :math:`\min_q B = c - \tfrac14 b^T A^+ b = 0`."""
    found = _minimum(poly, defaults)
    return found is not None and abs(found[0]) <= 1e-9 * found[1]


def _positive(base: sp.Expr, q: list[sp.Symbol], defaults: dict) -> bool:
    """Whether ``base`` is a quadratic polynomial in ``q`` with a positive minimum (a
    softened distance: nothing to resolve)."""
    expanded = sp.expand(base)
    if not expanded.is_polynomial(*q):
        return False
    poly = sp.Poly(expanded, *q)
    if poly.total_degree() != 2:
        return False
    found = _minimum(poly, defaults)
    return found is not None and found[0] > 1e-9 * found[1]


def _minimum(poly: sp.Poly, defaults: dict) -> tuple[float, float] | None:
    r"""``(min_q B, size)`` of a quadratic :math:`B = q^T A q + b^T q + c` at the
    parameters' defaults (size: the largest coefficient, at least 1), or None when
    :math:`B` is not bounded below or its coefficients are not numbers there."""
    n = len(poly.gens)
    a = np.zeros((n, n))
    b = np.zeros(n)
    c = 0.0
    for powers, coefficient in poly.terms():
        value = sp.sympify(coefficient).xreplace(defaults)
        if not value.is_number:
            return None
        value = float(value)
        where = [k for k, power in enumerate(powers) for _ in range(power)]
        if len(where) == 2:
            i, j = where
            a[i, j] += 0.5 * value
            a[j, i] += 0.5 * value
        elif len(where) == 1:
            b[where[0]] += value
        else:
            c += value
    size = max(1.0, abs(c), float(np.abs(a).max()), float(np.abs(b).max()))
    if np.linalg.eigvalsh(a).min() < -_VANISHING * size:
        return None
    # the minimiser solves 2 A q = -b; b outside the range of A: B is unbounded below
    q_min = np.linalg.lstsq(2.0 * a, -b, rcond=None)[0]
    if np.abs(2.0 * a @ q_min + b).max() > 1e-9 * size:
        return None
    return c + 0.5 * float(b @ q_min), size
