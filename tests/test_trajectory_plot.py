"""``Trajectory.plot``: positions, energy error and momenta against t."""

from __future__ import annotations

import matplotlib

matplotlib.use("Agg")  # no screen in CI

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402

import galerkin_vi as gvi  # noqa: E402
from galerkin_vi import problems  # noqa: E402


@pytest.fixture(scope="module")
def kepler_run():
    problem = problems.kepler(0.5)
    integ = gvi.Integrator(problem.system, gvi.Galerkin(2))
    return integ.integrate(problem.q0, problem.v0, h=0.05, n_steps=400, save_every=4)


def test_three_panels_hold_the_trajectorys_data(kepler_run):
    fig = kepler_run.plot()
    try:
        ax_q, ax_e, ax_p = fig.axes
        assert len(ax_q.lines) == 2 and len(ax_p.lines) == 2
        np.testing.assert_array_equal(ax_q.lines[1].get_ydata(), kepler_run.q[:, 1])
        np.testing.assert_array_equal(ax_p.lines[0].get_ydata(), kepler_run.p[:, 0])
        # the energy panel is the relative energy error where it is not exactly zero
        energy = kepler_run.energy()
        expected = np.abs(energy - energy[0]) / max(1.0, abs(energy[0]))
        drawn = ax_e.lines[0].get_ydata()
        np.testing.assert_array_equal(drawn, expected[expected > 0])
        np.testing.assert_array_equal(ax_e.lines[0].get_xdata(), kepler_run.t[expected > 0])
        assert ax_e.get_yscale() == "log"
        assert drawn.max() < 1e-4  # Gauss-Lobatto(3), h = 0.05: bounded energy error
        assert [t.get_text() for t in ax_q.get_legend().get_texts()] == ["x", "y"]
    finally:
        plt.close(fig)


def test_long_chains_draw_a_few_coordinates_and_say_so():
    chain = problems.spring_chain(20, beta=1.0)
    traj = gvi.Integrator(chain.system, gvi.Galerkin(2)).integrate(
        chain.q0, chain.v0, h=0.1, n_steps=50
    )
    fig = traj.plot()
    try:
        assert len(fig.axes[0].lines) == 8
        assert "8 of 20 coordinates" in fig.axes[0].get_title()
    finally:
        plt.close(fig)
    fig = traj.plot(coordinates=[0, 19])
    try:
        assert len(fig.axes[2].lines) == 2
    finally:
        plt.close(fig)
    with pytest.raises(ValueError, match="coordinates must be indices"):
        traj.plot(coordinates=[20])
