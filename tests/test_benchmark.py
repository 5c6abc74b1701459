"""galerkin_vi.tools.benchmark: work-precision curves of galerkin_vi's methods on a user's model.

No timing is asserted: only the shape of the results, the errors and the sweeps.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import galerkin_vi as gvi
from galerkin_vi import problems
from galerkin_vi.tools import benchmark as bm


@pytest.fixture(scope="module")
def oscillator():
    return problems.harmonic_oscillator(1.3)


@pytest.fixture(scope="module")
def result(oscillator):
    return bm.work_precision(
        oscillator.system,
        oscillator.q0,
        oscillator.v0,
        oscillator.t_final,
        [(1, "lobatto"), gvi.Galerkin(2, gvi.gauss_legendre(2))],
        oscillator.reference,
        params=oscillator.params,
        n_start=8,
        time_cap=0.01,
        repeats=1,
        energy_samples=20,
    )


def test_result_has_one_curve_per_method(result):
    assert list(result["curves"]) == ["galerkin_vi s=1 Lobatto(2)", "galerkin_vi s=2 Gauss(2)"]
    assert set(result["time_to_error"]) == set(result["curves"])
    assert set(result["best_galerkin_vi"]) == set(result["targets"]) == {"0.0001", "1e-08", "1e-11"}
    for curve in result["curves"].values():
        assert curve["family"] == "galerkin_vi" and curve["kind"] == "fixed-step"
        assert curve["points"], "every curve has at least one point"
        for p in curve["points"]:
            assert {"n_steps", "h", "time", "error", "energy_error", "newton_iterations"} <= set(p)
            assert p["time"] > 0 and p["error"] >= 0 and p["energy_error"] is not None


def test_errors_fall_at_the_method_order(result):
    """Halving h divides the error of an order-p method by about 2^p (pre-floor points)."""
    for label, order in (("galerkin_vi s=1 Lobatto(2)", 2), ("galerkin_vi s=2 Gauss(2)", 4)):
        pts = [p for p in result["curves"][label]["points"] if p["error"] > 1e-10]
        assert len(pts) >= 2
        slope = math.log2(pts[-2]["error"] / pts[-1]["error"])
        assert abs(slope - order) < 0.5


def test_default_reference_is_dop853(oscillator):
    """Without a reference, DOP853 on the Euler–Lagrange equations; a plain array works too."""
    args = (oscillator.system, oscillator.q0, oscillator.v0, 1.0, [(2, "gauss")])
    kwargs = {"params": oscillator.params, "time_cap": 0.005, "repeats": 1, "energy_samples": 5}
    default = bm.work_precision(*args, **kwargs)
    given = bm.work_precision(*args, oscillator.reference(1.0), **kwargs)
    np.testing.assert_allclose(
        default["reference_position"], given["reference_position"], atol=1e-11
    )


def test_markdown_and_outputs(result, tmp_path):
    text = bm.markdown(result, "oscillator")
    assert text.startswith("# galerkin_vi work-precision: oscillator")
    assert "| **fastest** |" in text and "## All points" in text
    assert "## All points" not in bm.markdown(result, "oscillator", points=False)
    files = bm.write_outputs({"oscillator": result}, str(tmp_path))
    names = {p.rsplit("/", 1)[-1] for p in files}
    assert names == {
        "work_precision.json",
        "work_precision.md",
        "oscillator_precision.png",
        "oscillator_energy.png",
    }
    data = json.loads((tmp_path / "work_precision.json").read_text())
    assert set(data["oscillator"]["curves"]) == set(result["curves"])


def test_sweep_helpers():
    assert bm.tolerances(1e-3, 3e-14, 10.0)[-2:] == [1e-13, 3e-14]
    assert bm.tolerances(1e-3, 1e-6, 10.0) == [1e-3, 1e-4, 1e-5, 1e-6]
    assert bm.step_counts(50, 2.0)[:3] == [50, 100, 200]
    assert bm.method_label(gvi.Galerkin(3)) == "galerkin_vi s=3 Lobatto(4)"
    with pytest.raises(ValueError, match="unknown quadrature family"):
        bm.quadrature(2, "radau")


def test_time_to_error_interpolates_log_log():
    points = [{"time": 1.0, "error": 1e-2}, {"time": 10.0, "error": 1e-6}]
    assert math.isclose(bm.time_to_error(points, 1e-4)["time"], math.sqrt(10.0))
    assert bm.time_to_error(points, 1e-8) is None
    assert bm.time_to_error(points, 1e-1) == {"time": 1.0, "bound": True}
