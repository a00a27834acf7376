"""joint_state_publisher: ``sensor_msgs/JointState`` for a robot's non-fixed joints.

Without a simulator something has to publish the positions of a robot's moving joints
for robot_state_publisher to place its links (a URDF shown in RViz, ROBOTIS'
``turtlebot3_model.launch``). :class:`JointStatePublisherNode` is ``executable:
joint_state_publisher`` (and ``joint_state_publisher_gui``, which runs headless here).

Parameters, as ROS's joint_state_publisher:

* ``robot_description`` (string): the URDF XML; empty: the node waits for the latched
  ``robot_description`` topic (robot_state_publisher publishes it; ROS 2's behaviour);
* ``rate`` (Hz, 10): how often ``joint_states`` is published;
* ``source_list`` (list of topics): JointState topics whose values replace the defaults
  of the joints they name (a driver's wheels, a gripper);
* ``zeros.<joint>`` (number): that joint's initial position instead of the default;
* ``publish_default_positions`` (true), ``publish_default_velocities`` (false),
  ``publish_default_efforts`` (false): which arrays are filled for joints no source gave;
* ``use_mimic_tags`` (true): a ``<mimic>`` joint follows its master instead of being free;
* ``use_gui`` (false): ROS 1's old switch for the slider window; visnav has no window,
  so it (and ``joint_state_publisher_gui``) logs one line and publishes the defaults.

A joint's default position is 0, or the middle of its limits when they do not contain 0,
as joint_state_publisher computes it. Fixed, floating and planar joints are not published.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from visnav.description.urdf import parse_urdf
from visnav.description.urdf_model import Joint, Urdf
from visnav.graph.node import Node, NodeOptions
from visnav.graph.param_dataclass import declare_params, param
from visnav.graph.qos import QoSProfile, qos_profile_latched
from visnav.msgs.time import ns_to_time
from visnav.msgs.types import Header, JointState, String
from visnav.tf.errors import TransformException
from visnav.tf.robot_state_node import kinematics_only

if TYPE_CHECKING:
    from typing_extensions import Unpack

__all__ = [
    "JointDefaults",
    "JointStatePublisherError",
    "JointStatePublisherGuiNode",
    "JointStatePublisherNode",
    "JointStatePublisherParams",
    "joint_defaults",
]

_QOS = QoSProfile(depth=10)
_FREE_TYPES = ("revolute", "continuous", "prismatic")


class JointStatePublisherError(TransformException, ValueError):
    """A bad parameter of joint_state_publisher (a ``zeros`` entry of no joint, a bad rate)."""


@dataclass(frozen=True)
class JointDefaults:
    """The joints joint_state_publisher publishes and their default positions.

    Attributes:
        names: every published joint, in URDF order (free and mimic joints).
        positions: joint -> default position of the free joints.
        mimics: mimic joint -> ``(master, multiplier, offset)`` (with ``use_mimic_tags``).
    """

    names: tuple[str, ...]
    positions: Mapping[str, float]
    mimics: Mapping[str, tuple[str, float, float]]

    def resolve(self, values: Mapping[str, float]) -> dict[str, float]:
        """Positions of every joint: ``values`` over the defaults, mimic joints computed."""
        out = {name: float(values.get(name, self.positions.get(name, 0.0))) for name in self.names}
        for name, (master, multiplier, offset) in self.mimics.items():
            if name not in values and master in out:
                out[name] = multiplier * out[master] + offset
        return out


def _default_position(joint: Joint) -> float:
    if joint.type == "continuous" or joint.limit is None:
        return 0.0
    low, high = joint.limit.lower, joint.limit.upper
    if low > 0 or high < 0:
        return (low + high) / 2.0
    return 0.0


def joint_defaults(
    urdf: Urdf, *, zeros: Mapping[str, float] | None = None, use_mimic_tags: bool = True
) -> JointDefaults:
    """The joints joint_state_publisher publishes for ``urdf`` and their start positions.

    Args:
        urdf: the robot.
        zeros: joint -> initial position (the ``zeros`` parameter).
        use_mimic_tags: mimic joints follow their master (else they are free joints).

    Raises:
        JointStatePublisherError: a ``zeros`` entry names no free joint of the robot.
    """
    zeros = dict(zeros or {})
    names: list[str] = []
    positions: dict[str, float] = {}
    mimics: dict[str, tuple[str, float, float]] = {}
    for name, joint in urdf.joints.items():
        if joint.type not in _FREE_TYPES:
            continue
        names.append(name)
        if use_mimic_tags and joint.mimic is not None:
            mimic = joint.mimic
            mimics[name] = (mimic.joint, mimic.multiplier, mimic.offset)
            continue
        positions[name] = float(zeros.pop(name, _default_position(joint)))
    if zeros:
        name = sorted(zeros)[0]
        msg = (
            f"parameter zeros.{name}: robot {urdf.name!r} has no free joint {name!r} (free "
            f"joints: {', '.join(positions) or 'none'}). Fix: correct the joint name"
        )
        raise JointStatePublisherError(msg)
    return JointDefaults(tuple(names), positions, mimics)


@dataclass(frozen=True)
class JointStatePublisherParams:
    """joint_state_publisher's parameters (``zeros.<joint>`` are declared per joint)."""

    robot_description: str = param("", description="URDF XML; empty: the robot_description topic")
    rate: float = param(10.0, description="publishing rate (Hz)", range=(0.001, 10000.0))
    source_list: tuple[str, ...] = param(("",), description="JointState topics merged in")
    publish_default_positions: bool = param(True, description="fill position for all joints")
    publish_default_velocities: bool = param(False, description="fill velocity with zeros")
    publish_default_efforts: bool = param(False, description="fill effort with zeros")
    use_mimic_tags: bool = param(True, description="mimic joints follow their master")
    use_gui: bool = param(False, description="ROS 1's slider window: not available, headless")


class JointStatePublisherNode(Node):
    """A joint_state_publisher node (see the module docstring).

    Args:
        name: the node's name.
        gui: run as ``joint_state_publisher_gui`` (headless; one info line says so).
        **node_kwargs: :class:`~visnav.graph.Node`'s keyword parameters (context, ...).

    Raises:
        JointStatePublisherError: a ``zeros`` entry names no free joint.
        RobotDescriptionError: ``robot_description`` is not a valid URDF.
    """

    def __init__(
        self,
        name: str = "joint_state_publisher",
        *,
        gui: bool = False,
        **node_kwargs: Unpack[NodeOptions],
    ) -> None:
        super().__init__(name, **node_kwargs)
        try:
            self.params = p = declare_params(self, JointStatePublisherParams)
            if gui or p.use_gui:
                self.get_logger().info(
                    "joint_state_publisher_gui: visnav has no slider window; publishing the "
                    "default positions (set them with zeros.<joint>, or merge a source_list topic)"
                )
            self.defaults: JointDefaults | None = None
            self._values: dict[str, float] = {}
            self._velocities: dict[str, float] = {}
            self._efforts: dict[str, float] = {}
            self._publisher = self.create_publisher(JointState, "joint_states", _QOS)
            for topic in p.source_list:
                if topic:
                    self.create_subscription(JointState, topic, self._on_source, _QOS)
            if p.robot_description.strip():
                self._load(p.robot_description)
            else:
                self.create_subscription(
                    String, "robot_description", self._on_description, qos_profile_latched
                )
            self.create_timer(1.0 / p.rate, self._publish)
        except BaseException:
            self.destroy_node()
            raise

    def _load(self, description: str) -> None:
        urdf = parse_urdf(kinematics_only(description), source="robot_description")
        zeros: dict[str, float] = {}
        for joint in urdf.joints.values():
            if joint.type in _FREE_TYPES:
                zeros[joint.name] = float(
                    self.declare_parameter(f"zeros.{joint.name}", math.nan).value
                )
        given = {k: v for k, v in zeros.items() if not math.isnan(v)}
        self.defaults = joint_defaults(urdf, zeros=given, use_mimic_tags=self.params.use_mimic_tags)

    def _on_description(self, msg: String) -> None:
        if self.defaults is None:
            self._load(msg.data)

    def _on_source(self, msg: JointState) -> None:
        for i, name in enumerate(msg.name):
            if i < len(msg.position):
                self._values[name] = float(msg.position[i])
            if i < len(msg.velocity):
                self._velocities[name] = float(msg.velocity[i])
            if i < len(msg.effort):
                self._efforts[name] = float(msg.effort[i])

    def joint_state(self, stamp_ns: int) -> JointState | None:
        """The message published at ``stamp_ns`` (None before the robot is known)."""
        if self.defaults is None:
            return None
        p = self.params
        names = list(self.defaults.names)
        positions = self.defaults.resolve(self._values)

        def column(values: Mapping[str, float], *, default: bool) -> Sequence[float]:
            # joint_state_publisher fills an array for every joint once any joint has a value
            if not default and not any(n in values for n in names):
                return []
            return [float(values.get(n, 0.0)) for n in names]

        has_position = (
            p.publish_default_positions or bool(self.defaults.mimics) or bool(self._values)
        )
        return JointState(
            header=Header(stamp=ns_to_time(stamp_ns), frame_id=""),
            name=names,
            position=_array(column(positions, default=True) if has_position else []),
            velocity=_array(column(self._velocities, default=p.publish_default_velocities)),
            effort=_array(column(self._efforts, default=p.publish_default_efforts)),
        )

    def _publish(self) -> None:
        msg = self.joint_state(self.get_clock().now_ns())
        if msg is not None:
            self._publisher.publish(msg)


def _array(values: Sequence[float]) -> Any:
    import numpy as np  # noqa: PLC0415 - the message arrays are numpy (rosbags)

    return np.asarray(values, dtype=np.float64)


class JointStatePublisherGuiNode(JointStatePublisherNode):
    """``joint_state_publisher_gui``: the same node, headless (one info line says so)."""

    def __init__(
        self, name: str = "joint_state_publisher_gui", **node_kwargs: Unpack[NodeOptions]
    ) -> None:
        super().__init__(name, gui=True, **node_kwargs)
