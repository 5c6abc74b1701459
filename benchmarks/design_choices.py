"""The measurements behind design choices cited in docs/design-notes.md.

Each study times the chosen way against the alternative it replaces, in one process,
best of several repeats, the time loops already compiled (run ``galerkin-vi warmup``
first). Not a test: it prints one line per measured point.

Usage::

    python benchmarks/design_choices.py                   # every study, about a minute
    python benchmarks/design_choices.py fixed-point-degree adaptive-newton
"""

from __future__ import annotations

import argparse
import pickle
import time
import timeit
from collections.abc import Callable

import numpy as np
import sympy as sp

import galerkin_vi as gvi
import galerkin_vi.run.loop_choice as loop_choice
from galerkin_vi import problems
from galerkin_vi.expression_walk import structural_bytes
from galerkin_vi.model.system import is_regular
from galerkin_vi.run.chunks import CHUNK_WORK


def best_seconds(call: Callable[[], object], number: int = 1, repeat: int = 5) -> float:
    """Smallest time of one call over ``repeat`` rounds of ``number`` calls (after one call)."""
    call()
    return min(timeit.repeat(call, number=number, repeat=repeat)) / number


def fixed_point_degree() -> None:
    """Gauss(2) on the double pendulum: simplified Newton against the varying-mass loop.

    Whole runs over t <= 20; ``MIN_FIXED_POINT_DEGREE`` is lowered to 2 here so that the
    fixed point runs Gauss(2) at all.
    """
    problem = problems.double_pendulum()
    method = gvi.Galerkin(2, gvi.gauss_legendre(2))
    loop_choice.MIN_FIXED_POINT_DEGREE = 2
    runs = {fp: gvi.Integrator(problem.system, method, fixed_point=fp) for fp in (True, False)}
    for h in (0.4, 0.2, 0.1, 0.05, 0.02):
        n = round(20.0 / h)
        best = {
            integrator.kernel_path: best_seconds(
                lambda i=integrator, h=h, n=n: i.integrate(
                    problem.q0, problem.v0, h=h, n_steps=n, save_every=n
                )
            )
            for integrator in runs.values()
        }
        ratio = best["newton"] / best["varying_mass"]
        print(
            f"h = {h:<5} newton {1e3 * best['newton']:.3f} ms, varying_mass "
            f"{1e3 * best['varying_mass']:.3f} ms: newton / varying_mass = {ratio:.2f}"
        )


def adaptive_newton() -> None:
    """AdaptiveIntegrator by Newton or by the fixed point: Kepler e = 0.9 over 20 periods and
    the Arenstorf orbit over one period (benchmarks/adaptive_three_body.py), Gauss(4)."""
    from adaptive_three_body import PERIOD, Q0, V0, arenstorf

    method = gvi.Galerkin(4, gvi.gauss_legendre(4))
    problem = problems.kepler(0.9)
    x, y = problem.system.q
    kepler = (problem.system, gvi.encounter_scaling([sp.sqrt(x**2 + y**2)], 1.5))
    three_body, r1, r2 = arenstorf()
    cases = {
        "kepler-0.9": (kepler, problem.q0, problem.v0, 40 * np.pi, (0.4, 0.2, 0.1, 0.05)),
        "arenstorf": ((three_body, gvi.encounter_scaling([r1, r2], 1.5)), Q0, V0, PERIOD,
                      (0.1, 0.02, 0.005)),
    }  # fmt: skip
    for name, ((system, g), q0, v0, t_final, steps) in cases.items():
        for h in steps:
            row = []
            for fixed_point in (False, True):
                adaptive = gvi.AdaptiveIntegrator(system, method, g=g, fixed_point=fixed_point)

                def run(a=adaptive, h=h, q0=q0, v0=v0, t_final=t_final):
                    return a.integrate(q0, v0, h=h, t_final=t_final, save_every=10**6)

                seconds = best_seconds(run, repeat=5)
                traj = run()
                error = np.abs(traj.q[-1] - (q0 if name == "arenstorf" else problem.exact(
                    np.array([t_final]))[0])).max() if traj.success else np.nan  # fmt: skip
                row.append(f"fixed_point={fixed_point}: {1e3 * seconds:7.2f} ms, "
                           f"error {error:.1e}")  # fmt: skip
            print(f"{name} h={h}: " + "; ".join(row))


def chunk_time() -> None:
    """Seconds of one chunk of ``CHUNK_WORK`` coordinate-steps, specialised and Newton loops."""
    for problem in (problems.pendulum(), problems.spring_chain(100)):
        steps = CHUNK_WORK // problem.system.n
        for specialize in (True, False):
            integrator = gvi.Integrator(problem.system, gvi.Galerkin(2), specialize=specialize)
            integrator.integrate(problem.q0, problem.v0, h=0.01, n_steps=10)
            start = time.perf_counter()
            integrator.integrate(problem.q0, problem.v0, h=0.01, n_steps=steps, save_every=steps)
            print(
                f"{problem.name}, {integrator.kernel_path} loop: {steps} steps in "
                f"{time.perf_counter() - start:.3f} s"
            )


def legendre_start() -> None:
    """The Legendre start (L_v, L_vv and the regularity test): NumPy expressions or compiled."""
    for problem in (problems.henon_heiles(), problems.spring_chain(100, beta=1.0)):
        system = problem.system
        prm = system.parameter_vector(None)
        q, v = np.asarray(problem.q0, float), np.asarray(problem.v0, float)

        def numpy_start(system=system, prm=prm, q=q, v=v) -> bool:
            system.evaluate("Lv", 0.0, q, v, prm)
            Lvv = np.asarray(system.evaluate("Lvv", 0.0, q, v, prm), float)
            n = system.n
            return is_regular(Lvv.reshape(n, n) if Lvv.size == n * n else np.diag(Lvv))

        compiled = gvi.Integrator(system, gvi.Galerkin(2)).run_spec.legendre
        for label, call in (
            ("NumPy expressions", numpy_start),
            ("compiled", lambda c=compiled, prm=prm, q=q, v=v: c.at(0.0, q, v, prm)),
        ):
            seconds = best_seconds(call, number=100)
            print(f"{problem.name}, {label}: {1e6 * seconds:.0f} us a call")


def analysis_key() -> None:
    """Bytes to hash of the Lagrangian of a 60-mass chain: pickles against srepr."""
    L = problems.spring_chain(60, beta=1.0).system.L
    for label, call in (
        ("pickle", lambda: pickle.dumps(L)),
        ("structural pickle", lambda: structural_bytes(L)),
        ("srepr", lambda: sp.srepr(L)),
    ):
        print(f"{label}: {1e3 * best_seconds(call, number=10):.2f} ms")


STUDIES: dict[str, Callable[[], None]] = {
    "fixed-point-degree": fixed_point_degree,
    "adaptive-newton": adaptive_newton,
    "chunk-time": chunk_time,
    "legendre-start": legendre_start,
    "analysis-key": analysis_key,
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("studies", nargs="*", help=f"any of {', '.join(STUDIES)} (default: all)")
    names = parser.parse_args().studies or list(STUDIES)
    unknown = [name for name in names if name not in STUDIES]
    if unknown:
        parser.error(f"unknown studies {unknown}; choose from {list(STUDIES)}")
    for name in names:
        print(f"== {name}: {STUDIES[name].__doc__.splitlines()[0]}")
        STUDIES[name]()


if __name__ == "__main__":
    main()
