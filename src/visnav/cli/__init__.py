"""The ``visnav`` command line: one module per verb, each wrapping a library function."""

from __future__ import annotations

__all__: list[str] = []
