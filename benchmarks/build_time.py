"""Cold build and warm load of a compiled kernel (double pendulum, and a separable pendulum).

Prints the time to import galerkin_vi, numba's own one-time initialisation (its
first compilation in a process, of a trivial function: it imports its typing
registries, and with them scipy.linalg), the system (SymPy differentiation and
structure analysis), the generated module (found or written), and the first
``integrate`` call (numba compile when cold, cache load when warm). Run it
twice with the same ``GALERKIN_VI_CACHE_DIR``: the first run is cold, the
second warm. Not a test.

Run: ``export GALERKIN_VI_CACHE_DIR=$(mktemp -d); python benchmarks/build_time.py;
python benchmarks/build_time.py``.
"""

from __future__ import annotations

import time

start = time.perf_counter()
import numba  # noqa: E402 - the imports are what is timed

import galerkin_vi as gvi  # noqa: E402
from galerkin_vi import problems  # noqa: E402

imported = time.perf_counter()


@numba.njit
def _trivial(x):
    return x + 1.0


_trivial(1.0)
numba_ready = time.perf_counter()
print(
    f"import {imported - start:.2f} s, numba initialisation (first compilation in the "
    f"process) {numba_ready - imported:.2f} s"
)
for name, make, method in (
    ("double pendulum, Galerkin(2)", problems.double_pendulum, gvi.Galerkin(2)),
    ("pendulum, Galerkin(2)", problems.pendulum, gvi.Galerkin(2)),
):
    begin = time.perf_counter()
    problem = make()
    integrator = gvi.Integrator(problem.system, method)
    built = time.perf_counter()
    source = integrator.source  # generate or find the module
    loaded = time.perf_counter()
    integrator.integrate(problem.q0, problem.v0, h=0.01, n_steps=1)
    called = time.perf_counter()
    print(
        f"{name} ({integrator.kernel_path} loop): system {built - begin:.2f} s, module "
        f"{loaded - built:.2f} s, first call (compile or cache load) {called - loaded:.2f} s"
    )
