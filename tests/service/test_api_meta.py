"""GET /v1/health and /v1/version."""

from fastapi.testclient import TestClient

import planner
from planner_api.app import create_app


def test_health_answers_ok():
    client = TestClient(create_app(), base_url="http://localhost")
    r = client.get("/v1/health")
    assert r.status_code == 200
    assert r.json() == {"status": "ok"}


def test_version_names_package_and_libraries():
    r = TestClient(create_app(), base_url="http://localhost").get("/v1/version")
    assert r.status_code == 200
    body = r.json()
    assert body["version"] == planner.__version__
    assert set(body["libraries"]) >= {"ompl", "toppra", "ruckig", "numpy"}
