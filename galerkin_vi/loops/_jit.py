"""The two decorators of the loops, where numba caches what they compile, and how.

``kernel`` marks a helper: inlined (in numba's IR) into every loop that
calls it, never compiled on its own: plain calls between compiled functions
pay numba's reference counting at each call, a large share of a small
system's step, which outweighs the longer compile time of inlined code.
:func:`driver_dispatcher` makes a loop's entry point (:func:`.on_demand.driver` the
decorator): compiled once per machine and argument types and cached on disk by
numba, with numba's compiler plus one pass,
:func:`fold_switch_tests`, that drops the branches of a switch that is data
(:mod:`.traits`) before typing, as numba drops those of a switch that is ``None``.

numba would cache a driver beside its source file, and judge staleness by that
file alone; a driver inlines helpers from several modules, so an edit to one
of them would go unnoticed. :class:`LoopCacheLocator` puts the cache of every
driver under :func:`galerkin_vi.cache.cache_root` in a folder named after a
hash of all loop sources (and numba's and Python's versions): any edit, or a
new package version, starts a fresh folder. numba takes its locators from one
global list; :func:`cache_locators` puts the package's there only while a driver
is decorated or a system's point functions are loaded, so a user's own cached
functions never meet them.

:func:`compiling` makes numba's compiler faster on the loops' large inlined IR
(three replacements of numba's internals). It is a context manager, entered only
while the package compiles its own loops (the warm-up processes of
:mod:`galerkin_vi.tools.warmup`): importing the package leaves numba as it is,
and the user's own numba code never compiles through these replacements.
"""

from __future__ import annotations

import copy
import hashlib
import sys
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from functools import cache
from pathlib import Path

import numba
from numba import njit
from numba.core import caching

from ..cache import cache_root, discard_unreadable

__all__ = [
    "LoopCacheLocator",
    "PointCacheLocator",
    "cache_locators",
    "called",
    "compiling",
    "discard_unreadable_loops",
    "driver_dispatcher",
    "kernel",
    "loop_cache_dir",
    "scalar",
]

_PACKAGE = Path(__file__).resolve().parent.parent
# every source a compiled loop is made of (the slot table and the interior point's
# tolerances: their numbers are compiled in)
_SOURCES = ("newton.py", "interior_point.py", "loops", "codegen/slots.py")
# modules of the loops' folder that decide when and where to compile, not what
_NOT_COMPILED = frozenset({"on_demand.py", "readiness.py"})


@cache
def _source_hash() -> str:
    h = hashlib.sha256()
    for name in _SOURCES:
        path = _PACKAGE / name
        files = sorted(path.glob("*.py")) if path.is_dir() else [path]
        for file in files:
            if file.name in _NOT_COMPILED:
                continue
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
        try:
            ours = path.resolve().parent == (cache_root() / "points").resolve()
        except OSError:
            return None
        if not ours or not path.name.startswith("gvi_"):
            return None
        return super().from_function(py_func, py_file)


@contextmanager
def cache_locators() -> Iterator[None]:
    """numba's cache locators of the package's compiled code, registered for the block only.

    numba picks a function's cache locator once, when the function is decorated
    with ``cache=True`` (a driver at its module's import, a point function when its
    module is loaded or compiled); outside these blocks numba's list of locators is
    numba's own, so a user's cached functions never meet the package's.
    """
    # numba 0.68 renamed _CacheImpl to CacheImpl; without either, numba's own
    # locators cache the loops beside their sources (staleness by file date)
    impl = getattr(caching, "CacheImpl", None) or getattr(caching, "_CacheImpl", None)
    classes = getattr(impl, "_locator_classes", None)
    added = []
    if isinstance(classes, list):
        added = [c for c in (PointCacheLocator, LoopCacheLocator) if c not in classes]
        classes[:0] = added
    try:
        yield
    finally:
        for locator in added:
            classes.remove(locator)


@cache
def discard_unreadable_loops() -> list[Path]:
    """Delete the loops' cache files that cannot be read back; once per process.

    A truncated index or data file (a killed writer, a full disk) would make
    numba raise instead of compiling again. Called where the loops are first
    made ready (:func:`galerkin_vi.loops.readiness.ensure_loops`), before numba
    reads the folder.
    """
    return discard_unreadable(loop_cache_dir())


class _SharedMemoCopy:
    """The ``copy`` module as numba's IR inliner sees it, with one memo per inlining.

    ``InlineWorker.inline_ir`` deep-copies the callee's IR block by block, each
    with a fresh memo, so every block drags along its own copy of the whole
    variable scope that all blocks share: quadratic in the callee's size. Inside
    one ``inline_ir`` call this module's ``deepcopy`` shares one memo, so the
    scope is copied once and the copied blocks share it, as the original ones do.
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


@dataclass(frozen=True)
class _Originals:
    """numba's own attributes that :func:`compiling` replaces, to put back on exit."""

    inline_ir: object
    inliner_copy: object
    postproc_run: object
    get_block_entry_vars: object
    run_untyped_passes: object


def _shared_memo_inline_ir(inline_ir, state):
    """``InlineWorker.inline_ir`` with one deep-copy memo per call (:class:`_SharedMemoCopy`)."""

    def shared_memo_inline_ir(self, *args, **kwargs):
        outer = getattr(state, "memo", None)
        state.memo = {}
        try:
            return inline_ir(self, *args, **kwargs)
        finally:
            state.memo = outer

    return shared_memo_inline_ir


def _memo_untyped_passes(run_untyped_passes):
    """``InlineWorker.run_untyped_passes`` remembering each helper's IR for the block.

    numba's inliner builds a helper's IR anew (bytecode, untyped passes and the inlining
    of the helper's own helpers) at every call site, although it depends only on the
    function and the compiler's flags and locals; ``inline_ir`` copies it before it
    changes anything. Here it is built once per helper and :func:`compiling` block.
    """
    memo = {}

    def memo_run_untyped_passes(self, func, enable_ssa=False):
        self.flags.enable_ssa = enable_ssa  # as numba's does, on the caller's flags
        try:
            key = (func, self.flags.copy(), frozenset(self.locals.items()), self.pipeline)
            hash(key)
        except TypeError:
            return run_untyped_passes(self, func, enable_ssa)
        if key not in memo:
            memo[key] = run_untyped_passes(self, func, enable_ssa)
        return memo[key]

    return memo_run_untyped_passes


def _lean_postproc(run, get):
    """``PostProcessor.run`` and ``FunctionIR.get_block_entry_vars`` with liveness on demand.

    ``PostProcessor.run`` runs after every change of a function's IR, and for
    every function it solves two data-flow fixed points for the variables live
    at each block's entry. In nopython mode only generators read that result
    (object-mode lowering reads it too); the loops' inlined IR, thousands of
    blocks, would pay for it after every inlining. Here it is computed for
    generators as numba does, and for other functions only when asked for
    (``FunctionIR.get_block_entry_vars``, from the final blocks). The machine
    code of the loops is the same instruction for instruction.
    """
    from numba.core import analysis, postproc

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

    return lean_run, block_entry_vars_on_demand


def _numba_originals() -> _Originals | None:
    """numba's attributes that :func:`compiling` replaces, or None if its layout differs."""
    from numba.core import inline_closurecall, ir, postproc

    worker = getattr(inline_closurecall, "InlineWorker", None)
    originals = _Originals(
        inline_ir=getattr(worker, "inline_ir", None),
        inliner_copy=getattr(inline_closurecall, "copy", None),
        postproc_run=getattr(postproc.PostProcessor, "run", None),
        get_block_entry_vars=getattr(ir.FunctionIR, "get_block_entry_vars", None),
        run_untyped_passes=getattr(worker, "run_untyped_passes", None),
    )
    if (
        None
        in (
            originals.inline_ir,
            originals.postproc_run,
            originals.get_block_entry_vars,
            originals.run_untyped_passes,
        )
        or originals.inliner_copy is not copy
    ):
        return None
    if not all(hasattr(postproc, name) for name in ("transforms", "VariableLifetime")):
        return None
    return originals


def _install(originals: _Originals) -> None:
    from numba.core import inline_closurecall, ir, postproc

    state = threading.local()
    inline_closurecall.copy = _SharedMemoCopy(copy, state)
    inline_closurecall.InlineWorker.inline_ir = _shared_memo_inline_ir(originals.inline_ir, state)
    inline_closurecall.InlineWorker.run_untyped_passes = _memo_untyped_passes(
        originals.run_untyped_passes
    )
    run, get = _lean_postproc(originals.postproc_run, originals.get_block_entry_vars)
    postproc.PostProcessor.run = run
    ir.FunctionIR.get_block_entry_vars = get


def _restore(originals: _Originals) -> None:
    from numba.core import inline_closurecall, ir, postproc

    inline_closurecall.copy = originals.inliner_copy
    inline_closurecall.InlineWorker.inline_ir = originals.inline_ir
    inline_closurecall.InlineWorker.run_untyped_passes = originals.run_untyped_passes
    postproc.PostProcessor.run = originals.postproc_run
    ir.FunctionIR.get_block_entry_vars = originals.get_block_entry_vars


_COMPILING_LOCK = threading.Lock()
_compiling_depth = 0
_installed: _Originals | None = None


@contextmanager
def compiling() -> Iterator[None]:
    """Compile the loops with the faster inliner and post-processor, numba's own after.

    Inside the ``with`` block numba's IR inliner builds each helper's IR once
    (:func:`_memo_untyped_passes`, not once per call site), copies each callee's variable
    scope once per inlining (:class:`_SharedMemoCopy`) and its post-processor
    computes block-entry liveness only on demand (:func:`_lean_postproc`), work
    that grows with the size of the inlined IR (docs/design-notes.md,
    "Compiling the loops"). On exit numba's originals are back in place.
    Nested blocks install once; with a numba whose internals differ the block
    compiles with numba's own. Process-wide while active: enter it only in a
    process that compiles nothing else meanwhile (the warm-up).
    """
    global _compiling_depth, _installed
    with _COMPILING_LOCK:
        if _compiling_depth == 0:
            _installed = _numba_originals()
            if _installed is not None:
                _install(_installed)
        _compiling_depth += 1
    try:
        yield
    finally:
        with _COMPILING_LOCK:
            _compiling_depth -= 1
            if _compiling_depth == 0 and _installed is not None:
                _restore(_installed)
                _installed = None


# numba's NumPy error model: a division by zero gives inf or NaN, which the loops
# report as a failed step with the partial trajectory, instead of raising out of them
kernel = njit(inline="always", error_model="numpy", cache=False)
# helpers of scalars only: ordinary calls, which LLVM inlines (no reference counts to
# pay), so that numba's IR inliner does not copy them into every call site
scalar = njit(error_model="numpy", cache=False)
# helpers with much work per call (the contact step's equations and blockwise solve):
# ordinary calls, typed and lowered once per signature instead of at every call site
called = njit(error_model="numpy", cache=False)


def _never_none(typ) -> bool:
    """Whether an argument of numba type ``typ`` can never be ``None`` (a switch that is data)."""
    from numba.core import types

    return isinstance(typ, (types.Array, types.BaseTuple, types.Number, types.Boolean))


def fold_switch_tests(func_ir, arg_types) -> int:
    """Rewrite ``x is None`` and ``x is not None`` into constants where ``x`` is a driver
    argument of a type that is never None; the number of tests rewritten.

    numba's dead branch pruning decides these tests only for arguments typed ``None``
    (:mod:`.traits`: ``pattern``, ``mass_diagonal``, ... of a variant where they are
    absent); where the switch is an array the test stays, and the branch for ``None``
    with everything inlined into it (the dense LU solve of a variant with a diagonal
    mass, the dense block assembly of a banded one) is typed and lowered, for LLVM to
    delete. As constants, numba's next pruning pass drops those branches before typing.
    """
    import operator

    from numba.core import ir
    from numba.core.ir_utils import get_definition, guard

    if not arg_types:
        return 0

    def side(var):
        found = guard(get_definition, func_ir, var)
        if isinstance(found, ir.Const) and found.value is None:
            return "none"
        if isinstance(found, ir.Arg) and found.index < len(arg_types):
            if _never_none(arg_types[found.index]):
                return "data"
        return None

    folded = 0
    for block in func_ir.blocks.values():
        for stmt in block.body:
            if not (isinstance(stmt, ir.Assign) and isinstance(stmt.value, ir.Expr)):
                continue
            expr = stmt.value
            if expr.op != "binop" or expr.fn not in (operator.is_, operator.is_not):
                continue
            if {side(expr.lhs), side(expr.rhs)} != {"none", "data"}:
                continue
            const = ir.Const(expr.fn is operator.is_not, loc=expr.loc)
            definitions = func_ir._definitions[stmt.target.name]
            if expr in definitions:
                definitions[definitions.index(expr)] = const
            stmt.value = const
            folded += 1
    return folded


def _loop_compiler():
    """numba's compiler with :func:`fold_switch_tests` before each dead branch pruning."""
    from numba.core.compiler import CompilerBase, DefaultPassBuilder
    from numba.core.compiler_machinery import FunctionPass, register_pass
    from numba.core.untyped_passes import DeadBranchPrune

    @register_pass(mutates_CFG=False, analysis_only=False)
    class FoldSwitchTests(FunctionPass):
        _name = "galerkin_vi_fold_switch_tests"

        def __init__(self):
            FunctionPass.__init__(self)

        def run_pass(self, state):
            return fold_switch_tests(state.func_ir, state.args) > 0

    class LoopCompiler(CompilerBase):
        def define_pipelines(self):
            pm = DefaultPassBuilder.define_nopython_pipeline(self.state)
            if not self.state.flags.force_pyobject:
                passes = []
                for each in pm.passes:
                    if each[0] is DeadBranchPrune:
                        passes.append((FoldSwitchTests, "fold the tests of switches"))
                    passes.append(each)
                pm.passes[:] = passes
                pm.finalize()
            else:  # pragma: no cover - the drivers are nopython
                pm = DefaultPassBuilder.define_objectmode_pipeline(self.state)
            return [pm]

    return LoopCompiler


_LOOP_COMPILER = _loop_compiler()
_DRIVER = njit(cache=True, error_model="numpy", nogil=True, pipeline_class=_LOOP_COMPILER)


def driver_dispatcher(function):
    """numba's dispatcher of a loop's entry point: ``nogil``, cached under the cache root,
    compiled through :func:`fold_switch_tests`. :func:`galerkin_vi.loops.on_demand.driver`
    makes it compile each variant at first use, in a child process."""
    with cache_locators():
        return _DRIVER(function)
