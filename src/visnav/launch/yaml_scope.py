"""Launch-file scaffolding: YAML with line numbers, value helpers and the entry scope.

Shared by the YAML format (:mod:`visnav.launch.yaml_format`) and the roslaunch XML
import (:mod:`visnav.launch.roslaunch`): mappings remember their line so every error
names the file and line; values follow roslaunch's spelling of booleans and
namespaces.
"""

from __future__ import annotations

import difflib
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, replace
from typing import Any

import yaml

from visnav.graph.names import InvalidNameError, validate_namespace
from visnav.launch.errors import LaunchParseError
from visnav.launch.substitutions import SubstitutionContext
from visnav.safe_yaml import LimitedSafeLoader, YamlError, load_yaml

__all__ = [
    "LineMap",
    "Scope",
    "arg_text",
    "flatten_params",
    "join_namespace",
    "parse_bool",
    "parse_yaml_text",
    "suggest_key",
    "typed_value",
]

_TRUE = ("true", "1", "yes", "on")
_FALSE = ("false", "0", "no", "off")


class LineMap(dict[str, Any]):
    """A YAML mapping that remembers its line."""

    line: int | None = None


class _LineLoader(LimitedSafeLoader):
    """Safe loader (alias limits) whose mappings are :class:`LineMap` with a line; no dup keys."""


def _construct_map(loader: _LineLoader, node: yaml.MappingNode) -> LineMap:
    loader.flatten_mapping(node)
    result = LineMap()
    result.line = node.start_mark.line + 1
    for key_node, value_node in node.value:
        key = loader.construct_object(key_node, deep=True)
        if key in result:
            mark = key_node.start_mark
            msg = f"{mark.name}:{mark.line + 1}: key {key!r} appears twice in one mapping"
            raise LaunchParseError(msg)
        result[key] = loader.construct_object(value_node, deep=True)
    return result


_LineLoader.add_constructor(yaml.resolver.BaseResolver.DEFAULT_MAPPING_TAG, _construct_map)


def parse_yaml_text(text: str, source: str) -> Any:
    """Parse YAML, keeping mapping lines; errors name the file and line.

    Loaded with visnav's alias limits (:mod:`visnav.safe_yaml`).

    Raises:
        LaunchParseError: the text is not valid YAML or breaks a limit.
    """
    return load_yaml(
        text, source=source, what="the launch file", loader=_LineLoader, error=LaunchParseError
    )


def parse_bool(value: Any, what: str, prefix: str = "") -> bool:
    """Interpret a launch value as a bool (``true/false/1/0/yes/no/on/off``, any case).

    Raises:
        LaunchParseError: anything else.
    """
    if isinstance(value, bool):
        return value
    text = str(value).strip().lower()
    if text in _TRUE:
        return True
    if text in _FALSE:
        return False
    msg = f"{prefix}{what} is {value!r}: expected true or false"
    raise LaunchParseError(msg)


def join_namespace(base: str, namespace: str, prefix: str = "") -> str:
    """Push ``namespace`` onto ``base`` as ROS does (absolute replaces, relative appends).

    Raises:
        LaunchParseError: the result is not a valid namespace.
    """
    namespace = namespace.strip()
    if not namespace:
        result = base
    elif namespace.startswith("/"):
        result = namespace
    else:
        result = f"{base.rstrip('/')}/{namespace}"
    if len(result) > 1:
        result = result.rstrip("/")
    try:
        validate_namespace(result)
    except InvalidNameError as exc:
        raise LaunchParseError(f"{prefix}namespace {namespace!r}: {exc}") from None
    return result


def arg_text(value: Any) -> str:
    """Launch arguments are strings; YAML scalars are written back the way ROS prints them."""
    if isinstance(value, bool):
        return "true" if value else "false"
    return "" if value is None else str(value)


def typed_value(text: str) -> Any:
    """Give a substituted string its YAML type (``"10"`` -> 10, ``"true"`` -> True)."""
    if not text.strip():
        return text
    try:
        value = load_yaml(text, source="a substituted value")
    except YamlError:
        return text
    if isinstance(value, bool | int | float | str):
        return value
    if isinstance(value, list) and all(isinstance(v, bool | int | float | str) for v in value):
        return value
    return text


def flatten_params(prefix: str, value: Any, out: dict[str, Any]) -> None:
    """Write nested parameter mappings into ``out`` as dotted names (``a.b.c``)."""
    if isinstance(value, Mapping):
        for key, sub in value.items():
            flatten_params(f"{prefix}.{key}" if prefix else str(key), sub, out)
    else:
        out[prefix] = value


def suggest_key(key: str, allowed: Iterable[str]) -> str:
    """``"; did you mean 'x'?"`` for the allowed key closest to ``key`` (or "")."""
    close = difflib.get_close_matches(key, list(allowed), n=1)
    return f"; did you mean {close[0]!r}?" if close else ""


@dataclass
class Scope:
    """What an entry inherits from the entries and groups around it.

    Attributes:
        ctx: substitution context (args in scope, file, line).
        namespace: the pushed namespace.
        remaps: group remaps, applied after a node's own.
        use_sim_time: group default for nodes.
        process: group default for nodes.
        passed_through: args an include passed with ``pass_all_args``: the included file
            need not declare them (as roslaunch).
    """

    ctx: SubstitutionContext
    namespace: str = "/"
    remaps: tuple[tuple[str, str], ...] = ()
    use_sim_time: bool | None = None
    process: str | None = None
    passed_through: frozenset[str] = frozenset()

    def child(self) -> Scope:
        """A scope for a group: its own copy of the args."""
        return replace(self, ctx=replace(self.ctx, args=dict(self.ctx.args)))
