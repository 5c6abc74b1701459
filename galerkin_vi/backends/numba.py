"""Compiled backend: the generated module jitted by numba with an on-disk cache."""

from __future__ import annotations

import importlib.util
import sys
from types import ModuleType

from ..codegen import KernelSpec, render_module, signature
from .cache import entry_path, read_entry, write_entry

__all__ = ["available", "load_kernels", "numba_version"]


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
    if read_entry(key) is None:
        write_entry(key, render_module(spec, key))
    path = entry_path(key)
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
