"""``libgazebo_ros_control.so`` and the URDF ``<transmission>`` elements it reads.

Read as gazebo_ros_control (ROS 1) reads them:

* the plugin's ``<robotNamespace>`` (default: the model's name; ``spawn_model
  -robot_namespace`` pushes the robot's namespace in front, as for every plugin),
  ``<controlPeriod>`` (s; default the physics step), ``<robotParam>``,
  ``<robotSimType>`` (only ``gazebo_ros_control/DefaultRobotHWSim``), ``<eStopTopic>``
  and ``<legacyModeNS>`` (it only changes where PID gains are read: accepted);
* every ``<transmission>`` with a ``<type>`` (``transmission_interface/SimpleTransmission``;
  DefaultRobotHWSim treats every type alike), one ``<joint name>`` and its
  ``<hardwareInterface>`` (``hardware_interface/VelocityJointInterface``,
  ``EffortJointInterface``, ``PositionJointInterface``; without the prefix too, with
  gazebo_ros_control's "deprecated syntax" warning; a pre-Noetic ``<hardwareInterface>``
  inside ``<actuator>`` is read too, with a warning).

What ``DefaultRobotHWSim`` skips with a log (no ``<type>``, no hardware interface, not
exactly one joint) is skipped here with a warning naming the transmission; what makes the
plugin fail to load (an unknown hardware interface, a transmission of a joint the robot
does not have, or of a fixed joint) raises
:class:`~visnav.description.errors.RobotDescriptionError`.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Literal, cast

from visnav.description._sdf_reader import SdfReader
from visnav.description.gazebo_specs import RosControlSpec, TransmissionSpec, ros1_join
from visnav.description.urdf import Urdf

__all__ = ["HARDWARE_INTERFACES", "parse_ros_control", "parse_transmissions"]

HARDWARE_INTERFACES = (
    "VelocityJointInterface",
    "EffortJointInterface",
    "PositionJointInterface",
)
"""The joint command interfaces ``DefaultRobotHWSim`` offers."""

_DEFAULT_HW_SIM = "gazebo_ros_control/DefaultRobotHWSim"
_KNOWN = (
    "robotNamespace",
    "controlPeriod",
    "robotParam",
    "robotSimType",
    "eStopTopic",
    "legacyModeNS",
)

Interface = Literal["VelocityJointInterface", "EffortJointInterface", "PositionJointInterface"]


def parse_ros_control(reader: SdfReader, plugin: ET.Element, urdf: Urdf) -> RosControlSpec:
    """The ``libgazebo_ros_control.so`` plugin of ``urdf`` with its transmissions.

    Raises:
        RobotDescriptionError: a bad ``<controlPeriod>``, a ``<robotSimType>`` other than
            DefaultRobotHWSim, or a transmission of a missing or fixed joint.
    """
    name = plugin.get("name") or "gazebo_ros_control"
    owner = f"plugin {name!r} (libgazebo_ros_control.so): "
    ns_text = reader.text(plugin, "robotNamespace")
    namespace = ros1_join(urdf.name if ns_text is None else ns_text)
    period = reader.number(plugin, "controlPeriod", 0.0, owner=owner, minimum=0.0)
    sim_type = reader.text(plugin, "robotSimType")
    if sim_type is not None and sim_type != _DEFAULT_HW_SIM:
        found = plugin.find("robotSimType")
        raise reader.error(
            found if found is not None else plugin,
            f"{owner}robotSimType {sim_type!r} cannot be simulated: visnav offers "
            f"{_DEFAULT_HW_SIM} (joints from the URDF transmissions) only",
            f"remove <robotSimType> or set it to {_DEFAULT_HW_SIM}",
        )
    robot_param = reader.text(plugin, "robotParam") or "robot_description"
    e_stop = reader.text(plugin, "eStopTopic") or None
    legacy = plugin.find("legacyModeNS")
    if legacy is not None:
        reader.boolean(plugin, "legacyModeNS", True, owner=owner)  # a malformed value still fails
    reader.unknown(plugin, _KNOWN, owner=owner, what="gazebo_ros_control")
    return RosControlSpec(
        plugin_name=name,
        robot_namespace=namespace,
        control_period=period,
        robot_param=robot_param,
        e_stop_topic=e_stop,
        transmissions=parse_transmissions(reader, urdf),
    )


def _interface(text: str) -> Interface | None:
    short = text.strip().removeprefix("hardware_interface/")
    return cast("Interface", short) if short in HARDWARE_INTERFACES else None


def parse_transmissions(reader: SdfReader, urdf: Urdf) -> tuple[TransmissionSpec, ...]:
    """The transmissions ``DefaultRobotHWSim`` would use, in URDF order.

    Raises:
        RobotDescriptionError: a transmission's joint is not a moving joint of ``urdf``.
    """
    out: list[TransmissionSpec] = []
    seen: dict[str, str] = {}
    for element in urdf.transmissions:
        name = element.get("name") or ""
        what = f"transmission {name!r}"
        kind = reader.text(element, "type")
        if kind is None:
            reader.warn(
                element,
                f"{what} has no <type> element (the type= attribute is the old format "
                "transmission_interface does not read) and is skipped",
            )
            continue
        joints = element.findall("joint")
        if len(joints) != 1:
            reader.warn(
                element,
                f"{what} has {len(joints)} <joint> elements and is skipped (a "
                "SimpleTransmission has exactly one)",
            )
            continue
        joint_el = joints[0]
        joint = joint_el.get("name") or ""
        if joint not in urdf.joints or not urdf.joints[joint].moves:
            moving = [j for j, spec in urdf.joints.items() if spec.moves]
            problem = "is fixed" if joint in urdf.joints else "does not exist"
            raise reader.error(
                joint_el,
                f"{what}: joint {joint!r} {problem} (gazebo_ros_control fails to load with "
                "a transmission of a joint the model does not move)",
                f"use one of: {', '.join(moving) or 'no moving joints defined'}",
            )
        texts = [(e.text or "").strip() for e in joint_el.findall("hardwareInterface")]
        if not texts:
            actuator_texts = [
                (e.text or "").strip() for e in element.findall("actuator/hardwareInterface")
            ]
            if actuator_texts:
                reader.warn(
                    element,
                    f"{what}: <hardwareInterface> inside <actuator> is deprecated; it belongs "
                    f"in <joint name={joint!r}>",
                )
            texts = actuator_texts
        if not texts:
            reader.warn(
                joint_el,
                f"{what}: joint {joint!r} has no <hardwareInterface>; the transmission is skipped",
            )
            continue
        interface = _interface(texts[0])
        if interface is None:
            raise reader.error(
                joint_el,
                f"{what}: hardware interface {texts[0]!r} of joint {joint!r} is not one "
                "DefaultRobotHWSim offers (gazebo_ros_control fails to load)",
                f"use hardware_interface/{' or hardware_interface/'.join(HARDWARE_INTERFACES)}",
            )
        if not texts[0].startswith("hardware_interface/"):
            reader.warn(
                joint_el,
                f"{what}: deprecated syntax {texts[0]!r}: prepend 'hardware_interface/' (as "
                "gazebo_ros_control warns)",
            )
        if len(texts) > 1:
            reader.warn(
                joint_el,
                f"{what}: joint {joint!r} lists {len(texts)} hardware interfaces; the first, "
                f"{interface}, is used",
            )
        if joint in seen:
            reader.warn(
                element,
                f"{what}: joint {joint!r} already has transmission {seen[joint]!r}; this one "
                "is skipped",
            )
            continue
        seen[joint] = name
        reduction = reader.number(element, "actuator/mechanicalReduction", 1.0, owner=f"{what}: ")
        out.append(
            TransmissionSpec(
                name=name, joint=joint, interface=interface, mechanical_reduction=reduction
            )
        )
    return tuple(out)
