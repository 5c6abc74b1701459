"""The on-disk cache of a system's symbolic analysis (galerkin_vi.model.analysis_cache)."""

from __future__ import annotations

import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen
from galerkin_vi.model import analysis_cache
from galerkin_vi.model import system as system_module

q, v, k = sp.symbols("q v k")


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("GALERKIN_VI_CACHE_DIR", str(tmp_path))
    return tmp_path


def _model(stiffness=2.0, **kw):
    return gvi.LagrangianSystem(
        v**2 / 2 - k * q**4 / 4 + sp.cos(q), [q], [v], params={k: stiffness}, **kw
    )


def _no_differentiation(monkeypatch):
    def refuse(*args, **kwargs):
        raise AssertionError("differentiated again")

    monkeypatch.setattr(system_module, "pointwise_pieces", refuse)


def test_a_second_build_loads_the_analysis_instead_of_deriving_it(monkeypatch, cache_dir):
    first = _model()
    assert list((cache_dir / "systems").glob("*.pickle"))
    _no_differentiation(monkeypatch)
    again = _model()
    assert again.pieces == first.pieces
    assert again.structure == first.structure and again.periodic == first.periodic
    x = np.array([[0.3], [1.1]])
    w = np.array([[0.2], [-0.4]])
    np.testing.assert_array_equal(again.hamiltonian(x, w), first.hamiltonian(x, w))


def _with_a_copy_of_q():
    """The model's Lagrangian with ``q**4`` holding an equal but distinct ``Symbol('q')``.

    What SymPy's cache hands out when a cached ``Pow`` outlived the symbol it was
    made with (evicted and made again by a later ``Symbol('q')``).
    """
    sp.core.cache.clear_cache()
    copy = sp.Symbol.__xnew__(sp.Symbol, "q")
    assert copy == q and copy is not q
    L = v**2 / 2 - k * sp.Pow(copy, 4) / 4 + sp.cos(q)
    sp.core.cache.clear_cache()
    return L


def test_one_model_has_one_key_whichever_objects_sympys_cache_holds(monkeypatch):
    L = _with_a_copy_of_q()
    clean = _model().L
    assert L == clean and pickle.dumps(L) != pickle.dumps(clean)  # the case this test is for
    first = gvi.LagrangianSystem(L, [q], [v], params={k: 2.0})
    _no_differentiation(monkeypatch)
    again = _model()
    assert again.analysis_key == first.analysis_key and again.pieces == first.pieces


def test_the_key_follows_every_input(monkeypatch):
    _model()
    _no_differentiation(monkeypatch)
    for other in (
        lambda: _model(stiffness=3.0),  # regularity is checked with the default values
        lambda: _model(forces=[-v / 10]),
        lambda: gvi.LagrangianSystem(v**2 / 2 - k * q**4 / 4, [q], [v], params={k: 2.0}),
    ):
        with pytest.raises(AssertionError, match="differentiated again"):
            other()


def test_a_damaged_entry_is_derived_and_written_again(cache_dir):
    first = _model()
    (entry,) = (cache_dir / "systems").glob("*.pickle")
    entry.write_bytes(b"\x80\x04 not a pickle")
    again = _model()
    assert again.pieces == first.pieces
    assert analysis_cache.load_analysis(again.analysis_key) is not None


def test_a_rejected_model_is_not_cached(cache_dir):
    for _ in range(2):  # rejected both times: nothing was stored in between
        with pytest.raises(gvi.DegenerateLagrangianError):
            gvi.LagrangianSystem(v + sp.cos(q), [q], [v])
    assert not list((cache_dir / "systems").glob("*.pickle"))


def test_a_cached_system_integrates_without_deriving_its_spec(monkeypatch):
    method = gvi.Galerkin(2)
    reference = gvi.Integrator(_model(), method).integrate([0.5], [0.1], h=0.05, n_steps=20)
    _no_differentiation(monkeypatch)

    def refuse(system):
        raise AssertionError("spec derived again")

    monkeypatch.setattr(codegen, "kernel_spec", refuse)
    traj = gvi.Integrator(_model(), method).integrate([0.5], [0.1], h=0.05, n_steps=20)
    np.testing.assert_array_equal(traj.q, reference.q)
    np.testing.assert_array_equal(traj.p, reference.p)


def test_the_sources_hash_covers_every_module_the_analysis_imports():
    import ast
    from pathlib import Path

    model = Path(analysis_cache.__file__).resolve().parent
    hashed = {(model / name).resolve() for name in analysis_cache._SOURCES}
    for name in ("symbolic.py", "system.py"):
        tree = ast.parse((model / name).read_text())
        for node in ast.walk(tree):
            if not (isinstance(node, ast.ImportFrom) and node.level == 1 and node.module):
                continue
            # the analysis's own helpers in model/ and the leaf walks it uses
            path = (model / (node.module.replace(".", "/") + ".py")).resolve()
            if node.module in ("terms", "symbolic", "system") or path.name == "expression_walk.py":
                assert path in hashed, f"{name} imports {node.module}, not in _SOURCES"
    assert (model.parent / "expression_walk.py").resolve() in hashed


def test_a_remembered_point_summary_of_another_code_generator_is_not_reused(monkeypatch):
    from galerkin_vi.codegen import compiled

    method = gvi.Galerkin(2)
    first = gvi.Integrator(_model(), method)
    key = first._summary.key
    compiled.generator_fingerprint.cache_clear()
    monkeypatch.setattr(compiled, "GENERATOR_VERSION", "another")
    try:
        second = gvi.Integrator(_model(), method)
        derived = []
        original = codegen.summarize

        def counting(spec, point_key):
            derived.append(point_key)
            return original(spec, point_key)

        monkeypatch.setattr(codegen, "summarize", counting)
        assert second._summary.key == key  # the spec's key itself is unchanged here
        assert len(derived) == 1  # but the summary was derived again, not recalled
    finally:
        compiled.generator_fingerprint.cache_clear()


def _lattice_row(n=12):
    """A row of ``n`` masses in the plane with springs of the distance: repeated terms."""
    x = sp.symbols(f"x0:{n}", real=True)
    y = sp.symbols(f"y0:{n}", real=True)
    u = sp.symbols(f"u0:{n}", real=True)
    w = sp.symbols(f"w0:{n}", real=True)
    L = sum(c**2 for c in (*u, *w)) / 2
    for a in range(n - 1):
        e = sp.sqrt((x[a + 1] - x[a] + 1) ** 2 + (y[a + 1] - y[a]) ** 2) - 1
        L -= e**2 / 2 + e**4 / 4
    return L, [*x, *y], [*u, *w]


def test_a_loaded_large_analysis_is_the_stored_one_node_for_node(monkeypatch):
    L, qs, vs = _lattice_row()
    first = gvi.LagrangianSystem(L, qs, vs)
    _no_differentiation(monkeypatch)
    again = gvi.LagrangianSystem(L, qs, vs)
    for name in ("Lq", "Lv", "Lqq", "Lqv", "Lvv"):
        a, b = getattr(first.pieces, name), getattr(again.pieces, name)
        assert a.shape == b.shape
        # loaded without evaluation: the very same trees, not only equal values
        assert all(sp.srepr(a[key]) == sp.srepr(b[key]) for key in a.todok())
    z = np.linspace(-0.2, 0.3, len(qs))
    np.testing.assert_array_equal(
        again.evaluate("hessian", 0.0, z, z, again.param_defaults),
        first.evaluate("hessian", 0.0, z, z, first.param_defaults),
    )


def test_remembered_values_go_beside_the_analysis_without_rewriting_it(cache_dir):
    system = _model()
    (main,) = (cache_dir / "systems").glob("*.pickle")
    before = main.read_bytes()
    system.remember("point_summary", ("numba", {"size": 3}))
    assert main.read_bytes() == before
    again = _model()
    assert again.recalled("point_summary") == ("numba", {"size": 3})
    assert again.recalled("absent") is None


def test_sum_of_distinct_is_sympys_sum():
    a, b, c = sp.symbols("a b c", real=True)
    from galerkin_vi.model.symbolic import sum_of_distinct

    cases = [
        [sp.sqrt(a**2 + b**2), -2 * a * b, sp.Integer(3), sp.Rational(1, 2)],
        [a * b, 2 * a * b],  # like terms: collected
        [sp.Integer(1), sp.Integer(-1)],  # cancels to zero
        [a + b, c - b],  # sums inside cancel
        [sp.sin(a) ** 2],
        [c, a + 2 * sp.cos(b)],
    ]
    for terms in cases:
        total = sum_of_distinct(terms)
        assert sp.simplify(total - sp.Add(*terms)) == 0
        point = {a: 0.3, b: -1.2, c: 0.7}
        assert float(total.subs(point)) == pytest.approx(float(sp.Add(*terms).subs(point)))
    assert sum_of_distinct([sp.Integer(1), sp.Integer(-1)]) == 0
    assert sum_of_distinct([a * b, 2 * a * b]) == 3 * a * b
    assert sum_of_distinct([a + b, c - b]) == a + c
