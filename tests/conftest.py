"""Shared fixtures: a private graph domain per test, so tests never see each other."""

from __future__ import annotations

import itertools
import os
import subprocess
import sys
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

_counter = itertools.count()


@pytest.fixture
def domain(monkeypatch: pytest.MonkeyPatch) -> int:
    """A graph domain id no other test (or test run) uses; also set as VISNAV_DOMAIN."""
    value = 1_000_000 + (os.getpid() % 20_000) * 1000 + next(_counter) % 1000
    monkeypatch.setenv("VISNAV_DOMAIN", str(value))
    return value


@pytest.fixture
def start_script(domain: int) -> Iterator[Callable[..., subprocess.Popen[str]]]:
    """Start ``python SCRIPT ARGS...`` in the test's domain; wait for its ``ready`` line.

    The processes are killed when the test ends.
    """
    procs: list[subprocess.Popen[str]] = []

    def start(script: Path, *args: str) -> subprocess.Popen[str]:
        env = {**os.environ, "VISNAV_DOMAIN": str(domain)}
        proc = subprocess.Popen(
            [sys.executable, str(script), *args], env=env, stdout=subprocess.PIPE, text=True
        )
        procs.append(proc)
        assert proc.stdout is not None
        line = proc.stdout.readline().strip()
        if line != "ready":
            pytest.fail(f"{script.name} did not start (first line {line!r})")
        return proc

    yield start
    for proc in procs:
        proc.kill()
        proc.wait(timeout=10)
