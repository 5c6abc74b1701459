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
from ..expression_walk import structural_bytes

__all__ = ["analysis_key", "load_analysis", "load_extra", "store_analysis", "store_extra"]

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
    """SHA-256 of ``parts``, by their structural pickles.

    SymPy pickles an expression as its class and canonically ordered arguments
    (symbols with their names and assumptions): the bytes are the same in every
    process, whatever the hash seed, and several times cheaper to make than
    ``srepr`` (docs/design-notes.md, "Building large models").
    :func:`~galerkin_vi.expression_walk.structural_bytes` shares repeated nodes by
    equality, so two builds of one model give one key whichever objects SymPy's
    cache handed out. A part that does not pickle is hashed by ``srepr``.
    """
    h = hashlib.sha256()
    for part in (_sources_hash(), sp.__version__, sys.version, *parts):
        h.update(structural_bytes(part))
        h.update(b"\0")
    return h.hexdigest()


def _path(key: str) -> Path:
    return cache_root() / "systems" / f"{key[:40]}.pickle"


def _extra_path(key: str, name: str) -> Path:
    return cache_root() / "systems" / f"{key[:40]}.{name}.pickle"


def _loads(path: Path, key: str):
    """The value pickled at ``path`` for ``key``, or None.

    Unpickling rebuilds each SymPy node from its stored arguments, which are
    already in canonical form: SymPy's evaluation (flattening, sorting,
    assumption queries) would only redo what was done before storing, and costs
    more than deriving a large model afresh. Under ``evaluate(False)`` the
    arguments are taken as they are.
    """
    try:
        data = path.read_bytes()
        with sp.evaluate(False):
            stored_key, value = pickle.loads(data)
    except Exception:  # noqa: BLE001 - absent or damaged: derive afresh
        return None
    return value if stored_key == key else None


def load_analysis(key: str) -> dict | None:
    """The stored analysis for ``key``, or None (absent, unreadable, or another key's)."""
    return _loads(_path(key), key)


def load_extra(key: str, name: str):
    """A value stored with :func:`store_extra` for ``key`` and ``name``, or None."""
    return _loads(_extra_path(key, name), key)


def store_extra(key: str, name: str, value: Any) -> None:
    """Store ``value`` (plain data derived from the system of ``key``) beside its analysis.

    In a file of its own: data found after the analysis (a compiled module's
    summary) does not re-pickle the analysis, whose expressions are most of
    the cost of storing a large model.
    """
    try:
        atomic_write_bytes(_extra_path(key, name), pickle.dumps((key, value)))
    except (OSError, pickle.PicklingError, TypeError, AttributeError, RecursionError):
        pass


def store_analysis(key: str, analysis: dict) -> None:
    """Store ``analysis`` for ``key`` (atomic; a failure to write only costs speed)."""
    try:
        atomic_write_bytes(_path(key), pickle.dumps((key, analysis)))
    except (OSError, pickle.PicklingError, TypeError, AttributeError, RecursionError):
        pass
