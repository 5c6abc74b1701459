"""Galerkin: predicted order, input checks, warnings and the numeric tables."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

import galerkin_vi as gvi

RULES = {"lobatto": gvi.gauss_lobatto, "legendre": gvi.gauss_legendre}


def _quadrature_order(family: str, m: int) -> int:
    # theory.md §1: Gauss m points has order 2m, Lobatto m points 2m - 2
    return 2 * m if family == "legendre" else 2 * m - 2


def _grid():
    for s in range(1, 7):
        for family in RULES:
            for m in range(max(s, 2 if family == "lobatto" else 1), s + 4):
                yield s, family, m


@pytest.mark.parametrize(("s", "family", "m"), list(_grid()))
def test_order_is_min_of_2s_and_quadrature_order(s, family, m):
    u = _quadrature_order(family, m)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.OrderReductionWarning)
        method = gvi.Galerkin(s, RULES[family](m))
    assert method.order == min(2 * s, u)
    assert method.degree == s


@pytest.mark.parametrize("s", range(1, 8))
def test_default_quadrature_is_collocated_lobatto(s):
    method = gvi.Galerkin(s)
    assert method.quadrature == gvi.gauss_lobatto(s + 1)
    assert method.nodes == "lobatto"
    assert method.order == 2 * s
    assert method.collocated


@pytest.mark.parametrize(
    "method",
    [
        lambda: gvi.Galerkin(2, gvi.gauss_legendre(2)),
        lambda: gvi.Galerkin(2, gvi.gauss_lobatto(4)),
        lambda: gvi.Galerkin(2, nodes="equidistant"),
    ],
)
def test_not_collocated(method):
    assert not method().collocated


@pytest.mark.parametrize(
    ("s", "quadrature"),
    [
        (2, gvi.gauss_legendre(1)),
        (3, gvi.gauss_legendre(2)),
        (3, gvi.gauss_lobatto(2)),
        (5, gvi.gauss_lobatto(4)),
        (6, gvi.gauss_legendre(5)),
    ],
)
def test_fewer_than_s_points_is_rejected(s, quadrature):
    with pytest.raises(ValueError, match=f"fewer than degree={s}"):
        gvi.Galerkin(s, quadrature)


@pytest.mark.parametrize(("s", "m"), [(2, 2), (3, 3), (4, 4), (6, 6)])
def test_lobatto_with_s_points_warns_order_reduction(s, m):
    # Lobatto s points: order 2s - 2 < 2s
    with pytest.warns(gvi.OrderReductionWarning, match=f"order {2 * s - 2} < 2\\*degree"):
        method = gvi.Galerkin(s, gvi.gauss_lobatto(m))
    assert method.order == 2 * s - 2


@pytest.mark.parametrize(
    "make",
    [
        lambda: gvi.Galerkin(3),
        lambda: gvi.Galerkin(3, gvi.gauss_legendre(3)),
        lambda: gvi.Galerkin(3, gvi.gauss_lobatto(5)),
        lambda: gvi.Galerkin(1, gvi.gauss_legendre(1)),
        lambda: gvi.Galerkin(6, nodes="equidistant"),
        lambda: gvi.Galerkin(12),
    ],
)
def test_no_warning_for_full_order_choices(make):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        make()


@pytest.mark.parametrize("s", [7, 8, 10])
def test_equidistant_above_6_warns_conditioning(s):
    with pytest.warns(gvi.ConditioningWarning, match=f"degree {s} > 6"):
        gvi.Galerkin(s, nodes="equidistant")


@pytest.mark.parametrize(
    ("args", "kwargs", "error", "match"),
    [
        (("2",), {}, TypeError, "degree must be an int, got str"),
        ((2.0,), {}, TypeError, "degree must be an int, got float"),
        ((True,), {}, TypeError, "degree must be an int, got bool"),
        ((None,), {}, TypeError, "degree must be an int"),
        ((0,), {}, ValueError, "degree must be >= 1, got 0"),
        ((-2,), {}, ValueError, "degree must be >= 1"),
        ((2, "lobatto"), {}, TypeError, "quadrature must be a QuadratureRule"),
        ((2, 3), {}, TypeError, "quadrature must be a QuadratureRule"),
        ((2,), {"nodes": "chebyshev"}, ValueError, "nodes must be one of"),
        ((2,), {"nodes": None}, ValueError, "nodes must be one of"),
    ],
)
def test_bad_arguments(args, kwargs, error, match):
    with pytest.raises(error, match=match):
        gvi.Galerkin(*args, **kwargs)


def test_numpy_integer_degree_is_accepted():
    assert gvi.Galerkin(np.int64(3)).order == 6


def test_equality_and_hash():
    a = gvi.Galerkin(3, gvi.gauss_legendre(3))
    b = gvi.Galerkin(3, gvi.gauss_legendre(3))
    assert a == b
    assert hash(a) == hash(b)
    assert a != gvi.Galerkin(3)
    assert a != gvi.Galerkin(3, gvi.gauss_legendre(3), nodes="equidistant")


# ------------------------------------------------------------------ tables
def _methods():
    out = []
    for s in range(1, 7):
        out.append(gvi.Galerkin(s))
        out.append(gvi.Galerkin(s, gvi.gauss_legendre(s)))
        out.append(gvi.Galerkin(s, gvi.gauss_legendre(s + 1), nodes="equidistant"))
        out.append(gvi.Galerkin(s, gvi.gauss_lobatto(s + 3)))
    return out


METHODS = _methods()


@pytest.mark.parametrize("method", METHODS, ids=repr)
def test_table_shapes_and_nodes(method):
    tb = method.tables
    s, r = method.degree, method.quadrature.npoints
    assert tb.Phi.shape == tb.D.shape == (r, s + 1)
    assert tb.extrapolation.shape == (s + 1, s + 1)
    assert tb.d[0] == 0.0 and tb.d[-1] == 1.0
    assert np.all(np.diff(tb.d) > 0)
    # the tables round the 40-digit values once; the rule reflects its upper half, so the two
    # may differ by one ulp (measured max 5.6e-17)
    np.testing.assert_allclose(tb.c, method.quadrature.nodes, rtol=0, atol=2e-16)
    np.testing.assert_allclose(tb.b, method.quadrature.weights, rtol=0, atol=2e-16)
    if method.nodes == "equidistant":
        np.testing.assert_array_equal(tb.d, np.arange(s + 1) / s)  # correctly rounded j/s


@pytest.mark.parametrize("method", METHODS, ids=repr)
def test_partition_of_unity(method):
    tb = method.tables
    # sum_nu l_nu = 1 and sum_nu l'_nu = 0 (theory.md §1)
    np.testing.assert_allclose(tb.Phi.sum(axis=1), 1.0, rtol=0, atol=1e-15)  # max 2.2e-16
    np.testing.assert_allclose(tb.D.sum(axis=1), 0.0, rtol=0, atol=1e-14)  # max 1.8e-15


@pytest.mark.parametrize("s", range(1, 8))
def test_collocated_default_has_identity_phi(s):
    tb = gvi.Galerkin(s).tables
    np.testing.assert_array_equal(tb.Phi, np.eye(s + 1))  # exact, not just close
    np.testing.assert_array_equal(tb.d, tb.c)


def _random_polynomials(s: int):
    rng = np.random.default_rng(100 + s)
    for degree in range(s + 1):
        yield np.polynomial.Polynomial(rng.normal(size=degree + 1))


@pytest.mark.parametrize("method", METHODS, ids=repr)
def test_tables_reproduce_polynomials_of_degree_s(method):
    tb = method.tables
    for p in _random_polynomials(method.degree):
        # Phi interpolates, D differentiates the interpolant at the quadrature nodes
        np.testing.assert_allclose(tb.Phi @ p(tb.d), p(tb.c), rtol=0, atol=1e-14)  # 6.7e-16
        np.testing.assert_allclose(
            tb.D @ p(tb.d), p.deriv()(tb.c), rtol=0, atol=1e-13
        )  # max 1.2e-14 (s = 6 equidistant)


@pytest.mark.parametrize("method", METHODS, ids=repr)
def test_extrapolation_reproduces_polynomials_of_degree_s(method):
    tb = method.tables
    E = tb.extrapolation
    # E[nu, mu] = l_mu(1 + d_nu): values at the next step's control nodes
    scale = np.abs(E).sum(axis=1).max()  # Lebesgue-type growth of extrapolation
    for p in _random_polynomials(method.degree):
        err = np.abs(E @ p(tb.d) - p(1 + tb.d)).max()
        assert err <= 1e-14 * scale * max(1.0, np.abs(p(tb.d)).max())  # s=6: 3.8e-12, scale ~1e3


@pytest.mark.parametrize("method", METHODS, ids=repr)
def test_extrapolation_first_row_is_exactly_the_endpoint(method):
    # the time loop relies on E[0] = e_s exactly: the new step starts at the old end point
    E = method.tables.extrapolation
    expected = np.zeros(method.degree + 1)
    expected[-1] = 1.0
    np.testing.assert_array_equal(E[0], expected)


def test_extrapolation_is_not_a_polynomial_of_higher_degree():
    # the check above is not vacuous: a degree s + 1 polynomial is not reproduced
    tb = gvi.Galerkin(3).tables
    p = np.polynomial.Polynomial([0, 0, 0, 0, 1.0])
    assert np.abs(tb.extrapolation @ p(tb.d) - p(1 + tb.d)).max() > 1e-2


def test_tables_are_the_same_for_equal_methods():
    a = gvi.Galerkin(4, gvi.gauss_legendre(4)).tables
    b = gvi.Galerkin(4, gvi.gauss_legendre(4)).tables
    for name in ("b", "c", "d", "Phi", "D", "extrapolation"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name))
