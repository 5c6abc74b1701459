"""Symplecticity: energy error is bounded with no drift over long runs (theory.md §5)."""

from __future__ import annotations

import numpy as np
import pytest

import galerkin_vi as gvi
from galerkin_vi import problems

STEPS = 100_000


def _tenths(energy: np.ndarray) -> tuple[float, float]:
    error = np.abs(energy - energy[0])
    tenth = error.size // 10
    return float(error[1 : tenth + 1].max()), float(error[-tenth:].max())


@pytest.mark.parametrize("s", [1, 2, 3])
def test_pendulum_energy_bounded(s):
    # theory.md §5: max|dH| first/last tenth 3.27e-2/3.27e-2 (s=1), 7.9e-5/7.9e-5 (s=2)
    # at h = 0.4; here h = 0.2 over 1e5 steps
    problem = problems.pendulum(1.5, 0.3)
    traj = gvi.Integrator(problem.system, gvi.Galerkin(s)).integrate(
        problem.q0, problem.v0, h=0.2, n_steps=STEPS, save_every=10
    )
    first, last = _tenths(traj.energy())
    bound = {1: 2e-2, 2: 1e-5, 3: 1e-8}[s]
    assert last <= 2.0 * first + 1e-14
    assert max(first, last) <= bound


@pytest.mark.parametrize("method", [gvi.Galerkin(2), gvi.Galerkin(2, gvi.gauss_legendre(2))])
def test_kepler_energy_bounded(method):
    problem = problems.kepler(0.5)
    traj = gvi.Integrator(problem.system, method).integrate(
        problem.q0, problem.v0, h=2 * np.pi / 200, n_steps=STEPS, save_every=10
    )
    first, last = _tenths(traj.energy())
    assert last <= 2.0 * first + 1e-14
    assert max(first, last) <= 1e-5
