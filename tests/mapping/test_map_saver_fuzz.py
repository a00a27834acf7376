"""Fuzz map_saver's and map_server's command-line parsers: only visnav errors escape."""

from __future__ import annotations

from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from visnav.errors import VisnavError
from visnav.mapping.map_saver_node import MapSaverArgs, parse_map_saver_args
from visnav.mapping.map_server_node import map_server_args

_SETTINGS = settings(
    max_examples=150, deadline=None, derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)  # fmt: skip

# tokens map_saver knows, values that break int(), remaps and free text
_TOKENS = st.one_of(
    st.sampled_from(["-f", "--occ", "--free", "-h", "--help", "map:=", ":=", "map:=/m",
                     "_a:=1", "__name:=x", "65", "25", "0", "100", "-1", "101", "1e3",
                     "65.5", " ", "", "nan", "\x00", "٣", "99999999999999999999999"]),
    st.text(max_size=12),
)  # fmt: skip


@_SETTINGS
@given(st.lists(_TOKENS, max_size=8))
def test_map_saver_args_only_visnav_errors(args: list[str]) -> None:
    try:
        parsed = parse_map_saver_args(args)
    except VisnavError:
        return
    assert isinstance(parsed, MapSaverArgs)
    assert 0 <= parsed.free < parsed.occ <= 100
    assert parsed.file.strip()
    assert all(a and b.strip() for a, b in parsed.remaps)


@_SETTINGS
@given(st.lists(_TOKENS, max_size=6))
def test_map_server_args_only_visnav_errors(args: list[str]) -> None:
    try:
        params, remaps = map_server_args(args)
    except VisnavError:
        return
    assert params["yaml_filename"].strip()
    assert all(":=" not in a for a in [params["yaml_filename"]])
    assert all(a and not a.startswith("_") for a, _ in remaps)
