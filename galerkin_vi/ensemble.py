"""Ensembles: many initial states or parameter sets, run in parallel.

Each member is one :meth:`Integrator.integrate` call, so its result is bitwise
the one-by-one run's. The compiled loops release the GIL (``nogil``), so the
default executor, a thread pool over the machine's cores, runs members in
parallel in one process. Any :class:`concurrent.futures.Executor` can be
given instead: a process pool, or Dask's ``Client.get_executor()``; members
are then sent as (system, method, start, parameters) and each worker process
builds the integrator once from its cache (the point functions and loops are
loaded from the user cache directory, not compiled, when it holds them).
Parameter values are run-time data: a sweep never compiles.
"""

from __future__ import annotations

import os
import pickle
from collections.abc import Mapping, Sequence
from concurrent.futures import Executor, ThreadPoolExecutor
from dataclasses import dataclass
from typing import Any

import numpy as np
import sympy as sp
from numpy.typing import ArrayLike, NDArray

from .trajectory import Trajectory

__all__ = ["Ensemble", "integrate_many", "member_parameters"]


@dataclass(frozen=True, eq=False)
class Ensemble:
    """The members' trajectories, and their states stacked when they line up.

    Attributes
    ----------
    trajectories : list of Trajectory
    t : ndarray, shape (N,) or None
        The common saved times, when every member saved the same ones.
    q, p : ndarray, shape (m, N, n) or None
        Stacked positions and momenta (None when the members differ in length,
        e.g. after a failure or a terminal event).
    success, status : ndarray, shape (m,)
    """

    trajectories: list[Trajectory]
    t: NDArray[np.float64] | None
    q: NDArray[np.float64] | None
    p: NDArray[np.float64] | None
    success: NDArray[np.bool_]
    status: NDArray[np.int64]

    def __len__(self) -> int:
        return len(self.trajectories)

    def __getitem__(self, i: int) -> Trajectory:
        return self.trajectories[i]

    @classmethod
    def of(cls, trajectories: list[Trajectory]) -> Ensemble:
        first = trajectories[0]
        same = all(len(tr) == len(first) and np.array_equal(tr.t, first.t) for tr in trajectories)
        return cls(
            trajectories=trajectories,
            t=first.t if same else None,
            q=np.stack([tr.q for tr in trajectories]) if same else None,
            p=np.stack([tr.p for tr in trajectories]) if same else None,
            success=np.array([tr.success for tr in trajectories]),
            status=np.array([int(tr.status) for tr in trajectories]),
        )


def member_parameters(
    params: Mapping[sp.Symbol | str, ArrayLike] | Sequence[Mapping] | None, m: int
) -> list[Mapping | None]:
    """Per-member parameter mappings from one mapping of scalars or length-m arrays,
    or from a sequence of m mappings."""
    if params is None:
        return [None] * m
    if isinstance(params, Mapping):
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
        return [{key: float(col[i]) for key, col in columns.items()} for i in range(m)]
    members = list(params)
    if len(members) != m:
        raise ValueError(f"params must hold one mapping per member ({m}), got {len(members)}")
    return members


def _starts(q0s: ArrayLike, v0s, p0s, n: int) -> tuple[NDArray, str, NDArray]:
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
    q, name, x = _starts(q0s, v0s, p0s, integrator.system.n)
    m = q.shape[0]
    members = member_parameters(params, m)
    run.setdefault("progress", False)
    if executor is None:
        # ThreadPoolExecutor: the compiled loops release the GIL
        with ThreadPoolExecutor(max_workers=workers or os.cpu_count() or 1) as pool:
            futures = [
                pool.submit(integrator.integrate, q[i], **{name: x[i]}, params=members[i], **run)
                for i in range(m)
            ]
            return Ensemble.of([f.result() for f in futures])
    spec = (
        type(integrator),
        integrator.system, integrator.method, integrator.backend, integrator.tol,
        integrator.maxiter, integrator.specialize,
    )  # fmt: skip
    futures = [
        executor.submit(_member, spec, q[i], {name: x[i]}, members[i], run) for i in range(m)
    ]
    return Ensemble.of([f.result() for f in futures])


_INTEGRATORS: dict = {}


def _member(spec, q0, start, params, run) -> Trajectory:
    """One member in a worker process: the integrator built once per process."""
    integrator_class, system, method, backend, tol, maxiter, specialize = spec
    key = (system._analysis_key, pickle.dumps(method), backend, tol, maxiter, specialize)
    if key not in _INTEGRATORS:
        _INTEGRATORS[key] = integrator_class(
            system, method, backend=backend, tol=tol, maxiter=maxiter, specialize=specialize
        )
    return _INTEGRATORS[key].integrate(q0, **start, params=params, **run)
