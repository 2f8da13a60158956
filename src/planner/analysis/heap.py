"""The one compiled binary min-heap of the grid searches: the flood of the obstacle proof
(:mod:`planner.analysis._obstacle_kernels`, keys: distances in cells to the nearest goal) and
the corridor's weighted A* (:mod:`planner.planning.corridor`, keys: path costs).

A heap is two arrays and a size, owned by the caller's compiled loop: ``keys`` and
``values`` (a cell), entries ``[0, size)`` in heap order. The functions are compiled for the
types each caller gives them (the flood: int32 distances and packed int64 cells; the A*:
float64 costs and int64 flat indices), so each search keeps its narrowest arrays: float64 keys
cost the flood's sift loops (up to a million entries) 7-10 % more CPU time on the largest
floods of ``benchmarks/regions.py --obstacles``. Ties keep the order of the classic
sift-up and sift-down (an entry moves past its parent only on a strictly smaller key, a child
is taken on a strictly smaller key), so a search pops its cells in one order whatever its key
type. :func:`heap_push` needs room (``size < len(keys)``): a search that cannot bound its
pushes calls :func:`heap_grow` first.

The functions are inlined into their callers (``inline="always"``), so the heap costs no call
in the hot loop. numba's on-disk cache keys a caller on its own source file: after an edit
here, clear the callers' cache (their ``__pycache__/*.nbi``, ``*.nbc``) or touch their files,
or they keep the old copy.
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = ["heap_grow", "heap_pop", "heap_push"]


@njit(cache=True, nogil=True, inline="always")
def heap_grow(keys, values, size):  # pragma: no cover - compiled
    """``(keys, values)`` with room for one more entry: the same arrays when ``size`` is below
    their length, else copies of twice the length holding the ``size`` entries."""
    if size < keys.shape[0]:
        return keys, values
    grown_keys = np.empty(max(2 * size, 1), dtype=keys.dtype)
    grown_values = np.empty(max(2 * size, 1), dtype=values.dtype)
    grown_keys[:size], grown_values[:size] = keys[:size], values[:size]
    return grown_keys, grown_values


@njit(cache=True, nogil=True, inline="always")
def heap_push(keys, values, size, key, value):  # pragma: no cover - compiled
    """Add ``(key, value)`` to the heap of ``size`` entries (``size < len(keys)``); returns
    ``size + 1``."""
    pos = size
    while pos > 0:
        parent = (pos - 1) >> 1
        if keys[parent] <= key:
            break
        keys[pos], values[pos] = keys[parent], values[parent]
        pos = parent
    keys[pos], values[pos] = key, value
    return size + 1


@njit(cache=True, nogil=True, inline="always")
def heap_pop(keys, values, size):  # pragma: no cover - compiled
    """Remove the entry of least key from the heap of ``size`` >= 1 entries; returns
    ``(value, size - 1)``."""
    top = values[0]
    size -= 1
    key, value = keys[size], values[size]
    pos = 0
    while True:
        child = 2 * pos + 1
        if child >= size:
            break
        if child + 1 < size and keys[child + 1] < keys[child]:
            child += 1
        if keys[child] >= key:
            break
        keys[pos], values[pos] = keys[child], values[child]
        pos = child
    if size > 0:
        keys[pos], values[pos] = key, value
    return top, size
