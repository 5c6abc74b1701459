"""Repeated terms evaluated side by side, square roots and divisions four at a time
(galerkin_vi.loops.vector_math, galerkin_vi.codegen.lanes).

Every result must be the one-instance-at-a-time code's bit for bit: the vector
square root and quotient are IEEE operations, and the lifting keeps each
operation's operands.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st
from numba import njit

import galerkin_vi as gvi
from galerkin_vi import codegen
from galerkin_vi.codegen import source
from galerkin_vi.codegen.lanes import LANES, lane_lines, lifted_statements
from galerkin_vi.codegen.scatter import ScatterGroup
from galerkin_vi.loops.vector_math import divide4, sqrt4
from galerkin_vi.problems.gravitation import n_body

from .test_build_structure import gravity, lattice

SPECIAL = [0.0, -0.0, 1.0, -1.0, 2.0, 0.1, 5e-324, 2.2e-308, 1.7976931348623157e308]
SPECIAL += [math.inf, -math.inf, math.nan, 3.0, 1e-300, -7.5, 4.0]
DOUBLES = st.floats(allow_nan=True, allow_infinity=True, allow_subnormal=True)


@njit(error_model="numpy")
def _lanes(x, y):
    out = np.empty((2, 4))
    out[0, 0], out[0, 1], out[0, 2], out[0, 3] = sqrt4(x[0], x[1], x[2], x[3])
    out[1, 0], out[1, 1], out[1, 2], out[1, 3] = divide4(
        x[0], x[1], x[2], x[3], y[0], y[1], y[2], y[3]
    )
    return out


@njit(error_model="numpy")
def _scalars(x, y):
    out = np.empty((2, 4))
    for k in range(4):
        out[0, k] = math.sqrt(x[k])
        out[1, k] = x[k] / y[k]
    return out


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    """Equal bit patterns, any NaN equal to any NaN."""
    a, b = np.asarray(a, dtype=np.float64), np.asarray(b, dtype=np.float64)
    nan = np.isnan(a)
    return bool(
        np.array_equal(nan, np.isnan(b))
        and np.array_equal(a[~nan].view(np.int64), b[~nan].view(np.int64))
    )


def _python(x, y) -> np.ndarray:
    return np.array([sqrt4(*x), divide4(*x, *y)])


def test_lanes_are_the_scalar_operations_on_special_values():
    values = np.array(SPECIAL)
    for x in values.reshape(-1, 4):
        for y in (values[:4], values[4:8], values[8:12], values[12:16]):
            assert _same(_lanes(x, y), _scalars(x, y))
            assert _same(_python(x, y), _scalars(x, y))


@settings(max_examples=300, deadline=None)
@given(st.lists(DOUBLES, min_size=4, max_size=4), st.lists(DOUBLES, min_size=4, max_size=4))
def test_lanes_are_the_scalar_operations_bit_for_bit(x, y):
    x, y = np.array(x), np.array(y)
    assert _same(_lanes(x, y), _scalars(x, y))
    assert _same(_python(x, y), _scalars(x, y))


def test_lanes_take_integers_and_refuse_what_is_not_a_number():
    @njit
    def integers():
        return sqrt4(4, 9, 2, 1), divide4(1, 2, 3, 4, 2, 2, 2, 2)

    roots, quotients = integers()
    assert roots == (2.0, 3.0, math.sqrt(2.0), 1.0)
    assert quotients == (0.5, 1.0, 1.5, 2.0)

    @njit
    def strings():
        return sqrt4("a", 1.0, 1.0, 1.0)

    with pytest.raises(Exception, match="float64, integers or booleans"):
        strings()

    @njit
    def singles(x):
        return sqrt4(x, x, x, x)

    with pytest.raises(Exception, match="float64, integers or booleans"):
        singles(np.float32(2.0))


# ------------------------------------------------------------------- the lifting
def test_each_square_root_and_division_becomes_a_statement_of_its_own():
    statements = lifted_statements(
        [("a", "x/(y*math.sqrt(y))"), ("b", "math.sqrt(y) + (1/2)*x"), ("c", "x - y")], "_l"
    )
    kinds = [(s.target, s.kind, s.operands) for s in statements]
    # the root of y is computed once; the whole of a is its division; 1/2 stays
    assert kinds == [
        ("_l0", "sqrt", ("y",)),
        ("a", "divide", ("x", "y * _l0")),
        ("b", "scalar", ("_l0 + 1 / 2 * x",)),
        ("c", "scalar", ("x - y",)),
    ]
    polynomial = lifted_statements([("c", "x - y"), ("d", "(1/2)*x**2")], "_l")
    assert all(s.kind == "scalar" for s in polynomial)


@pytest.mark.parametrize(
    "expression, kinds",
    [
        ("a/b/c", ["divide", "divide"]),  # (a/b)/c: the inner quotient first
        ("-a/b", ["divide"]),  # (-a)/b
        ("2/a + a**(-1)", ["divide", "scalar"]),
        ("math.sqrt(a*a/(b*b))/math.sqrt(a*a/(b*b))", ["divide", "sqrt", "divide"]),
        ("a/b if a > 0 else c", ["scalar"]),  # a branch not taken is not evaluated
        ("a > 0 and b/a > 1", ["scalar"]),
    ],
)
def test_the_lifted_statements_evaluate_as_the_expression(expression, kinds):
    statements = lifted_statements([("x", expression)], "_l")
    assert [s.kind for s in statements] == kinds and statements[-1].target == "x"
    rng = np.random.default_rng(7)
    for a, b, c in rng.normal(size=(20, 3)):
        values = {"math": math, "a": a, "b": b, "c": c}
        expected = eval(expression, values)
        for s in statements:
            if s.kind == "sqrt":
                values[s.target] = math.sqrt(eval(s.operands[0], values))
            elif s.kind == "divide":
                values[s.target] = eval(s.operands[0], values) / eval(s.operands[1], values)
            else:
                values[s.target] = eval(s.operands[0], values)
        assert _same(values["x"], expected)


def test_a_sum_written_in_chunks_is_one_assignment():
    """A template temporary of more than 32 terms is printed as ``x = ...`` and ``x += ...``
    lines; the lifting sees one assignment and the values are those of the lines."""
    z = sp.symbols("_g9_z0:40")
    total = sum(z[i] / sp.sqrt(1 + z[i] ** 2) / (i + 1) for i in range(40))
    group = ScatterGroup(
        name="_g9",
        value=total,
        entries=(("Lq", total * z[0]), ("Lq", total * z[1])),  # the sum: a temporary
        reads=tuple((f"_g9_z{i}", "q") for i in range(40)),
        table=np.zeros((5, 40), dtype=np.int64),
        slots=np.zeros((5, 2), dtype=np.int64),
    )
    temporaries, _, _ = source._group_code(group)
    assert any(" += " in line for line in temporaries)
    args = np.random.default_rng(2).normal(size=(5, 40))
    expected, result = np.zeros((5, 2)), np.zeros((5, 2))
    _compiled(_one_at_a_time(group, [0, 1]))(args, expected)
    _compiled(_side_by_side(group, [0, 1], 5))(args, result)
    assert _same(result, expected)


def _one_at_a_time(group, columns) -> str:
    temporaries, adds, _ = source._group_code(group)
    lines = ["def run(args, out):", "    for _k in range(args.shape[0]):"]
    lines += [f"        {var} = args[_k, {i}]" for i, (var, _) in enumerate(group.reads)]
    lines += ["    " + line for line in temporaries]
    lines += [f"        out[_k, {c}] = {adds[e]}" for c, e in enumerate(columns)]
    return "\n".join(lines)


def _side_by_side(group, columns, count) -> str:
    statements, targets = source._group_statements(group, columns)
    names = source._local_names(group, statements)
    suffixes = [f"_k{k}" for k in range(count)]
    lines = ["def run(args, out):"]
    lines += [
        f"    {var}{s} = args[{k}, {i}]"
        for k, s in enumerate(suffixes)
        for i, (var, _) in enumerate(group.reads)
    ]
    lines += ["    " + line for line in lane_lines(statements, names, suffixes)]
    lines += [
        f"    out[{k}, {c}] = {target}{s}"
        for k, s in enumerate(suffixes)
        for c, target in enumerate(targets)
    ]
    return "\n".join(lines)


def _compiled(text: str):
    namespace = {"math": math, "sqrt4": sqrt4, "divide4": divide4}
    exec(compile(text, "<generated>", "exec"), namespace)
    return njit(error_model="numpy")(namespace["run"])


@pytest.mark.parametrize("system", ["gravity", "lattice", "outer_solar_system"])
@pytest.mark.parametrize("count", [1, 3, 4, 6, 9])
def test_a_template_side_by_side_is_the_one_at_a_time_loop_bit_for_bit(system, count):
    if system == "outer_solar_system":
        spec = codegen.kernel_spec(gvi.problems.outer_solar_system().system)
    else:
        spec = codegen.kernel_spec(
            {"gravity": lambda: gravity(5), "lattice": lambda: lattice(4)}[system]()
        )
    group = next(g for g in spec.repeats if any(a == "Lq" for a, _ in g.entries))
    columns = [e for e, (array, _) in enumerate(group.entries) if array in ("Lq", "Lqq")]
    statements, _ = source._group_statements(group, columns)
    assert any(s.kind != "scalar" for s in statements)
    args = np.random.default_rng(count).normal(size=(count, len(group.reads)))
    if system == "lattice":
        args[0] = 0.0  # a spring of zero length: 0/0 in both
    expected, result = np.zeros((count, len(columns))), np.zeros((count, len(columns)))
    _compiled(_one_at_a_time(group, columns))(args, expected)
    _compiled(_side_by_side(group, columns, count))(args, result)
    assert _same(result, expected)
    text = _side_by_side(group, columns, count)
    # four instances per call; a last one alone is scalar code
    calls_per_statement = count // LANES + (count % LANES > 1)
    for function, kind in (("sqrt4(", "sqrt"), ("divide4(", "divide")):
        calls = [line for line in text.splitlines() if function in line]
        assert len(calls) == sum(s.kind == kind for s in statements) * calls_per_statement


# ------------------------------------------------------------------ in the modules
def test_only_the_unrolled_pair_force_calls_the_lanes():
    """The explicit loop of a small pair-potential system takes its roots and quotients
    four at a time; the point functions' scatter loops (every size) take none."""
    small = codegen.render_module(codegen.kernel_spec(n_body(masses=(1.0,) * 5).system), "k")
    point_functions, loop = small.split("def repeated_explicit_steps")
    assert "sqrt4(" in loop and "divide4(" in loop
    assert "sqrt4(" not in point_functions and "divide4(" not in point_functions
    large = codegen.render_module(codegen.kernel_spec(n_body(masses=(1.0,) * 13).system), "k")
    assert "repeated_explicit_steps" not in large and "sqrt4(" not in large


# 10 pairs (the last call padded), 21 pairs (a last pair alone)
@pytest.mark.parametrize("bodies", [5, 7])
def test_pair_force_runs_equal_across_the_loops_and_conserve_momentum(bodies):
    """The unrolled loop (four instances at a time, the last call padded or a last
    instance alone) and the shared loop (one instance at a time) are equal bit for
    bit; they and a Galerkin method keep the total momentum (a translation
    symmetry) to round-off."""
    problem = n_body(masses=tuple(1.0 + 0.1 * k for k in range(bodies)))
    kw = dict(h=problem.t_final / 80, n_steps=80, params=problem.params)
    runs = {}
    for name, method, specialize in [
        ("system", gvi.Composition(6), "system"),
        ("shared", gvi.Composition(6), True),
        ("galerkin", gvi.Galerkin(2), True),
    ]:
        integrator = gvi.Integrator(problem.system, method, specialize=specialize)
        runs[name] = integrator.integrate(problem.q0, problem.v0, **kw)
        if name == "system":
            steps = integrator.run_spec.explicit_steps.py_func
            assert steps.__name__ == "repeated_explicit_steps"
    assert np.array_equal(runs["system"].q, runs["shared"].q)
    assert np.array_equal(runs["system"].p, runs["shared"].p)
    for run in runs.values():
        total = run.p.reshape(len(run.p), bodies, 2).sum(axis=1)
        assert np.abs(total - total[0]).max() < 1e-13 * np.abs(run.p).max()
