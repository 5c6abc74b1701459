r"""The benchmark problems: settings, references and how each peer sees them.

:func:`make_case` builds a :class:`Case` per name in :data:`PROBLEMS` and
computes its reference final position once per process (cached): exact for
the pendulum and Kepler, the 6-stage Gauss method at a small step for the outer
solar system, DOP853 at scipy's tightest tolerance for the others, each with
independent cross-checks (:func:`reference_checks`). The hand-written kernels,
scipy and numbalsoda see a case through its problem id and parameter vector
(:mod:`.handwritten`), REBOUND through a :class:`ReboundSetup`.
"""

from __future__ import annotations

import functools
import importlib.util
import os
import warnings
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import mpmath
import numpy as np
from numpy.typing import NDArray
from scipy.integrate import solve_ivp

import galerkin_vi as gvi
from galerkin_vi import problems

from . import handwritten as hw

__all__ = [
    "CHAIN_BETA",
    "CHAIN_PULSE",
    "PROBLEMS",
    "REFERENCE_ATOL",
    "REFERENCE_RTOL",
    "Case",
    "ReboundSetup",
    "chain_problem",
    "make_case",
    "numbalsoda_available",
    "numbalsoda_dop853",
    "rebound_available",
    "reference_checks",
    "solar_rebound_setup",
    "solar_system_constants",
]

#: every benchmark problem (``spring_chain_N`` for any N >= 2 works too)
PROBLEMS = (
    "pendulum",
    "kepler",
    "outer_solar_system",
    "henon_heiles",
    "double_pendulum",
    "fpu",
    "spring_chain_100",
    "spring_chain_1000",
)


@dataclass(frozen=True)
class Case:
    """One benchmark problem: initial data, span, reference final position.

    ``v0`` are velocities; the hand-written kernels, scipy and REBOUND work in
    (q, v), galerkin_vi maps ``v0`` by its Legendre transform.
    """

    name: str
    title: str
    problem_id: int
    problem: problems.Problem
    q0: NDArray[np.float64]
    v0: NDArray[np.float64]
    t_final: float
    q_ref: NDArray[np.float64]
    reference: str
    energy0: float
    n_start: int
    per_step_h: float
    rhs: Callable
    jac: Callable
    hw_params: NDArray[np.float64] = field(default_factory=lambda: np.zeros(0))
    separable: bool = True
    ivp_methods: tuple[str, ...] | None = None
    rebound: Any = None  # ReboundSetup or None
    reference_checks: dict[str, float] = field(default_factory=dict)
    setting: str = ""

    @property
    def dim(self) -> int:
        return int(self.q0.size)

    def energy_from_momenta(self, q: NDArray, p: NDArray, traj=None) -> NDArray:
        """H at the rows of (q, p) (galerkin_vi's momenta).

        Separable problems: by the hand-written formula with v = M^-1 p (M diagonal,
        constant), which is exact and cheap; galerkin_vi's ``Trajectory.energy`` solves
        one mass-matrix system per row (1.5 s for 500 rows at N = 100).
        """
        if not self.separable and traj is not None:
            return traj.energy()
        inv_mass = hw.inverse_masses(self.problem_id, self.dim, self.hw_params)
        return hw.energy(self.problem_id, q, np.ascontiguousarray(p * inv_mass), self.hw_params)

    def hw_allowed(self, kernel: str) -> bool:
        """Whether the hand-written ``kernel`` applies to this problem.

        Separable problems only; above 20 coordinates only the kernels without a
        dense Jacobian (Störmer–Verlet, fixed-point Gauss), whose cost stays linear in N.
        """
        if not self.separable:
            return False
        return self.dim <= 20 or kernel == "verlet" or kernel.endswith("-fixed-point")


@dataclass(frozen=True)
class ReboundSetup:
    """How to put a case into a REBOUND simulation and read (q, v) back."""

    G: float
    masses: tuple[float, ...]
    positions: tuple[tuple[float, float, float], ...]
    velocities: tuple[tuple[float, float, float], ...]
    planar_test_particle: bool  # Kepler: q = position of particle 1 (x, y)
    integrators: tuple[str, ...]

    def simulation(self):
        import rebound

        sim = rebound.Simulation()
        sim.G = self.G
        for m, x, v in zip(self.masses, self.positions, self.velocities, strict=True):
            sim.add(m=m, x=x[0], y=x[1], z=x[2], vx=v[0], vy=v[1], vz=v[2])
        return sim

    def state(self, sim) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        ps = sim.particles
        if self.planar_test_particle:
            p0, p1 = ps[0], ps[1]
            return (
                np.array([p1.x - p0.x, p1.y - p0.y]),
                np.array([p1.vx - p0.vx, p1.vy - p0.vy]),
            )
        q = np.array([c for p in ps for c in (p.x, p.y, p.z)])
        v = np.array([c for p in ps for c in (p.vx, p.vy, p.vz)])
        return q, v


def rebound_available() -> bool:
    """Whether REBOUND can be imported."""
    try:
        import rebound  # noqa: F401
    except ImportError:
        return False
    return True


@functools.cache
def numbalsoda_dop853() -> Callable | None:
    """numbalsoda's ``dop853`` driver, or None when numbalsoda is not installed.

    Loaded from its module file alone: ``import numbalsoda`` also builds its
    ``solve_ivp`` driver, which takes about 10 s (numba, uncached) and is not used here.
    """
    try:
        found = importlib.util.find_spec("numbalsoda")
    except (ImportError, ValueError):
        found = None
    if found is None or not found.submodule_search_locations:
        return None
    path = os.path.join(next(iter(found.submodule_search_locations)), "driver_dop853.py")
    try:
        spec = importlib.util.spec_from_file_location("_galerkin_vi_numbalsoda_dop853", path)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module.dop853
    except Exception:  # noqa: BLE001 - layout changed or library missing: the full import
        try:
            import numbalsoda
        except (ImportError, OSError):
            return None
        return numbalsoda.dop853


def numbalsoda_available() -> bool:
    """Whether numbalsoda's DOP853 can be loaded."""
    return numbalsoda_dop853() is not None


def _pendulum_exact(q0: float, t: float, dps: int = 40) -> float:
    """Pendulum released from rest at ``q0``: 2 asin(k cd(t | k^2)), k = sin(q0/2)."""
    with mpmath.workdps(dps):
        k = mpmath.sin(mpmath.mpf(q0) / 2)
        return float(2 * mpmath.asin(k * mpmath.ellipfun("cd", mpmath.mpf(t), m=k * k)))


def _kepler_exact(t: float, e: float, dps: int = 40) -> NDArray[np.float64]:
    """Kepler orbit (a = mu = 1, perihelion at t = 0) at the float time ``t``, mpmath at 40 digits.

    The mean anomaly is reduced modulo 2 pi in extended precision, so the only
    error is the final rounding (``kepler_position`` reduces in float64: 6e-14 off here).
    """
    with mpmath.workdps(dps):
        ecc = mpmath.mpf(e)
        mean = mpmath.fmod(mpmath.mpf(t), 2 * mpmath.pi)
        E = mpmath.findroot(lambda x: x - ecc * mpmath.sin(x) - mean, mean + ecc * mpmath.sin(mean))
        return np.array(
            [float(mpmath.cos(E) - ecc), float(mpmath.sqrt(1 - ecc * ecc) * mpmath.sin(E))]
        )


def _ivp_functions(problem_id: int, prm: NDArray) -> tuple[Callable, Callable]:
    """scipy's ``fun(t, y)`` and ``jac(t, y)`` from the hand-derived numba functions."""
    prm = np.ascontiguousarray(prm, dtype=float)

    def fun(t, y):
        return hw.rhs(problem_id, y, prm)

    def jacobian(t, y):
        return hw.jac(problem_id, y, prm)

    return fun, jacobian


#: scipy refuses rtol below 100 eps (it raises it, with a warning): its tightest setting
REFERENCE_RTOL = 2.3e-14
REFERENCE_ATOL = 1e-16


def _dop853_final(fun, q0, v0, t_final: float) -> NDArray[np.float64]:
    """DOP853 at scipy's tightest rtol (100 eps) and atol 1e-16: the final position."""
    sol = solve_ivp(
        fun,
        (0.0, t_final),
        np.concatenate([q0, v0]),
        method="DOP853",
        rtol=REFERENCE_RTOL,
        atol=REFERENCE_ATOL,
    )
    if not sol.success:
        raise RuntimeError(f"reference DOP853 failed: {sol.message}")
    return sol.y[: q0.size, -1].copy()


def _gvi_final(prob: problems.Problem, s: int, n: int, t_final: float, q0, v0) -> NDArray:
    """galerkin_vi degree s with gauss_legendre(s), n steps over [0, t_final]: final position."""
    integ = gvi.Integrator(prob.system, gvi.Galerkin(s, gvi.gauss_legendre(s)))
    traj = integ.integrate(
        q0, v0, h=t_final / n, n_steps=n, save_every=n, params=prob.params, on_failure="raise"
    )
    return traj.q[-1].copy()


def _hw_gauss_final(pid: int, prm, s: int, n: int, t_final: float, q0, v0) -> NDArray:
    """The hand-written s-stage Gauss kernel, n steps: final position.

    Fixed-point iteration: at the small reference steps it contracts fast (even on
    FPU, h omega = 0.1), and full Newton costs 0.7 ms a step on the solar system.
    """
    run = hw.run_gauss(pid, s, q0, v0, t_final / n, n, n, iteration="fixed-point", params=prm)
    return run.q[-1].copy()


def _rel(a: NDArray, ref: NDArray) -> float:
    return float(np.linalg.norm(a - ref) / np.linalg.norm(ref))


def _numeric_case(
    name: str,
    title: str,
    setting: str,
    prob: problems.Problem,
    pid: int,
    prm: NDArray,
    q0: NDArray,
    v0: NDArray,
    t_final: float,
    n_ref: int,
    n_start: int,
    per_step_h: float,
    separable: bool = True,
    ivp_methods: tuple[str, ...] | None = None,
) -> Case:
    """A case whose reference is DOP853 at scipy's tightest tolerance.

    Cross-checked against galerkin_vi s = 6 Gauss(6) and (separable problems)
    the hand-written 6-stage Gauss kernel, both with ``n_ref`` steps.
    """
    fun, jacobian = _ivp_functions(pid, prm)
    q_ref = _dop853_final(fun, q0, v0, t_final)
    h_ref = t_final / n_ref
    checks = {
        f"gvi_s6_gauss6_h{h_ref:.3g}": _rel(_gvi_final(prob, 6, n_ref, t_final, q0, v0), q_ref)
    }
    if separable:
        checks[f"handwritten_gauss6_h{h_ref:.3g}"] = _rel(
            _hw_gauss_final(pid, prm, 6, n_ref, t_final, q0, v0), q_ref
        )
    return Case(
        name=name,
        title=title,
        problem_id=pid,
        problem=prob,
        q0=q0,
        v0=v0,
        t_final=t_final,
        q_ref=q_ref,
        reference=(
            f"DOP853 (scipy, numba right-hand side) at rtol = {REFERENCE_RTOL:g} "
            f"(scipy's floor, 100 eps), atol = {REFERENCE_ATOL:g}"
        ),
        energy0=float(hw.energy(pid, q0[None, :], v0[None, :], prm)[0]),
        n_start=n_start,
        per_step_h=per_step_h,
        rhs=fun,
        jac=jacobian,
        hw_params=prm,
        separable=separable,
        ivp_methods=ivp_methods,
        reference_checks=checks,
        setting=setting,
    )


#: spring chain: a Gaussian velocity pulse of this amplitude and width (in masses), mid-chain
CHAIN_PULSE = (1.0, 3.0)
CHAIN_BETA = 1.0


def chain_problem(n_masses: int) -> problems.Problem:
    """The benchmark's FPU-beta spring chain: k = m = 1, beta = 1, a velocity pulse mid-chain.

    At rest (q = 0), with :math:`v_i = A\\exp(-((i - (N+1)/2)/w)^2)`, A = 1,
    w = 3: the pulse excites the whole spectrum (frequencies up to 2) and
    stretches the springs it passes by up to about 0.5, where the quartic
    force :math:`\\beta e^3` is a quarter of the linear one.
    """
    amp, width = CHAIN_PULSE
    i = np.arange(1, n_masses + 1)
    v0 = amp * np.exp(-(((i - (n_masses + 1) / 2) / width) ** 2))
    return problems.spring_chain(n_masses, beta=CHAIN_BETA, q0=np.zeros(n_masses), v0=v0)


@functools.cache
def make_case(name: str) -> Case:
    """The benchmark problem ``name`` (one of :data:`PROBLEMS`), its reference computed once.

    * ``pendulum``: q0 = 1.5, v0 = 0, T = 100; exact reference.
    * ``kepler``: e = 0.6, 50 periods; exact reference.
    * ``outer_solar_system``: HLW's six bodies, T = 200 000 days. Reference: the
      6-stage Gauss method (= galerkin_vi s = 6 Gauss(6)) at h = 20 days, run by
      the hand-written kernel, whose round-off floor is lower (see
      ``reference_checks``: galerkin_vi's own run, DOP853 and REBOUND IAS15).
    * ``henon_heiles``: the library default (chaotic, H = 1/8), T = 50.
    * ``double_pendulum``: the library default, T = 20 (non-separable).
    * ``fpu``: Fermi–Pasta–Ulam, m = 3, omega = 50, T = 50.
    * ``spring_chain_N``: :func:`chain_problem` (beta = 1), T = 100.

    The last four take DOP853 at scipy's tightest tolerance as reference,
    cross-checked against galerkin_vi s = 6 Gauss(6) and the hand-written 6-stage Gauss.
    """
    if name == "pendulum":
        prob = problems.pendulum(1.5, 0.0)
        t_final = 100.0
        q_ref = np.array([_pendulum_exact(1.5, t_final)])
        fun, jacobian = _ivp_functions(hw.PENDULUM, hw.NO_PARAMS)
        return Case(
            name="pendulum",
            title="Pendulum",
            problem_id=hw.PENDULUM,
            problem=prob,
            q0=prob.q0.copy(),
            v0=prob.v0.copy(),
            t_final=t_final,
            q_ref=q_ref,
            reference="exact: 2 asin(k cd(T | k^2)), k = sin(0.75), mpmath at 40 digits",
            energy0=float(
                hw.energy(hw.PENDULUM, prob.q0[None, :], prob.v0[None, :], hw.NO_PARAMS)[0]
            ),
            n_start=50,
            per_step_h=0.1,
            rhs=fun,
            jac=jacobian,
            setting="L = v²/2 + cos q, q0 = 1.5, v0 = 0, T = 100",
        )
    if name == "kepler":
        e = 0.6
        prob = problems.kepler(e)
        t_final = 50 * 2 * np.pi
        fun, jacobian = _ivp_functions(hw.KEPLER, hw.NO_PARAMS)
        return Case(
            name="kepler",
            title="Kepler",
            problem_id=hw.KEPLER,
            problem=prob,
            q0=prob.q0.copy(),
            v0=prob.v0.copy(),
            t_final=t_final,
            q_ref=_kepler_exact(t_final, e),
            reference="exact: Kepler's equation solved with mpmath at 40 digits",
            energy0=float(
                hw.energy(hw.KEPLER, prob.q0[None, :], prob.v0[None, :], hw.NO_PARAMS)[0]
            ),
            n_start=50 * 16,
            per_step_h=2 * np.pi / 200,
            rhs=fun,
            jac=jacobian,
            rebound=ReboundSetup(
                G=1.0,
                masses=(1.0, 0.0),
                positions=((0.0, 0.0, 0.0), (float(prob.q0[0]), float(prob.q0[1]), 0.0)),
                velocities=((0.0, 0.0, 0.0), (float(prob.v0[0]), float(prob.v0[1]), 0.0)),
                planar_test_particle=True,
                integrators=("ias15",),
            ),
            setting="e = 0.6, 50 periods (T = 100π)",
        )
    if name == "outer_solar_system":
        return _solar_case()
    if name == "henon_heiles":
        prob = problems.henon_heiles()
        return _numeric_case(
            name,
            "Hénon–Heiles",
            "library default: q0 = (0, -0.2), H = 1/8 (chaotic), T = 50",
            prob,
            hw.HENON_HEILES,
            hw.NO_PARAMS,
            prob.q0.copy(),
            prob.v0.copy(),
            50.0,
            n_ref=2000,
            n_start=25,
            per_step_h=0.1,
        )
    if name == "double_pendulum":
        prob = problems.double_pendulum()
        prm = np.array([prob.params[p] for p in prob.system.params], dtype=float)
        return _numeric_case(
            name,
            "Double pendulum",
            "library default: unit masses and lengths, g = 1, q0 = (1, 0.5), v0 = (0, 0.3), T = 20",
            prob,
            hw.DOUBLE_PENDULUM,
            prm,
            prob.q0.copy(),
            prob.v0.copy(),
            20.0,
            n_ref=2000,
            n_start=25,
            per_step_h=0.02,
            separable=False,
        )
    if name == "fpu":
        omega = 50.0
        prob = problems.fermi_pasta_ulam(3, omega)
        return _numeric_case(
            name,
            "Fermi–Pasta–Ulam",
            "m = 3 (6 masses), omega = 50, HLW I.5 initial data, T = 50",
            prob,
            hw.SPRINGS,
            hw.springs_params(0.0, 4.0, omega**2 / 2, 0.0),
            prob.q0.copy(),
            prob.v0.copy(),
            50.0,
            n_ref=25_000,
            n_start=500,
            per_step_h=0.005,
        )
    if name.startswith("spring_chain_"):
        n_masses = int(name.rsplit("_", 1)[1])
        if n_masses < 2:
            raise ValueError(f"spring chain needs at least 2 masses, got {n_masses}")
        prob = chain_problem(n_masses)
        amp, width = CHAIN_PULSE
        return _numeric_case(
            name,
            f"Spring chain N = {n_masses}",
            f"N = {n_masses} unit masses, k = 1, beta = {CHAIN_BETA:g} (FPU-beta), fixed ends, "
            f"at rest with a Gaussian velocity pulse (amplitude {amp:g}, width {width:g} masses) "
            "mid-chain, T = 100",
            prob,
            hw.SPRINGS,
            hw.springs_params(1.0, CHAIN_BETA, 1.0, CHAIN_BETA, 1.0),
            prob.q0.copy(),
            prob.v0.copy(),
            100.0,
            n_ref=2000,
            n_start=50,
            per_step_h=0.1,
            ivp_methods=None if n_masses <= 200 else ("DOP853", "RK45"),
        )
    raise ValueError(f"unknown benchmark problem {name!r}; use one of {', '.join(PROBLEMS)}")


def solar_system_constants(prob: problems.Problem | None = None) -> tuple[float, tuple[float, ...]]:
    """G and the masses of :func:`galerkin_vi.problems.outer_solar_system` (its parameters)."""
    prob = problems.outer_solar_system() if prob is None else prob
    by_name = {str(k): float(v) for k, v in prob.params.items()}
    return by_name["G"], tuple(by_name[f"m{i}"] for i in range(prob.q0.size // 3))


def solar_rebound_setup() -> ReboundSetup:
    """The outer solar system as REBOUND particles (HLW's data, G in AU^3 / (M_sun day^2))."""
    prob = problems.outer_solar_system()
    G, masses = solar_system_constants(prob)
    return ReboundSetup(
        G=G,
        masses=masses,
        positions=tuple(tuple(float(c) for c in x) for x in prob.q0.reshape(-1, 3)),
        velocities=tuple(tuple(float(c) for c in x) for x in prob.v0.reshape(-1, 3)),
        planar_test_particle=False,
        integrators=("ias15", "whfast"),
    )


def _solar_case() -> Case:
    prob = problems.outer_solar_system()
    prm = hw.n_body_params(*solar_system_constants(prob))
    q0, v0 = prob.q0.copy(), prob.v0.copy()
    t_final = 200_000.0
    # h = 20 days: not a step of any sweep (they double or multiply by sqrt(2) from 500 steps),
    # so that no curve point is the reference run itself
    n_ref = 10_000
    q_ref = _hw_gauss_final(hw.N_BODY, prm, 6, n_ref, t_final, q0, v0)
    fun, jacobian = _ivp_functions(hw.N_BODY, prm)
    setup = solar_rebound_setup()
    h_ref = t_final / n_ref
    checks = {
        f"gvi_s6_gauss6_h{h_ref:.3g}": _rel(_gvi_final(prob, 6, n_ref, t_final, q0, v0), q_ref),
        f"handwritten_gauss6_h{2 * h_ref:.3g}": _rel(
            _hw_gauss_final(hw.N_BODY, prm, 6, n_ref // 2, t_final, q0, v0), q_ref
        ),
        f"dop853_rtol{REFERENCE_RTOL:g}": _rel(_dop853_final(fun, q0, v0, t_final), q_ref),
    }
    if rebound_available():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sim = setup.simulation()
            sim.integrator = "ias15"
            sim.integrate(t_final, exact_finish_time=1)
        checks["rebound_ias15_eps1e-9"] = _rel(setup.state(sim)[0], q_ref)
    return Case(
        name="outer_solar_system",
        title="Outer solar system",
        problem_id=hw.N_BODY,
        problem=prob,
        q0=q0,
        v0=v0,
        t_final=t_final,
        q_ref=q_ref,
        reference=(
            "6-stage Gauss (the method of galerkin_vi s=6 Gauss(6)) at h = 20 days, "
            "run by the hand-written kernel (lower round-off floor than galerkin_vi's run)"
        ),
        energy0=float(hw.energy(hw.N_BODY, q0[None, :], v0[None, :], prm)[0]),
        n_start=500,
        per_step_h=50.0,
        rhs=fun,
        jac=jacobian,
        hw_params=prm,
        rebound=setup,
        reference_checks=checks,
        setting="HLW I.2: Sun (with the inner planets), Jupiter … Pluto in 3D, AU and days, "
        "T = 200 000 days",
    )


# ----------------------------------------------------------------- references
def reference_checks(case: Case) -> dict:
    """Independent checks of the reference (computed here for the exact ones)."""
    if case.name == "kepler":
        q = np.asarray(problems.kepler_position(case.t_final, 0.6), dtype=float)
        return {"kepler_position_float64_relative_difference": _rel(q, case.q_ref)}
    if case.name != "pendulum":
        return dict(case.reference_checks)
    n = int(round(case.t_final / 0.1))
    integ = gvi.Integrator(case.problem.system, gvi.Galerkin(6, gvi.gauss_legendre(6)))
    traj = integ.integrate(
        case.q0, case.v0, h=case.t_final / n, n_steps=n, save_every=n, on_failure="raise"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # scipy raises rtol to 100 eps
        sol = solve_ivp(
            case.rhs,
            (0.0, case.t_final),
            np.concatenate([case.q0, case.v0]),
            method="DOP853",
            rtol=1e-14,
            atol=1e-14,
        )
    return {
        "gvi_s6_gauss6_h0.1_relative_difference": _rel(traj.q[-1], case.q_ref),
        "dop853_rtol1e-14_relative_difference": _rel(sol.y[:1, -1], case.q_ref),
    }
