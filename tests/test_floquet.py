"""Floquet stability of periodic orbits: monodromy matrices, multipliers, stability changes."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import sympy as sp
from scipy.optimize import brentq
from scipy.special import mathieu_a, mathieu_b

import galerkin_vi as gvi
from galerkin_vi.problems import n_body
from galerkin_vi.tangent.floquet import STABILITY_TOLERANCE, is_linearly_stable

th, w = sp.symbols("theta w")
PENDULUM = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])
J2 = np.array([[0.0, 1.0], [-1.0, 0.0]])


def test_the_pendulums_orbit_has_the_double_multiplier_one():
    orbit = gvi.solve_periodic(PENDULUM, gvi.Galerkin(3), [0.9], [0.0], 6.0, 40,
                               energy=-np.cos(1.0))  # fmt: skip
    M = orbit.monodromy
    assert M.shape == (2, 2)
    assert np.abs(M.T @ J2 @ M - J2).max() < 1e-12  # symplectic
    assert np.trace(M) == pytest.approx(2.0, abs=1e-12)  # both multipliers 1 ...
    # ... in a Jordan block (the period grows with the energy: a shear), so the
    # multipliers themselves are 1 only to sqrt(round-off): measured 5e-8
    assert abs(M[1, 0]) > 0.1
    np.testing.assert_allclose(orbit.floquet_multipliers, [1.0, 1.0], rtol=0, atol=1e-6)
    assert orbit.is_linearly_stable


def test_the_figure_eight_is_linearly_stable():
    problem = n_body(masses=(1.0, 1.0, 1.0), softening=0.0)
    symmetries = [problem.symmetries[name]
                  for name in ("translation_x", "translation_y", "rotation")]  # fmt: skip
    x1 = np.array([0.97000436, -0.24308753])
    v3 = np.array([-0.93240737, -0.86473146])
    q0 = np.concatenate([x1, -x1, [0.0, 0.0]])
    v0 = np.concatenate([-v3 / 2, -v3 / 2, v3])
    orbit = gvi.solve_periodic(problem.system, gvi.Galerkin(6), q0, v0, 6.32591398292621, 60,
                               symmetries=symmetries)  # fmt: skip
    assert orbit.success
    mu = orbit.floquet_multipliers
    assert mu.shape == (12,) and np.all(np.diff(np.abs(mu)) <= 0)
    # time shift, energy, two translations, rotation and angular momentum: eight 1s
    # (Jordan blocks: on the circle to sqrt(round-off), measured 2.3e-6), and two
    # pairs on the unit circle (Simo 2002; Roberts 2007): linearly stable
    trivial = np.abs(mu - 1) < 1e-4
    assert trivial.sum() == 8
    assert np.abs(np.abs(mu[trivial]) - 1).max() < 1e-5
    assert np.abs(np.abs(mu[~trivial]) - 1).max() < 1e-10
    assert np.abs(mu[~trivial].imag).min() > 0.05  # genuinely elliptic, away from 1
    assert orbit.is_linearly_stable


def _coupled():
    r"""x oscillates harmonically (period 2 pi at every amplitude A); across the orbit
    y'' + (0.81 + A^2 + A^2 cos 2t) y = 0, a Mathieu equation."""
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx**2 + vy**2) / 2 - x**2 / 2 - sp.Rational(81, 100) * y**2 / 2 - x**2 * y**2
    return gvi.LagrangianSystem(L, [x, y], [vx, vy])


def _mathieu_tongue() -> tuple[float, float]:
    """The energies E = A^2/2 = |q| where a = 0.81 + 2|q| crosses b_1(|q|) and a_1(|q|)."""
    lower = brentq(lambda q: 0.81 + 2 * q - mathieu_b(1, q), 1e-6, 0.5)
    upper = brentq(lambda q: 0.81 + 2 * q - mathieu_a(1, q), 1e-6, 0.5)
    return lower, upper  # 0.0632, 0.1856


def test_a_family_reports_where_it_enters_and_leaves_the_mathieu_tongue():
    system, method = _coupled(), gvi.Galerkin(3)
    start = gvi.solve_periodic(system, method, [0.2, 0.0], [0.0, 0.0], 2 * np.pi, 40,
                               energy=0.02)  # fmt: skip
    energies = np.arange(0.03, 0.255, 0.01)
    family = gvi.follow_family(system, method, start, energies)
    assert isinstance(family, list) and len(family) == len(energies)
    assert all(orbit.success for orbit in family)
    changes = family.stability_changes
    assert [change.stable for change in changes] == [False, True]
    for change, boundary in zip(changes, _mathieu_tongue(), strict=True):
        low, high = change.energies
        assert low < boundary < high
        assert energies[change.index - 1] == pytest.approx(low, abs=1e-12)
    inside = family[changes[0].index]
    assert np.abs(inside.floquet_multipliers[0]) > 1.05  # a real pair mu, 1/mu off the circle
    np.testing.assert_array_equal(
        family.stable, [not (changes[0].index <= i < changes[1].index) for i in range(len(family))]
    )


def test_an_orbit_pickles_with_its_multipliers_and_an_unconverged_one_has_none():
    orbit = gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20,
                               energy=-np.cos(1.0))  # fmt: skip
    mu = orbit.floquet_multipliers
    copy = pickle.loads(pickle.dumps(orbit))
    np.testing.assert_array_equal(copy.floquet_multipliers, mu)
    np.testing.assert_array_equal(copy.monodromy, orbit.monodromy)
    failed = gvi.solve_periodic(PENDULUM, gvi.Galerkin(2), [0.9], [0.0], 6.0, 20,
                                energy=-np.cos(1.0), maxiter=1)  # fmt: skip
    with pytest.raises(ValueError, match="the periodic orbit did not converge"):
        _ = failed.monodromy
    with pytest.raises(ValueError, match="tol must be positive"):
        is_linearly_stable(mu, tol=0.0)
    assert STABILITY_TOLERANCE == 1e-4
