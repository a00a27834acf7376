"""Shared fixtures: a private graph domain per test, so tests never see each other."""

from __future__ import annotations

import itertools
import os

import pytest

_counter = itertools.count()


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A graph domain id no other test (or test run) uses; also set as VISNAV_DOMAIN."""
    value = 1_000_000 + (os.getpid() % 20_000) * 1000 + next(_counter) % 1000
    monkeypatch.setenv("VISNAV_DOMAIN", str(value))
    return value
