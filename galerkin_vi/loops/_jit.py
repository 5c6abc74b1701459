"""The two decorators of the loops and where numba caches what they compile.

``kernel`` marks a helper: inlined (in numba's IR) into every loop that
calls it, never compiled on its own; measured, plain calls between compiled
functions (numba's reference counting at each call) made the stage form 2x
slower per step, while halving the compile time. ``driver`` marks a loop's
entry point: compiled once per machine and argument types and cached on disk
by numba.

numba would cache a driver beside its source file, and judge staleness by that
file alone; a driver inlines helpers from several modules, so an edit to one
of them would go unnoticed. :class:`LoopCacheLocator` puts the cache of every
driver under :func:`galerkin_vi.cache.cache_root` in a folder named after a
hash of all loop sources (and numba's and Python's versions): any edit, or a
new package version, starts a fresh folder.
"""

from __future__ import annotations

import hashlib
import sys
from functools import cache
from pathlib import Path

import numba
from numba import njit
from numba.core import caching

from ..cache import cache_root, discard_unreadable

__all__ = [
    "LoopCacheLocator",
    "PointCacheLocator",
    "driver",
    "kernel",
    "loop_cache_dir",
    "scalar",
]

_PACKAGE = Path(__file__).resolve().parent.parent
# every source a compiled loop is made of
_SOURCES = ("newton.py", "loops")


@cache
def _source_hash() -> str:
    h = hashlib.sha256()
    for name in _SOURCES:
        path = _PACKAGE / name
        files = sorted(path.glob("*.py")) if path.is_dir() else [path]
        for file in files:
            h.update(file.name.encode())
            h.update(file.read_bytes())
    return h.hexdigest()[:20]


@cache
def loop_cache_dir() -> Path:
    """The folder of the loops' compiled code for this package, numba and Python.

    Fixed for the process when the loops are first imported (numba binds each
    loop's cache to a folder then); ``GALERKIN_VI_CACHE_DIR`` set later does
    not move it.
    """
    tag = f"numba{numba.__version__}-py{sys.version_info.major}{sys.version_info.minor}"
    return cache_root() / "loops" / f"{tag}-{_source_hash()}"


class LoopCacheLocator(caching._CacheLocator):
    """numba cache locator for the drivers of :mod:`galerkin_vi.loops`."""

    def __init__(self, py_func, py_file):
        self._py_file = py_file
        self._lineno = py_func.__code__.co_firstlineno
        self._cache_path = str(loop_cache_dir())

    def get_cache_path(self):
        return self._cache_path

    def get_source_stamp(self):
        return _source_hash()

    def get_disambiguator(self):
        return str(self._lineno)

    @classmethod
    def from_function(cls, py_func, py_file):
        try:
            inside = Path(py_file).resolve().parent == Path(__file__).resolve().parent
        except OSError:
            return None
        if not inside:
            return None
        locator = cls(py_func, py_file)
        try:
            locator.ensure_cache_path()
        except OSError:
            return None  # unwritable: numba's own locators decide
        return locator


class PointCacheLocator(caching.InTreeCacheLocator):
    """numba cache locator for the point functions of :mod:`galerkin_vi.codegen.compiled`.

    Their compiled code stays beside their source, in ``points/__pycache__`` under
    the cache root, even when ``NUMBA_CACHE_DIR`` is set: one folder to clear.
    """

    @classmethod
    def from_function(cls, py_func, py_file):
        path = Path(py_file)
        if path.parent.name != "points" or not path.name.startswith("gvi_"):
            return None
        return super().from_function(py_func, py_file)


def _register_locators() -> None:
    # numba 0.68 renamed _CacheImpl to CacheImpl; without either, numba's own
    # locators cache the loops beside their sources (staleness by file date)
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    if isinstance(classes, list):
        for locator in (PointCacheLocator, LoopCacheLocator):
            if locator not in classes:
                classes.insert(0, locator)


_register_locators()


class _SharedMemoCopy:
    """The ``copy`` module as numba's IR inliner sees it, with one memo per inlining.

    ``InlineWorker.inline_ir`` deep-copies the callee's IR block by block, each
    with a fresh memo, so every block drags along its own copy of the whole
    variable scope that all blocks share: quadratic in the callee's size. Inside
    one ``inline_ir`` call this module's ``deepcopy`` shares one memo, so the
    scope is copied once and the copied blocks share it, as the original ones do.
    Measured: compiling the stage form 10.5 -> 6.8 s, the general loop 7.1 -> 3.8 s.
    """

    def __init__(self, module, state):
        self._module = module
        self._state = state

    def __getattr__(self, name):
        return getattr(self._module, name)

    def deepcopy(self, x, memo=None):
        shared = getattr(self._state, "memo", None)
        if memo is None and shared is not None:
            memo = shared
        return self._module.deepcopy(x, memo)


def _share_inliner_memo() -> None:
    """Install :class:`_SharedMemoCopy` in numba's inliner (skipped if its layout differs)."""
    import copy
    import threading

    from numba.core import inline_closurecall

    worker = getattr(inline_closurecall, "InlineWorker", None)
    inline_ir = getattr(worker, "inline_ir", None)
    if inline_ir is None or getattr(inline_ir, "_galerkin_vi", False):
        return
    if getattr(inline_closurecall, "copy", None) is not copy:
        return
    state = threading.local()
    inline_closurecall.copy = _SharedMemoCopy(copy, state)

    def shared_memo_inline_ir(self, *args, **kwargs):
        outer = getattr(state, "memo", None)
        state.memo = {}
        try:
            return inline_ir(self, *args, **kwargs)
        finally:
            state.memo = outer

    shared_memo_inline_ir._galerkin_vi = True
    worker.inline_ir = shared_memo_inline_ir


_share_inliner_memo()


def _skip_entry_liveness() -> None:
    """Let numba's IR post-processor skip the block-entry liveness of ordinary functions.

    ``PostProcessor.run`` runs after every change of a function's IR, and for
    every function it solves two data-flow fixed points for the variables live
    at each block's entry. In nopython mode only generators read that result
    (object-mode lowering reads it too); the loops' inlined IR, thousands of
    blocks, paid for it after every inlining. Here it is computed for generators
    as before, and for other functions only when asked for
    (``FunctionIR.get_block_entry_vars``, from the final blocks). Skipped if
    numba's layout differs. Measured: `galerkin-vi warmup` from an empty cache
    130-153 s -> 109-112 s (two alternating rounds, 2-core machine); the stage
    form's machine code is the same instruction for instruction.
    """
    from numba.core import analysis, ir, postproc

    run = getattr(postproc.PostProcessor, "run", None)
    get = getattr(ir.FunctionIR, "get_block_entry_vars", None)
    needed = ("transforms", "VariableLifetime")
    if run is None or get is None or getattr(run, "_galerkin_vi", False):
        return
    if not all(hasattr(postproc, name) for name in needed):
        return

    def lean_run(self, emit_dels: bool = False, extend_lifetimes: bool = False):
        func_ir = self.func_ir
        if func_ir.is_generator:
            return run(self, emit_dels, extend_lifetimes)
        func_ir.blocks = postproc.transforms.canonicalize_cfg(func_ir.blocks)
        func_ir.variable_lifetime = postproc.VariableLifetime(func_ir.blocks)
        func_ir.generator_info = None
        if emit_dels:
            self._insert_var_dels(extend_lifetimes=extend_lifetimes)
        return None

    def block_entry_vars_on_demand(self, block):
        if block not in self.block_entry_vars:
            lifetime = postproc.VariableLifetime(self.blocks)
            live = analysis.compute_live_variables(
                lifetime.cfg, self.blocks, lifetime.usedefs.defmap, lifetime.deadmaps.combined
            )
            for offset, each in self.blocks.items():
                self.block_entry_vars[each] = live[offset]
        return get(self, block)

    lean_run._galerkin_vi = True
    postproc.PostProcessor.run = lean_run
    ir.FunctionIR.get_block_entry_vars = block_entry_vars_on_demand


_skip_entry_liveness()
# a truncated index or data file (a killed writer, a full disk) would make numba
# raise instead of compiling again
discard_unreadable(loop_cache_dir())

# numba's NumPy error model: a division by zero gives inf or NaN, which the loops
# report as a failed step with the partial trajectory, instead of raising out of them
kernel = njit(inline="always", error_model="numpy", cache=False)
# helpers of scalars only: ordinary calls, which LLVM inlines (no reference counts to
# pay), so that numba's IR inliner does not copy them into every call site
scalar = njit(error_model="numpy", cache=False)
driver = njit(cache=True, error_model="numpy", nogil=True)
