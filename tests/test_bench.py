"""Smoke tests of the peer benchmark: the hand-written peers are the methods they claim to be.

The peer benchmark is the ``peers`` package in the repository's ``benchmarks/`` folder
(not installed; ``tests/conftest.py`` puts the folder on ``sys.path``).

No timing is asserted: benchmarks are not tests. The equivalences below are
what makes the per-step comparison like-for-like (same method, same h, same
Newton policy); the differences measured when they were written are noted
beside each tolerance.
"""

from __future__ import annotations

import dataclasses
import importlib.util
import math
import warnings

import numpy as np
import peers
import pytest
import sympy as sp
from peers import cases
from peers import handwritten as hw
from peers import workprecision as wp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.tools import benchmark as bm
from galerkin_vi.tools.benchmark import time_to_error

from .conftest import BENCHMARKS_DIR


@pytest.fixture(scope="module")
def kepler():
    return problems.kepler(0.6)


def _gvi(problem, method, h, n):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.OrderReductionWarning)
        integ = gvi.Integrator(problem.system, method)
    return integ.integrate(problem.q0, problem.v0, h=h, n_steps=n)


def test_stormer_verlet_equals_galerkin_s1_lobatto2(kepler):
    traj = _gvi(kepler, gvi.Galerkin(1, gvi.gauss_lobatto(2)), 0.05, 100)
    run = hw.run_verlet(hw.KEPLER, kepler.q0, kepler.v0, 0.05, 100)
    # measured 1.2e-14 (q) and 6.9e-15 (p)
    np.testing.assert_allclose(run.q, traj.q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(run.p, traj.p, rtol=0, atol=1e-13)


@pytest.mark.parametrize("s", [1, 2, 3])
def test_gauss_collocation_equals_galerkin_gauss(kepler, s):
    traj = _gvi(kepler, gvi.Galerkin(s, gvi.gauss_legendre(s)), 0.05, 100)
    for full in (True, False):
        iteration = "full" if full else "simplified"
        run = hw.run_gauss(hw.KEPLER, s, kepler.q0, kepler.v0, 0.05, 100, iteration=iteration)
        # measured 9e-15 / 3.6e-14 / 7.0e-14 for s = 1 / 2 / 3
        np.testing.assert_allclose(run.q, traj.q, rtol=0, atol=2e-13)
        np.testing.assert_allclose(run.p, traj.p, rtol=0, atol=2e-13)


@pytest.mark.parametrize("s", [1, 2, 3])
def test_lobatto_iiia_iiib_equals_galerkin_lobatto(kepler, s):
    traj = _gvi(kepler, gvi.Galerkin(s, gvi.gauss_lobatto(s + 1)), 0.05, 100)
    run = hw.run_lobatto(hw.KEPLER, s + 1, kepler.q0, kepler.v0, 0.05, 100)
    # measured 1e-14 / 3.4e-15 / 3.3e-14 for s = 1 / 2 / 3
    np.testing.assert_allclose(run.q, traj.q, rtol=0, atol=2e-13)
    np.testing.assert_allclose(run.p, traj.p, rtol=0, atol=2e-13)


def test_pendulum_kernels_match_galerkin():
    problem = problems.pendulum(1.5, 0.0)
    traj = _gvi(problem, gvi.Galerkin(2, gvi.gauss_legendre(2)), 0.1, 100)
    run = hw.run_gauss(hw.PENDULUM, 2, problem.q0, problem.v0, 0.1, 100)
    np.testing.assert_allclose(run.q, traj.q, rtol=0, atol=2e-13)
    energy = hw.energy(hw.PENDULUM, run.q, run.p, np.zeros(0))
    np.testing.assert_allclose(energy, traj.energy(), rtol=0, atol=1e-14)


def test_gauss_tables_are_the_gauss_method():
    for s in (1, 2, 3, 4, 6):
        tb = hw.gauss_tables(s)
        np.testing.assert_allclose(tb.A.sum(axis=1), tb.c, rtol=0, atol=1e-15)
        for k in range(2 * s):  # quadrature order 2s, sharp
            assert abs(tb.b @ tb.c**k - 1 / (k + 1)) < 1e-15
        assert abs(tb.b @ tb.c ** (2 * s) - 1 / (2 * s + 1)) > 1e-10
        np.testing.assert_allclose(tb.bA, tb.b * (1 - tb.c), rtol=0, atol=1e-15)  # condition D(1)


# -------------------------------------------------- the problems added for issue 3, item 4
def _twin_cases():
    """(name, problem, hand-written id, its parameters, step) for the new separable problems."""
    return {
        "henon_heiles": (problems.henon_heiles(), hw.HENON_HEILES, np.zeros(0), 0.1),
        "fpu": (
            problems.fermi_pasta_ulam(),
            hw.SPRINGS,
            hw.springs_params(0.0, 4.0, 50.0**2 / 2, 0.0),
            0.005,
        ),
        "spring_chain": (
            cases.chain_problem(10),
            hw.SPRINGS,
            hw.springs_params(1.0, cases.CHAIN_BETA, 1.0, cases.CHAIN_BETA, 1.0),
            0.1,
        ),
        "spring_chain_mass_2": (
            problems.spring_chain(10, stiffness=1.5, beta=0.5, mass=2.0),
            hw.SPRINGS,
            hw.springs_params(1.5, 0.5, 1.5, 0.5, 2.0),
            0.1,
        ),
        "outer_solar_system": (
            problems.outer_solar_system(),
            hw.N_BODY,
            hw.n_body_params(*cases.solar_system_constants()),
            50.0,
        ),
    }


TWINS = list(_twin_cases())


def _close(run, traj, inv_mass, rel):
    """q and v agree to ``rel`` relative to the largest |q| and |v| (round-off)."""
    qs, vs = max(1.0, np.abs(traj.q).max()), np.abs(traj.p * inv_mass).max()
    np.testing.assert_allclose(run.q, traj.q, rtol=0, atol=rel * qs)
    np.testing.assert_allclose(run.p, traj.p * inv_mass, rtol=0, atol=rel * vs)


@pytest.mark.parametrize("name", TWINS)
def test_new_kernels_equal_their_galerkin_twins(name):
    """Each new problem's hand-written ∇V, ∇²V: every kernel is its galerkin_vi twin (50 steps)."""
    problem, pid, prm, h = _twin_cases()[name]
    n = problem.q0.size
    inv_mass = hw.inverse_masses(pid, n, prm)

    def twin(method):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", gvi.OrderReductionWarning)
            integ = gvi.Integrator(problem.system, method)
        return integ.integrate(problem.q0, problem.v0, h=h, n_steps=50, params=problem.params)

    q0, v0 = problem.q0, problem.v0
    traj = twin(gvi.Galerkin(1, gvi.gauss_lobatto(2)))
    # measured up to 2e-15 relative (solar system: 4e-16 of |q| = 40 AU)
    _close(hw.run_verlet(pid, q0, v0, h, 50, params=prm), traj, inv_mass, 1e-13)
    traj = twin(gvi.Galerkin(2, gvi.gauss_legendre(2)))
    for iteration in ("full", "simplified", "fixed-point"):
        run = hw.run_gauss(pid, 2, q0, v0, h, 50, iteration=iteration, params=prm)
        _close(run, traj, inv_mass, 1e-13)  # measured up to 1.5e-14 (FPU velocities)
    traj = twin(gvi.Galerkin(2, gvi.gauss_lobatto(3)))
    _close(hw.run_lobatto(pid, 3, q0, v0, h, 50, params=prm), traj, inv_mass, 1e-13)
    # the energy formula is galerkin_vi's Hamiltonian
    np.testing.assert_allclose(
        hw.energy(pid, traj.q, traj.p * inv_mass, prm),
        traj.energy(),
        rtol=1e-13,
        atol=1e-15 * abs(traj.energy()[0]),
    )


def _rhs_cases():
    prob = problems.double_pendulum(m1=1.3, m2=0.7, l1=0.9, l2=1.2)
    dp = np.array([prob.params[p] for p in prob.system.params])
    out = {name: (c[0], c[1], c[2]) for name, c in _twin_cases().items()}
    out["kepler"] = (problems.kepler(0.6), hw.KEPLER, np.zeros(0))
    out["pendulum"] = (problems.pendulum(), hw.PENDULUM, np.zeros(0))
    out["double_pendulum"] = (prob, hw.DOUBLE_PENDULUM, dp)
    return out


@pytest.mark.parametrize("name", list(_rhs_cases()))
def test_scipy_rhs_and_jacobians_are_consistent(name):
    """rhs = the Euler–Lagrange accelerations of the library's system; jac = its derivative."""
    problem, pid, prm = _rhs_cases()[name]
    n = problem.q0.size
    rng = np.random.default_rng(1)
    q = problem.q0 + 0.01 * rng.standard_normal(n)
    v = problem.v0 + 0.01 * rng.standard_normal(n) * max(1e-3, np.abs(problem.v0).max())
    y = np.concatenate([q, v])
    system = problem.system
    values = system.evaluate("hessian", 0.0, q, v, system.parameter_vector(problem.params))
    Lq = values[:n]
    Lqv = values[2 * n + n * n : 2 * n + 2 * n * n].reshape(n, n)
    Lvv = values[2 * n + 2 * n * n :].reshape(n, n)
    acc = np.linalg.solve(Lvv, Lq - Lqv.T @ v)
    f = hw.rhs(pid, y, prm)
    np.testing.assert_allclose(f[:n], v, rtol=0, atol=0)
    np.testing.assert_allclose(f[n:], acc, rtol=1e-12, atol=1e-13 * np.abs(acc).max())
    eps = 1e-6 * (1 + np.abs(y))
    numeric = np.column_stack(
        [
            (hw.rhs(pid, y + eps[i] * e, prm) - hw.rhs(pid, y - eps[i] * e, prm)) / (2 * eps[i])
            for i, e in enumerate(np.eye(y.size))
        ]
    )
    J = hw.jac(pid, y, prm)
    np.testing.assert_allclose(J, numeric, rtol=0, atol=1e-7 * max(1.0, np.abs(J).max()))


def test_double_pendulum_energy_is_the_hamiltonian():
    problem = problems.double_pendulum(m1=1.3, m2=0.7, l1=0.9, l2=1.2)
    prm = np.array([problem.params[p] for p in problem.system.params])
    traj = gvi.Integrator(problem.system, gvi.Galerkin(2)).integrate(
        problem.q0, problem.v0, h=0.1, n_steps=20, params=problem.params
    )
    energy = hw.energy(hw.DOUBLE_PENDULUM, traj.q, traj.velocities(), prm)
    np.testing.assert_allclose(energy, traj.energy(), rtol=1e-13, atol=1e-14)


def test_rebound_setup_is_the_solar_system():
    """REBOUND's IAS15 on the benchmark's particles follows the hand-written 6-stage Gauss."""
    pytest.importorskip("rebound")
    setup = cases.solar_rebound_setup()
    prm = hw.n_body_params(*cases.solar_system_constants())
    problem = problems.outer_solar_system()
    sim = setup.simulation()
    sim.integrator = "ias15"
    sim.integrate(5000.0, exact_finish_time=1)
    q, v = setup.state(sim)
    run = hw.run_gauss(hw.N_BODY, 6, problem.q0, problem.v0, 50.0, 100, 100, params=prm)
    # measured 1.0e-15 (positions) and 2.7e-15 (velocities), relative
    assert np.linalg.norm(q - run.q[-1]) / np.linalg.norm(q) < 1e-12
    assert np.linalg.norm(v - run.p[-1]) / np.linalg.norm(v) < 1e-12


def test_time_to_error_interpolates_log_log():
    points = [{"time": 1.0, "error": 1e-2}, {"time": 10.0, "error": 1e-6}]
    assert math.isclose(time_to_error(points, 1e-4)["time"], math.sqrt(10.0))
    assert time_to_error(points, 1e-8) is None
    assert time_to_error(points, 1e-1) == {"time": 1.0, "bound": True}


def test_run_tiny_configuration_returns_expected_keys(tmp_path):
    results = peers.run(quick=True, output=str(tmp_path), config=peers.tiny_config(), verbose=False)
    assert set(results) >= {"meta", "problems", "per_step", "files"}
    entry = results["problems"]["kepler"]
    assert set(entry) >= {"curves", "time_to_error", "best_galerkin_vi", "ratio_peer_over_best"}
    assert set(entry["time_to_error"]) == set(entry["curves"])
    for curve in entry["curves"].values():
        assert curve["points"], "every curve has at least one point"
        for p in curve["points"]:
            assert {"time", "error", "energy_error"} <= set(p)
            assert p["time"] > 0 and p["error"] >= 0
    row = results["per_step"][0]
    assert row["ratio"] > 0 and row["gvi_ns_per_step"] > 0
    names = {p.rsplit("/", 1)[-1] for p in results["files"]}
    assert {"results.json", "results.md"} <= names
    assert (tmp_path / "results.md").read_text().startswith("# galerkin_vi benchmark")


def test_run_tiny_configuration_on_new_problems(tmp_path):
    """A separable and a non-separable new problem: hand-written peers only where they apply."""
    cfg = dataclasses.replace(
        peers.tiny_config(),
        problems=("henon_heiles", "double_pendulum"),
        peers=("numbalsoda",),
        per_step_problems=(),
    )
    results = peers.run(quick=True, output=str(tmp_path), config=cfg, verbose=False)
    hh = results["problems"]["henon_heiles"]
    dp = results["problems"]["double_pendulum"]
    families = {c["family"] for c in hh["curves"].values()}
    assert {"galerkin_vi", "hand-written", "scipy"} <= families
    assert "hand-written" not in {c["family"] for c in dp["curves"].values()}
    for entry in (hh, dp):
        # the reference (DOP853 at scipy's floor) agrees with galerkin_vi's s = 6 run
        checks = entry["reference_checks"]
        assert any(k.startswith("gvi_s6") for k in checks)
        assert max(checks.values()) < 1e-9
        for curve in entry["curves"].values():
            assert curve["points"]
    text = (tmp_path / "results.md").read_text()
    assert "## Summary" in text and "Hénon–Heiles" in text and "Double pendulum" in text


def test_tolerance_sweeps_end_at_the_floor():
    assert bm.tolerances(1e-3, 3e-14, 10.0)[-2:] == [1e-13, 3e-14]
    assert bm.tolerances(1e-3, 1e-6, 10.0) == [1e-3, 1e-4, 1e-5, 1e-6]
    assert bm.step_counts(50, 2.0)[:3] == [50, 100, 200]


def test_chain_cost_rows_and_growth():
    # enough steps that the time per step stands out of the fixed cost of a call (~0.1 ms)
    rows = wp.chain_cost((10,), n_steps=2000, repeats=3, log=lambda _: None)
    (row,) = rows
    assert row["n_masses"] == 10 and row["gvi_ns_per_step"] > 0 and row["n_steps"] == 2000
    assert row["hw_gauss2_fixed_point_ns_per_step"] > 0
    fake = [{"n_masses": 100, "gvi_ns_per_step": 2.0}, {"n_masses": 1000, "gvi_ns_per_step": 24.0}]
    assert wp.chain_growth(fake) == 12.0
    assert wp.chain_growth(fake[:1]) is None


def test_cli_arguments_parse():
    import argparse

    parser = peers.add_arguments(argparse.ArgumentParser())
    args = parser.parse_args(["--quick", "--output", "out"])
    assert args.quick and args.output == "out" and args.run is peers.main
    args = parser.parse_args(["--problems", "outer_solar_system", "fpu", "--no-chain-cost"])
    assert args.problems == ["outer_solar_system", "fpu"] and args.no_chain_cost


def test_problem_lists_agree():
    assert peers.PROBLEMS == cases.PROBLEMS == wp.PROBLEMS
    assert set(peers.quick_config().problems) < set(cases.PROBLEMS)
    assert peers.full_config().problems == wp.PROBLEMS


def test_run_script_help(capsys):
    """``python benchmarks/run.py --help``: the script loads the ``peers`` package."""
    spec = importlib.util.spec_from_file_location("benchmarks_run", BENCHMARKS_DIR / "run.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    with pytest.raises(SystemExit) as exit_info:
        module.main(["--help"])
    assert exit_info.value.code == 0
    out = capsys.readouterr().out
    assert "--quick" in out and "--no-chain-cost" in out


def test_the_package_holds_no_peer_code():
    """The peers live in benchmarks/ only: galerkin_vi has no ``bench`` subpackage."""
    assert importlib.util.find_spec("galerkin_vi.bench") is None
    assert not hasattr(gvi, "bench")


@pytest.mark.parametrize("e", [0.6, 0.9])
def test_the_handwritten_adaptive_gauss_is_galerkin_vis_adaptive_method(e):
    # benchmarks/adaptive.py's baseline: Gauss on K = r^1.5 (H - E) with time riding
    # along, against AdaptiveIntegrator's Galerkin(s, Gauss(s)) on the transformed
    # Lagrangian with its clock coordinate. Measured: equal steps, positions within
    # 1.7e-14, momenta within 3.8e-13 (method errors 1e-5 to 2e-9)
    from peers.poincare import kepler_poincare

    problem = problems.kepler(e)
    x, y = problem.system.q
    g = gvi.encounter_scaling([sp.sqrt(x**2 + y**2)], 1.5)
    t_final = 6 * math.pi
    for s in (2, 3):
        method = gvi.Galerkin(s, gvi.gauss_legendre(s))
        ours = gvi.AdaptiveIntegrator(problem.system, method, g=g).integrate(
            problem.q0, problem.v0, h=0.1, t_final=t_final
        )
        kernel = kepler_poincare(problem.q0, problem.v0, s, 0.1, t_final)
        assert kernel.t == t_final
        assert kernel.n_steps == ours.n_steps
        assert np.abs(kernel.q - ours.q[-1]).max() <= 1e-12
        assert np.abs(kernel.p - ours.p[-1]).max() <= 1e-11
