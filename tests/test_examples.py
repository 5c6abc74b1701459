"""Smoke tests: every script in examples/ runs (with shortened spans) and prints its table."""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
# a fixed directory, overwritten by every run, for the PNG of the smoke run below
SMOKE_OUTPUT = Path(tempfile.gettempdir()) / "galerkin_vi-example-smoke"

# script -> (arguments that shorten the run, text the output must contain)
RUNS = {
    "pendulum.py": (["--steps", "2000", "--degrees", "1", "2"], "RK4 (order 4, not symplectic)"),
    "kepler.py": (["--periods", "5"], "precession/T"),
    "double_pendulum.py": (["--steps", "2000", "--reverse-time", "2"], "back to start"),
    "outer_solar_system.py": (["--days", "20000"], "final Pluto position"),
    "choose_order.py": ([], "MethodChoice"),
    "constrained_dae.py": (["--t-final", "5", "--output", str(SMOKE_OUTPUT)], "max|g|"),
    "four_bar_linkage.py": (["--steps", "2000"], "max |g(q_k)|"),
    "rimless_wheel.py": (["--seconds", "0.6"], "closed form: omega-"),
    "pendulum_bvp.py": ([], "nodal slopes"),
    "figure_eight.py": ([], "the Newton iteration converged"),
    "catenary_brachistochrone.py": ([], "nodal slopes"),
    "cart_pole_swing_up.py": ([], "largest |u|"),
    "fit_damped_pendulum.py": (["--n-obs", "40", "--output", str(SMOKE_OUTPUT)], "std. error"),
    "henon_heiles_megno.py": (["--grid", "10", "--t-final", "50"], "Lyapunov exponents"),
    "gradient_shooting.py": (["--output", str(SMOKE_OUTPUT)], "gradient evaluations"),
    "periodic_family_stability.py": (
        ["--e-max", "0.3", "--output", str(SMOKE_OUTPUT)],
        "Mathieu boundary E = 0.1856",
    ),
    "tennis_racket.py": (["--t-final", "10", "--output", str(SMOKE_OUTPUT)], "flips (omega_2 = 0)"),
    "heavy_top.py": (["--t-final", "1", "--output", str(SMOKE_OUTPUT)], "closed form ["),
    "pendulum_3d.py": (["--t-final", "1", "--output", str(SMOKE_OUTPUT)], "max |energy error|"),
    "chain_10.py": (
        ["--links", "3", "--t-final", "0.5", "--output", str(SMOKE_OUTPUT)],
        "max joint residual",
    ),
    "die_on_table.py": (["--seconds", "0.5", "--output", str(SMOKE_OUTPUT)], "impacts; the first"),
    "box_stack.py": (
        ["--boxes", "1", "--seconds", "0.3", "--output", str(SMOKE_OUTPUT)],
        "height error",
    ),
    "explicit_splittings.py": (
        ["--t-final", "20", "--output", str(SMOKE_OUTPUT)],
        "max |energy error|",
    ),
}


def test_every_example_is_smoke_tested():
    assert {p.name for p in EXAMPLES.glob("*.py")} <= set(RUNS)


@pytest.mark.parametrize("script", sorted(RUNS))
def test_example_runs(script):
    path = EXAMPLES / script
    if not path.exists():
        pytest.skip(f"{script} not present")
    args, expected = RUNS[script]
    result = subprocess.run(
        [sys.executable, str(path), *args],
        capture_output=True,
        text=True,
        timeout=300,
        env=os.environ.copy(),
        check=False,
    )
    assert result.returncode == 0, result.stderr[-2000:]
    assert expected in result.stdout


def test_constrained_dae_keeps_constraints(tmp_path, monkeypatch):
    """The VI holds g = 0 to round-off; the DAE without Baumgarte drifts away like t**2."""
    path = EXAMPLES / "constrained_dae.py"
    spec = importlib.util.spec_from_file_location("constrained_dae", path)
    example = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "constrained_dae", example)
    spec.loader.exec_module(example)

    runs = example.main(["--t-final", "20", "--output", str(tmp_path)])

    assert (tmp_path / "constrained_dae.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    for model in ("pendulum", "double pendulum"):
        vi = [r for r in runs if r.model == model and r.kind == "VI"]
        index1 = [r for r in runs if r.model == model and r.kind == "index-1"]
        baumgarte = [r for r in runs if r.model == model and r.kind == "Baumgarte"]
        assert len(vi) == 2 and index1 and len(baumgarte) == len(index1)
        # measured at t_final = 20: max |g| and max |G v| <= 4.4e-16 for s = 1, 2
        vi_drift = max(r.max_constraint for r in vi)
        assert vi_drift <= 1e-12
        assert max(r.max_hidden for r in vi) <= 1e-12
        for run in index1:
            # measured max |g| 4.4e-10 (DOP853 rtol 1e-11) .. 4.4e-3 (RK45 rtol 1e-5),
            # at least 1e6 times the VI's
            assert run.max_constraint >= 1e4 * max(vi_drift, 1e-16), run.label
            # drift growing like t**2: max over the second half / first half measured 3.6-10.7
            late = run.t > run.t[-1] / 2
            assert run.constraint[late].max() >= 2 * run.constraint[~late].max(), run.label
        for damped, plain in zip(baumgarte, index1, strict=True):
            # same solver and tolerance; measured 33 to 7900 times smaller with alpha = beta = 5
            assert damped.label.rsplit(" ", 1)[0] == plain.label.rsplit(" ", 1)[0]
            assert damped.max_constraint < plain.max_constraint, damped.label


def test_four_bar_linkage_keeps_its_loop_closed(monkeypatch):
    """The tutorial's linkage: closure and hidden constraint at round-off, energy without drift."""
    path = EXAMPLES / "four_bar_linkage.py"
    spec = importlib.util.spec_from_file_location("four_bar_linkage", path)
    example = importlib.util.module_from_spec(spec)
    monkeypatch.setitem(sys.modules, "four_bar_linkage", example)
    spec.loader.exec_module(example)
    result = example.main(["--steps", "20000"])
    assert result["crank_turns"] > 100  # the crank turns through many full revolutions
    assert result["max_constraint_residual"] <= 1e-12
    assert result["max_hidden_residual"] <= 1e-12
    assert result["drift_ratio"] <= 2.0
    assert result["max_energy_error"] <= 1e-4  # O(h^4) at h = 0.005, s = 2
