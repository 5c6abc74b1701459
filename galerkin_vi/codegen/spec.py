r"""Stage 1 of code generation: a system's point-wise expressions as plain data.

:func:`kernel_spec` collects the expressions of :math:`L`, :math:`L_q + f`,
:math:`L_v`, :math:`L_{qq} + f_q`, :math:`L_{qv}`, :math:`L_{vv}`, :math:`f_v`
(and, for the varying-mass loop, the gradient with :math:`L_{qv} + f_v` and
:math:`L_{vv}` alone)
and of the constraints, drops the entries that are identically zero and
renames the user's symbols to array slots ``q[a]``, ``v[a]``, ``prm[j]``;
:func:`signature` hashes the result with the generator's version, naming the
system's cache entry. Nothing here depends on how the loops are compiled:
they are the same for every system (:mod:`galerkin_vi.loops`).
"""

from __future__ import annotations

import hashlib
import sys
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import sympy as sp

from ..expression_walk import structural_bytes
from ..method.stage_form import has_stage_form
from ..model.symbolic import pointwise_pieces, without_point_masses
from ..model.terms import repeated_terms
from .explicit_steps import has_generated_loops
from .scatter import ScatterGroup, scatter_group

if TYPE_CHECKING:
    from ..model.system import LagrangianSystem

__all__ = [
    "GENERATOR_VERSION",
    "KernelSpec",
    "LARGE",
    "has_stage_steps",
    "MIN_REPEATS",
    "REPEATS_FROM",
    "SpecSummary",
    "summarize",
    "kernel_spec",
    "parameter_derivative_spec",
    "signature",
    "sparsity_pattern",
    "use_banded",
]

GENERATOR_VERSION = "20"

#: the fewest instances of a term that become a scatter loop (:mod:`.scatter`)
MIN_REPEATS = 8
#: a point function with more entries than this is generated in parts (:mod:`.source`)
LARGE = 120
#: systems with more second-derivative entries than this have their repeated terms
#: generated as scatter loops; smaller ones as straight-line code with joint
#: common-subexpression elimination (faster per call, and quick to compile)
REPEATS_FROM = 120


@dataclass(frozen=True)
class KernelSpec:
    """Language-neutral description of one system's point functions.

    Each ``*_entries`` is a tuple of ``(target, expression)`` with target an
    array slot such as ``"Lqq[0, 1]"``; identically zero entries are absent.
    With ``repeats``, the point functions are the scatter loops of the repeated
    terms of :math:`L` (:mod:`.scatter`) plus the entries, which then hold
    only the rest: the derivatives of the terms that do not repeat and of the
    forces, and ``lagrangian`` the sum of those terms. ``generated_loops``:
    the module also holds the system's own explicit loop (:mod:`.explicit_steps`)
    and, with a diagonal mass, stage-form loop (:mod:`.stage_steps`).
    ``repeated_loop``: the module also holds ``repeated_explicit_steps``, the
    explicit loop of a small system whose force is its repeated terms alone, with
    their scatter loops unrolled in their order (:func:`.source.repeated_force_lines`).
    """

    n: int
    n_params: int
    autonomous: bool
    has_Lqv: bool
    lagrangian: sp.Expr
    gradient_entries: tuple[tuple[str, sp.Expr], ...]
    hessian_entries: tuple[tuple[str, sp.Expr], ...]
    mass_entries: tuple[tuple[str, sp.Expr], ...] = ()
    velocity_entries: tuple[tuple[str, sp.Expr], ...] = ()
    generated_loops: bool = False
    pattern: tuple[tuple[int, int], ...] = ()
    half_bandwidth: int = 0
    banded: bool = False
    has_fv: bool = False
    m: int = 0
    periodic: tuple[bool, ...] = ()
    separable: bool = False
    diagonal_mass: bool = False
    constraint_entries: tuple[tuple[str, sp.Expr], ...] = ()
    constraint_jacobian_entries: tuple[tuple[str, sp.Expr], ...] = ()
    constraint_rate_entries: tuple[tuple[str, sp.Expr], ...] = ()
    constraint_hessian_entries: tuple[tuple[str, sp.Expr], ...] = ()
    repeats: tuple[ScatterGroup, ...] = ()
    repeated_loop: bool = False
    contact_entries: tuple[tuple[str, sp.Expr], ...] = ()
    slip_entries: tuple[tuple[str, sp.Expr], ...] = ()

    @property
    def constraint_parts(self) -> tuple[tuple[str, sp.Expr], ...]:
        """Every constraint entry, in a fixed order (for hashing)."""
        return (
            self.constraint_entries
            + self.constraint_jacobian_entries
            + self.constraint_rate_entries
            + self.constraint_hessian_entries
        )

    @property
    def nnz(self) -> int:
        """Number of stored entries of each second-derivative block."""
        return len(self.pattern) if self.banded else self.n * self.n


@dataclass(frozen=True)
class SpecSummary:
    """What the loops need of a :class:`KernelSpec`, and the key of its point functions.

    Small plain data, kept in the system's analysis cache: a cached system then
    runs without re-deriving its spec or hashing its expressions (for a 60-mass
    chain, 0.3 s of SymPy printing).
    """

    key: str
    n: int
    m: int
    autonomous: bool
    has_Lqv: bool
    has_fv: bool
    banded: bool
    half_bandwidth: int
    pattern: tuple[tuple[int, int], ...]
    periodic: tuple[bool, ...]
    diagonal_mass: bool
    explicit_velocity: bool = False


def summarize(spec: KernelSpec, key: str) -> SpecSummary:
    """The :class:`SpecSummary` of ``spec`` with point-function key ``key``."""
    return SpecSummary(
        key=key,
        n=spec.n,
        m=spec.m,
        autonomous=spec.autonomous,
        has_Lqv=spec.has_Lqv,
        has_fv=spec.has_fv,
        banded=spec.banded,
        half_bandwidth=int(spec.half_bandwidth),
        pattern=tuple((int(a), int(b)) for a, b in spec.pattern),
        periodic=tuple(bool(x) for x in spec.periodic),
        diagonal_mass=bool(spec.diagonal_mass),
        explicit_velocity=bool(spec.velocity_entries),
    )


def sparsity_pattern(pieces, n: int, has_lqv: bool) -> tuple[tuple[int, int], ...]:
    """Union of the structural nonzeros of L_qq + f_q, L_vv, L_qv, f_v and transposes, row-major."""
    blocks = [pieces.force_q, pieces.Lvv] + ([pieces.Lqv] if has_lqv else [])
    if pieces.fv is not None:
        blocks.append(pieces.fv)
    pairs = set()
    for block in blocks:
        for (a, b), e in block.todok().items():
            if e != 0:
                # plain ints: a matrix loaded from the analysis cache keys by SymPy Integers
                a, b = int(a), int(b)
                pairs.add((a, b))
                pairs.add((b, a))
    pairs.update((a, a) for a in range(n))  # the diagonal, so every coordinate has a row
    return tuple(sorted(pairs))


def use_banded(n: int, half_bandwidth: int) -> bool:
    """Banded storage and LU pay when the coupling band is narrow against n.

    With s control points the stage Jacobian, ordered coordinate-major, has
    half-bandwidth (w + 1) s - 1 for coordinate coupling |a - b| <= w: a banded LU
    costs O(n s^3 w^2) instead of O(n^3 s^3).
    """
    return n >= 8 and 4 * (half_bandwidth + 1) <= n


def kernel_spec(system: LagrangianSystem, repeats: bool = True) -> KernelSpec:
    """Collect the expressions of ``system`` with symbols renamed to array slots.

    Parameters
    ----------
    system : LagrangianSystem
    repeats : bool
        Generate the repeated terms of a large Lagrangian as scatter loops
        (:mod:`.scatter`); False gives straight-line entries of every
        derivative (the reference the loops are tested against).
    """
    n = system.n
    rename = _renaming(system)
    full = system.pieces
    has_lqv = not system.structure.zero_Lqv
    has_fv = not system.structure.zero_fv
    pattern = sparsity_pattern(full, n, has_lqv)
    half_bandwidth = max(abs(a - b) for a, b in pattern) if pattern else 0
    m = system.m
    # the constrained loop is dense: multipliers couple every coordinate they touch
    banded = use_banded(n, half_bandwidth) and m == 0
    position = {pair: k for k, pair in enumerate(pattern)}
    groups: tuple[ScatterGroup, ...] = ()
    p = full
    if repeats and _entry_count(full, has_lqv, has_fv) > REPEATS_FROM:
        found = _scatter_groups(system, rename, position if banded else None)
        if found is not None:
            groups, p = found

    def vector(name: str, column: sp.Matrix) -> list[tuple[str, sp.Expr]]:
        return [(f"{name}[{a}]", e.xreplace(rename)) for a, e in enumerate(column) if e != 0]

    def matrix(name: str, block: sp.MatrixBase) -> list[tuple[str, sp.Expr]]:
        # flat storage: slot a*n + b (dense), or the pattern position of (a, b) (banded)
        out = []
        for (a, b), e in sorted(block.todok().items()):
            if e != 0:
                k = position[(a, b)] if banded else a * n + b
                out.append((f"{name}[{k}]", e.xreplace(rename)))
        return out

    # forces enter where L_q does: the kernels see L_q + f and L_qq + f_q
    gradient = vector("Lq", p.force) + vector("Lv", p.Lv)
    hessian = (
        gradient
        + matrix("Lqq", p.force_q)
        + (matrix("Lqv", p.Lqv) if has_lqv else [])
        + matrix("Lvv", p.Lvv)
        + (matrix("Fv", p.fv) if has_fv else [])
    )
    # the varying-mass loop's sweep: the gradient, d(L_q + f)/dv and L_vv, no L_qq
    velocity_coupling = p.Lqv + p.fv if has_fv else p.Lqv
    mass = gradient + matrix("Lqv", velocity_coupling) + matrix("Lvv", p.Lvv)
    return KernelSpec(
        n=n,
        n_params=len(system.params),
        autonomous=system.structure.autonomous,
        has_Lqv=has_lqv,
        lagrangian=p.L.xreplace(rename),
        gradient_entries=tuple(gradient),
        hessian_entries=tuple(hessian),
        mass_entries=tuple(mass),
        velocity_entries=() if groups else _velocity_entries(system, rename),
        # straight-line point functions only: the generated loops copy their text
        generated_loops=not groups and len(hessian) <= LARGE and has_generated_loops(system, p),
        pattern=pattern if banded else (),
        half_bandwidth=half_bandwidth,
        banded=banded,
        has_fv=has_fv,
        periodic=system.periodic,
        separable=has_stage_form(system),
        diagonal_mass=system.structure.constant_mass
        and all(a == b for (a, b), e in full.Lvv.todok().items() if e != 0),
        repeats=groups,
        # the whole L's L_v at rest, not the remainder's: a repeated a(t) . v is a group
        repeated_loop=bool(groups)
        and has_generated_loops(system, system.pieces)
        and not any(target.startswith("Lq[") for target, _ in gradient),
        **_constraint_entries(system, rename),
        **_contact_entries(system, rename),
    )


#: the largest system whose velocities are solved from a full (not diagonal) mass
#: matrix in closed form: the adjugate of a 2 x 2 matrix is two products
EXPLICIT_FULL_MASS = 2


def _velocity_entries(system: LagrangianSystem, rename: dict) -> tuple[tuple[str, sp.Expr], ...]:
    r"""Entries of ``point_velocity``: the velocity and the force at given momenta.

    For :math:`L = \tfrac12 v^TM(t, q)v + a(t, q)\cdot v - U(t, q)` the momentum
    equation :math:`p = L_v = M v + a` has the solution

    .. math::

        v(t, q, p) = M(t, q)^{-1}\big(p - a(t, q)\big),

    in closed form when :math:`M` is diagonal (any size) or has at most
    :data:`EXPLICIT_FULL_MASS` rows (by the adjugate). ``V[a]`` is :math:`v_a`
    and ``F[a]`` is :math:`(L_q + f)(t, q, v(t, q, p))`, with the momenta read
    from ``p[a]``: one call gives a Gauss stage both its velocity and its force,
    the sweep of Hamilton's equations that the varying-mass loop then runs
    (:mod:`galerkin_vi.loops.varying_mass`). Empty when the solution is not in
    closed form (L not quadratic in v, constraints, a full M of more rows) or
    when that loop does not run the system (constant mass and forces
    independent of v, or linear stage equations); :func:`kernel_spec` does not
    ask for it when the Lagrangian's repeated terms become scatter loops (the
    straight-line code of a large system would cost its build time).
    """
    structure = system.structure
    n = system.n
    # the loops of constant-mass and linear systems never read it
    if system.m or not structure.quadratic_in_v or structure.quadratic or has_stage_form(system):
        return ()
    pieces = system.pieces
    M = pieces.Lvv  # noqa: N806
    diagonal = all(a == b for (a, b), e in M.todok().items() if e != 0)
    if not diagonal and n > EXPLICIT_FULL_MASS:
        return ()
    at_rest = {w: sp.Integer(0) for w in system.v}
    p = [sp.Symbol(f"p[{a}]", real=True) for a in range(n)]
    rhs = [p[a] - pieces.Lv[a].xreplace(at_rest) for a in range(n)]
    if diagonal:
        if any(M[a, a] == 0 for a in range(n)):
            return ()
        velocity = [rhs[a] / M[a, a] for a in range(n)]
    else:
        det = M[0, 0] * M[1, 1] - M[0, 1] * M[1, 0]
        velocity = [
            (M[1, 1] * rhs[0] - M[0, 1] * rhs[1]) / det,
            (M[0, 0] * rhs[1] - M[1, 0] * rhs[0]) / det,
        ]
    solved = dict(zip(system.v, velocity, strict=True))
    force = [e.xreplace(solved) for e in pieces.force]
    entries = [(f"V[{a}]", e.xreplace(rename)) for a, e in enumerate(velocity) if e != 0]
    entries += [(f"F[{a}]", e.xreplace(rename)) for a, e in enumerate(force) if e != 0]
    return tuple(entries)


def _entry_count(pieces, has_lqv: bool, has_fv: bool) -> int:
    """Number of stored entries of the point functions' largest one (``point_hessian``)."""
    blocks = [pieces.force, pieces.Lv, pieces.force_q, pieces.Lvv]
    blocks += [pieces.Lqv] if has_lqv else []
    blocks += [pieces.fv] if has_fv else []
    return sum(sum(1 for e in block.values() if e != 0) for block in blocks)


def _consecutive(table) -> bool:
    """Whether the instances, sorted, step every index by the same amount (a chain's springs):
    the runs of :mod:`.repeats` then make loops of them without index tables, faster per
    call (on a 100-mass chain, 3.9 against 4.7 us per Gauss(2) step)."""
    rows = table[np.lexsort(table.T[::-1])]
    steps = np.diff(rows, axis=0)
    return len(rows) < 2 or bool(np.all(steps == steps[0]))


def _scatter_groups(system: LagrangianSystem, rename: dict, position: dict | None):
    """The scatter loops of ``system``'s repeated terms and the pieces of the rest.

    Returns ``(groups, pieces)`` with ``pieces`` the derivatives of the terms of
    :math:`L` that do not repeat (and of the forces), or None when nothing
    repeats or a repeated term's derivative falls outside the banded storage.
    """
    found, remainder = repeated_terms(
        system.pieces.L, system.q, system.v, system.params, system.t, MIN_REPEATS
    )
    if not found or all(_consecutive(group.table) for group in found):
        return None
    groups = []
    for k, group in enumerate(found):
        scattered = scatter_group(group, f"_g{k}", system.n, position, rename)
        if scattered is None:
            return None
        groups.append(scattered)
    forces = None if system.forces is None else list(system.forces)
    rest = without_point_masses(pointwise_pieces(remainder, list(system.q), list(system.v), forces))
    if position is not None:
        stored = (rest.force_q, rest.Lqv, rest.Lvv) + ((rest.fv,) if rest.fv is not None else ())
        if any(key not in position for block in stored for key in block.todok()):
            return None
    return tuple(groups), rest


def parameter_derivative_spec(system: LagrangianSystem, params) -> KernelSpec:
    r"""The derivatives of the stage equations' point values with respect to parameters.

    A spec whose ``point_gradient`` writes :math:`\partial (L_q + f)_a/\partial\theta_j`
    into ``Lq[a P + j]`` and :math:`\partial (L_v)_a/\partial\theta_j` into
    ``Lv[a P + j]`` for the ``P`` parameters ``params`` (symbols of ``system.params``,
    in that order): the :math:`R_\theta` of the tangent map
    (:mod:`galerkin_vi.loops.tangent`). Compiled on demand, as a cache entry of its own.
    """
    base = kernel_spec(system)
    n = system.n
    rename = _renaming(system)
    pieces = system.pieces
    P = len(params)  # noqa: N806
    entries = []
    for name, column in (("Lq", pieces.force), ("Lv", pieces.Lv)):
        for a in range(n):
            for j, theta in enumerate(params):
                e = sp.diff(column[a], theta)
                if e != 0:
                    entries.append((f"{name}[{a * P + j}]", e.xreplace(rename)))
    return KernelSpec(
        n=n, n_params=base.n_params, autonomous=base.autonomous, has_Lqv=base.has_Lqv,
        lagrangian=sp.Integer(0), gradient_entries=tuple(entries), hessian_entries=(),
        periodic=base.periodic,
    )  # fmt: skip


def _renaming(system: LagrangianSystem) -> dict:
    """The user's symbols to the generated code's array slots."""
    rename: dict[sp.Symbol, sp.Symbol] = {}
    for a, s in enumerate(system.q):
        rename[s] = sp.Symbol(f"q[{a}]", real=True)
    for a, s in enumerate(system.v):
        rename[s] = sp.Symbol(f"v[{a}]", real=True)
    for j, s in enumerate(system.params):
        rename[s] = sp.Symbol(f"prm[{j}]", real=True)
    if system.t is not None:
        rename[system.t] = sp.Symbol("t", real=True)
    return rename


def _constraint_entries(system: LagrangianSystem, rename: dict) -> dict:
    r"""Entries of the constraint point functions (empty without constraints).

    ``g[j]``, ``Gq[j n + a]`` (dense Jacobian), ``gt[j]`` and
    ``Hg[a n + b]`` :math:`= \sum_j \lambda_j \partial^2 g_j/\partial q_a\partial q_b`
    with the multipliers read from ``lam[j]``.
    """
    pieces = system.constraint_pieces
    if pieces is None:
        return {}
    m = system.m
    rename = dict(rename)
    rename[system.time_symbol] = sp.Symbol("t", real=True)
    lam = [sp.Symbol(f"lam[{j}]", real=True) for j in range(m)]

    def flat(name: str, matrix: sp.Matrix) -> tuple[tuple[str, sp.Expr], ...]:
        return tuple((f"{name}[{k}]", e.xreplace(rename)) for k, e in enumerate(matrix) if e != 0)

    return {
        "m": m,
        "constraint_entries": flat("g", pieces.g),
        "constraint_jacobian_entries": flat("Gq", pieces.jacobian),
        "constraint_rate_entries": flat("gt", pieces.rate),
        "constraint_hessian_entries": flat("Hg", pieces.contracted_hessian(lam)),
    }


def _contact_entries(system: LagrangianSystem, rename: dict) -> dict:
    r"""Entries of the contact point functions (empty without contacts).

    The gaps ``cg[j]`` :math:`= \varphi_j`, their gradients ``cG[j n + a]`` and Hessians
    ``cH[(j n + a) n + b]``; the slip velocities of every contact that declares them,
    stacked in the contacts' order (rows k), ``w[k]``, ``Wq[k n + a]`` :math:`=
    \partial w_k/\partial q_a`, ``Wv[k n + a]`` :math:`= \partial w_k/\partial v_a` and
    ``Wvq[(k n + a) n + b]`` :math:`= \partial^2 w_k/\partial v_a\partial q_b`.
    """
    if not system.contacts:
        return {}
    q, v, n = system.q, system.v, system.n
    gaps, grads, hessians = [], [], []
    for j, contact in enumerate(system.contacts):
        gap = contact.gap
        gaps.append((f"cg[{j}]", gap))
        for a in range(n):
            derivative = sp.diff(gap, q[a])
            grads.append((f"cG[{j * n + a}]", derivative))
            for b in range(n):
                hessians.append((f"cH[{(j * n + a) * n + b}]", sp.diff(derivative, q[b])))
    values, by_q, by_v, mixed = [], [], [], []
    k = 0
    for contact in system.contacts:
        for w in contact.slip or ():
            values.append((f"w[{k}]", w))
            for a in range(n):
                by_q.append((f"Wq[{k * n + a}]", sp.diff(w, q[a])))
                by_v.append((f"Wv[{k * n + a}]", sp.diff(w, v[a])))
                for b in range(n):
                    mixed.append((f"Wvq[{(k * n + a) * n + b}]", sp.diff(w, v[a], q[b])))
            k += 1

    def renamed(entries):
        return tuple((target, e.xreplace(rename)) for target, e in entries if e != 0)

    return {
        "contact_entries": renamed(gaps + grads + hessians),
        "slip_entries": renamed(values + by_q + by_v + mixed),
    }


def signature(spec: KernelSpec, backend: str, backend_version: str) -> str:
    """SHA-256 naming the cache entry of ``spec`` for ``backend`` at ``backend_version``.

    The expressions, the generator's version and Python's version: the loops
    are not part of it (they are cached once per machine, apart).
    """
    h = hashlib.sha256()
    for part in (
        GENERATOR_VERSION,
        backend,
        backend_version,
        sys.version,
        repr((spec.n, spec.n_params, spec.autonomous, spec.has_Lqv, spec.banded, spec.has_fv)),
        repr(
            (
                spec.half_bandwidth,
                spec.pattern,
                spec.m,
                spec.periodic,
                spec.separable,
                spec.diagonal_mass,
                spec.generated_loops,
                spec.repeated_loop,
            )
        ),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.constraint_parts),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.contact_entries + spec.slip_entries),
        sp.srepr(spec.lagrangian),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.hessian_entries),
        # every generated function's entries: a spec of derivatives in the parameters
        # (:func:`parameter_derivative_spec`) has gradient entries only
        *(f"{k}={sp.srepr(e)}" for k, e in spec.gradient_entries),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.mass_entries),
        *(f"{k}={sp.srepr(e)}" for k, e in spec.velocity_entries),
        *(_group_text(group) for group in spec.repeats),
        # the generated stage-form loop inlines the shared loop's stopping rule: compiled
        # anew with every version of the loops
        *((_loop_version(),) if backend == "numba" and has_stage_steps(spec) else ()),
    ):
        h.update(part.encode())
        h.update(b"\0")
    return h.hexdigest()


def _loop_version() -> str:
    """The name of the loops' cache folder: a hash of their sources, numba's and Python's."""
    from ..loops import loop_cache_dir

    return loop_cache_dir().name


def has_stage_steps(spec: KernelSpec) -> bool:
    """Whether the point module of ``spec`` holds the generated stage-form loop
    (:mod:`.stage_steps`): a system with the generated explicit loop and a diagonal M."""
    return spec.generated_loops and spec.diagonal_mass


def _group_text(group: ScatterGroup) -> str:
    """What names a scatter group in the cache key: its expressions and tables."""
    h = hashlib.sha256(group.table.tobytes() + group.slots.tobytes())
    # the template's expressions by their structural pickles: the same bytes in every
    # process, and cheaper than srepr, which sorts the terms of every sum
    for a, e in group.entries:
        h.update(a.encode() + b"=" + _expression_bytes(e) + b";")
    h.update(_expression_bytes(group.value))
    return f"{group.name}:{group.reads}:{group.table.shape}:{h.hexdigest()}"


def _expression_bytes(e: sp.Expr) -> bytes:
    """``e`` as bytes that name it (:func:`~galerkin_vi.expression_walk.structural_bytes`)."""
    return structural_bytes(e)
