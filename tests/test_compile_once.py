"""Loops compiled once per machine, point functions once per system (issue 13).

numba announces every real compilation (not a load from its disk cache) as a
``numba:compile`` event; these tests count them.
"""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sympy as sp
from numba.core import event

import galerkin_vi as gvi
from galerkin_vi import loops, problems
from galerkin_vi.codegen import compiled

q, v, k, c = sp.symbols("q v k c")


def _compilations(run) -> list[str]:
    with event.install_recorder("numba:compile") as recorder:
        run()
    return [str(e.data["dispatcher"].py_func.__name__) for _, e in recorder.buffer]


def _pendulum():
    return gvi.LagrangianSystem(v**2 / 2 - k * (1 - sp.cos(q)), [q], [v], params={k: 1.0})


def test_degree_quadrature_step_parameters_and_initial_data_never_compile():
    system = _pendulum()
    gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=3)
    gvi.Integrator(system, gvi.Galerkin(2), specialize=False).integrate(
        [1.0], [0.0], h=0.1, n_steps=3
    )
    points = compiled.load_point_functions(gvi.Integrator(system)._spec)
    functions_before = dict(points.compiled)

    def sweep():
        for method in (
            gvi.Galerkin(1, gvi.gauss_legendre(1)),
            gvi.Galerkin(3, gvi.gauss_lobatto(4)),
            gvi.Galerkin(4, gvi.gauss_legendre(5)),
            gvi.Galerkin(5, nodes="equidistant"),
            gvi.Galerkin(7, gvi.gauss_lobatto(9)),
        ):
            for specialize in (True, False):
                for h, kk, q0 in ((0.1, 1.0, 0.5), (-0.03, 4.0, 2.0)):
                    gvi.Integrator(system, method, specialize=specialize).integrate(
                        [q0], [0.1], h=h, n_steps=4, t0=h, params={k: kk}, save_every=3
                    )

    assert _compilations(sweep) == []
    assert points.compiled == functions_before  # no point function compiled again


def test_a_new_system_compiles_only_its_point_functions():
    # a Lagrangian never seen in this process (the coefficient makes it new)
    gvi.Integrator(_pendulum(), gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=2)
    coefficient = 1.0 + np.random.default_rng().random()
    system = gvi.LagrangianSystem(v**2 / 2 + coefficient * sp.cos(q) ** 3, [q], [v])

    def run():
        gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=2)

    names = _compilations(run)
    # cfuncs are not dispatchers: a loop compiled again would be listed here
    assert not any(name.endswith("_loop") for name in names), names


def test_the_warm_up_compiles_every_variant_and_the_problem_library_adds_none():
    # the switches of loops.traits: stage form and general loop 4 variants each,
    # linear 2, constrained 1, explicit 8, varying mass 1; every model of the problem library must
    # find its variant among them
    from galerkin_vi.tools.warmup import warm_up

    for group in range(3):
        warm_up(group, 3)
    expected = {
        loops.stage_form_loop: 4,
        loops.general_loop: 4,
        loops.linear_loop: 2,
        loops.constrained_loop: 2,
        loops.explicit_loop: 8,
        loops.varying_mass_loop: 1,
    }
    assert {loop: len(loop.signatures) for loop in expected} == expected
    factories = [
        problems.pendulum,
        problems.kepler,
        problems.double_pendulum,
        problems.henon_heiles,
        problems.harmonic_oscillator,
        problems.damped_oscillator,
        problems.driven_oscillator,
        problems.forced_pendulum,
        problems.spherical_pendulum,
        problems.constrained_spherical_pendulum,
        problems.cartesian_pendulum,
        problems.kapitza_pendulum,
        problems.rotating_hoop,
        problems.fermi_pasta_ulam,
        lambda: problems.spring_chain(10),
        lambda: problems.spring_chain(10, beta=1.0),
    ]

    def run():
        for factory in factories:
            problem = factory()
            for method in (gvi.Galerkin(1), gvi.Galerkin(2, gvi.gauss_legendre(2))):
                if problem.system.m and not method.collocated:
                    continue
                for specialize in (True, False):
                    gvi.Integrator(problem.system, method, specialize=specialize).integrate(
                        problem.q0, problem.v0, h=0.01, n_steps=2
                    )

    assert not any(name.endswith("_loop") for name in _compilations(run))
    assert {loop: len(loop.signatures) for loop in expected} == expected


def test_banded_chain_uses_the_same_loops_as_dense_systems():
    chain = problems.spring_chain(12)
    integrator = gvi.Integrator(chain.system, gvi.Galerkin(2), specialize=False)
    assert integrator._spec.banded

    def run():
        integrator.integrate(chain.q0, chain.v0, h=0.01, n_steps=3)

    assert not any(name.endswith("_loop") for name in _compilations(run))


_SCRIPT = textwrap.dedent(
    """
    import sys, time
    import sympy as sp
    import galerkin_vi as gvi
    from numba.core import event
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + 0.625 * sp.cos(q) ** 5, [q], [v])
    with event.install_recorder("numba:compile") as recorder:
        for method in (gvi.Galerkin(2), gvi.Galerkin(3, gvi.gauss_legendre(3))):
            gvi.Integrator(system, method).integrate([1.0], [0.0], h=0.1, n_steps=2)
    print(len(recorder.buffer))
    """
)


def test_cached_system_in_a_new_process_compiles_nothing(tmp_path):
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=os.environ["GALERKIN_VI_CACHE_DIR"])
    script = tmp_path / "run.py"
    script.write_text(_SCRIPT)
    first = subprocess.run(
        [sys.executable, str(script)], env=env, capture_output=True, text=True, check=True
    )
    second = subprocess.run(
        [sys.executable, str(script)], env=env, capture_output=True, text=True, check=True
    )
    assert int(first.stdout.split()[-1]) >= 0
    assert int(second.stdout.split()[-1]) == 0, second.stderr


@pytest.mark.parametrize("path", ["newton", "separable"])
def test_point_functions_by_address_match_the_numpy_reference(path):
    system = _pendulum()
    integrator = gvi.Integrator(system, gvi.Galerkin(3), specialize=path == "separable")
    assert integrator.kernel_path == path
    fast = integrator.integrate([1.2], [0.3], h=0.05, n_steps=40, params={k: 2.0})
    slow = gvi.Integrator(system, gvi.Galerkin(3), backend="numpy").integrate(
        [1.2], [0.3], h=0.05, n_steps=40, params={k: 2.0}
    )
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fast.p, slow.p, rtol=0, atol=1e-13)


def test_a_session_that_needs_every_loop_compiles_them_at_once_saying_so(monkeypatch, capsys):
    from galerkin_vi.loops import readiness

    calls = []
    monkeypatch.setattr(readiness, "_ENSURED", False)
    monkeypatch.setattr(readiness, "loops_ready", lambda: False)
    monkeypatch.setattr(readiness, "compile_all", lambda: calls.append(1) or 42.0)
    monkeypatch.delenv("GALERKIN_VI_WARMUP_CHILD", raising=False)
    readiness.ensure_loops()  # a run: compiles nothing ahead of use
    assert calls == []
    readiness.ensure_all_loops()
    err = capsys.readouterr().err
    assert calls == [1]
    assert "compiling every time loop" in err
    assert "galerkin-vi warmup" in err and "compiled in 42 s" in err


_NUMBA_DIR_SCRIPT = textwrap.dedent(
    """
    import sympy as sp
    import galerkin_vi as gvi
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + 0.375 * sp.cos(q) ** 3, [q], [v])
    gvi.Integrator(system, gvi.Galerkin(2)).integrate([1.0], [0.0], h=0.1, n_steps=2)
    """
)


def test_point_functions_stay_under_the_cache_root_with_numba_cache_dir(warm_cache):
    numba_dir = warm_cache / "numba-elsewhere"
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(warm_cache), NUMBA_CACHE_DIR=str(numba_dir))
    subprocess.run([sys.executable, "-c", _NUMBA_DIR_SCRIPT], env=env, check=True)
    assert list((warm_cache / "points" / "__pycache__").glob("gvi_*.nbi"))
    assert not list(numba_dir.rglob("gvi_*.nbi"))  # one folder to clear
