r"""Rigid bodies of :mod:`sympy.physics.mechanics` oriented by quaternions or direction cosines.

A ``LagrangesMethod`` whose bodies hang on frames oriented by a quaternion of
coordinates (``B.orient_quaternion(N, (q0, q1, q2, q3))``) or by nine direction
cosines (``B.orient_explicit(N, Matrix(3, 3, r))``) is an *embedded* rigid-body
model (:mod:`.body`): redundant coordinates that describe a rotation only on a
constraint manifold. As written by mechanics it is singular, and the manifold is
unknown to the integrator. :func:`embedded_model` completes it the way
:class:`~galerkin_vi.RigidBody` is built:

**Quaternions.** Mechanics writes :math:`\omega = 2G(\mathsf q)\dot{\mathsf q}` and
:math:`T_{\text{rot}} = 2\dot{\mathsf q}^\top G^\top J G\dot{\mathsf q}`, singular along
:math:`\mathsf q`. Added: the constraint :math:`(|\mathsf q|^2 - 1)/2 = 0` and the term

.. math::

    \tfrac{c}{2}(\mathsf q^\top\dot{\mathsf q})^2, \qquad c = \tfrac43\operatorname{tr} J,

with :math:`J` the sum of the central inertias of the bodies the quaternion turns,
which vanishes to second order on the manifold and makes
:math:`\partial^2 L/\partial\dot{\mathsf q}^2` regular (:mod:`.body`). For a free body the result is
:class:`~galerkin_vi.RigidBody` ``(rotation="quaternion")`` term by term.

**Direction cosines.** With :math:`R` (body → parent) the coordinates' matrix,
mechanics derives the space angular velocity from three entries of
:math:`M = \dot R R^\top`, :math:`\omega_s = (M_{32}, M_{13}, M_{21})`, so
:math:`T_{\text{rot}} = \tfrac12\omega_s^\top R J R^\top\omega_s` has rank 3 in the nine
velocities: its kernel is not the normal space :math:`\{R S: S = S^\top\}` of
:math:`SO(3)` (for symmetric :math:`S`, :math:`R S R^\top` has nonzero entries
:math:`M_{32}, M_{13}, M_{21}`), so the constraint alone leaves the Lagrangian
singular. Added: the six constraints of the upper triangle of :math:`(R^\top R - I)/2`
and either

- for a body whose frame is oriented directly relative to the inertial frame, the
  replacement of its rotational energy by the constant-mass-matrix form of
  :class:`~galerkin_vi.RigidBody` ``(rotation="matrix")``,
  :math:`T_{\text{rot}} \to \tfrac12\operatorname{tr}(\dot R J_d\dot R^\top)` with
  :math:`J_d = \tfrac12\operatorname{tr}(J) I - J` (equal on the tangent bundle of
  :math:`SO(3)`, where :math:`\dot R = R\hat\omega`), plus the term below when
  :math:`J_d` is not positive definite;
- otherwise the term :math:`\tfrac c2\|\operatorname{sym}(R^\top\dot R)\|_F^2`,
  :math:`c = \tfrac23\operatorname{tr} J`. It is zero on the tangent bundle, and the sum is
  positive definite: with :math:`\dot R = R(\hat w + S)`, :math:`S` symmetric, it is
  zero only if :math:`S = 0` and then :math:`T_{\text{rot}} = \tfrac12 w^\top J w = 0`
  forces :math:`w = 0`.

Either way the Lagrangian changes only off the tangent bundle of the
constraint manifold, where the constrained dynamics does not look (the
Euler–Lagrange equations with multipliers depend on :math:`L` restricted to
:math:`TM`), so the continuous motion is the mechanics model's; the discrete one
agrees to the method's order.

**Detection.** The frames of the rigid bodies in ``lm.bodies`` are walked to the
inertial frame through SymPy's orientation records; each step's direction cosine
matrix :math:`D` (child → parent) is classified by the coordinates it holds:

- homogeneous quadratic in :math:`k \le 4` coordinates :math:`e` with
  :math:`D^\top D = |e|^4 I` identically: a quaternion (``orient_quaternion``, in any
  order and signs of its components, or composed with a constant rotation);
- linear in nine coordinates with an invertible constant Jacobian: direction cosines;
- anything else without coordinates, trigonometric in them (angles), or a polynomial
  with a constant part (a linearised rotation): left as it is;
- any other homogeneous polynomial in coordinates: refused with a message (the
  coordinates are redundant, and no normalisation is known).

Quaternions and direction-cosine matrices may also be given explicitly
(``quaternions=``, ``direction_cosines=``), which is the route for rotations that
no listed body hangs on; :math:`c` is then read from the Lagrangian itself
(:math:`c` from the trace of :math:`\partial^2 L/\partial\dot e^2` at the identity).

A normalisation the model already states in ``hol_coneqs`` (constraints in the
rotation's coordinates only that vanish on random rotations with the full rank)
is not added again.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp
from sympy.core.function import AppliedUndef

from ..model.mechanics import MechanicsModel, lagranges_method_model
from ..model.system import LagrangianSystem
from .rotations import quaternion_to_matrix, symbolic_quaternion_matrix

__all__ = [
    "MechanicsRotation",
    "embedded_model",
    "from_lagranges_method",
    "mechanics_rotations",
]

#: the kinds of embedded rotation coordinates
KINDS = ("quaternion", "matrix")


@dataclass(frozen=True)
class MechanicsRotation:
    r"""Rotation coordinates of a mechanics model and what embedding them adds.

    Attributes
    ----------
    kind : {"quaternion", "matrix"}
        Unit quaternion (up to 4 coordinates) or direction cosines (9 coordinates).
    coordinates : tuple of sympy.Expr
        The coordinate functions (dynamicsymbols) of the rotation.
    matrix : sympy.Matrix
        The rotation :math:`R` (child → parent) in the coordinates.
    frames : tuple of str
        Names of the frames oriented by these coordinates (empty when given
        explicitly and found on no body's frame).
    bodies : tuple of str
        Names of the rigid bodies these coordinates turn.
    augmentation_constant : sympy.Expr or None
        :math:`c` of the added term, ``None`` when none is added.
    constraints : tuple of sympy.Expr
        The normalisation constraints added (empty when the model states them).
    energy : sympy.Expr
        What is added to the Lagrangian: the augmentation, and for direction
        cosines the replacement of the rotational energy (module notes).
    """

    kind: str
    coordinates: tuple[sp.Expr, ...]
    matrix: sp.Matrix
    frames: tuple[str, ...]
    bodies: tuple[str, ...]
    augmentation_constant: sp.Expr | None
    constraints: tuple[sp.Expr, ...]
    energy: sp.Expr


@dataclass
class _Edge:
    """One orientation record (child frame relative to parent) and the bodies it turns."""

    child: Any
    parent: Any
    kind: str
    coordinates: tuple[sp.Expr, ...]
    matrix: sp.Matrix
    bodies: list[Any]


def from_lagranges_method(
    lm: Any,
    params: Mapping[sp.Symbol, float] | None = None,
    t: sp.Symbol | None = None,
    frame: Any = None,
    quaternions: Sequence[Sequence[sp.Expr]] | None = None,
    direction_cosines: Sequence[Any] | None = None,
) -> LagrangianSystem:
    r"""The system of a ``LagrangesMethod`` whose rigid bodies are oriented by quaternions
    or direction cosines: :func:`embedded_model`, rewritten into plain symbols.

    Parameters
    ----------
    lm : sympy.physics.mechanics.LagrangesMethod
        The model; give it ``bodies=`` and ``frame=`` so that its rotations are found.
    params, t
        As for :meth:`~galerkin_vi.LagrangianSystem.from_lagranges_method`.
    frame : sympy.physics.vector.ReferenceFrame, optional
        The inertial frame; defaults to ``lm.inertial``.
    quaternions : sequence of sequences of dynamicsymbols, optional
        Quaternions (scalar first, up to four coordinates each) to embed whether or
        not they are detected.
    direction_cosines : sequence of 3×3 matrices of dynamicsymbols, optional
        Rotation matrices (body → space) of nine coordinates to embed likewise.

    Returns
    -------
    LagrangianSystem
        ``q`` are plain symbols named like the coordinates
        (``system.mechanics_symbols`` holds the map); the normalisation
        constraints follow the model's ``hol_coneqs``.

    Raises
    ------
    ValueError
        If a frame's orientation is a polynomial in coordinates that is neither
        a quaternion nor direction cosines, if an explicit quaternion or matrix
        is malformed, or as for :meth:`LagrangianSystem.from_lagranges_method`.

    Examples
    --------
    >>> import sympy.physics.mechanics as me
    >>> import galerkin_vi as gvi
    >>> from galerkin_vi.multibody.mechanics import from_lagranges_method
    >>> e = me.dynamicsymbols("e0:4")
    >>> N, B = me.ReferenceFrame("N"), me.ReferenceFrame("B")
    >>> B.orient_quaternion(N, e)
    >>> O = me.Point("O"); O.set_vel(N, 0)
    >>> body = me.RigidBody("b", O, B, 1, (me.inertia(B, 1, 2, 3), O))
    >>> lm = me.LagrangesMethod(me.Lagrangian(N, body), e, bodies=[body], frame=N)
    >>> system = from_lagranges_method(lm)
    >>> system.n, system.m
    (4, 1)
    """
    return LagrangianSystem.from_lagranges_method(
        lm, params, t, frame, quaternions=quaternions, direction_cosines=direction_cosines
    )


def embedded_model(
    lm: Any,
    frame: Any = None,
    quaternions: Sequence[Sequence[sp.Expr]] | None = None,
    direction_cosines: Sequence[Any] | None = None,
) -> MechanicsModel:
    """The model of ``lm`` (:func:`~galerkin_vi.model.mechanics.lagranges_method_model`)
    with its rotation coordinates embedded: the energies and constraints of
    :func:`mechanics_rotations` added. Unchanged when there are none (Euler angles)."""
    model = lagranges_method_model(lm, frame)
    rotations = mechanics_rotations(lm, frame, quaternions, direction_cosines)
    if not rotations:
        return model
    L = model.L + sp.Add(*(r.energy for r in rotations))
    constraints = list(model.constraints or []) + [g for r in rotations for g in r.constraints]
    return MechanicsModel(L, model.q, constraints or None, model.forces)


def mechanics_rotations(
    lm: Any,
    frame: Any = None,
    quaternions: Sequence[Sequence[sp.Expr]] | None = None,
    direction_cosines: Sequence[Any] | None = None,
) -> tuple[MechanicsRotation, ...]:
    """The quaternions and direction cosines of ``lm`` (module notes), detected on the
    frames of its rigid bodies and given explicitly, with what embedding each adds.

    Raises
    ------
    ValueError
        As for :func:`from_lagranges_method`.
    """
    model = lagranges_method_model(lm, frame)
    root = lm.inertial if frame is None else frame
    coords = tuple(model.q)
    edges = _detected_edges(lm.bodies or (), root, coords)
    for j, e in enumerate(quaternions or ()):
        _merge(edges, _explicit_quaternion(e, j, coords))
    for j, R in enumerate(direction_cosines or ()):
        _merge(edges, _explicit_matrix(R, j, coords))
    return tuple(_rotation(edge, model, root) for edge in edges)


# ----------------------------------------------------------------- detection
def _detected_edges(bodies: Sequence[Any], root: Any, coords: tuple) -> list[_Edge]:
    """The orientation records between the rigid bodies' frames and ``root`` that hold
    embedded rotation coordinates, with the bodies each turns."""
    edges: list[_Edge] = []
    if root is None:
        return edges
    for body in bodies:
        frame = getattr(body, "frame", None)
        if frame is None:  # a Particle
            continue
        path = _path(frame, root)
        for child, parent in zip(path[:-1], path[1:], strict=True):
            edge = _classified(child, parent, coords)
            if edge is None:
                continue
            known = next((e for e in edges if e.child is child and e.parent is parent), None)
            if known is None:
                edges.append(edge)
                known = edge
            known.bodies.append(body)
    return edges


def _path(frame: Any, root: Any) -> list[Any]:
    """Frames from ``frame`` to ``root`` through SymPy's orientation records (breadth first)."""
    # SymPy 1.12-1.14 keep the direct orientation records only in _dcm_dict
    previous = {frame: None}
    queue = [frame]
    while queue:
        f = queue.pop(0)
        if f is root:
            path = [f]
            while previous[path[-1]] is not None:
                path.append(previous[path[-1]])
            return path[::-1]
        for g in f._dcm_dict:
            if g not in previous:
                previous[g] = f
                queue.append(g)
    raise ValueError(
        f"frame {frame} of a rigid body is not oriented relative to the inertial frame "
        f"{root}: orient it (directly or through other frames)"
    )


def _classified(child: Any, parent: Any, coords: tuple) -> _Edge | None:
    r"""The edge if ``parent.dcm(child)`` is a quaternion or direction cosines of coordinates.

    ``None`` for orientations by angles, by constant rotations, or by polynomials
    with a constant part (a linearised rotation :math:`I + \hat\theta`, say), which are
    converted as they are. An orientation homogeneous of one degree in its
    coordinates scales with them, so they are redundant and the kinetic energy is
    singular along the scaling: when it is not a quaternion or direction cosines,
    no normalisation is known and a ``ValueError`` says so.
    """
    D = parent.dcm(child)
    held = tuple(c for c in coords if D.has(c))
    if not held:
        return None
    dummies = sp.symbols(f"_e0:{len(held)}", real=True)
    Dp = D.xreplace(dict(zip(held, dummies, strict=True)))
    if not all(x.is_polynomial(*dummies) for x in Dp):
        return None  # angles: nothing to embed
    if _is_quaternion_matrix(Dp, dummies):
        return _Edge(child, parent, "quaternion", held, D, [])
    if _is_matrix_of_coordinates(Dp, dummies):
        return _Edge(child, parent, "matrix", held, D, [])
    degrees = {sp.Poly(x, *dummies).homogeneous_order() for x in Dp if x != 0}
    if None in degrees or 0 in degrees or len(degrees) != 1:
        return None
    raise ValueError(
        f"the orientation of {child} relative to {parent} is homogeneous of degree "
        f"{degrees.pop()} in the coordinates {', '.join(map(str, held))}, so they are "
        "redundant, but it is neither a quaternion (homogeneous quadratic with "
        "D^T D = |e|^4 I, as from orient_quaternion) nor a matrix of nine direction "
        "cosines (as from orient_explicit): galerkin_vi cannot tell which manifold holds "
        "them. Orient the frame by orient_quaternion or orient_explicit of coordinates, "
        "or by angles (orient_body_fixed)"
    )


def _is_quaternion_matrix(D: sp.Matrix, e: tuple) -> bool:
    if len(e) > 4:
        return False
    for x in D:
        if x != 0 and sp.Poly(x, *e).homogeneous_order() != 2:
            return False
    norm2 = sum(s**2 for s in e)
    return sp.expand(D.T * D - norm2**2 * sp.eye(3)).is_zero_matrix


def _is_matrix_of_coordinates(D: sp.Matrix, r: tuple) -> bool:
    if len(r) != 9:
        return False
    for x in D:
        if x != 0 and sp.Poly(x, *r).homogeneous_order() != 1:
            return False
    jac = sp.Matrix(list(D)).jacobian(r)
    return not jac.free_symbols and jac.det() != 0


def _explicit_quaternion(e: Any, j: int, coords: tuple) -> _Edge:
    entries = _coordinate_list(e, f"quaternions[{j}]", coords)
    if not 1 <= len(entries) <= 4:
        raise ValueError(
            f"quaternions[{j}] must list 4 coordinates (scalar first), got {len(entries)}"
        )
    full = list(entries) + [0] * (4 - len(entries))
    return _Edge(None, None, "quaternion", entries, symbolic_quaternion_matrix(full), [])


def _explicit_matrix(R: Any, j: int, coords: tuple) -> _Edge:
    try:
        M = sp.Matrix(R)
    except (TypeError, ValueError) as exc:
        raise TypeError(f"direction_cosines[{j}] must be a 3x3 matrix of coordinates") from exc
    if M.shape != (3, 3):
        raise ValueError(
            f"direction_cosines[{j}] must be a 3x3 matrix of coordinates, got shape {M.shape}"
        )
    entries = _coordinate_list(list(M), f"direction_cosines[{j}]", coords)
    return _Edge(None, None, "matrix", entries, M, [])


def _coordinate_list(entries: Any, name: str, coords: tuple) -> tuple[sp.Expr, ...]:
    try:
        out = tuple(entries)
    except TypeError as exc:
        raise TypeError(f"{name} must be a sequence of coordinates of lm.q") from exc
    for x in out:
        if x not in coords:
            raise ValueError(
                f"{name} holds {x}, which is not a coordinate of lm.q "
                f"({', '.join(map(str, coords))})"
            )
    if len(set(out)) != len(out):
        raise ValueError(f"{name} repeats a coordinate")
    return out


def _merge(edges: list[_Edge], explicit: _Edge) -> None:
    """Add an explicitly given rotation unless a detected one has the same coordinates."""
    for edge in edges:
        if set(edge.coordinates) == set(explicit.coordinates):
            if edge.kind != explicit.kind:
                raise ValueError(
                    f"{', '.join(map(str, explicit.coordinates))} are given as a "
                    f"{explicit.kind} but orient {edge.child} as a {edge.kind}"
                )
            return
        if set(edge.coordinates) & set(explicit.coordinates):
            raise ValueError(
                f"the explicit {explicit.kind} {', '.join(map(str, explicit.coordinates))} "
                f"shares coordinates with the {edge.kind} that orients {edge.child}"
            )
    edges.append(explicit)


# ----------------------------------------------------------------- embedding
def _rotation(edge: _Edge, model: MechanicsModel, root: Any) -> MechanicsRotation:
    e = edge.coordinates
    time = e[0].args[0]
    ed = [c.diff(time) for c in e]
    R = edge.matrix
    constraints = _normalisation(edge, model)
    trace = sp.Add(*(_central_inertia(b).trace() for b in edge.bodies))
    energy = sp.S.Zero
    if edge.kind == "quaternion":
        c = sp.Rational(4, 3) * trace if edge.bodies else _hessian_constant(edge, model)
        energy = c / 2 * sp.Add(*(x * xd for x, xd in zip(e, ed, strict=True))) ** 2
        return _record(edge, c, constraints, energy)
    Rd = R.diff(time)
    replaced = [b for b in edge.bodies if b.frame is edge.child and edge.parent is root]
    J_sum = sp.zeros(3, 3)
    for body in replaced:
        J = _central_inertia(body)
        Jd = J.trace() / 2 * sp.eye(3) - J
        J_sum += Jd
        energy += (Rd * Jd * Rd.T).trace() / 2 - _mechanics_rotational_energy(body, root)
    if replaced and len(replaced) == len(edge.bodies) and _positive_definite(J_sum):
        return _record(edge, None, constraints, energy)
    c = sp.Rational(2, 3) * trace if edge.bodies else _hessian_constant(edge, model)
    W = R.T * Rd
    S = (W + W.T) / 2
    energy += c / 2 * sp.Add(*(x**2 for x in S))
    return _record(edge, c, constraints, energy)


def _record(edge: _Edge, c, constraints, energy) -> MechanicsRotation:
    frames = () if edge.child is None else (str(edge.child),)
    bodies = tuple(str(b.name) for b in edge.bodies)
    return MechanicsRotation(
        edge.kind, edge.coordinates, edge.matrix, frames, bodies, c, constraints, energy
    )


def _central_inertia(body: Any) -> sp.Matrix:
    """The inertia about the mass centre in the body's frame (its trace is frame-free)."""
    return body.central_inertia.to_matrix(body.frame)


def _mechanics_rotational_energy(body: Any, root: Any) -> sp.Expr:
    r""":math:`\tfrac12\omega\cdot I\omega` exactly as ``RigidBody.kinetic_energy`` writes it."""
    w = body.frame.ang_vel_in(root)
    return sp.S.Half * w.dot(body.central_inertia.dot(w))


def _positive_definite(M: sp.Matrix) -> bool:
    if M.free_symbols:
        return False  # not decidable for every parameter value: keep the augmentation
    values = np.linalg.eigvalsh(np.array(M, dtype=float))
    return bool(values.min() > 1e-12 * max(1.0, float(abs(values).max())))


def _hessian_constant(edge: _Edge, model: MechanicsModel) -> sp.Expr:
    r"""The augmentation constant read from the Lagrangian when no body is known.

    :math:`c = \tfrac13\operatorname{tr}\partial^2 L/\partial\dot e^2` (quaternion) or
    :math:`\tfrac23\operatorname{tr}\partial^2 L/\partial\dot R^2` (direction cosines) at the
    identity rotation, every other coordinate, every velocity and time zero: for a
    single free body these are :math:`\tfrac43\operatorname{tr}J` and
    :math:`\tfrac23\operatorname{tr}J`, the constants of :class:`~galerkin_vi.RigidBody`.
    """
    e = edge.coordinates
    time = e[0].args[0]
    trace = sp.Add(*(model.L.diff(x.diff(time), 2) for x in e))
    at = {c.diff(time): 0 for c in model.q}
    values = dict.fromkeys(model.q, 0)
    if edge.kind == "quaternion":
        values[e[0]] = 1
    else:
        values.update(_matrix_values(edge, np.eye(3)))
    c = trace.xreplace(at).xreplace(values).subs(time, 0)
    c = sp.nsimplify(c) if not c.free_symbols else sp.simplify(c)
    c = c / 3 if edge.kind == "quaternion" else 2 * c / 3
    if not c.free_symbols and not c > 0:
        raise ValueError(
            f"the kinetic energy of the {edge.kind} {', '.join(map(str, e))} is not positive "
            "at the identity rotation: no augmentation constant can be read from it"
        )
    return c


def _normalisation(edge: _Edge, model: MechanicsModel) -> tuple[sp.Expr, ...]:
    """The constraints to add: the normalisation, unless ``hol_coneqs`` states it."""
    e = edge.coordinates
    if edge.kind == "quaternion":
        ours = ((sp.Add(*(x**2 for x in e)) - 1) / 2,)
    else:
        R = edge.matrix
        C = (R.T * R - sp.eye(3)) / 2
        ours = tuple(C[i, j] for i in range(3) for j in range(i, 3))
    own = [g for g in model.constraints or [] if _only_of(g, e)]
    if not own:
        return ours
    rank = _rank_on_rotations(edge, own)
    if rank is None:
        return ours  # they restrict the rotation further: the normalisation still holds
    if rank == len(ours) == len(own):
        return ()
    raise ValueError(
        f"hol_coneqs states {len(own)} constraints on the {edge.kind} "
        f"{', '.join(map(str, e))} that hold on every rotation with rank {rank}, not the "
        f"{len(ours)} independent normalisation constraints: state all of them "
        f"(e.g. {ours[0]} = 0) or none (galerkin_vi adds them)"
    )


def _only_of(g: sp.Expr, e: tuple) -> bool:
    """Whether ``g`` depends on the coordinates ``e`` and on nothing else but time."""
    return (
        g.has(*e) and not (g.atoms(AppliedUndef) - set(e)) and not g.free_symbols - {e[0].args[0]}
    )


def _rank_on_rotations(edge: _Edge, constraints: list[sp.Expr]) -> int | None:
    """The rank of ``constraints`` on random rotations if they vanish there, else ``None``."""
    e = edge.coordinates
    time = e[0].args[0]
    g = sp.Matrix(constraints)
    jac = g.jacobian(e)
    rng = np.random.default_rng(29)
    ranks = []
    for _ in range(3):
        values = dict(_random_rotation_values(edge, rng))
        # coordinates first: substituting the time first would turn r(t) into r(0)
        residual = np.array(g.xreplace(values).subs(time, 0), dtype=float)
        if np.abs(residual).max() > 1e-9:
            return None
        jac_value = np.array(jac.xreplace(values).subs(time, 0), dtype=float)
        ranks.append(np.linalg.matrix_rank(jac_value, 1e-9))
    return int(min(ranks))


def _random_rotation_values(edge: _Edge, rng: np.random.Generator) -> dict[sp.Expr, float]:
    if edge.kind == "quaternion":
        q = rng.normal(size=len(edge.coordinates))
        return dict(zip(edge.coordinates, q / np.linalg.norm(q), strict=True))
    q = rng.normal(size=4)
    return _matrix_values(edge, quaternion_to_matrix(q / np.linalg.norm(q)))


def _matrix_values(edge: _Edge, R: np.ndarray) -> dict[sp.Expr, float]:
    """Coordinate values for which ``edge.matrix`` is ``R`` (it is linear in them)."""
    r = edge.coordinates
    jac = np.array(sp.Matrix(list(edge.matrix)).jacobian(r), dtype=float)
    values = np.linalg.solve(jac, R.ravel())
    return {x: float(v) for x, v in zip(r, values, strict=True)}
