"""``visnav action``: list, info, send_goal (the shape of ``ros2 action``)."""

from __future__ import annotations

import argparse
import difflib
import time
from typing import Any

from visnav.cli._common import cli_node
from visnav.errors import VisnavError
from visnav.graph.action_client import ActionClient
from visnav.graph.action_types import ACTION_INFIX, ActionError, GoalStatus
from visnav.graph.introspect import UnknownTopicError
from visnav.msgs.action import get_action_type
from visnav.msgs.construct import message_from_dict, message_to_yaml
from visnav.msgs.errors import MessageError
from visnav.safe_yaml import load_yaml

__all__ = ["ActionGoalArgumentError", "action_endpoints", "add_arguments"]

_SEND_GOAL = f"{ACTION_INFIX}send_goal"


class ActionGoalArgumentError(VisnavError, ValueError):
    """``action send_goal`` got a goal or option it cannot use."""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``action`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True
    p = sub.add_parser("list", help="list actions")
    p.add_argument("-t", "--show-types", action="store_true", help="show action types")
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("info", help="servers and clients of an action")
    p.add_argument("action", help="e.g. /navigate_to_pose")
    p.add_argument("-t", "--show-types", action="store_true", help="show action types")
    p.set_defaults(func=cmd_info)
    p = sub.add_parser("send_goal", help="send a goal, print the result")
    p.add_argument("action", help="e.g. /navigate_to_pose")
    p.add_argument("type", help="e.g. nav2_msgs/action/NavigateToPose")
    p.add_argument("goal", nargs="?", default="{}", help="goal fields as YAML")
    p.add_argument("-f", "--feedback", action="store_true", help="print feedback")
    p.add_argument(
        "--timeout",
        type=float,
        default=10.0,
        help="seconds to wait for the server (default 10; the goal itself has no limit)",
    )
    p.set_defaults(func=cmd_send_goal)


def action_endpoints(node: Any) -> dict[str, dict[str, list[tuple[str, str]]]]:
    """``{action: {"servers"|"clients": [(node fqn, action type)]}}`` from the graph.

    An action is found by its ``<name>/_action/send_goal`` service, as ``ros2 action``
    finds it.
    """
    out: dict[str, dict[str, list[tuple[str, str]]]] = {}
    for e in node.context.graph.service_endpoints():
        if not e.topic.endswith(_SEND_GOAL) or not e.type_name.endswith("_SendGoal"):
            continue
        name = e.topic[: -len(_SEND_GOAL)] or "/"
        entry = out.setdefault(name, {"servers": [], "clients": []})
        role = "servers" if e.kind == "service_server" else "clients"
        item = (e.node_fqn, e.type_name.removesuffix("_SendGoal"))
        if item not in entry[role]:
            entry[role].append(item)
    return dict(sorted(out.items()))


def _types(entry: dict[str, list[tuple[str, str]]]) -> list[str]:
    return sorted({t for role in entry.values() for _, t in role})


def cmd_list(args: argparse.Namespace) -> int:
    """``action list``."""
    with cli_node(args) as node:
        for name, entry in action_endpoints(node).items():
            print(f"{name} [{', '.join(_types(entry))}]" if args.show_types else name)
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``action info``."""
    with cli_node(args) as node:
        actions = action_endpoints(node)
        entry = actions.get(args.action)
        if entry is None:
            close = difflib.get_close_matches(args.action, list(actions), n=3, cutoff=0.5)
            hint = f"; did you mean {', '.join(close)}?" if close else ""
            msg = (
                f"action '{args.action}' has no server or client in the graph (domain "
                f"{node.context.domain}){hint}"
            )
            raise UnknownTopicError(msg)
        print(f"Action: {args.action}")
        for role, title in (("clients", "Action clients"), ("servers", "Action servers")):
            print(f"{title}: {len(entry[role])}")
            for fqn, type_name in sorted(entry[role]):
                print(f"    {fqn} [{type_name}]" if args.show_types else f"    {fqn}")
    return 0


_PLACEHOLDER = "structure_needs_at_least_one_member: 0"


def _yaml(msg: Any) -> str:
    """``message_to_yaml``, an empty message (rosidl's placeholder field) as ``{}``."""
    lines: list[str] = []
    for line in message_to_yaml(msg).splitlines():
        if line.strip() == _PLACEHOLDER:
            if lines and lines[-1].endswith(":"):
                lines[-1] += " {}"
            continue
        lines.append(line)
    return "\n".join(lines) or "{}"


def _goal(args: argparse.Namespace) -> tuple[Any, Any]:
    atype = get_action_type(args.type)
    values = load_yaml(
        args.goal,
        source=f"goal {args.goal!r}",
        what='the goal (write e.g. "{pose: {header: {frame_id: map}}}")',
        error=MessageError,
    )
    if values is None:
        values = {}
    if not isinstance(values, dict):
        text = (
            f"goal {args.goal!r}: expected a YAML mapping of {atype.name}_Goal fields, "
            "e.g. '{field: value}'"
        )
        raise ActionGoalArgumentError(text)
    return atype, message_from_dict(f"{atype.name}_Goal", values)


def cmd_send_goal(args: argparse.Namespace) -> int:
    """``action send_goal``: exit 0 once the goal ended (any status), as ros2's does."""
    atype, goal = _goal(args)
    with cli_node(args, discover=False) as node:
        ctx = node.context
        client = ActionClient(node, atype, args.action)
        if not client.server_is_ready():
            print("Waiting for an action server to become available...", flush=True)
            if not client.wait_for_server(args.timeout):
                text = (
                    f"action '{client.action_name}' ({atype.name}) has no server after "
                    f"{args.timeout:g} s; check `visnav action list -t` (name and type)"
                )
                raise ActionError(text)
        print(f"Sending goal:\n     {_yaml(goal)}\n", flush=True)

        def on_feedback(msg: Any) -> None:
            print(f"Feedback:\n    {_yaml(msg.feedback)}\n", flush=True)

        sent = client.send_goal_async(goal, on_feedback if args.feedback else None)
        ctx.spin_until(sent.done)
        handle = sent.result()
        if handle is None or not handle.accepted:
            print("Goal was rejected.")
            return 0
        result = None
        try:
            print(f"Goal accepted with ID: {bytes(handle.goal_id.uuid).hex()}\n", flush=True)
            result = handle.get_result_async()
            while not result.done():
                ctx.spin_once(0.1)
        except KeyboardInterrupt:
            print("Canceling goal...", flush=True)
            cancel = handle.cancel_goal_async()
            if result is None:
                result = handle.get_result_async()
            deadline = time.monotonic() + 5.0
            while not (cancel.done() and result.done()) and time.monotonic() < deadline:
                ctx.spin_once(0.1)
            if not result.done():
                return 130
        ctx.spin_some()  # the last feedback before the result
        response: Any = result.result()
        print(f"Result:\n    {_yaml(response.result)}\n")
        status = GoalStatus(int(response.status)).name.removeprefix("STATUS_")
        print(f"Goal finished with status: {status}", flush=True)
    return 0
