r"""Tests for galerkin_vi.method.basis.

The high-degree reference is the product form evaluated in mpmath at 50 digits, with
:math:`\ell_\nu' = w_\nu \sum_k \prod_{\mu \ne \nu, k}(x - d_\mu)` (prefix and suffix products):
independent of the barycentric formulas under test.  Nodes and points are the float64 inputs
converted exactly, so the comparison measures evaluation error only.
"""

from __future__ import annotations

import dataclasses

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from galerkin_vi.method.basis import (
    LagrangeBasis,
    equidistant_control_nodes,
    equidistant_control_nodes_mp,
    lagrange_tables,
    lobatto_control_nodes,
    lobatto_control_nodes_mp,
)
from galerkin_vi.method.quadrature import (
    gauss_legendre,
    gauss_legendre_mp,
    gauss_lobatto,
    gauss_lobatto_mp,
)

NODE_SETS = [("lobatto", s) for s in range(1, 31)] + [("equidistant", s) for s in range(1, 9)]


def control_nodes(kind: str, degree: int) -> np.ndarray:
    if kind == "lobatto":
        return lobatto_control_nodes(degree)
    return equidistant_control_nodes(degree)


def reference(nodes, x, dps: int = 50) -> tuple[np.ndarray, np.ndarray]:
    """Values and derivatives of every basis function at ``x`` by the product form.

    ``nodes`` and ``x`` are floats or mpmath numbers (converted exactly); results are rounded
    to float64.
    """
    with mpmath.workdps(dps):
        d = [mpmath.mpf(v) for v in nodes]
        xm = mpmath.mpf(x)
        n = len(d)
        values, derivs = [], []
        for nu in range(n):
            f = [xm - d[mu] for mu in range(n) if mu != nu]
            denominator = mpmath.fprod(d[nu] - d[mu] for mu in range(n) if mu != nu)
            prefix = [mpmath.mpf(1)]
            for v in f:
                prefix.append(prefix[-1] * v)
            suffix = [mpmath.mpf(1)]
            for v in reversed(f):
                suffix.append(suffix[-1] * v)
            suffix.reverse()
            derivative = mpmath.fsum(prefix[k] * suffix[k + 1] for k in range(len(f)))
            values.append(prefix[-1] / denominator)
            derivs.append(derivative / denominator)
        return np.array([float(v) for v in values]), np.array([float(v) for v in derivs])


def row_relative_error(actual: np.ndarray, expected: np.ndarray) -> float:
    """max over rows of max|actual - expected| / max|expected|."""
    actual, expected = np.atleast_2d(actual), np.atleast_2d(expected)
    return float(np.max(np.abs(actual - expected).max(axis=1) / np.abs(expected).max(axis=1)))


@pytest.mark.parametrize(("kind", "degree"), NODE_SETS)
def test_kronecker_property_is_exact(kind: str, degree: int) -> None:
    basis = LagrangeBasis(control_nodes(kind, degree))
    np.testing.assert_array_equal(basis.values(basis.nodes), np.eye(degree + 1))
    np.testing.assert_array_equal(basis.derivatives(basis.nodes), basis.differentiation_matrix())


@pytest.mark.parametrize(("kind", "degree"), NODE_SETS)
def test_partition_of_unity(kind: str, degree: int) -> None:
    basis = LagrangeBasis(control_nodes(kind, degree))
    rng = np.random.default_rng(degree)
    inside = rng.uniform(0.0, 1.0, 40)
    outside = np.concatenate([1.0 + basis.nodes, rng.uniform(-0.5, 0.0, 5), rng.uniform(1, 2, 5)])
    for x in (inside, outside):
        values, derivs = basis.values(x), basis.derivatives(x)
        # Relative to sum |.| because extrapolated values reach 1e21 at degree 30, x = 2.
        # Measured max 4.6e-16 (values) and 4.3e-16 (derivatives) over these node sets.
        assert np.all(np.abs(values.sum(axis=1) - 1) <= 2e-15 * np.abs(values).sum(axis=1))
        assert np.all(np.abs(derivs.sum(axis=1)) <= 2e-15 * np.abs(derivs).sum(axis=1))
    dmat = basis.differentiation_matrix()  # measured 7.3e-17
    assert np.all(np.abs(dmat.sum(axis=1)) <= 2e-15 * np.abs(dmat).sum(axis=1))


@pytest.mark.parametrize(("kind", "degree"), NODE_SETS)
def test_reproduces_polynomials_up_to_the_degree(kind: str, degree: int) -> None:
    basis = LagrangeBasis(control_nodes(kind, degree))
    rng = np.random.default_rng(100 + degree)
    x = np.concatenate([rng.uniform(0.0, 1.0, 30), gauss_legendre(degree + 2).nodes])
    values, derivs = basis.values(x), basis.derivatives(x)
    dmat = basis.differentiation_matrix()
    polynomials = [np.eye(degree + 1)[k] for k in range(degree + 1)]  # each degree up to s
    polynomials += [rng.uniform(-1, 1, degree + 1) for _ in range(3)]  # and random mixtures
    for c in polynomials:
        # Shifted Chebyshev series: |p| <= sum |c| on [0, 1].
        p = np.polynomial.Chebyshev(c, domain=[0.0, 1.0])
        dp = p.deriv()
        fd = p(basis.nodes)
        # Errors relative to the condition scale sum_nu |ell_nu(x)| |p(d_nu)| (and the same
        # with ell_nu').  Measured max 5.6e-14 (values), 1.2e-14 (derivatives) and 9.8e-15
        # (matrix), dominated by NumPy's own rounding in evaluating p: with p evaluated exactly
        # in mpmath the worst value case (GLL degree 25, T_17) drops from 3.1e-14 to 3.4e-16.
        assert np.all(np.abs(values @ fd - p(x)) <= 2e-13 * (np.abs(values) @ np.abs(fd)))
        assert np.all(np.abs(derivs @ fd - dp(x)) <= 5e-14 * (np.abs(derivs) @ np.abs(fd)))
        assert np.all(np.abs(dmat @ fd - dp(basis.nodes)) <= 5e-14 * (np.abs(dmat) @ np.abs(fd)))


def test_does_not_reproduce_degree_s_plus_1() -> None:
    basis = LagrangeBasis(lobatto_control_nodes(4))
    x = np.array([0.3])
    assert abs(basis.values(x) @ basis.nodes**5 - x**5)[0] > 1e-4


@pytest.mark.parametrize(("kind", "degree"), [("lobatto", 10), ("lobatto", 20), ("lobatto", 30)])
def test_high_degree_against_extended_precision(kind: str, degree: int) -> None:
    nodes = control_nodes(kind, degree)
    basis = LagrangeBasis(nodes)
    rng = np.random.default_rng(7)
    interior = np.concatenate(
        [
            rng.uniform(0.0, 1.0, 8),
            nodes[1:-1:3] + 1e-9,  # near a node: both branches of the formula
            nodes[1:-1:3] - 1e-13,
            [1e-14, 1.0 - 2**-52],
        ]
    )
    extrapolated = np.concatenate([1.0 + nodes[::4], [-0.3, 2.0]])
    for x in (interior, extrapolated):
        ref = [reference(nodes, xi) for xi in x]
        ref_values = np.array([r[0] for r in ref])
        ref_derivs = np.array([r[1] for r in ref])
        # Row-relative, measured max over degrees 10, 20, 30: values 4.4e-16 inside and
        # 7.4e-16 outside, derivatives 1.0e-15 and 7.4e-16 (the brief asks for ~1e-12).
        assert row_relative_error(basis.values(x), ref_values) <= 1e-14
        assert row_relative_error(basis.derivatives(x), ref_derivs) <= 1e-14
    ref_dmat = np.array([reference(nodes, d)[1] for d in nodes])
    # Measured max 8.1e-16.
    assert row_relative_error(basis.differentiation_matrix(), ref_dmat) <= 1e-14


@pytest.mark.parametrize("degree", [1, 2, 5, 12])
def test_barycentric_weights_match_definition(degree: int) -> None:
    nodes = lobatto_control_nodes(degree)
    weights = LagrangeBasis(nodes).barycentric_weights
    with mpmath.workdps(40):
        d = [mpmath.mpf(v) for v in nodes]
        expected = [
            1 / mpmath.fprod(d[i] - d[j] for j in range(len(d)) if j != i) for i in range(len(d))
        ]
    # Measured max 4.0e-16 relative.
    np.testing.assert_allclose(weights, [float(v) for v in expected], rtol=1e-14)


def test_points_extremely_close_to_a_node_are_treated_as_the_node() -> None:
    basis = LagrangeBasis(lobatto_control_nodes(6))
    for x in (5e-324, -5e-324, 1e-309):  # 1 / x overflows; inside and outside [0, 1]
        values, derivs = basis.values(x), basis.derivatives(x)
        np.testing.assert_array_equal(values[0], np.eye(7)[0])
        np.testing.assert_array_equal(derivs[0], basis.differentiation_matrix()[0])
    # 1e-300 is still evaluated by the formulas, and agrees with the node to rounding.
    np.testing.assert_allclose(basis.values(1e-300)[0], np.eye(7)[0], rtol=0, atol=1e-16)
    np.testing.assert_allclose(
        basis.derivatives(-1e-300)[0], basis.differentiation_matrix()[0], rtol=1e-15
    )


def test_linear_basis_closed_form() -> None:
    basis = LagrangeBasis([0.0, 1.0])
    x = np.array([-1e100, -1.0, 0.0, 0.25, 1.0, 3.0, 1e100])  # far extrapolation too
    np.testing.assert_array_equal(basis.values(x), np.stack([1 - x, x], axis=1))
    np.testing.assert_array_equal(basis.derivatives(x), np.tile([-1.0, 1.0], (x.size, 1)))
    assert basis.degree == 1


def test_shapes_scalars_and_empty_input() -> None:
    basis = LagrangeBasis(lobatto_control_nodes(3))
    assert basis.values(0.3).shape == (1, 4)
    assert basis.derivatives(np.float64(0.3)).shape == (1, 4)
    assert basis.values([0.1, 0.2, 0.3]).shape == (3, 4)
    assert basis.values(np.array([], dtype=float)).shape == (0, 4)
    assert basis.derivatives([]).shape == (0, 4)
    assert basis.differentiation_matrix().shape == (4, 4)
    np.testing.assert_array_equal(basis.values(0.3)[0], basis.values([0.3, 0.7])[0])


def test_basis_is_frozen_and_arrays_are_read_only() -> None:
    nodes = np.array([0.0, 0.4, 1.0])
    basis = LagrangeBasis(nodes)
    nodes[1] = 0.6  # the basis keeps its own copy
    assert basis.nodes[1] == 0.4
    with pytest.raises(dataclasses.FrozenInstanceError):
        basis.nodes = nodes  # type: ignore[misc]
    for array in (basis.nodes, basis.barycentric_weights):
        with pytest.raises(ValueError, match="read-only"):
            array[0] = 1.0
    dmat = basis.differentiation_matrix()
    dmat[0, 0] = 99.0  # a copy: the basis is unaffected
    assert basis.differentiation_matrix()[0, 0] != 99.0
    assert LagrangeBasis([0.0, 1.0]).nodes.dtype == np.float64


@pytest.mark.parametrize(
    ("nodes", "match"),
    [
        ([0.0, 0.5, 0.5, 1.0], "strictly increasing"),
        ([1.0, 0.0], "strictly increasing"),
        ([0.0, np.nan, 1.0], "finite"),
        ([0.0, np.inf], "finite"),
        ([0.5], "at least 2"),
        ([], "at least 2"),
        ([[0.0, 1.0]], "one-dimensional"),
        (0.5, "one-dimensional"),
        (np.linspace(0.0, 1.0, 1200), "overflow"),
    ],
)
def test_bad_nodes(nodes, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        LagrangeBasis(nodes)


@pytest.mark.parametrize(
    ("x", "match"),
    [([[0.1, 0.2]], "one-dimensional"), ([0.1, np.nan], "finite"), (np.inf, "finite")],
)
def test_bad_points(x, match: str) -> None:
    basis = LagrangeBasis([0.0, 0.5, 1.0])
    with pytest.raises(ValueError, match=match):
        basis.values(x)
    with pytest.raises(ValueError, match=match):
        basis.derivatives(x)


@pytest.mark.parametrize("degree", range(1, 16))
def test_control_node_families(degree: int) -> None:
    gll = lobatto_control_nodes(degree)
    assert gll is gauss_lobatto(degree + 1).nodes
    equi = equidistant_control_nodes(degree)
    assert equi[0] == 0.0 and equi[-1] == 1.0
    np.testing.assert_allclose(equi, np.linspace(0.0, 1.0, degree + 1), rtol=2.3e-16, atol=0)
    assert equi.tolist() == [float(v) for v in equidistant_control_nodes_mp(degree)]
    gll_mp = lobatto_control_nodes_mp(degree)
    assert gll_mp == gauss_lobatto_mp(degree + 1)[0]
    # The float rule rounds the upper half and reflects it, so the lower half may differ from
    # a direct rounding by one ulp (measured: at most 5.6e-17).
    assert np.abs(gll - np.array([float(v) for v in gll_mp])).max() <= 1.2e-16


@pytest.mark.parametrize(
    "func",
    [
        lobatto_control_nodes,
        equidistant_control_nodes,
        lobatto_control_nodes_mp,
        equidistant_control_nodes_mp,
    ],
)
def test_bad_degree(func) -> None:
    with pytest.raises(ValueError, match="degree must be >= 1, got 0"):
        func(0)
    for bad in (2.0, True, "3"):
        with pytest.raises(TypeError, match="degree must be an int"):
            func(bad)


@pytest.mark.parametrize(
    ("kind", "degree"), [(k, s) for k, s in NODE_SETS if s in (1, 2, 3, 5, 8, 13, 30)]
)
def test_lagrange_tables_match_float_barycentric(kind: str, degree: int) -> None:
    nodes = control_nodes(kind, degree)
    basis = LagrangeBasis(nodes)
    points = np.concatenate(
        [gauss_legendre(degree).nodes, gauss_legendre(degree + 3).nodes, 1.0 + nodes]
    )
    # Same float64 inputs (converted exactly), so only evaluation error differs:
    # measured max 9.2e-16 (values) and 1.0e-15 (derivatives), row-relative.
    phi, der = lagrange_tables(list(nodes), list(points))
    assert phi.shape == der.shape == (points.size, degree + 1)
    assert phi.dtype == der.dtype == np.float64
    assert row_relative_error(phi, basis.values(points)) <= 1e-14
    assert row_relative_error(der, basis.derivatives(points)) <= 1e-14


@pytest.mark.parametrize("degree", [1, 2, 3, 5, 8, 13, 30])
def test_lagrange_tables_in_extended_precision(degree: int) -> None:
    nodes_mp = lobatto_control_nodes_mp(degree)
    gauss_mp = gauss_legendre_mp(degree)[0]
    phi, der = lagrange_tables(nodes_mp, gauss_mp)
    # Each entry is the 40-digit value rounded once; compared with a 50-digit product-form
    # evaluation at the same mpmath inputs: measured difference 0 (every entry is the
    # correctly rounded value); one ulp is allowed for double rounding.
    for i, c in enumerate(gauss_mp):
        values, derivs = reference(nodes_mp, c)
        np.testing.assert_allclose(phi[i], values, rtol=2.3e-16)
        np.testing.assert_allclose(der[i], derivs, rtol=2.3e-16)
    # Rows sum to 1 and 0 up to the final rounding (measured 2.6e-16 and 9.4e-17 relative).
    assert np.all(np.abs(phi.sum(axis=1) - 1) <= 1e-15 * np.abs(phi).sum(axis=1))
    assert np.all(np.abs(der.sum(axis=1)) <= 1e-15 * np.abs(der).sum(axis=1))


@pytest.mark.parametrize("degree", [1, 2, 4, 7, 16])
def test_lagrange_tables_collocated_is_exact_identity(degree: int) -> None:
    nodes_mp = lobatto_control_nodes_mp(degree)
    phi, der = lagrange_tables(nodes_mp, gauss_lobatto_mp(degree + 1)[0])
    np.testing.assert_array_equal(phi, np.eye(degree + 1))
    dmat = LagrangeBasis(lobatto_control_nodes(degree)).differentiation_matrix()
    # The float basis sees nodes rounded to float64, which moves D: measured max 4.0e-15.
    assert row_relative_error(der, dmat) <= 2e-14


def test_lagrange_tables_small_exact_cases() -> None:
    phi, der = lagrange_tables([0, 0.5, 1], [0.25, "0.75", mpmath.mpf(0.5)])
    np.testing.assert_array_equal(phi, [[0.375, 0.75, -0.125], [-0.125, 0.75, 0.375], [0, 1, 0]])
    np.testing.assert_array_equal(der, [[-2, 2, 0], [0, -2, 2], [-1, 0, 1]])
    phi, der = lagrange_tables([0.0, 1.0], [2.0, -1.0], dps=20)
    np.testing.assert_array_equal(phi, [[-1, 2], [2, -1]])
    np.testing.assert_array_equal(der, [[-1, 1], [-1, 1]])


def test_lagrange_tables_does_not_change_global_precision() -> None:
    before = mpmath.mp.prec
    lagrange_tables([0, 1], [0.5], dps=60)
    assert mpmath.mp.prec == before


@pytest.mark.parametrize(
    ("nodes", "points", "match"),
    [
        ([0, 0.5, 0.5, 1], [0.2], "strictly increasing"),
        ([1, 0], [0.2], "strictly increasing"),
        ([0.5], [0.2], "at least 2"),
        ([0, mpmath.inf], [0.2], "finite"),
        ([0, 1], [mpmath.nan], "finite"),
    ],
)
def test_lagrange_tables_bad_input(nodes, points, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        lagrange_tables(nodes, points)


def test_lagrange_tables_bad_dps() -> None:
    with pytest.raises(TypeError, match="dps must be an int"):
        lagrange_tables([0, 1], [0.5], dps=40.0)
    with pytest.raises(ValueError, match="dps must be >= 1"):
        lagrange_tables([0, 1], [0.5], dps=0)


@st.composite
def node_sets(draw) -> np.ndarray:
    """2..9 strictly increasing nodes in [-2, 3] with gaps of at least 0.05."""
    gaps = draw(st.lists(st.floats(0.05, 1.0), min_size=1, max_size=8))
    start = draw(st.floats(-2.0, 0.0))
    return start + np.concatenate([[0.0], np.cumsum(gaps)])


@settings(max_examples=50, deadline=None)
@given(nodes=node_sets(), data=st.data())
def test_random_nodes_properties(nodes: np.ndarray, data) -> None:
    basis = LagrangeBasis(nodes)
    s = basis.degree
    np.testing.assert_array_equal(basis.values(nodes), np.eye(s + 1))
    x = np.array(
        data.draw(st.lists(st.floats(nodes[0], nodes[-1]), min_size=1, max_size=10)), dtype=float
    )
    values, derivs = basis.values(x), basis.derivatives(x)
    assert np.all(np.isfinite(values)) and np.all(np.isfinite(derivs))
    # Relative to sum |.| (these node sets can be badly spaced); over 3000 random node sets
    # the measured max is 4.4e-16 for the values and 1.5e-15 for the derivatives.
    assert np.all(np.abs(values.sum(axis=1) - 1) <= 1e-14 * np.abs(values).sum(axis=1))
    assert np.all(np.abs(derivs.sum(axis=1)) <= 1e-13 * (1 + np.abs(derivs).sum(axis=1)))
    # Reproduces a random polynomial of degree s (a Chebyshev series on the node interval, so
    # that NumPy evaluates it accurately); tolerance scaled by 1 + sum |ell_nu| |p(d_nu)|,
    # measured max 8.5e-15 (values) and 9.8e-15 (derivatives) over 3000 random node sets.
    coef = np.array(data.draw(st.lists(st.floats(-1, 1), min_size=s + 1, max_size=s + 1)))
    p = np.polynomial.Chebyshev(coef, domain=[nodes[0], nodes[-1]])
    fd = p(nodes)
    assert np.all(np.abs(values @ fd - p(x)) <= 1e-13 * (1 + np.abs(values) @ np.abs(fd)))
    dp = p.deriv()(x)
    assert np.all(np.abs(derivs @ fd - dp) <= 1e-13 * (1 + np.abs(derivs) @ np.abs(fd)))
