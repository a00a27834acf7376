"""``visnav param``: list, get, set, describe, dump, load (the shape of ``ros2 param``)."""

from __future__ import annotations

import argparse
from typing import Any

import yaml

from visnav.cli._common import cli_node
from visnav.errors import VisnavError
from visnav.graph.errors import ParameterError
from visnav.graph.introspect import UnknownTopicError
from visnav.graph.param_client import ParameterClient
from visnav.graph.parameters import Parameter, ParameterType
from visnav.safe_yaml import load_yaml, load_yaml_file

__all__ = ["ParamFileError", "add_arguments", "flatten_parameter_file"]

_PARAM_SERVICE = "/get_parameters"
_TYPE_WORDS = {
    ParameterType.BOOL: ("Boolean value is", "boolean"),
    ParameterType.INTEGER: ("Integer value is", "integer"),
    ParameterType.DOUBLE: ("Double value is", "double"),
    ParameterType.STRING: ("String value is", "string"),
    ParameterType.BYTE_ARRAY: ("Byte values are", "byte array"),
    ParameterType.BOOL_ARRAY: ("Boolean values are", "boolean array"),
    ParameterType.INTEGER_ARRAY: ("Integer values are", "integer array"),
    ParameterType.DOUBLE_ARRAY: ("Double values are", "double array"),
    ParameterType.STRING_ARRAY: ("String values are", "string array"),
}


class ParamFileError(VisnavError, ValueError):
    """A parameter file for ``param load`` does not have the ROS 2 layout."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``param`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True
    p = sub.add_parser("list", help="parameter names of one node or of every node")
    p.add_argument("node", nargs="?", default=None)
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("get", help="a parameter's value")
    p.add_argument("node")
    p.add_argument("name")
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(func=cmd_get)
    p = sub.add_parser("set", help="set a parameter (VALUE is YAML: 5, 1.5, true, text, [1, 2])")
    p.add_argument("node")
    p.add_argument("name")
    p.add_argument("value")
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(func=cmd_set)
    p = sub.add_parser("describe", help="a parameter's type, description and constraints")
    p.add_argument("node")
    p.add_argument("names", nargs="+")
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(func=cmd_describe)
    p = sub.add_parser("dump", help="a node's parameters as a ROS 2 parameter file")
    p.add_argument("node")
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(func=cmd_dump)
    p = sub.add_parser("load", help="set a node's parameters from a ROS 2 parameter file")
    p.add_argument("node")
    p.add_argument("file")
    p.add_argument("--timeout", type=float, default=5.0)
    p.set_defaults(func=cmd_load)


def _fqn(name: str) -> str:
    return name if name.startswith("/") else "/" + name


def _client(node: Any, target: str, timeout: float) -> ParameterClient:
    fqn = _fqn(target)
    nodes = sorted({n.fully_qualified_name for n in node.context.graph.nodes()})
    if fqn not in nodes:
        import difflib

        close = difflib.get_close_matches(fqn, nodes, n=3, cutoff=0.5)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = f"node '{fqn}' is not in the graph (domain {node.context.domain}){hint}"
        raise UnknownTopicError(msg)
    return ParameterClient(node, fqn, timeout_sec=timeout)


def cmd_list(args: argparse.Namespace) -> int:
    """``param list``."""
    with cli_node(args) as node:
        if args.node is not None:
            for name in _client(node, args.node, args.timeout).list_parameters():
                print(f"  {name}")
            return 0
        servers = sorted(
            {
                name[: -len(_PARAM_SERVICE)]
                for name, _types in node.context.graph.service_names_and_types()
                if name.endswith(_PARAM_SERVICE)
            }
        )
        for fqn in servers:
            if fqn.rsplit("/", 1)[-1].startswith("_"):
                continue
            print(f"{fqn}:")
            for name in ParameterClient(node, fqn, timeout_sec=args.timeout).list_parameters():
                print(f"  {name}")
    return 0


def _show(value: Any) -> str:
    if isinstance(value, bytes):
        return str(list(value))
    return str(value)


def cmd_get(args: argparse.Namespace) -> int:
    """``param get``."""
    with cli_node(args) as node:
        (value,) = _client(node, args.node, args.timeout).get_parameters([args.name])
    if value is None:
        print("Parameter not set.")
        return 1
    words = _TYPE_WORDS[
        ParameterType.from_value(value) if value != [] else ParameterType.STRING_ARRAY
    ]
    print(f"{words[0]}: {_show(value)}")
    return 0


def _parse_value(text: str) -> Any:
    value = load_yaml(
        text,
        source=f"value {text!r}",
        what="the parameter value (e.g. 5, 1.5, true, text or [1, 2])",
        error=ParameterError,
    )
    try:
        ParameterType.from_value(value)
    except ParameterError as exc:
        msg = f"value {text!r}: {exc}"
        raise ParameterError(msg) from None
    return "" if value is None else value


def cmd_set(args: argparse.Namespace) -> int:
    """``param set``."""
    value = _parse_value(args.value)
    with cli_node(args) as node:
        (result,) = _client(node, args.node, args.timeout).set_parameters(
            [Parameter(args.name, value)]
        )
    if result.successful:
        print("Set parameter successful")
        return 0
    print(f"Set parameter failed: {result.reason}")
    return 1


def cmd_describe(args: argparse.Namespace) -> int:
    """``param describe``."""
    with cli_node(args) as node:
        descriptors = _client(node, args.node, args.timeout).describe_parameters(args.names)
    known = {d.name: d for d in descriptors}
    code = 0
    for name in args.names:
        d = known.get(name)
        if d is None:
            print(f"Parameter name: {name}\n  Type: not set")
            code = 1
            continue
        kind = ParameterType(int(d.type))
        print(f"Parameter name: {d.name}")
        print(f"  Type: {_TYPE_WORDS[kind][1] if kind in _TYPE_WORDS else 'not set'}")
        if d.description:
            print(f"  Description: {d.description}")
        lines = []
        if d.read_only:
            lines.append("    Read only: true")
        for rng in [*d.integer_range, *d.floating_point_range]:
            lines += [f"    Min value: {rng.from_value}", f"    Max value: {rng.to_value}"]
            if rng.step:
                lines.append(f"    Step: {rng.step}")
        if lines:
            print("  Constraints:")
            print("\n".join(lines))
    return code


def _nest(flat: dict[str, Any]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for name, value in sorted(flat.items()):
        *parents, leaf = name.split(".")
        where = out
        for p in parents:
            nxt = where.setdefault(p, {})
            if not isinstance(nxt, dict):  # 'a' and 'a.b' both declared: keep the flat name
                where = out
                leaf = name
                break
            where = nxt
        where[leaf] = list(value) if isinstance(value, bytes) else value
    return out


def cmd_dump(args: argparse.Namespace) -> int:
    """``param dump``."""
    with cli_node(args) as node:
        client = _client(node, args.node, args.timeout)
        names = client.list_parameters()
        values = client.get_parameters(names)
    doc = {_fqn(args.node): {"ros__parameters": _nest(dict(zip(names, values, strict=True)))}}
    print(yaml.safe_dump(doc, sort_keys=False, default_flow_style=False), end="")
    return 0


def _flatten(prefix: str, value: Any, out: dict[str, Any]) -> None:
    if isinstance(value, dict):
        for k, v in value.items():
            _flatten(f"{prefix}.{k}" if prefix else str(k), v, out)
    else:
        out[prefix] = value


def flatten_parameter_file(data: Any, node: str, *, source: str) -> dict[str, Any]:
    """``{name: value}`` for ``node`` from a ROS 2 parameter file's data.

    Sections ``/**`` (every node) and the node's own name (with or without the leading
    ``/``) apply, in that order; each holds ``ros__parameters``.

    Raises:
        ParamFileError: the data does not have that layout.
    """
    fqn = _fqn(node)
    if not isinstance(data, dict):
        msg = f"{source}: expected a mapping '{fqn}: {{ros__parameters: {{...}}}}'"
        raise ParamFileError(msg)
    out: dict[str, Any] = {}
    matched = False
    for key in ("/**", fqn.lstrip("/"), fqn):
        section = data.get(key)
        if section is None:
            continue
        matched = True
        if not isinstance(section, dict) or not isinstance(section.get("ros__parameters"), dict):
            msg = f"{source}: section '{key}' has no 'ros__parameters' mapping"
            raise ParamFileError(msg)
        _flatten("", section["ros__parameters"], out)
    if not matched:
        names = ", ".join(map(str, data)) or "none"
        msg = f"{source}: no section for node '{fqn}' or '/**' (sections: {names})"
        raise ParamFileError(msg)
    return out


def cmd_load(args: argparse.Namespace) -> int:
    """``param load``."""
    data = load_yaml_file(args.file, what="the parameter file", error=ParamFileError)
    values = flatten_parameter_file(data, args.node, source=args.file)
    code = 0
    with cli_node(args) as node:
        results = _client(node, args.node, args.timeout).set_parameters(
            [Parameter(k, v) for k, v in values.items()]
        )
    for name, result in zip(values, results, strict=True):
        if result.successful:
            print(f"Set parameter {name} successful")
        else:
            print(f"Set parameter {name} failed: {result.reason}")
            code = 1
    return code
