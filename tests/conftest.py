"""Shared fixtures: one method registry that every method-parametrised test uses."""

from __future__ import annotations

import os
import sys
import warnings
from pathlib import Path

import pytest
from hypothesis import settings

import galerkin_vi as gvi

os.environ.setdefault("GALERKIN_VI_CACHE_DIR", os.path.join(os.getcwd(), ".gvi-test-cache"))
# the loops' cache folder is bound on import: here, before any test points
# GALERKIN_VI_CACHE_DIR at a temporary folder of its own
import galerkin_vi.loops  # noqa: E402, F401

#: the repository's benchmarks/ folder: its ``peers`` package (hand-written kernels, peer
#: adapters) is not installed with galerkin_vi; appended, so it never shadows an installed module
BENCHMARKS_DIR = Path(__file__).resolve().parents[1] / "benchmarks"
if str(BENCHMARKS_DIR) not in sys.path:
    sys.path.append(str(BENCHMARKS_DIR))

# The default run is deterministic: the same examples every time, so a CI result does not
# depend on the draw (an order study of a randomly drawn pendulum can land in the
# pre-asymptotic range). HYPOTHESIS_PROFILE=explore draws new examples.
settings.register_profile("deterministic", derandomize=True, database=None)
settings.register_profile("explore", derandomize=False)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "deterministic"))


def method_registry(max_degree: int = 6) -> list[gvi.Galerkin]:
    """Lobatto s+1, Gauss s, Lobatto s+2, Gauss s+1 and Lobatto s (order 2s-2), s = 1..max."""
    methods = []
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", gvi.OrderReductionWarning)
        for s in range(1, max_degree + 1):
            methods += [
                gvi.Galerkin(s, gvi.gauss_lobatto(s + 1)),
                gvi.Galerkin(s, gvi.gauss_legendre(s)),
                gvi.Galerkin(s, gvi.gauss_lobatto(s + 2)),
                gvi.Galerkin(s, gvi.gauss_legendre(s + 1)),
            ]
            if s >= 2:
                methods.append(gvi.Galerkin(s, gvi.gauss_lobatto(s)))
    return methods


@pytest.fixture(scope="session")
def methods() -> list[gvi.Galerkin]:
    return method_registry()


@pytest.fixture
def warm_cache(tmp_path):
    """An empty cache folder for one test, with a copy of the compiled loops.

    Subprocesses pointed at it find every loop compiled (as on a machine that has
    used the library) and build only their systems' point functions there.
    """
    import shutil

    from galerkin_vi.loops import loop_cache_dir
    from galerkin_vi.loops.readiness import ensure_all_loops

    ensure_all_loops()
    source = loop_cache_dir()
    shutil.copytree(source, tmp_path / "loops" / source.name)
    return tmp_path


def pytest_configure(config):
    """Compile the loops once, in the main process, before xdist starts its workers.

    Runs start no background compiles of the loops generated for their systems
    (``GALERKIN_VI_BACKGROUND=0``, inherited by the workers and their subprocesses): a
    session runs hundreds of systems twice, and would compile a loop for each on the
    cores the tests run on; tests/test_auto_loop.py turns them on where it tests them.
    """
    os.environ["GALERKIN_VI_BACKGROUND"] = "0"
    if not hasattr(config, "workerinput"):
        from galerkin_vi.loops.readiness import ensure_all_loops

        ensure_all_loops()
