r"""Point-wise symbolic pieces of the discrete Euler–Lagrange equations.

Every residual and Jacobian of a Galerkin variational integrator is a weighted
sum, over quadrature points :math:`(t_i, Q_i, V_i)`, of a handful of point-wise
derivatives of the Lagrangian :math:`L(t, q, v)`:

.. math::

    L_q = \partial_q L,\quad L_v = \partial_v L,\quad
    L_{qq} = \partial_q^2 L,\quad L_{qv} = \partial_q\partial_v L,\quad
    L_{vv} = \partial_v^2 L .

External generalised forces :math:`f(t, q, v)` (discrete Lagrange–d'Alembert)
enter the stage equations exactly where :math:`L_q` does, so the kernels use the
*generalised force* :math:`L_q + f` and its derivatives
:math:`L_{qq} + f_q` and :math:`L_{qv} + f_v`; the transposed coupling
:math:`L_{vq} = L_{qv}^T` comes from :math:`L` alone.

This module derives them with SymPy (never by finite differences) and reads off
the structure that lets the kernels skip work.
"""

from __future__ import annotations

import random
from dataclasses import dataclass, replace

import sympy as sp

# SymPy imports these on its first differentiation (Derivative sorts its variables
# with sympy.tensor.tensor, which pulls in sympy.combinatorics): 80 ms that would
# otherwise land on the first system a process builds
import sympy.tensor.tensor  # noqa: E402, F401  isort: skip

from ..expression_walk import distinct_nodes, symbols_of  # noqa: E402
from .terms import derivative, repeated_terms, substitute  # noqa: E402

__all__ = [
    "ConstraintPieces",
    "constraint_pieces",
    "PointwisePieces",
    "Structure",
    "analyse_structure",
    "periodic_coordinates",
    "sum_of_distinct",
    "pointwise_pieces",
    "without_point_masses",
]


@dataclass(frozen=True)
class PointwisePieces:
    """SymPy expressions for :math:`L` and its first and second derivatives.

    Attributes
    ----------
    L : sympy.Expr
    Lq, Lv : sympy.Matrix, shape (n, 1)
    Lqq, Lqv, Lvv : sympy.SparseMatrix, shape (n, n)
        ``Lqv[a, b]`` is :math:`\\partial^2 L / \\partial q_a \\partial v_b`; entries
        that are identically zero are not stored.
    f : sympy.Matrix, shape (n, 1), or None
        External generalised forces :math:`f(t, q, v)`; ``None`` without forces.
    fq, fv : sympy.SparseMatrix, shape (n, n), or None
        :math:`\\partial f_a/\\partial q_b` and :math:`\\partial f_a/\\partial v_b`.
    """

    L: sp.Expr
    Lq: sp.Matrix
    Lv: sp.Matrix
    Lqq: sp.MatrixBase
    Lqv: sp.MatrixBase
    Lvv: sp.MatrixBase
    f: sp.Matrix | None = None
    fq: sp.MatrixBase | None = None
    fv: sp.MatrixBase | None = None

    @property
    def force(self) -> sp.Matrix:
        r"""Generalised force of the stage equations, :math:`L_q + f`."""
        return self.Lq if self.f is None else self.Lq + self.f

    @property
    def force_q(self) -> sp.MatrixBase:
        r""":math:`\partial(L_q + f)/\partial q = L_{qq} + f_q` (sparse)."""
        return self.Lqq if self.fq is None else _sparse_sum(self.Lqq, self.fq)


@dataclass(frozen=True)
class Structure:
    """Structure of a Lagrangian that the integrator can exploit.

    Attributes
    ----------
    autonomous : bool
        :math:`L` does not depend on time.
    zero_Lqv : bool
        :math:`\\partial_q\\partial_v L \\equiv 0` (no velocity–position coupling).
    quadratic_in_v : bool
        :math:`L = \\tfrac12 v^T M(t, q) v + a(t, q)\\cdot v - V(t, q)`.
    constant_mass : bool
        :math:`L_{vv}` depends on parameters at most (constant mass matrix).
    forced : bool
        External forces :math:`f` are present.
    zero_fv : bool
        :math:`\\partial f/\\partial v \\equiv 0` (also true without forces).
    separable : bool
        :math:`L = \\tfrac12 v^T M v - V(q)` with constant :math:`M` (``zero_Lqv``
        and ``constant_mass``); the setting of Störmer–Verlet.
    quadratic : bool
        :math:`L` is a polynomial of degree at most two in :math:`(q, v)` and
        :math:`f` is affine in :math:`(q, v)` with constant coefficients, so
        the stage equations are linear.
    """

    autonomous: bool
    zero_Lqv: bool
    quadratic_in_v: bool
    constant_mass: bool
    separable: bool
    quadratic: bool
    forced: bool = False
    zero_fv: bool = True


class _TermDerivatives:
    """Derivatives of the terms of a sum, computed once per term shape.

    A term is rewritten over placeholder symbols (same assumptions, in a
    canonical order) before it is differentiated, so the springs of a chain of
    N masses, ``(q_{a+1} - q_a)**4``, share one symbolic derivative that is then
    re-instantiated by substitution. SymPy's differentiation of a fresh
    expression costs milliseconds (assumption queries); substitution costs
    microseconds.
    """

    def __init__(self) -> None:
        self._cache: dict[sp.Expr, dict[sp.Symbol, sp.Expr]] = {}

    def __call__(self, term: sp.Expr, wanted: dict[sp.Symbol, int]) -> dict[sp.Symbol, sp.Expr]:
        """``{s: d term / d s}`` for the symbols of ``term`` that are keys of ``wanted``."""
        symbols = sorted(term.free_symbols, key=sp.default_sort_key)
        # coordinates, velocities, time and parameters are real: d|v|/dv = sign(v)
        placeholders = [
            sp.Symbol(f"_gvi_x{k}", **_real_assumptions(s)) for k, s in enumerate(symbols)
        ]
        template = term.xreplace(dict(zip(symbols, placeholders, strict=True)))
        derivatives = self._cache.setdefault(template, {})
        back = dict(zip(placeholders, symbols, strict=True))
        out = {}
        for s, x in zip(symbols, placeholders, strict=True):
            if s in wanted:
                if x not in derivatives:
                    derivatives[x] = sp.diff(template, x)
                out[s] = derivatives[x].xreplace(back)
        return out


def _real_assumptions(symbol: sp.Symbol) -> dict[str, bool]:
    """The symbol's assumptions with ``real=True`` added where they allow it."""
    assumptions = dict(symbol.assumptions0)
    if symbol.is_real is None:
        assumptions["real"] = True
    return assumptions


def _gradient(expr: sp.Expr, symbols: list[sp.Symbol], derive: _TermDerivatives) -> sp.Matrix:
    """Column of the derivatives of ``expr`` by ``symbols``.

    A sum is differentiated term by term, each term only by the symbols it
    contains, so that a Lagrangian of N weakly coupled coordinates costs O(N),
    not O(N^2), derivative calls.
    """
    index = {s: i for i, s in enumerate(symbols)}
    parts: list[list[sp.Expr]] = [[] for _ in symbols]
    for term in sp.Add.make_args(expr):
        for s, d in derive(term, index).items():
            parts[index[s]].append(d)
    return sp.Matrix([sp.Add(*terms) for terms in parts])


def _jacobian(
    column: sp.Matrix, symbols: list[sp.Symbol], derive: _TermDerivatives
) -> sp.SparseMatrix:
    """Sparse Jacobian of ``column`` by ``symbols``: only structural nonzeros are stored."""
    index = {s: i for i, s in enumerate(symbols)}
    entries = {}
    for a, f in enumerate(column):
        parts: dict[int, list[sp.Expr]] = {}
        for term in sp.Add.make_args(f):
            for s, d in derive(term, index).items():
                parts.setdefault(index[s], []).append(d)
        for b, terms in parts.items():
            d = sp.Add(*terms)
            if d != 0:
                entries[(a, b)] = d
    return _sparse(len(column), len(symbols), entries)


def _sparse(rows: int, cols: int, entries: dict) -> sp.SparseMatrix:
    """A sparse matrix of ``entries``, read-only by convention.

    SymPy's immutable sparse matrix sorts its entries by their expressions'
    sort keys when built (0.5 ms an entry of a spring's second derivative:
    seconds for a lattice of hundreds of masses); the mutable one does not.
    """
    return sp.SparseMatrix(rows, cols, entries)


def _sparse_sum(a: sp.MatrixBase, b: sp.MatrixBase) -> sp.SparseMatrix:
    """Sum of two sparse matrices, storing only entries that do not cancel."""
    entries = dict(a.todok())
    for key, e in b.todok().items():
        total = entries.get(key, 0) + e
        if total == 0:
            entries.pop(key, None)
        else:
            entries[key] = total
    return _sparse(a.rows, a.cols, entries)


def pointwise_pieces(
    L: sp.Expr,
    q: list[sp.Symbol],
    v: list[sp.Symbol],
    forces: list[sp.Expr] | None = None,
) -> PointwisePieces:
    """Differentiate ``L`` once and twice, and ``forces`` once, by ``q`` and ``v``.

    The second derivatives are sparse matrices holding only the entries that
    are not identically zero (a chain of N masses has O(N) of them).
    """
    derive = _TermDerivatives()
    Lq, Lv, Lqq, Lqv, Lvv = _lagrangian_derivatives(L, q, v)
    f = fq = fv = None
    if forces is not None:
        f = sp.Matrix(forces)
        fq = _jacobian(f, q, derive)
        fv = _jacobian(f, v, derive)
    return PointwisePieces(L=L, Lq=Lq, Lv=Lv, Lqq=Lqq, Lqv=Lqv, Lvv=Lvv, f=f, fq=fq, fv=fv)


def _lagrangian_derivatives(L: sp.Expr, q: list[sp.Symbol], v: list[sp.Symbol]) -> tuple:
    r""":math:`L_q, L_v` (columns) and :math:`L_{qq}, L_{qv}, L_{vv}` (sparse) of ``L``.

    The terms of ``L`` are grouped by shape (:func:`~.terms.repeated_terms`:
    one template on the index tuples of its instances, the two powers of one
    spring summed into one template); each template's gradient and Hessian
    are taken once, over placeholders, and instantiated per term by
    substitution. Taking the second derivatives from the template, not from
    the instantiated first derivatives, halves the substitutions, which are
    what a lattice's analysis costs (each rebuilt power of a sum queries
    SymPy's assumptions).
    """
    index = {s: a for a, s in enumerate(q)} | {s: a for a, s in enumerate(v)}
    others = tuple(sorted(L.free_symbols - set(index), key=sp.default_sort_key))
    groups, rest = repeated_terms(L, tuple(q), tuple(v), others, None, min_count=1)
    first: dict[tuple[str, int], list[sp.Expr]] = {}
    second: dict[tuple[str, int, int], list[sp.Expr]] = {}
    symbols = {"q": tuple(q), "v": tuple(v), "prm": others}
    for group in groups:
        derivatives = _template_derivatives(group)
        flat = [e for _, d, seconds in derivatives for e in (d, *(dd for _, dd in seconds))]
        for row in group.table:
            mapping = {
                z: symbols[kind][int(j)]
                for z, kind, j in zip(group.arguments, group.kinds, row, strict=True)
            }
            values = iter(substitute(flat, mapping))
            for (kind_i, i), _, seconds in derivatives:
                first.setdefault((kind_i, int(row[i])), []).append(next(values))
                for (block, j), _ in seconds:
                    key = (block, int(row[i]), int(row[j]))
                    second.setdefault(key, []).append(next(values))
    n = len(q)
    columns = {kind: [sum_of_distinct(first.get((kind, a), ())) for a in range(n)] for kind in "qv"}
    Lq, Lv = sp.Matrix(columns["q"]), sp.Matrix(columns["v"])
    blocks = {}
    for name in ("Lqq", "Lqv", "Lvv"):
        entries = {}
        for (block, a, b), terms in second.items():
            if block == name:
                total = sum_of_distinct(terms)
                if total != 0:
                    entries[(a, b)] = total
        blocks[name] = _sparse(n, n, entries)
    if rest != 0:
        # terms of no indexed shape (none: every term of L has symbols, or is constant)
        derive = _TermDerivatives()
        Lq += _gradient(rest, q, derive)
        Lv += _gradient(rest, v, derive)
    return Lq, Lv, blocks["Lqq"], blocks["Lqv"], blocks["Lvv"]


def sum_of_distinct(terms: list[sp.Expr] | tuple[sp.Expr, ...]) -> sp.Expr:
    r"""``sp.Add(*terms)``, built without SymPy's evaluation where it has nothing to do.

    The contributions of different instances to one entry of a derivative
    (the four springs at a lattice site in :math:`L_{q_a q_a}`) are mostly
    different expressions. :math:`\sum_i c_i P_i` with numbers :math:`c_i`
    and pairwise distinct non-numeric parts :math:`P_i` has no like terms to
    collect: the sum is the numbers added plus the terms as given, in the
    given order, while ``Add`` would also sort them (a comparison of
    expression trees per pair), which costs more than the rest of the
    analysis of a lattice. Where two parts coincide, or a number is not
    finite, ``Add`` evaluates as usual.
    """
    if len(terms) == 1:
        return terms[0]
    number = sp.S.Zero
    parts: set[sp.Expr] = set()
    rest = []
    for term in terms:
        for a in sp.Add.make_args(term):
            if a.is_Number:
                number += a
                continue
            part = a.as_coeff_Mul()[1]
            if part in parts:
                return sp.Add(*terms)
            parts.add(part)
            rest.append(a)
    if not number.is_finite:
        return sp.Add(*terms)
    if not rest:
        return number
    if len(rest) == 1 and number == 0:
        return rest[0]
    return sp.Add._from_args(([number] if number != 0 else []) + rest)


def _template_derivatives(group):
    """Per coordinate or velocity argument ``i`` of a template: ``((kind, i), dT/dz_i,
    [((block, j), d2T/dz_i dz_j), ...])``, the nonzero ones."""
    z = group.arguments
    active = [i for i, kind in enumerate(group.kinds) if kind in ("q", "v")]
    blocks = {("q", "q"): "Lqq", ("q", "v"): "Lqv", ("v", "v"): "Lvv"}
    out = []
    for i in active:
        d = derivative(group.template, z[i])
        if d == 0:
            continue
        seconds = []
        for j in active:
            block = blocks.get((group.kinds[i], group.kinds[j]))
            if block is not None:
                dd = derivative(d, z[j])
                if dd != 0:
                    seconds.append(((block, j), dd))
        out.append(((group.kinds[i], i), d, seconds))
    return out


def without_point_masses(pieces: PointwisePieces) -> PointwisePieces:
    r"""The pieces with the Dirac deltas of the second derivatives set to zero.

    The second derivatives of a Lagrangian with kinks (``Abs``, ``Min``,
    ``Max``, ``sign`` of a first derivative) contain ``DiracDelta`` terms. They
    vanish everywhere except on the kink itself, so the point-wise (classical)
    second derivative, which Newton's Jacobian needs, is the expression without
    them; no code printer can evaluate a delta. Call it after
    :func:`analyse_structure`, which must see the deltas: the classical second
    derivative of an ``Abs(q)`` potential vanishes, yet the stage equations are
    not linear.
    """

    def drop(m: sp.MatrixBase | None) -> sp.MatrixBase | None:
        if m is None or not any(
            isinstance(node, sp.DiracDelta) for node in distinct_nodes(m.values())
        ):
            return m
        entries = {}
        for key, e in m.todok().items():
            e = e.replace(sp.DiracDelta, lambda *args: sp.S.Zero)
            if e != 0:
                entries[key] = e
        return _sparse(m.rows, m.cols, entries)

    return replace(
        pieces,
        Lqq=drop(pieces.Lqq),
        Lqv=drop(pieces.Lqv),
        Lvv=drop(pieces.Lvv),
        fq=drop(pieces.fq),
        fv=drop(pieces.fv),
    )


def _value_at(expr: sp.Expr, point: dict[sp.Symbol, sp.Float]) -> sp.Expr | None:
    """``expr`` evaluated at ``point``, or None where SymPy refuses.

    Min, Max and Piecewise conditions raise on NaN or complex values (an
    undefined branch, a negative number to a fractional power).
    """
    try:
        return expr.xreplace(point)
    except (TypeError, ValueError):
        return None


def _is_zero_matrix(m: sp.MatrixBase) -> bool:
    """Whether every entry is identically zero.

    An entry that is nonzero at a random point is not zero; only the others go
    through ``simplify`` (whose first call alone costs 0.3 s of imports).
    """
    rng = random.Random(20261122)
    for e in m.values():
        point = {s: sp.Float(rng.uniform(0.3, 1.7)) for s in e.free_symbols}
        value = _value_at(e, point)
        if value is None or (value.is_Number and value != 0):
            return False
        if sp.simplify(e) != 0:
            return False
    return True


def analyse_structure(
    pieces: PointwisePieces,
    q: list[sp.Symbol],
    v: list[sp.Symbol],
    t: sp.Symbol | None,
) -> Structure:
    """Find the structure flags of :class:`Structure` from the derivatives."""
    qv = set(q) | set(v)
    forced = pieces.f is not None
    timed = pieces.L.free_symbols | (pieces.f.free_symbols if forced else set())
    autonomous = t is None or t not in timed
    zero_fv = not forced or _is_zero_matrix(pieces.fv)
    zero_Lqv = _is_zero_matrix(pieces.Lqv)
    state = qv | ({t} if t is not None else set())
    lvv_symbols = symbols_of(pieces.Lvv.values())
    quadratic_in_v = not (lvv_symbols & set(v))
    constant_mass = not (lvv_symbols & state)
    hessians = (
        e
        for m in (pieces.Lqq, pieces.Lqv, pieces.Lvv, pieces.fq, pieces.fv)
        if m is not None
        for e in m.values()
    )
    # the walk stops at the first coordinate, velocity or time it meets: a nonlinear
    # model's first Hessian entry usually decides
    quadratic = not any(node in state for node in distinct_nodes(hessians))
    return Structure(
        autonomous=autonomous,
        zero_Lqv=zero_Lqv,
        quadratic_in_v=quadratic_in_v,
        constant_mass=constant_mass,
        separable=zero_Lqv and constant_mass,
        quadratic=quadratic,
        forced=forced,
        zero_fv=zero_fv,
    )


def periodic_coordinates(exprs: list[sp.Expr], q: list[sp.Symbol]) -> tuple[bool, ...]:
    r"""Which coordinates are angles: every expression is :math:`2\pi`-periodic in them.

    A coordinate counts when it occurs in some expression, and only inside the
    arguments of sine, cosine, tangent, cotangent, secant or cosecant, each
    argument an integer multiple of it plus terms free of it (``cos(2 a - b)``).
    The check is structural, one pass over each expression, so a chain of 1000
    coordinates costs milliseconds; a periodic expression in another form
    (:math:`\sqrt{\sin^2 a}`, say, is fine, but :math:`a - a\cos^2 a - a\sin^2 a`
    is not recognised) only costs the optimisation, never correctness.
    """
    candidates = set(q)
    seen: set[sp.Symbol] = set()
    for e in exprs:
        seen |= e.free_symbols & candidates
        candidates -= _outside_trig(e, candidates)
    return tuple(qa in candidates and qa in seen for qa in q)


_TRIG = (sp.sin, sp.cos, sp.tan, sp.cot, sp.sec, sp.csc)


def _outside_trig(expr: sp.Expr, symbols: set[sp.Symbol]) -> set[sp.Symbol]:
    """The ``symbols`` that occur in ``expr`` other than as whole turns of a trig argument."""
    present = expr.free_symbols & symbols
    if not present:
        return set()
    if isinstance(expr, sp.Symbol):
        return {expr}
    if isinstance(expr, _TRIG):
        (argument,) = expr.args
        bad = set()
        for s in present:
            slope = sp.diff(argument, s)
            if not (slope.is_Integer and not (argument - slope * s).has(s)):
                bad.add(s)
        return bad
    bad = set()
    for arg in expr.args:
        bad |= _outside_trig(arg, symbols)
    return bad


@dataclass(frozen=True)
class ConstraintPieces:
    r"""SymPy expressions of the constraints and their derivatives.

    Attributes
    ----------
    g : sympy.Matrix, shape (m, 1)
    jacobian : sympy.Matrix, shape (m, n)
        :math:`\mathcal G_{ja} = \partial g_j/\partial q_a`.
    rate : sympy.Matrix, shape (m, 1)
        :math:`\partial g_j/\partial t` (zero for scleronomic constraints).
    hessians : tuple of sympy.Matrix, shape (n, n) each
        :math:`\partial^2 g_j/\partial q^2`.
    """

    g: sp.Matrix
    jacobian: sp.Matrix
    rate: sp.Matrix
    hessians: tuple[sp.Matrix, ...]

    @property
    def m(self) -> int:
        """Number of constraints."""
        return self.g.rows

    def contracted_hessian(self, lam: list[sp.Symbol]) -> sp.Matrix:
        r""":math:`\sum_j \lambda_j \nabla^2 g_j` in the multiplier symbols ``lam``."""
        n = self.jacobian.cols
        total = sp.zeros(n, n)
        for lj, hj in zip(lam, self.hessians, strict=True):
            total += lj * hj
        return total


def constraint_pieces(
    constraints: tuple[sp.Expr, ...], q: tuple[sp.Symbol, ...], t: sp.Symbol
) -> ConstraintPieces:
    """Differentiate the constraints by ``q`` (once and twice) and by ``t``."""
    g = sp.Matrix(constraints)
    jacobian = g.jacobian(list(q))
    return ConstraintPieces(
        g=g,
        jacobian=jacobian,
        rate=g.diff(t),
        hessians=tuple(sp.hessian(e, list(q)) for e in constraints),
    )
