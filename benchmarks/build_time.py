"""Cold build and warm load of a compiled kernel (double pendulum).

Prints the time to import galerkin_vi, to build the system (SymPy
differentiation and structure analysis), to generate or find the kernel module,
and of the first ``integrate`` call (numba compile, or numba cache load when
warm). Run it twice with the same ``GALERKIN_VI_CACHE_DIR``: the first run is
cold, the second warm. Not a test.

Run: ``GALERKIN_VI_CACHE_DIR=$(mktemp -d) python benchmarks/build_time.py``.
"""

from __future__ import annotations

import time

start = time.perf_counter()
import galerkin_vi as gvi  # noqa: E402 - the import is what is timed
from galerkin_vi import problems  # noqa: E402

imported = time.perf_counter()
problem = problems.double_pendulum()
integrator = gvi.Integrator(problem.system, gvi.Galerkin(2))
built = time.perf_counter()
source = integrator.source  # generate or find the module
loaded = time.perf_counter()
integrator.integrate(problem.q0, problem.v0, h=0.01, n_steps=1)
called = time.perf_counter()
print(
    f"import {imported - start:.2f} s, system {built - imported:.2f} s, "
    f"module {loaded - built:.2f} s, first call (compile or cache load) {called - loaded:.2f} s"
)
