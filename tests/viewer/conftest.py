"""The viewer's browser tests share one headless chromium for the session (a launch costs a
second or two); each module opens its own context and page on it (``viewer_browser.py``)."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from viewer_browser import launch


@pytest.fixture(scope="session")
def browser() -> Iterator[object]:
    """One headless chromium for every viewer test of the session."""
    with launch() as b:
        yield b
