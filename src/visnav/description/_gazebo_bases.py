"""Model-level gazebo_ros plugins: the ROS 1 IMU, skid steer and planar move (internal).

Names, defaults and semantics are those of ``gazebo_ros_pkgs`` (noetic-devel for the ROS 1
plugins; ``ros2`` for the ROS 2 planar move):

* ``libgazebo_ros_imu.so`` (ROS 1 only): ``<bodyName>`` (required), ``<topicName>`` and
  ``<serviceName>`` (both default ``/default_imu``; an empty topic publishes nothing),
  ``<frameName>`` (default the body, not prefixed), ``<gaussianNoise>``, ``<updateRate>``
  (0 = every world update), ``<xyzOffset>``/``<rpyOffset>``; relative names are in
  ``<robotNamespace>``. The plugin reads nothing else: an ``<imu><noise>`` block in it (the
  TurtleBot3 descriptions carry one) is ignored, with a warning.
* ``libgazebo_ros_skid_steer_drive.so`` (ROS 1 only): four joints (``leftFrontJoint`` ..
  ``rightRearJoint``, defaults ``left_front_joint`` ..), ``wheelSeparation`` 0.4,
  ``wheelDiameter`` 0.15, ``torque`` 5, ``commandTopic`` / ``odometryTopic`` /
  ``odometryFrame`` / ``robotBaseFrame``, ``broadcastTF`` (default false), ``updateRate``
  100, ``covariance_x`` / ``covariance_y`` / ``covariance_yaw`` (1e-4, 1e-4, 1e-2).
* ``libgazebo_ros_planar_move.so``: ROS 1 ``commandTopic``, ``odometryTopic``,
  ``odometryFrame``, ``robotBaseFrame``, ``odometryRate`` (20), ``cmdTimeout`` (-1 = none;
  the velocity is set every world update, the odometry TF always broadcast);
  ``publishOdometryTf`` (not read by noetic's plugin) turns the TF off. ROS 2
  ``update_rate`` (20), ``publish_rate`` (20), ``publish_odom``, ``publish_odom_tf`` (true),
  ``odometry_frame``, ``robot_base_frame``, ``covariance_x|y|yaw``; topics ``cmd_vel`` and
  ``odom`` in the plugin's ``<ros>`` namespace.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

from visnav.description._sdf_reader import SdfReader, has_any, plugin_node
from visnav.description.gazebo_specs import (
    ImuModelSpec,
    PlanarMoveSpec,
    SkidSteerSpec,
    ros1_join,
    tf_resolve,
)
from visnav.description.urdf import Urdf

__all__ = ["parse_imu_model", "parse_planar_move", "parse_skid_steer"]

_IMU_KNOWN = (
    "robotNamespace", "bodyName", "frameName", "topicName", "serviceName", "gaussianNoise",
    "updateRate", "xyzOffset", "rpyOffset", "alwaysOn",
)  # fmt: skip
_SKID_KNOWN = (
    "robotNamespace", "leftFrontJoint", "rightFrontJoint", "leftRearJoint", "rightRearJoint",
    "wheelSeparation", "wheelDiameter", "torque", "commandTopic", "odometryTopic",
    "odometryFrame", "robotBaseFrame", "broadcastTF", "updateRate", "covariance_x",
    "covariance_y", "covariance_yaw", "alwaysOn",
)  # fmt: skip
_PLANAR_ROS1 = (
    "robotNamespace", "commandTopic", "odometryTopic", "odometryFrame", "robotBaseFrame",
    "odometryRate", "cmdTimeout", "publishOdometryTf", "alwaysOn",
)  # fmt: skip
_PLANAR_ROS2 = (
    "ros", "update_rate", "publish_rate", "publish_odom", "publish_odom_tf", "odometry_frame",
    "robot_base_frame", "covariance_x", "covariance_y", "covariance_yaw",
)  # fmt: skip


def _ros1_topic(ns: str, name: str) -> str:
    """``name`` resolved in a ``NodeHandle(ns)`` (absolute names stay absolute)."""
    return ros1_join(name) if name.startswith("/") else ros1_join(ns, name)


def _link(reader: SdfReader, plugin: ET.Element, urdf: Urdf, tag: str, owner: str) -> str:
    name = reader.text(plugin, tag)
    if not name:
        raise reader.error(
            plugin,
            f"{owner}missing <{tag}> (the plugin cannot start without it)",
            f"add <{tag}>{urdf.root}</{tag}> naming a link",
        )
    if name not in urdf.links:
        found = plugin.find(tag)
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}<{tag}> {name!r} is not a link",
            f"use one of: {', '.join(urdf.links)}",
        )
    return name


def parse_imu_model(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> ImuModelSpec:
    """``libgazebo_ros_imu.so``: the ROS 1 model plugin (not the ``<sensor>`` plugin)."""
    name = plugin.get("name") or "imu"
    owner = f"plugin {name!r} (libgazebo_ros_imu.so): "
    if plugin.find("ros") is not None:
        reader.warn(
            plugin,
            f"{owner}is a ROS 1 plugin and reads no <ros> block; in ROS 2 use "
            '<sensor type="imu"> with libgazebo_ros_imu_sensor.so',
        )
    body = _link(reader, plugin, urdf, "bodyName", owner)
    ns = reader.text(plugin, "robotNamespace") or ""
    topic_name = reader.text(plugin, "topicName")
    topic_name = "/default_imu" if topic_name is None else topic_name
    service_name = reader.text(plugin, "serviceName")
    service_name = "/default_imu" if service_name is None else service_name
    xyz = reader.vector(plugin, "xyzOffset", (0.0, 0.0, 0.0), owner=owner)
    rpy = reader.vector(plugin, "rpyOffset", (0.0, 0.0, 0.0), owner=owner)
    imu = plugin.find("imu")
    if imu is not None:
        reader.warn(
            imu,
            f"{owner}gazebo_ros_imu reads no <imu> block (its noise is <gaussianNoise> "
            "alone, the same on every axis); like Gazebo the block is ignored. For per-axis "
            'noise and biases use <sensor type="imu"> with libgazebo_ros_imu_sensor.so',
        )
    reader.unknown(plugin, (*_IMU_KNOWN, "imu", "ros"), owner=owner, what="the IMU plugin")
    return ImuModelSpec(
        plugin_name=name,
        body_name=body,
        frame_id=reader.text(plugin, "frameName") or body,
        topic=_ros1_topic(ns, topic_name) if topic_name else None,
        service=_ros1_topic(ns, service_name) if topic_name and service_name else None,
        update_rate=reader.number(plugin, "updateRate", 0.0, owner=owner, minimum=0.0),
        gaussian_noise=reader.number(plugin, "gaussianNoise", 0.0, owner=owner, minimum=0.0),
        xyz_offset=(xyz[0], xyz[1], xyz[2]),
        rpy_offset=(rpy[0], rpy[1], rpy[2]),
    )


def _wheel(
    reader: SdfReader, plugin: ET.Element, urdf: Urdf, tag: str, default: str, owner: str
) -> str:
    joint = reader.text(plugin, tag) or default
    if joint not in urdf.joints:
        found = plugin.find(tag)
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}<{tag}> {joint!r} is not a joint"
            + ("" if found is not None else " (the default of a missing element)"),
            f"use one of: {', '.join(urdf.joints) or 'no joints defined'}",
        )
    if not urdf.joints[joint].moves:
        found = plugin.find(tag)
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}wheel joint {joint!r} is fixed",
            "make the wheel joint continuous",
        )
    return joint


def parse_skid_steer(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> SkidSteerSpec:
    """``libgazebo_ros_skid_steer_drive.so`` (ROS 1)."""
    name = plugin.get("name") or "skid_steer_drive"
    owner = f"plugin {name!r} (libgazebo_ros_skid_steer_drive.so): "
    ns = reader.text(plugin, "robotNamespace") or ""
    if plugin.find("ros") is not None:
        reader.warn(
            plugin,
            f"{owner}is a ROS 1 plugin and reads no <ros> block; in ROS 2 use "
            "libgazebo_ros_diff_drive.so with <num_wheel_pairs>2</num_wheel_pairs>",
        )
    reader.unknown(plugin, (*_SKID_KNOWN, "ros"), owner=owner, what="the skid steer plugin")

    def number(tag: str, default: float, *, strict: bool = False) -> float:
        return reader.number(plugin, tag, default, owner=owner, minimum=0.0, strict=strict)

    return SkidSteerSpec(
        plugin_name=name,
        left_front_joint=_wheel(reader, plugin, urdf, "leftFrontJoint", "left_front_joint", owner),
        right_front_joint=_wheel(
            reader, plugin, urdf, "rightFrontJoint", "right_front_joint", owner
        ),
        left_rear_joint=_wheel(reader, plugin, urdf, "leftRearJoint", "left_rear_joint", owner),
        right_rear_joint=_wheel(reader, plugin, urdf, "rightRearJoint", "right_rear_joint", owner),
        wheel_separation=number("wheelSeparation", 0.4, strict=True),
        wheel_diameter=number("wheelDiameter", 0.15, strict=True),
        torque=number("torque", 5.0, strict=True),
        command_topic=_ros1_topic(ns, reader.text(plugin, "commandTopic") or "cmd_vel"),
        odometry_topic=_ros1_topic(ns, reader.text(plugin, "odometryTopic") or "odom"),
        odometry_frame=tf_resolve(ns, reader.text(plugin, "odometryFrame") or "odom"),
        robot_base_frame=tf_resolve(ns, reader.text(plugin, "robotBaseFrame") or "base_footprint"),
        broadcast_tf=reader.boolean(plugin, "broadcastTF", False, owner=owner),
        update_rate=number("updateRate", 100.0),
        covariance=(number("covariance_x", 0.0001), number("covariance_y", 0.0001),
                    number("covariance_yaw", 0.01)),
    )  # fmt: skip


def parse_planar_move(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> PlanarMoveSpec:
    """``libgazebo_ros_planar_move.so`` (ROS 1 names or ROS 2's, by the elements used)."""
    name = plugin.get("name") or "planar_move"
    owner = f"plugin {name!r} (libgazebo_ros_planar_move.so): "
    ros2 = plugin.find("ros") is not None or (
        has_any(plugin, _PLANAR_ROS2) and not has_any(plugin, _PLANAR_ROS1)
    )

    def number(tag: str, default: float) -> float:
        return reader.number(plugin, tag, default, owner=owner, minimum=0.0)

    if ros2:
        node = plugin_node(reader, plugin, owner=owner)
        reader.unknown(plugin, _PLANAR_ROS2, owner=owner, what="the planar move plugin")
        update_rate = number("update_rate", 20.0)
        publish_rate = number("publish_rate", 20.0)
        return PlanarMoveSpec(
            plugin_name=name,
            command_topic=node.resolve("cmd_vel"),
            odometry_topic=node.resolve("odom"),
            odometry_frame=reader.text(plugin, "odometry_frame") or "odom",
            robot_base_frame=reader.text(plugin, "robot_base_frame") or "base_footprint",
            update_rate=update_rate,
            # the plugin takes publish_rate's period only when update_rate > 0
            odometry_rate=publish_rate if update_rate > 0 else 0.0,
            publish_odom=reader.boolean(plugin, "publish_odom", True, owner=owner),
            publish_odom_tf=reader.boolean(plugin, "publish_odom_tf", True, owner=owner),
            covariance=(number("covariance_x", 0.00001), number("covariance_y", 0.00001),
                        number("covariance_yaw", 0.001)),
            ros_version=2,
        )  # fmt: skip
    ns = reader.text(plugin, "robotNamespace") or ""
    reader.unknown(plugin, _PLANAR_ROS1, owner=owner, what="the planar move plugin")
    rate = reader.number(plugin, "odometryRate", 20.0, owner=owner)
    timeout = reader.number(plugin, "cmdTimeout", -1.0, owner=owner)
    publish_tf = reader.boolean(plugin, "publishOdometryTf", True, owner=owner)
    tf_element = plugin.find("publishOdometryTf")
    if tf_element is not None:
        reader.warn(
            tf_element,
            f"{owner}<publishOdometryTf> is not read by gazebo_ros_planar_move (noetic), which "
            f"always broadcasts the odometry TF; visnav follows it ({publish_tf})",
        )
    return PlanarMoveSpec(
        plugin_name=name,
        command_topic=_ros1_topic(ns, reader.text(plugin, "commandTopic") or "cmd_vel"),
        odometry_topic=_ros1_topic(ns, reader.text(plugin, "odometryTopic") or "odom"),
        odometry_frame=tf_resolve(ns, reader.text(plugin, "odometryFrame") or "odom"),
        robot_base_frame=tf_resolve(ns, reader.text(plugin, "robotBaseFrame") or "base_footprint"),
        update_rate=0.0,
        # <= 0: no odometry at all (the plugin publishes only when odometryRate > 0)
        odometry_rate=max(rate, 0.0),
        publish_odom=rate > 0.0,
        publish_odom_tf=publish_tf and rate > 0.0,
        cmd_timeout=timeout,
        ros_version=1,
    )
