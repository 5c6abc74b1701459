"""The Newton iteration and the allocation-free LU, without any Lagrangian."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp

from galerkin_vi.newton import (
    CONTINUE,
    CONVERGED,
    DIVERGED,
    NOT_CONVERGED,
    band_lu_factor,
    band_lu_solve,
    lu_factor_inplace,
    lu_solve_inplace,
    newton_solve,
    newton_status,
)

ROOT = np.array([np.sqrt(2.0), np.sqrt(2.0), 0.5])


def circle_system(record=None):
    """x^2 + y^2 = 4, x = y, z^3 + z = 5/8 (root: sqrt(2), sqrt(2), 1/2)."""

    def f(u):
        if record is not None:
            record.append(u.copy())
        x, y, z = u
        r = np.array([x**2 + y**2 - 4.0, x - y, z**3 + z - 0.625])
        jac = np.array([[2 * x, 2 * y, 0.0], [1.0, -1.0, 0.0], [0.0, 0.0, 3 * z**2 + 1]])
        return r, jac

    return f


def test_converges_to_known_root():
    result = newton_solve(circle_system(), np.array([1.0, 2.0, 0.0]))
    assert result.converged
    assert result.status == CONVERGED
    np.testing.assert_allclose(result.x, ROOT, rtol=0, atol=1e-15)  # measured 0
    assert result.residual <= 1e-14  # measured 8.9e-16 (the residual before the last update)
    assert result.iterations <= 12  # measured 9 (incl. the stagnation checks)


def test_quadratic_convergence():
    iterates: list[np.ndarray] = []
    newton_solve(circle_system(iterates), np.array([1.0, 2.0, 0.0]))
    errors = [np.abs(u - ROOT).max() for u in iterates]
    ratios = [
        e1 / e0**2 for e0, e1 in zip(errors, errors[1:], strict=False) if e0 > 1e-7 and e1 > 0
    ]
    assert len(ratios) >= 3
    # e_{k+1} <= C e_k^2: measured ratios 0.36, 0.81, 0.85, 0.86 (-> f''/2f' = 0.857 of the
    # cubic); linear convergence would make them blow up like 1/e_k (here ~1e8)
    assert max(ratios) < 2.0
    assert errors[-1] <= 1e-15


def test_stops_on_stagnation_before_maxiter():
    # residual with noise at the 1e-16 level: the increment can never reach exactly zero,
    # so only the stagnation rule (increment stops decreasing) ends the iteration early
    calls = [0]

    def f(u):
        calls[0] += 1
        noise = 1e-15 * ((calls[0] * 7919) % 13 - 6) / 6
        return np.array([u[0] ** 3 - 2.0 + noise]), np.array([[3 * u[0] ** 2]])

    result = newton_solve(f, np.array([1.0]), tol=1e-14, maxiter=50)
    assert result.converged
    assert result.iterations < 15  # measured 7; without the stagnation stop it would be 50
    assert result.x[0] == pytest.approx(2 ** (1 / 3), rel=1e-15, abs=1e-15)


def test_maxiter_reached_is_not_converged():
    result = newton_solve(circle_system(), np.array([1.0, 2.0, 0.0]), maxiter=2)
    assert not result.converged
    assert result.status == NOT_CONVERGED
    assert result.iterations == 2


def test_no_real_root_fails():
    # x^2 + 1 = 0 has no real root: Newton wanders chaotically
    def f(u):
        return np.array([u[0] ** 2 + 1.0]), np.array([[2 * u[0]]])

    result = newton_solve(f, np.array([0.7]), maxiter=40)
    assert not result.converged
    assert result.status in (DIVERGED, NOT_CONVERGED)
    assert result.residual >= 1.0  # |x^2 + 1| >= 1 everywhere


def test_singular_jacobian_is_diverged():
    def f(u):
        x, y = u
        return np.array([x + y - 1.0, 2 * x + 2 * y - 3.0]), np.array([[1.0, 1.0], [2.0, 2.0]])

    result = newton_solve(f, np.zeros(2))
    assert result.status == DIVERGED
    assert result.iterations == 1
    assert result.increment == np.inf


def test_non_finite_residual_is_diverged():
    def f(u):
        return np.array([np.log(u[0])]), np.array([[1.0 / u[0]]])  # log of a negative -> NaN

    with np.errstate(invalid="ignore", divide="ignore"):
        result = newton_solve(f, np.array([-1.0]))
    assert result.status == DIVERGED
    assert not result.converged


# ----------------------------------------------------------- stopping rule
@pytest.mark.parametrize(
    ("increment", "previous", "scale", "iteration", "maxiter", "expected"),
    [
        (0.0, 1e-3, 1.0, 2, 30, CONVERGED),  # exactly zero
        # below eps^2 (1 + |X|) it counts as zero, though still decreasing: only
        # coordinates far below an ulp of |X| would change (a chain at rest at its far end)
        (1e-40, 1e-35, 1.0, 4, 30, CONVERGED),
        (1e-30, 1e-26, 1e3, 4, 30, CONVERGED),
        (1e-31, 1e-26, 1.0, 4, 30, CONTINUE),  # above eps^2 = 4.9e-32 and decreasing
        (1e-16, 1e-17, 1.0, 4, 30, CONVERGED),  # small and no longer decreasing
        (1e-16, 1e-16, 1.0, 4, 30, CONVERGED),  # stagnating at equality
        (1e-16, 1e-9, 1.0, 4, 30, CONTINUE),  # small but still decreasing: keep going
        (1e-16, 1e-9, 1.0, 30, 30, CONVERGED),  # small at the cap
        (1e-5, 1e-4, 1.0, 30, 30, NOT_CONVERGED),  # large at the cap
        (1e-5, 1e-4, 1.0, 3, 30, CONTINUE),
        (3e-4, 1e-4, 1.0, 3, 30, DIVERGED),  # more than doubled after 3 iterations
        (3e-4, 1e-4, 1.0, 2, 30, CONTINUE),  # ... but not before
        (np.inf, 1.0, 1.0, 1, 30, DIVERGED),
        (np.nan, 1.0, 1.0, 1, 30, DIVERGED),
        (1e301, np.inf, 1.0, 1, 30, DIVERGED),
        (1e-13, np.inf, 100.0, 1, 30, CONTINUE),  # tolerance is relative to 1 + |X|
        (1e-13, 1e-14, 100.0, 5, 30, CONVERGED),
        # above tol * scale = 1e-14 but no longer decreasing within 100 tol: the round-off
        # floor of an ill-conditioned solve (a 4-body close encounter stagnated at 1.3e-14)
        (1e-13, 1e-13, 1.0, 5, 30, CONVERGED),
        (1e-13, 1e-12, 1.0, 5, 30, CONTINUE),  # still decreasing
        (1e-11, 1e-11, 1.0, 5, 30, CONTINUE),  # stagnating far above the floor
        (1e-11, 1e-11, 1.0, 30, 30, NOT_CONVERGED),
        (1e-13, 1e-13, 1.0, 2, 30, CONTINUE),  # too early to call it stagnation
    ],
)
def test_newton_status(increment, previous, scale, iteration, maxiter, expected):
    assert newton_status(increment, previous, scale, 1e-14, iteration, maxiter) == expected


# ---------------------------------------------------------------------- LU
def _lu_solve(A, rhs):
    lu = np.array(A, dtype=float)
    piv = np.zeros(lu.shape[0], dtype=np.int64)
    ok = lu_factor_inplace(lu, piv)
    x = np.array(rhs, dtype=float)
    if ok:
        lu_solve_inplace(lu, piv, x)
    return ok, lu, piv, x


def _permuted(A, piv):
    pa = np.array(A, dtype=float)
    for k, p in enumerate(piv):
        pa[[k, p]] = pa[[p, k]]
    return pa


# exact zeros exercise the pivoting; no tiny magnitudes that would overflow the solution
entries = st.one_of(st.just(0.0), st.floats(1e-3, 10), st.floats(-10, -1e-3))
matrices = st.integers(1, 8).flatmap(
    lambda n: st.tuples(
        hnp.arrays(np.float64, (n, n), elements=entries),
        hnp.arrays(np.float64, (n,), elements=entries),
    )
)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(matrices)
def test_lu_solve_matches_numpy(data):
    A, rhs = data
    cond = np.linalg.cond(A)
    assume(np.isfinite(cond) and cond < 1e8)
    ok, lu, piv, x = _lu_solve(A, rhs)
    assert ok
    expected = np.linalg.solve(A, rhs)
    scale = max(1.0, np.abs(expected).max())
    assert np.abs(x - expected).max() <= 1e-14 * cond * scale  # measured <= 1.6e-16 cond
    # P A = L U with unit lower L and partial pivoting (|L| <= 1); the factors' diagonal
    # holds 1/u_ii
    L = np.tril(lu, -1) + np.eye(len(A))
    U = np.triu(lu, 1) + np.diag(1.0 / np.diag(lu))
    np.testing.assert_allclose(
        L @ U, _permuted(A, piv), rtol=0, atol=1e-13 * max(1.0, np.abs(A).max())
    )
    assert np.abs(np.tril(lu, -1)).max(initial=0.0) <= 1.0
    assert np.all((piv >= np.arange(len(A))) & (piv < len(A)))


def test_lu_pivots_on_zero_leading_entry():
    A = np.array([[0.0, 1.0], [1.0, 0.0]])
    ok, _, piv, x = _lu_solve(A, [2.0, 3.0])
    assert ok
    np.testing.assert_array_equal(piv, [1, 1])
    np.testing.assert_allclose(x, [3.0, 2.0])


@pytest.mark.parametrize(
    "A",
    [
        np.zeros((3, 3)),
        [[1.0, 2.0], [2.0, 4.0]],  # dependent rows
        [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, 0.0, 5.0]],  # zero column
        [[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]],  # row 2 = 2 row 1
        [[1.0, 2.0, 3.0], [4.0, 8.0, 13.0], [0.0, 0.0, 2.0]],  # zero pivot after elimination
        [[1.0, 2.0], [np.inf, 1.0]],
        [[np.nan, 1.0], [1.0, 1.0]],
    ],
)
def test_lu_detects_singular(A):
    lu = np.array(A, dtype=float)
    assert lu_factor_inplace(lu, np.zeros(lu.shape[0], dtype=np.int64)) is False


def test_lu_nearly_singular_but_regular_is_accepted():
    A = np.array([[1.0, 1.0], [1.0, 1.0 + 1e-12]])
    ok, _, _, x = _lu_solve(A, [2.0, 2.0 + 1e-12])
    assert ok
    np.testing.assert_allclose(
        x, [1.0, 1.0], rtol=0, atol=1e-3
    )  # cond 4e12: measured 0 (exact data)


# ------------------------------------------------------------------ banded LU
def _to_band(A: np.ndarray, kl: int, ku: int) -> np.ndarray:
    m = A.shape[0]
    ab = np.zeros((2 * kl + ku + 1, m))
    for i in range(m):
        for j in range(max(0, i - kl), min(m, i + ku + 1)):
            ab[kl + ku + i - j, j] = A[i, j]
    return ab


banded_systems = st.tuples(st.integers(1, 30), st.integers(0, 5), st.integers(0, 5)).flatmap(
    lambda dims: st.tuples(
        st.just(dims),
        hnp.arrays(np.float64, (dims[0], dims[0]), elements=entries),
        hnp.arrays(np.float64, (dims[0],), elements=entries),
    )
)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.filter_too_much])
@given(banded_systems)
def test_band_lu_solve_matches_dense_solve(data):
    (m, kl, ku), A, rhs = data
    i, j = np.indices(A.shape)
    A = np.where((i - j <= kl) & (j - i <= ku), A, 0.0)  # keep the band
    cond = np.linalg.cond(A)
    assume(np.isfinite(cond) and cond < 1e8)
    ab = _to_band(A, kl, ku)
    piv = np.zeros(m, dtype=np.int64)
    assert band_lu_factor(ab, piv, kl, ku)
    x = rhs.copy()
    band_lu_solve(ab, piv, kl, ku, x)
    expected = np.linalg.solve(A, rhs)
    scale = max(1.0, np.abs(expected).max())
    assert np.abs(x - expected).max() <= 1e-14 * cond * scale
    assert np.all((piv >= np.arange(m)) & (piv <= np.minimum(np.arange(m) + kl, m - 1)))


def test_band_lu_pivots_within_the_band():
    # a zero on the diagonal forces a row interchange, which fills the extra kl rows
    A = np.array([[0.0, 1.0, 0.0], [2.0, 1.0, 1.0], [0.0, 3.0, 1.0]])
    ab = _to_band(A, 1, 1)
    piv = np.zeros(3, dtype=np.int64)
    assert band_lu_factor(ab, piv, 1, 1)
    assert piv[0] == 1
    x = np.array([1.0, 2.0, 3.0])
    band_lu_solve(ab, piv, 1, 1, x)
    np.testing.assert_allclose(A @ x, [1.0, 2.0, 3.0], rtol=0, atol=1e-15)


@pytest.mark.parametrize(
    "A",
    [np.zeros((4, 4)), np.diag([1.0, 0.0, 2.0, 3.0]), np.diag([1.0, np.nan, 2.0, 3.0])],
)
def test_band_lu_detects_singular(A):
    assert not band_lu_factor(_to_band(A, 1, 1), np.zeros(4, dtype=np.int64), 1, 1)


def test_watched_unknowns_decide_convergence_alone():
    # x0 converges quadratically to its root; x1 carries noise of size 1e-11 that
    # never settles: watching x0 only, Newton stops once x0 has converged
    rng = np.random.default_rng(3)

    def residual_and_jacobian(x):
        noise = 1e-11 * rng.standard_normal()
        return np.array([x[0] ** 2 - 2.0, x[1] - 1.0 + noise]), np.array(
            [[2 * x[0], 0.0], [0.0, 1.0]]
        )

    watched = newton_solve(residual_and_jacobian, np.array([1.0, 0.0]), watched=1)
    assert watched.status == CONVERGED
    assert abs(watched.x[0] - np.sqrt(2.0)) <= 4e-16
    assert abs(watched.x[1] - 1.0) < 1e-10
    everything = newton_solve(residual_and_jacobian, np.array([1.0, 0.0]))
    assert everything.status != CONVERGED


def test_base_scales_the_stopping_test():
    # residual noise of 1e-10, the round-off of a coordinate of size 1e6: increments
    # stagnate there, above STAGNATION tol (1 + |x|) = 1e-12 for the increments alone;
    # judged against base = 1e6 (max|q_k|) they are at the floor and accepted
    rng = np.random.default_rng(0)

    def fun(x):
        return np.array([x[0] - 1e-3 + 1e-10 * rng.standard_normal()]), np.eye(1)

    assert newton_solve(fun, np.zeros(1)).status != CONVERGED
    assert newton_solve(fun, np.zeros(1), base=1e6).status == CONVERGED
