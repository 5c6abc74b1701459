"""The on-disk cache of a system's symbolic analysis (galerkin_vi.model.analysis_cache)."""

from __future__ import annotations

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
