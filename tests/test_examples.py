"""Smoke tests: every script in examples/ runs (with shortened spans) and prints its table."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"

# script -> (arguments that shorten the run, text the output must contain)
RUNS = {
    "pendulum.py": (["--steps", "2000", "--degrees", "1", "2"], "RK4 (order 4, not symplectic)"),
    "kepler.py": (["--periods", "5"], "precession/T"),
    "double_pendulum.py": (["--steps", "2000", "--reverse-time", "2"], "back to start"),
    "outer_solar_system.py": (["--days", "20000"], "final Pluto position"),
    "choose_order.py": ([], "MethodChoice"),
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
