"""visnav.safe_yaml.load_yaml_lines: the one line-numbered loader of launch files and worlds."""

from __future__ import annotations

import textwrap
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import given, settings
from hypothesis import strategies as st

from visnav.description.errors import WorldError
from visnav.description.world import load_world
from visnav.launch import LaunchParseError, load_launch
from visnav.safe_yaml import LineMap, YamlError, load_yaml_lines

MERGES = [
    "base: &b {a: 1, b: 2}\nuse: {<<: *b, c: 3}\n",
    "base: &b {a: 1, b: 2}\nuse: {<<: *b, a: 9}\n",  # the own key overrides the merged one
    "x: &x {k: 1, m: 1}\ny: &y {k: 2, n: 2}\nuse: {<<: [*x, *y], z: 0}\n",  # first one wins
    "a: &a {p: 1}\nb: &b {<<: *a, q: 2}\nc: {<<: *b, r: 3, p: 7}\n",  # merges of merges
    "c: {<<: &m {<<: {deep: 1}, mid: 2}, top: 3}\nd: *m\n",  # an inline merged anchor
    "list: [{<<: {a: 1}, b: 2}, {c: 3}]\n",
]


def _plain(value: Any) -> Any:
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_plain(v) for v in value]
    return value


@pytest.mark.parametrize("text", MERGES)
def test_merge_keys_load_as_pyyaml_does(text: str) -> None:
    assert _plain(load_yaml_lines(text, source="m.yaml")) == yaml.safe_load(text)


def test_mappings_remember_their_line() -> None:
    doc = load_yaml_lines("a: 1\nb:\n  c:\n    d: 2\ne: [{f: 1}]\n", source="x.yaml")
    assert isinstance(doc, LineMap)
    assert doc.line == 1
    assert doc["b"].line == 3  # a block mapping starts at its first key
    assert doc["b"]["c"].line == 4
    assert doc["e"][0].line == 5


@pytest.mark.parametrize(
    ("text", "line", "fragment"),
    [
        ("a: 1\nb:\n  c: 1\n  c: 2\n", 4, "duplicate key 'c': 'c' appears twice"),
        ("base: &b {a: 1}\nuse: {<<: *b, c: 1, c: 2}\n", 2, "duplicate key 'c'"),
        ("a: {<<: 3}\n", 1, "a merge key '<<' takes a mapping"),
        ("a: {<<: [{b: 1}, 2]}\n", 1, "a merge key '<<' takes a mapping"),
        ("a:\n  [1, 2]: 3\n", 2, "a key is a list, which cannot be a mapping key"),
        ("a: {b: 1\n", 2, "does not parse as YAML"),
    ],
)
def test_errors_are_one_line_with_the_line(text: str, line: int, fragment: str) -> None:
    with pytest.raises(YamlError) as info:
        load_yaml_lines(text, source="bad.yaml")
    message = str(info.value)
    assert message.startswith(f"bad.yaml:{line}: "), message
    assert fragment in message
    assert "\n" not in message


def test_string_keys() -> None:
    doc = load_yaml_lines("1: a\ntrue: b\nx: {2: c}\n", source="s.yaml", string_keys=True)
    assert doc == {"1": "a", "True": "b", "x": {"2": "c"}}
    assert load_yaml_lines("1: a\n", source="s.yaml") == {1: "a"}


def test_merged_alias_bombs_are_still_refused() -> None:
    lines = ["l0: &l0 {" + ", ".join(f"k{i}: lol" for i in range(9)) + "}"]
    for k in range(1, 8):
        items = ", ".join(f"m{i}: *l{k - 1}" for i in range(9))
        lines.append(f"l{k}: &l{k} {{<<: *l{k - 1}, {items}}}")
    with pytest.raises(YamlError, match="limit"):
        load_yaml_lines("\n".join(lines) + "\n", source="bomb.yaml")


scalars = st.one_of(st.integers(-5, 5), st.text("abc", max_size=3), st.booleans(), st.none())
documents = st.recursive(
    st.dictionaries(st.text("xyz", min_size=1, max_size=3), scalars, max_size=4),
    lambda inner: st.dictionaries(
        st.text("xyz", min_size=1, max_size=3), inner | st.lists(inner, max_size=3), max_size=4
    ),
    max_leaves=20,
)


@settings(deadline=None, max_examples=60)
@given(documents)
def test_plain_documents_load_as_safe_load(doc: dict[str, Any]) -> None:
    text = yaml.safe_dump(doc)
    assert _plain(load_yaml_lines(text, source="d.yaml")) == yaml.safe_load(text)


# ----------------------------------------------------------------------------- both callers


@pytest.mark.parametrize(
    ("load", "error", "text", "line", "fragment"),
    [
        (
            load_world,
            WorldError,
            "name: w\nobjects:\n  - {type: box, size: [1, 1, 1], size: [2, 2, 2]}\n",
            3,
            "duplicate key 'size'",
        ),
        (
            load_world,
            WorldError,  # a merged object is checked as a written one
            "objects:\n  - &w {type: box, size: [1, 1, 1]}\n  - {<<: *w, sise: 1}\n",
            3,
            "unknown key 'sise'",
        ),
        (
            load_launch,
            LaunchParseError,
            "launch:\n  - node:\n      exec: image_proc\n      exec: x\n",
            4,
            "'exec' appears twice",
        ),
        (
            load_launch,
            LaunchParseError,
            "launch:\n  - node: &n {exec: image_proc}\n  - node: {<<: *n, parms: {}}\n",
            3,
            "did you mean 'params'?",
        ),
    ],
)
def test_both_callers_name_the_file_and_line(
    tmp_path: Path, load: Any, error: type[Exception], text: str, line: int, fragment: str
) -> None:
    path = tmp_path / "bad.yaml"
    path.write_text(text)
    with pytest.raises(error) as info:
        load(path)
    assert str(info.value).startswith(f"{path}:{line}: "), str(info.value)
    assert fragment in str(info.value)


def test_world_files_take_merge_keys(tmp_path: Path) -> None:
    path = tmp_path / "merge.yaml"
    path.write_text(
        textwrap.dedent(
            """\
            name: w
            objects:
              - &wall {type: box, pos: [0, 5, 1], size: [10, 0.2, 2], name: north}
              - {<<: *wall, pos: [0, -5, 1], name: south}
              - {<<: *wall, size: [1, 1, 1], name: east}
            """
        )
    )
    by_name = {s.name: s for s in load_world(path).shapes}
    assert set(by_name) == {"north", "south", "east"}
    assert by_name["south"].pos == (0.0, -5.0, 1.0)
    assert by_name["south"].size == (10.0, 0.2, 2.0)  # type: ignore[union-attr]
    assert by_name["east"].size == (1.0, 1.0, 1.0)  # type: ignore[union-attr]


def test_launch_files_take_merge_keys(tmp_path: Path) -> None:
    path = tmp_path / "merge.launch.yaml"
    path.write_text(
        textwrap.dedent(
            """\
            launch:
              - node: &rect {exec: image_proc, name: rect_a, params: {queue_size: 3}}
              - node: {<<: *rect, name: rect_b}
            """
        )
    )
    nodes = {n.name: n for n in load_launch(path).nodes}
    assert set(nodes) == {"rect_a", "rect_b"}
    assert nodes["rect_b"].executable == "image_proc"
    assert nodes["rect_b"].params["queue_size"] == 3
