"""Launch tests: make ``launch_test_nodes`` importable here and in child processes."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

HERE = Path(__file__).resolve().parent


@pytest.fixture
def test_nodes_path(monkeypatch: pytest.MonkeyPatch) -> Path:
    """Put tests/launch on sys.path and PYTHONPATH (children inherit it)."""
    monkeypatch.syspath_prepend(str(HERE))
    old = os.environ.get("PYTHONPATH")
    monkeypatch.setenv("PYTHONPATH", str(HERE) + (os.pathsep + old if old else ""))
    return HERE
