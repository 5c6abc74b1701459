"""Ensembles: many initial states or parameter sets, run in parallel.

A member is what one :meth:`Integrator.integrate` call would compute, bitwise.
Runs of one compiled call (at most :data:`~galerkin_vi.run.chunks.FIRST_CHUNK`
steps, no events, dense output or ``t_eval``) go through
:func:`galerkin_vi.loops.members.members_loop`: the initial Legendre
transforms in Python, then blocks of members each in one compiled call of the
same loop a single run calls, in threads at once (the loops release the GIL).
A member that fails, or whose growth or momenta need the one-by-one run's
checks, is run again by :meth:`~Integrator.integrate`, which gives its status,
message and warnings. Other runs are one ``integrate`` call per member, in
threads.

Any :class:`concurrent.futures.Executor` can be given instead of the threads:
a process pool, or Dask's ``Client.get_executor()``. Blocks of members are sent
as (system, method, starts, parameters); each worker process builds the
integrator once, loading its point functions and loops from the user cache
directory (:func:`compile_statistics` shows the cache hits). Parameter values
are run-time data: a sweep never compiles.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import cached_property
from typing import Any

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from ..reference import numpy as numpy_backend
from .chunks import single_call
from .failures import check_failure_mode
from .plan import run_plan
from .spec import RunSpec
from .start import initial_state
from .trajectory import Trajectory
from .trust import checks_instability, momenta_grew, within_growth_bound

__all__ = [
    "Ensemble",
    "compile_statistics",
    "integrate_many",
    "member_parameters",
    "member_starts",
]

#: keyword arguments of a run that the compiled member loop takes (others: one by one)
COMPILED_RUN = frozenset({"h", "n_steps", "t0", "t_span", "save_every", "on_failure", "progress"})
#: the run options of the tangent map (:mod:`galerkin_vi.run.tangent`), which a compiled
#: member loop of their own takes
VARIATIONS = frozenset({"tangent", "sensitivity", "renormalize_every"})
#: blocks per thread: members differ in their iteration counts, so blocks balance the load
BLOCKS_PER_WORKER = 4


@dataclass(frozen=True, eq=False)
class Ensemble:
    """The members' trajectories, and their states stacked when they line up.

    Attributes
    ----------
    t : ndarray, shape (N,) or None
        The common saved times, when every member saved the same ones.
    q, p : ndarray, shape (m, N, n) or None
        Stacked positions and momenta (None when the members differ in length,
        e.g. after a failure or a terminal event).
    success : ndarray of bool, shape (m,)
        Each member's ``Trajectory.success``.
    status : ndarray of int, shape (m,)
        Each member's ``Trajectory.status``.
    trajectories : list of Trajectory
        One per member (built on first access from the stacked arrays).
    """

    t: NDArray[np.float64] | None
    q: NDArray[np.float64] | None
    p: NDArray[np.float64] | None
    success: NDArray[np.bool_]
    status: NDArray[np.int64]
    member: Callable[[int], Trajectory] = field(repr=False)

    def __len__(self) -> int:
        return len(self.success)

    def __getitem__(self, i: int) -> Trajectory:
        return self.trajectories[i]

    @cached_property
    def trajectories(self) -> list[Trajectory]:
        return [self.member(i) for i in range(len(self))]

    @classmethod
    def of(cls, trajectories: list[Trajectory]) -> Ensemble:
        first = trajectories[0]
        same = all(len(tr) == len(first) and np.array_equal(tr.t, first.t) for tr in trajectories)
        return cls(
            t=first.t if same else None,
            q=np.stack([tr.q for tr in trajectories]) if same else None,
            p=np.stack([tr.p for tr in trajectories]) if same else None,
            success=np.array([tr.success for tr in trajectories]),
            status=np.array([int(tr.status) for tr in trajectories]),
            member=trajectories.__getitem__,
        )


def member_parameters(
    params: Mapping[sp.Symbol | str, ArrayLike] | Sequence[Mapping] | None, m: int
) -> list[Mapping | None]:
    """Per-member parameter mappings from one mapping of scalars or length-m arrays,
    or from a sequence of m mappings."""
    if params is None:
        return [None] * m
    if isinstance(params, Mapping):
        columns = _parameter_columns(params, m)
        return [{key: float(col[i]) for key, col in columns.items()} for i in range(m)]
    members = list(params)
    if len(members) != m:
        raise ValueError(f"params must hold one mapping per member ({m}), got {len(members)}")
    return members


def _parameter_columns(params: Mapping, m: int) -> dict:
    """One array of m values per parameter: numbers repeated, arrays checked."""
    columns = {}
    for key, value in params.items():
        arr = np.asarray(value, dtype=float)
        if arr.ndim == 0:
            arr = np.full(m, float(arr))
        if arr.shape != (m,):
            raise ValueError(
                f"params[{key}] must be a number or an array of one value per member "
                f"({m}), got shape {arr.shape}"
            )
        columns[key] = arr
    return columns


def member_starts(q0s: ArrayLike, v0s, p0s, n: int) -> tuple[NDArray, str, NDArray]:
    """(q (m, n), "v0" or "p0", velocities or momenta (m, n)) of the members, single rows
    repeated for every member."""
    if (v0s is None) == (p0s is None):
        raise ValueError("give exactly one of v0s and p0s")
    name = "v0" if v0s is not None else "p0"
    q = np.atleast_2d(np.asarray(q0s, dtype=float))
    x = np.atleast_2d(np.asarray(v0s if v0s is not None else p0s, dtype=float))
    if q.ndim != 2 or q.shape[1] != n:
        raise ValueError(f"q0s must have shape (m, {n}), got {np.shape(q0s)}")
    if x.shape == (1, n) and q.shape[0] > 1:
        x = np.repeat(x, q.shape[0], axis=0)
    if q.shape[0] == 1 and x.shape[0] > 1:
        q = np.repeat(q, x.shape[0], axis=0)
    if x.shape != q.shape:
        raise ValueError(f"{name}s must have shape {q.shape} (or ({n},)), got {np.shape(x)}")
    return q, name, x


def integrate_many(
    integrator: Any,  # an Integrator (which imports this module)
    q0s: ArrayLike,
    v0s: ArrayLike | None = None,
    p0s: ArrayLike | None = None,
    *,
    params=None,
    executor: Executor | None = None,
    workers: int | None = None,
    **run,
) -> Ensemble:
    """Integrate every member; see :meth:`Integrator.integrate_many`."""
    q, name, x = member_starts(q0s, v0s, p0s, integrator.system.n)
    run.setdefault("progress", False)
    workers = workers or os.cpu_count() or 1
    if executor is not None:
        return _on_executor(executor, integrator, q, name, x, params, run, workers)
    if VARIATIONS & set(run):
        if _compiled_with_variations(integrator, run):
            return _members_with_variations(integrator, q, name, x, params, run, workers)
    elif _compiled(integrator, run):
        return _compiled_members(integrator, q, name, x, params, run, workers)
    # one by one on threads: the compiled loops release the GIL
    return _one_by_one(integrator, q, name, x, params, run, workers)


def _compiled_with_variations(integrator, run: dict) -> bool:
    """Whether runs with the tangent map can go through the compiled member loop."""
    if integrator.backend != "numba" or integrator.system.contacts:
        return False
    if not (COMPILED_RUN | VARIATIONS).issuperset(run):
        return False
    plan = run_plan(
        run.get("h"), run.get("n_steps"), run.get("t_span"), run.get("t0", 0.0),
        run.get("save_every", 1),
    )  # fmt: skip
    return single_call(plan.n_steps, plan.save_every)


def _members_with_variations(integrator, q, name, x, params, run, workers) -> Ensemble:
    """The members with the tangent map in blocks of one compiled call each
    (:func:`galerkin_vi.run.tangent.members_with_variations`); a member that fails or
    grows explosively runs again one by one, which reports it."""
    from .tangent import initial_sensitivity, members_with_variations, variation_request

    check_failure_mode(run.get("on_failure", "warn"))
    system = integrator.system
    request = variation_request(
        system, run.get("tangent"), run.get("sensitivity"), run.get("renormalize_every", 0)
    )
    if request is None or integrator.tangent_run_spec.path == "explicit":
        # the explicit tangent loop has no member loop: each member is one integrate call
        return _one_by_one(integrator, q, name, x, params, run, workers)
    plan = run_plan(
        run.get("h"), run.get("n_steps"), run.get("t_span"), run.get("t0", 0.0),
        run.get("save_every", 1),
    )  # fmt: skip
    spec = integrator.tangent_run_spec
    m = q.shape[0]
    prms = parameter_matrix(system, params, m)
    q0s, p0s, v0s = initial_states(spec, q, name, x, plan.t0, prms)
    starts = None
    if name == "v0" and request.parameters:
        starts = np.stack([
            initial_sensitivity(system, request.parameters, plan.t0, q0s[i], v0s[i], prms[i])
            for i in range(m)
        ])  # fmt: skip
    members = members_with_variations(
        spec, request, q0s, p0s, v0s, plan.t0, plan.h, plan.n_steps, plan.save_every, prms,
        starts, workers,
    )  # fmt: skip
    again = member_parameters(params, m)
    trajectories = []
    for i, (traj, result) in enumerate(members):
        grown = not within_growth_bound(traj.q[:1], traj.p[:1], traj.q[-1:], traj.p[-1:])
        if result.status != 0 or grown:
            traj = integrator.integrate(q[i], **{name: x[i]}, params=again[i], **run)
        trajectories.append(traj)
    return Ensemble.of(trajectories)


def _one_by_one(integrator, q, name, x, params, run, workers) -> Ensemble:
    """Every member by its own :meth:`Integrator.integrate`, on threads."""
    members = member_parameters(params, q.shape[0])
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = [
            pool.submit(integrator.integrate, q[i], **{name: x[i]}, params=members[i], **run)
            for i in range(q.shape[0])
        ]
        return Ensemble.of([f.result() for f in futures])


def _compiled(integrator, run: dict) -> bool:
    """Whether the members' runs can go through the compiled member loop."""
    if integrator.backend != "numba" or integrator.kernel_path == "explicit":
        return False  # the explicit loop's mass matrix depends on the parameters
    if not COMPILED_RUN.issuperset(run):
        return False  # events, dense output, t_eval, project: one integrate per member
    plan = run_plan(
        run.get("h"), run.get("n_steps"), run.get("t_span"), run.get("t0", 0.0),
        run.get("save_every", 1),
    )  # fmt: skip
    return single_call(plan.n_steps, plan.save_every)


@dataclass
class MemberOutputs:
    """What the member loop writes: one row per member of a run's outputs."""

    t: NDArray[np.float64]
    q: NDArray[np.float64]
    p: NDArray[np.float64]
    turns: NDArray[np.float64]
    iterations: NDArray[np.uint8]
    totals: NDArray[np.int64]
    results: NDArray[np.float64]

    @classmethod
    def allocate(cls, m: int, n_steps: int, save_every: int, n: int, periodic: bool):
        n_saved = n_steps // save_every + 1 + (1 if n_steps % save_every else 0)
        return cls(
            t=np.empty((m, n_saved)),
            q=np.empty((m, n_saved, n)),
            p=np.empty((m, n_saved, n)),
            turns=np.zeros((m, n_saved if periodic else 1, n)),
            iterations=np.zeros((m, -(-n_steps // save_every)), dtype=np.uint8),
            totals=np.zeros((m, 1), dtype=np.int64),
            results=np.zeros((m, 5)),
        )

    @classmethod
    def joined(cls, parts: list[MemberOutputs]) -> MemberOutputs:
        """The outputs of consecutive blocks of members as one."""
        names = ("t", "q", "p", "turns", "iterations", "totals", "results")
        return cls(**{k: np.concatenate([getattr(part, k) for part in parts]) for k in names})

    def rows(self, block: slice) -> tuple:
        """The member loop's output arguments for the members of ``block``."""
        return (
            self.t[block], self.q[block], self.p[block], self.turns[block],
            self.iterations[block], self.totals[block], self.results[block],
        )  # fmt: skip


def _compiled_members(integrator, q, name, x, params, run, workers) -> Ensemble:
    """The members through :func:`~galerkin_vi.loops.members.members_loop`, in blocks."""
    out, prms = member_outputs(integrator, q, name, x, params, run, workers)
    return _ensemble(integrator, out, q, name, x, params, run, prms)


def member_outputs(integrator, q, name, x, params, run, workers) -> tuple[MemberOutputs, NDArray]:
    """The compiled loops' outputs of the members, and their parameter vectors.

    What an executor's worker computes for a block of members: arrays only, which
    travel cheaply; the trajectories are made where the ensemble is assembled.
    """
    check_failure_mode(run.get("on_failure", "warn"))
    system = integrator.system
    h, n_steps, t0, save_every = run_plan(
        run.get("h"), run.get("n_steps"), run.get("t_span"), run.get("t0", 0.0),
        run.get("save_every", 1),
    )  # fmt: skip
    from ..loops.readiness import ensure_loops

    # before the compiled Legendre transforms of the members' starts load their loop
    ensure_loops()
    spec = integrator.run_spec
    m, n = q.shape
    prms = parameter_matrix(system, params, m)
    q0s, p0s, v0s = initial_states(spec, q, name, x, t0, prms)
    periodic = any(system.periodic)
    out = MemberOutputs.allocate(m, n_steps, save_every, n, periodic)
    fixed = (t0, h, n_steps, save_every)

    def block(rows: slice) -> None:
        from ..loops.members import members_loop

        loop, before, after = spec.loop_parts()  # work space of its own per block
        switches = [loop.__name__ == kind for kind in _LOOP_NAMES]
        members_loop(
            *(True if on else None for on in switches), before,
            q0s[rows], p0s[rows], v0s[rows], *fixed, prms[rows], after, *out.rows(rows),
        )  # fmt: skip

    blocks = _blocks(m, workers)
    if workers == 1 or len(blocks) == 1:
        for rows in blocks:
            block(rows)
    else:
        with ThreadPoolExecutor(max_workers=workers) as pool:
            for future in [pool.submit(block, rows) for rows in blocks]:
                future.result()
    return out, prms


def parameter_matrix(system, params, m: int) -> NDArray[np.float64]:
    """The members' parameter vectors, shape (m, P), as :meth:`LagrangianSystem.parameter_vector`
    gives them one by one (same values, same errors)."""
    if params is None or (isinstance(params, Mapping) and not params):
        return np.tile(system.parameter_vector(None), (m, 1))
    if not isinstance(params, Mapping):
        members = member_parameters(params, m)
        return np.array([system.parameter_vector(p) for p in members]).reshape(m, -1)
    columns = _parameter_columns(params, m)
    # keys and the first member's values checked as one run checks them
    prms = np.tile(system.parameter_vector({k: col[0] for k, col in columns.items()}), (m, 1))
    index = {s: i for i, s in enumerate(system.params)}
    index.update({str(s): i for i, s in enumerate(system.params)})
    for key, col in columns.items():
        if not np.isfinite(col).all():
            raise ValueError(f"params[{key}] must be finite, got {col[~np.isfinite(col)][0]!r}")
        prms[:, index[key]] = col
    return prms


def initial_states(spec: RunSpec, q, name, x, t0, prms) -> tuple[NDArray, NDArray, NDArray]:
    """(q0s, p0s, v0s) of the members, as :meth:`Integrator.integrate` finds them.

    The momenta of given velocities (and the velocities of given momenta when L
    is quadratic in v) of all members in one compiled call and a batched
    regularity test; a member that fails either (a singular L_vv, values not
    finite), and every member of a constrained system (projections), goes the
    one-by-one way, which gives its error.
    """
    system = spec.system
    m, n = q.shape
    q0s, p0s, v0s = q.copy(), np.empty((m, n)), np.empty((m, n))
    done = np.zeros(m, dtype=bool)
    fast = spec.legendre
    quadratic = system.structure.quadratic_in_v
    if fast is not None and not system.m and (name == "v0" or quadratic):
        fn = spec.model[0]
        finite = np.isfinite(q).all(axis=1) & np.isfinite(x).all(axis=1)
        v = x if name == "v0" else np.zeros((m, n))
        Lv, Lvv, regular = fast.many(fn, t0, q, v, prms)
        done = finite & regular
        if name == "v0":
            p0s[:], v0s[:] = Lv, x
        else:
            p0s[:] = x
            v0s[done] = np.linalg.solve(Lvv[done], (x[done] - Lv[done])[..., None])[..., 0]
        done &= np.isfinite(p0s).all(axis=1) & np.isfinite(v0s).all(axis=1)
    for i in np.flatnonzero(~done):
        q0s[i], p0s[i], v0s[i] = initial_state(
            spec, q[i], *((x[i], None) if name == "v0" else (None, x[i])), t0, prms[i]
        )
    return q0s, p0s, v0s


#: the loops members_loop switches between, in its argument order
_LOOP_NAMES = (
    "general_loop",
    "stage_form_loop",
    "linear_loop",
    "constrained_loop",
    "varying_mass_loop",
)


def _blocks(m: int, workers: int) -> list[slice]:
    count = max(1, min(m, workers * BLOCKS_PER_WORKER))
    edges = np.linspace(0, m, count + 1).round().astype(int)
    return [slice(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _ensemble(integrator, out: MemberOutputs, q, name, x, params, run, prms) -> Ensemble:
    """The members' trajectories; those that need the one-by-one run's checks get it."""
    system, order = integrator.system, integrator.method.order
    status = out.results[:, 0].astype(np.int64)
    q_reduced = out.q if any(system.periodic) else None
    q_all = numpy_backend.unwrapped(out.q, out.turns) if q_reduced is not None else out.q
    redo = (status != 0) | _explosive_ends(q_all, out.p) | _momenta_grew(system, out.p)
    members = member_parameters(params, len(status)) if redo.any() else []
    again = {
        int(i): integrator.integrate(q[i], **{name: x[i]}, params=members[i], **run)
        for i in np.flatnonzero(redo)
    }

    def member(i: int) -> Trajectory:
        if i in again:
            return again[i]
        return Trajectory(
            t=out.t[i],
            q=q_all[i],
            q_reduced=None if q_reduced is None else q_reduced[i],
            p=out.p[i],
            newton_iterations=out.iterations[i],
            total_newton_iterations=int(out.totals[i, 0]),
            n_steps=int(out.results[i, 1]),
            max_residual=float(out.results[i, 3]),
            system=system,
            params=prms[i],
            order=order,
        )

    if not again or all(tr.success for tr in again.values()):
        # every member completed: all rows saved, at the same times
        return Ensemble(
            t=out.t[0],
            q=q_all,
            p=out.p,
            success=np.ones(len(status), dtype=bool),
            status=np.zeros(len(status), dtype=np.int64),
            member=member,
        )
    return Ensemble.of([member(i) for i in range(len(status))])


def _explosive_ends(q: NDArray, p: NDArray) -> NDArray[np.bool_]:
    """Members whose last state is past the growth bound of their first (as integrate)."""
    return ~within_growth_bound(q[:, :1], p[:, :1], q[:, -1:], p[:, -1:])


def _momenta_grew(system, p: NDArray) -> NDArray[np.bool_]:
    """Members that integrate() would warn about (:func:`~galerkin_vi.run.trust.momenta_grew`)."""
    if not checks_instability(system, p.shape[1]):
        return np.zeros(p.shape[0], dtype=bool)
    return momenta_grew(p)


def _on_executor(executor, integrator, q, name, x, params, run, workers) -> Ensemble:
    """Blocks of members on ``executor``, each a compiled ensemble in a worker process."""
    spec = (
        type(integrator),
        integrator.system, integrator.method, integrator.backend, integrator.tol,
        integrator.maxiter, integrator.specialize, integrator.fixed_point,
    )  # fmt: skip
    m = q.shape[0]
    blocks = _blocks(m, workers)
    if _compiled(integrator, run):
        futures = [
            executor.submit(
                _block_outputs, spec, q[rows], name, x[rows], _rows_of(params, m, rows), run
            )
            for rows in blocks
        ]
        parts = [f.result() for f in futures]
        out = MemberOutputs.joined([part for part, _ in parts])
        prms = np.concatenate([prm for _, prm in parts])
        return _ensemble(integrator, out, q, name, x, params, run, prms)
    futures = [
        executor.submit(
            _block, spec, q[rows], {f"{name}s": x[rows]}, _rows_of(params, m, rows), run
        )
        for rows in blocks
    ]
    return Ensemble.of([tr for f in futures for tr in f.result()])


def _rows_of(params, m: int, rows: slice):
    """The parameters of the members ``rows``: a sweep's columns cut, or the mappings."""
    if params is None:
        return None
    if isinstance(params, Mapping):
        return {key: col[rows] for key, col in _parameter_columns(params, m).items()}
    return member_parameters(params, m)[rows]


_INTEGRATORS: dict = {}


def _worker_integrator(spec):
    """The integrator of ``spec`` in this process, built once (loaded from the cache)."""
    integrator_class, system, method, backend, tol, maxiter, specialize, fixed_point = spec
    key = (
        system.analysis_key, pickle.dumps(method), backend, tol, maxiter, specialize,
        fixed_point,
    )  # fmt: skip
    if key not in _INTEGRATORS:
        _INTEGRATORS[key] = integrator_class(
            system, method, backend=backend, tol=tol, maxiter=maxiter, specialize=specialize,
            fixed_point=fixed_point,
        )  # fmt: skip
    return _INTEGRATORS[key]


def _block_outputs(spec, q, name, x, params, run) -> tuple[MemberOutputs, NDArray]:
    """A block of members in a worker process: the compiled loops' outputs."""
    return member_outputs(_worker_integrator(spec), q, name, x, params, run, 1)


def _block(spec, q0s, starts, params, run) -> list[Trajectory]:
    """A block of members in a worker process, one ``integrate`` call each."""
    integrator = _worker_integrator(spec)
    return integrator.integrate_many(q0s, **starts, params=params, workers=1, **run).trajectories


def compile_statistics() -> dict[str, int]:
    """numba's disk-cache hits and misses in this process: the loops and point functions.

    ``loops_loaded``/``loops_compiled``: variants of the time loops (and the
    member loop) loaded from the cache or compiled; ``points_loaded`` /
    ``points_compiled``: the point functions of the integrators built by
    ensemble workers here. Run it on the workers of a cluster
    (``client.run(compile_statistics)``) to see that nothing was compiled there.
    """
    import sys

    counts = {"loops_loaded": 0, "loops_compiled": 0, "points_loaded": 0, "points_compiled": 0}
    loops = sys.modules.get("galerkin_vi.loops")
    if loops is not None:
        from ..loops.members import members_loop

        for loop in (*(getattr(loops, name) for name in _LOOP_NAMES), members_loop):
            counts["loops_loaded"] += sum(loop.stats.cache_hits.values())
            counts["loops_compiled"] += sum(loop.stats.cache_misses.values())
    systems = {id(integrator.system): integrator.system for integrator in _INTEGRATORS.values()}
    for system in systems.values():
        for _, points in system.derived.owned_by("points"):
            for compiled in points.compiled.values():
                hit = compiled.cache_hits > 0
                counts["points_loaded" if hit else "points_compiled"] += 1
    return counts
