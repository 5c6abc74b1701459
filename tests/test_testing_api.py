"""galerkin_vi.testing: assert_order and assert_conserved, passing, failing and misused.

Everything runs on the numpy backend (no compilation) with short runs.
"""

from __future__ import annotations

import re

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.testing import assert_conserved, assert_order

NUMPY = {"backend": "numpy"}


@pytest.fixture(scope="module")
def oscillator() -> problems.Problem:
    return problems.harmonic_oscillator()


@pytest.fixture(scope="module")
def kepler_run() -> tuple[problems.Problem, gvi.Trajectory]:
    problem = problems.kepler(0.5)
    traj = gvi.Integrator(problem.system, gvi.Galerkin(2), backend="numpy").integrate(
        problem.q0, problem.v0, h=2 * np.pi / 100, n_steps=400, save_every=2
    )
    return problem, traj


def _oscillator_trajectory(symplectic: bool, h: float = 0.1, steps: int = 2000):
    """Hand-made run of q'' = -q: symplectic Euler, or explicit Euler (energy grows)."""
    system = problems.harmonic_oscillator().system
    q, p = np.empty(steps + 1), np.empty(steps + 1)
    q[0], p[0] = 1.0, 0.0
    for k in range(steps):
        p[k + 1] = p[k] - h * q[k]
        q[k + 1] = q[k] + h * (p[k + 1] if symplectic else p[k])
    return gvi.Trajectory(
        t=h * np.arange(steps + 1),
        q=q[:, None],
        p=p[:, None],
        newton_iterations=np.zeros(steps, dtype=np.uint8),
        max_residual=0.0,
        system=system,
        params=np.array([1.0]),
    )


# ----------------------------------------------------------------- assert_order


@pytest.mark.parametrize("s", [1, 2])
def test_assert_order_passes_on_oscillator(oscillator, s):
    # measured 2.00 and 4.00 (errors 1.5e-3 .. 9.8e-9 over N = 10, 20, 40)
    result = assert_order(oscillator, gvi.Galerkin(s), step_counts=[10, 20, 40], **NUMPY)
    assert isinstance(result, gvi.OrderResult)
    assert result.mask.all()
    assert abs(result.order - 2 * s) < 0.05


def test_assert_order_bare_system_with_initial_data():
    x, v = sp.symbols("x v")
    system = gvi.LagrangianSystem(v**2 / 2 + sp.cos(x), [x], [v])
    result = assert_order(
        system, gvi.Galerkin(1), [1.0], [0.0], t_final=2.0, step_counts=[10, 20, 40], **NUMPY
    )
    assert abs(result.order - 2) <= 0.3


def test_assert_order_overridden_initial_data_drops_exact_solution(oscillator):
    # the exact solution belongs to the problem's own q0, v0 and omega; with others the
    # reference must be Richardson extrapolation, or the "errors" would be O(1)
    omega = oscillator.system.params[0]
    result = assert_order(oscillator, gvi.Galerkin(1), q0=[0.3], step_counts=[10, 20, 40], **NUMPY)
    assert result.errors.max() < 1e-2
    result = assert_order(
        oscillator, gvi.Galerkin(1), params={omega: 2.0}, step_counts=[10, 20, 40], **NUMPY
    )
    assert result.errors.max() < 1e-1


def test_assert_order_wrong_prediction_shows_table(oscillator):
    table = r"(?s)N\s+h\s+error\s+order\n.*10\s+2\.0000e-01.*4\.00\n"
    with pytest.raises(
        AssertionError, match=r"fitted order 4\.00 differs from the predicted 6"
    ) as info:
        assert_order(oscillator, gvi.Galerkin(2), predicted=6, step_counts=[10, 20, 40], **NUMPY)
    message = str(info.value)
    assert re.search(table, message), message
    assert "predicted=6 was given; method.order is 4" in message
    assert "hints:" in message


def test_assert_order_round_off_floor_hint(oscillator):
    with pytest.raises(AssertionError, match=r"(?s)excluded: round-off floor.*dps=40"):
        assert_order(oscillator, gvi.Galerkin(2), step_counts=[10, 20, 500, 1000], **NUMPY)


def test_assert_order_tolerance_is_respected(oscillator):
    # fitted 4.00 against a prediction of 3.5: fails at 0.3, passes at 0.6
    with pytest.raises(AssertionError, match="tolerance 0.3"):
        assert_order(oscillator, gvi.Galerkin(2), predicted=3.5, step_counts=[10, 20, 40], **NUMPY)
    assert_order(
        oscillator,
        gvi.Galerkin(2),
        predicted=3.5,
        tolerance=0.6,
        step_counts=[10, 20, 40],
        **NUMPY,
    )


@pytest.mark.parametrize(
    ("args", "kwargs", "error", "match"),
    [
        (("not a system", gvi.Galerkin(1)), {}, TypeError, "LagrangianSystem or a .*Problem"),
        ((None, "Galerkin(1)"), {}, TypeError, "method must be a galerkin_vi.Galerkin"),
        ((None, gvi.Galerkin(1)), {"tolerance": -0.1}, ValueError, "tolerance must be positive"),
        ((None, gvi.Galerkin(1)), {"tolerance": "0.3"}, TypeError, "tolerance must be a real"),
        ((None, gvi.Galerkin(1)), {"predicted": True}, TypeError, "predicted must be a real"),
        ((None, gvi.Galerkin(1)), {"min_points": 1}, ValueError, "min_points must be at least 2"),
        ((None, gvi.Galerkin(1)), {"step_counts": 8}, TypeError, "step_counts must be a seq"),
        (
            (None, gvi.Galerkin(1)),
            {"step_counts": [10, 20]},
            ValueError,
            "2 step counts cannot give min_points=3",
        ),
        (
            (None, gvi.Galerkin(1)),
            {"stepcounts": [8, 16]},
            TypeError,
            "unexpected keyword.*stepcounts",
        ),
    ],
)
def test_assert_order_bad_arguments(oscillator, args, kwargs, error, match):
    target = oscillator if args[0] is None else args[0]
    with pytest.raises(error, match=match):
        assert_order(target, args[1], **kwargs)


def test_assert_order_bare_system_needs_initial_data(oscillator):
    with pytest.raises(TypeError, match="needs q0 for a bare LagrangianSystem"):
        assert_order(oscillator.system, gvi.Galerkin(1))
    with pytest.raises(TypeError, match=r"needs v0 \(or p0=\)"):
        assert_order(oscillator.system, gvi.Galerkin(1), [1.0])


# ------------------------------------------------------------- assert_conserved


def test_assert_conserved_passes_on_kepler(kepler_run):
    # measured: rotation drift 2.6e-15, energy 2.9e-6 (no drift) over 400 steps of T/100
    problem, traj = kepler_run
    x, y = problem.system.q
    drifts = assert_conserved(
        traj, energy=1e-5, momenta={"rotation": ((-y, x), 1e-12)}, bounded=True
    )
    assert set(drifts) == {"energy", "rotation"}
    assert drifts["rotation"] <= 1e-12
    assert assert_conserved(traj, momenta=problem.symmetries, momentum_tol=1e-12).keys() == {
        "rotation"
    }


def test_assert_conserved_too_tight_bound_shows_table(kepler_run):
    problem, traj = kepler_run
    x, y = problem.system.q
    with pytest.raises(AssertionError) as info:
        assert_conserved(traj, energy=1e-9, momenta={"rotation": ((-y, x), 1e-12)})
    message = str(info.value)
    assert message.startswith("assert_conserved: 1 of 2 checks failed (201 saved states")
    assert "quantity" in message and "bound" in message and "max drift" in message
    energy_row = next(line for line in message.splitlines() if line.startswith("energy"))
    rotation_row = next(line for line in message.splitlines() if line.startswith("rotation"))
    assert energy_row.endswith("FAIL") and rotation_row.endswith("ok")
    # the time of the largest deviation is a saved time of the run
    when = float(energy_row.split()[-2])
    assert np.min(np.abs(traj.t - when)) < 1e-3 * when


def test_assert_conserved_relative_false_uses_absolute_drift(kepler_run):
    problem, traj = kepler_run
    x, y = problem.system.q
    J = traj.momentum((-y, x))
    drifts = assert_conserved(traj, momenta={"rotation": ((-y, x), 1e-12)}, relative=False)
    assert drifts["rotation"] == pytest.approx(np.max(np.abs(J - J[0])))


def test_assert_conserved_bounded_detects_drift():
    # explicit Euler: H grows by (1 + h^2) per step, about 1.5e9 over 2000 steps of h = 0.1
    with pytest.raises(AssertionError, match=r"energy no-drift check: .* > 2 x first tenth .*FAIL"):
        assert_conserved(_oscillator_trajectory(symplectic=False), bounded=True)
    # symplectic Euler: the energy error oscillates (max 5e-2 in both tenths)
    assert_conserved(_oscillator_trajectory(symplectic=True), energy=0.06, bounded=True)


def test_assert_conserved_non_finite_energy_fails():
    traj = _oscillator_trajectory(symplectic=True)
    traj.q[5, 0] = np.nan
    with pytest.raises(AssertionError, match=r"energy .*inf .*0\.5 +FAIL"):
        assert_conserved(traj, energy=1.0)


@pytest.mark.parametrize(
    ("kwargs", "error", "match"),
    [
        ({}, ValueError, "nothing to check"),
        ({"energy": -1.0}, ValueError, "energy must be a non-negative bound"),
        ({"energy": "1e-6"}, TypeError, "energy must be a real number"),
        ({"momenta": [(1, 0)]}, TypeError, "momenta must be a mapping"),
        ({"momenta": {"rotation": ("-y", "x")}}, ValueError, "has no bound"),
        ({"momenta": {"energy": ((1, 0), 1e-6)}}, ValueError, "'energy' is reserved"),
        ({"momenta": {"bad": ((1, 0, 0), 1e-6)}}, ValueError, "xi must have 2 components"),
        ({"momenta": {"bad": sp.Symbol("x")}}, TypeError, "sequence of expressions"),
        ({"bounded": 1}, TypeError, "bounded must be True or False"),
    ],
)
def test_assert_conserved_bad_arguments(kepler_run, kwargs, error, match):
    _, traj = kepler_run
    with pytest.raises(error, match=match):
        assert_conserved(traj, **kwargs)


def test_assert_conserved_rejects_non_trajectories(kepler_run):
    _, traj = kepler_run
    with pytest.raises(TypeError, match="must be a galerkin_vi.Trajectory, got ndarray"):
        assert_conserved(traj.q, energy=1e-6)
    failure = gvi.ConvergenceError("failed", step=3, t=0.3, residual=1.0, partial=traj)
    with pytest.raises(TypeError, match=r"pass its \.partial trajectory"):
        assert_conserved(failure, energy=1e-6)


def test_assert_conserved_bounded_needs_enough_states():
    short = _oscillator_trajectory(symplectic=True, steps=10)
    with pytest.raises(ValueError, match="need at least 20, got 11"):
        assert_conserved(short, bounded=True)
