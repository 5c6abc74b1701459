"""Stage 3 of code generation: a system's point functions compiled, cached, by address.

The source of :func:`~.source.render_module` is written once to the cache
(``points/gvi_<key>.py`` under :func:`galerkin_vi.cache.cache_root`) and
imported from there; each point function a loop needs is compiled on first
use as a numba ``cfunc`` with numba's own disk cache beside the file, so that
a later process loads it in milliseconds. The loops receive the functions'
addresses (:mod:`galerkin_vi.loops.point` gives the C signatures).

A file whose first and last lines do not carry its key, or that no longer
imports, is written afresh; numba cache files that cannot be read back are
deleted and rebuilt. Two processes that build the same entry at once both
succeed: the source is installed atomically (first complete file wins), and
numba writes its own files through temporary files.
"""

from __future__ import annotations

import hashlib
import importlib.util
import sys
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cache
from pathlib import Path
from types import ModuleType

import numpy as np
from numpy.typing import NDArray

from ..cache import atomic_write, cache_root, discard_unreadable
from .method_steps import LOOP_TEXT, has_method_steps, method_digest, render_method_module
from .slots import POINT_SLOTS
from .source import render_module
from .spec import GENERATOR_VERSION, KernelSpec, signature
from .velocity_steps import VELOCITY_LOOP_TEXT, has_velocity_steps, render_velocity_module

__all__ = [
    "PointFunctions",
    "discard_unreadable_numba_cache",
    "entry_path",
    "load_point_functions",
    "point_key",
    "numba_version",
    "read_entry",
]

_LOCK = threading.Lock()
# compiled point functions stay alive while the process runs: loops hold their addresses
_LOADED: dict[str, PointFunctions] = {}


def numba_version() -> str | None:
    """The installed numba version, or None when numba cannot be imported."""
    try:
        import numba
    except Exception:  # noqa: BLE001 - any import failure means "not available"
        return None
    return numba.__version__


def _c_signatures() -> dict:
    from numba import types

    double = types.float64
    ptr = types.CPointer(double)
    return {
        "point_gradient": types.void(double, *(ptr,) * 5),
        "point_hessian": types.void(double, *(ptr,) * 9),
        "lagrangian": double(double, *(ptr,) * 3),
        "point_constraint": types.void(double, *(ptr,) * 3),
        "point_constraint_jacobian": types.void(double, *(ptr,) * 3),
        "point_constraint_rate": types.void(double, *(ptr,) * 3),
        "point_constraint_hessian": types.void(double, *(ptr,) * 4),
        "point_mass": types.void(double, *(ptr,) * 7),
        "point_velocity": types.void(double, *(ptr,) * 5),
        "point_contact": types.void(double, *(ptr,) * 6),
        "point_slip": types.void(double, *(ptr,) * 7),
    }


@cache
def generator_fingerprint() -> str:
    """The code generator's version and a hash of its sources (codegen/*.py, the
    repeated-term analysis it reads, and the loops, whose stopping rule the generated
    stage-form loop compiles in): a point-function key remembered by an earlier
    process is trusted only under the same fingerprint and numba version."""
    h = hashlib.sha256(GENERATOR_VERSION.encode())
    for path in fingerprint_sources():
        h.update(path.read_bytes())
    return h.hexdigest()[:16]


def fingerprint_sources() -> list[Path]:
    """The files :func:`generator_fingerprint` hashes."""
    here = Path(__file__).resolve().parent
    package = here.parent
    sources = sorted(here.glob("*.py")) + [package / "model" / "terms.py"]
    return sources + sorted((package / "loops").glob("*.py")) + [package / "newton.py"]


def entry_path(key: str) -> Path:
    """Path of the source file of cache entry ``key``."""
    return cache_root() / "points" / f"gvi_{key[:32]}.py"


def read_entry(key: str) -> str | None:
    """The cached source for ``key``, or None if absent or corrupt."""
    try:
        text = entry_path(key).read_text()
    except (FileNotFoundError, UnicodeDecodeError):
        return None
    lines = text.rstrip("\n").splitlines()
    if not lines or key not in lines[0] or key not in lines[-1]:
        return None
    return text


@dataclass
class PointFunctions:
    """One system's point functions: their module and the ones compiled so far."""

    key: str
    module: ModuleType
    compiled: dict = field(default_factory=dict)
    loops: dict = field(default_factory=dict)

    @property
    def source(self) -> str:
        """The generated source text."""
        return entry_path(self.key).read_text()

    def addresses(self, names: tuple[str, ...]) -> NDArray[np.int64]:
        """Addresses in the slots of :data:`POINT_SLOTS`, compiling ``names``.

        Slots of functions not asked for (nor compiled before) hold 0.
        """
        from numba import cfunc

        from ..loops import cache_locators

        signatures = _c_signatures()
        with _LOCK, cache_locators():
            for name in names:
                if name not in self.compiled:
                    function = getattr(self.module, name)
                    self.compiled[name] = cfunc(signatures[name], cache=True, error_model="numpy")(
                        function
                    )
        out = np.zeros(len(POINT_SLOTS), dtype=np.int64)
        for name, compiled in self.compiled.items():
            out[POINT_SLOTS[name]] = _body_address(compiled)
        return out

    def generated_loop(self, name: str) -> Callable | None:
        """The system's generated loop ``name`` (``"explicit_steps"``, ``"stage_steps"``:
        :mod:`.explicit_steps`, :mod:`.stage_steps`), or None when it has none.

        numba compiles it on its first call (``nogil``, so that threads run it at
        once) and caches it beside the source.
        """
        function = getattr(self.module, name, None)
        if function is None:
            return None
        from numba import njit

        from ..loops import cache_locators

        with _LOCK, cache_locators():
            if name not in self.loops:
                self.loops[name] = njit(cache=True, nogil=True, error_model="numpy")(function)
        return self.loops[name]

    def stage_loop(self, b, c, tables) -> Callable | None:
        """The generated stage-form loop of this system for the method of ``b``, ``c``
        and ``tables`` (its :class:`~galerkin_vi.method.stage_form.SeparableTables`), or
        None when the system has none.

        The loop written for this system and this method (:mod:`.method_steps`) where
        :func:`.method_steps.has_method_steps`, else the system's own
        (:mod:`.stage_steps`). The former's source is a cache entry of its own, keyed
        by this module's key, the method's tables and the generator's fingerprint;
        numba compiles it on its first call and caches it beside the source.
        """
        text = getattr(self.module, LOOP_TEXT, None)
        if text is None:
            return None
        if not has_method_steps(text["n"], tables):
            return self.generated_loop("stage_steps")
        return self._method_module(
            method_digest(b, c, tables),
            lambda key: render_method_module(text, b, c, tables, key),
            "method_steps",
        )

    def velocity_loop(self, tables) -> Callable | None:
        """The velocity-stage loop generated for this system and the method of
        ``tables`` (:class:`~galerkin_vi.method.velocity_stages.VaryingMassTables`;
        :mod:`.velocity_steps`), or None when the system has no closed-form velocity
        or the method too many stages for it (:func:`.velocity_steps.has_velocity_steps`).
        Cached as :meth:`stage_loop`'s."""
        text = getattr(self.module, VELOCITY_LOOP_TEXT, None)
        if text is None or not has_velocity_steps(text["n"], tables):
            return None
        digest = "velocity:" + method_digest(tables.b, tables.c, tables)
        return self._method_module(
            digest, lambda key: render_velocity_module(text, tables, key), "velocity_steps"
        )

    def _method_module(self, digest: str, render: Callable, name: str) -> Callable:
        """The compiled function ``name`` of the module ``render(key)`` writes, cached
        under a key of this module's key, ``digest`` and the generator's fingerprint."""
        with _LOCK:
            loop = self.loops.get(digest)
            if loop is not None:
                return loop
            key = hashlib.sha256(
                f"{self.key}:{digest}:{generator_fingerprint()}".encode()
            ).hexdigest()
            cached = read_entry(key) is not None
            if not cached:
                atomic_write(entry_path(key), render(key))
            module_name = f"galerkin_vi_method_{key[:32]}"
            try:
                module = _import_entry(key, module_name)
            except (SyntaxError, ValueError):
                if not cached:
                    raise
                # intact key lines, damaged in between: as in _load_module
                atomic_write(entry_path(key), render(key))
                module = _import_entry(key, module_name)
            from numba import njit

            from ..loops import cache_locators

            with cache_locators():
                loop = njit(cache=True, nogil=True, error_model="numpy")(getattr(module, name))
            self.loops[digest] = loop
        return loop


def _body_address(compiled) -> int:
    """Address of the compiled body inside a numba ``cfunc`` (not of its C wrapper).

    The loops call the body directly with numba's calling convention
    (:mod:`galerkin_vi.loops.point`): one call per evaluation instead of two.
    The body's symbol is the wrapper's without numba's ``cfunc.`` prefix.
    """
    name = compiled._wrapper_name
    prefix = "cfunc."
    if not name.startswith(prefix):
        raise RuntimeError(f"unexpected numba cfunc wrapper name {name!r}")
    return compiled._library.get_pointer_to_function(name[len(prefix) :])


def point_key(spec: KernelSpec) -> str:
    """The cache key of ``spec``'s point functions for this numba."""
    return signature(spec, "numba", numba_version() or "none")


def load_point_functions(
    spec: KernelSpec | Callable[[], KernelSpec], key: str | None = None
) -> PointFunctions:
    """Generate (or find in the cache) and import the point functions of ``spec``.

    ``spec`` may be a function that builds it, called only when the module is
    not in the cache yet; ``key`` (from :func:`point_key`) must then be given.
    """
    if key is None:
        if callable(spec):
            raise ValueError("give the key when the spec is built on demand")
        key = point_key(spec)
    with _LOCK:
        loaded = _LOADED.get(key)
        if loaded is None:
            loaded = _LOADED[key] = PointFunctions(key, _load_module(spec, key))
    return loaded


def _load_module(spec, key: str) -> ModuleType:
    module_name = f"galerkin_vi_points_{key[:32]}"
    cached = read_entry(key) is not None
    if not cached:
        atomic_write(entry_path(key), render_module(_built(spec), key))
    try:
        return _import_entry(key, module_name)
    except (SyntaxError, ValueError):
        if not cached:
            raise
    # an entry with intact key lines but damaged in between (bit rot, a foreign
    # edit): rendered afresh and imported once more
    entry_path(key).unlink(missing_ok=True)
    atomic_write(entry_path(key), render_module(_built(spec), key))
    return _import_entry(key, module_name)


def _built(spec) -> KernelSpec:
    return spec() if callable(spec) else spec


def discard_unreadable_numba_cache(module_path: Path) -> list[Path]:
    """Delete the numba cache files of ``module_path`` that cannot be read back."""
    return discard_unreadable(module_path.parent / "__pycache__", module_path.stem)


def _import_entry(key: str, module_name: str) -> ModuleType:
    """Import the cache entry ``key`` as ``module_name``."""
    path = entry_path(key)
    discard_unreadable_numba_cache(path)
    loader_spec = importlib.util.spec_from_file_location(module_name, path)
    assert loader_spec is not None and loader_spec.loader is not None
    module = importlib.util.module_from_spec(loader_spec)
    sys.modules[module_name] = module
    from ..loops import cache_locators

    try:
        with cache_locators():  # its njit(cache=True) parts pick their locator here
            loader_spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[module_name]
        raise
    return module
