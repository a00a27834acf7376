"""``visnav service``: list, type, find, call (the shape of ``ros2 service``)."""

from __future__ import annotations

import argparse
import time
from typing import Any

import numpy as np

from visnav.cli._common import cli_node
from visnav.errors import VisnavError
from visnav.graph.errors import ServiceError
from visnav.graph.introspect import UnknownTopicError
from visnav.graph.names import is_hidden_name
from visnav.msgs.construct import message_from_dict
from visnav.msgs.errors import MessageError
from visnav.msgs.srv import get_service_type
from visnav.safe_yaml import load_yaml

__all__ = ["ServiceCallArgumentError", "add_arguments", "ros_repr"]


class ServiceCallArgumentError(VisnavError, ValueError):
    """``service call`` got a request or option it cannot use."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``service`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True
    p = sub.add_parser("list", help="list services")
    p.add_argument("-t", "--show-types", action="store_true", help="show service types")
    p.add_argument("-a", "--include-hidden-services", action="store_true")
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("type", help="the type of a service")
    p.add_argument("service")
    p.set_defaults(func=cmd_type)
    p = sub.add_parser("find", help="services of a type")
    p.add_argument("type", help="e.g. std_srvs/srv/Trigger")
    p.add_argument("-a", "--include-hidden-services", action="store_true")
    p.set_defaults(func=cmd_find)
    p = sub.add_parser("call", help="call a service with a YAML request")
    p.add_argument("service")
    p.add_argument("type", help="e.g. std_srvs/srv/SetBool")
    p.add_argument("values", nargs="?", default="{}", help="request fields as YAML")
    p.add_argument("-r", "--rate", type=float, default=None, help="repeat at this rate (Hz)")
    p.add_argument("--timeout", type=float, default=10.0, help="seconds to wait (default 10)")
    p.set_defaults(func=cmd_call)


def _services(node: Any, include_hidden: bool) -> list[tuple[str, list[str]]]:
    return [
        (name, types)
        for name, types in node.context.graph.service_names_and_types()
        if include_hidden or not is_hidden_name(name)
    ]


def cmd_list(args: argparse.Namespace) -> int:
    """``service list``."""
    with cli_node(args) as node:
        for name, types in _services(node, args.include_hidden_services):
            print(f"{name} [{', '.join(types)}]" if args.show_types else name)
    return 0


def cmd_type(args: argparse.Namespace) -> int:
    """``service type``."""
    with cli_node(args) as node:
        services = dict(_services(node, include_hidden=True))
        types = services.get(args.service)
        if not types:
            import difflib

            close = difflib.get_close_matches(args.service, list(services), n=3, cutoff=0.5)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            msg = (
                f"service '{args.service}' has no server in the graph (domain "
                f"{node.context.domain}){hint}"
            )
            raise UnknownTopicError(msg)
        for t in types:
            print(t)
    return 0


def cmd_find(args: argparse.Namespace) -> int:
    """``service find``."""
    wanted = get_service_type(args.type).name
    with cli_node(args) as node:
        for name, types in _services(node, args.include_hidden_services):
            if wanted in types:
                print(name)
    return 0


def ros_repr(msg: Any) -> str:
    """A message as rclpy prints it: ``std_srvs.srv.SetBool_Request(data=True)``."""
    type_name = getattr(msg, "__msgtype__", None)
    if type_name is None:
        if isinstance(msg, np.ndarray):
            return repr(msg.tolist())
        if isinstance(msg, list):
            return "[" + ", ".join(ros_repr(v) for v in msg) + "]"
        return repr(msg)
    fields = [
        f"{k}={ros_repr(getattr(msg, k))}"
        for k in msg.__dataclass_fields__
        if not k.startswith("__") and k != "structure_needs_at_least_one_member"
    ]
    return f"{type_name.replace('/', '.')}({', '.join(fields)})"


def _request(args: argparse.Namespace) -> Any:
    stype = get_service_type(args.type)
    values = load_yaml(
        args.values,
        source=f"request {args.values!r}",
        what='the request (write e.g. "{data: true}")',
        error=MessageError,
    )
    if values is None:
        values = {}
    if not isinstance(values, dict):
        text = (
            f"request {args.values!r}: expected a YAML mapping of {stype.request_type_name} "
            "fields, e.g. '{data: true}'"
        )
        raise ServiceCallArgumentError(text)
    return stype, message_from_dict(stype.request_type_name, values)


def cmd_call(args: argparse.Namespace) -> int:
    """``service call``."""
    if args.rate is not None and not args.rate > 0:
        text = f"--rate {args.rate:g}: expected a positive rate in Hz (e.g. --rate 1)"
        raise ServiceCallArgumentError(text)
    stype, request = _request(args)
    with cli_node(args, discover=False) as node:
        client = node.create_client(stype, args.service)
        if not client.service_is_ready():
            print("waiting for service to become available...", flush=True)
            if not client.wait_for_service(args.timeout):
                text = (
                    f"service '{client.srv_name}' ({stype.name}) did not appear within "
                    f"{args.timeout:g} s; check `visnav service list -t` (name and type)"
                )
                raise ServiceError(text)
        while True:
            print(f"requester: making request: {ros_repr(request)}\n", flush=True)
            response = client.call(request, timeout_sec=args.timeout)
            print("response:")
            print(ros_repr(response) + "\n", flush=True)
            if args.rate is None:
                return 0
            time.sleep(1.0 / args.rate)
