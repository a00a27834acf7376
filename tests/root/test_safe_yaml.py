"""visnav.safe_yaml: the one YAML loader (alias limits, one-line errors with lines)."""

from __future__ import annotations

import time
from pathlib import Path
from typing import ClassVar

import pytest

from visnav.errors import VisnavError
from visnav.safe_yaml import LimitedSafeLoader, YamlError, load_yaml, load_yaml_file
from visnav.textfile import TextFileError


def bomb(levels: int) -> str:
    lines = ["l0: &l0 [" + ",".join(['"lol"'] * 9) + "]"]
    for k in range(1, levels):
        lines.append(f"l{k}: &l{k} [" + ",".join([f"*l{k - 1}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def test_ordinary_documents_load_as_with_safe_load() -> None:
    text = "a: &x {b: [1, 2.5, true, null, '2001-01-01']}\nc: *x\nd:\n  <<: *x\n  e: f\n"
    assert load_yaml(text, source="t.yaml") == {
        "a": {"b": [1, 2.5, True, None, "2001-01-01"]},
        "c": {"b": [1, 2.5, True, None, "2001-01-01"]},
        "d": {"b": [1, 2.5, True, None, "2001-01-01"], "e": "f"},
    }
    assert load_yaml("", source="t.yaml") is None
    assert load_yaml(bomb(4), source="t.yaml")["l3"][0][0][0][0] == "lol"  # 9^4: within limits


def test_alias_bomb_is_refused_before_construction() -> None:
    start = time.perf_counter()
    with pytest.raises(YamlError) as info:
        load_yaml(bomb(9), source="bomb.yaml", what="the launch file")
    assert time.perf_counter() - start < 1.0
    # expanded: the mapping, 9 keys and every level in full; distinct: the mapping, its
    # keys, l0 with its 9 strings and the 8 other lists (an alias is no node of its own)
    sizes = [10]
    for _ in range(8):
        sizes.append(1 + 9 * sizes[-1])
    added = (1 + 9 + sum(sizes)) - (1 + 9 + 10 + 8)
    text = str(info.value)
    assert text.startswith("bomb.yaml:1: the launch file does not parse as YAML")
    assert f"aliases expand to {added:,} more nodes, over visnav's limit of 100,000" in text
    assert "fix: write the repeated values out" in text


def test_the_limit_is_a_class_attribute() -> None:
    class Tight(LimitedSafeLoader):
        max_alias_nodes: ClassVar[int] = 10

    text = "a: &a [1, 2, 3, 4, 5]\nb: [*a, *a]\n"
    assert load_yaml(text, source="t.yaml")["b"] == [[1, 2, 3, 4, 5]] * 2
    with pytest.raises(
        YamlError, match="aliases expand to 12 more nodes, over visnav's limit of 10"
    ):
        load_yaml(text, source="t.yaml", loader=Tight)


@pytest.mark.parametrize("text", ["a: &a [*a]", "a: &a {b: *a}", "a: &a [1, [2, *a]]"])
def test_recursive_aliases_are_refused(text: str) -> None:
    with pytest.raises(YamlError, match=r"t\.yaml:1: .*an alias refers to the anchored node"):
        load_yaml(text, source="t.yaml")


@pytest.mark.parametrize(
    ("text", "fragments"),
    [
        ("a: 1\nb: [1\n", ["t.yaml:3:", "does not parse as YAML", "expected ',' or ']'"]),
        ("a: 1\nb: 2001-13-45\n", ["t.yaml:2:", "'2001-13-45' cannot be read", "month must be"]),
        ("n: " + "9" * 5000, ["t.yaml:1:", "cannot be read", "4300 digits"]),
        ("a: 1\nb: x\x80y\n", ["t.yaml:2:", "character U+0080 at column 5", 'escape "\\x80"']),
        ("a: \x07\n", ["t.yaml:1:", "U+0007"]),
        ("? [1]\n: 2\n", ["t.yaml:1:", "unhashable"]),
        ("a: !!python/object:os.system x\n", ["t.yaml:1:", "could not determine a constructor"]),
        ("[" * 3000 + "]" * 3000, ["t.yaml", "nested too deeply"]),
    ],
)
def test_failures_are_one_line_with_file_and_line(text: str, fragments: list[str]) -> None:
    with pytest.raises(YamlError) as info:
        load_yaml(text, source="t.yaml")
    message = str(info.value)
    assert "\n" not in message
    for fragment in fragments:
        assert fragment in message


def test_callers_choose_their_error_class(tmp_path: Path) -> None:
    class MyError(VisnavError):
        pass

    with pytest.raises(MyError, match="does not parse"):
        load_yaml("a: [", source="x", error=MyError)
    (tmp_path / "bad.yaml").write_bytes(b"a: caf\xe9\n")
    with pytest.raises(MyError, match=r"bad\.yaml:1: the map is not UTF-8 text \(byte 0xe9"):
        load_yaml_file(tmp_path / "bad.yaml", what="the map", error=MyError)
    with pytest.raises(YamlError, match="does not exist"):
        load_yaml_file(tmp_path / "missing.yaml")
    assert issubclass(TextFileError, VisnavError)
