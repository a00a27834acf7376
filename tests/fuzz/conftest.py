"""Shared pieces of the fuzz suite: byte/text mutations and the "only visnav errors" check.

Every fuzz test feeds a parser random or mutated input and calls it through
:func:`only_visnav_errors`: a :class:`~visnav.errors.VisnavError` is the expected
way to refuse bad input; any other exception escapes and fails the test, and
hypothesis shrinks it to a minimal input.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from typing import Any, TypeVar

from hypothesis import HealthCheck, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError

T = TypeVar("T")

_DEEP = int(os.environ.get("VISNAV_FUZZ_EXAMPLES", "0"))
FUZZ = settings(
    max_examples=_DEEP or 80,
    deadline=None,
    derandomize=not _DEEP,  # the default run is deterministic; a deep run explores
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.filter_too_much],
)
"""Settings of every fuzz test: 80 fixed examples in the default test run;
``VISNAV_FUZZ_EXAMPLES=5000`` explores that many random ones per test."""

FUZZ_STRUCTURED = settings(FUZZ, max_examples=_DEEP or 40)
"""Structure-aware tests draw many values per example: fewer examples by default."""

# bytes that tend to break parsers: delimiters, quotes, control characters, non-UTF-8
INTERESTING = [
    b"\x00", b"\xff", b"\xe9", b"\x85", b"\x80", b"\x1b", b"\t", b"\n", b"\r", b" ", b":",
    b"-", b",", b"[", b"]", b"{", b"}", b"<", b">", b"/", b'"', b"'", b"&", b"*", b"!",
    b"#", b"%", b"$(", b"0", b"-1", b"1e309", b"nan", b"inf", b"99999999999999999999",
    b"&a ", b"*a", b"<<: ", b"!!python/object ", b"\xef\xbb\xbf", b"<!--", b"]]>",
]  # fmt: skip


@st.composite
def mutated(draw: st.DrawFn, seed: bytes, *, max_edits: int = 6) -> bytes:
    """``seed`` with a few random edits: replace, insert, delete, duplicate or truncate."""
    data = bytearray(seed)
    for _ in range(draw(st.integers(1, max_edits))):
        kind = draw(st.sampled_from(["replace", "insert", "delete", "dup", "truncate"]))
        pos = draw(st.integers(0, max(len(data) - 1, 0)))
        if kind == "truncate":
            del data[pos:]
            continue
        if kind == "delete":
            del data[pos : pos + draw(st.integers(1, 16))]
            continue
        if kind == "dup":
            end = pos + draw(st.integers(1, 64))
            data[pos:pos] = data[pos:end]
            continue
        piece = draw(st.one_of(st.sampled_from(INTERESTING), st.binary(min_size=1, max_size=4)))
        if kind == "replace":
            data[pos : pos + len(piece)] = piece
        else:
            data[pos:pos] = piece
    return bytes(data)


def only_visnav_errors(func: Callable[..., T], *args: Any, **kwargs: Any) -> T | None:
    """Call ``func``; a VisnavError means "refused" (None), anything else escapes."""
    try:
        return func(*args, **kwargs)
    except VisnavError as exc:
        if not str(exc).strip():
            msg = f"{type(exc).__name__} without a message"
            raise AssertionError(msg) from exc
        return None
