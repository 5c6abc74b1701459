r"""Chaos indicators from the tangent map: Lyapunov spectra and MEGNO.

Both ride on :meth:`Integrator.integrate` with ``tangent=V`` and
``renormalize_every=m`` (:mod:`galerkin_vi.run.tangent`), which carries a frame
:math:`T_k = \Phi_k V` of deviation vectors along the discrete flow,
:math:`\Phi_k = \partial(q_k, p_k)/\partial(q_0, p_0)`.

**Lyapunov spectrum (Benettin's method).** Every :math:`m` steps the loop
replaces the frame by the :math:`Q` of its QR factorisation
:math:`T = QR` (modified Gram–Schmidt, column 0 first) and accumulates
:math:`G_i = \sum \log R_{ii}`. Then

.. math::

    \lambda_i = \lim_{t\to\infty} \frac{G_i(t)}{t - t_0},
    \qquad \lambda_1 \ge \lambda_2 \ge \dots \ge \lambda_r,

are the r largest Lyapunov exponents for a generic start frame (Benettin,
Galgani, Giorgilli, Strelcyn, Meccanica 15 (1980) 9–30; Skokos, Lect. Notes
Phys. 790 (2010) 63–135). For a Hamiltonian flow, and for the discrete flow of
a variational integrator, which is symplectic, they come in pairs
:math:`\lambda_i + \lambda_{2n+1-i} = 0`; the finite-time estimates converge
like :math:`O(1/t)` for regular orbits and for these pair sums.

**MEGNO** (Cincotta & Simó, Astron. Astrophys. Suppl. 147 (2000) 205–228).
For a deviation vector :math:`\delta(t)`,

.. math::

    Y(t) = \frac{2}{t}\int_0^t s\,\frac{\dot{\|\delta\|}}{\|\delta\|}\,ds,
    \qquad \bar Y(t) = \frac1t\int_0^t Y(s)\,ds ,

discretised per step as
:math:`Y_N = \frac{2}{t_N}\sum_{k<N} t_{k+1}\log(\|\delta_{k+1}\|/\|\delta_k\|)`
(times from :math:`t_0`) and :math:`\bar Y_N` the mean of :math:`Y_1..Y_N`.
:math:`\bar Y \to 0` on an isochronous periodic orbit (harmonic oscillator),
:math:`\to 2` on a quasi-periodic one (KAM torus), and grows like
:math:`\lambda_1 t/2` on a chaotic one.

**Chaos maps.** :func:`lyapunov_map` and :func:`megno_map` run one member per
initial condition of a grid, on threads (the compiled loops release the GIL)
or on any executor with ``map`` (a process pool, Dask's
``Client.get_executor()``), and return the final values per member.
"""

from __future__ import annotations

import numbers
import pickle
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..run.ensemble import member_parameters, member_starts
from ..run.status import RunStatus, SolverResult
from ..run.trajectory import Trajectory

__all__ = [
    "ChaosMap",
    "LyapunovSpectrum",
    "Megno",
    "default_deviation",
    "lyapunov_map",
    "lyapunov_spectrum",
    "megno",
    "megno_map",
]

#: the seed of the default MEGNO deviation vector
DEFAULT_SEED = 0


@dataclass(frozen=True, eq=False)
class LyapunovSpectrum(SolverResult):
    r"""The result of :func:`lyapunov_spectrum`.

    Attributes
    ----------
    exponents : ndarray, shape (r,)
        The finite-time Lyapunov exponents at the last saved row, descending.
    times : ndarray, shape (rows - 1,)
        The saved times after the start (no estimate exists at :math:`t_0`).
    running : ndarray, shape (rows - 1, r)
        The estimates :math:`G_i(t)/(t - t_0)` at ``times``, columns in the order
        of ``exponents``.
    trajectory : Trajectory
        The run (its ``variations`` hold the renormalised frames and log-growths).
    status : RunStatus
        The run's status; estimates of a failed run are those of its last row.
    message : str
    """

    exponents: NDArray[np.float64]
    times: NDArray[np.float64]
    running: NDArray[np.float64]
    trajectory: Trajectory
    status: RunStatus
    message: str


@dataclass(frozen=True, eq=False)
class Megno(SolverResult):
    r"""The result of :func:`megno`.

    Attributes
    ----------
    times : ndarray, shape (rows,)
    Y : ndarray, shape (rows,)
        MEGNO :math:`Y(t)` (0 at :math:`t_0`).
    mean : ndarray, shape (rows,)
        Its running mean :math:`\bar Y(t)` over the steps (0 at :math:`t_0`).
    final : float
        ``mean[-1]``: the indicator (about 2 regular, 0 isochronous, large chaotic).
    direction : ndarray, shape (2n,)
        The initial deviation vector (unit length) in :math:`(q, p)`.
    trajectory : Trajectory
    status : RunStatus
    message : str
    """

    times: NDArray[np.float64]
    Y: NDArray[np.float64]
    mean: NDArray[np.float64]
    final: float
    direction: NDArray[np.float64]
    trajectory: Trajectory
    status: RunStatus
    message: str


@dataclass(frozen=True, eq=False)
class ChaosMap:
    """The final indicator of every member of :func:`lyapunov_map` or :func:`megno_map`.

    Attributes
    ----------
    values : ndarray, shape (m,) or (m, r)
        MEGNO's final mean :math:`\\bar Y`, or the Lyapunov exponents (descending).
        A member whose run failed has the value of its last saved row.
    success : ndarray of bool, shape (m,)
    status : ndarray of int, shape (m,)
        Each member's :class:`RunStatus` code.
    messages : list of str
        Each member's message.
    """

    values: NDArray[np.float64]
    success: NDArray[np.bool_]
    status: NDArray[np.int64]
    messages: list[str]

    def __len__(self) -> int:
        return len(self.success)


# ---------------------------------------------------------------- one orbit
def lyapunov_spectrum(
    integrator: Any,
    q0: ArrayLike,
    v0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    *,
    h: float,
    n_steps: int,
    renormalize_every: int = 10,
    directions: int | ArrayLike | None = None,
    params: Mapping | None = None,
    save_every: int | None = None,
    t0: float = 0.0,
    on_failure: str = "warn",
    seed: int = DEFAULT_SEED,
) -> LyapunovSpectrum:
    r"""The Lyapunov exponents of the orbit from ``(q0, v0 or p0)`` by Benettin's method.

    Parameters
    ----------
    integrator : Integrator
        With the numba backend (the tangent map runs in the compiled loops).
    q0, v0, p0
        The start, as :meth:`Integrator.integrate` (exactly one of ``v0``, ``p0``).
    h, n_steps : float, int
        Step size and number of steps; the exponents are estimates at
        :math:`t = t_0 + N h`.
    renormalize_every : int
        Steps between QR renormalisations of the frame, :math:`m \ge 1`: the
        frame grows by about :math:`e^{\lambda_1 m h}` in between, which must
        stay well inside the floating-point range.
    directions : None, int or array_like of shape (2n, r)
        None: all 2n exponents (start frame the identity). An int r: the r
        largest, from the first r columns of a random orthogonal matrix
        (``seed``). An array: these start directions (orthonormalised).
    params : mapping, optional
    save_every : int, optional
        Rows of the running estimates (default: about 1000 rows).
    t0 : float
    on_failure : "warn" or "raise"
    seed : int
        Seed of :func:`numpy.random.default_rng` for ``directions=r``.

    Returns
    -------
    LyapunovSpectrum
        ``exponents`` sorted descending, ``running`` estimates, the run.

    Notes
    -----
    The estimate at a saved row includes the growth since the last
    renormalisation, :math:`\log|R_{ii}|` of the QR factorisation of the
    saved frame, so that every row's estimate is :math:`G_i(t)/(t - t_0)`
    whatever ``save_every`` and ``renormalize_every`` are.
    """
    n = integrator.system.n
    frame = start_frame(n, directions, seed)
    every = _positive_int(renormalize_every, "renormalize_every")
    traj = integrator.integrate(
        q0, v0=v0, p0=p0, h=h, n_steps=n_steps, params=params, t0=t0, on_failure=on_failure,
        save_every=_default_save_every(n_steps, save_every), tangent=frame,
        renormalize_every=every,
    )  # fmt: skip
    return spectrum_of(traj)


def spectrum_of(traj: Trajectory) -> LyapunovSpectrum:
    """The :class:`LyapunovSpectrum` of a run with a renormalised tangent frame."""
    variations = traj.variations
    if variations is None or variations.log_growth is None:
        raise ValueError(
            "traj: a run with tangent=... and renormalize_every >= 1 is needed (its "
            "variations.log_growth holds the accumulated renormalisations)"
        )
    growth = variations.log_growth + _pending_growth(variations.tangent)
    elapsed = traj.t - traj.t[0]
    if len(elapsed) < 2:
        raise ValueError("traj: the run saved no row after its start")
    running = growth[1:] / elapsed[1:, None]
    order = np.argsort(-running[-1], kind="stable")
    running = running[:, order]
    return LyapunovSpectrum(
        exponents=running[-1].copy(), times=traj.t[1:], running=running, trajectory=traj,
        status=traj.status, message=_message("Lyapunov spectrum", traj),
    )  # fmt: skip


def _pending_growth(frames: NDArray[np.float64]) -> NDArray[np.float64]:
    r""":math:`\log|R_{ii}|` of each saved frame: its growth since the last renormalisation
    (zero right after one, where the frame is orthonormal)."""
    upper = np.linalg.qr(frames, mode="r")
    return np.log(np.abs(np.diagonal(upper, axis1=-2, axis2=-1)))


def megno(
    integrator: Any,
    q0: ArrayLike,
    v0: ArrayLike | None = None,
    p0: ArrayLike | None = None,
    *,
    h: float,
    n_steps: int,
    params: Mapping | None = None,
    seed: int = DEFAULT_SEED,
    direction: ArrayLike | None = None,
    save_every: int = 1,
    t0: float = 0.0,
    on_failure: str = "warn",
) -> Megno:
    r"""MEGNO :math:`Y(t)` and its running mean :math:`\bar Y(t)` along the orbit from ``q0``.

    Parameters
    ----------
    integrator, q0, v0, p0, h, n_steps, params, t0, on_failure
        As :func:`lyapunov_spectrum`.
    seed : int
        Seed of the default deviation vector :func:`default_deviation`: a unit
        vector of independent standard normal components, drawn by
        ``numpy.random.default_rng(seed)``, the same for every call with this
        seed (so maps over a grid use one deviation direction).
    direction : array_like, shape (2n,), optional
        The initial deviation :math:`\delta_0` in :math:`(q, p)` instead (normalised).
    save_every : int
        Rows of ``times``, ``Y`` and ``mean``; the mean is over every step.

    Returns
    -------
    Megno

    Notes
    -----
    The deviation is normalised after every step (``renormalize_every=1``),
    which changes no direction and keeps :math:`\|\delta\|` in range; the
    loop sums the logarithms of the true growths.
    """
    n = integrator.system.n
    delta = default_deviation(n, seed) if direction is None else _unit(direction, n)
    traj = integrator.integrate(
        q0, v0=v0, p0=p0, h=h, n_steps=n_steps, params=params, t0=t0, on_failure=on_failure,
        save_every=save_every, tangent=delta[:, None], renormalize_every=1,
    )  # fmt: skip
    variations = traj.variations
    return Megno(
        times=traj.t, Y=variations.megno, mean=variations.megno_mean,
        final=float(variations.megno_mean[-1]), direction=delta, trajectory=traj,
        status=traj.status, message=_message("MEGNO", traj),
    )  # fmt: skip


def default_deviation(n: int, seed: int = DEFAULT_SEED) -> NDArray[np.float64]:
    """The unit deviation vector (2n,) of seed ``seed``: standard normal components
    from ``numpy.random.default_rng(seed)``, normalised."""
    vector = np.random.default_rng(seed).standard_normal(2 * n)
    return vector / np.linalg.norm(vector)


def start_frame(n: int, directions, seed: int = DEFAULT_SEED) -> NDArray[np.float64]:
    """The start frame (2n, r) of a Lyapunov run; see :func:`lyapunov_spectrum`."""
    if directions is None:
        return np.eye(2 * n)
    if isinstance(directions, numbers.Integral) and not isinstance(directions, bool):
        r = int(directions)
        if not 1 <= r <= 2 * n:
            raise ValueError(f"directions must be an int in [1, 2n] = [1, {2 * n}], got {r}")
        random = np.random.default_rng(seed).standard_normal((2 * n, 2 * n))
        return np.linalg.qr(random)[0][:, :r]
    frame = np.array(directions, dtype=float, ndmin=2)
    if frame.ndim != 2 or frame.shape[0] != 2 * n or not 1 <= frame.shape[1] <= 2 * n:
        raise ValueError(
            f"directions must be None, an int r or an array of shape (2n, r) = ({2 * n}, r), "
            f"1 <= r <= {2 * n}, got shape {np.shape(directions)}"
        )
    if not np.isfinite(frame).all() or np.linalg.matrix_rank(frame) < frame.shape[1]:
        raise ValueError("directions must be finite and linearly independent columns")
    return frame


def _unit(direction: ArrayLike, n: int) -> NDArray[np.float64]:
    delta = np.asarray(direction, dtype=float)
    if delta.shape != (2 * n,):
        raise ValueError(f"direction must have shape (2n,) = ({2 * n},), got {delta.shape}")
    size = np.linalg.norm(delta)
    if not (np.isfinite(size) and size > 0):
        raise ValueError("direction must be finite and nonzero")
    return delta / size


def _positive_int(value, name: str) -> int:
    if isinstance(value, bool) or not isinstance(value, numbers.Integral) or value < 1:
        raise ValueError(f"{name} must be an int >= 1, got {value!r}")
    return int(value)


def _default_save_every(n_steps: int, save_every: int | None) -> int:
    if save_every is not None:
        return save_every
    return max(1, int(n_steps) // 1000)


def _message(what: str, traj: Trajectory) -> str:
    if traj.success:
        return f"{what} of the run to t = {traj.t[-1]:g}: {traj.message}"
    return f"{what} up to t = {traj.t[-1]:g}, where the run failed: {traj.message}"


# ---------------------------------------------------------------- maps over ensembles
@dataclass(frozen=True)
class IntegratorRecipe:
    """What rebuilds an integrator in another process (systems pickle, integrators need not)."""

    integrator_class: type
    system: Any
    method: Any
    backend: str
    tol: float
    maxiter: int
    specialize: bool
    fixed_point: bool

    @classmethod
    def of(cls, integrator) -> IntegratorRecipe:
        return cls(
            type(integrator), integrator.system, integrator.method, integrator.backend,
            integrator.tol, integrator.maxiter, integrator.specialize, integrator.fixed_point,
        )  # fmt: skip

    def key(self) -> tuple:
        return (
            self.system.analysis_key, pickle.dumps(self.method), self.backend, self.tol,
            self.maxiter, self.specialize, self.fixed_point,
        )  # fmt: skip

    def build(self):
        """The integrator, built once per process (its point functions from the cache)."""
        key = self.key()
        if key not in _BUILT:
            _BUILT[key] = self.integrator_class(
                self.system, self.method, backend=self.backend, tol=self.tol,
                maxiter=self.maxiter, specialize=self.specialize, fixed_point=self.fixed_point,
            )  # fmt: skip
        return _BUILT[key]


_BUILT: dict = {}


@dataclass(frozen=True)
class MemberTask:
    """One member of a chaos map: where it starts and what to compute."""

    integrator: Any  # an Integrator (threads) or an IntegratorRecipe (other executors)
    indicator: str  # "lyapunov" | "megno"
    q0: NDArray[np.float64]
    start: str  # "v0" | "p0"
    x0: NDArray[np.float64]
    params: Mapping | None
    options: Mapping


def run_member(task: MemberTask) -> tuple[NDArray[np.float64], int, str]:
    """(final values, status code, message) of one member; what an executor's worker runs."""
    integrator = task.integrator
    if isinstance(integrator, IntegratorRecipe):
        integrator = integrator.build()
    compute = lyapunov_spectrum if task.indicator == "lyapunov" else megno
    result = compute(
        integrator, task.q0, **{task.start: task.x0}, params=task.params, **task.options
    )
    value = result.exponents if task.indicator == "lyapunov" else np.array(result.final)
    return value, int(result.status), result.message


def lyapunov_map(
    integrator: Any,
    q0s: ArrayLike,
    v0s: ArrayLike | None = None,
    p0s: ArrayLike | None = None,
    *,
    h: float,
    n_steps: int,
    params=None,
    executor=None,
    workers: int | None = None,
    **options,
) -> ChaosMap:
    """:func:`lyapunov_spectrum` of every member (row) of ``q0s`` and ``v0s`` or ``p0s``.

    Parameters
    ----------
    integrator : Integrator
    q0s : array_like, shape (m, n)
    v0s, p0s : array_like, shape (m, n) or (n,)
        Exactly one; a single row is used for every member (as
        :meth:`Integrator.integrate_many`).
    h, n_steps : float, int
    params : mapping or sequence of mappings, optional
        As :meth:`Integrator.integrate_many`: numbers, arrays of m values, or
        one mapping per member.
    executor : object with ``map``, optional
        Where the members run: a :class:`concurrent.futures.Executor` (a
        process pool), Dask's ``Client.get_executor()``. It receives one
        picklable task per member (the system and method, not the integrator;
        each worker process builds the integrator once, from the cache).
        Default: threads in this process (the compiled loops release the GIL).
    workers : int, optional
        Threads of the default executor (default: all cores).
    **options
        Passed to :func:`lyapunov_spectrum` (``renormalize_every``,
        ``directions``, ``save_every``, ``t0``, ``seed``, ``on_failure``).

    Returns
    -------
    ChaosMap
        ``values`` shape (m, r): every member's exponents, descending.

    Notes
    -----
    Members save only their first and last rows (``save_every=n_steps`` unless
    given). Each member's values are bitwise those of the single call with the
    same options; a single call with another ``save_every`` cuts a long run into
    compiled chunks elsewhere (:mod:`galerkin_vi.run.chunks`), which changes the
    result by rounding, amplified on a chaotic orbit.
    """
    options = {"save_every": n_steps, **options}  # only the final values travel back
    return _chaos_map("lyapunov", integrator, q0s, v0s, p0s, h, n_steps, params, executor,
                      workers, options)  # fmt: skip


def megno_map(
    integrator: Any,
    q0s: ArrayLike,
    v0s: ArrayLike | None = None,
    p0s: ArrayLike | None = None,
    *,
    h: float,
    n_steps: int,
    params=None,
    executor=None,
    workers: int | None = None,
    **options,
) -> ChaosMap:
    """:func:`megno` of every member; arguments as :func:`lyapunov_map`.

    ``options`` go to :func:`megno` (``seed``, ``direction``, ``save_every``,
    ``t0``, ``on_failure``); every member uses the same deviation direction.
    Members save as :func:`lyapunov_map`'s do.

    Returns
    -------
    ChaosMap
        ``values`` shape (m,): every member's final :math:`\\bar Y`.
    """
    options = {"save_every": n_steps, **options}
    return _chaos_map("megno", integrator, q0s, v0s, p0s, h, n_steps, params, executor,
                      workers, options)  # fmt: skip


def _chaos_map(indicator, integrator, q0s, v0s, p0s, h, n_steps, params, executor, workers,
               options) -> ChaosMap:  # fmt: skip
    q, start, x = member_starts(q0s, v0s, p0s, integrator.system.n)
    members = member_parameters(params, q.shape[0])
    who = integrator if executor is None else IntegratorRecipe.of(integrator)
    options = {"h": h, "n_steps": n_steps, **options}
    tasks = [
        MemberTask(who, indicator, q[i], start, x[i], members[i], options)
        for i in range(q.shape[0])
    ]
    if executor is not None:
        if not callable(getattr(executor, "map", None)):
            raise TypeError(f"executor must have a map method, got {type(executor).__name__}")
        results = list(executor.map(run_member, tasks))
    else:
        results = _in_blocks(indicator, integrator, q, start, x, params, workers, options)
    return ChaosMap(
        values=np.array([value for value, _, _ in results]),
        success=np.array([code >= 0 for _, code, _ in results], dtype=bool),
        status=np.array([code for _, code, _ in results], dtype=np.int64),
        messages=[message for _, _, message in results],
    )


def _in_blocks(indicator, integrator, q, start, x, params, workers, options) -> list:
    """Every member's (value, status, message) through :meth:`Integrator.integrate_many`:
    blocks of members in one compiled call each (runs of one chunk), on threads."""
    n = integrator.system.n
    options = dict(options)
    seed = options.pop("seed", DEFAULT_SEED)
    if indicator == "lyapunov":
        frame = start_frame(n, options.pop("directions", None), seed)
        every = _positive_int(options.pop("renormalize_every", 10), "renormalize_every")
        options["save_every"] = _default_save_every(options["n_steps"], options.get("save_every"))
        ensemble = integrator.integrate_many(
            q, **{start + "s": x}, params=params, workers=workers, tangent=frame,
            renormalize_every=every, **options,
        )  # fmt: skip
        what = "Lyapunov spectrum"
        return [
            (spectrum_of(traj).exponents, int(traj.status), _message(what, traj))
            for traj in ensemble.trajectories
        ]
    direction = options.pop("direction", None)
    delta = default_deviation(n, seed) if direction is None else _unit(direction, n)
    ensemble = integrator.integrate_many(
        q, **{start + "s": x}, params=params, workers=workers, tangent=delta[:, None],
        renormalize_every=1, **options,
    )  # fmt: skip
    return [(np.array(float(traj.variations.megno_mean[-1])), int(traj.status),
             _message("MEGNO", traj)) for traj in ensemble.trajectories]  # fmt: skip
