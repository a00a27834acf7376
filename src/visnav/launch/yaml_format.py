"""visnav's YAML launch format: args, substitutions, includes, groups and nodes.

The layout follows ROS 2's YAML launch files (a ``launch:`` list of one-key
entries, ``$(...)`` substitutions, ``if`` / ``unless``); nodes are visnav's own
(``exec: image_proc`` or ``exec: my_pkg.nodes:MyNode``) and say whether they
share the launch process or run in their own. docs/launch.md describes every
key; :func:`load_yaml_launch` is the entry point.

Entries are evaluated in order, as ROS 2 does: an ``arg`` or ``let`` is visible
to the entries after it; a ``group`` scopes its ``let`` values, namespace,
remaps and defaults to its children. An included file sees only the args given
to it (and, with ``pass_all_args: true``, every arg in scope), as roslaunch.
"""

from __future__ import annotations

import difflib
import os
from collections.abc import Callable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from visnav.graph.names import InvalidNameError, validate_node_name
from visnav.launch.description import (
    ON_ERROR,
    PROCESS_KINDS,
    ArgInfo,
    LaunchDescription,
    NodeSpec,
    check_param_value,
    default_process,
)
from visnav.launch.errors import LaunchArgError, LaunchParseError, where
from visnav.launch.substitutions import has_substitution, substitute
from visnav.launch.yaml_scope import (
    Scope,
    arg_text,
    flatten_params,
    join_namespace,
    parse_bool,
    parse_yaml_text,
    suggest_key,
    typed_value,
)
from visnav.mapping.errors import MappingError
from visnav.node_registry import UnknownNodeError, check_node_name
from visnav.safe_yaml import LineMap
from visnav.textfile import TextFileError, read_text
from visnav.tf.static_tf import StaticTransformError, static_transform_params_from_args

__all__ = [
    "ENTRY_KEYS",
    "IncludeLoader",
    "Scope",
    "join_namespace",
    "load_yaml_launch",
    "parse_bool",
    "parse_yaml_text",
]

ENTRY_KEYS: Mapping[str, frozenset[str]] = {
    "arg": frozenset({"name", "default", "description", "choices", "if", "unless"}),
    "let": frozenset({"name", "value", "if", "unless"}),
    "include": frozenset({"file", "args", "pass_all_args", "namespace", "if", "unless"}),
    "group": frozenset(
        {"namespace", "remap", "use_sim_time", "process", "children", "if", "unless"}
    ),
    "node": frozenset(
        {
            "exec",
            "name",
            "namespace",
            "params",
            "remap",
            "args",
            "use_sim_time",
            "process",
            "respawn",
            "respawn_delay",
            "respawn_max_retries",
            "required",
            "on_error",
            "if",
            "unless",
        }
    ),
}


def _map_server_args(words: Sequence[str]) -> dict[str, Any]:
    from visnav.mapping.map_server_node import map_server_params_from_args  # noqa: PLC0415

    return map_server_params_from_args(words)


def _map_saver_args(words: Sequence[str]) -> dict[str, Any]:
    from visnav.mapping.map_saver_node import map_saver_params_from_args  # noqa: PLC0415

    return map_saver_params_from_args(words)


# Built-in nodes that also accept a command line (``args:``), translated into parameters.
_ARG_TRANSLATORS: Mapping[str, Callable[[Sequence[str]], dict[str, Any]]] = {
    "static_transform_publisher": static_transform_params_from_args,
    "map_server": _map_server_args,  # map_server MAP.yaml
    "map_saver": _map_saver_args,  # map_saver -f NAME --occ N --free N
}

IncludeLoader = Callable[[str, Mapping[str, str], Scope, tuple[str, ...]], list[NodeSpec]]
"""Loads an included file: (path, args, scope of the include, include chain) -> nodes."""


# --------------------------------------------------------------------------- interpreter
class _YamlInterpreter:
    def __init__(
        self,
        path: Path,
        given: Mapping[str, str],
        scope: Scope,
        *,
        chain: tuple[str, ...],
        include: IncludeLoader,
        description: LaunchDescription | None,
    ) -> None:
        self.path = path
        self.source = str(path)
        self.given = dict(given)
        self.declared: dict[str, int | None] = {}
        self.scope = scope
        self.chain = chain
        self.include_loader = include
        self.description = description  # top-level file only: records args
        self.nodes: list[NodeSpec] = []

    # ---------------------------------------------------------------- plumbing
    def at(self, line: int | None) -> str:
        return where(self.source, line)

    def sub(self, value: Any, scope: Scope, line: int | None) -> Any:
        """Substitute every string inside ``value`` (typed again if it had ``$(``)."""
        scope.ctx.line = line
        if isinstance(value, str):
            if not has_substitution(value):
                return value
            return typed_value(substitute(value, scope.ctx))
        if isinstance(value, list):
            return [self.sub(v, scope, line) for v in value]
        if isinstance(value, Mapping):
            return {k: self.sub(v, scope, line) for k, v in value.items()}
        return value

    def text(self, value: Any, scope: Scope, line: int | None) -> str:
        """Substitute and return a string."""
        scope.ctx.line = line
        return substitute(arg_text(value), scope.ctx)

    def body(self, kind: str, value: Any, line: int | None) -> LineMap:
        if not isinstance(value, LineMap):
            msg = (
                f"{self.at(line)}'{kind}' needs a mapping of keys "
                f"({', '.join(sorted(ENTRY_KEYS[kind]))}), got {value!r}"
            )
            raise LaunchParseError(msg)
        for key in value:
            if key not in ENTRY_KEYS[kind]:
                msg = (
                    f"{self.at(value.line)}unknown key {key!r} in '{kind}'"
                    f"{suggest_key(str(key), ENTRY_KEYS[kind])} ('{kind}' takes "
                    f"{', '.join(sorted(ENTRY_KEYS[kind]))})"
                )
                if kind == "node" and key in ("pkg", "executable", "plugin"):
                    msg += "; name the node with 'exec: <built-in name>' or 'exec: module:Class'"
                raise LaunchParseError(msg)
        return value

    def enabled(self, body: LineMap, scope: Scope) -> bool:
        if "if" in body and not parse_bool(
            self.text(body["if"], scope, body.line), "'if'", self.at(body.line)
        ):
            return False
        return not (
            "unless" in body
            and parse_bool(
                self.text(body["unless"], scope, body.line), "'unless'", self.at(body.line)
            )
        )

    def required(self, body: LineMap, key: str, kind: str) -> Any:
        if key not in body or body[key] is None or body[key] == "":
            msg = f"{self.at(body.line)}'{kind}' needs '{key}'"
            raise LaunchParseError(msg)
        return body[key]

    # ---------------------------------------------------------------- entries
    def run(self, entries: Any, line: int | None) -> list[NodeSpec]:
        self.entries(entries, self.scope, line)
        unused = sorted(set(self.given) - set(self.declared) - self.scope.passed_through)
        if unused:
            name = unused[0]
            hint = suggest_key(name, self.declared)
            declared = ", ".join(sorted(self.declared)) or "none"
            msg = (
                f"{self.source}: argument {name}:={self.given[name]!r} was given but the file "
                f"declares no arg {name!r}{hint} (declared: {declared})"
            )
            raise LaunchArgError(msg)
        return self.nodes

    def entries(self, entries: Any, scope: Scope, line: int | None) -> None:
        if entries is None:
            return
        if not isinstance(entries, list):
            msg = f"{self.at(line)}expected a list of entries (- node: ...), got {entries!r}"
            raise LaunchParseError(msg)
        for entry in entries:
            if not isinstance(entry, LineMap) or len(entry) != 1:
                msg = (
                    f"{self.at(getattr(entry, 'line', line))}each entry is one of "
                    f"{', '.join(ENTRY_KEYS)} with its keys below it (e.g. '- node: {{exec: "
                    f"image_proc}}'), got {entry!r}"
                )
                raise LaunchParseError(msg)
            ((kind, value),) = entry.items()
            if kind not in ENTRY_KEYS:
                hint = suggest_key(str(kind), ENTRY_KEYS)
                msg = (
                    f"{self.at(entry.line)}unknown entry {kind!r}{hint}"
                    f" (entries: {', '.join(ENTRY_KEYS)})"
                )
                raise LaunchParseError(msg)
            body = self.body(kind, value, entry.line)
            body.line = entry.line  # report the '- node:' line, where the entry starts
            if not self.enabled(body, scope):
                if kind == "arg":
                    self.declared.setdefault(str(body.get("name")), body.line)
                continue
            getattr(self, f"do_{kind}")(body, scope)

    def do_arg(self, body: LineMap, scope: Scope) -> None:
        name = str(self.required(body, "name", "arg"))
        if name in self.declared:
            msg = (
                f"{self.at(body.line)}arg {name!r} is declared twice (first at line "
                f"{self.declared[name]}); declare it once"
            )
            raise LaunchParseError(msg)
        self.declared[name] = body.line
        description = arg_text(body.get("description", ""))
        default: str | None = None
        if "default" in body:
            default = self.text(body["default"], scope, body.line)
        if name in self.given:
            value = self.given[name]
        elif default is not None:
            value = default
        else:
            unused = [g for g in self.given if g not in self.declared]
            close = difflib.get_close_matches(name, unused, n=1)
            hint = f"; you gave {close[0]}:=..., did you mean {name}:=...?" if close else ""
            msg = (
                f"{self.at(body.line)}missing arg {name!r} (no default"
                + (f": {description}" if description else "")
                + f"): give it as {name}:=VALUE{hint}"
            )
            raise LaunchArgError(msg)
        if "choices" in body:
            raw = body["choices"]
            if not isinstance(raw, list) or not all(
                isinstance(c, bool | int | float | str) for c in raw
            ):
                msg = (
                    f"{self.at(body.line)}arg {name!r}: choices is {raw!r}: expected a list "
                    "of values; fix: write e.g. choices: [low, high]"
                )
                raise LaunchParseError(msg)
            choices = [arg_text(c) for c in raw]
            if value not in choices:
                close = difflib.get_close_matches(value, choices, n=1)
                hint = f"; did you mean {close[0]!r}?" if close else ""
                msg = (
                    f"{self.at(body.line)}arg {name!r} is {value!r}: expected one of "
                    f"{', '.join(choices)}{hint}"
                )
                raise LaunchArgError(msg)
        scope.ctx.args[name] = value
        if self.description is not None:
            self.description.args[name] = ArgInfo(name, value, default, description)

    def do_let(self, body: LineMap, scope: Scope) -> None:
        name = str(self.required(body, "name", "let"))
        scope.ctx.args[name] = self.text(body.get("value", ""), scope, body.line)

    def do_group(self, body: LineMap, scope: Scope) -> None:
        inner = scope.child()
        line = body.line
        if "namespace" in body:
            ns = self.text(body["namespace"], scope, line)
            inner.namespace = join_namespace(scope.namespace, ns, self.at(line))
        if "remap" in body:
            inner.remaps = self.remaps(body["remap"], scope, line) + scope.remaps
        if "use_sim_time" in body:
            inner.use_sim_time = parse_bool(
                self.text(body["use_sim_time"], scope, line), "use_sim_time", self.at(line)
            )
        if "process" in body:
            inner.process = self.process(body["process"], scope, line)
        self.entries(body.get("children"), inner, line)

    def do_include(self, body: LineMap, scope: Scope) -> None:
        line = body.line
        file_text = self.text(self.required(body, "file", "include"), scope, line)
        path = Path(file_text)
        if not path.is_absolute():
            path = self.path.parent / path
        args: dict[str, str] = {}
        pass_all = parse_bool(
            self.text(body.get("pass_all_args", False), scope, line), "pass_all_args", self.at(line)
        )
        if pass_all:
            args.update(scope.ctx.args)
        raw = body.get("args") or {}
        if isinstance(raw, list):  # ROS 2 form: [{name: x, value: y}]
            pairs = []
            for item in raw:
                if not isinstance(item, Mapping) or set(item) != {"name", "value"}:
                    msg = f"{self.at(line)}include args: expected {{name:, value:}}, got {item!r}"
                    raise LaunchParseError(msg)
                pairs.append((item["name"], item["value"]))
        elif isinstance(raw, Mapping):
            pairs = list(raw.items())
        else:
            msg = f"{self.at(line)}include args: expected a mapping name: value, got {raw!r}"
            raise LaunchParseError(msg)
        for key, value in pairs:
            args[str(key)] = self.text(value, scope, line)
        inner = scope.child()
        inner.passed_through = frozenset(scope.ctx.args) if pass_all else frozenset()
        if "namespace" in body:
            ns = self.text(body["namespace"], scope, line)
            inner.namespace = join_namespace(scope.namespace, ns, self.at(line))
        chain = (*self.chain, f"{self.source}:{line}")
        included = self.include_loader(str(path), args, inner, chain)
        if inner.use_sim_time is not None:  # a group's use_sim_time reaches roslaunch files too
            included = [
                n if n.use_sim_time is not None else replace(n, use_sim_time=inner.use_sim_time)
                for n in included
            ]
        self.nodes.extend(included)

    def remaps(self, value: Any, scope: Scope, line: int | None) -> tuple[tuple[str, str], ...]:
        pairs: list[tuple[Any, Any]]
        if isinstance(value, Mapping):
            pairs = list(value.items())
        elif isinstance(value, list):
            pairs = []
            for item in value:
                if isinstance(item, str) and ":=" in item:
                    a, _, b = item.partition(":=")
                    pairs.append((a, b))
                elif isinstance(item, Mapping) and set(item) == {"from", "to"}:
                    pairs.append((item["from"], item["to"]))
                else:
                    msg = (
                        f"{self.at(line)}remap entry {item!r}: expected 'from:=to' or "
                        "{from: ..., to: ...}"
                    )
                    raise LaunchParseError(msg)
        else:
            msg = f"{self.at(line)}remap: expected a mapping from: to, got {value!r}"
            raise LaunchParseError(msg)
        return tuple((self.text(a, scope, line), self.text(b, scope, line)) for a, b in pairs)

    def process(self, value: Any, scope: Scope, line: int | None) -> str:
        kind = self.text(value, scope, line)
        if kind not in PROCESS_KINDS:
            msg = f"{self.at(line)}process is {kind!r}: expected 'shared' or 'own'"
            raise LaunchParseError(msg)
        return kind

    def params(self, value: Any, scope: Scope, line: int | None, fqn: str) -> dict[str, Any]:
        items = value if isinstance(value, list) else [value]
        out: dict[str, Any] = {}
        for item in items:
            if isinstance(item, str):
                out.update(self.param_file(self.text(item, scope, line), fqn, line))
            elif isinstance(item, Mapping):
                flatten_params("", self.sub(item, scope, line), out)
            else:
                msg = (
                    f"{self.at(line)}params: expected a mapping name: value or a parameter "
                    f"file path, got {item!r}"
                )
                raise LaunchParseError(msg)
        for key, val in out.items():
            out[key] = check_param_value(key, val, self.at(line))
        return out

    def param_file(self, file_text: str, fqn: str, line: int | None) -> dict[str, Any]:
        path = Path(file_text)
        if not path.is_absolute():
            path = self.path.parent / path
        try:
            text = read_text(path, what="the parameter file")
        except TextFileError as exc:
            raise LaunchParseError(f"{self.at(line)}{exc}") from None
        data = parse_yaml_text(text, str(path))
        if not isinstance(data, Mapping):
            msg = f"{path}: a parameter file maps node names to {{ros__parameters: ...}}"
            raise LaunchParseError(msg)
        name = fqn.rsplit("/", 1)[-1]
        keys = {fqn, fqn.lstrip("/"), name, "/**", "**", f"/**/{name}"}
        out: dict[str, Any] = {}
        if not any(isinstance(v, Mapping) and "ros__parameters" in v for v in data.values()):
            # a flat file (ROS 1's rosparam layout): every key is a parameter of this node
            flatten_params("", data, out)
            return out
        if not keys & set(data):
            msg = (
                f"{path}: no section for node {fqn}: the file has {', '.join(map(str, data))}; "
                f"name the section {name!r}, {fqn!r} or '/**' (ROS 2 parameter file format)"
            )
            raise LaunchParseError(msg)
        for key, section in data.items():
            if key not in keys:
                continue
            if not isinstance(section, Mapping) or "ros__parameters" not in section:
                msg = (
                    f"{path}:{getattr(section, 'line', '?')}: section {key!r} needs a "
                    "'ros__parameters:' mapping (ROS 2 parameter file format)"
                )
                raise LaunchParseError(msg)
            flatten_params("", section["ros__parameters"] or {}, out)
        return out

    def do_node(self, body: LineMap, scope: Scope) -> None:
        line = body.line
        at = self.at(line)
        executable = self.text(self.required(body, "exec", "node"), scope, line)
        try:
            check_node_name(executable)
        except UnknownNodeError as exc:
            raise UnknownNodeError(f"{at}{exc}") from None
        if "name" in body:
            name = self.text(body["name"], scope, line)
        else:
            name = executable.rpartition(":")[2] if ":" in executable else executable
            name = _snake(name)
        try:
            validate_node_name(name)
        except InvalidNameError as exc:
            raise LaunchParseError(f"{at}node name: {exc}") from None
        namespace = scope.namespace
        if "namespace" in body:
            namespace = join_namespace(namespace, self.text(body["namespace"], scope, line), at)
        fqn = f"{namespace.rstrip('/')}/{name}"
        params: dict[str, Any] = {}
        if "args" in body:
            params.update(self.node_args(executable, body["args"], scope, line))
        if "params" in body:
            params.update(self.params(body["params"], scope, line, fqn))
        remaps = scope.remaps
        if "remap" in body:
            remaps = self.remaps(body["remap"], scope, line) + scope.remaps
        use_sim_time = scope.use_sim_time
        if "use_sim_time" in body:
            use_sim_time = parse_bool(
                self.text(body["use_sim_time"], scope, line), "use_sim_time", at
            )
        respawn = parse_bool(self.text(body.get("respawn", False), scope, line), "respawn", at)
        on_error = self.text(body.get("on_error", "log"), scope, line)
        if on_error not in ON_ERROR:
            msg = f"{at}on_error is {on_error!r}: expected one of {', '.join(ON_ERROR)}"
            raise LaunchParseError(msg)
        if "process" in body:
            process = self.process(body["process"], scope, line)
        else:
            own = respawn or on_error == "restart"
            process = "own" if own else (scope.process or default_process(executable))
        delay = self.number(body.get("respawn_delay", 0.0), scope, line, "respawn_delay")
        retries: int | None = None
        if body.get("respawn_max_retries") is not None:
            retries = int(
                self.number(body["respawn_max_retries"], scope, line, "respawn_max_retries")
            )
        self.nodes.append(
            NodeSpec(
                executable=executable,
                name=name,
                namespace=namespace,
                params=params,
                remaps=remaps,
                use_sim_time=use_sim_time,
                process=process,
                respawn=respawn,
                respawn_delay=delay,
                respawn_max_retries=retries,
                required=parse_bool(
                    self.text(body.get("required", False), scope, line), "required", at
                ),
                on_error=on_error,
                source=f"{self.source}:{line}",
            )
        )

    def node_args(
        self, executable: str, value: Any, scope: Scope, line: int | None
    ) -> dict[str, Any]:
        translate = _ARG_TRANSLATORS.get(executable)
        if translate is None:
            msg = (
                f"{self.at(line)}node {executable!r} takes no 'args' (only "
                f"{', '.join(_ARG_TRANSLATORS)} does): give 'params' instead"
            )
            raise LaunchParseError(msg)
        words = value if isinstance(value, list) else self.text(value, scope, line).split()
        words = [self.text(w, scope, line) for w in words]
        try:
            return translate(words)
        except (StaticTransformError, MappingError) as exc:
            raise LaunchParseError(f"{self.at(line)}{exc}") from None

    def number(self, value: Any, scope: Scope, line: int | None, what: str) -> float:
        text = self.text(value, scope, line)
        try:
            return float(text)
        except ValueError:
            msg = f"{self.at(line)}{what} is {text!r}: expected a number"
            raise LaunchParseError(msg) from None


def _snake(name: str) -> str:
    out: list[str] = []
    for i, char in enumerate(name):
        if char.isupper() and i > 0 and (name[i - 1].islower() or name[i - 1].isdigit()):
            out.append("_")
        out.append(char.lower())
    text = "".join(out)
    return text.removesuffix("_node") or text


def load_yaml_launch(
    path: str | os.PathLike[str],
    args: Mapping[str, str],
    scope: Scope,
    *,
    chain: tuple[str, ...],
    include: IncludeLoader,
    description: LaunchDescription | None = None,
) -> list[NodeSpec]:
    """Evaluate one YAML launch file; return its nodes (includes loaded through ``include``).

    Args:
        path: the launch file.
        args: the arguments given to it (``name:=value`` or an include's ``args``).
        scope: the namespace, remaps and defaults it inherits (its ``ctx.file`` is replaced).
        chain: the include chain so far (``file:line`` of each include), for messages.
        include: loads an included file (any format).
        description: the top-level description, whose ``args`` this file fills (None for
            included files).

    Raises:
        LaunchError: the file does not parse, or an entry is wrong (file and line given).
    """
    file = Path(path)
    try:
        text = read_text(file, what="the launch file")
    except TextFileError as exc:
        via = f" (included from {chain[-1]})" if chain else ""
        raise LaunchParseError(f"{exc}{via}") from None
    data = parse_yaml_text(text, str(file))
    if not isinstance(data, LineMap) or "launch" not in data:
        msg = (
            f"{file}:1: a visnav launch file is a mapping with a 'launch:' list of entries "
            "(see docs/launch.md)"
        )
        raise LaunchParseError(msg)
    extra = [k for k in data if k != "launch"]
    if extra:
        msg = f"{file}:{data.line}: unknown top-level key {extra[0]!r}: only 'launch:' is allowed"
        raise LaunchParseError(msg)
    ctx = replace(scope.ctx, args={}, file=str(file), line=None)
    interp = _YamlInterpreter(
        file,
        args,
        replace(scope, ctx=ctx),
        chain=chain,
        include=include,
        description=description,
    )
    return interp.run(data["launch"], data.line)
