"""The new routes (workspace, timing, design optimisation, figures) never answer a 5xx:
malformed bodies are 422 at ``body``, fuzzed bodies and queries are 4xx or 200."""

from __future__ import annotations

import json

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

ROUTES = ["/v1/workspace", "/v1/timing", "/v1/design/optimize"]

_leaf = (
    st.none()
    | st.booleans()
    | st.integers(-(10**12), 10**12)
    | st.floats(allow_nan=False, allow_infinity=False)
    | st.sampled_from(["+", "-", "+-+", "any", "toppra", "ruckig", "gci", "volume", ""])
)
_json = st.recursive(
    _leaf,
    lambda children: (
        st.lists(children, max_size=4)
        | st.dictionaries(
            st.sampled_from(
                [
                    "waypoints",
                    "design",
                    "L0",
                    "L1",
                    "limits",
                    "velocity",
                    "sections",
                    "resolution",
                    "reach",
                    "objective",
                    "method",
                    "stop_at",
                    "x",
                ]
            ),
            children,
            max_size=4,
        )
    ),
    max_leaves=12,
)


def _raw(api, path: str, text: str):
    return api.post(path, content=text.encode(), headers={"content-type": "application/json"})


@pytest.mark.parametrize("path", ROUTES)
@pytest.mark.parametrize("text", ["", "{", "[]", "null", '"x"', "[" * 50_000 + "]" * 50_000])
def test_malformed_bodies_are_422(api, path, text):
    r = _raw(api, path, text)
    assert r.status_code == 422, r.text
    assert r.json()["detail"][0]["loc"][0] == "body"


@settings(
    max_examples=60,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(path=st.sampled_from(ROUTES), body=_json)
def test_fuzzed_bodies_never_give_a_5xx(api, path, body):
    if isinstance(body, dict):  # keep the valid requests fast
        if path == "/v1/workspace":
            body = {**body, "sections": {"resolution": 8}, "rel_se": 0.1}
        elif path == "/v1/design/optimize":
            body = {"n_samples": 64, "maxiter": 1, **body}
    r = _raw(api, path, json.dumps(body))
    assert r.status_code < 500, r.text
    assert r.json()


@settings(
    max_examples=40,
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    name=st.sampled_from(["cartesian_section", "working_modes", "x", "", "..", "a.b.png"]),
    fmt=st.sampled_from(["png", "svg", "jpg", ""]),
    query=st.dictionaries(
        st.sampled_from(["L0", "L1", "L2", "dpi", "resolution", "zz"]),
        st.sampled_from(["0", "-1", "0.3", "1e9", "nan", "inf", "abc", "", "20"]),
        max_size=4,
    ),
)
def test_fuzzed_figure_requests_never_give_a_5xx(api, name, fmt, query):
    query = {**query, "resolution": query.get("resolution", "16"), "dpi": query.get("dpi", "20")}
    r = api.get(f"/v1/figures/{name}.{fmt}", params=query)
    assert r.status_code < 500, r.text
