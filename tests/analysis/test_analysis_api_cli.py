"""POST /v1/design/check, the check-design and figures commands, and the figure files."""

import math

import pytest
from typer.testing import CliRunner

from planner import Design
from planner.wire import DesignModel
from planner_cli import app as cli_app


@pytest.fixture
def client(api):
    """The session's service (default settings, warm): these tests only read."""
    return api


def test_design_check_answers_the_wire_fields(client):
    r = client.post("/v1/design/check", json={"design": {"L0": 0.0, "L1": 0.4, "L2": 0.4}})
    assert r.status_code == 200
    body = r.json()
    assert body["volume"] == pytest.approx(4 / 3 * math.pi * 0.8**3)
    assert set(body["parallel_singularities"]) == {"C=D", "CD_stretched"}
    assert body["singularity_free"] is False
    assert set(body["operative_working_modes"]) == {"++-", "+-+", "-+-", "--+"}


def test_design_check_default_design_is_singularity_free(client):
    body = client.post("/v1/design/check", json={}).json()
    assert body["singularity_free"] is True and body["parallel_singularities"] == []
    assert body["design"]["L0"] == Design.default().L0


@pytest.mark.parametrize(
    ("design", "field"),
    [
        ('{"L0": NaN, "L1": 0.4, "L2": 0.4}', "L0"),
        ('{"L0": 0.1, "L1": Infinity, "L2": 0.4}', "L1"),
        ('{"L0": 0.1, "L1": 0.4, "L2": -0.4}', "L2"),
        ('{"L0": -0.1, "L1": 0.4, "L2": 0.4}', "L0"),
        ('{"L0": 0.1, "L1": 1e9, "L2": 0.4}', "L1"),
        ('{"L0": 0.1, "L1": 0.4, "L2": 0.4, "link_radius": -1}', "link_radius"),
        (
            '{"L0": 0.1, "L1": 0.4, "L2": 0.4, "joint_min": [0, 0, 0], "joint_max": [1, 0, 1]}',
            "joint_max",
        ),
        ('{"L0": 0.1, "L1": 0.4, "L2": 0.4, "joint_min": [0, -100, 0]}', "joint_min"),
        ('{"L0": 0.1, "L1": 0.4, "L2": "long"}', "L2"),  # absent fields take the default
    ],
)
def test_bad_design_is_422_naming_the_field(client, design, field):
    r = client.post(
        "/v1/design/check",
        content='{"design": ' + design + "}",
        headers={"content-type": "application/json"},
    )
    assert r.status_code == 422
    locs = [e["loc"] for e in r.json()["detail"]]
    assert any(loc[:3] == ["body", "design", field] for loc in locs), locs


def test_design_model_round_trip():
    d = Design(0.2, 0.3, 0.4, link_radius=0.01, joint_min=(-1, -2, -3), joint_max=(1, 2, 3))
    assert DesignModel.from_design(d).to_design() == d


def test_check_design_command():
    r = CliRunner().invoke(cli_app, ["check-design", "0.5", "0.2", "0.6"])
    assert r.exit_code == 0, r.output
    assert "parallel singularities: none" in r.output and "singularity free: yes" in r.output
    r = CliRunner().invoke(cli_app, ["check-design", "0.3", "0.3", "0.5"])
    assert "parallel singularities: C=D" in r.output


def test_check_design_command_rejects_a_bad_design():
    r = CliRunner().invoke(cli_app, ["check-design", "--", "0.5", "0.2", "-0.6"])
    assert r.exit_code == 2 and "L2" in r.output


def test_figures_command_writes_every_figure(tmp_path):
    r = CliRunner().invoke(cli_app, ["figures", str(tmp_path), "--n", "32", "--formats", "png,svg"])
    assert r.exit_code == 0, r.output
    for number in range(4, 16):
        for fmt in ("png", "svg"):
            files = list(tmp_path.glob(f"fig{number:02d}_*.{fmt}"))
            assert len(files) == 1, (number, fmt)
            assert files[0].stat().st_size > 2000
    png = next(tmp_path.glob("fig08_*.png")).read_bytes()
    assert png[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize(
    ("extra", "field"),
    [({"kappa_max": 0.5}, "kappa_max"), ({"rel_se": 0.0}, "rel_se"), ({"seed": -1}, "seed")],
)
def test_bad_check_options_are_422(client, extra, field):
    r = client.post("/v1/design/check", json={"design": {"L0": 0.1, "L1": 0.4, "L2": 0.4}, **extra})
    assert r.status_code == 422
    assert [e["loc"] for e in r.json()["detail"]] == [["body", field]]


def test_openapi_documents_the_design_check(client):
    spec = client.get("/openapi.json").json()
    op = spec["paths"]["/v1/design/check"]["post"]
    assert "requestBody" in op
    assert "DesignModel" in spec["components"]["schemas"]
