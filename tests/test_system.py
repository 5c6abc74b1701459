"""LagrangianSystem: validation, structure analysis, Legendre maps, energy, momentum maps.

No integrator is built here, so nothing is compiled.
"""

from __future__ import annotations

from functools import cache

import numpy as np
import pytest
import sympy as sp
from hypothesis import given, settings
from hypothesis import strategies as st

import galerkin_vi as gvi

# ----------------------------------------------------------------- the models
x, y, z, vx, vy, vz, t = sp.symbols("x y z vx vy vz t")
th, vth, g = sp.symbols("theta vtheta g")
a, b, va, vb = sp.symbols("a b va vb")
k = sp.symbols("k")


@cache
def pendulum() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(vth**2 / 2 + g * sp.cos(th), [th], [vth], params={g: 9.81})


@cache
def double_pendulum() -> gvi.LagrangianSystem:
    # theory.md §9: M(q) = [[2, cos(a - b)], [cos(a - b), 1]] is not constant
    L = (2 * va**2 + vb**2 + 2 * sp.cos(a - b) * va * vb) / 2 + 2 * sp.cos(a) + sp.cos(b)
    return gvi.LagrangianSystem(L, [a, b], [va, vb])


def _charged_particle_fields():
    r2 = x**2 + y**2
    A = (sp.Rational(1, 2) + r2 / 8) * sp.Matrix([-y, x, 0])  # B_z = 1 + r^2/2
    phi = r2 / 2 + z**2 / 2 + r2**2 / 20
    return A, phi


@cache
def charged_particle() -> gvi.LagrangianSystem:
    A, phi = _charged_particle_fields()
    vel = sp.Matrix([vx, vy, vz])
    L = vel.dot(vel) / 2 + A.dot(vel) - phi
    return gvi.LagrangianSystem(L, [x, y, z], [vx, vy, vz])


@cache
def driven_oscillator() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(vx**2 / 2 - x**2 / 2 + x * sp.cos(2 * t), [x], [vx], t=t)


@cache
def caldirola_kanai() -> gvi.LagrangianSystem:
    # damped oscillator as a time-dependent Lagrangian: the mass exp(t/5) depends on t
    return gvi.LagrangianSystem(
        sp.exp(t / 5) * (vx**2 - k * x**2) / 2, [x], [vx], t=t, params={k: 2.0}
    )


@cache
def relativistic() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(-sp.sqrt(1 - vx**2) - k * x**2 / 2, [x], [vx], params={k: 1.5})


@cache
def harmonic_2d() -> gvi.LagrangianSystem:
    return gvi.LagrangianSystem(
        (vx**2 + vy**2) / 2 - k * (x**2 + y**2) / 2, [x, y], [vx, vy], params={k: 4.0}
    )


def _closed_form_mass(q):
    c = np.cos(q[..., 0] - q[..., 1])
    M = np.empty(q.shape[:-1] + (2, 2))
    M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1] = 2.0, c, c, 1.0
    return M


# --------------------------------------------------------------- structure
STRUCTURE_CASES = {
    # name: (factory, expected flags)
    "pendulum": (
        pendulum,
        dict(
            autonomous=True,
            zero_Lqv=True,
            constant_mass=True,
            separable=True,
            quadratic=False,
            quadratic_in_v=True,
        ),
    ),
    "double_pendulum": (
        double_pendulum,
        dict(
            autonomous=True,
            zero_Lqv=False,
            constant_mass=False,
            separable=False,
            quadratic=False,
            quadratic_in_v=True,
        ),
    ),
    "charged_particle": (
        charged_particle,
        dict(
            autonomous=True,
            zero_Lqv=False,
            constant_mass=True,
            separable=False,
            quadratic=False,
            quadratic_in_v=True,
        ),
    ),
    "driven_oscillator": (
        driven_oscillator,
        dict(
            autonomous=False, zero_Lqv=True, constant_mass=True, quadratic=True, quadratic_in_v=True
        ),
    ),
    "caldirola_kanai": (
        caldirola_kanai,
        dict(
            autonomous=False,
            zero_Lqv=True,
            constant_mass=False,
            separable=False,
            quadratic_in_v=True,
        ),
    ),
    "relativistic": (
        relativistic,
        dict(
            autonomous=True,
            zero_Lqv=True,
            constant_mass=False,
            separable=False,
            quadratic=False,
            quadratic_in_v=False,
        ),
    ),
    "harmonic_2d": (
        harmonic_2d,
        dict(
            autonomous=True,
            zero_Lqv=True,
            constant_mass=True,
            separable=True,
            quadratic=True,
            quadratic_in_v=True,
        ),
    ),
}


@pytest.mark.parametrize("name", sorted(STRUCTURE_CASES))
def test_structure_flags(name):
    factory, expected = STRUCTURE_CASES[name]
    structure = factory().structure
    found = {flag: getattr(structure, flag) for flag in expected}
    assert found == expected


def test_declared_time_symbol_absent_from_L_is_autonomous():
    system = gvi.LagrangianSystem(vx**2 / 2 - x**2 / 2, [x], [vx], t=t)
    assert system.structure.autonomous
    assert system.t is t


def test_linear_velocity_term_with_constant_coefficient_keeps_Lqv_zero():
    # a * v with constant a is a gauge term: no q-v coupling
    system = gvi.LagrangianSystem(vx**2 / 2 + 3 * vx - x**4, [x], [vx])
    assert system.structure.zero_Lqv
    assert system.structure.separable
    assert not system.structure.quadratic


def test_basic_attributes():
    system = charged_particle()
    assert system.n == 3
    assert system.q == (x, y, z)
    assert system.v == (vx, vy, vz)
    assert system.t is None
    assert system.params == ()
    assert system.parameter_vector().shape == (0,)
    assert len(system.arguments) == 1 + 3 + 3


# --------------------------------------------------------- Legendre transform
def test_legendre_double_pendulum_closed_form():
    system = double_pendulum()
    rng = np.random.default_rng(0)
    q = rng.uniform(-3, 3, (20, 2))
    v = rng.uniform(-3, 3, (20, 2))
    p = system.legendre(q, v)
    expected = np.einsum("kab,kb->ka", _closed_form_mass(q), v)
    np.testing.assert_allclose(p, expected, rtol=0, atol=1e-14)  # measured 0


def test_legendre_charged_particle_closed_form():
    system = charged_particle()
    q = np.array([0.7, -0.4, 0.2])
    v = np.array([0.1, 0.5, -0.3])
    r2 = q[0] ** 2 + q[1] ** 2
    A = (0.5 + r2 / 8) * np.array([-q[1], q[0], 0.0])
    np.testing.assert_allclose(system.legendre(q, v), v + A, rtol=0, atol=1e-15)  # measured 0


finite = st.floats(-3, 3, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(
    q=st.tuples(finite, finite),
    v=st.tuples(finite, finite),
)
def test_legendre_round_trip_double_pendulum(q, v):
    system = double_pendulum()
    q, v = np.array(q), np.array(v)
    p = system.legendre(q, v)
    np.testing.assert_allclose(
        system.inverse_legendre(q, p), v, rtol=0, atol=1e-13
    )  # max 1.3e-15 measured


@settings(max_examples=25, deadline=None)
@given(
    q=st.tuples(finite, finite, finite),
    v=st.tuples(finite, finite, finite),
)
def test_legendre_round_trip_charged_particle(q, v):
    system = charged_particle()
    q, v = np.array(q), np.array(v)
    p = system.legendre(q, v)
    np.testing.assert_allclose(system.inverse_legendre(q, p), v, rtol=0, atol=1e-13)  # max 8.9e-16


def test_legendre_round_trip_time_dependent_mass_uses_t():
    system = caldirola_kanai()
    q, v = np.array([0.3]), np.array([-0.8])
    for time in (0.0, 1.0, 7.5):
        p = system.legendre(q, v, t=time)
        np.testing.assert_allclose(p, np.exp(time / 5) * v, rtol=1e-15)  # measured 0
        np.testing.assert_allclose(system.inverse_legendre(q, p, t=time), v, rtol=1e-14)


def test_relativistic_legendre_round_trip_moderate_speeds():
    # non-quadratic in v: the inverse needs Newton iterations, not one linear solve
    system = relativistic()
    v = np.linspace(-0.65, 0.65, 27)[:, None]
    q = np.full_like(v, 0.4)
    p = system.legendre(q, v)
    np.testing.assert_allclose(p, v / np.sqrt(1 - v**2), rtol=1e-15, atol=1e-15)
    np.testing.assert_allclose(system.inverse_legendre(q, p), v, rtol=0, atol=1e-14)  # measured 0


@settings(max_examples=25, deadline=None)
@given(v=st.floats(-0.95, 0.95))
def test_relativistic_legendre_round_trip_high_speeds(v):
    system = relativistic()
    q = np.array([0.4])
    p = system.legendre(q, np.array([v]))
    np.testing.assert_allclose(system.inverse_legendre(q, p), [v], rtol=0, atol=1e-13)


def test_relativistic_particle_in_the_plane_is_regular():
    system = gvi.LagrangianSystem(-sp.sqrt(1 - vx**2 - vy**2), [x, y], [vx, vy])
    v = np.array([0.3, -0.4])
    p = system.legendre(np.zeros(2), v)
    np.testing.assert_allclose(system.inverse_legendre(np.zeros(2), p), v, rtol=0, atol=1e-14)


# ------------------------------------------------------------------ energy
def test_hamiltonian_pendulum_closed_form():
    system = pendulum()
    q = np.linspace(-3, 3, 11)[:, None]
    p = np.linspace(-2, 5, 11)[:, None]
    H = system.hamiltonian(q, p)
    assert H.shape == (11,)
    np.testing.assert_allclose(
        H, p[:, 0] ** 2 / 2 - 9.81 * np.cos(q[:, 0]), rtol=1e-15, atol=1e-14
    )  # measured 8.9e-16


def test_hamiltonian_double_pendulum_closed_form():
    system = double_pendulum()
    rng = np.random.default_rng(1)
    q = rng.uniform(-3, 3, (30, 2))
    p = rng.uniform(-3, 3, (30, 2))
    Minv_p = np.linalg.solve(_closed_form_mass(q), p[..., None])[..., 0]
    expected = 0.5 * np.sum(p * Minv_p, axis=-1) - 2 * np.cos(q[:, 0]) - np.cos(q[:, 1])
    np.testing.assert_allclose(
        system.hamiltonian(q, p), expected, rtol=1e-13, atol=1e-13
    )  # measured 5.3e-15 (|H| <= 14)


def test_hamiltonian_charged_particle_closed_form():
    # H = |p - A|^2 / 2 + phi (theory.md §5)
    system = charged_particle()
    rng = np.random.default_rng(2)
    q = rng.uniform(-2, 2, (10, 3))
    p = rng.uniform(-2, 2, (10, 3))
    r2 = q[:, 0] ** 2 + q[:, 1] ** 2
    A = (0.5 + r2 / 8)[:, None] * np.stack([-q[:, 1], q[:, 0], 0 * r2], axis=-1)
    phi = r2 / 2 + q[:, 2] ** 2 / 2 + r2**2 / 20
    expected = 0.5 * np.sum((p - A) ** 2, axis=-1) + phi
    np.testing.assert_allclose(
        system.hamiltonian(q, p), expected, rtol=1e-14, atol=1e-14
    )  # measured 8.9e-16


def test_hamiltonian_time_dependent_uses_t():
    system = driven_oscillator()
    q, p = np.array([0.7]), np.array([-0.2])
    for time in (0.0, 0.4, 2.0):
        expected = p[0] ** 2 / 2 + q[0] ** 2 / 2 - q[0] * np.cos(2 * time)
        assert system.hamiltonian(q, p, t=time) == pytest.approx(expected, rel=1e-15, abs=1e-15)


def test_hamiltonian_relativistic_closed_form():
    system = relativistic()
    p = np.linspace(-0.9, 0.9, 7)[:, None]
    q = np.linspace(-1, 1, 7)[:, None]
    expected = np.sqrt(1 + p[:, 0] ** 2) + 1.5 * q[:, 0] ** 2 / 2
    np.testing.assert_allclose(system.hamiltonian(q, p), expected, rtol=1e-14)  # measured 2.2e-16


def test_hamiltonian_params_override():
    system = harmonic_2d()
    q, p = np.array([1.0, 2.0]), np.array([0.5, 0.0])
    assert system.hamiltonian(q, p) == pytest.approx(0.125 + 4.0 * 5 / 2, rel=1e-15)
    assert system.hamiltonian(q, p, params={k: 1.0}) == pytest.approx(0.125 + 5 / 2, rel=1e-15)
    assert system.hamiltonian(q, p, params={"k": 0.0}) == pytest.approx(0.125, rel=1e-15)


# ----------------------------------------------------------- momentum maps
def test_momentum_map_rotation_charged_particle():
    system = charged_particle()
    J = system.momentum_map([-y, x, 0])
    rng = np.random.default_rng(3)
    q = rng.normal(size=(8, 3))
    p = rng.normal(size=(8, 3))
    values = J(q, p)
    assert values.shape == (8,)
    np.testing.assert_allclose(
        values, q[:, 0] * p[:, 1] - q[:, 1] * p[:, 0], rtol=1e-15, atol=1e-15
    )  # measured 0
    assert J(q[0], p[0]) == pytest.approx(q[0, 0] * p[0, 1] - q[0, 1] * p[0, 0], rel=1e-15)


def test_momentum_map_translation_and_parameters():
    system = harmonic_2d()
    np.testing.assert_allclose(
        system.momentum_map([1, 1])([[0.0, 0.0], [5.0, 6.0]], [[1.0, 2.0], [-1.0, 4.0]]),
        [3.0, 3.0],
    )
    # a generator may use parameters; their default values are used
    np.testing.assert_allclose(
        system.momentum_map([k * y, 0])([[1.0, 2.0]], [[3.0, 5.0]]), [4.0 * 2.0 * 3.0]
    )


@pytest.mark.parametrize(
    ("xi", "match"),
    [
        ([-y, x], "3 components"),
        ([-y, x, 0, 0], "3 components"),
        ([-vy, vx, 0], "undeclared symbols: vx, vy"),
        ([-y, x, t], "undeclared symbols: t"),
        ([-y, x, sp.Symbol("w")], "undeclared symbols: w"),
    ],
)
def test_momentum_map_bad_generator(xi, match):
    with pytest.raises(ValueError, match=match):
        charged_particle().momentum_map(xi)


# ------------------------------------------------------------- parameters
def test_parameter_vector_defaults_and_overrides():
    c = sp.Symbol("c")
    system = gvi.LagrangianSystem(
        vx**2 / 2 - k * x**2 / 2 - c * x**4, [x], [vx], params={k: 2.0, c: 0.25}
    )
    np.testing.assert_array_equal(system.parameter_vector(), [2.0, 0.25])
    np.testing.assert_array_equal(system.parameter_vector({c: 3}), [2.0, 3.0])
    np.testing.assert_array_equal(system.parameter_vector({"k": -1.5}), [-1.5, 0.25])
    np.testing.assert_array_equal(system.parameter_vector({k: 1.0, "c": 0.0}), [1.0, 0.0])
    # overriding does not change the defaults
    np.testing.assert_array_equal(system.parameter_vector(), [2.0, 0.25])


@pytest.mark.parametrize(
    ("override", "error", "match"),
    [
        ({"kk": 1.0}, ValueError, "kk is not a declared parameter"),
        ({x: 1.0}, ValueError, "x is not a declared parameter"),
        ({k: float("nan")}, ValueError, r"params\[k\] must be finite"),
        ({"k": float("inf")}, ValueError, r"params\[k\] must be finite"),
        ({k: "abc"}, TypeError, r"params\[k\] must be a real number"),
    ],
)
def test_parameter_vector_bad_override(override, error, match):
    with pytest.raises(error, match=match):
        harmonic_2d().parameter_vector(override)


# --------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    ("build", "error", "match"),
    [
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 - k * x**2, [x], [vx]),
            ValueError,
            "undeclared symbols: k",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 - t * x**2, [x], [vx]),
            ValueError,
            "undeclared symbols: t.*pass t=",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 + vy**2 / 2, [x], [vx]),
            ValueError,
            "undeclared symbols: vy",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2, [x, y], [vx]),
            ValueError,
            r"same length.*len\(q\)=2, len\(v\)=1",
        ),
        (lambda: gvi.LagrangianSystem(vx**2 / 2, [], []), ValueError, "at least one symbol"),
        (
            lambda: gvi.LagrangianSystem("vx**2/2", [x], [vx]),
            TypeError,
            "L must be a SymPy expression, got str",
        ),
        (
            lambda: gvi.LagrangianSystem(lambda q, v: v**2 / 2, [x], [vx]),
            TypeError,
            "L must be a SymPy expression, got function",
        ),
        (
            lambda: gvi.LagrangianSystem(sp.Matrix([vx**2]), [x], [vx]),
            TypeError,
            "L must be a SymPy expression",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2, ["x"], [vx]),
            TypeError,
            "q must contain sympy.Symbol only",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2, [x], [vx**2]),
            TypeError,
            "v must contain sympy.Symbol only",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2, "x", [vx]),
            TypeError,
            "q must be a sequence of sympy.Symbol",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2, [x], [vx], t="t"),
            TypeError,
            "t must be a sympy.Symbol",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 + vy**2 / 2, [x, x], [vx, vy]),
            ValueError,
            r"distinct.*\[x\] repeat",
        ),
        (lambda: gvi.LagrangianSystem(vx**2 / 2, [x], [x]), ValueError, "distinct"),
        (lambda: gvi.LagrangianSystem(vx**2 / 2, [x], [vx], t=x), ValueError, "distinct"),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2, [x], [vx], params={vx: 1.0}),
            ValueError,
            r"distinct.*\[vx\] repeat",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 - k * x**2, [x], [vx], params={k: float("nan")}),
            ValueError,
            r"params\[k\] must be finite",
        ),
        (
            lambda: gvi.LagrangianSystem(
                vx**2 / 2 - k * x**2, [x], [vx], params={k: float("-inf")}
            ),
            ValueError,
            r"params\[k\] must be finite",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 - k * x**2, [x], [vx], params={k: sp.nan}),
            ValueError,
            r"params\[k\] must be finite",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 - k * x**2, [x], [vx], params={k: "one"}),
            TypeError,
            r"params\[k\] must be a real number",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 - k * x**2, [x], [vx], params={"k": 1.0}),
            TypeError,
            "params keys must be sympy.Symbol",
        ),
        (
            lambda: gvi.LagrangianSystem(vx**2 / 2 + sp.oo, [x], [vx]),
            ValueError,
            "infinite or undefined",
        ),
    ],
    ids=lambda v: None,
)
def test_bad_input(build, error, match):
    with pytest.raises(error, match=match):
        build()


@pytest.mark.parametrize(
    "L",
    [
        (vx + vy) ** 2 / 2 - x**2 - y**2,  # rank-one mass matrix
        vx**2 / 2 - x**2 - y**2,  # y has no kinetic term
        vx * vy - x**2 - y**2 + (vx - vy) ** 2 / 2 - (vx**2 + vy**2) / 2,  # cancels to 0
        x * vx + y * vy - x**2,  # linear in v: first-order Lagrangian
        vx**2 / 2 + 1e-14 * vy**2 / 2 - x**2,  # constant diagonal, numerically singular
    ],
)
def test_singular_mass_matrix_is_degenerate(L):
    with pytest.raises(gvi.DegenerateLagrangianError, match="singular"):
        gvi.LagrangianSystem(L, [x, y], [vx, vy])


def test_a_constant_diagonal_mass_is_decided_without_sampling(monkeypatch):
    # its entries decide; L_vv is never compiled for the check
    from galerkin_vi.model.system import LagrangianSystem

    def refuse(self, name, *args):
        raise AssertionError(f"evaluated {name}")

    monkeypatch.setattr(LagrangianSystem, "evaluate", refuse)
    system = gvi.LagrangianSystem(3 * vx**2 / 2 + 1e-6 * vy**2 / 2 - x**2 * y**2, [x, y], [vx, vy])
    assert system.structure.constant_mass


def test_degenerate_error_is_a_value_error():
    assert issubclass(gvi.DegenerateLagrangianError, ValueError)


def test_inverse_legendre_at_a_singular_state_raises():
    # L_vv = 1 + q^2 - 2 = q^2 - 1 is regular at random points but singular at q = +-1
    system = gvi.LagrangianSystem((x**2 - 1) * vx**2 / 2, [x], [vx])
    with pytest.raises(gvi.DegenerateLagrangianError, match="singular"):
        system.inverse_legendre([1.0], [0.5])


def test_inverse_legendre_outside_the_range_is_a_clear_error():
    # L = log cosh v: p = tanh v lies in (-1, 1); p = 2 has no velocity
    system = gvi.LagrangianSystem(sp.log(sp.cosh(vx)) - x**2 / 2, [x], [vx])
    np.testing.assert_allclose(
        system.inverse_legendre([0.0], [0.5]), [np.arctanh(0.5)], rtol=0, atol=1e-14
    )
    with pytest.raises(ValueError, match="range of the Legendre transform"):
        system.inverse_legendre([0.0], [2.0])


def test_trajectory_momentum_uses_the_runs_parameters():
    # a generator that depends on a parameter: J = <p, (a, 0)> = a p_x
    x, y, vx, vy, a = sp.symbols("x y vx vy a")
    system = gvi.LagrangianSystem((vx**2 + vy**2) / 2 - y**2 / 2, [x, y], [vx, vy], params={a: 1.0})
    traj = gvi.Integrator(system, backend="numpy").integrate(
        [0.0, 1.0], [0.5, 0.0], h=0.1, n_steps=3, params={a: 3.0}
    )
    np.testing.assert_allclose(traj.momentum([a, 0]), 3.0 * traj.p[:, 0], rtol=1e-15)
