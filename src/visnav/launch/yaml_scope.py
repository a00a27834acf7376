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

from visnav.graph.names import InvalidNameError, validate_namespace
from visnav.launch.errors import LaunchParseError
from visnav.launch.substitutions import SubstitutionContext
from visnav.safe_yaml import YamlError, load_yaml, load_yaml_lines

__all__ = [
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


def parse_yaml_text(text: str, source: str) -> Any:
    """Parse a launch file: mappings are :class:`~visnav.safe_yaml.LineMap` with their line.

    Loaded by :func:`visnav.safe_yaml.load_yaml_lines` (alias limits, merge keys, a key
    written twice refused); errors name the file and line.

    Raises:
        LaunchParseError: the text is not valid YAML or breaks a limit.
    """
    return load_yaml_lines(text, source=source, what="the launch file", error=LaunchParseError)


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
