"""Chaos indicators: Lyapunov spectra and MEGNO against closed forms and known behaviour."""

from __future__ import annotations

import multiprocessing
from concurrent.futures import ProcessPoolExecutor

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.problems import harmonic_oscillator, henon_heiles
from galerkin_vi.tangent import lyapunov_map, lyapunov_spectrum, megno, megno_map
from galerkin_vi.tangent.chaos import spectrum_of

q, v, g, length = sp.symbols("q v g l")
# the angle from the upright position: (q, p) = (0, 0) is an exact fixed point of every step
INVERTED = gvi.LagrangianSystem(
    length**2 * v**2 / 2 - g * length * sp.cos(q), [q], [v], params={g: 9.81, length: 2.0}
)
RATE = np.sqrt(9.81 / 2.0)  # sqrt(g / l)
HENON_HEILES = gvi.Integrator(henon_heiles().system, gvi.Galerkin(2))
CHAOTIC = henon_heiles()  # q0 = (0, -0.2) at E = 1/8: in the chaotic sea
REGULAR = henon_heiles(q0=(0.0, 0.1))  # on a KAM torus


def test_the_upright_pendulums_exponents_are_plus_and_minus_sqrt_g_over_l():
    integrator = gvi.Integrator(INVERTED, gvi.Galerkin(2))
    # the start frame's projection on the unstable direction costs log(C)/t with
    # log C = 1.49 here; the method's exponent differs from sqrt(g/l) by O(h^4)
    spectrum = lyapunov_spectrum(integrator, [0.0], [0.0], h=0.1, n_steps=50_000)
    assert spectrum.success and spectrum.exponents.shape == (2,)
    assert abs(spectrum.exponents[0] - RATE) < 1e-3  # measured 3.0e-4
    assert spectrum.exponents[1] == pytest.approx(-spectrum.exponents[0], abs=1e-12)  # det 1
    errors = np.abs(spectrum.running[:, 0] - RATE)
    assert errors[-1] < errors[len(errors) // 2] < errors[len(errors) // 10]  # O(1/t)
    finer = lyapunov_spectrum(integrator, [0.0], [0.0], h=0.05, n_steps=100_000)
    assert abs(finer.exponents[0] - spectrum.exponents[0]) < 1e-5  # measured 1.7e-6


def test_a_chaotic_spectrum_sums_to_zero_in_pairs():
    spectrum = lyapunov_spectrum(
        HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, h=0.2, n_steps=200_000, renormalize_every=10
    )
    lam = spectrum.exponents
    assert spectrum.success and np.all(np.diff(lam) <= 0)
    assert 0.03 < lam[0] < 0.09  # the chaotic sea's largest exponent (about 0.05)
    assert abs(lam.sum()) < 1e-10  # the frame's volume is preserved: det Phi = 1
    # symplectic: lambda_i + lambda_{2n+1-i} = 0; finite-time sums fall like 1/t
    assert abs(lam[0] + lam[3]) < 1e-3 * lam[0]
    assert abs(lam[1] + lam[2]) < 1e-3 * lam[0]
    assert abs(lam[1]) < 2e-3  # the flow direction and the energy: zero exponents


def test_the_estimates_do_not_depend_on_where_rows_fall_between_renormalisations():
    run = dict(h=0.1, n_steps=1400, renormalize_every=10)
    aligned = lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, save_every=10, **run)
    between = lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, save_every=7, **run)
    np.testing.assert_allclose(between.exponents, aligned.exponents, rtol=0, atol=1e-12)
    # at a row between renormalisations the frame's pending growth is counted
    every = lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, save_every=1, **run)
    np.testing.assert_allclose(every.running[6::7], between.running, rtol=0, atol=1e-12)


def test_the_largest_exponents_alone_match_the_full_spectrum():
    run = dict(h=0.1, n_steps=20_000)
    full = lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, **run)
    largest = lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, directions=1, **run)
    assert largest.exponents.shape == (1,)
    assert largest.exponents[0] == pytest.approx(full.exponents[0], rel=0.05)


def test_megno_vanishes_on_the_isochronous_harmonic_oscillator():
    problem = harmonic_oscillator(omega=3.0)  # |delta| oscillates: (q, p) turn on an ellipse
    integrator = gvi.Integrator(problem.system, gvi.Galerkin(2))
    run = dict(params=problem.params, h=0.05, save_every=100)
    short = megno(integrator, problem.q0, problem.v0, n_steps=2_000, **run)
    long = megno(integrator, problem.q0, problem.v0, n_steps=20_000, **run)
    assert np.abs(long.Y).max() > 0.5  # Y itself oscillates ...
    assert abs(long.final) < 0.01 and abs(long.final) < abs(short.final)  # ... its mean -> 0
    assert long.final == long.mean[-1] and long.times[-1] == pytest.approx(1000.0)


def test_megno_tends_to_two_on_a_quasi_periodic_orbit():
    result = megno(HENON_HEILES, REGULAR.q0, REGULAR.v0, h=0.1, n_steps=20_000, save_every=100)
    assert result.success and result.times[-1] == pytest.approx(2000.0)
    assert result.final == pytest.approx(2.0, abs=0.2)  # measured 1.97
    np.testing.assert_allclose(np.linalg.norm(result.direction), 1.0, rtol=1e-15)


def test_megno_grows_like_half_the_lyapunov_exponent_times_t_on_a_chaotic_orbit():
    run = dict(h=0.1, n_steps=40_000)
    result = megno(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, save_every=1000, **run)
    lam = lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, directions=1, **run)
    half = len(result.times) // 2
    slope = np.polyfit(result.times[half:], result.mean[half:], 1)[0]
    assert result.final > 50
    assert slope == pytest.approx(lam.exponents[0] / 2, rel=0.3)


def test_a_megno_map_separates_regular_from_chaotic_starts_and_matches_single_runs():
    ys = np.array([0.1, -0.2, 0.0])
    q0s = np.column_stack([np.zeros(3), ys])
    v0s = np.array([henon_heiles(q0=(0.0, y)).v0 for y in ys])
    run = dict(h=0.1, n_steps=10_000)
    chaos = megno_map(HENON_HEILES, q0s, v0s, workers=2, **run)
    assert chaos.values.shape == (3,) and chaos.success.all() and len(chaos) == 3
    # members save their first and last rows only; chunk joins fall where a single run's do
    single = [megno(HENON_HEILES, q0s[i], v0s[i], save_every=10_000, **run).final
              for i in range(3)]  # fmt: skip
    np.testing.assert_array_equal(chaos.values, single)
    assert abs(chaos.values[0] - 2) < 0.3 and abs(chaos.values[2] - 2) < 0.3
    assert chaos.values[1] > 10
    exponents = lyapunov_map(HENON_HEILES, q0s, v0s, directions=1, workers=2, **run)
    assert exponents.values.shape == (3, 1)
    assert exponents.values[1, 0] > 5 * max(exponents.values[0, 0], exponents.values[2, 0])


def test_a_chaos_map_runs_on_a_process_pool_bitwise_as_on_threads():
    q0s = np.array([[0.0, 0.1], [0.0, -0.2]])
    v0s = np.array([henon_heiles(q0=tuple(x)).v0 for x in q0s])
    run = dict(h=0.1, n_steps=2_000)
    threads = megno_map(HENON_HEILES, q0s, v0s, **run)
    context = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(max_workers=1, mp_context=context) as pool:
        processes = megno_map(HENON_HEILES, q0s, v0s, executor=pool, **run)
    np.testing.assert_array_equal(processes.values, threads.values)
    np.testing.assert_array_equal(processes.status, threads.status)


def test_bad_input_is_named():
    with pytest.raises(ValueError, match="renormalize_every must be an int >= 1"):
        lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=10,
                          renormalize_every=0)  # fmt: skip
    with pytest.raises(ValueError, match=r"directions must be an int in \[1, 2n\]"):
        lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=10, directions=5)
    with pytest.raises(ValueError, match="directions must be None, an int r or an array"):
        lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=10,
                          directions=np.ones((3, 1)))  # fmt: skip
    with pytest.raises(ValueError, match="linearly independent"):
        lyapunov_spectrum(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=10,
                          directions=np.ones((4, 2)))  # fmt: skip
    with pytest.raises(ValueError, match=r"direction must have shape \(2n,\) = \(4,\)"):
        megno(HENON_HEILES, CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=10, direction=[1.0, 0.0])
    with pytest.raises(ValueError, match="a run with tangent=... and renormalize_every"):
        spectrum_of(HENON_HEILES.integrate(CHAOTIC.q0, CHAOTIC.v0, h=0.1, n_steps=10))
    with pytest.raises(TypeError, match="executor must have a map method"):
        megno_map(HENON_HEILES, [CHAOTIC.q0], CHAOTIC.v0, h=0.1, n_steps=10, executor=object())
