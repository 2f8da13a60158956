"""The batch limit is the schema's and it is counted first: ``/v1/plan/batch``'s ``maxItems``
in the OpenAPI document is the service's real limit, and a longer list is refused by its
length alone, before any item is parsed (every item here is broken, yet the only error is the
count), so a 10,000-item body cannot hold the event loop for seconds."""

from __future__ import annotations

from planner.wire import MAX_BATCH_REQUESTS

ONE = {"start": {"q": [0, 2, 1], "assembly_mode": "+"},
       "goal": {"q": [0.1, 2, 1], "assembly_mode": "+"}}  # fmt: skip
BROKEN = {"start": {"q": [0, 2]}, "goal": {"x": 1}}


def test_the_schema_states_the_real_limit(api):
    schema = api.get("/openapi.json").json()["components"]["schemas"]["PlanBatchRequest"]
    assert schema["properties"]["requests"]["maxItems"] == MAX_BATCH_REQUESTS == 64
    assert api.app.state.settings.max_batch <= MAX_BATCH_REQUESTS


def test_a_long_batch_is_refused_by_its_count_before_its_items(api):
    r = api.post("/v1/plan/batch", json={"requests": [BROKEN] * 10_000})
    assert r.status_code == 422
    detail = r.json()["detail"]
    assert len(detail) == 1, detail[:3]  # no item was validated
    assert detail[0]["loc"] == ["body", "requests"]
    assert detail[0]["msg"] == "at most 64 requests per batch, got 10000"


def test_a_batch_at_the_limit_is_parsed(api):
    r = api.post("/v1/plan/batch", json={"requests": [BROKEN] * MAX_BATCH_REQUESTS})
    assert r.status_code == 422 and len(r.json()["detail"]) > 1  # the items' own errors
    body = {"requests": [{**ONE, "timing": {"method": "none"}}] * 2}
    assert api.post("/v1/plan/batch", json=body).status_code == 200


def test_the_schema_states_the_services_obstacle_limit(api):
    """Issue 36: every request's ``obstacles`` says ``PLANNER_MAX_OBSTACLES`` (not the wire's
    cap of 10,000), and one obstacle more than it is refused."""
    limit = api.app.state.settings.max_obstacles
    schemas = api.get("/openapi.json").json()["components"]["schemas"]
    lists = {
        name: s["properties"]["obstacles"]
        for name, s in schemas.items()
        if "items" in s.get("properties", {}).get("obstacles", {})
    }
    found = {name: prop.get("maxItems") for name, prop in lists.items()}
    assert {"PlanRequest", "SequenceRequest"} <= set(found)
    assert all(v == limit for v in found.values()), found
    sphere = {"type": "sphere", "center": [5.0, 5.0, 5.0], "radius": 0.01}
    r = api.post("/v1/plan", json={**ONE, "obstacles": [sphere] * (limit + 1)})
    assert r.status_code == 422
    assert f"at most {limit} obstacles" in r.text
