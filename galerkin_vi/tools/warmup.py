"""Compile every time loop once for this machine: ``python -m galerkin_vi.tools.warmup``.

The loops of :mod:`galerkin_vi.loops` are compiled by numba on their first
use and cached on disk (:func:`galerkin_vi.loops.loop_cache_dir`); after that,
any system, degree, quadrature, step size or parameter value loads them in
milliseconds. The runs here take every compiled variant of every loop (see
:mod:`galerkin_vi.loops.traits`) through two steps of a tiny system.
:func:`galerkin_vi.loops.readiness.compile_all` runs them in parallel
processes, ``--group g --of G`` each; ``galerkin-vi warmup`` is the command.
"""

from __future__ import annotations

import argparse
import os
import re
import sys
import time
from collections.abc import Sequence
from functools import cache
from pathlib import Path

__all__ = [
    "BOUNDARY_VALUE",
    "RUN_SECONDS",
    "main",
    "prefetch",
    "run_indices",
    "runs_ready",
    "variant_labels",
    "warm_up",
]

#: the label of the run that compiles the Newton iteration of boundary-value problems
#: (:mod:`galerkin_vi.loops.action`) instead of a time loop
BOUNDARY_VALUE = "boundary-value problem"
#: the label prefix of the runs that compile the tangent loop and the adjoint's reverse
#: pass (:mod:`galerkin_vi.loops.tangent`)
TANGENT = "tangent map"
#: the label of the run that compiles the time-stepping contact step
#: (:mod:`galerkin_vi.loops.contact_step`)
CONTACT_STEP = "contact step"


@cache
def _runs():
    """(label, system, method, specialize, q0, v0) of the warm-up runs, one per loop variant.

    The variants are the combinations of the switches of :mod:`galerkin_vi.loops.traits`
    that the loops take: stage form (diagonal or full mass matrix) x (dense or banded),
    general loop (dense or banded) x (with or without L_qv / f_v couplings), linear
    loop (dense or banded), constrained loop, explicit loop (diagonal or full mass
    matrix) x (angles or none) x (autonomous or time-dependent), the varying-mass
    loop, the tangent loop and the discrete adjoint's reverse pass (dense or banded;
    their couplings are run-time flags), the constrained tangent loop, the explicit
    tangent loop (angles or none, dense or banded Hessians). Each implicit variant
    is also run as a two-member ensemble (:mod:`galerkin_vi.loops.members`). The
    boundary-value run solves a boundary-value problem (:mod:`galerkin_vi.loops.action`);
    the last takes time-stepping contact steps (:mod:`galerkin_vi.loops.contact_step`,
    one variant for every system).
    """
    import sympy as sp

    from ..method.composition import Composition
    from ..method.galerkin import Galerkin
    from ..method.quadrature import gauss_legendre
    from ..model.contacts import Contact
    from ..model.system import LagrangianSystem

    t = sp.Symbol("t")
    q, v = sp.symbols("q v")
    x, y, vx, vy = sp.symbols("x y vx vy")
    n = 8  # the smallest chain stored banded (coupling half-width 1)
    qs, vs = sp.symbols(f"q0:{n}"), sp.symbols(f"v0:{n}")
    springs = [qs[0], *(qs[i + 1] - qs[i] for i in range(n - 1)), -qs[-1]]
    chain_v = sum(e**2 / 2 + e**4 / 4 for e in springs)
    kinetic = sum(w**2 for w in vs) / 2
    neighbours = sum(vs[i] * vs[i + 1] for i in range(n - 1)) / 10
    full_mass = (vx**2 + vx * vy + vy**2) / 2
    driven = sp.cos(t) / 10

    def system(L, coords, velocities, **kw):
        return LagrangianSystem(L, list(coords), list(velocities), **kw)

    pendulum = system(v**2 / 2 + sp.cos(q), [q], [v])
    quartic = system(v**2 / 2 - q**4 / 4, [q], [v])
    coupled = system(full_mass - (x**2 + y**2) / 2, [x, y], [vx, vy])
    coupled_angles = system(full_mass + sp.cos(x) + sp.cos(y), [x, y], [vx, vy])
    chain = system(kinetic - chain_v, qs, vs)
    chain_full_mass = system(kinetic + neighbours - chain_v, qs, vs)
    linear_chain = system(kinetic - sum(e**2 / 2 for e in springs), qs, vs)
    damped_chain = system(kinetic - chain_v, qs, vs, forces=[-w / 10 for w in vs])
    gyroscopic = system((1 + q**2) * v**2 / 2 + sp.cos(q), [q], [v])
    rod = system((vx**2 + vy**2) / 2 - y, [x, y], [vx, vy], constraints=[(x**2 + y**2 - 1) / 2])
    # a planar chain of point masses on rods: the smallest constrained step stored banded
    xs, ys = sp.symbols(f"x0:{n}"), sp.symbols(f"y0:{n}")
    xvs, yvs = sp.symbols(f"xv0:{n}"), sp.symbols(f"yv0:{n}")
    links = [(xs[0], ys[0])] + [(xs[i] - xs[i - 1], ys[i] - ys[i - 1]) for i in range(1, n)]
    rods = system(
        sum(a**2 + b**2 for a, b in zip(xvs, yvs, strict=True)) / 2 - sum(ys),
        [c for pair in zip(xs, ys, strict=True) for c in pair],
        [c for pair in zip(xvs, yvs, strict=True) for c in pair],
        constraints=[(a**2 + b**2 - 1) / 2 for a, b in links],
    )
    rods0 = (
        [c for i in range(n) for c in (0.0, -1.0 - i)],
        [c for i in range(n) for c in (0.1, 0.0)],
    )
    # a ball on the floor, with friction: the contact step (a constrained system or any
    # other takes the same variant)
    ball = system(
        (vx**2 + vy**2) / 2 - y, [x, y], [vx, vy],
        contacts=[Contact(y, restitution=0.0, friction=0.5, slip=[vx])],
    )  # fmt: skip
    timed_pendulum = system(v**2 / 2 + (1 + driven) * sp.cos(q), [q], [v], t=t)
    timed_quartic = system(v**2 / 2 - q**4 / 4 + driven * q, [q], [v], t=t)
    timed_angles = system(full_mass + (1 + driven) * sp.cos(x), [x, y], [vx, vy], t=t)
    timed_coupled = system(full_mass - (x**2 + y**2) / 2 + driven * x, [x, y], [vx, vy], t=t)
    one, two, chain0 = ([0.5], [0.1]), ([0.5, -0.2], [0.1, 0.0]), ([0.01] * n, [0.0] * n)
    g1, g2 = Galerkin(1), Galerkin(2)
    composed = Composition(4, "yoshida")  # the explicit tangent loop (three sub-steps)
    return [
        ("stage form, diagonal M", pendulum, g2, True, *one),
        ("stage form, full M", coupled_angles, g2, True, *two),
        ("stage form, diagonal M, banded", chain, g2, True, *chain0),
        ("stage form, full M, banded", chain_full_mass, g2, True, *chain0),
        ("general", pendulum, g2, False, *one),
        ("general, couplings", gyroscopic, g2, False, *one),
        ("general, banded", chain, g2, False, *chain0),
        ("general, banded, couplings", damped_chain, g2, True, *chain0),
        ("linear", coupled, g2, True, *two),
        ("linear, banded", linear_chain, g2, True, *chain0),
        ("constrained", rod, g2, True, [0.6, -0.8], [0.8, 0.6]),
        ("constrained, banded", rods, g2, True, *rods0),
        ("explicit", pendulum, g1, True, *one),
        ("explicit, no angles", quartic, g1, True, *one),
        ("explicit, full M", coupled_angles, g1, True, *two),
        ("explicit, full M, no angles", coupled, g1, True, *two),
        ("explicit, time", timed_pendulum, g1, True, *one),
        ("explicit, time, no angles", timed_quartic, g1, True, *one),
        ("explicit, time, full M", timed_angles, g1, True, *two),
        ("explicit, time, full M, no angles", timed_coupled, g1, True, *two),
        ("varying mass", gyroscopic, Galerkin(3, gauss_legendre(3)), True, *one),
        (f"{TANGENT}", gyroscopic, g2, True, *one),
        (f"{TANGENT}, banded", damped_chain, g2, True, *chain0),
        (f"{TANGENT}, constrained", rod, g2, True, [0.6, -0.8], [0.8, 0.6]),
        (f"{TANGENT}, explicit", pendulum, composed, True, *one),
        (f"{TANGENT}, explicit, no angles", coupled, composed, True, *two),
        (f"{TANGENT}, explicit, banded", chain, composed, True, *chain0),
        (BOUNDARY_VALUE, pendulum, g2, True, *one),
        # falling onto the floor within the first step: that step's first touch is cut
        # by single steps (the run's loop hands it back), the next ones are the loop's
        (CONTACT_STEP, ball, g1, True, [0.0, 0.004], [0.5, -1.0]),
    ]


def variant_labels(spec) -> list[str]:
    """The warm-up runs that compile the shared loop variants a run spec calls.

    ``spec`` is a :class:`~galerkin_vi.run.spec.RunSpec`; the explicit path (loops
    generated per system) needs none. A varying-mass run may hand over to the
    general loop with its couplings, so that variant comes with it.
    """
    banded = ", banded" if spec.model is not None and spec.model[2] is not None else ""
    if spec.path == "separable":
        return [f"stage form, {'diagonal M' if spec.diagonal_mass else 'full M'}{banded}"]
    if spec.path == "newton":
        return ["general" + banded + (", couplings" if spec.couplings else "")]
    if spec.path == "linear":
        return ["linear" + banded]
    if spec.path == "constrained":
        return ["constrained" + (", banded" if spec.band is not None else "")]
    if spec.path == "varying_mass":
        return ["varying mass", "general, couplings"]
    return []


#: compile seconds of each run, two processes on a 2-core machine (numba 0.68), in the
#: order of :func:`_runs`: the parallel groups are balanced by them (docs/performance.md,
#: "First use and compile time", gives the command that measures them)
RUN_SECONDS = (
    27.0,
    27.0,
    36.0,
    35.0,
    13.0,
    14.0,
    15.0,
    18.0,
    15.0,
    17.0,
    26.0,
    30.0,
    3.0,
    1.3,
    3.3,
    1.5,
    3.4,
    2.3,
    3.0,
    1.5,
    10.0,
    20.0,
    25.0,
    12.0,
    8.0,
    8.0,
    8.0,
    31.0,
    40.0,
)


def _group(index: int, count: int, runs: Sequence[int] | None = None) -> list[int]:
    """Runs of group ``index`` of ``count``: longest first, each to the least loaded group."""
    loads = [0.0] * count
    members: list[list[int]] = [[] for _ in range(count)]
    chosen = range(len(RUN_SECONDS)) if runs is None else runs
    for run in sorted(chosen, key=lambda r: -RUN_SECONDS[r]):
        target = loads.index(min(loads))
        loads[target] += RUN_SECONDS[run]
        members[target].append(run)
    return sorted(members[index])


def _marker(label: str, ensembles: bool) -> Path:
    """The file that records that warm-up run ``label`` has been compiled (in the loops'
    folder: a new package version starts without them)."""
    from ..loops import loop_cache_dir

    slug = re.sub(r"[^a-z0-9]+", "-", label.lower()).strip("-")
    return loop_cache_dir() / "ready" / (slug + ("" if ensembles else ".single"))


def runs_ready(labels: Sequence[str], ensembles: bool = True) -> bool:
    """Whether the warm-up runs ``labels`` have all been compiled (with their ensembles)."""
    from ..loops.readiness import loops_ready

    if loops_ready():
        return True
    return all(
        _marker(label, True).exists() or (not ensembles and _marker(label, False).exists())
        for label in labels
    )


def prefetch(labels: Sequence[str], ensembles: bool = False) -> float:
    """Compile the variants of the warm-up runs ``labels`` in parallel, unless they are ready.

    For a process that knows which loops it will run (``galerkin-vi verify``):
    compiled at once on all cores where first use would compile them one after
    another. Returns the seconds taken (0 when everything was ready).
    """
    from ..loops.on_demand import COMPILE_CHILD, messages_on
    from ..loops.readiness import compile_all

    if runs_ready(labels, ensembles) or os.environ.get(COMPILE_CHILD):
        return 0.0
    if messages_on():
        sys.stderr.write(
            f"galerkin_vi: compiling the {len(labels)} time loops this job runs, in parallel "
            "(once for this machine)...\n"
        )
    seconds = compile_all(runs=run_indices(labels), ensembles=ensembles)
    for label in labels:
        marker = _marker(label, ensembles)
        marker.parent.mkdir(parents=True, exist_ok=True)
        marker.write_text("compiled\n")
    return seconds


def run_indices(labels: Sequence[str]) -> list[int]:
    """The indices of the warm-up runs named ``labels`` (ValueError for an unknown one)."""
    known = {run[0]: i for i, run in enumerate(_runs())}
    unknown = [label for label in labels if label not in known]
    if unknown:
        raise ValueError(f"no warm-up run is named {unknown[0]!r}; the runs: {'; '.join(known)}")
    return [known[label] for label in labels]


def warm_up(
    group: int = 0,
    of: int = 1,
    verbose: bool = False,
    runs: Sequence[int] | None = None,
    ensembles: bool = True,
) -> dict[str, float]:
    """Run group ``group`` of ``of`` of the warm-up runs (all, or the indices ``runs``) here.

    With ``ensembles=False`` the member loops of ensembles are left out. Returns the
    seconds each run took, by the variant's label.
    """
    from ..loops import compiling

    all_runs = _runs()
    seconds: dict[str, float] = {}
    # numba's compiler with the package's faster inliner and post-processor, only here
    with compiling():
        for index in _group(group, of, runs):
            label = all_runs[index][0]
            seconds[label] = _warm_up_one(all_runs[index], ensembles)
            if verbose:
                print(f"  {seconds[label]:5.1f} s  {label}", flush=True)
    return seconds


def _warm_up_one(run: tuple, ensembles: bool = True) -> float:
    """Compile (or load) the loops of one warm-up run; the seconds it took."""
    from ..action import solve_bvp
    from ..integrator import Integrator

    label, system, method, specialize, q0, v0 = run
    start = time.perf_counter()
    if label == CONTACT_STEP:
        integrator = Integrator(system, method, specialize=specialize)
        integrator.integrate(
            q0, v0=v0, h=0.01, n_steps=3, contact_mode="time-stepping", on_failure="raise"
        )
    elif label == BOUNDARY_VALUE:
        solve_bvp(system, method, q0, v0, (0.0, 0.1), 4, backend="numba")
    elif label.startswith(TANGENT):
        from ..tangent.adjoint import warm_up_adjoint

        integrator = Integrator(system, method, specialize=specialize)
        integrator.integrate(q0, v0=v0, h=0.01, n_steps=2, tangent=True, on_failure="raise")
        if ensembles:  # the member loop of ensembles with the tangent map
            integrator.integrate_many(
                [q0, q0], [v0, v0], h=0.01, n_steps=2, tangent=True, workers=1
            )
        if not system.m:
            warm_up_adjoint(integrator, q0, v0)
    elif label.startswith("explicit"):
        from dataclasses import replace

        from ..run.smooth import integrate_smooth

        # the shared explicit loop, which the systems without a generated one run (the
        # warm-up's small systems have one: numba compiles that per system, on first use)
        integrator = Integrator(system, method, specialize=specialize)
        shared = replace(integrator.run_spec, explicit_steps=None)
        integrate_smooth(shared, q0, v0, None, h=0.01, n_steps=2, on_failure="raise")
    else:
        integrator = Integrator(system, method, specialize=specialize)
        integrator.integrate(q0, v0=v0, h=0.01, n_steps=2, on_failure="raise")
        if ensembles and integrator.kernel_path != "explicit":
            # the member loop of ensembles (and their Legendre transforms) for this loop
            integrator.integrate_many([q0, q0], [v0, v0], h=0.01, n_steps=2, workers=1)
    return time.perf_counter() - start


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m galerkin_vi.tools.warmup [--group g --of G]``."""
    parser = argparse.ArgumentParser(prog="python -m galerkin_vi.tools.warmup")
    parser.add_argument("--group", type=int, default=0)
    parser.add_argument("--of", type=int, default=1)
    parser.add_argument("--runs", help="comma-separated indices of the runs (default: all)")
    parser.add_argument("--no-ensembles", action="store_true", help="leave out member loops")
    args = parser.parse_args(argv)
    if not 0 <= args.group < args.of:
        parser.error(f"--group must be in [0, {args.of})")
    # this process is the warm-up: its integrations must not start another one
    os.environ["GALERKIN_VI_WARMUP_CHILD"] = "1"
    runs = [int(i) for i in args.runs.split(",")] if args.runs else None
    warm_up(args.group, args.of, verbose=True, runs=runs, ensembles=not args.no_ensembles)
    return 0


if __name__ == "__main__":
    sys.exit(main())
