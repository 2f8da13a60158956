"""The per-process cache of region maps and corridor grids (:class:`planner.caching.BoundedCache`):
least recently used out first, bounded in entries and in bytes, an oversized value never kept."""

from __future__ import annotations

from planner.caching import BoundedCache


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
    cache.put("big", b"x" * 11)  # larger than the whole budget alone: never kept
    assert cache.get("big") is None and cache.get("e") == b"xxxxxx"
    cache.clear()
    assert len(cache) == 0 and cache.get("d") is None


def test_putting_a_key_again_replaces_its_value() -> None:
    cache: BoundedCache[str] = BoundedCache(2, 0, lambda _: 0)
    cache.put("k", "old")
    cache.put("k", "new")
    assert cache.get("k") == "new" and len(cache) == 1
