"""Adaptive runs at the cost of the hand-written kernel: the persistent fixed point, few
compiled calls per run to a final time, and a landing step started from the clocks known."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.adaptive.integrator import landing_guess
from galerkin_vi.problems import gravitation
from galerkin_vi.run import dispatch, segment
from galerkin_vi.run.loop_choice import EARLY_HAND_OVER, PERSISTENT, hand_over

GAUSS4 = gvi.Galerkin(4, gvi.gauss_legendre(4))
PERIODS = 10


@pytest.fixture(scope="module")
def kepler():
    return gravitation.kepler(0.9)


@pytest.fixture(scope="module")
def g(kepler):
    x, y = kepler.system.q
    return gvi.encounter_scaling([sp.sqrt(x**2 + y**2)], 1.5)


def count_hand_overs(monkeypatch) -> list[int]:
    """Count the varying-mass loop's hand-overs to Newton (one per segment at most)."""
    calls = [0]
    original = segment.continue_from_last_row

    def counted(*args, **kwargs):
        calls[0] += 1
        return original(*args, **kwargs)

    monkeypatch.setattr(segment, "continue_from_last_row", counted)
    return calls


def test_the_rules_of_fixed_point():
    assert hand_over(True) == EARLY_HAND_OVER
    assert hand_over(False) == EARLY_HAND_OVER  # not read: the Newton loop runs
    assert hand_over("persistent") == PERSISTENT
    # a sweep in closed form costs a fraction of a Newton iteration: True keeps it
    assert hand_over(True, closed_form=True) == PERSISTENT
    assert hand_over("persistent", closed_form=True) == PERSISTENT
    double_pendulum = gvi.Integrator(problems.double_pendulum().system, GAUSS4)
    assert double_pendulum.run_spec.hand_over == PERSISTENT
    assert math.isinf(PERSISTENT.contraction) and math.isinf(PERSISTENT.allowance)
    system = gravitation.kepler(0.5).system
    for bad in ("always", 1, None):
        with pytest.raises(ValueError, match="fixed_point must be True, False or 'persistent'"):
            gvi.Integrator(system, GAUSS4, fixed_point=bad)


def test_the_adaptive_run_keeps_the_fixed_point_at_pericentre(kepler, g, monkeypatch):
    """Kepler e = 0.9, Gauss(4), h = 0.2: with the early rule (``fixed_point=True`` on a
    system without a closed-form sweep) every chunk hands over to Newton at its first
    pericentre; the persistent default never does, and both converge the stage equations
    to round-off: the final states agree to round-off growth."""
    t_final = 2 * math.pi * PERIODS
    calls = count_hand_overs(monkeypatch)
    adaptive = gvi.AdaptiveIntegrator(kepler.system, GAUSS4, g=g)
    assert adaptive.integrator.fixed_point == "persistent"
    kept = adaptive.integrate(kepler.q0, kepler.v0, h=0.2, t_final=t_final, on_failure="raise")
    assert calls[0] == 0
    with monkeypatch.context() as patch:
        patch.setattr(dispatch, "hand_over", lambda *_, **__: EARLY_HAND_OVER)
        early = gvi.AdaptiveIntegrator(kepler.system, GAUSS4, g=g, fixed_point=True)
        handed = early.integrate(kepler.q0, kepler.v0, h=0.2, t_final=t_final, on_failure="raise")
    assert calls[0] >= 2
    assert kept.t[-1] == handed.t[-1] == t_final
    assert np.abs(kept.q[-1] - handed.q[-1]).max() < 1e-11
    exact = gravitation.kepler_position(t_final, 0.9)
    assert np.abs(kept.q[-1] - exact).max() < 1e-6  # 1.3e-7 measured
    # the rule travels with the integrator into copies and ensembles
    again = pickle.loads(pickle.dumps(adaptive))
    assert again.integrator.fixed_point == "persistent"
    copy = again.integrate(kepler.q0, kepler.v0, h=0.2, t_final=t_final, on_failure="raise")
    assert np.array_equal(copy.q, kept.q)
    many = adaptive.integrate_many(
        np.stack([kepler.q0, kepler.q0]), np.stack([kepler.v0, kepler.v0]), h=0.2,
        t_final=t_final, workers=1,
    )  # fmt: skip
    assert np.array_equal(many[1].q[-1], kept.q[-1])


def test_a_run_to_a_final_time_takes_few_compiled_calls(kepler, g):
    """Chunks cover the predicted steps (plus 1%) and the landing starts from the step that
    passed t_final and the inverse quadratic guess: 2 chunks and 2 landing steps measured on
    1,000 steps (before: 7 chunks and 5 landing steps on 4,000)."""
    adaptive = gvi.AdaptiveIntegrator(kepler.system, GAUSS4, g=g)
    calls = []
    run = adaptive.integrator.integrate

    def counted(*args, **kwargs):
        calls.append(kwargs["n_steps"])
        return run(*args, **kwargs)

    adaptive.integrator.integrate = counted
    t_final = 2 * math.pi * PERIODS
    traj = adaptive.integrate(kepler.q0, kepler.v0, h=0.1, t_final=t_final)
    landing = sum(1 for n in calls if n == 1)
    assert traj.t[-1] == t_final and traj.success
    assert len(calls) - landing <= 3
    assert landing <= 3
    dropped = sum(calls) - landing - (traj.n_steps - 1)
    assert 0 <= dropped <= 0.05 * traj.n_steps + 20


@pytest.mark.parametrize("with_before", [True, False])
def test_landing_guess_has_its_order(with_before):
    """On a clock t(tau) = exp(tau) the guess's error falls like h^3 with the step before
    known (inverse quadratic interpolation), like h^2 without it (linear)."""
    errors = []
    for h in (0.2, 0.1, 0.05):
        target = math.exp(0.37 * h)
        t_before = math.exp(-h) if with_before else None
        guess = landing_guess(t_before, 1.0, math.exp(h), h, target)
        errors.append(abs(guess - 0.37 * h))
    rates = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    expected = 3.0 if with_before else 2.0
    assert np.all(np.abs(rates - expected) < 0.2), rates
    # clocks that do not increase (a step past a turning point) fall back to the linear guess
    assert landing_guess(1.5, 1.0, 2.0, 0.1, 1.5) == pytest.approx(0.05)


def test_small_steps_converge_to_round_off_late_in_a_long_run(kepler, g):
    """Gauss(6), 100 periods (the clock reaches 628): each coordinate's change is measured
    against its own size. Against the largest |q| (the clock) the round-off test accepted
    position changes of 6e-8 as converged: 2.7e-8 at h = 0.071, with energy jumps of 1e-10."""
    t_final = 2 * math.pi * 100
    exact = gravitation.kepler_position(t_final, 0.9)
    adaptive = gvi.AdaptiveIntegrator(kepler.system, gvi.Galerkin(6, gvi.gauss_legendre(6)), g=g)
    for h in (0.1, 0.1 / math.sqrt(2)):
        traj = adaptive.integrate(kepler.q0, kepler.v0, h=h, t_final=t_final, save_every=100)
        energy = traj.energy()
        assert np.abs(traj.q[-1] - exact).max() < 1e-11
        assert np.abs(energy - energy[0]).max() < 1e-12
