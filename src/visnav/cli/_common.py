"""Shared plumbing of the CLI verbs: the hidden CLI node and discovery."""

from __future__ import annotations

import argparse
import os
from collections.abc import Iterator
from contextlib import contextmanager

from visnav.graph.context import Context
from visnav.graph.introspect import wait_for_discovery
from visnav.graph.node import Node

__all__ = ["cli_node"]


@contextmanager
def cli_node(args: argparse.Namespace, *, discover: bool = True) -> Iterator[Node]:
    """Yield a hidden node (name starts with ``_``) in the chosen domain, after discovery."""
    with Context(getattr(args, "domain", None)) as ctx:
        node = Node(f"_visnav_cli_{os.getpid()}", context=ctx, start_parameter_services=False)
        if discover:
            wait_for_discovery(ctx)
        yield node
