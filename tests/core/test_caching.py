"""The process's caches (:mod:`planner.caching`): each bounded cache is least recently used
out first within its entries and its share of the one budget; every process-wide cache of
the library and the service is made through the registry, cleared by one call and
reported by :func:`~planner.caching.stats`; :func:`~planner.caching.cached` answers as
:func:`functools.lru_cache` did."""

from __future__ import annotations

import importlib
import math

import numpy as np
import pytest

from planner import caching
from planner.caching import CACHES, BoundedCache, cached, nbytes_of

#: The modules that make the caches of :data:`planner.caching.CACHES`.
MAKERS = (
    "planner.geometry",
    "planner.planning.corridor",
    "planner.planning.experience",
    "planner.analysis.regions",
    "planner.planning.region_walks",
    "planner.plotting",
    "planner.timing.toppra_method",
    "planner.wire",
    "planner_api.routes.scenes",
)


@pytest.fixture
def all_caches():
    """Every cache made (its module imported); after the test, the default budget again and
    every cache emptied of the test's entries."""
    for module in MAKERS:
        importlib.import_module(module)
    yield
    caching.configure(budget_mb=caching.DEFAULT_BUDGET_MB)
    caching.clear()


def test_least_recently_used_leaves_first_within_both_bounds() -> None:
    cache: BoundedCache[bytes] = BoundedCache(3, 10, len)
    for key in "abc":
        cache.put(key, b"xx")
    assert cache.get("a") == b"xx"  # 'a' now the most recent: 'b' is the oldest
    cache.put("d", b"xx")  # a fourth entry: 'b' goes
    assert cache.get("b") is None and len(cache) == 3
    cache.put("e", b"xxxxxx")  # c, a, d, e: 4 entries and 12 bytes, so the oldest goes
    assert cache.get("c") is None and len(cache) == 3
    assert cache.get("a") == cache.get("d") == b"xx" and cache.get("e") == b"xxxxxx"
    assert cache.nbytes == 10
    cache.put("big", b"x" * 11)  # larger than the whole budget alone: never kept
    assert cache.get("big") is None and cache.get("e") == b"xxxxxx"
    cache.clear()
    assert len(cache) == 0 and cache.get("d") is None and cache.nbytes == 0


def test_putting_a_key_again_replaces_its_value_and_its_bytes() -> None:
    cache: BoundedCache[str] = BoundedCache(2, 100, len)
    cache.put("k", "old value")
    cache.put("k", "new")
    assert cache.get("k") == "new" and len(cache) == 1 and cache.nbytes == 3
    cache.put("k", "x" * 101)  # too large now: the old value goes too, nothing stale kept
    assert cache.get("k") is None and cache.nbytes == 0


def test_hits_and_misses_are_counted_and_a_default_is_given() -> None:
    cache: BoundedCache[int] = BoundedCache(4, 100, lambda _: 1)
    missing = object()
    assert cache.get("a", missing) is missing
    cache.put("a", 0)  # a falsy value is still a hit
    assert cache.get("a", missing) == 0
    assert (cache.hits, cache.misses) == (1, 1)


def test_every_cache_is_registered_with_its_share_and_the_shares_fit_the_budget(
    all_caches,
) -> None:
    assert set(caching.stats()) == set(CACHES)
    assert sum(s.share for s in CACHES.values()) <= 1.0
    assert all(s.share > 0 and s.max_items >= 1 for s in CACHES.values())
    budget = caching.DEFAULT_BUDGET_MB * 2**20
    for name, s in caching.stats().items():
        assert s.max_bytes == int(CACHES[name].share * budget), name
    with pytest.raises(KeyError):
        caching.bounded_cache("no.such_cache")  # only the table's names are made


@pytest.mark.parametrize("name", sorted(CACHES))
def test_each_cache_honours_its_share(all_caches, name: str) -> None:
    caching.configure(budget_mb=4.0)
    cache = caching.registered(name)
    share = CACHES[name]
    bound = int(share.share * 4 * 2**20)
    assert cache.max_bytes == bound and cache.max_items == share.max_items
    value_bytes = bound // 3
    for i in range(share.max_items + 5):  # beyond both bounds
        cache.put(("test", i), np.zeros(value_bytes, np.uint8))
        assert cache.nbytes <= bound and len(cache) <= share.max_items
    assert len(cache) == min(3, share.max_items)  # the most recent that fit the bytes
    last = share.max_items + 4
    assert cache.get(("test", last)) is not None and cache.get(("test", 0)) is None
    caching.configure(budget_mb=1.0)  # a smaller budget drops entries at once
    assert cache.nbytes <= int(share.share * 2**20)
    assert len(cache) <= 1


def test_clear_empties_every_cache_or_one_rooms(all_caches) -> None:
    for name in CACHES:
        caching.registered(name).put(("test", name), b"x")
    assert all(s.entries >= 1 for s in caching.stats().values())
    caching.clear("corridor")
    after = caching.stats()
    assert after["corridor.grids"].entries == after["corridor.too_costly"].entries == 0
    assert after["geometry.packed"].entries >= 1  # another room's kept
    caching.clear()
    assert all(s.entries == 0 and s.bytes == 0 for s in caching.stats().values())


def test_stats_report_what_a_cache_holds_and_how_it_was_asked(all_caches) -> None:
    caching.clear()
    cache = caching.registered("plotting.figures")
    before = caching.stats()["plotting.figures"]
    cache.put(("test", 1), b"x" * 1000)
    assert cache.get(("test", 1)) is not None and cache.get(("test", 2)) is None
    s = caching.stats()["plotting.figures"]
    assert (s.entries, s.bytes) == (1, 1000)
    assert (s.hits - before.hits, s.misses - before.misses) == (1, 1)


def test_configure_refuses_a_negative_or_endless_budget() -> None:
    for bad in (-1.0, math.inf, math.nan):
        with pytest.raises(ValueError, match="budget_mb"):
            caching.configure(budget_mb=bad)
    assert caching.budget_mb() == caching.DEFAULT_BUDGET_MB


def test_cached_keys_calls_as_lru_cache_does(all_caches) -> None:
    calls = []

    @cached("plotting.iso")
    def twice(x, scale=2):
        calls.append((x, scale))
        return None if x == 0 else x * scale

    caching.clear("plotting.iso")
    assert twice(3) == twice(3) == 6 and calls == [(3, 2)]
    assert twice(3.0) == 6 and len(calls) == 1  # 3 == 3.0: one key, as lru_cache(typed=False)
    assert twice(3, scale=2) == 6 and len(calls) == 2  # a keyword is another key, as there
    assert twice(0) is None and twice(0) is None and len(calls) == 3  # None is remembered
    with pytest.raises(TypeError):
        twice([1])  # unhashable, as with lru_cache
    assert twice.__name__ == "twice"


def test_cached_does_not_remember_an_exception(all_caches) -> None:
    calls = []

    @cached("plotting.iso")
    def refuse(x):
        calls.append(x)
        raise ValueError(x)

    for _ in range(2):
        with pytest.raises(ValueError):
            refuse(1)
    assert calls == [1, 1]


def test_nbytes_of_counts_arrays_bytes_and_containers_once() -> None:
    a = np.zeros(1000)
    assert nbytes_of(a) == 8000
    assert nbytes_of(b"x" * 500) == 500
    shared = nbytes_of((a, a, [a]))  # one array, held three times
    assert 8000 <= shared < 8000 + 1000
    assert nbytes_of({"k": (a, np.zeros(10))}) >= 8080
