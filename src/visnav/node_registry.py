"""visnav's built-in nodes by name, for launch files and ``visnav run``.

Names follow the ROS executables users know (``image_proc``, ``point_cloud_xyz``,
``depthimage_to_laserscan``, ...). Values are ``module:Class`` paths imported only
when a node is started, so reading the registry imports nothing heavy.
"""

from __future__ import annotations

import difflib
import importlib
from collections.abc import Mapping
from typing import Any

from visnav.errors import VisnavError

__all__ = ["BUILTIN_NODES", "UnknownNodeError", "resolve_node_class"]

BUILTIN_NODES: Mapping[str, str] = {
    "image_proc": "visnav.perception.nodes:ImageProcNode",
    "point_cloud_xyz": "visnav.perception.nodes:PointCloudXyzNode",
    "point_cloud_xyzrgb": "visnav.perception.nodes:PointCloudXyzrgbNode",
    "convert_metric": "visnav.perception.nodes:ConvertMetricNode",
    "depthimage_to_laserscan": "visnav.perception.nodes:DepthImageToLaserScanNode",
}


class UnknownNodeError(VisnavError, LookupError):
    """A node name is neither built in nor a ``module:Class`` path that imports."""


def resolve_node_class(name: str) -> type[Any]:
    """Return the node class for a built-in name or a ``module:Class`` path.

    Raises:
        UnknownNodeError: unknown name (closest built-in names suggested) or a path that
            does not import.
    """
    path = BUILTIN_NODES.get(name, name)
    if ":" not in path:
        close = difflib.get_close_matches(name, list(BUILTIN_NODES), n=3)
        hint = f"; did you mean {', '.join(close)}?" if close else ""
        msg = (
            f"unknown node {name!r}: expected a built-in node ({', '.join(sorted(BUILTIN_NODES))}) "
            f"or 'module:Class' for your own{hint}"
        )
        raise UnknownNodeError(msg)
    module_name, _, cls_name = path.partition(":")
    try:
        module = importlib.import_module(module_name)
        cls = getattr(module, cls_name)
    except (ImportError, AttributeError) as exc:
        msg = f"node {name!r}: cannot import {path!r} ({exc}); check the module and class names"
        raise UnknownNodeError(msg) from exc
    if not isinstance(cls, type):
        msg = f"node {name!r}: {path!r} is not a class"
        raise UnknownNodeError(msg)
    return cls
