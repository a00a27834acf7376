"""robot_state_publisher as a standalone node (``executable: robot_state_publisher``).

Parameters, as ROS 2's robot_state_publisher:

* ``robot_description`` (string, required): the URDF XML (Xacro already expanded);
  republished latched on ``robot_description``;
* ``frame_prefix`` (string): prepended to every frame id.

It publishes ``/tf_static`` for the fixed joints once and ``/tf`` for the moving
joints on every ``joint_states`` message, stamped as the message (see
:mod:`visnav.sim.robot_state` for the differences from ROS). Meshes are not
needed: only links and joints are read.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Any

from visnav.errors import VisnavError
from visnav.graph.context import Context
from visnav.graph.node import Node
from visnav.sim.plugins import RobotStatePublisher
from visnav.sim.robot_state import RobotStateModel
from visnav.sim.urdf import parse_urdf

__all__ = ["RobotStatePublisherNode", "RobotStatePublisherNodeError", "kinematics_only"]


class RobotStatePublisherNodeError(VisnavError, ValueError):
    """The ``robot_description`` parameter is missing."""


def kinematics_only(urdf_xml: str) -> str:
    """The URDF without ``<visual>`` and ``<collision>`` elements (no meshes to resolve).

    Malformed XML is returned unchanged, for :func:`~visnav.sim.urdf.parse_urdf` to
    report with its line.
    """
    try:
        root = ET.fromstring(urdf_xml)  # noqa: S314 - the robot description, not network input
    except ET.ParseError:
        return urdf_xml
    for link in root.iter("link"):
        for child in list(link):
            if child.tag in ("visual", "collision"):
                link.remove(child)
    return ET.tostring(root, encoding="unicode")


class RobotStatePublisherNode(Node):
    """A robot_state_publisher node (see the module docstring).

    Args:
        node_name: the node's name.
        context: the graph context.
        **node_kwargs: passed to :class:`~visnav.graph.Node`.

    Raises:
        RobotStatePublisherNodeError: no ``robot_description`` parameter.
        RobotDescriptionError: the description is not a valid URDF.
    """

    def __init__(
        self,
        node_name: str = "robot_state_publisher",
        *,
        context: Context | None = None,
        **node_kwargs: Any,
    ) -> None:
        super().__init__(node_name, context=context, **node_kwargs)
        try:
            description = str(self.declare_parameter("robot_description", "").value)
            prefix = str(self.declare_parameter("frame_prefix", "").value)
            if not description.strip():
                msg = (
                    f"{self.get_fully_qualified_name()}: parameter robot_description is empty. "
                    "Fix: pass the URDF XML (e.g. the output of xacro) as robot_description"
                )
                raise RobotStatePublisherNodeError(msg)
            urdf = parse_urdf(kinematics_only(description), source="robot_description")
            self.publisher = RobotStatePublisher(
                self,
                RobotStateModel(urdf, frame_prefix=prefix),
                description,
                stamp_ns=self.get_clock().now_ns(),
            )
        except BaseException:
            self.destroy_node()
            raise
