"""``map_server``: publish a saved map file on ``map`` (latched) and ``map_metadata``.

Like ROS's map_server (nav2's ``yaml_filename`` parameter; ROS 1 takes the file as its
argument), the node loads a map_server YAML and its image with
:func:`visnav.mapping.map_io.load_map` and publishes, once and latched (reliable,
transient local, depth 1), ``map`` (``nav_msgs/OccupancyGrid``) and ``map_metadata``
(``nav_msgs/MapMetaData``), stamped with the clock at load time, in ``frame_id``.

Parameters: ``yaml_filename`` (required), ``frame_id`` ("map"), ``topic_name`` ("map").
ROS 1's command line ``map_server MAP.yaml [map:=TOPIC ...]`` (a roslaunch ``args=``)
becomes these with :func:`map_server_args`: the YAML is ``yaml_filename``, ``from:=to``
items are remappings; the deprecated ``map_server IMAGE RESOLUTION`` form is refused
(write a map YAML beside the image).

Services (``nav_msgs/srv/GetMap``, the loaded map): ``static_map`` (ROS 1 map_server's
name, relative: ``/static_map`` in the root namespace) and ``~/map`` (nav2's:
``/map_server/map``).

Where visnav differs: there is no ``map_server/load_map`` service; a launch file restarts
the node with another ``yaml_filename`` instead. A missing or invalid file is an error at
start, naming the file and field.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.mapping.costmap_ros import MAP_QOS
from visnav.mapping.map_io import MapFileError, OccupancyMap, load_map
from visnav.msgs.srv import get_service_type
from visnav.msgs.types import MapMetaData, OccupancyGrid

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["MapServerNode", "MapServerParams", "map_server_args", "map_server_params_from_args"]

_USAGE = "map_server MAP.yaml [map:=TOPIC]"


def map_server_args(args: Sequence[str]) -> tuple[dict[str, Any], tuple[tuple[str, str], ...]]:
    """ROS 1 map_server's command line as this node's parameters and remappings.

    Args:
        args: The arguments after the executable (a roslaunch ``args=`` split on
            whitespace): the map YAML, and ``from:=to`` remappings anywhere.

    Returns:
        ``({"yaml_filename": path}, ((from, to), ...))``.

    Raises:
        MapFileError: no YAML, more than one positional argument (the deprecated
            ``IMAGE RESOLUTION`` form is named), a private ``_param:=`` or special
            ``__name:=`` argument, or a remapping without a target.
    """
    positional: list[str] = []
    remaps: list[tuple[str, str]] = []
    for raw in args:
        item = str(raw)
        name, sep, target = item.partition(":=")
        if not sep:
            positional.append(item)
            continue
        if not name or name.startswith("_") or not target.strip():
            msg = (
                f"map_server: argument {item!r}: expected a remapping FROM:=TO (map:=/my_map); "
                "map_server's parameters (frame_id) and the node name go in the launch file. "
                f"Usage: {_USAGE}"
            )
            raise MapFileError(msg)
        remaps.append((name, target))
    if len(positional) == 2:
        msg = (
            f"map_server {' '.join(positional)}: the deprecated IMAGE RESOLUTION form is not "
            "taken. Fix: write a map YAML (image, resolution, origin, negate, "
            "occupied_thresh, free_thresh) beside the image and pass it"
        )
        raise MapFileError(msg)
    if len(positional) != 1 or not positional[0].strip():
        msg = f"map_server: arguments {list(args)!r}: expected one map YAML. Usage: {_USAGE}"
        raise MapFileError(msg)
    return {"yaml_filename": positional[0]}, tuple(remaps)


def map_server_params_from_args(args: Sequence[str]) -> dict[str, Any]:
    """``map_server MAP.yaml`` as this node's parameters (a YAML launch ``args:``).

    Raises:
        MapFileError: as :func:`map_server_args`, and for a remapping (a YAML launch file
            gives it as ``remap: {map: TOPIC}``).
    """
    params, remaps = map_server_args(args)
    if remaps:
        (name, target), *_ = remaps
        msg = (
            f"map_server args: {name}:={target} is a remapping; in a YAML launch file write "
            f"remap: {{{name}: {target}}} beside args"
        )
        raise MapFileError(msg)
    return params


@dataclass(frozen=True)
class MapServerParams:
    """map_server's parameters (read once at start)."""

    yaml_filename: str = param("", description="the map YAML to publish (required)")
    frame_id: str = param("map", description="frame of the published map")
    topic_name: str = param("map", description="topic of the map (map_metadata is fixed)")


class MapServerNode(Node):
    """Publishes a saved map (module docstring).

    Args:
        name: node name (default ``map_server``).
        **node_kwargs: passed to :class:`~visnav.graph.Node` (context, parameter_overrides).

    Raises:
        MapFileError: ``yaml_filename`` is empty, or the map files are invalid.
    """

    def __init__(self, name: str = "map_server", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        params = declare_params(self, MapServerParams)
        path, frame_id, topic = params.yaml_filename, params.frame_id, params.topic_name
        if not path:
            msg = (
                f"node {self.get_name()!r}: parameter yaml_filename is empty; expected the "
                "path of a map YAML. Fix: set yaml_filename:=PATH/map.yaml (written by "
                "`visnav map save` or a car run)"
            )
            raise MapFileError(msg)
        self.map: OccupancyMap = load_map(path)
        self.grid: OccupancyGrid = self.map.to_msg(
            frame_id=frame_id, stamp_ns=self.get_clock().now_ns()
        )
        self._map_pub = self.create_publisher(OccupancyGrid, topic, MAP_QOS)
        self._meta_pub = self.create_publisher(MapMetaData, "map_metadata", MAP_QOS)
        self._map_pub.publish(self.grid)
        self._meta_pub.publish(self.grid.info)
        get_map = get_service_type("nav_msgs/srv/GetMap")
        self.create_service(get_map, "static_map", self._on_get_map)  # ROS 1's name
        self.create_service(get_map, "~/map", self._on_get_map)  # nav2's
        info = self.grid.info
        self.get_logger().info(
            f"loaded {path}: {info.width} x {info.height} cells at {info.resolution:g} m/cell"
        )

    def _on_get_map(self, request: object, response: Any) -> Any:
        """``nav_msgs/GetMap``: the loaded map, as published on ``map``."""
        del request
        response.map = self.grid
        return response
