"""The loops generated per system (``galerkin_vi.codegen.explicit_steps`` and
``stage_steps``) and per system and method (``method_steps``): the shared loops' states
bit for bit, their failures and hand-overs, which systems get them,
``specialize="system"``, their cache entries, and their text run uncompiled."""

from __future__ import annotations

import dataclasses
import pickle

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi import codegen
from galerkin_vi.codegen import compiled
from galerkin_vi.codegen.explicit_steps import EXPLICIT_UNROLLED
from galerkin_vi.codegen.method_steps import METHOD_UNROLLED
from galerkin_vi.codegen.spec import LARGE
from galerkin_vi.method.stage_form import separable_tables
from galerkin_vi.problems.chains import spring_chain
from galerkin_vi.problems.forced import driven_oscillator
from galerkin_vi.problems.gravitation import kepler, n_body
from galerkin_vi.problems.mechanics import henon_heiles, pendulum
from galerkin_vi.run import segment
from galerkin_vi.run.segment import substeps
from galerkin_vi.run.smooth import integrate_smooth


def _coupled_masses() -> gvi.LagrangianSystem:
    # a constant mass matrix that is not diagonal, and a parameter in the force
    x, y, vx, vy, k = sp.symbols("x y vx vy k")
    kinetic = (2 * vx**2 + 2 * vx * vy + 3 * vy**2) / 2
    return gvi.LagrangianSystem(
        kinetic - k * (x**2 + y**2) / 2 - x**4 / 4 - (x - y) ** 4 / 8, [x, y], [vx, vy],
        params={k: 1.5},
    )  # fmt: skip


def _shared_factors() -> gvi.LagrangianSystem:
    # parameter products shared by the mass and the force: the common-subexpression form
    # of the point functions groups them, and the generated loops must round as they do
    q, v, m, c, g = sp.symbols("q v m c g")
    return gvi.LagrangianSystem(
        m * c * v**2 / 2 + m * g * c * sp.cos(q) + m * c * g * q**3 / 50, [q], [v],
        params={m: 1.3, c: 0.7, g: 2.9},
    )  # fmt: skip


def _angle_and_length() -> gvi.LagrangianSystem:
    # one angle, one length: the shared explicit loop compensates every coordinate then
    x, y, vx, vy = sp.symbols("x y vx vy")
    L = (vx**2 + vy**2) / 2 + sp.cos(x) - y**2 / 2 + y * sp.cos(x) / 10
    return gvi.LagrangianSystem(L, [x, y], [vx, vy])


def _oscillators(n: int) -> gvi.LagrangianSystem:
    # n uncoupled anharmonic oscillators: few second derivatives for n coordinates
    qs, vs = sp.symbols(f"q0:{n}"), sp.symbols(f"v0:{n}")
    L = sum(w**2 / 2 - x**2 / 2 - x**4 / 4 for x, w in zip(qs, vs, strict=True))
    return gvi.LagrangianSystem(L, list(qs), list(vs))


def _quartic() -> gvi.LagrangianSystem:
    q, v = sp.symbols("q v")
    return gvi.LagrangianSystem(v**2 / 2 - q**4, [q], [v])


CASES = {
    "henon_heiles": (henon_heiles().system, henon_heiles().q0, henon_heiles().v0),
    "kepler": (kepler(0.6).system, kepler(0.6).q0, kepler(0.6).v0),
    # v0 = 3: the pendulum goes over the top, so its angle wraps every turn
    "pendulum_rotating": (pendulum().system, [1.5], [3.0]),
    "driven_oscillator": (driven_oscillator().system, [1.0], [0.2]),
    "full_mass": (_coupled_masses(), [0.3, -0.2], [0.1, 0.4]),
    "shared_factors": (_shared_factors(), [0.4], [2.5]),
    "angle_and_length": (_angle_and_length(), [0.5, 0.2], [3.0, 0.1]),
}


def _shared(integrator: gvi.Integrator):
    """The run spec of ``integrator`` with the shared loops."""
    return dataclasses.replace(integrator.run_spec, explicit_steps=None, stage_steps=None)


def _hand_overs(monkeypatch) -> list[tuple[int, str]]:
    """(step, path) of each hand-over of a generated loop to a shared one, as they happen."""
    handed = []
    original = segment.continue_from_last_row

    def spy(spec, run, out, result, path):
        handed.append((result.steps, path))
        return original(spec, run, out, result, path)

    monkeypatch.setattr(segment, "continue_from_last_row", spy)
    return handed


def _driven_pendulum() -> gvi.LagrangianSystem:
    # separable, not quadratic, and time-dependent: the stage-form path with t in the force
    q, v, t = sp.symbols("q v t")
    return gvi.LagrangianSystem(v**2 / 2 + sp.cos(q) + q * sp.cos(2 * t) / 3, [q], [v], t=t)


@pytest.mark.parametrize("name", sorted(CASES))
@pytest.mark.parametrize(("h", "save_every"), [(0.05, 1), (0.05, 7), (-0.03, 5)])
def test_the_generated_loop_takes_the_shared_loops_steps_bit_for_bit(name, h, save_every):
    system, q0, v0 = CASES[name]
    integrator = gvi.Integrator(system, gvi.Composition(6))
    assert integrator.run_spec.explicit_steps is not None
    run = dict(h=h, n_steps=400, save_every=save_every)
    generated = integrator.integrate(q0, v0, **run)
    shared = integrate_smooth(_shared(integrator), q0, v0, None, **run)
    assert generated.success and len(generated) == len(shared) == -(-400 // save_every) + 1
    for field in ("t", "q", "p"):
        np.testing.assert_array_equal(getattr(generated, field), getattr(shared, field))
    if name in ("pendulum_rotating", "angle_and_length"):
        # many turns, and the reduced angles those of the shared loop's wraps
        assert abs(generated.q[-1, 0]) > 3 * np.pi
        np.testing.assert_array_equal(generated.q_reduced, shared.q_reduced)
        assert np.all(np.abs(generated.q_reduced) <= np.pi)


def test_stormer_verlet_itself_runs_the_generated_loop():
    system, q0, v0 = CASES["kepler"]
    integrator = gvi.Integrator(system, gvi.Galerkin(1, gvi.gauss_lobatto(2)))
    assert integrator.kernel_path == "explicit"
    assert integrator.run_spec.explicit_steps is not None
    generated = integrator.integrate(q0, v0, h=0.01, n_steps=1000, save_every=100)
    shared = integrate_smooth(_shared(integrator), q0, v0, None, h=0.01, n_steps=1000,
                              save_every=100)  # fmt: skip
    np.testing.assert_array_equal(generated.q, shared.q)
    np.testing.assert_array_equal(generated.p, shared.p)


@pytest.mark.parametrize("save_every", [1, 3, 1000])
def test_a_step_that_overflows_keeps_the_same_states_as_the_shared_loop(save_every):
    # V = q^4 with a step far past stability: |q| squares at every step until it overflows
    integrator = gvi.Integrator(_quartic(), gvi.Composition(4))
    run = dict(h=2.0, n_steps=1000, save_every=save_every, on_failure="warn")
    with pytest.warns(gvi.RunFailureWarning):
        generated = integrator.integrate([1.0], [0.0], **run)
    with pytest.warns(gvi.RunFailureWarning):
        shared = integrate_smooth(_shared(integrator), [1.0], [0.0], None, **run)
    assert not generated.success and generated.status == shared.status
    assert generated.n_steps == shared.n_steps < 1000
    assert generated.message == shared.message
    np.testing.assert_array_equal(generated.t, shared.t)
    np.testing.assert_array_equal(generated.q, shared.q)
    assert np.isfinite(generated.q).all() and np.isfinite(generated.p).all()


def test_which_systems_get_a_generated_loop():
    def has_steps(system) -> bool:
        return codegen.kernel_spec(system).generated_loops

    assert has_steps(henon_heiles().system) and has_steps(_coupled_masses())
    q, v, t = sp.symbols("q v t")
    # a gyroscopic term a(t) v: the shared loop (its drift averages a over the sub-step)
    gauge = gvi.LagrangianSystem(v**2 / 2 + sp.cos(t) * v - q**2 / 2, [q], [v], t=t)
    assert not has_steps(gauge)
    # a mass that varies: no explicit path at all
    assert not has_steps(gvi.LagrangianSystem((1 + q**2) * v**2 / 2 - q**2 / 2, [q], [v]))
    # too many coordinates to be scalars: the force dominates, the shared loop runs them
    assert has_steps(_oscillators(EXPLICIT_UNROLLED))
    many = gvi.Integrator(_oscillators(EXPLICIT_UNROLLED + 1), gvi.Composition(4))
    assert many.run_spec.explicit_steps is None
    # point functions generated in parts (more second derivatives than LARGE), which the
    # loops would have to copy: none, and the module holds none
    chain = spring_chain(EXPLICIT_UNROLLED, beta=0.5).system
    assert len(codegen.kernel_spec(chain).hessian_entries) > LARGE and not has_steps(chain)
    assert "def explicit_steps" not in gvi.Integrator(chain, gvi.Composition(4)).source
    assert "def explicit_steps" in gvi.Integrator(_oscillators(3), gvi.Composition(4)).source
    # the tangent map keeps the shared loop (whose states it carries bit for bit)
    small = gvi.Integrator(henon_heiles().system, gvi.Composition(4))
    assert small.tangent_run_spec.explicit_steps is None


FIVE_BODIES = (1.0, 0.5, 0.3, 0.2, 0.1)


@pytest.mark.parametrize("method", [gvi.Galerkin(1), gvi.Composition(4)], ids=["verlet", "c4"])
@pytest.mark.parametrize(("h", "save_every"), [(0.01, 3), (-0.02, 1)])
def test_a_small_system_of_repeated_terms_runs_its_unrolled_pair_force_on_request(
    method, h, save_every
):
    # five softened bodies: a pair potential of ten instances (a scatter loop), 10 coordinates
    problem = n_body(masses=FIVE_BODIES)
    system = problem.system
    spec = codegen.kernel_spec(system)
    assert spec.repeats and spec.repeated_loop and not spec.generated_loops
    assert gvi.Integrator(system, method).run_spec.explicit_steps is None
    integrator = gvi.Integrator(system, method, specialize="system")
    assert integrator.run_spec.explicit_steps.py_func.__name__ == "repeated_explicit_steps"
    run = dict(h=h, n_steps=400, save_every=save_every)
    generated = integrator.integrate(problem.q0, problem.v0, **run)
    shared = integrate_smooth(_shared(integrator), problem.q0, problem.v0, None, **run)
    for field in ("t", "q", "p"):
        np.testing.assert_array_equal(getattr(generated, field), getattr(shared, field))


def test_only_repeated_terms_alone_get_the_unrolled_pair_force():
    system = n_body(masses=FIVE_BODIES).system
    assert codegen.kernel_spec(system).repeated_loop
    # an external field beside the pairs: L_q is not the scatter loops' alone
    x0 = system.q[0]
    params = dict(zip(system.params, system.param_defaults, strict=True))
    field = gvi.LagrangianSystem(system.L - x0**2 / 2, system.q, system.v, params=params)
    assert codegen.kernel_spec(field).repeats and not codegen.kernel_spec(field).repeated_loop
    # a repeated gyroscopic term a(t) . v (a scatter group of its own): the drift of the
    # shared loop averages a over the sub-step, the generated loop has no such term
    t = sp.Symbol("t")
    gauge = sum(sp.cos(t) * w / 10 for w in system.v)
    gyroscopic = gvi.LagrangianSystem(system.L + gauge, system.q, system.v, params=params, t=t)
    spec = codegen.kernel_spec(gyroscopic)
    assert any(array == "Lv" for group in spec.repeats for array, _ in group.entries)
    assert not spec.repeated_loop
    chosen = gvi.Integrator(gyroscopic, gvi.Galerkin(1), specialize="system")
    assert chosen.run_spec.explicit_steps is None
    # too many coordinates: the shared loop
    many = n_body(masses=(1.0,) * 13).system
    assert codegen.kernel_spec(many).repeats and not codegen.kernel_spec(many).repeated_loop


def test_the_generated_text_runs_uncompiled_on_numpy_arrays():
    system, q0, v0 = CASES["full_mass"]
    source = codegen.render_module(codegen.kernel_spec(system), "key")
    namespace: dict = {}
    exec(compile(source, "<generated>", "exec"), namespace)
    integrator = gvi.Integrator(system, gvi.Composition(4))
    compiled = integrator.integrate(q0, v0, h=0.1, n_steps=20, save_every=4)
    prm = system.parameter_vector(None)
    _, inverse, _ = integrator.run_spec.legendre.inverse_mass(prm)
    p0 = compiled.p[0]
    t_out, q_out, p_out, turns = np.zeros(6), np.zeros((6, 2)), np.zeros((6, 2)), np.zeros((1, 2))
    status, steps, saved, _, _ = namespace["explicit_steps"](
        np.array(q0, float), p0, 0.0, 0.1, 20, 4, prm, inverse,
        *substeps(gvi.Composition(4)), t_out, q_out, p_out, turns,
    )  # fmt: skip
    assert (status, steps, saved) == (0, 20, 6)
    # Python's float arithmetic is the compiled code's, operation for operation
    np.testing.assert_array_equal(t_out, compiled.t)
    np.testing.assert_array_equal(q_out, compiled.q)
    np.testing.assert_array_equal(p_out, compiled.p)


def test_an_integrator_with_a_generated_loop_pickles_before_and_after_use():
    system, q0, v0 = CASES["henon_heiles"]
    integrator = gvi.Integrator(system, gvi.Composition(8))
    fresh = pickle.loads(pickle.dumps(integrator))
    first = integrator.integrate(q0, v0, h=0.1, n_steps=50)
    again = pickle.loads(pickle.dumps(integrator)).integrate(q0, v0, h=0.1, n_steps=50)
    np.testing.assert_array_equal(first.q, again.q)
    np.testing.assert_array_equal(first.q, fresh.integrate(q0, v0, h=0.1, n_steps=50).q)


def test_members_on_threads_run_the_generated_loop():
    system, q0, v0 = CASES["kepler"]
    integrator = gvi.Integrator(system, gvi.Composition(6))
    starts = np.array([q0, q0, q0], dtype=float) * np.array([[1.0], [1.1], [0.9]])
    many = integrator.integrate_many(starts, np.array([v0] * 3), h=0.05, n_steps=200, workers=3)
    for i in range(3):
        one = integrate_smooth(_shared(integrator), starts[i], v0, None, h=0.05, n_steps=200)
        np.testing.assert_array_equal(many[i].q, one.q)


# ------------------------------------------------------------ the stage-form loop
STAGE_CASES = {
    "henon_heiles": CASES["henon_heiles"],
    "kepler": CASES["kepler"],
    "pendulum_rotating": CASES["pendulum_rotating"],
    "driven_pendulum": (_driven_pendulum(), [0.5], [0.4]),
    "shared_factors": CASES["shared_factors"],
    "angle_and_length": CASES["angle_and_length"],
}
METHODS = {
    "gauss2": gvi.Galerkin(2, gvi.gauss_legendre(2)),
    "gauss4": gvi.Galerkin(4, gvi.gauss_legendre(4)),
    "lobatto3": gvi.Galerkin(2),
    "lobatto5": gvi.Galerkin(4),
}


# every system with one Gauss and one Lobatto method; the larger methods on two systems
# (each system and method is a loop of its own: a second of compilation)
STAGE_PAIRS = [(name, method) for name in sorted(STAGE_CASES) for method in ("gauss2", "lobatto3")]
STAGE_PAIRS += [(name, method) for name in ("kepler", "driven_pendulum")
                for method in ("gauss4", "lobatto5")]  # fmt: skip


@pytest.mark.parametrize(("name", "method"), STAGE_PAIRS)
@pytest.mark.parametrize(("h", "save_every"), [(0.05, 1), (-0.04, 6)])
def test_the_generated_stage_loop_takes_the_shared_loops_steps_and_sweeps(
    name, method, h, save_every, monkeypatch
):
    system, q0, v0 = STAGE_CASES[name]
    integrator = gvi.Integrator(system, METHODS[method], specialize="system")
    assert integrator.kernel_path == "separable"
    assert integrator.run_spec.stage_steps is not None
    handed = []
    monkeypatch.setattr(segment, "continue_from_last_row", lambda *args: handed.append(args))
    run = dict(h=h, n_steps=300, save_every=save_every)
    generated = integrator.integrate(q0, v0, **run)
    assert not handed  # steps this small converge by the fixed point alone
    shared = integrate_smooth(_shared(integrator), q0, v0, None, **run)
    for field in ("t", "q", "p", "newton_iterations"):
        np.testing.assert_array_equal(getattr(generated, field), getattr(shared, field))
    assert generated.total_newton_iterations == shared.total_newton_iterations
    assert generated.max_residual == shared.max_residual
    if name in ("pendulum_rotating", "angle_and_length"):
        np.testing.assert_array_equal(generated.q_reduced, shared.q_reduced)


def _outputs(n_steps: int, save_every: int, n: int) -> list[np.ndarray]:
    rows = -(-n_steps // save_every) + 2
    return [
        np.zeros(rows), np.zeros((rows, n)), np.zeros((rows, n)), np.zeros((rows, n)),
        np.zeros(rows - 1, dtype=np.uint8), np.zeros(1, dtype=np.int64),
    ]  # fmt: skip


@pytest.mark.parametrize("method", ["gauss2", "lobatto5"])
@pytest.mark.parametrize(
    ("q0", "h", "n_steps", "save_every"),
    [(2.0, 0.01, 3000, 7), (2.0, 0.01, 3000, 4), (2.6, 0.2, 10, 3)],
)
def test_a_methods_loop_fails_and_hands_over_as_the_systems_loop(
    method, q0, h, n_steps, save_every
):
    # V = -exp(q^2)/2 throws q outwards ever faster: the fixed point gives up (status 1)
    # or the state overflows (status 3), mid-row or at a row's end; both generated loops
    # called alike return the same tuple and write the same rows and sweep counts
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + sp.exp(q**2) / 2, [q], [v])
    integrator = gvi.Integrator(system, METHODS[method], specialize="system")
    assert _loop_name(integrator) == "method_steps"
    points = compiled.load_point_functions(codegen.kernel_spec(system))
    _, _, after = integrator.run_spec.loop_parts()
    results = []
    for loop in (points.generated_loop("stage_steps"), integrator.run_spec.stage_steps):
        out = _outputs(n_steps, save_every, 1)
        start = (np.array([q0]), np.array([0.0]), np.array([0.0]), 0.0, h, n_steps, save_every)
        status = loop(*start, system.parameter_vector(None), *after, *out)
        results.append((status, out))
    (first, rows), (second, again) = results
    assert first[0] != 0 and first[1] < n_steps  # the run does not get through
    assert first == second
    for a, b in zip(rows, again, strict=True):
        np.testing.assert_array_equal(a, b)


def _loop_name(integrator: gvi.Integrator) -> str:
    return integrator.run_spec.stage_steps.py_func.__name__


def test_small_systems_get_a_loop_written_for_the_method_and_large_ones_the_systems():
    # Kepler with Gauss(4): 4 implicit points x 2 coordinates; eight oscillators with
    # Gauss(4): 32 unknowns, past METHOD_UNROLLED, run the system's own loop
    small = gvi.Integrator(STAGE_CASES["kepler"][0], METHODS["gauss4"], specialize="system")
    assert _loop_name(small) == "method_steps"
    n = METHOD_UNROLLED // 4 + 1
    system = _oscillators(n)
    large = gvi.Integrator(system, METHODS["gauss4"], specialize="system")
    assert _loop_name(large) == "stage_steps"
    narrow = gvi.Integrator(system, METHODS["gauss2"], specialize="system")
    assert _loop_name(narrow) == ("method_steps" if 2 * n <= METHOD_UNROLLED else "stage_steps")
    q0, v0 = np.linspace(0.2, 0.9, n), np.linspace(-0.3, 0.3, n)
    run = dict(h=0.05, n_steps=200, save_every=7)
    for integrator in (large, narrow):
        generated = integrator.integrate(q0, v0, **run)
        shared = integrate_smooth(_shared(integrator), q0, v0, None, **run)
        np.testing.assert_array_equal(generated.q, shared.q)
        np.testing.assert_array_equal(generated.newton_iterations, shared.newton_iterations)


def test_the_systems_loop_starts_from_two_steps_as_the_shared_loop_does():
    # Gauss(2) extrapolates the forces of the last two steps (a (u, 3 r) table): with
    # 2 x 13 unknowns, past METHOD_UNROLLED, the system's own loop runs it, and its
    # states and sweeps are the shared loop's bit for bit
    n = METHOD_UNROLLED // 2 + 1
    system = _oscillators(n)
    integrator = gvi.Integrator(system, METHODS["gauss2"], specialize="system")
    assert _loop_name(integrator) == "stage_steps"
    assert separable_tables(METHODS["gauss2"]).force_extrapolation.shape == (2, 3 * 2)
    q0, v0 = np.linspace(0.2, 0.9, n), np.linspace(-0.3, 0.3, n)
    run = dict(h=0.05, n_steps=200, save_every=7)
    generated = integrator.integrate(q0, v0, **run)
    shared = integrate_smooth(_shared(integrator), q0, v0, None, **run)
    np.testing.assert_array_equal(generated.q, shared.q)
    np.testing.assert_array_equal(generated.p, shared.p)
    np.testing.assert_array_equal(generated.newton_iterations, shared.newton_iterations)


def test_each_method_is_a_cache_entry_of_its_own_and_its_key_follows_the_generator(
    monkeypatch,
):

    system, q0, v0 = STAGE_CASES["henon_heiles"]
    first = gvi.Integrator(system, METHODS["gauss2"], specialize="system")
    again = gvi.Integrator(system, gvi.Galerkin(2, gvi.gauss_legendre(2)), specialize="system")
    other = gvi.Integrator(system, METHODS["lobatto3"], specialize="system")
    assert again.run_spec.stage_steps is first.run_spec.stage_steps
    assert other.run_spec.stage_steps is not first.run_spec.stage_steps
    files = {f.__module__ for f in (first.run_spec.stage_steps.py_func,
                                    other.run_spec.stage_steps.py_func)}  # fmt: skip
    assert len(files) == 2
    # a new generator (its fingerprint) writes the method's loop afresh, under a new key
    points = compiled.load_point_functions(codegen.kernel_spec(system))
    tables = separable_tables(METHODS["gauss2"])
    b, c = METHODS["gauss2"].tables.b, METHODS["gauss2"].tables.c
    points.loops.clear()
    monkeypatch.setattr(compiled, "generator_fingerprint", lambda: "another generator")
    renewed = points.stage_loop(b, c, tables)
    assert renewed.py_func.__module__ not in files
    np.testing.assert_array_equal(
        first.integrate(q0, v0, h=0.05, n_steps=30).q,
        integrate_smooth(
            dataclasses.replace(first.run_spec, stage_steps=renewed), q0, v0, None,
            h=0.05, n_steps=30,
        ).q,
    )  # fmt: skip


def test_two_lobatto_points_iterate_nothing_in_either_loop():
    system, q0, v0 = STAGE_CASES["kepler"]
    with pytest.warns(gvi.OrderReductionWarning):  # order 2: two points, degree 2
        method = gvi.Galerkin(2, gvi.gauss_lobatto(2))  # no implicit point
    integrator = gvi.Integrator(system, method, specialize="system")
    assert integrator.run_spec.stage_steps is not None
    generated = integrator.integrate(q0, v0, h=0.01, n_steps=50)
    shared = integrate_smooth(_shared(integrator), q0, v0, None, h=0.01, n_steps=50)
    assert generated.total_newton_iterations == shared.total_newton_iterations == 0
    np.testing.assert_array_equal(generated.q, shared.q)


def test_specialize_false_keeps_the_shared_explicit_loop():
    system, _, _ = CASES["kepler"]
    integrator = gvi.Integrator(system, gvi.Composition(4), specialize=False)
    assert integrator.run_spec.explicit_steps is None


def test_a_step_the_fixed_point_cannot_take_goes_to_the_shared_loops_newton(monkeypatch):
    system, q0, v0 = STAGE_CASES["pendulum_rotating"]
    integrator = gvi.Integrator(system, METHODS["gauss2"], specialize="system")
    handed = _hand_overs(monkeypatch)
    # h = 0.3: the fixed point contracts too slowly a few steps in (measured: step 2)
    run = dict(h=0.3, n_steps=200, save_every=3)
    generated = integrator.integrate(q0, v0, **run)
    shared = integrate_smooth(_shared(integrator), q0, v0, None, **run)
    assert len(handed) == 1 and 0 < handed[0][0] < 200 and handed[0][1] == "separable"
    assert generated.success and len(generated) == len(shared)
    np.testing.assert_array_equal(generated.t, shared.t)
    # the rows before the hand-over are the shared loop's; after it the join restarts the
    # compensation and the first iterate, and the two runs agree to the iteration's tolerance
    before = handed[0][0] // 3 + 1
    np.testing.assert_array_equal(generated.q[:before], shared.q[:before])
    np.testing.assert_allclose(generated.q, shared.q, rtol=0, atol=1e-12)
    np.testing.assert_allclose(generated.p, shared.p, rtol=0, atol=1e-12)


def test_a_run_whose_steps_fail_fails_where_the_shared_loop_fails(monkeypatch):
    # V = -exp(q^2)/2 throws q outwards ever faster: the fixed point hands over, and the
    # shared loop's Newton then fails too, at the same step with the same rows kept
    q, v = sp.symbols("q v")
    system = gvi.LagrangianSystem(v**2 / 2 + sp.exp(q**2) / 2, [q], [v])
    integrator = gvi.Integrator(system, METHODS["gauss2"], specialize="system")
    handed = _hand_overs(monkeypatch)
    run = dict(h=0.01, n_steps=3000, save_every=4, on_failure="warn")
    with pytest.warns(gvi.RunFailureWarning):
        generated = integrator.integrate([2.0], [0.0], **run)
    with pytest.warns(gvi.RunFailureWarning):
        shared = integrate_smooth(_shared(integrator), [2.0], [0.0], None, **run)
    assert not generated.success and generated.status == shared.status
    assert 0 < generated.n_steps == shared.n_steps < 3000
    assert generated.message == shared.message
    np.testing.assert_array_equal(generated.t, shared.t)
    np.testing.assert_allclose(generated.q, shared.q, rtol=1e-13)
    assert handed and handed[0][0] < generated.n_steps  # the fixed point gave up first


def test_specialize_system_is_checked_kept_and_pickled():
    system, q0, v0 = STAGE_CASES["kepler"]
    with pytest.raises(ValueError, match='specialize must be "auto", True, False or "system"'):
        gvi.Integrator(system, METHODS["gauss2"], specialize="fast")
    # True builds no stage loop; the default ("auto") keeps one ready but compiles it only
    # in the background (tests/test_auto_loop.py)
    assert gvi.Integrator(system, METHODS["gauss2"], specialize=True).run_spec.stage_steps is None
    integrator = gvi.Integrator(system, METHODS["gauss2"], specialize="system")
    first = integrator.integrate(q0, v0, h=0.05, n_steps=40)
    copy = pickle.loads(pickle.dumps(integrator))
    assert copy.specialize == "system" and copy.run_spec.stage_steps is not None
    np.testing.assert_array_equal(copy.integrate(q0, v0, h=0.05, n_steps=40).q, first.q)
    # ensembles of it run the shared member loop: the same states
    many = integrator.integrate_many(np.array([q0, q0]), np.array([v0, v0]), h=0.05, n_steps=40)
    np.testing.assert_array_equal(many[1].q, first.q)


def test_the_generated_stage_text_runs_uncompiled_on_numpy_arrays():
    system, q0, v0 = STAGE_CASES["henon_heiles"]
    source = codegen.render_module(codegen.kernel_spec(system), "key")
    namespace: dict = {}
    exec(compile(source, "<generated>", "exec"), namespace)
    integrator = gvi.Integrator(system, METHODS["lobatto3"], specialize="system")
    compiled = integrator.integrate(q0, v0, h=0.1, n_steps=12, save_every=3)
    _, _, after = integrator.run_spec.loop_parts()
    t_out, q_out, p_out, turns = np.zeros(5), np.zeros((5, 2)), np.zeros((5, 2)), np.zeros((1, 2))
    iterations, total = np.zeros(4, dtype=np.uint8), np.zeros(1, dtype=np.int64)
    q, v = np.array(q0, float), np.array(v0, float)
    status, steps, saved, _, _ = namespace["stage_steps"](
        q, v.copy(), v, 0.0, 0.1, 12, 3, system.parameter_vector(None), *after,
        t_out, q_out, p_out, turns, iterations, total,
    )  # fmt: skip
    assert (status, steps, saved) == (0, 12, 5)
    np.testing.assert_array_equal(t_out, compiled.t)
    np.testing.assert_array_equal(q_out, compiled.q)
    assert total[0] == compiled.total_newton_iterations


@pytest.mark.parametrize("method", ["gauss2", "lobatto5"])
def test_the_method_text_runs_uncompiled_on_numpy_arrays(method):
    system, q0, v0 = STAGE_CASES["angle_and_length"]
    integrator = gvi.Integrator(system, METHODS[method], specialize="system")
    assert _loop_name(integrator) == "method_steps"
    source = integrator.run_spec.stage_steps.py_func.__globals__["__file__"]
    namespace: dict = {"__name__": "uncompiled"}
    with open(source) as f:
        exec(compile(f.read(), "<generated>", "exec"), namespace)
    compiled = integrator.integrate(q0, v0, h=0.1, n_steps=12, save_every=5)
    _, _, after = integrator.run_spec.loop_parts()
    out = _outputs(12, 5, 2)
    q, v = np.array(q0, float), np.array(v0, float)
    start = (q, v.copy(), v, 0.0, 0.1, 12, 5, system.parameter_vector(None))
    status, steps, saved, _, _ = namespace["method_steps"](*start, *after, *out)
    assert (status, steps, saved) == (0, 12, 4)
    t_out, q_out, _, _, iterations, total = out
    np.testing.assert_array_equal(t_out[:saved], compiled.t)
    np.testing.assert_array_equal(q_out[:saved], compiled.q_reduced)
    np.testing.assert_array_equal(iterations[: saved - 1], compiled.newton_iterations)
    assert total[0] == compiled.total_newton_iterations


def test_the_key_of_a_module_with_a_stage_loop_follows_the_loops(monkeypatch):
    # the generated stage loop compiles in the shared loop's stopping rule: a new version
    # of the loops is a new module (and a recalled key is trusted only under the same
    # fingerprint, which hashes the loops' sources)
    from galerkin_vi.codegen import spec as spec_module

    names = {path.name for path in compiled.fingerprint_sources()}
    assert {"stage_form.py", "linalg.py", "newton.py", "source.py"} <= names
    staged = codegen.kernel_spec(henon_heiles().system)
    driven = codegen.kernel_spec(STAGE_CASES["driven_pendulum"][0])
    plain = codegen.kernel_spec(spring_chain(30, beta=0.5).system)
    assert codegen.spec.has_stage_steps(staged) and not codegen.spec.has_stage_steps(plain)
    keys = {}
    for version in ("loops-a", "loops-b"):
        monkeypatch.setattr(spec_module, "_loop_version", lambda v=version: v)
        keys[version] = [codegen.signature(s, "numba", "0") for s in (staged, driven, plain)]
    assert keys["loops-a"][0] != keys["loops-b"][0]
    assert keys["loops-a"][1] != keys["loops-b"][1]
    assert keys["loops-a"][2] == keys["loops-b"][2]
