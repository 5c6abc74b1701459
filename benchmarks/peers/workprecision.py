r"""Work-precision benchmark: galerkin_vi against hand-written kernels, scipy and REBOUND.

What is measured
----------------
For each problem (:data:`PROBLEMS`; see :func:`make_case` for the settings and
references) and each *curve* (one galerkin_vi method, one hand-written kernel,
one scipy ``solve_ivp`` method, numbalsoda's compiled DOP853 or a REBOUND
integrator):

* fixed-step curves sweep the number of steps :math:`N` geometrically
  (:math:`h = T/N`) from a coarse start until the error reaches the round-off
  floor (below 1e-13, or three times in a row not below 0.7 times the best error
  once that is below 1e-9) or one run took longer than the configured time cap;
* adaptive curves (scipy, numbalsoda, IAS15) sweep their tolerance (``rtol``
  with ``atol = rtol``; IAS15's ``epsilon``) the same way.

Each point records the wall time (``time.perf_counter``, minimum over
``repeats`` runs; all points of all curves are re-timed in interleaved rounds,
so a burst of load on the shared machine hits every curve alike), the final
relative position error :math:`|q_N - q(T)| / |q(T)|`, and the maximum relative
energy error :math:`\max_k |H_k - H_0| / |H_0|`. Timing runs store only the
first and last state (``save_every = n_steps``); the error and energy are taken
from one extra, untimed run that saves about ``energy_samples`` evenly spaced
states (scipy: every accepted step).

From the curves: the time to reach a final error of 1e-4, 1e-8 and 1e-11
(first crossing, interpolated linearly in log time against log error), the
best galerkin_vi configuration at each target, and the ratio of each peer's
time to it (> 1: galerkin_vi is faster).

Two further tables: per step, galerkin_vi against the hand-written kernel of
the same method at the same h and Newton tolerance (time per step, interleaved
repeats, minimum); and the cost per step of galerkin_vi s = 2 Gauss(2) on the
spring chain against its length N at a fixed h.

References
----------
See :mod:`.cases` (:func:`~.cases.make_case`): exact for the pendulum and Kepler,
numerical and cross-checked for the others; computed once per process.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import os
import platform
import sys
import time
import warnings
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

import galerkin_vi as gvi
from galerkin_vi.run.loop_choice import composition_obstacle
from galerkin_vi.tools import benchmark as bm
from galerkin_vi.tools.benchmark import TARGETS, Curve, Sample, time_to_error

from . import handwritten as hw
from .cases import (
    CHAIN_BETA,
    PROBLEMS,
    Case,
    ReboundSetup,
    chain_problem,
    make_case,
    numbalsoda_available,
    numbalsoda_dop853,
    rebound_available,
    reference_checks,
)

__all__ = [
    "PER_STEP_PAIRS",
    "PROBLEMS",
    "TARGETS",
    "BenchConfig",
    "Case",
    "chain_cost",
    "chain_growth",
    "full_config",
    "make_case",
    "quick_config",
    "run_benchmark",
    "time_to_error",
    "tiny_config",
]

#: per-step comparisons: label -> (galerkin_vi (degree, family), hand-written kernel)
PER_STEP_PAIRS: dict[str, tuple[tuple[int, str], str]] = {
    "s=1 Lobatto(2) vs Störmer–Verlet": ((1, "lobatto"), "verlet"),
    "s=1 Gauss(1) vs 1-stage Gauss": ((1, "gauss"), "gauss1"),
    "s=2 Gauss(2) vs 2-stage Gauss": ((2, "gauss"), "gauss2"),
    "s=3 Gauss(3) vs 3-stage Gauss": ((3, "gauss"), "gauss3"),
    "s=2 Lobatto(3) vs 3-stage Lobatto IIIA–IIIB": ((2, "lobatto"), "lobatto3"),
    "s=3 Lobatto(4) vs 4-stage Lobatto IIIA–IIIB": ((3, "lobatto"), "lobatto4"),
}

_HW_LABELS = {
    "verlet": "Störmer–Verlet",
    **{f"gauss{s}": f"{s}-stage Gauss" for s in range(1, 9)},
    **{f"gauss{s}-simplified": f"{s}-stage Gauss (simplified Newton)" for s in range(1, 9)},
    **{f"gauss{s}-fixed-point": f"{s}-stage Gauss (fixed point)" for s in range(1, 9)},
    **{f"lobatto{r}": f"{r}-stage Lobatto IIIA–IIIB" for r in range(2, 9)},
}

#: adaptive peers outside scipy, used when importable: label -> family
OPTIONAL_PEERS = {
    "numbalsoda DOP853": "numbalsoda",
    "REBOUND IAS15": "REBOUND",
    "REBOUND WHFast": "REBOUND",
}


# ----------------------------------------------------------------- configuration
@dataclass(frozen=True)
class BenchConfig:
    """What to run and how long to spend on it.

    Attributes
    ----------
    problems : tuple of str
        Names from :data:`PROBLEMS`.
    gvi_methods : tuple of (int, str)
        galerkin_vi degree and quadrature family (``"lobatto"``: ``gauss_lobatto(s + 1)``,
        ``"gauss"``: ``gauss_legendre(s)``).
    compositions : tuple of int
        Orders of ``gvi.Composition`` (explicit splittings and compositions of
        Störmer–Verlet, default schemes), run on the problems whose Lagrangian allows
        them (separable, constant mass); galerkin_vi curves like the others.
    handwritten : tuple of str
        ``"verlet"``, ``"gaussS"``, ``"gaussS-simplified"``, ``"gaussS-fixed-point"``,
        ``"lobattoR"``; a problem runs those its case allows (:attr:`Case.hw_allowed`).
    ivp_methods : tuple of str
        scipy ``solve_ivp`` methods (a problem may exclude some: :attr:`Case.ivp_methods`).
    peers : tuple of str
        Optional peers, run where they apply and are importable:
        ``"numbalsoda"`` (compiled DOP853), ``"ias15"`` and ``"whfast"`` (REBOUND).
    ivp_min_rtol : dict
        Tightest tolerance per adaptive method (``"IAS15"``: its ``epsilon``).
    step_factor : float
        Ratio of successive step counts.
    rtol_factor : float
        Ratio of successive rtols (sweeps start at 1e-3; IAS15's at 1e-2).
    time_cap, ivp_time_cap : float
        A fixed-step (adaptive) sweep stops once its last run took longer than this (seconds).
    repeats : int
        Timed runs per point (minimum reported), in interleaved rounds.
    energy_samples : int
        States saved by the untimed error run, for the energy error.
    per_step_pairs : tuple of str
        Keys of :data:`PER_STEP_PAIRS` for the per-step table.
    per_step_problems : tuple of str
        Problems of the per-step table (separable ones only).
    per_step_time : float
        Target duration (s) of one galerkin_vi run in the per-step and chain-cost tables.
    per_step_repeats : int
    chain_cost_sizes : tuple of int
        Chain lengths N of the cost-per-step table (empty: no table).
    chain_cost_steps : int
        Steps per run of that table (the same for every N).
    overrides : dict
        Per problem, fields of this configuration to replace for that problem
        (e.g. ``{"fpu": {"gvi_methods": ((4, "gauss"),)}}``).
    specialize : bool or "system"
        ``Integrator(specialize=...)`` of the galerkin_vi curves: ``"system"`` (the
        default here) runs the loops generated for each small system and method, as a
        user after speed would; their compile time is not timed, as numbalsoda's is not.
    """

    problems: tuple[str, ...] = PROBLEMS[:-1]
    gvi_methods: tuple[tuple[int, str], ...] = ()
    compositions: tuple[int, ...] = ()
    handwritten: tuple[str, ...] = ()
    ivp_methods: tuple[str, ...] = ()
    peers: tuple[str, ...] = ()
    ivp_min_rtol: dict[str, float] = field(
        default_factory=lambda: {
            "DOP853": 3e-14,
            "RK45": 1e-11,
            "Radau": 1e-10,
            "numbalsoda": 1e-15,
            "IAS15": 1e-10,
        }
    )
    step_factor: float = 2.0
    rtol_factor: float = 10.0
    time_cap: float = 0.2
    ivp_time_cap: float = 1.0
    repeats: int = 2
    energy_samples: int = 1000
    per_step_pairs: tuple[str, ...] = tuple(PER_STEP_PAIRS)
    per_step_problems: tuple[str, ...] = ("pendulum", "kepler")
    per_step_time: float = 0.05
    per_step_repeats: int = 5
    chain_cost_sizes: tuple[int, ...] = ()
    chain_cost_steps: int = 300
    targets: tuple[float, ...] = TARGETS
    overrides: dict[str, dict[str, Any]] = field(default_factory=dict)
    specialize: bool | str = "system"

    def for_problem(self, name: str) -> BenchConfig:
        """This configuration with the overrides of problem ``name`` applied."""
        extra = self.overrides.get(name)
        if not extra:
            return self
        return dataclasses.replace(self, **extra)


# galerkin_vi and hand-written curves of the problems beyond pendulum and Kepler
_GVI_HIGH = ((2, "gauss"), (3, "lobatto"), (4, "gauss"), (6, "gauss"))
_GVI_ALL = tuple((s, fam) for s in (1, 2, 3, 4, 6) for fam in ("lobatto", "gauss"))


def quick_config() -> BenchConfig:
    """``--quick``: few methods per family, coarse sweeps, short caps (under 2 minutes).

    Pendulum and Kepler run as before (five galerkin_vi methods, four hand-written
    kernels, DOP853; RK45 on the pendulum). The other problems run galerkin_vi
    s = 2, 4, 6 Gauss and s = 3 Lobatto, two to four hand-written kernels and DOP853
    (RK45 only on the cheap Hénon–Heiles and double pendulum), plus numbalsoda and
    REBOUND where installed. Left out: the spring chain N = 1000 (its
    generated kernel alone takes about 4 minutes to compile, and a run 10 times longer
    than N = 100) and Radau; the chain-cost table stops at N = 100.
    """
    return BenchConfig(
        problems=PROBLEMS[:-1],
        gvi_methods=((1, "lobatto"), (2, "gauss"), (3, "lobatto"), (4, "gauss"), (6, "gauss")),
        compositions=(6, 8, 10),
        handwritten=("verlet", "gauss2", "gauss3", "lobatto4"),
        ivp_methods=("DOP853", "RK45"),
        peers=("numbalsoda", "ias15", "whfast"),
        step_factor=2.0,
        rtol_factor=10.0,
        time_cap=0.1,
        ivp_time_cap=0.3,
        repeats=2,
        energy_samples=200,
        per_step_time=0.03,
        per_step_repeats=5,
        chain_cost_sizes=(10, 100),
        chain_cost_steps=200,
        overrides={
            # DOP853 needs about 0.3 s (Kepler, solar system) and 0.5 s (FPU) to reach 1e-8
            "kepler": {"ivp_methods": ("DOP853",), "ivp_time_cap": 0.6},
            # galerkin_vi takes 0.1-0.2 s per run at the coarsest useful steps of these three
            "outer_solar_system": {
                "gvi_methods": _GVI_HIGH,
                "handwritten": ("verlet", "gauss4-fixed-point", "gauss6-fixed-point"),
                "ivp_methods": ("DOP853",),
                "time_cap": 0.25,
                "ivp_time_cap": 0.6,
            },
            "henon_heiles": {
                "gvi_methods": _GVI_HIGH,
                "handwritten": ("verlet", "gauss2", "lobatto4", "gauss6"),
            },
            "double_pendulum": {"gvi_methods": _GVI_HIGH},
            "fpu": {
                "gvi_methods": _GVI_HIGH,
                "handwritten": ("verlet", "gauss2", "gauss6"),
                "ivp_methods": ("DOP853",),
                "time_cap": 0.2,
                "ivp_time_cap": 0.8,
            },
            "spring_chain_100": {
                "gvi_methods": _GVI_HIGH,
                "handwritten": ("verlet", "gauss4-fixed-point"),
                "ivp_methods": ("DOP853",),
                "time_cap": 0.2,
            },
        },
    )


def full_config() -> BenchConfig:
    """The full run: more configurations, finer sweeps, longer caps (under 30 minutes).

    Pendulum and Kepler: all ten galerkin_vi methods. The others: galerkin_vi s = 2,
    4, 6 with Gauss and s = 3, 4, 6 with Lobatto quadrature (the chains fewer), with
    shorter caps; Radau everywhere except on the N = 1000 chain (a dense 2000 x 2000
    Jacobian per step).
    """
    many = (
        (2, "gauss"),
        (3, "lobatto"),
        (4, "gauss"),
        (4, "lobatto"),
        (6, "gauss"),
        (6, "lobatto"),
    )
    return BenchConfig(
        problems=PROBLEMS,
        gvi_methods=_GVI_ALL,
        compositions=(4, 6, 8, 10),
        handwritten=(
            "verlet",
            "gauss1",
            "gauss2",
            "gauss3",
            "gauss3-simplified",
            "gauss4",
            "gauss6",
            "lobatto3",
            "lobatto4",
        ),
        ivp_methods=("DOP853", "RK45", "Radau"),
        peers=("numbalsoda", "ias15", "whfast"),
        step_factor=math.sqrt(2.0),
        rtol_factor=10.0**0.5,
        time_cap=0.75,
        ivp_time_cap=2.5,
        repeats=3,
        per_step_time=0.15,
        per_step_repeats=7,
        per_step_problems=("pendulum", "kepler", "henon_heiles", "outer_solar_system"),
        chain_cost_sizes=(10, 100, 1000),
        chain_cost_steps=400,
        overrides={
            "outer_solar_system": {
                "gvi_methods": many,
                "handwritten": (
                    "verlet",
                    "gauss2-fixed-point",
                    "gauss4-fixed-point",
                    "gauss6-fixed-point",
                    "gauss6",
                    "lobatto4",
                ),
                "time_cap": 1.0,
            },
            "henon_heiles": {
                "gvi_methods": many,
                "handwritten": ("verlet", "gauss2", "gauss4", "gauss6", "lobatto3", "lobatto4"),
            },
            "double_pendulum": {"gvi_methods": many},
            "fpu": {
                "gvi_methods": many,
                "handwritten": ("verlet", "gauss2", "gauss4", "gauss6", "lobatto4"),
                "time_cap": 0.5,
                "ivp_time_cap": 2.0,
            },
            "spring_chain_100": {
                # Lobatto(5) and (7): fewer implicit stages than Gauss at the same order,
                # the fastest to 1e-8 and 1e-11 on this chain (2026-11-26)
                "gvi_methods": ((1, "lobatto"), *_GVI_HIGH, (4, "lobatto"), (6, "lobatto")),
                "handwritten": (
                    "verlet",
                    "gauss2-fixed-point",
                    "gauss4-fixed-point",
                    "gauss6-fixed-point",
                ),
                "time_cap": 0.5,
                "ivp_time_cap": 2.0,
            },
            "spring_chain_1000": {
                "gvi_methods": ((1, "lobatto"), (2, "gauss"), (4, "gauss"), (6, "gauss")),
                "handwritten": ("verlet", "gauss4-fixed-point", "gauss6-fixed-point"),
                "time_cap": 1.5,
                "ivp_time_cap": 3.0,
                "repeats": 2,
                "energy_samples": 100,
                "step_factor": 2.0,
            },
        },
    )


def tiny_config() -> BenchConfig:
    """A seconds-long smoke configuration (Kepler only), for tests."""
    return BenchConfig(
        problems=("kepler",),
        gvi_methods=((1, "lobatto"), (2, "gauss")),
        handwritten=("verlet", "gauss2"),
        ivp_methods=("DOP853",),
        ivp_min_rtol={"DOP853": 1e-6},
        step_factor=4.0,
        time_cap=0.01,
        ivp_time_cap=0.01,
        repeats=1,
        energy_samples=50,
        per_step_pairs=("s=2 Gauss(2) vs 2-stage Gauss",),
        per_step_problems=("kepler",),
        per_step_time=0.005,
        per_step_repeats=1,
    )


# ---------------------------------------------------------------------- curves
def gvi_label(s: int, family: str) -> str:
    """Curve label of galerkin_vi degree ``s`` with the given quadrature family."""
    return bm.method_label(gvi.Galerkin(s, bm.quadrature(s, family)))


def _gvi_curve(case: Case, s: int, family: str, cfg: BenchConfig) -> Curve:
    def energy(traj):
        return case.energy_from_momenta(traj.q, traj.p, traj)

    return bm.galerkin_curve(
        case.problem.system,
        gvi.Galerkin(s, bm.quadrature(s, family)),
        case.q0,
        case.v0,
        case.t_final,
        params=case.problem.params,
        n_start=case.n_start,
        step_factor=cfg.step_factor,
        energy_samples=cfg.energy_samples,
        energy=energy,
        warm_h=case.per_step_h,
        specialize=cfg.specialize,
    )


def _composition_curve(case: Case, order: int, cfg: BenchConfig) -> Curve:
    def energy(traj):
        return case.energy_from_momenta(traj.q, traj.p, traj)

    return bm.galerkin_curve(
        case.problem.system,
        gvi.Composition(order),
        case.q0,
        case.v0,
        case.t_final,
        params=case.problem.params,
        n_start=case.n_start,
        step_factor=cfg.step_factor,
        energy_samples=cfg.energy_samples,
        energy=energy,
        warm_h=case.per_step_h,
        specialize=cfg.specialize,
    )


def _hw_runner(case: Case, kernel: str) -> tuple[Callable, int]:
    pid, q0, v0, prm = case.problem_id, case.q0, case.v0, case.hw_params
    if kernel == "verlet":
        return (lambda h, n, every: hw.run_verlet(pid, q0, v0, h, n, every, params=prm)), 2
    if kernel.startswith("gauss"):
        s_text, _, variant = kernel[5:].partition("-")
        s = int(s_text)
        iteration = variant or "full"

        def run(h, n, every):
            return hw.run_gauss(pid, s, q0, v0, h, n, every, iteration=iteration, params=prm)

        return run, 2 * s
    if kernel.startswith("lobatto"):
        r = int(kernel[7:])
        return (
            lambda h, n, every: hw.run_lobatto(pid, r, q0, v0, h, n, every, params=prm)
        ), 2 * r - 2
    raise ValueError(f"unknown hand-written kernel {kernel!r}")


def _hw_curve(case: Case, kernel: str, cfg: BenchConfig) -> Curve:
    run, order = _hw_runner(case, kernel)
    T = case.t_final
    samples = cfg.energy_samples

    def timed(n):
        return run(T / n, int(n), int(n))

    def sample(n):
        n = int(n)
        res = run(T / n, n, bm.every(n, samples))
        e = hw.energy(case.problem_id, res.q, res.p, case.hw_params)
        return Sample(res.q[-1], e, {"newton_iterations": res.mean_newton_iterations})

    def warm():
        return run(case.per_step_h, 10, 1)

    return Curve(
        f"hand-written {_HW_LABELS[kernel]}",
        "hand-written",
        "fixed-step",
        order,
        sample,
        timed,
        warm,
        sweep=bm.step_counts(case.n_start, cfg.step_factor),
    )


def _state_energy(case: Case, q: NDArray, v: NDArray) -> NDArray:
    return hw.energy(
        case.problem_id, np.ascontiguousarray(q), np.ascontiguousarray(v), case.hw_params
    )


def _ivp_curve(case: Case, method: str, cfg: BenchConfig) -> Curve:
    y0 = np.concatenate([case.q0, case.v0])
    d = case.dim
    extra = {"jac": case.jac} if method == "Radau" else {}

    def timed(rtol):
        sol = solve_ivp(
            case.rhs, (0.0, case.t_final), y0, method=method, rtol=rtol, atol=rtol, **extra
        )
        if not sol.success:
            raise RuntimeError(f"solve_ivp({method}) failed: {sol.message}")
        return sol

    def sample(rtol):
        sol = timed(rtol)
        e = _state_energy(case, sol.y[:d].T, sol.y[d:].T)
        return Sample(sol.y[:d, -1].copy(), e, {"nfev": int(sol.nfev), "steps": sol.t.size - 1})

    def warm():
        return solve_ivp(
            case.rhs, (0.0, case.per_step_h), y0, method=method, rtol=1e-6, atol=1e-6, **extra
        )

    return Curve(
        f"scipy {method}",
        "scipy",
        "adaptive",
        None,
        sample,
        timed,
        warm,
        param_key="rtol",
        sweep=bm.tolerances(1e-3, cfg.ivp_min_rtol.get(method, 1e-10), cfg.rtol_factor),
    )


def _numbalsoda_curve(case: Case, cfg: BenchConfig) -> Curve:
    """numbalsoda's DOP853 (Hairer's code, compiled), the same right-hand side as a C callback."""
    dop853 = numbalsoda_dop853()
    address = hw.numbalsoda_rhs_address()
    y0 = np.concatenate([case.q0, case.v0])
    d = case.dim
    data = hw.numbalsoda_data(case.problem_id, y0.size, case.hw_params)
    ends = np.array([0.0, case.t_final])
    grid = np.linspace(0.0, case.t_final, cfg.energy_samples + 1)

    def solve(rtol, t_eval):
        u, ok = dop853(address, y0, t_eval, data=data, rtol=rtol, atol=rtol, mxstep=1_000_000_000)
        if not ok:
            raise RuntimeError(f"numbalsoda dop853 failed at rtol {rtol:g}")
        return u

    def sample(rtol):
        u = solve(rtol, grid)
        return Sample(u[-1, :d].copy(), _state_energy(case, u[:, :d], u[:, d:]), {})

    def warm():
        return solve(1e-6, np.array([0.0, case.per_step_h]))

    return Curve(
        "numbalsoda DOP853",
        "numbalsoda",
        "adaptive",
        None,
        sample,
        lambda rtol: solve(rtol, ends),
        warm,
        param_key="rtol",
        sweep=bm.tolerances(1e-3, cfg.ivp_min_rtol.get("numbalsoda", 1e-15), cfg.rtol_factor),
    )


def _ias15_curve(case: Case, cfg: BenchConfig) -> Curve:
    """REBOUND IAS15 (adaptive, 15th order), swept over its ``epsilon``."""
    setup: ReboundSetup = case.rebound
    T = case.t_final
    samples = cfg.energy_samples

    def simulation(eps):
        sim = setup.simulation()
        sim.integrator = "ias15"
        sim.integrator.epsilon = eps
        return sim

    def timed(eps):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sim = simulation(eps)
            sim.integrate(T, exact_finish_time=1)
        return setup.state(sim)

    def sample(eps):
        sim = simulation(eps)
        qs, vs = [], []
        for k in range(1, samples + 1):
            sim.integrate(T * k / samples, exact_finish_time=int(k == samples))
            q, v = setup.state(sim)
            qs.append(q)
            vs.append(v)
        steps = int(getattr(sim, "steps_done", 0))
        return Sample(qs[-1], _state_energy(case, np.array(qs), np.array(vs)), {"steps": steps})

    def warm():
        sim = simulation(1e-9)
        sim.integrate(case.per_step_h, exact_finish_time=1)

    return Curve(
        "REBOUND IAS15",
        "REBOUND",
        "adaptive",
        15,
        sample,
        timed,
        warm,
        param_key="epsilon",
        sweep=bm.tolerances(1e-2, cfg.ivp_min_rtol.get("IAS15", 1e-10), cfg.rtol_factor),
    )


def _whfast_curve(case: Case, cfg: BenchConfig) -> Curve:
    """REBOUND WHFast (Wisdom–Holman, Jacobi coordinates, symplectic corrector of order 11)."""
    setup: ReboundSetup = case.rebound
    T = case.t_final
    samples = cfg.energy_samples

    def simulation(n):
        sim = setup.simulation()
        sim.integrator = "whfast"
        sim.integrator.corrector = 11
        sim.integrator.safe_mode = 0
        sim.dt = T / n
        return sim

    def timed(n):
        sim = simulation(int(n))
        sim.steps(int(n))
        sim.synchronize()
        return setup.state(sim)

    def sample(n):
        n = int(n)
        sim = simulation(n)
        sim.integrator.keep_unsynchronized = 1  # outputs do not perturb the run
        every = bm.every(n, samples)
        qs, vs = [], []
        done = 0
        while done < n:
            k = min(every, n - done)
            sim.steps(k)
            done += k
            sim.synchronize()
            q, v = setup.state(sim)
            qs.append(q)
            vs.append(v)
        return Sample(qs[-1], _state_energy(case, np.array(qs), np.array(vs)), {})

    def warm():
        sim = simulation(100)
        sim.steps(10)
        sim.synchronize()

    return Curve(
        "REBOUND WHFast",
        "REBOUND",
        "fixed-step",
        2,
        sample,
        timed,
        warm,
        sweep=bm.step_counts(case.n_start, cfg.step_factor),
    )


def _curves(case: Case, cfg: BenchConfig, log: Callable[[str], None]) -> list[Curve]:
    """Every curve of ``case`` under ``cfg`` (peers that do not apply or import are skipped)."""
    curves = [_gvi_curve(case, s, fam, cfg) for s, fam in cfg.gvi_methods]
    if composition_obstacle(case.problem.system) is None:
        curves += [_composition_curve(case, order, cfg) for order in cfg.compositions]
    curves += [_hw_curve(case, k, cfg) for k in cfg.handwritten if case.hw_allowed(k)]
    methods = [m for m in cfg.ivp_methods if case.ivp_methods is None or m in case.ivp_methods]
    curves += [_ivp_curve(case, m, cfg) for m in methods]
    if "numbalsoda" in cfg.peers:
        if numbalsoda_available():
            curves.append(_numbalsoda_curve(case, cfg))
        else:
            log("  numbalsoda is not installed: its DOP853 peer is skipped")
    wanted = [p for p in ("ias15", "whfast") if p in cfg.peers]
    if case.rebound is not None and any(p in case.rebound.integrators for p in wanted):
        if not rebound_available():
            log("  rebound is not importable (pip install rebound): REBOUND peers skipped")
        else:
            if "ias15" in wanted and "ias15" in case.rebound.integrators:
                curves.append(_ias15_curve(case, cfg))
            if "whfast" in wanted and "whfast" in case.rebound.integrators:
                curves.append(_whfast_curve(case, cfg))
    return curves


# ---------------------------------------------------------------------- sweeps
def _sweep(case: Case, curve: Curve, cfg: BenchConfig, log: Callable[[str], None]) -> None:
    """Fill ``curve.points`` by one sweep against the case's reference.

    See :func:`galerkin_vi.tools.benchmark.sweep`.
    """
    bm.sweep(curve, case.q_ref, case.energy0, case.t_final, cfg.time_cap, cfg.ivp_time_cap, log)


# ----------------------------------------------------------------- time to error
def best_peer_ratios(entry: dict, target: str) -> dict[str, tuple[str, float] | None]:
    """Per peer family, the fastest curve of that family at ``target``: (label, ratio to gvi).

    Families: ``"DOP853"`` (scipy), ``"scipy"`` (any scipy method), ``"hand-written"``,
    ``"numbalsoda"``, ``"IAS15"``, ``"WHFast"``. Missing when no such curve
    reached the target or galerkin_vi did not.
    """
    ratios = entry["ratio_peer_over_best"][target]
    curves = entry["curves"]
    groups = {
        "DOP853": lambda lab: lab == "scipy DOP853",
        "scipy": lambda lab: curves[lab]["family"] == "scipy",
        "hand-written": lambda lab: curves[lab]["family"] == "hand-written",
        "numbalsoda": lambda lab: curves[lab]["family"] == "numbalsoda",
        "IAS15": lambda lab: lab == "REBOUND IAS15",
        "WHFast": lambda lab: lab == "REBOUND WHFast",
    }
    out: dict[str, tuple[str, float] | None] = {}
    for key, member in groups.items():
        found = [(r, lab) for lab, r in ratios.items() if member(lab) and r is not None]
        present = any(member(lab) for lab in ratios)
        if not present:
            continue
        out[key] = (min(found)[1], min(found)[0]) if found else None
    return out


# ------------------------------------------------------------------- per-step
def _per_step_row(case: Case, key: str, cfg: BenchConfig) -> dict:
    """galerkin_vi against its hand-written twin at the same h: interleaved repeats, minimum."""
    (s, family), kernel = PER_STEP_PAIRS[key]
    h = case.per_step_h
    prm = case.problem.params
    method = gvi.Galerkin(s, bm.quadrature(s, family))
    integ = gvi.Integrator(case.problem.system, method, specialize=cfg.specialize)
    run_hw, _ = _hw_runner(case, kernel)
    variants = {}
    if kernel.startswith("gauss"):
        for variant in ("simplified", "fixed-point"):
            variants[variant] = _hw_runner(case, f"{kernel}-{variant}")[0]

    def gvi_run(n, every):
        return integ.integrate(
            case.q0, case.v0, h=h, n_steps=n, save_every=every, params=prm, on_failure="raise"
        )

    # warm up, then size the runs so that one galerkin_vi run takes about per_step_time
    gvi_run(10, 10)
    run_hw(h, 10, 10)
    for run in variants.values():
        run(h, 10, 10)
    probe = 2000
    t_probe = bm.clock(lambda: gvi_run(probe, probe))
    n = int(min(2_000_000, max(1000, probe * cfg.per_step_time / max(t_probe, 1e-9))))
    t_gvi = t_hw = math.inf
    t_var = dict.fromkeys(variants, math.inf)
    for _ in range(cfg.per_step_repeats):
        t_gvi = min(t_gvi, bm.clock(lambda: gvi_run(n, n)))
        t_hw = min(t_hw, bm.clock(lambda: run_hw(h, n, n)))
        for name, run in variants.items():
            try:
                t_var[name] = min(t_var[name], bm.clock(lambda r=run: r(h, n, n)))
            except RuntimeError:
                pass
    overhead = min(bm.clock(lambda: gvi_run(1, 1)) for _ in range(5))

    def ns(t):
        return 1e9 * t / n if math.isfinite(t) else None

    return {
        "problem": case.name,
        "pair": key,
        "h": h,
        "n_steps": n,
        "gvi_ns_per_step": 1e9 * t_gvi / n,
        "hw_ns_per_step": 1e9 * t_hw / n,
        "ratio": t_gvi / t_hw,
        "gvi_newton_iterations": gvi_run(n, n).mean_newton_iterations,
        "hw_newton_iterations": run_hw(h, n, n).mean_newton_iterations,
        "hw_simplified_ns_per_step": ns(t_var["simplified"]) if variants else None,
        "hw_fixed_point_ns_per_step": ns(t_var["fixed-point"]) if variants else None,
        "gvi_call_overhead_us": 1e6 * overhead,
    }


def _per_step(case: Case, cfg: BenchConfig, log: Callable[[str], None]) -> list[dict]:
    rows = []
    for key in cfg.per_step_pairs:
        row = _per_step_row(case, key, cfg)
        log(
            f"  per step {case.name:8s} {key:45s} gvi {row['gvi_ns_per_step']:9.1f} ns  "
            f"hand-written {row['hw_ns_per_step']:9.1f} ns  ratio {row['ratio']:5.2f}"
        )
        rows.append(row)
    return rows


# ------------------------------------------------------------------ chain cost
CHAIN_COST_H = 0.1


def chain_cost(
    sizes: Sequence[int],
    n_steps: int = 300,
    repeats: int = 5,
    log: Callable[[str], None] = print,
) -> list[dict]:
    """Cost per step of galerkin_vi s = 2 Gauss(2) on :func:`chain_problem` (N masses), h = 0.1.

    For each N: ns/step of galerkin_vi (its banded Newton loop from N = 8), of the
    hand-written Störmer–Verlet and 2-stage Gauss (fixed point) kernels, the
    mean Newton iterations and the growth from the previous N. Every N runs the
    same ``n_steps`` steps (Störmer–Verlet 20 times as many), so that the
    iteration counts average over the same stretch of the motion; minimum over
    ``repeats`` interleaved rounds. galerkin_vi's time per step leaves out the fixed
    cost of its ``integrate`` call (the time of a 1-step call, reported as ``gvi_call_ms``).
    """
    rows: list[dict] = []
    h = CHAIN_COST_H
    spring = hw.springs_params(1.0, CHAIN_BETA, 1.0, CHAIN_BETA, 1.0)
    n = int(n_steps)
    n_verlet = 20 * n
    for n_masses in sizes:
        start = time.perf_counter()
        prob = chain_problem(int(n_masses))
        integ = gvi.Integrator(prob.system, gvi.Galerkin(2, gvi.gauss_legendre(2)))

        def gvi_run(steps, integ=integ, prob=prob):
            return integ.integrate(
                prob.q0, prob.v0, h=h, n_steps=steps, save_every=steps, params=prob.params
            )

        def verlet(steps, prob=prob):
            return hw.run_verlet(hw.SPRINGS, prob.q0, prob.v0, h, steps, steps, params=spring)

        def gauss2(steps, prob=prob):
            return hw.run_gauss(
                hw.SPRINGS,
                2,
                prob.q0,
                prob.v0,
                h,
                steps,
                steps,
                iteration="fixed-point",
                params=spring,
            )

        gvi_run(5)
        verlet(5)
        gauss2(5)
        setup = time.perf_counter() - start
        jobs = {
            "gvi": functools.partial(gvi_run, n),
            "gvi_call": functools.partial(gvi_run, 1),
            "verlet": functools.partial(verlet, n_verlet),
            "gauss": functools.partial(gauss2, n),
        }
        best = dict.fromkeys(jobs, math.inf)
        for _ in range(repeats):
            for key, job in jobs.items():
                best[key] = min(best[key], bm.clock(job))
        # the fixed cost of an integrate call grows with N (23 ms at N = 1000: Legendre
        # transform, allocations): it is reported apart, not spread over the steps
        t_gvi = (best["gvi"] - best["gvi_call"]) * n / (n - 1)
        t_verlet, t_gauss = best["verlet"], best["gauss"]
        try:
            banded = bool(integ._spec.banded)
        except AttributeError:  # the integrator's internals changed
            banded = None
        row = {
            "n_masses": int(n_masses),
            "h": h,
            "n_steps": n,
            "gvi_ns_per_step": 1e9 * t_gvi / n,
            "gvi_call_ms": 1e3 * best["gvi_call"],
            "gvi_newton_iterations": gvi_run(n).mean_newton_iterations,
            "gvi_banded": banded,
            "gvi_constant_mass": bool(integ.uses_constant_mass),
            "hw_verlet_ns_per_step": 1e9 * t_verlet / n_verlet,
            "hw_gauss2_fixed_point_ns_per_step": 1e9 * t_gauss / n,
            "hw_gauss2_fixed_point_iterations": gauss2(n).mean_newton_iterations,
            "setup_seconds": setup,
        }
        if rows:
            prev = rows[-1]
            row["growth_from_previous"] = row["gvi_ns_per_step"] / prev["gvi_ns_per_step"]
            row["hw_gauss2_growth_from_previous"] = (
                row["hw_gauss2_fixed_point_ns_per_step"] / prev["hw_gauss2_fixed_point_ns_per_step"]
            )
        log(
            f"  chain N = {n_masses:5d}: galerkin_vi s=2 Gauss(2) {row['gvi_ns_per_step']:10.0f} "
            f"ns/step ({row['gvi_newton_iterations']:.2f} its), hand-written 2-stage Gauss "
            f"(fixed point) {row['hw_gauss2_fixed_point_ns_per_step']:9.0f} ns/step, Verlet "
            f"{row['hw_verlet_ns_per_step']:8.0f} ns/step; set-up {setup:.1f} s"
        )
        rows.append(row)
    return rows


def chain_growth(rows: Sequence[dict], small: int = 100, large: int = 1000) -> float | None:
    """galerkin_vi's cost per step at N = ``large`` over that at N = ``small`` (issue: <= 15)."""
    by_n = {r["n_masses"]: r["gvi_ns_per_step"] for r in rows}
    if small in by_n and large in by_n:
        return by_n[large] / by_n[small]
    return None


# ------------------------------------------------------------------------ run
def _machine() -> dict:
    cpu = platform.processor()
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    import numba
    import scipy

    out = {
        "cpu": cpu,
        "cpus": os.cpu_count(),
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "numpy": np.__version__,
        "scipy": scipy.__version__,
        "numba": numba.__version__,
        "galerkin_vi": gvi.__version__,
    }
    for name in ("rebound", "numbalsoda"):
        try:
            from importlib.metadata import version

            out[name] = version(name)
        except Exception:  # not installed
            out[name] = None
    return out


def _load() -> list[float] | None:
    try:
        return [round(x, 2) for x in os.getloadavg()]
    except OSError:
        return None


def run_benchmark(cfg: BenchConfig, quick: bool, log: Callable[[str], None] = print) -> dict:
    """Run the whole benchmark described by ``cfg``; return the results as plain data."""
    start = time.perf_counter()
    results: dict = {
        "meta": {
            "quick": quick,
            "date": time.strftime("%Y-%m-%d %H:%M:%S %z"),
            "machine": _machine(),
            "load_average_start": _load(),
            "config": asdict(cfg),
            "timer": "time.perf_counter, minimum over repeats in interleaved rounds",
            "error": "final relative position error |q_N - q(T)| / |q(T)| (2-norm)",
            "energy_error": "max_k |H_k - H_0| / |H_0| over the saved states",
        },
        "problems": {},
        "per_step": [],
        "chain_cost": [],
    }
    for name in cfg.problems:
        pcfg = cfg.for_problem(name)
        t0 = time.perf_counter()
        case = make_case(name)
        log(
            f"[{name}] T = {case.t_final:.6g}, reference: {case.reference} "
            f"({time.perf_counter() - t0:.1f} s)"
        )
        curves = _curves(case, pcfg, log)
        warm = {}
        for c in curves:
            try:
                warm[c.label] = bm.clock(c.warm)
            except Exception as exc:  # a peer that cannot run here is dropped, with a note
                log(f"  {c.label}: warm-up failed ({type(exc).__name__}: {exc}); skipped")
                warm[c.label] = None
        curves = [c for c in curves if warm[c.label] is not None]
        log(f"  warm-up (compile or load) {time.perf_counter() - start:.1f} s since start")
        checks = reference_checks(case)
        for curve in curves:
            _sweep(case, curve, pcfg, log)
            if curve.points:
                last = curve.points[-1]
                log(
                    f"  {curve.label:52s} {len(curve.points):3d} points, last: "
                    f"{last['time']:.3g} s, error {last['error']:.2e}"
                )
        curves = [c for c in curves if c.points]
        bm.retime(curves, pcfg.repeats)
        entry = {
            "title": case.title,
            "setting": case.setting,
            "t_final": case.t_final,
            "reference": case.reference,
            "reference_position": case.q_ref.tolist(),
            "reference_checks": checks,
            "energy0": case.energy0,
            "first_call_seconds": {k: v for k, v in warm.items() if v is not None},
            "seconds": time.perf_counter() - t0,
            "curves": {
                c.label: {
                    "family": c.family,
                    "kind": c.kind,
                    "order": c.order,
                    "param": c.param_key,
                    "points": c.points,
                }
                for c in curves
            },
        }
        entry.update(bm.summarise(curves, pcfg.targets))
        results["problems"][name] = entry
        log(
            f"  {name} done in {entry['seconds']:.1f} s ({time.perf_counter() - start:.1f} s total)"
        )
    for name in cfg.per_step_problems:
        if name not in cfg.problems or not cfg.per_step_pairs:
            continue
        case = make_case(name)
        if case.separable and case.dim <= 20:
            results["per_step"] += _per_step(case, cfg, log)
    if cfg.chain_cost_sizes:
        log("[chain cost per step]")
        results["chain_cost"] = chain_cost(
            cfg.chain_cost_sizes, cfg.chain_cost_steps, cfg.per_step_repeats, log
        )
    results["meta"]["load_average_end"] = _load()
    results["meta"]["elapsed_seconds"] = time.perf_counter() - start
    return results
