"""The key settings at start: a tenant file (``PLANNER_API_KEYS=/path``) with a duplicate
key, a duplicate tenant, a malformed line, a bad tenant name, no tenant at all, or that
cannot be read is refused naming the file and the line, and so is a bad inline list
(naming the entry); both PLANNER_API_KEY and PLANNER_API_KEYS set is refused; the new store
settings are validated naming the variable; no message carries a key. ``planner serve``
refuses to start on such a file (exit status 2, the file and line on stderr). The start
log's word about a keyless service (:func:`planner_api.server.keyless_notice`)."""

from __future__ import annotations

import logging
import os
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import ValidationError

from planner_api.server import keyless_notice
from planner_api.settings import Settings

ROOT = Path(__file__).resolve().parents[2]


def _refusal(**settings: object) -> str:
    with pytest.raises(ValidationError) as caught:
        Settings(**settings)
    return str(caught.value)


def test_a_good_file_and_an_inline_list_define_the_tenants(tmp_path):
    keys = tmp_path / "keys"
    keys.write_text("# tenant key\nalice  k-alice\n   # indented comment\nbob\tk-bob\n")
    assert Settings(api_keys=str(keys)).tenant_keys == {"k-alice": "alice", "k-bob": "bob"}
    assert Settings(api_keys="alice:k1, bob:k:2").tenant_keys == {"k1": "alice", "k:2": "bob"}
    assert Settings(api_key="solo").tenant_keys == {"solo": "default"}
    assert Settings(api_key="", api_keys=" ").tenant_keys is None  # empty: no key


@pytest.mark.parametrize(
    ("text", "line", "rule"),
    [
        ("alice k1\nbob k1\n", 2, "already the key at"),
        ("alice k1\n# x\nalice k2\n", 3, "appears twice"),
        ("alice k1\nbob\n", 2, "got 1 field"),
        ("alice k1\n\nbob k2\n", 2, "an empty line"),
        ("alice k1\n   \n", 2, "an empty line"),
        ("alice k1 extra\n", 1, "got 3 field"),
        ("-alice k1\n", 1, "tenant name"),
        ("alice k\x7f1\n", 1, "printable ASCII"),
    ],
)
def test_a_bad_tenant_file_is_refused_naming_file_and_line(tmp_path, text, line, rule):
    keys = tmp_path / "tenants.txt"
    keys.write_text(text)
    message = _refusal(api_keys=str(keys))
    assert f"{keys}:{line}" in message and rule in message
    assert "k1" not in message and "k2" not in message  # never a key in the message


def test_an_unreadable_or_empty_file_is_refused_naming_it(tmp_path):
    missing = tmp_path / "nowhere"
    assert f"{missing}" in _refusal(api_keys=str(missing))
    empty = tmp_path / "empty"
    empty.write_text("# nothing but comments\n")
    message = _refusal(api_keys=str(empty))
    assert str(empty) in message and "lists no tenant" in message
    folder = tmp_path / "dir"
    folder.mkdir()
    assert "cannot be read" in _refusal(api_keys=str(folder))


@pytest.mark.parametrize(
    ("value", "rule"),
    [
        ("alice:k1,bob:k1", "entry 2: the key of tenant 'bob' is already the key at"),
        ("alice:k1,alice:k2", "entry 2: tenant 'alice' appears twice"),
        ("alice", "entry 1: expected 'tenant:key'"),
        ("alice:k1,,bob:k2", "entry 2: expected 'tenant:key'"),
        ("alice:", "entry 1: tenant 'alice' has an empty key"),
        ("keys.txt", "a file path starts with /, ./ or ~"),
    ],
)
def test_a_bad_inline_list_is_refused_naming_the_entry(value, rule):
    message = _refusal(api_keys=value)
    assert "PLANNER_API_KEYS" in message and rule in message


def test_both_key_settings_are_refused():
    message = _refusal(api_key="one", api_keys="alice:two")
    assert "PLANNER_API_KEY and PLANNER_API_KEYS are both set" in message
    assert "one" not in message.replace("set one", "")


@pytest.mark.parametrize(
    ("field", "value"),
    [
        ("store_timeout_s", 0),
        ("store_timeout_s", "nan"),
        ("store_threads", 0),
        ("scenes_max", 0),
        ("scene_bytes_max", 10),
    ],
)
def test_the_store_settings_are_validated_naming_the_variable(monkeypatch, field, value):
    monkeypatch.setenv(f"PLANNER_{field.upper()}", str(value))
    assert field in _refusal()


def test_planner_serve_refuses_a_bad_tenant_file_naming_file_and_line(tmp_path):
    keys = tmp_path / "tenants"
    keys.write_text("alice k1\nalice k2\n")
    env = {**os.environ, "PLANNER_API_KEYS": str(keys), "PLANNER_WORKERS": "1"}
    env.pop("PLANNER_API_KEY", None)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT / "src"), env.get("PYTHONPATH", "")])
    done = subprocess.run(
        [sys.executable, "-m", "planner_cli", "serve", "--port", "1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert f"{keys}:2" in done.stderr and "appears twice" in done.stderr


def test_the_start_log_says_when_the_service_is_keyless():
    level, message = keyless_notice(Settings(host="127.0.0.1"))
    assert level == logging.INFO and "keyless" in message and "loopback" in message
    assert keyless_notice(Settings(host="::1"))[0] == logging.INFO
    level, message = keyless_notice(Settings(host="0.0.0.0"))
    assert level == logging.WARNING and "0.0.0.0" in message and "anyone" in message
    assert keyless_notice(Settings(host="0.0.0.0", api_key="k")) is None
    assert keyless_notice(Settings(api_keys="a:k")) is None
