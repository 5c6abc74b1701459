"""Chunked runs (Integrator.stream) and the instability warning."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi

th, w = sp.symbols("th w")
PENDULUM = gvi.LagrangianSystem(w**2 / 2 + sp.cos(th), [th], [w])
OSCILLATOR = gvi.LagrangianSystem(w**2 / 2 - th**2 / 2, [th], [w])


def _joined(chunks):
    return (np.concatenate([c.t for c in chunks]), np.concatenate([c.q for c in chunks]))


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_chunks_hold_the_rows_of_one_run(backend):
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(2), backend=backend)
    n = 600 if backend == "numba" else 120
    one = integrator.integrate([1.2], v0=[0.3], h=0.05, n_steps=n, save_every=4)
    chunks = list(
        integrator.stream([1.2], v0=[0.3], h=0.05, n_steps=n, chunk_steps=40, save_every=4)
    )
    assert len(chunks) == n // 40
    t, q = _joined(chunks)
    np.testing.assert_allclose(t, one.t, rtol=1e-15, atol=0)
    # the joins restart Newton from a different guess: the same map up to round-off
    np.testing.assert_allclose(q, one.q, rtol=0, atol=1e-12)
    p = np.concatenate([c.p for c in chunks])
    np.testing.assert_allclose(p, one.p, rtol=0, atol=1e-12)


def test_a_last_short_chunk_and_a_run_of_no_steps():
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(1))
    chunks = list(integrator.stream([1.0], v0=[0.0], h=0.1, n_steps=25, chunk_steps=10))
    assert [len(c) for c in chunks] == [11, 10, 5]
    assert chunks[-1].t[-1] == pytest.approx(2.5)
    (only,) = integrator.stream([1.0], v0=[0.0], h=0.1, n_steps=0)
    assert len(only) == 1


def test_angles_continue_from_their_reduced_state():
    # a rotor through ~74 turns in chunks: continuous output, reduced state kept exact
    rotor = gvi.LagrangianSystem(w**2 / 2 + 0.3 * sp.cos(th), [th], [w])
    integrator = gvi.Integrator(rotor, gvi.Galerkin(2))
    one = integrator.integrate([0.5], v0=[2.0], h=0.05, n_steps=5000, save_every=10)
    chunks = list(
        integrator.stream([0.5], v0=[2.0], h=0.05, n_steps=5000, chunk_steps=500, save_every=10)
    )
    _, q = _joined(chunks)
    assert q[-1, 0] > 70 * 2 * np.pi
    assert np.all(np.diff(q[:, 0]) > 0)
    np.testing.assert_allclose(q, one.q, rtol=0, atol=1e-10)
    reduced = np.concatenate([c.q_reduced for c in chunks])
    assert np.all(np.abs(reduced) <= np.pi)


def test_stream_rejects_bad_chunking():
    integrator = gvi.Integrator(PENDULUM, gvi.Galerkin(1))
    with pytest.raises(ValueError, match="multiple of save_every"):
        next(integrator.stream([1.0], v0=[0.0], h=0.1, n_steps=10, chunk_steps=5, save_every=2))
    with pytest.raises(ValueError, match="chunk_steps"):
        next(integrator.stream([1.0], v0=[0.0], h=0.1, n_steps=10, chunk_steps=0))


def test_growth_past_the_stability_limit_warns_and_overflow_raises():
    # Stoermer-Verlet (degree 1, two Lobatto points) is stable for h omega < 2
    verlet = gvi.Integrator(OSCILLATOR, gvi.Galerkin(1))
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        stable = verlet.integrate([1.0], v0=[0.0], h=1.99, n_steps=2000)
    assert np.all(np.isfinite(stable.p)) and np.max(np.abs(stable.p)) < 100
    with pytest.warns(gvi.InstabilityWarning, match="stability limit"):
        grown = verlet.integrate([1.0], v0=[0.0], h=2.1, n_steps=200)
    assert np.all(np.isfinite(grown.p))
    with pytest.raises(gvi.ConvergenceError, match="non-finite") as info:
        verlet.integrate([1.0], v0=[0.0], h=2.1, n_steps=5000, on_failure="raise")
    partial = info.value.partial
    assert np.all(np.isfinite(partial.q)) and len(partial) > 100


def test_a_failing_chunk_reports_the_whole_run():
    # a rotor spun up by a torque while its potential stiffens: Newton fails after a while
    t = sp.Symbol("t")
    rotor = gvi.LagrangianSystem(
        w**2 / 2 + sp.exp(t / 3) * sp.cos(th), [th], [w], t=t, forces=[sp.Float(5.0)]
    )
    integrator = gvi.Integrator(rotor, gvi.Galerkin(2))
    got = []
    with pytest.raises(gvi.ConvergenceError) as info:
        for chunk in integrator.stream(
            [0.5], v0=[3.0], h=0.1, n_steps=1000, chunk_steps=100, on_failure="raise"
        ):
            got.append(chunk)
    error = info.value
    assert len(got) >= 1
    last_t, last_q = got[-1].t[-1], got[-1].q[-1, 0]
    partial = error.partial
    # the partial run continues the yielded rows: later times, continuous angle
    assert partial.t[0] == pytest.approx(last_t + 0.1)
    previous_increment = got[-1].q[-1, 0] - got[-1].q[-2, 0]
    assert abs((partial.q[0, 0] - last_q) - previous_increment) < 1.0
    assert error.step == round(partial.t[-1] / 0.1)
    assert error.step >= 100 * len(got)


@pytest.mark.parametrize("kind", ["explicit", "linear"])
def test_specialised_loops_keep_the_last_good_state(kind):
    integrator = gvi.Integrator(OSCILLATOR, gvi.Galerkin(1 if kind == "explicit" else 2))
    assert integrator.kernel_path == kind
    h = 2.1 if kind == "explicit" else 10.0  # past the stability limit: overflow
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.InstabilityWarning)
        with pytest.raises(gvi.ConvergenceError) as info:
            integrator.integrate(
                [1.0], v0=[0.0], h=h, n_steps=100_000, save_every=7, on_failure="raise"
            )
    error = info.value
    partial = error.partial
    # the state at the start of the failing step is saved, due or not
    assert partial.t[-1] == pytest.approx(error.t)
    assert np.all(np.isfinite(partial.q)) and np.all(np.isfinite(partial.p))


def test_the_instability_warning_does_not_depend_on_units():
    # a 1000 kg body falling from rest: p grows linearly to 1.8e6, no warning
    z, vz = sp.symbols("z vz")
    falling = gvi.LagrangianSystem(1000 * vz**2 / 2 - 1000 * 9.81 * z, [z], [vz])
    with warnings.catch_warnings():
        warnings.simplefilter("error", gvi.InstabilityWarning)
        traj = gvi.Integrator(falling, gvi.Galerkin(1)).integrate(
            [0.0], v0=[0.0], h=0.1, n_steps=1800
        )
    assert abs(traj.p[-1, 0]) > 1e6
    # an unstable run from a tiny amplitude warns although its momenta stay small
    verlet = gvi.Integrator(OSCILLATOR, gvi.Galerkin(1))
    with pytest.warns(gvi.InstabilityWarning):
        tiny = verlet.integrate([1e-20], v0=[0.0], h=2.1, n_steps=60)
    assert np.max(np.abs(tiny.p)) < 1e-3


def test_no_instability_warning_for_a_start_at_rest_with_few_rows():
    # the first tenth of 10 rows is p_0 = 0 alone: the test looks at two rows at least
    with warnings.catch_warnings():
        warnings.simplefilter("error", gvi.InstabilityWarning)
        traj = gvi.Integrator(PENDULUM, gvi.Galerkin(2)).integrate(
            [1.0], v0=[0.0], h=0.1, n_steps=9
        )
    assert len(traj) == 10
