"""Prometheus metrics at /metrics: request counts and latencies per route, plan outcomes and
durations reported by the worker processes, and the pool's saturation. The exposition is
read back with prometheus_client's own text parser."""

from __future__ import annotations

import threading
import time

import pytest
from ops_jobs import sleep_pid, timed_outcome
from prometheus_client.parser import text_string_to_metric_families

from planner_api.routes.plan import get_plan_function

START = {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"}


def _plan(seed: int, budget: float) -> dict:
    return {
        "start": START,
        "goal": {"p": [0.3, 0.1, 0.2]},
        "planner": {"seed": seed, "time_budget_s": budget},
    }


def scrape(client) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    """Every sample of /metrics as {(name, sorted labels): value}."""
    r = client.get("/metrics")
    assert r.status_code == 200
    assert r.headers["content-type"].startswith("text/plain")
    out = {}
    for family in text_string_to_metric_families(r.text):
        for s in family.samples:
            out[(s.name, tuple(sorted(s.labels.items())))] = s.value
    return out


def sample(metrics, name: str, **labels: str) -> float:
    return metrics.get((name, tuple(sorted(labels.items()))), 0.0)


def _wait_ready(client, timeout_s: float = 180.0) -> None:
    end = time.monotonic() + timeout_s
    while client.get("/v1/ready").status_code != 200:
        assert time.monotonic() < end, "workers never became ready"
        time.sleep(0.05)


def test_request_counts_and_latencies_per_route(client_factory):
    # a fresh app counts from zero; its worker is not warmed (fk jobs pay their imports)
    with client_factory(warm=False) as c:
        for q in ([0.1, 1.0, 2.0], [0.2, 1.1, 2.1]):
            assert c.post("/v1/fk", json={"q": q}).status_code == 200
        assert c.post("/v1/fk", json={"q": [0.1, 1.0]}).status_code == 422
        assert c.get("/no/such/path/123").status_code == 404
        not_json = c.post("/v1/fk", content=b"{x", headers={"content-type": "application/json"})
        assert not_json.status_code == 422
        m = scrape(c)
    fk = {"method": "POST", "route": "/v1/fk"}
    assert sample(m, "planner_http_requests_total", **fk, status="200") == 2
    assert sample(m, "planner_http_requests_total", **fk, status="422") == 2
    assert (
        sample(m, "planner_http_requests_total", method="GET", route="<unmatched>", status="404")
        == 1
    )
    # the histogram counts every answered /v1/fk request, with a positive total time
    assert sample(m, "planner_http_request_duration_seconds_count", **fk) == 4
    assert sample(m, "planner_http_request_duration_seconds_sum", **fk) > 0
    assert sample(m, "planner_http_request_duration_seconds_bucket", **fk, le="+Inf") == 4
    # jobs ran in the worker: the fk job's time was reported back (two succeeded)
    assert sample(m, "planner_job_duration_seconds_count", job="fk") == 2
    assert sample(m, "planner_build_info", version=__import__("planner").__version__) == 1


def test_oversized_body_is_counted_on_its_route(client_factory):
    with client_factory(max_body_bytes=1024, warm=False) as c:
        r = c.post("/v1/fk", content=b"[" * 2000, headers={"content-type": "application/json"})
        assert r.status_code == 413
        m = scrape(c)
    assert (
        sample(m, "planner_http_requests_total", method="POST", route="/v1/fk", status="413") == 1
    )


def test_plan_outcomes_and_durations_come_from_the_workers(client_factory):
    budgets = [0.5, 0.25, 2.0, 0.125]  # reported as planning times; a tenth as timing times
    with client_factory(warm=False) as c:
        c.app.dependency_overrides[get_plan_function] = lambda: timed_outcome
        for seed, budget in zip((6, 1), budgets[:2], strict=True):  # solved, no_path
            r = c.post("/v1/plan", json=_plan(seed, budget))
            assert r.status_code == 200, r.text
        r = c.post(
            "/v1/plan/batch", json={"requests": [_plan(6, budgets[2]), _plan(5, budgets[3])]}
        )
        assert r.status_code == 200
        assert [x["status"] for x in r.json()["results"]] == ["solved", "timeout"]
        m = scrape(c)
    assert sample(m, "planner_plan_outcomes_total", status="solved") == 2
    assert sample(m, "planner_plan_outcomes_total", status="no_path") == 1
    assert sample(m, "planner_plan_outcomes_total", status="timeout") == 1
    assert sample(m, "planner_plan_outcomes_total", status="unreachable") == 0
    assert sample(m, "planner_planning_duration_seconds_count") == 4
    assert sample(m, "planner_planning_duration_seconds_sum") == pytest.approx(sum(budgets))
    assert sample(m, "planner_timing_duration_seconds_sum") == pytest.approx(sum(budgets) / 10)
    # 0.5 s falls in the le=0.5 bucket, 2.0 s only from le=2.5 on
    assert sample(m, "planner_planning_duration_seconds_bucket", le="0.5") == 3
    assert sample(m, "planner_planning_duration_seconds_bucket", le="1.0") == 3
    assert sample(m, "planner_planning_duration_seconds_bucket", le="2.5") == 4
    assert sample(m, "planner_job_duration_seconds_count", job="timed_outcome") == 4


def test_pool_saturation_and_rejections(client_factory):
    with client_factory(workers=1, queue_size=1, warm=False) as c:
        c.app.dependency_overrides[get_plan_function] = lambda: sleep_pid
        _wait_ready(c)
        idle = scrape(c)
        assert sample(idle, "planner_pool_workers") == 1
        assert sample(idle, "planner_pool_capacity") == 2
        assert sample(idle, "planner_pool_in_flight") == 0
        assert sample(idle, "planner_pool_saturation") == 0
        assert sample(idle, "planner_pool_ready") == 1
        answers: list[int] = []
        threads = [
            threading.Thread(
                target=lambda: answers.append(c.post("/v1/plan", json=_plan(1, 1.0)).status_code)
            )
            for _ in range(2)
        ]
        for t in threads:
            t.start()
        pool = c.app.state.pool
        end = time.monotonic() + 10
        while pool.in_flight < 2:
            assert time.monotonic() < end
            time.sleep(0.01)
        busy = scrape(c)
        assert c.post("/v1/plan", json=_plan(1, 1.0)).status_code == 503  # the pool is full
        after = scrape(c)
        for t in threads:
            t.join()
    assert sorted(answers) == [200, 200]
    assert sample(busy, "planner_pool_in_flight") == 2
    assert sample(busy, "planner_pool_busy_workers") == 1
    assert sample(busy, "planner_pool_queue_depth") == 1
    assert sample(busy, "planner_pool_saturation") == 1.0
    assert sample(busy, "planner_http_requests_in_progress") == 3  # two plans and the scrape
    assert sample(busy, "planner_pool_rejected_total") == 0
    assert sample(after, "planner_pool_rejected_total") == 1
    assert (
        sample(after, "planner_http_requests_total", method="POST", route="/v1/plan", status="503")
        == 1
    )


def test_metrics_can_be_switched_off(client_factory):
    with client_factory(metrics=False, warm=False) as c:
        assert c.get("/metrics").status_code == 404
        assert c.post("/v1/fk", json={"q": [0.1, 1.0, 2.0]}).status_code == 200


def test_real_plan_reports_its_diagnostics(api):
    """One real plan on the session's warm service: what the metrics gained across it (they
    count every request of the session, so the test reads the difference of two scrapes, one
    request at a time in this process) are the answer's own diagnostics."""
    body = {
        "start": {"q": [0.0, 1.0, 2.0], "assembly_mode": "+"},
        "goal": {"q": [0.2, 1.1, 2.1], "assembly_mode": "+"},
        "planner": {"seed": 1, "time_budget_s": 5.0},
        "timing": {"method": "toppra"},
    }
    before = scrape(api)
    r = api.post("/v1/plan", json=body)
    assert r.status_code == 200, r.text
    after = scrape(api)

    def gained(name: str, **labels: str) -> float:
        return sample(after, name, **labels) - sample(before, name, **labels)

    answer = r.json()
    assert answer["status"] == "solved"
    d = answer["diagnostics"]
    assert gained("planner_plan_outcomes_total", status="solved") == 1
    assert gained("planner_planning_duration_seconds_count") == 1
    assert gained("planner_planning_duration_seconds_sum") == pytest.approx(d["planning_time_s"])
    assert gained("planner_timing_duration_seconds_sum") == pytest.approx(d["timing_time_s"])
    assert gained("planner_job_duration_seconds_count", job="plan") == 1
    # the job's time in the worker covers planning and timing, the request's covers the job
    job_s = gained("planner_job_duration_seconds_sum", job="plan")
    request_s = gained("planner_http_request_duration_seconds_sum", method="POST", route="/v1/plan")
    assert d["planning_time_s"] + d["timing_time_s"] <= job_s <= request_s


def _cache_plan(seed: int) -> dict:
    return {
        "start": START,
        "goal": {"q": [0.6, 2.3, 0.8], "assembly_mode": "+"},
        "obstacles": [{"type": "sphere", "center": [2.0, 2.0, 2.0], "radius": 0.1}],
        "planner": {"seed": seed},
    }


def test_the_caches_of_the_workers_are_reported_with_their_budget(client_factory):
    from planner import caching

    try:
        with client_factory(warm=False, cache_mb=64) as c:
            assert c.post("/v1/plan", json=_cache_plan(1)).status_code == 200
            first = scrape(c)
            assert c.post("/v1/plan", json=_cache_plan(1)).status_code == 200
            again = scrape(c)
    finally:
        caching.configure(budget_mb=caching.DEFAULT_BUDGET_MB)  # this process's, as before
    small = {"cache": "geometry.packed_small"}  # the worker packs the plan's one sphere
    assert sample(first, "planner_cache_entries", **small) >= 1
    assert sample(first, "planner_cache_bytes", **small) > 0
    assert sample(first, "planner_cache_misses_total", **small) >= 1
    assert sample(again, "planner_cache_hits_total", **small) > sample(
        first, "planner_cache_hits_total", **small
    )  # the same scene again: found packed
    # the worker's budget is the setting's (a worker left at the library's default would
    # report its larger bound, and the largest bound is shown)
    for name in ("geometry.packed", "geometry.packed_small"):
        assert sample(again, "planner_cache_budget_bytes", cache=name) == int(
            caching.CACHES[name].share * 64 * 2**20
        )


def test_cache_reports_are_summed_over_the_live_workers():
    from planner_api.metrics import JobSample, _CacheCollector

    class Pool:
        pids = (101, 102)

    collector = _CacheCollector(lambda: Pool)
    report = (("test.cache", 2, 100, 5, 1, 1000),)
    for pid in (101, 102, 999):
        collector.record(JobSample("plan", 0.1, pid=pid, caches=report))
    families = {f.name: f for f in collector.collect()}
    values = {
        f: next(s.value for s in families[f].samples if s.labels == {"cache": "test.cache"})
        for f in ("planner_cache_entries", "planner_cache_bytes", "planner_cache_budget_bytes")
    }
    # the two live workers summed (999 is gone), the bound per process
    assert values == {
        "planner_cache_entries": 4,
        "planner_cache_bytes": 200,
        "planner_cache_budget_bytes": 1000,
    }
    hits = families["planner_cache_hits"].samples
    assert next(s.value for s in hits if s.labels == {"cache": "test.cache"}) == 10
