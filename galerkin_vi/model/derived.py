"""Data derived from an object and kept with it: one cache, one pickling policy.

Lambdified functions, compiled point functions and solver pieces are derived
from a system's expressions and cost milliseconds to seconds to build. They are
kept in the system's :class:`DerivedData` (``system.derived``), keyed by a
tuple whose first item names the module that owns the entry, e.g.
``("events", expr)`` or ``("control", controls, cost)``.

Policy: derived data never pickles. A copy of its owner (``pickle``, a process
pool's worker, a Dask task) starts with an empty cache and rebuilds each entry
on first use, so the owner pickles whatever has been derived from it (lambdified
functions and compiled code do not pickle).
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Hashable, Iterator
from typing import Any, TypeVar

__all__ = ["DerivedData"]

T = TypeVar("T")


class DerivedData:
    """A get-or-build cache of values derived from its owner, safe across threads.

    Each key is built once: concurrent :meth:`get` calls for the same key wait
    for the first builder (one lock per key), calls for other keys proceed. A
    builder may itself call :meth:`get` for other keys. Pickling gives an empty
    cache (see the module's policy).

    Examples
    --------
    >>> cache = DerivedData()
    >>> cache.get(("demo", 2), lambda: 2**10)
    1024
    >>> ("demo", 2) in cache
    True
    """

    def __init__(self) -> None:
        self._values: dict[Hashable, Any] = {}
        self._locks: dict[Hashable, threading.Lock] = {}
        self._guard = threading.Lock()

    def get(self, key: tuple, build: Callable[[], T]) -> T:
        """The value of ``key``, built by ``build()`` on first use.

        Parameters
        ----------
        key : tuple
            Hashable; its first item names the owning module (``"events"``, ...).
        build : callable
            Called without arguments, at most once per key and cache.

        Raises
        ------
        TypeError
            If ``key`` is not a non-empty tuple or is unhashable.
        """
        try:
            return self._values[key]
        except KeyError:
            pass
        except TypeError:
            raise TypeError(f"key must be hashable, got {key!r}") from None
        if not isinstance(key, tuple) or not key:
            raise TypeError(f"key must be a non-empty tuple naming its owner first, got {key!r}")
        with self._guard:
            lock = self._locks.setdefault(key, threading.Lock())
        with lock:
            if key not in self._values:
                self._values[key] = build()
        return self._values[key]

    def peek(self, key: tuple, default: Any = None) -> Any:
        """The value of ``key`` if it has been built, else ``default`` (never builds)."""
        return self._values.get(key, default)

    def owned_by(self, owner: str) -> Iterator[tuple[tuple, Any]]:
        """The built ``(key, value)`` pairs whose key starts with ``owner``."""
        return iter([(k, v) for k, v in list(self._values.items()) if k[0] == owner])

    def clear(self) -> None:
        """Forget every entry (they are rebuilt on next use)."""
        with self._guard:
            self._values.clear()
            self._locks.clear()

    def __contains__(self, key: object) -> bool:
        return key in self._values

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        owners = sorted({str(k[0]) for k in self._values})
        return f"DerivedData({len(self._values)} entries: {', '.join(owners) or 'none'})"

    def __reduce__(self) -> tuple:
        # derived data never pickles: the copy rebuilds each entry on first use
        return (DerivedData, ())
