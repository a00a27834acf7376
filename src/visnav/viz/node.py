"""The viewer as a launchable node (what a launch file's ``rviz`` maps to).

``ViewerNode`` opens a Rerun viewer (the web viewer on 127.0.0.1 by default, since
launches often run headless; ``web: false`` spawns the native viewer) and streams every
topic of its context's graph to it, placed in ``fixed_frame`` through TF as
``visnav view`` does (a :class:`~visnav.viz.live_view.LiveView`: display rate, worker
thread, the sim's world). Parameters: ``fixed_frame`` (default: map, odom, world or the
TF root), ``web`` (true), ``port`` (9090) and ``grpc_port`` (9876), ``memory_limit``
(512MB), ``save`` (an ``.rrd`` path, default none), ``config`` (an ``.rviz`` file, as
``rviz -d``: its fixed frame, the topics of its enabled displays and their colours, see
:mod:`visnav.viz.rviz_config`), ``packages`` (``name=DIR``: the robot
model's ``package://`` meshes; the roslaunch import gives every package it knows).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

from visnav.graph.clock import Clock, ClockType
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.viz.live_view import LiveView
from visnav.viz.ports import check_ports
from visnav.viz.rviz_config import RvizConfigError, load_rviz_config
from visnav.viz.viewer import DEFAULT_GRPC_PORT, DEFAULT_MEMORY_LIMIT, DEFAULT_WEB_PORT

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = ["ViewerNode", "ViewerParams"]


@dataclass(frozen=True)
class ViewerParams:
    """The viewer node's parameters."""

    fixed_frame: str = param("", description="frame the scene is drawn in (empty: TF root)")
    web: bool = param(True, description="web viewer on 127.0.0.1 (false: native viewer)")
    port: int = param(DEFAULT_WEB_PORT, description="web viewer page port (0: a free one)")
    grpc_port: int = param(DEFAULT_GRPC_PORT, description="viewer data port (0: a free one)")
    memory_limit: str = param(DEFAULT_MEMORY_LIMIT, description="kept for late pages")
    save: str = param("", description="also write an .rrd recording here (empty: none)")
    config: str = param("", description="an .rviz file: fixed frame, displays, colours")
    packages: tuple[str, ...] = param(("",), description="name=DIR for package:// meshes")


class ViewerNode(Node):
    """Streams the graph to Rerun (see the module docstring)."""

    def __init__(self, name: str = "viewer", **node_kwargs: Unpack[NodeOptions]) -> None:
        super().__init__(name, **node_kwargs)
        p = self.params = declare_params(self, ViewerParams)
        packages = dict(
            item.split("=", 1) for item in p.packages if "=" in item and item.split("=", 1)[1]
        )
        rviz = None
        if p.config:
            try:
                rviz = load_rviz_config(p.config)
            except RvizConfigError as exc:  # RViz too starts with its defaults
                self.get_logger().warning(f"{exc}; showing every topic")
        if rviz is not None and rviz.note:
            self.get_logger().info(rviz.note)
        if p.web:  # refused naming the parameter to change (the CLI's flags elsewhere)
            check_ports(
                p.port,
                p.grpc_port,
                port_option="port",
                grpc_option="grpc_port",
                node=self.get_fully_qualified_name(),
            )
        self.view = LiveView(
            self.context,
            web=p.web,
            port=p.port,
            grpc_port=p.grpc_port,
            memory_limit=p.memory_limit,
            save=p.save or None,
            fixed_frame=p.fixed_frame or None,
            packages=packages,
            topics=rviz.topics if rviz is not None else None,
            rviz=rviz,
        )
        self.viewer = self.view.viewer
        self.feed = self.view.feed
        if self.viewer.url:
            self.get_logger().info(f"viewer: {self.viewer.url}")
        steady = Clock(ClockType.STEADY_TIME)
        self.create_timer(0.5, self._poll, clock=steady)

    def _poll(self) -> None:
        self.view.poll()

    def destroy_node(self) -> None:
        """Close the viewer, then destroy the node."""
        view = getattr(self, "view", None)
        if view is not None:
            view.close()
        super().destroy_node()
