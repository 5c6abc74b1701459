"""Compiled backend: the generated module jitted by numba with an on-disk cache."""

from __future__ import annotations

import importlib.util
import pickle
import pickletools
import sys
from pathlib import Path
from types import ModuleType

from ..codegen import KernelSpec, render_module, signature
from .cache import entry_path, read_entry, write_entry

__all__ = ["available", "discard_unreadable_numba_cache", "load_kernels", "numba_version"]


def numba_version() -> str | None:
    """The installed numba version, or None when numba cannot be imported."""
    try:
        import numba
    except Exception:  # noqa: BLE001 - any import failure means "not available"
        return None
    return numba.__version__


def available() -> bool:
    """Whether the compiled backend can be used."""
    return numba_version() is not None


def load_kernels(spec: KernelSpec) -> ModuleType:
    """Generate (or find in the cache) and import the kernel module of ``spec``.

    Compilation happens lazily at the first call of each kernel, and numba
    caches the machine code beside the module, so later processes load it.
    """
    key = signature(spec, "numba", numba_version() or "none")
    module_name = f"galerkin_vi_kernel_{key[:32]}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    cached = read_entry(key) is not None
    if not cached:
        write_entry(key, render_module(spec, key))
    try:
        return _import_entry(key, module_name)
    except (SyntaxError, ValueError):
        if not cached:
            raise
    # an entry with intact key lines but damaged in between (bit rot, a foreign
    # edit): rendered afresh and imported once more
    entry_path(key).unlink(missing_ok=True)
    write_entry(key, render_module(spec, key))
    return _import_entry(key, module_name)


def _import_entry(key: str, module_name: str) -> ModuleType:
    """Import the cache entry ``key`` as ``module_name`` (numba compiles lazily)."""
    path = entry_path(key)
    discard_unreadable_numba_cache(path)
    loader_spec = importlib.util.spec_from_file_location(module_name, path)
    assert loader_spec is not None and loader_spec.loader is not None
    module = importlib.util.module_from_spec(loader_spec)
    sys.modules[module_name] = module
    try:
        loader_spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[module_name]
        raise
    return module


def discard_unreadable_numba_cache(module_path: Path) -> list[Path]:
    """Delete numba cache files of ``module_path`` that cannot be read back.

    numba stores each compiled function as an index (``.nbi``: a pickled
    version, then pickled data, both unpickled here) and data files (``.nbc``:
    pickles, only parsed here). A truncated
    or overwritten file makes numba raise at the first call instead of
    recompiling; deleting it makes numba recompile and rewrite it. Returns the
    deleted paths.
    """
    folder = module_path.parent / "__pycache__"
    removed: list[Path] = []
    for index in sorted(folder.glob(f"{module_path.stem}.*.nbi")):
        try:
            with open(index, "rb") as fh:
                pickle.load(fh)
                pickle.loads(fh.read())
            for data in folder.glob(index.name[: -len(".nbi")] + ".*.nbc"):
                # parse the pickle stream without running it: it names the kernel
                # module, which is not importable until this load finishes
                for _opcode in pickletools.genops(data.read_bytes()):
                    pass
        except Exception:  # noqa: BLE001 - any failure to read means: rebuild
            stem = index.name[: -len(".nbi")]
            for stale in [index, *folder.glob(stem + ".*.nbc")]:
                stale.unlink(missing_ok=True)
                removed.append(stale)
    return removed
