"""Loops over repeated entries in the point functions of large systems (codegen.repeats)."""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen, problems
from galerkin_vi.codegen import source
from galerkin_vi.codegen.repeats import MIN_RUN, find_runs

Q = sp.symbols(" ".join(f"q[{i}]" for i in range(40)), real=True)


def test_a_repeated_template_becomes_one_run_and_the_ends_stay():
    entries = [(f"Lq[{i}]", Q[i + 1] - 2 * Q[i] + Q[i - 1]) for i in range(1, 39)]
    entries += [("Lq[0]", Q[1] - 2 * Q[0]), ("Lq[39]", Q[38] - 2 * Q[39])]
    runs, rest = find_runs(entries, 40)
    (run,) = runs
    assert (run.array, run.start, run.stop, run.stride, run.offset) == ("Lq", 1, 39, 1, 0)
    assert sorted(slot for slot, _ in rest) == ["Lq[0]", "Lq[39]"]


def test_short_or_broken_runs_stay_straight_line():
    short = [(f"Lq[{i}]", Q[i] ** 3) for i in range(MIN_RUN - 1)]
    runs, rest = find_runs(short, 40)
    assert runs == [] and len(rest) == MIN_RUN - 1
    gap = [(f"Lq[{i}]", Q[i] ** 3) for i in list(range(5)) + list(range(6, 11))]
    runs, rest = find_runs(gap, 40)  # rows 0-4 and 6-10: neither reaches MIN_RUN
    assert runs == [] and len(rest) == 10


def _evaluate(text, n, nnz, prm, seed=3):
    namespace: dict = {}
    exec(compile(text.replace("@part\n", ""), "<generated>", "exec"), namespace)
    rng = np.random.default_rng(seed)
    q, v = rng.normal(size=n), rng.normal(size=n)
    Lq, Lv, Lqq, Lqv, Lvv = np.zeros(n), np.zeros(n), *(np.zeros(nnz) for _ in range(3))
    namespace["point_hessian"](0.0, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, np.zeros(1))
    gq, gv = np.zeros(n), np.zeros(n)
    namespace["point_gradient"](0.0, q, v, prm, gq, gv)
    return np.concatenate([Lq, Lv, Lqq, Lvv, gq, gv])


@pytest.mark.parametrize("beta", [0.0, 1.0])
def test_looped_point_functions_equal_the_straight_line_ones(beta):
    system = problems.spring_chain(50, beta=beta).system
    # the runs of consecutive rows: what a large system's entries that are not
    # repeated terms of L (tests/test_build_structure.py) become
    spec = codegen.kernel_spec(system, repeats=False)
    looped = codegen.render_module(spec, "k")
    assert looped.count("for _i in range") >= 4
    straight = "\n".join(
        [
            "import math",
            *source._point_function("point_gradient", list(spec.gradient_entries), True)[0],
            *source._point_function("point_hessian", list(spec.hessian_entries), True)[0],
        ]
    )
    assert straight.count("\n") > 4 * looped.count("\n")  # what the loops save
    a = _evaluate(looped, spec.n, spec.nnz, system.param_defaults)
    b = _evaluate(straight, spec.n, spec.nnz, system.param_defaults)
    np.testing.assert_allclose(a, b, rtol=0, atol=1e-14 * np.abs(b).max())


def test_loops_and_one_part_are_one_function():
    """A chain's point functions are loops and a few end rows: written as one function
    (calling parts costs reference counts per array and call); a function whose rest
    exceeds one part's entries keeps its parts."""
    spec = codegen.kernel_spec(problems.spring_chain(50, beta=1.0).system, repeats=False)
    looped = codegen.render_module(spec, "k")
    for name in ("point_gradient", "point_hessian", "point_mass"):
        assert f"def {name}(" in looped
        assert f"def {name}_loops(" not in looped and f"def {name}_part0(" not in looped
    many = [(f"Lq[{i}]", sp.sin(Q[i % 40]) * Q[(7 * i) % 40]) for i in range(40)] * 6
    lines, _ = source._point_function("point_gradient", many, True, spec=spec)
    assert any(line.startswith("def point_gradient_part1(") for line in lines)


def test_a_large_chain_with_loops_integrates_like_the_numpy_reference():
    x = sp.symbols("x0:40")
    w = sp.symbols("w0:40")
    springs = [x[0], *(x[i + 1] - x[i] for i in range(39)), -x[-1]]
    L = sum(u**2 for u in w) / 2 - sum(e**2 / 2 + e**4 / 5 for e in springs)
    system = gvi.LagrangianSystem(L, list(x), list(w))
    compiled = gvi.Integrator(system, gvi.Galerkin(2), specialize=False)
    assert "for _i in range" in compiled.source  # a chain: runs of consecutive rows
    q0 = 0.3 * np.sin(np.linspace(0.5, 3.0, 40))
    fast = compiled.integrate(q0, np.zeros(40), h=0.05, n_steps=40)
    slow = gvi.Integrator(system, gvi.Galerkin(2), backend="numpy").integrate(
        q0, np.zeros(40), h=0.05, n_steps=40
    )
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.p, slow.p, rtol=0, atol=1e-12)
