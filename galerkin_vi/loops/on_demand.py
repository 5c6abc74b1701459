"""Each loop variant compiled at its first use, once per machine, in a child process.

A *variant* is one driver of :mod:`galerkin_vi.loops` at one tuple of argument
types (numba compiles one machine-code function per tuple: the structure
switches of :mod:`.traits` are types, ``None`` or an array). A run that calls a
variant which is neither in this process nor in the loops' disk cache
(:func:`galerkin_vi.loops.loop_cache_dir`) has it compiled by a child process
(:func:`compile_request`) and then loads it from the cache:

- the child compiles inside :func:`galerkin_vi.loops.compiling`, numba's compiler
  with the package's faster inliner, which never touches the user's process;
- an OS file lock per variant (``fcntl.flock``, released by the kernel when its
  holder dies) makes processes that start together compile each variant once:
  the second waits for the first and loads its result, and if the first was
  killed mid-compile the second compiles it itself;
- a cache folder that cannot be written (read-only file systems, shared images)
  falls back to compiling in this process, in memory.

A one-line message on stderr names the loop and gives the measured compile
time of that loop (:data:`COMPILE_SECONDS`, 2 cores); ``GALERKIN_VI_QUIET=1`` or
:func:`set_messages` silences it. Processes that compile on purpose (the
warm-up of :mod:`galerkin_vi.tools.warmup`, the children here) compile in
process, under the same locks.
"""

from __future__ import annotations

import contextlib
import hashlib
import importlib
import importlib.util
import os
import pickle
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

from numba.core import caching, sigutils
from numba.core.registry import CPUDispatcher

from ._jit import cache_locators, compiling, driver_dispatcher, loop_cache_dir

try:  # POSIX; elsewhere the variants are compiled without a cross-process lock
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None

__all__ = [
    "COMPILE_CHILD",
    "COMPILE_SECONDS",
    "background_compiles",
    "LoopDispatcher",
    "compile_in_background",
    "compile_in_child",
    "compile_request",
    "driver",
    "is_cached",
    "messages_on",
    "set_messages",
    "start_next_background",
    "variant_lock",
    "wait_for_background",
]

#: set in a process that compiles the loops itself (a warm-up process, a compile child)
COMPILE_CHILD = "GALERKIN_VI_WARMUP_CHILD"
#: the variant a compile child was started for (its parent holds that variant's lock)
_TARGET = "GALERKIN_VI_COMPILE_TARGET"

#: measured seconds to compile each driver's variants alone on the 2-core machine, the
#: largest (``python benchmarks/compile_time.py``, docs/performance.md); the message's
#: estimate
COMPILE_SECONDS: dict[str, float] = {
    "stage_form_loop": 15.0,
    "general_loop": 7.0,
    "linear_loop": 7.0,
    "constrained_loop": 12.0,
    "explicit_loop": 2.0,
    "varying_mass_loop": 6.0,
    "tangent_loop": 25.0,
    "adjoint_sweep": 10.0,
    "constrained_tangent_loop": 20.0,
    "explicit_tangent_loop": 7.0,
    "stationary_path": 15.0,
    "contact_steps": 34.0,
    "contact_step": 12.0,
}

_messages = os.environ.get("GALERKIN_VI_QUIET", "") in ("", "0")


def set_messages(on: bool) -> bool:
    """Turn the one-line "compiling ..." messages on or off; returns the previous setting."""
    global _messages
    previous, _messages = _messages, bool(on)
    return previous


def background_compiles() -> bool:
    """Whether runs may start compiles in the background (``GALERKIN_VI_BACKGROUND=0``
    turns them off: batch jobs without a spare core, test sessions)."""
    return os.environ.get("GALERKIN_VI_BACKGROUND", "") not in ("0", "false", "no")


def messages_on() -> bool:
    """Whether the one-line "compiling ..." messages are on."""
    return _messages


def _name(dispatcher) -> str:
    function = dispatcher.py_func
    return f"{function.__module__}:{function.__qualname__}"


def _variant_key(dispatcher, sig: tuple) -> str:
    text = f"{_name(dispatcher)}{sig!r}"
    return hashlib.sha256(text.encode()).hexdigest()[:24]


def is_cached(dispatcher, sig: tuple) -> bool:
    """Whether ``dispatcher`` has ``sig`` in this process or in its disk cache (no load)."""
    args, _ = sigutils.normalize_signature(sig)
    if tuple(args) in dispatcher.overloads:
        return True
    cache = dispatcher._cache
    if isinstance(cache, caching.NullCache):
        return False
    try:
        key = cache._index_key(sig, dispatcher.targetctx.codegen())
        return key in cache._cache_file._load_index()
    except Exception:  # noqa: BLE001 - an unreadable index is a miss; numba rewrites it
        return False


@contextlib.contextmanager
def variant_lock(dispatcher, sig: tuple) -> Iterator[bool]:
    """Hold the cross-process lock of one variant; yields False where none can be taken.

    The lock is an exclusive ``flock`` on ``locks/<variant>.lock`` in the dispatcher's
    cache folder: the kernel drops it when the holding process ends, however it ends.
    """
    cache = dispatcher._cache
    folder = getattr(cache, "cache_path", None)
    if fcntl is None or folder is None:
        yield False
        return
    path = Path(folder) / "locks" / f"{_variant_key(dispatcher, sig)}.lock"
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o666)
    except OSError:
        yield False
        return
    try:
        fcntl.flock(fd, fcntl.LOCK_EX)
        yield True
    finally:
        os.close(fd)  # closing the descriptor releases the lock


def _message(dispatcher, in_memory: bool = False) -> None:
    if not _messages:
        return
    name = dispatcher.py_func.__name__
    estimate = COMPILE_SECONDS.get(name)
    about = f", about {estimate:.0f} s" if estimate else ""
    if in_memory:
        tail = " in memory (the cache folder cannot be written)"
    else:
        tail = " (once for this machine; `galerkin-vi warmup` compiles every loop ahead of use)"
    sys.stderr.write(f"galerkin_vi: compiling the time loop {name}{about}{tail}\n")
    sys.stderr.flush()


def compile_in_child(dispatcher, sig: tuple) -> float:
    """Compile one variant in a child process, which writes it to the loops' cache.

    Returns the seconds the child took; raises RuntimeError with the child's last
    line of error output if it failed.
    """

    env = dict(
        os.environ,
        # the child must use this process's loop folder, fixed when the loops were imported
        GALERKIN_VI_CACHE_DIR=str(loop_cache_dir().parent.parent),
        **{COMPILE_CHILD: "1", _TARGET: _variant_key(dispatcher, sig)},
    )
    request = pickle.dumps((dispatcher.py_func.__module__, dispatcher.py_func.__qualname__, sig))
    start = time.perf_counter()
    done = subprocess.run(
        [sys.executable, "-c", _CHILD],
        input=request,
        env=env,
        capture_output=True,
        check=False,
    )
    if done.returncode != 0:
        lines = done.stderr.decode(errors="replace").strip().splitlines()
        raise RuntimeError(
            f"compiling the time loop {dispatcher.py_func.__name__} failed: "
            f"{lines[-1] if lines else f'exit status {done.returncode}'}"
        )
    return time.perf_counter() - start


_CHILD = (
    "import sys; from galerkin_vi.loops.on_demand import compile_request; "
    "sys.exit(compile_request(sys.stdin.buffer))"
)


class LoopDispatcher(CPUDispatcher):
    """numba's dispatcher of a loop driver, compiling each variant once per machine.

    ``compile`` is numba's entry for a new tuple of argument types, from a Python
    call and from the typing of another compiled function that calls this one.
    In a user's process a variant that is not cached is compiled by a child under
    the variant's lock and loaded from the cache; in a compiling process
    (``GALERKIN_VI_WARMUP_CHILD``) it is compiled here, under the same lock.
    """

    def compile(self, sig):
        if is_cached(self, sig):
            return super().compile(sig)
        if os.environ.get(COMPILE_CHILD):
            if os.environ.get(_TARGET) == _variant_key(self, sig):
                return super().compile(sig)  # the parent holds this variant's lock
            with variant_lock(self, sig):
                return super().compile(sig)
        with variant_lock(self, sig) as locked:
            if not locked:
                return self._compile_in_memory(sig)
            if not is_cached(self, sig):  # another process may have compiled it meanwhile
                _message(self)
                try:
                    compile_in_child(self, sig)
                except RuntimeError as error:
                    sys.stderr.write(f"galerkin_vi: {error}; compiling in this process\n")
            return super().compile(sig)

    def _compile_in_memory(self, sig):
        """Compile here without writing the cache (its folder cannot be written)."""
        _message(self, in_memory=True)
        cache, self._cache = self._cache, caching.NullCache()
        try:
            return super().compile(sig)
        finally:
            self._cache = cache


def _function_of(module: str, qualname: str, file: str | None):
    """The function a compile request names: by module name, or from a generated file."""
    if file is None:
        target = importlib.import_module(module)
    else:
        spec = importlib.util.spec_from_file_location(module, file)
        target = importlib.util.module_from_spec(spec)
        sys.modules[module] = target
        with cache_locators():
            spec.loader.exec_module(target)
    for part in qualname.split("."):
        target = getattr(target, part)
    return target


def driver(function):
    """Decorator of a loop's entry point: numba-compiled (``nogil``, cached under the cache
    root), each variant compiled at its first use by a child, once per machine."""
    dispatcher = driver_dispatcher(function)
    # same layout as numba's CPUDispatcher; only ``compile`` differs
    dispatcher.__class__ = LoopDispatcher
    return dispatcher


def compile_request(stream) -> int:
    """The child's side: compile the variant named on ``stream`` (pickled) into the cache.

    The request is ``(module, qualname, sig)`` for a loop driver, or
    ``(module, qualname, sig, file, options)`` for a function of a generated module
    (a system's own loop), which is decorated here with numba's ``options`` as the
    parent's and compiled under the variant's lock.
    """
    from numba import jit

    request = pickle.load(stream)
    module, qualname, sig = request[:3]
    if len(request) == 3:
        target = _function_of(module, qualname, None)
        with compiling():
            target.compile(sig)
        return 0
    file, options = request[3:]
    function = _function_of(module, qualname, file)
    with cache_locators():
        target = jit(**options)(function)
    with variant_lock(target, sig):
        if not is_cached(target, sig):
            target.compile(sig)
    return 0


#: the background compiles asked for, by (dispatcher, signature): their child, or None
#: while waiting
_BACKGROUND: dict[tuple, subprocess.Popen | None] = {}
#: the requests waiting for the running child to finish
_PENDING: list[tuple] = []


def compile_in_background(dispatcher, sig: tuple) -> bool:
    """Start compiling ``dispatcher`` for ``sig`` in a child process that this one does
    not wait for; its result lands in the disk cache.

    ``dispatcher`` is a loop driver (:class:`LoopDispatcher`) or a function of a
    generated module (a system's own loop). At most one child per variant and process
    (a failed one is not retried); returns False when one was started before. The
    child takes the variant's lock, so processes that ask at once compile it once.
    """
    start_next_background()  # reaps a finished child, starts a waiting one
    if not background_compiles():
        return False
    key = (id(dispatcher), sig)
    if key in _BACKGROUND:
        return False
    function = dispatcher.py_func
    from ..cache import cache_root

    if isinstance(dispatcher, LoopDispatcher):
        request = pickle.dumps((function.__module__, function.__qualname__, sig))
        # a compiling process that takes the variant's lock itself (no target: nobody
        # holds it for the child)
        env = dict(
            os.environ,
            GALERKIN_VI_CACHE_DIR=str(loop_cache_dir().parent.parent),
            **{COMPILE_CHILD: "1"},
        )
        env.pop(_TARGET, None)
    else:
        options = {k: v for k, v in dispatcher.targetoptions.items() if k != "nopython"}
        options.update(nopython=True, cache=True)
        file = function.__code__.co_filename
        request = pickle.dumps((function.__module__, function.__qualname__, sig, file, options))
        # the generated module's folder is under the cache root as this process reads it now
        env = dict(os.environ, GALERKIN_VI_CACHE_DIR=str(cache_root()))
    _BACKGROUND[key] = None
    _PENDING.append((key, request, env))
    start_next_background()
    return True


def start_next_background() -> None:
    """Start the next waiting background compile unless one is running: one at a time, so
    that a job that runs many systems (``galerkin-vi verify``) never floods the cores."""
    running = [c for c in _BACKGROUND.values() if c is not None and c.poll() is None]
    if running or not _PENDING:
        return
    key, request, env = _PENDING.pop(0)
    child = subprocess.Popen(
        [sys.executable, "-c", _CHILD],
        stdin=subprocess.PIPE,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )
    child.stdin.write(request)
    child.stdin.close()
    _BACKGROUND[key] = child


def wait_for_background(timeout: float | None = None) -> None:
    """Wait for the background compilations this process asked for (tests, benchmarks)."""
    while True:
        running = [c for c in _BACKGROUND.values() if c is not None and c.poll() is None]
        for child in running:
            child.wait(timeout)
        if not _PENDING:
            return
        start_next_background()
