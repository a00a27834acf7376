"""``visnav node``: list and info (the shape of ``ros2 node``)."""

from __future__ import annotations

import argparse

from visnav.cli._common import cli_node
from visnav.graph.introspect import node_summary

__all__ = ["add_arguments"]


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Add the ``node`` sub-commands."""
    sub = parser.add_subparsers(dest="cmd", metavar="CMD")
    sub.required = True
    p = sub.add_parser("list", help="list nodes")
    p.add_argument("-a", "--all", action="store_true", help="include hidden nodes (_name)")
    p.set_defaults(func=cmd_list)
    p = sub.add_parser("info", help="publishers and subscriptions of a node")
    p.add_argument("node", help="fully qualified node name, e.g. /camera/driver")
    p.set_defaults(func=cmd_info)


def cmd_list(args: argparse.Namespace) -> int:
    """``node list``."""
    with cli_node(args) as node:
        names = sorted({n.fully_qualified_name for n in node.context.graph.nodes()})
        for name in names:
            if args.all or not name.rsplit("/", 1)[-1].startswith("_"):
                print(name)
    return 0


def cmd_info(args: argparse.Namespace) -> int:
    """``node info``."""
    fqn = args.node if args.node.startswith("/") else "/" + args.node
    with cli_node(args) as node:
        summary = node_summary(node.context, fqn)
        print(fqn)
        sections = (
            ("Subscribers", "subscribers"),
            ("Publishers", "publishers"),
            ("Service Servers", "service_servers"),
            ("Service Clients", "service_clients"),
        )
        for title, key in sections:
            print(f"  {title}:")
            for name, type_name in sorted(summary[key]):
                if "/_action/" not in name:  # an action's parts are listed as the action
                    print(f"    {name}: {type_name}")
        for title, key in (
            ("Action Servers", "service_servers"),
            ("Action Clients", "service_clients"),
        ):
            print(f"  {title}:")
            for name, type_name in sorted(summary[key]):
                if name.endswith("/_action/send_goal") and type_name.endswith("_SendGoal"):
                    action = name.removesuffix("/_action/send_goal")
                    print(f"    {action}: {type_name.removesuffix('_SendGoal')}")
    return 0
