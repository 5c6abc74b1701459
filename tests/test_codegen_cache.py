"""Code generation (spec, signature, rendered source) and the on-disk point-function cache.

Every test points ``GALERKIN_VI_CACHE_DIR`` at its own ``tmp_path``. One Lagrangian (a
Duffing oscillator used nowhere else) is compiled, once, for the corrupt-entry test.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import cache, codegen
from galerkin_vi.codegen import compiled
from galerkin_vi.codegen.compiled import numba_version

x, y, vx, vy, a, b = sp.symbols("x y vx vy a b")
th1, th2, w1, w2 = sp.symbols("theta1 theta2 omega1 omega2")


@pytest.fixture(autouse=True)
def cache_dir(tmp_path, monkeypatch):
    monkeypatch.setenv("GALERKIN_VI_CACHE_DIR", str(tmp_path))
    return tmp_path


def double_pendulum(q=(x, y), v=(vx, vy)):
    (p, r), (vp, vr) = q, v
    L = (2 * vp**2 + vr**2 + 2 * sp.cos(p - r) * vp * vr) / 2 + 2 * sp.cos(p) + sp.cos(r)
    return gvi.LagrangianSystem(L, list(q), list(v))


def duffing(alpha=1.0, beta=0.5):
    return gvi.LagrangianSystem(
        vx**2 / 2 - a * x**2 / 2 - b * x**4 / 4, [x], [vx], params={a: alpha, b: beta}
    )


def _key(system, backend="numba"):
    return codegen.signature(codegen.kernel_spec(system), backend, numba_version() or "none")


# ------------------------------------------------------------------ cache root
def test_cache_root_follows_the_environment(cache_dir, monkeypatch):
    assert cache.cache_root() == cache_dir
    path = compiled.entry_path("ab" * 32)
    assert path.parent == cache.cache_root() / "points"
    assert path.name.startswith("gvi_") and path.suffix == ".py"
    monkeypatch.delenv("GALERKIN_VI_CACHE_DIR")
    monkeypatch.setenv("NUMBA_CACHE_DIR", str(cache_dir / "numba"))
    assert cache.cache_root() == cache_dir / "numba" / "galerkin_vi"
    monkeypatch.delenv("NUMBA_CACHE_DIR")
    assert cache_dir not in cache.cache_root().parents  # read at call time, not import time


# ------------------------------------------------------------------- signature
def test_signature_is_stable_for_equal_systems():
    first = _key(double_pendulum())
    again = _key(double_pendulum())
    renamed = _key(double_pendulum((th1, th2), (w1, w2)))  # symbol names do not matter
    assert first == again == renamed
    assert len(first) == 64 and int(first, 16) >= 0


def test_signature_ignores_parameter_values():
    # compile once per system: parameter values are run-time data
    assert _key(duffing(1.0, 0.5)) == _key(duffing(-3.0, 7.0))


@pytest.mark.parametrize(
    "other",
    [
        lambda: duffing(),  # a different Lagrangian
        lambda: gvi.LagrangianSystem(
            (2 * vx**2 + vy**2 + 2 * sp.cos(x - y) * vx * vy) / 2 + 2 * sp.cos(x) + 2 * sp.cos(y),
            [x, y],
            [vx, vy],
        ),  # one coefficient changed
        lambda: gvi.LagrangianSystem(double_pendulum().L, [y, x], [vy, vx]),  # order swapped
    ],
)
def test_signature_differs_for_different_lagrangians(other):
    assert _key(other()) != _key(double_pendulum())


def test_signature_depends_on_backend_and_version():
    spec = codegen.kernel_spec(double_pendulum())
    keys = {
        codegen.signature(spec, "numba", "0.60.0"),
        codegen.signature(spec, "numba", "0.61.0"),
        codegen.signature(spec, "source", ""),
    }
    assert len(keys) == 3


# ------------------------------------------------------------------------ spec
def test_spec_drops_identically_zero_entries():
    spec = codegen.kernel_spec(duffing())
    slots = [slot for slot, _ in spec.hessian_entries]
    assert not spec.has_Lqv
    assert not any(slot.startswith("Lqv") for slot in slots)  # L_qv == 0 is skipped
    assert "Lvv[0]" in slots and "Lqq[0]" in slots  # flat storage, entry (0, 0)
    assert spec.autonomous and spec.n == 1 and spec.n_params == 2

    coupled = codegen.kernel_spec(double_pendulum())
    assert coupled.has_Lqv
    coupled_slots = [slot for slot, _ in coupled.hessian_entries]
    assert "Lvv[3]" in coupled_slots  # entry (1, 1) of a 2 x 2 block, flat
    assert "Lqv[0]" in coupled_slots and "Lqv[1]" in coupled_slots
    assert not coupled.banded  # two coordinates: dense storage


# --------------------------------------------------------------------- render
def _load_uncompiled(source):
    namespace: dict = {}
    exec(compile(source, "<generated>", "exec"), namespace)
    return namespace


def test_render_module_is_valid_python_with_the_key_on_first_and_last_line():
    system = double_pendulum()
    key = _key(system)
    source = codegen.render_module(codegen.kernel_spec(system), key)
    compile(source, "<generated>", "exec")
    lines = source.rstrip("\n").splitlines()
    assert key in lines[0] and key in lines[-1]
    assert "def point_hessian(t, q, v, prm, Lq, Lv, Lqq, Lqv, Lvv, Fv):" in source


def test_rendered_point_functions_compute_the_derivatives():
    # run the generated module without numba: every entry against the closed form
    source = codegen.render_module(codegen.kernel_spec(double_pendulum()), "k")
    ns = _load_uncompiled(source)
    q, v = np.array([0.7, -0.4]), np.array([1.3, 0.2])
    Lq, Lv = np.zeros(2), np.zeros(2)
    Lqq, Lqv, Lvv = np.zeros(4), np.zeros(4), np.zeros(4)
    ns["point_hessian"](0.0, q, v, np.zeros(0), Lq, Lv, Lqq, Lqv, Lvv, np.zeros(1))
    # flat storage: entry (a, b) at 2 a + b
    Lqq, Lqv, Lvv = Lqq.reshape(2, 2), Lqv.reshape(2, 2), Lvv.reshape(2, 2)
    s, c = np.sin(q[0] - q[1]), np.cos(q[0] - q[1])
    vv = v[0] * v[1]
    np.testing.assert_allclose(
        Lq, [-s * vv - 2 * np.sin(q[0]), s * vv - np.sin(q[1])], rtol=1e-15, atol=1e-15
    )
    np.testing.assert_allclose(Lv, [2 * v[0] + c * v[1], v[1] + c * v[0]], rtol=1e-15)
    np.testing.assert_allclose(
        Lqq,
        [[-c * vv - 2 * np.cos(q[0]), c * vv], [c * vv, -c * vv - np.cos(q[1])]],
        rtol=1e-15,
        atol=1e-15,
    )
    np.testing.assert_allclose(Lqv, [[-s * v[1], -s * v[0]], [s * v[1], s * v[0]]], rtol=1e-15)
    np.testing.assert_allclose(Lvv, [[2, c], [c, 1]], rtol=1e-15)
    L = ns["lagrangian"](0.0, q, v, np.zeros(0))
    expected = (2 * v[0] ** 2 + v[1] ** 2 + 2 * c * vv) / 2 + 2 * np.cos(q[0]) + np.cos(q[1])
    assert L == pytest.approx(expected, rel=1e-15)
    Lq2, Lv2 = np.zeros(2), np.zeros(2)
    ns["point_gradient"](0.0, q, v, np.zeros(0), Lq2, Lv2)
    np.testing.assert_array_equal(Lq2, Lq)
    np.testing.assert_array_equal(Lv2, Lv)


def test_rendered_parameters_are_read_from_prm():
    ns = _load_uncompiled(codegen.render_module(codegen.kernel_spec(duffing()), "k"))
    Lq, Lv = np.zeros(1), np.zeros(1)
    ns["point_gradient"](0.0, np.array([2.0]), np.array([0.5]), np.array([3.0, 0.25]), Lq, Lv)
    assert Lq[0] == -3.0 * 2.0 - 0.25 * 8.0
    assert Lv[0] == 0.5


# ---------------------------------------------------------------------- cache
def test_read_entry_rejects_missing_truncated_and_foreign_files():
    system = double_pendulum()
    key = _key(system)
    source = codegen.render_module(codegen.kernel_spec(system), key)
    assert compiled.read_entry(key) is None  # missing
    path = compiled.entry_path(key)
    path.parent.mkdir(parents=True)
    path.write_text(source[: len(source) // 2])
    assert compiled.read_entry(key) is None  # truncated: no key on the last line
    path.write_text(source.replace(key, "f" * 64))
    assert compiled.read_entry(key) is None  # another key's module under this name
    path.write_bytes(b"\xff\xfe\x00garbage")
    assert compiled.read_entry(key) is None  # not text
    path.write_text(source)
    assert compiled.read_entry(key) == source


def test_atomic_write_twice_keeps_the_first_file():
    system = double_pendulum()
    key = _key(system)
    source = codegen.render_module(codegen.kernel_spec(system), key)
    path = compiled.entry_path(key)
    assert cache.atomic_write(path, source)
    before = os.stat(path)
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns - 10**9))  # make a rewrite visible
    before = os.stat(path)
    assert not cache.atomic_write(path, source)
    after = os.stat(path)
    assert after.st_mtime_ns == before.st_mtime_ns
    assert after.st_ino == before.st_ino
    assert path.read_text() == source
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]  # no temporaries left


def test_atomic_write_replaces_a_corrupt_file():
    system = double_pendulum()
    key = _key(system)
    source = codegen.render_module(codegen.kernel_spec(system), key)
    path = compiled.entry_path(key)
    path.parent.mkdir(parents=True)
    path.write_text(source[:100])
    assert cache.atomic_write(path, source)
    assert compiled.read_entry(key) == source
    assert sorted(p.name for p in path.parent.iterdir()) == [path.name]


def test_corrupt_entry_is_rebuilt_when_the_integrator_loads(monkeypatch):
    system = duffing()
    key = _key(system)
    source = codegen.render_module(codegen.kernel_spec(system), key)
    path = compiled.entry_path(key)
    path.parent.mkdir(parents=True)
    path.write_text(source[: len(source) // 3])  # an interrupted write
    assert compiled.read_entry(key) is None
    # make sure the module is imported from the cache, not reused from this process
    module_name = f"galerkin_vi_points_{key[:32]}"
    monkeypatch.delitem(sys.modules, module_name, raising=False)
    monkeypatch.delitem(compiled._LOADED, key, raising=False)

    method = gvi.Galerkin(2)
    integrator = gvi.Integrator(system, method, backend="numba")
    try:
        traj = integrator.integrate([1.0], [0.0], h=0.1, n_steps=50)
        assert compiled.read_entry(key) == source  # rebuilt in place
        assert integrator.source == source
    finally:
        sys.modules.pop(module_name, None)  # its file lives in tmp_path
        compiled._LOADED.pop(key, None)
    reference = gvi.Integrator(system, method, backend="numpy").integrate(
        [1.0], [0.0], h=0.1, n_steps=50
    )
    assert np.abs(traj.q - reference.q).max() <= 1e-13  # measured 3.1e-15
    assert np.abs(traj.p - reference.p).max() <= 1e-13  # measured 5.0e-15
    energy = traj.energy()
    assert np.abs(energy - energy[0]).max() < 1e-5  # measured 8.2e-7: a sane Duffing orbit


# ------------------------------------------------------- unsupported functions
def test_unsupported_function_is_rejected_at_construction():
    # besselj has no printer in the kernel language; SymPy differentiates it happily, so
    # the check must happen before any code is generated, for every backend
    with pytest.raises(ValueError, match="besselj"):
        gvi.LagrangianSystem(vx**2 / 2 - sp.besselj(0, x), [x], [vx])


def test_kernel_printer_refuses_unsupported_functions():
    # the printer itself is strict: render_module would fail at generation, not at run time
    assert codegen.unsupported_functions(sp.besselj(0, x) + sp.sin(x)) == ["besselj"]
    assert codegen.unsupported_functions(sp.sin(x) * sp.exp(x)) == []


def test_undefined_function_is_a_value_error_naming_it():
    f = sp.Function("mystery")
    with pytest.raises(ValueError, match=r"mystery\(x\)"):
        gvi.LagrangianSystem(vx**2 / 2 - f(x), [x], [vx])


def test_quarter_powers_of_one_base_share_one_root():
    # g = r^(3/2) of adaptive steps: (x^2 + y^2)^(k/4) for several k, one root computed by
    # two square roots, the powers as products; the values those of pow
    import math

    from galerkin_vi.codegen.source import shared_quarter_roots

    x, y, vx = sp.symbols("x y vx", real=True)
    b = x**2 + y**2
    exprs = [b ** sp.Rational(3, 4) * vx, vx / b ** sp.Rational(7, 4), b ** sp.Rational(-1, 4)]
    rewritten, roots = shared_quarter_roots(exprs)
    assert len(roots) == 1 and roots[0][1] == b
    rho = roots[0][0]
    assert all(not e.has(sp.Rational(1, 4)) for e in rewritten)
    point = {x: 0.3, y: -1.7, vx: 2.5}
    root = math.sqrt(math.sqrt(0.3**2 + 1.7**2))
    for original, new in zip(exprs, rewritten, strict=True):
        want = float(original.subs(point))
        got = float(new.subs(point).subs(rho, root))
        assert abs(got - want) <= 8 * abs(want) * 2.0**-52


def test_negative_powers_of_a_root_share_one_reciprocal_and_square_roots_are_squares():
    # the transformed Lagrangian divides by several powers of one root: one division,
    # the others products; sqrt(b) of a base with a quarter root is that root squared
    import math

    from galerkin_vi.codegen.source import shared_quarter_roots, shared_reciprocals

    x, y, vx = sp.symbols("x y vx", real=True)
    b = x**2 + y**2
    exprs = [
        vx / b ** sp.Rational(3, 2) + b ** sp.Rational(3, 4),
        3 / b ** sp.Rational(7, 4) - vx / sp.sqrt(b),
        b ** sp.Rational(-1, 4) * vx**2,
    ]
    rewritten, roots = shared_quarter_roots(exprs)
    rewritten, reciprocals = shared_reciprocals(rewritten, roots)
    (rho, _), (iota, of) = roots[0], reciprocals[0]
    assert len(roots) == len(reciprocals) == 1 and of == rho
    for e in rewritten:
        assert not e.has(sp.sqrt(b)) and not any(
            p.exp.is_negative for p in e.atoms(sp.Pow) if p.base in (rho, b)
        )
    point = {x: 0.3, y: -1.7, vx: 2.5}
    root = math.sqrt(math.sqrt(0.3**2 + 1.7**2))
    for original, new in zip(exprs, rewritten, strict=True):
        want = float(original.subs(point))
        got = float(new.subs(point).subs({rho: root, iota: 1.0 / root}))
        assert abs(got - want) <= 32 * abs(want) * 2.0**-52
