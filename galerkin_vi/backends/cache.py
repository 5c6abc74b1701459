"""On-disk cache of generated kernel modules.

Layout: ``<cache root>/v<generator version>/gvi_<key>.py``, with numba's own
cache files in ``__pycache__`` beside it. The root is
``$GALERKIN_VI_CACHE_DIR`` when set (read at call time), else the user cache
directory of the platform.

A module is written to a private temporary file and then hard-linked into
place, which fails if another process got there first: the first complete
file wins and is never rewritten, so its timestamp (numba's staleness check)
stays stable. A file whose first and last lines do not carry its key is
treated as corrupt and replaced.
"""

from __future__ import annotations

import os
import tempfile
from pathlib import Path

import platformdirs

from ..codegen import GENERATOR_VERSION

__all__ = ["cache_root", "entry_path", "read_entry", "write_entry"]


def cache_root() -> Path:
    """The cache directory (``GALERKIN_VI_CACHE_DIR`` overrides the default)."""
    override = os.environ.get("GALERKIN_VI_CACHE_DIR")
    base = Path(override) if override else Path(platformdirs.user_cache_dir("galerkin_vi"))
    return base / f"v{GENERATOR_VERSION}"


def entry_path(key: str) -> Path:
    """Path of the module file of cache entry ``key``."""
    return cache_root() / f"gvi_{key[:32]}.py"


def read_entry(key: str) -> str | None:
    """The cached source for ``key``, or None if absent or corrupt."""
    path = entry_path(key)
    try:
        text = path.read_text()
    except (FileNotFoundError, UnicodeDecodeError):
        return None
    lines = text.rstrip("\n").splitlines()
    if not lines or key not in lines[0] or key not in lines[-1]:
        return None
    return text


def write_entry(key: str, source: str) -> Path:
    """Install ``source`` as the entry for ``key`` (atomic; first writer wins)."""
    path = entry_path(key)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.stem + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(source)
        try:
            os.link(tmp, path)
        except FileExistsError:
            if read_entry(key) != source:
                os.replace(tmp, path)
                tmp = ""
    finally:
        if tmp:
            os.unlink(tmp)
    return path
