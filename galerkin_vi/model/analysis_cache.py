"""On-disk cache of a system's symbolic analysis, keyed by the user's input.

Building a :class:`~galerkin_vi.model.system.LagrangianSystem` differentiates ``L``,
the forces and the constraints with SymPy and analyses the result (structure,
angles, printability, regularity): 20-500 ms for the models of the problem
library, most of a cached system's start-up in a new process. The result is
plain data, pickled under ``<cache root>/systems/`` (3 ms to load for a
two-coordinate model, against 80 ms to derive).

The key hashes the inputs by their pickles (symbol names and assumptions
included, since the pieces hold the user's symbols), the default
parameter values (the regularity check samples with them), the sources of the
analysis (:mod:`galerkin_vi.model.symbolic`, :mod:`galerkin_vi.model.system`) and the
SymPy and Python versions: an edited analysis or a new SymPy starts afresh.
An unreadable entry is ignored and written again.
"""

from __future__ import annotations

import hashlib
import pickle
import sys
from functools import cache
from pathlib import Path
from typing import Any

import sympy as sp

from ..cache import atomic_write_bytes, cache_root

__all__ = ["analysis_key", "load_analysis", "store_analysis"]

#: the modules that compute what is stored (paths relative to this folder): an edit to
#: any of them makes every stored analysis stale
_SOURCES = (
    "symbolic.py",
    "system.py",
    "terms.py",
    "analysis_cache.py",
    "../expression_walk.py",
    "../printer.py",
)


@cache
def _sources_hash() -> str:
    h = hashlib.sha256()
    package = Path(__file__).resolve().parent
    for name in _SOURCES:
        h.update((package / name).read_bytes())
    return h.hexdigest()


def analysis_key(*parts: Any) -> str:
    """SHA-256 of ``parts``, by their pickles.

    SymPy pickles an expression as its class and canonically ordered arguments
    (symbols with their names and assumptions): the bytes are the same in every
    process, whatever the hash seed, and tens of times cheaper to make than
    ``srepr`` (docs/performance.md, "Measurements behind design choices"). A part that does
    not pickle is hashed by ``srepr``.
    """
    h = hashlib.sha256()
    for part in (_sources_hash(), sp.__version__, sys.version, *parts):
        try:
            data = pickle.dumps(part, protocol=4)
        except Exception:  # noqa: BLE001 - e.g. an expression holding a lambda
            data = sp.srepr(part).encode()
        h.update(data)
        h.update(b"\0")
    return h.hexdigest()


def _path(key: str) -> Path:
    return cache_root() / "systems" / f"{key[:40]}.pickle"


def load_analysis(key: str) -> dict | None:
    """The stored analysis for ``key``, or None (absent, unreadable, or another key's)."""
    try:
        data = _path(key).read_bytes()
        stored_key, analysis = pickle.loads(data)
    except Exception:  # noqa: BLE001 - absent or damaged: derive afresh
        return None
    return analysis if stored_key == key else None


def store_analysis(key: str, analysis: dict) -> None:
    """Store ``analysis`` for ``key`` (atomic; a failure to write only costs speed)."""
    try:
        atomic_write_bytes(_path(key), pickle.dumps((key, analysis)))
    except (OSError, pickle.PicklingError, TypeError, AttributeError, RecursionError):
        pass
