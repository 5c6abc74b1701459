"""``specialize="auto"``: the loop generated for a system when it is compiled, else the shared one.

The stage-form loop generated for one system and method
(:mod:`galerkin_vi.codegen.method_steps`, :mod:`~galerkin_vi.codegen.stage_steps`)
takes the shared loop's steps bit for bit in half to two thirds of the time, but
costs seconds to compile. (The varying-mass path's generated loop,
:mod:`~galerkin_vi.codegen.velocity_steps`, sweeps a closed form of its own that
agrees with the shared loop to round-off only; so that a run's numbers never depend
on the state of the cache, ``"auto"`` leaves it to ``"system"``.)

With ``specialize="auto"`` (the default) a run takes the system's loop exactly
when it is compiled already, in this process or in the disk cache, so the choice
is a function of the cache's state and never waits for a compiler. The compile
itself is started in the background (a child process,
:func:`galerkin_vi.loops.on_demand.compile_in_background`) for a system that is
worth it:

- run again: the second run of the same generated loop in this process
  (a second ``integrate``, a parameter sweep, the members of an ensemble);
- or a long run: at least :data:`LONG_RUN_STEPS` steps.

A short first run (fewer than :data:`LONG_RUN_STEPS` steps) never starts it. Background
compiles run one at a time (:func:`galerkin_vi.loops.on_demand.compile_in_background`);
``GALERKIN_VI_BACKGROUND=0`` turns them off (a run then takes the system's loop only where
something else compiled it: ``specialize="system"``, ``galerkin-vi warmup`` does not).

On a machine where the shared loop is not compiled either, a first run has to wait for
a compiler anyway: it compiles the system's own loop (about 2 s for a pendulum, under
the variant's lock) where the shared one would take ten, and the shared one in the
background, for the next systems and for a step that needs Newton. Which
loop ran is the trajectory's ``kernel_path`` (``"separable"`` or
``"separable:system"``; :func:`kernel_path`); both take the same steps bit for bit
up to a step that needs Newton, where the system's loop hands the rest of the run
to the shared one (:func:`galerkin_vi.run.segment.continue_from_last_row`).
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Callable, Sequence

__all__ = ["LONG_RUN_STEPS", "choose_generated", "kernel_path", "runs_of"]

#: a first run of at least this many steps starts the compile of its system's loop
#: (about 1–3 s once, saving 30–50 % of each step thereafter: at 0.1–0.3 µs per step
#: a run of 1e5 steps is worth recompiling for only if it is run again, which a run of
#: this length usually is)
LONG_RUN_STEPS = 100_000

#: the runs of each generated loop in this process, by its dispatcher's identity
_RUNS: Counter = Counter()
#: the generated loops compiled or loaded in this process (they stay so)
_READY: set[int] = set()
#: each generated loop's argument types, and its shared loop's
_SIGNATURES: dict[int, tuple] = {}


def runs_of(steps) -> int:
    """How many runs of the generated loop ``steps`` this process has started."""
    return _RUNS[id(steps)]


def choose_generated(
    steps, arguments: Sequence, n_steps: int, shared=None, shared_arguments: Sequence = ()
) -> Callable | None:
    """The generated loop ``steps`` if it is compiled for ``arguments``, else None.

    Counts the run; when the loop is not compiled and the system is run again or
    the run is long (module docstring), starts its compile in the background. On a
    machine where the shared loop ``shared`` is not compiled for ``shared_arguments``
    either, the run has to wait for a compiler anyway: it compiles the system's own
    loop here, a few seconds where the shared loop takes ten, and the shared loop in
    the background (the loop the next systems and methods run, and the one a step
    that needs Newton hands over to).
    """
    from numba import typeof

    from ..loops.on_demand import (
        compile_in_background,
        is_cached,
        start_next_background,
        variant_lock,
    )

    _RUNS[id(steps)] += 1
    start_next_background()  # a queued background compile, when the last one has ended
    if id(steps) in _READY:
        return steps
    # the argument types of a spec's runs do not change: typed once (numba's typeof
    # costs about 20 us an array, a large share of a short run's fixed cost)
    signature, shared_signature = _SIGNATURES.get(id(steps), (None, None))
    if signature is None:
        signature = tuple(typeof(a) for a in arguments)
        shared_signature = tuple(typeof(a) for a in shared_arguments)
        _SIGNATURES[id(steps)] = signature, shared_signature
    if is_cached(steps, signature):
        _READY.add(id(steps))
        return steps
    if shared is not None:
        if not is_cached(shared, shared_signature):
            compile_in_background(shared, shared_signature)
            # under the variant's lock: processes that start together compile it once,
            # the others load it
            with variant_lock(steps, signature):
                if not is_cached(steps, signature):
                    _compiling_message(steps)
                steps.compile(signature)
            _READY.add(id(steps))
            return steps
    if _RUNS[id(steps)] >= 2 or n_steps >= LONG_RUN_STEPS:
        compile_in_background(steps, signature)
    return None


def _compiling_message(steps) -> None:
    from ..loops import on_demand

    if on_demand.messages_on():
        import sys

        sys.stderr.write(
            f"galerkin_vi: compiling the loop {steps.py_func.__name__} of this system and "
            "method, about 2 s (once for this machine; the shared loops in the background)\n"
        )


def kernel_path(path: str, generated: bool) -> str:
    """The loop a run took: the integrator's path, ``":system"`` added for a generated loop."""
    return f"{path}:system" if generated else path
