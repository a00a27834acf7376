"""Fixtures for the simulator tests: headless OpenGL chosen per test, not at import."""

from __future__ import annotations

import os

import pytest


@pytest.fixture
def mujoco_gl(monkeypatch: pytest.MonkeyPatch) -> str:
    """Select EGL for MuJoCo rendering (unless the environment already chose a backend)."""
    if os.environ.get("MUJOCO_GL", "").strip().lower() not in ("egl", "osmesa"):
        monkeypatch.setenv("MUJOCO_GL", "egl")
    return os.environ["MUJOCO_GL"]
