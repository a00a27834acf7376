"""Model-level gazebo_ros plugins (p3d, diff drive, joint states) and link properties (internal)."""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from typing import Literal

from visnav.description._sdf_reader import SdfReader, has_any, plugin_node
from visnav.description.errors import QuadrotorParamsError
from visnav.description.gazebo_materials import GAZEBO_COLOURS
from visnav.description.gazebo_specs import (
    DiffDriveSpec,
    JointStatePublisherSpec,
    LinkProperties,
    OdometrySpec,
    QuadrotorSpec,
    ros1_join,
    tf_resolve,
)
from visnav.description.noise_specs import WHEEL_NOISE_TAGS, WheelOdometryNoise, parse_wheel_noise
from visnav.description.urdf import Urdf
from visnav.description.vehicle_params import QuadrotorParams

__all__ = [
    "link_properties",
    "parse_diff_drive",
    "parse_joint_state_publisher",
    "parse_p3d",
    "parse_quadrotor",
]


def parse_p3d(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> OdometrySpec:
    name = plugin.get("name") or "p3d"
    owner = f"plugin {name!r} (libgazebo_ros_p3d.so): "
    ros1 = plugin.find("ros") is None and has_any(
        plugin,
        (
            "robotNamespace",
            "bodyName",
            "topicName",
            "frameName",
            "gaussianNoise",
            "updateRate",
            "xyzOffset",
            "xyzOffsets",
            "rpyOffset",
            "rpyOffsets",
        ),
    )
    body_tag = "bodyName" if ros1 else "body_name"
    body = reader.text(plugin, body_tag)
    if not body:
        raise reader.error(
            plugin,
            f"{owner}missing <{body_tag}>",
            f"add <{body_tag}>base_link</{body_tag}> naming the tracked link",
        )
    if body not in urdf.links:
        found = plugin.find(body_tag)
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}<{body_tag}> {body!r} is not a link",
            f"use one of: {', '.join(urdf.links)}",
        )
    offsets_xyz = ("xyzOffset", "xyzOffsets") if ros1 else ("xyz_offsets", "xyz_offset")
    offsets_rpy = ("rpyOffset", "rpyOffsets") if ros1 else ("rpy_offsets", "rpy_offset")
    xyz = reader.vector(plugin, offsets_xyz, (0.0, 0.0, 0.0), owner=owner)
    rpy = reader.vector(plugin, offsets_rpy, (0.0, 0.0, 0.0), owner=owner)
    if ros1:
        ns = reader.text(plugin, "robotNamespace") or ""
        topic_name = reader.text(plugin, "topicName")
        if not topic_name:
            raise reader.error(
                plugin,
                f"{owner}missing <topicName> (gazebo_ros_p3d ROS 1 requires it)",
                "add <topicName>odom</topicName>",
            )
        topic = ros1_join(topic_name) if topic_name.startswith("/") else ros1_join(ns, topic_name)
        frame = tf_resolve(ns, reader.text(plugin, "frameName") or "world")
        child = tf_resolve(ns, body)
        rate = reader.number(plugin, "updateRate", 0.0, owner=owner, minimum=0.0)
        noise = reader.number(plugin, "gaussianNoise", 0.0, owner=owner, minimum=0.0)
        known: tuple[str, ...] = (
            "robotNamespace",
            "bodyName",
            "topicName",
            "frameName",
            "updateRate",
            "gaussianNoise",
            *offsets_xyz,
            *offsets_rpy,
            "publish_tf",
            "alwaysOn",
        )
    else:
        node = plugin_node(reader, plugin, owner=owner)
        topic = node.resolve("odom")
        frame = reader.text(plugin, "frame_name") or "world"
        child = body
        rate = reader.number(plugin, "update_rate", 0.0, owner=owner, minimum=0.0)
        noise = reader.number(plugin, "gaussian_noise", 0.0, owner=owner, minimum=0.0)
        known = (
            "ros",
            "body_name",
            "frame_name",
            "update_rate",
            "gaussian_noise",
            *offsets_xyz,
            *offsets_rpy,
            "publish_tf",
        )
    if frame.lstrip("/") not in ("world", "map") and frame not in urdf.links:
        reader.warn(
            plugin,
            f"{owner}frame_name {frame!r} is not a link; like Gazebo the "
            "odometry is reported in the world frame but labelled "
            f"{frame!r}",
        )
    reader.unknown(plugin, (*known, "topic_name"), owner=owner, what="the p3d plugin")
    publish_tf = reader.boolean(plugin, "publish_tf", body == urdf.root, owner=owner)
    if publish_tf and body != urdf.root:
        reader.warn(
            plugin,
            f"{owner}publish_tf: {body!r} already has a parent in the URDF; "
            f"broadcasting {frame} -> {child} gives it a second parent on TF",
        )
    return OdometrySpec(
        plugin_name=name, body_name=body, frame_id=frame, child_frame_id=child, topic=topic,
        update_rate=rate, gaussian_noise=noise, xyz_offset=(xyz[0], xyz[1], xyz[2]),
        rpy_offset=(rpy[0], rpy[1], rpy[2]), publish_tf=publish_tf,
        ros_version=1 if ros1 else 2,
    )  # fmt: skip


_DIFF_ROS1 = (
    "robotNamespace", "commandTopic", "odometryTopic", "odometryFrame", "robotBaseFrame",
    "publishWheelTF", "publishOdomTF", "publishWheelJointState", "wheelSeparation",
    "wheelDiameter", "wheelAcceleration", "wheelTorque", "updateRate", "odometrySource",
    "leftJoint", "rightJoint", "publishTf", "rosDebugLevel", "legacyMode",
)  # fmt: skip
_DIFF_ROS2 = (
    "ros", "num_wheel_pairs", "left_joint", "right_joint", "wheel_separation", "wheel_diameter",
    "max_wheel_torque", "max_wheel_acceleration", "update_rate", "odometry_frame",
    "robot_base_frame", "odometry_source", "publish_odom", "publish_odom_tf", "publish_wheel_tf",
    "covariance_x", "covariance_y", "covariance_yaw", "command_topic", "odometry_topic",
    *WHEEL_NOISE_TAGS,
)  # fmt: skip


def _wheel_noise(
    reader: SdfReader, plugin: ET.Element, *, owner: str, encoder: bool
) -> WheelOdometryNoise:
    noise = parse_wheel_noise(reader, plugin, owner=owner)
    if noise.active and not encoder:
        reader.warn(
            plugin,
            f"{owner}wheel noise elements only act on encoder odometry and are ignored with "
            "the world (ground-truth) source; set odometry_source to encoder (ROS 2: 0)",
        )
        return WheelOdometryNoise()
    return noise


def _ros1_odometry_source(
    reader: SdfReader, plugin: ET.Element, *, owner: str
) -> Literal["world", "encoder"]:
    """ROS 1 ``<odometrySource>``: exactly ``world`` or ``encoder``; anything else is world.

    gazebo_ros_utils looks the text up in {encoder, world} (case-sensitive) and keeps the
    default (world) with a warning when it does not match, numbers included.
    """
    found = plugin.find("odometrySource")
    if found is None:
        return "world"
    text = (found.text or "").strip()
    if text in ("world", "encoder"):
        return "encoder" if text == "encoder" else "world"
    meant = {"0": "encoder", "1": "world"}.get(text, text.lower())
    hint = f" (the ROS 2 number {text} means {meant})" if text in ("0", "1") else ""
    reader.warn(
        found,
        f"{owner}<odometrySource>{text}</odometrySource> is neither 'world' nor 'encoder'"
        f"{hint}; like gazebo_ros (ROS 1) the odometry comes from the world. Write world or "
        "encoder",
    )
    return "world"


def parse_diff_drive(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> DiffDriveSpec:
    name = plugin.get("name") or "diff_drive"
    owner = f"plugin {name!r} (libgazebo_ros_diff_drive.so): "
    ros1 = plugin.find("ros") is None and has_any(plugin, _DIFF_ROS1)

    def joints(tag: str) -> tuple[str, ...]:
        found = [((e.text or "").strip(), e) for e in plugin.findall(tag)]
        if not found:
            raise reader.error(
                plugin, f"{owner}missing <{tag}>", f"add <{tag}>wheel_joint_name</{tag}>"
            )
        for joint_name, element in found:
            if joint_name not in urdf.joints:
                raise reader.error(
                    element,
                    f"{owner}<{tag}> {joint_name!r} is not a joint",
                    f"use one of: {', '.join(urdf.joints) or 'no joints defined'}",
                )
            if not urdf.joints[joint_name].moves:
                raise reader.error(
                    element,
                    f"{owner}wheel joint {joint_name!r} is fixed",
                    "make the wheel joint continuous",
                )
        return tuple(j for j, _ in found)

    if ros1:
        ns = reader.text(plugin, "robotNamespace") or ""

        def topic(tag: str, default: str) -> str:
            value = reader.text(plugin, tag) or default
            return ros1_join(value) if value.startswith("/") else ros1_join(ns, value)

        publish_tf = reader.boolean(plugin, "publishTf", True, owner=owner)
        source = _ros1_odometry_source(reader, plugin, owner=owner)
        reader.unknown(
            plugin, (*_DIFF_ROS1, *WHEEL_NOISE_TAGS), owner=owner, what="the diff drive plugin"
        )
        legacy = reader.boolean(plugin, "legacyMode", False, owner=owner)
        if legacy:
            reader.warn(
                plugin,
                f"{owner}<legacyMode>true swaps the left and right wheel speeds (the kinetic "
                "plugin's legacy behaviour; melodic and noetic ignore the element): a positive "
                "angular.z turns the robot clockwise unless the joints are swapped too",
            )
        level = (reader.text(plugin, "rosDebugLevel") or "na").lower()
        if level not in ("na", "debug", "info", "warn", "error", "fatal"):
            reader.warn(
                plugin,
                f"{owner}<rosDebugLevel> {level!r} is not one of na, Debug, Info, Warn, Error, "
                "Fatal; like gazebo_ros it is ignored",
            )
        return DiffDriveSpec(
            plugin_name=name, left_joints=joints("leftJoint"), right_joints=joints("rightJoint"),
            wheel_separation=(reader.number(plugin, "wheelSeparation", 0.34, owner=owner,
                                            minimum=0.0, strict=True),),
            wheel_diameter=(reader.number(plugin, "wheelDiameter", 0.15, owner=owner,
                                          minimum=0.0, strict=True),),
            max_wheel_acceleration=reader.number(plugin, "wheelAcceleration", 0.0, owner=owner,
                                                 minimum=0.0),
            max_wheel_torque=reader.number(plugin, "wheelTorque", 5.0, owner=owner, minimum=0.0),
            command_topic=topic("commandTopic", "cmd_vel"),
            odometry_topic=topic("odometryTopic", "odom"),
            odometry_frame=tf_resolve(ns, reader.text(plugin, "odometryFrame") or "odom"),
            robot_base_frame=tf_resolve(ns, reader.text(plugin, "robotBaseFrame")
                                        or "base_footprint"),
            publish_odom=publish_tf,
            publish_odom_tf=publish_tf and reader.boolean(plugin, "publishOdomTF", True,
                                                          owner=owner),
            publish_wheel_tf=reader.boolean(plugin, "publishWheelTF", False, owner=owner),
            odometry_source=source,
            update_rate=reader.number(plugin, "updateRate", 100.0, owner=owner, minimum=0.0),
            odometry_noise=_wheel_noise(reader, plugin, owner=owner, encoder=source == "encoder"),
            ros_version=1,
            publish_wheel_joint_state=reader.boolean(plugin, "publishWheelJointState", False,
                                                     owner=owner),
            joint_states_topic=ros1_join(ns, "joint_states"),
            legacy_mode=legacy,
        )  # fmt: skip
    node = plugin_node(reader, plugin, owner=owner)
    pairs = int(reader.number(plugin, "num_wheel_pairs", 1.0, owner=owner, minimum=1.0))
    left, right = joints("left_joint"), joints("right_joint")
    if len(left) != pairs or len(right) != pairs:
        raise reader.error(
            plugin,
            f"{owner}num_wheel_pairs is {pairs} but there are "
            f"{len(left)} <left_joint> and {len(right)} <right_joint>",
            "give one left and one right joint per wheel pair",
        )

    def per_pair(tag: str, default: float) -> tuple[float, ...]:
        values = [
            reader.number(e, ".", default, owner=owner, minimum=0.0, strict=True)
            for e in plugin.findall(tag)
        ]
        values += [default] * (pairs - len(values))
        return tuple(values[:pairs])

    source_num = int(reader.number(plugin, "odometry_source", 1.0, owner=owner))
    if source_num not in (0, 1):
        raise reader.error(
            plugin,
            f"{owner}odometry_source {source_num} is not 0 or 1",
            "write 0 (encoder) or 1 (world)",
        )
    if plugin.find("command_topic") is not None or plugin.find("odometry_topic") is not None:
        reader.warn(
            plugin,
            f"{owner}<command_topic>/<odometry_topic> are ROS 1 era names the "
            "ROS 2 plugin ignores; use <ros><remapping>cmd_vel:=...</remapping>",
        )
    reader.unknown(plugin, _DIFF_ROS2, owner=owner, what="the diff drive plugin")
    spec = DiffDriveSpec(
        plugin_name=name, left_joints=left, right_joints=right,
        wheel_separation=per_pair("wheel_separation", 0.34),
        wheel_diameter=per_pair("wheel_diameter", 0.15),
        max_wheel_acceleration=reader.number(plugin, "max_wheel_acceleration", 0.0, owner=owner,
                                             minimum=0.0),
        max_wheel_torque=reader.number(plugin, "max_wheel_torque", 5.0, owner=owner, minimum=0.0),
        command_topic=node.resolve("cmd_vel"), odometry_topic=node.resolve("odom"),
        odometry_frame=reader.text(plugin, "odometry_frame") or "odom",
        robot_base_frame=reader.text(plugin, "robot_base_frame") or "base_footprint",
        publish_odom=reader.boolean(plugin, "publish_odom", False, owner=owner),
        publish_odom_tf=reader.boolean(plugin, "publish_odom_tf", False, owner=owner),
        publish_wheel_tf=reader.boolean(plugin, "publish_wheel_tf", False, owner=owner),
        odometry_source="world" if source_num == 1 else "encoder",
        update_rate=reader.number(plugin, "update_rate", 100.0, owner=owner, minimum=0.0),
        covariance=(reader.number(plugin, "covariance_x", 0.00001, owner=owner, minimum=0.0),
                    reader.number(plugin, "covariance_y", 0.00001, owner=owner, minimum=0.0),
                    reader.number(plugin, "covariance_yaw", 0.001, owner=owner, minimum=0.0)),
        odometry_noise=_wheel_noise(reader, plugin, owner=owner, encoder=source_num == 0),
        ros_version=2,
    )  # fmt: skip
    if not spec.publish_odom and not spec.publish_odom_tf:
        reader.warn(
            plugin,
            f"{owner}publishes neither odom nor the odom TF (the ROS 2 defaults "
            "of publish_odom and publish_odom_tf are false); add "
            "<publish_odom>true</publish_odom><publish_odom_tf>true"
            "</publish_odom_tf> if you expect them",
        )
    return spec


def parse_joint_state_publisher(
    reader: SdfReader, plugin: ET.Element, urdf: Urdf
) -> JointStatePublisherSpec:
    name = plugin.get("name") or "joint_state_publisher"
    owner = f"plugin {name!r} (libgazebo_ros_joint_state_publisher.so): "
    ros1 = plugin.find("ros") is None and has_any(
        plugin, ("robotNamespace", "jointName", "updateRate")
    )
    if ros1:
        raw = ",".join((e.text or "") for e in plugin.findall("jointName"))
        joint_names = [j.strip() for j in raw.split(",") if j.strip()]
        topic = ros1_join(reader.text(plugin, "robotNamespace") or "", "joint_states")
        rate = reader.number(plugin, "updateRate", 100.0, owner=owner, minimum=0.0)
        reader.unknown(
            plugin,
            ("robotNamespace", "jointName", "updateRate", "alwaysOn"),
            owner=owner,
            what="the joint state publisher",
        )
    else:
        joint_names = [(e.text or "").strip() for e in plugin.findall("joint_name")]
        topic = plugin_node(reader, plugin, owner=owner).resolve("joint_states")
        rate = reader.number(plugin, "update_rate", 100.0, owner=owner, minimum=0.0)
        reader.unknown(
            plugin,
            ("ros", "joint_name", "update_rate"),
            owner=owner,
            what="the joint state publisher",
        )
    for joint in joint_names:
        if joint not in urdf.joints:
            raise reader.error(
                plugin,
                f"{owner}joint {joint!r} does not exist",
                f"use one of: {', '.join(urdf.joints) or 'no joints defined'}",
            )
    return JointStatePublisherSpec(
        plugin_name=name,
        joints=tuple(joint_names),
        topic=topic,
        update_rate=rate,
        ros_version=1 if ros1 else 2,
    )


def parse_quadrotor(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> QuadrotorSpec:
    """``libvisnav_quadrotor.so``: body, vehicle limits and the command topics."""
    name = plugin.get("name") or "quadrotor"
    owner = f"plugin {name!r} (libvisnav_quadrotor.so): "
    node = plugin_node(reader, plugin, owner=owner)
    body = reader.text(plugin, "body_name") or urdf.root
    if body not in urdf.links:
        found = plugin.find("body_name")
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}<body_name> {body!r} is not a link",
            f"use one of: {', '.join(urdf.links)}",
        )
    params: list[tuple[str, str]] = []
    elements: dict[str, ET.Element] = {}
    for child in plugin:
        if child.tag in ("ros", "body_name"):
            continue
        params.append((child.tag, (child.text or "").strip()))
        elements[child.tag] = child
    try:
        QuadrotorParams.from_plugin_params(dict(params))
    except QuadrotorParamsError as exc:
        culprit = next((e for tag, e in elements.items() if f"<{tag}>" in str(exc)), plugin)
        raise reader.error(
            culprit,
            f"{owner}{exc}",
            "write max_thrust, max_tilt, motor_time_constant, disturbance_std as one number "
            "and max_moment as three",
        ) from None
    return QuadrotorSpec(
        plugin_name=name,
        body_name=body,
        parameters=tuple(params),
        trajectory_topic=node.resolve("command/trajectory"),
        pose_topic=node.resolve("command/pose"),
    )


def _value(element: ET.Element) -> str:
    """A URDF ``<gazebo>`` key's value: the ``value=`` attribute first, as sdformat reads it."""
    attribute = element.get("value")
    return (attribute if attribute is not None else element.text or "").strip()


def _friction(reader: SdfReader, element: ET.Element, *, owner: str) -> float:
    """``<mu1>``/``<mu2>`` from its text or ``value=`` attribute: a number >= 0."""
    raw = _value(element)
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not math.isfinite(value) or value < 0.0:
        raise reader.error(
            element,
            f"{owner}<{element.tag}> {raw!r} is not a friction coefficient (a number >= 0)",
            f'write <{element.tag}>1.0</{element.tag}> or <{element.tag} value="1.0"/>',
        )
    return value


def link_properties(reader: SdfReader, element: ET.Element, link: str) -> LinkProperties | None:
    owner = f"gazebo reference {link!r}: "
    rgba: tuple[float, float, float, float] | None = None
    mu1 = mu2 = None
    touched = False
    for child in element:
        if child.tag == "sensor":
            continue
        if child.tag == "material":
            text = _value(child)
            if text in GAZEBO_COLOURS:
                rgba = GAZEBO_COLOURS[text]
                touched = True
            else:
                reader.warn(
                    child,
                    f"{owner}Gazebo material {text!r} is not known; the URDF "
                    f"colour is kept (known: {', '.join(GAZEBO_COLOURS)})",
                )
        elif child.tag in ("mu1", "mu2"):
            value = _friction(reader, child, owner=owner)
            if child.tag == "mu1":
                mu1 = value
            else:
                mu2 = value
            touched = True
        elif child.tag == "plugin":
            reader.warn(
                child,
                f"{owner}plugin {child.get('filename')!r} inside a link reference "
                "is not supported and is ignored",
            )
        else:
            reader.warn(child, f"{owner}<{child.tag}> is not modelled and is ignored")
    return LinkProperties(rgba, mu1, mu2) if touched else None
