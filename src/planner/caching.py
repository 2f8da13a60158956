"""One per-process LRU cache bounded in entries and in bytes, thread-safe: what the region
maps (:mod:`planner.analysis.regions`) and the corridor grids
(:mod:`planner.planning.corridor`) keep between requests of a worker (a design's map, a
scene's grid: built once, asked for by every later plan of that design or scene).
"""

from __future__ import annotations

import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Generic, TypeVar

__all__ = ["BoundedCache"]

V = TypeVar("V")


class BoundedCache(Generic[V]):
    """Key -> value, least recently used first out, at most ``max_items`` entries and
    ``max_bytes`` bytes (``nbytes(value)`` each); a value larger than ``max_bytes`` alone is
    never kept. ``get`` marks an entry most recently used."""

    def __init__(self, max_items: int, max_bytes: int, nbytes: Callable[[V], int]) -> None:
        self.max_items, self.max_bytes, self._nbytes = max_items, max_bytes, nbytes
        self._items: OrderedDict[Hashable, V] = OrderedDict()
        self.lock = threading.Lock()

    def get(self, key: Hashable) -> V | None:
        """The value of ``key`` (marked most recently used), or None."""
        with self.lock:
            hit = self._items.get(key)
            if hit is not None:
                self._items.move_to_end(key)
            return hit

    def put(self, key: Hashable, value: V) -> None:
        """Keep ``value``, dropping the least recently used entries beyond the bounds."""
        if self._nbytes(value) > self.max_bytes:
            return
        with self.lock:
            self._items[key] = value
            self._items.move_to_end(key)
            total = sum(self._nbytes(v) for v in self._items.values())
            while len(self._items) > self.max_items or total > self.max_bytes:
                _, old = self._items.popitem(last=False)
                total -= self._nbytes(old)

    def clear(self) -> None:
        """Forget every entry."""
        with self.lock:
            self._items.clear()

    def __len__(self) -> int:
        return len(self._items)
