"""Large steps and high degrees: linear stability limits, stage conditioning, accuracy.

The theory is the exact trace of the one-step map on the harmonic oscillator,
:math:`\\operatorname{tr} M(h\\omega)` (``benchmarks/stability.py``, loaded from
its path; its module docstring has the formula). Runs use the compiled backend:
the oscillator takes the linear kernel (explicit Störmer–Verlet for degree 1),
Fermi–Pasta–Ulam the explicit or the Newton kernel. A run past a limit must
raise ``ConvergenceError`` or warn ``InstabilityWarning``; no run may return a
non-finite state. The measured figures are noted beside each tolerance.
"""

from __future__ import annotations

import importlib.util
import math
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

import galerkin_vi as gvi
from galerkin_vi import problems

_PATH = Path(__file__).resolve().parents[1] / "benchmarks" / "stability.py"
_SPEC = importlib.util.spec_from_file_location("stability_benchmark", _PATH)
stability = importlib.util.module_from_spec(_SPEC)
sys.modules[_SPEC.name] = stability  # dataclasses look their module up there
_SPEC.loader.exec_module(stability)

# Condition number bound for Lobatto control nodes, s <= 16. At moderate h omega the stage
# Jacobian is (1/h) sum_i b_i D_i D_i^T (rows 0..s-1, columns 1..s) minus a small mass term:
# a stiffness matrix in the nodal basis. On GLL nodes that basis is well conditioned
# (Lebesgue constant ~ log s) and only the derivative scale grows, polynomially; on
# equidistant nodes the basis itself is exponentially ill-conditioned. Measured kappa_2
# (Lobatto s+1 quadrature, h omega = 0.5): 7.5, 39, 99, 199, 354, 580, 889, 1290 for
# s = 2, 4, ..., 16 (7% less at h omega = 1), a power law s^2.7; 1e4 leaves a factor 7.7
# at s = 16 and would hold to s = 34 on that law. Equidistant: 3.6-3.9x per degree, 1.3e8
# at s = 16 (as in docs/theory.md, "Interior nodes do not change the map").
LOBATTO_CONDITION_BOUND = 1e4


def _run(integrator, problem, x, omega, n_steps=2000):
    return stability.classify(
        integrator, problem.q0, problem.v0, x, omega, n_steps, params=problem.params
    )


@pytest.fixture(scope="module")
def oscillator():
    return problems.harmonic_oscillator(1.0, 1.0, 0.0)


@pytest.fixture(scope="module")
def fpu():
    return problems.fermi_pasta_ulam(3, stability.FPU_OMEGA)


# ------------------------------------------------------------------------ theory
def test_verlet_trace_is_two_minus_x_squared_and_its_limit_is_two():
    polys = stability.trace_polynomials(stability.method_for("lobatto", 1))
    for x in (0.3, 1.0, 2.0, 2.5, 10.0):
        assert float(polys.trace(x)) == pytest.approx(2 - x * x, rel=1e-14, abs=1e-14)
    verlet = stability.analyse("lobatto", 1)
    assert verlet.limit == pytest.approx(2.0, rel=1e-14)
    (interval,) = verlet.unstable
    assert interval.hi is None and interval.sign == -1  # tr M < -2 for every x > 2


@pytest.mark.parametrize("degree", [1, 2, 3, 4])
def test_gauss_trace_is_that_of_the_diagonal_pade_approximant(degree):
    # degree s with Gauss s points = s-stage Gauss collocation: tr M = 2 Re R_ss(ix)
    polys = stability.trace_polynomials(stability.method_for("gauss", degree))
    for x in (0.1, 1.0, 3.0, 7.0, 50.0):
        assert float(polys.trace(x)) == pytest.approx(
            stability.pade_trace(degree, x), rel=1e-13, abs=1e-13
        )


@pytest.mark.parametrize(
    ("degree", "limit", "intervals"),
    [
        # s = 2: (2 sqrt 2, 2 sqrt 3) and (2 sqrt 6, inf)
        (2, 2 * math.sqrt(2), [(2 * math.sqrt(2), 2 * math.sqrt(3)), (2 * math.sqrt(6), None)]),
        # s = 3: roots of N + 2 Delta and N - 2 Delta; sqrt 10, sqrt 30, sqrt 60 exact
        (
            3,
            3.1127176481642174,
            [
                (3.1127176481642174, math.sqrt(10)),
                (math.sqrt(30), math.sqrt(60)),
                (8.62038217, None),
            ],
        ),
    ],
)
def test_lobatto_intervals_from_the_trace(degree, limit, intervals):
    result = stability.analyse("lobatto", degree)
    assert result.limit == pytest.approx(limit, rel=1e-12)
    assert len(result.unstable) == len(intervals)
    for found, (lo, hi) in zip(result.unstable, intervals, strict=True):
        assert found.lo == pytest.approx(lo, rel=1e-9)
        assert (found.hi is None) == (hi is None)
        if hi is not None:
            assert found.hi == pytest.approx(hi, rel=1e-12)
    assert result.singular == ()  # the stage equations are solvable at every h


@pytest.mark.parametrize("degree", [2, 3, 4, 5, 6])
def test_bounded_lobatto_intervals_end_where_gauss_is_plus_minus_identity(degree):
    # an observation the theory reproduces at every degree tried: Lobatto s+1 regains
    # stability exactly at the points where s-point Gauss has M = +-I
    lobatto = stability.analyse("lobatto", degree)
    gauss = stability.analyse("gauss", degree)
    ends = [iv.hi for iv in lobatto.unstable if iv.hi is not None]
    assert ends == pytest.approx(list(gauss.touches), rel=1e-12)


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_gauss_is_stable_for_every_step(degree):
    result = stability.analyse("gauss", degree)
    assert result.limit is None and result.unstable == ()
    # |tr M| = 2 only at isolated points where M = +-I (bounded); measured residual <= 2e-56
    assert len(result.touches) == degree - 1
    assert all(r < 1e-20 for r in result.touch_residuals)
    polys = stability.trace_polynomials(stability.method_for("gauss", degree))
    for x in (10.0, 100.0):
        assert abs(float(polys.trace(x))) < 2


# --------------------------------------------------------------- oscillator runs
@pytest.mark.parametrize("omega", [1.0, 50.0])
def test_verlet_runs_bounded_below_two_and_unstable_above(omega):
    problem = problems.harmonic_oscillator(omega, 1.0, 0.0)
    integrator = gvi.Integrator(problem.system, stability.method_for("lobatto", 1))
    assert integrator.kernel_path == "explicit"
    below = _run(integrator, problem, 1.99, omega)
    assert below.outcome == "bounded" and below.finite and below.growth < 1  # measured 0.0
    above = _run(integrator, problem, 2.01, omega)
    assert above.outcome in ("warning", "error") and above.finite  # measured: warning


@pytest.mark.parametrize("degree", [2, 3])
def test_lobatto_limits_agree_with_runs_on_both_sides(degree):
    result = stability.analyse("lobatto", degree)
    check = stability.check_against_runs(result, n_steps=20_000, x_max=10.0)
    assert check.kernel_path == "linear"
    # every edge below x = 10 located by bisection on runs; measured relative differences
    # 6.6e-8, 4.3e-7, 5.7e-8 (s = 2) and 5.4e-6, 1.5e-6, 1e-8, 5.6e-8, 2.8e-8 (s = 3),
    # within the expected lag of detection (ln 1e6 / N)^2 / |t'| (up to 9.4e-6)
    assert [e.theory for e in check.edges] == pytest.approx(
        [x for iv in result.unstable for x in (iv.lo, iv.hi) if x is not None]
    )
    for edge in check.edges:
        assert edge.relative_error < 2e-5
        assert abs(edge.measured - edge.theory) < 3 * edge.expected_lag + 1e-7 * edge.theory
    assert all(run.outcome == "bounded" and run.finite for run in check.stable_runs)
    for peak in check.unstable_runs:
        assert peak["run"]["outcome"] in ("warning", "error") and peak["run"]["finite"]
    # the first limit itself: 0.1 % either side
    run_at, _ = stability.oscillator_runner(stability.method_for("lobatto", degree))
    assert run_at(result.limit * 0.999, 2000).outcome == "bounded"
    past = run_at(result.limit * 1.001, 2000)
    assert past.outcome in ("warning", "error") and past.finite


@pytest.mark.parametrize("degree", [1, 2, 3])
@pytest.mark.parametrize("x", [10.0, 100.0])
def test_gauss_runs_stay_bounded_at_large_steps(oscillator, degree, x):
    integrator = gvi.Integrator(oscillator.system, stability.method_for("gauss", degree))
    run = _run(integrator, oscillator, x, 1.0)
    # Gauss collocation keeps the energy exactly: |q| <= |q0| up to round-off (measured 0.0)
    assert run.outcome == "bounded" and run.finite and run.growth < 1e-10


# -------------------------------------------------------------------------- FPU
def test_fpu_past_verlet_limit_raises_and_never_returns_non_finite_states(fpu):
    omega = stability.FPU_OMEGA
    integrator = gvi.Integrator(fpu.system, stability.method_for("lobatto", 1))
    assert integrator.kernel_path == "explicit"
    assert _run(integrator, fpu, 1.9, omega).outcome == "bounded"
    # the stiff springs' frequency reaches omega_max = 50.12 along the run: the limit is
    # 2 omega / omega_max = 1.995 (measured between 1.9933 and 1.9934), not 2
    for x in (2.01, 2.5, 5.0, 50.0):
        run = _run(integrator, fpu, x, omega)
        assert (
            run.outcome in ("warning", "error") and run.finite
        )  # measured: overflow at steps 4-25
    with pytest.raises(gvi.ConvergenceError) as info:
        integrator.integrate(
            fpu.q0, fpu.v0, h=2.5 / omega, n_steps=2000, params=fpu.params, on_failure="raise"
        )
    assert np.all(np.isfinite(info.value.partial.q)) and np.all(np.isfinite(info.value.partial.p))


def test_fpu_lobatto3_unstable_where_the_oscillator_is_gauss2_not(fpu):
    omega = stability.FPU_OMEGA
    lobatto = gvi.Integrator(fpu.system, stability.method_for("lobatto", 2))
    gauss = gvi.Integrator(fpu.system, stability.method_for("gauss", 2))
    assert lobatto.kernel_path == gauss.kernel_path == "separable"
    # Lobatto 3: unstable on (2.83, 3.46) and past 4.90 (oscillator), stable between
    for x, bounded in ((2.5, True), (3.0, False), (4.0, True), (6.0, False)):
        run = _run(lobatto, fpu, x, omega)
        assert run.finite and run.bounded == bounded  # measured: Newton failures when unstable
        assert _run(gauss, fpu, x, omega).outcome == "bounded"


# ------------------------------------------------------------------ high degree
def test_lobatto_stage_jacobians_stay_well_conditioned_equidistant_do_not():
    for degree in range(1, 17):
        method = stability.method_for("lobatto", degree)
        for x in (0.5, 1.0):
            assert stability.stage_condition(method, x) < LOBATTO_CONDITION_BOUND
    equidistant = stability.method_for("lobatto", 16, nodes="equidistant")
    # measured 1.3e8 at h omega = 0.5 and 1.2e8 at 1
    assert stability.stage_condition(equidistant, 0.5) > 1e3 * LOBATTO_CONDITION_BOUND


def test_degree_12_reaches_machine_precision_on_the_oscillator():
    problem = problems.harmonic_oscillator(1.0, 1.0, 0.5)
    integrator = gvi.Integrator(problem.system, stability.method_for("lobatto", 12))
    exact = problem.exact(10.0)[0]
    for h in (1.0, 0.5):
        traj = integrator.integrate(problem.q0, problem.v0, h=h, n_steps=round(10 / h))
        assert abs(traj.q[-1, 0] - exact) <= 1e-12  # measured 2.4e-15 (h = 1), 3.2e-14 (h = 0.5)


# ----------------------------------------------------------------------- stress
@pytest.mark.stress
@pytest.mark.parametrize("degree", [1, 2, 3, 4, 5, 6])
def test_every_lobatto_edge_up_to_16_matches_the_runs(degree):
    # weak instabilities are run with 4x the steps they need to grow 1e6-fold (up to 2.5e6:
    # s = 5's first interval (3.141564, 3.141616), peak rho - 1 = 2.6e-5); measured
    # relative differences <= 1.5e-5 (s = 6, second interval, N = 26558)
    result = stability.analyse("lobatto", degree)
    check = stability.check_against_runs(result, 20_000, 16.0, max_steps=2_500_000)
    for edge in check.edges:
        assert abs(edge.measured - edge.theory) < 3 * edge.expected_lag + 1e-7 * edge.theory
    assert all(run.outcome == "bounded" and run.finite for run in check.stable_runs)
    for peak in check.unstable_runs:
        assert peak["run"]["finite"]
        if peak["observable"]:
            assert peak["run"]["outcome"] in ("warning", "error")
        else:  # s = 6 at pi: rho - 1 = 4.5e-7, growth 0.004 decades predicted in 20000 steps
            assert peak["run"]["growth"] <= peak["predicted_growth"] + 0.5


@pytest.mark.stress
def test_gauss_sweep_to_1000_stays_bounded():
    for degree in range(1, 7):
        sweep = stability.growth_sweep("gauss", degree, np.geomspace(0.05, 1000.0, 40), 2000)
        assert sweep["finite"] and set(sweep["outcome"]) == {"bounded"}


@pytest.mark.stress
def test_fpu_sweep_every_trajectory_finite_and_limits_as_predicted():
    result = stability.fpu_sweep(stability.FULL.fpu_xs, 2000)
    assert result["omega_max"] == pytest.approx(50.1, abs=0.1)  # measured 50.116
    for entry in result["methods"]:
        assert entry["all_finite"]
        assert all(r["finite"] for r in entry["runs"])
    verlet, lobatto, gauss = result["methods"]
    # measured brackets [1.9933, 1.9934] (predicted 1.9954) and [2.8232, 2.8234] (2.8219)
    for entry in (verlet, lobatto):
        lo, hi = entry["measured_limit"]["bracket"]
        assert lo == pytest.approx(entry["predicted_limit"], rel=2e-3)
    # Gauss 2 runs bounded up to h omega = 15; Newton first fails at 17.5 (bracket 16.81)
    assert gauss["first_newton_failure"] >= 10


@pytest.mark.stress
def test_high_degree_accuracy_lobatto_against_equidistant():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.ConditioningWarning)
        result = stability.high_degree(range(6, 17), (1.0, 0.5))
    for row in result["rows"]:
        lobatto, equidistant = row["lobatto"], row["equidistant"]
        for kernel in ("linear", "newton"):
            # measured <= 8.8e-14 (s = 14, h = 0.5, linear)
            assert max(lobatto[kernel]["error"].values()) <= 2e-13
        assert equidistant["cond"]["0.5"] > lobatto["cond"]["0.5"]
    last = result["rows"][-1]
    # s = 16: one LU solve per step (linear kernel) amplifies round-off by kappa = 1.3e8:
    # measured 8.5e-11 / 1.8e-10 against 1.3e-15 / 2.2e-15 with Lobatto nodes
    assert min(last["equidistant"]["linear"]["error"].values()) > 1e-12


@pytest.mark.stress
def test_benchmark_quick_run_writes_its_outputs(tmp_path):
    assert stability.main(["--quick", "--output", str(tmp_path)]) == 0
    for name in ("stability.json", "stability.md", "stability_trace.png"):
        assert (tmp_path / name).stat().st_size > 0


@pytest.mark.parametrize("n", [2, 40], ids=["floats", "arrays"])
def test_the_growth_bound_of_one_run_against_its_definition(n):
    # within: no state exceeds EXPLOSIVE_GROWTH times the first's size (at least 1);
    # NaN and inf anywhere are never within
    from galerkin_vi.run.trust import EXPLOSIVE_GROWTH, within_growth_bound

    rng = np.random.default_rng(3)
    for _ in range(300):
        q_first, p_first = rng.standard_normal((2, 1, n)) * 10.0 ** rng.integers(-3, 3)
        q, p = rng.standard_normal((2, 2, n)) * 10.0 ** rng.integers(-2, 6)
        if rng.random() < 0.2:
            (q, p)[rng.integers(2)].flat[rng.integers(2 * n)] = rng.choice([np.nan, np.inf])
        start = max(1.0, np.abs(q_first).max(), np.abs(p_first).max())
        with np.errstate(invalid="ignore"):
            top = np.abs(np.concatenate([q, p])).max()
        expected = bool(np.isfinite(top) and top <= EXPLOSIVE_GROWTH * start)
        assert within_growth_bound(q_first, p_first, q, p) == expected
    ones = np.ones((1, n))
    first = ones.copy()
    first[0, -1] = np.nan  # a start that is not finite is never within either
    assert not within_growth_bound(first, ones, ones, ones)
    assert not within_growth_bound(ones, ones, ones, np.where(first == 1, 1, np.nan))
