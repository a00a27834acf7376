"""What the system declares about its topics: ``--expect`` merged with ``robot_description``.

A URDF published on ``robot_description`` with Gazebo ``<sensor>`` blocks declares,
per topic, the update rate, image size, horizontal field of view, clip range, frame
and encoding (parsed with :func:`visnav.description.gazebo.parse_gazebo_extensions`, which
resolves the exact topic names the ``gazebo_ros`` plugins publish). It also says
which joints are fixed (their transforms belong on ``/tf_static``). ``--expect``
values win over the URDF's.

Every sensor and plugin of the ``<gazebo>`` blocks is also listed with the topics it
publishes (:class:`DeclaredSensor`, found generically: every spec of
:class:`~visnav.description.gazebo_specs.GazeboExtensions` with a ``topic`` or
``*_topic`` field, so new sensor kinds are covered without a change here), and every
sensor or plugin the description parser ignored (:class:`IgnoredSensor`).
"""

from __future__ import annotations

import dataclasses
import logging
from collections.abc import Mapping
from dataclasses import dataclass, field, replace
from typing import Any

from visnav.doctor.expect import Expectations
from visnav.errors import VisnavError

__all__ = [
    "INPUT_TOPIC_FIELDS",
    "Declared",
    "DeclaredJoint",
    "DeclaredSensor",
    "DeclaredTopic",
    "IgnoredSensor",
    "declared_from",
    "declared_sensors",
    "spec_output_topics",
]

_LOG = logging.getLogger("visnav.doctor")

INPUT_TOPIC_FIELDS = frozenset({"command_topic", "trajectory_topic", "pose_topic", "e_stop_topic"})
"""Spec topic fields a plugin subscribes to (commands), not publishes."""


@dataclass(frozen=True)
class DeclaredTopic:
    """Declared properties of one topic (None: not declared).

    Attributes:
        topic: topic name.
        rate: Hz.
        width: image width in pixels.
        height: image height in pixels.
        hfov: horizontal field of view, radians.
        clip_far: sensor range, metres.
        frame_id: header frame_id.
        encoding: image encoding.
        source: where the declaration comes from (for evidence).
    """

    topic: str
    rate: float | None = None
    width: int | None = None
    height: int | None = None
    hfov: float | None = None
    clip_far: float | None = None
    frame_id: str | None = None
    encoding: str | None = None
    source: str = ""


@dataclass(frozen=True)
class DeclaredJoint:
    """A joint of the robot description: what places ``child`` on ``parent``.

    Attributes:
        name: the joint's name.
        parent: parent link.
        child: child link.
        moves: False for a fixed joint (its transform belongs on ``/tf_static``).
        xyz: the joint origin's translation, metres.
        rpy: the joint origin's roll, pitch, yaw, radians.
    """

    name: str
    parent: str
    child: str
    moves: bool
    xyz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    rpy: tuple[float, float, float] = (0.0, 0.0, 0.0)


@dataclass(frozen=True)
class DeclaredSensor:
    """A sensor or plugin of ``robot_description`` and the topics it publishes.

    Attributes:
        name: the sensor's name (or the plugin's ``name``).
        kind: the :class:`~visnav.description.gazebo_specs.GazeboExtensions` field it is
            in (``cameras``, ``rays``, ``diff_drives`` ...).
        declared_as: the tag and plugin that declare it (``<sensor type="ray">`` with
            ``libgazebo_ros_laser.so``).
        topics: the fully qualified topics it publishes.
    """

    name: str
    kind: str
    declared_as: str
    topics: tuple[str, ...]


@dataclass(frozen=True)
class IgnoredSensor:
    """A ``<sensor>`` or ``<plugin>`` the description parser did not simulate.

    Attributes:
        tag: ``sensor`` or ``plugin``.
        text: the parser's warning (names the sensor or plugin and why).
    """

    tag: str
    text: str


@dataclass(frozen=True)
class Declared:
    """Declarations by topic, the robot's joints, sensors and ignored sensors.

    Attributes:
        topics: declared topic properties.
        fixed_joints: child link -> parent link of every fixed joint.
        moving_joints: child link -> parent link of every joint that moves.
        joints: child link -> the joint placing it (name, parent, origin).
        sensors: every sensor and plugin of the description that publishes topics.
        ignored: every sensor and plugin the description parser ignored.
        description_topic: the topic ``robot_description`` came from ('' if none).
    """

    topics: Mapping[str, DeclaredTopic] = field(default_factory=dict)
    fixed_joints: Mapping[str, str] = field(default_factory=dict)
    moving_joints: Mapping[str, str] = field(default_factory=dict)
    joints: Mapping[str, DeclaredJoint] = field(default_factory=dict)
    sensors: tuple[DeclaredSensor, ...] = ()
    ignored: tuple[IgnoredSensor, ...] = ()
    description_topic: str = ""

    def get(self, topic: str) -> DeclaredTopic | None:
        """The declaration of ``topic``, if any."""
        return self.topics.get(topic)


def _prefix(namespace: str, topic: str) -> str:
    ns = namespace.rstrip("/")
    return f"{ns}{topic}" if ns else topic


def _words(name: str) -> set[str]:
    return {w for w in name.split("_") if w}


def _guarded_off(spec: Any, field_name: str) -> bool:
    """True when a ``publish_*`` flag of the spec turns this topic off.

    ``odometry_topic`` is guarded by ``publish_odom``, ``joint_states_topic`` by
    ``publish_wheel_joint_state``: a ``publish_`` flag (not one about TF) sharing a word,
    or a word's prefix, with the topic field's name.
    """
    stem = _words(field_name.removesuffix("topic"))
    if not stem:
        return False
    for f in dataclasses.fields(spec):
        if not f.name.startswith("publish_") or "tf" in _words(f.name):
            continue
        value = getattr(spec, f.name)
        if not isinstance(value, bool):
            continue
        flag = _words(f.name.removeprefix("publish_"))
        if any(a.startswith(b) or b.startswith(a) for a in stem for b in flag) and not value:
            return True
    return False


def spec_output_topics(spec: Any) -> list[str]:
    """The topics a sensor or plugin spec publishes (as written in the spec).

    Every ``topic`` / ``*_topic`` field holding a name, except the command inputs of
    :data:`INPUT_TOPIC_FIELDS` and topics a false ``publish_*`` flag turns off.
    """
    out: list[str] = []
    if not dataclasses.is_dataclass(spec):
        return out
    for f in dataclasses.fields(spec):
        if f.name != "topic" and not f.name.endswith("_topic"):
            continue
        value = getattr(spec, f.name)
        if not isinstance(value, str) or not value or f.name in INPUT_TOPIC_FIELDS:
            continue
        if _guarded_off(spec, f.name) or value in out:
            continue
        out.append(value)
    return out


def _declared_as(kind: str, spec: Any) -> str:
    plugin = getattr(spec, "plugin", None)
    plugin_text = plugin if isinstance(plugin, str) and plugin else None
    if hasattr(spec, "link") and hasattr(spec, "name"):
        sensor_type = getattr(spec, "kind", None) or kind.removesuffix("s")
        tag = f'<sensor type="{sensor_type}">'
        return f"{tag} with {plugin_text}" if plugin_text else tag
    what = plugin_text or kind.removesuffix("s").replace("_", " ")
    return f"<plugin> {what}"


def declared_sensors(ext: Any, namespace: str = "") -> tuple[DeclaredSensor, ...]:
    """Every spec of every tuple field of ``ext`` that publishes topics.

    Args:
        ext: a :class:`~visnav.description.gazebo_specs.GazeboExtensions` (any dataclass
            whose tuple fields hold spec dataclasses).
        namespace: prefixed to every topic (the namespace ``robot_description`` is in).
    """
    out: list[DeclaredSensor] = []
    for f in dataclasses.fields(ext):
        value = getattr(ext, f.name)
        if not isinstance(value, tuple):
            continue
        for spec in value:
            topics = spec_output_topics(spec)
            if not topics:
                continue
            name = getattr(spec, "name", None) or getattr(spec, "plugin_name", None) or f.name
            out.append(
                DeclaredSensor(
                    name=str(name),
                    kind=f.name,
                    declared_as=_declared_as(f.name, spec),
                    topics=tuple(_prefix(namespace, t) for t in topics),
                )
            )
    return tuple(out)


def _ignored(warnings: tuple[str, ...]) -> tuple[IgnoredSensor, ...]:
    from visnav.description.warning_summary import (  # noqa: PLC0415
        Consequence,
        DescriptionWarning,
    )

    out = []
    for message in warnings:
        warning = DescriptionWarning.parse(message)
        if warning.consequence is Consequence.LOST and warning.tag is not None:
            out.append(IgnoredSensor(warning.tag, warning.text))
    return tuple(out)


def _from_urdf(text: str, topic: str) -> Declared:
    # Parsing the URDF is the simulator's job; imported here so doctor runs without it.
    from visnav.description.gazebo import parse_gazebo_extensions  # noqa: PLC0415
    from visnav.description.urdf import parse_urdf  # noqa: PLC0415
    from visnav.tf.robot_state_node import kinematics_only  # noqa: PLC0415

    # Without visuals and collisions: package:// meshes need not resolve on this machine.
    urdf = parse_urdf(kinematics_only(text), source=topic)
    ext = parse_gazebo_extensions(urdf)
    namespace = topic.rsplit("/", 1)[0]
    out: dict[str, DeclaredTopic] = {}
    for cam in ext.cameras:
        src = f"robot_description sensor '{cam.name}'"
        for name, encoding, far in (
            (cam.image_topic, cam.encoding, None),
            (cam.camera_info_topic, None, None),
            (cam.depth_topic, cam.depth_encoding, cam.depth_range[1]),
            (cam.depth_info_topic, None, cam.depth_range[1]),
            (cam.points_topic, None, cam.depth_range[1]),
        ):
            if name:
                full = _prefix(namespace, name)
                out[full] = DeclaredTopic(
                    full,
                    rate=cam.update_rate or None,
                    width=cam.width,
                    height=cam.height,
                    hfov=cam.hfov,
                    clip_far=far,
                    frame_id=cam.frame_id,
                    encoding=encoding,
                    source=src,
                )
    for odo in ext.odometry:
        full = _prefix(namespace, odo.topic)
        out[full] = DeclaredTopic(
            full,
            rate=odo.update_rate or None,
            frame_id=odo.frame_id,
            source=f"robot_description plugin '{odo.plugin_name}'",
        )
    for dd in ext.diff_drives:
        if dd.publish_odom:
            full = _prefix(namespace, dd.odometry_topic)
            out[full] = DeclaredTopic(
                full,
                rate=dd.update_rate or None,
                frame_id=dd.odometry_frame,
                source=f"robot_description plugin '{dd.plugin_name}'",
            )
    fixed = {j.child: j.parent for j in urdf.joints.values() if not j.moves}
    moving = {j.child: j.parent for j in urdf.joints.values() if j.moves}
    joints = {
        j.child: DeclaredJoint(j.name, j.parent, j.child, j.moves, j.origin.xyz, j.origin.rpy)
        for j in urdf.joints.values()
    }
    return Declared(
        out,
        fixed,
        moving,
        joints,
        sensors=declared_sensors(ext, namespace),
        ignored=_ignored(ext.warnings),
        description_topic=topic,
    )


def declared_from(
    robot_description: str | None,
    robot_description_topic: str,
    expect: Expectations | None,
) -> Declared:
    """Merge the URDF's declarations with ``--expect`` (expect wins).

    A URDF that does not parse is ignored (logged at debug level): doctor checks the
    data, the simulator reports URDF errors.
    """
    declared = Declared()
    if robot_description:
        try:
            declared = _from_urdf(
                robot_description, robot_description_topic or "/robot_description"
            )
        except (VisnavError, ValueError, KeyError, TypeError) as exc:
            _LOG.debug("robot_description not used: %s", exc)
    if expect is None:
        return declared
    topics = dict(declared.topics)
    for name, exp in expect.topics.items():
        base = topics.get(name, DeclaredTopic(name))
        fields = (exp.rate, exp.hfov, exp.clip_far, exp.frame_id, exp.encoding)
        if all(v is None for v in fields):
            continue
        src = f"--expect {expect.source}"
        topics[name] = replace(
            base,
            rate=base.rate if exp.rate is None else exp.rate,
            hfov=base.hfov if exp.hfov is None else exp.hfov,
            clip_far=base.clip_far if exp.clip_far is None else exp.clip_far,
            frame_id=base.frame_id if exp.frame_id is None else exp.frame_id,
            encoding=base.encoding if exp.encoding is None else exp.encoding,
            source=f"{base.source}; {src}" if base.source else src,
        )
    return replace(declared, topics=topics)
