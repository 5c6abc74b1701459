"""The constrained stage Jacobian against central differences of its residual.

A wrong Jacobian still converges (more slowly), so the order tests would not
see it; this compares every entry. The system has everything that enters:
L_qv != 0 (a magnetic term), a velocity-dependent force, and two nonlinear,
time-dependent constraints.
"""

from __future__ import annotations

import numpy as np
import pytest
import sympy as sp

import galerkin_vi as gvi
from galerkin_vi.reference import numpy_constrained

x, y, z, vx, vy, vz, t, B = sp.symbols("x y z vx vy vz t B")
SYSTEM = gvi.LagrangianSystem(
    (vx**2 + vy**2 + vz**2) / 2 + B * (x * vy - y * vx) / 2 - z + sp.cos(t) * x * y,
    [x, y, z],
    [vx, vy, vz],
    t=t,
    params={B: 0.7},
    constraints=[x**2 + y**2 + z**2 - (1 + sp.sin(t) / 5) ** 2, x * z - sp.cos(2 * t) * y / 10],
    forces=[-0.3 * vx + 0.1 * y * vz, -0.2 * vy * x, -0.1 * vz**2],
)


class _Captured(Exception):
    pass


@pytest.mark.parametrize("degree", [1, 2, 3])
def test_constrained_jacobian_matches_central_differences(degree, monkeypatch):
    captured = {}

    def capture(fun, x0, **_):
        captured["fun"], captured["x0"] = fun, x0
        raise _Captured

    monkeypatch.setattr(numpy_constrained, "newton_solve", capture)
    tables = gvi.Galerkin(degree).tables
    rng = np.random.default_rng(degree)
    qk, pk = rng.normal(size=3), rng.normal(size=3)
    guess = np.vstack([np.zeros(3), 0.1 * rng.normal(size=(degree, 3))])
    impulses = rng.normal(size=(degree, 2))
    with pytest.raises(_Captured):
        numpy_constrained.solve_constrained_step(
            SYSTEM, tables, 0.37, 0.2, qk, pk, guess, impulses, SYSTEM.param_defaults, 1e-14, 20
        )
    fun, x0 = captured["fun"], captured["x0"]
    _, jac = fun(x0)
    step = 1e-6
    differences = np.empty_like(jac)
    for j in range(x0.size):
        e = np.zeros_like(x0)
        e[j] = step
        differences[:, j] = (fun(x0 + e)[0] - fun(x0 - e)[0]) / (2 * step)
    # central differences are accurate to O(step^2 |R'''|) + eps |R| / step ~ 1e-9 here
    np.testing.assert_allclose(jac, differences, rtol=0, atol=5e-8 * np.abs(jac).max())


def test_compiled_and_reference_constrained_loops_agree_with_everything_present():
    q0 = np.array([0.6, 0.0, 0.8])  # off the second constraint: project=True moves it
    runs = [
        gvi.Integrator(SYSTEM, gvi.Galerkin(2), backend=backend).integrate(
            q0, v0=[0.0, 0.3, 0.0], h=0.02, n_steps=30, project=True
        )
        for backend in ("numba", "numpy")
    ]
    np.testing.assert_allclose(runs[0].q, runs[1].q, rtol=0, atol=1e-13)
    np.testing.assert_allclose(runs[0].p, runs[1].p, rtol=0, atol=1e-13)
    assert runs[0].constraint_residual().max() < 1e-14
    assert runs[0].hidden_constraint_residual().max() < 1e-13
