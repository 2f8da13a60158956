"""The process's caches, all made, sized, cleared and reported here.

A worker keeps between requests what it built for one (a scene's packed obstacles, a
design's region map, a corridor grid, a figure's sections), so that the next request of the
same design or scene finds it. Each such process-wide cache is made through this module, by
its name in :data:`CACHES`, which gives its share of one budget and its most entries:

- :func:`bounded_cache` for a cache its module reads and writes with keys of its choosing;
- :func:`cached`, the replacement of :func:`functools.lru_cache` for a function's answers:
  keyed by the call's arguments as ``lru_cache`` keys them (positional, then keyword, in
  order), an exception not remembered, so the answers are the same as before.

One budget, :data:`DEFAULT_BUDGET_MB` (1 GiB) per process unless :func:`configure` sets
another: each cache holds at most its share of it in bytes (:func:`nbytes_of` of its
values), so all of them together stay within the budget. The service passes its
``PLANNER_CACHE_MB`` setting (:mod:`planner_api.settings`, which refuses a budget at or
above the worker memory bound ``PLANNER_WORKER_MAX_RSS_MB``: a worker whose caches filled
would otherwise be recycled after every job). :func:`clear` empties every cache (or those of
one room); :func:`stats` reports entries, bytes, hits and misses of each (the service's
``/metrics``).

Not caches in this sense, so not made here: a function of no arguments computed once per
process (the service's ``get_settings``, the viewer's page and its CSP, the preset
designs' JSON), whose one value is a constant of the process, not data that grows with the
requests; they keep :func:`functools.cache` / ``lru_cache(maxsize=1)`` and are named in
``tests/test_architecture.py``. Nor are memos that live and die with one object or one call
(a motion's plans of its legs, a timing's section profiles, a cached property), nor the
request gate's per-application table of which routes take a path (a thousand booleans on
the application's router).
"""

from __future__ import annotations

import functools
import math
import sys
import threading
from collections import OrderedDict
from collections.abc import Callable, Hashable
from typing import Any, Generic, NamedTuple, ParamSpec, TypeVar, overload

import numpy as np

__all__ = [
    "CACHES",
    "DEFAULT_BUDGET_MB",
    "BoundedCache",
    "CacheShare",
    "CacheStats",
    "bounded_cache",
    "budget_mb",
    "cached",
    "clear",
    "configure",
    "nbytes_of",
    "registered",
    "stats",
]

V = TypeVar("V")
D = TypeVar("D")
R = TypeVar("R")
P = ParamSpec("P")

#: The cache budget of a process when nothing sets another (:func:`configure`), MiB: half
#: the service's default worker memory bound (2048 MB), which also holds the libraries
#: (numba, OMPL, matplotlib: some hundreds of MB) and each job's own arrays.
DEFAULT_BUDGET_MB = 1024.0
_MIB = 2**20


class CacheShare(NamedTuple):
    """A cache's part of the budget: ``share`` of its bytes (0..1), at most ``max_items``
    entries, and what it holds."""

    share: float
    max_items: int
    holds: str


#: Every process-wide cache by name (``room.what``): its share of the budget (together at
#: most 1), its most entries, and what it holds. A worker fills the library's; the serving
#: process the service's (``scenes.resolved``) and the few it computes itself.
_TABLE = {
    "geometry.packed": (0.25, 16, "packed obstacle sets of more than 64 rows, by content"),
    "geometry.packed_small": (0.02, 256, "packed obstacle sets of at most 64 rows, by content"),
    "geometry.by_identity": (0.18, 8, "packed obstacle lists of 16+ objects or a cloud, by identity"),
    "geometry.by_identity_small": (0.005, 256, "packed obstacle lists of < 16 objects, by identity"),
    "geometry.digests": (0.0005, 64, "content digests of packed obstacle sets, by identity"),
    "corridor.grids": (0.06, 32, "corridor grids of (design, margins, obstacles, modes, shape)"),
    "corridor.too_costly": (0.0001, 32, "projected times (s) of corridor builds stopped"),
    "experience.paths": (0.005, 64, "remembered certified paths of (design, margins, modes, obstacles)"),
    "regions.maps": (0.25, 16, "region maps of (design, margins, n, refine)"),
    "region_walks.transits": (0.01, 512, "transit postures of a region map and flip"),
    "plotting.sections": (0.04, 16, "workspace sections of (kind, design, n)"),
    "plotting.loci": (0.02, 16, "singularity loci of (kind, design)"),
    "plotting.iso": (0.01, 16, "isoconditioning loci of (design, level)"),
    "plotting.figures": (0.02, 16, "rendered figure bytes of (name, design, n, format, dpi)"),
    "timing.joint_constraints": (0.001, 32, "toppra joint constraints of (v, a) limits"),
    "wire.designs": (0.001, 256, "designs of (L0, L1, L2, link radius, joint limits)"),
    "scenes.resolved": (0.10, 32, "the service's resolved scenes (obstacles, design) by hash"),
}  # fmt: skip
CACHES: dict[str, CacheShare] = {name: CacheShare(*row) for name, row in _TABLE.items()}


class CacheStats(NamedTuple):
    """What :func:`stats` reports of one cache: ``entries``, ``bytes`` (of its values,
    :func:`nbytes_of`), ``hits`` and ``misses`` (lookups since the process started) and
    ``max_bytes`` (its share of the budget)."""

    entries: int
    bytes: int
    hits: int
    misses: int
    max_bytes: int


class BoundedCache(Generic[V]):
    """Key -> value, least recently used first out, at most ``max_items`` entries and
    ``max_bytes`` bytes (``nbytes(value)`` each, measured once when it is put); a value
    larger than ``max_bytes`` alone is never kept. ``get`` marks an entry most recently
    used and counts a hit or a miss. Thread-safe. Made through :func:`bounded_cache` (or
    :func:`cached`), which names it and sizes it from the budget."""

    def __init__(self, max_items: int, max_bytes: int, nbytes: Callable[[V], int]) -> None:
        self.max_items, self.max_bytes, self._nbytes = max_items, max_bytes, nbytes
        self._items: OrderedDict[Hashable, tuple[V, int]] = OrderedDict()
        self._bytes = 0
        self.hits = self.misses = 0
        self.lock = threading.Lock()

    @overload
    def get(self, key: Hashable) -> V | None: ...
    @overload
    def get(self, key: Hashable, default: D) -> V | D: ...

    def get(self, key: Hashable, default: object = None) -> object:
        """The value of ``key`` (marked most recently used), or ``default``."""
        with self.lock:
            hit = self._items.get(key)
            if hit is None:
                self.misses += 1
                return default
            self.hits += 1
            self._items.move_to_end(key)
            return hit[0]

    def put(self, key: Hashable, value: V) -> None:
        """Keep ``value``, dropping the least recently used entries beyond the bounds."""
        size = self._nbytes(value)
        with self.lock:
            old = self._items.pop(key, None)
            if old is not None:
                self._bytes -= old[1]
            if size > self.max_bytes:
                return
            self._items[key] = (value, size)
            self._bytes += size
            self._evict()

    def resize(self, max_bytes: int) -> None:
        """Bound the bytes anew, dropping the least recently used entries beyond it."""
        with self.lock:
            self.max_bytes = max_bytes
            self._evict()

    def _evict(self) -> None:
        """Drop the oldest entries until both bounds hold (the lock held)."""
        while self._items and (len(self._items) > self.max_items or self._bytes > self.max_bytes):
            _, (_, size) = self._items.popitem(last=False)
            self._bytes -= size

    def clear(self) -> None:
        """Forget every entry."""
        with self.lock:
            self._items.clear()
            self._bytes = 0

    @property
    def nbytes(self) -> int:
        """Bytes of the values kept."""
        return self._bytes

    def __len__(self) -> int:
        return len(self._items)


#: The caches made, by name (:func:`bounded_cache`).
_REGISTRY: dict[str, BoundedCache[Any]] = {}
_REGISTRY_LOCK = threading.Lock()
_budget_bytes = int(DEFAULT_BUDGET_MB * _MIB)


def bounded_cache(name: str) -> BoundedCache[Any]:
    """The cache ``name`` of :data:`CACHES`, made once per process with its share of the
    budget and its most entries (a second call gives the same cache, so a module reloaded
    keeps its entries). KeyError for a name :data:`CACHES` does not list."""
    share = CACHES[name]
    with _REGISTRY_LOCK:
        cache = _REGISTRY.get(name)
        if cache is None:
            cache = _REGISTRY[name] = BoundedCache(
                share.max_items, int(share.share * _budget_bytes), nbytes_of
            )
        return cache


_KWARGS = object()  # between positional and keyword arguments in a key, as lru_cache does
_MISSING = object()


def cached(name: str) -> Callable[[Callable[P, R]], Callable[P, R]]:
    """A decorator remembering a function's answers in the cache ``name`` of
    :data:`CACHES`, in place of :func:`functools.lru_cache`: the key is the positional
    arguments, then the keyword ones in the order given (unhashable arguments raise
    TypeError, as with ``lru_cache``); an exception is not remembered. Callers must not
    alter what it returns (it is shared), as with ``lru_cache``."""

    def decorate(fn: Callable[P, R]) -> Callable[P, R]:
        store = bounded_cache(name)

        @functools.wraps(fn)
        def remembered(*args: P.args, **kwargs: P.kwargs) -> R:
            key = (*args, _KWARGS, *kwargs.items()) if kwargs else args
            hit = store.get(key, _MISSING)
            if hit is not _MISSING:
                return hit  # type: ignore[return-value]
            value = fn(*args, **kwargs)
            store.put(key, value)
            return value

        return remembered

    return decorate


def configure(*, budget_mb: float) -> None:
    """Set the budget of every cache of this process, MiB (each gets its share; entries
    beyond a smaller share are dropped at once); 0 keeps nothing. ValueError for a negative
    or non-finite budget."""
    global _budget_bytes
    if not (math.isfinite(budget_mb) and budget_mb >= 0):
        raise ValueError(f"budget_mb must be a finite number >= 0, got {budget_mb!r}")
    with _REGISTRY_LOCK:
        _budget_bytes = int(budget_mb * _MIB)
        for name, cache in _REGISTRY.items():
            cache.resize(int(CACHES[name].share * _budget_bytes))


def budget_mb() -> float:
    """The budget of this process's caches, MiB (:func:`configure`)."""
    return _budget_bytes / _MIB


def registered(name: str) -> BoundedCache[Any]:
    """The cache ``name`` made in this process (KeyError when its module has not made it:
    import the module first)."""
    return _REGISTRY[name]


def clear(*rooms: str) -> None:
    """Forget every entry of every cache of this process, or only of the caches of
    ``rooms`` (a name, or its part before the dot: ``clear("corridor")``), e.g. for a
    benchmark of cold builds or to free memory."""
    with _REGISTRY_LOCK:
        chosen = [c for n, c in _REGISTRY.items() if not rooms or _in_rooms(n, rooms)]
    for cache in chosen:
        cache.clear()


def _in_rooms(name: str, rooms: tuple[str, ...]) -> bool:
    return any(name == r or name.startswith(r + ".") for r in rooms)


def stats() -> dict[str, CacheStats]:
    """Entries, bytes, hits, misses and byte bound of each cache made in this process, by
    name (sorted)."""
    with _REGISTRY_LOCK:
        caches = sorted(_REGISTRY.items())
    return {name: CacheStats(len(c), c.nbytes, c.hits, c.misses, c.max_bytes) for name, c in caches}


#: How deep :func:`nbytes_of` looks into containers and objects.
_DEPTH = 6
#: What :func:`nbytes_of` counts for an object it does not look into.
_OBJECT_BYTES = 64


def nbytes_of(value: object) -> int:
    """The bytes a cached value holds, roughly: its numpy arrays' ``nbytes``, the length of
    its bytes and strings, through tuples, lists, sets, dicts, dataclasses and objects'
    ``__dict__`` or ``__slots__`` (each object counted once, :data:`_DEPTH` levels deep),
    and the size of anything else (``sys.getsizeof``). What every cache weighs its entries
    by, so one number means the same in every cache."""
    return _nbytes(value, set(), _DEPTH)


def _nbytes(value: object, seen: set[int], depth: int) -> int:
    if id(value) in seen:
        return 0
    seen.add(id(value))
    if isinstance(value, np.ndarray | memoryview):
        return int(value.nbytes)
    if isinstance(value, bytes | bytearray | str):
        return len(value)
    if isinstance(value, int | float | complex | type(None)):
        return sys.getsizeof(value)
    if depth == 0:
        return _OBJECT_BYTES
    if isinstance(value, dict):
        parts: list[object] = [*value.keys(), *value.values()]
    elif isinstance(value, tuple | list | set | frozenset):
        parts = list(value)
    elif hasattr(value, "__dict__") or hasattr(value, "__slots__"):
        parts = [*getattr(value, "__dict__", {}).values()]
        parts += [getattr(value, s, None) for s in _slots(type(value))]
    else:
        return sys.getsizeof(value)
    return _OBJECT_BYTES + sum(_nbytes(p, seen, depth - 1) for p in parts)


def _slots(cls: type) -> tuple[str, ...]:
    """A class's slot names over its MRO (a walk of a few classes: not worth a cache)."""
    return tuple(
        s
        for k in cls.__mro__
        for s in getattr(k, "__slots__", ())
        if s not in ("__dict__", "__weakref__")
    )
