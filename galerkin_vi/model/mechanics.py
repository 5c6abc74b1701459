r"""Models written with :mod:`sympy.physics.mechanics`, turned into plain symbols.

A ``sympy.physics.mechanics`` model states its Lagrangian in *dynamicsymbols*,
undefined functions of time :math:`q_i(t)`, with the velocities written as
:math:`\dot q_i = \mathrm{Derivative}(q_i(t), t)`. :class:`~galerkin_vi.LagrangianSystem`
works with plain symbols :math:`L(t, q, v)`. This module (the "system" stage of
the data flow; it imports SymPy only) rewrites one into the other, exactly:

.. math::

    q_i(t) \mapsto q_i, \qquad \frac{d q_i}{dt}(t) \mapsto v_i,

and :math:`t` stays as the time symbol where it occurs explicitly. The map is a
structural replacement (``xreplace``), so the expressions are the same trees
with symbols in place of functions: nothing is simplified or expanded.

It also reads a :class:`sympy.physics.mechanics.LagrangesMethod`: its
Lagrangian, coordinates, holonomic constraints and applied loads, the latter
turned into generalised forces by partial velocities
(:func:`generalised_forces`).
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import sympy as sp
from sympy.core.function import AppliedUndef

__all__ = [
    "MechanicsModel",
    "MechanicsSymbols",
    "PlainModel",
    "generalised_forces",
    "lagranges_method_model",
    "to_plain_symbols",
    "uses_dynamicsymbols",
]


@dataclass(frozen=True)
class MechanicsSymbols:
    r"""How the dynamicsymbols of a mechanics model map to plain symbols.

    The value of ``LagrangianSystem.mechanics_symbols`` for a model given in
    dynamicsymbols; use it to write further expressions (a symmetry generator
    for :meth:`~galerkin_vi.LagrangianSystem.momentum_map`, say) in the
    system's symbols, and to read results back.

    Attributes
    ----------
    time : sympy.Symbol
        The argument of the coordinate functions, usually
        ``sympy.physics.mechanics.dynamicsymbols._t``.
    coordinates : tuple of sympy.Expr
        The coordinate functions :math:`q_i(t)`, in the order of ``q``.
    q : tuple of sympy.Symbol
        The plain symbol standing for each :math:`q_i(t)`, named like the
        function (``q1``), with underscores appended where that name is taken.
    v : tuple of sympy.Symbol
        The plain symbol standing for each :math:`\dot q_i(t)`, named
        ``<q>_dot`` (``q1_dot``), with underscores appended where taken.
    t : sympy.Symbol or None
        ``time`` when the converted model depends on time explicitly (the
        system is then time dependent), else ``None`` (autonomous).
    """

    time: sp.Symbol
    coordinates: tuple[sp.Expr, ...]
    q: tuple[sp.Symbol, ...]
    v: tuple[sp.Symbol, ...]
    t: sp.Symbol | None

    @property
    def substitutions(self) -> dict[sp.Expr, sp.Symbol]:
        r"""The replacements :math:`\dot q_i(t) \mapsto v_i`, :math:`q_i(t) \mapsto q_i`."""
        rule: dict[sp.Expr, sp.Symbol] = {
            c.diff(self.time): vi for c, vi in zip(self.coordinates, self.v, strict=True)
        }
        rule.update(zip(self.coordinates, self.q, strict=True))
        return rule

    def to_plain(self, expr: Any, name: str = "expression") -> sp.Expr:
        """Rewrite an expression in dynamicsymbols into the system's plain symbols.

        Raises
        ------
        ValueError
            If ``expr`` holds a second or higher time derivative of a
            coordinate, or a function of time that is not a coordinate.
        """
        return _convert(sp.sympify(expr), name, self)

    def to_mechanics(self, expr: Any) -> sp.Expr:
        r"""Rewrite an expression in the plain symbols back into dynamicsymbols.

        :math:`q_i \mapsto q_i(t)`, :math:`v_i \mapsto \dot q_i(t)`; the inverse of
        :meth:`to_plain`.
        """
        back = {s: e for e, s in self.substitutions.items()}
        return sp.sympify(expr).xreplace(back)


@dataclass(frozen=True)
class PlainModel:
    """A model rewritten in plain symbols: what ``LagrangianSystem`` is built from.

    Attributes
    ----------
    L : sympy.Expr
        The Lagrangian :math:`L(t, q, v)`.
    q, v : tuple of sympy.Symbol
        Coordinates and velocities.
    t : sympy.Symbol or None
        The time symbol, ``None`` for an autonomous model.
    constraints, forces : list or None
        The converted constraints and forces, ``None`` where none were given.
        Entries that are not SymPy expressions are passed through unchanged
        (``LagrangianSystem`` reports them).
    symbols : MechanicsSymbols
        The map between the two sets of symbols.
    """

    L: sp.Expr
    q: tuple[sp.Symbol, ...]
    v: tuple[sp.Symbol, ...]
    t: sp.Symbol | None
    constraints: list[Any] | None
    forces: list[Any] | None
    symbols: MechanicsSymbols


@dataclass(frozen=True)
class MechanicsModel:
    """What a ``LagrangesMethod`` holds, still in dynamicsymbols.

    Attributes
    ----------
    L : sympy.Expr
        The Lagrangian.
    q : tuple of sympy.Expr
        The coordinate functions :math:`q_i(t)`.
    constraints : list of sympy.Expr or None
        The holonomic constraints :math:`g_j(t, q) = 0` (``hol_coneqs``).
    forces : list of sympy.Expr or None
        The generalised forces :math:`Q_i` of the applied loads, one per coordinate.
    """

    L: sp.Expr
    q: tuple[sp.Expr, ...]
    constraints: list[sp.Expr] | None
    forces: list[sp.Expr] | None


def uses_dynamicsymbols(q: object) -> bool:
    """Whether ``q`` lists functions (dynamicsymbols) rather than plain symbols.

    True as soon as one entry is an applied undefined function such as
    ``q1(t)``; :func:`to_plain_symbols` then checks that all entries are.
    """
    if isinstance(q, AppliedUndef):
        return True
    if isinstance(q, (str, bytes)) or not isinstance(q, Iterable | sp.MatrixBase):
        return False
    return any(isinstance(e, AppliedUndef) for e in q)


def to_plain_symbols(
    L: Any,
    q: Sequence[sp.Expr],
    *,
    constraints: Any = None,
    forces: Any = None,
    params: Iterable[sp.Symbol] = (),
    t: sp.Symbol | None = None,
) -> PlainModel:
    r"""Rewrite a Lagrangian in dynamicsymbols (and its constraints and forces) exactly.

    Every :math:`\dot q_i(t) = \mathrm{Derivative}(q_i(t), t)` becomes a velocity
    symbol :math:`v_i` and every :math:`q_i(t)` a coordinate symbol :math:`q_i`:

    .. math::

        L(t, q(t), \dot q(t)) \;\mapsto\; L(t, q, v).

    The time symbol stays where ``t`` occurs explicitly; the model is then time
    dependent, otherwise autonomous.

    Parameters
    ----------
    L : sympy.Expr
        The Lagrangian in dynamicsymbols (e.g. from
        ``sympy.physics.mechanics.Lagrangian``).
    q : sequence of sympy.Expr
        The coordinates, functions of one time symbol (``dynamicsymbols``).
    constraints, forces : sequence of sympy.Expr, optional
        Holonomic constraints :math:`g_j(t, q(t)) = 0` and generalised forces
        :math:`f_i(t, q(t), \dot q(t))`, rewritten the same way.
    params : iterable of sympy.Symbol, optional
        Parameter symbols: new symbols never take their names.
    t : sympy.Symbol, optional
        Declares the model time dependent; must be the time argument of ``q``.

    Returns
    -------
    PlainModel
        The rewritten model and the symbol map (:class:`MechanicsSymbols`).

    Raises
    ------
    TypeError
        If ``L`` is not a SymPy expression.
    ValueError
        If ``q`` is empty, repeats a coordinate, or holds an entry that is not a
        function of the same single time symbol as the others; if ``t`` is not
        that time symbol; if ``L``, a constraint or a force holds a function of
        time that is not listed in ``q`` or a second (or higher) time
        derivative of a coordinate.
    """
    if isinstance(L, (int, float)) and not isinstance(L, bool):
        L = sp.sympify(L)
    if not isinstance(L, sp.Expr):
        raise TypeError(f"L must be a SymPy expression, got {type(L).__name__}")
    coordinates, time = _coordinates(q)
    if t is not None and t != time:
        raise ValueError(
            f"t = {t!r} is not the time of the dynamicsymbols in q, {time}: omit t (time "
            "dependence is found from L) or pass that symbol"
        )
    constraint_list = _as_list(constraints)
    force_list = _as_list(forces)
    expressions = [L, *_exprs(constraint_list), *_exprs(force_list)]
    taken = {str(s) for e in expressions for s in e.free_symbols}
    taken |= {str(s) for s in params} | {str(time)}
    names = [_function_name(c) for c in coordinates]
    q_plain = tuple(sp.Symbol(_fresh(name, taken)) for name in names)
    v_plain = tuple(sp.Symbol(_fresh(f"{name}_dot", taken)) for name in names)
    symbols = MechanicsSymbols(time, coordinates, q_plain, v_plain, None)

    L_plain = _convert(L, "L", symbols)
    constraints_plain = _convert_list(constraint_list, "constraints", symbols)
    forces_plain = _convert_list(force_list, "forces", symbols)
    timed = any(time in e.free_symbols for e in [L_plain, *_exprs(constraints_plain)])
    timed |= any(time in e.free_symbols for e in _exprs(forces_plain))
    t_plain = time if (timed or t is not None) else None
    symbols = MechanicsSymbols(time, coordinates, q_plain, v_plain, t_plain)
    return PlainModel(L_plain, q_plain, v_plain, t_plain, constraints_plain, forces_plain, symbols)


def generalised_forces(loads: Iterable[Any], q: Sequence[sp.Expr], frame: Any) -> list[sp.Expr]:
    r"""Generalised forces of applied forces and torques, by partial velocities.

    For forces :math:`F_P` acting at points :math:`P` and torques :math:`T_B`
    acting on frames :math:`B`,

    .. math::

        Q_i = \sum_P F_P \cdot \frac{\partial v_P}{\partial \dot q_i}
            + \sum_B T_B \cdot \frac{\partial \omega_B}{\partial \dot q_i},

    with the velocities :math:`v_P` and angular velocities :math:`\omega_B` taken
    in the inertial ``frame`` (the fourth term of
    ``LagrangesMethod.form_lagranges_equations``). Exact: nothing is simplified.

    Parameters
    ----------
    loads : iterable of (Point, Vector) or (ReferenceFrame, Vector)
        Forces at points and torques on frames (``forcelist``; SymPy's ``Force``
        and ``Torque`` objects are such pairs).
    q : sequence of sympy.Expr
        The coordinates :math:`q_i(t)` (dynamicsymbols).
    frame : sympy.physics.vector.ReferenceFrame
        The inertial frame.

    Returns
    -------
    list of sympy.Expr
        :math:`Q_i` in dynamicsymbols, one per coordinate.

    Raises
    ------
    TypeError
        If a load is not a pair of a ``Point`` or ``ReferenceFrame`` and a
        ``Vector``, or ``frame`` is not a ``ReferenceFrame``.
    """
    from sympy.physics.vector import Point, ReferenceFrame, Vector

    if not isinstance(frame, ReferenceFrame):
        raise TypeError(f"frame must be a ReferenceFrame, got {type(frame).__name__}")
    rates: list[tuple[Any, Any]] = []
    for j, load in enumerate(loads):
        try:
            where, vector = load
        except (TypeError, ValueError) as exc:
            raise TypeError(
                f"forcelist[{j}] must be a (Point, Vector) or (ReferenceFrame, Vector) pair, "
                f"got {load!r}"
            ) from exc
        if not isinstance(vector, Vector) and vector != 0:
            raise TypeError(f"forcelist[{j}]: the load must be a Vector, got {vector!r}")
        if isinstance(where, ReferenceFrame):
            rates.append((where.ang_vel_in(frame), vector))
        elif isinstance(where, Point):
            rates.append((where.vel(frame), vector))
        else:
            raise TypeError(
                f"forcelist[{j}] acts on {where!r}: it must be a Point (a force) or a "
                "ReferenceFrame (a torque)"
            )
    speeds = [c.diff(c.args[0]) for c in q]
    return [
        sp.Add(*(_dot(velocity.diff(qd, frame), vector) for velocity, vector in rates))
        for qd in speeds
    ]


def lagranges_method_model(lm: Any, frame: Any = None) -> MechanicsModel:
    r"""Read the Lagrangian, coordinates, constraints and loads of a ``LagrangesMethod``.

    Parameters
    ----------
    lm : sympy.physics.mechanics.LagrangesMethod
        The model. Its ``forcelist`` becomes generalised forces
        (:func:`generalised_forces`), its ``hol_coneqs`` holonomic constraints.
    frame : sympy.physics.vector.ReferenceFrame, optional
        The inertial frame for the loads; defaults to ``lm.inertial`` (the
        ``frame`` given to ``LagrangesMethod``).

    Returns
    -------
    MechanicsModel
        Everything still in dynamicsymbols.

    Raises
    ------
    TypeError
        If ``lm`` is not a ``LagrangesMethod``.
    NotImplementedError
        If ``lm`` has nonholonomic constraints (``nonhol_coneqs``).
    ValueError
        If ``lm`` has loads but no inertial frame is known.
    """
    from sympy.physics.mechanics import LagrangesMethod

    if not isinstance(lm, LagrangesMethod):
        raise TypeError(f"lm must be a sympy.physics.mechanics.LagrangesMethod, got {lm!r}")
    # SymPy 1.12-1.14 keep the Lagrangian and the holonomic constraints only in these
    # attributes; coneqs holds the constraints' time derivatives, then the nonholonomic ones
    L = lm._L[0]
    holonomic = list(lm._hol_coneqs)
    nonholonomic = list(lm.coneqs)[len(holonomic) :]
    if nonholonomic:
        raise NotImplementedError(
            f"lm has nonholonomic constraints {nonholonomic}: LagrangianSystem supports "
            "holonomic constraints g(t, q) = 0 only (write an integrable constraint as "
            "hol_coneqs)"
        )
    q = tuple(lm.q)
    loads = list(lm.forcelist or ())
    forces = None
    if loads:
        frame = lm.inertial if frame is None else frame
        if frame is None:
            raise ValueError(
                "lm has a forcelist but no inertial frame: pass frame=... here or to "
                "LagrangesMethod"
            )
        Q = generalised_forces(loads, q, frame)
        # a load that does no work on any coordinate: nothing to pass on
        forces = None if all(e == 0 for e in Q) else Q
    return MechanicsModel(L, q, holonomic or None, forces)


# ----------------------------------------------------------------- helpers
def _coordinates(q: Any) -> tuple[tuple[sp.Expr, ...], sp.Symbol]:
    """Check that ``q`` lists distinct functions of one time symbol; return them and it."""
    if isinstance(q, AppliedUndef):
        q = [q]
    entries = list(q)
    if not entries:
        raise ValueError("q must contain at least one coordinate")
    first = entries[0]
    if not (isinstance(first, AppliedUndef) and _is_time_function(first)):
        raise ValueError(
            f"q[0] = {first!r} is not a function of time: list only dynamicsymbols "
            "(functions of one time symbol, e.g. dynamicsymbols('q1')) or only plain "
            "symbols (then pass v)"
        )
    time = first.args[0]
    for j, c in enumerate(entries):
        if not (isinstance(c, AppliedUndef) and _is_time_function(c) and c.args[0] == time):
            raise ValueError(
                f"q[{j}] = {c!r} is not a function of {time} like q[0] = {first}: list only "
                "dynamicsymbols of the same time, or only plain symbols (then pass v)"
            )
    repeated = sorted({str(c) for c in entries if entries.count(c) > 1})
    if repeated:
        raise ValueError(f"q lists {', '.join(repeated)} more than once")
    return tuple(entries), time


def _is_time_function(c: AppliedUndef) -> bool:
    return len(c.args) == 1 and isinstance(c.args[0], sp.Symbol)


def _function_name(c: AppliedUndef) -> str:
    return c.func.__name__


def _fresh(name: str, taken: set[str]) -> str:
    """``name``, with underscores appended until no symbol in ``taken`` has it; reserve it."""
    while name in taken:
        name += "_"
    taken.add(name)
    return name


def _as_list(exprs: Any) -> list[Any] | None:
    """Constraints or forces as a list; anything else passes through for later checks."""
    if exprs is None:
        return None
    if isinstance(exprs, sp.Basic) and not isinstance(exprs, sp.MatrixBase):
        return [exprs]
    if isinstance(exprs, (str, bytes)) or not isinstance(exprs, Iterable):
        return exprs
    return list(exprs)


def _exprs(items: Any) -> list[sp.Expr]:
    """The SymPy expressions among ``items`` (None or a list)."""
    if not isinstance(items, list):
        return []
    return [e for e in items if isinstance(e, sp.Expr)]


def _convert_list(items: Any, name: str, symbols: MechanicsSymbols) -> Any:
    if not isinstance(items, list):
        return items
    return [
        _convert(e, f"{name}[{j}]", symbols) if isinstance(e, sp.Expr) else e
        for j, e in enumerate(items)
    ]


def _convert(expr: sp.Expr, name: str, symbols: MechanicsSymbols) -> sp.Expr:
    """Replace coordinates and their first derivatives; reject anything else of time."""
    time = symbols.time
    coordinates = set(symbols.coordinates)
    unlisted = sorted(
        {
            str(f)
            for f in expr.atoms(AppliedUndef)
            if f not in coordinates and time in f.free_symbols
        }
    )
    if unlisted:
        raise ValueError(
            f"{name} contains {', '.join(unlisted)}: functions of time not listed in q (list "
            "them in q as coordinates, or replace them by expressions or parameters)"
        )
    higher = []
    other = []
    for d in expr.atoms(sp.Derivative):
        if d.expr in coordinates and d.variable_count == ((time, 1),):
            continue
        if d.expr in coordinates and all(x == time for x, _ in d.variable_count):
            higher.append(str(d))
        else:
            other.append(str(d))
    if higher:
        raise ValueError(
            f"{name} contains {', '.join(sorted(higher))}: second or higher time derivatives "
            "of coordinates; a Lagrangian L(t, q, v), its forces and constraints may "
            "depend on the first derivatives only"
        )
    if other:
        raise ValueError(
            f"{name} contains {', '.join(sorted(other))}: derivatives other than the time "
            "derivatives of the coordinates in q"
        )
    # xreplace works top-down: Derivative(q(t), t) is replaced whole, before the q(t) in it
    return expr.xreplace(symbols.substitutions)


def _dot(a: Any, b: Any) -> sp.Expr:
    """``a . b`` for vectors that may be the scalar 0 (SymPy's zero-vector shorthand)."""
    if a == 0 or b == 0:
        return sp.S.Zero
    return a.dot(b)
