"""Where galerkin_vi keeps what it compiles, and how an entry is written safely.

Layout under the cache root (``$GALERKIN_VI_CACHE_DIR``; else
``$NUMBA_CACHE_DIR/galerkin_vi``; else the platform's user cache directory,
read at call time)::

    loops/<numba>-<python>-<source hash>/    numba's cache of the time loops (once per machine)
    points/gvi_<key>.py                      one system's point functions (generated source)
    points/__pycache__/                      numba's cache of their compiled C functions
                                             (here even when NUMBA_CACHE_DIR is set)
    systems/<key>.pickle                     a system's symbolic analysis (derivatives,
                                             structure), keyed by its input expressions

The loops' folder is named after a hash of their sources, so an edited or
upgraded package compiles them afresh; a system's entry is named after a hash
of its expressions and of the generator (:func:`galerkin_vi.codegen.signature`).
Deleting the root clears everything; it is rebuilt on the next use.
"""

from __future__ import annotations

import os
import pickle
import tempfile
from pathlib import Path

import platformdirs

__all__ = ["atomic_write", "atomic_write_bytes", "cache_root", "discard_unreadable"]


def cache_root() -> Path:
    """The cache directory (see the module docstring for the order of the overrides)."""
    override = os.environ.get("GALERKIN_VI_CACHE_DIR")
    if override:
        return Path(override)
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "galerkin_vi"
    return Path(platformdirs.user_cache_dir("galerkin_vi"))


def atomic_write(path: Path, text: str) -> bool:
    """Install ``text`` at ``path`` unless a complete file is already there.

    The text goes to a private temporary file that is then hard-linked into
    place, which fails if another process got there first: the first complete
    file wins and is never rewritten (its timestamp, numba's staleness check,
    stays stable). Returns True when this call wrote the file.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.stem + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as fh:
            fh.write(text)
        try:
            os.link(tmp, path)
            return True
        except FileExistsError:
            if path.read_text() != text:
                os.replace(tmp, path)
                tmp = ""
                return True
            return False
    finally:
        if tmp:
            os.unlink(tmp)


def atomic_write_bytes(path: Path, data: bytes) -> None:
    """Install ``data`` at ``path`` through a private temporary file and a rename."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(prefix=path.stem + ".", suffix=".tmp", dir=path.parent)
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
        tmp = ""
    finally:
        if tmp:
            os.unlink(tmp)


def _whole_pickle(path: Path) -> bool:
    with open(path, "rb") as fh:
        first = fh.read(1)
        fh.seek(0, os.SEEK_END)
        if fh.tell() < 2:
            return False
        fh.seek(-1, os.SEEK_END)
        return first == pickle.PROTO and fh.read(1) == pickle.STOP


def discard_unreadable(folder: Path, stem: str = "*") -> list[Path]:
    """Delete numba cache files in ``folder`` (of module ``stem``) that cannot be read back.

    numba stores each compiled function as an index (``.nbi``: a pickled
    version, then pickled data, both unpickled here) and data files (``.nbc``:
    one pickle each, of megabytes: only its first and last byte, the protocol
    mark and the STOP opcode, are checked, which a truncated or overwritten
    file fails). Such a file makes numba raise at the first call instead of
    recompiling; deleting it makes numba recompile and rewrite it. Returns
    the deleted paths.
    """
    removed: list[Path] = []
    for index in sorted(folder.glob(f"{stem}.*.nbi")):
        try:
            with open(index, "rb") as fh:
                pickle.load(fh)
                pickle.loads(fh.read())
            for data in folder.glob(index.name[: -len(".nbi")] + ".*.nbc"):
                if not _whole_pickle(data):
                    raise ValueError(f"{data} is not a complete pickle")
        except Exception:  # noqa: BLE001 - any failure to read means: rebuild
            name = index.name[: -len(".nbi")]
            for stale in [index, *folder.glob(name + ".*.nbc")]:
                stale.unlink(missing_ok=True)
                removed.append(stale)
    return removed
