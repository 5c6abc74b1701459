r"""Tests for galerkin_vi.method.quadrature.

Reference values come from an independent 50-digit mpmath computation: roots of mpmath's
hypergeometric ``legendre`` found with ``findroot`` (secant) from NumPy/SciPy starting guesses,
Gauss weights from :math:`b = (1 - x^2)/(m P_{m-1}(x))^2` (not the :math:`P_m'` formula of the
implementation) and Lobatto weights from the moment equations
:math:`\sum_i b_i P_k(x_i) = \delta_{k0}`, :math:`k < m` (no closed formula) for
:math:`m \le 32`, beyond that from :math:`b = 1/(N(N+1)P_N(x)^2)` with mpmath's ``legendre``.
"""

from __future__ import annotations

import dataclasses
import functools
import math
import time

import mpmath
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from numpy.polynomial.legendre import leggauss
from scipy.special import roots_jacobi

from galerkin_vi.method.quadrature import (
    QuadratureRule,
    gauss_legendre,
    gauss_legendre_mp,
    gauss_lobatto,
    gauss_lobatto_mp,
)

REF_DPS = 50
# Sizes checked against the slow independent reference (about 1.5 s for all of them).
REF_SIZES = [1, 2, 3, 4, 5, 6, 7, 8, 11, 16, 23, 32, 47, 64]

FAMILIES = {
    "gauss_legendre": (gauss_legendre, gauss_legendre_mp, 1),
    "gauss_lobatto": (gauss_lobatto, gauss_lobatto_mp, 2),
}
# Building every rule up to 64 points takes about 4 s, so the float checks use every size up to
# 24 and a spread of larger ones, including the largest (64) and both parities.
FLOAT_SIZES = [*range(1, 25), 31, 32, 33, 47, 63, 64]
ALL_RULES = [(family, m) for family, (_, _, lo) in FAMILIES.items() for m in FLOAT_SIZES if m >= lo]
REF_CASES = [(family, m) for family, (_, _, lo) in FAMILIES.items() for m in REF_SIZES if m >= lo]


def _polish(f, guess: float) -> mpmath.mpf:
    return mpmath.findroot(f, mpmath.mpf(guess))


@functools.cache
def reference_rule(family: str, m: int) -> tuple[tuple[mpmath.mpf, ...], tuple[mpmath.mpf, ...]]:
    """Nodes and weights on [0, 1] at 50 digits, independent of the implementation."""
    with mpmath.workdps(REF_DPS):
        if family == "gauss_legendre":
            guesses, _ = leggauss(m)
            xs = [_polish(lambda t: mpmath.legendre(m, t), g) for g in guesses]
            weights = [(1 - x**2) / (m * mpmath.legendre(m - 1, x)) ** 2 for x in xs]
        else:
            n = m - 1
            guesses = roots_jacobi(m - 2, 1, 1)[0] if m > 2 else []
            interior = [
                _polish(lambda t: t * mpmath.legendre(n, t) - mpmath.legendre(n - 1, t), g)
                for g in guesses
            ]
            xs = [mpmath.mpf(-1), *interior, mpmath.mpf(1)]
            if m <= 32:
                moments = mpmath.matrix([[mpmath.legendre(k, x) for x in xs] for k in range(m)])
                weights = list(mpmath.lu_solve(moments, mpmath.matrix([1] + [0] * (m - 1))))
            else:  # the 50-digit LU solve would take about 1 s per size here
                weights = [1 / (n * (n + 1) * mpmath.legendre(n, x) ** 2) for x in xs]
        nodes = [(1 + x) / 2 for x in xs]
    assert all(a < b for a, b in zip(nodes, nodes[1:], strict=False))  # distinct roots found
    return tuple(nodes), tuple(weights)


def error_constant(family: str, m: int) -> mpmath.mpf:
    r"""Exact :math:`\int_0^1 x^{u} - \sum_i b_i c_i^{u}` for :math:`u` = degree + 1.

    Abramowitz & Stegun 25.4.30 / 25.4.32 mapped to [0, 1] with :math:`f^{(u)} = u!`.
    """
    f = mpmath.factorial
    if family == "gauss_legendre":
        return f(m) ** 4 / ((2 * m + 1) * f(2 * m) ** 2)
    return -m * (m - 1) ** 3 * f(m - 2) ** 4 / ((2 * m - 1) * f(2 * m - 2) ** 2)


@pytest.mark.parametrize(("family", "m"), REF_CASES)
def test_float_rule_matches_independent_reference(family: str, m: int) -> None:
    rule = FAMILIES[family][0](m)
    ref_nodes, ref_weights = reference_rule(family, m)
    with mpmath.workdps(REF_DPS):
        node_err = max(abs(mpmath.mpf(c) - r) for c, r in zip(rule.nodes, ref_nodes, strict=True))
        weight_rel = max(
            abs((mpmath.mpf(b) - r) / r) for b, r in zip(rule.weights, ref_weights, strict=True)
        )
    # Rounded once from 40 digits: max over all m <= 64 measured 5.55e-17 (half an ulp of 1/2..1)
    # for the nodes and 1.09e-16 relative for the weights; the brief allows 2e-15 / 1e-14.
    assert node_err <= 1.2e-16
    assert weight_rel <= 2.3e-16


@pytest.mark.parametrize(("family", "m"), REF_CASES)
def test_upper_half_is_correctly_rounded(family: str, m: int) -> None:
    rule = FAMILIES[family][0](m)
    ref_nodes, ref_weights = reference_rule(family, m)
    upper = slice(m // 2, None)  # c >= 1/2: rounded; the lower half is the exact reflection
    assert rule.nodes[upper].tolist() == [float(c) for c in ref_nodes[upper]]
    assert rule.weights[upper].tolist() == [float(b) for b in ref_weights[upper]]


@pytest.mark.parametrize(("family", "m"), REF_CASES)
def test_mp_rule_matches_independent_reference(family: str, m: int) -> None:
    nodes, weights = FAMILIES[family][1](m)
    ref_nodes, ref_weights = reference_rule(family, m)
    with mpmath.workdps(REF_DPS):
        node_err = max(abs(c - r) for c, r in zip(nodes, ref_nodes, strict=True))
        weight_rel = max(abs((b - r) / r) for b, r in zip(weights, ref_weights, strict=True))
    # 40 digits requested: measured max 1.1e-41 (nodes and relative weights, m <= 64).
    assert node_err <= 1e-39
    assert weight_rel <= 1e-39


@pytest.mark.parametrize(("family", "m"), [(f, m) for f, m in ALL_RULES if m <= 20])
def test_exactness_is_sharp_in_extended_precision(family: str, m: int) -> None:
    rule = FAMILIES[family][0](m)
    nodes, weights = FAMILIES[family][1](m)
    with mpmath.workdps(40):
        errors = [
            mpmath.mpf(1) / (k + 1)
            - mpmath.fsum(b * c**k for b, c in zip(weights, nodes, strict=True))
            for k in range(rule.degree + 2)
        ]
        # Exact up to the degree: measured max 5.7e-42 at 40 digits (m <= 20).
        assert max(abs(e) for e in errors[:-1]) <= 1e-39
        # ... and not one degree more: the error is the classical constant (measured relative
        # deviation 5.5e-19; the smallest such error, m = 20 Gauss, is 1.3e-24).
        assert abs(errors[-1] / error_constant(family, m) - 1) <= 1e-15


@pytest.mark.parametrize(("family", "m"), ALL_RULES)
def test_float_rule_integrates_monomials(family: str, m: int) -> None:
    rule = FAMILIES[family][0](m)
    k = np.arange(rule.degree + 1)
    moments = rule.nodes[:, None] ** k[None, :]
    errors = rule.weights @ moments - 1.0 / (k + 1)
    # Measured max 2.2e-16 over all k <= degree and all m <= 64 (brief: ~1e-14).
    assert np.max(np.abs(errors)) <= 1e-15


@pytest.mark.parametrize(("family", "m"), ALL_RULES)
def test_weights_positive_and_sum_to_one(family: str, m: int) -> None:
    rule = FAMILIES[family][0](m)
    assert np.all(rule.weights > 0)
    # Measured max 2.2e-16 (all m <= 64).
    assert abs(math.fsum(rule.weights) - 1.0) <= 4.5e-16


@pytest.mark.parametrize(("family", "m"), ALL_RULES)
def test_exact_symmetry_and_ordering(family: str, m: int) -> None:
    rule = FAMILIES[family][0](m)
    c, b = rule.nodes, rule.weights
    assert c.shape == b.shape == (m,)
    assert c.dtype == b.dtype == np.float64
    assert np.all(np.diff(c) > 0)
    np.testing.assert_array_equal(c[::-1], 1.0 - c)
    np.testing.assert_array_equal(b[::-1], b)
    if m % 2:
        assert c[m // 2] == 0.5
    if family == "gauss_legendre":
        assert 0.0 < c[0] and c[-1] < 1.0
    else:
        assert c[0] == 0.0 and c[-1] == 1.0
        assert b[0] == b[-1] == 1.0 / ((m - 1) * m)


@pytest.mark.parametrize(("family", "m"), [(f, m) for f, m in ALL_RULES if m in (2, 5, 20)])
def test_mp_rule_is_exactly_symmetric(family: str, m: int) -> None:
    nodes, weights = FAMILIES[family][1](m, dps=30)
    with mpmath.workdps(30):
        assert [1 - c for c in reversed(nodes)] == nodes
    assert list(reversed(weights)) == weights
    if family == "gauss_lobatto":
        assert nodes[0] == 0 and nodes[-1] == 1


def test_small_rules_closed_form() -> None:
    r3 = math.sqrt(3.0)
    np.testing.assert_allclose(gauss_legendre(2).nodes, [(3 - r3) / 6, (3 + r3) / 6], rtol=3e-16)
    np.testing.assert_array_equal(gauss_legendre(2).weights, [0.5, 0.5])
    np.testing.assert_array_equal(gauss_lobatto(2).nodes, [0.0, 1.0])
    np.testing.assert_array_equal(gauss_lobatto(2).weights, [0.5, 0.5])
    np.testing.assert_array_equal(gauss_lobatto(3).weights, [1 / 6, 2 / 3, 1 / 6])
    r5 = math.sqrt(5.0)
    np.testing.assert_allclose(gauss_lobatto(4).nodes, [0, (5 - r5) / 10, (5 + r5) / 10, 1])


def test_rule_attributes_equality_and_repr() -> None:
    rule = gauss_lobatto(4)
    assert (rule.family, rule.npoints, rule.degree, rule.order) == ("gauss_lobatto", 4, 5, 6)
    g = gauss_legendre(3)
    assert (g.family, g.npoints, g.degree, g.order) == ("gauss_legendre", 3, 5, 6)
    assert repr(rule) == "gauss_lobatto(4)"
    assert repr(g) == "gauss_legendre(3)"
    assert rule == QuadratureRule("gauss_lobatto", rule.nodes, rule.weights, 5)
    assert hash(rule) == hash(QuadratureRule("gauss_lobatto", rule.nodes, rule.weights, 5))
    assert rule != gauss_lobatto(5)
    assert rule != gauss_legendre(4)
    assert rule != "gauss_lobatto(4)"
    assert len({gauss_legendre(3), gauss_legendre(3), gauss_lobatto(3)}) == 2


def test_rules_are_memoised_and_immutable() -> None:
    rule = gauss_legendre(7)
    assert gauss_legendre(7) is rule
    assert gauss_legendre(np.int64(7)) is rule
    assert gauss_lobatto(7) is gauss_lobatto(7)
    with pytest.raises(ValueError, match="read-only"):
        rule.nodes[0] = 0.0
    with pytest.raises(ValueError, match="read-only"):
        rule.weights[0] = 0.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        rule.degree = 3  # type: ignore[misc]


def test_constructor_copies_its_input() -> None:
    nodes = np.array([0.0, 1.0])
    rule = QuadratureRule("gauss_lobatto", nodes, [0.5, 0.5], 1)
    nodes[0] = 0.25
    assert rule.nodes[0] == 0.0


@pytest.mark.parametrize(
    ("args", "match"),
    [
        (("simpson", [0.0, 0.5, 1.0], [1 / 6, 2 / 3, 1 / 6], 3), "family"),
        (("gauss_legendre", [0.5], [1.0], 2), "degree 1"),
        (("gauss_lobatto", [0.5], [1.0], -1), "at least 2"),
        (("gauss_legendre", [0.2, 0.8], [1.0], 3), "same length"),
        (("gauss_legendre", [[0.5]], [[1.0]], 1), "one-dimensional"),
        (("gauss_legendre", [0.8, 0.2], [0.5, 0.5], 3), "increasing"),
        (("gauss_legendre", [-0.1, 0.8], [0.5, 0.5], 3), r"\[0, 1\]"),
        (("gauss_legendre", [0.2, 0.8], [0.5, 0.6], 3), "sum to 1"),
        (("gauss_legendre", [np.nan, 0.8], [0.5, 0.5], 3), "finite"),
    ],
)
def test_constructor_validation(args: tuple, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        QuadratureRule(*args)


def test_constructor_degree_type() -> None:
    with pytest.raises(TypeError, match="degree must be an int"):
        QuadratureRule("gauss_legendre", [0.5], [1.0], 1.0)
    assert type(QuadratureRule("gauss_legendre", [0.5], [1.0], np.int64(1)).degree) is int


@pytest.mark.parametrize(
    "func", [gauss_legendre, gauss_lobatto, gauss_legendre_mp, gauss_lobatto_mp]
)
@pytest.mark.parametrize("bad", [2.0, "3", True, False, None, np.bool_(True), 3 + 0j])
def test_non_integer_m_is_a_type_error(func, bad) -> None:
    with pytest.raises(TypeError, match="m must be an int"):
        func(bad)


@pytest.mark.parametrize(
    ("func", "minimum"),
    [(gauss_legendre, 1), (gauss_legendre_mp, 1), (gauss_lobatto, 2), (gauss_lobatto_mp, 2)],
)
def test_too_small_m_is_a_value_error(func, minimum: int) -> None:
    for bad in (minimum - 1, -5):
        with pytest.raises(ValueError, match=rf"m must be >= {minimum}, got {bad}"):
            func(bad)


@pytest.mark.parametrize("func", [gauss_legendre_mp, gauss_lobatto_mp])
def test_bad_dps(func) -> None:
    with pytest.raises(TypeError, match="dps must be an int"):
        func(3, dps=40.0)
    with pytest.raises(ValueError, match="dps must be >= 1"):
        func(3, dps=0)


@pytest.mark.parametrize("func", [gauss_legendre_mp, gauss_lobatto_mp])
def test_mp_results_are_fresh_lists_of_mpf(func) -> None:
    nodes, weights = func(6, dps=25)
    assert isinstance(nodes, list) and isinstance(weights, list)
    assert all(isinstance(v, mpmath.mpf) for v in nodes + weights)
    nodes[0] = None
    weights.clear()
    again_nodes, again_weights = func(6, dps=25)
    assert again_nodes[0] is not None and len(again_weights) == 6


@pytest.mark.parametrize("dps", [20, 60])
def test_mp_rule_has_the_requested_precision(dps: int) -> None:
    nodes, _ = gauss_legendre_mp(5, dps)
    with mpmath.workdps(dps + 20):
        ref = sorted((1 + x) / 2 for x in mpmath.polyroots([63, 0, -70, 0, 15, 0], maxsteps=200))
        err = max(abs(c - r) for c, r in zip(nodes, ref, strict=True))
    # The value carries dps digits (plus the rounding of the last one).
    assert err <= mpmath.mpf(10) ** (-dps)


@pytest.mark.parametrize("func", [gauss_legendre_mp, gauss_lobatto_mp])
def test_m64_is_fast_from_a_cold_cache(func) -> None:
    start = time.perf_counter()
    func(64, dps=37)  # a precision nothing else uses, so the cache is cold
    # Measured 0.05-0.07 s (pure-Python mpmath backend); the brief asks for well under 1 s.
    assert time.perf_counter() - start < 1.0


@settings(max_examples=50, deadline=None)
@given(
    family=st.sampled_from(sorted(FAMILIES)),
    m=st.sampled_from([m for m in FLOAT_SIZES if m >= 2]),
    data=st.data(),
)
def test_random_polynomials_of_the_exactness_degree(family: str, m: int, data) -> None:
    rule = FAMILIES[family][0](m)
    coef = data.draw(
        st.lists(
            st.floats(min_value=-1, max_value=1), min_size=rule.degree + 1, max_size=rule.degree + 1
        )
    )
    # Shifted Legendre series: bounded by sum |coef| on [0, 1] and integrates to coef[0].
    p = np.polynomial.Legendre(coef, domain=[0.0, 1.0])
    approx = rule.weights @ p(rule.nodes)
    # Measured max 6.9e-17 relative to 1 + sum |coef| (20 random series per rule).
    assert abs(approx - coef[0]) <= 1e-15 * (1 + np.sum(np.abs(coef)))
