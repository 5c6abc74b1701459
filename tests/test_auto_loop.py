"""``specialize="auto"``: the system's own loop once compiled, never waited for.

Each test points the cache root at its own folder, so the loops generated for
its systems start uncompiled (the shared loops stay in the session's folder).
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import textwrap

import numpy as np
import pytest
import sympy as sp
from numba.core import event

import galerkin_vi as gvi
from galerkin_vi.loops import on_demand
from galerkin_vi.run import generated_choice

q, v = sp.symbols("q v")


@pytest.fixture(autouse=True)
def background_compiles(monkeypatch):
    """The default of a user's process (the test session turns them off)."""
    monkeypatch.setenv("GALERKIN_VI_BACKGROUND", "1")


@pytest.fixture
def own_cache(tmp_path, monkeypatch):
    monkeypatch.setenv("GALERKIN_VI_CACHE_DIR", str(tmp_path))
    return tmp_path


def _pendulum(strength: float = 1.0) -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(v**2 / 2 + strength * sp.cos(q), [q], [v])


def _generated_compilations(run) -> list[str]:
    with event.install_recorder("numba:compile") as recorder:
        run()
    names = [e.data["dispatcher"].py_func.__name__ for _, e in recorder.buffer if e.is_start]
    return [name for name in names if name.endswith("_steps")]


def test_auto_is_the_default_and_survives_pickling():
    integrator = gvi.Integrator(_pendulum())
    assert integrator.specialize == "auto"
    assert pickle.loads(pickle.dumps(integrator)).specialize == "auto"


def test_a_bad_value_names_every_choice():
    with pytest.raises(ValueError, match='"auto", True, False or "system"'):
        gvi.Integrator(_pendulum(), specialize="fast")


def test_a_short_first_run_never_waits_and_a_second_run_starts_the_compile(own_cache):
    integrator = gvi.Integrator(_pendulum(1.25), gvi.Galerkin(2))
    run = lambda: integrator.integrate([1.0], [0.0], h=0.05, n_steps=400)  # noqa: E731
    first = []
    assert _generated_compilations(lambda: first.append(run())) == []
    assert first[0].kernel_path == "separable"
    steps = integrator.run_spec.stage_steps
    assert not any(key[0] == id(steps) for key in on_demand._BACKGROUND)  # nothing started
    second = run()  # the system is run again: its loop compiles in a child
    assert second.kernel_path == "separable"
    on_demand.wait_for_background(timeout=300)
    third = []
    assert _generated_compilations(lambda: third.append(run())) == []  # loaded, not compiled
    assert third[0].kernel_path == "separable:system"
    # the same steps bit for bit
    np.testing.assert_array_equal(third[0].q, first[0].q)
    np.testing.assert_array_equal(third[0].p, first[0].p)


def test_a_long_first_run_starts_the_compile(own_cache, monkeypatch):
    monkeypatch.setattr(generated_choice, "LONG_RUN_STEPS", 300)
    integrator = gvi.Integrator(_pendulum(1.5), gvi.Galerkin(2))
    long_run = integrator.integrate([1.0], [0.0], h=0.05, n_steps=300)
    assert long_run.kernel_path == "separable"
    on_demand.wait_for_background(timeout=300)
    again = integrator.integrate([1.0], [0.0], h=0.05, n_steps=300)
    assert again.kernel_path == "separable:system"
    np.testing.assert_array_equal(again.q, long_run.q)


def test_the_chosen_values_keep_their_meaning(own_cache):
    system = _pendulum(1.75)
    shared = gvi.Integrator(system, gvi.Galerkin(2), specialize=True)
    for _ in range(3):  # run again and again: True never builds the system's loop
        assert shared.integrate([1.0], [0.0], h=0.05, n_steps=50).kernel_path == "separable"
    assert shared.run_spec.stage_steps is None
    own = gvi.Integrator(system, gvi.Galerkin(2), specialize="system")
    assert own.integrate([1.0], [0.0], h=0.05, n_steps=50).kernel_path == "separable:system"
    newton = gvi.Integrator(system, gvi.Galerkin(2), specialize=False)
    assert newton.integrate([1.0], [0.0], h=0.05, n_steps=50).kernel_path == "newton"


def test_a_varying_mass_keeps_the_shared_sweep_whose_numbers_do_not_depend_on_the_cache(
    own_cache,
):
    # the generated sweep agrees to round-off only: "auto" never switches to it
    bead = gvi.LagrangianSystem((1 + q**2) * v**2 / 2 + sp.cos(q), [q], [v])
    integrator = gvi.Integrator(bead, gvi.Galerkin(3, gvi.gauss_legendre(3)))
    runs = [integrator.integrate([0.5], [0.1], h=0.05, n_steps=100) for _ in range(3)]
    assert [r.kernel_path for r in runs] == ["varying_mass"] * 3
    assert integrator.run_spec.stage_steps is None
    np.testing.assert_array_equal(runs[2].q, runs[0].q)
    own = gvi.Integrator(bead, gvi.Galerkin(3, gvi.gauss_legendre(3)), specialize="system")
    system_run = own.integrate([0.5], [0.1], h=0.05, n_steps=100)
    assert system_run.kernel_path == "varying_mass:system"
    np.testing.assert_allclose(system_run.q, runs[0].q, rtol=0, atol=1e-13)


def test_ensembles_and_other_paths_report_their_loop(own_cache):
    integrator = gvi.Integrator(_pendulum(2.0), gvi.Galerkin(2))
    members = integrator.integrate_many([[1.0], [0.5]], [[0.0], [0.0]], h=0.05, n_steps=20)
    single = integrator.integrate([0.5], [0.0], h=0.05, n_steps=20)
    np.testing.assert_array_equal(members[1].q, single.q)
    explicit = gvi.Integrator(_pendulum(2.0), gvi.Galerkin(1))
    assert explicit.integrate([1.0], [0.0], h=0.05, n_steps=5).kernel_path == "explicit"


def test_a_fresh_process_takes_the_loop_the_cache_holds(warm_cache):
    code = textwrap.dedent(
        """
        import sympy as sp
        import galerkin_vi as gvi
        from galerkin_vi.loops.on_demand import wait_for_background
        q, v = sp.symbols("q v")
        system = gvi.LagrangianSystem(v**2 / 2 + 2.25 * sp.cos(q), [q], [v])
        integrator = gvi.Integrator(system, gvi.Galerkin(2))
        paths = [integrator.integrate([1.0], [0.0], h=0.05, n_steps=50).kernel_path
                 for _ in range(2)]
        wait_for_background()
        print(" ".join(paths))
        """
    )
    env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(warm_cache), GALERKIN_VI_QUIET="1")
    env["GALERKIN_VI_BACKGROUND"] = "1"

    def paths():
        done = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        return done.stdout.split()

    assert paths() == ["separable", "separable"]  # the second started the compile
    assert paths() == ["separable:system", "separable:system"]  # deterministic from the cache


def test_background_compiles_run_one_at_a_time_and_all_finish(own_cache):
    integrators = [gvi.Integrator(_pendulum(s), gvi.Galerkin(2)) for s in (3.0, 3.5, 4.0)]
    for integrator in integrators:
        for _ in range(2):  # run again: each asks for its loop
            integrator.integrate([1.0], [0.0], h=0.05, n_steps=20)
        running = [c for c in on_demand._BACKGROUND.values() if c is not None and c.poll() is None]
        assert len(running) <= 1
    on_demand.wait_for_background(timeout=600)
    assert not on_demand._PENDING
    paths = [i.integrate([1.0], [0.0], h=0.05, n_steps=20).kernel_path for i in integrators]
    assert paths == ["separable:system"] * 3


def test_background_compiles_can_be_turned_off(own_cache, monkeypatch):
    monkeypatch.setenv("GALERKIN_VI_BACKGROUND", "0")
    integrator = gvi.Integrator(_pendulum(4.5), gvi.Galerkin(2))
    paths = [integrator.integrate([1.0], [0.0], h=0.05, n_steps=20).kernel_path for _ in range(3)]
    on_demand.wait_for_background(timeout=300)
    paths.append(integrator.integrate([1.0], [0.0], h=0.05, n_steps=20).kernel_path)
    assert paths == ["separable"] * 4
