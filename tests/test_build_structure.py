"""Repeated terms of large Lagrangians as scatter loops (galerkin_vi.codegen.scatter).

The point functions generated with the loops must equal the straight-line ones
(``kernel_spec(system, repeats=False)``) on random states, for lattices,
chains, pair potentials, time dependence and parameters, forces and a
Lagrangian that only partly repeats; the generated module's number of
statements must not grow with the lattice; trajectories must agree with the
NumPy reference to round-off, through the run options.
"""

from __future__ import annotations

import ast
import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen
from galerkin_vi.expression_walk import structural_bytes
from galerkin_vi.model.terms import repeated_terms, substitute


# ---------------------------------------------------------------------- systems
def _lattice_L(n: int, beta: float = 0.5):
    """2-D lattice of n x n unit masses, nearest-neighbour springs k/2 (r-1)^2 + beta/4 (r-1)^4."""
    x, y = sp.symbols(f"x0:{n * n}"), sp.symbols(f"y0:{n * n}")
    u, w = sp.symbols(f"u0:{n * n}"), sp.symbols(f"w0:{n * n}")
    q = [c for a in range(n * n) for c in (x[a], y[a])]
    v = [c for a in range(n * n) for c in (u[a], w[a])]

    def spring(dx, dy):
        e = sp.sqrt(dx**2 + dy**2) - 1
        return e**2 / 2 + beta * e**4 / 4

    V = 0
    for i in range(n):
        for j in range(n):
            a = i * n + j
            if j + 1 < n:
                V += spring(x[a + 1] - x[a] + 1, y[a + 1] - y[a])
            if i + 1 < n:
                V += spring(x[a + n] - x[a], y[a + n] - y[a] + 1)
    return sum(c**2 for c in v) / 2 - V, q, v


def lattice(n: int, beta: float = 0.5) -> gvi.LagrangianSystem:
    L, q, v = _lattice_L(n, beta)
    return gvi.LagrangianSystem(L, q, v)


def fpu_chain(n: int) -> gvi.LagrangianSystem:
    q, v = sp.symbols(f"q0:{n}"), sp.symbols(f"v0:{n}")
    d = [q[0]] + [q[i + 1] - q[i] for i in range(n - 1)] + [-q[-1]]
    L = sum(c**2 for c in v) / 2 - sum(e**2 / 2 + e**4 / 4 for e in d)
    return gvi.LagrangianSystem(L, list(q), list(v))


def gravity(bodies: int) -> gvi.LagrangianSystem:
    """Planar bodies with softened gravity between all pairs (masses as parameters)."""
    x, y = sp.symbols(f"x0:{bodies}"), sp.symbols(f"y0:{bodies}")
    u, w = sp.symbols(f"u0:{bodies}"), sp.symbols(f"w0:{bodies}")
    m = sp.symbols(f"m0:{bodies}", positive=True)
    q = [c for a in range(bodies) for c in (x[a], y[a])]
    v = [c for a in range(bodies) for c in (u[a], w[a])]
    T = sum(m[a] * (u[a] ** 2 + w[a] ** 2) / 2 for a in range(bodies))
    U = sum(
        m[a] * m[b] / sp.sqrt((x[a] - x[b]) ** 2 + (y[a] - y[b]) ** 2 + sp.Rational(1, 100))
        for a in range(bodies)
        for b in range(a)
    )
    params = {m[a]: 1.0 + 0.1 * a for a in range(bodies)}
    return gvi.LagrangianSystem(T + U, q, v, params=params)


def driven_chain(n: int) -> gvi.LagrangianSystem:
    """A ring with time-dependent stiffness k (1 + eps cos t), a parameter per spring kind,
    and velocity coupling (a magnetic-like term q_i v_{i+1}) that repeats too."""
    q, v = sp.symbols(f"q0:{n}"), sp.symbols(f"v0:{n}")
    t, k, eps = sp.symbols("t k eps")
    d = [q[(i + 1) % n] - q[i] for i in range(n)]  # a ring: not a chain's runs
    L = (
        sum(c**2 for c in v) / 2
        - k * (1 + eps * sp.cos(t)) * sum(e**2 / 2 + e**4 / 12 for e in d)
        + sum(q[i] * v[(i + 1) % n] - q[(i + 1) % n] * v[i] for i in range(n)) / 5
    )
    return gvi.LagrangianSystem(L, list(q), list(v), t=t, params={k: 1.3, eps: 0.2})


def partly_repeated(n: int = 4) -> gvi.LagrangianSystem:
    """A lattice plus terms that do not repeat (a coupling of two far masses, a
    position-dependent mass of one coordinate) and damping forces."""
    L, q, v = _lattice_L(n)
    L += sp.sin(q[0] * q[5]) / 3 + q[2] ** 2 * v[2] ** 2 / 4
    forces = [-0.1 * c for c in v[:3]] + [0] * (len(q) - 3)
    return gvi.LagrangianSystem(L, q, v, forces=forces)


SYSTEMS = {
    "lattice": lambda: lattice(4),
    "lattice_banded": lambda: lattice(5),
    "gravity": lambda: gravity(8),
    "driven": lambda: driven_chain(30),
    "partly": partly_repeated,
}


# ---------------------------------------------------------------------- helpers
def _namespace(spec) -> dict:
    """The generated module run uncompiled (its parts as plain Python functions)."""
    source = codegen.render_module(spec, "k")
    source = source.replace('part = njit(cache=True, error_model="numpy")', "part = lambda f: f")
    namespace: dict = {}
    exec(compile(source, "<generated>", "exec"), namespace)
    return namespace


def _outputs(namespace, spec, t, q, v, prm) -> dict[str, np.ndarray]:
    """Every point function's outputs at one point, each called twice into the same
    arrays (the loops' zeroing of what they add into is part of the contract)."""
    n, nnz = spec.n, spec.nnz
    shapes = {
        "point_gradient": [n, n],
        "point_hessian": [n, n, nnz, nnz, nnz, n * n],
        "point_mass": [n, n, nnz, nnz],
    }
    out = {}
    for name, sizes in shapes.items():
        arrays = [np.zeros(size) for size in sizes]
        for _ in range(2):
            namespace[name](t, q, v, prm, *arrays)
        out[name] = np.concatenate(arrays)
    out["lagrangian"] = np.array([namespace["lagrangian"](t, q, v, prm)])
    return out


# ---------------------------------------------------------------------- tests
# the banded lattice's straight-line module alone takes seconds to render: a slow case
@pytest.mark.parametrize(
    "name",
    [
        pytest.param(s, marks=pytest.mark.slow) if s == "lattice_banded" else s
        for s in sorted(SYSTEMS)
    ],
)
def test_scatter_loops_equal_the_straight_line_point_functions(name):
    system = SYSTEMS[name]()
    looped = codegen.kernel_spec(system)
    straight = codegen.kernel_spec(system, repeats=False)
    assert looped.repeats, "the repeated terms were not found"
    assert not straight.repeats
    assert len(looped.hessian_entries) < len(straight.hessian_entries) / 4
    a, b = _namespace(looped), _namespace(straight)
    rng = np.random.default_rng(7)
    for _ in range(3):
        q, v = 0.3 * rng.standard_normal(system.n), rng.standard_normal(system.n)
        t = float(rng.uniform(0, 5))
        prm = system.param_defaults * rng.uniform(0.8, 1.2, size=len(system.params))
        fast, slow = _outputs(a, looped, t, q, v, prm), _outputs(b, straight, t, q, v, prm)
        for key in slow:
            scale = max(np.abs(slow[key]).max(), 1.0)
            np.testing.assert_allclose(fast[key], slow[key], rtol=0, atol=1e-13 * scale)


def test_a_chain_keeps_the_runs_of_consecutive_rows():
    # its springs step every index by one: loops without index tables (codegen/repeats.py)
    spec = codegen.kernel_spec(fpu_chain(40))
    assert not spec.repeats
    assert "for _i in range" in codegen.render_module(spec, "k")


def test_the_generated_source_does_not_grow_with_the_lattice():
    def statements(n: int) -> int:
        source = codegen.render_module(codegen.kernel_spec(lattice(n)), "k")
        return sum(isinstance(node, ast.stmt) for node in ast.walk(ast.parse(source)))

    small, large = statements(5), statements(6)  # 50 and 72 coordinates, both banded
    assert small == large
    assert small < 1000  # the straight-line module of 72 coordinates has thousands


def test_repeated_terms_split_the_lagrangian_exactly():
    L, q, v = _lattice_L(4)
    groups, rest = repeated_terms(L, tuple(q), tuple(v), min_count=8)
    # kinetic energy, horizontal and vertical springs (both powers of a spring in one)
    assert sorted(g.count for g in groups) == [12, 12, 32]
    assert rest == 0
    symbols = {"q": tuple(q), "v": tuple(v), "prm": ()}
    total = sum(g.instance(k, symbols) for g in groups for k in range(g.count))
    point = {s: 0.1 * (i % 7) - 0.2 for i, s in enumerate(q + v)}
    assert float((total - L).xreplace(point)) == pytest.approx(0.0, abs=1e-12)
    few, rest = repeated_terms(L, tuple(q), tuple(v), min_count=13)
    assert [g.count for g in few] == [32]
    assert rest != 0
    with pytest.raises(ValueError, match="min_count"):
        repeated_terms(L, tuple(q), tuple(v), min_count=0)


def test_substitute_equals_xreplace():
    a, b, c, d = sp.symbols("a b c d", real=True)
    x, y = sp.symbols("x y")
    exprs = [sp.sqrt((b - a + 1) ** 2 + c**2) ** 3 * sp.sin(a * c), sp.exp(-(b**2)) / (a - b)]
    mapping = {a: x, b: y, c: d}
    reference = [e.xreplace(mapping) for e in exprs]
    for fast, slow in zip(substitute(exprs, mapping), reference, strict=True):
        assert sp.simplify(fast - slow) == 0
    with pytest.raises(ValueError, match="distinct"):
        substitute(exprs, {a: x, b: x})


@pytest.fixture(scope="module")
def small_lattice():
    system = lattice(4)
    return system, gvi.Integrator(system, gvi.Galerkin(2), specialize=False)


def test_a_lattice_integrates_like_the_numpy_reference(small_lattice):
    system, compiled = small_lattice
    assert "for _k in range" in compiled.source
    rng = np.random.default_rng(1)
    q0, v0 = 0.05 * rng.standard_normal(system.n), 0.1 * rng.standard_normal(system.n)
    fast = compiled.integrate(q0, v0, h=0.05, n_steps=8, save_every=4)
    slow = gvi.Integrator(system, gvi.Galerkin(2), backend="numpy").integrate(
        q0, v0, h=0.05, n_steps=8, save_every=4
    )
    np.testing.assert_allclose(fast.q, slow.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(fast.p, slow.p, rtol=0, atol=1e-12)


def test_a_lattice_runs_through_the_run_options(small_lattice):
    system, integrator = small_lattice
    rng = np.random.default_rng(2)
    q0, v0 = 0.05 * rng.standard_normal(system.n), 0.1 * rng.standard_normal(system.n)
    full = integrator.integrate(q0, v0, h=0.05, n_steps=20)
    dense = integrator.integrate(q0, v0, h=0.05, t_span=(0.0, 1.0), t_eval=[0.25, 0.5],
                                 dense_output=True)  # fmt: skip
    assert dense.t[-1] == pytest.approx(0.5)  # the rows at t_eval; t = 0.5 is step 10
    np.testing.assert_allclose(dense.q[-1], full.q[10], rtol=0, atol=1e-12)
    event = gvi.Event(sp.Symbol("x0") - q0[0] - 1e-3, terminal=True)
    cut = integrator.integrate(q0, v0, h=0.05, t_span=(0.0, 1.0), events=[event])
    assert cut.t[-1] <= 1.0
    many = integrator.integrate_many(np.stack([q0, 0.5 * q0]), np.stack([v0, v0]), h=0.05,
                                     n_steps=20)  # fmt: skip
    np.testing.assert_allclose(many[0].q[-1], full.q[-1], rtol=0, atol=1e-13)
    copy = pickle.loads(pickle.dumps(integrator))
    again = copy.integrate(q0, v0, h=0.05, n_steps=20)
    np.testing.assert_array_equal(again.q, full.q)
    tangent = integrator.integrate(q0, v0, h=0.05, n_steps=4, tangent=True)
    assert np.all(np.isfinite(tangent.tangent))


def test_sensitivity_to_a_parameter_of_repeated_terms():
    system = gravity(8)
    integrator = gvi.Integrator(system, gvi.Galerkin(2))
    rng = np.random.default_rng(3)
    q0, v0 = 3 * rng.standard_normal(system.n), 0.1 * rng.standard_normal(system.n)
    m0 = system.params[0]
    run = integrator.integrate(q0, v0, h=0.01, n_steps=10, sensitivity=[m0])
    eps = 1e-6
    params = {s: float(x) for s, x in zip(system.params, system.param_defaults, strict=True)}
    up = integrator.integrate(q0, v0, h=0.01, n_steps=10, params={**params, m0: params[m0] + eps})
    down = integrator.integrate(q0, v0, h=0.01, n_steps=10,
                                params={**params, m0: params[m0] - eps})  # fmt: skip
    difference = (up.q[-1] - down.q[-1]) / (2 * eps)
    np.testing.assert_allclose(run.sensitivity[-1, : system.n, 0], difference, rtol=1e-5,
                               atol=1e-8)  # fmt: skip


def test_structural_bytes_name_an_expression_by_its_structure_not_its_objects():
    q = sp.Symbol("q")
    sp.core.cache.clear_cache()
    copy = sp.Symbol.__xnew__(sp.Symbol, "q")
    held = sp.cos(q) + sp.Pow(copy, 4)  # two distinct objects for one symbol
    sp.core.cache.clear_cache()
    shared = sp.cos(q) + q**4
    assert held == shared
    assert structural_bytes(held) == structural_bytes(shared)
    assert structural_bytes((held, [shared])) == structural_bytes((shared, [held]))
    x, y = sp.symbols("x y")
    others = [x + y, x * y, x - y, sp.Symbol("q", positive=True) ** 4 + sp.cos(q), held + 1]
    names = {structural_bytes(e) for e in [held, *others]}
    assert len(names) == len(others) + 1


def test_structural_bytes_fall_back_to_srepr_for_what_does_not_pickle():
    class Local(sp.Symbol):  # a class inside a function: pickle cannot name it
        pass

    e = sp.cos(Local("a")) + 1
    with pytest.raises((pickle.PicklingError, AttributeError)):
        pickle.dumps(e)
    assert structural_bytes(e) == sp.srepr(e).encode()
