"""Smoke tests of the benchmark suite: the hand-written peers are the methods they claim to be.

No timing is asserted: benchmarks are not tests. The equivalences below are
what makes the per-step comparison like-for-like (same method, same h, same
Newton policy); the differences measured when they were written are noted
beside each tolerance.
"""

from __future__ import annotations

import math
import warnings

import numpy as np
import pytest

import galerkin_vi as gvi
from galerkin_vi import bench, problems
from galerkin_vi.bench import handwritten as hw
from galerkin_vi.bench.workprecision import time_to_error


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
        run = hw.run_gauss(hw.KEPLER, s, kepler.q0, kepler.v0, 0.05, 100, full=full)
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
    energy = hw.energy(hw.PENDULUM, run.q, run.p)
    np.testing.assert_allclose(energy, traj.energy(), rtol=0, atol=1e-14)


def test_gauss_tables_are_the_gauss_method():
    for s in (1, 2, 3, 4, 6):
        tb = hw.gauss_tables(s)
        np.testing.assert_allclose(tb.A.sum(axis=1), tb.c, atol=1e-15)
        for k in range(2 * s):  # quadrature order 2s, sharp
            assert abs(tb.b @ tb.c**k - 1 / (k + 1)) < 1e-15
        assert abs(tb.b @ tb.c ** (2 * s) - 1 / (2 * s + 1)) > 1e-10
        np.testing.assert_allclose(tb.bA, tb.b * (1 - tb.c), atol=1e-15)  # condition D(1)


def test_scipy_rhs_and_jacobians_are_consistent():
    y = np.array([0.7, -0.4, 0.3, 1.1])
    eps = 1e-6
    for rhs, jac, yy in (
        (hw.kepler_rhs, hw.kepler_jac, y),
        (hw.pendulum_rhs, hw.pendulum_jac, y[:2]),
    ):
        numeric = np.column_stack(
            [(rhs(0.0, yy + eps * e) - rhs(0.0, yy - eps * e)) / (2 * eps) for e in np.eye(yy.size)]
        )
        np.testing.assert_allclose(jac(0.0, yy), numeric, atol=1e-8)


def test_time_to_error_interpolates_log_log():
    points = [{"time": 1.0, "error": 1e-2}, {"time": 10.0, "error": 1e-6}]
    assert math.isclose(time_to_error(points, 1e-4)["time"], math.sqrt(10.0))
    assert time_to_error(points, 1e-8) is None
    assert time_to_error(points, 1e-1) == {"time": 1.0, "bound": True}


def test_run_tiny_configuration_returns_expected_keys(tmp_path):
    results = bench.run(quick=True, output=str(tmp_path), config=bench.tiny_config(), verbose=False)
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
    names = sorted(p.rsplit("/", 1)[-1] for p in results["files"])
    assert names[:2] == ["results.json", "results.md"]
    assert (tmp_path / "results.md").read_text().startswith("# galerkin_vi benchmark")


def test_cli_arguments_parse():
    import argparse

    parser = bench.add_arguments(argparse.ArgumentParser())
    args = parser.parse_args(["--quick", "--output", "out"])
    assert args.quick and args.output == "out" and args.run is bench.main
